"""The README's headline numbers are the demo's (issue 17, item 6): its demo section is exactly
what `piezohyst demo --readme README.md` writes from the run's results.json, kept in
bench/results/demo_results.json; the captions say which gains are compared."""

import json
import re
from pathlib import Path

from piezohyst.papers.report import EQUAL_TUNING, MAIN_GAINS, README_BEGIN, README_END, _tables, readme_markdown

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "bench" / "results" / "demo_results.json"


def _section(text: str) -> str:
    i, j = text.index(README_BEGIN), text.index(README_END)
    return text[i + len(README_BEGIN) : j]


def test_readme_numbers_are_the_demo_results():
    results = json.loads(RESULTS.read_text())
    assert results["seed"] == 0 and results["quick"] is False  # the README quotes a full run
    section = _section((ROOT / "README.md").read_text())
    assert readme_markdown(results) in section, (
        "README's demo section is stale: run `make readme-demo` (piezohyst demo --readme README.md)"
    )
    # the figures a reader quotes, parsed back from the README, are the JSON's (3 significant digits)
    ours = results["seed1"]["rmse_um"][EQUAL_TUNING]["triangle 5 Hz"]
    m = re.search(
        r"\| seed 1 Table 3, triangle 5 Hz, SMC → SMC \+ CEMF, each tuned for itself \(µm\) \| [^|]+ \| "
        r"([\d.]+) → ([\d.]+) \(PID \+ FF ([\d.]+);",
        section,
    )
    assert m is not None
    assert float(m.group(1)) == float(f"{ours['SMC']:.3g}") and float(m.group(2)) == float(f"{ours['SMC+CEMF']:.3g}")
    assert float(m.group(3)) == float(f"{ours['PID+FF']:.3g}")
    t4 = results["seed2"]["table4_80hz"]["constant"]
    m = re.search(
        r"\| seed 2 Table 4, 80 Hz normalized max error: [^|]+\| [^|]+ \| ([\d.]+) / ([\d.]+) / ([\d.]+) \|", section
    )
    assert m is not None
    assert [float(x) for x in m.groups()] == [round(r["normalized_max_error"], 3) for r in t4.values()]


def test_captions_say_which_gains_are_compared():
    """Seed 1's main table compares SMC and SMC + CEMF each tuned for itself (with the tuned
    PID + FF and the noise floor); seed 1's own protocol (one gain set tuned for SMC + CEMF and
    reused for SMC) is a second table that says so. Each caption shows the gains it used."""
    results = json.loads(RESULTS.read_text())
    tables = {title: note for title, note, _, _ in _tables(results)}
    note = tables["Seed 1, Table 3 — tracking RMSE (µm), each controller tuned for itself"]
    assert "each tuned for itself by the same call" in note and "reused" not in note
    pid = results["seed1"]["pid_gains"]
    assert f"kp {pid['kp']:.3g} V/m" in note  # the PID gains shown are the ones used
    protocol = tables["Seed 1's protocol: one gain set for both cases (µm)"]
    g = results["seed1"]["gains"][MAIN_GAINS]
    assert f"kp {g['kp']:.3g}" in protocol and "reused" in protocol
    md = readme_markdown(results)
    assert "each tuned for itself" in md and "reused unchanged" not in md
    equal = results["seed1"]["rmse_um"][EQUAL_TUNING]["triangle 5 Hz"]
    assert f"{equal['SMC']:.3g} → {equal['SMC+CEMF']:.3g} (PID + FF {equal['PID+FF']:.3g}" in md
