"""Render ``:math:`` and ``.. math::`` as MathML at build time (latex2mathml).

Sphinx's default renderer, MathJax, loads a script from a CDN when the page is viewed; the
site must read offline, and every current browser renders MathML Core itself. A formula that
latex2mathml cannot convert is a build error naming the formula.
"""

from __future__ import annotations

from typing import Any

from docutils import nodes
from latex2mathml.converter import convert
from sphinx.application import Sphinx
from sphinx.errors import ExtensionError
from sphinx.writers.html5 import HTML5Translator


def _mathml(latex: str, display: str) -> str:
    try:
        return convert(latex, display=display)
    except Exception as exc:  # latex2mathml raises its own exception types per construct
        raise ExtensionError(f"mathml: cannot convert {latex!r}: {exc}") from exc


def _visit_inline(self: HTML5Translator, node: nodes.Element) -> None:
    self.body.append(f'<span class="math">{_mathml(node.astext(), "inline")}</span>')
    raise nodes.SkipNode


def _visit_block(self: HTML5Translator, node: nodes.Element) -> None:
    if node.get("no-wrap") or node.get("nowrap"):
        parts = [node.astext()]
    else:
        parts = [p for p in node.astext().split("\n\n") if p.strip()]
    self.body.append(self.starttag(node, "div", CLASS="math"))
    if node.get("number"):
        number = node["number"]
        self.body.append(f'<span class="eqno">({number})</span>')
    for part in parts:
        self.body.append(f'<div class="math-line">{_mathml(part, "block")}</div>')
    self.body.append("</div>\n")
    raise nodes.SkipNode


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_html_math_renderer(
        "mathml",
        inline_renderers=(_visit_inline, None),
        block_renderers=(_visit_block, None),
    )
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
