"""Run folders: where a command's results go, each file written atomically."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
from collections.abc import Collection, Mapping, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.errors import StudyError

__all__ = [
    "check_out_dir",
    "make_run_dir",
    "new_run_dir_path",
    "probe_writable",
    "read_records_csv",
    "records_to_csv",
    "table_to_csv",
    "to_json",
    "write_atomic",
]


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one.

    The data goes to a temporary file in the same folder, is flushed to disk and then renamed over
    ``path`` with :func:`os.replace` (atomic on POSIX and Windows).
    """
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(payload)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; results are meant to be shared
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def new_run_dir_path(root: Path, name: str, command: str, now: datetime) -> Path:
    """``root/<name>-<command>-<YYYYmmdd-HHMMSS>``, with ``-2``, ``-3``… if that exists."""
    base = root / f"{name}-{command}-{now:%Y%m%d-%H%M%S}"
    path, k = base, 1
    while path.exists():
        k += 1
        path = base.with_name(f"{base.name}-{k}")
    return path


def check_out_dir(path: Path) -> None:
    """Refuse an ``--out`` that cannot become a folder, before any work is done.

    Raises
    ------
    StudyError
        When ``path`` exists and is not a directory.
    """
    if path.exists() and not path.is_dir():
        raise StudyError("--out", f"'{path}' exists and is not a folder; give a folder path")


#: Bytes the write probe writes: enough to meet a full disk (creating an empty file may succeed
#: there), small enough to cost nothing.
PROBE_BYTES = 64 * 1024


def probe_writable(path: Path) -> None:
    """Check that ``path`` (a run folder, existing or not) can be written, before any work.

    Writes, fsyncs and removes a small temporary file in ``path`` or, when it does not exist
    yet, in its nearest existing parent (where it will be created).

    Raises
    ------
    OSError
        Read-only, not permitted or full, with the folder and the fix in the message.
    """
    folder = path
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".flexopt-probe-", suffix=".tmp")
        with os.fdopen(fd, "wb") as handle:
            handle.write(b"\0" * PROBE_BYTES)
            handle.flush()
            os.fsync(handle.fileno())
    except OSError as exc:
        raise OSError(
            exc.errno,
            f"'{folder}' cannot be written ({exc.strerror or exc}); free some space, fix the "
            "permissions or give another folder with --out",
        ) from None
    finally:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)


def make_run_dir(path: Path) -> Path:
    """Create the run folder (and parents); an existing folder is reused."""
    path.mkdir(parents=True, exist_ok=True)
    return path


def _cell(value: Any) -> str:
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    value = float(value)
    return "nan" if math.isnan(value) else f"{value:.10g}"


def table_to_csv(table: Mapping[str, np.ndarray]) -> str:
    """Columns of equal length → CSV text with a header row (floats to 10 significant digits)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(list(table))
    columns = [np.asarray(col) for col in table.values()]
    for i in range(len(columns[0]) if columns else 0):
        writer.writerow([_cell(col[i].item()) for col in columns])
    return out.getvalue()


def _record_cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return value
    if isinstance(value, bool | np.bool_ | int | np.integer | float | np.floating):
        return _cell(value)
    return json.dumps(_jsonable(value), allow_nan=False, default=str)  # a list or mapping


def records_to_csv(
    records: Sequence[Mapping[str, Any]],
    columns: Sequence[str],
    exact: Collection[str] = (),
) -> str:
    """Rows of mixed values → CSV text with a header row.

    Parameters
    ----------
    records : sequence of mappings
        One per row; a key missing from a row is an empty cell.
    columns : sequence of str
        Header, in order; keys of a record not in it are left out.
    exact : collection of str
        Columns whose floats are written with every digit (``repr``: they read back to the same
        bits, as design variables must); other floats get 10 significant digits.

    Returns
    -------
    str
        ``true``/``false`` for booleans, ``nan`` for NaN, empty for ``None`` or a missing key,
        JSON for a list or mapping.
    """
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(list(columns))
    for record in records:
        row = []
        for column in columns:
            value = record.get(column)
            if column in exact and isinstance(value, float | np.floating):
                row.append(repr(float(value)))
            else:
                row.append(_record_cell(value))
        writer.writerow(row)
    return out.getvalue()


def read_records_csv(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV file with a header, as dicts of text."""
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple | np.ndarray):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None  # JSON has no NaN/inf
    return value


def to_json(data: Mapping[str, Any]) -> str:
    """Strict JSON text (NaN and inf become null, other objects their ``str``), indented."""
    return json.dumps(_jsonable(data), indent=2, allow_nan=False, default=str) + "\n"
