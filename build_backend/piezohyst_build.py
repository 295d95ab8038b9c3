"""The package's PEP 517 build backend: maturin, after building the C library.

``pip wheel .`` / ``pip install .`` (and ``python -m build``) call this module
(``[build-system] build-backend`` in pyproject.toml, found through ``backend-path``). Before
maturin builds the wheel it runs ``cargo build --release -p piezohyst-capi`` and copies the C
library — ``libpiezohyst.so``, ``libpiezohyst.a`` (debug info stripped when ``strip`` is on the
PATH: 23 MB -> 15 MB) — and its header ``crates/capi/include/piezohyst.h`` into
``python/piezohyst/capi/lib`` and ``python/piezohyst/capi/include`` (ignored by git);
``[tool.maturin] include`` puts them in the wheel beside the Python package, where
``python -m piezohyst.capi --cflags --libs`` finds them. Every other hook is maturin's.

Why a wrapper rather than a Cargo build script: maturin builds only the crate of the Python
extension (crates/python); a build script of that crate running cargo again on the same
workspace would wait on cargo's own lock of the target folder.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import maturin
from maturin import (  # noqa: F401  (the hooks this backend passes through unchanged)
    build_sdist,
    get_requires_for_build_sdist,
    get_requires_for_build_wheel,
    prepare_metadata_for_build_wheel,
)

ROOT = Path(__file__).resolve().parents[1]
STAGE = ROOT / "python" / "piezohyst" / "capi"


def _log(text: str) -> None:
    print(f"piezohyst build: {text}", file=sys.stderr, flush=True)


def _target_dir() -> Path:
    out = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps", "--manifest-path", str(ROOT / "Cargo.toml")],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return Path(json.loads(out)["target_directory"])


def stage_c_library() -> list[Path]:
    """Build the C library (release) and copy it and its header into the package; return the
    files copied."""
    manifest = ROOT / "crates" / "capi" / "Cargo.toml"
    if not manifest.is_file():
        raise RuntimeError(f"{manifest} is missing: the C library cannot be built, the wheel would lack it")
    _log("cargo build --release -p piezohyst-capi (libpiezohyst.so, libpiezohyst.a)")
    subprocess.run(
        ["cargo", "build", "--release", "-p", "piezohyst-capi", "--manifest-path", str(ROOT / "Cargo.toml")],
        check=True,
    )
    release = _target_dir() / "release"
    lib, include = STAGE / "lib", STAGE / "include"
    for d in (lib, include):
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
    copied = []
    for name in ("libpiezohyst.so", "libpiezohyst.a"):
        src = release / name
        if not src.is_file():
            raise RuntimeError(f"{src} was not built")
        shutil.copy2(src, lib / name)
        copied.append(lib / name)
    strip = shutil.which("strip")
    if strip is not None:  # the Rust standard library's debug info: not needed to link
        subprocess.run([strip, "--strip-debug", str(lib / "libpiezohyst.a")], check=True)
        subprocess.run([strip, "--strip-unneeded", str(lib / "libpiezohyst.so")], check=True)
    shutil.copy2(ROOT / "crates" / "capi" / "include" / "piezohyst.h", include / "piezohyst.h")
    copied.append(include / "piezohyst.h")
    _log("staged " + ", ".join(f"{p.relative_to(STAGE)} ({p.stat().st_size // 1024} KiB)" for p in copied))
    return copied


def build_wheel(
    wheel_directory: str, config_settings: dict[str, Any] | None = None, metadata_directory: str | None = None
) -> str:
    """PEP 517 ``build_wheel``: the C library staged, then maturin's wheel."""
    if os.environ.get("PIEZOHYST_SKIP_CAPI") != "1":
        stage_c_library()
    name: str = maturin.build_wheel(wheel_directory, config_settings, metadata_directory)
    return name


def build_editable(
    wheel_directory: str, config_settings: dict[str, Any] | None = None, metadata_directory: str | None = None
) -> str:
    """PEP 517 ``build_editable`` (``pip install -e .``): the C library staged too."""
    if os.environ.get("PIEZOHYST_SKIP_CAPI") != "1":
        stage_c_library()
    name: str = maturin.build_editable(wheel_directory, config_settings, metadata_directory)
    return name


get_requires_for_build_editable = maturin.get_requires_for_build_editable
prepare_metadata_for_build_editable = maturin.prepare_metadata_for_build_editable
