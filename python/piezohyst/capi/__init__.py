"""The C library in the package: ``libpiezohyst`` (shared ``.so`` and static ``.a``) and its
header ``piezohyst.h``, shipped in the wheel under ``piezohyst/capi/lib`` and
``piezohyst/capi/include`` (built from ``crates/capi`` when the wheel is built), and the flags
to compile and link a C program against them:

.. code-block:: console

   $ cc -std=c99 app.c $(python -m piezohyst.capi --cflags --libs) -o app            # shared
   $ cc -std=c99 app.c $(python -m piezohyst.capi --cflags --libs --static) -o app   # static

In a source checkout (``maturin develop``) the header is ``crates/capi/include/piezohyst.h``
and the libraries ``target/release/`` (``cargo build --release -p piezohyst-capi``), found
when the package files are absent.

Examples
--------
>>> from piezohyst import capi
>>> capi.header_path().name
'piezohyst.h'
>>> capi.cflags().startswith("-I")
True
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from ..errors import ParameterError

__all__ = ["LINK_LIBS", "cflags", "header_path", "include_dir", "library_dir", "library_path", "libs", "main"]

#: Libraries the Rust static library needs from the system (``rustc --print native-static-libs``).
LINK_LIBS = "-lgcc_s -lutil -lrt -lpthread -lm -ldl -lc"

_HERE = Path(__file__).resolve().parent
#: The source tree's root when the package runs from ``python/piezohyst`` of a checkout.
_SOURCE_ROOT = _HERE.parents[2]


def _first(*candidates: Path) -> Path | None:
    return next((p for p in candidates if p.is_file()), None)


def header_path() -> Path:
    """The header ``piezohyst.h``: the package's copy, else the source tree's.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    FileNotFoundError
        Neither is there (a source checkout without the ``crates/`` folder).

    Examples
    --------
    >>> from piezohyst.capi import header_path
    >>> "phs_model_step" in header_path().read_text()
    True
    """
    found = _first(_HERE / "include" / "piezohyst.h", _SOURCE_ROOT / "crates" / "capi" / "include" / "piezohyst.h")
    if found is None:
        raise FileNotFoundError(
            "piezohyst.h is not in this installation (piezohyst/capi/include) "
            "nor in a source tree (crates/capi/include)"
        )
    return found


def include_dir() -> Path:
    """The folder holding ``piezohyst.h`` (what ``-I`` names).

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> from piezohyst.capi import include_dir
    >>> (include_dir() / "piezohyst.h").is_file()
    True
    """
    return header_path().parent


def library_path(static: bool = False) -> Path:
    """``libpiezohyst.so`` (or ``libpiezohyst.a`` with ``static``): the package's copy, else the
    source tree's ``target/release`` build.

    Parameters
    ----------
    static : bool
        The static library instead of the shared one.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    FileNotFoundError
        Not installed and not built (``cargo build --release -p piezohyst-capi`` builds it).

    Examples
    --------
    >>> from piezohyst.capi import library_path
    >>> try:
    ...     name = library_path(static=True).name
    ... except FileNotFoundError:  # a source tree where the C library is not built yet
    ...     name = "libpiezohyst.a"
    >>> name
    'libpiezohyst.a'
    """
    name = "libpiezohyst.a" if static else "libpiezohyst.so"
    found = _first(_HERE / "lib" / name, _SOURCE_ROOT / "target" / "release" / name)
    if found is None:
        raise FileNotFoundError(
            f"{name} is not in this installation (piezohyst/capi/lib) nor built in a source tree "
            "(cargo build --release -p piezohyst-capi)"
        )
    return found


def library_dir(static: bool = False) -> Path:
    """The folder holding the library (what ``-L`` names).

    Parameters
    ----------
    static : bool
        The folder of the static library instead of the shared one.

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> from piezohyst.capi import library_dir
    >>> try:
    ...     found = (library_dir() / "libpiezohyst.so").is_file()
    ... except FileNotFoundError:
    ...     found = True
    >>> found
    True
    """
    return library_path(static).parent


def cflags() -> str:
    """The compiler flags: ``-I`` the header's folder.

    Returns
    -------
    str

    Examples
    --------
    >>> from piezohyst.capi import cflags, include_dir
    >>> cflags() == "-I" + str(include_dir())
    True
    """
    return "-I" + shlex.quote(str(include_dir()))


def libs(static: bool = False) -> str:
    """The linker flags: the shared library with an rpath to its folder (the program finds it at
    run time), or the static library and the system libraries it needs.

    Parameters
    ----------
    static : bool
        Link ``libpiezohyst.a`` instead of ``libpiezohyst.so``.

    Returns
    -------
    str

    Examples
    --------
    >>> from piezohyst.capi import libs
    >>> try:
    ...     flags = libs()
    ... except FileNotFoundError:  # not built in this source tree
    ...     flags = "-L... -lpiezohyst -lm"
    >>> "-lpiezohyst" in flags
    True
    """
    if static:
        return f"{shlex.quote(str(library_path(static=True)))} {LINK_LIBS}"
    d = shlex.quote(str(library_dir()))
    return f"-L{d} -Wl,-rpath,{d} -lpiezohyst -lm"


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m piezohyst.capi``: print the flags (pkg-config style) or the paths asked for.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments (default: the command line's).

    Returns
    -------
    int
        The exit status: 0, or 2 when the files are missing (one line on stderr).

    Examples
    --------
    >>> from piezohyst.capi import main
    >>> main(["--header"])  # doctest: +ELLIPSIS
    /.../piezohyst.h
    0
    """
    p = argparse.ArgumentParser(
        prog="python -m piezohyst.capi",
        description="Flags and paths of the C library (libpiezohyst) and its header shipped with piezohyst.",
        epilog="example: cc -std=c99 app.c $(python -m piezohyst.capi --cflags --libs) -o app",
        allow_abbrev=False,
    )
    p.add_argument("--cflags", action="store_true", help="compiler flags (-I the header's folder)")
    p.add_argument("--libs", action="store_true", help="linker flags (the shared library, with an rpath)")
    p.add_argument("--static", action="store_true", help="with --libs: link the static library instead")
    p.add_argument("--include-dir", action="store_true", help="the header's folder")
    p.add_argument("--lib-dir", action="store_true", help="the libraries' folder")
    p.add_argument("--header", action="store_true", help="the header file")
    args = p.parse_args(argv)
    try:
        out: list[str] = []
        if args.cflags:
            out.append(cflags())
        if args.libs:
            out.append(libs(static=args.static))
        if args.include_dir:
            out.append(str(include_dir()))
        if args.lib_dir:
            out.append(str(library_dir(static=args.static)))
        if args.header:
            out.append(str(header_path()))
        if not out:
            raise ParameterError("give --cflags, --libs, --include-dir, --lib-dir or --header")
    except (FileNotFoundError, ParameterError) as e:
        print(f"python -m piezohyst.capi: error: {e}", file=sys.stderr)
        return 2
    print(" ".join(out))
    return 0
