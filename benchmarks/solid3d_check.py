"""3D solid against plane stress on a sea-spring design (issue 15; quoted in docs/solid3d.md).

Run from the repository root::

    python benchmarks/solid3d_check.py [study] [--layers 2 4 6] [--grading 3]
    python benchmarks/solid3d_check.py [study] --checks-only [--solver multigrid] [--no-cvxopt]

For the study's ``design:`` (default ``sea-spring``; ST solved from the target, as the run does)
it prints the nonlinear 2D answer of each direction and the 3D check the run's report carries
(``SeaSpringProblem.solid_3d``: linear 3D / linear 2D on the same plane mesh, applied to the
nonlinear 2D answers), then the same linear ratios for each number of layers in ``--layers``
(convergence through the thickness), with DOFs, time and peak memory.

``--checks-only`` (issue 27): the report's 3D checks alone, in this process, the peak
convergence off (it runs in the report's second process): each check's ST, solver,
iterations and time, then the CPU (``time.process_time``) and wall of the whole
``SeaSpringProblem.solid_3d``, this process's peak RSS and the load average before and after.
``--solver`` sets ``solid_3d.solver``; ``--no-cvxopt`` makes cvxopt unimportable first (what a
plain install runs: no CHOLMOD anywhere, "auto" takes multigrid for the 3D check and QDLDL
for the plane-stress solves).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

if "--no-cvxopt" in sys.argv:  # before anything imports it: what a plain install runs
    sys.modules["cvxopt"] = None
    sys.modules["cvxopt.cholmod"] = None

from flexopt.fea.mesh import mesh_polygon  # noqa: E402
from flexopt.fea.plane_stress import Clamp, Rotate  # noqa: E402
from flexopt.fea.solid3d import Solid3DSettings, compare_with_plane_stress  # noqa: E402
from flexopt.pipeline.studies.sea_spring import SeaSpringProblem, design_vector  # noqa: E402
from flexopt.pipeline.study import load_study  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study", nargs="?", default="sea-spring")
    ap.add_argument("--layers", type=int, nargs="*", default=[])
    ap.add_argument("--grading", type=float, default=Solid3DSettings().grading)
    ap.add_argument("--checks-only", action="store_true")
    ap.add_argument("--solver", default=None)
    ap.add_argument("--no-cvxopt", action="store_true")
    args = ap.parse_args()
    if args.checks_only:
        checks_only(args.study, args.solver)
        return

    study = load_study(args.study)
    prob = SeaSpringProblem(study, stage1={})
    x = design_vector(study)
    if prob.solve_st:
        x = np.delete(x, prob.names.index("ST"))
    t0 = time.perf_counter()
    _, geom, r, st = prob.solve(x, 1)
    print(f"{args.study}: ST = {st:.4f} mm, 2D nonlinear solve {time.perf_counter() - t0:.1f} s")
    print(
        f"  2D: K ccw {r.stiffness_Nm_per_rad:.2f}, cw {r.reverse_stiffness_Nm_per_rad:.2f} "
        f"N m/rad at +-{math.degrees(prob.theta):.2f} deg, "
        f"linear {r.linear_stiffness_Nm_per_rad:.2f}, peak {r.worst_peak_stress_MPa:.1f} MPa"
    )
    check = prob.solid_3d(geom, r)
    check.pop("field", None)  # the 3D state's arrays (best_3d.vtu), not for printing
    print(json.dumps(check, indent=1, default=float))

    spec = study.mesh
    m = mesh_polygon(geom.fe_outline, spec.max_edge_mm,
                     refine=geom.mesh_regions(spec.elements_through, spec.max_edge_mm))  # fmt: skip
    ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)
    if args.layers:
        print("layers  K3D/K2D   peak3D/2D (vertex)  peak3D qp MPa   DOFs     time s")
    for n in args.layers:
        c = compare_with_plane_stress(
            m,
            prob.material,
            geom.thickness_mm,
            Clamp(geom.pad_region),
            Rotate(geom.hub_region, (0.0, 0.0), prob.theta, 1),
            Solid3DSettings(layers=n, grading=args.grading),
            stress_ignore=ignore,
        )
        s = c["solid3d"]
        print(
            f"{n:6d}  {c['stiffness_ratio']:.5f}   {c['peak_stress_ratio']:.4f}"
            f"              {c['peak_stress_qp_3d_MPa']:.1f}         {s['n_dofs']:7d}  "
            f"{s['times_s']['total']:.1f}"
        )
    peak_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    print(f"peak memory {peak_gb:.2f} GB")


def checks_only(name: str, solver: str | None) -> None:
    """The report's 3D checks of the study's design, the peak convergence off (see above)."""
    print(f"load average {os.getloadavg()}")
    study = load_study(name)
    update = {"converge_peak": False, **({"solver": solver} if solver else {})}
    study = study.model_copy(update={"solid_3d": study.solid_3d.model_copy(update=update)})
    prob = SeaSpringProblem(study, stage1={})
    x = design_vector(study)
    if prob.solve_st:
        x = np.delete(x, prob.names.index("ST"))
    _, geom, r, _ = prob.solve(x, 1)
    c0, w0 = time.process_time(), time.perf_counter()
    out = prob.solid_3d(geom, r)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    print(out.get("model_3d", out.get("problem")))
    for c in out.get("checks", []):
        print(f"  ST {c['ST_mm']:.10f} mm  {c['solver']:<36s} {c['iterations']:3d} iterations  "
              f"{c['time_s']:6.2f} s wall  K3D/K2D {c['stiffness_ratio_3d_2d']:.10f}  "
              f"peak 3D {c['peak_stress_3d_MPa']:.6f} MPa")  # fmt: skip
    peak_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    print(
        f"3D checks: CPU {cpu:.2f} s, wall {wall:.2f} s, peak RSS {peak_gb:.2f} GB, "
        f"ST after {out.get('ST_after_mm', math.nan):.10f} mm"
    )
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
