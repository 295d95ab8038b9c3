"""``piezohyst demo``: both papers end to end on the virtual stage (:mod:`piezohyst.papers.demo`)."""

from __future__ import annotations

import argparse
import json

from .common import _count_arg, _Parser


def _demo_parser(sub: argparse._SubParsersAction[_Parser]) -> None:
    d = sub.add_parser(
        "demo",
        help="both papers end to end on the virtual stage: identify, compensate, track, "
        "report (index.html, report.md, figures, results.json)",
    )
    d.add_argument("--out", default="piezohyst-report", help="output directory (default: ./piezohyst-report)")
    d.add_argument("--force", action="store_true", help="overwrite an existing report")
    d.add_argument("--quick", action="store_true", help="smaller optimizer budgets (about 30 s)")
    d.add_argument("--seed", type=_count_arg, default=0, help="seed of the measurements and optimizers (default 0)")
    d.add_argument("--json", action="store_true", help="print the numbers as JSON")


def _quiet(*a: object, **k: object) -> None:
    """Prints nothing (the demo's progress with ``--json``)."""


def _demo(args: argparse.Namespace) -> None:
    from ..papers.demo import run_demo

    quiet = _quiet if args.json else print
    numbers = run_demo(args.out, force=args.force, quick=args.quick, seed=args.seed, print_fn=quiet, name="--out")
    if args.json:
        print(json.dumps(numbers, indent=2))
