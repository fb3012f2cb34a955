"""Checkpoints as data: every finished evaluation on disk at once, and how to replay a run.

A run is a deterministic function of its study, its seed and its evaluations (see
:mod:`optimise.ga`). So a checkpoint is not a pickled optimiser but data:

- ``evaluations.jsonl`` — one JSON line per finished evaluation (exact float64 ``x``, ``f``,
  ``g``, metrics, reason, time), handed to the kernel as each design finishes, so a SIGKILL of the
  run loses at most the designs still being solved; fsynced once per generation (before the
  generation is reported or checkpointed) and at least every ``sync_interval_s``, so a power cut
  loses no design a generation report acknowledged. JSON writes floats as their shortest
  round-trip repr, so the numbers read back to the same bits.
- ``checkpoint.json`` — rewritten atomically after every generation: the population, the seed and
  settings, the counts, and the study hash.

``flexopt run --resume RUN_DIR`` loads the store into the evaluation cache and replays the
optimiser from the same seed: every design already solved is served from the store, the rest are
solved, and the run ends with the same best design as an uninterrupted run.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.runfolder import (
    echo,
    read_folder_bytes,
    read_folder_json,
    to_json,
    write_atomic,
)
from flexopt.pipeline.study import Study, study_to_yaml

__all__ = [
    "CHECKPOINT_FILE",
    "STORE_FILE",
    "EvaluationStore",
    "evaluation_from_record",
    "evaluation_record",
    "read_checkpoint",
    "study_sha256",
    "write_checkpoint",
    "checkpoint_text",
]

log = logging.getLogger(__name__)

STORE_FILE = "evaluations.jsonl"
CHECKPOINT_FILE = "checkpoint.json"
#: Bumped when the store or checkpoint layout changes in a way old readers cannot follow.
FORMAT = 1


def study_sha256(study: Study) -> str:
    """sha256 of the resolved study YAML, without its ``parallel:`` block.

    Where designs are evaluated does not change what they evaluate to, so a run may be resumed
    with other workers or on a cluster; everything else (the seed included) must be the same.
    """
    text = study_to_yaml(study.model_copy(update={"parallel": None}))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _plain(value: Any) -> Any:
    """A metric value as JSON data; NaN and inf stay (the store is read by Python only)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple | np.ndarray):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return str(value)


def evaluation_record(evaluation: Evaluation) -> dict[str, Any]:
    """One evaluation as a JSON-ready mapping that :func:`evaluation_from_record` inverts."""
    return {
        "x": [float(v) for v in evaluation.x],
        "f": [float(v) for v in evaluation.f],
        "g": [float(v) for v in evaluation.g],
        "metrics": _plain(evaluation.metrics),
        "reason": evaluation.reason,
        "time_s": float(evaluation.time_s),
    }


def evaluation_from_record(record: Mapping[str, Any]) -> Evaluation:
    """The Evaluation of a :func:`evaluation_record` (bit-identical ``x``, ``f`` and ``g``).

    Raises
    ------
    ValueError
        Saying which field is not what :func:`evaluation_record` writes (no more than 60
        characters of a value are echoed).
    """
    if not isinstance(record, Mapping):
        raise ValueError(f"it is {echo(record)}, not a mapping with x, f and g")
    arrays = []
    for key in ("x", "f", "g"):
        value = record.get(key)
        if not isinstance(value, list) or not all(_number(v) for v in value):
            raise ValueError(f"{key} is {echo(value)}, not a list of numbers")
        arrays.append(np.array(value, dtype=float))
    if not arrays[1].size:
        raise ValueError("f is [], not a list of objective values")
    metrics = record.get("metrics")
    if metrics is not None and not isinstance(metrics, Mapping):
        raise ValueError(f"metrics is {echo(metrics)}, not a mapping")
    reason = record.get("reason")
    if reason is not None and not isinstance(reason, str):
        raise ValueError(f"reason is {echo(reason)}, not text")
    time_s = record.get("time_s")
    if time_s is not None and not _number(time_s):
        raise ValueError(f"time_s is {echo(time_s)}, not a number")
    return Evaluation(
        arrays[0], arrays[1], arrays[2], dict(metrics or {}), reason or "", float(time_s or 0.0)
    )


def _number(value: Any) -> bool:
    """A JSON number a float can hold (a bool is not one; an integer of 400 digits neither)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    return isinstance(value, float) or abs(value) <= 1e308


def store_fix(run_dir: Path, line: bool = True) -> str:
    """What to do about a damaged store (the end of a refusal): about one ``line`` of it, or
    the file as a whole."""
    if line:
        return (
            "was it edited? restore the file from a copy, or delete that line (flexopt run "
            f"--resume {run_dir} solves its design again)"
        )
    return (
        "restore it from a copy, or move it away (flexopt report then reads evaluations.csv, "
        "and flexopt run --resume solves every design again)"
    )


class EvaluationStore:
    """``evaluations.jsonl``: finished evaluations, appended one by one, fsynced in groups.

    Reading it never changes it; the first :meth:`append` of a session repairs a torn last line
    (a kill mid-write) so that the new line starts on a line of its own.

    Durability: :meth:`append` writes the line with one ``write`` (the kernel has it: a SIGKILL
    or a crash of this process cannot lose it); :meth:`sync` fsyncs what was appended (a power
    cut or a kernel crash cannot lose it then). The runner syncs before it reports or
    checkpoints a generation, and :meth:`append` syncs by itself when the last sync is older
    than ``sync_interval_s``. An fsync costs 5-15 ms on the development machine's disk: one per
    design was a main-process ceiling of ~100 designs/s, under the rate of two workers on
    15 ms designs.

    Parameters
    ----------
    path : Path
        The store file (created on the first append).
    sync_interval_s : float, s
        Longest time an appended line waits for its fsync; 0 fsyncs every line (the old way).

    Attributes
    ----------
    notes : list of str
        What the last :meth:`load` skipped (a torn last line).
    """

    def __init__(self, path: Path, sync_interval_s: float = 5.0) -> None:
        self.path = path
        self._fd: int | None = None
        self.n_appended = 0
        self.n_synced = 0  # lines appended and fsynced
        self.n_fsyncs = 0
        self.sync_interval_s = float(sync_interval_s)
        self._t_sync = time.monotonic()
        self.notes: list[str] = []

    def load(
        self,
        n_var: int | None = None,
        n_obj: int | None = None,
        n_con: int | None = None,
        option: str = "RUN_DIR",
    ) -> list[Evaluation]:
        """Every evaluation in the store, read only (the file is not changed).

        A torn last line (no newline after it and not a whole record: a kill mid-write) is
        skipped, with a note in :attr:`notes`.

        Parameters
        ----------
        n_var, n_obj, n_con : int, optional
            Variables, objectives and constraints each evaluation must have.
        option : str
            Where a refusal is reported (``RUN_DIR``, ``--resume``).

        Raises
        ------
        StudyError
            (a ValueError) At ``option``, naming the file and line, for a store that is a
            folder or cannot be read, a line that is not UTF-8, not JSON or not an evaluation
            (other than a torn last line), or an evaluation of the wrong size.
        """
        self.notes = []
        fix = store_fix(self.path.parent)
        data = read_folder_bytes(self.path, option, store_fix(self.path.parent, line=False))
        if not data:
            return []
        lines = data.split(b"\n")
        out: list[Evaluation] = []
        for number, raw in enumerate(lines, 1):
            if not raw.strip():
                continue
            where = f"'{self.path}' line {number}"
            torn = number == len(lines)  # no newline after it: possibly cut short
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                if torn:
                    self._torn(number)
                    break
                raise StudyError(
                    option, f"{where} is not UTF-8 text (byte 0x{raw[exc.start]:02x}); {fix}"
                ) from None
            try:
                evaluation = evaluation_from_record(json.loads(text))
            except (ValueError, RecursionError) as exc:
                if torn:
                    self._torn(number)
                    break
                problem = (
                    f"is not valid JSON ({exc.msg}: column {exc.colno})"
                    if isinstance(exc, json.JSONDecodeError)
                    else f"is not an evaluation ({str(exc) or type(exc).__name__})"
                )
                raise StudyError(option, f"{where} {problem}; {fix}") from None
            for size, wanted, what in (
                (evaluation.x.size, n_var, "design variables"),
                (evaluation.f.size, n_obj, "objectives"),
                (evaluation.g.size, n_con, "constraints"),
            ):
                if wanted is not None and size != wanted:
                    raise StudyError(
                        option, f"{where} has {size} {what}, the study {wanted}; {fix}"
                    )
            out.append(evaluation)
        return out

    def _torn(self, number: int) -> None:
        note = (
            f"{self.path.name} line {number} is torn (a kill while it was written); skipped, "
            "its design is solved again on --resume"
        )
        log.info("%s: %s", self.path, note)
        self.notes.append(note)

    def _repair(self, fd: int) -> None:
        """Before the first append: cut a torn last line, or end a whole one with a newline."""
        size = os.fstat(fd).st_size
        if not size or os.pread(fd, 1, size - 1) == b"\n":
            return
        tail_at = max(0, size - (1 << 20))
        tail = os.pread(fd, size - tail_at, tail_at)
        start = tail_at + tail.rfind(b"\n") + 1 if b"\n" in tail else tail_at
        last = os.pread(fd, size - start, start)
        try:
            evaluation_from_record(json.loads(last.decode("utf-8")))
        except (ValueError, RecursionError):
            log.warning("%s: dropping a torn last line", self.path)
            os.ftruncate(fd, start)
            return
        os.write(fd, b"\n")

    def append(self, evaluation: Evaluation) -> None:
        """Add one evaluation: once this returns, a SIGKILL of this process does not lose it.

        It is fsynced (safe from a power cut) by the next :meth:`sync`, or here when the last
        sync is ``sync_interval_s`` old.
        """
        if self._fd is None:
            self._fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_APPEND, 0o666)
            self._repair(self._fd)
        line = json.dumps(evaluation_record(evaluation), allow_nan=True) + "\n"
        os.write(self._fd, line.encode("utf-8"))  # one write: O_APPEND keeps lines whole
        self.n_appended += 1
        if time.monotonic() - self._t_sync >= self.sync_interval_s:
            self.sync()

    def sync(self) -> None:
        """fsync every line appended so far (no-op when there is none new)."""
        if self._fd is not None and self.n_synced < self.n_appended:
            os.fsync(self._fd)
            self.n_fsyncs += 1
            self.n_synced = self.n_appended
        self._t_sync = time.monotonic()

    def close(self) -> None:
        """fsync and close the file (appending again reopens it)."""
        if self._fd is not None:
            try:
                self.sync()
            finally:
                os.close(self._fd)
                self._fd = None


def checkpoint_text(data: Mapping[str, Any]) -> str:
    """The text of ``checkpoint.json`` for ``data`` (``format`` added)."""
    return to_json({"format": FORMAT, **data})


def write_checkpoint(run_dir: Path, data: Mapping[str, Any]) -> None:
    """Write ``checkpoint.json`` atomically (``format`` added)."""
    write_atomic(run_dir / CHECKPOINT_FILE, checkpoint_text(data))


def read_checkpoint(run_dir: Path, option: str = "RUN_DIR") -> dict[str, Any] | None:
    """``checkpoint.json`` of a run folder, or None when there is none.

    Raises
    ------
    StudyError
        (a ValueError) At ``option`` when it cannot be read, is not JSON, is not a checkpoint
        of this format or a field has the wrong type.
    """
    path = run_dir / CHECKPOINT_FILE
    fix = (
        "was it edited? delete it: flexopt run --resume rewrites it after the next generation "
        "(it is not needed to resume)"
    )
    data = read_folder_json(path, option, fix)
    if data is None:
        return None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        what = echo(data.get("format")) if isinstance(data, dict) else echo(data)
        raise StudyError(
            option, f"'{path}' is not a flexopt checkpoint of format {FORMAT} (got {what}); {fix}"
        )

    def count(value: Any) -> bool:
        return isinstance(value, int) and not isinstance(value, bool) and value >= 0

    checks = {
        "study_sha256": (lambda v: isinstance(v, str), "text"),
        "generation": (count, "a whole number >= 0"),
        "n_gen": (count, "a whole number >= 0"),
        "pop_size": (count, "a whole number >= 0"),
        "n_evaluations": (count, "a whole number >= 0"),
        "rng": (lambda v: isinstance(v, dict), "a mapping"),
        "population": (
            lambda v: (
                isinstance(v, list)
                and all(isinstance(x, list) and all(_number(n) for n in x) for x in v)
            ),
            "a list of design vectors",
        ),
    }
    for key, (check, what) in checks.items():
        if key in data and not check(data[key]):
            raise StudyError(option, f"'{path}': {key} is {echo(data[key])}, not {what}; {fix}")
    return data
