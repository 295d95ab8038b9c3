"""``piezohyst simulate``: run a saved model on an input record."""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..outputs import write_atomic
from .common import (
    _FORMATS,
    _add_record_options,
    _check_fs,
    _column,
    _column_help,
    _count_arg,
    _existing_file,
    _Fail,
    _load,
    _named,
    _parse_range,
    _Parser,
    _pct,
    _quantity,
    _read_model,
    _record_options,
    _writable,
)

if TYPE_CHECKING:
    from ..models.model import AnyModel
    from ..plant.stage import Stage
    from .common import FloatArray, _RecordOptions


def _simulate_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
    fmt = argparse.RawDescriptionHelpFormatter
    s = sub.add_parser(
        "simulate",
        formatter_class=fmt,
        help="simulate a model file on an input record; writes CSV",
        description=(
            "Simulate a model file (as written by 'piezohyst identify' or HysteresisModel.save) on the input\n"
            "signal of a record, from the relaxed initial state, and write CSV with the columns time (when\n"
            "known), input, output: exactly the numbers of load_model(MODEL).simulate(input), written so\n"
            "that they read back bit for bit. Every 'identify --model' kind's file simulates: a\n"
            "boucwen-benchmark file at its own fs (input force in N, output displacement in m), a cemf\n"
            "stage file open loop (input = voltage command, output = position: Stage.simulate(input).position).\n\n"
            "A multi-channel (MIMO) model file takes INPUT = U, a matrix (N, nu) of input voltages in V (one\n"
            "column per actuator; .npy, .npz with one array or the array named by --input, or delimited\n"
            "text), and writes YHAT (N, ny), the outputs in m, to --out (.npy, .npz with array y, or .csv;\n"
            "'-': CSV on standard output). --init-output Y0 (M, ny), the first M measured outputs in m,\n"
            "sets the initial state through the model's estimator (with U's first M samples); it is not\n"
            "used otherwise. Without it the model starts at rest.\n\n"
            + _FORMATS.replace("DATA formats", "INPUT formats")
        ),
        epilog=(
            "examples:\n"
            "  piezohyst simulate mpi.json sweep.csv --input voltage --fs 1000 --out predicted.csv\n"
            "  piezohyst simulate mpi.json run.csv --input v --output x --time t --out p.csv --json\n"
            "  piezohyst simulate mpi.json sweep.csv --input 0 > predicted.csv\n"
            "  piezohyst simulate mpi.json test.dat --input 0 --output 4 --fs 200 --rows 4652:6052 --lag 1 \\\n"
            "      --score-from 400 --out p.csv\n"
            "  piezohyst simulate fsm.json U.npy --init-output Y0.npy --out YHAT.npy  (MIMO: U (N, 3) V)\n\n"
            "exit status: 0 on success, 2 on bad input (one line on stderr naming the argument)."
        ),
    )
    s.add_argument("model", metavar="MODEL.json", help="the model file")
    s.add_argument("input_file", metavar="INPUT", help="the file holding the input signal (see the formats above)")
    s.add_argument(
        "--input",
        metavar="COL",
        help=_column_help(
            "input",
            "default: the column named 'input', else "
            "the only column besides --time; with --output, "
            "the first of exactly two",
        ),
    )
    s.add_argument(
        "--output",
        metavar="COL",
        help="a measured output column to compare with: adds RMSE and max error to the summary "
        "(not written to the CSV)",
    )
    g = s.add_mutually_exclusive_group()
    g.add_argument(
        "--fs",
        metavar="HZ",
        type=_quantity("Hz"),
        help="sample rate (> 0; a bare number is in Hz, or 10kHz), for the time column of the CSV; must "
        "agree with the sample time of a model that has one (rdpi, creep). Default: the model's, else no time column",
    )
    g.add_argument(
        "--time",
        metavar="COL",
        help="time column (strictly increasing, uniform), copied to the CSV in seconds; "
        "its unit from its name ('t [ms]') or --time-unit, else s",
    )
    s.add_argument(
        "--dataset",
        metavar="NAME",
        help="NPZ/MAT/HDF5: a 2-D matrix (rows = samples) whose columns integer COLs address",
    )
    _add_record_options(s)
    s.add_argument(
        "--rows",
        metavar="A:B",
        help="simulate only samples A (inclusive) to B (exclusive) of INPUT, from the relaxed state (default: all)",
    )
    s.add_argument(
        "--lag",
        metavar="N",
        type=_count_arg,
        default=0,
        help="the --output column lags the input by N samples (a sensor delay): compare "
        "output[k + N] with the simulation at k (default 0). A model file with an input_delay "
        "(identify --lag, --model auto) simulates that delay itself: leave --lag 0 for it",
    )
    s.add_argument(
        "--score-from",
        metavar="K",
        type=_count_arg,
        default=0,
        help="leave the first K simulated samples out of the comparison with --output (the "
        "model's warm-up from the relaxed state; default 0)",
    )
    s.add_argument(
        "--init-output",
        metavar="Y0",
        help="multi-channel models: the first M measured outputs (M, ny), in m (.npy, .npz, text), used only "
        "to set the initial state through the model's estimator",
    )
    s.add_argument(
        "--out",
        metavar="FILE",
        default="-",
        help="CSV file to write (default: '-', standard output); a multi-channel model's YHAT (N, ny) in m "
        "as .npy, .npz or .csv",
    )
    s.add_argument("--force", action="store_true", help="overwrite an existing --out file")
    s.add_argument(
        "--json",
        action="store_true",
        help="print summary statistics as JSON (needs --out FILE: the CSV cannot share stdout)",
    )
    s.add_argument("--debug", dest="sub_debug", action="store_true", help="show a traceback on errors")


def _model_ts(model: AnyModel | Stage) -> float | None:
    from ..models.boucwen_benchmark import BoucWenBenchmark
    from ..plant.stage import Stage

    if isinstance(model, BoucWenBenchmark):
        return 1.0 / model.fs
    if isinstance(model, Stage):
        return model.sample_time
    ts = getattr(model, "ts", None)
    if ts is None:
        ts = getattr(getattr(model, "creep", None), "ts", None)
    return None if ts is None else float(ts)


def _read_simulated(path: Path) -> AnyModel | Stage:
    """What MODEL holds: a model file (every ``identify --model`` kind; a ``boucwen-benchmark``
    file simulates at its own ``fs``) or a stage file (``identify --model cemf``, run open
    loop: the input is the voltage command, the output the position)."""
    from .._io import read_json_file
    from ..plant.stage import Stage

    d = read_json_file(path, "MODEL =")  # DataError: not JSON, too big, too deep, NaN, control characters
    if isinstance(d, dict) and d.get("kind") == "stage":
        try:
            return Stage.from_dict(d)
        except (ValueError, TypeError) as e:
            raise _Fail(f"MODEL = '{path}': {e}") from None
    from ..models.mimo import is_mimo_description, mimo_from_dict

    if is_mimo_description(d):  # a multi-channel model: cli/simulate_mimo.py runs it
        try:
            return mimo_from_dict(d)  # type: ignore[return-value]
        except (ValueError, TypeError) as e:
            raise _Fail(f"MODEL = '{path}': {e}") from None
    return _read_model(path, d)


def _run(model: AnyModel | Stage, v: FloatArray) -> FloatArray:
    """The model's output for ``v`` from rest (a stage: its open-loop position)."""
    from ..plant.stage import Stage

    if isinstance(model, Stage):
        return model.simulate(v).position
    return model.simulate(v)


def _kind(model: AnyModel | Stage) -> str:
    from ..plant.stage import Stage

    return "stage" if isinstance(model, Stage) else model.kind


def _model_units(model: object) -> dict[str, str]:
    """The units of a model's (or stage's) input and output, as its file gives them; a stage is
    in V and m."""
    from ..plant.stage import Stage

    if isinstance(model, Stage):
        return {"input": "V", "output": "m"}
    units = getattr(model, "units", None)
    return {k: v for k, v in units.items() if isinstance(v, str)} if isinstance(units, dict) else {}


def _read_input(
    path: Path,
    input_spec: str | int | None,
    time_spec: str | int | None,
    dataset: str | None,
    opts: _RecordOptions | None = None,
) -> tuple[FloatArray, FloatArray | None, float | None, dict[str, str]]:
    """The input column (and the time column when given) of a record file: what
    :func:`~piezohyst.data.load_record` reads, without requiring an output column."""
    from ..signals import data as D
    from ..signals.units import conversion_for

    suffix = path.suffix.lower()
    if dataset is not None and not dataset.strip():
        raise _Fail(f"--dataset = {dataset!r} may not be empty")
    opener: Callable[[], D.ColumnSource[Any]]
    if suffix in D.TEXT_SUFFIXES:
        if dataset is not None:
            raise _Fail(f"--dataset = {dataset!r} applies to NPZ/MAT/HDF5 files; {path} is a text file")
        opener = functools.partial(D.TextTable, path, None, "auto")
    elif suffix in D.NPZ_SUFFIXES:
        opener = functools.partial(D.open_npz, path, dataset)
    elif suffix in D.NPY_SUFFIXES:
        opener = functools.partial(D.open_npy, path, dataset)
    elif suffix in D.MAT_SUFFIXES:
        opener = functools.partial(D.open_mat, path, dataset)
    elif suffix in D.HDF5_SUFFIXES:
        opener = functools.partial(D.open_hdf5, path, dataset)
    elif suffix in D.PARQUET_SUFFIXES:
        opener = functools.partial(D.open_parquet, path, dataset)
    else:
        raise _Fail(
            f"INPUT = '{path}': unsupported file extension {path.suffix!r}; supported: {' '.join(D.SUPPORTED_SUFFIXES)}"
        )
    try:
        in_spec = D.check_column_spec(input_spec, "input")
        t_spec = D.check_column_spec(time_spec, "time")
        table: D.ColumnSource[Any] = opener()
        try:
            t_key = None if t_spec is None else table.resolve("time", t_spec)
            if in_spec is not None:
                key = table.resolve("input", in_spec)
            else:
                cols = table.columns()
                named = [c for c in cols if c[1] == "input"]
                free = [c for c in cols if t_key is None or c[0] != t_key[0]]
                if len(named) == 1:
                    key = named[0]
                elif len(free) == 1:
                    key = free[0]
                else:
                    raise _Fail(
                        f"{table.source}: --input not given and not inferable from the {len(cols)} columns "
                        f"{[lab for _, lab in cols]}; pass --input <name or 0-based index>"
                    )
            if t_key is not None and t_key[0] == key[0]:
                raise _Fail(f"{table.source}: --input and --time are the same column {key[1]!r}")
            v = table.read("input", *key)
            t = None if t_key is None else table.read("time", *t_key)
            o = opts or {}
            v = v * conversion_for("input", key[1], o.get("input_unit")).scale  # units -> SI
            if t is not None and t_key is not None:
                t = t * conversion_for("time", t_key[1], o.get("time_unit")).scale
        finally:
            table.close()
        if t is not None:
            assert t_key is not None  # t was read from the time column
            if t.size != v.size:
                raise _Fail(
                    f"{table.source}: time ({t_key[1]!r}) has {t.size} samples, input ({key[1]!r}) has "
                    f"{v.size}: lengths must match"
                )
            try:
                rtol = (opts or {}).get("time_rtol", D.TIME_RTOL)
                fs = D.fs_from_time(t, "time", rtol) if t.size >= 2 else None
            except ValueError as e:
                raise _Fail(f"{table.source}: {e}") from None
        else:
            fs = None
        if v.size < 1:
            raise _Fail(f"{table.source}: input column {key[1]!r} is empty")
        return v, t, fs, {"input": key[1], **({} if t_key is None else {"time": t_key[1]})}
    except _Fail:
        raise
    except (ValueError, TypeError, OSError, ImportError) as e:
        raise _named(e) from None


def _simulate(args: argparse.Namespace) -> None:
    import numpy as np

    from ..identify.core import fit_metrics

    fs = _check_fs(args.fs)
    model_path = _existing_file(args.model, "MODEL")
    input_path = _existing_file(args.input_file, "INPUT")
    to_stdout = args.out == "-"
    if to_stdout and args.json:
        raise _Fail("--json prints a summary on standard output; give --out FILE for the CSV")
    inputs = {"MODEL": model_path, "INPUT": input_path}
    out = None if to_stdout else _writable(args.out, "--out", args.force, inputs)
    model = _read_simulated(model_path)
    from .simulate_mimo import is_mimo, simulate_mimo

    if is_mimo(model):
        return simulate_mimo(args, model, model_path, input_path, out)
    if args.init_output is not None:
        raise _Fail(
            f"--init-output = '{args.init_output}' sets the state of a multi-channel model; "
            f"MODEL = '{model_path}' is a single-channel {_kind(model)} model (it starts at rest)"
        )

    opts = _record_options(args)
    measured = None
    if args.output is not None:
        rec = _load(
            input_path,
            input=_column(args.input),
            output=_column(args.output),
            time=_column(args.time),
            fs=fs if fs is not None or args.time is not None else 1.0,
            dataset=args.dataset,
            **opts,
        )
        v, t, measured, columns = rec.input, rec.time, rec.output, rec.columns
        fs_data = rec.fs if (fs is not None or t is not None) else None
    else:
        v, t, fs_time, columns = _read_input(input_path, _column(args.input), _column(args.time), args.dataset, opts)
        fs_data = fs if fs is not None else fs_time
    n_all = v.size
    a, b = _parse_range(args.rows, "--rows") if args.rows else (None, None)
    a = 0 if a is None else a
    b = n_all if b is None else b
    if not 0 <= a < b <= n_all:
        raise _Fail(f"--rows = '{args.rows}' must lie within the record's {n_all} samples and not be empty")
    if args.lag < 0:
        raise _Fail(f"--lag = {args.lag} must be >= 0")
    if measured is not None:
        if b + args.lag > n_all:
            raise _Fail(
                f"--lag = {args.lag}: output[{b - 1 + args.lag}] is beyond the record's {n_all} samples; "
                f"end --rows earlier"
            )
        measured = measured[a + args.lag : b + args.lag]
    v = v[a:b]
    t = None if t is None else t[a:b]
    if not 0 <= args.score_from < v.size:
        raise _Fail(f"--score-from = {args.score_from} must be >= 0 and below the {v.size} simulated samples")
    ts = _model_ts(model)
    if ts is not None and fs_data is not None and abs(fs_data * ts - 1.0) > 1e-6:
        name = "--fs" if args.fs is not None else "--time"
        raise _Fail(
            f"{name}: sample rate {fs_data:.9g} Hz disagrees with the model's sample time ts = {ts:.9g} s "
            f"({1 / ts:.9g} Hz); simulate at the rate the model was identified at"
        )
    fs_used = fs_data if fs_data is not None else (None if ts is None else 1.0 / ts)
    if t is None and fs_used is not None:
        t = np.arange(v.size) / fs_used

    t0 = time.perf_counter()
    try:
        y = _run(model, v)
    except (ValueError, TypeError) as e:
        raise _Fail(f"INPUT = '{input_path}': {e}") from None
    wall = time.perf_counter() - t0

    units = _model_units(model)
    cols = ([("time", t)] if t is not None else []) + [("input", v), ("output", y)]
    lists = [np.asarray(c, dtype=np.float64).tolist() for _, c in cols]
    # plain column names (readers select them by name: "time", "input", "output"); the units are
    # the model file's, printed in the summary and under "units" in --json
    lines = [",".join(name for name, _ in cols)]
    lines += [
        ",".join(map(repr, row)) for row in zip(*lists, strict=False)
    ]  # repr: shortest text that reads back exactly
    text = "\n".join(lines) + "\n"
    if out is None:  # "--out -"
        sys.stdout.write(text)
        return
    write_atomic(out, text, overwrite=args.force, name="--out", inputs=inputs)

    def stats(a: FloatArray) -> dict[str, float | None]:
        # on the record scaled to a largest magnitude of 1: a mean of values near 1e308 does not
        # overflow; a range beyond the largest double (values near +-1e308) is null in the JSON
        s = float(np.max(np.abs(a))) or 1.0
        mean, span = s * float(np.mean(a / s)), s * float(np.ptp(a / s))
        finite_span = span if np.isfinite(span) else None
        return {"min": float(np.min(a)), "max": float(np.max(a)), "mean": mean, "range": finite_span}

    summary = {
        "out": str(out),
        "model": _kind(model),
        "model_file": str(model_path),
        "input_file": str(input_path),
        "columns": dict(columns),
        "samples": int(v.size),
        "fs": fs_used,
        "wall_time_s": wall,
        "input": stats(v),
        "output": stats(y),
        "rows": [a, b],
        "lag": args.lag,
        "score_from": args.score_from,
        "error": None if measured is None else fit_metrics(y[args.score_from :], measured[args.score_from :]),
        "units": {"time": "s", "input": units.get("input", ""), "output": units.get("output", "")},
    }
    if args.json:
        print(json.dumps(summary, indent=2, allow_nan=False))
        return
    print(f"{_kind(model)} simulated on {v.size} samples of {input_path.name} in {wall:.3g} s -> {out}")
    unit = f" {units['output']}" if units.get("output") else " (the model file gives no unit)"
    print(f"  output {summary['output']['min']:.6g} .. {summary['output']['max']:.6g}{unit}")
    if measured is not None:
        m = summary["error"]
        scored = f" (samples {a + args.score_from}:{b}" + (f", output lagged {args.lag}" if args.lag else "") + ")"
        print(
            f"  vs measured: RMSE {_pct(m['rmse_percent'])} of range, max error {_pct(m['max_error_percent'])}{scored}"
        )
