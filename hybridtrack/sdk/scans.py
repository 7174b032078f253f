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

Value types:

* :class:`Scan` — the candidates of one sensor at one step, z of shape (L, m);
  what the clutter-aware estimators (``nearest_neighbour``, ``pda``) accept in
  place of the stacked z of :meth:`Estimator.update`.
* :class:`RowScan` — one sensor's candidates per filter row at one step,
  z of shape (M, L, m) NaN-padded (stacked runs: row j is run j's scan,
  :func:`stack_scans`); ``nearest_neighbour`` and ``pda`` accept it.
* :class:`ScanSequence` — one sensor's scans over steps 0 … K plus, for
  evaluation only, which candidate came from the target (−1: missed).
The clutter simulator is :mod:`hybridtrack.engine.clutter`; the recording of
scans and associations :mod:`hybridtrack.recording.clutter`.
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from hybridtrack.core.validation import as_float_array

# --------------------------------------------------------------------------- value types


def _candidates(value) -> np.ndarray:
    array = np.array(value, dtype=np.float64, copy=True)
    if array.ndim == 1 and array.size == 0:
        raise ValueError("z: expected candidates of shape (L, m); an empty scan needs its dimension, e.g. np.zeros((0, 2))")
    if array.ndim == 1:
        array = array[None, :]
    as_float_array(array, "z", (None, None))
    array.setflags(write=False)
    return array


@attrs.frozen(eq=False)
class Scan:
    """The candidate measurements of sensor ``sensor`` at one step: z (L, m), L ≥ 0.

    A 1-D z is one candidate.  Their origin is unknown to an estimator: any
    may be the target's (probability P_D that one is) and the rest clutter.
    """

    sensor: str
    z: np.ndarray = attrs.field(converter=_candidates)

    @property
    def size(self) -> int:
        """L, the number of candidates."""
        return self.z.shape[0]

    @property
    def measurement_dim(self) -> int:
        return self.z.shape[1]

    def __eq__(self, other):
        if not isinstance(other, Scan):
            return NotImplemented
        return self.sensor == other.sensor and np.array_equal(self.z, other.z)

    __hash__ = None


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


def stack_scans(scans: Sequence[Scan]) -> RowScan:
    """One :class:`RowScan` from M scans of one sensor (row j = ``scans[j]``), NaN-padded to the largest L."""
    scans = list(scans)
    if not scans or not all(isinstance(s, Scan) for s in scans):
        raise TypeError(f"scans: expected a non-empty sequence of Scan, got {type(scans).__name__}")
    names = {s.sensor for s in scans}
    dims = {s.measurement_dim for s in scans}
    if len(names) != 1 or len(dims) != 1:
        raise ValueError(f"scans: expected scans of one sensor and dimension, got sensors {sorted(names)} and dimensions {sorted(dims)}")
    z = np.full((len(scans), max(s.size for s in scans), dims.pop()), np.nan)
    for j, scan in enumerate(scans):
        z[j, : scan.size] = scan.z
    return RowScan(names.pop(), z)


@attrs.frozen(eq=False)
class ScanSequence:
    """One sensor's scans at steps 0 … K−1.

    ``points[k]`` (L_k, m) are the candidates of step k; ``target_index[k]`` is
    the row of the target-originated one, −1 when the target was missed (known
    to the simulator and to evaluations, never read by an estimator).
    """

    sensor: str
    points: tuple[np.ndarray, ...] = attrs.field(converter=lambda ps: tuple(_candidates(p) for p in ps))
    target_index: np.ndarray = attrs.field(converter=lambda t: np.array(t, dtype=np.int64, copy=True))

    def __attrs_post_init__(self):
        dims = {p.shape[1] for p in self.points}
        if len(dims) > 1:
            raise ValueError(f"points: every scan of sensor {self.sensor!r} must have the same dimension, got {sorted(dims)}")
        if self.target_index.shape != (len(self.points),):
            raise ValueError(f"target_index: expected shape ({len(self.points)},), got {self.target_index.shape}")
        for k, (p, t) in enumerate(zip(self.points, self.target_index)):
            if not -1 <= t < p.shape[0]:
                raise ValueError(f"target_index: step {k} names candidate {t} of a scan of {p.shape[0]}")
        self.target_index.setflags(write=False)

    @property
    def steps(self) -> int:
        return len(self.points)

    @property
    def measurement_dim(self) -> int:
        return self.points[0].shape[1]

    @property
    def counts(self) -> np.ndarray:
        """L_k, the number of candidates per step (K,)."""
        return np.array([p.shape[0] for p in self.points], dtype=np.int64)

    def scan(self, k: int) -> Scan:
        return Scan(self.sensor, self.points[k])

    def target_measurements(self) -> np.ndarray:
        """The target-originated measurement per step (K, m), NaN where it was missed."""
        out = np.full((self.steps, self.measurement_dim), np.nan)
        for k, (p, t) in enumerate(zip(self.points, self.target_index)):
            if t >= 0:
                out[k] = p[t]
        return out

    def false_measurements(self) -> np.ndarray:
        """The false candidates per step, NaN-padded: (K, max count, m)."""
        false = [np.delete(p, t, axis=0) if t >= 0 else p for p, t in zip(self.points, self.target_index)]
        width = max((f.shape[0] for f in false), default=0)
        out = np.full((self.steps, width, self.measurement_dim), np.nan)
        for k, f in enumerate(false):
            out[k, : f.shape[0]] = f
        return out


# --------------------------------------------------------------------------- parameter checks


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
