"""Where tasks run (issue 16, item 3): the thread plan (workers x Rust threads = the cores), the
serial runner, and an embedded LocalCluster of processes whose results equal the serial ones to
the bit, with a failing task reported as its own outcome."""

import io
import os

import numpy as np
import pytest

from piezohyst import PID, virtual_stage
from piezohyst.errors import ParameterError
from piezohyst.fleet import RobustnessProblem, Runner, parse_perturbations, plan, robustness, runner
from piezohyst.progress import Progress


def test_the_plan_never_oversubscribes_the_cores():
    assert plan("local", None, cores=2, env={}) == plan("local", 2, cores=2, env={})
    assert plan("local", 2, cores=2, env={}).rust_threads == 1
    assert plan("local", 1, cores=2, env={}).rust_threads == 2
    assert plan("local", 3, cores=8, env={}).rust_threads == 2
    assert plan("local", 4, cores=2, env={}).rust_threads == 1  # more workers than cores: 1 thread each
    assert plan("local", 1, cores=2, env={"RAYON_NUM_THREADS": "1"}).rust_threads == 1  # explicit wins
    assert plan("serial", None, cores=2, env={}).rust_threads == 2
    tcp = plan("tcp://127.0.0.1:8786", None, cores=2, env={})
    assert tcp.workers is None and tcp.rust_threads is None


@pytest.mark.parametrize(
    "scheduler, workers, env, match",
    [
        ("local", 0, {}, "--workers = 0"),
        ("serial", 2, {}, "does not apply to --scheduler serial"),
        ("tcp://127.0.0.1:1", 2, {}, "applies to --scheduler local"),
        ("lokal", None, {}, "--scheduler = 'lokal'"),
        ("local", 2, {"RAYON_NUM_THREADS": "two"}, "RAYON_NUM_THREADS = 'two'"),
        ("local", 2, {"RAYON_NUM_THREADS": "0"}, "RAYON_NUM_THREADS = '0'"),
    ],
)
def test_bad_plans_are_refused_by_name(scheduler, workers, env, match):
    with pytest.raises(ParameterError, match=match):
        plan(scheduler, workers, cores=2, env=env)


def boom(x):
    if x == 2:
        raise ValueError(f"record {x} is bad")
    return x * 10


def worker_env(_):
    import dask

    return os.environ.get("RAYON_NUM_THREADS"), os.getpid(), dask.config.get("distributed.worker.profile.enabled")


def test_the_serial_runner_reports_a_failing_task_and_runs_the_rest(capsys):

    stream = io.StringIO()
    outs = list(
        Runner(plan("serial", env={})).run(
            boom, [(f"t{i}", (i,)) for i in range(4)], Progress(1, "p", stream=stream, mode="lines", unit="tasks")
        )
    )
    assert [(o.key, o.value, o.error) for o in outs] == [
        ("t0", 0, None),
        ("t1", 10, None),
        ("t2", None, "ValueError: record 2 is bad"),
        ("t3", 30, None),
    ]
    lines = stream.getvalue().splitlines()
    assert "\r" not in stream.getvalue() and lines[-1].startswith("p: 4/4 tasks done (")


def problem():
    stage = virtual_stage()
    t = np.arange(0, 0.04, stage.sample_time)
    ref = 8e-6 + 5e-6 * np.sin(2 * np.pi * 25 * t)
    return RobustnessProblem(
        stage, PID(kp=2e6, ki=2e9), ref, 80, tuple(parse_perturbations("mass=±10%,stiffness=±20%")), 3
    )


@pytest.mark.parametrize("workers", [2, 1])
def test_a_local_cluster_of_processes_gives_the_serial_result_to_the_bit(workers):
    p = problem()
    serial = robustness(p, 90, Runner(plan("serial", env={})), chunk=20)
    cluster = plan("local", workers, cores=2, env={})
    with runner(cluster) as run:
        assert run.workers == workers
        bar = io.StringIO()  # Dask's own progress bar when the display is a bar
        tasks = [(f"e{i}", (i,)) for i in range(6)]
        envs = {o.value for o in run.run(worker_env, tasks, Progress(1, "t", stream=bar, mode="bar"))}
        assert {e[0] for e in envs} == {str(2 // workers)}  # RAYON_NUM_THREADS = cores // workers
        assert all(e[1] != os.getpid() for e in envs)  # worker processes, not this one
        assert {e[2] for e in envs} == {False}  # no statistical profiler sampling the tasks
        res = robustness(p, 90, run, chunk=20)
        outs = {o.key: o for o in run.run(boom, [(f"t{i}", (i,)) for i in range(4)])}
    assert np.array_equal(res.metrics, serial.metrics) and np.array_equal(res.factors, serial.factors)
    assert res.to_dict()["percentiles"] == serial.to_dict()["percentiles"]
    assert outs["t2"].error == "ValueError: record 2 is bad" and outs["t3"].value == 30
    assert "\rt: [########################################] | 100% Completed |" in bar.getvalue()
