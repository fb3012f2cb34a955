"""Speed of flexopt's compiled beam kernel against its numpy reference path and OpenSees.

Run from the repository root::

    python benchmarks/beam_kernel_speed.py [--repeat 11]

Prints, with the load average at start and end:

1. **First call in a fresh install.** A child process with an empty ``NUMBA_CACHE_DIR`` imports
   flexopt and solves one curve: its first solve compiles the kernel (CPU and wall time). A second
   child with the cache the first one wrote loads it instead, which is what every later process
   (a worker, a run) pays. No other figure below includes either.
2. **The three curves of benchmarks/beam_vs_opensees.py** (20 steps each), numpy path, numba path
   and OpenSees with 100 elements (when openseespy imports), interleaved round by round, medians
   of CPU time (``time.process_time``) and wall time. flexopt runs at the matched-accuracy mesh
   (the smallest of beam_vs_opensees.MATCH_LADDER whose error is at most OpenSees-100's; without
   OpenSees the meshes 10, 8, 16 found that way on 2026-11-23) and at 20 elements.
3. **One constant-force design evaluation** as a run evaluates it
   (``ConstantForceProblem.evaluate`` on the default study's design: 60 elements, 60 rows), with
   each kernel (FLEXOPT_BEAM_KERNEL), interleaved.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import beam_vs_opensees as bvo  # noqa: E402
from flexopt.fea.beam import KERNEL_ENV, BeamModel, BeamSettings  # noqa: E402
from flexopt.geometry.profile import BeamProfile  # noqa: E402

#: matched-accuracy meshes of docs/benchmarks.md, used when OpenSees is not installed
FALLBACK_MATCH = {"cantilever-force": 10, "cantilever-disp": 8, "fixed-guided": 16}

_CHILD = """
import json, sys, time
c0, w0 = time.process_time(), time.perf_counter()
sys.path.insert(0, {root!r})
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
from flexopt.fea.materials import get_material
from flexopt.geometry.profile import BeamProfile
c1, w1 = time.process_time(), time.perf_counter()
profile = BeamProfile([[0.0, 0.0], [100.0, 0.0]], [0.1, 0.1], 5.0)
drive = EndDrive("force", (0.0, 1.0), 7.5e-4, 20, "free", "free")
times = []
for _ in range(2):
    c, w = time.process_time(), time.perf_counter()
    model = BeamModel(profile, get_material("ABS"), settings=BeamSettings(kernel="numba"))
    assert model.solve(drive).ok
    times.append((time.process_time() - c, time.perf_counter() - w))
print(json.dumps({{"kernel": model.kernel, "import": (c1 - c0, w1 - w0), "first": times[0],
                  "second": times[1]}}))
"""


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def first_call(cache_dir: str) -> dict:
    """Run the child with ``NUMBA_CACHE_DIR=cache_dir``; its timings (s, as (cpu, wall))."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    env.pop(KERNEL_ENV, None)
    out = subprocess.run(
        [sys.executable, "-c", _CHILD.format(root=str(ROOT))],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def interleaved(runs: list[Callable[[], object]], repeat: int) -> list[tuple[float, float]]:
    """(median CPU s, median wall s) of each run over ``repeat`` interleaved rounds, after one
    untimed warm-up round."""
    for run in runs:
        run()
    cpu: list[list[float]] = [[] for _ in runs]
    wall: list[list[float]] = [[] for _ in runs]
    for _ in range(repeat):
        for run, c, w in zip(runs, cpu, wall, strict=True):
            c0, w0 = time.process_time(), time.perf_counter()
            run()
            w.append(time.perf_counter() - w0)
            c.append(time.process_time() - c0)
    return [(statistics.median(c), statistics.median(w)) for c, w in zip(cpu, wall, strict=True)]


def ms(t: tuple[float, float]) -> str:
    return f"{t[0] * 1e3:8.2f} ({t[1] * 1e3:7.2f})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=11, help="timed rounds (median)")
    parser.add_argument("--skip-compile", action="store_true", help="skip section 1")
    args = parser.parse_args(argv)
    import numba
    import scipy

    print(f"date      {datetime.datetime.now().astimezone():%Y-%m-%d %H:%M %Z}")
    print(f"machine   {platform.machine()}, {os.cpu_count()} cores, {platform.system()}")
    print(
        f"software  Python {platform.python_version()}, numpy {np.__version__}, scipy "
        f"{scipy.__version__}, numba {numba.__version__}"
    )
    print(f"load avg  {load()} (1, 5, 15 min) at start\n")

    if not args.skip_compile:
        print("1. first call in a fresh install (child processes; CPU s (wall s))")
        with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache:
            cold = first_call(cache)
            warm = first_call(cache)
        for name, r in (("empty cache (compiles)", cold), ("cache written by it", warm)):
            print(
                f"  {name:<24} import {r['import'][0]:6.2f} ({r['import'][1]:6.2f})  first solve "
                f"{r['first'][0]:6.2f} ({r['first'][1]:6.2f})  second solve "
                f"{r['second'][0]:6.3f} ({r['second'][1]:6.3f})  kernel {r['kernel']}"
            )
        print(f"  load avg {load()}\n")

    try:
        import openseespy.opensees as ops

        ops.logFile(os.devnull, "-noEcho")
        have_ops = True
    except Exception as exc:  # openseespy missing, or its wheel cannot load BLAS
        print(f"(OpenSees not available: {type(exc).__name__}: {exc})")
        have_ops = False

    section = bvo.Section(bvo.DEFAULT_THICKNESS_MM)
    problems = bvo.make_problems(section)
    print(
        "2. benchmark curves (20 steps; model build + curve), ms CPU (wall), medians of "
        f"{args.repeat} interleaved rounds"
    )
    header = (
        f"  {'problem':<17} {'el.':>4} {'err %':>9} | {'numpy':>18} {'numba':>18} "
        f"{'OpenSees-100':>18} | {'numpy/numba':>11} {'OS-100/numba':>12}"
    )
    print(header)
    print("  " + "-" * (len(header) - 2))
    for problem in problems:
        if have_ops:
            ops_out = bvo.run_opensees(problem, 100, "BandGeneral")
            target = bvo.relative_error(ops_out, problem)
            match = next(
                n
                for n in bvo.MATCH_LADDER
                if bvo.relative_error(bvo.run_flexopt(problem, n, "numba"), problem) <= target
            )
        else:
            match = FALLBACK_MATCH[problem.key]
        for n in sorted({match, 20}):
            runs = [
                lambda p=problem, n=n: bvo.run_flexopt(p, n, "numpy"),
                lambda p=problem, n=n: bvo.run_flexopt(p, n, "numba"),
            ]
            if have_ops:
                runs.append(lambda p=problem: bvo.run_opensees(p, 100, "BandGeneral"))
            t = interleaved(runs, args.repeat)
            err = bvo.relative_error(bvo.run_flexopt(problem, n, "numba"), problem)
            os_col = ms(t[2]) if have_ops else f"{'-':>18}"
            os_ratio = f"{t[2][0] / t[1][0]:12.1f}" if have_ops else f"{'-':>12}"
            tag = " (matched)" if n == match else ""
            print(
                f"  {problem.key:<17} {n:>4} {bvo.format_pct(err):>9} | {ms(t[0])} {ms(t[1])} "
                f"{os_col} | {t[0][0] / t[1][0]:11.1f} {os_ratio}{tag}"
            )
    print(f"  load avg {load()}\n")

    print("3. one constant-force design evaluation (default study, 60 elements, 60 rows)")
    from flexopt.pipeline.studies.constant_force import ConstantForceProblem, design_vector
    from flexopt.pipeline.study import load_study

    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    prob = ConstantForceProblem(study)
    x = design_vector(study)

    def evaluate(kernel: str) -> object:
        os.environ[KERNEL_ENV] = kernel
        try:
            return prob.evaluate(x)
        finally:
            os.environ.pop(KERNEL_ENV, None)

    results = {k: evaluate(k) for k in ("numpy", "numba")}
    # Agreement to 1e-9 of the force level: flatness and RMS error are small differences of
    # forces (an RMS error of 0.01 N on 1.5 N), so they are compared on the force's scale.
    a, b = results["numpy"].metrics, results["numba"].metrics
    force = abs(a["mean_force_N"])
    same = (
        abs(a["mean_force_N"] - b["mean_force_N"]) <= 1e-9 * force
        and abs(a["rms_error_N"] - b["rms_error_N"]) <= 1e-9 * force
        and abs(a["flatness_percent"] - b["flatness_percent"]) <= 1e-9 * 100.0
        and abs(a["peak_stress_MPa"] - b["peak_stress_MPa"]) <= 1e-9 * a["peak_stress_MPa"]
    )
    t = interleaved([lambda: evaluate("numpy"), lambda: evaluate("numba")], args.repeat)
    print(
        f"  numpy {ms(t[0])} ms, numba {ms(t[1])} ms CPU (wall): "
        f"numpy/numba {t[0][0] / t[1][0]:.1f}"
    )
    print(
        f"  same metrics to 1e-9 of the force / stress level: {same}; "
        f"mean force {results['numba'].metrics['mean_force_N']:.6f} N"
    )
    probe = BeamModel(
        BeamProfile([[0.0, 0.0], [1.0, 0.0]], [0.1, 0.1], 1.0),
        bvo.MATERIAL,
        settings=BeamSettings(kernel="numba"),
    )
    print(f"  kernel that ran: {probe.kernel}")
    print(f"load avg  {load()} (1, 5, 15 min) at end")
    return 0


if __name__ == "__main__":
    status = main()
    sys.stdout.flush()
    sys.stderr.flush()
    # OpenSees prints "Process 0 Terminating" from a C++ destructor at exit (see beam_vs_opensees)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    sys.exit(status)
