"""The built-in algorithms as components of kind ``algorithm``, registered as a third party registers its own.

Entry point ``algorithms`` of the ``hybridtrack`` group (``pyproject.toml``);
``hybridtrack plugins`` lists them and a ``track`` configuration names them
(``[estimator] algorithm = "imm"``).  Each factory imports its class when it is
called, so loading the plugins stays cheap.  The contract they keep is
:class:`hybridtrack.core.algorithm.Algorithm`; ``example_parameters`` and
``example_run`` let :func:`hybridtrack.testing.check_algorithm` build and run
each one on its own.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hybridtrack.core.hookspecs import hookimpl
from hybridtrack.core.registry import Registry, registry_or_default
from hybridtrack.engine.schedule import Schedule

#: a turn wide enough for the contract check's straight truth (10 m/s, steps of 1 s)
_TURN = ("right_turn", {"radius": 100.0})
_MODES = {"modes": ["straight", _TURN]}
_MARKOV = {**_MODES, "transition_matrix": [[0.95, 0.05], [0.05, 0.95]]}


def _multiple_model(method: str, modes: Sequence[Any], parameters: dict):
    from hybridtrack.algorithms.multiple_model import MultipleModelEstimator

    return MultipleModelEstimator(modes, method=method, **parameters)


def imm(*, modes: Sequence[Any], **parameters):
    """IMM: interacting multiple model estimator over Markov-switching modes (MultipleModelEstimator, method "imm")."""
    return _multiple_model("imm", modes, parameters)


def gpb1(*, modes: Sequence[Any], **parameters):
    """GPB1: first-order generalized pseudo-Bayesian estimator (MultipleModelEstimator, method "gpb1")."""
    return _multiple_model("gpb1", modes, parameters)


def gpb2(*, modes: Sequence[Any], **parameters):
    """GPB2: second-order generalized pseudo-Bayesian estimator (MultipleModelEstimator, method "gpb2")."""
    return _multiple_model("gpb2", modes, parameters)


def known_switch(**parameters):
    """Algorithm 1: SPRT on a bank re-created at each known switching moment (KnownSwitchAdaptive)."""
    from hybridtrack.algorithms.known_switch import KnownSwitchAdaptive

    return KnownSwitchAdaptive(**parameters)


def unknown_change(**parameters):
    """Algorithm 3: change-time SPRT on a growing or bounded bank, the estimate follows the mode (UnknownChangeAdaptive)."""
    from hybridtrack.algorithms.unknown_change import UnknownChangeAdaptive

    return UnknownChangeAdaptive(**parameters)


class KnownModes:
    """The filter told the true schedule: one filter in the true mode of each segment (seed 001's "optimal KF").

    ``run_known_modes`` as an algorithm: the ``schedule`` is given when it is
    built, the measurements and the prior when it runs.
    """

    def __init__(
        self,
        *,
        schedule: Schedule,
        sensors,
        estimator: Any = "kalman",
        tau: float | None = None,
        noise_cov=None,
        name: str = "known_modes",
        registry: Registry | None = None,
    ):
        from hybridtrack.engine.simulate import build_models

        self.schedule = schedule if isinstance(schedule, Schedule) else Schedule.from_rows(schedule)
        self.sensors, self.estimator, self.tau, self.noise_cov = sensors, estimator, tau, noise_cov
        self.name, self.registry = name, registry
        self.layout = build_models(self.schedule, registry_or_default(registry), noise_cov)[0].layout

    @staticmethod
    def example_parameters() -> dict:
        return {"schedule": Schedule.from_rows([("straight", 10), ("right_turn", 10, 100.0)])}

    def run(self, measurements, prior, *, times=None, recorder=None):
        """:func:`~hybridtrack.algorithms.known_modes.run_known_modes` over the schedule."""
        from hybridtrack.algorithms.known_modes import run_known_modes

        return run_known_modes(
            self.schedule, **self.settings(), measurements=measurements, prior=prior, times=times, recorder=recorder, name=self.name
        )

    def run_batch(self, measurements, prior, *, times=None):
        """:func:`~hybridtrack.algorithms.known_modes.run_known_modes_batch` over the schedule (R runs)."""
        from hybridtrack.algorithms.known_modes import run_known_modes_batch

        return run_known_modes_batch(self.schedule, **self.settings(), measurements=measurements, prior=prior, times=times)

    def settings(self) -> dict:
        """The keywords both runs share."""
        return dict(estimator=self.estimator, sensors=self.sensors, tau=self.tau, noise_cov=self.noise_cov, registry=self.registry)


imm.example_parameters = gpb1.example_parameters = gpb2.example_parameters = _MARKOV
unknown_change.example_parameters = _MODES
known_switch.example_parameters = {"r_min": 50.0, "r_max": 200.0, "n": 2}
known_switch.example_run = {"segments": [10, 10]}


@hookimpl
def register_algorithms(registry):
    for factory in (imm, gpb1, gpb2, known_switch, unknown_change):
        registry.add(factory.__name__, factory)
    registry.add("known_modes", KnownModes)
