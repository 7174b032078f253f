"""Contract checks: run a component through its interface with small generated inputs.

Each ``check_<kind>(component, ...)`` raises ``AssertionError`` with a message
naming the component and the broken rule, and returns nothing useful on
success (``check_solver`` returns the :class:`~hybridtrack.core.interfaces.Solution`
or ``None`` when it had no problem to solve).  The rules are the contracts in
the docstrings of :mod:`hybridtrack.core.interfaces`; the optional attributes they
read (``example_parameters``, ``example_layout``, ``example_innovations``,
``exact_kalman``, ``example_problem``) are described there too.

    from hybridtrack.testing import check_motion_model
    check_motion_model(MyModel(noise_cov=[[0.1, 0], [0, 0.1]]))
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from hybridtrack.core.algorithm import Algorithm
from hybridtrack.core.interfaces import (
    Detector,
    DetectorStep,
    Estimator,
    Innovation,
    LinearTransition,
    MotionModel,
    Sensor,
    Solution,
    Solver,
    TransitionBank,
)
from hybridtrack.core.kinds import KINDS
from hybridtrack.core.types import Decision, Gaussian
from hybridtrack.sdk import kalman_reference
from hybridtrack.sdk.linalg import symmetrize
from hybridtrack.testing._reference import (
    CV_LAYOUT,
    LinearPositionSensor,
    cv_transition,
    example_state,
    kalman_update,
    random_innovations,
)


def example_parameters(factory: Callable[..., Any]) -> dict:
    """The keyword arguments ``factory`` declares for building an example (``{}`` if none)."""
    params = getattr(factory, "example_parameters", None)
    if params is None:
        return {}
    if callable(params):
        params = params()
    if not isinstance(params, dict):
        raise TypeError(f"{_qualname(factory)}.example_parameters must be a dict (or return one), got {type(params).__name__}")
    return dict(params)


def build_example(factory: Callable[..., Any]) -> Any:
    """``factory(**example_parameters(factory))``, with the factory named if that fails."""
    params = example_parameters(factory)
    try:
        return factory(**params)
    except Exception as error:
        raise AssertionError(
            f"{_qualname(factory)}: cannot be built with example parameters {params!r} ({error!r});"
            " give the factory an `example_parameters` dict (see hybridtrack.core.interfaces)"
        ) from error


def _qualname(obj) -> str:
    return getattr(obj, "__qualname__", None) or type(obj).__qualname__


def _label(component, kind: str) -> str:
    registry_name = getattr(component, "registry_name" if kind == "sensor" else "name", None)
    return f"{kind} {registry_name!r} ({type(component).__qualname__})"


def _interface_label(component, kind: str, interface: type, attributes: Sequence[str] = ("name",), hint: str = "") -> str:
    """The label of ``component``, once it is an ``interface`` whose ``attributes`` are non-empty strings."""
    label = _label(component, kind)
    _require(isinstance(component, interface), label, f"is not a {interface.__module__}.{interface.__qualname__}{hint}")
    for attribute in attributes:
        value = getattr(component, attribute, None)
        _require(isinstance(value, str) and value, label, f"`{attribute}` must be a non-empty string, got {value!r}")
    return label


def _require(condition, label: str, message: str) -> None:
    if not condition:
        raise AssertionError(f"{label}: {message}")


def _array(value, label: str, what: str, shape: tuple | None = None, finite: bool = True) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise AssertionError(f"{label}: {what} is not a numeric array ({error})") from None
    if shape is not None:
        _require(array.shape == tuple(shape), label, f"{what} has shape {array.shape}, expected {tuple(shape)}")
    if finite:
        _require(np.isfinite(array).all(), label, f"{what} contains NaN or inf:\n{array}")
    return array


def _close(actual, expected, label: str, what: str, rtol: float = 1e-9, atol: float = 1e-9) -> None:
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    _require(actual.shape == expected.shape, label, f"{what}: shape {actual.shape}, expected {expected.shape}")
    if not np.allclose(actual, expected, rtol=rtol, atol=atol):
        worst = float(np.max(np.abs(actual - expected)))
        raise AssertionError(f"{label}: {what} differs (max abs difference {worst:.3g}):\n{actual}\nexpected\n{expected}")


def _symmetric_psd(matrix: np.ndarray, label: str, what: str, definite: bool) -> None:
    matrix = np.asarray(matrix, dtype=float)
    scale = max(float(np.abs(matrix).max(initial=0.0)), 1e-300)
    asym = float(np.abs(matrix - np.swapaxes(matrix, -1, -2)).max(initial=0.0))
    _require(asym <= 1e-9 * scale, label, f"{what} is not symmetric (max |A − Aᵀ| = {asym:.3g})")
    eigenvalues = np.linalg.eigvalsh(symmetrize(matrix))
    positive = (eigenvalues > 0) if definite else (eigenvalues >= -1e-10 * scale)
    kind = "definite" if definite else "semidefinite"
    _require(positive.all(), label, f"{what} is not positive {kind} (smallest eigenvalue {eigenvalues.min():.3g})")


def _numerical_jacobian(function: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    """Central differences at x (n,) → (out, n): J[:, i] = (f(x + h_i e_i) − f(x − h_i e_i)) / 2 h_i, h_i = 10⁻⁶ max(1, |x_i|)."""
    h = 1e-6 * np.maximum(1.0, np.abs(x))
    columns = [(np.asarray(function(x + step)) - np.asarray(function(x - step))) / (2 * h[i]) for i, step in enumerate(np.diag(h))]
    return np.stack(columns, axis=-1)


def check_motion_model(model: MotionModel, *, tau: float = 1.0, seed: int = 0) -> None:
    """Check a :class:`~hybridtrack.core.interfaces.MotionModel` against its contract.

    Name and layout; ``transition`` returns a :class:`LinearTransition` whose
    dimensions match the layout and ``noise_cov``, with Q and G Q Gᵀ symmetric
    PSD; F x_s + B = f(x_s); F matches finite differences of ``propagate``;
    ``propagate`` equals ``transition(...).apply`` for a linear model and is
    vectorized over leading axes; ``transition_bank`` with one Δt per row equals ``transition`` row by row; ``enter`` round-trips the model's own layout
    and accepts the 4-state layout; fifty noise-free steps stay finite.
    """
    label = _interface_label(model, "motion_model", MotionModel)
    layout = getattr(model, "layout", None)
    _require(isinstance(layout, tuple) and len(layout) > 0, label, f"`layout` must be a non-empty tuple, got {layout!r}")
    _require(all(isinstance(c, str) and c for c in layout), label, f"`layout` entries must be non-empty strings, got {layout!r}")
    _require(len(set(layout)) == len(layout), label, f"`layout` has repeated names: {layout!r}")
    n = len(layout)
    _require(model.state_dim == n, label, f"state_dim is {model.state_dim}, layout has {n} components")

    rng = np.random.default_rng(seed)
    x_s = example_state(layout, rng)
    T = model.transition(tau, x_s.copy())
    _require(isinstance(T, LinearTransition), label, f"transition() returned {type(T).__name__}, expected LinearTransition")
    _require(T.F.shape == (n, n), label, f"transition F has shape {T.F.shape}, expected ({n}, {n}) for layout {layout}")
    q = T.Q.shape[0]
    noise_cov = _array(getattr(model, "noise_cov", None), label, "noise_cov")
    _require(noise_cov.shape == (q, q), label, f"noise_cov has shape {noise_cov.shape}, transition Q has {T.Q.shape}")
    for what, matrix in (("F", T.F), ("B", T.B), ("G", T.G), ("Q", T.Q)):
        _array(matrix, label, f"transition {what}")
    _symmetric_psd(T.Q, label, "transition Q", definite=False)
    _symmetric_psd(T.process_noise, label, "G Q Gᵀ", definite=False)

    f_s = _array(model.propagate(x_s.copy(), tau, x_s.copy()), label, "propagate(x_s)", (n,))
    _close(
        T.F @ x_s + T.B, f_s, label, "F x_s + B (the linearization at x_s must pass through f(x_s))", atol=1e-9 * (1 + np.abs(f_s).max())
    )
    jac = _numerical_jacobian(lambda x: model.propagate(x, tau, x_s.copy()), x_s.copy())
    _close(T.F, jac, label, "transition F against finite differences of propagate", rtol=1e-5, atol=1e-6 * (1 + np.abs(T.F).max()))

    X = x_s + example_state(layout, rng, (5,)) * 0.1
    out = _array(model.propagate(X.copy(), tau, x_s.copy()), label, "propagate of a (5, n) stack", (5, n))
    rows = np.stack([model.propagate(row.copy(), tau, x_s.copy()) for row in X])
    _close(out, rows, label, "propagate of a (5, n) stack against row-by-row calls", atol=1e-9 * (1 + np.abs(rows).max()))
    out3 = _array(model.propagate(np.stack([X, X]), tau, x_s.copy()), label, "propagate of a (2, 5, n) stack", (2, 5, n))
    _close(out3[1], rows, label, "propagate of a (2, 5, n) stack", atol=1e-9 * (1 + np.abs(rows).max()))
    if getattr(model, "linear", True):
        _close(out, T.apply(X), label, "propagate against transition(...).apply for a linear model", atol=1e-9 * (1 + np.abs(out).max()))

    steps, states = tau * np.array([1.0, 0.5, 2.0]), x_s + example_state(layout, rng, (3,)) * 0.1
    bank = model.transition_bank(steps, states.copy())  # runs of irregular time stamps: one Δt per row
    for i, (t, x) in enumerate(zip(steps, states)):
        single = model.transition(float(t), x.copy())
        for what, got, expected in (("F", bank.F[i], single.F), ("B", bank.B[i], single.B), ("Q", bank.Q[i], single.process_noise)):
            _close(
                got,
                expected,
                label,
                f"transition_bank(one Δt per row) {what}[{i}] against transition",
                atol=1e-9 * (1 + np.abs(expected).max()),
            )

    _close(model.enter(x_s.copy(), layout), x_s, label, "enter(state, own layout) (must round-trip)")
    entered = _array(model.enter(example_state(CV_LAYOUT, rng), CV_LAYOUT), label, f"enter from layout {CV_LAYOUT}", (n,))
    _array(model.transition(0.5 * tau, entered).F, label, "transition F at a state entered from the 4-state layout")

    x = x_s.copy()
    for step in range(50):
        x = _array(model.propagate(x, tau, x_s.copy()), label, f"noise-free state after {step + 1} steps", (n,))


def check_sensor(sensor: Sensor, *, layout: Sequence[str] | None = None, seed: int = 0) -> None:
    """Check a :class:`~hybridtrack.core.interfaces.Sensor` against its contract.

    ``registry_name``/``name``; R symmetric positive definite of size ``measurement_dim``;
    ``measure``/``jacobian`` shapes over leading axes (and row-by-row equal);
    the Jacobian matches finite differences of ``measure`` (and, for a linear
    sensor, h(x) = H x with H the same everywhere); ``residual(z, z) == 0``;
    ``simulate`` is reproducible with a seeded Generator and its noise has
    covariance R (2000 draws, 25 % tolerance).
    """
    label = _interface_label(sensor, "sensor", Sensor, ("registry_name", "name"))
    R = _array(getattr(sensor, "noise_cov", None), label, "noise_cov")
    _require(R.ndim == 2 and R.shape[0] == R.shape[1], label, f"noise_cov must be square (m, m), got {R.shape}")
    m = R.shape[0]
    _require(sensor.measurement_dim == m, label, f"measurement_dim is {sensor.measurement_dim}, noise_cov is {R.shape}")
    _symmetric_psd(R, label, "noise_cov R", definite=True)

    layout = tuple(layout or getattr(sensor, "example_layout", CV_LAYOUT))
    n = len(layout)
    rng = np.random.default_rng(seed)
    X = example_state(layout, rng, (4,))
    z = _array(sensor.measure(X.copy(), layout), label, "measure of a (4, n) stack", (4, m))
    rows = np.stack([sensor.measure(row.copy(), layout) for row in X])
    _close(z, rows, label, "measure of a (4, n) stack against row-by-row calls")
    _array(sensor.measure(np.stack([X, X]), layout), label, "measure of a (2, 4, n) stack", (2, 4, m))
    J = _array(sensor.jacobian(X.copy(), layout), label, "jacobian of a (4, n) stack", (4, m, n))
    _array(sensor.jacobian(np.stack([X, X]), layout), label, "jacobian of a (2, 4, n) stack", (2, 4, m, n))
    for k, row in enumerate(X):
        numeric = _numerical_jacobian(lambda x: sensor.measure(x, layout), row.copy())
        atol = 1e-6 * (1e-3 + np.abs(J[k]).max())
        _close(J[k], numeric, label, f"jacobian at state {k} against finite differences of measure", rtol=1e-5, atol=atol)
    if getattr(sensor, "linear", True):
        _close(J, np.broadcast_to(J[0], J.shape), label, "jacobian of a linear sensor (must not depend on x)")
        _close(z, np.einsum("kij,kj->ki", J, X), label, "measure of a linear sensor against H x", atol=1e-9 * (1 + np.abs(z).max()))

    _close(sensor.residual(z, z.copy()), np.zeros_like(z), label, "residual(z, z)")
    first = _array(sensor.simulate(X.copy(), layout, np.random.default_rng(seed + 1)), label, "simulate of a (4, n) stack", (4, m))
    again = sensor.simulate(X.copy(), layout, np.random.default_rng(seed + 1))
    _close(again, first, label, "simulate with the same seed (must be reproducible)", rtol=0, atol=0)
    draws = 2000
    many = sensor.simulate(np.broadcast_to(X[0], (draws, n)).copy(), layout, np.random.default_rng(seed + 2))
    many = _array(many, label, "simulate of a (2000, n) stack", (draws, m))
    noise = _array(sensor.residual(many, np.broadcast_to(z[0], (draws, m))), label, "simulated noise")
    sample = np.cov(noise, rowvar=False).reshape(m, m)
    # R that goes with this measurement: noise_cov, or R(z) for pseudo-measurement sensors (Sensor.measurement_noise),
    # plus the part that depends on the state (Sensor.state_noise)
    R = _array(sensor.measurement_noise(z[0]), label, "measurement_noise(z)", (m, m))
    if getattr(sensor, "noise_depends_on_state", False):
        R = R + _array(sensor.state_noise(X[:1].copy(), layout), label, "state_noise(x)", (1, m, m))[0]
    error = np.linalg.norm(sample - R) / np.linalg.norm(R)
    _require(
        error < 0.25,
        label,
        f"simulated noise covariance\n{sample}\nis far from noise_cov R\n{R}\n(relative error {error:.2f} over {draws} draws)",
    )
    mean = noise.mean(axis=0)
    _require(np.all(np.abs(mean) < 5 * np.sqrt(np.diag(R) / draws) + 1e-12), label, f"simulated noise has mean {mean}, expected 0")


def _check_innovation(innovation, label: str, M: int, m: int, gaussian_loglik: bool = True) -> None:
    _require(isinstance(innovation, Innovation), label, f"update returned {type(innovation).__name__} as innovation, expected Innovation")
    nu = _array(innovation.nu, label, "innovation nu", (M, m))
    S = _array(innovation.S, label, "innovation S", (M, m, m))
    loglik = _array(innovation.loglik, label, "innovation loglik", (M,))
    nis = _array(innovation.nis, label, "innovation nis", (M,))
    if m == 0:
        _close(loglik, np.zeros(M), label, "loglik with no measurement")
        _close(nis, np.zeros(M), label, "nis with no measurement")
        return
    _symmetric_psd(S, label, "innovation S", definite=True)
    expected_nis = np.einsum("mi,mi->m", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    _close(nis, expected_nis, label, "nis against νᵀS⁻¹ν", rtol=1e-7, atol=1e-9)
    if gaussian_loglik:  # a sampling estimator's ℓ is its own estimate of ln p(z_k | z_1:k−1) (only finite, checked above)
        expected_loglik = -0.5 * (m * np.log(2 * np.pi) + np.linalg.slogdet(S)[1] + expected_nis)
        _close(loglik, expected_loglik, label, "loglik against −½(m ln 2π + ln det S + νᵀS⁻¹ν)", rtol=1e-7, atol=1e-9)


def check_estimator(estimator: Estimator, *, exact_kalman: bool | None = None, seed: int = 0) -> None:
    """Check an :class:`~hybridtrack.core.interfaces.Estimator` on a bank of M = 3 CV filters (the rules, and what
    ``exact_kalman`` and ``sampling`` change: docs/plugins.md, section 7).

    :class:`Innovation` fields ν (M, m), S (M, m, m), ℓ and NIS (M,); all-NaN z ⇒ prediction only (m = 0); NaN/inf
    or a wrong shape in the prior raises ValueError.  With ``exact_kalman`` (default: the estimator's attribute, else
    True) every mean, covariance and innovation is compared with :mod:`hybridtrack.sdk.kalman_reference`.
    """
    label = _interface_label(estimator, "estimator", Estimator)
    if exact_kalman is None:
        exact_kalman = bool(getattr(estimator, "exact_kalman", True))
    sampling = bool(getattr(estimator, "sampling", False))
    rng = np.random.default_rng(seed)
    M, n = 3, len(CV_LAYOUT)  # a bank of CV filters with different Q, two linear sensors (x, y) and (x)
    mean = example_state(CV_LAYOUT, rng, (M,))
    A = rng.normal(size=(M, n, n))
    cov = A @ np.swapaxes(A, -1, -2) + np.diag([25.0, 4.0, 25.0, 4.0])
    bank = TransitionBank.stack([cv_transition(1.0, q) for q in (0.01, 0.1, 1.0)])
    sensors = [
        LinearPositionSensor("contract_xy", ("x", "y"), [[4.0, 1.0], [1.0, 9.0]]),
        LinearPositionSensor("contract_x", ("x",), [[2.0]]),
    ]

    def compare(state, ref_mean, ref_cov, when: str) -> tuple[np.ndarray, np.ndarray]:
        x = _array(estimator.mean(state), label, f"mean {when}", (M, n)).copy()
        P = _array(estimator.covariance(state), label, f"covariance {when}", (M, n, n)).copy()
        _symmetric_psd(P, label, f"covariance {when}", definite=True)
        if exact_kalman:
            _close(x, ref_mean, label, f"mean {when} against the covariance-form KF", rtol=1e-7, atol=1e-7)
            _close(P, ref_cov, label, f"covariance {when} against the covariance-form KF", rtol=1e-7, atol=1e-7)
        return x, P

    truth = example_state(CV_LAYOUT, rng)
    if sampling:  # prior means drawn around the truth (x₀ − x̂₀ ~ N(0, P₀)): a z many σ from the prior collapses any sample
        mean = truth + np.einsum("mij,mj->mi", np.linalg.cholesky(cov), rng.standard_normal((M, n)))
    state = estimator.initialize(mean.copy(), cov.copy())
    compare(state, mean, cov, "after initialize")
    ref = (mean, cov)
    cases = (
        ("both sensors", np.ones(3, dtype=bool)),
        ("sensor contract_x missing (NaN rows)", np.array([True, True, False])),
        ("sensor contract_xy missing (NaN rows)", np.array([False, False, True])),
        ("no measurement (all NaN)", np.zeros(3, dtype=bool)),
    )
    for step, (case, present) in enumerate(cases * 2):
        state = estimator.predict(state, bank)
        ref = kalman_reference.predict(*ref, bank.F, bank.B, bank.Q)
        before = compare(state, *ref, f"after predict at step {step}")
        truth = cv_transition().apply(truth)
        z = np.concatenate([s.simulate(truth, CV_LAYOUT, rng) for s in sensors])
        z[~present] = np.nan
        state, innovation = estimator.update(state, z.copy(), sensors, CV_LAYOUT)
        m = int(present.sum())
        when = f"after update at step {step} ({case})"
        _check_innovation(innovation, f"{label} {when}", M, m, gaussian_loglik=not sampling)
        *ref, ref_innovation = kalman_update(*ref, z, sensors, CV_LAYOUT)
        after = compare(state, *ref, when)
        if m == 0:
            for what, value, predicted in zip(("mean", "covariance"), after, before):
                _close(value, predicted, label, f"{what} {when} (must equal the prediction)", rtol=1e-12, atol=1e-12)
        elif exact_kalman:
            for what, field in (("innovation nu", "nu"), ("innovation S", "S"), ("loglik", "loglik")):
                _close(getattr(innovation, field), getattr(ref_innovation, field), label, f"{what} {when}", rtol=1e-7, atol=1e-7)

    _check_bank_operations(estimator, label, state, bank, sensors, rng, sampling)
    bad_priors = (
        ("a NaN in the prior mean", np.where(np.arange(n) == 1, np.nan, mean), cov),
        ("an inf in the prior covariance", mean, np.where(np.eye(n, dtype=bool), np.inf, cov)),
        ("a covariance of the wrong shape", mean, cov[:, :-1, :-1]),
    )
    for what, bad_mean, bad_cov in bad_priors:
        try:
            estimator.initialize(np.array(bad_mean), np.array(bad_cov))
        except ValueError:
            continue
        except Exception as error:
            raise AssertionError(f"{label}: initialize with {what} raised {error!r}, expected ValueError") from error
        raise AssertionError(f"{label}: initialize with {what} did not raise ValueError")


def _check_bank_operations(estimator: Estimator, label: str, state, bank, sensors, rng, sampling: bool = False) -> None:
    """``take`` and ``concatenate`` select and join filters in the estimator's own form: the rows read back as
    the same rows of the whole bank, and a bank rebuilt from pieces steps exactly like the whole bank (``sampling``:
    except a freshly initialized filter, which draws new samples)."""
    mean = lambda state: np.asarray(estimator.mean(state), dtype=float)
    x, P = mean(state), np.asarray(estimator.covariance(state))
    rows = [2, 0, 0]
    taken = estimator.take(state, rows)
    _close(estimator.mean(taken), x[rows], label, "mean after take([2, 0, 0])", rtol=1e-12, atol=1e-12)
    _close(estimator.covariance(taken), P[rows], label, "covariance after take([2, 0, 0])", rtol=1e-12, atol=1e-12)
    joined = estimator.concatenate([estimator.take(state, [0]), estimator.take(state, [1, 2])])
    _close(estimator.mean(joined), x, label, "mean after concatenate of take([0]) and take([1, 2])", rtol=1e-12, atol=1e-12)
    fresh = estimator.concatenate([estimator.take(state, [0, 1]), estimator.initialize(x[2:], P[2:])])
    z = np.concatenate([s.simulate(x[0], CV_LAYOUT, rng) for s in sensors])
    step = lambda state: estimator.update(estimator.predict(state, bank), z.copy(), sensors, CV_LAYOUT)
    (whole, whole_innovation), (parts, parts_innovation), (mixed, _) = step(state), step(joined), step(fresh)
    kept = slice(0, 2) if sampling else slice(None)  # a sampling estimator's fresh filter 2 has new samples
    for what, other, rows in (
        ("a concatenated bank", parts, slice(None)),
        ("a bank joined with a freshly initialized filter", mixed, kept),
    ):
        _close(mean(other)[rows], mean(whole)[rows], label, f"mean of {what} after a step", rtol=1e-9, atol=1e-9)
    again, again_innovation = step(state)
    _close(estimator.mean(again), estimator.mean(whole), label, "mean of the same step taken twice", rtol=0, atol=0)
    _close(again_innovation.loglik, whole_innovation.loglik, label, "loglik of the same step taken twice", rtol=0, atol=0)
    _close(parts_innovation.loglik, whole_innovation.loglik, label, "loglik of a concatenated bank after a step", rtol=1e-9, atol=1e-9)


def _same_step(a: DetectorStep, b: DetectorStep) -> bool:
    """Same decision, and the same statistics and thresholds (NaN equal to NaN)."""
    for x, y in ((a.statistics, b.statistics), (a.thresholds, b.thresholds)):
        same = (np.array_equal(np.asarray(x[key], dtype=float), np.asarray(y[key], dtype=float), equal_nan=True) for key in x)
        if set(x) != set(y) or not all(same):
            return False
    return a.decision == b.decision


def check_detector(detector: Detector, innovations: Sequence[Innovation] | None = None, *, seed: int = 0) -> None:
    """Check a :class:`~hybridtrack.core.interfaces.Detector` over a sequence of innovations.

    ``innovations`` defaults to the detector's ``example_innovations(rng)`` or
    20 steps of a bank of M = 3, m = 2.  Every step returns a
    :class:`DetectorStep` whose statistics (a non-empty dict) and thresholds
    are numeric with no NaN; after ``reset()`` the same input gives the same
    outputs and decisions.
    """
    label = _interface_label(detector, "detector", Detector)
    if innovations is None:
        provider = getattr(detector, "example_innovations", None)
        innovations = provider(np.random.default_rng(seed)) if provider else random_innovations(np.random.default_rng(seed))
    innovations = list(innovations)
    _require(len(innovations) > 0, label, "no innovations to run on")

    def run() -> list[DetectorStep]:
        detector.reset()
        outputs = []
        for k, innovation in enumerate(innovations):
            out = detector.step(k, innovation)
            _require(isinstance(out, DetectorStep), label, f"step {k} returned {type(out).__name__}, expected DetectorStep")
            named = isinstance(out.statistics, dict) and out.statistics
            _require(named, label, f"step {k}: statistics must be a non-empty dict, got {out.statistics!r}")
            for kind, table in (("statistic", out.statistics), ("threshold", out.thresholds)):
                for key, value in table.items():
                    _require(isinstance(key, str) and key, label, f"step {k}: {kind} name {key!r} is not a non-empty string")
                    try:
                        array = np.asarray(value, dtype=float)
                    except (TypeError, ValueError):
                        raise AssertionError(f"{label}: step {k}: {kind} {key!r} is not numeric: {value!r}") from None
                    _require(not np.isnan(array).any(), label, f"step {k}: {kind} {key!r} is NaN: {value!r}")
            outputs.append(out)
        return outputs

    first, second = run(), run()
    for k, (a, b) in enumerate(zip(first, second)):
        _require(_same_step(a, b), label, f"step {k} differs after reset() on the same input:\n{a}\n{b}")


def check_solver(solver: Solver, problem: Any = None) -> Solution | None:
    """Check a :class:`~hybridtrack.core.interfaces.Solver` on ``problem`` (default: its ``example_problem()``).

    The answer is a :class:`Solution` with finite parameters θ (p,), a
    symmetric PSD covariance (p, p), a finite non-negative cost, non-negative
    counts and a bool ``converged``; solving again gives the same θ.  Without a
    problem only the name is checked and ``None`` is returned.
    """
    label = _interface_label(solver, "solver", Solver)
    if problem is None:
        provider = getattr(solver, "example_problem", None)
        if provider is None:
            return None
        problem = provider()
    solution = solver.solve(problem)
    _require(isinstance(solution, Solution), label, f"solve() returned {type(solution).__name__}, expected Solution")
    theta = _array(solution.parameters, label, "solution parameters")
    _require(theta.ndim == 1 and theta.size > 0, label, f"solution parameters must have shape (p,), got {theta.shape}")
    p = theta.shape[0]
    covariance = _array(solution.covariance, label, "solution covariance", (p, p))
    _symmetric_psd(covariance, label, "solution covariance", definite=False)
    _require(np.isfinite(solution.cost) and solution.cost >= 0, label, f"solution cost must be finite and ≥ 0, got {solution.cost!r}")
    for field in ("iterations", "evaluations"):
        value = getattr(solution, field)
        _require(isinstance(value, (int, np.integer)) and value >= 0, label, f"solution {field} must be an integer ≥ 0, got {value!r}")
    _require(isinstance(solution.converged, (bool, np.bool_)), label, f"solution converged must be a bool, got {solution.converged!r}")
    again = solver.solve(problem)
    _close(again.parameters, theta, label, "parameters of a second solve of the same problem", rtol=1e-12, atol=0)
    return solution


def _algorithm_example(factory: Callable[..., Any], tau: float) -> tuple[Any, dict]:
    """The algorithm as the checks build it (one position sensor ``contract_xy``, R = 4 I) and its ``example_run`` keywords."""
    sensor = LinearPositionSensor("contract_xy", ("x", "y"), 4.0 * np.eye(2))
    return factory(sensors=[sensor], tau=tau, **example_parameters(factory)), dict(getattr(factory, "example_run", None) or {})


def _straight_prior(layout: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """The straight target at t = 0: x = y = 0 (σ = 5 m), vx = 10, vy = 5 m/s (σ = 2 m/s), any other component 0 (σ = 1)."""
    start = {"x": 0.0, "y": 0.0, "vx": 10.0, "vy": 5.0}
    variances = {"x": 25.0, "y": 25.0, "vx": 4.0, "vy": 4.0}
    return np.array([start.get(c, 0.0) for c in layout]), np.diag([variances.get(c, 1.0) for c in layout])


def check_algorithm(factory: Callable[..., Any], *, steps: int = 20, tau: float = 1.0, seed: int = 0) -> Any:
    """Check an :class:`~hybridtrack.core.algorithm.Algorithm` factory on a target moving straight; return the result.

    Built as ``factory(sensors=[LinearPositionSensor("contract_xy")], tau=τ, **example_parameters(factory))``,
    R = 4 I (σ = 2 m), run with the factory's ``example_run`` keywords on K+1 = ``steps`` + 1 fixes of a
    constant-velocity target (10 m/s east, 5 m/s north); rules: docs/plugins.md, section 7.  Shapes: ``times``
    (K+1,), ``means`` (K+1, n), ``covs`` (K+1, n, n) (a fixed bank: (K+1, M, n), (K+1, M, n, n)); ``decisions``
    :class:`~hybridtrack.core.types.Decision` s; the estimate's mean position error below 5 σ.
    """
    instance, options = _algorithm_example(factory, tau)
    label = _interface_label(instance, "algorithm", Algorithm, hint=" (it needs a `run` method)")
    layout = tuple(getattr(instance, "layout", ()) or ())
    _require({"x", "y"} <= set(layout), label, f"`layout` must name the state components, with x and y; got {layout!r}")
    rng = np.random.default_rng(seed)
    t = tau * np.arange(steps + 1)
    true_xy = np.column_stack([10.0 * t, 5.0 * t])
    z = true_xy + 2.0 * rng.standard_normal((steps + 1, 2))
    prior = Gaussian(*_straight_prior(layout))

    def run(**times) -> Any:
        try:
            return instance.run({"contract_xy": z.copy()}, prior, **options, **times)
        except Exception as error:
            raise AssertionError(f"{label}: run on {steps + 1} steps of a straight track raised {error!r}") from error

    result = run()
    K1, n = steps + 1, len(layout)
    times = _array(getattr(result, "times", None), label, "result times")
    _close(times, t, label, "result times (default 0, τ, 2τ, …)", rtol=1e-12, atol=1e-12)
    means = _array(getattr(result, "means", None), label, "result means")
    shaped = means.shape == (K1, n) or (means.ndim == 3 and means.shape[::2] == (K1, n))  # (K+1, n) or a fixed bank's (K+1, M, n)
    _require(shaped, label, f"means has shape {means.shape}, expected ({K1}, {n})")
    covs = _array(getattr(result, "covs", None), label, "result covs", means.shape + (n,))
    _symmetric_psd(covs, label, "result covs", definite=False)
    decisions = tuple(getattr(result, "decisions", ()) or ())
    _require(all(isinstance(d, Decision) for d in decisions), label, f"decisions must be Decision objects, got {decisions!r}")
    steps_decided = [d.step for d in decisions]
    in_order = steps_decided == sorted(steps_decided) and all(0 <= k <= steps for k in steps_decided)
    _require(in_order, label, f"decision steps {steps_decided} not in step order within 0 … {steps}")
    for what, other in (("a run given the same times", run(times=t.copy())), ("a second run of the same instance", run())):
        _close(other.means, means, label, f"means of {what}", rtol=0, atol=0)
    offset = means[..., [layout.index("x"), layout.index("y")]] - (true_xy[:, None, :] if means.ndim == 3 else true_xy)
    error = float(np.mean(np.linalg.norm(offset, axis=-1)))
    _require(error < 10.0, label, f"the estimate does not follow a straight target: mean position error {error:.3g} m (σ = 2 m)")
    return result


def check_algorithm_batch(factory: Callable[..., Any], *, runs: int = 3, steps: int = 20, tau: float = 1.0, seed: int = 0) -> list:
    """R runs together equal R runs alone, to 1e-12: ``run_batch`` of an algorithm that has one against ``run``.

    Built as :func:`check_algorithm` builds it; the R runs of a straight
    target differ in their noise draws, their priors (shifted by up to 10 m)
    and their time stamps (irregular, Δt in [0.5 τ, 1.5 τ]), and the last run
    misses its fixes at two steps (NaN).  ``times``, ``means``, ``covs`` and
    ``mode`` of run r of the batch equal those of run r alone (relative 1e-12),
    and so do the decisions (step and mode).  Returns the batch's results
    ([] for an algorithm without ``run_batch``).
    """
    instance, options = _algorithm_example(factory, tau)
    if not callable(getattr(instance, "run_batch", None)):
        return []
    label = _label(instance, "algorithm")
    layout = tuple(instance.layout)
    rng = np.random.default_rng(seed)
    times = np.cumsum(np.concatenate([np.zeros((runs, 1)), tau * rng.uniform(0.5, 1.5, (runs, steps))], axis=1), axis=1)
    z = np.stack([np.column_stack([10.0 * t, 5.0 * t]) for t in times]) + 2.0 * rng.standard_normal((runs, steps + 1, 2))
    z[-1, [3, 11]] = np.nan
    mean, cov = _straight_prior(layout)
    means = np.tile(mean, (runs, 1))
    means[:, [layout.index("x"), layout.index("y")]] += rng.uniform(-10.0, 10.0, (runs, 2))
    covs = np.broadcast_to(cov, (runs,) + cov.shape)
    try:
        together = list(instance.run_batch({"contract_xy": z}, (means, covs.copy()), times=times, **options))
    except Exception as error:
        raise AssertionError(f"{label}: run_batch on {runs} runs raised {error!r}") from error
    _require(len(together) == runs, label, f"run_batch returned {len(together)} results for {runs} runs")
    for r, batched in enumerate(together):
        alone = instance.run({"contract_xy": z[r]}, Gaussian(means[r], covs[r]), times=times[r], **options)
        for field in ("times", "means", "covs", "mode"):
            a, b = getattr(batched, field, None), getattr(alone, field, None)
            if a is not None or b is not None:
                _close(a, b, label, f"run {r}: {field} of the batch vs the run alone", rtol=1e-12, atol=1e-12)
        decided = [[(d.step, d.mode) for d in getattr(result, "decisions", ())] for result in (batched, alone)]
        _require(decided[0] == decided[1], label, f"run {r}: decisions of the batch differ from the run alone")
    return together


_CHECKS: dict[str, Callable[..., Any]] = {kind: globals()[f"check_{kind}"] for kind in KINDS}


def check_component(kind: str, component: Any, **options) -> Any:
    """Run the check for ``kind`` (one of :data:`hybridtrack.core.kinds.KINDS`) on ``component`` (an algorithm's factory:
    the check builds the algorithm, :func:`check_algorithm`)."""
    try:
        check = _CHECKS[kind]
    except KeyError:
        raise ValueError(f"unknown component kind {kind!r}; kinds are {', '.join(KINDS)}") from None
    return check(component, **options)
