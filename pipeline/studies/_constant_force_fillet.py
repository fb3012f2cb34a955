"""The constant-force beam's pad fillets in the study: the beam and outline with the
``geometry.pad_fillet_mm`` fillets, and the stress at them (docs/constant_force.md, "Fillets at
the pads").

Why: with fillets drawn (:func:`geometry.constant_force.filleted_beam`) the beam model carries
the flare as a thickening beam, whose stress at the fillet's toe is the nominal stress of the
shoulder; the concentration on the arc is the fit's Kt times it (as the mechanism kind's roots,
fea/mechanism_design.py ``as_made_stress``). :func:`with_root_stress` folds that into the
response's ``peak_stress_MPa``, so the GA's stress constraint and the verdict see it.
``pad_fillet_mm = 0`` is the sharp step: the beam of
:func:`geometry.constant_force.beam_profile`, the stress from statics; its stress at the corners
is not bounded by any figure of the study, so the peak-stress row is NOT MET (:class:`PadStress`).
The default is :data:`DEFAULT_PAD_FILLET_MM`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from flexopt.fea.beam import BeamModel, BeamResponse, BeamSettings
from flexopt.fea.beam_statics import StaticsStress, statics_stress, with_statics_stress
from flexopt.geometry.constant_force import (
    WORK_DIRECTION,
    beam_profile,
    centreline_points,
    filleted_beam,
    outline,
)
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.mechanism import AsMadeBeam
from flexopt.geometry.profile import BeamProfile
from flexopt.optimise.requirements import AllowableStress, Verdict

__all__ = [
    "DEFAULT_PAD_FILLET_MM",
    "KINK_BLEND_MM",
    "SHARP_PADS",
    "SHARP_PADS_REASON",
    "TOE_CLEAR_MM",
    "PadStress",
    "beam_model",
    "made_beam",
    "pad_stress",
    "root_stress_MPa",
    "study_outline",
    "with_root_stress",
]

#: mm: the blend along each edge at a design vertex of the part as exported (capped at a quarter
#: of the shorter adjacent segment; why blended: pipeline/studies/_constant_force_kinks.py).
#: Why 1 mm: it moves the outline by 2.6 um at the shipped design's peak vertex (a 0.59 deg kink
#: per side), far under a printer's tolerance, and is drawn by chords of 0.25 mm, which the
#: study's 0.5 mm mesh keeps as nodes.
KINK_BLEND_MM = 1.0

#: mm: a fillet's toe must land at least this far from the first design point (p1 from S1, p10
#: from S6). Why: a toe on a vertex is a corner the Kt fit does not describe; at the shipped
#: design's capped S6 fillet (toe 3 um from p10) plane stress read 34.2 MPa against Kt x root
#: 31.1 MPa (benchmarks/pad_fillet.py, docs/constant_force.md).
TOE_CLEAR_MM = 0.1


#: mm: the fillet a study without ``geometry.pad_fillet_mm`` draws. Why 0.5 mm (measured on the
#: shipped design, docs/constant_force.md "Fillets at the pads"): it is printable (about a 0.4 mm
#: nozzle's line), its Kt (1.32 / 1.30) is the fit's, the plane-stress check at its toe stays
#: under Kt x root on every mesh measured (0.5 / 0.25 / 0.125 mm), it stiffens the clamp by only
#: 0.2 % in mean force, and its toe never lands near p1 / p10 in the design space (the end
#: segments are >= 1.35 mm, TOE_CLEAR_MM below). 0.2 mm is not resolved by the plane-stress mesh
#: and 1 mm raises Eq. 8's RMS error by 75 % on the shipped design.
DEFAULT_PAD_FILLET_MM = 0.5

#: The peak-stress row's bound on a study with ``geometry.pad_fillet_mm: 0``: the part meets its
#: pads in sharp corners.
SHARP_PADS = "pad corners sharp: geometry.pad_fillet_mm = 0"

#: Why that row is NOT MET (its detail): the corner's stress is outside every figure of the run.
SHARP_PADS_REASON = (
    "NOT MET whatever the figure: the part meets its pads in sharp 90 degree corners "
    "(geometry.pad_fillet_mm = 0), where the stress is singular in elasticity and no figure of "
    "this study bounds it (the beam's and the plane-stress check's are nominal there); set "
    f"geometry.pad_fillet_mm > 0 (default {DEFAULT_PAD_FILLET_MM:g} mm)"
)


@dataclass(frozen=True)
class PadStress(AllowableStress):
    """The constant-force kind's allowable stress. With ``sharp`` (``pad_fillet_mm = 0``) the
    verdict is NOT MET with :data:`SHARP_PADS_REASON` as its detail, and its bound says why
    (:data:`SHARP_PADS`). Why NOT MET and not a refusal: the standard judges MET only on what
    the model sees, but a user may still trace a sharp part and read its nominal figures. Its
    margin (and so the optimiser's constraint row) stays the nominal one: the GA of a sharp
    study still holds the nominal stress, only the verdict refuses to call it met."""

    sharp: bool = False

    def bound_text(self) -> str:
        text = super().bound_text()
        return f"{text} ({SHARP_PADS})" if self.sharp else text

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        v = super().check(metrics, curves)
        if not self.sharp:
            return v
        detail = SHARP_PADS_REASON + (f"; {v.detail}" if v.detail else "")
        return replace(v, met=False, detail=detail)


def pad_stress(study: Any, allowable_MPa: float) -> PadStress:
    """The ``peak stress`` requirement of a constant-force ``study`` (MPa)."""
    sharp = not study.geometry.pad_fillet_mm > 0
    return PadStress("peak_stress_MPa", "peak stress", "constraint", allowable_MPa, sharp=sharp)


def made_beam(problem: Any, design: Any) -> AsMadeBeam:
    """The study's beam as made, with ``geometry.pad_fillet_mm`` fillets at both pads.

    Raises
    ------
    GeometryError
        When a fillet's toe lands within :data:`TOE_CLEAR_MM` of p1 / p10 (named, with the
        distance), or the fillet is not buildable.
    """
    g = problem.study.geometry
    made = filleted_beam(design, problem.frame, g.pad_thickness_mm, g.end_flexures, g.pad_fillet_mm)
    pts = centreline_points(design, problem.frame, g.end_flexures)
    for end, a, b, name in ((made.start, 0, 1, "S1 and p1"), (made.end, -1, -2, "S6 and p10")):
        seg = float(np.linalg.norm(pts[a] - pts[b]))
        if end.root_mm > 0 and abs(end.root_mm - seg) < TOE_CLEAR_MM:
            raise GeometryError(
                f"the pad fillet of r = {end.root_mm:.3g} mm ends {abs(end.root_mm - seg):.3g} mm "
                f"from the design point between {name} ({seg:.3g} mm apart), closer than "
                f"{TOE_CLEAR_MM:g} mm: a corner the fillet's Kt does not describe; change "
                "geometry.pad_fillet_mm"
            )
    return made


def beam_model(problem: Any, design: Any) -> BeamModel:
    """The beam model of ``design``: the flared beam of :func:`made_beam`, or with
    ``pad_fillet_mm = 0`` the sharp beam of ``beam_profile`` (the study's before the key)."""
    g = problem.study.geometry
    settings = BeamSettings(n_elements=g.elements)
    if g.pad_fillet_mm > 0:
        shape = made_beam(problem, design).shape
        profile = BeamProfile(shape.points_mm, shape.thickness_mm, design.B)
    else:
        profile = beam_profile(design, problem.frame, g.end_flexures)
    return BeamModel(profile, problem.material, "clamped", settings)


def study_outline(problem: Any, design: Any) -> Any:
    """The part's outline (a shapely Polygon, mm) as exported: pads and the fillets drawn, the
    design vertices' kinks blended along :data:`KINK_BLEND_MM` (:mod:`._constant_force_kinks`:
    a mitred kink is a corner whose stress the plane-stress check cannot converge on)."""
    g = problem.study.geometry
    return outline(
        design,
        problem.frame,
        g.pad_length_mm,
        g.pad_thickness_mm,
        g.end_flexures,
        g.pad_fillet_mm,
        KINK_BLEND_MM,
    )


def _end_stress(made: AsMadeBeam, stress: StaticsStress) -> list[np.ndarray]:
    """Per end (S1, S6): (R,) MPa, Kt times the largest ``|axial| + |bending|`` over its flare;
    0 where the end has no fillet."""
    sigma = np.abs(stress.axial_MPa) + np.abs(stress.bending_MPa)
    s = np.asarray(stress.s_mm, dtype=float)
    total = float(s[-1])
    out = []
    # 1e-9 mm: the toe is a node (a sampling point) of the flared beam
    for end, near in (
        (made.start, s <= made.start.root_mm + 1e-9),
        (made.end, s >= total - made.end.root_mm - 1e-9),
    ):
        if end.root_mm > 0:
            out.append(end.kt * np.max(sigma[:, near], axis=1))
        else:
            out.append(np.zeros(sigma.shape[0]))
    return out


def root_stress_MPa(made: AsMadeBeam, stress: StaticsStress) -> np.ndarray:
    """(R,) MPa: per row, the larger over the two ends of Kt times the largest ``|axial| +
    |bending|`` (``stress``: (R, S) MPa at arc lengths ``s_mm`` (S,) mm) over that end's flare
    (``s <= root_mm`` from S1, ``s >= L - root_mm`` from S6); 0 where an end has no fillet.
    ``made`` is the beam ``stress`` was computed on (its ``start`` / ``end`` junctions)."""
    a, b = _end_stress(made, stress)
    return np.fmax(a, b)


def with_root_stress(
    problem: Any, design: Any, model: BeamModel, response: BeamResponse
) -> BeamResponse:
    """``response`` with its ``peak_stress_MPa`` / ``peak_stress_s_mm`` (R,) MPa / mm from
    statics, and with fillets the larger of that and :func:`root_stress_MPa` (at s = 0 or the
    beam's length, the end where Kt x root is larger). Without a fillet:
    :func:`fea.beam_statics.with_statics_stress`, unchanged."""
    if problem.study.geometry.pad_fillet_mm <= 0 or response.rotations_rad is None:
        return with_statics_stress(model, response, WORK_DIRECTION)
    made = made_beam(problem, design)
    st = statics_stress(model, response, np.asarray(WORK_DIRECTION))
    ok = np.isfinite(st.peak_stress_MPa)
    peak = np.where(ok, st.peak_stress_MPa, response.peak_stress_MPa)
    where = np.where(ok, st.peak_stress_s_mm, response.peak_stress_s_mm)
    a, b = _end_stress(made, st)
    root = np.fmax(a, b)
    wins = ok & (root > peak)
    at_end = np.where(a >= b, 0.0, float(st.s_mm[-1]))
    return replace(
        response,
        peak_stress_MPa=np.where(wins, root, peak),
        peak_stress_s_mm=np.where(wins, at_end, where),
    )
