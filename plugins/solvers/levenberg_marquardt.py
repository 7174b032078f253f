"""Maximum likelihood TMA by Levenberg–Marquardt, one problem or a batch (seed 002 §4.3).

The seed's algorithm, on F(s) = Σ r_k², r = wrap(X − f(s)), J = ∂f/∂s:

1. start from s, λ = λ_0 (with λ_up, λ_down, F_tol);
2. compute F(s), J(s) and H = JᵀJ;
3. A = H + λ diag(H) (Marquardt's scaling);
4. if A is not positive definite: λ ← λ λ_up, back to 3;
5. solve A Δs = Jᵀ r (Cholesky);
6. s_new = s + Δs, ΔF = F(s) − F(s_new);
7. if ΔF < 0 (or F(s_new) is not finite): λ ← λ λ_up, back to 3 (a ΔF within
   rounding of F, |ΔF| ≤ 10⁻¹² F, counts as 0: see :data:`ROUNDING_RTOL`);
8. accept s ← s_new, λ ← λ λ_down;
9. stop if ΔF < F_tol, else back to 2.

Iterations count accepted steps (8), evaluations count F evaluations (the
start and every trial of 6) — the seed's "Iter" and "Nf".  Two guards the seed
does not state: at most ``max_iterations`` accepted steps, and λ > ``lam_max``
stops (no step decreases F); both end with ``converged=False``.  The solver
works in the scaled parameters of :mod:`.tma_model` (docs/tma.md, "Parameter scaling").

:class:`BatchLevenbergMarquardt` runs them for B problems (:func:`minimize_batch`, or the compiled kernel);
:class:`LevenbergMarquardt` is the same solver under the one-problem name (a batch of one).
"""

from __future__ import annotations

import importlib.util
from typing import ClassVar

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.validation import check_positive
from hybridtrack.sdk.linalg import cholesky_solve, masked_cholesky, wrap_angle
from hybridtrack_plugins.sensors.bearing import angle_difference, bearing, bearing_gradient
from hybridtrack_plugins.solvers.observer import example_problem
from hybridtrack_plugins.solvers.tma_model import (
    N_PARAMETERS,
    BatchTMASolution,
    BearingsBatch,
    BearingsSolver,
    Scaling,
    conclude,
    normal_equations,
    scaled_start,
    time_powers,
)

#: step 7 counts ΔF ≥ −ROUNDING_RTOL·F as "no increase": a change at the rounding level of F
#: (the batch's block matrix products may round F(θ) differently for the same θ) must not
#: push λ to overflow at a minimum
ROUNDING_RTOL = 1e-12

#: numba is installed: the batched LM's "auto" engine is the compiled kernel (imported on first use, so
#: that loading the plugins does not import numba)
NUMBA_AVAILABLE = importlib.util.find_spec("numba") is not None

STOP_CONVERGED = "ΔF < F_tol"
STOP_ITERATIONS = "max_iterations reached"
STOP_LAMBDA = "λ > lam_max: no step decreases F"


_positive = lambda instance, attribute, value: check_positive(value, attribute.name)


@attrs.frozen
class LMSettings:
    """The seed's hyper-parameters (seed 002 §4.3; values chosen here, the seed gives none).

    ``lam0`` λ_0, ``lam_up`` λ_up > 1, ``lam_down`` λ_down < 1, ``F_tol`` (rad²)
    the stop on the decrease ΔF of an accepted step, ``max_iterations`` and
    ``lam_max`` the guards.
    """

    lam0: float = attrs.field(default=1.0, converter=float, validator=_positive)
    lam_up: float = attrs.field(default=10.0, converter=float, validator=_positive)
    lam_down: float = attrs.field(default=0.1, converter=float, validator=_positive)
    F_tol: float = attrs.field(default=1e-12, converter=float, validator=_positive)
    max_iterations: int = attrs.field(default=100, converter=int, validator=_positive)
    lam_max: float = attrs.field(default=1e16, converter=float, validator=_positive)

    def __attrs_post_init__(self):
        if not self.lam_up > 1:
            raise ValueError(f"lam_up: expected > 1, got {self.lam_up}")
        if not self.lam_down < 1:
            raise ValueError(f"lam_down: expected < 1, got {self.lam_down}")


class _Chunk:
    """Scaled data of one chunk of problems, compacted to the active ones as they stop.

    :meth:`evaluate` walks the rows in blocks of ``block`` problems so that its
    (block, n) work arrays, allocated once, stay in cache.
    """

    def __init__(self, tau, ox, oy, X, convention, block=32):
        self.tau, self.ox, self.oy, self.X, self.convention = tau, ox, oy, X, convention
        self.powers = time_powers(tau)
        self.block = block
        n = X.shape[1]
        self._work = np.empty((6, block, n))
        self._W = np.empty((block, 5, n))
        # shared observer: Δx = [s_0, s_2, 1]·[1, τ, −õx], Δy = [s_1, s_3, 1]·[1, τ, −õy], one small matrix product each
        if ox.ndim == 1:
            self._basis_x = np.stack([np.ones_like(tau), tau, -ox])
            self._basis_y = np.stack([np.ones_like(tau), tau, -oy])

    def evaluate(self, s):
        """F, H = JᵀJ and g = Jᵀr at s (m, 4): the trial of step 6 plus step 2 in case it is accepted."""
        m = s.shape[0]
        F, H, g = np.empty(m), np.empty((m, 4, 4)), np.empty((m, 4))
        shared = self.ox.ndim == 1
        if shared:
            ones = np.ones(m)
            Sx, Sy = np.stack([s[:, 0], s[:, 2], ones], axis=1), np.stack([s[:, 1], s[:, 3], ones], axis=1)
        for a in range(0, m, self.block):
            b = min(a + self.block, m)
            dx, dy, phi, p, q, w = self._work[:, : b - a]
            if shared:
                np.matmul(Sx[a:b], self._basis_x, out=dx)
                np.matmul(Sy[a:b], self._basis_y, out=dy)
            else:
                for d, i, o in ((dx, 0, self.ox), (dy, 1, self.oy)):  # Δ = s_i + s_{i+2} τ − õ
                    np.multiply(s[a:b, i + 2, None], self.tau, out=d)
                    d += s[a:b, i, None]
                    d -= o[a:b]
            bearing(dx, dy, self.convention, out=phi)
            r = angle_difference(self.X[a:b], phi, out=phi)
            F[a:b] = np.einsum("mk,mk->m", r, r)
            bearing_gradient(dx, dy, self.convention, out=(p, q, w))
            H[a:b], g[a:b] = normal_equations(p, q, r, self.powers, out=self._W[: b - a])
        return F, H, g

    def keep(self, rows):
        self.X = self.X[rows]
        if self.ox.ndim == 2:
            self.ox, self.oy = self.ox[rows], self.oy[rows]


def minimize_batch(chunk: _Chunk, s: np.ndarray, settings: LMSettings):
    """Seed 002 §4.3 for m problems at once; each keeps its own λ and stopping rule.

    Returns arrays (s, F, H, iterations, evaluations, status) with status
    0 converged, 1 max_iterations, 2 λ overflow.
    """
    m = s.shape[0]
    out_s, out_F, out_H = np.empty((m, 4)), np.empty(m), np.empty((m, 4, 4))  # every row is written when it stops
    out_it, out_nf, out_status = np.empty(m, int), np.empty(m, int), np.empty(m, int)
    ids = np.arange(m)
    F, H, g = chunk.evaluate(s)
    lam = np.full(m, settings.lam0)
    it, nf = np.zeros(m, int), np.ones(m, int)
    diag = np.arange(4)
    while ids.size:
        A = H.copy()
        A[:, diag, diag] *= 1.0 + lam[:, None]  # step 3
        L, ok = masked_cholesky(A)  # step 4
        delta = cholesky_solve(L, g)
        delta[~ok] = 0.0
        s_new = s + delta  # steps 5–6 (rows not ok are evaluated at s and ignored)
        F_new, H_new, g_new = chunk.evaluate(s_new)
        nf += ok
        dF = F - F_new
        accept = ok & np.isfinite(F_new) & (dF >= -ROUNDING_RTOL * F)
        lam = np.where(accept, lam * settings.lam_down, lam * settings.lam_up)  # steps 7–8
        it += accept
        stop = np.select(
            [accept & (dF < settings.F_tol), accept & (it >= settings.max_iterations), ~accept & (lam > settings.lam_max)], [0, 1, 2], -1
        )
        s = np.where(accept[:, None], s_new, s)
        F = np.where(accept, F_new, F)
        H = np.where(accept[:, None, None], H_new, H)  # step 2 at the new s
        g = np.where(accept[:, None], g_new, g)
        done = stop >= 0
        if done.any():
            d = np.flatnonzero(done)
            rows = ids[d]
            out_s[rows], out_F[rows], out_H[rows] = s[d], F[d], H[d]
            out_it[rows], out_nf[rows], out_status[rows] = it[d], nf[d], stop[d]
            keep = np.flatnonzero(~done)
            ids, s, F, H, g, lam, it, nf = (v[keep] for v in (ids, s, F, H, g, lam, it, nf))
            chunk.keep(keep)
    return out_s, out_F, out_H, out_it, out_nf, out_status


#: coordinate swap x ↔ y of s = (x0, y0, vx, vy): the "math" convention is the mirror image of "north"
_MIRROR = np.array([1, 0, 3, 2])
ENGINES = ("auto", "numba", "numpy")


def _check_engine(engine):
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    if engine == "numba" and not NUMBA_AVAILABLE:
        raise ValueError("engine: 'numba' asked for but numba is not installed (pip install numba), use 'auto' or 'numpy'")


def minimize_compiled(tau, ox, oy, X, convention, s, settings: LMSettings):
    """:func:`minimize_batch` by the numba kernel (:func:`._tma_kernel.minimize_problems`), one problem at a time.

    õx, õy (n,) shared or (m, n); X (m, n); s (m, 4).  The kernel works in the
    "north" convention (φ = atan2(Δx, Δy)); "math" (φ = atan2(Δy, Δx)) is the same
    problem with x and y swapped, so its data and s are mirrored in and s, H
    mirrored back (H ← P H P, P the swap).  Returns (s, F, H, iterations,
    evaluations, status) as :func:`minimize_batch`.
    """
    from hybridtrack_plugins.solvers import _tma_kernel

    if convention != "north":
        ox, oy, s = oy, ox, s[:, _MIRROR]
    arrays = [np.ascontiguousarray(a, dtype=float) for a in (s, tau, np.atleast_2d(ox), np.atleast_2d(oy), X)]
    settings = attrs.astuple(settings) + (ROUNDING_RTOL,)  # (λ_0, λ_up, λ_down, F_tol, max_iterations, λ_max) in field order
    out_s, out_F, out_H, out_it, out_nf, out_status = _tma_kernel.minimize_problems(*arrays, settings)
    if convention != "north":
        out_s, out_H = out_s[:, _MIRROR], out_H[:, _MIRROR][:, :, _MIRROR]
    return out_s, out_F, out_H, out_it, out_nf, out_status


@attrs.frozen
class BatchLevenbergMarquardt(BearingsSolver):
    """The seed's Levenberg–Marquardt vectorized over many independent problems (one per Monte Carlo target).

    Problems are processed ``chunk_size`` at a time (bounding memory); the answers
    do not depend on it.  ``engine``: "numba" the compiled kernel of
    :mod:`._tma_kernel`, "numpy" :func:`minimize_batch`, "auto" (default) the
    kernel when numba is installed (the two agree to ~10⁻¹⁴ relative).
    """

    name: ClassVar[str] = "levenberg_marquardt_batch"
    example_problem = staticmethod(example_problem)

    settings: LMSettings = attrs.field(factory=LMSettings)
    chunk_size: int = attrs.field(default=1024, converter=int, validator=_positive)
    engine: str = attrs.field(default="auto", validator=lambda i, a, v: _check_engine(v))

    @property
    def compiled(self) -> bool:
        """True when the numba kernel (:mod:`._tma_kernel`) runs the iterations, False for the numpy path."""
        return self.engine == "numba" or (self.engine == "auto" and NUMBA_AVAILABLE)

    def solve_rows(self, batch: BearingsBatch, numbers: np.ndarray) -> BatchTMASolution:
        B = len(batch)
        theta0 = np.broadcast_to(batch.initial, (B, N_PARAMETERS))
        scaling = Scaling.build(batch.times, batch.observer, theta0, batch.reference_time)
        s0 = scaling.to_scaled(theta0)
        tau = scaling.tau(batch.times)
        shared = batch.observer.ndim == 2 and np.ndim(scaling.length) == 0
        if shared:
            o = scaling.observer(batch.observer)
        s, F, H = np.empty((B, 4)), np.empty(B), np.empty((B, 4, 4))
        it, nf, status = np.empty(B, int), np.empty(B, int), np.empty(B, int)
        for start in range(0, B, self.chunk_size):
            rows = slice(start, min(start + self.chunk_size, B))
            if not shared:
                own = batch.observer.ndim == 3  # one observer path per problem
                origin = scaling.origin[rows] if own else scaling.origin
                part = attrs.evolve(scaling, origin=origin, length=np.broadcast_to(scaling.length, (B,))[rows])
                o = part.observer(batch.observer[rows] if own else batch.observer)
            if self.compiled:
                out = minimize_compiled(tau, o[..., 0], o[..., 1], batch.bearings[rows], batch.convention, s0[rows], self.settings)
            else:
                chunk = _Chunk(tau, o[..., 0], o[..., 1], wrap_angle(batch.bearings[rows]), batch.convention)
                with np.errstate(divide="ignore", invalid="ignore"):  # a zero range gives NaN F or H: checked below
                    out = minimize_batch(chunk, s0[rows].copy(), self.settings)
            s[rows], F[rows], H[rows], it[rows], nf[rows], status[rows] = out
            # a start on the observer gives a NaN F or H that no step can leave: name the problem
            for i in rows.start + np.flatnonzero(~(np.isfinite(F[rows]) & np.isfinite(H[rows]).all(axis=(1, 2)))):
                scaled_start(batch, i, theta0[i], numbers[i])
        messages = np.array([STOP_CONVERGED, STOP_ITERATIONS, STOP_LAMBDA], dtype=object)[status]
        return conclude(batch, scaling, s, F, H, it, nf, status == 0, messages, numbers, self.name)


@attrs.frozen
class LevenbergMarquardt(BatchLevenbergMarquardt):
    """Maximum likelihood θ of one problem by the seed's Levenberg–Marquardt (see the module doc): the batched
    solver under its one-problem name, ``solve(problem)`` a batch of one."""

    name: ClassVar[str] = "levenberg_marquardt"


@hookimpl
def register_solvers(registry):
    for solver in (LevenbergMarquardt, BatchLevenbergMarquardt):
        registry.add(solver.name, solver)
