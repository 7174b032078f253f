"""Algorithm 3's bank over modes of different state layouts: straight (x, vx, y, vy) and the coordinated turn with
ω in the state, in one bank in their union layout (issue 22: the SPRTs mix 4-, 5- and 6-state hypotheses)."""

import numpy as np
import pytest

from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.core.plugins import resolve

DT, SPEED, RADIUS, STRAIGHT, TURN = 2.0, 10.0, 200.0, 40, 40


def _leg(seed):
    """North at 10 m/s, then a left turn of 200 m (ω = 0.05 rad/s), fixes 2 s apart with σ = 5 m."""
    rng = np.random.default_rng(seed)
    t = np.arange(STRAIGHT + TURN + 1) * DT
    pos = np.zeros((t.size, 2))
    pos[: STRAIGHT + 1, 1] = SPEED * t[: STRAIGHT + 1]
    angle = SPEED / RADIUS * (t[STRAIGHT:] - t[STRAIGHT])
    pos[STRAIGHT:] = pos[STRAIGHT] + np.array([-RADIUS, 0.0]) + RADIUS * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    return t, pos + rng.normal(0.0, 5.0, pos.shape)


def _algorithm(**options):
    sensor = resolve("sensor", ("position", {"name": "p", "noise_cov": 25.0 * np.eye(2)}))
    modes = [("straight", {"noise_density": 0.01}), ("coordinated_turn", {"noise_density": 0.01})]
    options = {"missing_variance": {"omega": 1e-3}} | options
    return UnknownChangeAdaptive(modes=modes, sensors=[sensor], alpha=0.01, beta=0.01, **options)


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_the_change_to_the_turn_rate_mode_is_found_and_its_rate_estimated(seed):
    t, z = _leg(seed)
    alg = _algorithm(bank_size=20)
    assert alg.layout == ("x", "vx", "y", "vy", "omega")
    prior = (np.array([z[0, 0], 0.0, z[0, 1], SPEED, 0.0]), np.diag([25.0, 4.0, 25.0, 4.0, 1e-3]))
    run = alg.run({"p": z}, prior, times=t)
    turns = [c for c in run.changes if c.mode == "coordinated_turn"]
    assert turns and STRAIGHT <= turns[0].step <= STRAIGHT + 10, run.changes
    assert np.all(run.mode[10:STRAIGHT] == 0)  # straight on the straight leg
    assert run.means.shape == (t.size, 5)
    assert np.median(run.means[STRAIGHT + 15 :, 4]) == pytest.approx(SPEED / RADIUS, rel=0.15)


def test_runs_together_equal_runs_alone():
    legs = [_leg(seed) for seed in (7, 8)]
    alg = _algorithm(bank_size=10)
    priors = [(np.array([z[0, 0], 0.0, z[0, 1], SPEED, 0.0]), np.diag([25.0, 4.0, 25.0, 4.0, 1e-3])) for _, z in legs]
    alone = [alg.run({"p": z}, p, times=t) for (t, z), p in zip(legs, priors)]
    together = alg.run_batch(
        {"p": np.stack([z for _, z in legs])},
        (np.stack([p[0] for p in priors]), np.stack([p[1] for p in priors])),
        times=np.stack([t for t, _ in legs]),
    )
    for a, b in zip(alone, together):
        np.testing.assert_allclose(b.means, a.means, rtol=1e-12, atol=1e-9)
        assert np.array_equal(a.mode, b.mode)


def test_algorithm4_bank_size_needs_one_layout():
    with pytest.raises(ValueError, match="'algorithm4' needs modes of one state layout"):
        _algorithm(bank_size="algorithm4")


def test_a_bad_missing_variance_is_named():
    with pytest.raises(ValueError, match="missing_variance"):
        _algorithm(bank_size=5, missing_variance={"omega": -1.0})
