"""Two installs' `flexopt run STUDY`, alternating, on a shared machine (issue 27's wall figures).

    python benchmarks/ab_run.py A_VENV B_VENV [--study constant-force] [--rounds 10]

A_VENV and B_VENV are virtual environments with flexopt installed (e.g. two clones, each with
the README's quick start: ``python -m venv .venv && .venv/bin/pip install .``). Each round runs
A's ``bin/flexopt run STUDY --out <new folder>`` and then B's, as a user would (a fresh process,
its output to /dev/null), and prints each run's wall (s) and CPU (user + system of the process
and its children, s) with the 1-minute load average. The host's speed drifts from minute to
minute on shared machines, so the figure to read is the pair: B's wall over A's in the same
round (its median is printed), and each install's median. Nothing is timed inside flexopt.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _run(venv: Path, study: str, out: Path) -> tuple[float, float]:
    """(wall s, CPU s of the child) of one ``flexopt run``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run(
        [str(venv / "bin" / "flexopt"), "run", study, "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        check=True,
    )
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", type=Path, help="virtual environment A (run first each round)")
    parser.add_argument("b", type=Path, help="virtual environment B")
    parser.add_argument("--study", default="constant-force")
    parser.add_argument("--rounds", type=int, default=10)
    args = parser.parse_args(argv)
    for venv in (args.a, args.b):
        if not (venv / "bin" / "flexopt").exists():
            print(f"ab_run: {venv}: no bin/flexopt (give a venv with flexopt installed)")
            return 2
    print(f"{args.study}: A = {args.a}, B = {args.b}, {args.rounds} rounds; cores {os.cpu_count()}")
    walls: dict[str, list[float]] = {"A": [], "B": []}
    cpus: dict[str, list[float]] = {"A": [], "B": []}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(1, args.rounds + 1):
            line = []
            for name, venv in (("A", args.a), ("B", args.b)):
                wall, cpu = _run(venv, args.study, Path(tmp) / f"{name}{k}")
                walls[name].append(wall)
                cpus[name].append(cpu)
                line.append(f"{name} {wall:.2f} s wall {cpu:.2f} s CPU")
            line.append(f"load {os.getloadavg()[0]:.2f}")
            print(f"round {k}: " + ", ".join(line), flush=True)
    for name in ("A", "B"):
        print(
            f"  {name}: wall median {statistics.median(walls[name]):.2f} s "
            f"({min(walls[name]):.2f}-{max(walls[name]):.2f}), "
            f"CPU median {statistics.median(cpus[name]):.2f} s"
        )
    ratios = [b / a for a, b in zip(walls["A"], walls["B"], strict=True)]
    print(f"  B / A wall in the same round: median {statistics.median(ratios):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
