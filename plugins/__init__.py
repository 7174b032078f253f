"""Built-in plugins of hybridtrack, installed as ``hybridtrack_plugins``.

One sub-package per family; each is an entry point of the ``hybridtrack``
group in ``pyproject.toml``, loaded like any third-party plugin.
"""
