"""Wall time of the seed 002 Monte Carlo (σ = 0.5°) with the batched LM against a loop of scipy's LM.

    python benchmarks/tma.py --json docs/results/tma_bench.json

Both sides solve the same problems from the same start (the seed's prior) in
the same scaled parameters.  The batched side is the whole
``levenberg_marquardt_batch`` call on all targets (scaling, iterations,
covariances, χ² tests included).  The loop side is, per target,
``scipy.optimize.least_squares(fun, x0, jac=jac, method="lm")`` with the
analytic Jacobian and scipy's default tolerances; only that call is timed
(building the closures is not), which favours scipy.  One untimed batched
call on a few targets comes first (numba compiles the kernel, or loads it
from its cache; the JSON gives that time).  The loop may run on a
subset (``--scipy-n``) and is scaled to all targets; the JSON says so.  The
repeats of the two sides are interleaved and the fastest of each is used, so
that load from other processes affects both alike.  With numba installed the
batched side runs the compiled kernel (the default engine), and the numpy
engine is timed in the same rounds as well (``numpy_engine``: its time and
that it gives the same iterations and answers).  BLAS is pinned to one thread
for all (set before numpy is imported); nothing runs in parallel.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
from tma_montecarlo import errors, ref_fractions  # noqa: E402

from hybridtrack_plugins.solvers.levenberg_marquardt import BatchLevenbergMarquardt, LMSettings  # noqa: E402
from hybridtrack_plugins.solvers.observer import Seed002Scenario, simulate_bearings  # noqa: E402
from hybridtrack_plugins.solvers.scipy_reference import ScipyLeastSquares  # noqa: E402
from hybridtrack_plugins.solvers.tma_model import BearingsBatch, ScaledProblem, UnobservabilityWarning  # noqa: E402


def warm_up(batch, settings):
    """One untimed batched solve of a few targets: numba's first call compiles or loads the cached kernel."""
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnobservabilityWarning)
        BatchLevenbergMarquardt(settings).solve_batch(
            BearingsBatch(
                batch.times, batch.bearings[:4], batch.observer, batch.sigma, batch.initial, batch.reference_time, batch.convention
            )
        )
    return time.perf_counter() - start


def time_batched(batch, settings, repeats, engine="auto"):
    solver = BatchLevenbergMarquardt(settings, engine=engine)
    times, result = [], None
    for _ in range(repeats):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnobservabilityWarning)
            start = time.perf_counter()
            result = solver.solve_batch(batch)
            times.append(time.perf_counter() - start)
    return times, result


def time_scipy(batch, count, repeats):
    """Per-target least_squares(method="lm") with the analytic Jacobian; returns times and the answers of the last pass."""
    reference = ScipyLeastSquares()
    closures = []
    for i in range(count):
        problem = batch.problem(i)
        scaled = ScaledProblem.build(
            problem.times, problem.bearings, problem.observer, problem.initial, problem.reference_time, problem.convention
        )
        fun, jac = reference.residual_functions(scaled)
        closures.append((fun, jac, scaled.scaling.to_scaled(problem.initial), scaled.scaling))
    times = []
    for _ in range(repeats):
        answers = []
        start = time.perf_counter()
        for fun, jac, x0, _ in closures:
            answers.append(least_squares(fun, x0, jac=jac, method="lm"))
        times.append(time.perf_counter() - start)
    theta = np.array([scaling.from_scaled(r.x) for r, (_, _, _, scaling) in zip(answers, closures)])
    return times, answers, theta


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=10_000, help="targets (default 10000)")
    parser.add_argument("--sigma", type=float, default=0.5, help="bearing noise in degrees (default 0.5)")
    parser.add_argument("--seed", type=int, default=2021)
    parser.add_argument("--scipy-n", type=int, default=2000, help="targets timed with the scipy loop (scaled to --n)")
    parser.add_argument("--repeats", type=int, default=3, help="interleaved timed repeats of each side (the fastest is used)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    count = min(args.scipy_n, args.n)

    scenario = Seed002Scenario()
    times, observer, prior = scenario.times(), scenario.observer(), scenario.prior_theta()
    streams = np.random.SeedSequence(args.seed).spawn(2)
    targets = scenario.draw_targets(np.random.default_rng(streams[0]), args.n)
    sigma = float(np.deg2rad(args.sigma))
    X = simulate_bearings(targets, times, observer, sigma, np.random.default_rng(streams[1]), scenario.convention)
    batch = BearingsBatch(times, X, observer, sigma=sigma, initial=prior, convention=scenario.convention)
    settings = LMSettings()

    first_call = warm_up(batch, settings)
    load_before = os.getloadavg()
    # interleave the repeats so that load from other processes hits both sides alike; report the best (timeit's rule)
    lm_times, sp_times, np_times = [], [], []
    compiled = BatchLevenbergMarquardt().compiled
    for _ in range(args.repeats):
        t, lm = time_batched(batch, settings, 1)
        lm_times += t
        if compiled:  # the numpy engine on the same targets: its time, and that the answers are the same
            t, lm_numpy = time_batched(batch, settings, 1, engine="numpy")
            np_times += t
        t, sp_answers, sp_theta = time_scipy(batch, count, 1)
        sp_times += t
    lm_total = float(np.min(lm_times))
    sp_per = float(np.min(sp_times)) / count
    sp_total = sp_per * args.n

    def refs(theta, rows):
        return ref_fractions(errors(theta, targets[rows], 0.0, observer[0], scenario.convention))

    subset = slice(0, count)
    result = {
        "problem": {
            "targets": args.n,
            "sigma_deg": args.sigma,
            "seed": args.seed,
            "bearings_per_target": len(times),
            "scenario": "seed 002 three-leg observer, prior start (see experiments/tma_montecarlo.py)",
        },
        "batched_lm": {
            "solver": "levenberg_marquardt_batch",
            "engine": "numba kernel (_tma_kernel)" if BatchLevenbergMarquardt().compiled else "numpy",
            "first_call_s": first_call,
            "first_call_note": "untimed warm-up on 4 targets before the repeats (numba compile, or load from its cache)",
            "settings": attrs_dict(settings),
            "wall_time_s": lm_total,
            "wall_times_s": lm_times,
            "timing": "fastest of the interleaved repeats",
            "per_target_ms": 1e3 * lm_total / args.n,
            "iterations_mean": float(lm.iterations.mean()),
            "evaluations_mean": float(lm.evaluations.mean()),
            "converged_rate": float(lm.converged.mean()),
            "converged_rate_on_scipy_subset": float(lm.converged[subset].mean()),
            "ref_on_scipy_subset": refs(lm.parameters[subset], subset),
            "ref_all": refs(lm.parameters, slice(None)),
        },
        "numpy_engine": None
        if not compiled
        else {
            "solver": 'levenberg_marquardt_batch, engine="numpy" (the fallback without numba)',
            "wall_time_s": float(np.min(np_times)),
            "wall_times_s": np_times,
            "timing": "fastest of the interleaved repeats",
            "per_target_ms": 1e3 * float(np.min(np_times)) / args.n,
            "same_iterations_and_evaluations": float(
                np.mean((lm_numpy.iterations == lm.iterations) & (lm_numpy.evaluations == lm.evaluations))
            ),
            "max_relative_parameter_difference": float(
                np.max(np.abs(lm_numpy.parameters - lm.parameters) / np.abs(lm.parameters).max(axis=1, keepdims=True))
            ),
            "converged_rate": float(lm_numpy.converged.mean()),
        },
        "scipy_loop": {
            "call": 'least_squares(fun, x0, jac=analytic, method="lm"), default tolerances, same scaled start',
            "timed_targets": count,
            "scaled_to_targets": args.n,
            "note": f"timed on the first {count} targets and scaled by {args.n}/{count}; only the least_squares calls are timed",
            "wall_time_subset_s": float(np.min(sp_times)),
            "wall_times_subset_s": sp_times,
            "timing": "fastest of the interleaved repeats",
            "wall_time_scaled_s": sp_total,
            "per_target_ms": 1e3 * sp_per,
            "njev_mean": float(np.mean([r.njev for r in sp_answers])),
            "nfev_mean": float(np.mean([r.nfev for r in sp_answers])),
            "success_rate": float(np.mean([r.status > 0 for r in sp_answers])),
            "ref_on_subset": refs(sp_theta, subset),
        },
        "speedup": sp_total / lm_total,
        "speedup_numpy_engine": sp_total / float(np.min(np_times)) if compiled else None,
        "target_speedup": 20.0,
        "machine": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "numba": numba_version(),
            "load_average_1_5_15_min": {"before": [round(v, 2) for v in load_before], "after": [round(v, 2) for v in os.getloadavg()]},
            "processor": platform.processor() or platform.machine(),
            "cpu_count": os.cpu_count(),
            "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
        },
    }
    print(json.dumps(result, indent=2, ensure_ascii=False))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2, ensure_ascii=False) + "\n")
    return 0


def numba_version():
    try:
        import numba
    except ImportError:
        return None
    return numba.__version__


def attrs_dict(settings):
    import attrs

    return attrs.asdict(settings)


if __name__ == "__main__":
    raise SystemExit(main())
