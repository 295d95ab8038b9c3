"""Reference signals (docs/spec.md §6).

Every generator returns ``(t, x)``: two 1-D float64 arrays of equal length, with
``t = arange(n) / fs`` (so ``t[0] == 0`` and the spacing is exactly ``1 / fs``) and ``x``
the reference in the caller's units (volts, micrometres, ...). The number of samples is
``n = round(duration * fs)`` and must be at least 2.

Generators
----------
sine                    ``offset + amplitude sin(2 pi freq t + phase)``
triangle                triangle wave with optionally rounded (smooth) turn-arounds
variable_amplitude_sine sine under a decaying envelope: nested minor loops (seed 2)
multisine               random-phase multisine with a flat amplitude spectrum over a band
chirp                   linear or logarithmic frequency sweep
staircase               piecewise-constant levels held for a dwell time

Bad input raises :class:`ValueError` (NaN/Inf, fewer than 2 samples, non-positive ``fs`` or
frequency, frequencies above the Nyquist frequency ``fs / 2``, ``f_min >= f_max``,
``rounding`` outside [0, 1], empty ``levels``) or :class:`TypeError` (wrong types); the
message names the argument and the value. Random signals take an ``rng`` (an int seed or a
:class:`numpy.random.Generator`); the global NumPy random state is never used.

Examples
--------
>>> from piezohyst.references import triangle
>>> t, x = triangle(freq=1.0, amplitude=2.0, duration=1.0, fs=8.0)
>>> t.tolist()
[0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875]
>>> x.tolist()
[-2.0, -1.0, 0.0, 1.0, 2.0, 1.0, 0.0, -1.0]
"""

from __future__ import annotations

import numbers

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_scalar, as_vector
from ..errors import ParameterError, ParameterTypeError

FloatArray = npt.NDArray[np.float64]
#: What every generator returns: the sample times and the signal.
Reference = tuple[FloatArray, FloatArray]

__all__ = ["chirp", "multisine", "sine", "staircase", "triangle", "variable_amplitude_sine"]


# --------------------------------------------------------------------------- helpers


#: Longest reference, samples (16 GB as float64): beyond it a typo in ``duration`` or ``fs``
#: is far more likely than a wish, and numpy would fail with a bare MemoryError.
MAX_SAMPLES = 2**31


def _n_samples(duration: float, fs: float, name: str = "duration") -> tuple[int, float]:
    duration = as_scalar(duration, name, positive=True)
    fs = as_scalar(fs, "fs", positive=True)
    n = duration * fs
    if not np.isfinite(n) or round(n) < 2:
        raise ParameterError(f"{name} * fs = {duration} * {fs} = {n} gives fewer than 2 samples")
    if n > MAX_SAMPLES:
        raise ParameterError(f"{name} * fs = {duration} * {fs} = {n:.4g} samples is more than {MAX_SAMPLES:.4g}")
    return round(n), fs


def _time(duration: float, fs: float) -> tuple[FloatArray, float]:
    n, fs = _n_samples(duration, fs)
    return np.arange(n) / fs, fs


def _frequency(value: float, name: str, fs: float) -> float:
    """A positive frequency not above the Nyquist frequency ``fs / 2``."""
    f = as_scalar(value, name, positive=True)
    if f > fs / 2:
        raise ParameterError(f"{name} = {f} is above the Nyquist frequency fs / 2 = {fs / 2}")
    return f


def _rng(rng: object) -> np.random.Generator:
    if rng is None or isinstance(rng, np.random.Generator):
        return np.random.default_rng(rng)
    if isinstance(rng, bool) or not isinstance(rng, (numbers.Integral, np.integer)):
        raise ParameterTypeError(f"rng must be None, an int seed or a numpy.random.Generator, got {rng!r}")
    if rng < 0:
        raise ParameterError(f"rng = {rng} must be a non-negative seed")
    return np.random.default_rng(int(rng))


def _choice(value: object, name: str, options: tuple[str, ...]) -> str:
    if not isinstance(value, str):
        raise ParameterTypeError(f"{name} must be one of {options}, got {value!r}")
    if value not in options:
        raise ParameterError(f"{name} = {value!r} must be one of {options}")
    return value


# --------------------------------------------------------------------------- periodic


def sine(
    freq: float, amplitude: float, duration: float, fs: float, offset: float = 0.0, phase: float = -np.pi / 2
) -> Reference:
    """Sine wave ``offset + amplitude * sin(2 pi freq t + phase)``.

    Parameters
    ----------
    freq : float
        Frequency in Hz, ``0 < freq <= fs / 2``.
    amplitude : float
        Amplitude (half the peak-to-peak value), ``>= 0``.
    duration : float
        Length in seconds; ``round(duration * fs)`` samples (at least 2).
    fs : float
        Sample rate in Hz, ``> 0``.
    offset : float, optional
        Centre value.
    phase : float, optional
        Phase in radians. The default ``-pi/2`` starts at the minimum ``offset - amplitude``,
        which suits a unipolar piezo drive starting from rest.

    Returns
    -------
    t, x : ndarray of float64
        Sample times (from 0, spacing ``1/fs``) and the signal.

    Examples
    --------
    >>> t, x = sine(freq=1.0, amplitude=1.0, duration=1.0, fs=4.0, offset=2.0)
    >>> (np.round(x, 12) + 0.0).tolist()  # + 0.0 turns -0.0 into 0.0
    [1.0, 2.0, 3.0, 2.0]
    """
    t, fs = _time(duration, fs)
    f = _frequency(freq, "freq", fs)
    a = as_scalar(amplitude, "amplitude", nonnegative=True)
    c = as_scalar(offset, "offset")
    p = as_scalar(phase, "phase")
    return t, c + a * np.sin(2 * np.pi * f * t + p)


def triangle(
    freq: float,
    amplitude: float,
    duration: float,
    fs: float,
    offset: float = 0.0,
    phase: float = -np.pi / 2,
    rounding: float = 0.0,
) -> Reference:
    """Triangle wave, optionally with smooth (rounded) turn-arounds.

    The wave is the triangular counterpart of :func:`sine` with the same ``phase``: it has
    its minima where ``sin(2 pi freq t + phase) = -1`` and its maxima where it is ``+1``
    (the default phase starts at the minimum), ranges over
    ``[offset - amplitude, offset + amplitude]`` and has the period ``1 / freq``.

    **Sharp** (``rounding = 0``): straight ramps of slope ``+-4 * amplitude * freq``.

    **Rounded** (``0 < rounding <= 1``): each turn-around is replaced by a blend of duration
    ``w = rounding * T/2`` (``T = 1/freq``; ``T/2`` is the time of one ramp) centred on the
    corner, during which the velocity follows half a cosine from ``+s`` to ``-s`` (or back)::

        v(tau) = -s * sin(pi * tau / w),   -w/2 <= tau <= w/2,   tau = time from the corner

    so that position, velocity *and* acceleration are continuous (the acceleration is 0 at
    both ends of the blend; its peak is ``pi * s / w``). Rounding lowers the corners by
    ``s * w * (1/2 - 1/pi)``; the whole wave is then rescaled so that the extremes are again
    exactly ``offset +- amplitude``. The period and the peak-to-peak value are therefore
    unchanged, and the straight parts are steeper than in the sharp wave::

        s = 4 * amplitude * freq / (1 - rounding * (1 - 2/pi))

    ``rounding = 1`` leaves no straight part and gives exactly :func:`sine`.

    Parameters
    ----------
    freq : float
        Frequency in Hz, ``0 < freq <= fs / 2``.
    amplitude : float
        Half the peak-to-peak value, ``>= 0``.
    duration, fs : float
        Length in seconds and sample rate in Hz (at least 2 samples).
    offset : float, optional
        Centre value.
    phase : float, optional
        Phase in radians, as in :func:`sine`.
    rounding : float, optional
        Fraction of the half period ``T/2`` spent in each turn-around blend, in ``[0, 1]``.

    Returns
    -------
    t, x : ndarray of float64

    Examples
    --------
    >>> t, x = triangle(freq=1.0, amplitude=1.0, duration=1.0, fs=8.0, offset=1.0)
    >>> x.tolist()
    [0.0, 0.5, 1.0, 1.5, 2.0, 1.5, 1.0, 0.5]
    >>> t, x = triangle(freq=1.0, amplitude=1.0, duration=1.0, fs=1000.0, rounding=0.5)
    >>> float(x.max()), float(x.min())
    (1.0, -1.0)
    >>> t, xs = sine(1.0, 1.0, 1.0, 1000.0)
    >>> t, xr = triangle(1.0, 1.0, 1.0, 1000.0, rounding=1.0)
    >>> bool(np.allclose(xr, xs, atol=1e-12))
    True
    """
    t, fs = _time(duration, fs)
    f = _frequency(freq, "freq", fs)
    a = as_scalar(amplitude, "amplitude", nonnegative=True)
    c = as_scalar(offset, "offset")
    p = as_scalar(phase, "phase")
    r = as_scalar(rounding, "rounding")
    if not 0.0 <= r <= 1.0:
        raise ParameterError(f"rounding = {r} must be in [0, 1]")

    # Position within the period, in periods: 0 at a minimum, 1/2 at a maximum.
    u = np.mod(f * t + p / (2 * np.pi) + 0.25, 1.0)
    g = 1.0 - 4.0 * np.abs(u - 0.5)  # unit sharp triangle, slope +-4 per period
    if r > 0.0:
        w = 0.5 * r  # blend width in periods
        delta = np.minimum(np.abs(u - 0.5), np.minimum(u, 1.0 - u))  # distance to nearest corner
        sign = np.where(np.abs(u - 0.5) < 0.25, 1.0, -1.0)  # +1 near a maximum, -1 near a minimum
        s = 4.0
        top = 1.0 - s * w * (0.5 - 1.0 / np.pi)  # height of the rounded corner
        blend = delta < w / 2
        g = np.where(blend, sign * (top + s * w / np.pi * (np.cos(np.pi * delta / w) - 1.0)), g) / top
    return t, c + a * g


def variable_amplitude_sine(
    freq: float,
    amplitude: float,
    duration: float,
    fs: float,
    offset: float = 0.0,
    final_fraction: float = 0.2,
    envelope: str = "linear",
) -> Reference:
    """Sine under a decaying envelope: nested minor loops, as in seed 2's experiments.

    ``x = offset + amplitude * e(t) * sin(2 pi freq t)`` with ``e(0) = 1`` and
    ``e(t_end) = final_fraction`` (``t_end = t[-1]``, the last sample):

    * ``envelope="linear"``: ``e = 1 - (1 - final_fraction) * t / t_end``
    * ``envelope="exponential"``: ``e = final_fraction ** (t / t_end)`` (needs
      ``final_fraction > 0``)

    The signal starts at ``offset`` and each cycle turns around inside the previous one, so
    the hysteresis traces nested minor loops.

    Parameters
    ----------
    freq : float
        Frequency in Hz, ``0 < freq <= fs / 2``.
    amplitude : float
        Initial amplitude, ``>= 0``.
    duration, fs : float
        Length in seconds and sample rate in Hz (at least 2 samples).
    offset : float, optional
        Centre value.
    final_fraction : float, optional
        Envelope at the last sample relative to the start, in ``[0, 1]``.
    envelope : {"linear", "exponential"}, optional
        Shape of the decay.

    Returns
    -------
    t, x : ndarray of float64

    Examples
    --------
    >>> t, x = variable_amplitude_sine(1.0, 1.0, 2.25, 4.0, final_fraction=0.5)
    >>> (np.round(x, 12) + 0.0).tolist()  # + 0.0 turns -0.0 into 0.0
    [0.0, 0.9375, 0.0, -0.8125, 0.0, 0.6875, 0.0, -0.5625, 0.0]
    """
    t, fs = _time(duration, fs)
    f = _frequency(freq, "freq", fs)
    a = as_scalar(amplitude, "amplitude", nonnegative=True)
    c = as_scalar(offset, "offset")
    ff = as_scalar(final_fraction, "final_fraction")
    if not 0.0 <= ff <= 1.0:
        raise ParameterError(f"final_fraction = {ff} must be in [0, 1]")
    kind = _choice(envelope, "envelope", ("linear", "exponential"))
    if kind == "linear":
        env = 1.0 - (1.0 - ff) * t / t[-1]
    else:
        frac = t / t[-1]
        if ff == 0.0:
            raise ParameterError("final_fraction = 0.0 must be > 0 for envelope='exponential'")
        env = ff**frac
    return t, c + a * env * np.sin(2 * np.pi * f * t)


# --------------------------------------------------------------------------- broadband


def multisine(
    f_min: float,
    f_max: float,
    amplitude: float,
    period: float,
    fs: float,
    *,
    periods: int = 1,
    scale: str = "rms",
    offset: float = 0.0,
    rng: int | np.random.Generator | None = None,
) -> Reference:
    """Random-phase multisine with a flat amplitude spectrum over ``[f_min, f_max]``.

    One period has ``N = round(period * fs)`` samples, so the frequency resolution is
    ``f0 = fs / N``. Every DFT bin ``k`` with ``f_min <= k f0 <= f_max`` and ``0 < k < N/2``
    (DC and the Nyquist bin are never excited) gets the same amplitude and an independent
    phase drawn uniformly from ``[0, 2 pi)``::

        x(t) = offset + a * sum_k cos(2 pi k f0 t + phi_k)

    ``a`` is chosen so that the RMS of ``x - offset`` (``scale="rms"``; over whole periods
    this is exact: ``a = amplitude * sqrt(2 / K)`` for ``K`` lines) or its maximum
    magnitude over the samples (``scale="peak"``) equals ``amplitude``. The signal is
    periodic: ``periods`` identical periods are concatenated, so the DFT of any whole
    period is exactly zero outside the excited bins (no leakage).

    Parameters
    ----------
    f_min, f_max : float
        Band edges in Hz, ``0 < f_min < f_max <= fs / 2``. At least one bin must fall in
        the band; lengthen ``period`` for a finer resolution.
    amplitude : float
        RMS or peak value of ``x - offset`` (see ``scale``), ``>= 0``.
    period : float
        Length of one period in seconds (at least 2 samples).
    fs : float
        Sample rate in Hz.
    periods : int, optional
        Number of periods, ``>= 1``.
    scale : {"rms", "peak"}, optional
        What ``amplitude`` means.
    offset : float, optional
        Centre value.
    rng : None, int or numpy.random.Generator, optional
        Source of the phases: a seed, a generator (which is advanced), or ``None`` for fresh
        OS entropy. The global NumPy random state is never used.

    Returns
    -------
    t, x : ndarray of float64
        ``periods * N`` samples.

    Examples
    --------
    >>> t, x = multisine(1.0, 20.0, 0.5, period=1.0, fs=100.0, periods=2, rng=7)
    >>> len(x), round(float(np.sqrt(np.mean(x ** 2))), 12)
    (200, 0.5)
    >>> spectrum = np.abs(np.fft.rfft(x[:100]))
    >>> int(np.count_nonzero(spectrum > 1e-9)), np.flatnonzero(spectrum > 1e-9)[[0, -1]].tolist()
    (20, [1, 20])
    >>> bool(np.array_equal(x, multisine(1.0, 20.0, 0.5, 1.0, 100.0, periods=2, rng=7)[1]))
    True
    """
    n, fs = _n_samples(period, fs, "period")
    lo = _frequency(f_min, "f_min", fs)
    hi = _frequency(f_max, "f_max", fs)
    if lo >= hi:
        raise ParameterError(f"f_min = {lo} must be < f_max = {hi}")
    a = as_scalar(amplitude, "amplitude", nonnegative=True)
    m = as_int(periods, "periods", minimum=1)
    kind = _choice(scale, "scale", ("rms", "peak"))
    c = as_scalar(offset, "offset")
    gen = _rng(rng)

    f0 = fs / n
    k = np.arange(1, (n + 1) // 2)  # 0 < k < N/2
    # A relative tolerance so that band edges given as exact multiples of f0 are included.
    k = k[(k * f0 >= lo * (1 - 1e-12)) & (k * f0 <= hi * (1 + 1e-12))]
    if k.size == 0:
        raise ParameterError(
            f"no frequency line of the resolution fs / N = {f0} Hz (period = {n / fs} s) lies in "
            f"[f_min, f_max] = [{lo}, {hi}] below the Nyquist frequency; lengthen period"
        )
    phases = gen.uniform(0.0, 2 * np.pi, size=k.size)
    spectrum = np.zeros(n // 2 + 1, dtype=np.complex128)
    spectrum[k] = np.exp(1j * phases)
    one = np.fft.irfft(spectrum, n=n) * (n / 2)  # sum_k cos(2 pi k f0 t + phi_k)
    if kind == "rms":
        norm = np.sqrt(np.mean(one**2))
    else:
        norm = np.max(np.abs(one))
    one *= a / norm
    return np.arange(n * m) / fs, c + np.tile(one, m)


def chirp(
    f_start: float,
    f_end: float,
    amplitude: float,
    duration: float,
    fs: float,
    *,
    method: str = "linear",
    offset: float = 0.0,
    phase: float = -np.pi / 2,
) -> Reference:
    """Frequency sweep from ``f_start`` at ``t = 0`` to ``f_end`` at the last sample.

    ``x = offset + amplitude * sin(phi(t) + phase)`` with ``phi(0) = 0`` and the
    instantaneous frequency ``f(t) = phi'(t) / (2 pi)``, ``T = t[-1]``:

    * ``method="linear"``: ``f(t) = f_start + (f_end - f_start) t / T``,
      ``phi = 2 pi (f_start t + (f_end - f_start) t^2 / (2 T))``
    * ``method="logarithmic"``: ``f(t) = f_start (f_end / f_start) ** (t / T)`` (constant
      time per octave), ``phi = 2 pi f_start T ((f_end/f_start) ** (t/T) - 1) / ln(f_end/f_start)``

    Down-sweeps (``f_end < f_start``) are allowed; ``f_end == f_start`` gives a sine.

    Parameters
    ----------
    f_start, f_end : float
        Frequencies in Hz at the first and the last sample, in ``(0, fs / 2]``.
    amplitude : float
        Amplitude, ``>= 0``.
    duration, fs : float
        Length in seconds and sample rate in Hz (at least 2 samples).
    method : {"linear", "logarithmic"}, optional
        Sweep law.
    offset : float, optional
        Centre value.
    phase : float, optional
        Phase in radians; the default ``-pi/2`` starts at the minimum as :func:`sine` does.

    Returns
    -------
    t, x : ndarray of float64

    Examples
    --------
    >>> t, x = chirp(1.0, 3.0, 1.0, duration=1.0 + 1e-3, fs=1000.0, phase=0.0)
    >>> float(t[-1])
    1.0
    >>> # phi(T) = 2 pi * (1 + 3) / 2 * T: two whole cycles, so the sweep ends at 0
    >>> abs(float(x[-1])) < 1e-9
    True
    """
    t, fs = _time(duration, fs)
    f1 = _frequency(f_start, "f_start", fs)
    f2 = _frequency(f_end, "f_end", fs)
    a = as_scalar(amplitude, "amplitude", nonnegative=True)
    kind = _choice(method, "method", ("linear", "logarithmic"))
    c = as_scalar(offset, "offset")
    p = as_scalar(phase, "phase")
    T = t[-1]
    if kind == "linear" or f1 == f2:
        phi = 2 * np.pi * (f1 * t + (f2 - f1) * t**2 / (2 * T))
    else:
        ratio = np.log(f2 / f1)
        phi = 2 * np.pi * f1 * T * np.expm1(ratio * t / T) / ratio
    return t, c + a * np.sin(phi + p)


# --------------------------------------------------------------------------- steps


def staircase(levels: npt.ArrayLike, dwell: npt.ArrayLike, fs: float, offset: float = 0.0) -> Reference:
    """Piecewise-constant reference: ``offset + levels[i]`` held for ``dwell`` seconds each.

    Level ``i`` occupies ``round(dwell_i * fs)`` consecutive samples (at least 1), in order;
    the total must be at least 2 samples. A step up and back down
    (``levels=[0, 1, 2, 1, 0]``) exposes the hysteresis; a long dwell exposes creep.

    Parameters
    ----------
    levels : array_like of float
        The levels, in order (non-empty, finite).
    dwell : float or array_like of float
        Time per level in seconds: one value for all levels or one per level (``> 0``).
    fs : float
        Sample rate in Hz.
    offset : float, optional
        Added to every level.

    Returns
    -------
    t, x : ndarray of float64

    Examples
    --------
    >>> t, x = staircase([0.0, 1.0, 0.5], dwell=0.5, fs=4.0, offset=10.0)
    >>> x.tolist()
    [10.0, 10.0, 11.0, 11.0, 10.5, 10.5]
    >>> staircase([1.0, 2.0], dwell=[0.25, 0.75], fs=4.0)[1].tolist()
    [1.0, 2.0, 2.0, 2.0]
    """
    lv = as_vector(levels, "levels")
    if lv.size == 0:
        raise ParameterError("levels is empty; at least one level is needed")
    fs = as_scalar(fs, "fs", positive=True)
    c = as_scalar(offset, "offset")
    if np.ndim(dwell) == 0 and not isinstance(dwell, (str, bytes)):
        d = np.full(lv.size, as_scalar(dwell, "dwell", positive=True))
    else:
        d = as_vector(dwell, "dwell", length=lv.size)
        bad = np.flatnonzero(~(d > 0))
        if bad.size:
            raise ParameterError(f"dwell[{bad[0]}] = {d[bad[0]]} must be > 0")
    counts = np.rint(d * fs)
    bad = np.flatnonzero(counts < 1)
    if bad.size:
        i = bad[0]
        raise ParameterError(f"dwell[{i}] = {d[i]} is shorter than one sample at fs = {fs} (dwell * fs < 0.5)")
    total = counts.sum()
    if not total <= MAX_SAMPLES:
        raise ParameterError(f"dwell * fs gives {total:.4g} samples in all, more than {MAX_SAMPLES:.4g}")
    if total < 2:
        raise ParameterError(f"levels and dwell give {int(total)} sample; at least 2 are needed")
    x = np.repeat(lv, counts.astype(np.int64))
    return np.arange(x.size) / fs, c + x
