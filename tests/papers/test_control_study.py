"""Issue 19's acceptance, held by its key numbers (piezohyst.papers.control_study; every model
identified from simulated measurements, every controller tuned for itself by the same call).
The full run is ``bench/control_acceptance.py`` (its numbers are in the README); these use a
smaller tuning budget for the robustness and the full one for the 80 Hz comparison."""

from __future__ import annotations

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.papers.control_study import ROBUSTNESS_LIMIT, compensation_study, robustness_study


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
    (measured 0.44-0.60 %); at 80 Hz the compensated loop reaches seed 2's normalized max error
    (<= 0.0054; measured 0.0037 constant, 0.0040 variable, medians over five noise seeds) and
    beats a PID + static feedforward tuned by the same call by >= 6x (measured 7.8x / 8.1x at
    this seed; 5.4x / 5.6x at seed 1, 9.4x / 8.2x at seed 2: bench/control_acceptance.py)."""
    out = compensation_study(stage, np.random.default_rng(0))
    assert all(v <= 1.0 for v in out["feedforward_max_error_percent"].values()), out["feedforward_max_error_percent"]
    assert out["inverse_alone_max_error_percent"]["100 Hz constant"] > 2.0  # the inverse alone: 4.1 %
    for amp, row in out["table4_80hz"].items():
        assert row["compensated"]["normalized_max_error"] <= 0.0054, (amp, row)
        assert row["ratio"] >= 6, (amp, row)
