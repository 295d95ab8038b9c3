"""What the commands share: the argument parser class, the one-line failure, argument checks and
readers of data and model files."""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TypedDict, Unpack

import numpy as np
import numpy.typing as npt

from ..errors import ParameterError
from ..outputs import Inputs, check_output, write_atomic

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..models.model import AnyModel
    from ..signals.data import Record

#: A float array (signals, columns of records).
FloatArray = npt.NDArray[np.float64]

#: A sample range from the command line, ``A:B`` with either side optional.
_Range = tuple[int | None, int | None]


class _RecordOptions(TypedDict, total=False):
    """The unit and time-tolerance options of a record file (:func:`_add_record_options`)."""

    time_unit: str | None
    input_unit: str | None
    output_unit: str | None
    time_rtol: float


class _Columns(_RecordOptions, total=False):
    """The column options of a record file, as :func:`~piezohyst.signals.data.load_record` takes them."""

    input: str | int | None
    output: str | int | None
    time: str | int | None
    fs: float | None
    dataset: str | None


class _Parser(argparse.ArgumentParser):
    """argparse whose usage errors are one line on stderr with exit code 2 (docs/spec.md §8, §10),
    and which refuses abbreviated long options (``--forc`` is not ``--force``: an abbreviation that
    a later option makes ambiguous would silently change meaning). Subcommand parsers are made by
    this class too, so the rule holds on every level."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        msg = " ".join(str(message).split())
        self.exit(2, f"{self.prog}: error: {msg} (see {self.prog} --help)\n")


def _quantity(unit: str) -> Callable[[str], float]:
    """argparse ``type=`` of an option that takes a quantity: a number with an optional unit
    suffix (``5um``, ``1kHz``, ``2ms``, ``150V``), converted to SI; a bare number is in ``unit``,
    the default unit each option's help names (:func:`piezohyst.signals.units.parse_quantity`:
    the one parser of quantities; ``1_000`` is refused). argparse adds the option's name to the
    message: ``argument --amp: '5kg': 'kg' is not a unit of length (m, mm, um (µm), nm)``."""
    from ..signals.units import parse_quantity

    def parse(text: str) -> float:
        try:
            return parse_quantity(text, unit, name="")
        except ParameterError as e:
            raise argparse.ArgumentTypeError(str(e).removeprefix(" = ")) from None

    parse.__name__ = f"quantity ({unit})"  # argparse's fallback message names the type
    return parse


class _Fail(ParameterError):
    """A bad command-line input; the message names the argument and the value."""


_FORMATS = (
    "DATA formats: delimited text (.csv .tsv .txt .dat .asc; comma, tab, semicolon or whitespace\n"
    "separated, decimal point or comma, with or without a header line, # % ; comment lines),\n"
    "Parquet (.parquet .pq), NumPy .npz/.npy, MATLAB .mat (v4-v7; v7.3 with h5py), HDF5 (.h5 .hdf5\n"
    ".he5, with h5py). A column COL is a name (header name, NPZ key, MATLAB variable or 's.field',\n"
    "HDF5 dataset path) or a 0-based index, an integer ('column 5' of a data README is 4). Units\n"
    "annotated in a column name ('t [ms]', 'x (um)', 'disp_um') or given by --time-unit,\n"
    "--input-unit, --output-unit are converted to SI (s, V, m) on loading; a time column without\n"
    "a unit is in seconds. Arrays larger than PIEZOHYST_MAX_ARRAY_BYTES (default 1 GiB) are refused."
)

#: The CLI's default tolerance of a time column: rounded or jittered stamps within 5 % of a step.
TIME_TOLERANCE = 0.05


def _add_record_options(p: argparse.ArgumentParser, output: bool = True) -> None:
    """The unit and time-tolerance options of a record file (after --time / --dataset)."""
    p.add_argument(
        "--time-unit",
        metavar="UNIT",
        help="unit of the --time column: s, ms, us, ns, min (default: a unit in the column name, else s)",
    )
    p.add_argument(
        "--input-unit",
        metavar="UNIT",
        help="unit of the input column, converted to SI: V, mV, kV, ... (default: a unit in the column name)",
    )
    if output:
        p.add_argument(
            "--output-unit",
            metavar="UNIT",
            help="unit of the output column, converted to SI: m, mm, um, nm, ... (default: a unit in the column name)",
        )
    p.add_argument(
        "--time-tolerance",
        metavar="REL",
        type=_number_arg,
        default=TIME_TOLERANCE,
        help="--time: how far rounded or jittered stamps may stray, relative to a step (default "
        f"{TIME_TOLERANCE:g}); the rate is a least-squares fit; a step of 1.5 steps or more is a gap (an error)",
    )


def _record_options(args: argparse.Namespace) -> _RecordOptions:
    """The values of :func:`_add_record_options`' options, as :func:`_load` takes them."""
    tol = args.time_tolerance
    if not math.isfinite(tol) or not 0 < tol < 1:
        raise _Fail(f"--time-tolerance = {tol:g} must be a fraction of a step, 0 < REL < 1")
    out: _RecordOptions = {"time_unit": args.time_unit, "input_unit": args.input_unit, "time_rtol": tol}
    if hasattr(args, "output_unit"):
        out["output_unit"] = args.output_unit
    return out


def _units_report(rec: Record) -> dict[str, dict[str, str | float]]:
    """The JSON of a record's unit conversions: role -> {from, to, scale, origin}."""
    return {role: conv.to_dict() for role, conv in rec.units.items()}


def _units_line(rec: Record) -> str:
    """One line of the units read: ``input V, output m (from um, header), time s (from ms)``."""
    parts = []
    for role, c in rec.units.items():
        if not c.si:
            parts.append(f"{role} as read (no unit given)")
        else:
            src = "" if c.source == c.si else f" from {c.source}"
            parts.append(f"{role} {c.si}{src} ({c.origin})")
    return ", ".join(parts)


def _column_help(role: str, default: str) -> str:
    return f"{role} column, by name or 0-based index ({default})"


def _atomic_savefig(fig: Figure, path: str | Path, name: str = "--plot", force: bool = False) -> None:
    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    write_atomic(path, writer=lambda tmp: fig.savefig(tmp, dpi=110, format=fmt), overwrite=force, name=name)


#: A number on the command line: ASCII digits, one optional decimal point and exponent, or
#: inf / nan (each option then says what range it takes). Python's float() and int() also take
#: "1_000" (digit separators) and other scripts' digits ("١٢"): not numbers here.
_FLOAT_TEXT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:inf|infinity|nan)", re.I)
_INT_TEXT = re.compile(r"[+-]?[0-9]+")


def _number_arg(text: str) -> float:
    """argparse ``type=`` of a real-valued option: a plain decimal number (see :data:`_FLOAT_TEXT`)."""
    if not _FLOAT_TEXT.fullmatch(text.strip()):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number{_why_not(text)}")
    return float(text)


def _count_arg(text: str) -> int:
    """argparse ``type=`` of an integer option: ASCII digits with an optional sign."""
    if not _INT_TEXT.fullmatch(text.strip()):
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer{_why_not(text)}")
    return int(text)


def _integer(text: str, message: str, *, signed: bool = False) -> int:
    """An integer inside an option's value (``--lag 3``, ``auto:M``): ASCII digits only (and a
    sign when ``signed``); else ``_Fail(message)``, with why when it looked like a number."""
    if not _INT_TEXT.fullmatch(text.strip()) or (not signed and text.strip()[:1] in "+-"):
        raise _Fail(message + _why_not(text))
    return int(text)


def _why_not(text: str) -> str:
    if "_" in text:
        return " (digit separators '_' are not accepted: write 1000, not 1_000)"
    if not text.isascii():
        return " (digits 0-9 only)"
    return ""


def _column(spec: str | None) -> str | int | None:
    """A column spec from the command line: an integer string (ASCII digits) is a 0-based index."""
    if spec is None:
        return None
    s = spec.strip()
    if _INT_TEXT.fullmatch(s):
        return int(s)
    return spec


def _check_fs(fs: float | None) -> float | None:
    if fs is None:
        return None
    if not math.isfinite(fs) or fs <= 0:
        raise _Fail(f"--fs = {fs:g} must be a finite sample rate > 0 Hz")
    return fs


def _check_count(value: int | None, name: str, minimum: int = 1) -> int | None:
    if value is not None and value < minimum:
        raise _Fail(f"{name} = {value} must be >= {minimum}")
    return value


def _existing_file(path: str | Path, name: str) -> Path:
    p = Path(path)
    if not p.exists():
        raise _Fail(f"{name} = '{path}': no such file")
    if p.is_dir():
        raise _Fail(f"{name} = '{path}' is a directory, not a file")
    return p


def _writable(path: str | Path, name: str, force: bool, inputs: Inputs | None = None) -> Path:
    """An output file of the command, checked before any work (:func:`piezohyst.outputs.check_output`:
    a regular file, not one of ``inputs``, replaced only with --force, in a writable directory)."""
    return check_output(path, name=name, overwrite=force, inputs=inputs)


_RANGE = re.compile(r"\s*([^:]*?)\s*:\s*([^:]*?)\s*")


def _parse_range(text: str, name: str) -> _Range:
    """``"A:B"`` with either side optional -> ``(A or None, B or None)``; non-negative integers."""
    m = _RANGE.fullmatch(text)
    if m is None:
        raise _Fail(f"{name} = '{text}' is not a sample range A:B (0-based, B exclusive; either side may be omitted)")
    out: list[int | None] = []
    for part in m.groups():
        if part == "":
            out.append(None)
        elif re.fullmatch(r"\+?[0-9]+", part):
            out.append(int(part))
        else:
            raise _Fail(f"{name} = '{text}': {part!r} is not a sample index (a non-negative integer)")
    return out[0], out[1]


def _resolve_range(spec: _Range, n: int, name: str, text: str, what: str = "DATA") -> tuple[int, int]:
    a = 0 if spec[0] is None else spec[0]
    b = n if spec[1] is None else spec[1]
    if a >= n:
        raise _Fail(f"{name} = '{text}': start {a} is beyond the end of {what} ({n} samples, indices 0..{n - 1})")
    if b > n:
        raise _Fail(
            f"{name} = '{text}': stop {b} is beyond the end of {what} ({n} samples; stop is exclusive, at most {n})"
        )
    if b <= a:
        raise _Fail(f"{name} = '{text}': start {a} is not before stop {b}")
    if b - a < 2:
        raise _Fail(f"{name} = '{text}' keeps {b - a} sample; at least 2 are needed")
    return a, b


def _parse_validate(text: str | None) -> tuple[_Range | None, Path | None]:
    """``--validate``: a sample range of DATA, or a file. Returns ``(range, None)`` or ``(None, path)``."""
    if text is None:
        return None, None
    if re.fullmatch(r"\s*\+?[0-9]*\s*:\s*\+?[0-9]*\s*", text):
        return _parse_range(text, "--validate"), None
    if Path(text).exists():
        return None, _existing_file(text, "--validate")
    if ":" in text and not re.search(r"[/\\.]", text):
        return _parse_range(text, "--validate"), None  # a malformed range: say why
    raise _Fail(f"--validate = '{text}': no such file (and not a sample range A:B)")


_ROLE = re.compile(r"(?<![\w-])(input|output|time|fs|dataset)(?= = | is not )")
_UNIT_ROLE = re.compile(r"(?<![\w-])(input|output|time)_unit(?= = )")


def _named(e: Exception, prefix: str = "") -> _Fail:
    """A loader's error with its argument names spelled as the options (``input =`` -> ``--input =``)."""
    msg = str(e)
    if isinstance(e, FileNotFoundError) and e.filename is not None and not msg.startswith(str(e.filename)):
        msg = f"{e.filename}: {e.strerror or msg}"
    msg = _UNIT_ROLE.sub(r"--\1-unit", msg).replace("time_rtol", "--time-tolerance")
    return _Fail(prefix + _ROLE.sub(r"--\1", msg))


def _load(path: str | Path, **kw: Unpack[_Columns]) -> Record:
    from ..signals.data import load_record

    try:
        return load_record(path, **kw)
    except (ValueError, TypeError, OSError, ImportError) as e:
        raise _named(e) from None


def _pct(x: float) -> str:
    return f"{x:.4g} %"


def _read_model(path: Path, d: Any = None) -> AnyModel:
    """The model in the file ``path`` (``d``: its content, when already read)."""
    from .._io import read_json_file
    from ..models.model import model_from_dict

    if d is None:
        d = read_json_file(path, "MODEL =")  # DataError: not JSON, too big, too deep, NaN, control characters
    if isinstance(d, dict):
        d = {k: v for k, v in d.items() if k != "fit"}  # the fit report is not part of the model
    try:
        return model_from_dict(d)
    except (ValueError, TypeError) as e:
        raise _Fail(f"MODEL = '{path}': {e}") from None
