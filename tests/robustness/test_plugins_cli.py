"""Robustness of plugin loading (defect 6) and of the command line (defect 7).

Plugins: any exception a plugin raises at import or in its hook (SystemExit,
GeneratorExit, custom BaseException subclasses) is isolated and names the
plugin; KeyboardInterrupt still interrupts; unknown names in
HYBRIDTRACK_DISABLE_PLUGINS are warned about; a factory of the wrong type is
caught at registration (a class) or first use (a function) naming the plugin.

CLI: every bad input is exit status 2 with one line on stderr naming the
option or file and no traceback; a failed ``simulate`` leaves no output;
``--npz out.dat`` writes out.dat; ``ship_turn`` simulates; times beyond the
recording's int64-nanosecond axis are rejected; a closed pipe and a non-UTF-8
console end quietly.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

import hybridtrack.core.plugins as plugins
from hybridtrack.cli import main
from hybridtrack.core.plugins import PluginError, PluginWarning, load_plugins, resolve
from hybridtrack.engine.schedule import Schedule
from hybridtrack.engine.simulate import build_models
from hybridtrack.recording import MAX_RECORDABLE_SECONDS, RerunRecorder, check_recordable_times

SCRIPT = Path(sys.executable).with_name("hybridtrack")


# --------------------------------------------------------------------------- fake installed plugins


@pytest.fixture
def install(tmp_path, monkeypatch):
    """``install(entry, source)``: an installed-looking distribution ``ht-<entry>`` whose entry point ``entry`` is a module."""
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(site))
    modules = []

    def add(entry: str, source: str) -> None:
        module = f"ht_robust_{entry}"
        (site / f"{module}.py").write_text(textwrap.dedent(source))
        info = site / f"ht_{entry}-1.0.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: ht-{entry}\nVersion: 1.0\n")
        (info / "entry_points.txt").write_text(f"[{plugins.ENTRY_POINT_GROUP}]\n{entry} = {module}\n")
        modules.append(module)
        importlib.invalidate_caches()

    plugins.reset()
    yield add
    for module in modules:
        sys.modules.pop(module, None)
    importlib.invalidate_caches()
    plugins.reset()


def _load(**kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loaded = load_plugins(**kwargs)
    return loaded, [str(w.message) for w in caught if issubclass(w.category, PluginWarning)]


IMPORT_FAULTS = {
    "system_exit": "import sys\nsys.exit(3)\n",
    "generator_exit": "raise GeneratorExit('closing')\n",
    "custom_base": "class Fatal(BaseException):\n    pass\n\nraise Fatal('custom base exception')\n",
    "exit_builtin": "exit('bye')\n",
}


@pytest.mark.parametrize("fault", sorted(IMPORT_FAULTS))
def test_a_base_exception_at_import_is_isolated_and_names_the_plugin(install, fault):
    install(fault, IMPORT_FAULTS[fault])
    loaded, messages = _load(disabled=())
    (message,) = [m for m in messages if f"'{fault}'" in m]
    assert f"distribution ht-{fault}" in message and "failed to import" in message
    assert "straight" in loaded.registry.names("motion_model"), "the other plugins still load"
    with pytest.raises(PluginError, match=f"plugin '{fault}' \\(distribution ht-{fault}\\) failed to import"):
        load_plugins(strict=True, disabled=())


def test_keyboard_interrupt_at_import_still_interrupts(install):
    install("ctrl_c", "raise KeyboardInterrupt\n")
    with pytest.raises(KeyboardInterrupt):
        load_plugins(disabled=())


def test_a_base_exception_in_a_hook_is_isolated(install):
    install(
        "hook_exit",
        """
        import sys
        from hybridtrack import hookimpl

        @hookimpl
        def register_sensors(registry):
            sys.exit("no sensors today")
        """,
    )
    loaded, messages = _load(disabled=())
    (message,) = [m for m in messages if "'hook_exit'" in m]
    assert "register_sensors" in message and "no sensors today" in message
    assert "position" in loaded.registry.names("sensor")


@pytest.mark.parametrize("value", ["motoin", "motion,nosuch_plugin", " hybridtrack-zz "])
def test_unknown_names_in_the_disable_variable_warn_listing_the_known_ones(monkeypatch, value):
    monkeypatch.setenv(plugins.DISABLE_ENV, value)
    _, messages = _load()
    (message,) = [m for m in messages if plugins.DISABLE_ENV in m]
    unknown = [name.strip() for name in value.split(",") if name.strip() != "motion"]
    assert all(repr(name) in message for name in unknown)
    assert "known:" in message and "motion" in message.split("known:")[1] and "hybridtrack" in message


def test_known_names_in_the_disable_variable_do_not_warn(monkeypatch):
    monkeypatch.setenv(plugins.DISABLE_ENV, "solvers,hybridtrack")
    _, messages = _load()
    assert messages == []


def test_the_plugins_command_prints_the_unknown_disabled_name(monkeypatch, capsys):
    monkeypatch.setenv(plugins.DISABLE_ENV, "motoin")
    assert main(["plugins", "--json"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'motoin'" in err and "known:" in err


WRONG_CLASS = """
from hybridtrack import hookimpl


class NotASensor:
    '''Has nothing a sensor needs.'''


@hookimpl
def register_sensors(registry):
    registry.add("not_a_sensor", NotASensor)
"""

WRONG_FUNCTION = """
from hybridtrack import hookimpl


def make():
    '''Returns a string instead of a component.'''
    return "oops"


@hookimpl
def register_sensors(registry):
    registry.add("stringly", make)


@hookimpl
def register_motion_models(registry):
    registry.add("stringly_mode", make)
"""


def test_a_class_of_the_wrong_type_is_rejected_at_registration(install):
    install("wrongclass", WRONG_CLASS)
    loaded, messages = _load(disabled=())
    (message,) = [m for m in messages if "'wrongclass'" in m]
    assert "distribution ht-wrongclass" in message and "NotASensor" in message and "Sensor" in message
    assert "not_a_sensor" not in loaded.registry.names("sensor")


def test_a_factory_returning_the_wrong_type_is_caught_at_first_use(install):
    install("wrongfn", WRONG_FUNCTION)
    loaded, messages = _load(disabled=())
    assert not [m for m in messages if "wrongfn" in m]
    with pytest.raises(TypeError, match=r"sensor 'stringly'.*plugin 'wrongfn' \(distribution ht-wrongfn\) returned a str"):
        resolve("sensor", "stringly", loaded.registry)
    with pytest.raises(TypeError, match=r"motion_model 'stringly_mode'.*plugin 'wrongfn' \(distribution ht-wrongfn\)"):
        build_models(Schedule.from_rows([("stringly_mode", 3)]), loaded.registry)


# --------------------------------------------------------------------------- the time axis of recordings


@pytest.mark.parametrize("times", [[0.0, 1e10], [-1e10], [0.0, np.inf], [np.nan], 2**63 / 1e9])
def test_times_beyond_the_recording_axis_are_rejected(times):
    with pytest.raises(ValueError, match=r"^times: time .* does not fit the recording's time axis"):
        check_recordable_times(times)


def test_the_largest_recordable_time_passes():
    check_recordable_times([0.0, np.nextafter(MAX_RECORDABLE_SECONDS, 0.0), -9e9])


def test_the_recorder_rejects_an_overflowing_time_before_logging(tmp_path):
    with RerunRecorder(tmp_path / "t.rrd") as recorder:
        with pytest.raises(ValueError, match="times: time 10000000000.0 s"):
            recorder.log_path("world/truth", [0, 1], np.zeros((2, 2)), [0.0, 1e10])
        with pytest.raises(ValueError, match="time: time"):
            recorder.log_event(0, "x", time=-1e12)


# --------------------------------------------------------------------------- the command line


def _cli(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def _assert_usage_error(status, err, *names):
    assert status == 2, err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert "Traceback" not in err and "error:" in err
    for name in names:
        assert name in err, (name, err)


@pytest.mark.parametrize(
    "option, value",
    [
        ("--tau", "0"),
        ("--tau", "-0.1"),
        ("--tau", "nan"),
        ("--tau", "inf"),
        ("--tau", "fast"),
        ("--measurement-noise", "0"),
        ("--measurement-noise", "-1"),
        ("--measurement-noise", "nan"),
        ("--process-noise", "-0.001"),
        ("--process-noise", "inf"),
        ("--seed", "-1"),
        ("--seed", "1.5"),
        ("--x0", "nan"),
        ("--x0", "one"),
    ],
)
def test_simulate_rejects_bad_option_values(tmp_path, capsys, option, value):
    status, _, err = _cli(capsys, "simulate", "--no-record", "--npz", str(tmp_path / "s.npz"), option, value)
    _assert_usage_error(status, err, option, repr(value))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [["simulate", "--bogus"], ["plugins", "--frobnicate"], ["inspect"], ["nosuchcommand"]])
def test_argparse_errors_are_one_line(capsys, argv):
    status, _, err = _cli(capsys, *argv)
    _assert_usage_error(status, err, "hybridtrack")


SCHEDULES = {
    "not_toml": ("mode = [[[", "Invalid value"),
    "no_segments": ("title = 'x'\n", "no [[segment]] tables"),
    "unknown_mode": ('[[segment]]\nmode = "wobble"\nsteps = 3\n', "unknown motion_model 'wobble'"),
    "negative_steps": ('[[segment]]\nmode = "straight"\nsteps = -2\n', "steps: expected a positive integer, got -2"),
    "text_steps": ('[[segment]]\nmode = "straight"\nsteps = "ten"\n', "steps: expected a positive integer, got 'ten'"),
    "zero_radius": ('[[segment]]\nmode = "left_turn"\nsteps = 3\nradius = 0\n', "radius"),
    "radius_on_ship": ('[[segment]]\nmode = "ship_turn"\nsteps = 3\nradius = 2.0\n', "ship_turn"),
    "missing_mode": ("[[segment]]\nsteps = 3\n", "schedule row 0"),
}


@pytest.mark.parametrize("case", sorted(SCHEDULES))
def test_simulate_rejects_bad_schedules(tmp_path, capsys, case):
    text, expected = SCHEDULES[case]
    schedule = tmp_path / f"{case}.toml"
    schedule.write_text(text)
    status, _, err = _cli(capsys, "simulate", "--schedule", str(schedule), "--no-record", "--npz", str(tmp_path / "s.npz"))
    _assert_usage_error(status, err, str(schedule), expected)
    assert not (tmp_path / "s.npz").exists()


@pytest.mark.parametrize("case", ["missing", "directory", "binary"])
def test_simulate_rejects_unreadable_schedule_files(tmp_path, capsys, case):
    path = tmp_path / "s.toml"
    if case == "directory":
        path.mkdir()
    elif case == "binary":
        path.write_bytes(b"\xff\xfe\x00mode")
    status, _, err = _cli(capsys, "simulate", "--schedule", str(path), "--no-record", "--npz", str(tmp_path / "s.npz"))
    _assert_usage_error(status, err, "--schedule", str(path))


@pytest.mark.parametrize(
    "argv, names",
    [
        (["--x0", "1", "2"], ["--x0", "expected 4 numbers", "x, vx, y, vy"]),
        (["--npz", "{tmp}/missing/s.npz"], ["--npz", "does not exist"]),
        (["--npz", "{tmp}"], ["--npz", "directory"]),
        (["--rrd", "{tmp}/missing/s.rrd"], ["--rrd", "does not exist"]),
        (["--rrd", "{tmp}/same", "--npz", "{tmp}/same"], ["--npz and --rrd"]),
        (["--tau", "1e9"], ["--tau", "does not fit the recording's time axis"]),
        (["--x0", "1e308", "1e308", "1e308", "1e308", "--no-record"], ["--x0", "failed"]),
    ],
)
def test_simulate_rejects_bad_outputs_and_inputs_leaving_nothing(tmp_path, capsys, argv, names):
    (tmp_path / "keep.txt").write_text("untouched")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    defaults = ["--npz", str(tmp_path / "s.npz"), "--rrd", str(tmp_path / "s.rrd")]
    status, _, err = _cli(capsys, "simulate", *defaults, *argv)
    _assert_usage_error(status, err, *names)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"], "no partial output"


def test_a_failed_simulate_keeps_the_previous_outputs(tmp_path, capsys):
    npz = tmp_path / "s.npz"
    npz.write_bytes(b"previous")
    status, _, err = _cli(capsys, "simulate", "--npz", str(npz), "--no-record", "--x0", "1e308", "1e308", "1e308", "1e308")
    _assert_usage_error(status, err, "--x0")
    assert npz.read_bytes() == b"previous" and sorted(p.name for p in tmp_path.iterdir()) == ["s.npz"]


def test_process_noise_for_a_mode_with_its_own_noise_is_an_error(tmp_path, capsys):
    schedule = tmp_path / "ship.toml"
    schedule.write_text('[[segment]]\nmode = "ship_turn"\nsteps = 3\n')
    status, _, err = _cli(capsys, "simulate", "--schedule", str(schedule), "--no-record", "--process-noise", "0.1")
    _assert_usage_error(status, err, "--process-noise", "ship_turn")


def test_npz_with_another_suffix_is_written_where_reported(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, _ = _cli(capsys, "simulate", "--npz", "out.dat", "--no-record")
    assert status == 0 and "→ out.dat" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.dat"]
    assert np.load(tmp_path / "out.dat")["states"].shape == (361, 4)


def test_ship_turn_simulates_and_mixes_with_linear_modes(tmp_path, capsys):
    schedule = tmp_path / "ship.toml"
    schedule.write_text('[[segment]]\nmode = "ship_turn"\nsteps = 4\n\n[[segment]]\nmode = "straight"\nsteps = 2\n')
    npz, rrd = tmp_path / "ship.npz", tmp_path / "ship.rrd"
    status, out, err = _cli(capsys, "simulate", "--schedule", str(schedule), "--no-noise", "--npz", str(npz), "--rrd", str(rrd))
    assert status == 0, err
    assert "ship_turn×4" in out and rrd.stat().st_size > 0
    data = np.load(npz)
    assert tuple(data["layout"]) == ("x", "y", "vx", "vy", "omega")
    np.testing.assert_allclose(data["states"][-1], [0.0, 1.2, 0.0, 2.0, 0.0], atol=1e-12)  # vy = 2 for 6 steps of 0.1 s
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ship.npz", "ship.rrd", "ship.toml"]


@pytest.mark.parametrize("case", ["missing", "directory", "not_a_recording"])
def test_inspect_file_errors_are_one_line_with_status_2(tmp_path, capsys, case):
    path = tmp_path / "r.rrd"
    if case == "directory":
        path.mkdir()
    elif case == "not_a_recording":
        path.write_text("hello")
    status, _, err = _cli(capsys, "inspect", str(path))
    _assert_usage_error(status, err, str(path))


def _script(*argv, **env):
    return subprocess.Popen(
        [str(SCRIPT), *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, **env},
    )


def test_a_closed_pipe_ends_quietly():
    process = _script("plugins")
    process.stdout.close()  # the reader is gone before the command writes (as with `| head` after its lines)
    status = process.wait(timeout=120)
    err = process.stderr.read().decode()
    process.stderr.close()
    assert status == 141 and err == ""


@pytest.mark.parametrize("encoding", ["ascii", "latin-1"])
def test_plugins_on_a_non_utf8_console(encoding):
    process = _script("plugins", PYTHONIOENCODING=encoding)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 0, err.decode(errors="replace")
    assert b"Traceback" not in err and b"straight" in out
