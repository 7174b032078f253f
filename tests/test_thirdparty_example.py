"""The third-party plugin example (examples/thirdparty_plugin), "installed" from its own pyproject.

Instead of pip-installing it, the fixture writes the dist-info pip would write
(name, version and entry points read from the example's ``pyproject.toml``)
into a temporary folder on ``sys.path`` and puts the example's ``src`` next to
it: importlib.metadata sees a real installed distribution, nothing in the
project's environment changes.
"""

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from hybridtrack import cli
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.apps.tracking import track_file
from hybridtrack.core.plugins import load_plugins
from hybridtrack.core.types import Gaussian
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.schedule import Schedule
from hybridtrack.engine.simulate import simulate, simulate_trajectory
from hybridtrack.testing import build_example, check_algorithm, check_detector, check_estimator, check_motion_model
from hybridtrack_plugins.sensors.position import PositionSensor

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "thirdparty_plugin"
PROJECT = tomllib.loads((EXAMPLE / "pyproject.toml").read_text())["project"]
SCRIPT = Path(sys.executable).with_name("hybridtrack")
WEAVE_ROW = {
    "plugin": "zigzag",
    "distribution": "hybridtrack-zigzag",
    "version": PROJECT["version"],
    "kind": "motion_model",
    "name": "weave",
}


@pytest.fixture
def zigzag(install_distribution):
    """The example installed; returns the folder holding its dist-info (for a child's PYTHONPATH)."""
    install_distribution(PROJECT["name"], PROJECT["entry-points"]["hybridtrack"], version=PROJECT["version"], source_root=EXAMPLE / "src")
    return install_distribution.root


def test_the_example_declares_its_entry_point():
    assert PROJECT["name"] == "hybridtrack-zigzag"
    assert PROJECT["entry-points"]["hybridtrack"] == {"zigzag": "hybridtrack_zigzag"}


def test_the_plugin_loads_next_to_the_builtins(zigzag):
    loaded = load_plugins()
    assert loaded.problems == ()
    entry = loaded.registry.entry("motion_model", "weave")
    assert (entry.plugin, entry.distribution, entry.version) == ("zigzag", "hybridtrack-zigzag", PROJECT["version"])
    assert "straight" in loaded.registry.names("motion_model")


def test_the_plugin_shows_in_the_cli_listing(zigzag, capsys):
    assert cli.main(["plugins", "--json"]) == 0
    out, err = capsys.readouterr()
    assert WEAVE_ROW in json.loads(out) and err == ""


@pytest.mark.skipif(not SCRIPT.exists(), reason=f"console script not installed at {SCRIPT}")
def test_the_plugin_shows_in_the_installed_cli(zigzag):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(zigzag), str(EXAMPLE / "src")]))
    env.pop("HYBRIDTRACK_DISABLE_PLUGINS", None)
    result = subprocess.run([str(SCRIPT), "plugins", "--json"], capture_output=True, text=True, env=env, timeout=60, check=False)
    assert result.returncode == 0 and result.stderr == "", result.stderr
    assert WEAVE_ROW in json.loads(result.stdout)


def test_the_plugin_passes_the_contract_checks(zigzag):
    factory = load_plugins().registry.get("motion_model", "weave")
    check_motion_model(build_example(factory))


def test_a_schedule_can_use_the_new_mode(zigzag):
    registry = load_plugins().registry
    x0 = [0.0, 10.0, 0.0, 0.0, 0.0]
    noisy = simulate_trajectory(Schedule.from_rows([("weave", 20)]), x0, 0.5, seed=1, registry=registry)
    assert noisy.layout == ("x", "vx", "y", "vy", "phase") and noisy.states.shape == (21, 5)
    assert np.isfinite(noisy.states).all()
    mixed = Schedule.from_rows([("straight", 10), ("weave", 40), ("straight", 10)])
    clean = simulate_trajectory(mixed, [0.0, 10.0, 0.0, 0.0], 0.5, process_noise=False, registry=registry)
    speeds = np.hypot(clean.states[:, 1], clean.states[:, 3])
    np.testing.assert_allclose(speeds, 10.0, rtol=1e-12)
    headings = np.arctan2(clean.states[:, 3], clean.states[:, 1])
    assert np.ptp(headings[11:51]) > 0.9  # the weave swings the heading by ±0.5 rad


def test_the_example_own_tests_pass_with_the_pytest_fixtures(zigzag):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(zigzag), str(EXAMPLE / "src")]))
    env.pop("HYBRIDTRACK_DISABLE_PLUGINS", None)
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-c", str(EXAMPLE / "pyproject.toml"), str(EXAMPLE / "tests")],
        capture_output=True,
        text=True,
        env=env,
        cwd=EXAMPLE,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "10 passed" in result.stdout


# --------------------------------------------------------------------------- the estimator and detector of the example
# Example 1 of tests/algorithms/test_adaptive.py: 20 steps straight, then a right turn of radius 5 m.
X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
MODES = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]


def example1(seed, turn=30):
    sensors = [PositionSensor(noise_cov=NOISE)]
    schedule = Schedule.from_rows([("straight", 20), ("right_turn", turn, 5.0)])
    truth, z = simulate(schedule, X0, 0.1, sensors, seed=seed, noise_cov=NOISE)
    return truth, z, sensors


def test_the_new_estimator_and_detector_come_from_the_registry_and_pass_the_contract_checks(zigzag):
    registry = load_plugins().registry
    for kind, name in (("estimator", "info_kalman"), ("detector", "cumulative_llr")):
        entry = registry.entry(kind, name)
        assert (entry.plugin, entry.distribution) == ("zigzag", "hybridtrack-zigzag")
    check_estimator(build_example(registry.get("estimator", "info_kalman")))  # against the covariance-form KF
    for parameters in ({}, {"alpha": 0.2, "beta": 0.2, "pruning": "oldest"}):
        check_detector(registry.get("detector", "cumulative_llr")(**parameters))


def test_a_pipeline_with_the_new_estimator_and_detector_equals_the_builtin_kalman(zigzag):
    truth, z, sensors = example1(0)
    prior = Gaussian(X0, np.eye(4))
    runs = {
        estimator: Pipeline(
            models=MODES, estimator=estimator, sensors=sensors, measurements=z, prior=prior, tau=0.1, detectors=["cumulative_llr"]
        ).run()
        for estimator in ("info_kalman", "kalman")
    }
    ours, builtin = runs["info_kalman"], runs["kalman"]
    assert ours.means.shape == (51, 3, 4)
    np.testing.assert_allclose(ours.means, builtin.means, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.covs, builtin.covs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.loglik, builtin.loglik, rtol=0, atol=1e-9)
    ratios = ours.statistics["cumulative_llr"]["log_ratio"]
    assert ratios.shape == (51, 3)  # one per filter of the fixed bank
    np.testing.assert_allclose(ratios, builtin.statistics["cumulative_llr"]["log_ratio"], atol=1e-9)


def test_known_switch_adaptive_runs_with_the_new_components(zigzag):
    truth, z, sensors = example1(1)
    prior, segments = Gaussian(X0, np.eye(4)), [20, 30]
    options = dict(sensors=sensors, tau=0.1, noise_cov=NOISE, n=4, r_min=2.0, r_max=5.0)
    ours = KnownSwitchAdaptive(estimator="info_kalman", **options).run(z, prior, segments)
    builtin = KnownSwitchAdaptive(estimator="kalman", **options).run(z, prior, segments)
    np.testing.assert_allclose(ours.means, builtin.means, rtol=0, atol=1e-9)
    assert np.array_equal(ours.mode, builtin.mode) and ours.segments == builtin.segments

    adaptive = KnownSwitchAdaptive(estimator="info_kalman", detector=("cumulative_llr", {"alpha": 0.01, "beta": 0.01}), **options)
    run = adaptive.run(z, prior, segments)
    assert run.log_ratios.shape == (51, 9) and run.means.shape == (51, 4) and np.isfinite(run.means).all()
    straight, turn = run.segments
    assert straight.mode == "straight"  # undecided or "no change" within its 20 steps: the straight filter throughout
    assert turn.mode.startswith("right_turn") and turn.decision_step is not None and run.decisions[-1].mode == turn.mode
    error = np.sqrt(np.mean(np.sum((run.means[:, [0, 2]] - truth.positions) ** 2, axis=1)))
    assert error < 0.5


@pytest.mark.parametrize("pruning, bank_size", [("nearest_lower", None), ("nearest_lower", 10), ("oldest", 20)])
def test_unknown_change_adaptive_detects_the_right_turn_with_the_new_components(zigzag, pruning, bank_size):
    detected = 0
    for seed in range(6):
        truth, z, sensors = example1(seed)
        adaptive = UnknownChangeAdaptive(
            modes=MODES,
            sensors=sensors,
            tau=0.1,
            estimator="info_kalman",
            detector=("cumulative_llr", {"alpha": 0.01, "beta": 0.01}),
            bank_size=bank_size,
            pruning=pruning,
        )
        run = adaptive.run(z, Gaussian(X0, np.eye(4)))
        change = run.first_change(after=20)
        if not [c for c in run.changes if c.step <= 20] and change is not None and change.mode == "right_turn_r5":
            detected += 1
            assert (run.mode[change.step :] == 1).all()
        if bank_size is not None:
            assert run.bank_sizes.max() <= 1 + bank_size + 2
    assert detected >= 4


# --------------------------------------------------------------------------- the algorithm of the example
TRACK_CONFIG = """
[reader]
time = "t"
x = "east"
y = "north"
id = "name"

[measurement]
sigma = 1.0

[estimator]
algorithm = "most_likely"
process_noise = 0.05
modes = ["straight", "left_turn", "right_turn"]
radii = [200.0]
"""


def test_the_new_algorithm_is_listed_and_passes_the_contract_check(zigzag, capsys):
    registry = load_plugins().registry
    entry = registry.entry("algorithm", "most_likely")
    assert (entry.plugin, entry.distribution) == ("zigzag", "hybridtrack-zigzag")
    check_algorithm(entry.factory)
    assert cli.main(["plugins", "--json"]) == 0
    assert {**WEAVE_ROW, "kind": "algorithm", "name": "most_likely"} in json.loads(capsys.readouterr().out)


def test_track_names_the_new_algorithm(zigzag, tmp_path):
    """A config names the third party's algorithm; its fixed bank (transitions fixed at the first fixes) follows a left turn."""
    t = np.arange(41) * 2.0
    angle = t * 10.0 / 200.0  # 10 m/s on a left turn of 200 m from the start, heading east
    xy = 200.0 * np.column_stack([np.sin(angle), 1.0 - np.cos(angle)])
    xy += np.random.default_rng(3).normal(0.0, 1.0, xy.shape)
    csv = tmp_path / "legs.csv"
    csv.write_text("t,name,east,north\n" + "".join(f"{a:.1f},boat,{x:.3f},{y:.3f}\n" for a, (x, y) in zip(t, xy)))
    (tmp_path / "c.toml").write_text(TRACK_CONFIG)
    summary = track_file(csv, tmp_path / "c.toml", tmp_path / "out")
    (boat,) = summary["objects"]
    last = boat["segments"][-1]
    assert {key: last[key] for key in ("end", "mode", "radius")} == {"end": 80.0, "mode": "left_turn", "radius": 200.0}
    assert last["mean_speed"] == pytest.approx(10.0, rel=0.05) and last["mean_turn_rate"] == pytest.approx(
        np.degrees(10.0 / 200.0), rel=0.1
    )
    assert boat["segments"][-1]["start"] <= 20.0
    assert [d["mode"] for d in boat["decisions"]] == [s["mode"] for s in boat["segments"][1:]]  # no detector: the mode changes
    npz = np.load(tmp_path / "out" / "boat.npz")
    assert npz["means"].shape == (41, 4) and np.isfinite(npz["means"]).all()
