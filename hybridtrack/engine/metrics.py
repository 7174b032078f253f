"""Multi-target metrics: GOSPA and OSPA at one time and over time, and track-identity measures.

Notation: X = {x_1 … x_n} the true positions at one time, Y = {y_1 … y_m} the
estimated ones, d(x, y) the Euclidean distance, c > 0 the cut-off,
d^(c)(x, y) = min(d(x, y), c), p ≥ 1 the order.

GOSPA (Rahmathullah, García-Fernández, Svensson, "Generalized optimal sub-pattern
assignment metric", FUSION 2017, Definition 1), for n ≤ m (swap X and Y otherwise)::

    d_p^(c,α)(X, Y) = ( min_π Σ_{i=1..n} d^(c)(x_i, y_π(i))^p + (c^p / α) (m − n) )^(1/p),   0 < α ≤ 2,

π over the injections of {1 … n} into {1 … m}.  With α = 2 (their Proposition 1)
it is an optimisation over assignment sets γ ⊆ {1 … n} × {1 … m} (each index at
most once)::

    d^p = min_γ [ Σ_{(i,j) ∈ γ} d(x_i, y_j)^p + (c^p / 2) (n + m − 2 |γ|) ]

— the localisation cost of the assigned pairs, c^p/2 per missed truth and c^p/2 per
false estimate.

OSPA (Schuhmacher, Vo, Vo, "A consistent metric for performance evaluation of
multi-object filters", IEEE Trans. Signal Processing 56(8), 2008, Sec. III), for
n ≤ m::

    d̄_p^(c)(X, Y) = ( (1/m) ( min_π Σ_{i=1..n} d^(c)(x_i, y_π(i))^p + c^p (m − n) ) )^(1/p),

0 when both sets are empty; for p = ∞, min_π max_i d^(c)(x_i, y_π(i)) when n = m,
else c.

One matching serves both.  A pair at distance ≥ c costs c^p whether it is
paired or not (c^p/2 + c^p/2 for GOSPA with α = 2), so every minimum above is
reached by a maximum-weight matching M of the pairs *closer than c*, weights
c^p − d^p, completed by arbitrary pairs at the cut-off::

    min_π Σ_{i=1..n} d^(c)(x_i, y_π(i))^p = Σ_{(i,j) ∈ M} d_ij^p + c^p (n − |M|).

That matching does not depend on α.  Small problems solve it densely with
:func:`scipy.optimize.linear_sum_assignment` on the n × m matrix d^(c)^p (as
Stone Soup's ``GOSPAMetric`` does); large ones find the pairs within c with a
:class:`scipy.spatial.cKDTree` and solve the sparse problem with
:func:`scipy.sparse.csgraph.min_weight_full_bipartite_matching` (exact too: the
pairs further than c never lower the cost).

The identity measures (:func:`track_quality`) follow the CLEAR MOT mismatches of
Bernardin & Stiefelhagen ("Evaluating multiple object tracking performance: the
CLEAR MOT metrics", EURASIP J. Image and Video Processing, 2008, Sec. 2.1) and
the fragmentations of Li, Huang & Nevatia ("Learning to associate: HybridBoosting
multi-target tracker", CVPR 2009), counted on the per-time GOSPA assignment.
"""

from __future__ import annotations

import math
import types
from collections.abc import Hashable, Iterable, Mapping, Sequence

import attrs
import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching, min_weight_full_bipartite_matching
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from hybridtrack.core.validation import as_float_array, check_positive

#: at most this many truth × estimate pairs are solved densely without first looking for the pairs within c
DENSE_PAIRS = 10_000
#: above :data:`DENSE_PAIRS`, the dense solver is still used when the pairs within c are more than this share of all
#: pairs and all pairs are at most :data:`DENSE_PAIRS_LIMIT` (the sparse solver slows down on dense graphs)
DENSE_SHARE = 0.05
#: the largest number of truth × estimate pairs solved densely (an n × m float matrix: 32 MB at 4,000,000)
DENSE_PAIRS_LIMIT = 4_000_000


# ----------------------------------------------------------------------------------------------- value types


def _readonly(value) -> np.ndarray:
    array = np.array(value, copy=True)
    array.setflags(write=False)
    return array


def _array_field():
    return attrs.field(converter=_readonly, eq=attrs.cmp_using(eq=np.array_equal), hash=False)


def _frozen_mappings(value) -> tuple[Mapping, ...]:
    return tuple(types.MappingProxyType(dict(item)) for item in value)


@attrs.frozen(kw_only=True)
class GospaScore:
    """The GOSPA distance between one time's truth (n, d) and estimates (m, d), with its parts.

    * ``distance`` — d_p^(c,α)(X, Y);
    * ``localisation`` — Σ d_ij^p over the assigned pairs (all closer than c);
    * ``missed`` — the cost of the truths left without an estimate: c^p/2 each for α = 2;
    * ``false`` — the cost of the estimates left without a truth: c^p/2 each for α = 2;
    * ``assignment`` (n,) — the index of the estimate assigned to each truth, −1 where none.

    The parts are costs in the units of d^p (Stone Soup's ``GOSPAMetric`` convention, to which they agree):
    ``distance = (localisation + missed + false) ** (1/p)``.  With p = 1 the parts add up to the distance;
    with p ≠ 1 they add up to distance^p, so a part's share is ``part / distance**p``.

    For α ≠ 2 the paper gives no split into missed and false; here a pair of the optimal permutation at the
    cut-off (distance ≥ c, cost c^p) counts c^p/2 as missed and c^p/2 as false, as for α = 2, and each element
    of the larger set left over by the permutation costs c^p/α, to ``missed`` (a truth) or ``false`` (an
    estimate).  For α = 2 this is the paper's decomposition; for every α the parts add up as above.
    """

    distance: float
    localisation: float
    missed: float
    false: float
    assignment: np.ndarray = _array_field()


@attrs.frozen(kw_only=True)
class GospaSeries:
    """GOSPA at every time of two tables (:func:`gospa_over_time`).

    * ``times`` (K,) — the sorted distinct times of both tables;
    * ``distance``, ``localisation``, ``missed``, ``false`` (K,) — as :class:`GospaScore` at each time
      (``distance[k] ** p`` = the sum of the three parts);
    * ``assignment`` — K read-only mappings, one per time: every truth id present at that time → the track id
      assigned to it, or None;
    * ``track_ids`` — the distinct track ids of the track table, in order of first appearance;
    * ``c``, ``p``, ``alpha`` — the parameters.
    """

    times: np.ndarray = _array_field()
    distance: np.ndarray = _array_field()
    localisation: np.ndarray = _array_field()
    missed: np.ndarray = _array_field()
    false: np.ndarray = _array_field()
    assignment: tuple[Mapping, ...] = attrs.field(converter=_frozen_mappings)
    track_ids: tuple = attrs.field(converter=tuple)
    c: float
    p: float
    alpha: float

    def track_quality(self) -> TrackQuality:
        """:func:`track_quality` of this series' assignment and track ids."""
        return track_quality(self.assignment, self.track_ids)


@attrs.frozen(kw_only=True)
class OspaSeries:
    """OSPA at every time of two tables (:func:`ospa_over_time`): ``times`` (K,) sorted distinct times of both
    tables, ``distance`` (K,) the OSPA distance at each; ``c``, ``p`` the parameters."""

    times: np.ndarray = _array_field()
    distance: np.ndarray = _array_field()
    c: float
    p: float


@attrs.frozen(kw_only=True)
class TrackQuality:
    """Track-identity measures from a per-time assignment of truths to tracks (:func:`track_quality`).

    * ``id_switches`` — CLEAR MOT mismatches (IDSW, Bernardin & Stiefelhagen 2008, Sec. 2.1): for each truth,
      the number of times the track assigned to it differs from the track last assigned to it, the times where
      it is unassigned or absent skipped (A, A, B → 1; A, −, B → 1; A, −, A → 0; A, B, A → 2);
    * ``fragmentations`` — FM (Li, Huang & Nevatia 2009; py-motmetrics ``num_fragmentations``): for each truth,
      over the times it is present, the number of runs of unassigned times lying between two assigned times
      (A, −, −, A → 1; A, −, B → 1; −, A, A, − → 0);
    * ``tracks_created`` — the number of distinct track ids;
    * ``truths`` — the number of distinct truth ids;
    * ``tracks_per_truth`` — truth id → the number of distinct tracks ever assigned to it (0 for a lost truth);
    * ``false_tracks`` — the track ids never assigned to any truth;
    * ``lost_truths`` — the truth ids never assigned to any track.

    Ids are in order of first appearance.
    """

    id_switches: int
    fragmentations: int
    tracks_created: int
    truths: int
    tracks_per_truth: Mapping = attrs.field(converter=lambda value: types.MappingProxyType(dict(value)))
    false_tracks: tuple = attrs.field(converter=tuple)
    lost_truths: tuple = attrs.field(converter=tuple)


# ----------------------------------------------------------------------------------------------- checks


def _check_order(p, name: str = "p", *, allow_infinite: bool = False) -> float:
    try:
        value = float(p)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number ≥ 1 (the order of the metric), got {p!r}") from None
    if math.isnan(value) or value < 1 or (math.isinf(value) and not allow_infinite):
        expected = "a number ≥ 1 or inf" if allow_infinite else "a finite number ≥ 1"
        raise ValueError(f"{name}: expected {expected} (the order of the metric), got {p!r}")
    return value


def _check_parameters(c, p, alpha=2.0, *, allow_infinite: bool = False) -> tuple[float, float, float]:
    c = check_positive(c, "c", "the cut-off distance")
    p = _check_order(p, allow_infinite=allow_infinite)
    try:
        alpha_value = float(alpha)
    except (TypeError, ValueError):
        raise ValueError(f"alpha: expected a number in (0, 2] (the cardinality-mismatch parameter), got {alpha!r}") from None
    if not 0 < alpha_value <= 2:
        raise ValueError(f"alpha: expected a number in (0, 2] (the cardinality-mismatch parameter), got {alpha!r}")
    if math.isfinite(p):
        with np.errstate(over="ignore"):
            if not np.isfinite(np.power(c, p)):
                raise ValueError(f"c, p: c ** p = {c!r} ** {p!r} overflows float64; expected a smaller cut-off or order")
    return c, p, alpha_value


def _check_sets(truth, estimates) -> tuple[np.ndarray, np.ndarray]:
    truth = as_float_array(truth, "truth", (None, None))
    if truth.shape[1] < 1:
        raise ValueError(f"truth: expected shape (n, d) with d ≥ 1, got {truth.shape}")
    estimates = as_float_array(estimates, "estimates", (None, None))
    if estimates.shape[1] != truth.shape[1]:
        raise ValueError(f"estimates: expected shape (m, {truth.shape[1]}) (the dimension of truth), got {estimates.shape}")
    return truth, estimates


# ----------------------------------------------------------------------------------------------- the matching


def _matching(truth: np.ndarray, estimates: np.ndarray, c: float, p: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The optimal matching M of the pairs closer than c, minimising Σ_M (d_ij^p − c^p): (truth rows, estimate
    rows, d_ij^p) of its pairs, every d_ij < c."""
    n, m = len(truth), len(estimates)
    empty = np.zeros(0, dtype=np.intp)
    if n == 0 or m == 0:
        return empty, empty, np.zeros(0)
    if n * m <= DENSE_PAIRS:
        return _dense_matching(truth, estimates, c, p)
    # the pairs within c (a little further, not to lose a pair at the boundary to the tree's rounding), counted first
    # (cheap: no pair is listed) to leave a dense graph to the dense solver, then listed with their exact distances
    radius = c * (1 + 1e-9)
    truth_tree, estimate_tree = cKDTree(truth), cKDTree(estimates)
    if n * m <= DENSE_PAIRS_LIMIT and truth_tree.count_neighbors(estimate_tree, radius) > DENSE_SHARE * n * m:
        return _dense_matching(truth, estimates, c, p)
    near = truth_tree.sparse_distance_matrix(estimate_tree, radius, output_type="ndarray")
    rows, cols = near["i"].astype(np.intp), near["j"].astype(np.intp)
    distances = np.sqrt(((truth[rows] - estimates[cols]) ** 2).sum(axis=1))
    keep = distances < c
    rows, cols, distances = rows[keep], cols[keep], distances[keep]
    if len(rows) == 0:
        return empty, empty, np.zeros(0)
    return _sparse_matching(n, m, rows, cols, distances, c, p)


def _dense_matching(truth, estimates, c, p):
    distances = cdist(truth, estimates)
    cost = np.where(distances < c, distances, c) ** p
    rows, cols = linear_sum_assignment(cost)
    keep = distances[rows, cols] < c
    rows, cols = rows[keep], cols[keep]
    return rows, cols, cost[rows, cols]


def _sparse_matching(n, m, rows, cols, distances, c, p):
    """The min-cost full matching of an (n + m) × (m + n) graph: truth i → estimate j (d_ij^p, for d_ij < c),
    truth i → its own "missed" node m + i (c^p/2), the "false" node n + j of estimate j → estimate j (c^p/2),
    false node n + j → missed node m + i (0) for every pair (i, j) within c — so that the false and missed
    nodes of an assigned pair can pair off.  Its cost is Σ_M d^p + c^p/2 (n + m − 2|M|).  Every weight is
    shifted by c^p (a full matching has n + m edges whatever it is) to keep it non-zero, as the solver needs."""
    shift = c**p
    half = shift / 2
    truths, tracks = np.arange(n), np.arange(m)
    power = distances**p
    graph = coo_matrix(
        (
            np.concatenate([power + shift, np.full(n, half + shift), np.full(m, half + shift), np.full(len(rows), shift)]),
            (np.concatenate([rows, truths, n + tracks, n + cols]), np.concatenate([cols, m + truths, tracks, m + rows])),
        ),
        shape=(n + m, m + n),
    ).tocsr()
    left, right = min_weight_full_bipartite_matching(graph)
    real = (left < n) & (right < m)
    matched_rows, matched_cols = left[real].astype(np.intp), right[real].astype(np.intp)
    # d^p of each matched pair, looked up among the pairs within c
    lookup = csr_matrix((np.arange(1, len(rows) + 1), (rows, cols)), shape=(n, m))
    which = np.asarray(lookup[matched_rows, matched_cols]).ravel() - 1
    order = np.argsort(matched_rows)
    return matched_rows[order], matched_cols[order], power[which[order]]


def _gospa_parts(n: int, m: int, power: np.ndarray, c: float, p: float, alpha: float) -> tuple[float, float, float, float]:
    """(distance, localisation, missed, false) from the matching's d^p (see :class:`GospaScore`)."""
    matched = len(power)
    smaller = min(n, m)
    cut = c**p
    localisation = float(power.sum())
    cut_pairs = (cut / 2) * (smaller - matched)
    missed = cut_pairs + (cut / alpha) * (n - smaller)
    false = cut_pairs + (cut / alpha) * (m - smaller)
    distance = (localisation + missed + false) ** (1 / p)
    return float(distance), localisation, float(missed), float(false)


def _ospa_value(truth: np.ndarray, estimates: np.ndarray, c: float, p: float) -> float:
    n, m = len(truth), len(estimates)
    larger = max(n, m)
    if larger == 0:
        return 0.0
    if math.isinf(p):
        return _bottleneck(truth, estimates, c) if n == m else c
    _, _, power = _matching(truth, estimates, c, p)
    return float(((power.sum() + c**p * (larger - len(power))) / larger) ** (1 / p))


def _bottleneck(truth, estimates, c) -> float:
    """min over permutations π of max_i d^(c)(x_i, y_π(i)) for n = m: the smallest cut-off value t for which the
    pairs with d^(c) ≤ t hold a perfect matching (bisection over the distinct values)."""
    cost = np.minimum(cdist(truth, estimates), c)
    values = np.unique(cost)
    low, high = 0, len(values) - 1  # the largest value admits every pair: feasible
    while low < high:
        middle = (low + high) // 2
        match = maximum_bipartite_matching(csr_matrix(cost <= values[middle]), perm_type="column")
        if (match >= 0).all():
            high = middle
        else:
            low = middle + 1
    return float(values[low])


# ----------------------------------------------------------------------------------------------- one time


def gospa(truth, estimates, *, c: float, p: float = 1.0, alpha: float = 2.0) -> GospaScore:
    """The GOSPA distance d_p^(c,α)(X, Y) between truth (n, d) and estimates (m, d) at one time, with its parts.

    Rahmathullah, García-Fernández & Svensson, FUSION 2017, Definition 1 (see the module docstring); for α = 2::

        d^p = min_γ [ Σ_{(i,j) ∈ γ} d(x_i, y_j)^p + (c^p / 2) (n + m − 2 |γ|) ].

    The optimal assignment solves :func:`scipy.optimize.linear_sum_assignment` on d^(c)(x_i, y_j)^p (large sets:
    only the pairs within c, exactly); a pair at distance ≥ c is not assigned and counts as one missed truth
    and one false estimate.  Either set may be empty (shape (0, d)); both empty give 0.  The parts are costs in
    units of d^p: ``distance ** p = localisation + missed + false`` (:class:`GospaScore`, which also says how
    the parts are split for α ≠ 2).  For α = 2 (the only α of Stone Soup's ``GOSPAMetric``) distance and parts equal its ``compute_gospa_metric``'s.

    ``c`` > 0 the cut-off, ``p`` ≥ 1 (finite) the order, ``alpha`` in (0, 2] the cardinality-mismatch parameter.
    """
    c, p, alpha = _check_parameters(c, p, alpha)
    truth, estimates = _check_sets(truth, estimates)
    return _gospa_score(truth, estimates, c, p, alpha)


def _gospa_score(truth, estimates, c, p, alpha) -> GospaScore:
    rows, cols, power = _matching(truth, estimates, c, p)
    distance, localisation, missed, false = _gospa_parts(len(truth), len(estimates), power, c, p, alpha)
    assignment = np.full(len(truth), -1, dtype=np.intp)
    assignment[rows] = cols
    return GospaScore(distance=distance, localisation=localisation, missed=missed, false=false, assignment=assignment)


def ospa(truth, estimates, *, c: float, p: float = 1.0) -> float:
    """The OSPA distance d̄_p^(c)(X, Y) between truth (n, d) and estimates (m, d) at one time.

    Schuhmacher, Vo & Vo, IEEE TSP 2008, Sec. III: for n ≤ m (symmetric otherwise)::

        d̄_p^(c)(X, Y) = ( (1/m) ( min_π Σ_{i=1..n} d^(c)(x_i, y_π(i))^p + c^p (m − n) ) )^(1/p),

    0 when both sets are empty and c when exactly one is.  ``p`` ≥ 1 or ``inf``: d̄_∞ = min_π max_i
    d^(c)(x_i, y_π(i)) when n = m (a bottleneck assignment), else c.  The minimum is over d^(c)^p (Stone Soup's
    ``OSPAMetric`` assigns on d^(c) and then raises to p, which for p ≠ 1 can give a larger value, and takes the
    sum-minimising assignment's maximum for p = ∞).
    """
    c, p, _ = _check_parameters(c, p, allow_infinite=True)
    truth, estimates = _check_sets(truth, estimates)
    return _ospa_value(truth, estimates, c, p)


# ----------------------------------------------------------------------------------------------- over time


def _check_times(times, name: str) -> np.ndarray:
    array = np.asarray(times)
    if array.ndim != 1:
        raise ValueError(f"{name}: expected shape (N,) (one time per row), got {array.shape}")
    if array.dtype.kind == "M":
        if np.isnat(array).any():
            raise ValueError(f"{name}: contains NaT at row {int(np.argmax(np.isnat(array)))}")
        return array
    if array.dtype.kind not in "iuf" and array.size:
        raise TypeError(f"{name}: expected numeric or datetime64 times, got dtype {array.dtype}")
    return as_float_array(array, name, (None,))


def _check_ids(ids, name: str, rows: int) -> np.ndarray:
    array = np.asarray(ids)
    if array.shape != (rows,):
        raise ValueError(f"{name}: expected shape ({rows},) (one id per row of the table), got {array.shape}")
    if array.size and array.dtype.kind in "fcb":
        raise TypeError(f"{name}: expected integer or string ids, got dtype {array.dtype}")
    if array.dtype.kind == "O":
        missing = [i for i, value in enumerate(array.tolist()) if value is None or not isinstance(value, Hashable)]
        if missing:
            raise ValueError(f"{name}: expected a hashable id in every row, got {array[missing[0]]!r} at row {missing[0]}")
    return array


def _check_table(times, ids, positions, which: str, dimension: int | None):
    times = _check_times(times, f"{which}_times")
    ids = _check_ids(ids, f"{which}_ids", len(times))
    positions = as_float_array(positions, f"{which}_positions", (len(times), dimension))
    if positions.shape[1] < 1:
        raise ValueError(f"{which}_positions: expected shape (N, d) with d ≥ 1, got {positions.shape}")
    return times, ids, positions


def _time_index(times: np.ndarray, all_times: np.ndarray, ids: np.ndarray, which: str) -> tuple[np.ndarray, np.ndarray]:
    """(rows in time order, start of each time's rows (K + 1,)), after checking no id repeats within a time."""
    index = np.searchsorted(all_times, times)
    if len(ids):
        try:
            _, codes = np.unique(ids, return_inverse=True)
        except TypeError:
            raise TypeError(f"{which}_ids: expected ids of one sortable type (all integers or all strings)") from None
        keys = index.astype(np.int64) * (int(codes.max()) + 1) + codes.ravel()
        unique, first, counts = np.unique(keys, return_index=True, return_counts=True)
        if (counts > 1).any():
            row = int(first[np.argmax(counts > 1)])
            raise ValueError(
                f"{which}_ids: id {ids[row : row + 1].tolist()[0]!r} appears more than once at time {times[row : row + 1].tolist()[0]!r}; expected one row per object and time"
            )
    order = np.argsort(index, kind="stable")
    starts = np.searchsorted(index[order], np.arange(len(all_times) + 1))
    return order, starts


@attrs.frozen
class _Tables:
    """Two checked tables grouped by time: ``times`` (K,) sorted distinct times; per time k the truth rows
    ``truth_order[truth_starts[k]:truth_starts[k + 1]]`` and likewise the track rows."""

    times: np.ndarray
    truth_ids: np.ndarray
    truth_positions: np.ndarray
    truth_order: np.ndarray
    truth_starts: np.ndarray
    track_ids: np.ndarray
    track_positions: np.ndarray
    track_order: np.ndarray
    track_starts: np.ndarray

    def rows(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        return (
            self.truth_order[self.truth_starts[k] : self.truth_starts[k + 1]],
            self.track_order[self.track_starts[k] : self.track_starts[k + 1]],
        )


def _tables(truth_times, truth_ids, truth_positions, track_times, track_ids, track_positions) -> _Tables:
    truth_times, truth_ids, truth_positions = _check_table(truth_times, truth_ids, truth_positions, "truth", None)
    track_times, track_ids, track_positions = _check_table(track_times, track_ids, track_positions, "track", truth_positions.shape[1])
    # an empty table takes the other's time type
    if len(truth_times) == 0:
        truth_times = truth_times.astype(track_times.dtype)
    if len(track_times) == 0:
        track_times = track_times.astype(truth_times.dtype)
    if (truth_times.dtype.kind == "M") != (track_times.dtype.kind == "M"):
        raise TypeError(f"track_times: expected the type of truth_times ({truth_times.dtype}), got {track_times.dtype}")
    times = np.unique(np.concatenate([truth_times, track_times]))
    truth_order, truth_starts = _time_index(truth_times, times, truth_ids, "truth")
    track_order, track_starts = _time_index(track_times, times, track_ids, "track")
    return _Tables(times, truth_ids, truth_positions, truth_order, truth_starts, track_ids, track_positions, track_order, track_starts)


def gospa_over_time(
    truth_times,
    truth_ids,
    truth_positions,
    track_times,
    track_ids,
    track_positions,
    *,
    c: float,
    p: float = 1.0,
    alpha: float = 2.0,
) -> GospaSeries:
    """:func:`gospa` at every time of a truth table and a track table, with the assignment of truth ids to track ids.

    The tables are flat, one row per object per time: ``truth_times`` (N,), ``truth_ids`` (N,),
    ``truth_positions`` (N, d) and ``track_times`` (M,), ``track_ids`` (M,), ``track_positions`` (M, d).  Times
    are numbers or datetime64, matched exactly (both tables are sampled at the scan times); a time present in
    only one table is scored with the other set empty.  Ids are integers or strings (any hashable in an object
    array); an id may appear at most once per time in a table.  Returns a :class:`GospaSeries` over the K sorted
    distinct times: d_p^(c,α) and its parts at each time, and per time the mapping truth id → assigned track id
    (None when unassigned) for :func:`track_quality`.
    """
    c, p, alpha = _check_parameters(c, p, alpha)
    tables = _tables(truth_times, truth_ids, truth_positions, track_times, track_ids, track_positions)
    truth_list, track_list = tables.truth_ids.tolist(), tables.track_ids.tolist()
    parts = np.zeros((4, len(tables.times)))
    assignment = []
    for k in range(len(tables.times)):
        truth_rows, track_rows = tables.rows(k)
        score = _gospa_score(tables.truth_positions[truth_rows], tables.track_positions[track_rows], c, p, alpha)
        parts[:, k] = score.distance, score.localisation, score.missed, score.false
        assigned = score.assignment.tolist()
        assignment.append(
            {truth_list[row]: (track_list[track_rows[a]] if a >= 0 else None) for row, a in zip(truth_rows.tolist(), assigned)}
        )
    return GospaSeries(
        times=tables.times,
        distance=parts[0],
        localisation=parts[1],
        missed=parts[2],
        false=parts[3],
        assignment=assignment,
        track_ids=dict.fromkeys(track_list),
        c=c,
        p=p,
        alpha=alpha,
    )


def ospa_over_time(
    truth_times,
    truth_ids,
    truth_positions,
    track_times,
    track_ids,
    track_positions,
    *,
    c: float,
    p: float = 1.0,
) -> OspaSeries:
    """:func:`ospa` at every time of a truth table and a track table (the tables as in :func:`gospa_over_time`):
    an :class:`OspaSeries` of the K sorted distinct times and the OSPA distance at each."""
    c, p, _ = _check_parameters(c, p, allow_infinite=True)
    tables = _tables(truth_times, truth_ids, truth_positions, track_times, track_ids, track_positions)
    distance = np.zeros(len(tables.times))
    for k in range(len(tables.times)):
        truth_rows, track_rows = tables.rows(k)
        distance[k] = _ospa_value(tables.truth_positions[truth_rows], tables.track_positions[track_rows], c, p)
    return OspaSeries(times=tables.times, distance=distance, c=c, p=p)


# ----------------------------------------------------------------------------------------------- identities


def track_quality(assignments: Sequence[Mapping], track_ids: Iterable[Hashable]) -> TrackQuality:
    """Identity switches, fragmentations, tracks created, false tracks and lost truths from a per-time assignment.

    ``assignments`` — one mapping per time, in time order: every truth id present at that time → the track id
    assigned to it, or None (e.g. :attr:`GospaSeries.assignment`); ``track_ids`` — every track id of the track
    table (repeats allowed; ids assigned in ``assignments`` must be among them).  The measures are defined in
    :class:`TrackQuality`: per truth, its sequence a_1, a_2, … over the times it is present (a track id or
    None, unassigned); IDSW (Bernardin & Stiefelhagen 2008) counts the k with a_k ≠ None and a_k ≠ the last
    non-None value before k; FM (Li, Huang & Nevatia 2009) counts the k with a_k = None, a_{k−1} ≠ None and
    some later a_j ≠ None.
    """
    if isinstance(assignments, Mapping) or not isinstance(assignments, Iterable):
        raise TypeError(f"assignments: expected a sequence of mappings (one per time), got {type(assignments).__name__}")
    if isinstance(track_ids, (str, bytes)) or not isinstance(track_ids, Iterable):
        raise TypeError(f"track_ids: expected an iterable of track ids, got {type(track_ids).__name__}")
    tracks = list(dict.fromkeys(np.asarray(track_ids).tolist() if isinstance(track_ids, np.ndarray) else track_ids))
    known = set(tracks)
    last: dict = {}  # truth id → last non-None track
    gap: dict = {}  # truth id → unassigned since its last assigned time
    switches = fragmentations = 0
    per_truth: dict = {}
    used: set = set()
    for k, mapping in enumerate(assignments):
        if not isinstance(mapping, Mapping):
            raise TypeError(f"assignments[{k}]: expected a mapping truth id → track id or None, got {type(mapping).__name__}")
        seen_now: dict = {}
        for truth, track in mapping.items():
            tracks_of_truth = per_truth.setdefault(truth, set())
            if track is None:
                if truth in last:
                    gap[truth] = True
                continue
            if track not in known:
                raise ValueError(f"assignments[{k}]: track id {track!r} (assigned to truth {truth!r}) is not among track_ids")
            if track in seen_now:
                raise ValueError(f"assignments[{k}]: track id {track!r} is assigned to truths {seen_now[track]!r} and {truth!r} at once")
            seen_now[track] = truth
            if truth in last and last[truth] != track:
                switches += 1
            if gap.pop(truth, False):
                fragmentations += 1
            last[truth] = track
            tracks_of_truth.add(track)
            used.add(track)
    return TrackQuality(
        id_switches=switches,
        fragmentations=fragmentations,
        tracks_created=len(tracks),
        truths=len(per_truth),
        tracks_per_truth={truth: len(assigned) for truth, assigned in per_truth.items()},
        false_tracks=[track for track in tracks if track not in used],
        lost_truths=[truth for truth, assigned in per_truth.items() if not assigned],
    )
