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

A run of tasks on a Dask cluster (``piezohyst.fleet``: fleet identify, robustness) uses the same
class: :meth:`Progress.follow_dask` draws Dask's own progress bar (fed by the scheduler) on a
terminal instead of the tqdm bar, and the plain lines and silencing are the ones above.

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
import threading
import time
from collections.abc import Iterator
from types import TracebackType
from typing import IO, TYPE_CHECKING, Any, Literal, Never

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = ["Mode", "Progress", "is_silenced", "progress_mode", "silenced"]

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

    Parameters
    ----------
    stream : file-like, optional
        The stream progress would be written to (default ``sys.stderr``).

    Returns
    -------
    {"bar", "lines", "off"}

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
    unit : str, optional
        What is counted, named in the lines (``"records"``: ``fleet: 3/8 records done (38 %)``).

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

    def __init__(
        self,
        total: int,
        desc: str,
        *,
        stream: IO[str] | None = None,
        mode: Mode | None = None,
        unit: str | None = None,
    ) -> None:
        self.total, self.desc, self.unit = max(int(total), 1), desc, unit
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
        self._dask: threading.Thread | None = None
        if self.mode == "bar":
            self._bar = self._make_bar()

    def _make_bar(self) -> tqdm[Never] | None:
        from tqdm import tqdm

        try:
            return tqdm(
                total=self.total,
                desc=self.desc,
                unit=" " + self.unit if self.unit else "it",
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
        count = f"{self.n}/{self.total}" if self.unit is None else f"{self.n}/{self.total} {self.unit} done"
        self._write(f"{self.desc}: {count} ({pct:.0f} %){post} {when}\n")
        self._lines += 1

    def reset(self, total: int) -> None:
        """Start over for ``total`` units (a runner sets the count of its tasks), the clock too.

        Parameters
        ----------
        total : int
            Units of the step from now on.

        Examples
        --------
        >>> import io
        >>> from piezohyst.progress import Progress
        >>> log = io.StringIO()
        >>> p = Progress(1, "run", stream=log, mode="lines", unit="tasks")
        >>> p.reset(3)
        >>> p.update(3)
        >>> p.close()
        >>> log.getvalue().startswith("run: 3/3 tasks done (100 %) in ")
        True
        """
        self.total, self.n = max(int(total), 1), 0
        self._t0 = time.perf_counter()
        self._last_line, self._last_fraction = -math.inf, 0.0
        if self._bar is not None:  # a new bar for the new total (tqdm's reset would draw it at once)
            with contextlib.suppress(OSError, ValueError):
                self._bar.close()
            self._bar = self._make_bar()

    def follow_dask(self, client: Any, futures: list[Any]) -> bool:
        """On a terminal, show Dask's own progress bar of ``futures`` (drawn from a thread of its
        own, fed by the scheduler of ``client``) instead of the tqdm bar; elsewhere nothing
        changes (plain lines from :meth:`update`, or silence). True when Dask's bar follows them:
        the caller must then hold every future until the run ends (Dask's bar waits for the
        scheduler to know all of its keys, and a released future's key is forgotten).

        Parameters
        ----------
        client : distributed.Client
            The client of the cluster running the futures.
        futures : list of distributed.Future
            The tasks to follow.

        Examples
        --------
        >>> import io
        >>> from piezohyst.progress import Progress
        >>> p = Progress(2, "run", stream=io.StringIO(), mode="lines")
        >>> p.follow_dask(None, [])  # not a terminal: the plain lines stay
        False
        """
        if self.mode != "bar" or not futures or self.stream is None:
            return False
        from distributed.diagnostics.progressbar import TextProgressBar

        if self._bar is not None:  # not drawn yet (its delay): Dask's bar replaces it
            with contextlib.suppress(OSError, ValueError):
                self._bar.close()
            self._bar = None
        stream = self.stream
        desc = self.desc

        class _StreamBar(TextProgressBar):
            # Dask's bar, on our stream (stderr) instead of stdout, with the step's name
            def _draw_bar(self, remaining: int, all: int, **kwargs: Any) -> None:
                frac = (1 - remaining / all) if all else 1.0
                width = 40
                with contextlib.suppress(OSError, ValueError):
                    stream.write(
                        f"\r{desc}: [{'#' * int(width * frac):<{width}}] | {int(100 * frac):3d}% Completed | "
                        f"{self.elapsed:.1f} s"
                    )
                    stream.flush()

            def _draw_stop(self, **kwargs: Any) -> None:
                with contextlib.suppress(OSError, ValueError):
                    stream.write("\n")
                    stream.flush()

        address = client.scheduler.address

        def draw() -> None:
            try:
                _StreamBar(futures, scheduler=address, interval="200ms")  # type: ignore[no-untyped-call]
            except Exception:  # a progress bar never stops the run
                pass

        self._dask = threading.Thread(target=draw, name="piezohyst-progress", daemon=True)
        self._dask.start()
        return True

    def update(self, n: int, **postfix: float) -> None:
        """Record that ``n`` units are done (absolute, not an increment), with named numbers
        to show beside the count (``best=1.2e-7``).

        Parameters
        ----------
        n : int
            Units done so far (clipped to ``total``).
        **postfix : float
            Named numbers shown beside the count.

        Examples
        --------
        >>> import io
        >>> from piezohyst.progress import Progress
        >>> p = Progress(10, "css", stream=io.StringIO(), mode="lines")
        >>> p.update(4, best=1.5)
        >>> p.n
        4
        >>> p.update(99)                                       # absolute, at most total
        >>> p.n
        10
        """
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
        the count and the time taken.

        Examples
        --------
        >>> import io
        >>> from piezohyst.progress import Progress
        >>> log = io.StringIO()
        >>> p = Progress(10, "css", stream=log, mode="lines")
        >>> p.update(4, best=1.5)
        >>> p.close()
        >>> log.getvalue().startswith("css: 4/10 (40 %), best 1.5 in ")
        True
        >>> p.close()                                          # a second close writes nothing
        >>> log.getvalue().count("\\n")
        1
        """
        if self._closed:
            return
        self._closed = True
        if self._dask is not None:  # Dask's bar ends with its futures
            self._dask.join(timeout=2.0)
            self._dask = None
        elif self.mode == "bar" and self._bar is not None:
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
