"""``examples/aircraft.toml`` on simulated aircraft tracks written as an x/y file (issue 22, Show).

    python experiments/aircraft_tracks.py --json PATH [--flights N] [--seed S]

Each flight: a speed U(50, 250) m/s, a heading U(0°, 360°), and eight legs,
alternately straight (U(60, 240) s) and a turn of varying rate — the turn rate
ω(t) rises linearly from 0 to a peak |v|/r, r ~ U(1, 30) km, left or right
at random, holds it and falls back to 0, over U(60, 240) s (so the radius
varies through the turn).  Reports come U(1, 10) s apart; each is the
position at its time stamp plus the time-stamp error δt ~ N(0, σ_t²),
σ_t = 0.3 s (the report is where the aircraft was δt later: an along-track
error |v| δt, 15–75 m), plus N(0, σ²), σ = 30 m, per coordinate.  The
flights go to a CSV of columns ``time, flight, x, y``; ``track`` reads it with
examples/aircraft.toml whose ``[reader]`` table alone is replaced by
``time = "time", id = "flight", x = "x", y = "y"``.

The reference mode of a report is the truth's: straight where ω = 0, left or
right where |ω| > 0 (Bar-Shalom's convention, ω > 0 counter-clockwise);
scored: accuracy, balanced accuracy (straight / left / right), false turns per
hour (a turn segment of the tracker overlapping no true turn of its
direction), median onset delay (from the start of a true turn to the first
report the tracker gives it), position RMSE against the truth; for the
causal tracker, ``--smooth``, and the simplest sound alternative: one EKF of
the coordinated turn with the file's noise and sensor, a turn while |ω̂| >
0.5°/s until it falls below 0.25°/s (``turn_rate_ekf``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from hybridtrack.apps.tracking import load_config, output_name, track_file
from hybridtrack.core.plugins import resolve

ROOT = Path(__file__).resolve().parents[1]
AIRCRAFT = ROOT / "examples" / "aircraft.toml"
CLASSES = ("straight", "left_turn", "right_turn")
SIGMA, JITTER = 30.0, 0.3


def flight(rng: np.random.Generator, legs: int = 8, step: float = 0.1):
    """(times, positions (K, 2), velocities (K, 2), modes (K,)) of one noise-free flight on a 0.1 s grid."""
    speed, heading = rng.uniform(50.0, 250.0), rng.uniform(0.0, 2 * np.pi)
    rates = []
    for leg in range(legs):
        n = int(rng.uniform(60.0, 240.0) / step)
        if leg % 2 == 0:
            rates.append(np.zeros(n))
        else:
            peak = rng.choice([-1.0, 1.0]) * speed / rng.uniform(1e3, 30e3)
            ramp = max(1, n // 4)
            shape = np.minimum(1.0, np.minimum(np.arange(n) + 1, n - np.arange(n)) / ramp)
            rates.append(peak * shape)
    omega = np.concatenate(rates)
    psi = heading + np.cumsum(omega) * step
    velocity = speed * np.stack([np.cos(psi), np.sin(psi)], axis=1)
    position = np.cumsum(velocity, axis=0) * step
    modes = np.where(omega > 0, "left_turn", np.where(omega < 0, "right_turn", "straight"))
    return np.arange(omega.size) * step, position, velocity, modes


def reports(rng: np.random.Generator, times, position, velocity):
    """Indices of reports U(1, 10) s apart and their measured positions (jitter along the track, noise)."""
    chosen, t = [0], 0.0
    while True:
        t += rng.uniform(1.0, 10.0)
        k = int(np.searchsorted(times, t))
        if k >= times.size:
            break
        chosen.append(k)
    idx = np.array(chosen)
    measured = position[idx] + velocity[idx] * JITTER * rng.standard_normal((idx.size, 1)) + rng.normal(0.0, SIGMA, (idx.size, 2))
    return idx, measured


def config_for_xy(path: Path) -> Path:
    """examples/aircraft.toml with only its [reader] table replaced by the x/y file's columns."""
    text = AIRCRAFT.read_text(encoding="utf-8")
    head, rest = text.split("\n[reader]\n", 1)
    body = rest[rest.index("\n[") :]
    reader = '\n[reader]\ntime = "time"\nid = "flight"\nx = "x"\ny = "y"\nmin_reports = 20\n'
    path.write_text(head + reader + body, encoding="utf-8")
    tomllib.loads(path.read_text(encoding="utf-8"))
    return path


def _runs(values):
    edges = np.flatnonzero(values[1:] != values[:-1]) + 1
    return list(zip(np.r_[0, edges], np.r_[edges, values.size]))


def score(cases, decided, estimates, seconds) -> dict:
    labels = np.concatenate([c[2] for c in cases])
    modes = np.concatenate(decided)
    recall = {c: float(np.mean(modes[labels == c] == c)) for c in CLASSES if np.any(labels == c)}
    delays, onsets, false_turns, hours = [], 0, 0, 0.0
    for (t, _, label, _), mode in zip(cases, decided):
        hours += (t[-1] - t[0]) / 3600.0
        for a, b in _runs(label):
            if label[a] != "straight":
                onsets += 1
                hit = np.flatnonzero(mode[a:b] == label[a])
                if hit.size:
                    delays.append(float(t[a + hit[0]] - t[a]))
        for a, b in _runs(mode):
            if mode[a] != "straight" and not np.any(label[a:b] == mode[a]):
                false_turns += 1
    errors = np.concatenate([np.sum((e - c[1]) ** 2, axis=1) for c, e in zip(cases, estimates)])
    return {
        "accuracy": float(np.mean(modes == labels)),
        "balanced_accuracy": float(np.mean(list(recall.values()))),
        "recall": recall,
        "median_onset_delay_s": float(np.median(delays)) if delays else None,
        "detected_onsets": len(delays) / onsets if onsets else None,
        "false_turns_per_hour": float(false_turns / hours),
        "rmse_m": float(np.sqrt(np.mean(errors))),
        "us_per_report": seconds / labels.size * 1e6,
    }


def turn_rate_ekf(cases, measured: list, config: dict) -> tuple[list, list, float]:
    """One coordinated-turn EKF per flight with the configuration's density, σ and time jitter; hysteresis on ω̂."""
    est = config["estimator"]
    model = resolve("motion_model", ("coordinated_turn", {"noise_density": est["noise_density"]}))
    m = config["measurement"]
    sensor = resolve("sensor", ("position", {"noise_cov": m["sigma"] ** 2 * np.eye(2), "time_jitter": m.get("time_jitter", 0.0)}))
    ekf = resolve("estimator", ("ekf", {}))
    on, off = np.radians(0.5), np.radians(0.25)
    decided, estimates, start = [], [], time.perf_counter()
    for (t, *_), z in zip(cases, measured):
        v0 = (z[1] - z[0]) / (t[1] - t[0])
        state = ekf.initialize(
            np.array([[z[0, 0], v0[0], z[0, 1], v0[1], 0.0]]), np.diag([500.0**2, 100.0**2, 500.0**2, 100.0**2, 1e-4])[None]
        )
        state, _ = ekf.update(state, z[0], [sensor], model.layout)
        current, modes, xy = "straight", ["straight"], [ekf.mean(state)[0, [0, 2]]]
        for k in range(1, len(t)):
            state = ekf.predict(state, model.linearizer(t[k] - t[k - 1]))
            state, _ = ekf.update(state, z[k], [sensor], model.layout)
            w = ekf.mean(state)[0, 4]
            current = ("left_turn" if w > 0 else "right_turn") if abs(w) > on else ("straight" if abs(w) < off else current)
            modes.append(current)
            xy.append(ekf.mean(state)[0, [0, 2]])
        decided.append(np.array(modes))
        estimates.append(np.array(xy))
    return decided, estimates, time.perf_counter() - start


def evaluate(flights: int = 20, seed: int = 7) -> dict:
    cases, measured_all, rows = [], [], ["time,flight,x,y"]
    for f in range(flights):
        rng = np.random.default_rng(np.random.SeedSequence([seed, f]))
        times, position, velocity, modes = flight(rng)
        idx, measured = reports(rng, times, position, velocity)
        cases.append((times[idx], position[idx], modes[idx], f"f{f:03d}"))
        measured_all.append(measured)
        rows += [f"{times[k]:.3f},f{f:03d},{x:.3f},{y:.3f}" for k, (x, y) in zip(idx, measured)]
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "flights.csv").write_text("\n".join(rows) + "\n")
        config = config_for_xy(tmp / "aircraft_xy.toml")
        for label, smooth in (("causal", False), ("smoothed", True)):
            start = time.perf_counter()
            track_file(tmp / "flights.csv", config, tmp / label, smooth=smooth)
            seconds = time.perf_counter() - start
            decided, estimates = [], []
            for case in cases:
                with np.load(tmp / label / f"{output_name(case[3])}.npz") as npz:
                    layout = list(npz["layout"])
                    decided.append(np.array([str(m) for m in npz["modes"]]))
                    estimates.append(npz["means"][:, [layout.index("x"), layout.index("y")]])
            out[label] = score(cases, decided, estimates, seconds)
        out["turn_rate_ekf"] = score(cases, *turn_rate_ekf(cases, measured_all, load_config(config)))
    labels = np.concatenate([c[2] for c in cases])
    return {
        "protocol": {
            "flights": flights,
            "seed": seed,
            "reports": int(labels.size),
            "sigma_m": SIGMA,
            "time_jitter_s": JITTER,
            "labels": {c: int(np.sum(labels == c)) for c in CLASSES},
            "config": "examples/aircraft.toml, [reader] replaced by time/flight/x/y columns",
        },
        **out,
    }


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", required=True, metavar="PATH")
    parser.add_argument("--flights", type=int, default=20)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args(argv)
    result = evaluate(args.flights, args.seed)
    result["command"] = "python experiments/aircraft_tracks.py " + " ".join(sys.argv[1:] if argv is None else argv)
    for key in ("causal", "smoothed", "turn_rate_ekf"):
        r = result[key]
        print(
            f"{key:>9}: acc {r['accuracy']:.3f} bal {r['balanced_accuracy']:.3f} false/h {r['false_turns_per_hour']:.1f} delay {r['median_onset_delay_s']} rmse {r['rmse_m']:.1f} m"
        )
    Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
