"""Shared plumbing of the benchmarks: machine and version info, repetition counts, atomic
JSON output."""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import subprocess
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def extension_digest() -> str:
    """sha256 of the loaded extension module (the run must not mix builds)."""
    from piezohyst import _core

    return hashlib.sha256(Path(_core.__file__).read_bytes()).hexdigest()


def n_reps(first_call_s: float, min_reps: int, min_time: float, max_reps: int) -> int:
    """At least min_reps repetitions, more for fast calls (about min_time seconds in all)."""
    want = math.ceil(min_time / max(first_call_s, 1e-9))
    return int(max(min_reps, min(max_reps, want)))


def machine_info() -> dict:
    cpu_model, flags = None, set()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, val = line.partition(":")
                key = key.strip()
                if key == "model name" and cpu_model is None:
                    cpu_model = val.strip()
                elif key == "flags" and not flags:
                    flags = set(val.split())
    except OSError:
        pass
    try:
        affinity = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        affinity = None
    try:
        load = list(os.getloadavg())
    except OSError:
        load = None
    return {
        "cpu_model": cpu_model or platform.processor() or None,
        "cpu_count": os.cpu_count(),
        "cpus_usable": affinity,
        "simd": sorted(f for f in flags if f in {"avx2", "fma", "avx512f"}),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "loadavg_at_start": load,
    }


def versions() -> dict:
    from importlib import metadata

    import scipy

    from piezohyst import _core

    try:
        dist = metadata.version("piezohyst")
    except metadata.PackageNotFoundError:
        dist = None
    try:
        commit = (
            subprocess.run(
                ["git", "rev-parse", "HEAD"], cwd=HERE, capture_output=True, text=True, check=True
            ).stdout.strip()
            or None
        )
        dirty = bool(
            subprocess.run(
                ["git", "status", "--porcelain", "--untracked-files=no"],
                cwd=HERE,
                capture_output=True,
                text=True,
                check=True,
            ).stdout.strip()
        )
    except (OSError, subprocess.CalledProcessError):
        commit, dirty = None, None
    return {
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "piezohyst": dist,
        "piezohyst_core": _core.__version__,
        "extension_sha256": extension_digest(),
        "git_commit": commit,
        "git_tracked_changes": dirty,
    }


def write_json_atomic(path: Path, payload: dict) -> None:
    """The JSON of a result, written atomically (piezohyst's own writer)."""
    from piezohyst._io import write_atomic

    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, json.dumps(payload, indent=2, default=_json_default) + "\n")


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o).__name__)
