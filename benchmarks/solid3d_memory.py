"""Peak memory of the SEA spring's 3D check (fea/solid3d.py; issue 27 item 5).

What the report's 3D check holds at its peak: ``Solid3DModel(...)`` on the design's plane mesh,
``model.solve(ST)`` (the first thickness: CHOLMOD's, or QDLDL's, factorisation) and a re-check
at 0.98 ST (PCG preconditioned with that factor; with ``solver = "multigrid"`` both by
multigrid-preconditioned CG, no factor), as ``SeaSpringProblem.solid_3d`` makes them.
Run from the repository root::

    python benchmarks/solid3d_memory.py [study] [--run RUN_FOLDER] [--repeat 3]
        [--solvers multigrid cholmod] [--models today] [--keep] [--stages]

The design is the study's ``design:`` (default ``sea-spring``, ST from the target as the run
solves it) or the best design of a finished run folder (``--run``; nothing is written there).
Each measurement is a fresh process (one BLAS thread, numpy's huge pages off as in the report)
with each ``--solvers`` entry as ``Solid3DSettings.solver``, ``lean_factorisation`` True (the
default: the parts and the reduced triangle's pattern dropped while the factor is made or the
multigrid solver runs, made again after; ``--keep``: False); the solvers alternate, ``--repeat``
times each. Printed: medians of the peak RSS (``ru_maxrss``) of the process, wall and CPU time
of the build, first solve and re-check, each solver's answers with their relative difference
to the last solver's, and the load average before and after (the times move with it on a
shared machine). ``--stages``: instead, one process per solver printing the resident set after
each stage of the check and its peak during it (Linux's /proc/self/status, the peak reset
between stages).

``--models`` (each measured with each solver): ``today`` the whole part on Triangle's mesh of
the whole outline (the check before the sector, and the default here so that the commands
of docs/solid3d.md's earlier tables measure what they did); ``sector`` one sector of the
periodic mesh (fea/solid3d_sector.py: what the report's check solves now where the part
repeats); ``whole`` the whole part on that same periodic mesh (the sector's reference: the
same answers to round-off). The answers are compared with the last row's.
``--mesh-table [DEG ...]``: instead, in one process, the 3D/2D ratios the check applies
(``compare_with_plane_stress`` at the case's ST) on Triangle's mesh of the outline, on
Triangle's mesh of the outline turned by 360/n degrees and turned back (another mesh of the
same size), on the periodic mesh the check solves (its sector) and on periodic meshes cut
at the angles DEG (degrees; each must cross the outline alike on both cuts): the meshes'
own spread (docs/solid3d.md, "The sector solve").
"""

from __future__ import annotations

import argparse
import importlib.util
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


def _make_case(study: str, run: str | None) -> dict:
    """The plane mesh, supports and ST (benchmarks/solid3d_build_speed.py's ``make_case``),
    and the periodic mesh of the sector the report's check solves (``periodic``: as
    fea/sea_design.correct_3d makes it; None, with ``model_3d`` saying why, where it solves
    the whole)."""
    spec = importlib.util.spec_from_file_location(
        "solid3d_build_speed", Path(__file__).with_name("solid3d_build_speed.py")
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    # make_case builds the design's geometry; its outline and regions are read here through
    # the same study (one more build of the design, a fraction of a second)
    case = mod.make_case(study, run)
    from flexopt.fea.solid3d_sector import sector_or_reason
    from flexopt.pipeline.studies.sea_spring import SeaSpringProblem, design_vector
    from flexopt.pipeline.study import load_study

    if run is not None:
        st = load_study(str(Path(run) / "study.yaml"))
        prob = SeaSpringProblem(st)
        x = json.loads((Path(run) / "best.json").read_text())["x"]
        _, (_, geom, _, _) = prob._evaluate(x, st.mesh.curve_steps, keep_model=True)
    else:
        import numpy as np

        st = load_study(study)
        prob = SeaSpringProblem(st, stage1={})
        x = design_vector(st)
        if prob.solve_st:
            x = np.delete(x, prob.names.index("ST"))
        _, geom, _, _ = prob.solve(x, 1)
    regions = geom.mesh_regions(st.mesh.elements_through, st.mesh.max_edge_mm)
    repeat = {"hub": geom.hub_region, "pads": geom.pad_region, "stress-ignore": case["ignore"]}
    pm, why = sector_or_reason(geom.fe_outline, geom.params.n_sets, st.mesh.max_edge_mm,
                               regions, repeat, "cholmod")  # fmt: skip
    return {**case, "periodic": pm, "model_3d": why, "outline": geom.fe_outline,
            "regions": regions, "max_edge_mm": st.mesh.max_edge_mm}  # fmt: skip


def child(case_file: str, lean: str, solver: str, model_kind: str = "today") -> None:
    """One measurement, printed as one JSON line."""
    from flexopt.fea.solid3d import Solid3DModel, Solid3DSettings
    from flexopt.pipeline._hugepages import without_numpy_hugepages

    case = pickle.loads(Path(case_file).read_bytes())
    settings = Solid3DSettings(layers=case["layers"], lean_factorisation=lean == "lean",
                               solver=solver)  # fmt: skip
    pm = case.get("periodic")
    if model_kind != "today" and pm is None:
        raise SystemExit(f"no periodic mesh: {case.get('model_3d')}")
    mesh = {"today": case["mesh"], "sector": pm and pm.sector, "whole": pm and pm.whole}[model_kind]
    periodic = pm if model_kind == "sector" else None
    marks = [(time.perf_counter(), time.process_time())]
    with without_numpy_hugepages():
        model = Solid3DModel(mesh, case["material"], case["clamp"], case["drive"],
                             settings, stress_ignore=case["ignore"],
                             periodic=periodic)  # fmt: skip
        marks.append((time.perf_counter(), time.process_time()))
        r = model.solve(case["st_mm"])
        marks.append((time.perf_counter(), time.process_time()))
        r2 = model.solve(0.98 * case["st_mm"])
        marks.append((time.perf_counter(), time.process_time()))
    out = {
        "mode": lean,
        "model": model_kind,
        "peak_rss_GB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
    }
    for k, name in enumerate(("build", "solve", "recheck")):
        out[name + "_wall"] = marks[k + 1][0] - marks[k][0]
        out[name + "_cpu"] = marks[k + 1][1] - marks[k][1]
    out.update(n_dofs=r.n_dofs, solver=r.solver, stiffness=r.stiffness,
               peak_stress_MPa=r.peak_stress_MPa, peak_nodal_stress_MPa=r.peak_nodal_stress_MPa,
               recheck_stiffness=r2.stiffness, recheck_peak_nodal_MPa=r2.peak_nodal_stress_MPa,
               recheck_iterations=r2.iterations)  # fmt: skip
    print(json.dumps(out))


def _status_GB() -> tuple[float, float]:
    """(resident, peak resident since the last reset) of this process, GB (kB / 2^20)."""
    d = {}
    for line in Path("/proc/self/status").read_text().splitlines():
        k, _, v = line.partition(":")
        if k in ("VmRSS", "VmHWM"):
            d[k] = int(v.split()[0]) / 2**20
    return d["VmRSS"], d["VmHWM"]


def _mark(name: str) -> None:
    """Print the resident set and its peak since the last mark, then reset the peak (Linux:
    writing 5 to /proc/self/clear_refs)."""
    rss, peak = _status_GB()
    print(f"  {name:58s} {rss:5.2f} / {peak:5.2f} GB", flush=True)
    Path("/proc/self/clear_refs").write_text("5")


def child_stages(case_file: str, solver: str) -> None:
    """The resident set after each stage of the check and its peak during the stage."""
    import flexopt.fea.solid3d as s3
    from flexopt.pipeline._hugepages import without_numpy_hugepages

    case = pickle.loads(Path(case_file).read_bytes())
    model_cls = s3.Solid3DModel
    inner = model_cls._solve_multigrid

    def marked(self, *args, **kwargs):  # the multigrid solve between two marks
        _mark("K(t) formed, its values gathered, K (and the parts) let go")
        out = inner(self, *args, **kwargs)
        _mark("multigrid: whole matrix, P1 factor, CG")
        return out

    model_cls._solve_multigrid = marked
    print(f"{solver}: stage, resident / peak during the stage")
    _mark("start (interpreter, libraries, case)")
    with without_numpy_hugepages():
        model = model_cls(case["mesh"], case["material"], case["clamp"], case["drive"],
                          s3.Solid3DSettings(layers=case["layers"], solver=solver),
                          stress_ignore=case["ignore"])  # fmt: skip
        _mark("model built (mesh, P2 tables, pattern, parts, lower triangle)")
        r = model.solve(case["st_mm"])
        _mark("first thickness: (parts made again,) reactions, stress")
        model.solve(0.98 * case["st_mm"])
        _mark("re-check at 0.98 ST: (parts made again,) reactions, stress")
    print(f"  {r.solver}, {r.iterations} iterations, stiffness {r.stiffness:.6f} N·mm/rad")


def mesh_table(case_file: str, angles: list[float]) -> None:
    """The ratios of the check on several plane meshes of the same size (see above)."""
    import math

    import numpy as np
    from flexopt.fea.mesh import TriMesh, mesh_polygon
    from flexopt.fea.solid3d import Solid3DModel, Solid3DSettings
    from flexopt.fea.solid3d_sector import periodic_mesh, rotation_matrix
    from flexopt.pipeline._hugepages import without_numpy_hugepages
    from shapely import affinity

    case = pickle.loads(Path(case_file).read_bytes())
    pm = case["periodic"]
    if pm is None:
        raise SystemExit(f"no periodic mesh: {case['model_3d']}")
    outline, regions, edge = case["outline"], case["regions"], case["max_edge_mm"]
    deg = 360.0 / pm.n
    turned = mesh_polygon(affinity.rotate(outline, deg, origin=(0, 0)), edge,
                          refine=[(affinity.rotate(g, deg, origin=(0, 0)), h)
                                  for g, h in regions])  # fmt: skip
    back = TriMesh(turned.points @ rotation_matrix(-math.radians(deg)).T, turned.triangles)
    rows = [("Triangle's, whole outline", case["mesh"], None),
            (f"Triangle's, outline turned {deg:g} deg and back", back, None),
            (f"periodic, cut at {math.degrees(pm.angle0_rad):.4g} deg (the check's)",
             pm.sector, pm)]  # fmt: skip
    for a in angles:
        p = periodic_mesh(outline, pm.n, edge, refine=regions, angle0_rad=math.radians(a))
        rows.append((f"periodic, cut at {a:g} deg", p.sector, p))
    settings = Solid3DSettings(layers=case["layers"])
    print("plane mesh | plane nodes | stiffness ratio 3D/2D | peak ratio 3D/2D | 3D vertex peak "
          "MPa | where (x, y) mm | each arm's copy of the peak region (3 mm) MPa")  # fmt: skip
    for name, mesh, p in rows:
        with without_numpy_hugepages():
            model = Solid3DModel(mesh, case["material"], case["clamp"], case["drive"], settings,
                                 stress_ignore=case["ignore"], periodic=p)  # fmt: skip
            c = model.compare_with_plane_stress(case["st_mm"])
            f = model.last_field(case["st_mm"])  # the whole part (a sector's turned copies)
        nodes = (p.whole if p is not None else mesh).n_points
        x, y = (float(v) for v in c["solid3d"]["peak_nodal_stress_xyz_mm"][:2])
        pts, vm, counted = f["points_mm"][:, :2], f["von_mises_MPa"], f["stress_counted"]
        copies = []
        for j in range(pm.n):  # the judged vertex values near each arm's copy of the peak
            q = np.array([x, y]) @ rotation_matrix(j * math.radians(deg)).T
            near = counted & (np.linalg.norm(pts - q, axis=1) < 3.0)
            copies.append(f"{vm[near].max():.3f}")
        print(f"{name} | {nodes} | {c['stiffness_ratio']:.8f} | {c['peak_stress_ratio']:.6f} | "
              f"{c['peak_nodal_stress_3d_MPa']:.3f} | ({x:.2f}, {y:.2f}) | {' / '.join(copies)}",
              flush=True)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study", nargs="?", default="sea-spring")
    ap.add_argument("--run", help="a finished run folder: its best design (read only)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--solvers", nargs="+", default=["multigrid", "cholmod"],
                    choices=("auto", "cholmod", "qdldl", "multigrid"),
                    help="Solid3DSettings.solver of each; the last is the reference")  # fmt: skip
    ap.add_argument("--models", nargs="+", default=["today"],
                    choices=("today", "sector", "whole"),
                    help="the plane mesh and model of each (see above)")  # fmt: skip
    ap.add_argument("--keep", action="store_true",
                    help="lean_factorisation False (the arrays kept throughout)")  # fmt: skip
    ap.add_argument("--stages", action="store_true",
                    help="instead: the memory stage by stage, a process per solver")  # fmt: skip
    ap.add_argument("--mesh-table", nargs="*", type=float, metavar="DEG",
                    help="instead: the ratios on several meshes (see above)")  # fmt: skip
    ap.add_argument("--case", help=argparse.SUPPRESS)  # a pickled case (re-use between runs)
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    ap.add_argument("--child-stages", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    if args.child_stages:
        child_stages(*args.child_stages)
        return
    lean = "keep" if args.keep else "lean"
    with tempfile.TemporaryDirectory() as tmp:
        if args.case:
            case_file = Path(args.case)
        else:
            t0 = time.perf_counter()
            case = _make_case(args.study, args.run)
            case_file = Path(tmp) / "case.pkl"
            case_file.write_bytes(pickle.dumps(case))
            print(f"{args.run or args.study}: ST = {case['st_mm']:.4f} mm "
                  f"({time.perf_counter() - t0:.1f} s)")  # fmt: skip
        if args.mesh_table is not None:
            mesh_table(str(case_file), args.mesh_table)
            return
        if args.stages:
            for solver in args.solvers:
                subprocess.run([sys.executable, __file__, "--child-stages", str(case_file),
                                solver], check=True, cwd=ROOT)  # fmt: skip
            return
        combos = [(m, s) for m in args.models for s in args.solvers]
        rows: dict[str, list[dict]] = {f"{m}/{s}": [] for m, s in combos}
        load0 = os.getloadavg()
        for k in range(args.repeat):
            # the order alternates, so a load that changes with time favours neither
            for m, solver in combos if k % 2 == 0 else combos[::-1]:
                out = subprocess.run(
                    [sys.executable, __file__, "--child", str(case_file), lean, solver, m],
                    check=True, capture_output=True, text=True, cwd=ROOT,
                ).stdout  # fmt: skip
                rows[f"{m}/{solver}"].append(json.loads(out.strip().splitlines()[-1]))
        load1 = os.getloadavg()
    print(f"load average before {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, "
          f"after {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f} (2 cores)")  # fmt: skip
    print(f"medians of {args.repeat} fresh processes each ({lean}), one BLAS thread, "
          "s (wall / CPU):")  # fmt: skip
    keys = ("build", "solve", "recheck")
    print(f"{'model/solver':18s}" + "".join(f"{k:>16s}" for k in keys) + "   peak RSS GB")
    for solver, rs in rows.items():
        cells = "".join(
            f"{statistics.median(r[k + '_wall'] for r in rs):8.2f} /"
            f"{statistics.median(r[k + '_cpu'] for r in rs):6.2f}"
            for k in keys
        )
        peaks = sorted(r["peak_rss_GB"] for r in rs)
        print(f"{solver:18s}{cells}   {statistics.median(peaks):.2f} "
              f"({' '.join(f'{p:.2f}' for p in peaks)})")  # fmt: skip
    last = list(rows)[-1]
    ref = rows[last][0]
    for solver, rs in rows.items():
        a = rs[0]
        print(f"{solver}: {a['solver']}, DOFs {a['n_dofs']}, re-check iterations "
              f"{a['recheck_iterations']}")  # fmt: skip
        for key in ("stiffness", "peak_stress_MPa", "peak_nodal_stress_MPa",
                    "recheck_stiffness", "recheck_peak_nodal_MPa"):  # fmt: skip
            print(f"  {key}: {a[key]:.12g} (against {last}: "
                  f"{abs(a[key] / ref[key] - 1):.1e})")  # fmt: skip


if __name__ == "__main__":
    main()
