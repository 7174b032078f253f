"""Scan sequences and the clutter simulator: missed detections and Poisson false measurements over a region (SPEC §6; seed 004).

The false measurements follow the parametric model of Bar-Shalom's PDA
(Bar-Shalom & Fortmann 1988, §6.4; seed 004 ref. [4]):

    number of false measurements ~ Poisson(λ V),  positions ~ uniform over the region,

with λ the clutter spatial density and V the volume of the surveillance region,
a box [low, high] in measurement coordinates.  :func:`add_clutter` puts clutter
and missed detections on top of the clean measurements of
:func:`hybridtrack.engine.simulate.simulate_measurements`; :func:`simulate_scans`
does both from one seed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import attrs
import numpy as np

from hybridtrack.core.validation import as_float_array
from hybridtrack.engine.simulate import simulate_measurements
from hybridtrack.sdk.scans import RowScan, Scan, candidate_array, check_clutter_density, check_detection_probability


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
    points: tuple[np.ndarray, ...] = attrs.field(converter=lambda ps: tuple(candidate_array(p) for p in ps))
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


def _region(value) -> np.ndarray:
    if value is None:
        raise ValueError("region: the surveillance region (low, high) is required")
    array = as_float_array(value, "region", (2, None), readonly=True)
    if not np.all(array[1] > array[0]):
        raise ValueError(f"region: expected (low, high) with high > low in every coordinate, got {array.tolist()}")
    return array


@attrs.frozen(eq=False)
class ClutterModel:
    """Poisson clutter of density λ uniform over ``region`` (a box (low, high), each (m,)), and P_D.

    Per step: the target's measurement is kept with probability P_D; the number
    of false measurements is Poisson with mean λ V, V = Π(high − low); each is
    uniform over the box (Bar-Shalom & Fortmann 1988 §6.4, seed 004).
    """

    density: float = attrs.field(converter=check_clutter_density)
    detection_probability: float = attrs.field(default=1.0, converter=check_detection_probability)
    region: np.ndarray = attrs.field(default=None, converter=_region)

    @property
    def measurement_dim(self) -> int:
        return self.region.shape[1]

    @property
    def volume(self) -> float:
        """V = Π(high − low)."""
        return float(np.prod(self.region[1] - self.region[0]))

    @property
    def expected_false(self) -> float:
        """λ V, the mean number of false measurements per step."""
        return self.density * self.volume

    def draw_false(self, rng: np.random.Generator) -> np.ndarray:
        """One step's false measurements (N, m), N ~ Poisson(λ V)."""
        count = rng.poisson(self.expected_false)
        low, high = self.region
        return low + (high - low) * rng.random((count, self.measurement_dim))


def region_around(points: np.ndarray, margin: float) -> np.ndarray:
    """The box (low, high) around ``points`` (K, m) (NaN rows ignored), widened by ``margin`` on each side."""
    points = np.asarray(points, dtype=float)
    finite = points[np.all(np.isfinite(points), axis=-1)]
    if finite.size == 0:
        raise ValueError("points: no finite point to build a region around")
    return np.stack([finite.min(axis=0) - margin, finite.max(axis=0) + margin])


def add_clutter(
    measurements: Mapping[str, np.ndarray],
    clutter: ClutterModel | Mapping[str, ClutterModel],
    *,
    seed=None,
) -> dict[str, ScanSequence]:
    """Missed detections and false measurements on top of clean measurements: name → :class:`ScanSequence`.

    ``measurements`` maps a sensor name to (K, m) (NaN rows: no measurement,
    as from :func:`~hybridtrack.engine.simulate.simulate_measurements`); ``clutter`` is
    one model for every sensor or a mapping name → model (sensors without one
    get the clean measurement as a one-candidate scan).  At each step the
    target's row is kept with probability P_D and Poisson clutter is added;
    the candidates are shuffled so their order says nothing about the origin.
    """
    rng = np.random.default_rng(seed)
    out = {}
    for name, z in measurements.items():
        z = as_float_array(z, f"measurements[{name!r}]", (None, None), allow_nan=True)
        model = clutter.get(name) if isinstance(clutter, Mapping) else clutter
        if model is not None and model.measurement_dim != z.shape[1]:
            raise ValueError(f"clutter: the region of sensor {name!r} has dimension {model.measurement_dim}, its measurements {z.shape[1]}")
        points, targets = [], []
        for row in z:
            present = not np.isnan(row).any()
            if model is None:
                points.append(row[None, :] if present else np.zeros((0, z.shape[1])))
                targets.append(0 if present else -1)
                continue
            detected = present and rng.random() < model.detection_probability
            candidates = model.draw_false(rng)
            if detected:
                candidates = np.vstack([row[None, :], candidates])
            order = rng.permutation(candidates.shape[0])
            points.append(candidates[order])
            targets.append(int(np.flatnonzero(order == 0)[0]) if detected else -1)
        out[name] = ScanSequence(name, points, targets)
    return out


def simulate_scans(trajectory, sensors, clutter, *, seed=None) -> dict[str, ScanSequence]:
    """Clean measurements of ``trajectory`` by ``sensors`` and then clutter, from one seed (independent streams)."""
    measurement_seed, clutter_seed = np.random.SeedSequence(seed).spawn(2)
    clean = simulate_measurements(trajectory, sensors, seed=np.random.default_rng(measurement_seed))
    return add_clutter(clean, clutter, seed=np.random.default_rng(clutter_seed))
