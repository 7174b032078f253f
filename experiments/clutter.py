"""Tracking in clutter (seed 004, SPEC §6): nearest neighbour vs PDA, and mode-change detection in clutter.

    python experiments/clutter.py [--runs 10] [--detection-runs 60] [--methods NAME …] [--plot [PNG]]

(``--runs 0`` or ``--detection-runs 0`` skips that part and keeps its rows from
the existing output file.)

Part 1 — RMSE and track loss.  The seed-001 Table 1 trajectory (L 50 r3, R 75 r5,
S 50, L 75 r3, S 50, L 60 r4; x0 = [0, 0, 0, 2], τ = 0.1 s, Q = 0.001 I),
position measurements with R = 0.1 I, detection probability P_D = 0.9, Poisson
clutter uniform over the trajectory's bounding box widened by 3 m, at several
densities λ (false measurements per m² per step).  One nearly-constant-velocity
filter (``straight`` with Q = 0.1 I: with Q = 0.02 I it already loses tracks
without clutter, missed detections and a tight gate in the r = 3 m turns),
started at the truth with P0 = 0.1 I, runs as ``nearest_neighbour`` (P_G = 0.99)
and as ``pda`` (P_D = 0.9, the true λ, P_G = 0.99) on the same scans.  A track
is lost when the position error stays above 2 m (≈ 6.3 σ of the measurement
noise) for 5 consecutive steps; RMSE is over the runs whose track was not lost.
Every method runs run by run, so the time per step compares the methods' own
costs.  With ``--batched`` nearest neighbour and PDA run the runs of a cell as one
bank (one filter per run, each row gated against its own candidates:
``RowScan``, the same results as the runs one by one) and their time per step is
the bank's divided by the runs (what ``benchmarks/campaign.py`` measures).

Part 2 — Example 1 of seed 000 in clutter.  20 steps straight then 30 steps right
turn r = 5 m, x0 = [0, 0, 0, 2], Q = R = 0.01 I, τ = 0.1 s, prior N(x0, I);
modes straight / right r = 5 / left r = 5; seed 000 Algorithm 3 (a filter per
alternative started at every step, the growing bank) with the change-time SPRT
``sprt_unknown_change`` (α = β = 0.1, as ``examples/example1_unknown_change.py``).
Every filter is a ``pda`` (P_D, true λ, P_G = 0.99) and the SPRT is fed each
filter's association log-likelihood ln Λ (plugins/filters/_association.py) —
in clutter the Gaussian ℓ of one innovation does not compare filters.  λ = 0
with P_D = 1 is the Kalman-filter reference (there ln Λ = ℓ).  Alongside, the
signal function (``signal_function``, ±3) of the straight filter is fed the NIS
of its most probable gated candidate (m = 0 when nothing is gated).  Delay =
decision step − 20.

Writes docs/results/clutter.json and docs/results/clutter.md (tables also in docs/clutter.md).
"""

from __future__ import annotations

import argparse
import inspect
import json
import time
from pathlib import Path

import numpy as np

from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import get_registry
from hybridtrack.engine.bank import FilterBank
from hybridtrack.engine.clutter import ClutterModel, add_clutter, region_around, stack_scans
from hybridtrack.engine.schedule import SEED001_TABLE1, Schedule
from hybridtrack.engine.simulate import simulate_measurements, simulate_trajectory
from hybridtrack_plugins.detectors.signal_function import SignalFunction
from hybridtrack_plugins.detectors.sprt_change import ChangeTimeSPRT
from hybridtrack_plugins.filters.pda import PDAFilter
from hybridtrack_plugins.sensors.position import PositionSensor

ROOT = Path(__file__).resolve().parents[1]
LAYOUT = ("x", "vx", "y", "vy")
X0 = np.array([0.0, 0.0, 0.0, 2.0])
TAU = 0.1

# Part 1: the seed-001 Table 1 trajectory (SEED001_TABLE1)
TRACKING_R = 0.1
TRACKER_Q = 0.1
GATE = 0.99
LOSS_DISTANCE, LOSS_STEPS = 2.0, 5
DENSITIES = [0.025, 0.05, 0.1, 0.2]
DETECTION_PROBABILITIES = [0.9, 0.7]

#: the seven methods of seed 004 (registry names), in table order
METHODS = ("nearest_neighbour", "pda", "mht", "pmht", "msda", "particle", "gaussian_sum")
LABELS = {
    "nearest_neighbour": "NN",
    "pda": "PDA",
    "mht": "MHT",
    "pmht": "PMHT",
    "msda": "MSDA",
    "particle": "particle",
    "gaussian_sum": "Gaussian sum",
}
#: settings beyond the clutter model (P_D, the true λ and P_G = 0.99 go to every method whose factory takes them)
PARTICLES = 1000
SETTINGS = {
    "mht": {"window": 3, "max_hypotheses": 10},
    "particle": {"particles": PARTICLES},
    "gaussian_sum": {"max_components": 8},
}

# Part 2
CHANGE_STEP = 20
EXAMPLE1_NOISE = np.diag([0.01, 0.01])
ALPHA = BETA = 0.1
DETECTION_CASES = [(0.0, 1.0), (0.25, 0.9), (0.5, 0.9), (1.0, 0.9), (2.0, 0.9)]


# --------------------------------------------------------------------------- part 1


def _lost_at(errors: np.ndarray) -> int | None:
    """First step of the first run of LOSS_STEPS consecutive errors above LOSS_DISTANCE, or None."""
    above = errors > LOSS_DISTANCE
    run = 0
    for k, a in enumerate(above):
        run = run + 1 if a else 0
        if run == LOSS_STEPS:
            return k - LOSS_STEPS + 1
    return None


def make_estimator(registry, name: str, detection_probability: float, density: float, seed: int):
    """The registered estimator ``name`` with the clutter model (P_D, λ, P_G) and :data:`SETTINGS`, passing only the
    parameters its factory takes (nearest neighbour takes the gate only)."""
    factory = registry.get("estimator", name)
    accepted = inspect.signature(factory).parameters
    wanted = {"detection_probability": detection_probability, "clutter_density": density, "gate_probability": GATE, "seed": seed}
    wanted.update(SETTINGS.get(name, {}))
    estimator = factory(**{k: v for k, v in wanted.items() if k in accepted})
    if not estimator.accepts_scans:
        raise ValueError(f"--methods: estimator {name!r} does not take clutter scans")
    return estimator


def simulate_run(seed: int, density: float, detection_probability: float):
    """One seeded truth + clutter realisation: (scans of sensor ``pos``, true positions (K+1, 2), λV, the sensor)."""
    trajectory_seed, measurement_seed, clutter_seed = np.random.SeedSequence([seed, 1]).spawn(3)
    schedule = SEED001_TABLE1
    truth = simulate_trajectory(schedule, X0, TAU, seed=np.random.default_rng(trajectory_seed), noise_cov=np.eye(2) * 0.001)
    sensor = PositionSensor("pos", ("x", "y"), np.eye(2) * TRACKING_R)
    clean = simulate_measurements(truth, [sensor], seed=np.random.default_rng(measurement_seed))
    clutter = ClutterModel(density, detection_probability, region_around(truth.positions, 3.0))
    scans = add_clutter(clean, clutter, seed=np.random.default_rng(clutter_seed))["pos"]
    return scans, truth.states_in(LAYOUT)[:, [0, 2]], clutter.expected_false, sensor


def _outcome(errors: np.ndarray, seconds_per_step: float) -> dict:
    return {
        "lost_at": _lost_at(errors),
        "sum_sq_error": float(np.sum(errors**2)),
        "steps": int(errors.size),
        "seconds_per_step": seconds_per_step,
    }


def track_run(seed: int, density: float, detection_probability: float, methods, registry, models, simulated=None) -> dict:
    """One seeded truth + clutter realisation, every method on the same scans: loss step, squared errors, time per step
    (``simulated``: :func:`simulate_run`'s result for these arguments when already drawn)."""
    scans, positions, expected_false, sensor = simulated or simulate_run(seed, density, detection_probability)
    bank = TransitionBank.stack([models["tracker"].transition(TAU, X0)])
    steps = [scans.scan(k) for k in range(scans.steps)]
    out = {"expected_false_per_step": expected_false}
    for name in methods:
        estimator = make_estimator(registry, name, detection_probability, density, seed)
        state = estimator.initialize(X0[None], np.eye(4)[None] * 0.1)
        errors = np.empty(scans.steps)
        started = time.perf_counter()
        for k, scan in enumerate(steps):
            if k:
                state = estimator.predict(state, bank)
            state, _ = estimator.update(state, scan, [sensor], LAYOUT)
            errors[k] = np.hypot(*(estimator.mean(state)[0, [0, 2]] - positions[k]))
        out[name] = _outcome(errors, (time.perf_counter() - started) / scans.steps)
    return out


#: methods whose runs go as one bank of one filter per run, each row with its own candidates (``RowScan``)
BATCHED = ("nearest_neighbour", "pda")


def track_runs(seeds, density: float, detection_probability: float, methods, registry, models) -> list[dict]:
    """:func:`track_run` of every seed: the methods of :data:`BATCHED` as one bank of len(seeds) filters (row r = run r,
    updated with ``stack_scans`` of the runs' scans: the per-run results to rounding, the same loss steps), the
    others run by run.  A batched method's ``seconds_per_step`` is the bank's time per step divided by the runs."""
    seeds = list(seeds)
    simulated = [simulate_run(seed, density, detection_probability) for seed in seeds]
    alone = [name for name in methods if name not in BATCHED]
    outs = [track_run(seed, density, detection_probability, alone, registry, models, sim) for seed, sim in zip(seeds, simulated)]
    R = len(seeds)
    steps = simulated[0][0].steps
    positions = np.stack([s[1] for s in simulated])  # (R, K+1, 2)
    sensor = simulated[0][3]
    bank = TransitionBank.stack([models["tracker"].transition(TAU, X0)] * R)
    row_scans = [stack_scans([s[0].scan(k) for s in simulated]) for k in range(steps)]
    for name in [m for m in methods if m in BATCHED]:
        estimator = make_estimator(registry, name, detection_probability, density, seeds[0])
        state = estimator.initialize(np.repeat(X0[None], R, axis=0), np.repeat(np.eye(4)[None] * 0.1, R, axis=0))
        errors = np.empty((R, steps))
        started = time.perf_counter()
        for k, scan in enumerate(row_scans):
            if k:
                state = estimator.predict(state, bank)
            state, _ = estimator.update(state, scan, [sensor], LAYOUT)
            errors[:, k] = np.hypot(*(estimator.mean(state)[:, [0, 2]] - positions[:, k]).T)
        seconds = (time.perf_counter() - started) / (steps * R)
        for out, e in zip(outs, errors):
            out[name] = _outcome(e, seconds)
    return outs


def tracking_table(runs: int, methods, batched: bool = True) -> list[dict]:
    """The tracking rows per (P_D, λ); with ``batched`` the :data:`BATCHED` methods run as one bank per cell
    (:func:`track_runs`, equal results), else every method run by run."""
    registry = get_registry()
    models = {"tracker": registry.create("motion_model", "straight", noise_cov=np.eye(2) * TRACKER_Q)}
    rows = []
    for detection_probability in DETECTION_PROBABILITIES:
        for density in DENSITIES:
            if batched:
                results = track_runs(range(runs), density, detection_probability, methods, registry, models)
            else:
                results = [track_run(seed, density, detection_probability, methods, registry, models) for seed in range(runs)]
            row = {
                "density": density,
                "detection_probability": detection_probability,
                "runs": runs,
                "expected_false_per_step": float(np.mean([r["expected_false_per_step"] for r in results])),
            }
            for name in methods:
                kept = [r[name] for r in results if r[name]["lost_at"] is None]
                lost = [r[name]["lost_at"] for r in results if r[name]["lost_at"] is not None]
                row[name] = {
                    "track_loss_rate": 1.0 - len(kept) / runs,
                    "rmse_kept": float(np.sqrt(sum(r["sum_sq_error"] for r in kept) / sum(r["steps"] for r in kept))) if kept else None,
                    "mean_loss_step": float(np.mean(lost)) if lost else None,
                    "time_per_step_us": float(1e6 * np.mean([r[name]["seconds_per_step"] for r in results])),
                }
            rows.append(row)
            print(
                f"P_D = {detection_probability}, λ = {density}: "
                + ", ".join(f"{LABELS[n]} loss {row[n]['track_loss_rate']:.2f} rmse {_f(row[n]['rmse_kept'])}" for n in methods),
                flush=True,
            )
    return rows


def plot_loss(result: dict, path: Path) -> None:
    """Track-loss rate against λ per method, one panel per P_D (docs/images/clutter_loss.png)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["tracking"]
    methods = result["methods"]
    fig, axes = plt.subplots(1, len(DETECTION_PROBABILITIES), figsize=(10, 4), sharey=True)
    for ax, pd_ in zip(np.atleast_1d(axes), DETECTION_PROBABILITIES):
        mine = [r for r in rows if r["detection_probability"] == pd_]
        for name in methods:
            ax.plot([r["density"] for r in mine], [r[name]["track_loss_rate"] for r in mine], marker="o", label=LABELS[name])
        ax.set_xscale("log")
        ax.set_xticks(DENSITIES, [f"{d:g}" for d in DENSITIES])
        ax.minorticks_off()
        ax.set_xlabel("clutter density λ (false measurements per m² per step)")
        ax.set_title(f"P_D = {pd_:g}")
        ax.grid(True, alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel(f"track-loss rate ({result['tracking_runs']} runs)")
    np.atleast_1d(axes)[-1].legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------- part 2


def detection_run(seed: int, density: float, detection_probability: float, models, labels) -> dict:
    trajectory_seed, measurement_seed, clutter_seed = np.random.SeedSequence([seed, 2]).spawn(3)
    schedule = Schedule.from_rows([("straight", CHANGE_STEP), ("right_turn", 30, 5.0)])
    truth = simulate_trajectory(schedule, X0, TAU, seed=np.random.default_rng(trajectory_seed), noise_cov=EXAMPLE1_NOISE)
    sensor = PositionSensor("pos", ("x", "y"), EXAMPLE1_NOISE)
    clean = simulate_measurements(truth, [sensor], seed=np.random.default_rng(measurement_seed))
    clutter = ClutterModel(density, detection_probability, region_around(truth.positions, 2.0))
    scans = add_clutter(clean, clutter, seed=np.random.default_rng(clutter_seed))["pos"]
    gate = None if density == 0.0 and detection_probability == 1.0 else GATE  # the KF reference has no gate
    estimator = PDAFilter(detection_probability, density, gate)
    detector = ChangeTimeSPRT(alpha=ALPHA, beta=BETA)
    signal = SignalFunction()

    current = 0
    changes, signal_alarms = [], []

    def restart():
        alternatives = [i for i in range(len(models)) if i != current]
        detector.hypotheses = (labels[current],) + tuple(labels[i] for i in alternatives)
        detector.reset()
        return alternatives

    def observe_signal(k, innovation):
        a = innovation.associations[0]
        chosen = a.selected[0]
        nis = a.distances[0, chosen] if chosen >= 0 else 0.0
        out = signal.observe(k, np.zeros(1), np.array([nis]), 2 if chosen >= 0 else 0)
        if out.decision is not None:
            signal_alarms.append(k)

    alternatives = restart()
    bank = FilterBank(estimator, LAYOUT, [sensor])
    bank.start(X0, np.eye(4), [models[current]], X0)
    observe_signal(0, bank.step(None, scans.scan(0)).innovation)
    max_bank = 1
    for k in range(1, scans.steps):
        bank.add([0] * len(alternatives), [models[i] for i in alternatives], bank.means[0].copy())
        detector.add(np.arange(1, len(models)), k)
        innovation = bank.step(TAU, scans.scan(k)).innovation
        max_bank = max(max_bank, len(bank))
        out = detector.observe(k, innovation.association_loglik, innovation.nis, innovation.measurement_dim)
        observe_signal(k, innovation)
        if out.decision is not None:
            if detector.decided:
                entry = int(detector.chosen_entry)
                current = alternatives[detector.decided - 1]
                changes.append((k, labels[current], int(detector.starts[entry])))
                bank.take([1 + entry])
                signal.reset()
            else:
                bank.take([0])
            alternatives = restart()
    after = [c for c in changes if c[0] > CHANGE_STEP]
    first = after[0] if after else None
    signal_after = [k for k in signal_alarms if k > CHANGE_STEP]
    return {
        "seed": seed,
        "false_alarms": sum(1 for c in changes if c[0] <= CHANGE_STEP),
        "mode": None if first is None else first[1],
        "delay": None if first is None else first[0] - CHANGE_STEP,
        "estimated_change_step": None if first is None else first[2],
        "signal_false_alarms": sum(1 for k in signal_alarms if k <= CHANGE_STEP),
        "signal_delay": None if not signal_after else signal_after[0] - CHANGE_STEP,
        "max_bank": max_bank,
        "expected_false_per_step": clutter.expected_false,
    }


def detection_table(runs: int) -> list[dict]:
    registry = get_registry()
    specs = [("straight", {}), ("right_turn", {"radius": 5.0}), ("left_turn", {"radius": 5.0})]
    models = [registry.create("motion_model", name, noise_cov=EXAMPLE1_NOISE, **params) for name, params in specs]
    labels = ("straight", "right_turn_r5", "left_turn_r5")
    rows = []
    for density, detection_probability in DETECTION_CASES:
        results = [detection_run(seed, density, detection_probability, models, labels) for seed in range(runs)]
        right = [r for r in results if r["mode"] == "right_turn_r5"]
        delays = np.array([r["delay"] for r in right], dtype=float)
        signal_delays = np.array([r["signal_delay"] for r in results if r["signal_delay"] is not None], dtype=float)
        row = {
            "density": density,
            "detection_probability": detection_probability,
            "runs": runs,
            "expected_false_per_step": float(np.mean([r["expected_false_per_step"] for r in results])),
            "detected_right_turn": len(right) / runs,
            "detected_other_mode": sum(1 for r in results if r["mode"] not in (None, "right_turn_r5")) / runs,
            "undetected": sum(1 for r in results if r["mode"] is None) / runs,
            "runs_with_false_alarm_before_change": sum(1 for r in results if r["false_alarms"]) / runs,
            "delay_mean": float(delays.mean()) if delays.size else None,
            "delay_median": float(np.median(delays)) if delays.size else None,
            "delay_quartiles": [float(q) for q in np.percentile(delays, [25, 75])] if delays.size else None,
            "signal_detected": signal_delays.size / runs,
            "signal_delay_median": float(np.median(signal_delays)) if signal_delays.size else None,
            "signal_runs_with_false_alarm_before_change": sum(1 for r in results if r["signal_false_alarms"]) / runs,
            "max_bank": int(max(r["max_bank"] for r in results)),
        }
        rows.append(row)
        print(
            f"λ = {density}, P_D = {detection_probability}: right turn {row['detected_right_turn']:.2f}, median delay {row['delay_median']}, "
            f"false alarms {row['runs_with_false_alarm_before_change']:.2f}; signal {row['signal_detected']:.2f} "
            f"median {row['signal_delay_median']} FA {row['signal_runs_with_false_alarm_before_change']:.2f}",
            flush=True,
        )
    return rows


# --------------------------------------------------------------------------- report


def _f(value, digits=3):
    return "–" if value is None else f"{value:.{digits}f}"


def markdown(result: dict) -> str:
    methods = result["methods"]
    lines = [
        "### Seven methods in clutter: track loss, RMSE and cost (seed-001 Table 1 trajectory, R = 0.1 I)",
        "",
        f"{result['tracking_runs']} seeded runs per (P_D, λ), 361 steps, every method on the same scans; track lost after "
        f"{LOSS_STEPS} consecutive steps with position error > {LOSS_DISTANCE} m. Each cell: track-loss rate · RMSE (m) over "
        "the runs not lost · mean time per step (µs, predict + update, one filter"
        + ("; NN and PDA: their bank of all the runs' filters, per filter" if result.get("batched") else ", run by run")
        + "; timings depend on the machine's load).",
    ]
    for pd_ in DETECTION_PROBABILITIES:
        mine = [r for r in result["tracking"] if r["detection_probability"] == pd_]
        if not mine:
            continue
        lines += [
            "",
            f"P_D = {pd_:g}; mean false measurements per step: " + ", ".join(f"{r['expected_false_per_step']:.0f}" for r in mine),
            "",
            "| method | " + " | ".join(f"λ = {r['density']:g} /m²" for r in mine) + " |",
            "|---|" + "---|" * len(mine),
        ]
        for name in methods:
            cells = [f"{r[name]['track_loss_rate']:.2f} · {_f(r[name]['rmse_kept'])} · {r[name]['time_per_step_us']:.0f}" for r in mine]
            lines.append(f"| {LABELS[name]} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "### Example 1 in clutter: the right turn detected by the change-time SPRT on PDA filters",
        "",
        f"{result['detection_runs']} seeded runs per row; change at step {CHANGE_STEP}; α = β = {ALPHA}; delay = decision step − {CHANGE_STEP}. "
        "The signal-function columns: ±3 bounds on the straight filter's nearest gated candidate.",
        "",
        "| λ (1/m²) | P_D | mean false per step | right turn detected | other mode | undetected | SPRT false alarm before change | delay median [IQR] | delay mean | signal fn detected | signal fn median delay | signal fn false alarm before change |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in result["detection"]:
        iqr = "–" if row["delay_quartiles"] is None else f"[{row['delay_quartiles'][0]:g}, {row['delay_quartiles'][1]:g}]"
        lines.append(
            f"| {row['density']:g} | {row['detection_probability']:g} | {row['expected_false_per_step']:.1f} | {row['detected_right_turn']:.2f} | "
            f"{row['detected_other_mode']:.2f} | {row['undetected']:.2f} | {row['runs_with_false_alarm_before_change']:.2f} | "
            f"{_f(row['delay_median'], 1)} {iqr} | {_f(row['delay_mean'], 2)} | {row['signal_detected']:.2f} | "
            f"{_f(row['signal_delay_median'], 1)} | {row['signal_runs_with_false_alarm_before_change']:.2f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10, help="tracking runs per (P_D, clutter density)")
    parser.add_argument("--detection-runs", type=int, default=60, help="Example 1 runs per clutter density")
    parser.add_argument(
        "--methods", nargs="+", default=list(METHODS), metavar="NAME", help=f"registry names of the methods (default: {' '.join(METHODS)})"
    )
    parser.add_argument(
        "--batched",
        action="store_true",
        help="run NN and PDA as one bank per cell (faster; their time per step is then per filter of the bank)",
    )
    parser.add_argument("--out", default=str(ROOT / "docs" / "results" / "clutter.json"))
    parser.add_argument(
        "--plot",
        nargs="?",
        const=str(ROOT / "docs" / "images" / "clutter_loss.png"),
        default=None,
        help="write the track-loss figure (default path docs/images/clutter_loss.png)",
    )
    args = parser.parse_args(argv)
    if args.runs < 0 or args.detection_runs < 0:
        parser.error("--runs and --detection-runs must be ≥ 0")
    known = get_registry().names("estimator")
    unknown = [m for m in args.methods if m not in known]
    if unknown:
        parser.error(f"--methods: unknown estimator(s) {unknown}; registered: {known}")
    start = time.perf_counter()
    out = Path(args.out)
    # a part run with 0 runs keeps its rows from the existing output file (to re-run the other part alone)
    previous = json.loads(out.read_text()) if out.exists() and not (args.runs and args.detection_runs) else {}
    result = {"tracking_runs": args.runs, "detection_runs": args.detection_runs, "methods": list(args.methods), "batched": args.batched}
    result["settings"] = {"particles": PARTICLES, **{k: v for k, v in SETTINGS.items() if k in args.methods}, "gate_probability": GATE}
    if args.runs:
        result["tracking"] = tracking_table(args.runs, args.methods, batched=args.batched)
    else:
        for key in ("tracking_runs", "methods", "settings", "tracking"):
            result[key] = previous.get(key, [] if key in ("tracking", "methods") else result[key])
    if args.detection_runs:
        result["detection"] = detection_table(args.detection_runs)
    else:
        result["detection_runs"], result["detection"] = previous.get("detection_runs", 0), previous.get("detection", [])
    result["seconds"] = round(time.perf_counter() - start, 1)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    out.with_suffix(".md").write_text(markdown(result))
    if args.plot:
        plot_loss(result, Path(args.plot))
    print(markdown(result))
    return result


if __name__ == "__main__":
    main()
