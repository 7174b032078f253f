"""What the bank algorithms share: the run that is the batch of one, and the R runs of an SPRT bank
(:mod:`.known_switch`, :mod:`.unknown_change`) checked, grouped into banks and handed to their recorders.

The banks' step convention (as the Pipeline): step 0 updates the prior with z_0; step k ≥ 1 predicts over
Δt_k = t_k − t_{k−1} and updates.  The recording of a run is :mod:`hybridtrack.recording.adaptive`
(``recorder.log_result``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

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
