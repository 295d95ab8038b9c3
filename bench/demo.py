"""Wall time of `piezohyst demo` (full and --quick) on this machine: targets 3 min and 30 s
(issue 6). Each mode runs in a fresh subprocess, as a user runs it. JSON in
bench/results/demo.json.

Run: ``.venv/bin/python bench/demo.py``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine_info, write_json_atomic

OUT = Path(__file__).with_name("results") / "demo.json"
TARGETS = {"full": 180.0, "quick": 30.0}


def run(mode: str) -> dict:
    with tempfile.TemporaryDirectory() as d:
        cmd = [sys.executable, "-m", "piezohyst", "demo", "--out", str(Path(d) / "report"), "--json"]
        if mode == "quick":
            cmd.append("--quick")
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode:
            raise RuntimeError(f"{cmd} failed: {p.stderr[-2000:]}")
        wall = time.perf_counter() - t0
        numbers = json.loads(p.stdout)
    return {
        "wall_s": wall,
        "target_s": TARGETS[mode],
        "pass": wall <= TARGETS[mode],
        "demo_internal_wall_s": numbers["wall_s"],
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=OUT, help=f"JSON output (default {OUT})")
    ap.add_argument("--modes", nargs="+", choices=("quick", "full"), default=["quick", "full"])
    args = ap.parse_args(argv)
    result = {
        "timestamp_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "machine": machine_info(),
        "runs": {m: run(m) for m in args.modes},
    }
    write_json_atomic(args.out, result)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
