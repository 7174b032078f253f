"""Fixtures of the kernel tests: fake installed distributions and a clean default-plugin cache."""

from __future__ import annotations

import importlib
import sys
import textwrap
from pathlib import Path

import pytest

import hybridtrack.core.plugins


class DistributionFactory:
    """Writes installed-looking distributions (``*.dist-info`` + modules) into one folder on ``sys.path``.

    ``importlib.metadata`` finds them exactly like ``pip install`` output, so
    their entry points are real; the folder leaves ``sys.path`` and the modules
    leave ``sys.modules`` when the test ends.
    """

    def __init__(self, root: Path, monkeypatch: pytest.MonkeyPatch):
        self.root = root
        self.modules: set[str] = set()
        root.mkdir(parents=True, exist_ok=True)
        monkeypatch.syspath_prepend(str(root))

    def __call__(
        self,
        name: str,
        entry_points: dict[str, str],
        modules: dict[str, str] | None = None,
        *,
        version: str = "1.0",
        group: str = hybridtrack.core.plugins.ENTRY_POINT_GROUP,
        source_root: Path | None = None,
    ) -> Path:
        """Install distribution ``name`` with ``entry_points`` (entry name → module) in ``group``.

        ``modules`` maps a module name to its source (written next to the
        dist-info); ``source_root`` adds an existing source folder to the path
        instead (a ``.pth``-like editable install of e.g. an example project).
        """
        for module, source in (modules or {}).items():
            (self.root / f"{module}.py").write_text(textwrap.dedent(source))
            self.modules.add(module)
        info = self.root / f"{name.replace('-', '_')}-{version}.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
        lines = [f"[{group}]"] + [f"{entry} = {target}" for entry, target in entry_points.items()]
        (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
        if source_root is not None:
            sys.path.insert(0, str(source_root))
        importlib.invalidate_caches()
        return info

    def cleanup(self, extra_paths: list[str]) -> None:
        roots = tuple([str(self.root)] + extra_paths)
        for module in list(sys.modules):
            where = getattr(sys.modules[module], "__file__", None) or ""
            if module in self.modules or where.startswith(roots):
                del sys.modules[module]
        for path in extra_paths:
            while path in sys.path:
                sys.path.remove(path)
        importlib.invalidate_caches()


@pytest.fixture
def install_distribution(tmp_path, monkeypatch):
    """A :class:`DistributionFactory` on a fresh folder; the default plugins are re-read after the test."""
    before = list(sys.path)
    factory = DistributionFactory(tmp_path / "site", monkeypatch)
    hybridtrack.core.plugins.reset()
    yield factory
    factory.cleanup([p for p in sys.path if p not in before and p != str(factory.root)])
    hybridtrack.core.plugins.reset()


@pytest.fixture
def fresh_default_plugins():
    """Forget the cached default plugins before and after the test (for tests that change the environment)."""
    hybridtrack.core.plugins.reset()
    yield
    hybridtrack.core.plugins.reset()
