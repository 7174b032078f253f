"""Measurements in clutter: candidate sets per step (SPEC §6; seed 004).

In clutter a sensor returns at step k a *set* of m_k candidate measurements
(seed 004, "Распределение наблюдений": Z_k = {z_{k,i}, i = 1 … m_k}): at most
one from the target, detected with probability P_D, plus false ones.  The
false ones follow the parametric model of Bar-Shalom's PDA (Bar-Shalom &
Fortmann 1988, §6.4; seed 004 ref. [4]):

    number of false measurements ~ Poisson(λ V),  positions ~ uniform over the region,

with λ the clutter spatial density (false measurements per unit volume of the
measurement space, per step) and V the volume of the surveillance region, a
box [low, high] in measurement coordinates.

The clutter-aware estimators (``nearest_neighbour``, ``pda``) accept a :class:`Scan` (or, stacked runs, a
:class:`RowScan`) per sensor in place of the stacked z of :meth:`Estimator.update` (docs/clutter.md).
"""

from __future__ import annotations

import attrs
import numpy as np

from hybridtrack.core.validation import as_float_array


def candidate_array(value) -> np.ndarray:
    """Candidates z (L, m) as a read-only float64 copy (one candidate (m,) becomes (1, m)); an empty scan keeps its m."""
    array = np.array(value, dtype=np.float64, copy=True)
    if array.ndim == 1 and array.size == 0:
        raise ValueError("z: expected candidates of shape (L, m); an empty scan needs its dimension, e.g. np.zeros((0, 2))")
    if array.ndim == 1:
        array = array[None, :]
    as_float_array(array, "z", (None, None))
    array.setflags(write=False)
    return array


@attrs.frozen
class Scan:
    """The candidate measurements of sensor ``sensor`` at one step: z (L, m), L ≥ 0.

    A 1-D z is one candidate.  Their origin is unknown to an estimator: any
    may be the target's (probability P_D that one is) and the rest clutter.
    """

    sensor: str
    z: np.ndarray = attrs.field(converter=candidate_array, eq=attrs.cmp_using(eq=np.array_equal))

    @property
    def size(self) -> int:
        """L, the number of candidates."""
        return self.z.shape[0]

    @property
    def measurement_dim(self) -> int:
        return self.z.shape[1]


def _row_candidates(value) -> np.ndarray:
    array = np.array(value, dtype=np.float64, copy=True)
    if array.ndim != 3:
        raise ValueError(f"z: expected per-row candidates of shape (M, L, m), got shape {array.shape}")
    absent = np.isnan(array).all(axis=-1)
    partial = np.isnan(array).any(axis=-1) & ~absent
    if partial.any():
        raise ValueError(
            f"z: candidate {tuple(int(i) for i in np.argwhere(partial)[0])} is partly NaN; "
            "a padding candidate is NaN in every component, a real one in none"
        )
    as_float_array(np.where(np.isnan(array), 0.0, array), "z", (None, None, None))  # no inf
    array.setflags(write=False)
    return array


@attrs.frozen(eq=False)
class RowScan:
    """The candidates of sensor ``sensor`` at one step, one set per filter row: z (M, L, m).

    Row j's candidates are the rows of ``z[j]`` that are not NaN (``present``
    (M, L)); the rest is padding (NaN in every component), so the rows may
    hold different numbers of candidates.  This is how M independent runs,
    each one filter with its own scan, go through one bank
    (:func:`stack_scans`): ``nearest_neighbour`` and ``pda`` gate and weigh
    each row against its own candidates only, and row j's state and
    association equal the update of a one-filter bank with
    ``Scan(sensor, z[j][present[j]])`` to rounding.
    """

    sensor: str
    z: np.ndarray = attrs.field(converter=_row_candidates)

    @property
    def rows(self) -> int:
        """M, the number of filter rows."""
        return self.z.shape[0]

    @property
    def size(self) -> int:
        """L, the candidate slots per row (padding included)."""
        return self.z.shape[1]

    @property
    def measurement_dim(self) -> int:
        return self.z.shape[2]

    @property
    def present(self) -> np.ndarray:
        """(M, L): whether slot i of row j holds a candidate (not padding)."""
        return ~np.isnan(self.z).all(axis=-1)

    def row(self, j: int) -> Scan:
        """Row j's candidates as a :class:`Scan`."""
        return Scan(self.sensor, self.z[j][self.present[j]])


def check_detection_probability(value) -> float:
    """P_D in (0, 1]."""
    value = float(value)
    if not (0.0 < value <= 1.0):
        raise ValueError(f"detection_probability: expected P_D in (0, 1], got {value!r}")
    return value


def check_clutter_density(value) -> float:
    """λ ≥ 0, finite."""
    value = float(value)
    if not (np.isfinite(value) and value >= 0.0):
        raise ValueError(f"clutter_density: expected a finite λ ≥ 0 (false measurements per unit volume per step), got {value!r}")
    return value
