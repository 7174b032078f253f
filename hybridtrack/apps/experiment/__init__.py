"""Monte Carlo campaigns: seeded, resumable runs of an experiment on a chosen executor.

* :mod:`~hybridtrack.apps.experiment.definition` — :class:`Experiment` and the registry of named experiments;
* :mod:`~hybridtrack.apps.experiment.worker` — per-run seeds and the chunk function workers execute;
* :mod:`~hybridtrack.apps.experiment.executors` — ``inline``, ``process`` (default), ``dask``;
* :mod:`~hybridtrack.apps.experiment.store` — the result folder (manifest + one NPZ per finished chunk);
* :mod:`~hybridtrack.apps.experiment.campaign` — :class:`Campaign`, which ties them together;
* :mod:`~hybridtrack.apps.experiment.recordings` — chosen runs replayed with a recorder, the summary recording;
* :mod:`~hybridtrack.apps.experiment.builtin` — the built-in ``demo_rmse`` experiment.

The command line is ``hybridtrack run EXPERIMENT [--n N] [--executor …] [--out DIR] [--record K] [--summary-recording]``.
"""

from hybridtrack.apps.experiment.campaign import Campaign, CampaignInterrupted, CampaignResult, RunFailed, run_campaign
from hybridtrack.apps.experiment.definition import EXPERIMENTS, Experiment, UnknownExperiment, known_experiments, load_experiment
from hybridtrack.apps.experiment.executors import EXECUTORS
from hybridtrack.apps.experiment.store import CampaignLocked, CampaignMismatch, CorruptResults, ResultStore
from hybridtrack.apps.experiment.worker import run_seed

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
    "run_campaign",
    "run_seed",
]
