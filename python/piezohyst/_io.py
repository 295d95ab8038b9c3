"""Files in and out: JSON files read into objects (:func:`load_json_file`); every file written
goes through :func:`write_atomic`, the output policy of :mod:`piezohyst.outputs` (re-exported
here for the package's writers).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from .errors import DataError, ParameterError, PiezohystError
from .outputs import PathLike, write_atomic

_T = TypeVar("_T")

__all__ = ["PathLike", "load_json_file", "malformed_as", "write_atomic"]


def load_json_file(path: PathLike, what: str, build: Callable[[Any], _T]) -> _T:
    """Read the JSON file ``path`` and turn it into an object with ``build(parsed)``.

    A missing file is ``FileNotFoundError``; anything else wrong with the file — not text,
    not JSON, or JSON that ``build`` refuses or trips over (a list where an object belongs,
    a missing key, a string where a number belongs) — is :class:`DataError` naming ``what``
    and the path, never a bare ``KeyError``/``AttributeError`` from deep inside.
    """
    path = Path(path)
    parsed = read_json_file(path, what)  # size, nesting, numbers and strings checked
    try:
        return build(parsed)
    except DataError:
        raise
    except PiezohystError as e:
        raise DataError(f"{what} '{path}': {e}") from None
    except (KeyError, IndexError, TypeError, AttributeError, ValueError, OverflowError) as e:
        raise DataError(f"{what} '{path}' is malformed: {type(e).__name__}: {e}") from None


@contextlib.contextmanager
def malformed_as(what: str) -> Iterator[None]:
    """Inside a builder of objects from parsed JSON: a ``KeyError``/``TypeError``/
    ``AttributeError``/``IndexError`` (a missing key, a list where an object belongs) becomes a
    :class:`ParameterError` naming ``what``; piezohyst's own errors pass through."""
    try:
        yield
    except PiezohystError:
        raise
    except KeyError as e:
        raise ParameterError(f"{what} is missing {e.args[0]!r}") from None
    except (TypeError, AttributeError, IndexError) as e:
        raise ParameterError(f"{what} is malformed: {e}") from None


# ----------------------------------------------------------------------------------------
# Reading the JSON files piezohyst takes (model, stage and controller files): one home,
# read_json_file (and load_json_file on it), for what a hostile file may not do.
#
# - Size: A file is read only when it is a regular file (not a FIFO, a device or a
#   directory) of at most MAX_JSON_BYTES (64 MiB; a 1000-level Preisach model is about
#   12 MB), raised with the environment variable ``PIEZOHYST_MAX_JSON_BYTES``.
# - Nesting: Arrays and objects nested deeper than MAX_JSON_DEPTH (64; piezohyst's
#   files nest 4 deep) are refused before the parser runs, so a file of 100,000 ``[`` is a
#   DataError ("nested too deeply"), never a ``RecursionError``.
# - Numbers: ``NaN``, ``Infinity`` and ``-Infinity`` (not JSON, but Python's parser takes
#   them), a literal that overflows a double (``1e999``) and an integer of more than
#   MAX_INT_DIGITS digits (Python refuses 4301 and more with a bare ``ValueError``) are
#   refused with the field's path (``parameters.weights[3]``).
# - Strings: Control characters (C0, DEL, C1: an ANSI escape is ``ESC [``) and bidirectional
#   overrides in any key or string are refused with the field's path: a model's ``units`` or a
#   stage's ``name`` is printed on the terminal.
# - Types: check_numbers refuses a boolean, a string or ``null`` where a number
#   belongs (``true`` is not 1), naming the field's path.
#
# Every check runs in C (the parser, re, numpy) or on the error path only: a valid file
# costs one regular-expression scan more than ``json.loads``.

#: Largest JSON file piezohyst reads, bytes (64 MiB); ``PIEZOHYST_MAX_JSON_BYTES`` raises it.
MAX_JSON_BYTES = 64 * 2**20

#: The environment variable that raises :data:`MAX_JSON_BYTES`.
MAX_JSON_BYTES_ENV = "PIEZOHYST_MAX_JSON_BYTES"

#: Deepest nesting of arrays and objects read (piezohyst's own files nest at most 4 deep).
MAX_JSON_DEPTH = 64

#: Most digits of an integer literal: any more cannot be a double (1.8e308 has 309 digits).
MAX_INT_DIGITS = 309

#: What a string in a file may not hold: C0 controls (tab and newline included: one field is
#: printed on one line), DEL, C1 controls, and the bidirectional overrides and isolates.
_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")

#: A JSON text that may hold such a character: an escape (``\\u001b``, ``\\n``, ...), DEL, or a
#: C1 or bidi character (a raw C0 character is invalid JSON inside a string, whitespace outside).
_MAY_HOLD_CONTROL = re.compile("\\\\[ubfnrt]|[\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")

#: A JSON string literal (escapes included), to blank out before counting brackets.
_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"', re.DOTALL)


def max_json_bytes() -> int:
    """The size bound: ``PIEZOHYST_MAX_JSON_BYTES`` (a whole number of bytes >= 1) or 64 MiB."""
    env = os.environ.get(MAX_JSON_BYTES_ENV, "").strip()
    if not env:
        return MAX_JSON_BYTES
    if not re.fullmatch(r"[0-9]+", env) or int(env) < 1:
        raise ParameterError(f"{MAX_JSON_BYTES_ENV} = {env!r} must be a whole number of bytes >= 1 (e.g. 200000000)")
    return int(env)


def read_json_file(path: str | os.PathLike[str], what: str) -> Any:
    """The parsed content of the JSON file ``path``; ``what`` names it in errors ("model file").

    A missing file is ``FileNotFoundError``; a directory, a FIFO or a device, a file over the
    size bound, bytes that are not UTF-8, invalid JSON, nesting deeper than
    :data:`MAX_JSON_DEPTH`, a non-finite or out-of-range number, or a control character in a
    string is :class:`DataError` naming ``what``, the path and (for a value) the field."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise FileNotFoundError(f"{what} '{p}' does not exist") from None
    except OSError as e:
        raise DataError(f"{what} '{p}' cannot be read: {e.strerror or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise DataError(f"{what} '{p}' is a directory, not a file")
    if not stat.S_ISREG(st.st_mode):
        raise DataError(f"{what} '{p}' is not a regular file (a device, FIFO or socket is not read)")
    limit = max_json_bytes()
    if st.st_size > limit:
        raise DataError(_too_big(what, p, st.st_size, limit))
    try:
        with open(p, "rb") as f:
            raw = f.read(limit + 1)
    except OSError as e:
        raise DataError(f"{what} '{p}' cannot be read: {e.strerror or e}") from None
    if len(raw) > limit:  # grew since the stat
        raise DataError(_too_big(what, p, len(raw), limit))
    return parse_json(raw, f"{what} '{p}'")


def _too_big(what: str, path: Path, size: int, limit: int) -> str:
    return (
        f"{what} '{path}' has {size:,} bytes, over the limit of {limit:,} bytes for a JSON file; if the file "
        f"is trusted, raise the limit with the environment variable {MAX_JSON_BYTES_ENV}=<bytes>"
    )


def parse_json(raw: bytes | str, where: str) -> Any:
    """Parse JSON text with the checks of :func:`read_json_file`; ``where`` starts each error
    message (``"model file 'm.json'"``)."""
    if isinstance(raw, bytes):
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise DataError(f"{where} is not a text (JSON) file (not UTF-8)") from None
    else:
        text = raw
    # every bracket counted (an upper bound, vectorized); exactly, strings left out, when over the bound
    depth = _bracket_depth(text)
    if depth > MAX_JSON_DEPTH and (depth := nesting_depth(text)) > MAX_JSON_DEPTH:
        raise DataError(
            f"{where}: arrays/objects nested too deeply ({depth} levels, at most {MAX_JSON_DEPTH}); "
            "this is not a piezohyst file"
        )
    parsed, flagged = _loads(text, where, numbers=False)  # floats by json's C parser: 13 MB in 0.4 s
    if not flagged and _has_infinite(parsed):  # a literal beyond a double (1e999): again, to name it
        parsed, flagged = _loads(text, where, numbers=True)
    if flagged:
        field, bad = next((f, v) for f, v in _walk(parsed) if isinstance(v, _Refused))
        raise DataError(f"{where}: {field or 'the document'} = {bad.token}: {bad.reason}")
    if ("\\" in text or not text.isascii()) and _MAY_HOLD_CONTROL.search(text):  # an escape, DEL, C1, bidi
        for field, v in _walk(parsed):
            if isinstance(v, str) and _CONTROL.search(v):
                raise DataError(f"{where}: {_control_message(field, v)}")
    return parsed


def _loads(text: str, where: str, *, numbers: bool) -> tuple[Any, bool]:
    """``json.loads`` with NaN/Infinity and integers of more than :data:`MAX_INT_DIGITS` digits
    (and, with ``numbers``, floats beyond a double) parsed into :class:`_Refused` markers;
    returns the document and whether it holds one."""
    flagged: list[str] = []

    def constant(token: str) -> _Refused:
        flagged.append(token)
        return _Refused(token, "not a finite number (JSON has no NaN or Infinity)")

    def integer(token: str) -> int | _Refused:
        digits = len(token) - (token[0] == "-")
        if digits > MAX_INT_DIGITS:  # Python's int() stops at 4300 digits with a bare ValueError
            flagged.append(token)
            return _Refused(f"<{digits}-digit integer>", f"out of range (a number has at most {MAX_INT_DIGITS} digits)")
        return int(token)

    def number(token: str) -> float | _Refused:
        x = float(token)
        if x in (np.inf, -np.inf):
            flagged.append(token)
            shown = token if len(token) <= 40 else f"<{len(token)}-character number>"
            return _Refused(shown, "overflows a double (|x| > 1.8e308)")
        return x

    try:
        parsed = json.loads(text, parse_constant=constant, parse_int=integer, parse_float=number if numbers else None)
    except json.JSONDecodeError as e:
        raise DataError(f"{where} is not valid JSON: {e}") from None
    except RecursionError:  # not reached: the depth is bounded above
        raise DataError(f"{where}: arrays/objects nested too deeply") from None
    return parsed, bool(flagged)


def _has_infinite(node: Any) -> bool:
    """Whether a parsed document holds an infinite float (only a literal beyond a double gives
    one: NaN/Infinity are markers). Lists of numbers are checked by numpy, in C."""
    stack = [node]
    while stack:
        n = stack.pop()
        if isinstance(n, dict):
            stack.extend(n.values())
        elif isinstance(n, list):
            kinds = set(map(type, n))
            if kinds <= {int, float, bool, type(None), str}:
                if float in kinds:
                    floats = n if kinds == {float} else [x for x in n if type(x) is float]
                    if np.isinf(np.asarray(floats, dtype=np.float64)).any():
                        return True
            else:
                stack.extend(x for x in n if isinstance(x, (list, dict)))
                stack.append([x for x in n if type(x) is float])
        elif type(n) is float and n in (np.inf, -np.inf):
            return True
    return False


def nesting_depth(text: str) -> int:
    """The deepest nesting of ``[``/``{`` in JSON text, strings left out (vectorized)."""
    return _bracket_depth(_STRING.sub('""', text) if '"' in text else text)


def _bracket_depth(text: str) -> int:
    """The deepest nesting of every ``[``/``{`` in the text, those in strings included."""
    if "[" not in text and "{" not in text:
        return 0
    b = np.frombuffer(text.encode("utf-8", "surrogatepass"), dtype=np.uint8)
    opening = (b == 0x5B) | (b == 0x7B)
    brackets = opening | (b == 0x5D) | (b == 0x7D)
    step = np.where(opening[brackets], 1, -1)  # few, even in a file of large arrays
    return int(np.cumsum(step).max(initial=0))


class _Refused:
    """A number the parser met that piezohyst refuses; found with its path after parsing."""

    __slots__ = ("reason", "token")

    def __init__(self, token: str, reason: str) -> None:
        self.token = token
        self.reason = reason


def _walk(node: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    """Every ``(path, value)`` of a parsed document, keys included (as values at their own
    path), depth first. Used on the error path only."""
    stack: list[tuple[str, Any]] = [(path, node)]
    while stack:
        where, n = stack.pop()
        yield where, n
        if isinstance(n, dict):
            items = list(n.items())
            for k, v in reversed(items):
                child = f"{where}.{k}" if where else str(k)
                stack.append((child, v))
                stack.append((f"{child} (key)", k))
        elif isinstance(n, list):
            stack.extend((f"{where}[{i}]", v) for i, v in reversed(list(enumerate(n))))


def _control_message(field: str, value: str) -> str:
    m = _CONTROL.search(value)
    assert m is not None
    return (
        f"{printable(field)} = {json.dumps(value[:60])} holds the control character U+{ord(m.group()):04X} "
        f"at position {m.start()}; strings in piezohyst files may not hold control characters or escapes"
    )


def printable(text: str) -> str:
    """``text`` with every control character and bidirectional override escaped
    (``\\x1b``, ``\\u202e``): safe to print on a terminal, one line."""
    if not _CONTROL.search(text):
        return text
    return _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), text)


def check_numbers(node: object, field: str, *, allow_null: bool = False) -> None:
    """Refuse, naming the path, a boolean, a string (or ``null`` unless ``allow_null``) where
    ``node`` — a number, or arrays of numbers nested — must hold numbers: ``true`` is not 1."""
    bad = _first_non_number(node, field, allow_null)
    if bad is not None:
        where, v = bad
        kind = "a boolean" if isinstance(v, bool) else "null" if v is None else f"a {_json_type(v)}"
        raise ParameterError(f"{where} = {json_text(v)} is {kind}, expected a number")


def check_parameter_tree(node: object, field: str, *, strings: tuple[str, ...] = ("kind",)) -> None:
    """Refuse, naming the path, anything but numbers (arrays of numbers nested, ``null`` for an
    absent part or an open end) in a parameter object; objects nest (an envelope), and a key
    in ``strings`` may also hold a string (an envelope's ``kind``, a stage's ``"inf"``)."""
    if isinstance(node, dict):
        for k, v in node.items():
            if v is None or (k in strings and isinstance(v, str)):
                continue
            if k in strings and (isinstance(v, bool) or not isinstance(v, (int, float))):
                raise ParameterError(f"{field}.{k} = {json_text(v)} is neither a name (a string) nor a number")
            check_parameter_tree(v, f"{field}.{k}", strings=strings)
    else:
        check_numbers(node, field, allow_null=True)


def _first_non_number(node: object, field: str, allow_null: bool) -> tuple[str, object] | None:
    ok: tuple[type, ...] = (int, float, type(None)) if allow_null else (int, float)
    if isinstance(node, list):
        kinds = set(map(type, node))  # in C: the common case of a list of numbers costs one pass
        if kinds <= set(ok):
            return None
        for i, v in enumerate(node):
            if isinstance(v, list):
                hit = _first_non_number(v, f"{field}[{i}]", allow_null)
                if hit is not None:
                    return hit
            elif type(v) not in ok:
                return f"{field}[{i}]", v
        return None
    if type(node) in ok:
        return None
    return field, node


def _json_type(v: object) -> str:
    names: dict[type, str] = {dict: "JSON object", list: "JSON array", str: "string"}
    return names.get(type(v), type(v).__name__)


def json_text(v: object) -> str:
    """``v`` as a short JSON literal (``true``, ``null``, ``"V"``), safe to print."""
    try:
        text = json.dumps(v, allow_nan=False)
    except (TypeError, ValueError):
        text = repr(v)
    return printable(text if len(text) <= 60 else text[:57] + "...")
