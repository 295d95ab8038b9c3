"""MATLAB .mat files: exact round trips (bitwise float64) of records, models (every kind),
stages and the codec itself; MATLAB-valid names; clear errors on foreign files."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import scipy.io

import piezohyst as ph
from piezohyst import Stage, load_model, virtual_stage
from piezohyst.errors import DataError, OutputExistsError, ParameterError, ParameterTypeError
from piezohyst.signals import Record, load_record
from piezohyst.signals.matfile import is_matlab_name, read_mat, write_mat
from piezohyst.signals.units import UnitConversion
from tests.models_zoo import drive, zoo


def same(a, b) -> bool:
    """Equal in type and value, floats bitwise (NaN equal to NaN, -0.0 not equal to 0.0)."""
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, dict):
        return isinstance(b, dict) and list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float):
        return type(b) is float and np.float64(a).tobytes() == np.float64(b).tobytes()
    if dataclasses.is_dataclass(a) and not isinstance(a, type):  # field by field: arrays inside
        return type(a) is type(b) and all(
            same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a) if f.compare
        )
    return type(a) is type(b) and a == b


def matlab_names(value, path="") -> list[str]:
    """Every struct field name of a loadmat() value (struct_as_record, squeeze_me off)."""
    out = []
    arr = np.asarray(value)
    if arr.dtype.names:
        for name in arr.dtype.names:
            out.append(f"{path}.{name}")
            for item in arr.ravel():
                out += matlab_names(item[name], f"{path}.{name}")
    elif arr.dtype == object:
        for item in arr.ravel():
            out += matlab_names(item, path)
    return out


def test_codec_round_trip_is_exact(tmp_path):
    value = {
        "pi": math.pi,
        "tiny": 5e-324,
        "negzero": -0.0,
        "nan": math.nan,
        "inf": -math.inf,
        "int": 3,
        "big": 2**62 + 1,
        "flag": True,
        "text": "µm — 5 % <b>",
        "empty_text": "",
        "none": None,
        "one": [0.1],
        "empty": [],
        "ints": [3, 0, -2],
        "holes": [None, 1.5],
        "pair": (1.0, 2.0),
        "strings": ["a", ""],
        "nested": {"x": {"y": [1.0, "a", None, {"z": 1}]}},
        "not_matlab_names": {"a b": 1.0, "1x": [2.0], "é": "ok"},
        "no_keys": {},
        "matrix": np.arange(6.0).reshape(2, 3) / 7,
        "column": (np.arange(4.0) / 3).reshape(-1, 1),
        "vector1": np.array([7.0]),
        "scalar_array": np.array(3.0),
        "int_array": np.arange(3, dtype=np.int32),
        "bools": np.array([True, False]),
        "empty_array": np.zeros(0),
        "complex": np.array([1 + 2j, -0.5j]),
        "f32": np.float32(1.5),
    }
    path = write_mat(tmp_path / "v.mat", "result", value)
    back = read_mat(path, "result")
    for key, expected in value.items():
        assert same(expected, back[key]), key


def test_matlab_sees_valid_names_and_natural_types(tmp_path):
    rec = Record(np.arange(5.0), np.arange(5.0) ** 2, fs=10.0, columns={"input": "u", "output": "y"})
    path = rec.to_mat(tmp_path / "rec.mat")
    raw = scipy.io.loadmat(path, squeeze_me=False, struct_as_record=True)
    assert set(k for k in raw if not k.startswith("__")) == {"record", "piezohyst"}
    names = matlab_names(raw["record"]) + matlab_names(raw["piezohyst"])
    assert names and all(is_matlab_name(n.rsplit(".", 1)[-1]) for n in names), names
    r = raw["record"][0, 0]
    assert r["input"].shape == (5, 1) and r["input"].dtype == np.float64  # a column, as MATLAB signals are
    assert r["fs"].shape == (1, 1) and r["fs"][0, 0] == 10.0
    assert r["time"].shape == (0, 0)  # [] for "none"
    assert r["columns"][0, 0]["output"][0] == "y"
    with pytest.raises(ParameterError, match="content = '1bad'"):
        write_mat(tmp_path / "bad.mat", "1bad", {})
    assert not is_matlab_name("x" * 64) and is_matlab_name("x" * 63)


@pytest.mark.parametrize("with_time", [False, True])
def test_record_round_trip_is_exact(tmp_path, with_time):
    rng = np.random.default_rng(5)
    n = 1000
    t = 0.001 * np.arange(n) + 1e-4 if with_time else None
    rec = Record(
        rng.standard_normal(n),
        rng.standard_normal(n) * 1e-6,
        fs=1000.0000000001,
        time=t,
        source="bench/run 7.csv[10:1010]",
        columns={"input": "V (mV)", "output": "x [um]", **({"time": "t"} if with_time else {})},
        units={"input": UnitConversion("mV", "V", 1e-3, "header"), "output": UnitConversion("um", "m", 1e-6, "name")},
    )
    path = rec.to_mat(tmp_path / "rec.mat")
    back = Record.from_mat(path)
    for name in ("input", "output", "time"):
        assert same(getattr(rec, name), getattr(back, name)), name
    assert same(rec.fs, back.fs) and back.source == rec.source and back.columns == rec.columns
    assert back.units == rec.units
    # the readers of measured data open it too
    loaded = load_record(path, input="record.input", output="record.output", fs=rec.fs)
    assert same(loaded.output, rec.output)
    with pytest.raises(OutputExistsError):
        rec.to_mat(path)


@pytest.mark.parametrize("kind", list(zoo()))
def test_every_model_kind_round_trips_exactly(tmp_path, kind):
    model = zoo()[kind]
    if kind in ("pi", "gpi", "preisach"):
        model = model.with_output_map(offset=0.1 + 1e-17, gain=-1.75)
    path = model.to_mat(tmp_path / f"{kind}.mat")
    back = load_model(path)
    assert type(back) is type(model) and back == model  # rows compared with array_equal
    assert back.to_row().tobytes() == model.to_row().tobytes()
    assert back.output_map == model.output_map and back.units == model.units
    u = drive(300)
    assert np.array_equal(back.simulate(u), model.simulate(u))
    raw = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)["model"]
    assert raw.kind == model.kind and raw.family == model.family and raw.schema_version == 1
    assert raw.output_map.gain == model.output_map.gain


def test_model_state_and_units_round_trip(tmp_path):
    model = ph.PI([0.0, 0.4], [1.0, 0.5], 0.2, units={"input": "V", "output": "µm"})
    model.step(0.9)
    model.step(0.3)
    path = model.to_mat(tmp_path / "pi.mat", include_state=True)
    back = load_model(path)
    assert back.state.tobytes() == model.state.tobytes() and back.units == {"input": "V", "output": "µm"}
    # save() picks the format by the suffix
    model.save(tmp_path / "pi2.mat")
    assert load_model(tmp_path / "pi2.mat") == model


def test_gpi_unbounded_range_and_boucwen_benchmark(tmp_path):
    gpi = ph.GeneralizedPI([0.1, 0.3], [1.0, 0.5], (0, 0.5, 0, 0))
    assert gpi.input_range == (-math.inf, math.inf)
    back = load_model(gpi.to_mat(tmp_path / "gpi.mat"))
    assert back == gpi and back.input_range == gpi.input_range
    from piezohyst.models import BoucWenBenchmark

    bw = BoucWenBenchmark()
    back_bw = load_model(bw.to_mat(tmp_path / "bw.mat"))
    assert isinstance(back_bw, BoucWenBenchmark) and back_bw.parameters == bw.parameters and back_bw.fs == bw.fs


def test_stage_round_trip(tmp_path):
    stage = virtual_stage()
    path = stage.to_mat(tmp_path / "stage.mat")
    back = Stage.from_file(path)
    assert back == stage
    assert back.core_params().tobytes() == stage.core_params().tobytes()
    raw = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)["stage"]
    assert raw.mechanics.mass == stage.params.mass and raw.units.mass == "kg"


def test_foreign_and_mismatched_files_are_refused(tmp_path):
    foreign = tmp_path / "foreign.mat"
    scipy.io.savemat(foreign, {"x": np.arange(3.0)})
    with pytest.raises(DataError, match="not a .mat file written by piezohyst"):
        load_model(foreign)
    not_mat = tmp_path / "text.mat"
    not_mat.write_text("hello")
    with pytest.raises(DataError, match="model file .*text.mat"):
        load_model(not_mat)
    rec = Record(np.arange(3.0), np.arange(3.0), fs=1.0)
    path = rec.to_mat(tmp_path / "rec.mat")
    with pytest.raises(DataError, match="holds a 'record', not a 'model'"):
        load_model(path)
    with pytest.raises(FileNotFoundError):
        Record.from_mat(tmp_path / "missing.mat")
    with pytest.raises(ParameterTypeError, match="object"):
        write_mat(tmp_path / "o.mat", "result", {"x": object()})
