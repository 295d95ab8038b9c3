"""A stage with structural freedom (issue 19): added modes, a voltage-driven hysteresis law, a
DAC, the amplifier's current limit, a user-written controller in the loop."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.signal

import piezohyst as ph
from piezohyst import PI, Amplifier, OpenLoop, Sensor, Stage, StageParameters, closed_loop, virtual_stage
from piezohyst.errors import ParameterError, ParameterTypeError
from piezohyst.papers.experiments import identify_stage_mpi

BASE = virtual_stage()
G = BASE.params.static_gain


def _linear_stage(**amp: float) -> Stage:
    """The virtual stage's mechanics and amplifier lag, without hysteresis, creep,
    electrostriction or slew limit: a linear system."""
    p = dataclasses.replace(
        BASE.params,
        hyst_alpha=0.0,
        hyst_beta=0.0,
        hyst_gamma=0.0,
        electrostriction=0.0,
        creep_taus=(),
        creep_weights=(),
    )
    return BASE.with_(params=p, amplifier=Amplifier(bandwidth=3000.0, **amp), sensor=Sensor())


def test_added_modes_are_the_linear_systems_modes():
    """A linear stage with two added modes (one in anti-phase) simulated by the Rust kernel
    gives the zero-order-hold discretization of the state space `to_control` builds, to
    rounding: the modes are integrated exactly, and the two descriptions agree."""
    stage = _linear_stage().with_modes([(1800.0, 0.02, 0.3), (7000.0, 0.05, -0.2)])
    rng = np.random.default_rng(4)
    u = 75 + 35 * rng.standard_normal(3000).clip(-2, 2)
    x = stage.simulate(u).position
    sys = stage.to_scipy(discrete=True)
    _, y, _ = scipy.signal.dlsim(sys, u)
    # dlsim's y[k] is the output at k before u[k] acts: the stage's position[k]
    err = np.max(np.abs(x - y.ravel())) / np.ptp(x)
    assert err < 1e-9, err
    # and the analytic frequency response has both: the resonance and the anti-resonance's dip
    f = np.array([1.0, 1800.0, 7000.0])
    h = np.abs(stage.frequency_response(f))
    assert h[1] > 4 * h[0]
    assert np.isclose(h[0], G, rtol=1e-6)  # the static gain is the stage's


def test_modes_change_the_closed_loop_and_continue_from_the_final_state():
    """The modal sum is what the sensor reads; a run continued from its final state (stage
    and modes) is the same run, to the bit."""
    stage = BASE.with_modes([(1800.0, 0.02, 0.3)])
    assert stage.structured and stage.rest_state().shape == (14,)
    fs = 1 / stage.sample_time
    _, ref = ph.sine(20, 4e-6, 0.2, fs, offset=8e-6)
    pid = ph.PID(kp=4e4, ki=1.4e10)
    whole = closed_loop(stage, pid, ref, rng=1)
    plain = closed_loop(BASE, pid, ref, rng=1)
    assert not np.allclose(whole.position, plain.position, rtol=0, atol=1e-10)
    # an open loop (no controller state) continued from the final state
    ol = OpenLoop(gain=1 / G)
    a = closed_loop(stage, ol, ref, rng=1)
    first = closed_loop(stage, ol, ref[:1000], rng=1)
    second = closed_loop(stage, ol, ref[1000:], rng=1, initial_state=first.final_state)
    assert first.final_state.shape == (14,)
    np.testing.assert_array_equal(np.r_[first.position, second.position], a.position)


def test_a_voltage_driven_law_drives_the_stage():
    """Any hysteresis model (a PI here, then an identified MPI) driving the stage in place of
    the CEMF: the slow position follows the law's loop; the stroke is the law's."""
    p = dataclasses.replace(BASE.params, electrostriction=0.0, creep_taus=(), creep_weights=())
    law = PI([20.0, 60.0], [0.3 * G, 0.2 * G], p0=0.6 * G)
    stage = BASE.with_(params=p).with_hysteresis(law)
    u = 75 - 75 * np.cos(2 * np.pi * 2 * np.arange(0, 1.0, stage.sample_time))
    x = stage.simulate(u).position
    h = law.simulate(u)
    err = np.abs(x[1:] - h[:-1]).max() / np.ptp(x)
    assert err < 0.01, err
    # the CEMF law's loop is another: the plain stage differs by far more
    x_cemf = BASE.with_(params=p).simulate(u).position
    assert np.abs(x_cemf[1:] - h[:-1]).max() / np.ptp(x) > 0.05
    _, hi = stage.stroke()
    assert np.isclose(hi, law.simulate([0.0, 150.0])[-1], rtol=1e-9)
    # an identified model works the same (GPI with creep); the closed loop runs on it
    fit = identify_stage_mpi(BASE, np.random.default_rng(0))
    driven = BASE.with_hysteresis(fit.model)
    assert driven.rest_state().size == 12 + fit.model.initial_state().size
    fs = 1 / driven.sample_time
    _, ref = ph.triangle(5, 5e-6, 0.4, fs, offset=7e-6)
    r = ph.track(ph.PID(kp=4e4, ki=1.4e10), ref, stage=driven, rng=3, skip=0.2)
    assert r.metrics["rmse"] < 0.05e-6


def test_dac_and_current_limit():
    """A DAC of 1 V codes from -20 V: 10.3 V held reaches the position of 10 V; a current
    limit of 0.09 A on 1.8 uF is a 50 V/ms slew limit."""
    stage = _linear_stage(dac_step=1.0)
    x = stage.simulate(np.full(3000, 10.3)).position
    x10 = _linear_stage().simulate(np.full(3000, 10.0)).position
    np.testing.assert_allclose(x[-1], x10[-1], rtol=1e-12)
    assert not np.isclose(_linear_stage().simulate(np.full(3000, 10.3)).position[-1], x10[-1], rtol=1e-6)
    limited = _linear_stage(current_limit=0.09)
    assert limited.effective_slew_rate() == pytest.approx(5e4)
    va = limited.simulate(np.r_[0.0, np.full(40, 100.0)]).voltage
    assert np.max(np.diff(va)) <= 5e4 * limited.sample_time * (1 + 1e-12)
    assert Amplifier.dac(16, -20, 150) == pytest.approx(170 / 65535)


def test_structure_round_trips_through_a_stage_file(tmp_path):
    law = PI([20.0, 60.0], [0.3 * G, 0.2 * G], p0=0.6 * G)
    stage = BASE.with_modes([(1800.0, 0.02, 0.3)]).with_hysteresis(law)
    stage = stage.with_(amplifier=dataclasses.replace(stage.amplifier, dac_step=0.01, current_limit=0.5))
    back = Stage.from_dict(stage.to_dict())
    assert back.modes == stage.modes and back.amplifier == stage.amplifier
    assert back.hysteresis is not None and np.array_equal(back.hysteresis.to_row(), law.to_row())
    u = np.linspace(0, 120, 500)
    np.testing.assert_array_equal(back.simulate(u).position, stage.simulate(u).position)


def test_structure_bad_input():
    with pytest.raises(ParameterError, match=r"modes\[0\] frequency"):
        BASE.with_modes([(-5.0, 0.1, 0.2)])
    with pytest.raises(ParameterError, match=r"modes\[0\] = \(1\.0, 2\.0\)"):
        BASE.with_modes([(1.0, 2.0)])
    with pytest.raises(ParameterError, match="at most 4"):
        BASE.with_modes([(1e3 * (i + 1), 0.1, 0.1) for i in range(5)])
    with pytest.raises(ParameterError, match="1 \\+ sum of the relative gains"):
        BASE.with_modes([(1e3, 0.1, -1.0)])
    with pytest.raises(ParameterTypeError, match="hysteresis must be a hysteresis model"):
        BASE.with_hysteresis("pi")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="dac_step"):
        Amplifier(dac_step=-1.0)
    stage = BASE.with_modes([(1800.0, 0.02, 0.3)])
    with pytest.raises(ParameterError, match="state has 13 values; this stage's state has 14"):
        stage.simulate(np.zeros(10), initial_state=np.zeros(13))
    with pytest.raises(ParameterError, match=r"initial_state\[12\] = nan"):
        stage.simulate(np.zeros(10), initial_state=np.r_[np.zeros(12), np.nan, 0.0])


class _Feedforward:
    """A user controller: the static inverse, as OpenLoop computes it."""

    def __init__(self, gain: float) -> None:
        self.gain = gain
        self.calls = 0
        self.first = None

    def reset(self, y0: float) -> None:
        self.first = y0

    def step(self, reference: float, measured: float) -> float:
        self.calls += 1
        return self.gain * reference


def test_a_user_controller_runs_in_the_loop():
    """A Python class with `step` runs from the Rust loop: the same run as the packaged
    controller computing the same law, to the bit, on a stage with structure too."""
    fs = 1 / BASE.sample_time
    _, ref = ph.sine(10, 4e-6, 0.05, fs, offset=8e-6)
    for stage in (BASE, BASE.with_modes([(1800.0, 0.02, 0.3)])):
        user = _Feedforward(1 / G)
        mine = closed_loop(stage, user, ref, rng=2)
        theirs = closed_loop(stage, OpenLoop(gain=1 / G), ref, rng=2)
        assert user.calls == ref.size and user.first == 0.0
        np.testing.assert_array_equal(mine.position, theirs.position)
        np.testing.assert_array_equal(mine.measured, theirs.measured)
        assert mine.controller == "_Feedforward"


def test_a_user_controller_that_fails_says_where():
    class Bad:
        def step(self, reference: float, measured: float) -> float:
            return float("nan") if reference > 9e-6 else 0.0

    class Raises:
        def step(self, reference: float, measured: float) -> float:
            raise ZeroDivisionError("boom")

    ref = np.linspace(8e-6, 10e-6, 100)
    with pytest.raises(ParameterError, match=r"returned NaN at sample 50"):
        closed_loop(BASE, Bad(), ref)
    with pytest.raises(RuntimeError, match="step raised at sample 0") as e:
        closed_loop(BASE, Raises(), ref)
    assert isinstance(e.value.__cause__, ZeroDivisionError)


def test_stage_parameters_unchanged_by_structure():
    """Structure leaves the parameter row alone: the plain stage's core parameters are the
    same with or without modes (the kernel gets the modes separately)."""
    stage = BASE.with_modes([(1800.0, 0.02, 0.3)])
    np.testing.assert_array_equal(stage.core_params(), BASE.core_params())
    assert isinstance(stage.params, StageParameters)
