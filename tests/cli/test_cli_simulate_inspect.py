"""``hybridtrack simulate`` and ``hybridtrack inspect``, in process."""

import json

import numpy as np

from hybridtrack.cli import main


def test_simulate_builtin_table_then_inspect(tmp_path, capsys, rerun_cli):
    npz, rrd = tmp_path / "s.npz", tmp_path / "s.rrd"
    assert main(["simulate", "--npz", str(npz), "--rrd", str(rrd), "--seed", "4"]) == 0
    assert "simulated 360 steps" in capsys.readouterr().out
    data = np.load(npz)
    assert data["states"].shape == (361, 4) and data["z_sensor"].shape == (361, 2)
    assert list(data["schedule_mode"]) == ["left_turn", "right_turn", "straight", "left_turn", "straight", "left_turn"]
    assert rerun_cli("rrd", "verify", rrd).returncode == 0

    assert main(["inspect", str(rrd), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["application_id"] == "hybridtrack" and summary["step_range"] == [0, 360]
    assert {"/world/truth", "/world/measurements/sensor"} <= set(summary["entity_paths"])
    assert summary["configuration"]["seed"] == 4
    assert main(["inspect", str(rrd)]) == 0
    assert "recording id:" in capsys.readouterr().out


def test_simulate_toml_schedule_noise_free_without_recording(tmp_path, capsys):
    schedule = tmp_path / "s.toml"
    schedule.write_text('[[segment]]\nmode = "straight"\nsteps = 5\n\n[[segment]]\nmode = "stop"\nsteps = 2\n')
    npz = tmp_path / "s.npz"
    assert (
        main(
            [
                "simulate",
                "--schedule",
                str(schedule),
                "--no-noise",
                "--no-record",
                "--x0",
                "0",
                "1",
                "0",
                "0",
                "--npz",
                str(npz),
                "--rrd",
                str(tmp_path / "none.rrd"),
            ]
        )
        == 0
    )
    states = np.load(npz)["states"]
    np.testing.assert_allclose(states[-1], [0.5, 0, 0, 0], atol=1e-12)
    assert not (tmp_path / "none.rrd").exists()


def test_inspect_missing_file_fails_cleanly(tmp_path, capsys):
    assert main(["inspect", str(tmp_path / "nope.rrd")]) == 2
    assert "no such recording" in capsys.readouterr().err
