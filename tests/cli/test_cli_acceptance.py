"""Issue 14's acceptance command, exactly as the issue writes it, on ../shared/data/piezo/yan9a at
the issue's spans and on lookalike lab records (tests/lookalike_records.py: a 5 kHz ±150 V record
with a time column and a quiet lead-in, a 10 kHz two-column record with drift), asserting the
issue's targets for the validation RMSE (state carried) and that ``load_model(m.json).simulate``
over the training start -> validation end reproduces the reported figure to 1e-6.

The full study (six draws of each lookalike, three spans each, eight yan9a spans) is
``bench/identify_auto.py``; the cases here are a few of its rows (figures measured there)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import piezohyst as ph
from piezohyst.identify.core import fit_metrics
from tests.lookalike_records import piezo_5khz, piezo_10khz, spans, write_5khz, write_10khz

YAN9A = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "piezo" / "yan9a_model_1hz.dat"


def acceptance(cwd: Path, path: Path, inp: str, out: str, fs: float, train: str, validate: str) -> dict:
    """``piezohyst identify FILE --model auto --input COL --output COL --fs HZ --train A:B
    --validate B:C --json --out m.json``, then the model file over train start -> validation end."""
    cmd = [sys.executable, "-m", "piezohyst", "identify", str(path), "--model", "auto", "--input", inp,
           "--output", out, "--fs", repr(fs), "--train", train, "--validate", validate,
           "--json", "--out", "m.json"]  # fmt: skip
    run = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert report["assessment"]["validate_from"] == "carried"
    rec = ph.load_record(
        path, input=int(inp) if inp.isdigit() else inp, output=int(out) if out.isdigit() else out, fs=fs
    )
    a = int(train.split(":")[0])
    c, d = (int(x) for x in validate.split(":"))
    sim = ph.load_model(cwd / "m.json").simulate(rec.input[a:d])
    again = fit_metrics(sim[c - a :], rec.output[c:d])["rmse_percent"]
    assert abs(again - report["validation"]["rmse_percent"]) <= 1e-6
    return report


@pytest.mark.skipif(not YAN9A.exists(), reason="shared data not present")
@pytest.mark.parametrize(
    ("train", "validate", "measured"),
    [
        ("3152:3352", "3352:4152", 0.184),
        ("3152:4152", "4152:5152", 0.185),
        ("3152:4152", "4152:8027", 0.192),
        ("1000:2000", "2000:8027", 0.203),
    ],
)
def test_yan9a(tmp_path, train, validate, measured):
    report = acceptance(tmp_path, YAN9A, "0", "4", 200.0, train, validate)
    # before the model held its input delay and drift: 0.256 %, 0.281 %, 0.366 %; the third 0.240 %
    # before the Preisach candidates with a creep bank; the fourth (a sensor settling over six
    # times the training range's length) 0.338 % before the finalists' drift variants: the internal
    # split kept no drift, the validation span ranks the Preisach grid with tau = 3 T first
    assert report["validation"]["rmse_percent"] <= 0.3
    assert report["validation"]["rmse_percent"] == pytest.approx(measured, abs=0.01)
    assert report["input_delay"]["mode"] == "auto" and report["input_delay"]["samples"] in (3, 4)


@pytest.mark.parametrize(("seed", "span", "measured"), [(1, 0, 0.080), (2, 1, 0.120)])
def test_5khz_record_with_a_time_column_and_a_lead_in(tmp_path, seed, span, measured):
    # seed 1: a Preisach truth, 0.105 % before the finer (20-level) Preisach candidates
    rec = piezo_5khz(seed)
    path = write_5khz(rec, tmp_path / "scope.csv")
    train, validate = spans(rec)[span]
    report = acceptance(tmp_path, path, "voltage", "displacement", rec.fs, train, validate)
    assert report["validation"]["rmse_percent"] <= 0.2
    assert report["validation"]["rmse_percent"] == pytest.approx(measured, abs=0.01)
    if train.startswith("0:"):  # the training range holds the quiet lead-in: left out of the fit's cost
        assert report["structure"]["fit_start"] >= 0.9 * rec.meta["lead_in"]


@pytest.mark.parametrize(("seed", "span", "measured"), [(0, 1, 0.188), (4, 0, 0.234)])
def test_10khz_two_column_record_with_drift(tmp_path, seed, span, measured):
    # seed 4: a Preisach truth with a three-lag creep bank under a decaying sine; 1.002 % (gpi+creep2,
    # a 21-sample input delay standing in for the 50 ms lag) before the Preisach candidates with a
    # creep bank, 0.402 % before the finer (20-level) ones (its validation's minor loops are smaller)
    rec = piezo_10khz(seed)
    path = write_10khz(rec, tmp_path / "daq.dat")
    train, validate = spans(rec)[span]
    report = acceptance(tmp_path, path, "0", "1", rec.fs, train, validate)
    assert report["validation"]["rmse_percent"] <= 0.5
    assert report["validation"]["rmse_percent"] == pytest.approx(measured, abs=0.02)
