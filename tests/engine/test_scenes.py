"""Simulated multi-target scenes: the statistics of detections and clutter against their model (tolerances from the
binomial / Poisson / normal standard errors), truth consistent with the detections' origin, the exact coordinated
turn against the ``coordinated_turn`` motion model, lives and determinism."""

import math

import numpy as np
import pytest

from hybridtrack.engine.detections import Detections
from hybridtrack.engine.scenes import DEFAULT_REGION, SCENE_LAYOUT, coordinated_turn_step, crossing_scene, simulate_scene
from hybridtrack_plugins.motion.real_motion import CoordinatedTurn

#: tolerance in standard errors: a fixed-seed test far from flaky yet tight enough to catch a wrong model
SE = 4.0


@pytest.fixture(scope="module")
def scene() -> Detections:
    return crossing_scene(seed=11)


def truth_of(d: Detections):
    """The truth row of every target detection (a dict (scan time, id) → row)."""
    rows = {(t, i): r for r, (t, i) in enumerate(zip(d.truth.times.tolist(), d.truth.ids.tolist()))}
    target = np.flatnonzero(d.origin >= 0)
    return target, np.array([rows[(d.times[i], d.origin[i])] for i in target.tolist()], dtype=np.intp)


def test_crossing_scene_is_the_issue_scene(scene):
    assert scene.scans == 200 and np.array_equal(scene.scan_times, np.arange(200.0))
    assert scene.truth.layout == SCENE_LAYOUT and scene.truth.objects == 20
    assert scene.truth.size == 20 * 200  # all alive throughout, inside the region
    assert np.array_equal(scene.times, scene.scan_times[scene.scan])


def test_detection_probability_within_binomial_error(scene):
    n = scene.truth.size
    detected = int((scene.origin >= 0).sum())
    assert abs(detected / n - 0.9) <= SE * math.sqrt(0.9 * 0.1 / n)
    per_target = np.bincount(scene.origin[scene.origin >= 0], minlength=20) / 200
    assert np.all(np.abs(per_target - 0.9) <= SE * math.sqrt(0.9 * 0.1 / 200))


def test_clutter_count_and_region(scene):
    clutter = scene.origin == -1
    per_scan = np.bincount(scene.scan[clutter], minlength=scene.scans)
    assert abs(per_scan.mean() - 10.0) <= SE * math.sqrt(10.0 / scene.scans)
    assert abs(per_scan.var(ddof=1) / 10.0 - 1.0) <= SE * math.sqrt(
        2.0 / (scene.scans - 1) + 1.0 / 10.0 / scene.scans
    )  # Poisson: var = mean
    (x0, x1), (y0, y1) = DEFAULT_REGION
    z = scene.z[clutter]
    assert np.all((z[:, 0] >= x0) & (z[:, 0] <= x1) & (z[:, 1] >= y0) & (z[:, 1] <= y1))
    for axis, (lo, hi) in enumerate(DEFAULT_REGION):  # uniform: mean (lo + hi)/2, σ = (hi − lo)/√12
        se = (hi - lo) / math.sqrt(12.0 * z.shape[0])
        assert abs(z[:, axis].mean() - (lo + hi) / 2) <= SE * se
    p = scene.truth.positions
    assert np.all((p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1))


def test_detections_scatter_around_the_truth_with_sigma(scene):
    target, rows = truth_of(scene)
    residual = scene.z[target] - scene.truth.positions[rows]
    n = residual.shape[0]
    assert np.all(np.abs(residual.mean(axis=0)) <= SE * 10.0 / math.sqrt(n))
    assert np.all(np.abs(residual.std(axis=0, ddof=1) / 10.0 - 1.0) <= SE / math.sqrt(2.0 * (n - 1)))
    assert abs(np.corrcoef(residual.T)[0, 1]) <= SE / math.sqrt(n)


def test_order_within_a_scan_says_nothing_of_the_origin(scene):
    increasing = total = 0
    first_is_clutter = []
    for part in scene.bounds():
        origin = scene.origin[part]
        targets = origin[origin >= 0]
        increasing += int(np.sum(np.diff(targets) > 0))
        total += max(targets.size - 1, 0)
        first_is_clutter.append(origin.size > 0 and origin[0] == -1)
    # ascents of a random permutation of n: mean (n − 1)/2, variance (n + 1)/12 ≤ the binomial (n − 1)/4 used here
    assert abs(increasing / total - 0.5) <= SE * math.sqrt(0.25 / total)
    share = (scene.origin == -1).mean()
    assert abs(np.mean(first_is_clutter) - share) <= SE * math.sqrt(share * (1 - share) / scene.scans)


def test_motion_is_the_exact_coordinated_turn_with_piecewise_rates():
    d = simulate_scene(targets=30, scans=120, interval=2.0, turn_rate=(1.0, 3.0), clutter_per_scan=0.0, seed=5)
    model = CoordinatedTurn(max_rate=1.0)
    states = d.truth.states
    rates = []
    for i in range(30):
        s = states[d.truth.ids == i]  # consecutive scans (all alive, inside)
        speed = np.hypot(s[:, 1], s[:, 3])
        assert np.allclose(speed, speed[0], rtol=1e-12) and 5.0 <= speed[0] <= 15.0
        heading = np.unwrap(np.arctan2(s[:, 3], s[:, 1]))
        omega = np.diff(heading) / 2.0
        rates.append(omega)
        # each step from the previous state with the step's rate, through the motion model's f
        predicted = model.f(np.column_stack([s[:-1], omega]), 2.0)[:, :4]
        np.testing.assert_allclose(predicted, s[1:], rtol=0, atol=1e-8)
    rates = np.degrees(np.abs(np.concatenate(rates)))
    turning = rates > 1e-9
    assert 0.2 < turning.mean() < 0.8  # straight segments and turns
    assert np.all((rates[turning] >= 1.0 - 1e-9) & (rates[turning] <= 3.0 + 1e-9))


def test_coordinated_turn_step_at_zero_rate_and_against_the_model():
    x, vx, y, vy = (np.array([1.0, 2.0]), np.array([3.0, -1.0]), np.array([0.5, 0.0]), np.array([2.0, 4.0]))
    out = coordinated_turn_step(x, vx, y, vy, np.zeros(2), 1.5)
    np.testing.assert_array_equal(np.stack(out), np.stack([x + 1.5 * vx, vx, y + 1.5 * vy, vy]))
    omega = np.array([1e-9, -0.3])
    expected = CoordinatedTurn(max_rate=1.0).f(np.column_stack([x, vx, y, vy, omega]), 1.5)[:, :4]
    np.testing.assert_allclose(np.column_stack(coordinated_turn_step(x, vx, y, vy, omega, 1.5)), expected, rtol=1e-13, atol=1e-12)


def test_ramped_turns_rise_to_their_peak():
    d = simulate_scene(targets=20, scans=150, turn_rate=(2.0, 3.0), turn=(20.0, 30.0), ramp=5.0, clutter_per_scan=0.0, seed=3)
    rates = []
    for i in range(20):
        s = d.truth.states[d.truth.ids == i]
        rates.append(np.degrees(np.abs(np.diff(np.unwrap(np.arctan2(s[:, 3], s[:, 1]))))))
    rates = np.concatenate(rates)
    turning = rates > 1e-9
    assert np.all(rates <= 3.0 + 1e-9)
    assert np.any(turning & (rates < 2.0 * 0.5))  # the ramp's first steps: 1/5, 2/5 of a peak ≥ 2 °/s
    assert np.any(rates >= 2.0)


def test_births_and_deaths_within_the_scene():
    d = simulate_scene(targets=200, scans=100, births=True, lifetime=(10.0, 40.0), seed=8)
    ids, scans = d.truth.ids, np.rint(d.truth.times).astype(int)
    for i in np.unique(ids).tolist():
        k = scans[ids == i]
        assert np.all(np.diff(k) == 1)  # present at consecutive scans (paths fit the 5 km region)
        assert 10 <= k.size <= 40 and k[0] >= 0 and k[-1] <= 99
    assert np.unique(ids).size == 200
    alive = np.bincount(scans, minlength=100)
    assert alive.min() > 0 and alive.max() < 200
    target, rows = truth_of(d)
    assert rows.size == target.size  # every target detection has its truth row at its scan


def test_targets_outside_the_region_are_neither_detected_nor_truth():
    d = simulate_scene(targets=50, scans=100, region=((0.0, 300.0), (0.0, 300.0)), clutter_per_scan=1.0, seed=9)
    p = d.truth.positions
    assert np.all((p >= 0.0) & (p <= 300.0))
    assert d.truth.size < 50 * 100  # paths of 500–1500 m leave a 300 m region
    counts = np.bincount(d.truth.ids, minlength=50)
    assert np.all(counts >= 1)  # every target starts inside
    target, rows = truth_of(d)
    assert target.size == int((d.origin >= 0).sum())


def test_same_seed_same_scene():
    a, b = crossing_scene(seed=2), crossing_scene(seed=2)
    for name in ("scan_times", "scan", "times", "z", "origin"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    assert np.array_equal(a.truth.states, b.truth.states)
    c = crossing_scene(seed=3)
    assert not np.array_equal(a.truth.states, c.truth.states)
    g = simulate_scene(targets=3, scans=5, seed=np.random.default_rng(1))
    assert g.truth.size == 15


def test_no_targets_and_no_clutter():
    d = simulate_scene(targets=0, scans=4, clutter_per_scan=0.0, seed=1)
    assert d.size == 0 and d.scans == 4 and d.truth.size == 0 and d.counts().tolist() == [0, 0, 0, 0]
    d = simulate_scene(targets=5, scans=10, detection_probability=1.0, clutter_per_scan=0.0, sigma=0.0, seed=1)
    assert d.size == 50
    target, rows = truth_of(d)
    np.testing.assert_array_equal(d.z[target], d.truth.positions[rows])


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (dict(targets=-1), "targets: expected an integer ≥ 0"),
        (dict(scans=0), "scans: expected an integer ≥ 1"),
        (dict(interval=0.0), "interval: expected a number > 0"),
        (dict(region=((0, 1), (5, 2))), "region: expected x1 > x0 and y1 > y0"),
        (dict(region=(0, 1)), r"region: expected \(\(x0, x1\), \(y0, y1\)\)"),
        (dict(detection_probability=1.5), "detection_probability: expected P_D in"),
        (dict(clutter_per_scan=-1.0), "clutter_per_scan: expected a number ≥ 0"),
        (dict(speed=(15.0, 5.0)), "speed: expected low ≤ high"),
        (dict(turn_rate=(1.0,)), r"turn_rate: expected a range \(low, high\)"),
        (dict(straight=(0.0, 5.0)), r"straight\[0\]: expected a number > 0"),
        (dict(sigma=math.nan), "sigma: expected a finite number"),
        (dict(births=1), "births: expected True or False"),
        (dict(births=True, lifetime=(-1.0, 5.0)), r"lifetime\[0\]: expected a number > 0"),
    ],
)
def test_errors_name_the_input(changes, message):
    with pytest.raises((ValueError, TypeError), match=message):
        simulate_scene(**(dict(targets=2, scans=3) | changes))


def test_paths_cross(scene):
    paths = [scene.truth.positions[scene.truth.ids == i] for i in range(20)]

    def side(p, q, r):  # the sign of the turn p → q → r
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    crossing = 0
    for i in range(20):
        for j in range(i + 1, 20):
            a0, a1, b0, b1 = paths[i][:-1, None], paths[i][1:, None], paths[j][None, :-1], paths[j][None, 1:]
            crossing += bool(np.any((side(a0, a1, b0) != side(a0, a1, b1)) & (side(b0, b1, a0) != side(b0, b1, a1))))
    assert crossing >= 30  # of 190 pairs (34 with this seed; seeds 0, 1, 2: 43, 68, 41)
