"""The output map ``y = gain * h(v) + offset`` every model carries: simulation, stepping,
responses, the exact inverse, model files (old files load unchanged), the row layout (the
core's and the C ABI's) untouched, and the row that holds the map for the core's controllers."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

import piezohyst as ph
from piezohyst import _core
from piezohyst.errors import ParameterError, ParameterTypeError

OFFSET, GAIN = 37.25, 1.3


def _input() -> np.ndarray:
    t = np.arange(1500) / 1000.0
    return 50 + 40 * np.sin(2 * np.pi * 2 * t) * np.linspace(1, 0.3, t.size) + 4 * np.sin(2 * np.pi * 9 * t)


def models() -> dict[str, ph.HysteresisModel]:
    creep = ph.Creep(1e-3, [0.05, 0.5], [0.01, 0.02])
    return {
        "pi": ph.PI([4.0, 12.0, 25.0], [0.3, 0.2, 0.1], p0=0.5, creep=creep),
        "gpi": ph.GeneralizedPI([0.0, 8.0, 20.0], [0.5, 0.2, 0.1], [0.1, 0.05, 1e-4, 1e-6]),
        "rdpi": ph.RateDependentPI([4.0, 12.0], [0.3, 0.2], 1e-3, 0.5, 1e-4, [1e-4, 2e-4]),
        "preisach": ph.Preisach(6, (0.0, 100.0), np.linspace(0.1, 1.0, 21), 0.5, 0.2),
        "boucwen": ph.BoucWen(a=1.0, beta=0.05, gamma=0.01, d=0.8),
    }


@pytest.mark.parametrize("kind", list(models()))
def test_simulate_step_and_response_apply_the_map(kind):
    model = models()[kind]
    v = _input()
    h = model.simulate(v)
    mapped = model.with_output_map(offset=OFFSET, gain=GAIN)
    y = mapped.simulate(v)
    assert np.array_equal(y, GAIN * h + OFFSET)
    assert np.array_equal(mapped.response(v, fs=1000.0).output, y)
    assert np.array_equal([mapped.step(x) for x in v[:50]], y[:50])
    # the model itself is unchanged, and the row (the core's layout, the C ABI) is the same
    assert np.array_equal(model.simulate(v), h) and model.output_map.is_identity
    assert np.array_equal(mapped.to_row(), model.to_row()) and mapped.dims == model.dims
    assert _core.family_sizes(mapped.family, list(mapped.dims)) == _core.family_sizes(model.family, list(model.dims))


@pytest.mark.parametrize("kind", list(models()))
def test_inverse_of_forward_is_the_identity_with_a_map(kind):
    v = _input()
    mapped = models()[kind].with_output_map(offset=OFFSET, gain=GAIN)
    y = mapped.simulate(v)
    inv = mapped.inverse()
    v_back = inv.simulate(y)
    assert np.max(np.abs(mapped.simulate(v_back) - y)) < 1e-9 * np.ptp(y)
    # the input found is the family's inverse of the unmapped output; it is v where the
    # family is strictly increasing (the rate-dependent PI and this Bouc-Wen are not)
    reference = models()[kind].inverse().simulate(models()[kind].simulate(v))
    assert np.max(np.abs(v_back - reference)) < 1e-6 * np.ptp(v)
    if kind in ("pi", "gpi", "preisach"):
        assert np.max(np.abs(v_back - v)) < 1e-6 * np.ptp(v)
    stepped = np.array([inv.step(x) for x in y[:200]])
    assert np.max(np.abs(stepped - reference[:200])) < 1e-6 * np.ptp(v)
    assert np.array_equal(inv.response(y).input, v_back)
    # a negative gain (an inverted sensor) is inverted as exactly
    flipped = models()[kind].with_output_map(offset=-OFFSET, gain=-GAIN)
    y_flipped = flipped.simulate(v)
    assert np.max(np.abs(flipped.simulate(flipped.inverse().simulate(y_flipped)) - y_flipped)) < 1e-9 * np.ptp(y)


def test_identity_map_is_bit_for_bit_and_files_without_a_map_are_unchanged(tmp_path):
    model = models()["pi"]
    d = model.to_dict()
    assert "output_map" not in d  # files written today keep their exact content
    assert model.with_output_map(offset=0.0, gain=1.0).to_json() == model.to_json()
    # a file written before the map existed loads with the identity
    old = {"schema_version": 1, "kind": "pi", "parameters": {"thresholds": [1.0], "weights": [0.5], "p0": 1.0}}
    loaded = ph.model_from_dict(old)
    assert loaded.output_map == ph.OutputMap() and loaded.simulate([0.0, 2.0]).tolist() == [0.0, 2.5]
    # absent keys take the identity's values
    assert ph.model_from_dict({**old, "output_map": {"offset": 3.0}}).output_map == ph.OutputMap(3.0, 1.0)
    assert ph.model_from_dict({**old, "output_map": {"gain": 2.0}}).simulate([2.0]).tolist() == [5.0]


@pytest.mark.parametrize("kind", list(models()))
def test_model_files_carry_the_map(tmp_path, kind):
    mapped = models()[kind].with_output_map(offset=OFFSET, gain=GAIN)
    path = mapped.save(tmp_path / "m.json")
    assert json.loads(path.read_text())["output_map"] == {"offset": OFFSET, "gain": GAIN}
    back = ph.load_model(path)
    assert back == mapped and back != models()[kind]
    v = _input()
    assert np.array_equal(back.simulate(v), mapped.simulate(v))
    assert np.array_equal(pickle.loads(pickle.dumps(mapped)).simulate(v), mapped.simulate(v))
    assert "output_map=(offset=37.25, gain=1.3)" in repr(mapped)


@pytest.mark.parametrize(
    ("output_map", "error", "match"),
    [
        ({"offset": 1.0, "gain": 0.0}, ParameterError, "gain = 0.0 must be non-zero"),
        ({"offset": float("nan")}, ParameterError, "output_map.offset"),
        ({"gain": float("inf")}, ParameterError, "output_map.gain"),
        ({"ofset": 1.0}, ParameterError, "unknown keys \\['ofset'\\]"),
        ([1.0, 2.0], ParameterTypeError, "output_map must be"),
    ],
)
def test_bad_maps_are_named(output_map, error, match):
    old = {"schema_version": 1, "kind": "pi", "parameters": {"thresholds": [1.0], "weights": [0.5]}}
    with pytest.raises(error, match=match):
        ph.model_from_dict({**old, "output_map": output_map})


def test_with_output_map_arguments():
    m = models()["pi"]
    assert m.with_output_map(ph.OutputMap(1.0, 2.0)) == m.with_output_map({"offset": 1.0, "gain": 2.0})
    assert m.with_output_map(offset=1.0, gain=2.0) == m.with_output_map(ph.OutputMap(1.0, 2.0))
    assert m.with_output_map(offset=1.0).with_output_map(None) == m
    with pytest.raises(ParameterTypeError, match="not both"):
        m.with_output_map(ph.OutputMap(1.0), gain=2.0)


def test_analytic_inverses_refuse_a_map():
    with pytest.raises(ParameterError, match="analytic inverse does not cover it"):
        ph.PI([0.5], [1.0], p0=1.0).with_output_map(offset=1.0).analytic_inverse()
    with pytest.raises(ParameterError, match="analytic inverse does not cover it"):
        ph.GeneralizedPI([0.0, 0.5], [1.0, 0.5]).with_output_map(gain=2.0).analytic_inverse()


@pytest.mark.parametrize(
    ("kind", "offset", "gain", "family"),
    [
        ("pi", OFFSET, GAIN, "gpi"),  # a PI with an offset is the equal GPI (identity envelopes)
        ("pi", 0.0, GAIN, "gpi"),
        ("gpi", OFFSET, -GAIN, "gpi"),
        ("rdpi", 0.0, GAIN, "rdpi"),
        ("preisach", OFFSET, GAIN, "preisach"),
        ("boucwen", 0.0, GAIN, "boucwen"),
    ],
)
def test_mapped_row_holds_the_map(kind, offset, gain, family):
    mapped = models()[kind].with_output_map(offset=offset, gain=gain)
    folded = mapped.mapped_row()
    assert folded.family == family and folded.output_map.is_identity
    v = _input()
    y = mapped.simulate(v)
    assert np.max(np.abs(folded.simulate(v) - y)) < 1e-12 * np.max(np.abs(y))
    assert models()[kind].mapped_row() is models()[kind] or models()[kind].output_map.is_identity


@pytest.mark.parametrize(("kind", "gain"), [("rdpi", GAIN), ("boucwen", GAIN), ("preisach", -1.0)])
def test_mapped_row_names_maps_a_family_cannot_hold(kind, gain):
    mapped = models()[kind].with_output_map(offset=OFFSET, gain=gain)
    with pytest.raises(ParameterError, match=f"cannot be held in the parameter row of a {kind} model"):
        mapped.mapped_row()
