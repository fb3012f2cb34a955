"""The constant-force beam's peak stress under mesh refinement: by the elements' curvature (the
solver's sampled stress) and from statics (fea/beam_statics.py, the study's since session 25).

    nice python benchmarks/clamp_stress.py                     # the hybrid design of session 24
    nice python benchmarks/clamp_stress.py --design example    # the example's recorded design
    nice python benchmarks/clamp_stress.py --elements 60 480

For each element count: the largest stress over the rows and sampling points (MPa) and its arc
length (mm), both ways, from one solve of ``pipeline/examples/constant-force.yaml`` with
``geometry.elements`` set (docs/constant_force.md, "Stress at the clamp").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    from flexopt.fea.beam_statics import statics_stress
    from flexopt.geometry.constant_force import WORK_DIRECTION
    from flexopt.pipeline.studies import constant_force as cf
    from flexopt.pipeline.study import load_study

    sys.path.insert(0, str(ROOT / "tests" / "fea"))
    from test_beam_statics import HYBRID_DESIGN

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--design", choices=("hybrid", "example"), default="hybrid")
    parser.add_argument("--elements", nargs="+", type=int, default=[30, 60, 120, 240, 480, 960])
    args = parser.parse_args()
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    base = cf.problem(study)
    x = np.array(HYBRID_DESIGN) if args.design == "hybrid" else base.nominal_design()
    print(f"design: {args.design}; elements, curvature MPa (s mm), statics MPa (s mm)")
    for n in args.elements:
        geometry = study.geometry.model_copy(update={"elements": n})
        prob = cf.problem(study.model_copy(update={"geometry": geometry}))
        model = prob._beam(prob._design(x))
        response = model.solve(prob._drive(study.boundary.stroke_mm, study.boundary.rows))
        st = statics_stress(model, response, np.asarray(WORK_DIRECTION))
        j = int(np.nanargmax(response.peak_stress_MPa))
        k = int(np.nanargmax(st.peak_stress_MPa))
        print(
            f"{n:5d}  {response.peak_stress_MPa[j]:9.4f} ({response.peak_stress_s_mm[j]:6.3f})"
            f"  {st.peak_stress_MPa[k]:9.4f} ({st.peak_stress_s_mm[k]:6.3f})"
        )


if __name__ == "__main__":
    main()
