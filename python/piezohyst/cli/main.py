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
import contextlib
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import NoReturn

from .._io import printable
from ..errors import PiezohystError
from ..progress import silenced
from .bench import _bench, _bench_parser
from .common import _Parser
from .demo import _demo, _demo_parser
from .export_c import _export_c, _export_c_parser
from .fleet import _fleet, _fleet_parser
from .identify import _identify, _identify_parser
from .robustness import _robustness, _robustness_parser
from .simulate import _simulate, _simulate_parser
from .stage import _stage_info, _stage_parser
from .stops import Interrupted, describe, exit_code, handled, received
from .track import _track, _track_parser

__all__ = ["main", "run", "tune_malloc", "version_text"]


def version_text() -> str:
    """``piezohyst --version``: the installed package's version (its metadata) and the compiled
    core's (the Rust crates' version built into ``piezohyst._core``).

    Returns
    -------
    str
        Two lines: ``piezohyst X.Y.Z`` and ``core (piezohyst._core, Rust) X.Y.Z``.

    Examples
    --------
    >>> from piezohyst.cli.main import version_text
    >>> version_text().splitlines()[1].startswith("core (piezohyst._core, Rust) ")
    True
    """
    from importlib.metadata import PackageNotFoundError, version

    from .. import _core

    try:
        package = version("piezohyst")
    except PackageNotFoundError:  # run from a source tree that was never installed
        package = f"{_core.__version__} (source tree, not installed)"
    return f"piezohyst {package}\ncore (piezohyst._core, Rust) {_core.__version__}"


class _Version(argparse.Action):
    """``--version``: prints :func:`version_text` and exits 0 (computed only when asked)."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS, **kwargs: object) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, help=str(kwargs.get("help", "")))

    def __call__(self, parser: argparse.ArgumentParser, *args: object, **kwargs: object) -> None:
        print(version_text())  # on stdout, as argparse's own version action
        parser.exit(0)


def _add_quiet(p: argparse.ArgumentParser) -> None:
    """``--quiet`` on every command (each leaf parser: ``piezohyst demo --quiet``)."""
    subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
    if subs:
        for child in subs[0].choices.values():
            _add_quiet(child)
        return
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress on stderr (bars, step lines); results, warnings and errors are still printed",
    )


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="piezohyst", description="Piezo hysteresis modelling, identification and compensation.")
    p.add_argument("--version", action=_Version, help="print the package's and the compiled core's versions and exit")
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
    _add_quiet(p)  # last: every command registered above gets it
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
        with handled(), silenced() if args.quiet else contextlib.nullcontext():
            return _COMMANDS[args.command](args) or 0
    except KeyboardInterrupt as e:
        if debug:
            raise
        # a stop signal (Interrupted) or a KeyboardInterrupt a command raised to say what it kept
        detail = "" if isinstance(e, Interrupted) or not str(e) else f": {' '.join(str(e).split())}"
        _say(f"{prog}: interrupted by {describe(received() or signal.SIGINT)}{detail}")
        return exit_code()
    except MemoryError as e:
        if debug:
            raise
        _say(f"{prog}: error: out of memory ({' '.join(str(e).split()) or 'MemoryError'})")
        return 2
    except (PiezohystError, ValueError, TypeError, OSError, ImportError) as e:
        if debug:
            raise
        if isinstance(e, OSError) and received() is not None:
            return exit_code()  # a hang-up closed the terminal: the stop, not the write, is the news
        msg = printable(" ".join(str(e).split()))  # one line, no terminal escapes, whatever the message
        _say(f"{prog}: error: {msg}")
        return 2


def _say(line: str) -> None:
    """One line on stderr; nothing when stderr is gone (a hung-up terminal, a closed pipe)."""
    try:
        print(line, file=sys.stderr)
    except (OSError, ValueError):
        pass


#: glibc's ``mallopt`` parameters (malloc.h): ``M_TRIM_THRESHOLD``, ``M_MMAP_THRESHOLD``.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


def tune_malloc() -> bool:
    """Keep freed memory of this process's main heap for reuse (glibc only); True when set.

    Why: NumPy's temporaries of a fit (hundreds of kB each, allocated and freed on every
    iteration) come from glibc's main arena when the work runs on the main thread, as the
    ``piezohyst`` commands do. With glibc's defaults those blocks are mmapped or trimmed back to
    the system when freed, and the next allocation takes its pages again as fresh zeroed pages:
    ~190,000 minor page faults and ~0.3 s of CPU per identification of a 10,000-sample record
    (0.80 s instead of 0.57 s; the same work in a thread, whose arena is not trimmed so eagerly,
    does not pay it). Raising the mmap threshold to glibc's maximum (32 MiB) and the trim
    threshold to 128 MiB keeps those pages in the heap: the same fit takes ~230 page faults.
    The process keeps at most 128 MiB of freed memory beyond what it uses (a command's
    lifetime is one run). Called once by :func:`run`, the process entry; the library itself
    never changes the allocator of a program that imports it.
    """
    if not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        libc = ctypes.CDLL("libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc (musl has no mallopt)
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, 32 << 20)) and bool(mallopt(_M_TRIM_THRESHOLD, 128 << 20))


def run(argv: Sequence[str] | None = None) -> NoReturn:
    """The process entry point (the ``piezohyst`` script, ``python -m piezohyst``): :func:`main`,
    then the exit with its code, skipping the interpreter's native teardown.

    Why: pyarrow's idle I/O threads can race C++ static destructors at interpreter exit and abort
    the finished process (SIGABRT, "terminate called without an active exception"; apache/arrow
    issue 34314), turning a clean exit code into -6. The command's files are closed by then;
    Python's own exit handlers still run and the standard streams are flushed.

    First, :func:`tune_malloc` (the main thread's NumPy work keeps its freed pages).
    """
    tune_malloc()
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
