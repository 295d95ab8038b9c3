"""The ``piezohyst`` command line.

Every bad input ends the command with a one-line reason on stderr and exit code 2 (usage
errors included); ``--debug`` shows the traceback instead. Output files are written
atomically (a temporary file in the same directory, then ``os.replace``) and an existing file
is never replaced without ``--force``.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import time
from pathlib import Path

from ._io import write_atomic
from .errors import ParameterError, PiezohystError

__all__ = ["main"]

#: Model kinds of ``piezohyst identify`` (those of :func:`piezohyst.identify`).
_KINDS = ("pi", "gpi", "mpi", "rdpi", "preisach", "boucwen", "cemf", "boucwen-benchmark")
_OPTIMIZERS = ("css", "pso", "mpso", "de", "ls")


class _Parser(argparse.ArgumentParser):
    """argparse whose usage errors are one line on stderr with exit code 2 (docs/spec.md §8, §10)."""

    def error(self, message):
        msg = " ".join(str(message).split())
        self.exit(2, f"{self.prog}: error: {msg} (see {self.prog} --help)\n")


class _Fail(ParameterError):
    """A bad command-line input; the message names the argument and the value."""


_FORMATS = (
    "DATA formats: delimited text (.csv .tsv .txt .dat .asc; comma, tab, semicolon or whitespace\n"
    "separated; with or without a header line), NumPy .npz/.npy, MATLAB .mat (v4-v7; v7.3 with h5py),\n"
    "HDF5 (.h5 .hdf5 .he5, with h5py). A column COL is a name (header name, NPZ key, MATLAB variable or\n"
    "'s.field', HDF5 dataset path) or a 0-based index, an integer ('column 5' of a data README is 4)."
)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="piezohyst", description="Piezo hysteresis modelling, identification and compensation.")
    p.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = p.add_subparsers(dest="command", required=True)
    d = sub.add_parser(
        "demo",
        help="both papers end to end on the virtual stage: identify, compensate, track, "
        "report (index.html, report.md, figures, results.json)",
    )
    d.add_argument("--out", default="piezohyst-report", help="output directory (default: ./piezohyst-report)")
    d.add_argument("--force", action="store_true", help="overwrite an existing report")
    d.add_argument("--quick", action="store_true", help="smaller optimizer budgets (about 30 s)")
    d.add_argument("--seed", type=int, default=0, help="seed of the measurements and optimizers (default 0)")
    d.add_argument("--json", action="store_true", help="print the numbers as JSON")
    st = sub.add_parser("stage", help="stage utilities")
    st_sub = st.add_subparsers(dest="stage_command", required=True)
    info = st_sub.add_parser("info", help="measure stroke, hysteresis, resonance and creep of a stage by simulation")
    info.add_argument("--stage", metavar="FILE", help="stage file (JSON; default: the built-in virtual stage)")
    info.add_argument("--json", action="store_true", help="print the numbers as JSON")
    _identify_parser(sub)
    _simulate_parser(sub)
    _track_parser(sub)
    _export_c_parser(sub)
    b = sub.add_parser(
        "bench",
        help="run every benchmark in the source tree's bench/ and write one JSON + a "
        "Markdown table, each figure beside its same-run baseline",
    )
    b.add_argument("--only", nargs="+", metavar="NAME", help="run only these benchmarks")
    b.add_argument("--skip", nargs="+", metavar="NAME", help="skip these benchmarks")
    b.add_argument(
        "--quick", action="store_true", help="minimal repetitions and budgets (a smoke run, not figures to quote)"
    )
    b.add_argument("--report-only", action="store_true", help="do not run; summarize the JSON already in the results")
    b.add_argument(
        "--results",
        metavar="DIR",
        help="where the benchmarks write their JSON and the summary (default: bench/results)",
    )
    b.add_argument(
        "--readme",
        metavar="FILE",
        help="replace the section between <!-- bench:begin --> and <!-- bench:end --> of FILE with the table",
    )
    b.add_argument("--bench-dir", metavar="DIR", help="the bench/ directory (default: the source tree's)")
    return p


_CONTROLLERS = ("open-loop", "pid", "inverse", "smc", "smc-cemf", "absmc")
_REFERENCES = ("sine", "triangle", "variable-sine")


def _track_parser(sub) -> None:
    t = sub.add_parser(
        "track",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        help="simulate a controller tracking a reference on a stage (default: the virtual stage)",
        description=(
            "Run one controller in closed loop on a stage (amplifier, sensor noise, quantization and delay\n"
            "included) and print the tracking metrics: RMSE and max error (um and % of range), seed-2-style\n"
            "normalized errors, linearity error. Controllers: open-loop (static inverse gain), pid,\n"
            "inverse (exact inverse of a hysteresis model, with a one-sample lead), smc / smc-cemf (seed 1,\n"
            "Case 1 / Case 2, on the stage's own CEMF parameters), absmc (seed 2, behind the inverse).\n"
            "inverse and absmc use --model, or identify an MPI model from a simulated measurement first."
        ),
        epilog=(
            "examples:\n"
            "  piezohyst track --controller smc-cemf --reference triangle --freq 5 --amp 5 --offset 7\n"
            "  piezohyst track --controller absmc --reference sine --freq 80 --amp 8 --offset 9 --json\n\n"
            "exit status: 0 on success, 2 on bad input (one line on stderr naming the argument)."
        ),
    )
    t.add_argument("--stage", metavar="FILE", help="stage file (JSON; default: the built-in virtual stage)")
    t.add_argument("--controller", required=True, choices=_CONTROLLERS, help="controller kind")
    t.add_argument("--reference", default="sine", choices=_REFERENCES, help="reference kind (default sine)")
    t.add_argument("--freq", type=float, default=10.0, help="reference frequency, Hz (default 10)")
    t.add_argument("--amp", type=float, default=5.0, help="reference amplitude, um (default 5)")
    t.add_argument("--offset", type=float, default=8.0, help="reference centre, um (default 8)")
    t.add_argument("--duration", type=float, default=1.0, help="seconds (default 1)")
    t.add_argument("--skip", type=float, default=0.2, help="seconds left out of the metrics (default 0.2)")
    t.add_argument("--model", metavar="MODEL.json", help="hysteresis model file for inverse / absmc")
    t.add_argument("--seed", type=int, default=0, help="sensor-noise seed (default 0)")
    t.add_argument("--json", action="store_true", help="print the metrics as JSON")
    t.add_argument("--plot", metavar="FILE.png", help="write the tracking figure (not overwritten without --force)")
    t.add_argument("--force", action="store_true", help="overwrite --plot")


#: Longest `piezohyst track` run, samples (~1 GB of recorded signals).
_TRACK_MAX_SAMPLES = 10_000_000


def _track(args) -> None:
    import numpy as np

    from . import references as refs
    from .control import ABSMC, PID, SMC, Compensated, InverseFeedforward, OpenLoop, VelocityObserver
    from .stage import Stage, virtual_stage
    from .tuning import track

    stage = Stage.from_file(args.stage) if args.stage else virtual_stage()
    fs = 1.0 / stage.sample_time
    for name in ("freq", "amp", "duration"):
        if not getattr(args, name) > 0:
            raise _Fail(f"--{name} = {getattr(args, name)} must be > 0")
    if args.duration * fs > _TRACK_MAX_SAMPLES:
        raise _Fail(
            f"--duration = {args.duration:g} s is {args.duration * fs:.4g} samples at {fs:g} Hz; piezohyst track "
            f"runs at most {_TRACK_MAX_SAMPLES:.0e} (use piezohyst.closed_loop from Python for longer runs)"
        )
    amp, off = args.amp * 1e-6, args.offset * 1e-6
    if args.reference == "sine":
        _, ref = refs.sine(args.freq, amp, args.duration, fs, offset=off)
    elif args.reference == "triangle":
        _, ref = refs.triangle(args.freq, amp, args.duration, fs, offset=off)
    else:
        _, ref = refs.variable_amplitude_sine(args.freq, amp, args.duration, fs, offset=off)
    if args.plot and Path(args.plot).exists() and not args.force:
        raise _Fail(f"--plot {args.plot} exists; pass --force to overwrite it")

    def hysteresis_model():
        if args.model:
            from .model import load_model

            return load_model(args.model)
        from .identify import identify_mpi

        t = np.arange(int(2.0 * fs)) / fs
        u = 75 - 75 * np.clip(1 - 0.5 * t, 0.2, 1.0) * np.cos(2 * np.pi * 5 * t)
        x = stage.simulate(u).position
        return identify_mpi(u[:-1], x[1:], operators=9).model

    kind = args.controller
    if kind == "open-loop":
        c = OpenLoop()
    elif kind == "pid":
        c = PID(kp=2e6, ki=2e9)
    elif kind in ("smc", "smc-cemf"):
        c = SMC(
            stage.params, kp=1e6, kv=2e3, ks=20.0, phi=0.01, cemf=kind == "smc-cemf", observer=VelocityObserver(300.0)
        )
    elif kind == "inverse":
        c = InverseFeedforward(hysteresis_model(), c1=stage.sample_time)
    else:
        c = Compensated(ABSMC.linearized(2000.0, 0.7, c1=2e3, lam=2e3, ks=5e3, gamma_d=1e4), hysteresis_model())
    res = track(c, ref, stage=stage, rng=args.seed, skip=args.skip)
    m = res.metrics
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        fig = res.plot(zoom=(args.skip, args.skip + min(0.5 / args.freq, args.duration - args.skip)))
        _atomic_savefig(fig, args.plot)
    if args.json:
        print(
            json.dumps({"controller": kind, "reference": args.reference, "freq_hz": args.freq, "metrics": m}, indent=2)
        )
        return
    print(
        f"{kind} tracking a {args.freq:g} Hz {args.reference} ({args.amp:g} um around {args.offset:g} um), "
        f"{args.duration:g} s, metrics after {args.skip:g} s"
    )
    print(f"  RMSE          {m['rmse'] * 1e6:9.4f} um  ({m['rmse_percent']:.3f} % of range)")
    print(f"  max error     {m['max_error'] * 1e6:9.4f} um  ({m['max_error_percent']:.3f} % of range)")
    print(f"  normalized    max {m['normalized_max_error']:.4f}, rms {m['normalized_rms_error']:.4f}")
    print(f"  linearity     {m['linearity_error']:9.3f} %")


def _atomic_savefig(fig, path) -> None:
    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    write_atomic(path, writer=lambda tmp: fig.savefig(tmp, dpi=110, format=fmt))


def _column_help(role: str, default: str) -> str:
    return f"{role} column, by name or 0-based index ({default})"


def _identify_parser(sub) -> None:
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
            "select the samples scored. 'piezohyst simulate' reads neither file.\n\n"
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


def _simulate_parser(sub) -> None:
    fmt = argparse.RawDescriptionHelpFormatter
    s = sub.add_parser(
        "simulate",
        formatter_class=fmt,
        help="simulate a model file on an input record; writes CSV",
        description=(
            "Simulate a model file (as written by 'piezohyst identify' or HysteresisModel.save) on the input\n"
            "signal of a record, from the relaxed initial state, and write CSV with the columns time (when\n"
            "known), input, output: exactly the numbers of load_model(MODEL).simulate(input), written so\n"
            "that they read back bit for bit.\n\n" + _FORMATS.replace("DATA formats", "INPUT formats")
        ),
        epilog=(
            "examples:\n"
            "  piezohyst simulate mpi.json sweep.csv --input voltage --fs 1000 --out predicted.csv\n"
            "  piezohyst simulate mpi.json run.csv --input v --output x --time t --out p.csv --json\n"
            "  piezohyst simulate mpi.json sweep.csv --input 0 > predicted.csv\n"
            "  piezohyst simulate mpi.json test.dat --input 0 --output 4 --fs 200 --rows 4652:6052 --lag 1 \\\n"
            "      --score-from 400 --out p.csv\n\n"
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
        type=float,
        help="sample rate in Hz (> 0), for the time column of the CSV; must agree with the sample "
        "time of a model that has one (rdpi, creep). Default: the model's, else no time column",
    )
    g.add_argument(
        "--time", metavar="COL", help="time column in seconds (strictly increasing, uniform), copied to the CSV"
    )
    s.add_argument(
        "--dataset",
        metavar="NAME",
        help="NPZ/MAT/HDF5: a 2-D matrix (rows = samples) whose columns integer COLs address",
    )
    s.add_argument(
        "--rows",
        metavar="A:B",
        help="simulate only samples A (inclusive) to B (exclusive) of INPUT, from the relaxed state (default: all)",
    )
    s.add_argument(
        "--lag",
        metavar="N",
        type=int,
        default=0,
        help="the --output column lags the input by N samples (a sensor delay): compare "
        "output[k + N] with the simulation at k (default 0)",
    )
    s.add_argument(
        "--score-from",
        metavar="K",
        type=int,
        default=0,
        help="leave the first K simulated samples out of the comparison with --output (the "
        "model's warm-up from the relaxed state; default 0)",
    )
    s.add_argument("--out", metavar="FILE", default="-", help="CSV file to write (default: '-', standard output)")
    s.add_argument("--force", action="store_true", help="overwrite an existing --out file")
    s.add_argument(
        "--json",
        action="store_true",
        help="print summary statistics as JSON (needs --out FILE: the CSV cannot share stdout)",
    )
    s.add_argument("--debug", dest="sub_debug", action="store_true", help="show a traceback on errors")


# --------------------------------------------------------------------------------------------
# argument checks


def _column(spec):
    """A column spec from the command line: an integer string is a 0-based index."""
    if spec is None:
        return None
    s = spec.strip()
    if re.fullmatch(r"[+-]?\d+", s):
        return int(s)
    return spec


def _check_fs(fs):
    if fs is None:
        return None
    if not math.isfinite(fs) or fs <= 0:
        raise _Fail(f"--fs = {fs:g} must be a finite sample rate > 0 Hz")
    return fs


def _check_count(value, name, minimum=1):
    if value is not None and value < minimum:
        raise _Fail(f"{name} = {value} must be >= {minimum}")
    return value


def _existing_file(path, name) -> Path:
    p = Path(path)
    if not p.exists():
        raise _Fail(f"{name} = '{path}': no such file")
    if p.is_dir():
        raise _Fail(f"{name} = '{path}' is a directory, not a file")
    return p


def _writable(path, name, force) -> Path:
    p = Path(path)
    if p.is_dir():
        raise _Fail(f"{name} = '{path}' is a directory; give a file name")
    if p.exists() and not force:
        raise _Fail(f"{name} = '{path}' exists; pass --force to overwrite it")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise _Fail(f"{name} = '{path}': directory '{parent}' does not exist")
    return p


_RANGE = re.compile(r"\s*([^:]*?)\s*:\s*([^:]*?)\s*")


def _parse_range(text, name):
    """``"A:B"`` with either side optional -> ``(A or None, B or None)``; non-negative integers."""
    m = _RANGE.fullmatch(text)
    if m is None:
        raise _Fail(f"{name} = '{text}' is not a sample range A:B (0-based, B exclusive; either side may be omitted)")
    out = []
    for part in m.groups():
        if part == "":
            out.append(None)
        elif re.fullmatch(r"\+?\d+", part):
            out.append(int(part))
        else:
            raise _Fail(f"{name} = '{text}': {part!r} is not a sample index (a non-negative integer)")
    return tuple(out)


def _resolve_range(spec, n, name, text, what="DATA"):
    a = 0 if spec[0] is None else spec[0]
    b = n if spec[1] is None else spec[1]
    if a >= n:
        raise _Fail(f"{name} = '{text}': start {a} is beyond the end of {what} ({n} samples, indices 0..{n - 1})")
    if b > n:
        raise _Fail(
            f"{name} = '{text}': stop {b} is beyond the end of {what} ({n} samples; stop is exclusive, at most {n})"
        )
    if b <= a:
        raise _Fail(f"{name} = '{text}': start {a} is not before stop {b}")
    if b - a < 2:
        raise _Fail(f"{name} = '{text}' keeps {b - a} sample; at least 2 are needed")
    return a, b


def _parse_validate(text):
    """``--validate``: a sample range of DATA, or a file. Returns ``(range, None)`` or ``(None, path)``."""
    if text is None:
        return None, None
    if re.fullmatch(r"\s*\+?\d*\s*:\s*\+?\d*\s*", text):
        return _parse_range(text, "--validate"), None
    if Path(text).exists():
        return None, _existing_file(text, "--validate")
    if ":" in text and not re.search(r"[/\\.]", text):
        return _parse_range(text, "--validate"), None  # a malformed range: say why
    raise _Fail(f"--validate = '{text}': no such file (and not a sample range A:B)")


_ROLE = re.compile(r"(?<![\w-])(input|output|time|fs|dataset)(?= = | is not )")


def _named(e: Exception, prefix: str = "") -> _Fail:
    """A loader's error with its argument names spelled as the options (``input =`` -> ``--input =``)."""
    msg = str(e)
    if isinstance(e, FileNotFoundError) and e.filename is not None and not msg.startswith(str(e.filename)):
        msg = f"{e.filename}: {e.strerror or msg}"
    return _Fail(prefix + _ROLE.sub(r"--\1", msg))


def _load(path, **kw):
    from .data import load_record

    try:
        return load_record(path, **kw)
    except (ValueError, TypeError, OSError, ImportError) as e:
        raise _named(e) from None


def _pct(x) -> str:
    return f"{x:.4g} %"


# --------------------------------------------------------------------------------------------
# piezohyst identify


def _identify(args) -> int:
    from .identify import identify

    _check_count(args.operators, "--operators")
    _check_count(args.levels, "--levels")
    _check_count(args.iterations, "--iterations")
    _check_count(args.population, "--population", minimum=2)
    if args.seed is not None and args.seed < 0:
        raise _Fail(f"--seed = {args.seed} must be >= 0")
    extra = {}
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

    columns = dict(
        input=_column(args.input), output=_column(args.output), time=_column(args.time), fs=fs, dataset=args.dataset
    )
    if fs is None and args.time is None:
        raise _Fail("the sample rate is unknown: give --fs HZ or --time COL")
    rec = _load(data, **columns)
    n = rec.n
    val = None
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


def _model_document(res, kind, fs) -> dict:
    """The model file's content (without the fit report): the model's own layout, a stage file
    for ``cemf``, the oscillator's parameters for ``boucwen-benchmark``."""
    if kind == "cemf":
        from .stage import Amplifier, Stage

        return Stage(res.model, Amplifier(), sample_time=1.0 / fs, name="identified CEMF stage").to_dict()
    if kind == "boucwen-benchmark":
        from .boucwen_benchmark import UPSAMPLE
        from .model import SCHEMA_VERSION

        return {
            "schema_version": SCHEMA_VERSION,
            "kind": "boucwen-benchmark",
            "parameters": res.model.parameters,
            "fs": fs,
            "upsample": UPSAMPLE,
            "units": {"input": "N", "output": "m"},
        }
    return res.model.to_dict()


# --------------------------------------------------------------------------------------------
# piezohyst simulate


def _read_model(path: Path):
    from .model import model_from_dict

    try:
        d = json.loads(path.read_text())
    except UnicodeDecodeError:
        raise _Fail(f"MODEL = '{path}' is not a text (JSON) file") from None
    except json.JSONDecodeError as e:
        raise _Fail(f"MODEL = '{path}' is not valid JSON: {e}") from None
    if isinstance(d, dict):
        d = {k: v for k, v in d.items() if k != "fit"}  # the fit report is not part of the model
    try:
        return model_from_dict(d)
    except (ValueError, TypeError) as e:
        raise _Fail(f"MODEL = '{path}': {e}") from None


def _model_ts(model):
    ts = getattr(model, "ts", None)
    if ts is None:
        ts = getattr(getattr(model, "creep", None), "ts", None)
    return None if ts is None else float(ts)


def _read_input(path: Path, input_spec, time_spec, dataset):
    """The input column (and the time column when given) of a record file: what
    :func:`~piezohyst.data.load_record` reads, without requiring an output column."""
    from . import data as D

    suffix = path.suffix.lower()
    if dataset is not None and not dataset.strip():
        raise _Fail(f"--dataset = {dataset!r} may not be empty")
    if suffix in D.TEXT_SUFFIXES:
        if dataset is not None:
            raise _Fail(f"--dataset = {dataset!r} applies to NPZ/MAT/HDF5 files; {path} is a text file")
        opener = lambda: D._TextTable(path, None, "auto")
    elif suffix in D.NPZ_SUFFIXES:
        opener = lambda: D._open_npz(path, dataset)
    elif suffix in D.NPY_SUFFIXES:
        opener = lambda: D._open_npy(path, dataset)
    elif suffix in D.MAT_SUFFIXES:
        opener = lambda: D._open_mat(path, dataset)
    elif suffix in D.HDF5_SUFFIXES:
        opener = lambda: D._open_hdf5(path, dataset)
    else:
        raise _Fail(
            f"INPUT = '{path}': unsupported file extension {path.suffix!r}; supported: {' '.join(D.SUPPORTED_SUFFIXES)}"
        )
    try:
        in_spec = D._check_column_spec(input_spec, "input")
        t_spec = D._check_column_spec(time_spec, "time")
        table = opener()
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
        finally:
            close = getattr(table, "close", None)
            if close is not None:
                close()
        if t is not None:
            if t.size != v.size:
                raise _Fail(
                    f"{table.source}: time ({t_key[1]!r}) has {t.size} samples, input ({key[1]!r}) has "
                    f"{v.size}: lengths must match"
                )
            try:
                fs = D._fs_from_time(t, "time", D.TIME_RTOL) if t.size >= 2 else None
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


def _simulate(args) -> None:
    import numpy as np

    from .identify import fit_metrics

    fs = _check_fs(args.fs)
    model_path = _existing_file(args.model, "MODEL")
    input_path = _existing_file(args.input_file, "INPUT")
    to_stdout = args.out == "-"
    if to_stdout and args.json:
        raise _Fail("--json prints a summary on standard output; give --out FILE for the CSV")
    out = None if to_stdout else _writable(args.out, "--out", args.force)
    model = _read_model(model_path)

    measured = None
    if args.output is not None:
        rec = _load(
            input_path,
            input=_column(args.input),
            output=_column(args.output),
            time=_column(args.time),
            fs=fs if fs is not None or args.time is not None else 1.0,
            dataset=args.dataset,
        )
        v, t, measured, columns = rec.input, rec.time, rec.output, rec.columns
        fs_data = rec.fs if (fs is not None or t is not None) else None
    else:
        v, t, fs_time, columns = _read_input(input_path, _column(args.input), _column(args.time), args.dataset)
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
        y = model.simulate(v)
    except (ValueError, TypeError) as e:
        raise _Fail(f"INPUT = '{input_path}': {e}") from None
    wall = time.perf_counter() - t0

    cols = ([("time", t)] if t is not None else []) + [("input", v), ("output", y)]
    lists = [np.asarray(c, dtype=np.float64).tolist() for _, c in cols]
    lines = [",".join(name for name, _ in cols)]
    lines += [
        ",".join(map(repr, row)) for row in zip(*lists, strict=False)
    ]  # repr: shortest text that reads back exactly
    text = "\n".join(lines) + "\n"
    if to_stdout:
        sys.stdout.write(text)
        return
    write_atomic(out, text, overwrite=args.force, name="--out")

    def stats(a):
        return {"min": float(np.min(a)), "max": float(np.max(a)), "mean": float(np.mean(a)), "range": float(np.ptp(a))}

    summary = {
        "out": str(out),
        "model": model.kind,
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
    }
    if args.json:
        print(json.dumps(summary, indent=2, allow_nan=False))
        return
    print(f"{model.kind} simulated on {v.size} samples of {input_path.name} in {wall:.3g} s -> {out}")
    print(f"  output {summary['output']['min']:.6g} .. {summary['output']['max']:.6g}")
    if measured is not None:
        e = summary["error"]
        scored = f" (samples {a + args.score_from}:{b}" + (f", output lagged {args.lag}" if args.lag else "") + ")"
        print(
            f"  vs measured: RMSE {_pct(e['rmse_percent'])} of range, max error {_pct(e['max_error_percent'])}{scored}"
        )


# --------------------------------------------------------------------------------------------
# piezohyst export-c


def _export_c_parser(sub) -> None:
    e = sub.add_parser(
        "export-c",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        help="write C initializers of a model (and controller) and an example loop for the C library",
        description=(
            "Write the model file's parameters as a C initializer (piezohyst_model.h/.c) and, when given, the\n"
            "controller file's (piezohyst_controller.h/.c; written by piezohyst.export_c.save_controller), a copy\n"
            "of piezohyst.h and example.c: a minimal real-time loop that compiles with cc against the C library\n"
            "(crates/capi: `cargo build --release -p piezohyst-capi` gives target/release/libpiezohyst.a). The\n"
            "C library runs the same code as Python: the exported objects give the same numbers, bit for bit.\n"
            "Without a controller the example runs the model's exact inverse (inverse feedforward); with one,\n"
            "it closes the loop around the model. A controller behind an inverse must use MODEL's inverse."
        ),
        epilog=(
            "examples:\n"
            "  piezohyst export-c mpi.json --out c/\n"
            "  piezohyst export-c mpi.json absmc.json --out c/ --force\n\n"
            "exit status: 0 on success, 2 on bad input (one line on stderr naming the argument)."
        ),
    )
    e.add_argument("model", metavar="MODEL.json", help="the model file (piezohyst identify, HysteresisModel.save)")
    e.add_argument(
        "controller",
        metavar="CONTROLLER.json",
        nargs="?",
        help="a controller file (piezohyst.export_c.save_controller)",
    )
    e.add_argument("--out", metavar="DIR", required=True, help="output directory (created if missing)")
    e.add_argument("--force", action="store_true", help="overwrite existing files in DIR")
    e.add_argument(
        "--input-range",
        metavar=("LO", "HI"),
        nargs=2,
        type=float,
        help="input range the example drives the model over (default: the model's own range, e.g. an "
        "MPI input_range, else [0, 2 max threshold] for PI models, else [-1, 1])",
    )
    e.add_argument("--steps", metavar="N", type=int, help="samples the example runs (default: 3 reference periods)")
    e.add_argument("--json", action="store_true", help="print the written files and the build command as JSON")
    e.add_argument("--debug", dest="sub_debug", action="store_true", help="show a traceback on errors")


def _export_c(args) -> None:
    from . import export_c as X

    model_path = _existing_file(args.model, "MODEL")
    model = _read_model(model_path)
    controller = None
    if args.controller is not None:
        cpath = _existing_file(args.controller, "CONTROLLER")
        try:
            controller = X.load_controller(cpath)
        except (ValueError, FileNotFoundError) as e:
            raise _Fail(f"CONTROLLER = '{cpath}': {e}") from None
    _check_count(args.steps, "--steps")
    if args.input_range is not None:
        lo, hi = args.input_range
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise _Fail(f"--input-range = {lo:g} {hi:g} must be finite with LO < HI")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise _Fail(f"--out = '{out}' exists and is not a directory")
    if not out.exists() and not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise _Fail(f"--out = '{out}': directory '{out.parent}' does not exist")
    source = model_path.name + (f" and {Path(args.controller).name}" if controller is not None else "")
    try:
        written = X.export_c(
            model,
            out,
            controller=controller,
            force=args.force,
            source=source,
            input_range=args.input_range,
            steps=args.steps,
        )
    except FileExistsError as e:
        raise _Fail(str(e)) from None
    except ValueError as e:
        raise _Fail(f"{'CONTROLLER' if controller is not None else 'MODEL'}: {e}") from None
    lib = X.library_path()
    sources = "example.c piezohyst_model.c" + (" piezohyst_controller.c" if controller is not None else "")
    build = (
        f"cc -std=c99 -O2 -ffp-contract=off -I{out} "
        + " ".join(str(out / s) for s in sources.split())
        + f" {lib if lib else 'path/to/libpiezohyst.a'} {X.LINK_LIBS} -o {out / 'example'}"
    )
    if args.json:
        print(
            json.dumps(
                {
                    "out": str(out),
                    "files": [str(p) for p in written],
                    "build": build,
                    "library": None if lib is None else str(lib),
                },
                indent=2,
            )
        )
        return
    print(f"wrote {len(written)} files to {out}: {', '.join(p.name for p in written)}")
    if lib is None:
        print("  build the library first: cargo build --release -p piezohyst-capi")
    print(f"  build the example: {build}")


# --------------------------------------------------------------------------------------------


def _stage_info(args) -> None:
    from .stage import Stage, virtual_stage

    stage = Stage.from_file(args.stage) if args.stage else virtual_stage()
    info = stage.info().to_dict()
    if args.json:
        print(json.dumps(info, indent=2))
        return
    name = stage.name or (args.stage or "virtual stage")
    print(f"{name}")
    print(f"  stroke (0..{info['full_range_V'][1]:g} V, 1 Hz)      {info['stroke_um']:8.2f} um")
    print(f"  hysteresis (1 Hz, full range)   {info['hysteresis_percent_1hz_full_range']:8.2f} % of output range")
    print(f"  first resonance (measured)      {info['first_resonance_hz']:8.0f} Hz")
    print(
        f"  mechanical natural frequency    {info['natural_frequency_hz']:8.0f} Hz (damping ratio {info['damping_ratio']:.3f})"
    )
    print(f"  creep                           {info['creep_percent_per_decade']:8.2f} % per time decade (0.1..100 s)")


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    debug = args.debug or getattr(args, "sub_debug", False)
    prog = (
        f"piezohyst {args.command}"
        if args.command in ("identify", "simulate", "track", "export-c", "bench")
        else "piezohyst"
    )
    try:
        if args.command == "stage":
            _stage_info(args)
        elif args.command == "demo":
            from .demo import run_demo

            quiet = (lambda *a, **k: None) if args.json else print
            numbers = run_demo(args.out, force=args.force, quick=args.quick, seed=args.seed, print_fn=quiet)
            if args.json:
                print(json.dumps(numbers, indent=2))
        elif args.command == "identify":
            return _identify(args)
        elif args.command == "simulate":
            _simulate(args)
        elif args.command == "track":
            _track(args)
        elif args.command == "export-c":
            _export_c(args)
        elif args.command == "bench":
            from .benchmarks import main as bench_main

            failed = bench_main(args)["failed"]
            if failed:
                print(
                    f"piezohyst bench: {len(failed)} benchmark(s) did not produce results: {', '.join(failed)}",
                    file=sys.stderr,
                )
                return 1
        return 0
    except KeyboardInterrupt:
        if debug:
            raise
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except MemoryError as e:
        if debug:
            raise
        print(f"{prog}: error: out of memory ({' '.join(str(e).split()) or 'MemoryError'})", file=sys.stderr)
        return 2
    except (PiezohystError, ValueError, TypeError, OSError, ImportError) as e:
        if debug:
            raise
        msg = " ".join(str(e).split())  # one line, whatever the message
        print(f"{prog}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
