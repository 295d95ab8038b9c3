"""Controllers and compensators. The step functions live in the Rust core
(``crates/core/src/control/``: ``mod.rs``, ``smc.rs``, ``absmc.rs``, ``cemf.rs``, ``compensated.rs``,
``ilc.rs``); these classes validate and carry the parameters.

Every controller takes the reference and the measured position (m) and returns a voltage
clamped to ``[u_min, u_max]`` (by default the stage amplifier's range). Model-based laws
estimate position and velocity with a :class:`VelocityObserver` (never a raw difference of
the quantized reading).

``controller.core(stage)`` gives what the core runs: ``(kind, params, inverse, ilc)``.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Protocol, TypeAlias, TypeVar, cast

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_int, as_scalar
from ..errors import ParameterError, ParameterTypeError
from ..signals.lti import (
    TRIM_RTOL,
    polynomial_tf,
    require_control,
    scipy_state_space,
    scipy_transfer_function,
    siso_polynomials,
    state_space,
)
from .filters import IDENTITY, IRC, PPF, BiquadCoefficients, LagLead, LowPass, Notch, Section

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..models.model import HysteresisModel
    from ..plant.stage import Stage, StageParameters
    from .simulation import ControllerLike

FloatArray: TypeAlias = npt.NDArray[np.float64]
#: Output limits ``(lower, upper)`` of a controller.
Limits: TypeAlias = tuple[float, float]
#: ``(family, dims, row, u_min, u_max)``: the exact inverse of a model the command passes through.
InverseSpec: TypeAlias = tuple[str, list[int], FloatArray, float, float]
#: ``(period, gain, forgetting, lead, delay)`` of iterative learning control.
IlcSpec: TypeAlias = tuple[int, float, float, int, int]
#: What ``controller.core(stage)`` gives the core: ``(kind, params, inverse, ilc)`` (one form
#: of ``_core``'s controller spec).
CoreSpec: TypeAlias = tuple[str, FloatArray, InverseSpec | None, IlcSpec | None]

_C = TypeVar("_C", bound="ControllerLike")


#: The description every controller's ``core`` shares (:func:`_core_doc` puts it ahead of
#: each one's own examples): the contract of :class:`DomainController` written once.
_CORE_DOC = """The controller as the Rust core runs it on ``stage``: ``(kind, params, inverse,
ilc)``, the flat parameters in the order of the core's layout table
(``piezohyst.export.CONTROLLER_PARAMS``), validated.

Parameters
----------
stage : Stage
    The plant: sample time, sensor delay, amplifier limits (and the static gain where
    a default depends on it).
limits : (float, float), optional
    Output limits when the controller acts behind an inverse model (metres); by
    default the amplifier's, in volts.

Returns
-------
tuple
    ``(kind, params, inverse, ilc)``: the kind's name, the parameter array, the
    inverse model's ``(family, dims, row, u_min, u_max)`` or ``None``, the ILC settings
    or ``None``.
"""

_M = TypeVar("_M", bound=Callable[..., Any])


def _core_doc(method: _M) -> _M:
    """A controller's ``core`` with the shared description (:data:`_CORE_DOC`) ahead of its own
    docstring, which holds its examples only."""
    method.__doc__ = _CORE_DOC + "\n" + inspect.cleandoc(method.__doc__ or "")
    return method


class PackedController(Protocol):
    """A controller whose ``core(stage)`` gives the tuple form :data:`CoreSpec` (every
    controller of piezohyst, and :class:`~piezohyst.export.c.ExportedController`)."""

    def core(self, stage: Stage) -> CoreSpec: ...


class DomainController(Protocol):
    """A controller that can act in another domain than volts (behind an inverse): its
    ``core`` takes the output ``limits`` of that domain."""

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec: ...


__all__ = [
    "ABSMC",
    "ILC",
    "PID",
    "SMC",
    "CemfFeedforward",
    "Compensated",
    "FilteredPID",
    "InverseFeedforward",
    "OpenLoop",
    "SampleRateWarning",
    "VelocityObserver",
    "cemf_model_parameters",
    "check_sample_rate",
]


def _pid_feedforward(c: PID | FilteredPID, stage: Stage, limits: Limits | None) -> float:
    """A PID law's gains checked for the core, and its static feedforward gain: the given
    ``ff_gain``, else 1 behind an inverse (the plant linearized to unit gain) or the stage's
    ``1 / static_gain``."""
    for name in ("kp", "ki", "kd"):
        as_scalar(getattr(c, name), name, nonnegative=True)
    as_scalar(c.tau_d, "tau_d", positive=True)
    if c.ff_gain is not None:
        return as_scalar(c.ff_gain, "ff_gain")
    return 1.0 if limits is not None else 1.0 / stage.params.static_gain


def _check_limits(u_min: object, u_max: object) -> None:
    """Output limits given at construction: each ``None`` (the amplifier's) or finite, ordered."""
    lo = None if u_min is None else as_scalar(u_min, "u_min")
    hi = None if u_max is None else as_scalar(u_max, "u_max")
    if lo is not None and hi is not None and not hi > lo:
        raise ParameterError(f"u_min = {lo} must be < u_max = {hi}")


def _check_optional(x: object, name: str, **kw: bool) -> None:
    if x is not None:
        as_scalar(x, name, **kw)


def _limits(u_min: float | None, u_max: float | None, stage: Stage) -> Limits:
    lo = stage.amplifier.v_min if u_min is None else as_scalar(u_min, "u_min")
    hi = stage.amplifier.v_max if u_max is None else as_scalar(u_max, "u_max")
    if not hi > lo:
        raise ParameterError(f"u_min = {lo} must be < u_max = {hi}")
    a = stage.amplifier
    # limits beyond the amplifier would let it clip where the controller cannot see it
    # (the integrator would wind up)
    if lo < a.v_min:
        raise ParameterError(f"u_min = {lo} V is below the amplifier's v_min = {a.v_min} V")
    if hi > a.v_max:
        raise ParameterError(f"u_max = {hi} V is above the amplifier's v_max = {a.v_max} V")
    return lo, hi


def _domain_limits(u_min: float | None, u_max: float | None, stage: Stage, limits: Limits | None) -> Limits:
    """Output limits: the amplifier's (volts) or, behind an inverse, the ones given."""
    if limits is not None:
        return limits
    return _limits(u_min, u_max, stage)


@dataclass(frozen=True)
class VelocityObserver:
    """Position and velocity from the quantized, delayed reading: a steady-state alpha-beta
    filter with a double pole at ``exp(-2 pi bandwidth Ts)``, projected ``delay`` samples
    ahead (by default the sensor's delay). See ``crates/core/src/control/mod.rs``.

    Parameters
    ----------
    bandwidth : float
        The filter's bandwidth, Hz (below the Nyquist frequency).
    delay : float, optional
        Samples of prediction (default: the stage sensor's delay).

    Examples
    --------
    >>> from piezohyst import PID, VelocityObserver, virtual_stage
    >>> VelocityObserver(bandwidth=1000.0).core(virtual_stage())   # bandwidth, Ts, delay
    [1000.0, 0.0001, 1.0]
    """

    bandwidth: float = 1000.0
    delay: float | None = None

    def __post_init__(self) -> None:
        as_scalar(self.bandwidth, "observer_bandwidth", positive=True)
        _check_optional(self.delay, "observer_delay", nonnegative=True)

    def core(self, stage: Stage) -> list[float]:
        """The observer's slots for the core: ``[bandwidth, Ts, delay]`` on ``stage``.

        Parameters
        ----------
        stage : Stage
            The plant (its sample time and sensor delay).

        Returns
        -------
        list of float

        Examples
        --------
        >>> from piezohyst import VelocityObserver, virtual_stage
        >>> VelocityObserver(300.0, delay=2.0).core(virtual_stage())
        [300.0, 0.0001, 2.0]
        """
        bw = as_scalar(self.bandwidth, "observer_bandwidth", positive=True)
        if bw >= 0.5 / stage.sample_time:
            raise ParameterError(
                f"observer_bandwidth = {bw} Hz must be below the Nyquist frequency {0.5 / stage.sample_time:g} Hz"
            )
        delay = stage.sensor.delay if self.delay is None else as_scalar(self.delay, "observer_delay", nonnegative=True)
        return [bw, stage.sample_time, float(delay)]

    def _matrices(self, sample_time: float, delay: float | None) -> tuple[FloatArray, ...]:
        ts = as_scalar(sample_time, "sample_time", positive=True)
        bw = as_scalar(self.bandwidth, "observer_bandwidth", positive=True)
        if bw >= 0.5 / ts:
            raise ParameterError(f"observer_bandwidth = {bw} Hz must be below the Nyquist frequency {0.5 / ts:g} Hz")
        given = self.delay if delay is None else delay
        dly = 0.0 if given is None else as_scalar(given, "observer_delay", nonnegative=True)
        p = math.exp(-2.0 * math.pi * bw * ts)
        gx, gv = 1.0 - p * p, (1.0 - p) ** 2 / ts
        # the state before a reading q = [x, v]; the update s = F q + G y; the report H s
        f = np.array([[1.0 - gx, (1.0 - gx) * ts], [-gv, 1.0 - gv * ts]])
        g = np.array([[gx], [gv]])
        h = np.array([[1.0, dly * ts], [0.0, 1.0]])
        return f, g, h @ f, h @ g

    def to_control(self, sample_time: float, *, delay: float | None = None) -> Any:
        """The observer as a discrete python-control ``StateSpace`` at ``sample_time`` (s):
        input the reading ``measured`` (m), outputs the estimates ``position`` (m, projected
        ``delay`` samples ahead) and ``velocity`` (m/s), as the core runs it
        (``crates/core/src/control/mod.rs``). ``delay`` defaults to this observer's ``delay``,
        else 0 (a stage's sensor delay is known only with the stage: ``observer.core(stage)``).

        Parameters
        ----------
        sample_time : float
            The controller's sample time, s (``> 0``; the bandwidth must lie below Nyquist).
        delay : float, optional
            Samples the position estimate is projected ahead (``>= 0``).

        Returns
        -------
        control.StateSpace
            Discrete (``dt = sample_time``), states ``x``, ``v`` before each reading.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import VelocityObserver
        >>> sys = VelocityObserver(bandwidth=300.0).to_control(1e-4)
        >>> sys.dt, sys.output_labels
        (0.0001, ['position', 'velocity'])
        >>> np.abs(sys.poles()).round(6).tolist()       # the double pole exp(-2 pi bandwidth Ts)
        [0.828204, 0.828204]
        """
        a, b, c, d = self._matrices(sample_time, delay)
        return state_space(
            a,
            b,
            c,
            d,
            sample_time,
            inputs=["measured"],
            outputs=["position", "velocity"],
            states=["x", "v"],
            name="velocity_observer",
        )

    def to_scipy(self, sample_time: float, *, delay: float | None = None) -> Any:
        """:meth:`to_control` as a ``scipy.signal.StateSpace`` (a ``dlti``).

        Parameters
        ----------
        sample_time : float
            The controller's sample time, s.
        delay : float, optional
            Samples the position estimate is projected ahead.

        Returns
        -------
        scipy.signal.StateSpace

        Examples
        --------
        >>> from piezohyst import VelocityObserver
        >>> VelocityObserver(300.0).to_scipy(1e-4).dt
        0.0001
        """
        a, b, c, d = self._matrices(sample_time, delay)
        return scipy_state_space(a, b, c, d, as_scalar(sample_time, "sample_time", positive=True))


@dataclass(frozen=True)
class OpenLoop:
    """``u = offset + gain (x_d + c1 x_d' + c2 x_d'')``: a static inverse (``gain`` in V/m;
    by default the stage's ``1 / static_gain``), optionally with velocity and acceleration
    feedforward that inverts second-order dynamics (``c1 = B/K`` s, ``c2 = M/K`` s²).

    Parameters
    ----------
    gain : float, optional
        V/m (default: the stage's ``1 / static_gain``; 1 behind an inverse model).
    offset : float
        Added to the command, V.
    c1, c2 : float
        Velocity and acceleration feedforward, s and s².
    u_min, u_max : float, optional
        Output limits (default: the amplifier's).
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> from piezohyst import OpenLoop, virtual_stage
    >>> kind, p, inverse, ilc = OpenLoop(gain=7e6).core(virtual_stage())
    >>> kind, p.tolist()
    ('open_loop', [7000000.0, 0.0, 0.0, 0.0, -20.0, 150.0])
    """

    gain: float | None = None
    offset: float = 0.0
    c1: float = 0.0
    c2: float = 0.0
    u_min: float | None = None
    u_max: float | None = None
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        _check_optional(self.gain, "gain")
        for name in ("offset", "c1", "c2"):
            as_scalar(getattr(self, name), name)
        _check_limits(self.u_min, self.u_max)

    @property
    def uses_reference_derivatives(self) -> bool:
        """Whether the step reads the reference's velocity and acceleration (``c1`` or ``c2`` set)."""
        return self.c1 != 0 or self.c2 != 0

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> from piezohyst import OpenLoop, virtual_stage
        >>> OpenLoop(gain=7e6, c1=1e-4).core(virtual_stage())[1].tolist()
        [7000000.0, 0.0, 0.0001, 0.0, -20.0, 150.0]
        """
        if self.gain is not None:
            gain = as_scalar(self.gain, "gain")
        else:  # behind an inverse the plant is linearized to unit gain
            gain = 1.0 if limits is not None else 1.0 / stage.params.static_gain
        lo, hi = _domain_limits(self.u_min, self.u_max, stage, limits)
        return (
            "open_loop",
            _pack(
                "open_loop",
                gain=gain,
                offset=as_scalar(self.offset, "offset"),
                c1=as_scalar(self.c1, "c1"),
                c2=as_scalar(self.c2, "c2"),
                u_min=lo,
                u_max=hi,
            ),
            None,
            None,
        )

    def _polynomials(self) -> tuple[list[float], list[float]]:
        if self.gain is None:
            raise ParameterError("gain = None is the stage's 1 / static_gain: give the gain (V/m) to convert it")
        g = as_scalar(self.gain, "gain")
        return [g * as_scalar(self.c2, "c2"), g * as_scalar(self.c1, "c1"), g], [1.0]

    def to_control(self) -> Any:
        """The feedforward ``x_d -> u`` as a continuous python-control ``TransferFunction``
        ``gain (c2 s^2 + c1 s + 1)`` (improper when ``c1`` or ``c2`` is non-zero: the core is
        given the reference's derivatives). The ``offset`` and the limits are not linear and
        are left out; ``gain`` must be given (not the stage's default).

        Returns
        -------
        control.TransferFunction
            Input ``reference`` (m), output ``command`` (V).

        Examples
        --------
        >>> from piezohyst import OpenLoop
        >>> tf = OpenLoop(gain=7e6, c1=1e-4).to_control()
        >>> [c.tolist() for c in (tf.num[0][0], tf.den[0][0])]
        [[700.0, 7000000.0], [1.0]]
        """
        num, den = self._polynomials()
        return polynomial_tf(num, den, inputs=["reference"], outputs=["command"], name="open_loop")

    def to_scipy(self) -> Any:
        """:meth:`to_control` as a ``scipy.signal.TransferFunction``: only without ``c1``,
        ``c2`` (scipy's systems are proper; ``ParameterError`` otherwise).

        Returns
        -------
        scipy.signal.TransferFunction

        Examples
        --------
        >>> from piezohyst import OpenLoop
        >>> OpenLoop(gain=7e6).to_scipy().num.tolist()
        [7000000.0]
        """
        num, den = self._polynomials()
        if num[0] != 0 or num[1] != 0:
            raise ParameterError(
                f"c1 = {self.c1}, c2 = {self.c2}: the feedforward is improper, which scipy.signal cannot hold; "
                "use to_control()"
            )
        return scipy_transfer_function(num[2:], den)

    @classmethod
    def from_control(cls, sys: object, **fields: Any) -> OpenLoop:
        """The feedforward ``gain (c2 s^2 + c1 s + 1)`` equal to ``sys``: a continuous
        transfer function whose denominator is a constant and whose numerator has degree at
        most 2 and a non-zero constant term. ``fields`` sets the rest (``offset``, ``u_min``,
        ``u_max``).

        Parameters
        ----------
        sys : control.LTI or scipy.signal.lti
            The feedforward, input metres, output volts.
        **fields
            The other fields of :class:`OpenLoop`.

        Returns
        -------
        OpenLoop

        Examples
        --------
        >>> import control
        >>> from piezohyst import OpenLoop
        >>> OpenLoop.from_control(control.tf([2.0, 4.0, 8.0], [2.0]))
        OpenLoop(gain=4.0, offset=0.0, c1=0.5, c2=0.25, u_min=None, u_max=None)
        """
        num, den, dt = siso_polynomials(sys, "sys")
        if dt is not None:
            raise ParameterError(f"sys is discrete (dt = {dt} s); the open-loop feedforward is continuous")
        if den.size != 1 or num.size > 3:
            raise ParameterError(
                f"sys must be gain (c2 s^2 + c1 s + 1): a constant denominator and a numerator of degree <= 2; "
                f"got degrees {num.size - 1} / {den.size - 1}"
            )
        c = np.concatenate([np.zeros(3 - num.size), num])
        if c[2] == 0.0:
            raise ParameterError("sys has no static gain (its numerator's constant term is 0)")
        gain = float(c[2])
        return cls(gain=gain, c1=float(c[1] / gain), c2=float(c[0] / gain), **fields)


@dataclass(frozen=True)
class PID:
    """PID with static feedforward, filtered derivative on the measurement and
    conditional-integration anti-windup::

        u = offset + ff_gain x_d + kp e + ki sum(e) Ts + D,   e = x_d - y
        D = a D - kd (1 - a) (y - y_prev) / Ts,   a = tau_d / (tau_d + Ts)

    Gains in V/m, V/(m s), V s/m; ``tau_d`` in s; ``ff_gain`` defaults to the stage's
    ``1 / static_gain`` (set 0 for pure feedback).

    Parameters
    ----------
    kp, ki, kd : float
        Proportional, integral and derivative gains (>= 0).
    tau_d : float
        Time constant of the derivative's filter, s.
    ff_gain : float, optional
        Static feedforward gain, V/m (default: ``1 / static_gain``; 1 behind an inverse).
    offset : float
        Added to the command, V.
    u_min, u_max : float, optional
        Output limits (default: the amplifier's).
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> stage = ph.virtual_stage()
    >>> res = ph.closed_loop(stage, ph.PID(kp=1e6, ki=5e9), np.full(3000, 5e-6), rng=1)
    >>> round(float(res.position[-500:].mean()) * 1e6, 2)          # um: the integral removes the offset
    5.02
    """

    kp: float = 0.0
    ki: float = 0.0
    kd: float = 0.0
    tau_d: float = 1e-4
    ff_gain: float | None = None
    offset: float = 0.0
    u_min: float | None = None
    u_max: float | None = None
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)

    #: the step uses only the reference position
    uses_reference_derivatives = False

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd"):  # a negative gain is positive feedback
            as_scalar(getattr(self, name), name, nonnegative=True)
        as_scalar(self.tau_d, "tau_d", positive=True)
        _check_optional(self.ff_gain, "ff_gain")
        as_scalar(self.offset, "offset")
        _check_limits(self.u_min, self.u_max)

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> from piezohyst import PID, virtual_stage
        >>> kind, params, inverse, ilc = PID(kp=1e6, ki=5e9).core(virtual_stage())
        >>> kind, params.size, inverse, ilc
        ('pid', 9, None, None)
        """
        ff = _pid_feedforward(self, stage, limits)
        lo, hi = _domain_limits(self.u_min, self.u_max, stage, limits)
        return (
            "pid",
            _pack(
                "pid",
                kp=self.kp,
                ki=self.ki,
                kd=self.kd,
                tau_d=self.tau_d,
                ts=stage.sample_time,
                ff_gain=ff,
                offset=as_scalar(self.offset, "offset"),
                u_min=lo,
                u_max=hi,
            ),
            None,
            None,
        )

    def _gains(self) -> tuple[float, float, float, float]:
        kp, ki, kd = (as_scalar(getattr(self, n), n, nonnegative=True) for n in ("kp", "ki", "kd"))
        return kp, ki, kd, as_scalar(self.tau_d, "tau_d", positive=True)

    def _polynomials(self, sample_time: float | None) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(num_y, den_y, num_r, den_r)``, highest power first: ``u = C_r r - C_y y`` as the
        core runs it (``crates/core/src/control/mod.rs``, ``Pid``), without limits and offset;
        a term whose gain is 0 leaves its pole out (a PI is ``(kp s + ki) / s``)."""
        kp, ki, kd, tau = self._gains()
        ff = 0.0 if self.ff_gain is None else as_scalar(self.ff_gain, "ff_gain")
        if sample_time is None:
            # C_y = kp + ki / s + kd s / (tau s + 1), C_r = ff + kp + ki / s
            integral = ([ki], [1.0, 0.0])
            derivative = ([kd, 0.0], [tau, 1.0])
        else:
            ts = as_scalar(sample_time, "sample_time", positive=True)
            a = tau / (tau + ts)
            # backward Euler: ki Ts z / (z - 1), kd / (tau + Ts) (z - 1) / (z - a)
            integral = ([ki * ts, 0.0], [1.0, -1.0])
            derivative = ([kd / (tau + ts), -kd / (tau + ts)], [1.0, -a])
        terms_y = [([kp], [1.0])] + ([integral] if ki else []) + ([derivative] if kd else [])
        terms_r = [([ff + kp], [1.0])] + ([integral] if ki else [])
        return (*_rational_sum(terms_y), *_rational_sum(terms_r))

    def to_control(self, sample_time: float | None = None, *, two_dof: bool = False) -> Any:
        """The PID as a python-control ``TransferFunction``, without its limits (anti-windup,
        saturation) and its ``offset``, which are not linear.

        Parameters
        ----------
        sample_time : float, optional
            ``None``: the continuous PID ``C(s) = kp + ki / s + kd s / (tau_d s + 1)``. A
            sample time (s; the stage's ``sample_time``): the discrete law the core runs at that
            rate, ``C(z) = kp + ki Ts z / (z - 1) + kd / (tau_d + Ts) (z - 1) / (z - a)`` with
            ``a = tau_d / (tau_d + Ts)`` (the backward-Euler image of ``C(s)``), ``dt`` set.
        two_dof : bool
            ``False``: the feedback ``C`` from the error ``e = r - y`` to ``u`` (the loop gain
            is ``C P``; the derivative acts on the measurement, which changes the response to
            the reference only). ``True``: both inputs, ``u = C_r r - C_y y`` with ``C_r = ff_gain
            + kp + ki / s`` (no derivative; ``ff_gain = None`` is taken as 0) and ``C_y = C``:
            a 1x2 system with inputs ``reference`` and ``measured``.

        Examples
        --------
        >>> from piezohyst import PID
        >>> c = PID(kp=2.0, ki=10.0, kd=0.5, tau_d=0.01).to_control()
        >>> [x.round(6).tolist() for x in (c.num[0][0], c.den[0][0])]
        [[0.52, 2.1, 10.0], [0.01, 1.0, 0.0]]
        >>> PID(kp=2.0, ki=10.0).to_control(1e-3).dt
        0.001
        """
        num_y, den_y, num_r, den_r = self._polynomials(sample_time)
        if not two_dof:
            return polynomial_tf(num_y, den_y, sample_time, inputs=["error"], outputs=["command"], name="pid")
        # a state space (python-control converts a MIMO transfer function only with slycot):
        # C_r and C_y realized each, side by side, u = C_r r - C_y y
        ct = require_control()
        step = 0 if sample_time is None else sample_time
        r_part, y_part = (ct.ss(ct.tf(n, d, step)) for n, d in ((num_r, den_r), (num_y, den_y)))
        a = _block_diagonal([r_part.A, y_part.A])
        b = _block_diagonal([r_part.B, -y_part.B])
        c = np.hstack([r_part.C, y_part.C])
        d = np.hstack([r_part.D, -y_part.D])
        return state_space(a, b, c, d, sample_time, inputs=["reference", "measured"], outputs=["command"], name="pid")

    def to_scipy(self, sample_time: float | None = None) -> Any:
        """The feedback ``C`` of :meth:`to_control` as a ``scipy.signal.TransferFunction``
        (a ``dlti`` with ``sample_time``).

        Parameters
        ----------
        sample_time : float, optional
            ``None``: continuous; a sample time (s): the discrete law the core runs.

        Returns
        -------
        scipy.signal.TransferFunction

        Examples
        --------
        >>> from piezohyst import PID
        >>> PID(kp=2.0, ki=10.0).to_scipy().den.tolist()
        [1.0, 0.0]
        """
        num_y, den_y, _, _ = self._polynomials(sample_time)
        return scipy_transfer_function(num_y, den_y, sample_time)

    @classmethod
    def from_control(cls, sys: object, **fields: Any) -> PID:
        """The PID whose feedback :meth:`to_control` is ``sys``: a continuous transfer function
        of the form ``kp + ki / s + kd s / (tau_d s + 1)`` (denominator ``s (tau_d s + 1)``,
        ``s``, ``tau_d s + 1`` or a constant), or a discrete one of the form the core runs
        (denominator ``(z - 1)(z - a)``, ``z - 1``, ``z - a`` or a constant, ``0 < a < 1``; the
        sample time is the system's ``dt``). Gains must come out non-negative and ``tau_d``
        positive; anything else raises ``ParameterError`` saying why. ``fields`` sets the rest:
        ``ff_gain`` defaults to 0 (the transfer function is pure feedback), ``tau_d`` of a PID
        without derivative to 1e-4 s.

        Parameters
        ----------
        sys : control.LTI or scipy.signal.lti
            The feedback controller, input the error (m), output volts.
        **fields
            The other fields of :class:`PID` (``ff_gain``, ``offset``, ``u_min``, ``u_max``).

        Returns
        -------
        PID

        Examples
        --------
        >>> import control
        >>> from piezohyst import PID
        >>> s = control.tf("s")
        >>> pid = PID.from_control(2 + 10 / s + 0.5 * s / (0.01 * s + 1))
        >>> round(pid.kp, 9), round(pid.ki, 9), round(pid.kd, 9), round(pid.tau_d, 9)
        (2.0, 10.0, 0.5, 0.01)
        """
        num, den, dt = siso_polynomials(sys, "sys")
        kp, ki, kd, tau = _pid_gains(num, den, dt)
        values: dict[str, Any] = {"kp": kp, "ki": ki, "kd": kd, "ff_gain": 0.0}
        if tau is not None:
            values["tau_d"] = tau
        values.update(fields)
        pid = cls(**values)
        pid._gains()
        return pid


def _block_diagonal(blocks: Sequence[npt.ArrayLike]) -> FloatArray:
    """The block-diagonal matrix of ``blocks`` (2-D; empty blocks allowed)."""
    mats = [np.atleast_2d(np.asarray(m, dtype=np.float64)) for m in blocks]
    rows = sum(m.shape[0] for m in mats)
    cols = sum(m.shape[1] for m in mats)
    out = np.zeros((rows, cols))
    i = j = 0
    for m in mats:
        out[i : i + m.shape[0], j : j + m.shape[1]] = m
        i += m.shape[0]
        j += m.shape[1]
    return out


def _rational_sum(terms: Sequence[tuple[Sequence[float], Sequence[float]]]) -> tuple[FloatArray, FloatArray]:
    """``sum num_i / den_i`` as one ``(num, den)``, highest power first."""
    num: FloatArray = np.zeros(1)
    den: FloatArray = np.ones(1)
    for n_i, d_i in terms:
        n_arr, d_arr = np.asarray(n_i, dtype=np.float64), np.asarray(d_i, dtype=np.float64)
        num = np.asarray(np.polyadd(np.polymul(num, d_arr), np.polymul(n_arr, den)), dtype=np.float64)
        den = np.asarray(np.polymul(den, d_arr), dtype=np.float64)
    lead = int(np.argmax(num != 0)) if np.any(num) else num.size - 1  # exact leading zeros only
    return num[lead:], den


_FilterLike: TypeAlias = "Notch | LowPass | LagLead | PPF | Section"


@dataclass(frozen=True)
class FilteredPID:
    """The practitioner's loop: a PID with notch filters on its output, a feedforward that
    inverts identified dynamics, and a damping loop (positive position feedback)::

        u = offset + ff_gain F[x_d] + c1 x_d' + c2 x_d''     feedforward (F: ff_filters)
            + N[PID(e)]                                     feedback through the notches N
            + H[y]                                          damping loop (PPF)
        e = x_d(t - error_delay) - y                        the reference as old as the reading

    The PID is :class:`PID`'s law (filtered derivative on the measurement, conditional
    integration while saturated). ``ff_filters`` (at most two) and ``notches`` (at most three;
    any filter of :mod:`piezohyst.control.filters`: :class:`~piezohyst.control.filters.Notch`,
    :class:`~piezohyst.control.filters.LowPass`, :class:`~piezohyst.control.filters.LagLead`)
    are written in continuous time and discretized for the stage's sample time;
    ``damping`` is a :class:`~piezohyst.control.filters.PPF`. ``ff_gain`` defaults to the stage's
    ``1 / static_gain`` (1 behind an inverse, :class:`Compensated`). ``error_delay`` (samples;
    default: the stage's sensor delay) compares the reading with the reference as it was when
    the reading was taken (``x_d - d x_d' + d^2 x_d'' / 2``, ``d = error_delay Ts``), so the
    feedback does not fight the sensor's delay at high frequency (0: the plain ``x_d - y``).
    The step runs in the Rust core (``crates/core/src/control/filtered.rs``, kind
    ``filtered_pid``).

    :meth:`DynamicInversion.feedforward` gives ``ff_gain``, ``ff_filters``, ``c1``, ``c2`` that
    invert a stage's identified dynamics; behind the hysteresis inverse
    (``Compensated(FilteredPID(...), model)``) that is the dynamic-inversion feedforward.

    Parameters
    ----------
    kp, ki, kd : float
        Proportional, integral and derivative gains (>= 0), V/m, V/(m s), V s/m.
    tau_d : float
        Time constant of the derivative's filter, s.
    ff_gain : float, optional
        Static feedforward gain, V/m (default: ``1 / static_gain``; 1 behind an inverse).
    c1, c2 : float
        Velocity and acceleration lead of the feedforward, V s/m and V s^2/m.
    ff_filters : tuple of filters
        At most two filters applied to the reference in the feedforward.
    notches : tuple of filters
        At most three filters on the PID's output.
    damping : PPF, optional
        The damping loop on the reading.
    offset : float
        Added to the command, V.
    error_delay : float, optional
        Samples the reference is delayed by in the error (default: the stage's sensor delay).
    u_min, u_max : float, optional
        Output limits (default: the amplifier's).
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.control.filters import Notch
    >>> stage = ph.virtual_stage()
    >>> c = ph.FilteredPID(kp=4e4, ki=1.4e10, notches=(Notch(4500.0, width=0.3),))
    >>> _, ref = ph.sine(10, 4e-6, 0.2, 1 / stage.sample_time, offset=8e-6)
    >>> bool(ph.track(c, ref, stage=stage, rng=1, skip=0.1).metrics["rmse"] < 0.05e-6)
    True
    """

    kp: float = 0.0
    ki: float = 0.0
    kd: float = 0.0
    tau_d: float = 1e-4
    ff_gain: float | None = None
    c1: float = 0.0
    c2: float = 0.0
    ff_filters: tuple[_FilterLike, ...] = ()
    notches: tuple[_FilterLike, ...] = ()
    damping: PPF | IRC | None = None
    offset: float = 0.0
    error_delay: float | None = None
    u_min: float | None = None
    u_max: float | None = None
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)

    #: the step reads the reference's velocity and acceleration (feedforward lead, error delay)
    uses_reference_derivatives = True

    def _filters(
        self, sample_time: float
    ) -> tuple[list[BiquadCoefficients], list[BiquadCoefficients], BiquadCoefficients]:
        ff, notches = tuple(self.ff_filters), tuple(self.notches)
        if len(ff) > 2:
            raise ParameterError(f"ff_filters has {len(ff)} filters, at most 2")
        if len(notches) > 3:
            raise ParameterError(f"notches has {len(notches)} filters, at most 3")
        for name, group in (("ff_filters", ff), ("notches", notches)):
            for j, f in enumerate(group):
                if not isinstance(f, (Notch, LowPass, LagLead, PPF, Section)):
                    raise ParameterTypeError(
                        f"{name}[{j}] must be a filter of piezohyst.control.filters (Notch, LowPass, LagLead, "
                        f"Section), got {type(f).__name__}"
                    )
        if self.damping is not None and not isinstance(self.damping, (PPF, IRC)):
            raise ParameterTypeError(f"damping must be a PPF or an IRC, got {type(self.damping).__name__}")
        ffq = [f.biquad(sample_time) for f in ff] + [IDENTITY] * (2 - len(ff))
        nq = [f.biquad(sample_time) for f in notches] + [IDENTITY] * (3 - len(notches))
        dq = IDENTITY if self.damping is None else self.damping.biquad(sample_time)
        if isinstance(self.damping, PPF) and self.damping.gain == 0:
            dq = IDENTITY
        return ffq, nq, dq

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> from piezohyst import FilteredPID, virtual_stage
        >>> kind, params, inverse, ilc = FilteredPID(kp=4e4, ki=1.4e10).core(virtual_stage())
        >>> kind, params.size, inverse, ilc
        ('filtered_pid', 42, None, None)
        """
        ff = _pid_feedforward(self, stage, limits)
        lo, hi = _domain_limits(self.u_min, self.u_max, stage, limits)
        ffq, nq, dq = self._filters(stage.sample_time)
        if isinstance(self.damping, PPF) and self.damping.gain != 0 and dq == IDENTITY:
            dq = self.damping.biquad(stage.sample_time)
        coefs = ("b0", "b1", "b2", "a1", "a2")
        biquads: dict[str, float] = {}
        for prefix, q in [("ff1", ffq[0]), ("ff2", ffq[1]), ("notch1", nq[0]), ("notch2", nq[1]), ("notch3", nq[2])]:
            biquads.update({f"{prefix}_{c}": v for c, v in zip(coefs, q, strict=True)})
        biquads.update({f"damping_{c}": v for c, v in zip(coefs, dq, strict=True)})
        return (
            "filtered_pid",
            _pack(
                "filtered_pid",
                kp=self.kp,
                ki=self.ki,
                kd=self.kd,
                tau_d=self.tau_d,
                ts=stage.sample_time,
                ff_gain=ff,
                c1=as_scalar(self.c1, "c1"),
                c2=as_scalar(self.c2, "c2"),
                offset=as_scalar(self.offset, "offset"),
                error_delay=stage.sample_time
                * (
                    stage.sensor.delay
                    if self.error_delay is None
                    else as_scalar(self.error_delay, "error_delay", nonnegative=True)
                ),
                **biquads,
                u_min=lo,
                u_max=hi,
            ),
            None,
            None,
        )

    def to_control(self, sample_time: float) -> Any:
        """The feedback as a discrete python-control ``TransferFunction`` at ``sample_time``:
        ``u = -C(z) y`` for a fixed reference, ``C = N(z) PID(z) - H(z)`` (the notches times the
        PID the core runs, less the damping loop), so the loop gain with a stage ``P`` is ``C P``
        (:func:`piezohyst.loop_margins`). Limits, offset and feedforward are left out.

        Parameters
        ----------
        sample_time : float
            The loop's sample time, s.

        Returns
        -------
        control.TransferFunction
            Input ``measured`` (m), output ``command``, ``dt = sample_time``.

        Examples
        --------
        >>> import piezohyst as ph
        >>> from piezohyst.control.filters import Notch
        >>> c = ph.FilteredPID(kp=1e4, ki=1e9, notches=(Notch(3000.0),)).to_control(1e-4)
        >>> c.dt, len(c.den[0][0])                     # integrator, notch: order 3
        (0.0001, 4)
        """
        ct = require_control()
        ts = as_scalar(sample_time, "sample_time", positive=True)
        _, nq, dq = self._filters(ts)
        num, den, _, _ = PID(kp=self.kp, ki=self.ki, kd=self.kd, tau_d=self.tau_d)._polynomials(ts)
        c = ct.tf(num, den, ts)
        for q in nq:
            if q != IDENTITY:
                c = c * ct.tf([q[0], q[1], q[2]], [1.0, q[3], q[4]], ts)
        if dq != IDENTITY:
            c = c - ct.tf([dq[0], dq[1], dq[2]], [1.0, dq[3], dq[4]], ts)
        num_c, den_c, _ = siso_polynomials(c, "feedback")
        return polynomial_tf(num_c, den_c, ts, inputs=["measured"], outputs=["command"], name="filtered_pid")


def _pid_gains(num: FloatArray, den: FloatArray, dt: float | None) -> tuple[float, float, float, float | None]:
    """``(kp, ki, kd, tau_d or None)`` of a feedback transfer function of PID form
    (``num``/``den`` highest power first, ``den`` monic; ``dt`` the sample time or ``None``).

    The gains come in closed form (partial fractions), the numerator summed exactly and the
    filter's pole read from ``den``'s coefficients. A discrete PID's poles lie close together
    (1 and ``a = tau_d / (tau_d + Ts)``) and its numerator nearly vanishes at 1
    (``ki Ts (1 - a)`` from coefficients near ``kd / Ts``): the eigenvalue solver's 1e-14 on such
    a pair cost ``ki`` 1e-9 of itself, and a least-squares solve gave a gain of 0 back as a
    rounding residue (9e-20)."""
    form = (
        "kp + ki / s + kd s / (tau_d s + 1)"
        if dt is None
        else "kp + ki Ts z / (z - 1) + kd / (tau_d + Ts) (z - 1) / (z - a)"
    )

    def refuse(why: str) -> ParameterError:
        return ParameterError(f"sys is not of PID form {form}: {why}")

    if den.size > 3 or num.size > den.size:
        raise refuse(f"numerator degree {num.size - 1}, denominator degree {den.size - 1}")
    roots = np.roots(den) if den.size > 1 else np.zeros(0, dtype=np.complex128)
    if np.any(roots.imag != 0):
        raise refuse(f"complex poles {roots.tolist()}")
    poles = sorted(roots.real.tolist(), reverse=True)
    # the integrator's pole, and the zero of the derivative's term: s = 0, z = 1
    p_int = 0.0 if dt is None else 1.0
    size = max([1.0, *(abs(p) for p in poles)])
    integrator = bool(poles) and abs(poles[0] - p_int) <= 1e-9 * size
    rest = poles[1:] if integrator else poles
    if len(rest) > 1:
        raise refuse(f"poles {poles}")
    # the filter's pole from the coefficients (the roots of the monic den sum to -den[1]),
    # not the eigenvalue solver's
    filt = -float(den[1]) - (p_int if integrator else 0.0) if rest else None
    if filt is not None and not ((filt < 0) if dt is None else (0 < filt < 1)):
        raise refuse(f"the derivative filter's pole {filt} must be {'< 0' if dt is None else 'in (0, 1)'}")
    n = np.zeros(den.size)  # the numerator, powers ascending, as long as den
    n[: num.size] = num[::-1]

    def at(x: float) -> float:
        """The numerator at ``x``, its terms summed exactly."""
        return math.fsum(float(c) * x**k for k, c in enumerate(n))

    # C = kp + r I + h D, I = 1 / s or z / (z - 1) (r = ki or ki Ts), D = s / (s - f) or
    # (z - 1) / (z - a) (h = kd / tau_d or kd / (tau_d + Ts)): each gain from the coefficient
    # it alone sets, a residue at its pole or the numerator where the other terms vanish
    kp = r = h = 0.0
    if integrator and filt is not None:
        if dt is None:  # n = [-f ki, -f kp + ki, kp + h]
            r = float(n[0]) / -filt
            kp = (float(n[1]) - r) / -filt
            h = float(n[2]) - kp
            terms = (abs(float(n[1])) + abs(r)) / -filt
        else:  # residues at 1 and a; kp what is left at infinity, n[2] = kp + ki Ts + h
            r = at(1.0) / (1.0 - filt)
            h = at(filt) / (filt - 1.0) ** 2
            kp = float(n[2]) - r - h
            terms = abs(float(n[2])) + abs(r) + abs(h)
        # kp is a difference here: below TRIM_RTOL of the terms it is taken from, it is their
        # rounding residue (a PID without kp), as a leading coefficient is in siso_polynomials
        if abs(kp) <= TRIM_RTOL * terms:
            kp = 0.0
    elif integrator:  # n = [ki, kp] or [-kp, kp + ki Ts]
        r = at(p_int)
        kp = float(n[1]) if dt is None else -float(n[0])
    elif filt is not None:  # D vanishes at p_int; n[1] = kp + h
        kp = at(p_int) / (p_int - filt)
        h = float(n[1]) - kp
    else:
        kp = float(n[0])
    ki = r / (1.0 if dt is None else dt)
    tau: float | None = None
    kd = 0.0
    if filt is not None:
        tau = -1.0 / filt if dt is None else filt * dt / (1.0 - filt)
        kd = h * (tau if dt is None else tau + dt)
    largest = max(abs(kp), abs(ki), abs(kd))
    for name, value in (("kp", kp), ("ki", ki), ("kd", kd)):
        if value < -1e-9 * largest:
            raise ParameterError(f"sys gives {name} = {value:.6g}: the PID's gains are non-negative")
    # a residue within the tolerance above, or -0.0, is a gain of 0
    return kp if kp > 0 else 0.0, ki if ki > 0 else 0.0, kd if kd > 0 else 0.0, tau


def _check_sliding(kp: float, kv: float, alpha: float) -> None:
    """SMC's sliding dynamics ``e'' + (kv + alpha) e' + (alpha kv + kp) e = 0`` must be stable."""
    if alpha < 0:
        raise ParameterError(f"alpha = {alpha} must be >= 0")
    if not kv + alpha > 0:
        raise ParameterError(f"kv + alpha = {kv + alpha} must be > 0: the sliding dynamics would be unstable")
    if not alpha * kv + kp > 0:
        raise ParameterError(f"alpha * kv + kp = {alpha * kv + kp} must be > 0: the sliding dynamics would be unstable")


def _theta_bounds(bounds: object, n: int) -> tuple[list[float], list[float]]:
    """ABSMC's ``theta_bounds``: ``[[lower...], [upper...]]``, ``n`` finite values each, lower <= upper."""
    try:
        pair = list(cast("Sequence[Sequence[object]]", bounds))
        if len(pair) != 2:
            raise TypeError
        lo = [as_scalar(x, f"theta_bounds[0][{i}]") for i, x in enumerate(pair[0])]
        hi = [as_scalar(x, f"theta_bounds[1][{i}]") for i, x in enumerate(pair[1])]
    except (TypeError, ValueError) as e:
        if isinstance(e, (ParameterError, ParameterTypeError)):  # a value named by its index
            raise
        raise ParameterTypeError(f"theta_bounds must be [[lower...], [upper...]], got {bounds!r}") from None
    if len(lo) != n or len(hi) != n:
        raise ParameterError(f"theta_bounds must hold {n} lower and {n} upper values, got {len(lo)} and {len(hi)}")
    for i, (a, b) in enumerate(zip(lo, hi, strict=True)):
        if a > b:
            raise ParameterError(f"theta_bounds[0][{i}] = {a} must be <= theta_bounds[1][{i}] = {b}")
    return lo, hi


def _check_observer(observer: object) -> None:
    if not isinstance(observer, VelocityObserver):
        raise ParameterTypeError(f"observer must be a VelocityObserver, got {type(observer).__name__}")


def _stage_parameters(params: object) -> StageParameters:
    """``params`` if it is :class:`StageParameters`, else ``ParameterTypeError``."""
    from ..plant.stage import StageParameters

    if not isinstance(params, StageParameters):
        raise ParameterTypeError(
            f"model must be StageParameters (e.g. identify_cemf(...).model), got {type(params).__name__}"
        )
    return params


def cemf_model_parameters(params: StageParameters) -> dict[str, float]:
    """The volt-normalized CEMF model of seed 1 from (identified) stage parameters:
    ``M = m/Tem``, ``B = b/Tem``, ``K = k/Tem`` and the charge-driven Bouc–Wen law.

    Parameters
    ----------
    params : StageParameters
        Stage parameters with a charge-driven CEMF (e.g. :func:`piezohyst.identify_cemf`'s model).

    Returns
    -------
    dict
        ``M``, ``B``, ``K``, ``tem``, ``capacitance``, ``alpha``, ``beta``, ``gamma``.

    Examples
    --------
    >>> from piezohyst import virtual_stage
    >>> from piezohyst.control import cemf_model_parameters
    >>> c = cemf_model_parameters(virtual_stage().params)
    >>> round(c["M"], 6), round(c["K"]), c["alpha"]
    (0.0068, 6983810, 125000.0)
    """
    params = _stage_parameters(params)
    if params.hyst_drive != "charge":
        raise ParameterError(f"model.hyst_drive = {params.hyst_drive!r}: the CEMF observer needs the charge-driven law")
    t = params.tem
    return {
        "M": params.mass / t,
        "B": params.damping / t,
        "K": params.stiffness / t,
        "tem": t,
        "capacitance": params.capacitance,
        "alpha": params.hyst_alpha,
        "beta": params.hyst_beta,
        "gamma": params.hyst_gamma,
    }


def _pack(kind: str, **values: float) -> FloatArray:
    """The flat parameter array of a controller kind from its values by slot name, in the
    order of the core's layout table (``_core.controller_layout``)."""
    slots = _core.controller_layout(kind)["slots"]
    assert set(values) == set(slots), (kind, sorted(set(values) ^ set(slots)))
    return np.array([values[name] for name in slots], dtype=float)


def _slot_count(kind: str, name: str) -> int:
    """How many indexed slots ``name_0``, ``name_1``, ... a controller kind has (the core's
    layout table)."""
    slots = _core.controller_layout(kind)["slots"]
    return sum(1 for s in slots if s.startswith(f"{name}_") and s[len(name) + 1 :].isdigit())


def _cemf_slots(params: StageParameters) -> dict[str, float]:
    c = cemf_model_parameters(params)
    names = {"M": "M", "B": "B", "K": "K", "tem": "tem", "capacitance": "capacitance"}
    return {**{slot: c[key] for slot, key in names.items()}, **{f"hyst_{k}": c[k] for k in ("alpha", "beta", "gamma")}}


def _observer_slots(observer: VelocityObserver, stage: Stage) -> dict[str, float]:
    return dict(zip(("observer_bandwidth", "ts", "observer_delay"), observer.core(stage), strict=True))


@dataclass(frozen=True)
class SMC:
    """Extended sliding-mode control with a dynamic compensator (seed 1)::

        e = x_d - x,  xi' = -alpha xi + e,  s = e' + kv e + kp xi
        u = M (x_d'' + kv e' + kp e - alpha kp xi) + B x' + K x + [Vh] + Ks sat(s / phi)

    ``model`` is the identified CEMF stage model (:class:`StageParameters`, e.g. from
    :func:`piezohyst.identify_cemf`); ``cemf=True`` adds the CEMF observer estimate ``Vh``
    (seed 1's Case 2), ``False`` omits it (Case 1). ``switching="super_twisting"`` replaces
    ``Ks sat(s/phi)`` by ``k1 |s|^(1/2) sign(s) + nu``, ``nu' = k2 sign(s)`` (chattering-free).
    Units: ``kp`` 1/s², ``kv`` and ``alpha`` 1/s, ``ks`` V, ``phi`` m/s.
    ``model_terms="desired"`` (the default) evaluates ``B x' + K x`` on the reference
    (desired compensation: the stage's own stiffness and damping act on the error, and the loop
    recovers from a voltage limit); ``"measured"`` is seed 1's form on the measured motion, a
    positive feedback of the position estimate that latches at a voltage limit when the
    identified stiffness asks for more than the amplifier gives (kept for reproducing seed 1).
    The sliding dynamics ``e'' + (kv + alpha) e' + (alpha kv + kp) e = 0`` must be stable.

    Every gain is in continuous time (the observer's bandwidth in Hz, ``xi`` integrated
    exactly), so the law itself is the same at any rate; what does change with the rate is the
    loop's delay, counted in samples (the sensor's delay and the zero-order hold): at 5 kHz it
    is twice what it is at 10 kHz. ``rate_aware=True`` (the default) keeps the switching loop's
    delay margin when the controller runs slower than it was tuned at
    (``tuned_sample_time``, set by :func:`~piezohyst.tune`): the boundary layer ``phi`` is
    widened by ``Ts / tuned_sample_time`` (the switching loop's crossover ``~ ks / phi`` moves
    down with the delay, so ``crossover x delay`` stays), super-twisting's ``k1`` and ``k2``
    lowered by that ratio and its square (their homogeneity degrees). Faster than tuned, or
    never tuned, the gains are used as given. Measured (tests/control/test_rate_aware.py):
    tuned at 10 kHz, SMC loses the loop at 5 kHz without it (2.1 µm RMSE on a 5 µm triangle)
    and holds 0.019 µm with it (0.019 at 10 kHz); SMC + CEMF holds 0.029 µm at 5 kHz (0.016 at
    10 kHz); at 20 and 50 kHz both do better than at 10 kHz.

    Parameters
    ----------
    model : StageParameters
        The identified CEMF stage model.
    kp, kv, alpha : float
        The sliding surface's gains (1/s², 1/s) and the compensator's pole (1/s, >= 0).
    ks, phi : float
        Switching gain (V) and boundary layer (m/s).
    cemf : bool
        Add the CEMF observer's estimate (seed 1's Case 2).
    switching : {"boundary_layer", "super_twisting"}
        The switching law.
    k1, k2 : float
        Super-twisting gains.
    model_terms : {"measured", "desired"}
        Evaluate ``B x' + K x`` on the measured motion (seed 1) or on the reference.
    observer : VelocityObserver
        Position and velocity estimator.
    u_min, u_max : float, optional
        Output limits (default: the amplifier's).
    rate_aware : bool
        Widen the boundary layer (super-twisting: lower ``k1``, ``k2``) when run slower than
        tuned (:meth:`rate_scale`).
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> import piezohyst as ph
    >>> stage = ph.virtual_stage()
    >>> smc = ph.SMC(stage.params, kp=1e6, kv=2e3, ks=20.0, cemf=True)
    >>> t, ref = ph.triangle(5, 5e-6, 0.4, 1e4, offset=7e-6)
    >>> m = ph.track(smc, ref, stage=stage, rng=1, skip=0.2).metrics
    >>> bool(m["rmse"] < 0.1e-6)
    True
    >>> ph.SMC(stage.params, kv=-3.0).core(stage)
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: kv + alpha = -3.0 must be > 0: the sliding dynamics would be unstable
    """

    model: StageParameters
    kp: float = 1e6
    kv: float = 2e3
    alpha: float = 0.0
    ks: float = 20.0
    phi: float = 0.01
    cemf: bool = False
    switching: str = "boundary_layer"
    k1: float = 0.0
    k2: float = 0.0
    model_terms: str = "desired"
    observer: VelocityObserver = field(default_factory=lambda: VelocityObserver(300.0))
    u_min: float | None = None
    u_max: float | None = None
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)
    rate_aware: bool = True

    uses_reference_derivatives = True

    def __post_init__(self) -> None:
        _stage_parameters(self.model)
        kp, kv, alpha = (as_scalar(getattr(self, n), n) for n in ("kp", "kv", "alpha"))
        _check_sliding(kp, kv, alpha)
        as_scalar(self.ks, "ks", nonnegative=True)
        as_scalar(self.phi, "phi", positive=True)
        as_scalar(self.k1, "k1", nonnegative=True)
        as_scalar(self.k2, "k2", nonnegative=True)
        if not isinstance(self.cemf, (bool, np.bool_)):
            raise ParameterTypeError(f"cemf must be True or False, got {self.cemf!r}")
        if self.switching not in ("boundary_layer", "super_twisting"):
            raise ParameterError(f"switching = {self.switching!r} must be 'boundary_layer' or 'super_twisting'")
        if self.model_terms not in ("measured", "desired"):
            raise ParameterError(f"model_terms = {self.model_terms!r} must be 'measured' or 'desired'")
        _check_observer(self.observer)
        _check_limits(self.u_min, self.u_max)

    def rate_scale(self, sample_time: float) -> float:
        """The factor the loop's delay grows by at ``sample_time`` (s) against the rate the
        controller was tuned at: ``max(1, sample_time / tuned_sample_time)``, 1 when it was
        never tuned or ``rate_aware`` is off.

        Parameters
        ----------
        sample_time : float
            The sample time the controller runs at, s.

        Returns
        -------
        float

        Examples
        --------
        >>> import piezohyst as ph
        >>> smc = ph.SMC(ph.virtual_stage().params, tuned_sample_time=1e-4)
        >>> smc.rate_scale(2e-4), smc.rate_scale(5e-5)
        (2.0, 1.0)
        """
        ts = as_scalar(sample_time, "sample_time", positive=True)
        if not self.rate_aware or self.tuned_sample_time is None:
            return 1.0
        return max(1.0, ts / as_scalar(self.tuned_sample_time, "tuned_sample_time", positive=True))

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> from piezohyst import SMC, virtual_stage
        >>> stage = virtual_stage()
        >>> kind, params, inverse, ilc = SMC(stage.params, cemf=True).core(stage)
        >>> kind, params.size
        ('smc', 21)
        """
        cemf = _cemf_slots(self.model)
        scale = self.rate_scale(stage.sample_time)
        kp, kv, alpha = (as_scalar(getattr(self, n), n) for n in ("kp", "kv", "alpha"))
        _check_sliding(kp, kv, alpha)
        if self.switching == "boundary_layer":
            sw = [0.0, as_scalar(self.ks, "ks", nonnegative=True), as_scalar(self.phi, "phi", positive=True) * scale]
        elif self.switching == "super_twisting":
            k1 = as_scalar(self.k1, "k1", nonnegative=True) / scale
            sw = [1.0, k1, as_scalar(self.k2, "k2", nonnegative=True) / scale**2]
        else:
            raise ParameterError(f"switching = {self.switching!r} must be 'boundary_layer' or 'super_twisting'")
        if self.model_terms not in ("measured", "desired"):
            raise ParameterError(f"model_terms = {self.model_terms!r} must be 'measured' or 'desired'")
        lo, hi = _domain_limits(self.u_min, self.u_max, stage, limits)
        p = _pack(
            "smc",
            **cemf,
            kp=kp,
            kv=kv,
            alpha=alpha,
            **dict(zip(("switching", "ks_or_k1", "phi_or_k2"), sw, strict=True)),
            **_observer_slots(self.observer, stage),
            cemf=1.0 if self.cemf else 0.0,
            desired_model_terms=1.0 if self.model_terms == "desired" else 0.0,
            u_min=lo,
            u_max=hi,
        )
        return "smc", p, None, None


@dataclass(frozen=True)
class ABSMC:
    """Adaptive backstepping sliding-mode control (seed 2) for ``x'' = theta^T phi + b u + d``,
    ``phi = [-x, -x']``::

        e1 = x - x_d,  alpha1 = x_d' - c1 e1,  e2 = x' - alpha1,  s = lam e1 + e2
        u = (1/b) [-theta^T phi + alpha1' - lam (e2 - c1 e1) - e1 - ks s - D sat(s/phi)]
        theta' = Gamma phi s,   D' = gamma_d |s|      (projected onto their bounds)

    Build it with :meth:`for_stage` (alone, in volts: ``b = 1/M``, ``theta = [K/M, B/M]``) or
    :meth:`linearized` (behind an inverse model, in metres: ``b = theta0 = omega_n^2``).
    ``theta_bounds`` default to a factor ``theta_range`` around the nominal values.
    ``regressor="desired"`` (default) evaluates ``phi`` on the reference, ``"measured"`` on the
    observer's estimate as seed 2 writes it; the measured form cancels the stage stiffness with
    a delayed, quantized position and loses stability on a stiff stage (see
    ``crates/core/src/control/absmc.rs``).

    Parameters
    ----------
    b : float
        Input gain of the plant model (> 0).
    theta : sequence of 2 floats
        Nominal ``[a0, a1]`` of ``theta``.
    c1, lam : float
        Backstepping and sliding-surface gains, 1/s.
    ks : float
        Reaching gain.
    phi : float
        Boundary layer.
    gamma_theta : sequence of 2 floats
        Adaptation rates of ``theta``.
    gamma_d : float
        Adaptation rate of the disturbance bound ``D``.
    d0 : float
        Initial ``D``.
    d_max : float, optional
        Largest ``D`` (default: the output span times ``b``).
    theta_range : float
        ``theta``'s bounds as a factor around the nominal values (>= 1).
    theta_bounds : ((float, float), (float, float)), optional
        Explicit lower and upper bounds of ``theta``.
    regressor : {"desired", "measured"}
        Where ``phi`` is evaluated.
    observer : VelocityObserver
        Position and velocity estimator.
    u_min, u_max : float, optional
        Output limits.
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> from piezohyst import ABSMC, virtual_stage
    >>> a = ABSMC.for_stage(virtual_stage().params)
    >>> round(a.b, 3), [round(x) for x in a.theta]
    (147.059, [1027030812, 1923])
    """

    b: float
    theta: Sequence[float]
    c1: float = 2e3
    lam: float = 2e3
    ks: float = 1e3
    phi: float = 1e-3
    gamma_theta: Sequence[float] = (1e12, 1e6)
    gamma_d: float = 1e6
    d0: float = 0.0
    d_max: float | None = None
    theta_range: float = 3.0
    theta_bounds: Sequence[Sequence[float]] | None = None
    regressor: str = "desired"
    observer: VelocityObserver = field(default_factory=VelocityObserver)
    u_min: float | None = None
    u_max: float | None = None
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)

    uses_reference_derivatives = True

    def __post_init__(self) -> None:
        as_scalar(self.b, "b", positive=True)
        if isinstance(self.theta, (str, bytes)) or not hasattr(self.theta, "__len__"):
            raise ParameterTypeError(f"theta must be a sequence of numbers [a0, a1], got {self.theta!r}")
        for i, t in enumerate(self.theta):
            as_scalar(t, f"theta[{i}]")
        for name in ("c1", "lam", "phi", "gamma_d"):
            as_scalar(getattr(self, name), name, positive=True)
        as_scalar(self.ks, "ks", nonnegative=True)
        if isinstance(self.gamma_theta, (str, bytes)) or not hasattr(self.gamma_theta, "__len__"):
            raise ParameterTypeError(f"gamma_theta must be a sequence of rates, got {self.gamma_theta!r}")
        for i, x in enumerate(self.gamma_theta):
            as_scalar(x, f"gamma_theta[{i}]", positive=True)
        as_scalar(self.d0, "d0", nonnegative=True)
        _check_optional(self.d_max, "d_max", nonnegative=True)
        if as_scalar(self.theta_range, "theta_range", positive=True) < 1:
            raise ParameterError(f"theta_range = {self.theta_range} must be >= 1")
        if self.theta_bounds is not None:
            _theta_bounds(self.theta_bounds, len(self.theta))
        if self.regressor not in ("desired", "measured"):
            raise ParameterError(f"regressor = {self.regressor!r} must be 'desired' or 'measured'")
        _check_observer(self.observer)
        _check_limits(self.u_min, self.u_max)

    @classmethod
    def for_stage(cls, model: StageParameters, **kw: Any) -> ABSMC:
        """Voltage-domain ABSMC from identified stage parameters.

        Parameters
        ----------
        model : StageParameters
            The identified stage.
        **kw
            Other fields of :class:`ABSMC`.

        Returns
        -------
        ABSMC

        Examples
        --------
        >>> from piezohyst import ABSMC, virtual_stage
        >>> ABSMC.for_stage(virtual_stage().params, ks=5e3).ks
        5000.0
        """
        c = (
            cemf_model_parameters(model)
            if model.hyst_drive == "charge"
            else {"M": model.mass / model.tem, "B": model.damping / model.tem, "K": model.stiffness / model.tem}
        )
        return cls(b=1.0 / c["M"], theta=(c["K"] / c["M"], c["B"] / c["M"]), **kw)

    @classmethod
    def linearized(cls, natural_frequency: float, damping_ratio: float = 0.05, **kw: Any) -> ABSMC:
        """Displacement-domain ABSMC for a stage linearized by an inverse model: unit static
        gain, ``natural_frequency`` in Hz.

        Parameters
        ----------
        natural_frequency : float
            Of the linearized loop, Hz.
        damping_ratio : float
            Of the linearized loop.
        **kw
            Other fields of :class:`ABSMC`.

        Returns
        -------
        ABSMC

        Examples
        --------
        >>> from piezohyst import ABSMC
        >>> a = ABSMC.linearized(2000.0, 0.7, c1=2e3)
        >>> round(a.b), [round(x) for x in a.theta]
        (157913670, [157913670, 17593])
        """
        w = 2 * math.pi * as_scalar(natural_frequency, "natural_frequency", positive=True)
        z = as_scalar(damping_ratio, "damping_ratio", nonnegative=True)
        return cls(b=w * w, theta=(w * w, 2 * z * w), **kw)

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> from piezohyst import ABSMC, virtual_stage
        >>> stage = virtual_stage()
        >>> ABSMC.for_stage(stage.params).core(stage)[0]
        'absmc'
        """
        b = as_scalar(self.b, "b", positive=True)
        th = [as_scalar(t, f"theta[{i}]") for i, t in enumerate(self.theta)]
        n_theta = _slot_count("absmc", "theta0")  # the regressor phi = [-x, -x']
        if len(th) != n_theta:
            raise ParameterError(f"theta must have {n_theta} values [a0, a1], got {len(th)}")
        if self.theta_bounds is None:
            r = as_scalar(self.theta_range, "theta_range", positive=True)
            if r < 1:
                raise ParameterError(f"theta_range = {r} must be >= 1")
            lo_t = [min(t / r, t * r) for t in th]
            hi_t = [max(t / r, t * r) for t in th]
        else:
            lo_t, hi_t = _theta_bounds(self.theta_bounds, n_theta)
        for name in ("c1", "lam", "phi", "gamma_d"):
            as_scalar(getattr(self, name), name, positive=True)
        as_scalar(self.ks, "ks", nonnegative=True)
        if len(self.gamma_theta) != n_theta:
            raise ParameterError(f"gamma_theta = {self.gamma_theta!r} must have {n_theta} values (rates for a0, a1)")
        g = [as_scalar(x, f"gamma_theta[{i}]", positive=True) for i, x in enumerate(self.gamma_theta)]
        d0 = as_scalar(self.d0, "d0", nonnegative=True)
        lo, hi = _domain_limits(self.u_min, self.u_max, stage, limits)
        d_max = (hi - lo) * b if self.d_max is None else as_scalar(self.d_max, "d_max", nonnegative=True)
        if self.regressor not in ("desired", "measured"):
            raise ParameterError(f"regressor = {self.regressor!r} must be 'desired' or 'measured'")
        p = _pack(
            "absmc",
            b=b,
            **{
                f"{name}_{i}": x
                for name, xs in (("theta0", th), ("theta_min", lo_t), ("theta_max", hi_t))
                for i, x in enumerate(xs)
            },
            c1=self.c1,
            **{"lambda": self.lam},
            ks=self.ks,
            phi=self.phi,
            **{f"gamma_theta_{i}": x for i, x in enumerate(g)},
            gamma_d=self.gamma_d,
            d0=d0,
            d_max=d_max,
            desired_regressor=1.0 if self.regressor == "desired" else 0.0,
            **_observer_slots(self.observer, stage),
            u_min=lo,
            u_max=hi,
        )
        return "absmc", p, None, None


@dataclass(frozen=True)
class CemfFeedforward:
    """Exact inverse feedforward of the identified CEMF model (seed 1's model):
    ``F = M x_d'' + B x_d' + K x_d``, the charge ``q = Cz F + Tem x_d``, ``Vh`` from the
    Bouc–Wen law on ``q``, and ``u = F + Vh``.

    Parameters
    ----------
    model : StageParameters
        The identified CEMF stage model.
    u_min, u_max : float, optional
        Output limits (default: the amplifier's).
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> import piezohyst as ph
    >>> stage = ph.virtual_stage()
    >>> t, ref = ph.sine(5, 5e-6, 0.4, 1e4, offset=7e-6)
    >>> ff = ph.track(ph.CemfFeedforward(stage.params), ref, stage=stage, rng=1, skip=0.2).metrics
    >>> ol = ph.track(ph.OpenLoop(), ref, stage=stage, rng=1, skip=0.2).metrics
    >>> round(ff["rmse"] * 1e6, 2), round(ol["rmse"] * 1e6, 2)   # um: creep and electrostriction stay
    (0.46, 0.81)
    """

    model: StageParameters
    u_min: float | None = None
    u_max: float | None = None
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)

    uses_reference_derivatives = True

    def __post_init__(self) -> None:
        _stage_parameters(self.model)
        _check_limits(self.u_min, self.u_max)

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> from piezohyst import CemfFeedforward, virtual_stage
        >>> stage = virtual_stage()
        >>> CemfFeedforward(stage.params).core(stage)[0]
        'cemf_feedforward'
        """
        lo, hi = _domain_limits(self.u_min, self.u_max, stage, limits)
        return "cemf_feedforward", _pack("cemf_feedforward", **_cemf_slots(self.model), u_min=lo, u_max=hi), None, None


def _model_output_range(model: HysteresisModel, v_min: float, v_max: float) -> Limits:
    """Outputs of a hysteresis model at the amplifier limits, reached along the major loop
    (for wiping-out models these do not depend on the history)."""
    ramp = np.concatenate(
        [np.linspace(0.0, v_max, 400), np.linspace(v_max, v_min, 800), np.linspace(v_min, v_max, 800)]
    )
    y = model.simulate(ramp, initial_state=model.initial_state())
    return float(y[1199]), float(y[-1])


def _hysteresis_model(model: object) -> HysteresisModel:
    """``model`` if it is a hysteresis model, else ``ParameterTypeError``."""
    from ..models.model import HysteresisModel

    if not isinstance(model, HysteresisModel):
        raise ParameterTypeError(
            f"model must be a hysteresis model (e.g. identify(...).model), got {type(model).__name__}"
        )
    return model


@dataclass(frozen=True)
class Compensated:
    """``inner`` acting in the linearized (displacement) domain, behind the exact per-sample
    inverse of the identified hysteresis ``model`` (input V, output m): the inner command is
    the displacement wanted from the actuator, the inverse finds the voltage. The inner
    controller's limits are the model's outputs at the amplifier limits.

    Parameters
    ----------
    inner : controller configuration
        The controller acting in metres (``PID``, ``ABSMC.linearized(...)``, ``OpenLoop``, ...).
    model : HysteresisModel
        The identified hysteresis model (input V, output m).
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> import piezohyst as ph
    >>> model = ph.PI([20.0, 50.0], [2e-8, 1e-8], p0=1e-7)        # V -> m
    >>> kind, params, inverse, ilc = ph.Compensated(ph.PID(kp=0.5, ki=2e3), model).core(ph.virtual_stage())
    >>> kind, inverse[0], inverse[3:]                             # the PID in metres, before the inverse
    ('pid', 'pi', (-20.0, 150.0))
    """

    inner: DomainController
    model: HysteresisModel
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not is_controller(self.inner):
            raise ParameterTypeError(
                f"inner must be a controller (PID, SMC, ABSMC, ...), got {type(self.inner).__name__}"
            )
        if isinstance(self.inner, (Compensated, InverseFeedforward)):
            raise ParameterTypeError("inner must not itself be compensated")
        _hysteresis_model(self.model)

    @property
    def uses_reference_derivatives(self) -> bool:
        """Whether the inner controller reads the reference's derivatives."""
        return bool(getattr(self.inner, "uses_reference_derivatives", True))

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> import piezohyst as ph
        >>> model = ph.PI([20.0, 50.0], [2e-8, 1e-8], p0=1e-7)
        >>> params = ph.Compensated(ph.OpenLoop(), model).core(ph.virtual_stage())[1]
        >>> [round(float(x) * 1e6, 3) for x in params[-2:]]      # limits: the model's outputs at -20, 150 V (um)
        [-1.7, 18.6]
        """
        if isinstance(self.inner, (Compensated, InverseFeedforward)):
            raise ParameterTypeError("inner must not itself be compensated")
        v_lo, v_hi = _limits(None, None, stage) if limits is None else limits
        # the core inverts a bare parameter row: the model's output map goes into it
        model = _hysteresis_model(self.model).mapped_row((v_lo, v_hi))
        y_lo, y_hi = _model_output_range(model, v_lo, v_hi)
        if not y_hi > y_lo:
            raise ParameterError(f"the model's output range [{y_lo:.4g}, {y_hi:.4g}] at the amplifier limits is empty")
        kind, params, _, ilc = self.inner.core(stage, limits=(y_lo, y_hi))
        inverse = (model.family, list(model.dims), model.to_row(), v_lo, v_hi)
        return kind, params, inverse, ilc


@dataclass(frozen=True)
class InverseFeedforward:
    """Inverse feedforward: the exact per-sample inverse of ``model`` driven by the
    reference (optionally led by ``c1 x_d' + c2 x_d''`` to invert the stage's linear dynamics,
    docs/spec.md §5). Any invertible model: PI family, Preisach, Bouc–Wen; for the CEMF model use
    :class:`CemfFeedforward`.

    Parameters
    ----------
    model : HysteresisModel
        The identified hysteresis model (input V, output m).
    c1, c2 : float
        Lead on the reference's velocity and acceleration, s and s².
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> import piezohyst as ph
    >>> model = ph.PI([20.0, 50.0], [2e-8, 1e-8], p0=1e-7)
    >>> ff = ph.InverseFeedforward(model, c1=1e-4)
    >>> ff.uses_reference_derivatives, ff.core(ph.virtual_stage())[2][0]
    (True, 'pi')
    """

    model: HysteresisModel
    c1: float = 0.0
    c2: float = 0.0
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        _hysteresis_model(self.model)
        as_scalar(self.c1, "c1")
        as_scalar(self.c2, "c2")

    @property
    def uses_reference_derivatives(self) -> bool:
        """Whether the step reads the reference's derivatives (``c1`` or ``c2`` set)."""
        return self.c1 != 0 or self.c2 != 0

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> import piezohyst as ph
        >>> model = ph.PI([20.0, 50.0], [2e-8, 1e-8], p0=1e-7)
        >>> ph.InverseFeedforward(model).core(ph.virtual_stage())[0]     # an open loop behind the inverse
        'open_loop'
        """
        return Compensated(OpenLoop(gain=1.0, c1=self.c1, c2=self.c2), self.model).core(stage, limits=limits)


@dataclass(frozen=True)
class ILC:
    """Iterative learning control on top of ``inner`` for a reference of period ``period``
    samples: ``u = inner + L[k mod N]``, ``L[i] <- q smooth(L)[i] + gain e``, updated
    ``lead`` samples back (the plant's delay and lag). ``gain`` is in output units per metre
    (dimensionless behind an inverse); ``forgetting`` ``q`` in (0, 1]. Learning acts in the
    linearized domain when ``inner`` is :class:`Compensated`.

    The update runs every sample (``crates/core/src/control/ilc.rs``), so this is also the
    plug-in *repetitive controller* of a periodic reference: the internal model ``z^-N``
    (the memory ``L``) with the robustness low-pass ``Q = q (1, 2, 1) / 4`` (zero phase) and
    the phase lead ``z^lead``, added to any feedback (:meth:`repetitive` builds it from the
    reference's frequency). It is a controller like the others: :func:`~piezohyst.track`,
    :func:`~piezohyst.closed_loop_batch` and :func:`~piezohyst.tune` (``"gain"``,
    ``"inner.kp"``) take it.

    Parameters
    ----------
    inner : controller configuration
        The controller whose output is corrected.
    period : int
        Samples per period ``N`` of the reference.
    gain : float
        Learning gain.
    forgetting : float
        ``q`` in (0, 1].
    lead : int
        Learning shift in samples (the plant's delay and lag), below ``period``.
    tuned_sample_time : float, optional
        The sample time the gains were tuned at (set by :func:`piezohyst.tune`); a run at
        another rate warns (:class:`SampleRateWarning`). Not compared, not shown.

    Examples
    --------
    >>> import piezohyst as ph
    >>> model = ph.PI([20.0, 50.0], [2e-8, 1e-8], p0=1e-7)
    >>> ilc = ph.ILC(ph.InverseFeedforward(model), period=200, gain=0.3)
    >>> ilc.core(ph.virtual_stage())[3]                 # period, gain, forgetting, lead, sensor delay
    (200, 0.3, 1.0, 3, 1)
    """

    inner: DomainController
    period: int
    gain: float = 0.5
    forgetting: float = 1.0
    lead: int = 3
    tuned_sample_time: float | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not is_controller(self.inner):
            raise ParameterTypeError(
                f"inner must be a controller (PID, Compensated, ...), got {type(self.inner).__name__}"
            )
        if isinstance(self.inner, ILC):
            raise ParameterTypeError("inner must not itself be an ILC")
        n = as_int(self.period, "period", minimum=2)
        as_scalar(self.gain, "gain", nonnegative=True)
        if not 0 < as_scalar(self.forgetting, "forgetting", positive=True) <= 1:
            raise ParameterError(f"forgetting = {self.forgetting} must lie in (0, 1]")
        if as_int(self.lead, "lead", minimum=0) >= n:
            raise ParameterError(f"lead = {self.lead} must be below the period {n}")

    @property
    def uses_reference_derivatives(self) -> bool:
        """Whether the inner controller reads the reference's derivatives."""
        return bool(getattr(self.inner, "uses_reference_derivatives", True))

    @classmethod
    def repetitive(cls, inner: DomainController, frequency: float, sample_time: float, **kw: Any) -> ILC:
        """The plug-in repetitive controller for a reference of ``frequency`` (Hz) sampled at
        ``sample_time`` (s): the period ``N = 1 / (frequency Ts)`` samples, which must be a
        whole number (a reference whose period is not a whole number of samples has no
        ``z^-N`` internal model).

        Parameters
        ----------
        inner : controller
            The feedback it plugs into (a :class:`PID`, :class:`FilteredPID`, ...).
        frequency : float
            The reference's fundamental, Hz.
        sample_time : float
            The loop's sample time, s.
        **kw
            ``gain``, ``forgetting``, ``lead``.

        Returns
        -------
        ILC

        Examples
        --------
        >>> import piezohyst as ph
        >>> ph.ILC.repetitive(ph.PID(kp=1e6, ki=1e9), 50.0, 1e-4, gain=1e6).period
        200
        """
        f = as_scalar(frequency, "frequency", positive=True)
        ts = as_scalar(sample_time, "sample_time", positive=True)
        n = 1.0 / (f * ts)
        if abs(n - round(n)) > 1e-6 * n:
            raise ParameterError(
                f"frequency = {f} Hz at sample_time = {ts} s gives a period of {n:g} samples; it must be a whole number"
            )
        return cls(inner, period=round(n), **kw)

    @_core_doc
    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        """Examples
        --------
        >>> import piezohyst as ph
        >>> ph.ILC(ph.PID(kp=1e6), period=100).core(ph.virtual_stage())[0]
        'pid'
        """
        n = as_int(self.period, "period", minimum=2)
        gain = as_scalar(self.gain, "gain", nonnegative=True)
        q = as_scalar(self.forgetting, "forgetting", positive=True)
        if q > 1:
            raise ParameterError(f"forgetting = {q} must lie in (0, 1]")
        lead = as_int(self.lead, "lead", minimum=0)
        if lead >= n:
            raise ParameterError(f"lead = {lead} must be below the period {n}")
        if isinstance(self.inner, ILC):
            raise ParameterTypeError("inner must not itself be an ILC")
        kind, params, inverse, _ = self.inner.core(stage, limits=limits)
        return kind, params, inverse, (n, gain, q, lead, int(stage.sensor.delay))


class SampleRateWarning(UserWarning):
    """A controller runs at another sample rate than the one it was tuned at
    (``tuned_sample_time``, set by :func:`piezohyst.tune`): its discrete-time behaviour (the
    observer, the filters, the switching) changes with the rate, and gains tuned at 10 kHz need
    not hold at 5 kHz. Tune again at the rate it runs at.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> stage = ph.virtual_stage()
    >>> pid = ph.PID(kp=1e5, ki=1e9, tuned_sample_time=2e-4)       # tuned at 5 kHz
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = ph.closed_loop(stage, pid, np.full(100, 5e-6), rng=1)   # run at 10 kHz
    >>> [w.category.__name__ for w in caught]
    ['SampleRateWarning']
    """


def check_sample_rate(controller: object, sample_time: float) -> None:
    """Warn (:class:`SampleRateWarning`) when ``controller`` (or the controller it wraps) was
    tuned at another sample time than ``sample_time`` (s).

    Parameters
    ----------
    controller : controller configuration
        Any controller; one without ``tuned_sample_time`` (or with ``None``) is not checked.
    sample_time : float
        The sample time it is about to run at, s.

    Examples
    --------
    >>> import warnings
    >>> from piezohyst import PID
    >>> from piezohyst.control.controllers import SampleRateWarning, check_sample_rate
    >>> pid = PID(kp=1e5, tuned_sample_time=1e-4)
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     check_sample_rate(pid, 2e-4)
    >>> issubclass(w[0].category, SampleRateWarning), str(w[0].message)[:23]
    (True, 'PID was tuned at 10 kHz')
    """
    import warnings

    c: object | None = controller
    while c is not None:
        tuned = getattr(c, "tuned_sample_time", None)
        if tuned is not None and not math.isclose(float(tuned), float(sample_time), rel_tol=1e-9):
            warnings.warn(
                f"{type(c).__name__} was tuned at {1e-3 / tuned:g} kHz (sample time {tuned:g} s) and runs at "
                f"{1e-3 / sample_time:g} kHz ({sample_time:g} s): its discrete-time behaviour changes with the "
                "rate; tune it again at the rate it runs at",
                SampleRateWarning,
                stacklevel=3,
            )
            return
        c = getattr(c, "inner", None)


def is_controller(c: object) -> bool:
    """Whether ``c`` is a controller configuration (it has a ``core(stage)`` method).

    Parameters
    ----------
    c : object
        Anything.

    Returns
    -------
    bool

    Examples
    --------
    >>> from piezohyst import PID
    >>> from piezohyst.control import is_controller
    >>> is_controller(PID(kp=1e6)), is_controller("pid")
    (True, False)
    """
    return hasattr(c, "core") and callable(c.core)


def with_gains(controller: _C, **gains: Any) -> _C:
    """A copy of ``controller`` with some fields changed (for gain sweeps and tuning).

    Parameters
    ----------
    controller : controller configuration
        The template.
    **gains
        Fields and their new values.

    Returns
    -------
    controller configuration
        Of the same class.

    Examples
    --------
    >>> from piezohyst import PID
    >>> from piezohyst.control import with_gains
    >>> with_gains(PID(kp=1e6), ki=5e9)
    PID(kp=1000000.0, ki=5000000000.0, kd=0.0, tau_d=0.0001, ff_gain=None, offset=0.0, u_min=None, u_max=None)
    """
    return replace(controller, **gains)
