"""Issue 19's acceptance, held by its key numbers (piezohyst.papers.control_study; every model
identified from simulated measurements, every controller tuned for itself by the same call).
The full run is ``bench/control_acceptance.py`` (its numbers are in the README); these use a
smaller tuning budget for the robustness and the full one for the 80 Hz comparison."""

from __future__ import annotations

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.control.controllers import Compensated, FilteredPID, InverseFeedforward
from piezohyst.control.frequency import DynamicInversion, measure_frf
from piezohyst.control.tuning import track
from piezohyst.errors import ParameterError
from piezohyst.papers.control_study import (
    ROBUSTNESS_LIMIT,
    compensation_study,
    identify_operating_mpi,
    operating_excitation,
    robustness_study,
)
from piezohyst.papers.experiments import identify_stage_mpi, steady_sine
from piezohyst.plant.stage import Sensor


@pytest.fixture(scope="module")
def stage():
    return ph.virtual_stage()


def test_each_controller_holds_on_stages_it_was_not_identified_on(stage):
    """SMC, SMC + CEMF and PID + FF, each tuned for the worst of the identified model's ±20 %
    variants, stay within 3x of their nominal RMSE on ±20 % stiffness, Tem and hysteresis of the
    true stage and on the structurally different stages (measured here: worst 1.2x / 1.35x /
    1.65x; the full run over every parameter: 1.19x / 1.42x / 1.81x). Tuned for the model alone,
    the SMCs lose the loop (full run: 40x and 49x)."""
    out = robustness_study(
        stage,
        np.random.default_rng(0),
        tuning_iterations=8,
        population_size=10,
        identification_iterations=40,
        parameters=["stiffness", "tem", "hyst_alpha"],
    )
    assert set(out["ratio"]) >= {"second mode", "voltage-driven hysteresis", "sensor delay 2", "tem x0.8"}
    for name, worst in out["worst_ratio"].items():
        assert worst <= ROBUSTNESS_LIMIT, (name, out["ratio"])
    assert all(out["holds"].values())
    # the nominal figures (µm): SMC + CEMF and the PID at 0.012-0.016, the SMC at 0.019-0.021
    for name, rmse in out["nominal_rmse_um"].items():
        assert 0.008 < rmse < 0.03, (name, rmse)


def test_dynamic_inversion_and_80_hz_compensation(stage):
    """The dynamic-inversion feedforward keeps max|y - r| / range <= 1 % at 10/50/100 Hz
    (measured 0.43-0.75 %); at 80 Hz the compensated loop (its MPI identified over the task's
    range) reaches seed 2's normalized max error (<= 0.0054; measured 0.0029 constant, 0.0029
    variable, medians over five noise seeds) and beats a PID + static feedforward tuned by the
    same call by >= 6x (measured 8.9x / 8.5x; every seed and both tuning objectives:
    bench/control_acceptance.py)."""
    out = compensation_study(stage, np.random.default_rng(0))
    assert all(v <= 1.0 for v in out["feedforward_max_error_percent"].values()), out["feedforward_max_error_percent"]
    assert out["inverse_alone_max_error_percent"]["100 Hz constant"] > 2.0  # the inverse alone: 4.1 %
    for amp, row in out["table4_80hz"].items():
        assert row["compensated"]["normalized_max_error"] <= 0.0054, (amp, row)
        assert row["ratio"] >= 6, (amp, row)
    assert out["settings"]["identification"] == "operating"
    held = out["settings"]["mpi_operating"]["heldout"]
    assert held["operating"]["rmse_percent"] < held["full_range"]["rmse_percent"], held


def _harmonics_nm(stage, law, freq=80.0):
    """The dynamic-inversion feedforward's error at 2x and 3x ``freq`` (nm) on an 8 µm sine
    around 9 µm, on ``stage`` without sensor noise and quantization."""
    fs = 1 / stage.sample_time
    how = dict(method="stepped", points=12, band=(2.0, 300.0), amplitude=8e-6, offset=9e-6, rng=5)
    frf = measure_frf(stage, InverseFeedforward(law), **how)
    ff = Compensated(FilteredPID(**DynamicInversion.fit(frf).feedforward()), law)
    ref, k0 = steady_sine(freq, 8e-6, 9e-6, fs)
    clean = stage.with_(sensor=Sensor(0.0, 0.0, stage.sensor.delay))
    res = track(ff, ref, stage=clean, rng=1)
    e = (res.position - res.reference)[k0:]
    spec = np.abs(np.fft.rfft(e)) * 2 / e.size
    f = np.fft.rfftfreq(e.size, 1 / fs)
    return [float(spec[np.argmin(np.abs(f - h * freq))]) * 1e9 for h in (2, 3)]


def test_operating_range_identification_cuts_the_inverse_shape_error(stage):
    """The MPI fitted over the voltages the loop runs at (the full-range model's inverse of
    1..17 µm) holds the stage's hysteresis better there: the feedforward's 160 / 240 Hz error
    at 80 Hz falls from 19-20 / 18 nm (full-range record) to 8-9 / 12.5 nm (seeds 0-4), and a
    held-out record of that range (20 Hz, decaying amplitude, fresh noise) is predicted with a
    lower RMSE (measured 0.44 % against 0.59 %)."""
    rng = np.random.default_rng(0)
    first = identify_stage_mpi(stage, rng).model
    fit, info = identify_operating_mpi(stage, rng, first=first)
    v_low, v_high = info["voltages"]
    assert -7.0 < v_low < -3.0 and 119.0 < v_high < 124.0, info["voltages"]  # measured -5.3, 121.6 V
    held = info["heldout"]
    assert held["operating"]["rmse_percent"] < 0.85 * held["full_range"]["rmse_percent"], held
    full, operating = _harmonics_nm(stage, first), _harmonics_nm(stage, fit.model)
    assert full[0] > 15 and full[1] > 15, full
    assert operating[0] < 0.6 * full[0] and operating[1] < 0.8 * full[1], (full, operating)


def test_operating_excitation_spans_the_voltages_and_rejects_bad_input():
    u = operating_excitation(10_000.0, 5.0, 120.0)
    assert u.size == 500 + 40_000 and u[0] == 0.0
    assert u[500:].min() == pytest.approx(5.0) and u.max() == pytest.approx(120.0)
    tail = u[-2000:]  # the last cycle: the envelope from 28 % down to 20 % of the 115 V span
    assert 0.2 * 115 < np.ptp(tail) < 0.28 * 115 and abs(0.5 * (tail.max() + tail.min()) - 62.5) < 0.05 * 115
    with pytest.raises(ParameterError, match="v_low, v_high"):
        operating_excitation(10_000.0, 120.0, 5.0)
    with pytest.raises(ParameterError, match="final"):
        operating_excitation(10_000.0, 5.0, 120.0, final=1.5)
    with pytest.raises(ParameterError, match="hold"):
        operating_excitation(10_000.0, 5.0, 120.0, seconds=1.0, hold=2.0)
    with pytest.raises(ParameterError, match="identification"):
        compensation_study(ph.virtual_stage(), np.random.default_rng(0), identification="operatng")


def test_80_hz_ratio_holds_when_both_loops_are_tuned_for_the_maximum_error(stage):
    """Issue 19's stricter protocol: both loops tuned for the maximum error itself (each tuning
    candidate run with five noise realizations, as bench/control_acceptance.py does). Seed 1:
    the compensated loop 0.0028 / 0.0026 against the PID + FF's 0.0209 / 0.0241, 7.4x / 9.3x
    (5.3-6.0x over seeds 0-4 before the operating-range identification)."""
    out = compensation_study(stage, np.random.default_rng(1), objective="max_error", tuning_noise_seeds=5)
    for amp, row in out["table4_80hz"].items():
        assert row["compensated"]["normalized_max_error"] <= 0.0035, (amp, row)
        assert 0.018 < row["PID+FF"]["normalized_max_error"] < 0.03, (amp, row)
        assert row["ratio"] >= 6, (amp, row)
