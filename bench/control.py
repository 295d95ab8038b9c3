"""Control acceptance on the virtual stage (issue 5): seed 1 Table 3 and seed 2 Tables 3-4
patterns, with every model identified from simulated measurements (commanded voltage and
the quantized, noisy sensor reading), plus gain-tuning wall time. The experiments live in
``piezohyst.experiments`` (the demo runs the same code). One controller step in ns:
``cargo run --release -p piezohyst-core --example controller_step``.

Run: ``.venv/bin/python bench/control.py [--quick]``; JSON in ``bench/results/control.json``.
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
from piezohyst import experiments as ex

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import machine_info, write_json_atomic

OUT = Path(__file__).with_name("results") / "control.json"


def seed1(stage, rng, quick):
    (model, ident, f_res), t_ident = ex.timed(
        ex.identify_stage_cemf, stage, rng, optimizer="de", max_iterations=60 if quick else 100
    )
    out = ex.seed1_case_studies(stage, model, rng, tuning_iterations=10 if quick else 30)
    k = model.stiffness / model.tem
    out.pop("tuning_history")
    out.update(
        {
            "identification_s": t_ident,
            "identified": {
                "M": model.mass / model.tem,
                "B": model.damping / model.tem,
                "K": k,
                "tem": model.tem,
                "alpha": model.hyst_alpha,
                "beta": model.hyst_beta,
                "gamma": model.hyst_gamma,
                "fit_rmse_percent": ident.train["rmse_percent"],
                "resonance_hz": f_res,
            },
        }
    )
    return out


def seed2(stage, rng, quick):
    fit, t_ident = ex.timed(ex.identify_stage_mpi, stage, rng)
    out = ex.seed2_compensation(stage, fit.model)
    out.update({"identification_s": t_ident, "mpi_fit": repr(fit)})
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smaller optimizer budgets")
    ap.add_argument("--out", type=Path, default=OUT, help=f"JSON output (default {OUT})")
    args = ap.parse_args(argv)
    quick = args.quick
    stage = ph.virtual_stage()
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    result = {
        "seed1_table3": seed1(stage, rng, quick),
        "seed2": seed2(stage, rng, quick),
        "wall_s": time.perf_counter() - t0,
        "quick": quick,
    }
    result.update(timestamp_utc=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"), machine=machine_info())
    write_json_atomic(args.out, result)
    print(json.dumps(result, indent=1, default=float))


if __name__ == "__main__":
    main()
