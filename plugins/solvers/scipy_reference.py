"""Reference ML solver on ``scipy.optimize.least_squares`` (an oracle for the seed's LM, seed 002 §4.2).

Minimizes the same F(s) = Σ wrap(X − f(s))² in the same scaled parameters
(:mod:`.tma_model`) from the same start, with the analytic Jacobian
∂r/∂s = −J.  ``method="lm"`` is MINPACK's ``lmder`` (Moré's trust-region
Levenberg–Marquardt); "trf" and "dogbox" are also accepted.  Iterations are
scipy's Jacobian evaluations (``njev``), evaluations its ``nfev``.
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np
from scipy.optimize import least_squares

from hybridtrack import hookimpl
from hybridtrack.core.validation import check_positive
from hybridtrack_plugins.solvers.observer import example_problem
from hybridtrack_plugins.solvers.tma_model import N_PARAMETERS, BearingsSolver, ScaledProblem, Scaling, conclude, scaled_start

_tolerance = lambda instance, attribute, value: check_positive(value, attribute.name, "a tolerance")


@attrs.frozen
class ScipyLeastSquares(BearingsSolver):
    """ML θ by ``scipy.optimize.least_squares`` with the analytic Jacobian (reference variant)."""

    name: ClassVar[str] = "scipy_least_squares"
    example_problem = staticmethod(example_problem)

    method: str = attrs.field(default="lm", validator=attrs.validators.in_(("lm", "trf", "dogbox")))
    ftol: float = attrs.field(default=1e-10, converter=float, validator=_tolerance)
    xtol: float = attrs.field(default=1e-10, converter=float, validator=_tolerance)
    gtol: float = attrs.field(default=1e-10, converter=float, validator=_tolerance)

    def residual_functions(self, scaled: ScaledProblem):
        """(fun, jac) of s for ``least_squares``: r(s) = wrap(X − f(s)) and ∂r/∂s = −J(s)."""
        return scaled.residuals, lambda s: -scaled.jacobian(s)

    def solve_rows(self, batch, numbers):
        """:meth:`least_squares` problem by problem from its ``initial`` guess; the answers by :func:`.tma_model.conclude`."""
        theta0 = np.broadcast_to(batch.initial, (len(batch), N_PARAMETERS))
        answers = [self.least_squares(*scaled_start(batch, i, theta0[i], numbers[i])) for i in range(len(batch))]
        s, F, H, *rest = zip(*answers)
        scaling = Scaling.build(batch.times, batch.observer, theta0, batch.reference_time)
        return conclude(batch, scaling, np.array(s), np.array(F), np.array(H), *rest, numbers, self.name)

    def least_squares(self, scaled: ScaledProblem, s0: np.ndarray):
        """``least_squares`` from s0: (s, F, JᵀJ, iterations = njev, evaluations = nfev, converged, message)."""
        fun, jac = self.residual_functions(scaled)
        result = least_squares(fun, s0, jac=jac, method=self.method, ftol=self.ftol, xtol=self.xtol, gtol=self.gtol)
        J = scaled.jacobian(result.x)
        njev = result.njev if result.njev is not None else result.nfev
        return result.x, float(result.fun @ result.fun), J.T @ J, njev, result.nfev, result.status > 0, result.message


@hookimpl
def register_solvers(registry):
    registry.add(ScipyLeastSquares.name, ScipyLeastSquares)
