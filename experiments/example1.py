"""Example 1 of seed 000 over many seeded runs: detection of the right turn and the decision delay.

    python experiments/example1.py [--runs 200] [--plot [PNG]]
    python experiments/example1.py --plot-only docs/results/example1.json

Writes docs/results/example1.json and docs/results/example1.md.  The runs go
as one batch (``UnknownChangeAdaptive.run_batch``, equal to the per-run results
to rounding); ``--per-run`` runs them one by one.  The change is
at step 20 (x_21 is the first state of the turn); delay = decision step − 20.
``--plot`` draws the distribution of the detection delay for each α = β from
the JSON (:func:`plot`, default docs/images/example1.png); ``--plot-only JSON``
only draws, from an existing report.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
from pathlib import Path

import numpy as np

from hybridtrack.apps.reporting import save_figure

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("example1", ROOT / "examples" / "example1_unknown_change.py")
example1 = importlib.util.module_from_spec(spec)
spec.loader.exec_module(example1)


def batch_runs(adaptive, seeds) -> list:
    """Example 1 on every seed (drawn as ``run_once`` draws it), run as one batch (``run_batch``)."""
    data = [
        example1.simulate(example1.schedule(), example1.X0, example1.TAU, adaptive.network, seed=seed, noise_cov=example1.NOISE)[1]
        for seed in seeds
    ]
    z = {name: np.stack([d[name] for d in data]) for name in data[0]}
    return adaptive.run_batch(z, example1.Gaussian(example1.X0, np.eye(4)))


def outcomes(adaptive, runs: int, first_seed: int = 0, per_run: bool = False) -> list[dict]:
    """Each run's detection outcome; the runs go as one batch unless ``per_run`` (equal results)."""
    seeds = range(first_seed, first_seed + runs)
    results = [example1.run_once(seed, adaptive)[1] for seed in seeds] if per_run else batch_runs(adaptive, seeds)
    rows = []
    for seed, run in zip(seeds, results):
        change = run.first_change(after=example1.CHANGE_STEP)
        rows.append(
            {
                "seed": seed,
                "false_alarms": sum(1 for c in run.changes if c.step <= example1.CHANGE_STEP),
                "mode": None if change is None else change.mode,
                "delay": None if change is None else change.step - example1.CHANGE_STEP,
                "estimated_change_step": None if change is None else change.change_step,
                "max_bank": int(run.bank_sizes.max()),
            }
        )
    return rows


def summarize(rows: list[dict], horizon: int = 30) -> dict:
    runs = len(rows)
    right = [r for r in rows if r["mode"] == "right_turn_r5"]
    delays = np.array([r["delay"] for r in right], dtype=float)
    histogram = {str(d): int((delays == d).sum()) for d in range(1, horizon + 1) if (delays == d).any()}
    return {
        "runs": runs,
        "detected_right_turn": len(right) / runs,
        "detected_other_mode": sum(1 for r in rows if r["mode"] not in (None, "right_turn_r5")) / runs,
        "undetected_within_30_steps": sum(1 for r in rows if r["mode"] is None) / runs,
        "runs_with_false_alarm_before_change": sum(1 for r in rows if r["false_alarms"]) / runs,
        "within_15_steps": float((delays <= 15).sum() / runs),
        "within_10_steps": float((delays <= 10).sum() / runs),
        "delay_mean": float(delays.mean()) if delays.size else None,
        "delay_median": float(np.median(delays)) if delays.size else None,
        "delay_quartiles": np.percentile(delays, [25, 75]).tolist() if delays.size else None,
        "delay_min_max": [float(delays.min()), float(delays.max())] if delays.size else None,
        "delay_histogram": histogram,
        "estimated_change_step_median": float(np.median([r["estimated_change_step"] for r in right])) if right else None,
        "max_bank_size": max(r["max_bank"] for r in rows),
    }


#: where ``--plot`` writes by default
PLOT = ROOT / "docs" / "images" / "example1.png"


def plot(report: str | Path, png: str | Path = PLOT) -> Path:
    """The detection delay's distribution per α = β, from the JSON report: a PNG at ``png``.

    Left: the fraction of the runs whose right turn was accepted d steps after
    the change (``delay_histogram`` / ``runs``), one step curve per α = β, the
    median marked.  Right: the cumulative fraction detected within d steps
    (it ends at the share of runs that detected the right turn within the 30
    turn steps; the rest detected another mode or nothing).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = json.loads(Path(report).read_text(encoding="utf-8"))
    horizon = int(data["setup"].get("turn_steps", 30))
    delays = np.arange(1, horizon + 1)
    figure, (density, cumulative) = plt.subplots(1, 2, figsize=(11, 3.6))
    for key, summary in data["by_error_probabilities"].items():
        alpha = key.split(",")[0].split("=")[1]
        counts = np.array([summary["delay_histogram"].get(str(d), 0) for d in delays], dtype=float)
        fraction = counts / summary["runs"]
        label = f"α = β = {alpha} (median {summary['delay_median']:.0f}, detected {100 * summary['detected_right_turn']:.1f} %)"
        (line,) = density.step(delays, fraction, where="mid", label=label)
        if summary["delay_median"] is not None:
            density.axvline(summary["delay_median"], color=line.get_color(), linestyle=":", alpha=0.8)
        cumulative.step(delays, np.cumsum(fraction), where="post", color=line.get_color(), label=f"α = β = {alpha}")
    density.set_xlabel("detection delay (steps after the change)")
    density.set_ylabel("fraction of the runs")
    density.legend(fontsize=8)
    cumulative.set_xlabel("d (steps)")
    cumulative.set_ylabel("fraction detected within d steps")
    cumulative.set_ylim(0, 1)
    cumulative.legend(fontsize=8, loc="upper left")
    for axis in (density, cumulative):
        axis.grid(alpha=0.3)
    runs = next(iter(data["by_error_probabilities"].values()))["runs"]
    figure.suptitle(f"Seed 000 Example 1: delay of the right-turn decision ({runs} runs per α = β, change at step 20)", fontsize=10)
    figure.tight_layout()
    return save_figure(figure, png)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--plot", nargs="?", const=str(PLOT), metavar="PNG", help="draw the figure (default docs/images/example1.png)")
    parser.add_argument("--plot-only", metavar="JSON", help="only draw the figure from an existing report")
    parser.add_argument("--out", default=str(ROOT / "docs" / "results" / "example1"))
    parser.add_argument("--per-run", action="store_true", help="run each seed alone instead of one batch (the same results)")
    args = parser.parse_args(argv)
    if args.plot_only:
        print(f"wrote {plot(args.plot_only, args.plot or PLOT)}")
        return {}
    results = {
        "setup": {
            "tau": example1.TAU,
            "x0": example1.X0.tolist(),
            "Q": "diag(0.01, 0.01)",
            "R": "diag(0.01, 0.01)",
            "modes": ["straight", "right_turn r=5", "left_turn r=5"],
            "change_step": example1.CHANGE_STEP,
            "turn_steps": 30,
            "prior_cov": "I",
            "bank": "growing (Algorithm 3, no bound)",
            "seeds": f"0..{args.runs - 1}",
        },
        "by_error_probabilities": {},
    }
    for alpha, beta in ((0.1, 0.1), (0.05, 0.05), (0.01, 0.01)):
        rows = outcomes(example1.estimator(alpha=alpha, beta=beta), args.runs, per_run=args.per_run)
        results["by_error_probabilities"][f"alpha={alpha},beta={beta}"] = summarize(rows)
        print(alpha, beta, json.dumps(results["by_error_probabilities"][f"alpha={alpha},beta={beta}"]))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(results, indent=2))
    lines = [
        "| α = β | right turn detected | other mode | undetected (30 steps) | false alarm before change | delay mean | median | IQR | within 10 | within 15 |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key, s in results["by_error_probabilities"].items():
        a = key.split(",")[0].split("=")[1]
        lines.append(
            f"| {a} | {s['detected_right_turn']:.1%} | {s['detected_other_mode']:.1%} | {s['undetected_within_30_steps']:.1%} | "
            f"{s['runs_with_false_alarm_before_change']:.1%} | {s['delay_mean']:.1f} | {s['delay_median']:.0f} | "
            f"{s['delay_quartiles'][0]:.0f}–{s['delay_quartiles'][1]:.0f} | {s['within_10_steps']:.1%} | {s['within_15_steps']:.1%} |"
        )
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    if args.plot:
        print(f"wrote {plot(out.with_suffix('.json'), args.plot)}")
    return results


if __name__ == "__main__":
    main()
