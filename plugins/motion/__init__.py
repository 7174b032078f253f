"""Built-in motion plugins (every module's ``COMPONENTS`` is registered by ``register_motion_models``)."""

from hybridtrack import hookimpl
from hybridtrack_plugins._collect import components


@hookimpl
def register_motion_models(registry):
    for name, factory in components(__name__, __path__).items():
        registry.add(name, factory)
