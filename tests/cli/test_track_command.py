"""``hybridtrack track``: a configured estimator over every object of a position file (hybridtrack.apps.tracking)."""

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.apps.tracking import ConfigError, load_config, segments_of, track_file
from hybridtrack.cli import main
from hybridtrack.recording.inspection import RecordingFile

ROOT = Path(__file__).resolve().parents[2]
SOLENT = ROOT / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"

CONFIG = """
[reader]
time = "t"
x = "east"
y = "north"
id = "name"
min_reports = 5

[measurement]
sigma = 5.0

[prior]
velocity = "two_fixes"
position_sigma = 50.0
velocity_sigma = 5.0

[estimator]
kind = "{kind}"
process_noise = 0.05
modes = ["straight", "left_turn", "right_turn"]
radii = [200.0, 1000.0]
{extra}
"""
UNKNOWN_CHANGE = "alpha = 0.01\nbeta = 0.01\nbank_size = 20"
IMM = "sojourn = 60.0"

DT, SPEED, RADIUS, STRAIGHT, TURN = 2.0, 10.0, 200.0, 40, 40  # the turn: 80 s of 10 m/s on 200 m = 229° of heading


def leg(direction: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Times and noisy positions: north at SPEED for STRAIGHT steps, then a turn of RADIUS (+1 left, −1 right)."""
    t = np.arange(STRAIGHT + TURN + 1) * DT
    pos = np.zeros((t.size, 2))
    pos[: STRAIGHT + 1, 1] = SPEED * t[: STRAIGHT + 1]
    start = pos[STRAIGHT]
    centre = start + np.array([-direction * RADIUS, 0.0])  # heading north: left centre to the west
    angle = SPEED / RADIUS * (t[STRAIGHT:] - t[STRAIGHT])  # turned so far
    pos[STRAIGHT:] = centre + RADIUS * np.stack([direction * np.cos(angle), np.sin(angle)], axis=1)
    return t, pos + rng.normal(0.0, 5.0, pos.shape)


def write_csv(path: Path) -> Path:
    rng = np.random.default_rng(7)
    rows = ["t,name,east,north"]
    for name, direction in (("port", 1), ("starboard", -1)):
        t, pos = leg(direction, rng)
        rows += [f"{a:.1f},{name},{x:.3f},{y:.3f}" for a, (x, y) in zip(t, pos)]
    rows += ["0.0,short,0.0,0.0", "1.0,short,1.0,0.0"]  # too few reports: skipped
    path.write_text("\n".join(rows) + "\n")
    return path


def write_config(path: Path, kind: str = "unknown_change") -> Path:
    path.write_text(CONFIG.format(kind=kind, extra=UNKNOWN_CHANGE if kind == "unknown_change" else IMM))
    return path


@pytest.mark.parametrize("direction", [1, -1])
def test_synthetic_leg_geometry(direction):
    """The synthetic turn is a circle of RADIUS tangent to the straight leg, turning left (+1) or right (−1)."""
    t, pos = leg(direction, np.random.default_rng(0))
    clean = pos - np.random.default_rng(0).normal(0.0, 5.0, pos.shape)
    v = np.diff(clean, axis=0) / DT
    assert np.allclose(np.linalg.norm(v, axis=1), SPEED, rtol=2e-3)  # chord of a 0.1 rad arc: 0.04 % short
    heading = np.unwrap(np.arctan2(v[:, 1], v[:, 0]))
    assert np.allclose(np.diff(heading[STRAIGHT:]), direction * SPEED / RADIUS * DT)  # ω = v/r, + counter-clockwise


@pytest.mark.parametrize("kind", ["unknown_change", "imm"])
def test_track_writes_outputs_and_finds_the_turn(tmp_path, capsys, rerun_cli, kind):
    csv, cfg, out = write_csv(tmp_path / "legs.csv"), write_config(tmp_path / "c.toml", kind), tmp_path / "out"
    status = main(["track", str(csv), "--config", str(cfg), "--out", str(out), "--no-progress"])
    assert status == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) == {"objects", "skipped", "epoch_utc", "origin", "max_speed", "problem_counts", "problems"}
    assert summary["epoch_utc"] is None and summary["origin"] is None and summary["problems"] == []  # x/y metres, seconds
    assert summary["max_speed"] == {"max_speed": 400.0, "set_by": "default: no [reader] max_speed or object_class, the 'aircraft' class's"}
    assert summary["skipped"] == [{"id": "short", "reason": "2 reports < min_reports 5"}]
    assert [o["id"] for o in summary["objects"]] == ["port", "starboard"]
    t_turn = STRAIGHT * DT
    for obj, expected in zip(summary["objects"], ("left_turn", "right_turn")):
        assert set(obj) == {"id", "output", "segments", "decisions"} and obj["output"] == obj["id"]
        for s in obj["segments"]:
            assert set(s) == {"start", "end", "mode", "radius", "mean_speed", "heading_change", "mean_turn_rate"}
            assert s["mode"] in {"straight", "left_turn", "right_turn"}
            assert (s["radius"] is None) == (s["mode"] == "straight")
            if s["end"] - s["start"] >= 20 * DT:  # the estimate's speed and heading over a long segment
                assert s["mean_speed"] == pytest.approx(SPEED, rel=0.1), s
                assert s["mean_turn_rate"] == pytest.approx(s["heading_change"] / (s["end"] - s["start"]))
        turned = sum(s["heading_change"] for s in obj["segments"])  # 229° of heading, left positive
        assert turned == pytest.approx((1 if expected == "left_turn" else -1) * np.degrees(SPEED / RADIUS * TURN * DT), abs=25.0)
        for d in obj["decisions"]:
            assert set(d) == {"time", "mode"} and isinstance(d["time"], float)
        segs = obj["segments"]
        assert segs[0]["start"] == 0.0 and segs[-1]["end"] == (STRAIGHT + TURN) * DT
        assert all(a["end"] == b["start"] for a, b in zip(segs, segs[1:]))

        # after a warm-up of 10 reports (the IMM's modes are alike while the velocity is uncertain) the straight leg is
        # straight, and most of the turn is identified as a turn in the right direction
        def overlap(mode, a, b, segs=segs):
            return sum(max(0.0, min(s["end"], b) - max(s["start"], a)) for s in segs if s["mode"] == mode)

        assert overlap("straight", 10 * DT, t_turn) > 0.8 * (t_turn - 10 * DT), segs
        turning = overlap(expected, t_turn, t_turn + TURN * DT)
        wrong = overlap(({"left_turn", "right_turn"} - {expected}).pop(), 10 * DT, t_turn + TURN * DT)
        assert turning > 0.6 * TURN * DT and wrong < 0.1 * TURN * DT, segs
        with np.load(out / f"{obj['id']}.npz") as npz:
            assert npz["times"].shape == (STRAIGHT + TURN + 1,)
            assert npz["means"].shape == (STRAIGHT + TURN + 1, 4) and npz["covariances"].shape == (STRAIGHT + TURN + 1, 4, 4)
            assert list(npz["layout"]) == ["x", "vx", "y", "vy"]
            # the per-step modes merge into exactly the summary's segments
            radii = [None if np.isnan(r) else float(r) for r in npz["radii"]]
            base = [{key: seg[key] for key in ("start", "end", "mode", "radius")} for seg in segs]
            assert segments_of(npz["times"], [str(m) for m in npz["modes"]], radii) == base
            assert np.all(np.linalg.eigvalsh(npz["covariances"]) > 0)
        rrd = out / f"{obj['id']}.rrd"
        assert RecordingFile(rrd).application_id == "hybridtrack"
        assert rerun_cli("rrd", "verify", rrd).returncode == 0


def test_id_selects_objects(tmp_path):
    csv, cfg = write_csv(tmp_path / "legs.csv"), write_config(tmp_path / "c.toml")
    summary = track_file(csv, cfg, tmp_path / "out", ids=["starboard"])
    assert [o["id"] for o in summary["objects"]] == ["starboard"] and summary["skipped"] == []
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["starboard.npz", "starboard.rrd", "summary.json"]


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda c: c.replace("[measurement]", "[measurement]\nsigmaa = 3.0"), "unknown key(s) ['sigmaa'] in [measurement]"),
        (lambda c: c.replace('kind = "unknown_change"', 'kind = "kalman_bank"'), "kind = 'kalman_bank'"),
        (lambda c: c.replace('"straight", "left_turn"', '"straight", "zigzag", "left_turn"'), "unknown motion model 'zigzag'"),
        (lambda c: c + "\n[tracker]\n", "unknown section(s) ['tracker']"),
        (lambda c: c.replace("alpha = 0.01", "alpha = 0.7"), "alpha = 0.7"),
        (lambda c: c.replace("alpha = 0.01", "sojourn = 3.0"), "belong to kind 'imm'"),
        (lambda c: c.replace("sigma = 5.0", "sigma = 5.0 5"), "not a valid TOML file"),
        (lambda c: c.replace("process_noise = 0.05", "process_noise = 0.05\nnoise_density = 0.01"), "give one"),
        (lambda c: c.replace("[measurement]", "[measurement]\ntime_jitter = -1.0"), "[measurement] time_jitter = -1.0"),
        (lambda c: c.replace("process_noise = 0.05", "noise_density = -1.0"), "noise_density = -1.0; expected a positive number"),
        (lambda c: c.replace('"straight", "left_turn"', '{name = "stop", noise_density = 0}, "left_turn"'), "modes.noise_density = 0"),
    ],
)
def test_bad_config_is_one_line_and_status_2(tmp_path, capsys, edit, message):
    csv, cfg = write_csv(tmp_path / "legs.csv"), write_config(tmp_path / "c.toml")
    cfg.write_text(edit(cfg.read_text()))
    status = main(["track", str(csv), "--config", str(cfg), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and err.startswith("hybridtrack track: error:"), err
    assert message in err


@pytest.mark.parametrize("which", ["config", "file", "id", "column"])
def test_missing_inputs_are_one_line_and_status_2(tmp_path, capsys, which):
    csv, cfg = write_csv(tmp_path / "legs.csv"), write_config(tmp_path / "c.toml")
    argv = ["track", str(csv), "--config", str(cfg), "--out", str(tmp_path / "out")]
    if which == "config":
        argv[3] = str(tmp_path / "nope.toml")
    elif which == "file":
        argv[1] = str(tmp_path / "nope.csv")
    elif which == "id":
        argv += ["--id", "ghost"]
    else:
        cfg.write_text(cfg.read_text().replace('x = "east"', 'x = "easting"'))
    status = main(argv)
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and err.startswith("hybridtrack track: error:"), err
    assert {"config": "nope.toml", "file": "nope.csv", "id": "'ghost'", "column": "'easting'"}[which] in err


def test_example_configs_load():
    ships = load_config(ROOT / "examples" / "ships_sprt.toml")
    assert ships["measurement"]["sigma"] == 10.0 and ships["reader"]["id"] == "MMSI"
    assert len(ships["estimator"]["modes"]) == 1 + 2 * 3
    aircraft = load_config(ROOT / "examples" / "aircraft.toml")
    assert aircraft["estimator"]["algorithm"] == "imm"
    turn_rate = load_config(ROOT / "examples" / "ships_turn_rate.toml")
    assert [name for name, _ in turn_rate["estimator"]["modes"]] == ["straight", "coordinated_turn", "stop"]
    assert ships["estimator"]["noise_density"] == turn_rate["estimator"]["noise_density"] == 0.001


@pytest.mark.slow
def test_first_three_solent_vessels_with_the_ships_config(tmp_path):
    from hybridtrack.io.track_files import SOLENT_AIS, read_tracks

    ids = list(read_tracks(SOLENT, **SOLENT_AIS, warn=False).tracks)[:3]
    summary = track_file(SOLENT, ROOT / "examples" / "ships.toml", tmp_path, ids=ids)
    assert [o["id"] for o in summary["objects"]] == ids
    assert summary["epoch_utc"] == "2016-01-12T13:02:11.218000Z", summary["epoch_utc"]  # the file's earliest time stamp
    assert summary["origin"]["lat"] == pytest.approx(50.8, abs=0.2) and summary["origin"]["lon"] == pytest.approx(-1.3, abs=0.3)
    assert summary["problems"] and all(
        p["action"] in {"dropped", "flagged", "set_nan", "sorted"} and p["message"] for p in summary["problems"]
    )
    for obj in summary["objects"]:
        segs = obj["segments"]
        assert segs[0]["start"] < segs[-1]["end"] and all(a["end"] == b["start"] for a, b in zip(segs, segs[1:]))
        first = segs[0]
        assert first["start_utc"] == (
            datetime(2016, 1, 12, 13, 2, 11, 218000, tzinfo=UTC) + timedelta(seconds=first["start"])
        ).isoformat().replace("+00:00", "Z")
        with np.load(tmp_path / f"{obj['id']}.npz") as npz:
            assert np.all(np.isfinite(npz["means"]))
            assert npz["lat_lon"].shape == (npz["times"].size, 2)
            assert np.max(np.abs(npz["lat_lon"][:, 0] - 50.8)) < 0.3  # the estimate in degrees, in the Solent
        recording = RecordingFile(tmp_path / f"{obj['id']}.rrd")
        utc = recording.utc_range()
        assert utc[0] == first["start_utc"] and utc[1] == segs[-1]["end_utc"], (utc, first["start_utc"], segs[-1]["end_utc"])


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ('kind = "unknown_change"', 'algorithm = "unknown_change"'),
        ('kind = "imm"\nmethod = "gpb2"', 'algorithm = "gpb2"'),
        ('kind = "imm"', 'algorithm = "imm"\nparameters = {missing_variance = 1.0}'),
    ],
)
def test_the_older_kind_spelling_reads_the_same_as_the_algorithm_name(tmp_path, old, new):
    csv = write_csv(tmp_path / "legs.csv")
    kind = "unknown_change" if "unknown_change" in old else "imm"
    outputs = {}
    for which, line in (("old", old), ("new", new)):
        cfg = write_config(tmp_path / f"{which}.toml", kind)
        cfg.write_text(cfg.read_text().replace(f'kind = "{kind}"', line))
        outputs[which] = (track_file(csv, cfg, tmp_path / which, ids=["starboard"]), np.load(tmp_path / which / "starboard.npz"))
    (old_summary, old_npz), (new_summary, new_npz) = outputs["old"], outputs["new"]
    assert old_summary == new_summary
    for key in ("times", "means", "covariances", "radii"):
        np.testing.assert_array_equal(old_npz[key], new_npz[key])
    assert load_config(tmp_path / "new.toml")["estimator"]["algorithm"] == load_config(tmp_path / "old.toml")["estimator"]["algorithm"]


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda c: c.replace('kind = "unknown_change"', 'algorithm = "ukf"'), "algorithm = 'ukf'; expected a registered algorithm"),
        (lambda c: c.replace('kind = "unknown_change"', 'kind = "imm"\nalgorithm = "imm"'), "required, once"),
        (lambda c: c.replace("alpha = 0.01", 'method = "gpb1"'), "belong to kind 'imm'"),
        (
            lambda c: (
                c.replace('kind = "unknown_change"', 'algorithm = "gpb1"\nmethod = "imm"')
                .replace("alpha = 0.01\n", "")
                .replace("beta = 0.01\n", "")
                .replace("bank_size = 20", "")
            ),
            "method = 'imm'",
        ),
        (lambda c: c.replace("alpha = 0.01", "parameters = {modes = []}"), "parameters = {'modes': []}"),
        (lambda c: c.replace("alpha = 0.01", "parameters = {pruning = 3}"), "[estimator] algorithm 'unknown_change': pruning: expected"),
        (lambda c: c.replace("alpha = 0.01", 'parameters = {prunning = "oldest"}'), "unexpected keyword argument 'prunning'"),
    ],
)
def test_bad_algorithm_settings_are_config_errors(tmp_path, edit, message):
    csv, cfg = write_csv(tmp_path / "legs.csv"), write_config(tmp_path / "c.toml")
    cfg.write_text(edit(cfg.read_text()))
    with pytest.raises(ConfigError) as info:
        track_file(csv, cfg, tmp_path / "out", ids=["starboard"])
    assert message in str(info.value)


def test_turn_rate_mode_names_the_turn_by_the_sign_of_omega(tmp_path):
    """An IMM of straight and coordinated_turn (ω in the state, noise per second): the steps of the turn are a
    left turn for the port leg and a right turn for the starboard leg (the sign of the estimated ω)."""
    csv, cfg = write_csv(tmp_path / "legs.csv"), write_config(tmp_path / "c.toml", "imm")
    text = cfg.read_text().replace("process_noise = 0.05", "noise_density = 0.01").replace("radii = [200.0, 1000.0]\n", "")
    text = text.replace(
        'modes = ["straight", "left_turn", "right_turn"]', 'modes = ["straight", {name = "coordinated_turn", noise_density = 0.01}]'
    )
    cfg.write_text(text + "parameters = {missing_variance = {omega = 1e-3}}\n")
    summary = track_file(csv, cfg, tmp_path / "out")
    t_turn = STRAIGHT * DT
    for obj, expected in zip(summary["objects"], ("left_turn", "right_turn")):
        turning = sum(
            max(0.0, min(s["end"], t_turn + TURN * DT) - max(s["start"], t_turn + 10 * DT))
            for s in obj["segments"]
            if s["mode"] == expected
        )
        assert turning > 0.8 * (TURN - 10) * DT, obj["segments"]
        assert all(s["radius"] is None for s in obj["segments"])
        with np.load(tmp_path / "out" / f"{obj['id']}.npz") as npz:
            assert list(npz["layout"]) == ["x", "vx", "y", "vy", "omega"]
            omega = npz["means"][STRAIGHT + 10 :, 4]
            assert np.median(omega) == pytest.approx((1 if expected == "left_turn" else -1) * SPEED / RADIUS, rel=0.2)


def test_smooth_and_lag_give_the_smoothed_imm_run(tmp_path, capsys):
    """``--smooth`` (fixed interval) and ``--lag`` (fixed lag) on the IMM: the turn is found at least as well as by
    the causal run, the recording holds both, and a lag longer than the file equals ``--smooth``."""
    csv, cfg = write_csv(tmp_path / "legs.csv"), write_config(tmp_path / "c.toml", "imm")
    outputs = {}
    for label, extra in (("causal", []), ("smooth", ["--smooth"]), ("lag", ["--lag", "1000"])):
        out = tmp_path / label
        assert main(["track", str(csv), "--config", str(cfg), "--out", str(out), "--no-progress"] + extra) == 0, capsys.readouterr().err
        outputs[label] = json.loads((out / "summary.json").read_text())
    t_turn = STRAIGHT * DT

    def turning(summary, expected):
        obj = next(o for o in summary["objects"] if o["id"] == {"left_turn": "port", "right_turn": "starboard"}[expected])
        return sum(max(0.0, min(s["end"], t_turn + TURN * DT) - max(s["start"], t_turn)) for s in obj["segments"] if s["mode"] == expected)

    for expected in ("left_turn", "right_turn"):
        assert turning(outputs["smooth"], expected) >= turning(outputs["causal"], expected)
    assert outputs["lag"] == outputs["smooth"]
    entities = RecordingFile(tmp_path / "smooth" / "port.rrd").entity_paths
    assert "/world/estimate/track_smoothed" in entities and "/world/estimate/track" in entities, entities


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--smooth"], "has no smoother"),
        (["--lag", "-5"], "--lag -5.0: expected a number of seconds"),
        (["--smooth", "--lag", "3"], "not allowed with"),
    ],
)
def test_smoothing_errors_are_one_line_and_status_2(tmp_path, capsys, extra, message):
    csv, cfg = write_csv(tmp_path / "legs.csv"), write_config(tmp_path / "c.toml")  # unknown_change: no smoother
    if "-5" in extra:
        cfg = write_config(tmp_path / "c.toml", "imm")
    status = main(["track", str(csv), "--config", str(cfg), "--out", str(tmp_path / "out")] + extra)
    err = capsys.readouterr().err
    assert status == 2 and message in err, err


@pytest.mark.parametrize("name", sorted(p.name for p in (ROOT / "examples").glob("*.toml")))
def test_a_checked_configuration_is_checked_again_unchanged(name):
    """load_config takes its own result (a user composing in Python passes it on): checking it again gives it back."""
    checked = load_config(ROOT / "examples" / name)
    assert load_config(checked) == checked


def test_track_file_takes_the_checked_configuration(tmp_path):
    """track_file(path, load_config(...)) tracks as track_file(path, the TOML file) does (the same summary)."""
    config = ROOT / "examples" / "ships.toml"
    first = ["235007473"]
    from_file = track_file(SOLENT, config, tmp_path / "file", ids=first)
    from_dict = track_file(SOLENT, load_config(config), tmp_path / "dict", ids=first)
    assert from_dict["objects"] == from_file["objects"]
