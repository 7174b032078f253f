"""Shared fixtures: the rerun CLI with a throw-away HOME (it writes analytics files there)."""

import subprocess
import sys
from pathlib import Path

import pytest

RERUN = Path(sys.executable).with_name("rerun")


@pytest.fixture(scope="session")
def rerun_cli(tmp_path_factory):
    """Run ``rerun ARGS…`` with HOME in a temporary folder; returns the CompletedProcess."""
    home = tmp_path_factory.mktemp("rerun-home")

    def run(*args):
        return subprocess.run(
            [str(RERUN), *map(str, args)], capture_output=True, text=True, env={"HOME": str(home), "PATH": "/usr/bin:/bin"}, timeout=120
        )

    return run


@pytest.fixture(scope="session")
def clutter_scenario():
    """``make(straight=15, turn=15, density=0.5, seed=2)`` → (truth, sensor, scans): a straight leg then a right
    turn (r = 5) from x0 = [0, 0, 0, 2] (τ = 0.1, Q = 0.01 I), a position sensor "pos" (R = 0.01 I) and its scans
    with clutter of ``density`` and P_D = 0.9 around the track."""
    import numpy as np

    from hybridtrack.engine.clutter import ClutterModel, region_around, simulate_scans
    from hybridtrack.engine.schedule import Schedule, Segment
    from hybridtrack.engine.simulate import simulate_trajectory
    from hybridtrack_plugins.sensors.position import PositionSensor

    def make(straight=15, turn=15, density=0.5, seed=2):
        schedule = Schedule([Segment("straight", straight), Segment("right_turn", turn, 5.0)])
        truth = simulate_trajectory(schedule, [0.0, 0.0, 0.0, 2.0], 0.1, seed=seed, noise_cov=np.diag([0.01, 0.01]))
        sensor = PositionSensor("pos", ("x", "y"), np.diag([0.01, 0.01]))
        scans = simulate_scans(truth, [sensor], ClutterModel(density, 0.9, region_around(truth.positions, 2.0)), seed=seed)
        return truth, sensor, scans

    return make


@pytest.fixture(scope="session")
def clutter_pipeline():
    """``build(estimator, sensor, scans, **options)`` → a Pipeline of the straight and right-turn (r = 5) bank on the
    clutter ``scans`` of ``sensor`` from the prior N([0, 0, 0, 2], 0.01 I), τ = 0.1; ``options`` (recorder, truth,
    detectors, …) are added or override these."""
    import numpy as np

    from hybridtrack.engine.pipeline import Pipeline

    def build(estimator, sensor, scans, **options):
        settings = {
            "models": ["straight", ("right_turn", {"radius": 5.0})],
            "estimator": estimator,
            "sensors": [sensor],
            "candidates": scans,
            "prior": (np.array([0.0, 0.0, 0.0, 2.0]), np.eye(4) * 0.01),
            "tau": 0.1,
        }
        return Pipeline(**(settings | options))

    return build
