"""Wall time of `piezohyst demo` (full and --quick) on this machine: targets 3 min and 30 s
(issue 6). Each mode runs in a fresh subprocess, as a user runs it. JSON in
bench/results/demo.json.

Run: ``.venv/bin/python bench/demo.py``.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

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
    return {"wall_s": wall, "target_s": TARGETS[mode], "pass": wall <= TARGETS[mode],
            "demo_internal_wall_s": numbers["wall_s"]}


def main():
    result = {"machine": f"{os.cpu_count()} cores", "runs": {m: run(m) for m in ("quick", "full")}}
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
