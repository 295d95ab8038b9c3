"""Delimited text records (CSV, TSV, semicolon, whitespace), parsed by Apache Arrow's CSV reader.

The layout is sniffed from the first lines — byte-order mark, comment lines (``#``, ``%``,
``;``), the delimiter (tab, semicolon, comma or runs of whitespace), a decimal comma, a header
line (a first line whose fields all parse as numbers, empty fields included, is data) — and
the body is parsed by :func:`pyarrow.csv.read_csv` (multi-threaded, only the columns asked
for). Python touches the first lines only; lines and samples are never looped over in Python
except to name the line of an error.
"""

from __future__ import annotations

import codecs
import csv
import mmap
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DataError

FloatArray = npt.NDArray[np.float64]

PYARROW_HINT = "reading text records needs pyarrow: pip install pyarrow"

#: How many lines after the first data line the sniffer looks at.
SNIFF_LINES = 32

_COMMENT = (b"#", b"%")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:inf|infinity|nan)", re.IGNORECASE | re.ASCII)
_NUMBER_COMMA = re.compile(r"[+-]?(?:\d+,?\d*|,\d+)(?:[eE][+-]?\d+)?", re.ASCII)
# Arrow's pattern of a number (cells of a column Arrow could not type as numbers)
_ARROW_NUMBER = r"^\s*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\s*$|^\s*[+-]?(?:inf|infinity|nan)\s*$"
# whole lines the parser must not see: comments, whitespace-only lines
_JUNK = re.compile(rb"^(?:[ \t]*[#%][^\n]*|[ \t]+\r?)(?:\n|\Z)", re.MULTILINE)
_JUNK_SEMI = re.compile(rb"^(?:[ \t]*[#%;][^\n]*|[ \t]+\r?)(?:\n|\Z)", re.MULTILINE)


def _import_pyarrow() -> tuple[Any, Any, Any]:
    try:
        import pyarrow as pa
        import pyarrow.compute as pc
        import pyarrow.csv as pacsv
    except ImportError:
        raise ImportError(PYARROW_HINT) from None
    return pa, pacsv, pc


def _unquote(s: str) -> str:
    s = s.strip()
    if len(s) >= 2 and s[0] == s[-1] and s[0] in "\"'":
        return s[1:-1].strip()
    return s


def _is_number(s: str, decimal: str = ".") -> bool:
    u = _unquote(s)
    if decimal == ",":
        return _NUMBER_COMMA.fullmatch(u) is not None and any(c.isdigit() for c in u)
    return _NUMBER.fullmatch(u) is not None


def _split(line: str, delimiter: str) -> list[str]:
    """The fields of one line (quotes kept as they are; stripped later)."""
    if delimiter == " ":
        return line.split()
    if '"' in line:
        try:
            return [f.strip() for f in next(csv.reader([line.rstrip("\r\n")], delimiter=delimiter, quotechar='"'))]
        except csv.Error:  # a carriage return inside the line: split plainly, the parser names the cell
            pass
    return [f.strip() for f in line.rstrip().split(delimiter)]


def _decimal_of(rows: Sequence[Sequence[str]]) -> str:
    """``","`` when the sample cells use a decimal comma (and none a decimal point)."""
    comma = point = False
    for row in rows:
        for f in row:
            u = _unquote(f)
            if "," in u and _NUMBER_COMMA.fullmatch(u):
                comma = True
            elif "." in u and _NUMBER.fullmatch(u):
                point = True
    return "," if comma and not point else "."


def _sniff_delimiter(lines: Sequence[str]) -> str:
    """Tab, semicolon, comma or whitespace: the first that splits every sample line into the
    same number (> 1) of fields; else as the first line suggests (tab, comma, semicolon, spaces)."""
    consistent = []
    for d in ("\t", ";", ",", " "):
        if d != " " and not any(d in line for line in lines):
            continue
        counts = {len(_split(line, d)) for line in lines}
        if len(counts) == 1 and counts.pop() > 1:
            consistent.append(d)
    for d in consistent:  # prefer one whose data lines (after a possible header) are numbers
        data = [_split(line, d) for line in (lines[1:] or lines)]
        if all(_is_data_line(f, ".") or _is_data_line(f, ",") for f in data):
            return d
    if consistent:
        return consistent[0]
    s = lines[0]
    return "\t" if "\t" in s else "," if "," in s else ";" if ";" in s else " "


def _unit_cell(field: str) -> str:
    return _unquote(field).strip().strip("()[]").strip()


def _is_unit_row(fields: Sequence[str]) -> bool:
    """A row of unit names: no field a number, at least one a known unit."""
    from .units import lookup_unit

    cells = [_unit_cell(f) for f in fields]
    return not any(_is_number(c) for c in cells) and any(lookup_unit(c) is not None for c in cells if c)


def _is_data_line(fields: Sequence[str], decimal: str) -> bool:
    """Every field a number or empty, at least one a number."""
    return all(_is_number(f, decimal) or not _unquote(f) for f in fields) and any(_unquote(f) for f in fields)


def _map(path: Path) -> bytes | mmap.mmap:
    """The file's bytes, memory-mapped (no copy; Arrow parses the mapping) where it can be."""
    with open(path, "rb") as fh:
        try:
            return mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        except (ValueError, OSError):  # an empty file, a pipe
            return fh.read()


def _is_ascii(raw: bytes | mmap.mmap) -> bool:
    if isinstance(raw, bytes):
        return raw.isascii()
    return len(raw) == 0 or int(np.frombuffer(raw, dtype=np.uint8).max()) < 128


class TextTable:
    """A delimited text file: the layout sniffed at construction, the columns parsed by Arrow on
    :meth:`prepare` (or the first :meth:`read`). Keys are 0-based column indices."""

    kind = "text"

    def __init__(self, path: Path, delimiter: str | None, header: bool | str) -> None:
        self.source = str(path)
        self.path = path
        raw = _map(path)
        self.start = 0  # where the text begins (after a UTF-8 byte-order mark)
        if raw[:2] in (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE):
            try:
                raw = raw[:].decode("utf-16").encode("utf-8")
            except UnicodeDecodeError:
                raise DataError(f"{path}: has a UTF-16 byte-order mark but is not UTF-16 text") from None
        if raw.find(b"\x00") >= 0:
            raise DataError(f"{path}: contains NUL bytes: a binary file, not delimited text")
        if raw[:3] == codecs.BOM_UTF8:
            self.start = len(codecs.BOM_UTF8)
        if not _is_ascii(raw):
            text = raw[:]
            try:
                text.decode("utf-8")
            except UnicodeDecodeError:
                text = text.decode("latin-1").encode("utf-8")
            raw = text
        self.raw: bytes | mmap.mmap = raw
        self._scan_head(delimiter, header)
        self._arrays: dict[int, Any] | None = None
        self._read_keys: set[int] = set()

    # ---------------------------------------------------------------- layout

    def _next_line(self, pos: int) -> tuple[str, int]:
        end = self.raw.find(b"\n", pos)
        end = len(self.raw) if end < 0 else end + 1
        return self.raw[pos:end].decode("utf-8", errors="replace").rstrip("\r\n"), end

    def _scan_head(self, delimiter: str | None, header: bool | str) -> None:
        raw = self.raw
        path = self.source
        pos, lineno = self.start, 0
        first: int | None = None  # line number (0-based) of the first non-comment line
        first_pos = first_end = 0
        prev_comment: str | None = None  # the comment line right above it
        had_comment = False
        line = ""
        while pos < len(raw):
            line, nxt = self._next_line(pos)
            s = line.strip()
            if s and s[0] not in "#%":
                parts = s.split(";")
                if s[0] == ";" and delimiter != ";" and not (_is_data_line(parts, ".") or _is_data_line(parts, ",")):
                    prev_comment, had_comment = s, True  # a ';' comment (as some loggers write)
                else:
                    first, first_pos, first_end = lineno, pos, nxt
                    break
            elif s:
                prev_comment, had_comment = s, True
            else:
                prev_comment = None
            pos, lineno = nxt, lineno + 1
        if first is None:
            what = "has no data lines (only comments)" if had_comment else "is empty"
            raise DataError(f"{path}: {what}")
        # the first line and up to SNIFF_LINES lines after it that are not comments or blank
        sample: list[str] = [line]
        where: list[tuple[int, int]] = [(first, first_end)]  # (0-based line, end offset) of each
        p, k = first_end, first + 1
        while p < len(raw) and len(sample) <= SNIFF_LINES:
            ln, p = self._next_line(p)
            s = ln.strip()
            if s and s[0] not in "#%;":
                sample.append(ln)
                where.append((k, p))
            k += 1
        if delimiter is None:
            delimiter = _sniff_delimiter([ln.strip() if ln.strip() else ln for ln in sample])
        elif delimiter.isspace() and delimiter != "\t":
            delimiter = " "
        self.delimiter: str = delimiter
        rows = [_split(ln, delimiter) for ln in sample]
        self.decimal = _decimal_of(rows[1:] if len(rows) > 1 else rows)
        fields = rows[0]
        names: list[str] | None = None
        numeric = _is_data_line(fields, self.decimal)
        data_pos = first_pos
        self.header_line: int | None = None
        data_line = first
        if header is True or (header == "auto" and not numeric):
            names = [_unquote(f) for f in fields]
            data_pos, data_line = first_end, first + 1
            self.header_line = first
            if len(rows) > 1 and len(rows[1]) == len(names) and _is_unit_row(rows[1]):
                # a line of units under the names, as oscilloscope software writes: "(ms),(V),(V)"
                names = [f"{n} [{u}]" if u else n for n, u in zip(names, map(_unit_cell, rows[1]), strict=True)]
                data_line, data_pos = where[1][0] + 1, where[1][1]
        elif header == "auto" and prev_comment is not None:
            # a commented header right above the data, as numpy.savetxt(header=...) writes
            candidate = _split(prev_comment.lstrip("#%;").strip(), delimiter)
            if len(candidate) == len(fields) and not all(_is_number(f) for f in candidate):
                names = [_unquote(f) for f in candidate]
        self.names = names
        self.ncols = len(names) if names is not None else len(fields)
        self.first_line = first  # 0-based line of the first non-comment line
        self.data_pos = min(data_pos, len(raw))
        self.data_line = data_line  # 0-based line where data starts

    # ---------------------------------------------------------------- columns

    def columns(self) -> list[tuple[int, str]]:
        return [(j, self._label(j)) for j in range(self.ncols)]

    def _label(self, j: int) -> str:
        return self.names[j] if self.names is not None else f"column {j}"

    def resolve(self, role: str, spec: str | int) -> tuple[int, str]:
        if isinstance(spec, int):
            if spec >= self.ncols:
                raise DataError(
                    f"{self.source}: {role} = {spec} is out of range: the file has {self.ncols} columns "
                    f"(0-based indices 0..{self.ncols - 1})"
                )
            return spec, self._label(spec)
        if self.names is None:
            raise DataError(
                f"{self.source}: {role} = {spec!r} names a column, but the file has no header line; "
                f"use a 0-based column index 0..{self.ncols - 1} (or header=True)"
            )
        hits = [j for j, n in enumerate(self.names) if n == spec]
        if not hits:
            from .units import split_annotation

            hits = [j for j, n in enumerate(self.names) if split_annotation(n)[0] == spec]
        if not hits:
            raise DataError(f"{self.source}: {role} = {spec!r} is not a column; the columns are {self.names}")
        if len(hits) > 1:
            raise DataError(f"{self.source}: {role} = {spec!r} names columns {hits}; use a 0-based index")
        return hits[0], self.names[hits[0]]

    # ---------------------------------------------------------------- parsing

    def _body(self, clean: bool) -> bytes | memoryview:
        """The data lines as the parser sees them (zero-copy unless something must change):
        with ``clean``, comment and blank lines removed; runs of whitespace made one space for a
        whitespace-separated file; a delimiter of several characters made one."""
        body: bytes | memoryview = memoryview(self.raw)[self.data_pos :]
        junk = _JUNK if self.delimiter == ";" else _JUNK_SEMI
        if self.delimiter == " ":
            b = bytes(body).replace(b"\r", b"")
            b = junk.sub(b"", b)
            b = re.sub(rb"[ \t]+", b" ", b)
            return re.sub(rb"(?m)^ | $", b"", b)
        if clean:
            body = junk.sub(b"", bytes(body))
        if len(self.delimiter) > 1:
            body = bytes(body).replace(self.delimiter.encode(), b"\x1f")
        return body

    def _is_junk(self, text: str) -> bool:
        s = text.strip()
        return not s or s[0] in "#%" or (s[0] == ";" and self.delimiter != ";")

    def prepare(self, keys: Sequence[int]) -> None:
        """Parse the columns ``keys`` (all columns named later are parsed in one pass).

        Fast path: Arrow's streaming reader converts the columns to float64 batch by batch into
        arrays sized from the line count (peak memory: the file plus the columns), skipping
        comment and blank lines that its invalid-row handler sees as ragged. Any cell it cannot
        convert (a word, an empty field, a comment line with as many fields as the data) sends
        the file down the slow path: parsed as text (comment lines removed by a regular
        expression) so that :meth:`read` can name the first bad cell and its line."""
        keys = sorted(set(keys) | self._read_keys)
        if self._arrays is not None and set(keys) <= self._read_keys:
            return
        arrays = self._stream(keys)
        if arrays is None:
            comment_chars = b"#%" + (b"" if self.delimiter == ";" else b";")
            clean = any(bytes([c]) in self.raw[self.data_pos :] for c in comment_chars)
            table = self._parse(keys, clean=clean)
            if table.num_rows == 0:
                raise DataError(f"{self.source}: has no data rows")
            arrays = {k: table.column(f"c{k}") for k in keys}
        self._arrays = arrays
        self._read_keys = set(keys)

    def _options(self, keys: Sequence[int], bad: list[tuple[int, int]], types: Any) -> tuple[Any, Any, Any]:
        _, pacsv, _ = _import_pyarrow()

        def on_bad_row(row: Any) -> str:
            if self._is_junk(str(row.text)):
                return "skip"
            bad.append((int(row.expected_columns), int(row.actual_columns)))
            return "error"

        delim = "\x1f" if len(self.delimiter) > 1 else self.delimiter
        names = [f"c{j}" for j in range(self.ncols)]
        # Serial parsing: as fast as Arrow's CPU pool here (bench/load_csv.py, 0.14 s per 1M rows
        # either way) and no idle pool threads to race the interpreter's exit.
        return (
            pacsv.ReadOptions(column_names=names, use_threads=False),
            pacsv.ParseOptions(delimiter=delim, invalid_row_handler=on_bad_row),
            pacsv.ConvertOptions(
                include_columns=[names[k] for k in keys],
                column_types={names[k]: types for k in keys},
                null_values=[""],
                strings_can_be_null=False,
                quoted_strings_can_be_null=False,
                decimal_point=self.decimal,
            ),
        )

    def _stream(self, keys: Sequence[int]) -> dict[int, Any] | None:
        """The columns as float64 arrays, or ``None`` when a cell is not a number."""
        pa, pacsv, _ = _import_pyarrow()
        bad: list[tuple[int, int]] = []
        ro, po, co = self._options(keys, bad, pa.float64())
        body = self._body(False)
        chunks: dict[int, list[FloatArray]] = {k: [] for k in keys}
        n = 0
        try:
            reader = pacsv.open_csv(pa.py_buffer(body), read_options=ro, parse_options=po, convert_options=co)
            for batch in reader:
                for j, k in enumerate(keys):
                    col = batch.column(j)
                    if col.null_count:
                        return None
                    chunks[k].append(np.asarray(col.to_numpy(zero_copy_only=False), dtype=np.float64))
                n += batch.num_rows
        except Exception as e:  # ArrowInvalid: a ragged row (named) or a cell that is not a number
            if bad:
                self._raise_ragged()
            if "Empty CSV" in str(e):
                raise DataError(f"{self.source}: has no data rows") from None
            return None
        if n == 0:
            raise DataError(f"{self.source}: has no data rows")
        return {k: np.concatenate(c) for k, c in chunks.items()}

    def _parse(self, keys: Sequence[int], clean: bool) -> Any:
        """The columns as text (the slow path, for naming a bad cell)."""
        pa, pacsv, _ = _import_pyarrow()
        bad: list[tuple[int, int]] = []
        ro, po, co = self._options(keys, bad, pa.string())
        try:
            return pacsv.read_csv(
                pa.py_buffer(self._body(clean)), read_options=ro, parse_options=po, convert_options=co
            )
        except Exception as e:  # Arrow's ArrowInvalid, or anything else from a corrupt file
            if bad or "columns" in str(e):
                self._raise_ragged()
            if "Empty CSV" in str(e):
                raise DataError(f"{self.source}: has no data rows") from None
            raise DataError(f"{self.source}: not readable as delimited text ({type(e).__name__}: {e})") from None

    def read(self, role: str, key: int, label: str) -> FloatArray:
        _, _, pc = _import_pyarrow()
        if self._arrays is None or key not in self._read_keys:
            self.prepare([key])
        assert self._arrays is not None  # prepare() parsed the column
        col = self._arrays[key]
        import pyarrow as pa

        if isinstance(col, np.ndarray):
            values = col
        else:
            text = col if pa.types.is_string(col.type) else col.cast(pa.string())
            cells = pc.utf8_trim(text, characters=" \t\"'")
            if self.decimal == ",":
                cells = pc.replace_substring(cells, ",", ".")
            ok = np.asarray(pc.match_substring_regex(cells, _ARROW_NUMBER).fill_null(False))
            bad = np.flatnonzero(~ok)
            if bad.size:
                i = int(bad[0])
                self._raise_cell(role, key, label, i, str(text[i].as_py()))
            values = np.asarray(pc.cast(cells, pa.float64()).to_numpy(), dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            i = int(bad[0])
            raise DataError(
                f"{self.source}: {role}[{i}] = {values[i]} is not finite (line {self.line_of(i)}, column {label!r})"
            )
        return values

    def close(self) -> None:
        """Drop the parsed columns."""
        self._arrays = None

    # ---------------------------------------------------------------- errors (not on the fast path)

    def _data_lines(self) -> list[tuple[int, str]]:
        """``(1-based line number, text)`` of every data line: the error path only."""
        text = self.raw[:].decode("utf-8", errors="replace")
        out = []
        for i, line in enumerate(text.split("\n")[self.data_line :], start=self.data_line + 1):
            s = line.strip()
            if not s or s[0] in "#%" or (s[0] == ";" and self.delimiter != ";"):
                continue
            out.append((i, line))
        return out

    def line_of(self, sample: int) -> int:
        """The 1-based line number of data row ``sample``."""
        lines = self._data_lines()
        return lines[sample][0] if sample < len(lines) else -1

    def _raise_cell(self, role: str, key: int, label: str, i: int, cell: str) -> None:
        raise DataError(
            f"{self.source}: line {self.line_of(i)} (sample {i}), {role} column {label!r} (index {key}): "
            f"{cell!r} is not a number"
        )

    def _raise_ragged(self) -> None:
        for lineno, line in self._data_lines():
            delim = self.delimiter
            n = len(_split(line, delim))
            if n != self.ncols:
                where = "the header" if self.header_line is not None else f"line {self.first_line + 1}"
                raise DataError(
                    f"{self.source}: line {lineno} has {n} fields, expected {self.ncols} as on {where} "
                    f"(delimiter {self.delimiter!r})"
                )
        raise DataError(f"{self.source}: rows of unequal length (delimiter {self.delimiter!r})")
