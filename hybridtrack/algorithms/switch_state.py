"""A motion mode with its switch state carried in the filter state: the switch estimate is refined by the data.

A mode whose transition depends on the state at the switching moment s (a
turn fixes ω = |v_s|/r and the centre c(x_s) there, SPEC §1) is usually built
from the filtered estimate x̂_{s|s}; its error then biases the whole segment
(an orbit about the wrong centre), and the hypothesis test with it.  Here each
filter estimates the switch state jointly with the current state, so the
transition is effectively rebuilt from the smoothed switch estimate
x̂_{s|k} = E[x_s | z_1 … z_k] as data arrive.

Augmented state ζ = (x, s), n + n components, s constant.  With the mode's
transition x_{k+1} = F(s) x_k + B(s) + G w linearized in s about the estimate
ŝ it was created with (F's dependence on s, through ω, is kept at ŝ):

    x_{k+1} = F(ŝ) x_k + D s + (B(ŝ) − D ŝ) + G w,   D = ∂B/∂s |_ŝ
    s_{k+1} = s

so the augmented transition is linear: F_ζ = [[F, D], [0, I]],
B_ζ = [B − D ŝ; 0], G_ζ = [G; 0].  For the turns of seed 000, B = (I − F) E c(s)
with E placing the centre on the position components, so D carries the
centre's sensitivity to the switch position and velocity.  D is taken by
forward differences of ``transition(τ, ·).B`` (any mode, through the
:class:`~hybridtrack.core.interfaces.MotionModel` interface only).

At a switch the filters start from N(ζ̂, P_ζ) with ζ̂ = (x̂_s, x̂_s) and
P_ζ = [[P, P], [P, P + εI]]: x and s are the same random vector at the switch
(ε keeps P_ζ positive definite for the Cholesky-based estimators).  This is
the "smooth back to the switch" of the seed-001 issue done recursively: the
s-part of the filter's estimate is the fixed-interval smoothed switch state
under that hypothesis (Rauch, Tung & Striebel 1965, state augmentation form;
Bar-Shalom, Li & Kirubarajan 2001, §8.6).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridtrack.core.interfaces import LinearTransition, MotionModel

#: suffix of the switch-state components in the augmented layout
SWITCH_SUFFIX = "_switch"


def augmented_layout(layout: Sequence[str]) -> tuple[str, ...]:
    """(x components…, x components + ``_switch``…)."""
    return tuple(layout) + tuple(f"{c}{SWITCH_SUFFIX}" for c in layout)


def augmented_prior(mean: np.ndarray, cov: np.ndarray, epsilon: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """ζ̂ = (x̂, x̂), P_ζ = [[P, P], [P, P + ε s I]] (x = s at the switch; s = max(1, max diag P))."""
    mean, cov = np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)
    n = mean.shape[0]
    P = np.empty((2 * n, 2 * n))
    P[:n, :n] = P[:n, n:] = P[n:, :n] = P[n:, n:] = cov
    P[n:, n:] += epsilon * max(1.0, float(np.max(np.diag(cov)))) * np.eye(n)
    return np.concatenate([mean, mean]), P


class SwitchAugmented(MotionModel):
    """``base`` with its switch state carried in the filter state (module docstring).

    ``relinearize=False``: a linear model, linearized once at the switch
    estimate ŝ it is created with (ω kept at ŝ): F_ζ = [[F(ŝ), D], [0, I]],
    D = ∂B/∂s at ŝ, B_ζ = [B(ŝ) − D ŝ; 0].  ``relinearize=True``: the nonlinear
    model f(ζ) = (F(s) x + B(s), s), linearized at the filter's own estimate
    ζ̂ = (x̂, ŝ) every step (EKF; ω follows the refined switch speed):
    J = ∂(F(s) x̂ + B(s))/∂s at ŝ replaces D, so that F_ζ ζ̂ + B_ζ = f(ζ̂).
    Derivatives by forward differences of ``base.transition``.
    """

    def __init__(self, base: MotionModel, relinearize: bool = False):
        if not base.linear:
            raise ValueError(f"base: {base.name!r} is nonlinear; the switch-state augmentation needs a linear mode")
        self.base = base
        self.relinearize = bool(relinearize)
        self.linear = not self.relinearize
        self.name = base.name
        self.radius = base.radius
        self.layout = augmented_layout(base.layout)
        self.noise_cov = base.noise_cov

    def transition(self, tau: float, switch_state: np.ndarray) -> LinearTransition:
        """F_ζ, B_ζ, G_ζ, Q at ``switch_state`` = ζ̂ = (x̂, ŝ): the state at the switch, or the current estimate (EKF)."""
        n = len(self.base.layout)
        zeta = np.asarray(switch_state, dtype=float)
        x_hat, s_hat = zeta[:n], zeta[n:]
        t = self.base.transition(tau, s_hat)
        f = t.apply(x_hat) if self.relinearize else t.B
        J = np.empty((n, n))
        for j in range(n):  # forward differences: J enters the linearization only (f itself is exact)
            h = 1e-7 * max(1.0, abs(s_hat[j]))
            up = s_hat.copy()
            up[j] += h
            shifted = self.base.transition(tau, up)
            J[:, j] = ((shifted.apply(x_hat) if self.relinearize else shifted.B) - f) / h
        F = np.block([[t.F, J], [np.zeros((n, n)), np.eye(n)]])
        B = np.concatenate([t.B - J @ s_hat, np.zeros(n)])
        G = np.vstack([t.G, np.zeros((n, t.G.shape[1]))])
        return LinearTransition(F, B, G, t.Q)
