"""ClosedLoopResult is a Response (issue 18): its signals are the core's output bit for bit, the
old attributes stay, skip_samples is a constructor argument, metrics are cached, the result is
read-only and pickles."""

import pickle

import matplotlib
import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core
from piezohyst.control import ClosedLoopResult
from piezohyst.control.simulation import _prepare, seed_from
from piezohyst.signals import Response
from piezohyst.signals.metrics import tracking_metrics

matplotlib.use("Agg")

STAGE = ph.virtual_stage()
TS = STAGE.sample_time
REF = 10e-6 - 8e-6 * np.cos(2 * np.pi * 10 * np.arange(0, 0.2, TS))
PID = ph.PID(kp=2e6, ki=2e9)


def core_run(controller, ref, rng):
    """The core's own output for the run closed_loop makes (what the old attributes held)."""
    x, v, a, spec = _prepare(STAGE, controller, ref, None, None)
    s = STAGE.sensor
    return _core.closed_loop(
        STAGE.core_params(),
        STAGE.sample_time,
        STAGE.substeps,
        STAGE.tolerance,
        s.quantization,
        s.noise_std,
        s.delay,
        spec,
        x,
        v,
        a,
        STAGE.rest_state(),
        seed_from(rng),
    )


def test_closed_loop_returns_a_response_whose_signals_are_the_core_output_bit_for_bit():
    res = ph.closed_loop(STAGE, PID, REF, rng=4)
    d = core_run(PID, REF, 4)
    assert isinstance(res, Response)
    assert isinstance(res, ClosedLoopResult)
    names = list(d["term_names"])
    assert list(res.signals) == ["reference", "command", "voltage", "position", "measured"] + [
        f"term_{n}" for n in names
    ]
    for name in ("reference", "command", "voltage", "position", "measured"):
        assert np.array_equal(res.signals[name], d[name])
        assert np.array_equal(getattr(res, name), d[name])
        assert res[name] is res.signals[name]
    assert list(res.terms) == names
    for i, n in enumerate(names):
        assert np.array_equal(res.terms[n], d["terms"][:, i])
        assert res.terms[n] is res.signals[f"term_{n}"]
    assert np.array_equal(res.final_state, d["final_state"])
    assert np.array_equal(res.time, np.arange(REF.size) * TS)
    assert res.sample_time == TS
    assert res.controller == res.title == "PID"
    assert np.array_equal(res.error, res.reference - res.position)
    assert res.input_names == ("reference",)
    assert res.units["reference"] == res.units["position"] == res.units["measured"] == "m"
    assert res.units["command"] == res.units["voltage"] == "V"


def test_inputs_and_outputs_shapes():
    res = ph.closed_loop(STAGE, PID, REF, rng=1)
    n = REF.size
    assert res.inputs.shape == (1, n)
    assert np.array_equal(res.inputs[0], res.reference)
    assert res.outputs.shape == (4 + len(res.terms), n)
    assert np.array_equal(res.outputs[2], res.position)
    assert len(res) == res.n_time == n


def test_batch_results_are_responses_too():
    out = ph.closed_loop_batch(STAGE, [(PID, REF), (ph.OpenLoop(), REF)], rng=2)
    assert [type(r) for r in out] == [ClosedLoopResult, ClosedLoopResult]
    assert [r.title for r in out] == ["PID", "OpenLoop"]
    assert all(r.skip_samples == 0 for r in out)


def test_positional_construction_and_skip_samples_argument():
    n = 5
    sig = [np.linspace(0, 1e-6, n) + j * 1e-7 for j in range(5)]
    terms = {"p": np.ones(n), "i": np.zeros(n)}
    r = ClosedLoopResult(1e-3, *sig, terms, np.zeros(12), controller="X")
    assert r.skip_samples == 0
    assert r.controller == "X" and r.sample_time == 1e-3
    assert np.array_equal(r.reference, sig[0]) and np.array_equal(r.measured, sig[4])
    assert list(r.terms) == ["p", "i"]
    assert np.array_equal(r.term_p, np.ones(n))
    r2 = ClosedLoopResult(1e-3, *sig, terms, np.zeros(12), "X", 2)
    assert r2.skip_samples == 2
    r3 = ClosedLoopResult(1e-3, *sig, terms, np.zeros(12), skip_samples=3)
    assert r3.skip_samples == 3 and r3.controller == ""


def test_metrics_leave_out_skip_samples_and_are_cached():
    res = ph.track(PID, REF, stage=STAGE, rng=3, skip=0.05)
    k = round(0.05 / TS)
    assert res.skip_samples == k
    expected = tracking_metrics(res.reference[k:], res.position[k:])
    assert res.metrics == expected
    assert res.metrics is res.metrics  # cached on first use
    # the same run without the skip: metrics over the whole record
    full = res._with_skip(0)
    assert full.skip_samples == 0 and res.skip_samples == k
    assert full.metrics == tracking_metrics(res.reference, res.position)
    assert np.array_equal(full.position, res.position)
    assert full.controller == res.controller and np.array_equal(full.final_state, res.final_state)
    assert ph.closed_loop(STAGE, PID, REF, rng=3).skip_samples == 0


def test_the_result_is_read_only():
    res = ph.closed_loop(STAGE, PID, REF, rng=1)
    for name in ("skip_samples", "position", "controller", "metrics", "terms", "anything"):
        with pytest.raises(AttributeError):
            setattr(res, name, 1)
    with pytest.raises(AttributeError):
        del res.controller


def test_pickle_round_trip():
    res = ph.track(PID, REF, stage=STAGE, rng=5, skip=0.02)
    metrics = res.metrics
    back = pickle.loads(pickle.dumps(res))
    assert type(back) is ClosedLoopResult
    assert list(back.signals) == list(res.signals)
    for name, a in res.signals.items():
        assert np.array_equal(back.signals[name], a)
    assert back.skip_samples == res.skip_samples
    assert back.controller == res.controller and back.sample_time == res.sample_time
    assert list(back.terms) == list(res.terms)
    assert back.metrics == metrics
    assert back.units == res.units and back.input_names == res.input_names
    fresh = pickle.loads(pickle.dumps(ph.closed_loop(STAGE, PID, REF, rng=5)))
    assert fresh.metrics == tracking_metrics(fresh.reference, fresh.position)


def test_to_pandas_columns():
    pytest.importorskip("pandas")
    res = ph.closed_loop(STAGE, PID, REF, rng=1)
    cols = ["reference", "command", "voltage", "position", "measured", "error"] + [f"term_{k}" for k in res.terms]
    assert res.to_pandas().columns.tolist() == cols


def test_plot_is_the_tracking_plot_and_signals_give_the_response_panels():
    import matplotlib.pyplot as plt

    res = ph.closed_loop(STAGE, PID, REF, rng=1)
    fig = res.plot(zoom=(0.05, 0.1))
    assert len(fig.axes) >= 2
    assert fig.axes[0].get_ylabel() == "position (µm)"
    plt.close(fig)
    fig = res.plot(["position", "voltage"])
    assert [a.get_ylabel() for a in fig.axes] == ["(m)", "(V)"]
    plt.close(fig)
    assert "PID" in res._repr_html_()
