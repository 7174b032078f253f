"""The multi-target tracker: a population of tracks as R runs of one multiple-model bank, scan by scan.

Each track is a run of a :class:`~hybridtrack.algorithms.multiple_model.MultipleModelEstimator` (one mode — a
constant-velocity Kalman filter — or the IMM of a mode bank); the population's state is the estimator's
:class:`~hybridtrack.algorithms.multiple_model.MultipleModelState` with one row per track, and tracks are born
and removed by row (take / concatenate).  One scan k at time t_k (Δt = t_k − t_{k−1}, the same for all tracks):

1. **Predict** every track to t_k (the estimator's step without a measurement): x̂_{k|k−1}, P_{k|k−1}, the
   predicted position ẑ_t = H x̂ and S_t = H P Hᵀ + R (the mixture's moments for an IMM).
2. **Align** each detection i to t_k along the track that may take it: z_ti = z_i + v̂_t (t_k − t_i) (a
   time-windowed scan holds detections of slightly earlier times t_i ≤ t_k; simulated scans have t_i = t_k).
3. **Gate** (χ², probability P_G, a k-d tree on the detections: :mod:`.gating`) and score each gated pair with
   the log-likelihood ratio of "track t took detection i" against "t missed, i is clutter"
   (Bar-Shalom, Willett & Tian 2011, §6.2; Blackman & Popoli 1999, §6.2):

       s_ti = ln(P_D N(z_ti; ẑ_t, S_t)) − ln(λ (1 − P_D P_G))        (λ the clutter density, per m² per scan)

4. **Associate**: GNN — the joint assignment maximising Σ s (:func:`.assignment.gnn`), each assigned track
   updated with its detection; JPDA — the exact marginals β_ti, β_t0 over the joint events of each gated cluster
   (:func:`.jpda.jpda`; Fortmann, Bar-Shalom & Scheffe 1983), each track's posterior the β-weighted mixture of
   its hypothesis-conditioned posteriors (missed, or each gated detection), moment-matched per mode with the
   mode probabilities μ_j = Σ_h β_h μ_j^h (Blom & Bloem 2000, "Probabilistic data association avoiding track
   coalescence", the IMM-JPDA).
5. **Manage** (:mod:`.management`): the track score ΔL = s_ti + ln(1 − P_D P_G) for a hit, ln(1 − P_D P_G)
   for a miss (JPDA: its expectation under β), then confirmation and deletion by M-of-N or the score's SPRT.
6. **Initiate** from the detections no track took (JPDA: Σ_t β_ti < ½): two-point — a detection of the
   previous scan and one of this scan within ``max_speed`` of each other start a track with the velocity
   between them; single-point — each starts a track at rest with velocity standard deviation ``velocity_sigma``.

Confirmed tracks keep stable integer ids (1, 2, … in the order they were started).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import attrs
import numpy as np
from scipy.spatial import cKDTree

from hybridtrack.algorithms.multiple_model import MultipleModelEstimator, MultipleModelState
from hybridtrack.algorithms.multitarget.assignment import gnn
from hybridtrack.algorithms.multitarget.gating import Gate, gate_checked, gate_threshold
from hybridtrack.algorithms.multitarget.jpda import jpda
from hybridtrack.algorithms.multitarget.management import CONFIRMED, TENTATIVE, MofN, TrackScore, TrackStatus
from hybridtrack.core.validation import check_positive, check_positive_int
from hybridtrack.engine.detections import Detections
from hybridtrack.engine.mixing import merge_groups

ASSOCIATIONS = ("gnn", "jpda")
#: the step (s) before each further update of a track within one scan (``updates_per_scan`` > 1) for an estimator
#: whose step is not the update of its prediction (an IMM's or a single filter's further update takes no step)
REPEAT_STEP = 1e-3
INITIATIONS = ("two_point", "single_point")
#: up to this many (detection, seed) pairs the two-point initiation computes every distance (no k-d tree)
DENSE_SEED_PAIRS = 4096
_FIELDS = [f.name for f in attrs.fields(MultipleModelState)]


def _selects(sensor, layout: Sequence[str], components: tuple[str, str]) -> bool:
    """Whether ``sensor`` is linear in the state and measures exactly ``components`` of ``layout`` (H a selection)."""
    if not all(c in layout for c in components):
        return False
    H = np.asarray(sensor.jacobian(np.zeros(len(layout)), layout), dtype=float)
    return bool(np.array_equal(H, np.eye(len(layout))[[layout.index(c) for c in components]]))


def take_rows(state: MultipleModelState, rows) -> MultipleModelState:
    """The tracks at ``rows`` of a population."""
    return MultipleModelState(*(getattr(state, name)[rows] for name in _FIELDS))


def join_rows(states: Sequence[MultipleModelState]) -> MultipleModelState:
    """Populations one after another."""
    return MultipleModelState(*(np.concatenate([getattr(s, name) for s in states]) for name in _FIELDS))


def put_rows(state: MultipleModelState, rows: np.ndarray, new: MultipleModelState) -> MultipleModelState:
    """``state`` with its ``rows`` replaced by ``new``'s."""
    out = {}
    for name in _FIELDS:
        value = getattr(state, name).copy()
        value[rows] = getattr(new, name)
        out[name] = value
    return MultipleModelState(**out)


def collapse(hypotheses: MultipleModelState, owner: np.ndarray, log_weights: np.ndarray, tracks: int) -> MultipleModelState:
    """Each track's hypotheses (rows with ``owner`` t, weights w_h ∝ exp(``log_weights``) summing to one per track)
    merged into one multiple-model estimate: per mode j the weights w_hj = w_h μ_j^h, μ_j = Σ_h w_hj and the
    moment-matched x̂_j, P_j over h (Bar-Shalom, Li & Kirubarajan 2001, eqs. 11.6.6-9/10), computed about the
    first hypothesis' mean so that map-grid coordinates lose no digits; the output x̂, P the mixture over j
    (:func:`hybridtrack.engine.mixing.merge_groups`)."""
    h = hypotheses
    merged = merge_groups(owner, tracks, log_weights, h.log_mode_probabilities, h.model_means, h.model_covs, h.model_loglik, h.loglik)
    log_mu, model_means, model_covs, mean, cov, model_loglik, loglik = merged
    return MultipleModelState(model_means, model_covs, log_mu, mean, cov, model_loglik, loglik)


@attrs.frozen(eq=False, kw_only=True)
class TrackHistory:
    """One confirmed track: its ``id``, the time it was started (``born``), confirmed and deleted (None: alive at
    the end), and the detections it took (``detections``: indices into the input :class:`Detections`, in time
    order; for JPDA each scan's most probable detection when that beats "missed")."""

    id: int
    born: float
    confirmed: float
    deleted: float | None
    detections: np.ndarray


@attrs.frozen(eq=False, kw_only=True)
class MultiTargetResult:
    """What :meth:`MultiTargetTracker.run` returns: one row per scan per confirmed track alive at that scan
    (coasting ones included): ``time`` (Q,) the scan time, ``scan`` (Q,), ``track_id`` (Q,), ``means`` (Q, n)
    x̂_{k|k} in ``layout``, ``position_covs`` (Q, 2, 2), ``mode`` (Q,) the index into ``modes`` of the most probable
    mode, ``hit`` (Q,) whether the track took a detection at that scan; ``tracks`` the confirmed tracks' histories
    (by id); ``started`` the number of tentative tracks started; ``scan_times`` (K,)."""

    layout: tuple[str, ...]
    modes: tuple[str, ...]
    scan_times: np.ndarray
    time: np.ndarray
    scan: np.ndarray
    track_id: np.ndarray
    means: np.ndarray
    position_covs: np.ndarray
    mode: np.ndarray
    hit: np.ndarray
    tracks: tuple[TrackHistory, ...]
    started: int

    def positions(self) -> np.ndarray:
        """(Q, 2) the estimated x, y of every row."""
        return self.means[:, [self.layout.index("x"), self.layout.index("y")]]


class MultiTargetTracker:
    """Tracks many objects from unlabelled detections (module docstring).

    ``estimator``: the per-track :class:`MultipleModelEstimator` (its layout must hold x, vx, y, vy; its first
    sensor measures the position, an optional second the velocity the detections report, :attr:`Detections.velocity`,
    e.g. the ``velocity`` sensor of an AIS course and speed); ``association``: ``"gnn"`` or ``"jpda"``; ``management``: :class:`MofN` or
    :class:`TrackScore`; ``detection_probability`` P_D; ``clutter_density`` λ and ``birth_density`` β_NT (per m²
    per scan; the score starts at ln(β_NT/λ)); ``gate_probability`` P_G; ``initiation`` ``"two_point"`` or
    ``"single_point"``; ``max_speed`` (m/s) bounds a two-point velocity; ``velocity_sigma`` (m/s, default
    max_speed/2) the velocity prior of a single-point track and of the second point's likelihood;
    ``updates_per_scan``: how many detections one track may take in a scan (several reports of one object within a
    time window, e.g. AIS in 10 s scans: each further round associates the detections left with the updated tracks,
    each detection aligned to the scan's time, so a further update takes no time step — a stop mode's velocity,
    reset to its walk over the step, would otherwise be that of a 1 ms step; :data:`REPEAT_STEP` for an estimator
    that cannot update without stepping; 1 for sensors that see each object once per scan); ``seed_window`` (s):
    how long a detection no track took waits for its second point (default: one scan; objects that report every
    few minutes, moored ships on AIS, need minutes); ``duplicate_probability`` P_dup (None: off): after each scan, of
    two tracks that both took a detection and whose kinematic states agree, Δᵀ (P_a + P_b)⁻¹ Δ ≤ χ²₄(P_dup) (Δ the
    difference of their (x, vx, y, vy)), the one started later is a duplicate at that scan, and a track found one in
    ``duplicate_scans`` scans in a row (the scans it took no detection in do not break the row) is deleted: the
    duplicate tracks of one object that share its reports when it reports several times per scan, not the tracks
    of two ships moored side by side, which seldom report in one scan (Bar-Shalom, Willett & Tian 2011, §9.2, the
    track-to-track test of a common origin, without the cross-covariance; a tentative track found one is deleted at
    once); ``reacquire_window`` (s, None: off): a confirmed track deleted that long ago or less gives its id to a
    newly confirmed track whose state agrees with its own predicted over the gap (:meth:`_reacquire`)."""

    def __init__(
        self,
        estimator: MultipleModelEstimator,
        *,
        association: str = "gnn",
        management: MofN | TrackScore | None = None,
        detection_probability: float = 0.9,
        clutter_density: float = 1e-6,
        birth_density: float | None = None,
        gate_probability: float = 0.999,
        initiation: str = "two_point",
        max_speed: float = 50.0,
        velocity_sigma: float | None = None,
        updates_per_scan: int = 1,
        seed_window: float | None = None,
        duplicate_probability: float | None = None,
        duplicate_scans: int = 3,
        reacquire_window: float | None = None,
    ):
        if not isinstance(estimator, MultipleModelEstimator):
            raise TypeError(f"estimator: expected a MultipleModelEstimator (one mode or a bank), got {type(estimator).__name__}")
        missing = [c for c in ("x", "vx", "y", "vy") if c not in estimator.layout]
        if missing:
            raise ValueError(f"estimator: its layout {estimator.layout} lacks {missing}; tracks need x, vx, y, vy")
        sensors = estimator.network.sensors
        if (
            not 1 <= len(sensors) <= 2
            or any(s.measurement_dim != 2 for s in sensors)
            or not _selects(sensors[0], layout := estimator.layout, ("x", "y"))
        ):
            raise ValueError(
                f"estimator: expected a sensor measuring the position (x, y), and optionally a second measuring the velocity (vx, vy), got {[s.name for s in sensors]}"
            )
        if len(sensors) == 2 and not _selects(sensors[1], layout, ("vx", "vy")):
            raise ValueError(
                f"estimator: its second sensor {sensors[1].name!r} must measure the velocity (vx, vy), as a reported course and speed"
            )
        if association not in ASSOCIATIONS:
            raise ValueError(f"association: expected one of {ASSOCIATIONS}, got {association!r}")
        if initiation not in INITIATIONS:
            raise ValueError(f"initiation: expected one of {INITIATIONS}, got {initiation!r}")
        if not 0.0 < detection_probability <= 1.0:
            raise ValueError(f"detection_probability: expected P_D in (0, 1], got {detection_probability!r}")
        if not 0.0 < gate_probability < 1.0:
            raise ValueError(f"gate_probability: expected P_G in (0, 1), got {gate_probability!r}")
        self.estimator = estimator
        self.sensor = sensors[0]
        self.velocity_sensor = sensors[1] if len(sensors) == 2 else None
        self.association = association
        self.management = MofN() if management is None else management
        self.detection_probability = float(detection_probability)
        self.clutter_density = check_positive(clutter_density, "clutter_density (per m² per scan)")
        self.birth_density = self.clutter_density if birth_density is None else check_positive(birth_density, "birth_density")
        self.gate_probability = float(gate_probability)
        self.initiation = initiation
        self.updates_per_scan = check_positive_int(updates_per_scan, "updates_per_scan")
        self.seed_window = None if seed_window is None else check_positive(seed_window, "seed_window (s)")
        if duplicate_probability is not None and not 0.0 < duplicate_probability < 1.0:
            raise ValueError(f"duplicate_probability: expected a probability in (0, 1) or None, got {duplicate_probability!r}")
        self.duplicate_probability = duplicate_probability
        self.duplicate_scans = check_positive_int(duplicate_scans, "duplicate_scans")
        self.reacquire_window = None if reacquire_window is None else check_positive(reacquire_window, "reacquire_window (s)")
        self.max_speed = check_positive(max_speed, "max_speed (m/s)")
        self.velocity_sigma = self.max_speed / 2 if velocity_sigma is None else check_positive(velocity_sigma, "velocity_sigma (m/s)")
        layout = estimator.layout
        self._position = np.array([layout.index("x"), layout.index("y")])
        self._velocity = np.array([layout.index("vx"), layout.index("vy")])
        self._kinematic = ("x", "vx", "y", "vy")
        self._kinematic_index = np.array([layout.index(c) for c in self._kinematic])
        self.R = np.asarray(self.sensor.measurement_noise(np.zeros(2)), dtype=float)
        self._seed_slack = 3.0 * math.sqrt(2.0 * float(np.max(np.diag(self.R))))  # 3σ of a two-report difference
        self.gamma = gate_threshold(self.gate_probability, 2)
        self._gamma_joint = gate_threshold(self.gate_probability, 4)
        self._gamma_duplicate = None if duplicate_probability is None else gate_threshold(duplicate_probability, 4)
        self._measured = 2 * len(sensors)  # Σm: the columns of z the estimator takes
        self._log_speed_area = math.log(math.pi * self.max_speed**2)  # −ln of the uniform velocity density of clutter
        self._log_miss = math.log1p(-self.detection_probability * self.gate_probability)
        self._update_only = estimator.method == "imm" or len(estimator.models) == 1

    # ------------------------------------------------------------------ pieces
    def _scores(self, loglik: np.ndarray) -> np.ndarray:
        return math.log(self.detection_probability) + loglik - math.log(self.clutter_density) - self._log_miss

    def _noise_at(self, sensor, velocity: np.ndarray) -> np.ndarray:
        """(B, 2, 2) ``sensor``'s R(x) at the velocities (B, 2) (NaN read as 0; both sensors' R depends on the state
        through the velocity alone): the position sensor's R + σ_t² v vᵀ with a time-stamp jitter σ_t
        (``PositionSensor(time_jitter=…)``: AIS positions are fixes to metres, the time they are stamped with is
        not), the velocity sensor's σ_s² I + σ_χ² (|v|² I − v vᵀ); R alone for a sensor whose noise is fixed."""
        fixed = self.R if sensor is self.sensor else np.asarray(sensor.measurement_noise(np.zeros(2)), dtype=float)
        R = np.broadcast_to(fixed, (velocity.shape[0], 2, 2))
        if not sensor.noise_depends_on_state:
            return R
        x = np.zeros((velocity.shape[0], len(self.estimator.layout)))
        x[:, self._velocity] = np.nan_to_num(velocity)
        return R + sensor.state_noise(x, self.estimator.layout)

    def _start(self, means: np.ndarray, covs: np.ndarray, velocity: np.ndarray | None = None) -> MultipleModelState:
        """New tracks from (B, 4) means in (x, vx, y, vy) and their covariances, updated with the reported velocities
        (B, 2) of their last detection (when the estimator measures velocity; NaN: none), not with a position."""
        z = np.full((means.shape[0], self._measured), np.nan)
        if self.velocity_sensor is not None and velocity is not None:
            z[:, 2:] = velocity
        return self.estimator.start(means, covs, z, prior_layout=self._kinematic)

    def _single_point(self, z: np.ndarray, t: np.ndarray, now: float):
        """Tracks at rest at the detections (velocity prior N(0, σ_v² I)), moved to ``now``."""
        s2 = self.velocity_sigma**2
        B = z.shape[0]
        delta = now - t
        means = np.zeros((B, 4))
        means[:, [0, 2]] = z
        covs = np.zeros((B, 4, 4))
        for a, (p, v) in enumerate(((0, 1), (2, 3))):
            covs[:, p, p] = self.R[a, a] + delta**2 * s2
            covs[:, p, v] = covs[:, v, p] = delta * s2
            covs[:, v, v] = s2
        covs[:, 0, 2] = covs[:, 2, 0] = self.R[0, 1]
        return means, covs

    def _two_point(self, z1, t1, z2, t2, now: float):
        """Tracks from detection pairs: v = (z₂ − z₁)/(t₂ − t₁), position z₂ + v (t_k − t₂), with the covariance of
        that linear map of the two detections (each with R at v: with a time-stamp jitter, R + σ_t² v vᵀ)."""
        dt = t2 - t1
        delta = now - t2
        v = (z2 - z1) / dt[:, None]
        p = z2 + v * delta[:, None]
        a1, a2 = -delta / dt, 1 + delta / dt  # p = a1 z1 + a2 z2
        b1, b2 = -1 / dt, 1 / dt  # v = b1 z1 + b2 z2
        means = np.column_stack([p[:, 0], v[:, 0], p[:, 1], v[:, 1]])
        covs = np.zeros((z1.shape[0], 4, 4))
        pp, pv, vv = a1**2 + a2**2, a1 * b1 + a2 * b2, b1**2 + b2**2
        R = self._noise_at(self.sensor, v)
        for a in range(2):
            for b in range(2):
                i, j = 2 * a, 2 * b
                covs[:, i, j] = pp * R[:, a, b]
                covs[:, i, j + 1] = covs[:, j + 1, i] = pv * R[:, a, b]
                covs[:, i + 1, j + 1] = vv * R[:, a, b]
        return means, covs

    def _pair_seeds(self, seeds_z, seeds_t, z, t, seeds_v=None, v=None):
        """Greedy nearest pairs (previous-scan seed, new detection) within max_speed: (seed rows, detection rows).

        With the velocities both report (``seeds_v``, ``v``; NaN: none) a pair must also agree with them: the
        displacement against the trapezoid rule, ν = z₂ − z₁ − (v₁ + v₂) Δt / 2 (exact for a constant
        acceleration), within the χ²₂(P_G) gate of its covariance 2R + (Δt²/2) R_v(v̄) (R_v the velocity sensor's
        noise at the mean velocity v̄), and the pairs are taken in the order of that νᵀ S⁻¹ ν instead of the
        distance: two reports of one moored ship minutes apart pair, a moored ship and its neighbour do not."""
        if seeds_z.shape[0] == 0 or z.shape[0] == 0:
            return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
        slack = self._seed_slack
        reach = self.max_speed * float(t.max() - seeds_t.min()) + slack
        if z.shape[0] * seeds_z.shape[0] <= DENSE_SEED_PAIRS:  # every distance: quicker than a tree for a few
            rows, cols = np.nonzero(np.sum((z[:, None, :] - seeds_z[None, :, :]) ** 2, axis=-1) <= reach**2)
        else:
            pairs = cKDTree(seeds_z).query_ball_point(z, reach)
            rows = np.array([i for i, near in enumerate(pairs) for _ in near], dtype=np.intp)
            cols = np.array([j for near in pairs for j in near], dtype=np.intp)
        if rows.size == 0:
            return rows, cols
        distance = np.linalg.norm(z[rows] - seeds_z[cols], axis=1)
        ok = distance <= self.max_speed * (t[rows] - seeds_t[cols]) + slack
        ok &= t[rows] > seeds_t[cols]
        rows, cols, distance = rows[ok], cols[ok], distance[ok]
        if self.velocity_sensor is not None and seeds_v is not None and rows.size:
            v1, v2 = seeds_v[cols], v[rows]
            both = np.isfinite(v1).all(axis=1) & np.isfinite(v2).all(axis=1)
            dt = t[rows] - seeds_t[cols]
            mean_v = np.where(both[:, None], 0.5 * (v1 + v2), 0.0)
            nu = z[rows] - seeds_z[cols] - mean_v * dt[:, None]
            R_v = self._noise_at(self.velocity_sensor, mean_v)
            S = self._noise_at(self.sensor, v1) + self._noise_at(self.sensor, v2) + 0.5 * dt[:, None, None] ** 2 * R_v
            d2 = np.einsum("ei,ei->e", nu, np.linalg.solve(S, nu[..., None])[..., 0])
            ok = ~both | (d2 <= self.gamma)
            distance = np.where(both, d2, np.inf)[ok]  # velocity-checked pairs first, by d²; the others by distance after
            rows, cols = rows[ok], cols[ok]
            order = np.lexsort((np.linalg.norm(z[rows] - seeds_z[cols], axis=1), distance))
        else:
            order = np.argsort(distance, kind="stable")
        used_seed, used_det, out_s, out_d = set(), set(), [], []
        for i, j in zip(rows[order].tolist(), cols[order].tolist()):
            if i not in used_det and j not in used_seed:
                used_det.add(i)
                used_seed.add(j)
                out_s.append(j)
                out_d.append(i)
        return np.array(out_s, dtype=np.intp), np.array(out_d, dtype=np.intp)

    def _births(self, detections: Detections, seeds: np.ndarray, here: np.ndarray, free: np.ndarray, now: float):
        """New tracks from the scan's detections ``here[free]`` (indices into ``detections``) no track took: two-point,
        each paired with one of the waiting ``seeds`` (indices into ``detections``), or single-point.  Returns (birth,
        free left, the seeds paired); birth None or (the new tracks' state, their tentative status with the start
        score ln(β_NT/λ) [+ the second point's], the detections of each (B, hits))."""
        log_birth = math.log(self.birth_density / self.clutter_density)
        z, t = detections.z[here], detections.times[here]
        if self.initiation == "single_point":
            if not free.size:
                return None, free, seeds[:0]
            origin = here[free][:, None]
            birth = self._started(*self._single_point(z[free], t[free], now), np.full(free.size, log_birth), origin, now, detections)
            return birth, free[:0], seeds[:0]
        if not (seeds.size and free.size):
            return None, free, seeds[:0]
        reported = None if detections.velocity is None else detections.velocity[seeds]
        here_v = None if detections.velocity is None else detections.velocity[here][free]
        s_rows, d_rows = self._pair_seeds(detections.z[seeds], detections.times[seeds], z[free], t[free], reported, here_v)
        if not s_rows.size:
            return None, free, seeds[:0]
        pair = (detections.z[seeds[s_rows]], detections.times[seeds[s_rows]], z[free][d_rows], t[free][d_rows])
        score = log_birth + self._second_point_score(*pair)
        origin = np.column_stack([seeds[s_rows], here[free][d_rows]])
        fresh, status, origin = self._started(*self._two_point(*pair, now), score, origin, now, detections)
        if self.duplicate_probability is not None and origin.shape[0] > 1:
            # several reports of one object in the scan pair with its reports of earlier scans: of the new tracks
            # that agree (class docstring), the best pair is kept, the others' second points are left for it
            keep = ~self._duplicates(fresh, np.ones(origin.shape[0], dtype=bool))
            fresh, status, origin, d_rows = take_rows(fresh, keep), status.take(keep), origin[keep], d_rows[keep]
        return (fresh, status, origin), np.delete(free, d_rows), seeds[s_rows]

    def _started(self, means, covs, score, origin: np.ndarray, now: float, detections: Detections):
        """(state, status, origin) of new tracks: started at (means, covs) with the velocity their last detection
        reports, tentative with ``score`` (its peak too) and one hit per detection of ``origin`` (B, hits)."""
        status = TrackStatus.born(origin.shape[0], 0.0, now, origin.shape[1])
        status.score = np.asarray(score, dtype=float)
        status.peak = status.score.copy()
        velocity = None if detections.velocity is None else detections.velocity[origin[:, -1]]
        return self._start(means, covs, velocity), status, origin

    def _explained(self, state: MultipleModelState, now: float, z: np.ndarray, t: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
        """(B,) whether each waiting seed (z at t) lies within the χ² gate of some track's position retrodicted to t:
        with lag δ = t_k − t, x̂ − v̂ δ and S = P_pp − δ (P_pv + P_vp) + δ² P_vv + R + (v_max δ / 10)² I (the linear
        map of the track's (x, v) to its position δ earlier, and for the process noise over δ a velocity error of a
        tenth of ``max_speed``): an earlier report of an object already tracked, not the first point of a new one.
        A seed that reports its velocity v (v (B, 2), NaN: none; when the estimator measures velocity) is
        retrodicted along the velocity both give, v_f = v̂ + K (v − v̂), P_f = P_vv − K P_vv,
        K = P_vv (P_vv + R_v)⁻¹: x̂ − v_f δ with S = P_pp − δ (C + Cᵀ) + δ² P_f + R, C = P_pv (I − K)ᵀ the
        covariance of x̂ and v_f, within χ²₂(P_G), and its velocity must agree too,
        (v − v̂)ᵀ (P_vv + R_v)⁻¹ (v − v̂) ≤ χ²₂(P_G) — a moored ship's report is not explained by its neighbour's
        track, whose velocity the stop mode leaves uncertain."""
        pos, vel = self._position, self._velocity
        position, velocity = state.mean[:, pos], state.mean[:, vel]
        P = state.cov
        P_pp, P_pv, P_vv = P[:, pos[:, None], pos[None, :]], P[:, pos[:, None], vel[None, :]], P[:, vel[:, None], vel[None, :]]
        lag_max = float(np.max(now - t))
        R = self._noise_at(self.sensor, velocity)
        allowance = (0.1 * self.max_speed * lag_max) ** 2 * np.eye(2)  # the process noise over the lag, bounded
        bound = P_pp + lag_max * np.abs(P_pv + np.swapaxes(P_pv, 1, 2)) + lag_max**2 * P_vv + R + allowance
        speed = float(np.max(np.linalg.norm(velocity, axis=1)))
        reach = math.sqrt(self.gamma * float(np.max(np.linalg.eigvalsh(bound)))) * 2.0 + speed * lag_max
        near = cKDTree(position).query_ball_point(z, reach)
        out = np.zeros(z.shape[0], dtype=bool)
        check_velocity = np.zeros(z.shape[0], dtype=bool)
        if self.velocity_sensor is not None and v is not None:
            check_velocity = np.isfinite(v).all(axis=1)
            R_v = self._noise_at(self.velocity_sensor, velocity)
        for i, tracks in enumerate(near):
            if not tracks:
                continue
            lag = now - t[i]
            if check_velocity[i]:
                w = v[i] - velocity[tracks]
                S_v = P_vv[tracks] + R_v[tracks]
                K = np.linalg.solve(S_v, P_vv[tracks]).swapaxes(1, 2)  # P_vv S_v⁻¹ (both symmetric)
                fused = velocity[tracks] + np.einsum("tij,tj->ti", K, w)
                P_f = P_vv[tracks] - K @ P_vv[tracks]
                C = P_pv[tracks] @ (np.eye(2) - K).swapaxes(1, 2)  # cov(x̂, v_f) = P_pv (I − K)ᵀ
                nu = z[i] - (position[tracks] - fused * lag)
                S = P_pp[tracks] - lag * (C + C.swapaxes(1, 2)) + lag**2 * P_f + R[tracks]
                d2 = np.einsum("ti,ti->t", nu, np.linalg.solve(S, nu[..., None])[..., 0])
                d2_v = np.einsum("ti,ti->t", w, np.linalg.solve(S_v, w[..., None])[..., 0])
                out[i] = bool(((d2 <= self.gamma) & (d2_v <= self.gamma)).any())
                continue
            nu = z[i] - (position[tracks] - velocity[tracks] * lag)
            cross = P_pv[tracks] + np.swapaxes(P_pv[tracks], 1, 2)
            S = P_pp[tracks] - lag * cross + lag**2 * P_vv[tracks] + R[tracks] + (0.1 * self.max_speed * lag) ** 2 * np.eye(2)
            d2 = np.einsum("ti,ti->t", nu, np.linalg.solve(S, nu[..., None])[..., 0])
            out[i] = bool((d2 <= self.gamma).any())
        return out

    @staticmethod
    def _seed_points(detections: Detections, seeds: np.ndarray):
        """(z, t, v) of the waiting seeds: positions, times and reported velocities (None without)."""
        v = None if detections.velocity is None else detections.velocity[seeds]
        return detections.z[seeds], detections.times[seeds], v

    def _second_point_score(self, z1, t1, z2, t2) -> np.ndarray:
        """ln(P_D N(z₂; z₁, 2R + (Δt σ_v)² I) / λ): the likelihood ratio of the second point under the velocity prior."""
        dt = t2 - t1
        S = 2 * self.R[None] + (dt**2 * self.velocity_sigma**2)[:, None, None] * np.eye(2)
        nu = z2 - z1
        L = np.linalg.cholesky(S)
        w = np.linalg.solve(L, nu[..., None])[..., 0]
        logdet = 2 * np.log(np.abs(np.diagonal(L, axis1=1, axis2=2))).sum(-1)
        loglik = -0.5 * (np.sum(w**2, -1) + logdet + 2 * math.log(2 * math.pi))
        return math.log(self.detection_probability) + loglik - math.log(self.clutter_density)

    def _updated(self, state, predicted, rows, z, dt) -> MultipleModelState:
        """Tracks ``rows`` updated with z: the measurement update of their prediction (the IMM's step equals it:
        :meth:`MultipleModelEstimator.update`; a further report of the scan, ``predicted`` is ``state``, is an update
        with no time step: every report is aligned to the scan's time), otherwise a step of ``dt`` from ``state``."""
        if self._update_only:
            return self.estimator.update(take_rows(predicted, rows), z)
        return self.estimator.step(take_rows(state, rows), z, dt)

    def _gate(self, predicted: MultipleModelState, z: np.ndarray, t: np.ndarray, v: np.ndarray | None, now: float):
        """The gated pairs of the tracks ``predicted`` to ``now`` and the detections z (N, 2) at times t, with the
        measurement each pair's update takes (E, Σm): the detection aligned to ``now`` along the track, and the
        velocity it reports (v (N, 2), NaN: none) when the estimator measures velocity.

        With a reported velocity the gate and the likelihood are those of the joint (position, velocity) innovation,
        factored as p(z) p(v | z): for track t with predicted x̂, P (the mixture's moments for an IMM),
        S_p = P_pp + R, K = P_vp S_p⁻¹, v̄ = v̂ + K ν_p, S_v = P_vv − K P_pv + R_v(x̂) (R_v the velocity sensor's
        noise at x̂), d² = ν_pᵀ S_p⁻¹ ν_p + (v − v̄)ᵀ S_v⁻¹ (v − v̄) ≤ χ²₄(P_G), and ln N(z, v) gains
        ln N(v; v̄, S_v) + ln(π v_max²): against a clutter (or new) detection whose velocity is uniform over the
        disc of ``max_speed`` (Bar-Shalom, Willett & Tian 2011, §6.2, the measurement vector extended by the
        range-rate / velocity; Anderson & Moore 1979, §2.3, the conditional Gaussian).  Without one, the
        position's χ²₂(P_G) gate alone."""
        zhat = predicted.mean[:, self._position]
        velocity = predicted.mean[:, self._velocity]
        S = predicted.cov[:, self._position[:, None], self._position[None, :]] + self._noise_at(self.sensor, velocity)
        joint = self.velocity_sensor is not None
        pairs = gate_checked(zhat, S, z, self._gamma_joint if joint else self.gamma, velocity, t - now)
        track, detection = pairs.track, pairs.detection
        aligned = z[detection] + velocity[track] * (now - t[detection])[:, None]
        if not joint:
            return pairs, aligned
        reported = v[detection]
        P = predicted.cov[track]
        pos, vel = self._position, self._velocity
        S_p = S[track]
        P_vp = P[:, vel[:, None], pos[None, :]]
        K = np.linalg.solve(S_p, np.swapaxes(P_vp, 1, 2)).swapaxes(1, 2)  # P_vp S_p⁻¹ (S_p symmetric)
        nu = aligned - zhat[track]
        expected = velocity[track] + np.einsum("eij,ej->ei", K, nu)
        R_v = self._noise_at(self.velocity_sensor, velocity[track])
        S_v = P[:, vel[:, None], vel[None, :]] - np.einsum("eij,ekj->eik", K, P_vp) + R_v
        L = np.linalg.cholesky(S_v)
        w = np.linalg.solve(L, np.nan_to_num(reported - expected)[..., None])[..., 0]
        d2_v = np.sum(w * w, axis=1)
        log_v = -0.5 * d2_v - np.log(L[:, 0, 0] * L[:, 1, 1]) - math.log(2 * math.pi) + self._log_speed_area
        measured = np.isfinite(reported).all(axis=1)
        d2 = pairs.d2 + np.where(measured, d2_v, 0.0)
        keep = np.where(measured, d2 <= self._gamma_joint, pairs.d2 <= self.gamma)
        loglik = pairs.log_likelihood + np.where(measured, log_v, 0.0)
        gate = Gate(pairs.tracks, pairs.detections, track[keep], detection[keep], d2[keep], loglik[keep])
        return gate, np.column_stack([aligned, reported])[keep]

    def _associate(self, state, predicted, dt, z, t, v, now, *, first: bool):
        """One association round of detections z (N, 2) at times t (reported velocities v (N, 2) or None) with the
        tracks ``predicted`` to ``now``; the updates start from ``state`` over ``dt``.  Returns (new state, took
        (T,), ΔL (T,) beyond the miss term, picked (T,) the detection each track took (its most probable one for
        JPDA; −1 none), taken (N,) the detections used)."""
        T = predicted.mean.shape[0]
        pairs, aligned = self._gate(predicted, z, t, v, now)
        scores = self._scores(pairs.log_likelihood)
        miss = None if first else np.full(T, -self._log_miss)  # a further report: "took it" against "it is not the track's"
        # ΔL of a hit beyond the miss term ln(1 − P_D P_G) already counted: s (so ΔL = ln(P_D N / λ)); a further
        # report of the scan has no miss term of its own: s + ln(1 − P_D P_G) = ln(P_D N / λ)
        further = 0.0 if first else self._log_miss
        if self.association == "gnn":
            assigned = gnn(pairs, scores, miss_scores=miss)
            took = assigned >= 0
            rows = np.flatnonzero(took)
            N = max(z.shape[0], 1)
            e = np.searchsorted(pairs.track * N + pairs.detection, rows * N + assigned[rows])
            new = predicted
            if rows.size:
                new = put_rows(predicted, rows, self._updated(state, predicted, rows, aligned[e], dt))
            gain = np.zeros(T)
            gain[rows] = scores[e] + further
            taken = np.zeros(z.shape[0], dtype=bool)
            taken[assigned[rows]] = True
            return new, took, gain, assigned, taken
        beta, beta_miss = jpda(pairs, scores, miss_scores=miss)
        owner = np.concatenate([np.arange(T), pairs.track])
        hypotheses = predicted
        if pairs.track.size:
            hypotheses = join_rows([predicted, self._updated(state, predicted, pairs.track, aligned, dt)])
        with np.errstate(divide="ignore"):
            new = collapse(hypotheses, owner, np.log(np.concatenate([beta_miss, beta])), T)
        gain = np.zeros(T)
        np.add.at(gain, pairs.track, beta * (scores + further))
        top = np.zeros(T)
        np.maximum.at(top, pairs.track, beta)
        winner = np.flatnonzero(beta >= top[pairs.track])
        picked = np.full(T, -1, dtype=np.intp)
        picked[pairs.track[winner]] = pairs.detection[winner]
        took = (picked >= 0) & (top > beta_miss)
        share = np.zeros(z.shape[0])
        np.add.at(share, pairs.detection, beta)
        return new, took, gain, np.where(took, picked, -1), share >= 0.5

    def _duplicates(self, state: MultipleModelState, candidates: np.ndarray) -> np.ndarray:
        """(T,) the tracks to delete as duplicates: of each pair of ``candidates`` whose kinematic states agree within
        χ²₄(``duplicate_probability``) (class docstring), the later-started row (rows are in the order tracks started)."""
        T = candidates.size
        out = np.zeros(T, dtype=bool)
        rows = np.flatnonzero(candidates)
        if rows.size < 2:
            return out
        kinematic = self._kinematic_index
        x = state.mean[rows][:, kinematic]
        P = state.cov[rows][:, kinematic[:, None], kinematic[None, :]]
        gamma = self._gamma_duplicate
        largest = float(np.max(np.linalg.eigvalsh(P[:, [0, 2]][:, :, [0, 2]])))
        pairs = cKDTree(x[:, [0, 2]]).query_pairs(math.sqrt(2.0 * gamma * largest), output_type="ndarray")
        if not pairs.size:
            return out
        a, b = pairs.min(axis=1), pairs.max(axis=1)
        delta = x[a] - x[b]
        d2 = np.einsum("ei,ei->e", delta, np.linalg.solve(P[a] + P[b], delta[..., None])[..., 0])
        for i, j in zip(a[d2 <= gamma].tolist(), b[d2 <= gamma].tolist()):
            if not out[rows[i]]:  # a track already deleted deletes no other
                out[rows[j]] = True
        return out

    def _reacquire(self, state: MultipleModelState, ids: np.ndarray, confirm: np.ndarray, lost: dict, now: float, books) -> np.ndarray:
        """The track ids after re-acquisition: each track confirmed now whose kinematic state agrees with a confirmed
        track deleted within ``reacquire_window`` s, predicted by the estimator over the gap Δt (no measurement),
        Δᵀ (P_new + P_lost(Δt))⁻¹ Δ ≤ χ²₄(P_G) (Δ the difference of (x, vx, y, vy)), takes that track's id (the
        nearest by Δᵀ S⁻¹ Δ, each id once) and its history goes on: a moored ship heard again after a silence longer
        than the coasting allows, a ship lost in a turn and found again (Blackman & Popoli 1999, §3.2, track
        continuation).  ``books`` (born_at, confirmed_at, deleted_at, took) are updated in place."""
        born_at, _, deleted_at, took = books
        for track in [t for t, (gone, _) in lost.items() if now - gone > self.reacquire_window]:
            del lost[track]
        if not lost:
            return ids
        old_ids = list(lost)
        old = join_rows([lost[t][1] for t in old_ids])
        gap = np.array([now - lost[t][0] for t in old_ids])
        predicted = self.estimator.step(old, np.full((len(old_ids), self._measured), np.nan), np.maximum(gap, REPEAT_STEP))
        kinematic = self._kinematic_index
        x_old = predicted.mean[:, kinematic]
        P_old = predicted.cov[:, kinematic[:, None], kinematic[None, :]]
        gamma = self._gamma_joint
        ids = ids.copy()
        taken: set[int] = set()
        for row in np.flatnonzero(confirm).tolist():
            delta = state.mean[row, kinematic] - x_old
            S = state.cov[row][kinematic[:, None], kinematic[None, :]] + P_old
            d2 = np.einsum("ei,ei->e", delta, np.linalg.solve(S, delta[..., None])[..., 0])
            d2[[i for i, t in enumerate(old_ids) if t in taken]] = np.inf
            best = int(np.argmin(d2))
            if d2[best] > gamma:
                continue
            new, back = int(ids[row]), old_ids[best]
            taken.add(back)
            ids[row] = back
            took[back].extend(took.pop(new))
            born_at.pop(new)
            del deleted_at[back]
            del lost[back]
        return ids

    def _reported_velocity(self, detections: Detections) -> np.ndarray | None:
        """The velocities (N, 2) the detections report when the estimator measures velocity (a ValueError when it does
        and they report none); None when it does not (the tracks then use the positions alone)."""
        if self.velocity_sensor is None:
            return None
        if detections.velocity is None:
            raise ValueError(
                f"detections: the estimator's sensor {self.velocity_sensor.name!r} measures the velocity, the detections report none"
                " (give Detections velocity, e.g. [reader] course and speed; or leave the velocity sensor out)"
            )
        return detections.velocity

    # ------------------------------------------------------------------ the run
    def run(self, detections: Detections) -> MultiTargetResult:
        """All scans of ``detections``, in order (module docstring)."""
        if not isinstance(detections, Detections):
            raise TypeError(f"detections: expected a Detections (scans of unlabelled detections), got {type(detections).__name__}")
        if detections.measurement_dim != 2:
            raise ValueError(f"detections: expected (x, y) positions, got {detections.measurement_dim} components")
        reported = self._reported_velocity(detections)
        est = self.estimator
        state: MultipleModelState | None = None
        status = TrackStatus.born(0, 0.0, 0.0)
        ids = np.zeros(0, dtype=np.intp)
        born_at: dict[int, float] = {}
        confirmed_at: dict[int, float] = {}
        deleted_at: dict[int, float] = {}
        took: dict[int, list[int]] = {}
        lost: dict[int, tuple[float, MultipleModelState]] = {}  # confirmed tracks deleted: id → (time, last state)
        seeds = np.zeros(0, dtype=np.intp)  # detections of the previous scan left for two-point initiation
        next_id = 1
        rows_out: dict[str, list] = {k: [] for k in ("time", "scan", "id", "mean", "pcov", "mode", "hit")}
        bounds = detections.bounds()
        previous = None
        for k, now in enumerate(detections.scan_times.tolist()):
            here = np.arange(bounds[k].start, bounds[k].stop)
            z, t = detections.z[here], detections.times[here]
            v = None if reported is None else reported[here]
            used = np.zeros(here.size, dtype=bool)
            T = ids.size
            if T:
                dt = now - previous
                hit = np.zeros(T, dtype=bool)
                delta = np.full(T, self._log_miss)
                taken_pairs = []
                for round_ in range(self.updates_per_scan):
                    free = np.flatnonzero(~used)
                    if round_ == 0:
                        predicted, step = est.step(state, np.full((T, self._measured), np.nan), dt), dt
                        if not free.size:
                            state = predicted
                    else:  # a further report of the scan: an update of the updated tracks (_updated)
                        predicted, step = state, REPEAT_STEP
                    if not free.size:
                        break
                    state, took_now, gain, picked, taken = self._associate(
                        state, predicted, step, z[free], t[free], None if v is None else v[free], now, first=round_ == 0
                    )
                    if round_ and not took_now.any():
                        break
                    taken_pairs.append((ids[took_now], here[free[picked[took_now]]]))
                    hit |= took_now
                    delta += gain
                    used[free[taken]] = True
                status.record(hit, delta, now)
                confirm, delete = self.management.decide(status, now)
                if self.duplicate_probability is not None:
                    # a tentative track that is a duplicate is deleted at once (never confirmed); a confirmed one
                    # after duplicate_scans scans in a row found one
                    found = self._duplicates(state, hit & ~delete)
                    tentative = status.status == TENTATIVE
                    status.duplicate = np.where(found, status.duplicate + 1, np.where(hit, 0, status.duplicate))
                    delete |= (found & tentative) | (status.duplicate >= self.duplicate_scans)
                    confirm &= ~delete
                status.status = np.where(confirm, CONFIRMED, status.status).astype(np.int8)
                for tracks_taking, detections_taken in taken_pairs:
                    for track, detection in zip(tracks_taking.tolist(), detections_taken.tolist()):
                        took[track].append(int(detection))
                if self.reacquire_window is not None and confirm.any() and lost:
                    ids = self._reacquire(state, ids, confirm, lost, now, (born_at, confirmed_at, deleted_at, took))
                for track in ids[confirm].tolist():
                    confirmed_at.setdefault(track, now)
                gone = delete & (status.status == CONFIRMED)
                for row, track in zip(np.flatnonzero(gone).tolist(), ids[gone].tolist()):
                    deleted_at[track] = now
                    if self.reacquire_window is not None and status.duplicate[row] < self.duplicate_scans:
                        lost[track] = (now, take_rows(state, [row]))
                keep = ~delete
                shown = keep & (status.status == CONFIRMED)
                if shown.any():
                    rows_out["time"].append(np.full(int(shown.sum()), now))
                    rows_out["scan"].append(np.full(int(shown.sum()), k))
                    rows_out["id"].append(ids[shown])
                    rows_out["mean"].append(state.mean[shown])
                    rows_out["pcov"].append(state.cov[shown][:, self._position[:, None], self._position[None, :]])
                    rows_out["mode"].append(np.argmax(state.log_mode_probabilities[shown], axis=1))
                    rows_out["hit"].append(hit[shown])
                if not keep.all():
                    state, status, ids = take_rows(state, keep), status.take(keep), ids[keep]
            # initiation from the detections no track took
            birth, free, paired = self._births(detections, seeds, here, np.flatnonzero(~used), now)
            if paired.size:
                seeds = seeds[~np.isin(seeds, paired)]
            if birth is not None:
                fresh, new_status, origin = birth
                B = origin.shape[0]
                new_ids = np.arange(next_id, next_id + B)
                next_id += B
                for track, picked in zip(new_ids.tolist(), origin.tolist()):
                    born_at[track] = now
                    took[track] = [int(i) for i in picked]
                for _ in range(self.updates_per_scan - 1):  # the scan's further reports of the new objects
                    if not free.size:
                        break
                    fresh, took_now, gain, picked, taken = self._associate(
                        fresh, fresh, REPEAT_STEP, z[free], t[free], None if v is None else v[free], now, first=False
                    )
                    if not took_now.any():
                        break
                    for track, detection in zip(new_ids[took_now].tolist(), here[free[picked[took_now]]].tolist()):
                        took[track].append(int(detection))
                    new_status.score = new_status.score + gain
                    free = free[~taken]
                new_status.peak = new_status.score.copy()
                state = fresh if state is None or ids.size == 0 else join_rows([state, fresh])
                status = TrackStatus.concatenate([status, new_status])
                ids = np.concatenate([ids, new_ids])
            if self.initiation == "two_point":
                if self.seed_window is None or previous is None:
                    seeds = here[free]
                else:  # the older seeds within the window wait on, but those a track now explains
                    seeds = np.concatenate([seeds[detections.times[seeds] >= now - self.seed_window], here[free]])
                    if seeds.size and ids.size:
                        seeds = seeds[~self._explained(state, now, *self._seed_points(detections, seeds))]
            previous = now
        for track in ids[status.status == CONFIRMED].tolist():
            deleted_at.setdefault(track, None)
        histories = tuple(
            TrackHistory(
                id=track,
                born=born_at[track],
                confirmed=confirmed_at[track],
                deleted=deleted_at.get(track),
                detections=np.array(sorted(took[track], key=lambda i: detections.times[i]), dtype=np.intp),
            )
            for track in sorted(confirmed_at)
        )
        return self._result(detections, rows_out, histories, next_id - 1)

    def _result(self, detections: Detections, rows_out: dict[str, list], histories, started: int) -> MultiTargetResult:
        """The :class:`MultiTargetResult` of a run's per-scan row blocks ``rows_out`` (time, scan, id, mean, pcov,
        mode, hit), its track ``histories`` and the number of tracks ``started``."""
        n = len(self.estimator.layout)

        def stacked(name, shape, dtype=float):
            parts = rows_out[name]
            return np.concatenate(parts) if parts else np.zeros((0,) + shape, dtype=dtype)

        return MultiTargetResult(
            layout=self.estimator.layout,
            modes=self.estimator.modes,
            scan_times=np.asarray(detections.scan_times, dtype=float),
            time=stacked("time", ()),
            scan=stacked("scan", (), np.intp),
            track_id=stacked("id", (), np.intp),
            means=stacked("mean", (n,)),
            position_covs=stacked("pcov", (2, 2)),
            mode=stacked("mode", (), np.intp),
            hit=stacked("hit", (), bool),
            tracks=histories,
            started=started,
        )
