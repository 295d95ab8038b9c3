"""The output policy (:mod:`piezohyst.outputs`, issue 20): every rule with real files in a
temporary folder — FIFOs, device links, dangling links, links and hard links to an input,
directories, a path under a file, an unwritable folder — and the multi-file sets: an
interrupted or failing set leaves the old one whole, a killed run's leftovers do not block the
next."""

from __future__ import annotations

import os
import signal
import stat
import sys
from pathlib import Path

import pytest

import piezohyst as ph
from piezohyst import outputs
from piezohyst.errors import OutputExistsError, ParameterError
from piezohyst.export_c import save_controller
from piezohyst.models.boucwen_benchmark import BoucWenBenchmark
from piezohyst.outputs import check_output, check_output_dir, output_set, signals_deferred, write_atomic

ROOT = os.geteuid() == 0


@pytest.fixture
def files(tmp_path):
    """A folder with an input, a FIFO, a link to /dev/null, a dangling link, links to the input."""
    d = tmp_path
    (d / "data.csv").write_text("1,2\n3,4\n")
    os.mkfifo(d / "fifo")
    os.symlink("/dev/null", d / "null")
    os.symlink("nowhere", d / "dangling")
    os.symlink("data.csv", d / "to_input")
    os.link(d / "data.csv", d / "hard.csv")
    (d / "other.json").write_text("precious")
    os.symlink("other.json", d / "to_other")
    (d / "sub").mkdir()
    (d / "file.txt").write_text("x")
    return d


def _unchanged(d: Path) -> None:
    assert (d / "data.csv").read_text() == "1,2\n3,4\n"
    assert stat.S_ISFIFO(os.lstat(d / "fifo").st_mode)
    assert os.readlink(d / "null") == "/dev/null" and stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert os.readlink(d / "dangling") == "nowhere"
    assert os.readlink(d / "to_input") == "data.csv"
    assert (d / "other.json").read_text() == "precious"
    assert not [p for p in d.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("force", [False, True])
@pytest.mark.parametrize(
    "dest,message",
    [
        ("fifo", r"--out = '.*fifo' is a FIFO \(named pipe\), not a regular file"),
        ("null", r"--out = '.*null' is a symbolic link to '/dev/null', a character device"),
        ("sub", r"--out = '.*sub' is a directory, not a regular file; give a file name"),
        ("data.csv", r"--out = '.*data.csv' is the input DATA '.*data.csv': piezohyst never writes over"),
        ("to_input", r"is the input DATA '.*data.csv' \(through a symbolic link\)"),
        ("hard.csv", r"is the input DATA '.*data.csv' \(a hard link of it\)"),
        ("file.txt/out.json", r"--out = '.*file.txt/out.json': '.*file.txt' is a file, not a directory"),
        ("missing/out.json", r"--out = '.*missing/out.json': directory '.*missing' does not exist"),
    ],
)
def test_refused_destinations_with_or_without_force(files, dest, message, force):
    inputs = {"DATA": files / "data.csv"}
    with pytest.raises(ParameterError, match=message):
        check_output(files / dest, name="--out", overwrite=force, inputs=inputs)
    with pytest.raises(ParameterError, match=message):
        write_atomic(files / dest, "new", name="--out", overwrite=force, inputs=inputs)
    _unchanged(files)


@pytest.mark.parametrize("dest", ["dangling", "to_other"])
def test_a_link_is_refused_without_force_and_replaced_itself_with_it(files, dest):
    link = r"--out = '.*' is a symbolic link to .*; pass --force to replace the link"
    with pytest.raises(OutputExistsError, match=link):
        check_output(files / dest, name="--out")
    with pytest.raises(OutputExistsError, match="overwrite=True"):
        write_atomic(files / dest, "new", overwrite=False)
    _unchanged(files)
    check_output(files / dest, name="--out", overwrite=True)
    write_atomic(files / dest, "new", overwrite=True)
    assert not (files / dest).is_symlink() and (files / dest).read_text() == "new"
    assert (files / "other.json").read_text() == "precious"  # the link's target is left alone
    assert not (files / "nowhere").exists()


def test_existing_files_need_force_and_stdout_is_not_a_file_name(files):
    with pytest.raises(OutputExistsError, match=r"--out = '.*other.json' exists; pass --force to replace it"):
        check_output(files / "other.json", name="--out")
    with pytest.raises(ParameterError, match=r"--out = '-': standard output is not offered"):
        check_output("-", name="--out")
    assert check_output(files / "new.json", name="--out") == files / "new.json"
    assert not (files / "new.json").exists()  # the check writes nothing (its probe file is gone)
    assert sorted(p.name for p in files.iterdir() if p.name.startswith(".")) == []


@pytest.mark.skipif(ROOT, reason="root writes in read-only folders: the permission check cannot fail")
def test_an_unwritable_directory_is_named_before_any_work(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(ParameterError, match=r"--out = '.*ro/m.json': cannot write in directory '.*ro'"):
            check_output(ro / "m.json", name="--out")
        with pytest.raises(ParameterError, match=r"--out = '.*ro/c': cannot write in directory"):
            check_output_dir(ro / "c", name="--out")
    finally:
        ro.chmod(0o755)


def test_a_folder_refusing_files_is_named(tmp_path, monkeypatch):
    """What a read-only mount or a root-squashed share answers (as root too): the probe fails."""

    def refuse(*a, **k):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(outputs.tempfile, "mkstemp", refuse)
    with pytest.raises(ParameterError, match=r"^--out = '.*m.json': cannot write in directory '.*' \(Read-only"):
        check_output(tmp_path / "m.json", name="--out")
    with pytest.raises(ParameterError, match=r"^--out = '.*c': cannot write in directory '.*' \(Read-only"):
        check_output_dir(tmp_path / "c", name="--out")


def test_the_api_writers_follow_the_policy(files):
    """HysteresisModel.save, BoucWenBenchmark.save and save_controller go through write_atomic."""
    writers = {
        "model": lambda p, o: ph.PI([0.1], [0.2]).save(p, overwrite=o),
        "benchmark": lambda p, o: BoucWenBenchmark().save(p, overwrite=o),
        "controller": lambda p, o: save_controller(ph.PID(kp=1e5, ki=1e8), ph.virtual_stage(), p, overwrite=o),
    }
    for write in writers.values():
        for dest in ("fifo", "null", "sub"):
            with pytest.raises(ParameterError, match="regular file"):
                write(files / dest, True)
        with pytest.raises(OutputExistsError, match="symbolic link"):
            write(files / "to_other", False)
    _unchanged(files)


def test_a_write_that_fails_keeps_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "m.json"
    path.write_text("old")

    def fail(tmp: str) -> None:
        Path(tmp).write_text("half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space"):
        write_atomic(path, writer=fail)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["m.json"]


def test_a_folder_vanishing_during_the_work_is_named_not_a_temporary(tmp_path):
    d = tmp_path / "gone"
    d.mkdir()
    check_output(d / "m.json", name="--out")
    d.rmdir()  # (a fit ran meanwhile)
    with pytest.raises(ParameterError, match=r"^--out = '.*gone/m.json': directory '.*gone' does not exist$"):
        write_atomic(d / "m.json", "x", name="--out")


# -- sets ------------------------------------------------------------------------------------


def _write(d: Path, content: dict[str, str]) -> None:
    for n, text in content.items():
        (d / n).write_text(text)


def _folder(d: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in sorted(d.iterdir())}


def test_a_new_set_is_one_rename_and_the_folder_is_checked_first(tmp_path):
    out = tmp_path / "c"
    with output_set(out, names=["a.h", "a.c"]) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".c.") and not out.exists()
        _write(tmp, {"a.h": "h1", "a.c": "c1"})
    assert _folder(out) == {"a.c": "c1", "a.h": "h1"}
    assert [p.name for p in tmp_path.iterdir()] == ["c"]
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o777 & ~umask  # as mkdir makes it, not mkdtemp's 0700
    with pytest.raises(OutputExistsError, match=r"out_dir = '.*c/a.h' exists; pass overwrite=True"):
        check_output_dir(out, names=["a.h"])
    (tmp_path / "f").write_text("x")
    os.symlink("c", tmp_path / "link")
    os.mkfifo(out / "b.c")
    for bad, message in [
        (tmp_path / "f", "exists and is not a directory"),
        (tmp_path / "link", "is a symbolic link to 'c'; give the directory itself"),
        (tmp_path / "f" / "c", "'.*f' is a file, not a directory"),
    ]:
        with pytest.raises(ParameterError, match=message):
            check_output_dir(bad, overwrite=True)
    with pytest.raises(ParameterError, match="is a FIFO"):
        check_output_dir(out, names=["b.c"], overwrite=True)


def test_an_own_folder_is_replaced_whole(tmp_path, monkeypatch):
    if sys.platform.startswith("linux"):  # one renameat2(RENAME_EXCHANGE), not file by file

        def by_files(*a):
            raise AssertionError("swapped file by file")

        monkeypatch.setattr(outputs, "_commit_files", by_files)
    out = tmp_path / "c"
    out.mkdir()
    out.chmod(0o751)
    _write(out, {"a.h": "old", "a.c": "old", "ctl.c": "old controller"})
    with output_set(out, names=["a.h", "a.c"], previous=["a.h", "a.c", "ctl.c"], overwrite=True) as tmp:
        _write(tmp, {"a.h": "new", "a.c": "new"})
    assert _folder(out) == {"a.c": "new", "a.h": "new"}  # no file of the old run left
    assert [p.name for p in tmp_path.iterdir()] == ["c"]
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o751  # the folder's mode is kept


def test_a_shared_folder_gets_the_new_files_and_keeps_the_others(tmp_path):
    out = tmp_path / "c"
    out.mkdir()
    _write(out, {"a.h": "old", "ctl.c": "old controller", "Makefile": "mine"})
    with output_set(out, names=["a.h"], previous=["a.h", "ctl.c"], overwrite=True) as tmp:
        _write(tmp, {"a.h": "new"})
    assert _folder(out) == {"Makefile": "mine", "a.h": "new"}
    assert [p.name for p in tmp_path.iterdir()] == ["c"]


@pytest.mark.parametrize("shared", [False, True])
def test_an_interrupted_set_leaves_the_old_one_and_the_rerun_succeeds(tmp_path, shared):
    out = tmp_path / "c"
    out.mkdir()
    old = {"a.h": "old", "a.c": "old"} | ({"Makefile": "mine"} if shared else {})
    _write(out, old)
    for stop in (KeyboardInterrupt, OSError(28, "No space left on device")):
        with pytest.raises(type(stop) if isinstance(stop, OSError) else stop):
            with output_set(out, names=["a.h", "a.c"], overwrite=True) as tmp:
                _write(tmp, {"a.h": "new"})
                raise stop
        assert _folder(out) == old
        assert [p.name for p in tmp_path.iterdir()] == ["c"]
    with output_set(out, names=["a.h", "a.c"], overwrite=True) as tmp:
        _write(tmp, {"a.h": "new", "a.c": "new"})
    assert _folder(out) == old | {"a.h": "new", "a.c": "new"}


def test_a_failing_commit_is_rolled_back(tmp_path, monkeypatch):
    """Renames into a shared folder: the second fails, the first is undone."""
    out = tmp_path / "c"
    out.mkdir()
    _write(out, {"a.h": "old", "a.c": "old", "Makefile": "mine"})
    real = os.rename
    calls = {"in": 0}

    def rename(src, dst):
        if Path(dst).parent == out and Path(src).parent.name != ".previous":
            calls["in"] += 1
            if calls["in"] == 2:
                raise OSError(5, "Input/output error")
        return real(src, dst)

    monkeypatch.setattr(outputs.os, "rename", rename)
    with pytest.raises(OSError, match="Input/output"):
        with output_set(out, names=["a.h", "a.c"], overwrite=True) as tmp:
            _write(tmp, {"a.h": "new", "a.c": "new"})
    assert calls["in"] == 2
    assert _folder(out) == {"Makefile": "mine", "a.c": "old", "a.h": "old"}
    assert [p.name for p in tmp_path.iterdir()] == ["c"]


def test_a_killed_runs_leftovers_are_removed_and_do_not_block(tmp_path):
    out = tmp_path / "c"
    dead = 2**22 + 1  # above any pid_max: no such process
    stale = tmp_path / f".c.{dead}.x1y2z3.piezohyst-tmp"
    stale.mkdir()
    (stale / "a.h").write_text("half of a killed run")
    alive = tmp_path / f".c.{os.getppid()}.x1y2z3.piezohyst-tmp"  # a run still going: left alone
    alive.mkdir()
    with output_set(out, names=["a.h"]) as tmp:
        _write(tmp, {"a.h": "new"})
    assert _folder(out) == {"a.h": "new"}
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["c", alive.name])


def test_signals_are_deferred_over_a_commit():
    """A signal inside the block runs its handler after it (here Ctrl-C's KeyboardInterrupt)."""
    seen = []
    with pytest.raises(KeyboardInterrupt):
        with signals_deferred():
            signal.raise_signal(signal.SIGINT)
            seen.append("after the signal, inside the block")
    assert seen == ["after the signal, inside the block"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
