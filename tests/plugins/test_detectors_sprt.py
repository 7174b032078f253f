"""SPRTs: pairwise with elimination (seed 001 rule 5) and change-time averaging (seed 000 eqs. 24–25), pruning."""

import math

import numpy as np
import pytest

from hybridtrack.core.interfaces import Innovation
from hybridtrack_plugins.detectors.sprt_change import ChangeTimeSPRT
from hybridtrack_plugins.detectors.sprt_pairwise import PairwiseSPRT


def gaussian_innovation(nu, S):
    nu, S = np.asarray(nu, float), np.asarray(S, float)
    m = nu.shape[-1]
    nis = np.einsum("mi,mi->m", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    loglik = -0.5 * (m * np.log(2 * np.pi) + np.linalg.slogdet(S)[1] + nis)
    return Innovation(nu, S, loglik, nis)


def test_pairwise_increment_is_seed_001_equation_4():
    """2μ_ij = ln det S_j − ln det S_i + ν_jᵀS_j⁻¹ν_j − ν_iᵀS_i⁻¹ν_i, checked on the reported margin."""
    nu = np.array([[0.1, -0.2], [1.0, 0.5]])
    S = np.array([[[1.0, 0.2], [0.2, 2.0]], [[3.0, 0.0], [0.0, 1.0]]])
    d = PairwiseSPRT(alpha=0.01, beta=0.01)
    out = d.step(0, gaussian_innovation(nu, S))
    two_mu = (
        np.linalg.slogdet(S[1])[1]
        - np.linalg.slogdet(S[0])[1]
        + nu[1] @ np.linalg.solve(S[1], nu[1])
        - nu[0] @ np.linalg.solve(S[0], nu[0])
    )
    assert out.statistics["log_ratio"][0] == pytest.approx(two_mu / 2)
    assert out.statistics["log_ratio"][1] == pytest.approx(-two_mu / 2)


def test_pairwise_eliminates_and_accepts_the_survivor():
    d = PairwiseSPRT(alpha=0.05, beta=0.05, hypotheses=["s", "l", "r"])  # A = −B = ln 19 ≈ 2.944
    steps = [np.array([0.0, -1.0, -3.5]), np.array([0.0, -1.0, 0.0]), np.array([0.0, -1.5, 0.0])]
    outs = [d.observe(k, ll, np.zeros(3), 2) for k, ll in enumerate(steps)]
    assert outs[0].decision is None and outs[0].statistics["active"].tolist() == [1, 1, 0]
    assert outs[1].decision is None
    assert outs[2].decision.mode == "s" and outs[2].decision.step == 2  # λ_sl = 3.5 ≥ A, 'l' dropped, one left
    assert d.decided == 0
    later = d.observe(3, np.array([-9.0, 0.0, 0.0]), np.zeros(3), 2)
    assert later.decision is None and later.statistics["log_ratio"][0] == outs[2].statistics["log_ratio"][0]


def reference_log_lambda(loglik_rows, modes, starts, k_values):
    """ln((1/k) Σ_j Π_i f_p/f_0) by plain products over a hand-built bank (no logs until the end)."""
    out = []
    psi = np.zeros(len(modes))
    for t, (row, k) in enumerate(zip(loglik_rows, k_values)):
        active = np.array(starts) <= t
        ratio = np.exp(row[1:] - row[0])
        psi = np.where(active, np.where(psi == 0, 1.0, psi) * ratio, 0.0)
        out.append([math.log(psi[np.array(modes) == p].sum() / k) for p in (1, 2)])
    return np.array(out)


def test_change_time_ratios_equal_the_product_form_of_eq_25():
    rng = np.random.default_rng(5)
    d = ChangeTimeSPRT(alpha=1e-6, beta=1e-6)  # wide thresholds: no decision
    modes, starts, rows = [], [], []
    for k in range(6):
        d.add([1, 2], k)
        modes += [1, 2]
        starts += [k, k]
        ll = rng.normal(-2.0, 0.5, 1 + len(modes))
        rows.append(np.concatenate([ll, np.zeros(12 - len(ll) + 1)])[: 1 + 12])
        out = d.observe(k, ll, np.zeros_like(ll), 2)
    expected = reference_log_lambda([r for r in rows], [1, 2] * 6, sorted([0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5]), range(1, 7))
    np.testing.assert_allclose(out.statistics["log_ratio"], expected[-1], rtol=1e-12)


def test_change_time_decisions_and_restart():
    d = ChangeTimeSPRT(alpha=0.05, beta=0.05, hypotheses=["straight", "right", "left"])
    d.add([1, 2], 1)
    out = d.observe(1, np.array([-1.0, 2.5, -4.0]), np.zeros(3), 2)
    assert out.decision.mode == "right" and d.decided == 1 and d.chosen_entry == 0
    d.reset()
    d.add([1, 2], 1)
    out = d.observe(1, np.array([0.0, -4.0, -4.0]), np.zeros(3), 2)
    assert out.decision.mode == "straight" and d.decided is None and d.k == 0  # H0: the test restarts


def test_pruning_rules():
    d = ChangeTimeSPRT(alpha=1e-6, beta=1e-6, bank_size=3, pruning="nearest_lower")
    for k in range(3):
        d.add([1, 2], k)
    d.log_psi = np.array([-5.0, 0.3, -0.1, -7.0, 0.0, 0.2])
    rows = d.prune()
    assert rows.tolist() == [1, 4, 5] and d.starts.tolist() == [0, 2, 2]  # the three largest ln ψ survive
    d2 = ChangeTimeSPRT(alpha=1e-6, beta=1e-6, bank_size=3, pruning="oldest")
    for k in range(3):
        d2.add([1, 2], k)
    d2.log_psi = np.array([-5.0, 0.3, -0.1, -7.0, 0.0, 0.2])
    assert d2.prune().tolist() == [2, 4, 5]  # the newest start, then the earlier row of the next (ties by order)
    assert d2.prune(bank_size=10).tolist() == [0, 1, 2]


def test_fixed_bank_without_add_starts_every_alternative_at_the_first_step():
    d = ChangeTimeSPRT(averaging="none")
    d.observe(0, np.array([0.0, 0.5, -0.5]), np.zeros(3), 2)
    out = d.observe(1, np.array([0.0, 0.5, -0.5]), np.zeros(3), 2)
    np.testing.assert_allclose(out.statistics["log_ratio"], [1.0, -1.0])
