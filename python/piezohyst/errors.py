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
with status 2 for any of these (``--debug`` shows the traceback); Ctrl-C, SIGTERM and SIGHUP
exit with 130, 143 and 129 (``128 + signal``), keeping the best result so far where there is one.

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
    array) and ``value`` (the offending value); each is ``None`` where it does not apply.

    Examples
    --------
    >>> import piezohyst as ph
    >>> try:
    ...     ph.PI([0.1, 0.3], [0.5, -2.0], p0=1.0).analytic_inverse()
    ... except ph.PiezohystError as e:
    ...     print(type(e).__name__, e.parameter, e.index, e.value)
    NotInvertibleError weights 2 -0.5
    """

    parameter: str | None = None
    index: int | None = None
    value: float | None = None


class ParameterError(PiezohystError, ValueError):
    """An argument has a value outside its domain (non-finite, wrong sign, unordered,
    wrong length, unknown option). The message names the argument and the value.

    Examples
    --------
    >>> from piezohyst import PI
    >>> PI([0.1], [float("nan")])
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: weights[0] = nan is not finite
    """


class NotInvertibleError(ParameterError):
    """The model's parameters make it non-invertible (e.g. a negative partial weight sum),
    so no inverse compensator exists.

    Examples
    --------
    >>> from piezohyst import PI
    >>> from piezohyst.errors import NotInvertibleError
    >>> pi = PI([0.1, 0.3], [0.5, -2.0], p0=1.0)       # the forward model works ...
    >>> try:
    ...     pi.analytic_inverse()                        # ... its inverse does not exist
    ... except NotInvertibleError as e:
    ...     print(str(e).split(":")[0], "|", e.parameter, e.index, e.value)
    weights are not invertible | weights 2 -0.5
    """


class UnreachableError(PiezohystError, ValueError):
    """A desired output lies beyond what the model can produce from its current state.

    Examples
    --------
    >>> from piezohyst import Preisach
    >>> Preisach(2, (0.0, 1.0), [1.0, 1.0, 1.0]).inverse().simulate([0.0, 100.0])
    Traceback (most recent call last):
    ...
    piezohyst.errors.UnreachableError: desired output 100 at sample 1 is outside the range the model can produce
    """


class ParameterTypeError(PiezohystError, TypeError):
    """An argument has the wrong type (a string where a number belongs, a 2-D array where
    a record belongs).

    Examples
    --------
    >>> from piezohyst import PI
    >>> PI("0.1", [1.0])
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterTypeError: thresholds must be a 1-D array of numbers, got str
    """


class DataError(PiezohystError, ValueError):
    """A file or record cannot be read as what it claims to be (unknown format, missing
    column, malformed model JSON, non-numeric cell). The message names the file and, where
    it applies, the line, column or key.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst import load_model
    >>> from piezohyst.errors import DataError
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "not_a_model.json"
    >>> _ = path.write_text("{}")
    >>> try:
    ...     load_model(path)
    ... except DataError as e:
    ...     print(str(e).split(": ", 1)[1])
    schema_version = null is not supported (this version reads the integer 1)
    """


class ComputationError(PiezohystError, RuntimeError):
    """A computation could not produce a valid result from valid arguments (a simulation
    diverged, tuning found no stable candidate), or a stepping object was driven out of
    order (``tell`` without ``ask``).

    Examples
    --------
    >>> from piezohyst.optimize import PSO
    >>> PSO([(0.0, 1.0)], rng=0).tell([1.0])
    Traceback (most recent call last):
    ...
    piezohyst.errors.ComputationError: pso: tell() without a pending ask()
    """


class OutputExistsError(PiezohystError, FileExistsError):
    """An output file exists and overwriting was not asked for (``--force`` /
    ``overwrite=True``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst import PI
    >>> from piezohyst.errors import OutputExistsError
    >>> path = PI([0.5], [1.0]).save(pathlib.Path(tempfile.mkdtemp()) / "pi.json")
    >>> try:
    ...     PI([0.5], [2.0]).save(path)
    ... except OutputExistsError as e:
    ...     print(isinstance(e, FileExistsError), "overwrite=True" in str(e))
    True True
    """


class ResourceLimitError(PiezohystError, MemoryError):
    """A request would allocate more than the limit (2 GiB by default) before any work
    starts: the message names the size and the limit. Raise the limit with the
    environment variable ``PIEZOHYST_MAX_ALLOC_BYTES`` (bytes) when the machine has the
    memory.

    Examples
    --------
    >>> import os
    >>> import numpy as np
    >>> from piezohyst import PI
    >>> from piezohyst.errors import ResourceLimitError
    >>> saved = os.environ.get("PIEZOHYST_MAX_ALLOC_BYTES")
    >>> os.environ["PIEZOHYST_MAX_ALLOC_BYTES"] = "1000"      # 1000 bytes, for the example
    >>> try:
    ...     PI([0.5], [1.0]).simulate(np.zeros(1000))
    ... except ResourceLimitError as e:
    ...     print(isinstance(e, MemoryError), str(e).split(",")[0])
    ... finally:
    ...     _ = os.environ.pop("PIEZOHYST_MAX_ALLOC_BYTES")
    ...     if saved is not None:
    ...         os.environ["PIEZOHYST_MAX_ALLOC_BYTES"] = saved
    True simulate: the output needs 7.8 KiB (1000 float64 values)
    """


class InternalError(ComputationError):
    """A bug in piezohyst caught at the Rust boundary (a panic): every argument and state is
    validated first, so this should not happen; please report it with the message.

    Examples
    --------
    >>> from piezohyst.errors import ComputationError, InternalError, PiezohystError
    >>> issubclass(InternalError, ComputationError), issubclass(InternalError, PiezohystError)
    (True, True)
    """
