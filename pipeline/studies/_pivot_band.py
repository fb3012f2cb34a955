"""The ``flexure_pivot`` GA's stiffness band judged on the verdict's own figure (issue 27).

The verdict judges a planar pivot's stiffness band on its plane-stress check's linear stiffness
(pipeline/studies/flexure_pivot.py ``FIGURES``) whenever the run makes that check
(``fidelity.plane_stress``, no ``stops:``). The GA used to judge the band on the beam model
(the leaf types) or the closed form (the notches), and a design at the band's edge by one
figure can be outside it by the other: ``flexopt run flexure-pivot`` (seed 1, session 26) chose
a 30 x 2.238 mm leaf at 286.3 N·mm/rad by the beam, 284.3 by plane stress, 0.24 % under the
285-315 band: NOT MET 4 of 5 (docs/flexures.md, "The GA's stiffness band").

So every planar design the GA scores in such a study has its band constraint computed from
:func:`fea.flexure_design.plane_stress_stiffness` (the check's own linear solve and mesh, about
0.05-0.1 s CPU per design against the beam's 0.01 s): the GA's feasible designs are those the
verdict finds in the band. Only a design the beam (closed form) puts more than :data:`DOUBT`
(10 %) outside the band keeps that figure, and is infeasible by it: the plane-stress figure
could only make it feasible, never the reverse, so no design the GA counts feasible has skipped
the verdict's figure. Over the 758 planar designs of the seed-1 run checked both ways, plane
stress / beam (closed form) was 0.94-0.99 for every type (plane stress the softer). The margin
keeps the constraint consistent across the band's edge: without it (solves only inside the band
by the beam) a design just outside by the beam was judged by the beam, so it looked less
violated than one just inside (judged by plane stress, the softer), and the seed-1 run ended on
a 26.0 x 2.163 mm leaf (stress ratio 0.557, 491 solves) instead of 29.79 x 2.235 (0.504, 758).
The beam's (closed form's) figure stays the evaluation's
``stiffness_Nmm_per_rad``; the plane-stress one is its ``plane_stress_stiffness_Nmm_per_rad``.
Where the plane-stress model cannot be built the beam's figure is judged, as the verdict does
when the check is skipped. The stress constraint stays the beam's x Kt (the objective keeps it
far from the allowable in the shipped examples; the verdict judges the plane-stress peak).
"""

from __future__ import annotations

from typing import Any

from flexopt.fea.errors import FeaError
from flexopt.fea.flexure_design import plane_stress_stiffness
from flexopt.geometry.errors import GeometryError

__all__ = ["DOUBT", "KEY", "band_stiffness", "judged_by_plane_stress"]

#: how far outside the band (a fraction of the band's edge) the beam's figure must put a design
#: for the GA to judge it by that figure alone (infeasible); above the largest plane-stress /
#: beam gap measured (6 %, circular notches)
DOUBT = 0.10

#: the evaluation's metric of the plane-stress stiffness, N·mm/rad (the summary's name too)
KEY = "plane_stress_stiffness_Nmm_per_rad"


def judged_by_plane_stress(study: Any, flexure: Any) -> bool:
    """Whether the verdict judges ``flexure``'s stiffness band by plane stress in ``study``: a
    planar pivot in a study with ``fidelity.plane_stress`` and without stops (the detail's
    condition for its plane-stress check)."""
    return bool(study.fidelity.plane_stress and study.stops is None and flexure.is_planar)


def band_stiffness(problem: Any, flexure: Any, beam_Nmm_per_rad: float) -> tuple[float, dict]:
    """The stiffness (N·mm/rad) the GA's band constraint judges for ``flexure`` and the metrics
    to add to its evaluation: the linear plane-stress stiffness where the verdict judges that
    (:func:`judged_by_plane_stress`) and ``beam_Nmm_per_rad`` is within :data:`DOUBT` of the
    band, else
    ``beam_Nmm_per_rad`` (the beam's or closed form's) and no metric.

    Parameters
    ----------
    problem : the FlexurePivotProblem (``study``, ``material``, ``rom_rad`` in rad,
        ``target_Nmm`` in N·mm/rad, ``tolerance`` a fraction).
    flexure : Flexure.
    beam_Nmm_per_rad : float, N·mm/rad — the figure the design was scored on so far.
    """
    study = problem.study
    if not judged_by_plane_stress(study, flexure):
        return beam_Nmm_per_rad, {}
    lo = problem.target_Nmm * (1.0 - problem.tolerance) * (1.0 - DOUBT)
    hi = problem.target_Nmm * (1.0 + problem.tolerance) * (1.0 + DOUBT)
    if not lo <= beam_Nmm_per_rad <= hi:  # infeasible by far: no plane-stress solve
        return beam_Nmm_per_rad, {}
    try:
        K = plane_stress_stiffness(
            flexure, problem.material, problem.rom_rad, study.fidelity.web_elements
        )
    except (FeaError, GeometryError) as exc:  # the verdict then judges the beam's figure too
        return beam_Nmm_per_rad, {"plane_stress_note": f"no plane-stress stiffness: {exc}"}
    return K, {KEY: K}
