"""The coordinated turn's linearized bank, compiled by numba (:meth:`.real_motion.CoordinatedTurn.linearize`).

Row by row, the formulas of :mod:`.real_motion` and :mod:`.ship` (Bar-Shalom, Li & Kirubarajan 2001, §11.7.1):
with ω̄ = clip(ω, −ω_max, ω_max), a = ω̄ Δt, s₁ = sin a / a, c₁ = (1 − cos a)/a (as ``np.sinc`` evaluates them) and
their derivatives (the Taylor series below |a| = 10⁻²), F = ∂f/∂x (the ω column zero where the limit holds),
B = f(x) − F x, the noise root W = blockdiag(G_axis, G_axis, √Δt) diag(√q) (G_axis the Cholesky factor of
[[Δt³/3, Δt²/2], [Δt²/2, Δt]]) and Q = W Wᵀ.  The same arithmetic as the numpy path to rounding
(tests/plugins/test_turn_kernel.py).  ``cache=True``: compiled once per checkout; imported on first use only.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from hybridtrack_plugins.motion.ship import SERIES_BELOW


def _sinc(v):  # pragma: no cover - compiled
    """np.sinc(v) = sin(π v)/(π v), as numpy computes it (1e-20 in place of v = 0)."""
    y = math.pi * (v if v != 0.0 else 1.0e-20)
    return math.sin(y) / y


_sinc = numba.njit(cache=True, inline="always")(_sinc)


@numba.njit(cache=True, error_model="numpy", nogil=True)
def coordinated_turn_bank(x, tau, max_rate, q_root, F, B, Q, W):  # pragma: no cover - compiled
    """F (M, 5, 5), B (M, 5), Q (M, 5, 5), W (M, 5, 5) (outputs) at the rows of x (M, 5) (x, vx, y, vy, ω) over
    ``tau`` (M,) seconds; ``q_root`` (5,) the square roots of the noise densities (q, q, q, q, q_ω).  Returns 0, or 1
    when an input or an output is not finite (the numpy path then raises its error)."""
    M = x.shape[0]
    for i in range(M):
        px, vx, py, vy, w = x[i, 0], x[i, 1], x[i, 2], x[i, 3], x[i, 4]
        T = tau[i]
        if not (abs(px) < math.inf and abs(vx) < math.inf and abs(py) < math.inf and abs(vy) < math.inf and abs(w) < math.inf):
            return 1
        inside = abs(w) < max_rate
        wb = min(max(w, -max_rate), max_rate)
        a = wb * T
        s1 = _sinc(a / math.pi)
        c1 = math.sin(a / 2.0) * _sinc(a / (2.0 * math.pi))
        c, s = math.cos(a), math.sin(a)
        a2 = a * a
        if abs(a) < SERIES_BELOW:
            ds1 = a * (-1.0 / 3.0 + a2 * (1.0 / 30.0 - a2 / 840.0))
            dc1 = 0.5 + a2 * (-1.0 / 8.0 + a2 / 144.0)
        else:
            ds1 = (a * math.cos(a) - math.sin(a)) / (a * a)
            dc1 = (a * math.sin(a) - 1.0 + math.cos(a)) / (a * a)
        Fi = F[i]
        for r in range(5):
            for k in range(5):
                Fi[r, k] = 0.0
        # the ship turn's Jacobian (x, y, vx, vy, ω) in the layout's order (x, vx, y, vy, ω)
        Fi[0, 0] = Fi[2, 2] = 1.0
        Fi[4, 4] = 1.0 if inside else 0.0  # ω⁺ = ω̄: no derivative where the limit holds
        Fi[0, 1], Fi[0, 3] = T * s1, -T * c1
        Fi[2, 1], Fi[2, 3] = T * c1, T * s1
        Fi[1, 1], Fi[1, 3] = c, -s
        Fi[3, 1], Fi[3, 3] = s, c
        if inside:
            Fi[0, 4] = T * T * (vx * ds1 - vy * dc1)
            Fi[2, 4] = T * T * (vx * dc1 + vy * ds1)
            Fi[1, 4] = T * (-vx * s - vy * c)
            Fi[3, 4] = T * (vx * c - vy * s)
        f0 = px + T * (vx * s1 - vy * c1)
        f2 = py + T * (vx * c1 + vy * s1)
        f1 = vx * c - vy * s
        f3 = vx * s + vy * c
        f = (f0, f1, f2, f3, wb)
        for r in range(5):
            acc = 0.0
            for k in range(5):
                acc += Fi[r, k] * x[i, k]
            B[i, r] = f[r] - acc
        # W = blockdiag(G_axis, G_axis, √Δt) diag(√q), G_axis = chol([[Δt³/3, Δt²/2], [Δt²/2, Δt]])
        g00 = math.sqrt(T**3 * (1.0 / 3.0))
        g10 = T**2 * 0.5 / g00
        g11 = math.sqrt(T - g10 * g10)
        Wi = W[i]
        for r in range(5):
            for k in range(5):
                Wi[r, k] = 0.0
        for base in (0, 2):
            Wi[base, base] = g00 * q_root[base]
            Wi[base + 1, base] = g10 * q_root[base]
            Wi[base + 1, base + 1] = g11 * q_root[base + 1]
        Wi[4, 4] = math.sqrt(T) * q_root[4]
        Qi = Q[i]
        bad = False
        for r in range(5):
            for k in range(5):
                acc = 0.0
                for j in range(5):
                    acc += Wi[r, j] * Wi[k, j]
                Qi[r, k] = acc
                if not (abs(acc) < math.inf and abs(Fi[r, k]) < math.inf):
                    bad = True
            if not abs(B[i, r]) < math.inf:
                bad = True
        if bad:
            return 1
    return 0


def linearized_bank(x: np.ndarray, tau: np.ndarray, max_rate: float, q_root: np.ndarray):
    """(F, B, Q, W) of :func:`coordinated_turn_bank`, or None when it reports a non-finite value."""
    M = x.shape[0]
    F, B, Q, W = np.empty((M, 5, 5)), np.empty((M, 5)), np.empty((M, 5, 5)), np.empty((M, 5, 5))
    if coordinated_turn_bank(np.ascontiguousarray(x), np.ascontiguousarray(tau), float(max_rate), q_root, F, B, Q, W):
        return None
    return F, B, Q, W
