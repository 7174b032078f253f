"""Smoke runs of the seed 002 Monte Carlo and benchmark scripts (tiny sizes)."""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def run(script, *args):
    return subprocess.run([sys.executable, str(ROOT / script), *args], capture_output=True, text=True, check=True, cwd=ROOT)


def test_montecarlo_script_writes_the_table(tmp_path):
    out = tmp_path / "mc.json"
    md = tmp_path / "mc.md"
    result = run(
        "experiments/tma_montecarlo.py",
        "--n",
        "20",
        "--sigma",
        "0",
        "0.5",
        "--seed",
        "3",
        "--json",
        str(out),
        "--markdown",
        str(md),
        "--filter-n",
        "4",
        "--particles",
        "300",
    )
    data = json.loads(out.read_text())
    assert {row["method"] for row in data["rows"]} == {"LM", "N", "LM (filter targets)", "particle", "gaussian_sum"}
    filters = [row for row in data["rows"] if row["ref"] is None]
    assert {row["sigma_deg"] for row in filters} == {0.5} and all(row["targets"] == 4 for row in filters)
    assert all(len(row["ref_end"]) == 4 and all(0 <= r <= 1 for r in row["ref_end"]) for row in filters)
    assert "| particle | 0.5 | ours, end (4 targets) |" in md.read_text()
    for row in data["rows"]:
        if row["ref"] is None:
            continue
        assert set(row) >= {"method", "sigma_deg", "ref", "ref_end", "sqrt_ka_deg", "nf", "iter"}
        assert len(row["ref"]) == 4 and all(0 <= r <= 1 for r in row["ref"])
        if row["sigma_deg"] == 0:
            assert row["ref"] == [1.0, 1.0, 1.0, 1.0] and row["ref_end"] == [1.0, 1.0, 1.0, 1.0]
        if row["method"] == "N":
            assert row["nf"] is None and row["iter"] is None
        else:
            assert row["iter"] > 0 and row["nf"] > row["iter"]
    assert "start of the observation" in data["protocol"]["error_time"]
    assert "| LM | 0.5 | seed |" in md.read_text() and "| LM | 0.5 | ours, start |" in result.stdout


def test_benchmark_script(tmp_path):
    out = tmp_path / "bench.json"
    run("benchmarks/tma.py", "--n", "30", "--scipy-n", "10", "--repeats", "1", "--json", str(out))
    data = json.loads(out.read_text())
    assert data["scipy_loop"]["timed_targets"] == 10 and data["scipy_loop"]["scaled_to_targets"] == 30
    assert data["speedup"] > 0
    assert 0 <= data["batched_lm"]["converged_rate"] <= 1 and 0 <= data["scipy_loop"]["success_rate"] <= 1
