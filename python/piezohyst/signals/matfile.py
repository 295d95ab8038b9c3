"""MATLAB ``.mat`` files that piezohyst writes and reads back exactly: records, models and
results (v5 format through :func:`scipy.io.savemat`, which MATLAB and Octave load).

Layout of every file
--------------------
Two variables:

``<content>``
    A struct named for what it holds — ``record``, ``model``, ``result`` — described in the
    docstring of the method that writes it (:meth:`piezohyst.signals.Record.to_mat`,
    :meth:`piezohyst.models.HysteresisModel.to_mat`, ``to_mat`` of the result classes). In
    MATLAB: ``s = load('fit.mat'); s.model.parameters.weights``.
``piezohyst``
    A struct: ``format`` (this layout's version, 1), ``content`` (the name above) and
    ``types`` (a char array: JSON mapping a field's path to its Python type where MATLAB's
    types do not tell it, so that Python reads back exactly what was written). MATLAB users
    can ignore it.

How Python values are stored
----------------------------
============================  ==================================================================
Python                        MATLAB
============================  ==================================================================
dict with str keys            struct (field names: a letter, then letters, digits, ``_``, at
                              most 63 characters); a dict with other keys is a struct of two
                              cell arrays ``keys`` and ``values``
float, int, bool              1x1 double, int64, logical
str                           char row
None                          ``[]`` (0x0 double)
list or tuple of numbers      1xN double row (int64 when all are ints); ``None`` items are NaN
other list or tuple           1xN cell
numpy array                   the array (1-D as a 1xN row), its dtype kept
============================  ==================================================================

Every float64 is stored as the IEEE double it is: a round trip is bitwise exact. A scalar
and a one-element vector look the same in MATLAB; ``piezohyst.types`` tells them apart.

Examples
--------
>>> import tempfile, pathlib
>>> import numpy as np
>>> from piezohyst.signals.matfile import read_mat, write_mat
>>> path = pathlib.Path(tempfile.mkdtemp()) / "demo.mat"
>>> value = {"gain": 2.5, "taus": [0.01], "name": "µm", "x": np.array([1.0, 2.0]), "none": None}
>>> _ = write_mat(path, "result", value)
>>> back = read_mat(path, "result")
>>> back["taus"], back["name"], back["none"], back["x"].tolist()
([0.01], 'µm', None, [1.0, 2.0])
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeAlias, TypeVar

import numpy as np
import numpy.typing as npt

from .._io import PathLike, write_atomic
from ..errors import DataError, ParameterError, ParameterTypeError, PiezohystError

_T = TypeVar("_T")

__all__ = ["MATLAB_NAME", "MAT_FORMAT", "is_matlab_name", "load_mat_file", "read_mat", "write_mat"]

#: Version of the file layout (``piezohyst.format``).
MAT_FORMAT = 1

#: A valid MATLAB variable or struct field name.
MATLAB_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,62}")

#: A MATLAB-ready value: what :func:`scipy.io.savemat` takes.
Encoded: TypeAlias = Any
#: ``{path: type}`` of the values whose Python type MATLAB does not tell.
Hints: TypeAlias = dict[str, Any]


def is_matlab_name(name: object) -> bool:
    """``True`` for a valid MATLAB field name: a letter, then letters, digits or ``_``, at most
    63 characters.

    Parameters
    ----------
    name : object
        The candidate name (anything that is not a ``str`` is not a name).

    Returns
    -------
    bool

    Examples
    --------
    >>> from piezohyst.signals.matfile import is_matlab_name
    >>> is_matlab_name("rmse_percent"), is_matlab_name("term_P"), is_matlab_name("1x"), is_matlab_name("a b")
    (True, True, False, False)
    """
    return isinstance(name, str) and MATLAB_NAME.fullmatch(name) is not None


# -- encoding ------------------------------------------------------------------------------
def _is_number(x: object) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _encode(value: object, path: str, hints: Hints) -> Encoded:
    if value is None:
        hints[path] = "none"
        return np.zeros((0, 0))
    if isinstance(value, (bool, np.bool_)):
        hints[path] = "bool"
        return np.array([[bool(value)]])
    if isinstance(value, (int, np.integer)):
        v = int(value)
        if not -(2**63) <= v < 2**63:
            raise ParameterError(f"{path or 'value'} = {v} does not fit a MATLAB int64")
        return np.array([[v]], dtype=np.int64)
    if isinstance(value, (float, np.floating)):
        if isinstance(value, np.floating) and value.dtype != np.float64:
            hints[path] = {"scalar": str(value.dtype)}
        return np.array([[value]], dtype=np.float64 if isinstance(value, float) else value.dtype)
    if isinstance(value, str):
        return value
    if isinstance(value, np.ndarray):
        return _encode_array(value, path, hints)
    if isinstance(value, Mapping):
        return _encode_mapping(value, path, hints)
    if isinstance(value, (list, tuple)):
        return _encode_sequence(value, path, hints)
    raise ParameterTypeError(
        f"{path or 'value'} is a {type(value).__name__}, which a .mat file of piezohyst does not hold "
        "(numbers, strings, None, lists, dicts and numpy arrays)"
    )


def _encode_array(a: npt.NDArray[Any], path: str, hints: Hints) -> Encoded:
    if a.dtype.kind not in "biufc":
        raise ParameterTypeError(f"{path or 'value'} is an array of dtype {a.dtype}; only numbers and booleans")
    hints[path] = {"array": a.dtype.str, "shape": list(a.shape)}
    if a.ndim < 2:
        return np.ascontiguousarray(a.reshape(1, -1))
    return np.ascontiguousarray(a)


def _encode_mapping(m: Mapping[Any, Any], path: str, hints: Hints) -> Encoded:
    keys = list(m)
    if keys and all(is_matlab_name(k) for k in keys):
        return {k: _encode(m[k], f"{path}/{k}", hints) for k in keys}
    if any(not isinstance(k, str) for k in keys):
        bad = next(k for k in keys if not isinstance(k, str))
        raise ParameterTypeError(f"{path or 'value'} has a key {bad!r} that is not a str")
    # keys MATLAB cannot name (or no key at all): two cells
    hints[path] = "map"
    cell_keys = np.empty((1, len(keys)), dtype=object)
    cell_values = np.empty((1, len(keys)), dtype=object)
    for i, k in enumerate(keys):
        cell_keys[0, i] = k
        cell_values[0, i] = _encode(m[k], f"{path}/values/{i}", hints)
    return {"keys": cell_keys, "values": cell_values}


def _encode_sequence(seq: list[Any] | tuple[Any, ...], path: str, hints: Hints) -> Encoded:
    kind = "tuple" if isinstance(seq, tuple) else "list"
    numbers = all(_is_number(x) or x is None for x in seq)
    has_none = any(x is None for x in seq)
    has_nan = any(isinstance(x, (float, np.floating)) and np.isnan(x) for x in seq)
    if numbers and not (has_none and has_nan):
        if seq and all(isinstance(x, (int, np.integer)) for x in seq):
            hints[path] = kind
            return np.array([[int(x) for x in seq]], dtype=np.int64)
        hints[path] = {kind: "none"} if has_none else kind
        return np.array([[np.nan if x is None else float(x) for x in seq]], dtype=np.float64).reshape(1, len(seq))
    hints[path] = kind
    cell = np.empty((1, len(seq)), dtype=object)
    for i, x in enumerate(seq):
        cell[0, i] = _encode(x, f"{path}/{i}", hints)
    return cell


def write_mat(path: PathLike, content: str, value: Mapping[str, Any], *, overwrite: bool = True) -> Path:
    """Write ``value`` (a dict) to the ``.mat`` file ``path`` as the struct variable ``content``
    (``"record"``, ``"model"``, ``"result"``) with the ``piezohyst`` variable beside it (the
    layout of this module's docstring), atomically. ``overwrite=False`` keeps an existing file
    (:class:`~piezohyst.errors.OutputExistsError`).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mat`` file to write.
    content : str
        Name of the struct variable: a MATLAB name other than ``"piezohyst"``.
    value : dict
        The content: numbers, strings, arrays, lists, tuples and nested dicts.
    overwrite : bool, default True
        ``False`` refuses to replace an existing file.

    Returns
    -------
    pathlib.Path
        The file written.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> from piezohyst.signals.matfile import read_mat, write_mat
    >>> value = {"gain": 0.1, "name": "pi", "x": np.array([1.0, 2.5]), "n": (1, 2)}
    >>> path = write_mat(pathlib.Path(tempfile.mkdtemp()) / "m.mat", "model", value)
    >>> back = read_mat(path, "model")
    >>> back["gain"], back["name"], back["x"].tolist(), back["n"]
    (0.1, 'pi', [1.0, 2.5], (1, 2))
    """
    from scipy.io import savemat

    if not is_matlab_name(content) or content == "piezohyst":
        raise ParameterError(f"content = {content!r} must be a MATLAB name other than 'piezohyst'")
    if not isinstance(value, Mapping):
        raise ParameterTypeError(f"value must be a dict, got {type(value).__name__}")
    hints: Hints = {}
    encoded = _encode_mapping(value, "", hints)
    meta = {"format": np.array([[MAT_FORMAT]], dtype=np.int64), "content": content, "types": json.dumps(hints)}

    def writer(tmp: str) -> None:
        savemat(tmp, {content: encoded, "piezohyst": meta}, appendmat=False, long_field_names=True, do_compression=True)

    return write_atomic(path, writer=writer, overwrite=overwrite)


# -- decoding ------------------------------------------------------------------------------
def _decode(a: Any, path: str, hints: Hints) -> Any:
    hint = hints.get(path)
    if hint == "none":
        return None
    if hint == "bool":
        return bool(np.asarray(a).item())
    if hint == "map":
        keys = [_decode(k, "", {}) for k in _struct_field(a, "keys").ravel(order="F")]
        values = _struct_field(a, "values").ravel(order="F")
        return {
            str(k): _decode(v, f"{path}/values/{i}", hints) for i, (k, v) in enumerate(zip(keys, values, strict=True))
        }
    if isinstance(hint, dict) and "array" in hint:
        arr = np.asarray(a)
        return np.array(arr, dtype=np.dtype(hint["array"])).reshape(hint["shape"])
    if isinstance(hint, dict) and "scalar" in hint:
        return np.dtype(hint["scalar"]).type(np.asarray(a).item())
    if hint in ("list", "tuple") or (isinstance(hint, dict) and ({"list", "tuple"} & set(hint))):
        kind = hint if isinstance(hint, str) else next(k for k in ("list", "tuple") if k in hint)
        nones = isinstance(hint, dict)
        arr = np.asarray(a)
        if arr.dtype == object:
            items = [_decode(x, f"{path}/{i}", hints) for i, x in enumerate(arr.ravel(order="F"))]
        else:
            items = [None if nones and np.isnan(x) else x for x in arr.ravel(order="F").tolist()]
        return items if kind == "list" else tuple(items)
    return _decode_plain(a, path, hints)


def _struct_field(a: Any, name: str) -> npt.NDArray[Any]:
    arr = np.asarray(a)
    if arr.dtype.names is None or name not in arr.dtype.names:
        raise DataError(f"expected a struct with a field {name!r}")
    return np.asarray(arr.ravel()[0][name])


def _decode_plain(a: Any, path: str, hints: Hints) -> Any:
    """A MATLAB value without a type note: struct -> dict, cell -> list, char -> str, an empty
    double -> None, a 1x1 number -> a Python number, other arrays squeezed."""
    arr = np.asarray(a)
    if arr.dtype.names is not None:  # a struct (array)
        structs = [
            {name: _decode(s[name], f"{path}/{name}", hints) for name in arr.dtype.names} for s in arr.ravel(order="F")
        ]
        return structs[0] if len(structs) == 1 else structs
    if arr.dtype == object:  # a cell array
        return [_decode(x, f"{path}/{i}", hints) for i, x in enumerate(arr.ravel(order="F"))]
    if arr.dtype.kind == "U":
        flat = [str(x) for x in arr.ravel()]
        return "".join(flat) if arr.ndim <= 1 else flat
    if arr.size == 0 and arr.ndim == 2 and arr.shape == (0, 0):
        return None
    if arr.size == 1:
        return arr.item()
    return arr.squeeze() if arr.ndim == 2 and 1 in arr.shape else arr


def read_mat(path: PathLike, content: str | None = None) -> dict[str, Any]:
    """Read back the value :func:`write_mat` wrote (exactly: types and every bit of every
    float). ``content`` is the struct's name (``"model"``, ...); ``None`` takes what the file
    says. A file that is not a ``.mat`` file of piezohyst raises
    :class:`~piezohyst.errors.DataError` naming it.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mat`` file.
    content : str, optional
        The struct expected (``"record"``, ``"model"``, ``"result"``); ``None`` accepts any.

    Returns
    -------
    dict
        The value written.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from piezohyst.signals.matfile import read_mat, write_mat
    >>> path = write_mat(pathlib.Path(tempfile.mkdtemp()) / "r.mat", "record", {"dt": 1e-3})
    >>> read_mat(path)
    {'dt': 0.001}
    >>> read_mat(path, "model")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    piezohyst.errors.DataError: ...r.mat holds a 'record', not a 'model'
    """
    from scipy.io import loadmat

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    try:
        raw = loadmat(str(p), squeeze_me=False, struct_as_record=True, chars_as_strings=True)
    except Exception as e:  # scipy raises ValueError, TypeError, OSError ... on a foreign file
        raise DataError(f"{p}: not a readable MATLAB .mat file ({type(e).__name__}: {e})") from None
    if "piezohyst" not in raw:
        raise DataError(
            f"{p}: not a .mat file written by piezohyst (no 'piezohyst' variable; variables: "
            f"{sorted(k for k in raw if not k.startswith('__'))})"
        )
    try:
        meta = _decode_plain(raw["piezohyst"], "", {})
        fmt, what, types = meta["format"], meta["content"], meta["types"]
        hints = json.loads(types) if types else {}
    except (KeyError, TypeError, ValueError) as e:
        raise DataError(f"{p}: its 'piezohyst' variable is malformed ({type(e).__name__}: {e})") from None
    if fmt != MAT_FORMAT:
        raise DataError(f"{p}: format {fmt!r} is not supported (this version reads {MAT_FORMAT})")
    if content is not None and what != content:
        raise DataError(f"{p} holds a {what!r}, not a {content!r}")
    if what not in raw:
        raise DataError(f"{p}: the variable {what!r} is missing")
    try:
        value = _decode(raw[what], "", hints)
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise DataError(f"{p}: the variable {what!r} is malformed ({type(e).__name__}: {e})") from None
    if not isinstance(value, dict):
        raise DataError(f"{p}: the variable {what!r} is not a struct")
    return value


def load_mat_file(path: PathLike, content: str, what: str, build: Callable[[dict[str, Any]], _T]) -> _T:
    """Read the struct ``content`` of the ``.mat`` file ``path`` (:func:`read_mat`) and turn it
    into an object with ``build``; anything wrong — not a piezohyst ``.mat`` file, another
    content, a description ``build`` refuses — is :class:`~piezohyst.errors.DataError` naming
    ``what`` and the path (as :func:`piezohyst._io.load_json_file` does for JSON).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mat`` file.
    content : str
        The struct expected (``"record"``, ``"model"``, ``"result"``).
    what : str
        What the file is, for error messages (``"model file"``...).
    build : callable
        Makes the object from the struct's dict.

    Returns
    -------
    object
        What ``build`` returns.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from piezohyst.models.model import Drift
    >>> from piezohyst.signals.matfile import load_mat_file, write_mat
    >>> path = write_mat(pathlib.Path(tempfile.mkdtemp()) / "d.mat", "model", {"slope": 0.5})
    >>> load_mat_file(path, "model", "drift file", Drift.from_any)
    Drift(taus=(), weights=(), slope=0.5)
    >>> load_mat_file(path, "model", "drift file", lambda d: d["gain"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    piezohyst.errors.DataError: drift file '...d.mat' is malformed: KeyError: 'gain'
    """
    p = Path(path)
    if p.is_dir():
        raise DataError(f"{what} '{p}' is a directory, not a file")
    try:
        d = read_mat(p, content)
    except DataError as e:
        raise DataError(f"{what} '{p}': {e}") from None
    try:
        return build(d)
    except DataError:
        raise
    except PiezohystError as e:
        raise DataError(f"{what} '{p}': {e}") from None
    except (KeyError, IndexError, TypeError, AttributeError, ValueError, OverflowError) as e:
        raise DataError(f"{what} '{p}' is malformed: {type(e).__name__}: {e}") from None
