"""Where the tasks run: in this process (``serial``), on an embedded Dask ``LocalCluster`` of
worker processes (``local``, the default) or on an existing cluster (``tcp://HOST:PORT``).

The thread plan: a task spends its time in the Rust core, whose rayon pool takes
``RAYON_NUM_THREADS`` threads (default: every core). A local cluster of ``W`` worker processes,
each running one task at a time, gives each worker ``RAYON_NUM_THREADS = cores // W`` (at least
1; an explicit ``RAYON_NUM_THREADS`` in the environment wins), so workers × Rust threads = the
cores and the machine is never oversubscribed. A ``tcp://`` cluster's workers keep their own
environment: start them with ``--nthreads 1`` and ``RAYON_NUM_THREADS`` set to the cores each may
use.

Nothing here imports ``distributed`` until a cluster is started: ``import piezohyst.fleet`` is
cheap and the ``serial`` runner needs no Dask at all.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import itertools
import logging
import os
import secrets
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import ParameterError
from ..progress import Progress

__all__ = ["ClusterPlan", "Outcome", "Runner", "plan", "runner", "usable_cores"]


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity), at least 1.

    Returns
    -------
    int

    Examples
    --------
    >>> import os
    >>> from piezohyst.fleet import usable_cores
    >>> 1 <= usable_cores() <= (os.cpu_count() or 1)
    True
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _env_threads(env: dict[str, str]) -> int | None:
    raw = env.get("RAYON_NUM_THREADS")
    if raw is None or raw.strip() == "":
        return None
    try:
        n = int(raw)
    except ValueError:
        raise ParameterError(f"RAYON_NUM_THREADS = '{raw}' must be a whole number of threads >= 1") from None
    if n < 1:
        raise ParameterError(f"RAYON_NUM_THREADS = '{raw}' must be a whole number of threads >= 1")
    return n


@dataclass(frozen=True)
class ClusterPlan:
    """Where and how wide the tasks run.

    ``scheduler``: ``"serial"`` (this process, no Dask), ``"local"`` (an embedded
    ``LocalCluster``) or a ``tcp://`` / ``tls://`` address of a running ``dask scheduler``.
    ``workers``: local worker processes (1 for serial, ``None`` for an existing cluster: its own).
    ``rust_threads``: ``RAYON_NUM_THREADS`` given to each local worker (``None``: the workers' own).

    Parameters
    ----------
    scheduler : str
        ``"serial"``, ``"local"`` or a scheduler's address.
    workers : int or None
        Worker processes of a local cluster (1 for serial, None for an existing cluster).
    rust_threads : int or None
        Rust threads per worker (None: the existing cluster's own setting).

    Examples
    --------
    >>> from piezohyst.fleet import plan
    >>> plan("local", 2, cores=2, env={})
    ClusterPlan(scheduler='local', workers=2, rust_threads=1)
    """

    scheduler: str
    workers: int | None
    rust_threads: int | None

    def describe(self) -> str:
        """Where the tasks run, in words (the CLI's summary line and ``cluster`` JSON field).

        Returns
        -------
        str

        Examples
        --------
        >>> from piezohyst.fleet import plan
        >>> plan("local", 2, cores=2, env={}).describe()
        'local cluster of 2 worker process(es) x 1 Rust thread(s)'
        >>> plan("tcp://10.0.0.5:8786").describe()
        'cluster at tcp://10.0.0.5:8786'
        """
        if self.scheduler == "serial":
            return f"serial (this process, {self.rust_threads} Rust thread(s))"
        if self.scheduler == "local":
            return f"local cluster of {self.workers} worker process(es) x {self.rust_threads} Rust thread(s)"
        return f"cluster at {self.scheduler}"


def plan(
    scheduler: str = "local",
    workers: int | None = None,
    *,
    cores: int | None = None,
    env: dict[str, str] | None = None,
) -> ClusterPlan:
    """The cluster to use and its thread plan (see the module's docstring).

    Parameters
    ----------
    scheduler : str, optional
        ``"local"`` (default: an embedded ``LocalCluster``), ``"serial"`` (this process) or the
        ``tcp://HOST:PORT`` address of a running ``dask scheduler``.
    workers : int, optional
        Local worker processes (default: the cores); not for ``serial`` (1) nor an address.
    cores : int, optional
        The cores to plan for (default: :func:`usable_cores`).
    env : dict, optional
        The environment to read ``RAYON_NUM_THREADS`` from (default ``os.environ``): when set,
        it is each worker's Rust threads.

    Returns
    -------
    ClusterPlan

    Raises
    ------
    ParameterError
        A bad scheduler, worker count or ``RAYON_NUM_THREADS``.

    Examples
    --------
    >>> plan("local", 2, cores=2, env={})
    ClusterPlan(scheduler='local', workers=2, rust_threads=1)
    >>> plan("local", 1, cores=2, env={})
    ClusterPlan(scheduler='local', workers=1, rust_threads=2)
    >>> plan("local", None, cores=4, env={"RAYON_NUM_THREADS": "1"})
    ClusterPlan(scheduler='local', workers=4, rust_threads=1)
    """
    n_cores = usable_cores() if cores is None else cores
    environ = dict(os.environ) if env is None else env
    threads = _env_threads(environ)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ParameterError(f"--workers = {workers!r} must be a whole number >= 1")
    if scheduler == "serial":
        if workers not in (None, 1):
            raise ParameterError(f"--workers = {workers} does not apply to --scheduler serial (one process)")
        return ClusterPlan("serial", 1, threads or n_cores)
    if scheduler == "local":
        w = n_cores if workers is None else workers
        return ClusterPlan("local", w, threads or max(1, n_cores // w))
    if scheduler.startswith(("tcp://", "tls://", "inproc://")):
        if workers is not None:
            raise ParameterError(
                f"--workers = {workers} applies to --scheduler local; the cluster at {scheduler} has its own workers"
            )
        return ClusterPlan(scheduler, None, None)
    raise ParameterError(
        f"--scheduler = '{scheduler}' must be 'local', 'serial' or the address of a running dask scheduler "
        "(tcp://HOST:PORT)"
    )


@dataclass(frozen=True)
class Outcome:
    """One task's end: its key and either its ``value`` or the ``error`` (one line) that ended it.

    Parameters
    ----------
    key : str
        The task's key, as given to :meth:`Runner.run`.
    value : object, optional
        What the task returned.
    error : str, optional
        ``"ExceptionType: message"`` when the task raised.

    Examples
    --------
    >>> from piezohyst.fleet import Outcome
    >>> Outcome("t1", 42).error is None, Outcome("t2", error="ValueError: bad").value
    (True, None)
    """

    key: str
    value: Any = None
    error: str | None = None


class Runner:
    """Runs tasks ``fn(*args)`` and yields their :class:`Outcome` as they complete (any order).

    ``broadcast(obj)`` gives a handle to pass in the tasks' arguments instead of ``obj`` (sent to
    each worker once). A task that raises ends as an ``Outcome`` with ``error``; the others run on.

    This class runs the tasks in this process, one after the other (``--scheduler serial``);
    :func:`runner` gives the one of a plan (a Dask cluster's for ``local`` and addresses).

    Parameters
    ----------
    plan : ClusterPlan
        The plan it runs (``serial`` for this class itself).

    Examples
    --------
    >>> from piezohyst.fleet import Runner, plan
    >>> run = Runner(plan("serial", env={}))
    >>> [(o.key, o.value) for o in run.run(divmod, [("a", (7, 2)), ("b", (9, 3))])]
    [('a', (3, 1)), ('b', (3, 0))]
    """

    plan: ClusterPlan

    def __init__(self, plan: ClusterPlan) -> None:
        self.plan = plan

    @property
    def workers(self) -> int:
        """Worker processes running tasks now."""
        return 1

    def broadcast(self, obj: Any) -> Any:
        """A handle for ``obj`` to pass in the tasks' arguments: on a cluster it is sent to each
        worker once (not with every task); in this process it is ``obj`` itself.

        Parameters
        ----------
        obj : object
            A (picklable) object many tasks take, such as a robustness problem.

        Returns
        -------
        object
            What to pass to the tasks instead of ``obj``.

        Examples
        --------
        >>> from piezohyst.fleet import Runner, plan
        >>> run = Runner(plan("serial", env={}))
        >>> table = {"a": 1}
        >>> run.broadcast(table) is table
        True
        """
        return obj

    def run(
        self, fn: Callable[..., Any], tasks: Sequence[tuple[str, tuple[Any, ...]]], progress: Progress | None = None
    ) -> Iterator[Outcome]:
        """Run ``fn(*args)`` for each ``(key, args)`` of ``tasks``; yield each :class:`Outcome`
        as it completes (any order on a cluster, in order here).

        Parameters
        ----------
        fn : callable
            The task (a module-level function: a cluster pickles it by name).
        tasks : sequence of (str, tuple)
            Each task's key and arguments.
        progress : piezohyst.progress.Progress, optional
            The display to update (its total is set to the number of tasks).

        Yields
        ------
        Outcome
            Each task's value, or its error (the other tasks run on).

        Examples
        --------
        >>> import math
        >>> from piezohyst.fleet import Runner, plan
        >>> outs = Runner(plan("serial", env={})).run(math.sqrt, [("ok", (4.0,)), ("bad", (-1.0,))])
        >>> [(o.key, o.value, o.error) for o in outs]
        [('ok', 2.0, None), ('bad', None, 'ValueError: math domain error')]
        """
        if progress is not None:
            progress.reset(len(tasks))
        done = 0
        for key, args in tasks:
            try:
                out = Outcome(key, fn(*args))
            except Exception as e:  # a task's failure is its outcome, not the run's
                out = Outcome(key, error=_one_line(e))
            done += 1
            if progress is not None:
                progress.update(done)
            yield out
        if progress is not None:
            progress.close()


def _one_line(e: BaseException) -> str:
    msg = " ".join(str(e).split())
    return f"{type(e).__name__}: {msg}" if msg else type(e).__name__


class _DaskRunner(Runner):
    """Tasks on a Dask cluster through ``client`` (or the future of one still starting)."""

    def __init__(self, plan: ClusterPlan, client: Any) -> None:
        super().__init__(plan)
        self._client = client
        self._run_id = secrets.token_hex(4)
        self._count = itertools.count()

    @property
    def client(self) -> Any:
        """The Dask client, once the cluster has started."""
        if isinstance(self._client, concurrent.futures.Future):
            self._client = self._client.result()[1]
        return self._client

    @property
    def workers(self) -> int:
        return len(self.client.scheduler_info(n_workers=-1)["workers"])

    def broadcast(self, obj: Any) -> Any:
        return self.client.scatter(obj, broadcast=True, hash=False)

    def run(
        self, fn: Callable[..., Any], tasks: Sequence[tuple[str, tuple[Any, ...]]], progress: Progress | None = None
    ) -> Iterator[Outcome]:
        from distributed import as_completed

        batch = next(self._count)
        # unique keys per run: a tcp:// cluster may hold another client's (or an earlier run's) keys
        futures = {
            self.client.submit(fn, *args, key=f"{key}-{self._run_id}-{batch}-{i}", pure=False): key
            for i, (key, args) in enumerate(tasks)
        }
        hold = False  # release each future once its result is here, unless Dask's bar follows them
        if progress is not None:
            progress.reset(len(tasks))
            hold = progress.follow_dask(self.client, list(futures))
        done = 0
        try:
            for f in as_completed(list(futures)):  # type: ignore[no-untyped-call]
                key = futures[f]
                if f.status == "error":
                    exc = f.exception()
                    out = Outcome(key, error=_one_line(exc))
                elif f.status == "cancelled":
                    out = Outcome(key, error="cancelled")
                else:
                    out = Outcome(key, f.result())
                if not hold:
                    f.release()
                done += 1
                if progress is not None:
                    progress.update(done)
                yield out
        finally:
            pending = [f for f in futures if not f.done()]
            if pending:
                self.client.cancel(pending)
            if progress is not None:
                progress.close()


#: Modules every local worker starts with (imported once by the fork server, see :func:`runner`):
#: what a robustness chunk needs. A command adds its own (fleet identify: identify's modules).
PRELOAD = ("numpy", "piezohyst", "piezohyst.fleet")


def _start_method(preload: Sequence[str]) -> str:
    """``forkserver`` where the platform has it, started now with Dask and ``preload`` imported
    once in the server: each worker is then a fork of an interpreter that has Dask, NumPy and
    piezohyst loaded, which takes a fraction of a second where a spawned worker imports them all
    again (seconds on a busy 2-core machine), and stops as fast. Started before this process
    imports Dask itself, the server's imports run beside ours. The server imports modules only (no
    Rust thread pool, no event loop runs in it), so forking it is safe. ``spawn`` elsewhere."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():  # pragma: no cover - not POSIX
        return "spawn"
    import multiprocessing.forkserver

    multiprocessing.get_context("forkserver").set_forkserver_preload(["distributed", *PRELOAD, *preload])
    multiprocessing.forkserver.ensure_running()
    return "forkserver"


@contextlib.contextmanager
def runner(cluster: ClusterPlan, preload: Sequence[str] = ()) -> Iterator[Runner]:
    """A :class:`Runner` for ``cluster``: this process, a fresh ``LocalCluster`` (closed on exit,
    workers and all) or a client of an existing scheduler (the cluster is left running).

    A local cluster's workers start from a fork server that has imported :data:`PRELOAD` and
    ``preload`` (the modules of the tasks to come).

    Parameters
    ----------
    cluster : ClusterPlan
        Where the tasks run (:func:`plan`).
    preload : sequence of str, optional
        Modules a local cluster's workers import before their first task.

    Yields
    ------
    Runner
        The runner; a local cluster starts in the background and its first use waits for it.

    Raises
    ------
    ParameterError
        No scheduler answers at the address, or no worker joins it within 60 s.

    Examples
    --------
    >>> from piezohyst.fleet import plan, runner
    >>> with runner(plan("serial", env={})) as run:
    ...     [o.value for o in run.run(pow, [("a", (2, 10))])]
    [1024]
    """
    if cluster.scheduler == "serial":
        yield Runner(cluster)
        return
    if cluster.scheduler == "local":
        assert cluster.workers is not None and cluster.rust_threads is not None  # plan() sets both
        env = {"RAYON_NUM_THREADS": str(cluster.rust_threads)}
        method = _start_method(preload)

        def start() -> tuple[Any, Any]:
            import dask
            from distributed import Client, LocalCluster

            config = {
                "distributed.worker.multiprocessing-method": method,
                # the workers' statistical profiler samples every task's stack 100 times a second:
                # ~2 % of a fleet task's CPU (median task CPU 0.53 s -> 0.52 s), for a dashboard
                # the embedded cluster does not show
                "distributed.worker.profile.enabled": False,
            }
            with dask.config.set(config):
                lc = LocalCluster(  # type: ignore[no-untyped-call]
                    n_workers=cluster.workers,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address="127.0.0.1:0",  # its HTTP server on a free loopback port, not 8787
                    silence_logs=logging.CRITICAL,  # failures reach the caller as outcomes
                    env=env,
                )
            try:
                return lc, Client(lc)  # type: ignore[no-untyped-call]
            except BaseException:
                lc.close()
                raise

        # the cluster starts in the background while the caller prepares its tasks; the first
        # use of the runner's client waits for it
        with concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="piezohyst-cluster") as pool:
            started = pool.submit(start)
            try:
                yield _DaskRunner(cluster, started)
            finally:
                try:
                    lc, client = started.result()
                except Exception:  # it never started: nothing to close (the error was the caller's to see)
                    pass
                else:
                    client.close()
                    lc.close()
        return
    from distributed import Client

    try:
        client = Client(cluster.scheduler, timeout="10s")  # type: ignore[no-untyped-call]
    except OSError as e:
        raise ParameterError(f"--scheduler = '{cluster.scheduler}': no dask scheduler answers there ({e})") from None
    with client:
        try:
            client.wait_for_workers(1, timeout=60)
        except TimeoutError:
            raise ParameterError(f"--scheduler = '{cluster.scheduler}': no worker joined within 60 s") from None
        yield _DaskRunner(cluster, client)
