"""``python -m handeye.cli``: the ``handeye`` command."""

import sys

from . import main

sys.exit(main())
