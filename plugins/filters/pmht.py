"""Probabilistic multi-hypothesis tracking of one target by EM over a sliding window of scans (SPEC §6; seed 004).

Streit & Luginbuhl 1995, "Probabilistic Multi-Hypothesis Tracking", NUWC-NPT
TR 10,428 (also Proc. SPIE 2235, 1994); Willett, Ruan & Streit 2002, "PMHT:
problems and some solutions", IEEE Trans. AES 38(3) (the Poisson measurement
model below, and the sliding batch); Efe, Ruan & Willett 2005, IEE Proc. RSN
151(4) (seed 004 ref. [10]); seed 004 ("Вероятностный многогипотезный
алгоритм": PMHT drops "at most one mark per target per scan", so association is
an EM problem over a batch of scans, steps 1–5 of the seed's list).

Model.  Over the window of scans t = 1 … T (the last ``window`` scans) with the
prior x_0 ~ N(m_0, P_0) (the estimate just before the window) and the motion
x_t = F_t x_{t−1} + B_t + w_t, w_t ~ N(0, Q_t), the candidates z_{t,r} of scan t
(the gated ones) are a Poisson number of target measurements (mean P_D) plus
Poisson clutter of density λ, each independently of the others — no "at most
one per scan".  The measurement likelihood of scan t is then, up to factors
free of x_t,

    p(Z_t | x_t) ∝ Π_r (λ + P_D N(z_{t,r}; H x_t, R)).

EM for the MAP estimate X̂ = argmax ln p(X) + Σ_t ln p(Z_t | x_t):

* E-step (the association posteriors at the current X̂ⁱ; λ is the clutter class):

      w_{t,r} = P_D N(z_{t,r}; H x̂ⁱ_t, R) / (λ + P_D N(z_{t,r}; H x̂ⁱ_t, R)),  W_t = Σ_r w_{t,r};

* M-step: ln p(X) + Σ_{t,r} w_{t,r} ln N(z_{t,r}; H x_t, R) is, up to a constant,
  ln p(X) + Σ_t ln N(z̃_t; H x_t, R / W_t) with the synthetic measurement

      z̃_t = Σ_r w_{t,r} z_{t,r} / W_t,   covariance R̃_t = R / W_t,

  maximized by the Kalman filter forward and the Rauch–Tung–Striebel smoother
  backward over the window (Rauch, Tung & Striebel 1965):

      C_t = P_t Fᵀ_{t+1} (P⁻_{t+1})⁻¹,  x̂_t = x_t + C_t (x̂_{t+1} − x⁻_{t+1}),
      P̂_t = P_t + C_t (P̂_{t+1} − P⁻_{t+1}) C_tᵀ         (Cholesky solves with P⁻);

  a scan with W_t < ``MIN_WEIGHT`` = 1e-9 (nothing gated, or every candidate far
  off) is prediction only — its gain K ∝ W_t would move the estimate by a
  negligible fraction of P and R / W_t would overflow;
* the objective J(X̂) = ln p(X̂) + Σ_{t,r} ln(λ + P_D N(z_{t,r}; H x̂_t, R)) (the
  log posterior up to a constant; EM never decreases it).  ln p(X̂) at the
  smoother's output is −½[Σ_t ν_tᵀS_t⁻¹ν_t − Σ_t W_t (z̃_t − H x̂_t)ᵀR⁻¹(z̃_t − H x̂_t)]
  (the minimum of the quadratic form is the sum of the forward pass's NIS),
  so a singular Q needs no pseudo-inverse.  Iterations stop for a filter once
  J rises by ≤ ``tolerance`` (at least two M-steps), or after ``max_iterations``;
  a filter that stopped is frozen while the others go on, so a filter's
  result does not depend on the rest of the bank.

Sliding window: a new scan enters with the initial guess x̂⁰_T = x⁻ (the
prediction) and the other scans with their last smoothed means; when the window
is full the oldest scan leaves and the filtered estimate (x_1, P_1) of the last
forward pass (with the converged weights) becomes the window's prior.

Outputs: ``mean``/``covariance`` the filtered (= smoothed) estimate at the newest
scan; the innovation is the synthetic measurement's at the newest scan, ν =
z̃_T − H x⁻_T, S = H P⁻_T Hᵀ + R / W_T, with its Gaussian ℓ and NIS (so the
detectors read it like any filter's); the ``Association`` record of each scan
carries w (``weights``), Π_r (1 − w_r) (``missed``: every candidate clutter) and
ln Λ = Σ_r ln(1 + P_D N(ν_r; 0, S) / λ) at the prediction (λ = 0: Σ_r ln(P_D N));
the state keeps the window (smoothed means and covariances, weights).

With λ = 0 every gated candidate gets w = 1: with one candidate per scan the
synthetic measurement is that candidate with R, the forward pass is the Kalman
filter and the window's estimates are the RTS smoother's (tested to 1e-9
against filterpy), and the output the Kalman filter's (``exact_kalman``).

A filter is joined to a bank (``concatenate``) with its own window; a freshly
initialized filter has an empty window, so it steps like a filter with a full
window only for ``window = 1`` or λ = 0.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.protocols import Association
from hybridtrack.core.validation import check_positive, check_positive_int
from hybridtrack.sdk.estimation import bank_field, guarded
from hybridtrack.sdk.linalg import LOG_2PI, cholesky, cholesky_solve, forward_substitute, gaussian_scores, log_det_from_cholesky, symmetrize
from hybridtrack.sdk.scans import check_clutter_density, check_detection_probability
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters._association import ScanEstimator, log_half_det_2pi_s, pad_axis
from hybridtrack_plugins.filters.kalman import CovarianceState

#: total association weight W_t below which a scan is prediction only (module docstring)
MIN_WEIGHT = 1e-9


@attrs.frozen(eq=False, kw_only=True)
class PMHTState(CovarianceState):
    """A bank of M PMHT filters with windows of W = ``window`` scan slots (newest last).

    ``x``, ``P`` the current estimate (filtered at the newest scan, or predicted);
    ``prior_x``/``prior_P`` the window's initial condition; ``pending_*`` the
    transition accumulated since the newest slot.  Per slot: ``valid`` (M, W),
    the transition ``F``, ``B``, ``Q`` (identity, 0, 0 in an empty slot), ``H``
    (M, W, m̄, n) and ``R`` (M, W, m̄, m̄) zero-/identity-padded to the widest
    measurement m̄, ``pad`` (M, W) the number of padded components,
    ``candidates`` (M, W, L̄, m̄) the gated candidates (first, padded), ``present`` (M, W, L̄) (not padding),
    the last EM's ``weights`` (M, W, L̄), ``iterations`` (M,), the objective J it reached ``log_posterior``
    (M,, up to a constant), ``smoothed_mean`` (M, W, n),
    ``smoothed_covariance`` (M, W, n, n) and filtered ``filtered_mean``/``filtered_covariance``.
    """

    prior_x: np.ndarray = bank_field(0)
    prior_P: np.ndarray = bank_field(0)
    pending_F: np.ndarray = bank_field(0)
    pending_B: np.ndarray = bank_field(0)
    pending_Q: np.ndarray = bank_field(0)
    valid: np.ndarray = bank_field(0)
    F: np.ndarray = bank_field(0)
    B: np.ndarray = bank_field(0)
    Q: np.ndarray = bank_field(0)
    H: np.ndarray = bank_field(0)
    R: np.ndarray = bank_field(0)
    pad: np.ndarray = bank_field(0)
    candidates: np.ndarray = bank_field(0)
    present: np.ndarray = bank_field(0)
    weights: np.ndarray = bank_field(0)
    smoothed_mean: np.ndarray = bank_field(0)
    smoothed_covariance: np.ndarray = bank_field(0)
    filtered_mean: np.ndarray = bank_field(0)
    filtered_covariance: np.ndarray = bank_field(0)
    iterations: np.ndarray = bank_field(0)
    log_posterior: np.ndarray = bank_field(0)


def _padded(H, R, candidates, present, m: int, L: int):
    """H (…, m₀, n), R (…, m₀, m₀), candidates (…, L₀, m₀) and present (…, L₀) padded to m measurement components
    (zero rows of H, an identity block of R) and L candidates (absent)."""
    m0 = R.shape[-1]
    R_pad = np.zeros(R.shape[:-2] + (m, m))
    R_pad[..., :m0, :m0] = R
    R_pad[..., m0:, m0:] = np.eye(m - m0)
    return pad_axis(H, -2, m, 0.0), R_pad, pad_axis(pad_axis(candidates, -1, m, 0.0), -2, L, 0.0), pad_axis(present, -1, L, False)


def _widen(state: PMHTState, m: int, L: int) -> PMHTState:
    """The slots padded to at least m measurement components and L candidates."""
    mb, Lb = state.H.shape[2], state.candidates.shape[2]
    if m <= mb and L <= Lb:
        return state
    m2, L2 = max(m, mb), max(L, Lb)
    H, R, candidates, present = _padded(state.H, state.R, state.candidates, state.present, m2, L2)
    weights = pad_axis(state.weights, 2, L2, 0.0)
    return attrs.evolve(state, H=H, R=R, pad=state.pad + (m2 - mb), candidates=candidates, present=present, weights=weights)


def _no_pending(M: int, n: int) -> dict:
    """No transition since the newest slot: F = I, B = 0, Q = 0."""
    return {"pending_F": np.broadcast_to(np.eye(n), (M, n, n)).copy(), "pending_B": np.zeros((M, n)), "pending_Q": np.zeros((M, n, n))}


class PMHTFilter(ScanEstimator):
    """PMHT by EM over a sliding window of scans (module docstring).

    ``detection_probability`` P_D in (0, 1], ``clutter_density`` λ ≥ 0 (false
    measurements per unit measurement volume per step), ``gate_probability``
    P_G in (0, 1) or ``None`` (no gate), ``window`` W ≥ 1 scans,
    ``max_iterations`` ≥ 1 EM iterations per scan, ``tolerance`` > 0 (stop when
    the log posterior rises by no more), ``form`` the covariance update form.
    """

    name = "pmht"
    example_parameters = {"detection_probability": 0.9, "clutter_density": 0.01, "gate_probability": 0.99, "window": 1}

    def __init__(
        self,
        detection_probability: float = 0.9,
        clutter_density: float = 0.01,
        gate_probability: float | None = 0.99,
        window: int = 3,
        max_iterations: int = 20,
        tolerance: float = 1e-6,
        form: str = "joseph",
    ):
        super().__init__(gate_probability, form)
        self.detection_probability = check_detection_probability(detection_probability)
        self.clutter_density = check_clutter_density(clutter_density)
        self.window = check_positive_int(window, "window", what="the number of scans of the EM batch")
        self.max_iterations = check_positive_int(max_iterations, "max_iterations", what="EM iterations per scan")
        self.tolerance = check_positive(tolerance, "tolerance", what="the rise of the log posterior below which EM stops")
        self.log_pd = math.log(self.detection_probability)
        self.log_lambda = math.log(self.clutter_density) if self.clutter_density > 0 else -math.inf

    @property
    def exact_kalman(self) -> bool:
        """λ = 0 and no gate: every candidate has w = 1; with one per step this is the Kalman filter."""
        return self.clutter_density == 0.0 and self.gate_probability is None

    def initialize(self, mean, cov) -> PMHTState:
        x, P = self.check_prior(mean, cov)
        M, n = x.shape
        W = self.window
        return PMHTState(
            **dict.fromkeys(("x", "x_predicted", "prior_x"), x),  # the estimate, its prediction and the window's prior
            **dict.fromkeys(("P", "P_predicted", "prior_P"), P),
            **_no_pending(M, n),
            valid=np.zeros((M, W), dtype=bool),
            F=np.broadcast_to(np.eye(n), (M, W, n, n)).copy(),
            B=np.zeros((M, W, n)),
            Q=np.zeros((M, W, n, n)),
            H=np.zeros((M, W, 0, n)),
            R=np.zeros((M, W, 0, 0)),
            pad=np.zeros((M, W), dtype=np.int64),
            candidates=np.zeros((M, W, 0, 0)),
            present=np.zeros((M, W, 0), dtype=bool),
            weights=np.zeros((M, W, 0)),
            **{f"{kind}_mean": np.repeat(x[:, None], W, axis=1) for kind in ("smoothed", "filtered")},
            **{f"{kind}_covariance": np.repeat(P[:, None], W, axis=1) for kind in ("smoothed", "filtered")},
            iterations=np.zeros(M, dtype=np.int64),
            log_posterior=np.zeros(M),
        )

    def conform(self, states: list) -> list:
        """Pad every state's slots to the widest m̄ and L̄ of the group, so that they concatenate."""
        m = max(s.H.shape[2] for s in states)
        L = max(s.candidates.shape[2] for s in states)
        return [_widen(s, m, L) for s in states]

    @guarded
    def predict(self, state: PMHTState, transitions) -> PMHTState:
        """The covariance prediction, and the transition since the newest slot composed:
        F' = F F_p, B' = F B_p + B, Q' = F Q_p Fᵀ + Q."""
        new = super().predict(state, transitions)
        bank = self.check_transitions(transitions, *state.x.shape)  # checked by the prediction: not again
        Fp = bank.F @ state.pending_F
        Bp = np.einsum("mij,mj->mi", bank.F, state.pending_B) + bank.B
        Qp = symmetrize(bank.F @ state.pending_Q @ np.swapaxes(bank.F, -1, -2) + bank.Q)
        return attrs.evolve(new, pending_F=Fp, pending_B=Bp, pending_Q=Qp)

    def stacked_candidates(self, state: PMHTState, z, sensors, layout):
        """The one candidate of a stacked z: candidates (M, 1, m), H, R, the sensors' name, z; None if nothing was measured."""
        M, n = state.x.shape
        step = self.measurement_step(z, sensors, layout, M, n, state)
        if step is None:
            return None
        if step.H is None:
            names = [m.sensor.name for m in step.models if m.H is None]
            raise ValueError(f"sensors: {self.name!r} takes linear sensors only; {names} are nonlinear")
        if not step.plain_residual:
            raise ValueError(f"sensors: {self.name!r} needs sensors whose residual is z − H x (no angle wrapping)")
        cands = np.broadcast_to(step.z, (M, step.dim))[:, None, :]
        return cands, step.H, np.asarray(step.R), "+".join(m.sensor.name for m in step.models), step.z

    def scan_candidates(self, state: PMHTState, scan, sensor, model):
        """A scan's candidates (M, L, m) for every filter, H, R, the sensor's name and the scan's z."""
        if not model.plain_residual:
            raise ValueError(f"sensors: {self.name!r} needs sensors whose residual is z − H x; {sensor.name!r} wraps angles")
        cands = np.broadcast_to(scan.z[None], (state.x.shape[0],) + scan.z.shape)
        return cands, model.H, np.asarray(sensor.noise_cov), sensor.name, scan.z

    def associate_scan(self, state: PMHTState, cands: np.ndarray, H: np.ndarray, R: np.ndarray, name: str, raw):
        """Gate the scan at the prediction, add it as the newest slot (sliding the window), run EM; an empty scan
        adds no slot (prediction only) and its record says so."""
        M, n = state.x.shape
        L, m = cands.shape[1], cands.shape[2]
        z_pred = state.x @ H.T
        # gate at the prediction: d² = νᵀ S⁻¹ ν ≤ γ, S = H P⁻ Hᵀ + R
        S_pred, L_pred, gamma, d2, gated = self.gate(cands - z_pred[:, None, :], state.P, H, R)
        if L == 0:
            record = Association(name, np.asarray(raw), z_pred, S_pred, gamma, d2, gated, d2, np.ones(M), np.full(M, -1), np.zeros(M))
            return state, None, None, record
        ell = -0.5 * d2 - log_half_det_2pi_s(L_pred)[:, None]  # ln N(ν_r; 0, S) at the prediction
        # ln(1 + P_D N / λ), or ln(P_D N) for λ = 0
        terms = np.logaddexp(0.0, self.log_pd + ell - self.log_lambda) if self.clutter_density > 0 else self.log_pd + ell
        assoc_loglik = np.where(gated, terms, 0.0).sum(axis=1)
        # slide: when the oldest slot is occupied it leaves and its filtered estimate becomes the prior
        leaving = state.valid[:, 0]
        prior_x = np.where(leaving[:, None], state.filtered_mean[:, 0], state.prior_x)
        prior_P = np.where(leaving[:, None, None], state.filtered_covariance[:, 0], state.prior_P)
        # keep only the gated candidates, first (a stable sort), padded to the largest count of the bank
        Lg = int(gated.sum(axis=1).max(initial=0))
        order = np.argsort(~gated, axis=1, kind="stable")[:, :Lg]
        kept = np.take_along_axis(cands, order[:, :, None], axis=1)
        kept_present = np.take_along_axis(gated, order, axis=1)
        s = _widen(state, m, Lg)
        mb, Lb = s.H.shape[2], s.candidates.shape[2]
        Hs, Rs, cs, pr = _padded(np.broadcast_to(H, (M, m, n)), np.broadcast_to(R, (M, m, m)), kept, kept_present, mb, Lb)

        def shift(a, new):
            return np.concatenate([a[:, 1:], new[:, None]], axis=1)

        newest = {"valid": np.ones(M, dtype=bool), "F": s.pending_F, "B": s.pending_B, "Q": s.pending_Q, "H": Hs, "R": Rs}
        newest.update(pad=np.full(M, mb - m), candidates=cs, present=pr)
        slots = {name: shift(getattr(s, name), value) for name, value in newest.items()}
        guess = shift(s.smoothed_mean, state.x)  # the new scan starts from the prediction
        em = self._em(prior_x, prior_P, guess, **slots)
        # the newest scan's synthetic innovation ν = z̃ − H x⁻ (real components only), S = H P⁻ Hᵀ + R / W (R when W = 0)
        w_T = np.zeros((M, L))  # back to the scan's candidate order
        np.put_along_axis(w_T, order, em["weights"][:, -1, :Lg], axis=1)
        W_T = w_T.sum(axis=1)
        has = W_T >= MIN_WEIGHT
        safe = np.where(has, W_T, 1.0)
        z_syn = np.einsum("ml,mli->mi", w_T, cands) / safe[:, None]
        nu = np.where(has[:, None], z_syn - em["x_predicted"] @ H.T, 0.0)
        S = symmetrize(H @ em["P_predicted"] @ H.T + R / safe[:, None, None])
        selected = np.where(gated.any(axis=1), np.argmax(np.where(gated, w_T, -1.0), axis=1), -1).astype(np.int64)
        missed = np.prod(1.0 - w_T, axis=1)
        record = Association(name, np.asarray(raw), z_pred, S_pred, gamma, d2, gated, w_T, missed, selected, assoc_loglik)
        new = attrs.evolve(s, prior_x=prior_x, prior_P=prior_P, **_no_pending(M, n), **slots, **em)
        return new, nu, S, record

    def _estep(self, X, Hw, cw, pw, LR, logdet_R):
        """ln N(z_{t,r}; H x_t, R) (M, W, L̄) and w_{t,r} = P_D N / (λ + P_D N) (0 where not present)."""
        zhat = np.einsum("mwij,mwj->mwi", Hw, X)
        resid = cw - zhat[:, :, None, :]
        u = forward_substitute(LR[:, :, None], resid)
        q = np.einsum("...i,...i->...", u, u)
        logN = -0.5 * (q + logdet_R[:, :, None])
        a = self.log_pd + logN
        total = np.logaddexp(self.log_lambda, a) if self.clutter_density > 0 else a  # ln(λ + P_D N), or ln(P_D N)
        w = np.where(pw, np.exp(a - total) if self.clutter_density > 0 else 1.0, 0.0)
        return w, np.where(pw, total, 0.0).sum(axis=(1, 2))

    def _em(self, prior_x, prior_P, guess, valid, F, B, Q, H, R, pad, candidates, present):
        """EM over the window's slots from the initial guess X̂⁰ (M, W, n) (module docstring) → the PMHTState fields
        it sets: the window's smoothed and filtered moments and weights, the estimate at the newest scan (x, P and
        its prediction), the iterations and the objective J reached."""
        M, mb = guess.shape[0], H.shape[2]
        LR = cholesky(R, "measurement noise R")
        # ln |2π R| of the real components: the padded identity block adds pad · ln 2π
        logdet_R = mb * LOG_2PI + log_det_from_cholesky(LR) - pad * LOG_2PI
        w, _ = self._estep(guess, H, candidates, present, LR, logdet_R)
        active = np.ones(M, dtype=bool)
        best = None
        last_J = np.full(M, -np.inf)
        iterations = np.zeros(M, dtype=np.int64)
        for iteration in range(self.max_iterations):
            result = self._smooth(prior_x, prior_P, F, B, Q, H, R, candidates, w)
            xs, _, _, _, _, _, nis_sum, Wsum, zsyn = result
            # J = ln p(X̂) + Σ ln(λ + P_D N) at the smoother's output (module docstring)
            resid = zsyn - np.einsum("mwij,mwj->mwi", H, xs)
            u = forward_substitute(LR, resid)
            quad = np.where(Wsum >= MIN_WEIGHT, Wsum * np.einsum("...i,...i->...", u, u), 0.0).sum(axis=1)
            w_next, meas = self._estep(xs, H, candidates, present, LR, logdet_R)  # also the next iteration's E-step
            J = -0.5 * (nis_sum - quad) + meas
            if best is None:
                best = (result, w)
            else:
                keep = active[:, None]
                best = (
                    tuple(np.where(keep.reshape((M,) + (1,) * (a.ndim - 1)), a, b) for a, b in zip(result, best[0])),
                    np.where(keep[:, :, None], w, best[1]),
                )
            iterations = np.where(active, iteration + 1, iterations)
            converged = (iteration >= 1) & (J - last_J <= self.tolerance)
            last_J = np.where(active, J, last_J)
            active = active & ~converged
            if not active.any():
                break
            w = np.where(active[:, None, None], w_next, w)
        (xs, Ps, xf, Pf, xp_T, Pp_T, _, _, _), w = best
        self.check_finite("update", smoothed_mean=xs, smoothed_covariance=Ps)
        window = {"smoothed_mean": xs, "smoothed_covariance": Ps, "filtered_mean": xf, "filtered_covariance": Pf, "weights": w}
        estimate = {"x": xf[:, -1], "P": Pf[:, -1], "x_predicted": xp_T, "P_predicted": Pp_T}
        return window | estimate | {"iterations": iterations, "log_posterior": last_J}

    def _smooth(self, prior_x, prior_P, F, B, Q, Hw, Rw, cw, w):
        """Kalman filter and RTS smoother over the window on the synthetic measurements of the weights w."""
        M, W, n = F.shape[:3]
        Wsum = w.sum(axis=2)  # (M, W)
        has = Wsum >= MIN_WEIGHT
        safe = np.where(has, Wsum, 1.0)
        zsyn = np.einsum("mwl,mwli->mwi", w, cw) / safe[:, :, None]
        xp = np.empty((M, W, n))
        Pp = np.empty((M, W, n, n))
        xf = np.empty((M, W, n))
        Pf = np.empty((M, W, n, n))
        x, P = prior_x, prior_P
        nis_sum = np.zeros(M)
        for t in range(W):
            x, P = cov_form.predict(x, P, F[:, t], B[:, t], Q[:, t])
            xp[:, t], Pp[:, t] = x, P
            H = Hw[:, t]
            nu = zsyn[:, t] - np.einsum("mij,mj->mi", H, x)
            Rt = Rw[:, t] / safe[:, t, None, None]
            xu, Pu, S, LS, _ = cov_form.update(x, P, nu, H, Rt, None, self.form)
            _, nis = gaussian_scores(nu, LS)
            upd = has[:, t]
            x = np.where(upd[:, None], xu, x)
            P = np.where(upd[:, None, None], Pu, P)
            nis_sum += np.where(upd, nis, 0.0)
            xf[:, t], Pf[:, t] = x, P
        xs = xf.copy()
        Ps = Pf.copy()
        for t in range(W - 2, -1, -1):
            # C = P_t Fᵀ_{t+1} (P⁻_{t+1})⁻¹, i.e. Cᵀ = (P⁻_{t+1})⁻¹ F_{t+1} P_t (Cholesky solve)
            Lp = cholesky(Pp[:, t + 1], "predicted covariance P⁻ (smoother)")
            Ct = cholesky_solve(Lp, F[:, t + 1] @ Pf[:, t])
            C = np.swapaxes(Ct, -1, -2)
            xs[:, t] = xf[:, t] + np.einsum("mij,mj->mi", C, xs[:, t + 1] - xp[:, t + 1])
            Ps[:, t] = symmetrize(Pf[:, t] + C @ (Ps[:, t + 1] - Pp[:, t + 1]) @ Ct)
        return xs, Ps, xf, Pf, xp[:, -1], Pp[:, -1], nis_sum, Wsum, zsyn


@hookimpl
def register_estimators(registry):
    registry.add(PMHTFilter.name, PMHTFilter)
