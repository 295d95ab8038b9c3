import signal

import numpy as np
import pytest
from hypothesis import settings

settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True)
settings.load_profile("ci")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def random_walk(rng, n, scale=1.0):
    """A bounded random input with many reversals."""
    return scale * np.cumsum(rng.normal(size=n)) / np.sqrt(n)


@pytest.fixture(autouse=True, scope="session")
def _stop_signals_not_ignored():
    """The suite raises SIGHUP at commands and checks they stop; a command keeps a signal that
    was ignored when it started (``nohup``: by design, cli/stops.py). Run under ``nohup``, the
    suite would inherit an ignored SIGHUP: it starts from the default disposition instead."""
    if hasattr(signal, "SIGHUP") and signal.getsignal(signal.SIGHUP) is signal.SIG_IGN:
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
    yield
