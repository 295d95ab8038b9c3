"""The command line: the demo runs, writes its report, refuses to overwrite, fails cleanly."""

import json
import subprocess
import sys


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "piezohyst", *args], cwd=cwd, capture_output=True, text=True)


def test_demo_quick_writes_the_report_and_prints_json(tmp_path):
    readme = tmp_path / "R.md"
    readme.write_text("# intro\n<!-- demo:begin -->\nstale numbers\n<!-- demo:end -->\nrest\n")
    out = run("demo", "--out", "report", "--quick", "--seed", "1", "--json", "--readme", "R.md", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    numbers = json.loads(out.stdout)
    assert numbers["seed"] == 1 and numbers["quick"] is True
    assert set(numbers) >= {"identification", "seed1", "seed2", "figures"}
    assert "[5/5] write the report" in out.stderr  # progress per stage on stderr
    # stderr is not a terminal: progress in plain lines, never a carriage return (issue 17)
    assert "\r" not in out.stderr and "css: 25/25 (100 %)" in out.stderr
    report = tmp_path / "report"
    for name in ("index.html", "report.md", "results.json", *numbers["figures"].values()):
        assert (report / name).stat().st_size > 0, name
    # --readme: the marked section holds this run's numbers, labelled quick, and nothing else changed
    from piezohyst.papers.report import readme_markdown

    text = readme.read_text()
    saved = json.loads((report / "results.json").read_text())
    assert readme_markdown(saved) in text and "stale numbers" not in text
    assert text.startswith("# intro\n<!-- demo:begin -->") and text.endswith("<!-- demo:end -->\nrest\n")
    assert "(seed 1, QUICK run: smaller budgets)" in text
    # --report-only: the same section from the report on disk, without a run
    again = tmp_path / "R2.md"
    again.write_text("<!-- demo:begin --><!-- demo:end -->\n")
    out = run("demo", "--out", "report", "--report-only", "--readme", "R2.md", cwd=tmp_path)
    assert out.returncode == 0 and out.stderr == "", out.stderr
    assert readme_markdown(saved) in again.read_text()
    # the report's caption says which gains seed 1's main table compares
    md = (report / "report.md").read_text()
    assert "SMC (Case 1) and SMC + CEMF (Case 2) each tuned for itself by the same call" in md
    assert "Seed 1's protocol: one gain set for both cases" in md  # the seed's own protocol, labelled


def test_demo_refuses_to_overwrite_without_force(tmp_path):
    (tmp_path / "report").mkdir()
    (tmp_path / "report" / "index.html").write_bytes(b"mine")
    out = run("demo", "--out", "report", "--quick", cwd=tmp_path)
    assert out.returncode == 2
    assert out.stderr.strip().count("\n") == 0 and "--force" in out.stderr
    assert (tmp_path / "report" / "index.html").read_bytes() == b"mine"
    out = run("demo", "--out", "report", "--seed", "-2", "--force", cwd=tmp_path)
    assert out.returncode == 2 and "seed = -2 must be a non-negative int" in out.stderr


def test_stage_info_measures_the_virtual_stage_within_the_spec_ranges(tmp_path):
    out = run("stage", "info", "--json", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    info = json.loads(out.stdout)
    assert 18 <= info["stroke_um"] <= 22  # docs/spec.md §3.2: ~20 um at 150 V
    assert 10 <= info["hysteresis_percent_1hz_full_range"] <= 15
    assert 1 <= info["creep_percent_per_decade"] <= 2
    assert abs(info["natural_frequency_hz"] - 5100) < 60  # docs/spec.md §3.1: ~5.1 kHz
    # the charge coupling stiffens the stack: the measured resonance sits a little higher
    assert info["natural_frequency_hz"] < info["first_resonance_hz"] < 6000


def test_stage_info_bad_file_is_one_line_error(tmp_path):
    bad = tmp_path / "stage.json"
    bad.write_text(
        '{"mechanics": {"mass": -1, "stiffness": 1e7, "damping_ratio": 0.03, "tem": 10}, '
        '"cemf": {"alpha": 1, "beta": 1, "gamma": 1}}'
    )
    out = run("stage", "info", "--stage", str(bad), cwd=tmp_path)
    assert out.returncode == 2
    assert out.stderr.strip().count("\n") == 0 and "mass = -1.0 must be > 0" in out.stderr
