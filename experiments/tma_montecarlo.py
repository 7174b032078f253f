"""Monte Carlo of seed 002 §5.1: Levenberg–Marquardt vs N-bearings on the three-leg scenario.

    python experiments/tma_montecarlo.py --n 10000 --sigma 0.1 0.5 1.0 --seed 2021 \
        --json docs/results/tma_montecarlo.json --markdown docs/results/tma_montecarlo.md

Targets are drawn at the start of the observation as the seed says (bearing 0°,
range U(5, 50) km, course U(0°, 180°), speed U(5, 15) m/s); the same targets are
used for every σ (common random numbers), each σ with its own noise stream.
Every target is solved by the batched LM (from the seed's prior guess) and by
N-bearings.  Errors (bearing, relative range, course, relative speed) are
measured at the start of the observation (t = 0, where the targets are drawn,
the primary ``ref``) and at its end (t = last bearing, ``ref_end``).  A target
counts for Ref_j when all four errors are inside region j.  √Ka, Nf and Iter are
means over the targets.

``--plot [PNG]`` draws the success fractions Ref1–Ref4 against σ, ours and
the seed's, for both methods (:func:`plot`, default
``docs/images/tma_montecarlo.png``); ``--plot-only JSON`` only draws, from an
existing report.

Recursive filters (seed 004 / issue 17): at σ = ``FILTER_SIGMA`` (0.5°) the first
``--filter-n`` targets (default 50; the docs use 200) are also tracked, on the same bearings, by
``particle`` (``--particles`` per target, regularised) and ``gaussian_sum``
(EKF components), both started from the range-parameterised prior of the first
bearing (:func:`hybridtrack_plugins.filters.gaussian_sum.range_parameterised`:
ranges 5–50 km — the seed's range interval — in ``FILTER_COMPONENTS`` geometric
steps; velocity 0 ± 10 m/s per axis); the particle filter draws its particles
from that mixture.  Motion: constant velocity with a negligible process noise
(the targets move straight).  A filter has an estimate at the end only, so its
row has ``ref_end`` (errors at the last bearing) and ``ref`` null; the row
``LM (filter targets)`` gives LM's fractions on the same targets for comparison.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from hybridtrack.apps.reporting import save_figure
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import get_registry
from hybridtrack.sdk.linalg import wrap_angle
from hybridtrack_plugins.filters.gaussian_sum import GaussianSumFilter, range_parameterised
from hybridtrack_plugins.filters.particle import ParticleFilter
from hybridtrack_plugins.sensors.bearing import BearingSensor
from hybridtrack_plugins.solvers.levenberg_marquardt import BatchLevenbergMarquardt, LMSettings
from hybridtrack_plugins.solvers.n_bearings import NBearings
from hybridtrack_plugins.solvers.observer import Seed002Scenario, simulate_bearings
from hybridtrack_plugins.solvers.tma_model import BearingsBatch, UnobservabilityWarning, kinematics

#: success regions (bearing °, range fraction, course °, speed fraction), seed 002 §5.1
REFS = ((0.5, 0.05, 5.0, 0.05), (1.0, 0.10, 10.0, 0.10), (1.0, 0.15, 10.0, 0.10), (1.0, 0.15, 10.0, 0.15))

#: the seed's table (10,000 targets): method, σ°, Ref1..4, √Ka°, Nf, Iter
SEED_TABLE = (
    ("LM", 0.0, (1.000, 1.000, 1.000, 1.000), 0.00, 10, 9),
    ("N", 0.0, (1.000, 1.000, 1.000, 1.000), 0.00, None, None),
    ("LM", 0.1, (0.942, 0.983, 0.983, 0.992), 0.10, 10, 9),
    ("N", 0.1, (0.560, 0.758, 0.759, 0.848), 0.11, None, None),
    ("LM", 0.2, (0.862, 0.942, 0.942, 0.968), 0.20, 10, 9),
    ("N", 0.2, (0.307, 0.517, 0.524, 0.614), 0.21, None, None),
    ("LM", 0.3, (0.782, 0.900, 0.900, 0.936), 0.30, 10, 9),
    ("N", 0.3, (0.189, 0.351, 0.358, 0.442), 0.33, None, None),
    ("LM", 0.5, (0.636, 0.822, 0.823, 0.877), 0.50, 10, 9),
    ("N", 0.5, (0.049, 0.146, 0.148, 0.228), 0.61, None, None),
    ("LM", 1.0, (0.380, 0.635, 0.651, 0.739), 1.00, 10, 9),
    ("N", 1.0, (0.001, 0.012, 0.015, 0.022), 1.72, None, None),
)


#: the filters run at this σ (degrees) only
FILTER_SIGMA = 0.5
#: range-parameterised prior: components over the seed's range interval, velocity prior (m/s per axis)
FILTER_COMPONENTS = 8
FILTER_RANGES = (5_000.0, 50_000.0)
FILTER_SPEED_SIGMA = 10.0
#: process noise of the constant-velocity filter model (m²/s³ per axis; the targets move straight)
FILTER_Q = 1e-6
LAYOUT = ("x", "vx", "y", "vy")


def run_filters(theta, X, times, observer, sigma: float, particles: int, seed: int, convention: str) -> dict:
    """Track targets θ (n, 4) from their bearings X (n, T) with ``particle`` and ``gaussian_sum`` (module docstring).

    Each target is one filter of a bank (its own bearing per step).  Returns per method the end estimate as θ̂ at
    t = 0 (the end state propagated back along its own velocity, so :func:`errors` at t_end measures the end state).
    """
    n, T = X.shape
    model = get_registry().create("motion_model", "straight", noise_cov=np.eye(2) * FILTER_Q)
    means, covs, weights = range_parameterised(
        observer[0], X[:, 0], sigma, *FILTER_RANGES, FILTER_COMPONENTS, FILTER_SPEED_SIGMA, layout=LAYOUT, convention=convention
    )
    sensor = BearingSensor(name="bearing", sigma=sigma, observer=observer[0], convention=convention)
    estimators = {
        "particle": ParticleFilter(particles=particles, regularize=True, seed=seed),
        "gaussian_sum": GaussianSumFilter(max_components=FILTER_COMPONENTS * 2),
    }
    out = {}
    for name, estimator in estimators.items():
        started = time.perf_counter()
        state = estimator.initialize_mixture(means, covs, weights)
        bank = None
        for k in range(T):
            if k:
                dt = times[k] - times[k - 1]
                if bank is None or bank[0] != dt:
                    bank = (dt, TransitionBank.stack([model.transition(dt, np.zeros(4))] * n))
                state = estimator.predict(state, bank[1])
            state, _ = estimator.update(state, X[:, k, None], [sensor.at(observer[k])], LAYOUT)
        x = estimator.mean(state)
        t_end = times[-1] - times[0]
        out[name] = (
            np.stack([x[:, 0] - x[:, 1] * t_end, x[:, 2] - x[:, 3] * t_end, x[:, 1], x[:, 3]], axis=-1),
            time.perf_counter() - started,
        )
    return out


def errors(theta_hat, theta, t, observer_position, convention):
    """|bearing error| °, |range error|/range, |course error| °, |speed error|/speed at time t (θ at t = 0)."""
    b_hat, r_hat, c_hat, v_hat = kinematics(theta_hat, t, 0.0, observer_position, convention)
    b, r, c, v = kinematics(theta, t, 0.0, observer_position, convention)
    return (
        np.rad2deg(np.abs(wrap_angle(b_hat - b))),
        np.abs(r_hat - r) / r,
        np.rad2deg(np.abs(wrap_angle(c_hat - c))),
        np.abs(v_hat - v) / v,
    )


def ref_fractions(errs) -> list[float]:
    """Fraction of targets inside each Ref region (NaN answers count as outside)."""
    e_b, e_r, e_c, e_v = errs
    return [float(np.mean((e_b <= b) & (e_r <= r) & (e_c <= c) & (e_v <= v))) for b, r, c, v in REFS]


def run(
    n: int,
    sigmas_deg,
    seed: int,
    chunk: int = 2000,
    settings: LMSettings | None = None,
    scenario=None,
    filter_n: int = 50,
    particles: int = 2000,
):
    """The Monte Carlo; returns the result dict (rows + protocol)."""
    scenario = scenario or Seed002Scenario()
    settings = settings or LMSettings()
    times, observer, prior = scenario.times(), scenario.observer(), scenario.prior_theta()
    streams = np.random.SeedSequence(seed).spawn(1 + len(sigmas_deg))
    targets = scenario.draw_targets(np.random.default_rng(streams[0]), n)
    lm, nb = BatchLevenbergMarquardt(settings), NBearings()
    rows, started = [], time.perf_counter()
    for sigma_deg, stream in zip(sigmas_deg, streams[1:]):
        rng = np.random.default_rng(stream)
        sigma = float(np.deg2rad(sigma_deg))
        collected = {"LM": [], "N": []}
        filter_bearings = []
        for a in range(0, n, chunk):
            theta = targets[a : a + chunk]
            X = simulate_bearings(theta, times, observer, sigma, rng, scenario.convention)
            if sigma_deg == FILTER_SIGMA and a < filter_n:
                filter_bearings.append(X[: filter_n - a])
            batch = BearingsBatch(times, X, observer, sigma=sigma, initial=prior, convention=scenario.convention)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UnobservabilityWarning)  # counted below through `converged`
                collected["LM"].append(lm.solve_batch(batch))
                collected["N"].append(nb.solve_batch(batch))
        for method, parts in collected.items():
            params = np.concatenate([p.parameters for p in parts])
            start = errors(params, targets, 0.0, observer[0], scenario.convention)
            end = errors(params, targets, times[-1], observer[-1], scenario.convention)
            its = np.concatenate([p.iterations for p in parts])
            nfs = np.concatenate([p.evaluations for p in parts])
            rows.append(
                {
                    "method": method,
                    "sigma_deg": float(sigma_deg),
                    "ref": ref_fractions(start),
                    "ref_end": ref_fractions(end),
                    "sqrt_ka_deg": float(np.nanmean(np.concatenate([p.sqrt_ka_deg for p in parts]))),
                    "nf": float(nfs.mean()) if method == "LM" else None,
                    "iter": float(its.mean()) if method == "LM" else None,
                    "nf_median": float(np.median(nfs)) if method == "LM" else None,
                    "iter_median": float(np.median(its)) if method == "LM" else None,
                    "converged": float(np.mean(np.concatenate([p.converged for p in parts]))),
                }
            )
        if filter_bearings and sigma > 0:
            X = np.concatenate(filter_bearings)
            m = X.shape[0]
            lm_params = np.concatenate([p.parameters for p in collected["LM"]])[:m]
            end_lm = errors(lm_params, targets[:m], times[-1], observer[-1], scenario.convention)
            rows.append(_filter_row("LM (filter targets)", sigma_deg, m, ref_fractions(end_lm), None))
            for method, (theta_hat, seconds) in run_filters(
                targets[:m], X, times, observer, sigma, particles, seed, scenario.convention
            ).items():
                end = errors(theta_hat, targets[:m], times[-1], observer[-1], scenario.convention)
                rows.append(_filter_row(method, sigma_deg, m, ref_fractions(end), seconds))
        print(f"σ = {sigma_deg}° done ({time.perf_counter() - started:.1f} s)", file=sys.stderr)
    protocol = {
        "seed_document": "002 (bearings-only TMA report, §5.1)",
        "targets": n,
        "seed": seed,
        "sigmas_deg": [float(s) for s in sigmas_deg],
        "scenario": "observer 5 m/s: 0° 180 s; turn to 270° at 0.5°/s (180 s); 270° 300 s; turn to 90° (360 s, "
        f"the 180° tie broken to the {scenario.tie}, i.e. increasing course); 90° 180 s",
        "bearings": f"every {scenario.interval} s from t = 0: {len(times)} bearings, last at {times[-1]} s",
        "convention": f"{scenario.convention}: bearing and course clockwise from north, x east, y north",
        "prior_guess": "bearing 0°, range 25 km, course 90°, speed 10 m/s (LM start)",
        "target_draw": "at t = 0: bearing 0°, range U(5, 50) km, course U(0°, 180°), speed U(5, 15) m/s; the same targets for every σ",
        "refs": {
            f"Ref{j + 1}": {"bearing_deg": b, "range_fraction": r, "course_deg": c, "speed_fraction": v}
            for j, (b, r, c, v) in enumerate(REFS)
        },
        "error_time": "ref: start of the observation (t = 0, where targets are drawn); ref_end: end (t = last bearing)",
        "sqrt_ka": "mean over targets of √(F(θ̂)/n) in degrees (F the ML cost at the method's answer)",
        "nf_iter": "means over targets (medians in nf_median / iter_median); null for N-bearings (closed form)",
        "lm_settings": {
            "lam0": settings.lam0,
            "lam_up": settings.lam_up,
            "lam_down": settings.lam_down,
            "F_tol_rad2": settings.F_tol,
            "max_iterations": settings.max_iterations,
            "lam_max": settings.lam_max,
        },
        "filters": {
            "sigma_deg": FILTER_SIGMA,
            "targets": min(filter_n, n),
            "particles": particles,
            "prior": f"range-parameterised from the first bearing: {FILTER_COMPONENTS} components over "
            f"{FILTER_RANGES[0]:g}–{FILTER_RANGES[1]:g} m, velocity 0 ± {FILTER_SPEED_SIGMA:g} m/s per axis",
            "motion": f"constant velocity, process noise {FILTER_Q:g} I",
            "gaussian_sum": f"merge d² ≤ 4, prune w < 1e-5, at most {FILTER_COMPONENTS * 2} components",
            "particle": "bootstrap SIR, systematic resampling at N_eff < N/2, regularised",
        },
        "wall_time_s": round(time.perf_counter() - started, 2),
        "python": platform.python_version(),
        "numpy": np.__version__,
    }
    return {"rows": rows, "protocol": protocol}


def _filter_row(method: str, sigma_deg: float, targets: int, ref_end: list, seconds: float | None) -> dict:
    """A row measured at the end time only (recursive filters, and LM on the same targets)."""
    return {
        "method": method,
        "sigma_deg": float(sigma_deg),
        "targets": targets,
        "ref": None,
        "ref_end": ref_end,
        "sqrt_ka_deg": None,
        "nf": None,
        "iter": None,
        "seconds": None if seconds is None else round(seconds, 2),
    }


def markdown(result) -> str:
    """Our table next to the seed's (same σ)."""
    seed = {(m, s): (ref, ka, nf, it) for m, s, ref, ka, nf, it in SEED_TABLE}
    lines = [
        "| method | σ (°) | source | Ref1 | Ref2 | Ref3 | Ref4 | √Ka (°) | Nf | Iter |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]

    def fmt(value, digits):
        return "–" if value is None else f"{value:.{digits}f}"

    for row in result["rows"]:
        key = (row["method"], row["sigma_deg"])
        if row["ref"] is None:
            lines.append(
                f"| {key[0]} | {key[1]:g} | ours, end ({row['targets']} targets) | "
                + " | ".join(f"{x:.3f}" for x in row["ref_end"])
                + " | | | |"
            )
            continue
        if key in seed:
            ref, ka, nf, it = seed[key]
            lines.append(
                f"| {key[0]} | {key[1]:g} | seed | " + " | ".join(f"{x:.3f}" for x in ref) + f" | {ka:.2f} | {fmt(nf, 0)} | {fmt(it, 0)} |"
            )
        lines.append(
            f"| {key[0]} | {key[1]:g} | ours, start | "
            + " | ".join(f"{x:.3f}" for x in row["ref"])
            + f" | {row['sqrt_ka_deg']:.2f} | {fmt(row['nf'], 1)} | {fmt(row['iter'], 1)} |"
        )
        lines.append(f"| {key[0]} | {key[1]:g} | ours, end | " + " | ".join(f"{x:.3f}" for x in row["ref_end"]) + " | | | |")
    return "\n".join(lines) + "\n"


#: where ``--plot`` writes by default
PLOT = Path(__file__).resolve().parents[1] / "docs" / "images" / "tma_montecarlo.png"
_COLOURS = {"LM": "#1f77b4", "N": "#d62728"}


def plot(report: str | Path, png: str | Path = PLOT) -> Path:
    """Success fractions Ref1–Ref4 against the bearing noise σ, from the JSON report: a PNG at ``png``.

    One panel per success region (seed 002 §5.1, :data:`REFS`); per method
    (LM, N-bearings) our fractions at the start of the observation (``rows[i]
    ["ref"]``, solid) and the seed's table at every σ it gives
    (:data:`SEED_TABLE`, dashed).  With a single σ in the report each panel
    still shows that point against the seed's curve.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = json.loads(Path(report).read_text(encoding="utf-8"))
    rows = data["rows"]
    figure, axes = plt.subplots(1, len(REFS), figsize=(13, 3.4), sharey=True)
    for j, axis in enumerate(axes):
        for method in ("LM", "N"):
            seed = sorted((sigma, ref[j]) for m, sigma, ref, *_ in SEED_TABLE if m == method)
            ours = sorted((row["sigma_deg"], row["ref"][j]) for row in rows if row["method"] == method)
            name = "N-bearings" if method == "N" else "LM"
            axis.plot(*zip(*seed), "--", color=_COLOURS[method], alpha=0.6, label=f"{name}, seed 002")
            if ours:
                axis.plot(*zip(*ours), "o-", color=_COLOURS[method], label=f"{name}, ours")
        region = REFS[j]
        axis.set_title(
            f"Ref{j + 1}: bearing {region[0]:g}°, range {100 * region[1]:g} %,\ncourse {region[2]:g}°, speed {100 * region[3]:g} %",
            fontsize=9,
        )
        axis.set_xlabel("bearing noise σ (°)")
        axis.grid(alpha=0.3)
    axes[0].set_ylabel("fraction of targets inside the region")
    axes[0].set_ylim(-0.02, 1.02)
    handles, labels = axes[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    figure.suptitle(f"Seed 002 §5.1 Monte Carlo ({data['protocol'].get('targets', '?')} targets): success fractions vs σ", fontsize=10)
    figure.tight_layout(rect=(0, 0.07, 1, 1))
    return save_figure(figure, png)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--plot", nargs="?", const=PLOT, type=Path, metavar="PNG", help="draw the figure (default docs/images/tma_montecarlo.png)"
    )
    parser.add_argument("--plot-only", type=Path, metavar="JSON", help="only draw the figure from an existing report")
    parser.add_argument("--n", type=int, default=10_000, help="number of targets (default 10000)")
    parser.add_argument("--sigma", type=float, nargs="+", default=[0.1, 0.5, 1.0], help="bearing noise σ in degrees")
    parser.add_argument("--seed", type=int, default=2021)
    parser.add_argument("--json", type=Path, help="write the rows and protocol here")
    parser.add_argument("--markdown", type=Path, help="write the markdown table here (default: stdout only)")
    parser.add_argument("--tie", choices=("right", "left"), default="right", help="direction of the 180° turn")
    parser.add_argument("--filter-n", type=int, default=50, help=f"targets tracked by the filters at σ = {FILTER_SIGMA}° (0: none)")
    parser.add_argument("--particles", type=int, default=2000, help="particles per target of the particle filter")
    args = parser.parse_args(argv)
    if args.plot_only:
        print(f"wrote {plot(args.plot_only, args.plot or PLOT)}")
        return 0
    if args.plot and not args.json:
        parser.error("--plot draws from the JSON report: give --json PATH too")

    if args.filter_n < 0 or args.particles < 1:
        parser.error("--filter-n must be ≥ 0 and --particles ≥ 1")
    if args.n < 1:
        parser.error("--n must be ≥ 1")
    if any(s < 0 for s in args.sigma):
        parser.error("--sigma values must be ≥ 0")
    result = run(args.n, args.sigma, args.seed, scenario=Seed002Scenario(tie=args.tie), filter_n=args.filter_n, particles=args.particles)
    table = markdown(result)
    print(table)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2, ensure_ascii=False) + "\n")
    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text(table)
    if args.plot:
        print(f"wrote {plot(args.json, args.plot)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
