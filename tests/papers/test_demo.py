"""`piezohyst demo`: the report is written, complete, deterministic, never overwritten without
--force, and renders in a real browser (Chromium headless, where installed)."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from piezohyst.cli import main
from piezohyst.demo import run_demo


def _strip_times(d):
    if isinstance(d, dict):
        return {k: _strip_times(v) for k, v in d.items() if "wall" not in k}
    if isinstance(d, list):
        return [_strip_times(v) for v in d]
    return d


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    a = tmp_path_factory.mktemp("a") / "report"
    b = tmp_path_factory.mktemp("b") / "report"
    ra = run_demo(a, quick=True, seed=3, progress=False, print_fn=lambda *x: None)
    # the same seed in another process on one thread (rayon's pool size changes nothing)
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    out = subprocess.run(
        [sys.executable, "-m", "piezohyst", "demo", "--out", str(b), "--quick", "--seed", "3", "--json"],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    rb = json.loads(out.stdout)
    return a, ra, b, rb


def test_same_seed_same_numbers_whatever_the_thread_count(reports):
    a, _ra, b, _rb = reports
    ja = _strip_times(json.loads((a / "results.json").read_text()))
    jb = _strip_times(json.loads((b / "results.json").read_text()))
    assert ja == jb
    assert ja["seed"] == 3 and ja["quick"] is True


def test_report_holds_all_four_table_analogues_with_the_seeds_numbers(reports):
    a, r, _, _ = reports
    md = (a / "report.md").read_text()
    for title in ("Seed 2, Table 2", "Seed 1, Table 3", "Seed 2, Table 3", "Seed 2, Table 4"):
        assert title in md
    # the seeds' numbers sit beside ours
    for seed_number in ("0.1118 → 0.0715", "5.53 → 0.17", "0.0784 / 0.0348", "0.31 / 0.21"):
        assert seed_number in md
    assert "The seeds measured real stages" in md
    # every figure listed exists and is a real PNG
    assert len(r["figures"]) == 8
    for fn in r["figures"].values():
        data = (a / fn).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    # the numbers: the patterns of the seeds (quick budgets)
    t3 = r["seed2"]["table3_linearity_percent"]
    assert all(v["none"] > 5 and v["feedforward"] < 1 for v in t3.values())
    t4 = r["seed2"]["table4_80hz"]["constant"]
    assert t4["none"]["normalized_max_error"] > 10 * t4["feedforward+ABSMC"]["normalized_max_error"]
    s1 = r["seed1"]["rmse_um"]["tuned for SMC+CEMF"]
    assert all(v["SMC+CEMF"] < v["SMC"] < v["open loop"] for v in s1.values())
    assert set(r["identification"]["convergence"]) == {"css", "pso", "mpso", "de"}


def test_report_is_not_overwritten_without_force(reports, capsys):
    a, _, _, _ = reports
    before = (a / "results.json").read_bytes()
    with pytest.raises(FileExistsError, match="pass --force"):
        run_demo(a, quick=True, progress=False, print_fn=lambda *x: None)
    assert main(["demo", "--out", str(a), "--quick"]) == 2
    assert "exists; pass --force" in capsys.readouterr().err
    assert (a / "results.json").read_bytes() == before
    with pytest.raises(ValueError, match="seed = -1 must be a non-negative int"):
        run_demo(a.parent / "other", seed=-1, progress=False)


_CHECK = """<script>
window.addEventListener('load', () => {
  const imgs = Array.from(document.images);
  const broken = imgs.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.getAttribute('src'));
  const tables = Array.from(document.querySelectorAll('table'));
  const empty = tables.filter(t => t.querySelectorAll('tbody tr').length === 0 ||
     Array.from(t.querySelectorAll('tbody td')).some(td => td.textContent.trim() === '')).length;
  const pre = document.createElement('pre'); pre.id = 'check';
  pre.textContent = JSON.stringify({images: imgs.length, broken: broken, tables: tables.length, empty_tables: empty});
  document.body.appendChild(pre);
});
</script>"""


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("Chromium is not installed (apt-get install chromium) — the browser check needs it")


def _browser_check(chrome, page: Path) -> dict:
    out = subprocess.run(
        [
            chrome,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--virtual-time-budget=10000",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    ).stdout
    start = out.index('<pre id="check">') + len('<pre id="check">')
    return json.loads(out[start : out.index("</pre>", start)].replace("&quot;", '"'))


def test_report_renders_in_a_real_browser(reports, tmp_path):
    chrome = _chromium()
    a, r, _, _ = reports
    html = (a / "index.html").read_text()
    page = a / "_check.html"
    page.write_text(html.replace("</body>", _CHECK + "</body>"))
    seen = _browser_check(chrome, page)
    # five tables of the seeds and the dynamic-inversion feedforward (issue 19)
    assert seen == {"images": len(r["figures"]), "broken": [], "tables": 6, "empty_tables": 0}
    # the check can fail: a missing figure is reported as broken
    bad = a / "_bad.html"
    bad.write_text(html.replace("optimizer_convergence.png", "missing.png").replace("</body>", _CHECK + "</body>"))
    assert _browser_check(chrome, bad)["broken"] == ["missing.png"]
    page.unlink()
    bad.unlink()
    shot = tmp_path / "shot.png"
    subprocess.run(
        [
            chrome,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--window-size=1200,4000",
            f"--screenshot={shot}",
            (a / "index.html").as_uri(),
        ],
        capture_output=True,
        timeout=120,
    )
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)
    assert img.shape[0] == 4000 and float(np.std(img)) > 0.05  # not a blank page
