"""A parameter layout appears once, in the core's table (``piezohyst_core::layout``): every
Python consumer reads it from there (``_core.family_layout`` / ``_core.controller_layout``),
so a slot renamed in the table is renamed in the C export, the controller files and the
identification code alike. (The C header's doc block is checked against the same table by
``crates/capi/tests/layout_doc.rs``.)"""

import sys

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core, export_c
from piezohyst.errors import ParameterError

# the module defining fit_linear (wherever the package keeps it)
identify = sys.modules[ph.fit_linear.__module__]

FAMILY_DIMS = [
    ("pi", [3, 0]),
    ("pi", [2, 2]),
    ("gpi", [3, 1, 2, 1]),
    ("rdpi", [2, 1]),
    ("creep", [2]),
    ("preisach", [3, 4]),  # a row of two dims, from before the creep tail: no tail
    ("preisach", [3, 4, 2]),
    ("boucwen", []),
    ("duhem", []),
    ("dahl", []),
]


@pytest.mark.parametrize(("family", "dims"), FAMILY_DIMS)
def test_row_names_are_the_table_slots(family, dims):
    layout = _core.family_layout(family, dims)
    assert export_c.row_names(family, dims) == layout["slots"]
    assert len(layout["slots"]) == layout["param_len"] == _core.family_sizes(family, dims)[0]
    assert layout["state_len"] == _core.family_sizes(family, dims)[1]
    assert export_c.FAMILY_CODES[family] == layout["code"]
    # groups cover the row in order
    at = 0
    for _, offset, length in layout["groups"]:
        assert offset == at
        at += length
    assert at == layout["param_len"]


def test_pi_row_spelled_by_the_table():
    assert _core.family_layout("pi", [2, 1])["slots"] == [
        "p0",
        "r[0]",
        "r[1]",
        "w[0]",
        "w[1]",
        "creep_ts",
        "creep_tau[0]",
        "creep_c[0]",
    ]


def test_controller_names_and_codes_are_the_table():
    families, kinds = _core.layout_codes()
    assert export_c.FAMILY_CODES == families
    assert export_c.CONTROLLER_KINDS == kinds
    for kind in kinds:
        layout = _core.controller_layout(kind)
        assert export_c.CONTROLLER_PARAMS[kind] == tuple(layout["slots"])
        assert layout["code"] == kinds[kind]
        assert layout["slots"][-2:] == ["u_min", "u_max"]


@pytest.mark.parametrize(
    "model",
    [
        ph.PI([0.0, 0.2, 0.5], [1.0, 0.3, 0.1], p0=0.5),
        ph.RateDependentPI([0.0, 0.3], [0.5, 0.2], 1e-3, 1.0, 0.1, [0.0, 0.0], 0.0),
        ph.Preisach(3, (0.0, 1.0), np.full(6, 0.1), 0.0, 1.0),
        ph.Preisach(3, (0.0, 1.0), np.full(6, 0.1), 0.0, 1.0, creep=ph.Creep(1e-3, [0.01, 0.1], [0.02, 0.01])),
        ph.PI([0.0, 0.2], [1.0, 0.3], p0=0.1, creep=ph.Creep(1e-3, [0.01, 0.1], [0.02, 0.01])),
        ph.papers.mpi_seed2(),
    ],
)
def test_identify_columns_are_the_table_linear_slots(model):
    layout = _core.family_layout(model.family, list(model.dims))
    lb, _, build = identify._layout(model)
    sizes = {name: size for name, _, size in layout["groups"]}
    assert lb.size == sum(sizes[n] for n in layout["linear"])
    assert _core.regressors(model.family, list(model.dims), model.to_row(), np.linspace(0, 1, 4)).shape[1] == lb.size
    # the regressors dotted with the linear slots of the row reproduce the output
    row = model.to_row()
    theta = np.concatenate([row[o : o + n] for name in layout["linear"] for (g, o, n) in layout["groups"] if g == name])
    v = np.sin(np.linspace(0, 6, 50))
    X = _core.regressors(model.family, list(model.dims), row, v)
    np.testing.assert_allclose(X @ theta, model.simulate(v), rtol=1e-12, atol=1e-12)
    assert build(theta) == model
    # the lower bounds are the table's: 0 on its non-negative slots, free elsewhere
    free = np.concatenate(
        [np.full(sizes[n], n not in layout["nonnegative"]) for n in layout["linear"]] or [np.zeros(0, bool)]
    )
    assert np.array_equal(np.isneginf(lb), free)
    assert np.all(lb[~free] == 0.0)


def test_typed_model_matches_the_free_functions():
    m = ph.PI([0.0, 0.2, 0.5], [1.0, 0.3, 0.1], p0=0.5)
    core = _core.Model(m.family, list(m.dims), m.to_row())
    assert core.layout == _core.family_layout(m.family, list(m.dims))
    v = np.sin(np.linspace(0, 6, 100))
    assert np.array_equal(core.simulate(v), m.simulate(v))
    st = core.initial_state()
    y = core.simulate(v, st)
    assert np.array_equal(
        core.inverse(y, core.initial_state()),
        _core.inverse(m.family, list(m.dims), m.to_row(), y, core.initial_state(), 0.0),
    )


def test_core_errors_carry_parameter_index_value():
    with pytest.raises(ParameterError) as e:
        _core.Model("pi", [3, 0], np.array([0.9, 0.0, 0.2, 0.1, 0.5, 0.2, 0.1]))
    assert (e.value.parameter, e.value.index, e.value.value) == ("thresholds", 2, 0.1)
    with pytest.raises(ParameterError) as e:
        _core.validate("pi", [2, 0], np.array([0.9, 0.0, np.nan, 0.5, 0.2]))
    assert (e.value.parameter, e.value.index) == ("thresholds", 1)
    assert np.isnan(e.value.value)


def test_bad_switching_is_out_of_range_not_not_finite():
    p = np.ones(21)
    p[6] = 2.0
    p[-1] = 100.0  # u_max > u_min
    with pytest.raises(ParameterError, match=r"switching .* = 2 must lie within \[0, 1\]"):
        _core.Controller("smc", p)


def test_controller_arrays_are_packed_by_table_names():
    stage = ph.virtual_stage()
    kind, params, _, _ = ph.PID(kp=2e6, ki=2e9, kd=10.0).core(stage)
    named = dict(zip(_core.controller_layout(kind)["slots"], params, strict=True))
    assert (named["kp"], named["ki"], named["kd"], named["ts"]) == (2e6, 2e9, 10.0, stage.sample_time)
    kind, params, _, _ = ph.SMC(stage.params, switching="super_twisting", k1=10.0, k2=1000.0).core(stage)
    named = dict(zip(_core.controller_layout(kind)["slots"], params, strict=True))
    assert (named["switching"], named["ks_or_k1"], named["phi_or_k2"]) == (1.0, 10.0, 1000.0)


@pytest.mark.parametrize(
    "model",
    [
        ph.PI([0.0, 0.2, 0.5], [1.0, 0.3, 0.1], p0=0.5),
        ph.RateDependentPI([0.0, 0.3], [0.5, 0.2], 1e-3, 1.0, 0.1, [0.0, 0.0], 0.0),
        ph.Preisach(3, (-0.5, 2.0), np.full(6, 0.1), 0.0, 1.0),
    ],
)
def test_example_input_range_reads_the_table_groups(model):
    # the C example's input range is read at the offsets of the table's groups
    from piezohyst.export.c import demo_input_range

    layout = _core.family_layout(model.family, list(model.dims))
    groups = {name: (offset, length) for name, offset, length in layout["groups"]}
    row = model.to_row()
    if model.family == "preisach":
        expected = (row[groups["lo"][0]], row[groups["hi"][0]])
    else:
        offset, length = groups["r"]
        expected = (0.0, 2 * row[offset + length - 1])
    assert demo_input_range(model) == expected
    # the slots are named as the groups say
    assert layout["slots"][groups["r" if model.family != "preisach" else "hi"][0]].startswith(
        "r[" if model.family != "preisach" else "hi"
    )


def test_example_input_range_of_gpi_reads_the_table_groups():
    from piezohyst.export.c import demo_input_range

    m = ph.GeneralizedPI([0.0, 0.4], [1.0, 0.2], (0, 1.0, 0, 0), input_range=(-0.75, 1.25))
    layout = _core.family_layout(m.family, list(m.dims))
    groups = {name: offset for name, offset, _ in layout["groups"]}
    row = m.to_row()
    assert demo_input_range(m) == (row[groups["range_lo"]], row[groups["range_hi"]]) == (-0.75, 1.25)
    # without a finite range: [0, 2 max threshold] is for the PI family only
    assert demo_input_range(ph.GeneralizedPI([0.0, 0.4], [1.0, 0.2], (0, 1.0, 0, 0))) == (-1.0, 1.0)


@pytest.mark.parametrize(
    ("family", "dims", "scratch"),
    [
        ("pi", [3, 2], 2),
        ("gpi", [3, 1, 1, 0], 0),
        ("rdpi", [2, 1], 1),
        ("creep", [3], 3),
        ("preisach", [4, 8], 10),
        ("preisach", [4, 8, 2], 12),
    ],
)
def test_scratch_len_is_the_c_librarys(family, dims, scratch):
    # Preisach: n (n + 1) / 2 prefix sums; creep lags: one gain each (what phs_model_sizes reports)
    assert _core.family_layout(family, dims)["scratch_len"] == scratch
