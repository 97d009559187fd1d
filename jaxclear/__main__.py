"""``python -m jaxclear``: the command line (see :mod:`jaxclear.cli`)."""

from .cli import run

run()
