"""``python -m piezohyst.capi --cflags --libs``: see :func:`piezohyst.capi.main`."""

import sys

from . import main

if __name__ == "__main__":
    sys.exit(main())
