"""Track management: M-of-N and the track score's SPRT, on hand-built hit sequences."""

import math

import numpy as np
import pytest

from hybridtrack.algorithms.multitarget.management import CONFIRMED, MofN, TrackScore, TrackStatus


def _run(logic, hits, deltas=None, start_score=0.0, interval=1.0):
    """Feed one track's hit sequence; the (scan, 'confirm' | 'delete') events."""
    status = TrackStatus.born(1, start_score, 0.0)
    events = []
    for k, hit in enumerate(hits, start=1):
        delta = np.array([0.0 if deltas is None else deltas[k - 1]])
        status.record(np.array([hit]), delta, k * interval)
        confirm, delete = logic.decide(status, k * interval)
        status.status = np.where(confirm, CONFIRMED, status.status).astype(np.int8)
        if confirm[0]:
            events.append((k, "confirm"))
        if delete[0]:
            events.append((k, "delete"))
            break
    return events


def test_m_of_n_confirms_on_the_mth_hit_within_n():
    # born with one hit; 2 more hits within 4 scans: confirmed at the scan of the third hit
    assert _run(MofN(3, 4, 3), [False, True, True]) == [(3, "confirm")]
    assert _run(MofN(3, 4, 3), [True, True]) == [(2, "confirm")]


def test_m_of_n_deletes_a_tentative_track_once_m_is_out_of_reach():
    # born (1 hit), then two misses: 1 hit + 1 scan left < 3
    assert _run(MofN(3, 4, 3), [False, False]) == [(2, "delete")]


def test_m_of_n_deletes_a_confirmed_track_after_misses_in_a_row():
    events = _run(MofN(2, 3, 2), [True, False, True, False, False])
    assert events == [(1, "confirm"), (5, "delete")]


def test_max_coast_deletes_by_time():
    assert _run(MofN(2, 3, 99, max_coast=2.5), [True, False, False, False]) == [(1, "confirm"), (4, "delete")]


def test_track_score_thresholds_are_walds():
    logic = TrackScore(false_track_probability=1e-3, track_loss_probability=0.1)
    assert logic.confirm_threshold == pytest.approx(math.log(0.9 / 1e-3))
    assert logic.delete_threshold == pytest.approx(math.log(0.1 / (1 - 1e-3)))
    assert logic.drop == pytest.approx(logic.confirm_threshold - logic.delete_threshold)


def test_track_score_confirms_and_deletes_on_the_score():
    logic = TrackScore(false_track_probability=1e-3, track_loss_probability=0.1)
    up, down = 2.0, math.log(0.1)  # a hit's ΔL and a miss's ln(1 − P_D P_G) with P_D P_G = 0.9
    confirm_after = math.ceil(logic.confirm_threshold / up)
    events = _run(logic, [True] * confirm_after + [False] * 20, [up] * confirm_after + [down] * 20)
    assert events[0] == (confirm_after, "confirm")
    misses = math.floor(logic.drop / -down) + 1  # the first miss that takes the score more than the drop below its peak
    assert events[1] == (confirm_after + misses, "delete")
    assert _run(logic, [False] * 3, [down] * 3) == [(1, "delete")]  # −2.3 ≤ T_d ≈ −2.2: a tentative track goes at once


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="confirm_hits"):
        MofN(5, 3)
    with pytest.raises(ValueError, match="false_track_probability"):
        TrackScore(false_track_probability=1.5)
    with pytest.raises(ValueError, match="max_coast"):
        MofN(max_coast=-1.0)
