"""Ctrl-C during identification or tuning stops cleanly with the best result so far, marked
partial; on the command line it is saved, marked partial, with exit code 130 (issue 8)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np

import piezohyst as ph
from piezohyst.optimize import core as optimize


def _interrupt_after(monkeypatch, calls: int):
    """Make the optimizer's population evaluation raise KeyboardInterrupt on call ``calls``
    (as Ctrl-C does between two populations)."""
    real = optimize._evaluate
    count = {"n": 0}

    def evaluate(fun_batch, X):
        count["n"] += 1
        if count["n"] == calls:
            raise KeyboardInterrupt
        return real(fun_batch, X)

    monkeypatch.setattr(optimize, "_evaluate", evaluate)
    return count


def _boucwen_record():
    t = np.linspace(0, 1, 2000)
    v = 60 * np.sin(2 * np.pi * 3 * t) * (0.4 + 0.6 * t)
    y = ph.BoucWen(a=0.6, beta=0.02, gamma=0.01, n=1.0, d=1.0).simulate(v)
    return v, y


def test_identify_interrupted_returns_best_so_far_marked_partial(monkeypatch):
    v, y = _boucwen_record()
    full = ph.identify(v, y, model="boucwen", optimizer="de", rng=0, max_iterations=30)
    assert not full.partial and full.to_dict()["partial"] is False
    count = _interrupt_after(monkeypatch, 6)
    res = ph.identify(v, y, model="boucwen", optimizer="de", rng=0, max_iterations=30)
    assert count["n"] == 6 and res.partial and res.to_dict()["partial"] is True
    assert res.history["best_cost"].shape == (5,)  # five populations evaluated before Ctrl-C
    p = res.model.parameters
    assert all(np.isfinite(x) for x in p.values() if isinstance(x, float))
    assert np.isfinite(res.train["rmse"]) and res.train["rmse"] >= full.train["rmse"] * (1 - 1e-9)


def test_identify_vp_interrupted_is_partial(monkeypatch):
    rng = np.random.default_rng(1)
    v = np.cumsum(rng.normal(0, 1, 3000))
    v = 80 * (v - v.min()) / np.ptp(v)
    y = ph.papers.mpi_seed2().simulate(v)
    _interrupt_after(monkeypatch, 3)
    res = ph.identify(v, y, model="mpi", structure="fit", optimizer="de", rng=0, max_iterations=20, population_size=6)
    assert res.partial and np.isfinite(res.train["rmse_percent"])


def test_tune_interrupted_is_partial(monkeypatch):
    stage = ph.virtual_stage()
    ref = ph.sine(10.0, 2e-6, 0.3, 1e4, offset=5e-6)[1]
    full = ph.tune(
        ph.PID(kp=1e5, ki=1e8), {"kp": (1e4, 1e6), "ki": (1e7, 1e10)}, [ref], stage=stage, max_iterations=4, rng=0
    )
    assert not full.partial
    _interrupt_after(monkeypatch, 3)
    res = ph.tune(
        ph.PID(kp=1e5, ki=1e8), {"kp": (1e4, 1e6), "ki": (1e7, 1e10)}, [ref], stage=stage, max_iterations=4, rng=0
    )
    assert res.partial and np.isfinite(res.rmse) and res.history["best_cost"].shape == (2,)


def test_cli_identify_ctrl_c_saves_the_best_model_marked_partial(tmp_path):
    """A real SIGINT to a running `piezohyst identify`: exit 130, one line on stderr, the model
    file holds the best model so far with "partial": true and loads."""
    v, y = _boucwen_record()
    data = tmp_path / "run.csv"
    np.savetxt(data, np.c_[v, y], delimiter=",", header="v,y", comments="")
    out = tmp_path / "bw.json"
    cmd = [
        sys.executable,
        "-m",
        "piezohyst",
        "identify",
        str(data),
        "--model",
        "boucwen",
        "--input",
        "v",
        "--output",
        "y",
        "--fs",
        "2000",
        "--optimizer",
        "de",
        "--iterations",
        "100000",
        "--seed",
        "0",
        "--progress",
        "--out",
        str(out),
    ]
    p = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"}
    )
    # wait for the progress bar (the optimizer is running), then Ctrl-C
    buf = ""
    deadline = time.monotonic() + 60
    while "best" not in buf and time.monotonic() < deadline:
        ch = p.stderr.read(1)
        if not ch:
            break
        buf += ch
    assert "best" in buf, buf
    time.sleep(0.5)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("piezohyst identify: interrupted:") and "partial" in last and "Traceback" not in err
    doc = json.loads(out.read_text())
    assert doc["partial"] is True and doc["fit"]["partial"] is True
    model = ph.load_model(out)
    assert np.all(np.isfinite(model.simulate(v)))
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary left behind
