"""MultipleModelEstimator.run_batch's inputs named in errors (its equivalence with the runs alone is
tests/engine/test_batch.py), the sojourn-time matrices against scipy's expm, and the grouped transitions of its banks."""

import numpy as np
import pytest

from hybridtrack.algorithms.multiple_model import MultipleModelEstimator, sojourn_matrix
from hybridtrack_plugins.motion.linear_modes import LeftTurn, Straight
from hybridtrack_plugins.sensors.position import PositionSensor

RUNS, STEPS = 4, 16
SENSORS = [PositionSensor(name="a", noise_cov=np.diag([0.5, 0.8])), PositionSensor(name="b", components="x", noise_cov=[[0.3]])]
TOL = {"rtol": 1e-12, "atol": 1e-12}


def data(seed=3):
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.5, 1.5, size=(RUNS, STEPS)), axis=1)
    t = times - times[:, :1]
    x = np.stack([t[r] * (1.0 + 0.2 * r) for r in range(RUNS)])  # straight runs at different speeds
    y = np.stack([np.sin(0.3 * t[r]) * 5 for r in range(RUNS)])
    z = {
        "a": np.stack([x, y], axis=-1) + rng.normal(0, 0.7, (RUNS, STEPS, 2)),
        "b": x[..., None] + rng.normal(0, 0.5, (RUNS, STEPS, 1)),
    }
    z["b"][0, 4:8] = np.nan  # run 0 lacks sensor b
    z["a"][1, 6, 0] = np.nan  # run 1 lacks one component
    z["a"][2, 10], z["b"][2, 10] = np.nan, np.nan  # run 2: prediction only
    means = np.stack([[0.0, 1.0 + 0.2 * r, 0.0, 0.5] for r in range(RUNS)])
    covs = np.stack([np.diag([1.0, 0.5, 1.0, 0.5]) * (1 + r) for r in range(RUNS)])
    return z, times, (means, covs)


def test_batch_input_errors_name_the_argument():
    z, times, prior = data()
    mm = MultipleModelEstimator([Straight(), Straight(noise_cov=np.eye(2))], sojourn=5.0, sensors=SENSORS)
    with pytest.raises(ValueError, match="times"):
        mm.run_batch(z, prior, times=times[:2])
    with pytest.raises(ValueError, match="measurements"):
        mm.run_batch({n: a[0] for n, a in z.items()}, prior, times=times)
    with pytest.raises(ValueError, match="recorders"):
        mm.run_batch(z, prior, times=times, recorders={RUNS: None})


def test_sojourn_matrices_equal_scipy_expm_one_at_a_time_and_stacked():
    import scipy.linalg

    sojourn = np.array([1.0, 2.0, 5.0, 0.5])
    r = sojourn.size
    generator = np.repeat((1 / sojourn / (r - 1))[:, None], r, axis=1)
    np.fill_diagonal(generator, -1 / sojourn)
    steps = np.array([1e-4, 0.1, 1.0, 7.5])
    stacked = sojourn_matrix(sojourn, steps)
    for dt, P in zip(steps, stacked):
        np.testing.assert_allclose(P, scipy.linalg.expm(generator * dt), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(sojourn_matrix(sojourn, dt), P, rtol=1e-14, atol=1e-16)


def test_grouped_transitions_equal_the_stacked_per_filter_transitions():
    """The IMM/GPB banks' transitions (one transition_bank call per model and Δt) equal TransitionBank.stack of each
    filter's transition(Δt_i, x_i) to 1e-12, in filter order, with the noise roots."""
    from hybridtrack.core.interfaces import TransitionBank
    from hybridtrack.engine.bank import grouped_transitions
    from hybridtrack_plugins.motion.linear_modes import RightTurn

    rng = np.random.default_rng(4)
    kinds = [Straight(noise_cov=np.eye(2) * 0.01), LeftTurn(radius=20.0), RightTurn(radius=7.0, noise_cov=np.eye(2) * 0.3)]
    models = [kinds[i] for i in rng.integers(0, 3, 12)]
    x = rng.normal(0, 3, (12, 4))
    for dts in (0.5, rng.choice([0.5, 1.25], 12)):
        bank = grouped_transitions(models, dts, x)
        steps = np.broadcast_to(dts, (12,))
        reference = TransitionBank.stack([m.transition(float(d), xi) for m, d, xi in zip(models, steps, x)])
        for field in ("F", "B", "Q", "noise_root"):
            np.testing.assert_allclose(getattr(bank, field), getattr(reference, field), **TOL, err_msg=field)
    with pytest.raises(ValueError, match="switch_states"):
        grouped_transitions(models, 0.5, x[:3])
