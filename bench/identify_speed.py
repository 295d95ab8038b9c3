"""Identification speed of issue 14 item 7, each case against a named baseline measured in this run.

Usage (from the project root, after the extension is built):

    .venv/bin/python bench/identify_speed.py [--out bench/results/identify_speed.json] [--quick]

Cases (wall clock, ``time.perf_counter``, one process, the same record for a case and its baseline):

``preisach48``
    ``identify(v, y, "preisach", levels=48)`` on a 10,000-sample decaying-amplitude record (a
    sine of 20 periods whose amplitude decays by e^-2.5 over the record, output of a 7-play PI
    plus 0.1 % noise): the solver on the distinct relay patterns (Gram matrix, NNLS).
    Baseline ``bvls-full``: the previous solver, SciPy ``lsq_linear(method="bvls")`` on the whole
    equilibrated ``10,000 x 1,178`` regressor matrix (the same regressors from ``_core.regressors``).
    Target: <= 5 s.
``huber-fit``
    ``identify(v, y, "mpi", structure="fit", loss="huber", rng=0)`` on a 10,000-sample MPI record
    with glitches on 1 % of the samples. Baseline ``squared-fit``: the same call with the
    squared loss. Target: <= 10 s. Besides the training RMSE (against the glitched record), the
    RMSE against the true, noise- and glitch-free output (``clean_rmse_percent``), where the
    robust fit shows; and the process CPU time (``cpu_s``: on a shared machine the wall time
    carries the other processes' load).

``preisach-decaying`` (accuracy)
    ``identify(v[:7000], y[:7000], "preisach", levels=48)`` on 10,000-sample decaying-amplitude
    records from other generators (a PI of 40 operators, a Preisach of a Gaussian density on a
    160-level grid, the 7-operator PI; a decaying sine, a decaying two-tone, 70 decaying
    cycles), scored on samples 7000: with the state carried (``tests/identify/
    test_preisach_decaying.py``'s records). Baseline ``plain``: the previous method (no smoothness
    prior, a 64-extremum memory). Target: <= 1.5 % of the validation range, the worst record.

``rdpi-fit`` (accuracy)
    ``identify(..., "rdpi", structure="fit", rng=0)`` on the 5 kHz records of
    ``tests/identify/test_rdpi_conditioning.py`` (+-150 V; a rate-dependent PI, a PI behind a
    resonance, a Bouc-Wen behind one; lead-in, offset, noise), held out with the state carried,
    against the best of the fixed-structure families (pi, mpi, preisach, rdpi) in the same run;
    with the condition number of the fit's equilibrated regressors. Target: <= 1.5x the best.

Each case records its wall time, its baseline's, and the training RMSE (% of range) of both, so
a faster result that fits worse shows. ``--quick`` skips the slow ``bvls-full`` baseline.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import HERE, extension_digest, machine_info


def preisach_record(n: int = 10_000) -> tuple[np.ndarray, np.ndarray]:
    from piezohyst.models import PI

    t = np.arange(n)
    v = 5.0 + 5.0 * np.sin(2 * np.pi * 20 * t / n) * np.exp(-2.5 * t / n)
    truth = PI(np.arange(1, 8) * 0.6, [0.4, 0.2, 0.1, 0.08, 0.05, 0.03, 0.02], p0=0.5)
    y = truth.simulate(v)
    y = y + 1e-3 * np.ptp(y) * np.random.default_rng(0).standard_normal(n)
    return v, y


def mpi_record(n: int = 10_000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(v, y, clean)``: the input, the measured output (noise, glitches) and the true output."""
    from piezohyst.papers import mpi_seed2

    t = np.linspace(0.0, 1.0, n)
    v = 0.5 - 0.5 * np.cos(2 * np.pi * 20 * t) * (0.65 + 0.35 * np.sin(2 * np.pi * 2 * t))
    v = np.clip(v * (1 + 0.05 * np.sin(2 * np.pi * 53 * t)), 0.0, 1.0)
    clean = mpi_seed2().simulate(v)
    rng = np.random.default_rng(0)
    y = clean + 0.002 * np.ptp(clean) * rng.standard_normal(n)
    y[::100] += 0.2 * np.ptp(clean)  # glitches on 1 % of the samples
    return v, y, clean


def rmse_percent(model: Any, v: np.ndarray, y: np.ndarray) -> float:
    e = model.simulate(v) - y
    return float(np.sqrt(np.mean(e**2)) / np.ptp(y) * 100)


def bench_preisach(quick: bool) -> dict[str, Any]:
    from scipy.optimize import lsq_linear

    from piezohyst import _core, identify
    from piezohyst.models import Preisach

    v, y = preisach_record()
    identify(v[:500], y[:500], "preisach", levels=8)  # imports (SciPy's optimizers) outside the timings
    t0, c0 = time.perf_counter(), time.process_time()
    fit = identify(v, y, "preisach", levels=48)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    out: dict[str, Any] = {
        "case": "identify(preisach, levels=48), 10,000 samples",
        "wall_s": wall,
        "cpu_s": cpu,
        "smoothing": fit.history["smoothing"],
        "train_rmse_percent": fit.train["rmse_percent"],
        "target_s": 5.0,
        "baseline": "bvls-full: scipy lsq_linear(method='bvls') on the whole equilibrated regressor matrix",
    }
    if quick:
        out["baseline_wall_s"] = None
        return out
    template = Preisach(48, (float(v.min()), float(v.max())), np.zeros(48 * 49 // 2))
    t0 = time.perf_counter()
    A = _core.regressors(template.family, list(template.dims), template.to_row(), v)
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-300)
    lb = np.concatenate([[-np.inf], np.zeros(A.shape[1] - 1)]) * scale
    z = lsq_linear(A / scale, y, bounds=(lb, np.full(lb.size, np.inf)), method="bvls", lsmr_tol=None).x
    z = np.maximum(z / scale, [-np.inf, *np.zeros(A.shape[1] - 1)])
    base = Preisach(48, template.input_range, z[2:], z[0], z[1])
    out["baseline_wall_s"] = time.perf_counter() - t0
    out["baseline_train_rmse_percent"] = rmse_percent(base, v, y)
    out["speedup"] = out["baseline_wall_s"] / wall
    return out


def bench_huber_fit() -> dict[str, Any]:
    from piezohyst import identify

    v, y, clean = mpi_record()
    identify(v[:500], y[:500], "mpi", loss="huber")  # imports (SciPy's optimizers) outside the timings
    t0, c0 = time.perf_counter(), time.process_time()
    fit = identify(v, y, "mpi", structure="fit", loss="huber", rng=0)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    t0, c0 = time.perf_counter(), time.process_time()
    base = identify(v, y, "mpi", structure="fit", rng=0)
    base_wall, base_cpu = time.perf_counter() - t0, time.process_time() - c0
    return {
        "case": "identify(mpi, structure='fit', loss='huber'), 10,000 samples, glitches on 1 %",
        "wall_s": wall,
        "cpu_s": cpu,
        "train_rmse_percent": fit.train["rmse_percent"],
        "clean_rmse_percent": rmse_percent(fit.model, v, clean),
        "evaluations": fit.evaluations,
        "target_s": 10.0,
        "baseline": "squared-fit: the same call with loss='squared'",
        "baseline_wall_s": base_wall,
        "baseline_cpu_s": base_cpu,
        "baseline_train_rmse_percent": base.train["rmse_percent"],
        "baseline_clean_rmse_percent": rmse_percent(base.model, v, clean),
        "ratio_to_baseline": wall / base_wall,
    }


def bench_preisach_decaying() -> dict[str, Any]:
    from piezohyst import fit_linear, identify
    from piezohyst.models import Preisach

    records = _test_module("test_preisach_decaying")
    k = records.K
    cases = [("pi40", "sine", 0), ("gauss", "two-tone", 1), ("pi7", "two-tone", 0), ("pi40", "70 cycles", 1)]
    cases += [("gauss", "70 cycles", 0), ("pi7", "sine", 2)]
    rows = []
    t0 = time.perf_counter()
    for kind, shape, seed in cases:
        v, y = records.record(kind, shape, seed)
        fit = identify(v[:k], y[:k], "preisach", levels=48)
        lo_hi = (float(v[:k].min()), float(v[:k].max()))
        plain = fit_linear(Preisach(48, lo_hi, np.zeros(1176), memory=64), v[:k], y[:k], smoothing=0)
        rows.append(
            {
                "record": f"{kind}, {shape}, seed {seed}",
                "held_out_percent": records.held_out_percent(fit.model, v, y),
                "smoothing": fit.history["smoothing"],
                "baseline_held_out_percent": records.held_out_percent(plain.model, v, y),
            }
        )
    worst = max(r["held_out_percent"] for r in rows)
    return {
        "case": "identify(preisach, levels=48) on decaying-amplitude records, held out with the state carried",
        "metric": "held_out_percent",
        "records": rows,
        "held_out_percent": worst,
        "target_percent": 1.5,
        "baseline": "plain: NNLS without the smoothness prior, memory 64 (the previous method)",
        "baseline_held_out_percent": max(r["baseline_held_out_percent"] for r in rows),
        "wall_s": time.perf_counter() - t0,
    }


def _test_module(name: str) -> Any:
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, HERE.parent / "tests" / "identify" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def bench_rdpi_fit() -> dict[str, Any]:
    records = _test_module("test_rdpi_conditioning")
    rows = []
    t0 = time.perf_counter()
    for kind, shape in (("rdpi", "chirp"), ("pi+resonance", "triangle"), ("boucwen+resonance", "multisine")):
        v, y = records.record(kind, shape, 0)
        families = {m: records.held_out(v, y, m).validation["rmse_percent"] for m in ("pi", "mpi", "preisach", "rdpi")}
        fit = records.held_out(v, y, "rdpi", structure="fit", rng=0)
        best = min(families, key=families.__getitem__)
        rows.append(
            {
                "record": f"{kind}, {shape}",
                "held_out_percent": fit.validation["rmse_percent"],
                "best_family": best,
                "best_family_held_out_percent": families[best],
                "ratio_to_best": fit.validation["rmse_percent"] / families[best],
                "condition": fit.history["condition"],
            }
        )
    return {
        "case": "identify(rdpi, structure='fit') on 5 kHz records, held out with the state carried",
        "metric": "ratio_to_best",
        "records": rows,
        "ratio_to_best": max(r["ratio_to_best"] for r in rows),
        "target_ratio": 1.5,
        "wall_s": time.perf_counter() - t0,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(HERE / "results" / "identify_speed.json"))
    ap.add_argument("--quick", action="store_true", help="skip the slow bvls-full baseline")
    args = ap.parse_args()
    result = {
        "benchmark": "identify_speed (issue 14 item 7)",
        "timestamp_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": machine_info(),
        "extension_sha256": extension_digest(),
        "cases": [bench_preisach(args.quick), bench_huber_fit(), bench_preisach_decaying(), bench_rdpi_fit()],
    }
    text = json.dumps(result, indent=2)
    Path(args.out).write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
