"""Multiple hypothesis tracking (hybridtrack.algorithms.multitarget.mht) against references: K = 1 is GNN; with no
pruning the best hypothesis is the best of a brute-force enumeration of every assignment sequence, and N-scan
pruning keeps exactly the sequences that share the best's old decisions; on a cluttered crossing scene it is at least
as good as GNN; the configuration's method = "mht" builds it."""

import itertools
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2, multivariate_normal

from hybridtrack import MultipleModelEstimator, gospa_over_time
from hybridtrack.algorithms.multitarget.management import MofN, TrackScore
from hybridtrack.algorithms.multitarget.mht import MHTTracker, best_sums
from hybridtrack.algorithms.multitarget.tracker import MultiTargetTracker, take_rows
from hybridtrack.apps.multitarget import association_settings, build_multitarget
from hybridtrack.apps.tracking import ConfigError, load_config
from hybridtrack.core.plugins import resolve
from hybridtrack.engine.detections import Detections
from hybridtrack.engine.scenes import crossing_scene

ROOT = Path(__file__).resolve().parents[2]
SIGMA = 10.0
KINEMATIC = ("x", "vx", "y", "vy")


def _estimator():
    sensor = resolve("sensor", ("position", {"noise_cov": SIGMA**2 * np.eye(2)}))
    return MultipleModelEstimator([("straight", {"noise_density": 1.0})], [[1.0]], sensors=[sensor])


def test_best_sums_equal_brute_force():
    rng = np.random.default_rng(5)
    for _ in range(20):
        lists = [np.concatenate([[0.0], np.sort(rng.exponential(1.0, int(rng.integers(0, 4))))]) for _ in range(int(rng.integers(1, 5)))]
        k = int(rng.integers(1, 12))
        totals, choices = best_sums(lists, k)
        every = sorted(sum(r[j] for r, j in zip(lists, js)) for js in itertools.product(*[range(r.size) for r in lists]))
        np.testing.assert_allclose(totals, every[:k], rtol=0, atol=1e-12)
        assert len({tuple(c) for c in choices.tolist()}) == len(choices)  # each sum once
        np.testing.assert_allclose([sum(r[j] for r, j in zip(lists, c)) for c in choices], totals, atol=1e-12)
        bound = float(np.median(every[:k]))
        below, _ = best_sums(lists, k, bound=bound)
        np.testing.assert_allclose(below, [v for v in every[:k] if v <= bound], rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("management", "initiation", "seed_window"),
    [(MofN(), "two_point", None), (TrackScore(), "two_point", None), (MofN(), "single_point", None), (TrackScore(), "two_point", 3.0)],
)
def test_one_hypothesis_is_gnn(management, initiation, seed_window):
    detections = crossing_scene(seed=11).head(80)
    options = dict(clutter_density=10 / 25e6, max_speed=40.0, management=management, initiation=initiation, seed_window=seed_window)
    gnn = MultiTargetTracker(_estimator(), association="gnn", **options).run(detections)
    mht = MHTTracker(_estimator(), hypotheses=1, scans=3, **options).run(detections)
    assert len(gnn.tracks) >= 15 and mht.started == gnn.started
    np.testing.assert_array_equal(mht.track_id, gnn.track_id)
    np.testing.assert_array_equal(mht.scan, gnn.scan)
    np.testing.assert_array_equal(mht.hit, gnn.hit)
    np.testing.assert_allclose(mht.means, gnn.means, rtol=0, atol=1e-9)
    np.testing.assert_allclose(mht.position_covs, gnn.position_covs, rtol=0, atol=1e-9)
    assert [(h.id, h.born, h.confirmed, h.deleted) for h in mht.tracks] == [(h.id, h.born, h.confirmed, h.deleted) for h in gnn.tracks]
    for a, b in zip(mht.tracks, gnn.tracks):
        np.testing.assert_array_equal(a.detections, b.detections)


# ---------------------------------------------------------------- a tiny ambiguous scene and its brute force
P_D, LAMBDA, P_G = 0.8, 2e-4, 0.999


def _tiny_scene():
    """Two targets closing in (20 m/s, 26 m apart at t = 3), two clutter points between them at scan 2, B missed
    at scan 3: 5 scans of 1 s."""
    rng = np.random.default_rng(3)
    t = np.arange(5.0)
    a = np.column_stack([20.0 * t, 10.0 * t])
    b = np.column_stack([20.0 * t, 80.0 - 8.0 * t])
    times, z = [], []
    for k in range(5):
        points = [a[k]] + ([b[k]] if k != 3 else [])
        if k == 2:
            points += [0.5 * (a[k] + b[k]) + [6.0, -4.0], 0.5 * (a[k] + b[k]) + [-9.0, 7.0]]
        points = np.array(points) + ([0.0, 0.0] if k < 2 else SIGMA * rng.standard_normal((len(points), 2)))
        times += [float(k)] * len(points)
        z.append(points)
    return Detections.from_times(np.array(times), np.vstack(z), scan=np.array(times, dtype=int))


def _sequences(detections, est):
    """Every assignment sequence of scans 2 … 4 for the two tracks started at scan 1 (each scan: each track a
    detection of its χ² gate or none, no detection twice), with its Σ s and each track's detections."""
    R = SIGMA**2 * np.eye(2)
    gamma = chi2.ppf(P_G, 2)
    z0, z1 = detections.at(0)[1], detections.at(1)[1]
    means = np.column_stack([z1[:, 0], z1[:, 0] - z0[:, 0], z1[:, 1], z1[:, 1] - z0[:, 1]])
    cov = np.zeros((4, 4))
    cov[np.ix_([0, 2], [0, 2])], cov[np.ix_([0, 2], [1, 3])], cov[np.ix_([1, 3], [0, 2])], cov[np.ix_([1, 3], [1, 3])] = R, R, R, 2 * R
    start = est.start(means, np.stack([cov, cov]), np.full((2, 2), np.nan), prior_layout=KINEMATIC)
    bounds = detections.bounds()
    out = []

    def extend(k, states, total, taken):
        if k == detections.scans:
            out.append((total, taken))
            return
        z = detections.at(k)[1]
        options = []
        for state in states:
            predicted = est.step(state, np.full((1, 2), np.nan), 1.0)
            zhat, S = predicted.mean[0, [0, 2]], predicted.cov[0][np.ix_([0, 2], [0, 2])] + R
            nu = z - zhat
            d2 = np.einsum("ni,ij,nj->n", nu, np.linalg.inv(S), nu)
            s = math.log(P_D) + np.atleast_1d(multivariate_normal(zhat, S).logpdf(z)) - math.log(LAMBDA) - math.log1p(-P_D * P_G)
            options.append([(None, 0.0, predicted)] + [(i, s[i], est.step(state, z[i : i + 1], 1.0)) for i in np.flatnonzero(d2 <= gamma)])
        for first, second in itertools.product(*options):
            if first[0] is not None and first[0] == second[0]:
                continue
            picks = [taken[j] + ([] if o[0] is None else [bounds[k].start + o[0]]) for j, o in enumerate((first, second))]
            extend(k + 1, [first[2], second[2]], total + first[1] + second[1], picks)

    extend(2, [take(start, 0), take(start, 1)], 0.0, [[0, 2], [1, 3]])
    starts = sum(  # ln(β_NT/λ) = 0 (β_NT = λ) + the second point's score, per track
        math.log(P_D) + multivariate_normal(z0[i], 2 * R + 15.0**2 * np.eye(2)).logpdf(z1[i]) - math.log(LAMBDA) for i in range(2)
    )
    return out, starts


def take(state, row):
    return take_rows(state, [row])


@pytest.mark.parametrize("scans", [10, 1])
def test_the_best_hypothesis_is_the_brute_force_best_and_pruning_keeps_the_best_s_old_decisions(scans):
    detections = _tiny_scene()
    est = _estimator()
    tracker = MHTTracker(
        est,
        hypotheses=100_000,
        scans=scans,
        detection_probability=P_D,
        clutter_density=LAMBDA,
        gate_probability=P_G,
        management=MofN(2, 3, 5),
        max_speed=30.0,
        velocity_sigma=15.0,
    )
    result, scores = tracker.run_hypotheses(detections)
    assert result.started == 2 and [h.id for h in result.tracks] == [1, 2]  # the scene's only families: no other start
    sequences, starts = _sequences(detections, est)
    totals = np.array([total for total, _ in sequences]) + starts
    best = sequences[int(np.argmax(totals))]
    assert len(sequences) > 20  # an ambiguous scene
    assert scores[0] == pytest.approx(totals.max(), abs=1e-9)
    assert sorted(h.detections.tolist() for h in result.tracks) == sorted(sorted(p) for p in best[1])
    if scans >= detections.scans:  # no pruning: every sequence is a hypothesis
        np.testing.assert_allclose(np.sort(scores), np.sort(totals), rtol=0, atol=1e-9)
    else:  # N = 1: the hypotheses left are the sequences that agree with the best up to the last scan
        scan = detections.scan
        last = detections.scans - 1
        same = [
            all([d for d in p if scan[d] < last] == [d for d in q if scan[d] < last] for p, q in zip(taken, best[1]))
            for _, taken in sequences
        ]
        np.testing.assert_allclose(np.sort(scores), np.sort(totals[np.array(same)]), rtol=0, atol=1e-9)
        assert scores.size < totals.size


def test_on_a_cluttered_crossing_scene_mht_is_at_least_as_good_as_gnn():
    detections = crossing_scene(seed=14, detection_probability=0.7, clutter_per_scan=50.0, scans=100)
    options = dict(clutter_density=50 / 25e6, detection_probability=0.7, max_speed=40.0, management=TrackScore())
    truth = detections.truth
    found = {}
    for name, tracker in (
        ("gnn", MultiTargetTracker(_estimator(), association="gnn", **options)),
        ("mht", MHTTracker(_estimator(), hypotheses=10, scans=3, **options)),
    ):
        result = tracker.run(detections)
        series = gospa_over_time(truth.times, truth.ids, truth.positions, result.time, result.track_id, result.positions(), c=100.0)
        found[name] = (float(series.distance.mean()), series.track_quality().id_switches)
    assert found["mht"][0] < found["gnn"][0]  # measured: 229.7 against 240.7 (c = 100 m, 20 targets)
    assert found["mht"][1] <= found["gnn"][1]  # 1 against 3


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="hypotheses"):
        MHTTracker(_estimator(), hypotheses=0)
    with pytest.raises(ValueError, match="scans"):
        MHTTracker(_estimator(), scans=0)
    with pytest.raises(ValueError, match="updates_per_scan"):
        MHTTracker(_estimator(), updates_per_scan=2)
    with pytest.raises(ValueError, match="association"):
        MHTTracker(_estimator(), association="gnn")
    with pytest.raises(TypeError, match="Detections"):
        MHTTracker(_estimator()).run(np.zeros((3, 2)))


def test_the_configuration_builds_mht_and_names_its_faults():
    config = tomllib.loads((ROOT / "examples" / "multitarget.toml").read_text())
    config["association"] |= {"method": "mht", "hypotheses": 7, "mht_scans": 2}
    checked = load_config(config)
    tracker = build_multitarget(checked, association_settings(checked))
    assert isinstance(tracker, MHTTracker) and (tracker.hypotheses, tracker.scans, tracker.association) == (7, 2, "mht")
    for key, value in (("hypotheses", 0), ("mht_scans", 1.5)):
        bad = load_config(config | {"association": config["association"] | {key: value}})
        with pytest.raises(ConfigError, match=rf"\[association\] {key} = {value!r}; expected a positive integer"):
            association_settings(bad)
    bad = load_config(config | {"association": config["association"] | {"updates_per_scan": 2}})
    with pytest.raises(ConfigError, match="updates_per_scan"):
        build_multitarget(bad, association_settings(bad))
    plain = load_config(tomllib.loads((ROOT / "examples" / "multitarget.toml").read_text()))
    assert type(build_multitarget(plain, association_settings(plain))) is MultiTargetTracker
