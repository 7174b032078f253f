"""Reading and writing measurements: sensor name → array (steps, m), NaN rows = no measurement,
optionally with the time of each step.

CSV layout (comma separated, one header row)::

    step,radar.x,radar.y,buoy.x
    0,0.12,-0.03,0.05
    1,0.09,0.21,
    3,0.31,0.40,0.28

* ``step`` (first column): the integer step of the row; steps may be missing
  (those rows become NaN) or unordered, but not repeated.
* every other column is ``<sensor>.<component>``: the sensor name is what
  stands before the last dot; a sensor's columns keep their order (the order
  of its z vector).
* an empty cell (or ``nan``) means no value; a sensor whose cells are not all
  present at a step has no measurement at that step (its whole row is NaN).

Time-stamped CSV: the first column is ``time`` (seconds) instead of ``step``::

    time,radar.x,radar.y
    0.0,0.12,-0.03
    0.35,0.09,0.21
    2.1,,

  row k (in file order) is step k at time t_k; times must be finite and
  strictly increasing down the file (a row with empty cells is a step without
  a measurement).

NPZ layout: one array per sensor, named by the sensor, shape (steps, m), plus
optionally a 1-D array ``time`` (steps,) of the step times in seconds (a 2-D
array named ``time`` is still read as a sensor).

:func:`read_measurement_file` returns both, ``(measurements, times or None)``;
:func:`read_measurements` returns the measurements only.  Bad times (NaN,
infinite, repeated, decreasing) raise a ValueError naming the file, the row or
index and the value.  Pass the times on as ``Pipeline(..., times=times)``.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import numpy as np

from hybridtrack.timestamps import check_times
from hybridtrack.validation import as_float_array


class MeasurementFile(NamedTuple):
    """What a measurement file holds: sensor name → (steps, m), and the step times (steps,) in seconds or None."""

    measurements: dict[str, np.ndarray]
    times: np.ndarray | None


def _check(measurements: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    arrays = {name: as_float_array(z, f"measurements[{name!r}]", (None, None), allow_nan=True) for name, z in measurements.items()}
    if not arrays:
        raise ValueError("measurements: no sensor")
    lengths = {a.shape[0] for a in arrays.values()}
    if len(lengths) != 1:
        raise ValueError(f"measurements: sensors have different numbers of steps {sorted(lengths)}")
    return arrays


def _check_times(times, steps: int, name: str) -> np.ndarray | None:
    return None if times is None else check_times(times, name, steps)


def _csv_times(path, body) -> list[float]:
    """The ``time`` column, finite and strictly increasing; errors name the file line, the index and the value."""
    times: list[float] = []
    for index, (line, row) in enumerate(body):
        cell = row[0].strip()
        try:
            t = float(cell)
        except ValueError:
            raise ValueError(f"{path}:{line}: time at index {index} is {cell!r}, not a number of seconds") from None
        if not np.isfinite(t):
            raise ValueError(f"{path}:{line}: time at index {index} is {cell!r} (expected finite seconds)")
        if times and t <= times[-1]:
            what = "a duplicate of" if t == times[-1] else "earlier than"
            raise ValueError(
                f"{path}:{line}: time at index {index} ({t!r}) is {what} the time at index {index - 1} ({times[-1]!r});"
                " times must be strictly increasing"
            )
        times.append(t)
    return times


def _read_csv(path: str | Path) -> MeasurementFile:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    first = rows[0][0].strip() if rows and rows[0] else ""
    if first not in ("step", "time"):
        raise ValueError(f"{path}: the first header column must be 'step' (or 'time', in seconds)")
    header = [h.strip() for h in rows[0]]
    sensors: dict[str, list[int]] = {}
    for column, name in enumerate(header[1:], start=1):
        sensor, dot, _ = name.rpartition(".")
        if not dot or not sensor:
            raise ValueError(f"{path}: column {name!r} is not of the form <sensor>.<component>")
        sensors.setdefault(sensor, []).append(column)
    body = [(line, row) for line, row in enumerate(rows[1:], start=2) if any(cell.strip() for cell in row)]
    for line, row in body:
        if len(row) != len(header):
            raise ValueError(f"{path}:{line}: expected {len(header)} cells, got {len(row)}")
    times = None
    if first == "time":
        times = np.array(_csv_times(path, body), dtype=np.float64)
        steps = list(range(len(body)))
    else:
        steps = []
        for line, row in body:
            try:
                steps.append(int(row[0]))
            except ValueError:
                raise ValueError(f"{path}:{line}: step {row[0]!r} is not an integer") from None
        if len(set(steps)) != len(steps):
            raise ValueError(f"{path}: repeated steps")
        if any(s < 0 for s in steps):
            raise ValueError(f"{path}: negative step")
    count = max(steps) + 1 if steps else 0
    out = {name: np.full((count, len(cols)), np.nan) for name, cols in sensors.items()}
    for step, (line, row) in zip(steps, body):
        for name, cols in sensors.items():
            cells = [row[c].strip() for c in cols]
            try:
                values = [float(c) if c else np.nan for c in cells]
            except ValueError:
                raise ValueError(f"{path}:{line}: non-numeric value among {cells}") from None
            if np.all(np.isfinite(values)):
                out[name][step] = values
    if times is not None:
        times.setflags(write=False)
    return MeasurementFile(_check(out), times)


def read_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Read the CSV layout above (``step`` or ``time`` first column); the times are dropped — see :func:`read_measurement_file`."""
    return _read_csv(path).measurements


def write_csv(
    path: str | Path,
    measurements: Mapping[str, np.ndarray],
    components: Mapping[str, list[str]] | None = None,
    *,
    times=None,
) -> None:
    """Write the CSV layout; ``components`` names each sensor's columns (default 0, 1, …).

    With ``times`` (seconds, one per step, strictly increasing) the first column
    is ``time`` instead of ``step``; values are written exactly (``repr``).
    """
    arrays = _check(measurements)
    steps = next(iter(arrays.values())).shape[0]
    times = _check_times(times, steps, "times")
    components = components or {}
    header = ["step" if times is None else "time"]
    for name, z in arrays.items():
        labels = components.get(name) or [str(i) for i in range(z.shape[1])]
        header += [f"{name}.{label}" for label in labels]
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        for k in range(steps):
            row = [str(k) if times is None else repr(float(times[k]))]
            for z in arrays.values():
                row += ["" if not np.isfinite(v) else repr(float(v)) for v in z[k]]
            writer.writerow(row)


def _read_npz(path: str | Path) -> MeasurementFile:
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    times = arrays.pop("time") if "time" in arrays and np.ndim(arrays["time"]) == 1 else None
    measurements = _check(arrays)
    steps = next(iter(measurements.values())).shape[0]
    return MeasurementFile(measurements, _check_times(times, steps, f"{path}: 'time' array"))


def read_npz(path: str | Path) -> dict[str, np.ndarray]:
    """Read the NPZ layout (one (steps, m) array per sensor); a 1-D ``time`` array is checked and dropped — see
    :func:`read_measurement_file`."""
    return _read_npz(path).measurements


def write_npz(path: str | Path, measurements: Mapping[str, np.ndarray], *, times=None) -> None:
    """Write the NPZ layout; ``times`` (seconds, one per step, strictly increasing) is stored as the array ``time``."""
    arrays = _check(measurements)
    if times is None:
        np.savez(path, **arrays)
        return
    if "time" in arrays:
        raise ValueError("measurements: a sensor named 'time' cannot be written with times (the NPZ array 'time' holds them)")
    steps = next(iter(arrays.values())).shape[0]
    np.savez(path, time=_check_times(times, steps, "times"), **arrays)


def read_measurement_file(path: str | Path) -> MeasurementFile:
    """Read a ``.csv`` or ``.npz`` measurement file: ``(measurements, times)``, times None for a ``step`` file."""
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        return _read_csv(path)
    if suffix == ".npz":
        return _read_npz(path)
    raise ValueError(f"{path}: unknown measurement file type {suffix!r} (expected .csv or .npz)")


def read_measurements(path: str | Path) -> dict[str, np.ndarray]:
    """Read a ``.csv`` or ``.npz`` measurement file's measurements (times, if any, are checked and dropped)."""
    return read_measurement_file(path).measurements
