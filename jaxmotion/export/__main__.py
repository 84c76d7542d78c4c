"""``python -m jaxmotion.export``: see ``jaxmotion/export/cli.py``."""

import sys

from jaxmotion.export.cli import main

sys.exit(main())
