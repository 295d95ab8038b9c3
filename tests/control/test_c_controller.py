"""A C function in the loop (issue 19): a shared library's step called through ctypes from the
Rust loop's slow path, bit for bit the same loop as the same law written in Python."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

import piezohyst as ph
from piezohyst.control.user import STEP_SIGNATURE, CController
from piezohyst.errors import ComputationError, ParameterError

STAGE = ph.virtual_stage()
TS = STAGE.sample_time
KP, KI, FF = 4e4, 1.4e10, 1 / STAGE.params.static_gain

C_SOURCE = f"""
typedef struct {{ double integral; double first; }} pi_state;
void pi_reset(void *s, double measured) {{ ((pi_state *)s)->first = measured; }}
double pi_step(void *s, double r, double y, double v, double a) {{
    pi_state *st = (pi_state *)s;
    double e = r - y;
    st->integral += {TS!r} * e;
    double u = {FF!r} * r + {KP!r} * e + {KI!r} * st->integral;
    return u < -20.0 ? -20.0 : (u > 150.0 ? 150.0 : u);
}}
double bad_step(void *s, double r, double y, double v, double a) {{ return 0.0 / 0.0; }}
"""


class PythonPI:
    """The same law in Python."""

    def __init__(self) -> None:
        self.integral = 0.0

    def reset(self, measured: float) -> None:
        self.integral = 0.0

    def step(self, r: float, y: float) -> float:
        e = r - y
        self.integral += TS * e
        u = FF * r + KP * e + KI * self.integral
        return -20.0 if u < -20.0 else (150.0 if u > 150.0 else u)


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler")
    d = tmp_path_factory.mktemp("cctl")
    (d / "pi.c").write_text(C_SOURCE)
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(d / "libpi.so"), str(d / "pi.c")], check=True)
    return d / "libpi.so"


def test_c_controller_runs_the_loop_as_the_python_one(library):
    _, ref = ph.sine(20, 5e-6, 0.3, 1 / TS, offset=8e-6)
    c = CController.from_library(library, "pi_step", "pi_reset", state_size=16)
    res = ph.closed_loop(STAGE, c, ref, rng=3)
    py = ph.closed_loop(STAGE, PythonPI(), ref, rng=3)
    assert np.array_equal(res.position, py.position) and np.array_equal(res.command, py.command)
    # a second run starts from a zeroed state: the same bits again
    assert np.array_equal(ph.closed_loop(STAGE, c, ref, rng=3).position, res.position)
    assert ph.track(c, ref, stage=STAGE, rng=3, skip=0.1).metrics["rmse"] < 0.1e-6


def test_c_controller_from_a_cfunctype():
    calls = []

    @STEP_SIGNATURE
    def hold(state, r, y, v, a):  # a ctypes callback stands in for a C function
        calls.append(v)
        return 60.0

    out = ph.closed_loop(STAGE, CController(hold), np.full(50, 8e-6), rng=1)
    assert np.all(out.command == 60.0) and len(calls) == 50


def test_c_controller_errors(library):
    with pytest.raises(ParameterError, match="step = 'nope': no such function"):
        CController.from_library(library, "nope")
    with pytest.raises(ParameterError, match="cannot be loaded"):
        CController.from_library(library.parent / "missing.so", "pi_step")
    bad = CController.from_library(library, "bad_step")
    with pytest.raises(ComputationError, match="the C controller returned nan"):
        bad.step(8e-6, 8e-6)
    with pytest.raises(RuntimeError, match="the controller's step raised at sample 0") as info:
        ph.closed_loop(STAGE, bad, np.full(20, 8e-6), rng=1)
    assert isinstance(info.value.__cause__, ComputationError)
