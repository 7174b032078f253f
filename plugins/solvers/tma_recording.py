"""Recording a bearings-only TMA run through the recorder seam (entity paths: docs/recording.md).

Timeline ``step`` = bearing index k, ``time`` = t_k seconds.  The bearing lines
run along X_k as far as the first solution's track at t_k (so they fan in on
it); a solution's track is x(t_k) = x0 + v (t_k − t_r), its 2σ position ellipse
P(t) = Φ(t) P_θ Φ(t)ᵀ, Φ(t) = [[I, (t − t_r) I], [0, I]] (seed 002 §4: uniform
motion); residuals X_k − f_k(θ̂) wrapped, in degrees; ``events/decisions`` one
line per solution (θ̂, √Ka, χ² test, iterations).

No hook: a helper of the solver family, not a plugin.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hybridtrack.sdk.linalg import wrap_angle
from hybridtrack_plugins.sensors.bearing import bearing, direction
from hybridtrack_plugins.solvers.tma_model import BearingsProblem, TMASolution, propagate


def track_covariances(covariance: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """P(t) = Φ(t) P_θ Φ(t)ᵀ for θ = (x0, y0, vx, vy) moved by dt (K,) → (K, 4, 4)."""
    Phi = np.tile(np.eye(4), (dt.size, 1, 1))
    Phi[:, 0, 2] = Phi[:, 1, 3] = dt
    return Phi @ covariance @ np.swapaxes(Phi, -1, -2)


def record_tma(recorder, problem: BearingsProblem, solutions: Mapping[str, TMASolution], truth=None) -> None:
    """Log the observer, the bearings, the solutions (tracks, ellipses, residuals) and the truth θ (if given)."""
    steps = np.arange(problem.size)
    times = np.asarray(problem.times)
    dt = times - problem.reference_time
    recorder.log_path("world/observer", steps, problem.observer, times)
    if truth is not None:
        recorder.log_path("world/truth", steps, propagate(truth, dt)[:, :2], times)
    tracks = {name: propagate(solution.parameters, dt) for name, solution in solutions.items()}
    if tracks:
        first = next(iter(tracks.values()))
        length = np.hypot(*(first[:, :2] - problem.observer).T)
        ux, uy = direction(problem.bearings, problem.convention)
        ends = problem.observer + length[:, None] * np.stack([ux, uy], axis=-1)
        recorder.log_lines("world/bearings", steps, problem.observer, ends, times)
    for name, solution in solutions.items():
        estimate = tracks[name]
        recorder.log_path(f"world/estimate/{name}", steps, estimate[:, :2], times)
        recorder.log_ellipses(
            f"world/estimate/{name}/ellipse", steps, estimate[:, :2], track_covariances(solution.covariance, dt)[:, :2, :2], times
        )
        relative = estimate[:, :2] - problem.observer
        predicted = bearing(relative[:, 0], relative[:, 1], problem.convention)
        residual = np.rad2deg(wrap_angle(problem.bearings - predicted))
        recorder.log_scalars(f"solver/{name}/residual", steps, residual, times)
        x0, y0, vx, vy = solution.parameters
        recorder.log_event(
            int(steps[-1]),
            f"{name}: x0={x0:.1f} m y0={y0:.1f} m vx={vx:.3f} m/s vy={vy:.3f} m/s, √Ka={solution.sqrt_ka_deg:.3f}°,"
            f" χ² p={solution.chi2_pvalue:.3g}, iterations {solution.iterations}, evaluations {solution.evaluations}",
            float(times[-1]),
        )
