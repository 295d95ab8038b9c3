"""``piezohyst bench``: run every benchmark in the source tree's ``bench/`` and summarize
them in one JSON file and one Markdown table, each figure beside the baseline the same run
measured (and the target it answers to).

The benchmarks themselves are scripts in ``bench/`` (each writes its own detailed JSON to
``bench/results/``); this module runs them in fresh subprocesses, one after the other (they
time themselves and must not compete for the 2 cores), then reads their JSON and extracts
the headline rows. ``--report-only`` skips the runs and summarizes the JSON already there;
``--readme README.md`` replaces the text between ``<!-- bench:begin -->`` and ``<!--
bench:end -->`` with the table.

Examples
--------
>>> from piezohyst.benchmarks import BENCHMARKS
>>> [b.name for b in BENCHMARKS]  # doctest: +NORMALIZE_WHITESPACE
['pi_batch', 'closed_loop', 'identify_mpi', 'c_step', 'mimo_c_step', 'control', 'control_acceptance',
 'demo', 'load_csv', 'identify_speed', 'fleet', 'identify_auto', 'fsm']
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypedDict

from ..errors import DataError, ParameterError
from ..outputs import check_output, check_output_dir, write_atomic
from ..progress import is_silenced

__all__ = ["BENCHMARKS", "Benchmark", "find_bench_dir", "run_suite", "summarize", "to_markdown", "update_readme"]

BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"

#: A benchmark's JSON result, as parsed (its layout is the script's).
Json = dict[str, Any]

#: One row of the summary table.
Row = TypedDict(
    "Row",
    {
        "figure": str,
        "value": Any,
        "unit": str,
        "baseline": str,
        "baseline_value": Any,
        "ratio": Any,
        "ratio_label": str,
        "target": str | None,
        "pass": Any,
    },
)

#: ``print`` or a stand-in, for the progress lines (called with ``flush=True``; ``print``'s
#: overloads fit no single protocol signature).
_Print = Callable[..., object]


@dataclass(frozen=True)
class Benchmark:
    """One script in ``bench/``: how to run it (with its defaults, or with ``quick_args`` for
    ``--quick``), where it writes its JSON, and how to read its headline rows from that JSON.

    Parameters
    ----------
    name : str
        The benchmark's name (``--only``/``--skip``; its JSON is ``<name>.json``).
    script : str
        The script's file name in ``bench/``.
    what : str
        What it measures, for the progress line.
    quick_args : tuple of str
        The script's arguments under ``--quick``.
    rows : callable
        The script's parsed JSON to the summary table's rows.

    Examples
    --------
    >>> from pathlib import Path
    >>> from piezohyst.papers.benchmarks import BENCHMARKS, Benchmark
    >>> b = Benchmark("toy", "toy.py", "a toy", ("--quick",), lambda d: [])
    >>> b.result_path(Path("bench/results")).as_posix()
    'bench/results/toy.json'
    >>> {x.name: x.script for x in BENCHMARKS}["load_csv"]
    'load_csv.py'
    """

    name: str
    script: str
    what: str
    quick_args: tuple[str, ...]
    rows: Callable[[Json], list[Row]] = field(repr=False)

    def result_path(self, results: Path) -> Path:
        """Where the script writes its JSON in the folder ``results``.

        Parameters
        ----------
        results : pathlib.Path
            The results folder (``bench/results`` by default).

        Returns
        -------
        pathlib.Path
            ``results / "<name>.json"``.

        Examples
        --------
        >>> from pathlib import Path
        >>> from piezohyst.papers.benchmarks import BENCHMARKS
        >>> BENCHMARKS[0].result_path(Path("out")).as_posix()
        'out/pi_batch.json'
        """
        return results / f"{self.name}.json"


def _row(
    figure: str,
    value: Any,
    unit: str,
    baseline: str,
    baseline_value: Any,
    *,
    ratio: Any = None,
    ratio_label: str = "",
    target: str | None = None,
    passed: Any = None,
) -> Row:
    """One table row; ``ratio`` is how many times better than the baseline (None: not a
    speed/accuracy ratio)."""
    return {
        "figure": figure,
        "value": value,
        "unit": unit,
        "baseline": baseline,
        "baseline_value": baseline_value,
        "ratio": ratio,
        "ratio_label": ratio_label,
        "target": target,
        "pass": passed,
    }


def _pi_batch_rows(d: Json) -> list[Row]:
    rows: list[Row] = []
    for w in d["workloads"]:
        p2 = w["piezohyst"]["2_thread"]["updates_per_s"]
        sp = w["speedup"]
        label = f"PI batch RMSE, {w['S']} sets × {w['n']} operators × {w['N']} samples, 2 threads"
        t = w.get("targets", {})
        rows.append(
            _row(
                label,
                p2,
                "updates/s",
                "NumPy per-step (vectorized over sets and operators)",
                w["numpy_per_step"]["updates_per_s"],
                ratio=sp["2_thread_vs_numpy_per_step"],
                ratio_label="faster",
                target="≥ 1e9 updates/s and ≥ 100×" if w.get("headline") else None,
                passed=(t.get("updates_per_s_2_thread_ge_1e9") and t.get("speedup_2_thread_vs_numpy_per_step_ge_100"))
                if w.get("headline")
                else None,
            )
        )
        rows.append(
            _row(
                label,
                p2,
                "updates/s",
                "NumPy tuned (blocked across time)",
                w["numpy"]["updates_per_s"],
                ratio=sp["2_thread_vs_numpy"],
                ratio_label="faster",
                target="≥ 100×" if w.get("headline") else None,
                passed=t.get("speedup_2_thread_vs_numpy_ge_100") if w.get("headline") else None,
            )
        )
    return rows


def _closed_loop_rows(d: Json) -> list[Row]:
    rows: list[Row] = []
    for name, e in d["closed_loop_rtf"].items():
        rows.append(
            _row(
                f"closed-loop real-time factor, 10 kHz PID on the virtual stage, {name}, 1 thread (median; "
                f"best {e['rtf_best']:.0f}×)",
                e["rtf"],
                "× real time",
                "scipy solve_ivp plant + Python PID",
                e["baseline_rtf"],
                ratio=e["speedup_vs_baseline"],
                ratio_label="faster",
                target="≥ 1000×",
                passed=e["rtf"] >= 1000,
            )
        )
    b = d["batch"]
    rows.append(
        _row(
            f"batch of {b['scenarios']} closed-loop scenarios × {b['seconds_each']:g} s, 2 threads",
            b["2_thread"]["median_s"],
            "s",
            "the same batch on 1 thread",
            b["1_thread"]["median_s"],
            ratio=b["scaling_2T_over_1T"],
            ratio_label="scaling",
            target="≥ 1.8×",
            passed=b["scaling_2T_over_1T"] >= 1.8,
        )
    )
    for case, a in d["accuracy"].items():
        run = a["piezohyst"].get("tol=0.01") or next(iter(a["piezohyst"].values()))
        f = run["fastest_solve_ivp_at_least_as_accurate"]
        if f is None:
            continue
        rows.append(
            _row(
                f"stage integration, {case}, tolerance 0.01 (max rel. error {run['max_rel_error']:.1e})",
                run["median_s"],
                "s",
                f"fastest solve_ivp as accurate ({f['run']})",
                f["median_s"],
                ratio=f["speedup"],
                ratio_label="faster",
            )
        )
    return rows


def _identify_mpi_rows(d: Json) -> list[Row]:
    h = d["headline"]
    by_kind: dict[str, list[Json]] = {}
    for r in d["runs"]:
        by_kind.setdefault(r["method"], []).append(r)
    rows: list[Row] = []
    a: Json | None = by_kind.get("a", [None])[0]
    for kind, label in (("b", "MPSO alone (median over seeds)"), ("c", "pyswarms + NumPy")):
        runs = by_kind.get(kind)
        if not runs:
            continue
        times = sorted(r["time_to_target_s"] for r in runs if r["reached"])
        if len(times) == len(runs):
            base, ratio = times[len(times) // 2], times[len(times) // 2] / h["a_time_to_target_s"]
        else:  # the time it was given, a lower bound of its time to the target
            base, ratio = max(r.get("total_s") or 0.0 for r in runs), None
            label += " — did not reach the target in this time"
        rows.append(
            _row(
                "MPI identification, 10 000 samples: time to within 1 % of the best RMSE (least squares)",
                a["time_to_target_s"] if a else None,
                "s",
                label,
                base,
                ratio=ratio,
                ratio_label="faster",
                target="≤ 1 s" if kind == "b" else None,
                passed=h["pass"] if kind == "b" else None,
            )
        )
    return rows


def _c_step_rows(d: Json) -> list[Row]:
    rows: list[Row] = []
    base = (d.get("rust_api_baseline") or {}).get("results", {})
    # the C cases whose Rust-API counterpart has another name (the rest share theirs)
    rust_name = {
        "MPI inverse feedforward (open loop behind the inverse)": "PI-type inverse, 9 operators (MPI feedforward)",
        "PI inverse, 9 operators (phs_model_inverse_step)": "PI inverse, 9 operators (inverse_step)",
        "MPI inverse, 9 operators (phs_model_inverse_step)": "MPI inverse, 9 operators (inverse_step)",
    }
    target = d.get("target_ns", {})
    for name, s in d["summary"].items():
        b = base.get(rust_name.get(name, name), {}).get("mean")
        t = target.get(name)
        rows.append(
            _row(
                f"one step from C: {name} (worst of {d['steps_per_case']:.0e}: {s['worst_ns'] / 1e3:.0f} µs)",
                s["mean_ns"],
                "ns",
                "the same step through the Rust API" if b else "—",
                b,
                ratio=(b / s["mean_ns"]) if b else None,
                ratio_label="C / Rust speed",
                target=f"≤ {t:.0f} ns" if t else None,
                passed=(s["mean_ns"] <= t) if t else None,
            )
        )
    return rows


def _mimo_c_step_rows(d: Json) -> list[Row]:
    """MIMO model steps from C (issue 15): the median per case (means carry the preemption of a
    shared machine), against 10 % of the 156 µs sample period of the 6400 Hz mirror."""
    return [
        _row(
            f"one MIMO step from C: {name} (median of {d['steps_per_case']:.0e})",
            s["median_ns"],
            "ns",
            "—",
            None,
            target="≤ 15600 ns (10 % of a 6400 Hz period)",
            passed=s["median_ns"] <= 15600.0,
        )
        for name, s in d["summary"].items()
    ]


def _control_rows(d: Json) -> list[Row]:
    rows: list[Row] = []
    s1 = d["seed1_table3"]
    if "each tuned for itself" in s1["rmse_um"]:
        # each controller tuned for itself (issue 19), against the SMC tuned for itself
        for ref, r in s1["rmse_um"]["each tuned for itself"].items():
            rows.append(
                _row(
                    f"seed 1 Table 3, {ref}: tracking RMSE, SMC + CEMF (each tuned for itself; PID + FF "
                    f"{r['PID+FF']:.3g} µm, noise floor {r['noise floor']:.3g} µm)",
                    r["SMC+CEMF"],
                    "µm",
                    "SMC without the CEMF model (tuned for itself)",
                    r["SMC"],
                    ratio=r["SMC"] / r["SMC+CEMF"],
                    ratio_label="smaller error",
                )
            )
    else:
        key = next(iter(s1["rmse_um"]))
        for ref, r in s1["rmse_um"][key].items():
            rows.append(
                _row(
                    f"seed 1 Table 3, {ref}: tracking RMSE, SMC + CEMF ({key})",
                    r["SMC+CEMF"],
                    "µm",
                    "SMC without the CEMF model (same gains)",
                    r["SMC"],
                    ratio=r["SMC"] / r["SMC+CEMF"],
                    ratio_label="smaller error",
                )
            )
    tw = s1["tuning_wall_s"]
    worst = max(tw.values())
    rows.append(
        _row(
            "gain tuning wall time (CSS on the identified model, slowest case)",
            worst,
            "s",
            "—",
            None,
            target="≤ 60 s",
            passed=worst <= 60,
        )
    )
    s2 = d["seed2"]
    for case, r in s2["table3_linearity_percent"].items():
        none, ff = r["none"], r["feedforward"]
        rows.append(
            _row(
                f"seed 2 Table 3, {case}: linearity error with MPI inverse feedforward",
                ff,
                "%",
                "no compensation",
                none,
                ratio=none / ff,
                ratio_label="smaller error",
                target="≤ 1 %",
                passed=ff <= 1.0,
            )
        )
    for ref, r in s2["table4_80hz"].items():
        ab, ff = r["feedforward+ABSMC"]["normalized_rms_error"], r["feedforward"]["normalized_rms_error"]
        rows.append(
            _row(
                f"seed 2 Table 4, 80 Hz {ref} amplitude: normalized RMS error, feedforward + ABSMC",
                ab,
                "",
                "feedforward alone",
                ff,
                ratio=ff / ab,
                ratio_label="smaller error",
                target="below feedforward alone",
                passed=ab < ff,
            )
        )
    return rows


def _demo_rows(d: Json) -> list[Row]:
    rows: list[Row] = []
    for mode, r in d["runs"].items():
        rows.append(
            _row(
                f"`piezohyst demo{' --quick' if mode == 'quick' else ''}` wall time",
                r["wall_s"],
                "s",
                "— (a wall-time target)",
                None,
                target=f"≤ {r['target_s']:.0f} s",
                passed=r["pass"],
            )
        )
    return rows


def _load_csv_rows(d: Json) -> list[Row]:
    med = d["median_seconds"]
    speedup = d["speedup_vs_numpy_loadtxt"]
    mem = d["peak_memory_over_file"]
    what = f"{d['rows']:,} rows × {d['columns']} columns CSV ({d['file_bytes'] / 1e6:.0f} MB)"
    return [
        _row(
            f"load_record, {what}: median wall time",
            med["load_record"],
            "s",
            "numpy.loadtxt",
            med["numpy_loadtxt"],
            ratio=speedup,
            ratio_label="faster",
            target="≥ 2× faster",
            passed=speedup >= 2.0,
        ),
        _row(
            f"load_record, {what}: peak memory / file size",
            mem,
            "×",
            "— (a memory target)",
            None,
            target="≤ 4×",
            passed=mem <= 4.0,
        ),
    ]


def _identify_speed_rows(d: Json) -> list[Row]:
    rows: list[Row] = []
    for c in d["cases"]:
        if c.get("metric") == "held_out_percent":  # an accuracy case: the worst record
            value, base = c["held_out_percent"], c["baseline_held_out_percent"]
            rows.append(
                _row(
                    f"{c['case']}: RMSE % of range, worst of {len(c['records'])} records",
                    value,
                    "%",
                    c["baseline"].split(":")[0],
                    base,
                    ratio=base / value if value > 0 else None,
                    ratio_label="smaller error",
                    target=f"≤ {c['target_percent']:g} %",
                    passed=value <= c["target_percent"],
                )
            )
            continue
        if c.get("metric") == "ratio_to_best":  # an accuracy case against the best other family
            worst = max(c["records"], key=lambda r: r["ratio_to_best"])
            rows.append(
                _row(
                    f"{c['case']}: RMSE % of range vs the best fixed family's, worst of {len(c['records'])} records",
                    worst["held_out_percent"],
                    "%",
                    f"best family ({worst['best_family']})",
                    worst["best_family_held_out_percent"],
                    ratio=1.0 / c["ratio_to_best"],
                    ratio_label="smaller error",
                    target=f"≤ {c['target_ratio']:g}× the best",
                    passed=c["ratio_to_best"] <= c["target_ratio"],
                )
            )
            continue
        base = c.get("baseline_wall_s")
        rows.append(
            _row(
                f"{c['case']}: wall time (train RMSE {c['train_rmse_percent']:.4g} %)",
                c["wall_s"],
                "s",
                c["baseline"].split(":")[0],
                base,
                ratio=None if base is None else base / c["wall_s"],
                ratio_label="faster",
                target=f"≤ {c['target_s']:.0f} s",
                passed=c["wall_s"] <= c["target_s"],
            )
        )
    return rows


def _fleet_rows(d: Json) -> list[Row]:
    f, r, o = d["fleet_identify"], d["robustness"], d["overhead"]
    runs = f["runs"]
    what = f"{f['records']} × {f['samples_per_record']:,}-sample records, boucwen, RAYON_NUM_THREADS=1"
    local, serial = r["cases"]["local"], r["cases"]["serial"]
    return [
        _row(
            f"fleet identify, {what}: 2 workers, wall with start-up "
            f"({runs['workers2']['records_per_s']:.3g} records/s)",
            runs["workers2"]["wall_s"],
            "s",
            "1 worker",
            runs["workers1"]["wall_s"],
            ratio=f["speedup_2_vs_1_workers"],
            ratio_label="faster",
            target="≥ 1.6×",
            passed=f["pass"],
        ),
        _row(
            f"fleet identify, {what}: 2 workers vs one process without Dask",
            runs["workers2"]["wall_s"],
            "s",
            "--scheduler serial",
            runs["serial"]["wall_s"],
            ratio=f["speedup_2_workers_vs_serial"],
            ratio_label="faster",
        ),
        _row(
            f"robustness, {r['runs']:,} closed-loop runs of 0.2 s at 10 kHz ({local['runs_per_s']:.4g} runs/s)",
            local["wall_s"],
            "s",
            "--scheduler serial (rayon)",
            serial["wall_s"],
            ratio=serial["wall_s"] / local["wall_s"],
            ratio_label="faster",
            target="≤ 10 s",
            passed=r["pass"],
        ),
        _row(
            "Dask per-task overhead (no-op task, 2 workers)",
            o["per_task_overhead_s"] * 1e3,
            "ms",
            "— (cluster start-up, s)",
            o["cluster_start_s"],
        ),
    ]


def _fsm_rows(d: Json) -> list[Row]:
    target = d["published"]["LFR + neural net (test, target)"]
    base = "mimo-linear (order 28)"
    protocols = [(" and ".join(f"fit {x['fit']}→{x['score']}" for x in d["directions"]), d["mean_rmse_um"])]
    if d.get("leave_one_out"):
        held = ", ".join(str(r["held_out"]) for r in d["leave_one_out"]["runs"])
        loo = d["leave_one_out"]["mean_rmse_um"]
        protocols.append((f"fit on 5 of 6 realizations per level, realization {held} held out in turn", loo))
    rows = [
        _row(
            f"FSM {lev}: held-out RMSE of {label} ({split}, init from 100 outputs)",
            rm[lev],
            "µm",
            "mimo-linear order 28, same split",
            means[base][lev],
            ratio=means[base][lev] / rm[lev],
            ratio_label="lower",
            target=f"≤ {target[lev]}",
            passed=rm[lev] <= target[lev],
        )
        for split, means in protocols
        for label, rm in means.items()
        if label.startswith("mimo-lfr")
        for lev in rm
    ]
    if d.get("simulate_s") is not None:
        rows.append(
            _row(
                "FSM: one simulate call in the process, 8192 samples, init from 100 outputs",
                d["simulate_s"],
                "s",
                "—",
                None,
                target="≤ 1 s",
                passed=d["simulate_s"] <= 1.0,
            )
        )
    if d.get("auto"):
        auto = d["auto"]
        rows.append(
            _row(
                f"FSM: piezohyst identify TRAIN_DIR --model auto, a new process (chose {auto['chosen']}"
                + (" + static channels" if auto["static_channels"] else "")
                + ")",
                auto["wall_s"],
                "s",
                "—",
                None,
                target="≤ 600 s",
                passed=auto["wall_s"] <= 600,
            )
        )
        slowest = max(auto["simulate_cli_s"].values())
        rows.append(
            _row(
                "FSM: piezohyst simulate fsm.json U.npy --init-output Y0.npy, a new process, slowest of one per level",
                slowest,
                "s",
                "—",
                None,
                target="≤ 1 s",
                passed=slowest <= 1.0,
            )
        )
    return rows


_AUTO_RECORDS = {
    "yan9a": "yan9a (200 Hz, measured)",
    "5khz": "5 kHz ±150 V lookalikes (time column, lead-in)",
    "10khz": "10 kHz two-column lookalikes with drift",
}


def _identify_auto_rows(d: Json) -> list[Row]:
    rows: list[Row] = []
    for kind, s in d["summary"].items():
        if not s["runs"]:
            continue
        base = s.get("baseline_median_percent")
        rows.append(
            _row(
                f"identify --model auto, {_AUTO_RECORDS.get(kind, kind)}: median validation RMSE (state carried), "
                f"{s['met']}/{s['runs']} runs within target"
                + ("" if s.get("baseline_met") is None else f" (baseline {s['baseline_met']}/{s['runs']})"),
                s["median_percent"],
                "% of range",
                "--lag 0 --drift none",
                base,
                ratio=None if base is None else base / s["median_percent"],
                ratio_label="lower",
                target=f"≤ {s['target_percent']:g} % every run",
                passed=s["met"] == s["runs"] and s["reproduced"],
            )
        )
    return rows


def _control_acceptance_rows(d: Json) -> list[Row]:
    rows: list[Row] = []
    worst = d["robustness"]["worst_ratio"]
    nominal = d["robustness_nominal_tuning"]["worst_ratio"]
    for name, w in worst.items():
        rows.append(
            _row(
                f"{name} tuned for the model's ±20 % variants: worst RMSE / nominal over perturbed and "
                "structurally different stages",
                w,
                "×",
                "tuned for the identified model alone",
                nominal[name],
                ratio=nominal[name] / w,
                ratio_label="smaller",
                target="≤ 3×",
                passed=w <= 3.0,
            )
        )
    ff = d["compensation"]["rmse"]["feedforward_max_error_percent"]
    alone = d["compensation"]["rmse"]["inverse_alone_max_error_percent"]
    for f in (10, 50, 100):
        keys = [k for k in ff if k.startswith(f"{f} Hz")]
        worst_ff = max(ff[k] for k in keys)
        worst_alone = max(alone[k] for k in keys)
        rows.append(
            _row(
                f"dynamic-inversion feedforward at {f} Hz: max|y - r| / range",
                worst_ff,
                "%",
                "the hysteresis inverse alone",
                worst_alone,
                ratio=worst_alone / worst_ff,
                ratio_label="smaller error",
                target="≤ 1 %",
                passed=worst_ff <= 1.0,
            )
        )
    for amp, r in d["compensation"]["rmse"]["table4_80hz"].items():
        c = r["compensated"]["normalized_max_error"]
        rows.append(
            _row(
                f"80 Hz {amp} amplitude: normalized max error, dynamic inversion + FilteredPID (tuned)",
                c,
                "",
                "PID + static feedforward, tuned the same way",
                r["PID+FF"]["normalized_max_error"],
                ratio=r["ratio"],
                ratio_label="smaller error",
                target="≤ 0.0054 and ≥ 6×",
                passed=c <= 0.0054 and r["ratio"] >= 6,
            )
        )
    # every seed of a multi-seed run (bench/control_acceptance.py --seeds ...): the worst
    # robustness ratio and, per tuning objective, the 80 Hz amplitude with the smaller ratio
    for seed, sd in d.get("seeds", {}).items():
        w = max(sd["worst_ratio"].values())
        wn = max(sd["worst_ratio_nominal_tuning"].values())
        rows.append(
            _row(
                f"seed {seed}: worst RMSE / nominal of SMC, SMC+CEMF, PID+FF tuned for the model's ±20 % variants",
                w,
                "×",
                "tuned for the identified model alone",
                wn,
                ratio=wn / w,
                ratio_label="smaller",
                target="≤ 3×",
                passed=w <= 3.0,
            )
        )
        for obj, amps in sd["table4_80hz"].items():
            amp, r = min(amps.items(), key=lambda kv: kv[1]["ratio"])
            rows.append(
                _row(
                    f"seed {seed}: 80 Hz {amp} amplitude (the smaller ratio), both tuned for {obj}: "
                    "normalized max error, dynamic inversion + FilteredPID",
                    r["compensated"],
                    "",
                    "PID + static feedforward, tuned the same way",
                    r["PID+FF"],
                    ratio=r["ratio"],
                    ratio_label="smaller error",
                    target="≤ 0.0054 and ≥ 6×",
                    passed=r["compensated"] <= 0.0054 and r["ratio"] >= 6,
                )
            )
    return rows


BENCHMARKS: tuple[Benchmark, ...] = (
    Benchmark(
        "pi_batch",
        "pi_batch.py",
        "batch PI evaluation vs NumPy",
        ("--rounds", "1", "--reps", "2", "--numpy-reps", "1", "--min-time", "0.05", "--max-reps", "3"),
        _pi_batch_rows,
    ),
    Benchmark(
        "closed_loop",
        "closed_loop.py",
        "closed-loop real-time factor, batch scaling, integration accuracy",
        ("--rounds", "1", "--reps", "2", "--batch-reps", "1", "--min-time", "0.05", "--max-reps", "3"),
        _closed_loop_rows,
    ),
    Benchmark(
        "identify_mpi",
        "identify_mpi.py",
        "MPI identification: least squares vs MPSO vs pyswarms",
        ("--reps", "2", "--iterations", "60", "--mpso-seeds", "0", "--vp-seeds", "0", "--cap", "5"),
        _identify_mpi_rows,
    ),
    Benchmark("c_step", "c_step.py", "ns per step from C", ("--rounds", "1"), _c_step_rows),
    Benchmark("mimo_c_step", "mimo_c_step.py", "ns per MIMO model step from C", ("--rounds", "1"), _mimo_c_step_rows),
    Benchmark("control", "control.py", "seed 1 / seed 2 control tables, tuning time", ("--quick",), _control_rows),
    Benchmark(
        "control_acceptance",
        "control_acceptance.py",
        "issue 19: robustness, dynamic inversion, 80 Hz compensation (each controller tuned for itself)",
        ("--quick",),
        _control_acceptance_rows,
    ),
    Benchmark("demo", "demo.py", "wall time of piezohyst demo", ("--modes", "quick"), _demo_rows),
    Benchmark(
        "load_csv",
        "load_csv.py",
        "load_record vs numpy.loadtxt on a large CSV",
        ("--rows", "200000", "--repeats", "2"),
        _load_csv_rows,
    ),
    Benchmark(
        "identify_speed",
        "identify_speed.py",
        "Preisach 48 levels and huber + structure fit, against baselines in the same run",
        ("--quick",),
        _identify_speed_rows,
    ),
    Benchmark(
        "fleet",
        "fleet.py",
        "Dask scale-out: fleet identify 2 vs 1 workers, robustness runs/s, per-task overhead",
        ("--quick",),
        _fleet_rows,
    ),
    Benchmark(
        "identify_auto",
        "identify_auto.py",
        "issue 14's acceptance command on yan9a and lookalike records, against --lag 0 --drift none",
        ("--quick",),
        _identify_auto_rows,
    ),
    Benchmark(
        "fsm",
        "fsm.py",
        "Fine Steering Mirror (issue 15): MIMO LFR vs linear on held-back realizations, per level",
        ("--quick",),
        _fsm_rows,
    ),
)
_BY_NAME = {b.name: b for b in BENCHMARKS}


def find_bench_dir(explicit: str | Path | None = None) -> Path:
    """The ``bench/`` directory of the source tree this package was built from (or
    ``explicit``).

    Parameters
    ----------
    explicit : str or pathlib.Path, optional
        A ``bench/`` directory given by the caller (``--bench-dir``): checked to hold
        ``common.py``.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ParameterError
        ``explicit`` is not a ``bench/`` directory, or none is beside this installation.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from piezohyst.papers.benchmarks import find_bench_dir
    >>> d = tempfile.mkdtemp()
    >>> find_bench_dir(d)                              # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: --bench-dir = '...' is not piezohyst's bench/ directory (no common.py in it)
    >>> _ = open(f"{d}/common.py", "w").close()
    >>> find_bench_dir(d) == Path(d)
    True
    """
    if explicit is not None:
        p = Path(explicit)
        if not (p / "common.py").is_file():
            raise ParameterError(f"--bench-dir = '{p}' is not piezohyst's bench/ directory (no common.py in it)")
        return p
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "bench" / "common.py").is_file():
            return parent / "bench"
    raise ParameterError(
        "the benchmarks live in the source tree's bench/ directory, which is not beside this "
        f"installation ({here.parent}); pass --bench-dir"
    )


def select(only: Sequence[str] | None = None, skip: Sequence[str] | None = None) -> list[Benchmark]:
    for arg, names in (("--only", only), ("--skip", skip)):
        for n in names or ():
            if n not in _BY_NAME:
                raise ParameterError(f"{arg} {n!r} is not a benchmark; choose from {', '.join(_BY_NAME)}")
    chosen = [b for b in BENCHMARKS if (not only or b.name in only) and b.name not in (skip or ())]
    if not chosen:
        raise ParameterError("--only/--skip leave no benchmark to run")
    return chosen


def run_suite(
    benchmarks: Sequence[Benchmark], bench_dir: Path, results: Path, *, quick: bool = False, print_fn: _Print = print
) -> dict[str, dict[str, Any]]:
    """Run each benchmark script in a fresh subprocess, writing its JSON to ``results``.
    A failing script is recorded (exit code and the end of its stderr) and the others still
    run.

    Parameters
    ----------
    benchmarks : sequence of Benchmark
        The benchmarks to run, in order.
    bench_dir : pathlib.Path
        The ``bench/`` directory holding the scripts (its parent is the working directory).
    results : pathlib.Path
        The folder the scripts write their JSON to.
    quick : bool
        Run each with its ``quick_args``.
    print_fn : callable
        Takes the progress lines (``print`` by default).

    Returns
    -------
    dict
        ``{name: {"status": "ok" or "failed", "wall_s", "command", ...}}``; a failed one
        also has ``"exit_code"`` and ``"stderr_tail"``.

    Examples
    --------
    A toy ``bench/`` with one script that writes its JSON and one that fails:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from piezohyst.papers.benchmarks import Benchmark, run_suite
    >>> bench = Path(tempfile.mkdtemp()) / "bench"
    >>> bench.mkdir()
    >>> _ = (bench / "ok.py").write_text("import sys; open(sys.argv[2], 'w').write('{}')")
    >>> _ = (bench / "bad.py").write_text("raise SystemExit('no data')")
    >>> toys = [Benchmark(n, f"{n}.py", n, (), lambda d: []) for n in ("ok", "bad")]
    >>> status = run_suite(toys, bench, bench, print_fn=lambda *a, **k: None)
    >>> status["ok"]["status"], (bench / "ok.json").read_text()
    ('ok', '{}')
    >>> status["bad"]["status"], status["bad"]["exit_code"], status["bad"]["stderr_tail"]
    ('failed', 1, 'no data')
    """
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    status: dict[str, dict[str, Any]] = {}
    for i, b in enumerate(benchmarks, 1):
        out = b.result_path(results)
        cmd = [sys.executable, str(bench_dir / b.script), "--out", str(out), *(b.quick_args if quick else ())]
        print_fn(f"[{i}/{len(benchmarks)}] {b.name}: {b.what} ...", flush=True)
        t0 = time.perf_counter()
        p = subprocess.run(cmd, cwd=bench_dir.parent, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if p.returncode == 0 and out.is_file():
            status[b.name] = {"status": "ok", "wall_s": wall, "command": cmd[1:]}
            print_fn(f"      done in {wall:.0f} s", flush=True)
        else:
            tail = "\n".join((p.stderr or p.stdout).strip().splitlines()[-15:])
            status[b.name] = {
                "status": "failed",
                "wall_s": wall,
                "command": cmd[1:],
                "exit_code": p.returncode,
                "stderr_tail": tail,
            }
            print_fn(
                f"      FAILED (exit {p.returncode}): {tail.splitlines()[-1] if tail else 'no output'}", flush=True
            )
    return status


def summarize(
    benchmarks: Sequence[Benchmark], results: Path, run_status: dict[str, dict[str, Any]] | None = None
) -> Json:
    """One summary from the JSON files in ``results``: per benchmark its rows, the time
    its JSON was written and the machine it ran on.

    Parameters
    ----------
    benchmarks : sequence of Benchmark
        The benchmarks to summarize.
    results : pathlib.Path
        The folder of their JSON files.
    run_status : dict, optional
        :func:`run_suite`'s return (``None``: ``--report-only``, the JSON already there).

    Returns
    -------
    dict
        ``{"benchmarks": {name: {"status", "rows", ...}}, "targets": {"met", "judged",
        "missed"}, ...}``; a benchmark without its JSON has status ``"missing"``.

    Raises
    ------
    DataError
        A JSON file is not one its benchmark's reader understands.

    Examples
    --------
    >>> import json, tempfile
    >>> from pathlib import Path
    >>> from piezohyst.papers.benchmarks import Benchmark, summarize
    >>> results = Path(tempfile.mkdtemp())
    >>> _ = (results / "toy.json").write_text(json.dumps({"ms": 2.5}))
    >>> row = dict(figure="toy step", value=None, unit="ms", baseline="—", baseline_value=None,
    ...            ratio=None, ratio_label="", target="≤ 3 ms", **{"pass": None})
    >>> toy = Benchmark("toy", "toy.py", "a toy", (), lambda d: [dict(row, value=d["ms"], **{"pass": d["ms"] <= 3})])
    >>> s = summarize([toy, Benchmark("gone", "gone.py", "absent", (), lambda d: [])], results)
    >>> s["benchmarks"]["toy"]["rows"][0]["value"], s["benchmarks"]["gone"]["status"], s["targets"]["met"]
    (2.5, 'missing', 1)
    """
    out: Json = {
        "benchmark": "suite",
        "timestamp_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "results_dir": "bench/results"
        if (results.name == "results" and results.parent.name == "bench")
        else str(results),
        "benchmarks": {},
    }
    for b in benchmarks:
        entry = dict((run_status or {}).get(b.name, {}))
        path = b.result_path(results)
        if entry.get("status") == "failed":
            out["benchmarks"][b.name] = entry
            continue
        if not path.is_file():
            entry.update(status="missing", rows=[])
            out["benchmarks"][b.name] = entry
            continue
        try:
            d = json.loads(path.read_text())
            rows = b.rows(d)
        except (ValueError, KeyError, TypeError, IndexError, ZeroDivisionError, RecursionError) as e:
            raise DataError(
                f"{path}: not a result of bench/{b.script} this version reads ({type(e).__name__}: {e})"
            ) from None
        m = d.get("machine")
        entry.update(
            status=entry.get("status", "ok"),
            result_file=path.name,
            rows=rows,
            written_utc=d.get("timestamp_utc", "undated"),
            machine=(f"{m.get('cpu_model')}, {m.get('cpu_count')} CPUs" if isinstance(m, dict) else m),
        )
        out["benchmarks"][b.name] = entry
    rows = [r for e in out["benchmarks"].values() for r in e.get("rows", [])]
    judged = [r for r in rows if r["pass"] is not None]
    out["targets"] = {
        "met": sum(bool(r["pass"]) for r in judged),
        "judged": len(judged),
        "missed": [r["figure"] for r in judged if not r["pass"]],
    }
    return out


def _num(x: float | None, unit: str = "") -> str:
    if x is None:
        return "—"
    if unit == "updates/s":
        return f"{x / 1e9:.2f} G/s" if x >= 1e9 else f"{x / 1e6:.0f} M/s"
    if unit == "s":
        return f"{x * 1e3:.3g} ms" if x < 1 else f"{x:.3g} s"
    if unit == "× real time":
        return _times(x)
    if unit == "ns":
        return f"{x:.0f} ns"
    if unit in ("µm", "%"):
        return f"{x:.3g} {unit}"
    return f"{x:.3g}"


def _times(x: float) -> str:
    return f"{x:.3g}×" if x < 100 else f"{x:.0f}×"


def to_markdown(summary: Json) -> str:
    """The summary as one Markdown table plus a provenance line per benchmark.

    Parameters
    ----------
    summary : dict
        :func:`summarize`'s return.

    Returns
    -------
    str
        The table, the count of targets met, and the provenance line.

    Examples
    --------
    >>> from piezohyst.papers.benchmarks import to_markdown
    >>> row = dict(figure="toy step", value=2.5, unit="ns", baseline="Rust", baseline_value=5.0,
    ...            ratio=2.0, ratio_label="faster", target="≤ 3 ns", **{"pass": True})
    >>> summary = {"results_dir": "bench/results", "targets": {"met": 1, "judged": 1, "missed": []},
    ...            "benchmarks": {"toy": {"status": "ok", "rows": [row], "result_file": "toy.json"}}}
    >>> print(to_markdown(summary).splitlines()[2])
    | toy | toy step | 2 ns | Rust | 5 ns | 2× faster | ≤ 3 ns: **met** |
    """
    lines = [
        "| benchmark | figure | piezohyst | baseline (same run) | baseline | ratio | target |",
        "|---|---|---|---|---|---|---|",
    ]
    notes = []
    for name, e in summary["benchmarks"].items():
        if e.get("status") != "ok":
            lines.append(f"| {name} | **{e.get('status')}** | — | — | — | — | — |")
            continue
        for r in e["rows"]:
            ratio = "—" if r["ratio"] is None else f"{_times(r['ratio'])} {r['ratio_label']}".strip()
            target = "—" if r["target"] is None else f"{r['target']}: {'**met**' if r['pass'] else '**missed**'}"
            lines.append(
                f"| {name} | {r['figure']} | {_num(r['value'], r['unit'])} | {r['baseline']} | "
                f"{_num(r['baseline_value'], r['unit'])} | {ratio} | {target} |"
            )
        notes.append(
            f"`{summary['results_dir']}/{e['result_file']}` {e.get('written_utc', '')}, {e.get('machine') or ''}"
        )
    t = summary["targets"]
    lines += [
        "",
        f"Targets met: {t['met']} of {t['judged']}." + (f" Missed: {'; '.join(t['missed'])}." if t["missed"] else ""),
    ]
    lines += ["", "<sub>" + " · ".join(notes) + "</sub>"]
    return "\n".join(lines) + "\n"


def check_readme(readme: Path) -> None:
    """``--readme`` is edited in place: a regular file (not a link: the edit would replace the
    link with a copy) in a writable folder, checked before the benchmarks (or the demo) run.

    Parameters
    ----------
    readme : pathlib.Path
        The file to edit.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst.papers.benchmarks import check_readme
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "README.md"
    >>> _ = p.write_text("<!-- bench:begin --> <!-- bench:end -->")
    >>> check_readme(p)  # a regular, writable file: nothing to say
    """
    if readme.is_symlink():
        raise ParameterError(f"--readme = '{readme}' is a symbolic link; give the file it points to")
    if not readme.exists():
        raise ParameterError(f"--readme = '{readme}': no such file")
    check_output(readme, name="--readme", overwrite=True)


def update_readme(
    readme: Path, markdown: str, *, begin: str = BEGIN, end: str = END, generator: str = "piezohyst bench"
) -> None:
    """Replace the text between the markers ``begin`` and ``end`` of ``readme`` (atomically):
    the bench section by default, the demo's with ``<!-- demo:begin -->`` / ``<!-- demo:end -->``.
    A note names the ``generator`` (the command that wrote the section).

    Parameters
    ----------
    readme : pathlib.Path
        The file to edit in place (see :func:`check_readme`).
    markdown : str
        The new section's text.
    begin, end : str
        The markers around the section (kept).
    generator : str
        The command named in the note above the section.

    Raises
    ------
    DataError
        ``readme`` has no ``begin`` ... ``end`` section.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst.papers.benchmarks import update_readme
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "README.md"
    >>> _ = p.write_text("# Bench\\n<!-- bench:begin -->\\nold\\n<!-- bench:end -->\\n")
    >>> update_readme(p, "| new |\\n")
    >>> print(p.read_text())
    # Bench
    <!-- bench:begin -->
    <!-- generated by `piezohyst bench`; edits here are overwritten -->
    | new |
    <!-- bench:end -->
    <BLANKLINE>
    """
    check_readme(readme)
    text = readme.read_text(encoding="utf-8")
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        raise DataError(f"--readme '{readme}' has no '{begin}' ... '{end}' section to replace")
    note = f"<!-- generated by `{generator}`; edits here are overwritten -->\n"
    write_atomic(readme, text[: i + len(begin)] + "\n" + note + markdown + text[j:], name="--readme")


def main(args: argparse.Namespace, print_fn: _Print = print) -> Json:
    """The ``piezohyst bench`` command (``args`` from its parser)."""
    bench_dir = find_bench_dir(args.bench_dir)
    results = Path(args.results) if args.results else bench_dir / "results"
    chosen = select(args.only, args.skip)
    status: dict[str, dict[str, Any]] | None = None
    if args.report_only and not results.is_dir():
        raise ParameterError(f"--results = '{results}' is not a directory of benchmark results")
    # the destinations, before any benchmark runs (piezohyst.outputs)
    check_output_dir(results, name="--results", overwrite=True, names=("summary.json", "summary.md"), parents=True)
    if args.readme:
        check_readme(Path(args.readme))
    if not args.report_only:
        results.mkdir(parents=True, exist_ok=True)
        # the per-benchmark lines are progress: --quiet silences them (the table is still printed)
        steps = print_fn if not is_silenced() else (lambda *a, **k: None)
        status = run_suite(chosen, bench_dir, results, quick=args.quick, print_fn=steps)
    summary = summarize(chosen, results, status)
    summary["quick"] = bool(args.quick) and not args.report_only
    md = to_markdown(summary)
    write_atomic(results / "summary.json", json.dumps(summary, indent=1, default=float) + "\n", name="--results")
    write_atomic(results / "summary.md", md, name="--results")
    if args.readme:
        update_readme(Path(args.readme), md)
    print_fn(md)
    failed = [n for n, e in summary["benchmarks"].items() if e.get("status") != "ok"]
    summary["failed"] = failed
    return summary
