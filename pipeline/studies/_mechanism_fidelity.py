"""The ``mechanism`` kind's check of the part as exported (issue 22, items 2 and 4).

:func:`with_fidelity` takes a design solved by the beam model (a
:class:`~pipeline.studies._mechanism_result.Solved`) and the kind's problem (through the
public methods :class:`SolvedBy` names), runs
:func:`fea.mechanism_fidelity.mechanism_fidelity_check` on its exported outline in every load
case the check can take (plane stress always, the 3D solid where the width is at least three
times the thinnest beam), and returns the design judged on the highest-fidelity figure:

* forces, moments and their slopes (outputs that scale with the width) times the
  highest-fidelity model's stiffness ratio to the beam's, in that case;
* peak stresses: the beam model's as made (the roots' Kt) times the check's peak ratio where
  that is above 1 (the check's peak at the roots' chorded fillets rises slowly under mesh
  refinement, docs/mechanism.md, so the verdict never reads less than the beam's);

The check's beam model is the part as made (``outline.beams``: beams clipped and flared into
their roots' fillets, peak with the roots' Kt), the part whose forces and stresses the ratios
multiply; the exported outline it is compared with has the same fillets.
* with ``solve_width_from``, the width solved again from the corrected figures and the check
  run again at that width, so the exported part is the one the figures are for (the 3D ratio
  moves a little with the width: the figure sits that little off the centre).

The beam model's figures stay beside them (``info.fidelity.beam_model``, and each verdict's
detail). The optimiser's designs are judged by the beam model (the check costs seconds); the
reported design (``flexopt evaluate``, a run's best design) by the check. The study's
``fidelity:`` block is :class:`~pipeline.studies._mechanism_schema.MechanismFidelitySpec`; the
check's ratios and the corrected columns are :mod:`fea.mechanism_fidelity`'s.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np
from flexopt.optimise.mechanism_objectives import statistic
from flexopt.pipeline.studies._mechanism_result import Solved
from flexopt.pipeline.studies._mechanism_schema import (
    build_load_case,
    build_mechanism,
    output_columns,
)

__all__ = ["SolvedBy", "with_fidelity", "annotate"]

#: why a stress requirement stays on the beam model (docs/mechanism.md, "The check of the part
#: as exported")
STRESS_NOTE = (
    "judged on the larger of the beam model as made (its filleted roots' Kt included) and the "
    "check's peak (the check's linear peak over the as-made beam model's, applied at every "
    "row); the check's peak at the roots' chorded fillets rises slowly under mesh refinement, "
    "so it is a lower bound of the exported part's"
)


class SolvedBy(Protocol):
    """What :func:`with_fidelity` uses of the problem that solved a design (the kind's
    ``MechanismProblem``, pipeline/studies/mechanism.py): the study and material, and the
    parts of a design's answer the check recomputes at the width it solves."""

    study: Any
    material: Any

    def width_requirement(self) -> Any:
        """The requirement the width is solved from, or None."""

    def case_table(
        self, case: str, response: Any, scale: float, made: Any = None
    ) -> dict[str, np.ndarray]:
        """A load case's response as columns, forces times ``scale``."""

    def part_metrics(
        self, geometry: Any, outline: Any, tables: Any, width_mm: float, clearance: Any
    ) -> dict[str, Any]:
        """Every metric of the part as made at ``width_mm`` (mm)."""

    def curves_table(self, tables: Mapping[str, Mapping[str, np.ndarray]]) -> dict[str, Any]:
        """Every case's columns, prefixed by the case."""

    def judge(self, solved: Solved) -> tuple:
        """The requirements judged on ``solved``'s figures, without notes."""


def _check(study: Any, solved: Any, width_mm: float, case: str) -> dict[str, Any]:
    from flexopt.fea.mechanism_fidelity import FidelitySettings, mechanism_fidelity_check
    from shapely.geometry import Polygon

    spec = study.fidelity
    g = solved.geometry
    outline = solved.outline
    grounds = [*outline.pads.values(), *(Polygon(np.array(o)) for o in g.ground_outlines_mm)]
    settings = FidelitySettings(elements_through=spec.elements_through, layers=spec.layers)
    solid = {"auto": None, "always": True, "never": False}[spec.solid]
    # the beam model of the part as made (beams clipped and flared into their roots' fillets,
    # peak with the roots' Kt): the exported outline the check meshes has the fillets, and the
    # verdict multiplies the as-made peak by the check's ratio (like for like)
    mech = build_mechanism(g, study.material.to_material(), width_mm, outline.beams)
    return mechanism_fidelity_check(
        mech, build_load_case(study, case), outline.polygon, grounds, outline.bodies,
        list(outline.bands.values()), width_mm, settings, solid, outline.beams, True,
    )  # fmt: skip


def _width_case(problem: SolvedBy) -> str | None:
    """The load case the solved width's requirement reads (None: the width is not solved)."""
    study = problem.study
    req = problem.width_requirement()
    if req is None:
        return None
    quantity = req.quantity
    if len(study.load_cases) > 1 and "." in quantity:
        return quantity.split(".", 1)[0]
    return next(iter(study.load_cases))


def with_fidelity(problem: SolvedBy, solved: Solved) -> Solved:
    """``solved`` judged on the check of its exported outline (see the module); unchanged, with
    the reason in ``fidelity``, where the check is off, skipped or the design failed.

    ``problem`` is the kind's ``MechanismProblem`` (passed in: a module of the kind's helpers
    imports no kind), used through :class:`SolvedBy`'s public methods only."""

    from flexopt.fea.mechanism_fidelity import check_summary, corrected_columns, highest_fidelity

    study = problem.study
    if solved.reason:
        return solved
    if not study.fidelity.enabled:
        return dataclasses.replace(solved, fidelity={"skipped": "fidelity.enabled is false"})
    if getattr(study, "stops", None) is not None:
        why = (
            "the study has stops: the check of the exported outline solves it without contact, "
            "so its figures beyond a stop would be those of a part passing through it; the beam "
            "model's figures (with contact) are judged"
        )
        return dataclasses.replace(solved, fidelity={"skipped": why})
    if getattr(study, "contact", None):
        why = (
            "the study has beam contact: the check of the exported outline solves it without "
            "contact; the beam model's figures (with contact) are judged"
        )
        return dataclasses.replace(solved, fidelity={"skipped": why})
    width = solved.width_mm
    checks = {case: _check(study, solved, width, case) for case in study.load_cases}
    width_case = _width_case(problem)
    history = [width]
    if width_case is not None and "skipped" not in checks[width_case]:
        # the width that centres the corrected figure: forces are linear in the width and the
        # check's ratio is r(w), so w = w_beam / r(w). One step from the beam's width, and the
        # check run again there: every figure is computed at the width exported (in 3D r moves
        # a little with w, so the figure sits r(w1) / r(w0) - 1 off the centre: 0.7 % on the
        # parallel guide; plane stress's ratio does not depend on the width)
        _, ratio, _ = highest_fidelity(checks[width_case])
        new = solved.width_mm / ratio
        if abs(new - width) > 2e-3 * width:
            width = new
            history.append(width)
            checks = {case: _check(study, solved, width, case) for case in study.load_cases}
    scale = width / solved.geometry.width_mm
    tables, applied = {}, {}
    for case, response in solved.responses.items():
        table = problem.case_table(case, response, scale, solved.outline.beams)
        check = checks[case]
        if "skipped" in check:
            applied[case] = {"model": "beam", "why": check["skipped"]}
            tables[case] = table
            continue
        model, ratio, stress = highest_fidelity(check)
        applied[case] = {
            "model": model, "force_ratio": ratio, "stress_ratio_reported": stress,
            "stress": STRESS_NOTE,
        }  # fmt: skip
        control = study.load_cases[case].drive.control
        tables[case] = corrected_columns(table, control, output_columns(study, case), ratio, 1.0)
        # the stress the verdict reads: never below the check's own figure (issue 22: the best
        # figure the run computed), the part's as-made peak (roots' Kt) times the check's ratio
        # to that same as-made peak
        stress_col = np.asarray(tables[case]["peak_stress_MPa"], float)
        tables[case]["peak_stress_MPa"] = stress_col * max(1.0, stress)
    metrics = problem.part_metrics(solved.geometry, solved.outline, tables, width, solved.clearance)
    field_map = _field_map(study, solved, checks)
    beam_values = {**solved.metrics, **_worst(solved.curves_table)}
    beam_verdicts = {v.name: v.value for v in problem.judge(solved)}
    fidelity = {
        "summary": check_summary(checks, applied),
        "beam_model_verdicts": {k: v for k, v in beam_verdicts.items() if math.isfinite(v)},
        "checks": checks,
        "applied": applied,
        "width_mm": {"beam_model": solved.width_mm, "solved": width, "iterations": history},
        "beam_model": {k: v for k, v in beam_values.items() if isinstance(v, int | float)},
    }
    return dataclasses.replace(
        solved, width_mm=width, tables=tables, metrics=metrics,
        curves_table=problem.curves_table(tables), fidelity=fidelity, field_map=field_map,
    )  # fmt: skip


def _field_map(study: Any, solved: Solved, checks: dict[str, Any]) -> dict[str, Any] | None:
    """The first case's plane-stress field at every row (best.vtu draws the first case), every
    check's field removed from its record (best.json must not carry the mesh)."""
    from flexopt.pipeline.fields import mechanism_field_map

    case = next(iter(solved.responses))
    drive = np.asarray(solved.responses[case].drive, dtype=float)
    unit = study.load_cases[case].drive.unit
    rotation = study.load_cases[case].drive.control == "rotation"
    out = mechanism_field_map(
        checks[case], drive, f"drive_{unit}", 180.0 / np.pi if rotation else 1.0
    )
    for check in checks.values():
        if isinstance(check, dict):
            check.pop("field", None)
    return out


def _worst(curves: dict[str, np.ndarray]) -> dict[str, float]:
    return {k: v for k, col in curves.items() if (v := statistic(col, "max_abs")) is not None}


def annotate(verdicts: tuple, solved: Any) -> tuple:
    """Each verdict whose value the check changed says which model gave it, with the beam
    model's value beside it."""
    fid = getattr(solved, "fidelity", None) or {}
    if "applied" not in fid:
        return verdicts
    verdicts = _say_skipped(verdicts, fid["applied"])
    models = sorted({a["model"] for a in fid["applied"].values() if a["model"] != "beam"})
    if not models:
        return verdicts
    beam = fid.get("beam_model_verdicts", {})
    out = []
    for v in verdicts:
        if "peak_stress" in v.quantity or "stress_yield" in v.quantity:
            ratios = [
                f"{a['model']} / beam as made {a['stress_ratio_reported']:.3g}"
                for a in fid["applied"].values()
                if "stress_ratio_reported" in a
            ]
            note = f"{STRESS_NOTE} (peak {', '.join(ratios)})"
            out.append(dataclasses.replace(v, detail=f"{v.detail}; {note}" if v.detail else note))
            continue
        before = beam.get(v.name)
        if before is None or not math.isfinite(v.value) or math.isclose(v.value, before,
                                                                       rel_tol=1e-12):  # fmt: skip
            out.append(v)
            continue
        if v.quantity == "width_mm":
            note = (
                f"solved from the {'/'.join(models)} check of the exported outline; the beam "
                f"model's: {before:.6g} mm"
            )
        else:
            note = (
                f"judged on the {'/'.join(models)} check of the exported outline; beam model: "
                f"{before:.6g} {v.unit}".rstrip()
            )
        out.append(dataclasses.replace(v, detail=f"{v.detail}; {note}" if v.detail else note))
    return tuple(out)


#: quantities of the part's geometry, not of its response: the check changes none of them
_GEOMETRIC = ("width_mm", "mass_g", "envelope_", "interference_mm2", "min_clearance_mm",
              "min_thickness_mm")  # fmt: skip


def _say_skipped(verdicts: tuple, applied: dict[str, Any]) -> tuple:
    """A response verdict of a case the check skipped says so: it is judged on the beam model
    alone, with the reason (never silently on the lower-fidelity figure)."""
    skipped = {c: a.get("why", "") for c, a in applied.items() if a["model"] == "beam"}
    if not skipped:
        return verdicts
    out = []
    for v in verdicts:
        quantity = str(v.quantity)
        case, _, name = quantity.partition(".")
        cases = [case] if name and case in applied else list(skipped)
        whys = [f"{c}: {skipped[c]}" for c in cases if c in skipped]
        geometric = any(g in quantity for g in _GEOMETRIC) or v.name.startswith("design ")
        if not whys or geometric or quantity.startswith("variables"):
            out.append(v)
            continue
        note = "beam model only: the check of the exported outline skipped " + "; ".join(whys)
        out.append(dataclasses.replace(v, detail=f"{v.detail}; {note}" if v.detail else note))
    return tuple(out)
