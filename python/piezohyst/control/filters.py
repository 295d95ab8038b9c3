"""Loop-shaping filters of the practitioner's loop (:class:`~piezohyst.FilteredPID`): notch,
low-pass, lag-lead and positive position feedback (PPF), each written in continuous time and
discretized for the loop's sample time by the bilinear transform with its characteristic
frequency prewarped (the discrete filter has exactly the continuous one's response there). The
Rust core runs each as a biquad ``(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)``
(``crates/core/src/control/filtered.rs``).

Examples
--------
>>> import numpy as np
>>> from piezohyst.control.filters import Notch
>>> n = Notch(1000.0, width=0.3)
>>> h = n.frequency_response([100.0, 1000.0], sample_time=1e-4)
>>> np.abs(h).round(3).tolist()                         # passes 100 Hz, removes 1 kHz
[0.998, 0.0]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .._validate import as_scalar
from ..errors import ParameterError
from ..signals.lti import polynomial_tf

FloatArray: TypeAlias = npt.NDArray[np.float64]
ComplexArray: TypeAlias = npt.NDArray[np.complex128]
#: ``(b0, b1, b2, a1, a2)`` of a discrete biquad (``a0 = 1``).
BiquadCoefficients: TypeAlias = tuple[float, float, float, float, float]

__all__ = ["IDENTITY", "IRC", "PPF", "BiquadCoefficients", "LagLead", "LowPass", "Notch", "Section", "bilinear"]

#: The biquad that is no filter.
IDENTITY: BiquadCoefficients = (1.0, 0.0, 0.0, 0.0, 0.0)


def bilinear(num: npt.ArrayLike, den: npt.ArrayLike, sample_time: float, warp_hz: float) -> BiquadCoefficients:
    """A continuous filter ``num(s) / den(s)`` of order <= 2 (coefficients highest power first)
    as a discrete biquad at ``sample_time``, by the bilinear transform
    ``s = K (z - 1) / (z + 1)`` with ``K = w / tan(w Ts / 2)``, ``w = 2 pi warp_hz`` (the
    response is exact at ``warp_hz``).

    Parameters
    ----------
    num, den : array_like
        Polynomial coefficients in ``s``, at most three each (``den`` not all zero).
    sample_time : float
        Ts, s.
    warp_hz : float
        The frequency kept exact, Hz (below Nyquist).

    Returns
    -------
    tuple of float
        ``(b0, b1, b2, a1, a2)``.

    Examples
    --------
    >>> from piezohyst.control.filters import bilinear
    >>> [round(c, 6) for c in bilinear([1.0], [1.0], 1e-4, 100.0)]     # a unit gain stays one
    [1.0, 0.0, 0.0, 0.0, 0.0]
    """
    ts = as_scalar(sample_time, "sample_time", positive=True)
    f = as_scalar(warp_hz, "warp_hz", positive=True)
    if not f < 0.5 / ts:
        raise ParameterError(f"warp_hz = {f} Hz must be below the Nyquist frequency {0.5 / ts:g} Hz")
    n = np.zeros(3)
    d = np.zeros(3)
    nn, dd = np.atleast_1d(np.asarray(num, float)), np.atleast_1d(np.asarray(den, float))
    if nn.size > 3 or dd.size > 3:
        raise ParameterError("num and den must have at most three coefficients (order <= 2)")
    n[3 - nn.size :] = nn
    d[3 - dd.size :] = dd
    w = 2 * math.pi * f
    k = w / math.tan(w * ts / 2)
    if n[0] == n[1] == d[0] == d[1] == 0:
        if d[2] == 0:
            raise ParameterError("the filter's denominator vanishes")
        return float(n[2] / d[2]), 0.0, 0.0, 0.0, 0.0
    if n[0] == 0 and d[0] == 0:
        # first order: (c1 s + c0) times (z + 1), in powers z, 1 (no common factor z + 1, so
        # no pole on the unit circle)
        b1st = np.array([n[1] * k + n[2], n[2] - n[1] * k])
        a1st = np.array([d[1] * k + d[2], d[2] - d[1] * k])
        if a1st[0] == 0:
            raise ParameterError("the filter is improper or its denominator vanishes")
        b1st, a1st = b1st / a1st[0], a1st / a1st[0]
        return float(b1st[0]), float(b1st[1]), 0.0, float(a1st[1]), 0.0

    # (c2 s^2 + c1 s + c0) with s = k (z - 1)/(z + 1), times (z + 1)^2, in powers z^2, z, 1
    def poly(c: FloatArray) -> FloatArray:
        c2, c1, c0 = c
        return np.array(
            [c2 * k * k + c1 * k + c0, -2 * c2 * k * k + 2 * c0, c2 * k * k - c1 * k + c0], dtype=np.float64
        )

    b, a = poly(n), poly(d)
    if a[0] == 0:
        raise ParameterError("the filter is improper or its denominator vanishes")
    b, a = b / a[0], a / a[0]
    return float(b[0]), float(b[1]), float(b[2]), float(a[1]), float(a[2])


def _biquad_response(c: BiquadCoefficients, f: npt.ArrayLike, sample_time: float) -> ComplexArray:
    """Frequency response of a discrete biquad at ``f`` (Hz)."""
    z = np.exp(-2j * np.pi * np.asarray(f, float) * sample_time)
    b0, b1, b2, a1, a2 = c
    return np.asarray((b0 + b1 * z + b2 * z * z) / (1 + a1 * z + a2 * z * z), dtype=np.complex128)


class _Filter:
    """What every filter gives: its continuous polynomials, its biquad at a sample time, its
    discrete frequency response, its python-control transfer function."""

    def polynomials(self) -> tuple[list[float], list[float]]:  # pragma: no cover - abstract
        raise NotImplementedError

    def warp_hz(self) -> float:  # pragma: no cover - abstract
        raise NotImplementedError

    def biquad(self, sample_time: float) -> BiquadCoefficients:
        """The discrete biquad at ``sample_time`` (bilinear, prewarped at the filter's
        frequency).

        Parameters
        ----------
        sample_time : float
            Ts, s.

        Returns
        -------
        tuple of float
            ``(b0, b1, b2, a1, a2)``.

        Examples
        --------
        >>> from piezohyst.control.filters import IRC
        >>> b0, b1, b2, a1, a2 = IRC(1000.0, static_gain=1.0).biquad(1e-4)
        >>> round((b0 + b1 + b2) / (1.0 + a1 + a2), 9)        # the static gain 1 / (feedthrough g)
        0.5
        """
        num, den = self.polynomials()
        return bilinear(num, den, sample_time, self.warp_hz())

    def frequency_response(self, f: npt.ArrayLike, sample_time: float | None = None) -> ComplexArray:
        """The response at ``f`` (Hz): continuous (``sample_time=None``) or of the biquad.

        Parameters
        ----------
        f : array_like
            Frequencies, Hz.
        sample_time : float, optional
            Ts, s, for the discrete filter.

        Returns
        -------
        ndarray of complex

        Examples
        --------
        >>> from piezohyst.control.filters import IRC
        >>> h = IRC(1000.0, static_gain=1.0).frequency_response([0.0, 1000.0])
        >>> [round(complex(x).real, 6) for x in h], round(float(abs(h[1]) / abs(h[0])), 6)   # -3 dB at the pole
        ([0.5, 0.25], 0.707107)
        >>> round(float(abs(IRC(1000.0, static_gain=1.0).frequency_response([1000.0], 1e-4)[0])), 6)  # prewarped
        0.353553
        """
        if sample_time is not None:
            return _biquad_response(self.biquad(sample_time), f, sample_time)
        num, den = self.polynomials()
        s = 2j * np.pi * np.asarray(f, float)
        return np.asarray(np.polyval(num, s) / np.polyval(den, s), dtype=np.complex128)

    def to_control(self) -> Any:
        """The continuous filter as a python-control ``TransferFunction``.

        Returns
        -------
        control.TransferFunction

        Examples
        --------
        >>> from piezohyst.control.filters import IRC
        >>> tf = IRC(1000.0, static_gain=1.0).to_control()
        >>> round(float(tf.dcgain()), 6), round(float(tf.poles()[0].real), 2)    # pole at -2 pi 1000
        (0.5, -6283.19)
        """
        num, den = self.polynomials()
        return polynomial_tf(num, den, inputs=["input"], outputs=["output"], name=type(self).__name__.lower())


@dataclass(frozen=True)
class Notch(_Filter):
    """A notch ``(s^2 + 2 depth width w s + w^2) / (s^2 + 2 width w s + w^2)`` at ``frequency``
    (Hz): ``width`` is the poles' damping ratio (the notch's breadth), ``depth`` the gain at the
    notch frequency (0: zeros on the axis, full removal; 0.1: -20 dB).

    Parameters
    ----------
    frequency : float
        The notch frequency, Hz.
    width : float, optional
        The poles' damping ratio (the notch's breadth).
    depth : float, optional
        The gain at the notch frequency, in [0, 1).

    Examples
    --------
    >>> from piezohyst.control.filters import Notch
    >>> round(float(abs(Notch(5000.0, width=0.2, depth=0.1).frequency_response([5000.0])[0])), 6)
    0.1
    """

    frequency: float
    width: float = 0.3
    depth: float = 0.0

    def __post_init__(self) -> None:
        as_scalar(self.frequency, "notch frequency", positive=True)
        as_scalar(self.width, "notch width", positive=True)
        d = as_scalar(self.depth, "notch depth", nonnegative=True)
        if d >= 1:
            raise ParameterError(f"notch depth = {d} must be < 1 (the gain at the notch)")

    def polynomials(self) -> tuple[list[float], list[float]]:
        """Numerator and denominator in ``s``.

        Returns
        -------
        tuple of list of float

        Examples
        --------
        >>> from piezohyst.control.filters import Notch
        >>> Notch(1.0 / (2 * 3.141592653589793), width=0.5).polynomials()
        ([1.0, 0.0, 1.0], [1.0, 1.0, 1.0])
        """
        w = 2 * math.pi * self.frequency
        return [1.0, 2 * self.depth * self.width * w, w * w], [1.0, 2 * self.width * w, w * w]

    def warp_hz(self) -> float:
        """The frequency kept exact: the notch's.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.control.filters import Notch
        >>> Notch(1000.0).warp_hz()
        1000.0
        """
        return float(self.frequency)


@dataclass(frozen=True)
class LowPass(_Filter):
    """A second-order low-pass ``w^2 / (s^2 + 2 damping w s + w^2)`` at ``frequency`` (Hz).

    Parameters
    ----------
    frequency : float
        The corner frequency, Hz.
    damping : float, optional
        The poles' damping ratio (Butterworth by default).

    Examples
    --------
    >>> from piezohyst.control.filters import LowPass
    >>> round(float(abs(LowPass(1000.0).frequency_response([1000.0])[0])), 4)     # -3 dB
    0.7071
    """

    frequency: float
    damping: float = 1 / math.sqrt(2)

    def __post_init__(self) -> None:
        as_scalar(self.frequency, "low-pass frequency", positive=True)
        as_scalar(self.damping, "low-pass damping", positive=True)

    def polynomials(self) -> tuple[list[float], list[float]]:
        """Numerator and denominator in ``s``.

        Returns
        -------
        tuple of list of float

        Examples
        --------
        >>> from piezohyst.control.filters import LowPass
        >>> LowPass(1.0 / (2 * 3.141592653589793), damping=0.5).polynomials()
        ([1.0], [1.0, 1.0, 1.0])
        """
        w = 2 * math.pi * self.frequency
        return [w * w], [1.0, 2 * self.damping * w, w * w]

    def warp_hz(self) -> float:
        """The frequency kept exact: the corner.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.control.filters import LowPass
        >>> LowPass(250.0).warp_hz()
        250.0
        """
        return float(self.frequency)


@dataclass(frozen=True)
class LagLead(_Filter):
    """A first-order lag-lead ``(1 + s / (2 pi zero)) / (1 + s / (2 pi pole))`` (unit static
    gain; ``zero < pole`` is a lead, ``zero > pole`` a lag): the shape of a gain that changes
    by ``pole / zero`` between two corners, as a stage's creep makes it.

    Parameters
    ----------
    zero : float
        The zero's corner frequency, Hz.
    pole : float
        The pole's corner frequency, Hz.

    Examples
    --------
    >>> from piezohyst.control.filters import LagLead
    >>> h = LagLead(zero=10.0, pole=20.0).frequency_response([0.0, 1e6])
    >>> np.abs(h).round(3).tolist()
    [1.0, 2.0]
    """

    zero: float
    pole: float

    def __post_init__(self) -> None:
        as_scalar(self.zero, "lag-lead zero", positive=True)
        as_scalar(self.pole, "lag-lead pole", positive=True)

    def polynomials(self) -> tuple[list[float], list[float]]:
        """Numerator and denominator in ``s``.

        Returns
        -------
        tuple of list of float

        Examples
        --------
        >>> from piezohyst.control.filters import LagLead
        >>> LagLead(1.0 / (2 * 3.141592653589793), 1.0 / 3.141592653589793).polynomials()
        ([1.0, 1.0], [0.5, 1.0])
        """
        return [1.0 / (2 * math.pi * self.zero), 1.0], [1.0 / (2 * math.pi * self.pole), 1.0]

    def warp_hz(self) -> float:
        """The frequency kept exact: the corners' geometric mean.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.control.filters import LagLead
        >>> LagLead(zero=10.0, pole=1000.0).warp_hz()
        100.0
        """
        return math.sqrt(self.zero * self.pole)


@dataclass(frozen=True)
class PPF(_Filter):
    """Positive position feedback, a damping loop on the position reading:
    ``gain w^2 / (s^2 + 2 damping w s + w^2)`` tuned to a resonance at ``frequency`` (Hz), added
    to the command (V per m of reading: for a stage with static gain ``g`` m/V, ``gain`` of about
    ``0.5 / g`` adds damping; the loop is stable while ``gain g < 1``).

    Parameters
    ----------
    frequency : float
        The resonance the filter is tuned to, Hz.
    damping : float, optional
        The filter's damping ratio.
    gain : float, optional
        The static gain, command units per unit of reading.

    Examples
    --------
    >>> from piezohyst.control.filters import PPF
    >>> round(float(abs(PPF(5000.0, damping=0.3, gain=2.0).frequency_response([0.0])[0])), 6)
    2.0
    """

    frequency: float
    damping: float = 0.3
    gain: float = 0.0

    def __post_init__(self) -> None:
        as_scalar(self.frequency, "PPF frequency", positive=True)
        as_scalar(self.damping, "PPF damping", positive=True)
        as_scalar(self.gain, "PPF gain")

    def polynomials(self) -> tuple[list[float], list[float]]:
        """Numerator and denominator in ``s``.

        Returns
        -------
        tuple of list of float

        Examples
        --------
        >>> from piezohyst.control.filters import PPF
        >>> PPF(1.0 / (2 * 3.141592653589793), damping=0.5, gain=3.0).polynomials()
        ([3.0], [1.0, 1.0, 1.0])
        """
        w = 2 * math.pi * self.frequency
        return [self.gain * w * w], [1.0, 2 * self.damping * w, w * w]

    def warp_hz(self) -> float:
        """The frequency kept exact: the resonance's.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.control.filters import PPF
        >>> PPF(5000.0).warp_hz()
        5000.0
        """
        return float(self.frequency)


@dataclass(frozen=True)
class IRC(_Filter):
    """Integral resonant control (Aphale, Fleming and Moheimani 2007), a damping loop on the
    position reading beside :class:`PPF`: the reading plus a feedthrough ``D = -feedthrough g``
    (``g`` the loop's static gain, m per command unit) fed back through the integrator
    ``k / s``, ``u = k / s (y + D u)``, which is the first-order positive feedback::

        H(s) = k / (s + k feedthrough g),   k = 2 pi frequency / (feedthrough g)

    added to the command (the ``damping`` slot of :class:`~piezohyst.FilteredPID`). Its pole is
    at ``frequency`` (Hz; about the resonance to damp, or below it); ``feedthrough > 1`` puts the
    modified plant's zeros below its first resonance, so the loop is stable for every ``k`` on
    a collocated stage and damps every mode above ``frequency``, the ones it was not designed
    on included. It raises the damped stage's static gain by ``1 / (1 - 1 / feedthrough)``
    (:meth:`static_factor`: 2 for the usual ``feedthrough = 2``), which the outer loop's
    integral removes and a feedforward divides by.

    Parameters
    ----------
    frequency : float
        The integrator's pole, Hz.
    static_gain : float
        The loop's static gain ``g``, m per command unit.
    feedthrough : float, optional
        The feedthrough ratio (> 1).

    Examples
    --------
    >>> from piezohyst.control.filters import IRC
    >>> irc = IRC(1000.0, static_gain=1.0)
    >>> round(float(abs(irc.frequency_response([0.0])[0])), 6), irc.static_factor()
    (0.5, 2.0)
    """

    frequency: float
    static_gain: float
    feedthrough: float = 2.0

    def __post_init__(self) -> None:
        as_scalar(self.frequency, "IRC frequency", positive=True)
        as_scalar(self.static_gain, "IRC static_gain", positive=True)
        d = as_scalar(self.feedthrough, "IRC feedthrough", positive=True)
        if not d > 1:
            raise ParameterError(f"IRC feedthrough = {d} must be > 1 (zeros below the first resonance)")

    def polynomials(self) -> tuple[list[float], list[float]]:
        """Numerator and denominator in ``s``.

        Returns
        -------
        tuple of list of float

        Examples
        --------
        >>> from piezohyst.control.filters import IRC
        >>> IRC(1.0 / (2 * 3.141592653589793), static_gain=0.5, feedthrough=2.0).polynomials()
        ([1.0], [1.0, 1.0])
        """
        w = 2 * math.pi * self.frequency
        k = w / (self.feedthrough * self.static_gain)
        return [k], [1.0, w]

    def static_factor(self) -> float:
        """The damped loop's static gain over the stage's: ``1 / (1 - 1 / feedthrough)``.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.control.filters import IRC
        >>> IRC(1000.0, static_gain=1.0, feedthrough=4.0).static_factor()     # 1 / (1 - 1/4)
        1.3333333333333333
        """
        return 1.0 / (1.0 - 1.0 / self.feedthrough)

    def warp_hz(self) -> float:
        """The frequency kept exact: the pole's.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.control.filters import IRC
        >>> IRC(800.0, static_gain=1e-6).warp_hz()
        800.0
        """
        return float(self.frequency)


@dataclass(frozen=True)
class Section(_Filter):
    """A general continuous section ``num(s) / den(s)`` of order at most two (coefficients
    highest power first; proper), discretized by the bilinear transform prewarped at
    ``warp`` (Hz): how a controller designed elsewhere (e.g.
    :func:`piezohyst.control.design.mixed_sensitivity`'s H-infinity controller) is cut into the
    biquads a :class:`~piezohyst.FilteredPID` runs.

    Parameters
    ----------
    num : tuple of float
        Numerator coefficients in ``s``, highest power first (at most three).
    den : tuple of float
        Denominator coefficients in ``s``, highest power first (at most three, not all zero).
    warp : float
        The frequency kept exact, Hz.
    discretization : {"bilinear", "matched"}, optional
        How :meth:`biquad` discretizes the section.

    Examples
    --------
    >>> from piezohyst.control.filters import Section
    >>> s = Section((1.0, 10.0), (1.0, 20.0), warp=100.0)     # (s + 10) / (s + 20)
    >>> round(float(abs(s.frequency_response([0.0])[0])), 6)
    0.5
    """

    num: tuple[float, ...]
    den: tuple[float, ...]
    warp: float
    discretization: str = "bilinear"

    def biquad(self, sample_time: float) -> BiquadCoefficients:
        """The discrete biquad at ``sample_time``: ``discretization="bilinear"`` (prewarped at
        ``warp``) or ``"matched"`` (each pole and zero ``s`` to ``exp(s Ts)``, the zeros at
        infinity to ``z = 0``, the gain matched at ``warp``: a pole far above Nyquist goes to
        ``z ~ 0`` instead of the bilinear transform's ``z = -1``).

        Parameters
        ----------
        sample_time : float
            Ts, s.

        Returns
        -------
        tuple of float
            ``(b0, b1, b2, a1, a2)``.

        Examples
        --------
        >>> from piezohyst.control.filters import Section
        >>> q = Section((1.0, 10.0), (1.0, 1e9), warp=100.0, discretization="matched").biquad(1e-4)
        >>> abs(q[3]) < 1e-9                                    # the fast pole at z ~ 0
        True
        """
        if self.discretization == "bilinear":
            return super().biquad(sample_time)
        ts = as_scalar(sample_time, "sample_time", positive=True)
        if not self.warp < 0.5 / ts:
            raise ParameterError(f"Section warp = {self.warp} Hz must be below the Nyquist frequency {0.5 / ts:g} Hz")
        n = np.trim_zeros(np.asarray(self.num, float), "f")
        d = np.trim_zeros(np.asarray(self.den, float), "f")
        zp = np.exp(np.roots(n) * ts) if n.size > 1 else np.array([])
        pp = np.exp(np.roots(d) * ts) if d.size > 1 else np.array([])
        bz = np.real(np.poly(zp)) if zp.size else np.array([1.0])
        az = np.real(np.poly(pp)) if pp.size else np.array([1.0])
        b = np.zeros(3)
        a = np.zeros(3)
        # powers z^deg(d), ..., 1 (then z^-k form): the missing zeros (at infinity) land at z = 0
        b[: bz.size] = bz
        a[: az.size] = az
        w = 2 * math.pi * float(self.warp)
        zw = np.exp(1j * w * ts)
        hc = np.polyval(n, 1j * w) / np.polyval(d, 1j * w)
        deg = az.size - 1
        hd = np.polyval(b[: deg + 1], zw) / np.polyval(a[: deg + 1], zw)
        b = b * abs(hc) / abs(hd)
        return float(b[0]), float(b[1]), float(b[2]), float(a[1]), float(a[2])

    def __post_init__(self) -> None:
        n = np.trim_zeros(np.atleast_1d(np.asarray(self.num, float)), "f")
        d = np.trim_zeros(np.atleast_1d(np.asarray(self.den, float)), "f")
        if d.size == 0 or d.size > 3 or n.size > 3:
            raise ParameterError(
                f"Section num = {self.num}, den = {self.den}: order at most 2 and a non-zero denominator"
            )
        if n.size > d.size:
            raise ParameterError(f"Section num = {self.num}, den = {self.den} is improper")
        if not (np.all(np.isfinite(n)) and np.all(np.isfinite(d))):
            raise ParameterError(f"Section num = {self.num}, den = {self.den} must be finite")
        as_scalar(self.warp, "Section warp", positive=True)
        if self.discretization not in ("bilinear", "matched"):
            raise ParameterError(f"Section discretization = {self.discretization!r} must be 'bilinear' or 'matched'")

    def polynomials(self) -> tuple[list[float], list[float]]:
        """Numerator and denominator in ``s``.

        Returns
        -------
        tuple of list of float

        Examples
        --------
        >>> from piezohyst.control.filters import Section
        >>> Section((2, 10), (1, 3, 20), warp=100.0).polynomials()
        ([2.0, 10.0], [1.0, 3.0, 20.0])
        """
        return [float(c) for c in self.num], [float(c) for c in self.den]

    def warp_hz(self) -> float:
        """The frequency kept exact.

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst.control.filters import Section
        >>> Section((1.0, 10.0), (1.0, 20.0), warp=100.0).warp_hz()
        100.0
        """
        return float(self.warp)
