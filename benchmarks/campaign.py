"""Monte Carlo campaigns batched vs run by run, in one process (issue #14).

    python benchmarks/campaign.py --json docs/results/campaign_bench.json [--runs 100] [--example1-runs 200]

Cases (each timed both ways on the same runs, the results checked equal):

* ``seed001_campaign`` — experiments/seed001_adaptive.py with the default rule:
  100 trajectories × R ∈ {1, 0.1, 0.01} of the seed-001 schedule (360 steps),
  each with the optimal KF told the modes and the 21-filter known-switch
  adaptive estimator.  Both ways go through the path the script takes: one
  :class:`~hybridtrack.apps.experiment.Campaign` per R into a fresh temporary
  folder (chunk files written, as stored and resumable), on the ``inline``
  executor (this process, one worker: a clean comparison without pool start-up
  or the other engineers' share of the second core).  Batched: the script's
  ``EXPERIMENT`` (``run_batch``: each chunk of ≤ 100 trajectories propagated
  together, both estimators as stacked banks); per run: its ``PER_RUN`` (the
  same experiment without ``run_batch``, ``run_one`` per trajectory).
* ``example1`` — experiments/example1.py: Example 1 of seed 000 (α = β = 0.1)
  on 200 seeds with the growing bank of Algorithm 3; per run: ``run`` per seed,
  batched: ``UnknownChangeAdaptive.run_batch`` of the 200 runs.
* ``clutter`` — experiments/clutter.py's tracking table (8 cells of P_D × λ,
  ``--clutter-runs`` runs each, 361 steps) with the methods it batches,
  nearest neighbour and PDA: per run, one filter per run and method
  (``tracking_table(batched=False)``); batched, the runs of a cell as one bank
  with their own candidates per row (``RowScan``).  Both include drawing the
  trajectories and the clutter (the same in both); the loss steps and squared
  errors are checked equal.  The other five methods run per run in either path.

Writes ``{"cases": [{"name", "batched_s", "per_run_s", "speedup"}]}``.  The
timings depend on the machine's load (the 2-core machine is shared); each case
is timed once, batched first, after an untimed warm-up of both paths (imports,
numba compilation).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def load(name: str):
    spec = importlib.util.spec_from_file_location(f"_bench_{name}", ROOT / "experiments" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def timed(function):
    start = time.perf_counter()
    value = function()
    return time.perf_counter() - start, value


def case(name: str, batched_s: float | None, per_run_s: float) -> dict:
    speedup = None if batched_s is None else per_run_s / batched_s
    return {"name": name, "batched_s": batched_s, "per_run_s": per_run_s, "speedup": speedup}


def seed001_campaign(runs: int, r_values=(1.0, 0.1, 0.01), seed: int = 1, steps_scale: float = 1.0) -> dict:
    import tempfile

    from hybridtrack.apps.experiment import Campaign, load_experiment

    script = str(ROOT / "experiments" / "seed001_adaptive.py")
    batched_experiment, per_run_experiment = load_experiment(script), load_experiment(f"{script}:PER_RUN")
    rule = load("seed001_adaptive").DEFAULT_RULE

    def campaigns(experiment, folder: Path, n: int, scale: float) -> list[dict]:
        return [
            Campaign(
                experiment,
                n,
                folder / f"R{R:g}",
                seed=seed,
                executor="inline",
                progress=False,
                parameters={"R": R, "steps_scale": scale, **rule},
            )
            .run()
            .arrays
            for R in r_values
        ]

    with tempfile.TemporaryDirectory(prefix="campaign_bench_") as tmp:
        tmp = Path(tmp)
        campaigns(batched_experiment, tmp / "warm_batched", 2, 0.1)  # imports, numba compilation
        campaigns(per_run_experiment, tmp / "warm_per_run", 2, 0.1)
        batched_s, batched = timed(lambda: campaigns(batched_experiment, tmp / "batched", runs, steps_scale))
        per_run_s, single = timed(lambda: campaigns(per_run_experiment, tmp / "per_run", runs, steps_scale))
    for a, b in zip(batched, single):
        for name in a:
            np.testing.assert_allclose(a[name], b[name], rtol=1e-12, atol=1e-12, err_msg=name)
    scaled = "" if steps_scale == 1 else f", schedule scaled by {steps_scale:g}"
    return case(f"seed001_campaign ({runs} runs x {len(r_values)} R, default rule, runner inline{scaled})", batched_s, per_run_s)


def example1(runs: int) -> dict:
    module = load("example1")
    adaptive = module.example1.estimator(alpha=0.1, beta=0.1)
    module.outcomes(adaptive, 2), module.outcomes(adaptive, 2, per_run=True)  # warm-up
    batched_s, batched = timed(lambda: module.outcomes(adaptive, runs))
    per_run_s, single = timed(lambda: module.outcomes(adaptive, runs, per_run=True))
    if batched != single:
        raise AssertionError("example1: the batched outcomes differ from the per-run ones")
    return case(f"example1 ({runs} runs, alpha = beta = 0.1)", batched_s, per_run_s)


def clutter(runs: int) -> dict:
    module = load("clutter")
    methods = list(module.BATCHED)
    module.tracking_table(1, methods), module.tracking_table(1, methods, batched=False)  # warm-up
    batched_s, batched = timed(lambda: module.tracking_table(runs, methods))
    per_run_s, single = timed(lambda: module.tracking_table(runs, methods, batched=False))
    for a, b in zip(batched, single):
        for name in methods:
            assert a[name]["track_loss_rate"] == b[name]["track_loss_rate"] and a[name]["mean_loss_step"] == b[name]["mean_loss_step"]
            if b[name]["rmse_kept"] is not None:
                np.testing.assert_allclose(a[name]["rmse_kept"], b[name]["rmse_kept"], rtol=1e-12, err_msg=name)
    return case(f"clutter (tracking table, NN + PDA, {runs} runs per cell x 8 cells)", batched_s, per_run_s)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="PATH", help="write the cases here")
    parser.add_argument("--runs", type=int, default=100, help="seed-001 trajectories per R (default 100)")
    parser.add_argument("--steps-scale", type=float, default=1.0, help="scale the seed-001 schedule (tests)")
    parser.add_argument("--example1-runs", type=int, default=200)
    parser.add_argument("--clutter-runs", type=int, default=10, help="tracking runs per (P_D, clutter density) cell (0: skip)")
    args = parser.parse_args(argv)
    cases = [seed001_campaign(args.runs, steps_scale=args.steps_scale), example1(args.example1_runs)]
    if args.clutter_runs:
        cases.append(clutter(args.clutter_runs))
    result = {"cases": cases}
    for c in cases:
        speed = "" if c["speedup"] is None else f", batched {c['batched_s']:.2f} s, speedup {c['speedup']:.1f}x"
        print(f"{c['name']}: per run {c['per_run_s']:.2f} s{speed}", flush=True)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
