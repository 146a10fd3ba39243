"""``python -m scdk_sym``: the command line (:mod:`scdk_sym.cli`)."""

import sys

from .cli import main

if __name__ == "__main__":  # not when imported by a spawned worker process (scdk atlas)
    sys.exit(main())
