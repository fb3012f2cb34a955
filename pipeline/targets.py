"""Target curves from a study: a target spec, its table read from a CSV file when it has one.

Shared by the kinds that take a target curve (``cam``, ``collision``, a ``mechanism`` target
table), by the verdict (a ``requirements:`` target table) and by the run folder (its copies of
the tables, :func:`table_root`). Moved unchanged from ``pipeline/studies/_targets.py``, which
modules outside the kinds' package had to reach into.
"""

from __future__ import annotations

import codecs
import contextlib
import contextvars
import csv
import io
import os
import stat
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.targets import TargetCurve, TargetSpec, column_unit_factor
from flexopt.pipeline.errors import StudyError

__all__ = [
    "MAX_TABLE_BYTES",
    "read_table_bytes",
    "read_table_csv",
    "resolve_table_path",
    "resolve_target",
    "table_root",
]

_EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

#: Largest target-table file read (1 MiB: a table of ~50 000 rows; a real one has tens). A larger
#: file is refused from its size before a byte is read (docs/usage.md, "Target tables").
MAX_TABLE_BYTES = 1024 * 1024

#: The folder a relative ``file:`` is taken from (None: the working folder). A run folder sets it
#: to itself while its study is used, so ``report`` and ``export`` work from anywhere.
_ROOT: contextvars.ContextVar[Path | None] = contextvars.ContextVar("table_root", default=None)


@contextlib.contextmanager
def table_root(folder: Path | None) -> Iterator[None]:
    """Take relative table ``file:`` names from ``folder`` inside the ``with`` block."""
    token = _ROOT.set(folder)
    try:
        yield
    finally:
        _ROOT.reset(token)


def _shown(file: str) -> str:
    """The file's name as given, cut for an error line (the name is the user's, not content)."""
    text = repr(file)
    return text if len(text) <= 80 else text[:76] + "...'"


def resolve_table_path(file: str) -> Path:
    """Where a table ``file:`` is: relative to :func:`table_root` when it is set (a run folder's
    own copies), else to the working folder, else in the built-in examples folder."""
    root = _ROOT.get()
    path = Path(file)
    if path.is_absolute():
        return path
    for candidate in ((root / path,) if root is not None else ()) + (path, _EXAMPLES / path):
        if candidate.exists() or candidate.is_symlink():
            return candidate
    return root / path if root is not None else path


def read_table_bytes(file: str, key: str = "target.file") -> bytes:
    """The bytes of a table file, refused unless it is a regular file of at most
    :data:`MAX_TABLE_BYTES`.

    The file is examined (``stat``) before it is opened and opened non-blocking, so a FIFO, a
    device (``/dev/zero``), a folder or a socket is refused at once instead of hanging or filling
    memory; at most ``MAX_TABLE_BYTES + 1`` bytes are read even when the size lied (``/proc``).

    Raises
    ------
    StudyError
        At ``key``, naming the file (never its content) and what to do.
    """
    path = resolve_table_path(file)
    shown = _shown(file)
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            raise StudyError(
                key, f"{shown} is not a regular file (a folder, FIFO or device); give a CSV file"
            )
        if info.st_size > MAX_TABLE_BYTES:
            raise StudyError(key, _too_large(shown))
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):  # swapped for a FIFO since the stat
                raise StudyError(key, f"{shown} is not a regular file; give a CSV file")
            with os.fdopen(fd, "rb", closefd=False) as handle:
                data = handle.read(MAX_TABLE_BYTES + 1)
        finally:
            os.close(fd)
    except OSError as exc:
        raise StudyError(
            key, f"cannot read {shown} ({exc.strerror}); give the path of a CSV file"
        ) from None
    if len(data) > MAX_TABLE_BYTES:
        raise StudyError(key, _too_large(shown))
    return data


def _too_large(shown: str) -> str:
    return (
        f"{shown} is larger than {MAX_TABLE_BYTES // 1024} KiB, the limit of a target table; "
        "give a table of the curve's points (tens to thousands of rows)"
    )


def _decode(data: bytes, shown: str, key: str) -> str:
    """UTF-8 (a BOM is dropped), or UTF-16 when the file starts with its BOM; nothing else."""
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        encoding = "utf-16"
    else:
        encoding = "utf-8-sig"
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise StudyError(
            key,
            f"{shown} is not {'UTF-16' if encoding == 'utf-16' else 'UTF-8'} text (byte "
            f"{exc.start}); save it as CSV UTF-8 (UTF-8 with or without a BOM, or UTF-16 with a "
            "BOM, are read)",
        ) from None
    if "\x00" in text:
        raise StudyError(
            key,
            f"{shown} holds NUL characters: it is not UTF-8 text (UTF-16 without a BOM, or not "
            "text at all); save it as CSV UTF-8",
        )
    return text


def read_table_csv(
    file: str, columns: tuple[str, str] | None, key: str = "target.file"
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[str, str]]:
    """Read two numeric columns of a CSV file with a header row.

    ``file`` is taken relative to :func:`table_root` (default the working folder), else to the
    built-in examples folder. Columns are chosen by name (``columns``) or are the first two. The
    file must be a regular file of at most :data:`MAX_TABLE_BYTES`, in UTF-8 (a BOM is allowed)
    or UTF-16 with a BOM. An error names the file and the key, never the file's content: a
    ``file:`` may name any readable file, and its first line is no business of the error.

    Returns
    -------
    ((n,) float, (n,) float), (str, str)
        The two columns, in the units of their names, and the names.

    Raises
    ------
    StudyError
        At ``key`` when the file is missing, not a regular file, too large, not text, has no
        such columns, or holds a non-number.
    """
    shown = _shown(file)
    text = _decode(read_table_bytes(file, key), shown, key)
    limit = csv.field_size_limit()
    try:
        csv.field_size_limit(MAX_TABLE_BYTES + 1)  # the file's size bounds a field
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise StudyError(
            key, f"{shown} is not a readable CSV file ({exc}); save it as CSV"
        ) from None
    finally:
        csv.field_size_limit(limit)
    rows = [r for r in rows if r and not r[0].lstrip().startswith("#")]
    if len(rows) < 3:
        raise StudyError(key, f"{shown} needs a header row and at least 2 rows of numbers")
    header = [h.strip() for h in rows[0]]
    if len(header) < 2:
        raise StudyError(key, f"{shown} needs at least two columns")
    if columns is None:
        names = (header[0], header[1])
        try:
            for name in names:
                column_unit_factor(name)
        except OptimiseError:
            raise StudyError(
                key,
                f"the first two columns of {shown} are not named with a unit; name them like "
                "rotation_deg, displacement_mm, torque_Nm or force_N in its header row, or "
                "choose them with target.columns",
            ) from None
    else:
        names = columns
    missing = [n for n in names if n not in header]
    if missing:
        raise StudyError(
            key.rsplit(".", 1)[0] + ".columns" if key.endswith(".file") else "target.columns",
            f"{shown} has no column {', '.join(repr(n) for n in missing)} in its header row "
            f"({len(header)} columns); give the names as its header row spells them",
        )
    idx = [header.index(n) for n in names]
    try:
        data = np.array([[float(r[i]) for i in idx] for r in rows[1:]], dtype=float)
    except (ValueError, IndexError, OverflowError):
        raise StudyError(
            key, f"{shown} has a row that is not two numbers in columns {list(names)}"
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
