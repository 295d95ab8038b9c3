"""Model simulation as a signals.Response: HysteresisModel.response, Inverse.response,
BoucWenBenchmark.response."""

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.errors import ParameterError, ParameterTypeError
from piezohyst.models import BoucWenBenchmark, HysteresisModel
from piezohyst.papers import mpi_seed2
from piezohyst.signals import Response

MODELS = {
    "pi": lambda: ph.PI([0.1, 0.3], [0.5, 0.2], 1.0, units={"input": "V", "output": "um"}),
    "play": lambda: ph.PlayOperator(0.2),
    "mpi": mpi_seed2,
    "preisach": lambda: ph.Preisach(6, (0.0, 1.0), np.linspace(0.1, 1.0, 21), slope=0.5),
    "boucwen": lambda: ph.BoucWen(1.0, 0.2, 0.1, d=1.0),
    "boucwen_n2": lambda: ph.BoucWen(1.0, 0.2, 0.1, n=2.0, d=1.0),
    "duhem": lambda: ph.Duhem(1.0, [0.0, 1.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0]),
    "dahl": lambda: ph.Dahl(1.0, 0.5, 1.0),
    "creep": lambda: ph.Creep(1e-3, [0.1, 1.0, 10.0], [0.01, 0.01, 0.01]),
    "rdpi": lambda: ph.RateDependentPI([0.1, 0.3], [0.5, 0.2], 1e-3, beta=0.01, filter_tau=2e-3),
    "pi_creep": lambda: ph.PI([0.1, 0.3], [0.5, 0.2], 1.0, creep=ph.Creep(1e-3, [0.1, 1.0], [0.01, 0.02])),
}


@pytest.fixture
def v():
    rng = np.random.default_rng(7)
    return 0.5 + 0.4 * np.sin(np.linspace(0, 12, 400)) + 0.02 * rng.standard_normal(400)


# --------------------------------------------------------------------------- forward model


@pytest.mark.parametrize("name", MODELS)
def test_response_output_is_simulate_bit_for_bit(name, v):
    model: HysteresisModel = MODELS[name]()
    r = model.response(v)
    assert isinstance(r, Response)
    assert r.input_names == ("input",) and r.output_names == ("output",)
    assert np.array_equal(r.output, model.simulate(v))
    assert np.array_equal(r.input, v)
    assert r.inputs.shape == (1, v.size) and r.outputs.shape == (1, v.size)
    assert r.title == model.family
    state = model.state
    assert np.array_equal(r.final_state, _run_state(model, v))
    assert np.array_equal(model.state, state)  # the step() state is untouched


def _run_state(model, v):
    """The state step() reaches after v from rest (a fresh model of the same parameters)."""
    m = type(model)._from_parameters(model.parameters, model.units)
    for x in v:
        m.step(x)
    return m.state


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("split", [1, 157, 399])
def test_final_state_continues_a_split_run_exactly(name, split, v):
    model = MODELS[name]()
    whole = model.response(v)
    first = model.response(v[:split])
    rest = model.response(v[split:], initial_state=first.final_state)
    assert np.array_equal(np.concatenate([first.output, rest.output]), whole.output)
    assert np.array_equal(rest.final_state, whole.final_state)


def test_initial_state_is_used(v):
    model = MODELS["pi"]()
    start = model.response(v[:50]).final_state
    assert np.array_equal(model.response(v, initial_state=start).output, model.simulate(v, initial_state=start))
    with pytest.raises(ParameterError, match="initial_state has length 1"):
        model.response(v, initial_state=[0.0])


def test_units_come_from_the_model():
    r = MODELS["pi"]().response([0.0, 1.0])
    assert r.units == {"input": "V", "output": "um"}
    assert MODELS["play"]().response([0.0, 1.0]).units == {"input": "", "output": ""}
    assert mpi_seed2().response([0.0, 1.0]).units == {"input": "normalized", "output": "normalized"}


def test_time_base_defaults_to_the_sample_index(v):
    r = MODELS["pi"]().response(v)
    assert r.time.dtype == np.float64
    assert np.array_equal(r.time, np.arange(v.size, dtype=np.float64))


def test_time_base_from_fs(v):
    r = MODELS["pi"]().response(v, fs=200.0)
    assert np.array_equal(r.time, np.arange(v.size) / 200.0)
    assert r.time[1] == 0.005


def test_time_base_from_time(v):
    t = 10.0 + np.cumsum(np.full(v.size, 1e-3))
    r = MODELS["pi"]().response(v, time=t)
    assert np.array_equal(r.time, t)
    assert r.time is not t  # a copy
    irregular = np.sort(np.random.default_rng(1).uniform(0, 1, v.size))
    assert np.array_equal(MODELS["pi"]().response(v, time=irregular).time, irregular)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"fs": 0.0}, ParameterError, "fs = 0.0 must be > 0"),
        ({"fs": -1.0}, ParameterError, "fs = -1.0 must be > 0"),
        ({"fs": np.nan}, ParameterError, "fs = nan is not finite"),
        ({"fs": np.inf}, ParameterError, "fs = inf is not finite"),
        ({"fs": "1k"}, ParameterTypeError, "fs must be a real number"),
        ({"time": [0.0, 1.0]}, ParameterError, "time has 2 samples, the record 4"),
        ({"time": [0.0, 1.0, 1.0, 2.0]}, ParameterError, r"time must be strictly increasing: time\[2\]"),
        ({"time": [0.0, 2.0, 1.0, 3.0]}, ParameterError, r"time must be strictly increasing: time\[2\]"),
        ({"time": [0.0, 1.0, np.nan, 3.0]}, ParameterError, r"time\[2\] = nan is not finite"),
        ({"time": [[0.0, 1.0, 2.0, 3.0]]}, ParameterError, "time must be 1-D"),
        ({"time": "0123"}, ParameterTypeError, "time must be a 1-D array"),
        ({"fs": 1.0, "time": [0.0, 1.0, 2.0, 3.0]}, ParameterError, "fs and time are both given"),
    ],
)
def test_bad_fs_or_time_is_refused_naming_the_argument(kwargs, error, match):
    model = MODELS["pi"]()
    with pytest.raises(error, match=match):
        model.response([0.0, 1.0, 2.0, 1.0], **kwargs)
    with pytest.raises(error, match=match):
        model.inverse().response([0.0, 1.0, 2.0, 1.0], **kwargs)


def test_bad_input_is_refused_as_simulate_does():
    model = MODELS["pi"]()
    with pytest.raises(ParameterError, match=r"input\[1\] = nan is not finite"):
        model.response([0.0, np.nan])
    with pytest.raises(ParameterError, match="input has 0 samples"):
        model.response([])


# --------------------------------------------------------------------------- inverse


INVERTIBLE = ["pi", "play", "mpi", "preisach", "duhem", "dahl", "creep", "rdpi", "pi_creep"]


@pytest.mark.parametrize("name", INVERTIBLE)
def test_inverse_response_is_simulate_bit_for_bit(name, v):
    model = MODELS[name]()
    yd = model.simulate(v)
    inv = model.inverse()
    r = inv.response(yd, fs=100.0)
    assert isinstance(r, Response)
    assert r.input_names == ("desired",) and r.output_names == ("input",)
    assert np.array_equal(r.input, inv.simulate(yd))
    assert np.array_equal(r.desired, yd)
    assert np.array_equal(r.time, np.arange(yd.size) / 100.0)
    assert r.title == f"{model.family} inverse"
    assert np.max(np.abs(model.simulate(r.input) - yd)) <= 1e-9 * (1 + np.max(np.abs(yd)))
    # final_state is the forward model's state after the run
    assert np.array_equal(r.final_state, model.response(r.input).final_state)
    assert np.array_equal(inv.state, model.initial_state())  # the step() state is untouched


def test_inverse_units_swap_roles():
    r = MODELS["pi"]().inverse().response([0.0, 0.5, 1.0])
    assert r.units == {"desired": "um", "input": "V"}


@pytest.mark.parametrize("name", [n for n in INVERTIBLE if n != "play"])
def test_inverse_final_state_continues_a_split_run(name, v):
    """Continuing from final_state solves the same equations; the first sample's solver starts
    from a zero guess instead of the previous input, so the two runs agree to the solver's
    resolution (a few ulps), not bit for bit. (A lone play operator is left out: it is flat
    inside its band, so the input that reaches a desired output is not unique.)"""
    model = MODELS[name]()
    yd = model.simulate(v)
    inv = model.inverse()
    whole = inv.response(yd)
    first = inv.response(yd[:157])
    rest = inv.response(yd[157:], initial_state=first.final_state)
    joined = np.concatenate([first.input, rest.input])
    assert np.array_equal(first.input, whole.input[:157])
    np.testing.assert_allclose(joined, whole.input, rtol=0, atol=1e-12 * (1 + np.max(np.abs(whole.input))))
    np.testing.assert_allclose(rest.final_state, whole.final_state, rtol=0, atol=1e-12)
    assert np.max(np.abs(model.simulate(joined) - yd)) <= 1e-9 * (1 + np.max(np.abs(yd)))


# --------------------------------------------------------------------------- Bouc–Wen benchmark


@pytest.fixture
def force():
    return 50 * np.sin(2 * np.pi * 5 * np.arange(750) / 750.0)


@pytest.mark.parametrize("interpolation", ["fft", "linear", "zoh"])
def test_benchmark_response_is_simulate_bit_for_bit(force, interpolation):
    bw = BoucWenBenchmark()
    r = bw.response(force, 750.0, 4, (1e-5, 0.0, 0.1), interpolation=interpolation)
    y, z = bw.simulate(force, 750.0, 4, (1e-5, 0.0, 0.1), interpolation=interpolation, return_z=True)
    assert isinstance(r, Response)
    assert np.array_equal(r.y, y) and np.array_equal(r.z, z)
    assert np.array_equal(r.u, force)
    assert np.array_equal(bw.simulate(force, 750.0, 4, (1e-5, 0.0, 0.1), interpolation=interpolation), y)
    assert r.input_names == ("u",) and r.output_names == ("y", "z")
    assert r.units == {"u": "N", "y": "m", "z": "N"}
    assert r.outputs.shape == (2, force.size) and r.inputs.shape == (1, force.size)
    assert np.array_equal(r.time, np.arange(force.size) / 750.0)
    assert r.title == "Bouc–Wen benchmark"


def test_benchmark_final_state_is_the_integrators_last_step(force):
    bw = BoucWenBenchmark()
    r = bw.response(force, upsample=1)
    # with upsample = 1 and no decimation the last integration step is the last sample
    assert r.final_state.shape == (3,)
    assert r.final_state[0] == r.y[-1] and r.final_state[2] == r.z[-1]
    fine = bw.integrate(force, 1 / 750.0, return_z=True)
    assert np.array_equal(fine[0], r.y) and np.array_equal(fine[1], r.z)
    # the state continues the run: integrating on from it gives the whole run's samples
    whole_y, whole_z = bw.integrate(np.r_[force, force[:10]], 1 / 750.0, return_z=True)
    more_y, more_z = bw.integrate(np.r_[force[-1], force[:10]], 1 / 750.0, r.final_state, return_z=True)
    np.testing.assert_allclose(more_y, whole_y[force.size - 1 :], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(more_z, whole_z[force.size - 1 :], rtol=1e-9, atol=1e-9)


def test_benchmark_response_refuses_bad_arguments(force):
    bw = BoucWenBenchmark()
    with pytest.raises(ParameterError, match="fs = 0.0 must be > 0"):
        bw.response(force, fs=0.0)
    with pytest.raises(ParameterError, match="upsample = 0 must be >= 1"):
        bw.response(force, upsample=0)
    with pytest.raises(ParameterError, match="interpolation = 'cubic' is unknown"):
        bw.response(force, interpolation="cubic")
    with pytest.raises(ParameterError, match="initial_state has length 2"):
        bw.response(force, initial_state=(0.0, 0.0))
