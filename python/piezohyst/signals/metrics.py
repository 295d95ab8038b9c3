"""Tracking and compensation metrics (docs/spec.md §6).

Plain functions over 1-D records: the error ``e = output - reference`` as RMSE and maximum,
both also relative to the reference's range; the linearity error of an output against the
desired trajectory; the hysteresis of an input/output loop. Bad input raises
:class:`ValueError` (NaN/Inf, empty records, records of different lengths, a reference or
output with zero range where the metric divides by it) or :class:`TypeError` (not numbers);
the message names the argument and the value.

Functions
---------
rms                 root mean square of one record (scaled: no overflow, no underflow)
rmse                root-mean-square error
max_error           maximum absolute error
linearity_error     deviation from the least-squares line, % of the output range
hysteresis_percent  widest vertical loop width, % of the output range
tracking_metrics    all of the above for one tracking run, as a dict

Examples
--------
>>> import numpy as np
>>> from piezohyst.metrics import tracking_metrics
>>> reference = np.array([0.0, 1.0, 2.0, 3.0])
>>> m = tracking_metrics(reference, reference + [0.0, 0.0, 0.0, 0.3])
>>> round(m["max_error_percent"], 6), round(m["normalized_max_error"], 6)
(10.0, 0.1)
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_record
from ..errors import ParameterError

FloatArray = npt.NDArray[np.float64]

__all__ = ["hysteresis_percent", "linearity_error", "max_error", "rms", "rmse", "tracking_metrics"]


def _pair(
    a: npt.ArrayLike, b: npt.ArrayLike, name_a: str, name_b: str, min_length: int = 1
) -> tuple[FloatArray, FloatArray]:
    """Two finite 1-D float64 records of the same length."""
    x = as_record(a, name_a, min_length=min_length, copy=False)
    y = as_record(b, name_b, min_length=min_length, copy=False)
    if x.size != y.size:
        raise ParameterError(f"{name_b} has {y.size} samples, {name_a} has {x.size}; they must match")
    return x, y


def _span(x: FloatArray, name: str) -> float:
    """The range of ``x``; a metric that divides by it is undefined when it is zero."""
    span = float(np.ptp(x))
    if not span > 0:
        raise ParameterError(
            f"{name} has zero range (every sample = {float(x[0])}); the metric is relative to its range"
        )
    return span


def rms(x: npt.ArrayLike) -> float:
    """Root mean square of a finite record, computed on the record scaled by its largest
    magnitude: the squares of values near 1e300 do not overflow and those of subnormal values
    (1e-310) do not vanish, so a record's RMS is never 0 beside a non-zero maximum.

    Parameters
    ----------
    x : array_like, shape (N,)
        A finite record, N >= 1.

    Returns
    -------
    float
        ``sqrt(mean(x**2))``.

    Examples
    --------
    >>> from piezohyst.metrics import rms
    >>> rms([3.0, -4.0, 0.0, 0.0])
    2.5
    >>> from piezohyst.metrics import rms
    >>> rms([3e300, -4e300]) == rms([3.0, -4.0]) * 1e300, rms([3e-310, 4e-310]) > 0
    (True, True)
    """
    a = as_record(x, "x", copy=False)
    s = float(np.max(np.abs(a)))
    if s == 0.0:
        return 0.0
    return s * float(np.sqrt(np.mean((a / s) ** 2)))


def rmse(reference: npt.ArrayLike, output: npt.ArrayLike) -> float:
    """Root-mean-square error ``sqrt(mean((output - reference)**2))``.

    Parameters
    ----------
    reference, output : array_like, shape (N,)
        Finite records of the same length, N >= 1.

    Returns
    -------
    float

    Examples
    --------
    >>> from piezohyst.metrics import rmse
    >>> rmse([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 5.0])
    1.0
    """
    r, y = _pair(reference, output, "reference", "output")
    return rms(y - r)


def max_error(reference: npt.ArrayLike, output: npt.ArrayLike) -> float:
    """Maximum absolute error ``max|output - reference|``.

    Parameters
    ----------
    reference, output : array_like, shape (N,)
        Finite records of the same length, N >= 1.

    Returns
    -------
    float

    Examples
    --------
    >>> from piezohyst.metrics import max_error
    >>> max_error([0.0, 1.0, 2.0], [0.5, 1.0, 1.0])
    1.0
    """
    r, y = _pair(reference, output, "reference", "output")
    return float(np.max(np.abs(y - r)))


def linearity_error(desired: npt.ArrayLike, output: npt.ArrayLike) -> float:
    """Linearity error, percent: ``100 max|y - (a x_d + b)| / (max y - min y)``, with
    ``(a, b)`` the least-squares line of the output ``y`` against the desired ``x_d``
    (docs/spec.md §6; seed 2, Table 3).

    The line absorbs any gain and offset, so a compensated actuator that tracks with the wrong
    gain still scores 0; what remains is the curvature and the loop width.

    Parameters
    ----------
    desired, output : array_like, shape (N,)
        Finite records of the same length, N >= 2; neither may be constant.

    Returns
    -------
    float
        Percent of the output range.

    Examples
    --------
    >>> from piezohyst.metrics import linearity_error
    >>> round(linearity_error([0, 1, 2, 3, 4], [0, 1, 3, 3, 4]), 9)   # line y = x + 0.2, worst 0.8 / 4
    20.0
    """
    x, y = _pair(desired, output, "desired", "output", min_length=2)
    _span(x, "desired")
    span = _span(y, "output")
    # centred regressors: the normal equations stay well conditioned for large offsets
    xc, yc = x - x.mean(), y - y.mean()
    a = float(xc @ yc) / float(xc @ xc)
    deviation = yc - a * xc
    return float(100.0 * np.max(np.abs(deviation)) / span)


def _envelopes(x: FloatArray, y: FloatArray, levels: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Upper and lower envelopes of the piecewise-linear path ``(x, y)`` at ``levels``
    (increasing): for each level, the max and min of ``y`` interpolated on every sample
    interval that crosses it; NaN where no interval does.

    An interval covers the levels from its first sample (included) to its last (excluded; the
    record's last interval includes both), in the direction of travel, so every point of the
    path is counted once: a jump of the output where the input holds, or at a turning point,
    is not a width by itself."""
    x0, x1, y0, y1 = x[:-1], x[1:], y[:-1], y[1:]
    rising = x1 > x0
    last = np.arange(x0.size) == x0.size - 1
    # the covered index range [first, stop) of the levels, per interval
    first = np.where(rising, np.searchsorted(levels, x0, side="left"), np.searchsorted(levels, x1, side="right"))
    stop = np.where(rising, np.searchsorted(levels, x1, side="left"), np.searchsorted(levels, x0, side="right"))
    first = np.where(last & ~rising, np.searchsorted(levels, x1, side="left"), first)
    stop = np.where(last & rising, np.searchsorted(levels, x1, side="right"), stop)
    count = np.where(x0 != x1, np.maximum(stop - first, 0), 0)  # a held input crosses no level
    # every (interval, level) pair the path crosses, without a Python loop over intervals
    which = np.repeat(np.arange(count.size), count)
    level = first[which] + np.arange(which.size) - np.repeat(np.cumsum(count) - count, count)
    t = (levels[level] - x0[which]) / (x1[which] - x0[which])
    value = y0[which] + t * (y1[which] - y0[which])
    upper = np.full(levels.size, -np.inf)
    lower = np.full(levels.size, np.inf)
    np.maximum.at(upper, level, value)
    np.minimum.at(lower, level, value)
    reached = np.isfinite(upper)
    upper[~reached] = np.nan
    lower[~reached] = np.nan
    return upper, lower


def hysteresis_percent(input: npt.ArrayLike, output: npt.ArrayLike, *, levels: int = 200) -> float:
    """Hysteresis, percent: the widest vertical extent of the loop over the input, relative to
    the output range (docs/spec.md §6).

    Definition: the record is read as the path through the points ``(input[k], output[k])``,
    straight between samples. At each of ``levels`` input values evenly spaced from
    ``min(input)`` to ``max(input)`` (both included), every sample interval of the path that
    crosses the level is linearly interpolated there; the width at the level is the largest
    minus the smallest of those values. The result is
    ``100 * max(width) / (max(output) - min(output))``.

    For one closed loop the intervals crossing a level belong to the ascending and the
    descending branch, and the width is the vertical distance between them. With several
    loops (minor loops, several cycles, drift) it is the spread of all branches at the level,
    so a drift between cycles counts as width. An interval covers the levels from its first
    sample (included) to its next (excluded), in the direction of travel, so each point of the
    path counts once: an output jump while the input holds (a turning point's vertical edge,
    creep during a dwell) is not a width by itself, whether or not it sits on a level. Levels
    reached by one branch only have width 0.

    Parameters
    ----------
    input, output : array_like, shape (N,)
        Finite records of the same length, N >= 2; neither may be constant.
    levels : int
        Input levels the width is evaluated at (>= 2).

    Returns
    -------
    float
        Percent of the output range.

    Examples
    --------
    A parallelogram loop: ascending branch ``y = x - 0.1``, descending ``y = x + 0.1``, width
    0.2 over an output range of 1.2:

    >>> import numpy as np
    >>> from piezohyst.metrics import hysteresis_percent
    >>> up = np.linspace(0, 1, 11)
    >>> x = np.r_[up, up[::-1]]
    >>> y = np.r_[up - 0.1, up[::-1] + 0.1]
    >>> round(hysteresis_percent(x, y), 9)
    16.666666667
    """
    x, y = _pair(input, output, "input", "output", min_length=2)
    n = as_int(levels, "levels", minimum=2)
    _span(x, "input")
    span = _span(y, "output")
    upper, lower = _envelopes(x, y, np.linspace(x.min(), x.max(), n))
    return float(100.0 * np.nanmax(upper - lower) / span)


def tracking_metrics(reference: npt.ArrayLike, output: npt.ArrayLike) -> dict[str, float]:
    """Tracking metrics of one run of ``output`` following ``reference``.

    Parameters
    ----------
    reference, output : array_like, shape (N,)
        Finite records of the same length, N >= 2; the reference may not be constant.

    Returns
    -------
    dict
        ``rmse``, ``max_error``
            Of ``e = output - reference``, in the records' unit.
        ``rmse_percent``, ``max_error_percent``
            The same, in percent of the reference's range.
        ``normalized_max_error``, ``normalized_rms_error``
            ``max|e| / range(reference)`` and ``rms(e) / range(reference)``: seed 2's
            Table 4 "normalized max error / mean square error". We read the latter as the
            root-mean-square error over the range, not the mean of ``e**2``: the table's
            pairs (e.g. 0.0784 / 0.0348) have the ratio of a max to an RMS, a squared error
            would be orders of magnitude smaller and carry squared units.
        ``linearity_error``
            :func:`linearity_error` of the output against the reference, percent; ``nan``
            when the output is constant (the metric is then undefined).

    Examples
    --------
    >>> from piezohyst.metrics import tracking_metrics
    >>> m = tracking_metrics([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 5.0])
    >>> m["rmse"], m["max_error"], round(m["normalized_rms_error"], 6), round(m["linearity_error"], 6)
    (1.0, 2.0, 0.333333, 16.0)
    """
    r, y = _pair(reference, output, "reference", "output", min_length=2)
    span = _span(r, "reference")
    e_rms, e_max = rmse(r, y), max_error(r, y)
    # a constant output is a (failed) run worth reporting, not an input error
    lin = linearity_error(r, y) if np.ptp(y) > 0 else float("nan")
    return {
        "rmse": e_rms,
        "max_error": e_max,
        "rmse_percent": 100.0 * e_rms / span,
        "max_error_percent": 100.0 * e_max / span,
        "normalized_max_error": e_max / span,
        "normalized_rms_error": e_rms / span,
        "linearity_error": lin,
    }
