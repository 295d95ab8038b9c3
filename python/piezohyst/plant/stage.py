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
from dataclasses import dataclass, field, replace
from importlib import resources
from os import PathLike
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .. import _core
from .._io import check_parameter_tree, json_text, load_json_file, malformed_as, printable
from .._validate import as_int, as_record, as_scalar, as_vector
from ..errors import ParameterError, ParameterTypeError
from ..signals.response import Response

FloatArray: TypeAlias = npt.NDArray[np.float64]

__all__ = ["Amplifier", "Sensor", "Stage", "StageInfo", "StageParameters", "StageResponse", "virtual_stage"]

MAX_CREEP = 8


@dataclass(frozen=True)
class Amplifier:
    """Drive amplifier: output limits (V), -3 dB bandwidth (Hz, ``inf`` = ideal) and slew
    rate (V/s, ``inf`` = unlimited)."""

    v_min: float = -20.0
    v_max: float = 150.0
    bandwidth: float = math.inf
    slew_rate: float = math.inf

    def __post_init__(self) -> None:
        lo = as_scalar(self.v_min, "v_min")
        hi = as_scalar(self.v_max, "v_max")
        if not hi > lo:
            raise ParameterError(f"amplifier limits reversed: v_min = {lo} must be < v_max = {hi}")
        for name in ("bandwidth", "slew_rate"):
            x = as_scalar(getattr(self, name), name, allow_infinite=True)
            if not x > 0:
                raise ParameterError(f"{name} = {x} must be > 0 (inf for none)")


@dataclass(frozen=True)
class Sensor:
    """Position sensor: quantization step (m, 0 = none), white-noise standard deviation (m)
    and delay in whole controller samples."""

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
class StageParameters:
    """Physical parameters of a piezo stage with CEMF hysteresis (SI units).

    ``hyst_drive`` is ``"charge"`` (seed 1's model) or ``"voltage"`` (the input-driven
    variant, where ``alpha`` is V/V and ``beta``, ``gamma`` are 1/V).
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
        return self.damping / (2 * math.sqrt(self.stiffness * self.mass))

    @property
    def static_gain(self) -> float:
        """``Tem / k``: position per volt without hysteresis or creep, m/V."""
        return self.tem / self.stiffness


class StageResponse(Response):
    """Open-loop response, one value per controller sample: a
    :class:`~piezohyst.signals.Response` with the input ``command`` (V) and the outputs
    ``voltage`` (amplifier, V), ``position`` (m) and ``cemf`` (CEMF voltage, V).

    Parameters
    ----------
    time : array_like, shape (N,)
        Sample instants, s.
    command, voltage, position, cemf : array_like, shape (N,)
    final_state : array_like
        Stage state at the end ``[va, x, v, vh, creep[8]]``: pass it as the next run's
        ``initial_state`` to continue.
    title : str, optional
        The stage's name.
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
    """What ``piezohyst stage info`` measures on a stage."""

    stroke: float
    hysteresis_percent: float
    resonance: float
    creep_percent_per_decade: float
    natural_frequency: float
    damping_ratio: float
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
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

    def __post_init__(self) -> None:
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
        """Build from the stage-file layout (see ``presets/virtual_stage.json``): ``d`` is
        the parsed JSON object (a dict; anything else raises ``ValueError``)."""
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
                a.get("min", -20.0), a.get("max", 150.0), _inf(a.get("bandwidth")), _inf(a.get("slew_rate"))
            )
            s = d.get("sensor", {})
            sensor = Sensor(s.get("quantization", 0.0), s.get("noise_std", 0.0), s.get("delay", 0))
            loop = d.get("loop", {})
            return cls(
                params,
                amp,
                sensor,
                loop.get("sample_time", 1e-4),
                loop.get("substeps", 1),
                _inf(loop.get("tolerance", 0.05)),
                d.get("name", ""),
            )

    @classmethod
    def from_file(cls, path: str | PathLike[str]) -> Stage:
        """Read a stage file (JSON, the layout of the packaged virtual stage)."""
        return load_json_file(path, "stage file", cls.from_dict)

    def to_dict(self) -> dict[str, Any]:
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
        }

    def with_(self, **changes: Any) -> Stage:
        """A copy with some fields replaced (``params``, ``amplifier``, ``sensor``, ...)."""
        return replace(self, **changes)

    # -- core layout ----------------------------------------------------------------------
    def core_params(self) -> FloatArray:
        """The flat parameter array of the Rust core (``StageParams::from_slice``)."""
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
            a.slew_rate,
            float(len(p.creep_taus)),
        ]
        return np.array(head + taus + weights, dtype=np.float64)

    @functools.cached_property
    def compiled(self) -> _core.Stage:
        """The Rust core's stage (parameters, control period, integration settings and
        sensor), built and validated once per stage and reused by every run on it."""
        s = self.sensor
        return _core.Stage(
            self.core_params(), self.sample_time, self.substeps, self.tolerance, s.quantization, s.noise_std, s.delay
        )

    # the compiled stage is not picklable: a pickle carries the fields; it is rebuilt on use
    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state.pop("compiled", None)
        return state

    @staticmethod
    def rest_state() -> FloatArray:
        """The state at rest: ``[va, x, v, vh, creep[8]]`` all zero."""
        return np.zeros(_core.STAGE_STATE_LEN)

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
            core = _core.Stage(self.core_params(), ts, m, tol)
        x, va, vh = core.simulate(u, st)
        return StageResponse(np.arange(u.size) * ts, u, va, x, vh, st, title=self.name)

    def check_command(self, u: FloatArray, name: str = "command") -> None:
        a = self.amplifier
        bad = np.flatnonzero((u < a.v_min) | (u > a.v_max))
        if bad.size:
            k = bad[0]
            raise ParameterError(f"{name}[{k}] = {u[k]} V is outside the amplifier range [{a.v_min}, {a.v_max}] V")

    # -- measurements ---------------------------------------------------------------------
    def info(self) -> StageInfo:
        """Measure stroke, hysteresis at 1 Hz over the full 0..v_max range, first resonance and
        creep per time decade, by simulation (not from the parameters)."""
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
        stage with an ideal amplifier, the peak of the response spectrum (what :meth:`info` reports)."""
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


def virtual_stage() -> Stage:
    """The default virtual stage (``piezohyst/presets/virtual_stage.json``)."""
    text = resources.files("piezohyst").joinpath("presets/virtual_stage.json").read_text()
    return Stage.from_dict(json.loads(text))
