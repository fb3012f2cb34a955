"""The ``flexopt`` command line: one subcommand per verb (``evaluate`` for now).

Exit codes: 0 done (also when a solve did not converge: that is a result, reported by a warning
line and ``converged: false`` in evaluation.json), 1 the run folder could not be written,
2 bad command line or bad study file (one line on stderr naming the key path), 130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from rich.console import Console
from rich.table import Table

from pipeline.errors import StudyError
from pipeline.evaluate import EvaluateOutcome, evaluate_study, versions
from pipeline.study import list_examples, load_study, resolve_study_path

__all__ = ["build_parser", "main"]

EXIT_OK, EXIT_WRITE, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr (exit 2), like a bad study file."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be >= 1")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The ``flexopt`` parser; each subcommand sets ``handler``."""
    parser = _Parser(
        prog="flexopt",
        description="Design compliant mechanisms by shape optimisation driven by nonlinear FE.",
    )
    parser.add_argument(
        "--version", action="version", version=f"flexopt {versions()['flexopt'] or '(source)'}"
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    evaluate = commands.add_parser(
        "evaluate",
        help="solve one study and write its response, summary and plot",
        description=(
            "Solve the study once and write response.csv, evaluation.json, the resolved "
            "study.yaml and force_displacement.png into a run folder."
        ),
    )
    evaluate.add_argument(
        "study",
        metavar="STUDY",
        help="a study YAML file, or a built-in example: " + ", ".join(list_examples()),
    )
    evaluate.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="run folder (created if needed; default runs/<name>-evaluate-<timestamp>)",
    )
    evaluate.add_argument(
        "--repeat",
        type=_positive_int,
        default=1,
        metavar="N",
        help="solve N times and record the median solve time (default 1)",
    )
    evaluate.set_defaults(handler=_evaluate)
    return parser


def _format_value(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else str(value)
    return str(value)


def _print_summary(outcome: EvaluateOutcome, console: Console) -> None:
    result, record = outcome.result, outcome.record
    table = Table(title=f"{record['study']} ({record['kind']})", title_justify="left")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    converged = _format_value(result.converged)
    if "rows" in result.summary:
        converged += f" ({result.summary['rows_converged']} of {result.summary['rows']} rows)"
    table.add_row("converged", converged)
    for key in result.headline or tuple(result.summary):
        value = result.summary.get(key)
        if value is not None:
            table.add_row(key, _format_value(value))
    table.add_row(
        "solve_time_s",
        f"{record['solve_time_s']:.3g}"
        + (f" (median of {record['repeat']})" if record["repeat"] > 1 else ""),
    )
    console.print(table)
    console.print(f"wrote {outcome.run_dir}", soft_wrap=True)


def _evaluate(args: argparse.Namespace) -> int:
    prog = "flexopt evaluate"
    try:
        path = resolve_study_path(args.study)
        study = load_study(path)
        outcome = evaluate_study(study, out=args.out, repeat=args.repeat, source=str(path))
    except StudyError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"{prog}: error: cannot write the run folder: {exc}", file=sys.stderr)
        return EXIT_WRITE
    _print_summary(outcome, Console(highlight=False))
    if not outcome.result.converged:
        print(
            f"{prog}: warning: the solve did not converge ({outcome.result.message}); "
            f"rows with converged=false are not results; see {outcome.run_dir / 'evaluation.json'}",
            file=sys.stderr,
        )
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``flexopt`` with ``argv`` (default ``sys.argv[1:]``) and return the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version and usage errors
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    if args.verbose:
        logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.handler(args))
    except KeyboardInterrupt:
        print("flexopt: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
