"""The documentation site builds with ``mkdocs build --strict``, and every page is in its nav."""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _nav_pages(nav) -> list[str]:
    pages = []
    for entry in nav:
        value = next(iter(entry.values())) if isinstance(entry, dict) else entry
        pages += _nav_pages(value) if isinstance(value, list) else [value]
    return pages


def _config() -> dict:
    yaml = pytest.importorskip("yaml", reason="PyYAML comes with mkdocs; install the docs extra")
    # mkdocs.yml uses no custom tags, so the safe loader reads it
    return yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))


def test_every_page_is_in_the_nav_and_every_nav_page_exists():
    config = _config()
    listed = set(_nav_pages(config["nav"]))
    pages = {str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md") if p.relative_to(DOCS).parts[0] != "results"}
    assert not sorted(pages - listed), f"docs pages missing from mkdocs.yml nav: {sorted(pages - listed)}"
    assert not sorted(listed - pages), f"mkdocs.yml nav lists missing pages: {sorted(listed - pages)}"


def test_results_page_quotes_every_reproduction_script():
    text = (DOCS / "results.md").read_text(encoding="utf-8")
    for script in sorted((ROOT / "experiments").glob("*.py")):
        assert f"experiments/{script.name}" in text, f"docs/results.md does not mention experiments/{script.name}"


@pytest.mark.skipif(
    importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None,
    reason="mkdocs/mkdocstrings not installed (pip install -e '.[docs]')",
)
def test_mkdocs_build_strict(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert result.returncode == 0, result.stdout + result.stderr
    site = tmp_path / "site"
    assert (site / "index.html").exists() and (site / "results" / "index.html").exists()
    api = (site / "api" / "experiment" / "index.html").read_text(encoding="utf-8")
    assert "Campaign" in api and "run_seed" in api  # mkdocstrings rendered the kernel's docstrings
