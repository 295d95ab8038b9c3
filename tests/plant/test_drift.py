"""Thermal drift of the stage (issue 19): a slow additive displacement and a slow change of
the stroke with a time constant, in the Rust kernel's structure hooks."""

from __future__ import annotations

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.errors import ParameterError, ParameterTypeError
from piezohyst.plant import Drift, Stage

STAGE = ph.virtual_stage()
FS = 1 / STAGE.sample_time


def test_drift_moves_the_position_as_its_law_says():
    u = np.full(4000, 60.0)
    plain = STAGE.simulate(u).position
    drifting = STAGE.with_drift(offset=0.3e-6, gain=0.02, time_constant=0.1).simulate(u).position
    t = np.arange(u.size) * STAGE.sample_time
    # sample k is the position after k periods: the clock reads k Ts
    s = 1 - np.exp(-t / 0.1)
    assert np.allclose(drifting, (1 + 0.02 * s) * plain + 0.3e-6 * s, rtol=0, atol=1e-15)
    assert drifting[-1] - plain[-1] == pytest.approx(s[-1] * (0.3e-6 + 0.02 * plain[-1]), rel=1e-9)


def test_feedback_removes_the_drift_a_feedforward_cannot():
    """A 5 Hz sine (5 µm around 8 µm) for 1.5 s on a stage that drifts 0.5 µm and 2 % of its
    stroke with a 0.3 s time constant: the static feedforward's error grows by the drift
    (measured max error 2.09 µm over the last 0.5 s against 1.50 µm without drift), a PID's stays
    within a few nm of its figure without drift (46.5 nm against 44.2 nm)."""
    drifting = STAGE.with_drift(offset=0.5e-6, gain=0.02, time_constant=0.3)
    _, ref = ph.sine(5, 5e-6, 1.5, FS, offset=8e-6)
    ff = ph.OpenLoop(gain=1 / STAGE.params.static_gain)
    pid = ph.PID(kp=4e4, ki=1.4e10)
    err = {}
    for name, c in (("ff", ff), ("pid", pid)):
        for label, s in (("plain", STAGE), ("drift", drifting)):
            err[name, label] = ph.track(c, ref, stage=s, rng=1, skip=1.0).metrics["max_error"]
    assert err["ff", "drift"] > err["ff", "plain"] + 0.35e-6
    assert err["pid", "drift"] < err["pid", "plain"] + 5e-9
    assert err["pid", "drift"] < 0.1e-6


def test_drift_round_trips_and_is_checked():
    s = STAGE.with_drift(offset=-40e-9, gain=0.005, time_constant=30.0)
    assert s.structured and s.rest_state().size == STAGE.rest_state().size + 1
    back = Stage.from_dict(s.to_dict())
    assert back.drift == Drift(-40e-9, 0.005, 30.0)
    assert "drift" not in STAGE.to_dict()
    with pytest.raises(ParameterError, match="drift time_constant = 0.0 must be > 0"):
        STAGE.with_drift(time_constant=0.0)
    with pytest.raises(ParameterError, match="drift gain = -1.0 must be > -1"):
        STAGE.with_drift(gain=-1.0)
    with pytest.raises(ParameterTypeError, match="drift must be a Drift"):
        STAGE.with_(drift=(1.0, 0.0, 1.0))
