"""``piezohyst fleet identify``: ``piezohyst identify`` over many records on a Dask cluster.

Each record is one task that runs :func:`piezohyst.cli.identify._identify` itself (the code
behind ``piezohyst identify``) with the same options, so a record's model file is the one the
serial command writes for it. The task writes into a scratch directory of its worker and
returns the file's text; this process writes ``DIR/<stem>.json`` atomically (a temporary
sibling, then ``os.replace``) as results arrive, so an interrupted fleet leaves only whole
files and a rerun skips them (resume).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import math
import os
import socket
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._io import write_atomic
from ..errors import PiezohystError
from ..progress import Mode, Progress
from .common import _Fail, _Parser
from .identify import _identify, _identify_options

__all__: list[str] = []

#: Options of ``piezohyst identify`` that fleet sets itself, per record (not manifest columns).
_OWN = frozenset({"data", "out", "plot", "force", "json", "progress", "sub_debug"})


def _cluster_options(p: argparse.ArgumentParser) -> None:
    """``--scheduler --workers --progress``, shared by ``fleet identify`` and ``robustness``."""
    p.add_argument(
        "--scheduler",
        metavar="local|serial|tcp://HOST:PORT",
        default="local",
        help="where the tasks run: 'local' (default) an embedded Dask LocalCluster of --workers processes, "
        "closed at the end; 'serial' this process, no Dask; tcp://HOST:PORT a running 'dask scheduler' "
        "with its 'dask worker's (start them with --nthreads 1 and RAYON_NUM_THREADS = the cores each may use)",
    )
    p.add_argument(
        "--workers",
        metavar="N",
        type=int,
        help="local cluster: worker processes (default: the usable cores); each runs one task at a time with "
        "RAYON_NUM_THREADS = cores // N Rust threads (an explicit RAYON_NUM_THREADS wins), so workers x "
        "threads = the cores",
    )
    p.add_argument(
        "--progress",
        choices=("auto", "bar", "lines", "none"),
        default="auto",
        help="progress on stderr: auto (default) Dask's progress bar on a terminal, plain lines otherwise "
        "(no carriage returns); bar, lines or none",
    )


def _progress(args: argparse.Namespace, prog: str, total: int, unit: str) -> Progress:
    """The run's progress display for ``--progress`` (``auto``: by the stream; ``--quiet`` silences it)."""
    modes: dict[str, Mode | None] = {"auto": None, "bar": "bar", "lines": "lines", "none": "off"}
    return Progress(total, prog, mode=modes[args.progress], unit=unit)


def _fleet_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
    f = sub.add_parser(
        "fleet",
        help="run a command over many records on a Dask cluster (fleet identify)",
        description="Run a command over many records, one task per record, on a Dask cluster: an embedded "
        "LocalCluster by default, or an existing cluster (--scheduler tcp://HOST:PORT).",
    )
    fsub = f.add_subparsers(dest="fleet_command", required=True, metavar="COMMAND")
    i = fsub.add_parser(
        "identify",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        help="piezohyst identify over many records: one model file per record, a summary table and a report",
        description=(
            "Identify a model of each record with piezohyst identify's own code and options (one Dask task per\n"
            "record) and write DIR/<stem>.json per record (the file 'piezohyst identify RECORD --out' writes),\n"
            "DIR/summary.csv and DIR/summary.parquet (record, status, model, parameters p.*, train and\n"
            "validation errors, fit and task time, outlier flags, error) and DIR/report.png (each parameter's\n"
            "distribution over the fleet, outliers - robust z-score |z| > 3.5 by median and MAD - in red).\n\n"
            "A record that fails does not stop the others: it is listed with its error (status 'failed').\n"
            "Files are written whole (a temporary sibling, then os.replace); a rerun skips the records whose\n"
            "DIR/<stem>.json exists (--force: all of them again), so an interrupted fleet resumes. A task on a\n"
            "worker that dies is run again on another; every record's result is written once."
        ),
        epilog=(
            "examples:\n"
            "  piezohyst fleet identify recs/*.csv --model boucwen --fs 1000 --seed 0 --out models --workers 2\n"
            "  piezohyst fleet identify --manifest parts.csv --model mpi --out models --scheduler tcp://scheduler-host:8786\n\n"
            "manifest: a CSV file with a header; column 'record' names the record file (relative to the\n"
            "manifest's directory); optional column 'name' the output stem (default: the file's stem); any\n"
            "other column is an identify option for that record (fs, time, input, output, train, validate,\n"
            "lag, model, ...: the option's name without '--'); an empty cell keeps the command line's value.\n\n"
            "exit status: 0 when every record was identified (and trusted), 3 when some model is not\n"
            "trustworthy (identify's exit 3), 1 when some record failed, 2 on bad input (every record failing\n"
            "with the same error counts as bad input), 130 on Ctrl-C (finished files stay: rerun to resume)."
        ),
    )
    i.add_argument("records", metavar="RECORDS", nargs="*", help="record files (see piezohyst identify --help)")
    i.add_argument("--manifest", metavar="FILE.csv", help="a CSV naming the records and per-record options")
    _identify_options(i)
    i.add_argument("--out", metavar="DIR", required=True, help="output directory (created if missing)")
    i.add_argument("--plots", action="store_true", help="also write DIR/<stem>.png per record (identify's --plot)")
    i.add_argument("--force", action="store_true", help="identify every record again (default: skip finished ones)")
    _cluster_options(i)
    i.add_argument("--json", action="store_true", help="print the fleet's summary as JSON")
    i.add_argument("--debug", dest="sub_debug", action="store_true", help="show a traceback on errors")
    i.set_defaults(identify_actions={a.dest: a for a in i._actions if a.dest not in _OWN})


@dataclass(frozen=True)
class _Job:
    """One record: its name (the output stem), its path as given, and identify's options for it."""

    name: str
    path: str
    options: dict[str, Any] = field(hash=False)
    plot: bool = False


#: What a worker of a local cluster imports before its first record (see piezohyst.fleet.runner).
_PRELOAD = (
    "scipy.signal",
    "piezohyst.cli.fleet",
    "piezohyst.identify",
    "piezohyst.identify.dispatch",
    "piezohyst.signals.data",
)

#: One identification at a time per worker process: stdout/stderr are captured process-wide
#: (and the Rust core's threads are the worker's to use).
_LOCK = threading.Lock()


def _worker() -> str:
    """Which process runs this task (the summary's ``worker`` column), as host:pid."""
    return f"{socket.gethostname()}:{os.getpid()}"


def _identify_task(job: _Job) -> dict[str, Any]:
    """Run ``piezohyst identify`` on one record in a scratch directory; return the model file's
    text (and figure), the exit code, what it printed on stderr and the time it took."""
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="piezohyst-fleet-") as tmp:
        ns = argparse.Namespace(**job.options)
        ns.data = job.path
        ns.out = os.path.join(tmp, "model.json")
        ns.plot = os.path.join(tmp, "model.png") if job.plot else None
        ns.force, ns.json, ns.progress, ns.sub_debug = True, True, False, False
        out, err = io.StringIO(), io.StringIO()
        with _LOCK, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = _identify(ns)
            except (PiezohystError, ValueError, TypeError, OSError, ImportError, MemoryError) as e:
                return {
                    "status": "failed",
                    "error": " ".join(str(e).split()) or type(e).__name__,
                    "stderr": err.getvalue(),
                    "seconds": time.perf_counter() - t0,
                    "worker": _worker(),
                }
        text = Path(ns.out).read_text(encoding="utf-8")
        png = Path(ns.plot).read_bytes() if ns.plot and Path(ns.plot).is_file() else None
    status = {0: "ok", 3: "untrusted", 130: "partial"}.get(code, "failed")
    return {
        "status": status,
        "code": code,
        "document": text,
        "png": png,
        "stderr": err.getvalue(),
        "seconds": time.perf_counter() - t0,
        "error": None if status != "failed" else f"identify exited with status {code}",
        "worker": _worker(),
    }


def _preflight(options: dict[str, Any]) -> None:
    """Identify's checks of its options, run here before any record: ``_identify`` on a record that
    does not exist checks its options first, then fails on DATA; any other failure is a bad option
    for every record (exit 2 at once, no cluster started)."""
    with tempfile.TemporaryDirectory(prefix="piezohyst-fleet-") as tmp:
        ns = argparse.Namespace(**options)
        ns.data = os.path.join(tmp, "no-record")
        ns.out, ns.plot = os.path.join(tmp, "model.json"), None
        ns.force, ns.json, ns.progress, ns.sub_debug = True, True, False, False
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            try:
                _identify(ns)
            except _Fail as e:
                if f"DATA = '{ns.data}'" not in str(e):
                    raise
                return
    raise AssertionError("identify ran without a record")  # pragma: no cover - _identify reads DATA


def _options(args: argparse.Namespace) -> dict[str, Any]:
    actions: dict[str, argparse.Action] = args.identify_actions
    return {d: getattr(args, d) for d in actions if d != "help"}


def _absolute_if_file(value: Any, base: Path) -> Any:
    """A --validate/--weights value naming a file, made absolute (workers may run elsewhere)."""
    if isinstance(value, str) and value and (base / value).is_file():
        return str((base / value).resolve())
    return value


def _convert(action: argparse.Action, raw: str, where: str) -> Any:
    """A manifest cell as the option's value (its type and choices)."""
    text = raw.strip()
    if action.nargs == 0 or isinstance(action, argparse.BooleanOptionalAction):
        low = text.lower()
        if low in ("1", "true", "yes", "on"):
            return True
        if low in ("0", "false", "no", "off"):
            return False
        raise _Fail(f"{where} = '{raw}' must be true or false")
    conv = action.type if callable(action.type) else str
    try:
        value = conv(text)
    except (TypeError, ValueError):
        raise _Fail(f"{where} = '{raw}' is not a valid value of --{action.dest.replace('_', '-')}") from None
    if action.choices is not None and value not in action.choices:
        raise _Fail(f"{where} = '{raw}' must be one of {', '.join(map(str, action.choices))}")
    return value


def _manifest_jobs(path: str, base: dict[str, Any], actions: dict[str, argparse.Action]) -> list[_Job]:
    p = Path(path)
    if not p.is_file():
        raise _Fail(f"--manifest = '{path}': no such file")
    root = p.resolve().parent
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise _Fail(f"--manifest = '{path}' cannot be read as text: {e}") from None
    reader = csv.DictReader(io.StringIO(text))
    header = [h.strip() for h in (reader.fieldnames or [])]
    if "record" not in header:
        raise _Fail(f"--manifest = '{path}' has no 'record' column (its header: {', '.join(header) or 'empty'})")
    columns: dict[str, str] = {}
    for h in header:
        if h in ("record", "name"):
            continue
        dest = h.lstrip("-").replace("-", "_")
        if dest in _OWN or dest not in actions:
            raise _Fail(
                f"--manifest = '{path}': column '{h}' is not a per-record identify option "
                "(record, name, fs, time, input, output, train, validate, model, ...)"
            )
        columns[h] = dest
    jobs = []
    for line, row in enumerate(reader, start=2):
        row = {(k or "").strip(): (v or "") for k, v in row.items()}
        rec = row.get("record", "").strip()
        if not rec:
            raise _Fail(f"--manifest = '{path}', line {line}: empty 'record'")
        opts = dict(base)
        for h, dest in columns.items():
            cell = row.get(h, "")
            if cell.strip() == "":
                continue
            opts[dest] = _convert(actions[dest], cell, f"--manifest '{path}' line {line}, column '{h}'")
            if dest == "time":
                opts["fs"] = opts["fs"] if row.get("fs", "").strip() else None
            if dest == "fs":
                opts["time"] = opts["time"] if row.get("time", "").strip() else None
        for dest in ("validate", "weights"):
            if opts.get(dest) is not base.get(dest):
                opts[dest] = _absolute_if_file(opts.get(dest), root)
        full = (root / rec).resolve()
        name = row.get("name", "").strip() or full.stem
        jobs.append(_Job(name, str(full), opts))
    return jobs


def _jobs(args: argparse.Namespace) -> list[_Job]:
    base = _options(args)
    for dest in ("validate", "weights"):
        base[dest] = _absolute_if_file(base.get(dest), Path.cwd())
    jobs = [_Job(Path(r).stem, str(Path(r).resolve()), dict(base)) for r in args.records]
    if args.manifest is not None:
        jobs += _manifest_jobs(args.manifest, base, args.identify_actions)
    if not jobs:
        raise _Fail("no records: give RECORDS... and/or --manifest FILE.csv")
    seen: dict[str, str] = {}
    for j in jobs:
        if j.name in seen:
            raise _Fail(
                f"records '{seen[j.name]}' and '{j.path}' would both write {j.name}.json; rename one "
                "(a manifest's 'name' column sets the output name)"
            )
        if j.name in ("summary", "report"):
            raise _Fail(f"record '{j.path}': the name '{j.name}' is the fleet's own summary file; rename it")
        seen[j.name] = j.path
    return [_Job(j.name, j.path, j.options, bool(args.plots)) for j in jobs]


def _row(job: _Job, status: str, doc: dict[str, Any] | None, **extra: Any) -> dict[str, Any]:
    from ..fleet.summary import flatten_parameters

    row: dict[str, Any] = {"record": job.name, "path": job.path, "status": status}
    if doc is not None:
        fit = doc.get("fit", {})
        league = fit.get("league")
        chosen = next((r["name"] for r in league if r.get("chosen")), None) if isinstance(league, list) else None
        row["model"] = chosen or doc.get("kind")
        row["file_kind"] = doc.get("kind")
        row["method"] = fit.get("method")
        for part in ("train", "validation"):
            m = fit.get(part) or {}
            row[f"{part}_rmse_percent"] = m.get("rmse_percent")
            row[f"{part}_max_error_percent"] = m.get("max_error_percent")
        assessment = fit.get("assessment")
        row["trusted"] = None if not isinstance(assessment, dict) else str(bool(assessment.get("trusted", True)))
        row["fit_seconds"] = fit.get("wall_time_s")
        row.update(flatten_parameters(doc))
    row.update(extra)
    return row


_BASE_COLUMNS = (
    "record",
    "status",
    "model",
    "file_kind",
    "method",
    "train_rmse_percent",
    "train_max_error_percent",
    "validation_rmse_percent",
    "validation_max_error_percent",
    "trusted",
    "fit_seconds",
    "task_seconds",
    "resumed",
    "outliers",
    "max_abs_z",
    "error",
    "worker",
    "path",
)


def _read_done(path: Path) -> dict[str, Any] | None:
    """A finished record's model file, or None when it is not a whole model file (or holds the
    best model found before an interrupted fit, ``"partial": true``)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    whole = isinstance(doc, dict) and "kind" in doc and "fit" in doc and not doc.get("partial")
    return doc if whole else None


def _fleet(args: argparse.Namespace) -> int:
    if args.fleet_command == "identify":
        return _fleet_identify(args)
    raise _Fail(f"unknown fleet command '{args.fleet_command}'")  # pragma: no cover - argparse checks


def _fleet_identify(args: argparse.Namespace) -> int:
    from ..fleet import plan, runner

    t0 = time.perf_counter()
    cluster = plan(args.scheduler, args.workers)
    jobs = _jobs(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise _Fail(f"--out = '{args.out}' is a file; give a directory")
    out.mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict[str, Any]] = {}
    todo: list[_Job] = []
    for j in jobs:
        doc = None if args.force else _read_done(out / f"{j.name}.json")
        if doc is None:
            todo.append(j)
        else:
            trusted = (doc["fit"].get("assessment") or {}).get("trusted", True)
            rows[j.name] = _row(j, "ok" if trusted else "untrusted", doc, resumed="yes")
    prog = "piezohyst fleet identify"
    by_name = {j.name: j for j in todo}
    if todo:
        progress = _progress(args, prog, len(todo), "records")
        with runner(cluster, _PRELOAD) as run:  # a local cluster starts in the background meanwhile
            for opts in {tuple(sorted((k, repr(v)) for k, v in j.options.items())): j.options for j in todo}.values():
                _preflight(opts)
            # the report's libraries load while the records are identified
            threading.Thread(target=_import_report_libraries, daemon=True).start()
            if progress.mode != "off":
                print(
                    f"{prog}: {len(todo)} record(s) to identify, {len(jobs) - len(todo)} done before; on "
                    f"{cluster.describe()}",
                    file=sys.stderr,
                )
            # the longest records first (file size as the proxy), so the last tasks to finish are
            # short ones and the workers end together (Dask runs the submissions in order)
            tasks = [(f"identify-{j.name}", (j,)) for j in _longest_first(todo)]
            for o in run.run(_identify_task, tasks, progress):
                j = by_name[o.key.removeprefix("identify-")]
                if o.error is not None:  # the task itself raised (a bug, or its worker died too often)
                    rows[j.name] = _row(j, "failed", None, error=o.error)
                    continue
                r = o.value
                if r["status"] == "failed" and "document" not in r:
                    rows[j.name] = _row(
                        j, "failed", None, error=r["error"], task_seconds=r["seconds"], worker=r["worker"]
                    )
                    continue
                write_atomic(out / f"{j.name}.json", r["document"], name="--out")
                if r.get("png") is not None:
                    write_atomic(out / f"{j.name}.png", r["png"], name="--plots")
                doc = json.loads(r["document"])
                rows[j.name] = _row(
                    j, r["status"], doc, task_seconds=r["seconds"], resumed="no", error=r["error"], worker=r["worker"]
                )
    ordered = [rows[j.name] for j in jobs]
    summary = _summarize(ordered, out)
    summary["wall_time_s"] = time.perf_counter() - t0
    summary["cluster"] = cluster.describe()
    failed = [r for r in ordered if r["status"] == "failed"]
    if args.json:
        print(json.dumps(summary, indent=2, allow_nan=False, default=str))
    else:
        _print_summary(summary, prog)
    if failed and len(failed) == len(jobs) and len({r["error"] for r in failed}) == 1 and not _any_resumed(ordered):
        raise _Fail(f"every record failed: {failed[0]['error']}")
    for r in failed:
        print(f"{prog}: {r['record']} failed: {r['error']}", file=sys.stderr)
    if failed:
        return 1
    return 3 if any(r["status"] == "untrusted" for r in ordered) else 0


def _longest_first(jobs: list[_Job]) -> list[_Job]:
    """``jobs`` by record size on disk, largest first (stable; an unreadable record counts 0 and
    its task reports why)."""

    def size(job: _Job) -> int:
        try:
            return os.path.getsize(job.path)
        except OSError:
            return 0

    return sorted(jobs, key=size, reverse=True)


def _import_report_libraries() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot
    import pyarrow.parquet  # noqa: F401


def _any_resumed(rows: list[dict[str, Any]]) -> bool:
    return any(r.get("resumed") == "yes" for r in rows)


def _summarize(rows: list[dict[str, Any]], out: Path) -> dict[str, Any]:
    """Outlier flags, DIR/summary.csv, DIR/summary.parquet and DIR/report.png; the summary as a dict."""
    from ..fleet.summary import OUTLIER_Z, distribution_figure, outliers, robust_z, write_table

    good = [r for r in rows if r["status"] in ("ok", "untrusted")]
    params = sorted({k for r in good for k in r if k.startswith("p.")}, key=_param_order)
    scored = [c for c in ("train_rmse_percent", "validation_rmse_percent") if any(r.get(c) is not None for r in good)]
    flags = outliers(good, [*params, *scored])
    for r, f in zip(good, flags, strict=True):
        r["outliers"] = "; ".join(f)
    for c in [*params, *scored]:
        vals = [float(r[c]) if isinstance(r.get(c), (int, float)) else math.nan for r in good]
        if len(vals) >= 5:
            for r, z in zip(good, robust_z(vals), strict=True):
                if math.isfinite(z) or math.isinf(z):
                    r["max_abs_z"] = max(r.get("max_abs_z", 0.0), abs(float(z)))
    columns = [*_BASE_COLUMNS, *params]
    write_table(rows, columns, out / "summary.csv", out / "summary.parquet")
    report = None
    if good:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from .common import _atomic_savefig

        fig = distribution_figure(
            good,
            [*scored, *params][:24],
            f"{len(good)} records: parameter distributions, outliers (|robust z| > {OUTLIER_Z:g}) in red",
        )
        try:
            # the fleet's own summary of DIR, rebuilt from every record on each run (as summary.csv)
            _atomic_savefig(fig, out / "report.png", name="report.png", force=True)
        finally:
            plt.close(fig)
        report = str(out / "report.png")
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["status"]] = counts.get(r["status"], 0) + 1
    return {
        "out": str(out),
        "records": len(rows),
        "counts": counts,
        "resumed": sum(r.get("resumed") == "yes" for r in rows),
        "summary_csv": str(out / "summary.csv"),
        "summary_parquet": str(out / "summary.parquet"),
        "report": report,
        "outliers": [{"record": r["record"], "flags": r["outliers"]} for r in good if r.get("outliers")],
        "failed": [{"record": r["record"], "error": r.get("error")} for r in rows if r["status"] == "failed"],
    }


def _param_order(name: str) -> tuple[str, int]:
    """``p.weights[10]`` after ``p.weights[9]``."""
    head, _, idx = name.partition("[")
    return (head, int(idx.rstrip("]")) if idx.rstrip("]").isdigit() else -1)


def _print_summary(summary: dict[str, Any], prog: str) -> None:
    counts = ", ".join(f"{v} {k}" for k, v in sorted(summary["counts"].items()))
    print(
        f"{summary['records']} records ({counts}; {summary['resumed']} done before) in "
        f"{summary['wall_time_s']:.3g} s on {summary['cluster']} -> {summary['out']}"
    )
    print(f"  summary: {summary['summary_csv']}, {summary['summary_parquet']}")
    if summary["report"]:
        print(f"  report:  {summary['report']}")
    for o in summary["outliers"]:
        print(f"  outlier: {o['record']}: {o['flags']}")
