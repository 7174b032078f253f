"""``make screenshots`` (tools/screenshots.py): its pieces without the viewer, and the committed screenshots in the docs."""

import importlib.util
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
IMAGES = ROOT / "docs" / "images"


def load_tool():
    spec = importlib.util.spec_from_file_location("_screenshots_tool", ROOT / "tools" / "screenshots.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_aircraft_settings_on_the_solent_file_keep_everything_but_the_reader(tmp_path):
    tool = load_tool()
    config = tomllib.loads(tool.aircraft_on_solent(tmp_path).read_text())
    original = tomllib.loads((ROOT / "examples" / "aircraft.toml").read_text())
    assert config["reader"] == {"preset": "solent_ais", "max_speed": 400.0, "jump_tolerance": 200.0, "min_reports": 20}
    assert {k: v for k, v in config.items() if k != "reader"} == {k: v for k, v in original.items() if k != "reader"}


def test_shrink_keeps_a_png_under_the_limit(tmp_path):
    Image = pytest.importorskip("PIL.Image")
    tool = load_tool()
    noise = np.random.default_rng(0).integers(0, 256, size=(200, 300, 3), dtype=np.uint8)  # incompressible
    Image.fromarray(noise).save(tmp_path / "raw.png")
    size = tool.shrink(tmp_path / "raw.png", tmp_path / "small.png", limit=30_000)  # 7 bits a pixel: must scale down
    small = Image.open(tmp_path / "small.png")
    assert size == (tmp_path / "small.png").stat().st_size <= 30_000
    assert small.mode == "P" and small.width < 300  # 128-colour palette, scaled


def test_every_example_has_a_committed_screenshot_shown_in_the_docs():
    tool = load_tool()
    examples = ["demo", "example1", "bearings_only", "monte_carlo", "monte_carlo_summary"]
    examples += [f"{config}_{vessel}" for config in ("ships", "aircraft") for vessel in tool.VESSELS]
    pages = {name: (ROOT / "docs" / name).read_text() for name in ("examples.md", "recording.md", "results.md")}
    for name in examples:
        png = IMAGES / f"rerun_{name}.png"
        assert png.is_file(), f"{png} missing: run make screenshots"
        assert png.stat().st_size < 300_000
        assert f"images/rerun_{name}.png" in pages["examples.md"]
    assert "images/rerun_demo.png" in pages["recording.md"]
    assert len(set(re.findall(r"images/rerun_\w+\.png", pages["results.md"]))) >= 2
