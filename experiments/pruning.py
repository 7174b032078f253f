"""Bank bounding on Example 1 (seed 003 vs seed 000): nearest-to-B pruning with 4 filters vs oldest-first with 32.

    python experiments/pruning.py [--runs 200]

Same seeds for every configuration (paired); α = β = 0.1.  Writes
docs/results/pruning.json and docs/results/pruning.md.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("example1_experiment", ROOT / "experiments" / "example1.py")
experiment = importlib.util.module_from_spec(spec)
spec.loader.exec_module(experiment)

CONFIGS = [("nearest_lower", 4), ("oldest", 32), ("oldest", 4), ("nearest_lower", 32), ("oldest", "algorithm4"), (None, None)]


def _num(value, spec: str) -> str:
    return "–" if value is None else format(value, spec)


def write_markdown(results: dict, path: Path) -> None:
    lines = [
        "| bank | right turn detected | undetected (30 steps) | false alarm | delay mean | median | IQR | within 15 | max filters |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for key, s in results.items():
        if key.startswith("paired"):
            continue
        iqr = "–" if s["delay_quartiles"] is None else f"{s['delay_quartiles'][0]:.0f}–{s['delay_quartiles'][1]:.0f}"
        limit = f" (Algorithm 4: {s['algorithm4_bank_limit']})" if "algorithm4_bank_limit" in s else ""
        lines.append(
            f"| {key}{limit} | {s['detected_right_turn']:.1%} | {s['undetected_within_30_steps']:.1%} | {s['runs_with_false_alarm_before_change']:.1%} | "
            f"{_num(s['delay_mean'], '.1f')} | {_num(s['delay_median'], '.0f')} | {iqr} | {s['within_15_steps']:.1%} | {s['max_bank_size']} |"
        )
    p = results["paired_nearest4_minus_oldest32"]
    lines.append(
        f"\nPaired (runs detected by both, n = {p['runs_detected_by_both']}): delay(nearest-4) − delay(oldest-32) = "
        f"{p['mean_difference']:.2f} ± {p['std_error']:.2f} (s.e.); identical in {p['same_delay']} runs."
    )
    path.write_text("\n".join(lines) + "\n")


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--markdown-only", action="store_true", help="rewrite the table from docs/results/pruning.json")
    args = parser.parse_args(argv)
    if args.markdown_only:
        results = json.loads((ROOT / "docs" / "results" / "pruning.json").read_text())["results"]
        write_markdown(results, ROOT / "docs" / "results" / "pruning.md")
        return results
    results, delays = {}, {}
    for pruning, size in CONFIGS:
        adaptive = experiment.example1.estimator(bank_size=size, pruning=pruning)
        rows = experiment.outcomes(adaptive, args.runs)
        key = "growing" if size is None else f"{pruning}-{size}"
        summary = experiment.summarize(rows)
        if size == "algorithm4":
            summary["algorithm4_bank_limit"] = adaptive.algorithm4_bank_size(experiment.example1.X0)
        results[key] = summary
        delays[key] = [r["delay"] if r["mode"] == "right_turn_r5" else None for r in rows]
        print(key, json.dumps(summary))
    a, b = delays["nearest_lower-4"], delays["oldest-32"]
    both = [(x, y) for x, y in zip(a, b) if x is not None and y is not None]
    diff = np.array([x - y for x, y in both], dtype=float)
    results["paired_nearest4_minus_oldest32"] = {
        "runs_detected_by_both": len(both),
        "mean_difference": float(diff.mean()),
        "std_error": float(diff.std(ddof=1) / np.sqrt(diff.size)),
        "same_delay": int((diff == 0).sum()),
    }
    out = ROOT / "docs" / "results" / "pruning"
    out.with_suffix(".json").write_text(
        json.dumps({"setup": f"Example 1, α = β = 0.1, seeds 0..{args.runs - 1}", "results": results}, indent=2)
    )
    write_markdown(results, out.with_suffix(".md"))
    return results


if __name__ == "__main__":
    main()
