"""Example 1 of seed 000: detecting a change to a right turn at an unknown time (Algorithm 3).

20 steps straight, then 30 steps of a right turn r = 5 m; x(0) = [0, 0, 0, 2],
Q = R = diag(0.01, 0.01), τ = 0.1 s (SPEC §7); hypotheses straight (main),
right turn r = 5, left turn r = 5; α = β = 0.1 (the seed gives none; see
docs/detectors.md).  The growing bank of Algorithm 3 (or a bounded one) runs
on the position measurements; the estimate follows the identified mode.
Truth, measurements, estimate, ln λ per hypothesis with A and B, the signal
function with ±3, the bank size and the decisions go to a Rerun recording.

    python examples/example1_unknown_change.py --out example1.rrd [--seed 0] [--bank-size 4 --pruning nearest_lower]
"""

from __future__ import annotations

import argparse

import numpy as np

from hybridtrack import Gaussian, Schedule
from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import RerunRecorder
from hybridtrack_plugins.sensors.position import PositionSensor

TAU = 0.1
X0 = np.array([0.0, 0.0, 0.0, 2.0])
NOISE = np.diag([0.01, 0.01])
MODES = ["straight", ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
ALPHA = BETA = 0.1
CHANGE_STEP = 20


def schedule(straight_steps: int = 20, turn_steps: int = 30) -> Schedule:
    return Schedule.from_rows([("straight", straight_steps), ("right_turn", turn_steps, 5.0)])


def estimator(bank_size=None, pruning=None, alpha=ALPHA, beta=BETA, estimator_name="kalman", sensors=None) -> UnknownChangeAdaptive:
    """The adaptive estimator of Example 1, composed from registered names."""
    return UnknownChangeAdaptive(
        modes=MODES,
        sensors=sensors or [PositionSensor(noise_cov=NOISE)],
        tau=TAU,
        estimator=estimator_name,
        alpha=alpha,
        beta=beta,
        bank_size=bank_size,
        pruning=pruning,
        name="example1",
    )


def run_once(seed: int, adaptive: UnknownChangeAdaptive, turn_steps: int = 30, recorder=None):
    truth, z = simulate(schedule(CHANGE_STEP, turn_steps), X0, TAU, adaptive.network, seed=seed, noise_cov=NOISE, recorder=recorder)
    return truth, adaptive.run(z, Gaussian(X0, np.eye(4)), recorder=recorder, truth=None)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="example1.rrd")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--turn-steps", type=int, default=30)
    parser.add_argument("--bank-size", default=None, help="bound on the alternative filters (int or 'algorithm4'); default: growing")
    parser.add_argument("--pruning", default=None, choices=["oldest", "nearest_lower"])
    args = parser.parse_args(argv)
    bank_size = None if args.bank_size is None else (args.bank_size if args.bank_size == "algorithm4" else int(args.bank_size))
    adaptive = estimator(bank_size, args.pruning)
    configuration = {
        "example": "example1",
        "seed": args.seed,
        "turn_steps": args.turn_steps,
        "bank_size": args.bank_size,
        "pruning": args.pruning,
    }
    with RerunRecorder(args.out, configuration) as recorder:
        truth, run = run_once(args.seed, adaptive, args.turn_steps, recorder)
    change = run.first_change(after=CHANGE_STEP)
    false_alarms = [c for c in run.changes if c.step <= CHANGE_STEP]
    position = [0, 2]
    summary = {
        "steps": int(run.means.shape[0]),
        "detected_mode": None if change is None else change.mode,
        "decision_step": None if change is None else change.step,
        "delay": None if change is None else change.step - CHANGE_STEP,
        "estimated_change_step": None if change is None else change.change_step,
        "false_alarms": len(false_alarms),
        "max_bank_size": int(run.bank_sizes.max()),
        "position_rmse": float(np.sqrt(np.mean(np.sum((run.means[:, position] - truth.states_in(run.layout)[:, position]) ** 2, axis=1)))),
    }
    for key, value in summary.items():
        print(f"{key}: {value}")
    print(f"recording: {args.out}   open it with: .venv/bin/rerun {args.out}")
    return summary


if __name__ == "__main__":
    main()
