"""Preprocessing of measured records before identification.

Lab records carry defects a hysteresis model should not have to explain. Each defect has one
function here, and :func:`preprocess` applies them in a fixed, documented order:

1. **outliers** — :func:`flag_outliers` finds glitches of the output (a running median and a
   MAD threshold); :func:`replace_outliers` replaces them by linear interpolation between
   their good neighbours (the samples are *not* dropped: a hysteresis model is a dynamic
   system and needs a continuous time axis). Done first, so that a glitch corrupts neither
   the lead-in search, the lag estimate, the drift fit nor (spread by the filter) the
   decimated record.
2. **lead-in** — :func:`find_excitation_start` finds where a quiet lead-in of the input ends;
   the samples before are dropped.
3. **lag** — :func:`estimate_lag` estimates the input→output delay in samples;
   :func:`apply_lag` realigns the channels (the output is advanced).
4. **drift** — :func:`remove_drift` removes a slow polynomial trend of the output, fitted
   jointly with a rate-independent function of the input so that the response to the
   input is not taken for drift. (Creep — the slow response *to the input* — is modelled
   instead, by the PI family's ``creep`` lags.)
5. **decimation** — :func:`decimate` low-pass filters both channels with the same
   linear-phase FIR anti-alias filter and keeps every ``factor``-th sample. Last, so the
   steps above work at the full time resolution.

Examples
--------
>>> import numpy as np
>>> from piezohyst.signals import Record, preprocess
>>> fs = 1000.0
>>> t = np.arange(4000) / fs
>>> u = np.where(t < 0.5, 0.0, np.sin(2 * np.pi * (t - 0.5)))
>>> y = np.roll(u, 3) + 0.2 * t
>>> y[:3] = 0.0
>>> rec, report = preprocess(Record(u, y, fs), lag="auto", lead_in="auto", drift="remove")
>>> report["steps"], report["lead_in"]["samples"], report["lag"]["samples"]
(['lead_in', 'lag', 'drift'], 501, 3)
>>> round(report["drift"]["change"], 2)
0.7
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_int, as_record, as_scalar
from ..errors import DataError, ParameterError, ParameterTypeError
from .data import Record

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "apply_lag",
    "decimate",
    "estimate_lag",
    "find_excitation_start",
    "flag_outliers",
    "preprocess",
    "processed_index",
    "remove_drift",
    "replace_outliers",
]

#: Rows the lag estimate fits at most (a strided subset of the record; all lags use the same rows).
_LAG_ROWS = 20000
#: Play-operator thresholds of the lag estimate's proxy model, as fractions of the input range.
_LAG_THRESHOLDS = (0.0, 0.04, 0.08, 0.15, 0.25, 0.35, 0.5)


def _record(record: object) -> Record:
    if not isinstance(record, Record):
        raise ParameterTypeError(f"record must be a piezohyst Record, got {type(record).__name__}")
    return record


def _with(
    record: Record, input: FloatArray, output: FloatArray, time: FloatArray | None, fs: float | None = None
) -> Record:
    return Record(input, output, record.fs if fs is None else fs, time, record.source, dict(record.columns))


# --------------------------------------------------------------------------------------
# lag


def _proxy_regressors(u: FloatArray) -> FloatArray:
    """Play-operator outputs of ``u`` (from rest) for thresholds spread over its range, then
    powers 2 ... 5 of the scaled input and a constant: a linear-in-parameters, rate-independent
    proxy of hysteresis (the play columns first, ``_LAG_THRESHOLDS`` of them)."""
    span = float(np.ptp(u))
    r = np.asarray(_LAG_THRESHOLDS) * span
    m = r.size
    row = np.concatenate(([1.0], r, np.ones(m)))
    phi = _core.regressors("pi", [m, 0], row, np.ascontiguousarray(u))
    z = (u - 0.5 * (float(np.max(u)) + float(np.min(u)))) / span
    powers = z[:, None] ** np.arange(2, 6)
    return np.column_stack((phi[:, 1:], powers, np.ones(u.size)))


def estimate_lag(input: npt.ArrayLike, output: npt.ArrayLike, max_lag: int) -> int:
    """The input→output delay of a record, in samples.

    For each candidate lag ``k`` in ``-max_lag ... max_lag`` the output advanced by ``k``
    samples is fitted, by least squares with non-negative branch slopes, with a
    rate-independent proxy of hysteresis: play operators of the input with thresholds spread
    over half its range (a Prandtl–Ishlinskii model whose weights' running sums, the slopes
    of its branches, are kept >= 0, so hardening and saturating loops both fit), powers of
    the input and a constant. The lag with the smallest residual wins.

    Why this proxy: a rate-independent model with non-negative slopes moves its output
    only in the direction its input moves, and stops when the input stops, so it explains
    the hysteresis loop but not a delay — after every input reversal a delayed output keeps
    going the old way for ``k`` samples, which the proxy cannot follow. A linear proxy (or
    the cross-correlation of the derivatives) would take the loop's phase lag for a delay:
    on a sine, a hysteresis loop and a delay both shift the phase, and the derivative
    correlation's peak moves by a large part of the loop's phase. Both signs of the output
    are tried (sensors that read lower for larger displacement). Powers 2 to 5 of the input
    (free sign) absorb a static nonlinearity, a parabola in time a slow drift. All lags are
    scored on the same rows (at most 20,000, strided) with one QR factorisation; each lag
    then costs a small NNLS.

    Checked on PI and Bouc–Wen records at 200 Hz with 0.3 % noise (delays of 0, 3 and 12
    samples found exactly) and on ``yan9a_model_1hz.dat`` (5 samples, 25 ms, where the held-out
    error of an MPI fit is smallest: 0.85 % of range without the shift, 0.45 % with it). Its
    limit: on a heavily oversampled record (thousands of samples per cycle) of a loop the
    proxy does not fit well, the delay can be missed by several samples; give the delay
    (``apply_lag``) when it is known.

    Parameters
    ----------
    input, output : array_like
        1-D finite signals of equal length.
    max_lag : int
        Largest delay searched, in samples (``>= 0``; less than a quarter of the record).
        Negative lags (output leading the input) are searched too.

    Returns
    -------
    int
        ``k > 0``: the output lags the input by ``k`` samples (``output[i + k]`` answers
        ``input[i]``); ``k < 0``: it leads.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(3000) / 1000.0
    >>> u = np.sin(2 * np.pi * t) + 0.5 * np.sin(2 * np.pi * 3.3 * t)
    >>> y = np.concatenate((np.zeros(7), (u + 0.3 * u**3)[:-7]))
    >>> estimate_lag(u, y, max_lag=20)
    7
    """
    u = as_record(input, "input", min_length=8)
    y = as_record(output, "output", min_length=8)
    if u.size != y.size:
        raise ParameterError(f"output has {y.size} samples, input has {u.size}: lengths must match")
    k_max = as_int(max_lag, "max_lag", minimum=0)
    n = u.size
    if 4 * k_max >= n:
        raise ParameterError(f"max_lag = {k_max} must be less than a quarter of the record ({n} samples)")
    if k_max == 0:
        return 0
    if np.ptp(u) == 0.0:
        raise DataError("input is constant: no excitation to estimate a lag from")
    if np.ptp(y) == 0.0:
        raise DataError("output is constant: no response to estimate a lag from")
    from scipy.optimize import nnls

    phi = _proxy_regressors(u)
    stride = max(1, (n - 2 * k_max) // _LAG_ROWS)
    rows = np.arange(k_max, n - k_max, stride)
    lags = np.arange(-k_max, k_max + 1)
    m = len(_LAG_THRESHOLDS)
    x = 2.0 * rows / (n - 1) - 1.0  # a slow drift (degree 2 in time) is free too
    # slopes, not weights, are kept >= 0: with plays ordered by threshold, the columns
    # play_j - play_{j+1} (and the last play) take the prefix sums of the weights, i.e. the
    # slope of a branch once j+1 operators move, so concave (saturating) branches fit as well
    # as convex ones while the output still moves only with the input
    plays = phi[rows, :m] - np.column_stack((phi[rows, 1:m], np.zeros(rows.size)))
    static = np.column_stack((phi[rows, m:], x, x * x))
    targets = y[rows[:, None] + lags[None, :]]  # column j: the output advanced by lags[j]
    # the static terms are free: project them out of the plays and of every target at once
    qs, _ = np.linalg.qr(static)
    plays = plays - qs @ (qs.T @ plays)
    targets = targets - qs @ (qs.T @ targets)
    qp, rp = np.linalg.qr(plays / (np.sqrt(np.mean(plays * plays, axis=0)) + 1e-300))
    b = qp.T @ targets
    base = np.sum(targets * targets, axis=0) - np.sum(b * b, axis=0)  # residual outside span(plays)
    cost = np.empty(lags.size)
    for j in range(lags.size):  # a loop over candidate lags (small m x m NNLS), not over samples
        inside = min(nnls(rp, b[:, j])[1], nnls(rp, -b[:, j])[1])  # either sign of the output
        cost[j] = base[j] + inside * inside
    return int(lags[int(np.argmin(cost))])


def apply_lag(record: Record, lag: int) -> Record:
    """Realign a record whose output lags its input by ``lag`` samples.

    Sample ``i`` of the result pairs ``input[i]`` with ``output[i + lag]``; the ``|lag|``
    samples without a partner are dropped (at the end for ``lag > 0``, at the start for
    ``lag < 0``). The time axis, if any, is the input's.

    Parameters
    ----------
    record : Record
        The record to realign.
    lag : int
        The output's delay in samples (negative: the output leads).

    Returns
    -------
    Record

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals import Record
    >>> rec = apply_lag(Record(np.arange(6.0), np.arange(6.0) - 2, fs=10.0), 2)
    >>> rec.input, rec.output
    (array([0., 1., 2., 3.]), array([0., 1., 2., 3.]))
    """
    rec = _record(record)
    if isinstance(lag, bool) or not isinstance(lag, (int, np.integer)):
        raise ParameterTypeError(f"lag must be an int (samples), got {lag!r}")
    k = int(lag)
    if rec.n - abs(k) < 2:
        raise ParameterError(f"lag = {k} leaves {max(rec.n - abs(k), 0)} samples of a {rec.n}-sample record")
    if k == 0:
        return rec
    n = rec.n
    if k > 0:
        t = None if rec.time is None else rec.time[: n - k]
        return _with(rec, rec.input[: n - k], rec.output[k:], t)
    t = None if rec.time is None else rec.time[-k:]
    return _with(rec, rec.input[-k:], rec.output[: n + k], t)


# --------------------------------------------------------------------------------------
# drift


def remove_drift(
    output: npt.ArrayLike, fs: float, *, input: npt.ArrayLike | None = None, order: int = 1
) -> tuple[FloatArray, FloatArray]:
    """Remove a slow polynomial drift from an output signal.

    The drift is a polynomial of time of degree ``order`` that is zero at the first sample
    (the record keeps its level at the start). With ``input`` given (recommended) the drift
    is fitted jointly with a rate-independent function of the input — play operators of the
    input (a Prandtl–Ishlinskii proxy) plus powers 2 to 5 of it — so the response to an input
    whose level moves during the record is not taken for drift; only the polynomial of time
    is removed. Without ``input`` it is a plain polynomial detrend.

    This removes a trend the input does not explain (thermal or sensor drift). Creep — the
    slow response to the input itself — is better modelled: the PI family's ``creep`` lags.

    Parameters
    ----------
    output : array_like
        The measured output.
    fs : float
        Sample rate in Hz.
    input : array_like, optional
        The input of the same record.
    order : int
        Degree of the drift polynomial, ``1`` (linear drift, default) to ``5``.

    Returns
    -------
    corrected, drift : ndarray
        ``output - drift`` and the drift itself (``drift[0] == 0``).

    Examples
    --------
    >>> import numpy as np
    >>> fs = 100.0
    >>> t = np.arange(2000) / fs
    >>> u = np.sin(2 * np.pi * 0.5 * t)
    >>> y, d = remove_drift(2 * u + 0.05 * t, fs, input=u)
    >>> round(float(d[-1]), 4), round(float(np.max(np.abs(y - 2 * u))), 6)
    (0.9995, 0.0)
    """
    y = as_record(output, "output", min_length=2)
    as_scalar(fs, "fs", positive=True)  # checked for the API's sake; the drift is fitted on sample time
    deg = as_int(order, "order", minimum=1)
    if deg > 5:
        raise ParameterError(f"order = {deg} must be 1 to 5 (a drift is slow; use creep lags for a response)")
    n = y.size
    if n < 2 * (deg + 1):
        raise ParameterError(f"output has {n} samples: too few for a drift of order {deg}")
    x = 2.0 * np.arange(n) / (n - 1) - 1.0  # time scaled to [-1, 1] for a well-conditioned basis
    time_cols = np.polynomial.legendre.legvander(x, deg)[:, 1:]  # without the constant
    cols = [time_cols, np.ones((n, 1))]
    if input is not None:
        u = as_record(input, "input", min_length=2)
        if u.size != n:
            raise ParameterError(f"input has {u.size} samples, output has {n}: lengths must match")
        if np.ptp(u) > 0:
            cols.append(_proxy_regressors(u)[:, :-1])
    a = np.hstack(cols)
    scale = np.sqrt(np.mean(a * a, axis=0))
    scale[scale == 0] = 1.0
    coef = np.linalg.lstsq(a / scale, y, rcond=None)[0] / scale
    drift = time_cols @ coef[:deg]
    drift = drift - drift[0]
    return y - drift, drift


# --------------------------------------------------------------------------------------
# lead-in


def find_excitation_start(input: npt.ArrayLike, fs: float, *, threshold: float = 0.02) -> int:
    """Where a quiet lead-in of the input ends: the index of the first excited sample.

    The lead-in level is the median of the first 10 ms (at least 5 samples); the input is
    excited once it leaves that level by more than ``threshold`` times its range (robust:
    the 0.5 ... 99.5 percentiles). The start is then moved back to where the input last
    sat within the lead-in's noise band (6 robust standard deviations of the lead-in, from
    the median absolute deviation), so a slowly rising excitation keeps its beginning.

    Parameters
    ----------
    input : array_like
        The input signal.
    fs : float
        Sample rate in Hz.
    threshold : float
        Fraction of the input range that counts as excitation (default 0.02), in (0, 1).

    Returns
    -------
    int
        ``0`` when the record starts excited (or quiet for less than 20 ms / 10 samples); else
        the number of lead-in samples.

    Raises
    ------
    DataError
        The input never leaves its initial level.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(3000) / 1000.0
    >>> u = np.where(t < 1.0, 0.0, np.sin(2 * np.pi * (t - 1.0)))
    >>> find_excitation_start(u, 1000.0)
    1001
    >>> find_excitation_start(np.sin(2 * np.pi * t), 1000.0)
    0
    """
    u = as_record(input, "input", min_length=2)
    rate = as_scalar(fs, "fs", positive=True)
    frac = as_scalar(threshold, "threshold", positive=True)
    if frac >= 1:
        raise ParameterError(f"threshold = {frac:g} must be a fraction of the input range in (0, 1)")
    n = u.size
    w = int(min(max(5, round(0.01 * rate)), max(2, n // 10)))
    level = float(np.median(u[:w]))
    lo, hi = np.percentile(u, [0.5, 99.5])
    span = float(max(hi - lo, np.ptp(u) * 1e-3))
    if span == 0.0:
        raise DataError("input never leaves its initial level: no excitation in the record")
    dev = np.abs(u - level)
    over = np.flatnonzero(dev > frac * span)
    if over.size == 0:
        raise DataError(
            f"input never leaves its initial level {level:.6g} by more than {frac:g} x its range: no excitation found"
        )
    first = int(over[0])
    if first < 2 * w:
        return 0  # excited from the start (a lead-in shorter than 20 ms is not worth dropping)
    quiet = u[:first]
    sigma = 1.4826 * float(np.median(np.abs(quiet - np.median(quiet))))
    band = max(6.0 * sigma, 1e-9 * span)
    inside = np.flatnonzero(dev[:first] <= band)
    start = int(inside[-1]) + 1 if inside.size else 0
    return 0 if start <= 1 else start


# --------------------------------------------------------------------------------------
# outliers


def flag_outliers(
    signal: npt.ArrayLike, *, window: int = 11, threshold: float = 8.0, min_fraction: float = 0.02
) -> npt.NDArray[np.intp]:
    """Indices of glitches (isolated outliers) of a signal.

    A sample is a glitch when it departs from the running median of ``window`` samples by
    more than ``threshold`` robust standard deviations (1.4826 x the median absolute
    deviation of the signal minus its running median) and by more than ``min_fraction`` of
    the signal's range (so the corners of a clean triangle wave, which a running median
    rounds off, are not glitches). Glitches up to ``window // 2`` samples long are found.

    Parameters
    ----------
    signal : array_like
        The signal (usually the measured output).
    window : int
        Odd length of the running median, >= 3 (default 11).
    threshold : float
        Robust standard deviations that make a glitch (default 8).
    min_fraction : float
        Smallest glitch, as a fraction of the signal's range (default 0.02).

    Returns
    -------
    ndarray of int
        The glitches' indices, increasing.

    Examples
    --------
    >>> import numpy as np
    >>> y = np.sin(np.linspace(0, 6, 500))
    >>> y[[100, 101, 300]] += [3.0, 2.5, -4.0]
    >>> flag_outliers(y).tolist()
    [100, 101, 300]
    """
    from scipy.ndimage import median_filter

    y = as_record(signal, "signal", min_length=3)
    w = as_int(window, "window", minimum=3)
    if w % 2 == 0:
        raise ParameterError(f"window = {w} must be odd")
    k = as_scalar(threshold, "threshold", positive=True)
    frac = as_scalar(min_fraction, "min_fraction", positive=False)
    if frac < 0:
        raise ParameterError(f"min_fraction = {frac:g} must be >= 0")
    r = y - median_filter(y, size=w, mode="nearest")
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    lo, hi = np.percentile(y, [0.5, 99.5])
    limit = max(k * sigma, frac * float(hi - lo))
    flagged = np.flatnonzero(np.abs(r) > limit)
    if flagged.size:
        # a glitch shifts the running median of its neighbours by a rank: score every sample
        # again against the running median of the signal with the glitches interpolated over
        clean = replace_outliers(y, flagged)
        r = y - median_filter(clean, size=w, mode="nearest")
        flagged = np.flatnonzero(np.abs(r) > limit)
    return flagged


def replace_outliers(signal: npt.ArrayLike, indices: npt.ArrayLike) -> FloatArray:
    """The signal with the samples at ``indices`` replaced by linear interpolation between
    their nearest good neighbours (the ends: the nearest good value). Keeps the time axis
    continuous, as a dynamic model needs.

    Parameters
    ----------
    signal : array_like
        The samples.
    indices : array_like of int
        The samples to replace.

    Returns
    -------
    ndarray

    Examples
    --------
    >>> import numpy as np
    >>> replace_outliers(np.array([0.0, 1.0, 9.0, 3.0, 4.0]), [2]).tolist()
    [0.0, 1.0, 2.0, 3.0, 4.0]
    """
    y = as_record(signal, "signal", min_length=2)
    idx = np.asarray(indices)
    if idx.size == 0:
        return y
    if idx.dtype.kind not in "iu" or idx.ndim != 1:
        raise ParameterTypeError("indices must be a 1-D array of int sample indices")
    if idx.min() < 0 or idx.max() >= y.size:
        raise ParameterError(f"indices must lie in 0 ... {y.size - 1}, got {int(idx.min())} ... {int(idx.max())}")
    good = np.ones(y.size, dtype=bool)
    good[idx] = False
    if not good.any():
        raise DataError("every sample is an outlier: nothing to interpolate from")
    pos = np.arange(y.size)
    out = y.copy()
    out[~good] = np.interp(pos[~good], pos[good], y[good])
    return out


# --------------------------------------------------------------------------------------
# decimation


def decimate(record: Record, factor: int) -> Record:
    """Reduce the sample rate by an integer ``factor`` with an anti-alias filter.

    Both channels go through the same linear-phase FIR low-pass (:func:`scipy.signal.resample_poly`,
    Kaiser window, cut-off at the new Nyquist frequency) whose group delay is compensated,
    so the result is zero-phase: no delay between input and output is introduced, and a
    hysteresis loop keeps its shape. The record's ends are extended by a straight line
    (``padtype="line"``) so an offset does not ring into the first samples. An IIR filter
    run forward and backward (``filtfilt``) would also be zero-phase, but squares its
    magnitude response and needs long edge transients; the FIR is exact, stable and
    standard. Sample ``j`` of the result is sample ``j * factor`` of the record.

    Parameters
    ----------
    record : Record
        The record to decimate.
    factor : int
        Keep every ``factor``-th sample (>= 1).

    Returns
    -------
    Record

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals import Record
    >>> t = np.arange(10000) / 10000.0
    >>> u = np.sin(2 * np.pi * 5 * t) + 0.3 * np.sin(2 * np.pi * 4990 * t)
    >>> d = decimate(Record(u, u, fs=10000.0), 10)
    >>> d.n, d.fs, bool(np.max(np.abs(d.input - np.sin(2 * np.pi * 5 * t[::10]))) < 0.01)
    (1000, 1000.0, True)
    """
    from scipy.signal import resample_poly

    rec = _record(record)
    q = as_int(factor, "factor", minimum=1)
    if q == 1:
        return rec
    if rec.n // q < 2:
        raise ParameterError(f"factor = {q} leaves {rec.n // q} samples of a {rec.n}-sample record")
    u = resample_poly(rec.input, 1, q, padtype="line")
    y = resample_poly(rec.output, 1, q, padtype="line")
    m = u.size
    t = None if rec.time is None else rec.time[::q][:m]
    return _with(rec, u, y, t, fs=rec.fs / q)


_decimate = decimate  # preprocess's keyword ``decimate`` hides the function


# --------------------------------------------------------------------------------------
# all of them


def _check_choice(value: object, name: str, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise ParameterError(f"{name} = {value!r} must be one of {', '.join(repr(c) for c in choices)}")
    return value


def preprocess(
    record: Record,
    *,
    lag: int | str = 0,
    drift: str = "none",
    lead_in: int | str = "none",
    outliers: str = "none",
    decimate: int = 1,
    max_lag: int | None = None,
    drift_order: int = 1,
) -> tuple[Record, dict[str, Any]]:
    """Apply the preprocessing steps to a record, in the module's order: outliers, lead-in,
    lag, drift, decimation.

    Parameters
    ----------
    record : Record
    lag : int or "auto"
        Input→output delay in samples to remove (``0``: none, the default), or ``"auto"``:
        :func:`estimate_lag` up to ``max_lag``.
    drift : {"none", "remove"}
        ``"remove"``: :func:`remove_drift` of order ``drift_order`` (fitted with the input).
    lead_in : "none", "auto" or int
        ``"auto"``: drop the samples before :func:`find_excitation_start`; an int: drop that
        many samples.
    outliers : {"none", "flag", "replace", "drop"}
        ``"flag"``: report the glitches of the output (:func:`flag_outliers`) and leave them;
        ``"replace"``: also replace them by linear interpolation (:func:`replace_outliers`).
        ``"drop"`` is the same as ``"replace"``: removing samples would break the time axis a
        dynamic model needs, so they are interpolated over instead (the report says so).
    decimate : int
        Keep every ``decimate``-th sample after an anti-alias filter (:func:`decimate`).
    max_lag : int, optional
        ``lag="auto"``: the largest delay searched (default: 2 % of a second of samples,
        at least 10, at most a fifth of the record).
    drift_order : int
        Degree of the drift polynomial (default 1).

    Returns
    -------
    record : Record
        The processed record.
    report : dict
        What was done, JSON-ready: ``steps`` (the steps applied, in order), one entry per
        step (``outliers``, ``lead_in``, ``lag``, ``drift``, ``decimate``) and ``index``:
        ``{"start": s, "step": q}`` — sample ``j`` of the processed record is sample
        ``s + j * q`` of the input record (see :func:`processed_index`).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals import Record
    >>> rec = Record(np.sin(np.arange(100) / 5), np.sin(np.arange(100) / 5), fs=50.0)
    >>> out, report = preprocess(rec)
    >>> out is rec, report["steps"], report["index"]
    (True, [], {'start': 0, 'step': 1})
    """
    rec = _record(record)
    drift = _check_choice(drift, "drift", ("none", "remove"))
    outliers = _check_choice(outliers, "outliers", ("none", "flag", "replace", "drop"))
    q = as_int(decimate, "decimate", minimum=1)
    order = as_int(drift_order, "drift_order", minimum=1)
    if isinstance(lag, str):
        if lag != "auto":
            raise ParameterError(f"lag = {lag!r} must be 'auto' or an int number of samples")
    elif isinstance(lag, bool) or not isinstance(lag, (int, np.integer)):
        raise ParameterTypeError(f"lag must be 'auto' or an int number of samples, got {lag!r}")
    if isinstance(lead_in, str):
        if lead_in not in ("none", "auto"):
            raise ParameterError(f"lead_in = {lead_in!r} must be 'none', 'auto' or an int number of samples")
    else:
        lead_in = as_int(lead_in, "lead_in", minimum=0)
    report: dict[str, Any] = {
        "steps": [],
        "outliers": None,
        "lead_in": None,
        "lag": None,
        "drift": None,
        "decimate": None,
        "index": {"start": 0, "step": 1},
    }
    start = 0
    if outliers != "none":
        idx = flag_outliers(rec.output)
        replaced = outliers in ("replace", "drop") and idx.size > 0
        if replaced:
            rec = _with(rec, rec.input, replace_outliers(rec.output, idx), rec.time)
        report["outliers"] = {
            "mode": outliers,
            "count": int(idx.size),
            "rows": idx.tolist(),
            "replaced": "linear interpolation" if replaced else None,
        }
        report["steps"].append("outliers")
    if lead_in != "none":
        k = find_excitation_start(rec.input, rec.fs) if lead_in == "auto" else int(lead_in)
        if k and rec.n - k < 2:
            raise ParameterError(f"lead_in = {k} leaves {rec.n - k} samples of a {rec.n}-sample record")
        if k:
            rec = rec.trim(k)
        start += k
        report["lead_in"] = {"mode": "auto" if lead_in == "auto" else "given", "samples": k, "seconds": k / rec.fs}
        report["steps"].append("lead_in")
    if lag == "auto" or lag != 0:
        if lag == "auto":
            m = max_lag
            if m is None:
                m = min(max(10, round(0.02 * rec.fs)), (rec.n - 1) // 5)
            k = estimate_lag(rec.input, rec.output, m)
        else:
            k = int(lag)
            m = None
        rec = apply_lag(rec, k)
        start += max(0, -k)
        report["lag"] = {
            "mode": "auto" if lag == "auto" else "given",
            "samples": k,
            "seconds": k / rec.fs,
            "max_lag": m,
        }
        report["steps"].append("lag")
    if drift == "remove":
        corrected, d = remove_drift(rec.output, rec.fs, input=rec.input, order=order)
        rec = _with(rec, rec.input, corrected, rec.time)
        report["drift"] = {
            "order": order,
            "change": float(d[-1]),
            "max_abs": float(np.max(np.abs(d))),
            "fitted_with": "input (play operators, powers 2 to 5)",
        }
        report["steps"].append("drift")
    if q > 1:
        fs0 = rec.fs
        rec = _decimate(rec, q)
        report["decimate"] = {"factor": q, "fs_in": fs0, "fs_out": rec.fs, "filter": "FIR (Kaiser), zero-phase"}
        report["steps"].append("decimate")
    report["index"] = {"start": start, "step": q}
    return rec, report


def processed_index(report: dict[str, Any], index: int) -> int:
    """The sample of the processed record that sample ``index`` of the input record maps to
    (rounded up; clipped to ``0`` when it falls inside a dropped lead-in), from the
    ``report`` of :func:`preprocess`.

    Parameters
    ----------
    report : dict
        The report :func:`preprocess` returned.
    index : int
        A sample of the input record.

    Returns
    -------
    int

    Examples
    --------
    >>> processed_index({"index": {"start": 100, "step": 4}}, 502)
    101
    """
    s = int(report["index"]["start"])
    q = int(report["index"]["step"])
    i = as_int(index, "index", minimum=0)
    return max(0, math.ceil((i - s) / q))
