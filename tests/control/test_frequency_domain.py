"""The frequency domain and the practitioner's loop (issue 19): measured frequency responses
agree with the stage's linear model, margins predict what the simulation does, a notch and a
PPF damping loop do what they are for, and the dynamic-inversion feedforward tracks within 1 %."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import PID, Amplifier, Compensated, InverseFeedforward, Sensor
from piezohyst.control import FilteredPID
from piezohyst.control.filters import PPF, LagLead, LowPass, Notch
from piezohyst.control.frequency import DynamicInversion, loop_margins, measure_frf
from piezohyst.errors import ParameterError, ParameterTypeError
from piezohyst.papers.experiments import identify_stage_mpi, steady_sine

BASE = ph.virtual_stage()
P = dataclasses.replace(
    BASE.params, hyst_alpha=0.0, hyst_beta=0.0, hyst_gamma=0.0, electrostriction=0.0, creep_taus=(), creep_weights=()
)
#: the virtual stage's mechanics and amplifier lag, linear, with a clean one-sample-delay sensor
LINEAR = BASE.with_(params=P, amplifier=Amplifier(bandwidth=3000.0, v_min=-1e4, v_max=1e4), sensor=Sensor(0.0, 0.0, 1))
FS = 1 / BASE.sample_time


def _discrete(sys, f):
    return np.array([complex(np.ravel(sys(z))[0]) for z in np.exp(2j * np.pi * np.asarray(f) / FS)])


def test_measured_open_loop_is_the_linear_model():
    """The multisine measurement of the Rust-simulated stage is its zero-order-hold model to
    1e-7; the swept and stepped sines agree with it within their estimators' error."""
    stage = LINEAR.with_modes([(1800.0, 0.02, 0.3)])
    model = stage.to_control(discrete=True)
    frf = measure_frf(stage, band=(10.0, 4000.0), output="position", periods=2)
    np.testing.assert_allclose(frf.response, _discrete(model, frf.frequency), rtol=1e-7)  # measured 2e-8
    stepped = measure_frf(stage, method="stepped", band=(10.0, 4000.0), points=12, output="position", periods=3)
    np.testing.assert_allclose(stepped.response, _discrete(model, stepped.frequency), rtol=2e-5)  # 4e-6 at 1.8 kHz
    swept = measure_frf(stage, method="swept", band=(10.0, 1000.0), points=10, output="position", periods=3)
    np.testing.assert_allclose(np.abs(swept.response), np.abs(_discrete(model, swept.frequency)), rtol=0.03)
    # the sensor's reading (noise, quantization; its one-sample delay divided out) on the
    # virtual stage gives the true position's response within 2 %
    noisy = measure_frf(BASE, band=(20.0, 1000.0), amplitude=30.0, periods=8, rng=2)
    true = measure_frf(BASE, band=(20.0, 1000.0), amplitude=30.0, periods=8, rng=2, output="position")
    assert np.max(np.abs(noisy.response / true.response - 1)) < 0.02


def test_gain_margin_predicts_the_simulated_stability_limit():
    """Scaling a PID by 0.9x its gain margin keeps the Rust-simulated loop stable, by 1.1x makes
    it ring up: the margin's discrete model is the loop the kernel runs."""
    pid = PID(kp=4e4, ki=1.4e10)
    m = loop_margins(LINEAR, pid)
    assert m.stable and 4 < m.gain_margin < 8 and 60 < m.phase_margin_deg < 80  # measured 5.58, 73 deg
    assert m.sensitivity_peak == pytest.approx(1 / m.modulus_margin)
    t = np.arange(0, 0.05, 1 / FS)
    kick = 5e-6 + 1e-6 * np.sin(2 * np.pi * m.phase_crossover_hz * t) * (t < 0.002)
    ends = {}
    for factor in (0.9, 1.1):
        c = PID(kp=4e4 * m.gain_margin * factor, ki=1.4e10 * m.gain_margin * factor, ff_gain=0.0)
        e = ph.closed_loop(LINEAR, c, kick).position - 5e-6
        ends[factor] = np.abs(e[-100:]).max()
    assert ends[0.9] < 1e-12 and ends[1.1] > 1e-4
    with pytest.raises(ParameterTypeError, match="SMC is not linear"):
        loop_margins(BASE, ph.SMC(BASE.params))


def test_measured_closed_loop_is_the_loops_model():
    """The complementary sensitivity measured on the linear stage is python-control's
    ``feedback`` of the plant and the PID's two-degree-of-freedom law."""
    pid = PID(kp=4e4, ki=1.4e10, ff_gain=1 / P.static_gain)
    t = measure_frf(LINEAR, pid, band=(10.0, 2000.0), output="position", periods=2, amplitude=1e-7, offset=5e-6)
    plant = _discrete(LINEAR.to_control(discrete=True, measured=True), t.frequency)
    position = _discrete(LINEAR.to_control(discrete=True), t.frequency)
    c = pid.to_control(BASE.sample_time, two_dof=True)
    # u = C_r r - C_y y, y = plant u, position = position-plant u
    c_r, c_y = _discrete(c[0, 0], t.frequency), -_discrete(c[0, 1], t.frequency)
    np.testing.assert_allclose(t.response, position * c_r / (1 + c_y * plant), rtol=1e-6)


def test_a_notch_restores_the_margins_a_second_mode_takes():
    stage = LINEAR.with_modes([(1800.0, 0.005, 0.3)])
    plain = loop_margins(stage, FilteredPID(kp=4e4, ki=1.4e10, error_delay=0))
    notched = loop_margins(stage, FilteredPID(kp=4e4, ki=1.4e10, error_delay=0, notches=(Notch(1800.0, width=0.3),)))
    # measured: Ms 4.5 at 1.76 kHz -> 1.46; gain margin 7.3 -> 11.3 dB
    assert plain.sensitivity_peak > 4 and 1700 < plain.sensitivity_peak_hz < 1900
    assert notched.sensitivity_peak < 1.6 and notched.gain_margin_db > plain.gain_margin_db + 3
    # without filters the FilteredPID's loop is the PID's
    pid = loop_margins(stage, PID(kp=4e4, ki=1.4e10))
    assert pid.gain_margin == pytest.approx(plain.gain_margin, rel=1e-9)


def test_ppf_damps_a_mode():
    """Positive position feedback tuned to a 400 Hz mode (damping ratio 0.005) cuts the
    closed loop's resonance peak from 9.8 to 1.9; with too much gain the loop is unstable
    (PPF's condition gain x static gain < 1)."""
    stage = LINEAR.with_modes([(400.0, 0.005, 0.3)])
    g = P.static_gain
    peaks = {}
    for gain in (0.0, 0.3):
        c = FilteredPID(damping=PPF(400.0, 0.3, gain / g) if gain else None, error_delay=0)
        frf = measure_frf(stage, c, band=(50.0, 2000.0), output="position", periods=2, amplitude=1e-7)
        peaks[gain] = frf.peak()[1]
    assert peaks[0.0] > 9 and peaks[0.3] < 2.0
    assert not loop_margins(stage, FilteredPID(damping=PPF(400.0, 0.3, 2.0 / g), error_delay=0)).stable


def test_dynamic_inversion_feedforward_tracks_within_one_percent():
    """Issue 19's acceptance: the hysteresis inverse of an MPI model identified from a simulated
    measurement, plus the inverse of the dynamics identified from a measured (stepped-sine,
    sensor reading) frequency response of the compensated stage, keeps max|y - r| / range
    within 1 % at 10, 50 and 100 Hz (8 um around 9 um, constant and variable amplitude;
    measured 0.53 / 0.54 / 0.46 %; the inverse alone: 0.63 / 2.4 / 4.1 %)."""
    model = identify_stage_mpi(BASE, np.random.default_rng(0)).model
    frf = measure_frf(
        BASE,
        InverseFeedforward(model),
        method="stepped",
        points=12,
        band=(2.0, 300.0),
        amplitude=8e-6,
        offset=9e-6,
        rng=1,
    )
    dyn = DynamicInversion.fit(frf)
    assert 0.95 < dyn.gain < 1.05 and 50e-6 < dyn.delay < 200e-6  # measured 1.000, 118 us
    ff = Compensated(FilteredPID(**dyn.feedforward()), model)
    worst = {}
    for f in (10, 50, 100):
        errors = []
        for variable in (False, True):
            ref, k0 = steady_sine(f, 8e-6, 9e-6, FS, variable)
            r = ph.track(ff, ref, stage=BASE, rng=1, skip=k0 / FS)
            errors.append(r.metrics["max_error"] / np.ptp(ref[k0:]))
        worst[f] = max(errors)
    assert all(e < 0.01 for e in worst.values()), worst
    # the inverse alone misses by more at 50 and 100 Hz (its gain and lag)
    ref, k0 = steady_sine(100, 8e-6, 9e-6, FS, False)
    alone = ph.track(InverseFeedforward(model), ref, stage=BASE, rng=1, skip=k0 / FS)
    assert alone.metrics["max_error"] / np.ptp(ref[k0:]) > 2 * worst[100]


def test_dynamic_inversion_fit_and_filters_bad_input():
    f = np.geomspace(2, 300, 3)
    from piezohyst.signals.frequency import FrequencyResponse

    with pytest.raises(ParameterError, match="frf has 3 frequencies; the fit needs at least 4"):
        DynamicInversion.fit(FrequencyResponse(f, np.ones(3)))
    with pytest.raises(ParameterTypeError, match="frf must be a FrequencyResponse"):
        DynamicInversion.fit([1.0, 2.0])  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="notch depth = 1.5 must be < 1"):
        Notch(1000.0, depth=1.5)
    with pytest.raises(ParameterError, match="warp_hz = 6000.0 Hz must be below the Nyquist"):
        ph.track(FilteredPID(notches=(Notch(6000.0),)), np.full(100, 5e-6), stage=BASE)
    with pytest.raises(ParameterError, match="notches has 4 filters, at most 3"):
        ph.track(FilteredPID(notches=(LowPass(1e3),) * 4), np.full(100, 5e-6), stage=BASE)
    with pytest.raises(ParameterTypeError, match=r"ff_filters\[0\] must be a filter"):
        ph.track(FilteredPID(ff_filters=("lag",)), np.full(100, 5e-6), stage=BASE)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="output = 'velocity' must be one of"):
        measure_frf(BASE, output="velocity")
    with pytest.raises(ParameterError, match="leaves the amplifier range"):
        measure_frf(BASE, amplitude=200.0)
    b0, b1, b2, a1, a2 = LagLead(10.0, 20.0).biquad(1e-4)
    assert b2 == a2 == 0.0 and abs(a1) < 1  # first order: one pole inside, none at z = -1
    assert (b0 + b1) / (1 + a1) == pytest.approx(1.0)  # unit static gain


def test_filtered_pid_without_filters_runs_the_pid():
    """The Rust kind ``filtered_pid`` with no filter and no error delay is ``pid``, to the bit,
    in a closed loop that saturates."""
    fs = FS
    _, ref = ph.triangle(20, 9e-6, 0.2, fs, offset=11e-6)
    pid = PID(kp=3e4, ki=5e10, kd=1.0, tau_d=2e-4, u_min=0.0, u_max=120.0)
    f = FilteredPID(kp=3e4, ki=5e10, kd=1.0, tau_d=2e-4, error_delay=0, u_min=0.0, u_max=120.0)
    a, b = ph.closed_loop(BASE, pid, ref, rng=3), ph.closed_loop(BASE, f, ref, rng=3)
    assert np.any(a.command >= 120.0)  # it saturates
    np.testing.assert_array_equal(a.command, b.command)
    np.testing.assert_array_equal(a.position, b.position)
