"""Every registered clutter estimator on odd scans: empty (a missed detection, no clutter), single-candidate and
all-clutter (every candidate far from the track) (issue 24 item 3; plugins/filters/*, hybridtrack/sdk/scans.py).

The estimators are those of the registry that take clutter scans (``accepts_scans``), so a new one is tested
here without listing it.  Each is built from its ``example_parameters`` and the clutter settings of
:data:`SETTINGS` it takes (windows > 1, several hypotheses or components, a seeded particle cloud).  Checked on a
bank of two filters: no exception, finite means and covariances, symmetric positive semi-definite covariances,
and an empty scan leaves the mean and covariance equal to the prediction — the definition of a missed detection
without clutter in every one of them (NN, PDA, MSDA: nothing gated is prediction only; MHT: every hypothesis
continues as "missed"; PMHT: an empty scan adds no slot; the Gaussian sum and the particle filter: every
component or particle gets the same factor 1 − P_D P_G, so the weights do not change).
"""

import inspect

import numpy as np
import pytest

from hybridtrack import Gaussian, Pipeline
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.plugins import get_registry
from hybridtrack.engine.clutter import ScanSequence
from hybridtrack.sdk.scans import Scan
from hybridtrack.testing import example_parameters
from hybridtrack_plugins.filters.mht import MHTFilter
from hybridtrack_plugins.sensors.position import PositionSensor

REGISTRY = get_registry()
#: every registered estimator that associates candidate scans
CLUTTER_ESTIMATORS = [name for name in REGISTRY.names("estimator") if getattr(REGISTRY.get("estimator", name), "accepts_scans", False)]
#: clutter settings, passed to the factories that take them
SETTINGS = {
    "detection_probability": 0.9,
    "clutter_density": 0.01,
    "gate_probability": 0.99,
    "window": 3,
    "max_hypotheses": 5,
    "max_components": 4,
    "particles": 200,
    "seed": 0,
}
X0 = np.array([0.0, 0.0, 0.0, 2.0])
TAU = 0.1
SENSOR = PositionSensor("pos", ("x", "y"), np.eye(2) * 0.1)
MODEL = REGISTRY.create("motion_model", "straight", noise_cov=np.eye(2) * 0.1)
EMPTY = np.zeros((0, 2))
FAR = np.array([[1e3, 1e3], [-1e3, 5e2], [4e2, -9e2]])  # all clutter: thousands of σ from the track


def make(name: str):
    factory = REGISTRY.get("estimator", name)
    taken = inspect.signature(factory).parameters
    return factory(**{**example_parameters(factory), **{k: v for k, v in SETTINGS.items() if k in taken}})


def near(k: int, *offsets) -> np.ndarray:
    """Candidates close to the target's position at step k (x = 0, y = 2 k τ), one per offset (dx, dy)."""
    return np.array([[dx, 2.0 * TAU * k + dy] for dx, dy in offsets])


#: scan sequences, one candidate set (L, 2) per step
SEQUENCES = {
    "empty first": [EMPTY, EMPTY, near(2, (0.1, 0.0)), EMPTY, near(4, (0.0, -0.1)), EMPTY, EMPTY],
    "single candidates": [near(k, (0.05 * (-1) ** k, 0.02)) for k in range(8)],
    "missed and single": [near(0, (0, 0)), EMPTY, near(2, (0.1, 0.0)), EMPTY, EMPTY, near(5, (-0.1, 0.1)), EMPTY, near(7, (0, 0))],
    "all clutter": [near(0, (0, 0)), FAR, FAR, EMPTY, FAR, near(5, (0.1, 0.0)), FAR],
    "clutter around the target": [near(k, (0.05, 0.0), (1.5, 0.5), (-0.8, -1.2)) if k % 2 else FAR for k in range(8)],
}


def check_moments(estimator, state, where: str) -> None:
    mean, cov = estimator.mean(state), estimator.covariance(state)
    assert mean.shape == (2, 4) and cov.shape == (2, 4, 4), where
    assert np.all(np.isfinite(mean)) and np.all(np.isfinite(cov)), f"{where}: non-finite moments"
    np.testing.assert_allclose(cov, np.swapaxes(cov, -1, -2), rtol=1e-10, atol=1e-12, err_msg=f"{where}: covariance not symmetric")
    eigenvalues = np.linalg.eigvalsh(0.5 * (cov + np.swapaxes(cov, -1, -2)))
    assert np.all(eigenvalues >= -1e-10 * np.abs(eigenvalues).max()), f"{where}: covariance not PSD ({eigenvalues.min()})"


@pytest.mark.parametrize("sequence", list(SEQUENCES))
@pytest.mark.parametrize("name", CLUTTER_ESTIMATORS)
def test_odd_scans_keep_the_moments_finite_and_an_empty_scan_is_the_prediction(name, sequence):
    estimator = make(name)
    bank = TransitionBank.stack([MODEL.transition(TAU, X0)] * 2)
    state = estimator.initialize(np.stack([X0, X0 + 0.1]), np.stack([np.eye(4) * 0.1, np.eye(4) * 0.2]))
    for k, z in enumerate(SEQUENCES[sequence]):
        if k:
            state = estimator.predict(state, bank)
        predicted = estimator.mean(state).copy(), estimator.covariance(state).copy()
        state, innovation = estimator.update(state, Scan("pos", z), [SENSOR], MODEL.layout)
        where = f"{name}, {sequence}, step {k} ({len(z)} candidates)"
        check_moments(estimator, state, where)
        assert np.all(np.isfinite(innovation.loglik)), where
        if len(z) == 0:
            np.testing.assert_array_equal(estimator.mean(state), predicted[0], err_msg=f"{where}: the mean moved")
            np.testing.assert_array_equal(estimator.covariance(state), predicted[1], err_msg=f"{where}: the covariance moved")


@pytest.mark.parametrize("name", CLUTTER_ESTIMATORS)
def test_missed_detections_without_clutter_run_through_the_pipeline(name):
    """A ScanSequence whose missed steps are empty scans (no false measurement), as the Pipeline hands them over."""
    steps = 12
    points = [EMPTY if k % 3 == 1 else near(k, (0.05, 0.0)) for k in range(steps)]
    candidates = {"pos": ScanSequence("pos", points, [-1 if len(p) == 0 else 0 for p in points])}
    pipeline = Pipeline(
        models=[("straight", {"noise_cov": np.eye(2) * 0.1})],
        estimator=make(name),
        sensors=[SENSOR],
        candidates=candidates,
        prior=Gaussian(X0, np.eye(4) * 0.1),
        tau=TAU,
    )
    pipeline.run()
    assert pipeline.processed == steps
    assert np.all(np.isfinite(pipeline.means)) and np.all(np.isfinite(pipeline.covs))


def test_an_empty_scan_continues_every_mht_hypothesis_as_missed():
    """MHT: after an empty scan every live hypothesis is its prediction, its score rose by ln(1 − P_D P_G) and its
    newest decision is "missed" (−1); the probabilities (a softmax of the scores) do not change."""
    mht = MHTFilter(detection_probability=0.9, clutter_density=0.1, gate_probability=0.99, window=3, max_hypotheses=6)
    bank = TransitionBank.stack([MODEL.transition(TAU, X0)])
    state = mht.initialize(X0[None], np.eye(4)[None])
    state, _ = mht.update(state, Scan("pos", [[0.1, 0.0], [-0.2, 0.3]]), [SENSOR], MODEL.layout)
    before = mht.predict(state, bank)
    after, innovation = mht.update(before, Scan("pos", EMPTY), [SENSOR], MODEL.layout)
    live = np.isfinite(before.scores[0])
    assert live.sum() == 3 and np.array_equal(np.isfinite(after.scores[0]), live)
    np.testing.assert_allclose(after.scores[0, live], before.scores[0, live] + np.log(1 - 0.9 * 0.99), rtol=1e-14)
    np.testing.assert_array_equal(after.x[0, live], before.x[0, live])
    np.testing.assert_array_equal(after.P[0, live], before.P[0, live])
    np.testing.assert_array_equal(after.history[0, live, -1], -1)
    np.testing.assert_array_equal(after.history[0, live, :-1], before.history[0, live, 1:])
    np.testing.assert_allclose(after.probabilities, before.probabilities, rtol=1e-12)
    record = innovation.associations[0]
    assert record.candidates.shape == (0, 2) and record.selected[0] == -1 and record.missed[0] == pytest.approx(1.0)
    assert innovation.nu.shape == (1, 0) and innovation.loglik[0] == 0.0
