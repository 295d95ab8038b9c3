"""Every public name has a numpydoc docstring with a runnable example and documents every
parameter (issue 17: "every public name has a docstring with an example, a test proves it").

Public means: each name of ``piezohyst.__all__``, of each wing's ``__all__`` (``models``,
``signals``, ``identify``, ``optimize``, ``plant``, ``control``, ``export``, ``papers``,
``errors``, ``fleet``, ``capi``) and of every other module's ``__all__`` (the command line's
modules and private ones aside) that is a class or a function, and every public method (functions, class and
static methods) of those classes, inherited from a base inside piezohyst included. Properties
must have a docstring. The docstrings are parsed by numpydoc, as the documentation site parses
them; the examples themselves run as doctests (``--doctest-modules`` in ``pyproject.toml``), so
an example that no longer holds fails the suite.
"""

from __future__ import annotations

import importlib
import inspect
import os
import pkgutil
import sys
from collections.abc import Iterator

import pytest

import piezohyst

if os.environ.get("CI"):
    import numpydoc.validate as npv  # the test extra installs it: never skipped in CI
else:
    npv = pytest.importorskip("numpydoc.validate", reason="numpydoc (the 'test' extra) checks the docstrings")

WINGS = ("models", "signals", "identify", "optimize", "plant", "control", "export", "papers", "errors", "fleet", "capi")

#: numpydoc's codes this test holds: no docstring, no Examples section, a parameter of the
#: signature not documented, a documented parameter the signature does not have.
CODES = {"GL08", "EX01", "PR01", "PR02"}


def _modules():
    # the wings first: a name is checked at the path of the wing that defines it; then every
    # other module's __all__ (a name a submodule lists is public too: piezohyst.control.filters.IRC),
    # the command line's modules and private ones (a leading underscore) aside
    for wing in WINGS:
        yield importlib.import_module(f"piezohyst.{wing}")
    yield piezohyst
    for info in pkgutil.walk_packages(piezohyst.__path__, "piezohyst."):
        parts = info.name.split(".")[1:]
        if parts[0] == "cli" or any(p.startswith("_") for p in parts):
            continue
        yield importlib.import_module(info.name)


def _public() -> dict[str, object]:
    """Every public class and function by the first path that names it."""
    found: dict[int, tuple[str, object]] = {}
    for module in _modules():
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if inspect.isclass(obj) or inspect.isfunction(obj):
                found.setdefault(id(obj), (f"{module.__name__}.{name}", obj))
    return dict(found.values())


def _members(cls: type) -> Iterator[tuple[str, object]]:
    """The public methods and properties of ``cls`` and of its bases inside piezohyst."""
    seen: set[str] = set()
    for base in cls.__mro__:
        if not base.__module__.startswith("piezohyst"):
            continue
        for name, member in vars(base).items():
            if name.startswith("_") or name in seen:
                continue
            seen.add(name)
            if isinstance(member, property):
                yield name, member
            elif isinstance(member, (classmethod, staticmethod)):
                yield name, member.__func__
            elif inspect.isfunction(member):
                yield name, member


def _names() -> tuple[list[str], list[str]]:
    """Dotted paths of the public callables and properties, each object once (a method
    inherited by several public classes is checked at the first class that has it)."""
    callables: dict[int, str] = {}
    properties: dict[int, str] = {}
    for path, obj in _public().items():
        callables.setdefault(id(obj), path)
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            for name, member in _members(obj):
                target = properties if isinstance(member, property) else callables
                target.setdefault(id(member), f"{path}.{name}")
    return sorted(callables.values()), sorted(properties.values())


CALLABLES, PROPERTIES = _names()


def _resolve(path: str) -> object:
    """The object a dotted path names (a property as the ``property`` object itself)."""
    module, _, rest = path.partition(".")
    obj: object = importlib.import_module(module)
    parts = rest.split(".")
    for k, part in enumerate(parts):
        name = ".".join([module, *parts[: k + 1]])
        if name in sys.modules:  # a wing, not the same-named attribute (piezohyst.identify)
            obj = sys.modules[name]
        elif inspect.isclass(obj) and isinstance(inspect.getattr_static(obj, part), property):
            obj = inspect.getattr_static(obj, part)
        else:
            obj = getattr(obj, part)
    return obj


def test_the_public_surface_is_what_we_check():
    # the package's main names and the methods of its classes are all covered
    assert len(CALLABLES) > 200 and len(PROPERTIES) > 20
    checked = {id(_resolve(path)) for path in CALLABLES}
    for name in (
        "piezohyst.models.PI",
        "piezohyst.models.HysteresisModel.simulate",
        "piezohyst.signals.load_record",
        "piezohyst.fleet.Runner.run",
        "piezohyst.fleet.RobustnessResult.worst",
        "piezohyst.capi.cflags",
        "piezohyst.control.filters.IRC",
        "piezohyst.models.MimoModel.simulate",
    ):
        assert id(_resolve(name)) in checked, name


@pytest.mark.parametrize("path", CALLABLES)
def test_numpydoc_docstring_with_example_and_every_parameter(path):
    doc = npv.get_doc_object(_resolve(path))
    errors = [(code, msg) for code, msg in npv.validate(doc)["errors"] if code in CODES]
    assert not errors, f"{path}: " + "; ".join(f"{c} {m}" for c, m in errors)
    assert any(">>>" in line for line in doc["Examples"]), f"{path}: the Examples section has no doctest (>>>)"


@pytest.mark.parametrize("path", PROPERTIES)
def test_property_has_a_docstring(path):
    prop = _resolve(path)
    assert isinstance(prop, property) and (prop.__doc__ or "").strip(), f"{path} has no docstring"
