"""The sojourn-time matrices of MultipleModelEstimator against scipy's expm, and the grouped transitions of its
banks (its batch equivalence and its named input errors are in tests/engine/test_batch.py)."""

import numpy as np
import pytest

from hybridtrack.algorithms.multiple_model import sojourn_matrix
from hybridtrack_plugins.motion.linear_modes import LeftTurn, Straight

TOL = {"rtol": 1e-12, "atol": 1e-12}


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
