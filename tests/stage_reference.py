"""An independent reference for the stage: the continuous equations integrated by
scipy.integrate.solve_ivp at a tight tolerance, one controller period at a time (the
command is held over each period, so the right-hand side is smooth inside a period).
The amplifier must have a finite bandwidth and no slew limit (no jumps, no kinks)."""

import math

import numpy as np
from scipy.integrate import solve_ivp


def reference_positions(stage, command, ts, rtol=1e-12, atol_scale=1e-14):
    p, a = stage.params, stage.amplifier
    assert math.isfinite(a.bandwidth) and math.isinf(a.slew_rate)
    tau_a = 1 / (2 * math.pi * a.bandwidth)
    taus = np.array(p.creep_taus)
    weights = np.array(p.creep_weights)
    m = len(taus)

    def rhs(t, s, u):
        va, x, v, vh = s[:4]
        w = s[4:]
        dva = (u - va) / tau_a
        if p.hyst_drive == "charge":
            drive = p.tem * v + p.capacitance * dva  # q' before the CEMF feedback
            sg = math.copysign(1.0, drive) if drive != 0 else 0.0
            g = p.hyst_alpha - p.hyst_beta * sg * vh - p.hyst_gamma * abs(vh)
            dq = drive / (1 + p.capacitance * g)
            dvh = g * dq
        else:
            sg = math.copysign(1.0, dva) if dva != 0 else 0.0
            dvh = (p.hyst_alpha - p.hyst_beta * sg * vh - p.hyst_gamma * abs(vh)) * dva
        vcr = float(weights @ w) if m else 0.0
        force = p.tem * (va - vh + vcr + p.electrostriction * va * va)
        dv = (force - p.damping * v - p.stiffness * x) / p.mass
        dw = (va - w) / taus if m else []
        return [dva, v, dv, dvh, *dw]

    s = np.zeros(4 + m)
    xs = []
    scale = np.array([150.0, 2e-5, 1.0, 20.0] + [150.0] * m)
    for u in command:
        xs.append(s[1])
        sol = solve_ivp(rhs, (0.0, ts), s, args=(float(u),), method="DOP853", rtol=rtol, atol=atol_scale * scale)
        s = sol.y[:, -1]
    return np.array(xs)
