"""Minimum segment durations from the mode sojourn prior (hybridtrack.apps.minimum_duration, ``[segments]
sojourn_quantile``): the quantile against hand values and the exponential law, the causal hold and the offline merge
on hand examples, the configuration's checks and the tracker's summary on a track with a brief wiggle."""

import math

import numpy as np
import pytest

from hybridtrack.apps.minimum_duration import held_modes, merged_modes, minimum_durations
from hybridtrack.apps.tracking import ConfigError, load_config, mode_sojourns, track_one
from hybridtrack.core.plugins import resolve
from hybridtrack.io.track_files import Track


def test_the_minimum_is_the_quantile_of_the_exponential_sojourn():
    d = minimum_durations({"straight": 120.0, "stop": 3600.0}, 0.1)
    assert d["straight"] == pytest.approx(-120.0 * math.log(0.9), rel=1e-15) == pytest.approx(12.643, abs=1e-3)
    assert d["stop"] == pytest.approx(30 * d["straight"], rel=1e-14)
    # the fraction of exponential sojourns of mean T below d is q
    rng = np.random.default_rng(3)
    sojourns = rng.exponential(120.0, 200_000)
    assert np.mean(sojourns < d["straight"]) == pytest.approx(0.1, abs=0.003)
    assert minimum_durations({"straight": 120.0}, 0.0) == {"straight": 0.0}
    for bad in (-0.1, 1.0, float("nan")):
        with pytest.raises(ValueError, match="quantile"):
            minimum_durations({"straight": 1.0}, bad)


def test_a_switch_is_taken_once_it_has_lasted_its_minimum_and_dated_from_its_start():
    t = np.arange(14.0)
    S, T = "straight", "turn"
    modes = [S, S, S, T, T, S, S, T, T, T, T, T, S, S]
    held, decided = held_modes(t, modes, {T: 3.0})
    # the 2-step turn at 3–4 lasts 1 s < 3 s: dropped; the turn from 7 lasts 3 s at step 10: taken, from step 7;
    # straight has no minimum: taken at once at 12
    assert held == [S] * 7 + [T] * 5 + [S, S]
    assert decided == [(7, 10), (12, 12)]
    assert held_modes(t, modes, {}) == (modes, [(3, 3), (5, 5), (7, 7), (12, 12)])


def test_an_interrupted_spell_starts_again():
    t = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 10.0])
    modes = ["a", "b", "c", "b", "b", "b"]
    held, decided = held_modes(t, modes, {"b": 2.5, "c": 2.5})
    assert held == ["a", "a", "a", "b", "b", "b"] and decided == [(3, 5)]  # the spell of b restarts at 3 after c


def test_offline_the_shortest_segments_are_merged_into_their_longer_neighbour():
    t = np.arange(12.0)
    modes = ["s"] * 5 + ["l"] + ["s"] * 2 + ["r"] * 4
    # segments s 0–5 (5 s), l 5–6 (1 s), s 6–8 (2 s), r 8–11 (3 s): with 2.5 s for every mode, l goes into its
    # longer neighbour (the first s), then the joined s 0–8 stands and r (3 s) stands
    assert merged_modes(t, modes, {m: 2.5 for m in "slr"}) == ["s"] * 8 + ["r"] * 4
    # the shortest relative to its own minimum first: r is short of its 5 s, merged into the s before it
    assert merged_modes(t, modes, {"s": 2.5, "l": 2.5, "r": 5.0}) == ["s"] * 12
    assert merged_modes(t, modes, {}) == modes


def _config(**segments):
    return {
        "measurement": {"sigma": 5.0},
        "prior": {"velocity_sigma": 2.0},
        "estimator": {
            "algorithm": "imm",
            "modes": ["straight", {"name": "coordinated_turn"}],
            "noise_density": 0.001,
            "sojourn": [120.0, 60.0],
        },
        "segments": segments,
    }


def test_the_configuration_checks_the_quantile_and_the_algorithm():
    assert load_config(_config())["segments"]["sojourn_quantile"] == 0.0
    assert load_config(_config(sojourn_quantile=0.1))["segments"]["sojourn_quantile"] == 0.1
    for bad in (1.0, -0.5, "0.1", True):
        with pytest.raises(ConfigError, match="sojourn_quantile"):
            load_config(_config(sojourn_quantile=bad))
    sprt = _config(sojourn_quantile=0.1)
    sprt["estimator"] = {"algorithm": "unknown_change", "modes": ["straight"], "noise_density": 0.001}
    with pytest.raises(ConfigError, match="sojourn_quantile needs the modes' sojourn prior"):
        load_config(sprt)


def test_each_summary_mode_takes_the_sojourn_of_its_models():
    models = [resolve("motion_model", name) for name in ("straight", "coordinated_turn", "stop")]
    assert mode_sojourns(models, [120.0, 60.0, 3600.0]) == {"straight": 120.0, "left_turn": 60.0, "right_turn": 60.0, "stop": 3600.0}
    assert mode_sojourns(models, 30.0) == dict.fromkeys(("straight", "left_turn", "right_turn", "stop"), 30.0)


def _bend_track():
    """Straight at 10 m/s east for 200 s with a brief S-bend at 100 s (8°/s left for 10 s, then right for 10 s),
    a report every second, σ = 2 m."""
    t = np.arange(0.0, 200.0, 1.0)
    left, right = (t >= 100) & (t < 110), (t >= 110) & (t < 120)
    heading = np.cumsum(np.radians(8.0) * (left.astype(float) - right))
    xy = np.cumsum(10.0 * np.column_stack([np.cos(heading), np.sin(heading)]), axis=0)
    none = np.full(t.size, np.nan)
    noisy = xy + np.random.default_rng(8).normal(0.0, 2.0, xy.shape)
    return Track("bend", times=t, positions=noisy, lines=np.arange(t.size) + 2, course=none, speed=none)


def _shortest(segments) -> float:
    return min(s["end"] - s["start"] for s in segments[:-1])  # the last segment ends at the last report


def test_the_tracker_holds_its_segments_to_the_sojourn_minimum(tmp_path):
    track = _bend_track()
    free = track_one(track, load_config(_config()), tmp_path, record=False)
    assert {"left_turn", "right_turn"} <= {s["mode"] for s in free["segments"]}  # the bend's two turns
    # q = 0.3: d = −60 s ln 0.7 = 21.4 s for the turns, 42.8 s for straight: no turn lasts that long
    held = track_one(track, load_config(_config(sojourn_quantile=0.3)), tmp_path, record=False)
    assert [s["mode"] for s in held["segments"]] == ["straight"] and held["decisions"] == []
    # q = 0.02 (turns 1.2 s, straight 2.4 s): the turns stay, each decided at least its minimum after its start
    mild = track_one(track, load_config(_config(sojourn_quantile=0.02)), tmp_path, record=False)
    turns = [d for d in mild["decisions"] if d["mode"] != "straight"]
    assert {d["mode"] for d in turns} == {"left_turn", "right_turn"}
    assert all(d["time"] - d["start"] >= -60.0 * math.log(0.98) for d in turns)
    assert [d["start"] for d in mild["decisions"]] == [s["start"] for s in mild["segments"][1:]]  # dated from its start
    # offline (--smooth): the smoothed run's one-report segments are merged away
    smoothed = track_one(track, load_config(_config()), tmp_path, record=False, smooth=True)
    merged = track_one(track, load_config(_config(sojourn_quantile=0.02)), tmp_path, record=False, smooth=True)
    assert _shortest(smoothed["segments"]) < 1.2
    assert _shortest(merged["segments"]) >= -60.0 * math.log(0.98)
    assert {"left_turn", "right_turn"} <= {s["mode"] for s in merged["segments"]}
