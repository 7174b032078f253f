"""One bank of filters: R runs × M_r filters in one estimator state, whose membership changes between steps.

The storage under every algorithm with a changing bank (known switch,
unknown change, known modes); a single run is R = 1.  The filters are
ordered run by run; each carries its run index, its motion model and the
switch state its transition is fixed at (SPEC §1: a turn's ω and centre come
from the estimate at the hypothesised switch).  The bank holds the
estimator's own state object (covariance, information, square-root factors,
per-node copies) from step to step and changes its membership only through
the estimator's bank operations (:meth:`~hybridtrack.core.interfaces.Estimator.take`
and :meth:`~hybridtrack.core.interfaces.Estimator.concatenate`), so a
square-root filter's factors are propagated, never rebuilt from P, and a
decentralized filter's nodes keep their own states.

A step predicts every filter over its own run's Δt and updates it with its
own run's measurement row (the Estimator contract takes ``z`` of shape
(M, Σm), one row per filter).  Runs
whose measurements miss different components (NaN) at a step are updated in
groups of equal missing pattern (the contract needs one pattern per update).
Transitions are built for each filter's Δt and kept until its Δt, model or
switch state changes, so regular sampling builds each filter's transition
once; a run whose bank holds a nonlinear model relinearizes all its filters
at their means every step (EKF; MotionModel contract: F x̂ + B = f(x̂)).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.core.interfaces import Estimator, Innovation, MotionModel, Sensor, TransitionBank


@attrs.frozen(eq=False)
class BankStep:
    """One step of a bank: ℓ (F,), NIS (F,) and m (F,), the number of components each filter's update measured
    (0: prediction only); ``innovation`` the estimator's own Innovation when one update covered the whole bank
    (e.g. the associations of a clutter-aware update), else None."""

    loglik: np.ndarray
    nis: np.ndarray
    m: np.ndarray
    innovation: Innovation | None = None


class FilterBank:
    """Filters of R runs in one estimator state, ordered run by run: each filter's run, model and switch state.

    ``run`` (F,) is each filter's run index; :meth:`start` / :meth:`set` create
    the bank, :meth:`take` changes membership (rows in the new order, repeats
    copy a filter), :meth:`add` appends copies behind their runs' filters,
    :meth:`assign` gives filters new models; :meth:`step` predicts every filter
    over its run's Δt and updates it with its run's measurement.
    """

    def __init__(self, estimator: Estimator, layout: Sequence[str], sensors: Sequence[Sensor]):
        self.estimator = estimator
        self.layout = tuple(layout)
        self.sensors = sensors
        self.runs = 1
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

    # ------------------------------------------------------------------ reading
    def _read(self) -> tuple[np.ndarray, np.ndarray]:
        if self._moments is None:
            covs = np.asarray(self.estimator.covariance(self.state), dtype=float)
            self._moments = (np.asarray(self.estimator.mean(self.state), dtype=float), 0.5 * (covs + np.swapaxes(covs, -1, -2)))
        return self._moments

    @property
    def means(self) -> np.ndarray:
        """x (F, n) of every filter."""
        return self._read()[0]

    @property
    def covs(self) -> np.ndarray:
        """P (F, n, n) of every filter, symmetrized ½(P + Pᵀ)."""
        return self._read()[1]

    @property
    def sizes(self) -> np.ndarray:
        """Filters per run (R,)."""
        return np.bincount(self.run, minlength=self.runs)

    @property
    def offsets(self) -> np.ndarray:
        """The first filter of each run (R,)."""
        return np.searchsorted(self.run, np.arange(self.runs))

    def node_scores(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(ℓ, NIS) each node computed locally, shape (N, F), for a decentralized estimator; else None."""
        scores = self.estimator.node_scores(self.state)
        return None if scores is None else (np.asarray(scores[0], float), np.asarray(scores[1], float))

    # ------------------------------------------------------------------ membership
    def start(self, means, covs, models: Sequence[MotionModel], switch_states, run=None) -> None:
        """A new bank of one filter per model starting at N(means, covs) ((F, n), (F, n, n); one (n,), (n, n)
        for all), its transition fixed at ``switch_states`` ((F, n) or (n,)); ``run`` (F,) default all 0."""
        F = len(models)
        means, covs = np.asarray(means, dtype=float), np.asarray(covs, dtype=float)
        means = np.broadcast_to(means, (F,) + means.shape[-1:])
        covs = np.broadcast_to(covs, (F,) + covs.shape[-2:])
        self.set(self.estimator.initialize(means, covs), models, switch_states, run)

    def set(self, state, models: Sequence[MotionModel], switch_states, run=None) -> None:
        """Replace the whole bank by ``state`` (transitions rebuilt at the next step)."""
        self.state, self.models = state, list(models)
        F = len(self.models)
        self.switch_states = np.array(np.broadcast_to(np.asarray(switch_states, dtype=float), (F, len(self.layout))))
        self.run = np.zeros(F, dtype=int) if run is None else np.asarray(run, dtype=int)
        self.runs = int(self.run.max()) + 1 if F else 1
        self._dt = np.full(F, np.nan)
        self._F = self._B = self._Q = self._root = None
        self._bank = None
        self._linear = None
        self._moments = None

    def take(self, rows, fresh: np.ndarray | None = None) -> None:
        """Keep the filters ``rows`` in that order (repeats copy a filter's state, in its own form).

        ``fresh`` (bool per new row): filters whose model or switch state the
        caller changes next (:meth:`assign`); their transition is rebuilt.
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

    def assign(self, rows, models: Sequence[MotionModel], switch_states) -> None:
        """Give the filters ``rows`` new models and switch states (their transitions are rebuilt at the next step)."""
        rows = np.asarray(rows, dtype=np.intp).reshape(-1)
        for i, model in zip(rows, models):
            self.models[i] = model
        self.switch_states[rows] = switch_states
        self._dt[rows] = np.nan
        if self._linear:
            self._linear = all(m.linear for m in models)

    def add(self, rows, models: Sequence[MotionModel], switch_states) -> np.ndarray:
        """Append a copy of each filter ``rows[i]`` running ``models[i]`` from ``switch_states[i]`` (a switch
        hypothesised there), behind the filters of its run (in the order given); returns the new filters' rows."""
        rows = np.asarray(rows, dtype=np.intp).reshape(-1)
        F = len(self)
        source = np.concatenate([np.arange(F), rows])
        position = np.argsort(self.run[source], kind="stable")  # the bank is ordered run by run: copies go behind their run
        self.take(source[position], fresh=position >= F)
        added = np.flatnonzero(position >= F)
        which = position[added] - F
        states = np.broadcast_to(np.asarray(switch_states, dtype=float), (rows.size, len(self.layout)))
        self.assign(added, [models[i] for i in which], states[which])
        return added

    # ------------------------------------------------------------------ steps
    def transitions(self, dt) -> TransitionBank:
        """Every filter's transition over its own Δt ((F,) or one for all), each built at its switch state (rebuilt
        where Δt changed or the filter is new); the filters of a run with a nonlinear model are relinearized at
        their current means."""
        dt = np.broadcast_to(np.asarray(dt, dtype=float), (len(self),))
        if self._linear is None:
            self._linear = all(m.linear for m in {id(m): m for m in self.models}.values())
        stale = np.arange(len(self)) if self._F is None else np.flatnonzero(~(dt == self._dt))
        if stale.size:
            new = grouped_transitions([self.models[i] for i in stale], dt[stale], self.switch_states[stale])
            if self._F is None or stale.size == len(self):
                self._F, self._B, self._Q, self._root = np.array(new.F), np.array(new.B), np.array(new.Q), new.noise_root
            else:
                self._F[stale], self._B[stale], self._Q[stale] = new.F, new.B, new.Q
                self._root = _fill(self._root, stale, new.noise_root)
            self._dt = dt.copy()
            self._bank = None
        if self._bank is None:
            self._bank = TransitionBank(self._F, self._B, self._Q, self._root)
        if self._linear:
            return self._bank
        nonlinear = np.zeros(self.runs, dtype=bool)
        nonlinear[self.run[[not m.linear for m in self.models]]] = True
        rows = np.flatnonzero(nonlinear[self.run])
        at = TransitionBank.stack([self.models[i].transition(float(dt[i]), x) for i, x in zip(rows, self.means[rows])])
        if rows.size == len(self):
            return at
        F, B, Q = self._F.copy(), self._B.copy(), self._Q.copy()
        F[rows], B[rows], Q[rows] = at.F, at.B, at.Q
        return TransitionBank(F, B, Q, _fill(None if self._root is None else self._root.copy(), rows, at.noise_root))

    def step(self, dt, z) -> BankStep:
        """Predict every filter over its run's Δt (``dt`` (R,) or one for all; None: update only), then update it
        with its run's row of ``z`` (R, Σm) (any other form, e.g. a clutter scan, is handed to every filter)."""
        state = self.state
        if dt is not None:
            dt = np.broadcast_to(np.asarray(dt, dtype=float), (self.runs,))
            state = self.estimator.predict(state, self.transitions(dt[self.run]))
        if isinstance(z, np.ndarray) and z.ndim == 2:
            missing = np.isnan(z)
            if (missing != missing[:1]).any():
                return self._grouped(state, z, missing)
            z = z[self.run]
        self.state, innovation = self.estimator.update(state, z, self.sensors, self.layout)
        self._moments = None
        m = np.full(len(self), innovation.measurement_dim)
        return BankStep(np.asarray(innovation.loglik, dtype=float), np.asarray(innovation.nis, dtype=float), m, innovation)

    def _grouped(self, state, z: np.ndarray, missing: np.ndarray) -> BankStep:
        """The update of runs with different missing components, one update per missing pattern."""
        _, group = np.unique(missing, axis=0, return_inverse=True)
        group = group.reshape(-1)[self.run]
        F = len(self)
        loglik, nis, m = np.zeros(F), np.zeros(F), np.zeros(F, dtype=int)
        parts, order = [], []
        for g in np.unique(group):
            rows = np.flatnonzero(group == g)
            part, innovation = self.estimator.update(self.estimator.take(state, rows), z[self.run[rows]], self.sensors, self.layout)
            parts.append(part)
            order.append(rows)
            loglik[rows], nis[rows], m[rows] = innovation.loglik, innovation.nis, innovation.measurement_dim
        order = np.concatenate(order)
        inverse = np.empty_like(order)
        inverse[order] = np.arange(order.size)
        self.state = self.estimator.take(self.estimator.concatenate(parts), inverse)
        self._moments = None
        return BankStep(loglik, nis, m)


def _fill(root: np.ndarray | None, rows: np.ndarray, new: np.ndarray | None) -> np.ndarray | None:
    """``root`` with ``rows`` replaced by ``new`` (None when either is missing or their shapes differ)."""
    if root is None or new is None or new.shape[1:] != root.shape[1:]:
        return None
    root[rows] = new
    return root


def grouped_transitions(models: Sequence[MotionModel], dts, switch_states: np.ndarray) -> TransitionBank:
    """The transitions of S filters, filter i running ``models[i]`` over ``dts[i]`` (a float for all, or (S,))
    from switch state ``switch_states[i]`` (S, n), all in one layout: one
    :meth:`~hybridtrack.core.interfaces.MotionModel.transition_bank` call per (model, Δt) group of several
    filters (one ``TransitionBank.stack`` of the filters alone in theirs), scattered back into filter order.  Equal to ``TransitionBank.stack([models[i].transition(dts[i], switch_states[i]) …])``
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
    singles = [members[0] for _, members in groups.values() if len(members) == 1]  # one stack for all of them
    banks = []
    if singles:
        banks.append(
            (np.asarray(singles), TransitionBank.stack([models[i].transition(float(steps[i]), switch_states[i]) for i in singles]))
        )
    for (_, d), (model, members) in groups.items():
        if len(members) > 1:
            banks.append((np.asarray(members), model.transition_bank(d, switch_states[members])))
    for members, bank in banks:
        F[members], B[members], Q[members] = bank.F, bank.B, bank.Q
        roots.append(bank.noise_root)
        positions.append(members)
    root = None
    if all(r is not None for r in roots) and len({r.shape[1:] for r in roots}) == 1:
        root = np.zeros((S,) + roots[0].shape[1:])
        for members, r in zip(positions, roots):
            root[members] = r
    return TransitionBank(F, B, Q, root)
