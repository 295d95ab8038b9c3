"""Progress of long steps on stderr: a tqdm bar on a terminal, plain lines elsewhere, nothing
when silenced.

One home for every progress display of the package (the optimizers of ``minimize``, so every
fit and tuning with ``progress=True``; the demo's steps; the CLI's ``--quiet``):

* **terminal** (the stream is a TTY): a tqdm bar, rewritten in place, shown only once a step
  has run for half a second (short steps leave no trace);
* **not a terminal** (a log file, a pipe, CI): one plain line at a time, never a carriage
  return: the first after a second, then one per further 10 % (at most one a second) or every
  5 s, and a closing line with the count and the time;
* **silenced** (:func:`silenced`, the CLI's ``--quiet``; or ``PIEZOHYST_PROGRESS=off``):
  nothing. ``PIEZOHYST_PROGRESS=lines`` forces the plain lines, ``bar`` the tqdm bar.

A stream that fails while a step runs (a terminal hung up: SIGHUP, then EIO) ends the display,
never the step: the best result so far must still reach the caller.

Examples
--------
>>> import io
>>> from piezohyst.progress import Progress
>>> log = io.StringIO()
>>> with Progress(4, "fit", stream=log, mode="lines") as p:
...     for k in range(1, 5):
...         p.update(k, best=0.5 / k)
>>> print(log.getvalue().splitlines()[-1].split(" in ")[0])
fit: 4/4 (100 %), best 0.125
>>> "\\r" in log.getvalue()
False
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from collections.abc import Iterator
from types import TracebackType
from typing import IO, TYPE_CHECKING, Literal, Never

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = ["Progress", "is_silenced", "progress_mode", "silenced"]

#: How progress is shown: a tqdm bar, plain lines, or not at all.
Mode = Literal["bar", "lines", "off"]

_SILENCED = 0


@contextlib.contextmanager
def silenced() -> Iterator[None]:
    """Silence every progress display inside the block (the CLI's ``--quiet``).

    Examples
    --------
    >>> import io
    >>> from piezohyst.progress import Progress, is_silenced, silenced
    >>> log = io.StringIO()
    >>> with silenced():
    ...     is_silenced(), Progress(3, "quiet", stream=log, mode="lines").mode
    (True, 'off')
    >>> is_silenced()
    False
    """
    global _SILENCED
    _SILENCED += 1
    try:
        yield
    finally:
        _SILENCED -= 1


def is_silenced() -> bool:
    """Whether progress is silenced (inside :func:`silenced` or ``PIEZOHYST_PROGRESS=off``).

    Examples
    --------
    >>> from piezohyst.progress import is_silenced
    >>> is_silenced()
    False
    """
    return _SILENCED > 0 or os.environ.get("PIEZOHYST_PROGRESS", "").strip().lower() == "off"


def progress_mode(stream: IO[str] | None = None) -> Mode:
    """How progress is shown on ``stream`` (default ``sys.stderr``): ``"off"`` when silenced,
    else ``PIEZOHYST_PROGRESS`` (``bar`` / ``lines``) when set, else ``"bar"`` on a terminal
    and ``"lines"`` elsewhere.

    Examples
    --------
    >>> import io
    >>> from piezohyst.progress import progress_mode
    >>> progress_mode(io.StringIO())  # not a terminal
    'lines'
    """
    if is_silenced():
        return "off"
    forced = os.environ.get("PIEZOHYST_PROGRESS", "").strip().lower()
    if forced in ("bar", "lines"):
        return "bar" if forced == "bar" else "lines"
    s = sys.stderr if stream is None else stream
    try:
        return "bar" if s.isatty() else "lines"
    except (OSError, ValueError, AttributeError):
        return "lines"


def _fmt(value: float) -> str:
    return f"{value:.6g}"


class Progress:
    """The progress of one step of ``total`` units (iterations, runs) on a stream.

    Parameters
    ----------
    total : int
        Units of the whole step (``update`` takes the count done so far).
    desc : str
        What runs, the line's or bar's prefix (``"css"``, ``"tune"``).
    stream : file-like, optional
        Where to write (default ``sys.stderr``).
    mode : {"bar", "lines", "off"}, optional
        Default: :func:`progress_mode` of the stream (silenced wins over any mode).

    Examples
    --------
    >>> import io
    >>> from piezohyst.progress import Progress
    >>> log = io.StringIO()
    >>> p = Progress(10, "tune", stream=log, mode="lines")
    >>> for k in range(1, 11):
    ...     p.update(k)
    >>> p.close()
    >>> log.getvalue().count("\\n"), log.getvalue().startswith("tune: 10/10 (100 %) in ")
    (1, True)
    """

    #: Plain lines: the first after this many seconds, then one per further 10 % (at most one a
    #: second) or every ``EVERY`` seconds.
    FIRST, EVERY = 1.0, 5.0
    #: A terminal bar appears once the step has run this long.
    BAR_DELAY = 0.5

    def __init__(self, total: int, desc: str, *, stream: IO[str] | None = None, mode: Mode | None = None) -> None:
        self.total, self.desc = max(int(total), 1), desc
        self.stream: IO[str] | None = sys.stderr if stream is None else stream
        self.mode: Mode = "off" if is_silenced() else (mode or progress_mode(self.stream))
        self.n = 0
        self._postfix: dict[str, float] = {}
        self._t0 = time.perf_counter()
        self._last_line = -math.inf
        self._last_fraction = 0.0
        self._lines = 0
        self._closed = False
        self._bar: tqdm[Never] | None = None
        if self.mode == "bar":
            self._bar = self._make_bar()

    def _make_bar(self) -> tqdm[Never] | None:
        from tqdm import tqdm

        try:
            return tqdm(
                total=self.total,
                desc=self.desc,
                file=self.stream,
                delay=self.BAR_DELAY,
                mininterval=0.1,
                dynamic_ncols=True,
                leave=True,
            )
        except (OSError, ValueError):
            self.stream = None
            return None

    def _write(self, text: str) -> None:
        if self.stream is None:
            return
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # a closed or hung-up stream
            self.stream = None

    def _line(self, done: bool = False) -> None:
        elapsed = time.perf_counter() - self._t0
        pct = 100.0 * self.n / self.total
        post = "".join(f", {k} {_fmt(v)}" for k, v in self._postfix.items())
        when = f"in {elapsed:.1f} s" if done else f"{elapsed:.1f} s elapsed"
        if not done and 0 < self.n < self.total:
            when += f", about {elapsed * (self.total - self.n) / self.n:.0f} s left"
        self._write(f"{self.desc}: {self.n}/{self.total} ({pct:.0f} %){post} {when}\n")
        self._lines += 1

    def update(self, n: int, **postfix: float) -> None:
        """Record that ``n`` units are done (absolute, not an increment), with named numbers
        to show beside the count (``best=1.2e-7``)."""
        if self.mode == "off" or self._closed:
            return
        self.n = min(int(n), self.total)
        self._postfix = dict(postfix)
        if self.mode == "bar":
            bar = self._bar
            if bar is None:
                return
            try:
                if postfix:
                    bar.set_postfix({k: _fmt(v) for k, v in postfix.items()}, refresh=False)
                bar.update(self.n - bar.n)
            except (OSError, ValueError):
                self._bar = None
            return
        now = time.perf_counter()
        elapsed = now - self._t0
        if elapsed < self.FIRST or self.n >= self.total:
            return
        fraction = self.n / self.total
        due = (fraction - self._last_fraction >= 0.1 and now - self._last_line >= 1.0) or (
            now - self._last_line >= self.EVERY
        )
        if due:
            self._last_line, self._last_fraction = now, fraction
            self._line()

    def close(self) -> None:
        """End the display: the terminal bar stays as it ended; plain lines end with a line of
        the count and the time taken."""
        if self._closed:
            return
        self._closed = True
        if self.mode == "bar" and self._bar is not None:
            try:
                self._bar.close()
            except (OSError, ValueError):
                pass
            self._bar = None
        elif self.mode == "lines":
            self._line(done=True)

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
