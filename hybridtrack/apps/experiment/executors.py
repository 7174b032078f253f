"""Where chunks of runs execute: ``inline`` (this process), ``process`` (default; a pool of spawned
processes) or ``dask`` (a running Dask scheduler).

Each executor is a context manager with ``map_unordered(function, tasks)``
yielding ``function(*task)`` for every task as soon as it finishes, in any
order, and ``cancel_pending()`` to start no further task (those already running
still finish and are yielded).  When a task raises, the executor cancels what
has not started, still yields the results of tasks already running, and then
raises the error.  Leaving a process pool's ``with`` block on an exception
(Ctrl-C included) terminates its workers instead of waiting for them.
"""

from __future__ import annotations

import contextlib
import ipaddress
import multiprocessing
import os
import re
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import InvalidStateError, ProcessPoolExecutor, as_completed
from typing import Any

from hybridtrack.apps.experiment.worker import worker_init

EXECUTORS = ("inline", "process", "dask")
#: address schemes ``distributed`` connects with
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")
#: seconds the dask executor waits for the scheduler to answer
CONNECT_TIMEOUT = 10.0
_HOSTNAME = re.compile(r"^(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*$")
_EXPECTED_ADDRESS = "expected SCHEME://HOST:PORT such as tcp://10.0.0.5:8786 (schemes: " + ", ".join(SCHEDULER_SCHEMES) + ")"


def _is_client(value: Any) -> bool:
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - depends on the install
        return False
    return isinstance(value, Client)


def check_scheduler_address(scheduler: Any) -> Any:
    """``scheduler`` if it is a ``distributed.Client`` or a well-formed address; else a clear error.

    An address is ``SCHEME://HOST:PORT`` or ``HOST:PORT`` (scheme ``tcp``):
    HOST a host name, an IPv4 address or ``[IPv6]``, PORT in 1–65535.
    ``inproc://…`` addresses are passed on unchecked.  A malformed address
    would otherwise make ``distributed`` retry until its connect timeout.
    """
    if scheduler is None or (isinstance(scheduler, str) and not scheduler.strip()):
        raise ValueError("the dask executor needs a scheduler address (--scheduler tcp://HOST:PORT)")
    if not isinstance(scheduler, str):
        if _is_client(scheduler):
            return scheduler
        raise TypeError(f"scheduler: expected an address string or a distributed.Client, got {type(scheduler).__name__}")

    def bad(problem: str) -> ValueError:
        return ValueError(f"scheduler address {scheduler!r}: {problem}; {_EXPECTED_ADDRESS}")

    if scheduler != scheduler.strip() or any(character.isspace() for character in scheduler):
        raise bad("contains white space")
    scheme, separator, rest = scheduler.partition("://")
    if not separator:
        scheme, rest = "tcp", scheduler
    if scheme not in SCHEDULER_SCHEMES:
        raise bad(f"unknown scheme {scheme!r}")
    if scheme == "inproc":
        return scheduler
    if "/" in rest:
        raise bad("has a path after the port")
    if rest.startswith("["):
        host, bracket, port = rest[1:].partition("]")
        if not bracket or not port.startswith(":"):
            raise bad("an IPv6 host needs [ADDRESS]:PORT")
        port, version = port[1:], ipaddress.IPv6Address
    else:
        host, colon, port = rest.rpartition(":")
        if not colon:
            raise bad("has no port")
        if not host:
            raise bad("has no host")
        if ":" in host:
            raise bad("has more than one ':' (write an IPv6 host as [ADDRESS])")
        version = ipaddress.IPv4Address if re.fullmatch(r"[0-9.]+", host) else None
        if version is None and not _HOSTNAME.match(host):
            raise bad(f"{host!r} is not a host name")
    if version is not None:
        try:
            version(host)
        except ValueError:
            raise bad(f"{host!r} is not an {version.__name__.removesuffix('Address')} address") from None
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise bad(f"port {port!r} is not an integer in 1-65535")
    return scheduler


def _results(finished: Iterable, cancel_pending: Callable[[], None]) -> Iterator[Any]:
    """The results of the futures ``finished`` as they come, a failure handled as the module docstring says."""
    error: BaseException | None = None
    for future in finished:
        if future.cancelled():
            continue
        failure = future.exception()
        if failure is None:
            yield future.result()
        elif error is None:
            error = failure
            cancel_pending()
    if error is not None:
        raise error


class InlineExecutor(contextlib.AbstractContextManager):
    """Runs every task in this process, in order."""

    workers = 1

    def __init__(self):
        self._stopped = False

    def cancel_pending(self) -> None:
        self._stopped = True

    def __exit__(self, *exc_info):
        return False

    def map_unordered(self, function: Callable, tasks: Sequence[tuple]) -> Iterator[Any]:
        for task in tasks:
            if self._stopped:
                return
            yield function(*task)


class ProcessExecutor(contextlib.AbstractContextManager):
    """A pool of ``workers`` spawned processes (default: the CPU count)."""

    def __init__(self, workers: int | None = None):
        self.workers = workers or os.cpu_count() or 1
        self._pool: ProcessPoolExecutor | None = None
        self._pending: set = set()
        self._processes: list = []

    def cancel_pending(self) -> None:
        for future in self._pending:
            future.cancel()

    def terminate(self) -> None:
        """End the workers at once (SIGTERM, then SIGKILL after a second); the pool fails the tasks left.

        Futures are not cancelled first: on Python 3.11 the pool's manager
        thread raises ``InvalidStateError`` when it fails a cancelled future
        of a broken pool (fixed in 3.12), so that error is silenced here.
        """
        previous_hook = threading.excepthook

        def quiet_hook(arguments):
            if not issubclass(arguments.exc_type, InvalidStateError):
                previous_hook(arguments)

        threading.excepthook = quiet_hook
        try:
            for process in self._processes:
                process.terminate()  # a no-op for a process that has ended
            for process in self._processes:
                process.join(1.0)
                if process.is_alive():
                    process.kill()
                    process.join(1.0)
            if self._pool is not None:
                self._pool.shutdown(wait=True, cancel_futures=False)
        finally:
            threading.excepthook = previous_hook

    def __exit__(self, exc_type, *exc_info):
        if self._pool is not None:
            if exc_type is not None:  # nobody will read the results of the tasks still running
                self.terminate()
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
            self._processes = []

    def map_unordered(self, function: Callable, tasks: Sequence[tuple]) -> Iterator[Any]:
        if not tasks:
            return
        before = set(multiprocessing.active_children())
        self._pool = ProcessPoolExecutor(
            max_workers=min(self.workers, len(tasks)),
            mp_context=multiprocessing.get_context("spawn"),
            initializer=worker_init,
            initargs=(os.getpid(),),
        )
        self._pending = {self._pool.submit(function, *task) for task in tasks}
        # the pool starts its workers while tasks are submitted; remember them to end them on an interrupt
        self._processes = [process for process in multiprocessing.active_children() if process not in before]
        yield from _results(as_completed(self._pending), self.cancel_pending)


class DaskExecutor(contextlib.AbstractContextManager):
    """Tasks on a Dask distributed cluster reached at ``scheduler`` (an address or a ``distributed.Client``)."""

    def __init__(self, scheduler, timeout: float = CONNECT_TIMEOUT):
        self.scheduler = check_scheduler_address(scheduler)
        self.timeout = float(timeout)
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
            try:
                self._client = Client(self.scheduler, set_as_default=False, timeout=self.timeout)
            except (OSError, TimeoutError) as error:
                raise ConnectionError(
                    f"scheduler {self.scheduler!r}: no Dask scheduler answered within {self.timeout:g} s ({error})"
                ) from error
            self._owns_client = True
        return self

    def cancel_pending(self) -> None:
        # distributed cannot tell queued from running tasks here; cancelling the not-done ones loses at
        # most the running ones, which a resumed campaign recomputes
        for future in self._futures:
            if not future.done():
                future.cancel()

    def __exit__(self, exc_type, *exc_info):
        if exc_type is not None and self._client is not None:
            self.cancel_pending()
        if self._owns_client and self._client is not None:
            self._client.close()
        self._client = None

    def map_unordered(self, function: Callable, tasks: Sequence[tuple]) -> Iterator[Any]:
        from distributed import as_completed

        if not tasks:
            return
        self._futures = [self._client.submit(function, *task, pure=False) for task in tasks]
        yield from _results(as_completed(self._futures, loop=self._client.loop), self.cancel_pending)


def make_executor(name: str, *, workers: int | None = None, scheduler=None, timeout: float = CONNECT_TIMEOUT):
    """The executor called ``name`` (one of :data:`EXECUTORS`); ``timeout``: seconds to reach a Dask scheduler."""
    factories = {"inline": InlineExecutor, "process": lambda: ProcessExecutor(workers), "dask": lambda: DaskExecutor(scheduler, timeout)}
    if name not in factories:
        raise ValueError(f"unknown executor {name!r}; choose one of {', '.join(EXECUTORS)}")
    return factories[name]()
