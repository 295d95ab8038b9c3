"""Units of measured signals: parsed from column names (``t [ms]``, ``x (um)``, ``disp_um``) or
given, and converted to SI (s, V, m, N, A) when a record is loaded.

Examples
--------
>>> from piezohyst.signals.units import parse_unit, split_annotation
>>> split_annotation("t [ms]"), split_annotation("x (um)"), split_annotation("disp_um"), split_annotation("u")
(('t', 'ms'), ('x', 'um'), ('disp', 'um'), ('u', None))
>>> c = parse_unit("µm", "output")
>>> c.si, c.scale
('m', 1e-06)
"""

from __future__ import annotations

import re
from typing import NamedTuple

from ..errors import ParameterError

__all__ = ["SI_UNITS", "UnitConversion", "parse_unit", "split_annotation"]

#: The SI base unit of each quantity a record may carry.
SI_UNITS = ("s", "V", "m", "N", "A")

_PREFIX = {"": 1.0, "k": 1e3, "M": 1e6, "m": 1e-3, "u": 1e-6, "µ": 1e-6, "μ": 1e-6, "n": 1e-9, "p": 1e-12}

# unit spelling -> (SI unit, scale to SI); built from the prefixes and the base units, plus the
# spellings the prefixes do not give
_TABLE: dict[str, tuple[str, float]] = {}
for _base in ("s", "V", "m", "N", "A"):
    for _p, _f in _PREFIX.items():
        if _base == "m" and _p == "M":
            continue  # Mm is not a stage travel
        _TABLE[_p + _base] = (_base, _f)
_TABLE.update(
    {
        "sec": ("s", 1.0),
        "msec": ("s", 1e-3),
        "usec": ("s", 1e-6),
        "min": ("s", 60.0),
        "micron": ("m", 1e-6),
        "microns": ("m", 1e-6),
        "um": ("m", 1e-6),
        "cm": ("m", 1e-2),
        "volt": ("V", 1.0),
        "volts": ("V", 1.0),
        "v": ("V", 1.0),
        "mv": ("V", 1e-3),
        "kv": ("V", 1e3),
        "Hz": ("", 1.0),
    }
)
del _TABLE["Hz"]  # a rate is not a signal unit


class UnitConversion(NamedTuple):
    """How a column was converted: from ``source`` (as read or given) to ``si`` by ``scale``
    (``value_si = scale * value``). ``origin`` tells where ``source`` came from: ``"header"``
    (a column-name annotation), ``"argument"`` (given), or ``"assumed"`` (nothing said; for a
    time column seconds are assumed, other columns keep their values and ``si`` is ``""``)."""

    source: str
    si: str
    scale: float
    origin: str

    def to_dict(self) -> dict[str, str | float]:
        """JSON-ready: ``{"from": ..., "to": ..., "scale": ..., "origin": ...}``."""
        return {"from": self.source, "to": self.si, "scale": self.scale, "origin": self.origin}


def known_units() -> list[str]:
    """Every unit spelling :func:`parse_unit` converts."""
    return sorted(_TABLE)


def lookup_unit(text: str) -> tuple[str, float] | None:
    """``(SI unit, scale)`` of a unit spelling, or ``None`` if unknown."""
    s = text.strip()
    hit = _TABLE.get(s)
    if hit is None:
        hit = _TABLE.get(s.replace("μ", "u").replace("µ", "u"))
    return hit


def parse_unit(text: object, role: str, origin: str = "argument") -> UnitConversion:
    """The conversion to SI of a unit spelling given for ``role`` (``ParameterError`` when unknown)."""
    if not isinstance(text, str) or not text.strip():
        raise ParameterError(f"{role}_unit = {text!r} must be a unit such as 's', 'ms', 'V', 'mV', 'um', 'nm'")
    hit = lookup_unit(text)
    if hit is None:
        raise ParameterError(
            f"{role}_unit = {text!r} is not a known unit; known: s ms us ns min, V mV kV uV, "
            "m mm um µm nm, N mN kN, A mA"
        )
    si, scale = hit
    if role == "time" and si != "s":
        raise ParameterError(f"time_unit = {text!r} is not a unit of time (s, ms, us, ns, min)")
    if role != "time" and si == "s":
        raise ParameterError(f"{role}_unit = {text!r} is a unit of time, not of a signal")
    return UnitConversion(text.strip(), si, scale, origin)


_BRACKETS = re.compile(r"^(?P<name>.*?)\s*(?:\[\s*(?P<a>[^\[\]]+?)\s*\]|\(\s*(?P<b>[^()]+?)\s*\))\s*$")
_SUFFIX = re.compile(r"^(?P<name>.+?)[_ ](?P<unit>[A-Za-zµμ]+)$")


def split_annotation(label: str) -> tuple[str, str | None]:
    """A column name and the unit it is annotated with: ``"t [ms]"``, ``"x (um)"`` (any unit
    spelling), or a suffix ``"disp_um"`` (only a unit :func:`parse_unit` knows, so that
    ``"run_a"`` stays a name)."""
    m = _BRACKETS.match(label)
    if m is not None and m.group("name"):
        return m.group("name"), m.group("a") or m.group("b")
    m = _SUFFIX.match(label)
    if (
        m is not None
        and lookup_unit(m.group("unit")) is not None
        and (len(m.group("unit")) >= 2 or m.group("unit") == "s")
    ):
        return m.group("name"), m.group("unit")
    return label, None


def conversion_for(role: str, label: str, given: str | None, stored: str | None = None) -> UnitConversion:
    """The conversion of a column: the unit ``given`` (an argument) wins over the unit
    ``stored`` with the column (an HDF5 ``units`` attribute, Parquet field metadata), which wins
    over the label's annotation; a time column without any is in seconds; an unknown unit read
    from the file is kept as it is (recorded, not converted)."""
    if given is not None:
        return parse_unit(given, role, "argument")
    if stored is not None and stored.strip():
        ann: str | None = stored.strip()
        origin = "file"
    else:
        _, ann = split_annotation(label)
        origin = "header"
    if ann is not None:
        hit = lookup_unit(ann)
        if hit is not None and (hit[0] == "s") == (role == "time"):
            return UnitConversion(ann, hit[0], hit[1], origin)
        if role != "time":
            return UnitConversion(ann, ann, 1.0, origin)  # a unit we do not convert: kept as it is
    if role == "time":
        return UnitConversion("s", "s", 1.0, "assumed")
    return UnitConversion("", "", 1.0, "assumed")
