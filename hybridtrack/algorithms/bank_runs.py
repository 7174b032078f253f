"""What the bank algorithms share: the run that is the batch of one, and the R runs of an SPRT bank
(:mod:`.known_switch`, :mod:`.unknown_change`) checked, grouped into banks and handed to their recorders.

The banks' step convention (as the Pipeline): step 0 updates the prior with z_0; step k ≥ 1 predicts over
Δt_k = t_k − t_{k−1} and updates.  The recording of a run is :mod:`hybridtrack.recording.adaptive`
(``recorder.log_result``).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from hybridtrack.engine.batch import batch_times, per_run, prior_arrays, run_groups, stacked_measurements


def run_alone(algorithm, measurements: Mapping[str, np.ndarray], *args, recorder=None, truth=None, **options):
    """``algorithm.run_batch`` of one run: ``measurements`` sensor name → (K+1, m), ``recorder`` the run's, if any;
    ``args`` and ``options`` go to ``run_batch`` as given."""
    z = algorithm.network.stack(measurements)
    recorders = None if recorder is None else {0: recorder}
    return algorithm.run_batch(algorithm.network.split(z[None]), *args, truth=[truth], recorders=recorders, **options)[0]


def run_banks(algorithm, runs_of: Callable[..., list], measurements, prior, times, truth, recorders, **context) -> list:
    """The R runs of an SPRT-bank ``algorithm``; each run's result is what it gives alone (to rounding, 1e-12).

    ``measurements``: sensor name → (R, K+1, m); ``times`` (K+1,) shared or
    (R, K+1) per run (default 0, τ, 2τ, …); ``prior`` one Gaussian or per-run
    (means (R, n), covs (n, n) or (R, n, n)); ``truth`` one per run
    (recordings only); ``recorders`` run index → Recorder for the runs to
    record.  ``runs_of(z, t, dt, x0, P0, recorded)`` runs the runs of one bank
    (z (R, K+1, Σm), t (R, K+1), Δt (R, K), priors (R, n), (R, n, n),
    ``recorded`` the runs that keep their hypotheses' positions): all runs at
    once, except that runs of a decentralized or sampling estimator each form
    their own batch of one (:func:`~hybridtrack.engine.batch.run_groups`).
    Each recorded run goes to ``recorder.log_result`` with its measurements,
    the sensors, its truth, the algorithm's name, the detector's label and
    ``context``.
    """
    z = stacked_measurements(algorithm.network, measurements)
    R = z.shape[0]
    t, dt = batch_times(times, algorithm.tau, R, z.shape[1])
    x0, P0 = prior_arrays(prior, R, len(algorithm.layout))
    truths = per_run(truth, R, "truth")
    recorders = {r: x for r, x in enumerate(per_run(recorders, R, "recorders")) if x is not None}
    runs = []
    for g in run_groups(algorithm.estimator, R):
        runs += runs_of(z[g], t[g], dt[g], x0[g], P0[g], [i for i, r in enumerate(g) if r in recorders])
    for r, recorder in sorted(recorders.items()):
        recorder.log_result(
            runs[r],
            measurements=algorithm.network.split(z[r]),
            sensors=algorithm.network.sensors,
            truth=truths[r],
            name=algorithm.name,
            detector=algorithm.detector.label,
            **context,
        )
    return runs


#: the step (s) between the unmeasured steps that pad a shorter run to its batch's length (:func:`run_ragged`)
PAD_STEP = 1e-3


def run_ragged(algorithm, measurements: Sequence[Mapping[str, np.ndarray]], priors: Sequence, times: Sequence, **options) -> list:
    """Runs of different lengths (objects of one file) as one batch of ``algorithm.run_batch``: run r's
    ``measurements[r]`` (sensor name → (K_r+1, m)) at ``times[r]`` (K_r+1,) from ``priors[r]`` ((mean, cov), all in one
    layout), padded after its last report to the longest run with unmeasured steps (NaN) :data:`PAD_STEP` s apart, and
    each result cut back to its K_r+1 steps (``RunResult.first_steps``): what the run gives alone, to rounding (the
    padding follows its last step; a run's arithmetic never mixes with another's).  An algorithm whose ``run_batch``
    takes ``lengths`` (the multiple-model estimators) is given them and does not filter the padding at all.
    ``options`` go to ``run_batch``."""
    lengths = [len(np.asarray(t)) for t in times]
    if not (len(measurements) == len(priors) == len(lengths) > 0):
        raise ValueError(
            f"measurements, priors, times: expected one of each per run, got {len(measurements)}, {len(priors)}, {len(lengths)}"
        )
    longest = max(lengths)
    stacked = {}
    T = np.empty((len(lengths), longest))
    for r, (z, t, k) in enumerate(zip(measurements, times, lengths)):
        for name, values in z.items():
            values = np.asarray(values, dtype=float)
            if name not in stacked:
                stacked[name] = np.full((len(lengths), longest) + values.shape[1:], np.nan)
            stacked[name][r, :k] = values
        T[r, :k] = t
        T[r, k:] = T[r, k - 1] + PAD_STEP * np.arange(1, longest - k + 1)
    means = np.stack([np.asarray(p[0], dtype=float) for p in priors])
    covs = np.stack([np.asarray(p[1], dtype=float) for p in priors])
    if "lengths" in inspect.signature(algorithm.run_batch).parameters:  # the padding is not filtered at all
        options = {**options, "lengths": lengths}
    runs = algorithm.run_batch(stacked, (means, covs), times=T, **options)
    return [run.first_steps(k) for run, k in zip(runs, lengths)]


def record_run(algorithm, run, recorder, measurements: Mapping[str, np.ndarray], truth=None) -> None:
    """``recorder.log_result`` of one of ``algorithm``'s runs as its ``run_batch`` records it: the algorithm's name, its
    sensors, the run's ``measurements`` (sensor name → (K+1, m)), ``truth`` and, for an algorithm with a detector,
    the detector's label."""
    context = {"name": algorithm.name, "sensors": algorithm.network.sensors, "measurements": measurements, "truth": truth}
    if getattr(algorithm, "detector", None) is not None:
        context["detector"] = algorithm.detector.label
    recorder.log_result(run, **context)
