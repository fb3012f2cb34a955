"""Where the constant-force part's plane-stress peak sits and how it moves under refinement
(docs/constant_force.md, "The plane-stress peak under refinement").

    nice python benchmarks/cf_kink_convergence.py [--fillet 0.5] [--global 0.5 0.25 0.125]
        [--local 0.25 0.125 0.0625 0.03125] [--radius 1.0]

The shipped example's recorded design, at its last row (30 mm), through the study's own
plane-stress check (``fea.fidelity.plane_stress_check``, Newton from the beam's shape). For each
mesh: the peak nodal von Mises stress, where it sits (arc length s from S1 and the distance to
the nearest centreline vertex), and the peak over the nodes farther than ``--radius`` from every
vertex. ``--global``: the whole outline at that edge; ``--local``: 0.5 mm everywhere and that
edge inside discs of ``--radius`` around the vertices next to the 0.5 mm mesh's peak.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from flexopt.fea.fidelity import plane_stress_check
from flexopt.geometry.constant_force import WORK_DIRECTION, outline
from flexopt.pipeline.studies import constant_force as cf
from flexopt.pipeline.study import load_study
from shapely.geometry import Point

EXAMPLE = Path(__file__).resolve().parents[1] / "pipeline" / "examples" / "constant-force.yaml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fillet", type=float, default=None, help="pad_fillet_mm (default: study's)")
    ap.add_argument("--global", dest="glob", type=float, nargs="*", default=[0.5, 0.25, 0.125])
    ap.add_argument("--local", type=float, nargs="*", default=[])
    ap.add_argument("--radius", type=float, default=1.0)
    ap.add_argument(
        "--blend", type=float, default=None, help="outline's blend_mm (default: the study's)"
    )
    args = ap.parse_args()
    study = load_study(EXAMPLE)
    if args.fillet is not None:
        geo = study.geometry.model_copy(update={"pad_fillet_mm": args.fillet})
        study = study.model_copy(update={"geometry": geo})
    prob = cf.problem(study)
    x = prob.nominal_design()
    design = prob._design(x)
    beam = prob._beam(design)
    _, response, reason = prob._solve(x)
    assert reason == "", reason
    last = len(response.displacement_mm) - 1
    g = study.geometry
    if args.blend is None:
        shape = cf.pads.study_outline(prob, design)
    else:
        shape = outline(
            design, prob.frame, g.pad_length_mm, g.pad_thickness_mm, g.end_flexures,
            g.pad_fillet_mm, args.blend,
        )  # fmt: skip
    verts = beam.profile.points_mm  # (n, 2) mm, the centreline vertices (with the flare's)
    s_vert = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(verts, axis=0), axis=1))])
    stroke = response.displacement_mm[last]
    print(f"blend {args.blend}; pad_fillet_mm {g.pad_fillet_mm:g}; row {last} ({stroke} mm)")
    where = response.peak_stress_s_mm[last]
    print(f"beam peak {response.peak_stress_MPa[last]:.3f} MPa at s {where:.3f} mm")
    print(
        "mesh | triangles | peak MPa | at s mm | to nearest vertex mm (s of it) | "
        "peak away from vertices MPa"
    )

    def run(edge: float, refine, label: str):
        res = plane_stress_check(
            beam, shape, prob.material, design.B, g.pad_length_mm, g.pad_thickness_mm,
            WORK_DIRECTION, response, np.array([last]), float(response.displacement_mm[last]),
            edge, refine,
        )  # fmt: skip
        f = res["field"]
        xy = np.asarray(f["points_mm"], dtype=float)
        counted = np.asarray(f["stress_counted"], dtype=bool)
        vm = np.asarray(f["steps"][0]["von_mises_MPa"], dtype=float)
        k = int(np.flatnonzero(counted)[np.argmax(vm[counted])])
        d = np.linalg.norm(verts[None, :, :] - xy[:, None, :], axis=2)  # (n_nodes, n_verts)
        j = int(np.argmin(d[k]))
        # s of the peak: projection on the nearest vertex's neighbouring segment
        s_peak = s_vert[j] + float(
            (xy[k] - verts[j]) @ (verts[min(j + 1, len(verts) - 1)] - verts[j])
        ) / max(np.linalg.norm(verts[min(j + 1, len(verts) - 1)] - verts[j]), 1e-12)
        away = counted & (d.min(axis=1) > args.radius)
        print(
            f"{label} | {res['mesh']['triangles']} | {vm[k]:.3f} | {s_peak:.2f} | "
            f"{d[k, j]:.3f} (vertex {j}, s {s_vert[j]:.2f}) | {np.max(vm[away]):.3f}"
        )
        return xy[k], j

    peak_xy, j = None, None
    for edge in args.glob:
        peak_xy, j = run(edge, None, f"global {edge:g}")
    if args.local:
        if j is None:
            peak_xy, j = run(0.5, None, "global 0.5")
        discs = Point(verts[j]).buffer(args.radius)
        for edge in args.local:
            run(0.5, [(discs, edge)], f"0.5, {edge:g} within {args.radius:g} mm of vertex {j}")


if __name__ == "__main__":
    main()
