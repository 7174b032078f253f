"""The contract: the five interfaces and the protocols the algorithms call, value types, the component kinds,
hookspecs, the registry and the plugin loader, validation.  Plugins import only :mod:`hybridtrack.core` and
:mod:`hybridtrack.sdk`."""
