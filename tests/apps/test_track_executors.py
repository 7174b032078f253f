"""``hybridtrack track --executor``: the objects of a file tracked in shards on an executor (inline, a Dask
LocalCluster) give the summary and the outputs of the one in-process batch; bad executor options are refused."""

import json

import numpy as np
import pytest

from hybridtrack.apps.tracking import ConfigError, track_file
from hybridtrack.cli import main

CONFIG = """
[reader]
id = "id"
min_reports = 5

[measurement]
sigma = 5.0

[estimator]
algorithm = "imm"
noise_density = 0.001
modes = ["straight", "coordinated_turn"]
sojourn = 60.0
"""


@pytest.fixture
def ships(tmp_path):
    """Three ships of different lengths (x/y metres), one turning left, and one object too short to track."""
    rows, rng = ["time,id,x,y"], np.random.default_rng(4)
    for name, count, turn in (("a", 40, True), ("b", 25, False), ("c", 31, True), ("short", 3, False)):
        t = np.arange(count) * 5.0
        angle = np.where(t > 60, (t - 60) * 6.0 / 300.0, 0.0) if turn else np.zeros(count)
        heading = np.cumsum(np.r_[0.0, np.diff(angle)])
        x = np.cumsum(6.0 * 5.0 * np.cos(heading)) + rng.normal(0, 2, count)
        y = np.cumsum(6.0 * 5.0 * np.sin(heading)) + rng.normal(0, 2, count) + 1000.0 * len(rows)
        rows += [f"{a:g},{name},{p:.2f},{q:.2f}" for a, p, q in zip(t, x, y)]
    csv, cfg = tmp_path / "ships.csv", tmp_path / "c.toml"
    csv.write_text("\n".join(rows) + "\n")
    cfg.write_text(CONFIG)
    return csv, cfg


def same_outputs(one, other, summary):
    for entry in summary["objects"]:
        with np.load(one / f"{entry['output']}.npz") as a, np.load(other / f"{entry['output']}.npz") as b:
            np.testing.assert_allclose(a["means"], b["means"], rtol=0, atol=1e-9)
            assert (a["modes"] == b["modes"]).all()
        assert (other / f"{entry['output']}.rrd").stat().st_size > 0


def test_shards_inline_and_on_a_dask_local_cluster_give_the_batch_summary(ships, tmp_path):
    distributed = pytest.importorskip("distributed")
    csv, cfg = ships
    batch = track_file(csv, cfg, tmp_path / "batch")
    inline = track_file(csv, cfg, tmp_path / "inline", executor="inline", shard_objects=1)
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, protocol="tcp://", host="127.0.0.1", dashboard_address=None
    ) as cluster:
        dask = track_file(csv, cfg, tmp_path / "dask", executor="dask", scheduler=cluster.scheduler_address, shard_objects=2)
    assert [o["id"] for o in batch["objects"]] == ["a", "b", "c"]
    assert batch["skipped"] == [{"id": "short", "reason": "3 reports < min_reports 5"}]
    for summary, folder in ((inline, "inline"), (dask, "dask")):
        assert json.dumps(summary["objects"]) == json.dumps(batch["objects"])  # the file's order, whatever the shards'
        assert summary["skipped"] == batch["skipped"]
        same_outputs(tmp_path / "batch", tmp_path / folder, batch)


def test_bad_executor_options_are_refused_before_tracking(ships, tmp_path, capsys):
    csv, cfg = ships
    with pytest.raises(ConfigError, match="--executor 'threads': expected one of inline, process, dask"):
        track_file(csv, cfg, tmp_path / "out", executor="threads")
    with pytest.raises(ConfigError, match="shard_objects = 0: expected a positive number"):
        track_file(csv, cfg, tmp_path / "out", executor="inline", shard_objects=0)
    status = main(["track", str(csv), "--config", str(cfg), "--out", str(tmp_path / "cli"), "--executor", "dask", "--no-progress"])
    assert status == 2 and "--executor dask needs --scheduler ADDRESS" in capsys.readouterr().err
    assert not (tmp_path / "out" / "summary.json").exists()
