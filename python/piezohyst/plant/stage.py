"""Piezo-driven stages: parameters, the default virtual stage, open-loop simulation and the
measurements ``piezohyst stage info`` prints (docs/spec.md §2.6, §3.1, §3.2).

The physics (integrated in the Rust core, ``crates/core/src/plant/stage.rs``)::

    m x'' + b x' + k x = Tem (Va - Vh + Vcr + e2 Va^2)
    q   = Cz (Va - Vh) + Tem x
    dVh = alpha dq - beta |dq| Vh - gamma dq |Vh|        (CEMF, Bouc–Wen n = 1 on charge)
    Vcr = sum_j c_j w_j,   tau_j w_j' = Va - w_j          (creep)
    tau_a Va' = u - Va, |Va'| <= slew, u in [min, max]   (amplifier)

The default virtual stage is ``presets/virtual_stage.json`` inside the package; every number
in it can be overridden from a file of the same layout (:meth:`Stage.from_file`).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from importlib import resources
from os import PathLike
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self, TypeAlias

import numpy as np
import numpy.typing as npt

from .. import _core
from .._io import check_parameter_tree, json_text, load_json_file, malformed_as, printable
from .._validate import as_int, as_record, as_scalar, as_vector
from ..errors import ParameterError, ParameterTypeError
from ..signals.lti import scipy_state_space, state_space
from ..signals.matfile import load_mat_file, write_mat
from ..signals.response import MatSignals, Response
from . import linear

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..models.model import HysteresisModel

FloatArray: TypeAlias = npt.NDArray[np.float64]
ComplexArray: TypeAlias = npt.NDArray[np.complex128]

__all__ = [
    "PERTURBABLE",
    "Amplifier",
    "Sensor",
    "Stage",
    "StageInfo",
    "StageParameters",
    "StageResponse",
    "perturbations",
    "virtual_stage",
]

MAX_CREEP = 8
#: Most modes :meth:`Stage.with_modes` can add.
MAX_MODES = 4

#: The SI unit of every number of a stage file (:meth:`Stage.to_dict`), by its name.
STAGE_UNITS = {
    "mass": "kg",
    "stiffness": "N/m",
    "damping": "N s/m",
    "tem": "N/V",
    "capacitance": "F",
    "alpha": "V/C (charge drive), V/V (voltage drive)",
    "beta": "1/C (charge drive), 1/V (voltage drive)",
    "gamma": "1/C (charge drive), 1/V (voltage drive)",
    "electrostriction": "1/V",
    "creep_taus": "s",
    "creep_weights": "V/V",
    "amplifier_min": "V",
    "amplifier_max": "V",
    "amplifier_bandwidth": "Hz",
    "amplifier_slew_rate": "V/s",
    "sensor_quantization": "m",
    "sensor_noise_std": "m",
    "sensor_delay": "samples",
    "amplifier_dac_step": "V",
    "amplifier_current_limit": "A",
    "modes": "[Hz, 1, 1] (frequency, damping ratio, relative gain)",
    "sample_time": "s",
    "substeps": "1",
    "tolerance": "1",
}


@dataclass(frozen=True)
class Amplifier:
    """Drive amplifier: output limits (V), -3 dB bandwidth (Hz, ``inf`` = ideal), slew
    rate (V/s, ``inf`` = unlimited), the DAC in front of it and its current limit.

    ``dac_step`` is the DAC's resolution (V per code, 0 = ideal): the command is rounded to the
    nearest code ``v_min + j dac_step`` before the amplifier (:meth:`dac` gives the step of an
    ``n``-bit DAC over the range). ``current_limit`` (A, ``inf`` = none) limits the charging
    current of the stack: with capacitance ``Cz`` it is the slew limit ``current_limit / Cz``
    (the smaller of the two applies; see :meth:`Stage.effective_slew_rate`).

    Parameters
    ----------
    v_min, v_max : float
        Output limits, V (``v_min < v_max``).
    bandwidth : float
        -3 dB bandwidth, Hz (``inf``: ideal).
    slew_rate : float
        Largest output rate, V/s (``inf``: unlimited).
    dac_step : float
        DAC resolution, V per code (0: ideal).
    current_limit : float
        Largest charging current of the stack, A (``inf``: none).

    Examples
    --------
    >>> from piezohyst import Amplifier
    >>> a = Amplifier(dac_step=Amplifier.dac(16))
    >>> round(a.dac_step * 1e3, 4)                      # mV per code of a 16-bit DAC over -20..150 V
    2.594
    >>> from piezohyst.plant import Amplifier
    >>> Amplifier(v_min=-20.0, v_max=150.0, bandwidth=3e3).slew_rate
    inf
    >>> Amplifier(v_min=10.0, v_max=0.0)
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: amplifier limits reversed: v_min = 10.0 must be < v_max = 0.0
    """

    v_min: float = -20.0
    v_max: float = 150.0
    bandwidth: float = math.inf
    slew_rate: float = math.inf
    dac_step: float = 0.0
    current_limit: float = math.inf

    def __post_init__(self) -> None:
        lo = as_scalar(self.v_min, "v_min")
        hi = as_scalar(self.v_max, "v_max")
        if not hi > lo:
            raise ParameterError(f"amplifier limits reversed: v_min = {lo} must be < v_max = {hi}")
        for name in ("bandwidth", "slew_rate", "current_limit"):
            x = as_scalar(getattr(self, name), name, allow_infinite=True)
            if not x > 0:
                raise ParameterError(f"{name} = {x} must be > 0 (inf for none)")
        as_scalar(self.dac_step, "dac_step", nonnegative=True)

    @staticmethod
    def dac(bits: int, v_min: float = -20.0, v_max: float = 150.0) -> float:
        """The step (V per code) of a ``bits``-bit DAC spanning ``v_min .. v_max``.

        Parameters
        ----------
        bits : int
            Resolution, 1..32 bits.
        v_min, v_max : float
            The range the codes span, V.

        Returns
        -------
        float
            ``(v_max - v_min) / (2**bits - 1)``.

        Examples
        --------
        >>> from piezohyst import Amplifier
        >>> Amplifier.dac(8, 0.0, 255.0)
        1.0
        """
        n = as_int(bits, "bits", minimum=1)
        if n > 32:
            raise ParameterError(f"bits = {n} must be <= 32")
        return float((as_scalar(v_max, "v_max") - as_scalar(v_min, "v_min")) / (2**n - 1))


@dataclass(frozen=True)
class Sensor:
    """Position sensor: quantization step (m, 0 = none), white-noise standard deviation (m)
    and delay in whole controller samples.

    Parameters
    ----------
    quantization : float
        Step of the reading, m (0: none).
    noise_std : float
        White-noise standard deviation, m.
    delay : int
        Delay of the reading in controller samples (0..16).

    Examples
    --------
    >>> from piezohyst.plant import Sensor
    >>> Sensor(quantization=1e-7, noise_std=1e-8, delay=1)
    Sensor(quantization=1e-07, noise_std=1e-08, delay=1)
    """

    quantization: float = 0.0
    noise_std: float = 0.0
    delay: int = 0

    def __post_init__(self) -> None:
        as_scalar(self.quantization, "quantization", nonnegative=True)
        as_scalar(self.noise_std, "noise_std", nonnegative=True)
        d = as_int(self.delay, "delay")
        if d > 16:
            raise ParameterError(f"delay = {d} must be <= 16 samples")


@dataclass(frozen=True)
class Drift:
    """Thermal drift of the stage after a temperature step at the start of a run: the position
    (the stage's and so the sensor's) becomes ``(1 + gain s(t)) x + offset s(t)`` with
    ``s(t) = 1 - exp(-t / time_constant)``: a slow displacement of ``offset`` (m) and a slow
    change of the stroke by the fraction ``gain``, ``t`` counted from the run's start (from
    :meth:`Stage.rest_state`; a state carried from one run to the next carries the clock). It
    is not linear time-invariant: :meth:`Stage.to_control` and the frequency responses leave it
    out.

    Parameters
    ----------
    offset : float
        The settled displacement, m.
    gain : float
        The settled relative change of the stroke (> -1).
    time_constant : float
        Settling time constant, s (> 0).

    Examples
    --------
    >>> from piezohyst.plant.stage import Drift
    >>> Drift(offset=50e-9, gain=0.01, time_constant=2.0)
    Drift(offset=5e-08, gain=0.01, time_constant=2.0)
    """

    offset: float = 0.0
    gain: float = 0.0
    time_constant: float = 1.0

    def __post_init__(self) -> None:
        as_scalar(self.offset, "drift offset")
        g = as_scalar(self.gain, "drift gain")
        if not g > -1:
            raise ParameterError(f"drift gain = {g} must be > -1 (the stroke would vanish)")
        as_scalar(self.time_constant, "drift time_constant", positive=True)


@dataclass(frozen=True)
class StageParameters:
    """Physical parameters of a piezo stage with CEMF hysteresis (SI units).

    ``hyst_drive`` is ``"charge"`` (seed 1's model) or ``"voltage"`` (the input-driven
    variant, where ``alpha`` is V/V and ``beta``, ``gamma`` are 1/V).

    Parameters
    ----------
    mass : float
        Equivalent moving mass ``meq``, kg.
    damping : float
        Equivalent damping ``beq``, N s/m.
    stiffness : float
        Equivalent stiffness ``keq``, N/m.
    tem : float
        Electromechanical transformation ratio ``Tem``, N/V.
    capacitance : float
        The stack's capacitance ``Cz``, F.
    hyst_alpha, hyst_beta, hyst_gamma : float
        The CEMF's Bouc–Wen parameters: V/C and 1/C on charge (V/V and 1/V on voltage).
    hyst_drive : {"charge", "voltage"}
        What drives the CEMF.
    electrostriction : float
        Quadratic term of the drive, 1/V.
    creep_taus, creep_weights : tuple of float
        Creep lags' time constants (s) and weights (V/V), at most 8.

    Examples
    --------
    >>> from piezohyst import virtual_stage
    >>> p = virtual_stage().params
    >>> p.mass, p.tem, round(p.natural_frequency), round(p.damping_ratio, 3)
    (0.0714, 10.5, 5100, 0.03)
    """

    mass: float
    damping: float
    stiffness: float
    tem: float
    capacitance: float = 1.8e-6
    hyst_alpha: float = 0.0
    hyst_beta: float = 0.0
    hyst_gamma: float = 0.0
    hyst_drive: str = "charge"
    electrostriction: float = 0.0
    creep_taus: tuple[float, ...] = ()
    creep_weights: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        for name in ("mass", "stiffness", "tem", "capacitance"):
            as_scalar(getattr(self, name), name, positive=True)
        as_scalar(self.damping, "damping", nonnegative=True)
        for name in ("hyst_alpha", "hyst_beta", "hyst_gamma", "electrostriction"):
            as_scalar(getattr(self, name), name)
        if self.hyst_drive not in ("charge", "voltage"):
            raise ParameterError(f"hyst_drive = {self.hyst_drive!r} must be 'charge' or 'voltage'")
        taus = tuple(float(x) for x in as_vector(self.creep_taus, "creep_taus"))
        weights = tuple(float(x) for x in as_vector(self.creep_weights, "creep_weights"))
        if len(taus) != len(weights):
            raise ParameterError(f"creep_weights has length {len(weights)}, creep_taus has {len(taus)}")
        if len(taus) > MAX_CREEP:
            raise ParameterError(f"creep_taus has {len(taus)} terms, at most {MAX_CREEP}")
        for j, t in enumerate(taus):
            if not (t > 0 and math.isfinite(t)):
                raise ParameterError(f"creep_taus[{j}] = {t} must be > 0 and finite")
        object.__setattr__(self, "creep_taus", taus)
        object.__setattr__(self, "creep_weights", weights)

    @property
    def natural_frequency(self) -> float:
        """Undamped natural frequency of the mechanics, Hz."""
        return math.sqrt(self.stiffness / self.mass) / (2 * math.pi)

    @property
    def damping_ratio(self) -> float:
        """Damping ratio of the mechanics, ``damping / (2 sqrt(stiffness mass))``."""
        return self.damping / (2 * math.sqrt(self.stiffness * self.mass))

    @property
    def static_gain(self) -> float:
        """``Tem / k``: position per volt without hysteresis or creep, m/V."""
        return self.tem / self.stiffness

    # -- linear part (piezohyst.plant.linear) ---------------------------------------------
    def frequency_response(self, f: npt.ArrayLike, *, creep: bool = True, cemf: bool = False) -> ComplexArray:
        """The linear part's frequency response from the drive voltage to the position (m/V),
        evaluated from the parameters (:mod:`piezohyst.plant.linear`), without an amplifier
        (:meth:`Stage.frequency_response` adds one).

        Parameters
        ----------
        f : array_like
            Frequencies, Hz (finite, ``>= 0``).
        creep : bool
            Keep the creep lags (default ``True``).
        cemf : bool
            Add the CEMF hysteresis by its slope at the demagnetized rest state (the
            small-signal model around rest; default ``False``: left out).

        Returns
        -------
        ndarray of complex
            ``H(j 2 pi f)``, m/V.

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> p = virtual_stage().params
        >>> h = p.frequency_response([0.0], creep=False)
        >>> round(float(h[0].real / p.static_gain), 12)       # Tem / k
        1.0
        """
        return linear.frequency_response(linear.linear_part(self, creep=creep, cemf=cemf), f)

    def to_control(self, *, creep: bool = True, cemf: bool = False) -> Any:
        """The linear part as a continuous python-control ``StateSpace`` from the drive voltage
        ``command`` (V) to the ``position`` (m): the system of :meth:`frequency_response`.

        Parameters
        ----------
        creep : bool
            Keep the creep lags (default ``True``).
        cemf : bool
            Add the CEMF's slope at rest (default ``False``).

        Returns
        -------
        control.StateSpace
            States ``x`` (m), ``v`` (m/s), ``w0 ...`` (creep lags, V).

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> sys = virtual_stage().params.to_control(creep=False)
        >>> sys.nstates, sys.input_labels, sys.output_labels
        (2, ['command'], ['position'])
        """
        return _to_control(linear.linear_system(linear.linear_part(self, creep=creep, cemf=cemf)), "stage_parameters")

    def to_scipy(self, *, creep: bool = True, cemf: bool = False) -> Any:
        """:meth:`to_control` as a ``scipy.signal.StateSpace`` (an ``lti``).

        Parameters
        ----------
        creep : bool
            Keep the creep lags (default ``True``).
        cemf : bool
            Add the CEMF's slope at rest (default ``False``).

        Returns
        -------
        scipy.signal.StateSpace

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> virtual_stage().params.to_scipy(creep=False).A.shape
        (2, 2)
        """
        sys = linear.linear_system(linear.linear_part(self, creep=creep, cemf=cemf))
        return scipy_state_space(sys.a, sys.b, sys.c, sys.d)


class StageResponse(Response):
    """Open-loop response, one value per controller sample: a
    :class:`~piezohyst.signals.Response` with the input ``command`` (V) and the outputs
    ``voltage`` (amplifier, V), ``position`` (m) and ``cemf`` (CEMF voltage, V).

    Parameters
    ----------
    time : array_like, shape (N,)
        Sample instants, s.
    command, voltage, position, cemf : array_like, shape (N,)
        The signals (V, V, m, V).
    final_state : array_like
        Stage state at the end ``[va, x, v, vh, creep[8]]``: pass it as the next run's
        ``initial_state`` to continue.
    title : str, optional
        The stage's name.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import virtual_stage
    >>> r = virtual_stage().simulate(np.full(100, 75.0))
    >>> r.output_names, r.units["position"], bool(r.position[-1] > 0)
    (('voltage', 'position', 'cemf'), 'm', True)
    """

    final_state: FloatArray

    def __init__(
        self,
        time: npt.ArrayLike,
        command: npt.ArrayLike,
        voltage: npt.ArrayLike,
        position: npt.ArrayLike,
        cemf: npt.ArrayLike,
        final_state: npt.ArrayLike,
        *,
        title: str = "",
    ) -> None:
        super().__init__(
            time,
            {"command": command, "voltage": voltage, "position": position, "cemf": cemf},
            inputs=["command"],
            units={"command": "V", "voltage": "V", "position": "m", "cemf": "V"},
            final_state=final_state,
            title=title,
        )

    @classmethod
    def _from_mat_fields(cls, f: MatSignals) -> Self:
        s = f.signals
        state = np.zeros(0) if f.final_state is None else f.final_state
        return cls(f.time, s["command"], s["voltage"], s["position"], s["cemf"], state, title=f.title)

    @property
    def command(self) -> FloatArray:
        """Voltage command held over each sample, V."""
        return self.signals["command"]

    @property
    def voltage(self) -> FloatArray:
        """Amplifier voltage at the end of each period, V."""
        return self.signals["voltage"]

    @property
    def position(self) -> FloatArray:
        """Position at each sample instant (before that sample's command acts), m."""
        return self.signals["position"]

    @property
    def cemf(self) -> FloatArray:
        """CEMF (hysteresis) voltage at the end of each period, V."""
        return self.signals["cemf"]


@dataclass(frozen=True)
class StageInfo:
    """What ``piezohyst stage info`` measures on a stage (:meth:`Stage.info`).

    Parameters
    ----------
    stroke : float
        Output range of a 1 Hz full-range loop, m.
    hysteresis_percent : float
        That loop's largest width, % of the range.
    resonance : float
        First resonance, Hz, measured from a simulated frequency response.
    creep_percent_per_decade : float
        Creep after a half-range step, % per time decade (0.1 to 100 s).
    natural_frequency : float
        Of the mechanics alone, Hz.
    damping_ratio : float
        Of the mechanics.
    details : dict
        Further fields of the report.

    Examples
    --------
    >>> from piezohyst import virtual_stage
    >>> info = virtual_stage().info()
    >>> round(info.stroke * 1e6, 2), round(info.hysteresis_percent, 2), round(info.resonance)
    (19.92, 13.08, 5478)
    """

    stroke: float
    hysteresis_percent: float
    resonance: float
    creep_percent_per_decade: float
    natural_frequency: float
    damping_ratio: float
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The report as ``piezohyst stage info --json`` prints it (stroke in µm).

        Returns
        -------
        dict

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> d = virtual_stage().info().to_dict()
        >>> round(d["stroke_um"], 2), round(d["first_resonance_hz"])
        (19.92, 5478)
        """
        return {
            "stroke_um": self.stroke * 1e6,
            "hysteresis_percent_1hz_full_range": self.hysteresis_percent,
            "first_resonance_hz": self.resonance,
            "creep_percent_per_decade": self.creep_percent_per_decade,
            "natural_frequency_hz": self.natural_frequency,
            "damping_ratio": self.damping_ratio,
            **self.details,
        }


@dataclass(frozen=True)
class Stage:
    """A stage with its amplifier, sensor and loop rate.

    Parameters
    ----------
    params : StageParameters
        The physics.
    amplifier : Amplifier
        The drive amplifier.
    sensor : Sensor
        The position sensor.
    sample_time : float
        The controller's sample time, s.
    substeps : int
        Integration sub-steps per sample (at least; refined where the voltage moves fast).
    tolerance : float
        Refinement tolerance (CEMF exponent change per sub-step; ``inf``: never refine).
    name : str
        The stage's name.
    modes : tuple of (float, float, float)
        Added structural modes ``(frequency Hz, damping ratio, relative gain)``
        (:meth:`Stage.with_modes`).
    hysteresis : HysteresisModel, optional
        A hysteresis model driven by the amplifier voltage in place of the CEMF law
        (:meth:`Stage.with_hysteresis`).
    drift : Drift, optional
        Thermal drift after a temperature step at the run's start (:meth:`Stage.with_drift`).

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst import virtual_stage
    >>> stage = virtual_stage()
    >>> t = np.arange(0, 0.5, stage.sample_time)
    >>> r = stage.simulate(75 - 75 * np.cos(2 * np.pi * 2 * t))
    >>> bool(15e-6 < np.ptp(r.position) < 25e-6)
    True
    """

    params: StageParameters
    amplifier: Amplifier = Amplifier()
    sensor: Sensor = Sensor()
    sample_time: float = 1e-4
    substeps: int = 1
    tolerance: float = 0.05
    name: str = ""
    modes: tuple[tuple[float, float, float], ...] = ()
    hysteresis: HysteresisModel | None = None
    drift: Drift | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "modes", _checked_modes(self.modes))
        if self.drift is not None and not isinstance(self.drift, Drift):
            raise ParameterTypeError(f"drift must be a Drift, got {type(self.drift).__name__}")
        if self.hysteresis is not None:
            from ..models.model import HysteresisModel

            if not isinstance(self.hysteresis, HysteresisModel):
                raise ParameterTypeError(
                    f"hysteresis must be a hysteresis model (e.g. identify(...).model), got "
                    f"{type(self.hysteresis).__name__}"
                )
        as_scalar(self.sample_time, "sample_time", positive=True)
        n = as_int(self.substeps, "substeps", minimum=1)
        if n > 10_000:
            raise ParameterError(f"substeps = {n} must be <= 10000")
        tol = as_scalar(self.tolerance, "tolerance", allow_infinite=True)
        if math.isnan(tol) or not tol > 0:
            raise ParameterError(f"tolerance = {tol} must be > 0 (inf: never refine)")
        if not isinstance(self.params, StageParameters):
            raise ParameterTypeError(f"params must be StageParameters, got {type(self.params).__name__}")
        if not isinstance(self.amplifier, Amplifier):
            raise ParameterTypeError(f"amplifier must be an Amplifier, got {type(self.amplifier).__name__}")
        if not isinstance(self.sensor, Sensor):
            raise ParameterTypeError(f"sensor must be a Sensor, got {type(self.sensor).__name__}")
        if not isinstance(self.name, str):
            raise ParameterTypeError(f"name must be a string, got {type(self.name).__name__}")
        if printable(self.name) != self.name:  # printed by `piezohyst stage info`
            raise ParameterError(f"name = {printable(repr(self.name))} holds a control character; a name is plain text")

    # -- files --------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, d: object) -> Stage:
        """Build from the stage-file layout (see ``presets/virtual_stage.json``).

        Parameters
        ----------
        d : dict
            The parsed JSON object (anything else raises ``ValueError``).

        Returns
        -------
        Stage

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> from piezohyst.plant import Stage
        >>> stage = virtual_stage()
        >>> Stage.from_dict(stage.to_dict()) == stage
        True
        """
        if not isinstance(d, dict):
            raise ParameterError(f"a stage description must be a JSON object, got {type(d).__name__}")
        version = d.get("schema_version", 1)  # files before the version field are version 1
        if type(version) is not int or version != 1:  # true is not 1
            raise ParameterError(
                f"schema_version = {json_text(version)} is not supported (this version reads the integer 1)"
            )
        for section in ("mechanics", "cemf", "electrostriction", "creep", "amplifier", "sensor", "loop"):
            if d.get(section) is not None:  # numbers only (a few names and "inf"): a path names what is wrong
                check_parameter_tree(d[section], section, strings=_STAGE_STRINGS)
        with malformed_as("the stage description"):
            mech, cemf = d["mechanics"], d["cemf"]
            m, k = _number(mech, "mass"), _number(mech, "stiffness")
            if "damping" in mech:
                b = _number(mech, "damping")
            else:
                zeta = as_scalar(mech["damping_ratio"], "damping_ratio", nonnegative=True)
                b = 2 * zeta * math.sqrt(abs(k) * abs(m))
            creep = d.get("creep", {"taus": [], "weights": []})
            params = StageParameters(
                mass=m,
                damping=b,
                stiffness=k,
                tem=mech["tem"],
                capacitance=cemf.get("capacitance", 1.8e-6),
                hyst_alpha=cemf["alpha"],
                hyst_beta=cemf["beta"],
                hyst_gamma=cemf["gamma"],
                hyst_drive=cemf.get("drive", "charge"),
                electrostriction=d.get("electrostriction", 0.0),
                creep_taus=tuple(creep["taus"]),
                creep_weights=tuple(creep["weights"]),
            )
            a = d.get("amplifier", {})
            amp = Amplifier(
                a.get("min", -20.0),
                a.get("max", 150.0),
                _inf(a.get("bandwidth")),
                _inf(a.get("slew_rate")),
                a.get("dac_step", 0.0),
                _inf(a.get("current_limit")),
            )
            s = d.get("sensor", {})
            sensor = Sensor(s.get("quantization", 0.0), s.get("noise_std", 0.0), s.get("delay", 0))
            loop = d.get("loop", {})
            hyst = d.get("hysteresis")
            if hyst is not None:
                from ..models.model import HysteresisModel, model_from_dict

                law = model_from_dict(hyst)
                if not isinstance(law, HysteresisModel):
                    raise ParameterError(f"hysteresis: a {type(law).__name__} cannot drive a stage")
                hyst = law
            return cls(
                params,
                amp,
                sensor,
                loop.get("sample_time", 1e-4),
                loop.get("substeps", 1),
                _inf(loop.get("tolerance", 0.05)),
                d.get("name", ""),
                tuple(tuple(m) for m in d.get("modes", ())),
                hyst,
                None if d.get("drift") is None else Drift(**d["drift"]),
            )

    @classmethod
    def from_file(cls, path: str | PathLike[str]) -> Stage:
        """Read a stage file (JSON, the layout of the packaged virtual stage; a ``.mat`` file:
        the MATLAB file of :meth:`to_mat`).

        Parameters
        ----------
        path : str or os.PathLike
            The stage file (``piezohyst identify --model cemf`` writes one).

        Returns
        -------
        Stage

        Examples
        --------
        >>> import json, tempfile, pathlib
        >>> from piezohyst import virtual_stage
        >>> from piezohyst.plant import Stage
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "stage.json"
        >>> _ = path.write_text(json.dumps(virtual_stage().to_dict()))
        >>> Stage.from_file(path).sensor.quantization
        1e-07
        """
        if str(path).lower().endswith(".mat"):
            return load_mat_file(path, "stage", "stage file", cls.from_dict)
        return load_json_file(path, "stage file", cls.from_dict)

    def to_mat(self, path: str | PathLike[str], *, overwrite: bool = False) -> Path:
        """Write the stage to the MATLAB file ``path`` (read back exactly by
        :meth:`from_file`): the struct ``stage`` with the fields of the stage-file layout
        (:meth:`to_dict`: ``mechanics``, ``cemf``, ``electrostriction``, ``creep``,
        ``amplifier``, ``sensor``, ``loop``; an unlimited bandwidth or slew rate is the text
        ``'inf'``) and ``units`` (layout: :mod:`piezohyst.signals.matfile`).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (``.mat``), atomically.
        overwrite : bool
            Replace an existing file (default ``False``: ``OutputExistsError``).

        Returns
        -------
        pathlib.Path
            The file written.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from piezohyst import Stage, virtual_stage
        >>> path = virtual_stage().to_mat(pathlib.Path(tempfile.mkdtemp()) / "stage.mat")
        >>> Stage.from_file(path) == virtual_stage()
        True
        """
        return write_mat(path, "stage", {**self.to_dict(), "units": dict(STAGE_UNITS)}, overwrite=overwrite)

    def to_dict(self) -> dict[str, Any]:
        """The stage-file layout (JSON-ready; :meth:`from_dict` reads it back).

        Returns
        -------
        dict

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> d = virtual_stage().to_dict()
        >>> d["kind"], d["amplifier"]["max"], d["loop"]["sample_time"]
        ('stage', 150.0, 0.0001)
        """
        p = self.params
        return {
            "schema_version": 1,
            "kind": "stage",
            "name": self.name,
            "mechanics": {"mass": p.mass, "stiffness": p.stiffness, "damping": p.damping, "tem": p.tem},
            "cemf": {
                "drive": p.hyst_drive,
                "capacitance": p.capacitance,
                "alpha": p.hyst_alpha,
                "beta": p.hyst_beta,
                "gamma": p.hyst_gamma,
            },
            "electrostriction": p.electrostriction,
            "creep": {"taus": list(p.creep_taus), "weights": list(p.creep_weights)},
            "amplifier": {
                "min": self.amplifier.v_min,
                "max": self.amplifier.v_max,
                "bandwidth": _json_inf(self.amplifier.bandwidth),
                "slew_rate": _json_inf(self.amplifier.slew_rate),
                **({"dac_step": self.amplifier.dac_step} if self.amplifier.dac_step else {}),
                **(
                    {"current_limit": self.amplifier.current_limit}
                    if math.isfinite(self.amplifier.current_limit)
                    else {}
                ),
            },
            "sensor": {
                "quantization": self.sensor.quantization,
                "noise_std": self.sensor.noise_std,
                "delay": self.sensor.delay,
            },
            "loop": {
                "sample_time": self.sample_time,
                "substeps": self.substeps,
                "tolerance": _json_inf(self.tolerance),
            },
            **({"modes": [list(m) for m in self.modes]} if self.modes else {}),
            **({"hysteresis": self.hysteresis.to_dict()} if self.hysteresis is not None else {}),
            **({"drift": asdict(self.drift)} if self.drift is not None else {}),
        }

    def with_(self, **changes: Any) -> Stage:
        """A copy with some fields replaced (``params``, ``amplifier``, ``sensor``, ...).

        Parameters
        ----------
        **changes
            Fields of :class:`Stage` and their new values.

        Returns
        -------
        Stage

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> from piezohyst.plant import Sensor
        >>> quiet = virtual_stage().with_(sensor=Sensor())
        >>> quiet.sensor.noise_std, quiet.amplifier == virtual_stage().amplifier
        (0.0, True)
        """
        return replace(self, **changes)

    # -- structure ------------------------------------------------------------------------
    def with_modes(self, modes: object) -> Stage:
        """A copy with more modes: each ``(freq_hz, damping_ratio, relative_gain)``.

        The stack's own mode is the stage's ``m x'' + b x' + k x = F``. Each added mode ``i`` is
        driven by the same force with the same static deflection,
        ``q_i'' + 2 zeta_i w_i q_i' + w_i^2 q_i = w_i^2 F / k``, and the position the sensor
        reads is the modal sum ``(x + sum_i g_i q_i) / (1 + sum_i g_i)``: the static gain stays
        the stage's, ``relative_gain`` ``g_i`` is the mode's share of the deflection against the
        stack's (negative: a mode in anti-phase at a non-collocated sensor; ``1 + sum g > 0``).
        The CEMF's charge sees the stack's displacement ``x``. Integrated in the Rust kernel,
        sub-step by sub-step, as exactly as the stack's mode (``crates/core/src/plant/structure.rs``);
        :meth:`frequency_response` and :meth:`to_control` include the modes.

        Parameters
        ----------
        modes : sequence of (float, float, float)
            Frequency (Hz, > 0), damping ratio (>= 0), relative gain. At most
            ``MAX_MODES`` (4) in all.

        Returns
        -------
        Stage
            The stage with ``modes`` appended to its own.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import virtual_stage
        >>> stage = virtual_stage().with_modes([(1800.0, 0.02, 0.3)])
        >>> stage.modes
        ((1800.0, 0.02, 0.3),)
        >>> h = stage.frequency_response([1.0, 1800.0])
        >>> bool(abs(h[1]) > 3 * abs(h[0]))                     # the new resonance
        True
        """
        return replace(self, modes=self.modes + _checked_modes(modes))

    def with_drift(self, offset: float = 0.0, gain: float = 0.0, time_constant: float = 1.0) -> Stage:
        """A copy with thermal drift (:class:`Drift`): the position drifts by ``offset`` (m)
        and its stroke by the fraction ``gain`` with the time constant ``time_constant`` (s)
        from the start of a run.

        Parameters
        ----------
        offset, gain, time_constant : float

        Returns
        -------
        Stage

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import virtual_stage
        >>> s = virtual_stage().with_drift(offset=0.2e-6, time_constant=0.05)
        >>> x = s.simulate(np.full(3000, 60.0)).position
        >>> x0 = virtual_stage().simulate(np.full(3000, 60.0)).position
        >>> round(float(x[-1] - x0[-1]) * 1e9)              # 0.2 um (1 - e^-6) after 0.3 s
        200
        """
        return replace(self, drift=Drift(offset, gain, time_constant))

    def with_hysteresis(self, model: HysteresisModel | None) -> Stage:
        """A copy whose hysteresis is ``model`` driven by the amplifier voltage, in place of the
        CEMF law (a voltage-driven hysteresis): any hysteresis model of the package (PI, GPI/MPI,
        Preisach, Bouc–Wen, ... or one identified from a record), input V, output m.

        The stage's quasi-static position is ``model(Va)``: the hysteresis voltage is
        ``Vh = Va - (k / Tem) model(Va)`` in the force ``Tem (Va - Vh + Vcr + e2 Va^2)``, so the
        mechanics, modes, creep and electrostriction stay the stage's (give a stage without
        creep and electrostriction for the model alone). The model is stepped once per control
        period with the period's end voltage (its sample time is the loop's). ``None`` returns
        to the CEMF law.

        Parameters
        ----------
        model : HysteresisModel or None
            The law (input V, output m).

        Returns
        -------
        Stage

        Examples
        --------
        >>> import dataclasses
        >>> import numpy as np
        >>> from piezohyst import PI, virtual_stage
        >>> base = virtual_stage()
        >>> bare = dataclasses.replace(base.params, electrostriction=0.0, creep_taus=(), creep_weights=())
        >>> g = base.params.static_gain
        >>> law = PI([20.0, 60.0], [0.3 * g, 0.2 * g], p0=0.6 * g)
        >>> stage = base.with_(params=bare).with_hysteresis(law)
        >>> u = 75 - 75 * np.cos(2 * np.pi * 2 * np.arange(0, 1.0, stage.sample_time))
        >>> x = stage.simulate(u).position
        >>> err = np.abs(x[1:] - law.simulate(u)[:-1]).max() / np.ptp(x)   # the law's loop, lagged
        >>> bool(err < 0.01)
        True
        """
        return replace(self, hysteresis=model)

    @property
    def structured(self) -> bool:
        """Whether the stage has added modes, a voltage-driven hysteresis or a DAC (the Rust
        kernel then runs its structure hooks; the state is longer than ``STAGE_STATE_LEN``)."""
        return bool(self.modes) or self.hysteresis is not None or self.amplifier.dac_step > 0 or self.drift is not None

    def effective_slew_rate(self) -> float:
        """The amplifier's slew limit (V/s): its slew rate or ``current_limit / Cz``, the
        smaller.

        Returns
        -------
        float
            V/s (``inf``: none).

        Examples
        --------
        >>> from piezohyst import Amplifier, virtual_stage
        >>> s = virtual_stage()
        >>> s.with_(amplifier=Amplifier(current_limit=0.09)).effective_slew_rate()   # 0.09 A / 1.8 uF
        50000.0
        """
        a = self.amplifier
        return min(a.slew_rate, a.current_limit / self.params.capacitance)

    def stroke(self) -> tuple[float, float]:
        """The positions (m) the stage reaches at the amplifier limits, quasi-statically: the
        static gain with creep and electrostriction, or the voltage-driven hysteresis model's
        outputs at the limits along its major loop.

        Returns
        -------
        tuple of float
            ``(lowest, highest)``, m.

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> lo, hi = virtual_stage().stroke()
        >>> round(hi * 1e6, 2)
        24.15
        """
        p, a = self.params, self.amplifier
        if self.hysteresis is not None:
            ramp = np.concatenate(
                [np.linspace(0.0, a.v_max, 200), np.linspace(a.v_max, a.v_min, 400), np.linspace(a.v_min, a.v_max, 400)]
            )
            y = self.hysteresis.simulate(ramp, initial_state=self.hysteresis.initial_state())
            extra = p.static_gain * (sum(p.creep_weights) * np.array([a.v_min, a.v_max]))
            ends = (float(y[599]) + float(extra[0]), float(y[-1]) + float(extra[1]))
            return min(ends), max(ends)
        creep = 1 + sum(p.creep_weights)
        reach = [p.static_gain * (v * creep + p.electrostriction * v * v) for v in (a.v_min, a.v_max)]
        return min(reach), max(reach)

    # -- core layout ----------------------------------------------------------------------
    def core_params(self) -> FloatArray:
        """The flat parameter array of the Rust core (``StageParams::from_slice``).

        Returns
        -------
        ndarray, shape (31,)

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> p = virtual_stage().core_params()
        >>> p.size, p[0], p[3]          # mass (kg), Tem (N/V), ...
        (31, np.float64(0.0714), np.float64(10.5))
        """
        p, a = self.params, self.amplifier
        taus = list(p.creep_taus) + [1.0] * (MAX_CREEP - len(p.creep_taus))
        weights = list(p.creep_weights) + [0.0] * (MAX_CREEP - len(p.creep_weights))
        head = [
            p.mass,
            p.damping,
            p.stiffness,
            p.tem,
            p.capacitance,
            p.hyst_alpha,
            p.hyst_beta,
            p.hyst_gamma,
            0.0 if p.hyst_drive == "charge" else 1.0,
            p.electrostriction,
            a.v_min,
            a.v_max,
            a.bandwidth,
            self.effective_slew_rate(),
            float(len(p.creep_taus)),
        ]
        return np.array(head + taus + weights, dtype=np.float64)

    @functools.cached_property
    def compiled(self) -> _core.Stage:
        """The Rust core's stage (parameters, control period, integration settings and
        sensor), built and validated once per stage and reused by every run on it."""
        s = self.sensor
        law = self.hysteresis
        return _core.Stage(
            self.core_params(),
            self.sample_time,
            self.substeps,
            self.tolerance,
            s.quantization,
            s.noise_std,
            s.delay,
            modes=list(self.modes) or None,
            hysteresis=None if law is None else _law_row(law, self.amplifier),
            dac_step=self.amplifier.dac_step,
            drift=None if self.drift is None else (self.drift.offset, self.drift.gain, self.drift.time_constant),
        )

    # the compiled stage is not picklable: a pickle carries the fields; it is rebuilt on use
    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state.pop("compiled", None)
        return state

    def rest_state(self) -> FloatArray:
        """The state at rest: ``[va, x, v, vh, creep[8]]`` all zero, then, for a stage with
        structure (:attr:`structured`), the added modes' ``[q, q']`` at rest and the
        voltage-driven hysteresis model's relaxed state.

        Returns
        -------
        ndarray, shape (12,) or longer (a stage with structure)

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> virtual_stage().rest_state().tolist() == [0.0] * 12
        True
        """
        if not self.structured:
            return np.zeros(_core.STAGE_STATE_LEN)
        return self.compiled.rest_state()

    # -- simulation -----------------------------------------------------------------------
    def simulate(
        self,
        command: npt.ArrayLike,
        *,
        initial_state: npt.ArrayLike | None = None,
        sample_time: float | None = None,
        substeps: int | None = None,
        tolerance: float | None = None,
    ) -> StageResponse:
        """Open-loop response to a voltage command held over each sample.

        ``position[k]`` is the position at ``t_k = k Ts`` (before command ``k`` acts);
        ``voltage`` and ``cemf`` are the amplifier and CEMF voltages at the end of each period.
        Commands beyond the amplifier range raise ``ValueError`` (the amplifier would clip
        them; say so instead of clipping silently).

        Parameters
        ----------
        command : array_like, shape (N,)
            Voltage command per sample, V.
        initial_state : array_like, optional
            The state to start from (default: at rest), e.g. a previous run's ``final_state``.
        sample_time : float, optional
            Override the stage's sample time, s.
        substeps : int, optional
            Override the integration sub-steps per sample.
        tolerance : float, optional
            Override the refinement tolerance.

        Returns
        -------
        StageResponse

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import virtual_stage
        >>> stage = virtual_stage()
        >>> r = stage.simulate(np.full(2000, 150.0))           # a 150 V step, 0.2 s
        >>> round(float(r.position[-1]) * 1e6, 2)
        22.12
        >>> stage.simulate([200.0])
        Traceback (most recent call last):
        ...
        piezohyst.errors.ParameterError: command[0] = 200.0 V is outside the amplifier range [-20.0, 150.0] V
        """
        u = as_record(command, "command")
        self.check_command(u)
        ts = self.sample_time if sample_time is None else as_scalar(sample_time, "sample_time", positive=True)
        m = self.substeps if substeps is None else as_int(substeps, "substeps", minimum=1)
        tol = self.tolerance if tolerance is None else as_scalar(tolerance, "tolerance", allow_infinite=True)
        st = self.rest_state() if initial_state is None else as_record(initial_state, "initial_state")
        st = st.copy()
        if (ts, m, tol) == (self.sample_time, self.substeps, self.tolerance):
            core = self.compiled
        else:
            core = replace(self, sample_time=ts, substeps=m, tolerance=tol).compiled
        x, va, vh = core.simulate(u, st)
        return StageResponse(np.arange(u.size) * ts, u, va, x, vh, st, title=self.name)

    def check_command(self, u: FloatArray, name: str = "command") -> None:
        """Refuse commands outside the amplifier's range (naming the first one).

        Parameters
        ----------
        u : ndarray
            Commands, V.
        name : str
            The argument's name, for the message.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import virtual_stage
        >>> virtual_stage().check_command(np.array([0.0, 150.0]))    # inside: nothing happens
        >>> virtual_stage().check_command(np.array([0.0, -30.0]), "u")
        Traceback (most recent call last):
        ...
        piezohyst.errors.ParameterError: u[1] = -30.0 V is outside the amplifier range [-20.0, 150.0] V
        """
        a = self.amplifier
        bad = np.flatnonzero((u < a.v_min) | (u > a.v_max))
        if bad.size:
            k = bad[0]
            raise ParameterError(f"{name}[{k}] = {u[k]} V is outside the amplifier range [{a.v_min}, {a.v_max}] V")

    # -- linear part (piezohyst.plant.linear) ---------------------------------------------
    def frequency_response(
        self, f: npt.ArrayLike, *, creep: bool = True, amplifier: bool = True, cemf: bool = False
    ) -> ComplexArray:
        """The frequency response of the stage's linear part, command (V) to position (m), at
        the frequencies ``f`` (Hz), evaluated analytically from the parameters::

            H(s) = (g + Tem sum_j c_j / (tau_j s + 1)) / ((tau_a s + 1) (m s^2 + b s + k))

        the amplifier's lag (``amplifier``; not its limits or slew rate), the mechanics and
        the creep lags (``creep``); the electrostriction and the CEMF hysteresis are left out,
        or the hysteresis enters by its slope at the demagnetized rest state (``cemf=True``:
        the small-signal model around rest). See :mod:`piezohyst.plant.linear`.

        Parameters
        ----------
        f : array_like
            Frequencies, Hz (finite, ``>= 0``).
        creep : bool
            Keep the creep lags (default ``True``).
        amplifier : bool
            Keep the amplifier's lag (default ``True``).
        cemf : bool
            Add the CEMF hysteresis by its slope at rest (default ``False``: left out).

        Returns
        -------
        ndarray of complex
            ``H(j 2 pi f)``, m/V.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import virtual_stage
        >>> h = virtual_stage().frequency_response([1.0, 1e3, 5e3])
        >>> np.abs(h).round(9).tolist()         # m/V: flat, then the amplifier and the resonance
        [1.47e-07, 1.41e-07, 1.044e-06]
        """
        return linear.frequency_response(self._linear_part(creep, amplifier, cemf), f)

    def _linear_part(self, creep: bool, amplifier: bool, cemf: bool) -> linear.LinearPart:
        return linear.linear_part(
            self.params, self.amplifier if amplifier else None, creep=creep, cemf=cemf, modes=self.modes
        )

    def _linear_system(
        self, discrete: bool, measured: bool, creep: bool, amplifier: bool, cemf: bool
    ) -> linear.LinearSystem:
        if measured and not discrete:
            raise ParameterError("measured=True needs discrete=True (the sensor's delay is whole samples)")
        part = self._linear_part(creep, amplifier, cemf)
        if not discrete:
            return linear.linear_system(part)
        return linear.linear_system(part, sample_time=self.sample_time, delay=self.sensor.delay if measured else 0)

    def to_control(
        self,
        *,
        discrete: bool = False,
        measured: bool = False,
        creep: bool = True,
        amplifier: bool = True,
        cemf: bool = False,
    ) -> Any:
        """The stage's linear part as a python-control ``StateSpace``, input ``command`` (V),
        output ``position`` (m): the system whose response :meth:`frequency_response` gives.

        Parameters
        ----------
        discrete : bool
            ``False``: continuous. ``True``: the zero-order-hold discretization at the stage's
            ``sample_time`` (``dt``), the command held over each sample as :meth:`simulate`
            holds it: for a stage without hysteresis, electrostriction and creep it gives
            :meth:`simulate`'s positions to rounding.
        measured : bool
            With ``discrete``: the output is the sensor's reading ``measured``, the position
            delayed by the sensor's ``delay`` samples (its noise and quantization are not
            linear and are left out).
        creep, amplifier, cemf : bool
            Keep the creep lags, keep the amplifier's lag, add the CEMF's slope at rest (see
            :meth:`frequency_response`).

        Returns
        -------
        control.StateSpace
            States ``va`` (amplifier voltage, V; with an amplifier lag), ``x`` (m), ``v``
            (m/s), ``w0 ...`` (creep lags, V), then ``delay1 ...`` (m) when ``measured``.

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst import virtual_stage
        >>> stage = virtual_stage()
        >>> sys = stage.to_control()
        >>> sys.nstates, sys.input_labels, sys.output_labels
        (8, ['command'], ['position'])
        >>> f = np.array([10.0, 5e3])
        >>> bool(np.allclose(sys(2j * np.pi * f).ravel(), stage.frequency_response(f), rtol=1e-9))
        True
        >>> stage.to_control(discrete=True, measured=True).dt
        0.0001
        """
        sys = self._linear_system(discrete, measured, creep, amplifier, cemf)
        return _to_control(sys, self.name or "stage")

    def to_scipy(
        self,
        *,
        discrete: bool = False,
        measured: bool = False,
        creep: bool = True,
        amplifier: bool = True,
        cemf: bool = False,
    ) -> Any:
        """:meth:`to_control` as a ``scipy.signal.StateSpace`` (an ``lti``, or a ``dlti`` with
        ``dt`` when ``discrete``).

        Parameters
        ----------
        discrete : bool
            The zero-order-hold system at the stage's ``sample_time`` (default continuous).
        measured : bool
            With ``discrete``: the sensor's delayed reading as the output.
        creep, amplifier, cemf : bool
            Keep the creep lags, keep the amplifier's lag, add the CEMF's slope at rest.

        Returns
        -------
        scipy.signal.StateSpace

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> virtual_stage().to_scipy(discrete=True).dt
        0.0001
        """
        sys = self._linear_system(discrete, measured, creep, amplifier, cemf)
        return scipy_state_space(sys.a, sys.b, sys.c, sys.d, sys.dt)

    @classmethod
    def from_control(cls, sys: object, *, base: Stage | None = None) -> Stage:
        """A stage whose linear part is the second-order system ``sys``: a python-control
        ``StateSpace`` / ``TransferFunction`` or a ``scipy.signal.lti`` equal to
        ``Tem / (m s^2 + b s + k)`` (continuous, one input and output, no zeros).

        ``base`` gives everything else — ``Tem`` (the transfer function fixes only ``m / Tem``,
        ``b / Tem``, ``k / Tem``), hysteresis, creep, amplifier, sensor, loop rate — and only its
        mass, damping and stiffness are replaced. Without ``base`` the stage is linear: no
        hysteresis, electrostriction or creep, an ideal amplifier (-20..150 V), an ideal sensor,
        ``Tem = 1`` N/V, so that ``Stage.from_control(sys).to_control()`` is ``sys`` again.
        Anything not of that form raises ``ParameterError`` saying what it is.

        Parameters
        ----------
        sys : control.LTI or scipy.signal.lti
            The second-order system, input volts, output metres.
        base : Stage, optional
            The stage whose mechanics are replaced (default: the linear stage above).

        Returns
        -------
        Stage

        Examples
        --------
        >>> import control
        >>> from piezohyst import Stage
        >>> stage = Stage.from_control(control.tf([1.0], [0.01, 20.0, 4e6]))
        >>> round(stage.params.natural_frequency, 3), round(stage.params.damping_ratio, 4)
        (3183.099, 0.05)
        """
        if base is None:
            base = cls(StageParameters(mass=1.0, damping=0.0, stiffness=1.0, tem=1.0), name="linear stage")
        elif not isinstance(base, Stage):
            raise ParameterTypeError(f"base must be a Stage, got {type(base).__name__}")
        mass, damping, stiffness = linear.second_order_from_control(sys, base.params.tem)
        return base.with_(params=replace(base.params, mass=mass, damping=damping, stiffness=stiffness))

    # -- measurements ---------------------------------------------------------------------
    def info(self) -> StageInfo:
        """Measure stroke, hysteresis at 1 Hz over the full 0..v_max range, first resonance and
        creep per time decade, by simulation (not from the parameters).

        Returns
        -------
        StageInfo

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> info = virtual_stage().info()
        >>> round(info.creep_percent_per_decade, 2), round(info.natural_frequency)
        (1.42, 5100)
        """
        v_max = self.amplifier.v_max
        ts = self.sample_time
        # 1 Hz full-range loop, third period
        t = np.arange(0, 3.0, ts)
        u = 0.5 * v_max * (1 - np.cos(2 * np.pi * t))
        x = self.simulate(u).position
        last = t >= 2.0
        stroke, hyst = _loop_width(u[last], x[last])
        # first resonance: FRF position / amplifier voltage from a small multisine at 100 kHz
        resonance = self.measured_resonance()
        # creep: step to half range, held 100 s; slope of x against log10(t) over 0.1..100 s
        creep = self._creep_per_decade(0.5 * v_max)
        p = self.params
        return StageInfo(
            stroke,
            100 * hyst,
            resonance,
            creep,
            p.natural_frequency,
            p.damping_ratio,
            {"full_range_V": [0.0, v_max], "amplifier_V": [self.amplifier.v_min, v_max]},
        )

    def measured_resonance(self) -> float:
        """The first resonance (Hz), measured by simulation: a random-phase multisine through the
        stage with an ideal amplifier, the peak of the response spectrum (what :meth:`info` reports).

        Returns
        -------
        float

        Examples
        --------
        >>> from piezohyst import virtual_stage
        >>> round(virtual_stage().measured_resonance())     # above the mechanics' 5100 Hz
        5478
        """
        fs = 100_000.0
        ideal = self.with_(amplifier=Amplifier(self.amplifier.v_min, self.amplifier.v_max))
        n = 2**15
        rng = np.random.default_rng(0)
        k = np.arange(1, n // 2)
        spectrum = np.zeros(n // 2 + 1, complex)
        spectrum[k] = np.exp(2j * np.pi * rng.uniform(size=k.size))
        ms = np.fft.irfft(spectrum, n)
        ms *= 2.0 / np.max(np.abs(ms))
        u = 75.0 + np.tile(ms, 2)
        r = ideal.simulate(u, sample_time=1 / fs, substeps=1)
        # position is sampled before the command acts: shift by one sample
        x = r.position[n + 1 :] if r.position.size > n + 1 else r.position[n:]
        v_in = u[n : n + x.size]
        X, V = np.fft.rfft(x - x.mean()), np.fft.rfft(v_in - v_in.mean())
        f = np.fft.rfftfreq(x.size, 1 / fs)
        band = (f > 500) & (f < 40_000)
        H = np.abs(X[band] / V[band])
        return float(f[band][np.argmax(H)])

    def _creep_per_decade(self, level: float) -> float:
        ts = 1e-3
        t_end = 100.0
        n = round(t_end / ts) + 1
        u = np.full(n, level)
        ramp = round(0.002 / ts)
        u[:ramp] = np.linspace(0, level, ramp)
        x = self.simulate(u, sample_time=ts, substeps=8).position
        t = np.arange(n) * ts
        probes = np.array([0.1, 1.0, 10.0, 100.0])
        xs = np.interp(probes, t, x)
        slope = np.polyfit(np.log10(probes), xs, 1)[0]
        return float(100 * slope / xs[0])


def _to_control(sys: linear.LinearSystem, name: str) -> Any:
    return state_space(
        sys.a, sys.b, sys.c, sys.d, sys.dt, inputs=["command"], outputs=[sys.output], states=sys.states, name=name
    )


def _checked_modes(modes: object) -> tuple[tuple[float, float, float], ...]:
    """Modes as a tuple of ``(frequency, damping ratio, relative gain)``, validated."""
    if isinstance(modes, (str, bytes)) or not isinstance(modes, Sequence):
        raise ParameterTypeError(f"modes must be a sequence of (freq_hz, damping_ratio, relative_gain), got {modes!r}")
    out = []
    for i, m in enumerate(modes):
        if isinstance(m, (str, bytes)) or not isinstance(m, Sequence) or len(m) != 3:
            raise ParameterError(f"modes[{i}] = {m!r} must be (freq_hz, damping_ratio, relative_gain)")
        f = as_scalar(m[0], f"modes[{i}] frequency", positive=True)
        z = as_scalar(m[1], f"modes[{i}] damping_ratio", nonnegative=True)
        g = as_scalar(m[2], f"modes[{i}] relative_gain")
        out.append((f, z, g))
    if len(out) > MAX_MODES:
        raise ParameterError(f"modes has {len(out)} modes, at most {MAX_MODES}")
    total = 1.0 + sum(g for _, _, g in out)
    if not total > 0:
        raise ParameterError(f"1 + sum of the relative gains = {total} must be > 0")
    return tuple(out)


def _law_row(law: HysteresisModel, amp: Amplifier) -> tuple[str, list[int], FloatArray]:
    """``(family, dims, row)`` of a voltage-driven law for the core (its output map folded in)."""
    m = law.mapped_row((amp.v_min, amp.v_max))
    return m.family, list(m.dims), m.to_row()


def _loop_width(u: FloatArray, x: FloatArray) -> tuple[float, float]:
    """Output range and max loop width / range for one closed loop of (input, output)."""
    rng = float(np.ptp(x))
    du = np.gradient(u)
    up, down = du > 0, du < 0
    grid = np.linspace(u.min(), u.max(), 400)[5:-5]
    iu, idn = np.argsort(u[up]), np.argsort(u[down])
    xu = np.interp(grid, u[up][iu], x[up][iu])
    xd = np.interp(grid, u[down][idn], x[down][idn])
    return rng, float(np.max(np.abs(xd - xu)) / rng)


def _number(section: dict[str, Any], key: str) -> float:
    x = section[key]
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ParameterError(f"{key} = {x!r} must be a number")
    return float(x)


#: The keys of a stage file's sections that may hold a string: the CEMF drive, and "inf".
_STAGE_STRINGS = ("drive", "bandwidth", "slew_rate", "tolerance")


def _inf(x: float | str | None) -> float:
    return math.inf if x is None or x == "inf" else float(x)


def _json_inf(x: float) -> float | str:
    return "inf" if math.isinf(x) else x


#: The parameters :func:`perturbations` knows: the physics (:class:`StageParameters` fields;
#: ``creep_weights`` scales every weight), and the amplifier's ``bandwidth`` and ``slew_rate``.
PERTURBABLE = (
    "mass",
    "damping",
    "stiffness",
    "tem",
    "capacitance",
    "hyst_alpha",
    "hyst_beta",
    "hyst_gamma",
    "electrostriction",
    "creep_weights",
    "bandwidth",
    "slew_rate",
)


def perturbations(stage: Stage, parameters: Sequence[str] | None = None, fraction: float = 0.2) -> list[Stage]:
    """The stage with each parameter in turn ``fraction`` lower and higher, the others as they
    are: ``2 len(parameters)`` stages, named ``"<name> x0.8"``, ``"<name> x1.2"`` (for the
    default 20 %). The set a robustness check runs on (one parameter at a time), and the set
    :func:`piezohyst.tune` can tune for (``stages=``, worst case or a percentile).

    Parameters
    ----------
    stage : Stage
        The nominal stage (e.g. :func:`piezohyst.stage_from_model` of an identified model).
    parameters : sequence of str, optional
        Names from :data:`PERTURBABLE` (default: every one the stage has non-zero; an
        unlimited amplifier bandwidth or slew rate is left out).
    fraction : float
        Relative change, in ``(0, 1)``.

    Returns
    -------
    list of Stage

    Examples
    --------
    >>> from piezohyst import virtual_stage
    >>> from piezohyst.plant import perturbations
    >>> stages = perturbations(virtual_stage(), ["stiffness", "tem"])
    >>> [s.name for s in stages]
    ['stiffness x0.8', 'stiffness x1.2', 'tem x0.8', 'tem x1.2']
    >>> round(stages[1].params.stiffness / virtual_stage().params.stiffness, 12)
    1.2
    """
    if not isinstance(stage, Stage):
        raise ParameterTypeError(f"stage must be a Stage, got {type(stage).__name__}")
    f = as_scalar(fraction, "fraction", positive=True)
    if not f < 1:
        raise ParameterError(f"fraction = {f} must be < 1")
    p, a = stage.params, stage.amplifier
    if parameters is None:
        names = [
            n
            for n in PERTURBABLE
            if (n in ("bandwidth", "slew_rate") and math.isfinite(getattr(a, n)))
            or (n == "creep_weights" and any(p.creep_weights))
            or (n not in ("bandwidth", "slew_rate", "creep_weights") and getattr(p, n) != 0)
        ]
    elif isinstance(parameters, str) or not isinstance(parameters, Sequence):
        raise ParameterTypeError(f"parameters must be a list of names, got {parameters!r}")
    else:
        names = list(parameters)
    out = []
    for n in names:
        if n not in PERTURBABLE:
            raise ParameterError(f"parameters: {n!r} is not one of {', '.join(PERTURBABLE)}")
        for k in (1 - f, 1 + f):
            if n in ("bandwidth", "slew_rate"):
                changed = stage.with_(amplifier=replace(a, **{n: getattr(a, n) * k}))
            elif n == "creep_weights":
                changed = stage.with_(params=replace(p, creep_weights=tuple(w * k for w in p.creep_weights)))
            else:
                changed = stage.with_(params=replace(p, **{n: getattr(p, n) * k}))
            out.append(changed.with_(name=f"{n} x{k:g}"))
    return out


def virtual_stage() -> Stage:
    """The default virtual stage (``piezohyst/presets/virtual_stage.json``).

    Returns
    -------
    Stage

    Examples
    --------
    >>> from piezohyst import virtual_stage
    >>> stage = virtual_stage()
    >>> stage.name, stage.sample_time, stage.amplifier.v_max
    ('piezohyst virtual stage v1', 0.0001, 150.0)
    """
    text = resources.files("piezohyst").joinpath("presets/virtual_stage.json").read_text()
    return Stage.from_dict(json.loads(text))
