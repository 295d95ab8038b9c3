"""Summarize the benchmark results in bench/results/*.json as Markdown (the README's
performance section is pasted from this output).

    .venv/bin/python bench/report.py
"""
from __future__ import annotations

import json
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def _g(x):
    return f"{x / 1e9:.2f} G" if x >= 1e9 else f"{x / 1e6:.0f} M"


def pi_batch(d) -> list[str]:
    out = ["**PI batch evaluation** (`bench/pi_batch.py`, play-operator updates/s, median; "
           "NumPy references single-threaded, same run):", "",
           "| workload (S sets × n operators × N samples) | piezohyst 1 thread | piezohyst 2 threads | "
           "NumPy per-step | NumPy tuned (blocked) | 2T / per-step | 2T / tuned |",
           "|---|---|---|---|---|---|---|"]
    for e in d["workloads"]:
        p1, p2 = e["piezohyst"]["1_thread"]["updates_per_s"], e["piezohyst"]["2_thread"]["updates_per_s"]
        out.append(f"| {e['S']} × {e['n']} × {e['N']} | {_g(p1)} | {_g(p2)} | {_g(e['numpy_per_step']['updates_per_s'])} | "
                   f"{_g(e['numpy']['updates_per_s'])} | {e['speedup']['2_thread_vs_numpy_per_step']:.0f}× | "
                   f"{e['speedup']['2_thread_vs_numpy']:.0f}× |")
    return out


def closed_loop(d) -> list[str]:
    out = ["", "**Closed loop on the virtual stage** (`bench/closed_loop.py`, 10 kHz PID, public API, median):", "",
           "| case | real-time factor (median / best) | baseline: solve_ivp plant + Python PID | speed-up |",
           "|---|---|---|---|"]
    for name, e in d["closed_loop_rtf"].items():
        out.append(f"| {name} | {e['rtf']:.0f}× / {e['rtf_best']:.0f}× | {e['baseline_rtf']:.2f}× | "
                   f"{e['speedup_vs_baseline']:.0f}× |")
    b = d["batch"]
    out += ["", f"Batch of {b['scenarios']} scenarios × {b['seconds_each']:g} s: "
            f"{b['1_thread']['median_s'] * 1e3:.0f} ms on 1 thread, {b['2_thread']['median_s'] * 1e3:.0f} ms on 2 "
            f"(scaling {b['scaling_2T_over_1T']:.2f}×; the Rust call alone {b['core_call_scaling_2T_over_1T']:.2f}×); "
            "results identical for 1 and 2 threads."]
    return out


def identify_mpi(d) -> list[str]:
    h = d["headline"]
    out = ["", "**MPI identification** (`bench/identify_mpi.py`, 10 000 samples, time to reach within 1 % of "
           "the best RMSE any method found):", "",
           "| method | reached | time to target |", "|---|---|---|"]
    for r in d["runs"]:
        name = r.get("name") or r.get("run") or r.get("label", "?")
        reached = r.get("reached")
        t = r.get("time_to_target_s")
        out.append(f"| {name} | {'yes' if reached else 'no'} | {'' if t is None else f'{t:.3g} s'} |")
    out.append(f"\nTarget ≤ 1 s for piezohyst's least squares: {'PASS' if h['pass'] else 'FAIL'} "
               f"({h['a_time_to_target_s'] * 1e3:.1f} ms).")
    return out


def main():
    lines = []
    for name, fn in (("pi_batch.json", pi_batch), ("closed_loop.json", closed_loop), ("identify_mpi.json", identify_mpi)):
        path = RESULTS / name
        if path.exists():
            d = json.loads(path.read_text())
            lines += fn(d)
            lines.append(f"<sub>{name}: {d.get('timestamp_utc', '')}, {d['machine'].get('cpu_model', '')}, "
                         f"{d['machine'].get('cpu_count', '')} CPUs</sub>")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
