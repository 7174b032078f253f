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

Pass the times of :func:`read_measurement_file` on as ``Pipeline(..., times=times)``.

What the readers accept and refuse — every error names the file, and the line
and column or the array where it applies — is tabulated in ``docs/sensors.md``
(*Measurement files*): missing files, directories, suffixes other than ``.csv``
/ ``.npz``, text that is not UTF-8, malformed headers and rows, ``inf`` cells,
steps beyond :data:`MAX_STEP`, files beyond :data:`MAX_BYTES` (checked before
allocating), and NPZ archives that are corrupt or hold Python objects (read with
``allow_pickle=False``, headers checked before any data is loaded).  Blank CSV
lines are skipped.  The writers refuse what the readers could not read back.
"""

from __future__ import annotations

import csv
import math
import os
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import numpy as np

from hybridtrack.core.validation import as_float_array
from hybridtrack.io.csv_text import NUMBER, checked_path, read_csv
from hybridtrack.sdk.timestamps import check_times


class MeasurementFile(NamedTuple):
    """What a measurement file holds: sensor name → (steps, m), and the step times (steps,) in seconds or None."""

    measurements: dict[str, np.ndarray]
    times: np.ndarray | None


def _check(measurements: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Sensor name (a non-empty str) → float (steps, m) array, NaN allowed, inf refused; ≥ 1 step and component, equal steps."""
    if not isinstance(measurements, Mapping):
        raise TypeError(f"measurements: expected a mapping sensor name → (steps, m) array, got {type(measurements).__name__}")
    for name in measurements:
        if not isinstance(name, str) or not name:
            raise ValueError(f"measurements: sensor name {name!r} must be a non-empty str")
    arrays = {name: as_float_array(z, f"measurements[{name!r}]", (None, None), allow_nan=True) for name, z in measurements.items()}
    if not arrays:
        raise ValueError("measurements: no sensor")
    lengths = {a.shape[0] for a in arrays.values()}
    if len(lengths) != 1:
        raise ValueError(f"measurements: sensors have different numbers of steps {sorted(lengths)}")
    for name, a in arrays.items():
        if a.shape[0] == 0 or a.shape[1] == 0:
            raise ValueError(f"measurements[{name!r}]: shape {a.shape}; expected at least one step and one component")
    return arrays


def _csv_times(path, body) -> np.ndarray:
    """The ``time`` column (read-only), finite and strictly increasing; errors name the file line, the index and the value."""
    times: list[float] = []
    for index, (line, row) in enumerate(body):
        cell = row[0]
        if not NUMBER.fullmatch(cell) and not _NON_FINITE.fullmatch(cell):
            raise ValueError(f"{path}:{line}: time at index {index} is {cell!r}, not a number of seconds")
        t = float(cell)
        if not np.isfinite(t):
            raise ValueError(f"{path}:{line}: time at index {index} is {cell!r} (expected finite seconds)")
        if times and t <= times[-1]:
            what = "a duplicate of" if t == times[-1] else "earlier than"
            raise ValueError(
                f"{path}:{line}: time at index {index} ({t!r}) is {what} the time at index {index - 1} ({times[-1]!r});"
                " times must be strictly increasing"
            )
        times.append(t)
    return as_float_array(times, f"{path}: time", readonly=True)


#: the largest step number a ``step`` CSV may hold (its rows are stored densely, steps 0 … max)
MAX_STEP = 10_000_000
#: the most memory (bytes of float64) a file's dense measurement arrays may take; checked before allocating
MAX_BYTES = 2**30

_INTEGER = re.compile(r"[+-]?\d+", re.ASCII)
_NON_FINITE = re.compile(r"[+-]?(?:inf|infinity|nan)", re.ASCII | re.IGNORECASE)  # the words float() reads
_CSV_HINT = "expected a UTF-8 text CSV: a header 'step,<sensor>.<component>,…' (or 'time,…') and one row per step"


def _header(path: Path, line: int, header: list[str]) -> tuple[str, dict[str, list[int]]]:
    """The first column (``step``/``time``) and sensor → column indices; names the bad column."""
    first = header[0]
    if first not in ("step", "time"):
        raise ValueError(f"{path}:{line}: the first header column is {first!r}; expected 'step' (or 'time', in seconds)")
    if len(header) == 1:
        raise ValueError(f"{path}:{line}: no sensor columns after {first!r}; expected columns <sensor>.<component>")
    seen: dict[str, int] = {}
    sensors: dict[str, list[int]] = {}
    for column, name in enumerate(header[1:], start=1):
        if name in seen:
            raise ValueError(f"{path}:{line}: column {name!r} appears twice (columns {seen[name] + 1} and {column + 1})")
        seen[name] = column
        sensor, dot, component = name.rpartition(".")
        if not dot or not sensor or not component:
            raise ValueError(f"{path}:{line}: column {column + 1} {name!r} is not of the form <sensor>.<component>")
        sensors.setdefault(sensor, []).append(column)
    return first, sensors


def _cell(path: Path, line: int, column: str, cell: str) -> float:
    """A finite float, NaN for an empty/``nan`` cell; the error names the file, line, column and value."""
    try:  # fast path: a plain ASCII decimal number (float() alone would also take '1_0', 'inf', non-ASCII digits)
        value = float(cell)
        if math.isfinite(value) and cell.isascii() and "_" not in cell:
            return value
    except ValueError:
        pass
    if not cell or cell.lower().lstrip("+-") == "nan":
        return np.nan
    if not NUMBER.fullmatch(cell):
        if cell.lower().lstrip("+-") in ("inf", "infinity"):
            raise ValueError(f"{path}:{line}: column {column!r} holds {cell!r}; expected a finite number (an empty cell for no value)")
        hint = " (a decimal comma? use a decimal point)" if re.fullmatch(r"[+-]?\d+,\d+", cell) else ""
        raise ValueError(f"{path}:{line}: column {column!r} holds {cell!r}, not a number{hint}")
    # a plain decimal number the fast path did not return is not finite as a float (1e400)
    raise ValueError(f"{path}:{line}: column {column!r} holds {cell!r}, beyond the float range (expected a finite number)")


def _steps(path: Path, body) -> list[int]:
    """The ``step`` column: integers 0 … :data:`MAX_STEP`, none repeated (the error names both lines)."""
    lines: dict[int, int] = {}  # step → its line, in file order
    for line, row in body:
        cell = row[0]
        if not _INTEGER.fullmatch(cell):
            raise ValueError(f"{path}:{line}: step {cell!r} is not an integer")
        if cell.startswith("-") and cell.strip("-0"):
            raise ValueError(f"{path}:{line}: step {cell} is negative; expected 0 … {MAX_STEP}")
        if len(cell.lstrip("+0")) > len(str(MAX_STEP)) or int(cell) > MAX_STEP:
            raise ValueError(f"{path}:{line}: step {cell} exceeds the limit {MAX_STEP} (measurements_io.MAX_STEP)")
        step = int(cell)
        if step in lines:
            raise ValueError(f"{path}:{line}: step {step} is repeated (first at line {lines[step]})")
        lines[step] = line
    return list(lines)


def _read_csv(path: Path) -> MeasurementFile:
    header_line, header, body = read_csv(path, "a .csv measurement file", _CSV_HINT)
    first, sensors = _header(path, header_line, header)
    if not body:
        raise ValueError(f"{path}: header only, no data rows; {_CSV_HINT}")
    for line, row in body:
        if len(row) != len(header):
            raise ValueError(f"{path}:{line}: expected {len(header)} cells (as in the header), got {len(row)}")
    times = _csv_times(path, body) if first == "time" else None
    steps = _steps(path, body) if times is None else range(len(body))
    count = max(steps) + 1
    size = count * (len(header) - 1) * 8
    if size > MAX_BYTES:
        raise ValueError(
            f"{path}: steps 0 … {count - 1} × {len(header) - 1} columns need {size / 2**20:.0f} MiB, above the limit"
            f" {MAX_BYTES / 2**20:.0f} MiB (measurements_io.MAX_BYTES)"
        )
    values = {name: np.full((count, len(cols)), np.nan) for name, cols in sensors.items()}
    for step, (line, row) in zip(steps, body):
        for name, cols in sensors.items():
            cells = [_cell(path, line, header[c], row[c]) for c in cols]
            if np.all(np.isfinite(cells)):
                values[name][step] = cells
    return MeasurementFile(_check(values), times)


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
    times = None if times is None else check_times(times, "times", steps)
    if times is None and steps - 1 > MAX_STEP:
        raise ValueError(f"measurements: {steps} steps, above the step CSV limit {MAX_STEP} + 1 (measurements_io.MAX_STEP); write an NPZ")
    header = ["step" if times is None else "time"]
    for name, z in arrays.items():
        labels = [str(label) for label in (components or {}).get(name) or range(z.shape[1])]
        if len(labels) != z.shape[1] or len(set(labels)) != len(labels) or not all(labels) or any("." in x for x in labels):
            raise ValueError(
                f"components[{name!r}]: {labels!r}; expected {z.shape[1]} distinct non-empty labels without '.'"
                " (one per column of the array)"
            )
        header += [f"{name}.{label}" for label in labels]
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        for k, z in enumerate(np.hstack(list(arrays.values()))):  # z: step k of every sensor, in header order
            row = [str(k) if times is None else repr(float(times[k]))]
            writer.writerow(row + ["" if not np.isfinite(v) else repr(float(v)) for v in z])


_NPZ_HINT = "expected an NPZ archive (numpy.savez) of one (steps, m) numeric array per sensor"


def _read_npz(path: Path) -> MeasurementFile:
    with open(path, "rb") as handle:
        magic = handle.read(6)
    if not magic:
        raise ValueError(f"{path}: empty file; {_NPZ_HINT}")
    if magic.startswith(b"\x93NUMPY"):
        raise ValueError(f"{path}: a single .npy array, not an NPZ archive; {_NPZ_HINT}")
    if not magic.startswith((b"PK\x03\x04", b"PK\x05\x06")):
        raise ValueError(f"{path}: not an NPZ (zip) archive (it starts with {magic!r}); {_NPZ_HINT}")
    try:
        archive = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, EOFError) as error:
        raise ValueError(f"{path}: corrupt or truncated NPZ archive ({error}); {_NPZ_HINT}") from None

    def member(name: str, header: bool):
        try:
            with archive.open(name + ".npy") as stream:
                if header:
                    version = np.lib.format.read_magic(stream)
                    read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
                    return read(stream)
                return np.lib.format.read_array(stream, allow_pickle=False), stream.read()  # reaching the end: the CRC-32 check
        except Exception as error:  # zipfile, zlib and numpy raise several types for a damaged header or body
            raise ValueError(f"{path}: array {name!r} cannot be read, the archive is corrupt or truncated ({error})") from None

    with archive:
        headers: dict[str, tuple[tuple[int, ...], bool, np.dtype]] = {}
        for entry in archive.namelist():
            name = entry.removesuffix(".npy")
            if not entry.endswith(".npy"):
                raise ValueError(f"{path}: archive member {entry!r} is not a .npy array; {_NPZ_HINT}")
            if name in headers:
                raise ValueError(f"{path}: array {name!r} appears twice in the archive")
            headers[name] = member(name, header=True)
        if not headers:
            raise ValueError(f"{path}: the archive holds no arrays; {_NPZ_HINT}")
        is_time = "time" in headers and len(headers["time"][0]) == 1
        for name, (shape, _, dtype) in headers.items():
            if dtype.hasobject:
                raise ValueError(f"{path}: array {name!r} holds Python objects (a pickle), which are refused; {_NPZ_HINT}")
            if dtype.kind not in "iuf":  # signed/unsigned integers and floats; bool, complex, text, objects are refused
                raise ValueError(f"{path}: array {name!r} has dtype {dtype} ({dtype.kind!r} kind); expected float or integer numbers")
            if is_time and name == "time":
                continue
            if len(shape) != 2:
                extra = " (a time array must be named 'time')" if len(shape) == 1 else ""
                raise ValueError(f"{path}: array {name!r} has shape {shape}; expected 2-D (steps, m){extra}")
            if shape[0] == 0 or shape[1] == 0:
                raise ValueError(f"{path}: array {name!r} has shape {shape}; expected at least one step and one component")
        sensors = {name: shape for name, (shape, _, _) in headers.items() if not (is_time and name == "time")}
        if not sensors:
            raise ValueError(f"{path}: the archive holds only the 'time' array, no sensor; {_NPZ_HINT}")
        steps = {shape[0] for shape in sensors.values()}
        if len(steps) != 1:
            counts = ", ".join(f"{name} {shape[0]}" for name, shape in sensors.items())
            raise ValueError(f"{path}: the arrays have different numbers of steps ({counts}); expected one row per step in each")
        size = sum(8 * int(np.prod(shape)) for shape, _, _ in headers.values())
        if size > MAX_BYTES:
            raise ValueError(
                f"{path}: the arrays need {size / 2**20:.0f} MiB as float64, above the limit {MAX_BYTES / 2**20:.0f} MiB"
                " (measurements_io.MAX_BYTES)"
            )
        arrays = {}
        for name in headers:
            arrays[name], trailing = member(name, header=False)
            if trailing:
                raise ValueError(f"{path}: array {name!r} has {len(trailing)} bytes after its data; the archive is corrupt")
    times = arrays.pop("time") if is_time else None
    measurements = {name: as_float_array(z, f"{path}: array {name!r}", (None, None), allow_nan=True) for name, z in arrays.items()}
    if times is not None:
        times = check_times(times, f"{path}: 'time' array", next(iter(steps)))
    return MeasurementFile(measurements, times)


def _save_npz(path: str | Path, arrays: Mapping[str, np.ndarray]) -> None:
    """The archive ``np.savez(path, **arrays)`` writes (one uncompressed ``<name>.npy`` member per array, zip64, the
    suffix ``.npz`` added to a path without it), written member by member: ``np.savez`` takes the arrays as
    keywords, so a sensor named ``file`` or ``allow_pickle`` (its own parameters) could not be written there."""
    path = os.fspath(path)
    if not path.endswith(".npz"):
        path += ".npz"
    with zipfile.ZipFile(path, mode="w", compression=zipfile.ZIP_STORED, allowZip64=True) as archive:
        for name, array in arrays.items():
            with archive.open(name + ".npy", mode="w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(array), allow_pickle=False)


def write_npz(path: str | Path, measurements: Mapping[str, np.ndarray], *, times=None) -> None:
    """Write the NPZ layout; ``times`` (seconds, one per step, strictly increasing) is stored as the array ``time``.

    Every sensor name is an array name of its own, ``file`` included (read back by :func:`read_measurement_file`
    and ``np.load`` under the same name)."""
    arrays = _check(measurements)
    if times is not None:
        if "time" in arrays:
            raise ValueError("measurements: a sensor named 'time' cannot be written with times (the NPZ array 'time' holds them)")
        arrays = {"time": check_times(times, "times", next(iter(arrays.values())).shape[0]), **arrays}
    _save_npz(path, arrays)


def read_measurement_file(path: str | Path) -> MeasurementFile:
    """Read a ``.csv`` or ``.npz`` measurement file: ``(measurements, times)``, times None for a ``step`` file."""
    path = checked_path(path)
    if path.is_dir():
        checked_path(path, "a .csv or .npz measurement file")
    readers = {".csv": _read_csv, ".npz": _read_npz}
    suffix = path.suffix.lower()
    if suffix not in readers:
        raise ValueError(f"{path}: unknown measurement file type {suffix!r} (expected .csv or .npz)")
    return readers[suffix](checked_path(path, f"a {suffix} measurement file"))


def read_measurements(path: str | Path) -> dict[str, np.ndarray]:
    """Read a ``.csv`` or ``.npz`` measurement file's measurements (times, if any, are checked and dropped)."""
    return read_measurement_file(path).measurements
