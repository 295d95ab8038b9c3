"""Progress of a run on stderr, terminal-aware.

On a terminal, a Dask run shows Dask's own progress bar (``distributed``'s
``TextProgressBar``, fed by the scheduler's progress plugin, redrawn in place on stderr);
a serial run a bar of the same look. Anywhere else (a log file, a pipe, CI) there is no
carriage return and no redraw: one plain line per tenth of the tasks done, and one at the end.
"""

from __future__ import annotations

import sys
import threading
from typing import Any, TextIO

__all__ = ["Progress"]


def _bar(frac: float, width: int = 40) -> str:
    return f"[{'#' * int(width * frac):<{width}}] | {int(100 * frac):3d}% Completed"


class Progress:
    """Progress of ``what`` (e.g. ``"records"``) on ``stream`` (default stderr).

    ``mode``: ``"auto"`` (a bar on a terminal, lines elsewhere), ``"bar"``, ``"lines"`` or
    ``"none"``.
    """

    def __init__(self, prog: str, what: str, *, mode: str = "auto", stream: TextIO | None = None) -> None:
        self.prog = prog
        self.what = what
        self.stream = sys.stderr if stream is None else stream
        if mode == "auto":
            isatty = getattr(self.stream, "isatty", None)
            mode = "bar" if callable(isatty) and isatty() else "lines"
        if mode not in ("bar", "lines", "none"):
            raise ValueError(f"progress mode {mode!r} must be 'auto', 'bar', 'lines' or 'none'")
        self.mode = mode
        self._last_tenth = -1
        self._thread: threading.Thread | None = None
        self._dask_bar = False

    def attach(self, client: Any, futures: list[Any]) -> None:
        """On a terminal, Dask's progress bar for ``futures`` (drawn from a thread of its own)."""
        if self.mode != "bar" or not futures:
            return
        from distributed.diagnostics.progressbar import TextProgressBar

        stream = self.stream

        class _StderrBar(TextProgressBar):
            # Dask's bar, drawn on our stream (stderr) instead of stdout
            def _draw_bar(self, remaining: int, all: int, **kwargs: Any) -> None:
                frac = (1 - remaining / all) if all else 1.0
                stream.write(f"\r{_bar(frac)} | {self.elapsed:.1f} s")
                stream.flush()

            def _draw_stop(self, **kwargs: Any) -> None:
                stream.write("\n")
                stream.flush()

        address = client.scheduler.address

        def draw() -> None:
            try:
                _StderrBar(futures, scheduler=address, interval="200ms")  # type: ignore[no-untyped-call]
            except Exception:  # a progress bar never stops the run
                pass

        self._dask_bar = True
        self._thread = threading.Thread(target=draw, name="piezohyst-progress", daemon=True)
        self._thread.start()

    def update(self, done: int, total: int, elapsed: float) -> None:
        if self.mode == "none" or total == 0:
            return
        if self.mode == "bar":
            if not self._dask_bar:
                self.stream.write(f"\r{_bar(done / total)} | {elapsed:.1f} s")
                self.stream.flush()
            return
        tenth = (10 * done) // total
        if tenth != self._last_tenth and done < total:
            self._last_tenth = tenth
            self.stream.write(f"{self.prog}: {done}/{total} {self.what} done ({elapsed:.1f} s)\n")
            self.stream.flush()

    def close(self, done: int, total: int, elapsed: float) -> None:
        if self.mode == "none":
            return
        if self.mode == "bar":
            if self._thread is not None:
                self._thread.join(timeout=2.0)
            elif total:
                self.stream.write("\n")
                self.stream.flush()
            return
        self.stream.write(f"{self.prog}: {done}/{total} {self.what} done ({elapsed:.1f} s)\n")
        self.stream.flush()
