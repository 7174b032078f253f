"""Built-in sensors plugins (every module's ``COMPONENTS`` is registered by ``register_sensors``)."""

from hybridtrack import hookimpl
from hybridtrack_plugins._collect import components


@hookimpl
def register_sensors(registry):
    for name, factory in components(__name__, __path__).items():
        registry.add(name, factory)
