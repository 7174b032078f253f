"""Extended Kalman filter banks, covariance and square-root (SPEC §3 "EKF"; seed 003).

The EKF linearizes f and h at the current estimate:

* predict: ``transitions`` is a callable x (M, n) → TransitionBank giving, at
  each filter's x⁺, F = ∂f/∂x and B = f(x⁺) − F x⁺ (e.g.
  ``ShipTurn(...).linearizer(tau)``), so x⁻ = F x⁺ + B = f(x⁺) and
  P⁻ = F P⁺ Fᵀ + Γ Q Γᵀ; a plain TransitionBank works as for the linear filter;
* update: ẑ = h(x⁻), H = ∂h/∂x at x⁻, ν = residual(z, ẑ) (angles wrapped by
  the sensor), then the linear update with that H.

``ekf`` is the covariance form (Joseph update); ``ekf_sqrt`` the Potter
square-root form with scalar processing of the whitened measurement, as
seed 003 recommends; ``ekf_ud`` the Bierman UD form.
"""

from __future__ import annotations

from hybridtrack import hookimpl
from hybridtrack_plugins.filters.bierman import BiermanFilter
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.filters.potter import PotterFilter


class ExtendedKalmanFilter(KalmanFilter):
    """Extended Kalman filter bank, covariance form (relinearizes f and h at the current estimate)."""

    name = "ekf"
    accepts_nonlinear = True


class SquareRootExtendedKalmanFilter(PotterFilter):
    """Extended Kalman filter bank, Potter square-root form with scalar measurement processing (seed 003)."""

    name = "ekf_sqrt"
    accepts_nonlinear = True


class UDExtendedKalmanFilter(BiermanFilter):
    """Extended Kalman filter bank, Bierman UD form (seed 003, "Bierman style")."""

    name = "ekf_ud"
    accepts_nonlinear = True


@hookimpl
def register_estimators(registry):
    for estimator in (ExtendedKalmanFilter, SquareRootExtendedKalmanFilter, UDExtendedKalmanFilter):
        registry.add(estimator.name, estimator)
