"""Quantities on the command line take unit suffixes (issue 17, item 2): SI inside, a bare number
keeps its documented unit, a bad suffix is one line naming the argument and the value."""

import json
import subprocess
import sys

import numpy as np
import pytest

from piezohyst.errors import ParameterError
from piezohyst.signals.units import parse_quantity


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "piezohyst", *args], cwd=cwd, capture_output=True, text=True)


@pytest.mark.parametrize(
    "text,unit,si",
    [
        ("5", "um", 5e-6),
        ("5um", "um", 5e-6),
        ("5µm", "um", 5e-6),
        ("5 μm", "um", 5e-6),
        ("0.005mm", "um", 5e-6),
        ("5000nm", "um", 5e-6),
        ("1e-5m", "um", 1e-5),
        ("10", "Hz", 10.0),
        ("1kHz", "Hz", 1000.0),
        ("2.5MHz", "Hz", 2.5e6),
        ("150V", "V", 150.0),
        ("500mV", "V", 0.5),
        ("2ms", "s", 0.002),
        ("2", "s", 2.0),
        ("250us", "s", 250e-6),
        ("1800nF", "F", 1.8e-6),
        ("-3um", "um", -3e-6),
    ],
)
def test_parse_quantity_gives_si(text, unit, si):
    assert parse_quantity(text, unit) == si  # exact: the decimal is scaled once, as Python reads 5e-6


@pytest.mark.parametrize(
    "text,unit,message",
    [
        ("5kg", "um", "--x = '5kg': 'kg' is not a unit of length"),
        ("5s", "um", "--x = '5s': 's' is a unit of time, not of length"),
        ("1kHz", "s", "'kHz' is a unit of frequency, not of time"),
        ("1_000", "Hz", "--x = '1_000' is not a number with an optional unit (digit separators '_'"),
        ("١٠", "Hz", "(digits 0-9 only)"),
        ("ten", "Hz", "--x = 'ten' is not a number"),
        ("", "Hz", "--x = '' is not a number"),
        ("5 um um", "um", "is not a number with an optional unit"),
    ],
)
def test_parse_quantity_refuses_with_the_argument_and_value(text, unit, message):
    with pytest.raises(ParameterError, match=None) as e:
        parse_quantity(text, unit, "--x")
    assert message in str(e.value)


def test_track_with_units_equals_track_with_bare_numbers(tmp_path):
    bare = run(
        "track", "--controller", "pid", "--freq", "20", "--amp", "4", "--offset", "7", "--duration", "0.4",
        "--skip", "0.1", "--json", cwd=tmp_path,
    )  # fmt: skip
    units = run(
        "track", "--controller", "pid", "--freq", "0.02kHz", "--amp", "4um", "--offset", "0.007mm", "--duration",
        "400ms", "--skip", "100ms", "--json", cwd=tmp_path,
    )  # fmt: skip
    assert bare.returncode == 0 and units.returncode == 0, bare.stderr + units.stderr
    a, b = json.loads(bare.stdout), json.loads(units.stdout)
    assert a == b
    # SI in the JSON, each number's unit said
    assert a["amplitude_m"] == 4e-6 and a["offset_m"] == 7e-6 and a["freq_hz"] == 20.0 and a["duration_s"] == 0.4
    assert a["units"]["rmse"] == "m" and a["units"]["rmse_percent"] == "%"
    # the RMSE in m is the % of range times the reference's range (8 um): not um, not a mix
    assert a["metrics"]["rmse"] == pytest.approx(a["metrics"]["rmse_percent"] / 100 * 8e-6, rel=1e-9)
    text = run("track", "--controller", "pid", "--amp", "4um", "--duration", "0.4", "--skip", "0.1", cwd=tmp_path)
    assert "(4 um around 8 um)" in text.stdout and " um  (" in text.stdout


@pytest.mark.parametrize(
    "argv,named",
    [
        (["track", "--controller", "pid", "--amp", "5kg"], "argument --amp: '5kg': 'kg' is not a unit of length"),
        (["track", "--controller", "pid", "--freq", "1_000"], "argument --freq: '1_000' is not a number"),
        (["track", "--controller", "pid", "--duration", "2um"], "argument --duration: '2um': 'um' is a unit of length"),
        (["identify", "x.csv", "--model", "mpi", "--fs", "10kV"], "argument --fs: '10kV': 'kV' is a unit of voltage"),
        (["simulate", "m.json", "x.csv", "--fs", "fast"], "argument --fs: 'fast' is not a number"),
    ],
)
def test_a_bad_suffix_is_one_line_naming_the_argument(tmp_path, argv, named):
    out = run(*argv, cwd=tmp_path)
    assert out.returncode == 2 and out.stderr.count("\n") == 1, out.stderr
    assert named in out.stderr and "Traceback" not in out.stderr


def test_identify_fs_in_khz_equals_hz(tmp_path):
    rng = np.random.default_rng(0)
    v = 60 + 50 * np.sin(np.linspace(0, 6 * np.pi, 1200)) + rng.normal(0, 0.1, 1200)
    import piezohyst as ph

    y = ph.papers.mpi_seed2().simulate(v)
    np.savetxt(tmp_path / "r.csv", np.c_[v, y], delimiter=",", header="input,output", comments="")
    outs = []
    for fs in ("2000", "2kHz"):
        out = run("identify", "r.csv", "--model", "mpi", "--fs", fs, "--out", f"m{len(outs)}.json", "--json",
                  cwd=tmp_path)  # fmt: skip
        assert out.returncode == 0, out.stderr
        outs.append(json.loads((tmp_path / f"m{len(outs)}.json").read_text()))
    assert outs[0]["fit"]["data"]["fs"] == outs[1]["fit"]["data"]["fs"] == 2000.0
    assert outs[0]["parameters"] == outs[1]["parameters"]
