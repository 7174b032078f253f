"""Time-stamped (irregularly sampled) measurements end to end: simulator → files → pipeline → recording.

A hybrid trajectory simulated at random Δt ∈ [0.05, 2] s, with gaps, filtered
by a one-mode Kalman bank must match filterpy's ``KalmanFilter`` stepped by hand
with F(Δt_k), B(Δt_k), G Q Gᵀ of each step; the recording's ``time`` timeline
must hold the given times.
"""

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FilterpyKalman

from hybridtrack import Gaussian, Schedule
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.core.plugins import resolve
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.simulate import simulate
from hybridtrack.io.measurement_files import read_measurement_file, write_csv, write_npz
from hybridtrack.recording import RerunRecorder
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack_plugins.sensors.position import PositionSensor

X0 = np.array([0.0, 0.0, 0.0, 2.0])
#: seed 001's table 1 scaled down: straight and both turns
SCHEDULE = Schedule.from_rows([("left_turn", 12, 3.0), ("right_turn", 15, 5.0), ("straight", 10), ("left_turn", 12, 4.0)])
GAPS = [5, 17, 18, 33]  # rows without a measurement
MODES = [
    "straight",
    ("left_turn", {"radius": 5.0}),
    ("right_turn", {"radius": 5.0}),
    "stop",
    "constant_acceleration",
]


def irregular_times(steps: int, seed: int = 4) -> np.ndarray:
    dt = np.random.default_rng(seed).uniform(0.05, 2.0, steps - 1)
    dt[[3, 20]], dt[[10, 30]] = 0.05, 2.0  # both ends of the range
    return np.concatenate([[0.0], np.cumsum(dt)])


@pytest.fixture(scope="module")
def scenario():
    times = irregular_times(SCHEDULE.total_steps + 1)
    sensor = PositionSensor(name="a", noise_cov=np.diag([0.04, 0.09]))
    truth, z = simulate(SCHEDULE, X0, sensors=[sensor], times=times, seed=1, noise_cov=1e-3 * np.eye(2))
    z["a"][GAPS] = np.nan
    return times, sensor, truth, z


def prior_for(model) -> Gaussian:
    mean = np.zeros(model.state_dim)
    mean[list(model.layout).index("vy")] = 2.0
    return Gaussian(mean, np.eye(model.state_dim))


def filterpy_run(model, sensor, z, times, prior):
    """filterpy's KalmanFilter with each step's F, B (as the control input, B = I), G Q Gᵀ."""
    n = model.state_dim
    network = SensorNetwork([sensor])
    kf = FilterpyKalman(dim_x=n, dim_z=2)
    kf.x, kf.P = prior.mean.copy(), prior.cov.copy()
    kf.H, kf.R, kf.B = network.jacobian(prior.mean, model.layout), network.noise_cov(), np.eye(n)
    means, covs = [], []
    for k, zk in enumerate(z):
        if k:
            transition = model.transition(times[k] - times[k - 1], prior.mean)  # fixed at the switch: the prior mean
            kf.predict(u=transition.B, F=transition.F, Q=transition.G @ transition.Q @ transition.G.T)
        if np.all(np.isfinite(zk)):
            kf.update(zk)
        means.append(kf.x.copy())
        covs.append(kf.P.copy())
    return np.array(means), np.array(covs)


def test_simulated_trajectory_holds_the_given_times(scenario):
    times, _, truth, z = scenario
    assert np.array_equal(truth.times, times) and truth.tau is None
    assert truth.states.shape == (SCHEDULE.total_steps + 1, 4) and z["a"].shape == (SCHEDULE.total_steps + 1, 2)
    np.testing.assert_allclose([np.diff(times).min(), np.diff(times).max()], [0.05, 2.0])


@pytest.mark.parametrize("spec", MODES, ids=lambda s: s if isinstance(s, str) else s[0])
def test_one_mode_bank_matches_filterpy_stepped_per_dt(scenario, spec):
    times, sensor, _, z = scenario
    model = resolve("motion_model", spec)
    prior = prior_for(model)
    result = Pipeline(models=[model], estimator="kalman", sensors=[sensor], measurements=z, prior=prior, times=times).run()
    means, covs = filterpy_run(model, sensor, z["a"], times, prior)
    assert np.array_equal(result.times, times)
    assert np.isnan(result.nis[GAPS]).all()
    np.testing.assert_allclose(result.means[:, 0], means, rtol=0, atol=1e-9)
    np.testing.assert_allclose(result.covs[:, 0], covs, rtol=0, atol=1e-9)


def test_recording_time_axis_is_the_given_times(tmp_path, scenario):
    times, sensor, truth, z = scenario
    path = tmp_path / "irregular.rrd"
    with RerunRecorder(path, {"test": "irregular"}) as recorder:
        Pipeline(
            models=["straight"],
            estimator="kalman",
            sensors=[sensor],
            measurements=z,
            prior=Gaussian(X0, np.eye(4)),
            times=times,
            recorder=recorder,
            truth=truth,
            filter_names=["cv"],
        ).run()
    recording = RecordingFile(path)
    steps, _ = recording.series("estimator/cv/nis")
    assert np.array_equal(steps, np.arange(len(times)))
    # the `time` timeline is a rerun duration, stored as whole nanoseconds
    for entity in ("/estimator/cv/nis", "/world/estimate/cv", "/world/truth"):
        steps, stored = recording.times(entity)
        assert list(steps) == list(range(len(times)))
        np.testing.assert_allclose(stored, times, rtol=0, atol=1e-9)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_time_stamped_file_feeds_the_pipeline(tmp_path, scenario, suffix):
    times, sensor, _, z = scenario
    path = tmp_path / f"z{suffix}"
    if suffix == ".csv":
        write_csv(path, z, {"a": ["x", "y"]}, times=times)
    else:
        write_npz(path, z, times=times)
    measurements, read_times = read_measurement_file(path)
    assert np.array_equal(read_times, times) and np.array_equal(measurements["a"], z["a"], equal_nan=True)
    common = {"models": ["straight"], "estimator": "kalman", "sensors": [sensor], "prior": Gaussian(X0, np.eye(4))}
    from_file = Pipeline(measurements=measurements, times=read_times, **common).run()
    direct = Pipeline(measurements=z, times=times, **common).run()
    assert np.array_equal(from_file.means, direct.means)


def test_unknown_change_adaptive_runs_on_irregular_times(scenario):
    times, sensor, _, z = scenario
    adaptive = UnknownChangeAdaptive(modes=MODES[:3], sensors=[sensor], alpha=0.1, beta=0.1, bank_size=6)
    run = adaptive.run(z, Gaussian(X0, np.eye(4)), times=times)
    assert np.array_equal(run.times, times)
    assert np.all(np.isfinite(run.means)) and run.means.shape == (len(times), 4)


def bad_times(times):
    duplicate, earlier, nan, inf = (times.copy() for _ in range(4))
    duplicate[7] = duplicate[6]
    earlier[9] = earlier[8] - 0.5
    nan[3] = np.nan
    inf[12] = np.inf
    return [
        (duplicate, r"index 7 .*duplicate of the time at index 6"),
        (earlier, r"index 9 .*earlier than the time at index 8"),
        (nan, r"index 3 is nan"),
        (inf, r"index 12 is inf"),
        (times[:-1], rf"expected {len(times)} times .* got {len(times) - 1}"),
    ]


@pytest.mark.parametrize("case", range(5), ids=["duplicate", "decreasing", "nan", "inf", "length"])
def test_bad_times_name_the_index(scenario, case):
    times, sensor, _, z = scenario
    bad, message = bad_times(times)[case]
    adaptive = UnknownChangeAdaptive(modes=MODES[:3], sensors=[sensor])
    with pytest.raises(ValueError, match=message):
        adaptive.run(z, Gaussian(X0, np.eye(4)), times=bad)
    with pytest.raises(ValueError, match=message):
        Pipeline(models=["straight"], estimator="kalman", sensors=[sensor], measurements=z, prior=Gaussian(X0, np.eye(4)), times=bad)
    with pytest.raises(ValueError, match=message):
        simulate(SCHEDULE, X0, sensors=[sensor], times=bad, seed=1)
