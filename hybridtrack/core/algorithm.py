"""The Algorithm interface: an estimator run over a whole measurement sequence, registered like any component.

Contract (what ``hybridtrack track``, the experiments and the contract check
rely on; :func:`hybridtrack.testing.check_algorithm` checks it):

* The registered factory takes keywords.  Every algorithm accepts ``sensors``
  (the :class:`~hybridtrack.core.interfaces.Sensor` objects it reads, or a
  ``SensorNetwork``) and ``tau`` (the step in seconds, or None when every run
  gives its ``times``); an algorithm over motion modes takes them as
  ``modes`` (objects, registry names or (name, parameters)); ``estimator``
  (the filter inside, a registered name or an object), ``name`` and
  ``registry`` are accepted where they apply.
* ``name`` (str) names the instance (recordings, results); ``layout`` (tuple
  of str) the state components of its estimate.
* ``run(measurements, prior, *, times=None, recorder=None, …)`` runs steps
  0 … K: ``measurements`` maps a sensor name to its (K+1, m) array (NaN: no
  measurement), ``prior`` is a :class:`~hybridtrack.core.types.Gaussian` or
  (mean, cov) in ``layout``, ``times`` the K+1 times in seconds (default 0, τ,
  2τ, …).  It returns a result with ``times`` (K+1,), ``means`` (K+1, n),
  ``covs`` (K+1, n, n) and ``decisions`` (the detectors' decisions in step
  order; none for an algorithm without detector) — the fields of
  ``hybridtrack.engine.results.RunResult``, whose ``modes`` and ``mode`` (the
  index of the mode followed per step) ``hybridtrack track`` also reads.  An algorithm that needs
  more per run (Algorithm 1's known switching steps) takes it as a further
  argument of ``run``.

A class with a ``run`` method counts as an Algorithm (structural, as the ABCs
of :mod:`collections.abc`); the contract check's conventions
(``example_parameters``, ``example_run``) are in ``docs/plugins.md``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar


class Algorithm(ABC):
    """An estimator over a whole measurement sequence: ``run(measurements, prior, *, times=None, …)`` → a result."""

    name: str
    layout: tuple[str, ...]
    declared_attributes: ClassVar[tuple[str, ...]] = ("name", "layout")

    @abstractmethod
    def run(self, measurements, prior, *, times=None, **options) -> Any:
        """The run over steps 0 … K: a result with ``times``, ``means``, ``covs``, ``decisions``."""

    @classmethod
    def __subclasshook__(cls, other: type):
        if cls is Algorithm and callable(getattr(other, "run", None)):
            return True
        return NotImplemented
