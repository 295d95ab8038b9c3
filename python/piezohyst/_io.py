"""Files in and out: JSON files read into objects (:func:`load_json_file`); every file written
goes through :func:`write_atomic`, the output policy of :mod:`piezohyst.outputs` (re-exported
here for the package's writers).
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

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
