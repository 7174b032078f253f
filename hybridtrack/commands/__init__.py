"""Sub-commands of the ``hybridtrack`` command line, one module each (see :mod:`hybridtrack.cli`)."""
