"""The layering rules, checked on the source: the kernel never imports plugins; no private name crosses a package.

Every ``import``/``from … import`` anywhere in a module counts, including the
ones inside functions.  "Private" is a name starting with one underscore
(``_x``, not ``__x__``); its owner is the package holding the module that
defines it, and only modules inside that package (or its subpackages) may
import it.  The rule covers the kernel, the built-in plugins, the examples
(the third-party plugin included), the experiments and the benchmarks, and the
Python snippets of the docs.  The tests themselves are white-box and exempt.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = {"hybridtrack": "hybridtrack", "plugins": "hybridtrack_plugins"}
OURS = ("hybridtrack", "hybridtrack_plugins", "hybridtrack_zigzag")


def _module(path: Path) -> str | None:
    """Dotted name of a module of one of our packages (None outside them)."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    if parts[0] in PACKAGES:
        dotted = [PACKAGES[parts[0]], *parts[1:]]
    elif parts[:3] == ("examples", "thirdparty_plugin", "src"):
        dotted = list(parts[3:])
    else:
        return None
    return ".".join(dotted[:-1] if dotted[-1] == "__init__" else dotted)


def _imports(tree: ast.AST):
    """(line, dotted path of every imported name) for every import statement in the tree."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                yield node.lineno, f"{node.module}.{alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name


def _sources() -> list[tuple[str, ast.AST, str | None]]:
    files = [p for folder in ("hybridtrack", "plugins", "examples", "experiments", "benchmarks") for p in (ROOT / folder).rglob("*.py")]
    found = [(str(p.relative_to(ROOT)), ast.parse(p.read_text()), _module(p)) for p in sorted(files)]
    for page in sorted((ROOT / "docs").rglob("*.md")):
        for i, snippet in enumerate(re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)):
            try:
                tree = ast.parse(snippet)
            except SyntaxError:  # an excerpt with "..." in place of code; its import lines still count
                tree = ast.parse("\n".join(line for line in snippet.splitlines() if line.lstrip().startswith(("import ", "from "))))
            found.append((f"{page.relative_to(ROOT)} (snippet {i + 1})", tree, None))
    return found


SOURCES = _sources()


def private_imports(sources) -> list[str]:
    bad = []
    for where, tree, module in sources:
        importer = None if module is None else (module if where.endswith("__init__.py") else module.rpartition(".")[0])
        for line, dotted in _imports(tree):
            parts = dotted.split(".")
            if parts[0] not in OURS:
                continue
            for i, part in enumerate(parts):
                if part.startswith("_") and not part.startswith("__"):
                    # a private module or name of a package belongs to that package; a private name of a module, to its package
                    owner = ".".join(parts[:i] if _is_package(parts[:i]) else parts[: i - 1])
                    if importer is None or not (importer == owner or importer.startswith(owner + ".")):
                        bad.append(f"{where}:{line}: {dotted}")
                    break
    return bad


def _is_package(parts: list[str]) -> bool:
    """Whether the dotted path names a package (a folder) rather than a module."""
    top = {"hybridtrack": ROOT / "hybridtrack", "hybridtrack_plugins": ROOT / "plugins"}.get(parts[0])
    if top is None:
        return True
    return top.joinpath(*parts[1:]).is_dir()


def test_the_kernel_never_imports_plugins():
    offenders = [
        f"{where}:{line}: {dotted}"
        for where, tree, _ in SOURCES
        if where.startswith("hybridtrack/")
        for line, dotted in _imports(tree)
        if dotted.split(".")[0] == "hybridtrack_plugins"
    ]
    assert not offenders, "the kernel imports plugins:\n" + "\n".join(offenders)


def test_no_private_name_is_imported_across_packages():
    offenders = private_imports(SOURCES)
    assert not offenders, "private names imported from another package:\n" + "\n".join(offenders)


@pytest.mark.parametrize(
    ("source", "module", "flagged"),
    [
        ("from hybridtrack._x import y", "hybridtrack_plugins.filters.kalman", True),
        ("def f():\n    from hybridtrack_plugins.filters._covariance import update", "hybridtrack.engine.pipeline", True),
        ("from hybridtrack_plugins.filters._covariance import update", "hybridtrack_plugins.filters.kalman", False),
        ("from hybridtrack.engine.pipeline import _helper", "hybridtrack.engine.bank", False),
        ("from hybridtrack.engine.pipeline import _helper", "hybridtrack.algorithms.known_switch", True),
        ("from hybridtrack.engine.pipeline import _helper", None, True),
        ("import numpy._core", None, False),
    ],
)
def test_the_private_import_rule_itself(source, module, flagged):
    assert bool(private_imports([("x.py", ast.parse(source), module)])) is flagged
