"""Near-perfect measurements (R = 1e-12·I) with a huge prior (P0 = 1e12·I): docs/estimators.md, "Ill-conditioned case".

The conventional update P⁺ = (I − K H) P⁻ (and its symmetrised variant) loses
positive definiteness and then fails (S not positive definite); Potter, Bierman
and the SRIF stay positive definite and agree with a Joseph-form reference
computed exactly in rational arithmetic.
"""

import functools
from fractions import Fraction

import numpy as np
import pytest
from _filters_support import LAYOUT, bank_of, position_sensor, simulate, straight

import hybridtrack as ht

STEPS = 100


def _case():
    rng = np.random.default_rng(0)
    tr = straight(tau=1.0, q=1e-6)
    sensor = position_sensor(np.eye(2) * 1e-12)
    X, Z = simulate(tr, [sensor], np.array([0.0, 1.0, 0.0, 1.0]), STEPS, rng)
    return tr, sensor, X[0], Z[0], np.zeros((1, 4)), np.eye(4)[None] * 1e12


@functools.cache
def _exact_covariances():
    tr, _, _, _, _, P0 = _case()
    return _reference_covariances(tr, P0, STEPS)


def _reference_covariances(tr, P0, steps):
    """The exact P⁺ sequence in rational arithmetic (fractions.Fraction), independent of the plugin code.

    Inputs are the exact binary values of the float data, so this is the true
    answer to the problem the filters are given.
    """
    n = 4
    F = [[Fraction(v) for v in row] for row in tr.F]
    Q = [[Fraction(v) for v in row] for row in tr.process_noise]
    r = Fraction(1e-12)
    P = [[Fraction(v) for v in row] for row in P0[0]]
    out = []
    for _ in range(steps):
        FP = [[sum(F[i][k] * P[k][j] for k in range(n)) for j in range(n)] for i in range(n)]
        P = [[sum(FP[i][k] * F[j][k] for k in range(n)) + Q[i][j] for j in range(n)] for i in range(n)]
        S = [[P[0][0] + r, P[0][2]], [P[2][0], P[2][2] + r]]
        det = S[0][0] * S[1][1] - S[0][1] * S[1][0]
        S_inv = [[S[1][1] / det, -S[0][1] / det], [-S[1][0] / det, S[0][0] / det]]
        PHt = [[P[i][0], P[i][2]] for i in range(n)]
        K = [[sum(PHt[i][a] * S_inv[a][b] for a in range(2)) for b in range(2)] for i in range(n)]
        P = [[P[i][j] - sum(K[i][a] * PHt[j][a] for a in range(2)) for j in range(n)] for i in range(n)]
        out.append(np.array([[float(v) for v in row] for row in P]))
    return out


def _run(est, tr, sensor, Z, x0, P0):
    state = est.initialize(x0, P0)
    bank = bank_of([tr])
    min_eig, asym, history = np.inf, 0.0, []
    for z in Z:
        state = est.predict(state, bank)
        state, _ = est.update(state, z, [sensor], LAYOUT)
        P = est.covariance(state)[0]
        asym = max(asym, np.abs(P - P.T).max() / np.abs(P).max())
        min_eig = min(min_eig, np.linalg.eigvalsh(0.5 * (P + P.T)).min())
        history.append((est.mean(state)[0], P))
    return min_eig, asym, history


def _covariance_run(est, tr, sensor, Z, x0, P0, reference):
    """(failed step or None, min eigenvalue of P⁺ so far, worst entry error relative to √(P_ii P_jj))."""
    state, bank, min_eig, worst = est.initialize(x0, P0), bank_of([tr]), np.inf, 0.0
    for k, z in enumerate(Z):
        try:
            state, _ = est.update(est.predict(state, bank), z, [sensor], LAYOUT)
        except np.linalg.LinAlgError:
            return k + 1, min_eig, worst
        P = est.covariance(state)[0]
        min_eig = min(min_eig, np.linalg.eigvalsh(0.5 * (P + P.T)).min())
        worst = max(worst, (np.abs(P - reference[k]) / np.sqrt(np.outer(np.diag(reference[k]), np.diag(reference[k])))).max())
    return None, min_eig, worst


def test_conventional_kf_fails():
    tr, sensor, _, Z, x0, P0 = _case()
    est = ht.load_plugins().registry.create("estimator", "kalman", form="conventional")
    failed, min_eig, _ = _covariance_run(est, tr, sensor, Z, x0, P0, _exact_covariances())
    assert failed is not None and failed < 10  # "innovation covariance S is not positive definite"
    assert min_eig < 0  # lost positive definiteness before failing


@pytest.mark.parametrize("structure", [True, False], ids=["axis_separable", "dense"])
@pytest.mark.parametrize("form", ["symmetric", "joseph"])
def test_covariance_forms_lose_definiteness(form, structure):
    """Even the symmetrised and Joseph updates lose positive definiteness here (P⁺ singular or indefinite)."""
    tr, sensor, _, Z, x0, P0 = _case()
    est = ht.load_plugins().registry.create("estimator", "kalman", form=form, structure=structure)
    failed, min_eig, worst = _covariance_run(est, tr, sensor, Z, x0, P0, _exact_covariances())
    assert failed is not None or (min_eig <= 0 and worst > 0.1)


@pytest.mark.parametrize("name", ["potter", "bierman", "srif"])
def test_square_root_forms_stay_positive_definite_and_accurate(name):
    tr, sensor, X, Z, x0, P0 = _case()
    reference = _exact_covariances()
    min_eig, asym, history = _run(ht.load_plugins().registry.create("estimator", name), tr, sensor, Z, x0, P0)
    assert min_eig > 0.5e-12  # the smallest true eigenvalue is ≈ 1e-12
    assert asym < 1e-12
    scale = lambda P: np.sqrt(np.outer(np.diag(P), np.diag(P)))  # noqa: E731
    worst = max((np.abs(P - P_ref) / scale(P_ref)).max() for (_, P), P_ref in zip(history, reference))
    assert worst < 1e-4, worst  # every entry within 1e-4 of √(P_ii P_jj) of the exact answer
    # and the estimate is as good as the data: position error at the measurement-noise level
    errors = np.array([x[[0, 2]] - X[k + 1, [0, 2]] for k, (x, _) in enumerate(history)])
    assert np.abs(errors).max() < 1e-5
