"""StageResponse is a Response (issue 18): Stage.simulate's signals are the core's output bit for
bit, the old attributes and positional construction stay, the response is read-only and pickles."""

import pickle

import numpy as np
import pytest

from piezohyst import _core, virtual_stage
from piezohyst.plant import StageResponse
from piezohyst.signals import Response

STAGE = virtual_stage()
TS = STAGE.sample_time
U = 75 - 75 * np.cos(2 * np.pi * 5 * np.arange(0, 0.2, TS))


def test_simulate_returns_a_response_equal_to_the_core_output():
    r = STAGE.simulate(U)
    st = STAGE.rest_state()
    x, va, vh = _core.stage_simulate(STAGE.core_params(), TS, STAGE.substeps, STAGE.tolerance, U.copy(), st)
    assert isinstance(r, Response) and isinstance(r, StageResponse)
    assert list(r.signals) == ["command", "voltage", "position", "cemf"]
    assert r.input_names == ("command",)
    assert r.units == {"command": "V", "voltage": "V", "position": "m", "cemf": "V"}
    assert np.array_equal(r.command, U) and np.array_equal(r.signals["command"], U)
    assert np.array_equal(r.position, x) and np.array_equal(r["position"], x)
    assert np.array_equal(r.voltage, va) and np.array_equal(r.cemf, vh)
    assert np.array_equal(r.final_state, st)
    assert np.array_equal(r.time, np.arange(U.size) * TS)
    assert r.title == STAGE.name


def test_inputs_outputs_shapes():
    r = STAGE.simulate(U)
    assert r.inputs.shape == (1, U.size)
    assert r.outputs.shape == (3, U.size)
    assert np.array_equal(r.outputs[1], r.position)


def test_positional_construction_still_works():
    t = np.arange(4) * 1e-3
    r = StageResponse(t, np.ones(4), 2 * np.ones(4), np.zeros(4), 3 * np.ones(4), np.zeros(12))
    assert np.array_equal(r.time, t)
    assert np.array_equal(r.command, np.ones(4)) and np.array_equal(r.voltage, 2 * np.ones(4))
    assert np.array_equal(r.cemf, 3 * np.ones(4))
    assert r.final_state.shape == (12,)


def test_continuing_from_the_final_state():
    whole = STAGE.simulate(U)
    k = U.size // 2
    first = STAGE.simulate(U[:k])
    second = STAGE.simulate(U[k:], initial_state=first.final_state)
    assert np.allclose(np.concatenate([first.position, second.position]), whole.position, rtol=0, atol=1e-15)


def test_read_only_and_pickle():
    r = STAGE.simulate(U)
    for name in ("position", "final_state", "title", "other"):
        with pytest.raises(AttributeError):
            setattr(r, name, 1)
    back = pickle.loads(pickle.dumps(r))
    assert type(back) is StageResponse
    for name, a in r.signals.items():
        assert np.array_equal(back.signals[name], a)
    assert np.array_equal(back.final_state, r.final_state)
    assert back.units == r.units and back.input_names == r.input_names
