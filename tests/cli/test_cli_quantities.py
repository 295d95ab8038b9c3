"""Wrong quantities on the command line (issue 20, item 8): a model of another actuator given
to ``track``, a model file a controller does not use, digit separators in numbers, a fit
from too few samples, a --validate file that is the training data."""

from __future__ import annotations

import contextlib
import io
import json
import os
from pathlib import Path

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.cli import main


def cli(argv, cwd):
    """``main(argv)`` in ``cwd``: (exit code, stdout, stderr); argparse's exits included."""
    out, err, here = io.StringIO(), io.StringIO(), os.getcwd()
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main([str(a) for a in argv])
            except SystemExit as e:
                code = e.code
    finally:
        os.chdir(here)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """Models identified on the virtual stage's voltage -> position (shifted one sample, as
    track's own), and the same record in other quantities."""
    d = tmp_path_factory.mktemp("models")
    stage = ph.virtual_stage()
    fs = 1 / stage.sample_time
    t = np.arange(int(1.0 * fs)) / fs
    u = 75 - 75 * np.clip(1 - 0.5 * t, 0.2, 1.0) * np.cos(2 * np.pi * 5 * t)
    x = stage.simulate(u).position
    records = {
        "own": (u[:-1], x[1:]),
        "offset": (u[:-1], x[1:] + 1e-3),  # a sensor 1 mm off: same span, another range
        "gain": (u[:-1], 1.5 * x[1:]),  # span 1.5x: inside the 3x span check
        "kilovolts": (u[:-1] / 1000, x[1:]),  # identified on kV
        "unitless": (u[:-1], x[1:] / np.ptp(x)),  # normalized output
    }
    for name, (v, y) in records.items():
        ph.identify_mpi(v, y).model.save(d / f"{name}.json")
    own = ph.identify_mpi(u[:-1], x[1:]).model
    _save_with_units(own, d / "um_unit.json", {"input": "V", "output": "um"})  # numbers in m, unit says um
    _save_with_units(own, d / "mv_input.json", {"input": "mV", "output": "m"})
    (d / "broken.json").write_text('{"schema_version": 1, "kind": "pi", "parameters": ')
    return d


def _save_with_units(model, path: Path, units: dict[str, str]) -> None:
    doc = model.to_dict()
    doc["units"] = units
    path.write_text(json.dumps(doc))


TRACK = ("track", "--controller", "inverse", "--duration", "0.3", "--skip", "0.1", "--json", "--model")


def test_a_model_of_this_stage_passes(models):
    code, out, err = cli([*TRACK, "own.json"], models)
    assert code == 0, err
    assert "model_check" not in json.loads(out)
    assert json.loads(out)["metrics"]["rmse_percent"] < 2.0  # measured 0.77 %


@pytest.mark.parametrize(
    ("name", "says"),
    [
        ("offset", ["differ by", "the reference [3e-06, 1.3e-05] m is outside the model's output", "no output unit"]),
        ("gain", ["differ by", "of the stage's range (RMS)"]),
        ("unitless", ["span 1.0", "4.81e+04x"]),
        ("um_unit", ["its output unit is 'um', the stage's position is in m"]),
        ("mv_input", ["its input unit is 'mV', the stage's amplifier takes V"]),
    ],
)
def test_a_model_of_another_actuator_exits_3_naming_units_and_ranges(models, name, says):
    code, out, err = cli([*TRACK, f"{name}.json"], models)
    assert code == 3, (name, err)
    line = err.strip().splitlines()[-1]
    assert line.startswith("piezohyst track: not trustworthy: --model looks like a model of another actuator")
    for s in says:
        assert s in line, (name, line)
    check = json.loads(out)["model_check"]
    assert check["foreign"] and check["reasons"]
    lo, hi = check["stage_position_range"]
    assert lo == pytest.approx(0.0, abs=1e-7) and hi == pytest.approx(2.135e-5, rel=0.01)
    assert set(check["units"]) == {"input", "output"} and len(check["model_output_range"]) == 2


def test_gain_and_offset_used_to_pass_silently(models):
    """Before: the 3x span check alone let a 1.5x gain and a 1 mm offset through with exit 0
    (tracking errors of tens of % and over 100 % of range)."""
    for name, worst in (("gain", 20.0), ("offset", 90.0)):
        code, out, _err = cli([*TRACK, f"{name}.json"], models)
        assert code == 3
        assert json.loads(out)["metrics"]["rmse_percent"] > worst  # the run is still made and reported
        assert json.loads(out)["model_check"]["mismatch_percent"] > 10.0


def test_a_model_that_cannot_drive_the_stage_is_one_line_naming_why(models):
    code, _out, err = cli([*TRACK, "kilovolts.json"], models)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert "cannot drive this stage" in lines[0] and "another actuator" in lines[0] and "over 0..150 V" in lines[0]


@pytest.mark.parametrize("controller", ["pid", "smc", "open-loop", "inverse"])
def test_a_broken_model_file_is_an_error_with_every_controller(models, controller):
    code, _out, err = cli(["track", "--controller", controller, "--duration", "0.05", "--model", "broken.json"], models)
    assert code == 2, err
    assert err.strip().splitlines() == [
        "piezohyst track: error: model file 'broken.json' is not valid JSON: Expecting value: line 1 column 51 "
        "(char 50)"
    ]


def test_a_model_the_controller_does_not_use_is_read_and_named(models):
    code, _out, err = cli(
        ["track", "--controller", "pid", "--duration", "0.05", "--skip", "0.01", "--model", "own.json"], models
    )
    assert code == 0
    assert "warning: --model = 'own.json' is not used by --controller pid" in err


# ---------------------------------------------------------------------------- numbers


@pytest.mark.parametrize(
    "argv",
    [
        ["track", "--controller", "pid", "--duration", "1_0"],
        ["track", "--controller", "pid", "--freq", "1_0.5"],
        ["track", "--controller", "pid", "--seed", "1_0"],
        ["track", "--controller", "pid", "--amp", "\u0661"],  # ARABIC-INDIC DIGIT ONE: float() takes it
        ["identify", "d.csv", "--fs", "1_000"],
        ["identify", "d.csv", "--fs", "1000", "--operators", "1_0"],
        ["identify", "d.csv", "--fs", "1000", "--time-tolerance", "0_1"],
        ["simulate", "m.json", "d.csv", "--fs", "1_000"],
        ["export-c", "m.json", "--steps", "1_00"],
    ],
)
def test_digit_separators_and_other_digits_are_not_numbers(tmp_path, argv):
    code, _out, err = cli(argv, tmp_path)
    assert code == 2
    assert "is not a number" in err or "is not an integer" in err, err
    assert "digit separators '_' are not accepted" in err or "digits 0-9 only" in err, err


def test_integers_inside_option_values_are_strict(tmp_path):
    v = np.sin(np.linspace(0, 20, 500))
    np.savetxt(tmp_path / "d.csv", np.c_[v, v], delimiter=",", header="input,output", comments="")
    base = ["identify", "d.csv", "--fs", "1000", "--model", "pi", "--out", "m.json"]
    for option, value in (("--lag", "1_0"), ("--lag", "auto:1_0"), ("--lead-in", "1_0"), ("--periodic", "1_0")):
        code, _out, err = cli([*base, option, value], tmp_path)
        assert code == 2 and f"{option} = '{value}'" in err, err
        assert "digit separators" in err
    code, _out, err = cli([*base, "--lead-in", "-3"], tmp_path)  # a count: no sign
    assert code == 2 and "--lead-in = '-3' must be 'auto', 'none' or a number of samples" in err, err
    # ASCII digits only for a column index: '\u0661' is a (missing) column name, not index 1
    code, _out, err = cli([*base, "--input", "\u0661"], tmp_path)
    assert code == 2 and "is not a column" in err


# ------------------------------------------------------------------ identifiability


def test_a_fit_from_too_few_samples_is_refused(tmp_path):
    np.savetxt(tmp_path / "two.csv", [[0.1, 0.2], [0.5, 0.4]], delimiter=",", header="input,output", comments="")
    code, _out, err = cli(["identify", "two.csv", "--fs", "100", "--model", "pi", "--out", "m.json"], tmp_path)
    assert code == 2
    assert err.strip() == (
        "piezohyst identify: error: the training record has 2 samples, too few to fit the 11 parameters of a PI "
        "model of 9 operators: a fit needs at least 10 samples per parameter (110); give a longer record or fewer "
        "operators"
    )
    assert not (tmp_path / "m.json").exists()


# ---------------------------------------------------------------- --validate = DATA


@pytest.fixture
def record_files(tmp_path):
    t = np.arange(3000) / 1000
    v = 0.5 + 0.4 * np.sin(2 * np.pi * 5 * t) * np.linspace(1, 0.3, 3000)
    y = ph.papers.mpi_seed2().simulate(v)
    np.savetxt(tmp_path / "r.csv", np.c_[t, v, y], delimiter=",", header="t,v,y", comments="")
    np.savez(tmp_path / "r.npz", t=t, v=v, y=y)
    np.savez(tmp_path / "span.npz", t=t[:1000], v=v[:1000], y=y[:1000])
    np.savez(tmp_path / "held_out.npz", t=t[2000:], v=v[2000:], y=y[2000:])
    (tmp_path / "copy.csv").write_bytes((tmp_path / "r.csv").read_bytes())
    (tmp_path / "link.csv").symlink_to(tmp_path / "r.csv")
    return tmp_path


@pytest.mark.parametrize(
    ("validate", "train", "why"),
    [
        ("r.csv", None, "is DATA itself (the same file)"),
        ("link.csv", None, "is DATA itself (the same file)"),
        ("copy.csv", None, "is a byte-identical copy of DATA"),
        ("r.csv", "0:1000", "is DATA itself (the same file)"),
        ("r.npz", None, "holds the same samples as DATA"),
        ("span.npz", "0:1000", "holds the same samples as the training span"),
    ],
)
def test_validating_on_the_training_data_warns(record_files, validate, train, why):
    argv = ["identify", "r.csv", "--time", "t", "--input", "v", "--output", "y", "--model", "mpi", "--json"]
    argv += ["--validate", validate, "--out", "m.json"] + ([] if train is None else ["--train", train])
    code, out, err = cli(argv, record_files)
    assert code in (0, 3), err
    assert f"piezohyst identify: warning: --validate = '{validate}' {why}: the training span" in err
    assert "the validation is not independent of the training" in err
    where = json.loads(out)["data"]["validation"]
    assert where["independent"] is False and where["warning"].startswith(why)
    assert where["samples"] == (1000 if validate == "span.npz" else 3000)


def test_held_out_validation_file_does_not_warn(record_files):
    argv = ["identify", "r.csv", "--time", "t", "--input", "v", "--output", "y", "--model", "mpi", "--json"]
    code, out, err = cli([*argv, "--train", "0:2000", "--validate", "held_out.npz", "--out", "m.json"], record_files)
    assert code in (0, 3) and "warning" not in err
    assert "independent" not in json.loads(out)["data"]["validation"]


# ------------------------------------------------------------------------ extremes


@pytest.mark.parametrize(("scale", "says"), [(1e301, "reaches 1.11e+301"), (1e-310, "spans 9.27e-311")])
def test_an_extreme_record_is_one_line_without_warnings(tmp_path, scale, says):
    t = np.arange(2000) / 1000
    v = 0.5 + 0.4 * np.sin(2 * np.pi * 5 * t)
    y = ph.papers.mpi_seed2().simulate(v)
    np.savetxt(tmp_path / "x.csv", np.c_[t, v, y * scale], delimiter=",", header="t,v,y", comments="")
    for kind in ("pi", "mpi", "preisach", "boucwen"):
        argv = ["identify", "x.csv", "--time", "t", "--model", kind, "--out", "m.json", "--iterations", "2"]
        code, _out, err = cli(argv, tmp_path)
        assert code == 2, (kind, err)
        assert err.count("\n") == 1 and "Warning" not in err, err
        assert f"output {says}" in err and "rescale the record" in err, err


def test_simulate_summarizes_values_near_the_largest_double(tmp_path):
    model = ph.PI([0.0], [1.0], p0=0.0)  # the identity: the output is the input
    model.save(tmp_path / "m.json")
    v = np.array([9e307, 9e307, -9e307, 8e307, 9e307])  # their sum and their range exceed 1.8e308
    np.savetxt(tmp_path / "x.csv", np.c_[v], delimiter=",", header="v", comments="")
    argv = ["simulate", "m.json", "x.csv", "--input", "v", "--fs", "1", "--out", "o.csv", "--json"]
    code, out, err = cli(argv, tmp_path)
    assert code == 0, err
    summary = json.loads(out)["output"]
    assert summary["range"] is None  # 3.4e308 is beyond the largest double: null, not an error
    assert summary["mean"] == pytest.approx(np.mean(v / 1e308) * 1e308)
    assert summary["min"] == -9e307 and summary["max"] == 9e307
