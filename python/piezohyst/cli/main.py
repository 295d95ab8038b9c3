"""The ``piezohyst`` command line: the parser and :func:`main`; one module per command
(``demo``, ``stage``, ``identify``, ``simulate``, ``track``, ``export-c``, ``bench``, ``fleet``,
``robustness``), their
shared checks and readers in :mod:`piezohyst.cli.common`.

Every bad input ends the command with a one-line reason on stderr and exit code 2 (usage
errors included); ``--debug`` shows the traceback instead. Output files are written
atomically (a temporary file in the same directory, then ``os.replace``) and an existing file
is never replaced without ``--force``.
"""

from __future__ import annotations

import argparse
import atexit
import os
import sys
from collections.abc import Callable, Sequence
from typing import NoReturn

from ..errors import PiezohystError
from .bench import _bench, _bench_parser
from .common import _Parser
from .demo import _demo, _demo_parser
from .export_c import _export_c, _export_c_parser
from .fleet import _fleet, _fleet_parser
from .identify import _identify, _identify_parser
from .robustness import _robustness, _robustness_parser
from .simulate import _simulate, _simulate_parser
from .stage import _stage_info, _stage_parser
from .track import _track, _track_parser

__all__ = ["main", "run"]


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="piezohyst", description="Piezo hysteresis modelling, identification and compensation.")
    p.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = p.add_subparsers(dest="command", required=True)
    _demo_parser(sub)
    _stage_parser(sub)
    _identify_parser(sub)
    _simulate_parser(sub)
    _track_parser(sub)
    _export_c_parser(sub)
    _bench_parser(sub)
    _fleet_parser(sub)
    _robustness_parser(sub)
    return p


#: What each command runs; ``None`` or nothing returned means exit code 0.
_COMMANDS: dict[str, Callable[[argparse.Namespace], int | None]] = {
    "stage": _stage_info,
    "demo": _demo,
    "identify": _identify,
    "simulate": _simulate,
    "track": _track,
    "export-c": _export_c,
    "bench": _bench,
    "fleet": _fleet,
    "robustness": _robustness,
}


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    debug = args.debug or getattr(args, "sub_debug", False)
    prog = (
        f"piezohyst {args.command}"
        if args.command in ("identify", "simulate", "track", "export-c", "bench", "fleet", "robustness")
        else "piezohyst"
    )
    try:
        return _COMMANDS[args.command](args) or 0
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


def run(argv: Sequence[str] | None = None) -> NoReturn:
    """The process entry point (the ``piezohyst`` script, ``python -m piezohyst``): :func:`main`,
    then the exit with its code, skipping the interpreter's native teardown.

    Why: pyarrow's idle I/O threads can race C++ static destructors at interpreter exit and abort
    the finished process (SIGABRT, "terminate called without an active exception"; apache/arrow
    issue 34314), turning a clean exit code into -6. The command's files are closed by then;
    Python's own exit handlers still run and the standard streams are flushed.
    """
    try:
        code: int = main(argv)
    except SystemExit as e:  # argparse's usage errors and --help
        if e.code is None or isinstance(e.code, int):
            code = e.code or 0
        else:
            print(e.code, file=sys.stderr)
            code = 1
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing left to tell
            pass
    os._exit(code)


if __name__ == "__main__":
    run()
