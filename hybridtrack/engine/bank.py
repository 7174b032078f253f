"""One bank of filters: R runs × M_r filters in one estimator state, whose membership changes between steps.

The storage and the step under every bank of filters: the pipeline's fixed
bank, the changing banks of the adaptive algorithms (known switch, unknown
change, known modes) and the model-matched filters of the multiple-model
estimators (re-started at the mixed estimates every step); a single run is R = 1.  The filters are
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
(M, Σm), one row per filter; a bank of one run is given the run's row (Σm,),
shared by its filters), or hands every filter the same clutter scans.  Runs
whose measurements miss different components (NaN) at a step are updated in
groups of equal missing pattern (the contract needs one pattern per update).
Transitions are built for each filter's Δt and kept until its Δt, model or
switch state changes, so regular sampling builds each filter's transition
once, and a re-started bank whose transitions came out equal keeps the
previous bank object (the estimator's per-bank caches stay valid); a run whose
bank holds a nonlinear model relinearizes all its filters at their means
every step (EKF; MotionModel contract: F x̂ + B = f(x̂)).  :meth:`FilterBank.restart_step` is a start and a
step in one call of the estimator's optional compiled ``restart_step`` over every filter of every layout (the
multiple-model estimators' filters, re-started at every step), equal to them to rounding.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property
from typing import Any

import numpy as np

from hybridtrack.core.interfaces import Estimator, Innovation, MotionModel, Sensor, TransitionBank
from hybridtrack.engine.layouts import LayoutFill

#: the lists of models whose :meth:`FilterBank.restart_step` plans a bank keeps (a tracker alternates lists of many
#: lengths: its tracks' predictions and its gated pairs' updates; a plan is a few index arrays)
RESTART_PLANS = 64


class BankStep:
    """One step of a bank: ``updates``, the runs each update covered (ascending) with the estimator's own
    Innovation of their filters (one update for the whole bank, or one per missing pattern), and per filter
    (F,) ℓ ``loglik``, ``nis`` and ``m``, the number of components its update measured (0: prediction only);
    ``innovation`` the Innovation when one update covered the whole bank (e.g. the associations of a
    clutter-aware update), else None."""

    def __init__(self, updates: tuple[tuple[np.ndarray, Innovation], ...], size: int, **scores):
        self.updates, self.size = updates, size
        self.innovation = updates[0][1] if len(updates) == 1 else None
        self.__dict__.update(scores)  # loglik, nis, m of a grouped update (else read from the innovation on first use)

    @cached_property
    def loglik(self) -> np.ndarray:
        return np.asarray(self.innovation.loglik, dtype=float)

    @cached_property
    def nis(self) -> np.ndarray:
        return np.asarray(self.innovation.nis, dtype=float)

    @cached_property
    def m(self) -> np.ndarray:
        return np.full(self.size, self.innovation.measurement_dim)


class BankRestart:
    """The posteriors of :meth:`FilterBank.restart_step` in the bank's layout: ``means`` (F, n), ``covs`` (F, n, n)
    and per filter ℓ ``loglik``, ``nis`` and ``m`` (the components its update measured; 0: prediction only)."""

    __slots__ = ("means", "covs", "loglik", "nis", "m")

    def __init__(self, means, covs, loglik, nis, m):
        self.means, self.covs, self.loglik, self.nis, self.m = means, covs, loglik, nis, m


class LayoutBank:
    """Filters of R runs of one state layout in one estimator state, ordered run by run: each filter's run, model and
    switch state (a :class:`FilterBank` holds one per layout).

    ``run`` (F,) is each filter's run index; :meth:`start` / :meth:`set` create
    the bank, :meth:`take` changes membership (rows in the new order, repeats
    copy a filter), :meth:`assign` gives filters new models; :meth:`step` predicts every filter
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
        self._runs = np.arange(1)
        self._dt = np.zeros(0)  # Δt each filter's cached transition was built for (NaN: none)
        self._shared_dt: float | None = None  # the one Δt of every cached transition of a linear bank, if one
        self._F = self._B = self._Q = self._root = None
        self._bank: TransitionBank | None = None  # the same object while nothing changes (estimators cache per bank)
        self._last: TransitionBank | None = None  # the bank object before the last set (kept if equal)
        self._linear: bool | None = None  # every model linear (None: not known yet)
        self._forget_moments()  # x, P as the estimator gives them, ½(P + Pᵀ)

    def __len__(self) -> int:
        return len(self.models)

    # ------------------------------------------------------------------ reading
    @property
    def means(self) -> np.ndarray:
        """x (F, n) of every filter."""
        if self._mean is None:
            self._mean = np.asarray(self.estimator.mean(self.state), dtype=float)
        return self._mean

    @property
    def raw_covs(self) -> np.ndarray:
        """P (F, n, n) of every filter as the estimator gives it."""
        if self._cov is None:
            self._cov = np.asarray(self.estimator.covariance(self.state), dtype=float)
        return self._cov

    @property
    def covs(self) -> np.ndarray:
        """P (F, n, n) of every filter, symmetrized ½(P + Pᵀ)."""
        if self._sym is None:
            self._sym = 0.5 * (self.raw_covs + np.swapaxes(self.raw_covs, -1, -2))
        return self._sym

    def _forget_moments(self) -> None:
        self._mean = self._cov = self._sym = None

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
        self._runs = np.arange(self.runs)
        self._dt, self._shared_dt = np.full(F, np.nan), None
        self._F = self._B = self._Q = self._root = None
        self._last, self._bank = (self._last if self._bank is None else self._bank), None
        self._linear = None
        self._forget_moments()

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
            self._dt, self._shared_dt = np.where(fresh, np.nan, self._dt), None
        self._bank = None
        if self._F is not None:
            self._F, self._B, self._Q = self._F[rows], self._B[rows], self._Q[rows]
            self._root = None if self._root is None else self._root[rows]
        self._mean, self._cov, self._sym = (None if a is None else a[rows] for a in (self._mean, self._cov, self._sym))

    def assign(self, rows, models: Sequence[MotionModel], switch_states) -> None:
        """Give the filters ``rows`` new models and switch states (their transitions are rebuilt at the next step)."""
        rows = np.asarray(rows, dtype=np.intp).reshape(-1)
        for i, model in zip(rows, models):
            self.models[i] = model
        self.switch_states[rows] = switch_states
        self._dt[rows], self._shared_dt = np.nan, None
        if self._linear:
            self._linear = all(m.linear for m in models)

    # ------------------------------------------------------------------ steps
    def transitions(self, dt) -> TransitionBank:
        """Every filter's transition over its own Δt ((F,) or one for all), each built at its switch state (rebuilt
        where Δt changed or the filter is new); the filters of a run with a nonlinear model are relinearized at
        their current means — or, for an estimator that ``accepts_nonlinear``, wherever it asks: the linearizing
        callable x (F, n) → TransitionBank of the EKF contract, which the EKF calls at the means (the same bank)
        and a sigma-point filter at each of its points."""
        if dt.__class__ is float and dt == self._shared_dt and self._bank is not None:
            return self._bank  # the common step: nothing changed
        shared = float(dt) if np.ndim(dt) == 0 else None
        dt = np.broadcast_to(np.asarray(dt, dtype=float), (len(self),))
        if self._linear is None:
            self._linear = all(m.linear for m in {id(m): m for m in self.models}.values())
        rows = np.zeros(0, dtype=np.intp)
        if not self._linear:
            nonlinear = np.zeros(self.runs, dtype=bool)
            nonlinear[self.run[[not m.linear for m in self.models]]] = True
            rows = np.flatnonzero(nonlinear[self.run])
            if rows.size == len(self):
                return self._relinearized(rows, dt, None)
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
            last = self._last
            if last is not None and all(np.array_equal(getattr(last, f), a) for f, a in (("F", self._F), ("B", self._B), ("Q", self._Q))):
                self._bank = last  # equal transitions: the estimator's caches for this object still hold
            else:
                self._bank = TransitionBank(self._F, self._B, self._Q, self._root)
        if not rows.size:
            self._shared_dt = shared
            return self._bank
        return self._relinearized(rows, dt, self._bank)

    def _relinearized(self, rows: np.ndarray, dt: np.ndarray, base: TransitionBank | None):
        """The bank with the filters ``rows`` linearized at x[rows] (the others as in ``base``; None: rows are
        all): the callable x → TransitionBank for an estimator that ``accepts_nonlinear``, else that bank at the
        current means.  x is (F, n), one point per filter, or (k F, n), k points per filter in filter order (a
        particle filter's particles): the bank then has k rows per filter."""
        filters = len(self)

        def at(x: np.ndarray) -> TransitionBank:
            x = np.asarray(x, dtype=float)
            k, rest = divmod(x.shape[0], filters)
            if rest or not k:
                raise ValueError(
                    f"x: expected points for each of the {filters} filters of the bank (k·{filters} rows), got shape {x.shape}"
                )
            points = (rows[:, None] * k + np.arange(k)).reshape(-1)
            groups: dict = {}
            for i, p in enumerate(points):
                groups.setdefault(id(self.models[p // k]), []).append(i)
            parts = []
            for members in map(np.asarray, groups.values()):
                at_points, model = points[members], self.models[points[members[0]] // k]
                parts.append((members, model.transition_bank(dt[at_points // k], x[at_points])))
            new = _scattered(parts, points.size, x.shape[1])
            if base is None:
                return new
            F, B, Q = (np.repeat(a, k, axis=0) for a in (base.F, base.B, base.Q))
            F[points], B[points], Q[points] = new.F, new.B, new.Q
            root = None if base.noise_root is None else np.repeat(base.noise_root, k, axis=0)
            return TransitionBank(F, B, Q, _fill(root, points, new.noise_root))

        return at if self.estimator.accepts_nonlinear else at(self.means)

    def step(self, dt, z) -> BankStep:
        """Predict every filter over its run's Δt (``dt`` (R,) or one for all; None: update only), then update it
        with its run's row of ``z`` (R, Σm) (any other form, e.g. a clutter scan, is handed to every filter)."""
        state = self.state
        if dt is not None:
            if not isinstance(dt, np.ndarray):
                dt = float(dt)
            else:
                dt = dt.take(self.run) if dt.size > 1 else dt.item()
            state = self.estimator.predict(state, self.transitions(dt))
        if isinstance(z, np.ndarray) and z.ndim == 2:
            if z.shape[0] > 1:
                missing = np.isnan(z)
                if (missing != missing[:1]).any():
                    return self._grouped(state, z, missing)
            z = z[0] if self.runs == 1 else z.take(self.run, axis=0)  # take: ten times faster than z[run] here
        self.state, innovation = self.estimator.update(state, z, self.sensors, self.layout)
        self._mean = self._cov = self._sym = None
        return BankStep(((self._runs, innovation),), len(self.models))

    def _grouped(self, state, z: np.ndarray, missing: np.ndarray) -> BankStep:
        """The update of runs with different missing components, one update per missing pattern."""
        _, group = np.unique(missing, axis=0, return_inverse=True)
        group = group.reshape(-1)
        F = len(self)
        loglik, nis, m = np.zeros(F), np.zeros(F), np.zeros(F, dtype=int)
        parts, order, updates = [], [], []
        for g in np.unique(group[self.run]):
            rows = np.flatnonzero(group[self.run] == g)
            part, innovation = self.estimator.update(self.estimator.take(state, rows), z[self.run[rows]], self.sensors, self.layout)
            parts.append(part)
            order.append(rows)
            updates.append((np.unique(self.run[rows]), innovation))
            loglik[rows], nis[rows], m[rows] = innovation.loglik, innovation.nis, innovation.measurement_dim
        self.state = self.estimator.take(self.estimator.concatenate(parts), np.argsort(np.concatenate(order)))
        self._forget_moments()
        return BankStep(tuple(updates), F, loglik=loglik, nis=nis, m=m)


class FilterBank:
    """Filters of R runs in one bank, ordered run by run, their models of any state layouts: one :class:`LayoutBank`
    per layout, the bank read and written in its ``layout`` (the union of the models' layouts).

    A filter keeps its estimate in its model's layout; :attr:`means` and
    :attr:`covs` give every filter in the bank's layout, each component its
    model lacks at ``missing_mean`` with variance ``missing_variance``,
    uncorrelated (:class:`~hybridtrack.engine.layouts.LayoutFill`), and
    :meth:`start` gives each filter the marginal of its start on its model's
    components.  A filter :meth:`assign` gives a model of another layout moves
    to that layout's group, restarted from its estimate in the bank's layout.
    A step steps every layout's group (one ``predict``/``update`` per layout) and
    returns the scores in filter order.  A bank whose filters all run models of
    its own layout is its one :class:`LayoutBank`: every call is forwarded.
    """

    def __init__(self, estimator: Estimator, layout: Sequence[str], sensors: Sequence[Sensor], *, missing_mean=0.0, missing_variance=1.0):
        self.estimator, self.layout, self.sensors = estimator, tuple(layout), sensors
        self.fill = LayoutFill(self.layout, missing_mean, missing_variance)
        self.groups: dict[tuple[str, ...], LayoutBank] = {}
        self.models: list[MotionModel] = []
        self.run = np.zeros(0, dtype=int)
        self.runs = 1
        self._group = np.zeros(0, dtype=np.intp)  # each filter's group: index into self.groups
        self._only: LayoutBank | None = None  # the one group, when every filter runs a model of the bank's layout
        self._positions: dict[tuple[str, ...], np.ndarray] = {}  # a group's components in the bank's layout
        self._moments: dict = {}
        self._restart_plans: dict = {}  # model ids -> (models, the grouping of restart_step)
        self._sensor_fits: dict[tuple[str, ...], bool] = {}  # layout -> every sensor measures its components

    def __len__(self) -> int:
        return len(self.models)

    def _index(self, models: Sequence[MotionModel]) -> np.ndarray:
        """Each model's group (the group of its layout, created on first sight), looked up once per distinct model."""
        ids = np.fromiter(map(id, models), dtype=np.int64, count=len(models))
        _, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
        groups = np.empty(first.size, dtype=np.intp)
        for u, i in enumerate(first):
            layout = tuple(models[i].layout)
            if layout not in self.groups:
                self._positions[layout] = self.fill.positions(layout, f"model {models[i].name!r}")
                self.groups[layout] = LayoutBank(self.estimator, layout, self.sensors)
            groups[u] = list(self.groups).index(layout)
        return groups[inverse.reshape(-1)]

    def _members(self):
        """(group, its filters' rows in the bank, its components' positions in the bank's layout) per non-empty group."""
        for g, (layout, bank) in enumerate(self.groups.items()):
            rows = np.flatnonzero(self._group == g)
            if rows.size:
                yield bank, rows, self._positions[layout]

    def _rank(self) -> np.ndarray:
        """Each filter's row in its group (a group holds its filters in bank order)."""
        rank = np.empty(len(self), dtype=np.intp)
        for _, rows, _ in self._members():
            rank[rows] = np.arange(rows.size)
        return rank

    def _changed(self) -> None:
        self._moments = {}
        banks = list(self.groups.values())
        only = banks[self._group[0]] if self._group.size and (self._group == self._group[0]).all() else None
        self._only = only if only is not None and only.layout == self.layout else None
        if self._only is not None:
            self.models, self.run = self._only.models, self._only.run

    def _clear(self, bank: LayoutBank) -> None:
        bank.set(None, [], np.zeros((0, len(bank.layout))), np.zeros(0, dtype=int))

    # ------------------------------------------------------------------ reading
    def _in_layout(self, which: str) -> np.ndarray:
        """``means`` or ``switch_states`` of every group in the bank's layout (what a model lacks at the missing mean)."""
        out = np.broadcast_to(self.fill.mean, (len(self), len(self.layout))).copy()
        for bank, rows, pos in self._members():
            out[rows[:, None], pos] = getattr(bank, which)
        return out

    @property
    def means(self) -> np.ndarray:
        """x (F, n) of every filter in the bank's layout."""
        if self._only is not None:
            return self._only.means
        if "means" not in self._moments:
            self._moments["means"] = self._in_layout("means")
        return self._moments["means"]

    @property
    def switch_states(self) -> np.ndarray:
        """The switch state (F, n) each filter's transition is fixed at, in the bank's layout."""
        return self._only.switch_states if self._only is not None else self._in_layout("switch_states")

    def _expanded_covs(self, which: str) -> np.ndarray:
        if self._only is not None:
            return getattr(self._only, which)
        if which not in self._moments:
            n = len(self.layout)
            P = np.empty((len(self), n, n))
            for bank, rows, pos in self._members():
                P[rows] = self.fill.expand(bank.means, getattr(bank, which), pos)[1]
            self._moments[which] = P
        return self._moments[which]

    @property
    def raw_covs(self) -> np.ndarray:
        """P (F, n, n) of every filter as the estimator gives it, in the bank's layout."""
        return self._expanded_covs("raw_covs")

    @property
    def covs(self) -> np.ndarray:
        """P (F, n, n) of every filter, symmetrized ½(P + Pᵀ), in the bank's layout."""
        return self._expanded_covs("covs")

    @property
    def state(self):
        """The estimator's state of a bank of one layout (the bank's own)."""
        if self._only is None:
            raise ValueError(
                f"state: the bank holds filters of layouts {[b.layout for b, _, _ in self._members()]}, not one estimator state"
            )
        return self._only.state

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
        if self._only is not None:
            return self._only.node_scores()
        parts = [(bank.node_scores(), rows) for bank, rows, _ in self._members()]
        if not parts or any(scores is None for scores, _ in parts):
            return None
        out = np.empty((2, parts[0][0][0].shape[0], len(self)))
        for (loglik, nis), rows in parts:
            out[0][:, rows], out[1][:, rows] = loglik, nis
        return out[0], out[1]

    def transitions(self, dt) -> TransitionBank:
        """Every filter's transition over ``dt`` (:meth:`LayoutBank.transitions`; a bank of one layout)."""
        if self._only is None:
            raise ValueError("transitions: the filters of a bank of several layouts have transitions of different sizes")
        return self._only.transitions(dt)

    # ------------------------------------------------------------------ membership
    def start(self, means, covs, models: Sequence[MotionModel], switch_states, run=None) -> None:
        """A new bank of one filter per model starting at N(means, covs) ((F, n), (F, n, n) in the bank's layout; one
        (n,), (n, n) for all), its transition fixed at ``switch_states`` ((F, n) or (n,)); ``run`` (F,) default all 0."""
        F = len(models)
        self.models = list(models)
        self.run = np.zeros(F, dtype=int) if run is None else np.asarray(run, dtype=int)
        self.runs = int(self.run.max()) + 1 if F else 1
        self._group = self._index(self.models)
        members = list(self._members())
        if len(members) == 1 and members[0][0].layout == self.layout:
            members[0][0].start(means, covs, self.models, switch_states, self.run)
        else:
            n = len(self.layout)
            means = np.broadcast_to(np.asarray(means, dtype=float), (F, n))
            covs = np.broadcast_to(np.asarray(covs, dtype=float), (F, n, n))
            switch_states = np.broadcast_to(np.asarray(switch_states, dtype=float), (F, n))
            for bank, rows, pos in members:
                models = [self.models[i] for i in rows]
                bank.start(means[rows][:, pos], covs[rows][:, pos[:, None], pos], models, switch_states[rows][:, pos], self.run[rows])
        for bank in self.groups.values():
            if not any(bank is b for b, _, _ in members):
                self._clear(bank)
        self._changed()

    def set(self, state, models: Sequence[MotionModel], switch_states, run=None) -> None:
        """Replace the whole bank by the estimator's ``state`` of filters running ``models`` of the bank's layout."""
        wrong = [m.name for m in models if tuple(m.layout) != self.layout]
        if wrong:
            raise ValueError(f"models: {wrong} are not of the bank's layout {self.layout}; one estimator state holds one layout")
        self._group = self._index(models)
        for bank in self.groups.values():
            if bank.layout != self.layout:
                self._clear(bank)
        self.groups[self.layout].set(state, models, switch_states, run)
        self.runs = self.groups[self.layout].runs
        self._changed()

    def take(self, rows, fresh: np.ndarray | None = None) -> None:
        """Keep the filters ``rows`` in that order (repeats copy a filter's state, in its own form); ``fresh`` (bool
        per new row): filters whose model or switch state the caller changes next (:meth:`assign`)."""
        if self._only is not None:
            self._only.take(rows, fresh)
            self._group = np.full(len(self._only), self._group[0], dtype=np.intp)
            self.models, self.run = self._only.models, self._only.run
            return self._changed()
        rows = np.asarray(rows, dtype=np.intp).reshape(-1)
        group, rank = self._group[rows], self._rank()
        for g, bank in enumerate(self.groups.values()):
            kept = np.flatnonzero(group == g)
            if kept.size:
                bank.take(rank[rows[kept]], None if fresh is None else np.asarray(fresh)[kept])
            elif len(bank):
                self._clear(bank)
        self._group, self.models, self.run = group, [self.models[i] for i in rows], self.run[rows]
        self._changed()

    def assign(self, rows, models: Sequence[MotionModel], switch_states) -> None:
        """Give the filters ``rows`` new models and switch states (in the bank's layout; their transitions are rebuilt
        at the next step); a filter given a model of another layout restarts there from its estimate."""
        rows = np.asarray(rows, dtype=np.intp).reshape(-1)
        states = np.broadcast_to(np.asarray(switch_states, dtype=float), (rows.size, len(self.layout)))
        group = self._index(models)
        if self._only is not None and (group == self._group[0]).all():
            self._only.assign(rows, models, states)
            return self._changed()
        moved = group != self._group[rows]
        self.models = list(self.models)
        x, P, rank = self.means[rows[moved]], self.covs[rows[moved]], self._rank()
        for g, (layout, bank) in enumerate(self.groups.items()):
            pos = self._positions[layout]
            same = np.flatnonzero(~moved & (group == g))
            if same.size:
                bank.assign(rank[rows[same]], [models[i] for i in same], states[same][:, pos])
        if moved.any():
            self._move(rows[moved], [m for m, flag in zip(models, moved) if flag], states[moved], x, P, rank)
        for i, model in zip(rows, models):
            self.models[i] = model
        self._changed()

    def _move(self, rows, models, switch_states, x, P, rank) -> None:
        """Filters ``rows`` to the groups of ``models`` (other layouts), restarted at N(x, P) (bank's layout)."""
        old = self._group.copy()
        self._group[rows] = self._index(models)
        for g in np.unique(np.concatenate([old[rows], self._group[rows]])):
            layout, bank = list(self.groups.items())[g]
            pos = self._positions[layout]
            members = np.flatnonzero(self._group == g)
            arriving = np.isin(members, rows)
            kept = members[~arriving]
            if kept.size:
                bank.take(rank[kept])
            if not arriving.any():
                if not kept.size:
                    self._clear(bank)
                continue
            j = np.array([np.flatnonzero(rows == i)[0] for i in members[arriving]])
            new = self.estimator.initialize(x[j][:, pos], P[j][:, pos[:, None], pos])
            state = new if not kept.size else self.estimator.concatenate([bank.state, new])
            order = np.concatenate([kept, members[arriving]])
            filter_models = [self.models[i] for i in kept] + [models[i] for i in j]
            switch = np.concatenate([bank.switch_states[: kept.size], switch_states[j][:, pos]])
            bank.set(state, filter_models, switch, self.run[order])
            bank.take(np.argsort(order, kind="stable"))

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
    def restart_step(self, means, covs, models: Sequence[MotionModel], switch_states, run, dt, z) -> BankRestart | None:
        """The posteriors of :meth:`start` at N(means, covs) ((F, n), (F, n, n), the bank's layout) followed by
        :meth:`step` over ``dt`` with ``z`` (R, Σm), in one call of the estimator's optional compiled ``restart_step``
        (``KalmanFilter.restart_step``) over every filter at once, whatever its layout and missing components — the
        model-matched filters of a multiple-model estimator, re-started at every step.  The bank itself is not
        changed.  None when the estimator has no ``restart_step``, cannot take filters of smaller layouts embedded
        in the bank's (``restart_embeds_layouts``) and some model lacks components, a sensor does not measure a
        model's own components, or the estimator declines the step: the caller then takes :meth:`start` and
        :meth:`step` (which raise their errors).

        Filter i runs ``models[i]`` over its run's Δt, its transition built as :meth:`LayoutBank.transitions` builds
        it (one ``transition_bank`` call per model over its filters' own Δt — entries equal to the stacked
        ``transition``, the models' contract — at the switch states, or at the means for the filters of a run with a
        nonlinear model) in its model's layout and embedded in the bank's: F, B and Q map the components it lacks to
        zero, so its prediction, update and scores are its layout's (the estimator's arithmetic adds exact zeros
        only) and those components come out at the fill (:class:`~hybridtrack.engine.layouts.LayoutFill`), as
        :attr:`means` and :attr:`covs` read a filter of a smaller layout.  The grouping of a list of models (gather
        and scatter indices) is kept for the next calls with the same models (by identity)."""
        lane = getattr(self.estimator, "restart_step", None)
        if lane is None or type(z) is not np.ndarray or z.ndim != 2:
            return None
        F, n = len(models), len(self.layout)
        means, covs = np.asarray(means, dtype=float), np.asarray(covs, dtype=float)
        at = means if switch_states is means else np.asarray(switch_states, dtype=float)
        run = np.zeros(F, dtype=int) if run is None else np.asarray(run, dtype=int)
        if means.shape != (F, n) or covs.shape != (F, n, n) or at.shape != (F, n) or run.shape != (F,) or not F or z.shape[0] <= run.max():
            return None
        plan = self._restart_plan(models)
        if plan is None:
            return None
        groups, lacking_x, lacking_P, lacking_var = plan
        if dt is None:  # update only: the identity on each filter's own components (x⁻ = x⁺, P⁻ = P⁺ exactly)
            transitions = TransitionBank(np.zeros((F, n, n)), np.zeros((F, n)), np.zeros((F, n, n)))
            transitions.F.reshape(F, n * n)[:, :: n + 1] = 1.0
            transitions.F.reshape(-1)[lacking_P] = 0.0
        else:
            transitions = self._restart_transitions(groups, dt, means, at, run)
        result = lane(means, covs, transitions, z.take(run, axis=0), self.sensors, self.layout)
        if result is None:
            return None
        state, loglik, nis, m = result
        x, P = np.asarray(self.estimator.mean(state), dtype=float), np.asarray(self.estimator.covariance(state), dtype=float)
        if lacking_x.size:  # the components a filter's model lacks: at the fill (their covariances are zero already)
            x.reshape(-1)[lacking_x] = self.fill.mean.take(lacking_var)
            P.reshape(-1)[lacking_P] = self.fill.variance.take(lacking_var)
        return BankRestart(x, P, loglik, nis, m)

    def _restart_transitions(self, groups, dt, means: np.ndarray, at: np.ndarray, run: np.ndarray) -> TransitionBank:
        """The transitions of :meth:`restart_step` ((model, rows, indices) per distinct model of its plan): each
        model's ``transition_bank`` over its filters' Δt at ``at`` (the switch states; the means for the runs holding
        a nonlinear model), embedded in the bank's layout."""
        F, n = means.shape
        if isinstance(dt, np.ndarray):
            dt = dt.take(run) if dt.size > 1 else float(dt.item())
        else:
            dt = float(dt)
        if any(not model.linear for model, *_ in groups):  # the runs holding a nonlinear model are relinearized at the means
            nonlinear = np.zeros(int(run.max()) + 1, dtype=bool)
            for model, rows, _ in groups:
                if not model.linear:
                    nonlinear[run[rows]] = True
            at = means if nonlinear[run].all() else np.where(nonlinear[run][:, None], means, at)
        if len(groups) == 1 and groups[0][2] is None:  # one model of the bank's layout: its bank as it comes
            return groups[0][0].transition_bank(dt, at)
        Fu, Bu, Qu = np.zeros((F, n, n)), np.zeros((F, n)), np.zeros((F, n, n))
        flat_at, flat_F, flat_B, flat_Q = at.reshape(-1), Fu.reshape(-1), Bu.reshape(-1), Qu.reshape(-1)
        for model, rows, (at_x, at_P) in groups:
            bank = model.transition_bank(dt if type(dt) is float else dt.take(rows), flat_at.take(at_x).reshape(rows.size, -1))
            flat_F[at_P], flat_B[at_x], flat_Q[at_P] = bank.F.reshape(-1), bank.B.reshape(-1), bank.Q.reshape(-1)
        return TransitionBank(Fu, Bu, Qu)

    def _restart_plan(self, models: Sequence[MotionModel]):
        """([(model, its filters' rows, (gather/scatter indices of its components in the flattened (F, n) and (F, n, n)
        arrays) or None for a model of the bank's layout)], the flattened indices of the components the filters
        lack in (F, n) and of their variances in (F, n, n), their union-layout components) for a list of models, or
        None when :meth:`restart_step` cannot take them; kept for the last :data:`RESTART_PLANS` lists (by the models' identities)."""
        key = tuple(map(id, models))
        cached = self._restart_plans.get(key)
        if cached is not None:
            return cached[1]
        n = len(self.layout)
        index: dict = {}
        for i, model in enumerate(models):
            index.setdefault(id(model), (model, []))[1].append(i)
        groups, lacking = [], []
        plan = ()
        for model, rows in index.values():
            rows = np.asarray(rows, dtype=np.intp)
            try:
                pos = self.fill.positions(model.layout, f"model {model.name!r}")
            except ValueError:
                plan = None
                break
            if pos.size == n and (pos == np.arange(n)).all():
                groups.append((model, rows, None if len(index) == 1 else (self._flat(rows, pos))))
                continue
            if not getattr(self.estimator, "restart_embeds_layouts", False) or not self._sensors_fit(tuple(model.layout)):
                plan = None
                break
            groups.append((model, rows, self._flat(rows, pos)))
            lack = self.fill.lacking(pos)
            lacking.append((rows, lack))
        if plan is not None:
            rows_l = [np.repeat(rows, lack.size) for rows, lack in lacking] or [np.zeros(0, dtype=np.intp)]
            comps = [np.tile(lack, rows.size) for rows, lack in lacking] or [np.zeros(0, dtype=np.intp)]
            rows_l, comps = np.concatenate(rows_l), np.concatenate(comps)
            plan = (groups, rows_l * n + comps, rows_l * n * n + comps * (n + 1), comps)
        if len(self._restart_plans) >= RESTART_PLANS:
            self._restart_plans.pop(next(iter(self._restart_plans)))
        self._restart_plans[key] = (list(models), plan)  # the models kept: their ids stay theirs
        return plan

    def _flat(self, rows: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The flattened indices of the components ``pos`` of the filters ``rows`` in (F, n) and of their entries in (F, n, n)."""
        n = len(self.layout)
        at_x = (rows[:, None] * n + pos[None, :]).reshape(-1)
        at_P = (rows[:, None, None] * n * n + pos[None, :, None] * n + pos[None, None, :]).reshape(-1)
        return at_x, at_P

    def _sensors_fit(self, layout: tuple[str, ...]) -> bool:
        """Whether every sensor measures (and, for a state-dependent R, reads) components ``layout`` has: its Jacobian
        and its state noise at a zero state of that layout raise nothing (kept per layout)."""
        fits = self._sensor_fits.get(layout)
        if fits is None:
            zero = np.zeros((1, len(layout)))
            try:
                for sensor in self.sensors:
                    sensor.jacobian(zero, layout)
                    if sensor.noise_depends_on_state:
                        sensor.state_noise(zero, layout)
                fits = True
            except Exception:  # the reference steps raise it
                fits = False
            self._sensor_fits[layout] = fits
        return fits

    def step(self, dt, z) -> BankStep:
        """Predict every filter over its run's Δt and update it with its run's row of ``z``
        (:meth:`LayoutBank.step`), one step per layout; the scores in filter order."""
        if self._only is not None:
            return self._only.step(dt, z)
        F = len(self)
        loglik, nis, m = np.zeros(F), np.zeros(F), np.zeros(F, dtype=int)
        updates: list = []
        for bank, rows, _ in self._members():
            scores = bank.step(dt, z)
            loglik[rows], nis[rows], m[rows] = scores.loglik, scores.nis, scores.m
            updates += scores.updates
        self._moments = {}
        return BankStep(tuple(updates), F, loglik=loglik, nis=nis, m=m)


def _fill(root: np.ndarray | None, rows: np.ndarray, new: np.ndarray | None) -> np.ndarray | None:
    """``root`` with ``rows`` replaced by ``new`` (None when either is missing or their shapes differ)."""
    if root is None or new is None or new.shape[1:] != root.shape[1:]:
        return None
    root[rows] = new
    return root


def grouped_transitions(models: Sequence[MotionModel], dts, switch_states: np.ndarray) -> TransitionBank:
    """The transitions of S filters, filter i running ``models[i]`` over ``dts[i]`` (a float for all, or (S,))
    from switch state ``switch_states[i]`` (S, n), all in one layout: one
    :meth:`~hybridtrack.core.interfaces.MotionModel.transition_bank` call per model, over its filters' own Δt
    (runs of irregular time stamps step together), scattered back into filter order; a model's filters at one
    Δt and one switch state share one ``transition``.  Equal to
    ``TransitionBank.stack([models[i].transition(dts[i], switch_states[i]) …])`` entry by entry
    (``transition_bank`` must equal the stacked transitions; the contract kit checks), so F_i, B_i, Q_i are
    seed 000's eq. (3) transitions of each filter's mode.  The noise roots G·chol(Q) are kept when every
    model's bank has one of the same shape (else ``None``, as ``TransitionBank.stack`` gives for noise inputs of
    different sizes)."""
    switch_states = np.asarray(switch_states, dtype=float)
    S = len(models)
    if switch_states.ndim != 2 or switch_states.shape[0] != S:
        raise ValueError(f"switch_states: expected ({S}, n) for {S} filters, got shape {switch_states.shape}")
    steps = np.broadcast_to(np.asarray(dts, dtype=float), (S,))
    groups: dict = {}
    for i, model in enumerate(models):
        groups.setdefault(id(model), []).append(i)
    banks = []
    for members in map(np.asarray, groups.values()):
        model, first = models[members[0]], members[0]
        if (steps[members] == steps[first]).all() and (switch_states[members] == switch_states[first]).all():
            one = TransitionBank.stack([model.transition(float(steps[first]), switch_states[first])])
            banks.append((members, _taken(one, np.zeros(len(members), dtype=np.intp))))
        else:
            d = steps[members]
            banks.append((members, model.transition_bank(float(d[0]) if (d == d[0]).all() else d, switch_states[members])))
    return _scattered(banks, S, switch_states.shape[1])


def _taken(bank: TransitionBank, rows: np.ndarray) -> TransitionBank:
    """The bank of the filters ``rows`` of ``bank`` (repeats allowed)."""
    root = None if bank.noise_root is None else bank.noise_root[rows]
    return TransitionBank(bank.F[rows], bank.B[rows], bank.Q[rows], root)


def _scattered(banks: Sequence[tuple[np.ndarray, TransitionBank]], S: int, n: int) -> TransitionBank:
    """One bank of S filters from (filter indices, their bank) pairs; the noise roots kept when all have one of one shape."""
    F, B, Q = np.zeros((S, n, n)), np.zeros((S, n)), np.zeros((S, n, n))
    for members, bank in banks:
        F[members], B[members], Q[members] = bank.F, bank.B, bank.Q
    roots = [bank.noise_root for _, bank in banks]
    root = None
    if all(r is not None for r in roots) and len({r.shape[1:] for r in roots}) == 1:
        root = np.zeros((S,) + roots[0].shape[1:])
        for (members, _), r in zip(banks, roots):
            root[members] = r
    return TransitionBank(F, B, Q, root)
