"""Probabilistic data association filter bank, parametric PDA (SPEC §6; seed 004).

Bar-Shalom & Tse 1975; Bar-Shalom & Fortmann 1988, §6.4; Bar-Shalom, Daum &
Huang 2009, "The probabilistic data association filter", IEEE Control Systems
29(6), eqs. (21)–(27).  Seed 004 ("Алгоритм вероятностного объединения
данных"): the estimate is the β-weighted sum of the estimates conditioned on
each gated candidate being the target's, plus "none is the target".

With the candidates inside the χ² gate (d² ≤ γ, P(χ²_m ≤ γ) = P_G), e_i = exp(−½ d²_i),

    b   = λ √|2π S| (1 − P_D P_G) / P_D                       (parametric: λ known)
    β_i = e_i / (b + Σ_j e_j),   β_0 = b / (b + Σ_j e_j)
    ν   = Σ_i β_i ν_i,   x⁺ = x⁻ + K ν,   K = P⁻ Hᵀ S⁻¹
    P⁺  = β_0 P⁻ + (1 − β_0) Pᶜ + K [Σ_i β_i ν_i ν_iᵀ − ν νᵀ] Kᵀ,   Pᶜ = (I − K H) P⁻

(Pᶜ in Joseph form by default).  With λ = 0, P_D = 1 and no gate, b = 0 and a
single candidate gets β_1 = 1 exactly: the update is the Kalman filter's.  The
association likelihood ln Λ of each scan (module
:mod:`~hybridtrack_plugins.filters._association`) is in the innovation's
``associations`` for mode comparison in clutter.
"""

from __future__ import annotations

import numpy as np

from hybridtrack import hookimpl
from hybridtrack_plugins.filters._association import ClutterEstimator, pda_weights, set_clutter_model


class PDAFilter(ClutterEstimator):
    """Parametric PDA over a bank: ``detection_probability`` P_D in (0, 1], ``clutter_density`` λ ≥ 0
    (false measurements per unit measurement volume per step), ``gate_probability`` P_G in (0, 1)
    or ``None`` (no gate, P_G = 1)."""

    name = "pda"
    example_parameters = {"detection_probability": 0.9, "clutter_density": 0.01, "gate_probability": 0.99}

    def __init__(
        self, detection_probability: float = 1.0, clutter_density: float = 0.0, gate_probability: float | None = 0.99, form: str = "joseph"
    ):
        super().__init__(gate_probability, form)
        set_clutter_model(self, detection_probability, clutter_density, gate_probability)

    @property
    def exact_kalman(self) -> bool:
        """λ = 0, P_D = 1, no gate: the Kalman filter exactly (for one candidate per step)."""
        return self.clutter_density == 0.0 and self.detection_probability == 1.0 and self.gate_probability is None

    def associate(self, d2, gated, L):
        beta, beta0, loglik = pda_weights(d2, gated, L, self.detection_probability, self.clutter_density, self.log_miss)
        selected = np.where(gated.any(axis=1), np.argmax(beta, axis=1), -1) if beta.shape[1] else np.full(beta.shape[0], -1)
        return beta, beta0, selected.astype(np.int64), loglik


@hookimpl
def register_estimators(registry):
    registry.add(PDAFilter.name, PDAFilter)
