"""The package's import rules, checked on the source with ``ast`` (nothing is imported).

The package is split into wings by role (``piezohyst/__init__.py`` lists them). Every import
of every module counts — module level, inside functions, inside ``if TYPE_CHECKING:`` — with
these rules:

1. **No cycle** in the module graph. Imports under ``if TYPE_CHECKING:`` never run, so they
   are left out of this rule only (they still obey 2 and 3). An edge goes to the module an
   import names (``from .core import x`` -> ``identify.core``; ``from ..signals import data``
   -> ``signals.data``; ``from ..signals import Record`` -> ``signals`` (its ``__init__``)); the
   parent packages Python initializes on the way are not edges, or every package
   ``__init__`` that re-exports its modules would be a cycle.
2. **The library never imports ``papers`` or ``cli``**: no module outside ``piezohyst.papers``
   and ``piezohyst.cli`` imports them, except ``piezohyst/__main__.py`` (``python -m
   piezohyst`` is the command line). The top-level ``piezohyst/__init__.py`` is held to it too:
   the public names whose home is ``papers`` (``load_train_multisine``, the provenance presets)
   and the former flat paths of ``papers`` modules load on first use, and
   ``test_import_piezohyst_loads_no_application_wing`` checks that at run time.
3. **No private name across wings**: ``from piezohyst.<wing>.<module> import _x`` only from the
   same wing. The top-level helper modules (``_core``, ``_io``, ``_validate``, ``errors``,
   ``outputs``, ``progress``) are the shared base: any wing may import those modules and their public names,
   never a private name inside them.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "piezohyst"
ROOT = "piezohyst"
#: Wings that may import anything (the rest is "the library").
APPLICATIONS = ("papers", "cli")
#: Top-level modules outside every wing that may still import papers/cli.
FACADES = (f"{ROOT}.__main__",)


def module_sources(package: Path = PACKAGE) -> dict[str, str]:
    """``{dotted module name: source}`` of every ``.py`` file of the package."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path.read_text(encoding="utf-8")
    return out


def extension_modules(package: Path = PACKAGE) -> set[str]:
    """Compiled modules (``_core``) known by their stub."""
    return {f"{ROOT}.{p.stem}" for p in package.glob("*.pyi")}


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST):
    """``(node, under TYPE_CHECKING)`` for every import statement, at any depth."""
    stack = [(tree, False)]
    while stack:
        node, typing_only = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node, typing_only
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend((child, True) for child in node.body)
            stack.extend((child, typing_only) for child in node.orelse)
            continue
        stack.extend((child, typing_only) for child in ast.iter_child_nodes(node))


def import_edges(sources: dict[str, str], extra_modules=()):
    """Every import of a package module: dicts with ``source``, ``target`` (a module of the
    package), ``name`` (the attribute imported from it, or None), ``typing_only``, ``line``."""
    modules = set(sources) | set(extra_modules)
    packages = {m for m in sources if any(o.startswith(m + ".") for o in modules)} | {ROOT}
    edges = []
    for mod, src in sources.items():
        base = mod if mod in packages else mod.rpartition(".")[0]
        for node, typing_only in _imports(ast.parse(src, filename=mod)):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name == ROOT or alias.name.startswith(ROOT + "."):
                        edges.append(
                            dict(source=mod, target=alias.name, name=None, typing_only=typing_only, line=node.lineno)
                        )
                continue
            if node.level:
                parts = base.split(".")
                anchor = ".".join(parts[: len(parts) - node.level + 1])
                target = f"{anchor}.{node.module}" if node.module else anchor
            else:
                target = node.module or ""
            if not (target == ROOT or target.startswith(ROOT + ".")):
                continue
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                if sub in modules:
                    edges.append(dict(source=mod, target=sub, name=None, typing_only=typing_only, line=node.lineno))
                else:
                    edges.append(
                        dict(source=mod, target=target, name=alias.name, typing_only=typing_only, line=node.lineno)
                    )
    return edges


def wing(module: str) -> str:
    """``models`` for ``piezohyst.models.pi``; ``""`` (the shared base) for a top-level module."""
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in WINGS) else ""


WINGS = ("models", "signals", "optimize", "identify", "plant", "control", "export", "capi", "fleet", "papers", "cli")


def find_cycle(edges) -> list[str] | None:
    """One cycle of the graph (run-time imports only), as a closed path, or None."""
    graph: dict[str, set[str]] = {}
    for e in edges:
        if not e["typing_only"] and e["source"] != e["target"]:
            graph.setdefault(e["source"], set()).add(e["target"])
    WHITE, GREY, BLACK = 0, 1, 2
    colour: dict[str, int] = {}
    path: list[str] = []

    def visit(node):
        colour[node] = GREY
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            c = colour.get(nxt, WHITE)
            if c == GREY:
                return [*path[path.index(nxt) :], nxt]
            if c == WHITE:
                found = visit(nxt)
                if found:
                    return found
        path.pop()
        colour[node] = BLACK
        return None

    for start in sorted(graph):
        if colour.get(start, WHITE) == WHITE:
            found = visit(start)
            if found:
                return found
    return None


def layer_violations(edges) -> list[str]:
    """Library modules importing ``papers`` or ``cli``."""
    bad = []
    for e in edges:
        src, tgt = e["source"], e["target"]
        if src in FACADES or wing(src) in APPLICATIONS:
            continue
        if wing(tgt) in APPLICATIONS:
            bad.append(f"{src}:{e['line']} imports {tgt}{'.' + e['name'] if e['name'] else ''}")
    return bad


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_violations(edges) -> list[str]:
    """Private names (or private modules of a wing) imported from another wing."""
    bad = []
    for e in edges:
        src, tgt, name = e["source"], e["target"], e["name"]
        if wing(src) == wing(tgt):
            continue
        inner = tgt.split(".")[1:]
        shared_helper = len(inner) == 1  # a top-level module: the shared base
        private_module = any(_private(p) for p in inner) and not shared_helper
        if private_module or (name is not None and _private(name)):
            bad.append(f"{src}:{e['line']} imports {tgt}{'.' + name if name else ''} from wing {wing(tgt) or 'base'!r}")
    return bad


def check(sources: dict[str, str]) -> dict[str, object]:
    edges = import_edges(sources, extension_modules())
    return {"cycle": find_cycle(edges), "layers": layer_violations(edges), "private": private_violations(edges)}


@pytest.fixture(scope="module")
def sources():
    return module_sources()


def test_every_wing_is_a_package(sources):
    top = {m for m in sources if m.count(".") == 1}
    expected = {f"{ROOT}.{m}" for m in ("__main__", "_io", "_validate", "errors", "outputs", "progress", *WINGS)}
    assert top == expected, f"modules at the top besides the wings and the shared base: {sorted(top - expected)}"


def test_the_graph_sees_every_kind_of_import(sources):
    edges = import_edges(sources, extension_modules())
    seen = {(e["source"], e["target"]) for e in edges}
    assert ("piezohyst.identify.dispatch", "piezohyst.identify.varpro") in seen  # module level
    assert ("piezohyst.cli.demo", "piezohyst.papers.demo") in seen  # inside a function
    assert ("piezohyst.models.pi", "piezohyst._core") in seen  # from .. import _core


def test_no_import_cycle(sources):
    cycle = check(sources)["cycle"]
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_library_never_imports_papers_or_cli(sources):
    assert check(sources)["layers"] == []


def test_no_private_name_across_wings(sources):
    assert check(sources)["private"] == []


# -- the rules bite: each bad import added to a copy of the package's sources is reported --


def _with(sources, module, text):
    out = dict(sources)
    out[module] = out.get(module, "") + "\n" + text + "\n"
    return out


@pytest.mark.parametrize(
    "module, text",
    [
        ("piezohyst.models.pi", "from ..papers import experiments"),
        ("piezohyst.identify.core", "def f():\n    from ..cli.main import main"),
        ("piezohyst.signals.data", "import piezohyst.papers.demo"),
        ("piezohyst.plant.stage", "if TYPE_CHECKING:\n    from ..cli import main"),
    ],
)
def test_a_library_import_of_papers_or_cli_fails(sources, module, text):
    assert check(_with(sources, module, text))["layers"], text


@pytest.mark.parametrize(
    "module, text",
    [
        ("piezohyst.models.model", "def f():\n    from ..identify.dispatch import identify"),  # hidden, in a function
        ("piezohyst.identify.core", "from .varpro import identify_vp"),
        ("piezohyst.optimize.core", "from ..control import tuning"),
    ],
)
def test_an_import_cycle_fails(sources, module, text):
    assert check(_with(sources, module, text))["cycle"], text


def test_a_type_checking_import_is_no_cycle(sources):
    text = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..identify.dispatch import identify"
    result = check(_with(sources, "piezohyst.models.model", text))
    assert result["cycle"] is None and result["layers"] == [] and result["private"] == []


@pytest.mark.parametrize(
    "module, text",
    [
        ("piezohyst.control.tuning", "from ..identify.core import _check_loss"),
        ("piezohyst.papers.demo", "def f():\n    from ..signals.data import _import_h5py"),
        ("piezohyst.cli.simulate", "from .._io import _private_helper"),
        ("piezohyst.export.c", "from ..models import _secret"),
    ],
)
def test_a_private_import_across_wings_fails(sources, module, text):
    assert check(_with(sources, module, text))["private"], text


def test_private_names_within_a_wing_and_the_shared_base_pass(sources):
    ok = "from .core import _check_loss\nfrom .. import _core\nfrom .._validate import as_int"
    result = check(_with(sources, "piezohyst.identify.varpro", ok))
    assert result["private"] == []


def test_import_piezohyst_loads_no_application_wing():
    import subprocess
    import sys

    code = (
        "import sys, piezohyst, piezohyst.pi, piezohyst.stage; "
        "print(sorted(m for m in sys.modules if m.startswith(('piezohyst.papers', 'piezohyst.cli'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_application_wings_load_on_attribute_access():
    import subprocess
    import sys

    code = "import piezohyst as ph; print(ph.papers.mpi_seed2().kind, callable(ph.cli.main))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["gpi", "True"]


def test_import_piezohyst_loads_no_optional_heavy_library():
    """scipy, python-control, pandas, pyarrow, matplotlib and dask load where they are used:
    ``import piezohyst`` (every command's start) took 0.57 s with scipy.optimize imported at the
    top of one module, 0.27 s without."""
    import subprocess
    import sys

    heavy = ("scipy", "control", "pandas", "pyarrow", "matplotlib", "dask", "distributed")
    code = f"import sys, piezohyst; print(sorted(m for m in sys.modules if m.split('.')[0] in {heavy!r}))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
