"""Track-oriented multiple hypothesis tracking of one target in clutter (SPEC §6; seed 004).

Blackman & Popoli 1999, *Design and Analysis of Modern Tracking Systems*, §6
(track score, §6.2; hypothesis pruning, §6.6 and §16.3); Bar-Shalom, Li &
Kirubarajan 2001 §11 (the likelihood ratio of an association); Singer, Sea &
Housewright 1974, IEEE Trans. IT-20(4) (hypotheses that agree on the last N
scans treated as one: the "N-scan-back" rule); seed 004 ("метод
многогипотезного сопровождения").

Every filter j of the bank carries up to ``max_hypotheses`` hypotheses h, each a
Kalman filter (x_h, P_h) conditioned on one association history, with a track
score (log-likelihood ratio, target vs clutter) Σ_h.  At each scan of L
candidates every hypothesis branches into "missed" and one child per gated
candidate i (d²_hi = ν_hiᵀ S_h⁻¹ ν_hi ≤ γ, P(χ²_m ≤ γ) = P_G), with the score
increments (Blackman & Popoli 1999 §6.2, eqs. 6.11–6.13)

    missed:        ΔΣ = ln(1 − P_D P_G)
    candidate i:   ΔΣ = ln(P_D / λ) + ℓ_hi,   ℓ_hi = −½ (d²_hi + ln|2π S_h|)

(λ the clutter density, false measurements per unit measurement volume per
step).  The candidate child is the Kalman update of h with ν_hi; the missed
child is h unchanged (an empty scan, L = 0, a missed detection without clutter: every hypothesis continues as
"missed", its prediction, with ΔΣ = ln(1 − P_D P_G): the probabilities change only where the N-scan rule merges).  Then

* N-scan rule: children whose last N decisions (one per scan: a candidate index
  or "missed") are equal differ only in branches older than N scans; only the
  best-scoring of them is kept (Singer et al. 1974);
* cap: the ``max_hypotheses`` best children by score are kept (Blackman &
  Popoli 1999 §16.3.3, pruning by score).

The hypothesis probabilities are the softmax of the scores,
p_h = exp(Σ_h) / Σ_g exp(Σ_g) (Blackman & Popoli 1999 §6.4), and the bank's
estimate (``mean``/``covariance``) is that of the best hypothesis, which is
kept in slot 0 (hypotheses are stored sorted by score, best first).

With ``window = 1`` and ``max_hypotheses = 1`` the best child of the single
hypothesis is the gated candidate nearest in Mahalanobis distance, unless the
missed branch scores higher (d² > 2[ln(P_D/λ) − ln√|2πS| − ln(1 − P_D P_G)]):
whenever that threshold exceeds γ this is exactly the nearest-neighbour filter.
With P_D = 1, no gate (P_G = 1) and one candidate per scan the missed branch
has score −∞ and every hypothesis is the Kalman filter.
"""

from __future__ import annotations

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.protocols import Association, ClutterInnovation
from hybridtrack.core.validation import check_positive, check_positive_int
from hybridtrack.sdk.estimation import bank_field
from hybridtrack.sdk.mixtures import normalized_weights
from hybridtrack.sdk.scans import check_detection_probability
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters._association import ScanEstimator, log_half_det_2pi_s, pad_axis, set_clutter_model, stacked_innovation
from hybridtrack_plugins.filters.clutter_recording import RecordsFilterStates
from hybridtrack_plugins.filters.kalman import CovarianceState

#: history entry of a scan not yet seen (the root hypothesis); −1 is "missed", i ≥ 0 candidate i
_NO_SCAN = -2


@attrs.frozen(eq=False)
class MHTState(CovarianceState):
    """Hypotheses of a bank of M filters, H = ``max_hypotheses`` slots each, sorted by score (best first).

    x (M, H, n), P (M, H, n, n), their last prediction, ``scores`` Σ (M, H) (−∞:
    an empty slot), ``history`` (M, H, N) the last N decisions (−1 missed, i ≥ 0
    candidate i, −2 before the first scan).  ``mean``/``covariance`` are the best
    hypothesis's (slot 0); ``count`` (M,) the live hypotheses, ``probabilities``
    p_h = exp(Σ_h) / Σ_g exp(Σ_g) (M, H), 0 for an empty slot.
    """

    scores: np.ndarray = bank_field(0, kw_only=True)
    history: np.ndarray = bank_field(0, kw_only=True)

    mean = property(lambda self: self.x[:, 0])
    covariance = property(lambda self: self.P[:, 0])
    predicted_mean = property(lambda self: self.x_predicted[:, 0])
    predicted_covariance = property(lambda self: self.P_predicted[:, 0])
    count = property(lambda self: np.isfinite(self.scores).sum(axis=1))
    probabilities = property(lambda self: normalized_weights(self.scores))


@attrs.frozen(eq=False)
class MHTInnovation(ClutterInnovation):
    """A :class:`ClutterInnovation` of the best hypothesis plus every hypothesis's score and probability (M, H)."""

    scores: np.ndarray | None = None
    probabilities: np.ndarray | None = None


class MHTFilter(RecordsFilterStates, ScanEstimator):
    """Track-oriented MHT over a bank (module docstring).

    ``detection_probability`` P_D in (0, 1], ``clutter_density`` λ > 0,
    ``gate_probability`` P_G in (0, 1) or ``None`` (no gate, P_G = 1),
    ``window`` N ≥ 1 (scans of the N-scan rule), ``max_hypotheses`` ≥ 1 (the
    cap), ``form`` the covariance update form as for ``kalman``.
    """

    name = "mht"
    example_parameters = {"detection_probability": 0.9, "clutter_density": 0.01, "gate_probability": 0.99, "window": 2, "max_hypotheses": 4}

    def __init__(
        self,
        detection_probability: float = 0.9,
        clutter_density: float = 0.01,
        gate_probability: float | None = 0.99,
        window: int = 3,
        max_hypotheses: int = 10,
        form: str = "joseph",
    ):
        super().__init__(gate_probability, form)
        check_detection_probability(detection_probability)
        clutter_density = check_positive(clutter_density, "clutter_density", what="λ; the score has ln(P_D/λ)")
        set_clutter_model(self, detection_probability, clutter_density, gate_probability)  # log_miss, log_detect
        self.window = check_positive_int(window, "window", what="the N of N-scan pruning")
        self.max_hypotheses = check_positive_int(max_hypotheses, "max_hypotheses", what="the cap on hypotheses per filter")

    def initialize(self, mean, cov) -> MHTState:
        x, P = self.check_prior(mean, cov)
        M, n = x.shape
        H, N = self.max_hypotheses, self.window
        xs = np.repeat(x[:, None], H, axis=1)
        Ps = np.repeat(P[:, None], H, axis=1)
        scores = np.full((M, H), -np.inf)
        scores[:, 0] = 0.0
        history = np.full((M, H, N), _NO_SCAN, dtype=np.int64)
        return MHTState(xs, Ps, xs, Ps, scores=scores, history=history)

    def associate_scan(self, state: MHTState, nu, Hm, R, selection, sensor_name, candidates, z_pred):
        """One scan: every hypothesis branches (missed, each gated candidate), scored, N-scan rule, cap.

        ν (M H, L, m) → the new state, the best hypothesis's ν (M, m) and S (M, m, m), the Association.
        """
        M, H, n = state.x.shape
        L, N = nu.shape[1], self.window
        x, P = state.x.reshape(M * H, n), state.P.reshape(M * H, n, n)
        S, chol, gamma, d2, gated = self.gate(nu, P, Hm, R, selection)
        ell = -0.5 * d2 - log_half_det_2pi_s(chol)[:, None]  # ℓ_hi (M H, L)
        # child scores (M, H, 1 + L): column 0 missed, column 1 + i candidate i
        parent = state.scores[:, :, None]
        child = np.empty((M, H, 1 + L))
        child[:, :, 0] = parent[:, :, 0] + self.log_miss
        child[:, :, 1:] = np.where(gated.reshape(M, H, L), parent + self.log_detect + ell.reshape(M, H, L), -np.inf)
        dead = ~np.isfinite(child).any(axis=(1, 2))  # a miss impossible and nothing gated: no information, keep as missed
        child[dead, :, 0] = state.scores[dead]
        decisions = np.arange(-1, L)  # (1 + L,)
        child_history = np.empty((M, H, 1 + L, N), dtype=np.int64)
        child_history[..., :-1] = state.history[:, :, None, 1:]
        child_history[..., -1] = decisions
        flat_scores = child.reshape(M, H * (1 + L))
        flat_history = child_history.reshape(M, H * (1 + L), N)
        chosen, kept_scores = self._select(flat_scores, flat_history)  # (M, H) child ids, scores
        parents, columns = np.divmod(chosen, 1 + L)
        picked = decisions[columns]  # (M, H): −1 missed, i candidate i
        rows = (np.arange(M)[:, None] * H + parents).reshape(-1)  # flat parent index
        take = picked.reshape(-1)
        nu_sel = np.zeros((M * H, S.shape[-1]))
        hit = take >= 0
        nu_sel[hit] = nu[rows[hit], take[hit]]  # ν (M H, L, m)
        x_new, P_new = x[rows], P[rows]  # the parents (copies)
        if hit.any():
            R_rows = R[rows[hit]] if R.ndim == 3 and R.shape[0] == M * H else R
            x_new[hit], P_new[hit] = cov_form.update(x_new[hit], P_new[hit], nu_sel[hit], Hm, R_rows, selection, self.form)[:2]
        self.check_finite("update", updated_mean=x_new, updated_covariance=P_new)
        history = np.take_along_axis(flat_history, chosen[:, :, None], axis=1)
        new = MHTState(
            x_new.reshape(M, H, n), P_new.reshape(M, H, n, n), state.x_predicted, state.P_predicted, scores=kept_scores, history=history
        )
        # the record: the best hypothesis's parent (gate, d², ẑ, S) and its choice; β marginal over hypotheses
        best = rows.reshape(M, H)[:, 0]
        probabilities = normalized_weights(kept_scores)
        marginal = np.where(decisions[:, None, None] == picked, probabilities, 0.0).sum(axis=2)  # (1 + L, M)
        missed, weights = marginal[0], marginal[1:].T
        selected = picked[:, 0].astype(np.int64)
        loglik = np.full(M, np.nan)
        chose = selected >= 0
        loglik[chose] = ell[best[chose], selected[chose]]
        zp = z_pred.reshape(M * H, -1)[best] if z_pred.shape[0] == M * H else z_pred
        record = Association(
            sensor_name, np.asarray(candidates), zp, S[best], gamma, d2[best], gated[best], weights, missed, selected, loglik
        )
        return new, nu_sel.reshape(M, H, -1)[:, 0], S[best], record

    def _select(self, scores: np.ndarray, history: np.ndarray):
        """Per filter: children sorted by score; of those with equal last-N histories the best only; the first H.

        scores (M, C), history (M, C, N) → chosen child ids (M, H) and their scores (−∞ padding, pointing at the best).
        """
        C, H = scores.shape[1], self.max_hypotheses
        order = np.argsort(-scores, axis=1, kind="stable")
        s = np.take_along_axis(scores, order, axis=1)
        hist = np.take_along_axis(history, order[:, :, None], axis=1)
        alive = np.isfinite(s)
        # among live children with equal (filter, last-N history) the first in score order is kept
        filters, positions = np.nonzero(alive)  # row-major: per filter in score order
        keys = np.concatenate([filters[:, None], hist[filters, positions]], axis=1)
        _, first_seen = np.unique(keys, axis=0, return_index=True)
        keep = np.zeros_like(alive)
        keep[filters[first_seen], positions[first_seen]] = True
        rank = np.where(keep, np.arange(C), C + np.arange(C))
        first = np.argsort(rank, axis=1, kind="stable")[:, :H]
        first = pad_axis(first, 1, H, 0)  # fewer children than slots (L = 0 and H > 1 parents already fill this)
        valid = np.take_along_axis(keep, first, axis=1)
        first = np.where(valid, first, 0)  # empty slots copy the best child
        chosen = np.take_along_axis(order, first, axis=1)
        kept = np.where(valid, np.take_along_axis(s, first, axis=1), -np.inf)
        return chosen, kept

    def finish(self, state: MHTState, used, blocks, records):
        nu, S, loglik, nis = stacked_innovation(state.x.shape[0], used, blocks)
        innovation = MHTInnovation(nu, S, loglik, nis, tuple(records), state.scores, state.probabilities)
        return attrs.evolve(state, innovation=innovation), innovation


@hookimpl
def register_estimators(registry):
    registry.add(MHTFilter.name, MHTFilter)
