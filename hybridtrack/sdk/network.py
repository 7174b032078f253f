"""A multisensor network of N fully connected nodes (SPEC §2; seed 000, eq. 4–5).

z_{i,k} = h_i(x_k) + v_{i,k}, v_i ~ N(0, R_i).  The centralized model stacks the
nodes: H = [H_1; …; H_N], R = blockdiag(R_1, …, R_N).  Node names must be
unique; a node's rows of the stacked z are ``network.slices[i]``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import attrs
import numpy as np
import scipy.linalg

from hybridtrack.core.interfaces import Sensor
from hybridtrack.core.validation import as_float_array


def _sensors(value) -> tuple[Sensor, ...]:
    value = (value,) if isinstance(value, Sensor) else tuple(value)
    if not value:
        raise ValueError("sensors: a network needs at least one sensor")
    for sensor in value:
        if not isinstance(sensor, Sensor):
            raise ValueError(f"sensors: {sensor!r} is not a hybridtrack Sensor")
    names = [sensor.name for sensor in value]
    duplicated = sorted({n for n in names if names.count(n) > 1})
    if duplicated:
        raise ValueError(f"sensors: node names must be unique, repeated: {duplicated}")
    return value


@attrs.frozen
class SensorNetwork:
    """N sensor nodes; stacks their measurements and models for the centralized filter."""

    sensors: tuple[Sensor, ...] = attrs.field(converter=_sensors)

    @property
    def names(self) -> list[str]:
        return [sensor.name for sensor in self.sensors]

    @property
    def dims(self) -> list[int]:
        return [sensor.measurement_dim for sensor in self.sensors]

    @property
    def measurement_dim(self) -> int:
        return sum(self.dims)

    @property
    def slices(self) -> list[slice]:
        ends = np.cumsum([0] + self.dims)
        return [slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:])]

    def noise_cov(self) -> np.ndarray:
        """R = blockdiag(R_1, …, R_N)."""
        return scipy.linalg.block_diag(*[sensor.noise_cov for sensor in self.sensors])

    def jacobian(self, x: np.ndarray, layout: Sequence[str]) -> np.ndarray:
        """H = [H_1; …; H_N] at x (..., n) → (..., Σm, n)."""
        return np.concatenate([sensor.jacobian(x, layout) for sensor in self.sensors], axis=-2)

    def stack(self, measurements: Mapping[str, np.ndarray]) -> np.ndarray:
        """Stack per-node arrays (steps, m_i) into (steps, Σm), checking names and shapes."""
        unknown = set(measurements) - set(self.names)
        if unknown:
            raise ValueError(f"measurements: unknown sensors {sorted(unknown)}; network nodes are {self.names}")
        missing = [name for name in self.names if name not in measurements]
        if missing:
            raise ValueError(f"measurements: no data for sensors {missing}")
        arrays = [
            as_float_array(measurements[s.name], f"measurements[{s.name!r}]", (None, s.measurement_dim), allow_nan=True)
            for s in self.sensors
        ]
        steps = {a.shape[0] for a in arrays}
        if len(steps) != 1:
            raise ValueError(f"measurements: sensors have different numbers of steps {sorted(steps)}")
        return np.concatenate(arrays, axis=1)

    def split(self, z: np.ndarray) -> dict[str, np.ndarray]:
        """The inverse of :meth:`stack` (works on (..., Σm))."""
        return {name: z[..., part] for name, part in zip(self.names, self.slices)}
