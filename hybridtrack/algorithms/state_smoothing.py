"""Fixed-interval state smoothing: the Rauch–Tung–Striebel backward pass over one motion model's filtered run.

Given the filtered estimates x̂_{k|k}, P_{k|k} (k = 0 … N) of a Kalman filter
(or an EKF) of the motion model f with the transitions linearized at the
filtered means, F_k = ∂f/∂x at x̂_{k|k} over Δt_{k+1} = t_{k+1} − t_k and Q_k
its process noise (``MotionModel.transition(Δt, x̂_{k|k})``):

    x̄_{k+1} = f(x̂_{k|k}),   P̄_{k+1} = F_k P_{k|k} F_kᵀ + Q_k,
    C_k = P_{k|k} F_kᵀ P̄_{k+1}⁻¹            (a Cholesky solve of P̄_{k+1}),
    x̂_{k|N} = x̂_{k|k} + C_k (x̂_{k+1|N} − x̄_{k+1}),
    P_{k|N} = P_{k|k} + C_k (P_{k+1|N} − P̄_{k+1}) C_kᵀ,

run back from x̂_{N|N}, P_{N|N} (Rauch, Tung & Striebel 1965, AIAA J. 3(8);
Bar-Shalom, Li & Kirubarajan 2001, *Estimation with Applications to Tracking
and Navigation*, §8.6; the extended form: Särkkä 2013, *Bayesian Filtering and
Smoothing*, §9.1).  For a linear model it is the exact smoother of the Kalman
filter.

A multiple-model run (r models, filtered model-conditioned estimates x̂_{j,k|k},
P_{j,k|k} and mode probabilities μ_{j,k|k}, smoothed μ_{j,k|N}, transitions
π_ij(Δt)) is smoothed by the backward pass of the fixed-interval IMM smoother
(Helmick, Blair & Hoffman 1995, IEEE Trans. IT 41(6); Bar-Shalom, Li &
Kirubarajan §11.6.7): model j at k is conditioned on the *backward-mixed*
smoothed estimate of the next step,

    μ_{i|j} ∝ π_ji μ_{i,k+1|N} / c̄_{i,k+1},   c̄_{i,k+1} = Σ_l π_li μ_{l,k|k}
    (the probability of mode i at k+1 given mode j at k and all the reports),
    x̂⁰_{j,k+1|N}, P⁰_{j,k+1|N} = the μ_{·|j}-mixture of the x̂_{i,k+1|N}, P_{i,k+1|N},
    x̂_{j,k|N} = x̂_{j,k|k} + C_{j,k} (x̂⁰_{j,k+1|N} − x̄_{j,k+1}),
    P_{j,k|N} = P_{j,k|k} + C_{j,k} (P⁰_{j,k+1|N} − P̄_{j,k+1}) C_{j,k}ᵀ,

each model on its own components (C, x̄, P̄ its RTS gain and prediction from
x̂_{j,k|k}; in the mixture a component that model i lacks — a straight model's
turn rate — is model j's own, since model i says nothing about it, where the
forward filter gives it the missing mean), and the output is the
μ_{k|N}-mixture of the x̂_{j,k|N}.  Left out
against Helmick et al.: their second, forward filter (the smoothed model
estimates here come from the RTS form, each model's filtered estimate taken
as its own Kalman filter's).  With r = 1 it is the RTS smoother above.

A gate guards the linearization.  Under the model the shift of a step,
δ = x̂_{k|N} − x̂_{k|k} = C_k (x̂_{k+1|N} − x̄_{k+1}), is N(0, P_{k|k} − P_{k|N})
with P_{k|N} ≥ 0, so δᵀ P_{k|k}⁻¹ δ is at most χ²_n-distributed; a step beyond
its 1 − 10⁻⁴ quantile (a coordinated turn linearized over a gap of half an
hour, where F x̂ is far from f) keeps its filtered estimate, and the pass goes
on from there.

The gate also stops the one known failure of this approximation: the
model-conditioned estimates of an IMM are mixed at every step, so a model whose
velocity is not the object's (the stop mode's, v ≈ 0, while the object moves)
would bias the others' velocities through the backward mixing, and the pass
would integrate that bias into the positions; such steps fall outside the
gate.  Measured on the 74 Solent ships (``experiments/real_tracks.py``, the
whole file): docs/results.md.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from hybridtrack.core.interfaces import MotionModel
from hybridtrack.sdk.distributions import chi2_quantile
from hybridtrack.sdk.mixtures import logsumexp, mixture

#: the probability beyond which a smoothing step's shift counts as a failed linearization (module docstring)
GATE_PROBABILITY = 1e-4


def consistent(shift, P, gate: float) -> bool:
    """δᵀ P⁻¹ δ ≤ gate for the shift δ = x̂_{k|N} − x̂_{k|k} of a smoothing step and the filtered covariance P: under the
    model δ ~ N(0, P_{k|k} − P_{k|N}), P_{k|N} ≥ 0, so δᵀ P_{k|k}⁻¹ δ is at most χ²_n-distributed (module docstring)."""
    try:
        factor = scipy.linalg.cho_factor(P)
    except np.linalg.LinAlgError:
        return True  # a singular filtered covariance (a state known exactly): nothing to gate against
    return float(shift @ scipy.linalg.cho_solve(factor, shift)) <= gate


def rts_smooth(means, covs, times, model: MotionModel) -> tuple[np.ndarray, np.ndarray]:
    """x̂_{k|N} (N+1, n), P_{k|N} (N+1, n, n) from the filtered ``means`` (N+1, n), ``covs`` (N+1, n, n) in the
    model's layout at the strictly increasing ``times`` (N+1,) seconds (module docstring)."""
    means, covs = np.asarray(means, dtype=float), np.asarray(covs, dtype=float)
    N1, n = means.shape[0], len(model.layout)
    if means.shape != (N1, n) or covs.shape != (N1, n, n) or np.shape(times) != (N1,):
        raise ValueError(
            f"means, covs, times: expected shapes ({N1}, {n}), ({N1}, {n}, {n}), ({N1},) for the model {model.name!r} {model.layout},"
            f" got {means.shape}, {covs.shape}, {np.shape(times)}"
        )
    zeros = np.zeros((N1, 1))
    _, _, smoothed, smoothed_covs = smooth_models(
        means[:, None], covs[:, None], zeros, zeros, np.zeros((N1, 1, 1)), times, [model], model.layout
    )
    return smoothed, smoothed_covs


def smooth_models(model_means, model_covs, log_filtered, log_smoothed, log_transitions, times, models, layout):
    """The multiple-model backward pass of the module docstring: from the filtered ``model_means`` (N+1, r, n),
    ``model_covs`` (N+1, r, n, n) in ``layout`` (each model's missing components ignored), ln μ_{k|k}
    ``log_filtered`` and ln μ_{k|N} ``log_smoothed`` (N+1, r), ln Π_k ``log_transitions`` (N+1, r, r) (row k the
    switch into step k; row 0 unused), returns the smoothed model estimates (same shapes; the missing components as
    filtered) and the combined x̂_{k|N} (N+1, n), P_{k|N} (N+1, n, n)."""
    model_means = np.asarray(model_means, dtype=float)
    model_covs = np.asarray(model_covs, dtype=float)
    log_filtered, log_smoothed = np.asarray(log_filtered, dtype=float), np.asarray(log_smoothed, dtype=float)
    log_transitions = np.asarray(log_transitions, dtype=float)
    times = np.asarray(times, dtype=float)
    N1, r, n = model_means.shape
    shapes = (model_covs.shape, log_filtered.shape, log_smoothed.shape, log_transitions.shape, times.shape, len(models), len(layout))
    if shapes != ((N1, r, n, n), (N1, r), (N1, r), (N1, r, r), (N1,), r, n):
        raise ValueError(
            "model_covs, log_filtered, log_smoothed, log_transitions, times, models, layout: expected"
            f" {((N1, r, n, n), (N1, r), (N1, r), (N1, r, r), (N1,), r, n)} beside model_means {model_means.shape}, got {shapes}"
        )
    if N1 > 1 and not np.all(np.diff(times) > 0):
        raise ValueError("times: expected strictly increasing report times for the smoother")
    owns = []
    for model in models:
        missing = [c for c in model.layout if c not in layout]
        if missing:
            raise ValueError(f"layout {tuple(layout)}: lacks {missing} of the model {model.name!r}")
        owns.append(np.array([list(layout).index(c) for c in model.layout]))
    gates = [chi2_quantile(1.0 - GATE_PROBABILITY, len(own)) for own in owns]
    has = np.zeros((r, n), dtype=bool)  # has[i, c]: model i has component c
    for i, own in enumerate(owns):
        has[i, own] = True
    smoothed_means, smoothed_covs = model_means.copy(), model_covs.copy()
    for k in range(N1 - 2, -1, -1):
        dt = float(times[k + 1] - times[k])
        log_pi = log_transitions[k + 1]  # π_ji: row j (mode at k), column i (mode at k+1)
        log_predicted = logsumexp(log_pi + log_filtered[k][:, None], axis=0)  # ln c̄_i
        log_backward = log_pi + (log_smoothed[k + 1] - log_predicted)[None, :]  # ln μ_{i|j}, unnormalized, (j, i)
        for j, (model, own) in enumerate(zip(models, owns)):
            # what model i lacks it says nothing about: there it takes model j's own smoothed estimate (no cross terms)
            filled = np.where(has, smoothed_means[k + 1], smoothed_means[k + 1, j])
            both, neither = has[:, :, None] & has[:, None, :], ~has[:, :, None] & ~has[:, None, :]
            filled_covs = np.where(both, smoothed_covs[k + 1], 0.0) + np.where(neither, smoothed_covs[k + 1, j], 0.0)
            target, target_cov = mixture(log_backward[j], filled, filled_covs)
            x, P = model_means[k, j, own], model_covs[k, j][np.ix_(own, own)]
            transition = model.transition(dt, x)
            F = transition.F
            predicted_cov = F @ P @ F.T + transition.process_noise
            predicted_cov = 0.5 * (predicted_cov + predicted_cov.T)
            gain = scipy.linalg.cho_solve(scipy.linalg.cho_factor(predicted_cov), F @ P).T  # C = P Fᵀ P̄⁻¹ (P̄ symmetric)
            shift = gain @ (target[own] - transition.apply(x))
            if consistent(shift, P, gates[j]):  # else the linearization failed: the filtered estimate stays
                smoothed_means[k, j, own] = x + shift
                cov = P + gain @ (target_cov[np.ix_(own, own)] - predicted_cov) @ gain.T
                smoothed_covs[k, j][np.ix_(own, own)] = 0.5 * (cov + cov.T)
    means, covs = mixture(log_smoothed, smoothed_means, smoothed_covs)
    return smoothed_means, smoothed_covs, means, covs
