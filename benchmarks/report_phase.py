"""The report phase of a run alone (issue 27 item 4): ``RunState.finish`` of a finished run
folder, made again in fresh processes, as ``flexopt report RUN_DIR`` makes it, after the
imports a run's preload thread makes while its workers solve.

    nice python benchmarks/report_phase.py RUN_DIR [--repeat 5] [--ab OTHER_PYTHON]

Each round copies RUN_DIR (a finished ``flexopt run`` folder) to a temporary folder and, in a
fresh process of this interpreter (and of OTHER_PYTHON, alternating, A first), imports what the
run's report preload imports (matplotlib, trimesh, manifold3d, ezdxf, scipy.optimize, the
report's modules, report.html's template and plotly.js warm-up, the kind's ``warm_up`` and ``warm_up_detail``),
then times ``rebuild_report`` with ``RunState.finish`` inside it: wall (``time.perf_counter``),
the CPU of the process (``time.process_time``) and of the children it waited for (the plot
children, best.step's; ``RUSAGE_CHILDREN``), s. Medians are printed with the load average, since
the machine is shared. A hybrid run hands its report the exact Jacobian at the best design
(``known_jacobian``) and its detail finds the checks its workers made (the kind's memo): here
the Jacobian is taken and the detail solved once before the timer starts.
The copies are removed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import json, resource, sys, time
from pathlib import Path

def children():
    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return u.ru_utime + u.ru_stime

import matplotlib.backends.backend_agg, matplotlib.figure  # noqa: E401
import flexopt.geometry.dxf, flexopt.geometry.solid, manifold3d, scipy.optimize, trimesh  # noqa
from flexopt.pipeline.html_templates import warm_up
from flexopt.pipeline.run import rebuild_report
from flexopt.pipeline.run import state
import flexopt.pipeline.report, flexopt.pipeline.report_html, flexopt.pipeline.vtu  # noqa
warm_up()
times = {}
real = state.RunState.finish

def timed(self, result, *args, **kwargs):
    self.problem.warm_up()
    self.problem.warm_up_detail()
    # a hybrid run hands the report its Jacobian at the best design (known_jacobian)
    import numpy as np
    from flexopt.pipeline.sensitivity_report import known_jacobian
    x = np.asarray(result.best.x, dtype=float)
    jacobian = self.problem.jacobian(x)
    # a run's detail finds the best design's plane-stress check made by a worker (its memo)
    self.problem.detail(x)
    if jacobian is not None:
        known_jacobian(self.problem, jacobian)
    t0, c0, k0 = time.perf_counter(), time.process_time(), children()
    try:
        return real(self, result, *args, **kwargs)
    finally:
        times.update(wall=time.perf_counter() - t0, cpu=time.process_time() - c0,
                     children_cpu=children() - k0)

state.RunState.finish = timed
rebuild_report(Path(sys.argv[1]))
print(json.dumps(times))
"""


def _round(python: str, run_dir: Path) -> dict[str, float]:
    with tempfile.TemporaryDirectory(prefix="report-phase-") as tmp:
        copy = Path(tmp) / "run"
        shutil.copytree(run_dir, copy)
        done = subprocess.run(
            [python, "-c", CHILD, str(copy)], capture_output=True, text=True, check=False
        )
        if done.returncode != 0:
            raise SystemExit(f"{python} failed: {done.stderr[-800:]}")
        return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--ab", metavar="OTHER_PYTHON", help="A: this interpreter's other install")
    args = parser.parse_args()
    installs = {"B": sys.executable}
    if args.ab:
        installs = {"A": args.ab, "B": sys.executable}
    print(f"load {' '.join(f'{v:.2f}' for v in os.getloadavg())} at start; {args.run_dir}")
    rows: dict[str, list[dict[str, float]]] = {k: [] for k in installs}
    for k in range(args.repeat):
        for name, python in installs.items():
            row = _round(python, args.run_dir)
            rows[name].append(row)
            print(
                f"  round {k + 1} {name}: finish {row['wall']:.3f} s wall, {row['cpu']:.3f} s CPU "
                f"(+ children {row['children_cpu']:.3f} s); load {os.getloadavg()[0]:.2f}",
                flush=True,
            )
    for name, got in rows.items():
        med = {key: statistics.median(r[key] for r in got) for key in got[0]}
        print(
            f"{name} ({installs[name]}): medians of {len(got)}: {med['wall']:.3f} s wall, "
            f"{med['cpu']:.3f} s CPU, children {med['children_cpu']:.3f} s CPU"
        )


if __name__ == "__main__":
    main()
