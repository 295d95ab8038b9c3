"""Argument checks shared by the public API: each error names the argument and the value."""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Sized

import numpy as np
import numpy.typing as npt

from .errors import ParameterError, ParameterTypeError

FloatArray = npt.NDArray[np.float64]


def as_record(x: object, name: str, *, min_length: int = 1, copy: bool = True, finite: bool = True) -> FloatArray:
    """A finite 1-D float64 record: a copy the caller may keep, or (``copy=False``) a
    read-only view when the data is already float64. ``finite=False`` leaves the
    NaN/Inf check to the Rust core, which reports it with the same wording."""
    if isinstance(x, (str, bytes)):
        raise ParameterTypeError(f"{name} must be a 1-D array of numbers, got {type(x).__name__}")
    try:
        raw = np.asarray(x) if not isinstance(x, np.ndarray) else x
    except (TypeError, ValueError) as e:  # ragged nesting, objects numpy cannot shape
        raise ParameterTypeError(f"{name} must be a 1-D array of numbers: {e}") from None
    if raw.dtype.kind in "cbUSO" and raw.dtype.kind != "O":
        raise ParameterTypeError(f"{name} must be real numbers, got dtype {raw.dtype}")
    try:
        # aligned too: an array unpickled from a message buffer (Dask) may sit at any byte offset,
        # and the Rust core reads aligned memory only (copied then, as a non-contiguous one is)
        a = np.array(x, dtype=np.float64, copy=True) if copy else np.require(x, np.float64, ["C", "A"])
    except (TypeError, ValueError) as e:
        raise ParameterTypeError(f"{name} must be a 1-D array of numbers: {e}") from None
    if a.ndim != 1:
        raise ParameterError(f"{name} must be 1-D, got shape {a.shape}")
    if a.size < min_length:
        raise ParameterError(f"{name} has {a.size} samples, at least {min_length} needed")
    if not finite:
        return a
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise ParameterError(f"{name}[{bad[0]}] = {a[bad[0]]} is not finite")
    return a


def as_vector(x: object, name: str, *, length: int | None = None, allow_empty: bool = True) -> FloatArray:
    """A finite 1-D float64 parameter vector."""
    a = as_record(x, name, min_length=0 if allow_empty else 1)
    if length is not None and a.size != length:
        raise ParameterError(f"{name} has length {a.size}, expected {length}")
    return a


def as_scalar(
    x: object, name: str, *, positive: bool = False, nonnegative: bool = False, allow_infinite: bool = False
) -> float:
    """A finite real scalar (``allow_infinite``: also +-inf, never NaN)."""
    if isinstance(x, bool) or not isinstance(x, (numbers.Real, np.floating, np.integer)):
        raise ParameterTypeError(f"{name} must be a real number, got {x!r}")
    v = float(x)
    if np.isnan(v) or (not allow_infinite and not np.isfinite(v)):
        raise ParameterError(f"{name} = {v} is not finite")
    if positive and not v > 0:
        raise ParameterError(f"{name} = {v} must be > 0")
    if nonnegative and v < 0:
        raise ParameterError(f"{name} = {v} must be >= 0")
    return v


def as_int(x: object, name: str, *, minimum: int = 0, maximum: int | None = None) -> int:
    """An integer >= minimum (and <= maximum, if given)."""
    if isinstance(x, bool) or not isinstance(x, (numbers.Integral, np.integer)):
        raise ParameterTypeError(f"{name} must be an integer, got {x!r}")
    v = int(x)
    if v < minimum:
        raise ParameterError(f"{name} = {v} must be >= {minimum}")
    if maximum is not None and v > maximum:
        raise ParameterError(f"{name} = {v} must lie within [{minimum}, {maximum}]")
    return v


def as_interval(x: object, name: str) -> tuple[float, float]:
    """A pair ``(lower, upper)`` of real numbers (infinite allowed, NaN not) with lower < upper."""
    if isinstance(x, (str, bytes, dict)) or not isinstance(x, Sized) or not isinstance(x, Iterable):
        raise ParameterTypeError(f"{name} must be a pair (lower, upper), got {x!r}")
    if len(x) != 2:
        raise ParameterError(f"{name} must be a pair (lower, upper), got {len(x)} values: {list(x)!r}")
    ends: list[float] = []
    for i, v in enumerate(x):
        if isinstance(v, bool) or not isinstance(v, (numbers.Real, np.floating, np.integer)):
            raise ParameterTypeError(f"{name}[{i}] must be a real number, got {v!r}")
        ends.append(float(v))
    lo, hi = ends
    if not lo < hi:
        raise ParameterError(f"{name} = ({lo}, {hi}) must have lower < upper")
    return lo, hi
