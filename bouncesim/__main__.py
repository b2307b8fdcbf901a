"""``python -m bouncesim``: the ``bouncesim`` command line (the same as the installed script)."""

import sys

from bouncesim.cli import main

sys.exit(main())
