"""The one protocol of every result class, and what the classes share to satisfy it.

A result — of a simulation (:class:`~piezohyst.signals.Response`, ``StageResponse``,
``ClosedLoopResult``), of a fit, an identification, a tuning or an optimization (the
:class:`~piezohyst.optimize.RunReport` family: ``FitResult``, ``IdentificationResult``,
``ValidatedResult``, ``TuningResult``, ``OptimizeResult``) or an optimizer's callback
(``IntermediateResult``) — has:

- ``to_pandas()``: its data as a ``pandas.DataFrame`` (pandas is optional: without it an
  ``ImportError`` says ``pip install pandas``);
- ``plot(...)``: a matplotlib figure of it;
- ``_repr_html_()``: a small HTML table, every text escaped (the notebook display);
- ``to_mat(path)``: a MATLAB ``.mat`` file (:mod:`piezohyst.signals.matfile`), and the class
  method ``from_mat(path)`` reading it back exactly.

:class:`Result` states it; ``tests/test_results_protocol.py`` finds every public class named
``...Result``, ``...Response`` or ``...Report`` in the package and fails on one that does not
follow it. :class:`MatFile` is the one ``to_mat``/``from_mat`` of them all (the struct
``result`` naming its class); :class:`DataclassMatFile` fills it for a frozen dataclass: each
field stored by value, piezohyst objects inside (models, stage parameters, controllers) by
their class and their own description.

Examples
--------
>>> from piezohyst.signals.results import Result, html_table
>>> from piezohyst.signals import Response
>>> isinstance(Response([0.0, 1.0], {"x": [1.0, 2.0]}), Result)
True
>>> html_table("a <b>", [("rmse", "1 < 2")])
'<div><p>a &lt;b&gt;</p><table><tr><th>rmse</th><td>1 &lt; 2</td></tr></table></div>'
"""

from __future__ import annotations

import dataclasses
import html
import importlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any, ClassVar, Protocol, Self, runtime_checkable

import numpy as np

from .._io import PathLike
from ..errors import DataError, ParameterTypeError
from .matfile import read_mat, write_mat

__all__ = [
    "PANDAS_HINT",
    "DataclassMatFile",
    "MatFile",
    "Result",
    "decode_object",
    "encode_object",
    "html_table",
    "require_pandas",
]

#: What to do when pandas is missing (it is optional).
PANDAS_HINT = "pip install pandas"

#: The field of a struct that names the Python class of the object it holds.
CLASS_FIELD = "python_class"


@runtime_checkable
class Result(Protocol):
    """What every result class of piezohyst provides (see the module docstring).

    A protocol: checked with ``isinstance``, never instantiated.

    Parameters
    ----------
    *args, **kwargs : object
        None are taken (a protocol cannot be instantiated).

    Examples
    --------
    >>> from piezohyst.signals import Response
    >>> from piezohyst.signals.results import Result
    >>> isinstance(Response([0.0, 1.0], {"x": [1.0, 2.0]}), Result), isinstance(1.0, Result)
    (True, False)
    """

    to_pandas: Callable[[], Any]
    plot: Callable[..., Any]
    _repr_html_: Callable[[], str]
    to_mat: Callable[..., Path]
    from_mat: Callable[..., Any]


def require_pandas(owner: str) -> ModuleType:
    """The ``pandas`` module, or ``ImportError`` naming ``owner.to_pandas()`` and saying how to
    install it.

    Parameters
    ----------
    owner : str
        The class whose ``to_pandas()`` needs pandas, named in the error.

    Returns
    -------
    module
        The imported ``pandas`` package.

    Examples
    --------
    >>> from piezohyst.signals.results import require_pandas
    >>> require_pandas("Response").__name__  # doctest: +SKIP
    'pandas'
    """
    try:
        import pandas
    except ImportError:
        raise ImportError(f"{owner}.to_pandas() needs pandas, which is not installed: {PANDAS_HINT}") from None
    module: ModuleType = pandas
    return module


def html_table(title: str, rows: Sequence[Sequence[str]], header: Sequence[str] | None = None) -> str:
    """A small HTML table: ``title`` above, one ``<tr>`` per ``(name, value)`` row (or, with
    ``header``, one cell per column of each row); every text escaped.

    Parameters
    ----------
    title : str
        The text above the table.
    rows : sequence of sequence of str
        ``(name, value)`` pairs, or with ``header`` one cell per column.
    header : sequence of str, optional
        Column titles; without it each row is a name and a value.

    Returns
    -------
    str
        The HTML fragment.

    Examples
    --------
    >>> from piezohyst.signals.results import html_table
    >>> html_table("fit", [("rmse", "1 < 2")])
    '<div><p>fit</p><table><tr><th>rmse</th><td>1 &lt; 2</td></tr></table></div>'
    >>> html_table("t", [("1", "2")], header=("a", "b")).count("<td>")
    2
    """
    esc = html.escape
    head = ""
    if header is not None:
        head = "<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr></thead>"
        body = "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>" for row in rows)
        return f"<div><p>{esc(title)}</p><table>{head}<tbody>{body}</tbody></table></div>"
    body = "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in rows)
    return f"<div><p>{esc(title)}</p><table>{body}</table></div>"


# -- piezohyst objects inside a result -----------------------------------------------------
def _class_path(obj: object) -> str:
    cls = type(obj)
    return f"{cls.__module__}.{cls.__qualname__}"


def encode_object(value: object) -> Any:
    """``value`` as plain data for a ``.mat`` file: numbers, strings, arrays, lists and dicts as
    they are; a piezohyst object with ``to_dict()`` and a class method ``from_dict`` (a model,
    a stage) or a dataclass (stage parameters, a controller) as a struct naming its class
    (``python_class``) with its description; anything else raises ``ParameterTypeError``.

    Parameters
    ----------
    value : object
        The value to store.

    Returns
    -------
    object
        Plain data (numbers, strings, arrays, lists, tuples, dicts).

    Examples
    --------
    >>> from piezohyst.models.model import Drift
    >>> from piezohyst.signals.results import decode_object, encode_object
    >>> encode_object({"n": 3, "drift": Drift(slope=0.5)})["drift"]["python_class"]
    'piezohyst.models.model.Drift'
    >>> decode_object(encode_object([Drift(slope=0.5)]))[0] == Drift(slope=0.5)
    True
    """
    if value is None or isinstance(value, (bool, int, float, str, np.generic, np.ndarray)):
        return value
    if isinstance(value, Mapping):
        return {k: encode_object(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        items = [encode_object(v) for v in value]
        return tuple(items) if isinstance(value, tuple) else items
    cls = type(value)
    if not cls.__module__.startswith("piezohyst."):
        raise ParameterTypeError(f"a {cls.__name__} cannot be stored in a .mat file")
    to_dict = getattr(value, "to_dict", None)
    if callable(to_dict) and callable(getattr(cls, "from_dict", None)):
        return {CLASS_FIELD: _class_path(value), "description": encode_object(to_dict())}
    if dataclasses.is_dataclass(value):
        fields = {f.name: encode_object(getattr(value, f.name)) for f in dataclasses.fields(value) if f.init}
        return {CLASS_FIELD: _class_path(value), "fields": fields}
    raise ParameterTypeError(
        f"a {cls.__name__} cannot be stored in a .mat file (no to_dict/from_dict, not a dataclass)"
    )


def _resolve(path: object) -> type:
    if not isinstance(path, str) or not path.startswith("piezohyst."):
        raise DataError(f"{CLASS_FIELD} = {path!r} is not a class of piezohyst")
    module_name, _, name = path.rpartition(".")
    try:
        cls = getattr(importlib.import_module(module_name), name)
    except (ImportError, AttributeError):
        raise DataError(f"{CLASS_FIELD} = {path!r} names no class of this version of piezohyst") from None
    if not isinstance(cls, type):
        raise DataError(f"{CLASS_FIELD} = {path!r} is not a class")
    return cls


def decode_object(value: object) -> Any:
    """The inverse of :func:`encode_object`: structs naming a ``python_class`` become that
    object again (only classes of piezohyst are built).

    Parameters
    ----------
    value : object
        Plain data as :func:`encode_object` returns it (or as read back from a ``.mat`` file).

    Returns
    -------
    object
        The value with every struct naming a ``python_class`` built again.

    Examples
    --------
    >>> from piezohyst.models.model import Drift
    >>> from piezohyst.signals.results import decode_object, encode_object
    >>> decode_object(encode_object({"d": Drift(slope=0.1)}))["d"].slope
    0.1
    """
    if isinstance(value, dict):
        if CLASS_FIELD in value:
            cls = _resolve(value[CLASS_FIELD])
            if "description" in value:
                build: Callable[[Any], Any] = cls.from_dict  # type: ignore[attr-defined]
                return build(decode_object(value["description"]))
            if not dataclasses.is_dataclass(cls):
                raise DataError(f"{CLASS_FIELD} = {value[CLASS_FIELD]!r} is not a dataclass")
            fields = value.get("fields", {})
            return cls(**{k: decode_object(v) for k, v in fields.items()})
        return {k: decode_object(v) for k, v in value.items()}
    if isinstance(value, list):
        return [decode_object(v) for v in value]
    if isinstance(value, tuple):
        return tuple(decode_object(v) for v in value)
    return value


def _is_function(value: object) -> bool:
    """A function-like field (``simulator``): callable, and not an object :func:`encode_object`
    stores (a class, a dataclass, an object with ``to_dict``)."""
    return (
        callable(value)
        and not isinstance(value, type)
        and not dataclasses.is_dataclass(value)
        and not hasattr(value, "to_dict")
    )


class MatFile:
    """``to_mat``/``from_mat`` of a result: the one home of the results' ``.mat`` layout. The
    struct ``result`` names the result's class (``python_class``) beside what the class writes
    (``_mat_value``: a response's time base and signals, a dataclass result's fields);
    ``from_mat`` resolves that class (only classes of piezohyst are built) and has it build
    itself again from the struct (``_from_mat_value``).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from piezohyst.signals import Response
    >>> from piezohyst.signals.results import MatFile
    >>> r = Response([0.0, 1.0], {"x": [1.0, 2.0]})
    >>> isinstance(r, MatFile)
    True
    >>> MatFile.from_mat(r.to_mat(pathlib.Path(tempfile.mkdtemp()) / "r.mat")).x.tolist()
    [1.0, 2.0]
    """

    def _mat_value(self) -> dict[str, Any]:
        """The fields of the struct ``result`` besides ``python_class``."""
        raise NotImplementedError

    @classmethod
    def _from_mat_value(cls, d: dict[str, Any], path: Path) -> Self:
        """The result the struct ``d`` (read from ``path``) describes; ``DataError`` when it
        does not make one."""
        raise NotImplementedError

    def to_mat(self, path: PathLike, *, overwrite: bool = True) -> Path:
        """Write this result to the MATLAB file ``path`` (see :mod:`piezohyst.signals.matfile`):
        the struct ``result`` with ``python_class`` (the result's class) and what the class
        stores: a response (:class:`~piezohyst.signals.Response` and its subclasses) its
        ``time``, ``signals``, ``inputs``, ``units``, ``final_state``, ``title`` and ``extra``;
        a dataclass result (:class:`DataclassMatFile`) the struct ``fields``, one field per
        attribute (metrics as structs, histories as arrays, a model as its class and its
        description). :meth:`from_mat` reads it back exactly.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (``.mat``), atomically.
        overwrite : bool
            Replace an existing file (default ``True``).

        Returns
        -------
        pathlib.Path
            The file written.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> import numpy as np
        >>> from piezohyst.optimize import minimize
        >>> res = minimize(lambda X: np.sum(X**2, axis=1), [(-1.0, 1.0)] * 2, max_iterations=3, rng=0)
        >>> path = res.to_mat(pathlib.Path(tempfile.mkdtemp()) / "opt.mat")
        >>> type(res).from_mat(path).fun == res.fun
        True
        """
        value = {CLASS_FIELD: _class_path(self), **self._mat_value()}
        return write_mat(path, "result", value, overwrite=overwrite)

    @classmethod
    def from_mat(cls, path: PathLike) -> Self:
        """Read a result :meth:`to_mat` wrote, exactly, as the class written (``DataError``
        when the file holds another class, or a malformed result). Function fields (an
        identification's ``simulator``) take their default.

        Parameters
        ----------
        path : str or os.PathLike
            The ``.mat`` file.

        Returns
        -------
        object
            The result, of the class written (a subclass of ``cls``).

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from piezohyst.signals import Response
        >>> path = Response([0.0, 1.0], {"x": [1.0, 2.0]}).to_mat(pathlib.Path(tempfile.mkdtemp()) / "r.mat")
        >>> Response.from_mat(path).x.tolist()
        [1.0, 2.0]
        """
        d = read_mat(path, "result")
        p = Path(path)
        found = _resolve(d.get(CLASS_FIELD))
        if not issubclass(found, cls):
            raise DataError(f"{p} holds a {found.__name__}, not a {cls.__name__}")
        out = found._from_mat_value(d, p)
        assert isinstance(out, cls)
        return out


class DataclassMatFile(MatFile):
    """``to_mat``/``from_mat`` for a result that is a frozen dataclass: a struct ``result`` with
    ``python_class`` (the result's class) and one field per dataclass field. Fields that hold
    functions (an identification's ``simulator``) are left out and take their default when
    read back; the others come back exactly (:func:`encode_object`).

    Examples
    --------
    >>> import dataclasses, pathlib, tempfile
    >>> from piezohyst.signals import FrequencyResponse
    >>> from piezohyst.signals.results import DataclassMatFile
    >>> issubclass(FrequencyResponse, DataclassMatFile), dataclasses.is_dataclass(FrequencyResponse)
    (True, True)
    """

    #: Fields not written (callables); they take their default on reading.
    _mat_skip: ClassVar[tuple[str, ...]] = ()

    def _mat_value(self) -> dict[str, Any]:
        me: Any = self
        if not dataclasses.is_dataclass(me):
            raise ParameterTypeError(f"{type(self).__name__} is not a dataclass")
        fields = {
            f.name: encode_object(getattr(self, f.name))
            for f in dataclasses.fields(me)
            if f.init and f.name not in self._mat_skip and not _is_function(getattr(self, f.name))
        }
        return {"fields": fields}

    @classmethod
    def _from_mat_value(cls, d: dict[str, Any], path: Path) -> Self:
        fields = d.get("fields", {})
        if not isinstance(fields, dict):
            raise DataError(f"{path}: result.fields is not a struct")
        try:
            return cls(**{k: decode_object(v) for k, v in fields.items()})
        except TypeError as e:
            raise DataError(f"{path}: the fields do not make a {cls.__name__}: {e}") from None
