"""``piezohyst identify``: fit a model to a record and save it."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

from .._io import write_atomic
from ..identify.dispatch import KINDS
from .common import (
    _FORMATS,
    _check_count,
    _check_fs,
    _column,
    _column_help,
    _existing_file,
    _Fail,
    _load,
    _parse_range,
    _parse_validate,
    _Parser,
    _pct,
    _resolve_range,
    _writable,
)

if TYPE_CHECKING:
    from ..identify.core import IdentificationResult
    from ..signals.data import Record
    from .common import FloatArray, _Columns

#: Model kinds of ``piezohyst identify``: those of :func:`piezohyst.identify`, from its registry
#: (:data:`piezohyst.identify.KINDS`), in its order.
_KINDS = KINDS


class _Where(TypedDict):
    """Where the validation data come from: a file and a sample range of it."""

    source: str
    range: list[int]


_OPTIMIZERS = ("css", "pso", "mpso", "de", "ls")


def _identify_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
    fmt = argparse.RawDescriptionHelpFormatter
    i = sub.add_parser(
        "identify",
        formatter_class=fmt,
        help="identify a hysteresis model from a measured input/output record; writes a model file",
        description=(
            "Identify a hysteresis model from a measured record (free-run simulation error) and write it as a\n"
            'model file (JSON) that includes the fit report under "fit". Prints RMSE and max error in % of\n'
            "the output range, on the training range and on the validation data when given.\n\n" + _FORMATS
        ),
        epilog=(
            "examples:\n"
            "  piezohyst identify run.csv --model mpi --input voltage --output x --time t \\\n"
            "      --train :6000 --validate 6000: --out mpi.json\n"
            "  piezohyst identify yan9a_model_1hz.dat --model preisach --levels 10 --input 0 --output 4 \\\n"
            "      --fs 200 --train 3152:4152 --json\n"
            "  piezohyst identify bw.csv --model boucwen --optimizer de --seed 1 --iterations 80 \\\n"
            "      --validate bw_check.csv --out bw.json --plot bw.png\n"
            "  piezohyst identify stage_run.csv --model cemf --input volts --output x --fs 10000 --seed 0 \\\n"
            "      --optimizer de --iterations 30 --out stage.json\n"
            "  piezohyst identify train_multisine.csv --model boucwen-benchmark --input u --output y --fs 750 \\\n"
            "      --train 8192:24576 --validate 32768: --seed 0 --out bw_benchmark.json\n\n"
            'cemf writes a stage file (kind "stage": the identified mechanics, Tem and CEMF constants with\n'
            "an ideal -20..150 V amplifier at the record's sample time), which 'piezohyst stage info --stage'\n"
            "and 'piezohyst track --stage' read; boucwen-benchmark writes its eight parameters (kind\n"
            '"boucwen-benchmark", with fs and the upsampling factor); it is simulated over DATA from the\n'
            "record's start (at rest, as the benchmark's generator), and --train / --validate ranges of DATA\n"
            "select the samples scored. 'piezohyst simulate' runs both (the stage open loop, the oscillator at\n"
            "its fs); load_model reads the boucwen-benchmark file, Stage.from_file the stage file.\n\n"
            "exit status: 0 on success, 2 on bad input (one line on stderr naming the argument)."
        ),
    )
    i.add_argument("data", metavar="DATA", help="the record file (see the formats above)")
    i.add_argument(
        "--model",
        metavar="KIND",
        required=True,
        choices=_KINDS,
        help=f"model to identify: {', '.join(_KINDS)} (required). pi/gpi/mpi/rdpi/preisach: least "
        "squares over the linear parameters with a default structure; boucwen: population "
        "optimizer over all parameters; cemf: seed 1's grey-box stage model (input = voltage "
        "across the stack in V, output = displacement), population optimizer (default css) then "
        "a least-squares polish; boucwen-benchmark: the Noel-Schoukens oscillator (input = force "
        "in N, output = displacement in m; --fs 750 for the benchmark's data), population "
        "optimizer (default de) then least squares",
    )
    i.add_argument(
        "--input",
        metavar="COL",
        help=_column_help("input", "default: the column named 'input', else the first of exactly two"),
    )
    i.add_argument(
        "--output",
        metavar="COL",
        help=_column_help("output (measured)", "default: the column named 'output', else the second of exactly two"),
    )
    g = i.add_mutually_exclusive_group()
    g.add_argument("--fs", metavar="HZ", type=float, help="sample rate in Hz (> 0); this or --time is required")
    g.add_argument(
        "--time", metavar="COL", help="time column in seconds (strictly increasing and uniform; gives the sample rate)"
    )
    i.add_argument(
        "--dataset",
        metavar="NAME",
        help="NPZ/MAT/HDF5: a 2-D matrix (rows = samples) whose columns integer COLs address",
    )
    i.add_argument(
        "--train",
        metavar="A:B",
        help="training samples A (inclusive) to B (exclusive), 0-based; either side may be omitted "
        "(default: the whole record, or, with --validate A:B and no --train, the samples before "
        "the validation range - after it when it starts at 0)",
    )
    i.add_argument(
        "--validate",
        metavar="A:B|FILE",
        help="held-out validation data, reported, not fitted: a sample range of DATA (must not overlap "
        "--train) or a second file read with the same column options",
    )
    i.add_argument(
        "--optimizer",
        choices=_OPTIMIZERS,
        default="ls",
        metavar="NAME",
        help="css, pso, mpso, de or ls (default: ls). Used for the parameters that are not linear "
        "(boucwen, cemf, boucwen-benchmark: all of them; 'ls' there means each kind's default: "
        "de, css for cemf); the linear families are solved exactly by least squares",
    )
    i.add_argument(
        "--seed",
        metavar="N",
        type=int,
        help="random seed of the optimizer (same seed, same result; default: fresh randomness)",
    )
    i.add_argument(
        "--operators",
        metavar="N",
        type=int,
        default=9,
        help="pi/gpi/mpi/rdpi: number of play operators, thresholds spread over half the input range (default: 9)",
    )
    i.add_argument(
        "--levels",
        metavar="N",
        type=int,
        default=12,
        help="preisach: grid levels over the input range, N(N+1)/2 cells (default: 12)",
    )
    i.add_argument(
        "--structure",
        choices=("fixed", "fit"),
        default="fixed",
        help="pi/gpi/mpi/rdpi: 'fixed' (default) solves the weights for the default structure; "
        "'fit' also identifies the structure (threshold spread, envelopes, rate terms, creep "
        "time constants) by variable projection: --optimizer over them, least squares inside",
    )
    i.add_argument("--creep", metavar="M", type=int, default=0, help="pi/gpi/mpi/rdpi: add M creep lags (default 0)")
    i.add_argument(
        "--iterations",
        metavar="N",
        type=int,
        help="optimizer iterations (populations evaluated) (default: 200 for boucwen, 150 for cemf, "
        "30 for boucwen-benchmark)",
    )
    i.add_argument(
        "--population",
        metavar="N",
        type=int,
        help="optimizer population size (default: max(20, 5 x number of parameters))",
    )
    i.add_argument(
        "--capacitance",
        metavar="F",
        type=float,
        help="cemf: the stack's capacitance in farads, taken as known (default: 1.8e-6, seed 1's 1800 nF)",
    )
    i.add_argument(
        "--out",
        metavar="FILE",
        default="model.json",
        help='model file to write (JSON, with the fit report under "fit") (default: model.json)',
    )
    i.add_argument("--plot", metavar="PNG", help="also write a figure: loop, fit and residual on the training data")
    i.add_argument("--force", action="store_true", help="overwrite existing --out / --plot files")
    i.add_argument("--json", action="store_true", help="print the metrics and the output path as JSON")
    i.add_argument(
        "--progress",
        action="store_true",
        help="show the optimizer's progress bar on stderr (default: only when stderr is a terminal)",
    )
    i.add_argument("--debug", dest="sub_debug", action="store_true", help="show a traceback on errors")


def _identify(args: argparse.Namespace) -> int:
    from ..identify.dispatch import identify

    _check_count(args.operators, "--operators")
    _check_count(args.levels, "--levels")
    _check_count(args.iterations, "--iterations")
    _check_count(args.population, "--population", minimum=2)
    if args.seed is not None and args.seed < 0:
        raise _Fail(f"--seed = {args.seed} must be >= 0")
    extra: dict[str, Any] = {}
    if args.capacitance is not None:
        if args.model != "cemf":
            raise _Fail(f"--capacitance applies to --model cemf, not to --model {args.model}")
        if not math.isfinite(args.capacitance) or args.capacitance <= 0:
            raise _Fail(f"--capacitance = {args.capacitance:g} must be a finite capacitance > 0 F")
        extra["capacitance"] = args.capacitance
    if args.model == "cemf":
        extra["polish"] = True
    fs = _check_fs(args.fs)
    data = _existing_file(args.data, "DATA")
    train_spec = None if args.train is None else _parse_range(args.train, "--train")
    val_spec, val_file = _parse_validate(args.validate)
    out = _writable(args.out, "--out", args.force)
    plot = None if args.plot is None else _writable(args.plot, "--plot", args.force)
    if plot is not None and plot.resolve() == out.resolve():
        raise _Fail(f"--plot = '{args.plot}' is the same file as --out")

    columns: _Columns = dict(
        input=_column(args.input), output=_column(args.output), time=_column(args.time), fs=fs, dataset=args.dataset
    )
    if fs is None and args.time is None:
        raise _Fail("the sample rate is unknown: give --fs HZ or --time COL")
    rec = _load(data, **columns)
    n = rec.n
    val: Record | None = None
    val_where: _Where
    if val_spec is not None:
        c, d = _resolve_range(val_spec, n, "--validate", args.validate)
        if train_spec is None:
            a, b = (0, c) if c >= 2 else (d, n)
            if b - a < 2:
                raise _Fail(
                    f"--validate = '{args.validate}' leaves no training range in DATA ({n} samples); give --train A:B"
                )
        else:
            a, b = _resolve_range(train_spec, n, "--train", args.train)
        if a < d and c < b:
            raise _Fail(
                f"--train = {a}:{b} and --validate = {c}:{d} overlap (samples {max(a, c)} to "
                f"{min(b, d) - 1}); validation data must be held out"
            )
        val, val_where = rec.trim(c, d), {"source": str(data), "range": [c, d]}
    else:
        a, b = (0, n) if train_spec is None else _resolve_range(train_spec, n, "--train", args.train)
        if val_file is not None:
            val = _load(val_file, **columns)
            if abs(val.fs - rec.fs) > 1e-6 * rec.fs:
                raise _Fail(
                    f"--validate = '{val_file}' is sampled at {val.fs:.9g} Hz, DATA at {rec.fs:.9g} Hz; "
                    f"the records must share the sample rate"
                )
            val_where = {"source": str(val_file), "range": [0, val.n]}
    train = rec.trim(a, b) if (a, b) != (0, n) else rec
    fit_input, fit_output = train.input, train.output
    validate: tuple[FloatArray, FloatArray] | tuple[FloatArray, FloatArray, tuple[int, int]] | None
    validate = None if val is None else (val.input, val.output)
    if args.model == "boucwen-benchmark":
        # the oscillator has a long memory: simulate DATA from its start (from rest, as the
        # benchmark's generator) and score the ranges, rather than restart at rest inside them
        fit_input, fit_output = rec.input, rec.output
        extra["fit_range"] = (a, b)
        if val_spec is not None:
            validate = (rec.input, rec.output, (c, d))

    if (args.structure == "fit" or args.creep) and args.model not in ("pi", "gpi", "mpi", "rdpi"):
        raise _Fail(f"--structure fit / --creep apply to --model pi, gpi, mpi or rdpi, not {args.model}")
    if args.creep < 0:
        raise _Fail(f"--creep = {args.creep} must be >= 0")
    if args.structure == "fit":
        extra["structure"] = "fit"
    if args.creep:
        extra["creep"] = args.creep
    res = identify(
        fit_input,
        fit_output,
        model=args.model,
        fs=train.fs,
        operators=args.operators,
        levels=args.levels,
        optimizer=args.optimizer,
        rng=args.seed,
        max_iterations=args.iterations,
        population_size=args.population,
        validate=validate,
        progress=bool(args.progress or sys.stderr.isatty()),
        **extra,
    )

    fit = res.to_dict()
    fit["data"] = {
        "train": {"source": str(data), "range": [a, b], "samples": b - a},
        "validation": None if val is None else {**val_where, "samples": val.n},
        "columns": dict(rec.columns),
        "fs": rec.fs,
    }
    doc = _model_document(res, args.model, train.fs)
    if res.partial:
        doc["partial"] = True  # Ctrl-C stopped the optimizer: the best model found before it
    doc["fit"] = fit
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
    write_atomic(out, text, overwrite=args.force, name="--out")
    if plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig = res.plot(train.input, train.output)
        try:
            write_atomic(
                plot, writer=lambda tmp: fig.savefig(tmp, format="png", dpi=110), overwrite=args.force, name="--plot"
            )
        finally:
            plt.close(fig)

    if args.json:
        report = {"out": str(out), "plot": None if plot is None else str(plot), "model": doc["kind"], **fit}
        print(json.dumps(report, indent=2, allow_nan=False))
    else:
        print(f"{args.model} identified by {res.method} in {res.wall_time:.3g} s -> {out}")
        rows = [("train", res.train, f"{data.name}[{a}:{b}], {b - a} samples")]
        if res.validation is not None:
            assert val is not None  # validation metrics are those of val
            rows.append(
                (
                    "validation",
                    res.validation,
                    f"{Path(val_where['source']).name}[{val_where['range'][0]}:"
                    f"{val_where['range'][1]}], {val.n} samples",
                )
            )
        print(f"  {'':<11} {'RMSE (% of range)':>18} {'max error (%)':>14}")
        for name, m, where in rows:
            print(f"  {name:<11} {_pct(m['rmse_percent']):>18} {_pct(m['max_error_percent']):>14}   ({where})")
        if plot is not None:
            print(f"  figure: {plot}")
    if res.partial:
        print(
            f'piezohyst identify: interrupted: {out} holds the best model found before Ctrl-C, marked "partial": true',
            file=sys.stderr,
        )
        return 130
    return 0


def _model_document(res: IdentificationResult, kind: str, fs: float) -> dict[str, Any]:
    """The model file's content (without the fit report): the model's own layout, a stage file
    for ``cemf``, the oscillator's parameters for ``boucwen-benchmark``."""
    if kind == "cemf":
        from ..plant.stage import Amplifier, Stage, StageParameters

        assert isinstance(res.model, StageParameters)  # what identify_cemf returns
        return Stage(res.model, Amplifier(), sample_time=1.0 / fs, name="identified CEMF stage").to_dict()
    if kind == "boucwen-benchmark":
        from ..models.boucwen_benchmark import UPSAMPLE, BoucWenBenchmark
        from ..models.model import SCHEMA_VERSION

        assert isinstance(res.model, BoucWenBenchmark)  # what identify_boucwen_benchmark returns

        return {
            "schema_version": SCHEMA_VERSION,
            "kind": "boucwen-benchmark",
            "parameters": res.model.parameters,
            "fs": fs,
            "upsample": UPSAMPLE,
            "units": {"input": "N", "output": "m"},
        }
    from ..models.model import HysteresisModel

    assert isinstance(res.model, HysteresisModel)  # the linear families and Bouc-Wen
    return res.model.to_dict()
