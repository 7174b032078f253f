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
from hybridtrack.plugins import load_plugins
from hybridtrack.simulate import simulate_trajectory
from hybridtrack.testing import build_example, check_motion_model
from hybridtrack.types import Schedule

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "thirdparty_plugin"
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
    assert "5 passed" in result.stdout
