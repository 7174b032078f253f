"""Recordings of a campaign: chosen runs replayed with a recorder, and a summary of every run.

A campaign stores numbers only.  :func:`record_runs` replays chosen runs
(:func:`choose_runs`) with the generators they had in the campaign, one
``RerunRecorder`` file each, so a recording shows exactly a stored run;
:func:`write_summary_recording` writes every result as a series over the run
index with its running mean and 95 % band, :func:`read_summary_recording` reads the results back.  ``hybridtrack run
EXPERIMENT --record K`` (``--record-runs I,J,…``) and ``--summary-recording``
use them (docs/experiments.md, "Recordings of a campaign").
"""

from __future__ import annotations

import inspect
import json
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hybridtrack.apps.experiment.definition import Experiment, load_experiment
from hybridtrack.apps.experiment.worker import run_seed
from hybridtrack.core.validation import check_positive_int

#: the timeline of a summary recording: the run index
RUN_TIMELINE = "run"


def accepts_recorder(experiment: Experiment) -> bool:
    """Whether ``experiment.run_one`` takes a ``recorder`` keyword argument (so its runs can be recorded)."""
    try:
        parameters = inspect.signature(experiment.run_one).parameters
    except (TypeError, ValueError):  # pragma: no cover - builtins without a signature
        return False
    recorder = parameters.get("recorder")
    return recorder is not None and recorder.kind in (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)


def choose_runs(n: int, k: int) -> list[int]:
    """``k`` run indices spread evenly over ``0 … n−1``: ``round(linspace(0, n−1, k))`` (all ``n`` when k ≥ n)."""
    check_positive_int(n, "n")
    check_positive_int(k, "record")
    if k >= n:
        return list(range(n))
    return sorted({int(i) for i in np.round(np.linspace(0, n - 1, k)).astype(int)})


def check_run_indices(indices: Iterable[int], n: int) -> list[int]:
    """``indices`` sorted without repeats; a ValueError naming ``record_runs`` for one outside ``0 … n−1``."""
    chosen = []
    for index in indices:
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < n:
            raise ValueError(f"record_runs: run index {index!r} is not in 0 … {n - 1} (the campaign has {n} runs)")
        chosen.append(int(index))
    return sorted(set(chosen))


def run_recording_path(folder: str | Path, index: int) -> Path:
    """Where :func:`record_runs` writes run ``index``: ``FOLDER/run_00017.rrd``."""
    return Path(folder) / f"run_{int(index):05d}.rrd"


def record_runs(
    experiment: Experiment | str,
    indices: Iterable[int],
    folder: str | Path,
    *,
    seed: int,
    parameters: Mapping[str, Any],
) -> dict[int, tuple[Path, dict[str, np.ndarray]]]:
    """Replay runs ``indices`` of a campaign (``seed``, ``parameters``) with a recorder each.

    Returns index → (recording path, the run's results as arrays).  Each file's
    configuration (and so its recording id) is the experiment's name, the
    campaign seed, the run index and the parameters.
    """
    from hybridtrack.recording import RerunRecorder

    experiment = load_experiment(experiment)
    if not accepts_recorder(experiment):
        raise TypeError(f"experiment {experiment.name!r} cannot record its runs: its run_one takes no 'recorder' keyword argument")
    written = {}
    for index in indices:
        path = run_recording_path(folder, index)
        configuration = {"experiment": experiment.name, "campaign_seed": int(seed), "run": int(index), "parameters": dict(parameters)}
        rng = np.random.default_rng(run_seed(seed, int(index)))
        with RerunRecorder(path, configuration) as recorder:
            results = experiment.run_one(int(index), rng, recorder=recorder, **parameters)
            recorder.log_event(0, f"{experiment.name}: run {index} of the campaign seeded {seed}")
        written[int(index)] = (path, {name: np.asarray(value) for name, value in results.items()})
    return written


#: the first run at which a summary recording draws the 95 % band (below it s/√n of a handful of runs says little)
BAND_FROM_RUNS = 5

#: the unit of a result, by its name (the first pattern that matches; the library's SI units: positions in metres,
#: times in seconds): a position RMSE or error in m, a squared error in the state's units squared, NIS without
#: unit, steps in steps; any other name has no declared unit (``write_summary_recording(..., units=)`` gives one)
RESULT_UNITS = (
    (re.compile(r"(^|_)rmse(_|$)|(^|_)position_error(_|$)"), "m"),
    (re.compile(r"squared_error"), "state units²"),
    (re.compile(r"(^|_)nis(_|$)"), "no unit"),
    (re.compile(r"(^|_)(steps|delay)(_|$)"), "steps"),
    (re.compile(r"(^|_)(seconds|time|duration)(_|$)"), "s"),
)


def result_unit(name: str, units: Mapping[str, str] | None = None) -> str:
    """The unit of result ``name`` in a summary recording: ``units[name]`` if given, else :data:`RESULT_UNITS`, else
    ``"unit not declared"``."""
    if units and name in units:
        return str(units[name])
    return next((unit for pattern, unit in RESULT_UNITS if pattern.search(name)), "unit not declared")


def running_statistics(values: np.ndarray, start: int = BAND_FROM_RUNS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The running mean over runs 0 … i of ``values`` (n,) or (n, c) (NaN runs left out) and the 95 % band of that
    mean, mean ∓ 1.96 s/√m (s the sample standard deviation of the m finite runs so far; NaN until m ≥ ``start``).

    The sums are taken about the overall mean, so a constant result has s = 0 exactly rather than rounding noise.
    """
    x = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(x)
    centre = np.nanmean(np.where(finite, x, np.nan), axis=0) if finite.any() else np.zeros(x.shape[1:])
    d = np.where(finite, x - np.where(np.isfinite(centre), centre, 0.0), 0.0)
    m = np.cumsum(finite, axis=0).astype(np.float64)
    s1, s2 = np.cumsum(d, axis=0), np.cumsum(d * d, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(m > 0, s1 / m, np.nan)
        variance = np.clip((s2 - s1 * s1 / m) / (m - 1), 0.0, None)
        half = np.where(m >= max(start, 2), 1.96 * np.sqrt(variance / m), np.nan)
    mean = mean + np.where(np.isfinite(centre), centre, 0.0)
    return mean, mean - half, mean + half


def write_summary_recording(
    arrays: Mapping[str, np.ndarray], path: str | Path, configuration: Mapping[str, Any], *, units: Mapping[str, str] | None = None
) -> list[str]:
    """Every result of ``arrays`` (name → (n, …) by run, plus ``index``) as series over the run index, into ``path``.

    Each result ``campaign/<name>`` (c series ``<name>[i]`` for a result of shape (c,)) gets beside it, under
    ``statistics/<name>``, its running mean over the runs so far and the 95 % band of that mean, mean ± 1.96 s/√n
    (:func:`running_statistics`, from run :data:`BAND_FROM_RUNS`), in one panel per result whose title and series
    names give the unit (:func:`result_unit`; ``units`` result name → unit overrides it).  Returns the names left
    out (rank > 1 per run).  ``configuration`` is stored as the recording property ``configuration`` and gives
    the recording id.
    """
    import rerun as rr
    import rerun.blueprint as rrb

    from hybridtrack.recording import APPLICATION_ID, palette, recording_id

    if "index" not in arrays:
        raise ValueError("arrays: expected the campaign's arrays with their 'index' (CampaignResult.arrays)")
    index = np.asarray(arrays["index"], dtype=np.int64)
    order = np.argsort(index, kind="stable")  # the running statistics go over the runs in index order
    results, skipped = {}, []
    for name, values in arrays.items():
        if name == "index":
            continue
        values = np.asarray(values, dtype=np.float64)
        if values.ndim in (1, 2):
            results[name] = values[order]
        else:
            skipped.append(name)
    index = index[order]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    configuration = dict(configuration)
    stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id({"summary": configuration}))
    panels = []
    for name in sorted(results):
        unit = result_unit(name, units)
        title = f"{name} ({unit}): per run, running mean, 95 % band mean ± 1.96 s/√n (n ≥ {BAND_FROM_RUNS} runs)"
        legend = rrb.PlotLegend(corner=rrb.Corner2D.RightBottom, visible=True)
        panels.append(
            rrb.TimeSeriesView(origin="/", contents=[f"+ /campaign/{name}", f"+ /statistics/{name}"], name=title, plot_legend=legend)
        )
    blueprint = rrb.Blueprint(rrb.Grid(*panels), rrb.TimePanel(timeline=RUN_TIMELINE, state="collapsed"), collapse_panels=True)
    stream.save(str(path), default_blueprint=blueprint)
    try:
        stream.send_property("configuration", rr.AnyValues(json=json.dumps(configuration, sort_keys=True, default=str)))
        runs = [rr.TimeColumn(RUN_TIMELINE, sequence=index)]
        for name, values in sorted(results.items()):
            unit, colour = result_unit(name, units), palette(name)
            columns = [""] if values.ndim == 1 else [f"[{i}]" for i in range(values.shape[1])]
            light = tuple(round(c + (255 - c) * 0.55) for c in colour)
            stream.send_columns(f"campaign/{name}", indexes=runs, columns=rr.Scalars.columns(scalars=values))
            stream.log(
                f"campaign/{name}",
                rr.SeriesLines(
                    names=[f"{name}{c} per run ({unit})" for c in columns], colors=[light] * len(columns), widths=[1.0] * len(columns)
                ),
                static=True,
            )
            mean, lower, upper = running_statistics(values)
            stacked = np.column_stack([mean, lower, upper])  # (n, 3c): the means, the lower bounds, the upper bounds
            labels = [f"running mean{c} ({unit})" for c in columns]
            labels += [f"mean{c} − 1.96 s/√n ({unit})" for c in columns] + [f"mean{c} + 1.96 s/√n ({unit})" for c in columns]
            widths = [3.0] * len(columns) + [1.5] * 2 * len(columns)
            colours = [colour] * len(columns) + [palette("threshold")] * 2 * len(columns)
            stream.send_columns(f"statistics/{name}", indexes=runs, columns=rr.Scalars.columns(scalars=stacked))
            stream.log(f"statistics/{name}", rr.SeriesLines(names=labels, colors=colours, widths=widths), static=True)
    finally:
        stream.flush()
        stream.disconnect()
    return skipped


def read_summary_recording(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The series of a summary recording: result name → (run indices (n,), values (n,) or (n, c)), sorted by run."""
    import rerun as rr

    series: dict[str, list[tuple[int, Any]]] = {}
    for chunk in rr.chunk.RrdReader(str(path)).stream():
        entity = chunk.entity_path
        if not entity.startswith("/campaign/"):
            continue
        batch = chunk.to_record_batch()
        if RUN_TIMELINE not in batch.schema.names or "Scalars:scalars" not in batch.schema.names:
            continue
        name = entity.removeprefix("/campaign/")
        for run, value in zip(batch.column(RUN_TIMELINE).to_pylist(), batch.column("Scalars:scalars").to_pylist()):
            if run is not None and value is not None:
                series.setdefault(name, []).append((int(run), value))
    table = {}
    for name, pairs in series.items():
        pairs.sort(key=lambda pair: pair[0])  # stable: a run logged twice keeps its order
        array = np.array([value for _, value in pairs], dtype=np.float64)
        table[name] = (np.array([run for run, _ in pairs], dtype=np.int64), array[:, 0] if array.shape[1] == 1 else array)
    return table
