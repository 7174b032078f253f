"""Array checks shared by the value types, the interfaces and the plugins.

Every public entry point that takes an array runs it through one of these, so a
wrong shape, a NaN or a covariance that is not symmetric positive (semi)definite
fails early with a ``ValueError`` naming the argument and what was expected.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping, Sequence

import attrs
import numpy as np

#: relative tolerance for symmetry of a covariance
SYMMETRY_RTOL = 1e-9


def _shape_text(shape: Sequence[int | None]) -> str:
    return "(" + ", ".join("*" if s is None else str(s) for s in shape) + (",)" if len(shape) == 1 else ")")


def as_float_array(
    value, name: str, shape: Sequence[int | None] | None = None, *, allow_nan: bool = False, readonly: bool = False
) -> np.ndarray:
    """Return ``value`` as a float64 array, checking shape and finiteness.

    ``shape`` may hold ``None`` for a free axis.  With ``readonly`` the result is
    a private copy that cannot be written to (for frozen value objects).
    """
    try:
        array = np.array(value, dtype=np.float64, copy=True) if readonly else np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name}: expected a numeric array, got {type(value).__name__} ({error})") from None
    if shape is not None:
        if array.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, array.shape)):
            raise ValueError(f"{name}: expected shape {_shape_text(shape)}, got {array.shape}")
    bad = ~np.isfinite(array)
    if allow_nan:
        bad &= ~np.isnan(array)
    if bad.any():
        what = "inf" if allow_nan else "NaN or inf"
        raise ValueError(f"{name}: contains {what} at index {tuple(int(i) for i in np.argwhere(bad)[0])}")
    if readonly:
        array.setflags(write=False)
    return array


def check_covariance(value, name: str, dim: int | None = None, *, definite: bool = False, readonly: bool = False) -> np.ndarray:
    """Check a covariance (or a stack of them, shape ``(..., n, n)``).

    It must be finite, symmetric to :data:`SYMMETRY_RTOL` and positive
    semidefinite (positive definite with ``definite=True``, tested by Cholesky).
    """
    array = as_float_array(value, name, readonly=readonly)
    if array.ndim < 2 or array.shape[-1] != array.shape[-2] or (dim is not None and array.shape[-1] != dim):
        expected = f"({dim}, {dim})" if dim is not None else "(n, n)"
        raise ValueError(f"{name}: expected a square covariance of shape (..., {expected[1:-1]}), got {array.shape}")
    scale = max(float(np.abs(array).max(initial=0.0)), np.finfo(float).tiny)
    if np.abs(array - np.swapaxes(array, -1, -2)).max(initial=0.0) > SYMMETRY_RTOL * scale:
        raise ValueError(f"{name}: covariance is not symmetric")
    if definite:
        try:
            np.linalg.cholesky(array)
        except np.linalg.LinAlgError:
            raise ValueError(f"{name}: covariance is not positive definite") from None
    else:
        eigenvalues = np.linalg.eigvalsh(array)
        if (eigenvalues < -1e-10 * scale).any():
            raise ValueError(f"{name}: covariance is not positive semidefinite (eigenvalue {eigenvalues.min():.3g})")
    return array


#: read-only float64 arrays owning their data (so immutable) already checked as covariances, by id
_CHECKED_COVARIANCES: dict[int, weakref.ref] = {}


def _checked_covariance(value, name: str) -> np.ndarray:
    """check_covariance(value, readonly=True), once per immutable array: a model passing its own (immutable)
    Q to every transition it builds is checked the first time only; any other value is copied and checked."""
    if not (isinstance(value, np.ndarray) and value.dtype == np.float64 and not value.flags.writeable and value.base is None):
        return check_covariance(value, name, readonly=True)
    key = id(value)
    ref = _CHECKED_COVARIANCES.get(key)
    if ref is None or ref() is not value:
        check_covariance(value, name)
        _CHECKED_COVARIANCES[key] = weakref.ref(value, lambda _, key=key: _CHECKED_COVARIANCES.pop(key, None))
    return value


def readonly_array_field(shape: Sequence[int | None] | None = None, *, covariance: bool = False, allow_nan: bool = False, **kwargs):
    """An attrs field holding a read-only float64 array (a private copy, or the value itself when it is already
    an immutable float64 array), compared with ``np.array_equal``.

    Errors name the field.  ``covariance=True`` adds the symmetric-PSD check.
    """

    def convert(value, field):
        if covariance:
            return _checked_covariance(value, field.name)
        return as_float_array(value, field.name, shape, allow_nan=allow_nan, readonly=True)

    return attrs.field(converter=attrs.Converter(convert, takes_field=True), eq=attrs.cmp_using(eq=np.array_equal), hash=False, **kwargs)


def check_positive_int(value, name: str, minimum: int = 1, what: str | None = None) -> int:
    """``value`` as an int ≥ ``minimum`` (bools and floats refused), else a ValueError naming ``name``
    (and saying ``what`` the value is, when given)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        meaning = "" if what is None else f" ({what})"
        raise ValueError(f"{name}: expected an integer ≥ {minimum}{meaning}, got {value!r}")
    return int(value)


def check_positive(value, name: str, what: str | None = None) -> float:
    """``value`` as a positive finite float, else a ValueError naming ``name`` (and saying ``what`` the value
    is, when given)."""
    expected = "a positive finite number" if what is None else f"a finite number > 0 ({what})"
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {'a positive number' if what is None else expected}, got {value!r}") from None
    if not (np.isfinite(number) and number > 0):
        raise ValueError(f"{name}: expected {expected}, got {value!r}")
    return number


#: the largest magnitude a filter input (measurement, prior mean, prior covariance entry) may have:
#: the filters square and multiply such values (ν², P Hᵀ, x ᵀ I x, F P Fᵀ), and float64 overflows
#: above about 1.8e308, so values beyond about √1.8e308 ≈ 1.3e154 cannot be processed; 1e150
#: leaves room for the few further factors of a step.
FILTER_MAGNITUDE_LIMIT = 1e150


def check_magnitude(array: np.ndarray, name: str, what: str) -> np.ndarray:
    """``array`` (finite or NaN entries) if every finite entry has |value| ≤ :data:`FILTER_MAGNITUDE_LIMIT`.

    Otherwise a ValueError naming ``name``, the value and where it is, saying
    that ``what`` exceeds the float64 arithmetic of the filter.  NaN entries
    (missing data) are not compared.
    """
    with np.errstate(invalid="ignore"):
        big = np.abs(array) > FILTER_MAGNITUDE_LIMIT
    if big.any():
        index = tuple(int(i) for i in np.argwhere(big)[0])
        raise ValueError(
            f"{name}: {what} value {float(array[index]):.3g} at index {index} exceeds the float64 arithmetic of the filter "
            f"(its square or products overflow); expected |value| ≤ {FILTER_MAGNITUDE_LIMIT:.0e}"
        )
    return array


def _check_prior_arrays(mean, cov) -> None:
    """A TypeError naming the prior when ``initialize(mean, cov)`` is given a prior object (a Gaussian, a dict)
    in place of the two arrays."""
    for name, value in (("mean", mean), ("cov", cov)):
        if isinstance(value, Mapping) or (not isinstance(value, np.ndarray) and hasattr(value, "mean") and hasattr(value, "cov")):
            what = "a dict" if isinstance(value, Mapping) else f"a {type(value).__name__}"
            raise TypeError(
                f"prior: initialize(mean, cov) takes the bank's prior as two arrays, mean (M, n) and cov (M, n, n); got {what} as"
                f" {name}. From a hybridtrack.Gaussian g: initialize(g.mean[None], g.cov[None]); from arrays x (n,), P (n, n):"
                " initialize(x[None], P[None])"
            )


#: the largest prior standard deviation (state units: m, m/s) the pipeline and the algorithms take.  Beyond it
#: the covariance forms of the Kalman filter lose the measurement noise in S = H P Hᵀ + R (float64 keeps about
#: 16 digits: at a variance of 1e14, entries of R below about 0.02 vanish in the rounding of S), so a "diffuse"
#: prior of 1e16·I gives a singular S or, with one sensor, a silently wrong first update.
PRIOR_STD_LIMIT = 1e7


def check_prior_spread(cov: np.ndarray, name: str = "prior") -> np.ndarray:
    """``cov`` ((..., n, n) covariances) if every standard deviation √P_ii is ≤ :data:`PRIOR_STD_LIMIT`.

    Otherwise a ValueError naming ``name``, the largest standard deviation, its
    component index and the supported range (a diffuse prior: start from the
    first measurement instead, e.g. its position with the sensor's σ).
    """
    variances = np.diagonal(cov, axis1=-2, axis2=-1)
    big = variances > PRIOR_STD_LIMIT**2
    if big.any():
        index = tuple(int(i) for i in np.unravel_index(int(np.argmax(np.where(big, variances, -np.inf))), variances.shape))
        std = float(np.sqrt(variances[index]))
        raise ValueError(
            f"{name}: covariance standard deviations up to {PRIOR_STD_LIMIT:.0e} (m, m/s) are supported, got {std:.3g}"
            f" (variance {float(variances[index]):.3g} of state component {index[-1]}); beyond, the Kalman filter's"
            " S = H P Hᵀ + R loses the measurement noise R in float64 rounding. For an uninformative start give a prior"
            " from the first measurement (its position, the sensor's σ) and a velocity σ of the fastest expected speed"
        )
    return cov


#: the largest |entry| of a motion model's transition matrix F the filters take: the prediction F P Fᵀ
#: multiplies a covariance (entries up to FILTER_MAGNITUDE_LIMIT = 1e150) by F twice, and (1e75)² · 1e150
#: stays below the float64 range (about 1.8e308).
TRANSITION_MAGNITUDE_LIMIT = 1e75


def transition_excess(F, B, process_noise) -> str | None:
    """None if the entries of F (..., n, n), B (..., n) and the process noise G Q Gᵀ (..., n, n) are finite with
    |F| ≤ :data:`TRANSITION_MAGNITUDE_LIMIT` (1e75), |B| ≤ 1e225 (as large as F x may be for a prior mean within
    :data:`FILTER_MAGNITUDE_LIMIT`) and |G Q Gᵀ| ≤ :data:`FILTER_MAGNITUDE_LIMIT` (1e150, a covariance the filter
    takes, like the prior's); otherwise the first offending entry, e.g. ``"F[1, 0] = -1.28e+299 (expected finite,
    |value| ≤ 1e+75)"``, for a motion model to raise a ValueError naming the parameter that caused it."""
    limits = (TRANSITION_MAGNITUDE_LIMIT, 1e225, FILTER_MAGNITUDE_LIMIT)
    for what, array, limit in zip(("F", "B", "G Q Gᵀ"), (F, B, process_noise), limits):
        array = np.asarray(array, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            if array.size == 0 or np.abs(array).max() <= limit:  # a NaN maximum fails the comparison
                continue
            index = tuple(int(i) for i in np.argwhere(~(np.abs(array) <= limit))[0])
        return f"{what}[{', '.join(map(str, index))}] = {float(array[index]):.3g} (expected finite, |value| ≤ {limit:.0e})"
    return None


def check_prior(mean, cov) -> tuple[np.ndarray, np.ndarray]:
    """Validate a bank prior: mean (M, n), cov (M, n, n) symmetric positive definite, within the filters' arithmetic.

    Every entry of mean and cov must have |value| ≤ ``FILTER_MAGNITUDE_LIMIT``
    (1e150) and every variance be ≥ its inverse 1e-150 (the information forms
    invert P): beyond, the filters' products overflow float64.  Errors are
    ValueErrors naming the argument; a prior object (a Gaussian, a dict) given
    in place of the arrays is a TypeError naming the prior.
    """
    _check_prior_arrays(mean, cov)
    mean = as_float_array(mean, "mean", (None, None))
    M, n = mean.shape
    cov = as_float_array(cov, "cov", (M, n, n))
    check_magnitude(mean, "mean", "prior mean")
    check_magnitude(cov, "cov", "prior covariance")
    variances = np.diagonal(cov, axis1=-2, axis2=-1)
    tiny = (variances > 0) & (variances < 1.0 / FILTER_MAGNITUDE_LIMIT)
    if tiny.any():
        index = tuple(int(i) for i in np.argwhere(tiny)[0])
        raise ValueError(
            f"cov: prior variance {float(variances[index]):.3g} at index {index + index[-1:]} is too small for the float64 "
            f"arithmetic of the filter (its inverse, the information, overflows); expected variances ≥ {1.0 / FILTER_MAGNITUDE_LIMIT:.0e}"
        )
    check_covariance(cov, "cov", n, definite=True)
    return mean, cov


def check_prior_mixture(means, covs, weights) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validate a bank's prior mixtures Σ_c w_c N(means_c, covs_c): means (M, C, n), covs (M, C, n, n) each as
    :func:`check_prior` requires, weights (M, C) ≥ 0 with a positive sum per filter.

    Returns (means, covs, weights, totals (M,)) as float arrays; errors are ValueErrors naming the argument.
    """
    means = as_float_array(means, "means", (None, None, None))
    M, C, n = means.shape
    covs = as_float_array(covs, "covs", (M, C, n, n))
    weights = as_float_array(weights, "weights", (M, C))
    if (weights < 0).any():
        raise ValueError(f"weights: expected weights ≥ 0, got a minimum of {float(weights.min())!r}")
    total = weights.sum(axis=1)
    if not (total > 0).all():
        raise ValueError(f"weights: every filter needs a positive total weight, got sums {total.tolist()}")
    check_prior(means.reshape(M * C, n), covs.reshape(M * C, n, n))
    return means, covs, weights, total
