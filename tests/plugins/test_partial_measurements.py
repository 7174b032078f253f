"""Missing data per component: a NaN in one component of a sensor drops only that component.

The update with a partially missing sensor must equal the update with a sensor
measuring only the present components, with R the matching sub-block (rows and
columns) of the original R — for every estimator, linear and nonlinear sensors,
one sensor or several, one filter or a bank.
"""

import numpy as np
import pytest
from _filters_support import LAYOUT, MatrixSensor, bank_of, position_sensor, radii_bank, random_spd, simulate, straight

import hybridtrack
from hybridtrack.sdk.measurements import MeasurementAssembler
from hybridtrack_plugins.filters.kalman import AxisState
from hybridtrack_plugins.sensors.bearing import BearingSensor
from hybridtrack_plugins.sensors.position import PositionSensor
from hybridtrack_plugins.sensors.radar import PolarRadarSensor

TOL = 1e-12
CLUTTER = ("nearest_neighbour", "pda")
ESTIMATORS = [name for name in hybridtrack.get_registry().names("estimator") if name not in CLUTTER]
EXTENDED = ("ekf", "ekf_sqrt", "ekf_ud")

R2 = np.array([[0.04, 0.015], [0.015, 0.09]])  # correlated: the sub-block choice matters
R3 = np.array([[0.05, 0.01, 0.02], [0.01, 0.03, -0.005], [0.02, -0.005, 0.07]])
RB = np.array([[0.02, -0.006], [-0.006, 0.03]])


def _create(name, **parameters):
    return hybridtrack.get_registry().create("estimator", name, **parameters)


def _prior(M, block, seed):
    """Means (M, 4) and covariances (M, 4, 4); ``block``: block diagonal over the axes (x, vx), (y, vy)."""
    rng = np.random.default_rng(seed)
    x0 = rng.standard_normal((M, 4))
    if block:
        P0 = np.stack(
            [np.kron(np.diag([1.0, 0.0]), random_spd(rng, 2)) + np.kron(np.diag([0.0, 1.0]), random_spd(rng, 2)) for _ in range(M)]
        )
    else:
        P0 = np.stack([random_spd(rng, 4) for _ in range(M)])
    return x0, P0


def _update(name, z, sensors, M, block=False, seed=0, **parameters):
    """One predict + update of a fresh estimator; (estimator, updated state, innovation)."""
    est = _create(name, **parameters)
    x0, P0 = _prior(M, block, seed)
    state = est.predict(est.initialize(x0, P0), bank_of([straight(q=0.01 * (i + 1)) for i in range(M)]))
    new, innovation = est.update(state, z, sensors, LAYOUT)
    return est, new, innovation


def _rel(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, (a.shape, b.shape)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)) if b.size else 0.0


def _assert_same(got, ref, tol=TOL):
    (est_a, a, ia), (est_b, b, ib) = got, ref
    worst = {
        "mean": _rel(est_a.mean(a), est_b.mean(b)),
        "covariance": _rel(est_a.covariance(a), est_b.covariance(b)),
        "nu": _rel(ia.nu, ib.nu),
        "S": _rel(ia.S, ib.S),
        "loglik": _rel(ia.loglik, ib.loglik),
        "nis": _rel(ia.nis, ib.nis),
    }
    assert max(worst.values()) <= tol, worst


def _variants(name):
    """(name, constructor parameters, block-diagonal prior): kalman also on its dense path and its axis-separable path."""
    if name in ("kalman", "ekf"):
        return [(name, {"structure": False}, False), (name, {}, True)]
    return [(name, {}, False)]


def _cases():
    return [pytest.param(*v, id=f"{v[0]}-{'axes' if v[2] else 'dense'}") for name in ESTIMATORS for v in _variants(name)]


# --------------------------------------------------------------------------- linear sensors, every estimator


@pytest.mark.parametrize(("name", "parameters", "block"), _cases())
@pytest.mark.parametrize("M", [1, 3])
def test_one_sensor_partial_equals_reduced_sensor(name, parameters, block, M):
    full = PositionSensor(name="pos", components=("x", "y"), noise_cov=R2)
    only_x = PositionSensor(name="pos", components=("x",), noise_cov=R2[:1, :1])
    got = _update(name, np.array([0.3, np.nan]), [full], M, block, **parameters)
    ref = _update(name, np.array([0.3]), [only_x], M, block, **parameters)
    _assert_same(got, ref)
    assert got[2].nu.shape == (M, 1)
    if block and name == "kalman":
        assert isinstance(got[1], AxisState), "the axis-separable path takes the reduced selection"


@pytest.mark.parametrize(("name", "parameters", "block"), _cases())
def test_bank_rows_per_filter_partial_equals_reduced_sensor(name, parameters, block):
    """z of shape (M, m): one row per filter, the same component missing in every row."""
    full = PositionSensor(name="pos", components=("x", "y"), noise_cov=R2)
    only_y = PositionSensor(name="pos", components=("y",), noise_cov=R2[1:, 1:])
    y = np.array([[0.2], [-0.4], [1.1]])
    z = np.hstack([np.full((3, 1), np.nan), y])
    _assert_same(_update(name, z, [full], 3, block, seed=1, **parameters), _update(name, y, [only_y], 3, block, seed=1, **parameters))


@pytest.mark.parametrize(("name", "parameters", "block"), _cases())
def test_three_components_middle_missing_uses_the_sub_block(name, parameters, block):
    """Rows and columns (0, 2) of a correlated 3×3 R: a non-contiguous sub-block."""
    full = PositionSensor(name="pos", components=("x", "vx", "y"), noise_cov=R3)
    rows = np.ix_([0, 2], [0, 2])
    reduced = PositionSensor(name="pos", components=("x", "y"), noise_cov=R3[rows])
    got = _update(name, np.array([0.3, np.nan, -0.7]), [full], 3, block, seed=2, **parameters)
    ref = _update(name, np.array([0.3, -0.7]), [reduced], 3, block, seed=2, **parameters)
    _assert_same(got, ref)


@pytest.mark.parametrize(("name", "parameters", "block"), _cases())
@pytest.mark.parametrize("M", [1, 3])
def test_two_sensors_one_partially_missing(name, parameters, block, M):
    a = PositionSensor(name="a", components=("x", "y"), noise_cov=R2)
    a_y = PositionSensor(name="a", components=("y",), noise_cov=R2[1:, 1:])
    b = PositionSensor(name="b", components=("x", "y"), noise_cov=RB)
    got = _update(name, np.array([np.nan, 0.4, 0.25, 0.5]), [a, b], M, block, seed=3, **parameters)
    ref = _update(name, np.array([0.4, 0.25, 0.5]), [a_y, b], M, block, seed=3, **parameters)
    _assert_same(got, ref)
    assert got[2].nu.shape == (M, 3)


@pytest.mark.parametrize("name", CLUTTER)
def test_clutter_estimators_take_a_partial_stacked_measurement(name):
    """The stacked z of NN / PDA (one candidate): the present components only, gate of their dimension."""
    a = PositionSensor(name="a", components=("x", "y"), noise_cov=R2)
    a_x = PositionSensor(name="a", components=("x",), noise_cov=R2[:1, :1])
    b = PositionSensor(name="b", components=("x", "y"), noise_cov=RB)
    got = _update(name, np.array([0.3, np.nan, 0.25, 0.5]), [a, b], 3, seed=4)
    ref = _update(name, np.array([0.3, 0.25, 0.5]), [a_x, b], 3, seed=4)
    _assert_same(got, ref)
    assert got[2].associations[0].gate == ref[2].associations[0].gate


# --------------------------------------------------------------------------- nonlinear sensor


SITE = (120.0, -40.0)
AZIMUTH_STD = 0.01


def _polar_prior(M):
    """Targets west of the site, so that their azimuth is near ±π (the wrap matters)."""
    rng = np.random.default_rng(5)
    x0 = np.column_stack([np.full(M, -880.0), rng.standard_normal(M), SITE[1] + np.array([3.0, -2.0, 0.5])[:M], rng.standard_normal(M)])
    P0 = np.stack([np.diag([100.0, 1.0, 100.0, 1.0]) + 5.0 * np.eye(4)[[0, 2]].T @ np.array([[0, 1], [1, 0]]) @ np.eye(4)[[0, 2]]] * M)
    return x0, P0


def _polar_update(name, z, sensor, M=3):
    est = _create(name)
    x0, P0 = _polar_prior(M)
    state = est.predict(est.initialize(x0, P0), bank_of([straight(q=0.01)] * M))
    new, innovation = est.update(state, z, [sensor], LAYOUT)
    return est, new, innovation


@pytest.mark.parametrize("name", EXTENDED)
def test_polar_radar_range_missing_equals_bearing_only(name):
    """radar_polar measures θ = atan2(Δy, Δx) from +x, counter-clockwise: the ``math`` bearing convention."""
    radar = PolarRadarSensor(name="radar", range_std=15.0, azimuth_std=AZIMUTH_STD, site=SITE)
    bearing = BearingSensor(name="radar", sigma=AZIMUTH_STD, observer=np.array(SITE), convention="math")
    theta = -np.pi + 0.004  # the predicted azimuths are near +π: ν wraps across ±π
    got = _polar_update(name, np.array([np.nan, theta]), radar)
    ref = _polar_update(name, np.array([theta]), bearing)
    _assert_same(got, ref)
    assert np.all(np.abs(got[2].nu) < 0.05), "the azimuth innovation is wrapped"


def test_polar_radar_azimuth_missing_equals_hand_computed_ekf():
    """Range only: the EKF update with the range row of the Jacobian, written out."""
    radar = PolarRadarSensor(name="radar", range_std=15.0, azimuth_std=AZIMUTH_STD, site=SITE)
    rho = 1003.0
    est, new, innovation = _polar_update("ekf", np.array([rho, np.nan]), radar)
    x0, P0 = _polar_prior(3)
    tr = straight(q=0.01)
    x = x0 @ tr.F.T + tr.B
    P = tr.F @ P0 @ tr.F.T + tr.process_noise
    dx, dy = x[:, 0] - SITE[0], x[:, 2] - SITE[1]
    r = np.hypot(dx, dy)
    H = np.zeros((3, 1, 4))
    H[:, 0, 0], H[:, 0, 2] = dx / r, dy / r
    nu = (rho - r)[:, None]
    S = H @ P @ np.swapaxes(H, -1, -2) + 15.0**2
    K = P @ np.swapaxes(H, -1, -2) / S
    x_new = x + (K @ nu[..., None])[..., 0]
    A = np.eye(4) - K @ H
    P_new = A @ P @ np.swapaxes(A, -1, -2) + K * 15.0**2 @ np.swapaxes(K, -1, -2)
    nis = nu[:, 0] ** 2 / S[:, 0, 0]
    loglik = -0.5 * (np.log(2 * np.pi * S[:, 0, 0]) + nis)
    assert _rel(est.mean(new), x_new) <= 1e-12
    assert _rel(est.covariance(new), P_new) <= 1e-12
    assert _rel(innovation.nu, nu) <= 1e-12 and _rel(innovation.S, S) <= 1e-12
    assert _rel(innovation.nis, nis) <= 1e-12 and _rel(innovation.loglik, loglik) <= 1e-12


# --------------------------------------------------------------------------- decentralized = centralized


@pytest.mark.parametrize("name", ["decentralized", "srif_decentralized"])
def test_decentralized_with_a_partial_node_equals_centralized(name):
    rng = np.random.default_rng(6)
    s0 = np.array([0.0, 0.0, 0.0, 2.0])
    trs = radii_bank(s0, n_radii=1)  # straight + one left + one right turn: M = 3
    sensors = [
        position_sensor(R2, name="n0"),
        position_sensor(np.array([[0.07]]), ("x",), name="n1"),
        position_sensor(RB * 2.0, name="n2"),
    ]
    _, Z = simulate(trs[1], sensors, s0, 20, rng)
    Z = Z[0].copy()
    Z[3, 0] = np.nan  # n0: x missing
    Z[6, 1] = np.nan  # n0: y missing
    Z[8, [1, 3]] = np.nan  # n0 y missing, n1 missing
    Z[10, [0, 4]] = np.nan  # n0 x missing, n2 y missing
    Z[12, [0, 1, 2, 3]] = np.nan  # only n2's x
    central, dec = _create("kalman"), _create(name)
    M = len(trs)
    x0, P0 = np.tile(s0, (M, 1)), np.stack([np.diag([1.0, 0.5, 1.0, 0.5])] * M)
    sc, sd = central.initialize(x0, P0), dec.initialize(x0, P0)
    bank = bank_of(trs)
    for k in range(Z.shape[0]):
        sc, sd = central.predict(sc, bank), dec.predict(sd, bank)
        sc, ic = central.update(sc, Z[k], sensors, LAYOUT)
        sd, id_ = dec.update(sd, Z[k], sensors, LAYOUT)
        assert id_.measurement_dim == ic.measurement_dim == np.isfinite(Z[k]).sum()
        assert _rel(dec.mean(sd), central.mean(sc)) <= 1e-9
        assert _rel(dec.covariance(sd), central.covariance(sc)) <= 1e-9
        for i in range(sd.nodes):
            assert _rel(sd.node_means[i], central.mean(sc)) <= 1e-9
        assert _rel(id_.nu, ic.nu) <= 1e-9 and _rel(id_.S, ic.S) <= 1e-9
        assert _rel(id_.loglik, ic.loglik) <= 1e-9 and _rel(id_.nis, ic.nis) <= 1e-9


# --------------------------------------------------------------------------- errors, cache, R(z)


def test_missing_pattern_differing_across_the_bank_names_the_sensor():
    est = _create("kalman")
    sensor = PositionSensor(name="pos", components=("x", "y"), noise_cov=R2)
    state = est.initialize(*_prior(3, False, 0))
    z = np.array([[np.nan, 0.1], [0.2, 0.1], [0.3, 0.1]])
    with pytest.raises(ValueError, match=r"sensor 'pos' has NaN in component\(s\) \[0\] for some filters of the bank"):
        est.update(state, z, [sensor], LAYOUT)
    # one filter without x, another without anything: component 1 differs
    z = np.array([[np.nan, 0.1], [np.nan, np.nan], [np.nan, 0.1]])
    with pytest.raises(ValueError, match=r"sensor 'pos' has NaN in component\(s\) \[1\]"):
        est.update(state, z, [sensor], LAYOUT)


def test_cached_step_structure_and_partial_steps_interleave():
    """A complete step, a partial one, a complete one again: each equals a fresh estimator's update."""
    a = PositionSensor(name="a", components=("x", "y"), noise_cov=R2)
    b = PositionSensor(name="b", components=("x", "y"), noise_cov=RB)
    steps = [np.array([0.1, 0.2, 0.3, 0.4]), np.array([0.1, np.nan, 0.3, 0.4]), np.array([0.5, 0.6, 0.7, 0.8]), np.array([np.nan] * 4)]
    for first in (0, 1):
        est = _create("kalman", structure=False)
        x0, P0 = _prior(3, False, 7)
        state = est.initialize(x0, P0)
        for z in steps[first:]:
            ref, inn_ref = _create("kalman", structure=False).update(state, z, [a, b], LAYOUT)
            state_new, inn = est.update(state, z, [a, b], LAYOUT)
            np.testing.assert_array_equal(state_new.mean, ref.mean)
            np.testing.assert_array_equal(state_new.covariance, ref.covariance)
            np.testing.assert_array_equal(inn.nu, inn_ref.nu)
            state = state_new


class _NoiseFromZ(MatrixSensor):
    """A linear sensor whose R depends on z (like radar pseudo-measurements)."""

    def measurement_noise(self, z):
        z = np.asarray(z, dtype=float)
        return self.noise_cov + np.einsum("...i,...j->...ij", z, z)


def test_measurement_dependent_noise_uses_noise_cov_sub_block_when_partial():
    H = np.eye(4)[[0, 2]]
    sensor = _NoiseFromZ(H, R2, name="zr")
    assembler = MeasurementAssembler()
    step = assembler.assemble(np.array([2.0, 3.0]), [sensor], LAYOUT, 1)
    np.testing.assert_array_equal(step.R, R2 + np.outer([2.0, 3.0], [2.0, 3.0]))  # complete row: R(z)
    step = assembler.assemble(np.array([np.nan, 3.0]), [sensor], LAYOUT, 1)
    np.testing.assert_array_equal(step.R, R2[1:, 1:])  # partial row: noise_cov rows/columns
    assert step.models[0].rows == (1,) and step.selection == (2,)
    np.testing.assert_array_equal(step.models[0].H, H[1:])
