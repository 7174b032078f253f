"""Packaging: plugins/ folders vs declared packages and entry points, and what a wheel really contains.

An editable install imports any sub-package of ``plugins/`` whether or not it
is declared, so a family missing from ``[tool.setuptools] packages`` or a
plugin module missing from the ``hybridtrack`` entry points only shows up in a
real wheel (silently absent) or after a re-install (silently unloaded).  These
tests catch both, and a component class that no hook registers.
"""

import importlib
import importlib.metadata
import inspect
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
PACKAGES = set(PYPROJECT["tool"]["setuptools"]["packages"])
PACKAGE_DIR = PYPROJECT["tool"]["setuptools"]["package-dir"]
ENTRY_POINTS = PYPROJECT["project"]["entry-points"]
PLUGINS = ROOT / "plugins"


def _package_dirs(top: str) -> dict[str, Path]:
    """Import name → folder for every folder with an ``__init__.py`` under the source of ``top``."""
    source = ROOT / PACKAGE_DIR.get(top, top)
    found = {}
    for init in sorted(source.rglob("__init__.py")):
        relative = init.parent.relative_to(source)
        if "__pycache__" in relative.parts:
            continue
        found[".".join((top,) + relative.parts)] = init.parent
    return found


def _source_of(module: str) -> Path:
    """Where ``module`` lives in the source tree, following ``package-dir``."""
    top, *rest = module.split(".")
    base = ROOT / PACKAGE_DIR.get(top, top)
    path = base.joinpath(*rest)
    return path / "__init__.py" if path.is_dir() else path.with_suffix(".py")


def _plugin_modules() -> dict[str, object]:
    """Import name → module for every public module in a family folder of ``plugins/``."""
    found = {}
    for path in sorted(PLUGINS.glob("*/*.py")):
        if path.name.startswith("_") or not (path.parent / "__init__.py").exists():
            continue
        name = f"hybridtrack_plugins.{path.parent.name}.{path.stem}"
        found[name] = importlib.import_module(name)
    return found


def _hooks(module) -> list[str]:
    return [name for name, value in vars(module).items() if name.startswith("register_") and hasattr(value, "hybridtrack_impl")]


def test_every_plugin_family_folder_is_a_declared_package():
    families = [d.name for d in sorted(PLUGINS.iterdir()) if (d / "__init__.py").exists()]
    assert families, "no plugin family found under plugins/"
    for family in families:
        assert f"hybridtrack_plugins.{family}" in PACKAGES, f"plugins/{family}/ missing from [tool.setuptools] packages"


def test_every_plugin_module_with_a_hook_is_an_entry_point_named_family_dot_module():
    declared = ENTRY_POINTS["hybridtrack"]
    modules = {name: module for name, module in _plugin_modules().items() if _hooks(module)}
    assert len(modules) > 20, sorted(modules)
    for name in modules:
        family, module = name.split(".")[1:]
        assert declared.get(f"{family}.{module}") == name, (
            f"{name} has hooks {_hooks(modules[name])} but no entry point {family}.{module} = {name!r} in [project.entry-points.hybridtrack]"
        )
    assert declared["algorithms"] == "hybridtrack.algorithms.registration"
    for entry, target in declared.items():
        assert _hooks(importlib.import_module(target)), f"entry point {entry} = {target!r}: the module has no register_ hook"


def test_every_component_class_of_a_plugin_module_is_registered():
    """A public, concrete class implementing a kind's interface and defined in a plugin module is some entry's factory:
    a module (or a class) nobody registers fails here."""
    from hybridtrack.core.kinds import KINDS
    from hybridtrack.core.plugins import load_plugins

    factories = {entry.factory for entry in load_plugins(disabled=()).registry.entries()}
    unregistered = [
        f"{module.__name__}.{name}"
        for module in _plugin_modules().values()
        for name, value in vars(module).items()
        if isinstance(value, type)
        and value.__module__ == module.__name__
        and not name.startswith("_")
        and not inspect.isabstract(value)
        and any(issubclass(value, kind.interface) for kind in KINDS.values())
        and value not in factories
    ]
    assert not unregistered, f"component classes no hook registers: {unregistered}"


@pytest.mark.parametrize("top", ["hybridtrack", "hybridtrack_plugins"])
def test_every_subpackage_is_declared(top):
    missing = sorted(set(_package_dirs(top)) - PACKAGES)
    assert not missing, f"packages missing from [tool.setuptools] packages: {missing}"


def test_declared_packages_exist():
    absent = [p for p in sorted(PACKAGES) if not _source_of(p).exists()]
    assert not absent, f"declared packages without a folder: {absent}"


@pytest.mark.parametrize("group", ["hybridtrack", "pytest11"])
def test_entry_point_modules_exist_and_import(group):
    assert ENTRY_POINTS.get(group), f"no [project.entry-points.{group}] table"
    for name, target in ENTRY_POINTS[group].items():
        module = target.split(":")[0]
        assert _source_of(module).exists(), f"entry point {group}/{name}: no source for {module} ({_source_of(module)})"
        importlib.import_module(module)


def test_the_pytest_plugin_and_console_script_are_declared():
    assert ENTRY_POINTS["pytest11"] == {"hybridtrack": "hybridtrack.testing.pytest_plugin"}
    module, function = PYPROJECT["project"]["scripts"]["hybridtrack"].split(":")
    assert callable(getattr(importlib.import_module(module), function))


def test_the_installed_metadata_matches_pyproject():
    """Entry points are read at install time: a new one needs ``pip install -e .`` again."""
    installed = importlib.metadata.distribution("hybridtrack").entry_points
    for group in ("hybridtrack", "pytest11"):
        have = {p.name: p.value for p in installed if p.group == group}
        assert have == ENTRY_POINTS[group], f"installed {group} entry points {have} differ from pyproject.toml: re-run `pip install -e .`"


def _unmet_build_requirements() -> list[str]:
    from packaging.requirements import Requirement

    unmet = []
    for text in PYPROJECT["build-system"]["requires"]:
        requirement = Requirement(text)
        try:
            version = importlib.metadata.version(requirement.name)
        except importlib.metadata.PackageNotFoundError:
            unmet.append(f"{text} (not installed)")
            continue
        if not requirement.specifier.contains(version, prereleases=True):
            unmet.append(f"{text} (have {version})")
    return unmet


def test_the_wheel_contains_every_module(tmp_path):
    unmet = _unmet_build_requirements()
    if unmet:
        pytest.skip(
            "building without isolation needs the build requirements in this environment; unmet: "
            + ", ".join(unmet)
            + f" (install them with `{sys.executable} -m pip install "
            + " ".join(f"'{r.split(' (')[0]}'" for r in unmet)
            + "`)"
        )
    result = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", str(ROOT), "-w", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    (wheel,) = tmp_path.glob("hybridtrack-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {f"hybridtrack_plugins/{p.relative_to(PLUGINS).as_posix()}" for p in PLUGINS.rglob("*.py") if "__pycache__" not in p.parts}
    expected |= {p.relative_to(ROOT).as_posix() for p in (ROOT / "hybridtrack").rglob("*.py") if "__pycache__" not in p.parts}
    missing = sorted(expected - names)
    assert not missing, f"files missing from the wheel: {missing}"
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    text = zipfile.ZipFile(wheel).read(entry_points).decode()
    assert "[hybridtrack]" in text and "[pytest11]" in text
