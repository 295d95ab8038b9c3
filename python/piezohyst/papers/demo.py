"""``piezohyst demo``: both papers end to end on the virtual stage.

1. excite the virtual stage and "measure" it (sensor noise and quantization included);
2. identify the CEMF stage model with CSS and a least-squares polish (PSO, MPSO and DE run alongside for the
   convergence figure) and the MPI model by least squares; validate the MPI model at
   2-100 Hz (seed 2, Table 2);
3. seed 1's case studies: each controller tuned for itself on the identified model (the same
   call, box, budget and seed), then open loop, SMC (Case 1), SMC + CEMF (Case 2) and a tuned
   PID with static feedforward beside the closed-loop noise floor (seed 1, Table 3, Figures 9-14);
4. seed 2's compensation: linearity without/with the inverse feedforward (Table 3), and none /
   feedforward / feedforward + ABSMC at 80 Hz (Table 4), beside a PID + static feedforward and the
   dynamic-inversion loop (:func:`piezohyst.papers.control_study.compensation_study`), each tuned
   for itself by the same call;
5. a report in ``out_dir``: ``index.html``, ``report.md``, PNG figures and ``results.json``.

Same ``seed`` → same numbers (whatever the thread count).
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ..errors import OutputExistsError, ParameterError
from ..models.model import HysteresisModel
from ..plant.stage import virtual_stage
from . import control_study
from . import experiments as ex

if TYPE_CHECKING:
    from ..identify.core import IdentificationResult
    from ..plant.stage import StageParameters

__all__ = ["REPORT_FILES", "run_demo"]

#: Files the report writes (figures are listed in results.json).
REPORT_FILES = ("index.html", "report.md", "results.json")


class _Steps:
    """One progress line per stage on stderr: ``[k/n] what ... done in s``."""

    def __init__(self, total: int, stream: IO[str] | None) -> None:
        self.total, self.k, self.stream, self.t0 = total, 0, stream, time.perf_counter()

    def start(self, what: str) -> None:
        self.k += 1
        self._t = time.perf_counter()
        if self.stream:
            print(f"[{self.k}/{self.total}] {what} ...", file=self.stream, flush=True)

    def done(self, detail: str = "") -> None:
        if self.stream:
            dt = time.perf_counter() - self._t
            print(f"      done in {dt:.1f} s{'  ' + detail if detail else ''}", file=self.stream, flush=True)


def run_demo(
    out_dir: str | Path = "piezohyst-report",
    *,
    force: bool = False,
    quick: bool = False,
    seed: int | np.integer[Any] = 0,
    progress: bool = True,
    print_fn: Callable[[str], object] = print,
) -> dict[str, Any]:
    """Run the demo and write the report; return every number (also in ``results.json``).

    Raises ``FileExistsError`` if ``out_dir`` already holds a report and ``force`` is false.
    """
    from .._io import write_atomic
    from .report import write_report

    out_dir = Path(out_dir)
    existing = [f for f in REPORT_FILES if (out_dir / f).exists()]
    if existing and not force:
        raise OutputExistsError(f"{out_dir / existing[0]} exists; pass --force to overwrite the report")
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ParameterError(f"seed = {seed!r} must be a non-negative int")
    stream = sys.stderr if progress else None
    steps = _Steps(5, stream)
    t_start = time.perf_counter()
    stage = virtual_stage()
    rng = np.random.default_rng(seed)
    iters = 25 if quick else 100

    steps.start("excite and measure the virtual stage")
    info = stage.info() if not quick else None
    steps.done("" if info is None else f"stroke {info.stroke * 1e6:.2f} um, hysteresis {info.hysteresis_percent:.1f} %")

    steps.start(
        "identify: CEMF stage model (CSS + least-squares polish; PSO, MPSO, DE for comparison) and MPI "
        "model (least squares)"
    )
    convergence: dict[str, dict[str, Any]] = {}
    cemf: tuple[StageParameters, IdentificationResult, float] | None = None
    for method in ("css", "pso", "mpso", "de"):
        sub = np.random.default_rng([int(seed), len(convergence)])
        # the model used is CSS's, polished by least squares; the others are the comparison
        (model, ident, f_res), dt = ex.timed(
            ex.identify_stage_cemf,
            stage,
            sub,
            optimizer=method,
            max_iterations=iters,
            progress=progress,
            polish=method == "css",
        )
        assert ident.history is not None  # a population optimizer's run
        convergence[method] = {
            "best_cost": [float(c) for c in ident.history["best_cost"]],
            "wall_s": dt,
            "rmse_percent": ident.train["rmse_percent"],
            "polished": method == "css",
        }
        if method == "css":
            cemf = (model, ident, f_res)
    assert cemf is not None  # CSS ran first
    model, ident, f_res = cemf
    mpi_fit, t_mpi = ex.timed(ex.identify_stage_mpi, stage, rng)
    mpi_model = mpi_fit.model
    assert isinstance(mpi_model, HysteresisModel)  # the MPI model
    table2 = ex.mpi_validation(stage, mpi_model, rng)
    mpi_vp: dict[str, Any] | None = None
    if not quick:
        # seed 2 identifies its MPI with MPSO: here MPSO over the structure (threshold spread,
        # envelopes, creep time constants) with the weights by least squares inside
        from ..identify.dispatch import identify

        fs = 1.0 / stage.sample_time
        u, y = ex.measure(stage, ex.excitation(fs), np.random.default_rng([int(seed), 99]))
        vp, t_vp = ex.timed(
            identify, u, y, "mpi", structure="fit", optimizer="mpso", rng=seed, creep=3, fs=fs, max_iterations=30
        )
        assert isinstance(vp.model, HysteresisModel)  # the MPI model
        mpi_vp = {
            "method": vp.method,
            "fit_rmse_percent": vp.train["rmse_percent"],
            "fit_max_error_percent": vp.train["max_error_percent"],
            "wall_s": t_vp,
            "table2_mpi_validation": ex.mpi_validation(stage, vp.model, np.random.default_rng([int(seed), 98])),
        }
    steps.done(f"CEMF fit {ident.train['rmse_percent']:.2f} % RMSE; MPI fit {mpi_fit.metrics['rmse_percent']:.2f} %")

    steps.start("seed 1: tune the SMC on the identified model; open loop, SMC, SMC + CEMF")
    s1, runs1 = ex.seed1_case_studies(stage, model, rng, tuning_iterations=10 if quick else 30, keep_runs=True)
    steps.done(
        " ".join(
            f"{k}: {v['SMC']:.4f} -> {v['SMC+CEMF']:.4f} um (PID+FF {v['PID+FF']:.4f})"
            for k, v in s1["rmse_um"]["each tuned for itself"].items()
        )
    )

    steps.start("seed 2: inverse-MPI feedforward and adaptive backstepping SMC")
    s2, runs2 = ex.seed2_compensation(stage, mpi_model, keep_runs=True)
    t4 = s2["table4_80hz"]["constant"]
    # each tuned for itself: a PID + static feedforward and the dynamic-inversion loop
    honest = control_study.compensation_study(
        stage,
        np.random.default_rng([int(seed), 19]),
        tuning_iterations=10 if quick else 30,
        mechanics=model,
        law=mpi_model,
    )
    h4 = honest["table4_80hz"]["constant"]
    steps.done(
        f"80 Hz normalized max error {t4['none']['normalized_max_error']:.4f} -> "
        f"{t4['feedforward+ABSMC']['normalized_max_error']:.4f} (ABSMC), "
        f"{h4['PID+FF']['normalized_max_error']:.4f} (PID+FF, tuned) -> "
        f"{h4['compensated']['normalized_max_error']:.4f} (dynamic inversion + FilteredPID, tuned)"
    )

    steps.start(f"write the report to {out_dir}")
    k = model.stiffness / model.tem
    results: dict[str, Any] = {
        "seed": seed,
        "quick": quick,
        "stage": None if info is None else info.to_dict(),
        "identification": {
            "cemf": {
                "optimizer": "css+least_squares",
                "iterations": iters,
                "fit_rmse_percent": ident.train["rmse_percent"],
                "M": model.mass / model.tem,
                "B": model.damping / model.tem,
                "K": k,
                "tem": model.tem,
                "alpha": model.hyst_alpha,
                "beta": model.hyst_beta,
                "gamma": model.hyst_gamma,
                "resonance_hz": f_res,
                "wall_s": convergence["css"]["wall_s"],
            },
            "convergence": convergence,
            "mpi": {
                "fit_rmse_percent": mpi_fit.metrics["rmse_percent"],
                "fit_max_error_percent": mpi_fit.metrics["max_error_percent"],
                "wall_s": t_mpi,
                "operators": 9,
                "creep_taus_s": [0.01, 0.1, 1.0],
            },
            "table2_mpi_validation": table2,
            "seed_table2": ex.SEED2_TABLE2,
            "mpi_mpso_structure": mpi_vp,
        },
        "seed1": s1,
        "seed2": s2,
        "compensation": honest,
    }
    figures = write_report(out_dir, results, runs1=runs1, runs2=runs2, mpi_fit=mpi_fit, stage=stage)
    results["figures"] = figures
    results["wall_s"] = time.perf_counter() - t_start
    write_atomic(out_dir / "results.json", json.dumps(results, indent=1, default=float))
    steps.done()
    print_fn(f"report: {out_dir / 'index.html'} (and report.md, results.json); {results['wall_s']:.0f} s in all")
    return results
