"""A configuration fitted by ``hybridtrack fit`` on half the vessels, scored on the other half beside the hand-tuned
one (issue 22, "Parameters from the data" and its Show item).

    python experiments/fit_halves.py [FILE] --json PATH [--config CFG] [--vessels N] [--max-reports K] [--sigma S] [--seed S]

The vessels, their labels and the noisy reports are those of experiments/real_tracks.py (the objects of FILE,
default the Solent AIS file, with course and speed and ≥ ``min_reports`` reports; N(0, σ²) added to each
coordinate, σ = ``--sigma`` = 10 m, seeded per vessel).  They are split by their order in the file into two
halves, A = vessels 0, 2, 4, … and B = vessels 1, 3, 5, …, and two folds are run: fit on A and test on B, fit on
B and test on A.  In each fold :func:`hybridtrack.apps.fitting.fit_tracks` estimates, by maximum likelihood over
the fit half's noisy reports, the measurement σ, the white-acceleration density, the mean time in each mode and
each mode's own densities and, where CFG measures the reported course and speed, their noise σ_s and σ_χ,
starting from CFG (default examples/ships.toml, its ``[measurement] sigma`` set to ``--sigma``: the hand-tuned
configuration); a second fit holds σ_s and σ_χ at CFG's values (``hold``; ``fitted_holding_course_speed``).
The hand-tuned and the fitted configurations then track the test half causally and with ``--smooth`` and are scored against the course labels with the scores of
experiments/real_tracks.py (accuracy, balanced accuracy, per-class recall, onset delay, false turns per hour,
stopped and stationary reports in a turn, RMSE).  The labels are never used by the fit.

The JSON holds ``protocol`` (file, vessels and reports per half, σ, seed, the starting configuration's values),
``folds`` (per fold: the halves, per fit the parameters held, the fitted values with their standard errors,
log-likelihoods, evaluations and seconds, and one row per configuration × causal / smoothed), and
``fitted_at_least_as_good``: per fold, fitted configuration and output, whether its accuracy and balanced
accuracy are each at least the hand-tuned one's on the test half.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from real_tracks import ROOT, SHIPS, SOLENT, noisy, run_tracker, score, vessels  # noqa: E402

from hybridtrack.apps.fitting import MAX_ITERATIONS, VELOCITY_NOISE, fit_tracks, starting_values  # noqa: E402
from hybridtrack.apps.tracking import load_config  # noqa: E402

HALVES = {"A": slice(0, None, 2), "B": slice(1, None, 2)}


def fits(hand: dict) -> dict:
    """fitted configuration's name → the parameters it holds at the hand-tuned values."""
    held = [name for name in VELOCITY_NOISE if name in starting_values(hand)]
    return {"fitted": ()} | ({"fitted_holding_course_speed": tuple(held)} if held else {})


def fold(cases, fit_half: str, test_half: str, hand: dict, max_iterations: int = MAX_ITERATIONS) -> dict:
    fit_cases, test_cases = cases[HALVES[fit_half]], cases[HALVES[test_half]]
    configs, found = {"hand_tuned": hand}, {}
    for name, hold in fits(hand).items():
        start = time.perf_counter()
        fitted = fit_tracks([measured for _, _, measured in fit_cases], hand, hold=hold, max_iterations=max_iterations)
        configs[name] = fitted.config
        found[name] = {
            "held": list(hold),
            "values": fitted.values,
            "standard_errors": fitted.standard_errors,
            "loglik": fitted.loglik,
            "start_loglik": fitted.start_loglik,
            "objects": fitted.objects,
            "reports": fitted.reports,
            "evaluations": fitted.evaluations,
            "converged": fitted.converged,
            "seconds": time.perf_counter() - start,
        }
    rows = [
        {"config": name, "smooth": smooth} | score(test_cases, *run_tracker(test_cases, config, smooth))
        for name, config in configs.items()
        for smooth in (False, True)
    ]
    return {"fit_half": fit_half, "test_half": test_half, "fits": found, "rows": rows}


def at_least_as_good(result: dict) -> dict:
    """fold → fitted configuration → output (causal / smoothed) → its accuracy and balanced accuracy each ≥ the
    hand-tuned one's."""
    verdict = {}
    for f in result["folds"]:
        rows = {(r["config"], r["smooth"]): r for r in f["rows"]}
        verdict[f"fit_{f['fit_half']}_test_{f['test_half']}"] = {
            name: {
                ("smoothed" if smooth else "causal"): all(
                    rows[name, smooth][key] >= rows["hand_tuned", smooth][key] for key in ("accuracy", "balanced_accuracy")
                )
                for smooth in (False, True)
            }
            for name in f["fits"]
        }
    return verdict


def evaluate(
    path=SOLENT, *, config=SHIPS, sigma=10.0, seed=2016, vessel_count=None, max_reports=None, max_iterations=MAX_ITERATIONS
) -> dict:
    found = vessels(path, vessel_count, max_reports)
    if len(found) < 2:
        raise SystemExit(f"{path}: {len(found)} object(s) with course, speed and min_reports reports; two halves need at least 2")
    cases = [(track, label, noisy(track, sigma, seed, i)) for i, (track, label) in enumerate(found)]
    hand = load_config(config)
    hand["measurement"]["sigma"] = sigma
    result = {
        "protocol": {
            "file": str(Path(path).relative_to(ROOT)) if Path(path).is_relative_to(ROOT) else str(path),
            "config": str(Path(config).relative_to(ROOT)) if Path(config).is_relative_to(ROOT) else str(config),
            "halves": {
                half: {"vessels": len(cases[part]), "reports": sum(len(c[0]) for c in cases[part])} for half, part in HALVES.items()
            },
            "sigma_m": sigma,
            "seed": seed,
            "max_reports": max_reports,
            "hand_tuned_values": starting_values(hand),
        },
        "folds": [fold(cases, "A", "B", hand, max_iterations), fold(cases, "B", "A", hand, max_iterations)],
    }
    result["fitted_at_least_as_good"] = at_least_as_good(result)
    return result


def markdown(result: dict) -> str:
    """One row per fold × configuration × output."""
    lines = [
        "| fit on → test on | configuration | output | accuracy | balanced | recall straight / left / right / stop | false turns / h |"
        " stopped reports in a turn (all, stationary) | RMSE (m) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for f in result["folds"]:
        for r in f["rows"]:
            recall = " / ".join("–" if v is None else f"{v:.2f}" for v in r["recall"].values())
            stopped = " ".join("–" if r[k] is None else f"{r[k]:.3f}" for k in ("stopped_in_turn", "stationary_in_turn"))
            lines.append(
                f"| {f['fit_half']} → {f['test_half']} | {r['config']} | {'smoothed' if r['smooth'] else 'causal'} | {r['accuracy']:.3f}"
                f" | {r['balanced_accuracy']:.3f} | {recall} | {r['false_turns_per_hour']:.1f} | {stopped} | {r['rmse_m']:.1f} |"
            )
    return "\n".join(lines) + "\n"


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", nargs="?", default=str(SOLENT))
    parser.add_argument("--json", required=True, metavar="PATH", help="report to write (markdown table beside it, .md)")
    parser.add_argument("--config", default=str(SHIPS), help="the hand-tuned configuration the fits start from")
    parser.add_argument("--vessels", type=int, help="the first N vessels only")
    parser.add_argument("--max-reports", type=int, help="the first K reports of each vessel only")
    parser.add_argument("--sigma", type=float, default=10.0, help="noise added to the reports (m)")
    parser.add_argument("--seed", type=int, default=2016)
    parser.add_argument("--max-iterations", type=int, default=MAX_ITERATIONS, help="the optimizer's iterations per fit at most")
    args = parser.parse_args(argv)
    result = evaluate(
        args.file,
        config=args.config,
        sigma=args.sigma,
        seed=args.seed,
        vessel_count=args.vessels,
        max_reports=args.max_reports,
        max_iterations=args.max_iterations,
    )
    result["command"] = "python experiments/fit_halves.py " + " ".join(sys.argv[1:] if argv is None else argv)
    for f in result["folds"]:
        for r in f["rows"]:
            print(
                f"fit {f['fit_half']} test {f['test_half']} {r['config']:>27} {'smoothed' if r['smooth'] else 'causal  '}: "
                f"acc {r['accuracy']:.3f} bal {r['balanced_accuracy']:.3f} false/h {r['false_turns_per_hour']:.1f}"
            )
    print("fitted at least as good:", result["fitted_at_least_as_good"])
    Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    Path(args.json).with_suffix(".md").write_text(markdown(result))
    return result


if __name__ == "__main__":
    main()
