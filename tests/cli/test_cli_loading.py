"""identify's loading options (issue 14 item 1): --time-unit / --input-unit / --output-unit,
--time-tolerance, units in the model file and the report, one-line errors for gaps and units."""

import json
import subprocess
import sys

import numpy as np
import pytest

import piezohyst as ph

FS = 1000.0
N = 1500


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "piezohyst", *map(str, args)], cwd=cwd, capture_output=True, text=True)


def one_line_error(out):
    return out.returncode == 2 and "\n" not in out.stderr.strip() and "Traceback" not in out.stderr


def record():
    t = np.arange(N) / FS
    u = 5.0 + 4.0 * np.sin(2 * np.pi * 3 * t) * (0.6 + 0.4 * np.cos(2 * np.pi * 0.5 * t))
    model = ph.PI(thresholds=[0.0, 1.5, 3.0], weights=[0.8, 0.3, 0.2], p0=0.0)
    y_um = model.simulate(u)  # micrometres
    return t, u, np.asarray(y_um)


def write(path, header, *cols, fmt="{!r}"):
    path.write_text(
        header + "\n" + "".join(",".join(fmt.format(float(v)) for v in r) + "\n" for r in zip(*cols, strict=True))
    )
    return path


def test_units_from_the_header_reach_the_model_file_and_json(tmp_path):
    t, u, y = record()
    write(tmp_path / "ms.csv", "t [ms],u (V),x (um)", t * 1e3, u, y)
    out = run(
        "identify", "ms.csv", "--model", "pi", "--input", "u", "--output", "x", "--time", "t",
        "--train", "0:1000", "--validate", "1000:1500", "--out", "m.json", "--json", cwd=tmp_path,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert report["data"]["fs"] == pytest.approx(FS, rel=1e-9)
    units = report["data"]["units"]
    assert units["time"] == {"from": "ms", "to": "s", "scale": 1e-3, "origin": "header"}
    assert units["output"] == {"from": "um", "to": "m", "scale": 1e-6, "origin": "header"}
    assert units["input"]["to"] == "V"
    model_doc = json.loads((tmp_path / "m.json").read_text())
    assert model_doc["units"] == {"input": "V", "output": "m"}
    model = ph.load_model(tmp_path / "m.json")
    assert model.units == {"input": "V", "output": "m"}
    # the model maps volts to metres: its output is the measured micrometres times 1e-6
    assert np.max(np.abs(model.simulate(u))) == pytest.approx(np.max(np.abs(y)) * 1e-6, rel=0.05)
    assert report["train"]["rmse_percent"] < 1.0
    text = run(
        "identify", "ms.csv", "--model", "pi", "--input", "u", "--output", "x", "--time", "t",
        "--out", "m2.json", cwd=tmp_path,
    )  # fmt: skip
    assert text.returncode == 0, text.stderr
    assert "units: input V (header), output m from um (header), time s from ms (header)" in text.stdout


def test_unit_options_override_and_time_in_ms_is_not_seconds(tmp_path):
    t, u, y = record()
    write(tmp_path / "plain.csv", "t,u,x", t * 1e3, u * 1e3, y)
    out = run(
        "identify", "plain.csv", "--model", "pi", "--input", "u", "--output", "x", "--time", "t",
        "--time-unit", "ms", "--input-unit", "mV", "--output-unit", "um", "--out", "m.json", "--json", cwd=tmp_path,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert report["data"]["fs"] == pytest.approx(FS, rel=1e-9)
    assert report["data"]["units"]["input"] == {"from": "mV", "to": "V", "scale": 1e-3, "origin": "argument"}
    bad = run(
        "identify", "plain.csv", "--model", "pi", "--input", "u", "--output", "x", "--time", "t",
        "--output-unit", "furlong", "--out", "m3.json", cwd=tmp_path,
    )  # fmt: skip
    assert one_line_error(bad)
    assert "--output-unit = 'furlong' is not a known unit" in bad.stderr


def test_time_tolerance_rounded_jittered_and_gaps(tmp_path):
    t, u, y = record()
    rng = np.random.default_rng(0)
    tj = np.round(t + rng.uniform(-0.02, 0.02, t.size) / FS, 6)  # jitter of 2 % of a step, us stamps
    write(tmp_path / "j.csv", "t,u,x", tj, u, y)
    args = ("identify", "j.csv", "--model", "pi", "--input", "u", "--output", "x", "--time", "t", "--json")
    ok = run(*args, "--out", "m.json", cwd=tmp_path)  # the CLI's default tolerance, 0.05 of a step
    assert ok.returncode == 0, ok.stderr
    assert json.loads(ok.stdout)["data"]["fs"] == pytest.approx(FS, rel=1e-4)
    strict = run(*args, "--out", "m2.json", "--time-tolerance", "1e-6", cwd=tmp_path)
    assert one_line_error(strict)
    assert "time is not uniformly sampled" in strict.stderr and "raise --time-tolerance" in strict.stderr
    bad = run(*args, "--out", "m3.json", "--time-tolerance", "2", cwd=tmp_path)
    assert one_line_error(bad) and "--time-tolerance = 2 must be a fraction of a step" in bad.stderr
    keep = np.r_[0:700, 705:N]
    write(tmp_path / "gap.csv", "t,u,x", t[keep], u[keep], y[keep])
    gap = run(
        "identify",
        "gap.csv",
        "--model",
        "pi",
        "--input",
        "u",
        "--output",
        "x",
        "--time",
        "t",
        "--out",
        "g.json",
        cwd=tmp_path,
    )
    assert one_line_error(gap)
    assert "gap.csv: time has a gap at row 700" in gap.stderr and "about 5 samples missing" in gap.stderr


def test_simulate_converts_the_input_and_time_units(tmp_path):
    t, u, _y = record()
    model = ph.PI(thresholds=[0.0, 1.5, 3.0], weights=[0.8, 0.3, 0.2], p0=0.0, units={"input": "V", "output": "m"})
    model.save(tmp_path / "m.json")
    write(tmp_path / "in.csv", "t [ms],u (mV)", t * 1e3, u * 1e3)
    out = run("simulate", "m.json", "in.csv", "--input", "u", "--time", "t", "--out", "sim.csv", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    sim = np.genfromtxt(tmp_path / "sim.csv", delimiter=",", names=True)
    np.testing.assert_allclose(sim["time"], t, rtol=1e-12, atol=1e-15)  # seconds, not milliseconds
    np.testing.assert_allclose(sim["input"], u, rtol=1e-12)  # volts, not millivolts
    np.testing.assert_allclose(sim["output"], model.simulate(u), rtol=1e-9, atol=1e-12)
    bad = run("simulate", "m.json", "in.csv", "--input", "u", "--time", "t", "--time-unit", "V", cwd=tmp_path)
    assert one_line_error(bad) and "--time-unit = 'V' is not a unit of time" in bad.stderr
