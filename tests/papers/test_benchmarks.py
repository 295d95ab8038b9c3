"""`piezohyst bench`: every benchmark in bench/ runs, one JSON + one Markdown table, each
figure beside its same-run baseline, the README section generated from it (issue 7)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from piezohyst import benchmarks as bm
from piezohyst.cli import main
from piezohyst.errors import DataError, ParameterError

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "bench" / "results"


def test_every_bench_script_is_in_the_suite():
    scripts = {p.name for p in (ROOT / "bench").glob("*.py")} - {"common.py", "numpy_reference.py"}
    assert scripts == {b.script for b in bm.BENCHMARKS}
    assert bm.find_bench_dir() == ROOT / "bench"


def test_summary_rows_carry_the_figures_of_the_result_files():
    summary = bm.summarize(bm.BENCHMARKS, RESULTS)
    assert set(summary["benchmarks"]) == {b.name for b in bm.BENCHMARKS}
    cl = json.loads((RESULTS / "closed_loop.json").read_text())
    rows = summary["benchmarks"]["closed_loop"]["rows"]
    rtf = next(r for r in rows if "sine_10Hz" in r["figure"])
    e = cl["closed_loop_rtf"]["sine_10Hz"]
    assert rtf["value"] == e["rtf"] and rtf["baseline_value"] == e["baseline_rtf"]
    assert rtf["ratio"] == e["speedup_vs_baseline"] and rtf["pass"] == (e["rtf"] >= 1000)
    cs = json.loads((RESULTS / "c_step.json").read_text())
    head = next(r for r in summary["benchmarks"]["c_step"]["rows"] if r["target"])
    assert head["value"] == cs["summary"]["MPI inverse (9 operators) + SMC"]["mean_ns"]
    assert head["baseline_value"] == cs["rust_api_baseline"]["results"]["MPI inverse (9 operators) + SMC"]["mean"]
    # every benchmark has at least one row and every row a baseline or a target
    for name, e in summary["benchmarks"].items():
        assert e["status"] == "ok" and e["rows"], name
        for r in e["rows"]:
            assert r["baseline_value"] is not None or r["target"] is not None, (name, r["figure"])
    judged = [r for e in summary["benchmarks"].values() for r in e["rows"] if r["pass"] is not None]
    assert summary["targets"]["judged"] == len(judged)
    assert summary["targets"]["met"] == sum(r["pass"] for r in judged)


def test_markdown_table_has_one_line_per_row_and_marks_targets():
    summary = bm.summarize(bm.BENCHMARKS, RESULTS)
    md = bm.to_markdown(summary)
    n_rows = sum(len(e["rows"]) for e in summary["benchmarks"].values())
    table = [line for line in md.splitlines() if line.startswith("| ") and not line.startswith("| benchmark")]
    assert len(table) == n_rows
    assert md.count("**met**") == summary["targets"]["met"]
    assert md.count("**missed**") == summary["targets"]["judged"] - summary["targets"]["met"]


def test_readme_section_is_the_generated_table():
    """The README's performance section is exactly what `piezohyst bench --report-only`
    generates from the checked-in results (regenerate it after running benchmarks)."""
    readme = (ROOT / "README.md").read_text()
    i, j = readme.index(bm.BEGIN), readme.index(bm.END)
    section = readme[i + len(bm.BEGIN) : j]
    table = bm.to_markdown(bm.summarize(bm.BENCHMARKS, RESULTS))
    # the generation time stamp is the only line allowed to differ: there is none in the table
    assert table in section, (
        "README performance section is stale: run `piezohyst bench --report-only --readme README.md`"
    )


def test_update_readme_replaces_only_the_marked_section(tmp_path):
    p = tmp_path / "R.md"
    p.write_text(f"intro\n{bm.BEGIN}\nold table\n{bm.END}\noutro\n")
    bm.update_readme(p, "| new |\n")
    text = p.read_text()
    assert text.startswith("intro\n" + bm.BEGIN) and text.endswith(bm.END + "\noutro\n")
    assert "| new |" in text and "old table" not in text
    q = tmp_path / "plain.md"
    q.write_text("no markers\n")
    with pytest.raises(DataError, match="plain.md"):
        bm.update_readme(q, "x")
    assert q.read_text() == "no markers\n"


def test_bad_arguments_are_one_line_errors(tmp_path, capsys):
    assert main(["bench", "--only", "nonsense"]) == 2
    err = capsys.readouterr().err
    assert "--only 'nonsense' is not a benchmark" in err and err.count("\n") == 1
    assert main(["bench", "--report-only", "--results", str(tmp_path / "none")]) == 2
    assert "is not a directory" in capsys.readouterr().err
    assert main(["bench", "--bench-dir", str(tmp_path)]) == 2
    assert "not piezohyst's bench/ directory" in capsys.readouterr().err
    with pytest.raises(ParameterError):
        bm.select(["pi_batch"], ["pi_batch"])


def test_a_failing_benchmark_is_reported_and_the_others_still_run(tmp_path, capsys):
    bench = tmp_path / "bench"
    bench.mkdir()
    (bench / "common.py").write_text("")
    (bench / "pi_batch.py").write_text("import sys\nprint('boom: no luck', file=sys.stderr)\nsys.exit(3)\n")
    src = json.loads((RESULTS / "demo.json").read_text())
    (bench / "demo.py").write_text(
        f"import shutil, sys\nshutil.copy({str(RESULTS / 'demo.json')!r}, sys.argv[sys.argv.index('--out') + 1])\n"
    )
    results = tmp_path / "res"
    code = main(["bench", "--bench-dir", str(bench), "--results", str(results), "--only", "pi_batch", "demo"])
    _out, err = capsys.readouterr()
    assert code == 1 and "pi_batch" in err
    s = json.loads((results / "summary.json").read_text())
    assert s["benchmarks"]["pi_batch"]["status"] == "failed" and s["benchmarks"]["pi_batch"]["exit_code"] == 3
    assert "boom: no luck" in s["benchmarks"]["pi_batch"]["stderr_tail"]
    assert s["benchmarks"]["demo"]["status"] == "ok" and len(s["benchmarks"]["demo"]["rows"]) == len(src["runs"])
    assert "| pi_batch | **failed** |" in (results / "summary.md").read_text()


def test_quick_run_of_real_benchmarks(tmp_path):
    """A real (smoke) run through the command line: two benchmarks with --quick budgets."""
    res = tmp_path / "res"
    p = subprocess.run(
        [sys.executable, "-m", "piezohyst", "bench", "--quick", "--only", "pi_batch", "control", "--results", str(res)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert p.returncode == 0, p.stderr
    s = json.loads((res / "summary.json").read_text())
    assert s["quick"] is True and set(s["benchmarks"]) == {"pi_batch", "control"}
    pb = json.loads((res / "pi_batch.json").read_text())
    rows = s["benchmarks"]["pi_batch"]["rows"]
    assert rows[0]["value"] == pb["workloads"][0]["piezohyst"]["2_thread"]["updates_per_s"] > 1e8
    ctl = s["benchmarks"]["control"]["rows"]
    lin = [r for r in ctl if "linearity" in r["figure"]]
    assert len(lin) == 8 and all(r["value"] < r["baseline_value"] for r in lin)
    assert "| control |" in (res / "summary.md").read_text() and "| control |" in p.stdout
