"""``python -m jaxclear``: the command line (see :mod:`jaxclear.cli`)."""

import sys

from .cli import main

sys.exit(main())
