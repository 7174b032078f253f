"""Speed of a bank of M Kalman filters: hybridtrack's bank vs filterpy objects vs a plain numpy loop.

Problem (seed 001): 4-state (x, vx, y, vy), τ = 0.1, Q_w = 0.001·I₂, 2-D
position measurements with R = 0.01·I₂, 360 steps of a left turn of radius 5
from x0 = (0, 0, 0, 2).  The bank is straight + n left + n right turns with
radii linspace(1, 10, n), n = (M − 1)/2 (M = 21: radii 1…10).  Every filter
step includes ν, S and the log-likelihood ℓ.

Implementations, all timed in the same run (median of ``--repeats`` runs,
single-threaded BLAS: the *_NUM_THREADS variables are set to 1 before numpy
is imported):

* ``hybridtrack``: the ``kalman`` estimator (Joseph update; the axis-separable
  path is taken since F, Q, P0 are block diagonal and R is diagonal);
* ``hybridtrack_dense``: the same estimator with ``structure=False``, which
  forces the general dense (M, n, n) path (the one correlated R, mixed sensors,
  the 6-state mode, per-filter H or R and the EKF use) on the same bank, with
  its default ``engine="auto"``: the compiled numba kernel (the kernel is
  compiled or loaded from its cache in an untimed warm-up before any timing);
* ``hybridtrack_dense_numpy``: the dense path with ``engine="numpy"`` (stacked
  numpy operations, the path before the compiled kernel);
* ``numpy_batched``: a straightforward batched numpy bank written out here —
  stacked matmuls, closed-form 2×2 S⁻¹, Joseph update, no validation or
  symmetrisation — the yardstick for the dense path;
* ``filterpy``: a loop over M ``filterpy.kalman.KalmanFilter`` objects, reading
  ``kf.log_likelihood`` each step;
* ``numpy_loop``: a plain per-filter numpy loop (solve, slogdet);
* ``simdkalman``: simdkalman's ``KalmanFilter`` (vectorized numpy over the M
  filters, per-filter F and Q as (M, n, n) stacks), stepped with its
  ``predict_next`` and ``update(..., log_likelihood=True)`` — the two calls its
  own ``compute`` makes per observation (``compute`` itself takes only a shared
  F).  It has no input term B, so its state is augmented with a constant 1:
  F' = [[F, B], [0, 1]], Q' = blockdiag(Q, 0), H' = [H, 0], x0' = (x0, 1),
  P0' = blockdiag(P0, 0).  Its update is the conventional P⁻ − K H P⁻ with
  ``inv(S)`` (not Joseph) and its log-likelihood omits −(m/2) ln 2π, which is
  added back here.  Optional: ``pip install simdkalman`` (not a dependency of
  hybridtrack); without it the case is skipped with a message and the JSON says so.

The per-filter loops may be timed on fewer steps (``--loop-steps``; by default
36 at M = 2001) and scaled: their cost is linear in steps.  The JSON says so
per case (``timed_steps``, ``scaled``).  Results are checked equal: the
log-likelihoods of all steps timed by an implementation (relative 1e-8) and,
where all 360 steps ran, the final x and P; the JSON records the largest
log-likelihood difference between simdkalman and hybridtrack.

Usage: ``python benchmarks/bank.py --json docs/results/bank_bench.json``
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

import hybridtrack as ht  # noqa: E402
from hybridtrack.core.interfaces import LinearTransition, TransitionBank  # noqa: E402

TAU, Q_W, R_VAR, STEPS = 0.1, 1e-3, 1e-2, 360
G = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
LAYOUT = ("x", "vx", "y", "vy")


def turn(xs, radius, left):
    """SPEC §1 turn transition (written here so the benchmark needs only the kernel)."""
    x, vx, y, vy = xs
    w = np.hypot(vx, vy) / radius
    c, s = np.cos(w * TAU), np.sin(w * TAU)
    sign = 1.0 if left else -1.0
    F = np.kron(np.eye(2), [[c, s / w], [-w * s, c]])
    B = np.array([(x - sign * vy / w) * (1 - c), (w * x - sign * vy) * s, (y + sign * vx / w) * (1 - c), (w * y + sign * vx) * s])
    return LinearTransition(F, B, G, np.eye(2) * Q_W)


def straight():
    return LinearTransition(np.kron(np.eye(2), [[1.0, TAU], [0.0, 1.0]]), np.zeros(4), G, np.eye(2) * Q_W)


def problem(M, seed=0):
    n = (M - 1) // 2
    x0 = np.array([0.0, 0.0, 0.0, 2.0])
    radii = np.linspace(1.0, 10.0, n)
    transitions = [straight()] + [turn(x0, r, True) for r in radii] + [turn(x0, r, False) for r in radii]
    truth_model = turn(x0, 5.0, True)
    rng = np.random.default_rng(seed)
    x, Z = x0.copy(), []
    for _ in range(STEPS):
        x = truth_model.F @ x + truth_model.B + G @ (rng.standard_normal(2) * np.sqrt(Q_W))
        Z.append(H @ x + rng.standard_normal(2) * np.sqrt(R_VAR))
    return transitions, np.array(Z), x0, np.eye(4)


# --------------------------------------------------------------------------- implementations


def run_hybridtrack(transitions, Z, x0, P0, steps, structure=True, engine="auto"):
    registry = ht.load_plugins().registry
    est = registry.create("estimator", "kalman", structure=structure, engine=engine)
    sensor = registry.create("sensor", "position", noise_cov=np.eye(2) * R_VAR)
    bank = TransitionBank.stack(transitions)
    M = len(transitions)
    state = est.initialize(np.tile(x0, (M, 1)), np.broadcast_to(P0, (M, 4, 4)))
    logliks = np.empty((steps, M))
    t = time.perf_counter()
    for k in range(steps):
        state = est.predict(state, bank)
        state, innovation = est.update(state, Z[k], [sensor], LAYOUT)
        logliks[k] = innovation.loglik
    elapsed = time.perf_counter() - t
    return elapsed, logliks, est.mean(state), est.covariance(state)


def run_numpy_batched(transitions, Z, x0, P0, steps):
    """The covariance KF over stacked (M, n, n) arrays, written the obvious way (Joseph update, S⁻¹ by its adjugate)."""
    bank = TransitionBank.stack(transitions)
    F, B, Q = bank.F, bank.B, bank.Q
    Ft = np.ascontiguousarray(np.swapaxes(F, 1, 2))
    R = np.eye(2) * R_VAR
    eye = np.eye(4)
    M = len(transitions)
    x = np.tile(x0, (M, 1))
    P = np.broadcast_to(P0, (M, 4, 4)).copy()
    logliks = np.empty((steps, M))
    log2pi = np.log(2 * np.pi)
    t = time.perf_counter()
    for k in range(steps):
        x = np.einsum("mij,mj->mi", F, x) + B
        P = F @ P @ Ft + Q
        nu = Z[k] - x @ H.T
        PHt = P @ H.T
        S = H @ PHt + R
        det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
        S_inv = np.stack([S[:, 1, 1], -S[:, 0, 1], -S[:, 1, 0], S[:, 0, 0]], axis=-1).reshape(M, 2, 2) / det[:, None, None]
        K = PHt @ S_inv
        x = x + np.einsum("mij,mj->mi", K, nu)
        A = eye - K @ H
        P = A @ P @ np.swapaxes(A, 1, 2) + K @ R @ np.swapaxes(K, 1, 2)
        logliks[k] = -0.5 * (2 * log2pi + np.log(det) + np.einsum("mi,mij,mj->m", nu, S_inv, nu))
    elapsed = time.perf_counter() - t
    return elapsed, logliks, x, P


def run_filterpy(transitions, Z, x0, P0, steps):
    from filterpy.kalman import KalmanFilter

    filters = []
    for tr in transitions:
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x, kf.P = x0.copy(), P0.copy()
        kf.F, kf.Q, kf.B = tr.F.copy(), tr.process_noise, tr.B[:, None].copy()
        kf.H, kf.R = H.copy(), np.eye(2) * R_VAR
        filters.append(kf)
    u = np.array([1.0])
    logliks = np.empty((steps, len(filters)))
    t = time.perf_counter()
    for k in range(steps):
        z = Z[k]
        for i, kf in enumerate(filters):
            kf.predict(u=u)
            kf.update(z)
            logliks[k, i] = kf.log_likelihood
    elapsed = time.perf_counter() - t
    return elapsed, logliks, np.array([kf.x for kf in filters]), np.array([kf.P for kf in filters])


def run_numpy_loop(transitions, Z, x0, P0, steps):
    """The textbook covariance KF (Joseph update), one filter at a time."""
    Fs = [tr.F for tr in transitions]
    Bs = [tr.B for tr in transitions]
    Qs = [tr.process_noise for tr in transitions]
    R = np.eye(2) * R_VAR
    eye = np.eye(4)
    xs = [x0.copy() for _ in transitions]
    Ps = [P0.copy() for _ in transitions]
    logliks = np.empty((steps, len(transitions)))
    log2pi = np.log(2 * np.pi)
    t = time.perf_counter()
    for k in range(steps):
        z = Z[k]
        for i in range(len(transitions)):
            F = Fs[i]
            x = F @ xs[i] + Bs[i]
            P = F @ Ps[i] @ F.T + Qs[i]
            nu = z - H @ x
            PHt = P @ H.T
            S = H @ PHt + R
            K = np.linalg.solve(S, PHt.T).T
            x = x + K @ nu
            A = eye - K @ H
            P = A @ P @ A.T + K @ R @ K.T
            logliks[k, i] = -0.5 * (2 * log2pi + np.linalg.slogdet(S)[1] + nu @ np.linalg.solve(S, nu))
            xs[i], Ps[i] = x, P
    elapsed = time.perf_counter() - t
    return elapsed, logliks, np.array(xs), np.array(Ps)


def run_simdkalman(transitions, Z, x0, P0, steps):
    """simdkalman on the bank, its state augmented with a constant 1 to carry B (it has no input term)."""
    import simdkalman

    bank = TransitionBank.stack(transitions)
    M, n = bank.B.shape
    F_aug = np.zeros((M, n + 1, n + 1))
    F_aug[:, :n, :n], F_aug[:, :n, n], F_aug[:, n, n] = bank.F, bank.B, 1.0
    Q_aug = np.zeros((M, n + 1, n + 1))
    Q_aug[:, :n, :n] = bank.Q
    H_aug = np.hstack([H, np.zeros((2, 1))])
    kf = simdkalman.KalmanFilter(state_transition=F_aug, process_noise=Q_aug, observation_model=H_aug, observation_noise=np.eye(2) * R_VAR)
    m = np.tile(np.append(x0, 1.0), (M, 1))[:, :, None]
    P = np.zeros((M, n + 1, n + 1))
    P[:, :n, :n] = P0
    Y = np.ascontiguousarray(np.broadcast_to(Z[:, None, :, None], (len(Z), M, 2, 1)))  # (steps, M, m, 1), as compute() slices it
    logliks = np.empty((steps, M))
    t = time.perf_counter()
    for k in range(steps):
        m, P = kf.predict_next(m, P)
        m, P, _, loglik = kf.update(m, P, Y[k], log_likelihood=True)
        logliks[k] = loglik
    elapsed = time.perf_counter() - t
    logliks -= np.log(2 * np.pi)  # simdkalman's ℓ omits −(m/2) ln 2π, m = 2
    return elapsed, logliks, m[:, :n, 0], P[:, :n, :n]


def simdkalman_version():
    """simdkalman's version, or None when it is not installed."""
    try:
        from importlib.metadata import PackageNotFoundError, version

        return version("simdkalman")
    except PackageNotFoundError:
        return None


IMPLEMENTATIONS = {
    "hybridtrack": lambda *a: run_hybridtrack(*a, structure=True),
    "hybridtrack_dense": lambda *a: run_hybridtrack(*a, structure=False),
    "hybridtrack_dense_numpy": lambda *a: run_hybridtrack(*a, structure=False, engine="numpy"),
    "numpy_batched": run_numpy_batched,
    "filterpy": run_filterpy,
    "numpy_loop": run_numpy_loop,
    "simdkalman": run_simdkalman,
}
PER_FILTER_LOOPS = ("filterpy", "numpy_loop")


def warm_up():
    """Compile (or load from numba's cache) the dense path's kernel on a small bank, untimed; seconds taken."""
    transitions, Z, x0, P0 = problem(5)
    t = time.perf_counter()
    run_hybridtrack(transitions, Z, x0, P0, 2, structure=False)
    return time.perf_counter() - t


def bench(M, repeats, loop_steps, implementations):
    transitions, Z, x0, P0 = problem(M)
    cases, results = [], {}
    for impl, run in implementations.items():
        steps = loop_steps if impl in PER_FILTER_LOOPS else STEPS
        times = []
        for _ in range(repeats):
            elapsed, logliks, x, P = run(transitions, Z, x0, P0, steps)
            times.append(elapsed)
        median = statistics.median(times)
        results[impl] = (steps, logliks, x, P)
        cases.append(
            {
                "M": M,
                "steps": STEPS,
                "impl": impl,
                "filter_steps_per_s": M * steps / median,
                "timed_steps": steps,
                "scaled": steps != STEPS,
                "median_s_for_360_steps": median * STEPS / steps,
                "repeats": repeats,
            }
        )
        print(f"M={M:5d} {impl:18s} {M * steps / median:12.4g} filter-steps/s  (timed {steps} steps, median of {repeats})", flush=True)
    # equality checks
    ref_steps, ref_ll, ref_x, ref_P = results["hybridtrack"]
    for impl, (steps, ll, x, P) in results.items():
        np.testing.assert_allclose(ll, ref_ll[:steps], rtol=1e-8, atol=1e-8, err_msg=f"log-likelihoods of {impl}")
        if steps == STEPS:
            np.testing.assert_allclose(x, ref_x, rtol=1e-8, atol=1e-10, err_msg=f"final x of {impl}")
            np.testing.assert_allclose(P, ref_P, rtol=1e-8, atol=1e-12, err_msg=f"final P of {impl}")
    speed = {c["impl"]: c["filter_steps_per_s"] for c in cases}
    ratios = {"vs_filterpy": speed["hybridtrack"] / speed["filterpy"], "vs_loop": speed["hybridtrack"] / speed["numpy_loop"]}
    dense = {
        "vs_numpy_batched": speed["hybridtrack_dense"] / speed["numpy_batched"],
        "vs_filterpy": speed["hybridtrack_dense"] / speed["filterpy"],
        "vs_loop": speed["hybridtrack_dense"] / speed["numpy_loop"],
        "compiled_vs_numpy_engine": speed["hybridtrack_dense"] / speed["hybridtrack_dense_numpy"],
        "numpy_engine_vs_numpy_batched": speed["hybridtrack_dense_numpy"] / speed["numpy_batched"],
        "numpy_engine_vs_filterpy": speed["hybridtrack_dense_numpy"] / speed["filterpy"],
    }
    simd = None
    if "simdkalman" in speed:
        ll = results["simdkalman"][1]
        diff = np.abs(ll - ref_ll)
        simd = {
            "ratios": {
                "hybridtrack": speed["hybridtrack"] / speed["simdkalman"],
                "hybridtrack_dense": speed["hybridtrack_dense"] / speed["simdkalman"],
                "hybridtrack_dense_numpy": speed["hybridtrack_dense_numpy"] / speed["simdkalman"],
            },
            "loglik_agreement": {
                "max_abs_diff": float(diff.max()),
                "max_abs_diff_over_max_abs_loglik": float(diff.max() / np.abs(ref_ll).max()),
                "max_rel_diff": float((diff / np.abs(ref_ll)).max()),
                "steps_compared": int(ll.shape[0]),
            },
        }
    return cases, ratios, speed["hybridtrack"] / speed["hybridtrack_dense"], dense, simd


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", required=True, help="where to write the results")
    parser.add_argument("--sizes", type=int, nargs="+", default=[21, 201, 2001])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--loop-steps", type=int, default=None, help="steps timed for the per-filter loops (default: 360, 36 at M ≥ 2001)")
    args = parser.parse_args(argv)
    if args.repeats < 3:
        parser.error("--repeats must be at least 3")
    implementations = dict(IMPLEMENTATIONS)
    simd_version = simdkalman_version()
    if simd_version is None:
        del implementations["simdkalman"]
        print("simdkalman is not installed: its case is skipped (pip install simdkalman to time it)", flush=True)
    engine = ht.load_plugins().registry.create("estimator", "kalman", structure=False).dense_engine(4, 2)
    warm_up_s = warm_up()
    print(f"dense path engine: {engine}; warm-up (compile or cache load, untimed) {warm_up_s:.2f} s", flush=True)
    all_cases, ratios, vs_dense, dense_ratios, simd_ratios, simd_agreement, loads = [], {}, {}, {}, {}, {}, {}
    for M in args.sizes:
        loop_steps = args.loop_steps or (36 if M >= 2001 else STEPS)
        load_before = os.getloadavg()[0]
        cases, r, dense, dense_r, simd = bench(M, args.repeats, loop_steps, implementations)
        loads[str(M)] = {"before": load_before, "after": os.getloadavg()[0]}
        all_cases += cases
        ratios[str(M)] = r
        vs_dense[str(M)] = dense
        dense_ratios[str(M)] = dense_r
        if simd is not None:
            simd_ratios[str(M)] = simd["ratios"]
            simd_agreement[str(M)] = simd["loglik_agreement"]
        print(
            f"M={M}: {r['vs_filterpy']:.0f}x filterpy, {r['vs_loop']:.0f}x numpy loop, {dense:.2f}x dense bank; "
            f"dense bank {dense_r['vs_numpy_batched']:.2f}x the batched numpy bank, "
            f"{dense_r['compiled_vs_numpy_engine']:.2f}x its numpy engine"
            + (
                f"; vs simdkalman {simd['ratios']['hybridtrack']:.1f}x (separable), {simd['ratios']['hybridtrack_dense']:.1f}x (dense), "
                f"max |Δℓ| {simd['loglik_agreement']['max_abs_diff']:.2g}"
                if simd
                else ""
            )
            + f" (load {load_before:.2f})",
            flush=True,
        )
    import filterpy

    out = {
        "cases": all_cases,
        "ratios": ratios,
        "hybridtrack_vs_dense_bank": vs_dense,
        "dense_ratios": dense_ratios,
        "simdkalman_ratios": simd_ratios if simd_version else "simdkalman not installed: case skipped (pip install simdkalman)",
        "simdkalman_loglik_agreement": simd_agreement if simd_version else None,
        "load_average_1min": loads,
        "settings": {
            "steps": STEPS,
            "state_dim": 4,
            "measurement": "2-D position, R = 0.01 I",
            "update": "Joseph form in every implementation; each step computes nu, S and the log-likelihood",
            "per_filter_loops_scaled": "filterpy and numpy_loop cases with scaled = true were timed on timed_steps steps and scaled linearly to 360",
            "equality": "log-likelihoods of every timed step equal to hybridtrack's (rtol 1e-8); final x, P equal where all 360 steps ran",
            "hybridtrack_dense": "the kalman estimator with structure=False: the general dense (M, n, n) path on the same bank",
            "hybridtrack_dense_engine": engine,
            "hybridtrack_dense_numpy": "the dense path with engine='numpy' (stacked numpy operations: the dense path before the compiled kernel)",
            "warm_up_s": warm_up_s,
            "warm_up": "the dense path's numba kernel compiled or loaded from its cache on a 5-filter bank before any timing (not counted)",
            "numpy_batched": "a straightforward batched numpy bank (stacked matmuls, adjugate S^-1, Joseph, no checks), timed in the same run",
            "simdkalman": (
                "simdkalman.KalmanFilter with per-filter (M, 5, 5) F' = [[F, B], [0, 1]], Q' = blockdiag(Q, 0), H' = [H, 0] "
                "(state augmented with a constant 1: no input term), stepped by predict_next + update(log_likelihood=True); "
                "conventional update P - K H P with inv(S); its log-likelihood + (-ln 2 pi) compared with hybridtrack's"
            ),
            "simdkalman_version": simd_version,
            "blas_threads": 1,
            "OPENBLAS_CORETYPE": os.environ.get("OPENBLAS_CORETYPE"),
            "repeats": args.repeats,
            "statistic": "median",
            "python": sys.version.split()[0],
            "numpy": np.__version__,
            "filterpy": filterpy.__version__,
            "machine": platform.machine(),
            "cpu_count": os.cpu_count(),
        },
    }
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump(out, f, indent=2)
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
