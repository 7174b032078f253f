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

ROOT = Path(__file__).resolve().parents[1]
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
        ("from hybridtrack.engine.pipeline import _helper", "hybridtrack.algorithms.adaptive", True),
        ("from hybridtrack.engine.pipeline import _helper", None, True),
        ("import numpy._core", None, False),
    ],
)
def test_the_private_import_rule_itself(source, module, flagged):
    assert bool(private_imports([("x.py", ast.parse(source), module)])) is flagged


# --------------------------------------------------------------------------- layers point downwards

#: rank of each layer of hybridtrack; a module may import its own layer and the ones of lower rank
#: (recording and io are siblings: neither imports the other)
LAYERS = {"core": 0, "sdk": 1, "engine": 2, "algorithms": 3, "recording": 4, "io": 4, "apps": 5, "testing": 5, "cli": 6}
#: what a plugin (built-in or third-party) may import from hybridtrack
PLUGIN_LAYERS = ("core", "sdk")


def _layer(dotted: str) -> str | None:
    parts = dotted.split(".")
    return parts[1] if parts[0] == "hybridtrack" and len(parts) > 1 and parts[1] in LAYERS else None


def layer_violations(sources) -> list[str]:
    """Imports of a higher layer, or of a sibling layer, from a module of hybridtrack's layers; imports of
    anything but core and sdk (or the package root, for hookimpl and the user surface) from a plugin."""
    bad = []
    for where, tree, module in sources:
        if module is None:
            continue
        own = _layer(module)
        plugin = module.split(".")[0] in ("hybridtrack_plugins", "hybridtrack_zigzag")
        for line, dotted in _imports(tree):
            target = _layer(dotted)
            if dotted.split(".")[0] != "hybridtrack" or target is None:
                continue
            if plugin and target not in PLUGIN_LAYERS:
                bad.append(f"{where}:{line}: a plugin imports {dotted}")
            elif own is not None and target != own and LAYERS[target] >= LAYERS[own]:
                bad.append(f"{where}:{line}: {own} imports {dotted}")
    return bad


def test_imports_point_downwards():
    offenders = layer_violations(SOURCES)
    assert not offenders, "imports against the layers (core ← sdk ← engine ← algorithms ← recording / io ← apps ← cli):\n" + "\n".join(
        offenders
    )


@pytest.mark.parametrize(
    ("source", "module", "flagged"),
    [
        ("from hybridtrack.recording import RerunRecorder", "hybridtrack.engine.pipeline", True),
        ("from hybridtrack.sdk.linalg import cholesky", "hybridtrack.engine.pipeline", False),
        ("def f():\n    from hybridtrack.apps.tracking import track", "hybridtrack.io.track_files", True),
        ("from hybridtrack.io.track_files import read_tracks", "hybridtrack.recording.recorder", True),
        ("from hybridtrack.engine.pipeline import Pipeline", "hybridtrack_plugins.filters.kalman", True),
        ("from hybridtrack.sdk.estimation import BankEstimator", "hybridtrack_zigzag.estimator", False),
        ("from hybridtrack import hookimpl", "hybridtrack_plugins.filters.kalman", False),
    ],
)
def test_the_layer_rule_itself(source, module, flagged):
    assert bool(layer_violations([("x.py", ast.parse(source), module)])) is flagged


# --------------------------------------------------------------------------- private attributes

#: private-looking names that are documented public API of their library
PUBLIC_UNDERSCORE = {"_exit"}  # os._exit: the documented way out of a forked child without cleanup


def _package(module: str) -> str:
    """The package a module's private names belong to: its first two dotted parts (hybridtrack.engine, …)."""
    return ".".join(module.split(".")[:2])


def _private_names(tree: ast.AST) -> set[str]:
    """The ``_names`` a module defines: functions, classes, attributes it assigns, module variables."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
    return {n for n in names if n.startswith("_") and not n.startswith("__")}


def private_attribute_uses(sources) -> list[str]:
    """``x._name`` where no module of the same package defines ``_name``: a private attribute of another
    package (ours or a library's) used as if it were public."""
    defined: dict[str, set[str]] = {}
    for _, tree, module in sources:
        if module is not None:
            defined.setdefault(_package(module), set()).update(_private_names(tree))
    bad = []
    for where, tree, module in sources:
        own = defined.get(_package(module), set()) if module is not None else _private_names(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
                if node.attr not in own and node.attr not in PUBLIC_UNDERSCORE:
                    bad.append(f"{where}:{node.lineno}: .{node.attr}")
    return bad


def test_no_private_attribute_crosses_a_package():
    offenders = private_attribute_uses(SOURCES)
    assert not offenders, "private attributes used outside the package that defines them:\n" + "\n".join(offenders)


@pytest.mark.parametrize(
    ("sources", "flagged"),
    [
        (
            [
                ("a.py", "class A:\n    def __init__(self):\n        self._x = 1", "hybridtrack.sdk.a"),
                ("b.py", "def f(a): return a._x", "hybridtrack.engine.b"),
            ],
            True,
        ),
        (
            [
                ("a.py", "class A:\n    def __init__(self):\n        self._x = 1", "hybridtrack.sdk.a"),
                ("b.py", "def f(a): return a._x", "hybridtrack.sdk.b"),
            ],
            False,
        ),
        ([("b.py", "import rerun\nrerun.components._ARROW", "hybridtrack.recording.b")], True),
        ([("b.py", "import os\nos._exit(0)", "hybridtrack.apps.b")], False),
    ],
)
def test_the_private_attribute_rule_itself(sources, flagged):
    parsed = [(where, ast.parse(text), module) for where, text, module in sources]
    assert bool(private_attribute_uses(parsed)) is flagged
