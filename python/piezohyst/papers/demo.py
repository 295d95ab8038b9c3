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
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ..errors import ParameterError
from ..models.model import HysteresisModel
from ..outputs import check_output_dir, output_set
from ..plant.stage import virtual_stage
from ..progress import is_silenced
from . import control_study
from . import experiments as ex
from .report import EQUAL_TUNING, write_report

if TYPE_CHECKING:
    from ..control.simulation import ClosedLoopResult
    from ..identify.core import FitResult, IdentificationResult
    from ..plant.stage import Stage, StageParameters

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
    name: str = "out_dir",
) -> dict[str, Any]:
    """Run the demo and write the report; return every number (also in ``results.json``).

    Raises ``FileExistsError`` if ``out_dir`` already holds a report and ``force`` is false.
    The folder is checked before the run starts and the report is put in place as a set
    (:func:`piezohyst.outputs.output_set`): a run stopped by Ctrl-C or a signal, or one that
    fails, leaves ``out_dir`` as it was; with ``force`` the new report replaces the old one
    whole (no figure of the old run is left beside the new). ``name`` is the argument the
    messages name.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        The report's folder (created; its parents too).
    force : bool
        Replace a report already in ``out_dir``.
    quick : bool
        The quick demo (smaller tuning budgets; ``piezohyst demo --quick``).
    seed : int
        The seed of every random draw (non-negative): the same seed, the same numbers.
    progress : bool
        Print the steps on stderr.
    print_fn : callable
        Takes the closing summary lines (``print`` by default).
    name : str
        The argument's name in the messages (``"--out"`` from the CLI).

    Returns
    -------
    dict
        Every number of the report (also written to ``results.json``).

    Raises
    ------
    FileExistsError
        ``out_dir`` already holds a report and ``force`` is false.
    ParameterError
        ``seed`` is not a non-negative int.

    Examples
    --------
    >>> import tempfile
    >>> from piezohyst.papers.demo import REPORT_FILES, run_demo
    >>> results = run_demo(tempfile.mkdtemp(), quick=True, progress=False)  # doctest: +SKIP
    >>> REPORT_FILES                                  # what the folder holds afterwards
    ('index.html', 'report.md', 'results.json')
    >>> run_demo(tempfile.mkdtemp(), seed=-1)        # checked before anything runs
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: seed = -1 must be a non-negative int
    """
    out_dir = Path(out_dir)
    hint = "--force" if name.startswith("--") else "--force (force=True)"
    check_output_dir(out_dir, name=name, overwrite=force, names=REPORT_FILES, parents=True, force_hint=hint)
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ParameterError(f"seed = {seed!r} must be a non-negative int")
    stream = sys.stderr if progress and not is_silenced() else None
    steps = _Steps(5, stream)
    t_start = time.perf_counter()
    try:
        results, runs1, runs2, mpi_fit, stage = _experiments(steps, quick=quick, seed=seed, progress=progress)
    except KeyboardInterrupt:
        raise KeyboardInterrupt(f"the report was not written; '{out_dir}' is as it was") from None

    steps.start(f"write the report to {out_dir}")
    with output_set(
        out_dir,
        name=name,
        overwrite=force,
        names=REPORT_FILES,
        previous=_previous_report(out_dir),
        parents=True,
        force_hint=hint,
    ) as tmp:
        figures = write_report(tmp, results, runs1=runs1, runs2=runs2, mpi_fit=mpi_fit, stage=stage)
        results["figures"] = figures
        results["wall_s"] = time.perf_counter() - t_start
        (tmp / "results.json").write_text(json.dumps(results, indent=1, default=float), encoding="utf-8")
    steps.done()
    label = " [QUICK run: smaller optimizer and tuning budgets, equal for every controller]" if quick else ""
    print_fn(f"report: {out_dir / 'index.html'} (and report.md, results.json); {results['wall_s']:.0f} s in all{label}")
    return results


def _previous_report(out_dir: Path) -> list[str]:
    """The files of the report already in ``out_dir`` (its fixed files and the figures its
    ``results.json`` lists): what a new report replaces."""
    names = list(REPORT_FILES)
    try:
        old = json.loads((out_dir / "results.json").read_text(encoding="utf-8"))
        figures = old.get("figures", {}) if isinstance(old, dict) else {}
        names += [f for f in figures.values() if isinstance(f, str) and re.fullmatch(r"[\w.-]+\.png", f)]
    except (OSError, ValueError, AttributeError):
        pass
    return names


def _stop_if_partial(*partial: bool) -> None:
    """An optimizer or a tuning stopped early by Ctrl-C or a signal (it keeps its best so far):
    the demo stops too, rather than report numbers from a cut run."""
    if any(partial):
        raise KeyboardInterrupt


def _experiments(
    steps: _Steps, *, quick: bool, seed: int | np.integer[Any], progress: bool
) -> tuple[
    dict[str, Any],
    dict[tuple[str, str], ClosedLoopResult],
    dict[tuple[str, str, str], ClosedLoopResult],
    FitResult,
    Stage,
]:
    """Steps 1-4 of the demo: every number of the report and the runs its figures show."""
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
        _stop_if_partial(ident.partial)
        assert ident.history is not None  # a population optimizer's run
        convergence[method] = {
            "best_cost": [float(c) for c in ident.history["best_cost"]],
            "wall_s": dt,
            "rmse_percent": ident.train["rmse_percent"],
            "rmse": ident.train["rmse"],  # m; after the polish for CSS (the model used)
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
        _stop_if_partial(vp.partial)
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
    _stop_if_partial(*s1["tuning_partial"].values())
    steps.done(
        " ".join(
            f"{k}: {v['SMC']:.4f} -> {v['SMC+CEMF']:.4f} um (PID+FF {v['PID+FF']:.4f})"
            for k, v in s1["rmse_um"][EQUAL_TUNING].items()
        )
    )

    steps.start("seed 2: inverse-MPI feedforward and adaptive backstepping SMC")
    s2, runs2 = ex.seed2_compensation(stage, mpi_model, keep_runs=True)
    t4 = s2["table4_80hz"]["constant"]
    # each tuned for itself: a PID + static feedforward and the dynamic-inversion loop, whose MPI
    # the study identifies over the 80 Hz task's range (control_study.identify_operating_mpi)
    honest = control_study.compensation_study(
        stage,
        np.random.default_rng([int(seed), 19]),
        tuning_iterations=10 if quick else 30,
        mechanics=model,
    )
    h4 = honest["table4_80hz"]["constant"]
    steps.done(
        f"80 Hz normalized max error {t4['none']['normalized_max_error']:.4f} -> "
        f"{t4['feedforward+ABSMC']['normalized_max_error']:.4f} (ABSMC), "
        f"{h4['PID+FF']['normalized_max_error']:.4f} (PID+FF, tuned) -> "
        f"{h4['compensated']['normalized_max_error']:.4f} (dynamic inversion + FilteredPID, tuned)"
    )

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
    return results, runs1, runs2, mpi_fit, stage
