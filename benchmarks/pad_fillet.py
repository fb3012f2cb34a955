"""The constant-force beam with a fillet where it meets each pad: the judged stress and the force.

    nice python benchmarks/pad_fillet.py                        # r = 0 (sharp), 0.5, 1, 2 mm
    nice python benchmarks/pad_fillet.py --radii 0 1 --elements 60 240
    nice python benchmarks/pad_fillet.py --radii 0.5 1 --plane-stress 0.5 0.25 0.125

The example's recorded design (``pipeline/examples/constant-force.yaml``, ``design:``) with its
pads ``pad_thickness_mm`` thick, both ends flared into fillets of radius r
(:func:`geometry.constant_force.filleted_beam`, the mechanism kind's rule: r capped at the
shoulder height (pad - t) / 2) and solved over the study's drive on the study's beam model, the
stress from statics (fea/beam_statics.py). Per radius (r as asked -> as drawn at S1 / S6):

* ``beam peak``: the beam model's peak stress over the drive, MPa (at the flare's toe it is the
  nominal stress there, what the verdict judges today with r = 0);
* ``Kt`` at S1 / S6 (:func:`geometry.mechanism.shoulder_kt`) and ``Kt x root``: Kt times the
  largest beam stress over each flare (s within root_mm of the end), MPa, the larger end;
* ``estimate``: Kt times the sharp beam's nominal stress at the toe's arc length (no flare
  modelled), MPa;
* ``judged``: max(beam peak, Kt x root), MPa, the figure a filleted verdict would judge (with
  the plane-stress check's, which this script does not run);
* the force band: the mean force and the worst |F - target| over the rows from 0.5 mm (N), and
  Eq. 8's RMS error (N).

``--plane-stress EDGE ...``: the study's plane-stress check (fea/fidelity.py
``plane_stress_check``, Newton from the beam's shape) of the filleted outline at the last row
(30 mm) on uniform meshes of those edge lengths (mm): its peak nodal von Mises stress over the
counted elements (MPa; with fillets only the first layer at each pad face is left out), and the
largest over the fillets (0 <= s <= root_mm + 0.25 mm from S1 and from S6, and where), against Kt x
the beam's largest stress over each flare at that row and the beam's largest past the toe in the
same strip.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    from flexopt.fea.beam import BeamModel, BeamSettings
    from flexopt.fea.beam_statics import statics_stress
    from flexopt.geometry.constant_force import WORK_DIRECTION, filleted_beam
    from flexopt.geometry.profile import BeamProfile
    from flexopt.pipeline.studies import constant_force as cf
    from flexopt.pipeline.studies._constant_force_fillet import root_stress_MPa
    from flexopt.pipeline.study import load_study

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--radii", nargs="+", type=float, default=[0.0, 0.5, 1.0, 2.0])
    parser.add_argument("--elements", nargs="+", type=int, default=[60])
    parser.add_argument("--plane-stress", nargs="*", type=float, default=[])
    args = parser.parse_args()
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    prob = cf.problem(study)
    design = prob._design(prob.nominal_design())
    g, t = study.geometry, study.target
    drive = prob._drive(study.boundary.stroke_mm, study.boundary.rows)
    direction = np.asarray(WORK_DIRECTION)

    def solve(r: float, n: int):
        made = filleted_beam(design, prob.frame, g.pad_thickness_mm, g.end_flexures, r)
        profile = BeamProfile(made.shape.points_mm, made.shape.thickness_mm, design.B)
        model = BeamModel(profile, prob.material, "clamped", BeamSettings(n_elements=n))
        response = model.solve(drive)
        if not response.ok:
            raise SystemExit(f"r = {r:g} mm, {n} elements: {response.message}")
        st = statics_stress(model, response, direction)
        return made, model, response, st

    print(
        "r mm (S1/S6 drawn) | elements | beam peak MPa (s mm) | Kt S1/S6 | Kt x root MPa | "
        "estimate MPa | judged MPa | mean F N | worst |F-target| N | RMS N"
    )
    for n in args.elements:
        _, _, _, sharp = solve(0.0, n)
        sharp_sigma = np.nanmax(np.abs(sharp.axial_MPa) + np.abs(sharp.bending_MPa), axis=0)
        length = float(sharp.s_mm[-1])
        for r in args.radii:
            made, model, response, st = solve(r, n)
            root, est = float(np.nanmax(root_stress_MPa(made, st))), 0.0
            for j, end in enumerate((made.start, made.end)):
                if end.root_mm <= 0:
                    continue
                toe = end.root_mm if j == 0 else length - end.root_mm
                est = max(est, end.kt * float(np.interp(toe, sharp.s_mm, sharp_sigma)))
            k = int(np.nanargmax(st.peak_stress_MPa))
            peak = float(st.peak_stress_MPa[k])
            d = np.asarray(response.displacement_mm, dtype=float)
            f = np.asarray(response.force_N, dtype=float)
            worst = float(np.max(np.abs(f[d >= 0.5 - 1e-9] - t.force_N)))
            probes = d[-1] * np.arange(1, t.samples + 1) / t.samples
            rms = float(np.sqrt(np.mean((np.interp(probes, d, f) - t.force_N) ** 2)))
            print(
                f"{r:g} ({made.start.fillet_mm:.3g}/{made.end.fillet_mm:.3g}) | {model.n_elements}"
                f" | {peak:.2f} ({float(st.peak_stress_s_mm[k]):.2f}) | {made.start.kt:.3f}/"
                f"{made.end.kt:.3f} | {root:.2f} | {est:.2f} | {max(peak, root):.2f} | "
                f"{float(np.mean(f[d >= 0.5 - 1e-9])):.4f} | {worst:.4f} | {rms:.5f}"
            )

    if args.plane_stress:
        plane_stress(args, study, prob, design, solve)


def plane_stress(args, study, prob, design, solve) -> None:
    """The filleted outline's plane-stress check at the last row (module docstring)."""
    from flexopt.fea.fidelity import plane_stress_check
    from flexopt.geometry.constant_force import WORK_DIRECTION, outline

    g = study.geometry
    print(
        "r mm | max edge mm | triangles | F plane stress / beam N | peak MPa | "
        "near S1: plane stress (at s mm from S1) / Kt x root / beam beyond the toe MPa | "
        "near S6: the same (s from S6)"
    )
    for r in args.radii:
        made, model, response, st = solve(r, g.elements)
        last = len(response.displacement_mm) - 1
        sigma = np.abs(st.axial_MPa[last]) + np.abs(st.bending_MPa[last])  # (S,) MPa
        s, total = st.s_mm, float(st.s_mm[-1])
        shape = outline(design, prob.frame, g.pad_length_mm, g.pad_thickness_mm, g.end_flexures, r)
        ends = made.shape.points_mm[[0, -1]]
        kt_root = [
            made.start.kt * float(np.max(sigma[s <= made.start.root_mm + 1e-9])),
            made.end.kt * float(np.max(sigma[s >= total - made.end.root_mm - 1e-9])),
        ]
        # the beam's own (nominal) stress past the toe inside the searched strip (s <= root + 0.25)
        # (the sampling points are ~1 mm apart: read it on a fine grid, linear in between)
        beyond = [
            float(np.max(np.interp(np.linspace(a, a + 0.25, 26), s, sigma)))
            for a in (made.start.root_mm, total - made.end.root_mm - 0.25)
        ]
        for edge in args.plane_stress:
            res = plane_stress_check(
                model,
                shape,
                prob.material,
                design.B,
                g.pad_length_mm,
                g.pad_thickness_mm,
                WORK_DIRECTION,
                response,
                np.array([last]),
                float(response.displacement_mm[last]),
                edge,
            )
            if "skipped" in res:
                print(f"{r:g} | {edge:g} | skipped: {res['skipped']}")
                continue
            field = res["field"]
            xy, counted = field["points_mm"], field["stress_counted"]
            vm = np.asarray(field["steps"][0]["von_mises_MPa"], dtype=float)
            near, at = [], []
            pts = made.shape.points_mm
            for e, inward, root in (
                (ends[0], pts[1] - pts[0], made.start.root_mm),
                (ends[1], pts[-2] - pts[-1], made.end.root_mm),
            ):
                along = (xy - e) @ inward / np.linalg.norm(inward)  # (n,) mm from the end
                # the flare and 0.25 mm past its toe (the next vertex, a kink where the taper
                # changes, is 1.36 mm or more from an end: left out)
                mask = counted & (along >= 0) & (along <= root + 0.25)
                mask &= np.linalg.norm(xy - e, axis=1) <= root + 3.0
                k = int(np.flatnonzero(mask)[np.argmax(vm[mask])])
                near.append(float(vm[k]))
                at.append(float(along[k]))
            print(
                f"{r:g} | {edge:g} | {res['mesh']['triangles']} | "
                f"{res['plane_stress_force_N'][0]:.4f} / {res['beam_force_N'][0]:.4f} | "
                f"{res['plane_stress_peak_nodal_von_mises_MPa'][0]:.2f} | "
                f"{near[0]:.2f} (s {at[0]:.3f}) / {kt_root[0]:.2f} / {beyond[0]:.2f} | "
                f"{near[1]:.2f} (s {at[1]:.3f}) / {kt_root[1]:.2f} / {beyond[1]:.2f}"
            )


if __name__ == "__main__":
    main()
