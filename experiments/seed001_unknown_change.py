"""Seed 000's SPRT with unknown change time (Algorithm 3, repeated) on the seed 001 schedule, beside Algorithm 1 and the optimal KF.

Protocol (the seed 001 experiment of SPEC §7, with the switching moments *not*
given to the estimator): Table 1 schedule (L3 R5 S L3 S L4, 360 steps),
τ = 0.1 s, x0 = [0, 0, 0, 2], Q = diag(0.001, 0.001), R ∈ {1, 0.1, 0.01}·I₂,
prior N(x0, I); trajectories drawn exactly as in ``seed001_adaptive.py`` (run i
uses child i of SeedSequence(seed), the same trajectories for every R).

Three estimators on every trajectory:

* the optimal KF told each segment's mode (seed 001 Table 2);
* the known-switch adaptive estimator (:class:`hybridtrack.algorithms.known_switch.KnownSwitchAdaptive`,
  seed 001 Algorithm 1, the 21-filter bank, α = β = 0.01, the seed's
  ``follow="previous"`` rule);
* the unknown-change-time adaptive estimator
  (:class:`hybridtrack.algorithms.unknown_change.UnknownChangeAdaptive`, seed 000 Algorithm 3
  repeated): filter 0 runs the current mode (straight at the start — nothing
  is known), every step starts one filter per alternative mode from filter 0's
  estimate (a turn's ω and centre fixed from it), ln λ_p averages the
  likelihood ratios over the change times, rule (24) with A, B from α = β
  (``--alpha``, default 0.001: with 20 alternatives each tested at every step,
  a smaller α than Algorithm 1's); a change makes the most likely filter of the
  new mode filter 0.  The bank is bounded to ``bank_size`` alternative filters
  (default 40), pruned by seed 003's rule (drop the ln ψ nearest B).
  ``--modes seed001`` is the 2n+1 = 21 modes of seed 001 (straight, left and
  right turns of radii 1, 2, …, 10); ``--modes table1`` the smaller set of the
  radii that occur in Table 1 (straight, left and right turns of radii 3, 4, 5:
  7 modes).

Reported per R: nRMSE of the three (RMSE_i = √(mean over runs and steps
k = 1 … 360 of (x_i − x̂_i)²), nRMSE = ‖RMSE‖₂); per true switch (the 6
segment starts, step 0 included since filter 0 starts straight) the detection
delay = first detected change inside the segment to a mode of the segment's
motion type (straight / left / right) minus the segment's first step, over the
runs that detect it, and the fraction detected; false alarms = detected changes
to a motion type other than the true one at that step, per run; all changes
per run; modes right = fraction of segments whose followed mode at the
segment's last step has the right motion type (for Algorithm 1: the mode it
identified, as in ``seed001_adaptive.py``).

    python experiments/seed001_unknown_change.py --json docs/results/seed001_unknown_change.json [--n 50] [--modes seed001]

Each R is one campaign of the runner (:class:`~hybridtrack.apps.experiment.Campaign`),
stored under ``--out`` (resumable) and chunked over ``--executor``'s workers;
:data:`EXPERIMENT` declares ``run_batch``, so each chunk runs as one batch
(stacked banks, equal to the per-run results to 1e-12).  ``--per-run`` runs the
same campaigns with :data:`PER_RUN` (no ``run_batch``: one trajectory at a
time), stored under ``--out``/per_run.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import attrs
import numpy as np

from hybridtrack.apps.experiment import Campaign, Experiment, load_experiment
from hybridtrack.apps.experiment.builtin import (
    X0,
    known_modes_estimate,
    known_modes_estimate_batch,
    pooled_rmse,
    seed001_prior,
    simulate_seed001,
    simulate_seed001_batch,
    squared_errors,
)
from hybridtrack.apps.reporting import Column, write_report

R_VALUES = (1.0, 0.1, 0.01)
SEGMENTS = 6
TURN_TYPES = ("straight", "left_turn", "right_turn")
MODE_SETS = {"seed001": (1.0, 10.0, 10), "table1": (3.0, 5.0, 3)}


def motion_type(mode: str) -> str:
    for kind in TURN_TYPES:
        if mode.startswith(kind):
            return kind
    return mode


def _estimators(sensors, *, q, tau, alpha, beta, known_alpha, modes, bank_size):
    """(Algorithm 1, Algorithm 3 repeated) as configured by the protocol."""
    from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive, turn_bank
    from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive

    if modes not in MODE_SETS:
        raise ValueError(f"modes: expected one of {sorted(MODE_SETS)}, got {modes!r}")
    r_min, r_max, n = MODE_SETS[modes]
    known = KnownSwitchAdaptive(
        sensors=sensors,
        tau=tau,
        noise_cov=q * np.eye(2),
        alpha=known_alpha,
        beta=known_alpha,
        follow="previous",
        switch_inflation=1.0,
    )
    unknown = UnknownChangeAdaptive(
        modes=turn_bank(r_min, r_max, n, q * np.eye(2)),
        sensors=sensors,
        tau=tau,
        alpha=alpha,
        beta=beta,
        bank_size=int(bank_size),
        pruning="nearest_lower",
        signal=None,
    )
    return known, unknown


def _outcome(schedule, truth, optimal, known_run, run) -> dict:
    """One trajectory's figures from the three estimators' runs."""
    starts = np.cumsum([0] + [s.steps for s in schedule.segments])
    true_type = np.empty(schedule.total_steps + 1, dtype=object)
    for i, segment in enumerate(schedule.segments):
        true_type[starts[i] : starts[i + 1] + 1] = segment.mode
    delays, right, known_right = [], [], []
    for i, segment in enumerate(schedule.segments):
        inside = [c for c in run.changes if starts[i] < c.step <= starts[i + 1] and motion_type(c.mode) == segment.mode]
        delays.append(float(inside[0].step - starts[i]) if inside else np.nan)
        right.append(float(motion_type(run.modes[run.mode[starts[i + 1]]]) == segment.mode))
        known_right.append(float(motion_type(known_run.segments[i].mode) == segment.mode))
    wrong = sum(1 for c in run.changes if motion_type(c.mode) != true_type[c.step])
    return {
        "squared_error_optimal": squared_errors(optimal.means, truth, optimal.layout),
        "squared_error_known": squared_errors(known_run.means, truth, known_run.layout),
        "squared_error_unknown": squared_errors(run.means, truth, run.layout),
        "steps": schedule.total_steps,
        "detection_delay": np.array(delays),
        "modes_correct": np.array(right),
        "modes_correct_known": np.array(known_right),
        "false_alarms": float(wrong),
        "changes": float(len(run.changes)),
        "max_bank": float(run.bank_sizes.max()),
    }


def run_one(
    index: int,
    rng: np.random.Generator,
    *,
    R: float,
    q: float,
    tau: float,
    alpha: float,
    beta: float,
    known_alpha: float,
    modes: str,
    bank_size: int,
    steps_scale: float,
) -> dict:
    """One trajectory: squared errors of the three estimators, per-segment delays, changes, identifications."""
    schedule, sensors, truth, measurements = simulate_seed001(rng, R=R, q=q, tau=tau, steps_scale=steps_scale)
    known, unknown = _estimators(sensors, q=q, tau=tau, alpha=alpha, beta=beta, known_alpha=known_alpha, modes=modes, bank_size=bank_size)
    prior = seed001_prior()
    optimal = known_modes_estimate(schedule, sensors, measurements, q=q, tau=tau)
    return _outcome(schedule, truth, optimal, known.run(measurements, prior, schedule), unknown.run(measurements, prior))


def run_batch(
    indices,
    rngs,
    *,
    R: float,
    q: float,
    tau: float,
    alpha: float,
    beta: float,
    known_alpha: float,
    modes: str,
    bank_size: int,
    steps_scale: float,
) -> list[dict]:
    """:func:`run_one` of the runs ``indices`` (generators ``rngs``) as one batch: trajectories drawn run by run,
    the three estimators as stacked banks (``KnownModes.run_batch``, ``run_batch``); equal to the per-run results
    to rounding."""
    schedule, sensors, truths, z = simulate_seed001_batch(rngs, R=R, q=q, tau=tau, steps_scale=steps_scale)
    known, unknown = _estimators(sensors, q=q, tau=tau, alpha=alpha, beta=beta, known_alpha=known_alpha, modes=modes, bank_size=bank_size)
    prior = seed001_prior()
    optimal = known_modes_estimate_batch(schedule, sensors, z, q=q, tau=tau)
    known_runs, runs = known.run_batch(z, prior, schedule), unknown.run_batch(z, prior)
    return [_outcome(schedule, truth, o, k, u) for truth, o, k, u in zip(truths, optimal, known_runs, runs)]


def batch_arrays(parameters: dict, n: int, seed: int, chunk: int = 50) -> dict[str, np.ndarray]:
    """Every run's results stacked (name → (n, …)), as a campaign returns them, computed by :func:`run_batch` in
    chunks of ``chunk`` runs (:func:`hybridtrack.apps.experiment.worker.batch_arrays`)."""
    from hybridtrack.apps.experiment import worker

    return worker.batch_arrays(run_batch, parameters, n, seed, chunk)


EXPERIMENT = Experiment(
    name="seed001_unknown_change",
    run_one=run_one,
    parameters={
        "R": 0.1,
        "q": 0.001,
        "tau": 0.1,
        "alpha": 0.001,
        "beta": 0.001,
        "known_alpha": 0.01,
        "modes": "seed001",
        "bank_size": 40,
        "steps_scale": 1.0,
    },
    description="seed 000 Algorithm 3 (unknown change time) on the seed 001 schedule, beside Algorithm 1 and the optimal KF",
    run_batch=run_batch,
    batch_size=50,
)
#: the same experiment without ``run_batch``: the runner runs one trajectory at a time (``--per-run``)
PER_RUN = attrs.evolve(EXPERIMENT, run_batch=None)


def aggregate(arrays: dict[str, np.ndarray], R: float) -> dict:
    """One report row from one R's runs."""
    nrmse = {
        name: float(np.linalg.norm(pooled_rmse(arrays[f"squared_error_{name}"], arrays["steps"])))
        for name in ("optimal", "known", "unknown")
    }
    delays = arrays["detection_delay"]
    detected = np.isfinite(delays)
    counts = detected.sum(axis=0)
    per_segment = np.divide(np.where(detected, delays, 0.0).sum(axis=0), counts, out=np.full(counts.shape, np.nan), where=counts > 0)
    return {
        "R": float(R),
        "runs": int(delays.shape[0]),
        "optimal_nrmse": nrmse["optimal"],
        "known_switch_nrmse": nrmse["known"],
        "unknown_change_nrmse": nrmse["unknown"],
        "detection_delay": per_segment.tolist(),
        "mean_detection_delay": float(np.nanmean(delays)) if detected.any() else None,
        "detected": detected.mean(axis=0).tolist(),
        "detected_fraction": float(detected.mean()),
        "false_alarms_per_run": float(np.mean(arrays["false_alarms"])),
        "changes_per_run": float(np.mean(arrays["changes"])),
        "modes_correct": float(np.mean(arrays["modes_correct"])),
        "modes_correct_known_switch": float(np.mean(arrays["modes_correct_known"])),
        "max_bank": int(np.max(arrays["max_bank"])),
    }


COLUMNS = [
    Column("R", "R", "g"),
    Column("runs", "runs", "d"),
    Column("optimal_nrmse", "optimal KF nRMSE", ".4f"),
    Column("known_switch_nrmse", "known-switch nRMSE", ".4f"),
    Column("unknown_change_nrmse", "unknown-change nRMSE", ".4f"),
    *[Column("detection_delay", f"delay seg {i + 1}", ".1f", i) for i in range(SEGMENTS)],
    Column("detected_fraction", "switches detected", ".3f"),
    Column("false_alarms_per_run", "false alarms / run", ".1f"),
    Column("changes_per_run", "changes / run", ".1f"),
    Column("modes_correct", "modes right (unknown)", ".3f"),
    Column("modes_correct_known_switch", "modes right (known)", ".3f"),
]


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", required=True, metavar="PATH", help="report to write (markdown table beside it, .md)")
    parser.add_argument("--n", type=int, default=50, help="trajectories per R (default 50)")
    parser.add_argument("--R", type=float, nargs="+", default=list(R_VALUES), help="measurement noise levels r (R = r·I)")
    parser.add_argument("--alpha", type=float, default=0.001, help="α = β of the unknown-change SPRT")
    parser.add_argument("--modes", default="seed001", choices=sorted(MODE_SETS))
    parser.add_argument("--bank-size", type=int, default=40, help="alternative filters kept (nearest-B pruning)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--steps-scale", type=float, default=1.0, help="scale the schedule (tests)")
    parser.add_argument(
        "--executor",
        choices=("inline", "process", "dask"),
        help="where the chunks run (default: inline for the batches — a worker pool's start-up costs more than it saves "
        "on these batches — and process with --per-run)",
    )
    parser.add_argument("--scheduler", help="Dask scheduler address")
    parser.add_argument("--workers", type=int)
    parser.add_argument("--out", default="runs/seed001_unknown_change", help="campaign folders (one per R)")
    parser.add_argument("--no-progress", action="store_true")
    parser.add_argument(
        "--per-run",
        action="store_true",
        help="the same campaigns without run_batch: one trajectory at a time (stored under --out/per_run) instead of one batch per chunk",
    )
    args = parser.parse_args(argv)

    script = str(Path(__file__).resolve())
    experiment = load_experiment(f"{script}:PER_RUN" if args.per_run else script)
    out = Path(args.out) / "per_run" if args.per_run else Path(args.out)
    rows = []
    for R in args.R:
        parameters = {
            "R": R,
            "alpha": args.alpha,
            "beta": args.alpha,
            "modes": args.modes,
            "bank_size": args.bank_size,
            "steps_scale": args.steps_scale,
        }
        folder = out / f"{args.modes}_alpha{args.alpha:g}_bank{args.bank_size}_scale{args.steps_scale:g}" / f"R{R:g}"
        campaign = Campaign(
            experiment,
            args.n,
            folder,
            seed=args.seed,
            executor=args.executor or ("process" if args.per_run else "inline"),
            scheduler=args.scheduler,
            workers=args.workers,
            progress=not args.no_progress,
            parameters=parameters,
        )
        rows.append(aggregate(campaign.run().arrays, R))
        r = rows[-1]
        print(
            f"R = {R:g}: nRMSE optimal {r['optimal_nrmse']:.4f}, known-switch {r['known_switch_nrmse']:.4f}, "
            f"unknown-change {r['unknown_change_nrmse']:.4f}; switches detected {r['detected_fraction']:.3f}, "
            f"false alarms/run {r['false_alarms_per_run']:.1f}, modes right {r['modes_correct']:.3f}",
            flush=True,
        )
    r_min, r_max, n = MODE_SETS[args.modes]
    protocol = {
        "source": "seed 000 Algorithm 3 (repeated) on the seed 001 Table 1 schedule; SPEC sections 4 and 7",
        "schedule": "Table 1: L r=3 x50, R r=5 x75, S x50, L r=3 x75, S x50, L r=4 x60"
        + ("" if args.steps_scale == 1 else f" (lengths scaled by {args.steps_scale})"),
        "x0": list(X0),
        "tau": 0.1,
        "Q": "0.001 I2",
        "prior": "N(x0, I4) for every estimator",
        "trajectories_per_R": args.n,
        "campaign_seed": args.seed,
        "seeds": "run i uses child i of SeedSequence(campaign_seed) for every R (the trajectories of seed001_adaptive.py)",
        "modes": {"set": args.modes, "r_min": r_min, "r_max": r_max, "n": n, "count": 2 * n + 1},
        "unknown_change": {
            "alpha": args.alpha,
            "beta": args.alpha,
            "initial_mode": "straight",
            "bank_size": f"{args.bank_size} alternative filters + filter 0, nearest-B pruning (seed 003)",
        },
        "known_switch": {"bank": "21 filters, radii 1..10", "alpha": 0.01, "beta": 0.01, "follow": "previous (seed 001 line 9)"},
        "detection_delay": "per segment: first detected change inside the segment to the segment's motion type, minus its first step; "
        "mean over the runs that detect it",
        "false_alarms": "detected changes to a motion type other than the true one at that step, per run",
        "modes_correct": "fraction of segments whose followed mode at the segment's last step has the right motion type",
        "command": "python experiments/seed001_unknown_change.py " + " ".join(sys.argv[1:] if argv is None else argv),
    }
    write_report(args.json, rows, protocol, columns=COLUMNS, title=f"Unknown-change-time SPRT on the seed 001 schedule ({2 * n + 1} modes)")
    return {"rows": rows, "protocol": protocol}


if __name__ == "__main__":
    main()
