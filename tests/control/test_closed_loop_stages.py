"""Closed loops over many stages (issue 16): ``closed_loop_batch_stages`` runs one controller,
packed for the nominal stage, on many parameter rows in one Rust call; each row's figures are
those of the existing one-stage kernels, and rows are independent of one another."""

import numpy as np
import pytest

from piezohyst import PID, SMC, VelocityObserver, _core, virtual_stage
from piezohyst.control.simulation import closed_loop_batch_stages, closed_loop_perturbed
from piezohyst.errors import ParameterError

STAGE = virtual_stage()
T = np.arange(0, 0.05, STAGE.sample_time)
REF = 8e-6 + 5e-6 * np.sin(2 * np.pi * 20 * T)
SKIP = 100


def rows(n, seed=0):
    rng = np.random.default_rng(seed)
    p = np.tile(STAGE.core_params(), (n, 1))
    p[:, 0] *= rng.uniform(0.9, 1.1, n)  # mass
    p[:, 2] *= rng.uniform(0.8, 1.2, n)  # stiffness
    p[:, 3] *= rng.uniform(0.95, 1.05, n)  # tem
    return p


@pytest.mark.parametrize(
    "controller",
    [PID(kp=2e6, ki=2e9), SMC(STAGE.params, kp=1e6, kv=2e3, ks=20.0, phi=0.01, observer=VelocityObserver(300.0))],
)
def test_nominal_row_equals_the_one_stage_tracking_kernel_to_the_bit(controller):
    seeds = np.array([11, 12, 13], dtype=np.uint64)
    m = closed_loop_batch_stages(STAGE, controller, REF, np.tile(STAGE.core_params(), (3, 1)), seeds, skip=SKIP)
    v = np.gradient(REF, STAGE.sample_time)
    a = np.gradient(v, STAGE.sample_time)
    spec = controller.core(STAGE)
    ref = STAGE.compiled.closed_loop_batch_tracking(
        [(spec, REF, v, a, int(s)) for s in seeds], STAGE.rest_state(), SKIP
    )
    assert np.array_equal(m, ref)
    assert m[0, 0] != m[1, 0]  # the seeds matter (sensor noise)


def test_each_row_is_independent_of_the_others():
    p, seeds = rows(12), np.arange(100, 112, dtype=np.uint64)
    c = PID(kp=2e6, ki=2e9)
    whole = closed_loop_batch_stages(STAGE, c, REF, p, seeds, skip=SKIP)
    parts = np.vstack(
        [closed_loop_batch_stages(STAGE, c, REF, p[i : i + 1], seeds[i : i + 1], skip=SKIP) for i in range(12)]
    )
    assert np.array_equal(whole, parts)
    assert np.unique(whole[:, 0]).size == 12  # the parts differ


def test_a_perturbed_run_replays_with_its_signals():
    p, seeds = rows(4, seed=3), np.array([1, 2, 3, 4], dtype=np.uint64)
    c = PID(kp=2e6, ki=2e9)
    m = closed_loop_batch_stages(STAGE, c, REF, p, seeds, skip=SKIP)
    for j in range(4):
        r = closed_loop_perturbed(STAGE, c, REF, p[j], int(seeds[j]), skip=SKIP)
        assert r.metrics["rmse"] == pytest.approx(m[j, 0], rel=1e-12)
        assert r.metrics["max_error"] == pytest.approx(m[j, 1], rel=1e-12)
    # the plant differs from the nominal one: so does the run
    nominal = closed_loop_perturbed(STAGE, c, REF, STAGE.core_params(), int(seeds[0]), skip=SKIP)
    assert nominal.metrics["rmse"] != pytest.approx(m[0, 0], rel=1e-6)


def test_a_stiffer_part_tracks_worse_under_the_same_pid():
    # PID gains tuned for the nominal stage: a 30 % stiffer part has 30 % less static gain, so
    # the integrator lags more on the same sine
    p = np.tile(STAGE.core_params(), (2, 1))
    p[1, 2] *= 1.3
    m = closed_loop_batch_stages(STAGE, PID(kp=2e6, ki=2e9), REF, p, np.zeros(2, dtype=np.uint64), skip=SKIP)
    assert m[1, 0] > 1.1 * m[0, 0]


def test_bad_rows_and_seeds_are_refused_by_name():
    c = PID(kp=2e6, ki=2e9)
    p = rows(3)
    p[2, 0] = -1.0
    with pytest.raises(ParameterError, match=r"params\[2\]"):
        closed_loop_batch_stages(STAGE, c, REF, p, np.zeros(3, dtype=np.uint64))
    with pytest.raises(ParameterError, match="one seed per row"):
        closed_loop_batch_stages(STAGE, c, REF, rows(3), np.zeros(2, dtype=np.uint64))
    with pytest.raises(ParameterError, match=r"expected \(S, "):
        closed_loop_batch_stages(STAGE, c, REF, np.ones((2, 5)), np.zeros(2, dtype=np.uint64))
    with pytest.raises(ParameterError, match="seeds"):
        closed_loop_batch_stages(STAGE, c, REF, rows(2), np.array([-1, 2]))
    q = rows(2)
    q[1, 3] = np.nan
    with pytest.raises(ParameterError, match=r"params\[1\]\[3\]"):
        closed_loop_batch_stages(STAGE, c, REF, q, np.zeros(2, dtype=np.uint64))
    with pytest.raises(ParameterError, match="skip"):
        closed_loop_batch_stages(STAGE, c, REF, rows(2), np.zeros(2, dtype=np.uint64), skip=REF.size)


def test_an_unaligned_reference_runs():
    # arrays unpickled from a Dask message can sit at an odd byte offset: the entry point copies
    # them into aligned memory rather than refuse them
    buf = bytearray(REF.size * 8 + 1)
    odd = np.frombuffer(buf, dtype=np.float64, count=REF.size, offset=1)
    odd[:] = REF
    assert not odd.flags.aligned
    c = PID(kp=2e6, ki=2e9)
    seeds = np.zeros(2, dtype=np.uint64)
    assert np.array_equal(
        closed_loop_batch_stages(STAGE, c, odd, rows(2), seeds), closed_loop_batch_stages(STAGE, c, REF, rows(2), seeds)
    )
    assert _core.STAGE_PARAM_LEN == STAGE.core_params().size
