"""Adaptive estimation: Algorithm 1 (known switching moments), Algorithm 3 repeated (unknown change time),
decentralized = centralized ratios, recording, parameter errors."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from hybridtrack import Gaussian, Schedule, TransitionBank
from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive, turn_bank
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.simulate import simulate
from hybridtrack_plugins.motion.linear_modes import RightTurn, Straight
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
MODES = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def example1(seed, sensors=None, turn=30):
    sensors = sensors or [PositionSensor(noise_cov=NOISE)]
    schedule = Schedule.from_rows([("straight", 20), ("right_turn", turn, 5.0)])
    return simulate(schedule, X0, 0.1, sensors, seed=seed, noise_cov=NOISE)


def test_turn_bank_is_the_2n_plus_1_hypotheses_of_seed_001():
    bank = turn_bank(1.0, 10.0, 10)
    assert len(bank) == 21 and bank[0][0] == "straight"
    assert [b[1]["radius"] for b in bank[1:11]] == pytest.approx(np.arange(1.0, 11.0))
    assert all(b[0] == "left_turn" for b in bank[1:11]) and all(b[0] == "right_turn" for b in bank[11:])


@pytest.mark.parametrize(
    "args, message",
    [((5.0, 1.0, 3), "r_min"), ((0.0, 1.0, 3), "r_min"), ((1.0, 2.0, 0), "n"), ((1.0, 2.0, 1), "n")],
)
def test_turn_bank_parameter_errors(args, message):
    with pytest.raises(ValueError, match=message):
        turn_bank(*args)


def test_parameter_errors_of_the_adaptive_estimators():
    sensors = [PositionSensor()]
    with pytest.raises(ValueError, match="modes"):
        UnknownChangeAdaptive(modes=[], sensors=sensors, tau=0.1)
    with pytest.raises(ValueError, match="modes"):
        UnknownChangeAdaptive(modes=["straight"], sensors=sensors, tau=0.1)
    with pytest.raises(ValueError, match="alpha"):
        UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, alpha=1.2)
    with pytest.raises(ValueError, match="alpha \\+ beta"):
        UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, alpha=0.5, beta=0.5)
    with pytest.raises(ValueError, match="bank_size"):
        UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, bank_size="all")
    with pytest.raises(ValueError, match="initial_mode"):
        UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, initial_mode=3)
    with pytest.raises(TypeError, match="detector.*ChangeTimeTest.*lacks add, keep, log_ratios, prune"):
        UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, detector="signal_function")
    with pytest.raises(TypeError, match="detector.*HypothesisTest.*lacks hypotheses, decided, upper, lower"):
        KnownSwitchAdaptive(sensors=sensors, tau=0.1, detector="signal_function")
    with pytest.raises(ValueError, match="modes"):
        KnownSwitchAdaptive(modes=[], sensors=sensors, tau=0.1)
    with pytest.raises(ValueError, match="r_min"):
        KnownSwitchAdaptive(r_min=10.0, r_max=1.0, sensors=sensors, tau=0.1)
    with pytest.raises(ValueError, match="beta"):
        KnownSwitchAdaptive(sensors=sensors, tau=0.1, beta=0.0)


def test_filter_bank_grows_and_shrinks_and_steps_like_the_pipeline_filter():
    from hybridtrack_plugins.filters.kalman import KalmanFilter
    from hybridtrack_plugins.motion.linear_modes import LeftTurn

    layout = ("x", "vx", "y", "vy")
    sensors = [PositionSensor()]
    bank = FilterBank(KalmanFilter(), layout, sensors)
    models = [Straight(), LeftTurn(radius=3.0), RightTurn(radius=5.0)]
    bank.start(X0, np.eye(4), models, X0)
    bank.step(0.1, np.array([[0.1, 0.3]]))
    before = bank.means.copy(), bank.covs.copy()
    bank.take([2, 0])
    assert bank.models == [models[2], models[0]]
    np.testing.assert_array_equal(bank.means, before[0][[2, 0]])
    np.testing.assert_array_equal(bank.covs, before[1][[2, 0]])
    copy = LeftTurn(radius=3.0)
    added = bank.add([1], [copy], bank.means[1])  # a copy of the straight filter
    assert len(bank) == 3 and added.tolist() == [2] and bank.models[2] is copy
    np.testing.assert_array_equal(bank.means[2], bank.means[1])
    scores = bank.step(0.1, np.array([[0.2, 0.5]]))
    assert scores.nis.shape == (3,) and scores.m.tolist() == [2, 2, 2] and bank.node_scores() is None
    # the same filters stepped directly
    kf = KalmanFilter()
    state = kf.initialize(np.stack([X0] * 3), np.stack([np.eye(4)] * 3))
    state, _ = kf.update(
        kf.predict(state, TransitionBank.stack([m.transition(0.1, X0) for m in models])), np.array([0.1, 0.3]), sensors, layout
    )
    state = kf.take(state, [2, 0, 0])
    x_s = kf.mean(state)[2]
    stacked = TransitionBank.stack(
        [models[2].transition(0.1, X0), models[0].transition(0.1, X0), LeftTurn(radius=3.0).transition(0.1, x_s)]
    )
    state, reference = kf.update(kf.predict(state, stacked), np.array([0.2, 0.5]), sensors, layout)
    np.testing.assert_allclose(bank.means, kf.mean(state), rtol=0, atol=1e-12)
    np.testing.assert_allclose(scores.loglik, reference.loglik, rtol=0, atol=1e-12)


def test_filter_bank_of_two_runs_keeps_each_run_s_filters_together_and_updates_by_missing_pattern():
    from hybridtrack_plugins.filters.kalman import KalmanFilter
    from hybridtrack_plugins.motion.linear_modes import LeftTurn

    layout = ("x", "vx", "y", "vy")
    sensors = [PositionSensor()]
    models = [Straight(), LeftTurn(radius=3.0)]
    bank = FilterBank(KalmanFilter(), layout, sensors)
    starts = np.stack([X0, X0, X0 + 0.1, X0 + 0.1])
    bank.start(starts, np.eye(4), models * 2, starts, run=[0, 0, 1, 1])
    added = bank.add([0, 2], [RightTurn(radius=5.0)] * 2, bank.means[[0, 2]])
    assert bank.run.tolist() == [0, 0, 0, 1, 1, 1] and added.tolist() == [2, 5]
    assert bank.offsets.tolist() == [0, 3] and bank.sizes.tolist() == [3, 3]
    z = np.array([[0.1, np.nan], [0.2, 0.4]])  # run 0 misses y: two updates, one per missing pattern
    scores = bank.step(np.array([0.1, 0.2]), z)
    assert scores.m.tolist() == [1, 1, 1, 2, 2, 2] and scores.innovation is None
    assert [runs.tolist() for runs, _ in scores.updates] == [[1], [0]]  # one update per pattern, in pattern order
    for r, rows in enumerate(([0, 1, 2], [3, 4, 5])):  # each run alone gives the same filters
        alone = FilterBank(KalmanFilter(), layout, sensors)
        alone.start(X0 + 0.1 * r, np.eye(4), models, X0 + 0.1 * r)
        alone.add([0], [RightTurn(radius=5.0)], alone.means[0])
        single = alone.step(0.1 * (r + 1), z[r : r + 1])
        np.testing.assert_allclose(bank.means[rows], alone.means, rtol=0, atol=1e-12)
        np.testing.assert_allclose(scores.loglik[rows], single.loglik, rtol=0, atol=1e-12)


def test_a_restarted_filter_bank_keeps_its_equal_transition_object():
    """The multiple-model estimators re-start their banks every step: equal transitions keep the bank object
    (the estimator's per-bank caches), a changed switch state of a turn gives a new one."""
    from hybridtrack_plugins.filters.kalman import KalmanFilter
    from hybridtrack_plugins.motion.linear_modes import LeftTurn

    bank = FilterBank(KalmanFilter(), ("x", "vx", "y", "vy"), [PositionSensor()])
    models = [Straight(), LeftTurn(radius=3.0)]
    bank.start(X0, np.eye(4), models, X0)
    first = bank.transitions(0.1)
    bank.start(X0 + 1.0, np.eye(4), models, X0)
    assert bank.transitions(0.1) is first
    bank.start(X0, np.eye(4), models, X0 + 1.0)
    assert bank.transitions(0.1) is not first


def test_example1_detects_the_right_turn():
    adaptive = UnknownChangeAdaptive(modes=MODES, sensors=[PositionSensor(noise_cov=NOISE)], tau=0.1, alpha=0.1, beta=0.1)
    detected = 0
    for seed in range(6):
        truth, z = example1(seed)
        run = adaptive.run(z, Gaussian(X0, np.eye(4)))
        change = run.first_change(after=20)
        assert not [c for c in run.changes if c.step <= 20]  # no false alarm on the straight part
        if change is not None and change.mode == "right_turn_r5":
            detected += 1
            assert (run.mode[change.step :] == 1).all()  # the estimate now follows the right-turn filter
        assert run.bank_sizes[0] == 1 and run.bank_sizes.max() <= 1 + 2 * 50
    assert detected >= 5


def test_bank_is_bounded_by_pruning_and_by_algorithm4():
    sensors = [PositionSensor(noise_cov=NOISE)]
    _, z = example1(1)
    small = UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, alpha=0.1, beta=0.1, bank_size=4, pruning="nearest_lower").run(
        z, Gaussian(X0, np.eye(4))
    )
    assert small.bank_sizes.max() <= 1 + 4 + 2  # filter 0, the kept entries, this step's new pair
    alg4 = UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, alpha=0.1, beta=0.1, bank_size="algorithm4")
    run = alg4.run(z, Gaussian(X0, np.eye(4)))
    assert run.bank_limit % 2 == 0 and 2 <= run.bank_limit <= 100
    assert run.bank_sizes.max() <= 1 + run.bank_limit + 2


def test_decentralized_ratios_and_signal_function_equal_the_centralized_ones():
    sensors = [
        PositionSensor(name="a", noise_cov=NOISE),
        PositionSensor(name="b", components="x", noise_cov=[[0.04]]),
        PositionSensor(name="c", components="y", noise_cov=[[0.02]]),
    ]
    _, z = example1(3, sensors)
    runs = {
        name: UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, alpha=0.1, beta=0.1, estimator=name).run(
            z, Gaussian(X0, np.eye(4))
        )
        for name in ("kalman", "decentralized")
    }
    central, decentral = runs["kalman"], runs["decentralized"]
    assert decentral.node_log_ratios.shape == (51, 3, 3) and central.node_log_ratios is None
    finite = np.isfinite(central.log_ratios)
    assert finite.sum() > 50
    for node in range(3):
        assert np.array_equal(np.isfinite(decentral.node_log_ratios[:, node]), finite)
        assert np.max(np.abs(decentral.node_log_ratios[:, node][finite] - central.log_ratios[finite])) <= 1e-9
        assert np.max(np.abs(decentral.node_signal[:, node] - central.signal)) <= 1e-9
    assert [c.step for c in decentral.changes] == [c.step for c in central.changes]


def test_known_switch_identifies_each_segment():
    sensors = [PositionSensor(noise_cov=0.01 * np.eye(2))]
    q = np.diag([1e-3, 1e-3])
    schedule = Schedule.from_rows([("left_turn", 50, 3.0), ("right_turn", 50, 5.0), ("straight", 50)])
    truth, z = simulate(schedule, X0, 0.1, sensors, seed=0, noise_cov=q)
    adaptive = KnownSwitchAdaptive(sensors=sensors, tau=0.1, noise_cov=q, alpha=0.01, beta=0.01)
    run = adaptive.run(z, Gaussian(X0, np.eye(4)), schedule)
    assert [s.mode for s in run.segments] == ["left_turn_r3", "right_turn_r5", "straight"]
    assert all(s.decision_step is not None and 0 < s.delay <= 50 for s in run.segments)
    assert run.means.shape == (151, 4) and len(run.decisions) == 3
    from hybridtrack.algorithms.known_modes import run_known_modes

    error = np.sqrt(np.mean(np.sum((run.means[:, [0, 2]] - truth.positions) ** 2, axis=1)))
    known = run_known_modes(
        schedule, estimator="kalman", sensors=sensors, measurements=z, prior=Gaussian(X0, np.eye(4)), tau=0.1, noise_cov=q
    )
    optimal = np.sqrt(np.mean(np.sum((known.means[:, [0, 2]] - truth.positions) ** 2, axis=1)))
    assert optimal < error < 1.0  # as in seed 001 Table 2: the optimal KF beats the adaptive one


def test_known_switch_can_follow_the_most_likely_hypothesis_before_the_decision():
    """follow="most_likely": before the SPRT decides, the estimate is the filter with the largest Σ ℓ among the
    hypotheses in play (the one with a positive margin λ_i = L_i − max_j L_j); the decisions of the first segment
    are the seed's; over noisy runs the error is smaller than following the previous segment's hypothesis."""
    sensors = [PositionSensor(noise_cov=0.5 * np.eye(2))]
    q = np.diag([1e-3, 1e-3])
    schedule = Schedule.from_rows([("left_turn", 40, 3.0), ("right_turn", 40, 5.0), ("straight", 40)])
    errors = {"previous": 0.0, "most_likely": 0.0}
    for seed in range(4):
        truth, z = simulate(schedule, X0, 0.1, sensors, seed=seed, noise_cov=q)
        runs = {}
        for follow in errors:
            adaptive = KnownSwitchAdaptive(sensors=sensors, tau=0.1, noise_cov=q, n=4, r_min=2.0, r_max=5.0, follow=follow)
            runs[follow] = run = adaptive.run(z, Gaussian(X0, np.eye(4)), schedule)
            errors[follow] += float(np.sum((run.means[1:, [0, 2]] - truth.positions[1:]) ** 2))
        run, seed_rule = runs["most_likely"], runs["previous"]
        assert run.segments[0].decision_step == seed_rule.segments[0].decision_step
        first = run.segments[0].decision_step or 40
        for step in range(1, first):
            ratios = run.log_ratios[step]
            assert run.mode[step] == int(np.nanargmax(ratios)) and ratios[run.mode[step]] >= 0
        assert (seed_rule.mode[1:first] == 0).all()  # the seed's rule: straight until the first decision
    assert errors["most_likely"] < errors["previous"]
    with pytest.raises(ValueError, match="follow"):
        KnownSwitchAdaptive(sensors=sensors, tau=0.1, follow="best")


def test_recording_of_an_adaptive_run(tmp_path):
    rerun = pytest.importorskip("rerun")
    from hybridtrack.recording import RerunRecorder

    path = tmp_path / "adaptive.rrd"
    _, z = example1(0)
    adaptive = UnknownChangeAdaptive(modes=MODES, sensors=[PositionSensor(noise_cov=NOISE)], tau=0.1, alpha=0.1, beta=0.1, name="ex1")
    with RerunRecorder(path, {"test": "adaptive"}) as recorder:
        run = adaptive.run(z, Gaussian(X0, np.eye(4)), recorder=recorder)
    recording = rerun.recording.load_recording(str(path)) if hasattr(rerun, "recording") else None
    assert path.stat().st_size > 0 and run.decisions
    if recording is not None:
        paths = {str(c.entity_path) for c in recording.schema().component_columns()}
        for entity in (
            "/world/estimate/ex1",
            "/detector/sprt_unknown_change/log_ratio/right_turn_r5",
            "/detector/sprt_unknown_change/upper",
            "/detector/signal_function/signal",
            "/estimator/ex1/bank_size",
        ):
            assert entity in paths, (entity, sorted(paths))


def test_example1_script_runs_small(tmp_path):
    spec = importlib.util.spec_from_file_location("example1", EXAMPLES / "example1_unknown_change.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    summary = module.main(["--out", str(tmp_path / "e.rrd"), "--turn-steps", "20", "--bank-size", "8", "--pruning", "nearest_lower"])
    assert summary["steps"] == 41 and summary["max_bank_size"] <= 11


def test_a_growing_bank_through_a_long_gap_warns_and_is_pruned():
    sensors = [PositionSensor(noise_cov=NOISE)]
    _, z = example1(2, turn=200)
    gap = {name: values.copy() for name, values in z.items()}
    for values in gap.values():
        values[25:200] = np.nan  # a long gap: nothing can decide, the bank grows by 2 filters a step
    adaptive = UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, alpha=0.05, beta=0.05, max_bank_size=60)
    with pytest.warns(RuntimeWarning, match="growing bank reached 62 alternative filters at step .*max_bank_size = 60"):
        run = adaptive.run(gap, Gaussian(X0, np.eye(4)))
    assert run.bank_sizes.max() <= 1 + 60 + 2
    with pytest.raises(ValueError, match="max_bank_size"):
        UnknownChangeAdaptive(modes=MODES, sensors=sensors, tau=0.1, max_bank_size=0)
