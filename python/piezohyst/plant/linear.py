"""The linear part of a piezo stage: state space, frequency response and the way back from a
second-order transfer function (the one home of the stage's linear dynamics).

Of the stage's physics (:mod:`piezohyst.plant.stage`)::

    tau_a Va' = u - Va                                   amplifier (-3 dB bandwidth 1 / (2 pi tau_a))
    m x'' + b x' + k x = Tem (Va - Vh + Vcr + e2 Va^2)   mechanics
    tau_j w_j' = Va - w_j,   Vcr = sum_j c_j w_j          creep

the linear part keeps the amplifier's first-order lag (not its limits or slew rate), the
mechanics and the creep lags, and leaves out the electrostriction ``e2 Va^2`` and the CEMF
hysteresis ``Vh``. With ``cemf=True`` the hysteresis enters by its slope at the demagnetized
rest state (``Vh = 0``, where the Bouc–Wen law is ``dVh = alpha dq``): the small-signal model
around rest. For the charge drive ``q = Cz (Va - Vh) + Tem x`` that gives the input gain
``Tem / (1 + alpha Cz)`` and the extra stiffness ``alpha Tem^2 / (1 + alpha Cz)``; for the
voltage drive the input gain ``Tem (1 - alpha)``.

The transfer function from the command ``u`` (V) to the position ``x`` (m)::

    H(s) = A(s) (g + Tem sum_j c_j / (tau_j s + 1)) / (m s^2 + b s + k'),   A(s) = 1 / (tau_a s + 1)

(``g = Tem``, ``k' = k`` without the CEMF slope). :func:`frequency_response` evaluates it from
the parameters; :func:`state_space` gives the same system as matrices, states ``[Va, x, v,
w_0 ...]`` (``Va`` only with a finite amplifier bandwidth).

Examples
--------
>>> import numpy as np
>>> from piezohyst import virtual_stage
>>> stage = virtual_stage()
>>> h0 = stage.frequency_response([1e-9])[0]          # the static gain: Tem / k (1 + sum c_j)
>>> bool(np.isclose(h0.real, stage.params.static_gain * 1.075))
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .._validate import as_record, as_scalar
from ..errors import ParameterError
from ..signals.lti import siso_polynomials

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .stage import Amplifier, StageParameters

FloatArray: TypeAlias = npt.NDArray[np.float64]
ComplexArray: TypeAlias = npt.NDArray[np.complex128]

__all__ = [
    "LinearPart",
    "LinearSystem",
    "discretize",
    "frequency_response",
    "linear_part",
    "linear_system",
    "second_order_from_control",
    "state_space",
]


@dataclass(frozen=True)
class LinearPart:
    """The coefficients of a stage's linear part (see the module docstring).

    Parameters
    ----------
    mass, damping, stiffness : float
        ``m`` (kg), ``b`` (N s/m), ``k'`` (N/m; with the CEMF slope when asked).
    input_gain : float
        ``g``: force per volt of amplifier voltage (N/V).
    tem : float
        ``Tem``: force per volt of creep voltage (N/V).
    creep_taus, creep_weights : tuple of float
        The creep lags (empty when left out).
    amplifier_tau : float
        ``tau_a`` in s; 0 for an ideal amplifier (or when left out).
    modes : tuple of (float, float, float)
        Added modes ``(frequency Hz, damping ratio, relative gain)`` (:meth:`Stage.with_modes`):
        each driven by the stack's force ``m x'' + b x' + k x`` (the stage's own ``m, b, k``),
        the position being their normalized sum with the stack's displacement.
    mode_mechanics : tuple of float
        The stage's own ``(m, b, k)`` that drive the added modes.

    Examples
    --------
    >>> from piezohyst.plant.linear import LinearPart, frequency_response
    >>> part = LinearPart(1.0, 2.0, 4.0, input_gain=4.0, tem=4.0, creep_taus=(), creep_weights=(), amplifier_tau=0.0)
    >>> complex(frequency_response(part, [0.0])[0])               # g / k
    (1+0j)
    """

    mass: float
    damping: float
    stiffness: float
    input_gain: float
    tem: float
    creep_taus: tuple[float, ...]
    creep_weights: tuple[float, ...]
    amplifier_tau: float
    modes: tuple[tuple[float, float, float], ...] = ()
    mode_mechanics: tuple[float, float, float] = (1.0, 0.0, 1.0)


def linear_part(
    params: StageParameters,
    amplifier: Amplifier | None = None,
    *,
    creep: bool = True,
    cemf: bool = False,
    modes: tuple[tuple[float, float, float], ...] = (),
) -> LinearPart:
    """The linear part of a stage with ``params`` behind ``amplifier`` (``None``: ideal).

    ``creep=False`` leaves the creep lags out; ``cemf=True`` adds the CEMF hysteresis's slope
    at the demagnetized rest state; ``modes`` are the stage's added modes.

    Parameters
    ----------
    params : StageParameters
        The stage's physical parameters.
    amplifier : Amplifier, optional
        The amplifier whose bandwidth gives the first-order lag (``None``: ideal).
    creep : bool, optional
        Whether the creep lags are kept.
    cemf : bool, optional
        Whether the CEMF hysteresis enters by its slope at rest.
    modes : tuple of (float, float, float), optional
        Added modes ``(frequency Hz, damping ratio, relative gain)``.

    Returns
    -------
    LinearPart

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import virtual_stage
    >>> from piezohyst.plant.linear import frequency_response, linear_part
    >>> params = virtual_stage().params
    >>> stiff = linear_part(params, creep=False)                 # the static gain Tem / k
    >>> bool(np.isclose(abs(frequency_response(stiff, [0.0])[0]), params.static_gain))
    True
    >>> crept = linear_part(params)                              # the creep adds 7.5 %
    >>> round(float(abs(frequency_response(crept, [0.0])[0]) / params.static_gain), 6)
    1.075
    """
    p = params
    gain, stiffness = p.tem, p.stiffness
    if cemf:
        if p.hyst_drive == "charge":
            den = 1.0 + p.hyst_alpha * p.capacitance
            if not den > 0:
                raise ParameterError(
                    f"hyst_alpha * capacitance = {p.hyst_alpha * p.capacitance} must be > -1 for the CEMF slope"
                )
            gain = p.tem / den
            stiffness = p.stiffness + p.hyst_alpha * p.tem * p.tem / den
        else:
            gain = p.tem * (1.0 - p.hyst_alpha)
    bw = math.inf if amplifier is None else amplifier.bandwidth
    tau_a = 0.0 if math.isinf(bw) else 1.0 / (2.0 * math.pi * bw)
    taus, weights = (p.creep_taus, p.creep_weights) if creep else ((), ())
    return LinearPart(
        p.mass,
        p.damping,
        stiffness,
        gain,
        p.tem,
        tuple(taus),
        tuple(weights),
        tau_a,
        tuple(modes),
        (p.mass, p.damping, p.stiffness),
    )


def _mode_factor(part: LinearPart, s: npt.NDArray[np.complexfloating[Any, Any]]) -> ComplexArray:
    """``position / x``: ``(1 + sum_i g_i w_i^2 (m s^2 + b s + k) / (k (s^2 + 2 zeta_i w_i s + w_i^2))) /
    (1 + sum g)`` (1 without added modes)."""
    out = np.ones(s.shape, dtype=np.complex128)
    if not part.modes:
        return out
    m, b, k = part.mode_mechanics
    total = 1.0
    for f, zeta, g in part.modes:
        w = 2 * np.pi * f
        out += g * w * w * (m * s * s + b * s + k) / (k * (s * s + 2 * zeta * w * s + w * w))
        total += g
    return out / total


def frequency_response(part: LinearPart, f: npt.ArrayLike) -> ComplexArray:
    """``H(j 2 pi f)``, position per command volt (m/V), evaluated from the coefficients at the
    frequencies ``f`` (Hz, finite, ``>= 0``).

    Parameters
    ----------
    part : LinearPart
        The linear part.
    f : array_like
        Frequencies, Hz.

    Returns
    -------
    ndarray of complex
        The response, m/V.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.plant.linear import LinearPart, frequency_response
    >>> part = LinearPart(1.0, 2.0, 4.0, input_gain=4.0, tem=4.0, creep_taus=(), creep_weights=(), amplifier_tau=0.0)
    >>> h = frequency_response(part, [0.0, 1 / np.pi])           # 4 / (s^2 + 2 s + 4) at s = 0, 2j
    >>> np.round(h, 12).tolist()
    [(1+0j), -1j]
    """
    freq = as_record(np.atleast_1d(np.asarray(f, dtype=np.float64)), "f", min_length=1)
    bad = np.flatnonzero(freq < 0)
    if bad.size:
        raise ParameterError(f"f[{bad[0]}] = {freq[bad[0]]} Hz must be >= 0")
    s = 2j * np.pi * freq
    drive = np.full(s.shape, part.input_gain, dtype=np.complex128)
    for tau, c in zip(part.creep_taus, part.creep_weights, strict=True):
        drive += part.tem * c / (tau * s + 1.0)
    h: ComplexArray = drive / (part.mass * s * s + part.damping * s + part.stiffness) * _mode_factor(part, s)
    if part.amplifier_tau > 0:
        h = h / (part.amplifier_tau * s + 1.0)
    return h


def state_space(part: LinearPart) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, list[str]]:
    """``(A, B, C, D, state names)`` of the linear part: input the command (V), output the
    position (m), states ``["va", "x", "v", "w0", ...]`` (``va`` only with an amplifier lag).

    Parameters
    ----------
    part : LinearPart
        The linear part.

    Returns
    -------
    tuple
        ``(A, B, C, D, state names)``.

    Examples
    --------
    >>> from piezohyst.plant.linear import LinearPart, state_space
    >>> part = LinearPart(1.0, 2.0, 4.0, input_gain=4.0, tem=4.0, creep_taus=(), creep_weights=(), amplifier_tau=0.0)
    >>> a, b, c, d, names = state_space(part)
    >>> a.tolist(), b.ravel().tolist(), names
    ([[0.0, 1.0], [-4.0, -2.0]], [0.0, 4.0], ['x', 'v'])
    """
    amp = part.amplifier_tau > 0
    nc = len(part.creep_taus)
    nm = len(part.modes)
    n = (1 if amp else 0) + 2 + nc + 2 * nm
    a = np.zeros((n, n))
    b = np.zeros((n, 1))
    c = np.zeros((1, n))
    i_x = 1 if amp else 0
    i_v = i_x + 1
    names = (["va"] if amp else []) + ["x", "v"] + [f"w{j}" for j in range(nc)]
    names += [n for i in range(nm) for n in (f"q{i + 1}", f"dq{i + 1}")]
    # the voltage that drives the mechanics and the creep: Va (a state) or the command itself
    drive = np.zeros(n)
    drive_b = 0.0
    if amp:
        a[0, 0] = -1.0 / part.amplifier_tau
        b[0, 0] = 1.0 / part.amplifier_tau
        drive[0] = 1.0
    else:
        drive_b = 1.0
    m = part.mass
    a[i_x, i_v] = 1.0
    a[i_v, i_x] = -part.stiffness / m
    a[i_v, i_v] = -part.damping / m
    a[i_v] += part.input_gain / m * drive
    b[i_v, 0] += part.input_gain / m * drive_b
    for j, (tau, w) in enumerate(zip(part.creep_taus, part.creep_weights, strict=True)):
        i_w = i_v + 1 + j
        a[i_v, i_w] += part.tem * w / m
        a[i_w] += drive / tau
        a[i_w, i_w] -= 1.0 / tau
        b[i_w, 0] += drive_b / tau
    c[0, i_x] = 1.0
    if nm:
        # q'' = -w^2 q - 2 zeta w q' + (w^2 / k) (m x'' + b x' + k x), the stage's own m, b, k
        mm, bm, km = part.mode_mechanics
        row_f = mm * a[i_v].copy()
        row_f[i_v] += bm
        row_f[i_x] += km
        b_f = mm * b[i_v, 0]
        total = 1.0 + sum(g for _, _, g in part.modes)
        c[0, i_x] = 1.0 / total
        for i, (f, zeta, g) in enumerate(part.modes):
            w = 2 * np.pi * f
            i_q = i_v + 1 + nc + 2 * i
            a[i_q, i_q + 1] = 1.0
            a[i_q + 1] = (w * w / km) * row_f
            a[i_q + 1, i_q] -= w * w
            a[i_q + 1, i_q + 1] -= 2 * zeta * w
            b[i_q + 1, 0] = (w * w / km) * b_f
            c[0, i_q] = g / total
    return a, b, c, np.zeros((1, 1)), names


def second_order_from_control(sys: object, tem: float) -> tuple[float, float, float]:
    """``(mass, damping, stiffness)`` of ``m x'' + b x' + k x = Tem u`` whose transfer function
    ``Tem / (m s^2 + b s + k)`` is ``sys`` (continuous, single input and output, no zeros,
    ``m, k > 0``, ``b >= 0``); ``tem`` (N/V) fixes the scale, which the transfer function alone
    does not tell.

    Parameters
    ----------
    sys : control.TransferFunction
        The continuous second-order system ``b0 / (s^2 + a1 s + a0)``.
    tem : float
        ``Tem``, N/V.

    Returns
    -------
    tuple of float
        ``(mass, damping, stiffness)``.

    Examples
    --------
    >>> import control
    >>> from piezohyst.plant.linear import second_order_from_control
    >>> second_order_from_control(control.tf([2.0], [1.0, 3.0, 4.0]), tem=2.0)
    (1.0, 3.0, 4.0)
    """
    t = as_scalar(tem, "tem", positive=True)
    num, den, dt = siso_polynomials(sys, "sys")
    if dt is not None:
        raise ParameterError(
            f"sys is discrete (dt = {dt} s); a stage is built from a continuous system (convert it with d2c first)"
        )
    if num.size != 1 or den.size != 3:
        raise ParameterError(
            f"sys must be a second-order transfer function b0 / (s^2 + a1 s + a0) without zeros; got a numerator "
            f"of degree {num.size - 1} and a denominator of degree {den.size - 1} (build the stage's system with "
            "amplifier=False, creep=False for this form)"
        )
    b0 = float(num[0])
    _, a1, a0 = (float(x) for x in den)
    if not (b0 > 0 and a0 > 0 and a1 >= 0):
        raise ParameterError(
            f"sys = {b0:.6g} / (s^2 + {a1:.6g} s + {a0:.6g}) is not a stage: the gain and the stiffness term "
            "must be > 0 and the damping term >= 0"
        )
    mass = t / b0
    return mass, a1 * mass, a0 * mass


def discretize(
    a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray, dt: float, *, delay: int = 0
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The zero-order-hold discretization over ``dt`` (the command held over each sample, as
    :meth:`~piezohyst.plant.Stage.simulate` holds it; :func:`scipy.signal.cont2discrete`), with
    the output delayed by ``delay`` whole samples (a sensor's delay): ``delay`` more states,
    the last of which is the output.

    Parameters
    ----------
    a, b, c, d : ndarray
        The continuous system's matrices (one input, one output).
    dt : float
        The sample time, s.
    delay : int, optional
        Whole samples of output delay.

    Returns
    -------
    tuple of ndarray
        ``(Ad, Bd, Cd, Dd)``.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.plant.linear import discretize
    >>> a, b, c, d = np.array([[-1.0]]), np.array([[1.0]]), np.array([[1.0]]), np.zeros((1, 1))
    >>> ad, bd, cd, dd = discretize(a, b, c, d, 0.1)
    >>> bool(np.isclose(ad[0, 0], np.exp(-0.1))), bool(np.isclose(bd[0, 0], 1 - np.exp(-0.1)))
    (True, True)
    >>> discretize(a, b, c, d, 0.1, delay=2)[0].shape            # two more states
    (3, 3)
    """
    from scipy.signal import cont2discrete

    ad, bd, cd, dd, _ = cont2discrete((a, b, c, d), dt, method="zoh")
    ad, bd, cd, dd = (np.asarray(m, dtype=np.float64) for m in (ad, bd, cd, dd))
    if delay <= 0:
        return ad, bd, cd, dd
    n = ad.shape[0]
    big = np.zeros((n + delay, n + delay))
    big[:n, :n] = ad
    big_b = np.zeros((n + delay, 1))
    big_b[:n] = bd
    # z_1[k+1] = y[k] = C x[k] + D u[k]; z_i[k+1] = z_{i-1}[k]; output z_delay
    big[n, :n] = cd[0]
    big_b[n, 0] = dd[0, 0]
    for i in range(1, delay):
        big[n + i, n + i - 1] = 1.0
    big_c = np.zeros((1, n + delay))
    big_c[0, -1] = 1.0
    return big, big_b, big_c, np.zeros((1, 1))


@dataclass(frozen=True)
class LinearSystem:
    """Matrices of a stage's linear part, ready for python-control or scipy: ``dt`` ``None``
    (continuous) or the sample time in s; ``states``, ``output`` the signal names.

    Parameters
    ----------
    a, b, c, d : ndarray
        The state-space matrices.
    dt : float or None
        ``None`` (continuous) or the sample time, s.
    states : list of str
        The states' names.
    output : str
        The output's name (``"position"`` or ``"measured"``).

    Examples
    --------
    >>> from piezohyst.plant.linear import LinearPart, linear_system
    >>> part = LinearPart(1.0, 2.0, 4.0, input_gain=4.0, tem=4.0, creep_taus=(), creep_weights=(), amplifier_tau=0.0)
    >>> sys = linear_system(part)
    >>> sys.dt, sys.states, sys.output
    (None, ['x', 'v'], 'position')
    """

    a: FloatArray
    b: FloatArray
    c: FloatArray
    d: FloatArray
    dt: float | None
    states: list[str]
    output: str


def linear_system(part: LinearPart, *, sample_time: float | None = None, delay: int = 0) -> LinearSystem:
    """The continuous system of ``part`` (``sample_time=None``), or its zero-order-hold
    discretization at ``sample_time`` with the output delayed by ``delay`` samples (the
    sensor's reading: output ``"measured"`` instead of ``"position"``).

    Parameters
    ----------
    part : LinearPart
        The linear part.
    sample_time : float, optional
        The sample time, s (``None``: continuous).
    delay : int, optional
        Whole samples of output delay (discrete only).

    Returns
    -------
    LinearSystem

    Examples
    --------
    >>> from piezohyst.plant.linear import LinearPart, linear_system
    >>> part = LinearPart(1.0, 2.0, 4.0, input_gain=4.0, tem=4.0, creep_taus=(), creep_weights=(), amplifier_tau=0.0)
    >>> sys = linear_system(part, sample_time=0.01, delay=2)
    >>> sys.a.shape, sys.states, sys.output
    ((4, 4), ['x', 'v', 'delay1', 'delay2'], 'measured')
    """
    a, b, c, d, names = state_space(part)
    if sample_time is None:
        return LinearSystem(a, b, c, d, None, names, "position")
    ts = as_scalar(sample_time, "sample_time", positive=True)
    ad, bd, cd, dd = discretize(a, b, c, d, ts, delay=delay)
    names = names + [f"delay{i}" for i in range(1, delay + 1)]
    return LinearSystem(ad, bd, cd, dd, ts, names, "measured" if delay else "position")
