"""Every registered component of every kind, built from its example parameters, against its interface.

The parameter list is read from the default registry at collection time, so a
plugin added to ``plugins/`` (or installed from another distribution) is
covered without editing this file.  Conventions for components that need
arguments or a problem: docs/plugins.md (contract-check conventions).
"""

import pytest

from hybridtrack.core.plugins import get_registry
from hybridtrack.testing import build_example, check_component

ENTRIES = get_registry().entries()


def _id(entry) -> str:
    return f"{entry.kind}:{entry.name}"


def test_the_default_registry_is_not_empty():
    assert ENTRIES, "no component registered: are the built-in plugins installed (pip install -e .)?"


@pytest.mark.parametrize("entry", ENTRIES, ids=_id)
def test_component_honours_its_contract(entry):
    component = entry.factory if entry.kind == "algorithm" else build_example(entry.factory)  # an algorithm's check builds it
    result = check_component(entry.kind, component)
    if entry.kind == "solver" and result is None:
        pytest.skip(f"solver {entry.name!r} defines no example_problem(); only its name was checked")
