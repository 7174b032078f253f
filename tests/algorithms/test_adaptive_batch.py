"""Batched runs of the adaptive estimators (issue #14): ``run_batch`` equals ``[run(...) for each run]`` to 1e-12.

Several estimators (covariance, information, Potter, Bierman, SRIF), the
detectors they drive (pairwise SPRT vectorized; the change-time SPRT and the
signal function per run; a third-party-like test through the looped fallback),
per-run irregular times and a NaN measurement in one run only.
"""

import numpy as np
import pytest

from hybridtrack import Gaussian, Schedule
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.core.protocols import HypothesisTestBatch
from hybridtrack.engine.simulate import simulate
from hybridtrack_plugins.detectors.sprt_pairwise import PairwiseSPRT, batch_margins
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
MODES = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
RUNS = 4
TOL = dict(rtol=0, atol=1e-12)


def batch_data(schedule, runs=RUNS, irregular=True, nan=True, noise=NOISE, seed=0):
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


def assert_runs_equal(batched, single, fields):
    for b, s in zip(batched, single, strict=True):
        for name in fields:
            np.testing.assert_allclose(getattr(b, name), getattr(s, name), **TOL, err_msg=name)
        assert len(b.decisions) == len(s.decisions)
        for db, ds in zip(b.decisions, s.decisions):
            assert (db.step, db.detector, db.mode, db.message, db.time) == (ds.step, ds.detector, ds.mode, ds.message, ds.time)
            assert db.statistic == pytest.approx(ds.statistic, rel=0, abs=1e-12)


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


@pytest.mark.parametrize("estimator", ["kalman", "information", "potter", "bierman", "srif"])
@pytest.mark.parametrize("follow, inflation", [("mixture", 4.0), ("previous", 1.0), ("most_likely", 1.0)])
def test_known_switch_batch_equals_the_runs(estimator, follow, inflation):
    schedule = Schedule.from_rows([("straight", 12), ("left_turn", 14, 3.0), ("straight", 10)])
    sensor, z, times = batch_data(schedule)
    adaptive = KnownSwitchAdaptive(
        sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=4.0, noise_cov=NOISE, alpha=0.05, beta=0.05,
        estimator=estimator, follow=follow, switch_inflation=inflation,
    )  # fmt: skip
    prior = (X0 + np.arange(RUNS)[:, None] * 0.01, np.eye(4))
    lengths = [s.steps for s in schedule.segments]
    batched = adaptive.run_batch({sensor.name: z}, prior, schedule, times=times)
    single = single_runs(adaptive, sensor, z, times, prior, lengths)
    assert_runs_equal(batched, single, ("times", "means", "covs", "mode", "log_ratios"))
    for b, s in zip(batched, single):
        assert b.segments == s.segments
    assert any(o.decision_step is not None for b in batched for o in b.segments)


@pytest.mark.parametrize("estimator", ["kalman", "information", "bierman", "srif", "ekf", "potter"])
@pytest.mark.parametrize("follow, inflation", [("mixture", 4.0), ("previous", 1.0), ("most_likely", 1.0)])
def test_known_switch_batch_with_the_joint_switch_estimate_equals_the_runs(estimator, follow, inflation):
    """The estimating bank of switch-augmented models (relinearized after a decision) in one bank of R runs.

    Its Jacobians are forward differences (h = 1e-7), which turn a last-bit difference of the estimate into
    ~1e-9: Potter's update of a run updated alone (its own missing pattern) rounds differently from the same
    run's update inside a larger group, so Potter is checked on fully measured runs."""
    schedule = Schedule.from_rows([("straight", 12), ("left_turn", 14, 3.0), ("straight", 10)])
    sensor, z, times = batch_data(schedule, nan=estimator != "potter")
    adaptive = KnownSwitchAdaptive(
        sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=4.0, noise_cov=NOISE, alpha=0.05, beta=0.05,
        estimator=estimator, follow=follow, switch_inflation=inflation, switch_estimate="joint",
    )  # fmt: skip
    prior = (X0 + np.arange(RUNS)[:, None] * 0.01, np.eye(4))
    batched = adaptive.run_batch({sensor.name: z}, prior, schedule, times=times)
    single = single_runs(adaptive, sensor, z, times, prior, schedule)
    assert_runs_equal(batched, single, ("times", "means", "covs", "mode", "log_ratios"))
    for b, s in zip(batched, single):
        assert b.segments == s.segments
    assert any(o.decision_step is not None for b in batched for o in b.segments)


def _per_run_estimator(name):
    """A decentralized filter, or a seeded particle filter (a new one per call: its streams restart)."""
    if name == "particle":
        from hybridtrack_plugins.filters.particle import ParticleFilter

        return ParticleFilter(particles=60, seed=5)
    return name


@pytest.mark.parametrize(
    "estimator, switch_estimate", [("decentralized", "filtered"), ("decentralized", "joint"), ("particle", "filtered")]
)
def test_known_switch_batch_of_per_run_estimators_equals_the_runs(estimator, switch_estimate):
    """Runs that cannot share one bank (node copies, particle streams) each run as a batch of one."""
    schedule = Schedule.from_rows([("straight", 10), ("left_turn", 12, 3.0)])
    sensor, z, times = batch_data(schedule, runs=3)
    kwargs = dict(sensors=[sensor], tau=0.1, n=2, r_min=2.0, r_max=4.0, noise_cov=NOISE, switch_estimate=switch_estimate)
    batched = KnownSwitchAdaptive(estimator=_per_run_estimator(estimator), **kwargs).run_batch(
        {sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, times=times
    )
    adaptive = KnownSwitchAdaptive(estimator=_per_run_estimator(estimator), **kwargs)
    single = single_runs(adaptive, sensor, z, times, Gaussian(X0, np.eye(4)), schedule)
    assert_runs_equal(batched, single, ("times", "means", "covs", "mode", "log_ratios"))


@pytest.mark.parametrize("estimator", ["decentralized", "particle"])
@pytest.mark.parametrize("bank_size, pruning", [(None, None), (3, "nearest_lower"), (4, "oldest")])
def test_unknown_change_batch_of_per_run_estimators_equals_the_runs(estimator, bank_size, pruning):
    """Decentralized node series (a run without any measurement at a step feeds the nodes ℓ = 0, m = 0) and
    particle streams, each run a batch of one."""
    schedule = Schedule.from_rows([("straight", 15), ("right_turn", 20, 5.0)])
    sensor, z, times = batch_data(schedule, runs=3)
    kwargs = dict(modes=MODES, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1, bank_size=bank_size, pruning=pruning)
    batched = UnknownChangeAdaptive(estimator=_per_run_estimator(estimator), **kwargs).run_batch(
        {sensor.name: z}, Gaussian(X0, np.eye(4)), times=times
    )
    single = single_runs(
        UnknownChangeAdaptive(estimator=_per_run_estimator(estimator), **kwargs), sensor, z, times, Gaussian(X0, np.eye(4))
    )
    fields = ("times", "means", "covs", "mode", "log_ratios", "bank_sizes", "signal", "signal_bounds")
    assert_runs_equal(batched, single, fields + (("node_log_ratios", "node_signal") if estimator == "decentralized" else ()))
    for b, s in zip(batched, single):
        assert b.changes == s.changes
    if estimator == "decentralized":
        assert batched[0].node_log_ratios.shape == (schedule.total_steps + 1, 1, len(MODES))
        assert np.isfinite(batched[2].node_log_ratios[12]).any()  # the step run 2 measured nothing


def test_known_switch_batch_with_a_looped_test_and_regular_sampling():
    """A test without a vectorized batch (the HypothesisTestBatch fallback) gives the same runs."""

    class Looped(PairwiseSPRT):
        def batch(self, runs):
            return HypothesisTestBatch(self, runs)

    schedule = Schedule.from_rows([("straight", 10), ("right_turn", 12, 3.0)])
    sensor, z, _ = batch_data(schedule, irregular=False, nan=False)
    kwargs = dict(sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=4.0, noise_cov=NOISE)
    vectorized = KnownSwitchAdaptive(**kwargs).run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule)
    looped = KnownSwitchAdaptive(**kwargs, detector=Looped(0.01, 0.01)).run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule)
    assert_runs_equal(vectorized, looped, ("means", "covs", "mode", "log_ratios"))


def test_batch_margins_equal_margins_row_by_row_with_ties():
    rng = np.random.default_rng(3)
    L = np.round(rng.normal(size=(50, 5)), 1)  # ties
    active = rng.random((50, 5)) < 0.6
    expected = np.concatenate([batch_margins(L[i : i + 1], active[i : i + 1]) for i in range(50)])
    np.testing.assert_array_equal(batch_margins(L, active), expected)


@pytest.mark.parametrize("estimator", ["kalman", "information", "potter", "srif", "ekf"])
@pytest.mark.parametrize("bank_size, pruning", [(None, None), (3, "nearest_lower"), (4, "oldest"), ("algorithm4", None)])
def test_unknown_change_batch_equals_the_runs(estimator, bank_size, pruning):
    schedule = Schedule.from_rows([("straight", 15), ("right_turn", 20, 5.0)])
    sensor, z, times = batch_data(schedule)
    adaptive = UnknownChangeAdaptive(
        modes=MODES, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1, estimator=estimator, bank_size=bank_size, pruning=pruning
    )
    prior = Gaussian(X0, np.eye(4))
    batched = adaptive.run_batch({sensor.name: z}, prior, times=times)
    single = single_runs(adaptive, sensor, z, times, prior)
    assert_runs_equal(batched, single, ("times", "means", "covs", "mode", "log_ratios", "bank_sizes", "signal", "signal_bounds"))
    for b, s in zip(batched, single):
        assert b.changes == s.changes and b.bank_limit == s.bank_limit
    if bank_size is None:
        assert any(b.changes for b in batched)


class ListRecorder:
    """Keeps every logging call (name, arguments) so two recordings can be compared."""

    def __init__(self):
        self.calls = []

    def log_result(self, result, **context):
        from hybridtrack.recording.results import log_result

        log_result(result, self, **context)

    def __getattr__(self, name):
        if not name.startswith("log_"):
            raise AttributeError(name)
        return lambda *args, **kwargs: self.calls.append((name, args, kwargs))


def same_calls(a, b):
    assert len(a.calls) == len(b.calls)
    for (na, aa, ka), (nb, ab, kb) in zip(a.calls, b.calls):
        assert na == nb and ka.keys() == kb.keys() and len(aa) == len(ab)
        for x, y in zip(list(aa) + list(ka.values()), list(ab) + list(kb.values())):
            if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
                np.testing.assert_allclose(np.asarray(x, float), np.asarray(y, float), **TOL)
            elif isinstance(x, str) and x.startswith("sprt"):
                assert x.split("margin")[0] == y.split("margin")[0]
            else:
                assert x == pytest.approx(y, rel=0, abs=1e-12) if isinstance(x, float) else x == y


def test_batch_records_the_requested_runs_like_the_single_run():
    schedule = Schedule.from_rows([("straight", 8), ("right_turn", 12, 5.0)])
    sensor, z, _ = batch_data(schedule, runs=3, irregular=False, nan=False)
    adaptive = UnknownChangeAdaptive(modes=MODES, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1)
    batched, single = ListRecorder(), ListRecorder()
    adaptive.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), recorders={1: batched})
    adaptive.run({sensor.name: z[1]}, Gaussian(X0, np.eye(4)), recorder=single)
    assert batched.calls and any(c[0] == "log_scalars" for c in batched.calls)
    same_calls(batched, single)
    known = KnownSwitchAdaptive(sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=5.0, noise_cov=NOISE)
    batched, single = ListRecorder(), ListRecorder()
    known.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, recorders={2: batched})
    known.run({sensor.name: z[2]}, Gaussian(X0, np.eye(4)), schedule, recorder=single)
    same_calls(batched, single)
    joint = KnownSwitchAdaptive(sensors=[sensor], tau=0.1, n=3, r_min=2.0, r_max=5.0, noise_cov=NOISE, switch_estimate="joint")
    batched, single = ListRecorder(), ListRecorder()
    joint.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, recorders={0: batched})
    joint.run({sensor.name: z[0]}, Gaussian(X0, np.eye(4)), schedule, recorder=single)
    assert any(c[1][0].startswith("world/estimate/known_switch/hypotheses/") for c in batched.calls if c[0] == "log_path")
    same_calls(batched, single)


def test_batch_input_errors():
    schedule = Schedule.from_rows([("straight", 5)])
    sensor, z, _ = batch_data(schedule, runs=2, irregular=False, nan=False)
    adaptive = KnownSwitchAdaptive(sensors=[sensor], tau=0.1, n=2, r_min=2.0, r_max=4.0)
    with pytest.raises(ValueError, match="measurements"):
        adaptive.run_batch({sensor.name: z[0]}, Gaussian(X0, np.eye(4)), schedule)
    with pytest.raises(ValueError, match="times"):
        adaptive.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, times=np.zeros((3, 6)))
    with pytest.raises(ValueError, match="prior"):
        adaptive.run_batch({sensor.name: z}, (np.zeros((3, 4)), np.eye(4)), schedule)
    with pytest.raises(ValueError, match="recorders"):
        adaptive.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), schedule, recorders={5: None})


@pytest.mark.parametrize("estimator", ["kalman", "bierman", "srif", "decentralized", "particle"])
def test_known_modes_batch_equals_the_runs(estimator):
    from hybridtrack.algorithms.known_modes import KnownModes, run_known_modes

    schedule = Schedule.from_rows([("straight", 10), ("left_turn", 12, 3.0), ("straight", 8)])
    sensor, z, times = batch_data(schedule)
    kwargs = dict(sensors=[sensor], prior=Gaussian(X0, np.eye(4)), tau=0.1, noise_cov=NOISE)
    known = KnownModes(schedule=schedule, estimator=_per_run_estimator(estimator), sensors=[sensor], tau=0.1, noise_cov=NOISE)
    batched = known.run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), times=times)
    single_estimator = _per_run_estimator(estimator)
    for r, b in enumerate(batched):
        s = run_known_modes(schedule, estimator=single_estimator, measurements={sensor.name: z[r]}, times=times[r], **kwargs)
        assert b.modes == s.modes == ("straight", "left_turn_r3") and b.mode.tolist() == [0] * 11 + [1] * 12 + [0] * 8
        for name in ("times", "means", "covs", "nis"):
            np.testing.assert_allclose(getattr(b, name), getattr(s, name), **TOL, err_msg=name)


@pytest.mark.parametrize("mode", ["straight", "stop", ("left_turn", {"radius": 3.0}), ("right_turn", {"radius": 7.0})])
def test_vectorized_transition_bank_equals_the_stacked_transitions(mode):
    from hybridtrack.core.interfaces import MotionModel, TransitionBank
    from hybridtrack.core.plugins import resolve

    model = resolve("motion_model", mode)
    states = np.random.default_rng(5).normal(size=(6, 4))
    states[0, [1, 3]] = 0.0  # zero speed: ω = 0, the straight motion
    fast = model.transition_bank(0.1, states)
    reference = MotionModel.transition_bank(model, 0.1, states)
    stacked = TransitionBank.stack([model.transition(0.1, x) for x in states])
    for name in ("F", "B", "Q", "noise_root"):
        np.testing.assert_allclose(getattr(fast, name), getattr(stacked, name), **TOL, err_msg=name)
        np.testing.assert_allclose(getattr(reference, name), getattr(stacked, name), **TOL, err_msg=name)


def test_simulate_trajectories_draw_what_each_run_draws():
    from hybridtrack.engine.simulate import simulate_trajectories, simulate_trajectory

    schedule = Schedule.from_rows([("straight", 6), ("left_turn", 7, 3.0), ("right_turn", 5, 4.0)])
    seeds = [np.random.SeedSequence(7, spawn_key=(i,)) for i in range(3)]
    batch = simulate_trajectories(schedule, X0, 0.1, seeds=[np.random.default_rng(s) for s in seeds], noise_cov=NOISE)
    for s, b in zip(seeds, batch):
        single = simulate_trajectory(schedule, X0, 0.1, seed=np.random.default_rng(s), noise_cov=NOISE)
        np.testing.assert_allclose(b.states, single.states, **TOL)
        np.testing.assert_array_equal(b.segment, single.segment)
        assert b.layout == single.layout
    with pytest.raises(ValueError, match="seeds"):
        simulate_trajectories(schedule, X0, 0.1, seeds=[])


def test_seed001_experiment_batch_equals_the_runner(tmp_path):
    """experiments/seed001_adaptive.py: the batched arrays equal run_one's (small schedule, default and seed rule)."""
    import importlib.util
    from pathlib import Path

    from hybridtrack.apps.experiment.worker import run_seed

    path = Path(__file__).resolve().parents[2] / "experiments" / "seed001_adaptive.py"
    spec = importlib.util.spec_from_file_location("_seed001_batch_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for rule in (module.DEFAULT_RULE, module.SEED_RULE):
        parameters = module.EXPERIMENT.with_parameters(R=0.1, steps_scale=0.2, **rule)
        batched = module.batch_arrays(parameters, 3, 1)
        for i in range(3):
            row = module.run_one(i, np.random.default_rng(run_seed(1, i)), **parameters)
            for name, value in row.items():
                np.testing.assert_allclose(batched[name][i], value, **TOL, err_msg=name)


@pytest.mark.parametrize("bank_size, pruning", [(None, None), (3, "nearest_lower"), (4, "oldest")])
def test_unknown_change_batch_with_a_looped_test_equals_the_vectorized_one(bank_size, pruning):
    """A change-time test without a vectorized batch (the ChangeTimeTestBatch fallback) gives the same runs."""
    from hybridtrack.core.protocols import ChangeTimeTestBatch
    from hybridtrack_plugins.detectors.sprt_change import ChangeTimeSPRT

    class Looped(ChangeTimeSPRT):
        def batch(self, runs):
            return ChangeTimeTestBatch(self, runs)

    schedule = Schedule.from_rows([("straight", 15), ("right_turn", 20, 5.0)])
    sensor, z, times = batch_data(schedule, seed=3)
    kwargs = dict(modes=MODES, sensors=[sensor], tau=0.1, bank_size=bank_size, pruning=pruning)
    vectorized = UnknownChangeAdaptive(**kwargs, alpha=0.1, beta=0.1).run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), times=times)
    looped = UnknownChangeAdaptive(**kwargs, detector=Looped(0.1, 0.1)).run_batch({sensor.name: z}, Gaussian(X0, np.eye(4)), times=times)
    assert_runs_equal(vectorized, looped, ("means", "covs", "mode", "log_ratios", "bank_sizes", "signal"))
    for a, b in zip(vectorized, looped):
        assert a.changes == b.changes


def test_unknown_change_batch_with_a_nonlinear_mode_relinearizes_like_the_runs():
    """A run whose bank holds a nonlinear mode relinearizes all its filters at their means (as FilterBank does):
    switch-state-augmented modes, the turns refining their switch state (EKF)."""
    from hybridtrack.algorithms.switch_state import SwitchAugmented
    from hybridtrack_plugins.motion.linear_modes import LeftTurn, RightTurn, Straight

    schedule = Schedule.from_rows([("straight", 8), ("right_turn", 10, 5.0)])
    sensor, z, times = batch_data(schedule, runs=3)
    modes = [SwitchAugmented(Straight(noise_cov=NOISE)), SwitchAugmented(RightTurn(radius=5.0, noise_cov=NOISE), relinearize=True)]
    modes.append(SwitchAugmented(LeftTurn(radius=5.0, noise_cov=NOISE)))
    adaptive = UnknownChangeAdaptive(modes=modes, sensors=[sensor], tau=0.1, alpha=0.1, beta=0.1, estimator="ekf", bank_size=6)
    mean = np.concatenate([X0, X0])
    prior = Gaussian(mean, np.eye(8))
    batched = adaptive.run_batch({sensor.name: z}, prior, times=times)
    single = single_runs(adaptive, sensor, z, times, prior)
    assert_runs_equal(batched, single, ("means", "covs", "mode", "log_ratios", "bank_sizes"))


def test_campaign_benchmark_runs_small(tmp_path):
    """benchmarks/campaign.py at a tiny size: the agreed JSON layout (batched and per-run results checked equal inside)."""
    import importlib.util
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "campaign.py"
    spec = importlib.util.spec_from_file_location("_campaign_bench_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = tmp_path / "bench.json"
    module.main(["--json", str(out), "--runs", "2", "--steps-scale", "0.1", "--example1-runs", "2", "--clutter-runs", "0"])
    written = json.loads(out.read_text())
    assert set(written) == {"cases"} and len(written["cases"]) == 2
    for case in written["cases"]:
        assert set(case) == {"name", "batched_s", "per_run_s", "speedup"}
        assert case["batched_s"] > 0 and case["per_run_s"] > 0 and case["speedup"] == pytest.approx(case["per_run_s"] / case["batched_s"])
