"""What ``flexopt run`` shows while it runs: a progress bar over generations (on a terminal)
and one line per generation on stderr; used by the CLI and by ``flexopt.run(progress=True)``."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

if TYPE_CHECKING:  # pipeline.run imports pymoo (~1 s): not for a progress line
    from flexopt.optimise.ga import GAConfig
    from flexopt.pipeline.run import GenerationReport

__all__ = ["RunProgress", "format_generation"]


class RunProgress:
    """A progress bar over generations (TTY only) and one line per generation on stderr."""

    def __init__(self, quiet: bool) -> None:
        self.console = Console(stderr=True, highlight=False)
        self.lines = not quiet
        self.bar_enabled = not quiet and self.console.is_terminal
        self.progress: Progress | None = None
        self.task: Any = None
        self.run_dir: Path | None = None
        self.step = 0.0
        self.shown = 0  # the generation of the last line printed

    def start(self, run_dir: Path, config: GAConfig) -> None:
        self.run_dir = run_dir
        self.step = 1.0 / config.pop_size
        if self.lines:
            self._say(
                f"run folder {run_dir}\n{config.algorithm}: {config.pop_size} designs x "
                f"{config.n_gen} generations, seed {config.seed}{_where(run_dir)}"
            )
        if self.bar_enabled:
            self.progress = Progress(
                TextColumn("[progress.description]{task.description}"),
                BarColumn(),
                TextColumn("{task.completed:.0f}/{task.total:.0f} generations"),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=self.console,
                transient=True,
            )
            self.task = self.progress.add_task("optimising", total=config.n_gen)
            self.progress.start()

    def result(self) -> None:
        """One design solved: creep forward within the generation (never past its end)."""
        if self.progress is not None:
            task = self.progress.tasks[0]
            if task.completed >= task.total:  # the hybrid's gradient stage: the GA's bar is full
                return
            ceiling = math.floor(task.completed) + 1.0 - 1e-9
            self.progress.update(self.task, completed=min(task.completed + self.step, ceiling))

    def generation(self, report: GenerationReport) -> None:
        if self.progress is not None:
            if report.stage == "gradient":  # past the GA stage: its bar full, the step named
                task = self.progress.tasks[0]
                self.progress.update(
                    self.task, completed=task.total, description=f"gradient step {report.step}"
                )
            else:
                self.progress.update(self.task, completed=report.generation)
        # a hybrid run's end repeats its last report (GenerationReport.last): one line of it
        if self.lines and report.generation != self.shown:
            self._say(format_generation(report))
        self.shown = report.generation
        if report.last:
            self.stop()
            if self.lines:
                self._say("writing the best design's response, plots, STL and report")

    def _say(self, text: str) -> None:
        if self.progress is not None:
            self.progress.console.print(text, soft_wrap=True)
        else:
            print(text, file=sys.stderr, flush=True)

    def stop(self) -> None:
        if self.progress is not None:
            self.progress.stop()
            self.progress = None


def _where(run_dir: Path) -> str:
    """``, on processes (2 workers)``: where the run evaluates, from its run.json."""
    # run.json was just written by this run, but the line is only decoration: whatever is in
    # the file (a hand-edited or damaged record), a wrong shape leaves it out, never raises.
    try:
        record = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
        where = f", on {record['parallel']['description']}"
        restored = record.get("resumed") and record["resumed"][-1].get("n_in_store")
    except (OSError, ValueError, LookupError, TypeError, AttributeError):
        return ""
    return where + (f"; resuming with {restored} designs from the store" if restored else "")


def format_generation(report: GenerationReport) -> str:
    """``gen 3/30  best 0.0123  feasible 85%  12.3 eval/s``; a step of the hybrid optimiser's
    gradient stage: ``gradient step 4 (evaluations 57)  best ...``, with the designs
    evaluated so far in the run."""
    from flexopt.pipeline.labels import objective_view

    best = report.best
    names = getattr(report, "objective_names", None) or [""] * len(best.f)
    shown = []
    for name, v in zip(names, best.f, strict=False):
        sense, _, value = objective_view(name, float(v), best.metrics)
        shown.append(f"{value:.4g}" + (" (max)" if sense == "maximise" else ""))
    value = ", ".join(shown) if best.feasible else "none feasible"
    where = (
        f"gradient step {report.step} (evaluations {report.n_evaluations})"
        if getattr(report, "stage", "ga") == "gradient"
        else f"gen {report.generation}/{report.n_gen}"
    )
    return (
        f"{where}  best {value}  "
        f"feasible {100 * report.feasible_fraction:.0f}%  {report.evaluations_per_s:.3g} eval/s"
    )
