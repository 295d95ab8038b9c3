"""Model-based feedback design: H-infinity mixed sensitivity (python-control's ``mixsyn``,
which runs SLICOT's ``sb10ad`` through slycot, the optional extra ``piezohyst[hinf]``), cut
into the loop the Rust core runs.

:func:`mixed_sensitivity` designs on the stage's linear part (amplifier lag, mechanics, added
modes; the sensor's delay and the zero-order hold as a first-order Padé delay), with the
classic weights (Skogestad and Postlethwaite, §3.4.6 and §9.3)::

    W1(s) = (s / M + wb) / (s + wb A)       performance: |S| < 1/|W1|, bandwidth wb, peak M
    W2    = effort                           control effort (in units of the inverse static gain)
    W3(s) = (s + wt / MT) / (eps s + wt)     robustness: |T| < 1/|W3| above wt (unmodelled modes)

then realizes the controller as a :class:`~piezohyst.FilteredPID`: its slowest pole (the
``A``-shifted integrator) becomes the PID's integrator (conditional integration: anti-windup)
and the rest is cut into at most three :class:`~piezohyst.control.filters.Section` biquads
(pole/zero pairs, bilinear prewarped at the bandwidth). A controller of a higher order is
first reduced by balanced truncation (python-control ``balred``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .._validate import as_scalar
from ..errors import ComputationError, ParameterError
from ..signals.lti import require_control
from .controllers import FilteredPID
from .filters import Section

if TYPE_CHECKING:
    from ..plant.stage import Stage

__all__ = ["MixedSensitivity", "mixed_sensitivity"]

FloatArray = npt.NDArray[np.float64]
#: The largest controller the FilteredPID realizes: an integrator and three biquads.
MAX_ORDER = 7


@dataclass(frozen=True)
class MixedSensitivity:
    """The result of :func:`mixed_sensitivity`.

    Parameters
    ----------
    controller : FilteredPID
        The loop the core runs (``Compensated(result.controller, model)`` behind a hysteresis
        inverse when designed with ``linearized=True``).
    gamma : float
        The H-infinity norm achieved (below 1: every weighted bound holds).
    full : control.TransferFunction
        mixsyn's continuous controller (``u = K e``).
    realized : control.TransferFunction
        The continuous controller the FilteredPID runs (integrator times sections, before
        discretization).
    plant : control.TransferFunction
        The design plant (normalized to a unit static gain).

    Examples
    --------
    :func:`mixed_sensitivity` needs slycot; the result's fields, built by hand for a PI
    controller ``K(s) = kp + ki / s`` (what the FilteredPID realizes without sections):

    >>> import control
    >>> import piezohyst as ph
    >>> from piezohyst.control.design import MixedSensitivity
    >>> k = control.tf([1e4, 1e9], [1.0, 0.0])
    >>> d = MixedSensitivity(ph.FilteredPID(kp=1e4, ki=1e9), 0.8, k, k, control.tf([1.0], [1e-4, 1.0]))
    >>> bool(d.gamma < 1), d.controller.ki, d.realized.poles().tolist()   # every bound holds
    (True, 1000000000.0, [0j])
    """

    controller: FilteredPID
    gamma: float
    full: Any
    realized: Any
    plant: Any


def _pairs(roots: npt.ArrayLike) -> list[list[complex]]:
    """Roots grouped into conjugate pairs and pairs of reals (slowest first)."""
    r = sorted((complex(x) for x in np.atleast_1d(roots)), key=abs)
    cplx = [x for x in r if x.imag > 1e-9 * max(1.0, abs(x))]
    real = [complex(x.real, 0.0) for x in r if abs(x.imag) <= 1e-9 * max(1.0, abs(x))]
    groups = [[x, x.conjugate()] for x in cplx]
    groups += [real[j : j + 2] for j in range(0, len(real), 2)]
    return sorted(groups, key=lambda g: min(abs(x) for x in g))


def _poly(group: list[complex]) -> FloatArray:
    return np.real(np.poly(group)) if group else np.array([1.0])


def mixed_sensitivity(
    stage: Stage,
    *,
    bandwidth: float,
    peak: float = 2.0,
    low_frequency_error: float = 1e-4,
    effort: float = 0.05,
    robustness_frequency: float | None = None,
    robustness_peak: float = 2.0,
    robustness_gain: float = 100.0,
    linearized: bool = False,
    modes: bool = True,
) -> MixedSensitivity:
    """An H-infinity mixed-sensitivity feedback for ``stage`` (python-control ``mixsyn``; needs
    slycot).

    Parameters
    ----------
    stage : Stage
        The stage designed on (normally the identified model's,
        :func:`~piezohyst.stage_from_model`): its linear part without creep (the integrator
        takes care of it), the sensor's delay plus half a sample as a Padé delay.
    bandwidth : float
        ``wb``, Hz: where ``|S|`` crosses one.
    peak : float
        ``M``, the bound on the sensitivity peak.
    low_frequency_error : float
        ``A``, the bound on ``|S|`` at low frequency.
    effort : float
        ``W2``, the control effort's weight (on the command in units of ``1 / static gain``).
    robustness_frequency : float, optional
        ``wt``, Hz, where ``|T|`` must start rolling off (default: 4 x ``bandwidth``).
    robustness_peak, robustness_gain : float
        ``MT``, the bound on the peak of ``T``, and ``1 / eps``, the weight's high-frequency
        gain (``|T| < eps`` far above ``wt``).
    linearized : bool
        Design for the loop behind a hysteresis inverse (:class:`~piezohyst.Compensated`):
        the plant divided by its static gain (the inverse's ideal).
    modes : bool
        Keep the stage's added modes in the design plant.

    Returns
    -------
    MixedSensitivity

    Examples
    --------
    >>> import piezohyst as ph
    >>> from piezohyst.control.design import mixed_sensitivity
    >>> d = mixed_sensitivity(ph.virtual_stage(), bandwidth=200.0)      # doctest: +SKIP
    >>> bool(d.gamma < 1.5)                                             # doctest: +SKIP
    True
    """
    ct = require_control()
    try:
        import slycot  # noqa: F401
    except ImportError:
        raise ImportError(
            "mixed_sensitivity needs slycot (SLICOT, the H-infinity synthesis python-control calls): pip install slycot"
        ) from None
    ts = stage.sample_time
    wb = 2 * math.pi * as_scalar(bandwidth, "bandwidth", positive=True)
    if not bandwidth < 0.25 / ts:
        raise ParameterError(f"bandwidth = {bandwidth} Hz must be below a quarter of the sample rate {1 / ts:g} Hz")
    m = as_scalar(peak, "peak", positive=True)
    a = as_scalar(low_frequency_error, "low_frequency_error", positive=True)
    w2 = as_scalar(effort, "effort", positive=True)
    ftv = 4.0 * bandwidth if robustness_frequency is None else robustness_frequency
    wt = 2 * math.pi * as_scalar(ftv, "robustness_frequency", positive=True)
    mt = as_scalar(robustness_peak, "robustness_peak", positive=True)
    eps = 1.0 / as_scalar(robustness_gain, "robustness_gain", positive=True)
    if m <= 1 or mt <= 1:
        raise ParameterError(f"peak = {m} and robustness_peak = {mt} must be > 1")
    if a >= 1:
        raise ParameterError(f"low_frequency_error = {a} must be < 1")

    src = stage if modes else stage.with_(modes=())
    g_static = float(stage.params.static_gain)
    p = ct.ss2tf(src.to_control(creep=False))
    p = ct.tf(np.asarray(p.num[0][0], float) / g_static, np.asarray(p.den[0][0], float))
    delay = (float(stage.sensor.delay) + 0.5) * ts
    num_d, den_d = ct.pade(delay, 1)
    plant = ct.minreal(p * ct.tf(num_d, den_d), verbose=False)
    w1 = ct.tf([1.0 / m, wb], [1.0, wb * a])
    w3 = ct.tf([1.0, wt / mt], [eps, wt])
    try:
        with warnings.catch_warnings():
            # python-control 0.10.2's augw calls its own deprecated connect(): nothing the
            # caller can act on
            warnings.filterwarnings("ignore", r"connect\(\) is deprecated", FutureWarning)
            k, _, info = ct.mixsyn(plant, w1, ct.tf([w2], [1.0]), w3)
    except Exception as exc:  # slycot's errors carry SLICOT's info code
        raise ComputationError(f"mixsyn found no stabilizing controller: {exc}") from None
    gamma = float(info[0])
    kt = ct.ss2tf(k)
    num = np.asarray(kt.num[0][0], float)
    den = np.asarray(kt.den[0][0], float)
    num = np.trim_zeros(np.where(np.abs(num) < 1e-12 * np.max(np.abs(num)), 0.0, num), "f")
    poles = np.roots(den)
    if poles.size > MAX_ORDER:
        kr = ct.ss2tf(ct.balred(ct.tf2ss(kt), MAX_ORDER, method="truncate"))
        num, den = np.asarray(kr.num[0][0], float), np.asarray(kr.den[0][0], float)
        poles = np.roots(den)
    if np.any(poles.real > 1e-9 * max(1.0, float(np.max(np.abs(poles))))):
        raise ComputationError(f"the H-infinity controller is unstable (poles {poles}); relax the weights")
    slow = int(np.argmin(np.abs(poles)))
    rest = np.delete(poles, slow)
    zeros = np.roots(num) if num.size > 1 else np.array([])
    gain = float(num[0] / den[0])
    # the sections: pole groups, each with at most as many zeros as poles
    pole_groups = _pairs(rest)
    zero_groups = _pairs(zeros)
    if len(pole_groups) > 3:
        raise ComputationError(f"the controller's order {poles.size} leaves {len(pole_groups)} sections, at most 3")
    zeros_left = [z for g in zero_groups for z in g]
    sections: list[Section] = []
    for pg in pole_groups:
        take: list[complex] = []
        while zeros_left and len(take) < len(pg):
            z = zeros_left.pop(0)
            if abs(z.imag) > 0 and len(take) == len(pg) - 1:  # a conjugate pair needs two places
                zeros_left.insert(0, z)
                break
            take.append(z)
            if abs(z.imag) > 0:
                take.append(zeros_left.pop(0))
        nz, dz = _poly(take), _poly(pg)
        # unit gain at the bandwidth's scale: each section's gain moved into the PID
        sw = 1j * wb
        scale = float(abs(np.polyval(dz, sw) / np.polyval(nz, sw)))
        sections.append(
            Section(
                tuple(float(c) * scale for c in nz),
                tuple(float(c) for c in dz),
                warp=bandwidth,
                discretization="matched",
            )
        )
        gain /= scale
    if zeros_left:
        raise ComputationError(f"the controller has {len(zeros_left)} zero(s) no section can hold (improper)")
    # K(s) = gain prod(sections) / (s - slow): PID = ki / s with ki = gain (the slow pole to 0)
    ki = gain
    if not ki > 0:
        raise ComputationError(f"the controller's integral gain {ki} is not positive: the loop's sign is wrong")
    scale_domain = 1.0 if linearized else 1.0 / g_static
    controller = FilteredPID(ki=ki * scale_domain, notches=tuple(sections))
    realized = ct.tf([ki], [1.0, 0.0])
    for s in sections:
        n_s, d_s = s.polynomials()
        realized = realized * ct.tf(n_s, d_s)
    return MixedSensitivity(controller, gamma, kt, realized, plant)
