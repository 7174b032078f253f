"""pytest plugin (entry point ``pytest11``) exposing hybridtrack's contract checks.

Fixtures, available in any project that has hybridtrack installed:

* ``hybridtrack_contracts`` — the module :mod:`hybridtrack.testing.contracts`
  (``check_motion_model``, ``check_sensor``, …, ``check_algorithm``,
  ``check_component``, ``build_example``);
* ``hybridtrack_registry`` — the default :class:`~hybridtrack.core.registry.Registry`
  (entry-point plugins, honouring ``HYBRIDTRACK_DISABLE_PLUGINS``).

The marker ``hybridtrack_contract`` labels such tests (``pytest -m hybridtrack_contract``);
example: docs/plugins.md, section 7.  hybridtrack is imported only when a fixture is used,
so the plugin costs nothing to projects that do not use it.
"""

import pytest


def pytest_configure(config):
    config.addinivalue_line("markers", "hybridtrack_contract: a contract check of a hybridtrack component")


@pytest.fixture
def hybridtrack_contracts():
    """The contract-check functions (module :mod:`hybridtrack.testing.contracts`)."""
    from hybridtrack.testing import contracts

    return contracts


@pytest.fixture
def hybridtrack_registry():
    """The default registry of components loaded from the installed plugins."""
    from hybridtrack.core.plugins import get_registry

    return get_registry()
