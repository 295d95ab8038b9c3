"""Model files: JSON round trips are bit-identical; nothing is overwritten by accident."""

import json

import numpy as np
import pytest

import piezohyst as ph
from tests.models_zoo import drive, zoo

ZOO = zoo()


@pytest.mark.parametrize("name", list(ZOO))
def test_save_load_simulate_is_bit_identical(name, tmp_path):
    m = ZOO[name]
    path = m.save(tmp_path / f"{name}.json")
    loaded = ph.load_model(path)
    assert type(loaded) is type(m)
    assert loaded == m
    v = drive()
    assert np.array_equal(loaded.simulate(v), m.simulate(v))
    d = json.loads(path.read_text())
    assert d["schema_version"] == ph.SCHEMA_VERSION and d["kind"] == m.kind


def test_state_is_saved_when_asked(tmp_path):
    m = ph.PI([0.1, 0.5], [0.3, 0.2])
    for x in [0.0, 1.0, 0.4]:
        m.step(x)
    loaded = ph.load_model(m.save(tmp_path / "m.json", include_state=True))
    assert np.array_equal(loaded.state, m.state)
    assert loaded.step(0.7) == m.step(0.7)


def test_existing_file_is_not_overwritten(tmp_path):
    path = tmp_path / "m.json"
    path.write_text("precious")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        ph.PI([0.1], [0.2]).save(path)
    assert path.read_text() == "precious"
    ph.PI([0.1], [0.2]).save(path, overwrite=True)
    assert ph.load_model(path) == ph.PI([0.1], [0.2])


@pytest.mark.parametrize(
    "text,message",
    [
        ("{", "not valid JSON"),
        ("[]", "must be a JSON object"),
        ('{"schema_version": 99, "kind": "pi", "parameters": {}}', "schema_version = 99"),
        ('{"schema_version": 1, "kind": "nope", "parameters": {}}', "kind = 'nope' is unknown"),
        (
            '{"schema_version": 1, "kind": "pi", "parameters": {"thresholds": [0.2, 0.1], "weights": [1, 1]}}',
            r"thresholds\[1\] = 0.1",
        ),
        (
            '{"schema_version": 1, "kind": "pi", "parameters": {"thresholds": [0.1], "wrong": [1]}}',
            "parameters of kind 'pi' are not valid",
        ),
    ],
)
def test_bad_model_files_raise_clear_errors(tmp_path, text, message):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises((ValueError, TypeError), match=message):
        ph.load_model(path)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        ph.load_model(tmp_path / "nothing.json")
