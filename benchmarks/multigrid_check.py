"""The SEA spring's 3D checks by the multigrid solver (a plain install's path: no cvxopt), two
installs A/B alternating in fresh processes (issue 27: ``flexopt run sea-spring`` <= 70 s on a
plain install; session 30).

    nice python benchmarks/multigrid_check.py [--study sea-spring] [--repeat 3]
        [--ab OTHER_PYTHON] [--solver multigrid]

Each round runs ``benchmarks/solid3d_check.py STUDY --checks-only --no-cvxopt`` (the report's
3D checks of the study's ``design:``, the peak convergence off; its numba kernels warmed by a
first, untimed round per interpreter) with this interpreter (B) and, with ``--ab``, another
install's (A, e.g. main's venv), the order swapped every round. Printed per run: the checks'
CPU (``time.process_time``) and wall, each check's iterations, and the figures the verdict
reads with every digit (to compare installs: they must agree to the multigrid tolerance, not
bit for bit, when the smoother's sums change order); then medians and the load average.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

CHECK = Path(__file__).resolve().parent / "solid3d_check.py"


def one(python: str, study: str, solver: str | None) -> dict:
    """One fresh process: the parsed lines of solid3d_check.py --checks-only."""
    cmd = [python, str(CHECK), study, "--checks-only", "--no-cvxopt"]
    if solver:
        cmd += ["--solver", solver]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    m = re.search(r"3D checks: CPU ([\d.]+) s, wall ([\d.]+) s, peak RSS ([\d.]+) GB, "
                  r"ST after ([\d.na]+) mm", out)  # fmt: skip
    if m is None:
        raise SystemExit(f"unexpected output of {cmd}:\n{out}")
    checks = re.findall(r"ST ([\d.]+) mm\s+(.+?)\s+(\d+) iterations .* K3D/K2D ([\d.]+)\s+"
                        r"peak 3D ([\d.]+) MPa", out)  # fmt: skip
    return {
        "cpu_s": float(m[1]), "wall_s": float(m[2]), "rss_gb": float(m[3]), "st_after": m[4],
        "iterations": [int(c[2]) for c in checks],
        "figures": [(c[0], c[3], c[4]) for c in checks],
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", default="sea-spring")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--ab", metavar="OTHER_PYTHON", help="A: another install's interpreter")
    ap.add_argument("--solver", default=None, help="solid_3d.solver (default: the study's)")
    args = ap.parse_args()
    pythons = {"B": sys.executable} | ({"A": args.ab} if args.ab else {})
    print(f"load average before {os.getloadavg()}")
    for py in pythons.values():  # warm: numba's cache, the study's imports
        one(py, args.study, args.solver)
    runs: dict[str, list[dict]] = {name: [] for name in pythons}
    order = sorted(pythons)
    for r in range(args.repeat):
        for name in order if r % 2 == 0 else order[::-1]:
            got = one(pythons[name], args.study, args.solver)
            runs[name].append(got)
            print(f"round {r} {name}: CPU {got['cpu_s']:.2f} s, wall {got['wall_s']:.2f} s, "
                  f"RSS {got['rss_gb']:.2f} GB, iterations {got['iterations']}, "
                  f"ST after {got['st_after']} mm, load {os.getloadavg()[0]:.1f}")  # fmt: skip
            for f in got["figures"]:
                print(f"    ST {f[0]} mm  K3D/K2D {f[1]}  peak 3D {f[2]} MPa")
    for name in order:
        cpu = statistics.median(g["cpu_s"] for g in runs[name])
        wall = statistics.median(g["wall_s"] for g in runs[name])
        print(f"{name} ({pythons[name]}): median CPU {cpu:.2f} s, wall {wall:.2f} s")
    print(f"load average after {os.getloadavg()}")


if __name__ == "__main__":
    main()
