"""The normal generator's ziggurat tables (crates/core/src/num/ziggurat_tables.rs) are what their
generator script (crates/core/ziggurat_tables.py, exact decimal arithmetic) prints."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_checked_in_tables_are_the_scripts_output():
    out = subprocess.run(
        [sys.executable, str(ROOT / "crates" / "core" / "ziggurat_tables.py")],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    assert out == (ROOT / "crates" / "core" / "src" / "num" / "ziggurat_tables.rs").read_text()
    # the well-known constants of the 256-layer normal ziggurat (Marsaglia & Tsang 2000)
    assert "pub(crate) const ZIG_R: f64 = 3.654152885361009;" in out
    assert "ZIG_V: f64 = 0.0049286732339" in out
