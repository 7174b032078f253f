"""Bootstrap particle filter bank (SIR) with systematic resampling (Gordon, Salmond & Smith 1993; Arulampalam et al. 2002).

Each of the M filters of the bank carries N particles x⁽ⁱ⁾ with log-weights
ln w⁽ⁱ⁾ (normalised: Σ w⁽ⁱ⁾ = 1); the state holds them stacked, particles
(M, N, n) and log-weights (M, N), and every step is one vectorized operation
over filters and particles (Arulampalam et al. 2002, Algorithm 4, "SIR"):

* predict (the bootstrap proposal, the transition density):
  x⁽ⁱ⁾ ← F x⁽ⁱ⁾ + B + W e⁽ⁱ⁾, e⁽ⁱ⁾ ~ N(0, I), W Wᵀ = G Q Gᵀ (W is the
  bank's ``noise_root`` G chol(Q_w), else :func:`hybridtrack.sdk.linalg.psd_square_root`
  of G Q Gᵀ).  A linearizing callable (nonlinear motion, ``accepts_nonlinear``)
  is evaluated at every particle, x (M·N, n) → a bank of M·N transitions, so
  F x⁽ⁱ⁾ + B = f(x⁽ⁱ⁾) is the exact nonlinear step of each particle;
* update: w⁽ⁱ⁾ ∝ w⁽ⁱ⁾⁻ p(z | x⁽ⁱ⁾) with
  ln p(z | x) = −½(m ln 2π + ln det R + νᵀR⁻¹ν), ν = residual(z, h(x)) (angles
  wrapped by the sensor; R from ``measurement_noise``; NaN components left out
  as in every estimator, :mod:`hybridtrack.sdk.measurements`);
* the step's log-likelihood, the SIR estimate of ln p(z_k | z_1:k−1):
  ℓ = ln Σ_i w⁽ⁱ⁾⁻ p(z | x⁽ⁱ⁾) (the log of the mean unnormalised weight when
  the prior weights are uniform), computed in log space (log-sum-exp);
* effective sample size N_eff = 1 / Σ_i (w⁽ⁱ⁾)² (Arulampalam et al. eq. 51);
  where N_eff < ``threshold`` · N the filter is resampled systematically
  (Kitagawa 1996; Arulampalam et al. Algorithm 2): one U ~ U[0, 1) per filter,
  u_j = (j + U)/N, particle i copied once for each u_j in
  [c_{i−1}, c_i), c_i = Σ_{l≤i} w⁽ˡ⁾; the weights become 1/N;
* optional regularisation after resampling (``regularize=True``; Musso, Oudjane
  & Le Gland 2001; Arulampalam et al. Algorithm 6): x⁽ⁱ⁾ ← x⁽ⁱ⁾ + h D ε⁽ⁱ⁾,
  ε ~ N(0, I), D Dᵀ the weighted covariance of the particles before resampling,
  h = A N^{−1/(n+4)}, A = (4/(n+2))^{1/(n+4)} (Silverman 1986's rule for the
  Gaussian kernel).

In clutter (``accepts_scans``: ``z`` a :class:`~hybridtrack.sdk.scans.Scan` or a
sequence of them, one per sensor) a scan Z = {z_1 … z_L} replaces z and the
particle likelihood is the scan likelihood of the parametric clutter model
(Poisson false measurements of density λ, detection probability P_D; seed 004
"Распределение наблюдений"; Gordon, Salmond & Ewing 1995, "Bayesian state
estimation for tracking and guidance using the bootstrap filter", J. Guidance
18(6), eq. 12; Bar-Shalom, Li & Kirubarajan 2001 §11.7.4 for the ratio to the
clutter-only density):

    Λ(x) = (1 − P_D P_G) + (P_D / λ) Σ_r N(z_r; h(x), R)             (λ > 0)
    Λ(x) = P_D Σ_r N(z_r; h(x), R)  (r gated),  1 − P_D P_G  (none)   (λ = 0)

(no gate: P_G = 1 and every r; with ``gate_probability`` only the candidates
with d²_r = ν_rᵀS⁻¹ν_r ≤ γ, P(χ²_m ≤ γ) = P_G, against the particle prediction
(ẑ, S) below count, as in PDA — in dense clutter most candidates are then never
evaluated at the particles)

w⁽ⁱ⁾ ∝ w⁽ⁱ⁾⁻ Λ(x⁽ⁱ⁾), vectorized over filters, particles and candidates
(ν (M, N, L, m)); the step's log-likelihood is ℓ = ln Σ_i w⁽ⁱ⁾⁻ Λ(x⁽ⁱ⁾), the SIR
estimate of PDA's association likelihood ln Λ (no gate: P_G = 1), which is what
the detectors compare across a bank in clutter.  The association weights are
the posterior probabilities of "candidate r is the target" and "none is",
β_r ∝ (P_D/λ) Σ_i w⁽ⁱ⁾⁻ N(z_r; h(x⁽ⁱ⁾), R), β_0 ∝ 1 − P_D P_G (Σ β = 1), recorded
in a :class:`~hybridtrack.core.protocols.Association` per scan with the particle
prediction ẑ, S, d²_r and the gate.  The innovation reported
is the combined ν = Σ_r β_r ν_r, ν_r = residual(z_r, ẑ), with S and its NIS;
several scans of one step are applied one after the other.  With P_D = 1,
λ = 0 and one candidate, Λ(x) = N(z; h(x), R) and the update is the ordinary
one.  A scan impossible under the model (P_D P_G = 1 and nothing gated) is
taken as no measurement (weights unchanged, ℓ = 0).

The :class:`~hybridtrack.core.interfaces.Innovation` of an update holds, besides ℓ,
the particle prediction of the measurement: ν̄ = Σ w⁽ⁱ⁾⁻ ν⁽ⁱ⁾ (z against the
particle mean of h(x), the residuals wrapped per particle),
S = Σ w⁽ⁱ⁾⁻ (ν⁽ⁱ⁾ − ν̄)(ν⁽ⁱ⁾ − ν̄)ᵀ + R (the sample covariance of h(x) plus R)
and NIS = ν̄ᵀS⁻¹ν̄; :class:`ParticleInnovation` adds N_eff, whether each filter
was resampled, and the Gaussian ℓ of (ν̄, S).  ``mean`` and ``covariance`` are
the weighted moments Σ w x and Σ w (x − x̄)(x − x̄)ᵀ.

Random numbers: every draw of a step comes from a generator seeded by (the filter's stream key, drawn from
``seed`` at ``initialize``; the stage; its step counter), so a filter's step is a function of its own state
(what follows, and why the estimator is ``sampling``: docs/estimators.md, "Random numbers").
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Sequence
from functools import cached_property

import attrs
import numpy as np

from hybridtrack import hookimpl
from hybridtrack.core.interfaces import Innovation, Sensor, TransitionBank
from hybridtrack.core.protocols import Association, ClutterInnovation
from hybridtrack.core.validation import check_prior_mixture
from hybridtrack.sdk.estimation import BankEstimator, DerivedMoments, bank_field, check_layout, guarded
from hybridtrack.sdk.linalg import CholeskyFactor, cholesky, psd_square_root, symmetrize
from hybridtrack.sdk.mixtures import logsumexp
from hybridtrack_plugins.filters._association import (
    as_scans,
    candidate_residuals,
    distances,
    gate_threshold,
    scan_by_scan,
    set_clutter_model,
    stacked_innovation,
    summed_loglik,
)
from hybridtrack_plugins.filters.clutter_recording import RecordsFilterStates

#: stages of a step, part of each draw's seed so that the draws of one step never share a stream
_INITIALIZE, _PREDICT, _RESAMPLE = 0, 1, 2


@attrs.frozen(eq=False)
class ParticleInnovation(Innovation):
    """The :class:`Innovation` of a particle update plus what the resampling did.

    ``loglik`` is the SIR estimate ℓ = ln Σ_i w⁽ⁱ⁾⁻ p(z | x⁽ⁱ⁾); ``gaussian_loglik``
    (M,) the Gaussian −½(m ln 2π + ln det S + NIS) of (ν̄, S);
    ``effective_sample_size`` (M,) N_eff = 1/Σ w² of the updated weights (before
    resampling); ``resampled`` (M,) bool, the filters resampled at this step.
    """

    gaussian_loglik: np.ndarray = None
    effective_sample_size: np.ndarray = None
    resampled: np.ndarray = None


@attrs.frozen(eq=False)
class ParticleClutterInnovation(ClutterInnovation):
    """The :class:`ClutterInnovation` of a particle update on scans (module docstring).

    ``loglik`` (M,) ℓ = Σ_scans ln Σ_i w⁽ⁱ⁾⁻ Λ(x⁽ⁱ⁾) (the association likelihood, as
    ``association_loglik`` but 0 for an empty scan when P_D = 1); ``nu`` the combined
    innovations, ``S`` block-diagonal over the scans; ``gaussian_loglik``,
    ``effective_sample_size`` and ``resampled`` as in :class:`ParticleInnovation`.
    """

    gaussian_loglik: np.ndarray = None
    effective_sample_size: np.ndarray = None
    resampled: np.ndarray = None


def weighted_moments(particles: np.ndarray, log_weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x̄ = Σ w x (M, n) and P = Σ w (x − x̄)(x − x̄)ᵀ (M, n, n) of particles (M, N, n) with normalised log-weights (M, N)."""
    w = np.exp(log_weights)
    mean = np.einsum("mk,mki->mi", w, particles)
    d = particles - mean[:, None, :]
    cov = np.swapaxes(d * w[..., None], -1, -2) @ d
    return mean, symmetrize(cov)


def effective_sample_size(log_weights: np.ndarray) -> np.ndarray:
    """N_eff = 1 / Σ w² (Arulampalam et al. 2002 eq. 51) of normalised log-weights (..., N), in log space."""
    return np.exp(-logsumexp(2.0 * log_weights, axis=-1))


def systematic_resample(log_weights: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Indices (R, N) of systematic resampling (Kitagawa 1996; Arulampalam et al. 2002 Algorithm 2).

    ``log_weights`` (R, N) normalised, ``u`` (R,) one U[0, 1) draw per row: with
    c_i = Σ_{l≤i} w_l, index j takes the first i with c_i > (j + u)/N.  Particle i
    is copied ⌊N w_i⌋ or ⌈N w_i⌉ times.  One ``searchsorted`` over all rows (each
    row's c and u shifted by its row number, so the rows stay apart).
    """
    R, N = log_weights.shape
    c = np.cumsum(np.exp(log_weights), axis=1)
    c[:, -1] = 1.0  # the total is 1 up to rounding; the last particle closes the row
    offsets = np.arange(R, dtype=float)[:, None]
    points = (np.arange(N) + u[:, None]) / N
    index = np.searchsorted((c + offsets).ravel(), (points + offsets).ravel(), side="right").reshape(R, N)
    return np.minimum(index - N * np.arange(R)[:, None], N - 1)


def silverman_bandwidth(N: int, n: int) -> float:
    """h = A N^{−1/(n+4)}, A = (4/(n+2))^{1/(n+4)}: Silverman's (1986) rule for a Gaussian kernel (Arulampalam et al. 2002 eq. 82)."""
    return (4.0 / (n + 2)) ** (1.0 / (n + 4)) * N ** (-1.0 / (n + 4))


@attrs.frozen(eq=False, slots=False)
class ParticleState(DerivedMoments):
    """A bank of M particle filters: particles (M, N, n), normalised log-weights (M, N), random-stream keys (M, 2)
    and step counters (M,), plus the moments of the last prediction and the last innovation; ``weights`` w (M, N)
    (Σ_i w⁽ⁱ⁾ = 1) and ``effective_sample_size`` N_eff = 1/Σ w² (M,) read the current weights."""

    particles: np.ndarray = bank_field(0)
    log_weights: np.ndarray = bank_field(0)
    keys: np.ndarray = bank_field(0)
    counters: np.ndarray = bank_field(0)
    x_predicted: np.ndarray = bank_field(0)
    P_predicted: np.ndarray = bank_field(0)
    innovation: Innovation | None = None

    @cached_property
    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        return weighted_moments(self.particles, self.log_weights)

    weights = property(lambda self: np.exp(self.log_weights))
    effective_sample_size = property(lambda self: effective_sample_size(self.log_weights))


def _check_seed(seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        return np.random.default_rng()
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise TypeError(f"seed: expected an int ≥ 0, a numpy.random.Generator or None, got {type(seed).__name__} {seed!r}")
    if seed < 0:
        raise ValueError(f"seed: expected an int ≥ 0, got {seed}")
    return np.random.default_rng(int(seed))


class ParticleFilter(RecordsFilterStates, BankEstimator):
    """Bootstrap particle filter bank (SIR, systematic resampling when N_eff < threshold · N); see the module docstring.

    ``particles`` N ≥ 1 per filter; ``threshold`` in (0, 1] (default ½: resample
    when N_eff < N/2; 1 resamples at every measured step); ``regularize``
    (default False): Gaussian kernel jitter after resampling with Silverman's
    bandwidth; ``seed``: an int ≥ 0, a ``numpy.random.Generator`` (consumed at
    each ``initialize``), or None (fresh entropy, not reproducible).  The
    moments of N < n + 1 particles are singular.  For scans (clutter):
    ``detection_probability`` P_D in (0, 1] and ``clutter_density`` λ ≥ 0
    (false measurements per unit measurement volume per step) of the scan
    likelihood Λ(x), ``gate_probability`` P_G in (0, 1) or None (default: no
    gate, every candidate evaluated); an array ``z`` ignores them.
    """

    name = "particle"
    exact_kalman = False
    accepts_nonlinear = True
    accepts_scans = True
    sampling = True
    example_parameters = {"particles": 400, "seed": 0}

    def __init__(
        self,
        particles: int = 1000,
        threshold: float = 0.5,
        regularize: bool = False,
        seed=0,
        detection_probability: float = 1.0,
        clutter_density: float = 0.0,
        gate_probability: float | None = None,
    ):
        super().__init__()
        set_clutter_model(self, detection_probability, clutter_density, gate_probability)
        if isinstance(particles, bool) or not isinstance(particles, numbers.Integral):
            raise TypeError(f"particles: expected an int ≥ 1 (particles per filter), got {type(particles).__name__} {particles!r}")
        if particles < 1:
            raise ValueError(f"particles: expected an int ≥ 1 (particles per filter), got {particles}")
        if isinstance(threshold, bool) or not isinstance(threshold, numbers.Real):
            raise TypeError(f"threshold: expected a number in (0, 1] (resample when N_eff < threshold · N), got {threshold!r}")
        if not 0.0 < threshold <= 1.0:
            raise ValueError(f"threshold: expected a number in (0, 1] (resample when N_eff < threshold · N), got {threshold}")
        if not isinstance(regularize, (bool, np.bool_)):
            raise TypeError(f"regularize: expected a bool, got {regularize!r}")
        self.particles = int(particles)
        self.threshold = float(threshold)
        self.regularize = bool(regularize)
        self._seeds = _check_seed(seed)
        self._root_cache: tuple | None = None

    @staticmethod
    def _generators(keys: np.ndarray, counters: np.ndarray, stage: int, rows=None):
        """One generator per filter (of ``rows``), seeded by (key, stage, counter): a filter's draws depend on its state only."""
        for r in range(keys.shape[0]) if rows is None else rows:
            yield np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(keys[r, 0]), int(keys[r, 1]), stage, int(counters[r])])))

    def _normals(self, state_keys, counters, stage, shape) -> np.ndarray:
        return np.stack([g.standard_normal(shape) for g in self._generators(state_keys, counters, stage)])

    def initialize(self, mean, cov) -> ParticleState:
        """N particles per filter drawn from N(mean, cov); uniform weights; a fresh stream key per filter."""
        x, P = self.check_prior(mean, cov)
        keys, counters = self._new_streams(x.shape[0])
        e = self._normals(keys, counters, _INITIALIZE, (self.particles, x.shape[1]))
        return self._initial_state(x[:, None, :] + e @ np.swapaxes(cholesky(P, "cov"), -1, -2), keys)

    def initialize_mixture(self, means, covs, weights) -> ParticleState:
        """N particles per filter drawn from a Gaussian mixture Σ_c w_c N(means_c, covs_c) (e.g. the range-parameterised
        prior of bearings-only tracking, :func:`hybridtrack_plugins.filters.gaussian_sum.range_parameterised`).

        means (M, C, n), covs (M, C, n, n) positive definite, weights (M, C) ≥ 0 with a positive sum per filter
        (renormalised).  The component of each particle is allocated systematically (Kitagawa 1996): component c
        gets ⌊N w_c⌋ or ⌈N w_c⌉ particles, then each is drawn from its Gaussian; uniform weights 1/N.
        """
        means, covs, weights, total = check_prior_mixture(means, covs, weights)
        M, C, n = means.shape
        roots = cholesky(covs, "covs")
        keys, counters = self._new_streams(M)
        generators = list(self._generators(keys, counters, _INITIALIZE))
        u = np.array([g.random() for g in generators])
        c = np.cumsum(weights / total[:, None], axis=1)
        c[:, -1] = 1.0
        points = (np.arange(self.particles) + u[:, None]) / self.particles  # (M, N), systematic points in [0, 1)
        component = np.minimum((points[:, :, None] >= c[:, None, :]).sum(axis=2), C - 1)  # first c with c_c > point
        e = np.stack([g.standard_normal((self.particles, n)) for g in generators])
        rows = np.arange(M)[:, None]
        return self._initial_state(means[rows, component] + np.einsum("mkij,mkj->mki", roots[rows, component], e), keys)

    def _new_streams(self, M: int) -> tuple[np.ndarray, np.ndarray]:
        """A fresh stream key (M, 2) per filter from ``seed``, and the step counters at 0."""
        return self._seeds.integers(0, np.iinfo(np.uint64).max, size=(M, 2), dtype=np.uint64, endpoint=True), np.zeros(M, dtype=np.int64)

    def _initial_state(self, particles: np.ndarray, keys: np.ndarray) -> ParticleState:
        """The state of freshly drawn particles (M, N, n): uniform weights 1/N, the counters past the draw."""
        log_weights = np.full(particles.shape[:2], -math.log(self.particles))
        mean, cov = weighted_moments(particles, log_weights)
        return ParticleState(particles, log_weights, keys, np.ones(len(keys), dtype=np.int64), mean, cov, None)

    def _noise_root(self, bank: TransitionBank) -> np.ndarray:
        """W (K, n, r) with W Wᵀ = G Q Gᵀ: the bank's ``noise_root``, else the PSD square root of Q (cached per bank)."""
        if bank.noise_root is not None:
            return np.asarray(bank.noise_root, dtype=float)
        cached = self._root_cache
        if cached is not None and cached[0] is bank and cached[1] is bank.Q:
            return cached[2]
        root = psd_square_root(np.asarray(bank.Q, dtype=float))
        self._root_cache = (bank, bank.Q, root)
        return root

    @guarded
    def predict(self, state: ParticleState, transitions) -> ParticleState:
        """x⁽ⁱ⁾ ← F x⁽ⁱ⁾ + B + W e⁽ⁱ⁾ per filter (TransitionBank) or per particle (a linearizing callable, F x + B = f(x))."""
        if not isinstance(state, ParticleState):
            raise TypeError(f"state: expected a ParticleState (from initialize), got {type(state).__name__}")
        M, N, n = state.particles.shape
        per_particle = callable(transitions) and not isinstance(transitions, TransitionBank)
        flat = state.particles.reshape(M * N, n)
        bank = self.check_transitions(transitions, M * N, n, flat) if per_particle else self.check_transitions(transitions, M, n)
        root = self._noise_root(bank)
        e = self._normals(state.keys, state.counters, _PREDICT, (N, root.shape[-1]))
        if per_particle:
            moved = np.einsum("kij,kj->ki", bank.F, flat) + bank.B + np.einsum("kij,kj->ki", root, e.reshape(M * N, -1))
            particles = moved.reshape(M, N, n)
        else:
            particles = state.particles @ np.swapaxes(bank.F, -1, -2)
            particles += bank.B[:, None, :]
            particles += e @ np.swapaxes(root, -1, -2)
        self.check_finite("predict", predicted_particles=particles)
        x, P = weighted_moments(particles, state.log_weights)
        return ParticleState(particles, state.log_weights, state.keys, state.counters + 1, x, P, None)

    @guarded
    def update(self, state: ParticleState, z, sensors: Sequence[Sensor], layout: Sequence[str]):
        """SIR update: w ∝ w⁻ p(z | x) in log space, ℓ, N_eff, systematic resampling where N_eff < threshold · N."""
        if not isinstance(state, ParticleState):
            raise TypeError(f"state: expected a ParticleState (from initialize), got {type(state).__name__}")
        M, N, n = state.particles.shape
        scans = as_scans(z)
        if scans is not None or (isinstance(z, (list, tuple)) and len(z) == 0):
            return self._update_scans(state, scans or [], sensors, layout)
        step = self.measurement_step(z, sensors, layout, M, n, state)
        if step is None:
            return self.unmeasured(state, M)
        # ν⁽ⁱ⁾ = residual(z, h(x⁽ⁱ⁾)) (M, N, m) of the present components, through the step's sensor models
        flat = state.particles.reshape(M * N, n)
        if step.H is not None:
            z_pred = step.predicted(flat, layout)[0]
        else:
            z_pred = np.concatenate([model.measure(flat, layout) for model in step.models], axis=-1)
        z_rows = np.broadcast_to(step.z[:, None, :], (M, N, step.dim)).reshape(M * N, step.dim)
        nu = np.asarray(step.with_z(z_rows).residual(z_pred)).reshape(M, N, step.dim)
        R = np.asarray(step.R, dtype=float)
        particle_loglik, _ = CholeskyFactor(R if R.ndim == 2 else R[:, None], "measurement noise R").scores(nu)
        prior = state.log_weights
        joint = prior + particle_loglik
        loglik = logsumexp(joint, axis=1)
        log_weights = joint - loglik[:, None]
        # the particle prediction of z: ν̄ = Σ w⁻ ν, S = Σ w⁻ (ν − ν̄)(ν − ν̄)ᵀ + R
        w_prior = np.exp(prior)
        nu_mean = np.einsum("mk,mki->mi", w_prior, nu)
        d = nu - nu_mean[:, None, :]
        S = symmetrize(np.swapaxes(d * w_prior[..., None], -1, -2) @ d + R)
        gaussian_loglik, nis = CholeskyFactor(S, "innovation covariance S").scores(nu_mean)
        return self._resampled(state, log_weights, ParticleInnovation, nu_mean, S, loglik, nis, gaussian_loglik)

    def _update_scans(self, state: ParticleState, scans: list, sensors, layout):
        """w ∝ w⁻ Λ(x) scan after scan, ℓ = Σ ln Λ̂, then N_eff and resampling as in :meth:`update`."""
        M, N, n = state.particles.shape
        check_layout(layout, n)
        step = functools.partial(self._scan_weights, particles=state.particles, layout=tuple(layout))
        log_weights, used, blocks, records = scan_by_scan(self, state.log_weights, scans, sensors, layout, step, linear=False)
        nu, S, gaussian_loglik, nis = stacked_innovation(M, used, blocks, factored=True)
        loglik = summed_loglik(records, M)
        return self._resampled(state, log_weights, ParticleClutterInnovation, nu, S, loglik, nis, tuple(records), gaussian_loglik)

    def _resampled(self, state: ParticleState, log_weights, innovation_class, *scores):
        """The updated state: N_eff of the new weights, systematic resampling where N_eff < threshold · N, and the
        innovation ``innovation_class(*scores, N_eff, resampled)``."""
        N, n = state.particles.shape[1:]
        ess = effective_sample_size(log_weights)
        resampled = ess < self.threshold * N
        particles = state.particles
        if resampled.any():
            # systematic resampling of those filters (then weights 1/N), with the regularisation jitter if enabled
            rows = np.flatnonzero(resampled)
            generators = list(self._generators(state.keys, state.counters, _RESAMPLE, rows))
            index = systematic_resample(log_weights[rows], np.array([g.random() for g in generators]))
            chosen = np.take_along_axis(particles[rows], index[..., None], axis=1)
            if self.regularize:
                _, spread = weighted_moments(particles[rows], log_weights[rows])
                eps = np.stack([g.standard_normal((N, n)) for g in generators])
                chosen = chosen + silverman_bandwidth(N, n) * (eps @ np.swapaxes(psd_square_root(spread), -1, -2))
            particles, log_weights = particles.copy(), log_weights.copy()
            particles[rows], log_weights[rows] = chosen, -math.log(N)
        innovation = innovation_class(*scores, ess, resampled)
        new = ParticleState(particles, log_weights, state.keys, state.counters + 1, state.x_predicted, state.P_predicted, innovation)
        self.check_finite("update", updated_mean=new.mean)
        return new, innovation

    def _scan_weights(self, log_weights, scan, sensor, model, *, particles, layout):
        """One scan: posterior log-weights (M, N), the combined ν (M, m), S (M, m, m) and the Association (ln Λ̂ (M,)
        its ``loglik``)."""
        M, N, n = particles.shape
        R = np.asarray(sensor.noise_cov, dtype=float)
        L, m = scan.z.shape
        flat = particles.reshape(M * N, n)
        h = model.measure(flat, layout).reshape(M, N, m)
        # the particle prediction of z: ẑ = h(x̄) + Σ w δ, δ = residual(h(x), h(x̄)) (wrapped about the mean for angles)
        w = np.exp(log_weights)
        h_bar = model.measure(np.einsum("mk,mki->mi", w, particles), layout)
        delta = h - h_bar[:, None, :] if model.plain_residual else sensor.residual(h, np.broadcast_to(h_bar[:, None, :], h.shape))
        delta_mean = np.einsum("mk,mki->mi", w, delta)
        z_hat = h_bar + delta_mean
        d = delta - delta_mean[:, None, :]
        S = symmetrize(np.swapaxes(d * w[..., None], -1, -2) @ d + R)
        chol_S = cholesky(S, "innovation covariance S")
        gamma = gate_threshold(self.gate_probability, m)
        nu_r = np.asarray(candidate_residuals(z_hat, scan.z, sensor, model))
        d2 = distances(nu_r, chol_S)  # (M, L)
        gated = d2 <= gamma
        cols = np.flatnonzero(gated.any(axis=0))  # candidates inside some filter's gate: the only ones evaluated
        any_gated = gated.any(axis=1)
        miss_term = np.where(
            (self.clutter_density > 0) | ~any_gated, self.log_miss, -np.inf
        )  # λ = 0 and a candidate gated: no miss term (as PDA)
        beta = np.zeros((M, L))
        if cols.size:
            nu_i = np.asarray(candidate_residuals(h.reshape(M * N, m), scan.z[cols], sensor, model)).reshape(M, N, cols.size, m)
            log_n, _ = CholeskyFactor(R, "measurement noise R").scores(nu_i)  # (M, N, Lg)
            log_detected = np.where(gated[:, None, cols], self.log_detect + log_n, -np.inf)
            terms = np.concatenate([np.broadcast_to(miss_term[:, None, None], (M, N, 1)), log_detected], axis=2)
            particle_loglik = logsumexp(terms, axis=2)  # ln Λ(x⁽ⁱ⁾) (M, N)
            joint = log_weights + particle_loglik
            loglik = logsumexp(joint, axis=1)
            ok = np.isfinite(loglik)
            new_log_weights = np.where(ok[:, None], joint - np.where(ok, loglik, 0.0)[:, None], log_weights)
            # association weights: β_0 ∝ 1 − P_D P_G, β_r ∝ (P_D/λ) Σ_i w_i N(z_r; h(x_i), R) over the gated r
            per_candidate = logsumexp(log_weights[:, :, None] + log_detected, axis=1)  # (M, Lg)
            beta[:, cols] = np.where(ok[:, None], np.exp(per_candidate - np.where(ok, loglik, 0.0)[:, None]), 0.0)
            beta0 = np.where(ok, np.exp(miss_term - np.where(ok, loglik, 0.0)), 1.0)
        else:
            new_log_weights = log_weights
            loglik = np.full(M, self.log_miss)
            beta0 = np.ones(M)
        combined = np.einsum("jl,jli->ji", beta, nu_r)
        selected = np.where(any_gated & (beta.sum(axis=1) > 0), np.argmax(beta, axis=1) if L else -1, -1).astype(np.int64)
        record = Association(sensor.name, scan.z, z_hat, S, gamma, d2, gated, beta, beta0, selected, loglik)
        return new_log_weights, combined, S, record


@hookimpl
def register_estimators(registry):
    registry.add(ParticleFilter.name, ParticleFilter)
