"""Writes the regression files of the reader fuzz targets (tests/signals/test_fuzz_readers.py)
and their manifest ``cases.json``: each a minimal file of a kind the targets found breaking the
property, with what the loader did before (``was``) and what it must do (``expect``).

    python tests/data/fuzz_regressions/make_cases.py tests/data/fuzz_regressions
"""

from __future__ import annotations

import io
import json
import struct
import sys
from pathlib import Path

import numpy as np
import scipy.io


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    cases = []
    t = np.arange(64) / 100.0
    u = 1.5 + np.sin(2 * np.pi * 3 * t)
    y = 0.7 * u

    def case(file: str, kwargs: dict[str, object], was: str, expect: str = "DataError") -> None:
        cases.append({"file": file, "kwargs": kwargs, "expect": expect, "was": was})

    # 1. a quote and a carriage return inside one line of delimited text: csv.Error from the sniffer
    rows = "".join(f"{a:.6f};{b:.9f};{c:.9f}\r\n".replace(".", ",") for a, b, c in zip(t, u, y, strict=True))
    text = ("t [s];u [V];y [um]\r\n" + rows).encode()
    (out / "quote_cr_in_line.txt").write_bytes(text[:40] + b'"' + text[40:45] + b"\r" + text[45:])
    case(
        "quote_cr_in_line.txt",
        {"input": 1, "output": 2, "time": 0},
        "_csv.Error: new-line character seen in unquoted field (not a PiezohystError: a traceback)",
    )

    # 2. an NPY header declaring 10^10 x 3 doubles over 1.5 kB of data: refused before allocating
    buf = io.BytesIO()
    np.save(buf, np.column_stack([t, u, y]))
    raw = buf.getvalue()
    hdr_len = struct.unpack("<H", raw[8:10])[0]
    header = raw[10 : 10 + hdr_len].replace(b"(64, 3)", b"(10000000000, 3)").rstrip(b" \n")
    header += b" " * ((64 - (10 + len(header) + 1) % 64) % 64) + b"\n"
    (out / "npy_huge_shape.npy").write_bytes(raw[:8] + struct.pack("<H", len(header)) + header + raw[10 + hdr_len :])
    case(
        "npy_huge_shape.npy",
        {"input": 1, "output": 2, "fs": 100.0},
        "DataError after numpy tried to allocate the declared 224 GiB (a MemoryError here; granted where memory "
        "is overcommitted)",
    )

    # 3. an NPY header declaring more rows than the file holds
    header = raw[10 : 10 + hdr_len].replace(b"(64, 3)", b"(6400, 3)")
    (out / "npy_truncated.npy").write_bytes(raw[:10] + header + raw[10 + hdr_len :])
    case("npy_truncated.npy", {"input": 1, "output": 2, "fs": 100.0}, "DataError from numpy, after allocating")

    # 4. a MAT v4 header of an unknown byte order ('VAX D-float'): scipy warned "may be corrupt"
    buf = io.BytesIO()
    scipy.io.savemat(buf, {"u": u, "y": y}, format="4")
    raw4 = bytearray(buf.getvalue())
    raw4[:4] = struct.pack("<i", struct.unpack("<i", raw4[:4])[0] + 2000)  # M digit 2: VAX D-float
    (out / "mat4_vax_order.mat").write_bytes(bytes(raw4))
    case(
        "mat4_vax_order.mat",
        {"input": "u", "output": "y", "fs": 100.0},
        "loaded (64 samples) with scipy's UserWarning 'returned data may be corrupt'",
    )

    # 5. a sparse MAT v4 header whose dimensions overflow scipy's int32 arithmetic
    raw4 = bytearray(buf.getvalue())
    raw4[0:4] = struct.pack("<i", 2)  # a sparse matrix
    raw4[4:8] = struct.pack("<i", 2**31 - 1)
    raw4[8:12] = struct.pack("<i", 3)
    (out / "mat4_huge_dims.mat").write_bytes(bytes(raw4))
    case(
        "mat4_huge_dims.mat",
        {"input": "u", "output": "y", "fs": 100.0},
        "DataError, after two RuntimeWarnings (overflow encountered in scalar multiply) on stderr",
    )

    # 6. an NPZ archive cut short: a corrupt zip (np.load leaked its own file handle)
    buf = io.BytesIO()
    np.savez_compressed(buf, t=t, u=u, y=y)
    raw = buf.getvalue()
    (out / "npz_cut.npz").write_bytes(raw[: len(raw) // 2])
    case(
        "npz_cut.npz",
        {"input": "u", "output": "y", "time": "t"},
        "DataError, and a ResourceWarning: np.load leaked its own file handle",
    )
    (out / "cases.json").write_text(json.dumps(cases, indent=2) + "\n")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
