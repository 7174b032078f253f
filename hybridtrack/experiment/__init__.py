"""Monte Carlo campaigns: seeded, resumable runs of an experiment on a chosen executor.

* :mod:`~hybridtrack.experiment.definition` — :class:`Experiment` and the registry of named experiments;
* :mod:`~hybridtrack.experiment.worker` — per-run seeds and the chunk function workers execute;
* :mod:`~hybridtrack.experiment.executors` — ``inline``, ``process`` (default), ``dask``;
* :mod:`~hybridtrack.experiment.store` — the result folder (manifest + one NPZ per finished chunk);
* :mod:`~hybridtrack.experiment.campaign` — :class:`Campaign`, which ties them together;
* :mod:`~hybridtrack.experiment.recordings` — chosen runs replayed with a recorder, the summary recording;
* :mod:`~hybridtrack.experiment.builtin` — the built-in ``demo_rmse`` experiment.

The command line is ``hybridtrack run EXPERIMENT [--n N] [--executor …] [--out DIR] [--record K] [--summary-recording]``.
"""

from hybridtrack.experiment.campaign import Campaign, CampaignInterrupted, CampaignResult, RunFailed, run_campaign
from hybridtrack.experiment.definition import (
    EXPERIMENTS,
    Experiment,
    UnknownExperiment,
    known_experiments,
    load_experiment,
    register_experiment,
)
from hybridtrack.experiment.executors import EXECUTORS
from hybridtrack.experiment.store import CampaignLocked, CampaignMismatch, CorruptResults, ResultStore
from hybridtrack.experiment.worker import run_seed

__all__ = [
    "EXECUTORS",
    "EXPERIMENTS",
    "Campaign",
    "CampaignInterrupted",
    "CampaignLocked",
    "CampaignMismatch",
    "CampaignResult",
    "CorruptResults",
    "Experiment",
    "ResultStore",
    "RunFailed",
    "UnknownExperiment",
    "known_experiments",
    "load_experiment",
    "register_experiment",
    "run_campaign",
    "run_seed",
]
