"""Monte-Carlo robustness (issue 16, item 2): perturbations parsed and mapped onto the stage's
parameter row, per-sample seeds from SeedSequence spawn, chunks independent of how the samples
are split and of the runner, percentiles and worst cases that are the samples' own."""

import dataclasses

import numpy as np
import pytest

from piezohyst import PID, virtual_stage
from piezohyst.errors import ParameterError
from piezohyst.fleet import (
    PARAMETERS,
    Perturbation,
    RobustnessProblem,
    Runner,
    draw,
    parse_perturbations,
    plan,
    robustness,
    run_chunk,
)

STAGE = virtual_stage()
T = np.arange(0, 0.04, STAGE.sample_time)
REF = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * T)


def problem(spec="mass=±10%,stiffness=±20%,tem=±5%:normal", seed=7):
    return RobustnessProblem(STAGE, PID(kp=2e6, ki=2e9), REF, 80, tuple(parse_perturbations(spec)), seed)


@pytest.mark.parametrize("name", sorted(PARAMETERS))
def test_each_parameter_scales_its_own_columns_of_the_core_row(name):
    base = virtual_stage()
    sp = base.params
    if name == "creep_weights" and not sp.creep_weights:
        sp = dataclasses.replace(sp, creep_taus=(0.1, 1.0), creep_weights=(0.02, 0.03))
        base = base.with_(params=sp)
    p = RobustnessProblem(base, PID(kp=1.0, ki=1.0), REF, 0, (Perturbation(name, 10.0),), 0)
    value = getattr(sp, name)
    scaled = tuple(w * 1.07 for w in value) if isinstance(value, tuple) else value * 1.07
    expected = base.with_(params=dataclasses.replace(sp, **{name: scaled})).core_params()
    row = p.rows(np.array([[1.07]]))[0]
    assert np.array_equal(row, expected)
    assert p.part([1.07]) == dataclasses.replace(sp, **{name: scaled})


def test_perturbations_parse_with_aliases_and_distributions():
    ps = parse_perturbations("mass=±10%, stiffness=+-5%,gamma=2.5%:normal , creep=+/-30%")
    assert [(p.name, p.percent, p.distribution) for p in ps] == [
        ("mass", 10.0, "uniform"),
        ("stiffness", 5.0, "uniform"),
        ("hyst_gamma", 2.5, "normal"),
        ("creep_weights", 30.0, "uniform"),
    ]


@pytest.mark.parametrize(
    "text, match",
    [
        ("mass", "NAME=±P%"),
        ("mass=10", "NAME=±P%"),
        ("weight=±10%", "'weight' is not a perturbable"),
        ("mass=±100%", "< 100 %"),
        ("mass=±40%:normal", "< 33.33 %"),
        ("mass=±0%", "> 0"),
        ("mass=±5%:cauchy", "uniform or normal"),
        ("mass=±5%,mass=±3%", "twice"),
        (" , ", "names no parameter"),
    ],
)
def test_bad_perturbations_are_refused_by_name(text, match):
    with pytest.raises(ParameterError, match=match):
        parse_perturbations(text)


def test_sample_i_draws_from_the_i_th_spawned_seed_sequence():
    ps = parse_perturbations("mass=±10%,tem=±6%:normal")
    f, s = draw(ps, 42, 0, 6)
    children = np.random.SeedSequence(42).spawn(6)
    for i, child in enumerate(children):
        g = np.random.default_rng(child)
        u = g.random(2)
        assert f[i, 0] == 1 + 0.1 * (2 * u[0] - 1)
        assert s[i] == g.integers(0, 2**63 - 1)
    # a sample's draw does not depend on the range it is drawn in
    f2, s2 = draw(ps, 42, 3, 5)
    assert np.array_equal(f2, f[3:5]) and np.array_equal(s2, s[3:5])
    # the factors respect their distributions
    big, _ = draw(ps, 1, 0, 4000)
    assert 0.9 <= big[:, 0].min() and big[:, 0].max() <= 1.1
    assert abs(big[:, 1].std() - 0.06) < 0.004 and np.abs(big[:, 1] - 1).max() <= 3 * 0.06


def test_chunks_are_independent_of_the_split():
    p = problem()
    whole = run_chunk(p, 0, 24)
    left, right = run_chunk(p, 0, 10), run_chunk(p, 10, 24)
    assert np.array_equal(whole.metrics, np.vstack([left.metrics, right.metrics]))
    assert np.array_equal(whole.factors, np.vstack([left.factors, right.factors]))


def test_a_result_is_the_same_whatever_the_chunk_size_and_its_worst_cases_are_its_samples():
    p = problem()
    serial = Runner(plan("serial", env={}))
    a = robustness(p, 60, serial, chunk=7)
    b = robustness(p, 60, serial, chunk=60)
    assert np.array_equal(a.metrics, b.metrics) and np.array_equal(a.seeds, b.seeds)
    assert not a.errors and np.isfinite(a.metrics).all()
    d = a.to_dict()
    rmse = a.metrics[:, 0]
    assert d["percentiles"]["rmse"]["max"] == rmse.max()
    assert d["percentiles"]["rmse"]["p50"] == pytest.approx(np.median(rmse), rel=1e-12)
    worst = d["worst"]
    assert [w["sample"] for w in worst] == list(np.argsort(-rmse, kind="stable")[:5])
    w = worst[0]
    assert w["rmse"] == rmse.max()
    assert w["parameters"]["mass"]["value"] == pytest.approx(STAGE.params.mass * a.factors[w["sample"], 0], rel=1e-15)
    # the replay of the worst part has the batch's figures
    r = a.replay(w["sample"])
    assert r.metrics["rmse"] == pytest.approx(w["rmse"], rel=1e-12)
    # stiffness drives the error of this PID: more stiffness, less static gain, more lag
    assert d["sensitivity_spearman"]["stiffness"] > 0.5


def test_a_feedforward_inverse_errs_both_ways_off_nominal():
    # the inverse compensates the nominal gain: a softer or a stiffer part are both off, so the
    # error ranks with |factor - 1|, not with the factor
    from piezohyst.cli.track import _build_controller

    inverse = _build_controller("inverse", STAGE, None)
    p = RobustnessProblem(STAGE, inverse, REF, 80, tuple(parse_perturbations("stiffness=±20%")), 2)
    res = robustness(p, 200, Runner(plan("serial", env={})), chunk=100)
    assert abs(res.sensitivity()["stiffness"]) < 0.3
    assert res.sensitivity(deviation=True)["stiffness"] > 0.8


def test_samples_and_chunk_are_checked():
    serial = Runner(plan("serial", env={}))
    with pytest.raises(ParameterError, match="--samples"):
        robustness(problem(), 0, serial)
    with pytest.raises(ParameterError, match="chunk"):
        robustness(problem(), 5, serial, chunk=0)
