"""The ``flexopt`` command line: one subcommand per verb (``evaluate``, ``run``, ``status``,
``report``, ``export``; ``list``, ``init`` and ``schema`` help write a study).

Exit codes: 0 done (also when a solve did not converge or no feasible design was found: those are
results, reported by a warning line and in the run folder), 1 the run folder (or standard output:
full, closed) could not be written,
the run failed, or the design could not be exported, 2 bad command line or bad study file (one line
on stderr naming the key path; nothing is written), 130 interrupted (Ctrl-C), 143 stopped by
SIGTERM (like Ctrl-C: the run folder keeps what was done, status `stopped`, resumable).

Only this module prints; progress goes to stderr, results to stdout.
"""

from __future__ import annotations

import argparse
import atexit
import builtins
import contextlib
import json
import logging
import math
import os
import shlex
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from flexopt.pipeline.errors import FlexoptError, StudyError, Terminated, printable
from flexopt.pipeline.evaluate import MAX_REPEAT, EvaluateOutcome, evaluate_study, versions
from flexopt.pipeline.progress import RunProgress, format_generation
from flexopt.pipeline.study import list_examples, load_study, resolve_study_path, workers_problem
from rich.console import Console
from rich.table import Table
from rich.text import Text

if TYPE_CHECKING:  # pipeline.run imports pymoo (~1 s): only `run` and `export` pay for it
    from flexopt.pipeline.run import RunOutcome

__all__ = ["build_parser", "format_generation", "main"]

EXIT_OK, EXIT_WRITE, EXIT_USAGE, EXIT_INTERRUPTED, EXIT_TERMINATED = 0, 1, 2, 130, 143


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr (exit 2), like a bad study file."""

    def error(self, message: str) -> NoReturn:
        message = " ".join(message.split())  # one line, whatever argparse echoes
        if len(message) > 300:  # an option's value is echoed: cut a pasted megabyte
            message = message[:200] + " ... " + message[-95:]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _echo(text: str) -> str:
    """An option's value quoted for an error line, cut to 40 characters."""
    return repr(text if len(text) <= 40 else text[:37] + "...")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{_echo(text)} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be >= 1")
    return value


def _repeat(text: str) -> int:
    value = _positive_int(text)
    if value > MAX_REPEAT:
        raise argparse.ArgumentTypeError(
            f"{value} is more than {MAX_REPEAT}; repeats only time the solve"
        )
    return value


def _workers(text: str) -> int:
    value = _positive_int(text)
    problem = workers_problem(value)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return value


def _path(text: str) -> Path:
    """A path option: never empty (``Path('')`` is the current folder, which nobody means)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty; give a path")
    return Path(text)


def _nonnegative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{_echo(text)} is not a whole number") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} must be >= 0")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{_echo(text)} is not a number") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{_echo(text)} must be a number > 0 (seconds)")
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
        type=_path,
        metavar="DIR",
        help="run folder (created if needed; default runs/<name>-evaluate-<timestamp>)",
    )
    evaluate.add_argument(
        "--repeat",
        type=_repeat,
        default=1,
        metavar="N",
        help=f"solve N times and record the median solve time (default 1, at most {MAX_REPEAT})",
    )
    evaluate.set_defaults(handler=_evaluate)

    run = commands.add_parser(
        "run",
        help="optimise a study: best design, every evaluation, plots, STL and a report",
        description=(
            "Optimise the study's design problem with a genetic algorithm and write every "
            "evaluation, the history, the best design, its response and plots, best.stl and "
            "report.md into a run folder."
        ),
    )
    run.add_argument(
        "study",
        metavar="STUDY",
        nargs="?",
        help="a study YAML file, or a built-in example: "
        + ", ".join(list_examples())
        + " (with --resume: optional, checked against the run's study)",
    )
    run.add_argument(
        "--out",
        type=_path,
        metavar="DIR",
        help="run folder (created; must not hold a run yet; default runs/<name>-run-<timestamp>)",
    )
    run.add_argument(
        "--resume",
        type=_path,
        metavar="RUN_DIR",
        help="finish an interrupted or killed run: replay it from its seed, serving every "
        "finished evaluation from RUN_DIR/evaluations.jsonl (refused if the study changed)",
    )
    run.add_argument(
        "--workers",
        type=_workers,
        metavar="N",
        help="worker processes (default: parallel.workers, else one per core; 1 = serial in "
        "this process)",
    )
    run.add_argument(
        "--dask",
        metavar="ADDRESS",
        help="evaluate on the Dask cluster whose scheduler is at ADDRESS (tcp://host:8786)",
    )
    run.add_argument(
        "--eval-timeout",
        type=_positive_float,
        metavar="S",
        help="time limit of one evaluation in s (default parallel.eval_timeout_s, else none); "
        "a design over it is an infeasible row",
    )
    run.add_argument(
        "--quick",
        action="store_true",
        help="a small smoke run: optimiser.quick_pop_size designs for optimiser.quick_n_gen "
        "generations",
    )
    run.add_argument(
        "--seed",
        type=_nonnegative_int,
        metavar="N",
        help="random seed, replacing optimiser.seed (the same seed gives the same run)",
    )
    run.add_argument(
        "-q", "--quiet", action="store_true", help="no progress bar and no line per generation"
    )
    run.set_defaults(handler=_run)

    status = commands.add_parser(
        "status",
        help="progress of a running or finished run",
        description=(
            "Show a run's progress from its folder: generation, evaluations, feasible share, "
            "best so far, status, elapsed time and an estimate of the time left."
        ),
    )
    status.add_argument("run_dir", type=_path, metavar="RUN_DIR", help="a folder of flexopt run")
    status.set_defaults(handler=_status)

    report = commands.add_parser(
        "report",
        help="rebuild a run's report and plots from its folder",
        description=(
            "Rebuild best.json, the best design's response, the plots, best.stl and report.md "
            "from the evaluations in a run folder (nothing is optimised again; only the best "
            "design is solved again for its response)."
        ),
    )
    report.add_argument("run_dir", type=_path, metavar="RUN_DIR", help="a folder of flexopt run")
    report.set_defaults(handler=_report)

    export = commands.add_parser(
        "export",
        help="write one design of a run or evaluate folder as STL, DXF, STEP, VTU or a study "
        "(YAML)",
        description=(
            "Rebuild a design of a run (from its study.yaml), or the design of a flexopt "
            "evaluate folder, and write its part in mm: binary STL (to print; laid flat and "
            "aligned to the bed axes), DXF (the outline with its holes, to cut or sketch on) or "
            "STEP (needs pip install 'flexopt[step]'), these two in the design frame (where the "
            "kind draws the part: a spring's axis at the origin); --frame chooses. A sheet part "
            "(the leaf-spring joint's leaf) is laid flat as its flat profile, and its DXF is "
            "that profile. --format vtu writes the design's beam shapes per load step and its "
            "stress field for ParaView (in the design frame). --format cad writes a "
            "parametric build123d script of the part (its dimensions named at the top), 3mf "
            "the part with the print settings it assumes, sheet its one-page print sheet. "
            "--format yaml writes the design "
            "as a study instead (the run's study "
            "with the design's values set), which flexopt evaluate solves to the numbers of "
            "best.json."
        ),
    )
    export.add_argument(
        "run_dir",
        type=_path,
        metavar="RUN_DIR",
        help="a folder of flexopt run or of flexopt evaluate",
    )
    export.add_argument(
        "--design",
        default="best",
        metavar="best|INDEX",
        help="best (best.json, the default) or the index of a row of evaluations.csv",
    )
    export.add_argument(
        "--format",
        choices=("stl", "dxf", "step", "vtu", "cad", "3mf", "sheet", "yaml"),
        default=None,
        help="file format (default: what --out ends in, else stl); cad: the parametric "
        "build123d script (best_cad.py), 3mf: the part with its print settings (best.3mf), "
        "sheet: the one-page print sheet (print_sheet.md)",
    )
    export.add_argument(
        "--out",
        type=_path,
        metavar="FILE",
        help=(
            "file to write (default RUN_DIR/best.FORMAT, RUN_DIR/design-INDEX.FORMAT, or "
            "RUN_DIR/design.FORMAT in an evaluate folder; FORMAT yaml: a study file)"
        ),
    )
    export.add_argument(
        "--frame",
        choices=("design", "bed"),
        default=None,
        help="design (the kind's coordinates) or bed (laid flat, first quadrant); default: "
        "bed for stl, design for dxf, step and vtu (only design)",
    )
    export.set_defaults(handler=_export)
    _add_study_tools(commands)
    from flexopt.pipeline.cli_print import add_print_commands

    add_print_commands(commands)  # coupon, calibrate, compare, retrim (docs/print_to_part.md)
    return parser


def _add_study_tools(commands: Any) -> None:
    """The subcommands that help write a study: ``list``, ``init`` and ``schema``."""
    listing = commands.add_parser(
        "list",
        help="study kinds (built-in and plugins) and built-in studies, one line each",
        description=(
            "List every study kind (geometry.kind: built-in, or from a plugin package through "
            "the flexopt.kinds entry points) and every built-in study, one line each with what "
            "it designs, and any plugin kind that could not be loaded, with the reason."
        ),
    )
    listing.set_defaults(handler=_list)

    init = commands.add_parser(
        "init",
        help="write a commented starter study of a kind",
        description=(
            "Write a commented starter study named NAME: the kind's built-in study with its "
            "comments (or, for a kind without one, keys and their descriptions from its schema). "
            "It loads as written: flexopt evaluate NAME.yaml. An existing file is never "
            "overwritten."
        ),
    )
    init.add_argument("name", metavar="NAME", help="the study's name (names its run folders)")
    source = init.add_mutually_exclusive_group()
    source.add_argument(
        "--kind", metavar="K", help="the study kind (geometry.kind; default polyline_beam)"
    )
    source.add_argument(
        "--example", metavar="STUDY", help="start from this built-in study (see flexopt list)"
    )
    init.add_argument(
        "--out", type=_path, metavar="FILE", help="file to write (default ./NAME.yaml)"
    )
    init.set_defaults(handler=_init)

    schema = commands.add_parser(
        "schema",
        help="the JSON schema of a study file, for editor completion",
        description=(
            "Print the JSON schema of a study file: of one kind with --kind, else of any kind "
            "(oneOf the kinds, told apart by geometry.kind). Editors use it for completion and "
            "checking as you type (docs/usage.md, 'Editor completion')."
        ),
    )
    schema.add_argument("--kind", metavar="K", help="only this kind's study (default: any kind)")
    schema.add_argument(
        "--out", type=_path, metavar="FILE", help="write it to FILE (default: standard output)"
    )
    schema.set_defaults(handler=_schema)


def print(
    *values: Any, sep: str = " ", end: str = "\n", file: Any = None, flush: bool = False
) -> None:
    """:func:`builtins.print` for every line this module prints, with each control character
    of the values escaped (:func:`pipeline.errors.printable`): a name, a path, a plugin's text
    or an exception's message cannot retitle, clear or move the user's terminal."""
    shown = (printable(v, keep_newlines=True) for v in values)
    builtins.print(*shown, sep=sep, end=end, file=file, flush=flush)


class _PrintableFormatter(logging.Formatter):
    """Log lines of ``-v`` with control characters escaped, as every line this module prints."""

    def format(self, record: logging.LogRecord) -> str:
        return printable(super().format(record), keep_newlines=True)


def _format_value(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else str(value)
    return str(value)


def _print_verdict(verdicts: Sequence[Any], title: str, console: Console) -> None:
    """The verdict first: one line per requirement (value, bound, margin, MET / NOT MET), then
    the overall word. Never 'feasible' alone: a design is judged by what it must meet."""
    from flexopt.optimise.requirements import verdict_lines

    console.print(printable(f"{title}: requirements"), soft_wrap=True, markup=False)
    for line in verdict_lines(verdicts):
        console.print(printable(line), soft_wrap=True, markup=False)


def _print_robustness(record: dict[str, Any], console: Console) -> None:
    """One line per requirement with the share of scatter samples that meet it."""
    from flexopt.pipeline.robustness import robustness_lines

    for line in robustness_lines(record.get("robustness")):
        console.print(line, soft_wrap=True, markup=False)


def _print_cases(cases: Any, console: Console) -> None:
    """Every load case of a response (a mechanism's free and blocked jaw): the drive, its
    reaction, the peak stress and each output, from start to end with its range."""
    from flexopt.pipeline.responses import case_rows

    if not cases:
        return
    table = Table(title="load cases (converged rows)", title_justify="left")
    for name, justify in (("case", "left"), ("column", "left"), ("unit", "left"),
                          ("start", "right"), ("end", "right"), ("range", "right")):  # fmt: skip
        table.add_column(name, justify=justify)  # type: ignore[arg-type]
    for case, response in cases.items():
        for column, _, unit, start, end, low, high in case_rows(response):
            # (Text: a case or output name is the user's, never rich markup)
            span = f"{_format_value(low)} … {_format_value(high)}"
            table.add_row(
                Text(case), Text(column), unit, _format_value(start), _format_value(end), span
            )
    console.print(table)


def _print_summary(outcome: EvaluateOutcome, console: Console) -> None:
    result, record = outcome.result, outcome.record
    _print_verdict(result.verdicts, f"{record['study']} ({record['kind']})", console)
    _print_robustness(record, console)
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
    _print_cases(result.cases, console)
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
    if outcome.result.summary.get("stable") is False:
        # a design past a bifurcation is never reported as a plain result (issue 11)
        message = outcome.result.summary.get("unstable_message") or "passed an instability"
        print(
            f"{prog}: warning: {message}; rows with stable=false are not a safe "
            f"design; see {outcome.run_dir / 'evaluation.json'}",
            file=sys.stderr,
        )
    if not outcome.result.converged:
        print(
            f"{prog}: warning: the solve did not converge ({outcome.result.message}); "
            f"rows with converged=false are not results; see {outcome.run_dir / 'evaluation.json'}",
            file=sys.stderr,
        )
    return EXIT_OK


def _print_run_summary(outcome: RunOutcome, console: Console) -> None:
    record, best = outcome.record, outcome.result.best
    verdicts = getattr(outcome, "verdicts", ())
    _print_verdict(verdicts, f"{record['study']} ({record['kind']}): best design", console)
    _print_robustness(record, console)
    table = Table(title=f"{record['study']} ({record['kind']}): best design", title_justify="left")
    table.add_column("")
    table.add_column("name")
    table.add_column("value", justify="right")
    from flexopt.pipeline.labels import best_design_rows

    names = (record["variables"], record["objectives"], record["constraints"])
    for label, name, value in best_design_rows(*names, best, verdicts):
        table.add_row(label, Text(name), Text(value))
    table.add_row("", "optimiser constraints met (feasible)", _format_value(best.feasible))
    console.print(table)
    _print_cases(outcome.detail.cases if outcome.detail is not None else {}, console)
    rate = record.get("evaluations_per_s")
    console.print(
        f"{record['n_evaluations']} designs solved ({record['n_cache_hits']} repeats from the "
        f"cache, {record['n_failed']} failed) in {record['wall_s']:.3g} s"
        + (f", {rate:.3g} eval/s" if rate else ""),
        soft_wrap=True,
    )
    console.print(f"wrote {outcome.run_dir}", soft_wrap=True)


def _run(args: argparse.Namespace) -> int:
    from flexopt.pipeline.parallel import BackendError
    from flexopt.pipeline.run import parallel_settings, prepare_run, resume_run, run_study
    from flexopt.pipeline.run.runner import start_early_step

    prog = "flexopt run"
    if args.resume is None and args.study is None:
        print(
            f"{prog}: error: give a STUDY, or --resume RUN_DIR (see {prog} --help)", file=sys.stderr
        )
        return EXIT_USAGE
    if args.resume is not None and (args.seed is not None or args.quick or args.out):
        print(
            f"{prog}: error: --resume continues the run with its own seed, --quick and folder; "
            "leave out --seed, --quick and --out",
            file=sys.stderr,
        )
        return EXIT_USAGE
    progress = RunProgress(args.quiet)
    callbacks = {
        "command_line": shlex.join(["flexopt", *args.argv]),
        "on_start": progress.start,
        "on_generation": progress.generation,
        "on_result": progress.result,
    }
    early = None
    try:
        if args.resume is not None:
            outcome = resume_run(
                args.resume,
                resolve_study_path(args.study) if args.study is not None else None,
                workers=args.workers,
                dask=args.dask,
                eval_timeout_s=args.eval_timeout,
                **callbacks,
            )
        else:
            path = resolve_study_path(args.study)
            # best.step's child before the study loads: its import of the STEP writer uses the
            # core that idles while this process imports the kind (the run ends it)
            early = start_early_step()
            study = load_study(path)
            setup = prepare_run(study, quick=args.quick, seed=args.seed)
            settings = parallel_settings(study, args.workers, args.dask, args.eval_timeout)
            outcome = run_study(
                setup,
                out=args.out,
                source=str(path),
                parallel=settings,
                early_step=early,
                **callbacks,
            )
    except StudyError as exc:
        progress.stop()
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BackendError as exc:
        progress.stop()
        where = f"; see {progress.run_dir / 'run.json'}" if progress.run_dir else ""
        print(f"{prog}: error: {exc}{where}", file=sys.stderr)
        return EXIT_WRITE
    except OSError as exc:
        progress.stop()
        print(f"{prog}: error: cannot write the run folder: {exc}", file=sys.stderr)
        return EXIT_WRITE
    except KeyboardInterrupt as exc:
        progress.stop()
        stopped = isinstance(exc, Terminated)
        what, status = (
            ("stopped by SIGTERM", "stopped") if stopped else ("interrupted", "interrupted")
        )
        where = f"; what was done is in {progress.run_dir}" if progress.run_dir else ""
        resume = f"; continue with: flexopt run --resume {progress.run_dir}" if where else ""
        print(f"{prog}: {what}{where} (run.json status: {status}){resume}", file=sys.stderr)
        return EXIT_TERMINATED if stopped else EXIT_INTERRUPTED
    except Exception as exc:
        progress.stop()
        where = f"; see {progress.run_dir / 'run.json'}" if progress.run_dir else ""
        print(f"{prog}: error: the run failed: {type(exc).__name__}: {exc}{where}", file=sys.stderr)
        return EXIT_WRITE
    finally:
        if early is not None:  # a run that did not reach its report (a refused study): at once
            early.abort()
    progress.stop()
    _print_run_summary(outcome, Console(highlight=False))
    for note in outcome.notes:
        print(f"{prog}: warning: {note}", file=sys.stderr)
    if not outcome.result.best.feasible:
        print(
            f"{prog}: warning: no feasible design found; best.json holds the least violating "
            "one. Widen the design space, relax the constraints or run longer (no --quick)",
            file=sys.stderr,
        )
    return EXIT_OK


def _status(args: argparse.Namespace) -> int:
    from flexopt.pipeline.status import format_status, run_status

    try:
        status = run_status(args.run_dir)
    except StudyError as exc:
        print(f"flexopt status: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print(format_status(status))
    return EXIT_OK


def _report(args: argparse.Namespace) -> int:
    from flexopt.pipeline.run import rebuild_report

    prog = "flexopt report"
    try:
        outcome = rebuild_report(args.run_dir)
    except StudyError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"{prog}: error: cannot write the run folder: {exc}", file=sys.stderr)
        return EXIT_WRITE
    print(
        f"rebuilt {', '.join(outcome.files)} in {outcome.run_dir} from "
        f"{outcome.n_evaluations} evaluations"
    )
    for note in outcome.notes:
        print(f"{prog}: warning: {note}", file=sys.stderr)
    return EXIT_OK


def _exported(args: argparse.Namespace, make: Callable[[], Any]) -> tuple[Any, int]:
    """``make()``'s outcome, or ``(None, exit code)`` with its one line on stderr: a bad
    argument or run folder exits 2, a design that cannot be exported or written 1."""
    from flexopt.pipeline.run import ExportError

    prog = "flexopt export"
    try:
        return make(), EXIT_OK
    except StudyError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return None, EXIT_USAGE
    except ExportError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return None, EXIT_WRITE
    except OSError as exc:
        print(f"{prog}: error: cannot write {args.out or 'the file'}: {exc}", file=sys.stderr)
        return None, EXIT_WRITE


def _export_study(args: argparse.Namespace) -> int:
    """``flexopt export --format yaml``: the design as a study file."""
    from flexopt.pipeline.run import export_study

    outcome, code = _exported(args, lambda: export_study(args.run_dir, args.design, args.out))
    if outcome is None:
        return code
    print(
        f"wrote {outcome.path} (design {outcome.design} as a {outcome.study.kind} study; "
        f"solve it with: flexopt evaluate {outcome.path})"
    )
    return EXIT_OK


def _export(args: argparse.Namespace) -> int:
    from flexopt.pipeline.run import STUDY_SUFFIXES, export_design

    prog = "flexopt export"
    if args.out is not None:
        from flexopt.pipeline.runfolder import regular_target

        try:  # before any work, for every format: never a device node, FIFO or folder
            regular_target(args.out)
        except StudyError as exc:
            print(f"{prog}: error: {exc}", file=sys.stderr)
            return EXIT_USAGE
    if args.format == "yaml" or (
        args.format is None and args.out is not None and args.out.suffix.lower() in STUDY_SUFFIXES
    ):
        return _export_study(args)
    outcome, code = _exported(
        args,
        lambda: export_design(args.run_dir, args.design, args.out, args.format, args.frame),
    )
    if outcome is None:
        return code
    if outcome.format == "vtu":  # no part: the mesh and results for ParaView
        print(f"wrote {outcome.path} (design {outcome.design}, VTU: shapes and stress field)")
    elif outcome.format in HANDOFF_LINES:  # the part's hand-off files
        print(f"wrote {outcome.path} (design {outcome.design}, {HANDOFF_LINES[outcome.format]})")
    else:
        _print_part(outcome)
    # (an evaluate folder's design is judged by its own verdict, not by the run's constraints)
    if not outcome.evaluation.feasible and outcome.design != "evaluated":
        reason = f": {outcome.evaluation.reason}" if outcome.evaluation.reason else ""
        print(f"{prog}: warning: this design is not feasible{reason}", file=sys.stderr)
    return EXIT_OK


#: What ``flexopt export --format cad|3mf|sheet`` says it wrote.
HANDOFF_LINES = {
    "cad": "parametric build123d script: change a dimension at its top and run it",
    "3mf": "the part laid flat with the print settings it assumes",
    "sheet": "print sheet: what to print, how, what to measure",
}


def _print_part(outcome: Any) -> None:
    """The line of an exported part (STL, DXF, STEP): its size, frame and volume."""
    w, h = outcome.footprint_mm
    laid = "flat profile of the sheet" if outcome.sheet else "laid flat"
    if outcome.frame == "design":
        laid = "in the design frame"
    elif outcome.rotation_deg:
        laid += f", turned {outcome.rotation_deg:+.3g} deg to the bed axes"
    triangles = f"{outcome.triangles} triangles, " if outcome.triangles else ""
    print(
        f"wrote {outcome.path} (design {outcome.design}, {outcome.format.upper()}: footprint "
        f"{w:.4g} x {h:.4g} mm, {outcome.thickness_mm:.4g} mm thick, {laid}; {triangles}"
        f"volume {outcome.volume_mm3:.6g} mm^3)"
    )


def _list(args: argparse.Namespace) -> int:
    from flexopt.pipeline.init_study import catalogue

    found = catalogue()
    width = max(len(name) for name, *_ in found.kinds + found.studies)
    print("Study kinds (geometry.kind):")
    for name, origin, summary in found.kinds:
        print(f"  {name:<{width}}  {origin:<8}  {summary}")
    print("Built-in studies (flexopt evaluate NAME, run NAME, init MINE --example NAME):")
    kind_width = max(len(kind) for _, kind, _ in found.studies)
    for name, kind, summary in found.studies:
        print(f"  {name:<{width}}  {kind:<{kind_width}}  {summary}")
    if found.unavailable:
        print("Unavailable plugin kinds:")
        for name, reason in found.unavailable:
            print(f"  {name:<{width}}  {reason}")
    return EXIT_OK


def _init(args: argparse.Namespace) -> int:
    from flexopt.pipeline.init_study import starter_study

    prog = "flexopt init"
    out = args.out or Path(f"{args.name}.yaml")
    if args.out is not None and out.is_dir():  # --out studies/ means "in that folder", as cp
        out = out / f"{args.name}.yaml"  # does; a folder named NAME.yaml is refused below
    try:
        text = starter_study(args.name, kind=args.kind, example=args.example, file=str(out))
    except StudyError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if out.exists() or out.is_symlink():
        what = "is a folder" if out.is_dir() else "exists"
        print(
            f"{prog}: error: {out} {what}; flexopt init never overwrites a file: give another "
            "NAME or --out FILE",
            file=sys.stderr,
        )
        return EXIT_USAGE
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with open(out, "x", encoding="utf-8") as handle:  # "x": not even a file made just now
            handle.write(text)
    except FileExistsError:
        print(f"{prog}: error: {out} exists; give another NAME or --out FILE", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"{prog}: error: cannot write {out}: {exc}", file=sys.stderr)
        return EXIT_WRITE
    print(f"wrote {out}; try: flexopt evaluate {shlex.quote(str(out))}")
    return EXIT_OK


def _schema(args: argparse.Namespace) -> int:
    from flexopt.pipeline.init_study import study_schema

    prog = "flexopt schema"
    try:
        if args.out is not None:
            from flexopt.pipeline.runfolder import regular_target

            regular_target(args.out)  # before any work: never a device node, FIFO or folder
        text = json.dumps(study_schema(args.kind), indent=2, ensure_ascii=False) + "\n"
    except StudyError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.out is None:
        sys.stdout.write(text)
        return EXIT_OK
    try:
        from flexopt.pipeline.runfolder import write_atomic

        args.out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(args.out, text)  # an editor reading the schema never sees half of it
    except OSError as exc:
        print(f"{prog}: error: cannot write {args.out}: {exc}", file=sys.stderr)
        return EXIT_WRITE
    print(f"wrote {args.out}")
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``flexopt`` with ``argv`` (default ``sys.argv[1:]``) and return the exit code."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    stdout, sys.stdout = sys.stdout, _GuardedStdout(sys.stdout)
    try:  # --help and --version print here: a full or closed stdout is one line too
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help, --version and usage errors
            sys.stdout.flush()
            return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    except _StdoutFailed as exc:
        _silence_stdout(stdout)
        print(f"flexopt: error: {exc}", file=sys.stderr)
        return EXIT_WRITE
    finally:
        sys.stdout = stdout
    args.argv = argv
    if args.verbose:
        handler = logging.StreamHandler()
        handler.setFormatter(_PrintableFormatter("%(levelname)s %(name)s: %(message)s"))
        logging.basicConfig(level=logging.INFO, handlers=[handler])
    else:
        # Without -v nothing is logged: what a user must know is printed by this module as one
        # line, and logging's last-resort handler would print warnings (and their tracebacks)
        # of flexopt and of the libraries it uses.
        logging.getLogger().addHandler(logging.NullHandler())
        # numpy's RuntimeWarnings (a 0/0 in a design that does not converge, a NaN in a
        # column) are the solver's business: the result says what went wrong; -v shows them
        warnings.filterwarnings("ignore", category=RuntimeWarning)
    previous = _stop_on_sigterm()
    stdout, sys.stdout = sys.stdout, _GuardedStdout(sys.stdout)
    try:
        code = int(args.handler(args))
        sys.stdout.flush()  # a full disk behind stdout shows here, not at the interpreter's exit
        return code
    except _StdoutFailed as exc:
        _silence_stdout(stdout)
        print(f"flexopt {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_WRITE
    except Terminated:
        print("flexopt: stopped by SIGTERM", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("flexopt: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        sys.stdout = stdout
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


class _StdoutFailed(FlexoptError):
    """Standard output is closed, full or a closed pipe: the command's output cannot be given.

    Not an :class:`OSError`, so no handler takes it for a run folder it could not write.
    """


class _GuardedStdout:
    """``sys.stdout`` while a command runs: a write or flush that fails (``> /dev/full``,
    ``>&-``, a closed pipe) raises :class:`_StdoutFailed`, which :func:`main` reports as one line
    (exit 1) instead of a traceback."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def _fail(self, exc: BaseException | None) -> NoReturn:
        why = f" ({exc.strerror or exc})" if isinstance(exc, OSError) else ""
        closed = "is closed" if exc is None or not isinstance(exc, OSError) else "failed"
        raise _StdoutFailed(
            f"standard output {closed}{why}; what was written to files is kept (the result "
            "goes to standard output: redirect it to a file with room)"
        )

    def write(self, text: str) -> int:
        if self._stream is None:
            self._fail(None)
        try:
            return self._stream.write(text)
        except (OSError, ValueError) as exc:  # ValueError: the stream was closed
            self._fail(exc)

    def flush(self) -> None:
        if self._stream is None:
            return
        try:
            self._stream.flush()
        except (OSError, ValueError) as exc:
            self._fail(exc)

    def isatty(self) -> bool:
        try:
            return self._stream is not None and self._stream.isatty()
        except (OSError, ValueError):
            return False

    def fileno(self) -> int:
        if self._stream is None:
            raise OSError(9, "standard output is closed")
        return self._stream.fileno()

    @property
    def encoding(self) -> str:
        return getattr(self._stream, "encoding", None) or "utf-8"

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _silence_stdout(stream: Any) -> None:
    """Point file descriptor 1 at the null device, so the buffered text that could not be
    written is dropped quietly at exit instead of failing again with a traceback."""
    if stream is None:
        return
    with contextlib.suppress(OSError, ValueError):
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, stream.fileno())
        os.close(null)
    with contextlib.suppress(OSError, ValueError):
        stream.flush()


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated()


def _stop_on_sigterm() -> Any:
    """Make SIGTERM end a command as Ctrl-C does (the run folder says ``stopped``, resumable).

    Returns the previous handler (None where signals cannot be set: not the main thread).
    """
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _raise_terminated)


def entry() -> None:
    """The ``flexopt`` command (and ``python -m flexopt.pipeline.cli``): :func:`main`, then the
    process ends without the interpreter's teardown.

    Freeing every module and object of a run's process (numba, scipy, matplotlib, trimesh, ...)
    took ~0.6 s after the last file was written, on every command (issue 13 measured the whole
    ``flexopt run``). The atexit handlers still run (logging's flush, multiprocessing's, a
    plugin's) and stdout and stderr are flushed; only the deallocation is skipped. When a
    non-daemon thread or a child process is still running, the normal exit waits for it.
    """
    code = main()
    others = [
        t for t in threading.enumerate()
        if t is not threading.main_thread() and t.is_alive() and not t.daemon
    ]  # fmt: skip
    import multiprocessing

    run_exitfuncs = getattr(atexit, "_run_exitfuncs", None)
    if others or multiprocessing.active_children() or run_exitfuncs is None:
        sys.exit(code)
    run_exitfuncs()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError, AttributeError):  # `| head`, `> /dev/full`, `>&-`: said once
        pass
    os._exit(code)


if __name__ == "__main__":
    entry()
