"""Every public result class follows the one result protocol (piezohyst.signals.results.Result):
``to_pandas()`` (or an ImportError saying ``pip install pandas``), ``plot()`` (a matplotlib
figure), ``_repr_html_()`` (escaped HTML) and ``to_mat``/``from_mat`` (exact round trip).

The classes are found, not listed: every public class of the package whose name ends in
``Result``, ``Response`` or ``Report``. A new one fails ``test_every_result_class_is_covered``
until it is given the protocol and an instance here (FACTORIES)."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
import re

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

import piezohyst as ph
from piezohyst.signals.results import Result
from tests.signals.test_matfile import same

NAME = re.compile(r"(?!_)\w*(Result|Response|Report)")
#: Mixins named like results that are never instantiated themselves (they carry the protocol).
MIXINS = {"piezohyst.optimize.report.RunReport"}

try:
    import pandas  # noqa: F401

    HAVE_PANDAS = True
except ImportError:
    HAVE_PANDAS = False


def result_classes() -> dict[str, type]:
    """Every public class named ...Result / ...Response / ...Report defined in the package."""
    found: dict[str, type] = {}
    for info in pkgutil.walk_packages(ph.__path__, "piezohyst."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            protocol = getattr(obj, "_is_protocol", False)  # the Result protocol itself
            if inspect.isclass(obj) and obj.__module__ == info.name and NAME.fullmatch(name) and not protocol:
                found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


# -- one real instance of each -------------------------------------------------------------
def _record():
    stage = ph.virtual_stage()
    v = ph.plant.excitation(1 / stage.sample_time, seconds=0.6)
    u, y = ph.plant.measure(stage, v, np.random.default_rng(0))
    return u, y


def _response():
    model = ph.PI([0.0, 0.5], [1.0, 0.3], 0.2, units={"input": "V", "output": "m"})
    return model.response(np.linspace(0, 2, 50), fs=1e3)


def _stage_response():
    stage = ph.virtual_stage()
    return stage.simulate(75 - 75 * np.cos(np.linspace(0, 6, 400)))


def _closed_loop():
    stage = ph.virtual_stage()
    _, ref = ph.sine(5, 5e-6, 0.1, 1 / stage.sample_time, offset=7e-6)
    return ph.track(ph.PID(kp=2e6, ki=2e9), ref, stage=stage, rng=1, skip=0.02)


def _fit():
    u, y = _record()
    return ph.identify_pi(u, y, operators=5)


def _identification():
    u, y = _record()
    fit = ph.identify_pi(u, y, operators=4)
    from piezohyst.identify import IdentificationResult

    return IdentificationResult(
        fit.model, fit.metrics, None, "ls", 0.01, history={"best_cost": np.array([2.0, 1.0])}, evaluations=3
    )


def _validated():
    u, y = _record()
    n = u.size // 2
    return ph.identify(u[:n], y[:n], "mpi", fs=1e4, validate=(u[n:], y[n:]))


def _minimize(callback=None):
    return ph.optimize.minimize(
        lambda X: np.sum((X - 0.3) ** 2, axis=1),
        [(-1.0, 1.0)] * 3,
        method="pso",
        max_iterations=5,
        population_size=8,
        rng=2,
        callback=callback,
    )


def _intermediate():
    seen = []
    _minimize(callback=seen.append)
    return seen[-1]


def _tuning():
    stage = ph.virtual_stage()
    _, ref = ph.sine(10, 5e-6, 0.05, 1 / stage.sample_time, offset=7e-6)
    return ph.tune(
        ph.PID(),
        {"kp": (1e5, 1e7), "ki": (1e8, 1e10)},
        [ref],
        stage=stage,
        max_iterations=2,
        population_size=4,
        rng=1,
        skip=0.01,
    )


def _multi_axis():
    from piezohyst.control import closed_loop_multi
    from piezohyst.plant import MultiAxisStage

    xy = MultiAxisStage.from_axes([ph.virtual_stage()] * 2, coupling=0.05)
    ref = np.column_stack([np.linspace(4e-6, 6e-6, 300), np.full(300, 5e-6)])
    return closed_loop_multi(xy, [ph.PID(kp=1e6, ki=5e9)] * 2, ref, rng=1).with_skip(0.005)


def _multi_axis_tuning():
    from piezohyst.plant import MultiAxisStage

    xy = MultiAxisStage.from_axes([ph.virtual_stage()] * 2, coupling=0.05)
    ref = np.column_stack([np.linspace(4e-6, 6e-6, 300), np.full(300, 5e-6)])
    return ph.tune(
        [ph.PID(kp=1e6, ki=5e9)] * 2,
        {"ki": (1e8, 1e10)},
        ref,
        stage=xy,
        max_iterations=2,
        population_size=4,
        rng=1,
        skip=0.01,
    )


def _robustness():
    from piezohyst.fleet.cluster import Runner, plan
    from piezohyst.fleet.robustness import RobustnessProblem, parse_perturbations, robustness

    stage = ph.virtual_stage()
    _, ref = ph.sine(20, 4e-6, 0.02, 1 / stage.sample_time, offset=7e-6)
    problem = RobustnessProblem(
        stage, ph.PID(kp=2e6, ki=2e9), ref, 20, tuple(parse_perturbations("mass=±10%,stiffness=±20%")), 3
    )
    return robustness(problem, 12, Runner(plan("serial", env={})), chunk=6)


def _frequency_response():
    from piezohyst.control.frequency import measure_frf

    return measure_frf(ph.virtual_stage(), band=(20.0, 2000.0), periods=2, rng=1)


FACTORIES = {
    "piezohyst.signals.response.Response": _response,
    "piezohyst.signals.frequency.FrequencyResponse": _frequency_response,
    "piezohyst.plant.stage.StageResponse": _stage_response,
    "piezohyst.control.simulation.ClosedLoopResult": _closed_loop,
    "piezohyst.control.multiaxis.MultiAxisResult": _multi_axis,
    "piezohyst.identify.core.FitResult": _fit,
    "piezohyst.identify.core.IdentificationResult": _identification,
    "piezohyst.identify.validation.ValidatedResult": _validated,
    "piezohyst.optimize.core.OptimizeResult": _minimize,
    "piezohyst.optimize.core.IntermediateResult": _intermediate,
    "piezohyst.control.tuning.TuningResult": _tuning,
    "piezohyst.control.tuning.MultiAxisTuningResult": _multi_axis_tuning,
    "piezohyst.fleet.robustness.RobustnessResult": _robustness,
}


def test_every_result_class_is_covered():
    found = result_classes()
    missing = sorted(set(found) - set(FACTORIES) - MIXINS)
    assert not missing, f"result classes without an instance in FACTORIES (give them the protocol): {missing}"
    assert set(FACTORIES) <= set(found)  # a renamed class is noticed
    for name, cls in found.items():
        for method in ("to_pandas", "plot", "_repr_html_", "to_mat", "from_mat"):
            assert callable(getattr(cls, method, None)), f"{name} has no {method}"


@pytest.fixture(scope="module", params=sorted(FACTORIES))
def result(request):
    obj = FACTORIES[request.param]()
    assert f"{type(obj).__module__}.{type(obj).__qualname__}" == request.param
    return obj


def test_protocol(result):
    assert isinstance(result, Result)


def test_to_pandas(result):
    if not HAVE_PANDAS:
        with pytest.raises(
            ImportError, match=rf"{type(result).__name__}\.to_pandas\(\) needs pandas.*pip install pandas"
        ):
            result.to_pandas()
        return
    df = result.to_pandas()
    assert df.shape[1] > 0


def test_plot(result):
    fig = result.plot()
    try:
        assert isinstance(fig, Figure) and fig.axes
        assert any(ax.has_data() or ax.texts for ax in fig.axes)
    finally:
        plt.close(fig)


def test_repr_html(result):
    text = result._repr_html_()
    assert text.startswith("<div>") and text.endswith("</div>") and "<table>" in text
    assert "<script" not in text


def test_mat_round_trip_is_exact(result, tmp_path):
    path = result.to_mat(tmp_path / "r.mat")
    back = type(result).from_mat(path)
    assert type(back) is type(result)
    if dataclasses.is_dataclass(result):
        for f in dataclasses.fields(result):
            if f.name == "simulator":  # a function: not stored (documented), default on reading
                continue
            assert same(getattr(result, f.name), getattr(back, f.name)) or getattr(result, f.name) == getattr(
                back, f.name
            ), f.name
    else:
        assert same(result.time, back.time) and list(result.signals) == list(back.signals)
        for k in result.signals:
            assert same(result.signals[k], back.signals[k]), k
        assert result.units == back.units and result.input_names == back.input_names and result.title == back.title
        assert same(result.final_state, back.final_state)
        for attr in ("sample_time", "controller", "skip_samples"):
            if hasattr(result, attr):
                assert getattr(result, attr) == getattr(back, attr)
        if hasattr(result, "metrics"):
            assert result.metrics == back.metrics
    # a result file read as another class is refused
    other = ph.optimize.OptimizeResult if not isinstance(result, ph.optimize.OptimizeResult) else ph.signals.Response
    with pytest.raises(ph.errors.DataError):
        other.from_mat(path)


def test_html_is_escaped():
    r = ph.signals.Response([0.0, 1.0], {"x<y>": [1.0, 2.0]}, units={"x<y>": "µ&m"}, title="<script>alert(1)</script>")
    text = r._repr_html_()
    assert "<script>" not in text and "&lt;script&gt;" in text and "x&lt;y&gt;" in text and "µ&amp;m" in text


def test_plot_without_history_draws_the_scores():
    fit = _fit()
    assert fit.history == {}
    fig = fit.plot()
    labels = [t.get_text() for t in fig.axes[0].get_yticklabels()]
    plt.close(fig)
    assert "rmse (% of range)" in labels


def test_to_pandas_error_without_pandas(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pandas", None)
    for obj in (_response(), _minimize()):
        with pytest.raises(ImportError, match="pip install pandas"):
            obj.to_pandas()
