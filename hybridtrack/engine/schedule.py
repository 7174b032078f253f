"""The truth schedule of a simulation: segments of motion modes (SPEC §1; seed 001 Table 1).

A :class:`Schedule` is what :func:`hybridtrack.engine.simulate.simulate` follows
and what the filter told the modes (:mod:`hybridtrack.algorithms.known_modes`)
and Algorithm 1's known switching moments read; it is not part of any
component's contract, so it lives in the engine, not in :mod:`hybridtrack.core`.
"""

from __future__ import annotations

import tomllib
from collections.abc import Iterable
from pathlib import Path

import attrs
import numpy as np


def _positive_integer(instance, attribute, value):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value <= 0:
        raise ValueError(f"{attribute.name}: expected a positive integer, got {value!r}")


def _positive_or_none(instance, attribute, value):
    """None or a positive finite real number (a string, a list or a bool is refused, naming the field)."""
    if value is None:
        return
    if (
        isinstance(value, (bool, np.bool_))
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not (np.isfinite(value) and value > 0)
    ):
        raise ValueError(f"{attribute.name}: expected a positive finite number (metres), got {value!r}")


@attrs.frozen
class Segment:
    """One row of a schedule table: motion ``mode`` for ``steps`` steps.

    ``radius`` is the turn radius (turn modes only, metres); ``acceleration`` the
    (ax, ay) set when entering constant acceleration (default: zero, noise-driven).
    """

    mode: str = attrs.field(validator=attrs.validators.min_len(1))
    steps: int = attrs.field(validator=_positive_integer)
    radius: float | None = attrs.field(default=None, validator=_positive_or_none)
    acceleration: tuple[float, float] | None = attrs.field(
        default=None, converter=attrs.converters.optional(lambda a: tuple(float(v) for v in a))
    )

    @acceleration.validator
    def _check_acceleration(self, attribute, value):
        if value is not None and (len(value) != 2 or not np.all(np.isfinite(value))):
            raise ValueError(f"acceleration: expected two finite numbers (ax, ay), got {value!r}")

    def parameters(self) -> dict:
        """Keyword arguments for the motion-model factory of this segment."""
        return {"radius": self.radius} if self.radius is not None else {}


@attrs.frozen
class Schedule:
    """A hybrid trajectory's schedule: a sequence of :class:`Segment` rows."""

    segments: tuple[Segment, ...] = attrs.field(converter=tuple, validator=attrs.validators.min_len(1))

    @segments.validator
    def _check_segments(self, attribute, value):
        for i, segment in enumerate(value):
            if not isinstance(segment, Segment):
                raise TypeError(
                    f"segments: row {i} is a {type(segment).__name__}, expected Segment"
                    " (Schedule.from_rows builds segments from tuples or dicts)"
                )

    @classmethod
    def from_rows(cls, rows: Iterable) -> Schedule:
        """Build from (mode, steps[, radius]) tuples or dicts with the Segment fields."""
        segments = []
        for i, row in enumerate(rows):
            try:
                segments.append(Segment(**row) if isinstance(row, dict) else Segment(*row))
            except (TypeError, ValueError) as error:
                raise ValueError(f"schedule row {i}: {error}") from None
        return cls(segments)

    @classmethod
    def from_toml(cls, path: str | Path) -> Schedule:
        """Read ``[[segment]]`` tables (keys ``mode``, ``steps``, optional ``radius``, ``acceleration``)."""
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
        if "segment" not in data:
            raise ValueError(f"{path}: no [[segment]] tables")
        return cls.from_rows(data["segment"])

    @property
    def total_steps(self) -> int:
        return sum(segment.steps for segment in self.segments)

    def switch_steps(self) -> list[int]:
        """Step index at which each segment starts (the first is 0)."""
        return list(np.cumsum([0] + [s.steps for s in self.segments[:-1]]).astype(int))


#: Table 1 of seed 001 (L, R, S = left turn, right turn, straight; radii in metres).
SEED001_TABLE1 = Schedule.from_rows(
    [
        ("left_turn", 50, 3.0),
        ("right_turn", 75, 5.0),
        ("straight", 50),
        ("left_turn", 75, 3.0),
        ("straight", 50),
        ("left_turn", 60, 4.0),
    ]
)
