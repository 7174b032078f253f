"""experiments/clutter.py run small: the method factory, one seeded run, the table and the figure (issue 17)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.core.plugins import get_registry

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def load():
    spec = importlib.util.spec_from_file_location("_small_clutter", EXPERIMENTS / "clutter.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_each_method_gets_only_the_parameters_it_takes():
    clutter = load()
    registry = get_registry()
    nn = clutter.make_estimator(registry, "nearest_neighbour", 0.7, 0.1, seed=3)
    assert nn.gate_probability == clutter.GATE and not hasattr(nn, "clutter_density")
    pf = clutter.make_estimator(registry, "particle", 0.7, 0.1, seed=3)
    assert (pf.detection_probability, pf.clutter_density, pf.gate_probability, pf.particles) == (0.7, 0.1, clutter.GATE, clutter.PARTICLES)
    gs = clutter.make_estimator(registry, "gaussian_sum", 0.7, 0.1, seed=3)
    assert gs.max_components == clutter.SETTINGS["gaussian_sum"]["max_components"]
    with pytest.raises(ValueError, match="does not take clutter scans"):
        clutter.make_estimator(registry, "kalman", 0.7, 0.1, seed=3)


def test_one_seeded_run_is_reproducible_and_the_report_has_every_method(tmp_path):
    clutter = load()
    registry = get_registry()
    models = {"tracker": registry.create("motion_model", "straight", noise_cov=np.eye(2) * clutter.TRACKER_Q)}
    a = clutter.track_run(0, 0.025, 0.9, ["pda"], registry, models)
    b = clutter.track_run(0, 0.025, 0.9, ["pda"], registry, models)
    for name in ("pda",):
        assert a[name]["sum_sq_error"] == b[name]["sum_sq_error"] and a[name]["lost_at"] == b[name]["lost_at"]
        assert a[name]["steps"] == 361 and a[name]["seconds_per_step"] > 0
    row = {"density": 0.025, "detection_probability": 0.9, "runs": 1, "expected_false_per_step": a["expected_false_per_step"]}
    row.update({n: {"track_loss_rate": 0.0, "rmse_kept": 0.3, "mean_loss_step": None, "time_per_step_us": 120.0} for n in ("pda", "mht")})
    result = {"tracking_runs": 1, "detection_runs": 0, "methods": ["pda", "mht"], "tracking": [row], "detection": []}
    table = clutter.markdown(result)
    assert "| PDA | 0.00 · 0.300 · 120 |" in table and "| MHT |" in table
    png = tmp_path / "loss.png"
    clutter.plot_loss(result, png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(SystemExit):
        clutter.main(["--methods", "no_such_method", "--out", str(tmp_path / "x.json")])


def test_one_detection_run_of_example_1_in_clutter():
    clutter = load()
    registry = get_registry()
    specs = [("straight", {}), ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
    models = [registry.create("motion_model", name, noise_cov=clutter.EXAMPLE1_NOISE, **params) for name, params in specs]
    out = clutter.detection_run(0, 0.5, 0.9, models, ("straight", "right_turn_r5", "left_turn_r5"))
    assert out["mode"] in (None, "straight", "right_turn_r5", "left_turn_r5") and out["max_bank"] >= 3


def test_batched_tracking_equals_the_runs_one_by_one():
    """track_runs (NN and PDA as one bank of the runs, RowScan) gives each run's track_run results: the same loss
    steps and squared errors to 1e-12, in a dense cell where tracks are lost; a method not batched runs per run."""
    clutter = load()
    registry = get_registry()
    models = {"tracker": registry.create("motion_model", "straight", noise_cov=np.eye(2) * clutter.TRACKER_Q)}
    methods = ["nearest_neighbour", "pda"]
    batched = clutter.track_runs([0, 1, 2], 0.2, 0.7, methods, registry, models)
    lost = 0
    for seed, row in zip([0, 1, 2], batched):
        single = clutter.track_run(seed, 0.2, 0.7, methods, registry, models)
        assert row["expected_false_per_step"] == single["expected_false_per_step"]
        for name in methods:
            assert row[name]["lost_at"] == single[name]["lost_at"] and row[name]["steps"] == single[name]["steps"] == 361
            assert row[name]["sum_sq_error"] == pytest.approx(single[name]["sum_sq_error"], rel=1e-12, abs=1e-12)
            lost += row[name]["lost_at"] is not None
    assert lost > 0  # the comparison covers lost tracks too
    assert set(clutter.BATCHED) == set(methods)
