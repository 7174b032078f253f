"""Nearest-neighbour filter bank in clutter (SPEC §6; seed 004; Bar-Shalom & Fortmann 1988, §6.2).

Each filter of the bank takes, among the candidates inside its χ² gate
d² = νᵀS⁻¹ν ≤ γ (γ the χ²_m quantile of the gate probability P_G), the one
nearest in Mahalanobis distance,

    i* = argmin_{i : d²_i ≤ γ} d²_i,

and updates with it as a Kalman filter (x⁺ = x⁻ + K ν_{i*}, P⁺ = (I − K H) P⁻,
Joseph form by default).  Nothing gated: prediction only (x⁺ = x⁻, P⁺ = P⁻).
The covariance ignores that the chosen candidate may be clutter, which is why
NN loses the track in dense clutter (seed 004: "метод ближайшего соседа ...
не требует знаний об окружающей среде").

Gating, distances and the shared update are in
:mod:`hybridtrack_plugins.filters._association`.
"""

from __future__ import annotations

from hybridtrack import hookimpl
from hybridtrack_plugins.filters._association import ClutterEstimator, nearest_weights


class NearestNeighbourFilter(ClutterEstimator):
    """Covariance KF bank updating each filter with its nearest gated candidate.

    ``gate_probability`` P_G in (0, 1) sets γ; ``None`` means no gate (the
    nearest candidate is always taken — with one candidate per step this is
    exactly the Kalman filter).  ``form`` as for ``kalman``.
    """

    name = "nearest_neighbour"
    example_parameters = {"gate_probability": 0.99}

    @property
    def exact_kalman(self) -> bool:
        """Without a gate and with one candidate per step (a plain z) NN is the Kalman filter."""
        return self.gate_probability is None

    associate = staticmethod(nearest_weights)


@hookimpl
def register_estimators(registry):
    registry.add(NearestNeighbourFilter.name, NearestNeighbourFilter)
