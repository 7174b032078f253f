"""Built-in detectors plugins (every module's ``COMPONENTS`` is registered by ``register_detectors``)."""

from hybridtrack import hookimpl
from hybridtrack_plugins._collect import components


@hookimpl
def register_detectors(registry):
    for name, factory in components(__name__, __path__).items():
        registry.add(name, factory)
