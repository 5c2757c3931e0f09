"""``python -m skyfuse.services.cli.main``: the ``skyfuse`` command."""

import sys

from skyfuse.services.cli.main import main

sys.exit(main())
