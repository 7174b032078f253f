"""Structure-exploiting covariance KF for axis-separable banks (ARCHITECTURE.md, "The hot path").

When F and G Q Gᵀ of every filter are block diagonal over the same partition
of the state into equal-size blocks ("axes": (x, vx) and (y, vy) for the
4-state modes of SPEC §1, Φ = blockdiag(Φ_axis, Φ_axis)), the prior P is block
diagonal too, and each measured row selects one component of one axis with R
diagonal, then the KF splits exactly into independent d-state filters, one per
axis, each with a scalar measurement.  P stays block diagonal after every step.

Storage is "structure of arrays" with the bank last: x as (d, A, M), P as
(d, d, A, M) (A axes, M filters), so every line below is one vectorized
operation over all axes and filters at once.  The maths is that of
``_covariance`` (seed 000 Algorithm 1) written out for a scalar update
h = e_c, r on each axis:

    s = P_cc + r,  k = P_:c / s,  ν = z − x_c,  x⁺ = x + k ν,
    Joseph:     P⁺ = P − k P_c:ᵀ − P_:c kᵀ + s k kᵀ   (= (I − k hᵀ) P (I − k hᵀ)ᵀ + r k kᵀ)
    symmetric:  P⁺ = P − s k kᵀ                          (= P − K S Kᵀ)
    ℓ = −½ Σ_axes (ln 2π + ln s + ν²/s)   (the axes are independent given the prior)

Both P⁺ forms are exactly symmetric as computed.  ν, S = diag(s) and ℓ equal
those of the dense filter on the stacked model.
"""

from __future__ import annotations

import attrs
import numpy as np

from hybridtrack.sdk.linalg import LOG_2PI


def partition(pattern: np.ndarray) -> tuple[tuple[int, ...], ...] | None:
    """Connected components of a symmetric (n, n) boolean pattern with a true diagonal (the rows of its transitive
    closure, by repeated squaring), or None unless all have the same size ≥ 1 and there are ≥ 2."""
    reach = pattern
    for _ in range(pattern.shape[0].bit_length()):  # k squarings: every path of length ≤ 2^k > n
        reach = reach @ reach
    blocks = sorted({tuple(np.flatnonzero(row).tolist()) for row in reach})
    if len(blocks) < 2 or len({len(b) for b in blocks}) != 1:
        return None
    return tuple(blocks)


@attrs.frozen(eq=False)
class SeparableBank:
    """A transition bank split by axes: F, Q as (d, d, A, M), B as (d, A, M)."""

    axes: tuple[tuple[int, ...], ...]
    F: np.ndarray
    B: np.ndarray
    Q: np.ndarray


def split_bank(F: np.ndarray, B: np.ndarray, Q: np.ndarray) -> SeparableBank | None:
    """The bank's axis partition and blocks, or None when F, Q couple the state unevenly."""
    pattern = (F != 0).any(axis=0) | (Q != 0).any(axis=0)
    pattern = pattern | pattern.T | np.eye(F.shape[-1], dtype=bool)
    axes = partition(pattern)
    if axes is None:
        return None
    idx = np.array(axes)  # (A, d)
    Fa = F[:, idx[:, :, None], idx[:, None, :]]  # (M, A, d, d)
    Qa = Q[:, idx[:, :, None], idx[:, None, :]]
    Ba = B[:, idx]  # (M, A, d)
    return SeparableBank(
        axes,
        np.ascontiguousarray(Fa.transpose(2, 3, 1, 0)),
        np.ascontiguousarray(Ba.transpose(2, 1, 0)),
        np.ascontiguousarray(Qa.transpose(2, 3, 1, 0)),
    )


def is_block_diagonal(P: np.ndarray, axes) -> bool:
    """True when P (M, n, n) has no entries coupling different axes."""
    idx = np.array(axes)
    inside = np.zeros(P.shape[-2:], dtype=bool)
    inside[idx[:, :, None], idx[:, None, :]] = True
    return not P[:, ~inside].any()


def to_blocks(x: np.ndarray, P: np.ndarray, axes) -> tuple[np.ndarray, np.ndarray]:
    """x (M, n), P (M, n, n) → xa (d, A, M), Pa (d, d, A, M)."""
    idx = np.array(axes)
    xa = x[:, idx].transpose(2, 1, 0)
    Pa = P[:, idx[:, :, None], idx[:, None, :]].transpose(2, 3, 1, 0)
    return np.ascontiguousarray(xa), np.ascontiguousarray(Pa)


def from_blocks(xa: np.ndarray, Pa: np.ndarray, axes, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`to_blocks` (cross-axis entries zero)."""
    d, A, M = xa.shape
    idx = np.array(axes)
    x = np.empty((M, n))
    x[:, idx] = xa.transpose(2, 1, 0)
    P = np.zeros((M, n, n))
    P[:, idx[:, :, None], idx[:, None, :]] = Pa.transpose(3, 2, 0, 1)
    return x, P


def predict(xa, Pa, bank: SeparableBank):
    """x⁻ = F x + B, P⁻ = F P Fᵀ + Q per axis and filter (einsum over the small block indices)."""
    x_new = np.einsum("ijam,jam->iam", bank.F, xa)
    x_new += bank.B
    T = np.einsum("ikam,kjam->ijam", bank.F, Pa)
    P_new = np.einsum("ikam,jkam->ijam", T, bank.F)
    P_new += bank.Q
    return x_new, P_new


def update(xa, Pa, c: int, axes_measured, z, r, form: str):
    """The scalar update of the module docstring, of component c on the measured axes (index array into A; None:
    all), z and r (A_m, 1 or M).  Returns x⁺, P⁺, ν (A_m, M), s (A_m, M), ℓ (M,), NIS (M,)."""
    full = axes_measured is None
    xs = xa if full else xa[:, axes_measured]
    Ps = Pa if full else Pa[:, :, axes_measured]
    s = Ps[c, c] + r
    if not (s > 0).all():
        raise np.linalg.LinAlgError("innovation covariance S is not positive definite")
    s_inv = 1.0 / s
    nu = z - xs[c]
    k = Ps[:, c] * s_inv  # (d, A_m, M)
    x_new = xs + k * nu
    kk = k[:, None] * k[None, :]
    kk *= s
    if form == "joseph":
        u = k[:, None] * Ps[c][None, :]
        u += np.swapaxes(u, 0, 1)
        P_new = Ps - u
        P_new += kk
    else:
        P_new = Ps - kk
    nis_axes = nu * nu * s_inv
    m = nu.shape[0]
    loglik = -0.5 * (LOG_2PI * m + np.log(s).sum(axis=0) + nis_axes.sum(axis=0)) if m > 1 else -0.5 * (LOG_2PI + np.log(s[0]) + nis_axes[0])
    if not full:
        xa = xa.copy()
        Pa = Pa.copy()
        xa[:, axes_measured] = x_new
        Pa[:, :, axes_measured] = P_new
        x_new, P_new = xa, Pa
    return x_new, P_new, nu, s, loglik, nis_axes.sum(axis=0)
