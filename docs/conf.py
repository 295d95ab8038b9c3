"""Sphinx configuration of the piezohyst documentation site (``make docs``).

The build downloads nothing: no intersphinx inventories, the theme's assets are in its wheel,
equations are written as MathML at build time (``_ext/mathml.py``), and the example gallery
(``examples/*.py``) runs on the package installed in ``.venv``. ``make docs`` passes ``-W
--keep-going``: any warning fails the build.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import piezohyst

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE / "_ext"))

project = "piezohyst"
author = "the piezohyst developers"
copyright = "2026, the piezohyst developers (MIT licence)"
version = release = piezohyst.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "mathml",
]

# nothing fetched at build time
intersphinx_mapping: dict[str, tuple[str, str | None]] = {}
html_math_renderer = "mathml"

templates_path = ["_templates"]
exclude_patterns = ["_build", "**/*.md", "gallery/*.ipynb", "gallery/*.zip", "references_list.rst", "cli/help.rst"]
source_suffix = {".rst": "restructuredtext"}
root_doc = "index"
default_role = "py:obj"

# API reference: one page per public name, generated from the docstrings (numpydoc sections)
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"  # the numpydoc Parameters sections carry the types
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()  # tests/test_docstrings.py holds the rules

# the example gallery: every examples/*.py runs at build time and its figures are kept
sphinx_gallery_conf = {
    "examples_dirs": [str(ROOT / "examples")],
    "gallery_dirs": ["gallery"],
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"__init__\.py",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "show_memory": False,
    "plot_gallery": "True",
    "capture_repr": (),
    "min_reported_time": 1,
    # the execution-times page loads DataTables from a CDN: the site must read offline
    "write_computation_times": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"piezohyst {release}"
html_static_path = ["_static"]
html_css_files = ["piezohyst.css"]
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "navbar_align": "left",
    "header_links_before_dropdown": 7,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_sidebars = {"index": [], "references": [], "changelog": []}
html_context = {"default_mode": "light"}

pygments_style = "sphinx"


def _cli_reference() -> None:
    """Write ``cli/help.rst``: each command's ``--help`` as the installed ``piezohyst`` prints it."""
    commands = [
        ("piezohyst", []),
        ("piezohyst demo", ["demo"]),
        ("piezohyst identify", ["identify"]),
        ("piezohyst simulate", ["simulate"]),
        ("piezohyst track", ["track"]),
        ("piezohyst export-c", ["export-c"]),
        ("piezohyst stage info", ["stage", "info"]),
        ("piezohyst bench", ["bench"]),
    ]
    env = dict(os.environ, COLUMNS="100", PYTHONWARNINGS="ignore")
    out = [
        ".. This file is written by docs/conf.py at build time; do not edit.",
        "",
    ]
    for title, argv in commands:
        proc = subprocess.run(
            [sys.executable, "-m", "piezohyst", *argv, "--help"],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
            check=True,
        )
        out += [f"``{title}``", "-" * (len(title) + 4), "", ".. code-block:: text", ""]
        out += [("   " + line).rstrip() for line in proc.stdout.splitlines()]
        out += [""]
    target = HERE / "cli" / "help.rst"
    target.parent.mkdir(exist_ok=True)
    text = "\n".join(out) + "\n"
    if not target.exists() or target.read_text() != text:
        target.write_text(text)


#: The library's wings in the order of the API reference, with a one-line role each.
WINGS = {
    "models": "hysteresis models, model files, batch evaluation",
    "signals": "records and readers, references, preprocessing, metrics, ``Response``",
    "identify": "least squares, variable projection, robust losses, validation, ``identify()``",
    "optimize": "CSS, PSO, MPSO, DE (ask/tell), ``minimize``, ``RunReport``",
    "plant": "stages, amplifier, sensor, flexure design, excitation",
    "control": "controllers, the closed loop, tuning",
    "export": "controller files and C code generation",
    "papers": "the two seed papers' reference sets",
    "errors": "the exception hierarchy",
}


def _api_reference() -> None:
    """Write ``api/<wing>.rst`` and ``api/top_level.rst`` from the ``__all__`` lists, so the
    reference always holds every public name (one page each, generated from its docstring)."""
    import importlib

    homes: dict[int, str] = {}
    pages: dict[str, str] = {}
    for wing, role in WINGS.items():
        module = importlib.import_module(f"piezohyst.{wing}")
        names = list(module.__all__)
        for name in names:
            homes.setdefault(id(getattr(module, name)), f"piezohyst.{wing}.{name}")
        title = f"``piezohyst.{wing}``"
        pages[wing] = "\n".join(
            [
                ".. This file is written by docs/conf.py at build time; do not edit.",
                "",
                title,
                "=" * len(title),
                "",
                role[0].upper() + role[1:] + ".",
                "",
                f".. automodule:: piezohyst.{wing}",
                "   :no-members:",
                "",
                f".. currentmodule:: piezohyst.{wing}",
                "",
                ".. autosummary::",
                "   :toctree: generated",
                "",
                *[f"   {name}" for name in names],
                "",
            ]
        )
    rows = []
    own = []
    for name in piezohyst.__all__:
        home = homes.get(id(getattr(piezohyst, name)))
        if home is None:  # defined outside the library wings (an application wing's name)
            own.append(name)
            continue
        rows.append(f"   * - :py:obj:`{name} <{home}>`\n     - ``{home.rsplit('.', 1)[0]}``")
    top = [
        ".. This file is written by docs/conf.py at build time; do not edit.",
        "",
        "``import piezohyst``",
        "====================",
        "",
        "Every name of ``piezohyst.__all__``: the package re-exports the main names of its wings, so",
        "``import piezohyst as ph; ph.PI`` is ``piezohyst.models.PI``. Each links to its page in the",
        "wing that defines it.",
        "",
        ".. list-table::",
        "   :header-rows: 1",
        "   :widths: 40 60",
        "",
        "   * - name",
        "     - wing",
        *rows,
        "",
    ]
    if own:
        top += [
            "Names whose home is an application wing (loaded on first use):",
            "",
            ".. currentmodule:: piezohyst",
            "",
            ".. autosummary::",
            "   :toctree: generated",
            "",
            *[f"   {name}" for name in own],
            "",
        ]
    out = HERE / "api"
    for wing, text in [("top_level", "\n".join(top)), *pages.items()]:
        target = out / f"{wing}.rst"
        if not target.exists() or target.read_text() != text:
            target.write_text(text)


_LATEX = {
    r"{\"e}": "ë",
    r"{\"u}": "ü",
    r"{\"o}": "ö",
    r"{\"U}": "Ü",
    r"{\'c}": "ć",
    r"{\'e}": "é",
    r"{\u\i}": "ĭ",
    r"{\c{c}}": "ç",
    r"{\AA}": "Å",
    "--": "–",
}


def _bib_text(value: str) -> str:
    for latex, text in _LATEX.items():
        value = value.replace(latex, text)
    value = value.replace("$\\alpha$", "α").replace("$\\beta$", "β").replace("$\\gamma$", "γ")
    return " ".join(value.replace("{", "").replace("}", "").split())


def _bib_entries(path: Path) -> list[tuple[str, str, dict[str, str]]]:
    """The entries of a BibTeX file: (type, key, fields), fields in braces (nesting allowed)."""
    import re

    text = path.read_text()
    entries = []
    for m in re.finditer(r"@(\w+)\{([^,]+),", text):
        i, fields, depth = m.end(), {}, 1
        while depth > 0:
            f = re.compile(r"\s*(\w+)\s*=\s*\{").match(text, i)
            if f is None:
                break
            j, level = f.end(), 1
            while level:
                level += {"{": 1, "}": -1}.get(text[j], 0)
                j += 1
            fields[f.group(1).lower()] = _bib_text(text[f.end() : j - 1])
            i = j
            k = text.find(",", i, i + 3)
            if k < 0:
                break
            i = k + 1
        entries.append((m.group(1).lower(), m.group(2).strip(), fields))
    return entries


def _references() -> None:
    """Write ``references_list.rst``: one citation target per entry of ``references.bib``."""
    out = [".. This file is written by docs/conf.py from references.bib; do not edit.", ""]
    for _kind, key, f in _bib_entries(HERE / "references.bib"):
        parts = []
        if "author" in f:
            parts.append(f["author"].replace(" and ", "; "))
        parts.append(f"*{f.get('title', '')}*")
        where = f.get("journal") or f.get("booktitle") or f.get("publisher") or f.get("institution")
        if where:
            vol = f.get("volume", "")
            num = f" ({f['number']})" if "number" in f else ""
            series = f"{f['series']} " if "series" in f else ""
            parts.append(f"{where}{', ' + series + vol + num if vol else ''}")
        if "pages" in f:
            parts.append(f"pp. {f['pages']}" if "–" in f["pages"] else f["pages"])
        parts.append(f.get("year", ""))
        text = ", ".join(p for p in parts if p) + "."
        if "doi" in f:
            text += f" doi:`{f['doi']} <https://doi.org/{f['doi']}>`__."
        if "note" in f:
            text += f" {f['note']}."
        out += [f".. [{key}] {text}", ""]
    body = "\n".join(out)
    target = HERE / "references_list.rst"
    if not target.exists() or target.read_text() != body:
        target.write_text(body)


_cli_reference()
_api_reference()
_references()
