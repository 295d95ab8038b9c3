"""Units of measured signals: parsed from column names (``t [ms]``, ``x (um)``, ``disp_um``) or
given, and converted to SI (s, V, m, N, A) when a record is loaded; and quantities written with
a unit suffix (``5um``, ``1kHz``, ``150V``, ``2ms``), the one parser of the command line's
quantities (:func:`parse_quantity`).

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

import math
import re
from decimal import Decimal
from typing import NamedTuple

from ..errors import ParameterError

__all__ = ["SI_UNITS", "UnitConversion", "parse_quantity", "parse_unit", "split_annotation"]

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
    time column seconds are assumed, other columns keep their values and ``si`` is ``""``).

    Parameters
    ----------
    source : str
        The unit as read from the header or given (``"ms"``, ``"um"``, ...).
    si : str
        The SI unit the values are converted to (``""`` when nothing was said).
    scale : float
        The factor: ``value_si = scale * value``.
    origin : str
        ``"header"``, ``"argument"`` or ``"assumed"``.

    Examples
    --------
    >>> from piezohyst.signals.units import parse_unit
    >>> c = parse_unit("ms", "time")
    >>> c
    UnitConversion(source='ms', si='s', scale=0.001, origin='argument')
    >>> c.scale * 250.0                                    # 250 ms in s
    0.25
    """

    source: str
    si: str
    scale: float
    origin: str

    def to_dict(self) -> dict[str, str | float]:
        """JSON-ready: ``{"from": ..., "to": ..., "scale": ..., "origin": ...}``.

        Returns
        -------
        dict
            The fields under the names the ``--json`` reports use.

        Examples
        --------
        >>> from piezohyst.signals.units import UnitConversion
        >>> UnitConversion("um", "m", 1e-6, "header").to_dict()
        {'from': 'um', 'to': 'm', 'scale': 1e-06, 'origin': 'header'}
        """
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
    """The conversion to SI of a unit spelling given for ``role`` (``ParameterError`` when unknown).

    Parameters
    ----------
    text : str
        The unit spelling, e.g. ``"ms"``, ``"mV"``, ``"um"`` or ``"µm"``.
    role : str
        The column it applies to (``"time"``, ``"input"``, ``"output"``...): a time column needs
        a unit of time, any other column a unit that is not one. Names the argument in errors.
    origin : str, default "argument"
        Where the spelling came from, copied to :attr:`UnitConversion.origin`.

    Returns
    -------
    UnitConversion

    Raises
    ------
    ParameterError
        When ``text`` is not a known unit or does not fit ``role``.

    Examples
    --------
    >>> from piezohyst.signals.units import parse_unit
    >>> parse_unit("ms", "time")
    UnitConversion(source='ms', si='s', scale=0.001, origin='argument')
    >>> parse_unit("um", "output").scale
    1e-06
    >>> parse_unit("V", "time")
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: time_unit = 'V' is not a unit of time (s, ms, us, ns, min)
    """
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
    ``"run_a"`` stays a name).

    Parameters
    ----------
    label : str
        A column name as read from a header.

    Returns
    -------
    name : str
        The label without its annotation.
    unit : str or None
        The unit spelling, or ``None`` when the label carries none.

    Examples
    --------
    >>> from piezohyst.signals.units import split_annotation
    >>> split_annotation("t [ms]"), split_annotation("disp_um"), split_annotation("run_a")
    (('t', 'ms'), ('disp', 'um'), ('run_a', None))
    """
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


# -- quantities: a number and an optional unit suffix ------------------------------------------
#: A plain decimal number: ASCII digits, one optional decimal point and exponent, or inf / nan.
#: Python's float() also takes "1_000" (digit separators) and other scripts' digits: not here.
_NUMBER = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:inf|infinity|nan)"
_QUANTITY = re.compile(rf"(?P<number>{_NUMBER})\s*(?P<unit>[A-Za-zµμ]+)?", re.IGNORECASE)
_NUMBER_ONLY = re.compile(_NUMBER, re.IGNORECASE)

#: What each SI unit measures, for the messages.
_DIMENSION = {
    "m": "length",
    "s": "time",
    "V": "voltage",
    "Hz": "frequency",
    "F": "capacitance",
    "N": "force",
    "A": "current",
}
#: The spellings of each SI unit a quantity may carry (beyond the signal units above).
_EXTRA: dict[str, tuple[str, float]] = {}
for _p, _f in _PREFIX.items():
    _EXTRA[_p + "Hz"] = ("Hz", _f)
    _EXTRA[_p + "F"] = ("F", _f)
_EXTRA.update({"hz": ("Hz", 1.0), "khz": ("Hz", 1e3), "mhz": ("Hz", 1e-3), "ms": ("s", 1e-3), "us": ("s", 1e-6)})
_EXTRA.update({"MHz": ("Hz", 1e6), "KHz": ("Hz", 1e3), "uf": ("F", 1e-6), "nf": ("F", 1e-9), "pf": ("F", 1e-12)})


def _quantity_unit(text: str) -> tuple[str, float] | None:
    """``(SI unit, scale)`` of a quantity's unit spelling, or ``None``."""
    hit = _EXTRA.get(text) or lookup_unit(text)
    if hit is None:
        t = text.replace("μ", "u").replace("µ", "u")
        hit = _EXTRA.get(t)
    return hit


def _examples(si: str) -> str:
    """Spellings of a unit for the messages: ``m, mm, um, nm``."""
    return {
        "m": "m, mm, um (µm), nm",
        "s": "s, ms, us (µs), ns",
        "V": "V, mV, kV",
        "Hz": "Hz, kHz, MHz",
        "F": "F, uF (µF), nF, pF",
        "N": "N, mN, kN",
        "A": "A, mA, uA",
    }.get(si, si)


def parse_quantity(text: object, unit: str, name: str = "value") -> float:
    """A quantity written as a number with an optional unit suffix, in SI.

    The one parser of the command line's quantities (``--amp 5um``, ``--freq 1kHz``, ``--fs
    10kHz``, ``150V``, ``2ms``). A bare number is in ``unit`` (the option's documented default
    unit), so it keeps its meaning; a suffix must measure the same thing as ``unit`` (a length
    for ``um``). Numbers are plain decimals (ASCII digits, a point, an exponent; ``inf`` and
    ``nan`` pass, for the option's own range check to name): ``1_000`` and other scripts'
    digits are refused.

    Parameters
    ----------
    text : str
        The quantity as written: ``"5"``, ``"5um"``, ``"5 µm"``, ``"1e3 Hz"``.
    unit : str
        The unit of a bare number: one of ``m``, ``mm``, ``um``, ``nm``, ``s``, ``ms``, ``V``,
        ``Hz``, ``kHz``, ``F``, ``uF`` ... (any spelling this module knows).
    name : str
        The argument the message names (``"--amp"``).

    Returns
    -------
    float
        The value in SI (m, s, V, Hz, F, N, A).

    Raises
    ------
    ParameterError
        Not a number, an unknown unit, or a unit of another quantity; the message names
        ``name``, the text and the units accepted.

    Examples
    --------
    >>> from piezohyst.signals.units import parse_quantity
    >>> parse_quantity("5", "um"), parse_quantity("5um", "um"), parse_quantity("0.5 mm", "um")
    (5e-06, 5e-06, 0.0005)
    >>> parse_quantity("1kHz", "Hz"), parse_quantity("10", "Hz"), parse_quantity("2ms", "s")
    (1000.0, 10.0, 0.002)
    >>> parse_quantity("150V", "V"), parse_quantity("1.8uF", "F")
    (150.0, 1.8e-06)
    >>> parse_quantity("5kg", "um", "--amp")
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: --amp = '5kg': 'kg' is not a unit of length (m, mm, um (µm), nm)
    >>> parse_quantity("1_000", "Hz", "--fs")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    piezohyst.errors.ParameterError: --fs = '1_000' is not a number ... (digit separators '_' are not accepted: ...)
    """
    base = _quantity_unit(unit)
    if base is None:
        raise ParameterError(f"unit = {unit!r} is not a known unit (the default unit of {name})")
    si, default_scale = base
    what = _DIMENSION.get(si, si)
    if not isinstance(text, str):
        raise ParameterError(f"{name} = {text!r} must be a number with an optional unit such as {unit!r}")
    m = _QUANTITY.fullmatch(text.strip())
    if m is None:
        why = ""
        if "_" in text:
            why = " (digit separators '_' are not accepted: write 1000, not 1_000)"
        elif not text.isascii() and not _QUANTITY.fullmatch(text.strip().rstrip("µμ")):
            why = " (digits 0-9 only)"
        raise ParameterError(f"{name} = {text!r} is not a number with an optional unit{why}")
    suffix = m.group("unit")
    if suffix is None:
        return _scaled(m.group("number"), default_scale)
    if _NUMBER_ONLY.fullmatch(m.group("number")) and m.group("number").lower().endswith(("inf", "infinity", "nan")):
        raise ParameterError(f"{name} = {text!r}: {m.group('number')} takes no unit")
    hit = _quantity_unit(suffix)
    if hit is None:
        raise ParameterError(f"{name} = {text!r}: {suffix!r} is not a unit of {what} ({_examples(si)})")
    if hit[0] != si:
        raise ParameterError(
            f"{name} = {text!r}: {suffix!r} is a unit of {_DIMENSION.get(hit[0], hit[0])}, "
            f"not of {what} ({_examples(si)})"
        )
    return _scaled(m.group("number"), hit[1])


def _scaled(number: str, scale: float) -> float:
    """The number written times ``scale``, rounded once: a power-of-ten scale shifts the decimal
    exponent (``1.8uF`` is ``float("1.8e-6")``, as Python reads ``1.8e-6``; ``1.8 * 1e-6`` would
    be ``1.8000000000000001e-06``)."""
    exponent = round(math.log10(scale))
    if 10.0**exponent == scale:
        return float(Decimal(number).scaleb(exponent))
    return float(number) * scale
