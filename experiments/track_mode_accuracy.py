"""Mode accuracy of ``hybridtrack track`` against the course-based labels (hybridtrack.apps.mode_labels).

    python experiments/track_mode_accuracy.py FILE --config examples/ships_sprt.toml [--out DIR] [--json PATH] [--moving-only]
        [--smooth | --lag SECONDS]

Runs :func:`hybridtrack.apps.tracking.track_file` on FILE (or reads the results
already in ``--out`` with ``--reuse``) and compares, report by report, the
mode the tracker followed (``modes`` in ``<id>.npz``: straight / left_turn /
right_turn, the radius ignored) with the label of
:func:`hybridtrack.apps.mode_labels.label_track` (default parameters) on the same
track.  Reports labelled ``stop`` are left out (the ship configurations have
no stop mode), as are objects without course/speed.  Printed and returned:

* ``accuracy`` — the fraction of the compared reports with the label's mode;
* ``balanced_accuracy`` — the mean over straight / left / right of the
  fraction of that label's reports given that mode (a tracker that never
  turns scores 1/3, however many straight reports there are);
* per label: reports and recall; per tracker mode: reports and precision;
* ``turn_reports_labelled`` / ``turn_reports_decided``.

``--moving-only`` tracks only the objects with at least ``--min-moving``
non-stop labelled reports (the berthed vessels change nothing in the scores
but cost time).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from hybridtrack.apps.mode_labels import label_track
from hybridtrack.apps.tracking import load_config, output_name, track_file
from hybridtrack.io.track_files import read_tracks

CLASSES = ("straight", "left_turn", "right_turn")


def labelled_tracks(path, config) -> dict:
    """id → (Track, per-report label) for the objects of ``path`` read with ``config``'s reader settings."""
    cfg = load_config(config)
    data = read_tracks(path, **cfg["reader"], warn=False)
    out = {}
    for key, track in data.tracks.items():
        if len(track) < cfg["min_reports"] or track.course is None or track.speed is None:
            continue
        out[key] = (track, np.array(label_track(track).modes))
    return out


def scores(pairs: list[tuple[np.ndarray, np.ndarray]]) -> dict:
    """Accuracy figures over (label, decided) arrays of reports; stop labels are dropped."""
    labels = np.concatenate([p[0] for p in pairs]) if pairs else np.array([], dtype=str)
    decided = np.concatenate([p[1] for p in pairs]) if pairs else np.array([], dtype=str)
    keep = labels != "stop"
    labels, decided = labels[keep], decided[keep]
    recall = {c: (float(np.mean(decided[labels == c] == c)) if np.any(labels == c) else None) for c in CLASSES}
    precision = {c: (float(np.mean(labels[decided == c] == c)) if np.any(decided == c) else None) for c in CLASSES}
    present = [v for v in recall.values() if v is not None]
    return {
        "reports": int(labels.size),
        "accuracy": float(np.mean(labels == decided)) if labels.size else None,
        "balanced_accuracy": float(np.mean(present)) if present else None,
        "recall": recall,
        "precision": precision,
        "labelled": {c: int(np.sum(labels == c)) for c in CLASSES},
        "decided": {c: int(np.sum(decided == c)) for c in CLASSES},
    }


def evaluate(
    path, config, out, *, reuse: bool = False, moving_only: bool = False, min_moving: int = 50, ids=None, smooth=False, lag=None
) -> dict:
    labelled = labelled_tracks(path, config)
    ids = list(labelled) if ids is None else [k for k in ids if k in labelled]
    if moving_only:
        ids = [k for k in ids if np.sum(labelled[k][1] != "stop") >= min_moving]
    if not reuse:
        track_file(path, config, out, ids, smooth=smooth, lag=lag)
    summary = json.loads((Path(out) / "summary.json").read_text())
    pairs = []
    for entry in summary["objects"]:
        if entry["id"] not in labelled or entry["id"] not in ids:
            continue
        decided = np.load(Path(out) / f"{output_name(entry['id'])}.npz")["modes"]
        pairs.append((labelled[entry["id"]][1], decided))
    result = scores(pairs)
    result["objects"] = len(pairs)
    return result


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file")
    parser.add_argument("--config", required=True)
    parser.add_argument("--out", default="runs/track_mode_accuracy")
    parser.add_argument("--reuse", action="store_true", help="score the results already in --out")
    parser.add_argument("--moving-only", action="store_true")
    parser.add_argument("--min-moving", type=int, default=50)
    parser.add_argument("--json", help="write the scores here")
    parser.add_argument("--id", action="append", dest="ids", help="score only this object (repeatable)")
    parser.add_argument("--smooth", action="store_true", help="score the fixed-interval smoothed run (hybridtrack track --smooth)")
    parser.add_argument("--lag", type=float, help="score the fixed-lag smoothed run (seconds)")
    args = parser.parse_args(argv)
    options = dict(
        reuse=args.reuse, moving_only=args.moving_only, min_moving=args.min_moving, ids=args.ids, smooth=args.smooth, lag=args.lag
    )
    result = evaluate(args.file, args.config, args.out, **options)
    result["command"] = "python experiments/track_mode_accuracy.py " + " ".join(sys.argv[1:] if argv is None else argv)
    text = json.dumps(result, indent=2)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")
    return result


if __name__ == "__main__":
    main()
