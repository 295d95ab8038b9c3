"""``piezohyst export-c``: a saved model or controller as C code."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from ..outputs import check_output_dir
from .common import (
    _check_count,
    _count_arg,
    _existing_file,
    _Fail,
    _Parser,
    _quantity,
    _read_model,
)


def _export_c_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
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
            "it closes the loop around the model. A controller behind an inverse must use MODEL's inverse.\n"
            "A MIMO model file (kind 'mimo') gives piezohyst_mimo.h/.c for phs_mimo_* and an example.c that\n"
            "steps it on inputs read from a text file (one sample per line) and prints the outputs."
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
    e.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="output directory (created if missing; the files are put in place together, or not at all)",
    )
    e.add_argument(
        "--force",
        action="store_true",
        help="replace an earlier export in DIR (as a set: none of its files is left beside the new ones)",
    )
    e.add_argument(
        "--input-range",
        metavar=("LO", "HI"),
        nargs=2,
        type=_quantity("V"),
        help="input range the example drives the model over, in the model's input unit (V for a model of a "
        "stack's voltage: a bare number is in V, or 500mV) (default: the model's own range, e.g. an "
        "MPI input_range, else [0, 2 max threshold] for PI models, else [-1, 1])",
    )
    e.add_argument(
        "--steps", metavar="N", type=_count_arg, help="samples the example runs (default: 3 reference periods)"
    )
    e.add_argument("--json", action="store_true", help="print the written files and the build command as JSON")
    e.add_argument("--debug", dest="sub_debug", action="store_true", help="show a traceback on errors")


def _export_c(args: argparse.Namespace) -> None:
    from ..export import c as X
    from ..models.boucwen_benchmark import BoucWenBenchmark

    model_path = _existing_file(args.model, "MODEL")
    from .._io import read_json_file
    from ..models.mimo import is_mimo_description

    d = read_json_file(model_path, "MODEL =")
    if is_mimo_description(d):
        return _export_c_mimo(args, model_path, d)
    model = _read_model(model_path, d)
    if isinstance(model, BoucWenBenchmark):
        raise _Fail(
            f"MODEL = '{model_path}': kind 'boucwen-benchmark' (the Noel-Schoukens oscillator) has no C "
            f"export: the C library runs the hysteresis families (pi, gpi/mpi, rdpi, preisach, boucwen, "
            f"creep, duhem, dahl); simulate it with 'piezohyst simulate'"
        )
    if model.drift is not None:
        print(
            f"piezohyst export-c: warning: MODEL = '{model_path}' has a drift term (a trend of its training "
            "record's sensor, counted from that record's start): it is not exported; the C model is the "
            "actuator's (delay line, hysteresis, output map)",
            file=sys.stderr,
        )
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
    names = ["piezohyst_model.h", "piezohyst_model.c", "example.c"]
    names += ["piezohyst_controller.h", "piezohyst_controller.c"] if controller is not None else []
    names += ["piezohyst.h"] if X.header_path() is not None else []
    inputs = {"MODEL": model_path, "CONTROLLER": args.controller}
    out = check_output_dir(args.out, name="--out", overwrite=args.force, names=names, inputs=inputs)
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
            name="--out",
        )
    except ValueError as e:
        if str(e).startswith("--out"):  # the output folder (piezohyst.outputs), not the model
            raise
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


def _export_c_mimo(args: argparse.Namespace, model_path: Path, d: object) -> None:
    """A MIMO model file: ``piezohyst_mimo.h/.c``, ``example.c`` and ``piezohyst.h`` for the C
    library's ``phs_mimo_*`` functions."""
    from ..export import c as X
    from ..export.c_mimo import MIMO_EXPORT_FILES, export_c_mimo
    from ..models.mimo import mimo_from_dict

    for flag, value in (("CONTROLLER", args.controller), ("--input-range", args.input_range), ("--steps", args.steps)):
        if value is not None:
            raise _Fail(f"{flag} applies to single-channel models; MODEL = '{model_path}' is a MIMO model")
    try:
        model = mimo_from_dict(d)
    except (ValueError, TypeError) as e:
        raise _Fail(f"MODEL = '{model_path}': {e}") from None
    names = list(MIMO_EXPORT_FILES) + (["piezohyst.h"] if X.header_path() is not None else [])
    out = check_output_dir(args.out, name="--out", overwrite=args.force, names=names, inputs={"MODEL": model_path})
    written = export_c_mimo(model, out, force=args.force, source=model_path.name, name="--out")
    lib = X.library_path()
    build = (
        f"cc -std=c99 -O2 -ffp-contract=off -I{out} {out / 'example.c'} {out / 'piezohyst_mimo.c'} "
        f"{lib if lib else 'path/to/libpiezohyst.a'} {X.LINK_LIBS} -o {out / 'example'}"
    )
    if args.json:
        files = [str(p) for p in written]
        print(
            json.dumps(
                {"out": str(out), "files": files, "build": build, "library": None if lib is None else str(lib)},
                indent=2,
            )
        )
        return
    print(f"wrote {len(written)} files to {out}: {', '.join(p.name for p in written)} (MIMO model, phs_mimo_*)")
    if lib is None:
        print("  build the library first: cargo build --release -p piezohyst-capi")
    print(f"  build the example: {build}")
