"""The experiment scripts' figures (``--plot`` / ``--plot-only``), drawn from the committed JSON reports into a tmp dir."""

import importlib.util
import json
import struct
from pathlib import Path

import pytest

pytest.importorskip("matplotlib")  # in the test extra, so this runs

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"


def load(name):
    spec = importlib.util.spec_from_file_location(f"_plots_{name}", ROOT / "experiments" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def png_size(path: Path) -> tuple[int, int]:
    """Width and height from the PNG header (IHDR)."""
    header = path.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return struct.unpack(">II", header[16:24])


@pytest.mark.parametrize("name", ["seed001_adaptive", "tma_montecarlo", "example1"])
def test_plot_from_the_committed_report(tmp_path, name):
    png = load(name).plot(RESULTS / f"{name}.json", tmp_path / "figures" / f"{name}.png")
    assert png == tmp_path / "figures" / f"{name}.png"
    width, height = png_size(png)
    assert width >= 800 and 250 <= height <= width
    assert 10_000 < png.stat().st_size < 300_000


@pytest.mark.parametrize("name", ["seed001_adaptive", "example1"])
def test_plot_only_from_the_command_line(tmp_path, name, capsys):
    png = tmp_path / "out.png"
    load(name).main(["--plot-only", str(RESULTS / f"{name}.json"), "--plot", str(png)])
    assert png.is_file() and str(png) in capsys.readouterr().out


def test_tma_plot_only_and_a_report_with_one_sigma(tmp_path):
    tma = load("tma_montecarlo")
    report = json.loads((RESULTS / "tma_montecarlo.json").read_text())
    report["rows"] = [row for row in report["rows"] if row["sigma_deg"] == 0.5]  # a single σ: one point per method
    single = tmp_path / "single.json"
    single.write_text(json.dumps(report))
    assert tma.main(["--plot-only", str(single), "--plot", str(tmp_path / "single.png")]) == 0
    assert png_size(tmp_path / "single.png")[0] >= 800


def test_the_committed_figures_are_in_the_docs():
    results = (ROOT / "docs" / "results.md").read_text()
    for name in ("seed001_adaptive", "tma_montecarlo", "example1"):
        assert (ROOT / "docs" / "images" / f"{name}.png").is_file()
        assert f"images/{name}.png" in results
