"""The reproduction scripts on the runner write the agreed JSON layout; the report helper's tables."""

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hybridtrack.apps.reporting import Column, markdown_table, plain, write_report

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def load(name):
    spec = importlib.util.spec_from_file_location(f"_reproduction_{name}", EXPERIMENTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_seed001_adaptive_writes_the_agreed_json_layout_small(tmp_path):
    out = tmp_path / "seed001.json"
    report = load("seed001_adaptive").main(
        [
            "--json",
            str(out),
            "--n",
            "2",
            "--R",
            "0.1",
            "0.01",
            "--steps-scale",
            "0.3",
            "--executor",
            "inline",
            "--out",
            str(tmp_path / "runs"),
            "--no-progress",
            "--replicates",
            "1",
        ]
    )
    written = json.loads(out.read_text())
    assert written["rows"] == plain(report["rows"])  # NaN (a segment no run decided in) is written as null
    assert [row["R"] for row in written["rows"]] == [0.1, 0.01]
    for row in written["rows"]:
        assert set(row) == {"R", "optimal_nrmse", "adaptive_nrmse", "rmse_optimal", "rmse_adaptive", "decision_steps", "modes_correct"}
        assert len(row["rmse_optimal"]) == 4 and len(row["rmse_adaptive"]) == 4 and len(row["decision_steps"]) == 6
        assert math.isclose(row["optimal_nrmse"], float(np.linalg.norm(row["rmse_optimal"])))
        assert math.isclose(row["adaptive_nrmse"], float(np.linalg.norm(row["rmse_adaptive"])))
        assert 0 <= row["modes_correct"] <= 1
        assert 0 < row["optimal_nrmse"] < row["adaptive_nrmse"]  # the filter told the modes is the better one
    protocol = written["protocol"]
    assert protocol["trajectories_per_R"] == 2 and protocol["alpha"] == 0.01 and protocol["bank"]["filters"] == 21
    for extra, row in zip(protocol["supplementary"], written["rows"]):  # the seed's rule and the steps, same trajectories
        for other in [extra["seed_rule"], *extra["steps"]]:
            assert other["optimal_nrmse"] == row["optimal_nrmse"] and math.isclose(
                other["adaptive_nrmse"], float(np.linalg.norm(other["rmse_adaptive"]))
            )
            assert other["mean_decision_steps_undecided_as_length"] >= 0 and 0 <= other["undecided_fraction"] <= 1
        assert len(extra["steps"]) == 4 and len(extra["replicates"]) == 2
        assert (
            extra["replicate_spread"]["adaptive_nrmse"]["min"]
            <= row["adaptive_nrmse"]
            <= extra["replicate_spread"]["adaptive_nrmse"]["max"]
        )
    table = out.with_suffix(".md").read_text()
    # ours, the seed's figures, the supplementary table, the seed's rule, five rules of the steps table, the replicates
    assert table.count("\n| 0.1 |") == 10 and "Seed 001" in table


def test_report_tables_and_strict_json(tmp_path):
    rows = [
        {"name": "a", "values": np.array([1.0, 2.5]), "score": np.float64(0.25)},
        {"name": "b", "values": [3.0, float("nan")], "score": None},
    ]
    columns = [Column("name", "name"), Column("values", "v1", ".2f", 0), Column("values", "v2", ".2f", 1), Column("score", "score", ".3f")]
    assert markdown_table(plain(rows), columns) == (
        "| name | v1 | v2 | score |\n|---|---|---|---|\n| a | 1.00 | 2.50 | 0.250 |\n| b | 3.00 | – | – |\n"
    )
    json_path, md_path = write_report(tmp_path / "r.json", rows, {"runs": np.int64(3)}, columns=columns, title="T")
    data = json.loads(json_path.read_text())
    assert data == {
        "rows": [{"name": "a", "values": [1.0, 2.5], "score": 0.25}, {"name": "b", "values": [3.0, None], "score": None}],
        "protocol": {"runs": 3},
    }
    assert md_path.read_text().startswith("### T\n\n| name |")
    with pytest.raises(KeyError, match="row has no 'missing'"):
        markdown_table(rows, [Column("missing", "m")])


def _numbers(value):
    """Every number of a report (nested lists/dicts flattened in order; None → NaN), and the non-numbers."""
    if isinstance(value, dict):
        return [x for key in sorted(value) if key != "command" for x in _numbers(value[key])]
    if isinstance(value, (list, tuple)):
        return [x for item in value for x in _numbers(item)]
    if value is None:
        return [math.nan]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return [value]
    return [float(value)]


def _assert_same_report(a: Path, b: Path):
    left, right = _numbers(json.loads(a.read_text())), _numbers(json.loads(b.read_text()))
    assert len(left) == len(right)
    for x, y in zip(left, right):
        if isinstance(x, float) and isinstance(y, float):
            assert (math.isnan(x) and math.isnan(y)) or math.isclose(x, y, rel_tol=1e-12, abs_tol=1e-12), (x, y)
        else:
            assert x == y


@pytest.mark.parametrize(
    "name, extra",
    [
        ("seed001_adaptive", ["--R", "0.1", "--replicates", "0", "--no-ablation"]),
        ("seed001_unknown_change", ["--R", "0.01", "--modes", "table1", "--bank-size", "12"]),
    ],
)
def test_reproductions_go_through_the_runner_batched_and_per_run_alike(tmp_path, name, extra):
    """The default path is the campaign runner with run_batch (chunks stored, resumable); --per-run the same runner
    one run at a time: the same report to 1e-12, each stored in its own campaign folders."""
    module = load(name)
    assert module.EXPERIMENT.run_batch is not None and module.PER_RUN.run_batch is None
    common = ["--n", "3", "--steps-scale", "0.2", "--executor", "inline", "--out", str(tmp_path / "runs"), "--no-progress", *extra]
    module.main(["--json", str(tmp_path / "batched.json"), *common])
    module.main(["--json", str(tmp_path / "per_run.json"), "--per-run", *common])
    _assert_same_report(tmp_path / "batched.json", tmp_path / "per_run.json")
    batched = [p for p in (tmp_path / "runs").rglob("runs-*.npz") if "per_run" not in p.parts]
    per_run = list((tmp_path / "runs" / "per_run").rglob("runs-*.npz"))
    campaigns = len({p.parent for p in batched})
    assert campaigns >= 1 and len(batched) == campaigns  # one batch (one stored chunk) per campaign
    assert len({p.parent for p in per_run}) == campaigns
    stamp = {p: p.stat().st_mtime_ns for p in batched}
    module.main(["--json", str(tmp_path / "again.json"), *common])  # resumed: every run found stored, nothing recomputed
    assert {p: p.stat().st_mtime_ns for p in batched} == stamp
    _assert_same_report(tmp_path / "batched.json", tmp_path / "again.json")
