"""Controller configurations. The step functions live in the Rust core
(``crates/core/src/control.rs``); these classes validate and carry the parameters.

Every controller takes the reference and the measured position (m) and returns a voltage
clamped to ``[u_min, u_max]`` (by default the stage amplifier's range).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_scalar

__all__ = ["OpenLoop", "PID"]


def _limits(u_min, u_max, stage):
    lo = stage.amplifier.v_min if u_min is None else as_scalar(u_min, "u_min")
    hi = stage.amplifier.v_max if u_max is None else as_scalar(u_max, "u_max")
    if not hi > lo:
        raise ValueError(f"u_min = {lo} must be < u_max = {hi}")
    a = stage.amplifier
    # limits beyond the amplifier would let it clip where the controller cannot see it
    # (the integrator would wind up)
    if lo < a.v_min:
        raise ValueError(f"u_min = {lo} V is below the amplifier's v_min = {a.v_min} V")
    if hi > a.v_max:
        raise ValueError(f"u_max = {hi} V is above the amplifier's v_max = {a.v_max} V")
    return lo, hi


@dataclass(frozen=True)
class OpenLoop:
    """``u = offset + gain * x_d``: a static inverse (``gain`` in V/m; by default the
    stage's ``1 / static_gain``).

    Examples
    --------
    >>> from piezohyst import OpenLoop, virtual_stage
    >>> kind, p = OpenLoop(gain=7e6).core(virtual_stage())
    >>> kind, p.tolist()
    ('open_loop', [7000000.0, 0.0, -20.0, 150.0])
    """

    gain: float | None = None
    offset: float = 0.0
    u_min: float | None = None
    u_max: float | None = None

    #: the step uses only the reference position
    uses_reference_derivatives = False

    def core(self, stage):
        gain = 1.0 / stage.params.static_gain if self.gain is None else as_scalar(self.gain, "gain")
        lo, hi = _limits(self.u_min, self.u_max, stage)
        return "open_loop", np.array([gain, as_scalar(self.offset, "offset"), lo, hi])


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

    def core(self, stage):
        for name in ("kp", "ki", "kd"):
            as_scalar(getattr(self, name), name, nonnegative=True)
        as_scalar(self.tau_d, "tau_d", positive=True)
        ff = 1.0 / stage.params.static_gain if self.ff_gain is None else as_scalar(self.ff_gain, "ff_gain")
        lo, hi = _limits(self.u_min, self.u_max, stage)
        return "pid", np.array([self.kp, self.ki, self.kd, self.tau_d, stage.sample_time, ff,
                                as_scalar(self.offset, "offset"), lo, hi])


def is_controller(c) -> bool:
    return hasattr(c, "core") and callable(c.core)


