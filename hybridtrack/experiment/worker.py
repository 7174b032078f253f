"""What runs on a worker: a chunk of runs of one experiment, each with its own seed.

Run ``i`` of a campaign seeded ``seed`` uses ``numpy.random.default_rng(
SeedSequence(seed, spawn_key=(i,)))`` — exactly the ``i``-th child of
``SeedSequence(seed).spawn(n)`` for any n > i, computed without spawning the
others.  So a run's numbers depend only on (experiment, parameters, seed, i):
not on the executor, the chunking, the number of runs or the resume order.

A chunk stops at the first failing run and returns the runs finished before it
together with the failure, so the campaign can store them before reporting it.
"""

from __future__ import annotations

import traceback
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.experiment.definition import Experiment, resolve_locator


def run_seed(seed: int, index: int) -> np.random.SeedSequence:
    """The seed sequence of run ``index``: child ``index`` of ``SeedSequence(seed)``."""
    return np.random.SeedSequence(seed, spawn_key=(int(index),))


@attrs.frozen(eq=False)
class ChunkOutcome:
    """Runs ``indices`` finished with ``results`` (name → (len(indices), …)); ``failure`` = (index, report) or None."""

    indices: tuple[int, ...]
    results: dict[str, np.ndarray]
    failure: tuple[int, str] | None = None


def _as_row(experiment: str, index: int, name: Any, value: Any) -> np.ndarray:
    if not isinstance(name, str) or not name or name == "index":
        raise TypeError(f"experiment {experiment!r}, run {index}: result names must be non-empty strings other than 'index', got {name!r}")
    array = np.asarray(value)
    if array.dtype.kind not in "biuf":
        raise TypeError(
            f"experiment {experiment!r}, run {index}: result {name!r} is {type(value).__name__} "
            f"(dtype {array.dtype}), expected a number or a numeric array"
        )
    return array


def _stack(experiment: str, indices: Sequence[int], rows: list[Mapping[str, Any]]) -> dict[str, np.ndarray]:
    if not rows:
        return {}
    names = sorted(rows[0])
    for index, row in zip(indices, rows):
        if sorted(row) != names:
            raise ValueError(
                f"experiment {experiment!r}, run {index}: results {sorted(row)} differ from {names} returned by run {indices[0]}"
            )
    stacked = {}
    for name in names:
        values = [row[name] for row in rows]
        shapes = {np.shape(v) for v in values}
        if len(shapes) != 1:
            raise ValueError(f"experiment {experiment!r}: result {name!r} changes shape between runs {list(indices)}: {sorted(shapes)}")
        stacked[name] = np.stack(values)
    return stacked


def _experiment(source: str | Experiment) -> Experiment:
    return resolve_locator(source) if isinstance(source, str) else source


def run_chunk(source: str | Experiment, parameters: Mapping[str, Any], seed: int, indices: Sequence[int]) -> ChunkOutcome:
    """Run ``indices`` of the experiment (a locator or the object itself) with ``parameters``."""
    experiment = _experiment(source)
    done: list[int] = []
    rows: list[dict[str, np.ndarray]] = []
    failure = None
    for index in indices:
        rng = np.random.default_rng(run_seed(seed, index))
        try:
            result = experiment.run_one(int(index), rng, **parameters)
            if not isinstance(result, Mapping):
                raise TypeError(
                    f"experiment {experiment.name!r}, run {index}: run_one returned "
                    f"{type(result).__name__}, expected a mapping name → number or array"
                )
            row = {name: _as_row(experiment.name, index, name, value) for name, value in result.items()}
        except Exception as error:  # reported with the finished runs, re-raised by the campaign
            failure = (int(index), f"{type(error).__name__}: {error}\n{traceback.format_exc()}")
            break
        done.append(int(index))
        rows.append(row)
    try:
        stacked = _stack(experiment.name, done, rows)
    except ValueError as error:
        return ChunkOutcome((), {}, (done[0], f"ValueError: {error}"))
    return ChunkOutcome(tuple(done), stacked, failure)
