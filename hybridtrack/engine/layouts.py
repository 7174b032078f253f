"""State layouts of different sizes in one bank: the union layout and what a model says about the components it lacks.

Models of different state sizes (the 6-state ``constant_acceleration``
("x", "vx", "ax", "y", "vy", "ay") beside the 4-state ("x", "vx", "y", "vy"),
a turn-rate mode with ω) are compared, mixed and read in the *union layout*:
the largest model layout when it contains every other, otherwise the ordered
union of the layouts.  A filter's estimate (x̂, P) in its model's layout is
expanded to it by component name with mean ``missing_mean`` (default 0) and
variance ``missing_variance`` (default 1, in that component's units², e.g.
(m/s²)² for an acceleration) for each component the model lacks, uncorrelated
with the rest — what a model without an acceleration says about it: "zero,
give or take σ"; an estimate in the union layout is given to a model as its
marginal on the model's components (the sub-vector and sub-matrix of a
Gaussian).  Bar-Shalom, Li & Kirubarajan 2001, §11.6.6, mix models of one
state; the expansion is the usual augmentation of the smaller models.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np


def union_layout(layouts: Sequence[Sequence[str]]) -> tuple[str, ...]:
    """The largest layout if it contains every other one, else the ordered union (first appearance)."""
    layouts = [tuple(layout) for layout in layouts]
    largest = max(layouts, key=len)
    if all(set(layout) <= set(largest) for layout in layouts):
        return largest
    union: list[str] = []
    for layout in layouts:
        union += [name for name in layout if name not in union]
    return tuple(union)


class LayoutFill:
    """The union ``layout`` with the mean and variance a model gives each component it lacks (module docstring).

    ``missing_mean`` / ``missing_variance``: a number for every component, or a
    mapping component → value (defaults 0 and 1); variances positive, all finite.
    """

    def __init__(
        self, layout: Sequence[str], missing_mean: float | Mapping[str, float] = 0.0, missing_variance: float | Mapping[str, float] = 1.0
    ):
        self.layout = tuple(layout)
        self.mean = self._per_component(missing_mean, "missing_mean", positive=False)
        self.variance = self._per_component(missing_variance, "missing_variance", positive=True)
        self._lacking_cache: dict[bytes, np.ndarray] = {}

    def _per_component(self, value, name: str, positive: bool) -> np.ndarray:
        if isinstance(value, Mapping):
            unknown = sorted(set(value) - set(self.layout))
            if unknown:
                raise ValueError(f"{name}: components {unknown} are not in the union layout {self.layout}")
            default = 1.0 if positive else 0.0
            out = np.array([float(value.get(c, default)) for c in self.layout])
        else:
            out = np.full(len(self.layout), float(value))
        if not np.all(np.isfinite(out)) or (positive and np.any(out <= 0)):
            raise ValueError(f"{name}: expected {'positive ' if positive else ''}finite values, got {value!r}")
        return out

    def positions(self, layout: Sequence[str], what: str = "layout") -> np.ndarray:
        """Where the components of ``layout`` stand in the union layout (a ValueError naming ``what`` if one is not there)."""
        missing = [c for c in layout if c not in self.layout]
        if missing:
            raise ValueError(f"{what}: components {missing} are not in the bank's layout {self.layout}")
        return np.array([self.layout.index(c) for c in layout], dtype=np.intp)

    def expand(self, means: np.ndarray, covs: np.ndarray, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(…, n_j) means and covariances of the union-layout components at ``positions`` in the union layout; each
        component they lack at the missing mean with the missing variance, uncorrelated with the rest."""
        n = len(self.layout)
        lacking = self.lacking(positions)
        x = np.broadcast_to(self.mean, means.shape[:-1] + (n,)).copy()
        x[..., positions] = means
        P = np.zeros(covs.shape[:-2] + (n, n))
        P[..., lacking, lacking] = self.variance[lacking]
        P[..., positions[:, None], positions[None, :]] = covs
        return x, P

    def lacking(self, positions: np.ndarray) -> np.ndarray:
        """The union-layout components not at ``positions`` (kept per positions: a bank asks at every step)."""
        key = np.asarray(positions, dtype=np.intp).tobytes()
        lacking = self._lacking_cache.get(key)
        if lacking is None:
            lacking = self._lacking_cache[key] = np.setdiff1d(np.arange(len(self.layout)), positions)
        return lacking
