"""Built-in filters plugins (every module's ``COMPONENTS`` is registered by ``register_estimators``)."""

from hybridtrack import hookimpl
from hybridtrack_plugins._collect import components


@hookimpl
def register_estimators(registry):
    for name, factory in components(__name__, __path__).items():
        registry.add(name, factory)
