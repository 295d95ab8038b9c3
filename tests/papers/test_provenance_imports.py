"""papers/ and cli/ take the provenance names (``mpi_seed2``, ``SEED2_TABLE1``,
``seed1_stage``) from ``piezohyst.papers`` or their defining module, never from the
top-level ``piezohyst`` namespace, where they are deprecated."""

import ast
import importlib
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import piezohyst

DEPRECATED = {"mpi_seed2", "SEED2_TABLE1", "seed1_stage"}
ROOT = Path(piezohyst.__file__).resolve().parent
FILES = sorted([*(ROOT / "papers").glob("*.py"), *(ROOT / "cli").glob("*.py")])


def _top_level_uses(path):
    """``from piezohyst import NAME`` / ``from .. import NAME`` (at package depth) and
    ``piezohyst.NAME`` / ``ph.NAME`` attribute reads of a deprecated name."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            top = (node.level == 0 and node.module == "piezohyst") or (node.level == 2 and node.module is None)
            if top:
                found += [a.name for a in node.names if a.name in DEPRECATED]
        elif isinstance(node, ast.Attribute) and node.attr in DEPRECATED:
            if isinstance(node.value, ast.Name) and node.value.id in ("piezohyst", "ph"):
                found.append(f"{node.value.id}.{node.attr}")
    return found


@pytest.mark.parametrize("path", FILES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_top_level_provenance_names(path):
    assert _top_level_uses(path) == []


def test_modules_import_without_deprecation_warnings():
    names = [
        f"{pkg}.{info.name}"
        for pkg in ("piezohyst.papers", "piezohyst.cli")
        for info in pkgutil.iter_modules(importlib.import_module(pkg).__path__)
        if info.name != "__main__"  # runs the command line
    ]
    code = "; ".join(f"import {n}" for n in names)
    out = subprocess.run(
        [sys.executable, "-W", "error::DeprecationWarning", "-c", code], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
