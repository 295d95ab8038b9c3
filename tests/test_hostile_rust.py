"""Hostile input at the Rust boundary (issue 20): tampered and non-finite states are a
``ParameterError`` naming the slot (never a ``PanicException``), a panic is an
``InternalError`` (a ``PiezohystError``), requests beyond the allocation limit raise
``ResourceLimitError`` (a ``MemoryError``) before allocating, and Ctrl-C stops a long
GIL-free batch within about a second."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from piezohyst import _core
from piezohyst.errors import (
    ComputationError,
    InternalError,
    ParameterError,
    PiezohystError,
    ResourceLimitError,
)


def _preisach(levels: int = 4, memory: int = 16) -> _core.Model:
    w = 0.05 * (1 + np.arange(levels * (levels + 1) // 2))
    row = np.concatenate([[-1.5, 1.5, 0.2, 0.3], w])
    return _core.Model("preisach", [levels, memory], row)


def _pid() -> _core.Controller:
    # kp, ki, kd, tau_d, ts, ff_gain, offset, u_min, u_max
    return _core.Controller("pid", np.array([2e6, 2e9, 0.0, 1e-4, 1e-4, 7e6, 0.0, -20.0, 150.0]))


@pytest.mark.parametrize("bad", [1e9, 17.0, -1.0, 2.5])
def test_tampered_preisach_memory_length_is_a_parameter_error_naming_the_slot(bad):
    m = _preisach()
    state = m.initial_state()
    m.simulate(1.2 * np.sin(0.3 * np.arange(40)), state)
    state[1] = bad
    before = state.copy()
    with pytest.raises(ParameterError, match=r"state \(memory length\)\[1\] = .* must lie within \[0, 16\]") as e:
        m.simulate(np.array([0.3]), state)
    assert e.value.parameter == "state (memory length)" and e.value.index == 1 and e.value.value == bad
    with pytest.raises(PiezohystError, match=r"memory length"):
        m.inverse(np.array([0.1]), state)
    with pytest.raises(Exception, match=r"memory length"):  # `except Exception` catches it (a PanicException did not)
        _core.simulate("preisach", [4, 16], m.params, np.array([0.3]), state)
    np.testing.assert_array_equal(state, before)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_controller_state_is_refused(bad):
    c = _pid()
    state = c.initial_state(0.0)
    z = np.zeros(3)
    c.steps(np.full(3, 1e-6), z, z, z, state)
    state[0] = bad
    with pytest.raises(ParameterError, match=r"state\[0\] = .* is not finite"):
        c.steps(np.full(3, 1e-6), z, z, z, state)


def test_a_panic_is_an_internal_error_not_a_panic_exception():
    with pytest.raises(InternalError, match=r"internal error .*a deliberate panic") as e:
        _core._panic_for_tests()
    assert isinstance(e.value, PiezohystError) and isinstance(e.value, ComputationError)


def _pi_rows(s: int, n: int) -> np.ndarray:
    row = np.concatenate([[0.5], np.linspace(0.0, 1.0, n), np.full(n, 0.1 / n)])
    return np.tile(row, (s, 1))


def test_batch_simulate_beyond_the_limit_raises_before_allocating():
    rows = _pi_rows(10_000, 2)
    v = np.zeros(1_000_000)  # the result would be 80 GB
    with pytest.raises(ResourceLimitError, match=r"batch_simulate.*74\.5 GiB.*PIEZOHYST_MAX_ALLOC_BYTES") as e:
        _core.batch_simulate("pi", [2, 0], rows, v)
    assert isinstance(e.value, MemoryError)


def test_the_limit_is_set_by_the_environment(monkeypatch):
    rows = _pi_rows(10, 2)
    v = np.sin(np.linspace(0, 6, 100))
    assert _core.batch_simulate("pi", [2, 0], rows, v).shape == (10, 100)
    monkeypatch.setenv("PIEZOHYST_MAX_ALLOC_BYTES", "4000")
    with pytest.raises(ResourceLimitError, match=r"10 x 100 float64 values.*limit of 3\.9 KiB \(4000 bytes\)"):
        _core.batch_simulate("pi", [2, 0], rows, v)
    with pytest.raises(ResourceLimitError, match=r"regressors"):
        _core.regressors("pi", [2, 0], rows[0], np.zeros(1000))
    with pytest.raises(ResourceLimitError, match=r"simulate"):
        _core.Model("pi", [2, 0], rows[0]).simulate(np.zeros(1000))
    stage = _core.Stage(_core.virtual_stage_params(), 1e-4, 4, 1e-9)
    with pytest.raises(ResourceLimitError, match=r"closed_loop_batch"):
        stage.closed_loop_batch([_core.Scenario(_pid(), np.zeros(1000))], np.zeros(12))
    monkeypatch.setenv("PIEZOHYST_MAX_ALLOC_BYTES", "lots")
    with pytest.raises(ParameterError, match=r"PIEZOHYST_MAX_ALLOC_BYTES = \"lots\" is not a whole number"):
        _core.batch_simulate("pi", [2, 0], rows, v)


_LONG = {
    # 100,000 operators (MAX_OPERATORS) on a long record: minutes of work without Ctrl-C
    "batch_simulate": """
        rows = np.tile(np.concatenate([[0.5], np.linspace(0, 1, 100_000), np.full(100_000, 1e-6)]), (8, 1))
        v = np.sin(np.linspace(0, 60, 200_000))
        _core.batch_simulate("pi", [100_000, 0], rows, v)
    """,
    "batch_rmse": """
        rows = np.tile(np.concatenate([[0.5], np.linspace(0, 1, 100_000), np.full(100_000, 1e-6)]), (8, 1))
        v = np.sin(np.linspace(0, 60, 200_000))
        _core.batch_rmse("pi", [100_000, 0], rows, v, v)
    """,
    "simulate": """
        row = np.concatenate([[0.5], np.linspace(0, 1, 100_000), np.full(100_000, 1e-6)])
        _core.Model("pi", [100_000, 0], row).simulate(np.sin(np.linspace(0, 60, 2_000_000)))
    """,
}


@pytest.mark.parametrize("call", list(_LONG))
def test_ctrl_c_stops_a_long_rust_call_within_a_second(call):
    code = "import sys, numpy as np\nfrom piezohyst import _core\nprint('started', flush=True)\n"
    code += textwrap.dedent(_LONG[call]) + "print('finished', flush=True)\n"
    p = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy()
    )
    try:
        assert p.stdout is not None and p.stdout.readline().strip() == "started"
        time.sleep(1.5)  # inside the Rust call by now
        assert p.poll() is None, "the call finished before Ctrl-C: make it longer"
        t0 = time.monotonic()
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=30)
        latency = time.monotonic() - t0
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert "finished" not in out
    assert "KeyboardInterrupt" in err, err
    assert p.returncode != 0
    # at most a second of latency; the bound leaves room for a busy two-core machine
    # (before the fix, Ctrl-C waited for the whole call: minutes)
    assert latency < 3.0, f"{call}: Ctrl-C took {latency:.2f} s"


def test_operator_level_and_population_bounds_name_the_range():
    from piezohyst.optimize import minimize

    with pytest.raises(ParameterError, match=r"n = 100001 must lie within \[0, 100000\]"):
        _core.Model("pi", [100_001, 0], np.zeros(1 + 2 * 100_001))
    with pytest.raises(ParameterError, match=r"levels = 1001 must lie within \[1, 1000\]"):
        _core.family_sizes("preisach", [1001, 8])
    with pytest.raises(ParameterError, match=r"population_size = 1000000 must lie within \[4, 100000\]"):
        minimize(lambda x: float(np.sum(x**2)), [(-1, 1), (-1, 1)], population_size=1_000_000)
