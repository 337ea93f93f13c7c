"""``python -m krl.cli``: the ``krl`` command."""

import sys

from krl.cli import main

sys.exit(main())
