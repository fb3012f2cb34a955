"""The ``mechanism`` kind's answer for one solved design, as the pipeline shows it: the solve's
record (:class:`Solved`), the plot spec of a load case with its target band, every load case's
response, the design's info for the report and its files (deformed_shapes.png, one CSV per
case). The kind (pipeline/studies/mechanism.py) solves; this module only arranges.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np
from flexopt.fea.materials import Material
from flexopt.fea.mechanism_design import REACTION_UNIT
from flexopt.fea.mechanism_fields import solved_vtu
from flexopt.geometry.mechanism import BeamShape, MechanismOutline, as_made_info
from flexopt.optimise.problem import CaseResponse
from flexopt.optimise.requirements import Requirement
from flexopt.pipeline.plot_targets import band_spec
from flexopt.pipeline.plots import mechanism_shapes_png
from flexopt.pipeline.runfolder import table_to_csv
from flexopt.pipeline.studies._mechanism_schema import (
    MechanismGeometry,
    MechanismStudy,
    case_prefix,
    outputs_in,
)
from flexopt.pipeline.studies._mechanism_stops import contact_png

__all__ = [
    "Solved",
    "case_responses",
    "design_files",
    "design_info",
    "plot_spec",
    "response_plot",
]


@dataclasses.dataclass
class Solved:
    """Everything one design's solve gives (before and after the width is solved)."""

    geometry: MechanismGeometry
    shapes: list[BeamShape]
    outline: MechanismOutline
    width_mm: float
    responses: dict[str, Any]  # case -> MechanismResponse (at the reference width)
    tables: dict[str, dict[str, np.ndarray]]  # case -> columns (width solved)
    metrics: dict[str, Any]
    curves_table: dict[str, np.ndarray]  # every case's columns, prefixed: what requirements read
    reason: str = ""
    clearance: dict[str, Any] = dataclasses.field(default_factory=dict)  # design.interference
    fidelity: dict[str, Any] | None = None  # the check of the exported outline (detail, result)
    field_map: dict[str, Any] | None = None  # its plane-stress field (best.vtu; fields.py)


def plot_spec(study: MechanismStudy, case: str, material: Material) -> dict[str, Any]:
    """How to plot ``case``'s response: the drive (``x``), its reaction (``y``), the peak
    stress (``stress``) and the material's yield (``allowable_MPa``, MPa)."""
    d = study.load_cases[case].drive
    return {
        "x": f"drive_{d.unit}",
        "y": f"drive_reaction_{REACTION_UNIT[d.control]}",
        "stress": "peak_stress_MPa",
        "allowable_MPa": material.yield_MPa,
    }


def response_plot(
    study: MechanismStudy,
    solved: Solved,
    case: str,
    material: Material,
    requirements: Sequence[Requirement],
) -> dict[str, Any]:
    """:func:`plot_spec` of ``case`` with the target band of a requirement on it, drawn."""
    plot = plot_spec(study, case, material)
    plot.update(
        band_spec(requirements, solved.tables[case], plot["x"], "y", case_prefix(study, case))
    )
    return plot


def case_responses(
    study: MechanismStudy,
    solved: Solved,
    material: Material,
    requirements: Sequence[Requirement],
) -> dict[str, CaseResponse]:
    """Every load case's table, plot spec (with its target band) and the user's outputs in it:
    what the pipeline draws and tabulates for each case (pipeline/responses.py)."""
    out = {}
    for case, table in solved.tables.items():
        plot = response_plot(study, solved, case, material, requirements)
        d = study.load_cases[case].drive
        plot["x_label"] = f"drive of {d.part} ({d.control}, {d.unit})"
        # with stops, each stop's force is drawn and tabulated with the outputs
        forces = [f"stop_{o.name}_force_N" for o in (study.stops.outlines if study.stops else ())]
        vtu = solved_vtu(solved, case)  # best_CASE.vtu (pipeline/vtu.py)
        out[case] = CaseResponse(table, plot, (*outputs_in(study, case), *forces), vtu)
    return out


def design_info(study: MechanismStudy, solved: Solved) -> dict[str, Any]:
    """The design as the report lists it: width (mm), outline area (mm²), every beam's
    centreline and thickness (mm) as made, the clearance, the bodies, each case's convergence
    and the check of the exported outline."""
    g = solved.geometry
    return {
        "width_mm": solved.width_mm,
        "width_solved": study.solve_width_from is not None,
        "outline_area_mm2": solved.outline.area_mm2,
        "beams": {
            n: {
                "points_mm": b.centreline().round(6).tolist(),
                "thickness_mm": b.thickness().round(6).tolist(),
                **as_made_info(solved.outline.beams.get(n)),
            }
            for n, b in g.beams.items()
        },
        "clearance": dict(solved.clearance),
        "bodies": {n: {"ref_mm": list(b.ref_mm)} for n, b in g.bodies.items()},
        "cases": {c: {"ok": bool(r.ok), "message": r.message} for c, r in solved.responses.items()},
        **({"fidelity": solved.fidelity} if solved.fidelity is not None else {}),
    }


def design_files(study: MechanismStudy, solved: Solved) -> dict[str, bytes]:
    """deformed_shapes.png and, with more than one load case, response_<case>.csv each."""
    # (outputs.png, every case's outputs on the axis of their unit, is the pipeline's: cases=)
    bodies = [(b.ref_mm, b.outline_mm) for b in solved.geometry.bodies.values()]
    drives = {c: (s.drive.control, s.drive.unit) for c, s in study.load_cases.items()}
    title = f"{study.name}: deformed shapes"
    shapes = mechanism_shapes_png(solved.responses, solved.outline.polygon, bodies, drives, title)
    files = {"deformed_shapes.png": shapes}
    contact = contact_png(study, solved.responses)  # with stops (None without)
    if contact is not None:
        files["contact_shapes.png"] = contact
    if len(solved.tables) > 1:
        for case, table in solved.tables.items():
            files[f"response_{case}.csv"] = table_to_csv(table).encode("utf-8")
    return files
