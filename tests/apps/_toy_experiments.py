"""Small experiments for the runner tests, loaded by path (``…/_toy_experiments.py:NAME``) like a user's script.

``draws`` returns numbers taken from the run's generator, so equal arrays mean
equal seeds.  ``flaky`` does the same and appends each call's index to
``log``; the first time it reaches ``fail_at`` it fails (``how="raise"``),
kills its own process (``how="kill"``) or acts as a Ctrl-C (``how="interrupt"``), leaving ``marker`` so the next attempt
succeeds.  ``slow`` sleeps ``delay`` seconds, appends "index pid" to ``log`` when
a run finishes and then returns what ``draws`` returns (the kill tests).
``impure`` takes a recorder but also reads a clock, so a recorded replay differs
from the stored run (the ``--record`` warning).
"""

import os
import signal
import time
from pathlib import Path

from hybridtrack.apps.experiment import Experiment


def draws(index, rng, *, size=3):
    return {"normal": rng.standard_normal(size), "uniform": float(rng.uniform()), "index_seen": index}


def flaky(index, rng, *, log, marker, fail_at, how, size=3):
    with open(log, "a") as handle:
        handle.write(f"{index}\n")
    if index == fail_at and not Path(marker).exists():
        Path(marker).write_text("failed once")
        if how == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        if how == "interrupt":
            raise KeyboardInterrupt
        raise RuntimeError(f"planned failure at run {index}")
    return draws(index, rng, size=size)


def slow(index, rng, *, delay, log, size=3):
    time.sleep(delay)
    with open(log, "a") as handle:
        handle.write(f"{index} {os.getpid()}\n")
    return draws(index, rng, size=size)


def not_numeric(index, rng):
    return {"label": "text"}


DRAWS = Experiment("draws", draws, {"size": 3})
FLAKY = Experiment("flaky", flaky, {"log": "", "marker": "", "fail_at": -1, "how": "raise", "size": 3})
EXPERIMENT = FLAKY  # what `hybridtrack run tests/apps/_toy_experiments.py` runs
SLOW = Experiment("slow", slow, {"delay": 0.1, "log": "", "size": 3})
NOT_NUMERIC = Experiment("not_numeric", not_numeric)


def impure(index, rng, *, recorder=None):
    """Draws from a clock besides its generator: a replay (``--record``) cannot give the stored result."""
    return {"clock": float(time.perf_counter_ns()), "uniform": float(rng.uniform())}


IMPURE = Experiment("impure", impure)
