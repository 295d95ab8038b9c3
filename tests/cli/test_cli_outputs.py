"""Every command's outputs under the one output policy (issue 20, :mod:`piezohyst.outputs`):
refused destinations are named on one line before any work starts (with or without --force),
nothing the user owns is replaced or read, and the multi-file outputs (export-c, the demo
report) are put in place as a set — an interrupted run leaves the old set."""

from __future__ import annotations

import json
import os
import signal
import stat
from pathlib import Path

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.cli import main
from piezohyst.export_c import save_controller


def run_cli(capsys, *argv):
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.fixture
def folder(tmp_path):
    """A record, and beside it a FIFO, a link to /dev/null, links to the record, a folder, a file."""
    t = np.arange(600) / 600
    v = 60 * np.sin(2 * np.pi * 3 * t) + 60
    y = ph.PI([0.0, 20.0, 40.0], [0.5, 0.2, 0.1]).simulate(v)
    np.savetxt(tmp_path / "run.csv", np.c_[v, y], delimiter=",", header="v,y", comments="")
    os.mkfifo(tmp_path / "fifo")
    os.symlink("/dev/null", tmp_path / "null")
    os.symlink("nowhere.json", tmp_path / "dangling")
    os.symlink("run.csv", tmp_path / "to_input")
    os.link(tmp_path / "run.csv", tmp_path / "hard.csv")
    (tmp_path / "sub").mkdir()
    (tmp_path / "file.txt").write_text("x")
    return tmp_path


def _identify(folder, out, *extra):
    cols = ["--input", "v", "--output", "y", "--fs", "600"]
    return ["identify", folder / "run.csv", "--model", "pi", "--operators", "3", *cols, "--out", out, *extra]


def _untouched(folder):
    assert stat.S_ISFIFO(os.lstat(folder / "fifo").st_mode)
    assert os.readlink(folder / "null") == "/dev/null" and stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert os.readlink(folder / "to_input") == "run.csv" and os.readlink(folder / "dangling") == "nowhere.json"
    assert (folder / "run.csv").read_text().startswith("v,y\n") and os.stat(folder / "run.csv").st_nlink == 2
    assert not [p for p in folder.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("force", [[], ["--force"]])
@pytest.mark.parametrize(
    "dest,message",
    [
        ("fifo", "is a FIFO (named pipe), not a regular file"),
        ("null", "is a symbolic link to '/dev/null', a character device"),
        ("to_input", "is the input DATA"),
        ("hard.csv", "is the input DATA"),
        ("run.csv", "is the input DATA"),
        ("sub", "is a directory, not a regular file"),
        ("file.txt/m.json", "file.txt' is a file, not a directory"),
    ],
)
def test_identify_refuses_before_any_work(folder, capsys, monkeypatch, dest, message, force):
    def never(*a, **k):
        raise AssertionError("the fit ran before the destination was checked")

    from piezohyst.cli import identify as cli_identify
    from piezohyst.identify import dispatch

    monkeypatch.setattr(dispatch, "identify", never)
    monkeypatch.setattr(cli_identify, "_load", never)
    code, out, err = run_cli(capsys, *_identify(folder, folder / dest, *force))
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert err.startswith(f"piezohyst identify: error: --out = '{folder / dest}'") and message in err
    _untouched(folder)


def test_identify_links_need_force_and_the_link_itself_is_replaced(folder, capsys):
    target = folder / "theirs.json"
    target.write_text("theirs")
    os.symlink("theirs.json", folder / "link.json")
    for link in ("dangling", "link.json"):
        code, _, err = run_cli(capsys, *_identify(folder, folder / link))
        assert code == 2 and "is a symbolic link to" in err and "pass --force to replace the link itself" in err
    for link in ("dangling", "link.json"):
        code, _, err = run_cli(capsys, *_identify(folder, folder / link, "--force"))
        assert code in (0, 3), err
        assert not (folder / link).is_symlink() and ph.load_model(folder / link).kind == "pi"
    assert target.read_text() == "theirs" and not (folder / "nowhere.json").exists()


def test_identify_names_a_folder_that_vanished_during_the_fit(folder, capsys, monkeypatch):
    """Not "[Errno 2] ... .m.json.x1y2.tmp": the argument and the directory."""
    from piezohyst.identify import dispatch

    real = dispatch.identify
    gone = folder / "gone"
    gone.mkdir()

    def identify(*a, **k):
        res = real(*a, **k)
        gone.rmdir()
        return res

    monkeypatch.setattr(dispatch, "identify", identify)
    code, _, err = run_cli(capsys, *_identify(folder, gone / "m.json"))
    assert code == 2 and err.count("\n") == 1
    assert f"--out = '{gone / 'm.json'}': directory '{gone}' does not exist" in err and ".tmp" not in err


def test_simulate_out_rules(folder, capsys):
    model = folder / "m.json"
    ph.PI([0.0, 20.0], [0.5, 0.2]).save(model)
    base = ["simulate", model, folder / "run.csv", "--input", "v", "--fs", "600", "--force", "--out"]
    for dest, message in [
        ("fifo", "is a FIFO"),
        ("hard.csv", "is the input INPUT"),
        ("m.json", "is the input MODEL"),
        ("null", "a character device"),
    ]:
        code, _, err = run_cli(capsys, *base, folder / dest)
        assert code == 2 and message in err and err.count("\n") == 1, err
    code, out, _ = run_cli(capsys, *base, "-")  # standard output stays offered
    assert code == 0 and out.startswith("time,input,output\n") and out.count("\n") == 601
    _untouched(folder)


def test_track_plot_rules(folder, capsys):
    for dest, message in [("null", "a character device"), ("dangling", "is a symbolic link")]:
        track = ["track", "--controller", "open-loop", "--duration", "0.05"]
        code, _, err = run_cli(capsys, *track, "--plot", folder / dest)
        assert code == 2 and f"--plot = '{folder / dest}'" in err and message in err, err
    _untouched(folder)


def test_bench_readme_link_is_refused_before_running(folder, capsys):
    (folder / "README.md").write_text("<!-- bench:begin -->\n<!-- bench:end -->\n")
    os.symlink("README.md", folder / "LINK.md")
    results = folder / "results"
    results.mkdir()
    code, _, err = run_cli(capsys, "bench", "--report-only", "--results", results, "--readme", folder / "LINK.md")
    assert code == 2 and "--readme" in err and "is a symbolic link" in err
    code, _, err = run_cli(capsys, "bench", "--report-only", "--results", folder / "fifo")
    assert code == 2 and "--results" in err


# -- export-c: a set ---------------------------------------------------------------------------


@pytest.fixture
def exported(tmp_path):
    mpi = ph.papers.mpi_seed2()
    mpath = tmp_path / "mpi.json"
    mpi.save(mpath)
    cpath = save_controller(ph.InverseFeedforward(mpi), ph.virtual_stage(), tmp_path / "ff.json")
    return tmp_path, mpath, cpath


def _set(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def test_export_c_interrupted_or_full_disk_keeps_the_old_set(exported, capsys, monkeypatch):
    tmp_path, mpath, cpath = exported
    out = tmp_path / "c"
    assert run_cli(capsys, "export-c", mpath, cpath, "--out", out)[0] == 0
    old = _set(out)
    assert {"piezohyst_controller.c", "piezohyst_model.c", "example.c"} <= set(old)
    real = Path.write_text
    for stop in (OSError(28, "No space left on device"), KeyboardInterrupt()):
        calls = {"n": 0}

        def write_text(self, *a, stop=stop, calls=calls, **k):
            calls["n"] += 1
            if calls["n"] == 2:  # the second file of the set
                raise stop
            return real(self, *a, **k)

        monkeypatch.setattr(Path, "write_text", write_text)
        code, _, err = run_cli(capsys, "export-c", mpath, "--out", out, "--force")
        monkeypatch.setattr(Path, "write_text", real)
        assert code == (2 if isinstance(stop, OSError) else 130), err
        assert _set(out) == old  # the whole old set, nothing of the new
        assert sorted(p.name for p in tmp_path.iterdir()) == ["c", "ff.json", "mpi.json"]  # no temporary
    # the rerun is not blocked; the model-only export replaces the set: no controller file of the old one
    code, _, err = run_cli(capsys, "export-c", mpath, "--out", out, "--force")
    assert code == 0, err
    new = _set(out)
    assert not {"piezohyst_controller.c", "piezohyst_controller.h"} & set(new)
    assert set(new) == set(old) - {"piezohyst_controller.c", "piezohyst_controller.h"}
    assert b"model(inverse(y))" in new["example.c"] and b"model(inverse(y))" not in old["example.c"]


def test_export_c_killed_run_does_not_block_and_links_are_refused(exported, capsys):
    tmp_path, mpath, _ = exported
    stale = tmp_path / f".c.{2**22 + 1}.abcd1234.piezohyst-tmp"  # a killed run's half set
    stale.mkdir()
    (stale / "piezohyst_model.h").write_text("half")
    code, _, err = run_cli(capsys, "export-c", mpath, "--out", tmp_path / "c")
    assert code == 0, err
    assert not stale.exists() and (tmp_path / "c" / "piezohyst_model.h").read_text() != "half"
    os.symlink("c", tmp_path / "link")
    code, _, err = run_cli(capsys, "export-c", mpath, "--out", tmp_path / "link", "--force")
    assert code == 2 and "is a symbolic link to 'c'; give the directory itself" in err
    os.remove(tmp_path / "c" / "example.c")
    os.mkfifo(tmp_path / "c" / "example.c")
    code, _, err = run_cli(capsys, "export-c", mpath, "--out", tmp_path / "c", "--force")
    assert code == 2 and "example.c' is a FIFO" in err
    os.remove(tmp_path / "c" / "example.c")
    os.link(mpath, tmp_path / "c" / "example.c")
    code, _, err = run_cli(capsys, "export-c", mpath, "--out", tmp_path / "c", "--force")
    assert code == 2 and "is the input MODEL" in err
    assert json.loads(mpath.read_text())["kind"]


# -- the demo report: a set ---------------------------------------------------------------------


def _old_report(tmp_path: Path) -> Path:
    a = tmp_path / "report"
    a.mkdir()
    (a / "index.html").write_text("old index")
    (a / "report.md").write_text("old md")
    (a / "results.json").write_text(json.dumps({"figures": {"loops": "old_loops.png"}}))
    (a / "old_loops.png").write_bytes(b"old png")
    return a


def test_demo_stopped_by_a_signal_leaves_the_old_report(tmp_path, capsys, monkeypatch):
    """SIGTERM during the experiments and SIGHUP while the report is written: exit 143 / 129,
    the old report whole (no file of the new run), no temporary folder left."""
    from piezohyst.papers import demo

    a = _old_report(tmp_path)
    old = _set(a)

    def experiments(*a, **k):
        signal.raise_signal(signal.SIGTERM)
        raise AssertionError("SIGTERM did not stop the demo")

    monkeypatch.setattr(demo, "_experiments", experiments)
    code, _, err = run_cli(capsys, "demo", "--out", a, "--force", "--quick")
    assert code == 143, err
    assert err.strip() == f"piezohyst: interrupted by SIGTERM: the report was not written; '{a}' is as it was"
    assert _set(a) == old

    def write_report(out_dir, results, **k):
        (out_dir / "index.html").write_text("new index")
        (out_dir / "new.png").write_bytes(b"new png")
        signal.raise_signal(signal.SIGHUP)
        raise AssertionError("SIGHUP did not stop the demo")

    monkeypatch.setattr(demo, "_experiments", lambda *a, **k: ({}, {}, {}, None, None))
    monkeypatch.setattr(demo, "write_report", write_report)
    code, _, err = run_cli(capsys, "demo", "--out", a, "--force", "--quick")
    assert code == 129 and "interrupted by SIGHUP" in err, err
    assert _set(a) == old and sorted(p.name for p in tmp_path.iterdir()) == ["report"]


def test_demo_stops_on_a_fit_a_signal_cut_short(tmp_path, capsys, monkeypatch):
    """An optimizer keeps its best on a signal (partial); the demo then stops, writing nothing."""
    from piezohyst.papers import experiments

    a = _old_report(tmp_path)
    old = _set(a)

    class Cut:
        partial = True

    def identify_stage_cemf(*a, **k):
        try:
            signal.raise_signal(signal.SIGHUP)
        except KeyboardInterrupt:  # as the optimizer does: keep the best so far
            return None, Cut(), 0.0
        raise AssertionError("SIGHUP was not raised")

    monkeypatch.setattr(experiments, "identify_stage_cemf", identify_stage_cemf)
    code, _, err = run_cli(capsys, "demo", "--out", a, "--force", "--quick")
    assert code == 129 and "the report was not written" in err, err
    assert _set(a) == old


def test_demo_force_replaces_the_whole_old_report(tmp_path, capsys, monkeypatch):
    from piezohyst.papers import demo

    a = _old_report(tmp_path)

    def write_report(out_dir, results, **k):
        for n in ("index.html", "report.md"):
            (out_dir / n).write_text("new")
        (out_dir / "new.png").write_bytes(b"new png")
        return {"new": "new.png"}

    monkeypatch.setattr(demo, "_experiments", lambda *a, **k: ({}, {}, {}, None, None))
    monkeypatch.setattr(demo, "write_report", write_report)
    code, _, err = run_cli(capsys, "demo", "--out", a, "--force", "--quick")
    assert code == 0, err
    assert sorted(p.name for p in a.iterdir()) == ["index.html", "new.png", "report.md", "results.json"]
    assert json.loads((a / "results.json").read_text())["figures"] == {"new": "new.png"}


def test_identify_auto_stopped_by_a_signal_ranks_what_was_fitted(folder, capsys, monkeypatch):
    """--model auto: a SIGTERM swallowed by a candidate's optimizer (kept its best) stops the
    league there; the winner among the fitted is saved marked partial, exit 143."""
    from piezohyst.identify import dispatch

    real = dispatch.identify
    calls = []

    def identify(*a, **k):
        calls.append(k.get("model"))
        if len(calls) == 2:
            try:  # as a population optimizer does: the signal stops it, the best is kept
                signal.raise_signal(signal.SIGTERM)
            except KeyboardInterrupt:
                pass
        return real(*a, **k)

    monkeypatch.setattr(dispatch, "identify", identify)
    out = folder / "auto.json"
    argv = [a if a != "pi" else "auto" for a in _identify(folder, out)]
    code, _, err = run_cli(capsys, *argv, "--validate", "400:")
    assert code == 143, err
    assert len(calls) == 2  # no candidate after the signal
    doc = json.loads(out.read_text())
    assert doc["partial"] is True and doc["fit"]["partial"] is True
    stopped = [row for row in doc["fit"]["league"] if row.get("error") == "stopped by SIGTERM"]
    assert len(stopped) == len(doc["fit"]["league"]) - 2
    assert "holds the best model found before SIGTERM" in err
    assert ph.load_model(out).kind == "pi"


@pytest.mark.parametrize("levels", [12, 20])
def test_identify_auto_fits_the_finer_preisach_grid_unless_levels_is_as_fine(folder, capsys, monkeypatch, levels):
    """--model auto's finer Preisach candidates (AUTO_FINE_LEVELS, with and without two creep
    lags) are fitted on their own grid; with --levels at least as fine they are listed as not
    fitted, never chosen."""
    from piezohyst.cli.identify import AUTO_FINE_LEVELS
    from piezohyst.identify import dispatch

    real = dispatch.identify
    grids = []

    def identify(*a, **k):
        if k.get("model") == "preisach":
            grids.append((k["levels"], k.get("creep", 0)))
        return real(*a, **k)

    monkeypatch.setattr(dispatch, "identify", identify)
    out = folder / "auto.json"
    argv = [a if a != "pi" else "auto" for a in _identify(folder, out)]
    code, _, err = run_cli(capsys, *argv, "--validate", "400:", "--levels", levels)
    assert code in (0, 3), err
    rows = {row["name"]: row for row in json.loads(out.read_text())["fit"]["league"]}
    fine = [f"preisach{AUTO_FINE_LEVELS}", f"preisach{AUTO_FINE_LEVELS}+creep2"]
    if levels < AUTO_FINE_LEVELS:
        # (a finalist's drift variants are fitted on its grid too)
        assert {g for g in grids if g[0] >= AUTO_FINE_LEVELS} == {(AUTO_FINE_LEVELS, 0), (AUTO_FINE_LEVELS, 2)}
        assert all(rows[name]["rank"] is not None for name in fine)
    else:
        assert {g for g, _ in grids} == {levels}
        assert all(rows[name]["rank"] is None and "as fine" in rows[name]["error"] for name in fine)
        assert not any(rows[name]["chosen"] for name in fine)
