"""Target curves from a study: a target spec, its table read from a CSV file when it has one.

Shared by the kinds that take a torque target (``cam``, ``collision``) and by the verdict (a
``requirements:`` target table). Moved here from ``pipeline/studies/cam.py`` unchanged.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.targets import TargetCurve, TargetSpec
from flexopt.pipeline.errors import StudyError

__all__ = ["read_table_csv", "resolve_target"]

_EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def read_table_csv(
    file: str, columns: tuple[str, str] | None, key: str = "target.file"
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[str, str]]:
    """Read two numeric columns of a CSV file with a header row.

    ``file`` is taken relative to the working directory, else to the built-in examples folder.
    Columns are chosen by name (``columns``) or are the first two.

    Raises
    ------
    StudyError
        At ``key`` when the file is missing, has no such columns, or holds a non-number.
    """
    path = Path(file)
    if not path.is_file() and (_EXAMPLES / file).is_file():
        path = _EXAMPLES / file
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise StudyError(
            key, f"cannot read '{file}' ({exc.strerror}); give the path of a CSV file"
        ) from None
    rows = [r for r in rows if r and not r[0].lstrip().startswith("#")]
    if len(rows) < 3:
        raise StudyError(key, f"'{file}' needs a header row and at least 2 rows of numbers")
    header = [h.strip() for h in rows[0]]
    names = columns or (header[0], header[1]) if len(header) >= 2 else None
    if names is None:
        raise StudyError(key, f"'{file}' needs at least two columns")
    missing = [n for n in names if n not in header]
    if missing:
        raise StudyError(
            "target.columns",
            f"'{file}' has no column {', '.join(missing)}; its columns are {', '.join(header)}",
        )
    idx = [header.index(n) for n in names]
    try:
        data = np.array([[float(r[i]) for i in idx] for r in rows[1:]])
    except (ValueError, IndexError):
        raise StudyError(
            key, f"'{file}' has a row that is not two numbers in columns {list(names)}"
        ) from None
    return (data[:, 0], data[:, 1]), (names[0], names[1])


def resolve_target(spec: TargetSpec, key: str = "target") -> TargetCurve:
    """The :class:`TargetCurve` of a spec, reading a table's file when it has one.

    Raises
    ------
    StudyError
        At ``key`` when the file cannot be read or the curve refuses the values.
    """
    table = columns = None
    if spec.kind == "table" and spec.file is not None:
        table, columns = read_table_csv(spec.file, spec.columns, f"{key}.file")
    try:
        return spec.to_curve(table, columns)
    except OptimiseError as exc:
        raise StudyError(key, str(exc)) from exc
