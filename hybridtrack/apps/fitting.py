"""Parameters of a tracker configuration fitted to a file by maximum likelihood (``hybridtrack fit``).

The multiple-model tracker of a configuration gives, for every object, the
innovation likelihood of each report, ln p(z_k | z_0 … z_{k−1}) (the mixture's
``loglik`` of :class:`~hybridtrack.algorithms.multiple_model.MultipleModelRun`),
so the log-likelihood of the file under parameters θ is

    ℓ(θ) = Σ_objects Σ_k ln p(z_k | Z_{k−1}; θ)

(the prediction-error decomposition; Harvey 1989, *Forecasting, Structural
Time Series Models and the Kalman Filter*, §3.4; Bar-Shalom, Li &
Kirubarajan 2001, §11.6 for the mixture's likelihood).  Fitted, each as its
logarithm so that it stays positive: the measurement noise σ (``[measurement]
sigma``, m) and, where the configuration measures the reported course and speed, their σ_s and σ_χ
(``speed_sigma``, m/s; ``course_sigma``, degrees, where not 0), the white-acceleration density q (``[estimator] noise_density``,
m²/s³, every mode without its own; started from σ_w²/10 s for a file of the
per-report ``process_noise``), with more than one mode the mean time in
each mode (``[estimator] sojourn``, s, one per mode: ``sojourn.<mode>``, :func:`sojourns`), and each mode's own
process densities (``<mode>.rate_density`` …, :func:`mode_densities`).  θ̂ maximizes ℓ
(L-BFGS-B from the configuration's values, at most ``max_iterations`` iterations, 60 unless given:
``FitResult.converged`` says whether it stopped at a minimum); the standard errors come from
the observed information, the numerical Hessian H of −ℓ in the logarithms at
θ̂ (central differences): SE(ln θ_i) = √(H⁻¹)_ii and SE(θ_i) = θ̂_i SE(ln θ_i)
(the delta method).  Parameters named in ``hold`` (``hybridtrack fit --hold NAME``) keep the configuration's
values: a datasheet's noise, or one the data cannot tell apart from the rest.  Direct maximization, not EM: the IMM's likelihood has no
closed-form M-step.
"""

from __future__ import annotations

import copy
import inspect
import json
import math
import os
import re
import tomllib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import attrs
import numpy as np
from scipy.optimize import minimize

from hybridtrack.apps.tracking import MULTIPLE_MODEL, ConfigError, build_tracker, load_config, measurements_of, run_objects, track_prior
from hybridtrack.core.registry import registry_or_default
from hybridtrack.io.track_files import read_tracks

#: parameter → (table, key, units)
PARAMETERS = {
    "sigma": ("measurement", "sigma", "m"),
    "noise_density": ("estimator", "noise_density", "m²/s³"),
    "speed_sigma": ("measurement", "speed_sigma", "m/s"),
    "course_sigma": ("measurement", "course_sigma", "degrees"),
}
#: fitted when the configuration measures the reported course and speed (the ``velocity`` sensor)
VELOCITY_NOISE = ("speed_sigma", "course_sigma")


#: the units of the motion models' own densities a fit estimates (``<mode>.<parameter>``, :func:`mode_densities`)
DENSITY_UNITS = {"noise_density": "m²/s³ (stop: m²/s)", "rate_density": "rad²/s³", "jerk_density": "(m/s²)²/s"}


def mode_densities(config: dict, registry=None) -> dict[str, tuple[int, str, float]]:
    """The modes' own process densities a fit estimates: ``"<mode>.<parameter>"`` → (index in ``[estimator] modes``,
    parameter, start value) for every ``*_density`` parameter of a mode's registered factory (the coordinated
    turn's ``rate_density``, speed change's ``jerk_density``, a third party's), started from the mode's table or
    the factory's default; ``noise_density`` only where the mode's table gives its own (the others share the
    estimator's, fitted as ``noise_density``).  A name repeated by two modes gets the mode's index: ``left_turn[2].…``."""
    found, labels = [], mode_names(config)
    for i, (name, params) in enumerate(config["estimator"]["modes"]):
        try:
            parameters = inspect.signature(registry_or_default(registry).get("motion_model", name)).parameters.values()
        except (KeyError, TypeError, ValueError):
            continue
        for parameter in parameters:
            if not parameter.name.endswith("_density") or (parameter.name == "noise_density" and parameter.name not in params):
                continue
            start = params.get(parameter.name, parameter.default)
            if isinstance(start, (int, float)) and not isinstance(start, bool) and math.isfinite(start) and start > 0:
                found.append((labels[i], i, parameter.name, float(start)))
    return {f"{label}.{key}": (i, key, start) for label, i, key, start in found}


def mode_names(config: dict) -> list[str]:
    """The name of each mode of ``[estimator] modes`` in fitted parameters: its registry name, with its index
    (``left_turn[2]``) when two modes share it."""
    names = [name for name, _ in config["estimator"]["modes"]]
    return [f"{name}[{i}]" if names.count(name) > 1 else name for i, name in enumerate(names)]


def sojourns(config: dict) -> dict[str, tuple[int, float]]:
    """``"sojourn.<mode>"`` → (mode index, start value): the mean time in each mode (s) of a configuration with more
    than one mode, started from ``[estimator] sojourn`` (one number for all, or one per mode)."""
    est = config["estimator"]
    if len(est["modes"]) < 2:  # one mode: no switching, nothing to learn about the sojourn
        return {}
    given = est.get("sojourn", 60.0)
    values = given if isinstance(given, list) else [given] * len(est["modes"])
    return {f"sojourn.{label}": (i, float(values[i])) for i, label in enumerate(mode_names(config))}


def describe(name: str) -> tuple[str, str, str]:
    """(table, key, units) of a fitted parameter: :data:`PARAMETERS`, or ``modes`` and the unit of a mode's density."""
    if name in PARAMETERS:
        return PARAMETERS[name]
    if name.startswith("sojourn."):
        return "estimator", f"sojourn {name.removeprefix('sojourn.')}", "s"
    return "estimator", f"modes {name}", DENSITY_UNITS.get(name.rsplit(".", 1)[-1], "")


@attrs.frozen
class FitResult:
    """``values`` and ``standard_errors`` by parameter name, the log-likelihood at the fit and at the start, the
    objects and reports used, the likelihood evaluations taken, the fitted configuration (a checked dict) and whether
    the optimizer converged (False: it stopped at ``max_iterations``, θ̂ is where it stopped)."""

    values: dict[str, float]
    standard_errors: dict[str, float]
    loglik: float
    start_loglik: float
    objects: int
    reports: int
    evaluations: int
    config: dict
    converged: bool


def _with(config: dict, values: Mapping[str, float], registry=None) -> dict:
    out = copy.deepcopy(config)
    densities, times = mode_densities(config, registry), sojourns(config)
    for name, value in values.items():
        if name in times:
            given = out["estimator"].get("sojourn", 60.0)
            out["estimator"]["sojourn"] = given if isinstance(given, list) else [given] * len(out["estimator"]["modes"])
            out["estimator"]["sojourn"][times[name][0]] = float(value)
            continue
        if name in densities:
            index, key, _ = densities[name]
            out["estimator"]["modes"][index][1][key] = float(value)
            continue
        table, key, _ = PARAMETERS[name]
        out[table][key] = float(value)
    if "noise_density" in values:
        out["estimator"].pop("process_noise", None)
    return out


def log_likelihood(config: dict, tracks: Iterable, registry=None) -> float:
    """ℓ of the tracks (module docstring) under a checked configuration of a multiple-model algorithm: the objects
    stacked as runs of one bank (:func:`~hybridtrack.apps.tracking.run_objects`; an object of a batch that failed
    runs alone)."""
    estimator = build_tracker(config, registry)[0]
    tracks = list(tracks)
    total = 0.0
    for track, run in zip(tracks, run_objects(estimator, tracks, config)):
        if run is None:
            run = estimator.run(measurements_of(track, config), track_prior(track, config, estimator.layout), times=track.times)
        total += float(np.sum(run.loglik))
    return total


#: the optimizer's iterations unless a fit is given ``max_iterations`` (``hybridtrack fit --max-iterations``)
MAX_ITERATIONS = 60


def _check_fittable(cfg: dict) -> None:
    if cfg["estimator"]["algorithm"] not in MULTIPLE_MODEL:
        raise ConfigError(f"[estimator] algorithm {cfg['estimator']['algorithm']!r}: fit needs a multiple-model algorithm {MULTIPLE_MODEL}")


def fit_config(
    path: str | os.PathLike,
    config: str | os.PathLike | Mapping[str, Any],
    *,
    ids=None,
    max_objects: int | None = None,
    hold: Iterable[str] = (),
    max_iterations: int = MAX_ITERATIONS,
    registry=None,
) -> FitResult:
    """θ̂ and its standard errors for the objects of ``path`` (those in ``ids``, or the first ``max_objects`` with at
    least ``min_reports`` reports) under ``config`` (module docstring), the parameters named in ``hold`` kept at the
    configuration's values; a ConfigError for an algorithm other than imm, gpb1, gpb2, a file without objects to
    fit or a name in ``hold`` that is not one of the parameters the configuration has to fit."""
    cfg = load_config(config, registry)
    _check_fittable(cfg)
    data = read_tracks(path, **cfg["reader"], warn=False)
    chosen = [t for key, t in data.tracks.items() if (ids is None or key in set(ids)) and len(t) >= cfg["min_reports"]]
    chosen = chosen[:max_objects] if max_objects is not None else chosen
    if not chosen:
        raise ConfigError(f"{path}: no object with at least min_reports = {cfg['min_reports']} reports to fit")
    return fit_tracks(chosen, cfg, hold=hold, max_iterations=max_iterations, registry=registry)


def starting_values(config: dict, registry=None) -> dict[str, float]:
    """The parameters a fit of the checked ``config`` estimates (module docstring), by name, each at the value it
    starts from: the configuration's own."""
    est, measured = config["estimator"], config["measurement"]
    start = {"sigma": measured["sigma"], "noise_density": est.get("noise_density", est.get("process_noise", 0.1) ** 2 / 10.0)}
    start |= {name: measured[name] for name in VELOCITY_NOISE if measured.get(name, 0.0) > 0}  # σ_χ = 0: no course
    start |= {name: value for name, (_, value) in sojourns(config).items()}
    return start | {name: value for name, (_, _, value) in mode_densities(config, registry).items()}


def fit_tracks(
    tracks: Iterable, config: dict, *, hold: Iterable[str] = (), max_iterations: int = MAX_ITERATIONS, registry=None
) -> FitResult:
    """:func:`fit_config` on tracks already read (:class:`~hybridtrack.io.track_files.Track` objects, e.g. a
    part of a file's, or tracks with simulated noise) under a checked configuration (:func:`load_config`)."""
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, int) or max_iterations < 1:
        raise ConfigError(f"max_iterations: expected a positive whole number of optimizer iterations, got {max_iterations!r}")
    cfg, chosen = config, list(tracks)
    _check_fittable(cfg)
    if not chosen:
        raise ConfigError("tracks: no track to fit")
    start = starting_values(cfg, registry)
    hold = list(dict.fromkeys([hold] if isinstance(hold, str) else hold))
    unknown = [name for name in hold if name not in start]
    if unknown:
        raise ConfigError(f"hold {unknown[0]!r}: not a parameter of this configuration; expected some of {', '.join(start)}")
    if len(hold) == len(start):
        raise ConfigError(f"hold {', '.join(hold)}: every parameter held, nothing left to fit")
    names = [name for name in start if name not in hold]
    evaluations = 0

    def negative(log_theta: np.ndarray) -> float:
        nonlocal evaluations
        evaluations += 1
        value = -log_likelihood(_with(cfg, dict(zip(names, np.exp(log_theta))), registry), chosen, registry)
        return value if math.isfinite(value) else 1e300

    x0 = np.log([start[n] for n in names])
    start_value = negative(x0)
    found = minimize(
        negative, x0, method="L-BFGS-B", bounds=[(v - 7.0, v + 7.0) for v in x0], options={"eps": 1e-4, "maxiter": max_iterations}
    )
    theta = found.x
    H = _hessian(negative, theta, found.fun)
    try:
        cov = np.linalg.inv(H)
        se_log = np.sqrt(np.where(np.diag(cov) > 0, np.diag(cov), np.nan))
    except np.linalg.LinAlgError:
        se_log = np.full(theta.size, np.nan)
    values = dict(zip(names, np.exp(theta).tolist()))
    return FitResult(
        values=values,
        standard_errors={n: float(values[n] * s) for n, s in zip(names, se_log)},
        loglik=-float(found.fun),
        start_loglik=-start_value,
        objects=len(chosen),
        reports=sum(len(t) for t in chosen),
        evaluations=evaluations,
        config=_with(cfg, values, registry),
        converged=bool(found.success),
    )


def _hessian(function, x: np.ndarray, fx: float, step: float = 1e-2) -> np.ndarray:
    """The Hessian of ``function`` at x by central differences of step ``step`` (in the logarithms: 1 %)."""
    n = x.size
    H = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            if i == j:
                e = np.zeros(n)
                e[i] = step
                H[i, i] = (function(x + e) - 2.0 * fx + function(x - e)) / step**2
            else:
                ei, ej = np.zeros(n), np.zeros(n)
                ei[i], ej[j] = step, step
                H[i, j] = H[j, i] = (function(x + ei + ej) - function(x + ei - ej) - function(x - ei + ej) + function(x - ei - ej)) / (
                    4.0 * step**2
                )
    return 0.5 * (H + H.T)


def write_fitted(config_path: str | os.PathLike, values: Mapping[str, float], out: str | os.PathLike) -> Path:
    """The configuration file ``config_path`` with the fitted values set (comments and everything else kept): each
    key replaced in its table, or added under the table's header; ``process_noise`` dropped for ``noise_density``."""
    text = Path(config_path).read_text(encoding="utf-8")
    for name, value in values.items():
        if name in PARAMETERS:
            table, key, units = PARAMETERS[name]
            text = _set_key(text, table, key, f"{value:.6g}", f"fitted by hybridtrack fit ({units})")
    given = load_config(Path(config_path))
    times = sojourns(given)
    if any(name in times for name in values):
        fitted = [values.get(name, start) for name, (_, start) in times.items()]
        text = _set_key(text, "estimator", "sojourn", _toml_value(fitted), "fitted by hybridtrack fit (s, per mode)")
    own = {name: value for name, value in values.items() if name not in PARAMETERS and name not in times}
    if own:
        text = _set_mode_densities(text, own, given)
    if "noise_density" in values:
        text = re.sub(r"(?m)^process_noise\s*=.*\n", "", text)
    out = Path(out)
    out.write_text(text, encoding="utf-8")
    load_config(out)  # what track will read
    return out


def _set_key(text: str, table: str, key: str, value: str, comment: str) -> str:
    header = re.search(rf"(?m)^\[{re.escape(table)}\]\s*$", text)
    line = f"{key} = {value}    # {comment}"
    if header is None:
        return text.rstrip("\n") + f"\n\n[{table}]\n{line}\n"
    end = re.search(r"(?m)^\[", text[header.end() :])
    body_end = header.end() + (end.start() if end else len(text) - header.end())
    body = text[header.end() : body_end]
    pattern = rf"(?m)^{re.escape(key)}\s*=.*$"
    body = re.sub(pattern, line, body, count=1) if re.search(pattern, body) else "\n" + line + body
    return text[: header.end()] + body + text[body_end:]


def _set_mode_densities(text: str, values: Mapping[str, float], config: dict) -> str:
    """``text`` with ``[estimator] modes`` rewritten: each mode whose density was fitted a table with the value
    (the other entries as they were written; the array's own comments are replaced by one line saying so)."""
    table = tomllib.loads(text)["estimator"]
    raw, radii = table["modes"], table.get("radii") or []
    densities = mode_densities(config)
    entries, first = [], 0  # the checked config's mode index of each raw entry (a bare turn takes one per radius)
    for entry in raw:
        entries.append((first, entry))
        first += len(radii) if isinstance(entry, str) and entry in ("left_turn", "right_turn") and radii else 1
    out = []
    for index, entry in entries:
        fitted = {key: value for name, value in values.items() for i, key, _ in [densities[name]] if i == index}
        if fitted:
            entry = ({"name": entry} if isinstance(entry, str) else dict(entry)) | fitted
        out.append(_toml_value(entry))
    array = "modes = [    # densities fitted by hybridtrack fit\n" + "".join(f"    {entry},\n" for entry in out) + "]"
    start = re.search(r"(?m)^modes\s*=\s*\[", text)
    return text[: start.start()] + array + text[_closing_bracket(text, start.end() - 1) + 1 :]


def _toml_value(value) -> str:
    """A TOML inline value of a mode entry: a string, a number, a bool, a list or an inline table."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, float):
        return f"{value:.6g}" if "e" in f"{value:.6g}" or "." in f"{value:.6g}" else f"{value:.6g}.0"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, list):
        return "[" + ", ".join(map(_toml_value, value)) + "]"
    return "{" + ", ".join(f"{key} = {_toml_value(v)}" for key, v in value.items()) + "}"


def _closing_bracket(text: str, opening: int) -> int:
    """The index of the ``]`` closing the ``[`` at ``opening`` (strings and comments skipped)."""
    depth, i = 0, opening
    while i < len(text):
        c = text[i]
        if c == "#":
            i = text.find("\n", i)
            i = len(text) if i < 0 else i
            continue
        if c in "\"'":
            i = text.index(c, i + 1)
        elif c in "[{":
            depth += 1
        elif c in "]}":
            depth -= 1
            if depth == 0:
                return i
        i += 1
    raise ValueError("[estimator] modes: the array is not closed")
