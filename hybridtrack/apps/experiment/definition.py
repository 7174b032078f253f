"""What a Monte Carlo experiment is, and how a name or a path becomes one.

An :class:`Experiment` is a name, ``run_one(index, rng, **parameters)`` (one run's results, name → float or
array with the same names and shapes in every run, all randomness drawn from ``rng``), default ``parameters`` and
optionally ``run_batch(indices, rngs, **parameters)`` giving ``run_one``'s results for a chunk at once
(docs/experiments.md).  Workers receive not the function but a *locator* string they resolve on their side (so a
script that is not an importable module runs):

* ``"package.module:ATTRIBUTE"`` — an importable module's attribute;
* ``"/path/to/script.py"`` (or ``"/path/to/script.py:ATTRIBUTE"``) — a file
  loaded by path, attribute ``EXPERIMENT`` by default.

:func:`load_experiment` turns a registered name, a ``.py`` path or a locator
into an :class:`Experiment` whose ``locator`` is set; a script with a syntax error is an
:class:`ExperimentScriptError` naming the file, the line and the error.

Parameter overrides are checked before any run (:meth:`Experiment.with_parameters`): a name the experiment
does not have, a value of another type than the default's (a number for a number, an integer for an integer,
true/false, text, a list, a mapping; a finite number where the default is finite), and the experiment's own
``check_parameters`` — each a :class:`ParameterError` naming the parameter, what was expected and what was got.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import math
import numbers
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import attrs

#: registered name → locator
EXPERIMENTS: dict[str, str] = {"demo_rmse": "hybridtrack.apps.experiment.builtin:DEMO_RMSE"}

#: where ``hybridtrack run NAME`` also looks for ``NAME.py`` (relative to the working directory)
SCRIPT_FOLDER = Path("experiments")


class UnknownExperiment(LookupError):
    """A name that is neither registered nor a script; the message lists what is known."""


class ExperimentScriptError(ValueError):
    """An experiment script that does not compile: the message names the file, the line and the error."""


class ParameterError(ValueError):
    """A parameter override that does not fit the experiment: the message names the parameter, what was expected
    and what was got."""


def _expected_like(default) -> tuple[str, Callable[[Any], bool]] | None:
    """(what is expected, the test) of an override of a parameter whose default is ``default``; None: anything."""
    if isinstance(default, bool):
        return "true or false", lambda value: isinstance(value, bool)
    if isinstance(default, numbers.Integral):
        return "an integer", lambda value: isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if isinstance(default, numbers.Real):
        finite = math.isfinite(default)

        def number(value) -> bool:
            return isinstance(value, numbers.Real) and not isinstance(value, bool) and (not finite or math.isfinite(value))

        return ("a finite number" if finite else "a number"), number
    if isinstance(default, str):
        return "text", lambda value: isinstance(value, str)
    if isinstance(default, (list, tuple)):
        return "a list", lambda value: isinstance(value, (list, tuple))
    if isinstance(default, Mapping):
        return "a mapping", lambda value: isinstance(value, Mapping)
    return None


@attrs.frozen(eq=False)
class Experiment:
    """A named Monte Carlo experiment (module docstring); ``parameters`` are the JSON-serializable defaults
    (the manifest records them); ``locator`` says how a worker process finds it again (``None``: pickle the
    function by reference); ``batch_size`` is the default chunk size of a campaign with ``run_batch``."""

    name: str
    run_one: Callable[..., Mapping[str, Any]]
    parameters: dict[str, Any] = attrs.field(factory=dict, converter=lambda value: dict(value or {}))
    description: str = ""
    locator: str | None = None
    run_batch: Callable[..., Any] | None = None
    batch_size: int = 100
    #: ``check_parameters(parameters)``: raises ValueError or TypeError, its message starting with the parameter's
    #: name, for a value the runs cannot take (a range, a relation between parameters); called before any run
    check_parameters: Callable[[dict[str, Any]], Any] | None = None

    def __attrs_post_init__(self):
        if not self.name or not isinstance(self.name, str):
            raise ValueError(f"Experiment name: expected a non-empty string, got {self.name!r}")
        if not callable(self.run_one):
            raise TypeError(f"Experiment {self.name!r}: run_one must be callable, got {self.run_one!r}")
        if self.run_batch is not None and not callable(self.run_batch):
            raise TypeError(f"Experiment {self.name!r}: run_batch must be callable or None, got {self.run_batch!r}")
        if isinstance(self.batch_size, bool) or not isinstance(self.batch_size, int) or self.batch_size < 1:
            raise ValueError(f"Experiment {self.name!r}: batch_size must be a positive integer, got {self.batch_size!r}")
        if self.check_parameters is not None and not callable(self.check_parameters):
            raise TypeError(f"Experiment {self.name!r}: check_parameters must be callable or None, got {self.check_parameters!r}")

    def with_parameters(self, **overrides: Any) -> dict[str, Any]:
        """The defaults updated by ``overrides``, checked: an unknown parameter name, a value unlike its default
        (module docstring) or one ``check_parameters`` refuses is a :class:`ParameterError`."""
        unknown = sorted(set(overrides) - set(self.parameters))
        if unknown:
            raise ParameterError(f"experiment {self.name!r}: unknown parameter(s) {unknown}; its parameters are {sorted(self.parameters)}")
        for name, value in overrides.items():
            default = self.parameters[name]
            like = _expected_like(default)
            if like is not None and not like[1](value):
                raise ParameterError(
                    f"experiment {self.name!r}: parameter {name}: expected {like[0]} (as its default {default!r}), got {value!r}"
                )
        parameters = {**self.parameters, **overrides}
        if self.check_parameters is not None:
            try:
                self.check_parameters(dict(parameters))
            except (ValueError, TypeError) as error:
                raise ParameterError(f"experiment {self.name!r}: parameter {error}") from None
        return parameters


def _load_script(path: Path) -> Any:
    path = path.resolve()
    digest = hashlib.sha1(str(path).encode()).hexdigest()[:10]
    module_name = f"_hybridtrack_experiment_{path.stem}_{digest}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise UnknownExperiment(f"cannot load {path} as a Python script")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except SyntaxError as error:  # IndentationError and TabError too; in the script or a module it imports
        where = f"{error.filename or path}, line {error.lineno}" if error.lineno else f"{error.filename or path}"
        inside = "" if error.filename in (None, str(path)) else f" (imported by experiment script {path})"
        raise ExperimentScriptError(f"{where}: {type(error).__name__}: {error.msg}{inside}") from None
    return module


@functools.cache
def resolve_locator(locator: str) -> Experiment:
    """The :class:`Experiment` a locator points at (cached per process)."""
    target, separator, attribute = locator.rpartition(":")
    if locator.endswith(".py"):
        target, attribute = locator, "EXPERIMENT"
    elif not separator or not target or not attribute:
        raise UnknownExperiment(f"locator {locator!r}: expected 'module:ATTRIBUTE', 'script.py' or 'script.py:ATTRIBUTE'")
    if target.endswith(".py"):
        path = Path(target)
        if not path.is_file():
            raise UnknownExperiment(f"experiment script {path} does not exist")
        holder = _load_script(path)
    else:
        holder = importlib.import_module(target)
    experiment = getattr(holder, attribute, None)
    if not isinstance(experiment, Experiment):
        raise UnknownExperiment(f"{target} has no Experiment named {attribute} (found {type(experiment).__name__})")
    return attrs.evolve(experiment, locator=locator)


def known_experiments() -> list[str]:
    """Registered names and the scripts in ``experiments/`` of the working directory that define ``EXPERIMENT``."""
    scripts = [path for path in SCRIPT_FOLDER.glob("[!_]*.py") if "EXPERIMENT" in path.read_text("utf-8", errors="replace")]
    return sorted({*EXPERIMENTS, *(path.stem for path in scripts)})


def load_experiment(spec: str | Experiment) -> Experiment:
    """An :class:`Experiment` from a registered name, a script path, ``experiments/NAME.py`` or a locator."""
    if isinstance(spec, Experiment):
        return spec
    if spec in EXPERIMENTS:
        return resolve_locator(EXPERIMENTS[spec])
    if spec.endswith(".py"):
        return resolve_locator(str(Path(spec).resolve()))
    script = SCRIPT_FOLDER / f"{spec}.py"
    if script.is_file():
        return resolve_locator(str(script.resolve()))
    if ":" in spec:
        return resolve_locator(spec)
    raise UnknownExperiment(
        f"unknown experiment {spec!r}; known experiments: {', '.join(known_experiments())} (or give a path to a script defining EXPERIMENT)"
    )
