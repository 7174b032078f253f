"""Shared plumbing of the detectors that watch one N(0, 1) sequence (GLR, CUSUM; seed 003).

The sequence is either given directly (:meth:`ScalarDetector.observe_value`,
e.g. angular-rate estimates) or taken from the bank: the NIS of filter
``watch``.  Raw values are normalized ỹ = Φ⁻¹(F̂(y)) through the empirical CDF
of ``reference`` (a sample of the raw signal under H_0); for the NIS without a
reference, the reference is a seeded sample of χ²(m), the NIS distribution of
the correct model.  The threshold is λ(α), the (1 − α) quantile of the
statistic under H_0 from seeded simulation (:mod:`.null_calibration`); setting ``alpha``
moves it (dynamic thresholds).

The seeded simulation feeds the statistic independent N(0, 1) values (seed 003);
for an autocorrelated input (why: docs/detectors.md, "GLR / CUSUM") ``null_sample``
replaces it by values of the statistic on the actual signal under H_0 (e.g.
:func:`.null_calibration.glr_statistics` on normalized estimates of simulated
straight runs); λ(α) is then its (1 − α) quantile.
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from hybridtrack.core.interfaces import DetectorStep
from hybridtrack.core.protocols import ScoreDetector
from hybridtrack.core.types import Decision
from hybridtrack.core.validation import check_positive_int
from hybridtrack.sdk.thresholds import check_probability
from hybridtrack_plugins.detectors.null_calibration import EmpiricalNormalizer, h0_quantile, sorted_sample

REFERENCE_SIZE = 20000


class ScalarDetector(ScoreDetector):
    """A change detector on one normalized sequence with a threshold λ(α) from H0 quantiles."""

    def __init__(
        self, alpha: float = 0.001, watch: int = 0, reference=None, normalize: bool = True, seed: int = 20240601, null_sample=None
    ):
        self.watch = check_positive_int(watch, "watch", minimum=0)
        self.normalize = bool(normalize)
        self.seed = int(seed)
        self._normalizer = None if reference is None else EmpiricalNormalizer(reference)
        self._chi2_normalizers: dict[int, EmpiricalNormalizer] = {}
        self._null = None if null_sample is None else sorted_sample(null_sample, "null_sample", "the statistic")
        self.alpha = alpha
        self.reset()

    def threshold_sample(self) -> np.ndarray:
        """The sorted H0 sample λ(α) is taken from: ``null_sample`` if given, else :meth:`h0_sample`."""
        return self._null if self._null is not None else self.h0_sample()

    @property
    def alpha(self) -> float:
        """Per-step false-alarm probability under H_0; the threshold is its (1 − α) H0 quantile."""
        return self._alpha

    @alpha.setter
    def alpha(self, value) -> None:
        self._alpha = check_probability(value, "alpha")
        self.threshold = self.threshold_for(self._alpha)

    def threshold_for(self, alpha) -> float:
        """λ(α) without changing the detector."""
        return h0_quantile(self.threshold_sample(), alpha)

    @abstractmethod
    def h0_sample(self) -> np.ndarray:
        """Sorted H0 sample of the statistic on seeded independent N(0, 1) input (cached)."""

    @abstractmethod
    def update_statistic(self, y: float) -> float:
        """Consume one normalized value, return the statistic g_n."""

    def normalized(self, value: float, m: int | None = None) -> float:
        if not self.normalize:
            return float(value)
        if self._normalizer is not None:
            return float(self._normalizer(value))
        if m is None:
            raise ValueError("reference: a raw value needs a reference sample under H0 to normalize (or normalize=False)")
        if m not in self._chi2_normalizers:
            draws = np.random.default_rng([self.seed, m]).chisquare(m, REFERENCE_SIZE)
            self._chi2_normalizers[m] = EmpiricalNormalizer(draws)
        return float(self._chi2_normalizers[m](value))

    def observe_value(self, step: int, value: float, m: int | None = None) -> DetectorStep:
        """Consume one raw value of the watched sequence."""
        y = self.normalized(value, m)
        g = self.update_statistic(y)
        decision = None
        if g > self.threshold:
            decision = Decision(
                step, self.label, "change", g, f"{self.name} statistic {g:.2f} > λ(α = {self.alpha:g}) = {self.threshold:.2f}"
            )
            self.reset()
        return DetectorStep({"statistic": g, "normalized": y}, {"threshold": self.threshold}, decision)

    def observe(self, step, loglik, nis, m) -> DetectorStep:
        nis = np.atleast_1d(np.asarray(nis, dtype=float))
        if self.watch >= nis.shape[0]:
            raise ValueError(f"watch: filter {self.watch} is not in a bank of {nis.shape[0]} filters")
        if m == 0:  # no measurement: nothing to add
            return DetectorStep({"statistic": self.current(), "normalized": 0.0}, {"threshold": self.threshold})
        return self.observe_value(step, float(nis[self.watch]), int(m))

    @abstractmethod
    def current(self) -> float:
        """The statistic as it stands."""
