"""The frequency domain of a stage and its loops: measured frequency responses of the open
and the closed loop (multisine, swept sine, stepped sine; in simulation, the Rust kernel
running the stage and the controller), the margins of a linearizable loop by python-control
(gain, phase and modulus margins, sensitivity peaks), and the dynamic inversion of identified
dynamics for a feedforward.

Examples
--------
>>> import numpy as np
>>> import piezohyst as ph
>>> from piezohyst.control.frequency import loop_margins, measure_frf
>>> stage = ph.virtual_stage()
>>> plant = measure_frf(stage, band=(10.0, 2000.0), periods=3)          # open loop, m/V
>>> bool(abs(plant.at([10.0])[0]) / stage.params.static_gain > 1.0)  # creep adds a few %
True
>>> m = loop_margins(stage, ph.PID(kp=4e4, ki=1.4e10))
>>> m.stable, m.phase_margin_deg > 30, m.sensitivity_peak < 2
(True, True, True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .._validate import as_int, as_scalar
from ..errors import ComputationError, ParameterError, ParameterTypeError
from ..signals.frequency import FrequencyResponse, frf_from_record, multisine, swept_sine
from ..signals.lti import require_control, siso_polynomials
from ..signals.results import html_table
from .controllers import PID, Compensated, FilteredPID, InverseFeedforward, OpenLoop
from .filters import LagLead
from .simulation import closed_loop, closed_loop_batch

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..plant.stage import Stage
    from .simulation import ControllerLike

FloatArray = npt.NDArray[np.float64]

__all__ = ["DynamicInversion", "LoopMargins", "loop_margins", "measure_frf"]

_OUTPUTS = ("position", "measured", "error", "command")


def _grid(band: tuple[float, float], points: int) -> FloatArray:
    lo, hi = (as_scalar(b, "band") for b in band)
    if not 0 < lo < hi:
        raise ParameterError(f"band = {band} must satisfy 0 < f_min < f_max")
    return np.geomspace(lo, hi, as_int(points, "points", minimum=2))


def measure_frf(
    stage: Stage,
    controller: ControllerLike | None = None,
    *,
    method: str = "multisine",
    band: tuple[float, float] = (1.0, 1000.0),
    amplitude: float | None = None,
    offset: float | None = None,
    periods: int = 4,
    points: int = 40,
    output: str = "measured",
    rng: int | np.random.Generator | None = None,
) -> FrequencyResponse:
    """Measure a frequency response by simulation, as one would on the bench.

    Without ``controller``, the open loop: the command ``offset + amplitude x(t)`` (V) drives
    the stage, the response is ``output / command`` (m/V). With ``controller``, the closed
    loop (or a feedforward): the reference ``offset + amplitude x(t)`` (m) is tracked, the
    response is ``output / reference``: the complementary sensitivity ``T`` (``"position"``,
    ``"measured"``), the sensitivity ``S`` (``"error"``: reference minus position) or the
    control sensitivity (``"command"``, V/m). For a feedforward controller (e.g. the
    hysteresis inverse, :class:`~piezohyst.InverseFeedforward`) it is the compensated stage as
    the feedforward leaves it: what :meth:`DynamicInversion.fit` inverts.

    Parameters
    ----------
    stage : Stage
        The (virtual) stage.
    controller : controller, optional
        Closes the loop.
    method : {"multisine", "swept", "stepped"}
        A periodic multisine with Schroeder phases (``periods`` periods after one settling
        period; resolution ``band[0]``), a logarithmic swept sine (``periods`` sweeps of
        ``4 / band[0]`` s; Welch's H1 at ``points`` frequencies) or a stepped sine (a sine at
        each of ``points`` log-spaced frequencies, two periods or 50 ms of settling, whichever
        is longer, then ``periods`` measured ones, lock-in; closed loops run in parallel).
    band : (float, float)
        ``(f_min, f_max)``, Hz, below Nyquist.
    amplitude, offset : float, optional
        The excitation's peak and its operating point: V open loop (default 2 V around the
        middle of the amplifier range), m closed loop (default 1 µm around the middle of the
        stroke).
    periods : int
        Periods (sweeps) averaged.
    points : int
        Frequencies of the stepped sine and the swept sine's report.
    output : {"measured", "position", "error", "command"}
        ``"measured"``: the sensor's reading (noise and quantization as the stage's sensor
        has them), its known delay of ``sensor.delay`` samples divided out, as a bench
        measurement reports the stage; ``"position"``: the true position (simulation only).
    rng : int or Generator, optional
        Noise seed.

    Returns
    -------
    FrequencyResponse

    Examples
    --------
    >>> import piezohyst as ph
    >>> from piezohyst.control.frequency import measure_frf
    >>> stage = ph.virtual_stage()
    >>> t = measure_frf(stage, ph.PID(kp=4e4, ki=1.4e10), band=(5.0, 500.0), output="position")
    >>> round(float(abs(t.at([5.0])[0])), 2)       # tracks slow references
    1.0
    """
    if output not in _OUTPUTS:
        raise ParameterError(f"output = {output!r} must be one of {', '.join(_OUTPUTS)}")
    fs = 1.0 / stage.sample_time
    lo, hi = (as_scalar(b, "band") for b in band)
    if not 0 < lo < hi < fs / 2:
        raise ParameterError(f"band = {band} must satisfy 0 < f_min < f_max < fs / 2 = {fs / 2:g} Hz")
    reps = as_int(periods, "periods", minimum=1)
    seed = 0 if rng is None else rng
    noise = np.random.default_rng(seed)
    closed = controller is not None
    if closed and output == "command":
        unit = "V/m"
    else:
        unit = "" if closed else ("V/V" if output == "command" else "m/V")
    if closed:
        s_lo, s_hi = stage.stroke()
        off = 0.5 * (s_lo + s_hi) if offset is None else as_scalar(offset, "offset")
        amp = 1e-6 if amplitude is None else as_scalar(amplitude, "amplitude", positive=True)
        if off - amp < s_lo or off + amp > s_hi:
            raise ParameterError(
                f"offset ± amplitude = {off:.4g} ± {amp:.4g} m leaves the stage's stroke [{s_lo:.4g}, {s_hi:.4g}] m"
            )
    else:
        a = stage.amplifier
        off = 0.5 * (max(a.v_min, 0.0) + a.v_max) if offset is None else as_scalar(offset, "offset")
        amp = 2.0 if amplitude is None else as_scalar(amplitude, "amplitude", positive=True)
        if off - amp < a.v_min or off + amp > a.v_max:
            raise ParameterError(
                f"offset ± amplitude = {off:g} ± {amp:g} V leaves the amplifier range [{a.v_min}, {a.v_max}] V"
            )

    def respond(excitation: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(input, output)`` records for one excitation (already scaled)."""
        x = off + excitation
        if closed:
            assert controller is not None
            res = closed_loop(stage, controller, x, rng=int(noise.integers(0, 2**31)))
            return x, _output(stage, res.position, res.command, x, output, noise)
        r = stage.simulate(x)
        return x, _output(stage, r.position, x, x, output, noise)

    name_in = "reference" if closed else "command"
    if method == "multisine":
        n = math.ceil(fs / lo)
        ex, _ = multisine(fs, n, (lo, hi), periods=reps + 1, amplitude=amp)
        u, y = respond(ex)
        frf = frf_from_record(u, y, fs, period=n, skip=n, input_name=name_in, output_name=output, unit=unit)
    elif method == "swept":
        seconds = 4.0 / lo
        sweep = swept_sine(fs, lo, hi, seconds, amplitude=amp)
        ex = np.tile(sweep, reps + 1)
        u, y = respond(ex)
        frf = frf_from_record(
            u,
            y,
            fs,
            frequencies=_grid((lo, hi), points),
            nperseg=sweep.size,
            skip=sweep.size,
            input_name=name_in,
            output_name=output,
            unit=unit,
        )
    elif method == "stepped":
        frf = _stepped(stage, controller, off, amp, _grid((lo, hi), points), reps, output, noise, name_in, unit)
    else:
        raise ParameterError(f"method = {method!r} must be 'multisine', 'swept' or 'stepped'")
    h = frf.response
    if output == "measured":
        # the sensor's known delay divided out
        h = h * np.exp(2j * np.pi * frf.frequency * stage.sensor.delay * stage.sample_time)
    title = f"{'closed loop ' + type(controller).__name__ if closed else 'open loop'}: {output} / {name_in}"
    method_name = {"multisine": "multisine", "swept": "swept sine", "stepped": "stepped sine"}[method]
    return FrequencyResponse(frf.frequency, h, frf.coherence, name_in, output, unit, method_name, title)


def _output(
    stage: Stage,
    position: FloatArray,
    command: FloatArray,
    reference: FloatArray,
    output: str,
    noise: np.random.Generator,
) -> FloatArray:
    """The recorded output: the true position, the sensor's reading (noise, quantization and
    delay as the stage's sensor), the error or the command."""
    if output == "position":
        return position
    if output == "error":
        return reference - position
    if output == "command":
        return command
    s = stage.sensor
    y = position + s.noise_std * noise.standard_normal(position.size)
    if s.quantization > 0:
        y = np.round(y / s.quantization) * s.quantization
    return np.r_[np.full(s.delay, y[0]), y[: y.size - s.delay]] if s.delay else y


def _stepped(
    stage: Stage,
    controller: ControllerLike | None,
    off: float,
    amp: float,
    freqs: FloatArray,
    reps: int,
    output: str,
    noise: np.random.Generator,
    name_in: str,
    unit: str,
) -> FrequencyResponse:
    fs = 1.0 / stage.sample_time
    records = []
    # the operating point reached smoothly first (a raised cosine over 20 ms), so a lightly
    # damped mode is not rung by a step to the offset
    n_ramp = math.ceil(0.02 * fs)
    ramp = off * 0.5 * (1 - np.cos(np.pi * np.arange(n_ramp) / n_ramp))
    for f in freqs:
        # two periods, and at least 50 ms for lightly damped modes to settle
        n_settle = max(math.ceil(2 * fs / f), math.ceil(0.05 * fs))
        n_meas = round(reps * fs / f)
        t = np.arange(n_settle + n_meas) / fs
        records.append((np.r_[ramp, off + amp * np.sin(2 * np.pi * f * t)], n_ramp + n_settle))
    outs: list[FloatArray] = []
    if controller is not None:
        runs = closed_loop_batch(stage, [(controller, x) for x, _ in records], rng=int(noise.integers(0, 2**31)))
        for (x, _), r in zip(records, runs, strict=True):
            outs.append(_output(stage, r.position, r.command, x, output, noise))
    else:
        for x, _ in records:
            outs.append(_output(stage, stage.simulate(x).position, x, x, output, noise))
    h = np.empty(freqs.size, dtype=np.complex128)
    for i, (f, (x, k0), y) in enumerate(zip(freqs, records, outs, strict=True)):
        t = (np.arange(x.size)[k0:] - k0) / fs
        basis = np.c_[np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t), np.ones_like(t)]
        cx = np.linalg.lstsq(basis, x[k0:], rcond=None)[0]
        cy = np.linalg.lstsq(basis, y[k0:], rcond=None)[0]
        h[i] = complex(cy[0], -cy[1]) / complex(cx[0], -cx[1])
    return FrequencyResponse(freqs, h, None, name_in, output, unit, "stepped sine")


# -- margins --------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class LoopMargins:
    """Stability margins of a loop ``L = C P`` (python-control), and its sensitivity peaks.

    Parameters
    ----------
    gain_margin : float
        Factor the loop gain may grow before instability (``inf``: none).
    gain_margin_db : float
        The same in dB, ``20 log10 gain_margin``.
    phase_margin_deg : float
        The phase margin at the gain crossover, degrees.
    modulus_margin : float
        The smallest distance of ``L`` to -1, ``1 / sensitivity_peak``.
    gain_crossover_hz, phase_crossover_hz : float
        Where ``|L| = 1`` and where the phase is -180 degrees (``nan``: none).
    sensitivity_peak, sensitivity_peak_hz : float
        ``Ms = max |1 / (1 + L)|`` and its frequency.
    complementary_peak, complementary_peak_hz : float
        ``Mt = max |L / (1 + L)|`` and its frequency.
    stable : bool
        Every closed-loop pole inside the unit circle.
    loop : FrequencyResponse
        ``L`` on the grid the peaks were taken on.

    Examples
    --------
    >>> import numpy as np
    >>> import piezohyst as ph
    >>> from piezohyst.control.frequency import loop_margins
    >>> m = loop_margins(ph.virtual_stage(), ph.PID(kp=4e4, ki=1.4e10))
    >>> m.stable, round(m.gain_margin_db, 1), round(m.phase_margin_deg, 1)
    (True, 14.9, 72.9)
    >>> bool(np.isclose(m.gain_margin_db, 20 * np.log10(m.gain_margin)))
    True
    >>> bool(np.isclose(m.modulus_margin * m.sensitivity_peak, 1.0))
    True
    """

    gain_margin: float
    gain_margin_db: float
    phase_margin_deg: float
    modulus_margin: float
    gain_crossover_hz: float
    phase_crossover_hz: float
    sensitivity_peak: float
    sensitivity_peak_hz: float
    complementary_peak: float
    complementary_peak_hz: float
    stable: bool
    loop: FrequencyResponse

    def to_dict(self) -> dict[str, float | bool]:
        """The numbers (JSON-ready).

        Returns
        -------
        dict

        Examples
        --------
        >>> import piezohyst as ph
        >>> from piezohyst.control.frequency import loop_margins
        >>> sorted(loop_margins(ph.virtual_stage(), ph.PID(kp=4e4, ki=1.4e10)).to_dict())[:3]
        ['complementary_peak', 'complementary_peak_hz', 'gain_crossover_hz']
        """
        return {k: v for k, v in vars(self).items() if k != "loop"}

    def _repr_html_(self) -> str:
        rows = [
            ("gain margin", f"{self.gain_margin_db:.3g} dB"),
            ("phase margin", f"{self.phase_margin_deg:.3g} deg at {self.gain_crossover_hz:.4g} Hz"),
            ("modulus margin", f"{self.modulus_margin:.3g}"),
            ("Ms", f"{self.sensitivity_peak:.3g} at {self.sensitivity_peak_hz:.4g} Hz"),
            ("Mt", f"{self.complementary_peak:.3g} at {self.complementary_peak_hz:.4g} Hz"),
            ("stable", str(self.stable)),
        ]
        return html_table("loop margins", rows)


def _feedback(controller: object, sample_time: float) -> tuple[Any, bool]:
    """The controller's linear feedback ``C(z)`` (``u = -C y``) and whether it acts behind a
    hysteresis inverse (the loop is then in the linearized domain)."""
    ct = require_control()
    inner, behind = controller, False
    if isinstance(controller, (Compensated, InverseFeedforward)):
        behind = True
        inner = controller.inner if isinstance(controller, Compensated) else OpenLoop(gain=1.0)
    if isinstance(inner, FilteredPID):
        return inner.to_control(sample_time), behind
    if isinstance(inner, PID):
        return inner.to_control(sample_time), behind
    if isinstance(inner, OpenLoop):
        return ct.tf([0.0], [1.0], sample_time), behind
    raise ParameterTypeError(
        f"{type(inner).__name__} is not linear (its margins are not defined): loop_margins takes a PID, a "
        "FilteredPID, an OpenLoop, or one of them behind a hysteresis inverse"
    )


def loop_margins(
    stage: Stage, controller: object, *, creep: bool = True, cemf: bool = False, points: int = 2000
) -> LoopMargins:
    """Gain, phase and modulus margins and the sensitivity peaks of the loop ``controller``
    closes around ``stage``'s linear part, by python-control.

    The plant is the stage's zero-order-hold discretization with the sensor's delay
    (:meth:`~piezohyst.Stage.to_control` with ``discrete=True, measured=True``: amplifier lag,
    mechanics, added modes, creep; the CEMF by its slope at rest with ``cemf=True``); the
    controller is the discrete law the core runs (:meth:`~piezohyst.PID.to_control`,
    :meth:`~piezohyst.FilteredPID.to_control`). Behind a hysteresis inverse
    (:class:`~piezohyst.Compensated`) the loop is taken in the linearized domain: the stage
    divided by its static gain (the inverse's ideal). Non-linear laws (SMC, ABSMC) have no
    margins: ``ParameterTypeError``.

    Parameters
    ----------
    stage : Stage
    controller : PID, FilteredPID, OpenLoop or Compensated
    creep, cemf : bool
        The plant's creep lags and CEMF slope (see :meth:`~piezohyst.Stage.to_control`).
    points : int
        Frequencies of the peak search (log-spaced up to Nyquist).

    Returns
    -------
    LoopMargins

    Examples
    --------
    >>> import piezohyst as ph
    >>> from piezohyst.control.frequency import loop_margins
    >>> m = loop_margins(ph.virtual_stage(), ph.PID(kp=4e4, ki=1.4e10))
    >>> round(m.phase_margin_deg), round(m.gain_margin_db, 1), round(m.sensitivity_peak, 2)
    (73, 14.9, 1.3)
    """
    ct = require_control()
    ts = stage.sample_time
    c, behind = _feedback(controller, ts)
    p = stage.to_control(discrete=True, measured=True, creep=creep, cemf=cemf)
    if behind:
        p = p * (1.0 / stage.params.static_gain)
    # state space throughout: the creep lags put poles within 1e-6 of z = 1, where the
    # polynomial form loses them
    num_c, den_c, _ = siso_polynomials(c, "controller")
    loop = ct.ss(ct.tf(num_c, den_c, ts)) * ct.ss(p)
    f = np.geomspace(0.1, 0.5 / ts * 0.999, as_int(points, "points", minimum=10))
    z = np.exp(2j * np.pi * f * ts)
    a, b, cc, d = (np.asarray(m, dtype=np.float64) for m in (loop.A, loop.B, loop.C, loop.D))
    eye = np.eye(a.shape[0])
    lz = np.array([(cc @ np.linalg.solve(zk * eye - a, b))[0, 0] + d[0, 0] for zk in z], dtype=np.complex128)
    s_mag, t_mag = np.abs(1 / (1 + lz)), np.abs(lz / (1 + lz))
    ks, kt = int(np.argmax(s_mag)), int(np.argmax(t_mag))
    try:
        gm, pm, _, wpc, wgc, _ = ct.stability_margins(ct.frd(lz, 2 * np.pi * f))
    except Exception as e:  # pragma: no cover - python-control's own failures
        raise ComputationError(f"python-control could not compute the margins: {e}") from e
    closed = ct.feedback(loop, 1)
    stable = bool(np.all(np.abs(np.linalg.eigvals(np.asarray(closed.A, dtype=np.float64))) < 1.0))

    def hz(w: float) -> float:
        return float(w) / (2 * math.pi) if np.isfinite(w) and w > 0 else float("nan")

    gm = float(gm)
    return LoopMargins(
        gain_margin=gm,
        gain_margin_db=20 * math.log10(gm) if np.isfinite(gm) and gm > 0 else float("inf"),
        phase_margin_deg=float(pm),
        modulus_margin=1.0 / float(s_mag[ks]),
        gain_crossover_hz=hz(wgc),
        phase_crossover_hz=hz(wpc),
        sensitivity_peak=float(s_mag[ks]),
        sensitivity_peak_hz=float(f[ks]),
        complementary_peak=float(t_mag[kt]),
        complementary_peak_hz=float(f[kt]),
        stable=stable,
        loop=FrequencyResponse(
            f, np.asarray(lz, dtype=np.complex128), None, "error", "measured", "", "python-control", "loop gain C P"
        ),
    )


# -- dynamic inversion ----------------------------------------------------------------------
@dataclass(frozen=True)
class DynamicInversion:
    """Identified dynamics ``G(s) = gain (1 + s / (2 pi zero)) / (1 + s / (2 pi pole)) e^(-s delay)``
    of a stage as a feedforward sees it (measured, e.g. behind the hysteresis inverse:
    :func:`measure_frf` with :class:`~piezohyst.InverseFeedforward`), and their inverse for the
    feedforward of a :class:`~piezohyst.FilteredPID`.

    The lag-lead captures a gain that changes with frequency (a model's creep terms against the
    stage's), the delay the amplifier's lag, the sample-and-hold and what the mechanics add
    below their resonance. The inverse is ``(1 / gain) (1 + s / (2 pi pole)) / (1 + s / (2 pi
    zero)) e^(s delay)``: the lag-lead inverted as a filter on the reference, the lead
    ``e^(s delay) ~ 1 + delay s + delay^2 s^2 / 2`` from the reference's velocity and
    acceleration (:meth:`feedforward`).

    Parameters
    ----------
    gain : float
        The static gain.
    zero : float
        The lag-lead's zero, Hz.
    pole : float
        The lag-lead's pole, Hz.
    delay : float
        The delay, s.

    Examples
    --------
    >>> import numpy as np
    >>> from piezohyst.control.frequency import DynamicInversion
    >>> from piezohyst.signals.frequency import FrequencyResponse
    >>> f = np.geomspace(2, 300, 20)
    >>> truth = DynamicInversion(gain=1.01, zero=15.0, pole=16.0, delay=1.1e-4)
    >>> fit = DynamicInversion.fit(FrequencyResponse(f, truth.response(f)))
    >>> round(fit.gain, 4), round(fit.zero / fit.pole, 4), round(fit.delay * 1e6, 2)
    (1.01, 0.9375, 110.0)
    """

    gain: float
    zero: float
    pole: float
    delay: float

    def response(self, f: npt.ArrayLike) -> npt.NDArray[np.complex128]:
        """``G(j 2 pi f)``.

        Parameters
        ----------
        f : array_like
            Hz.

        Returns
        -------
        ndarray of complex

        Examples
        --------
        >>> from piezohyst.control.frequency import DynamicInversion
        >>> round(float(abs(DynamicInversion(2.0, 10.0, 10.0, 0.0).response([5.0])[0])), 6)
        2.0
        """
        s = 2j * np.pi * np.asarray(f, dtype=np.float64)
        g = self.gain * (1 + s / (2 * np.pi * self.zero)) / (1 + s / (2 * np.pi * self.pole)) * np.exp(-s * self.delay)
        return np.asarray(g, dtype=np.complex128)

    @classmethod
    def fit(cls, frf: FrequencyResponse, *, lag_lead: bool = True) -> DynamicInversion:
        """Fit ``G`` to a measured response by least squares on ``log(G_model / G_measured)``
        (relative gain and phase errors weighted alike).

        Parameters
        ----------
        frf : FrequencyResponse
            At least four frequencies (a ratio, e.g. position / reference).
        lag_lead : bool
            Fit the lag-lead (default); ``False``: gain and delay only.

        Returns
        -------
        DynamicInversion

        Examples
        --------
        >>> import numpy as np
        >>> from piezohyst.control.frequency import DynamicInversion
        >>> from piezohyst.signals.frequency import FrequencyResponse
        >>> f = np.array([10.0, 50.0, 100.0, 200.0])
        >>> g = DynamicInversion.fit(FrequencyResponse(f, 0.98 * np.exp(-2j * np.pi * f * 1e-4)), lag_lead=False)
        >>> round(g.gain, 6), round(g.delay * 1e6, 3)
        (0.98, 100.0)
        """
        from scipy.optimize import least_squares

        if not isinstance(frf, FrequencyResponse):
            raise ParameterTypeError(f"frf must be a FrequencyResponse, got {type(frf).__name__}")
        if frf.frequency.size < 4:
            raise ParameterError(f"frf has {frf.frequency.size} frequencies; the fit needs at least 4")
        f, h = frf.frequency, frf.response
        w = 2 * np.pi * f
        phase = np.unwrap(np.angle(h))
        k = max(2, f.size // 3)
        delay0 = max(0.0, -float(np.polyfit(w[-k:], phase[-k:], 1)[0]))
        mid = float(np.sqrt(f[0] * f[-1]))

        def model(theta: FloatArray) -> npt.NDArray[np.complex128]:
            if lag_lead:
                g, z, p, d = math.exp(theta[0]), math.exp(theta[1]), math.exp(theta[2]), theta[3]
            else:
                g, z, p, d = math.exp(theta[0]), mid, mid, theta[1]
            return cls(g, z, p, d).response(f)

        def residual(theta: FloatArray) -> FloatArray:
            r = np.log(model(theta) / h)
            r = r.real + 1j * (np.angle(np.exp(1j * r.imag)))
            return np.concatenate([r.real, r.imag])

        g0 = math.log(float(np.abs(h[0])))
        start = np.array([g0, math.log(mid), math.log(mid * 1.01), delay0]) if lag_lead else np.array([g0, delay0])
        sol = least_squares(residual, start, x_scale="jac")
        if lag_lead:
            g, z, p, d = math.exp(sol.x[0]), math.exp(sol.x[1]), math.exp(sol.x[2]), float(sol.x[3])
        else:
            g, z, p, d = math.exp(sol.x[0]), mid, mid, float(sol.x[1])
        return cls(g, z, p, d)

    def feedforward(self) -> dict[str, Any]:
        """The fields of a :class:`~piezohyst.FilteredPID` that invert ``G``: ``ff_gain``,
        ``ff_filters`` (the inverted lag-lead) and ``c1``, ``c2`` (the delay's lead on the
        reference's velocity and acceleration, at the lag-lead's high-frequency gain).

        Returns
        -------
        dict

        Examples
        --------
        >>> from piezohyst.control.frequency import DynamicInversion
        >>> ff = DynamicInversion(gain=1.03, zero=20.0, pole=21.0, delay=1e-4).feedforward()
        >>> round(ff["ff_gain"], 6), ff["ff_filters"][0]
        (0.970874, LagLead(zero=21.0, pole=20.0))
        """
        hf = (self.zero / self.pole) / self.gain  # the inverse's gain above the corners
        return {
            "ff_gain": 1.0 / self.gain,
            "ff_filters": (LagLead(zero=self.pole, pole=self.zero),),
            "c1": self.delay * hf,
            "c2": 0.5 * self.delay * self.delay * hf,
        }
