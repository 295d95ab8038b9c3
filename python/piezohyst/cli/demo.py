"""``piezohyst demo``: both papers end to end on the virtual stage (:mod:`piezohyst.papers.demo`)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from .common import _count_arg, _Fail, _Parser


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
    d.add_argument(
        "--readme",
        metavar="FILE",
        help="replace the section between <!-- demo:begin --> and <!-- demo:end --> of FILE with the run's "
        "headline table (seed and quick/full said in it): the README's numbers are the demo's, never typed",
    )
    d.add_argument(
        "--report-only",
        action="store_true",
        help="do not run: take the numbers of the report already in --out (its results.json), for --readme",
    )


def _quiet(*a: object, **k: object) -> None:
    """Prints nothing (the demo's progress with ``--json``)."""


def _demo(args: argparse.Namespace) -> None:
    from ..papers.benchmarks import check_readme, update_readme
    from ..papers.demo import run_demo
    from ..papers.report import README_BEGIN, README_END, readme_markdown

    if args.readme:
        check_readme(Path(args.readme))  # before the run: a bad --readme costs nothing
    quiet = _quiet if args.json else print
    if args.report_only:
        if not args.readme and not args.json:
            raise _Fail("--report-only takes the numbers of an existing report: give --readme FILE and/or --json")
        numbers = _read_results(Path(args.out) / "results.json")
    else:
        numbers = run_demo(args.out, force=args.force, quick=args.quick, seed=args.seed, print_fn=quiet, name="--out")
    if args.readme:
        generator = "piezohyst demo --readme" + (" (quick run)" if numbers.get("quick") else "")
        update_readme(
            Path(args.readme), readme_markdown(numbers), begin=README_BEGIN, end=README_END, generator=generator
        )
        quiet(f"{args.readme}: the demo section now holds this run's numbers")
    if args.json:
        print(json.dumps(numbers, indent=2))


def _read_results(path: Path) -> dict[str, Any]:
    """The numbers of a report the demo wrote (``--report-only``)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise _Fail(f"--out: no report in '{path.parent}' ({path.name} is missing); run piezohyst demo first") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise _Fail(f"--out: '{path}' is not the demo's results.json: {e}") from None
    if not isinstance(doc, dict) or not {"seed", "quick", "identification", "seed1", "seed2"} <= set(doc):
        raise _Fail(f"--out: '{path}' is not the demo's results.json (seed, quick, identification, seed1, seed2)")
    return doc
