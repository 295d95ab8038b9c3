"""Every controller configuration gives the core the same shape (``CoreSpec``, the tuple form
of ``_core``'s controller spec) and is what the closed loop runs (``ControllerLike``: a
dataclass with ``core(stage)``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core
from piezohyst.control.controllers import with_gains
from piezohyst.export_c import controller_from_dict, controller_to_dict


@pytest.fixture(scope="module")
def stage():
    return ph.virtual_stage()


@pytest.fixture(scope="module")
def model():
    return ph.PI([0.0, 2.0, 5.0, 10.0], [1.5e-7, 5e-8, 3e-8, 2e-8])


def configurations(stage, model):
    p = stage.params
    return {
        "open_loop": ph.OpenLoop(),
        "pid": ph.PID(kp=2e6, ki=2e9, kd=10.0),
        "smc": ph.SMC(p),
        "smc_st": ph.SMC(p, cemf=True, switching="super_twisting", k1=10.0, k2=1000.0),
        "absmc": ph.ABSMC.for_stage(p),
        "cemf_feedforward": ph.CemfFeedforward(p),
        "compensated": ph.Compensated(ph.PID(kp=0.3, ki=1500.0), model),
        "inverse_ff": ph.InverseFeedforward(model, c1=1e-4),
        "ilc": ph.ILC(ph.Compensated(ph.PID(kp=0.3, ki=1500.0), model), period=400, gain=0.3),
        "ilc_volts": ph.ILC(ph.PID(kp=1e6), period=100),
    }


def check_spec(spec):
    kind, params, inverse, ilc = spec
    layout = _core.controller_layout(kind)
    assert isinstance(params, np.ndarray) and params.dtype == np.float64 and params.shape == (layout["param_len"],)
    if inverse is not None:
        family, dims, row, lo, hi = inverse
        assert isinstance(family, str) and isinstance(dims, list) and all(type(d) is int for d in dims)
        assert isinstance(row, np.ndarray) and row.dtype == np.float64
        assert row.shape == (_core.family_layout(family, dims)["param_len"],)
        assert type(lo) is float and type(hi) is float and lo < hi
    if ilc is not None:
        assert [type(x) for x in ilc] == [int, float, float, int, int]
    _core.controller_initial_state(spec, 0.0)  # the core takes it


@pytest.mark.parametrize(
    "name",
    [
        "open_loop",
        "pid",
        "smc",
        "smc_st",
        "absmc",
        "cemf_feedforward",
        "compensated",
        "inverse_ff",
        "ilc",
        "ilc_volts",
    ],
)
def test_every_controller_gives_the_core_spec(stage, model, name):
    c = configurations(stage, model)[name]
    assert dataclasses.is_dataclass(c) and not isinstance(c, type)
    assert isinstance(c.uses_reference_derivatives, bool)
    spec = c.core(stage)
    check_spec(spec)
    # an exported controller gives the same spec
    exported = controller_from_dict(controller_to_dict(c, stage))
    assert dataclasses.is_dataclass(exported)
    again = exported.core(stage)
    check_spec(again)
    assert again[0] == spec[0] and np.array_equal(again[1], spec[1]) and again[3] == spec[3]
    # and the closed loop runs it
    r = ph.closed_loop(stage, c, np.full(50, 1e-6))
    assert r.command.shape == (50,)


def test_with_gains_keeps_the_type(stage):
    pid = ph.PID(kp=1e6)
    faster = with_gains(pid, kp=2e6)
    assert type(faster) is ph.PID and faster.kp == 2e6 and pid.kp == 1e6


def test_absmc_theta_count_is_the_table(stage):
    n = sum(1 for s in _core.controller_layout("absmc")["slots"] if s.startswith("theta0_"))
    c = ph.ABSMC.for_stage(stage.params)
    assert len(c.theta) == n
    with pytest.raises(ph.errors.ParameterError, match=f"theta must have {n} values"):
        dataclasses.replace(c, theta=(*c.theta, 1.0)).core(stage)
    with pytest.raises(ph.errors.ParameterError, match=f"must have {n} values"):
        dataclasses.replace(c, gamma_theta=(1.0,) * (n + 1)).core(stage)
