"""Monte Carlo campaigns: seeded, resumable runs of an experiment on a chosen executor (docs/experiments.md).

:class:`Campaign` (:mod:`~hybridtrack.apps.experiment.campaign`) ties together the definition of an experiment,
the workers, the executors, the result store and the recordings, one module each; on the command line it is
``hybridtrack run EXPERIMENT``.
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
