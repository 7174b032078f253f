"""pytest plugin (entry point ``pytest11``) exposing hybridtrack's contract checks (docs/plugins.md, section 7).

Fixtures ``hybridtrack_contracts`` (the module :mod:`hybridtrack.testing.contracts`) and ``hybridtrack_registry``
(the default registry); the marker ``hybridtrack_contract`` labels such tests.  hybridtrack is imported only when
a fixture is used, so the plugin costs nothing to projects that do not use it.
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
