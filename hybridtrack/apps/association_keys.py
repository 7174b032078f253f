"""The keys of a configuration's ``[association]`` table (unlabelled detections: :mod:`hybridtrack.apps.multitarget`)."""

#: ``[association]`` keys and their defaults (None: not set); docs/config.md lists them
ASSOCIATION_DEFAULTS = {
    "method": "gnn",
    "motion": "cv",
    "scan_window": None,
    "scan": None,
    "detection_probability": 0.9,
    "clutter_density": 1e-6,
    "birth_density": None,
    "gate_probability": 0.999,
    "initiation": "two_point",
    "updates_per_scan": 1,
    "hypotheses": 10,
    "mht_scans": 3,
    "seed_window": None,
    "max_speed": None,
    "velocity_sigma": None,
    "noise_density": None,
    "management": "m_of_n",
    "confirm_hits": 3,
    "confirm_scans": 4,
    "delete_misses": 3,
    "false_track_probability": 1e-4,
    "track_loss_probability": 0.1,
    "deletion_drop": None,
    "max_coast": None,
}
