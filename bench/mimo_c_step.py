"""ns per step of a MIMO model (issue 15) from C: ``phs_mimo_step`` of the C library
(``crates/capi``, ``libpiezohyst.a``), as a real-time loop of a 3-actuator / 3-sensor mirror
calls it.

Usage (from the project root)::

    .venv/bin/python bench/mimo_c_step.py [--out bench/results/mimo_c_step.json] [--rounds 3]

Builds the static library, compiles ``bench/c/mimo_step_bench.c`` (``cc -O2``) and runs it
``--rounds`` times; per case (a linear 28-state model, a 12-state Hammerstein, LFRs of 28
states with 3 feedback channels of 10 and 20 plays, and the size of the LFR identified on the
CubeSpec mirror: 120 states, 12 channels of 1 play) the mean ns per step (best of 5 loops of
200,000 steps) and the per-step distribution. The summary keeps the best mean and the largest
worst case over the rounds; the load average is recorded (the machine may be shared).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from common import machine_info, versions, write_json_atomic

LINK = ["-lgcc_s", "-lutil", "-lrt", "-lpthread", "-lm", "-ldl", "-lc"]


def build(cc: str) -> Path:
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "piezohyst-capi"], cwd=ROOT, check=True)
    exe = ROOT / "target" / "c-bench" / "mimo_step_bench"
    exe.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, "-std=c99", "-O2", "-I", str(ROOT / "crates/capi/include"), str(HERE / "c/mimo_step_bench.c")]
    subprocess.run([*cmd, str(ROOT / "target/release/libpiezohyst.a"), *LINK, "-o", str(exe)], check=True)
    return exe


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(HERE / "results" / "mimo_c_step.json"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--cc", default=os.environ.get("CC", "cc"))
    args = ap.parse_args(argv)
    info = machine_info()
    exe = build(args.cc)
    rounds = []
    for r in range(args.rounds):
        rounds.append(json.loads(subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout))
        print(f"mimo_c_step: round {r + 1}/{args.rounds} done", file=sys.stderr)
    summary = {}
    for name in rounds[0]["results"]:
        rs = [rd["results"][name] for rd in rounds]
        summary[name] = {
            **{k: rs[0][k] for k in ("nx", "nw", "nr", "params", "state")},
            "mean_ns": min(x["mean"] for x in rs),
            "median_ns": min(x["median"] for x in rs),
            "p99.9_ns": min(x["p99.9"] for x in rs),
            "worst_ns": max(x["worst"] for x in rs),
        }
    try:
        info["loadavg_at_end"] = list(os.getloadavg())
    except OSError:
        pass
    payload = {
        "benchmark": "mimo_c_step",
        "timestamp_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "machine": info,
        "versions": versions(),
        "compiler": subprocess.run([args.cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0],
        "steps_per_case": rounds[0]["steps"],
        "clock_read_ns": min(rd["clock_read_ns"] for rd in rounds),
        "summary": summary,
        "rounds": rounds,
    }
    write_json_atomic(Path(args.out), payload)
    print(f"{'case':<40} {'mean':>8} {'median':>8} {'p99.9':>8} {'worst':>10}   (ns per step, C API)")
    for name, s in summary.items():
        print(f"{name:<40} {s['mean_ns']:8.1f} {s['median_ns']:8.0f} {s['p99.9_ns']:8.0f} {s['worst_ns']:10.0f}")
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
