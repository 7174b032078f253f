"""Clutter simulator and candidate-measurement types (hybridtrack/sdk/scans.py), the pipeline's
``candidates`` option and the recording of clutter, gates and association weights (SPEC §6)."""

import numpy as np
import pytest
from scipy import stats

from hybridtrack.engine.clutter import ClutterModel, ScanSequence, add_clutter, region_around, simulate_scans
from hybridtrack.engine.pipeline import Pipeline
from hybridtrack.engine.schedule import Schedule, Segment
from hybridtrack.engine.simulate import simulate_trajectory
from hybridtrack.recording import RerunRecorder
from hybridtrack.recording.inspection import RecordingFile
from hybridtrack.sdk.scans import Scan
from hybridtrack_plugins.sensors.position import PositionSensor

REGION = [[-10.0, 0.0], [10.0, 5.0]]  # V = 100


def test_clutter_counts_are_poisson_positions_uniform_and_detections_bernoulli():
    clean = {"pos": np.zeros((4000, 2))}
    model = ClutterModel(density=0.03, detection_probability=0.7, region=REGION)
    assert model.volume == 100.0 and model.expected_false == pytest.approx(3.0)
    scans = add_clutter(clean, model, seed=1)["pos"]
    detected = scans.target_index >= 0
    false_counts = scans.counts - detected
    # mean and variance of a Poisson(3) over 4000 steps; detection rate of Bernoulli(0.7)
    assert abs(false_counts.mean() - 3.0) < 4 * np.sqrt(3.0 / 4000)
    assert abs(false_counts.var() - 3.0) < 0.25
    assert abs(detected.mean() - 0.7) < 4 * np.sqrt(0.21 / 4000)
    false = scans.false_measurements().reshape(-1, 2)
    false = false[~np.isnan(false[:, 0])]
    assert stats.kstest((false[:, 0] + 10) / 20, "uniform").pvalue > 1e-3
    assert stats.kstest(false[:, 1] / 5, "uniform").pvalue > 1e-3
    # the labelled candidate is the clean measurement, and it is not always first
    np.testing.assert_array_equal(scans.target_measurements()[detected], np.zeros((detected.sum(), 2)))
    assert len(set(scans.target_index[detected].tolist())) > 3


def test_same_seed_same_scans_and_a_missing_measurement_stays_missing():
    clean = {"pos": np.array([[1.0, 1.0], [np.nan, np.nan], [2.0, 2.0]])}
    model = ClutterModel(0.05, 1.0, REGION)
    a, b = add_clutter(clean, model, seed=7)["pos"], add_clutter(clean, model, seed=7)["pos"]
    assert all(np.array_equal(p, q) for p, q in zip(a.points, b.points))
    np.testing.assert_array_equal(a.target_index, b.target_index)
    assert a.target_index[1] == -1 and a.target_index[0] >= 0 and a.target_index[2] >= 0
    # a sensor without a clutter model keeps its clean measurement as a one-candidate scan
    plain = add_clutter(clean, {"other": model}, seed=7)["pos"]
    np.testing.assert_array_equal(plain.counts, [1, 0, 1])


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"density": -0.1, "region": REGION}, "clutter_density"),
        ({"density": np.inf, "region": REGION}, "clutter_density"),
        ({"density": 0.1, "detection_probability": 0.0, "region": REGION}, "detection_probability"),
        ({"density": 0.1, "detection_probability": 1.01, "region": REGION}, "detection_probability"),
        ({"density": 0.1, "region": [[0.0, 0.0], [0.0, 1.0]]}, "region"),
        ({"density": 0.1}, "region"),
    ],
)
def test_bad_clutter_models_raise_value_error(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ClutterModel(**kwargs)


def test_scan_types_validate_and_compare():
    assert Scan("pos", [1.0, 2.0]).z.shape == (1, 2)
    assert Scan("pos", np.zeros((0, 2))).size == 0
    assert Scan("pos", [[1.0, 2.0]]) == Scan("pos", [1.0, 2.0])
    with pytest.raises(ValueError, match="empty scan"):
        Scan("pos", [])
    with pytest.raises(ValueError, match="target_index"):
        ScanSequence("pos", [np.zeros((1, 2))], [1])
    with pytest.raises(ValueError, match="same dimension"):
        ScanSequence("pos", [np.zeros((1, 2)), np.zeros((1, 3))], [0, 0])
    with pytest.raises(ValueError, match="no finite point"):
        region_around(np.full((3, 2), np.nan), 1.0)


def _scenario(density=0.5, seed=2):
    schedule = Schedule([Segment("straight", 20), Segment("right_turn", 30, 5.0)])
    truth = simulate_trajectory(schedule, [0.0, 0.0, 0.0, 2.0], 0.1, seed=seed, noise_cov=np.diag([0.01, 0.01]))
    sensor = PositionSensor("pos", ("x", "y"), np.diag([0.01, 0.01]))
    model = ClutterModel(density, 0.9, region_around(truth.positions, 2.0))
    return truth, sensor, simulate_scans(truth, [sensor], model, seed=seed)


def test_pipeline_runs_a_pda_bank_on_candidates_and_records_clutter_gates_and_weights(tmp_path, rerun_cli, clutter_pipeline):
    truth, sensor, scans = _scenario()
    path = tmp_path / "clutter.rrd"
    with RerunRecorder(path, {"seed": 2}) as recorder:
        pda = ("pda", {"detection_probability": 0.9, "clutter_density": 0.5})
        pipeline = clutter_pipeline(pda, sensor, scans, recorder=recorder, truth=truth)
        result = pipeline.run()
    assert result.means.shape == (51, 2, 4)
    assert np.abs(result.means[:20, 0, [0, 2]] - truth.positions[:20]).max() < 0.5  # straight filter on the straight leg
    assert rerun_cli("rrd", "verify", path).returncode == 0
    rec = RecordingFile(path)
    steps, sets = rec.point_sets("world/clutter/pos")
    false = scans["pos"].false_measurements()
    for k, points in zip(steps, sets):
        expected = false[k][~np.isnan(false[k, :, 0])]
        np.testing.assert_allclose(points, expected, rtol=1e-6, atol=1e-5)  # float32 positions
    steps, beta = rec.series("estimator/straight/beta")
    expected = np.array(
        [[r.innovation.associations[0].missed[0], r.innovation.associations[0].weights[0].max(initial=0.0)] for r in pipeline.results]
    )
    np.testing.assert_array_equal(beta, expected)
    steps, loglik = rec.series("estimator/right_turn_r5/association_loglik")
    np.testing.assert_array_equal(loglik, [r.innovation.associations[0].loglik[1] for r in pipeline.results])
    gate_steps, strips = rec.strips("world/estimate/straight/gate")
    assert len(gate_steps) == 51 and strips[0][0].shape[1] == 2
    assert "/world/measurements/pos" in rec.summary()["entity_paths"]


def test_pipeline_candidates_need_an_associating_estimator_and_exclude_measurements():
    truth, sensor, scans = _scenario()
    common = dict(models=["straight"], sensors=[sensor], prior=(np.zeros(4), np.eye(4)), tau=0.1)
    with pytest.raises(ValueError, match="does not associate"):
        Pipeline(estimator="kalman", candidates=scans, **common)
    with pytest.raises(ValueError, match="either measurements or candidates"):
        Pipeline(estimator="pda", candidates=scans, measurements={"pos": np.zeros((51, 2))}, **common)
    with pytest.raises(ValueError, match="one ScanSequence per sensor"):
        Pipeline(estimator="pda", candidates={}, **common)
    with pytest.raises(ValueError, match="measurements: required"):
        Pipeline(estimator="pda", **common)


def test_nearest_neighbour_and_pda_in_the_pipeline_agree_with_direct_updates():
    truth, sensor, scans = _scenario(density=1.0, seed=4)
    for estimator in ("nearest_neighbour", ("pda", {"detection_probability": 0.9, "clutter_density": 1.0})):
        pipeline = Pipeline(
            models=["straight"],
            estimator=estimator,
            sensors=[sensor],
            candidates=scans,
            prior=(np.array([0.0, 0.0, 0.0, 2.0]), np.eye(4) * 0.01),
            tau=0.1,
        )
        result = pipeline.run()
        est = pipeline.estimator
        state = est.initialize(np.array([[0.0, 0.0, 0.0, 2.0]]), np.eye(4)[None] * 0.01)
        bank = pipeline.bank.transitions(0.1)
        for k in range(scans["pos"].steps):
            if k:
                state = est.predict(state, bank)
            state, _ = est.update(state, scans["pos"].scan(k), [sensor], ("x", "vx", "y", "vy"))
            np.testing.assert_array_equal(result.means[k, 0], state.x[0])
