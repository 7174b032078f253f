"""``hybridtrack track``: the vertical filter (altitude), the inverse projection and the map / 3-D views."""

from pathlib import Path

import numpy as np
import pytest

from hybridtrack.apps.tracking import filter_altitude, load_config, record_track, track_file
from hybridtrack.io.track_files import ecef_to_geodetic, geodetic_to_ecef, project, unproject
from hybridtrack.recording.inspection import RecordingFile

ORIGIN = (50.8, -1.2, 30.0)


def climbing_track(rng, K=200, rate=5.0, sigma=10.0):
    t = np.cumsum(np.r_[0.0, rng.uniform(2.0, 10.0, K - 1)])
    return t, 1000.0 + rate * t + rng.normal(0.0, sigma, K)


def test_steady_climb_rate_is_estimated_with_finite_variance():
    t, h = climbing_track(np.random.default_rng(3))
    mean, var = filter_altitude(t, h, sigma=10.0, acceleration_density=1e-4, velocity_sigma=5.0)
    assert mean.shape == var.shape == (200, 2)
    assert np.all(np.isfinite(var)) and np.all(var > 0)
    assert abs(mean[-1, 1] - 5.0) < 4 * np.sqrt(var[-1, 1]) and np.sqrt(var[-1, 1]) < 0.1
    assert np.sqrt(var[-1, 0]) < 10.0  # the filtered height beats one fix
    # the first estimate is the first fix (variance σ², the prior rate 0 with its σ_v²)
    np.testing.assert_allclose(mean[0], [h[0], 0.0])
    np.testing.assert_allclose(var[0], [100.0, 25.0])


def test_without_process_noise_the_filter_is_the_least_squares_line():
    """Hand check: with q → 0 (and a vague prior rate) the estimate is the straight-line fit h = a + b t, whose
    slope has variance σ²/Σ(t − t̄)² (≈ 0.002² m²/s² here): b and its variance to 0.5 %."""
    t, h = climbing_track(np.random.default_rng(3))
    mean, var = filter_altitude(t, h, sigma=10.0, acceleration_density=1e-12, velocity_sigma=1e4)
    slope, intercept = np.polyfit(t, h, 1)
    assert mean[-1, 1] == pytest.approx(slope, rel=1e-4)
    assert mean[-1, 0] == pytest.approx(intercept + slope * t[-1], abs=0.05)
    assert var[-1, 1] == pytest.approx(100.0 / np.sum((t - t.mean()) ** 2), rel=5e-3)
    assert abs(slope - 5.0) < 4 * np.sqrt(var[-1, 1])


def test_altitude_filter_equals_filterpy():
    filterpy = pytest.importorskip("filterpy.kalman")
    t, h = climbing_track(np.random.default_rng(5), K=60)
    q, sigma = 0.3, 7.0
    mean, var = filter_altitude(t, h, sigma=sigma, acceleration_density=q, velocity_sigma=3.0)
    kf = filterpy.KalmanFilter(dim_x=2, dim_z=1)
    kf.x = np.array([[h[0]], [0.0]])
    kf.P = np.diag([sigma**2, 9.0])
    kf.H = np.array([[1.0, 0.0]])
    kf.R = np.array([[sigma**2]])
    for k in range(1, t.size):
        dt = t[k] - t[k - 1]
        kf.F = np.array([[1.0, dt], [0.0, 1.0]])
        kf.Q = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        kf.predict()
        kf.update(np.array([[h[k]]]))
        np.testing.assert_allclose(mean[k], kf.x[:, 0], rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(var[k], np.diag(kf.P), rtol=1e-9, atol=1e-12)


def test_altitude_filter_refuses_bad_input():
    with pytest.raises(ValueError, match="times"):
        filter_altitude([0.0, 0.0, 1.0], [1.0, 2.0, 3.0], sigma=1.0, acceleration_density=1.0, velocity_sigma=1.0)
    with pytest.raises(ValueError, match="heights"):
        filter_altitude([0.0, 1.0], [1.0, np.nan], sigma=1.0, acceleration_density=1.0, velocity_sigma=1.0)
    with pytest.raises(ValueError, match="sigma"):
        filter_altitude([0.0, 1.0], [1.0, 2.0], sigma=-1.0, acceleration_density=1.0, velocity_sigma=1.0)


def test_unproject_inverts_project_and_agrees_with_pymap3d():
    rng = np.random.default_rng(0)
    lat = ORIGIN[0] + rng.uniform(-0.5, 0.5, 50)
    lon = ORIGIN[1] + rng.uniform(-0.7, 0.7, 50)
    h = rng.uniform(0.0, 10000.0, 50)
    enu = project(lat, lon, h, origin=ORIGIN)
    back = unproject(enu, origin=ORIGIN)
    np.testing.assert_allclose(back[:, :2], np.stack([lat, lon], axis=1), atol=1e-10)
    np.testing.assert_allclose(back[:, 2], h, atol=1e-5)
    # without the up component: the point at the origin's height
    flat = unproject(project(lat, lon, origin=ORIGIN[:2]), origin=ORIGIN[:2])
    np.testing.assert_allclose(flat, np.stack([lat, lon], axis=1), atol=1e-10)
    eq = unproject(project(lat, lon, origin=ORIGIN[:2], projection="equirectangular"), origin=ORIGIN[:2], projection="equirectangular")
    np.testing.assert_allclose(eq, np.stack([lat, lon], axis=1), atol=1e-10)
    phi, lam, height = ecef_to_geodetic(geodetic_to_ecef(lat, lon, h))
    np.testing.assert_allclose(np.stack([phi, lam, height], axis=1), np.stack([lat, lon, h], axis=1), atol=1e-6)
    pymap3d = pytest.importorskip("pymap3d")
    expected = np.stack(pymap3d.enu2geodetic(enu[:, 0], enu[:, 1], enu[:, 2], *ORIGIN), axis=1)
    np.testing.assert_allclose(back, expected, atol=1e-6)
    with pytest.raises(ValueError, match="positions"):
        unproject(np.zeros((3, 4)), origin=ORIGIN)


CONFIG = {
    "reader": {"time": "t", "lat": "lat", "lon": "lon", "alt": "alt", "id": "id", "origin": [50.8, -1.2], "min_reports": 5},
    "measurement": {"sigma": 10.0},
    "altitude": {"sigma": 10.0, "acceleration_density": 0.01, "velocity_sigma": 10.0},
    "prior": {"position_sigma": 100.0, "velocity_sigma": 50.0},
    "estimator": {"kind": "imm", "process_noise": 1.0, "modes": ["straight", "left_turn", "right_turn"], "radii": [3000.0]},
}


def write_flight(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A climbing aircraft heading east at 100 m/s and 8 m/s climb, 1–4 s between reports, positions in lat/lon."""
    rng = np.random.default_rng(11)
    t = np.cumsum(np.r_[0.0, rng.uniform(1.0, 4.0, 59)])
    enu = np.stack([100.0 * t, 0.0 * t, 500.0 + 8.0 * t], axis=1) + rng.normal(0.0, 5.0, (t.size, 3))
    geo = unproject(enu, origin=(50.8, -1.2, 0.0))
    lines = ["t,id,lat,lon,alt"] + [f"{a:.3f},plane,{la:.9f},{lo:.9f},{h:.3f}" for a, (la, lo, h) in zip(t, geo)]
    path.write_text("\n".join(lines) + "\n")
    return t, geo


def test_track_writes_altitude_and_the_map_view(tmp_path):
    t, geo = write_flight(tmp_path / "flight.csv")
    summary = track_file(tmp_path / "flight.csv", CONFIG, tmp_path / "out")
    assert [o["id"] for o in summary["objects"]] == ["plane"]
    data = np.load(tmp_path / "out" / "plane.npz")
    assert data["altitude_mean"].shape == data["altitude_var"].shape == (t.size, 2)
    assert np.all(np.isfinite(data["altitude_var"])) and np.all(data["altitude_var"] > 0)
    np.testing.assert_allclose(data["altitude"], geo[:, 2], atol=1e-3)  # the geodetic height (origin at h = 0)
    assert abs(data["altitude_mean"][-1, 1] - 8.0) < 1.0  # climb rate
    recording = RecordingFile(tmp_path / "out" / "plane.rrd")
    for entity in ("/world/estimate/track/altitude", "/world/measurements/altitude", "/map/estimate/track", "/map/measurements/path"):
        assert entity in recording.entity_paths, entity
    steps, values = recording._table("/map/measurements", "GeoPoints:positions")
    logged = np.array([v[0] for v in values])
    np.testing.assert_allclose(logged, geo[:, :2], atol=1e-8)  # the measurements converted back = the file's lat/lon
    steps, values = recording._table("/world/estimate/track/altitude", "Points3D:positions")
    z = np.array([v[0][2] for v in values])
    np.testing.assert_allclose(z, data["altitude_mean"][:, 0], rtol=1e-6)


def test_altitude_config_is_checked():
    with pytest.raises(ValueError, match=r"\[altitude\] sigma"):
        load_config({**CONFIG, "altitude": {"sigma": 0.0}})
    with pytest.raises(ValueError, match="unknown key"):
        load_config({**CONFIG, "altitude": {"q": 1.0}})


def test_the_layout_gets_a_map_view(tmp_path):
    from hybridtrack.recording import RerunRecorder

    with RerunRecorder(tmp_path / "map.rrd", {"test": "map"}) as recorder:
        t = np.arange(5.0)
        lat_lon = np.column_stack([50.8 + 1e-4 * t, -1.2 + 1e-4 * t])
        record_track(recorder, "imm", t, lat_lon_measured=lat_lon, lat_lon_estimated=lat_lon)
        assert recorder.content["map/estimate/imm"] == "Map"
        views = []

        def walk(item):
            views.append(type(item).__name__)
            for child in getattr(item, "contents", []) or []:
                if not isinstance(child, str):
                    walk(child)

        walk(recorder.blueprint().root_container)
    assert "MapView" in views, views
    with pytest.raises(ValueError, match="lat_lon"):
        RerunRecorder(tmp_path / "bad.rrd", {}).log_geo_path("map/x", np.arange(2), np.zeros((2, 3)))
