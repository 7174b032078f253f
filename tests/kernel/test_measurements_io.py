"""CSV/NPZ measurement files round-trip and reject malformed input."""

import numpy as np
import pytest

from hybridtrack.measurements_io import read_measurements, write_csv, write_npz


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
        ("time,a.x\n0,1\n", "'step'"),
        ("step,ax\n0,1\n", "<sensor>.<component>"),
        ("step,a.x\n0,1\n0,2\n", "repeated"),
        ("step,a.x\nzero,1\n", "integer"),
        ("step,a.x\n0,abc\n", "non-numeric"),
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
