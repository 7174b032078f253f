"""The compiled kernels of :mod:`.mixing` (numba, ``cache=True``): imported on first use only, so that importing
the engine does not import numba.  The formulas and the arithmetic are those of :mod:`.mixing`'s docstring."""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

_jit = functools.partial(numba.njit, cache=True, error_model="numpy", nogil=True)


@_jit(inline="always")
def _weights(a, w):  # pragma: no cover - compiled
    """w ∝ exp(a) normalized (``normalized_weights``' arithmetic) into ``w``; returns ln Σ exp(a) (−∞ when all −∞)."""
    r = a.shape[0]
    top = -math.inf
    for i in range(r):
        if a[i] > top:
            top = a[i]
    shift = top if abs(top) < math.inf else 0.0
    total = 0.0
    for i in range(r):
        w[i] = math.exp(a[i] - shift)
        total += w[i]
    if total > 0.0:
        for i in range(r):
            w[i] = w[i] / total
    else:
        for i in range(r):
            w[i] = 1.0 / r
    return (math.log(total) if total > 0.0 else -math.inf) + shift


@_jit(inline="always")
def _moments(w, x, P, x_out, P_out):  # pragma: no cover - compiled
    """The moment-matched Gaussian of components x (c, n), P (c, n, n) with weights w (c,) into x_out (n,), P_out (n, n)."""
    c, n = x.shape
    for a in range(n):
        acc = 0.0
        for i in range(c):
            acc += w[i] * x[i, a]
        x_out[a] = acc
    for a in range(n):
        for b in range(a, n):
            c_ab = c_ba = spread = 0.0
            for i in range(c):
                c_ab += w[i] * P[i, a, b]
                c_ba += w[i] * P[i, b, a]
            for i in range(c):
                spread += w[i] * (x[i, a] - x_out[a]) * (x[i, b] - x_out[b])
            P_out[a, b] = P_out[b, a] = 0.5 * ((c_ab + spread) + (c_ba + spread))  # ½(C + Cᵀ)


@_jit()
def mix(log_pi, log_mu, x, P, log_cbar, x0, P0):  # pragma: no cover - compiled
    """ln c̄ (R, r) and the starts x̂_0 (R, r, n), P_0 (R, r, n, n) of the models' filters (outputs written)."""
    R, r, n = x.shape
    per_run = log_pi.shape[0] > 1
    a = np.empty(r)
    w = np.empty(r)
    for k in range(R):
        pi = log_pi[k if per_run else 0]
        for j in range(r):
            for i in range(r):
                a[i] = pi[i, j] + log_mu[k, i]
            log_cbar[k, j] = _weights(a, w)
            _moments(w, x[k], P[k], x0[k, j], P0[k, j])


@_jit()
def merge(joint, x, P, log_mu, total, mean, cov):  # pragma: no cover - compiled
    """ln μ (R, r), the totals ln Σ exp(a) (R,) and the output x̂ (R, n), P (R, n, n) (outputs written)."""
    R, r, n = x.shape
    w = np.empty(r)
    for k in range(R):
        total[k] = _weights(joint[k], w)
        for j in range(r):
            log_mu[k, j] = joint[k, j] - total[k]
        _moments(w, x[k], P[k], mean[k], cov[k])


@_jit()
def merge_groups(
    order, starts, counts, log_weights, log_p, x, P, model_ll, ll, log_mu, x_out, P_out, mean, cov, model_ll_out, ll_out
):  # pragma: no cover - compiled
    """Group g's hypotheses ``order[starts[g]:starts[g] + counts[g]]`` merged per mode (outputs written)."""
    G = starts.shape[0]
    H, r, n = x.shape
    w = np.empty(r)
    d = np.empty(n)
    for g in range(G):
        s, c = starts[g], counts[g]
        first = order[s]
        total_ll = 0.0
        for q in range(s, s + c):
            total_ll += math.exp(log_weights[order[q]]) * ll[order[q]]
        ll_out[g] = total_ll
        for j in range(r):
            top = -math.inf
            for q in range(s, s + c):
                a = log_weights[order[q]] + log_p[order[q], j]
                if a > top:
                    top = a
            shift = top if abs(top) < math.inf else 0.0
            total = 0.0
            for q in range(s, s + c):
                total += math.exp(log_weights[order[q]] + log_p[order[q], j] - shift)
            log_mu[g, j] = math.log(total) + shift if total > 0.0 else -math.inf
            for a_ in range(n):
                x_out[g, j, a_] = 0.0
                for b in range(n):
                    P_out[g, j, a_, b] = 0.0
            model_ll_out[g, j] = 0.0
            for q in range(s, s + c):
                h = order[q]
                if total > 0.0:
                    wh = math.exp(log_weights[h] + log_p[h, j] - shift) / total
                else:  # a mode of probability zero: the first hypothesis' estimate (any finite choice is exact)
                    wh = 1.0 if q == s else 0.0
                for a_ in range(n):
                    d[a_] = x[h, j, a_] - x[first, j, a_]
                    x_out[g, j, a_] += wh * d[a_]
                for a_ in range(n):
                    for b in range(n):
                        P_out[g, j, a_, b] += wh * (P[h, j, a_, b] + d[a_] * d[b])
                model_ll_out[g, j] += wh * model_ll[h, j]
            for a_ in range(n):
                for b in range(a_, n):
                    v = 0.5 * (
                        (P_out[g, j, a_, b] - x_out[g, j, a_] * x_out[g, j, b]) + (P_out[g, j, b, a_] - x_out[g, j, b] * x_out[g, j, a_])
                    )
                    P_out[g, j, a_, b] = P_out[g, j, b, a_] = v
            for a_ in range(n):
                x_out[g, j, a_] += x[first, j, a_]
        total_mu = _weights(log_mu[g], w)
        for j in range(r):
            log_mu[g, j] -= total_mu
        _moments(w, x_out[g], P_out[g], mean[g], cov[g])
