"""Smoothed mode probabilities of a multiple-model run: the forward–backward algorithm over its Markov chain.

The filter gives, per step k = 0 … N, the mode probabilities μ_{k|k}(j) =
P(mode j at k | z_0 … z_k) and each model's likelihood Λ_j(k) = p(z_k | mode j
at k, Z_{k−1}) (ln Λ_j: ``model_loglik`` of a
:class:`~hybridtrack.algorithms.multiple_model.MultipleModelRun`), with the
transition matrices Π_k (π_ij = P(j at k | i at k−1), Π(Δt_k) for a sojourn
prior).  Taking Λ_j(k) as the emission probabilities of a hidden Markov chain,
the backward recursion

    β_N(i) = 1,    β_k(i) = Σ_j π_ij(k+1) Λ_j(k+1) β_{k+1}(j)

gives the smoothed probabilities μ_{k|N}(i) ∝ μ_{k|k}(i) β_k(i) (Rabiner 1989,
Proc. IEEE 77(2), eqs. 24–27; for switching linear systems the same backward
pass over the model-conditioned likelihoods is the mode part of the IMM
smoothers, Helmick, Blair & Hoffman 1995, IEEE Trans. IT 41(6)).  Fixed lag
L seconds: step k uses the reports up to t_k + L only, β run back from the
last step j with t_j ≤ t_k + L.  Everything in logarithms (log-sum-exp), each
β normalized, so that long runs and modes of probability e^−745 stay finite.
"""

from __future__ import annotations

import numpy as np

from hybridtrack.sdk.mixtures import logsumexp


def smooth_log_mode_probabilities(log_filtered, model_loglik, log_transitions, times=None, lag: float | None = None) -> np.ndarray:
    """ln μ_{k|N} (or, with ``lag``, ln μ_{k|k+L}) (N+1, r) from ln μ_{k|k} ``log_filtered`` (N+1, r), ln Λ_j(k)
    ``model_loglik`` (N+1, r) and ln Π_k ``log_transitions`` (N+1, r, r) (row k the switch into step k; row 0
    unused), module docstring.  ``times`` (N+1,) seconds and ``lag`` ≥ 0 for the fixed-lag smoother."""
    log_filtered = np.asarray(log_filtered, dtype=float)
    model_loglik = np.asarray(model_loglik, dtype=float)
    log_transitions = np.asarray(log_transitions, dtype=float)
    N1, r = log_filtered.shape
    if model_loglik.shape != (N1, r) or log_transitions.shape != (N1, r, r):
        raise ValueError(
            f"model_loglik, log_transitions: expected shapes ({N1}, {r}) and ({N1}, {r}, {r}) beside log_filtered {log_filtered.shape},"
            f" got {model_loglik.shape} and {log_transitions.shape}"
        )
    if lag is None:
        last = np.full(N1, N1 - 1)
    else:
        times = np.asarray(times, dtype=float)
        if times.shape != (N1,) or not np.all(np.diff(times) > 0):
            raise ValueError(f"times: expected {N1} strictly increasing report times for the fixed-lag smoother")
        if not (np.isfinite(lag) and lag >= 0):
            raise ValueError(f"lag: expected a number of seconds ≥ 0, got {lag!r}")
        last = np.searchsorted(times, times + lag, side="right") - 1
    log_beta = np.zeros((N1, r))  # β of every step k, run back from its own last step
    steps = np.arange(N1)
    for d in range(int((last - steps).max(initial=0)), 0, -1):  # the report at k + d enters every β it reaches
        k = np.flatnonzero(steps + d <= last)
        j = k + d
        beta = logsumexp(log_transitions[j] + (model_loglik[j] + log_beta[k])[:, None, :], axis=2)  # over j, (·, i)
        log_beta[k] = beta - logsumexp(beta, axis=1)[:, None]
    smoothed = log_filtered + log_beta
    return smoothed - logsumexp(smoothed, axis=1)[:, None]
