"""The built documentation site in a real browser (issue 17): headless Chromium opens the index
and a gallery page and every figure has loaded (an ``img`` whose natural size is > 0), the
equations of a theory page are laid out, and no page asks the network for anything.

The site is built by ``make docs``; without it these tests skip, unless
``PIEZOHYST_DOCS_REQUIRED=1`` (``make docs-check``, CI), where a missing site or a missing
Chromium fails.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

SITE = Path(__file__).resolve().parents[1] / "docs" / "_build" / "html"
REQUIRED = os.environ.get("PIEZOHYST_DOCS_REQUIRED") == "1"

# appended to a copy of a page: once everything has loaded, report what the browser sees
_CHECK = """<script>
window.addEventListener('load', () => {
  const imgs = Array.from(document.querySelectorAll('article img, .bd-article img'));
  const seen = imgs.map(i => ({src: i.getAttribute('src'), w: i.naturalWidth, h: i.naturalHeight,
                               shown: i.getBoundingClientRect().width}));
  const maths = Array.from(document.querySelectorAll('math'));
  const laid = maths.filter(m => m.getBoundingClientRect().width > 0).length;
  const pre = document.createElement('pre'); pre.id = 'check';
  pre.textContent = JSON.stringify({images: seen, maths: maths.length, maths_laid_out: laid});
  document.body.appendChild(pre);
});
</script>"""


def _site() -> Path:
    if not (SITE / "index.html").is_file():
        if REQUIRED:
            pytest.fail(f"the documentation site is not built ({SITE / 'index.html'} is missing): run make docs")
        pytest.skip("the documentation site is not built (make docs)")
    return SITE


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if REQUIRED:
        pytest.fail("Chromium is not installed: make docs-browser-deps installs Debian's chromium")
    pytest.skip("Chromium is not installed (make docs-browser-deps) — the browser check needs it")


def _in_browser(page: Path, html: str | None = None) -> dict:
    """What headless Chromium sees on ``page`` (or on ``html`` served from page's folder)."""
    text = page.read_text() if html is None else html
    probe = page.with_name(f"_check_{page.name}")
    probe.write_text(text.replace("</body>", _CHECK + "</body>"))
    try:
        out = subprocess.run(
            [
                _chromium(),
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--window-size=1300,2000",
                "--virtual-time-budget=10000",
                "--dump-dom",
                probe.as_uri(),
            ],
            capture_output=True,
            text=True,
            timeout=120,
        ).stdout
    finally:
        probe.unlink()
    # the theme's script adds attributes (tabindex) to every <pre>
    found = re.search(r'<pre id="check"[^>]*>(.*?)</pre>', out, re.DOTALL)
    assert found, f"no report from the page: Chromium printed {len(out)} characters"
    return json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))


def _figures_loaded(seen: dict) -> list[dict]:
    return [i for i in seen["images"] if i["w"] > 0 and i["h"] > 0 and i["shown"] > 0]


def test_index_shows_its_figure():
    seen = _in_browser(_site() / "index.html")
    assert seen["images"], "the index has no figure"
    assert _figures_loaded(seen) == seen["images"], seen["images"]


def test_gallery_page_shows_the_figures_it_made():
    page = _site() / "gallery" / "plot_inverse_feedforward.html"
    seen = _in_browser(page)
    figures = [i for i in _figures_loaded(seen) if "sphx_glr_plot_inverse_feedforward" in i["src"]]
    assert figures, seen["images"]
    assert _figures_loaded(seen) == seen["images"], seen["images"]
    # every example of the gallery ran and left at least one figure on its page
    for example in sorted((SITE / "gallery").glob("plot_*.html")):
        assert re.search(r'<img src="../_images/sphx_glr_plot_\w+_001\.png"', example.read_text()), example.name


def test_the_check_sees_a_missing_figure():
    # the same gallery page with its figure's file name changed: the browser must report it
    page = _site() / "gallery" / "plot_inverse_feedforward.html"
    html = page.read_text().replace("sphx_glr_plot_inverse_feedforward_001.png", "missing.png")
    seen = _in_browser(page, html)
    broken = [i["src"] for i in seen["images"] if i["w"] == 0]
    assert any(src.endswith("missing.png") for src in broken), seen["images"]


def test_equations_are_laid_out_as_mathml():
    seen = _in_browser(_site() / "theory" / "hysteresis.html")
    assert seen["maths"] >= 20, seen
    assert seen["maths_laid_out"] == seen["maths"], seen


def test_pages_ask_the_network_for_nothing():
    # offline: no script, style sheet or image from another host (links to papers are fine)
    site = _site()
    remote = re.compile(r'<(?:script|link|img)\b[^>]*\b(?:src|href)="(?:https?:)?//', re.IGNORECASE)
    pages = list(site.glob("*.html")) + list(site.glob("*/*.html")) + list(site.glob("api/generated/*.html"))
    assert len(pages) > 50
    for page in pages:
        assert not remote.search(page.read_text()), page
