"""Options every command shares: --version, --quiet, and no abbreviated long options."""

import argparse
import subprocess
import sys
from importlib.metadata import version

import pytest

import piezohyst as ph
from piezohyst.cli.main import _parser, version_text


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "piezohyst", *args], cwd=cwd, capture_output=True, text=True)


def _leaves(p: argparse.ArgumentParser, prefix=()):
    subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield prefix, p
        return
    for name, child in subs[0].choices.items():
        yield from _leaves(child, (*prefix, name))


def test_version_names_the_package_and_the_core(tmp_path):
    out = run("--version", cwd=tmp_path)
    assert out.returncode == 0 and out.stderr == ""
    lines = out.stdout.splitlines()
    assert lines[0] == f"piezohyst {version('piezohyst')}"
    assert lines[1] == f"core (piezohyst._core, Rust) {ph._core.__version__}"
    assert out.stdout == version_text() + "\n"


@pytest.mark.parametrize(
    "argv",
    [
        ["demo", "--forc"],  # --force
        ["demo", "--qui"],  # --quick or --quiet: refused, never guessed
        ["stage", "info", "--jso"],  # --json, one level deeper
        ["track", "--controller", "pid", "--ref", "sine"],  # --reference
        ["identify", "x.csv", "--model", "mpi", "--fs", "10", "--iter", "5"],  # --iterations
        ["stage", "info", "--vers"],  # not --version
    ],
)
def test_abbreviated_long_options_are_refused(tmp_path, argv):
    out = run(*argv, cwd=tmp_path)
    assert out.returncode == 2, out.stdout
    abbreviated = next(a for a in reversed(argv) if a.startswith("--"))
    assert out.stderr.count("\n") == 1 and f"unrecognized arguments: {abbreviated}" in out.stderr
    assert list(tmp_path.iterdir()) == []  # nothing ran


def test_every_command_takes_quiet_and_refuses_abbreviations():
    leaves = dict(_leaves(_parser()))
    assert {" ".join(k) for k in leaves} >= {"demo", "stage info", "identify", "simulate", "track", "export-c", "bench"}
    for name, p in leaves.items():
        assert p.allow_abbrev is False, name
        assert "--quiet" in p._option_string_actions, name


def test_quiet_silences_the_progress_only(tmp_path):
    """identify with an optimizer and --progress prints its progress on stderr (plain lines: not
    a terminal); --quiet silences it, the result on stdout stays."""
    import numpy as np

    rng = np.random.default_rng(2)
    v = np.cumsum(rng.normal(0, 1, 1500))
    v = 80 * (v - v.min()) / np.ptp(v)
    y = ph.BoucWen(a=0.4, beta=0.02, gamma=0.01).simulate(v)
    np.savetxt(tmp_path / "r.csv", np.c_[v, y], delimiter=",", header="input,output", comments="")
    base = ["identify", "r.csv", "--model", "boucwen", "--fs", "1kHz", "--iterations", "15", "--seed", "0"]
    loud = run(*base, "--out", "a.json", "--progress", cwd=tmp_path)
    quiet = run(*base, "--out", "b.json", "--progress", "--quiet", cwd=tmp_path)
    assert loud.returncode in (0, 3) and quiet.returncode == loud.returncode, loud.stderr + quiet.stderr
    assert "15/15 (100 %)" in loud.stderr and "\r" not in loud.stderr
    assert "/15" not in quiet.stderr and "identified by" in quiet.stdout
    assert (tmp_path / "b.json").is_file()
