"""What a person sees in the viewer: 3-D east-north-up views, colours, one panel per quantity, every entity in a view.

The blueprint and the data are read back from the files (``RecordingFile.blueprint_views``,
``rerun.chunk.RrdReader``, ``rerun rrd print``), not from the objects that wrote them.
"""

import importlib.util
from itertools import combinations
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.engine.schedule import Schedule, Segment
from hybridtrack.engine.simulate import simulate
from hybridtrack.recording import TRAIL_STEPS, RerunRecorder, content_blueprint, nis_bounds, palette, series_style, spatial_style
from hybridtrack.recording.inspection import RecordingFile, view_selects
from hybridtrack_plugins.sensors.position import PositionSensor

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def chunks(path):
    """(entity path, record batch) of every chunk of the file's recording store."""
    import rerun as rr

    return [(c.entity_path, c.to_record_batch()) for c in rr.chunk.RrdReader(str(path)).stream()]


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "demo.rrd"
    load("demo").main(["--out", str(out), "--steps-scale", "0.2"])
    return out


@pytest.fixture(scope="module")
def example1(tmp_path_factory):
    out = tmp_path_factory.mktemp("example1") / "example1.rrd"
    load("example1_unknown_change").main(["--out", str(out), "--seed", "0"])
    return out


def test_demo_recording_holds_3d_archetypes_and_world_is_east_north_up(demo, rerun_cli):
    printed = rerun_cli("rrd", "print", demo)
    assert printed.returncode == 0, printed.stderr
    assert "Points3D:positions" in printed.stdout and "LineStrips3D:strips" in printed.stdout
    assert "Points2D" not in printed.stdout and "LineStrips2D" not in printed.stdout
    coordinates = {
        entity: batch.column("ViewCoordinates:xyz").to_pylist()
        for entity, batch in chunks(demo)
        if "ViewCoordinates:xyz" in batch.schema.names
    }
    # rerun's ViewDir codes: Up = 1, Right = 3, Forward = 5 → x right (east), y forward (north), z up
    assert coordinates["/world"] == [[[3, 5, 1]]]
    assert coordinates["/spacetime"] == [[[3, 5, 1]]]


def signed_area(points: np.ndarray) -> float:
    """Shoelace area ½ Σ (x_i y_{i+1} − x_{i+1} y_i) of the closed polygon: > 0 anticlockwise."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


@pytest.mark.parametrize("turn, sign", [("left_turn", 1.0), ("right_turn", -1.0)])
def test_a_simulated_left_turn_is_anticlockwise_in_the_logged_east_north_coordinates(tmp_path, turn, sign):
    """40 steps of 0.1 s at 2 m/s on r = 5 m, no process noise: the 41 points lie on an arc of θ = 8/5 rad; the
    polygon they make, closed by the chord, has area (r²/2)(N sin(θ/N) − sin θ), N = 40 (fan of triangles from the centre)."""
    path = tmp_path / "turn.rrd"
    sensor = PositionSensor(name="pos", components=("x", "y"), noise_cov=1e-4 * np.eye(2))
    with RerunRecorder(path, {"turn": turn}) as recorder:
        simulate(Schedule([Segment(turn, 40, 5.0)]), [0.0, 0.0, 0.0, 2.0], 0.1, [sensor], seed=0, process_noise=False, recorder=recorder)
    steps, east_north = RecordingFile(path).points("world/truth")
    assert steps.tolist() == list(range(41))
    theta = 0.1 * 40 * 2.0 / 5.0
    np.testing.assert_allclose(signed_area(east_north), sign * 12.5 * (40 * np.sin(theta / 40) - np.sin(theta)), rtol=1e-5)
    _, up = RecordingFile(path).points("world/truth", dims=3)
    np.testing.assert_array_equal(up[:, 2], 0.0)  # no altitude in this data: z = 0


def test_altitude_is_logged_as_up(tmp_path):
    path = tmp_path / "climb.rrd"
    xyz = np.column_stack([np.arange(5.0), np.zeros(5), 100.0 + 10 * np.arange(5.0)])
    with RerunRecorder(path) as recorder:
        recorder.log_path("world/truth", np.arange(5), xyz, np.arange(5) * 1.0)
    _, points = RecordingFile(path).points("world/truth", dims=3)
    np.testing.assert_allclose(points, xyz)


def test_palette_is_stable_distinct_for_a_bank_and_shared_by_every_view(demo):
    assert palette("left_turn_r3") == palette("left_turn_r3") == (94, 237, 130)
    assert palette("truth") != palette("measurements")
    bank = ["straight"] + [f"{turn}_r{r}" for turn in ("left_turn", "right_turn") for r in range(1, 11)]
    colours = np.array([palette(n) for n in bank], dtype=float)
    distances = [np.abs(a - b).sum() for a, b in combinations(colours, 2)]
    assert min(distances) >= 12  # every pair of the 21 filters differs
    with pytest.raises(TypeError, match="name"):
        palette(3)
    # the same filter has the same colour in the 3-D view and in every time-series panel
    styles = {}
    for entity, batch in chunks(demo):
        for column in ("Points3D:colors", "SeriesLines:colors", "LineStrips3D:colors"):
            if column in batch.schema.names:
                styles.setdefault(entity, batch.column(column).to_pylist()[0][0])
    rgba = lambda name: int.from_bytes(bytes([*palette(name), 255]), "big")  # noqa: E731
    assert styles["/world/estimate/known_modes"] == styles["/estimator/known_modes/nis"] == rgba("known_modes")
    assert styles["/world/truth"] == rgba("truth") and styles["/world/measurements/plotter"] == rgba("measurements")


def test_series_are_named_after_their_hypothesis_and_thresholds_after_a_and_b():
    assert series_style("detector/sprt/log_ratio/left_turn_r3", 1) == (["ln λ left_turn_r3"], [palette("left_turn_r3")])
    assert series_style("detector/sprt/upper", 1)[0] == ["A (upper)"]
    assert series_style("detector/signal_function/lower", 1)[0] == ["−3 bound"]
    assert series_style("estimator/straight/nis", 1) == (["straight"], [palette("straight")])
    names, colours = series_style("estimator/straight/innovation", 2)
    assert names == ["straight [0]", "straight [1]"] and colours[0] == palette("straight") and colours[1] != colours[0]
    assert spatial_style("world/estimate/straight/ellipse") == (palette("straight"), "straight")


def test_no_line_joins_two_periods_a_hypothesis_was_out_of_play(example1):
    """ln λ of an alternative is logged on every step, NaN where it is not in play: rerun breaks the line at NaN
    (one series per mode it is weighed against: left_turn_r5 against straight, then against right_turn_r5)."""
    rec = RecordingFile(example1)
    steps, ratio = rec.series("detector/sprt_unknown_change/log_ratio/left_turn_r5")
    assert steps.tolist() == list(range(steps[0], steps[-1] + 1))  # no step missing: the gap is explicit
    assert ratio.shape == (steps.size, 2)
    assert np.isnan(ratio).any(axis=0).all() and np.isfinite(ratio).any(axis=0).all()
    assert np.isnan(ratio[0]).all()  # step 0: no alternative yet
    assert not (np.isfinite(ratio[:, 0]) & np.isfinite(ratio[:, 1])).any()  # one pair at a time


def test_each_quantity_has_its_own_panel(demo, example1):
    for path in (demo, example1):
        views = RecordingFile(path).blueprint_views()
        classes = sorted(v["class"] for v in views)
        assert classes.count("3D") == 2 and ("TextLog" in classes) == bool(RecordingFile(path).events())
        series = [v for v in views if v["class"] == "TimeSeries"]
        for view in series:
            quantities = {rule.split("/")[1] if "/detector/" in rule else rule.rstrip("/*").split("/")[-1] for rule in view["contents"]}
            quantities -= {"nis_bounds"}  # the χ² bounds go with NIS
            assert len(quantities) == 1, view
    names = {v["name"] for v in RecordingFile(example1).blueprint_views()}
    assert {"Bank size (filters running)", "Signal function with its bounds (signal_function)"} <= names
    world = next(v for v in RecordingFile(demo).blueprint_views() if v["origin"] == "/world")
    assert world["name"] == "World (east, north, up)"


def test_the_space_time_view_marks_switches_and_decisions_and_colours_the_estimate_by_mode(example1):
    batches = dict(chunks(example1))
    switch = batches["/spacetime/truth/changes"]
    assert switch.column("Points3D:labels").to_pylist()[0] == ["truth → right_turn_r5 (step 21)"]  # state 21: the first of the turn
    z = np.array(switch.column("Points3D:positions").to_pylist()[0])[:, 2]
    decisions = batches["/spacetime/decisions"]
    decided = np.array(decisions.column("Points3D:positions").to_pylist()[0])[:, 2]
    assert np.all(decided > z)  # the decision comes after the switch: higher on the time axis
    estimate = batches["/spacetime/estimate/example1"]
    labels = estimate.column("LineStrips3D:labels").to_pylist()[0]
    assert labels[0] == "straight" and "right_turn_r5" in labels
    rgba = lambda name: int.from_bytes(bytes([*palette(name), 255]), "big")  # noqa: E731
    assert estimate.column("LineStrips3D:colors").to_pylist()[0] == [rgba(n) for n in labels]


def test_view_selects_follows_rerun_entity_filter_rules():
    assert view_selects(["$origin/**"], "/world", "/world/truth")
    assert view_selects(["$origin/**"], "/world", "/world")
    assert not view_selects(["$origin/**"], "/world", "/worlds/x")
    assert view_selects(["+ /a/b"], "/", "/a/b") and not view_selects(["+ /a/b"], "/", "/a/b/c")
    assert not view_selects(["+ /a/**", "- /a/b/**"], "/", "/a/b/c")
    assert view_selects(["+ /a/**", "- /a/b/**", "+ /a/b/c"], "/", "/a/b/c")
    assert not view_selects([], "/", "/a")


def test_nis_bounds_are_the_chi_square_95_percent_interval():
    bounds = nis_bounds(np.array([2, 1, 0]))
    np.testing.assert_allclose(bounds[0], [-2 * np.log(0.975), -2 * np.log(0.025)], rtol=1e-9)  # χ²(2): F⁻¹(p) = −2 ln(1 − p)
    np.testing.assert_allclose(bounds[1], [0.000982069117, 5.023886187314], rtol=1e-8)
    assert np.isnan(bounds[2]).all()


def test_trail_keeps_the_last_measurements_visible():
    import rerun.blueprint as rrb

    blueprint = content_blueprint({"world/truth": "3D", "estimator/a/nis": "TimeSeries"}, time_step=0.1)
    assert isinstance(blueprint, rrb.Blueprint) and TRAIL_STEPS >= 10


def _coverage(path):
    rec = RecordingFile(path)
    assert rec.unviewed_entities() == [], f"{path.name}: entities in no view"
    assert len(rec.entity_paths) > 5
    return rec


def test_every_logged_entity_is_in_a_view_demo_and_example1(demo, example1):
    rec = _coverage(demo)
    assert "/world/measurements/rangefinder" in rec.entity_paths  # the x-only rangefinder: a scalar panel
    _coverage(example1)


def test_every_logged_entity_is_in_a_view_bearings_only(tmp_path):
    out = tmp_path / "tma.rrd"
    load("bearings_only").main(["--out", str(out), "--interval", "20", "--sigma", "0.2"])
    rec = _coverage(out)
    residuals = next(v for v in rec.blueprint_views() if v["name"] == "Bearing residuals (degrees)")
    assert all(view_selects(residuals["contents"], "/", e) for e in rec.entity_paths if e.startswith("/solver/"))


def test_every_logged_entity_is_in_a_view_clutter_and_imm(tmp_path, clutter_scenario, clutter_pipeline):
    from hybridtrack.algorithms.multiple_model import MultipleModelEstimator

    truth, sensor, scans = clutter_scenario()
    path = tmp_path / "clutter.rrd"
    with RerunRecorder(path, {"seed": 2}) as recorder:
        pda = ("pda", {"detection_probability": 0.9, "clutter_density": 0.5})
        clutter_pipeline(pda, sensor, scans, detectors=["sprt_pairwise"], recorder=recorder, truth=truth).run()
    rec = _coverage(path)
    assert {"/world/clutter/pos", "/estimator/straight/beta", "/estimator/nis_bounds"} <= set(rec.entity_paths)
    names = {v["name"] for v in rec.blueprint_views()}
    assert {"Association weights β", "NIS (normalized innovation squared) with the χ² 95 % bounds"} <= names
    text = [t for _, _, t in rec.events()]
    assert not any(" H0" in t or " H1" in t for t in text)  # decisions name the filters

    imm_path = tmp_path / "imm.rrd"
    z = {"pos": truth.positions + 0.1 * np.random.default_rng(0).standard_normal(truth.positions.shape)}
    imm = MultipleModelEstimator(
        ["straight", ("right_turn", {"radius": 5.0})], [[0.95, 0.05], [0.05, 0.95]], sensors=[sensor], tau=0.1, name="imm"
    )
    with RerunRecorder(imm_path) as recorder:
        imm.run(z, (np.array([0.0, 0.0, 0.0, 2.0]), np.eye(4)), recorder=recorder, truth=truth)
    rec = _coverage(imm_path)
    assert "Mode probabilities μ" in {v["name"] for v in rec.blueprint_views()}


@pytest.mark.slow
def test_every_logged_entity_is_in_a_view_ships_config(tmp_path):
    from hybridtrack.apps.tracking import track_file
    from hybridtrack.io.track_files import SOLENT_AIS, read_tracks

    solent = ROOT / "data" / "solent_ais" / "SolentAIS_20160112_130211.csv"
    ids = list(read_tracks(solent, **SOLENT_AIS, warn=False).tracks)[:1]
    track_file(solent, EXAMPLES / "ships.toml", tmp_path, ids=ids)
    for path in sorted(tmp_path.glob("*.rrd")):
        _coverage(path)
