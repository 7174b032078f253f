"""Hostile inputs at the door of the Python API (issue 24, item 3): each a clear error naming the input, what was
expected and what was got — or, where it can be, handled (a sensor named ``file`` in an NPZ, the truth given both
to the simulator's and the pipeline's recorder).

Each case is refused where the input is owned: the motion model (``radius``, ``tau``), the prior's door of the
pipeline and the algorithms (:func:`hybridtrack.engine.batch.prior_arrays`), the estimators' ``initialize``, the
schedule, the TMA problem, the pipeline's composition (detectors needing an algorithm's bank).
"""

import re
import warnings

import numpy as np
import pytest

from hybridtrack import Gaussian, Pipeline, RerunRecorder, simulate
from hybridtrack.algorithms.known_modes import KnownModes
from hybridtrack.algorithms.multiple_model import MultipleModelEstimator
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.core.interfaces import Detector
from hybridtrack.core.plugins import resolve
from hybridtrack.engine.schedule import Schedule
from hybridtrack.io.measurement_files import read_measurement_file, write_npz
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack_plugins.motion.linear_modes import ConstantAcceleration, LeftTurn, Stop, Straight
from hybridtrack_plugins.sensors.position import PositionSensor
from hybridtrack_plugins.solvers.levenberg_marquardt import LevenbergMarquardt
from hybridtrack_plugins.solvers.observer import example_problem
from hybridtrack_plugins.solvers.tma_model import BearingsBatch, BearingsProblem

SENSORS = [PositionSensor(name="a")]
X0 = np.array([0.0, 0.0, 0.0, 2.0])
PRIOR = Gaussian(X0, np.eye(4))
SCHEDULE = Schedule.from_rows([("straight", 10), ("left_turn", 10, 3.0)])


@pytest.fixture(scope="module")
def measured():
    """(truth, z) of SCHEDULE, τ = 0.1, sensor 'a'."""
    return simulate(SCHEDULE, X0, 0.1, SENSORS, seed=1)


def pipeline(z, **options):
    kwargs = dict(models=["straight", ("left_turn", {"radius": 3.0})], estimator="kalman", sensors=SENSORS, measurements=z, prior=PRIOR)
    return Pipeline(**{"tau": 0.1, **kwargs, **options})


# --------------------------------------------------------------------------- 1. tau and radius beyond float64


@pytest.mark.parametrize("mode", ["left_turn", "right_turn"])
def test_a_vanishing_turn_radius_is_refused_naming_radius_and_the_range(mode):
    with pytest.raises(ValueError, match=r"^radius: expected a turn radius of at least 1e-06 m .*got 1e-300$"):
        resolve("motion_model", (mode, {"radius": 1e-300}))


@pytest.mark.parametrize(
    "model, bound",
    [
        (Straight(), r"1e\+75"),
        (Straight(noise_density=1.0), r"1\.44e\+50"),  # q τ³/3 ≤ 1e150
        (ConstantAcceleration(), r"4\.47e\+37"),
        (Stop(noise_density=1.0), r"1e\+150"),
        (LeftTurn(radius=3.0, noise_density=1.0), r"1\.44e\+50"),
    ],
    ids=["straight", "straight_density", "constant_acceleration", "stop_density", "left_turn_density"],
)
def test_a_step_whose_transition_overflows_is_refused_naming_tau_and_its_usable_range(model, bound):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy overflow warning on the way
        with pytest.raises(
            ValueError, match=rf"^tau: a step of 1e\+300 s gives the '{model.name}' transition .*; expected tau ≤ {bound} s"
        ):
            model.transition(1e300, np.zeros(model.state_dim))


@pytest.mark.parametrize(
    "model, order, bound", [(Straight(noise_density=1.0), 2, r"1\.95e-108"), (ConstantAcceleration(noise_density=1.0), 3, r"3\.42e-65")]
)
def test_a_step_too_short_for_the_noise_density_names_the_step_and_the_shortest_usable(model, order, bound):
    """Q(Δt) = q Δt³/3 … underflows: the Cholesky factor G(Δt) was a raw LinAlgError."""
    with pytest.raises(
        ValueError,
        match=rf"^dt: a step Δt \(tau\) of 1e-300 s is too short for white noise of order {order}: .*expected steps ≥ {bound} s$",
    ):
        model.transition(1e-300, np.zeros(model.state_dim))


def test_a_tau_beyond_float64_is_named_through_the_pipeline_and_the_simulator(measured):
    _, z = measured
    match = r"^tau: a step of 1e\+300 s gives the 'straight' transition F\[0, 1\] = 1e\+300 .*expected tau ≤ 1e\+75 s"
    with pytest.raises(ValueError, match=match):
        pipeline(z, tau=1e300).run()
    with pytest.raises(ValueError, match=match):
        simulate(Schedule.from_rows([("straight", 3)]), X0, 1e300, SENSORS, seed=1)


def test_a_turn_rate_beyond_float64_names_the_radius_the_speed_and_the_usable_radius():
    with pytest.raises(
        ValueError, match=r"^radius: a turn of radius 1\.0 m at the switch speed 1e\+80 m/s .*expected radius ≥ \|v\|/1e\+75 = 1e\+05 m"
    ):
        LeftTurn(radius=1.0).transition(0.1, np.array([0.0, 1e80, 0.0, 0.0]))
    with pytest.raises(ValueError, match=r"^radius: a turn of radius 1\.0 m"):  # the vectorized bank, one bad row
        LeftTurn(radius=1.0).transition_bank(0.1, np.array([[0.0, 1.0, 0.0, 0.0], [0.0, 1e80, 0.0, 0.0]]))


# --------------------------------------------------------------------------- 2. a radius that is not a number of metres


@pytest.mark.parametrize("radius", ["x", None, [1.0, 2.0], float("nan"), float("inf"), -1.0, 0, True], ids=repr)
def test_a_radius_that_is_not_a_positive_number_of_metres_is_named(radius):
    with pytest.raises(
        ValueError, match=rf"^radius: expected a finite number of metres > 0 \(the turn radius\), got {re.escape(repr(radius))}$"
    ):
        resolve("motion_model", ("left_turn", {"radius": radius}))


@pytest.mark.parametrize("radius", ["x", [1.0], True, float("nan")], ids=repr)
def test_a_schedule_row_radius_that_is_not_a_number_is_named(radius):
    with pytest.raises(
        ValueError, match=rf"^schedule row 0: radius: expected a positive finite number \(metres\), got {re.escape(repr(radius))}$"
    ):
        Schedule.from_rows([("left_turn", 3, radius)])


# --------------------------------------------------------------------------- 3. a prior of the wrong kind

PRIOR_EXPECTED = r"^prior: expected a hybridtrack\.Gaussian, e\.g\. Gaussian\(np\.array\(\[x, vx, y, vy\]\).*; got "


@pytest.mark.parametrize(
    "prior, got",
    [
        ({"mean": X0, "cov": np.eye(4)}, r"a dict with keys \['cov', 'mean'\]"),
        (X0, r"an array of shape \(4,\) \(a bare mean\?"),
        ([0.0, 0.0, 0.0, 2.0], r"a sequence of 4 numbers \(a bare mean\?"),
        ("prior", r"a str"),
    ],
    ids=["dict", "array", "list", "str"],
)
def test_a_prior_that_is_not_a_gaussian_is_a_type_error_showing_how_to_build_one(measured, prior, got):
    _, z = measured
    with pytest.raises(TypeError, match=PRIOR_EXPECTED + got):
        pipeline(z, prior=prior)
    with pytest.raises(TypeError, match=PRIOR_EXPECTED + got):
        Pipeline.run_batch({"a": z["a"][None]}, prior, models=["straight"], estimator="kalman", sensors=SENSORS, tau=0.1)


def test_an_algorithm_given_a_dict_prior_is_a_type_error_naming_the_prior(measured):
    _, z = measured
    with pytest.raises(TypeError, match=PRIOR_EXPECTED + "a dict"):
        UnknownChangeAdaptive(modes=["straight", ("left_turn", {"radius": 3.0})], sensors=SENSORS, tau=0.1).run(z, {"mean": X0})
    with pytest.raises(TypeError, match=PRIOR_EXPECTED + "an array"):
        MultipleModelEstimator(["straight", ("left_turn", {"radius": 3.0})], sojourn=1.0, sensors=SENSORS, tau=0.1).run(z, X0)


@pytest.mark.parametrize("name", ["kalman", "srif", "particle"])
@pytest.mark.parametrize("value", [PRIOR, {"mean": X0[None]}], ids=["gaussian", "dict"])
def test_an_estimator_initialized_with_a_prior_object_says_to_pass_its_arrays(name, value):
    with pytest.raises(
        TypeError,
        match=r"^prior: initialize\(mean, cov\) takes the bank's prior as two arrays.*initialize\(g\.mean\[None\], g\.cov\[None\]\)",
    ):
        resolve("estimator", name).initialize(value, np.eye(4)[None])


@pytest.mark.parametrize("x0, got", [(PRIOR, "a Gaussian"), ({"mean": X0}, r"a dict with keys \['mean'\]")], ids=["gaussian", "dict"])
def test_simulate_given_a_prior_for_x0_says_to_pass_a_state(x0, got):
    with pytest.raises(
        TypeError, match=rf"^x0: simulate starts from a state, an array \(n,\) .*not from a prior; got {got}: pass its mean"
    ):
        simulate(SCHEDULE, x0, 0.1, SENSORS, seed=1)


# --------------------------------------------------------------------------- 4. a diffuse prior


def test_a_diffuse_prior_is_refused_with_the_supported_range(measured):
    """1e16·I made the covariance-form filters' S singular (two sensors measuring x) or their first update silently
    wrong (one sensor): refused at the door of the pipeline and the algorithms."""
    _, z = measured
    diffuse = Gaussian(X0, 1e16 * np.eye(4))
    match = (
        r"^prior: covariance standard deviations up to 1e\+07 \(m, m/s\) are supported, got 1e\+08 \(variance 1e\+16 of state component 0\)"
    )
    with pytest.raises(ValueError, match=match):
        pipeline(z, prior=diffuse)
    with pytest.raises(ValueError, match=match):
        KnownModes(schedule=SCHEDULE, sensors=SENSORS, tau=0.1).run(z, diffuse)
    with pytest.raises(
        ValueError, match=r"^prior: covariance standard deviations up to 1e\+07 .*got 3e\+07 \(variance 9e\+14 of state component 3\)"
    ):
        pipeline(z, prior=(X0, np.diag([1.0, 1.0, 1.0, 9e14])))


def test_a_prior_at_the_supported_limit_runs(measured):
    _, z = measured
    result = pipeline(z, prior=Gaussian(X0, 1e14 * np.eye(4))).run()
    assert np.isfinite(result.means).all()


# --------------------------------------------------------------------------- 5. no step


def test_measurements_without_a_step_are_refused_naming_the_sensor():
    empty = {"a": np.zeros((0, 2))}
    with pytest.raises(ValueError, match=r"^measurements: expected at least one step .*got 0 steps \('a' \(0, 2\)\)$"):
        pipeline(empty)
    with pytest.raises(ValueError, match=r"^measurements: expected at least one step .*got 0 steps"):
        pipeline(empty, tau=None, times=[])
    with pytest.raises(
        ValueError,
        match=r"^measurements: expected at least one run and one step, got \(runs, K\+1\) = \(2, 0\) \(sensor shapes 'a' \(2, 0, 2\)\)",
    ):
        Pipeline.run_batch({"a": np.zeros((2, 0, 2))}, PRIOR, models=["straight"], estimator="kalman", sensors=SENSORS, tau=0.1)
    with pytest.raises(ValueError, match=r"^measurements: expected at least one run and one step, got \(runs, K\+1\) = \(1, 0\)"):
        UnknownChangeAdaptive(modes=["straight", ("left_turn", {"radius": 3.0})], sensors=SENSORS, tau=0.1).run(empty, PRIOR)


# --------------------------------------------------------------------------- 6. runs of different lengths


def test_batched_runs_of_different_lengths_name_each_run_and_its_length():
    runs = [np.zeros((10, 2)), np.zeros((7, 2)), np.zeros((10, 2))]
    match = r"^measurements\['a'\]: the runs of a batch need the same number of steps \(K\+1\), got run 0: 10 steps, run 1: 7 steps, run 2: 10 steps;"
    with pytest.raises(ValueError, match=match):
        Pipeline.run_batch({"a": runs}, PRIOR, models=["straight"], estimator="kalman", sensors=SENSORS, tau=0.1)
    with pytest.raises(ValueError, match=match):
        MultipleModelEstimator(["straight", ("left_turn", {"radius": 3.0})], sojourn=1.0, sensors=SENSORS, tau=0.1).run_batch(
            {"a": runs}, PRIOR
        )


def test_batched_runs_of_one_length_given_as_a_list_still_run():
    runs = [np.zeros((5, 2)), np.ones((5, 2))]
    results = Pipeline.run_batch({"a": runs}, PRIOR, models=["straight"], estimator="kalman", sensors=SENSORS, tau=0.1)
    assert len(results) == 2 and results[1].steps == 5


# --------------------------------------------------------------------------- 7. a sensor named like np.savez's parameters


@pytest.mark.parametrize("times", [None, [0.0, 0.5, 2.0]], ids=["steps", "times"])
def test_a_sensor_named_file_is_written_and_read_back_identically(tmp_path, times):
    z = {"file": np.array([[1.0, 2.0], [np.nan, np.nan], [3.0, 4.0]]), "allow_pickle": np.array([[0.5], [1.5], [2.5]])}
    path = tmp_path / "z.npz"
    write_npz(path, z, times=times)
    measurements, read_times = read_measurement_file(path)
    assert list(measurements) == ["file", "allow_pickle"]
    for name, value in z.items():
        np.testing.assert_array_equal(measurements[name], value)
    assert (read_times is None) if times is None else np.array_equal(read_times, times)
    with np.load(path) as archive:  # a plain NPZ for numpy too
        np.testing.assert_array_equal(archive["file"], z["file"])


def test_write_npz_adds_the_suffix_as_numpy_does(tmp_path):
    write_npz(tmp_path / "z", {"file": np.ones((2, 1))})
    np.testing.assert_array_equal(read_measurement_file(tmp_path / "z.npz").measurements["file"], np.ones((2, 1)))


# --------------------------------------------------------------------------- 8. TMA observer positions


def test_observer_positions_beyond_the_usable_range_are_named():
    p = example_problem()
    match = r"^observer: observer positions must be finite with \|coordinate\| ≤ 1e\+09 m, got 1e\+300 m \(position 0, x\)"
    with pytest.raises(ValueError, match=match):
        LevenbergMarquardt().solve(BearingsProblem(p.times, p.bearings, p.observer + [1e300, 0.0], sigma=p.sigma, initial=p.initial))
    observers = np.stack([p.observer, p.observer * [1.0, 1e12]])
    with pytest.raises(ValueError, match=r"^observer: .*≤ 1e\+09 m, got -?[0-9.]+e\+1[0-9] m \(problem 1, position \d+, y\)"):
        BearingsBatch(p.times, np.stack([p.bearings, p.bearings]), observers, sigma=p.sigma)


def test_observer_positions_within_the_range_still_solve():
    p = example_problem()
    shifted = BearingsProblem(p.times, p.bearings, p.observer + [5e8, -5e8], sigma=p.sigma, initial=p.initial + [5e8, -5e8, 0.0, 0.0])
    assert LevenbergMarquardt().solve(shifted).converged


# --------------------------------------------------------------------------- 9. a turn row without a radius


def test_a_turn_row_without_a_radius_is_refused_naming_the_row_and_the_key():
    schedule = Schedule.from_rows([("straight", 10), ("left_turn", 8)])
    match = r"^schedule row 1 \(left_turn, 8 steps from step 10\): no radius; .*\(key 'radius', metres > 0\)"
    with pytest.raises(ValueError, match=match):
        simulate(schedule, X0, 0.1, SENSORS, seed=1)
    with pytest.raises(ValueError, match=match):
        KnownModes(schedule=schedule, sensors=SENSORS, tau=0.1)
    with pytest.raises(ValueError, match=r"^schedule row 0 \(right_turn, 4 steps from step 0\): no radius"):
        simulate(Schedule.from_rows([{"mode": "right_turn", "steps": 4}]), X0, 0.1, SENSORS, seed=1)


# --------------------------------------------------------------------------- 10. detectors needing an algorithm's bank


def test_detectors_declare_the_bank_they_need():
    assert Detector.requires_bank_management is None
    assert resolve("detector", "glr").requires_bank_management is None
    assert resolve("detector", "sprt_unknown_change").requires_bank_management == "unknown_change"


@pytest.mark.parametrize(
    "detector", ["sprt_unknown_change", ("dynamic_threshold", {"detector": "sprt_unknown_change"})], ids=["sprt_unknown_change", "wrapped"]
)
def test_a_pipeline_refuses_a_change_time_test_and_names_the_algorithm(measured, detector):
    _, z = measured
    with pytest.raises(
        ValueError,
        match=r"^detectors: '(sprt_unknown_change|dynamic_threshold)' .*needs the bank management of the algorithm 'unknown_change'",
    ):
        pipeline(z, detectors=[detector])


def test_the_named_algorithm_takes_the_refused_detector(measured):
    _, z = measured
    algorithm = resolve(
        "algorithm", ("unknown_change", {"modes": ["straight", ("left_turn", {"radius": 3.0})], "sensors": SENSORS, "tau": 0.1})
    )
    assert algorithm.run(z, PRIOR).means.shape[0] == z["a"].shape[0]


def test_the_pairwise_sprt_still_runs_on_a_fixed_bank(measured):
    """Seed 001's rule (5) is a test over a fixed bank (Algorithm 1 re-creates the bank only at known switches)."""
    _, z = measured
    assert pipeline(z, detectors=["sprt_pairwise"]).run().decisions


# --------------------------------------------------------------------------- 11. the truth logged twice


def test_the_truth_given_to_the_simulator_and_the_pipelines_is_recorded_once(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    path = tmp_path / "run.rrd"
    with RerunRecorder(path, {"seed": 1}) as recorder:
        truth, z = simulate(SCHEDULE, X0, 0.1, SENSORS, seed=1, recorder=recorder)
        pipeline(z, recorder=recorder, truth=truth, record_every=7).run()  # streamed in chunks
        pipeline(z, recorder=recorder, truth=truth, filter_names=["s", "l"], record_measurements=False).run()
    steps, positions = RecordingFile(path).points("world/truth")
    assert steps.tolist() == list(range(truth.states.shape[0]))
    np.testing.assert_allclose(positions, truth.positions, rtol=1e-6)  # stored as float32


def test_a_truth_logged_only_by_the_pipeline_is_recorded_whole(tmp_path, monkeypatch, measured):
    monkeypatch.setenv("HOME", str(tmp_path))
    truth, z = measured
    path = tmp_path / "run.rrd"
    with RerunRecorder(path, {"seed": 1}) as recorder:
        pipeline(z, recorder=recorder, truth=truth, record_every=6).run()
    steps, _ = RecordingFile(path).points("world/truth")
    assert steps.tolist() == list(range(truth.states.shape[0]))
