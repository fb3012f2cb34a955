"""Run folders: where a command's results go, each file written atomically.

Also the two things every command that opens an existing run folder needs:

- :func:`lock_run_dir`, an exclusive lock on the folder (``.flexopt.lock``, ``flock``) that a run
  holds for its whole life, so two commands never write one folder at once;
- validated readers of the folder's files (:func:`read_folder_json`, :func:`read_folder_csv`,
  :func:`read_run_json`): a damaged file is a :class:`StudyError` naming the file, what is wrong
  with it and what to do, never a traceback.
"""

from __future__ import annotations

import contextlib
import csv
import errno
import io
import json
import math
import os
import socket
import stat
import tempfile
from collections.abc import Callable, Collection, Mapping, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

try:  # POSIX; elsewhere a run folder is not locked
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

import numpy as np
from flexopt.pipeline.errors import StudyError

__all__ = [
    "LOCK_FILE",
    "RunDirLock",
    "INPUTS_DIR",
    "check_out_dir",
    "copy_inputs",
    "echo",
    "file_mode",
    "grouped_files",
    "input_files",
    "input_hashes",
    "load_folder_study",
    "lock_run_dir",
    "make_run_dir",
    "new_run_dir_path",
    "probe_writable",
    "read_folder_bytes",
    "read_folder_csv",
    "read_folder_json",
    "read_folder_text",
    "read_records_csv",
    "read_run_json",
    "records_to_csv",
    "study_sha256_with_inputs",
    "regular_target",
    "table_to_csv",
    "text_cell",
    "to_json",
    "write_atomic",
]


def _read_umask() -> int:
    """The process's umask, read without changing it where Linux allows (``/proc``): setting it
    to read it would race with a thread creating a file in between."""
    with contextlib.suppress(OSError, ValueError):
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """The mode of a new file flexopt writes: ``0o666`` less the umask, as ``open`` gives."""
    return 0o666 & ~_read_umask()


def regular_target(path: Path, key: str = "--out") -> Path:
    """The file a write to ``path`` replaces: ``path``, or the file its symbolic link names.

    flexopt writes only regular files: a device node (``/dev/null``, a disk), a FIFO, a socket or
    a folder at ``path`` (or at the end of its link) is refused, never replaced or written into
    (as root, replacing ``/dev/null`` would break the system). A symbolic link to a regular file
    (or to nothing yet) is written through, so the link stays.

    Raises
    ------
    StudyError
        When ``path`` exists and is not a regular file, naming ``key``.
    """
    try:
        info = os.stat(path)  # follows a link: what a write would reach
    except FileNotFoundError:
        return Path(os.path.realpath(path)) if os.path.islink(path) else path
    except OSError as exc:
        raise StudyError(key, f"'{path}' cannot be examined ({exc.strerror})") from None
    if stat.S_ISREG(info.st_mode):
        return Path(os.path.realpath(path)) if os.path.islink(path) else path
    what = (
        "a folder"
        if stat.S_ISDIR(info.st_mode)
        else "a device node"
        if stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode)
        else "a FIFO"
        if stat.S_ISFIFO(info.st_mode)
        else "a socket"
        if stat.S_ISSOCK(info.st_mode)
        else "not a regular file"
    )
    raise StudyError(
        key,
        f"'{path}' is {what}; flexopt writes only regular files: give the path of a new or "
        "regular file",
    )


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one.

    The data goes to a temporary file in the same folder, is flushed to disk and then renamed over
    ``path`` with :func:`os.replace` (atomic on POSIX and Windows). Only a regular file is ever
    replaced (:func:`regular_target`; a link to one is written through); the new file's mode is
    ``0o666`` less the umask, as any program's.

    Raises
    ------
    OSError
        When the file cannot be written, or ``path`` is not a regular file (``EINVAL``).
    """
    try:
        path = regular_target(path)
    except StudyError as exc:
        raise OSError(errno.EINVAL, exc.problem, str(path)) from None
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(payload)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, file_mode())  # mkstemp makes 0600; the umask says what the user shares
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


# --------------------------------------------------------------------------------------------
# Files a study reads (target tables): copied into the run folder, hashed by their bytes

#: The run folder's copy of every file its study reads (``inputs/<name>``).
INPUTS_DIR = "inputs"


def _table_files(data: Any, path: str, found: list[tuple[str, dict[str, Any]]]) -> None:
    if isinstance(data, dict):
        if data.get("kind") == "table" and isinstance(data.get("file"), str):
            found.append((f"{path}.file" if path else "file", data))
        for key, value in data.items():
            _table_files(value, f"{path}.{key}" if path else str(key), found)
    elif isinstance(data, list):
        for i, value in enumerate(data):
            _table_files(value, f"{path}[{i}]", found)


def input_files(study: Any) -> list[tuple[str, str]]:
    """``(key path, file)`` of every file ``study`` reads: each target table's ``file:``
    (``requirements[0].target.file``, ``target.file``, ``spring.file``...), in key order."""
    found: list[tuple[str, dict[str, Any]]] = []
    _table_files(study.model_dump(mode="json", exclude_none=True), "", found)
    return [(key, spec["file"]) for key, spec in found]


def input_hashes(study: Any) -> dict[str, str]:
    """sha256 of the bytes of every file ``study`` reads, by key path (read as the study reads
    them: bounded, regular files only; a bad file is the study's :class:`StudyError`)."""
    import hashlib

    from flexopt.pipeline.targets import read_table_bytes

    return {
        key: hashlib.sha256(read_table_bytes(file, key)).hexdigest()
        for key, file in input_files(study)
    }


def study_sha256_with_inputs(study: Any, base: str) -> str:
    """The hash a run records for ``study``: ``base`` (:func:`checkpoint.study_sha256`, of the
    study's text) when it reads no file, else the hash of the study with each file's NAME
    replaced by the sha256 of its BYTES.

    So a resume is refused when a target table changed though its name did not, and accepted
    when the run folder's study names its own copy (``inputs/curve.csv``) of the same bytes.
    """
    import hashlib

    hashes = input_hashes(study)
    if not hashes:
        return base
    data = study.model_dump(mode="json", exclude_none=True)
    data.pop("parallel", None)  # as study_sha256: where designs are solved changes nothing
    found: list[tuple[str, dict[str, Any]]] = []
    _table_files(data, "", found)
    for key, spec in found:
        spec["file"] = f"sha256:{hashes[key]}"
    text = json.dumps(data, sort_keys=True, ensure_ascii=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _input_name(file: str, used: set[str]) -> str:
    """A safe, unique file name in ``inputs/`` for ``file`` (its own name where it can)."""
    stem = "".join(c if c.isalnum() or c in "._-" else "_" for c in Path(file).name)
    stem = stem.lstrip(".")[-80:] or "table.csv"
    name, k = stem, 1
    while name in used:
        k += 1
        name = f"{k}-{stem}"
    used.add(name)
    return name


def copy_inputs(study: Any, run_dir: Path) -> tuple[Any, dict[str, dict[str, str]]]:
    """Copy every file ``study`` reads into ``run_dir/inputs/``, so the folder stands alone.

    Returns
    -------
    study : the same study with each ``file:`` naming its copy (``inputs/curve.csv``, relative
        to the run folder: write it as the folder's study.yaml).
    record : ``{key path: {"file": "inputs/...", "source": as given, "sha256": of the bytes}}``
        for run.json / evaluation.json (empty when the study reads no file).

    Raises
    ------
    StudyError
        When a file cannot be read (as the study's load would say).
    OSError
        When the copy cannot be written.
    """
    import hashlib

    from flexopt.pipeline.targets import read_table_bytes, table_root

    files = input_files(study)
    if not files:
        return study, {}
    folder = run_dir / INPUTS_DIR
    folder.mkdir(exist_ok=True)
    used: set[str] = set()
    record: dict[str, dict[str, str]] = {}
    for key, file in files:
        data = read_table_bytes(file, key)
        name = f"{INPUTS_DIR}/{_input_name(file, used)}"
        write_atomic(run_dir / name, data)
        record[key] = {"file": name, "source": file, "sha256": hashlib.sha256(data).hexdigest()}
    with table_root(run_dir):  # the copies are read (validated) from the run folder
        copied = study.with_values({key: entry["file"] for key, entry in record.items()})
    return copied, record


def load_folder_study(run_dir: Path, path: Path) -> Any:
    """The study.yaml of a run or evaluate folder, its table files read from the folder's own
    copies (``inputs/``) wherever the command runs; the returned study names them by absolute
    path, so it works in any folder and process. A folder written before the copies were made
    names files relative to the working folder, which is tried next."""
    from flexopt.pipeline.study import load_study
    from flexopt.pipeline.targets import table_root

    with table_root(run_dir):
        study = load_study(path)
        inside = {
            key: str((run_dir / file).resolve())
            for key, file in input_files(study)
            if not Path(file).is_absolute() and (run_dir / file).is_file()
        }
        return study.with_values(inside) if inside else study


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
    if value is None or isinstance(value, str):  # a load_case column, a gap in a bool column
        return "" if value is None else value
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


#: What a spreadsheet takes for the start of a formula (OWASP's list for CSV injection).
FORMULA_LEAD = ("=", "+", "-", "@", "\t", "\r")


def text_cell(text: str) -> str:
    """A text cell of a CSV file flexopt writes: one that a spreadsheet would take for a formula
    (``=HYPERLINK(...)``, ``@SUM``, ``+1+1``; a number such as ``-1.5`` excepted) gets a leading
    ``'``, so it is shown as the text it is. Names obey the name rule (docs/usage.md, "Names")
    and never start so; this guards the other text a row carries (reasons, a kind's values)."""
    if text.startswith(FORMULA_LEAD):
        try:
            float(text)
        except ValueError:
            return "'" + text
    return text


def _record_cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return text_cell(value)
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
    # The plain types first, by exact type (what most values are): the isinstance checks against
    # the abstract Mapping made a checkpoint's population (pop_size x n_var floats) cost ~10 ms
    # a generation in the run process. The same result as the general path below.
    kind = type(value)
    if kind is float:
        return value if math.isfinite(value) else None
    if kind is str or kind is int or kind is bool or value is None:
        return value
    if kind is list:
        return [_jsonable(v) for v in value]
    if kind is np.ndarray and value.ndim and value.dtype.kind in "biuf":
        return _jsonable(value.tolist())  # the items' .item(), nested as the rows are
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


# --------------------------------------------------------------------------------------------
# Echoing values in messages

#: Characters of a value echoed in a message (a message stays one readable line).
ECHO_CHARS = 60


def echo(value: Any) -> str:
    """``repr(value)`` cut to :data:`ECHO_CHARS` characters (``…`` marks the cut)."""
    text = repr(value)
    return text if len(text) <= ECHO_CHARS else text[: ECHO_CHARS - 1] + "…"


# --------------------------------------------------------------------------------------------
# The run-folder lock

#: The lock file of a run folder: whoever holds an exclusive ``flock`` on it may write the folder.
LOCK_FILE = ".flexopt.lock"

#: File descriptors of the locks this process holds; a forked child (a worker) closes its copies,
#: so that a worker outliving a killed run does not keep its folder locked.
_HELD: set[int] = set()


def _close_held_locks_in_child() -> None:
    for fd in list(_HELD):
        with contextlib.suppress(OSError):
            os.close(fd)
    _HELD.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_close_held_locks_in_child)


class RunDirLock:
    """An exclusive lock on a run folder, held until :meth:`release` or the end of the process.

    The kernel drops the lock of a process that dies (also on SIGKILL), so a killed run never
    leaves its folder locked; the lock file it leaves behind is reused by the next taker.

    Attributes
    ----------
    run_dir : the folder.
    path : its lock file.
    created : whether this lock created the lock file (it is then removed on release).
    claimed : whether :meth:`claim` was called (the holder writes the folder).
    """

    def __init__(self, run_dir: Path, fd: int | None, created: bool) -> None:
        self.run_dir = run_dir
        self.path = run_dir / LOCK_FILE
        self._fd = fd
        self.created = created
        self.claimed = False

    @property
    def held(self) -> bool:
        return self._fd is not None

    def claim(self, command: str = "run") -> None:
        """Say who writes the folder (pid, host, command in the lock file, what a refused
        taker reports); from now on the lock file is removed on release."""
        if self._fd is None:
            return
        text = f"{os.getpid()} {socket.gethostname()} {command}\n".encode()
        with contextlib.suppress(OSError):
            os.ftruncate(self._fd, 0)
            os.pwrite(self._fd, text, 0)
        self.claimed = True

    def release(self) -> None:
        """Drop the lock (idempotent). A lock file this holder created or wrote is removed first,
        while still locked: a taker that opened it meanwhile sees it is gone and tries again."""
        fd, self._fd = self._fd, None
        if fd is None:
            return
        if self.claimed or self.created:
            with contextlib.suppress(OSError):
                os.unlink(self.path)
        _HELD.discard(fd)
        with contextlib.suppress(OSError):
            os.close(fd)

    def __enter__(self) -> RunDirLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _lock_holder(path: Path, fd: int) -> str:
    """``flexopt run (pid 123)``: who holds the lock on ``path`` (from /proc/locks on Linux,
    else the lock file's content), as far as can be told."""
    pid: int | None = None
    command = "run"
    with contextlib.suppress(OSError, ValueError):
        info = os.fstat(fd)
        for line in Path("/proc/locks").read_text().splitlines():
            fields = line.replace("->", " ").split()
            if "FLOCK" not in fields:
                continue
            at = fields.index("FLOCK")
            device, _, inode = fields[at + 4].rpartition(":")
            major, _, minor = device.partition(":")
            if int(inode) == info.st_ino and (int(major, 16), int(minor, 16)) == (
                os.major(info.st_dev),
                os.minor(info.st_dev),
            ):
                pid = int(fields[at + 3])
                break
    with contextlib.suppress(OSError, ValueError, UnicodeDecodeError):
        words = os.pread(fd, 200, 0).decode("utf-8").split()
        if len(words) >= 3 and words[2].isidentifier():
            if pid is None or int(words[0]) == pid:
                pid, command = int(words[0]), words[2]
    return f"flexopt {command}" + (f" (pid {pid})" if pid and pid > 0 else "")


def lock_run_dir(run_dir: Path, option: str, hint: str) -> RunDirLock:
    """Take the exclusive lock of an existing run folder, without waiting.

    Parameters
    ----------
    run_dir : Path
        The folder (it must exist).
    option : str
        The option named in the refusal (``--out``, ``--resume``, ``RUN_DIR``).
    hint : str
        What to do when another process holds the lock.

    Raises
    ------
    StudyError
        When another flexopt process holds the lock: ``'DIR' is in use by another flexopt run
        (pid N); <hint>``.
    OSError
        When the lock file cannot be created (a read-only folder), with the fix in the message.
    """
    path = run_dir / LOCK_FILE
    if fcntl is None:  # pragma: no cover - no flock: no lock
        return RunDirLock(run_dir, None, False)
    flags = os.O_RDWR | getattr(os, "O_CLOEXEC", 0)
    for _ in range(20):
        created = False
        try:
            fd = os.open(path, flags | os.O_CREAT | os.O_EXCL, 0o666)
            created = True
        except FileExistsError:
            try:
                fd = os.open(path, flags)
            except FileNotFoundError:
                continue  # removed by its holder in between: try again
            except OSError as exc:
                raise _unlockable(run_dir, exc) from None
        except OSError as exc:
            raise _unlockable(run_dir, exc) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _lock_holder(path, fd)
            os.close(fd)
            raise StudyError(option, f"'{run_dir}' is in use by another {holder}; {hint}") from None
        except OSError as exc:
            os.close(fd)
            raise _unlockable(run_dir, exc) from None
        try:  # the holder before us may have removed the file while we opened it
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except OSError:
            same = False
        if same:
            _HELD.add(fd)
            return RunDirLock(run_dir, fd, created)
        os.close(fd)
    raise StudyError(option, f"'{run_dir}' could not be locked (its lock file keeps changing)")


def _unlockable(run_dir: Path, exc: OSError) -> OSError:
    return OSError(
        exc.errno,
        f"'{run_dir}' cannot be locked ({exc.strerror or exc}): {LOCK_FILE} cannot be created or "
        "locked there; fix the permissions or give another folder",
    )


# --------------------------------------------------------------------------------------------
# Validated readers of run-folder files


def read_folder_bytes(path: Path, option: str, fix: str) -> bytes | None:
    """The bytes of a run-folder file; None when there is no such file.

    Raises
    ------
    StudyError
        At ``option`` when the path is a folder (or other non-file) or cannot be read; ``fix``
        says what to do.
    """
    try:
        info = os.stat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise _unreadable(path, exc, option, fix) from None
    if stat.S_ISDIR(info.st_mode):
        raise StudyError(option, f"'{path}' is a folder, not a file; {fix}")
    if not stat.S_ISREG(info.st_mode):
        raise StudyError(option, f"'{path}' is not a regular file; {fix}")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise _unreadable(path, exc, option, fix) from None


def _unreadable(path: Path, exc: OSError, option: str, fix: str) -> StudyError:
    return StudyError(option, f"'{path}' cannot be read ({exc.strerror or exc}); {fix}")


def _decode(data: bytes, path: Path, option: str, fix: str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise StudyError(
            option,
            f"'{path}' line {line} is not UTF-8 text (byte 0x{data[exc.start]:02x}); {fix}",
        ) from None


def read_folder_text(path: Path, option: str, fix: str) -> str | None:
    """The UTF-8 text of a run-folder file; None when there is no such file.

    Raises
    ------
    StudyError
        As :func:`read_folder_bytes`, and for bytes that are not UTF-8 (naming the line).
    """
    data = read_folder_bytes(path, option, fix)
    return None if data is None else _decode(data, path, option, fix)


def parse_json(text: str, where: str, option: str, fix: str) -> Any:
    """``json.loads`` with every failure a one-line :class:`StudyError` about ``where``."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise StudyError(
            option,
            f"{where} is not valid JSON (truncated? {exc.msg}: line {exc.lineno} column "
            f"{exc.colno}); {fix}",
        ) from None
    except (ValueError, RecursionError) as exc:  # a huge integer, nesting too deep
        problem = str(exc) if isinstance(exc, ValueError) else "nested too deeply"
        raise StudyError(option, f"{where} is not valid JSON ({problem[:80]}); {fix}") from None


def read_folder_json(path: Path, option: str, fix: str) -> Any:
    """The JSON data of a run-folder file; None when there is no such file.

    Raises
    ------
    StudyError
        As :func:`read_folder_text`, and for text that is not JSON.
    """
    text = read_folder_text(path, option, fix)
    return None if text is None else parse_json(text, f"'{path}'", option, fix)


def read_folder_csv(
    path: Path, option: str, fix: str, required: Sequence[str] = ()
) -> list[dict[str, str]] | None:
    """The rows of a run-folder CSV file as dicts of text; None when there is no such file.

    Parameters
    ----------
    required : sequence of str
        Columns the header must have.

    Raises
    ------
    StudyError
        As :func:`read_folder_text`; for a file without a header, a header without a
        ``required`` column, or a row with another number of cells than the header (a cut row).
    """
    text = read_folder_text(path, option, fix)
    if text is None:
        return None
    try:
        table = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise StudyError(option, f"'{path}' is not a CSV table ({exc}); {fix}") from None
    if not table or not table[0]:
        raise StudyError(option, f"'{path}' is empty (no header row); {fix}")
    header = table[0]
    missing = [name for name in required if name not in header]
    if missing:
        raise StudyError(
            option,
            f"'{path}' has no column {echo(missing[0])}"
            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
            + f"; {fix}",
        )
    rows = []
    for number, cells in enumerate(table[1:], 2):
        if not cells:
            continue
        if len(cells) != len(header):
            raise StudyError(
                option,
                f"'{path}' line {number} has {len(cells)} cells, the header {len(header)} "
                f"(cut short?); {fix}",
            )
        rows.append(dict(zip(header, cells, strict=True)))
    return rows


def cell_float(row: Mapping[str, str], column: str, where: str, option: str, fix: str) -> float:
    """A number from a CSV row read by :func:`read_folder_csv` (``nan``/``inf`` allowed)."""
    text = row.get(column, "")
    try:
        return float(text)
    except (TypeError, ValueError):
        raise StudyError(
            option, f"{where}, column {echo(column)}: {echo(text)} is not a number; {fix}"
        ) from None


# -- run.json ---------------------------------------------------------------------------------


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _kind(checks: Callable[[Any], bool], what: str) -> tuple[Callable[[Any], bool], str]:
    return checks, what


_COUNT = _kind(lambda v: _is_int(v) and v >= 0, "a whole number >= 0")
_POSITIVE = _kind(lambda v: _is_int(v) and v >= 1, "a whole number >= 1")
_SECONDS = _kind(lambda v: v is None or (_is_number(v) and v >= 0), "a number >= 0 or null")
_TEXT = _kind(lambda v: isinstance(v, str), "text")
_TEXT_OR_NULL = _kind(lambda v: v is None or isinstance(v, str), "text or null")
_NAMES = _kind(
    lambda v: isinstance(v, list) and all(isinstance(i, str) for i in v), "a list of text"
)
_MAPPING = _kind(lambda v: isinstance(v, dict), "a mapping")
_SEED = _kind(lambda v: v is None or (_is_int(v) and v >= 0), "a whole number >= 0")

#: What each command reads of run.json, with its type: a value of another type is refused.
RUN_JSON_FIELDS: dict[str, tuple[Callable[[Any], bool], str]] = {
    "status": _kind(
        lambda v: v in ("running", "finished", "interrupted", "stopped", "failed"),
        "one of running, finished, interrupted, stopped, failed",
    ),
    "study": _TEXT,
    "kind": _TEXT,
    "source": _TEXT,
    "command_line": _TEXT,
    "error": _TEXT_OR_NULL,
    "started": _TEXT,
    "finished": _TEXT_OR_NULL,
    "hostname": _TEXT_OR_NULL,
    "pid": _kind(lambda v: v is None or (_is_int(v) and v >= 0), "a process id (a whole number)"),
    "quick": _kind(lambda v: isinstance(v, bool), "true or false"),
    "seed": _SEED,
    "study_sha256": _kind(
        lambda v: isinstance(v, str) and len(v) == 64 and all(c in "0123456789abcdef" for c in v),
        "a sha256 (64 hex digits)",
    ),
    "optimiser": _MAPPING,
    "optimiser.algorithm": _TEXT,
    "optimiser.pop_size": _POSITIVE,
    "optimiser.n_gen": _POSITIVE,
    "optimiser.seed": _SEED,
    "variables": _NAMES,
    "objectives": _NAMES,
    "constraints": _NAMES,
    "generations_done": _COUNT,
    "n_evaluations": _COUNT,
    "n_cache_hits": _COUNT,
    "n_restored": _COUNT,
    "n_solved": _COUNT,
    "n_failed": _COUNT,
    "n_feasible": _COUNT,
    "wall_s": _SECONDS,
    "optimise_wall_s": _SECONDS,
    "evaluations_per_s": _SECONDS,
    "mean_evaluation_s": _SECONDS,
    "worker_utilisation": _SECONDS,
    "resumed": _kind(
        lambda v: (
            isinstance(v, list)
            and all(isinstance(i, dict) and isinstance(i.get("at"), str) for i in v)
        ),
        "a list of mappings with an 'at' time",
    ),
    "failure_reasons": _kind(
        lambda v: isinstance(v, dict) and all(_is_int(n) for n in v.values()),
        "a mapping of reasons to counts",
    ),
    "files": _NAMES,
    "file_counts": _kind(
        lambda v: isinstance(v, dict) and all(_is_int(n) and n >= 0 for n in v.values()),
        "a mapping of folders to counts",
    ),
    "notes": _NAMES,
    "parallel": _MAPPING,
    "versions": _MAPPING,
    "host": _MAPPING,
}


def grouped_files(names: Sequence[str]) -> tuple[list[str], dict[str, int]]:
    """The ``files`` list of run.json / evaluation.json: ``names`` (relative paths of the files
    written) with the files inside a folder (``best_steps/best_000.vtu`` ..., one VTU per load
    step of best.pvd: 61 for constant-force) listed as that folder once, ``best_steps/`` (the
    trailing slash says it is a folder), at its first file's place; and how many files each
    such folder holds (``file_counts``). Names without a folder are kept as they are, in order;
    a folder's entry given again (a list already grouped) is kept once and counts no file.
    """
    files: list[str] = []
    counts: dict[str, int] = {}
    for name in names:
        folder, sep, rest = str(name).partition("/")
        if not sep:
            files.append(str(name))
            continue
        key = f"{folder}/"
        if key not in counts:
            files.append(key)
            counts[key] = 0
        counts[key] += 1 if rest else 0
    return files, counts


def _run_json_fix(run_dir: Path) -> str:
    return (
        "was it edited or cut short? restore it from a copy, or start a new run with flexopt run "
        f"{run_dir / 'study.yaml'}"
    )


def read_run_json(run_dir: Path, option: str = "RUN_DIR") -> dict[str, Any]:
    """run.json of a run folder of ``flexopt run``, every field a command relies on checked.

    Fields may be missing (older runs); a field that is there must have its type
    (:data:`RUN_JSON_FIELDS`).

    Raises
    ------
    StudyError
        At ``option`` when ``run_dir`` is not a folder, has no run.json, or its run.json cannot
        be read, is not JSON, is not the record of a flexopt run or has a field of the wrong type.
    """
    if not run_dir.is_dir():
        raise StudyError(option, f"'{run_dir}' is not a folder; give a run folder of flexopt run")
    path = run_dir / "run.json"
    fix = _run_json_fix(run_dir)
    record = read_folder_json(path, option, fix)
    if record is None:
        raise StudyError(
            option, f"'{run_dir}' has no run.json; give a folder written by flexopt run"
        )
    if not isinstance(record, dict):
        raise StudyError(
            option, f"'{path}' holds {echo(record)}, not the record of a flexopt run; {fix}"
        )
    if record.get("command") != "run":
        raise StudyError(
            option,
            f"'{path}' is not the record of a flexopt run (command is "
            f"{echo(record.get('command'))}, not 'run'); give a folder written by flexopt run",
        )
    for key, (check, what) in RUN_JSON_FIELDS.items():
        parent, _, name = key.rpartition(".")
        holder = record.get(parent) if parent else record
        if not isinstance(holder, dict) or name not in holder:
            continue
        if not check(holder[name]):
            raise StudyError(option, f"'{path}': {key} is {echo(holder[name])}, not {what}; {fix}")
    return record
