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
from hybridtrack.core.validation import as_float_array
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import step_intervals


def batch_measurements(measurements: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], int, int]:
    """The measurements of R runs, sensor name → (R, K+1, m_i) float arrays (NaN: not measured), with R and K+1."""
    if not isinstance(measurements, Mapping) or not measurements:
        raise ValueError("measurements: expected a mapping sensor name → array (runs, K+1, m)")
    arrays = {
        name: as_float_array(value, f"measurements[{name!r}]", (None, None, None), allow_nan=True) for name, value in measurements.items()
    }
    shapes = {a.shape[:2] for a in arrays.values()}
    if len(shapes) != 1:
        raise ValueError(f"measurements: every sensor needs the same (runs, K+1), got {sorted(shapes)}")
    runs, steps = shapes.pop()
    if runs < 1 or steps < 1:
        raise ValueError(f"measurements: expected at least one run and one step, got (runs, K+1) = ({runs}, {steps})")
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


def prior_arrays(prior, runs: int, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-run prior means (R, n) and covariances (R, n, n) from one Gaussian (or (mean (n,), cov (n, n))), or
    per-run means (R, n) with a shared (n, n) or per-run (R, n, n) covariance; ``n`` the state size expected
    (None: any).  Each run's prior is checked as a :class:`~hybridtrack.core.types.Gaussian`."""
    if isinstance(prior, Gaussian):
        priors = [prior] * runs
    elif not isinstance(prior, (tuple, list)) or len(prior) != 2:
        raise ValueError("prior: expected a Gaussian, (mean (n,), cov (n, n)) or per-run (mean (runs, n), cov (runs, n, n))")
    elif np.ndim(prior[0]) == 1:
        priors = [Gaussian(*prior)] * runs
    else:
        mean = as_float_array(prior[0], "prior mean", (runs, None))
        cov = np.broadcast_to(prior[1], (runs,) + np.shape(prior[1])) if np.ndim(prior[1]) == 2 else prior[1]
        cov = as_float_array(cov, "prior cov", (runs, mean.shape[1], mean.shape[1]))
        priors = [Gaussian(mean[r], cov[r]) for r in range(runs)]
    if n is not None and priors[0].mean.shape != (n,):
        raise ValueError(f"prior: expected a mean of the {n} state components, got shape {priors[0].mean.shape}")
    return np.stack([p.mean for p in priors]), np.stack([p.cov for p in priors])


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
