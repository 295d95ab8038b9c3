"""A MIMO model in the C runtime (issue 15): ``piezohyst export-c`` of a ``kind: "mimo"`` file,
its example compiled against the C library and run on a long record — the outputs equal
``MimoModel.run`` from rest bit for bit."""

from __future__ import annotations

import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from piezohyst.cli.main import main
from piezohyst.export.c import LINK_LIBS
from piezohyst.export.c_mimo import export_c_mimo, mimo_row
from piezohyst.models.mimo import MimoModel

ROOT = Path(__file__).resolve().parents[2]


def lfr_model(seed: int = 3, nx: int = 10, nw: int = 3, nr: int = 6) -> MimoModel:
    """An FSM-like LFR: 3 inputs (V), 3 outputs (m), rotation blocks in A, play feedback."""
    rng = np.random.default_rng(seed)
    a = np.zeros((nx, nx))
    for k in range(nx // 2):
        r, th = 0.9 + 0.015 * k, 0.3 + 0.4 * k
        a[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = r * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    return MimoModel(
        A=a,
        B=rng.standard_normal((nx, 3)),
        C=1e-6 * rng.standard_normal((3, nx)),
        D=1e-7 * rng.standard_normal((3, 3)),
        E=0.05 * rng.standard_normal((nx, nw)),
        F=1e-8 * rng.standard_normal((3, nw)),
        G=0.1 * rng.standard_normal((nw, nx)),
        H=rng.standard_normal((nw, 3)),
        thresholds=np.tile(np.linspace(0.0, 0.15, nr), (nw, 1)),
        weights=0.3 * rng.standard_normal((nw, nr)),
        fs=6400.0,
        structure="lfr",
    )


@pytest.fixture(scope="module")
def c_library():
    if shutil.which("cc") is None:
        pytest.skip("no C compiler (cc)")
    if shutil.which("cargo") is not None:  # a no-op when the library is up to date
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "piezohyst-capi"], cwd=ROOT, check=True)
    lib = ROOT / "target" / "release" / "libpiezohyst.a"
    if not lib.is_file():
        pytest.skip("the C library is not built (cargo build --release -p piezohyst-capi)")
    return lib


def build(out: Path, lib: Path) -> Path:
    exe = out / "example"
    cmd = ["cc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-ffp-contract=off", f"-I{out}"]
    cmd += [str(out / "example.c"), str(out / "piezohyst_mimo.c"), str(lib), *LINK_LIBS.split(), "-o", str(exe)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return exe


def test_row_layout_and_exact_literals(tmp_path):
    m = lfr_model()
    row = mimo_row(m)
    assert row.size == 10 * 10 + 10 * 3 + 3 * 10 + 9 + 10 * 3 + 9 + 3 * 10 + 9 + 2 * 18
    assert row[0] == m.A[0, 0] and row[100] == m.B[0, 0] and row[-1] == m.weights[-1, -1]
    files = export_c_mimo(m, tmp_path / "c", source="the test")
    text = (tmp_path / "c" / "piezohyst_mimo.c").read_text()
    assert {p.name for p in files} >= {"piezohyst_mimo.h", "piezohyst_mimo.c", "example.c"}
    literals = [
        line.split(",")[0].split()[0]
        for line in text.splitlines()
        if line.startswith("    0x") or line.startswith("    -0x")
    ]
    assert np.array_equal([float.fromhex(x) for x in literals], row)
    assert "#define PIEZOHYST_MIMO_NW 3" in (tmp_path / "c" / "piezohyst_mimo.h").read_text()


@pytest.mark.parametrize("static", [False, True])
def test_c_runtime_is_bit_exact_with_python_over_a_long_record(tmp_path, capsys, c_library, static):
    m = lfr_model()
    if static:  # the last channel a static saturation (r tanh(z / r))
        th = m.thresholds.copy()
        th[-1] = np.linspace(0.05, 0.3, th.shape[1])
        m = replace(m, thresholds=th, static_channels=1)
    m.save(tmp_path / "m.json")
    assert main(["export-c", str(tmp_path / "m.json"), "--out", str(tmp_path / "c")]) == 0
    assert "phs_mimo_*" in capsys.readouterr().out
    exe = build(tmp_path / "c", c_library)
    rng = np.random.default_rng(11)
    n = 20_000
    t = np.arange(n) / 6400.0
    u = 0.3 * np.column_stack([np.sin(2 * np.pi * f * t) for f in (13.0, 41.0, 97.0)]) + 0.05 * rng.standard_normal(
        (n, 3)
    )
    (tmp_path / "U.txt").write_text("\n".join(" ".join(float(v).hex() for v in row) for row in u) + "\n")
    r = subprocess.run([str(exe), str(tmp_path / "U.txt")], capture_output=True, text=True, check=True)
    y_c = np.array([[float.fromhex(x) for x in line.split()] for line in r.stdout.splitlines()])
    y_py, _, _ = m.run(u, np.zeros((1, m.state_len)))
    assert y_c.shape == (n, 3)
    assert f"#define PIEZOHYST_MIMO_NT {int(static)}" in (tmp_path / "c" / "piezohyst_mimo.h").read_text()
    assert np.array_equal(y_c, y_py[0])  # bit for bit
    assert np.max(np.abs(y_c)) > 1e-7  # and not trivially zero
    # the example without a file runs the built-in triangle
    r = subprocess.run([str(exe)], capture_output=True, text=True, check=True)
    assert "4000 steps" in r.stdout


def test_export_c_mimo_refuses_single_channel_options(tmp_path, capsys):
    lfr_model().save(tmp_path / "m.json")
    code = main(["export-c", str(tmp_path / "m.json"), "--out", str(tmp_path / "c"), "--steps", "10"])
    assert code == 2 and "--steps applies to single-channel models" in capsys.readouterr().err
    assert main(["export-c", str(tmp_path / "m.json"), "--out", str(tmp_path / "c")]) == 0
    assert main(["export-c", str(tmp_path / "m.json"), "--out", str(tmp_path / "c")]) == 2
    assert "--force" in capsys.readouterr().err


def test_the_identified_fsm_model_in_c_is_bit_exact(tmp_path, capsys, c_library):
    """The 120-state LFR identified on the CubeSpec mirror (examples/data), exported and run in C
    on two periods of a multisine-like record from rest: Python's outputs bit for bit."""
    src = ROOT / "examples" / "data" / "fsm_lfr_123.json"
    from piezohyst.models.mimo import load_mimo_model

    m = load_mimo_model(src)
    assert (m.nx, m.nu, m.ny, m.nw) == (120, 3, 3, 12)
    assert main(["export-c", str(src), "--out", str(tmp_path / "c")]) == 0
    exe = build(tmp_path / "c", c_library)
    rng = np.random.default_rng(2)
    n = 16384
    spec = np.zeros((n // 2 + 1, 3), dtype=complex)
    spec[1:1500] = np.exp(2j * np.pi * rng.random((1499, 3)))  # random-phase multisine up to 586 Hz
    u = np.fft.irfft(spec, n=n, axis=0)
    u *= 0.2 / np.sqrt(np.mean(u**2, axis=0))  # 200 mV RMS per input
    (tmp_path / "U.txt").write_text("\n".join(" ".join(float(v).hex() for v in row) for row in u) + "\n")
    r = subprocess.run([str(exe), str(tmp_path / "U.txt")], capture_output=True, text=True, check=True)
    y_c = np.array([[float.fromhex(x) for x in line.split()] for line in r.stdout.splitlines()])
    y_py, _, _ = m.run(u, np.zeros((1, m.state_len)))
    assert np.array_equal(y_c, y_py[0])
    assert 1e-6 < np.max(np.abs(y_c)) < 1e-4  # micrometres of travel
