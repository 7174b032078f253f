"""Hybrid trajectories from a schedule, and multisensor measurements of them (SPEC §1–2).

A schedule row (mode, steps, radius) runs the motion model registered as
``mode`` for ``steps`` steps of length τ:

    x_k = F_p x_{k-1} + B_p + G_p w_{k-1},  w ~ N(0, Q_p)   (seed 000, eq. 1)

or, with ``times`` (seconds t_0 < t_1 < … < t_K, any spacing, one per state)
in place of ``tau``, step k of length Δt_k = t_k − t_{k−1} with F_p, B_p, G_p,
Q_p built for that Δt_k (a schedule row still counts steps).

At each switch the new model ``enter``s the state (layout conversion,
augmentation on entering constant acceleration) and fixes its transition from
the state at the switching moment s (a turn's ω = |v_s|/r and centre).  With
``process_noise=False`` the trajectory is noise-free.

Randomness comes from ``numpy.random.Generator`` only; the same seed gives
identical arrays.  :func:`simulate` spawns independent streams for the
trajectory and the measurements from one seed.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence
from pathlib import Path

import attrs
import numpy as np

from hybridtrack.core.interfaces import MotionModel, Sensor, convert_layout
from hybridtrack.core.registry import Registry, registry_or_default
from hybridtrack.core.types import Gaussian
from hybridtrack.core.validation import as_float_array, check_covariance
from hybridtrack.engine.schedule import Schedule
from hybridtrack.sdk.linalg import psd_square_root
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import check_tau, check_times


@attrs.frozen(eq=False)
class Trajectory:
    """A simulated hybrid trajectory: states at steps 0..K.

    ``states`` (K+1, n) are in ``layout``, the union of the layouts of the
    schedule's modes (components a mode lacks are zero while it runs);
    ``segment`` (K+1,) is the index of the schedule row that produced each state
    (row 0 for the initial state); ``times`` = step · τ, or the times the
    trajectory was simulated at (then ``tau`` is None).
    """

    schedule: Schedule
    tau: float | None
    layout: tuple[str, ...]
    states: np.ndarray
    segment: np.ndarray
    sample_times: np.ndarray | None = None

    @property
    def steps(self) -> np.ndarray:
        return np.arange(self.states.shape[0])

    @property
    def times(self) -> np.ndarray:
        return self.steps * self.tau if self.sample_times is None else self.sample_times

    @property
    def modes(self) -> list[str]:
        """Mode name governing each step (the initial state counts as the first mode)."""
        return [self.schedule.segments[i].mode for i in self.segment]

    def states_in(self, layout: Sequence[str]) -> np.ndarray:
        """States converted to another layout (by component name; missing components are zero)."""
        return convert_layout(self.states, self.layout, layout)

    @property
    def positions(self) -> np.ndarray:
        return self.states_in(("x", "y"))

    def save_npz(self, path: str | Path, **extra: np.ndarray) -> None:
        """Write states, layout, steps, times, segment and the schedule rows (plus ``extra`` arrays);
        ``tau`` is NaN for a trajectory simulated at given times."""
        segments = self.schedule.segments
        np.savez(
            path,
            states=self.states,
            layout=np.array(self.layout),
            steps=self.steps,
            times=self.times,
            segment=self.segment,
            schedule_mode=np.array([s.mode for s in segments]),
            schedule_steps=np.array([s.steps for s in segments]),
            schedule_radius=np.array([np.nan if s.radius is None else s.radius for s in segments]),
            tau=np.nan if self.tau is None else self.tau,
            **extra,
        )


def takes_keyword(factory, name: str) -> bool:
    """Whether ``factory`` accepts the keyword argument ``name`` (True when its signature is unknown)."""
    try:
        parameters = inspect.signature(factory).parameters.values()
    except (TypeError, ValueError):
        return True
    return any((p.name == name and p.kind is not p.POSITIONAL_ONLY) or p.kind is p.VAR_KEYWORD for p in parameters)


def names_parameter(factory, name: str) -> bool:
    """Whether the signature of ``factory`` names the parameter ``name`` (False when it is unknown or only ``**kwargs``)."""
    try:
        return name in inspect.signature(factory).parameters
    except (TypeError, ValueError):
        return False


def build_models(
    schedule: Schedule, registry: Registry | None = None, noise_cov=None, *, noise_cov_where_taken: bool = False
) -> list[MotionModel]:
    """One motion model per schedule row, created from the registry by mode name.

    ``noise_cov`` (2×2 Q), when given, is passed to every model; with
    ``noise_cov_where_taken`` only to the models whose factory takes a
    ``noise_cov`` keyword (the others, e.g. ``ship_turn`` with its own
    ``sigma_velocity`` and ``sigma_rate``, keep their own process noise).
    A factory returning something that is not a MotionModel is a TypeError
    naming the plugin that registered it.  A row without a radius whose mode's
    factory names a ``radius`` parameter (the turns) is a ValueError naming the
    row and the key: the radius is the row's to give, never the model's default.
    """
    registry = registry_or_default(registry)
    models = []
    starts = schedule.switch_steps()
    for i, segment in enumerate(schedule.segments):
        parameters = segment.parameters()
        if segment.radius is None and names_parameter(registry.get("motion_model", segment.mode), "radius"):
            raise ValueError(
                f"schedule row {i} ({segment.mode}, {segment.steps} steps from step {starts[i]}): no radius; the {segment.mode!r}"
                f" mode turns at a radius the row gives (key 'radius', metres > 0), e.g. ({segment.mode!r}, {segment.steps}, 3.0)"
                f" or [[segment]] mode = {segment.mode!r}, steps = {segment.steps}, radius = 3.0"
            )
        if noise_cov is not None and (not noise_cov_where_taken or takes_keyword(registry.get("motion_model", segment.mode), "noise_cov")):
            parameters["noise_cov"] = noise_cov
        try:
            model = registry.create("motion_model", segment.mode, **parameters)
        except (TypeError, ValueError) as error:
            raise ValueError(f"schedule row {i} ({segment.mode}): {error}") from error
        models.append(registry.check("motion_model", segment.mode, model))
    return models


def _schedule_models(schedule: Schedule, models, registry, noise_cov) -> tuple[list[MotionModel], tuple[str, ...]]:
    """The models of the schedule's rows (``models``, or built from the registry) and the union of their layouts."""
    if noise_cov is not None:
        noise_cov = check_covariance(noise_cov, "noise_cov")
    models = list(models) if models is not None else build_models(schedule, registry, noise_cov)
    if len(models) != len(schedule.segments):
        raise ValueError(f"models: expected {len(schedule.segments)} models (one per schedule row), got {len(models)}")
    return models, tuple(dict.fromkeys(name for model in models for name in model.layout))


def _initial_state(x0):
    """``x0``, unless it is a prior (a Gaussian, a dict): then a TypeError naming it and saying what to pass."""
    if isinstance(x0, Gaussian) or isinstance(x0, Mapping):
        what = "a Gaussian" if isinstance(x0, Gaussian) else f"a dict with keys {sorted(map(str, x0))}"
        raise TypeError(
            f"x0: simulate starts from a state, an array (n,) in the first mode's layout (e.g. np.array([x, vx, y, vy])),"
            f" not from a prior; got {what}: pass its mean (x0=prior.mean), or a draw from it"
            " (np.random.default_rng(seed).multivariate_normal(prior.mean, prior.cov))"
        )
    return x0


def _sampling(tau, times, steps: int) -> tuple[float | None, np.ndarray | None]:
    """(τ, None) for regular sampling or (None, times (steps + 1,)) for given times; exactly one is given."""
    if times is None:
        if tau is None:
            raise ValueError("tau: give the sampling period tau or the times (seconds) of the states")
        return check_tau(tau), None
    if tau is not None:
        raise ValueError("tau: give either the sampling period tau or the times, not both")
    return None, check_times(times, "times", steps + 1)


def simulate_trajectory(
    schedule: Schedule,
    x0,
    tau: float | None = None,
    *,
    times=None,
    process_noise: bool = True,
    seed=None,
    noise_cov=None,
    registry: Registry | None = None,
    models: Sequence[MotionModel] | None = None,
    recorder=None,
) -> Trajectory:
    """:func:`simulate_trajectories` of one run, drawn from ``seed``; with a ``recorder`` the true path is logged
    under ``world/truth``."""
    options = dict(times=times, process_noise=process_noise, noise_cov=noise_cov, registry=registry, models=models)
    (trajectory,) = simulate_trajectories(schedule, x0, tau, seeds=[seed], **options)
    if recorder is not None:
        recorder.log_path("world/truth", trajectory.steps, trajectory.positions, trajectory.times)
        labels = [s.mode if s.radius is None else f"{s.mode}_r{s.radius:g}" for s in schedule.segments]
        recorder.log_modes("world/truth", trajectory.steps, trajectory.segment, labels, trajectory.times)
    return trajectory


def simulate_measurements(trajectory: Trajectory, sensors: Sequence[Sensor] | SensorNetwork, *, seed=None) -> dict[str, np.ndarray]:
    """Noisy measurements of every state (steps 0..K) by each sensor: name → (K+1, m)."""
    network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
    rng = np.random.default_rng(seed)
    return {sensor.name: sensor.simulate(trajectory.states, trajectory.layout, rng) for sensor in network.sensors}


def simulate(
    schedule: Schedule, x0, tau: float | None = None, sensors=None, *, times=None, seed=None, recorder=None, **options
) -> tuple[Trajectory, dict[str, np.ndarray]]:
    """Trajectory and measurements from one seed — an int, a ``SeedSequence`` or a ``Generator`` —
    with independent streams for the two (``spawn``).

    Sampling is ``tau`` (regular) or ``times`` (seconds, one per state, any
    spacing; see :func:`simulate_trajectories`).  With a ``recorder`` the truth
    is logged; the measurements are logged by what consumes them (the
    pipeline), or by :func:`hybridtrack.recording.log_measurements`.
    """
    if sensors is None:
        raise ValueError("sensors: required (a list of sensors or a SensorNetwork)")
    if isinstance(seed, np.random.Generator):
        trajectory_rng, measurement_rng = seed.spawn(2)
    else:
        trajectory_rng, measurement_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
    trajectory = simulate_trajectory(schedule, x0, tau, times=times, seed=trajectory_rng, recorder=recorder, **options)
    return trajectory, simulate_measurements(trajectory, sensors, seed=measurement_rng)


def simulate_trajectories(
    schedule: Schedule,
    x0,
    tau: float | None = None,
    *,
    seeds: Sequence,
    times=None,
    process_noise: bool = True,
    noise_cov=None,
    registry: Registry | None = None,
    models: Sequence[MotionModel] | None = None,
) -> list[Trajectory]:
    """R runs of ``schedule`` from ``x0`` (in the first mode's layout), one seed per run, with sampling period
    ``tau`` or at ``times`` (one per state: ``schedule.total_steps + 1``; module docstring).  ``models``
    overrides the registry lookup (one model per schedule row).

    Each run draws each segment's process noise w from its own stream, as one
    (steps, q) block, and the states of all runs are propagated together,
    x_k = F_r x_{k−1} + B_r + G_r L_r w_k (each run's transition fixed at its
    own switch state, SPEC §1; a nonlinear mode propagates each run's state by
    its own f), so a run's trajectory does not depend on the others.
    """
    tau, times = _sampling(tau, times, schedule.total_steps)
    models, layout = _schedule_models(schedule, models, registry, noise_cov)
    rngs = [np.random.default_rng(seed) for seed in seeds]
    if not rngs:
        raise ValueError("seeds: expected one seed per run, got none")
    R, K = len(rngs), schedule.total_steps
    intervals = np.full(K, tau) if times is None else np.diff(times)
    x = np.repeat(as_float_array(_initial_state(x0), "x0", (models[0].state_dim,))[None], R, axis=0)
    states = np.zeros((R, K + 1, len(layout)))
    states[:, 0] = convert_layout(x, models[0].layout, layout)
    segment_index = np.zeros(K + 1, dtype=int)
    current_layout, k = models[0].layout, 0
    for i, (segment, model) in enumerate(zip(schedule.segments, models)):
        x = np.stack([model.enter(row, current_layout, {"acceleration": segment.acceleration}) for row in x])
        current_layout, switch_states, built = model.layout, x.copy(), None
        block = np.empty((R, segment.steps, model.state_dim))
        for j in range(segment.steps):
            dt = float(intervals[k + j])
            if dt != built:  # regular sampling: one transition per segment; given times: one per step
                transitions, built = [model.transition(dt, row) for row in switch_states], dt
                F, B = np.stack([t.F for t in transitions]), np.stack([t.B for t in transitions])
                GL = np.stack([t.G @ psd_square_root(t.Q) for t in transitions])
            if process_noise and j == 0:  # the segment's noise, each run from its own stream
                noise = np.stack([rng.standard_normal((segment.steps, GL.shape[2])) for rng in rngs])  # (R, steps, q)
            if model.linear:
                x = np.einsum("rij,rj->ri", F, x) + B
            else:
                x = np.stack([model.propagate(row, dt, s) for row, s in zip(x, switch_states)])
            if process_noise:
                x = x + np.einsum("rij,rj->ri", GL, noise[:, j])
            block[:, j] = x
        if not np.all(np.isfinite(block)):
            raise FloatingPointError(f"schedule row {i} ({segment.mode}): state became non-finite")
        states[:, k + 1 : k + segment.steps + 1] = convert_layout(block, current_layout, layout)
        segment_index[k + 1 : k + segment.steps + 1] = i
        k += segment.steps
    return [Trajectory(schedule, tau, layout, states[r], segment_index.copy(), times) for r in range(R)]
