"""Hostile JSON files (issue 20, item 6): model, stage and controller files read through one
home (``piezohyst._io.read_json_file``). Each case is a ``DataError`` naming the file and, for a value,
the field's path; on the command line one stderr line and exit 2 — never a ``RecursionError``
traceback, a bare ``ValueError`` or a value taken for another (``true`` for 1)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import piezohyst as ph
from piezohyst._io import MAX_JSON_DEPTH, nesting_depth, parse_json, printable
from piezohyst.export_c import load_controller, save_controller

ROOT = Path(__file__).resolve().parents[1]
MODEL = ph.papers.mpi_seed2()
STAGE_TEXT = (Path(ph.__file__).parent / "presets" / "virtual_stage.json").read_text()
DEEP = "[" * 100_000 + "]" * 100_000


def _cli(*argv: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
    return subprocess.run(
        [sys.executable, "-m", "piezohyst", *argv], cwd=cwd, env=env, capture_output=True, text=True, timeout=120
    )


@pytest.fixture
def files(tmp_path):
    model = json.loads(MODEL.to_json())
    controller = tmp_path / "c.json"
    save_controller(ph.PID(kp=2e6, ki=2e9), ph.virtual_stage(), controller)
    t = np.arange(400) / 1000.0
    np.savetxt(tmp_path / "x.csv", np.c_[t, 0.5 + 0.4 * np.sin(2 * np.pi * 5 * t)], delimiter=",", header="t,v")
    return tmp_path, model, json.loads(controller.read_text())


def _write(d: Path, name: str, text: str) -> Path:
    p = d / name
    p.write_text(text)
    return p


# ----------------------------------------------------------------------------- nesting


def test_depth_is_counted_outside_strings_and_bounded():
    assert nesting_depth('{"a": [[1, 2], {"b": "[[[[{{"}]}') == 3
    assert nesting_depth("[]") == 1 and nesting_depth("1") == 0
    assert nesting_depth(DEEP) == 100_000
    assert nesting_depth(MODEL.to_json()) == 4  # parameters.rising.coefficients
    with pytest.raises(
        ph.DataError, match=rf"x: arrays/objects nested too deeply \(100000 levels, at most {MAX_JSON_DEPTH}\)"
    ):
        parse_json(DEEP, "x")
    # exactly the bound parses
    assert parse_json("[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH, "x") == json.loads(
        "[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH
    )


@pytest.mark.parametrize("text", [DEEP, '{"a":' * 50_000 + "1" + "}" * 50_000, "[" * 200_000])
def test_deep_nesting_is_a_data_error_in_every_reader(tmp_path, text):
    p = _write(tmp_path, "deep.json", text)
    for read, what in (
        (ph.load_model, "model file"),
        (ph.Stage.from_file, "stage file"),
        (load_controller, "controller file"),
    ):
        with pytest.raises(ph.DataError, match=rf"{what} '.*deep\.json': arrays/objects nested too deeply"):
            read(p)


def test_deep_nesting_on_the_command_line(files):
    d, _model, _c = files
    _write(d, "deep.json", DEEP)
    runs = {
        "simulate": ("simulate", "deep.json", "x.csv", "--input", "1", "--fs", "1000", "--out", "s.csv"),
        "export-c": ("export-c", "deep.json", "--out", "cdir"),
        "track --model": ("track", "--controller", "inverse", "--model", "deep.json", "--duration", "0.05"),
        "track --stage": ("track", "--controller", "pid", "--stage", "deep.json", "--duration", "0.05"),
        "stage info": ("stage", "info", "--stage", "deep.json"),
    }
    for label, argv in runs.items():
        r = _cli(*argv, cwd=d)
        assert r.returncode == 2, (label, r.stderr)
        assert "Traceback" not in r.stderr and "RecursionError" not in r.stderr, (label, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "deep.json" in lines[0] and "nested too deeply" in lines[0], (label, r.stderr)


# ----------------------------------------------------------------------------- numbers


def test_a_5001_digit_integer_is_named_by_its_field(files):
    d, model, _c = files
    text = json.dumps(model).replace(json.dumps(model["parameters"]["weights"][2]), "9" * 5001, 1)
    p = _write(d, "m.json", text)
    with pytest.raises(ph.DataError, match=r"m\.json': parameters\.weights\[2\] = <5001-digit integer>: out of range"):
        ph.load_model(p)
    r = _cli("export-c", "m.json", "--out", "cdir", cwd=d)
    assert r.returncode == 2 and "parameters.weights[2] = <5001-digit integer>" in r.stderr, r.stderr
    stage = _write(d, "s.json", STAGE_TEXT.replace('"mass": 0.0714', '"mass": -' + "1" * 5001))
    with pytest.raises(ph.DataError, match=r"mechanics\.mass = <5001-digit integer>"):
        ph.Stage.from_file(stage)
    # 309 digits (1e308) is a number: refused by the model for its value, not by the reader
    ok = _write(d, "ok.json", json.dumps(model).replace('"schema_version": 1', '"schema_version": 1' + "0" * 300))
    with pytest.raises(ph.DataError, match=r"schema_version = 1000.* is not supported"):
        ph.load_model(ok)


@pytest.mark.parametrize(
    ("literal", "message"),
    [
        ("NaN", "NaN: not a finite number"),
        ("Infinity", "Infinity: not a finite number"),
        ("-Infinity", "-Infinity: not a finite number"),
        ("1e999", "1e999: overflows a double"),
        ("-2e400", "-2e400: overflows a double"),
    ],
)
def test_non_finite_literals_are_refused_with_the_field_path(files, literal, message):
    d, model, c = files
    text = json.dumps(model).replace(json.dumps(model["parameters"]["thresholds"][4]), literal, 1)
    with pytest.raises(ph.DataError, match=rf"parameters\.thresholds\[4\] = {message}"):
        ph.load_model(_write(d, "m.json", text))
    stage = STAGE_TEXT.replace('"bandwidth": 3000.0', f'"bandwidth": {literal}')
    with pytest.raises(ph.DataError, match=rf"amplifier\.bandwidth = {message}"):
        ph.Stage.from_file(_write(d, "s.json", stage))
    ctext = json.dumps(c).replace('"kp": 2000000.0', f'"kp": {literal}')
    with pytest.raises(ph.DataError, match=rf"params\.kp = {message}"):
        load_controller(_write(d, "c2.json", ctext))


# ------------------------------------------------------------------------------- types


@pytest.mark.parametrize("value", [True, 1.0, "1", None, [1]])
def test_schema_version_must_be_the_integer_1(files, value):
    d, model, c = files
    for doc, read, name in (
        (model, ph.load_model, "m.json"),
        (json.loads(STAGE_TEXT), ph.Stage.from_file, "s.json"),
        (c, load_controller, "c.json"),
    ):
        doc = {**doc, "schema_version": value}
        shown = re.escape(json.dumps(value))
        with pytest.raises(ph.DataError, match=rf"{name}': schema_version = {shown} is not supported"):
            read(_write(d, name, json.dumps(doc)))


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (("parameters", "weights", 1), True, r"parameters\.weights\[1\] = true is a boolean, expected a number"),
        (("parameters", "weights", 0), "0.2", r'parameters\.weights\[0\] = "0\.2" is a string, expected a number'),
        (("parameters", "thresholds"), "abc", r'parameters\.thresholds = "abc" is a string, expected a number'),
        (("parameters", "polynomial", 3), {"a": 1}, r"parameters\.polynomial\[3\] = \{.*\} is a JSON object"),
        (("parameters", "rising", "kind"), True, r"parameters\.rising\.kind = true is neither a name"),
        (("parameters", "rising", "coefficients", 0), False, r"parameters\.rising\.coefficients\[0\] = false"),
        (("output_map", "gain"), True, r"output_map\.gain = true is a boolean"),
        (("state", 0), "x", r'state\[0\] = "x" is a string'),
    ],
)
def test_wrong_types_are_named_by_field_path(files, path, value, message):
    d, model, _c = files
    doc = json.loads(json.dumps(model))
    doc["output_map"] = {"offset": 0.0, "gain": 1.0}
    doc["state"] = MODEL.initial_state().tolist() if hasattr(MODEL, "initial_state") else MODEL.state.tolist()
    node = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    with pytest.raises(ph.DataError, match=rf"m\.json': {message}"):
        ph.load_model(_write(d, "m.json", json.dumps(doc)))


def test_stage_sections_hold_numbers(files):
    d, _m, _c = files
    doc = json.loads(STAGE_TEXT)
    doc["sensor"]["delay"] = True
    with pytest.raises(ph.DataError, match=r"sensor\.delay = true is a boolean, expected a number"):
        ph.Stage.from_file(_write(d, "s.json", json.dumps(doc)))
    doc = json.loads(STAGE_TEXT)
    doc["creep"]["taus"][2] = "1"
    with pytest.raises(ph.DataError, match=r'creep\.taus\[2\] = "1" is a string'):
        ph.Stage.from_file(_write(d, "s.json", json.dumps(doc)))
    doc = json.loads(STAGE_TEXT)
    doc["amplifier"]["bandwidth"] = "inf"  # the documented spelling of an ideal amplifier
    assert ph.Stage.from_file(_write(d, "s.json", json.dumps(doc))).amplifier.bandwidth == np.inf


# ----------------------------------------------------------------------------- strings


@pytest.mark.parametrize("unit", ["m\x1b[31m", "\x1b[2J", "m\n", "m\r", "\x07", "\x9b31m", "m\u202e", "\x7f"])
def test_control_characters_in_strings_are_refused(files, unit):
    d, model, _c = files
    doc = {**model, "units": {"input": "V", "output": unit}}
    with pytest.raises(ph.DataError, match=r"units\.output = .* holds the control character U\+"):
        ph.load_model(_write(d, "m.json", json.dumps(doc)))
    # the same through the API: a unit is plain text
    with pytest.raises(ph.ParameterError, match=r"units\['output'\] = .* holds a control character"):
        ph.PI([0.1], [1.0], units={"input": "V", "output": unit})
    stage = json.loads(STAGE_TEXT)
    stage["name"] = "stage " + unit
    with pytest.raises(ph.DataError, match=r"name = .* holds the control character"):
        ph.Stage.from_file(_write(d, "s.json", json.dumps(stage)))
    # a key is a string too
    doc = {**model, "units": {"in" + unit: "V"}}
    with pytest.raises(ph.DataError, match=r"\(key\) = .* holds the control character"):
        ph.load_model(_write(d, "m.json", json.dumps(doc)))


def test_a_control_character_never_reaches_the_terminal(files):
    d, model, _c = files
    doc = {**model, "units": {"input": "V", "output": "\x1b[2J\x1b[31mm"}}
    _write(d, "m.json", json.dumps(doc))
    for argv in (
        ("simulate", "m.json", "x.csv", "--input", "1", "--fs", "1000", "--out", "s.csv"),
        ("track", "--controller", "inverse", "--model", "m.json", "--duration", "0.05"),
        ("export-c", "m.json", "--out", "cdir"),
    ):
        r = _cli(*argv, cwd=d)
        assert r.returncode == 2, r.stderr
        assert "\x1b" not in r.stdout + r.stderr and "\\u001b" in r.stderr, r.stderr
    # any message printed by the CLI has its control characters escaped
    assert printable("a\x1b[31mb\u202ec") == "a\\x1b[31mb\\u202ec"
    r = _cli("simulate", "m.json", "no\x1b[31mfile.csv", "--input", "1", "--fs", "1000", cwd=d)
    assert r.returncode == 2 and "\x1b" not in r.stderr and "\\x1b[31m" in r.stderr, r.stderr


# --------------------------------------------------------------------------- the file


def test_size_is_bounded_before_reading(files, monkeypatch):
    d, model, _c = files
    p = _write(d, "m.json", json.dumps(model))
    size = p.stat().st_size
    monkeypatch.setenv("PIEZOHYST_MAX_JSON_BYTES", str(size - 1))
    with pytest.raises(
        ph.DataError, match=rf"has {size:,} bytes, over the limit of {size - 1:,} bytes.*PIEZOHYST_MAX_JSON_BYTES"
    ):
        ph.load_model(p)
    monkeypatch.setenv("PIEZOHYST_MAX_JSON_BYTES", str(size))
    assert ph.load_model(p) == MODEL
    monkeypatch.setenv("PIEZOHYST_MAX_JSON_BYTES", "1_000")
    with pytest.raises(ph.ParameterError, match=r"PIEZOHYST_MAX_JSON_BYTES = '1_000' must be a whole number"):
        ph.load_model(p)


def test_only_regular_files_are_read(tmp_path):
    with pytest.raises(ph.DataError, match=r"'/dev/zero' is not a regular file"):
        ph.load_model("/dev/zero")
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    t0 = time.perf_counter()
    with pytest.raises(ph.DataError, match=r"fifo\.json' is not a regular file"):
        ph.Stage.from_file(fifo)  # never opened: no writer, no hang
    assert time.perf_counter() - t0 < 5
    with pytest.raises(ph.DataError, match="is a directory"):
        load_controller(tmp_path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        ph.load_model(tmp_path / "missing.json")


def test_a_large_valid_model_still_loads_quickly(tmp_path):
    model = ph.Preisach(400, (0.0, 1.0), np.random.default_rng(1).random(400 * 401 // 2))
    p = model.save(tmp_path / "big.json")
    assert p.stat().st_size > 1_000_000
    t0 = time.perf_counter()
    loaded = ph.load_model(p)
    assert time.perf_counter() - t0 < 2.0
    assert loaded == model
