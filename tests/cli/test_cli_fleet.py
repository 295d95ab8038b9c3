"""``piezohyst fleet identify`` and ``piezohyst robustness`` (issue 16): per-record model files
equal to serial ``piezohyst identify``'s, summary tables, failing records listed without stopping
the rest, resume after deleting outputs, manifests, and Monte-Carlo runs that give the same result
whatever the workers. The test with a real ``dask scheduler`` and two ``dask worker`` processes,
one killed mid-run, is in test_cli_fleet_cluster.py."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from piezohyst.cli.main import main
from piezohyst.models import BoucWen

FAST = ["--model", "boucwen", "--fs", "1000", "--seed", "0", "--iterations", "12"]


def run(*args, cwd=None, env=None):
    return subprocess.run(
        [sys.executable, "-m", "piezohyst", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        env=None if env is None else {**os.environ, **env},
        timeout=600,
    )


def make_records(folder: Path, n: int, samples: int = 1500, start: int = 0) -> list[Path]:
    """Bouc-Wen records with part-to-part variation (each part's a, beta, gamma, d drawn around
    a nominal part), 0.2 % output noise."""
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(samples) / 1000.0
    u = (
        5
        + 4 * np.sin(2 * np.pi * 1.0 * t) * (0.6 + 0.4 * np.sin(2 * np.pi * 0.13 * t))
        + 0.5 * np.sin(2 * np.pi * 3.1 * t)
    )
    paths = []
    for k in range(start, start + n):
        rng = np.random.default_rng(k)
        m = BoucWen(
            a=0.8 * (1 + 0.1 * rng.standard_normal()),
            beta=0.5 * (1 + 0.1 * rng.standard_normal()),
            gamma=0.2 * (1 + 0.1 * rng.standard_normal()),
            d=1.2 * (1 + 0.05 * rng.standard_normal()),
        )
        y = m.simulate(u)
        y = y + 0.002 * np.ptp(y) * rng.standard_normal(samples)
        p = folder / f"part{k:02d}.csv"
        np.savetxt(p, np.column_stack([u, y]), delimiter=",", header="input,output", comments="", fmt="%.9g")
        paths.append(p)
    return paths


def without_times(doc):
    doc = json.loads(json.dumps(doc))
    doc["fit"].pop("wall_time_s")
    return doc


def serial_identify(record: Path, out: Path, extra=()):
    code = main(["identify", str(record.resolve()), *FAST, *extra, "--out", str(out), "--force", "--json"])
    return code, json.loads(out.read_text())


def summary_rows(folder: Path):
    with open(folder / "summary.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_a_local_cluster_fleet_writes_the_models_serial_identify_writes(tmp_path, capsys):
    recs = make_records(tmp_path / "recs", 5)
    p = run("fleet", "identify", *map(str, recs), *FAST, "--out", str(tmp_path / "out"), "--workers", "2")
    assert p.returncode == 0, p.stderr
    assert "\r" not in p.stderr  # stderr is a pipe here: progress as plain lines
    assert "5/5 records done" in p.stderr and "local cluster of 2 worker process(es) x 1 Rust thread(s)" in p.stderr
    for r in recs:
        code, want = serial_identify(r, tmp_path / "serial.json")
        got = json.loads((tmp_path / "out" / f"{r.stem}.json").read_text())
        assert code == 0
        assert got["parameters"] == want["parameters"]  # to the bit (JSON floats round-trip exactly)
        assert without_times(got) == without_times(want)
    capsys.readouterr()
    rows = summary_rows(tmp_path / "out")
    assert [r["record"] for r in rows] == [r.stem for r in recs]
    assert {r["status"] for r in rows} == {"ok"} and {r["resumed"] for r in rows} == {"no"}
    t = pq.read_table(tmp_path / "out" / "summary.parquet").to_pylist()
    for row, r in zip(t, recs, strict=True):
        doc = json.loads((tmp_path / "out" / f"{r.stem}.json").read_text())
        assert row["p.a"] == doc["parameters"]["a"] and row["p.beta"] == doc["parameters"]["beta"]
        assert row["train_rmse_percent"] == doc["fit"]["train"]["rmse_percent"]
        assert row["model"] == "boucwen" and row["method"] == "de"
    assert (tmp_path / "out" / "report.png").stat().st_size > 10_000
    assert not list((tmp_path / "out").glob(".*.tmp"))


def test_a_failing_record_is_listed_and_the_others_run(tmp_path):
    recs = make_records(tmp_path / "recs", 3)
    bad = tmp_path / "recs" / "garbled.csv"
    bad.write_text("just one column\n1\n2\n3\n")
    missing = tmp_path / "recs" / "missing.csv"
    args = [str(recs[0]), str(bad), str(recs[1]), str(missing), str(recs[2])]
    p = run("fleet", "identify", *args, *FAST, "--out", str(tmp_path / "out"), "--scheduler", "serial", "--json")
    assert p.returncode == 1, p.stderr
    summary = json.loads(p.stdout)
    assert summary["counts"] == {"ok": 3, "failed": 2}
    failed = {f["record"]: f["error"] for f in summary["failed"]}
    assert "garbled" in failed and "not inferable" in failed["garbled"]
    assert "missing" in failed and "no such file" in failed["missing"]
    assert "piezohyst fleet identify: garbled failed: " in p.stderr
    rows = {r["record"]: r for r in summary_rows(tmp_path / "out")}
    assert rows["missing"]["status"] == "failed" and "no such file" in rows["missing"]["error"]
    assert sorted(f.name for f in (tmp_path / "out").glob("*.json")) == [f"{r.stem}.json" for r in recs]
    # a rerun skips the three finished records and tries the failing two again
    p = run("fleet", "identify", *args, *FAST, "--out", str(tmp_path / "out"), "--scheduler", "serial", "--json")
    again = json.loads(p.stdout)
    assert p.returncode == 1 and again["resumed"] == 3 and again["counts"] == {"ok": 3, "failed": 2}


def test_a_rerun_rewrites_exactly_the_deleted_models(tmp_path):
    recs = make_records(tmp_path / "recs", 8)
    out = tmp_path / "out"
    cmd = [
        "fleet",
        "identify",
        *map(str, recs),
        *FAST,
        "--out",
        str(out),
        "--scheduler",
        "serial",
        "--progress",
        "none",
    ]
    first = run(*cmd)
    assert first.returncode in (0, 3), first.stderr  # 3: some fit not trustworthy (a short optimizer run)
    before = {f.name: f.stat() for f in out.glob("*.json")}
    texts = {f.name: f.read_text() for f in out.glob("*.json")}
    assert len(before) == 8
    gone = [f"{r.stem}.json" for r in recs[1::2]] + [f"{recs[0].stem}.json"]  # 5 of 8
    for name in gone:
        (out / name).unlink()
    # a file holding an interrupted fit's best model is not finished either
    partial = out / f"{recs[2].stem}.json"
    doc = json.loads(partial.read_text())
    partial.write_text(json.dumps({**doc, "partial": True}))
    before[partial.name] = partial.stat()
    gone.append(partial.name)
    p = run(*cmd, "--json")
    assert p.returncode == first.returncode, p.stderr
    assert json.loads(p.stdout)["resumed"] == 2
    after = {f.name: f.stat() for f in out.glob("*.json")}
    assert sorted(after) == sorted(before)
    for name, st in after.items():
        same = (st.st_ino, st.st_mtime_ns) == (before[name].st_ino, before[name].st_mtime_ns)
        assert same == (name not in gone), name
        assert (out / name).read_text() != "" and json.loads((out / name).read_text())["parameters"] == json.loads(
            texts[name]
        )["parameters"]
    rows = {r["record"]: r["resumed"] for r in summary_rows(out)}
    assert rows == {r.stem: ("no" if f"{r.stem}.json" in gone else "yes") for r in recs}
    # --force: every model again
    assert run(*cmd, "--force").returncode == first.returncode
    assert all(f.stat().st_ino != after[f.name].st_ino for f in out.glob("*.json"))


def test_a_manifest_gives_per_record_columns_rates_and_names(tmp_path):
    recs = make_records(tmp_path / "recs", 2)
    # the second record as a 3-column file with its own column names and sample rate
    u, y = np.loadtxt(recs[1], delimiter=",", skiprows=1, unpack=True)
    np.savetxt(
        tmp_path / "recs" / "wide.csv",
        np.column_stack([np.arange(u.size) / 2000.0, u, y]),
        delimiter=",",
        header="t,volts,x",
        comments="",
        fmt="%.9g",
    )
    (tmp_path / "parts.csv").write_text(
        f"record,name,input,output,time,train\nrecs/{recs[0].name},first,,,,\nrecs/wide.csv,second,volts,x,t,:1200\n"
    )
    fast = [a for a in FAST if a not in ("--fs", "1000")]
    p = run(
        "fleet",
        "identify",
        "--manifest",
        str(tmp_path / "parts.csv"),
        *fast,
        "--fs",
        "1000",
        "--out",
        "out",
        "--scheduler",
        "serial",
        "--json",
        "--plots",
        cwd=tmp_path,
    )
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "out" / "first.png").stat().st_size > 10_000  # identify's --plot, per record
    first = json.loads((tmp_path / "out" / "first.json").read_text())
    second = json.loads((tmp_path / "out" / "second.json").read_text())
    assert first["fit"]["data"]["fs"] == 1000.0 and first["fit"]["data"]["train"]["samples"] == 1500
    assert second["fit"]["data"]["fs"] == pytest.approx(2000.0) and second["fit"]["data"]["train"]["range"] == [0, 1200]
    assert second["fit"]["data"]["columns"] == {"input": "volts", "output": "x", "time": "t"}
    # the same as serial identify with the manifest's options
    code = main(
        [
            "identify",
            str((tmp_path / "recs" / "wide.csv").resolve()),
            "--input",
            "volts",
            "--output",
            "x",
            "--time",
            "t",
            "--train",
            ":1200",
            *fast,
            "--out",
            str(tmp_path / "s.json"),
            "--json",
        ]
    )
    assert code == 0
    assert without_times(json.loads((tmp_path / "s.json").read_text())) == without_times(second)


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--operators", "0"], "error: --operators = 0 must be >= 1"),
        (["--capacitance", "1e-6"], "--capacitance applies to --model cemf"),
        (["--workers", "0"], "--workers = 0"),
        (["--scheduler", "nowhere"], "--scheduler = 'nowhere'"),
        (["--manifest", "nope.csv"], "--manifest = 'nope.csv': no such file"),
    ],
)
def test_bad_fleet_input_is_one_line_and_exit_2(tmp_path, extra, match):
    recs = make_records(tmp_path / "recs", 2)
    where = [] if {"--workers", "--scheduler"} & set(extra) else ["--scheduler", "serial"]
    p = run("fleet", "identify", *map(str, recs), *FAST, "--out", str(tmp_path / "out"), *where, *extra)
    assert p.returncode == 2, p.stderr
    assert match in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr


def test_duplicate_stems_and_a_bad_manifest_column_are_refused(tmp_path):
    a = make_records(tmp_path / "a", 1)[0]
    b = make_records(tmp_path / "b", 1)[0]
    p = run("fleet", "identify", str(a), str(b), *FAST, "--out", str(tmp_path / "out"), "--scheduler", "serial")
    assert p.returncode == 2 and "would both write part00.json" in p.stderr
    (tmp_path / "m.csv").write_text(f"record,colour\n{a}\n")
    p = run(
        "fleet",
        "identify",
        "--manifest",
        str(tmp_path / "m.csv"),
        *FAST,
        "--out",
        str(tmp_path / "o"),
        "--scheduler",
        "serial",
    )
    assert p.returncode == 2 and "column 'colour' is not a per-record identify option" in p.stderr


ROBUST = [
    "--controller",
    "pid",
    "--perturb",
    "mass=±10%,stiffness=+-20%,tem=±5%:normal",
    "--seed",
    "4",
    "--duration",
    "0.05",
    "--skip",
    "0.01",
    "--samples",
    "300",
    "--chunk",
    "64",
]


def test_robustness_gives_the_same_result_serial_and_on_two_workers(tmp_path):
    a = run("robustness", *ROBUST, "--scheduler", "serial", "--json", "--out", str(tmp_path / "a"))
    b = run("robustness", *ROBUST, "--workers", "2", "--json", "--progress", "lines")
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    da, db = json.loads(a.stdout), json.loads(b.stdout)
    for k in ("percentiles", "worst", "nominal", "sensitivity_spearman", "diverged", "samples"):
        assert da[k] == db[k], k
    assert "\r" not in b.stderr and "5/5 chunks done" in b.stderr
    assert da["samples"] == 300 and da["reference_samples"] == 500 and da["skip_samples"] == 100
    assert da["percentiles"]["rmse"]["p50"] < da["percentiles"]["rmse"]["p99"] <= da["percentiles"]["rmse"]["max"]
    t = pq.read_table(tmp_path / "a" / "samples.parquet").to_pylist()
    assert len(t) == 300 and [r["sample"] for r in t] == list(range(300))
    assert max(r["rmse"] for r in t) == da["percentiles"]["rmse"]["max"]
    worst = da["worst"][0]
    assert t[worst["sample"]]["rmse"] == worst["rmse"]
    assert t[worst["sample"]]["factor.mass"] == worst["parameters"]["mass"]["factor"]
    assert (tmp_path / "a" / "robustness.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "a" / "robustness.json").read_text())["worst"] == da["worst"]


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--perturb", "mass=±120%"], "--perturb mass=±120%"),
        (["--perturb", "height=±1%"], "'height' is not a perturbable"),
        (["--samples", "0"], "--samples = 0"),
        (["--skip", "1"], "--skip = 1 s must be"),
    ],
)
def test_bad_robustness_input_is_one_line_and_exit_2(extra, match):
    args = ["--controller", "pid", "--perturb", "mass=±10%", "--samples", "10", "--scheduler", "serial", *extra]
    p = run("robustness", *args)
    assert p.returncode == 2 and match in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr


def test_the_longest_records_are_submitted_first(tmp_path):
    """Tail imbalance: the largest record files go to the workers first (stable among equals),
    so the run ends on short tasks; a missing file counts 0 (its task reports it)."""
    from piezohyst.cli.fleet import _Job, _longest_first

    sizes = {"a": 100, "b": 5000, "c": 100, "d": 2500}
    jobs = []
    for name, size in sizes.items():
        (tmp_path / f"{name}.csv").write_bytes(b"1,2\n" * (size // 4))
        jobs.append(_Job(name, str(tmp_path / f"{name}.csv"), {}))
    jobs.append(_Job("gone", str(tmp_path / "gone.csv"), {}))
    assert [j.name for j in _longest_first(jobs)] == ["b", "d", "a", "c", "gone"]
