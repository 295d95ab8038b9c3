"""The CLI process keeps the main heap's freed pages (``tune_malloc``): NumPy temporaries of a
few hundred kB, allocated and freed in a loop on the main thread, must not be taken from the
system again as fresh pages each time (the serial path's slowness, issue 16)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

CHURN = textwrap.dedent(
    """
    import resource, sys
    import numpy as np
    from piezohyst.cli.main import tune_malloc
    if sys.argv[1] == "tuned":
        assert tune_malloc()
    np.ones(200_000) * 2  # warm: the first block of this size
    r0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(50):
        a = np.ones(200_000)  # 1.6 MB: mmapped / trimmed on free by glibc's defaults
        b = a * 2
        del a, b
    print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - r0)
    """
)


def faults(mode: str) -> int:
    out = subprocess.run([sys.executable, "-c", CHURN, mode], capture_output=True, text=True, check=True)
    return int(out.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_tune_malloc_keeps_freed_numpy_pages_for_reuse():
    default, tuned = faults("default"), faults("tuned")
    # 50 iterations x 2 arrays x 1.6 MB: ~39,000 fresh pages by default; a few hundred kept
    assert default > 20_000, default
    assert tuned < default / 20, (tuned, default)


def test_the_process_entry_tunes_the_allocator(monkeypatch, capsys):
    import importlib

    cli_main = importlib.import_module("piezohyst.cli.main")
    calls: list[str] = []

    def exit_(code: int) -> None:
        calls.append(f"exit {code}")
        raise SystemExit(code)

    monkeypatch.setattr(cli_main, "tune_malloc", lambda: calls.append("tune") or True)
    monkeypatch.setattr(cli_main.os, "_exit", exit_)
    # run() runs the exit handlers before os._exit: not this test process's (h5py's among them)
    monkeypatch.setattr(cli_main.atexit, "_run_exitfuncs", lambda: calls.append("atexit"))
    with pytest.raises(SystemExit):
        cli_main.run(["--version"])
    assert calls == ["tune", "atexit", "exit 0"]
    assert capsys.readouterr().out.startswith("piezohyst ")
