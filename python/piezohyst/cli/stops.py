"""Hard stops of the command line: SIGTERM and SIGHUP stop a command the way Ctrl-C (SIGINT)
does.

While a command runs (:func:`handled`, entered by :func:`piezohyst.cli.main.main`), the three
signals raise :class:`Interrupted`, a ``KeyboardInterrupt``: every path that keeps the best
result so far on Ctrl-C (the population optimizers, tuning; the Rust batches, which poll
Python's signal handlers every 50 ms and stop their workers) keeps it on a termination or a
hang-up too. The command then exits with ``128 + signal``: 130 (SIGINT), 143 (SIGTERM), 129
(SIGHUP), saying what was kept. A signal that was ignored when the command started (``nohup``,
a background job's SIGINT) stays ignored.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType

__all__ = ["Interrupted", "describe", "exit_code", "handled", "received"]

#: The signals that stop a command, those this platform has.
STOP_SIGNALS = tuple(getattr(signal, s) for s in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, s))

#: The signals received while :func:`handled` was active, in order.
_received: list[int] = []


class Interrupted(KeyboardInterrupt):
    """A stop signal (SIGINT, SIGTERM, SIGHUP) arrived; ``signum`` says which. A
    ``KeyboardInterrupt``, so whatever keeps the best result on Ctrl-C keeps it here."""

    def __init__(self, signum: int) -> None:
        super().__init__()
        self.signum = signum

    def __repr__(self) -> str:
        return f"Interrupted({describe(self.signum)})"


def describe(signum: int) -> str:
    """``Ctrl-C (SIGINT)``, ``SIGTERM``, ``SIGHUP``: how a message names the signal."""
    try:
        name = signal.Signals(signum).name
    except ValueError:
        name = f"signal {signum}"
    return "Ctrl-C (SIGINT)" if name == "SIGINT" else name


def received() -> int | None:
    """The first stop signal received while the command ran, or ``None``."""
    return _received[0] if _received else None


def exit_code() -> int:
    """The command's exit code after a stop: ``128 + signal`` (130 when none was recorded, as
    for a ``KeyboardInterrupt`` raised without a signal)."""
    return 128 + (received() or signal.SIGINT)


def _raise(signum: int, frame: FrameType | None) -> None:
    _received.append(signum)
    raise Interrupted(signum)


@contextlib.contextmanager
def handled() -> Iterator[None]:
    """Within the block, SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted` (only in the
    main thread, where Python runs signal handlers; a signal ignored before stays ignored);
    the handlers before are put back after."""
    _received.clear()
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved: dict[int, Callable[[int, FrameType | None], object] | int | None] = {}
    try:
        for s in STOP_SIGNALS:
            h = signal.getsignal(s)
            if h is signal.SIG_IGN or h is None:
                continue
            saved[s] = h
            signal.signal(s, _raise)
        yield
    finally:
        for s, h in saved.items():
            signal.signal(s, h)
