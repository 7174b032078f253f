"""``hybridtrack track`` on hostile position files: every dropped row reported, no empty success, one bad object
never sinks a file (issue 24; :mod:`hybridtrack.apps.tracking`, :mod:`hybridtrack.io.track_files`)."""

import json
import re

import numpy as np
import pytest

import hybridtrack.apps.tracking as tracking
from hybridtrack.cli import main

CONFIG = """
[reader]
id = "id"
{reader}
[measurement]
sigma = 10.0

[estimator]
algorithm = "imm"
noise_density = 0.01
modes = ["straight", {{name = "coordinated_turn"}}]
sojourn = 120.0
"""


def straight_rows(name: str, count: int = 30, step: float = 10.0, speed: float = 5.0, y: float = 0.0) -> list[str]:
    return [f"{k * step:g},{name},{k * step * speed:g},{y:g}" for k in range(count)]


def run_track(tmp_path, rows, *options, reader="", header="time,id,x,y"):
    csv, cfg, out = tmp_path / "f.csv", tmp_path / "c.toml", tmp_path / "out"
    csv.write_text("\n".join([header, *rows]) + "\n")
    cfg.write_text(CONFIG.format(reader=reader))
    status = main(["track", str(csv), "--config", str(cfg), "--out", str(out), "--no-progress", *options])
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else None
    return status, summary, out


# one bad row of each kind, in an otherwise good object 'a' (line numbers: the header is line 1)
BAD_ROWS = {
    "bad_time": ("noon,a,1,1", "column 'time' holds 'noon'"),
    "not_a_number": ("3.5,a,abc,1", "column 'x' holds 'abc'"),
    "out_of_range": ("3.5,a,1e202,1", "farther than 1e+09 m"),
    "duplicate_time": ("20,a,100,0", "repeats line"),
    "conflicting_duplicate": ("20,a,1100,0", "different positions"),
    "speed_jump": ("25,a,5000000000,0", "max_speed 400 m/s"),
    "bad_row": ("25,a,1", "the header has 4"),
    "missing_id": ("25,,1,1", "column 'id' is empty"),
}


@pytest.mark.parametrize("kind", sorted(BAD_ROWS))
def test_each_bad_row_is_printed_and_written(tmp_path, capsys, kind):
    row, text = BAD_ROWS[kind]
    if kind == "speed_jump":  # the jump check of an x/y file: positions within 10⁹ m, far beyond the speed limit
        row = "25,a,900000000,0"
    rows = straight_rows("a")
    rows.insert(5, row)
    status, summary, _ = run_track(tmp_path, rows)
    err = capsys.readouterr().err
    assert status == 0, err
    assert kind in summary["problem_counts"] and any(p["kind"] == kind for p in summary["problems"])
    line = f"  {summary['problem_counts'][kind]} {kind} ("
    assert line in err and "f.csv:7" in err and (text in err or kind == "speed_jump"), err
    assert "speed limit 400 m/s" in err and summary["max_speed"]["max_speed"] == 400.0
    assert [o["id"] for o in summary["objects"]] == ["a"]


def test_strict_turns_a_problem_into_status_2(tmp_path, capsys):
    rows = straight_rows("a")
    rows.insert(5, "noon,a,1,1")
    status, summary, _ = run_track(tmp_path, rows, "--strict")
    err = capsys.readouterr().err
    assert status == 2 and summary is None and err.count("\n") == 1
    assert "--strict" in err and "1 bad_time" in err and "f.csv:7" in err


def test_conflicting_duplicates_are_refused_not_resolved_by_order(tmp_path):
    rows = straight_rows("a")
    rows.insert(3, "20,a,1100,0")  # time 20 is also line 4 (x = 100): 1 km apart
    _, summary, out = run_track(tmp_path, rows)
    conflicts = [p for p in summary["problems"] if p["kind"] == "conflicting_duplicate"]
    assert sorted(p["line"] for p in conflicts) == [4, 5]
    with np.load(out / "a.npz") as npz:
        assert 20.0 not in npz["times"] and len(npz["times"]) == 29


def test_a_fix_far_off_is_dropped_by_the_default_speed_limit(tmp_path, capsys):
    rows = straight_rows("a", speed=5.0)
    rows[10] = "100,a,5000000,0"  # 5,000 km off, within the 10⁹ m of a position
    status, summary, _ = run_track(tmp_path, rows)
    assert status == 0
    assert [p["line"] for p in summary["problems"] if p["kind"] == "speed_jump"] == [12]
    assert [s["mode"] for s in summary["objects"][0]["segments"]] == ["straight"]


@pytest.mark.parametrize(
    "rows, header, reader, message",
    [
        (
            [f"12/01/2016 13:00:{k:02d},a,{k * 5},0" for k in range(30)],
            "time,id,x,y",
            "",
            r"no report left of 30 data rows \(30 bad_time\).*column 'time' holds '12/01/2016 13:00:00'.*time_format",
        ),
        (
            [f"{k},a,-122.4,{37.8 + k * 1e-4}" for k in range(30)],
            "time,id,lat,lon",
            'lat = "lat"\nlon = "lon"',
            r"no report left of 30 data rows \(30 out_of_range\).*latitude and longitude swapped",
        ),
        (
            [f"{1452603731218 + 1000 * k},a,{k * 5},0" for k in range(30)],
            "time,id,x,y",
            "",
            r"f.csv:2: column 'time' holds 1452603731218.*time_unit = 'ms'",
        ),
    ],
    ids=["day-month-year", "lat-lon-swapped", "milliseconds"],
)
def test_no_report_left_is_status_2_naming_the_column(tmp_path, capsys, rows, header, reader, message):
    status, summary, _ = run_track(tmp_path, rows, reader=reader, header=header)
    err = capsys.readouterr().err
    assert status == 2 and summary is None and err.count("\n") == 1
    assert re.search(message, err), err


def test_day_month_year_tracks_with_time_format(tmp_path, capsys):
    rows = [f"12/01/2016 13:{k // 6:02d}:{k % 6 * 10:02d},a,{k * 50},0" for k in range(30)]
    status, summary, _ = run_track(tmp_path, rows, reader='time_format = "%d/%m/%Y %H:%M:%S"')
    assert status == 0 and summary["epoch_utc"] == "2016-01-12T13:00:00Z"
    assert summary["objects"][0]["segments"][0]["end_utc"] == "2016-01-12T13:04:50Z"


def test_an_object_with_every_row_dropped_is_listed(tmp_path):
    rows = straight_rows("a") + [f"{k},b,1e300,0" for k in range(30)]
    status, summary, _ = run_track(tmp_path, rows)
    assert status == 0 and [o["id"] for o in summary["objects"]] == ["a"]
    (entry,) = summary["skipped"]
    assert entry["id"] == "b" and "every row dropped" in entry["reason"] and "30 out_of_range" in entry["reason"]


def test_one_failing_object_never_sinks_the_file(tmp_path, capsys, monkeypatch):
    real = tracking.track_one

    def poisoned(track, config, out, *args, **kwargs):
        if track.id == "p":
            (out / "p.rrd").write_bytes(b"partial")  # a recording begun, then the failure
            raise FloatingPointError("the filter's covariance is not finite")
        return real(track, config, out, *args, **kwargs)

    monkeypatch.setattr(tracking, "track_one", poisoned)
    rows = straight_rows("a") + straight_rows("p", y=500.0) + straight_rows("c", y=1000.0)
    status, summary, out = run_track(tmp_path, rows)
    captured = capsys.readouterr()
    assert status == 1 and "tracked 2 object(s), skipped 1 (1 failed)" in captured.out
    assert [o["id"] for o in summary["objects"]] == ["a", "c"] and (out / "a.rrd").exists() and (out / "c.npz").exists()
    (entry,) = summary["skipped"]
    assert entry["failed"] is True and entry["id"] == "p"
    assert "f.csv: object 'p' (lines 32–61): tracking failed: FloatingPointError: the filter's covariance is not finite" in entry["reason"]
    assert entry["reason"] in captured.err
    assert not (out / "p.rrd").exists() and not (out / "p.npz").exists()


def test_an_estimate_that_is_not_finite_fails_that_object_only(tmp_path, capsys, monkeypatch):
    """A filter that returns NaN (without raising) for one object: that object failed, naming the report."""
    real = tracking.build_tracker

    def nan_for_b(config, registry=None):
        estimator, sensor, models = real(config, registry)
        run_batch = estimator.run_batch

        def patched(measurements, prior, times, **kwargs):  # the objects of the file, one batch
            results = run_batch(measurements, prior, times=times, **kwargs)
            for result in results:
                if result.times[0] == 1000.0:  # object 'b'
                    result.means[7:] = np.nan
            return results

        monkeypatch.setattr(estimator, "run_batch", patched)
        return estimator, sensor, models

    monkeypatch.setattr(tracking, "build_tracker", nan_for_b)
    rows = straight_rows("a") + [f"{1000 + k * 10},b,{k * 50},0" for k in range(30)]
    status, summary, out = run_track(tmp_path, rows)
    assert status == 1 and [o["id"] for o in summary["objects"]] == ["a"]
    (entry,) = summary["skipped"]
    assert entry["failed"] and "object 'b' (lines 32–61)" in entry["reason"]
    assert "the estimate is not finite from the report of line 39 (t = 1070 s) on" in entry["reason"], entry
    assert not (out / "b.npz").exists()


def test_a_batch_that_raises_runs_each_object_alone_and_fails_only_the_culprit(tmp_path, capsys, monkeypatch):
    """The objects of a file run as one batch; when that batch raises, every object runs alone, and only the one whose
    own run raises is failed (the others are tracked as they would be in the batch)."""
    real = tracking.build_tracker

    def raise_for_b(config, registry=None):
        estimator, sensor, models = real(config, registry)
        run_batch = estimator.run_batch

        def patched(measurements, prior, times, **kwargs):
            if any(t[0] == 1000.0 for t in np.atleast_2d(times)):  # a batch (or the run alone) holding object 'b'
                raise np.linalg.LinAlgError("Matrix is not positive definite")
            return run_batch(measurements, prior, times=times, **kwargs)

        monkeypatch.setattr(estimator, "run_batch", patched)
        return estimator, sensor, models

    monkeypatch.setattr(tracking, "build_tracker", raise_for_b)
    rows = straight_rows("a") + [f"{1000 + k * 10},b,{k * 50},0" for k in range(30)]
    status, summary, out = run_track(tmp_path, rows)
    assert status == 1 and [o["id"] for o in summary["objects"]] == ["a"] and (out / "a.npz").exists()
    (entry,) = summary["skipped"]
    assert entry["failed"] and "object 'b' (lines 32–61): tracking failed: LinAlgError: Matrix is not positive definite" in entry["reason"]


def test_no_object_tracked_is_status_2_not_an_empty_success(tmp_path, capsys):
    status, summary, _ = run_track(tmp_path, ["0,a,0,0", "10,a,50,0", "0,b,0,0"])
    err = capsys.readouterr().err
    assert status == 2 and "no object tracked, every one skipped" in err and "'a': 2 reports < min_reports 3" in err
    assert [entry["id"] for entry in summary["skipped"]] == ["a", "b"]  # the summary says why
