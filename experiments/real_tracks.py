"""The trackers on real ship tracks, scored against the course-based labels (issue 22, "The evaluation").

    python experiments/real_tracks.py [FILE] --json PATH [--plot [--plot-path PNG]] [--vessels N] [--max-reports K] [--seed S]

FILE (default the Solent AIS file of data/solent_ais) is read with the reader
settings of examples/ships.toml; every object with course and speed columns and
at least ``min_reports`` reports is used (``--vessels`` the first N of them,
``--max-reports`` the first K reports of each, for a quick run).  The reports
are the reference positions; each tracker runs on the reports with N(0, σ²)
added to each coordinate, σ = ``--sigma`` = 10 m (seeded per vessel), so its
position error can be measured against the reports.  The reference modes are
the labels of :func:`hybridtrack.apps.mode_labels.label_track` (default
thresholds: a turn above 0.5°/s of smoothed course change, back below 0.25°/s,
stop below 0.5 m/s, segments under 20 s merged).

Trackers (``hybridtrack track`` through :func:`hybridtrack.apps.tracking.track_one`,
outputs read from its ``.npz``, no recording):

* ``sprt`` — examples/ships_sprt.toml (Algorithm 3's SPRT bank over fixed-radius turns);
* ``fixed_radius_imm`` — the same modes and noise in an IMM (sojourn 120 s);
* ``turn_rate_imm`` — examples/ships_turn_rate.toml (IMM of straight and the
  coordinated turn with ω in the state), causal;
* ``turn_rate_imm_smoothed`` — the same, ``--smooth`` (fixed interval);
* ``ships`` — examples/ships.toml: the same IMM also measuring the reported course
  and speed (the velocity sensor), each report's mode by the estimated turn rate
  and speed (``[segments] by = "motion"``), causal; ``ships_smoothed`` the same
  with ``--smooth``; ``ships_lag_15s`` with ``--lag 15`` (each report decided
  from the reports up to 15 s after it: the half-width of the labels' window);
* ``cv`` — one constant-velocity Kalman filter, its density q chosen from
  {10⁻⁴, 10⁻³, 10⁻², 10⁻¹} m²/s³ for the least position error over the vessels
  (always "straight");
* ``turn_rate_ekf`` — the simplest sound alternative: one EKF of the coordinated
  turn (the noise of ``turn_rate_imm``, ω bounded by 0.05 rad/s) and the labels'
  own hysteresis applied to its estimate (stop below 0.5 m/s until 1 m/s, else
  a turn above 0.5°/s of |ω̂| until below 0.25°/s), written here in a few lines;
  ``turn_rate_ekf_course_speed`` the same EKF also measuring the reported course
  and speed (the velocity sensor of ``ships``): the alternative to ``ships``;
* ``always_straight`` — "straight" at every report (positions: the noisy reports).

Scores, pooled over the vessels:

* ``accuracy`` — the fraction of reports whose mode is the label's;
  ``balanced_accuracy`` the mean recall over the labelled classes straight /
  left_turn / right_turn / stop (a tracker without a stop mode scores 0 on
  stop); ``recall`` per class;
* ``median_onset_delay_s`` — over the labelled turn onsets (a report whose label
  becomes left or right), the time to the first report of that labelled
  segment the tracker gives the same turn; ``detected_onsets`` the fraction so
  found;
* ``false_turns_per_hour`` — the tracker's turn segments (maximal runs of one
  turn direction) that share no report with a labelled turn of that direction,
  per hour of data;
* ``stopped_in_turn`` — the fraction of stop-labelled reports the tracker calls
  a turn; ``stationary_in_turn`` the same over the stationary reports: those of
  a labelled stop more than the labels' window W = 30 s from both its ends (near
  an end the vessel is still slowing or starting: the labels smooth its speed
  over W);
* ``rmse_m`` — √(mean ‖p̂_k − report_k‖²) over all reports;
* ``us_per_report`` — wall time per report (this machine; relative).

The JSON holds ``protocol`` (data, noise, seed, trackers' configurations), one
row per tracker and the per-class label counts; the Markdown table goes beside
it (``.md``).  ``--plot`` draws accuracy, balanced accuracy and false turns per
hour per tracker into docs/images/real_tracks.png (or ``--plot-path``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import attrs
import numpy as np

from hybridtrack.apps.mode_labels import DEFAULTS as LABEL_DEFAULTS
from hybridtrack.apps.mode_labels import label_track
from hybridtrack.apps.tracking import load_config, measurements_of, output_name, track_one
from hybridtrack.core.plugins import resolve
from hybridtrack.io.track_files import read_tracks

ROOT = Path(__file__).resolve().parents[1]
SOLENT = ROOT / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"
SHIPS, SPRT, TURN_RATE = (ROOT / "examples" / name for name in ("ships.toml", "ships_sprt.toml", "ships_turn_rate.toml"))
CLASSES = ("straight", "left_turn", "right_turn", "stop")
TURNS = ("left_turn", "right_turn")
CV_DENSITIES = (1e-4, 1e-3, 1e-2, 1e-1)
#: the turn-rate EKF's bound on ω (rad/s, 2.9°/s: a ship's turn) and its stop hysteresis (m/s, the labels' v_stop, v_go)
EKF_MAX_RATE, V_STOP, V_GO = 0.05, 0.5, 1.0
#: s: the fixed lag of ``ships_lag_15s``, the half-width of the labels' centred window
LAG = LABEL_DEFAULTS["window"] / 2


def vessels(path, vessel_count=None, max_reports=None) -> list[tuple]:
    """(track, labels) of the objects with course and speed and ≥ min_reports reports (ships.toml's reader)."""
    cfg = load_config(SHIPS)
    data = read_tracks(path, **cfg["reader"], warn=False)
    out = []
    for track in data.tracks.values():
        if len(track) < cfg["min_reports"] or track.course is None or track.speed is None:
            continue
        if max_reports is not None and len(track) > max_reports:
            keep = slice(0, max_reports)
            track = attrs.evolve(
                track,
                times=track.times[keep],
                positions=track.positions[keep],
                lines=track.lines[keep],
                course=track.course[keep],
                speed=track.speed[keep],
            )
        out.append((track, np.array(label_track(track).modes)))
        if vessel_count is not None and len(out) == vessel_count:
            break
    return out


def noisy(track, sigma: float, seed: int, index: int):
    """The track with N(0, σ²) added to each horizontal coordinate (seeded by (seed, index))."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, index]))
    positions = np.array(track.positions, dtype=float)
    positions[:, :2] += rng.normal(0.0, sigma, positions[:, :2].shape)
    return attrs.evolve(track, positions=positions)


def configurations(sigma: float) -> dict:
    """tracker → (config dict, smooth: False, True (fixed interval) or a fixed lag in seconds)."""
    sprt, turn_rate, ships = load_config(SPRT), load_config(TURN_RATE), load_config(SHIPS)
    for cfg in (sprt, turn_rate, ships):
        cfg["measurement"]["sigma"] = sigma
    est = sprt["estimator"]
    imm = {**sprt, "estimator": {k: v for k, v in est.items() if k not in ("alpha", "beta", "bank_size", "initial_mode")}}
    imm["estimator"] |= {"algorithm": "imm", "sojourn": 120.0}
    return {
        "sprt": (sprt, False),
        "fixed_radius_imm": (imm, False),
        "turn_rate_imm": (turn_rate, False),
        "turn_rate_imm_smoothed": (turn_rate, True),
        "ships": (ships, False),
        "ships_smoothed": (ships, True),
        "ships_lag_15s": (ships, LAG),
    }


def cv_config(sigma: float, q: float) -> dict:
    cfg = load_config(TURN_RATE)
    cfg["measurement"]["sigma"] = sigma
    cfg["estimator"] = {
        "algorithm": "imm",
        "noise_density": q,
        "modes": [("straight", {})],
        "sojourn": 1e9,
        "filter": "kalman",
        "parameters": {},
    }
    return cfg


def run_tracker(cases, config: dict, smooth: bool | float) -> tuple[list, list, float]:
    """Per vessel (modes (K,), positions (K, 2)) and the seconds taken (tracking and the .npz, no recording)."""
    modes, positions, seconds = [], [], 0.0
    with tempfile.TemporaryDirectory() as out:
        for track, _, measured in cases:
            start = time.perf_counter()
            lag = None if isinstance(smooth, bool) else float(smooth)
            track_one(measured, config, Path(out), smooth=smooth is True, lag=lag, record=False)
            seconds += time.perf_counter() - start
            with np.load(Path(out) / f"{output_name(track.id)}.npz") as npz:
                layout = list(npz["layout"])
                modes.append(np.array([str(m) for m in npz["modes"]]))
                positions.append(npz["means"][:, [layout.index("x"), layout.index("y")]])
    return modes, positions, seconds


def run_turn_rate_ekf(cases, sigma: float, max_rate: float = EKF_MAX_RATE, course_speed: bool = False) -> tuple[list, list, float]:
    """One coordinated-turn EKF per vessel, hysteresis on ω̂ and on the speed (module docstring); ``course_speed``:
    also measuring the reported course and speed (ships.toml's velocity sensor)."""
    turn_rate = load_config(TURN_RATE)["estimator"]
    model = resolve("motion_model", ("coordinated_turn", {"noise_density": turn_rate["noise_density"], "max_rate": max_rate}))
    sensors = [resolve("sensor", ("position", {"noise_cov": sigma**2 * np.eye(2)}))]
    ships = load_config(SHIPS)
    if course_speed:
        measured = ships["measurement"]
        spec = {"speed_sigma": measured["speed_sigma"], "course_sigma": np.radians(measured["course_sigma"])}
        sensors.append(resolve("sensor", ("velocity", spec)))
    ekf = resolve("estimator", ("ekf", {}))
    on, off = np.radians(0.5), np.radians(0.25)
    modes, positions, seconds = [], [], 0.0
    for _, _, measured in cases:
        start = time.perf_counter()
        z, t = measured.positions[:, :2], measured.times
        v0 = (z[1] - z[0]) / (t[1] - t[0])
        if course_speed:
            z = np.hstack([z, measurements_of(measured, ships)["velocity"]])
        state = ekf.initialize(
            np.array([[z[0, 0], v0[0], z[0, 1], v0[1], 0.0]]), np.diag([250.0**2, 7.5**2, 250.0**2, 7.5**2, 0.02**2])[None]
        )
        state, _ = ekf.update(state, z[0], sensors, model.layout)
        current, out_modes, out_xy = "straight", ["straight"], [ekf.mean(state)[0, [0, 2]]]
        for k in range(1, len(t)):
            state = ekf.predict(state, model.linearizer(t[k] - t[k - 1]))
            state, _ = ekf.update(state, z[k], sensors, model.layout)
            x = ekf.mean(state)[0]
            w, speed = x[4], np.hypot(x[1], x[3])
            if speed < V_STOP or (current == "stop" and speed < V_GO):
                current = "stop"
            elif abs(w) > on:
                current = "left_turn" if w > 0 else "right_turn"
            elif abs(w) < off or current == "stop":
                current = "straight"
            out_modes.append(current)
            out_xy.append(ekf.mean(state)[0, [0, 2]])
        seconds += time.perf_counter() - start
        modes.append(np.array(out_modes))
        positions.append(np.array(out_xy))
    return modes, positions, seconds


def _runs(values: np.ndarray):
    """(start, stop, value) of the maximal runs of equal values."""
    edges = np.flatnonzero(values[1:] != values[:-1]) + 1
    starts, stops = np.r_[0, edges], np.r_[edges, values.size]
    return [(int(a), int(b), values[a]) for a, b in zip(starts, stops)]


def score(cases, modes: list, positions: list, seconds: float) -> dict:
    labels = np.concatenate([c[1] for c in cases])
    decided = np.concatenate(modes)
    recall = {c: (float(np.mean(decided[labels == c] == c)) if np.any(labels == c) else None) for c in CLASSES}
    delays, onsets, false_turns, hours, stationary = [], 0, 0, 0.0, []
    for (track, label, _), decision in zip(cases, modes):
        t = track.times
        hours += (t[-1] - t[0]) / 3600.0
        for a, b, value in _runs(label):
            if value == "stop":
                inside = (t[a:b] - t[a] > LABEL_DEFAULTS["window"]) & (t[b - 1] - t[a:b] > LABEL_DEFAULTS["window"])
                stationary.append(np.isin(decision[a:b][inside], TURNS))
            if value in TURNS:
                onsets += 1
                hit = np.flatnonzero(decision[a:b] == value)
                if hit.size:
                    delays.append(float(t[a + hit[0]] - t[a]))
        for a, b, value in _runs(decision):
            if value in TURNS and not np.any(label[a:b] == value):
                false_turns += 1
    errors = np.concatenate([np.sum((p - c[0].positions[:, :2]) ** 2, axis=1) for c, p in zip(cases, positions)])
    stopped = labels == "stop"
    present = [v for v in recall.values() if v is not None]
    return {
        "accuracy": float(np.mean(decided == labels)),
        "balanced_accuracy": float(np.mean(present)),
        "recall": recall,
        "median_onset_delay_s": float(np.median(delays)) if delays else None,
        "detected_onsets": len(delays) / onsets if onsets else None,
        "false_turns_per_hour": float(false_turns / hours),
        "stopped_in_turn": float(np.mean(np.isin(decided[stopped], TURNS))) if stopped.any() else None,
        "stationary_in_turn": float(np.mean(np.concatenate(stationary))) if sum(map(len, stationary)) else None,
        "rmse_m": float(np.sqrt(np.mean(errors))),
        "us_per_report": seconds / labels.size * 1e6,
    }


def evaluate(path=SOLENT, *, sigma=10.0, seed=2016, vessel_count=None, max_reports=None) -> dict:
    found = vessels(path, vessel_count, max_reports)
    cases = [(track, label, noisy(track, sigma, seed, i)) for i, (track, label) in enumerate(found)]
    rows, settings = [], {}
    for name, (config, smooth) in configurations(sigma).items():
        rows.append({"tracker": name} | score(cases, *run_tracker(cases, config, smooth)))
        settings[name] = {"estimator": {k: v for k, v in config["estimator"].items()}, "smooth": smooth}
    best = min(CV_DENSITIES, key=lambda q: score(cases, *run_tracker(cases, cv_config(sigma, q), False))["rmse_m"])
    rows.append({"tracker": "cv"} | score(cases, *run_tracker(cases, cv_config(sigma, best), False)))
    settings["cv"] = {"noise_density": best, "chosen_from": list(CV_DENSITIES)}
    rows.append({"tracker": "turn_rate_ekf"} | score(cases, *run_turn_rate_ekf(cases, sigma)))
    rows.append({"tracker": "turn_rate_ekf_course_speed"} | score(cases, *run_turn_rate_ekf(cases, sigma, course_speed=True)))
    straight = [np.full(len(c[0]), "straight") for c in cases]
    rows.append({"tracker": "always_straight"} | score(cases, straight, [c[2].positions[:, :2] for c in cases], 0.0))
    labels = np.concatenate([c[1] for c in cases])
    return {
        "protocol": {
            "file": str(Path(path).relative_to(ROOT)) if Path(path).is_relative_to(ROOT) else str(path),
            "vessels": len(cases),
            "reports": int(labels.size),
            "sigma_m": sigma,
            "seed": seed,
            "max_reports": max_reports,
            "labels": {c: int(np.sum(labels == c)) for c in CLASSES},
            "trackers": json.loads(json.dumps(settings, default=str)),
        },
        "rows": rows,
    }


def markdown(result: dict) -> str:
    """The table of the rows (docs/results.md includes it)."""
    lines = [
        "| tracker | accuracy | balanced (4 classes) | recall straight / left / right / stop | median onset delay (s) | onsets found |"
        " false turns / h | stopped reports in a turn (stationary) | RMSE (m) | µs / report |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]

    def number(value, form):
        return "–" if value is None else format(value, form)

    for row in result["rows"]:
        recall = " / ".join(number(row["recall"][c], ".2f") for c in CLASSES)
        lines.append(
            f"| {row['tracker']} | {row['accuracy']:.3f} | {row['balanced_accuracy']:.3f} | {recall} | {number(row['median_onset_delay_s'], '.0f')}"
            f" | {number(row['detected_onsets'], '.2f')} | {row['false_turns_per_hour']:.1f}"
            f" | {number(row['stopped_in_turn'], '.3f')} ({number(row['stationary_in_turn'], '.3f')})"
            f" | {row['rmse_m']:.1f} | {row['us_per_report']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def plot(result: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["rows"]
    names = [r["tracker"] for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for ax, key, title in zip(
        axes,
        ("accuracy", "balanced_accuracy", "false_turns_per_hour"),
        ("accuracy", "balanced accuracy (4 classes)", "false turns per hour"),
    ):
        ax.bar(range(len(rows)), [r[key] for r in rows], color="#4c72b0")
        ax.set_xticks(range(len(rows)), names, rotation=30, ha="right", fontsize=8)
        ax.set_title(title)
    fig.suptitle(
        f"{result['protocol']['vessels']} Solent vessels, {result['protocol']['reports']:,} reports, σ = {result['protocol']['sigma_m']:g} m added"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", nargs="?", default=str(SOLENT))
    parser.add_argument("--json", required=True, metavar="PATH", help="report to write (markdown table beside it, .md)")
    parser.add_argument("--plot", action="store_true", help="write docs/images/real_tracks.png (or --plot-path)")
    parser.add_argument("--plot-path", default=str(ROOT / "docs" / "images" / "real_tracks.png"))
    parser.add_argument("--vessels", type=int, help="the first N vessels only")
    parser.add_argument("--max-reports", type=int, help="the first K reports of each vessel only")
    parser.add_argument("--sigma", type=float, default=10.0, help="noise added to the reports (m)")
    parser.add_argument("--seed", type=int, default=2016)
    args = parser.parse_args(argv)
    result = evaluate(args.file, sigma=args.sigma, seed=args.seed, vessel_count=args.vessels, max_reports=args.max_reports)
    result["command"] = "python experiments/real_tracks.py " + " ".join(sys.argv[1:] if argv is None else argv)
    for row in result["rows"]:
        print(
            f"{row['tracker']:>24}: acc {row['accuracy']:.3f} bal {row['balanced_accuracy']:.3f} "
            f"false/h {row['false_turns_per_hour']:.1f} delay {row['median_onset_delay_s']} rmse {row['rmse_m']:.1f} m "
            f"{row['us_per_report']:.0f} µs"
        )
    Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    Path(args.json).with_suffix(".md").write_text(markdown(result))
    if args.plot:
        plot(result, args.plot_path)
    return result


if __name__ == "__main__":
    main()
