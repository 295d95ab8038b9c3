"""Issue 19's acceptance on the virtual stage (piezohyst.papers.control_study): robustness of
SMC, SMC + CEMF and PID + feedforward, each tuned for itself, on ±20 % perturbations of every
stage parameter and on structurally different stages; the dynamic-inversion feedforward at
10/50/100 Hz; compensated tracking at 80 Hz against a PID + static feedforward tuned the same way.

Run: ``.venv/bin/python bench/control_acceptance.py [--quick] [--seed N]``; JSON in
``bench/results/control_acceptance.json``.
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smaller tuning budgets")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    budget = {"tuning_iterations": 12 if args.quick else 30, "population_size": 12 if args.quick else 16}
    stage = ph.virtual_stage()
    t0 = time.perf_counter()
    robust = robustness_study(stage, np.random.default_rng(args.seed), **budget)
    t1 = time.perf_counter()
    nominal_tuned = robustness_study(stage, np.random.default_rng(args.seed), robust=False, **budget)
    t2 = time.perf_counter()
    comp = {
        obj: compensation_study(stage, np.random.default_rng(args.seed), objective=obj, **budget)
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
        "quick": args.quick,
        "seed": args.seed,
    }
    result.update(timestamp_utc=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"), machine=machine_info())
    write_json_atomic(args.out, result)
    print(json.dumps(result["acceptance"], indent=1, default=float))
    print(json.dumps({"worst_ratio": robust["worst_ratio"], "nominal_rmse_um": robust["nominal_rmse_um"]}, indent=1))
    for obj, c in comp.items():
        print(obj, json.dumps(c["table4_80hz"], indent=1, default=float))
        print(json.dumps(c["feedforward_max_error_percent"], indent=1, default=float))


if __name__ == "__main__":
    main()
