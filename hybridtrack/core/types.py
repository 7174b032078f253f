"""Frozen value types passed between components.

Arrays inside them are read-only float64 copies; equality compares arrays with
``np.array_equal``; array fields take no part in the hash (``hash=False``), so
equal objects hash equal and objects differing only in arrays collide.  A
wrong shape, NaN/inf or a non-symmetric / non-PSD covariance raises
``ValueError`` naming the field.
"""

from __future__ import annotations

import tomllib
from collections.abc import Iterable
from pathlib import Path

import attrs
import numpy as np

from hybridtrack.core.validation import readonly_array_field


@attrs.frozen
class Gaussian:
    """A Gaussian state N(mean, cov); mean of shape (n,), cov of shape (n, n), symmetric PSD."""

    mean: np.ndarray = readonly_array_field((None,))
    cov: np.ndarray = readonly_array_field(covariance=True)

    def __attrs_post_init__(self):
        n = self.mean.shape[0]
        if self.cov.shape != (n, n):
            raise ValueError(f"cov: expected shape ({n}, {n}) to match mean of shape ({n},), got {self.cov.shape}")

    @property
    def dim(self) -> int:
        return self.mean.shape[0]


@attrs.frozen
class Measurement:
    """One measurement vector ``z`` (shape (m,)) of sensor ``sensor`` at step ``step``."""

    sensor: str
    step: int = attrs.field(validator=attrs.validators.ge(0))
    z: np.ndarray = readonly_array_field((None,))


@attrs.frozen
class Decision:
    """A detector's decision event: at ``step`` detector ``detector`` (its label) chose ``mode``.

    ``statistic`` is the value that crossed the threshold (e.g. a log-likelihood
    ratio or a signal-function value), ``message`` a human-readable line;
    ``time`` the measurement time in seconds of that step, filled in by the
    pipeline or adaptive estimator that ran the detector (None until then).
    """

    step: int
    detector: str
    mode: str
    statistic: float = attrs.field(converter=float)
    message: str = ""
    time: float | None = None


def _positive_integer(instance, attribute, value):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value <= 0:
        raise ValueError(f"{attribute.name}: expected a positive integer, got {value!r}")


def _positive_or_none(instance, attribute, value):
    if value is not None and not (np.isfinite(value) and value > 0):
        raise ValueError(f"{attribute.name}: expected a positive finite number, got {value!r}")


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

    segments: tuple[Segment, ...] = attrs.field(
        converter=tuple,
        validator=attrs.validators.min_len(1),
    )

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
