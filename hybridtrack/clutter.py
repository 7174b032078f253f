"""Measurements in clutter: candidate sets per step and the clutter simulator (SPEC §6; seed 004).

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
* :class:`ClutterModel` — λ, P_D and the region.

:func:`add_clutter` puts clutter and missed detections on top of the clean
measurements of :func:`hybridtrack.simulate.simulate_measurements` (so the
hybrid trajectory is the same one); :func:`simulate_scans` does both from one
seed.  :func:`log_scans` and :func:`log_associations` write the clutter, the
gates and the association weights through a recorder (paths in
``docs/recording.md``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import attrs
import numpy as np

from hybridtrack.interfaces import ClutterInnovation
from hybridtrack.validation import as_float_array

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


# --------------------------------------------------------------------------- the clutter model


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


def _region(value) -> np.ndarray:
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
    region: np.ndarray = attrs.field(default=None)

    def __attrs_post_init__(self):
        if self.region is None:
            raise ValueError("region: the surveillance region (low, high) is required")
        object.__setattr__(self, "region", _region(self.region))

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
    as from :func:`~hybridtrack.simulate.simulate_measurements`); ``clutter`` is
    one model for every sensor or a mapping name → model (sensors without one
    get the clean measurement as a one-candidate scan).  At each step the
    target's row is kept with probability P_D and Poisson clutter is added;
    the candidates are shuffled so their order says nothing about the origin.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
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
    from hybridtrack.simulate import simulate_measurements

    measurement_seed, clutter_seed = np.random.SeedSequence(seed).spawn(2)
    clean = simulate_measurements(trajectory, sensors, seed=np.random.default_rng(measurement_seed))
    return add_clutter(clean, clutter, seed=np.random.default_rng(clutter_seed))


def scans_at(sequences: Sequence[ScanSequence], k: int) -> list[Scan]:
    """The scans of step k of several sensors (the input of one clutter-aware update)."""
    return [s.scan(k) for s in sequences]


# --------------------------------------------------------------------------- recording


def log_scans(recorder, sequences: Sequence[ScanSequence], steps: np.ndarray, times: np.ndarray | None = None) -> None:
    """False candidates under ``world/clutter/<sensor>`` and target-originated ones under
    ``world/measurements/<sensor>`` (2-D sensors only: the split uses the simulator's labels)."""
    for seq in sequences:
        if seq.measurement_dim != 2:
            continue
        K = len(steps)
        recorder.log_points(f"world/measurements/{seq.sensor}", steps, seq.target_measurements()[:K], times)
        false = seq.false_measurements()[:K]
        if false.shape[1]:
            recorder.log_points(f"world/clutter/{seq.sensor}", steps, false, times)


def log_associations(
    recorder, filter_names: Sequence[str], steps: np.ndarray, innovations: Sequence, times: np.ndarray | None = None
) -> None:
    """Gates, association weights and association likelihoods of clutter-aware updates.

    ``innovations`` holds one :class:`~hybridtrack.interfaces.ClutterInnovation`
    (or plain Innovation, skipped) per step.  Per filter j and sensor s:

    * ``world/estimate/<filter>/gate`` — the gate {z : (z − ẑ)ᵀS⁻¹(z − ẑ) ≤ γ}
      as an ellipse (2-D sensors, finite γ; with several sensors the path is
      ``…/gate/<sensor>``);
    * ``estimator/<filter>/beta`` — β_0 (no candidate is the target) and the
      largest β_i;
    * ``estimator/<filter>/gated`` — number of candidates inside the gate;
    * ``estimator/<filter>/association_loglik`` — ln Λ of the scan.
    """
    steps = np.asarray(steps)
    by_sensor: dict[str, list] = {}
    for k, innovation in zip(steps, innovations):
        for a in innovation.associations if isinstance(innovation, ClutterInnovation) else ():
            by_sensor.setdefault(a.sensor, []).append((k, a))
    times_of = {int(k): t for k, t in zip(steps, times)} if times is not None else None
    several = len(by_sensor) > 1
    for sensor, rows in by_sensor.items():
        ks = np.array([k for k, _ in rows])
        ts = None if times_of is None else np.array([times_of[int(k)] for k in ks])
        suffix = f"/{sensor}" if several else ""
        for j, name in enumerate(filter_names):
            beta0 = np.array([a.missed[j] for _, a in rows])
            largest = np.array([a.weights[j].max(initial=0.0) for _, a in rows])
            recorder.log_scalars(
                f"estimator/{name}/beta{suffix}", ks, np.stack([beta0, largest], axis=-1), ts, names=["beta_0", "beta_max"]
            )
            recorder.log_scalars(f"estimator/{name}/gated{suffix}", ks, np.array([float(a.gated[j].sum()) for _, a in rows]), ts)
            recorder.log_scalars(f"estimator/{name}/association_loglik{suffix}", ks, np.array([a.loglik[j] for _, a in rows]), ts)
            gamma = rows[0][1].gate
            if rows[0][1].predicted.shape[-1] == 2 and np.isfinite(gamma):
                centers = np.stack([a.predicted[j] for _, a in rows])
                covs = np.stack([a.S[j] for _, a in rows])
                recorder.log_ellipses(f"world/estimate/{name}/gate{suffix}", ks, centers, covs, ts, sigmas=float(np.sqrt(gamma)))
