"""Issue 14: the input delay and the drift are the model's, so the model file ``piezohyst
identify`` writes reproduces the validation figure it reported, state carried: for every kind,
with and without a lag, with creep, with a drift term, and for ``--model auto``; the file
simulates through ``piezohyst simulate``; the JSON says what was decided and on what."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.cli.main import main
from piezohyst.identify.core import delayed, fit_metrics

FS = 1000.0
N = 5000
A, B, C = 500, 2500, 5000  # --train A:B --validate B:C (a lead-in of DATA before A)
DELAY = 3


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray, np.ndarray]:
    """A PI loop off the fitted grid behind a static nonlinearity, with two creep lags, read 3
    samples late through noise, plus a slow sensor drift (1 % of the range over the record)."""
    t = np.arange(N) / FS
    v = 2 + np.sin(2 * np.pi * 1.3 * t) * (1 - 0.3 * t / t[-1]) + 0.3 * np.sin(2 * np.pi * 3.7 * t)
    x = delayed(v, DELAY)
    loop = ph.PI([0.05, 0.2, 0.45, 0.7, 1.0], [0.5, 0.3, 0.2, 0.1, 0.05], p0=0.4)
    y = loop.simulate(x + 0.08 * x**2) + ph.Creep(1 / FS, [0.05, 0.5], [0.03, 0.03]).simulate(x)
    r = float(np.ptp(y))
    y = y + 0.01 * r * -np.expm1(-t / 3.0) + 1e-3 * r * np.random.default_rng(0).standard_normal(N)
    path = tmp_path_factory.mktemp("delay") / "rec.csv"
    np.savetxt(path, np.c_[v, y], delimiter=",", header="input,output", comments="")
    return path, v, y


def identify(capsys: pytest.CaptureFixture[str], path: Path, out: Path, *flags: object) -> tuple[int, dict, str]:
    argv = ["identify", path, "--fs", FS, "--train", f"{A}:{B}", "--validate", f"{B}:{C}", "--json",
            "--out", out, "--force", "--seed", 0, *flags]  # fmt: skip
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    assert code in (0, 3), cap.err  # 3: fitted and written, not trustworthy
    return code, json.loads(cap.out), cap.err


def reproduced(out: Path, v: np.ndarray, y: np.ndarray, report: dict) -> float:
    """load_model(m.json).simulate over the training start -> validation end, scored on the
    validation range: minus the reported figure."""
    model = ph.load_model(out)
    sim = model.simulate(v[A:C])
    return fit_metrics(sim[B - A :], y[B:C])["rmse_percent"] - report["validation"]["rmse_percent"]


CASES = [
    (kind, lag, creep) for kind in ("pi", "gpi", "mpi", "rdpi") for lag in ("0", "auto") for creep in ("0", "2")
] + [
    ("pi", "3", "0"),
    ("preisach", "0", "0"),
    ("preisach", "auto", "0"),
    ("preisach", "0", "2"),
    ("preisach", "auto", "2"),
    ("boucwen", "0", "0"),
    ("boucwen", "auto", "0"),
]


@pytest.mark.parametrize(("kind", "lag", "creep"), CASES, ids=["-".join(c) for c in CASES])
def test_the_model_file_reproduces_the_validation_figure(capsys, tmp_path, record, kind, lag, creep):
    path, v, y = record
    out = tmp_path / "m.json"
    flags: list[object] = ["--model", kind, "--lag", lag]
    if creep != "0":
        flags += ["--creep", creep]
    if kind == "boucwen":
        flags += ["--iterations", 15]
    _, report, _ = identify(capsys, path, out, *flags)
    assert report["assessment"]["validate_from"] == "carried"
    assert abs(reproduced(out, v, y, report)) <= 1e-6
    delay = report["input_delay"]
    model = ph.load_model(out)
    assert model.input_delay == delay["samples"]
    if lag == "0":
        assert delay == {"samples": 0, "seconds": 0.0, "mode": None} and report["structure"] is None
        assert "input_delay" not in json.loads(out.read_text())
    else:
        assert delay["mode"] == ("auto" if lag == "auto" else "given") and delay["seconds"] == delay["samples"] / FS
        assert json.loads(out.read_text()).get("input_delay", 0) == delay["samples"]  # absent: 0
        assert (
            report["preprocessing"]["lag"]["in_model"] and report["preprocessing"]["lag"]["samples"] == delay["samples"]
        )
    if lag == "auto":
        # chosen on the training range: the structure report says how; the families that fit the
        # loop well (GPI/MPI with the polynomial, Preisach) find the record's delay
        assert report["structure"]["delay"] == delay["samples"]
        if kind in ("gpi", "mpi") or (kind == "preisach" and creep == "0"):
            assert delay["samples"] == DELAY, report["structure"]["delay_rmse"]
        elif kind == "preisach":
            # the grid's fastest default lag (6 ms over a 2 s range) takes part of the 3 ms delay's
            # phase: measured 1 sample, the training RMSE within 3 % of the delay of 3's
            assert 0 < delay["samples"] <= DELAY, report["structure"]["delay_rmse"]
    if lag == "3":
        assert delay["samples"] == 3


@pytest.mark.parametrize("kind", ["mpi", "preisach", "boucwen"])
def test_drift_auto_is_in_the_model_and_the_file_reproduces(capsys, tmp_path, record, kind):
    path, v, y = record
    out = tmp_path / "m.json"
    flags: list[object] = ["--model", kind, "--lag", "auto", "--drift", "auto"]
    if kind == "boucwen":
        flags += ["--iterations", 15]
    _, report, _ = identify(capsys, path, out, *flags)
    drift = report["drift"]
    assert drift["mode"] == "auto" and drift["time_origin"] == "the training range's first sample"
    # the settlings offered: tau = the training span T and 3 T
    assert set(report["structure"]["drift_rmse"]) == {"none", f"exp({float(B - A):g})", f"exp({3.0 * (B - A):g})"}
    model = ph.load_model(out)
    assert (model.drift is None) == (drift["term"] is None)
    if model.drift is not None:
        assert drift["term"] == model.drift.to_dict() and model.drift.taus in ((float(B - A),), (3.0 * (B - A),))
        assert report["structure"]["drift"]["name"] == f"exp({model.drift.taus[0]:g})"
    assert abs(reproduced(out, v, y, report)) <= 1e-6


def test_auto_decides_and_reports_lag_drift_and_fit_start(capsys, tmp_path, record):
    path, v, y = record
    out = tmp_path / "m.json"
    code, report, _ = identify(capsys, path, out, "--model", "auto")
    assert code == 0
    assert abs(reproduced(out, v, y, report)) <= 1e-6
    s = report["structure"]
    assert report["input_delay"]["mode"] == "auto" and report["drift"]["mode"] == "auto"
    assert s["delay"] == report["input_delay"]["samples"] == DELAY
    assert s["fit_start"] == report["assessment"]["fit_start"] > 0  # the first, unwiped stretch
    rows = [r for r in report["league"] if r["rank"] is not None]
    assert all({"input_delay", "drift", "fit_start"} <= set(r) for r in rows)
    # the Preisach grid is a candidate with the creep banks of the PI family too
    assert {"preisach", "preisach+creep2", "preisach+creep4x10T"} <= {r["name"] for r in rows}
    chosen = next(r for r in rows if r["chosen"])
    assert chosen["input_delay"] == s["delay"] and chosen["drift"] == s["drift"]["name"]
    # the text league shows the decisions too
    code = main([str(a) for a in ["identify", path, "--fs", FS, "--train", f"{A}:{B}", "--validate", f"{B}:{C}",
                                  "--model", "auto", "--seed", 0, "--out", tmp_path / "t.json"]])  # fmt: skip
    text = capsys.readouterr().out
    assert "delay  drift" in text and "input delay:" in text and "drift term:" in text
    # --lag 0 and --drift none switch the decisions off
    _, off, _ = identify(capsys, path, out, "--model", "auto", "--lag", "0", "--drift", "none")
    assert off["input_delay"]["samples"] == 0 and off["drift"]["term"] is None
    # measured: 0.342 % with the decisions (gpi+creep2, delay 3), 0.514 % without
    assert report["validation"]["rmse_percent"] < 0.4 < 0.5 < off["validation"]["rmse_percent"]


def test_piezohyst_simulate_runs_a_delayed_drifting_model(capsys, tmp_path, record):
    path, v, _ = record
    out = tmp_path / "m.json"
    identify(capsys, path, out, "--model", "mpi", "--lag", "auto", "--drift", "auto", "--creep", "2")
    model = ph.load_model(out)
    assert model.input_delay > 0
    code = main(
        ["simulate", str(out), str(path), "--input", "input", "--fs", str(FS), "--out", str(tmp_path / "s.csv")]
    )
    assert code == 0, capsys.readouterr().err
    written = np.loadtxt(tmp_path / "s.csv", delimiter=",", skiprows=1)
    assert np.array_equal(written[:, -1], model.simulate(v))


def test_bad_structure_flags_are_one_line_errors(capsys, tmp_path, record):
    path, _, _ = record
    for flags, message in [
        (
            ("--model", "cemf", "--drift", "auto"),
            "--drift auto fits a drift term of pi, gpi, mpi, rdpi, preisach or boucwen",
        ),
        (("--model", "mpi", "--structure", "fit", "--drift", "auto"), "not --model mpi --structure fit"),
        (("--model", "pi", "--lag", "auto:x"), "--lag = 'auto:x': auto:M needs M"),
    ]:
        code = main([str(a) for a in ["identify", path, "--fs", FS, "--out", tmp_path / "m.json", *flags]])
        err = capsys.readouterr().err
        assert code == 2 and message in err and err.count("\n") == 1, (flags, err)
