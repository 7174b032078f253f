"""Compiled kernel of the batched Levenberg–Marquardt for bearings-only TMA (seed 002 §4.3), by numba.

The same steps as :func:`.levenberg_marquardt.minimize_batch`, run problem by
problem in compiled code (:func:`minimize_problems`), with one fused pass over
the n bearings per trial point s = (s_0, s_1, s_2, s_3) (scaled units, see
:mod:`.tma_model`; "north" convention, φ = atan2(Δx, Δy) — the "math"
convention is its mirror image x ↔ y and is solved that way by the caller):

    a_k = Δx_k = s_0 + s_2 τ_k − õx_k,   b_k = Δy_k = s_1 + s_3 τ_k − õy_k,   ρ_k² = a_k² + b_k²,
    S_k = sin X_k b_k − cos X_k a_k = ρ_k sin r_k,   C_k = cos X_k b_k + sin X_k a_k = ρ_k cos r_k,
    r_k = wrap(X_k − φ_k) = atan2(S_k, C_k),   p_k = b_k/ρ_k²,  q_k = −a_k/ρ_k²,

(S, C: the measured direction (sin X, cos X) against the predicted one (a, b)/ρ,
so no wrap is needed), accumulating F = Σ r_k² and the 13 sums Σ w_k τ_k^j
(w ∈ {p², pq, q²}, j = 0, 1, 2; w ∈ {pr, qr}, j = 0, 1) from which H = JᵀJ and
g = Jᵀr are read (J_k = (p_k, q_k, p_k τ_k, q_k τ_k)): no Jacobian array, nothing
stored per bearing.  sin X_k and cos X_k are computed once per problem
(:func:`unit_vectors`).

**Two passes.**  :func:`pass_small` assumes |S_k| ≤ tan(π/8) C_k for every k
(residuals within 22.5°, true after the first one or two steps): then
r_k = atan(S_k/C_k) by :func:`atan_small`, and S_k/C_k and 1/ρ_k² come from one
division 1/(C_k ρ_k²).  :func:`pass_general` takes any S, C (:func:`atan2`).
:func:`evaluate` tries the small pass unless the previous evaluation of the
problem broke the bound, and redoes a pass that breaks it in general form.

**atan2, sin, cos** in arithmetic the compiler vectorizes (why: docs/tma.md, "Benchmark").
atan2(y, x): with A = |y|, B = |x|, m = min(A, B), M = max(A, B),

    z = m/M                      if m ≤ tan(π/8) M,
    z = (m − M)/(m + M), + π/4   otherwise      (atan(m/M) = π/4 + atan((m − M)/(m + M))),

so |z| ≤ tan(π/8) and atan(z) = z + z u P(u), u = z², P a degree-10 polynomial
(:data:`ATAN_P`, derived by ``fit_atan_polynomial`` in ``tests/plugins/test_tma_kernel.py``: a least-squares fit at 200
Chebyshev nodes on [0, tan²(π/8)] to the series P(u) = Σ_{k≥1} (−1)^k u^{k−1}/(2k+1)
evaluated in 50-digit decimals; error < 10⁻¹⁵ in P, < 3·10⁻¹⁷ relative in atan).
Then θ = π/2 − θ when A > B, θ = π − θ when x < 0, and the sign of y (π/4, π/2,
π each as a two-double constant).  sin/cos: X = n π/2 + y, |y| ≤ π/4, Taylor
series of sin y and cos y, quadrant n mod 4.  Against numpy: atan2 ≤ 2 ulp,
sin/cos ≤ 2.3·10⁻¹⁶ (``tests/plugins/test_tma_kernel.py``).  F, H and g agree
with the numpy path to ~10⁻¹⁴ relative.

**Floating point.**  The passes are compiled with ``fastmath={"reassoc",
"contract"}`` only (reordered sums, so that the loops are vectorized, and FMA);
NaN/inf semantics are kept (a non-finite trial F is rejected as in the numpy
path; a trial point so far out that C ρ² overflows falls to the general pass).
The λ logic and the 4×4 Cholesky are compiled without fastmath, in the
operation order of :mod:`hybridtrack.sdk.linalg`.  ``error_model="numpy"``: no
Python zero-division checks (they would stop the vectorization).
``cache=True``: the first call in a fresh checkout compiles (≈ 5 s) and caches
the machine code next to this file (``__pycache__``).

``AVAILABLE`` is False when numba is not installed (the batched solver then uses the numpy path).
"""

from __future__ import annotations

import math

import numpy as np

try:
    import numba
except ImportError:  # pragma: no cover - exercised only without numba
    numba = None

AVAILABLE = numba is not None

#: P(u) with atan(z) = z + z u P(u), u = z² ≤ tan²(π/8): coefficients of u⁰ … u¹⁰ (module doc)
ATAN_P = (
    -0.33333333333333337,
    0.19999999999995072,
    -0.14285714284697382,
    0.11111111020754154,
    -0.09090904847282058,
    0.07692189924877749,
    -0.06664610050049277,
    0.05859027333736597,
    -0.050901362349793325,
    0.03936929724571587,
    -0.019347970377818047,
)
TAN_PI_8 = 0.41421356237309503  # tan(π/8) = √2 − 1
# π/4, π/2, π as hi + lo (hi the nearest double, lo the rest)
PI_4_HI, PI_4_LO = 0.7853981633974483, 3.061616997868383e-17
PI_2_HI, PI_2_LO = 1.5707963267948966, 6.123233995736766e-17
PI_HI, PI_LO = 3.141592653589793, 1.2246467991473532e-16

STATUS_CONVERGED, STATUS_ITERATIONS, STATUS_LAMBDA = 0, 1, 2


# Taylor coefficients (−1)^k/(2k+1)! of sin (k = 8 … 1) and (−1)^k/(2k)! of cos (k = 8 … 2), for |y| ≤ π/4,
# and ATAN_P, each highest power first (for :func:`horner`)
_SIN = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(8, 0, -1))
_COS = tuple((-1) ** k / math.factorial(2 * k) for k in range(8, 1, -1))
_ATAN = ATAN_P[::-1]
TWO_OVER_PI = 0.6366197723675814


def _njit(**options):
    def decorate(function):
        return numba.njit(cache=True, error_model="numpy", **options)(function) if AVAILABLE else function

    return decorate


_FAST = {"reassoc", "contract"}


@_njit(fastmath=_FAST, inline="always")
def horner(coefficients, u):
    """Σ_j c_j u^j by Horner's rule, ``coefficients`` (c_d, …, c_1, c_0) highest power first."""
    poly = coefficients[0]
    for c in coefficients[1:]:
        poly = poly * u + c
    return poly


@_njit(fastmath=_FAST, inline="always")
def atan_small(z):
    """atan(z) = z + z u P(u), u = z², for |z| ≤ tan(π/8) (:data:`ATAN_P`, Horner)."""
    u = z * z
    return z + z * (u * horner(_ATAN, u))


@_njit(fastmath=_FAST, inline="always")
def atan2(y, x):
    """atan2(y, x) ∈ [−π, π] by octant reduction and :func:`atan_small` (module doc); atan2(0, 0) = 0, NaN in → NaN out."""
    a, b = abs(y), abs(x)
    m = a if a < b else b  # min and max that pass a NaN on (the NaN lands in m or M)
    M = b if a < b else a
    infinite = M == math.inf  # atan2(±inf, ±inf) = ±π/4, ±3π/4: take m/M = 1 (both infinite) or 0
    m = (1.0 if m == math.inf else m * 0.0) if infinite else m  # m * 0: 0, or NaN kept
    M = 1.0 if infinite else M
    big = m > TAN_PI_8 * M
    num = m - M if big else m
    den = m + M if big else M
    z = num / den if den != 0.0 else num  # 0/0 → 0 as atan2(0, 0)
    t = atan_small(z)
    t = (PI_4_HI + (t + PI_4_LO)) if big else t
    t = (PI_2_HI - (t - PI_2_LO)) if a > b else t
    t = (PI_HI - (t - PI_LO)) if math.copysign(1.0, x) < 0.0 else t  # x = −0 counts as negative, as in atan2
    return math.copysign(t, y)


@_njit(fastmath=_FAST)
def unit_vectors(X, sx, cx):
    """sx, cx ← sin X, cos X for any finite X (n,), vectorized.

    X = n π/2 + y with n = ⌊2X/π + ½⌉ and y = (X − n P₁) − n P₂ (π/2 = P₁ + P₂ as two
    doubles), |y| ≤ π/4; sin y and cos y by their Taylor series to y¹⁷ and y¹⁶
    (truncation < 10⁻¹⁸), then the quadrant q = n mod 4 gives
    (sin X, cos X) = (s, c), (c, −s), (−s, −c), (−c, s) for q = 0, 1, 2, 3.
    """
    for k in range(X.shape[0]):
        x = X[k]
        n = math.floor(x * TWO_OVER_PI + 0.5)
        y = (x - n * PI_2_HI) - n * PI_2_LO
        u = y * y
        sin_y = y + y * (u * horner(_SIN, u))
        cos_y = 1.0 + (u * (u * horner(_COS, u)) - 0.5 * u)
        q = n - 4.0 * math.floor(n * 0.25)
        odd = q == 1.0 or q == 3.0
        sin_x = cos_y if odd else sin_y
        cos_x = sin_y if odd else cos_y
        sx[k] = -sin_x if q >= 2.0 else sin_x
        cx[k] = -cos_x if (q == 1.0 or q == 2.0) else cos_x


@_njit(fastmath=_FAST, inline="always")
def _add(acc, a, b, w, r, t):
    """acc + (r², p², p²τ, p²τ², pq, pqτ, pqτ², q², q²τ, q²τ², pr, prτ, qr, qrτ) with p = b w, q = −a w."""
    p = b * w
    q = -a * w
    pp, pq, qq, pr, qr = p * p, p * q, q * q, p * r, q * r
    t2 = t * t
    return (
        acc[0] + r * r,
        acc[1] + pp,
        acc[2] + pp * t,
        acc[3] + pp * t2,
        acc[4] + pq,
        acc[5] + pq * t,
        acc[6] + pq * t2,
        acc[7] + qq,
        acc[8] + qq * t,
        acc[9] + qq * t2,
        acc[10] + pr,
        acc[11] + pr * t,
        acc[12] + qr,
        acc[13] + qr * t,
    )


@_njit(fastmath=_FAST, inline="always")
def _geometry(s, t, ox, oy, sx, cx):
    """a = Δx, b = Δy at τ = t for s = (s_0, s_1, s_2, s_3) (a tuple), S = sx b − cx a, C = cx b + sx a (module doc)."""
    a = s[0] + s[2] * t - ox
    b = s[1] + s[3] * t - oy
    return a, b, sx * b - cx * a, cx * b + sx * a


@_njit(fastmath=_FAST)
def pass_small(s, tau, ox, oy, sx, cx, out):
    """One pass over the bearings assuming |S| ≤ tan(π/8) C (module doc, "Two passes"): r = atan_small(S/C), S/C and
    1/ρ² from one division 1/(C ρ²).  ``out`` (14,) ← (F, Σp², Σp²τ, Σp²τ², Σpq, Σpqτ, Σpqτ², Σq², Σq²τ, Σq²τ², Σpr,
    Σprτ, Σqr, Σqrτ); returns the count of bearings where the assumption fails (then :func:`pass_general` is used).
    """
    point = (s[0], s[1], s[2], s[3])  # loaded once, outside the loop
    acc = (0.0,) * 14
    bad = 0
    for k in range(tau.shape[0]):
        a, b, S, C = _geometry(point, tau[k], ox[k], oy[k], sx[k], cx[k])
        rho2 = a * a + b * b
        bad += 0 if abs(S) <= TAN_PI_8 * C else 1
        inverse = 1.0 / (C * rho2)
        acc = _add(acc, a, b, C * inverse, atan_small(S * rho2 * inverse), tau[k])
    out[:] = acc
    return bad


@_njit(fastmath=_FAST)
def pass_general(s, tau, ox, oy, sx, cx, out):
    """:func:`pass_small` without its assumption: r = atan2(S, C), 1/ρ² by its own division.

    Returns the count of bearings with |S| > tan(π/8) C all the same (the hint for the next pass).
    """
    point = (s[0], s[1], s[2], s[3])  # loaded once, outside the loop
    acc = (0.0,) * 14
    bad = 0
    for k in range(tau.shape[0]):
        a, b, S, C = _geometry(point, tau[k], ox[k], oy[k], sx[k], cx[k])
        bad += 0 if abs(S) <= TAN_PI_8 * C else 1
        acc = _add(acc, a, b, 1.0 / (a * a + b * b), atan2(S, C), tau[k])
    out[:] = acc
    return bad


@_njit()
def evaluate(s, tau, ox, oy, sx, cx, out, small):
    """``out`` (14,) ← F(s) and the 13 sums; returns (F, whether the residuals at s were all small).

    ``small`` (the previous evaluation's answer) picks the first try (module doc, "Two passes"); a small
    pass whose F is not finite is also redone in general form.
    """
    if small:
        if pass_small(s, tau, ox, oy, sx, cx, out) == 0 and math.isfinite(out[0]):
            return out[0], True
    bad = pass_general(s, tau, ox, oy, sx, cx, out)
    return out[0], bad == 0


@_njit()
def normal_from_sums(sums, H, g):
    """H = JᵀJ (4, 4) and g = Jᵀr (4,) from the sums of :func:`evaluate` (J_k = (p, q, pτ, qτ))."""
    pp0, pp1, pp2, pq0, pq1, pq2, qq0, qq1, qq2 = sums[1], sums[2], sums[3], sums[4], sums[5], sums[6], sums[7], sums[8], sums[9]
    H[0, 0], H[0, 1], H[0, 2], H[0, 3] = pp0, pq0, pp1, pq1
    H[1, 0], H[1, 1], H[1, 2], H[1, 3] = pq0, qq0, pq1, qq1
    H[2, 0], H[2, 1], H[2, 2], H[2, 3] = pp1, pq1, pp2, pq2
    H[3, 0], H[3, 1], H[3, 2], H[3, 3] = pq1, qq1, pq2, qq2
    g[0], g[1], g[2], g[3] = sums[10], sums[12], sums[11], sums[13]


@_njit()
def damped_step(H, g, lam, L, delta):
    """Solve (H + λ diag(H)) Δ = g by Cholesky (A_jj = H_jj (1 + λ)); False when A is not positive definite.

    L_jj = √(A_jj − Σ_{t<j} L_jt²), L_ij = (A_ij − Σ_{t<j} L_it L_jt)/L_jj, then
    L y = g and Lᵀ Δ = y, in the operation order of :mod:`hybridtrack.sdk.linalg`.
    """
    k = 4
    for j in range(k):
        d = H[j, j] * (1.0 + lam)
        for t in range(j):
            d -= L[j, t] ** 2
        if not d > 0.0:
            return False
        root = math.sqrt(d)
        L[j, j] = root
        for i in range(j + 1, k):
            v = H[i, j]
            for t in range(j):
                v -= L[i, t] * L[j, t]
            L[i, j] = v / root
    y = np.empty(k)
    for i in range(k):
        v = g[i]
        for t in range(i):
            v -= L[i, t] * y[t]
        y[i] = v / L[i, i]
    for i in range(k - 1, -1, -1):
        v = y[i]
        for t in range(i + 1, k):
            v -= L[t, i] * delta[t]
        delta[i] = v / L[i, i]
    return True


@_njit()
def minimize_problems(s0, tau, ox, oy, X, settings):
    """Seed 002 §4.3 steps 1–9 (:mod:`.levenberg_marquardt`) for each row of s0 (m, 4) with bearings X (m, n),
    any finite radians ("north" convention); õx, õy (1, n) shared or (m, n); ``settings`` = (λ_0, λ_up, λ_down,
    F_tol, max_iterations, λ_max, rounding_rtol).  An accepted trial's H, g come from its own pass.  Returns
    s (m, 4), F (m,), H (m, 4, 4), iterations, evaluations, status (m,) (0 ΔF < F_tol, 1 max_iterations, 2 λ > λ_max).
    """
    lam0, lam_up, lam_down, F_tol, max_iterations, lam_max, rounding_rtol = settings
    m = s0.shape[0]
    out_s, out_F, out_H = np.empty((m, 4)), np.empty(m), np.empty((m, 4, 4))
    out_it, out_nf, out_status = np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m, np.int64)
    sums = np.empty(14)
    sxi, cxi = np.empty(X.shape[1]), np.empty(X.shape[1])
    H, g, L = np.empty((4, 4)), np.empty(4), np.zeros((4, 4))
    delta, s, s_new = np.empty(4), np.empty(4), np.empty(4)
    shared = ox.shape[0] == 1
    for i in range(m):
        row = 0 if shared else i
        oxi, oyi = ox[row], oy[row]
        unit_vectors(X[i], sxi, cxi)
        s[:] = s0[i]
        F, small = evaluate(s, tau, oxi, oyi, sxi, cxi, sums, False)
        normal_from_sums(sums, H, g)
        lam = lam0
        it, nf, status = 0, 1, -1
        while status < 0:
            accept = False
            dF = 0.0
            if damped_step(H, g, lam, L, delta):
                for j in range(4):
                    s_new[j] = s[j] + delta[j]
                F_new, small = evaluate(s_new, tau, oxi, oyi, sxi, cxi, sums, small)
                nf += 1
                dF = F - F_new
                accept = math.isfinite(F_new) and dF >= -rounding_rtol * F
            if accept:
                normal_from_sums(sums, H, g)  # the sums of the trial point's pass
                s[:] = s_new
                F = F_new
                lam *= lam_down
                it += 1
                if dF < F_tol:
                    status = STATUS_CONVERGED
                elif it >= max_iterations:
                    status = STATUS_ITERATIONS
            else:
                lam *= lam_up
                if lam > lam_max:
                    status = STATUS_LAMBDA
        out_s[i], out_H[i] = s, H
        out_F[i], out_it[i], out_nf[i], out_status[i] = F, it, nf, status
    return out_s, out_F, out_H, out_it, out_nf, out_status
