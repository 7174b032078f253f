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


def series_style(entity: str, columns: int, names: Sequence[str] | None = None) -> tuple[list[str], list[tuple[int, int, int]]]:
    """Legend names and colours of the ``columns`` series of a scalar entity, from its path.

    ``detector/<d>/log_ratio/<h>`` → h in the colour of h; ``detector/<d>/upper``/``lower`` → A/B (signal
    functions: the ±3 bounds) in the threshold colour; ``estimator/<f>/<quantity>[/<sub>]`` → f (or "f: sub")
    in the colour of f (of sub below ``mode_probability``); ``solver/<method>/…`` → method;
    ``world/measurements/<sensor>`` → sensor.  Several columns: ``names`` (or ``[i]``) after the name,
    the colour lightened per column.
    """
    parts = entity.strip("/").split("/")
    name, colour = parts[-1], palette(parts[-1])
    if parts[0] == "estimator" and len(parts) == 2 and names is not None and len(names) == columns:  # estimator/nis_bounds
        return list(names), [palette("threshold")] * columns
    if parts[0] == "detector" and len(parts) >= 3:
        signal = "signal" in parts[1]
        if parts[2] == "log_ratio" and len(parts) > 3:
            name, colour = parts[3], palette(parts[3])
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
