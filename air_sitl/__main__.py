"""``python -m air_sitl`` runs the CLI."""

import sys

from air_sitl.cli import main

sys.exit(main())
