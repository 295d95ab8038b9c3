"""The ``piezohyst`` command line (``piezohyst = "piezohyst.cli:main"``): :func:`main` in
:mod:`piezohyst.cli.main`, one module per command beside it."""

from .main import main

__all__ = ["main"]
