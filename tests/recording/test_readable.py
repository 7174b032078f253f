"""Recordings read at a glance (issue 25, items 4 and 5): modes by name, a legend naming every series (ln λ by its
hypothesis pair), real-data recordings opening on the ``utc`` timeline, the map's need for the internet said in
the layout, and a Monte Carlo summary with its running mean and 95 % band.

Everything is read back from the files (``rerun.chunk.RrdReader``, :class:`RecordingFile`; rerun-sdk 0.41 has no
``rerun.dataframe``), not from the objects that wrote them.
"""

from datetime import UTC, datetime
from types import SimpleNamespace

import numpy as np
import pytest

from hybridtrack import Gaussian, Schedule
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.apps.experiment.recordings import (
    BAND_FROM_RUNS,
    read_summary_recording,
    result_unit,
    running_statistics,
    write_summary_recording,
)
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import MAP_VIEW_NAME, MODE_PANEL_TITLE, RerunRecorder, log_ratio_name, mode_lanes, palette
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack.recording.recorder import log_mode
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
SCHEDULE = Schedule.from_rows([("straight", 20), ("right_turn", 30, 3.0), ("straight", 30)])
EPOCH = datetime(2016, 1, 12, 13, 2, 11, 218000, tzinfo=UTC)


def styles(path) -> dict[str, dict]:
    """Entity path → {"names", "colors", "widths"} of its SeriesLines and "scalars" (rows of its Scalars, in the
    order logged)."""
    import rerun as rr

    found: dict[str, dict] = {}
    for chunk in rr.chunk.RrdReader(str(path)).stream():
        batch = chunk.to_record_batch()
        entry = found.setdefault(chunk.entity_path, {})
        for column, key in (("SeriesLines:names", "names"), ("SeriesLines:colors", "colors"), ("SeriesLines:widths", "widths")):
            if column in batch.schema.names:
                entry[key] = batch.column(column).to_pylist()[-1]
        if "Scalars:scalars" in batch.schema.names:
            entry.setdefault("scalars", []).extend(batch.column("Scalars:scalars").to_pylist())
    return found


def rgba(name: str) -> int:
    return int.from_bytes(bytes([*palette(name), 255]), "big")


@pytest.fixture(scope="module")
def measured():
    sensor = PositionSensor(noise_cov=NOISE)
    truth, z = simulate(SCHEDULE, X0, 0.1, [sensor], seed=1)
    return sensor, truth, z


@pytest.fixture(scope="module")
def unknown(tmp_path_factory, measured):
    sensor, truth, z = measured
    modes = ["straight", ("right_turn", {"radius": 3.0}), ("left_turn", {"radius": 3.0})]
    adaptive = UnknownChangeAdaptive(sensors=[sensor], tau=0.1, modes=modes, alpha=0.05, beta=0.05, bank_size=20)
    path = tmp_path_factory.mktemp("readable") / "unknown.rrd"
    with RerunRecorder(path, {"seed": 1, "algorithm": "unknown"}, epoch=EPOCH) as recorder:
        run = adaptive.run(z, Gaussian(X0, np.eye(4)), recorder=recorder, truth=truth)
    return run, path


@pytest.fixture(scope="module")
def known(tmp_path_factory, measured):
    sensor, truth, z = measured
    adaptive = KnownSwitchAdaptive(sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=4.0, noise_cov=NOISE, alpha=0.1, beta=0.1)
    path = tmp_path_factory.mktemp("readable") / "known.rrd"
    with RerunRecorder(path, {"seed": 1, "algorithm": "known"}) as recorder:
        run = adaptive.run(z, Gaussian(X0, np.eye(4)), SCHEDULE, recorder=recorder, truth=truth)
    return run, path


def test_mode_lanes_give_each_mode_entered_its_own_lane_the_one_of_most_steps_on_top():
    lanes, names = mode_lanes(np.array([0, 2, 2, 2, -1, 0]), ["straight", "left_turn_r3", "right_turn_r5"])
    assert names == ["right_turn_r5", "straight"]  # 3 steps before 2; left_turn_r3 never entered: no lane; −1: in none
    np.testing.assert_array_equal(lanes[:, 0], [np.nan, 1, 1, 1, np.nan, np.nan])  # the first name on the top lane
    np.testing.assert_array_equal(lanes[:, 1], [0, np.nan, np.nan, np.nan, np.nan, 0])
    _, tied = mode_lanes(np.array([1, 0]), ["straight", "stop"])
    assert tied == ["straight", "stop"]  # a tie in the order of the names
    empty, none = mode_lanes(np.full(3, -1), ["straight"])
    assert none == [] and empty.shape == (3, 0)


def test_the_mode_series_are_named_after_the_modes_in_their_colours(unknown):
    run, path = unknown
    entity = "/estimator/unknown_change/mode"
    style = styles(path)[entity]
    held = {name: int(np.count_nonzero(run.mode == j)) for j, name in enumerate(run.modes)}
    entered = sorted((name for name in run.modes if held[name]), key=lambda name: -held[name])
    assert len(entered) >= 2 and style["names"] == entered
    assert style["colors"] == [rgba(name) for name in entered]  # the colours of the mode-coloured 3-D path
    steps, lanes = RecordingFile(path).series(entity)
    for i, name in enumerate(entered):
        in_mode = run.mode[steps] == run.modes.index(name)
        np.testing.assert_array_equal(lanes[in_mode, i], len(entered) - 1 - i)
        assert np.isnan(lanes[~in_mode, i]).all()  # a gap wherever the run is in another mode


def test_log_mode_of_one_mode_is_a_single_named_series(tmp_path):
    run = SimpleNamespace(mode=np.zeros(4, dtype=int), modes=("straight", "stop"), times=np.arange(4) * 0.1)
    with RerunRecorder(tmp_path / "one.rrd") as recorder:
        log_mode(recorder, "kf", np.arange(4), run)
    assert styles(tmp_path / "one.rrd")["/estimator/kf/mode"]["names"] == ["straight"]
    np.testing.assert_array_equal(RecordingFile(tmp_path / "one.rrd").series("estimator/kf/mode")[1], np.zeros(4))


def test_known_switch_ln_lambda_series_name_the_pair_and_the_followed_lanes_the_hypotheses(known):
    run, path = known
    found = styles(path)
    ratios = {e: s for e, s in found.items() if e.startswith("/detector/") and "/log_ratio/" in e}
    assert len(ratios) == len(run.modes)
    for entity, style in ratios.items():
        hypothesis = entity.rsplit("/", 1)[-1]
        assert style["names"] == [log_ratio_name(hypothesis)] == [f"ln λ {hypothesis} : best other"]
    assert found["/detector/sprt_pairwise/upper"]["names"] == ["A (upper)"]
    followed = found["/estimator/known_switch/followed"]["names"]
    assert followed and set(followed) <= set(run.modes)


def test_unknown_change_ln_lambda_is_one_series_per_pair_against_the_mode_of_the_step_before(unknown):
    run, path = unknown
    rec = RecordingFile(path)
    found = styles(path)
    before = np.concatenate([run.mode[:1], run.mode[:-1]])
    checked = 0
    for p, alternative in enumerate(run.modes):
        entity = f"/detector/sprt_unknown_change/log_ratio/{alternative}"
        if entity not in found:
            assert not np.isfinite(run.log_ratios[:, p]).any()
            continue
        names = found[entity]["names"]
        rivals = sorted({int(c) for c in before[np.isfinite(run.log_ratios[:, p])]})
        assert names == [f"ln λ {alternative} : {run.modes[c]}" for c in rivals]
        assert alternative not in [n.split(" : ")[1] for n in names]  # never weighed against itself
        steps, values = rec.series(entity)
        values = values.reshape(len(steps), -1)
        for i, c in enumerate(rivals):
            rows = np.isfinite(run.log_ratios[steps, p]) & (before[steps] == c)
            np.testing.assert_array_equal(values[rows, i], run.log_ratios[steps[rows], p])
            assert np.isnan(values[~rows, i]).all()
        checked += len(rivals)
    assert checked >= 3  # the alternatives of straight, then of the turn


def test_every_time_series_panel_shows_its_legend(known, unknown):
    import rerun as rr

    for _, path in (known, unknown):
        views = [v for v in RecordingFile(path).blueprint_views() if v["class"] == "TimeSeries"]
        reader = rr.chunk.RrdReader(str(path))
        visible = [
            chunk.to_record_batch().column("PlotLegend:visible").to_pylist()[-1]
            for store in reader.blueprints()
            for chunk in reader.stream(store=store)
            if chunk.entity_path.endswith("/PlotLegend")
        ]
        assert len(visible) >= len(views) >= 3 and all(v == [True] for v in visible)
        titles = {v["name"] for v in views}
        assert MODE_PANEL_TITLE in titles


def test_innovations_are_named_by_sensor_and_component(known):
    # the known-switch run records no innovations; a pipeline's are named after the measured components
    from hybridtrack.engine.pipeline import Pipeline

    _, path = known
    sensor = PositionSensor(name="plotter", noise_cov=NOISE)
    truth, z = simulate(Schedule.from_rows([("straight", 10)]), X0, 0.1, [sensor], seed=2)
    out = path.with_name("pipeline.rrd")
    with RerunRecorder(out, {"seed": 2}) as recorder:
        Pipeline(
            models=["straight"],
            estimator="kalman",
            sensors=[sensor],
            measurements=z,
            prior=Gaussian(X0, np.eye(4)),
            tau=0.1,
            recorder=recorder,
        ).run()
    assert styles(out)["/estimator/straight/innovation"]["names"] == ["straight plotter x", "straight plotter y"]


def test_a_recording_with_an_epoch_opens_on_the_utc_timeline_with_step_beside_it(unknown, known):
    run, path = unknown
    rec = RecordingFile(path)
    assert rec.utc_range()[0] == "2016-01-12T13:02:11.218000Z"  # the utc timeline is there …
    assert rec.step_range() == (0, run.steps - 1)  # … beside the step timeline
    assert rec.blueprint_timeline() == "utc"
    assert RecordingFile(known[1]).blueprint_timeline() is None  # no epoch: the viewer's choice (step)
    import rerun as rr

    reader = rr.chunk.RrdReader(str(path))
    trails = [
        chunk.to_record_batch().column("VisibleTimeRanges:ranges").to_pylist()[-1]
        for store in reader.blueprints()
        for chunk in reader.stream(store=store)
        if chunk.entity_path.endswith("/VisibleTimeRanges")
    ]
    assert any({"step", "time", "utc"} <= {r["timeline"] for r in ranges} for ranges in trails)  # the world's trail on utc too


def test_an_epoch_without_times_leaves_the_timeline_to_the_viewer(tmp_path):
    with RerunRecorder(tmp_path / "steps.rrd", epoch=EPOCH) as recorder:
        recorder.log_scalars("estimator/kf/nis", np.arange(3), np.ones(3))  # no times: nothing on utc
    assert RecordingFile(tmp_path / "steps.rrd").blueprint_timeline() is None


def test_the_map_view_says_its_tiles_need_the_internet(tmp_path):
    path = tmp_path / "geo.rrd"
    with RerunRecorder(path, epoch=EPOCH) as recorder:
        recorder.log_geo_path("map/measurements", np.arange(3), np.array([[50.8, -1.3], [50.81, -1.31], [50.82, -1.3]]), np.arange(3.0))
    (view,) = [v for v in RecordingFile(path).blueprint_views() if v["class"] == "Map"]
    assert view["name"] == MAP_VIEW_NAME and "internet" in view["name"] and "offline" in view["name"]
    assert RecordingFile(path).unviewed_entities() == []


def test_running_statistics_are_the_mean_and_the_normal_95_percent_band_of_the_runs_so_far():
    x = np.array([1.0, 2.0, np.nan, 3.0, 4.0, 5.0, 6.0])
    mean, lower, upper = running_statistics(x, start=3)
    np.testing.assert_allclose(mean, [1.0, 1.5, 1.5, 2.0, 2.5, 3.0, 3.5])  # the NaN run is left out
    assert np.isnan(lower[:3]).all() and np.isnan(upper[:3]).all()  # fewer than 3 finite runs: no band
    half = 1.96 * np.std([1.0, 2.0, 3.0, 4.0, 5.0, 6.0], ddof=1) / np.sqrt(6)
    np.testing.assert_allclose([lower[-1], upper[-1]], [3.5 - half, 3.5 + half])
    constant = running_statistics(np.full((8, 2), 720.0))
    np.testing.assert_array_equal(constant[1][-1], [720.0, 720.0])  # s = 0 exactly, no rounding noise


def test_the_summary_recording_has_per_metric_panels_with_units_mean_and_band(tmp_path, rerun_cli):
    rng = np.random.default_rng(0)
    n = 12
    arrays = {"index": np.arange(n), "rmse_known_modes": 0.2 + 0.02 * rng.standard_normal(n), "squared_error": rng.random((n, 2))}
    path = tmp_path / "summary.rrd"
    assert write_summary_recording(arrays, path, {"experiment": "x"}) == []
    assert sorted(read_summary_recording(path)) == ["rmse_known_modes", "squared_error"]  # the results, as before
    found = styles(path)
    assert found["/campaign/rmse_known_modes"]["names"] == ["rmse_known_modes per run (m)"]
    assert found["/statistics/rmse_known_modes"]["names"] == ["running mean (m)", "mean − 1.96 s/√n (m)", "mean + 1.96 s/√n (m)"]
    assert found["/statistics/squared_error"]["names"][:2] == ["running mean[0] (state units²)", "running mean[1] (state units²)"]
    stats = np.array(found["/statistics/rmse_known_modes"]["scalars"], dtype=np.float64)  # one row per run, in run order
    expected = np.column_stack(running_statistics(arrays["rmse_known_modes"]))
    np.testing.assert_array_equal(stats, expected)
    assert np.isnan(stats[: BAND_FROM_RUNS - 1, 1:]).all() and np.isfinite(stats[BAND_FROM_RUNS - 1 :]).all()
    views = RecordingFile(path).blueprint_views()
    (rmse,) = [v for v in views if v["name"].startswith("rmse_known_modes")]
    assert "(m)" in rmse["name"] and "95 % band mean ± 1.96 s/√n" in rmse["name"]
    assert sorted(rmse["contents"]) == ["+ /campaign/rmse_known_modes", "+ /statistics/rmse_known_modes"]
    assert RecordingFile(path).unviewed_entities() == []
    assert rerun_cli("rrd", "verify", path).returncode == 0


def test_result_units_come_from_the_name_or_the_caller():
    assert result_unit("rmse_straight") == "m" and result_unit("position_rmse") == "m"
    assert result_unit("mean_nis") == "no unit" and result_unit("steps") == "steps"
    assert result_unit("nrmse") == "unit not declared"  # mixed m and m/s: not guessed
    assert result_unit("nrmse", {"nrmse": "m"}) == "m"
