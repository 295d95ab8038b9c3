"""``piezohyst identify``: fit a model to a record and save it."""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, NotRequired, TypedDict

from ..errors import ParameterError
from ..identify.dispatch import KINDS
from ..outputs import write_atomic
from . import stops
from .common import (
    _FORMATS,
    _add_record_options,
    _check_count,
    _check_fs,
    _column,
    _column_help,
    _count_arg,
    _existing_file,
    _Fail,
    _integer,
    _load,
    _parse_range,
    _parse_validate,
    _Parser,
    _pct,
    _quantity,
    _record_options,
    _resolve_range,
    _units_line,
    _units_report,
    _writable,
)

if TYPE_CHECKING:
    from ..identify.core import IdentificationResult
    from ..identify.structure import StructureChoice
    from ..signals.data import Record
    from .common import FloatArray, _Columns, _Range

#: Model kinds of ``piezohyst identify``: those of :func:`piezohyst.identify`, from its registry
#: (:data:`piezohyst.identify.KINDS`), in its order.
_KINDS = KINDS


class _Where(TypedDict):
    """Where the validation data come from: a file and a sample range of it (and, for a file
    that repeats the training data, ``independent: false`` with the ``warning``)."""

    source: str
    range: list[int]
    independent: NotRequired[bool]
    warning: NotRequired[str]


_OPTIMIZERS = ("css", "pso", "mpso", "de", "ls")


class _KindsOrAuto(tuple[str, ...]):
    """``--model``'s choices: the registry's kinds (what the choices list), and ``auto``."""

    def __contains__(self, key: object) -> bool:
        from ..identify.mimo import MIMO_KINDS  # the MIMO kinds, for multi-channel DATA (issue 15)

        return key == "auto" or key in MIMO_KINDS or tuple.__contains__(self, key)


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
            "validation: a --validate range of DATA is simulated with the model's state carried: the model\n"
            "runs from the start of --train through the validation range and only that range is scored\n"
            "(--validate-from rest: from rest, as before; a --validate FILE always starts from rest).\n"
            "The report gives RMSE and max error (output units and % of range) and the residual's\n"
            "whiteness (autocorrelation, cross-correlation with the input, Ljung-Box).\n\n"
            "exit status: 0 on success, 2 on bad input (one line on stderr naming the argument), 3 when the\n"
            "model was fitted (and written) but is not trustworthy: validation RMSE > 5 % of range, or a\n"
            "residual far from white (most autocorrelation lags outside the 95 % band with RMSE > 1 %);\n"
            'a diagnosis on stderr (and under "assessment" in --json) names the likely cause: offset,\n'
            "drift, delay, swapped columns, sample rate / time unit. Ctrl-C, SIGTERM and SIGHUP during the\n"
            'fit save the best model so far, marked "partial": true, and exit 130, 143 and 129.\n\n'
            "--out / --plot: regular files only (never DATA or a --validate file, not a FIFO, device or\n"
            "directory), checked before the fit; an existing file or a symbolic link is replaced only with\n"
            "--force (the link itself, never what it points to)."
        ),
    )
    i.add_argument("data", metavar="DATA", help="the record file (see the formats above)")
    _identify_options(i)
    _identify_outputs(i)


def _identify_options(i: argparse.ArgumentParser) -> None:
    """The fit's options (model, columns, ranges, preprocessing, optimizer), shared with ``piezohyst
    fleet identify``: what it passes on to :func:`_identify` for each record."""
    i.add_argument(
        "--model",
        metavar="KIND",
        required=True,
        choices=_KindsOrAuto(_KINDS),
        help=f"model to identify: {', '.join(_KINDS)} (required). Or auto: it fits pi, gpi, mpi, rdpi, "
        "preisach and boucwen (the PI family and preisach with and without --creep 2, mpi also with --creep 4, "
        "mpi and preisach with --creep 4 --creep-horizon 10, preisach also on a finer 20-level grid with and "
        "without --creep 2), each with its input delay, drift term and fit "
        "start chosen on the training range (--lag auto, --drift auto; with --validate the three best "
        "least-squares ones are also fitted with each other drift basis, rows NAME/nodrift, /drift1T, "
        "/drift3T), ranks them by validation "
        "error (state carried) and saves the winner: the simplest model within one standard error "
        "of the best (without --validate: by BIC on the training range); the league table is printed "
        'and put under "league" in --json. pi/gpi/mpi/rdpi/preisach: least '
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
    g.add_argument(
        "--fs",
        metavar="HZ",
        type=_quantity("Hz"),
        help="sample rate (> 0): a bare number is in Hz, or give a unit: 10kHz; this or --time is required",
    )
    g.add_argument(
        "--time",
        metavar="COL",
        help="time column (strictly increasing, uniform within --time-tolerance; gives the sample rate); "
        "seconds unless its name ('t [ms]') or --time-unit says otherwise",
    )
    i.add_argument(
        "--dataset",
        metavar="NAME",
        help="NPZ/MAT/HDF5: a 2-D matrix (rows = samples) whose columns integer COLs address",
    )
    _add_record_options(i)
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
        type=_count_arg,
        help="random seed of the optimizer (same seed, same result; default: fresh randomness)",
    )
    i.add_argument(
        "--operators",
        metavar="N",
        type=_count_arg,
        default=9,
        help="pi/gpi/mpi/rdpi: number of play operators, thresholds spread over half the input range (default: 9)",
    )
    i.add_argument(
        "--levels",
        metavar="N",
        type=_count_arg,
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
    i.add_argument(
        "--creep",
        metavar="M",
        type=_count_arg,
        default=0,
        help="pi/gpi/mpi/rdpi/preisach: add M creep lags (default 0)",
    )
    i.add_argument(
        "--creep-horizon",
        metavar="X",
        type=float,
        default=1.0,
        help="with --creep: the creep lags' time constants span 2 samples to X times the training range's "
        "duration (default 1; 10 models creep slower than the record, which a short record shows as a trend)",
    )
    # preprocessing (issue 14, item 2): piezohyst.signals.preprocess on DATA (and a --validate file)
    i.add_argument(
        "--lag",
        metavar="auto|N",
        default=None,
        help="input->output delay in samples, held by the model (its input_delay: the model file "
        "simulates the record as given); 'auto' or 'auto:M' chooses it on the training range (the "
        "delay whose fit has the smallest training error, up to M samples, default M: 20 ms of "
        "samples, at least 10). A negative N (output leading the input) cannot be a model's: the "
        "record is realigned instead (the output delayed), as for cemf and boucwen-benchmark "
        "(default: 0; --model auto: auto)",
    )
    i.add_argument(
        "--drift",
        metavar="none|auto|remove[:K]",
        default=None,
        help="'auto': a drift term of the model (an exponential settling of the output with the training "
        "range's duration or three times it as time constant, counted from its start, in the model file) fitted "
        "when an internal split of the training range says it predicts better (pi, gpi, mpi, rdpi, preisach, boucwen; "
        "fixed structure). 'remove': a slow polynomial drift (degree K, default 1) removed from the "
        "record before the fit, fitted together with a rate-independent function of the input. "
        "Creep is modelled by --creep (default: none; --model auto: auto)",
    )
    i.add_argument(
        "--lead-in",
        metavar="auto|none|N",
        default="none",
        help="drop a quiet lead-in before the excitation: 'auto' finds where the input starts to move, N "
        "drops N samples (default: none)",
    )
    i.add_argument(
        "--outliers",
        choices=("none", "flag", "drop"),
        default="none",
        help="glitches of the output (running median + MAD): 'flag' reports their rows (JSON "
        "preprocessing.outliers.rows) and warns; 'drop' replaces them by linear interpolation (samples are "
        "kept: the model needs a continuous time axis) (default: none)",
    )
    i.add_argument(
        "--decimate",
        metavar="N",
        type=_count_arg,
        default=1,
        help="keep every N-th sample after a zero-phase FIR anti-alias filter, on both channels (default: 1). "
        "With any preprocessing, --train/--validate count rows of DATA; they are mapped to the processed "
        "record (JSON preprocessing.index: processed sample j is row start + j*step)",
    )
    i.add_argument(
        "--offset",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="fit the output's offset (a sensor's zero) into the model's output map (default: on for every "
        "model but cemf and boucwen-benchmark, which have no map); --no-offset: the family's own terms only",
    )
    i.add_argument(
        "--validate-from",
        choices=("carried", "rest"),
        default="carried",
        help="carried (default): a --validate range of DATA is simulated from the start of --train with "
        "the state carried (across any gap); rest: the validation data simulated from rest",
    )
    i.add_argument(
        "--warmup",
        metavar="N",
        type=_count_arg,
        default=0,
        help="samples at the start of each scored range (train, validation) left out of the score (default 0)",
    )
    i.add_argument(
        "--periodic",
        metavar="N|auto",
        help="periodic records: simulate one period (N samples, or auto: estimated from the input) "
        "before each simulation, so the model starts in its periodic steady state",
    )
    i.add_argument(
        "--loss",
        choices=("l2", "huber", "linf"),
        default="l2",
        help="fit cost: l2 (default, least squares), huber (robust to glitches), linf (minimax: the "
        "largest error made smallest; a linear program for pi/gpi/mpi/rdpi/preisach, the max-abs "
        "error for boucwen)",
    )
    i.add_argument(
        "--weights",
        metavar="FILE|COL",
        help="sample weights (>= 0) of the linear families' fit: a column of DATA, or a text file "
        "with one weight per line (one per sample of DATA, or of the --train range)",
    )
    i.add_argument(
        "--iterations",
        metavar="N",
        type=_count_arg,
        help="optimizer iterations (populations evaluated) (default: 200 for boucwen, 150 for cemf, "
        "30 for boucwen-benchmark)",
    )
    i.add_argument(
        "--population",
        metavar="N",
        type=_count_arg,
        help="optimizer population size (default: max(20, 5 x number of parameters))",
    )
    i.add_argument(
        "--capacitance",
        metavar="F",
        type=_quantity("F"),
        help="cemf: the stack's capacitance, taken as known; a bare number is in farads, or give a unit: "
        "1800nF, 1.8uF (default: 1.8e-6 F, seed 1's 1800 nF)",
    )


def _identify_outputs(i: argparse.ArgumentParser) -> None:
    """``--out --plot --force --json --progress --debug`` of ``piezohyst identify``."""
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
    from .identify_mimo import _identify_mimo, _is_multichannel

    if _is_multichannel(args.data) or args.model.startswith("mimo-"):  # multi-channel DATA: MIMO models
        return _identify_mimo(args)

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
    inputs = {"DATA": data, "--validate": val_file}
    out = _writable(args.out, "--out", args.force, inputs)
    plot = None if args.plot is None else _writable(args.plot, "--plot", args.force, inputs)
    if plot is not None and plot.resolve() == out.resolve():
        raise _Fail(f"--plot = '{args.plot}' is the same file as --out")

    columns: _Columns = dict(
        input=_column(args.input),
        output=_column(args.output),
        time=_column(args.time),
        fs=fs,
        dataset=args.dataset,
        **_record_options(args),
    )
    if fs is None and args.time is None:
        raise _Fail("the sample rate is unknown: give --fs HZ or --time COL")
    rec = _load(data, **columns)
    model_lag, model_drift = _model_structure_flags(args)
    rec, preprocessing, train_spec, val_spec = _preprocess(args, rec, train_spec, val_spec, model_lag, model_drift)
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
            val = _preprocess_file(args, val, preprocessing)
            if abs(val.fs - rec.fs) > 1e-6 * rec.fs:
                raise _Fail(
                    f"--validate = '{val_file}' is sampled at {val.fs:.9g} Hz, DATA at {rec.fs:.9g} Hz; "
                    f"the records must share the sample rate"
                )
            val_where = {"source": str(val_file), "range": [0, val.n]}
            dependence = _not_independent(data, val_file, rec, val, (a, b))
            if dependence is not None:  # scored on what it was fitted to: say so, keep going
                val_where["independent"], val_where["warning"] = False, dependence
                print(f"piezohyst identify: warning: --validate = '{val_file}' {dependence}", file=sys.stderr)
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

    if args.structure == "fit" and args.model not in ("pi", "gpi", "mpi", "rdpi"):
        raise _Fail(f"--structure fit applies to --model pi, gpi, mpi or rdpi, not {args.model}")
    if args.creep and args.model not in ("pi", "gpi", "mpi", "rdpi", "preisach"):
        raise _Fail(f"--creep applies to --model pi, gpi, mpi, rdpi or preisach, not {args.model}")
    if args.creep < 0:
        raise _Fail(f"--creep = {args.creep} must be >= 0")
    if args.structure == "fit":
        extra["structure"] = "fit"
    if args.creep:
        extra["creep"] = args.creep
    if args.creep_horizon != 1.0:
        if not args.creep or not (math.isfinite(args.creep_horizon) and args.creep_horizon > 0):
            raise _Fail(f"--creep-horizon = {args.creep_horizon:g} needs --creep M and must be a finite number > 0")
        extra["creep_horizon"] = args.creep_horizon
    honest = _honest_options(args, rec, data, columns, (a, b), None if val_spec is None else (c, d), n)
    if args.model != "boucwen-benchmark":
        extra.update(honest.pop("identify"))
    elif args.warmup or args.periodic or args.loss != "l2" or args.weights or args.validate_from != "carried":
        raise _Fail(
            "--warmup / --periodic / --loss / --weights / --validate-from do not apply to --model boucwen-benchmark "
            "(it is simulated from the record's start and scores its ranges)"
        )
    common: dict[str, Any] = dict(
        fs=train.fs,
        operators=args.operators,
        levels=args.levels,
        optimizer=args.optimizer,
        rng=args.seed,
        max_iterations=args.iterations,
        population_size=args.population,
        validate=validate,
        progress=bool(args.progress or sys.stderr.isatty()),
        offset=args.offset,
    )
    league = None
    kind = args.model
    structure: dict[str, Any] | None = None
    if kind == "auto":
        kind, res, league, structure = _auto(fit_input, fit_output, common, extra, train.fs, model_lag, model_drift)
    else:
        if model_lag is not None or model_drift == "auto":
            choice = _decide(fit_input, fit_output, kind, common, extra, train.fs, model_lag, model_drift)
            structure = choice.to_dict()
            extra.update(_structure_options(choice))
        res = identify(fit_input, fit_output, model=kind, **common, **extra)

    fit = res.to_dict()
    fit["data"] = {
        "train": {"source": str(data), "range": [a, b], "samples": b - a},
        "validation": None if val is None else {**val_where, "samples": val.n},
        "columns": dict(rec.columns),
        "fs": rec.fs,
        "units": _units_report(rec),
    }
    fit["preprocessing"] = preprocessing
    output_map = getattr(res.model, "output_map", None)  # cemf, boucwen-benchmark: none
    fit["output_map"] = None if output_map is None else output_map.to_dict()
    fit.update(_structure_report(res.model, train.fs, model_lag, model_drift, structure))
    if preprocessing.get("lag") is not None and preprocessing["lag"].get("in_model"):
        # the model's input delay, known now: DATA and a --validate file are simulated with it
        preprocessing["lag"]["samples"] = fit["input_delay"]["samples"]
        preprocessing["lag"]["seconds"] = fit["input_delay"]["seconds"]
        if preprocessing.get("validation_file") is not None:
            preprocessing["validation_file"]["lag"] = dict(preprocessing["lag"])
    doc = _model_document(res, kind, train.fs)
    if isinstance(doc.get("units"), dict):  # the model's signals are in the record's (SI) units
        doc["units"] = {
            **{k: v for k, v in rec.si_units().items() if v},
            **{k: v for k, v in doc["units"].items() if v},
        }
    assessment = getattr(res, "assessment", None)
    if assessment is not None:
        fit["assessment"] = {**assessment, "note": honest["note"]} if honest["note"] else assessment
    if league is not None:
        fit["league"] = league
    partial = res.partial or stops.received() is not None  # a stop signal: the best model found before it
    if partial:
        doc["partial"] = fit["partial"] = True  # a stop signal: the best model found before it
    doc["fit"] = fit
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
    write_atomic(out, text, overwrite=args.force, name="--out", inputs=inputs)
    if plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        if val_spec is not None and args.validate_from == "carried" and c >= a and kind != "boucwen-benchmark":
            from ..identify.validation import plot_validation

            fig = plot_validation(
                res.simulate,
                rec.input[a:d],
                rec.output[a:d],
                {"train": (0, b - a), "validation": (c - a, d - a)},
                periodic=assessment["periodic"] if assessment else None,
            )
        else:
            fig = res.plot(train.input, train.output)
        try:
            write_atomic(
                plot,
                writer=lambda tmp: fig.savefig(tmp, format="png", dpi=110),
                overwrite=args.force,
                name="--plot",
                inputs=inputs,
            )
        finally:
            plt.close(fig)

    if args.json:
        named = doc["kind"] if kind == "cemf" else kind  # the kind fitted (mpi, not its file's gpi)
        report = {"out": str(out), "plot": None if plot is None else str(plot), "model": named, **fit}
        report["file_kind"] = doc["kind"]
        print(json.dumps(report, indent=2, allow_nan=False))
    else:
        if league is not None:
            _print_league(league)
        print(f"{kind} identified by {res.method} in {res.wall_time:.3g} s -> {out}")
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
        unit = rec.units["output"].si if "output" in rec.units else ""
        unit = f"({unit})" if unit else "(as read)"  # the output's unit: SI, or the file's when none was given
        w1, w2 = max(11, len("RMSE " + unit)), max(11, len("max error " + unit))
        print(
            f"  {'':<11} {'RMSE (% of range)':>18} {'max error (%)':>14} {'RMSE ' + unit:>{w1}} "
            f"{'max error ' + unit:>{w2}}"
        )
        for name, m, where in rows:
            print(
                f"  {name:<11} {_pct(m['rmse_percent']):>18} {_pct(m['max_error_percent']):>14} "
                f"{m['rmse']:>{w1}.4g} {m['max_error']:>{w2}.4g}   ({where})"
            )
        print(f"  units: {_units_line(rec)}")
        if any(not c.si for c in rec.units.values()):
            print("  (the model file carries the units the data give: name them with --input-unit / --output-unit)")
        _print_structure(fit)
        if assessment:
            _print_whiteness(assessment)
        if plot is not None:
            print(f"  figure: {plot}")
    if partial:
        signum = stops.received() or signal.SIGINT
        print(
            f"piezohyst identify: interrupted: {out} holds the best model found before {stops.describe(signum)}, "
            f'marked "partial": true',
            file=sys.stderr,
        )
        return stops.exit_code()
    if assessment and not assessment["trusted"]:
        _print_distrust(assessment)
        return 3
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


def _parse_lag(args: argparse.Namespace) -> tuple[int | str, int | None]:
    """``--lag``: ``(0 | N | "auto", M or None)``; no flag: 0, or ``"auto"`` for ``--model auto``."""
    if args.lag is None:
        return ("auto" if args.model == "auto" else 0), None
    lag = str(args.lag).strip()
    if lag == "auto" or lag.startswith("auto:"):
        if lag == "auto":
            return "auto", None
        return "auto", _integer(
            lag[5:], f"--lag = '{args.lag}': auto:M needs M, the largest lag searched, a number of samples"
        )
    return _integer(
        lag, f"--lag = '{args.lag}' must be 'auto', 'auto:M' or an integer number of samples", signed=True
    ), None


#: Kinds whose model holds an input delay (the others have no output map: the record is realigned).
_DELAY_KINDS = ("pi", "gpi", "mpi", "rdpi", "preisach", "boucwen", "auto")
#: Kinds that fit a drift term (fixed structure).
_DRIFT_KINDS = ("pi", "gpi", "mpi", "rdpi", "preisach", "boucwen", "auto")


def _model_structure_flags(args: argparse.Namespace) -> tuple[tuple[int | str, int | None] | None, str]:
    """What the model itself holds: ``(lag, max lag)`` of its input delay (``None``: the record is
    realigned by the preprocessing, or no delay) and its drift mode (``"auto"`` or ``"none"``)."""
    lag, top = _parse_lag(args)
    model_lag: tuple[int | str, int | None] | None = None
    if args.model in _DELAY_KINDS and (lag == "auto" or (isinstance(lag, int) and lag > 0)):
        model_lag = (lag, top)
    drift = "auto" if args.drift is None and args.model == "auto" else str(args.drift or "none")
    if drift == "auto":
        if args.model not in _DRIFT_KINDS or args.structure == "fit":
            raise _Fail(
                f"--drift auto fits a drift term of pi, gpi, mpi, rdpi, preisach or boucwen with a fixed structure, "
                f"not --model {args.model}{' --structure fit' if args.structure == 'fit' else ''}"
            )
        return model_lag, "auto"
    return model_lag, "none"


def _preprocess(
    args: argparse.Namespace,
    rec: Record,
    train: _Range | None,
    validate: _Range | None,
    model_lag: tuple[int | str, int | None] | None = None,
    model_drift: str = "none",
) -> tuple[Record, dict[str, Any], _Range | None, _Range | None]:
    """``--lag --drift --lead-in --outliers --decimate`` applied to DATA; the ``--train`` /
    ``--validate`` ranges (rows of DATA) mapped into the processed record. A lag the model
    holds (``model_lag``) and a drift it fits (``model_drift = "auto"``) leave the record as it is."""
    from ..signals.preprocess import preprocess, processed_index

    options: dict[str, Any] = {}
    lag, top = _parse_lag(args)
    if model_lag is None:
        options["lag"] = lag
        if top is not None:
            options["max_lag"] = top
    drift = "none" if model_drift == "auto" else str(args.drift or "none")
    if drift == "remove" or drift.startswith("remove:"):
        options["drift"] = "remove"
        if drift != "remove":
            options["drift_order"] = _integer(
                drift[7:], f"--drift = '{args.drift}': remove:K needs K, the polynomial degree (1 to 5)"
            )
    elif drift != "none":
        raise _Fail(f"--drift = '{args.drift}' must be 'none', 'auto', 'remove' or 'remove:K'")
    lead = str(args.lead_in)
    if lead in ("auto", "none"):
        options["lead_in"] = lead
    else:
        options["lead_in"] = _integer(
            lead, f"--lead-in = '{args.lead_in}' must be 'auto', 'none' or a number of samples"
        )
    options["outliers"] = args.outliers
    if args.decimate < 1:
        raise _Fail(f"--decimate = {args.decimate} must be >= 1")
    options["decimate"] = args.decimate
    try:
        out, report = preprocess(rec, **options)
    except (ValueError, TypeError) as e:
        raise _Fail(f"preprocessing DATA: {e}") from None
    _warn_outliers(report, "DATA")
    if model_lag is not None:  # the model's input delay: reported here too (the record is not shifted)
        report["lag"] = {
            "mode": "auto" if model_lag[0] == "auto" else "given",
            "samples": None if model_lag[0] == "auto" else model_lag[0],
            "seconds": None,
            "max_lag": model_lag[1],
            "in_model": True,
        }
        report["steps"].insert(
            report["steps"].index("drift") if "drift" in report["steps"] else len(report["steps"]), "lag"
        )
    if report["steps"] and not args.json and _summary(report):
        print(f"preprocessing: {_summary(report)}")
    if report["steps"]:
        report["ranges_of_data"] = {"train": None if train is None else list(train)}
        report["ranges_of_data"]["validate"] = None if validate is None else list(validate)

        def mapped(r: _Range | None) -> _Range | None:
            if r is None:
                return None
            a, b = (None if x is None else min(processed_index(report, x), out.n) for x in r)
            return a, b

        train, validate = mapped(train), mapped(validate)
    return out, report, train, validate


def _not_independent(data: Path, val_file: Path, rec: Record, val: Record, train: tuple[int, int]) -> str | None:
    """Why a --validate FILE is not independent of the training span of DATA (``None`` when it
    is): the same file (or a link to it), a byte-identical copy, or the same samples in another
    file (the whole record, or exactly the training span)."""
    import numpy as np

    a, b = train
    why = None
    try:
        if os.path.samefile(data, val_file):
            why = "is DATA itself (the same file)"
        elif data.stat().st_size == val_file.stat().st_size and _digest(data) == _digest(val_file):
            why = "is a byte-identical copy of DATA"
    except OSError:
        pass
    if why is None:
        spans = {"DATA": (rec.input, rec.output), "the training span": (rec.input[a:b], rec.output[a:b])}
        for label, (u, y) in spans.items():
            if u.size == val.n and np.array_equal(u, val.input) and np.array_equal(y, val.output):
                why = f"holds the same samples as {label}"
                break
    if why is None:
        return None
    return (
        f"{why}: the training span {a}:{b} is scored again, so the validation is not independent of the "
        "training (hold out a span instead: --train A:B --validate B:C)"
    )


def _digest(path: Path) -> bytes:
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.digest()


def _preprocess_file(args: argparse.Namespace, val: Record, report: dict[str, Any]) -> Record:
    """The same preprocessing on a --validate file, with DATA's lag (not estimated again)."""
    from ..signals.preprocess import preprocess

    if not report["steps"]:
        return val
    lag = 0 if report["lag"] is None or report["lag"].get("in_model") else int(report["lag"]["samples"])
    lead = str(args.lead_in)
    drift = report["drift"]
    try:
        out, rep = preprocess(
            val,
            lag=lag,
            drift="none" if drift is None else "remove",
            drift_order=1 if drift is None else int(drift["order"]),
            lead_in=lead if lead in ("auto", "none") else int(lead),
            outliers=args.outliers,
            decimate=args.decimate,
        )
    except (ValueError, TypeError) as e:
        raise _Fail(f"preprocessing --validate = '{args.validate}': {e}") from None
    _warn_outliers(rep, f"--validate = '{args.validate}'")
    report["validation_file"] = rep
    return out


def _warn_outliers(report: dict[str, Any], where: str) -> None:
    o = report["outliers"]
    if o is not None and o["count"]:
        rows = ", ".join(str(r) for r in o["rows"][:10]) + (" ..." if o["count"] > 10 else "")
        what = "replaced by linear interpolation" if o["replaced"] else "left in (--outliers drop replaces them)"
        print(
            f"piezohyst identify: warning: {o['count']} glitch(es) in the output of {where}, rows {rows}: {what}",
            file=sys.stderr,
        )


def _summary(report: dict[str, Any]) -> str:
    """One line saying what the preprocessing did."""
    parts = []
    if report["outliers"] is not None:
        o = report["outliers"]
        parts.append(f"{o['count']} glitch(es) " + ("interpolated over" if o["replaced"] else "flagged"))
    if report["lead_in"] is not None:
        parts.append(f"lead-in of {report['lead_in']['samples']} samples dropped")
    if report["lag"] is not None and not report["lag"].get("in_model"):
        parts.append(f"lag {report['lag']['samples']} samples ({report['lag']['mode']}) removed")
    if report["drift"] is not None:
        parts.append(f"drift of order {report['drift']['order']} removed (change {report['drift']['change']:.4g})")
    if report["decimate"] is not None:
        d = report["decimate"]
        parts.append(f"decimated by {d['factor']} to {d['fs_out']:g} Hz")
    return "; ".join(parts)


def _honest_options(
    args: argparse.Namespace,
    rec: Record,
    data: Path,
    columns: _Columns,
    train: tuple[int, int],
    val: tuple[int, int] | None,
    n: int,
) -> dict[str, Any]:
    """The validation and loss options of ``identify`` from the flags: ``{"identify": keywords,
    "note": what the report should say of how the validation was simulated}``."""
    import numpy as np

    a, b = train
    kw: dict[str, Any] = {"validate_from": args.validate_from}
    note = None
    if args.warmup < 0:
        raise _Fail(f"--warmup = {args.warmup} must be >= 0")
    kw["warmup"] = args.warmup
    if args.periodic is not None:
        if args.periodic == "auto":
            kw["periodic"] = "auto"
        else:
            kw["periodic"] = _integer(
                args.periodic, f"--periodic = '{args.periodic}' must be a period in samples (>= 1) or 'auto'"
            )
            if kw["periodic"] < 1:
                raise _Fail(f"--periodic = '{args.periodic}' must be a period in samples (>= 1) or 'auto'")
    kw["loss"] = {"l2": "squared"}.get(args.loss, args.loss)
    if args.validate_from == "carried" and args.validate is not None:
        if val is None:
            kw["validate_from"] = "rest"
            note = "the validation file is another record: simulated from rest"
        elif val[0] < a:
            kw["validate_from"] = "rest"
            note = "the validation range precedes the training range: simulated from rest"
        else:
            kw["gap"] = rec.input[b : val[0]]
    if args.weights is not None:
        if Path(args.weights).is_file():
            try:
                w = np.loadtxt(args.weights, dtype=np.float64, ndmin=1)
            except ValueError as e:
                raise _Fail(f"--weights = '{args.weights}' is not a file of numbers, one per line: {e}") from None
            if w.ndim != 1 or w.size not in (n, b - a):
                raise _Fail(
                    f"--weights = '{args.weights}' holds {w.size} values; expected one per sample of DATA ({n}) "
                    f"or of the --train range ({b - a})"
                )
            kw["weights"] = w[a:b] if w.size == n and n != b - a else w
        else:
            wcols: _Columns = {**columns, "output": _column(args.weights)}
            try:
                wrec = _load(data, **wcols)
            except ParameterError as e:
                raise _Fail(f"--weights = '{args.weights}' is neither a file nor a column of DATA ({e})") from None
            kw["weights"] = wrec.output[a:b]
    return {"identify": kw, "note": note}


#: The grid levels of ``--model auto``'s finer Preisach candidates (with ``--levels`` at or above
#: it they are not fitted: the regular grid is as fine). A decaying excitation's validation span
#: holds minor loops smaller than the training range's, spanning two to five cells of the
#: default 12-level grid. ``bench/identify_auto.py`` (the acceptance command, state carried),
#: against the league without them on the same machine: 10 kHz lookalikes 16 of 18 runs within
#: 0.5 % of the range (14), median 0.291 % (0.328); 5 kHz 17 of 18 within 0.2 % (16), median
#: 0.107 % (0.115); yan9a unchanged (7 of 8). Seeds 6-11, not used for the choice: 16 and 17 of
#: 18 with or without them, medians 0.293 % (0.302) and 0.123 % (0.128), no run worse. The
#: league takes about 40 % longer (a 10 kHz record's 57,551 training samples: 27 s against 20 s
#: on a 2-core Xeon).
AUTO_FINE_LEVELS = 20

#: ``--model auto``'s candidates: (kind, creep lags, creep horizon in training durations, grid
#: levels: ``None`` for ``--levels``). The MPI with four lags twice: over the record's time
#: scales, and reaching ten times its duration (creep slower than the record, which a short
#: training range shows as a trend). The Preisach grid with the same creep banks as the PI family
#: (two lags; four reaching ten durations): a loop shape no PI holds with creep, which a grid
#: without lags imitated by an input delay and missed on smaller loops (10 kHz lookalikes,
#: Preisach truth with a creep bank: 1.0-1.6 % validation RMSE without lags, 0.5 % with them;
#: bench/identify_auto.py). And a finer grid (:data:`AUTO_FINE_LEVELS`), with and without two
#: lags, for the minor loops a record's validation span reaches below its training range's
#: (a decaying excitation): see :data:`AUTO_FINE_LEVELS`.
_AUTO: tuple[tuple[str, int, float, int | None], ...] = (
    ("pi", 0, 1.0, None),
    ("pi", 2, 1.0, None),
    ("gpi", 0, 1.0, None),
    ("gpi", 2, 1.0, None),
    ("mpi", 0, 1.0, None),
    ("mpi", 2, 1.0, None),
    ("mpi", 4, 1.0, None),
    ("mpi", 4, 10.0, None),
    ("rdpi", 0, 1.0, None),
    ("rdpi", 2, 1.0, None),
    ("preisach", 0, 1.0, None),
    ("preisach", 2, 1.0, None),
    ("preisach", 4, 10.0, None),
    ("preisach", 0, 1.0, AUTO_FINE_LEVELS),
    ("preisach", 2, 1.0, AUTO_FINE_LEVELS),
    ("boucwen", 0, 1.0, None),
)

#: With a validation span, ``--model auto`` also fits its ``AUTO_DRIFT_FINALISTS`` best
#: candidates of the least-squares kinds (one solve each; a Bouc-Wen refit is a population
#: search) with each drift basis their internal split did not keep (none, or an exponential
#: settling of ``tau = T`` or ``3 T``, :data:`~piezohyst.identify.structure.DRIFT_BASES`), at the
#: same input delay and fit start, and ranks them beside the rest, as it ranks the families. The
#: internal split judges a drift on the last part of the training range alone; whether it goes on,
#: levels off or was creep shows over the span the model is scored on. bench/identify_auto.py
#: (the acceptance command, state carried; AMD EPYC, 2 cores, against the league without them
#: in the same session): yan9a 8 of 8 spans within 0.3 % (7: 1000:2000 -> 2000:8027, a settling
#: six training lengths long, 0.338 -> 0.203 %); lookalike draws 0-5 the same counts (5 kHz 17,
#: 10 kHz 16 of 18), four runs better, one worse by 0.002 %; draws 6-11, not used for the choice,
#: the same counts, 10 kHz median 0.235 % (0.293), nine runs better, none worse. A 10 kHz record
#: of 57,551 training samples: 35-39 s against 26-29 s.
AUTO_DRIFT_FINALISTS = 3


def _decide(
    v: FloatArray,
    y: FloatArray,
    kind: str,
    common: dict[str, Any],
    extra: dict[str, Any],
    fs: float,
    model_lag: tuple[int | str, int | None] | None,
    model_drift: str,
) -> StructureChoice:
    """The structure decisions of ``kind`` on the training range (the model's input delay, its
    drift basis, the fit's first sample): :func:`piezohyst.identify.structure.decide_structure`;
    a kind it does not cover (variable projection) takes an MPI's."""
    from ..identify.structure import decide_structure

    lag, top = (0, None) if model_lag is None else model_lag
    own = kind if kind in ("pi", "gpi", "mpi", "rdpi", "preisach", "boucwen") and "structure" not in extra else "mpi"
    try:
        return decide_structure(
            v,
            y,
            own,
            fs=fs,
            operators=common["operators"],
            levels=common["levels"],
            creep=extra.get("creep", 0) if own == kind else 0,
            creep_horizon=extra.get("creep_horizon", 1.0) if own == kind else 1.0,
            delay=lag,
            max_delay=top,
            drift=model_drift,
            # a delay line (given or chosen) starts held at the record's first input and a drift
            # term is a decision taken on the training range: both take the fit's start with
            # them (the same delay, given or found, gives the same model); no delay and no drift
            # leave the fit as it was
            start=0 if lag == 0 and model_drift != "auto" else "auto",
        )
    except ParameterError as e:
        raise _Fail(f"choosing the input delay and drift on the training range: {e}") from None


def _structure_options(choice: StructureChoice) -> dict[str, Any]:
    """``identify`` keywords of a structure choice."""
    return {
        "input_delay": choice.delay,
        "drift": None if choice.drift.empty else choice.drift,
        "fit_start": choice.start,
    }


def _structure_report(
    model: object,
    fs: float,
    model_lag: tuple[int | str, int | None] | None,
    model_drift: str,
    structure: dict[str, Any] | None,
) -> dict[str, Any]:
    """The ``--json`` fields of the model's input delay and drift, and what decided them."""
    delay = int(getattr(model, "input_delay", 0))
    drift = getattr(model, "drift", None)
    mode = None if model_lag is None else ("auto" if model_lag[0] == "auto" else "given")
    return {
        "input_delay": {"samples": delay, "seconds": delay / fs, "mode": mode},
        "drift": {
            "mode": model_drift,
            "basis": None if structure is None else structure["drift"]["name"],
            "chosen_by": None if structure is None else structure.get("drift_chosen_by"),
            "term": None if drift is None else drift.to_dict(),
            "time_origin": "the training range's first sample",
        },
        "structure": structure,
    }


def _auto(
    v: FloatArray,
    y: FloatArray,
    common: dict[str, Any],
    extra: dict[str, Any],
    fs: float,
    model_lag: tuple[int | str, int | None] | None,
    model_drift: str,
) -> tuple[str, IdentificationResult, list[dict[str, Any]], dict[str, Any] | None]:
    """``--model auto``: every candidate's structure decided on the training range (input delay,
    drift, fit start), every candidate fitted, with a validation span the finalists' drift
    variants too (:func:`_drift_variants`), the league ranked, the winner's result and its
    structure decisions."""
    from ..identify.dispatch import identify
    from ..identify.validation import league_table
    from ..progress import Progress

    if extra.get("structure") == "fit" or extra.get("creep"):
        raise _Fail("--model auto chooses the structure and the creep itself: drop --structure fit / --creep")
    results: list[tuple[str, int, IdentificationResult | None, str | None]] = []
    labels: list[str] = []
    choices: dict[int, StructureChoice] = {}
    settings: dict[int, dict[str, Any]] = {}  # each fitted candidate's identify keywords (its grid)
    bar = Progress(len(_AUTO), "auto: candidates fitted") if common.get("progress") else None
    for spec in _AUTO:
        kind, creep, horizon, levels = spec
        if bar is not None:
            bar.update(len(results))
        kw = _candidate_options(extra, spec)
        labels.append(
            kind
            + (str(levels) if levels is not None else "")
            + (f"+creep{creep}" if creep else "")
            + (f"x{horizon:g}T" if horizon != 1.0 else "")
        )
        if kind in ("boucwen",) and "weights" in kw:
            results.append((kind, creep, None, "--weights apply to the linear families"))
            continue
        if levels is not None and common["levels"] >= levels:
            results.append((kind, creep, None, f"--levels {common['levels']} is as fine as its {levels} levels"))
            continue
        signum = stops.received()
        if signum is not None:  # a stop signal: rank what was fitted before it
            results.append((kind, creep, None, f"stopped by {stops.describe(signum)}"))
            continue
        try:
            # Bouc-Wen takes the decisions of the MPI (rate independent, no creep), and the GPI
            # and MPI of one creep structure share theirs: the same regressors, the same decisions
            same = (
                ("mpi", 0, 1.0, None)
                if kind == "boucwen"
                else ("mpi" if kind == "gpi" else "gpi", creep, horizon, None)
            )
            choice = choices.get(_AUTO.index(same)) if same in _AUTO and kind in ("boucwen", "gpi", "mpi") else None
            own = {**common, "levels": common["levels"] if levels is None else levels, "progress": False}
            settings[len(results)] = own
            if choice is None:
                choice = _decide(v, y, kind, own, kw, fs, model_lag, model_drift)
            choices[len(results)] = choice
            kw.update(_structure_options(choice))
            fitted = identify(v, y, model=kind, **own, diagnosis=False, **kw)
            results.append((kind, creep, fitted, None))
        except ParameterError as e:
            results.append((kind, creep, None, str(e)))
    if bar is not None:
        bar.update(len(results))
        bar.close()
    specs = list(_AUTO)  # each row's (kind, creep, horizon, levels)
    if model_drift == "auto" and common.get("validate") is not None:
        _drift_variants(v, y, extra, results, labels, choices, settings, specs)
    table, best = league_table(results, v.size, labels=labels)
    kind, creep, res, _ = results[best]
    assert res is not None  # league_table picks a fitted one
    chosen = choices[best]
    if not getattr(res, "assessment", {}).get("trusted", True) and stops.received() is None:  # the winner's diagnosis
        opts = _candidate_options(extra, specs[best])
        res = identify(v, y, model=kind, **settings[best], **opts, **_structure_options(chosen))
    for row in table:
        c = choices.get(labels.index(row["name"]))
        if c is not None and row["rank"] is not None:
            row["input_delay"] = c.delay
            row["drift"] = c.drift.name
            row["drift_chosen_by"] = c.drift_by
            row["fit_start"] = c.start
            row["creep_horizon"] = specs[labels.index(row["name"])][2]
    return kind, res, table, chosen.to_dict()


def _candidate_options(extra: dict[str, Any], spec: tuple[str, int, float, int | None]) -> dict[str, Any]:
    """``identify`` keywords of a league candidate ``(kind, creep, horizon, levels)`` beside the
    command's own (its grid is in its settings)."""
    kw = dict(extra)
    if spec[1]:
        kw["creep"] = spec[1]
    if spec[2] != 1.0:
        kw["creep_horizon"] = spec[2]
    return kw


def _drift_variants(
    v: FloatArray,
    y: FloatArray,
    extra: dict[str, Any],
    results: list[tuple[str, int, IdentificationResult | None, str | None]],
    labels: list[str],
    choices: dict[int, StructureChoice],
    settings: dict[int, dict[str, Any]],
    specs: list[tuple[str, int, float, int | None]],
) -> None:
    """The league's :data:`AUTO_DRIFT_FINALISTS` best least-squares candidates (by validation
    RMSE) fitted again with each drift basis their internal split did not keep, appended to the
    league as rows ``NAME/nodrift``, ``NAME/drift1T``, ``NAME/drift3T`` (the settling's time
    constant in training durations)."""
    import dataclasses

    from ..identify.dispatch import LEAST_SQUARES_KINDS, identify
    from ..identify.structure import DRIFT_BASES, DriftBasis, drift_bases

    tagged = [(b, f"drift{f:g}T") for b, (_, f) in zip(drift_bases(v.size), DRIFT_BASES, strict=True)]
    bases = [(DriftBasis(), "nodrift"), *tagged]
    scored = sorted(
        (r.validation["rmse"], i)
        for i, (kind, _, r, _) in enumerate(results)
        if kind in LEAST_SQUARES_KINDS and r is not None and r.validation is not None
    )
    for _, i in scored[:AUTO_DRIFT_FINALISTS]:
        for basis, tag in bases:
            if basis.name == choices[i].drift.name or stops.received() is not None:
                continue
            choice = dataclasses.replace(choices[i], drift=basis, drift_by="validation")
            kind, creep = results[i][0], results[i][1]
            j = len(results)
            labels.append(f"{labels[i]}/{tag}")
            specs.append(specs[i])
            settings[j] = settings[i]
            choices[j] = choice
            try:
                opts = _candidate_options(extra, specs[i])
                fitted = identify(
                    v, y, model=kind, **settings[i], diagnosis=False, **opts, **_structure_options(choice)
                )
                results.append((kind, creep, fitted, None))
            except ParameterError as e:
                results.append((kind, creep, None, str(e)))


def _print_league(league: list[dict[str, Any]]) -> None:
    print(
        f"  {'rank':<5}{'model':<28}{'params':>7}{'delay':>6}  {'drift':<14}{'train %':>9}"
        f"{'validation %':>14}  ranked by"
    )
    for row in league:
        if row["rank"] is None:
            print(f"  {'-':<5}{row['name']:<28}{'':>7}{'':>6}  {'':<14}{'':>9}{'':>14}  not fitted: {row['error']}")
            continue
        mark = "  <- saved" if row["chosen"] else ""
        val = "-" if row["validation_rmse_percent"] is None else f"{row['validation_rmse_percent']:.4g}"
        print(
            f"  {row['rank']:<5}{row['name']:<28}{row['parameters']:>7}{row.get('input_delay', 0):>6}  "
            f"{row.get('drift', 'none'):<14}{row['train_rmse_percent']:>9.4g}{val:>14}  {row['criterion']}{mark}"
        )


def _print_structure(fit: dict[str, Any]) -> None:
    """The model's input delay and drift, when it has them or they were chosen."""
    d = fit["input_delay"]
    if d["samples"] or d["mode"] is not None:
        how = {"auto": "chosen on the training range", "given": "given"}.get(d["mode"] or "", "")
        print(
            f"  input delay: {d['samples']} samples ({d['seconds']:.4g} s), held by the model"
            + (f", {how}" if how else "")
        )
    drift = fit["drift"]
    if drift["mode"] == "auto":
        term = drift["term"]
        what = "none" if term is None else f"{drift['basis']} (from the training range's first sample)"
        how = (
            "ranked on the validation span (the league's drift variants)"
            if drift.get("chosen_by") == "validation"
            else "chosen by an internal split of the training range"
        )
        print(f"  drift term: {what}, {how}")


def _print_whiteness(assessment: dict[str, Any]) -> None:
    w = assessment.get("validation") or assessment.get("train")
    if not w:
        return
    print(
        f"  residual ({assessment['scored']}): "
        f"{100 * w['autocorrelation_outside']:.0f} % of {w['lags']} autocorrelation lags and "
        f"{100 * w['cross_correlation_outside']:.0f} % of input cross-correlation lags outside the 95 % band, "
        f"Ljung-Box Q = {w['ljung_box']:.4g} (p = {w['ljung_box_p']:.2g})"
    )


def _print_distrust(assessment: dict[str, Any]) -> None:
    print(f"piezohyst identify: fitted, not trustworthy: {'; '.join(assessment['reasons'])}", file=sys.stderr)
    causes = assessment.get("diagnosis") or []
    if not causes:
        print("  likely cause: none of offset, drift, delay, swapped columns, sample rate found", file=sys.stderr)
    for cause in causes:
        print(f"  likely cause: {cause['cause']}: {cause['evidence']}", file=sys.stderr)
