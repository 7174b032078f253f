"""RowScan: stacked runs (one filter each, each its own candidates) through one NN / PDA bank, row by row equal to the
one-filter update with that run's Scan to 1e-12 (state, association weights and likelihood), over several steps."""

import numpy as np
import pytest

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.engine.clutter import stack_scans
from hybridtrack.sdk.scans import RowScan, Scan
from hybridtrack_plugins.filters.nearest_neighbour import NearestNeighbourFilter
from hybridtrack_plugins.filters.pda import PDAFilter
from hybridtrack_plugins.motion.linear_modes import Straight
from hybridtrack_plugins.sensors.position import PositionSensor

LAYOUT = ("x", "vx", "y", "vy")
SENSOR = PositionSensor("pos", ("x", "y"), np.eye(2) * 0.1)
TOL = {"rtol": 1e-12, "atol": 1e-12}
RUNS, STEPS = 5, 12


def scans(seed=2):
    """Per run and step a Scan: near the predicted track with clutter; run 1 gets empty scans at some steps."""
    rng = np.random.default_rng(seed)
    out = []
    for r in range(RUNS):
        rows = []
        for k in range(STEPS):
            target = np.array([0.2 * k * (1 + 0.1 * r), 0.1 * k]) + rng.normal(0, 0.3, 2)
            count = 0 if (r == 1 and k % 3 == 1) else int(rng.integers(0, 6))
            clutter = target + rng.uniform(-3, 3, (count, 2))
            z = np.vstack([target[None], clutter]) if not (r == 1 and k % 3 == 1) else np.zeros((0, 2))
            rows.append(Scan("pos", rng.permutation(z)))
        out.append(rows)
    return out


@pytest.mark.parametrize(
    "estimator",
    [
        NearestNeighbourFilter(gate_probability=0.99),
        PDAFilter(detection_probability=0.9, clutter_density=0.05, gate_probability=0.99),
        PDAFilter(detection_probability=0.8, clutter_density=0.0, gate_probability=0.95),
    ],
)
def test_row_scans_equal_each_run(estimator):
    data = scans()
    transition = Straight(noise_cov=np.eye(2) * 0.1).transition(0.1, np.zeros(4))
    prior = np.array([0.0, 2.0, 0.0, 1.0])
    bank = estimator.initialize(np.repeat(prior[None], RUNS, 0), np.repeat(np.eye(4)[None], RUNS, 0))
    single = [estimator.initialize(prior[None], np.eye(4)[None]) for _ in range(RUNS)]
    stacked_transition = TransitionBank.stack([transition] * RUNS)
    one = TransitionBank.stack([transition])
    for k in range(STEPS):
        if k:
            bank = estimator.predict(bank, stacked_transition)
            single = [estimator.predict(s, one) for s in single]
        row_scan = stack_scans([data[r][k] for r in range(RUNS)])
        bank, innovation = estimator.update(bank, row_scan, [SENSOR], LAYOUT)
        (association,) = innovation.associations
        for r in range(RUNS):
            single[r], own = estimator.update(single[r], data[r][k], [SENSOR], LAYOUT)
            (mine,) = own.associations
            np.testing.assert_allclose(estimator.mean(bank)[r], estimator.mean(single[r])[0], **TOL, err_msg=f"mean {r} {k}")
            np.testing.assert_allclose(estimator.covariance(bank)[r], estimator.covariance(single[r])[0], **TOL)
            L = data[r][k].size
            np.testing.assert_allclose(association.weights[r, :L], mine.weights[0], **TOL)
            assert not association.weights[r, L:].any() and not association.gated[r, L:].any()
            np.testing.assert_allclose(association.missed[r], mine.missed[0], **TOL)
            np.testing.assert_allclose(association.loglik[r], mine.loglik[0], **TOL, equal_nan=True)
            assert association.selected[r] == mine.selected[0]


def test_row_scan_inputs_are_checked():
    with pytest.raises(ValueError, match="partly NaN"):
        RowScan("pos", [[[1.0, np.nan]]])
    with pytest.raises(ValueError, match=r"\(M, L, m\)"):
        RowScan("pos", [[1.0, 2.0]])
    with pytest.raises(ValueError, match="one sensor"):
        stack_scans([Scan("pos", [[1.0, 2.0]]), Scan("other", [[1.0, 2.0]])])
    row_scan = stack_scans([Scan("pos", [[1.0, 2.0], [3.0, 4.0]]), Scan("pos", np.zeros((0, 2)))])
    assert row_scan.z.shape == (2, 2, 2) and row_scan.present.tolist() == [[True, True], [False, False]]
    assert row_scan.row(0) == Scan("pos", [[1.0, 2.0], [3.0, 4.0]]) and row_scan.row(1).size == 0
    nn = NearestNeighbourFilter(gate_probability=0.99)
    state = nn.initialize(np.zeros((3, 4)), np.repeat(np.eye(4)[None], 3, 0))
    with pytest.raises(ValueError, match="2 rows for a bank of 3"):
        nn.update(state, row_scan, [SENSOR], LAYOUT)


def test_other_clutter_estimators_refuse_row_scans():
    from hybridtrack.core.plugins import get_registry

    estimator = get_registry().create("estimator", "gaussian_sum", detection_probability=0.9, clutter_density=0.05)
    state = estimator.initialize(np.zeros((1, 4)), np.eye(4)[None])
    with pytest.raises(TypeError, match="nearest_neighbour and pda only"):
        estimator.update(state, stack_scans([Scan("pos", [[1.0, 2.0]])]), [SENSOR], LAYOUT)
