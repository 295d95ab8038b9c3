"""The linear controllers in python-control and scipy: PID (continuous, and the discrete law the
core runs), the open-loop feedforward, the velocity observer; and back (from_control)."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest
from scipy import signal

from piezohyst import PID, OpenLoop, VelocityObserver, _core, virtual_stage
from piezohyst.errors import ParameterError

TS = 1e-4


def _core_commands(pid: PID, reference: np.ndarray, measured: np.ndarray) -> np.ndarray:
    stage = virtual_stage()
    kind, params, _, _ = pid.core(stage)
    core = _core.Controller(kind, params)
    state = core.initial_state(0.0)
    zeros = np.zeros_like(reference)
    return core.steps(reference, zeros, zeros, measured, state)


def test_pid_continuous_transfer_function():
    c = PID(kp=2.0, ki=10.0, kd=0.5, tau_d=0.01).to_control()
    assert isinstance(c, ct.TransferFunction) and c.isctime()
    s = 2j * np.pi * np.array([0.3, 7.0, 200.0])
    expected = 2.0 + 10.0 / s + 0.5 * s / (0.01 * s + 1)
    assert np.allclose(c(s).ravel(), expected, rtol=1e-14)
    # terms with a zero gain leave their pole out: a PI is (kp s + ki) / s
    pi = PID(kp=2e6, ki=2e9).to_control()
    assert pi.den[0][0].tolist() == [1.0, 0.0] and pi.num[0][0].tolist() == [2e6, 2e9]
    assert PID(kp=3.0).to_control().den[0][0].tolist() == [1.0]


def test_pid_discrete_law_is_what_the_core_runs():
    """Inside the limits the core's PID is linear: the discrete transfer functions give its
    commands to rounding, from the error (1-DOF) and from reference and reading (2-DOF)."""
    pid = PID(kp=2e6, ki=2e9, kd=40.0, tau_d=3e-4, ff_gain=5e5)
    rng = np.random.default_rng(3)
    n = 400
    reference = 5e-6 * np.sin(2 * np.pi * 50 * TS * np.arange(n)) + 1e-8 * np.cumsum(rng.standard_normal(n))
    measured = reference + 2e-8 * rng.standard_normal(n)
    measured[0] = 0.0  # the core's derivative starts from the first reading (initial_state(0))
    u = _core_commands(pid, reference, measured)
    assert np.ptp(u) > 1.0 and np.all((u > -20) & (u < 150))  # a real signal, never saturated
    two = pid.to_control(TS, two_dof=True)
    assert two.dt == TS and two.input_labels == ["reference", "measured"]
    y = ct.forced_response(two, U=np.vstack([reference, measured])).outputs
    assert np.max(np.abs(y - u)) < 1e-9 * np.max(np.abs(u))
    # the feedback alone: with ff_gain = 0 and reference = 0, u = -C(z) y (a reading small
    # enough for the integrator to stay inside the limits)
    fb = PID(kp=2e6, ki=2e9, kd=40.0, tau_d=3e-4, ff_gain=0.0)
    small = 5e-8 * np.sin(2 * np.pi * 100 * TS * np.arange(n)) + 1e-8 * rng.standard_normal(n)
    small[0] = 0.0
    u0 = _core_commands(fb, np.zeros(n), small)
    assert np.ptp(u0) > 0.1 and np.all((u0 > -20) & (u0 < 150))
    y0 = ct.forced_response(fb.to_control(TS), U=-small).outputs
    assert np.max(np.abs(y0 - u0)) < 1e-9 * np.max(np.abs(u0))
    # and the scipy system is the same
    _, ys, *_ = signal.dlsim(fb.to_scipy(TS), -small)
    assert np.max(np.abs(ys.ravel() - u0)) < 1e-9 * np.max(np.abs(u0))


def test_discrete_pid_is_the_backward_euler_image_of_the_continuous_one():
    pid = PID(kp=2.0, ki=10.0, kd=0.5, tau_d=0.01)
    z = np.exp(2j * np.pi * np.array([0.5, 20.0, 900.0]) * TS)
    s = (z - 1) / (TS * z)
    assert np.allclose(pid.to_control(TS)(z).ravel(), pid.to_control()(s).ravel(), rtol=1e-12)


@pytest.mark.parametrize(
    "pid",
    [
        PID(kp=2.0, ki=10.0, kd=0.5, tau_d=0.01),
        PID(kp=2e6, ki=2e9),
        PID(kp=3.0),
        PID(kp=1.0, kd=0.2, tau_d=1e-3),
        PID(ki=5.0),
        PID(kp=2e6, ki=2e9, kd=30.0, tau_d=1e-4),
    ],
)
@pytest.mark.parametrize("dt", [None, TS])
def test_pid_round_trip(pid, dt):
    back = PID.from_control(pid.to_control(dt))
    for name in ("kp", "ki", "kd"):
        assert getattr(back, name) == pytest.approx(getattr(pid, name), rel=1e-9, abs=1e-9 * pid.kp)
    if pid.kd:
        assert back.tau_d == pytest.approx(pid.tau_d, rel=1e-9)
    assert back.ff_gain == 0.0  # the transfer function is pure feedback
    # from a state-space realization and from scipy alike
    assert PID.from_control(ct.ss(pid.to_control(dt))).kp == pytest.approx(pid.kp, rel=1e-8, abs=1e-9)
    assert PID.from_control(pid.to_scipy(dt)).ki == pytest.approx(pid.ki, rel=1e-8, abs=1e-9)


def test_pid_from_control_built_by_hand():
    s = ct.tf("s")
    pid = PID.from_control(2 + 10 / s + 0.5 * s / (0.01 * s + 1), u_min=0.0, u_max=100.0)
    assert (pid.kp, pid.ki, pid.kd, pid.tau_d) == pytest.approx((2.0, 10.0, 0.5, 0.01), rel=1e-12)
    assert (pid.u_min, pid.u_max) == (0.0, 100.0)


@pytest.mark.parametrize(
    "sys, message",
    [
        (ct.tf([1.0], [1.0, 2.0, 3.0]), "complex poles"),
        (ct.tf([-1.0, 0.0], [1.0, 0.0]), "kp = -1"),
        (ct.tf([1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 0.0]), "numerator degree 3"),
        (ct.tf([1.0, 1.0], [1.0, -5.0]), "filter's pole 5.0 must be < 0"),
        (ct.tf([1.0, 1.0, 1.0], [1.0, 3.0, 2.0]), "poles"),
        (ct.tf([1.0, 0.0], [1.0, -1.5], TS), r"must be in \(0, 1\)"),
    ],
)
def test_pid_from_control_refuses_other_forms(sys, message):
    with pytest.raises(ParameterError, match=message):
        PID.from_control(sys)


def test_open_loop_feedforward():
    ol = OpenLoop(gain=7e6, c1=1e-4, c2=2e-9)
    tf = ol.to_control()
    s = 2j * np.pi * 300.0
    assert tf(s) == pytest.approx(7e6 * (1 + 1e-4 * s + 2e-9 * s * s), rel=1e-14)
    back = OpenLoop.from_control(tf, offset=1.0)
    assert (back.gain, back.c1, back.c2, back.offset) == pytest.approx((7e6, 1e-4, 2e-9, 1.0), rel=1e-14)
    assert OpenLoop(gain=3.0).to_scipy().num.tolist() == [3.0]
    with pytest.raises(ParameterError, match="improper"):
        ol.to_scipy()
    with pytest.raises(ParameterError, match="gain = None"):
        OpenLoop().to_control()
    with pytest.raises(ParameterError, match="constant denominator"):
        OpenLoop.from_control(ct.tf([1.0], [1.0, 1.0]))
    with pytest.raises(ParameterError, match="no static gain"):
        OpenLoop.from_control(ct.tf([1.0, 0.0], [1.0]))


def test_velocity_observer_is_the_core_recurrence():
    obs = VelocityObserver(bandwidth=300.0, delay=1.0)
    sys = obs.to_control(TS)
    p = math.exp(-2 * math.pi * 300.0 * TS)
    assert np.sort(np.abs(sys.poles())) == pytest.approx([p, p], rel=1e-6)
    # the recurrence of crates/core/src/control/mod.rs, VelocityObserver::update
    rng = np.random.default_rng(4)
    y = np.cumsum(rng.standard_normal(300)) * 1e-8 + 1e-6 * np.arange(300) * TS * 50
    gx, gv = 1 - p * p, (1 - p) ** 2 / TS
    x = v = 0.0
    expected = []
    for yk in y:
        pred = x + TS * v
        innov = yk - pred
        x, v = pred + gx * innov, v + gv * innov
        expected.append((x + 1.0 * TS * v, v))
    out = ct.forced_response(sys, U=y).outputs
    assert np.allclose(out.T, np.array(expected), rtol=1e-9, atol=1e-15)
    # a ramp is tracked without lag in steady state (type 2)
    ramp = 1e-3 * np.arange(2000) * TS
    est = ct.forced_response(obs.to_control(TS, delay=0.0), U=ramp).outputs
    assert est[1, -1] == pytest.approx(1e-3, rel=1e-6) and est[0, -1] == pytest.approx(ramp[-1], rel=1e-6)
    assert isinstance(obs.to_scipy(TS), signal.dlti)
    with pytest.raises(ParameterError, match="Nyquist"):
        VelocityObserver(bandwidth=6000.0).to_control(TS)
