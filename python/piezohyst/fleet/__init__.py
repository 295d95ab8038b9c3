"""Scale-out on Dask: many identifications (a fleet of records) and Monte-Carlo closed-loop
robustness, on an embedded ``LocalCluster`` (the default), an existing cluster
(``tcp://HOST:PORT``) or in this process (``serial``).

- :mod:`~piezohyst.fleet.cluster`: the thread plan (workers × Rust threads = the cores) and the
  :class:`Runner` that yields each task's :class:`Outcome` as it completes (a failing task is its
  outcome, not the run's end; a task on a worker that dies is run again by Dask);
- :mod:`~piezohyst.fleet.summary`: robust z-scores and outlier flags, the summary table (CSV and
  Parquet), the parameter-distribution figure;
- :mod:`~piezohyst.fleet.robustness`: perturbations of the stage, per-sample seeds, chunks batched
  in the Rust core, percentiles, worst cases and figures.

Progress of a run is :class:`piezohyst.progress.Progress` (Dask's bar on a terminal, plain lines
elsewhere, silent with ``--quiet``), the package's one home for progress.

The command line's ``piezohyst fleet identify`` and ``piezohyst robustness`` drive them
(``docs/scale_out.md`` gives the scaling model and measured numbers).
"""

from .cluster import ClusterPlan, Outcome, Runner, plan, runner, usable_cores
from .robustness import (
    PARAMETERS,
    Perturbation,
    RobustnessProblem,
    RobustnessResult,
    draw,
    parse_perturbations,
    robustness,
    run_chunk,
)
from .summary import OUTLIER_Z, flatten_parameters, outliers, robust_z, write_table

__all__ = [
    "OUTLIER_Z",
    "PARAMETERS",
    "ClusterPlan",
    "Outcome",
    "Perturbation",
    "RobustnessProblem",
    "RobustnessResult",
    "Runner",
    "draw",
    "flatten_parameters",
    "outliers",
    "parse_perturbations",
    "plan",
    "robust_z",
    "robustness",
    "run_chunk",
    "runner",
    "usable_cores",
    "write_table",
]
