"""Shared helper of the built-in families: gather ``COMPONENTS`` from a family's modules.

Convention: every module of a family folder defines ``COMPONENTS``, a dict
mapping a registry name to a factory (usually the class).  The family's
``__init__`` registers them all through its hook, so adding a module needs no
other edit.
"""

import importlib
import pkgutil


def components(package_name: str, package_path) -> dict:
    found: dict = {}
    for module_info in sorted(pkgutil.iter_modules(package_path), key=lambda m: m.name):
        if module_info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{package_name}.{module_info.name}")
        for name, factory in getattr(module, "COMPONENTS", {}).items():
            if name in found:
                raise ValueError(f"{package_name}: component {name!r} defined twice")
            found[name] = factory
    return found
