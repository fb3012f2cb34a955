"""The ``sea_spring`` study file: its pydantic models (every key; docs/sea_spring.md and the
kind's docstring show a whole file), and what they say to the optimiser: the geometry frame
(:func:`spring_frame`), the stiffness target (:func:`target_stiffness_Nm_per_rad`, from
``target:`` or the SEA stiffness window), the topology and its variables, the design space
(:func:`design_space`, Table 9's bounds overridden by ``design_space:``) and the study's
``design:`` in it (:func:`design_vector`, :func:`design_sets`), and the refusals of a study
before any FE (:func:`check`). The kind is pipeline/studies/sea_spring.py.

Units: mm, N m, N m/rad, MPa, degrees as named in the keys.
"""

from __future__ import annotations

import difflib
import logging
from dataclasses import replace
from typing import Any, Literal

import numpy as np
from flexopt.fea.sea_design import SpringTopology, build_any
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import SpringFrame
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies._blocks import MeshSpec, Solid3DSpec
from flexopt.pipeline.studies._spring_frame import SpringFrameBlock
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study
from pydantic import BaseModel, Field, model_validator

__all__ = [
    "SeaSpringGeometry",
    "SeaSpringStudy",
    "SlotContactSpec",
    "SpringTarget",
    "TaguchiSpec",
    "WindowSpec",
    "check",
    "design_of",
    "design_sets",
    "design_space",
    "design_vector",
    "problem_space",
    "spring_frame",
    "target_stiffness_Nm_per_rad",
    "topology",
    "variables",
]

log = logging.getLogger(__name__)

# --------------------------------------------------------------------------------------------
# The study file


class SeaSpringGeometry(SpringFrameBlock):
    """The ``geometry:`` block: topology, set count and the shared frame keys (mm)."""

    kind: Literal["sea_spring"] = Field(description="sea_spring")
    topology: Literal["serpentine", "spiral"] = Field(
        "serpentine",
        description="serpentine: the paper's sets of concentric arcs joined by links (Tables 6 "
        "and 9); spiral: one curved arm per set from hub to pad (geometry.arm_spring), which "
        "carries the torque as a nearly uniform bending moment",
    )
    n_sets: int | None = Field(
        None,
        ge=1,
        le=12,
        description="RP of the GA stage; default: the Taguchi stage's choice (4 without it)",
    )
    arcs: int = Field(
        5,
        ge=1,
        le=15,
        description="arcs per set in the GA stage (odd; Table 9 has 5; 7 lowers the stress)",
    )
    min_deformed_slot_mm: float | None = Field(
        None,
        ge=0,
        description="a constraint: the narrowest slot at +-theta_T (the loaded spring must not "
        "touch itself), mm; null: measured and reported only",
    )

    @model_validator(mode="after")
    def _odd_arcs(self) -> SeaSpringGeometry:
        if self.arcs % 2 == 0:
            raise ValueError(
                f"arcs = {self.arcs}: the serpentine needs an odd number of arcs (hub spoke at "
                f"one end of a set, pad at the other); use {self.arcs - 1} or {self.arcs + 1}"
            )
        return self


class SpringTarget(BaseModel):
    """The ``target:`` block: the stiffness at the design torque and the stress not to pass."""

    model_config = STUDY_CONFIG

    stiffness_Nm_per_rad: float | None = Field(
        275.0, gt=0, description="secant stiffness at torque_Nm (null: from stiffness_window)"
    )
    torque_Nm: float = Field(53.0, gt=0, description="design torque (paper: 53 N m)")
    tolerance_percent: float = Field(2.0, gt=0, lt=100, description="stiffness band, percent")
    allowable_stress_MPa: float = Field(800.0, gt=0, description="peak von Mises allowed, MPa")
    max_asymmetry_percent: float | None = Field(
        None,
        gt=0,
        description="if set, a constraint: each direction's secant stiffness within this "
        "percentage of their mean (null: reported only)",
    )
    directions: Literal["both", "positive"] = Field(
        "both",
        description="both: load the hub both ways (an SEA spring works in both; a serpentine "
        "is chiral, so the two secant stiffnesses differ); positive: counter-clockwise only",
    )


class WindowSpec(BaseModel):
    """The ``stiffness_window:`` block: take the target from fea.sea_window (paper section 4)."""

    model_config = STUDY_CONFIG

    required_bandwidth_Hz: float = Field(4.0, gt=0, description="torque bandwidth at torque_Nm")
    impact_speed_rpm: float = Field(46.86, gt=0, description="output speed at the collision")
    impact_spring_torque_Nm: float = Field(0.0, ge=0, description="spring torque at collision")
    criterion: Literal["spring", "gearbox"] = Field("spring", description="K_max criterion")
    pick: Literal["k_max", "k_min", "middle"] = Field(
        "k_max", description="which stiffness of the window becomes the target"
    )


class TaguchiSpec(BaseModel):
    """The ``taguchi:`` block: stage 1 (L25 over Table 6)."""

    model_config = STUDY_CONFIG

    enabled: bool = Field(
        True, description="run stage 1 before the optimisation (flexopt run; not flexopt evaluate)"
    )
    torque_Nm: float | None = Field(
        None, gt=0, description="screening torque (default: a fifth of target.torque_Nm)"
    )
    pool_below_percent: float = Field(5.0, ge=0, lt=100, description="ANOVA pooling threshold")
    min_error_dof: int = Field(4, ge=0, le=20, description="pool until this many error dof")
    extra_runs: int = Field(5, ge=0, le=50, description="off-array runs for the additivity check")
    seed: int = Field(1, ge=0, description="seed of the extra runs")


class SlotContactSpec(BaseModel):
    """The ``contact:`` block: self-contact across the slots, and the overload curve beyond
    first contact (fea/plane_stress_contact.py; docs/durability.md, Contact across the slots)."""

    model_config = STUDY_CONFIG

    overload_deg: float = Field(
        gt=0, le=90, description="largest hub rotation of the overload curve, each way, degrees"
    )
    steps: int = Field(12, ge=2, le=200, description="rows of the overload curve each way")
    penalty_factor: float = Field(
        1.0, gt=0, description="contact pressure per mm of penetration = factor x E / h"
    )
    reach_mm: float = Field(
        3.0, gt=0, description="slot sides farther apart than this (loaded) do not pair, mm"
    )
    max_stress_MPa: float | None = Field(
        None, gt=0, description="if set, a check: the windings' peak stress with contact up "
        "to overload_deg at most this, MPa (null: reported only)",
    )  # fmt: skip


class SeaSpringStudy(Study):
    """A whole ``sea_spring`` study file."""

    geometry: SeaSpringGeometry = Field(description="kind: sea_spring and its limits")
    target: SpringTarget = Field(default_factory=SpringTarget, description="stiffness, torque")
    stiffness_window: WindowSpec | None = Field(
        None, description="take the stiffness target from the SEA stiffness window"
    )
    taguchi: TaguchiSpec = Field(default_factory=TaguchiSpec, description="stage 1")
    design_space: dict[str, list[float]] = Field(
        default_factory=dict,
        description="bounds [lower, upper] by Table 9 name (R1..R5, S1..S5, W1..W4, P1, P2, "
        "alpha, ST); unlisted variables keep Table 9",
    )
    thickness: Literal["solve", "search"] = Field(
        "solve",
        description="solve: ST follows from the stiffness target (plane-stress torque is "
        "proportional to ST), objectives stress and mass; search: ST is a GA variable and the "
        "stiffness error an objective (the paper's formulation)",
    )
    design: dict[str, float] | None = Field(
        None,
        description="the design flexopt evaluate analyses (mid-range if null), by variable "
        "name; RP: its number of sets (arms) when geometry.n_sets is null",
    )
    mesh: MeshSpec = Field(default_factory=MeshSpec, description="FE discretisation")
    contact: SlotContactSpec | None = Field(
        None, description="self-contact across the slots and the overload curve past it"
    )
    solid_3d: Solid3DSpec = Field(
        default_factory=Solid3DSpec,
        description="the chosen design as a 3D solid: check, thickness correction, converged "
        "peak stress (check: false for quick runs)",
    )
    optimiser: OptimiserSpec = Field(
        default_factory=lambda: OptimiserSpec(
            algorithm="nsga2", pop_size=20, n_gen=20, quick_pop_size=6, quick_n_gen=2
        ),
        description="algorithm (nsga2), pop_size, n_gen, seed, quick_pop_size, quick_n_gen",
    )

    @model_validator(mode="before")
    @classmethod
    def _old_check_3d(cls, data: Any) -> Any:
        if isinstance(data, dict) and "check_3d" in data:
            raise ValueError(
                "check_3d was replaced by the solid_3d block; write solid_3d: {check: "
                f"{str(bool(data['check_3d'])).lower()}}} instead of check_3d"
            )
        return data

    @model_validator(mode="after")
    def _target_or_window(self) -> SeaSpringStudy:
        if self.target.stiffness_Nm_per_rad is None and self.stiffness_window is None:
            raise ValueError(
                "target.stiffness_Nm_per_rad is null and there is no stiffness_window block; "
                "give one of them (e.g. stiffness_Nm_per_rad: 275)"
            )
        return self


# --------------------------------------------------------------------------------------------
# From the study to the optimiser's inputs


def spring_frame(study: SeaSpringStudy) -> SpringFrame:
    """The geometry frame of a study (its ``geometry:`` limits and ``mesh.fillet_segments``)."""
    return replace(study.geometry.frame(), fillet_segments=study.mesh.fillet_segments)


def target_stiffness_Nm_per_rad(study: SeaSpringStudy) -> tuple[float, dict[str, Any]]:
    """The stiffness target and where it came from (``stiffness_window`` wins when given)."""
    if study.stiffness_window is None:
        return float(study.target.stiffness_Nm_per_rad), {"source": "target.stiffness_Nm_per_rad"}
    from flexopt.fea.sea_window import Gearbox, Motor, rpm_to_rad_per_s, stiffness_window

    w = study.stiffness_window
    window = stiffness_window(
        Motor(),
        Gearbox(),
        required_torque_Nm=study.target.torque_Nm,
        impact_speed_rad_per_s=rpm_to_rad_per_s(w.impact_speed_rpm),
        required_bandwidth_Hz=w.required_bandwidth_Hz,
        impact_spring_torque_Nm=w.impact_spring_torque_Nm,
        criterion=w.criterion,
    )
    if window.is_empty:
        raise StudyError(
            "stiffness_window",
            f"the window is empty (K_min {window.k_min_Nm_per_rad:.4g} > K_max "
            f"{window.k_max_Nm_per_rad:.4g} N m/rad); lower required_bandwidth_Hz or "
            "impact_speed_rpm, or give target.stiffness_Nm_per_rad",
        )
    lo, hi = window.k_min_Nm_per_rad, window.k_max_Nm_per_rad
    k = {"k_max": hi, "k_min": lo, "middle": 0.5 * (lo + hi)}[w.pick]
    return float(k), {"source": f"stiffness_window ({w.pick})", "k_min": lo, "k_max": hi}


def topology(study: SeaSpringStudy) -> SpringTopology:
    """The study's topology (:class:`fea.sea_design.SpringTopology`)."""
    g = study.geometry
    return SpringTopology(g.topology, g.arcs, g.root_fillet_mm)


def variables(study: SeaSpringStudy) -> tuple[str, ...]:
    """Names of the GA variables of the study's topology (ST included, in vector order)."""
    return topology(study).variables


def _unit_name(name: str) -> str:
    if name in ("alpha", "sweep"):
        return f"{name}_deg"
    if name in ("F1", "F2"):
        return f"{name}_fraction"
    return f"{name}_mm"


def _unknown(name: str, path: str, names: tuple[str, ...]) -> StudyError:
    close = [n for n in names if n.lower() == name.lower()]
    close = close or difflib.get_close_matches(name, names, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    return StudyError(
        f"{path}.{name}",
        f"unknown design variable '{name}'; {hint}use {', '.join(names)} (Table 9 for 5 arcs; "
        "geometry.arcs sets the count)",
    )


def design_space(study: SeaSpringStudy) -> DesignSpace:
    """Table 9 bounds overridden by ``design_space:`` (names carry units: ``R1_mm``, ``alpha_deg``).

    Raises
    ------
    StudyError
        At ``design_space.<name>``: unknown name, not two numbers, swapped, equal or non-positive
        bounds, ST above ``geometry`` limits or alpha outside (0, 360 / RP).
    """
    names = variables(study)
    bounds = {k: list(v) for k, v in topology(study).bounds.items()}
    for name, b in study.design_space.items():
        path = f"design_space.{name}"
        if name not in bounds:
            raise _unknown(name, "design_space", names)
        if len(b) != 2:
            raise StudyError(path, f"got {list(b)}; give two bounds [lower, upper]")
        lo, hi = float(b[0]), float(b[1])
        if lo > hi:
            raise StudyError(path, f"lower {lo:g} > upper {hi:g}; did you swap them?")
        if lo == hi:
            raise StudyError(path, f"equal bounds [{lo:g}, {hi:g}]; give a range")
        if not lo > 0:
            raise StudyError(path, f"lower bound {lo:g} must be > 0")
        if name == "alpha" and hi >= 360:
            raise StudyError(path, f"alpha up to {hi:g} degrees leaves no room; keep it < 360 / RP")
        if name in ("F1", "F2") and hi >= 1:
            raise StudyError(path, f"upper bound {hi:g}: {name} is a fraction; keep it below 1")
        bounds[name] = [lo, hi]
    return DesignSpace(
        tuple(_unit_name(n) for n in names),
        np.array([bounds[n][0] for n in names]),
        np.array([bounds[n][1] for n in names]),
    )


def design_vector(study: SeaSpringStudy) -> np.ndarray:
    """(18,) the study's ``design:`` (unlisted variables at the middle of their range)."""
    space = design_space(study)
    names = variables(study)
    x = 0.5 * (space.lower + space.upper)
    for name, value in (study.design or {}).items():
        if name == "RP":
            continue  # the set count, see design_sets
        if name not in names:
            raise _unknown(name, "design", (*names, "RP"))
        x[names.index(name)] = float(value)
    return x


def design_sets(study: SeaSpringStudy) -> int:
    """Sets (arms) of the study's ``design:``: geometry.n_sets, else the design's RP, else 4."""
    if study.geometry.n_sets:
        return int(study.geometry.n_sets)
    rp = (study.design or {}).get("RP")
    if rp is None:
        return 4
    if rp != int(rp) or not 1 <= rp <= 12:
        raise StudyError("design.RP", f"RP = {rp:g} must be a whole number of sets, 1 to 12")
    return int(rp)


def problem_space(study: SeaSpringStudy) -> DesignSpace:
    """The space the design problem moves in: :func:`design_space` without ST when it is
    solved from the stiffness target (``thickness: solve``)."""
    space, names = design_space(study), variables(study)
    if study.thickness != "solve":
        return space
    keep = [i for i in range(len(names)) if names[i] != "ST"]
    return DesignSpace(tuple(space.names[i] for i in keep), space.lower[keep], space.upper[keep])


def design_of(study: SeaSpringStudy) -> tuple[DesignSpace, np.ndarray]:
    """The space the problem moves in (:func:`problem_space`) and the study's ``design:`` in
    it, as given (what ``flexopt evaluate`` solves; ST left out when it is solved)."""
    x = design_vector(study)
    if study.thickness == "solve":
        x = np.delete(x, variables(study).index("ST"))
    return problem_space(study), x


def check(study: SeaSpringStudy) -> None:
    """Refuse what would stop a run, before any folder exists (no FE here)."""
    try:
        frame = study.geometry.frame()
    except GeometryError as exc:
        raise StudyError("geometry", str(exc)) from exc
    space = design_space(study)
    names = variables(study)
    st = space.upper[names.index("ST")]
    if st > 20.0 + 1e-9:
        log.info("design_space.ST reaches %.3g mm, beyond the paper's 20 mm", st)
    n_sets = design_sets(study)
    if "alpha" in names and space.upper[names.index("alpha")] >= 360.0 / n_sets:
        raise StudyError(
            "design_space.alpha",
            f"alpha may reach {space.upper[names.index('alpha')]:g} degrees but {n_sets} "
            f"sets leave {360.0 / n_sets:g} degrees each; lower its upper bound",
        )
    if study.design is not None:
        x = design_vector(study)
        try:
            build_any(topology(study).params(x, n_sets, frame), frame)
        except GeometryError as exc:
            raise StudyError("design", str(exc)) from exc
    target_stiffness_Nm_per_rad(study)
