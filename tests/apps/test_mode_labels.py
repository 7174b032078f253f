"""Mode labels from course/speed over ground: signs, radii, stops, hysteresis, and a check on the Solent AIS data."""

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.apps.mode_labels import DEFAULTS, label_modes, label_track, turn_rate
from hybridtrack.io.track_files import SOLENT_AIS, Track, read_tracks

SOLENT = Path(__file__).resolve().parents[2] / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"

# (duration s, turn rate °/s counter-clockwise, speed m/s or "decel"/"accel")
PHASES = [(120, 0, 5), (30, 3, 5), (120, 0, 5), (45, -2, 5), (120, 0, 5), (20, 0, "decel"), (90, 0, 0), (20, 0, "accel"), (60, 0, 5)]
EDGES = np.cumsum([0] + [p[0] for p in PHASES])


def synthetic(seed=1):
    """A track with a known left turn (3°/s), right turn (2°/s) and stop; irregular sampling 1.5–2.5 s.

    Returns times, compass course, speed and the east-north positions integrated from the heading."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(np.r_[0, rng.uniform(1.5, 2.5, 400)])
    t = t[t < EDGES[-1]]
    heading = np.zeros_like(t)  # counter-clockwise from east, degrees
    speed = np.zeros_like(t)
    h0 = 0.0
    for (duration, rate, v), a, b in zip(PHASES, EDGES[:-1], EDGES[1:]):
        m = (t >= a) & (t < b)
        heading[m] = h0 + rate * (t[m] - a)
        ramp = (t[m] - a) / duration
        speed[m] = 5 * (1 - ramp) if v == "decel" else 5 * ramp if v == "accel" else v
        h0 += rate * duration
    course = (90.0 - heading) % 360.0  # compass: clockwise from north
    step = np.diff(t, prepend=t[0])
    positions = np.cumsum(np.stack([speed * np.cos(np.radians(heading)), speed * np.sin(np.radians(heading))], 1) * step[:, None], 0)
    return t, course, speed, positions


def test_left_turn_right_turn_and_stop_are_recovered():
    t, course, speed, positions = synthetic()
    labels = label_modes(t, course, speed)
    modes = [s["mode"] for s in labels.segments]
    assert modes == ["straight", "left_turn", "straight", "right_turn", "straight", "stop", "straight"]
    left, right = labels.segments[1], labels.segments[3]
    # r = v/|ω|: 5 m/s at 3°/s and at 2°/s
    assert left["radius"] == pytest.approx(5 / math.radians(3), rel=1e-6)
    assert right["radius"] == pytest.approx(5 / math.radians(2), rel=1e-6)
    assert left["turn_rate"] > 0 > right["turn_rate"]  # counter-clockwise positive
    assert all(s["radius"] is None for s in labels.segments if s["mode"] in ("straight", "stop"))
    # boundaries within half a window (the smoothing blur) plus a sampling step of the truth
    tol = DEFAULTS["window"] / 2 + 2.5
    for segment, (a, b) in zip((left, right), ((EDGES[1], EDGES[2]), (EDGES[3], EDGES[4]))):
        assert abs(segment["start"] - a) <= tol and abs(segment["end"] - b) <= tol
    stop = labels.segments[5]
    assert EDGES[5] <= stop["start"] <= EDGES[6] + tol and EDGES[6] <= stop["end"] <= EDGES[7] + tol
    # the segments tile the track and the per-report modes follow them
    assert labels.segments[0]["start"] == t[0] and labels.segments[-1]["end"] == t[-1]
    assert all(a["end"] == b["start"] for a, b in zip(labels.segments, labels.segments[1:]))
    assert len(labels.modes) == len(t) and labels.modes[labels.segments[1]["first"]] == "left_turn"


def test_left_is_counter_clockwise_in_the_east_north_frame():
    """Independent of the labeller's formula: the positions of the 'left_turn' segment curve counter-clockwise."""
    t, course, speed, positions = synthetic()
    labels = label_modes(t, course, speed)
    for segment in labels.segments:
        if segment["mode"] in ("left_turn", "right_turn"):
            p = positions[segment["first"] : segment["last"] + 1]
            d = np.diff(p, axis=0)
            cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]
            assert np.sign(cross.sum()) == (1 if segment["mode"] == "left_turn" else -1)
    # a decreasing compass course is a left turn: 10°, 8°, 6° … through north (wrapping to 358°)
    t = np.arange(0.0, 60.0, 2.0)
    omega = turn_rate(t, (10.0 - t) % 360.0, window=10.0)
    np.testing.assert_allclose(omega, math.radians(1.0))


def test_hysteresis_keeps_a_noisy_turn_in_one_segment():
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 600.0, 2.0)
    rate = 0.45  # °/s clockwise (right), between omega_off and omega_on of the parameters below
    course = (350.0 + rate * t + rng.normal(0.0, 1.5, t.size)) % 360.0  # through north
    speed = np.full_like(t, 6.0)
    on, off = math.radians(0.4), math.radians(0.15)
    calm = label_modes(t, course, speed, window=20.0, omega_on=on, omega_off=off, min_duration=0.0)
    assert [s["mode"] for s in calm.segments] == ["right_turn"]
    assert calm.segments[0]["radius"] == pytest.approx(6.0 / math.radians(rate), rel=0.01)
    # one threshold (omega_off = omega_on) and no minimum length: the same data chatter
    chatter = label_modes(t, course, speed, window=20.0, omega_on=on, omega_off=on, min_duration=0.0)
    assert len(chatter.segments) >= 5


def test_noisy_constant_course_is_one_straight_segment():
    rng = np.random.default_rng(11)
    t = np.cumsum(rng.uniform(1.5, 10.0, 500))
    course = (359.0 + rng.normal(0.0, 3.0, t.size)) % 360.0  # noise around north: the course wraps 359°/0°
    speed = 8.0 + rng.normal(0.0, 0.3, t.size)
    labels = label_modes(t, course, speed)
    assert [s["mode"] for s in labels.segments] == ["straight"]
    # with 2–10 s between reports a 30 s window may hold only 3 of them: the smoothed rate still crosses omega_on
    # now and then, and without hysteresis and the minimum length the same course chatters
    assert np.nanmax(np.abs(labels.turn_rate)) > DEFAULTS["omega_on"]
    chatter = label_modes(t, course, speed, omega_off=DEFAULTS["omega_on"], min_duration=0.0)
    assert len(chatter.segments) > 3


def test_stop_hysteresis_and_missing_values():
    t = np.arange(0.0, 200.0, 2.0)
    speed = np.where((t > 60) & (t < 140), 0.7, 3.0)  # between v_stop and v_go: never enters a stop
    course = np.full_like(t, 45.0)
    course[10:20] = np.nan  # "not available": left out of the turn rate
    labels = label_modes(t, course, speed, window=10.0)
    assert [s["mode"] for s in labels.segments] == ["straight"]
    speed[40:60] = 0.0
    stop = label_modes(t, course, speed, window=10.0)
    assert [s["mode"] for s in stop.segments] == ["straight", "stop", "straight"]
    # leaving needs v ≥ v_go = 1 m/s: the 0.7 m/s reports after the halt stay 'stop'
    assert stop.segments[1]["end"] > t[60]


def test_parameters_are_recorded_and_json_ready():
    t, course, speed, _ = synthetic()
    labels = label_modes(t, course, speed, window=20.0)
    document = json.loads(json.dumps(labels.to_dict()))
    assert document["parameters"] == {**DEFAULTS, "window": 20.0}
    assert document["segments"][1]["mode"] == "left_turn" and set(document["segments"][0]) >= {"start", "end", "mode", "radius"}


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"omega_on": 0.01, "omega_off": 0.02}, ValueError, "omega_off"),
        ({"v_stop": 2.0, "v_go": 1.0}, ValueError, "v_go"),
        ({"window": 0.0}, ValueError, "window"),
        ({"min_duration": -1.0}, ValueError, "min_duration"),
        ({"threshold": 1.0}, TypeError, "unknown parameters"),
    ],
)
def test_bad_parameters(kwargs, error, message):
    with pytest.raises(error, match=message):
        label_modes([0.0, 1.0], [0.0, 0.0], [1.0, 1.0], **kwargs)


def test_bad_inputs():
    with pytest.raises(ValueError, match="course: expected shape"):
        label_modes([0.0, 1.0], [0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        label_modes([1.0, 0.0], [0.0, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="needs course and speed"):
        label_track(Track(id="a", times=[0.0], positions=[[0.0, 0.0]], lines=[2], course=None, speed=None))


def test_solent_turn_labels_agree_with_the_reported_positions():
    """On the AIS data, the labels (from course over ground) and the positions (from latitude/longitude) are
    independent reports: a labelled turn's positions should curve the same way."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = read_tracks(SOLENT, **SOLENT_AIS, max_speed=30.0, jump_tolerance=50.0)
    agree = total = 0
    for track in data.tracks.values():
        if len(track) < 2:
            continue
        for s in label_track(track).segments:
            if s["mode"] in ("left_turn", "right_turn") and s["speed"] > 3.0 and s["last"] - s["first"] >= 4:
                p = track.positions[s["first"] : s["last"] + 1]
                m = len(p) // 2
                a, b = p[m] - p[0], p[-1] - p[m]
                total += 1
                agree += (a[0] * b[1] - a[1] * b[0] > 0) == (s["mode"] == "left_turn")
    assert total >= 50 and agree / total >= 0.9
