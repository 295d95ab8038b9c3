"""``piezohyst fleet identify --scheduler tcp://…`` on a real cluster (issue 16, item 5): a ``dask
scheduler`` and two ``dask worker`` processes on localhost (random free ports, torn down whatever
happens), one worker killed mid-run. The run completes, every record's model is there once and
equal to serial ``piezohyst identify``'s."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.cli.test_cli_fleet import FAST, make_records, serial_identify, without_times

PYTHON_DIR = str(Path(__file__).resolve().parents[2] / "python")


def _env():
    path = os.pathsep.join(p for p in (PYTHON_DIR, os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, "RAYON_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}


def _start(args, log: Path) -> subprocess.Popen:
    # a session of its own: the test ends exactly this process group, nothing else
    return subprocess.Popen(
        [sys.executable, "-m", "dask", *args],
        stdout=log.open("w"),
        stderr=subprocess.STDOUT,
        env=_env(),
        start_new_session=True,
    )


def _kill(p: subprocess.Popen) -> None:
    if p.poll() is None:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    p.wait(timeout=30)


@pytest.fixture
def cluster(tmp_path):
    """``(address, [worker processes])`` of a scheduler and two single-threaded, nanny-less workers."""
    sched_file = tmp_path / "scheduler.json"
    procs = []
    try:
        procs.append(
            _start(
                [
                    "scheduler",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    "0",
                    "--no-dashboard",
                    "--scheduler-file",
                    str(sched_file),
                ],
                tmp_path / "scheduler.log",
            )
        )
        workers = []
        for i in range(2):
            w = _start(
                [
                    "worker",
                    "--scheduler-file",
                    str(sched_file),
                    "--nthreads",
                    "1",
                    "--no-nanny",
                    "--no-dashboard",
                    "--host",
                    "127.0.0.1",
                    "--name",
                    f"w{i}",
                    "--death-timeout",
                    "60",
                ],
                tmp_path / f"worker{i}.log",
            )
            procs.append(w)
            workers.append(w)
        deadline = time.monotonic() + 120
        address = None
        while time.monotonic() < deadline:
            if procs[0].poll() is not None:
                pytest.fail("the dask scheduler exited: " + (tmp_path / "scheduler.log").read_text())
            if sched_file.is_file():
                try:
                    address = json.loads(sched_file.read_text())["address"]
                    break
                except (ValueError, KeyError):
                    pass
            time.sleep(0.1)
        assert address, "the dask scheduler wrote no address"
        from distributed import Client

        with Client(address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=120)
        yield address, workers
    finally:
        for p in reversed(procs):
            _kill(p)


def test_a_worker_killed_mid_run_loses_no_record_and_duplicates_none(tmp_path, cluster):
    address, workers = cluster
    recs = make_records(tmp_path / "recs", 10, samples=3000)
    out = tmp_path / "out"
    fleet = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "piezohyst",
            "fleet",
            "identify",
            *map(str, recs),
            *FAST,
            "--out",
            str(out),
            "--scheduler",
            address,
            "--progress",
            "lines",
            "--json",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
    )
    from distributed import Client

    try:
        done_at_kill = None
        deadline = time.monotonic() + 300
        with Client(address, timeout="30s") as client:
            name_of = {a: w["name"] for a, w in client.scheduler_info()["workers"].items()}
            while time.monotonic() < deadline and fleet.poll() is None:
                done = len(list(out.glob("part*.json"))) if out.is_dir() else 0
                # killed while it runs a record: that task is lost with it and must run again
                busy = {name_of.get(a) for a, keys in client.processing().items() if keys}
                if done >= 2 and "w0" in busy:
                    _kill(workers[0])
                    done_at_kill = done
                    break
                time.sleep(0.02)
        stdout, stderr = fleet.communicate(timeout=300)
    finally:
        if fleet.poll() is None:
            fleet.kill()
            fleet.wait()
    assert done_at_kill is not None and done_at_kill < len(recs), "the worker was not killed mid-run"
    assert workers[0].returncode == -signal.SIGKILL
    assert fleet.returncode in (0, 3), stderr
    summary = json.loads(stdout)
    assert summary["records"] == 10 and summary.get("failed") == []
    with open(out / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted(r["record"] for r in rows) == sorted(r.stem for r in recs)  # each once
    ran = [int(r["worker"].rpartition(":")[2]) for r in rows]
    # the survivor finished the rest; the killed worker may or may not have finished a record
    # before (the scheduler decides who runs the first ones)
    assert set(ran) <= {workers[0].pid, workers[1].pid} and workers[1].pid in ran
    assert ran.count(workers[1].pid) >= len(recs) - done_at_kill
    assert sorted(p.name for p in out.glob("*.json")) == sorted(f"{r.stem}.json" for r in recs)
    assert not list(out.glob(".*.tmp"))
    # the models are serial identify's, whichever worker ran them and however often
    for r in recs[:4]:
        _, want = serial_identify(r, tmp_path / "serial.json")
        got = json.loads((out / f"{r.stem}.json").read_text())
        assert without_times(got) == without_times(want)
