"""The Monte Carlo campaign: n seeded runs of an experiment, stored as they finish, resumable.

    campaign = Campaign("demo_rmse", n=200, out="runs/demo", seed=0)
    result = campaign.run()              # computes only the runs missing from runs/demo
    result.arrays["rmse"]                # (200,) ordered by run index

Run ``i`` always gets child ``i`` of ``SeedSequence(seed)`` (:func:`~hybridtrack.apps.experiment.worker.run_seed`);
each finished chunk is stored at once (:mod:`~hybridtrack.apps.experiment.store`); a failing run stops the
campaign with :class:`RunFailed`, Ctrl-C with :class:`CampaignInterrupted`, both after the finished runs are
stored; running it again resumes (docs/experiments.md).
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from hybridtrack.apps.experiment.definition import Experiment, load_experiment
from hybridtrack.apps.experiment.executors import CONNECT_TIMEOUT, EXECUTORS, check_scheduler_address, make_executor
from hybridtrack.apps.experiment.store import ResultStore, _is_integer
from hybridtrack.apps.experiment.worker import run_chunk


class RunFailed(RuntimeError):
    """A run raised; the runs finished before it are stored."""


class CampaignInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped the campaign; ``stored`` runs (``computed`` of them by this call) are in ``out``."""

    def __init__(self, out: Path, n: int, stored: int, computed: int):
        super().__init__(
            f"interrupted: {stored} of {n} runs stored in {out} ({computed} computed by this call); run the same campaign again to resume"
        )
        self.out, self.n, self.stored, self.computed = out, n, stored, computed


def _valid(test, expected: str, error: type[Exception] = ValueError):
    """An attrs validator: ``test(value)`` or ``error`` naming the field and saying ``expected``."""

    def check(instance, attribute, value):
        if not test(value):
            raise error(f"{attribute.name}: expected {expected}, got {value!r}")

    return check


_positive_int = _valid(lambda value: _is_integer(value, 1), "a positive integer")


def _executor(instance, attribute, value):
    if value not in EXECUTORS:
        raise ValueError(f"unknown executor {value!r}; choose one of {', '.join(EXECUTORS)}")


def chunks(indices: np.ndarray, size: int) -> list[tuple[int, ...]]:
    """``indices`` (sorted) cut into consecutive pieces of at most ``size``."""
    return [tuple(int(i) for i in indices[start : start + size]) for start in range(0, len(indices), size)]


@attrs.frozen(eq=False)
class CampaignResult:
    """All stored runs of a campaign (``arrays``: name → (n, …) by run index, plus ``index``) and
    how many runs this call computed versus found already stored."""

    experiment: str
    out: Path
    n: int
    arrays: dict[str, np.ndarray]
    computed: int
    reused: int
    #: (original path, path in OUT/set_aside/, reason) of every file this call set aside
    set_aside: tuple[tuple[Path, Path, str], ...] = ()

    def summary(self) -> dict[str, dict[str, Any]]:
        """Per result name: mean and standard deviation over runs (for scalars) or the per-run shape."""
        table = {}
        for name, values in self.arrays.items():
            if name == "index":
                continue
            if values.ndim == 1:
                table[name] = {"mean": float(np.mean(values)), "std": float(np.std(values, ddof=1)) if len(values) > 1 else 0.0}
            else:
                table[name] = {"shape": list(values.shape[1:]), "mean": np.mean(values, axis=0).tolist()}
        return table


def _progress(total: int, done: int, description: str, enabled: bool):
    from tqdm.auto import tqdm

    stream = sys.stderr
    show = enabled and hasattr(stream, "isatty") and stream.isatty()
    return tqdm(total=total, initial=done, desc=description, unit="run", disable=not show, file=stream, dynamic_ncols=True)


@attrs.frozen(eq=False)
class Campaign:
    """``n`` runs of ``experiment`` (an :class:`Experiment`, a registered name or a script path) into ``out``.

    The options are those of ``hybridtrack run`` (docs/experiments.md): ``parameters`` override the
    experiment's defaults; ``executor`` ``dask`` needs ``scheduler`` (an address or a
    ``distributed.Client``); ``chunk_size`` runs per stored file (default: about four chunks per worker,
    at most 25 runs; for an experiment with ``run_batch`` one batch per worker of at most its
    ``batch_size``); ``progress`` shows a tqdm bar when stderr is a terminal.
    """

    experiment: Experiment = attrs.field(converter=load_experiment)
    n: int = attrs.field(validator=_positive_int)
    out: Path = attrs.field(converter=Path)
    seed: int = attrs.field(default=0, validator=_valid(lambda value: _is_integer(value, 0), "a non-negative integer"))
    parameters: dict[str, Any] = attrs.field(factory=dict, converter=dict)
    executor: str = attrs.field(default="process", validator=_executor)
    scheduler: Any = None
    workers: int | None = attrs.field(default=None, validator=attrs.validators.optional(_positive_int))
    chunk_size: int | None = attrs.field(default=None, validator=attrs.validators.optional(_positive_int))
    progress: bool = True
    set_aside: bool = attrs.field(
        default=False, validator=_valid(lambda value: isinstance(value, (bool, np.bool_)), "True or False", TypeError)
    )
    connect_timeout: float = attrs.field(
        default=CONNECT_TIMEOUT,
        validator=_valid(
            lambda value: not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating)) and 0 < value < math.inf,
            "a positive number of seconds",
        ),
    )

    def __attrs_post_init__(self):
        object.__setattr__(self, "parameters", self.experiment.with_parameters(**self.parameters))
        if self.executor == "dask":
            check_scheduler_address(self.scheduler)

    def _chunk_size(self, missing: int, workers: int) -> int:
        if self.chunk_size is not None:
            return self.chunk_size
        if self.experiment.run_batch is not None:  # a chunk is one batch: as large as the experiment's batch_size
            return max(1, min(self.experiment.batch_size, math.ceil(missing / workers)))
        return max(1, min(25, math.ceil(missing / (4 * workers))))

    def run(self) -> CampaignResult:
        """Compute the missing runs (storing each chunk as it finishes) and return every run's results."""
        store = ResultStore(self.out)
        with store.locked():
            done = store.open(
                experiment=self.experiment.name,
                locator=self.experiment.locator,
                parameters=self.parameters,
                seed=self.seed,
                n=self.n,
                set_aside=self.set_aside,
            )
            missing = np.setdiff1d(np.arange(self.n), done)
            reused, computed = self.n - len(missing), 0
            failures: list[tuple[int, str]] = []
            executor = make_executor(self.executor, workers=self.workers, scheduler=self.scheduler, timeout=self.connect_timeout)
            try:
                if len(missing):
                    with executor, _progress(self.n, reused, self.experiment.name, self.progress) as bar:
                        source = self.experiment.locator or self.experiment
                        size = self._chunk_size(len(missing), executor.workers)
                        tasks = [(source, self.parameters, int(self.seed), chunk) for chunk in chunks(missing, size)]
                        for outcome in executor.map_unordered(run_chunk, tasks):
                            if outcome.indices:
                                store.write_chunk(outcome.indices, outcome.results)
                                computed += len(outcome.indices)
                                bar.update(len(outcome.indices))
                            if outcome.interrupted:
                                raise KeyboardInterrupt
                            if outcome.failure is not None:
                                failures.append(outcome.failure)
                                executor.cancel_pending()
            except KeyboardInterrupt:
                raise CampaignInterrupted(self.out, self.n, reused + computed, computed) from None
            if failures:
                index, report = min(failures)
                raise RunFailed(
                    f"experiment {self.experiment.name!r}: run {index} failed "
                    f"({computed} run(s) computed and stored in {self.out}; run again to resume)\n{report}"
                )
            arrays = store.load(self.n)
        return CampaignResult(self.experiment.name, self.out, self.n, arrays, computed, reused, tuple(store.set_aside_files))


def run_campaign(experiment: Experiment | str, n: int, out: str | os.PathLike, **options: Any) -> CampaignResult:
    """Shorthand for ``Campaign(experiment, n, out, **options).run()``."""
    return Campaign(experiment, n, out, **options).run()
