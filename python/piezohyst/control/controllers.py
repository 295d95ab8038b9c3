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

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Protocol, TypeAlias, TypeVar, cast

import numpy as np
import numpy.typing as npt

from .. import _core
from .._validate import as_int, as_scalar
from ..errors import ParameterError, ParameterTypeError

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
    "InverseFeedforward",
    "OpenLoop",
    "VelocityObserver",
    "cemf_model_parameters",
]


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
    ahead (by default the sensor's delay). See ``crates/core/src/control/mod.rs``."""

    bandwidth: float = 1000.0
    delay: float | None = None

    def __post_init__(self) -> None:
        as_scalar(self.bandwidth, "observer_bandwidth", positive=True)
        _check_optional(self.delay, "observer_delay", nonnegative=True)

    def core(self, stage: Stage) -> list[float]:
        bw = as_scalar(self.bandwidth, "observer_bandwidth", positive=True)
        if bw >= 0.5 / stage.sample_time:
            raise ParameterError(
                f"observer_bandwidth = {bw} Hz must be below the Nyquist frequency {0.5 / stage.sample_time:g} Hz"
            )
        delay = stage.sensor.delay if self.delay is None else as_scalar(self.delay, "observer_delay", nonnegative=True)
        return [bw, stage.sample_time, float(delay)]


@dataclass(frozen=True)
class OpenLoop:
    """``u = offset + gain (x_d + c1 x_d' + c2 x_d'')``: a static inverse (``gain`` in V/m;
    by default the stage's ``1 / static_gain``), optionally with velocity and acceleration
    feedforward that inverts second-order dynamics (``c1 = B/K`` s, ``c2 = M/K`` s²).

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

    def __post_init__(self) -> None:
        _check_optional(self.gain, "gain")
        for name in ("offset", "c1", "c2"):
            as_scalar(getattr(self, name), name)
        _check_limits(self.u_min, self.u_max)

    @property
    def uses_reference_derivatives(self) -> bool:
        return self.c1 != 0 or self.c2 != 0

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
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


@dataclass(frozen=True)
class PID:
    """PID with static feedforward, filtered derivative on the measurement and
    conditional-integration anti-windup::

        u = offset + ff_gain x_d + kp e + ki sum(e) Ts + D,   e = x_d - y
        D = a D - kd (1 - a) (y - y_prev) / Ts,   a = tau_d / (tau_d + Ts)

    Gains in V/m, V/(m s), V s/m; ``tau_d`` in s; ``ff_gain`` defaults to the stage's
    ``1 / static_gain`` (set 0 for pure feedback).
    """

    kp: float = 0.0
    ki: float = 0.0
    kd: float = 0.0
    tau_d: float = 1e-4
    ff_gain: float | None = None
    offset: float = 0.0
    u_min: float | None = None
    u_max: float | None = None

    #: the step uses only the reference position
    uses_reference_derivatives = False

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd"):  # a negative gain is positive feedback
            as_scalar(getattr(self, name), name, nonnegative=True)
        as_scalar(self.tau_d, "tau_d", positive=True)
        _check_optional(self.ff_gain, "ff_gain")
        as_scalar(self.offset, "offset")
        _check_limits(self.u_min, self.u_max)

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        for name in ("kp", "ki", "kd"):
            as_scalar(getattr(self, name), name, nonnegative=True)
        as_scalar(self.tau_d, "tau_d", positive=True)
        if limits is not None and self.ff_gain is None:
            ff = 1.0  # behind an inverse the plant is linearized to unit gain
        else:
            ff = 1.0 / stage.params.static_gain if self.ff_gain is None else as_scalar(self.ff_gain, "ff_gain")
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
    ``M = m/Tem``, ``B = b/Tem``, ``K = k/Tem`` and the charge-driven Bouc–Wen law."""
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
    ``model_terms="measured"`` is seed 1's ``B x' + K x`` on the measured motion (positive
    position feedback that can latch at a voltage limit when the identified stiffness asks for
    more than the amplifier gives); ``"desired"`` evaluates them on the reference.
    The sliding dynamics ``e'' + (kv + alpha) e' + (alpha kv + kp) e = 0`` must be stable.
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
    model_terms: str = "measured"
    observer: VelocityObserver = field(default_factory=lambda: VelocityObserver(300.0))
    u_min: float | None = None
    u_max: float | None = None

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

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        cemf = _cemf_slots(self.model)
        kp, kv, alpha = (as_scalar(getattr(self, n), n) for n in ("kp", "kv", "alpha"))
        _check_sliding(kp, kv, alpha)
        if self.switching == "boundary_layer":
            sw = [0.0, as_scalar(self.ks, "ks", nonnegative=True), as_scalar(self.phi, "phi", positive=True)]
        elif self.switching == "super_twisting":
            sw = [1.0, as_scalar(self.k1, "k1", nonnegative=True), as_scalar(self.k2, "k2", nonnegative=True)]
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
        """Voltage-domain ABSMC from identified stage parameters."""
        c = (
            cemf_model_parameters(model)
            if model.hyst_drive == "charge"
            else {"M": model.mass / model.tem, "B": model.damping / model.tem, "K": model.stiffness / model.tem}
        )
        return cls(b=1.0 / c["M"], theta=(c["K"] / c["M"], c["B"] / c["M"]), **kw)

    @classmethod
    def linearized(cls, natural_frequency: float, damping_ratio: float = 0.05, **kw: Any) -> ABSMC:
        """Displacement-domain ABSMC for a stage linearized by an inverse model: unit static
        gain, ``natural_frequency`` in Hz."""
        w = 2 * math.pi * as_scalar(natural_frequency, "natural_frequency", positive=True)
        z = as_scalar(damping_ratio, "damping_ratio", nonnegative=True)
        return cls(b=w * w, theta=(w * w, 2 * z * w), **kw)

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
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
    Bouc–Wen law on ``q``, and ``u = F + Vh``."""

    model: StageParameters
    u_min: float | None = None
    u_max: float | None = None

    uses_reference_derivatives = True

    def __post_init__(self) -> None:
        _stage_parameters(self.model)
        _check_limits(self.u_min, self.u_max)

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
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
    controller's limits are the model's outputs at the amplifier limits."""

    inner: DomainController
    model: HysteresisModel

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
        return bool(getattr(self.inner, "uses_reference_derivatives", True))

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
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
    :class:`CemfFeedforward`."""

    model: HysteresisModel
    c1: float = 0.0
    c2: float = 0.0

    def __post_init__(self) -> None:
        _hysteresis_model(self.model)
        as_scalar(self.c1, "c1")
        as_scalar(self.c2, "c2")

    @property
    def uses_reference_derivatives(self) -> bool:
        return self.c1 != 0 or self.c2 != 0

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
        return Compensated(OpenLoop(gain=1.0, c1=self.c1, c2=self.c2), self.model).core(stage, limits=limits)


@dataclass(frozen=True)
class ILC:
    """Iterative learning control on top of ``inner`` for a reference of period ``period``
    samples: ``u = inner + L[k mod N]``, ``L[i] <- q smooth(L)[i] + gain e``, updated
    ``lead`` samples back (the plant's delay and lag). ``gain`` is in output units per metre
    (dimensionless behind an inverse); ``forgetting`` ``q`` in (0, 1]. Learning acts in the
    linearized domain when ``inner`` is :class:`Compensated`."""

    inner: DomainController
    period: int
    gain: float = 0.5
    forgetting: float = 1.0
    lead: int = 3

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
        return bool(getattr(self.inner, "uses_reference_derivatives", True))

    def core(self, stage: Stage, *, limits: Limits | None = None) -> CoreSpec:
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


def is_controller(c: object) -> bool:
    return hasattr(c, "core") and callable(c.core)


def with_gains(controller: _C, **gains: Any) -> _C:
    """A copy of ``controller`` with some fields changed (for gain sweeps and tuning)."""
    return replace(controller, **gains)
