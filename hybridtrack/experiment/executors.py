"""Where chunks of runs execute: in this process, a local process pool, or a Dask cluster.

Each executor is a context manager with ``map_unordered(function, tasks)``
yielding ``function(*task)`` for every task as soon as it finishes, in any
order, and ``cancel_pending()`` to start no further task (those already running
still finish and are yielded).  When a task raises, the executor cancels what
has not started, still yields the results of tasks already running, and then
raises the error.

* ``inline``: one after the other in this process (debugging, tiny campaigns);
* ``process`` (default): ``concurrent.futures.ProcessPoolExecutor`` with the
  ``spawn`` start method (safe with threads and on every platform);
* ``dask``: ``distributed.Client(scheduler)`` on a running scheduler
  (``tcp://host:port``), e.g. ``dask scheduler`` + ``dask worker`` or a
  ``LocalCluster``.  Workers must be able to import ``hybridtrack`` and read
  the experiment script's path.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any

EXECUTORS = ("inline", "process", "dask")


class InlineExecutor:
    """Runs every task in this process, in order."""

    name = "inline"
    workers = 1

    def __init__(self):
        self._stopped = False

    def __enter__(self):
        return self

    def cancel_pending(self) -> None:
        self._stopped = True

    def __exit__(self, *exc_info):
        return False

    def map_unordered(self, function: Callable, tasks: Sequence[tuple]) -> Iterator[Any]:
        for task in tasks:
            if self._stopped:
                return
            yield function(*task)


class ProcessExecutor:
    """A pool of ``workers`` spawned processes (default: the CPU count)."""

    name = "process"

    def __init__(self, workers: int | None = None):
        if workers is not None and (not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers: expected a positive integer, got {workers!r}")
        self.workers = workers or os.cpu_count() or 1
        self._pool: ProcessPoolExecutor | None = None
        self._pending: set = set()

    def __enter__(self):
        return self

    def cancel_pending(self) -> None:
        for future in self._pending:
            future.cancel()

    def __exit__(self, *exc_info):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        return False

    def map_unordered(self, function: Callable, tasks: Sequence[tuple]) -> Iterator[Any]:
        if not tasks:
            return
        self._pool = ProcessPoolExecutor(max_workers=min(self.workers, len(tasks)), mp_context=multiprocessing.get_context("spawn"))
        self._pending = {self._pool.submit(function, *task) for task in tasks}
        error: BaseException | None = None
        while self._pending:
            finished, self._pending = wait(self._pending, return_when=FIRST_COMPLETED)
            for future in finished:
                if future.cancelled():
                    continue
                failure = future.exception()
                if failure is None:
                    yield future.result()
                elif error is None:
                    error = failure
                    self.cancel_pending()
        if error is not None:
            raise error


class DaskExecutor:
    """Tasks on a Dask distributed cluster reached at ``scheduler`` (an address or a ``distributed.Client``)."""

    name = "dask"

    def __init__(self, scheduler):
        if scheduler is None or scheduler == "":
            raise ValueError("the dask executor needs a scheduler address (--scheduler tcp://HOST:PORT)")
        self.scheduler = scheduler
        self._client = None
        self._owns_client = False
        self._futures: list = []

    @property
    def workers(self) -> int:
        return max(1, len(self._client.scheduler_info().get("workers", {}))) if self._client is not None else 1

    def __enter__(self):
        try:
            from distributed import Client
        except ImportError as error:  # pragma: no cover - depends on the install
            raise RuntimeError("the dask executor needs 'distributed': pip install 'hybridtrack[dask]'") from error
        if isinstance(self.scheduler, Client):
            self._client = self.scheduler
        else:
            self._client = Client(self.scheduler, set_as_default=False)
            self._owns_client = True
        return self

    def cancel_pending(self) -> None:
        # distributed cannot tell queued from running tasks here; cancelling the not-done ones loses at
        # most the running ones, which a resumed campaign recomputes
        for future in self._futures:
            if not future.done():
                future.cancel()

    def __exit__(self, *exc_info):
        if self._owns_client and self._client is not None:
            self._client.close()
        self._client = None
        return False

    def map_unordered(self, function: Callable, tasks: Sequence[tuple]) -> Iterator[Any]:
        from distributed import as_completed

        if not tasks:
            return
        self._futures = [self._client.submit(function, *task, pure=False) for task in tasks]
        error: BaseException | None = None
        for future in as_completed(self._futures, loop=self._client.loop):
            if future.cancelled():
                continue
            if future.status == "error":
                if error is None:
                    error = future.exception()
                    self.cancel_pending()
                continue
            yield future.result()
        if error is not None:
            raise error


def make_executor(name: str, *, workers: int | None = None, scheduler=None):
    """The executor called ``name`` (one of :data:`EXECUTORS`)."""
    if name == "inline":
        return InlineExecutor()
    if name == "process":
        return ProcessExecutor(workers)
    if name == "dask":
        return DaskExecutor(scheduler)
    raise ValueError(f"unknown executor {name!r}; choose one of {', '.join(EXECUTORS)}")
