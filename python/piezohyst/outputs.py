"""The output policy: every file piezohyst writes goes through this module.

Every command's output (``identify --out/--plot``, ``simulate --out``, ``track --plot``,
``export-c --out``, the ``demo`` report folder, ``bench``'s summary and ``--readme``) and every
writer of the API (``HysteresisModel.save``, ``BoucWenBenchmark.save``, ``save_controller``,
``export_c``, ``run_demo``) follows the same rules:

1. **Regular files only.** A destination that is a directory, a FIFO, a character or block
   device or a socket is refused (:class:`~piezohyst.errors.ParameterError` naming the argument
   and the path), with or without ``--force``: nothing is written into it and its directory
   entry is never replaced (``--out /dev/null --force`` does not turn the device node into a
   file, as root or not). ``-`` means standard output where a command offers it
   (``simulate --out -``); elsewhere it is refused rather than taken as a file name.
2. **Never an input.** A destination that is the same file as one of the command's inputs (the
   same device and inode: the path itself, a symbolic link to it or a hard link of it) is
   refused, with or without ``--force``.
3. **Existing files are kept** unless ``--force`` / ``overwrite=True``
   (:class:`~piezohyst.errors.OutputExistsError`, a ``FileExistsError``).
4. **Symbolic links** (to a file or dangling) are refused without ``--force``; with it the
   *link itself* is replaced by a regular file and the file it pointed to is left alone (a
   planted link cannot make piezohyst write somewhere else). A link to something that is not a
   regular file (a device, a FIFO, a directory) is refused even with ``--force``. An output
   *directory* given as a link is refused (give the directory it points to).
5. **The destination is checked before any work**: :func:`check_output` /
   :func:`check_output_dir` run when a command starts (a fit does not run for a minute and then
   fail); the destination's directory must exist (or be creatable, where the writer creates
   it) and a file must be creatable in it (a probe file is made and removed, which also
   catches read-only mounts and root-squashed shares). The error names the argument and the
   directory.
6. **Atomic files.** :func:`write_atomic` writes a temporary file beside the destination,
   flushes it to disk and renames it over the destination: a reader sees the old file or the
   new one; an interrupted write (a signal, a full disk, an exception in a plotting call)
   leaves the old file and no temporary behind.
7. **Atomic sets.** A multi-file output (the C export, the demo report) is written into a
   temporary directory (:func:`output_set`) and put in place as a set only when every file is
   complete: a new folder is one rename; a folder holding only the command's own files is
   swapped whole (one ``renameat2(RENAME_EXCHANGE)`` on Linux); a folder holding other files
   too gets the new files by renames with rollback, while SIGINT/SIGTERM/SIGHUP are deferred
   (:func:`signals_deferred`). An interrupted or failed run leaves the old set untouched; a
   temporary folder left by a killed run (its process gone) is removed by the next run.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import shutil
import signal
import stat
import sys
import tempfile
import threading
from collections.abc import Callable, Collection, Iterator, Mapping
from pathlib import Path
from types import FrameType

from .errors import OutputExistsError, ParameterError

__all__ = [
    "Inputs",
    "PathLike",
    "check_output",
    "check_output_dir",
    "output_set",
    "signals_deferred",
    "write_atomic",
]

#: What a file path argument may be.
PathLike = str | os.PathLike[str]

#: A command's inputs, by the name its messages give them (``{"DATA": path, "--validate": None}``);
#: ``None`` entries are skipped.
Inputs = Mapping[str, PathLike | None]

#: The suffix of a set's temporary folder (``.<name>.<pid>.<random>.piezohyst-tmp``).
_STAGE_SUFFIX = ".piezohyst-tmp"

#: The signals a commit defers (the ones that stop a command).
_STOP_SIGNALS = tuple(getattr(signal, s) for s in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, s))


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _kind(mode: int) -> str | None:
    """What a file of ``mode`` is, when it is not a regular file (``None`` for a regular file)."""
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    return "not a regular file"


def _parent(p: Path) -> Path:
    return p.parent if str(p.parent) else Path(".")


def _lstat(p: Path, name: str) -> os.stat_result | None:
    """``os.lstat(p)``, ``None`` when nothing is there; a parent that is not a directory is a
    :class:`ParameterError` naming ``name``."""
    try:
        return os.lstat(p)
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise ParameterError(f"{name} = '{p}': {_not_a_directory(_parent(p))}") from None
    except PermissionError as e:
        raise ParameterError(f"{name} = '{p}': directory '{_parent(p)}' cannot be searched: {e.strerror}") from None


def _not_a_directory(d: Path) -> str:
    """Why ``d`` is not a directory: the first component on its way that is a file."""
    for a in reversed([d, *d.parents]):
        try:
            st = os.stat(a)
        except OSError:
            break
        if not stat.S_ISDIR(st.st_mode):
            return f"'{a}' is {_kind(st.st_mode) or 'a file'}, not a directory"
    return f"directory '{d}' does not exist"


def _same_input(p: Path, st: os.stat_result, name: str, inputs: Inputs | None, via: str) -> None:
    """Refuse ``p`` (whose followed stat is ``st``) when it is one of ``inputs``."""
    for iname, ipath in (inputs or {}).items():
        if ipath is None:
            continue
        try:
            ist = os.stat(ipath)
        except OSError:
            continue
        if (ist.st_dev, ist.st_ino) == (st.st_dev, st.st_ino):
            how = via
            if not how and os.path.abspath(p) != os.path.abspath(ipath):
                how = " (a hard link of it)"
            raise ParameterError(
                f"{name} = '{p}' is the input {iname} '{ipath}'{how}: piezohyst never writes over its input, "
                f"with or without --force; give another file name"
            )


def _hint(name: str, force: str | None) -> str:
    """How to ask for a replacement: ``--force`` on the command line, else the API's keyword."""
    if force is not None:
        return force
    return "--force" if name.startswith("--") else "overwrite=True"


def _check_entry(p: Path, name: str, overwrite: bool, inputs: Inputs | None, force: str | None = None) -> None:
    """Rules 1-4 for one destination file (what is at ``p`` now); ``force`` names the way to
    ask for a replacement (default: ``--force`` for an option ``name``, else ``overwrite=True``)."""
    st = _lstat(p, name)
    if st is None:
        return
    if stat.S_ISLNK(st.st_mode):
        try:
            target = os.readlink(p)
        except OSError:
            target = "?"
        try:
            tst: os.stat_result | None = os.stat(p)
        except OSError:  # dangling, a loop, or a target that cannot be reached
            tst = None
        if tst is not None:
            _same_input(p, tst, name, inputs, " (through a symbolic link)")
            kind = _kind(tst.st_mode)
            if kind is not None:
                raise ParameterError(
                    f"{name} = '{p}' is a symbolic link to '{target}', {kind}: piezohyst writes regular files "
                    f"only (not through a link, not with --force); give a file name"
                )
        if not overwrite:
            dangling = " (dangling)" if tst is None else ""
            raise OutputExistsError(
                f"{name} = '{p}' is a symbolic link to '{target}'{dangling}; pass {_hint(name, force)} to "
                f"replace the link itself with a regular file (what it points to is left alone)"
            )
        return
    kind = _kind(st.st_mode)
    if kind is not None:
        what = "give a file name" if stat.S_ISDIR(st.st_mode) else "piezohyst writes regular files only"
        raise ParameterError(f"{name} = '{p}' is {kind}, not a regular file; {what} (--force does not change this)")
    _same_input(p, st, name, inputs, "")
    if not overwrite:
        raise OutputExistsError(f"{name} = '{p}' exists; pass {_hint(name, force)} to replace it")


def _probe(d: Path, name: str, what: Path) -> None:
    """A file can be created in directory ``d`` (made and removed), else a
    :class:`ParameterError` naming ``name`` (the argument ``what``) and ``d``."""
    try:
        fd, tmp = tempfile.mkstemp(dir=d, prefix=".piezohyst-probe-", suffix=".tmp")
    except OSError as e:
        reason = e.strerror or type(e).__name__
        raise ParameterError(
            f"{name} = '{what}': cannot write in directory '{d}' ({reason}); nothing was done"
        ) from None
    os.close(fd)
    os.unlink(tmp)


def _existing_ancestor(d: Path, name: str, what: Path) -> Path:
    """The nearest existing ancestor of ``d`` (``d`` itself if it exists): a directory, else
    a :class:`ParameterError`."""
    for a in [d, *d.parents]:
        try:
            st = os.stat(a)
        except FileNotFoundError:
            continue
        except OSError as e:
            raise ParameterError(f"{name} = '{what}': directory '{a}' cannot be reached ({e.strerror})") from None
        if not stat.S_ISDIR(st.st_mode):
            raise ParameterError(f"{name} = '{what}': '{a}' is {_kind(st.st_mode) or 'a file'}, not a directory")
        return a
    return Path(".")


def _check_directory(d: Path, name: str, what: Path, parents: bool) -> None:
    """Rule 5: directory ``d`` exists (or, with ``parents``, can be made) and is writable."""
    try:
        st = os.stat(d)
    except FileNotFoundError:
        if not parents:
            raise ParameterError(f"{name} = '{what}': directory '{d}' does not exist") from None
        _probe(_existing_ancestor(d, name, what), name, what)
        return
    except NotADirectoryError:
        raise ParameterError(f"{name} = '{what}': {_not_a_directory(d)}") from None
    except PermissionError as e:
        raise ParameterError(f"{name} = '{what}': directory '{d}' cannot be searched: {e.strerror}") from None
    if not stat.S_ISDIR(st.st_mode):
        raise ParameterError(f"{name} = '{what}': {_not_a_directory(d)}")
    _probe(d, name, what)


def check_output(path: PathLike, *, name: str = "path", overwrite: bool = False, inputs: Inputs | None = None) -> Path:
    """Check that ``path`` may be written as one output file (rules 1-5 of the module), before
    any work starts; return it as a :class:`~pathlib.Path`.

    ``name`` is the argument the messages name (``"--out"``); ``inputs`` the files the run
    reads, by name. Raises :class:`~piezohyst.errors.ParameterError` (not a regular file, an
    input, a directory that does not exist or is not writable, ``-`` where standard output is
    not offered) or :class:`~piezohyst.errors.OutputExistsError` (an existing file or a link
    without ``overwrite``).

    Parameters
    ----------
    path : str or os.PathLike
        The output file.
    name : str, optional
        The argument the messages name (``"--out"``).
    overwrite : bool, optional
        Whether an existing file may be replaced.
    inputs : mapping of str to path, optional
        The files the run reads, by the name the messages give them.

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import os, tempfile, pathlib
    >>> from piezohyst.outputs import check_output
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> os.mkfifo(d / "fifo")
    >>> try:
    ...     check_output(d / "fifo", name="--out", overwrite=True)
    ... except ValueError as e:
    ...     print(str(e).split(",")[0].replace(str(d), "D"))
    --out = 'D/fifo' is a FIFO (named pipe)
    """
    if str(path) == "-":
        raise ParameterError(
            f"{name} = '-': standard output is not offered for this output; give a file name ('./-' for a file named -)"
        )
    p = Path(path)
    if not p.name:
        raise ParameterError(f"{name} = '{path}' names a directory; give a file name")
    _check_entry(p, name, overwrite, inputs)
    _check_directory(_parent(p), name, p, parents=False)
    return p


def write_atomic(
    path: PathLike,
    data: str | bytes | None = None,
    *,
    writer: Callable[[str], None] | None = None,
    overwrite: bool = True,
    name: str = "path",
    inputs: Inputs | None = None,
) -> Path:
    """Write ``data`` (text is UTF-8 with ``\\n`` line ends) or let ``writer(temp_path)`` write
    the file, then move it to ``path`` atomically (rule 6), under the rules of
    :func:`check_output`: only a regular file (or a link, replaced itself, with
    ``overwrite``), never one of ``inputs``.

    With ``overwrite=False`` an existing ``path`` is kept and :class:`OutputExistsError`
    (a :class:`FileExistsError`) names the argument ``name``.

    Parameters
    ----------
    path : str or os.PathLike
        The output file.
    data : str or bytes, optional
        The content (exactly one of ``data`` and ``writer``).
    writer : callable, optional
        ``writer(temp_path)`` writes the content into the temporary file.
    overwrite : bool, optional
        Whether an existing file may be replaced.
    name : str, optional
        The argument the messages name (``"--out"``).
    inputs : mapping of str to path, optional
        The files the run reads, by the name the messages give them.

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst.outputs import write_atomic
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "model.json"
    >>> write_atomic(p, "{}\\n").read_text()
    '{}\\n'
    >>> try:
    ...     write_atomic(p, "new", overwrite=False, name="--out")
    ... except FileExistsError:
    ...     print(p.read_text() == "{}\\n")                   # the old file is kept
    True
    """
    if (data is None) == (writer is None):
        raise TypeError("write_atomic needs exactly one of data and writer")
    if str(path) == "-":
        raise ParameterError(f"{name} = '-': standard output is not offered for this output; give a file name")
    target = Path(path)
    _check_entry(target, name, overwrite, inputs)
    parent = _parent(target)
    try:
        fd, tmp = tempfile.mkstemp(dir=parent, prefix=f".{target.name}.", suffix=".tmp")
    except FileNotFoundError:
        raise ParameterError(f"{name} = '{target}': directory '{parent}' does not exist") from None
    except NotADirectoryError:
        raise ParameterError(f"{name} = '{target}': {_not_a_directory(parent)}") from None
    except PermissionError as e:
        raise ParameterError(f"{name} = '{target}': cannot write in directory '{parent}' ({e.strerror})") from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        if writer is None:
            assert data is not None  # exactly one of data and writer, checked above
            raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
            with os.fdopen(fd, "wb") as f:
                f.write(raw)
                f.flush()
                os.fsync(f.fileno())
        else:
            os.close(fd)
            writer(tmp)
        _check_entry(target, name, overwrite, inputs)  # what may have appeared meanwhile
        os.replace(tmp, target)
    except BaseException:
        if os.path.lexists(tmp):
            os.unlink(tmp)
        raise
    return target


# -- multi-file outputs ------------------------------------------------------------------------


def _set_names(names: Collection[str], name: str) -> list[str]:
    for n in names:
        if not n or n in (".", "..") or "/" in n or os.sep in n:
            raise ParameterError(f"{name}: {n!r} is not a plain file name")
    return list(names)


def check_output_dir(
    directory: PathLike,
    *,
    name: str = "out_dir",
    overwrite: bool = False,
    names: Collection[str] = (),
    inputs: Inputs | None = None,
    parents: bool = False,
    force_hint: str | None = None,
) -> Path:
    """Check that ``directory`` may receive the output set ``names`` (rules 1-5 for the folder
    and for each file in it), before any work starts; return it as a Path.

    The folder is a directory or does not exist yet (its parent must exist, or with
    ``parents`` its nearest existing ancestor, and be writable); not a link. Each of ``names``
    in it is checked as :func:`check_output` checks a file: an existing one needs
    ``overwrite``, a non-regular one or an input is refused. ``force_hint`` is how a message
    says to ask for a replacement (default: ``--force`` for an option ``name``, else
    ``overwrite=True``).

    Parameters
    ----------
    directory : str or os.PathLike
        The output folder (existing or not).
    name : str, optional
        The argument the messages name (``"--out-dir"``).
    overwrite : bool, optional
        Whether existing files of the set may be replaced.
    names : collection of str, optional
        The plain file names of the set.
    inputs : mapping of str to path, optional
        The files the run reads, by the name the messages give them.
    parents : bool, optional
        Whether missing ancestors of ``directory`` may be created.
    force_hint : str, optional
        How a message says to ask for a replacement.

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst.outputs import check_output_dir
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "a.txt").write_text("old")
    >>> check_output_dir(d, names=["b.txt"]) == d            # a new file: fine
    True
    >>> try:
    ...     check_output_dir(d, name="--out-dir", names=["a.txt"])
    ... except FileExistsError:
    ...     print("a.txt exists")
    a.txt exists
    """
    out = Path(directory)
    if str(directory) == "-" or not str(directory):
        raise ParameterError(f"{name} = '{directory}' is not a directory name")
    st = _lstat(out, name)
    if st is None:
        _check_directory(_parent(out), name, out, parents)
        return out
    if stat.S_ISLNK(st.st_mode):
        try:
            target = os.readlink(out)
        except OSError:
            target = "?"
        raise ParameterError(
            f"{name} = '{out}' is a symbolic link to '{target}'; give the directory itself (piezohyst does not "
            f"write through links, with or without --force)"
        )
    if not stat.S_ISDIR(st.st_mode):
        raise ParameterError(f"{name} = '{out}' exists and is not a directory (it is {_kind(st.st_mode) or 'a file'})")
    for n in _set_names(names, name):
        _check_entry(out / n, name, overwrite, inputs, force_hint)
    _probe(out, name, out)
    return out


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return True
    return True


def _stage_pattern(out: Path) -> re.Pattern[str]:
    return re.compile(rf"\.{re.escape(out.name)}\.(\d+)\.[^/]*{re.escape(_STAGE_SUFFIX)}")


def _clean_stale(out: Path) -> None:
    """Remove the temporary folders of ``out``'s sets left by runs whose process is gone."""
    pattern = _stage_pattern(out)
    for where in (_parent(out), out):
        try:
            entries = os.listdir(where)
        except OSError:
            continue
        for e in entries:
            m = pattern.fullmatch(e)
            if m is None or int(m.group(1)) == os.getpid() or _alive(int(m.group(1))):
                continue
            shutil.rmtree(where / e, ignore_errors=True)


def _fsync_dir(d: Path) -> None:
    try:
        fd = os.open(d, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _fsync_tree(d: Path) -> None:
    for root, _, files in os.walk(d):
        for f in files:
            path = os.path.join(root, f)
            if os.path.islink(path):
                continue
            fd = os.open(path, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        _fsync_dir(Path(root))


def _exchange(a: Path, b: Path) -> bool:
    """Swap directories ``a`` and ``b`` in one step (Linux ``renameat2(RENAME_EXCHANGE)``);
    ``False`` where that is not available (the caller falls back)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    renameat2.restype = ctypes.c_int
    at_fdcwd, rename_exchange = -100, 2
    return int(renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange)) == 0


def _commit_files(staging: Path, out: Path, staged: list[str], remove: list[str]) -> None:
    """Move ``staged`` from ``staging`` into ``out`` and remove ``remove`` from it; on any
    error, put everything back as it was (the old files wait in ``staging/.previous``)."""
    backup = staging / ".previous"
    backup.mkdir()
    moved_away: list[str] = []
    moved_in: list[str] = []
    try:
        for n in staged + remove:
            if os.path.lexists(out / n):
                os.rename(out / n, backup / n)
                moved_away.append(n)
        for n in staged:
            os.rename(staging / n, out / n)
            moved_in.append(n)
    except BaseException:
        for n in reversed(moved_in):
            os.rename(out / n, staging / n)
        for n in reversed(moved_away):
            os.rename(backup / n, out / n)
        raise


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP for the duration of the block, then deliver them: a
    commit of renames runs whole. Python-level handlers are swapped for a recorder (only in
    the main thread, the only one that runs Python signal handlers); a signal that arrived is
    raised again after the block, so the handler (or the default action) runs then.

    Examples
    --------
    >>> import signal
    >>> from piezohyst.outputs import signals_deferred
    >>> got = []
    >>> old = signal.signal(signal.SIGTERM, lambda signum, frame: got.append(signum))
    >>> with signals_deferred():
    ...     signal.raise_signal(signal.SIGTERM)
    ...     held = list(got)
    >>> held, got == [signal.SIGTERM]                          # held in the block, delivered after
    ([], True)
    >>> _ = signal.signal(signal.SIGTERM, old)
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []

    def hold(signum: int, frame: FrameType | None) -> None:
        pending.append(signum)

    saved: dict[int, Callable[[int, FrameType | None], object] | int | None] = {}
    try:
        for s in _STOP_SIGNALS:
            h = signal.getsignal(s)
            if h is signal.SIG_IGN or h is None:
                continue
            saved[s] = h
            signal.signal(s, hold)
        yield
    finally:
        for s, h in saved.items():
            signal.signal(s, h)
        for s in dict.fromkeys(pending):
            signal.raise_signal(s)


@contextlib.contextmanager
def output_set(
    directory: PathLike,
    *,
    name: str = "out_dir",
    overwrite: bool = False,
    names: Collection[str] = (),
    previous: Collection[str] = (),
    inputs: Inputs | None = None,
    parents: bool = False,
    force_hint: str | None = None,
) -> Iterator[Path]:
    """Write a set of files into ``directory`` as one (rule 7): the block writes its files
    into the yielded temporary folder (plain writes; nothing else may be there); when it ends
    without an exception the set is put in place. An exception (a signal, a full disk) leaves
    ``directory`` as it was and removes the temporary folder.

    ``names`` are the files the set is expected to hold (checked by :func:`check_output_dir`
    before the block runs); ``previous`` the names an earlier run may have left that this set
    replaces (removed with ``overwrite`` when the new set does not hold them: a folder never
    mixes two runs). With ``parents`` missing ancestors of ``directory`` are created;
    ``force_hint`` as for :func:`check_output_dir`.

    Parameters
    ----------
    directory : str or os.PathLike
        The output folder (existing or not).
    name : str, optional
        The argument the messages name (``"--out-dir"``).
    overwrite : bool, optional
        Whether an earlier set may be replaced.
    names : collection of str, optional
        The plain file names the set is expected to hold.
    previous : collection of str, optional
        Names an earlier run may have left that this set replaces.
    inputs : mapping of str to path, optional
        The files the run reads, by the name the messages give them.
    parents : bool, optional
        Whether missing ancestors of ``directory`` are created.
    force_hint : str, optional
        How a message says to ask for a replacement.

    Yields
    ------
    pathlib.Path
        The temporary folder the block writes the files into.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from piezohyst.outputs import output_set
    >>> d = pathlib.Path(tempfile.mkdtemp()) / "set"
    >>> with output_set(d, names=["a.txt", "b.txt"]) as tmp:
    ...     _ = (tmp / "a.txt").write_text("a")
    ...     _ = (tmp / "b.txt").write_text("b")
    >>> sorted(p.name for p in d.iterdir())
    ['a.txt', 'b.txt']
    """
    out = check_output_dir(
        directory,
        name=name,
        overwrite=overwrite,
        names=names,
        inputs=inputs,
        parents=parents,
        force_hint=force_hint,
    )
    previous = _set_names(previous, name)
    out = Path(os.path.abspath(out))  # "." has a name and a parent
    parent = out.parent
    if parents:
        parent.mkdir(parents=True, exist_ok=True)
    _clean_stale(out)
    prefix = f".{out.name}.{os.getpid()}."
    exists = os.path.isdir(out)
    beside = not exists
    if exists:
        try:
            _probe(parent, name, out)
            beside = os.stat(parent).st_dev == os.stat(out).st_dev
        except ParameterError:
            beside = False  # the parent is not writable: stage inside the folder
    staging = Path(tempfile.mkdtemp(dir=parent if beside else out, prefix=prefix, suffix=_STAGE_SUFFIX))
    pattern = _stage_pattern(out)
    try:
        # the folder as a plain mkdir makes it (mkdtemp's is private), or as the one it replaces
        own = os.stat(out) if exists else None
        os.chmod(staging, stat.S_IMODE(own.st_mode) if own is not None else 0o777 & ~_umask())
        yield staging
        staged = sorted(os.listdir(staging))
        for n in staged:
            mode = os.lstat(staging / n).st_mode
            if not stat.S_ISREG(mode):
                raise ParameterError(f"{name}: the set's {n!r} is {_kind(mode)}; a set holds regular files only")
        _fsync_tree(staging)
        with signals_deferred():
            if not os.path.lexists(out):
                os.rename(staging, out)
                _fsync_dir(parent)
                return
            for n in staged:  # what may have appeared since the check
                _check_entry(out / n, name, overwrite, inputs, force_hint)
            remove = [n for n in previous if n not in staged and overwrite and os.path.lexists(out / n)]
            current = {e for e in os.listdir(out) if pattern.fullmatch(e) is None}
            swap = beside and own is not None and own.st_uid == os.geteuid()  # a swap cannot keep the owner
            if swap and current <= set(staged) | set(previous) and _exchange(staging, out):
                _fsync_dir(parent)
            else:
                _commit_files(staging, out, staged, remove)
                _fsync_dir(out)
        shutil.rmtree(staging, ignore_errors=True)  # the old set (or the emptied folder)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
