"""The exceptions piezohyst raises on purpose.

Every one derives from :class:`PiezohystError` and also from the builtin a caller would
catch without knowing piezohyst (``ValueError``, ``TypeError``, ``RuntimeError``,
``FileExistsError``), so ``except ValueError`` keeps working and ``except
piezohyst.PiezohystError`` catches exactly what piezohyst itself rejected. Every message
names the argument (or file and line) and the offending value.

============================  ===================  =========================================
class                         builtin              C status (``crates/capi``)
============================  ===================  =========================================
:class:`ParameterError`       ``ValueError``       ``PHS_ERR_INVALID_PARAMETER``,
                                                   ``PHS_ERR_NOT_FINITE``,
                                                   ``PHS_ERR_NOT_INCREASING``,
                                                   ``PHS_ERR_BAD_LENGTH``,
                                                   ``PHS_ERR_UNKNOWN_KIND``
:class:`NotInvertibleError`   ``ValueError``       ``PHS_ERR_NOT_INVERTIBLE``
:class:`UnreachableError`     ``ValueError``       ``PHS_ERR_UNREACHABLE``
:class:`ParameterTypeError`   ``TypeError``        (C is typed; ``PHS_ERR_NULL_POINTER``)
:class:`DataError`            ``ValueError``       (files are read in Python only)
:class:`ComputationError`     ``RuntimeError``     ``PHS_ERR_NOT_FINITE`` on a result
:class:`OutputExistsError`    ``FileExistsError``  (no files in C)
:class:`ResourceLimitError`   ``MemoryError``      (C never allocates)
:class:`InternalError`        ``RuntimeError``     ``PHS_ERR_INTERNAL``
============================  ===================  =========================================

The command line prints ``piezohyst <command>: error: <message>`` on one line and exits
with status 2 for any of these (``--debug`` shows the traceback); Ctrl-C exits with 130.

Examples
--------
>>> import piezohyst as ph
>>> try:
...     ph.PI([0.0, 0.0], [1.0, 0.5])
... except ph.PiezohystError as e:
...     print(type(e).__name__, isinstance(e, ValueError))
ParameterError True
"""

from __future__ import annotations

__all__ = [
    "ComputationError",
    "DataError",
    "InternalError",
    "NotInvertibleError",
    "OutputExistsError",
    "ParameterError",
    "ParameterTypeError",
    "PiezohystError",
    "ResourceLimitError",
    "UnreachableError",
]


class PiezohystError(Exception):
    """Base class of every error piezohyst raises on purpose. Errors the Rust core raises
    also say what they are about: ``parameter`` (its name), ``index`` (the element, for an
    array) and ``value`` (the offending value); each is ``None`` where it does not apply."""

    parameter: str | None = None
    index: int | None = None
    value: float | None = None


class ParameterError(PiezohystError, ValueError):
    """An argument has a value outside its domain (non-finite, wrong sign, unordered,
    wrong length, unknown option). The message names the argument and the value."""


class NotInvertibleError(ParameterError):
    """The model's parameters make it non-invertible (e.g. a negative partial weight sum),
    so no inverse compensator exists."""


class UnreachableError(PiezohystError, ValueError):
    """A desired output lies beyond what the model can produce from its current state."""


class ParameterTypeError(PiezohystError, TypeError):
    """An argument has the wrong type (a string where a number belongs, a 2-D array where
    a record belongs)."""


class DataError(PiezohystError, ValueError):
    """A file or record cannot be read as what it claims to be (unknown format, missing
    column, malformed model JSON, non-numeric cell). The message names the file and, where
    it applies, the line, column or key."""


class ComputationError(PiezohystError, RuntimeError):
    """A computation could not produce a valid result from valid arguments (a simulation
    diverged, tuning found no stable candidate), or a stepping object was driven out of
    order (``tell`` without ``ask``)."""


class OutputExistsError(PiezohystError, FileExistsError):
    """An output file exists and overwriting was not asked for (``--force`` /
    ``overwrite=True``)."""


class ResourceLimitError(PiezohystError, MemoryError):
    """A request would allocate more than the limit (2 GiB by default) before any work
    starts: the message names the size and the limit. Raise the limit with the
    environment variable ``PIEZOHYST_MAX_ALLOC_BYTES`` (bytes) when the machine has the
    memory."""


class InternalError(ComputationError):
    """A bug in piezohyst caught at the Rust boundary (a panic): every argument and state is
    validated first, so this should not happen; please report it with the message."""
