"""Issue 19's acceptance on the virtual stage (piezohyst.papers.control_study): robustness of
SMC, SMC + CEMF and PID + feedforward, each tuned for itself, on ±20 % perturbations of every
stage parameter and on structurally different stages; the dynamic-inversion feedforward at
10/50/100 Hz; compensated tracking at 80 Hz against a PID + static feedforward tuned the same way.

Run: ``.venv/bin/python bench/control_acceptance.py [--quick] [--seed N] [--seeds N ...]``; JSON in
``bench/results/control_acceptance.json`` (the first seed's full result at the top, every seed's
acceptance figures under ``"seeds"``).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import sys
import time
from pathlib import Path

import numpy as np

import piezohyst as ph
from piezohyst.papers.control_study import ROBUSTNESS_LIMIT, compensation_study, robustness_study

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine_info, write_json_atomic

OUT = Path(__file__).with_name("results") / "control_acceptance.json"
#: Noise realizations each 80 Hz tuning candidate runs with (both loops alike): a maximum error
#: is one sample's, and with one realization the search chases its noise (seed 1, max_error:
#: ratio 5.1 / 4.7 with one, 6.3 / 6.0 with five).
TUNING_NOISE_SEEDS = 5


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smaller tuning budgets")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--seeds", type=int, nargs="+", help="several seeds (the first one's full result on top)")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    seeds = args.seeds or [args.seed]
    results = [run_seed(s, args.quick) for s in seeds]
    result = dict(results[0])
    result["seeds"] = {str(s): _summary(r) for s, r in zip(seeds, results, strict=True)}
    result.update(timestamp_utc=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"), machine=machine_info())
    write_json_atomic(args.out, result)
    print(json.dumps(result["seeds"], indent=1, default=float))


def _summary(r):
    """The acceptance figures of one seed."""
    comp = r["compensation"]
    return {
        "worst_ratio": r["robustness"]["worst_ratio"],
        "worst_ratio_nominal_tuning": r["robustness_nominal_tuning"]["worst_ratio"],
        "nominal_rmse_um": r["robustness"]["nominal_rmse_um"],
        "feedforward_max_error_percent": comp["rmse"]["feedforward_max_error_percent"],
        # the compensated loop's MPI, identified over the 80 Hz task's range, against the
        # full-range model on a held-out record of that range
        "mpi_heldout": comp["rmse"]["settings"]["mpi_operating"]["heldout"],
        "table4_80hz": {
            obj: {
                amp: {
                    "compensated": row["compensated"]["normalized_max_error"],
                    "PID+FF": row["PID+FF"]["normalized_max_error"],
                    "ratio": row["ratio"],
                }
                for amp, row in c["table4_80hz"].items()
            }
            for obj, c in comp.items()
        },
    }


def run_seed(seed, quick):
    """Both studies at one seed."""
    budget = {"tuning_iterations": 12 if quick else 30, "population_size": 12 if quick else 16}
    stage = ph.virtual_stage()
    t0 = time.perf_counter()
    robust = robustness_study(stage, np.random.default_rng(seed), **budget)
    t1 = time.perf_counter()
    nominal_tuned = robustness_study(stage, np.random.default_rng(seed), robust=False, **budget)
    t2 = time.perf_counter()
    comp = {
        obj: compensation_study(
            stage, np.random.default_rng(seed), objective=obj, tuning_noise_seeds=TUNING_NOISE_SEEDS, **budget
        )
        for obj in ("rmse", "max_error")
    }
    t3 = time.perf_counter()
    result = {
        "robustness": robust,
        "robustness_nominal_tuning": nominal_tuned,
        "compensation": comp,
        "acceptance": {
            "robustness_within_3x": robust["holds"],
            "worst_ratio": robust["worst_ratio"],
            "dynamic_inversion_max_error_percent_le_1": {
                k: v <= 1.0 for k, v in comp["rmse"]["feedforward_max_error_percent"].items()
            },
            "80hz_normalized_max_error_le_0.0054": {
                obj: {a: r["compensated"]["normalized_max_error"] <= 0.0054 for a, r in c["table4_80hz"].items()}
                for obj, c in comp.items()
            },
            "80hz_ratio_ge_6": {
                obj: {a: r["ratio"] >= 6 for a, r in c["table4_80hz"].items()} for obj, c in comp.items()
            },
            "limit": ROBUSTNESS_LIMIT,
        },
        "wall_s": {"robustness": t1 - t0, "robustness_nominal_tuning": t2 - t1, "compensation": t3 - t2},
        "quick": quick,
        "seed": seed,
    }
    print(f"seed {seed}:", json.dumps(result["acceptance"], default=float), flush=True)
    return result


if __name__ == "__main__":
    main()
