"""The Monte Carlo runner: per-run seeds, executors agree, resumption loses and repeats nothing, the CLI."""

import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.apps.experiment import (
    Campaign,
    CampaignInterrupted,
    CampaignMismatch,
    CorruptResults,
    Experiment,
    ResultStore,
    RunFailed,
    UnknownExperiment,
    load_experiment,
    run_campaign,
    run_seed,
)
from hybridtrack.apps.experiment.builtin import pooled_rmse
from hybridtrack.apps.experiment.campaign import _progress, chunks
from hybridtrack.cli import main

TOY = Path(__file__).with_name("_toy_experiments.py")
DRAWS = f"{TOY}:DRAWS"
FLAKY = f"{TOY}:FLAKY"


def assert_same_results(a, b):
    assert sorted(a) == sorted(b)
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def calls(log: Path) -> list[int]:
    return [int(line) for line in log.read_text().split()] if log.exists() else []


# -- seeds -------------------------------------------------------------------------------------------


def test_run_seed_is_the_index_th_child_of_the_campaign_seed_sequence():
    children = np.random.SeedSequence(42).spawn(7)
    for i, child in enumerate(children):
        np.testing.assert_array_equal(run_seed(42, i).generate_state(4), child.generate_state(4))
    assert not np.array_equal(run_seed(42, 0).generate_state(4), run_seed(43, 0).generate_state(4))


def test_a_run_depends_on_its_index_not_on_n_chunking_or_seed_of_others(tmp_path):
    small = run_campaign(DRAWS, 4, tmp_path / "a", executor="inline", chunk_size=3, seed=5, progress=False)
    large = run_campaign(DRAWS, 9, tmp_path / "b", executor="inline", chunk_size=2, seed=5, progress=False)
    for name in small.arrays:
        np.testing.assert_array_equal(small.arrays[name], large.arrays[name][:4])
    np.testing.assert_array_equal(large.arrays["index"], np.arange(9))
    np.testing.assert_array_equal(large.arrays["index_seen"], np.arange(9))
    assert large.arrays["normal"].shape == (9, 3)
    # every run drew from its own stream
    assert len(np.unique(large.arrays["uniform"])) == 9
    expected = np.random.default_rng(run_seed(5, 6)).standard_normal(3)
    np.testing.assert_array_equal(large.arrays["normal"][6], expected)


def test_chunks_cut_sorted_indices():
    assert chunks(np.array([0, 1, 2, 5, 6]), 2) == [(0, 1), (2, 5), (6,)]


# -- executors ---------------------------------------------------------------------------------------


def test_inline_process_and_dask_executors_give_identical_results(tmp_path):
    distributed = pytest.importorskip("distributed")
    inline = run_campaign(DRAWS, 10, tmp_path / "inline", executor="inline", seed=11, progress=False)
    process = run_campaign(DRAWS, 10, tmp_path / "process", executor="process", workers=2, chunk_size=3, seed=11, progress=False)
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://", host="127.0.0.1", dashboard_address=None
    ) as cluster:
        dask = run_campaign(
            DRAWS, 10, tmp_path / "dask", executor="dask", scheduler=cluster.scheduler_address, chunk_size=4, seed=11, progress=False
        )
    assert_same_results(inline.arrays, process.arrays)
    assert_same_results(inline.arrays, dask.arrays)
    assert (inline.computed, process.computed, dask.computed) == (10, 10, 10)
    assert len(list((tmp_path / "process").glob("runs-*.npz"))) == 4


# -- interruption and resumption ---------------------------------------------------------------------


@pytest.mark.parametrize("executor", ["inline", "process"])
def test_a_failed_campaign_resumes_without_losing_or_repeating_a_run(tmp_path, executor):
    log, marker = tmp_path / "calls.log", tmp_path / "failed-once"
    parameters = {"log": str(log), "marker": str(marker), "fail_at": 6, "how": "raise"}
    options = dict(executor=executor, workers=2, chunk_size=1, seed=3, parameters=parameters, progress=False)
    with pytest.raises(RunFailed, match="run 6 failed"):
        run_campaign(FLAKY, 12, tmp_path / "out", **options)
    stored = ResultStore(tmp_path / "out").completed()
    assert 6 not in stored and set(range(6)) <= set(stored)
    first_calls = calls(log)

    resumed = run_campaign(FLAKY, 12, tmp_path / "out", **options)
    assert resumed.reused == len(stored) and resumed.computed == 12 - len(stored)
    second_calls = calls(log)[len(first_calls) :]
    assert sorted(second_calls) == sorted(set(range(12)) - set(stored.tolist())), "a stored run was recomputed"
    np.testing.assert_array_equal(resumed.arrays["index"], np.arange(12))

    uninterrupted = run_campaign(f"{TOY}:DRAWS", 12, tmp_path / "clean", executor="inline", seed=3, progress=False)
    assert_same_results(resumed.arrays, uninterrupted.arrays)


def test_a_killed_campaign_resumes_where_it_stopped(tmp_path):
    """The process running the campaign is killed (SIGKILL) inside run 5; `hybridtrack run` again finishes it."""
    log, marker, out = tmp_path / "calls.log", tmp_path / "killed-once", tmp_path / "out"
    args = [
        "run",
        str(TOY),
        "--n",
        "9",
        "--executor",
        "inline",
        "--chunk",
        "1",
        "--out",
        str(out),
        "--seed",
        "8",
        "--param",
        f"log={log}",
        "--param",
        f"marker={marker}",
        "--param",
        "fail_at=5",
        "--param",
        "how=kill",
        "--no-progress",
    ]
    killed = subprocess.run([sys.executable, "-m", "hybridtrack", *args], capture_output=True, text=True, timeout=120)
    assert killed.returncode == -9, killed.stderr
    assert ResultStore(out).completed().tolist() == [0, 1, 2, 3, 4]
    assert calls(log) == [0, 1, 2, 3, 4, 5]

    assert main([*args, "--json"]) == 0
    assert calls(log) == [0, 1, 2, 3, 4, 5, 5, 6, 7, 8]
    results = ResultStore(out).load()
    clean = run_campaign(DRAWS, 9, tmp_path / "clean", executor="inline", seed=8, progress=False)
    assert_same_results(results, clean.arrays)


def test_leftover_temporary_files_are_removed_and_never_read(tmp_path):
    run_campaign(DRAWS, 3, tmp_path, executor="inline", chunk_size=1, progress=False)
    leftover = tmp_path / "runs-0000003-0000004.npz.tmp-999-deadbeef"
    leftover.write_bytes(b"half a file")
    result = run_campaign(DRAWS, 5, tmp_path, executor="inline", chunk_size=1, progress=False)
    assert not leftover.exists()
    assert (result.reused, result.computed) == (3, 2)


def test_a_folder_of_another_campaign_is_refused(tmp_path):
    run_campaign(DRAWS, 2, tmp_path, executor="inline", seed=1, progress=False)
    with pytest.raises(CampaignMismatch, match="seed"):
        run_campaign(DRAWS, 2, tmp_path, executor="inline", seed=2, progress=False)
    with pytest.raises(CampaignMismatch, match="parameters"):
        run_campaign(DRAWS, 2, tmp_path, executor="inline", seed=1, parameters={"size": 4}, progress=False)
    with pytest.raises(CampaignMismatch, match="experiment"):
        run_campaign("demo_rmse", 2, tmp_path, executor="inline", seed=1, progress=False)


def test_a_run_stored_twice_is_reported(tmp_path):
    run_campaign(DRAWS, 2, tmp_path, executor="inline", chunk_size=2, progress=False)
    store = ResultStore(tmp_path)
    store.write_chunk([1], {"normal": np.zeros((1, 3)), "uniform": [0.0], "index_seen": [1]})
    with pytest.raises(CorruptResults, match=r"\[1\] stored more than once"):
        store.completed()


# -- definitions and errors --------------------------------------------------------------------------


def test_bad_arguments_are_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="n: expected a positive integer"):
        Campaign(DRAWS, 0, tmp_path)
    with pytest.raises(ValueError, match="unknown executor 'threads'; choose one of inline, process, dask"):
        Campaign(DRAWS, 2, tmp_path, executor="threads")
    with pytest.raises(ValueError, match="needs a scheduler address"):
        Campaign(DRAWS, 2, tmp_path, executor="dask")
    with pytest.raises(ValueError, match=r"unknown parameter\(s\) \['sigma'\]"):
        Campaign(DRAWS, 2, tmp_path, parameters={"sigma": 1})
    with pytest.raises(UnknownExperiment, match="known experiments: .*demo_rmse"):
        load_experiment("no_such_experiment")
    with pytest.raises(RunFailed, match="result 'label' is str"):
        run_campaign(f"{TOY}:NOT_NUMERIC", 1, tmp_path / "text", executor="inline", progress=False)


def test_an_experiment_object_with_an_importable_function_runs_without_a_locator(tmp_path):
    experiment = Experiment("sums", _sum_of_draws, {"count": 5})
    result = run_campaign(experiment, 3, tmp_path, executor="inline", progress=False)
    expected = [np.random.default_rng(run_seed(0, i)).uniform(size=5).sum() for i in range(3)]
    np.testing.assert_allclose(result.arrays["total"], expected)


def _sum_of_draws(index, rng, *, count):
    return {"total": rng.uniform(size=count).sum()}


def test_progress_bar_only_on_a_terminal(monkeypatch):
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert _progress(10, 0, "x", True).disable
    terminal = Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert _progress(10, 0, "x", False).disable
    with _progress(10, 4, "toy", True) as bar:
        bar.update(6)
    assert "toy" in terminal.getvalue() and "10/10" in terminal.getvalue()


# -- the CLI and the built-in experiment -------------------------------------------------------------


def test_cli_runs_demo_rmse_and_a_second_call_reuses_every_run(tmp_path, capsys):
    out = tmp_path / "demo"
    args = [
        "run",
        "demo_rmse",
        "--n",
        "3",
        "--executor",
        "inline",
        "--out",
        str(out),
        "--seed",
        "4",
        "--param",
        "steps_scale=0.1",
        "--param",
        "R=0.1",
        "--json",
    ]
    assert main(args) == 0
    first = json.loads(capsys.readouterr().out)
    assert (first["computed"], first["reused"], first["n"]) == (3, 0, 3)
    assert first["parameters"]["R"] == 0.1 and first["parameters"]["steps_scale"] == 0.1
    assert main(args) == 0
    second = json.loads(capsys.readouterr().out)
    assert (second["computed"], second["reused"]) == (0, 3)
    assert second["results"] == first["results"]

    arrays = ResultStore(out).load()
    assert arrays["squared_error"].shape == (3, 4) and np.all(arrays["steps"] == 37)  # steps 1 … K, as seed 001
    per_run = np.linalg.norm(np.sqrt(arrays["squared_error"] / arrays["steps"][:, None]), axis=1)
    np.testing.assert_allclose(arrays["nrmse"], per_run)
    pooled = pooled_rmse(arrays["squared_error"], arrays["steps"])
    assert np.all(pooled > 0) and np.all(pooled < 1.5)  # known-modes KF at R = 0.1: well under a metre
    assert 0.5 < np.mean(arrays["mean_nis"]) < 4  # 2 on average under the model


def test_cli_errors(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "nope"]) == 2
    assert "unknown experiment 'nope'; known experiments: demo_rmse" in capsys.readouterr().err
    assert main(["run", "demo_rmse", "--n", "0"]) == 2
    assert "--n: expected a positive integer" in capsys.readouterr().err
    assert main(["run", "demo_rmse", "--executor", "threads"]) == 2
    assert "invalid choice: 'threads'" in capsys.readouterr().err
    assert main(["run", "demo_rmse", "--executor", "dask"]) == 2
    assert "--executor dask needs --scheduler" in capsys.readouterr().err
    assert main(["run", "demo_rmse", "--param", "oops"]) == 2
    assert "expected KEY=VALUE" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


def test_cli_finds_experiments_by_name_in_the_experiments_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "experiments").mkdir()
    (tmp_path / "experiments" / "coin.py").write_text(
        "from hybridtrack.apps.experiment import Experiment\n"
        "EXPERIMENT = Experiment('coin', lambda index, rng: {'heads': float(rng.uniform() < 0.5)})\n"
    )
    assert main(["run", "coin", "--n", "4", "--executor", "inline", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["out"] == str(Path("runs") / "coin") and summary["computed"] == 4
    assert main(["run", "nothing_here"]) == 2
    assert "known experiments: coin, demo_rmse" in capsys.readouterr().err


# -- Ctrl-C and SIGKILL of a process-pool campaign ---------------------------------------------------

SLOW = f"{TOY}:SLOW"


def test_ctrl_c_inside_a_run_stores_the_finished_runs_and_resumes(tmp_path):
    log, marker = tmp_path / "calls.log", tmp_path / "interrupted-once"
    parameters = {"log": str(log), "marker": str(marker), "fail_at": 4, "how": "interrupt"}
    options = dict(executor="inline", chunk_size=3, seed=2, parameters=parameters, progress=False)
    with pytest.raises(CampaignInterrupted, match=r"interrupted: 4 of 7 runs stored in .* \(4 computed by this call\)") as caught:
        run_campaign(FLAKY, 7, tmp_path / "out", **options)
    assert isinstance(caught.value, KeyboardInterrupt)
    assert ResultStore(tmp_path / "out").completed().tolist() == [0, 1, 2, 3]  # run 3 of the interrupted chunk kept
    resumed = run_campaign(FLAKY, 7, tmp_path / "out", **options)
    assert (resumed.computed, resumed.reused) == (3, 4)
    assert calls(log) == [0, 1, 2, 3, 4, 4, 5, 6]


def _children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                status = (entry / "status").read_text()
            except OSError:
                continue
            fields = dict(line.split(":\t", 1) for line in status.splitlines() if ":\t" in line)
            if int(fields.get("PPid", "0")) == pid:
                found.append(int(entry.name))
    return found


def _running(pid: int) -> bool:
    """``pid`` exists and is not a zombie."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    return "State:\tZ" not in status


def _as_from_a_terminal() -> None:
    """In the child before exec: SIGINT at its default and unblocked, as a shell starts a program (a child inherits
    an ignored or blocked SIGINT, and a test run's threads — thread pools, spawned helpers — may leave it so)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _wait_for(condition, limit: float = 60.0) -> bool:
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc")
@pytest.mark.parametrize("how", ["SIGKILL", "Ctrl-C"])
def test_killing_a_process_pool_campaign_leaves_no_worker_and_resumes_every_run_once(tmp_path, how):
    """The main process of a 2-worker campaign is SIGKILLed (or gets Ctrl-C on its process group) after 3 chunks."""
    out, log, n = tmp_path / "out", tmp_path / "runs.log", 10
    args = ["run", SLOW, "--n", n, "--executor", "process", "--workers", 2, "--chunk", 1, "--out", out, "--seed", 6]
    args = [*map(str, args), "--param", "delay=0.3", "--param", f"log={log}", "--no-progress"]
    campaign = subprocess.Popen(
        [sys.executable, "-m", "hybridtrack", *args],
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=_as_from_a_terminal,
    )
    try:
        assert _wait_for(lambda: len(list(out.glob("runs-*.npz"))) >= 3), "the campaign stored nothing"
        workers = _children(campaign.pid)
        assert len(workers) >= 2, workers  # two workers (and perhaps multiprocessing's resource tracker)
        if how == "SIGKILL":
            os.kill(campaign.pid, signal.SIGKILL)
        else:
            os.killpg(campaign.pid, signal.SIGINT)  # what a terminal's Ctrl-C does
        status = campaign.wait(timeout=60)
        err = campaign.stderr.read()
    finally:
        if campaign.poll() is None:
            campaign.kill()
    assert _wait_for(lambda: not any(_running(pid) for pid in workers), limit=10), "a worker survived its campaign"
    if how == "SIGKILL":
        assert status == -signal.SIGKILL
    else:
        assert status == 130
        assert err.strip().splitlines() == [err.strip()] and "interrupted:" in err and "Traceback" not in err, err

    before = ResultStore(out).completed().tolist()
    assert len(before) >= 3 and len(set(before)) == len(before)
    logged_before = len(log.read_text().splitlines())
    assert main([*args, "--json"]) == 0
    recomputed = [int(line.split()[0]) for line in log.read_text().splitlines()[logged_before:]]
    assert sorted(recomputed) == sorted(set(range(n)) - set(before)), "a stored run was computed again"
    results = ResultStore(out).load()
    clean = run_campaign(DRAWS, n, tmp_path / "clean", executor="inline", seed=6, progress=False)
    assert_same_results(results, clean.arrays)  # every run exactly once, with its own seed
