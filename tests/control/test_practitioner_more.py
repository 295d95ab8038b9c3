"""The practitioner's set, the rest of it (issue 19): H-infinity mixed sensitivity (python-control
``mixsyn`` through slycot), integral resonant control beside PPF, the ILC as the plug-in
repetitive controller of a periodic reference; each run on a stage it was not designed on."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.control.filters import IRC, Section
from piezohyst.control.frequency import loop_margins, measure_frf
from piezohyst.control.simulation import closed_loop_batch
from piezohyst.errors import ParameterError, ParameterTypeError

STAGE = ph.virtual_stage()
P = STAGE.params
G = P.static_gain
FS = 1 / STAGE.sample_time
SECOND_MODE = STAGE.with_modes([(1800.0, 0.02, 0.3)])


def test_irc_damps_a_mode_it_was_not_tuned_to():
    """An IRC with its pole at 1.2 kHz on a stage with an added 1.8 kHz mode: the measured
    (stepped-sine, simulated) response reference -> position of the feedforward loop peaks at
    1.67 kHz at 2.1x its low-frequency gain without it (1.5 / 0.71), and has no peak with it
    (the largest gain is at the lowest frequency, 0.67 / 0.52)."""
    peaks = {}
    for name, damp in (("none", None), ("irc", IRC(1200.0, G, 2.0))):
        fac = 1.0 if damp is None else damp.static_factor()
        c = ph.FilteredPID(ff_gain=1 / (G * fac), damping=damp, error_delay=0)
        fr = measure_frf(
            SECOND_MODE,
            c,
            method="stepped",
            band=(100.0, 2500.0),
            points=25,
            amplitude=0.5e-6,
            offset=9e-6,
            output="position",
            rng=1,
        )
        m = np.abs(fr.response)
        peaks[name] = (float(m.max() / m[0]), float(fr.frequency[np.argmax(m)]))
    assert peaks["none"][0] > 1.8 and 1500 < peaks["none"][1] < 2000
    assert peaks["irc"][0] < 1.35 and peaks["irc"][1] < 500


def test_irc_filter_and_its_errors():
    irc = IRC(1000.0, static_gain=2e-7)
    assert irc.static_factor() == 2.0
    assert abs(irc.frequency_response([0.0])[0]) == pytest.approx(1 / (2 * 2e-7))
    with pytest.raises(ParameterError, match=r"IRC feedthrough = 0\.5 must be > 1"):
        IRC(1000.0, static_gain=1.0, feedthrough=0.5)
    with pytest.raises(ParameterTypeError, match="damping must be a PPF or an IRC"):
        ph.track(ph.FilteredPID(damping=Section((1.0,), (1.0,), warp=10.0)), np.full(10, 5e-6), stage=STAGE)  # type: ignore[arg-type]


def test_matched_section_puts_a_fast_pole_at_the_origin():
    fast = Section((1.0, 10.0), (1.0, 1e9), warp=100.0, discretization="matched").biquad(1e-4)
    assert abs(fast[3]) < 1e-9
    bil = Section((1.0, 10.0), (1.0, 1e9), warp=100.0).biquad(1e-4)
    assert bil[3] == pytest.approx(1.0, abs=1e-4)  # the bilinear transform's z = -1
    slow = Section((1.0,), (1.0, 100.0), warp=10.0, discretization="matched")
    f = np.array([1.0, 10.0, 100.0])
    assert np.allclose(np.abs(slow.frequency_response(f, 1e-4)), np.abs(slow.frequency_response(f)), rtol=2e-3)
    with pytest.raises(ParameterError, match="improper"):
        Section((1.0, 0.0, 0.0), (1.0, 1.0), warp=10.0)
    with pytest.raises(ParameterError, match="discretization = 'zoh'"):
        Section((1.0,), (1.0, 1.0), warp=10.0, discretization="zoh")


def test_mixed_sensitivity_holds_off_its_design_model():
    """Designed (bandwidth 200 Hz, |S| < 2) on a model 10 % stiffer with a 5 % smaller Tem,
    run on the stage, on a stage with a 1.8 kHz mode and on ±20 % stiffness / Tem. Measured:
    gamma 0.84; on the stage phase margin 76°, modulus margin 0.77, |S| peak 1.3, crossover
    350 Hz, RMSE 55 nm on a 20 Hz sine of 5 µm; the other stages 55-58 nm, every loop stable
    (the second mode leaves a modulus margin of 0.16)."""
    pytest.importorskip("slycot")
    from piezohyst.control.design import mixed_sensitivity

    model = dataclasses.replace(P, stiffness=P.stiffness * 1.1, tem=P.tem * 0.95)
    d = mixed_sensitivity(STAGE.with_(params=model), bandwidth=200.0)
    assert d.gamma < 1.0
    m = loop_margins(STAGE, d.controller)
    assert m.stable and m.sensitivity_peak < 1.5 and m.modulus_margin > 0.7 and 250 < m.gain_crossover_hz < 450
    _, ref = ph.sine(20, 5e-6, 0.4, FS, offset=8e-6)
    nominal = ph.track(d.controller, ref, stage=STAGE, rng=1, skip=0.2).metrics["rmse"]
    assert nominal < 70e-9
    others = [
        SECOND_MODE,
        STAGE.with_(params=dataclasses.replace(P, stiffness=P.stiffness * 0.8)),
        STAGE.with_(params=dataclasses.replace(P, tem=P.tem * 1.2)),
    ]
    for s in others:
        assert loop_margins(s, d.controller).stable
        assert ph.track(d.controller, ref, stage=s, rng=1, skip=0.2).metrics["rmse"] < 1.1 * nominal
    # the realized loop is mixsyn's controller with its slowest pole moved to the origin
    f = np.array([20.0, 200.0, 1000.0])
    s = 2j * np.pi * f
    assert np.allclose(np.abs(d.realized(s)), np.abs(d.full(s)), rtol=0.02)


def test_mixed_sensitivity_rejects_bad_weights():
    pytest.importorskip("slycot")
    from piezohyst.control.design import mixed_sensitivity

    with pytest.raises(ParameterError, match="bandwidth = 4000.0 Hz must be below a quarter"):
        mixed_sensitivity(STAGE, bandwidth=4000.0)
    with pytest.raises(ParameterError, match="peak = 0.5"):
        mixed_sensitivity(STAGE, bandwidth=100.0, peak=0.5)


def test_repetitive_control_is_a_drop_in_controller():
    """The ILC as the plug-in repetitive controller of a PID (learning gain 0.3 / g, q = 0.99,
    lead 3) on a 50 Hz sine, on the stage and on a stage 20 % softer that it was not set up
    on: the PID alone 93.9 / 84 nm RMSE over the last 0.4 s of 2 s, with the repetitive plug-in
    21.5 / 20 nm (measured). It runs through closed_loop_batch (the same numbers as one run
    at a time) and tune."""
    softer = STAGE.with_(params=dataclasses.replace(P, stiffness=P.stiffness * 0.8))
    _, ref = ph.sine(50, 5e-6, 2.0, FS, offset=8e-6)
    pid = ph.PID(kp=4e4, ki=1.4e10)
    rc = ph.ILC.repetitive(pid, 50.0, STAGE.sample_time, gain=0.3 / G, forgetting=0.99, lead=3)
    assert rc.period == 200
    for s in (STAGE, softer):
        alone = ph.track(pid, ref, stage=s, rng=1, skip=1.6).metrics["rmse"]
        learned = ph.track(rc, ref, stage=s, rng=1, skip=1.6).metrics["rmse"]
        assert learned < alone / 3.5, (s.params.stiffness, alone, learned)
    seed = int(np.random.default_rng(5).integers(0, 2**63 - 1))  # the batch's first scenario's seed
    one = ph.closed_loop(STAGE, rc, ref[:4000], rng=seed)
    batch = closed_loop_batch(STAGE, [(rc, ref[:4000]), (pid, ref[:4000])], rng=5)
    assert np.array_equal(batch[0].position, one.position)
    assert batch[0].metrics["rmse"] < batch[1].metrics["rmse"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ph.tune(
            rc,
            {"gain": (0.05 / G, 0.5 / G)},
            ref[:6000],
            stage=STAGE,
            rng=1,
            max_iterations=3,
            population_size=6,
            skip=0.4,
        )
    assert isinstance(res.controller, ph.ILC) and res.controller.tuned_sample_time == STAGE.sample_time
    with pytest.raises(ParameterError, match="period of 133.333 samples"):
        ph.ILC.repetitive(pid, 75.0, STAGE.sample_time)
