"""User errors refused at the door, before any work, in one line with exit status 2 naming the input (issue 24
item 4): a bad ``hybridtrack run --param`` value, an experiment script with a syntax error, a component hidden by
``HYBRIDTRACK_DISABLE_PLUGINS``, an ``--out`` of the wrong kind (run, track, fit; simulate's outputs), and a model
spec of none of the accepted forms (``resolve``)."""

import re
from pathlib import Path

import numpy as np
import pytest

from hybridtrack import Gaussian, Pipeline
from hybridtrack.apps.experiment import Campaign
from hybridtrack.apps.experiment.definition import ExperimentScriptError, ParameterError
from hybridtrack.cli import main
from hybridtrack.core.plugins import load_plugins, resolve
from hybridtrack.core.registry import UnknownComponentError

TOY = Path(__file__).parents[1] / "apps" / "_toy_experiments.py"
CONFIG = """
[reader]
time = "t"
x = "east"
y = "north"
id = "name"
min_reports = 5

[measurement]
sigma = 20.0

[prior]
position_sigma = 50.0
velocity_sigma = 5.0

[estimator]
algorithm = "imm"
process_noise = 0.3
modes = {modes}
"""


def cli(capsys, *argv):
    status = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return status, captured.err


def assert_refused(status, err, *names):
    """Exit 2, one line on stderr, no traceback, every name in it."""
    assert status == 2, err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and err.endswith("\n"), err
    for name in names:
        assert name in err, (name, err)


def track_inputs(tmp_path, modes='["straight"]'):
    """A small position file (two objects, eight fixes each) and a tracker configuration."""
    rows = ["t,name,east,north"] + [f"{2.0 * k},o{o},{10.0 * k + 1000 * o},{5.0 * k}" for o in range(2) for k in range(8)]
    csv = tmp_path / "tracks.csv"
    csv.write_text("\n".join(rows) + "\n")
    config = tmp_path / "config.toml"
    config.write_text(CONFIG.format(modes=modes))
    return csv, config


# --------------------------------------------------------------------------- run --param


@pytest.mark.parametrize(
    "param, names",
    [
        ("R=x", ["parameter R", "expected a finite number", "0.01", "got 'x'"]),
        ("R=[1, 2]", ["parameter R", "expected a finite number", "got [1, 2]"]),
        ("tau=NaN", ["parameter tau", "expected a finite number", "got nan"]),
        ("q=true", ["parameter q", "expected a finite number", "got True"]),
        ("R=-1", ["parameter R", "expected a finite number > 0", "got -1"]),
        ("steps_scale=0", ["parameter steps_scale", "expected a finite number > 0", "got 0"]),
        ("q=-0.5", ["parameter q", "expected a finite number ≥ 0", "got -0.5"]),
    ],
)
def test_run_refuses_a_bad_parameter_value_before_any_run(tmp_path, capsys, param, names):
    out = tmp_path / "out"
    status, err = cli(capsys, "run", "demo_rmse", "--n", 2, "--executor", "inline", "--no-progress", "--out", out, "--param", param)
    assert_refused(status, err, "experiment 'demo_rmse'", *names)
    assert "resume" not in err and not out.exists(), "no run started, nothing stored"


@pytest.mark.parametrize(
    "param, names",
    [
        ("size=2.5", ["parameter size", "expected an integer (as its default 3)", "got 2.5"]),
        ("size=many", ["parameter size", "expected an integer", "got 'many'"]),
        ("size=true", ["parameter size", "expected an integer", "got True"]),
    ],
)
def test_run_checks_a_script_experiment_parameter_against_its_default(tmp_path, capsys, param, names):
    out = tmp_path / "out"
    status, err = cli(capsys, "run", f"{TOY}:DRAWS", "--n", 2, "--executor", "inline", "--no-progress", "--out", out, "--param", param)
    assert_refused(status, err, "experiment 'draws'", *names)
    assert not out.exists()


def test_campaign_raises_a_parameter_error_naming_the_parameter(tmp_path):
    with pytest.raises(ParameterError, match=r"parameter R: expected a finite number \(as its default 0.01\), got 'x'"):
        Campaign("demo_rmse", 2, tmp_path / "out", parameters={"R": "x"})
    with pytest.raises(ParameterError, match=r"parameter tau: expected a finite number > 0 .*, got -0.1"):
        Campaign("demo_rmse", 2, tmp_path / "out", parameters={"tau": -0.1})
    assert Campaign("demo_rmse", 2, tmp_path / "out", parameters={"R": 1, "steps_scale": 0.5}).parameters["R"] == 1  # int for a float


# --------------------------------------------------------------------------- an experiment script with a syntax error


@pytest.mark.parametrize(
    "source, line, error",
    [
        ("from hybridtrack.apps.experiment import Experiment\ndef run_one(index, rng:\n    return {}\n", 2, "SyntaxError"),
        ("def run_one(index, rng):\n    x = 1\n        return {}\n", 3, "IndentationError"),
    ],
)
def test_run_reports_a_syntax_error_of_the_script_in_one_line(tmp_path, capsys, source, line, error):
    script = tmp_path / "broken.py"
    script.write_text(source)
    status, err = cli(capsys, "run", script, "--n", 2, "--executor", "inline", "--no-progress", "--out", tmp_path / "out")
    assert_refused(status, err, f"{script}, line {line}", error)
    with pytest.raises(ExperimentScriptError, match=rf"broken\.py, line {line}: {error}"):
        Campaign(str(script), 2, tmp_path / "out")


# --------------------------------------------------------------------------- HYBRIDTRACK_DISABLE_PLUGINS


def test_a_component_of_a_disabled_plugin_is_reported_as_disabled(tmp_path, capsys, monkeypatch, fresh_default_plugins):
    monkeypatch.setenv("HYBRIDTRACK_DISABLE_PLUGINS", "motion")
    status, err = cli(capsys, "simulate", "--no-record", "--npz", tmp_path / "s.npz")
    assert_refused(
        status,
        err,
        "motion_model 'left_turn' is disabled by HYBRIDTRACK_DISABLE_PLUGINS=motion",
        "plugin 'motion.linear_modes'",
        "known: none",
    )
    assert not (tmp_path / "s.npz").exists()


def test_the_disabled_message_names_the_plugin_and_lists_what_is_known():
    registry = load_plugins(disabled=["filters.kalman"]).registry
    with pytest.raises(UnknownComponentError, match=r"estimator 'kalman' is disabled by disabled=\['filters.kalman'\]") as info:
        resolve("estimator", "kalman", registry)
    assert "plugin 'filters.kalman' (distribution hybridtrack) registers it" in str(info.value)
    assert re.search(r"known: .*\bpda\b", str(info.value)) and ", kalman," not in str(info.value)
    with pytest.raises(UnknownComponentError, match=r"^unknown estimator 'kalmann'; known: "):  # no blocked plugin has it
        registry.get("estimator", "kalmann")


# --------------------------------------------------------------------------- --out of the wrong kind


def test_run_refuses_an_out_that_is_a_file(tmp_path, capsys):
    (tmp_path / "taken").write_text("x")
    for out in (tmp_path / "taken", tmp_path / "taken" / "sub"):
        status, err = cli(capsys, "run", "demo_rmse", "--n", 2, "--executor", "inline", "--no-progress", "--out", out)
        assert_refused(status, err, f"--out {out}: ", "is a file; expected a folder")
    assert (tmp_path / "taken").read_text() == "x"


def test_track_refuses_an_out_that_is_a_file(tmp_path, capsys):
    csv, config = track_inputs(tmp_path)
    (tmp_path / "taken").write_text("x")
    status, err = cli(capsys, "track", csv, "--config", config, "--out", tmp_path / "taken", "--no-progress")
    assert_refused(status, err, f"--out {tmp_path / 'taken'}: is a file; expected a folder")


@pytest.mark.parametrize(
    "out, names",
    [
        ("{tmp}", ["--out {tmp}: is a folder; expected a file"]),
        ("{tmp}/missing/tuned.toml", ["--out {tmp}/missing/tuned.toml", "does not exist"]),
    ],
)
def test_fit_refuses_an_out_that_cannot_be_its_file_before_fitting(tmp_path, capsys, out, names):
    csv, config = track_inputs(tmp_path)
    out = out.format(tmp=tmp_path)
    status, err = cli(capsys, "fit", csv, "--config", config, "--out", out)
    assert_refused(status, err, *(name.format(tmp=tmp_path) for name in names))


@pytest.mark.parametrize("option", ["--npz", "--rrd"])
def test_simulate_outputs_refuse_a_folder(tmp_path, capsys, option):
    """simulate has no --out: its two output files refuse a folder the same way."""
    argv = ["simulate", "--npz", tmp_path / "s.npz", "--rrd", tmp_path / "s.rrd", option, tmp_path]
    status, err = cli(capsys, *argv)
    assert_refused(status, err, option, str(tmp_path), "expected a file name, got a directory")


# --------------------------------------------------------------------------- model specs


@pytest.mark.parametrize(
    "spec, got",
    [
        (["left_turn", 500], r"got list \['left_turn', 500\]; the parameters go in a mapping"),
        (["left_turn", {"radius": 3.0}], r"got list \['left_turn', \{'radius': 3.0\}\]; a list is not a spec: write a tuple"),
        (("left_turn", 500), r"got tuple \('left_turn', 500\); the parameters go in a mapping"),
        (("left_turn",), r"got tuple \('left_turn',\)"),
        (None, r"got NoneType None"),
        ({"name": "left_turn"}, r"got dict \{'name': 'left_turn'\}"),
    ],
)
def test_a_spec_of_none_of_the_accepted_forms_lists_them(spec, got):
    forms = r"motion_model: expected a registered name, \(name, \{parameters\}\), \(name, \{parameters\}, label\) or a MotionModel object, "
    with pytest.raises(TypeError, match=forms + got):
        resolve("motion_model", spec)


def test_a_list_spec_in_a_pipeline_and_in_a_tracker_configuration(tmp_path, capsys):
    with pytest.raises(TypeError, match=r"motion_model: expected a registered name.*got list \['left_turn', 500\]"):
        Pipeline(
            models=[["left_turn", 500]], estimator="kalman", sensors=[], measurements={}, prior=Gaussian(np.zeros(4), np.eye(4)), tau=0.1
        )
    csv, config = track_inputs(tmp_path, modes='[["left_turn", 500]]')
    status, err = cli(capsys, "track", csv, "--config", config, "--out", tmp_path / "out", "--no-progress")
    assert_refused(status, err, str(config), "modes entry ['left_turn', 500]", "expected a name or")
