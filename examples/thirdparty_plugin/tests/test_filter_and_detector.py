"""Tests of the info_kalman estimator and the cumulative_llr detector, with hybridtrack's contract checks."""

import numpy as np
import pytest

from hybridtrack_zigzag import CumulativeLLR, InfoKalman


def test_info_kalman_honours_the_estimator_contract(hybridtrack_contracts, hybridtrack_registry):
    assert hybridtrack_registry.get("estimator", "info_kalman") is InfoKalman
    hybridtrack_contracts.check_estimator(InfoKalman())


@pytest.mark.parametrize("pruning", ["oldest", "nearest_lower"])
def test_cumulative_llr_honours_the_detector_contract(hybridtrack_contracts, hybridtrack_registry, pruning):
    assert hybridtrack_registry.get("detector", "cumulative_llr") is CumulativeLLR
    hybridtrack_contracts.check_detector(CumulativeLLR(alpha=0.1, beta=0.1, pruning=pruning))


def test_cumulative_llr_takes_the_maximum_over_change_times_and_prunes():
    detector = CumulativeLLR(alpha=0.05, beta=0.05, hypotheses=("h0", "h1", "h2"), bank_size=2, pruning="nearest_lower")
    detector.add([1, 2], start=1)
    out = detector.observe(1, np.array([0.0, -0.5, -1.0]), np.zeros(3), 2)
    np.testing.assert_allclose(out.statistics["log_ratio"], [-0.5, -1.0])
    detector.add([1, 2], start=2)
    out = detector.observe(2, np.array([0.0, 0.3, -0.2, 0.1, 0.4]), np.zeros(5), 2)
    np.testing.assert_allclose(detector.log_psi, [-0.2, -1.2, 0.1, 0.4])
    np.testing.assert_allclose(out.statistics["log_ratio"], [0.1, 0.4])  # ln λ_p = max over p's entries
    rows = detector.prune()
    assert rows.tolist() == [2, 3] and detector.starts.tolist() == [2, 2]
    out = detector.observe(3, np.array([0.0, 1.0, 3.0]), np.zeros(3), 2)
    assert detector.decided == 2 and detector.chosen_entry == 1 and out.decision.mode == "h2"
    assert detector.observe(4, np.zeros(3), np.zeros(3), 2).decision is None  # frozen until reset()
