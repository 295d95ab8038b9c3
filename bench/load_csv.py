"""Loading a large CSV record: ``load_record`` against ``numpy.loadtxt`` in the same run.

Usage (from the project root)::

    .venv/bin/python bench/load_csv.py [--rows 1000000] [--repeats 5] [--out bench/results/load_csv.json]

Writes a 4-column CSV (header ``t,u,y,aux``; time, a sine input, a hysteretic-looking output,
an auxiliary channel; 17 significant digits, as ``repr`` prints floats) of ``--rows`` rows to
a temporary folder, then times, alternating and ``--repeats`` times each, ``load_record(f,
input="u", output="y", time="t")`` and ``numpy.loadtxt(f, delimiter=",", skiprows=1)``
(the median is reported). Peak memory of each is measured in a fresh subprocess: the
Python-side peak through ``tracemalloc`` and the process's peak resident set (``VmHWM``)
minus its resident set before loading, both against the file size.

Target (issue 14): ``load_record`` at least 2x faster than ``numpy.loadtxt``, with peak
memory <= 4x the file size.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "python"))

import numpy as np

from common import machine_info, versions, write_json_atomic

TARGET_SPEEDUP = 2.0
TARGET_MEMORY = 4.0

_MEMORY_PROBE = r"""
import json, resource, sys, tracemalloc
sys.path.insert(0, sys.argv[3])
import numpy as np
from piezohyst.data import load_record
import pyarrow, pyarrow.csv  # imported before the baseline so that only the load is measured

def peak_kib():
    # VmHWM: this process's peak resident set (ru_maxrss is inherited from the parent across exec)
    try:
        for line in open("/proc/self/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

base = peak_kib()
tracemalloc.start()
if sys.argv[1] == "load_record":
    rec = load_record(sys.argv[2], input="u", output="y", time="t")
    n = rec.n
else:
    a = np.loadtxt(sys.argv[2], delimiter=",", skiprows=1)
    n = a.shape[0]
_, peak = tracemalloc.get_traced_memory()
rss = peak_kib()
print(json.dumps({"rows": n, "tracemalloc_peak_bytes": peak, "rss_before_kib": base, "rss_peak_kib": rss}))
"""


def write_record(path: Path, rows: int) -> None:
    """The CSV: 4 float columns written by numpy (``%.17g``) with a header line."""
    fs = 10_000.0
    t = np.arange(rows) / fs
    u = 75.0 + 75.0 * np.sin(2 * np.pi * 5.0 * t)
    y = 1e-6 * (0.8 * u + 5.0 * np.sin(2 * np.pi * 5.0 * t + 0.3))
    aux = np.cos(2 * np.pi * 50.0 * t)
    np.savetxt(path, np.column_stack([t, u, y, aux]), delimiter=",", header="t,u,y,aux", comments="", fmt="%.17g")


def memory(which: str, path: Path) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", _MEMORY_PROBE, which, str(path), str(ROOT / "python")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    m = json.loads(out)
    size = path.stat().st_size
    m["rss_growth_bytes"] = (m["rss_peak_kib"] - m["rss_before_kib"]) * 1024
    m["tracemalloc_peak_over_file"] = m["tracemalloc_peak_bytes"] / size
    m["rss_growth_over_file"] = m["rss_growth_bytes"] / size
    return m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=HERE / "results" / "load_csv.json")
    args = ap.parse_args(argv)

    from piezohyst.data import load_record

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "record.csv"
        write_record(path, args.rows)
        size = path.stat().st_size
        # both once first (page cache warm, imports done); the results must agree
        rec = load_record(path, input="u", output="y", time="t")
        ref = np.loadtxt(path, delimiter=",", skiprows=1)
        np.testing.assert_array_equal(rec.input, ref[:, 1])
        np.testing.assert_array_equal(rec.output, ref[:, 2])
        np.testing.assert_array_equal(rec.time, ref[:, 0])
        times: dict[str, list[float]] = {"load_record": [], "numpy_loadtxt": []}
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            load_record(path, input="u", output="y", time="t")
            times["load_record"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            np.loadtxt(path, delimiter=",", skiprows=1)
            times["numpy_loadtxt"].append(time.perf_counter() - t0)
        mem = {k: memory(k, path) for k in times}

    med = {k: statistics.median(v) for k, v in times.items()}
    speedup = med["numpy_loadtxt"] / med["load_record"]
    mem_ratio = max(mem["load_record"]["tracemalloc_peak_over_file"], mem["load_record"]["rss_growth_over_file"])
    payload = {
        "benchmark": "load_csv",
        "timestamp_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "rows": args.rows,
        "columns": 4,
        "file_bytes": size,
        "repeats": args.repeats,
        "seconds": times,
        "median_seconds": med,
        "speedup_vs_numpy_loadtxt": speedup,
        "memory": mem,
        "peak_memory_over_file": mem_ratio,
        "target": {"speedup_at_least": TARGET_SPEEDUP, "peak_memory_over_file_at_most": TARGET_MEMORY},
        "meets_target": bool(speedup >= TARGET_SPEEDUP and mem_ratio <= TARGET_MEMORY),
        "machine": machine_info(),
        "versions": versions(),
    }
    import pyarrow

    payload["versions"]["pyarrow"] = pyarrow.__version__
    write_json_atomic(args.out, payload)
    print(
        f"{args.rows} rows x 4 columns, {size / 1e6:.1f} MB: load_record {med['load_record']:.3f} s, "
        f"numpy.loadtxt {med['numpy_loadtxt']:.3f} s (x{speedup:.1f}); peak memory {mem_ratio:.2f} x the file "
        f"(tracemalloc {mem['load_record']['tracemalloc_peak_bytes'] / 1e6:.0f} MB, "
        f"RSS growth {mem['load_record']['rss_growth_bytes'] / 1e6:.0f} MB) -> {args.out}"
    )
    return 0 if payload["meets_target"] else 1


if __name__ == "__main__":
    sys.exit(main())
