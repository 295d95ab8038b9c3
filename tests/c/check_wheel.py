"""Check a built wheel (``make wheel-check``): it holds the C library (shared and static), its
header and ``py.typed``; ``python -m piezohyst.capi --cflags --libs`` run from the wheel's files
points into them; the docs' C example (``examples/c/pi_inverse.c``, docs/guides/export_c.rst)
compiles against the wheel's files alone, shared and static, and runs with the documented output.

Usage: ``python tests/c/check_wheel.py WHEEL_DIR`` (the folder ``pip wheel . -w`` wrote).
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NEEDED = (
    "piezohyst/capi/lib/libpiezohyst.so",
    "piezohyst/capi/lib/libpiezohyst.a",
    "piezohyst/capi/include/piezohyst.h",
    "piezohyst/capi/__init__.py",
    "piezohyst/py.typed",
    "piezohyst/_core.pyi",
)
EXPECTED_LAST_LINE = "largest |inverse(model(v)) - v| = 1.11e-16"


def _run(cmd: list[str], **kw: object) -> str:
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, **kw)  # type: ignore[call-overload]
    return str(out.stdout)


def check(wheel_dir: Path) -> None:
    wheels = sorted(wheel_dir.glob("piezohyst-*.whl"))
    assert len(wheels) == 1, f"one piezohyst wheel expected in {wheel_dir}, found {[w.name for w in wheels]}"
    wheel = wheels[0]
    with zipfile.ZipFile(wheel) as z:
        sizes = {i.filename: i.file_size for i in z.infolist()}
        missing = [n for n in NEEDED if n not in sizes]
        assert not missing, f"{wheel.name} lacks {missing}"
        bytecode = [n for n in sizes if n.endswith(".pyc") or "__pycache__/" in n]
        assert not bytecode, f"{wheel.name} holds the source tree's bytecode: {bytecode[:3]}"
        print(f"{wheel.name}: {wheel.stat().st_size / 1e6:.1f} MB")
        for n in NEEDED[:3]:
            print(f"  {n}: {sizes[n] / 1e3:.0f} kB")
        with tempfile.TemporaryDirectory() as tmp:
            site = Path(tmp) / "site"
            z.extractall(site)  # the wheel's files as an installation lays them out
            header = site / "piezohyst/capi/include/piezohyst.h"
            assert header.read_bytes() == (ROOT / "crates/capi/include/piezohyst.h").read_bytes(), "stale header"
            env = {**os.environ, "PYTHONPATH": str(site)}  # the wheel's package first on the path
            where = _run([sys.executable, "-c", "import piezohyst.capi as c; print(c.__file__)"], env=env, cwd=tmp)
            assert where.startswith(str(site)), f"piezohyst.capi imported from {where}, not from the wheel"
            cc = os.environ.get("CC", "cc")
            source = ROOT / "examples" / "c" / "pi_inverse.c"
            for static in (False, True):
                args = [sys.executable, "-m", "piezohyst.capi", "--cflags", "--libs"] + (["--static"] if static else [])
                flags = _run(args, env=env, cwd=tmp).split()
                paths = [f for f in flags if "/" in f]
                assert paths and all(str(site) in f for f in paths), f"flags outside the wheel: {flags}"
                exe = Path(tmp) / ("pi_static" if static else "pi_shared")
                cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", str(source), *flags]
                _run([*cmd, "-o", str(exe)], cwd=tmp)
                out = _run([str(exe)], cwd=tmp)
                assert out.splitlines()[0].startswith("libpiezohyst "), out
                assert out.splitlines()[-1] == EXPECTED_LAST_LINE, out
                kind = "static" if static else "shared"
                print(f"  {kind}: {shlex.join([cc, source.name, *flags])} -> runs: {out.splitlines()[-1]}")
                if not static and shutil.which("ldd"):
                    ldd = _run(["ldd", str(exe)])
                    line = next(x for x in ldd.splitlines() if "libpiezohyst" in x)
                    assert str(site) in line, f"the program loads {line.strip()}"
    print("wheel check: passed")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    check(Path(sys.argv[1]))
