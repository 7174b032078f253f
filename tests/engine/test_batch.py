"""R runs together equal R runs alone: ONE parametrized check, :func:`test_runs_together_equal_runs_alone`, over
every registered estimator and detector (through Pipeline.run_batch) and algorithm (its run_batch, through
:func:`hybridtrack.testing.check_algorithm_batch`), and over the named variants of the pipeline and of the
algorithms: Algorithm 1 (known switch) × estimators × follow/inflation, its joint switch estimate, per-run
estimators (decentralized, particle), Algorithm 3 (unknown change) × estimators × bank_size/pruning (with
algorithm4), known modes × estimators, tests without a vectorized batch (looped fallbacks), a nonlinear
relinearized bank, and IMM/GPB1/GPB2 × estimators.  Each variant's runner builds its scenario (irregular per-run
times, per-run priors, NaN patterns that differ between runs) and returns a :class:`Compared` — the batch's
results, the results alone and the fields to compare — and :func:`assert_runs_equal` compares them at the
variant's tolerance (1e-12).  The other tests here: a batched run's recording equals the run's own, inputs are
named in errors, Innovation.take slices per filter."""

import copy
import functools
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from hybridtrack import Decision, Detector, DetectorStep, Gaussian, Schedule
from hybridtrack.algorithms.known_modes import KnownModes, run_known_modes
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.algorithms.multiple_model import MultipleModelEstimator
from hybridtrack.algorithms.switch_state import SwitchAugmented
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.core.interfaces import Innovation
from hybridtrack.core.plugins import get_registry
from hybridtrack.core.protocols import Association, ChangeTimeTestBatch, ClutterInnovation, HypothesisTestBatch
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import RerunRecorder
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack.testing import build_example, check_algorithm_batch
from hybridtrack_plugins.detectors.sprt_change import ChangeTimeSPRT
from hybridtrack_plugins.detectors.sprt_pairwise import PairwiseSPRT
from hybridtrack_plugins.motion.linear_modes import ConstantAcceleration, LeftTurn, RightTurn, Straight
from hybridtrack_plugins.sensors.position import PositionSensor

ESTIMATORS = [e for e in get_registry().entries() if e.kind == "estimator"]
DETECTORS = [e for e in get_registry().entries() if e.kind == "detector"]
ALGORITHMS = [e for e in get_registry().entries() if e.kind == "algorithm"]
TOL = {"rtol": 1e-12, "atol": 1e-12}
ABSOLUTE_TOL = {"rtol": 0, "atol": 1e-12}  # the adaptive algorithms' and known modes' variants


@dataclass(frozen=True)
class Compared:
    """What one case compares, run r of ``batched`` against ``alone[r]``: ``fields`` within ``tol``, ``exact``
    arrays bit for bit, ``same`` attributes with ==, the ``decisions`` attributes with == and each decision's
    statistic within ``tol`` (``None``: decisions not compared), and the ``statistics`` series within ``tol``."""

    batched: list
    alone: list
    fields: tuple[str, ...]
    tol: dict
    exact: tuple[str, ...] = ()
    same: tuple[str, ...] = ()
    decisions: tuple[str, ...] | None = ("step", "detector", "mode", "message", "time")
    statistics: bool = False


def assert_runs_equal(compared):
    """The one assertion of the batch equivalence."""
    c = compared
    assert len(c.batched) == len(c.alone)
    for r, (b, s) in enumerate(zip(c.batched, c.alone, strict=True)):
        for name in c.fields:
            np.testing.assert_allclose(getattr(b, name), getattr(s, name), **c.tol, err_msg=f"run {r} {name}")
        for name in c.exact:
            np.testing.assert_array_equal(getattr(b, name), getattr(s, name), err_msg=f"run {r} {name}")
        for name in c.same:
            assert getattr(b, name) == getattr(s, name), f"run {r} {name}"
        if c.statistics:
            assert b.statistics.keys() == s.statistics.keys()
            for label, series in s.statistics.items():
                assert b.statistics[label].keys() == series.keys()
                for key, values in series.items():
                    np.testing.assert_allclose(b.statistics[label][key], values, **c.tol, err_msg=f"{label}/{key}")
        if c.decisions is not None:
            keys = [[tuple(getattr(d, k) for k in c.decisions) for d in result.decisions] for result in (b, s)]
            assert keys[0] == keys[1], f"run {r} decisions"
            for db, ds in zip(b.decisions, s.decisions):
                np.testing.assert_allclose(db.statistic, ds.statistic, **c.tol, err_msg=f"run {r} decision statistic")


@dataclass(frozen=True)
class Variant:
    """A named case: ``run()`` builds the scenario and returns its :class:`Compared`."""

    id: str
    run: Callable[[], Compared]


def variant(name, runner, **options):
    return Variant(":".join([name, *map(str, options.values())]), functools.partial(runner, **options))


# --- the Pipeline: registered estimators and detectors, and its variants ------------------------------------------

RUNS, STEPS = 3, 24
SENSORS = [PositionSensor(name="a"), PositionSensor(name="b", components="x", noise_cov=[[0.04]])]
MODELS = ["straight", ("left_turn", {"radius": 3.0, "noise_cov": np.diag([1e-3, 1e-3])})]


def batch_data():
    """Per-run irregular times, per-run priors, and NaN patterns that differ between runs at some steps."""
    rng = np.random.default_rng(7)
    schedule = Schedule.from_rows([("straight", STEPS // 2), ("left_turn", STEPS - 1 - STEPS // 2, 3.0)])
    times = np.cumsum(rng.uniform(0.05, 0.15, size=(RUNS, STEPS)), axis=1)
    z = {"a": np.empty((RUNS, STEPS, 2)), "b": np.empty((RUNS, STEPS, 1))}
    means = np.empty((RUNS, 4))
    for r in range(RUNS):
        x0 = np.array([0.1 * r, 0.0, 0.0, 2.0 + 0.1 * r])
        _, measured = simulate(schedule, x0, times=times[r], sensors=SENSORS, seed=r, noise_cov=np.diag([1e-3, 1e-3]))
        z["a"][r], z["b"][r] = measured["a"], measured["b"]
        means[r] = x0 + 0.05
    z["b"][0, 3:6] = np.nan  # run 0 lacks sensor b
    z["a"][1, 5, 1] = np.nan  # run 1 lacks one component of a
    z["a"][2, 7], z["b"][2, 7] = np.nan, np.nan  # run 2: prediction only
    z["a"][:, 9], z["b"][:, 9] = np.nan, np.nan  # every run: prediction only
    covs = np.stack([np.eye(4) * (1.0 + 0.5 * r) for r in range(RUNS)])
    return z, times, (means, covs)


def per_run(z, times, prior, r, **options):
    measurements = {name: a[r] for name, a in z.items()}
    return Pipeline(measurements=measurements, prior=Gaussian(prior[0][r], prior[1][r]), times=times[r], **options).run()


def pipeline_compared(batched, alone):
    """A Pipeline's results: every array, its layout and filters, its detectors' statistics and decisions."""
    fields = ("times", "means", "covs", "nis", "loglik", "innovations")
    decisions = ("step", "detector", "mode", "time")
    return Compared(batched, alone, fields, TOL, same=("layout", "filters"), decisions=decisions, statistics=True)


def pipeline_runs(entry):
    """(runs together, runs alone) of a Pipeline on :func:`batch_data` with the registered estimator, or the
    registered detector on a Kalman bank; None when the pipeline does not take the component on this scenario."""
    z, times, prior = batch_data()
    if entry.kind == "estimator":
        options = {"models": MODELS, "sensors": SENSORS, "estimator": build_example(entry.factory)}
    else:
        options = {"models": MODELS, "sensors": SENSORS, "estimator": "kalman", "detectors": [build_example(entry.factory)]}
    try:
        alone = [per_run(z, times, prior, r, **copy.deepcopy(options)) for r in range(RUNS)]
    except (ValueError, TypeError, AttributeError):
        return None
    return Pipeline.run_batch(z, prior, times=times, **options), alone


def registered(entry):
    """A registered estimator or detector through the Pipeline (None for an algorithm: the contract kit's
    :func:`hybridtrack.testing.check_algorithm_batch` compares times, means, covs, mode and decisions itself)."""
    if entry.kind == "algorithm":
        if not check_algorithm_batch(entry.factory):
            pytest.skip(f"algorithm {entry.name!r} has no run_batch")
        return None
    found = pipeline_runs(entry)
    if found is None:
        pytest.skip(f"the pipeline does not run {entry.kind} {entry.name!r} on this scenario")
    batched, alone = found
    assert len(batched) == RUNS
    if entry.kind == "detector":
        assert all(s.statistics for s in alone), "the detector reported nothing"
    return pipeline_compared(batched, alone)


def pipeline_shared_times_prior_nonlinear():
    """Shared times and prior, a nonlinear model (the ship layout) on an EKF bank."""
    z, _, _ = batch_data()
    prior = Gaussian(np.array([0.0, 0.0, 0.0, 2.0, 0.1]), np.eye(5))  # the ship layout (x, y, vx, vy, ω)
    options = {"models": ["ship_turn", ("ship_turn", {"sigma_rate": 1e-2})], "sensors": SENSORS, "estimator": "ekf", "tau": 0.1}
    options["filter_names"] = ["slow", "fast"]
    singles = [Pipeline(measurements={n: a[r] for n, a in z.items()}, prior=prior, **options).run() for r in range(RUNS)]
    return pipeline_compared(Pipeline.run_batch(z, prior, **options), singles)


class NisAbove(Detector):
    """A third-party detector (plain Detector, no batch method): decides once when NIS of filter 1 exceeds 3."""

    name = "nis_above"

    def __init__(self):
        self.reset()

    def reset(self):
        self.fired = False

    def step(self, step, innovation):
        nis = float(innovation.nis[1]) if innovation.measurement_dim else 0.0
        decision = None
        if nis > 3 and not self.fired:
            self.fired = True
            decision = Decision(step, self.name, "change", nis, "NIS above 3")
        return DetectorStep({"nis": nis}, {"threshold": 3.0}, decision)


def pipeline_signal_function_and_third_party(window, calibration):
    """The vectorized signal function and a third-party detector decide as per run."""
    z, times, prior = batch_data()
    parameters = {"window": window, "alpha": 0.3, "watch": 1, "calibration": calibration}
    detectors = [("signal_function", parameters, "sf"), NisAbove()]
    options = {"models": MODELS, "sensors": SENSORS, "estimator": "kalman"}
    singles = [per_run(z, times, prior, r, detectors=copy.deepcopy(detectors), **options) for r in range(RUNS)]
    assert sum(len(s.decisions) for s in singles) >= 2 * RUNS, "the scenario should make both detectors decide"
    return pipeline_compared(Pipeline.run_batch(z, prior, times=times, detectors=detectors, **options), singles)


PIPELINE_VARIANTS = [
    variant("pipeline:shared_times_prior_nonlinear", pipeline_shared_times_prior_nonlinear),
    *(
        variant("pipeline:signal_function+nis_above", pipeline_signal_function_and_third_party, window=w, calibration=c)
        for w, c in [(None, "normal"), (None, "chi2"), (3, "normal")]
    ),
]


# --- the adaptive algorithms (known switch, unknown change, known modes) -------------------------------------------

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
MODES = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
ADAPTIVE_RUNS = 4
FOLLOW = [("mixture", 4.0), ("previous", 1.0), ("most_likely", 1.0)]
BANKS = [(None, None), (3, "nearest_lower"), (4, "oldest")]
ADAPTIVE_FIELDS = ("times", "means", "covs", "mode", "log_ratios")
UNKNOWN_CHANGE_FIELDS = ADAPTIVE_FIELDS + ("bank_sizes", "signal", "signal_bounds")


def adaptive_data(schedule, runs=ADAPTIVE_RUNS, irregular=True, nan=True, noise=NOISE, seed=0):
    """Per-run measurements (runs, K+1, 2) at per-run times; one run misses x at one step and everything at another."""
    K1 = schedule.total_steps + 1
    rng = np.random.default_rng(seed)
    times = np.cumsum(np.concatenate([np.zeros((runs, 1)), rng.uniform(0.07, 0.13, (runs, K1 - 1))], axis=1), axis=1)
    sensor = PositionSensor(noise_cov=noise)
    z = []
    for r in range(runs):
        _, measured = simulate(schedule, X0, None if irregular else 0.1, [sensor], times=times[r] if irregular else None, seed=seed + r)
        z.append(measured[sensor.name])
    z = np.stack(z)
    if nan:
        z[1, 7, 0] = np.nan  # one component missing in run 1 only
        z[2, 12] = np.nan  # nothing measured in run 2 at step 12
    return sensor, z, (times if irregular else None)


def single_runs(adaptive, sensor, z, times, prior, *args):
    return [
        adaptive.run(
            {sensor.name: z[r]},
            prior if isinstance(prior, Gaussian) else Gaussian(prior[0][r], prior[1]),
            *args,
            times=None if times is None else times[r],
        )
        for r in range(z.shape[0])
    ]


def per_run_estimator(name):
    """A decentralized filter, or a seeded particle filter (a new one per call: its streams restart)."""
    if name == "particle":
        from hybridtrack_plugins.filters.particle import ParticleFilter

        return ParticleFilter(particles=60, seed=5)
    return name


def known_switch(estimator, follow, inflation):
    """Algorithm 1 with a known switch schedule (the run alone gets the segment lengths)."""
    schedule = Schedule.from_rows([("straight", 12), ("left_turn", 14, 3.0), ("straight", 10)])
    sensor, z, times = adaptive_data(schedule)
    adaptive = KnownSwitchAdaptive(
        sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=4.0, noise_cov=NOISE, alpha=0.05, beta=0.05,
        estimator=estimator, follow=follow, switch_inflation=inflation,
    )  # fmt: skip
    prior = (X0 + np.arange(ADAPTIVE_RUNS)[:, None] * 0.01, np.eye(4))
    lengths = [s.steps for s in schedule.segments]
    batched = adaptive.run_batch({sensor.name: z}, prior, schedule, times=times)
    single = single_runs(adaptive, sensor, z, times, prior, lengths)
    assert any(o.decision_step is not None for b in batched for o in b.segments)
    return Compared(batched, single, ADAPTIVE_FIELDS, ABSOLUTE_TOL, same=("segments",))


def known_switch_joint(estimator, follow, inflation):
    """The estimating bank of switch-augmented models (relinearized after a decision) in one bank of R runs.

    Its Jacobians are forward differences (h = 1e-7), which turn a last-bit difference of the estimate into
    ~1e-9: Potter's update of a run updated alone (its own missing pattern) rounds differently from the same
    run's update inside a larger group, so Potter is checked on fully measured runs."""
    schedule = Schedule.from_rows([("straight", 12), ("left_turn", 14, 3.0), ("straight", 10)])
    sensor, z, times = adaptive_data(schedule, nan=estimator != "potter")
    adaptive = KnownSwitchAdaptive(
        sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=4.0, noise_cov=NOISE, alpha=0.05, beta=0.05,
        estimator=estimator, follow=follow, switch_inflation=inflation, switch_estimate="joint",
    )  # fmt: skip
    prior = (X0 + np.arange(ADAPTIVE_RUNS)[:, None] * 0.01, np.eye(4))
    batched = adaptive.run_batch({sensor.name: z}, prior, schedule, times=times)
    single = single_runs(adaptive, sensor, z, times, prior, schedule)
    assert any(o.decision_step is not None for b in batched for o in b.segments)
    return Compared(batched, single, ADAPTIVE_FIELDS, ABSOLUTE_TOL, same=("segments",))


def known_switch_per_run(estimator, switch_estimate):
    """Runs that cannot share one bank (node copies, particle streams) each run as a batch of one."""
    schedule = Schedule.from_rows([("straight", 10), ("left_turn", 12, 3.0)])
    sensor, z, times = adaptive_data(schedule, runs=3)
    kwargs = dict(sensors=[sensor], tau=0.1, n=2, r_min=2.0, r_max=4.0, noise_cov=NOISE, switch_estimate=switch_estimate)
    batched = KnownSwitchAdaptive(estimator=per_run_estimator(estimator), **kwargs).run_batch(
        {sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, times=times
    )
    adaptive = KnownSwitchAdaptive(estimator=per_run_estimator(estimator), **kwargs)
    single = single_runs(adaptive, sensor, z, times, Gaussian(X0, np.eye(4)), schedule)
    return Compared(batched, single, ADAPTIVE_FIELDS, ABSOLUTE_TOL)


def known_switch_looped_test():
    """A test without a vectorized batch (the HypothesisTestBatch fallback) gives the same runs, regular sampling."""

    class Looped(PairwiseSPRT):
        def batch(self, runs):
            return HypothesisTestBatch(self, runs)

    schedule = Schedule.from_rows([("straight", 10), ("right_turn", 12, 3.0)])
    sensor, z, _ = adaptive_data(schedule, irregular=False, nan=False)
    kwargs = dict(sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=4.0, noise_cov=NOISE)
    vectorized = KnownSwitchAdaptive(**kwargs).run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule)
    looped = KnownSwitchAdaptive(**kwargs, detector=Looped(0.01, 0.01)).run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule)
    return Compared(vectorized, looped, ("means", "covs", "mode", "log_ratios"), ABSOLUTE_TOL)


def unknown_change(estimator, bank_size, pruning):
    """Algorithm 3 (unknown change) with a bounded bank (its pruning rules, or algorithm4's bound)."""
    schedule = Schedule.from_rows([("straight", 15), ("right_turn", 20, 5.0)])
    sensor, z, times = adaptive_data(schedule)
    adaptive = UnknownChangeAdaptive(
        modes=MODES, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1, estimator=estimator, bank_size=bank_size, pruning=pruning
    )
    prior = Gaussian(X0, np.eye(4))
    batched = adaptive.run_batch({sensor.name: z}, prior, times=times)
    single = single_runs(adaptive, sensor, z, times, prior)
    if bank_size is None:
        assert any(b.changes for b in batched)
    return Compared(batched, single, UNKNOWN_CHANGE_FIELDS, ABSOLUTE_TOL, same=("changes", "bank_limit"))


def unknown_change_per_run(estimator, bank_size, pruning):
    """Decentralized node series (a run without any measurement at a step feeds the nodes ℓ = 0, m = 0) and
    particle streams, each run a batch of one."""
    schedule = Schedule.from_rows([("straight", 15), ("right_turn", 20, 5.0)])
    sensor, z, times = adaptive_data(schedule, runs=3)
    kwargs = dict(modes=MODES, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1, bank_size=bank_size, pruning=pruning)
    batched = UnknownChangeAdaptive(estimator=per_run_estimator(estimator), **kwargs).run_batch(
        {sensor.name: z}, Gaussian(X0, np.eye(4)), times=times
    )
    single = single_runs(UnknownChangeAdaptive(estimator=per_run_estimator(estimator), **kwargs), sensor, z, times, Gaussian(X0, np.eye(4)))
    fields = UNKNOWN_CHANGE_FIELDS
    if estimator == "decentralized":
        fields += ("node_log_ratios", "node_signal")
        assert batched[0].node_log_ratios.shape == (schedule.total_steps + 1, 1, len(MODES))
        assert np.isfinite(batched[2].node_log_ratios[12]).any()  # the step run 2 measured nothing
    return Compared(batched, single, fields, ABSOLUTE_TOL, same=("changes",))


def unknown_change_looped_test(bank_size, pruning):
    """A change-time test without a vectorized batch (the ChangeTimeTestBatch fallback) gives the same runs."""

    class Looped(ChangeTimeSPRT):
        def batch(self, runs):
            return ChangeTimeTestBatch(self, runs)

    schedule = Schedule.from_rows([("straight", 15), ("right_turn", 20, 5.0)])
    sensor, z, times = adaptive_data(schedule, seed=3)
    kwargs = dict(modes=MODES, sensors=[sensor], tau=0.1, bank_size=bank_size, pruning=pruning)
    vectorized = UnknownChangeAdaptive(**kwargs, alpha=0.1, beta=0.1).run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), times=times)
    looped = UnknownChangeAdaptive(**kwargs, detector=Looped(0.1, 0.1)).run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), times=times)
    fields = ("means", "covs", "mode", "log_ratios", "bank_sizes", "signal")
    return Compared(vectorized, looped, fields, ABSOLUTE_TOL, same=("changes",))


def unknown_change_nonlinear():
    """A run whose bank holds a nonlinear mode relinearizes all its filters at their means (as FilterBank does):
    switch-state-augmented modes, the turns refining their switch state (EKF)."""
    schedule = Schedule.from_rows([("straight", 8), ("right_turn", 10, 5.0)])
    sensor, z, times = adaptive_data(schedule, runs=3)
    modes = [SwitchAugmented(Straight(noise_cov=NOISE)), SwitchAugmented(RightTurn(radius=5.0, noise_cov=NOISE), relinearize=True)]
    modes.append(SwitchAugmented(LeftTurn(radius=5.0, noise_cov=NOISE)))
    adaptive = UnknownChangeAdaptive(modes=modes, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1, estimator="ekf", bank_size=6)
    mean = np.concatenate([X0, X0])
    prior = Gaussian(mean, np.eye(8))
    batched = adaptive.run_batch({sensor.name: z}, prior, times=times)
    single = single_runs(adaptive, sensor, z, times, prior)
    return Compared(batched, single, ("means", "covs", "mode", "log_ratios", "bank_sizes"), ABSOLUTE_TOL)


def known_modes(estimator):
    """The known mode sequence (KnownModes.run_batch) against run_known_modes of each run."""
    schedule = Schedule.from_rows([("straight", 10), ("left_turn", 12, 3.0), ("straight", 8)])
    sensor, z, times = adaptive_data(schedule)
    kwargs = dict(sensors=[sensor], prior=Gaussian(X0, np.eye(4)), tau=0.1, noise_cov=NOISE)
    known = KnownModes(schedule=schedule, estimator=per_run_estimator(estimator), sensors=[sensor], tau=0.1, noise_cov=NOISE)
    batched = known.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), times=times)
    single_estimator = per_run_estimator(estimator)
    single = [
        run_known_modes(schedule, estimator=single_estimator, measurements={sensor.name: z[r]}, times=times[r], **kwargs)
        for r in range(len(batched))
    ]
    for b in batched:
        assert b.modes == ("straight", "left_turn_r3") and b.mode.tolist() == [0] * 11 + [1] * 12 + [0] * 8
    return Compared(batched, single, ("times", "means", "covs", "nis"), ABSOLUTE_TOL, same=("modes",), decisions=None)


# --- the multiple-model estimators (IMM, GPB1, GPB2) --------------------------------------------------------------

MM_RUNS, MM_STEPS = 4, 16
MM_SENSORS = [PositionSensor(name="a", noise_cov=np.diag([0.5, 0.8])), PositionSensor(name="b", components="x", noise_cov=[[0.3]])]
MM_FIELDS = ("means", "covs", "log_mode_probabilities", "model_means", "model_covs", "model_loglik", "loglik")


def multiple_model_data(seed=3):
    """Straight runs at different speeds, irregular per-run times, per-run priors, NaN components differing between runs."""
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.5, 1.5, size=(MM_RUNS, MM_STEPS)), axis=1)
    t = times - times[:, :1]
    x = np.stack([t[r] * (1.0 + 0.2 * r) for r in range(MM_RUNS)])  # straight runs at different speeds
    y = np.stack([np.sin(0.3 * t[r]) * 5 for r in range(MM_RUNS)])
    z = {
        "a": np.stack([x, y], axis=-1) + rng.normal(0, 0.7, (MM_RUNS, MM_STEPS, 2)),
        "b": x[..., None] + rng.normal(0, 0.5, (MM_RUNS, MM_STEPS, 1)),
    }
    z["b"][0, 4:8] = np.nan  # run 0 lacks sensor b
    z["a"][1, 6, 0] = np.nan  # run 1 lacks one component
    z["a"][2, 10], z["b"][2, 10] = np.nan, np.nan  # run 2: prediction only
    means = np.stack([[0.0, 1.0 + 0.2 * r, 0.0, 0.5] for r in range(MM_RUNS)])
    covs = np.stack([np.diag([1.0, 0.5, 1.0, 0.5]) * (1 + r) for r in range(MM_RUNS)])
    return z, times, (means, covs)


def multiple_model(method, estimator):
    """MultipleModelEstimator.run_batch: runs × models vectorized, with a sojourn-time chain."""
    z, times, prior = multiple_model_data()
    models = [Straight(noise_cov=np.eye(2) * 0.01), LeftTurn(radius=20.0, noise_cov=np.eye(2) * 0.1), ConstantAcceleration()]
    mm = MultipleModelEstimator(models, sensors=MM_SENSORS, sojourn=[10.0, 5.0, 8.0], method=method, estimator=estimator)
    batched = mm.run_batch(z, prior, times=times)
    assert len(batched) == MM_RUNS
    single = [mm.run({n: a[r] for n, a in z.items()}, Gaussian(prior[0][r], prior[1][r]), times=times[r]) for r in range(MM_RUNS)]
    return Compared(batched, single, MM_FIELDS, TOL, exact=("times", "mode"), decisions=None)


def multiple_model_shared_times_matrix_recording():
    """Shared times and prior, a transition matrix, and run 2 recorded."""
    z, _, _ = multiple_model_data(5)
    prior = Gaussian(np.array([0.0, 1.0, 0.0, 0.5]), np.eye(4))
    mm = MultipleModelEstimator(
        [Straight(noise_cov=np.eye(2) * 0.01), Straight(noise_cov=np.eye(2) * 4.0)], [[0.95, 0.05], [0.1, 0.9]], sensors=MM_SENSORS, tau=1.0
    )
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run2.rrd"
        recorder = RerunRecorder(path)
        batched = mm.run_batch(z, prior, recorders={2: recorder})
        recorder.close()
        assert path.stat().st_size > 0
    single = [mm.run({n: a[r] for n, a in z.items()}, prior) for r in range(MM_RUNS)]
    return Compared(batched, single, ("log_mode_probabilities", "covs"), TOL, decisions=None)


ALGORITHM_VARIANTS = [
    *(
        variant("known_switch", known_switch, estimator=e, follow=f, inflation=i)
        for e in ["kalman", "information", "potter", "bierman", "srif"]
        for f, i in FOLLOW
    ),
    *(
        variant("known_switch_joint", known_switch_joint, estimator=e, follow=f, inflation=i)
        for e in ["kalman", "information", "bierman", "srif", "ekf", "potter"]
        for f, i in FOLLOW
    ),
    *(
        variant("known_switch_per_run", known_switch_per_run, estimator=e, switch_estimate=s)
        for e, s in [("decentralized", "filtered"), ("decentralized", "joint"), ("particle", "filtered")]
    ),
    variant("known_switch_looped_test", known_switch_looped_test),
    *(
        variant("unknown_change", unknown_change, estimator=e, bank_size=b, pruning=p)
        for e in ["kalman", "information", "potter", "srif", "ekf"]
        for b, p in BANKS + [("algorithm4", None)]
    ),
    *(
        variant("unknown_change_per_run", unknown_change_per_run, estimator=e, bank_size=b, pruning=p)
        for e in ["decentralized", "particle"]
        for b, p in BANKS
    ),
    *(variant("unknown_change_looped_test", unknown_change_looped_test, bank_size=b, pruning=p) for b, p in BANKS),
    variant("unknown_change_nonlinear", unknown_change_nonlinear),
    *(variant("known_modes", known_modes, estimator=e) for e in ["kalman", "bierman", "srif", "decentralized", "particle"]),
    *(
        variant("multiple_model", multiple_model, method=m, estimator=e)
        for m, e in [("imm", "kalman"), ("gpb1", "kalman"), ("gpb2", "kalman"), ("imm", "potter"), ("gpb2", "information")]
    ),
    variant("multiple_model:shared_times_matrix_recording", multiple_model_shared_times_matrix_recording),
]


@pytest.mark.parametrize(
    "case",
    ESTIMATORS + DETECTORS + ALGORITHMS + PIPELINE_VARIANTS + ALGORITHM_VARIANTS,
    ids=lambda c: c.id if isinstance(c, Variant) else f"{c.kind}:{c.name}",
)
def test_runs_together_equal_runs_alone(case):
    """The one batch-equivalence check: R runs in one batch equal each run alone (per-run irregular times,
    per-run priors, missing components), over every registered estimator, detector and algorithm and every
    named variant, each at its tolerance (1e-12)."""
    compared = case.run() if isinstance(case, Variant) else registered(case)
    if compared is not None:
        assert_runs_equal(compared)


# --- not batch equivalences ---------------------------------------------------------------------------------------


def test_batch_records_the_runs_asked_for(tmp_path):
    z, times, prior = batch_data()
    options = {"models": MODELS, "sensors": SENSORS, "estimator": "kalman", "detectors": ["signal_function"]}
    path = tmp_path / "run1.rrd"
    recorder = RerunRecorder(path)
    batched = Pipeline.run_batch(z, prior, times=times, recorders={1: recorder}, record_seconds=None, **options)
    recorder.close()
    assert path.stat().st_size > 0
    reference = tmp_path / "single.rrd"
    single = RerunRecorder(reference)
    pipeline = Pipeline(
        measurements={n: a[1] for n, a in z.items()},
        prior=Gaussian(prior[0][1], prior[1][1]),
        times=times[1],
        recorder=single,
        record_seconds=None,
        **options,
    )
    assert_runs_equal(pipeline_compared([batched[1]], [pipeline.run()]))
    single.close()
    one, alone = RecordingFile(path), RecordingFile(reference)
    assert one.entity_paths == alone.entity_paths and one.events() == alone.events()
    for entity in (
        "estimator/straight/nis",
        "estimator/left_turn_r3/innovation",
        "estimator/nis_bounds",
        "detector/signal_function/signal",
    ):
        steps, values = one.series(entity)
        np.testing.assert_array_equal(steps, alone.series(entity)[0])
        np.testing.assert_allclose(values, alone.series(entity)[1], **TOL, err_msg=entity)
    for entity in ("world/measurements/a", "world/estimate/straight"):
        np.testing.assert_array_equal(one.points(entity)[1], alone.points(entity)[1])


def test_innovation_take_slices_every_per_filter_field():
    nu, S = np.arange(12.0).reshape(6, 2), np.tile(np.eye(2), (6, 1, 1))
    innovation = Innovation(nu, S, np.arange(6.0), np.arange(6.0) + 1)
    part = innovation.take(np.array([2, 3]), 6)
    np.testing.assert_array_equal(part.nu, nu[2:4])
    np.testing.assert_array_equal(part.loglik, [2.0, 3.0])
    assert type(part) is Innovation
    candidates = np.zeros((6, 2))  # L = 6 candidates, as many as filters: describe the scan, not sliced
    association = Association(
        "a", candidates, nu, S, 9.0, np.ones((6, 6)), np.ones((6, 6), bool), np.ones((6, 6)), np.zeros(6), np.arange(6), np.arange(6.0)
    )
    clutter = ClutterInnovation(nu, S, np.arange(6.0), np.arange(6.0), (association,)).take(np.array([4]), 6)
    (cut,) = clutter.associations
    assert type(clutter) is ClutterInnovation and cut.candidates.shape == (6, 2) and cut.weights.shape == (1, 6)
    np.testing.assert_array_equal(cut.selected, [4])


def test_bad_multiple_model_batch_inputs_are_named():
    z, times, prior = multiple_model_data()
    mm = MultipleModelEstimator([Straight(), Straight(noise_cov=np.eye(2))], sojourn=5.0, sensors=MM_SENSORS)
    with pytest.raises(ValueError, match="times"):
        mm.run_batch(z, prior, times=times[:2])
    with pytest.raises(ValueError, match="measurements"):
        mm.run_batch({n: a[0] for n, a in z.items()}, prior, times=times)
    with pytest.raises(ValueError, match="recorders"):
        mm.run_batch(z, prior, times=times, recorders={MM_RUNS: None})


def test_bad_batch_inputs_are_named():
    z, times, prior = batch_data()
    options = {"models": MODELS, "sensors": SENSORS, "estimator": "kalman"}
    with pytest.raises(ValueError, match="measurements"):
        Pipeline.run_batch({"a": z["a"][0], "b": z["b"][0]}, prior, times=times, **options)
    with pytest.raises(ValueError, match="times"):
        Pipeline.run_batch(z, prior, times=times[:, :-1], **options)
    with pytest.raises(ValueError, match="prior"):
        Pipeline.run_batch(z, (prior[0][:2], prior[1][:2]), times=times, **options)
    with pytest.raises(ValueError, match="recorders"):
        Pipeline.run_batch(z, prior, times=times, recorders={RUNS: None}, **options)
