"""Built-in plugins of hybridtrack, installed as ``hybridtrack_plugins``.

One sub-package per family; each public module with a hook is an entry point
of the ``hybridtrack`` group in ``pyproject.toml`` (named ``family.module``),
loaded like any third-party plugin.
"""
