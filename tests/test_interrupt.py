"""Ctrl-C during identification or tuning stops cleanly with the best result so far, marked
partial; on the command line it is saved, marked partial, with exit code 130 (issue 8).
SIGTERM and SIGHUP do the same on the command line, exiting 143 and 129 (issue 20)."""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

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


def test_a_hung_up_terminal_does_not_lose_the_best_so_far(monkeypatch):
    """SIGHUP from a closed terminal: the progress bar's writes fail (EIO) as the optimizer
    stops; the run still returns its best point, marked interrupted."""

    class HungUp(io.StringIO):
        def write(self, s):
            raise OSError(5, "Input/output error")

    monkeypatch.setattr(sys, "stderr", HungUp())
    _interrupt_after(monkeypatch, 4)
    res = optimize.minimize(lambda X: np.sum(X**2, axis=1), [(-1, 1)] * 2, method="de", rng=0, progress=True)
    assert res.interrupted and res.partial and res.history["best_cost"].shape == (3,) and np.isfinite(res.fun)


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


@pytest.mark.parametrize(
    "signum,code,named",
    [(signal.SIGINT, 130, "Ctrl-C (SIGINT)"), (signal.SIGTERM, 143, "SIGTERM"), (signal.SIGHUP, 129, "SIGHUP")],
)
def test_cli_identify_ctrl_c_saves_the_best_model_marked_partial(tmp_path, signum, code, named):
    """A real SIGINT (SIGTERM, SIGHUP) to a running `piezohyst identify`: exit 130 (143, 129),
    one line on stderr naming the signal, the model file holds the best model so far with
    "partial": true and loads; the process ends within seconds of the signal."""
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
    # wait for the progress bar (the optimizer is running), then the signal
    buf = ""
    deadline = time.monotonic() + 60
    while "best" not in buf and time.monotonic() < deadline:
        ch = p.stderr.read(1)
        if not ch:
            break
        buf += ch
    assert "best" in buf, buf
    time.sleep(0.5)
    t0 = time.monotonic()
    p.send_signal(signum)
    _, err = p.communicate(timeout=60)
    latency = time.monotonic() - t0
    assert p.returncode == code, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("piezohyst identify: interrupted:") and "partial" in last and "Traceback" not in err
    assert f"before {named}," in last
    doc = json.loads(out.read_text())
    assert doc["partial"] is True and doc["fit"]["partial"] is True
    model = ph.load_model(out)
    assert np.all(np.isfinite(model.simulate(v)))
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary left behind
    # the fit stops at once; the metrics, the diagnosis and the write follow (about 1.5 s here)
    assert latency < 15, f"{named}: {latency:.1f} s from the signal to the exit"


def test_sigterm_stops_a_long_rust_batch_within_a_second():
    """The command line's handler (cli.stops) makes SIGTERM raise like Ctrl-C: the Rust batch,
    which polls Python's signal handlers every 50 ms, stops its workers and returns."""
    code = textwrap.dedent(
        """
        import numpy as np
        from piezohyst import _core
        from piezohyst.cli.stops import Interrupted, handled
        rows = np.tile(np.concatenate([[0.5], np.linspace(0, 1, 100_000), np.full(100_000, 1e-6)]), (8, 1))
        v = np.sin(np.linspace(0, 60, 200_000))
        with handled():
            print("started", flush=True)
            try:
                _core.batch_rmse("pi", [100_000, 0], rows, v, v)
                print("finished", flush=True)
            except Interrupted as e:
                print("stopped by", e.signum, flush=True)
        """
    )
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert p.stdout is not None and p.stdout.readline().strip() == "started"
        time.sleep(1.5)  # inside the Rust call by now
        assert p.poll() is None, "the call finished before the signal: make it longer"
        t0 = time.monotonic()
        p.send_signal(signal.SIGTERM)
        out, err = p.communicate(timeout=30)
        latency = time.monotonic() - t0
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert out.strip() == f"stopped by {int(signal.SIGTERM)}" and p.returncode == 0, err
    # about 0.1 s here; the bound leaves room for a busy two-core machine
    assert latency < 3.0, f"SIGTERM took {latency:.2f} s"
