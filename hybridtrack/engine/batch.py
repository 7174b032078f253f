"""The inputs of R runs, checked and stacked for one bank: measurements, times, priors, per-run values.

:meth:`hybridtrack.engine.pipeline.Pipeline.batch` and the algorithms'
``run_batch`` take R runs as one :class:`~hybridtrack.engine.bank.FilterBank`
of R × M filters, row r·M + j being filter j of run r.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from hybridtrack.core.interfaces import Estimator
from hybridtrack.core.types import Gaussian
from hybridtrack.core.validation import as_float_array, check_prior_spread
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import step_intervals


def _length(run) -> int | None:
    """The number of rows of one run's array or nested sequence (None for a scalar)."""
    if isinstance(run, np.ndarray):
        return run.shape[0] if run.ndim else None
    return len(run) if isinstance(run, Sequence) and not isinstance(run, str) else None


def check_run_lengths(value, name: str) -> None:
    """A ValueError naming ``name`` and each run's number of steps when ``value``, the measurements of one sensor
    given as a sequence of per-run arrays (K_r+1, m), holds runs of different lengths (a batch needs one K)."""
    if isinstance(value, np.ndarray) or not isinstance(value, Sequence) or isinstance(value, str) or not value:
        return
    lengths = [_length(run) for run in value]
    if len(set(lengths)) > 1:
        listed = ", ".join(f"run {r}: {k} steps" for r, k in enumerate(lengths[:10])) + (", …" if len(lengths) > 10 else "")
        raise ValueError(
            f"{name}: the runs of a batch need the same number of steps (K+1), got {listed}; run them one by one,"
            " or pad the shorter ones with NaN rows (not measured) to a common length"
        )


def batch_measurements(measurements: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], int, int]:
    """The measurements of R runs, sensor name → (R, K+1, m_i) float arrays (NaN: not measured), with R and K+1.

    A sensor's runs may be given as one array or a sequence of R arrays (K+1, m_i); runs of different lengths
    (:func:`check_run_lengths`) and runs without a step are ValueErrors naming the sensor.
    """
    if not isinstance(measurements, Mapping) or not measurements:
        raise ValueError("measurements: expected a mapping sensor name → array (runs, K+1, m)")
    for name, value in measurements.items():
        check_run_lengths(value, f"measurements[{name!r}]")
    arrays = {
        name: as_float_array(value, f"measurements[{name!r}]", (None, None, None), allow_nan=True) for name, value in measurements.items()
    }
    shapes = {a.shape[:2] for a in arrays.values()}
    if len(shapes) != 1:
        raise ValueError(f"measurements: every sensor needs the same (runs, K+1), got {sorted(shapes)}")
    runs, steps = shapes.pop()
    if runs < 1 or steps < 1:
        sizes = ", ".join(f"{name!r} {a.shape}" for name, a in arrays.items())
        raise ValueError(
            f"measurements: expected at least one run and one step, got (runs, K+1) = ({runs}, {steps}) (sensor shapes {sizes})"
        )
    return arrays, runs, steps


def stacked_measurements(network: SensorNetwork, measurements: Mapping[str, np.ndarray]) -> np.ndarray:
    """z (R, K+1, Σm): every sensor's (R, K+1, m_i) array side by side in the network's order (names and m checked)."""
    arrays, runs, steps = batch_measurements(measurements)
    flat = network.stack({name: value.reshape(runs * steps, *value.shape[2:]) for name, value in arrays.items()})
    return flat.reshape(runs, steps, -1)


def batch_times(times, tau, runs: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Times (R, K+1) and Δt (R, K): ``times`` shared (K+1,) or per run (R, K+1), else ``tau``."""
    if times is None or np.ndim(times) == 1:
        t, dt = step_intervals(times, tau, steps)
        return np.broadcast_to(t, (runs, steps)), np.broadcast_to(dt, (runs, steps - 1))
    t = np.asarray(times, dtype=float)
    if t.shape != (runs, steps):
        raise ValueError(f"times: expected (K+1,) = ({steps},) shared or (runs, K+1) = ({runs}, {steps}) per run, got {t.shape}")
    pairs = [step_intervals(t[r], None, steps) for r in range(runs)]
    out_t, out_dt = np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])
    out_t.setflags(write=False)
    return out_t, out_dt


#: how a prior is built, for the errors of :func:`prior_arrays`
PRIOR_HINT = (
    "expected a hybridtrack.Gaussian, e.g. Gaussian(np.array([x, vx, y, vy]), np.diag([σx², σvx², σy², σvy²])),"
    " the pair (mean (n,), cov (n, n)), or per-run (means (runs, n), covs (runs, n, n))"
)


def _prior_kind(prior) -> str | None:
    """What a prior that is not a Gaussian nor a (mean, cov) pair is (for the TypeError), or None if it may be a pair."""
    if isinstance(prior, Mapping):
        return f"a dict with keys {sorted(map(str, prior))} (build Gaussian(mean, cov) from its entries)"
    if isinstance(prior, np.ndarray):
        return f"an array of shape {prior.shape} (a bare mean? give its covariance too)"
    if not isinstance(prior, (tuple, list)):
        return f"a {type(prior).__name__}"
    if prior and all(np.ndim(v) == 0 for v in prior):
        return f"a sequence of {len(prior)} numbers (a bare mean? give its covariance too)"
    return None


def prior_arrays(prior, runs: int, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-run prior means (R, n) and covariances (R, n, n) from one Gaussian (or (mean (n,), cov (n, n))), or
    per-run means (R, n) with a shared (n, n) or per-run (R, n, n) covariance; ``n`` the state size expected
    (None: any).  Each run's prior is checked as a :class:`~hybridtrack.core.types.Gaussian`, and its standard
    deviations against :data:`~hybridtrack.core.validation.PRIOR_STD_LIMIT` (a diffuse prior is refused).

    A prior of another kind (a dict, a bare mean) is a TypeError naming ``prior`` and showing how to build one;
    a pair of wrong shapes a ValueError."""
    kind = None if isinstance(prior, Gaussian) else _prior_kind(prior)
    if kind is not None:
        raise TypeError(f"prior: {PRIOR_HINT}; got {kind}")
    if isinstance(prior, Gaussian):
        priors = [prior] * runs
    elif len(prior) != 2:
        raise ValueError(f"prior: {PRIOR_HINT}; got a sequence of {len(prior)} items")
    elif np.ndim(prior[0]) == 1:
        priors = [Gaussian(*prior)] * runs
    else:
        mean = as_float_array(prior[0], "prior mean", (runs, None))
        cov = np.broadcast_to(prior[1], (runs,) + np.shape(prior[1])) if np.ndim(prior[1]) == 2 else prior[1]
        cov = as_float_array(cov, "prior cov", (runs, mean.shape[1], mean.shape[1]))
        priors = [Gaussian(mean[r], cov[r]) for r in range(runs)]
    if n is not None and priors[0].mean.shape != (n,):
        raise ValueError(f"prior: expected a mean of the {n} state components, got shape {priors[0].mean.shape}")
    return np.stack([p.mean for p in priors]), check_prior_spread(np.stack([p.cov for p in priors]), "prior")


def per_run(value, runs: int, name: str) -> list:
    """``value`` given per run (a sequence of R, or a mapping run → value) as a list of R (None where absent)."""
    if value is None:
        return [None] * runs
    if isinstance(value, Mapping):
        bad = [r for r in value if not isinstance(r, (int, np.integer)) or not 0 <= r < runs]
        if bad:
            raise ValueError(f"{name}: run indices must be in 0 … {runs - 1}, got {bad}")
        return [value.get(r) for r in range(runs)]
    if isinstance(value, Sequence) and not isinstance(value, str) and len(value) == runs:
        return list(value)
    raise ValueError(f"{name}: expected a mapping run index → value or a sequence of {runs} (one per run)")


def run_groups(estimator: Estimator, runs: int) -> list[np.ndarray]:
    """The runs that share one bank: all of them for a centralized, non-sampling estimator, else each run alone
    (a decentralized one's node copies and a particle filter's streams stay per run, on a batch of one)."""
    if not getattr(estimator, "sampling", False) and type(estimator).node_scores is Estimator.node_scores:
        return [np.arange(runs)]
    return [np.array([r]) for r in range(runs)]
