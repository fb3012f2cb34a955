"""Checkpoints as data: every finished evaluation on disk at once, and how to replay a run.

A run is a deterministic function of its study, its seed and its evaluations (see
:mod:`optimise.ga`). So a checkpoint is not a pickled optimiser but data:

- ``evaluations.jsonl`` — one JSON line per finished evaluation (exact float64 ``x``, ``f``,
  ``g``, metrics, reason, time), appended and fsynced as each design finishes, so a SIGKILL loses
  at most the designs still being solved. JSON writes floats as their shortest round-trip repr,
  so the numbers read back to the same bits.
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
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from optimise.evaluation import Evaluation
from pipeline.runfolder import to_json, write_atomic
from pipeline.study import Study, study_to_yaml

__all__ = [
    "CHECKPOINT_FILE",
    "STORE_FILE",
    "EvaluationStore",
    "evaluation_from_record",
    "evaluation_record",
    "read_checkpoint",
    "study_sha256",
    "write_checkpoint",
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
    """The Evaluation of a :func:`evaluation_record` (bit-identical ``x``, ``f`` and ``g``)."""
    return Evaluation(
        np.array(record["x"], dtype=float),
        np.array(record["f"], dtype=float),
        np.array(record["g"], dtype=float),
        dict(record.get("metrics") or {}),
        str(record.get("reason") or ""),
        float(record.get("time_s") or 0.0),
    )


class EvaluationStore:
    """``evaluations.jsonl``: finished evaluations, appended and fsynced one by one.

    Parameters
    ----------
    path : Path
        The store file (created on the first append).
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd: int | None = None
        self.n_appended = 0

    def load(self, n_var: int | None = None) -> list[Evaluation]:
        """Every evaluation in the store; a torn last line (a kill mid-write) is dropped.

        The file is rewritten without the torn line, so the next append starts a new line.

        Raises
        ------
        ValueError
            For a line other than the last that is not an evaluation (the store was edited),
            or a design with the wrong number of variables.
        """
        if not self.path.is_file():
            return []
        text = self.path.read_text(encoding="utf-8")
        lines = text.split("\n")
        out: list[Evaluation] = []
        good = 0  # characters of whole, readable lines
        for number, line in enumerate(lines, 1):
            if not line.strip():
                good += len(line) + 1
                continue
            last = number == len(lines)  # no newline after it: possibly cut short
            try:
                evaluation = evaluation_from_record(json.loads(line))
            except (ValueError, KeyError, TypeError) as exc:
                if last:
                    log.warning("%s: dropping a torn last line", self.path)
                    break
                raise ValueError(
                    f"{self.path} line {number} is not an evaluation ({exc}); was it edited?"
                ) from None
            if n_var is not None and evaluation.x.shape != (n_var,):
                raise ValueError(
                    f"{self.path} line {number} has {evaluation.x.size} design variables, the "
                    f"study {n_var}"
                )
            out.append(evaluation)
            good += len(line) + 1
        good = min(good, len(text))
        if good < len(text) or (text and not text.endswith("\n")):
            keep = text[:good]
            write_atomic(self.path, keep if keep.endswith("\n") or not keep else keep + "\n")
        return out

    def append(self, evaluation: Evaluation) -> None:
        """Add one evaluation and fsync it: once this returns, a SIGKILL does not lose it."""
        if self._fd is None:
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        line = json.dumps(evaluation_record(evaluation), allow_nan=True) + "\n"
        os.write(self._fd, line.encode("utf-8"))  # one write: O_APPEND keeps lines whole
        os.fsync(self._fd)
        self.n_appended += 1

    def close(self) -> None:
        """Close the file (appending again reopens it)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def write_checkpoint(run_dir: Path, data: Mapping[str, Any]) -> None:
    """Write ``checkpoint.json`` atomically (``format`` added)."""
    write_atomic(run_dir / CHECKPOINT_FILE, to_json({"format": FORMAT, **data}))


def read_checkpoint(run_dir: Path) -> dict[str, Any] | None:
    """``checkpoint.json`` of a run folder, or None when there is none.

    Raises
    ------
    ValueError
        When it is not a checkpoint this version can read.
    """
    path = run_dir / CHECKPOINT_FILE
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path} cannot be read ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{path} is not a flexopt checkpoint of format {FORMAT}")
    return data
