"""Reading and writing measurements: sensor name → array (steps, m), NaN rows = no measurement.

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

NPZ layout: one array per sensor, named by the sensor, shape (steps, m).
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from hybridtrack.validation import as_float_array


def _check(measurements: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    arrays = {name: as_float_array(z, f"measurements[{name!r}]", (None, None), allow_nan=True) for name, z in measurements.items()}
    if not arrays:
        raise ValueError("measurements: no sensor")
    lengths = {a.shape[0] for a in arrays.values()}
    if len(lengths) != 1:
        raise ValueError(f"measurements: sensors have different numbers of steps {sorted(lengths)}")
    return arrays


def read_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Read the CSV layout above."""
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    if not rows or not rows[0] or rows[0][0].strip() != "step":
        raise ValueError(f"{path}: the first header column must be 'step'")
    header = [h.strip() for h in rows[0]]
    sensors: dict[str, list[int]] = {}
    for column, name in enumerate(header[1:], start=1):
        sensor, dot, _ = name.rpartition(".")
        if not dot or not sensor:
            raise ValueError(f"{path}: column {name!r} is not of the form <sensor>.<component>")
        sensors.setdefault(sensor, []).append(column)
    body = [row for row in rows[1:] if any(cell.strip() for cell in row)]
    steps = []
    for line, row in enumerate(body, start=2):
        if len(row) != len(header):
            raise ValueError(f"{path}:{line}: expected {len(header)} cells, got {len(row)}")
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
    for line, (step, row) in enumerate(zip(steps, body), start=2):
        for name, cols in sensors.items():
            cells = [row[c].strip() for c in cols]
            try:
                values = [float(c) if c else np.nan for c in cells]
            except ValueError:
                raise ValueError(f"{path}:{line}: non-numeric value among {cells}") from None
            if np.all(np.isfinite(values)):
                out[name][step] = values
    return _check(out)


def write_csv(path: str | Path, measurements: Mapping[str, np.ndarray], components: Mapping[str, list[str]] | None = None) -> None:
    """Write the CSV layout; ``components`` names each sensor's columns (default 0, 1, …)."""
    arrays = _check(measurements)
    components = components or {}
    header = ["step"]
    for name, z in arrays.items():
        labels = components.get(name) or [str(i) for i in range(z.shape[1])]
        header += [f"{name}.{label}" for label in labels]
    steps = next(iter(arrays.values())).shape[0]
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        for k in range(steps):
            row = [str(k)]
            for z in arrays.values():
                row += ["" if not np.isfinite(v) else repr(float(v)) for v in z[k]]
            writer.writerow(row)


def read_npz(path: str | Path) -> dict[str, np.ndarray]:
    """Read the NPZ layout (one (steps, m) array per sensor)."""
    with np.load(path) as data:
        return _check({name: data[name] for name in data.files})


def write_npz(path: str | Path, measurements: Mapping[str, np.ndarray]) -> None:
    np.savez(path, **_check(measurements))


def read_measurements(path: str | Path) -> dict[str, np.ndarray]:
    """Read a ``.csv`` or ``.npz`` measurement file."""
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        return read_csv(path)
    if suffix == ".npz":
        return read_npz(path)
    raise ValueError(f"{path}: unknown measurement file type {suffix!r} (expected .csv or .npz)")
