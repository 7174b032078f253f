"""Colours and names of what a recording shows: one palette for every hypothesis, filter, mode and role,
and the legend names of each series (docs/recording.md).
"""

from __future__ import annotations

import colorsys
import hashlib
import re
from collections.abc import Sequence

import numpy as np

_FIXED_COLOURS = {
    "truth": (235, 235, 235),
    "measurements": (255, 196, 0),
    "clutter": (140, 140, 140),
    "observer": (0, 200, 255),
    "bearings": (110, 120, 170),
    "threshold": (160, 160, 160),
    "decision": (255, 70, 70),
}
#: hue (degrees) of each motion family; the radius sets a lightness step (and shifts the hue a little) within it
_FAMILY_HUES = {"straight": 215.0, "left_turn": 130.0, "right_turn": 5.0, "cv": 215.0, "ca": 275.0, "ct": 300.0}
_RADIUS_NAME = re.compile(r"(?P<family>[a-z_]+?)(?:_r(?P<radius>\d+(?:\.\d+)?))?")


def palette(name: str) -> tuple[int, int, int]:
    """The fixed RGB colour of a hypothesis, filter, mode or role ``name``: the same in every view and every run.

    Roles (``truth``, ``measurements``, ``clutter``, ``observer``, ``bearings``,
    ``threshold``, ``decision``) have fixed colours; a motion family (``straight``,
    ``left_turn``, ``right_turn``, ``cv``, ``ca``, ``ct``) a fixed hue, and its radius
    suffix ``_r<ρ>`` a lightness step (ρ = 1 … 10: light to dark, hue +2.5° per metre);
    any other name the hue given by the first 32 bits of its SHA-256 (outside 20°–70°, the measurements' amber).
    """
    if not isinstance(name, str):
        raise TypeError(f"name: expected a str, got {type(name).__name__}")
    if name in _FIXED_COLOURS:
        return _FIXED_COLOURS[name]
    match = _RADIUS_NAME.fullmatch(name)
    if match and match["family"] in _FAMILY_HUES:
        hue, lightness = _FAMILY_HUES[match["family"]], 0.55
        if match["radius"] is not None:
            step = (float(match["radius"]) - 1.0) % 10.0
            lightness, hue = 0.72 - 0.035 * step, hue + 2.5 * step
        rgb = colorsys.hls_to_rgb((hue % 360.0) / 360.0, lightness, 0.8)
    else:  # hues 20°–70° (the measurements' amber) are skipped: 310° of hue for the hash
        hue = 310.0 * int(hashlib.sha256(name.encode()).hexdigest()[:8], 16) / 2**32
        rgb = colorsys.hls_to_rgb(((hue + 50.0 if hue > 20.0 else hue) % 360.0) / 360.0, 0.6, 0.75)
    return tuple(round(255 * c) for c in rgb)


def is_hypothesis(entity: str) -> bool:
    """Whether a spatial entity is one hypothesis of a bank (``<root>/estimate/<name>/hypotheses/<h>[/…]``): drawn thin
    and unlabelled, so the fan of a bank's hypotheses does not hide the followed estimate."""
    parts = entity.strip("/").split("/")
    return len(parts) > 4 and parts[1] == "estimate" and parts[3] == "hypotheses"


def finite_runs(finite: np.ndarray) -> list[tuple[int, int]]:
    """The [start, stop) index ranges of the runs of True in a boolean vector (a path's pieces between NaN gaps)."""
    edges = np.diff(np.concatenate([[0], np.asarray(finite, dtype=np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def _shade(colour, i: int) -> tuple[int, int, int]:
    """Column i of a multi-column series: the colour mixed 30 % per column towards white."""
    f = min(0.3 * i, 0.8)
    return tuple(round(c + (255 - c) * f) for c in colour)


def spatial_style(entity: str) -> tuple[tuple[int, int, int], str]:
    """Colour and label of a spatial entity from its path: ``…/truth``, ``…/measurements/<sensor>``,
    ``…/clutter/<sensor>``, ``…/estimate/<name>[/…]`` (the palette colour of ``name``), ``…/estimate/<name>/hypotheses/<h>``
    (a bank's hypothesis: the colour of ``h``), ``…/observer``, ``…/bearings``."""
    parts = entity.strip("/").split("/")[1:] or [entity.strip("/")]
    role = parts[0]
    if role == "estimate" and len(parts) > 3 and parts[2] == "hypotheses":
        return palette(parts[3]), parts[3]
    if role == "estimate" and len(parts) > 1:
        return palette(parts[1]), parts[1]
    if role in ("truth", "measurements", "clutter", "observer", "bearings"):
        return palette(role), role if len(parts) == 1 else f"{role} {parts[1]}"
    return palette(parts[-1]), parts[-1]


#: the ``estimator/<f>/<series>`` entities of a mode per step, logged as one lane per mode (:func:`mode_lanes`)
MODE_SERIES = ("mode", "followed", "segment")

#: the line width (UI points) of each mode lane: thick enough that a mode held for a few steps shows
LANE_WIDTH = 4.0


def is_mode_series(entity: str) -> bool:
    """Whether a scalar entity is a mode per step (``estimator/<f>/mode``, ``…/followed`` or ``…/segment``), drawn as lanes."""
    parts = entity.strip("/").split("/")
    return len(parts) == 3 and parts[0] == "estimator" and parts[2] in MODE_SERIES


def mode_lanes(modes: np.ndarray, names: Sequence[str]) -> tuple[np.ndarray, list[str]]:
    """One lane per mode the run was in: values (K, L) and the L mode names, the mode of the most steps first (ties
    in the order of ``names``).

    Column i holds the lane number L − 1 − i at the steps in its mode and NaN elsewhere (rerun draws no line
    across NaN), so the legend lists the lanes top down and, cut at the panel's edge in a large bank, still names
    the modes the run spent most steps in; −1 (no mode yet) is in no lane, a mode never entered has none.
    """
    modes = np.asarray(modes, dtype=np.int64)
    counts = np.array([np.count_nonzero(modes == j) for j in range(len(names))], dtype=np.int64)
    visited = [int(j) for j in np.argsort(-counts, kind="stable") if counts[j] > 0]
    values = np.full((modes.size, len(visited)), np.nan)
    for i, j in enumerate(visited):
        values[modes == j, i] = len(visited) - 1 - i
    return values, [str(names[j]) for j in visited]


def log_ratio_name(hypothesis: str, against: str | None = None) -> str:
    """The legend name of ln λ of ``hypothesis`` against ``against`` (None: the best of the other hypotheses in
    play, what ``sprt_pairwise`` reports): ``ln λ left_turn_r3 : straight``, ``ln λ left_turn_r3 : best other``."""
    return f"ln λ {hypothesis} : {'best other' if against is None else against}"


def series_style(entity: str, columns: int, names: Sequence[str] | None = None) -> tuple[list[str], list[tuple[int, int, int]]]:
    """Legend names and colours of the ``columns`` series of a scalar entity, from its path.

    ``detector/<d>/log_ratio/<h>`` → ``names`` (the hypothesis pairs, :func:`log_ratio_name`) or ``ln λ h``, in
    the colour of h; ``detector/<d>/log_ratio`` (one column per hypothesis) → ``ln λ <name>``;
    ``detector/<d>/upper``/``lower`` → A/B (signal functions: the ±3 bounds) in the threshold colour;
    ``estimator/<f>/mode``/``followed`` with ``names`` → the mode names in their colours (:func:`mode_lanes`);
    ``estimator/<f>/<quantity>[/<sub>]`` → f (or "f: sub") in the colour of f (of sub below ``mode_probability``);
    ``solver/<method>/…`` → method; ``world/measurements/<sensor>`` → sensor.  Several columns: ``names`` (or
    ``[i]``) after the name, the colour lightened per column.
    """
    parts = entity.strip("/").split("/")
    name, colour = parts[-1], palette(parts[-1])
    named = names is not None and len(names) == columns
    if parts[0] == "estimator" and len(parts) == 2 and named:  # estimator/nis_bounds
        return list(names), [palette("threshold")] * columns
    if is_mode_series(entity) and named:
        return list(names), [palette(n) for n in names]
    if parts[0] == "detector" and len(parts) == 3 and parts[2] == "log_ratio" and columns > 1 and named:
        return [f"ln λ {n}" for n in names], [palette(n) for n in names]
    if parts[0] == "detector" and len(parts) >= 3:
        signal = "signal" in parts[1]
        if parts[2] == "log_ratio" and len(parts) > 3:
            name, colour = f"ln λ {parts[3]}", palette(parts[3])
            if named:
                return list(names), [_shade(colour, i) for i in range(columns)]
        elif parts[-1] in ("upper", "lower") and len(parts) == 3:
            bound = {"upper": ("+3 bound", "A (upper)"), "lower": ("−3 bound", "B (lower)")}[parts[-1]]
            name, colour = bound[0] if signal else bound[1], palette("threshold")
        else:
            name, colour = "/".join(parts[2:]), palette(parts[1] if len(parts) == 3 else parts[-1])
    elif parts[0] == "estimator" and len(parts) >= 3:
        if len(parts) > 3:
            name, colour = f"{parts[1]}: {'/'.join(parts[3:])}", palette(parts[-1])
        else:
            name, colour = parts[1], palette(parts[1])
    elif parts[0] == "solver" and len(parts) >= 2:
        name, colour = parts[1], palette(parts[1])
    elif parts[:2] == ["world", "measurements"] and len(parts) > 2:
        name, colour = parts[2], palette("measurements")
    if columns == 1:
        return [name], [colour]
    labels = list(names) if names is not None else [f"[{i}]" for i in range(columns)]
    return [f"{name} {label}" for label in labels], [_shade(colour, i) for i in range(columns)]
