"""Runs stacked into one bank: the storage and inputs of the adaptive estimators' ``run_batch`` (issue #14).

R Monte Carlo runs of a driver whose bank changes membership (the adaptive
estimators of :mod:`hybridtrack.algorithms.adaptive`) become ONE bank of
Σ_r M_r filters, ordered run by run.  Every filter carries its run index; a
step predicts every filter over its own run's Δt and updates it with its own
run's measurement row (the Estimator contract takes ``z`` of shape (M, Σm),
one row per filter).  Membership changes — re-creating a run's bank at a
switch, branching, elimination, pruning — are index arrays passed to the
estimator's ``take`` and ``concatenate``, so a square-root filter keeps its
factors exactly as in the per-run :class:`~hybridtrack.engine.bank.FilterBank`.

Each filter's computation is the per-run one (the estimators act filter by
filter on stacked arrays), so a batch equals the runs done one at a time up to
floating-point rounding (the tests check 1e-12).  The two exceptions handled
here: runs whose measurement misses different components (NaN) at a step are
updated in groups of equal missing pattern (the contract needs one pattern per
update), and transitions are rebuilt only for the filters whose Δt changed or
that were just added.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hybridtrack.core.interfaces import Estimator, MotionModel, Sensor, TransitionBank
from hybridtrack.core.types import Gaussian
from hybridtrack.core.validation import as_float_array
from hybridtrack.engine.bank import BankMoments
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import step_intervals


def batch_measurements(network: SensorNetwork, measurements: Mapping[str, np.ndarray]) -> np.ndarray:
    """Stack per-sensor arrays (runs, K+1, m_i) into z (runs, K+1, Σm), checking names and shapes."""
    if not isinstance(measurements, Mapping):
        raise TypeError(f"measurements: expected a mapping sensor name → (runs, K+1, m) array, got {type(measurements).__name__}")
    arrays = {name: np.asarray(value, dtype=float) for name, value in measurements.items()}
    for name, value in arrays.items():
        if value.ndim != 3:
            raise ValueError(f"measurements[{name!r}]: expected shape (runs, K+1, m), got {value.shape}")
    runs = {value.shape[0] for value in arrays.values()}
    if len(runs) != 1 or 0 in runs:
        raise ValueError(f"measurements: every sensor needs the same positive number of runs, got {sorted(runs)}")
    R = runs.pop()
    return np.stack([network.stack({name: value[r] for name, value in arrays.items()}) for r in range(R)])


def batch_times(times, tau: float | None, runs: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(t (runs, K+1), Δt (runs, K)) from ``times`` (K+1,) shared, (runs, K+1) per run, or None (τ)."""
    if times is None or np.ndim(times) == 1:
        t, dt = step_intervals(None if times is None else np.asarray(times, dtype=float), tau, steps)
        return np.broadcast_to(t, (runs, steps)), np.broadcast_to(dt, (runs, max(steps - 1, 0)))
    times = np.asarray(times, dtype=float)
    if times.shape != (runs, steps):
        raise ValueError(f"times: expected shape ({steps},) shared or ({runs}, {steps}) per run, got {times.shape}")
    pairs = [step_intervals(times[r], tau, steps) for r in range(runs)]
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def batch_prior(prior, runs: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-run prior means (runs, n) and covariances (runs, n, n) from one Gaussian (or (mean, cov)),
    or per-run means (runs, n) with a shared (n, n) or per-run (runs, n, n) covariance."""
    if isinstance(prior, Gaussian):
        mean, cov = prior.mean, prior.cov
    elif isinstance(prior, Sequence) and len(prior) == 2:
        mean, cov = prior
    else:
        raise TypeError(f"prior: expected a Gaussian or (means, covs), got {type(prior).__name__}")
    mean, cov = np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)
    if mean.ndim == 1:
        mean = np.broadcast_to(mean, (runs,) + mean.shape)
    if cov.ndim == 2:
        cov = np.broadcast_to(cov, (runs,) + cov.shape)
    mean = as_float_array(mean, "prior mean", (runs, n))
    cov = as_float_array(cov, "prior cov", (runs, n, n))
    return mean, cov


def per_run(value, runs: int, name: str) -> list:
    """``value`` split into one item per run: None → [None] * runs; otherwise a sequence of length ``runs``."""
    if value is None:
        return [None] * runs
    items = list(value)
    if len(items) != runs:
        raise ValueError(f"{name}: expected one entry per run ({runs}), got {len(items)}")
    return items


def check_recorders(recorders, runs: int) -> dict[int, Any]:
    """``recorders`` as a dict run index → Recorder (indices in 0 … runs − 1)."""
    if recorders is None:
        return {}
    if not isinstance(recorders, Mapping):
        raise TypeError(f"recorders: expected a mapping run index → Recorder, got {type(recorders).__name__}")
    out = {}
    for key, recorder in recorders.items():
        if isinstance(key, bool) or not isinstance(key, (int, np.integer)) or not 0 <= key < runs:
            raise ValueError(f"recorders: expected run indices in 0 … {runs - 1}, got {key!r}")
        out[int(key)] = recorder
    return out


def batchable(estimator: Estimator) -> bool:
    """True when runs of ``estimator`` can share one bank: a centralized, non-sampling estimator
    (a decentralized one's node copies and a particle filter's streams stay per run)."""
    return not getattr(estimator, "sampling", False) and type(estimator).node_scores is Estimator.node_scores


class RunBank(BankMoments):
    """Filters of R runs in one estimator state, ordered run by run: each filter's run, model and switch state.

    ``run`` (F,) is each filter's run index; :meth:`take` changes membership
    (rows in the new order, repeats copy a filter); :meth:`step` predicts every
    filter over its run's Δt and updates it with its run's measurement.
    """

    def __init__(self, estimator: Estimator, layout: Sequence[str], sensors: Sequence[Sensor]):
        self.estimator = estimator
        self.layout = tuple(layout)
        self.sensors = sensors
        self.state: Any = None
        self.models: list[MotionModel] = []
        self.switch_states = np.zeros((0, len(self.layout)))
        self.run = np.zeros(0, dtype=int)
        self._dt = np.zeros(0)  # Δt each filter's cached transition was built for (NaN: none)
        self._F = self._B = self._Q = self._root = None
        self._bank: TransitionBank | None = None  # the same object while nothing changes (estimators cache per bank)
        self._linear: bool | None = None  # every model linear (None: not known yet)
        self._moments: tuple | None = None

    def __len__(self) -> int:
        return len(self.models)

    # ------------------------------------------------------------------ membership
    def initialize(self, means: np.ndarray, covs: np.ndarray, models: Sequence[MotionModel], switch_states: np.ndarray, run: np.ndarray):
        """A new state for filters (means (F, n), covs (F, n, n)) — the caller joins it with :meth:`join`."""
        return self.estimator.initialize(means, covs), list(models), np.asarray(switch_states, dtype=float), np.asarray(run, dtype=int)

    def set(self, state, models: Sequence[MotionModel], switch_states: np.ndarray, run: np.ndarray) -> None:
        """Replace the whole bank (transitions rebuilt at the next step)."""
        self.state, self.models = state, list(models)
        self.switch_states, self.run = np.asarray(switch_states, dtype=float), np.asarray(run, dtype=int)
        self._dt = np.full(len(self.models), np.nan)
        self._F = self._B = self._Q = self._root = None
        self._bank = None
        self._linear = None
        self._moments = None

    def assign(self, rows: np.ndarray, models: Sequence[MotionModel], switch_states: np.ndarray) -> None:
        """Give the filters ``rows`` new models and switch states (their transitions are rebuilt at the next step)."""
        rows = np.asarray(rows, dtype=np.intp).reshape(-1)
        for i, model in zip(rows, models):
            self.models[i] = model
        self.switch_states[rows] = switch_states
        self._dt[rows] = np.nan
        if self._linear:
            self._linear = all(m.linear for m in models)

    def take(self, rows: np.ndarray, fresh: np.ndarray | None = None) -> None:
        """Keep the filters ``rows`` in that order (repeats copy a filter's state).

        ``fresh`` (bool per new row): filters whose model or switch state changed
        (their transition is rebuilt at the next step); the caller sets
        ``models``/``switch_states`` of those rows afterwards.
        """
        rows = np.asarray(rows, dtype=np.intp).reshape(-1)
        self.state = self.estimator.take(self.state, rows)
        self.models = [self.models[i] for i in rows]
        self.switch_states = self.switch_states[rows]
        self.run = self.run[rows]
        self._dt = self._dt[rows]
        if self._linear is False:  # the nonlinear models may have gone
            self._linear = None
        if fresh is not None:
            self._dt = np.where(fresh, np.nan, self._dt)
        self._bank = None
        if self._F is not None:
            self._F, self._B, self._Q = self._F[rows], self._B[rows], self._Q[rows]
            self._root = None if self._root is None else self._root[rows]
        if self._moments is not None:
            self._moments = (self._moments[0][rows], self._moments[1][rows])

    # ------------------------------------------------------------------ steps
    def transitions(self, dt: np.ndarray) -> TransitionBank:
        """Every filter's transition over its own Δt (F,), each built at its switch state (rebuilt where Δt
        changed or the filter is new); a bank with a nonlinear model relinearizes at the current means."""
        dt = np.asarray(dt, dtype=float)
        if self._linear is None:
            self._linear = all(m.linear for m in {id(m): m for m in self.models}.values())
        if not self._linear:  # as FilterBank: a run whose bank has a nonlinear model relinearizes all its filters
            self._F = None
            nonlinear = np.zeros(int(self.run.max()) + 1, dtype=bool)
            nonlinear[self.run[[not m.linear for m in self.models]]] = True
            at = np.where(nonlinear[self.run][:, None], self.means, self.switch_states)
            return TransitionBank.stack([m.transition(float(d), x) for m, d, x in zip(self.models, dt, at)])
        stale = np.flatnonzero(~(dt == self._dt))
        if self._F is None:
            stale = np.arange(len(self.models))
        if stale.size:
            new = self._build(stale, dt)
            if self._F is None or stale.size == len(self.models):
                self._F, self._B, self._Q, self._root = (np.array(new.F), np.array(new.B), np.array(new.Q), new.noise_root)
            else:
                self._F[stale], self._B[stale], self._Q[stale] = new.F, new.B, new.Q
                if self._root is not None and new.noise_root is not None and new.noise_root.shape[1:] == self._root.shape[1:]:
                    self._root[stale] = new.noise_root
                else:
                    self._root = None
            self._dt = dt.copy()
            self._bank = None
        if self._bank is None:
            self._bank = TransitionBank(self._F, self._B, self._Q, self._root)
        return self._bank

    def _build(self, rows: np.ndarray, dt: np.ndarray) -> TransitionBank:
        """The transitions of filters ``rows``: one :meth:`~hybridtrack.core.interfaces.MotionModel.transition_bank`
        call per (model, Δt) group (vectorized over the runs that switched together), :func:`grouped_transitions`."""
        return grouped_transitions([self.models[i] for i in rows], dt[rows], self.switch_states[rows])

    def step(self, dt: np.ndarray | None, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predict every filter over ``dt`` (F,) (None: update only), update it with its row of ``z`` (F, Σm).

        Returns ℓ (F,), NIS (F,) and m (F,), the number of measured components
        of each filter's update (0: prediction only).  Rows with different
        missing (NaN) components are updated in separate groups.
        """
        state = self.state if dt is None else self.estimator.predict(self.state, self.transitions(dt))
        missing = np.isnan(z)
        F = len(self.models)
        if not missing.any():
            self.state, innovation = self.estimator.update(state, z, self.sensors, self.layout)
            self._moments = None
            m = np.full(F, innovation.measurement_dim)
            return np.asarray(innovation.loglik, dtype=float), np.asarray(innovation.nis, dtype=float), m
        patterns, group = np.unique(missing, axis=0, return_inverse=True)
        group = group.reshape(-1)
        loglik, nis, m = np.zeros(F), np.zeros(F), np.zeros(F, dtype=int)
        parts, order = [], []
        for g in range(patterns.shape[0]):
            rows = np.flatnonzero(group == g)
            part, innovation = self.estimator.update(self.estimator.take(state, rows), z[rows], self.sensors, self.layout)
            parts.append(part)
            order.append(rows)
            loglik[rows], nis[rows], m[rows] = innovation.loglik, innovation.nis, innovation.measurement_dim
        order = np.concatenate(order)
        inverse = np.empty_like(order)
        inverse[order] = np.arange(order.size)
        self.state = self.estimator.take(self.estimator.concatenate(parts), inverse)
        self._moments = None
        return loglik, nis, m


def grouped_transitions(models: Sequence[MotionModel], dts, switch_states: np.ndarray) -> TransitionBank:
    """The transitions of S filters, filter i running ``models[i]`` over ``dts[i]`` (a float for all, or (S,))
    from switch state ``switch_states[i]`` (S, n), all in one layout: one
    :meth:`~hybridtrack.core.interfaces.MotionModel.transition_bank` call per (model, Δt) group, scattered back
    into filter order.  Equal to ``TransitionBank.stack([models[i].transition(dts[i], switch_states[i]) …])``
    entry by entry (``transition_bank`` must equal the stacked transitions; the motion tests check), so
    F_i, B_i, Q_i are seed 000's eq. (3) transitions of each filter's mode.  The noise roots G·chol(Q) are
    kept when every group has one of the same shape (else ``None``, as ``TransitionBank.stack`` gives for
    noise inputs of different sizes)."""
    switch_states = np.asarray(switch_states, dtype=float)
    S = len(models)
    if switch_states.ndim != 2 or switch_states.shape[0] != S:
        raise ValueError(f"switch_states: expected ({S}, n) for {S} filters, got shape {switch_states.shape}")
    steps = np.broadcast_to(np.asarray(dts, dtype=float), (S,))
    groups: dict = {}
    for i, (model, d) in enumerate(zip(models, steps)):
        groups.setdefault((id(model), float(d)), (model, []))[1].append(i)
    n = switch_states.shape[1]
    F, B, Q = np.zeros((S, n, n)), np.zeros((S, n)), np.zeros((S, n, n))
    roots, positions = [], []
    for (_, d), (model, members) in groups.items():
        members = np.asarray(members)
        bank = model.transition_bank(d, switch_states[members])
        F[members], B[members], Q[members] = bank.F, bank.B, bank.Q
        roots.append(bank.noise_root)
        positions.append(members)
    root = None
    if all(r is not None for r in roots) and len({r.shape[1:] for r in roots}) == 1:
        root = np.zeros((S,) + roots[0].shape[1:])
        for members, r in zip(positions, roots):
            root[members] = r
    return TransitionBank(F, B, Q, root)
