"""The printed path of a mechanism that bifurcates is judged as the drawn part is: the
imperfect copy the path is solved on keeps its beams' roots (``MechBeam.root_mm``, the flares
of the filleted ends), so the verdict's as-made stress is K_t times the largest stress over
each flare, not the end section's alone (docs/mechanism.md, ``imperfection_mm``: "The
imperfect part is judged as the drawn one").

Reference computed here: each beam's fibre stress at every FE node of the solved rows
(fea.beam_fields.members_field, from the response's shapes and rotations), times the end's
K_t at the nodes within that end's flare as made (geometry.mechanism AsMadeBeam: root_mm,
kt), its largest value over the stable rows.
"""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.beam_fields import Members, members_field
from flexopt.fea.mechanism import first_unstable_row
from flexopt.pipeline.studies.mechanism import MechanismProblem
from flexopt.pipeline.study import load_study


@pytest.fixture(scope="module")
def solved():
    prob = MechanismProblem(load_study("bistable-switch"))
    out = prob.solve(prob.nominal_design())
    assert not isinstance(out, tuple), out
    return out


def test_bistable_switch_printed_path_is_judged_over_the_flares(solved):
    response = solved.responses["snap"]
    made = solved.outline.beams
    # the drawn switch bifurcates: the case is the imperfect part's path
    assert "imperfection" in response.message
    roots = [(b.start.root_mm, b.end.root_mm) for b in made.values()]
    assert any(r > 0 for pair in roots for r in pair)  # filleted ends with a flare
    assert [tuple(r) for r in response.beam_roots_mm] == roots
    rows = first_unstable_row(response) or len(response.drive)
    judged_ref = 0.0
    end_only = 0.0
    for i, beam in enumerate(made.values()):
        m = response.beam_models[i]
        field = members_field(Members((m,), (response.shapes_mm[i],), (response.rotations_rad[i],)))
        sigma = np.asarray(field["equivalent_MPa"], dtype=float)[:rows]  # (rows, nodes) MPa
        s = np.asarray(m.s_nodes, dtype=float)  # (nodes,) mm from the start
        length = float(m.profile.length_mm)
        factor = np.ones_like(s)
        factor[s <= beam.start.root_mm + 1e-9] = max(1.0, beam.start.kt)
        factor[s >= length - beam.end.root_mm - 1e-9] = max(1.0, beam.end.kt)
        judged_ref = max(judged_ref, float(np.nanmax(sigma * factor)))
        # what a copy without its roots was judged by: K_t times the end sections' stress
        ends = np.maximum(sigma[:, 0] * beam.start.kt, sigma[:, -1] * beam.end.kt)
        end_only = max(end_only, float(np.nanmax(np.fmax(sigma.max(axis=1), ends))))
    table = solved.tables["snap"]
    judged = float(np.nanmax(table["peak_stress_MPa"]))
    assert judged == pytest.approx(judged_ref, rel=1e-9)
    # the flare's toe, not the end section, is where this part is judged: > 10 % apart
    assert judged > 1.1 * end_only
