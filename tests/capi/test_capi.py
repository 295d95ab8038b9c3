"""The C library in the package (piezohyst.capi): flags and paths from a source tree, the build
backend that stages the library for the wheel, and what pyproject tells maturin to include.
The wheel itself is checked by ``make wheel-check`` (tests/c/check_wheel.py)."""

import importlib.util
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from piezohyst import capi

ROOT = Path(__file__).resolve().parents[2]


def run(*args):
    return subprocess.run([sys.executable, "-m", "piezohyst.capi", *args], capture_output=True, text=True, cwd=ROOT)


def test_cflags_point_at_the_header():
    out = run("--cflags")
    assert out.returncode == 0, out.stderr
    (flag,) = out.stdout.split()
    assert flag.startswith("-I") and (Path(flag[2:]) / "piezohyst.h").is_file()
    assert capi.header_path().read_bytes() == (ROOT / "crates/capi/include/piezohyst.h").read_bytes()


def test_libs_name_the_library_or_say_it_is_not_built():
    out = run("--cflags", "--libs")
    try:
        lib = capi.library_path()
    except FileNotFoundError:
        assert (
            out.returncode == 2
            and out.stderr.count("\n") == 1
            and "cargo build --release -p piezohyst-capi" in (out.stderr)
        )
        return
    assert out.returncode == 0, out.stderr
    flags = out.stdout.split()
    assert f"-L{lib.parent}" in flags and f"-Wl,-rpath,{lib.parent}" in flags and "-lpiezohyst" in flags
    static = run("--libs", "--static").stdout.split()
    assert static[0] == str(capi.library_path(static=True)) and "-lpthread" in static


def test_no_request_is_a_one_line_error():
    out = run()
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and "give --cflags" in out.stderr
    assert run("--cflag").returncode == 2  # no abbreviations


def test_the_backend_stages_what_pyproject_includes():
    """The files the build backend copies are exactly the wheel includes of [tool.maturin]."""
    spec = importlib.util.spec_from_file_location("piezohyst_build", ROOT / "build_backend" / "piezohyst_build.py")
    pytest.importorskip("maturin")
    backend = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(backend)
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert conf["build-system"]["build-backend"] == "piezohyst_build"
    assert conf["build-system"]["backend-path"] == ["build_backend"]
    wheel = {e["path"] for e in conf["tool"]["maturin"]["include"] if e["format"] == "wheel"}
    staged = {f"python/piezohyst/capi/{d}/{n}" for d, n in (("lib", "libpiezohyst.so"), ("lib", "libpiezohyst.a"))}
    staged.add("python/piezohyst/capi/include/piezohyst.h")
    assert wheel == staged
    assert backend.STAGE == ROOT / "python" / "piezohyst" / "capi"
    for hook in ("build_wheel", "build_sdist", "prepare_metadata_for_build_wheel", "get_requires_for_build_wheel"):
        assert callable(getattr(backend, hook)), hook
    # git never holds the staged copies
    ignored = (ROOT / ".gitignore").read_text().splitlines()
    assert "/python/piezohyst/capi/lib/" in ignored and "/python/piezohyst/capi/include/" in ignored


def test_py_typed_ships():
    assert (ROOT / "python" / "piezohyst" / "py.typed").is_file()
