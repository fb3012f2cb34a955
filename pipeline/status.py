"""``flexopt status``: the progress of a run, read from its folder (never written to).

The running process keeps run.json, history.csv and checkpoint.json current after each
generation and appends every finished design to evaluations.jsonl at once, so the folder alone
says how far a run is, also mid-generation and after a kill. It reads run.json and the store
through their validated readers (a damaged file is one line naming it, exit 2) and takes no lock.
"""

from __future__ import annotations

import os
import socket
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from flexopt.optimise.evaluation import Evaluation
from flexopt.pipeline.checkpoint import STORE_FILE, EvaluationStore
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.labels import objective_text
from flexopt.pipeline.runfolder import read_run_json

__all__ = ["RunStatus", "format_status", "run_status"]


@dataclass(frozen=True)
class RunStatus:
    """What ``flexopt status`` shows.

    Attributes
    ----------
    run_dir : the run folder.
    study, kind : the study's name and kind.
    status : running, finished, interrupted, failed, or stopped (run.json says running but its
        process is gone: killed; resume it).
    generation, n_gen : generations done and in all (a hybrid run: of its GA stage).
    n_evaluations : designs evaluated so far (the store, which is ahead of the tables mid-run).
    n_feasible : feasible designs among them.
    n_failed : designs that could not be evaluated.
    best : objective values of the best design so far, by name (None before the first).
    best_feasible : whether that design is feasible.
    elapsed_s : s since the run (or its last resume) started; its wall time once finished.
    evaluations_per_s : designs solved per second in the current session.
    eta_s : estimated s to the end (None when unknown or done).
    error : run.json's error, when there is one.
    notes : what was skipped reading the folder (a torn last line of the store).
    """

    run_dir: Path
    study: str
    kind: str
    status: str
    generation: int
    n_gen: int
    n_evaluations: int
    n_feasible: int
    n_failed: int
    best: dict[str, float] | None
    best_feasible: bool
    elapsed_s: float | None
    evaluations_per_s: float | None
    eta_s: float | None
    error: str = ""
    notes: tuple[str, ...] = ()
    best_metrics: dict[str, Any] | None = None  # the best design's metrics (a maximised X)
    gradient_steps: int = 0  # a hybrid run: batches of its gradient stage so far

    @property
    def feasible_share(self) -> float:
        """Share of the evaluated designs that are feasible."""
        return self.n_feasible / self.n_evaluations if self.n_evaluations else 0.0


def _alive(record: dict[str, Any]) -> bool:
    if record.get("hostname") not in (None, socket.gethostname()):
        return True  # another machine: trust the record
    try:
        os.kill(int(record.get("pid")), 0)
    except (OSError, TypeError, ValueError):
        return False
    return True


def _seconds_since(stamp: str | None) -> float | None:
    if not stamp:
        return None
    try:
        then = datetime.fromisoformat(stamp)
        if then.tzinfo is None:  # a stamp without its offset: local time
            then = then.astimezone()
        return (datetime.now().astimezone() - then).total_seconds()
    except (ValueError, OverflowError, OSError):  # not a time, or out of range
        return None


def run_status(run_dir: Path) -> RunStatus:
    """Read the progress of the run in ``run_dir``.

    Raises
    ------
    StudyError
        At ``RUN_DIR`` when it is not a run folder of ``flexopt run``.
    """
    if not run_dir.is_dir():
        raise StudyError("RUN_DIR", f"'{run_dir}' is not a folder; give a run folder")
    record = read_run_json(run_dir)

    status = str(record.get("status", "unknown"))
    if status == "running" and not _alive(record):
        status = "stopped"
    optimiser = record.get("optimiser", {})
    n_gen = int(optimiser.get("n_gen", 0))
    pop_size = int(optimiser.get("pop_size", 0))
    generation = int(record.get("generations_done", 0))
    # a hybrid run counts its gradient stage's batches as generations: shown apart
    gradient_steps = int(record.get("gradient_steps") or 0)
    generation -= gradient_steps
    objectives = list(record.get("objectives", []))

    def size(key: str) -> int | None:
        return len(record[key]) if key in record else None

    store = EvaluationStore(run_dir / STORE_FILE)
    rows: list[Evaluation] = store.load(size("variables"), size("objectives"), size("constraints"))
    n_evaluations = len(rows) or int(record.get("n_evaluations", 0))
    failed = [ev for ev in rows if ev.reason]
    feasible = [ev for ev in rows if ev.feasible]
    best = None
    best_feasible = False
    top = None
    if feasible:
        top = min(feasible, key=lambda ev: float(ev.f[0]))
        best, best_feasible = dict(zip(objectives, map(float, top.f), strict=False)), True
    elif rows:
        evaluated = [ev for ev in rows if not ev.reason] or rows
        top = min(evaluated, key=lambda ev: (ev.violation, float(ev.f[0])))
        best = dict(zip(objectives, map(float, top.f), strict=False))

    if status == "running":
        resumed = record.get("resumed") or []
        elapsed = _seconds_since(resumed[-1]["at"] if resumed else record.get("started"))
    else:
        elapsed = record.get("wall_s")
    n_solved = int(record.get("n_solved") or 0)
    optimise_wall = record.get("optimise_wall_s")
    rate = record.get("evaluations_per_s")
    if rate is None and n_solved and optimise_wall:
        rate = n_solved / optimise_wall
    eta = None
    if status == "running" and rate and not gradient_steps:
        asked = n_evaluations + int(record.get("n_cache_hits", 0))
        # designs still to come; repeats (served by the cache) so far say how many are new
        new_share = (
            int(record.get("n_evaluations", 0)) / (generation * pop_size)
            if generation and pop_size
            else 1.0
        )
        remaining = max(0.0, (n_gen * pop_size - asked) * min(1.0, new_share))
        eta = remaining / rate
    return RunStatus(
        run_dir=run_dir,
        study=str(record.get("study", "")),
        kind=str(record.get("kind", "")),
        status=status,
        generation=generation,
        n_gen=n_gen,
        n_evaluations=n_evaluations,
        n_feasible=len(feasible),
        n_failed=len(failed),
        best=best,
        best_feasible=best_feasible,
        elapsed_s=elapsed,
        evaluations_per_s=rate,
        eta_s=eta,
        error=str(record.get("error") or ""),
        notes=tuple(store.notes),
        best_metrics=dict(top.metrics) if top is not None and top.metrics else None,
        gradient_steps=gradient_steps,
    )


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return "–"
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def format_status(status: RunStatus) -> str:
    """The lines ``flexopt status`` prints."""
    if status.best is None:
        best = "–"
    else:
        # a maximised objective as the study states it (not the negative the GA minimises)
        values = ", ".join(
            objective_text(name, value, status.best_metrics) for name, value in status.best.items()
        )
        late = " yet" if status.status == "running" else ""
        best = values + ("" if status.best_feasible else f" (none feasible{late})")
    rate = f"{status.evaluations_per_s:.3g} eval/s" if status.evaluations_per_s else "–"
    lines = [
        f"run          {status.run_dir}",
        f"study        {status.study} ({status.kind})",
        f"status       {status.status}",
        f"generation   {status.generation}/{status.n_gen}",
        *(
            [f"gradient     step {status.gradient_steps} (evaluations {status.n_evaluations})"]
            if status.gradient_steps
            else []
        ),
        f"evaluations  {status.n_evaluations} ({status.n_failed} failed)",
        f"feasible     {100 * status.feasible_share:.0f}%",
        f"best so far  {best}",
        f"elapsed      {_duration(status.elapsed_s)}",
        f"speed        {rate}",
    ]
    if status.status == "running":
        lines.append(f"ETA          {_duration(status.eta_s)}")
    if status.status in ("stopped", "interrupted", "failed"):
        hint = f"resume with: flexopt run --resume {status.run_dir}"
        lines.append(f"next         {hint}")
    if status.error:
        lines.append(f"error        {status.error}")
    lines += [f"note         {note}" for note in status.notes]
    return "\n".join(lines)
