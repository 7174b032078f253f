"""The docs name only code that exists: every dotted ``hybridtrack…`` name in the pages and the README resolves.

A name is resolved by importing its longest importable module prefix and
reading the rest as attributes; ``:mod:``/``:class:`` roles and code spans are
both covered.  File paths (``plugins/filters/kalman.py``) are checked too.
"""

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")), *sorted((ROOT / "examples").rglob("README.md"))]
DOTTED = re.compile(r"\b(hybridtrack(?:_plugins|_zigzag)?(?:\.[A-Za-z_][A-Za-z0-9_]*)+)")
PATH = re.compile(r"`((?:hybridtrack|plugins|examples|experiments|benchmarks|tests|docs)/[A-Za-z0-9_./-]+\.(?:py|md|toml|json))`")


def resolves(name: str) -> bool:
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attribute in parts[cut:]:
            if not hasattr(obj, attribute):
                return False
            obj = getattr(obj, attribute)
        return True
    return False


def _names():
    found = []
    for page in PAGES:
        text = page.read_text()
        found += [(page.relative_to(ROOT), n.rstrip(".")) for n in DOTTED.findall(text)]
    return sorted(set(found))


@pytest.mark.parametrize(("page", "name"), _names(), ids=lambda v: str(v))
def test_named_code_exists(page, name, monkeypatch):
    if name.startswith("hybridtrack_zigzag"):  # the third-party example's package, from its source tree
        monkeypatch.syspath_prepend(str(ROOT / "examples" / "thirdparty_plugin" / "src"))
    assert resolves(name), f"{page} names {name}, which does not exist"


def test_named_files_exist():
    missing = [
        f"{page.relative_to(ROOT)}: {path}"
        for page in PAGES
        for path in PATH.findall(page.read_text())
        if "NAME" not in path and not (ROOT / path).exists() and not (ROOT / "examples" / "thirdparty_plugin" / path).exists()
    ]
    assert not missing, "pages name files that do not exist:\n" + "\n".join(missing)
