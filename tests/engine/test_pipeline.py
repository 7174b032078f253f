"""Pipeline: composition by name or object, step-by-step vs run, missing rows, recording."""

import numpy as np
import pytest

from hybridtrack import Decision, Detector, DetectorStep, Gaussian, Schedule
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import RerunRecorder
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.motion.linear_modes import LeftTurn, Straight
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
PRIOR = Gaussian(X0, np.eye(4))


class NisThreshold(Detector):
    """A tiny detector for the test: decides 'change' the first time NIS of filter 0 exceeds 30."""

    name = "nis_threshold"

    def __init__(self):
        self.reset()

    def reset(self):
        self.fired = False

    def step(self, step, innovation):
        nis = float(innovation.nis[0]) if innovation.measurement_dim else 0.0
        decision = None
        if nis > 30 and not self.fired:
            self.fired = True
            decision = Decision(step, self.name, "change", nis, "NIS above 30")
        return DetectorStep({"nis": nis}, {"threshold": 30.0}, decision)


def scenario(seed=0, steps=60):
    schedule = Schedule.from_rows([("straight", steps // 2), ("left_turn", steps // 2, 3.0)])
    sensors = [PositionSensor(name="a"), PositionSensor(name="b", components="x", noise_cov=[[0.04]])]
    trajectory, z = simulate(schedule, X0, 0.1, sensors, seed=seed, noise_cov=np.diag([1e-3, 1e-3]))
    return schedule, sensors, trajectory, z


def test_by_name_equals_by_object_and_step_equals_run():
    _, sensors, trajectory, z = scenario()
    by_name = Pipeline(
        models=["straight", ("left_turn", {"radius": 3.0, "noise_cov": np.diag([1e-3, 1e-3])})],
        estimator="kalman",
        sensors=sensors,
        measurements=z,
        prior=PRIOR,
        tau=0.1,
    )
    by_object = Pipeline(
        models=[Straight(), LeftTurn(radius=3.0, noise_cov=np.diag([1e-3, 1e-3]))],
        estimator=KalmanFilter(),
        sensors=sensors,
        measurements=z,
        prior=(X0, np.eye(4)),
        tau=0.1,
    )
    run = by_name.run()
    steps = [by_object.step() for _ in range(by_object.steps)]
    assert by_object.done
    np.testing.assert_array_equal(run.means, np.stack([s.mean for s in steps]))
    assert run.means.shape == (61, 2, 4) and run.covs.shape == (61, 2, 4, 4) and run.nis.shape == (61, 2)
    assert run.filters == ("straight", "left_turn_r3")
    with pytest.raises(StopIteration):
        by_object.step()


def test_missing_rows_predict_only():
    _, sensors, _, z = scenario()
    z = {name: value.copy() for name, value in z.items()}
    z["a"][10:20] = np.nan
    z["b"][10:20] = np.nan
    pipeline = Pipeline(models=["straight"], estimator="kalman", sensors=sensors, measurements=z, prior=PRIOR, tau=0.1)
    result = pipeline.run()
    assert np.isnan(result.nis[10:20]).all() and np.isfinite(result.nis[20:]).all()
    # predicted-only steps grow the covariance
    assert np.all(np.diff(result.covs[10:20, 0, 0, 0]) > 0)


def test_estimates_track_the_truth_with_the_right_model():
    schedule, sensors, trajectory, z = scenario(seed=4, steps=200)
    pipeline = Pipeline(
        models=[("left_turn", {"radius": 3.0, "noise_cov": np.diag([1e-3, 1e-3])})],
        estimator="kalman",
        sensors=sensors,
        measurements={k: v[100:] for k, v in z.items()},
        prior=Gaussian(trajectory.states[100], 0.01 * np.eye(4)),
        tau=0.1,
    )
    result = pipeline.run()
    error = result.means[:, 0] - trajectory.states[100:]
    nees = np.einsum("ki,kij,kj->k", error, np.linalg.inv(result.covs[:, 0]), error)
    assert nees.mean() < 9.5  # χ²(4) mean is 4; a wrong model would diverge


def test_detector_decisions_and_statistics_are_collected():
    _, sensors, _, z = scenario(seed=1, steps=200)
    stiff = ("straight", {"noise_cov": 1e-6 * np.eye(2)})  # cannot follow the turn: NIS explodes there
    pipeline = Pipeline(
        models=[stiff], estimator="kalman", sensors=sensors, measurements=z, prior=PRIOR, tau=0.1, detectors=[NisThreshold()]
    )
    result = pipeline.run()
    assert len(result.decisions) == 1 and result.decisions[0].step > 100  # the turn starts at step 100
    assert result.statistics["nis_threshold"]["nis"].shape == (201,)
    assert np.all(result.statistics["nis_threshold"]["threshold"] == 30.0)


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"models": []}, ValueError, "at least one"),
        ({"models": ["straight", "constant_acceleration"]}, ValueError, "layout"),
        ({"models": ["nope"]}, KeyError, "known: .*straight"),
        ({"estimator": "nope"}, KeyError, "unknown estimator 'nope'"),
        ({"estimator": 3}, TypeError, "estimator"),
        ({"tau": -1}, ValueError, "tau"),
        ({"prior": (np.zeros(6), np.eye(6))}, ValueError, "prior"),
        ({"prior": (np.zeros(4), -np.eye(4))}, ValueError, "cov"),
        ({"measurements": {"a": np.zeros((5, 2))}}, ValueError, "no data for sensors"),
    ],
)
def test_bad_composition_is_named(kwargs, error, message):
    _, sensors, _, z = scenario()
    arguments = dict(models=["straight"], estimator="kalman", sensors=sensors, measurements=z, prior=PRIOR, tau=0.1)
    arguments.update(kwargs)
    with pytest.raises(error, match=message):
        Pipeline(**arguments)


def test_run_is_recorded_and_error_midway_keeps_what_was_done(tmp_path):
    import rerun as rr

    _, sensors, trajectory, z = scenario()
    path = tmp_path / "run.rrd"
    with RerunRecorder(path, {"test": 1}) as recorder:
        pipeline = Pipeline(
            models=["straight"],
            estimator="kalman",
            sensors=sensors,
            measurements=z,
            prior=PRIOR,
            tau=0.1,
            recorder=recorder,
            truth=trajectory,
        )
        pipeline.step()
        pipeline.step()

        def broken(*args, **kwargs):
            raise RuntimeError("boom")

        pipeline.estimator.predict = broken
        with pytest.raises(RuntimeError, match="boom"):
            pipeline.run()
    entities = set(rr.chunk.RrdReader(path).stream().collect().schema().entity_paths())
    assert {"/world/truth", "/world/measurements/a", "/world/estimate/straight", "/estimator/straight/nis"} <= entities


def test_known_modes_runner_follows_the_schedule():
    from hybridtrack.algorithms.known_modes import run_known_modes

    schedule = Schedule.from_rows([("straight", 40), ("left_turn", 60, 3.0), ("right_turn", 40, 5.0)])
    sensors = [PositionSensor(name="a")]
    Q = np.diag([1e-3, 1e-3])
    trajectory, z = simulate(schedule, X0, 0.1, sensors, seed=2, noise_cov=Q)
    run = run_known_modes(schedule, estimator="kalman", sensors=sensors, measurements=z, prior=PRIOR, tau=0.1, noise_cov=Q)
    assert run.means.shape == (141, 4) and run.covs.shape == (141, 4, 4)
    error = run.means - trajectory.states
    nees = np.einsum("ki,kij,kj->k", error, np.linalg.inv(run.covs), error)
    assert nees[10:].mean() < 8  # consistent (χ²(4) mean 4); a filter with the wrong modes diverges
    straight = Pipeline(
        models=[("straight", {"noise_cov": Q})], estimator="kalman", sensors=sensors, measurements=z, prior=PRIOR, tau=0.1
    ).run()
    wrong = straight.means[:, 0] - trajectory.states
    assert np.einsum("ki,kij,kj->k", wrong, np.linalg.inv(straight.covs[:, 0]), wrong)[10:].mean() > 20
    with pytest.raises(ValueError, match="expected 141 steps"):
        run_known_modes(schedule, estimator="kalman", sensors=sensors, measurements={"a": z["a"][:50]}, prior=PRIOR, tau=0.1)


def test_two_labelled_instances_of_one_detector_share_a_pipeline():
    _, sensors, _, z = scenario()
    times = 0.1 * np.arange(z["a"].shape[0]) + 1000.0
    pipeline = Pipeline(
        models=["straight"],
        estimator="kalman",
        sensors=sensors,
        measurements=z,
        prior=PRIOR,
        times=times,
        detectors=[("signal_function", {"window": 5}, "sf5"), ("signal_function", {"window": 20, "label": "sf20"}), "signal_function"],
    )
    result = pipeline.run()
    assert set(result.statistics) == {"sf5", "sf20", "signal_function"}
    assert not np.array_equal(result.statistics["sf5"]["signal"], result.statistics["sf20"]["signal"])
    assert result.decisions
    for decision in result.decisions:
        assert decision.detector in {"sf5", "sf20", "signal_function"} and decision.time == times[decision.step]
    with pytest.raises(ValueError, match="labels must be unique.*'signal_function', 'signal_function'"):
        Pipeline(
            models=["straight"],
            estimator="kalman",
            sensors=sensors,
            measurements=z,
            prior=PRIOR,
            tau=0.1,
            detectors=["signal_function"] * 2,
        )
    with pytest.raises(ValueError, match="label: expected a non-empty name"):
        Pipeline(
            models=["straight"], estimator="kalman", sensors=sensors, measurements=z, prior=PRIOR, tau=0.1, detectors=[("glr", {}, "a/b")]
        )


@pytest.mark.parametrize(
    ("names", "message"),
    [(["a", "a"], r"unique.*\['a'\] repeated"), (["", "b"], "non-empty"), (["a/b", "c"], "without '/'"), ([" ", "c"], "non-empty")],
)
def test_filter_names_that_would_merge_recorded_entities_are_refused(names, message):
    _, sensors, _, z = scenario()
    with pytest.raises(ValueError, match=f"filter_names: .*{message}"):
        Pipeline(models=["straight", "stop"], estimator="kalman", sensors=sensors, measurements=z, prior=PRIOR, tau=0.1, filter_names=names)
