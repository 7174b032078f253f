"""Recording particle clouds, mixture components and MHT hypotheses (plugins/filters/clutter_recording.py; docs/recording.md)."""

import numpy as np
import pytest

import hybridtrack as ht
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.recording import NullRecorder, RerunRecorder
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack.sdk.scans import Scan
from hybridtrack_plugins.filters.clutter_recording import log_filter_states
from hybridtrack_plugins.filters.gaussian_sum import GaussianSumFilter
from hybridtrack_plugins.filters.mht import MHTFilter
from hybridtrack_plugins.filters.particle import ParticleFilter

REGISTRY = ht.load_plugins(strict=True).registry
X0 = np.array([0.0, 1.0, 0.0, 2.0])
P0 = np.diag([1.0, 0.2, 1.0, 0.2])


def _run(estimator, steps=6):
    """Two filters, seeded scans (the target's measurement plus two false candidates): the states per step."""
    model = REGISTRY.create("motion_model", "straight", noise_cov=np.eye(2) * 0.05)
    sensor = REGISTRY.create("sensor", "position", noise_cov=np.eye(2) * 0.2)
    t = model.transition(0.5, X0)
    bank = TransitionBank.stack([t, t])
    rng = np.random.default_rng(2)
    state = estimator.initialize(np.tile(X0, (2, 1)), np.stack([P0] * 2))
    truth, states = X0.copy(), []
    for _ in range(steps):
        truth = t.apply(truth)
        z = np.concatenate([truth[[0, 2]][None] + rng.normal(0, 0.4, (1, 2)), truth[[0, 2]] + rng.uniform(-3, 3, (2, 2))])
        state, _ = estimator.update(estimator.predict(state, bank), Scan(sensor.name, z), [sensor], model.layout)
        states.append(state)
    return states, model.layout


def test_particles_components_and_hypotheses_read_back(tmp_path):
    runs = {
        "pf": _run(ParticleFilter(particles=50, seed=1, detection_probability=0.9, clutter_density=0.1)),
        "gs": _run(GaussianSumFilter(detection_probability=0.9, clutter_density=0.1, max_components=4)),
        "mht": _run(MHTFilter(detection_probability=0.9, clutter_density=0.1, window=2, max_hypotheses=3)),
    }
    path = tmp_path / "inside.rrd"
    steps = np.arange(6)
    with RerunRecorder(path, {"test": "clutter_recording"}) as rec:
        for prefix, (states, layout) in runs.items():
            log_filter_states(rec, [f"{prefix}_a", f"{prefix}_b"], steps, states, layout, times=0.5 * steps, max_points=20)
    f = RecordingFile(path)
    assert not f.truncated
    # particles: the 20 heaviest per step, at the particle positions
    k, clouds = f.point_sets("world/estimate/pf_b/particles")
    np.testing.assert_array_equal(k, steps)
    pf_states = runs["pf"][0]
    for step, cloud in zip(k, clouds):
        assert cloud.shape == (20, 2)
        particles = pf_states[step].particles[1][:, [0, 2]]
        heaviest = np.argsort(-pf_states[step].log_weights[1], kind="stable")[:20]
        np.testing.assert_allclose(cloud, particles[heaviest], rtol=1e-6, atol=1e-5)  # float32 storage
    _, ess = f.series("estimator/pf_a/effective_sample_size")
    np.testing.assert_allclose(ess, [s.effective_sample_size[0] for s in pf_states])
    # mixture: weights per slot (0 when empty) and one ellipse entity per slot
    gs_states = runs["gs"][0]
    _, w = f.series("estimator/gs_a/component_weight")
    width = max(s.x.shape[1] for s in gs_states)
    assert w.shape == (6, width)
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    np.testing.assert_allclose(w[3, : gs_states[3].x.shape[1]], np.exp(gs_states[3].log_weights[0]))
    assert "/world/estimate/gs_a/component/0" in f.entity_paths and "/world/estimate/gs_b/components" in f.entity_paths
    # MHT: hypothesis probabilities and counts
    mht_states = runs["mht"][0]
    _, p = f.series("estimator/mht_b/hypothesis_probability")
    np.testing.assert_allclose(p, np.stack([s.probabilities[1] for s in mht_states]))
    _, count = f.series("estimator/mht_a/hypotheses")
    np.testing.assert_array_equal(count, [s.count[0] for s in mht_states])
    assert "/world/estimate/mht_a/hypothesis/0" in f.entity_paths


def test_a_recorder_without_weighted_points_gets_plain_points_and_bad_input_raises():
    states, layout = _run(ParticleFilter(particles=30, seed=0, detection_probability=0.9, clutter_density=0.1), steps=2)

    class Plain:
        def __init__(self):
            self.calls = []

        def log_points(self, entity, steps, points, times=None):
            self.calls.append((entity, np.asarray(points).shape))

        def log_scalars(self, entity, steps, values, times=None, names=None):
            self.calls.append((entity, np.asarray(values).shape))

    rec = Plain()
    log_filter_states(rec, ["a", "b"], [0, 1], states, layout)
    assert ("world/estimate/a/particles", (2, 30, 2)) in rec.calls
    log_filter_states(NullRecorder(), ["a", "b"], [0, 1], states, layout)
    with pytest.raises(ValueError, match="one state per step"):
        log_filter_states(rec, ["a", "b"], [0, 1, 2], states, layout)
    with pytest.raises(ValueError, match="filter_names"):
        log_filter_states(rec, ["a"], [0, 1], states, layout)
    with pytest.raises(ValueError, match="layout"):
        log_filter_states(rec, ["a", "b"], [0, 1], states, ("p", "q", "r", "s"))


def test_a_pipeline_records_the_particle_clouds_of_every_step(tmp_path):
    """Estimator.record_states through Pipeline: the cloud logged at each step is that step's state (no state is
    changed in place by a later step), across more than one STATE_CHUNK of streamed steps."""
    from hybridtrack.engine.pipeline import STATE_CHUNK, Pipeline

    steps = STATE_CHUNK + 30
    rng = np.random.default_rng(5)
    z = {"pos": X0[[0, 2]] + np.outer(np.arange(steps) * 0.5, X0[[1, 3]]) + rng.normal(0, 0.3, (steps, 2))}
    options = dict(
        models=[("straight", {"noise_cov": np.eye(2) * 0.05})],
        sensors=[REGISTRY.create("sensor", "position", name="pos", noise_cov=np.eye(2) * 0.09)],
        measurements=z,
        prior=(X0, P0),
        tau=0.5,
        filter_names=["pf"],
    )
    path = tmp_path / "pf.rrd"
    with RerunRecorder(path) as rec:
        pipeline = Pipeline(estimator=ParticleFilter(particles=40, seed=3), recorder=rec, record_seconds=None, **options)
        pipeline.run()
        pipeline.record()
    reference = Pipeline(estimator=ParticleFilter(particles=40, seed=3), **options)
    states = []
    for _ in range(steps):
        reference.step()
        states.append(reference.state)
    k, clouds = RecordingFile(path).point_sets("world/estimate/pf/particles")
    np.testing.assert_array_equal(k, np.arange(steps))
    for step in (0, STATE_CHUNK - 1, STATE_CHUNK, steps - 1):
        heaviest = np.argsort(-states[step].log_weights[0], kind="stable")
        np.testing.assert_allclose(clouds[step], states[step].particles[0][heaviest][:, [0, 2]], rtol=1e-6, atol=1e-5)
    assert reference._pending_states is None  # no recorder, nothing kept
