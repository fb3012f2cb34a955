"""The constant-force example's verdict figure against local refinement, per chords of the kink
blend (docs/constant_force.md, "16 chords, not 8").

    nice python benchmarks/cf_blend_chords.py [--chords 8 16 32] [--edges 0.25 0.125 0.0625 0.03125]

For each chord count (``geometry.constant_force.BLEND_CHORDS``, set for this process): the
study's own fidelity check of the example's recorded design (its 4 strokes at 0.5 mm and the
re-solve of its peak row at 0.125 mm within 1 mm: the verdict's figures), then that row solved
again with the mesh refined to each of ``--edges`` within 1 mm of the re-solve's peak: the peak
nodal von Mises stress (MPa), where it sits (mm), the triangles, and the check's CPU time.
"""

from __future__ import annotations

import argparse
import time

import flexopt.geometry.constant_force as geometry
import numpy as np
from flexopt.fea.fidelity import plane_stress_check
from flexopt.geometry.constant_force import WORK_DIRECTION
from flexopt.optimise.curve_objectives import compared_over
from flexopt.pipeline.studies import constant_force as cf
from flexopt.pipeline.study import load_study
from shapely.geometry import Point


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--chords", type=int, nargs="*", default=[8, 16, 32])
    ap.add_argument("--edges", type=float, nargs="*", default=[0.25, 0.125, 0.0625, 0.03125])
    args = ap.parse_args()
    prob = cf.problem(load_study("constant-force"))
    x = prob.nominal_design()
    design, g = prob._design(x), prob.study.geometry
    _, response, reason = prob._solve(x)
    assert reason == "", reason
    lo, hi = compared_over(prob._metrics(design, response), prob.study.boundary.stroke_mm)
    disp = np.asarray(response.displacement_mm)
    for chords in args.chords:
        geometry.BLEND_CHORDS = chords  # read by the outline's blend at each call
        t0 = time.process_time()
        check = cf.fidelity_check(prob, design, response, lo, hi)
        cpu = time.process_time() - t0
        ref = check["refined"]
        peaks = np.round(check["plane_stress_peak_nodal_von_mises_MPa"], 3)
        print(
            f"chords {chords:3d}: check peaks {peaks} MPa, re-solve "
            f"{ref.get('peak_MPa', float('nan')):.3f} MPa at {np.round(ref['at_mm'], 3)} "
            f"({ref.get('triangles')} triangles), check {cpu:.2f} s CPU"
        )
        shape = cf.pads.study_outline(prob, design)
        beam = prob._beam(design)
        row = np.array([int(np.argmin(np.abs(disp - ref["stroke_mm"])))])
        fixed = (beam, shape, prob.material, design.B, g.pad_length_mm, g.pad_thickness_mm)
        for edge in args.edges:
            disc = Point(ref["at_mm"]).buffer(1.0)
            r = plane_stress_check(*fixed, WORK_DIRECTION, response, row, hi, 0.5, [(disc, edge)])
            field = r["field"]
            vm = np.asarray(field["steps"][0]["von_mises_MPa"])
            counted = np.asarray(field["stress_counted"], dtype=bool)
            at = np.asarray(field["points_mm"])[np.flatnonzero(counted)[np.argmax(vm[counted])]]
            peak = r["plane_stress_peak_nodal_von_mises_MPa"][0]
            print(
                f"    {edge:g} mm within 1 mm: {peak:.4f} MPa at {np.round(at, 3)}, "
                f"{r['mesh']['triangles']} triangles"
            )


if __name__ == "__main__":
    main()
