"""Assemble one step's stacked measurement model for a bank (SPEC §2).

``update(state, z, sensors, layout)`` receives the stacked measurement of N
sensors, z = [z_1; …; z_N] of shape (Σ m_i,) (the same data for every filter)
or (M, Σ m_i) (one row per filter, e.g. Monte Carlo runs stacked as a bank).
A sensor whose rows hold NaN has no measurement at this step and is skipped;
all sensors skipped means prediction only.  The present sensors form the
centralized model H = [H_1; …; H_N], R = blockdiag(R_1, …, R_N).

Linear sensors whose H only picks state components ("selection" H, e.g. the
position sensor) are detected once and then handled by indexing instead of
matrix products.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import attrs
import numpy as np

from hybridtrack.interfaces import Sensor
from hybridtrack.validation import as_float_array


@attrs.frozen(eq=False)
class SensorModel:
    """What a filter needs about one sensor in a given state layout (cached)."""

    sensor: Sensor
    dim: int
    H: np.ndarray | None  # (m, n) for a linear sensor, None for a nonlinear one
    selection: tuple[int, ...] | None  # state indices when H selects components
    plain_residual: bool  # residual is z − ẑ (no angle wrapping)


@attrs.frozen(eq=False)
class MeasurementStep:
    """The present sensors of one step, stacked."""

    models: tuple[SensorModel, ...]
    z: np.ndarray  # (1 or M, m) present rows
    R: np.ndarray  # (m, m) or (M, m, m)
    blocks: tuple[slice, ...]  # each present sensor's rows within z
    H: np.ndarray | None  # (m, n) when every present sensor is linear
    selection: tuple[int, ...] | None  # when every present sensor selects components
    plain_residual: bool
    R_diagonal: bool = False  # R has no off-diagonal entries

    @property
    def dim(self) -> int:
        return self.z.shape[-1]

    def with_z(self, z: np.ndarray) -> MeasurementStep:
        """The same model with new measurement rows (the cached-structure path of :meth:`MeasurementAssembler.assemble`)."""
        return MeasurementStep(self.models, z, self.R, self.blocks, self.H, self.selection, self.plain_residual, self.R_diagonal)

    def predicted(self, x: np.ndarray, layout: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """ẑ = h(x⁻) (M, m) and H = ∂h/∂x at x⁻ ((m, n) linear, (M, m, n) otherwise)."""
        if self.selection is not None:
            return x[:, selection_index(self.selection)], self.H
        if self.H is not None:
            return x @ self.H.T, self.H
        z_pred = np.concatenate([model.sensor.measure(x, layout) if model.H is None else x @ model.H.T for model in self.models], axis=-1)
        H = np.concatenate(
            [
                model.sensor.jacobian(x, layout) if model.H is None else np.broadcast_to(model.H, (x.shape[0],) + model.H.shape)
                for model in self.models
            ],
            axis=-2,
        )
        return z_pred, H

    def residual(self, z_pred: np.ndarray) -> np.ndarray:
        """ν = z − ẑ, each sensor's block through its own ``residual`` (angle wrapping)."""
        if self.plain_residual:
            return self.z - z_pred
        z = np.broadcast_to(self.z, z_pred.shape)
        return np.concatenate([m.sensor.residual(z[..., b], z_pred[..., b]) for m, b in zip(self.models, self.blocks)], axis=-1)


@lru_cache(maxsize=256)
def selection_index(selection: tuple[int, ...]) -> slice | list[int]:
    """The state indices a selection H picks, as a slice when they are evenly spaced (a view instead of a gather)."""
    idx = [int(i) for i in selection]
    if len(idx) == 1:
        return slice(idx[0], idx[0] + 1)
    step = idx[1] - idx[0]
    if step > 0 and all(b - a == step for a, b in zip(idx, idx[1:])):
        return slice(idx[0], idx[-1] + 1, step)
    return idx


def block_diagonal(blocks: Sequence[np.ndarray]) -> np.ndarray:
    """blockdiag of (m_i, m_i) or (M, m_i, m_i) blocks."""
    lead = np.broadcast_shapes(*[b.shape[:-2] for b in blocks])
    m = sum(b.shape[-1] for b in blocks)
    out = np.zeros(lead + (m, m))
    i = 0
    for b in blocks:
        k = b.shape[-1]
        out[..., i : i + k, i : i + k] = b
        i += k
    return out


class MeasurementAssembler:
    """Caches each sensor's model per layout and splits z by sensor."""

    def __init__(self):
        self._cache: dict = {}
        self._template: tuple | None = None

    def sensor_model(self, sensor: Sensor, layout: tuple[str, ...]) -> SensorModel:
        key = (id(sensor), layout)
        hit = self._cache.get(key)
        if hit is not None and hit.sensor is sensor:
            return hit
        if not isinstance(sensor, Sensor):
            raise ValueError(f"sensors: expected hybridtrack Sensor objects, got {type(sensor).__name__}")
        n = len(layout)
        dim = sensor.measurement_dim
        H = selection = None
        if sensor.linear:
            H = as_float_array(sensor.jacobian(np.zeros((1, n)), layout), f"jacobian of sensor {sensor.name!r}", (1, dim, n))[0].copy()
            H.setflags(write=False)
            rows = [np.flatnonzero(row) for row in H]
            if all(len(r) == 1 and H[i, r[0]] == 1.0 for i, r in enumerate(rows)):
                selection = tuple(int(r[0]) for r in rows)
        plain = type(sensor).residual is Sensor.residual
        model = SensorModel(sensor, dim, H, selection, plain)
        self._cache[key] = model
        return model

    def assemble(self, z, sensors: Sequence[Sensor], layout: Sequence[str], bank_size: int) -> MeasurementStep | None:
        """The present sensors' stacked model, or None when no sensor measured (prediction only).

        The common case — the same sensors as the previous call, every row
        finite, R independent of z — reuses the previous step's structure.
        """
        if isinstance(sensors, Sensor):
            sensors = (sensors,)
        layout = tuple(layout)
        z_array = np.asarray(z, dtype=np.float64) if isinstance(z, np.ndarray) else None
        template = self._template
        if (
            template is not None
            and z_array is not None
            and template[0] == (tuple(map(id, sensors)), layout, bank_size, z_array.shape)
            and np.isfinite(z_array).all()  # NaN or ±inf anywhere: the full path below decides (missing sensor or error)
        ):
            return template[1].with_z(z_array.reshape(-1, template[1].dim))
        step = self._assemble(z, sensors, layout, bank_size)
        if (
            step is not None
            and z_array is not None
            and len(step.models) == len(sensors)
            and all(_constant_noise(m.sensor) for m in step.models)
        ):
            self._template = ((tuple(map(id, sensors)), layout, bank_size, z_array.shape), step)
        return step

    def _assemble(self, z, sensors: Sequence[Sensor], layout: tuple[str, ...], bank_size: int) -> MeasurementStep | None:
        models = [self.sensor_model(s, layout) for s in sensors]
        total = sum(m.dim for m in models)
        z = as_float_array(z, "z", allow_nan=True)
        if z.shape not in ((total,), (bank_size, total)):
            raise ValueError(
                f"z: expected shape ({total},) or ({bank_size}, {total}) (the stacked measurement of {len(models)} sensor(s)), got {z.shape}"
            )
        z2 = z.reshape(-1, total)
        present, blocks, columns = [], [], []
        start = out = 0
        for model in models:
            rows = z2[:, start : start + model.dim]
            missing = np.isnan(rows).any(axis=1)
            if missing.any() and not missing.all():
                raise ValueError(
                    f"z: sensor {model.sensor.name!r} has NaN for some filters of the bank and not others; the missing pattern must be the same for the whole bank"
                )
            if not missing.any():
                present.append(model)
                blocks.append(slice(out, out + model.dim))
                columns.extend(range(start, start + model.dim))
                out += model.dim
            start += model.dim
        if not present:
            return None
        zp = z2[:, columns]
        R = block_diagonal([_noise(m.sensor, zp[:, b] if zp.shape[0] > 1 else zp[0, b]) for m, b in zip(present, blocks)])
        linear = all(m.H is not None for m in present)
        H = np.concatenate([m.H for m in present], axis=0) if linear else None
        selection = None
        if linear and all(m.selection is not None for m in present):
            selection = tuple(i for m in present for i in m.selection)
        plain = all(m.plain_residual for m in present)
        R_diagonal = not np.count_nonzero(R * (1.0 - np.eye(R.shape[-1])))
        return MeasurementStep(tuple(present), zp, R, tuple(blocks), H, selection, plain, R_diagonal)


def _constant_noise(sensor: Sensor) -> bool:
    """R does not depend on z (the sensor keeps the default ``measurement_noise``)."""
    method = getattr(type(sensor), "measurement_noise", None)
    return method is None or method is Sensor.measurement_noise


def _noise(sensor: Sensor, z: np.ndarray) -> np.ndarray:
    """R of ``sensor`` for the measurement z ((m,) or (M, m)); pseudo-measurement sensors depend on z."""
    noise = getattr(sensor, "measurement_noise", None)
    R = noise(z) if callable(noise) else sensor.noise_cov
    return np.asarray(R, dtype=float)
