"""signals.Response: construction checks, read-only, pickling, stacked shapes, display, pandas."""

import copy
import pickle

import numpy as np
import pytest

from piezohyst.errors import ParameterError
from piezohyst.signals import Response


def make(n=5, **kw):
    t = np.arange(n) * 1e-3
    signals = {"voltage": np.linspace(0.0, 1.0, n), "position": np.linspace(0.0, 2e-6, n), "force": np.ones(n)}
    kw.setdefault("inputs", ["voltage"])
    kw.setdefault("units", {"voltage": "V", "position": "m", "force": "N"})
    return Response(t, signals, **kw)


# --------------------------------------------------------------------------- construction


def test_signals_are_float64_arrays_readable_by_name_and_attribute():
    r = make(final_state=[1, 2], title="stage")
    assert r.time.dtype == np.float64 and r.time.shape == (5,)
    assert r.position is r["position"] is r.signals["position"]
    assert r.voltage.dtype == np.float64
    assert r.input_names == ("voltage",)
    assert r.output_names == ("position", "force")
    assert r.units == {"voltage": "V", "position": "m", "force": "N"}
    assert r.final_state.tolist() == [1.0, 2.0] and r.final_state.dtype == np.float64
    assert r.title == "stage"
    assert len(r) == r.n_time == 5
    assert {"voltage", "position", "force"} <= set(dir(r))


def test_defaults():
    r = Response([0.0, 1.0], {"y": [1, 2]})
    assert r.input_names == () and r.output_names == ("y",)
    assert r.units == {"y": ""}
    assert r.final_state is None and r.title == ""


def test_wrong_length_signal_is_refused_naming_it():
    with pytest.raises(ParameterError, match="signal 'y' has shape \\(2,\\)"):
        Response([0.0, 1.0, 2.0], {"u": [0, 1, 2], "y": [1, 2]})
    with pytest.raises(ParameterError, match="signal 'y'"):
        Response([0.0, 1.0], {"y": [[1, 2], [3, 4]]})


@pytest.mark.parametrize("time", [[0.0, 1.0, 1.0], [0.0, 2.0, 1.0], [0.0, np.nan, 2.0]])
def test_non_increasing_time_is_refused(time):
    with pytest.raises(ParameterError, match="time"):
        Response(time, {"y": [1, 2, 3]})


def test_non_finite_or_2d_time_is_refused():
    with pytest.raises(ParameterError, match=r"time\[2\] = inf is not finite"):
        Response([0.0, 1.0, np.inf], {"y": [1, 2, 3]})
    with pytest.raises(ParameterError, match="time must be 1-D"):
        Response([[0.0, 1.0]], {})


def test_unknown_input_or_unit_name_is_refused():
    with pytest.raises(ParameterError, match="inputs names 'v'.*signals: \\['u', 'y'\\]"):
        Response([0.0, 1.0], {"u": [0, 1], "y": [1, 2]}, inputs=["v"])
    with pytest.raises(ParameterError, match="units names 'z'"):
        Response([0.0, 1.0], {"u": [0, 1]}, units={"z": "m"})


def test_unknown_signal_lookup():
    r = make()
    with pytest.raises(KeyError, match="no signal 'speed'"):
        r["speed"]
    with pytest.raises(AttributeError, match="no attribute or signal 'speed'"):
        r.speed  # noqa: B018


# --------------------------------------------------------------------------- read-only


def test_read_only():
    r = make()
    with pytest.raises(AttributeError, match="read-only"):
        r.title = "x"
    with pytest.raises(AttributeError, match="read-only"):
        r.position = np.zeros(5)
    with pytest.raises(AttributeError, match="read-only"):
        del r.time
    assert r.title == ""


# --------------------------------------------------------------------------- pickling


def test_pickle_and_copy_round_trip():
    r = make(final_state=[0.5, -1.0], title="run")
    for back in (pickle.loads(pickle.dumps(r)), copy.deepcopy(r), copy.copy(r)):
        assert type(back) is Response
        assert np.array_equal(back.time, r.time)
        assert back.signals.keys() == r.signals.keys()
        for name in r.signals:
            assert np.array_equal(back[name], r[name])
        assert back.input_names == r.input_names and back.output_names == r.output_names
        assert back.units == r.units and back.title == r.title
        assert np.array_equal(back.final_state, r.final_state)
        assert np.array_equal(back.position, r.position)
        with pytest.raises(AttributeError, match="read-only"):
            back.title = "x"


# --------------------------------------------------------------------------- stacked shapes


def test_inputs_outputs_shapes_are_never_squeezed():
    r = make(n=7)
    assert r.inputs.shape == (1, 7)
    assert r.outputs.shape == (2, 7)
    assert np.array_equal(r.inputs[0], r.voltage)
    assert np.array_equal(r.outputs, np.vstack([r.position, r.force]))
    none_in = Response(np.arange(4.0), {"y": np.ones(4)})
    assert none_in.inputs.shape == (0, 4) and none_in.outputs.shape == (1, 4)
    one_sample = Response([0.0], {"u": [1.0], "y": [2.0]}, inputs=["u"])
    assert one_sample.inputs.shape == (1, 1) and one_sample.outputs.shape == (1, 1)
    all_in = Response(np.arange(3.0), {"u": np.ones(3)}, inputs=["u"])
    assert all_in.outputs.shape == (0, 3)


# --------------------------------------------------------------------------- display


def test_repr_and_html():
    r = make(title="PI <model>")
    assert repr(r) == "Response(PI <model>: 5 samples over 0.004 s; signals voltage, position, force)"
    h = r._repr_html_()
    assert h.startswith("<div>") and h.endswith("</div>")
    assert "PI &lt;model&gt;" in h and "<model>" not in h  # escaped
    for header in ("signal", "role", "unit", "min", "max", "rms"):
        assert f"<th>{header}</th>" in h
    assert "<tr><td>voltage</td><td>input</td><td>V</td><td>0</td><td>1</td>" in h
    assert "<tr><td>position</td><td>output</td><td>m</td>" in h
    assert "<tr><td>force</td><td>output</td><td>N</td><td>1</td><td>1</td><td>1</td></tr>" in h
    assert h.count("<tr>") == 1 + 3  # header row + one per signal


def test_plot_returns_a_figure():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    r = make(title="run")
    fig = r.plot()
    try:
        assert isinstance(fig, Figure)
        assert len(fig.axes) == 3  # one panel per unit
        assert fig.axes[0].get_title() == "run"
    finally:
        plt.close(fig)
    fig2, axes = plt.subplots(2, 1)
    try:
        assert r.plot(["voltage", "position"], ax=axes) is fig2
        assert r.plot(["force"], ax=axes[0]) is fig2
        with pytest.raises(ParameterError, match="ax has 2 axes; this plot needs 3"):
            r.plot(ax=axes)
        with pytest.raises(KeyError, match="no signal 'speed'"):
            r.plot(["speed"], ax=axes)
    finally:
        plt.close(fig2)


def test_to_pandas():
    pd = pytest.importorskip("pandas")
    r = make()
    df = r.to_pandas()
    assert isinstance(df, pd.DataFrame)
    assert df.columns.tolist() == ["voltage", "position", "force"]
    assert df.index.name == "time"
    assert np.array_equal(df.index.to_numpy(), r.time)
    assert np.array_equal(df["position"].to_numpy(), r.position)
