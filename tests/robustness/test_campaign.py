"""The campaign store and runner on bad input: damaged or foreign files, a missing manifest, a held lock,
bad scheduler addresses and bad options; each is a clear error naming the input (one line, exit 2 on the CLI),
and ``set_aside`` / ``--set-aside`` moves the bad file away and recomputes its runs."""

import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.apps.experiment import (
    Campaign,
    CampaignLocked,
    CampaignMismatch,
    CorruptResults,
    ResultStore,
    run_campaign,
)
from hybridtrack.apps.experiment.executors import check_scheduler_address
from hybridtrack.apps.experiment.store import IDENTITY_ARRAY
from hybridtrack.cli import main

TOY = Path(__file__).parents[1] / "apps" / "_toy_experiments.py"
DRAWS = f"{TOY}:DRAWS"
FIRST = "runs-0000000-0000000.npz"


def stored(out, n=3, seed=1, **options):
    """A finished campaign of DRAWS in ``out``: chunks of one run each."""
    return run_campaign(DRAWS, n, out, executor="inline", chunk_size=1, seed=seed, progress=False, **options)


def campaign(out, n=3, seed=1, **options):
    return stored(out, n, seed, **options)


def write_npz(path, **arrays):
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)


def good_arrays(index=0):
    return {"index": np.array([index]), "normal": np.zeros((1, 3)), "uniform": np.zeros(1), "index_seen": np.array([index])}


# -- the bad chunk files: (name, how to damage OUT/runs-0000000-0000000.npz, words of the message) ---------------


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _single_npy(path):
    with open(path, "wb") as handle:
        np.save(handle, np.arange(3))


def _directory(path):
    path.unlink()
    path.mkdir()


BAD_CHUNKS = {
    "empty": (lambda p: p.write_bytes(b""), "is empty"),
    "truncated": (_truncate, "not a readable NPZ archive"),
    "foreign text": (lambda p: p.write_text("hello, not numbers\n"), "not a readable NPZ archive"),
    "single npy": (_single_npy, "not a readable NPZ archive"),
    "pickled object": (lambda p: write_npz(p, **good_arrays(), extra=np.array([{"a": 1}], dtype=object)), "not a readable NPZ"),
    "no index": (lambda p: write_npz(p, normal=np.zeros((1, 3))), "has no 'index' array"),
    "float index": (lambda p: write_npz(p, **{**good_arrays(), "index": np.array([0.0])}), "'index' is float64"),
    "2-D index": (
        lambda p: write_npz(p, **{**good_arrays(), "index": np.zeros((1, 1), dtype=int)}),
        r"'index' is int64 with shape \(1, 1\)",
    ),
    "negative index": (lambda p: write_npz(p.with_name("runs--000001--000001.npz"), **good_arrays(-1)) or p.unlink(), "negative"),
    "rows mismatch": (lambda p: write_npz(p, **{**good_arrays(), "uniform": np.zeros(2)}), r"'uniform' has \(2,\) rows for 1 runs"),
    "text results": (lambda p: write_npz(p, **{**good_arrays(), "uniform": np.array(["x"])}), "'uniform' has dtype <U1"),
    "name contradicts runs": (lambda p: write_npz(p, **good_arrays(7)), "its name should be runs-0000007-0000007.npz"),
    "directory": (_directory, "cannot be read"),
    "other result shape": (lambda p: write_npz(p, **{**good_arrays(), "normal": np.zeros((1, 4))}), "differ from"),
    "identity not JSON": (lambda p: write_npz(p, **good_arrays(), **{IDENTITY_ARRAY: np.array("{oops")}), "not valid JSON"),
}


def damage_first_chunk(out, kind):
    damage, _ = BAD_CHUNKS[kind]
    path = out / FIRST
    damage(path)
    return sorted(out.glob("runs-*.npz"))[0] if kind == "negative index" else path


@pytest.mark.parametrize("kind", list(BAD_CHUNKS))
def test_a_bad_chunk_file_is_an_error_naming_it(tmp_path, kind):
    stored(tmp_path)
    path = damage_first_chunk(tmp_path, kind)
    message = BAD_CHUNKS[kind][1]
    with pytest.raises(CorruptResults, match=f"chunk file {path}.*{message}.*--set-aside"):
        campaign(tmp_path)
    with pytest.raises(CorruptResults, match=str(path)):
        ResultStore(tmp_path).load()


@pytest.mark.parametrize("kind", ["empty", "truncated", "foreign text", "no index", "other result shape"])
def test_set_aside_moves_a_bad_chunk_away_and_recomputes_its_runs(tmp_path, kind):
    clean = stored(tmp_path / "clean")
    out = tmp_path / "out"
    stored(out)
    damage_first_chunk(out, kind)
    result = campaign(out, set_aside=True)
    assert (result.computed, result.reused) == (1, 2)
    assert [moved.name for _, moved, _ in result.set_aside] == [FIRST]
    assert (out / "set_aside" / FIRST).exists() and FIRST in (out / "set_aside" / "REASONS.txt").read_text()
    for name in clean.arrays:
        np.testing.assert_array_equal(result.arrays[name], clean.arrays[name])


# -- manifest ------------------------------------------------------------------------------------------


BAD_MANIFESTS = {
    "empty": ("", "is empty"),
    "not JSON": ("{experiment: draws", "is not valid JSON"),
    "a list": ("[1, 2]", "expected a JSON object, got list"),
    "no seed": (json.dumps({"format": 1, "experiment": "draws", "parameters": {}, "n": 3, "locator": None}), "has no 'seed' entry"),
    "seed text": (
        json.dumps({"format": 1, "experiment": "draws", "parameters": {}, "seed": "1", "n": 3, "locator": None}),
        "'seed' is '1', expected a non-negative integer",
    ),
    "n zero": (
        json.dumps({"format": 1, "experiment": "draws", "parameters": {}, "seed": 1, "n": 0, "locator": None}),
        "'n' is 0, expected a positive integer",
    ),
    "not UTF-8": (b"\xff\xfe\x00", "cannot be read"),
}


@pytest.mark.parametrize("kind", list(BAD_MANIFESTS))
def test_a_damaged_manifest_is_an_error_naming_it(tmp_path, kind):
    stored(tmp_path)
    text, message = BAD_MANIFESTS[kind]
    manifest = tmp_path / "manifest.json"
    manifest.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(CorruptResults, match=f"manifest {manifest} {message}.*--set-aside"):
        campaign(tmp_path)


def test_set_aside_replaces_a_damaged_manifest_and_keeps_the_runs(tmp_path):
    stored(tmp_path)
    (tmp_path / "manifest.json").write_text("{")
    result = campaign(tmp_path, set_aside=True)
    assert (result.computed, result.reused) == (0, 3)
    assert json.loads((tmp_path / "manifest.json").read_text())["seed"] == 1
    assert (tmp_path / "set_aside" / "manifest.json").read_text() == "{"


def test_a_deleted_manifest_does_not_let_another_seed_reuse_the_runs(tmp_path):
    stored(tmp_path, seed=1)
    (tmp_path / "manifest.json").unlink()
    with pytest.raises(CampaignMismatch, match=f"chunk file {tmp_path / FIRST} belongs to another campaign.*seed: folder has 1, asked 2"):
        campaign(tmp_path, seed=2)
    with pytest.raises(CampaignMismatch, match="parameters: folder has"):
        campaign(tmp_path, seed=1, parameters={"size": 4})
    resumed = campaign(tmp_path, n=4, seed=1)  # the same campaign still resumes without its manifest
    assert (resumed.computed, resumed.reused) == (1, 3)


def test_a_chunk_of_another_seed_copied_into_a_folder_is_refused(tmp_path):
    stored(tmp_path / "a", n=4, seed=1)
    stored(tmp_path / "b", n=3, seed=2)
    shutil.copy(tmp_path / "a" / "runs-0000003-0000003.npz", tmp_path / "b")
    with pytest.raises(CampaignMismatch, match="runs-0000003-0000003.npz belongs to another campaign.*seed: folder has 1, asked 2"):
        campaign(tmp_path / "b", n=4, seed=2)
    result = campaign(tmp_path / "b", n=4, seed=2, set_aside=True)
    assert (result.computed, result.reused) == (1, 3)


def test_an_old_chunk_without_identity_and_without_manifest_is_refused(tmp_path):
    stored(tmp_path)
    (tmp_path / "manifest.json").unlink()
    write_npz(tmp_path / FIRST, **good_arrays())
    with pytest.raises(CorruptResults, match=f"chunk file {tmp_path / FIRST} records no campaign identity.*manifest.json is missing"):
        campaign(tmp_path)


# -- the lock ------------------------------------------------------------------------------------------


def test_a_second_campaign_on_a_locked_folder_is_refused_naming_folder_and_holder(tmp_path):
    stored(tmp_path)
    with ResultStore(tmp_path).locked():
        with pytest.raises(CampaignLocked, match=f"{tmp_path} is in use by another campaign \\(process {os.getpid()} "):
            campaign(tmp_path, n=4)
        assert len(list(tmp_path.glob("runs-*.npz"))) == 3
    assert campaign(tmp_path, n=4).computed == 1  # released


def test_an_out_path_that_is_a_file_is_refused(tmp_path):
    target = tmp_path / "file"
    target.write_text("x")
    with pytest.raises(NotADirectoryError, match=f"result folder {target} is a file"):
        campaign(target)


# -- options -------------------------------------------------------------------------------------------


BAD_ADDRESSES = {
    "tcp://host": "has no port",
    "tcp://:8786": "has no host",
    "tcp://10.0.0.5:0": "port '0' is not an integer in 1-65535",
    "tcp://10.0.0.5:99999": "port '99999'",
    "tcp://10.0.0.5:port": "port 'port'",
    "http://10.0.0.5:8786": "unknown scheme 'http'",
    "tcp://10.0.0:8786": "'10.0.0' is not an IPv4 address",
    "tcp://::1:8786": "more than one ':'",
    "tcp://[not-v6]:8786": "'not-v6' is not an IPv6 address",
    "tcp://10.0.0.5:8786/path": "has a path after the port",
    "tcp://10.0.0.5 :8786": "contains white space",
    "tcp://bad_host!:8786": "is not a host name",
}


@pytest.mark.parametrize("address", list(BAD_ADDRESSES))
def test_a_malformed_scheduler_address_fails_before_anything_starts(tmp_path, address):
    expected = re.escape(f"scheduler address {address!r}: ") + f".*{re.escape(BAD_ADDRESSES[address])}.*expected SCHEME://HOST:PORT"
    with pytest.raises(ValueError, match=expected):
        Campaign(DRAWS, 2, tmp_path / "out", executor="dask", scheduler=address)
    assert not (tmp_path / "out").exists()


def test_well_formed_scheduler_addresses_pass():
    for address in ("tcp://10.0.0.5:8786", "localhost:8786", "tls://[::1]:8786", "inproc://10.0.0.5/123/1"):
        assert check_scheduler_address(address) == address
    with pytest.raises(TypeError, match="scheduler: expected an address string or a distributed.Client, got int"):
        check_scheduler_address(8786)


@pytest.mark.slow
def test_an_unreachable_scheduler_fails_within_the_connect_timeout(tmp_path):
    pytest.importorskip("distributed")
    with pytest.raises(ConnectionError, match="scheduler 'tcp://127.0.0.1:9': no Dask scheduler answered within 0.5 s"):
        run_campaign(DRAWS, 2, tmp_path, executor="dask", scheduler="tcp://127.0.0.1:9", connect_timeout=0.5, progress=False)


@pytest.mark.parametrize(
    ("options", "error", "message"),
    [
        ({"set_aside": "yes"}, TypeError, "set_aside: expected True or False, got 'yes'"),
        ({"connect_timeout": 0}, ValueError, "connect_timeout: expected a positive number of seconds, got 0"),
        ({"connect_timeout": float("nan")}, ValueError, "connect_timeout: expected a positive number of seconds, got nan"),
    ],
)
def test_bad_campaign_options(tmp_path, options, error, message):
    with pytest.raises(error, match=message):
        Campaign(DRAWS, 2, tmp_path, **options)


# -- the command line ----------------------------------------------------------------------------------


def cli(capsys, *args):
    status = main(["run", DRAWS, "--executor", "inline", "--no-progress", *map(str, args)])
    captured = capsys.readouterr()
    return status, captured.err


def assert_one_line(err, *words):
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    for word in words:
        assert word in err, err


def _lock_and_run(capsys, out):
    with ResultStore(out).locked():
        return cli(capsys, "--n", 3, "--out", out)


CLI_CASES = {
    "corrupt chunk": (lambda out: (out / FIRST).write_bytes(b""), ["--n", 3], [FIRST, "is empty", "--set-aside"]),
    "damaged manifest": (lambda out: (out / "manifest.json").write_text("{"), ["--n", 3], ["manifest.json", "not valid JSON"]),
    "seed without manifest": (
        lambda out: (out / "manifest.json").unlink(),
        ["--n", 3, "--seed", 2],
        [FIRST, "seed: folder has 1, asked 2"],
    ),
    "seed with manifest": (lambda out: None, ["--n", 3, "--seed", 2], ["holds another campaign", "seed: folder has 1, asked 2"]),
    "bad scheduler": (lambda out: None, ["--executor", "dask", "--scheduler", "tcp://host"], ["scheduler address 'tcp://host'", "no port"]),
    "n zero": (lambda out: None, ["--n", 0], ["--n", "expected a positive integer, got '0'"]),
    "seed negative": (lambda out: None, ["--seed", -1], ["--seed", "expected a non-negative integer, got '-1'"]),
    "workers text": (lambda out: None, ["--workers", "two"], ["--workers", "got 'two'"]),
    "chunk zero": (lambda out: None, ["--chunk", 0], ["--chunk", "got '0'"]),
    "connect timeout": (lambda out: None, ["--connect-timeout", "-1"], ["--connect-timeout", "got '-1'"]),
    "param": (lambda out: None, ["--param", "size"], ["--param", "expected KEY=VALUE, got 'size'"]),
    "unknown param": (lambda out: None, ["--param", "sigma=1"], ["unknown parameter(s) ['sigma']"]),
}


@pytest.mark.parametrize("case", list(CLI_CASES))
def test_cli_user_errors_are_one_line_with_status_2(tmp_path, capsys, case):
    prepare, args, words = CLI_CASES[case]
    out = tmp_path / "out"
    assert cli(capsys, "--n", 3, "--out", out, "--seed", 1)[0] == 0
    prepare(out)
    status, err = cli(capsys, "--out", out, "--seed", 1, *args)
    assert status == 2
    assert_one_line(err, *words)


def test_cli_refuses_a_locked_folder_in_one_line(tmp_path, capsys):
    status, err = _lock_and_run(capsys, tmp_path)
    assert status == 2
    assert_one_line(err, str(tmp_path), "in use by another campaign", f"process {os.getpid()}")


def test_cli_refuses_an_out_that_is_a_file(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    status, err = cli(capsys, "--out", tmp_path / "file")
    assert status == 2
    assert_one_line(err, str(tmp_path / "file"), "is a file")


def test_cli_set_aside_moves_the_bad_file_reports_it_and_finishes(tmp_path, capsys):
    assert cli(capsys, "--n", 3, "--out", tmp_path, "--seed", 1)[0] == 0
    (tmp_path / FIRST).write_bytes(b"PK\x03\x04 truncated")
    status, err = cli(capsys, "--n", 3, "--out", tmp_path, "--seed", 1, "--set-aside")
    assert status == 0
    assert_one_line(err, f"set aside {tmp_path / FIRST} as {tmp_path / 'set_aside' / FIRST}", "not a readable NPZ")
    assert ResultStore(tmp_path).completed().tolist() == [0, 1, 2]
