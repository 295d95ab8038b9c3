"""Atomic file output: every file piezohyst writes goes through :func:`write_atomic`.

A temporary file is written in the destination's directory, flushed to disk, given the
permissions a plain ``open(path, "w")`` would give (``mkstemp`` makes it private), and moved
into place with ``os.replace``: a reader sees the old file or the new one, never half of
one, and an interrupted write (Ctrl-C, a full disk, an exception in a plotting call) leaves
the old file untouched and no temporary behind.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from .errors import DataError, OutputExistsError, ParameterError, PiezohystError

_T = TypeVar("_T")

#: What a file path argument may be.
PathLike = str | os.PathLike[str]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomic(
    path: PathLike,
    data: str | bytes | None = None,
    *,
    writer: Callable[[str], None] | None = None,
    overwrite: bool = True,
    name: str = "path",
) -> Path:
    """Write ``data`` (text is UTF-8 with ``\\n`` line ends) or let ``writer(temp_path)`` write
    the file, then move it to ``path`` atomically.

    With ``overwrite=False`` an existing ``path`` is kept and :class:`OutputExistsError`
    (a :class:`FileExistsError`) names the argument ``name``.
    """
    if (data is None) == (writer is None):
        raise TypeError("write_atomic needs exactly one of data and writer")
    target = Path(path)
    if not overwrite and target.exists():
        raise OutputExistsError(f"{name} = '{target}' exists; pass --force (or overwrite=True) to replace it")
    parent = target.parent if str(target.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(dir=parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        if writer is None:
            assert data is not None  # exactly one of data and writer, checked above
            raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
            with os.fdopen(fd, "wb") as f:
                f.write(raw)
                f.flush()
                os.fsync(f.fileno())
        else:
            os.close(fd)
            writer(tmp)
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return target


def load_json_file(path: PathLike, what: str, build: Callable[[Any], _T]) -> _T:
    """Read the JSON file ``path`` and turn it into an object with ``build(parsed)``.

    A missing file is ``FileNotFoundError``; anything else wrong with the file — not text,
    not JSON, or JSON that ``build`` refuses or trips over (a list where an object belongs,
    a missing key, a string where a number belongs) — is :class:`DataError` naming ``what``
    and the path, never a bare ``KeyError``/``AttributeError`` from deep inside.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise FileNotFoundError(f"{what} '{path}' does not exist") from None
    except IsADirectoryError:
        raise DataError(f"{what} '{path}' is a directory, not a file") from None
    try:
        parsed = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise DataError(f"{what} '{path}' is not a text (JSON) file") from None
    except (json.JSONDecodeError, RecursionError) as e:
        raise DataError(f"{what} '{path}' is not valid JSON: {e}") from None
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
