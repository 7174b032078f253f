"""A bank's hypotheses fan out of each switch (issue #16): each hypothesis's estimate is recorded while in play,
NaN elsewhere, in the world view and in the space-time view, in its palette colour."""

import numpy as np
import pytest

from hybridtrack import Gaussian, Schedule
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import RerunRecorder, finite_runs, is_hypothesis, palette, spatial_style
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
SCHEDULE = Schedule.from_rows([("straight", 20), ("right_turn", 30, 3.0), ("straight", 30)])


@pytest.fixture(scope="module")
def known(tmp_path_factory):
    sensor = PositionSensor(noise_cov=NOISE)
    truth, z = simulate(SCHEDULE, X0, 0.1, [sensor], seed=1)
    adaptive = KnownSwitchAdaptive(sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=4.0, noise_cov=NOISE, alpha=0.1, beta=0.1)
    path = tmp_path_factory.mktemp("fan") / "known.rrd"
    with RerunRecorder(path, {"seed": 1}) as recorder:
        run = adaptive.run(z, Gaussian(X0, np.eye(4)), SCHEDULE, recorder=recorder, truth=truth)
    return adaptive, run, path, sensor, z


def test_hypotheses_start_at_the_switch_and_stop_when_eliminated_or_decided(known):
    adaptive, run, _, sensor, z = known
    fan = run.hypothesis_positions
    H = len(run.modes)
    xy = [run.layout.index("x"), run.layout.index("y")]
    assert fan.shape == (SCHEDULE.total_steps + 1, H, 2)
    for segment in run.segments:
        s = segment.start
        np.testing.assert_array_equal(fan[s], np.tile(run.means[s, xy], (H, 1)))  # all from the estimate
        end = s + segment.steps
        if segment.decision_step is not None:
            assert np.isnan(fan[segment.decision_step + 1 : end]).all()  # none after the decision (the next switch is at end)
            assert np.isfinite(fan[segment.decision_step, segment.index]).all()  # the decided one drawn up to its decision
            end = segment.decision_step
        # in play ⇔ ln λ logged (finite): the same steps, between the switch and the decision
        inner = slice(s + 1, end)
        np.testing.assert_array_equal(np.isfinite(fan[inner, :, 0]), np.isfinite(run.log_ratios[inner]))
    assert any(seg.decision_step is not None for seg in run.segments)
    # without a recorder nothing is collected
    assert adaptive.run(z, Gaussian(X0, np.eye(4)), SCHEDULE).hypothesis_positions is None


def test_the_fan_is_recorded_in_both_views_in_the_hypothesis_colours_without_joining_gaps(known):
    _, run, path, _, _ = known
    rec = RecordingFile(path)
    assert rec.unviewed_entities() == []
    name = run.modes[1]
    entity = f"/world/estimate/known_switch/hypotheses/{name}"
    assert entity in rec.entity_paths and f"/spacetime/estimate/known_switch/hypotheses/{name}" in rec.entity_paths
    steps, points = rec.points(entity)
    finite = np.isfinite(run.hypothesis_positions[:, 1, 0])
    np.testing.assert_array_equal(steps, np.flatnonzero(finite))
    np.testing.assert_allclose(points, run.hypothesis_positions[finite, 1], rtol=1e-6, atol=1e-6)
    import rerun as rr

    static = {c.entity_path: c.to_record_batch() for c in rr.chunk.RrdReader(str(path)).stream()}
    for view in ("world", "spacetime"):
        key = f"/{view}/estimate/known_switch/hypotheses/{name}" + ("/path" if view == "world" else "")
        strips = static[key].column("LineStrips3D:strips").to_pylist()[0]
        assert len(strips) == len(finite_runs(finite)) > 1, view  # one piece per period in play: no line joins them
    assert spatial_style(entity) == (palette(name), name) and is_hypothesis(entity) and not is_hypothesis("world/estimate/a")


def test_unknown_change_records_each_alternatives_most_likely_filter(tmp_path):
    sensor = PositionSensor(noise_cov=NOISE)
    schedule = Schedule.from_rows([("straight", 10), ("right_turn", 15, 5.0)])
    truth, z = simulate(schedule, X0, 0.1, [sensor], seed=2)
    modes = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
    adaptive = UnknownChangeAdaptive(modes=modes, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1)
    with RerunRecorder(tmp_path / "u.rrd") as recorder:
        run = adaptive.run(z, Gaussian(X0, np.eye(4)), recorder=recorder, truth=truth)
    fan = run.hypothesis_positions
    assert np.isnan(fan[0]).all() and np.isnan(fan[1:, 0]).sum() > 0  # the current mode is the estimate itself
    assert np.isfinite(fan[1:11, 1:]).all()  # straight is current until the change: both turns in play
    # a new alternative starts from filter 0 after one step: near the estimate at first
    assert np.linalg.norm(fan[1, 1] - run.means[1, [run.layout.index("x"), run.layout.index("y")]]) < 1.0
    rec = RecordingFile(tmp_path / "u.rrd")
    assert rec.unviewed_entities() == []
    assert "/spacetime/estimate/unknown_change/hypotheses/right_turn_r5" in rec.entity_paths


def test_space_time_labels_only_the_decisions_briefly_and_the_map_zoom_fits_the_paths():
    from hybridtrack.recording import map_zoom, short_decision

    assert short_decision("sprt_pairwise: left_turn_r3 accepted with margin 4.76 (A = 4.60)") == "left_turn_r3 accepted"
    assert short_decision("sprt_unknown_change: change to right_turn_r5 (most likely at step 20), ln λ = 2.20") == "change to right_turn_r5"
    assert short_decision("sprt_unknown_change: no change: every ln λ ≤ B = -2.20; the test restarts") == "no change"
    assert short_decision("n_bearings: x0=-40.5 m y0=8174.9 m") == "n_bearings"
    # 0.2° of longitude at the equator in 700 px: 360 · 3500 / 256 = 2^12.27 → 12.27 − 0.5 margin (latitude not binding)
    assert map_zoom(np.array([[0.0, 0.0], [0.001, 0.2]])) == pytest.approx(np.log2(360 * 3500 / 256) - 0.5)
