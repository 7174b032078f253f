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


def known_modes(**parameters):
    """The filter told the true schedule: one filter in the true mode of each segment (KnownModes)."""
    from hybridtrack.algorithms.known_modes import KnownModes

    return KnownModes(**parameters)


imm.example_parameters = gpb1.example_parameters = gpb2.example_parameters = _MARKOV
unknown_change.example_parameters = _MODES
known_switch.example_parameters = {"r_min": 50.0, "r_max": 200.0, "n": 2}
known_switch.example_run = {"segments": [10, 10]}
known_modes.example_parameters = {"schedule": [("straight", 10), ("right_turn", 10, 100.0)]}


@hookimpl
def register_algorithms(registry):
    for factory in (imm, gpb1, gpb2, known_switch, unknown_change, known_modes):
        registry.add(factory.__name__, factory)
