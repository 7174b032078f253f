"""R runs together equal R runs alone, to 1e-12: one parametrized check over every registered estimator,
detector (through Pipeline.run_batch) and algorithm (its run_batch), with irregular per-run times, per-run priors
and NaN components; a batched run's recording equals the run's own.  The algorithms' own variants (follow rules,
switch estimates, pruning, IMM/GPB × estimators) are in tests/algorithms/test_*_batch.py."""

import copy

import numpy as np
import pytest

from hybridtrack import Decision, Detector, DetectorStep, Gaussian, Schedule
from hybridtrack.core.interfaces import Innovation
from hybridtrack.core.plugins import get_registry
from hybridtrack.core.protocols import Association, ClutterInnovation
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import RerunRecorder
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack.testing import build_example, check_algorithm_batch
from hybridtrack_plugins.sensors.position import PositionSensor

RUNS, STEPS = 3, 24
SENSORS = [PositionSensor(name="a"), PositionSensor(name="b", components="x", noise_cov=[[0.04]])]
MODELS = ["straight", ("left_turn", {"radius": 3.0, "noise_cov": np.diag([1e-3, 1e-3])})]
ESTIMATORS = [e for e in get_registry().entries() if e.kind == "estimator"]
DETECTORS = [e for e in get_registry().entries() if e.kind == "detector"]
ALGORITHMS = [e for e in get_registry().entries() if e.kind == "algorithm"]
TOL = {"rtol": 1e-12, "atol": 1e-12}


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


def assert_same(batched, single):
    for field in ("times", "means", "covs", "nis", "loglik", "innovations"):
        np.testing.assert_allclose(getattr(batched, field), getattr(single, field), **TOL, err_msg=field)
    assert batched.layout == single.layout and batched.filters == single.filters
    assert batched.statistics.keys() == single.statistics.keys()
    for label, series in single.statistics.items():
        assert batched.statistics[label].keys() == series.keys()
        for key, values in series.items():
            np.testing.assert_allclose(batched.statistics[label][key], values, **TOL, err_msg=f"{label}/{key}")
    assert [(d.step, d.detector, d.mode, d.time) for d in batched.decisions] == [
        (d.step, d.detector, d.mode, d.time) for d in single.decisions
    ]
    for a, b in zip(batched.decisions, single.decisions):
        np.testing.assert_allclose(a.statistic, b.statistic, **TOL)


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


@pytest.mark.parametrize("entry", ESTIMATORS + DETECTORS + ALGORITHMS, ids=lambda e: f"{e.kind}:{e.name}")
def test_runs_together_equal_runs_alone(entry):
    """The one batch-equivalence check over every registered estimator, detector and algorithm: R runs in one
    batch equal each run alone to 1e-12 (per-run irregular times, per-run priors, missing components).
    Estimators and detectors run through the Pipeline; an algorithm through its own run_batch
    (:func:`hybridtrack.testing.check_algorithm_batch`, which compares times, means, covs, mode and decisions)."""
    if entry.kind == "algorithm":
        if not check_algorithm_batch(entry.factory):
            pytest.skip(f"algorithm {entry.name!r} has no run_batch")
        return
    found = pipeline_runs(entry)
    if found is None:
        pytest.skip(f"the pipeline does not run {entry.kind} {entry.name!r} on this scenario")
    batched, alone = found
    assert len(batched) == RUNS
    for b, s in zip(batched, alone):
        assert_same(b, s)
        if entry.kind == "detector":
            assert s.statistics, "the detector reported nothing"


def test_batch_with_shared_times_prior_and_a_nonlinear_model():
    z, _, _ = batch_data()
    prior = Gaussian(np.array([0.0, 0.0, 0.0, 2.0, 0.1]), np.eye(5))  # the ship layout (x, y, vx, vy, ω)
    options = {"models": ["ship_turn", ("ship_turn", {"sigma_rate": 1e-2})], "sensors": SENSORS, "estimator": "ekf", "tau": 0.1}
    options["filter_names"] = ["slow", "fast"]
    singles = [Pipeline(measurements={n: a[r] for n, a in z.items()}, prior=prior, **options).run() for r in range(RUNS)]
    batched = Pipeline.run_batch(z, prior, **options)
    for b, s in zip(batched, singles):
        assert_same(b, s)


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
    assert_same(batched[1], pipeline.run())
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


@pytest.mark.parametrize(("window", "calibration"), [(None, "normal"), (None, "chi2"), (3, "normal")])
def test_vectorized_signal_function_and_a_third_party_detector_decide_as_per_run(window, calibration):
    z, times, prior = batch_data()
    parameters = {"window": window, "alpha": 0.3, "watch": 1, "calibration": calibration}
    detectors = [("signal_function", parameters, "sf"), NisAbove()]
    options = {"models": MODELS, "sensors": SENSORS, "estimator": "kalman"}
    singles = [per_run(z, times, prior, r, detectors=copy.deepcopy(detectors), **options) for r in range(RUNS)]
    assert sum(len(s.decisions) for s in singles) >= 2 * RUNS, "the scenario should make both detectors decide"
    batched = Pipeline.run_batch(z, prior, times=times, detectors=detectors, **options)
    for b, s in zip(batched, singles):
        assert_same(b, s)
