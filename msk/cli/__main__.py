"""``python -m msk.cli``: the ``msk`` command."""

import sys

from msk.cli import main

sys.exit(main())
