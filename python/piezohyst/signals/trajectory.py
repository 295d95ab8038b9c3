"""Motion references a practitioner shapes before a loop sees them: jerk-limited point-to-point
moves (the seven-segment "S-curve": jerk, acceleration and velocity bounded) and input
shaping (zero-vibration shapers that cancel a lightly damped mode's residual vibration).
Vectorized numpy: the few segment boundaries are computed in Python, every sample at once.

Examples
--------
>>> import numpy as np
>>> from piezohyst.signals.trajectory import jerk_limited, input_shaper
>>> t, x, v, a = jerk_limited(2e-6, 18.5e-6, fs=1e4, max_velocity=5e-3, max_acceleration=20.0, max_jerk=1e5)
>>> round(float(x[0]) * 1e6, 6), round(float(x[-1]) * 1e6, 6), bool(np.max(v) <= 5e-3 + 1e-12)
(2.0, 18.5, True)
>>> shaped = input_shaper(np.r_[np.zeros(10), np.ones(200)], fs=1e4, frequency=400.0, damping=0.01)
>>> round(float(shaped[-1]), 12)                       # the same final value
1.0
"""

from __future__ import annotations

import math
from typing import TypeAlias

import numpy as np
import numpy.typing as npt

from .._validate import as_record, as_scalar
from ..errors import ParameterError

FloatArray: TypeAlias = npt.NDArray[np.float64]

__all__ = ["input_shaper", "jerk_limited", "shaper_impulses"]


def _rise(v: float, a_max: float, j_max: float) -> tuple[float, float]:
    """``(Tj, Ta)``: jerk time and acceleration time to reach velocity ``v`` from rest."""
    if v * j_max >= a_max * a_max:
        tj = a_max / j_max
        return tj, tj + v / a_max
    tj = math.sqrt(v / j_max)
    return tj, 2 * tj


def jerk_limited(
    start: float,
    end: float,
    *,
    fs: float,
    max_velocity: float,
    max_acceleration: float,
    max_jerk: float,
    hold: float = 0.0,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """A jerk-limited move from ``start`` to ``end`` (the seven-segment S-curve, from rest to
    rest): the jerk is ``+-max_jerk`` or 0, and the acceleration and velocity never exceed
    their bounds. When the distance is too short to reach ``max_velocity`` the peak velocity
    is lowered (bisection on the distance the rise and the fall cover).

    Parameters
    ----------
    start, end : float
        Positions (m).
    fs : float
        Sample rate, Hz.
    max_velocity, max_acceleration, max_jerk : float
        Bounds (m/s, m/s^2, m/s^3), > 0.
    hold : float
        Seconds at ``end`` after the move (default 0).

    Returns
    -------
    t, position, velocity, acceleration : ndarray
        One value per sample from 0 (the move's duration rounded up to a sample, then
        ``hold``); the velocity and acceleration are the exact ones (pass them to a closed
        loop as the reference's derivatives).

    Examples
    --------
    >>> from piezohyst.signals.trajectory import jerk_limited
    >>> t, x, v, a = jerk_limited(0.0, 1e-5, fs=1e5, max_velocity=1e-2, max_acceleration=10.0, max_jerk=1e5)
    >>> round(float(t[-1]) * 1e3, 2), round(float(max(abs(a))), 6)    # ms (too short for 1 cm/s)
    (2.11, 10.0)
    """
    q0, q1 = as_scalar(start, "start"), as_scalar(end, "end")
    fs = as_scalar(fs, "fs", positive=True)
    v_max = as_scalar(max_velocity, "max_velocity", positive=True)
    a_max = as_scalar(max_acceleration, "max_acceleration", positive=True)
    j_max = as_scalar(max_jerk, "max_jerk", positive=True)
    rest = as_scalar(hold, "hold", nonnegative=True)
    h = abs(q1 - q0)
    sign = 1.0 if q1 >= q0 else -1.0
    tj, ta = _rise(v_max, a_max, j_max)
    v_peak = v_max
    if h > 0 and v_max * ta > h:
        # the bounds' velocity is not reached: the largest peak velocity whose rise and fall
        # (each covering v ta / 2) fit in h
        lo, hi = 0.0, v_max
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid * _rise(mid, a_max, j_max)[1] > h:
                hi = mid
            else:
                lo = mid
        v_peak = lo
        tj, ta = _rise(v_peak, a_max, j_max)
    tv = h / v_peak - ta if h > 0 else 0.0
    tv = max(tv, 0.0)
    a_peak = j_max * tj
    # the seven segments: (duration, jerk)
    segments = [
        (tj, j_max),
        (ta - 2 * tj, 0.0),
        (tj, -j_max),
        (tv, 0.0),
        (tj, -j_max),
        (ta - 2 * tj, 0.0),
        (tj, j_max),
    ]
    if h == 0:
        segments = []
    starts = [0.0]
    states = [(0.0, 0.0, 0.0)]  # (position from q0, velocity, acceleration) at each start
    for dur, jerk in segments:
        p, v, acc = states[-1]
        states.append(
            (
                p + v * dur + acc * dur * dur / 2 + jerk * dur**3 / 6,
                v + acc * dur + jerk * dur * dur / 2,
                acc + jerk * dur,
            )
        )
        starts.append(starts[-1] + dur)
    duration = starts[-1]
    n = math.ceil(duration * fs - 1e-9) + 1 + round(rest * fs)
    t = np.arange(n) / fs
    jerks = np.array([j for _, j in segments] + [0.0])
    k = np.clip(np.searchsorted(np.array(starts[1:]), t, side="right"), 0, len(segments))
    st = np.array(states)
    tau = t - np.array(starts)[k]
    if segments:
        tau = np.where(k == len(segments), t - duration, tau)
    p0, v0, a0, jj = st[k, 0], st[k, 1], st[k, 2], jerks[k]
    pos = p0 + v0 * tau + a0 * tau**2 / 2 + jj * tau**3 / 6
    vel = v0 + a0 * tau + jj * tau**2 / 2
    acc = a0 + jj * tau
    done = t >= duration
    pos[done], vel[done], acc[done] = h, 0.0, 0.0
    if a_peak > a_max * (1 + 1e-9):  # pragma: no cover - guards the algebra above
        raise ParameterError("internal: the acceleration bound is exceeded")
    return t, q0 + sign * pos, sign * vel, sign * acc


def shaper_impulses(frequency: float, damping: float = 0.0, kind: str = "zv") -> tuple[FloatArray, FloatArray]:
    """The impulses of a zero-vibration input shaper for a mode at ``frequency`` (Hz) with
    ``damping`` ratio: ``"zv"`` (two impulses over half a damped period), ``"zvd"`` (three,
    robust to a frequency error), ``"zvdd"`` (four, more robust still). The amplitudes sum to 1.

    Parameters
    ----------
    frequency : float
        The mode's natural frequency, Hz.
    damping : float
        Its damping ratio, ``0 <= damping < 1``.
    kind : {"zv", "zvd", "zvdd"}

    Returns
    -------
    times, amplitudes : ndarray
        Seconds from the first impulse, and the weights.

    Examples
    --------
    >>> from piezohyst.signals.trajectory import shaper_impulses
    >>> t, a = shaper_impulses(100.0, 0.0, "zvd")
    >>> (t * 1e3).round(6).tolist(), a.tolist()
    ([0.0, 5.0, 10.0], [0.25, 0.5, 0.25])
    """
    f = as_scalar(frequency, "frequency", positive=True)
    z = as_scalar(damping, "damping", nonnegative=True)
    if not z < 1:
        raise ParameterError(f"damping = {z} must be < 1")
    order = {"zv": 1, "zvd": 2, "zvdd": 3}.get(kind)
    if order is None:
        raise ParameterError(f"kind = {kind!r} must be 'zv', 'zvd' or 'zvdd'")
    k = math.exp(-z * math.pi / math.sqrt(1 - z * z))
    half = 0.5 / (f * math.sqrt(1 - z * z))
    amps = np.array([math.comb(order, i) * k**i for i in range(order + 1)])
    times = np.arange(order + 1, dtype=np.float64) * half
    return times, np.asarray(amps / amps.sum(), dtype=np.float64)


def input_shaper(
    reference: npt.ArrayLike, *, fs: float, frequency: float, damping: float = 0.0, kind: str = "zv"
) -> FloatArray:
    """``reference`` convolved with a zero-vibration shaper (:func:`shaper_impulses`): a move
    through it leaves no residual vibration of the mode (``frequency`` Hz, ``damping``), at the
    price of a delay of half a period (ZV) or one period (ZVD). Impulses between samples are
    split linearly between the two neighbours; the output has the reference's length (the
    tail holds the last value's shaping).

    Parameters
    ----------
    reference : array_like
        One value per sample.
    fs : float
        Sample rate, Hz.
    frequency, damping : float
        The mode to cancel.
    kind : {"zv", "zvd", "zvdd"}

    Returns
    -------
    ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals.trajectory import input_shaper
    >>> input_shaper(np.r_[0.0, np.ones(5)], fs=1000.0, frequency=250.0).tolist()   # ZV: half at 2 ms
    [0.0, 0.5, 0.5, 1.0, 1.0, 1.0]
    """
    x = as_record(reference, "reference", min_length=1)
    fs = as_scalar(fs, "fs", positive=True)
    times, amps = shaper_impulses(frequency, damping, kind)
    pos = times * fs
    kernel = np.zeros(math.floor(pos[-1]) + 2)
    for p, a in zip(pos, amps, strict=True):
        i = math.floor(p)
        w = p - i
        kernel[i] += a * (1 - w)
        kernel[i + 1] += a * w
    padded = np.r_[np.full(kernel.size, x[0]), x]
    out = np.convolve(padded, kernel)[kernel.size : kernel.size + x.size]
    return np.asarray(out, dtype=np.float64)
