"""N-bearings pseudo-linear estimator of θ (seed 002 §4.4).

The first bearing φ_0 fixes the direction of the target at t_0 = t_1 (first
bearing time); the unknowns are x = (r_0, v_x, v_y), r_0 the range at t_0.
With u(φ) the unit vector along bearing φ (sensor convention), the target at
t_i lies on the bearing line from the observer, cross(u(φ_i), d_i) = 0 with
d_i = r_0 u(φ_0) + v Δt_i − Δõ_i, Δt_i = t_i − t_0, Δõ_i = o_i − o_0.  Row i of
the linear regression H x = b is therefore

    H_i = [cross(u_i, u_0), −u_iy Δt_i, u_ix Δt_i],   b_i = u_ix Δỹ_i − u_iy Δx̃_i,

with cross(a, b) = a_x b_y − a_y b_x.  In the math convention (u = (cos φ, sin φ))
this is minus the seed's row H_i = [sin(φ_i − φ_0), sin φ_i Δt_i, −cos φ_i Δt_i],
b_i = Δx̃_i sin φ_i − Δỹ_i cos φ_i, i.e. the same equations; in the north
convention (u = (sin φ, cos φ)) it reads H_i = [sin(φ_i − φ_0), −cos φ_i Δt_i,
sin φ_i Δt_i], b_i = Δỹ_i sin φ_i − Δx̃_i cos φ_i.  The solution is exact for
noise-free bearings and biased by the error of φ_0 otherwise (seed 002 §4.4).

Columns are scaled (r_0/L, v T/L; Δt/T, Δõ/L) as in :mod:`.tma_model`.  The
reported covariance is the regression's s_b² (HᵀH)⁻¹ (s_b² = |b − Hx|²/(n−3))
mapped to θ, plus the φ_0 term Var(φ_0) r_0² u'(φ_0) u'(φ_0)ᵀ on the position
(Var(φ_0) = σ² when known, else Ka); it ignores the bias.
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.sdk.linalg import cholesky_solve, masked_cholesky, wrap_angle
from hybridtrack_plugins.sensors.bearing import direction
from hybridtrack_plugins.solvers.observer import example_problem
from hybridtrack_plugins.solvers.tma_model import (
    CONSTANT_FIT_MESSAGE,
    BatchTMASolution,
    BearingsBatch,
    BearingsSolver,
    ScaledProblem,
    answers,
    fit_statistics,
    flag_constant_fits,
    warn_unobservable,
)


def pseudo_linear_system(tau, bearings, ox, oy, convention):
    """H (..., n, 3) and b (..., n) of the N-bearings regression in scaled units (τ_0 = 0, õ_0 = 0)."""
    ux, uy = direction(bearings, convention)
    u0x, u0y = ux[..., :1], uy[..., :1]
    H = np.stack(np.broadcast_arrays(ux * u0y - uy * u0x, -uy * tau, ux * tau), axis=-1)
    b = ux * oy - uy * ox
    return H, b


def solve_normal(H, b):
    """B regressions at once: Jacobi-scaled normal equations HᵀH x = Hᵀb by a masked Cholesky."""
    N = np.einsum("bki,bkj->bij", H, H)
    c = np.einsum("bki,bk->bi", H, b)
    e = 1.0 / np.sqrt(np.maximum(np.diagonal(N, axis1=-2, axis2=-1), np.finfo(float).tiny))
    L, ok = masked_cholesky(N * e[:, :, None] * e[:, None, :])
    # reject near-singular systems like lstsq's rank test would
    ok &= np.diagonal(L, axis1=-2, axis2=-1).min(axis=-1) ** 2 > 1e-12
    x = cholesky_solve(L, c * e) * e
    N_inv = cholesky_solve(L, np.broadcast_to(np.eye(3), L.shape)) * (e[:, :, None] * e[:, None, :])
    return np.where(ok[:, None], x, np.nan), np.where(ok[:, None, None], N_inv, np.nan), ok


def assemble(x, HtH_inv, residual_ss, n, X0, variance_phi0, scaling_t0, reference_time, convention):
    """θ (..., 4) at ``reference_time`` and its covariance from x = (r_0, v_x, v_y) (scaled, at t_0).

    s = (r_0 u(φ_0), v); C_s = G C_x Gᵀ + Var(φ_0) r_0² u'(φ_0) u'(φ_0)ᵀ (position block),
    C_x = s_b² (HᵀH)⁻¹; then θ = D s + (o_0, 0) moved by A = [[I, Δt I], [0, I]].
    """
    u0x, u0y = direction(X0, convention)
    r0 = x[..., 0]
    s = np.stack([r0 * u0x, r0 * u0y, x[..., 1], x[..., 2]], axis=-1)
    G = np.zeros(x.shape[:-1] + (4, 3))
    G[..., 0, 0], G[..., 1, 0], G[..., 2, 1], G[..., 3, 2] = u0x, u0y, 1.0, 1.0
    cov_x = (np.asarray(residual_ss) / (n - 3))[..., None, None] * HtH_inv
    cov_s = G @ cov_x @ np.swapaxes(G, -1, -2)
    # ∂u/∂φ: north (cos φ, −sin φ) = (u_y, −u_x); math (−sin φ, cos φ) = (−u_y, u_x)
    du = np.stack([u0y, -u0x] if convention == "north" else [-u0y, u0x], axis=-1)
    cov_s[..., :2, :2] += (variance_phi0 * r0**2)[..., None, None] * du[..., :, None] * du[..., None, :]
    D = scaling_t0.factors
    A = np.eye(4)
    A[0, 2] = A[1, 3] = reference_time - scaling_t0.reference_time
    theta = scaling_t0.from_scaled(s) @ A.T
    cov = A @ (cov_s * D[..., :, None] * D[..., None, :]) @ A.T
    return theta, cov


@attrs.frozen
class NBearings(BearingsSolver):
    """N-bearings pseudo-linear least squares (seed 002 §4.4); closed form, biased by the first bearing's error.

    A batch by scaled normal equations and Cholesky (:func:`solve_normal`).  The observer must maneuver
    (else :class:`UnobservableError`).
    """

    name: ClassVar[str] = "n_bearings"
    needs_start: ClassVar[bool] = False
    example_problem = staticmethod(example_problem)

    def solve_rows(self, batch: BearingsBatch, numbers) -> BatchTMASolution:
        """The regression of every problem of ``batch`` (:func:`solve_normal`)."""
        n, conv = batch.size, batch.convention
        X = wrap_angle(batch.bearings)
        scaled = ScaledProblem.build(batch.times, X, batch.observer, None, batch.times[0], conv)
        H, b = pseudo_linear_system(scaled.tau, X, scaled.ox, scaled.oy, conv)
        x, HtH_inv, ok = solve_normal(H, b)
        residual = b - np.einsum("...ki,...i->...k", H, x)
        residual_ss = np.einsum("...k,...k->...", residual, residual)
        if not np.all(ok):
            warn_unobservable(int(np.size(ok) - np.count_nonzero(ok)), self.name)
        args = (x, HtH_inv, residual_ss, n, X[..., 0])
        theta, _ = assemble(*args, np.zeros(np.shape(residual_ss)), scaled.scaling, batch.reference_time, conv)
        # √Ka and the χ² test judge θ_N under the ML model, as the seed's table does (§5.1)
        at_ref = ScaledProblem.build(batch.times, X, batch.observer, None, batch.reference_time, conv)
        F, _ = at_ref.cost(at_ref.scaling.to_scaled(theta))
        ska, stat, pval, cons = fit_statistics(F, n, batch.sigma)
        variance_phi0 = batch.sigma**2 if batch.sigma is not None else ska**2
        theta, cov = assemble(*args, variance_phi0, scaled.scaling, batch.reference_time, conv)
        r0 = x[..., 0]
        fit = flag_constant_fits(batch, F, ok, numbers, self.name)
        converged = ok & (r0 > 0) & ~fit
        singular = "unobservable: the N-bearings system is singular"
        behind = "range r_0 ≤ 0: the bearings do not fit a target ahead of the observer"
        messages = (CONSTANT_FIT_MESSAGE if f else "closed form" if c else behind if o else singular for c, o, f in zip(converged, ok, fit))
        cov = np.where(fit[:, None, None], np.nan, cov)
        zeros = np.zeros(len(F), int)
        return answers(batch, theta, cov, F, (ska, stat, pval, cons), zeros, zeros, converged, messages, self.name)


@hookimpl
def register_solvers(registry):
    registry.add(NBearings.name, NBearings)
