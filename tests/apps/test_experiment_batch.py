"""The runner with batched experiments: a chunk is one ``run_batch`` call, results equal the per-run path whatever
the chunking and executor, resume works per chunk, a failing batch is located run by run."""

from pathlib import Path

import numpy as np
import pytest

from hybridtrack.apps.experiment import CampaignInterrupted, Experiment, ResultStore, RunFailed, run_campaign
from hybridtrack.apps.experiment.worker import run_chunk

SCRIPT = Path(__file__).with_name("_batch_experiments.py")
BATCHED = f"{SCRIPT}:BATCHED"
PER_RUN = f"{SCRIPT}:PER_RUN"
N = 9


def assert_close(a, b):
    assert sorted(a) == sorted(b)
    for name in a:
        np.testing.assert_allclose(a[name], b[name], rtol=1e-12, atol=1e-12, err_msg=name)


def log_lines(log: Path) -> list[str]:
    return log.read_text().splitlines() if log.exists() else []


@pytest.fixture(scope="module")
def per_run(tmp_path_factory):
    """The reference: every run through run_one."""
    out = tmp_path_factory.mktemp("per_run")
    return run_campaign(PER_RUN, N, out, executor="inline", chunk_size=2, seed=4, progress=False).arrays


def test_batched_campaign_equals_the_per_run_campaign_and_uses_batches(tmp_path, per_run):
    log = tmp_path / "calls.log"
    result = run_campaign(BATCHED, N, tmp_path / "out", executor="inline", seed=4, parameters={"log": str(log)}, progress=False)
    assert_close(result.arrays, per_run)
    assert log_lines(log) == ["batch 0 3", "batch 4 7", "batch 8 8"]  # default chunk = the experiment's batch_size (4)
    assert result.arrays["first_decision"].dtype.kind == "i"


@pytest.mark.parametrize("chunk_size", [1, 2, 5, N])
def test_batched_results_do_not_depend_on_the_chunk_size(tmp_path, per_run, chunk_size):
    result = run_campaign(BATCHED, N, tmp_path / "out", executor="inline", chunk_size=chunk_size, seed=4, progress=False)
    assert_close(result.arrays, per_run)


@pytest.mark.slow
def test_process_and_dask_executors_distribute_batches(tmp_path, per_run):
    process = run_campaign(BATCHED, N, tmp_path / "process", executor="process", workers=2, chunk_size=3, seed=4, progress=False)
    assert_close(process.arrays, per_run)
    assert len(list((tmp_path / "process").glob("runs-*.npz"))) == 3
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://", host="127.0.0.1", dashboard_address=None
    ) as cluster:
        dask = run_campaign(
            BATCHED, N, tmp_path / "dask", executor="dask", scheduler=cluster.scheduler_address, chunk_size=4, seed=4, progress=False
        )
    assert_close(dask.arrays, per_run)


def test_an_interrupted_batched_campaign_resumes_per_chunk(tmp_path, per_run):
    log, marker = tmp_path / "calls.log", tmp_path / "interrupted-once"
    parameters = {"log": str(log), "marker": str(marker), "interrupt_at": 4}
    options = dict(executor="inline", chunk_size=3, seed=4, parameters=parameters, progress=False)
    with pytest.raises(CampaignInterrupted, match=r"3 of 9 runs stored"):
        run_campaign(BATCHED, N, tmp_path / "out", **options)
    assert ResultStore(tmp_path / "out").completed().tolist() == [0, 1, 2]  # the interrupted chunk (3, 4, 5) is lost whole
    resumed = run_campaign(BATCHED, N, tmp_path / "out", **options)
    assert (resumed.computed, resumed.reused) == (6, 3)
    assert log_lines(log) == ["batch 0 2", "batch 3 5", "batch 3 5", "batch 6 8"]
    assert_close(resumed.arrays, per_run)


def test_a_failing_batch_is_run_again_run_by_run_and_reported(tmp_path, per_run):
    log = tmp_path / "calls.log"
    options = dict(executor="inline", chunk_size=3, seed=4, parameters={"log": str(log), "fail_at": 4}, progress=False)
    with pytest.raises(RunFailed, match=r"run 3 failed[\s\S]*run_batch of runs 3…5[\s\S]*planned batch failure"):
        run_campaign(BATCHED, N, tmp_path / "out", **options)
    assert "one 3" in log_lines(log) and "one 5" in log_lines(log)
    # run_one succeeded on the failing chunk, so its runs are stored; the campaign started no chunk after the failure
    stored = ResultStore(tmp_path / "out").completed().tolist()
    assert stored == list(range(6))
    resumed = run_campaign(BATCHED, N, tmp_path / "out", **options)  # the chunk holding run 4 is stored: no failure left
    assert (resumed.computed, resumed.reused) == (3, 6)
    assert_close(resumed.arrays, per_run)


def _stacked_batch(indices, rngs, *, size=2):
    return {"normal": np.stack([rng.standard_normal(size) for rng in rngs]), "index_seen": np.array(indices)}


def _one(index, rng, *, size=2):
    return {"normal": rng.standard_normal(size), "index_seen": index}


def test_run_batch_may_return_arrays_stacked_over_the_runs_and_bad_results_are_named():
    experiment = Experiment("stacked", _one, {"size": 2}, run_batch=_stacked_batch)
    batched = run_chunk(experiment, {"size": 2}, 1, [2, 5])
    single = run_chunk(Experiment("single", _one, {"size": 2}), {"size": 2}, 1, [2, 5])
    assert batched.indices == (2, 5) and batched.failure is None
    np.testing.assert_array_equal(batched.results["normal"], single.results["normal"])
    short = Experiment("short", _one, {"size": 2}, run_batch=lambda indices, rngs, size: [{"normal": 0.0}])
    outcome = run_chunk(short, {"size": 2}, 1, [2, 5])
    assert "returned 1 results for 2 runs" in outcome.failure[1]
    with pytest.raises(TypeError, match="run_batch must be callable"):
        Experiment("bad", _one, run_batch=3)
    with pytest.raises(ValueError, match="batch_size"):
        Experiment("bad", _one, run_batch=_stacked_batch, batch_size=0)
