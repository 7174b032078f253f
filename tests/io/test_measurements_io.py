"""CSV/NPZ measurement files round-trip and reject malformed input."""

import numpy as np
import pytest

from hybridtrack.io.measurement_files import read_measurement_file, read_measurements, write_csv, write_npz


def sample():
    a = np.arange(10.0).reshape(5, 2) / 3
    a[2] = np.nan
    b = np.arange(5.0)[:, None] * 1.5
    b[4] = np.nan
    return {"radar": a, "buoy": b}


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip(tmp_path, suffix):
    path = tmp_path / f"z{suffix}"
    (write_csv if suffix == ".csv" else write_npz)(path, sample())
    back = read_measurements(path)
    assert set(back) == {"radar", "buoy"}
    for name, z in sample().items():
        np.testing.assert_array_equal(back[name], z)


def test_csv_layout_with_gaps(tmp_path):
    path = tmp_path / "z.csv"
    path.write_text("step,radar.x,radar.y,buoy.x\n0,1,2,3\n3,4,,6\n1,7,8,\n")
    z = read_measurements(path)
    assert z["radar"].shape == (4, 2) and z["buoy"].shape == (4, 1)
    np.testing.assert_array_equal(z["radar"][0], [1, 2])
    assert np.isnan(z["radar"][2]).all() and np.isnan(z["radar"][3]).all()  # missing step, partial row
    np.testing.assert_array_equal(z["buoy"][:, 0], [3, np.nan, np.nan, 6])


@pytest.mark.parametrize(
    "text, message",
    [
        ("when,a.x\n0,1\n", "'step'"),
        ("step,ax\n0,1\n", "<sensor>.<component>"),
        ("step,a.x\n0,1\n0,2\n", "repeated"),
        ("step,a.x\nzero,1\n", "integer"),
        ("step,a.x\n0,abc\n", "not a number"),
        ("step,a.x,a.y\n0,1\n", "expected 3 cells"),
    ],
)
def test_csv_errors(tmp_path, text, message):
    path = tmp_path / "z.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_measurements(path)


def test_unknown_suffix(tmp_path):
    with pytest.raises(ValueError, match="unknown measurement file type"):
        read_measurements(tmp_path / "z.txt")


TIMES = np.array([0.0, 0.05, 0.7, 2.7000000000000002, 3.1])


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip_with_times(tmp_path, suffix):
    path = tmp_path / f"z{suffix}"
    (write_csv if suffix == ".csv" else write_npz)(path, sample(), times=TIMES)
    measurements, times = read_measurement_file(path)
    assert np.array_equal(times, TIMES)  # exact
    for name, z in sample().items():
        np.testing.assert_array_equal(measurements[name], z)
        np.testing.assert_array_equal(read_measurements(path)[name], z)  # the old reader still works, without the times
    if suffix == ".csv":
        assert path.read_text().splitlines()[0] == "time,radar.0,radar.1,buoy.0"


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_step_files_have_no_times(tmp_path, suffix):
    path = tmp_path / f"z{suffix}"
    (write_csv if suffix == ".csv" else write_npz)(path, sample())
    assert read_measurement_file(path).times is None


def test_csv_time_layout(tmp_path):
    path = tmp_path / "z.csv"
    path.write_text("time,radar.x,radar.y\n0.5,1,2\n\n0.75,,\n2,3,\n4.25,5,6\n")
    measurements, times = read_measurement_file(path)
    np.testing.assert_array_equal(times, [0.5, 0.75, 2.0, 4.25])
    np.testing.assert_array_equal(measurements["radar"], [[1, 2], [np.nan, np.nan], [np.nan, np.nan], [5, 6]])


@pytest.mark.parametrize(
    "body, message",
    [
        ("0,1\n1,2\n1,3\n", r"z.csv:4: time at index 2 \(1.0\) is a duplicate of the time at index 1 \(1.0\)"),
        ("0,1\n1,2\n0.5,3\n", r"z.csv:4: time at index 2 \(0.5\) is earlier than the time at index 1 \(1.0\)"),
        ("0,1\nnan,2\n", r"z.csv:3: time at index 1 is 'nan' \(expected finite seconds\)"),
        ("0,1\n1,2\ninf,3\n", r"z.csv:4: time at index 2 is 'inf'"),
        ("0,1\n,2\n", r"z.csv:3: time at index 1 is '', not a number"),
        ("0,1\nsoon,2\n", r"z.csv:3: time at index 1 is 'soon', not a number"),
    ],
)
def test_csv_bad_times_name_file_row_index_and_value(tmp_path, body, message):
    path = tmp_path / "z.csv"
    path.write_text("time,a.x\n" + body)
    with pytest.raises(ValueError, match=message):
        read_measurement_file(path)
    with pytest.raises(ValueError, match=message):
        read_measurements(path)


@pytest.mark.parametrize(
    "times, message",
    [
        ([0.0, 1.0, 1.0, 2.0, 3.0], r"time at index 2 \(.*1.0\)+ is a duplicate of the time at index 1"),
        ([0.0, 1.0, 0.5, 2.0, 3.0], r"time at index 2 \(.*0.5\)+ is earlier than the time at index 1"),
        ([0.0, 1.0, np.nan, 2.0, 3.0], "time at index 2 is nan"),
        ([0.0, 1.0, 2.0, 3.0, -np.inf], "time at index 4 is -inf"),
        ([0.0, 1.0, 2.0], "expected 5 times"),
    ],
)
def test_npz_bad_times_name_file_index_and_value(tmp_path, times, message):
    path = tmp_path / "z.npz"
    np.savez(path, time=np.array(times), **sample())
    with pytest.raises(ValueError, match=r"z.npz: 'time' array: " + message):
        read_measurement_file(path)
    with pytest.raises(ValueError, match="times: " + message):
        write_npz(tmp_path / "w.npz", sample(), times=times)
    with pytest.raises(ValueError, match="times: " + message):
        write_csv(tmp_path / "w.csv", sample(), times=times)


def test_npz_sensor_named_time(tmp_path):
    path = tmp_path / "z.npz"
    write_npz(path, {"time": np.ones((3, 1))})  # a 2-D 'time' array is a sensor, as before
    measurements, times = read_measurement_file(path)
    assert times is None and measurements["time"].shape == (3, 1)
    with pytest.raises(ValueError, match="sensor named 'time'"):
        write_npz(path, {"time": np.ones((3, 1))}, times=[0.0, 1.0, 2.0])
