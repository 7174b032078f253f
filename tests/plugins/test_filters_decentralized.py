"""Decentralized filters (Algorithm 2 of seed 000) equal the centralized KF on the stacked model."""

import numpy as np
import pytest
from _filters_support import LAYOUT, bank_of, position_sensor, radii_bank, simulate, straight

import hybridtrack as ht

REL = 1e-9


def _network(N, rng):
    """N heterogeneous nodes: every third measures x only, the others (x, y); different R."""
    sensors = []
    for j in range(N):
        if j % 3 == 1:
            sensors.append(position_sensor(np.array([[0.05 * (j + 1)]]), ("x",), name=f"n{j}"))
        else:
            A = rng.standard_normal((2, 2)) * 0.1
            sensors.append(position_sensor(A @ A.T + np.diag([0.02, 0.05]) * (j + 1), name=f"n{j}"))
    return sensors


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


@pytest.mark.parametrize("name", ["decentralized", "srif_decentralized"])
@pytest.mark.parametrize("N", [1, 3, 5])
def test_decentralized_equals_centralized(name, N):
    rng = np.random.default_rng(10 + N)
    s0 = np.array([0.0, 0.0, 0.0, 2.0])
    trs = radii_bank(s0, n_radii=3)
    sensors = _network(N, rng)
    _, Z = simulate(trs[2], sensors, s0, 40, rng)
    # some steps with a node missing, one step with no data at all
    Z = Z[0].copy()
    Z[5, :1] = np.nan if sensors[0].measurement_dim == 1 else Z[5, :1]
    Z[7, : sensors[0].measurement_dim] = np.nan
    Z[9, :] = np.nan
    registry = ht.load_plugins(strict=True).registry
    central, dec = registry.create("estimator", "kalman"), registry.create("estimator", name)
    M = len(trs)
    x0, P0 = np.tile(s0, (M, 1)), np.stack([np.diag([1.0, 0.5, 1.0, 0.5])] * M)
    sc, sd = central.initialize(x0, P0), dec.initialize(x0, P0)
    bank = bank_of(trs)
    for k in range(Z.shape[0]):
        sc, sd = central.predict(sc, bank), dec.predict(sd, bank)
        sc, ic = central.update(sc, Z[k], sensors, LAYOUT)
        sd, id_ = dec.update(sd, Z[k], sensors, LAYOUT)
        assert _rel(dec.mean(sd), central.mean(sc)) <= REL
        assert _rel(dec.covariance(sd), central.covariance(sc)) <= REL
        assert _rel(sd.predicted_covariance, sc.predicted_covariance) <= REL
        # every node holds the same estimate
        for i in range(sd.nodes):
            assert _rel(sd.node_means[i], central.mean(sc)) <= REL
            assert _rel(sd.node_covariances[i], central.covariance(sc)) <= REL
        if ic.measurement_dim:
            assert _rel(id_.nu, ic.nu) <= REL and _rel(id_.S, ic.S) <= REL
            np.testing.assert_allclose(id_.loglik, ic.loglik, rtol=REL)
            # locally computed detection quantities at every node (seed 000 eq. 22)
            np.testing.assert_allclose(sd.node_nis, np.broadcast_to(ic.nis, sd.node_nis.shape), rtol=1e-6, atol=1e-9)
            np.testing.assert_allclose(sd.node_loglik, np.broadcast_to(ic.loglik, sd.node_loglik.shape), rtol=1e-6, atol=1e-9)
        else:
            assert id_.nu.shape == (M, 0)


def test_node_count_mismatch_raises():
    dec = ht.load_plugins(strict=True).registry.create("estimator", "decentralized", nodes=3)
    state = dec.initialize(np.zeros((1, 4)), np.eye(4)[None])
    with pytest.raises(ValueError, match="sensors: expected 3 sensors"):
        dec.update(state, np.zeros(2), [position_sensor()], LAYOUT)


OFFSETS = [0.0, 3e3, 5e5, 5e6]  # origin, 3 km, map-grid coordinates (500 km, 5000 km)


@pytest.mark.parametrize("offset", OFFSETS)
def test_node_statistics_equal_the_centralized_ones_far_from_the_origin(offset):
    """Each node's ℓ and NIS (seed 000 eq. 22, computed about the prediction) equal the centralized KF's to 1e-9
    relative at every step, wherever the coordinate origin is (eq. 22 as printed lost 1e-6 at 3 km)."""
    rng = np.random.default_rng(3)
    sensors = _network(3, rng)
    s0 = np.array([offset, 1.0, offset, 2.0])
    trs = [straight(), straight(q=0.01)]
    _, Z = simulate(trs[0], sensors, s0, 50, rng)
    registry = ht.load_plugins(strict=True).registry
    central, dec = registry.create("estimator", "kalman"), registry.create("estimator", "decentralized")
    M = len(trs)
    x0, P0 = np.tile(s0, (M, 1)), np.stack([np.diag([1.0, 0.5, 1.0, 0.5])] * M)
    sc, sd = central.initialize(x0, P0), dec.initialize(x0, P0)
    bank = bank_of(trs)
    for k in range(Z.shape[1]):
        sc, sd = central.predict(sc, bank), dec.predict(sd, bank)
        sc, ic = central.update(sc, Z[0, k], sensors, LAYOUT)
        sd, _ = dec.update(sd, Z[0, k], sensors, LAYOUT)
        loglik, nis = dec.node_scores(sd)
        assert loglik is sd.node_loglik and nis is sd.node_nis and nis.shape == (3, M)
        np.testing.assert_allclose(nis, np.broadcast_to(ic.nis, nis.shape), rtol=REL, atol=0)
        np.testing.assert_allclose(loglik, np.broadcast_to(ic.loglik, loglik.shape), rtol=REL, atol=0)


def test_node_sprt_decisions_equal_the_centralized_ones_at_5000_km():
    from hybridtrack import Gaussian, Schedule
    from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
    from hybridtrack.engine.simulate import simulate as simulate_schedule
    from hybridtrack_plugins.sensors.position import PositionSensor

    sensors = [
        PositionSensor(name="a", noise_cov=np.diag([0.01, 0.01])),
        PositionSensor(name="b", components="x", noise_cov=[[0.04]]),
        PositionSensor(name="c", components="y", noise_cov=[[0.02]]),
    ]
    x0 = np.array([5e6, 0.0, 5e6, 2.0])
    schedule = Schedule.from_rows([("straight", 20), ("right_turn", 30, 5.0)])
    _, z = simulate_schedule(schedule, x0, 0.1, sensors, seed=3, noise_cov=np.diag([0.01, 0.01]))
    modes = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
    runs = {
        name: UnknownChangeAdaptive(modes=modes, sensors=sensors, tau=0.1, alpha=0.1, beta=0.1, estimator=name).run(
            z, Gaussian(x0, np.eye(4))
        )
        for name in ("kalman", "decentralized")
    }
    central, decentral = runs["kalman"], runs["decentralized"]
    finite = np.isfinite(central.log_ratios)
    assert finite.sum() > 40 and central.changes
    for node in range(3):
        assert np.array_equal(np.isfinite(decentral.node_log_ratios[:, node]), finite)
        scale = np.maximum(np.abs(central.log_ratios[finite]), 1.0)
        assert np.max(np.abs(decentral.node_log_ratios[:, node][finite] - central.log_ratios[finite]) / scale) <= 1e-9
    assert [c.step for c in decentral.changes] == [c.step for c in central.changes]
