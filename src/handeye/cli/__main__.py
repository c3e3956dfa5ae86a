"""``python -m handeye.cli``: the ``handeye`` command."""

import sys

from . import main

if __name__ == "__main__":  # not when a spawned process (handeye live's calibrations) imports the main module again
    sys.exit(main())
