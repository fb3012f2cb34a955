"""Study kind ``gripper``: the finger force of paper 001 as the target of a constant-force beam.

The chain: a workpiece (mass, grip normal force) and the finger geometry (paper 001, Fig. 3) give
the drive force ``F1`` each finger must hold (:func:`fea.statics.finger_force`, the vector
form of Eqs. 5–14, with the paper's scalar Eq. 14 beside it); over the finger's rotation range
the largest ``F1`` (times a safety factor) becomes ``target.force_N`` of a ``constant_force``
study (paper 003), and the drive travel between the smallest and largest workpiece its operative
stroke. The constant-force study is a shipped or user study (``constant_force.study``) with those
keys replaced and its width ``B`` rescaled so that its design holds the new force (the beam's
force is proportional to ``B``).

Both commands work on one design problem, :class:`GripperProblem`: the resolved constant-force
study's, with the gripper's requirement beside it.

* ``flexopt evaluate gripper``: the nominal design's result (:meth:`GripperProblem.result`):
  the requirement, the resolved constant-force study (in ``evaluation.json`` under
  ``inputs.constant_force_study``, and as ``constant-force.yaml``) and the response of its
  design.
* ``flexopt run gripper --quick``: optimises the resolved constant-force beam (its GA, report,
  ``best.stl``).

YAML::

    geometry: {kind: gripper, lever_mm: 20, jaw_mm: 30, beta_deg: 20, alpha_deg: [5, 15]}
    material: ABS                          # the constant-force beam
    workpiece: {mass_kg: 0.02, normal_force_N: 0.8}      # or friction: {mu: 0.4, contacts: 2}
    jaws: [{name: lower, normal_deg: -90, weight_share: 1}, {name: upper, normal_deg: 90,
           weight_share: 0, mirrored: true}]
    constant_force: {study: constant-force, safety_factor: 1.0, pre_stroke_mm: 2.0}
"""

from __future__ import annotations

import copy
import math
import time
from typing import Any, Literal

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.statics import (
    FingerGeometry,
    FingerRequirement,
    JawLoad,
    finger_force,
    normal_force_for_friction_N,
    overtravel_mm,
)
from flexopt.optimise.joint_objectives import plateau_mean_N
from flexopt.optimise.problem import DesignResult, ProblemWrapper
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import StudyKind, _builtin, kinds, register
from flexopt.pipeline.study import (
    STUDY_CONFIG,
    OptimiserSpec,
    Study,
    parse_study_text,
    read_study_file,
    resolve_study_path,
    study_to_yaml,
    validate_study,
)
from pydantic import BaseModel, Field, model_validator

__all__ = [
    "GripperGeometry",
    "GripperStudy",
    "GripperProblem",
    "requirement",
    "resolved_constant_force_study",
]


class GripperGeometry(BaseModel):
    """The ``geometry:`` block: the finger of paper 001, Fig. 3 (mm, degrees)."""

    model_config = STUDY_CONFIG

    kind: Literal["gripper"] = Field(description="gripper")
    lever_mm: float = Field(gt=0, description="l1: pivot E to the line of the drive force, mm")
    jaw_mm: float = Field(gt=0, description="l2: pivot E to the jaw contact J, mm")
    beta_deg: float = Field(description="β: fixed angle of the jaw arm, degrees")
    alpha_deg: tuple[float, float] = Field(
        description="[α_min, α_max]: finger rotation at the largest and smallest workpiece, deg"
    )

    @model_validator(mode="after")
    def _range(self) -> GripperGeometry:
        lo, hi = self.alpha_deg
        if not -90 < lo <= hi < 90:
            raise ValueError(
                f"alpha_deg = [{lo:g}, {hi:g}] must be [min, max] inside (-90, 90) degrees"
            )
        return self


class FrictionGrip(BaseModel):
    """``workpiece.friction``: derive the normal force from holding by friction."""

    model_config = STUDY_CONFIG

    mu: float = Field(gt=0, description="friction coefficient jaw-workpiece")
    contacts: int = Field(2, ge=1, description="jaws sharing the weight")
    safety: float = Field(2.0, ge=1, description="safety factor on slipping")


class WorkpieceSpec(BaseModel):
    """The ``workpiece:`` block."""

    model_config = STUDY_CONFIG

    mass_kg: float = Field(ge=0, description="mass of the workpiece, kg")
    normal_force_N: float | None = Field(None, ge=0, description="grip normal force N, N")
    friction: FrictionGrip | None = Field(None, description="or: N from friction {mu, contacts}")
    gravity_deg: float = Field(-90.0, description="direction of gravity from +x, degrees")
    acceleration_m_per_s2: float = Field(0.0, description="gripper acceleration along gravity")

    @model_validator(mode="after")
    def _one_normal_force(self) -> WorkpieceSpec:
        if (self.normal_force_N is None) == (self.friction is None):
            raise ValueError("give normal_force_N or friction: {mu, contacts, safety}, not both")
        return self

    @property
    def normal_N(self) -> float:
        if self.normal_force_N is not None:
            return self.normal_force_N
        f = self.friction
        assert f is not None
        return normal_force_for_friction_N(
            self.mass_kg, f.mu, f.contacts, f.safety, self.acceleration_m_per_s2
        )


class JawSpec(BaseModel):
    """One entry of ``jaws:``: how the workpiece loads this finger's jaw."""

    model_config = STUDY_CONFIG

    name: str = Field("jaw", description="label")
    normal_deg: float = Field(
        -90.0, description="direction of the workpiece's push on the jaw, from +x, degrees"
    )
    weight_share: float = Field(1.0, ge=0, le=1, description="share of the weight on this jaw")
    mirrored: bool = Field(
        False, description="the finger is the mirror image (about the horizontal) of geometry"
    )


class ConstantForceLink(BaseModel):
    """The ``constant_force:`` block: which constant-force study the requirement feeds."""

    model_config = STUDY_CONFIG

    study: str = Field("constant-force", description="constant_force study: example name or path")
    safety_factor: float = Field(1.0, ge=1, description="target force = factor x largest F1")
    pre_stroke_mm: float = Field(
        2.0, ge=0, description="drive before the force plateau starts (paper 003: ~3 mm), mm"
    )
    stroke_mm: float | None = Field(
        None, gt=0, description="drive of the beam; default pre_stroke_mm + overtravel"
    )
    rescale_width: bool = Field(
        True, description="rescale the design's width B so its plateau holds the new force"
    )


class GripperStudy(Study):
    """A whole ``gripper`` study file."""

    geometry: GripperGeometry = Field(description="kind: gripper, lever_mm, jaw_mm, beta_deg, ...")
    workpiece: WorkpieceSpec = Field(description="mass_kg, normal_force_N or friction")
    jaws: tuple[JawSpec, ...] = Field(
        (JawSpec(name="lower"),), min_length=1, description="the jaws to check (paper: lower)"
    )
    constant_force: ConstantForceLink = Field(
        default_factory=ConstantForceLink, description="study, safety_factor, pre_stroke_mm"
    )
    optimiser: OptimiserSpec | None = Field(
        None, description="replaces the constant-force study's optimiser for flexopt run"
    )


# --------------------------------------------------------------------------------------------
# The requirement


def _requirements(study: GripperStudy) -> list[dict[str, Any]]:
    g = study.geometry
    w = study.workpiece
    rows = []
    for alpha in np.linspace(*g.alpha_deg, 7 if g.alpha_deg[0] < g.alpha_deg[1] else 1):
        for jaw in study.jaws:
            sign = -1.0 if jaw.mirrored else 1.0
            finger = FingerGeometry(
                g.lever_mm, g.jaw_mm, sign * math.radians(alpha), sign * math.radians(g.beta_deg)
            )
            # a mirrored finger (the upper one of the paper's pair) has its jaw arm at -(α + β);
            # the load directions stay in the real frame (N of the upper jaw points up)
            load = JawLoad(
                w.mass_kg,
                w.normal_N,
                math.radians(jaw.normal_deg),
                math.radians(w.gravity_deg),
                jaw.weight_share,
                w.acceleration_m_per_s2,
            )
            r: FingerRequirement = finger_force(load, finger)
            rows.append({"jaw": jaw.name, "alpha_deg": float(alpha), "result": r})
    return rows


def requirement(study: GripperStudy) -> dict[str, Any]:
    """The finger force over the jaws and the rotation range, the target and the stroke.

    Returns
    -------
    dict
        ``target_force_N`` (largest F1 x safety), ``finger_force_N`` / ``paper_finger_force_N``
        (largest of each), the jaw and angle where it occurs, ``normal_force_N``, ``weight_N``,
        ``overtravel_mm``, ``stroke_mm``, and ``rows`` (every jaw and angle).
    """
    try:
        rows = _requirements(study)
        travel = overtravel_mm(study.geometry.lever_mm, np.radians(study.geometry.alpha_deg))
    except FeaError as exc:
        raise StudyError("geometry", str(exc)) from exc
    best = max(rows, key=lambda r: r["result"].finger_force_N)
    paper = max(rows, key=lambda r: r["result"].paper_finger_force_N)
    link = study.constant_force
    f1 = best["result"].finger_force_N
    if not f1 > 0:
        raise StudyError(
            "workpiece",
            "the jaw load has no moment about the pivot (F1 = 0): give a normal force or mass",
        )
    stroke = link.stroke_mm if link.stroke_mm is not None else link.pre_stroke_mm + travel
    return {
        "target_force_N": f1 * link.safety_factor,
        "finger_force_N": f1,
        "finger_force_jaw": best["jaw"],
        "finger_force_alpha_deg": best["alpha_deg"],
        "paper_finger_force_N": paper["result"].paper_finger_force_N,
        "paper_over_vector": paper["result"].paper_finger_force_N / f1,
        "normal_force_N": study.workpiece.normal_N,
        "weight_N": best["result"].weight_N,
        "overtravel_mm": travel,
        "stroke_mm": stroke,
        "rows": [
            {
                "jaw": r["jaw"],
                "alpha_deg": r["alpha_deg"],
                "finger_force_N": r["result"].finger_force_N,
                "paper_finger_force_N": r["result"].paper_finger_force_N,
                "jaw_force_N": r["result"].jaw_force_N,
                "paper_jaw_force_N": r["result"].paper_jaw_force_N,
            }
            for r in rows
        ],
    }


# --------------------------------------------------------------------------------------------
# The constant-force study it feeds


def _base_raw(study: GripperStudy) -> dict[str, Any]:
    if "constant_force" not in kinds():
        raise StudyError(
            "constant_force.study",
            "the constant_force study kind is not installed; the requirement is in "
            "fea.statics.finger_force",
        )
    path = resolve_study_path(study.constant_force.study)
    raw = parse_study_text(read_study_file(path), str(path))
    kind = (raw.get("geometry") or {}).get("kind")
    if kind != "constant_force":
        raise StudyError(
            "constant_force.study",
            f"'{study.constant_force.study}' is a {kind!r} study; name a constant_force study",
        )
    return raw


def resolved_constant_force_study(
    study: GripperStudy, req: dict[str, Any] | None = None
) -> tuple[Study, dict[str, Any]]:
    """The constant-force study with the gripper's target force, stroke and material.

    With ``rescale_width`` the design's width B (and B's bounds) are scaled by
    ``target / plateau`` of the base design over ``[pre_stroke, stroke]`` at that stroke: the
    planar beam's stiffness, hence its force at a given stroke, is proportional to B, and its
    stresses do not depend on B.

    Returns
    -------
    Study, dict
        The validated constant-force study and what was changed (``changes``).

    Raises
    ------
    StudyError
        At ``constant_force.*`` when the base study cannot be read or the result is invalid.
    """
    req = req or requirement(study)
    link = study.constant_force
    raw = copy.deepcopy(_base_raw(study))
    force = req["target_force_N"]
    stroke = req["stroke_mm"]
    window = (min(link.pre_stroke_mm, stroke), stroke)
    raw["name"] = f"{study.name}-constant-force"
    raw["material"] = study.material.model_dump(mode="json", exclude_none=True)
    raw.setdefault("boundary", {})["stroke_mm"] = stroke
    target = raw.setdefault("target", {})
    target["force_N"] = force
    target.pop("allowable_stress_MPa", None)  # the new material's yield, unless given anew
    travel = req["overtravel_mm"]
    if 0 < travel <= stroke:
        target["min_operative_stroke_mm"] = travel
    if isinstance(raw.get("prb"), dict):
        raw["prb"] = {**raw["prb"], "target_force_N": force, "stroke_mm": stroke}
    if study.optimiser is not None:
        raw["optimiser"] = study.optimiser.model_dump(mode="json")
    changes: dict[str, Any] = {
        "target.force_N": force,
        "boundary.stroke_mm": stroke,
        "target.min_operative_stroke_mm": target.get("min_operative_stroke_mm"),
        "material": study.material.name,
    }
    try:
        resolved = validate_study(raw, source=f"{link.study} (resolved by {study.name})")
        if link.rescale_width:
            from flexopt.pipeline.problems import study_result

            base = study_result(resolved, 1)  # the base design's result, as flexopt evaluate's
            plateau = plateau_mean_N(base.table["displacement_mm"], base.table["force_N"], *window)
            if not plateau > 0:
                raise StudyError(
                    "constant_force.study",
                    f"the base design pushes no force over {window} mm; check its design",
                )
            scale = force / plateau
            design = dict(raw.get("design") or {}) if isinstance(raw.get("design"), dict) else {}
            width = design.get("B", base.inputs.get("design", {}).get("B"))
            if width is None:
                raise StudyError("constant_force.study", "the design has no width B to rescale")
            design["B"] = float(width) * scale
            raw["design"] = design
            # seed the GA with the rescaled design, which holds the target already
            raw["initial"] = "design"
            space = dict(raw.get("design_space") or {})
            if "B" in space:
                lo, hi = space["B"]
                space["B"] = [float(lo) * scale, float(hi) * scale]
                raw["design_space"] = space
            changes.update(
                {
                    "base_plateau_force_N": plateau,
                    "width_scale": scale,
                    "design.B": design["B"],
                    "design_space.B": space.get("B"),
                }
            )
            resolved = validate_study(raw, source=f"{link.study} (resolved by {study.name})")
    except StudyError as exc:
        raise StudyError(
            "constant_force", f"the resolved constant-force study is refused: {exc}"
        ) from exc
    return resolved, changes


def check(study: GripperStudy) -> None:
    """Compute the requirement and build the constant-force study it feeds."""
    resolved_constant_force_study(study)


# --------------------------------------------------------------------------------------------
# The design problem: flexopt run and flexopt evaluate


class GripperProblem(ProblemWrapper):
    """The constant-force design problem of the resolved study (``inner``: the
    ``constant_force`` kind's problem; every hook, ``study`` included, is its own), with the
    gripper's study (``gripper``), its requirement (``grip``, :func:`requirement`) and what the
    resolution changed (``changes``) for the result of a design. Picklable."""

    def __init__(self, study: GripperStudy) -> None:
        self.gripper = study
        self.grip = requirement(study)
        self.resolved, self.changes = resolved_constant_force_study(study, self.grip)
        from flexopt.pipeline.problems import kind_problem

        # kind_problem: a calibrated material's thickness offset, which the resolved study
        # inherits, is applied to the beam there (pipeline.as_printed)
        super().__init__(kind_problem(self.resolved))

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        """``flexopt evaluate``: the requirement by statics beside the response of the beam
        ``x`` (23,) (the resolved study's design, :meth:`nominal_design`), solved ``repeat``
        times; ``constant-force.yaml`` (the resolved study, ready for ``flexopt run``) among
        the files."""
        times = []
        for _ in range(max(1, repeat)):
            t0 = time.perf_counter()
            beam = self.inner.result(x, 1)  # the resolved design's result (flexopt evaluate's)
            times.append(time.perf_counter() - t0)
        return _with_requirement(self.gripper, self.grip, self.resolved, self.changes, beam, times)


def _with_requirement(
    study: GripperStudy,
    req: dict[str, Any],
    resolved: Study,
    changes: dict[str, Any],
    beam: DesignResult,
    times: list[float],
) -> DesignResult:
    """The gripper's result: the requirement ``req`` and the beam's response ``beam``."""
    table = dict(beam.table)
    force = req["target_force_N"]
    window = (min(study.constant_force.pre_stroke_mm, req["stroke_mm"]), req["stroke_mm"])
    plateau = plateau_mean_N(table["displacement_mm"], table["force_N"], *window)
    s = np.asarray(table["displacement_mm"], dtype=float)
    inside = (s >= window[0]) & (s <= window[1])
    f = np.asarray(table["force_N"], dtype=float)
    stress = np.asarray(table["peak_stress_MPa"], dtype=float)
    summary: dict[str, Any] = {
        key: req[key]
        for key in (
            "target_force_N",
            "finger_force_N",
            "paper_finger_force_N",
            "paper_over_vector",
            "finger_force_jaw",
            "finger_force_alpha_deg",
            "normal_force_N",
            "weight_N",
            "overtravel_mm",
            "stroke_mm",
        )
    }
    summary.update(
        {
            "beam_width_mm": changes.get("design.B"),
            "beam_plateau_force_N": plateau,
            "beam_plateau_error": plateau / force - 1.0,
            "beam_max_deviation_percent": float(np.max(np.abs(f[inside] / force - 1.0)) * 100.0),
            "beam_peak_stress_MPa": float(np.max(stress)),
            "peak_stress_MPa": float(np.max(stress)),  # the name flexopt run reports
            # the constant-force study's plane-stress check: the figure the verdict judges
            "plane_stress_peak_stress_MPa": beam.summary.get("plane_stress_peak_stress_MPa"),
            "checked_peak_stress_MPa": beam.summary.get("checked_peak_stress_MPa"),
            "stress_yield_ratio": float(np.max(stress)) / study.material.yield_MPa,
        }
    )
    # the beam analysed as printed (a calibrated material's offset, pipeline.as_printed) says so
    printed = {k: v for k, v in beam.info.items() if k == "as printed"}
    if printed:
        summary["thickness_offset_mm"] = beam.summary["thickness_offset_mm"]
    header = f"Constant-force study resolved by the gripper study '{study.name}'"
    return DesignResult(
        table=table,
        summary=summary,
        converged=beam.converged,
        message=beam.message,
        solve_times_s=tuple(times),
        inputs={
            "requirement_rows": req["rows"],
            "constant_force_changes": changes,
            "constant_force_study": resolved.model_dump(mode="json", exclude_none=True),
            "constant_force_summary": beam.summary,
        },
        diagnostics=dict(beam.diagnostics),
        info=printed,
        plot={
            "x": "displacement_mm",
            "y": "force_N",
            "stress": "peak_stress_MPa",
            "allowable_MPa": study.material.yield_MPa,
            # the finger's force and the band the beam is held to, over the gripping stroke
            "target": force,
            "tolerance": force * resolved.target.tolerance_percent / 100.0,
            "band_x": list(window),
        },
        headline=(
            "target_force_N",
            "paper_finger_force_N",
            "finger_force_jaw",
            "overtravel_mm",
            "stroke_mm",
            "beam_width_mm",
            "beam_plateau_force_N",
            "beam_max_deviation_percent",
            "stress_yield_ratio",
        ),
        files={"constant-force.yaml": study_to_yaml(resolved, header).encode("utf-8")},
        # the beam's design.vtu (section, fibre stresses) and its plane-stress check's field
        **{k: getattr(beam, k) for k in ("shapes_mm", "beam_field", "field_map")},
    )


def problem(study: GripperStudy) -> GripperProblem:
    """The design problem: the resolved constant-force study's, with the requirement."""
    return GripperProblem(study)


register(
    StudyKind(
        "gripper",
        GripperStudy,
        check,
        None,  # flexopt evaluate: the nominal design's GripperProblem.result
        problem,
        requirements=_builtin.gripper,
        quantities=_builtin.GRIPPER,
        figures=_builtin.CONSTANT_FORCE_FIGURES,
    )  # type: ignore[arg-type]
)
