"""The .pyi stub describes the compiled module exactly."""

import ast
import inspect
from pathlib import Path

import piezohyst
from piezohyst import _core

STUB = Path(piezohyst.__file__).with_name("_core.pyi")


def stub_functions():
    tree = ast.parse(STUB.read_text())
    funcs = {n.name: [a.arg for a in n.args.args] for n in tree.body if isinstance(n, ast.FunctionDef)}
    names = {t.target.id for t in tree.body if isinstance(t, ast.AnnAssign)}
    names |= {n.name for n in tree.body if isinstance(n, ast.ClassDef)}
    return funcs, names


def test_stub_lists_every_public_name_and_nothing_else():
    funcs, names = stub_functions()
    public = {n for n in dir(_core) if not n.startswith("_")} | {"__version__"}
    declared = set(funcs) | (names - {"Array1", "Array2"})
    assert declared == public


def test_stub_signatures_match_compiled_signatures():
    funcs, _ = stub_functions()
    for name, args in funcs.items():
        sig = inspect.signature(getattr(_core, name))
        assert list(sig.parameters) == args, name


def test_stub_classes_are_final_and_frozen():
    tree = ast.parse(STUB.read_text())
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            assert any(getattr(d, "id", None) == "final" for d in node.decorator_list), node.name
            cls = getattr(_core, node.name)
            try:
                cls.__new__(cls).x = 1  # an attribute may not be set on a frozen class
            except (AttributeError, TypeError):
                pass
            else:
                raise AssertionError(f"{node.name} accepts new attributes")
