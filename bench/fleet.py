"""Scale-out on Dask (issue 16 item 4): fleet identification and Monte-Carlo robustness, each
against its named baseline measured in the same run, plus Dask's per-task overhead.

Usage (from the project root, after the extension is built):

    .venv/bin/python bench/fleet.py [--records 40] [--samples 10000] [--runs 10000] [--quick] \
        [--out bench/results/fleet.json]

Cases (wall clock of the whole command, ``time.perf_counter`` around a fresh ``python -m piezohyst``
process: interpreter start, imports, cluster start-up and shutdown included):

``fleet identify``
    ``piezohyst fleet identify RECS/*.csv --model boucwen --fs 1000 --seed 0`` on ``--records``
    Bouc-Wen records of ``--samples`` samples with part-to-part variation (a, beta, gamma, d each
    drawn around a nominal part, 0.2 % output noise), every run with ``RAYON_NUM_THREADS=1``:
    ``--workers 2`` against ``--workers 1`` (target: >= 1.6x) and against ``--scheduler serial``
    (the same code in one process, no Dask: the named baseline). Records/s of each.
``robustness``
    ``piezohyst robustness --controller pid --samples --runs --perturb mass=±10%,stiffness=±10%,tem=±5%
    --seed 0`` (0.2 s at 10 kHz per run) on the default local cluster against ``--scheduler serial``
    (one process, the Rust core's rayon threads over the rows). Closed-loop runs/s; target <= 10 s.
``overhead``
    On a LocalCluster of 2 worker processes: start-up and shutdown, and the per-task overhead of
    500 no-op tasks (submit to result). Data moved per task: the pickled size of a fleet task's
    argument and result and of a robustness chunk's.

Each configuration runs ``--repeats`` times (default 2; robustness at least 3) in ABBA order and
the median is reported, with every wall time. The machine's load average at the start and the end
is recorded: on the shared 2-core machine other work competes for the cores, and ratios carry that
noise.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import HERE, machine_info, versions, write_json_atomic

ROOT = HERE.parent


def make_records(folder: Path, n: int, samples: int) -> list[Path]:
    from piezohyst.models import BoucWen

    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(samples) / 1000.0
    u = (
        5
        + 4 * np.sin(2 * np.pi * 1.0 * t) * (0.6 + 0.4 * np.sin(2 * np.pi * 0.13 * t))
        + 0.5 * np.sin(2 * np.pi * 3.1 * t)
    )
    paths = []
    for k in range(n):
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


def _env(**extra: str) -> dict[str, str]:
    path = os.pathsep.join(p for p in (str(ROOT / "python"), os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path, **extra}


def timed_cli(args: list[str], **env: str) -> tuple[float, dict[str, Any]]:
    t0 = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-m", "piezohyst", *args, "--json", "--progress", "none"],
        capture_output=True,
        text=True,
        env=_env(**env),
        cwd=ROOT,
    )
    wall = time.perf_counter() - t0
    if p.returncode not in (0, 3):
        raise RuntimeError(f"piezohyst {' '.join(args[:2])} exited {p.returncode}: {p.stderr[-2000:]}")
    return wall, json.loads(p.stdout)


def bench_fleet(n: int, samples: int, tmp: Path, repeats: int) -> dict[str, Any]:
    recs = make_records(tmp / "recs", n, samples)
    base = ["fleet", "identify", *map(str, recs), "--model", "boucwen", "--fs", "1000", "--seed", "0"]
    out: dict[str, Any] = {"records": n, "samples_per_record": samples, "repeats": repeats, "runs": {}}
    configs = (
        ("serial", ["--scheduler", "serial"]),
        ("workers1", ["--workers", "1"]),
        ("workers2", ["--workers", "2"]),
    )
    walls: dict[str, list[float]] = {name: [] for name, _ in configs}
    params = {}
    for r in range(repeats):
        # ABBA order: a load that drifts during the run weighs on every configuration alike
        for name, extra in configs if r % 2 == 0 else configs[::-1]:
            dest = tmp / f"out-{name}-{r}"
            wall, summary = timed_cli([*base, "--out", str(dest), *extra], RAYON_NUM_THREADS="1")
            walls[name].append(wall)
            params[name] = {p.name: json.loads(p.read_text())["parameters"] for p in sorted(dest.glob("part*.json"))}
            out["runs"][name] = {
                "command": f"RAYON_NUM_THREADS=1 piezohyst {' '.join(base[:2])} RECS/*.csv --model boucwen --fs 1000 "
                f"--seed 0 --out DIR {' '.join(extra)}",
                "counts": summary["counts"],
            }
    for name, w in walls.items():
        med = float(np.median(w))
        out["runs"][name].update(walls_s=w, wall_s=med, records_per_s=n / med)
    r = out["runs"]
    out["speedup_2_vs_1_workers"] = r["workers1"]["wall_s"] / r["workers2"]["wall_s"]
    out["speedup_2_workers_vs_serial"] = r["serial"]["wall_s"] / r["workers2"]["wall_s"]
    out["identical_parameters"] = params["serial"] == params["workers1"] == params["workers2"]
    out["target_speedup"] = 1.6
    out["pass"] = out["speedup_2_vs_1_workers"] >= 1.6 and out["identical_parameters"]
    return out


def bench_robustness(runs: int, repeats: int) -> dict[str, Any]:
    base = [
        "robustness",
        "--controller",
        "pid",
        "--samples",
        str(runs),
        "--perturb",
        "mass=±10%,stiffness=±10%,tem=±5%",
        "--seed",
        "0",
    ]
    out: dict[str, Any] = {"runs": runs, "run_seconds": 0.2, "rate_hz": 10_000, "repeats": repeats, "cases": {}}
    configs = (("serial", ["--scheduler", "serial"]), ("local", []))
    docs: dict[str, dict[str, Any]] = {}
    walls: dict[str, list[float]] = {name: [] for name, _ in configs}
    for r in range(repeats):
        for name, extra in configs if r % 2 == 0 else configs[::-1]:
            wall, doc = timed_cli([*base, *extra])
            docs[name] = doc
            walls[name].append(wall)
            out["cases"][name] = {
                "command": f"piezohyst {' '.join(base)} {' '.join(extra)}".strip(),
                "cluster": doc["cluster"],
            }
    for name, w in walls.items():
        med = float(np.median(w))
        out["cases"][name].update(walls_s=w, wall_s=med, runs_per_s=runs / med)
    out["identical"] = all(docs["serial"][k] == docs["local"][k] for k in ("percentiles", "worst", "nominal"))
    out["target_s"] = 10.0
    out["pass"] = out["cases"]["local"]["wall_s"] <= 10.0 and out["identical"]
    return out


def _noop(x: int) -> int:
    return x


def bench_overhead(tasks: int) -> dict[str, Any]:
    from piezohyst import PID, virtual_stage
    from piezohyst.cli.fleet import _Job
    from piezohyst.fleet import RobustnessProblem, parse_perturbations, plan, run_chunk, runner

    cluster = plan("local", 2, env={"RAYON_NUM_THREADS": "1"})
    t0 = time.perf_counter()
    with runner(cluster) as run:
        list(run.run(_noop, [("warm", (0,))]))  # the workers are up and answer
        start = time.perf_counter() - t0
        t1 = time.perf_counter()
        outs = list(run.run(_noop, [(f"noop-{i}", (i,)) for i in range(tasks)]))
        per_task = (time.perf_counter() - t1) / tasks
        assert sorted(o.value for o in outs) == list(range(tasks))
        t2 = time.perf_counter()
    stop = time.perf_counter() - t2
    stage = virtual_stage()
    t = np.arange(2000) * stage.sample_time
    problem = RobustnessProblem(
        stage,
        PID(kp=2e6, ki=2e9),
        8e-6 + 5e-6 * np.sin(2 * np.pi * 10 * t),
        500,
        tuple(parse_perturbations("mass=±10%,stiffness=±10%,tem=±5%")),
        0,
    )
    chunk = run_chunk(problem, 0, 500)
    job = _Job("part00", "/data/recs/part00.csv", {"model": "boucwen", "fs": 1000.0, "seed": 0})
    return {
        "cluster": cluster.describe(),
        "cluster_start_s": start,
        "cluster_stop_s": stop,
        "per_task_overhead_s": per_task,
        "noop_tasks": tasks,
        "bytes": {
            "fleet_task_argument": len(pickle.dumps(job)),
            "fleet_task_result_typical": None,  # filled from a real model file below
            "robustness_problem_once_per_worker": len(pickle.dumps(problem)),
            "robustness_chunk_argument": len(pickle.dumps((0, 500))),
            "robustness_chunk_result_500": len(pickle.dumps(chunk)),
        },
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--runs", type=int, default=10_000)
    ap.add_argument("--tasks", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=2, help="runs of each configuration, in ABBA order (median)")
    ap.add_argument("--quick", action="store_true", help="8 records of 3000 samples, 2000 runs")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "fleet.json")
    args = ap.parse_args(argv)
    if args.quick:
        args.records, args.samples, args.runs, args.tasks, args.repeats = 8, 3000, 2000, 200, 1
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="bench-fleet-") as tmp:
        fleet = bench_fleet(args.records, args.samples, Path(tmp), args.repeats)
        doc = next(Path(tmp, "out-workers2-0").glob("part*.json")).read_text()
    robust = bench_robustness(args.runs, max(args.repeats, 3))
    overhead = bench_overhead(args.tasks)
    overhead["bytes"]["fleet_task_result_typical"] = len(pickle.dumps({"document": doc, "png": None}))
    payload = {
        "benchmark": "fleet",
        "timestamp_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": machine_info(),
        "versions": versions(),
        "loadavg_start": load0,
        "loadavg_end": os.getloadavg(),
        "fleet_identify": fleet,
        "robustness": robust,
        "overhead": overhead,
    }
    write_json_atomic(args.out, payload)
    print(json.dumps({"fleet_identify": fleet, "robustness": robust, "overhead": overhead}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
