"""How quickly hostile or impossible inputs are refused: the wall time the tests no longer bound.

The tests (tests/pipeline/test_hostile_*.py, test_run_inputs.py, test_plugins.py,
test_constant_force_study.py) assert what a refusal does: exit 2, one line, nothing written and
nothing solved. How long it takes depends on the machine and on what else runs there, so it is
timed here instead (issue 24: no timed tests). Each case is run ``--repeat`` times; the median
and the slowest wall time are printed, with the load average. On an idle machine every case is
well under a second (docs/usage.md); before the limits, the bombs took minutes and gigabytes.

    python benchmarks/refusals.py               # every case, 3 rounds
    python benchmarks/refusals.py --repeat 7 --only bomb

Cases: study files (an alias bomb, nesting 5000 deep), target tables (1 GB sparse, /dev/zero, a
field far over the csv limit), study data from Python (contains itself, nested 100 000 deep, a
million points as a list and as an array, ``with_values``), ``--repeat 10**12``, and a
constant-force design too thin to print (infeasible before any solve).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import flexopt  # noqa: E402
from flexopt.pipeline.cli import main as cli  # noqa: E402
from flexopt.pipeline.errors import StudyError  # noqa: E402
from flexopt.pipeline.study import resolve_study_path  # noqa: E402

CANTILEVER = """\
name: cantilever
geometry:
  kind: polyline_beam
  points_mm: [[0, 0], [30, 0], [60, 0]]
  thickness_mm: [1.5, 1.5, 1.5]
  width_mm: 8.0
  elements: 30
material: ABS
boundary:
  start: clamped
  end: {control: displacement, direction: [0, 1], max_mm: 20.0, steps: 20}
"""

TABLED = (
    CANTILEVER
    + """requirements:
  - name: curve
    quantity: force_N
    x: displacement_mm
    target: {kind: table, file: FILE}
    tolerance_percent: 50
"""
)


def _bomb(levels: int = 9, fan: int = 10) -> str:
    """A billion-laughs alias chain: ``fan**levels`` leaves from a few hundred bytes."""
    text = "a0: &a0 [" + ", ".join(['"lol"'] * fan) + "]\n"
    for i in range(1, levels):
        text += f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * fan) + "]\n"
    return text


def _cantilever() -> dict:
    return yaml.safe_load(resolve_study_path("cantilever").read_text(encoding="utf-8"))


def _deep_list(depth: int) -> dict:
    nested: list = []
    cur = nested
    for _ in range(depth):
        nxt: list = []
        cur.append(nxt)
        cur = nxt
    raw = _cantilever()
    raw["geometry"]["points_mm"] = nested
    return raw


def _points(n: int, array: bool = False) -> dict:
    raw = _cantilever()
    pts = [[float(i), 0.0] for i in range(n)]
    raw["geometry"]["points_mm"] = np.array(pts) if array else pts
    return raw


def _self_containing() -> dict:
    raw = _cantilever()
    raw["geometry"]["extra"] = raw
    return raw


def _cli_refuses(argv: list[str]) -> None:
    """``flexopt ARGV`` in this process: it must exit 2 with one line on stderr."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = cli(argv)
    if code != 2 or len(err.getvalue().splitlines()) != 1:
        raise SystemExit(f"not refused in one line: flexopt {' '.join(argv)}: {err.getvalue()}")


def _api_refuses(call: Callable[[], object]) -> None:
    try:
        call()
    except StudyError:
        return
    raise SystemExit("not refused")


def _study_file_case(folder: Path, name: str, text: str) -> Callable[[], None]:
    path = folder / f"{name}.yaml"
    path.write_text(text, encoding="utf-8")
    return lambda: _cli_refuses(["evaluate", str(path)])


def _table_case(folder: Path, name: str, make: Callable[[Path], None] | Path):
    if isinstance(make, Path):
        table = make
    else:
        table = folder / f"{name}.csv"
        make(table)
    return _study_file_case(folder, name, TABLED.replace("FILE", str(table)))


def _sparse(size: int) -> Callable[[Path], None]:
    def make(path: Path) -> None:
        with open(path, "wb") as handle:
            handle.write(b"displacement_mm,force_N\n0,0\n10,1\n")
            handle.truncate(size)  # a hole: no disk used

    return make


def _too_thin() -> Callable[[], None]:
    """Paper 003's Table 3 design with a 0.7 mm segment: infeasible before any solve (the
    check of tests/pipeline/test_constant_force_study.py)."""
    import flexopt.pipeline.studies.constant_force as cf
    from flexopt.geometry.constant_force import (
        DESIGN_VARIABLE_NAMES,
        TABLE3_OPTIMUM,
        design_to_vector,
    )
    from flexopt.pipeline.study import validate_study

    raw = {"name": "cf", "geometry": {"kind": "constant_force"}, "material": "ABS"}
    problem = cf.problem(validate_study({**raw, "design_space": {"t6": [0.5, 1.15]}}))
    x = design_to_vector(TABLE3_OPTIMUM)
    x[DESIGN_VARIABLE_NAMES.index("t6")] = 0.7

    def run() -> None:
        ev = problem.evaluate(x.copy())
        if ev.feasible or not ev.reason.startswith("not printable"):
            raise SystemExit(f"the thin design was not refused as unprintable: {ev.reason}")

    return run


def cases(folder: Path) -> dict[str, Callable[[], None]]:
    # built once, outside the timing: only the refusal is timed
    deep, many, many_array = _deep_list(100_000), _points(1_000_000), _points(1_000_000, True)
    itself = _self_containing()
    study = flexopt.load_study("cantilever")
    return {
        "file: alias bomb as material": _study_file_case(
            folder, "bomb", _bomb() + CANTILEVER.replace("material: ABS", "material: *a8")
        ),
        "file: list nested 5000 deep": _study_file_case(
            folder,
            "nested",
            CANTILEVER.replace("material: ABS", "material: " + "[" * 5000 + "]" * 5000),
        ),
        "table: 1 GB (sparse)": _table_case(folder, "gb", _sparse(1024**3)),
        "table: /dev/zero": _table_case(folder, "zero", Path("/dev/zero")),
        "table: field over the csv limit": _table_case(
            folder,
            "field",
            lambda p: p.write_bytes(
                ("displacement_mm,force_N\n0,0\n10," + "9" * 200_000 + "x\n").encode()
            ),
        ),
        "api: load_study, contains itself": lambda: _api_refuses(
            lambda: flexopt.load_study(itself)
        ),
        "api: evaluate, nested 100000 deep": lambda: _api_refuses(lambda: flexopt.evaluate(deep)),
        "api: evaluate, a million points": lambda: _api_refuses(lambda: flexopt.evaluate(many)),
        "api: evaluate, a million points as an array": lambda: _api_refuses(
            lambda: flexopt.evaluate(many_array)
        ),
        "api: with_values, a million points": lambda: _api_refuses(
            lambda: study.with_values({"geometry.points_mm": many["geometry"]["points_mm"]})
        ),
        "api+cli: --repeat 10**12": lambda: (
            _api_refuses(lambda: flexopt.evaluate("cantilever", repeat=10**12)),
            _cli_refuses(["evaluate", "cantilever", "--repeat", str(10**12)]),
        ),
        "constant-force: a design too thin to print": _too_thin(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="rounds per case (default 3)")
    parser.add_argument("--only", default="", help="only the cases whose name has this text")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        os.chdir(folder)  # a refusal writes nothing; a default runs/ would appear here
        todo = {k: v for k, v in cases(folder).items() if args.only in k}
        print(
            f"load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores, {args.repeat} rounds"
        )
        print(f"{'case':<48} {'median s':>9} {'max s':>8}")
        for name, run in todo.items():
            times = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                run()
                times.append(time.perf_counter() - t0)
            print(f"{name:<48} {statistics.median(times):9.3f} {max(times):8.3f}")
        if list(folder.glob("runs")):
            raise SystemExit("a refusal wrote a runs/ folder")
        print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
