"""``python -m hybridtrack`` runs the command line."""

import sys

from hybridtrack.cli import main

sys.exit(main())
