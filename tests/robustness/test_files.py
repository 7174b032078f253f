"""Bad measurement files (CSV and NPZ): each is refused with a clear error naming the file and what is wrong.

Accepted on purpose: a UTF-8 byte-order mark (stripped) and a ``;``-separated
CSV (the header line has no comma).  See :mod:`hybridtrack.io.measurement_files`.
"""

import io
import warnings
import zipfile

import numpy as np
import pytest

from hybridtrack.io import measurement_files as measurements_io
from hybridtrack.io.measurement_files import read_measurement_file, read_measurements, write_csv, write_npz

# ---------------------------------------------------------------- CSV accepted


@pytest.mark.parametrize(
    "data",
    [
        b"\xef\xbb\xbfstep,a.x,a.y\n0,1,2\n2,3,4\n",  # UTF-8 byte-order mark
        b"step;a.x;a.y\n0;1;2\n2;3;4\n",  # semicolon separator
        b"\xef\xbb\xbfstep;a.x;a.y\r\n0;1;2\r\n\r\n2;3;4\r\n",  # both, Windows line ends, a blank line
        b"step , a.x , a.y\n 0 , 1 , 2 \n+2,3.0,4e0\n",  # spaces around cells, a '+' step
    ],
    ids=["bom", "semicolon", "bom-semicolon-crlf", "spaces"],
)
def test_csv_variants_accepted(tmp_path, data):
    path = tmp_path / "z.csv"
    path.write_bytes(data)
    z = read_measurements(path)
    np.testing.assert_array_equal(z["a"], [[1, 2], [np.nan, np.nan], [3, 4]])


# ---------------------------------------------------------------- CSV refused

CSV_CASES = [
    # encoding / not text
    ("garbage", bytes(range(256)) * 8, r"z\.csv: not a UTF-8 text CSV \(byte 0x80 at offset 128\)"),
    ("latin-1", "step,café.x\n0,1\n".encode("latin-1"), r"z\.csv: not a UTF-8 text CSV \(byte 0xe9"),
    ("utf-16", "step,a.x\n0,1\n".encode("utf-16"), r"z\.csv: the file is UTF-16 text; save it as UTF-8"),
    ("nul", b"step,a.x\n0,1\x00\n", r"z\.csv: not a UTF-8 text CSV \(NUL byte at offset 12\)"),
    ("zip", b"PK\x03\x04" + b"\x00" * 40, r"z\.csv: the file is a zip archive"),
    # structure
    ("empty", b"", r"z\.csv: empty file"),
    ("blank", b"\n  \n\n", r"z\.csv: empty file"),
    ("header-only", b"step,a.x\n", r"z\.csv: header only, no data rows"),
    ("no-step", b"a.x,a.y\n1,2\n", r"z\.csv:1: the first header column is 'a\.x'; expected 'step'"),
    ("no-sensor", b"step\n0\n1\n", r"z\.csv:1: no sensor columns after 'step'"),
    ("duplicate-column", b"step,a.x,a.y,a.x\n0,1,2,3\n", r"z\.csv:1: column 'a\.x' appears twice \(columns 2 and 4\)"),
    ("duplicate-spaced", b"step,a.x, a.x\n0,1,2\n", r"z\.csv:1: column 'a\.x' appears twice"),
    ("no-dot", b"step,ax\n0,1\n", r"z\.csv:1: column 2 'ax' is not of the form <sensor>\.<component>"),
    ("no-sensor-name", b"step,.x\n0,1\n", r"z\.csv:1: column 2 '\.x' is not of the form"),
    ("no-component", b"step,a.\n0,1\n", r"z\.csv:1: column 2 'a\.' is not of the form"),
    ("colon", b"step,a:x\n0,1\n", r"z\.csv:1: column 2 'a:x' is not of the form"),
    ("short-row", b"step,a.x,a.y\n0,1,2\n1,1\n", r"z\.csv:3: expected 3 cells \(as in the header\), got 2"),
    ("long-row", b"step,a.x\n0,1\n1,1,2\n", r"z\.csv:3: expected 2 cells \(as in the header\), got 3"),
    ("huge-field", b"step,a.x\n0," + b"1" * 200_000 + b"\n", r"z\.csv:\d+: malformed CSV"),
    # cells
    ("text-cell", b"step,a.x\n0,abc\n", r"z\.csv:2: column 'a\.x' holds 'abc', not a number"),
    ("decimal-comma", b"step;a.x\n0;0,5\n", r"z\.csv:2: column 'a\.x' holds '0,5', not a number \(a decimal comma"),
    ("arabic-digits", "step,a.x\n0,١٢\n".encode(), r"z\.csv:2: column 'a\.x' holds '١٢', not a number"),
    ("arabic-step", "step,a.x\n١,1\n".encode(), r"z\.csv:2: step '١' is not an integer"),
    ("underscore", b"step,a.x\n0,1_000\n", r"z\.csv:2: column 'a\.x' holds '1_000', not a number"),
    ("inf", b"step,a.x\n0,1\n1,inf\n", r"z\.csv:3: column 'a\.x' holds 'inf'; expected a finite number"),
    ("-inf", b"step,a.x,a.y\n0,1,-inf\n", r"z\.csv:2: column 'a\.y' holds '-inf'; expected a finite number"),
    ("infinity", b"step,a.x\n0,Infinity\n", r"z\.csv:2: column 'a\.x' holds 'Infinity'; expected a finite number"),
    ("1e400", b"step,a.x\n0,1e400\n", r"z\.csv:2: column 'a\.x' holds '1e400', beyond the float range"),
    ("-1e999", b"step,a.x,b.y\n0,1,-1e999\n", r"z\.csv:2: column 'b\.y' holds '-1e999', beyond the float range"),
    ("time-1e400", b"time,a.x\n0,1\n1e400,2\n", r"z\.csv:3: time at index 1 is '1e400' \(expected finite seconds\)"),
    # steps
    ("repeated-step", b"step,a.x\n0,1\n1,2\n0,3\n", r"z\.csv:4: step 0 is repeated \(first at line 2\)"),
    ("repeated-after-blank", b"step,a.x\n5,1\n\n\n5,3\n", r"z\.csv:5: step 5 is repeated \(first at line 2\)"),
    ("negative-step", b"step,a.x\n0,1\n-1,2\n", r"z\.csv:3: step -1 is negative; expected 0 … 10000000"),
    ("fraction-step", b"step,a.x\n1.5,2\n", r"z\.csv:2: step '1\.5' is not an integer"),
    ("empty-step", b"step,a.x\n,2\n", r"z\.csv:2: step '' is not an integer"),
    ("underscore-step", b"step,a.x\n1_000,2\n", r"z\.csv:2: step '1_000' is not an integer"),
    ("nan-step", b"step,a.x\nnan,2\n", r"z\.csv:2: step 'nan' is not an integer"),
    ("step-over-limit", b"step,a.x\n10000001,2\n", r"z\.csv:2: step 10000001 exceeds the limit 10000000"),
    ("step-1e30", b"step,a.x\n" + b"9" * 30 + b",2\n", r"z\.csv:2: step 9{30} exceeds the limit"),
    ("step-4301-digits", b"step,a.x\n" + b"9" * 4301 + b",2\n", r"z\.csv:2: step 9+ exceeds the limit"),
    (
        "dense-over-memory",
        b"step," + b",".join(b"a.%d" % i for i in range(20)) + b"\n9000000" + b",1" * 20 + b"\n",
        r"z\.csv: steps 0 … 9000000 × 20 columns need 1373 MiB, above the limit 1024 MiB",
    ),
]


@pytest.mark.parametrize("data, message", [c[1:] for c in CSV_CASES], ids=[c[0] for c in CSV_CASES])
def test_bad_csv_is_refused_naming_file_and_fault(tmp_path, data, message):
    path = tmp_path / "z.csv"
    path.write_bytes(data)
    with pytest.raises(ValueError, match=message):
        read_measurement_file(path)


# ---------------------------------------------------------------- paths


@pytest.mark.parametrize(
    "name, make_dir, error, message",
    [
        ("absent.csv", False, FileNotFoundError, r"absent\.csv: no such file \(expected a \.csv measurement file\)"),
        ("absent.npz", False, FileNotFoundError, r"absent\.npz: no such file \(expected a \.npz measurement file\)"),
        ("dir.csv", True, IsADirectoryError, r"dir\.csv: is a directory, expected a \.csv or \.npz measurement file"),
        ("dir.npz", True, IsADirectoryError, r"dir\.npz: is a directory, expected a \.csv or \.npz measurement file"),
        ("dir", True, IsADirectoryError, r"dir: is a directory, expected a \.csv or \.npz measurement file"),
    ],
)
def test_missing_files_and_directories(tmp_path, name, make_dir, error, message):
    if make_dir:
        (tmp_path / name).mkdir()
    with pytest.raises(error, match=message):
        read_measurements(tmp_path / name)


@pytest.mark.parametrize("name", ["z.txt", "z", "z.npy", "z.csv.gz"])
def test_wrong_extension(tmp_path, name):
    path = tmp_path / name
    path.write_text("step,a.x\n0,1\n")
    with pytest.raises(ValueError, match=rf"{name}: unknown measurement file type .* \(expected \.csv or \.npz\)"):
        read_measurement_file(path)


@pytest.mark.parametrize("path", [3, None, b"z.csv"])
def test_path_of_wrong_type(path):
    with pytest.raises(TypeError, match=r"path: expected a file name \(str or os\.PathLike\), got"):
        read_measurement_file(path)


# ---------------------------------------------------------------- NPZ refused


def _npz(**arrays) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def _zip(members) -> bytes:
    buffer = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # zipfile warns about duplicate names
        with zipfile.ZipFile(buffer, "w") as archive:
            for name, data in members:
                archive.writestr(name, data)
    return buffer.getvalue()


def _npy(array) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


GOOD = _npz(a=np.arange(10.0).reshape(5, 2), b=np.ones((5, 1)))
_corrupt = bytearray(GOOD)
_at = _corrupt.index(np.float64(1.0).tobytes())  # array 'a' holds 0, 1, 2, …
_corrupt[_at : _at + 8] = b"garbage!"  # the zip's CRC-32 no longer matches

NPZ_CASES = [
    ("empty-file", b"", r"z\.npz: empty file"),
    ("empty-archive", _npz(), r"z\.npz: the archive holds no arrays"),
    ("truncated-half", GOOD[: len(GOOD) // 2], r"z\.npz: corrupt or truncated NPZ archive"),
    ("truncated-tail", GOOD[:-10], r"z\.npz: corrupt or truncated NPZ archive"),
    ("corrupt-data", bytes(_corrupt), r"z\.npz: array 'a' cannot be read, the archive is corrupt or truncated"),
    ("text", b"step,a.x\n0,1\n", r"z\.npz: not an NPZ \(zip\) archive \(it starts with b'step,a'\)"),
    ("garbage", bytes(range(256)), r"z\.npz: not an NPZ \(zip\) archive"),
    ("lone-npy", _npy(np.ones((3, 2))), r"z\.npz: a single \.npy array, not an NPZ archive"),
    (
        "pickled",
        _npz(a=np.array([{"x": 1}, None], dtype=object)),
        r"z\.npz: array 'a' holds Python objects \(a pickle\), which are refused",
    ),
    ("pickled-time", _npz(a=np.ones((2, 1)), time=np.array([0.0, "x"], dtype=object)), r"z\.npz: array 'time' holds Python objects"),
    ("3-d", _npz(a=np.ones((5, 2, 3))), r"z\.npz: array 'a' has shape \(5, 2, 3\); expected 2-D \(steps, m\)"),
    ("1-d", _npz(a=np.ones(5)), r"z\.npz: array 'a' has shape \(5,\); expected 2-D \(steps, m\) \(a time array must be named 'time'\)"),
    ("0-d", _npz(a=np.float64(1.0)), r"z\.npz: array 'a' has shape \(\); expected 2-D"),
    ("no-steps", _npz(a=np.ones((0, 2))), r"z\.npz: array 'a' has shape \(0, 2\); expected at least one step"),
    ("no-components", _npz(a=np.ones((4, 0))), r"z\.npz: array 'a' has shape \(4, 0\); expected at least one step and one component"),
    ("steps-mismatch", _npz(a=np.ones((5, 2)), b=np.ones((4, 1))), r"z\.npz: the arrays have different numbers of steps \(a 5, b 4\)"),
    ("text-dtype", _npz(a=np.array([["1", "2"]])), r"z\.npz: array 'a' has dtype <U1 \('U' kind\); expected float or integer"),
    ("bytes-dtype", _npz(a=np.array([[b"1"]])), r"z\.npz: array 'a' has dtype \|S1 \('S' kind\)"),
    ("complex-dtype", _npz(a=np.ones((3, 2), complex)), r"z\.npz: array 'a' has dtype complex128 \('c' kind\)"),
    ("bool-dtype", _npz(a=np.ones((3, 2), bool)), r"z\.npz: array 'a' has dtype bool \('b' kind\)"),
    ("datetime-dtype", _npz(a=np.zeros((3, 1), "datetime64[s]")), r"z\.npz: array 'a' has dtype datetime64\[s\]"),
    ("structured-dtype", _npz(a=np.zeros((3, 1), [("x", float)])), r"z\.npz: array 'a' has dtype .*\('V' kind\)"),
    ("inf", _npz(a=np.array([[1.0], [np.inf]])), r"z\.npz: array 'a': contains inf at index \(1, 0\)"),
    ("only-time", _npz(time=np.arange(3.0)), r"z\.npz: the archive holds only the 'time' array, no sensor"),
    ("bad-time", _npz(a=np.ones((3, 1)), time=np.array([0.0, 2.0, 1.0])), r"z\.npz: 'time' array: time at index 2 \(1\.0\) is earlier"),
    (
        "non-npy-member",
        _zip([("a.npy", _npy(np.ones((2, 1)))), ("notes.txt", b"hello")]),
        r"z\.npz: archive member 'notes\.txt' is not a \.npy array",
    ),
    ("repeated-member", _zip([("a.npy", _npy(np.ones((2, 1)))), ("a.npy", _npy(np.zeros((2, 1))))]), r"z\.npz: array 'a' appears twice"),
    ("short-member", _zip([("a.npy", _npy(np.ones((4, 1)))[:-8])]), r"z\.npz: array 'a' cannot be read, the archive is corrupt"),
    ("long-member", _zip([("a.npy", _npy(np.ones((4, 1))) + b"extra")]), r"z\.npz: array 'a' has 5 bytes after its data"),
    ("bad-npy-header", _zip([("a.npy", b"\x93NUMPY\x01\x00\x05\x00{'de")]), r"z\.npz: array 'a' cannot be read"),
]


@pytest.mark.parametrize("data, message", [c[1:] for c in NPZ_CASES], ids=[c[0] for c in NPZ_CASES])
def test_bad_npz_is_refused_naming_file_and_fault(tmp_path, data, message):
    path = tmp_path / "z.npz"
    path.write_bytes(data)
    with pytest.raises(ValueError, match=message):
        read_measurement_file(path)


def test_npz_memory_bound_checked_before_loading(tmp_path, monkeypatch):
    """The size comes from the .npy headers: an over-limit archive is refused without loading its data."""
    path = tmp_path / "z.npz"
    path.write_bytes(GOOD)
    monkeypatch.setattr(measurements_io, "MAX_BYTES", 64)
    monkeypatch.setattr(np.lib.format, "read_array", lambda *a, **k: pytest.fail("an array was loaded"))
    with pytest.raises(ValueError, match=r"z\.npz: the arrays need 0 MiB as float64, above the limit 0 MiB"):
        read_measurement_file(path)


def test_npz_integer_arrays_read_as_float(tmp_path):
    path = tmp_path / "z.npz"
    path.write_bytes(_npz(a=np.arange(6, dtype=np.int16).reshape(3, 2), time=np.arange(3)))
    z, times = read_measurement_file(path)
    assert z["a"].dtype == np.float64 and times.tolist() == [0.0, 1.0, 2.0]


# ---------------------------------------------------------------- writers refuse what cannot be read back

WRITE_CASES = [
    ("no-sensor", {}, None, ValueError, r"measurements: no sensor"),
    ("not-mapping", [np.ones((2, 1))], None, TypeError, r"measurements: expected a mapping"),
    ("empty-name", {"": np.ones((2, 1))}, None, ValueError, r"measurements: sensor name '' must be a non-empty str"),
    ("int-name", {3: np.ones((2, 1))}, None, ValueError, r"measurements: sensor name 3 must be a non-empty str"),
    ("zero-steps", {"a": np.ones((0, 2))}, None, ValueError, r"measurements\['a'\]: shape \(0, 2\); expected at least one step"),
    ("zero-components", {"a": np.ones((3, 0))}, None, ValueError, r"measurements\['a'\]: shape \(3, 0\)"),
    ("inf", {"a": np.array([[1.0], [np.inf]])}, None, ValueError, r"measurements\['a'\]: contains inf at index \(1, 0\)"),
    ("few-labels", {"a": np.ones((2, 2))}, {"a": ["x"]}, ValueError, r"components\['a'\]: \['x'\]; expected 2 distinct"),
    ("repeated-labels", {"a": np.ones((2, 2))}, {"a": ["x", "x"]}, ValueError, r"components\['a'\]: \['x', 'x'\]"),
    ("dotted-label", {"a": np.ones((2, 1))}, {"a": ["b.x"]}, ValueError, r"components\['a'\]: \['b\.x'\]; .* without '\.'"),
]


WRITES = [(suffix, *case) for case in WRITE_CASES for suffix in (".csv", ".npz") if suffix == ".csv" or case[2] is None]


@pytest.mark.parametrize(
    "suffix, measurements, components, error, message", [w[:1] + w[2:] for w in WRITES], ids=[w[1] + w[0] for w in WRITES]
)
def test_writers_refuse_unreadable_output(tmp_path, suffix, measurements, components, error, message):
    path = tmp_path / f"w{suffix}"
    with pytest.raises(error, match=message):
        if suffix == ".csv":
            write_csv(path, measurements, components)
        else:
            write_npz(path, measurements)
    assert not path.exists()


def test_step_csv_over_max_step_is_refused(monkeypatch, tmp_path):
    monkeypatch.setattr(measurements_io, "MAX_STEP", 3)
    with pytest.raises(ValueError, match=r"measurements: 5 steps, above the step CSV limit 3 \+ 1 .*write an NPZ"):
        write_csv(tmp_path / "w.csv", {"a": np.ones((5, 1))})
    write_csv(tmp_path / "w.csv", {"a": np.ones((4, 1))})
    assert read_measurements(tmp_path / "w.csv")["a"].shape == (4, 1)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip_unusual_names_and_values(tmp_path, suffix):
    """Names with dots, commas, quotes, non-ASCII; extreme finite values; all-NaN first and last steps."""
    z = {
        "radar.front": np.array([[np.nan, np.nan], [1e308, -5e-324], [0.1, np.nan], [np.nan, np.nan]]),
        'buoy,"β"': np.array([[np.nan], [-0.0], [2.5], [np.nan]]),
    }
    path = tmp_path / f"w{suffix}"
    (write_csv if suffix == ".csv" else write_npz)(path, z)
    back = read_measurements(path)
    assert list(back) == list(z)
    expected = z["radar.front"].copy()
    if suffix == ".csv":
        expected[2] = np.nan  # the CSV reader blanks a sensor's row when one of its cells is empty
    np.testing.assert_array_equal(back["radar.front"], expected)
    np.testing.assert_array_equal(back['buoy,"β"'], z['buoy,"β"'])
