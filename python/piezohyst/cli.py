"""The ``piezohyst`` command line."""
from __future__ import annotations

import argparse
import json
import sys

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="piezohyst", description="Piezo hysteresis modelling, identification and compensation.")
    p.add_argument("--debug", action="store_true", help="show a traceback on errors")
    sub = p.add_subparsers(dest="command", required=True)
    d = sub.add_parser("demo", help="forward and exact inverse of the seed-2 MPI model; writes a loop figure")
    d.add_argument("--out", default="piezohyst-report", help="output directory (default: ./piezohyst-report)")
    d.add_argument("--force", action="store_true", help="overwrite existing output files")
    d.add_argument("--json", action="store_true", help="print the numbers as JSON")
    return p


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "demo":
            from .demo import run_demo

            quiet = (lambda *a, **k: None) if args.json else print
            numbers = run_demo(args.out, force=args.force, print_fn=quiet)
            if args.json:
                print(json.dumps(numbers, indent=2))
        return 0
    except (ValueError, TypeError, OSError) as e:
        if args.debug:
            raise
        print(f"piezohyst: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
