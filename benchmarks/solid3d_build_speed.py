"""Build and first solve of the 3D check's model (fea/solid3d.py), compiled path against numpy.

What the SEA-spring report's first 3D check costs (issue 13): ``Solid3DModel(...)`` on the plane
mesh of a design, then ``model.solve(ST)`` (the first thickness: CHOLMOD's factorisation), with
``Solid3DSettings(assembly="compiled")`` (numba kernels, fea/_solid3d_kernels.py) and
``assembly="numpy"`` (scikit-fem's Basis, the reference). Run from the repository root::

    python benchmarks/solid3d_build_speed.py [study] [--run RUN_FOLDER] [--repeat 3]

The design is the study's ``design:`` (default ``sea-spring``, ST from the target as the run
solves it), or the best design of a finished run folder (``--run``; nothing is written there).
Its plane mesh is made once; each measurement is a fresh process (one BLAS thread, numpy's huge
pages off as in the report, a small plane-stress solve first as the report's process has made,
the 3D kernels loaded from numba's cache) that builds the model and solves the first
thickness; the two paths alternate, ``--repeat`` times each, and the medians are printed: wall
and CPU time of the build, of the first solve, of CHOLMOD's symbolic and numeric factorisation
(timed by wrapping cvxopt.cholmod) and of everything else, peak memory, and the answers of both
paths (stiffness, peaks) with their relative difference. The load average before and after is
printed: on a shared machine the times move with it.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]


def make_case(study_name: str, run: str | None) -> dict:
    """The plane mesh, supports and ST of the design, as the report's 3D check makes them."""
    import numpy as np
    from flexopt.fea.mesh import mesh_polygon
    from flexopt.fea.plane_stress import Clamp, Rotate
    from flexopt.pipeline.studies.sea_spring import SeaSpringProblem, design_vector
    from flexopt.pipeline.study import load_study

    if run is not None:
        study = load_study(str(Path(run) / "study.yaml"))
        prob = SeaSpringProblem(study)
        x = np.asarray(json.loads((Path(run) / "best.json").read_text())["x"], dtype=float)
        _, (_, geom, _, st) = prob._evaluate(x, study.mesh.curve_steps, keep_model=True)
    else:
        study = load_study(study_name)
        prob = SeaSpringProblem(study, stage1={})
        x = design_vector(study)
        if prob.solve_st:
            x = np.delete(x, prob.names.index("ST"))
        _, geom, _, st = prob.solve(x, 1)
    spec = study.mesh
    regions = geom.mesh_regions(spec.elements_through, spec.max_edge_mm)
    return {
        "mesh": mesh_polygon(geom.fe_outline, spec.max_edge_mm, refine=regions),
        "material": prob.material,
        "clamp": Clamp(geom.pad_region),
        "drive": Rotate(geom.hub_region, (0.0, 0.0), prob.theta, 1),
        "layers": study.solid_3d.layers,
        "ignore": geom.hub_region.union(geom.pad_region).buffer(0.05),
        "st_mm": float(st),
    }


def child(case_file: str, assembly: str) -> None:
    """One measurement: build and first solve, printed as one JSON line."""
    import cvxopt.cholmod as cholmod
    import skfem.quadrature  # noqa: F401
    from flexopt.fea.mesh import mesh_polygon
    from flexopt.fea.plane_stress import Clamp, Translate, solve_plane_stress
    from flexopt.fea.solid3d import Solid3DModel, Solid3DSettings
    from flexopt.pipeline._hugepages import without_numpy_hugepages
    from shapely.geometry import LineString, box

    case = pickle.loads(Path(case_file).read_bytes())
    # The report's process has solved plane stress (numba, scikit-fem and cvxopt loaded and
    # used) before its first 3D check: a small plane-stress solve does that here. The 3D
    # kernels are loaded from numba's cache inside the measurement, as there.
    solve_plane_stress(mesh_polygon(box(0.0, 0.0, 10.0, 2.0), 1.0), case["material"], 2.0,
                       Clamp(LineString([(0.0, 0.0), (0.0, 2.0)])),
                       Translate(LineString([(10.0, 0.0), (10.0, 2.0)]), (0.0, 1.0), 0.1, 1),
                       "linear")  # fmt: skip
    spent = {"wall": 0.0, "cpu": 0.0, "solve_wall": 0.0}

    def timed(f, key):
        def g(*a, **k):
            w, c = time.perf_counter(), time.process_time()
            try:
                return f(*a, **k)
            finally:
                spent[key] += time.perf_counter() - w
                if key == "wall":
                    spent["cpu"] += time.process_time() - c

        return g

    cholmod.symbolic = timed(cholmod.symbolic, "wall")
    cholmod.numeric = timed(cholmod.numeric, "wall")
    cholmod.solve = timed(cholmod.solve, "solve_wall")
    with without_numpy_hugepages():
        w0, c0 = time.perf_counter(), time.process_time()
        model = Solid3DModel(case["mesh"], case["material"], case["clamp"], case["drive"],
                             Solid3DSettings(layers=case["layers"], assembly=assembly),
                             stress_ignore=case["ignore"])  # fmt: skip
        w1, c1 = time.perf_counter(), time.process_time()
        r = model.solve(case["st_mm"])
        w2, c2 = time.perf_counter(), time.process_time()
    print(json.dumps({
        "assembly": model.assembly,
        "build_wall": w1 - w0, "build_cpu": c1 - c0,
        "solve_wall": w2 - w1, "solve_cpu": c2 - c1,
        "cholmod_wall": spent["wall"], "cholmod_cpu": spent["cpu"],
        "rest_wall": w2 - w0 - spent["wall"], "rest_cpu": c2 - c0 - spent["cpu"],
        "cholmod_solve_wall": spent["solve_wall"],
        "peak_rss_GB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
        "n_dofs": r.n_dofs, "stiffness": r.stiffness, "peak_stress_MPa": r.peak_stress_MPa,
        "peak_nodal_stress_MPa": r.peak_nodal_stress_MPa, "solver": r.solver,
    }))  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study", nargs="?", default="sea-spring")
    ap.add_argument("--run", help="a finished run folder: its best design (read only)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--child", nargs=2, metavar=("CASE", "ASSEMBLY"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    t0 = time.perf_counter()
    case = make_case(args.study, args.run)
    print(f"{args.run or args.study}: ST = {case['st_mm']:.4f} mm, plane mesh "
          f"{case['mesh'].n_points} points, {case['layers']} layers "
          f"({time.perf_counter() - t0:.1f} s)")  # fmt: skip
    rows: dict[str, list[dict]] = {"numpy": [], "compiled": []}
    with tempfile.TemporaryDirectory() as tmp:
        case_file = Path(tmp) / "case.pkl"
        case_file.write_bytes(pickle.dumps(case))
        load0 = os.getloadavg()
        for k in range(args.repeat):
            order = ("numpy", "compiled") if k % 2 == 0 else ("compiled", "numpy")
            for assembly in order:
                out = subprocess.run(
                    [sys.executable, __file__, "--child", str(case_file), assembly],
                    check=True, capture_output=True, text=True, cwd=ROOT,
                ).stdout  # fmt: skip
                rows[assembly].append(json.loads(out.strip().splitlines()[-1]))
        load1 = os.getloadavg()
    print(f"load average before {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, "
          f"after {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f} (2 cores)")  # fmt: skip
    print(f"medians of {args.repeat} fresh processes each, one BLAS thread, seconds (wall / CPU):")
    keys = ("build", "solve", "cholmod", "rest")
    print(f"{'assembly':10s}" + "".join(f"{k:>16s}" for k in keys) + "   peak GB")
    for name, rs in rows.items():
        cells = "".join(
            f"{statistics.median(r[k + '_wall'] for r in rs):8.2f} /"
            f"{statistics.median(r[k + '_cpu'] for r in rs):6.2f}"
            for k in keys
        )
        print(f"{name:10s}{cells}   {statistics.median(r['peak_rss_GB'] for r in rs):.2f}")
    a, b = rows["compiled"][0], rows["numpy"][0]
    print("(build: mesh, tables, supports, pattern and parts; solve: the first thickness; "
          "cholmod: its symbolic + numeric factorisation; rest: build + solve - cholmod, of "
          "which CHOLMOD's triangular solve "
          + " / ".join(f"{statistics.median(r['cholmod_solve_wall'] for r in rs):.2f}"
                       for rs in rows.values())
          + " s wall)")  # fmt: skip
    for key in ("stiffness", "peak_stress_MPa", "peak_nodal_stress_MPa"):
        print(f"{key}: compiled {a[key]:.10g}, numpy {b[key]:.10g}, "
              f"relative difference {abs(a[key] / b[key] - 1):.1e}")  # fmt: skip
    print(f"DOFs {a['n_dofs']}, solver {a['solver']}")


if __name__ == "__main__":
    main()
