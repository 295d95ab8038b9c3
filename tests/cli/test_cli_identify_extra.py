"""`piezohyst identify --model cemf` and `--model boucwen-benchmark` from the command line:
synthetic records from known systems, the files written, the reports, and one-line errors."""

import json
import subprocess
import sys

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.boucwen_benchmark import BoucWenBenchmark
from piezohyst.stage import Amplifier, Stage, StageParameters

M_KG, K_NM, TEM = 0.0714, 7.333e7, 10.5
B_NSM = 2 * 0.03 * np.sqrt(K_NM * M_KG)
FS_STAGE = 1e4


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "piezohyst", *map(str, args)], cwd=cwd, capture_output=True, text=True)


def one_line_error(out, *fragments):
    msg = out.stderr.strip()
    return (
        out.returncode == 2
        and msg != ""
        and "\n" not in msg
        and "Traceback" not in msg
        and all(f in msg for f in fragments)
    )


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli_identify_extra")
    # a stage that is exactly the CEMF model (ideal amplifier, no creep): 0.2 s at 10 kHz of a
    # 10 Hz variable-amplitude sine and a 100 Hz - 3 kHz multisine for training; another such
    # record (7 Hz, another multisine) for validation, each from rest
    stage = Stage(
        StageParameters(M_KG, B_NSM, K_NM, TEM, 1.8e-6, 1.25e5, 8000.0, 3000.0),
        Amplifier(-20.0, 150.0),
        sample_time=1 / FS_STAGE,
    )
    for name, freq, seed in (("stage.csv", 10, 0), ("stage_val.csv", 7, 1)):
        t, slow = ph.variable_amplitude_sine(freq, 70, 0.2, FS_STAGE, offset=75)
        _, ms = ph.multisine(100, 3000, 2.0, 0.2, FS_STAGE, rng=seed)
        n = min(slow.size, ms.size)
        u = slow[:n] + ms[:n]
        np.savetxt(
            d / name,
            np.c_[t[:n], u, stage.simulate(u).position],
            delimiter=",",
            header="t,volts,x",
            comments="",
            fmt="%.17g",
        )
    # the Bouc-Wen benchmark system on three periods of a 512-sample 5-150 Hz multisine
    rng = np.random.default_rng(1)
    lines = np.zeros(257, complex)
    lines[4:103] = np.exp(2j * np.pi * rng.random(99))
    f = np.fft.irfft(lines, 512)
    f = np.tile(50 * f / f.std(), 3)
    np.savetxt(
        d / "bw.csv", np.c_[f, BoucWenBenchmark().simulate(f)], delimiter=",", header="u,y", comments="", fmt="%.17g"
    )
    return d, stage


def test_cemf_from_the_command_line(files):
    d, stage = files
    out = run(
        "identify",
        "stage.csv",
        "--model",
        "cemf",
        "--input",
        "volts",
        "--output",
        "x",
        "--time",
        "t",
        "--validate",
        "stage_val.csv",
        "--optimizer",
        "de",
        "--iterations",
        "15",
        "--seed",
        "0",
        "--capacitance",
        "1.8e-6",
        "--out",
        "stage.json",
        "--plot",
        "stage.png",
        "--json",
        cwd=d,
    )
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert report["model"] == "stage" and report["method"] == "de+least_squares"
    assert report["train"]["rmse_percent"] < 1e-6 and report["validation"]["rmse_percent"] < 1e-6
    assert report["data"]["train"]["range"] == [0, 2000] and report["data"]["fs"] == pytest.approx(FS_STAGE)
    assert report["data"]["validation"]["source"] == "stage_val.csv"
    assert (d / "stage.png").stat().st_size > 1000
    # the model file is a stage file: Stage.from_file reads it, with the true parameters
    got = Stage.from_file(d / "stage.json")
    p, q = got.params, stage.params
    for name in ("mass", "damping", "stiffness", "tem", "hyst_alpha", "hyst_beta", "hyst_gamma"):
        assert getattr(p, name) == pytest.approx(getattr(q, name), rel=0.01), name
    assert p.capacitance == 1.8e-6 and got.sample_time == pytest.approx(1 / FS_STAGE)
    assert json.loads((d / "stage.json").read_text())["fit"]["validation"]["rmse_percent"] < 1e-6
    # the human-readable summary
    out = run(
        "identify",
        "stage.csv",
        "--model",
        "cemf",
        "--input",
        "volts",
        "--output",
        "x",
        "--fs",
        FS_STAGE,
        "--train",
        ":600",
        "--optimizer",
        "de",
        "--iterations",
        "2",
        "--population",
        "8",
        "--seed",
        "0",
        "--out",
        "quick.json",
        cwd=d,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("cemf identified by de+least_squares in ") and "train" in out.stdout


def test_boucwen_benchmark_from_the_command_line(files):
    d, _ = files
    out = run(
        "identify",
        "bw.csv",
        "--model",
        "boucwen-benchmark",
        "--input",
        "u",
        "--output",
        "y",
        "--fs",
        750,
        "--train",
        "512:1024",
        "--validate",
        "1024:",
        "--iterations",
        "10",
        "--seed",
        "0",
        "--out",
        "bw.json",
        "--json",
        cwd=d,
    )
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert report["model"] == "boucwen-benchmark" and report["method"] == "de+least_squares"
    # simulated from the record's start: the true system reproduces the record exactly
    assert report["train"]["rmse"] < 1e-10 and report["validation"]["rmse"] < 1e-10
    doc = json.loads((d / "bw.json").read_text())
    assert doc["fs"] == 750.0 and doc["upsample"] == 20
    got = BoucWenBenchmark(**doc["parameters"])
    for name, value in BoucWenBenchmark().parameters.items():
        assert getattr(got, name) == pytest.approx(value, rel=1e-6), name


def test_help_and_errors(files):
    d, _ = files
    out = run("identify", "--help", cwd=d)
    assert out.returncode == 0
    for text in ("cemf", "boucwen-benchmark", "--capacitance", "stage file"):
        assert text in out.stdout, text
    base = ("identify", "stage.csv", "--input", "volts", "--output", "x")
    assert one_line_error(run(*base, "--model", "cemf", cwd=d), "the sample rate is unknown")
    assert one_line_error(
        run(*base, "--model", "mpi", "--fs", 1e4, "--capacitance", "1e-6", cwd=d),
        "--capacitance applies to --model cemf",
    )
    assert one_line_error(
        run(*base, "--model", "cemf", "--fs", 1e4, "--capacitance", "-1", cwd=d), "--capacitance = -1 must be"
    )
    assert one_line_error(run(*base, "--model", "cemf-2", "--fs", 1e4, cwd=d), "invalid choice")
    np.savetxt(
        d / "flat.csv", np.c_[np.linspace(0, 100, 50), np.zeros(50)], delimiter=",", header="volts,x", comments=""
    )
    assert one_line_error(
        run("identify", "flat.csv", "--model", "cemf", "--fs", 1e4, "--iterations", "1", "--out", "flat.json", cwd=d),
        "position does not move",
    )
    assert one_line_error(
        run(
            "identify",
            "flat.csv",
            "--model",
            "boucwen-benchmark",
            "--fs",
            750,
            "--iterations",
            "1",
            "--out",
            "flat.json",
            cwd=d,
        ),
        "y is constant",
    )
    assert not (d / "flat.json").exists()


def test_simulate_rows_lag_and_score_from(tmp_path):
    """`simulate --rows A:B --lag N --score-from K` scores output[k + N] against the simulation
    of rows A:B from sample K on, as the README's walk-through does."""
    import numpy as np

    from piezohyst import PI

    v = np.sin(np.linspace(0, 12, 300)) * 2.0
    model = PI([0.0, 0.3, 0.7], [1.0, 0.5, 0.2], 0.1)
    model.save(tmp_path / "pi.json")
    y = model.simulate(v[50:250])
    out = np.zeros(300)
    out[51:251] = y  # the output lags the input by one sample
    out[51:61] += 5.0  # a warm-up glitch the score leaves out
    np.savetxt(tmp_path / "rec.csv", np.c_[v, out], delimiter=",", header="v,x", comments="")
    import json
    import subprocess
    import sys

    def run(*args):
        return subprocess.run(
            [
                sys.executable,
                "-m",
                "piezohyst",
                "simulate",
                str(tmp_path / "pi.json"),
                str(tmp_path / "rec.csv"),
                "--input",
                "v",
                "--output",
                "x",
                *args,
            ],
            capture_output=True,
            text=True,
        )

    r = run("--rows", "50:250", "--lag", "1", "--score-from", "10", "--out", str(tmp_path / "p.csv"), "--json")
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert summary["error"]["max_error"] == 0.0 and summary["rows"] == [50, 250]
    r = run("--rows", "50:250", "--lag", "1", "--out", str(tmp_path / "p.csv"), "--force", "--json")
    assert json.loads(r.stdout)["error"]["max_error"] == 5.0  # the glitch is scored now
    r = run("--rows", "50:300", "--lag", "1", "--out", str(tmp_path / "p.csv"), "--force")
    assert r.returncode == 2 and "--lag = 1: output[300] is beyond the record's 300 samples" in r.stderr
    r = run("--rows", "250:50", "--out", str(tmp_path / "p.csv"), "--force")
    assert r.returncode == 2 and "--rows = '250:50'" in r.stderr
    r = run("--rows", "0:100", "--score-from", "100", "--out", str(tmp_path / "p.csv"), "--force")
    assert r.returncode == 2 and "--score-from = 100" in r.stderr
