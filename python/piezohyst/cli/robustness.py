"""``piezohyst robustness``: Monte-Carlo closed-loop runs over part-to-part variation of a stage."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from .._io import write_atomic
from .common import _atomic_savefig, _Fail, _Parser
from .fleet import _cluster_options, _progress
from .track import _CONTROLLERS, _REFERENCES, _TRACK_MAX_SAMPLES, _build_controller

#: Most Monte-Carlo samples of one command (their factors and metrics are held in memory).
_MAX_SAMPLES = 10_000_000


def _robustness_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
    r = sub.add_parser(
        "robustness",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        help="Monte-Carlo closed-loop runs of a controller over part-to-part variation of the stage",
        description=(
            "Check a controller across part-to-part variation: the controller is designed for the nominal\n"
            "stage (--stage, default the virtual stage; as piezohyst track), and each of --samples parts is\n"
            "that stage with the --perturb parameters scaled by random factors, run in closed loop on the\n"
            "reference with its own sensor noise. The runs are batched in the Rust core, --chunk parts per\n"
            "Dask task. Prints the tracking-error percentiles (RMSE and max error of reference - true\n"
            "position after --skip), the nominal stage's figures, which parameter drives the error (Spearman\n"
            "rank correlation) and the worst parts with their parameters.\n\n"
            "Same --seed, same result, whatever --workers or --scheduler: part i draws its factors and noise\n"
            "seed from numpy.random.SeedSequence(seed, spawn_key=(i,)) only, and the chunks do not depend on\n"
            "the workers."
        ),
        epilog=(
            "examples:\n"
            "  piezohyst robustness --controller pid --samples 10000 --perturb mass=±10%,stiffness=±10%,tem=±5% \\\n"
            "      --seed 0\n"
            "  piezohyst robustness --stage stage.json --controller absmc --model mpi.json --samples 2000 \\\n"
            "      --perturb 'gamma=+-20%:normal,capacitance=+-10%' --out robust/ --workers 2\n\n"
            "perturbable parameters: mass, damping, stiffness, tem, capacitance, hyst_alpha (alpha), hyst_beta\n"
            "(beta), hyst_gamma (gamma), electrostriction, creep_weights (creep: every weight by one factor).\n"
            "NAME=±P% (or +-P%, or P%): a factor uniform in [1 - P/100, 1 + P/100]; NAME=±P%:normal: normal\n"
            "with standard deviation P/100, truncated at 3 standard deviations.\n\n"
            "exit status: 0 on success, 1 when some chunk failed (listed; its parts are left out), 2 on bad input."
        ),
    )
    r.add_argument("--stage", metavar="FILE", help="stage file (JSON; default: the built-in virtual stage)")
    r.add_argument("--controller", required=True, choices=_CONTROLLERS, help="controller kind (as piezohyst track)")
    r.add_argument("--model", metavar="MODEL.json", help="hysteresis model file for inverse / absmc")
    r.add_argument("--samples", metavar="N", type=int, default=1000, help="Monte-Carlo parts (default 1000)")
    r.add_argument(
        "--perturb",
        metavar="NAME=±P%,...",
        required=True,
        help="the parameters that vary from part to part and by how much, e.g. mass=±10%%,stiffness=±5%%",
    )
    r.add_argument("--seed", metavar="S", type=int, default=0, help="Monte-Carlo seed (default 0)")
    r.add_argument("--reference", default="sine", choices=_REFERENCES, help="reference kind (default sine)")
    r.add_argument("--freq", type=float, default=10.0, help="reference frequency, Hz (default 10)")
    r.add_argument("--amp", type=float, default=5.0, help="reference amplitude, um (default 5)")
    r.add_argument("--offset", type=float, default=8.0, help="reference centre, um (default 8)")
    r.add_argument("--duration", type=float, default=0.2, help="seconds per run (default 0.2)")
    r.add_argument("--skip", type=float, default=0.05, help="seconds left out of the metrics (default 0.05)")
    r.add_argument(
        "--chunk", metavar="N", type=int, default=500, help="parts per task, batched in one Rust call (default 500)"
    )
    _cluster_options(r)
    r.add_argument(
        "--out",
        metavar="DIR",
        help="also write DIR/robustness.json (the summary), DIR/samples.csv and DIR/samples.parquet (every "
        "part's factors, noise seed and metrics) and DIR/robustness.png",
    )
    r.add_argument("--plot", metavar="FILE.png", help="write the figure (distribution, sensitivity, worst part)")
    r.add_argument("--force", action="store_true", help="overwrite --plot and the files of --out")
    r.add_argument("--json", action="store_true", help="print the summary as JSON")
    r.add_argument("--debug", dest="sub_debug", action="store_true", help="show a traceback on errors")


def _robustness(args: argparse.Namespace) -> int:
    from ..fleet import RobustnessProblem, parse_perturbations, plan, robustness, runner
    from ..plant.stage import Stage, virtual_stage
    from ..signals import references as refs

    for name in ("freq", "amp", "duration"):
        if not getattr(args, name) > 0:
            raise _Fail(f"--{name} = {getattr(args, name)} must be > 0")
    if not 1 <= args.samples <= _MAX_SAMPLES:
        raise _Fail(f"--samples = {args.samples} must be between 1 and {_MAX_SAMPLES}")
    if args.chunk < 1:
        raise _Fail(f"--chunk = {args.chunk} must be >= 1")
    if args.seed < 0:
        raise _Fail(f"--seed = {args.seed} must be >= 0")
    perturbations = tuple(parse_perturbations(args.perturb))
    cluster = plan(args.scheduler, args.workers)
    stage = Stage.from_file(args.stage) if args.stage else virtual_stage()
    fs = 1.0 / stage.sample_time
    n = round(args.duration * fs)
    if n > _TRACK_MAX_SAMPLES:
        raise _Fail(f"--duration = {args.duration:g} s is {n} samples at {fs:g} Hz; at most {_TRACK_MAX_SAMPLES:.0e}")
    skip = round(args.skip * fs)
    if not 0 <= skip < n:
        raise _Fail(f"--skip = {args.skip:g} s must be >= 0 and shorter than --duration = {args.duration:g} s")
    amp, off = args.amp * 1e-6, args.offset * 1e-6
    if args.reference == "sine":
        _, ref = refs.sine(args.freq, amp, args.duration, fs, offset=off)
    elif args.reference == "triangle":
        _, ref = refs.triangle(args.freq, amp, args.duration, fs, offset=off)
    else:
        _, ref = refs.variable_amplitude_sine(args.freq, amp, args.duration, fs, offset=off)
    out = None if args.out is None else Path(args.out)
    targets = [] if out is None else [out / "robustness.json", out / "samples.csv", out / "samples.parquet"]
    targets += [] if out is None else [out / "robustness.png"]
    targets += [] if args.plot is None else [Path(args.plot)]
    if out is not None and out.exists() and not out.is_dir():
        raise _Fail(f"--out = '{args.out}' is a file; give a directory")
    for t in targets:
        if t.exists() and not args.force:
            raise _Fail(f"'{t}' exists; pass --force to overwrite it")
    prog = "piezohyst robustness"
    progress = _progress(args, prog, 1, "chunks")  # the runner sets the count of chunks
    with runner(cluster) as run:  # a local cluster starts in the background meanwhile
        controller = _build_controller(args.controller, stage, args.model)
        problem = RobustnessProblem(stage, controller, ref, skip, perturbations, args.seed)
        import scipy.stats  # noqa: F401 - the summary's rank correlation, loaded while the cluster starts

        res = robustness(problem, args.samples, run, chunk=args.chunk, progress=progress)
    doc: dict[str, Any] = {
        "controller": args.controller,
        "stage": args.stage or "virtual stage",
        "reference": {"kind": args.reference, "freq_hz": args.freq, "amp_um": args.amp, "offset_um": args.offset},
        "duration_s": args.duration,
        "sample_rate_hz": fs,
        "chunk": args.chunk,
        "cluster": cluster.describe(),
        **res.to_dict(),
    }
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        _write_samples(res, out)
        write_atomic(out / "robustness.json", json.dumps(doc, indent=2, allow_nan=False) + "\n", name="--out")
    figures = ([] if out is None else [out / "robustness.png"]) + ([] if args.plot is None else [Path(args.plot)])
    if figures:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig = res.plot()
        try:
            for f in figures:
                _atomic_savefig(fig, f)
        finally:
            plt.close(fig)
    if args.json:
        print(json.dumps(doc, indent=2, allow_nan=False))
    else:
        _print(doc, res.samples)
    for e in res.errors:
        print(f"{prog}: chunk failed: {e}", file=sys.stderr)
    return 1 if res.errors else 0


def _write_samples(res: Any, out: Path) -> None:
    from ..fleet.summary import write_table

    rows = []
    for i in range(res.samples):
        row: dict[str, Any] = {"sample": i, "noise_seed": str(int(res.seeds[i]))}
        for c, name in enumerate(res.names):
            row[f"factor.{name}"] = float(res.factors[i, c])
        row["rmse"], row["max_error"], row["saturated_fraction"] = (float(x) for x in res.metrics[i])
        rows.append(row)
    cols = ["sample", "noise_seed", *[f"factor.{n}" for n in res.names], "rmse", "max_error", "saturated_fraction"]
    write_table(rows, cols, out / "samples.csv", out / "samples.parquet")


def _print(doc: dict[str, Any], samples: int) -> None:
    um = 1e6
    print(
        f"{doc['controller']} on {doc['stage']}: {samples} parts ({', '.join(doc['perturbations'])}), seed "
        f"{doc['seed']}, {doc['duration_s']:g} s at {doc['sample_rate_hz']:g} Hz each, in "
        f"{doc['wall_time_s']:.3g} s on {doc['cluster']}"
    )
    print(f"  {'(um)':<11}{'nominal':>9}{'p50':>9}{'p90':>9}{'p95':>9}{'p99':>9}{'p99.9':>9}{'max':>9}")
    for key, label in (("rmse", "RMSE"), ("max_error", "max error")):
        p = doc["percentiles"][key]
        cells = "".join(f"{p[q] * um:>9.4g}" for q in ("p50", "p90", "p95", "p99", "p99.9", "max"))
        print(f"  {label:<11}{doc['nominal'][key] * um:>9.4g}{cells}")
    print(f"  diverged: {doc['diverged']}, runs that saturated the amplifier: {doc['saturated_runs']}")
    sens = ", ".join(f"{k} {v:+.2f}" for k, v in doc["sensitivity_spearman"].items())
    dev = ", ".join(f"{k} {v:+.2f}" for k, v in doc["sensitivity_spearman_deviation"].items())
    print(f"  RMSE's rank correlation with each factor: {sens}")
    print(f"  ... with each factor's distance from nominal: {dev}")
    print("  worst parts:")
    for w in doc["worst"]:
        parts = ", ".join(f"{k} x{v['factor']:.4f}" for k, v in w["parameters"].items())
        print(f"    #{w['sample']:<7} RMSE {w['rmse'] * um:.4g} um, max {w['max_error'] * um:.4g} um: {parts}")
