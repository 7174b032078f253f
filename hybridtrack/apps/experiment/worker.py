"""What runs on a worker: a chunk of runs of one experiment, run ``i`` seeded by :func:`run_seed` (docs/experiments.md,
"Seeds").  A chunk stops at the first failing run (or Ctrl-C) and returns the runs finished before it with the
failure (or ``interrupted``), so the campaign stores them first; a chunk of an experiment with ``run_batch`` is one
batch, run again with ``run_one`` when it raises ("Batched experiments").  Pool workers start with :func:`worker_init`.
"""

from __future__ import annotations

import os
import signal
import threading
import time
import traceback
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.apps.experiment.definition import Experiment, resolve_locator

#: seconds between two checks of a worker that its parent process is still alive
PARENT_POLL = 0.2
#: exit status of a worker ended because its parent process died
ORPHAN_EXIT = 70


def run_seed(seed: int, index: int) -> np.random.SeedSequence:
    """The seed sequence of run ``index``: SeedSequence(seed, spawn_key=(index,)), exactly child ``index`` of
    ``SeedSequence(seed).spawn(n)`` for any n > index, so a run's numbers do not depend on the executor, the
    chunking or the resume order."""
    return np.random.SeedSequence(seed, spawn_key=(int(index),))


def batch_arrays(run_batch, parameters: Mapping[str, Any], n: int, seed: int, chunk: int = 100) -> dict[str, np.ndarray]:
    """Every run's results stacked (name → (n, …)), as a campaign returns them, computed by an experiment's
    ``run_batch(indices, rngs, **parameters)`` (one mapping per run) in chunks of ``chunk`` runs; run i uses
    child i of SeedSequence(``seed``) (:func:`run_seed`), as in the campaign."""
    rows = []
    for first in range(0, n, chunk):
        indices = list(range(first, min(n, first + chunk)))
        rows += run_batch(indices, [np.random.default_rng(run_seed(seed, i)) for i in indices], **parameters)
    return {name: np.stack([np.asarray(row[name]) for row in rows]) for name in rows[0]}


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(PARENT_POLL)
    os._exit(ORPHAN_EXIT)  # the parent is gone: nobody will read our results


def worker_init(parent: int) -> None:
    """Set up a pool worker of the process ``parent``: ignore SIGINT, exit as soon as ``parent`` is gone.

    Called in the worker (``ProcessPoolExecutor(initializer=worker_init,
    initargs=(os.getpid(),))``).  An orphaned process is re-parented (to
    init or a subreaper), so ``os.getppid()`` differing from ``parent``
    means the parent died.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if os.getppid() != parent:
        os._exit(ORPHAN_EXIT)
    threading.Thread(target=_watch_parent, args=(parent,), name="hybridtrack-parent-watch", daemon=True).start()


@attrs.frozen(eq=False)
class ChunkOutcome:
    """Runs ``indices`` finished with ``results`` (name → (len(indices), …)); ``failure`` = (index, report) or None;
    ``interrupted`` when a KeyboardInterrupt stopped the chunk."""

    indices: tuple[int, ...]
    results: dict[str, np.ndarray]
    failure: tuple[int, str] | None = None
    interrupted: bool = False


def _row(experiment: str, index: int, result: Any, source: str) -> dict[str, np.ndarray]:
    """One run's results (what ``source`` returned for run ``index``) as arrays: a mapping name → numbers, checked."""
    where = f"experiment {experiment!r}, run {index}"
    if not isinstance(result, Mapping):
        raise TypeError(f"{where}: {source} returned {type(result).__name__}, expected a mapping name → number or array")
    row = {}
    for name, value in result.items():
        if not isinstance(name, str) or not name or name in ("index", "__campaign__"):
            raise TypeError(f"{where}: result names must be non-empty strings other than 'index' and '__campaign__', got {name!r}")
        row[name] = np.asarray(value)
        if row[name].dtype.kind not in "biuf":
            raise TypeError(
                f"{where}: result {name!r} is {type(value).__name__} (dtype {row[name].dtype}), expected a number or a numeric array"
            )
    return row


def _stack(experiment: str, rows: Mapping[int, Mapping[str, Any]]) -> dict[str, np.ndarray]:
    """Run index → results as name → (runs, …), checked: the same names and shapes in every run."""
    if not rows:
        return {}
    first = next(iter(rows))
    names = sorted(rows[first])
    for index, row in rows.items():
        if sorted(row) != names:
            raise ValueError(f"experiment {experiment!r}, run {index}: results {sorted(row)} differ from {names} returned by run {first}")
    for name in names:
        shapes = {np.shape(row[name]) for row in rows.values()}
        if len(shapes) != 1:
            raise ValueError(f"experiment {experiment!r}: result {name!r} changes shape between runs {list(rows)}: {sorted(shapes)}")
    return {name: np.stack([row[name] for row in rows.values()]) for name in names}


def _batch_rows(experiment: Experiment, indices: Sequence[int], result: Any) -> dict[int, dict[str, np.ndarray]]:
    """``run_batch``'s result (one mapping per run, or name → array stacked over the runs) as run index → row."""
    count, where = len(indices), f"experiment {experiment.name!r}: run_batch"
    if isinstance(result, Mapping):
        for name, value in result.items():
            if np.shape(value)[:1] != (count,):
                raise ValueError(
                    f"{where} result {name!r} has shape {np.shape(value)}, expected ({count}, …) (one row per run of the chunk)"
                )
        result = [{name: value[i] for name, value in result.items()} for i in range(count)]
    elif not isinstance(result, Sequence) or isinstance(result, (str, bytes)):
        raise TypeError(
            f"{where} returned {type(result).__name__}, "
            "expected a list of mappings (one per run) or a mapping name → array stacked over the runs"
        )
    if len(result) != count:
        raise ValueError(f"{where} returned {len(result)} results for {count} runs")
    return {index: _row(experiment.name, index, row, "run_batch") for index, row in zip(indices, result)}


def run_chunk(source: str | Experiment, parameters: Mapping[str, Any], seed: int, indices: Sequence[int]) -> ChunkOutcome:
    """Run ``indices`` of the experiment (a locator or the object itself) with ``parameters``: as one batch when
    the experiment has ``run_batch``, else (or to locate a failure) one run at a time."""
    experiment = resolve_locator(source) if isinstance(source, str) else source
    if experiment.run_batch is None or not indices:
        return _run_each(experiment, parameters, seed, indices)
    indices = [int(i) for i in indices]
    rngs = [np.random.default_rng(run_seed(seed, index)) for index in indices]
    try:
        stacked = _stack(experiment.name, _batch_rows(experiment, indices, experiment.run_batch(indices, rngs, **parameters)))
    except Exception as error:
        report = f"{type(error).__name__} in run_batch of runs {indices[0]}…{indices[-1]}: {error}\n{traceback.format_exc()}"
        outcome = _run_each(experiment, parameters, seed, indices)
        if outcome.failure is None and not outcome.interrupted:
            return attrs.evolve(outcome, failure=(indices[0], report))
        return outcome
    except KeyboardInterrupt:
        return ChunkOutcome((), {}, None, True)
    return ChunkOutcome(tuple(indices), stacked)


def _run_each(experiment: Experiment, parameters: Mapping[str, Any], seed: int, indices: Sequence[int]) -> ChunkOutcome:
    """The chunk one run at a time with ``run_one``, stopping at the first failure or Ctrl-C."""
    rows: dict[int, dict[str, np.ndarray]] = {}
    failure, interrupted = None, False
    for index in indices:
        rng = np.random.default_rng(run_seed(seed, index))
        try:
            row = _row(experiment.name, index, experiment.run_one(int(index), rng, **parameters), "run_one")
        except Exception as error:  # reported with the finished runs, re-raised by the campaign
            failure = (int(index), f"{type(error).__name__}: {error}\n{traceback.format_exc()}")
            break
        except KeyboardInterrupt:  # the runs finished so far are still stored
            interrupted = True
            break
        rows[int(index)] = row
    try:
        stacked = _stack(experiment.name, rows)
    except ValueError as error:
        return ChunkOutcome((), {}, (next(iter(rows)), f"ValueError: {error}"), interrupted)
    return ChunkOutcome(tuple(rows), stacked, failure, interrupted)
