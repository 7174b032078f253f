"""Assemble one step's stacked measurement model for a bank (SPEC §2).

``update(state, z, sensors, layout)`` receives the stacked measurement z = [z_1; …; z_N] of N sensors, shape
(Σ m_i,) or (M, Σ m_i); the present rows form the centralized model H = [H_1; …; H_N], R = blockdiag(R_1, …, R_N).
Missing components (NaN, one pattern for the whole bank), the R(z) of pseudo-measurement sensors and the magnitude
limit ``FILTER_MAGNITUDE_LIMIT`` behave as ``docs/estimators.md`` ("Measurements", "Numerics") states.  Angle
wrapping stays per component: ``residual`` is called on full-width arrays (the missing entries of z and ẑ both 0)
and the present columns are kept.  Linear sensors whose H only picks state components ("selection" H, e.g. the
position sensor) are detected once and then handled by indexing instead of matrix products.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import attrs
import numpy as np

from hybridtrack.core.interfaces import Sensor
from hybridtrack.core.validation import FILTER_MAGNITUDE_LIMIT, as_float_array, check_magnitude


@attrs.frozen(eq=False)
class SensorModel:
    """What a filter needs about one sensor in a given state layout (cached)."""

    sensor: Sensor
    dim: int
    H: np.ndarray | None  # (m, n) for a linear sensor, None for a nonlinear one
    selection: tuple[int, ...] | None  # state indices when H selects components
    plain_residual: bool  # residual is z − ẑ (no angle wrapping)
    rows: tuple[int, ...] | None = None  # the present components when some are missing (NaN); None: all

    def restricted(self, rows: tuple[int, ...]) -> SensorModel:
        """This sensor reduced to its components ``rows``: dim, H and selection keep those rows only."""
        H = selection = None
        if self.H is not None:
            H = self.H[list(rows)]
            H.setflags(write=False)
        if self.selection is not None:
            selection = tuple(self.selection[i] for i in rows)
        return SensorModel(self.sensor, len(rows), H, selection, self.plain_residual, rows)

    def measure(self, x: np.ndarray, layout: Sequence[str]) -> np.ndarray:
        """ẑ = h(x) (M, dim) of the present components."""
        if self.H is not None:
            return x @ self.H.T
        z_pred = self.sensor.measure(x, layout)
        return z_pred if self.rows is None else z_pred[..., list(self.rows)]

    def jacobian(self, x: np.ndarray, layout: Sequence[str]) -> np.ndarray:
        """∂h/∂x (M, dim, n) of the present components."""
        if self.H is not None:
            return np.broadcast_to(self.H, (x.shape[0],) + self.H.shape)
        H = self.sensor.jacobian(x, layout)
        return H if self.rows is None else H[..., list(self.rows), :]

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        """ν (…, dim) through the sensor's ``residual``; with missing components it is called on the
        full-width arrays (missing entries of z and ẑ both 0) and the present columns are kept."""
        if self.rows is None:
            return self.sensor.residual(z, z_pred)
        rows = list(self.rows)
        full_pred = np.zeros(z_pred.shape[:-1] + (self.sensor.measurement_dim,))
        full_pred[..., rows] = z_pred
        full_z = full_pred.copy()
        full_z[..., rows] = z
        return np.asarray(self.sensor.residual(full_z, full_pred))[..., rows]


@attrs.frozen(eq=False)
class MeasurementStep:
    """The present sensors of one step, stacked (a partially missing sensor reduced to its present components)."""

    models: tuple[SensorModel, ...]  # present sensors; ``rows`` set on those with missing components
    z: np.ndarray  # (1 or M, m) present components
    R: np.ndarray  # (m, m) or (M, m, m)
    blocks: tuple[slice, ...]  # each present sensor's components within z
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

    @property
    def noise_depends_on_state(self) -> bool:
        """Some present sensor's R depends on the state (:meth:`with_state_noise` completes R)."""
        return any(model.sensor.noise_depends_on_state for model in self.models)

    def with_state_noise(self, x: np.ndarray, layout: Sequence[str]) -> MeasurementStep:
        """The model with R (M, m, m) per filter: each state-dependent sensor's block plus its ``state_noise`` at the
        filter's state x (M, n) (the present components only)."""
        M, m = x.shape[0], self.dim
        R = np.array(np.broadcast_to(self.R, (M, m, m)))
        for model, block in zip(self.models, self.blocks):
            if model.sensor.noise_depends_on_state:
                extra = np.asarray(model.sensor.state_noise(x, layout), dtype=float)
                if model.rows is not None:
                    extra = extra[:, list(model.rows)][:, :, list(model.rows)]
                R[:, block, block] += extra
        return MeasurementStep(self.models, self.z, R, self.blocks, self.H, self.selection, self.plain_residual, False)

    def predicted(self, x: np.ndarray, layout: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """ẑ = h(x⁻) (M, m) and H = ∂h/∂x at x⁻ ((m, n) linear, (M, m, n) otherwise)."""
        if self.selection is not None:
            return x[:, selection_index(self.selection)], self.H
        if self.H is not None:
            return x @ self.H.T, self.H
        z_pred = np.concatenate([model.measure(x, layout) for model in self.models], axis=-1)
        H = np.concatenate([model.jacobian(x, layout) for model in self.models], axis=-2)
        return z_pred, H

    def residual(self, z_pred: np.ndarray) -> np.ndarray:
        """ν = z − ẑ, each sensor's block through its own ``residual`` (angle wrapping)."""
        if self.plain_residual:
            return self.z - z_pred
        z = np.broadcast_to(self.z, z_pred.shape)
        return np.concatenate([m.residual(z[..., b], z_pred[..., b]) for m, b in zip(self.models, self.blocks)], axis=-1)


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
        model = self._cache[key] = SensorModel(sensor, dim, H, selection, type(sensor).residual is Sensor.residual)
        return model

    def assemble(self, z, sensors: Sequence[Sensor], layout: Sequence[str], bank_size: int) -> MeasurementStep | None:
        """The present sensors' stacked model, or None when no sensor measured (prediction only).

        The common case — the same sensors as the previous call, every
        component finite, R independent of z — reuses the previous step's structure.
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
            and (np.abs(z_array) <= FILTER_MAGNITUDE_LIMIT).all()  # NaN, ±inf or a too large value: the full path below decides
        ):
            return template[1].with_z(z_array.reshape(-1, template[1].dim))
        step = self._assemble(z, sensors, layout, bank_size)
        if (
            step is not None
            and z_array is not None
            and len(step.models) == len(sensors)
            and all(m.rows is None for m in step.models)
            and all(type(m.sensor).measurement_noise is Sensor.measurement_noise for m in step.models)  # R independent of z
        ):
            self._template = ((tuple(map(id, sensors)), layout, bank_size, z_array.shape), step)
        return step

    def _assemble(self, z, sensors: Sequence[Sensor], layout: tuple[str, ...], bank_size: int) -> MeasurementStep | None:
        models = [self.sensor_model(s, layout) for s in sensors]
        total = sum(m.dim for m in models)
        z = check_magnitude(as_float_array(z, "z", allow_nan=True), "z", "measurement")
        if z.shape not in ((total,), (bank_size, total)):
            raise ValueError(
                f"z: expected shape ({total},) or ({bank_size}, {total}) (the stacked measurement of {len(models)} sensor(s)), got {z.shape}"
            )
        z2 = z.reshape(-1, total)
        nan = np.isnan(z2)
        present, blocks, columns = [], [], []
        start = out = 0
        for model in models:
            dim = model.dim
            block_nan = nan[:, start : start + dim]
            if block_nan.any():
                missing = block_nan.any(axis=0)  # per component
                mixed = np.flatnonzero(missing & ~block_nan.all(axis=0))
                if mixed.size:
                    raise ValueError(
                        f"z: sensor {model.sensor.name!r} has NaN in component(s) {mixed.tolist()} for some filters of the bank "
                        "and not others; the missing pattern must be the same for the whole bank"
                    )
                if missing.all():
                    start += dim
                    continue
                model = self._restricted(model, tuple(int(i) for i in np.flatnonzero(~missing)), layout)
            present.append(model)
            blocks.append(slice(out, out + model.dim))
            columns.extend(range(start, start + dim) if model.rows is None else [start + i for i in model.rows])
            out += model.dim
            start += dim
        if not present:
            return None
        zp = z2[:, columns]
        R = block_diagonal([_model_noise(m, zp[:, b] if zp.shape[0] > 1 else zp[0, b]) for m, b in zip(present, blocks)])
        linear = all(m.H is not None for m in present)
        H = np.concatenate([m.H for m in present], axis=0) if linear else None
        selection = None
        if linear and all(m.selection is not None for m in present):
            selection = tuple(i for m in present for i in m.selection)
        plain = all(m.plain_residual for m in present)
        R_diagonal = not np.count_nonzero(R * (1.0 - np.eye(R.shape[-1])))
        return MeasurementStep(tuple(present), zp, R, tuple(blocks), H, selection, plain, R_diagonal)

    def _restricted(self, model: SensorModel, rows: tuple[int, ...], layout: tuple[str, ...]) -> SensorModel:
        """``model`` reduced to the present components ``rows`` (cached like the full model)."""
        key = (id(model.sensor), layout, rows)
        hit = self._cache.get(key)
        if hit is None or hit.sensor is not model.sensor:
            hit = self._cache[key] = model.restricted(rows)
        return hit


def _model_noise(model: SensorModel, z: np.ndarray) -> np.ndarray:
    """R of the present components: the sensor's R(z) for a complete row z ((m,) or (M, m); pseudo-measurement
    sensors depend on z), else the rows/columns ``rows`` of ``noise_cov``."""
    if model.rows is None:
        return np.asarray(model.sensor.measurement_noise(z), dtype=float)
    rows = list(model.rows)
    return np.asarray(model.sensor.noise_cov, dtype=float)[np.ix_(rows, rows)]
