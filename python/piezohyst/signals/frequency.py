"""Frequency responses: the result class (:class:`FrequencyResponse`: Bode and Nyquist
figures, peaks, python-control's ``FRD``), the excitations that measure one (a periodic
multisine with Schroeder phases, a logarithmic swept sine) and the estimate from a record
(:func:`frf_from_record`: a user's measured input and output, vectorized numpy/scipy).

Measuring the frequency response of a simulated stage or loop is
:func:`piezohyst.control.frequency.measure_frf`.

Examples
--------
>>> import numpy as np
>>> from piezohyst.signals.frequency import frf_from_record, multisine
>>> fs = 1000.0
>>> u, freqs = multisine(fs, 1000, (5.0, 200.0), periods=4, rng=0)
>>> y = 2.0 * np.roll(u, 1)                          # a gain of 2 and one sample of delay
>>> frf = frf_from_record(u, y, fs, period=1000)
>>> bool(np.allclose(np.abs(frf.response), 2.0))
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_record, as_scalar
from ..errors import ParameterError
from .results import DataclassMatFile, html_table, require_pandas

if TYPE_CHECKING:  # pragma: no cover - typing only
    import pandas as pd
    from matplotlib.figure import Figure

FloatArray: TypeAlias = npt.NDArray[np.float64]
ComplexArray: TypeAlias = npt.NDArray[np.complex128]

__all__ = ["FrequencyResponse", "frf_from_record", "multisine", "swept_sine"]


@dataclass(frozen=True, eq=False)
class FrequencyResponse(DataclassMatFile):
    """A measured (or computed) frequency response ``output / input`` at ``frequency`` (Hz).

    Parameters
    ----------
    frequency : array_like
        Frequencies, Hz, increasing.
    response : array_like of complex
        The response at each frequency (``output`` per ``input``, in ``unit``).
    coherence : array_like, optional
        Magnitude-squared coherence at each frequency (0..1), when estimated from a record.
    input, output : str
        Names of the signals (e.g. ``"command"``, ``"position"``).
    unit : str
        The response's unit (e.g. ``"m/V"``; ``""`` for a ratio).
    method : str
        How it was obtained (``"multisine"``, ``"swept sine"``, ``"stepped sine"``, ``"welch"``).
    title : str
        What was measured.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals.frequency import FrequencyResponse
    >>> f = np.array([10.0, 100.0, 1000.0])
    >>> h = FrequencyResponse(f, 1 / (1 + 1j * f / 100.0), title="low-pass")
    >>> h.magnitude_db.round(2).tolist()
    [-0.04, -3.01, -20.04]
    >>> h.peak()
    (10.0, 0.995037190209989)
    """

    frequency: FloatArray
    response: ComplexArray
    coherence: FloatArray | None = None
    input: str = "input"
    output: str = "output"
    unit: str = ""
    method: str = ""
    title: str = ""

    def __post_init__(self) -> None:
        f = as_record(self.frequency, "frequency", min_length=1)
        h = np.atleast_1d(np.asarray(self.response, dtype=np.complex128))
        if h.shape != f.shape:
            raise ParameterError(f"response has {h.size} values, frequency has {f.size}; they must match")
        if not np.all(np.isfinite(h)):
            k = int(np.flatnonzero(~np.isfinite(h))[0])
            raise ParameterError(f"response[{k}] = {h[k]} is not finite")
        if f.size > 1 and not np.all(np.diff(f) > 0):
            raise ParameterError("frequency must be increasing")
        object.__setattr__(self, "frequency", f)
        object.__setattr__(self, "response", h)
        if self.coherence is not None:
            c = as_record(self.coherence, "coherence", min_length=1)
            if c.shape != f.shape:
                raise ParameterError(f"coherence has {c.size} values, frequency has {f.size}; they must match")
            object.__setattr__(self, "coherence", c)

    @property
    def magnitude(self) -> FloatArray:
        """``|H|``."""
        return np.abs(self.response)

    @property
    def magnitude_db(self) -> FloatArray:
        """``20 log10 |H|``, dB."""
        return np.asarray(20 * np.log10(np.maximum(np.abs(self.response), 1e-300)))

    @property
    def phase_deg(self) -> FloatArray:
        """Phase, degrees, unwrapped along frequency."""
        return np.asarray(np.degrees(np.unwrap(np.angle(self.response))))

    def peak(self) -> tuple[float, float]:
        """The largest magnitude and its frequency (a sensitivity peak ``Ms``, a resonance).

        Returns
        -------
        tuple of float
            ``(frequency Hz, |H|)``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.signals.frequency import FrequencyResponse
        >>> FrequencyResponse([1.0, 2.0, 3.0], [1.0, 3.0j, 2.0]).peak()
        (2.0, 3.0)
        """
        k = int(np.argmax(np.abs(self.response)))
        return float(self.frequency[k]), float(np.abs(self.response[k]))

    def at(self, f: npt.ArrayLike) -> ComplexArray:
        """The response interpolated at ``f`` (Hz; magnitude and unwrapped phase linear in
        ``log f``), inside the measured band.

        Parameters
        ----------
        f : array_like
            Frequencies, Hz.

        Returns
        -------
        ndarray of complex

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.signals.frequency import FrequencyResponse
        >>> h = FrequencyResponse([1.0, 100.0], [1.0, 0.01])
        >>> round(float(abs(h.at([10.0])[0])), 6)
        0.1
        """
        q = np.atleast_1d(np.asarray(f, dtype=np.float64))
        lo, hi = self.frequency[0], self.frequency[-1]
        if np.any(q < lo * (1 - 1e-12)) or np.any(q > hi * (1 + 1e-12)):
            raise ParameterError(f"f must lie in the measured band [{lo:g}, {hi:g}] Hz")
        lf, lq = np.log(self.frequency), np.log(q)
        mag = np.exp(np.interp(lq, lf, np.log(np.maximum(self.magnitude, 1e-300))))
        ph = np.interp(lq, lf, np.unwrap(np.angle(self.response)))
        return np.asarray(mag * np.exp(1j * ph), dtype=np.complex128)

    def to_control(self) -> Any:
        """As a python-control frequency-response data object (``control.FRD``, omega in
        rad/s), for python-control's margin and Nyquist tools.

        Returns
        -------
        control.FRD

        Examples
        --------
        >>> from piezohyst.signals.frequency import FrequencyResponse
        >>> frd = FrequencyResponse([1.0, 2.0], [1.0, 0.5]).to_control()
        >>> frd.omega.round(4).tolist()
        [6.2832, 12.5664]
        """
        from .lti import require_control

        ct = require_control()
        return ct.frd(self.response, 2 * np.pi * self.frequency)

    def to_pandas(self) -> pd.DataFrame:
        """Frequency, magnitude (and dB), phase (degrees), real and imaginary parts and coherence
        as a ``pandas.DataFrame`` indexed by frequency (needs pandas).

        Returns
        -------
        pandas.DataFrame

        Examples
        --------
        >>> from piezohyst.signals.frequency import FrequencyResponse
        >>> df = FrequencyResponse([1.0, 2.0], [1.0, 0.5j]).to_pandas()      # doctest: +SKIP
        >>> list(df.columns)                                                  # doctest: +SKIP
        ['magnitude', 'magnitude_db', 'phase_deg', 'real', 'imag', 'coherence']
        """
        pd = require_pandas(type(self).__name__)
        cols: dict[str, Any] = {
            "magnitude": self.magnitude,
            "magnitude_db": self.magnitude_db,
            "phase_deg": self.phase_deg,
            "real": self.response.real,
            "imag": self.response.imag,
            "coherence": self.coherence if self.coherence is not None else np.full(self.frequency.size, np.nan),
        }
        return pd.DataFrame(cols, index=pd.Index(self.frequency, name="frequency_hz"))

    def plot(self, *, kind: str = "bode", ax: Any = None, label: str | None = None) -> Figure:
        """A Bode plot (magnitude in dB and phase against log frequency; ``kind="bode"``) or a
        Nyquist plot (``kind="nyquist"``: the response in the complex plane with its mirror,
        and the critical point -1).

        Parameters
        ----------
        kind : {"bode", "nyquist"}
        ax : matplotlib Axes, optional
            Two axes for a Bode plot, one for a Nyquist plot (default: a new figure), to
            overlay several responses.
        label : str, optional
            The curve's legend (default: ``title``).

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> import matplotlib
        >>> matplotlib.use("Agg")
        >>> from piezohyst.signals.frequency import FrequencyResponse
        >>> fig = FrequencyResponse([1.0, 10.0], [1.0, 0.5j]).plot()
        >>> len(fig.axes)
        2
        """
        import matplotlib.pyplot as plt

        name = label if label is not None else (self.title or None)
        if kind == "bode":
            if ax is None:
                fig, ax = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
            else:
                fig = ax[0].figure
            ax[0].semilogx(self.frequency, self.magnitude_db, label=name)
            ax[0].set_ylabel(f"|{self.output}/{self.input}| (dB{', ' + self.unit if self.unit else ''})")
            ax[1].semilogx(self.frequency, self.phase_deg)
            ax[1].set_ylabel("phase (deg)")
            ax[1].set_xlabel("frequency (Hz)")
            if name:
                ax[0].legend()
            return fig
        if kind == "nyquist":
            if ax is None:
                fig, ax = plt.subplots(figsize=(5, 5))
            else:
                fig = ax.figure
            h = self.response
            (line,) = ax.plot(h.real, h.imag, label=name)
            ax.plot(h.real, -h.imag, "--", color=line.get_color(), lw=0.8)
            ax.plot([-1], [0], "r+", ms=10)
            ax.set_xlabel("real")
            ax.set_ylabel("imaginary")
            ax.set_aspect("equal", adjustable="datalim")
            if name:
                ax.legend()
            return fig
        raise ParameterError(f"kind = {kind!r} must be 'bode' or 'nyquist'")

    def _repr_html_(self) -> str:
        f_pk, h_pk = self.peak()
        rows = [
            ("band", f"{self.frequency[0]:.4g} .. {self.frequency[-1]:.4g} Hz ({self.frequency.size} points)"),
            ("peak", f"{h_pk:.4g} {self.unit} at {f_pk:.4g} Hz"),
            ("method", self.method or "-"),
        ]
        if self.coherence is not None:
            rows.append(("coherence (min)", f"{float(np.min(self.coherence)):.3f}"))
        return html_table(self.title or f"{self.output} / {self.input}", rows)


def multisine(
    fs: float,
    period: int,
    band: tuple[float, float] | npt.ArrayLike,
    *,
    periods: int = 1,
    amplitude: float = 1.0,
    rng: int | np.random.Generator | None = None,
) -> tuple[FloatArray, FloatArray]:
    """A periodic multisine of ``period`` samples with equal amplitudes on the FFT bins of
    ``band`` and Schroeder phases (low crest factor), repeated ``periods`` times, scaled to a
    peak of ``amplitude``. Periodic excitation gives an FRF without leakage:
    :func:`frf_from_record` with ``period=``.

    Parameters
    ----------
    fs : float
        Sample rate, Hz.
    period : int
        Samples per period (the frequency resolution is ``fs / period``).
    band : (float, float) or array_like
        ``(f_min, f_max)`` Hz (every bin between, logarithmically thinned to at most 60), or
        the frequencies themselves (rounded to bins).
    periods : int
        Repetitions.
    amplitude : float
        Peak value.
    rng : int or Generator, optional
        Seed of a random phase offset (default: pure Schroeder phases).

    Returns
    -------
    signal : ndarray, shape (period * periods,)
    frequencies : ndarray
        The excited frequencies, Hz.

    Examples
    --------
    >>> from piezohyst.signals.frequency import multisine
    >>> u, f = multisine(1000.0, 1000, [10.0, 20.0, 40.0])
    >>> f.tolist(), round(float(abs(u).max()), 12)
    ([10.0, 20.0, 40.0], 1.0)
    """
    fs = as_scalar(fs, "fs", positive=True)
    n = as_int(period, "period", minimum=4)
    reps = as_int(periods, "periods", minimum=1)
    amp = as_scalar(amplitude, "amplitude", positive=True)
    df = fs / n
    b = np.atleast_1d(np.asarray(band, dtype=np.float64))
    if b.size == 2 and isinstance(band, tuple):
        lo, hi = float(b[0]), float(b[1])
        if not (0 < lo < hi < fs / 2):
            raise ParameterError(f"band = {band} must satisfy 0 < f_min < f_max < fs / 2 = {fs / 2:g}")
        k_lo, k_hi = max(1, math.ceil(lo / df)), math.floor(hi / df)
        if k_hi < k_lo:
            raise ParameterError(f"band = {band} holds no frequency of the resolution fs / period = {df:g} Hz")
        bins = np.unique(np.round(np.geomspace(k_lo, k_hi, min(60, k_hi - k_lo + 1))).astype(int))
    else:
        bins = np.unique(np.round(b / df).astype(int))
        if bins.size == 0 or bins[0] < 1 or bins[-1] >= n // 2:
            raise ParameterError(f"band frequencies must lie between fs / period = {df:g} Hz and fs / 2")
    m = bins.size
    phases = -np.pi * np.arange(m) * (np.arange(m) + 1) / m  # Schroeder
    if rng is not None:
        phases = phases + np.random.default_rng(rng).uniform(0, 2 * np.pi, m)
    spectrum = np.zeros(n // 2 + 1, dtype=np.complex128)
    spectrum[bins] = np.exp(1j * phases)
    one = np.fft.irfft(spectrum, n)
    one *= amp / np.max(np.abs(one))
    return np.tile(one, reps), bins * df


def swept_sine(fs: float, f0: float, f1: float, duration: float, *, amplitude: float = 1.0) -> FloatArray:
    """A logarithmic swept sine (chirp) from ``f0`` to ``f1`` Hz over ``duration`` s, peak
    ``amplitude`` (:func:`scipy.signal.chirp`).

    Parameters
    ----------
    fs : float
        Sample rate, Hz.
    f0, f1 : float
        Start and end frequencies, Hz (``0 < f0 < f1 < fs / 2``).
    duration : float
        Seconds.
    amplitude : float
        Peak value.

    Returns
    -------
    ndarray

    Examples
    --------
    >>> from piezohyst.signals.frequency import swept_sine
    >>> u = swept_sine(1000.0, 1.0, 100.0, 2.0)
    >>> u.size, round(float(u[0]), 6)
    (2000, 1.0)
    """
    from scipy.signal import chirp

    fs = as_scalar(fs, "fs", positive=True)
    a, b = as_scalar(f0, "f0", positive=True), as_scalar(f1, "f1", positive=True)
    if not a < b < fs / 2:
        raise ParameterError(f"f0 = {a}, f1 = {b} must satisfy 0 < f0 < f1 < fs / 2 = {fs / 2:g}")
    t = np.arange(round(as_scalar(duration, "duration", positive=True) * fs)) / fs
    return np.asarray(as_scalar(amplitude, "amplitude", positive=True) * chirp(t, a, t[-1], b, method="logarithmic"))


def frf_from_record(
    input: npt.ArrayLike,
    output: npt.ArrayLike,
    fs: float,
    *,
    period: int | None = None,
    frequencies: npt.ArrayLike | None = None,
    nperseg: int | None = None,
    skip: int = 0,
    input_name: str = "input",
    output_name: str = "output",
    unit: str = "",
) -> FrequencyResponse:
    """The frequency response ``output / input`` estimated from a record (a user's measured
    excitation and response, or a simulated one).

    With ``period`` (a periodic excitation such as :func:`multisine`): the whole periods after
    ``skip`` are averaged, and the response is the ratio of their spectra at the excited bins
    (the bins where the input's spectrum is above 1e-6 of its peak, or those nearest
    ``frequencies``) — no leakage, no window. Without: Welch's H1 estimate
    ``P_yu / P_uu`` (:func:`scipy.signal.csd`, Hann window, ``nperseg`` samples per segment,
    default ``min(N, 8 fs / f_low)`` capped to the record) with the coherence, at
    ``frequencies`` (interpolated) or every bin.

    Parameters
    ----------
    input, output : array_like
        The records, one value per sample, the same length.
    fs : float
        Sample rate, Hz.
    period : int, optional
        Samples per period of a periodic excitation.
    frequencies : array_like, optional
        Where to report the response, Hz.
    nperseg : int, optional
        Welch segment length (non-periodic records).
    skip : int
        Samples left out at the start (the transient).
    input_name, output_name, unit : str
        Labels of the result.

    Returns
    -------
    FrequencyResponse

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.signals.frequency import frf_from_record
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(20000)
    >>> y = 0.5 * u + 0.5 * np.r_[0.0, u[:-1]]          # (1 + z^-1) / 2: a zero at Nyquist
    >>> frf = frf_from_record(u, y, 1000.0, frequencies=[10.0, 250.0])
    >>> np.abs(frf.response).round(2).tolist()
    [1.0, 0.71]
    """
    u = as_record(input, "input", min_length=4)
    y = as_record(output, "output", min_length=4)
    if u.size != y.size:
        raise ParameterError(f"output has {y.size} samples, input has {u.size}; they must match")
    fs = as_scalar(fs, "fs", positive=True)
    k0 = as_int(skip, "skip", minimum=0)
    if k0 >= u.size - 4:
        raise ParameterError(f"skip = {k0} leaves fewer than 4 of the {u.size} samples")
    u, y = u[k0:], y[k0:]
    if period is not None:
        n = as_int(period, "period", minimum=4)
        reps = u.size // n
        if reps < 1:
            raise ParameterError(f"period = {n} is longer than the record after skip ({u.size} samples)")
        uu = u[: reps * n].reshape(reps, n).mean(axis=0)
        yy = y[: reps * n].reshape(reps, n).mean(axis=0)
        U, Y = np.fft.rfft(uu - uu.mean()), np.fft.rfft(yy - yy.mean())
        f_all = np.fft.rfftfreq(n, 1 / fs)
        if frequencies is None:
            mag = np.abs(U)
            bins = np.flatnonzero(mag > 1e-6 * mag.max())
            bins = bins[bins > 0]
        else:
            q = np.atleast_1d(np.asarray(frequencies, dtype=np.float64))
            bins = np.unique(np.clip(np.round(q * n / fs).astype(int), 1, n // 2))
        if bins.size == 0:
            raise ParameterError("the input excites no frequency (it is constant over a period)")
        coh = None
        if reps >= 2:
            # coherence of the periodic estimate: the periods' spread against the mean
            Us, Ys = (
                np.fft.rfft(u[: reps * n].reshape(reps, n), axis=1),
                np.fft.rfft(y[: reps * n].reshape(reps, n), axis=1),
            )
            Hs = Ys[:, bins] / Us[:, bins]
            h_mean = Hs.mean(axis=0)
            spread = np.mean(np.abs(Hs - h_mean) ** 2, axis=0)
            coh = np.abs(h_mean) ** 2 / (np.abs(h_mean) ** 2 + spread + 1e-300)
        return FrequencyResponse(
            np.asarray(f_all[bins], dtype=np.float64),
            np.asarray(Y[bins] / U[bins], dtype=np.complex128),
            coh,
            input_name,
            output_name,
            unit,
            "periodic",
            "frf from a record",
        )
    from scipy.signal import coherence as sp_coherence
    from scipy.signal import csd, welch

    if nperseg is None:
        f_low = float(np.min(frequencies)) if frequencies is not None else fs / u.size * 8
        seg = int(min(u.size, max(256, 2 ** math.ceil(math.log2(8 * fs / max(f_low, fs / u.size))))))
    else:
        seg = as_int(nperseg, "nperseg", minimum=8)
    seg = min(seg, u.size)
    f_w, p_uu = welch(u, fs, nperseg=seg)
    _, p_yu = csd(u, y, fs, nperseg=seg)
    _, coh_w = sp_coherence(u, y, fs, nperseg=seg)
    keep = (f_w > 0) & (p_uu > 1e-12 * p_uu.max())
    h = p_yu[keep] / p_uu[keep]
    fk, ck = f_w[keep], coh_w[keep]
    if frequencies is not None:
        q = np.atleast_1d(np.asarray(frequencies, dtype=np.float64))
        if np.any(q < fk[0]) or np.any(q > fk[-1]):
            raise ParameterError(f"frequencies must lie in the estimated band [{fk[0]:g}, {fk[-1]:g}] Hz")
        h = np.interp(q, fk, h.real) + 1j * np.interp(q, fk, h.imag)
        ck = np.interp(q, fk, ck)
        fk = q
    return FrequencyResponse(fk, h, ck, input_name, output_name, unit, "welch", "frf from a record")
