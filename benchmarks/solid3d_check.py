"""3D solid against plane stress on a sea-spring design (issue 15; quoted in docs/solid3d.md).

Run from the repository root::

    python benchmarks/solid3d_check.py [study] [--layers 2 4 6] [--grading 3]

For the study's ``design:`` (default ``sea-spring``; ST solved from the target, as the run does)
it prints the nonlinear 2D answer of each direction and the 3D check the run's report carries
(``SeaSpringProblem.solid_3d``: linear 3D / linear 2D on the same plane mesh, applied to the
nonlinear 2D answers), then the same linear ratios for each number of layers in ``--layers``
(convergence through the thickness), with DOFs, time and peak memory.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

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
    args = ap.parse_args()

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


if __name__ == "__main__":
    main()
