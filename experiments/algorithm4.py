"""Algorithm 4 (seed 000) against Monte Carlo: mean SPRT decision time for pairs of modes.

    python experiments/algorithm4.py [--runs 2000]

For each pair (mode 0, mode p) and each true mode, a two-hypothesis SPRT
λ_k = Σ (ℓ_p − ℓ_0) runs from the switching moment on real Kalman filters
(the runs stacked as one bank): both filters start from x̂ = x_s + e,
e ~ N(0, P⁺_0) (P⁺_0 the steady posterior covariance of mode 0's filter), with
ω and the turn centre fixed from the true switch state (Algorithm 4's
assumptions).  Predictions: the seed's steady-state N (when μ has a limit),
and the transient N from the cumulative expected drift with steady gains (the
seed's Σ̄ recursion) and with each filter's own Riccati recursion.
Example 1 setting: τ = 0.1, Q = R = diag(0.01, 0.01), x_s = [0, 0, 0, 2].
Writes docs/results/algorithm4.json and .md.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from hybridtrack.algorithms import algorithm4 as wald
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.sdk.thresholds import sprt_thresholds
from hybridtrack_plugins.filters.kalman import KalmanFilter
from hybridtrack_plugins.motion.linear_modes import LeftTurn, RightTurn, Straight
from hybridtrack_plugins.sensors.position import PositionSensor

ROOT = Path(__file__).resolve().parents[1]
TAU, XS = 0.1, np.array([0.0, 0.0, 0.0, 2.0])
H, R = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]]), 0.01 * np.eye(2)
LAYOUT = ("x", "vx", "y", "vy")
PAIRS = {
    "straight vs right r=5": (Straight(), RightTurn(radius=5.0)),
    "straight vs left r=3": (Straight(), LeftTurn(radius=3.0)),
    "right r=5 vs straight": (RightTurn(radius=5.0), Straight()),
}


def monte_carlo(model_0, model_p, true, alpha, beta, runs, horizon, seed):
    rng = np.random.default_rng(seed)
    t0, tp, tt = (m.transition(TAU, XS) for m in (model_0, model_p, true))
    P0 = wald.steady_state_filter(t0.F, H, t0.process_noise, R).P_posterior
    upper, lower = sprt_thresholds(alpha, beta)
    x = np.tile(XS, (runs, 1))
    start = XS + rng.standard_normal((runs, 4)) @ np.linalg.cholesky(P0).T
    kf, sensor = KalmanFilter(), PositionSensor(noise_cov=R)
    state = kf.initialize(np.concatenate([start, start]), np.tile(P0, (2 * runs, 1, 1)))
    bank = TransitionBank(
        np.concatenate([np.tile(t0.F, (runs, 1, 1)), np.tile(tp.F, (runs, 1, 1))]),
        np.concatenate([np.tile(t0.B, (runs, 1)), np.tile(tp.B, (runs, 1))]),
        np.concatenate([np.tile(t0.process_noise, (runs, 1, 1)), np.tile(tp.process_noise, (runs, 1, 1))]),
    )
    Lq = np.linalg.cholesky(true.noise_cov)
    lam = np.zeros(runs)
    stop = np.full(runs, np.nan)
    accepted_p = np.zeros(runs, dtype=bool)
    for k in range(1, horizon + 1):
        x = tt.apply(x) + (rng.standard_normal((runs, 2)) @ Lq.T) @ tt.G.T
        z = x[:, [0, 2]] + 0.1 * rng.standard_normal((runs, 2))
        state = kf.predict(state, bank)
        state, innovation = kf.update(state, np.concatenate([z, z]), [sensor], LAYOUT)
        running = np.isnan(stop)
        lam = np.where(running, lam + innovation.loglik[runs:] - innovation.loglik[:runs], lam)
        hit = running & ((lam >= upper) | (lam <= lower))
        stop[hit] = k
        accepted_p |= hit & (lam >= upper)
        if not np.isnan(stop).any():
            break
    done = ~np.isnan(stop)
    return {
        "mean_decision_time": float(np.nanmean(stop)),
        "median": float(np.nanmedian(stop)),
        "std_error": float(np.nanstd(stop, ddof=1) / np.sqrt(done.sum())),
        "undecided": int((~done).sum()),
        "accepted_alternative": float(accepted_p[done].mean()),
    }


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=2000)
    parser.add_argument("--horizon", type=int, default=300)
    args = parser.parse_args(argv)
    results = {}
    for alpha, beta in ((0.05, 0.05), (0.01, 0.01)):
        for name, (m0, mp) in PAIRS.items():
            t0, tp = (m.transition(TAU, XS) for m in (m0, mp))
            f0, fp = (t0.F, t0.B, t0.process_noise), (tp.F, tp.B, tp.process_noise)
            steady = wald.wald_pair(f0, fp, H, R, XS, alpha, beta, horizon=args.horizon, gains="steady")
            own = wald.wald_pair(f0, fp, H, R, XS, alpha, beta, horizon=args.horizon, gains="transient")
            row = {
                "predicted": {
                    "N_0p_steady_limit": steady.n_0p_steady,
                    "N_p0_steady_limit": steady.n_p0_steady,
                    "N_0p_transient_steady_gains": steady.n_0p_transient,
                    "N_p0_transient_steady_gains": steady.n_p0_transient,
                    "N_0p_transient_own_gains": own.n_0p_transient,
                    "N_p0_transient_own_gains": own.n_p0_transient,
                    "bank_size_M_p": steady.bank_size,
                    "mu_0p_last": float(steady.mu_0p[-1]),
                    "mu_p0_last": float(steady.mu_p0[-1]),
                },
                "monte_carlo_data_mode_0": monte_carlo(m0, mp, m0, alpha, beta, args.runs, args.horizon, seed=1),
                "monte_carlo_data_mode_p": monte_carlo(m0, mp, mp, alpha, beta, args.runs, args.horizon, seed=2),
            }
            results[f"{name}, alpha=beta={alpha}"] = row
            print(name, alpha, json.dumps(row))
    out = ROOT / "docs" / "results" / "algorithm4"
    out.with_suffix(".json").write_text(json.dumps({"setup": __doc__, "runs": args.runs, "results": results}, indent=2))
    lines = [
        "| pair, α = β | data | Algorithm 4 steady-state N | transient N (steady gains) | transient N (own gains) | Monte Carlo mean N ± s.e. | MC median | MC accepts H_p |",
        "|---|---|---|---|---|---|---|---|",
    ]
    fmt = lambda v: "no limit" if v is None else ("∞" if v == float("inf") else f"{v:.1f}")  # noqa: E731
    for key, row in results.items():
        p = row["predicted"]
        for data, suffix, mc in (("mode 0", "0p", row["monte_carlo_data_mode_0"]), ("mode p", "p0", row["monte_carlo_data_mode_p"])):
            lines.append(
                f"| {key} | {data} | {fmt(p[f'N_{suffix}_steady_limit'])} | {fmt(p[f'N_{suffix}_transient_steady_gains'])} | "
                f"{fmt(p[f'N_{suffix}_transient_own_gains'])} | {mc['mean_decision_time']:.1f} ± {mc['std_error']:.1f} | {mc['median']:.0f} | {mc['accepted_alternative']:.1%} |"
            )
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    return results


if __name__ == "__main__":
    main()
