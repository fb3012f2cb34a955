"""Study kind ``sea_spring``: the compact torsional SEA spring of paper 004 (Ardakanian et al.).

Two topologies (``geometry.topology``): the paper's **serpentine** of concentric arcs joined by
links (:mod:`geometry.sea_spring`, Tables 6 and 9) and **spiral** arms (:mod:`geometry.arm_spring`,
one curved arm per set, which carries the torque as a nearly uniform moment and is the default
study's; docs/sea_spring.md, section 6). Two stages, as in the paper:

1. **Taguchi screening** (paper section 5, Tables 6-8): an L25 array over six shape factors
   (the serpentine's RP, RR, ST, A, RT, D, :data:`geometry.sea_spring.TABLE6_LEVELS`; the
   spiral's :data:`geometry.arm_spring.SPIRAL_LEVELS`), each run a linear plane-stress FEA at a
   fifth of the design torque (10 N m, target 2.08 degrees); cost
   ``C = 0.5 sigma_n + 0.5 |theta_T - theta|_n`` (Eq. 27, each term divided by its largest value
   over the array), S/N smaller-the-better, pooled ANOVA, main effects, the predicted optimum and
   its confirmation run, and the additivity check with extra runs off the array. It runs once,
   when the design problem is built (31 linear solves, under a minute), fixes RP for stage 2 and
   seeds its first population; its results are in ``detail().info["taguchi"]`` and
   ``taguchi.png``.
2. **NSGA-II** over the planform variables of the topology (Table 9's, or
   :data:`geometry.arm_spring.SPIRAL_VARIABLES`). With ``thickness: solve`` (default) ST follows
   from the stiffness target and the objectives are the peak von Mises stress and the mass;
   constraints the geometric margins, the ST range, optionally each direction's stiffness
   (``target.max_asymmetry_percent``) and the loaded slots (``geometry.min_deformed_slot_mm``).
   With ``thickness: search`` (the paper's formulation) ST is a variable and
   ``|K - K_target| / K_target`` the second objective.

Each design is evaluated by a linear solve (stiffness ``K_lin``) and geometrically nonlinear
solves in one step to ``+-theta_T = torque / K_target`` (11.04 degrees for 53 N m and
275 N m/rad): ``K = T(theta_T) / theta_T`` is the secant stiffness at the design torque. The
hub's flange footprint is turned rigidly about the axis, the pads' washer footprints are held.

YAML (every key optional but ``name``, ``geometry.kind`` and ``material``)::

    geometry: {kind: sea_spring, topology: spiral, envelope_diameter_mm: 72, n_sets: null,
               root_fillet_mm: 1.5, min_deformed_slot_mm: 0.2}
    material: maraging-300
    target: {stiffness_Nm_per_rad: 275, torque_Nm: 53, tolerance_percent: 2,
             allowable_stress_MPa: 800, max_asymmetry_percent: 2}
    stiffness_window: null          # or {required_bandwidth_Hz: 4, impact_speed_rpm: 46.86, ...}
    taguchi: {enabled: true, torque_Nm: 10}
    design_space: {sweep: [150, 480]}   # the topology's bounds unless overridden
    mesh: {max_edge_mm: 3.0, elements_through: 1.0, curve_steps: 4}
    optimiser: {algorithm: nsga2, pop_size: 24, n_gen: 16}
    design: {RP: 2, sweep: 479.8, ...}  # what flexopt evaluate analyses
"""

from __future__ import annotations

import difflib
import logging
import math
import time
from dataclasses import replace
from typing import Any, Literal

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import (
    Clamp,
    Rotate,
)
from flexopt.fea.spring_analysis import SpringResponse, analyse_spring
from flexopt.fea.spring_analysis import stress_map_data as _stress_map_data
from flexopt.geometry.arm_spring import (
    SPIRAL_BOUNDS,
    SPIRAL_LEVELS,
    SPIRAL_VARIABLES,
    ArmSpringParams,
    arm_clearances,
    build_arm_spring,
    spiral_level_values,
    spiral_params,
)
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import (
    TABLE6_LEVELS,
    SpringFrame,
    SpringGeometry,
    SpringParams,
    build_spring,
    clearances,
    ga_bounds,
    ga_variables,
    params_from_vector,
    taguchi_params,
)
from flexopt.optimise.evaluation import INFEASIBLE_VALUE, Evaluation
from flexopt.optimise.problem import DesignDetail, DesignProblem
from flexopt.optimise.requirements import (
    PLANE_STRESS,
    SOLID_3D,
    Figure,
    MinFeature,
    Range,
    Requirement,
)
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline._hugepages import no_numpy_hugepages
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import EvaluationResult, StudyKind, _builtin, register
from flexopt.pipeline.studies._blocks import MeshSpec, Solid3DSpec
from flexopt.pipeline.studies._spring_frame import SpringFrameBlock
from flexopt.pipeline.study import STUDY_CONFIG, OptimiserSpec, Study, material_record
from flexopt.pipeline.verdict import envelope_values
from pydantic import BaseModel, Field, model_validator

__all__ = [
    "PUBLISHED_SPRINGS",
    "SeaSpringStudy",
    "SeaSpringProblem",
    "SpringResponse",
    "analyse_spring",
    "run_taguchi",
    "stress_map_png",
    "design_space",
    "target_stiffness_Nm_per_rad",
    "problem",
    "evaluate",
    "check",
]

log = logging.getLogger(__name__)

#: Paper 004, Table 1: published SEA springs (stiffness N m/rad, max torque N m, thickness mm,
#: diameter mm; None where the paper gives none). Row "t" is the template the paper follows.
_TABLE1 = (  # ref, stiffness N m/rad, max torque N m, thickness mm, diameter mm
    ("a [5]", 46, 15, 2.75, 60),
    ("b [8]", 219, 100, 15, 75),
    ("p [7]", 98, 7.7, 3, 85),
    ("t [11] (template)", 500, 60, 11, 90),
    ("s [12]", 110, 25, 12, 80),
    ("j [13]", 84, 15, 6, 125),
    ("ch [14]", 645, 45, None, None),
    ("h [15]", 9.7, 7.5, 10, 71),
    ("kh [16]", 172, 12, None, None),
)
PUBLISHED_SPRINGS: tuple[dict[str, Any], ...] = tuple(
    dict(zip(("ref", "stiffness_Nm_per_rad", "torque_Nm", "thickness_mm", "diameter_mm"), row,
             strict=True))
    for row in _TABLE1
)  # fmt: skip


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

    enabled: bool = Field(True, description="run stage 1 when the problem is built")
    torque_Nm: float | None = Field(
        None, gt=0, description="screening torque (default: a fifth of target.torque_Nm)"
    )
    pool_below_percent: float = Field(5.0, ge=0, lt=100, description="ANOVA pooling threshold")
    min_error_dof: int = Field(4, ge=0, le=20, description="pool until this many error dof")
    extra_runs: int = Field(5, ge=0, le=50, description="off-array runs for the additivity check")
    seed: int = Field(1, ge=0, description="seed of the extra runs")


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


# Both topologies behind one interface: variable names and bounds, parameters from a vector,
# building, geometric margins, Taguchi factors.


def variables(study: SeaSpringStudy) -> tuple[str, ...]:
    """Names of the GA variables of the study's topology (ST included, in vector order)."""
    if study.geometry.topology == "spiral":
        return SPIRAL_VARIABLES
    return ga_variables(study.geometry.arcs)


def _bounds(study: SeaSpringStudy) -> dict[str, tuple[float, float]]:
    if study.geometry.topology == "spiral":
        return dict(SPIRAL_BOUNDS)
    return ga_bounds(study.geometry.arcs)


def _unit_name(name: str) -> str:
    if name in ("alpha", "sweep"):
        return f"{name}_deg"
    if name in ("F1", "F2"):
        return f"{name}_fraction"
    return f"{name}_mm"


def params_of(
    study: SeaSpringStudy, x: np.ndarray, n_sets: int, frame: SpringFrame
) -> SpringParams | ArmSpringParams:
    """The spring parameters of a full vector (ST included) of the study's topology."""
    x = np.asarray(x, dtype=float).ravel()
    if study.geometry.topology == "spiral":
        values = dict(zip(SPIRAL_VARIABLES, map(float, x), strict=True))
        return spiral_params(values, n_sets, frame, study.geometry.root_fillet_mm)
    return params_from_vector(x, n_sets, study.geometry.arcs)


def build(p: SpringParams | ArmSpringParams, frame: SpringFrame) -> SpringGeometry:
    """Build either topology (:func:`build_spring` or :func:`build_arm_spring`)."""
    if isinstance(p, ArmSpringParams):
        return build_arm_spring(p, frame)
    return build_spring(p, frame)


def margins(p: SpringParams | ArmSpringParams, frame: SpringFrame) -> dict[str, float]:
    """Signed geometric margins (mm) of either topology, in :func:`constraint_keys` order."""
    if isinstance(p, ArmSpringParams):
        return arm_clearances(p, frame)
    return clearances(p, frame)


def constraint_keys(study: SeaSpringStudy) -> tuple[str, ...]:
    """The geometric constraints of the study's topology."""
    if study.geometry.topology == "spiral":
        return _SPIRAL_CONSTRAINTS
    return _GEOMETRY_CONSTRAINTS


def factor_levels(study: SeaSpringStudy) -> dict[str, tuple[float, ...]]:
    """The stage-1 factors and their five levels: Table 6, or the spiral's."""
    if study.geometry.topology == "spiral":
        return SPIRAL_LEVELS
    return TABLE6_LEVELS


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
    bounds = {k: list(v) for k, v in _bounds(study).items()}
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
            build(params_of(study, x, n_sets, frame), frame)
        except GeometryError as exc:
            raise StudyError("design", str(exc)) from exc
    target_stiffness_Nm_per_rad(study)


# --------------------------------------------------------------------------------------------
# Stage 1: Taguchi L25 (paper section 5, Tables 6-8)


def _levels_to_values(
    levels: np.ndarray | tuple[int, ...], table: dict[str, tuple[float, ...]] = TABLE6_LEVELS
) -> dict[str, float]:
    return {n: float(table[n][int(lv)]) for n, lv in zip(table, levels, strict=True)}


def screen_params(
    values: dict[str, float], frame: SpringFrame, topology: str = "serpentine",
    root_fillet_mm: float = 1.5,
) -> SpringParams | ArmSpringParams:  # fmt: skip
    """The spring of one stage-1 run: Table 6 factors (serpentine) or SPIRAL_LEVELS (spiral)."""
    v = values
    if topology == "spiral":
        return spiral_params(spiral_level_values(v), int(v["RP"]), frame, root_fillet_mm)
    return taguchi_params(v["RP"], v["RR"], v["ST"], v["A"], v["RT"], v["D"], frame)


def _screen_one(
    levels: tuple[int, ...], frame: SpringFrame, material: Material, study: SeaSpringStudy
) -> tuple[float, float, str]:
    """(stiffness N m/rad, peak stress per radian MPa/rad, reason) of one level combination."""
    v = _levels_to_values(levels, factor_levels(study))
    mesh = study.mesh
    try:
        p = screen_params(v, frame, study.geometry.topology, study.geometry.root_fillet_mm)
        geom = build(p, frame)
        theta = math.radians(1.0)  # linear: any angle; 1 degree keeps the numbers readable
        r = analyse_spring(geom, material, theta, mesh, nonlinear=False)
    except (GeometryError, FeaError) as exc:
        return math.nan, math.nan, str(exc)
    return r.linear_stiffness_Nm_per_rad, r.linear_peak_stress_MPa / theta, ""


#: Stage 1 solves its screening runs in two processes where fork is available (this one and a
#: forked child, each on one core); False: all in this process, in order. The results are the
#: same bit for bit (each run is an independent solve; tests/pipeline/test_sea_spring_stage1.py).
TAGUCHI_FORK = True


def _fork_context_here() -> Any:
    """multiprocessing's fork context where forking is safe here, else None: not on macOS or
    Windows (pipeline.run._fork_context's test), and only from a single-threaded process (a
    lock another thread holds at the fork stays held for ever in the child)."""
    import multiprocessing as mp
    import sys
    import threading

    if sys.platform in ("darwin", "win32") or "fork" not in mp.get_all_start_methods():
        return None
    if threading.active_count() != 1:
        return None
    return mp.get_context("fork")


class _Screening:
    """Stage 1's screening runs ``jobs`` (level tuples; the array rows first), solved by this
    process and, where fork is available, one forked child beside it.

    Both take the next unsolved run from a shared counter, so the two cores stay busy whatever
    each run costs (a row that cannot be built takes milliseconds, a spring ~0.1 s); the child
    sends back ``(index, result)`` through a pipe. Fork shares the study, so nothing is pickled
    on the way in. :meth:`get` returns the results of the first runs in order, solving here
    what is not taken yet (later runs too, while the child finishes one of these) and then
    waiting for what the child took: the confirmation run (which needs the array's analysis)
    is solved while the child goes on with the extra runs. Where fork is
    not available or the child cannot start, every run is solved here; a child that dies leaves
    its runs to this process, and one that keeps a run much longer than the slowest run here
    took (stuck, or starved of CPU) has it solved here too. The results do not depend on which
    process solved a run.
    """

    def __init__(
        self, jobs: list[tuple[int, ...]], frame: SpringFrame, material: Material,
        study: SeaSpringStudy, fork: bool = True,
    ) -> None:  # fmt: skip
        self.jobs = jobs
        self._args = (frame, material, study)
        self.results: list[tuple[float, float, str] | None] = [None] * len(jobs)
        self.in_child = 0  # results of the child's that were used (for the log)
        self._slowest_s = 0.0  # the longest run solved here, s
        self._process: Any = None
        self._conn: Any = None
        self._gone = ""  # why the child is no longer of use ("" while it is)
        if fork and len(jobs) > 1:
            self._start()

    def solve(self, levels: tuple[int, ...]) -> tuple[float, float, str]:
        """One run, in this process: :func:`_screen_one`."""
        t0 = time.perf_counter()
        out = _screen_one(levels, *self._args)
        self._slowest_s = max(self._slowest_s, time.perf_counter() - t0)
        return out

    def _start(self) -> None:
        import sys

        ctx = _fork_context_here()
        if ctx is None:
            return
        try:
            from flexopt.fea.plane_stress import warm_up

            # the compiled kernels and the sparse Cholesky loaded once, here, for both (~0.4 s
            # CPU each process would spend on its first run; the pool's warm-up then finds them)
            warm_up()
            self._lock = ctx.Lock()
            self._next = ctx.RawValue("i", 0)
            receive, send = ctx.Pipe(duplex=False)
            # output buffered here would be written a second time by the child at its exit
            sys.stdout.flush()
            sys.stderr.flush()
            process = ctx.Process(target=_screening_child, args=(self, receive, send),
                                  name="flexopt-taguchi", daemon=True)  # fmt: skip
            process.start()
            send.close()
        except Exception as exc:  # a daemonic process, no more processes: all solved here
            log.info("stage 1 in this process only (%s)", exc)
            return
        self._process, self._conn = process, receive

    def claim(self, keep_trying: Any) -> int | None:
        """The next run nobody has taken (``len(jobs)`` when all are), or None when the lock
        stays held elsewhere and ``keep_trying()`` is False (the other process died or hangs
        holding it: it is held for microseconds)."""
        from flexopt.pipeline.parallel import PARENT_CHECK_S

        while not self._lock.acquire(timeout=PARENT_CHECK_S):
            if not keep_trying():
                return None
        try:
            i = self._next.value
            if i < len(self.jobs):
                self._next.value = i + 1
            return i
        finally:
            self._lock.release()

    def get(self, n: int) -> list[tuple[float, float, str]]:
        """The results of runs ``0 .. n-1``: (stiffness N m/rad, peak stress per radian
        MPa/rad, reason) each, as :func:`_screen_one` gives them."""
        while True:
            if self._process is not None:
                self._receive(0.0)
            missing = [i for i in range(n) if self.results[i] is None]
            if not missing:
                return self.results[:n]  # type: ignore[return-value]
            if self._process is not None and self._gone:
                self._drop()
            if self._process is None:
                self.results[missing[0]] = self.solve(self.jobs[missing[0]])
            elif self._next.value < len(self.jobs):
                # a run nobody has taken: solve it here, also when it is not one of these
                # (rather than wait for the child's last run of these, idle)
                i = self.claim(lambda: False)
                if i is None:  # the child holds the lock: dead or stuck
                    self._process.join(0.1)
                    code = self._process.exitcode
                    self._gone = "is stuck" if code is None else f"ended (exit code {code})"
                elif i < len(self.jobs):
                    self.results[i] = self.solve(self.jobs[i])
            elif not self._receive(2.0 * self._slowest_s + 0.05) and not self._gone:
                # the child has the rest of these, and has kept the first much longer than
                # the slowest run here took: solve it here (its answer would be the same)
                log.debug("stage 1: run %d taken over from the second process", missing[0])
                self.results[missing[0]] = self.solve(self.jobs[missing[0]])

    def _receive(self, timeout_s: float) -> bool:
        """Take the child's results that have arrived, waiting up to ``timeout_s`` for one;
        whether one came. Sets ``_gone`` when the child has ended."""
        try:
            if not self._conn.poll(timeout_s):
                if not self._process.is_alive() and not self._conn.poll():
                    self._gone = f"ended (exit code {self._process.exitcode})"
                return False
            while self._conn.poll():
                i, result = self._conn.recv()
                if self.results[i] is None:  # else solved here meanwhile: the same answer
                    self.results[i] = result
                    self.in_child += 1
            return True
        except (EOFError, OSError):  # its end of the pipe closed: it has ended
            self._process.join(5.0)
            self._gone = f"ended (exit code {self._process.exitcode})"
            return True

    def _drop(self) -> None:
        log.warning("stage 1: the second process %s before it sent all its runs; they are "
                    "solved here", self._gone)  # fmt: skip
        self.close()

    def close(self) -> None:
        """Stop the child (at once when it is not done: its results are not needed) and reap
        it; idempotent."""
        if self._process is not None:
            log.info("stage 1: %d of %d runs solved in the second process", self.in_child,
                     len(self.jobs))  # fmt: skip
            if not self._gone and all(r is not None for r in self.results):
                self._process.join(0.5)  # it has found nothing left to take and is exiting
            if self._process.is_alive():
                self._process.terminate()
                self._process.join(5.0)
            if self._process.is_alive():
                self._process.kill()
                self._process.join()
            self._conn.close()
        self._process = self._conn = None


def _screening_child(screening: _Screening, receive: Any, send: Any) -> None:
    """The forked child of :class:`_Screening`: takes runs until none is left, sends each
    result; ends when its parent is gone. Starts as pipeline.parallel's workers."""
    import os
    import signal

    from flexopt.pipeline.parallel import _limit_loaded_pools, pin_threads

    receive.close()  # the parent's end: a send to a parent that died then fails at once
    pin_threads()
    _limit_loaded_pools()  # one BLAS thread beside the parent's, whatever its caller set
    # Ctrl-C reaches the whole process group: the parent decides (and ends this one); a
    # forked child inherits the CLI's SIGTERM handler, but is ended by its parent and must
    # then end at once, as a process normally does
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    parent = os.getppid()

    def parent_alive() -> bool:
        return os.getppid() == parent

    try:
        while parent_alive():
            i = screening.claim(parent_alive)
            if i is None or i >= len(screening.jobs):
                return
            send.send((i, screening.solve(screening.jobs[i])))
    except Exception:  # the parent is gone, or a run raised: the parent solves it again
        return  # (and raises it, where the error belongs)
    finally:
        send.close()


def run_taguchi(study: SeaSpringStudy) -> dict[str, Any]:
    """Stage 1: the paper's L25 screening of Table 6, reproduced step by step.

    Each run is a linear plane-stress analysis: at 2 degrees the nonlinear model differs from the
    linear one by far less than the factor effects (docs/sea_spring.md), so the screening torque
    ``T_s`` gives ``theta = T_s / K_lin`` and ``sigma = sigma'(theta)`` from one solve.

    Returns
    -------
    dict
        Plain data: the runs (levels, values, theta, sigma, C, S/N), the pooled ANOVA, the best
        levels and predicted S/N, the confirmation, the additivity check, the chosen design
        (``chosen``: the better of the confirmed optimum and the best tested run) and timings.
    """
    from flexopt.optimise.taguchi import select_array

    t0 = time.perf_counter()
    frame = spring_frame(study)
    material = study.material.to_material()
    k_target, _ = target_stiffness_Nm_per_rad(study)
    torque = study.taguchi.torque_Nm or study.target.torque_Nm / 5.0
    theta_t = math.degrees(torque / k_target)
    table = factor_levels(study)
    lay = select_array({n: len(v) for n, v in table.items()})
    spec = study.taguchi
    # the extra runs are drawn before any result is known, so they are solved beside the array
    rng = np.random.default_rng(spec.seed)
    extra = rng.integers(0, 5, size=(spec.extra_runs, len(table)))
    n_array = len(lay.design)
    jobs = [tuple(int(v) for v in row) for row in (*lay.design, *extra)]
    screening = _Screening(jobs, frame, material, study, fork=TAGUCHI_FORK)
    try:
        runs = screening.get(n_array)
        stage1 = _taguchi_analysis(study, lay, table, runs, extra, screening, torque, theta_t)
    finally:
        screening.close()
    stage1["time_s"] = time.perf_counter() - t0  # wall time of the whole stage
    return stage1


def _taguchi_analysis(
    study: SeaSpringStudy, lay: Any, table: dict[str, tuple[float, ...]],
    runs: list[tuple[float, float, str]], extra: np.ndarray, screening: _Screening,
    torque: float, theta_t: float,
) -> dict[str, Any]:  # fmt: skip
    """:func:`run_taguchi` from the array's results ``runs``: the analysis, the confirmation
    run (solved here) and the ``extra`` runs (from ``screening``, solved beside the array)."""
    from flexopt.optimise.taguchi import Pool, analyse, confirm

    k = np.array([r[0] for r in runs])
    sig_per_rad = np.array([r[1] for r in runs])
    theta = np.degrees(torque / k)
    sigma = sig_per_rad * np.radians(theta)
    failed = ~np.isfinite(theta)
    # A run that cannot be built keeps the array balanced with the worst observed values.
    theta_err = np.abs(theta - theta_t)
    if failed.any():
        theta_err[failed] = np.nanmax(theta_err)
        sigma[failed] = np.nanmax(sigma)
    s_max, e_max = float(sigma.max()), float(theta_err.max())

    def cost(sig: float, err: float) -> float:
        # Eq. 27 on values divided by their largest over the array (positive, so S/N is finite)
        return 0.5 * sig / s_max + 0.5 * err / e_max

    C = np.array([cost(s, e) for s, e in zip(sigma, theta_err, strict=True)])
    spec = study.taguchi
    kw = dict(factor_names=lay.factor_names, columns=lay.columns)
    result = analyse(
        lay.array,
        C,
        "smaller",
        pool=Pool(below_percent=spec.pool_below_percent, min_error_dof=spec.min_error_dof),
        **kw,
    )
    best = tuple(int(v) for v in result.best_levels)

    def measure(run: tuple[float, float, str]) -> tuple[float, float, float, float]:
        kk, sp, _ = run
        if not math.isfinite(kk):
            return math.nan, math.nan, math.nan, float(C.max())
        th = math.degrees(torque / kk)
        sg = sp * math.radians(th)
        return kk, th, sg, cost(sg, abs(th - theta_t))

    kb, thb, sgb, cb = measure(screening.solve(best))
    conf = confirm(result, responses=[cb])
    n_array = len(runs)
    extra_c = np.array([measure(r)[3] for r in screening.get(len(screening.jobs))[n_array:]])
    additivity = (
        result.additivity(extra_levels=extra, extra_sn=-10.0 * np.log10(extra_c**2))
        if spec.extra_runs
        else result.additivity()
    )
    i_run = int(np.argmin(C))
    if cb <= C[i_run]:
        chosen_levels, chosen_from = best, "S/N optimum (confirmed run)"
    else:
        chosen_levels, chosen_from = tuple(int(v) for v in lay.design[i_run]), f"array run {i_run}"
    anova_rows = [
        {k2: (float(v) if isinstance(v, float | np.floating) else v) for k2, v in row.items()}
        for row in result.anova.rows()
    ]
    return {
        "array": lay.array_name,
        "topology": study.geometry.topology,
        "torque_Nm": torque,
        "target_rotation_deg": theta_t,
        "cost": "C = 0.5 sigma/max(sigma) + 0.5 |theta_T - theta|/max|theta_T - theta| (Eq. 27)",
        "runs": {
            **{
                n: [float(table[n][lv]) for lv in lay.design[:, j]] for j, n in enumerate(table)
            },  # fmt: skip
            "stiffness_Nm_per_rad": k.tolist(),
            "rotation_deg": theta.tolist(),
            "stress_MPa": sigma.tolist(),
            "C": C.tolist(),
            "sn_dB": np.asarray(result.sn).tolist(),
            "failed": [r[2] for r in runs],
        },
        "anova": anova_rows,
        "main_effects": {
            me.name: {"levels": [float(v) for v in table[me.name]], "sn_dB": me.sn.tolist()}
            for me in result.main_effects
        },
        "best_levels": dict(zip(lay.factor_names, best, strict=True)),
        "best_values": _levels_to_values(best, table),
        "predicted_sn_dB": float(result.predicted_sn),
        "confirmation": {
            "stiffness_Nm_per_rad": kb,
            "rotation_deg": thb,
            "stress_MPa": sgb,
            "C": cb,
            "measured_sn_dB": float(conf.measured_sn),
            "difference_dB": float(conf.difference),
            "half_width_dB": float(conf.half_width),
            "within": bool(conf.within),
        },
        "additivity": {
            "extra_levels": extra.tolist(),
            "extra_residuals_dB": np.asarray(additivity.extra_residuals).tolist(),
            "rms_extra_residual_dB": (
                float(np.sqrt(np.mean(np.square(additivity.extra_residuals))))
                if spec.extra_runs
                else None
            ),
            "largest_pair": (
                f"{additivity.pairs[0].a}x{additivity.pairs[0].b}" if additivity.pairs else None
            ),
            "notes": list(additivity.notes),
        },
        "best_run": {
            "index": i_run,
            "C": float(C[i_run]),
            **_levels_to_values(lay.design[i_run], table),
        },
        "chosen": {"from": chosen_from, **_levels_to_values(chosen_levels, table)},
    }


def seed_from_taguchi(
    chosen: dict[str, float], space: DesignSpace, frame: SpringFrame, n_arcs: int = 5,
    topology: str = "serpentine",
) -> np.ndarray:  # fmt: skip
    """The stage-1 spring as a GA vector: ``n_arcs`` arcs (its other levels kept, arcs spread
    evenly as in stage 1) or the spiral's variables; clipped into the space."""
    if topology == "spiral":
        v = spiral_level_values(chosen)
        return space.clip(np.array([v[n] for n in SPIRAL_VARIABLES]))
    n = int(n_arcs)
    p = taguchi_params(
        chosen["RP"], (n - 1) // 2, chosen["ST"], chosen["A"], chosen["RT"], chosen["D"], frame
    )
    x = np.array(
        [*p.radii_mm, *p.arc_thickness_mm, *p.link_width_mm, p.hub_link_mm, p.pad_link_mm,
         p.span_deg, p.thickness_mm]
    )  # fmt: skip
    return space.clip(x)


# --------------------------------------------------------------------------------------------
# Stage 2: the design problem


class SeaSpringProblem(DesignProblem):
    """The NSGA-II problem of stage 2 (picklable; stage 1 runs in the constructor).

    With ``thickness: solve`` (default) the variables are the 17 planform variables of Table 9
    (ST left out) and ST is computed: under displacement control the plane-stress displacement
    field does not depend on the thickness and the torque is proportional to it, so one solve at
    a reference thickness gives the ST at which ``T(theta_T) = torque_Nm`` exactly (the secant
    stiffness is then the target to solver precision). Objectives: ``peak_stress_MPa`` (which
    does not depend on ST either) and ``mass_g``; constraints: the four geometric margins of
    :func:`geometry.sea_spring.clearances` and the ST range (``thickness_over_mm``,
    ``thickness_under_mm``). With ``target.directions: both`` the hub is turned both ways: the
    stiffness is the mean of the two secant stiffnesses, the stress the worse direction, and
    ``asymmetry_percent`` (each direction against the mean) is reported, or constrained when
    ``target.max_asymmetry_percent`` is set.

    With ``thickness: search`` (the paper's formulation) ST is the 18th variable; objectives
    ``peak_stress_MPa`` and ``stiffness_error_percent`` (|K/K_target - 1| 100), constraints the
    geometric margins and ``stiffness_band_percent`` (error minus ``tolerance_percent``).
    """

    #: thickness at which the "solve" mode's single solve is made, mm (any value gives the
    #: same ST; 10 mm keeps the forces in a familiar range)
    REFERENCE_THICKNESS_MM = 10.0

    def __init__(self, study: SeaSpringStudy, stage1: dict[str, Any] | None = None) -> None:
        self.study = study
        self.material = study.material.to_material()
        self.frame = spring_frame(study)
        self.k_target, self.target_source = target_stiffness_Nm_per_rad(study)
        self.theta = study.target.torque_Nm / self.k_target  # rad
        self.full_space = design_space(study)
        self.solve_st = study.thickness == "solve"
        self.n_arcs = study.geometry.arcs
        self.topology = study.geometry.topology
        self.names = variables(study)
        i_st = self.names.index("ST")
        self.st_range = (float(self.full_space.lower[i_st]), float(self.full_space.upper[i_st]))
        if self.solve_st:
            keep = [i for i in range(len(self.names)) if i != i_st]
            self.space = DesignSpace(
                tuple(self.full_space.names[i] for i in keep),
                self.full_space.lower[keep],
                self.full_space.upper[keep],
            )
            self.objective_names = ("peak_stress_MPa", "mass_g")
            extra: tuple[str, ...] = ("thickness_over_mm", "thickness_under_mm")
        else:
            self.space = self.full_space
            self.objective_names = ("peak_stress_MPa", "stiffness_error_percent")
            extra = ("stiffness_band_percent",)
        if study.target.max_asymmetry_percent is not None:
            extra = (*extra, "asymmetry_percent")
        self.min_gap = study.geometry.min_deformed_slot_mm
        if self.min_gap is not None:
            extra = (*extra, "deformed_slot_mm")
        self.geometry_constraints = constraint_keys(study)
        self.constraint_names = (*self.geometry_constraints, *extra)
        if stage1 is None and study.taguchi.enabled:
            from threadpoolctl import threadpool_limits

            # One BLAS thread, as in the pool's workers: CHOLMOD's supernodes of a 30k-DOF
            # spring are too small for a second thread to pay (the 31 screening runs took
            # ~4.7 s CPU / 3.8 s wall with two threads, 3.3 s both with one; same answers).
            with threadpool_limits(1):
                stage1 = run_taguchi(study)
        self.stage1 = stage1
        self.n_sets = int(stage1["chosen"]["RP"]) if stage1 else design_sets(study)
        if study.geometry.n_sets:
            self.n_sets = int(study.geometry.n_sets)
        # a robustness sample holds the nominal design's solved ST (hold_solved), mm
        self.held_st_mm: float | None = None

    def warm_up(self) -> None:
        """Load the compiled plane-stress kernels and the sparse Cholesky once (a pool calls
        this before it forks its workers, :func:`pipeline.backends.open_backend`; without it
        every worker loaded them on its first design)."""
        from flexopt.fea.plane_stress import warm_up

        warm_up()

    # -- robustness samples (pipeline/robustness.py) -------------------------------------------

    def scatter_design(
        self, x: np.ndarray, thickness_delta_mm: float, width_delta_mm: float
    ) -> np.ndarray:
        """(n_var,) ``x`` as cut or printed off by a tolerance: every in-plane member width
        (spiral W1..W4; serpentine arcs S1..Sn, links W1..W(n-1), hub spoke P1, pad neck P2)
        plus ``thickness_delta_mm``; the plate thickness ST (a variable with ``thickness:
        search``) plus ``width_delta_mm``; radii, angles and fractions stay."""
        x = np.array(x, dtype=float)
        for i, name in enumerate(n.removesuffix("_mm") for n in self.space.names):
            if name == "ST":
                x[i] += width_delta_mm
            elif name in ("P1", "P2") or (name[:1] in "SW" and name[1:].isdigit()):
                x[i] += thickness_delta_mm
        return x

    @property
    def held_scatter(self) -> dict[str, str]:
        """The solved quantity a sample holds and the scatter that moves it."""
        return {"ST": "width"} if self.solve_st else {}

    def held_state(self, evaluation: Evaluation) -> dict[str, float]:
        """ST solved for the nominal design (``thickness: solve``), else nothing."""
        st = evaluation.metrics.get("ST_mm")
        if not self.solve_st or st is None or not math.isfinite(st):
            return {}
        return {"ST_mm": float(st)}

    def hold_solved(
        self, held: dict[str, float], thickness_delta_mm: float, width_delta_mm: float
    ) -> None:
        """Solve at the held ST plus ``width_delta_mm`` (the plate's thickness tolerance)
        instead of the ST of the stiffness target; an empty ``held`` solves ST again."""
        st = held.get("ST_mm")
        self.held_st_mm = None if st is None else float(st) + width_delta_mm

    # -- helpers ---------------------------------------------------------------------------

    def full_vector(self, x: np.ndarray, st_mm: float | None = None) -> np.ndarray:
        """(18,) Table 9 vector of a design vector (ST inserted in solve mode)."""
        x = np.asarray(x, dtype=float).ravel()
        if not self.solve_st:
            return x
        st = self.REFERENCE_THICKNESS_MM if st_mm is None else st_mm
        return np.insert(x, self.names.index("ST"), st)

    def params(self, x: np.ndarray, st_mm: float | None = None) -> SpringParams | ArmSpringParams:
        return params_of(self.study, self.full_vector(x, st_mm), self.n_sets, self.frame)

    def nominal_design(self) -> np.ndarray:
        """(n_var,) the study's ``design:`` in this problem's space (ST left out when it is
        solved): what ``flexopt evaluate`` solves, so ``flexopt export`` of an evaluate folder
        rebuilds it."""
        x = design_vector(self.study)  # as given: outside its range it is judged NOT MET
        return np.delete(x, self.names.index("ST")) if self.solve_st else x

    def initial_designs(self) -> np.ndarray | None:
        """The stage-1 spring (five-arc version) or else the study's ``design:``, seeded into
        the first population."""
        if self.stage1:
            x = seed_from_taguchi(
                self.stage1["chosen"], self.full_space, self.frame, self.n_arcs, self.topology
            )
        elif self.study.design is not None:
            x = self.full_space.clip(design_vector(self.study))
        else:
            return None
        if self.solve_st:
            x = np.delete(x, self.names.index("ST"))
        return x[None, :]

    def _margins_g(self, p: SpringParams | ArmSpringParams) -> np.ndarray:
        m = margins(p, self.frame)
        return -np.array([m[k] for k in self.geometry_constraints])

    def solve(self, x: np.ndarray, steps: int = 1, keep_model: bool = False):
        """Build and analyse a design; returns (params, geometry, response, ST mm) or raises.

        In solve mode the analysis is made at the reference thickness and ST is the thickness
        whose torque at theta_T is the target torque; the returned response is rescaled to it
        (torques scale with ST, displacements and stresses do not).

        Raises
        ------
        GeometryError, FeaError
        """
        p = self.params(x)
        geom = build(p, self.frame)
        both = self.study.target.directions == "both"
        r = analyse_spring(geom, self.material, self.theta, self.study.mesh, steps, True,
                           keep_model, both_directions=both,
                           gaps=keep_model or self.min_gap is not None)  # fmt: skip
        if not self.solve_st or not r.ok:
            return p, geom, r, p.thickness_mm
        # The thickness at which the (mean) secant stiffness is the target (or the held one).
        scale = self.k_target / r.mean_stiffness_Nm_per_rad
        if self.held_st_mm is not None:
            scale = self.held_st_mm / p.thickness_mm
        st = p.thickness_mm * scale
        p = self.params(x, st)
        # ST is the extrusion: the outline, regions and checks do not depend on it, so the
        # built geometry only takes the new parameters (a second build cost ~25 ms a design).
        geom = replace(geom, params=p)
        r = r.scaled(scale)
        if r.model is not None:
            r.model.thickness_mm = st  # only the stress map reads it; stresses do not change
        return p, geom, r, st

    # -- the contract ----------------------------------------------------------------------

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return self._evaluate(x)[0]

    def _evaluate(self, x: np.ndarray, steps: int = 1, keep_model: bool = False) -> tuple:
        """(Evaluation, solved) with solved = (params, geometry, response, ST) or None."""
        t0 = time.perf_counter()
        x = np.asarray(x, dtype=float)
        n_obj, n_con = len(self.objective_names), len(self.constraint_names)
        try:
            p = self.params(x)
            g_geo = self._margins_g(p)
        except GeometryError as exc:
            return Evaluation.failed(x, n_obj, n_con, f"cannot build: {exc}"), None
        n_extra = n_con - g_geo.size
        if np.any(g_geo > 1e-9):
            # Not buildable: no FE, but graded violations lead the GA back.
            g = np.append(g_geo, np.full(n_extra, INFEASIBLE_VALUE))
            f = np.full(n_obj, INFEASIBLE_VALUE)
            ev = Evaluation(x, f, g, {"buildable": False}, "", time.perf_counter() - t0)
            return ev, None
        try:
            p, geom, r, st = self.solve(x, steps, keep_model)
        except (GeometryError, FeaError) as exc:
            return Evaluation.failed(x, n_obj, n_con, f"cannot build: {exc}"), None
        if not r.ok:
            reason = f"nonlinear solve: {r.message}"
            return Evaluation.failed(x, n_obj, n_con, reason, time.perf_counter() - t0), None
        mass_g = geom.mass_kg(self.material.density_kg_m3) * 1e3
        k_mean = r.mean_stiffness_Nm_per_rad
        err = abs(k_mean / self.k_target - 1.0) * 100.0
        asym = abs(r.stiffness_Nm_per_rad / k_mean - 1.0) * 100.0
        peak = r.worst_peak_stress_MPa
        if self.solve_st:
            f = np.array([peak, mass_g])
            g = np.append(g_geo, [st - self.st_range[1], self.st_range[0] - st])
        else:
            f = np.array([peak, err])
            g = np.append(g_geo, err - self.study.target.tolerance_percent)
        if self.study.target.max_asymmetry_percent is not None:
            g = np.append(g, asym - self.study.target.max_asymmetry_percent)
        deformed_gap = math.nan
        if r.slot_gaps_mm:
            # no slot found (inf) counts as plenty of room, kept finite for the optimiser
            deformed_gap = min(
                [min(v, 1e3) for k, v in r.slot_gaps_mm.items() if k != "undeformed"] or [1e3]
            )
        if self.min_gap is not None:
            g = np.append(g, self.min_gap - deformed_gap)
        # the thinnest printed size: the thinnest member (its margin + the limit) or the plate
        i_thin = self.geometry_constraints.index("thinnest_mm")
        thinnest = float(-g_geo[i_thin]) + self.frame.min_feature_mm
        metrics = {
            "ST_mm": st,
            "min_feature_mm": min(thinnest, st),
            "stiffness_Nm_per_rad": r.mean_stiffness_Nm_per_rad,
            "stiffness_ccw_Nm_per_rad": r.stiffness_Nm_per_rad,
            "stiffness_cw_Nm_per_rad": r.reverse_stiffness_Nm_per_rad,
            "asymmetry_percent": asym,
            "linear_stiffness_Nm_per_rad": r.linear_stiffness_Nm_per_rad,
            "torque_Nm": float(r.torque_Nm[-1]),
            "peak_stress_MPa": peak,
            "mass_g": mass_g,
            "n_dofs": r.n_dofs,
            "newton_iterations": r.iterations,
            "fe_time_s": r.solve_time_s,
            "deformed_slot_mm": deformed_gap,
        }
        return Evaluation(x, f, g, metrics, "", time.perf_counter() - t0), (p, geom, r, st)

    @no_numpy_hugepages  # large arrays ahead (pipeline/_hugepages.py)
    def detail(self, x: np.ndarray) -> DesignDetail:
        x = np.asarray(x, dtype=float)
        study = self.study
        # One solve serves the evaluation and the curve (the last row is the design point).
        evaluation, solved = self._evaluate(x, study.mesh.curve_steps, keep_model=True)
        info: dict[str, Any] = {
            "thickness": study.thickness,
            "n_sets": self.n_sets,
            "material": {
                "name": self.material.name,
                "why": "maraging 300: highest yield (2000 MPa) and yield/E of the library's "
                "steels, so the 800 MPa cap is 40 % of yield and about its fatigue limit",
            },
            "target": {
                "stiffness_Nm_per_rad": self.k_target,
                "torque_Nm": study.target.torque_Nm,
                "rotation_deg": math.degrees(self.theta),
                **self.target_source,
            },
        }
        files: dict[str, bytes] = {}
        if self.stage1:
            info["taguchi"] = _stage1_summary(self.stage1)
            if "main_effects" in self.stage1:
                from flexopt.pipeline.plots import plot_taguchi

                files["taguchi.png"] = plot_taguchi(
                    self.stage1["main_effects"],
                    self.stage1["anova"],
                    title=f"stage 1: {self.stage1['array']} over the {self.topology}'s factors",
                )
        if solved is None:
            info["problem"] = evaluation.reason or "not buildable (see the constraints)"
            return DesignDetail(evaluation, info=info)
        p, geom, r, st = solved
        info["design"] = dict(zip(self.names, map(float, self.full_vector(x, st)), strict=True))
        # The 3D checks keep this process busy; a second one takes what needs no 3D answer:
        # the peak convergence and the two 2D solves below (_SideProcess).
        s3, side = study.solid_3d, None
        if s3.check and s3.converge_peak:
            side = _SideProcess.start()
            side.submit("peak", _peak_job_main, self, geom.params, _worse_direction(r))
            side.submit("analyses", _detail_analyses, self, geom)
        try:
            solid = self.solid_3d(geom, r, side) if s3.check else None
            got = side.get("analyses") if side is not None else None
        finally:
            if side is not None:
                side.close()
        check, small = got if got is not None else _detail_analyses(self, geom)
        if self.solve_st:
            # ST was computed from a solve at the reference thickness; solving again at ST
            # shows the proportionality (the stiffness must be the target to solver precision).
            # (one direction suffices to show it; torques scale with ST in both).
            assert check is not None
            info["thickness_solved"] = {
                "ST_mm": st,
                "ccw_stiffness_scaled_from_reference_Nm_per_rad": r.stiffness_Nm_per_rad,
                "ccw_stiffness_resolved_at_ST_Nm_per_rad": check.stiffness_Nm_per_rad,
                "ccw_peak_stress_resolved_at_ST_MPa": float(check.peak_stress_MPa[-1]),
            }
        table = _curve_table(r)
        volume = geom.volume_mm3
        mass = geom.mass_kg(self.material.density_kg_m3)
        disc_cm3 = math.pi * (0.5 * study.geometry.envelope_diameter_mm) ** 2 * p.thickness_mm
        disc_cm3 *= 1e-3
        k_mean = r.mean_stiffness_Nm_per_rad
        info.update(
            {
                "stiffness_Nm_per_rad": k_mean,
                "stiffness_ccw_Nm_per_rad": r.stiffness_Nm_per_rad,
                "stiffness_cw_Nm_per_rad": r.reverse_stiffness_Nm_per_rad,
                "stiffness_error_percent": (k_mean / self.k_target - 1) * 100,
                "peak_stress_MPa": r.worst_peak_stress_MPa,
                "peak_stress_ccw_xy_mm": r.peak_stress_xy_mm[-1].tolist(),
                "allowable_stress_MPa": study.target.allowable_stress_MPa,
                "stress_ok": bool(r.worst_peak_stress_MPa <= study.target.allowable_stress_MPa),
                "linear_vs_nonlinear": {
                    "at_1_deg_percent": (
                        small.stiffness_Nm_per_rad / small.linear_stiffness_Nm_per_rad - 1
                    )
                    * 100,
                    "at_design_percent": (
                        r.stiffness_Nm_per_rad / r.linear_stiffness_Nm_per_rad - 1
                    )
                    * 100,
                },  # fmt: skip
                "outer_diameter_mm": 2 * geom.checks["outer_radius_mm"],
                "thickness_mm": p.thickness_mm,
                "mass_g": mass * 1e3,
                "volume_mm3": volume,
                "stiffness_per_volume_Nm_per_rad_cm3": k_mean / (volume * 1e-3),
                "stiffness_per_disc_volume_Nm_per_rad_cm3": k_mean / disc_cm3,
                "torque_per_disc_volume_Nm_per_cm3": study.target.torque_Nm / disc_cm3,
                "max_torque_per_mass_Nm_per_kg": study.target.torque_Nm / mass,
                "checks": geom.checks,
                "slot_gaps_mm": r.slot_gaps_mm,
                "mesh": {"dofs": r.n_dofs, "triangles": r.n_triangles},
                "published_springs": _published_comparison(),
            }
        )
        height_mm, part_outline = p.thickness_mm, geom.outline
        if solid is not None:
            info["solid_3d"] = solid
            info.update(solid_3d_scalars(info["solid_3d"]))
            # the part to make is the corrected one (its STL, DXF, footprint)
            height_mm = info["solid_3d"].get("ST_after_mm", height_mm)
            if "problem" not in solid.get("peak_convergence", {"problem": ""}):
                # ... and the outline whose peak stress converged (issue 22): its arms sampled
                # every curve_step_mm, not the optimiser's facets (on those the peak is higher)
                part_outline = _fine_geometry(self, geom.params).outline
        smap = _stress_map_data(r)
        tol = study.target.tolerance_percent / 100.0 * study.target.torque_Nm
        plot = {
            "x": "rotation_deg",
            "y": "torque_Nm",
            "stress": "peak_stress_MPa",
            "target": study.target.torque_Nm,
            "tolerance": tol,
            # the band where the design torque must be met: near +theta_T
            "band_x": [0.9 * math.degrees(self.theta), math.degrees(self.theta)],
            "allowable_MPa": study.target.allowable_stress_MPa,
            "xlabel": "hub rotation (deg)",
            "ylabel": "torque on the hub (N m)",
        }
        field_map = None
        if smap:
            field_map = {
                "points_mm": smap["points_mm"],
                "triangles": smap["triangles"],
                "values": smap["von_mises_MPa"],
                "label": "von Mises stress at +theta_T, counter-clockwise (MPa)",
                "limit": study.target.allowable_stress_MPa,
            }
        return DesignDetail(
            evaluation=evaluation,
            table=table,
            plot=plot,
            outline=part_outline,
            height_mm=height_mm,
            info=info,
            field_map=field_map,
            files=files,
        )

    @no_numpy_hugepages  # the 3D model's arrays (pipeline/_hugepages.py)
    def solid_3d(
        self, geom: SpringGeometry, r: SpringResponse, side: _SideProcess | None = None
    ) -> dict[str, Any]:
        """The design as a 3D solid, its thickness corrected for it, its peak stress converged
        (issue 15; docs/solid3d.md; the study's ``solid_3d:`` block).

        1. **3D check** (:func:`fea.solid3d.compare_with_plane_stress`): the plane mesh of the
           2D model extruded to ST (P2 tetrahedra, half the thickness, hub turned rigidly, pads
           held through the thickness), linear at theta_T, beside linear plane stress on the
           same mesh. The stiffness ratio multiplies each direction's nonlinear 2D stiffness, the
           vertex-averaged peak-stress ratio the 2D peak: the ratio is a property of the
           cross-sections, the same at 1 and 11 degrees (issue 15: 1.022 by CalculiX, both).
        2. **Correction** (``correct``, :func:`fea.solid3d.correct_thickness_3d`): when the
           ratio is off 1 by more than ``max_fraction_of_tolerance`` of the band, ST becomes
           ST x K_target / mean K_3D (plane stress is linear in ST, so the 2D answers scale
           exactly) and is checked in 3D again, until both directions are in the band and the
           mean is centred, the spread of the directions makes the band unreachable, or
           ``max_checks`` checks were made. The part is the last checked ST.
        3. **Converged peak** (``converge_peak``, :func:`fea.solid3d.converge_peak_stress`):
           the outline rebuilt with its arms sampled every ``curve_step_mm``, the plane mesh
           refined at the peak of the worse direction (nonlinear) until it moves < 1 %; the 3D
           peak is that value times the last check's 3D/2D peak ratio. The optimiser's outline
           is left as it is (its 1.4 deg facets cost nothing in the GA and the stress
           objective only ranks designs; finer sampling would triple its triangles), but the
           part exported (:meth:`detail`'s outline: STL, DXF, STEP) is the finely sampled one
           whose peak converged (issue 22).

        Cost (docs/solid3d.md): the checks share one 3D model (:class:`fea.solid3d.Solid3DModel`:
        the mesh extruded and assembled once, ST only scales its parts; the first check
        factorises, the re-checks solve by conjugate gradients preconditioned with that
        factor); the peak convergence, which needs no 3D answer until its last product, runs
        meanwhile in a second process (``side``'s "peak" task when the caller started one,
        else its own).

        Returns
        -------
        dict — N m/rad, MPa, mm, s; ``problem`` alone when the 3D model cannot be built.
        """
        from flexopt.fea.solid3d import Solid3DModel, Solid3DSettings, correct_thickness_3d

        spec, target, s3 = self.study.mesh, self.study.target, self.study.solid_3d
        t0 = time.perf_counter()
        st0 = float(geom.thickness_mm)
        ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)
        clamp = Clamp(geom.pad_region)
        regions = geom.mesh_regions(spec.elements_through, spec.max_edge_mm)
        k2d = {"ccw": r.stiffness_Nm_per_rad}
        if math.isfinite(r.reverse_stiffness_Nm_per_rad):
            k2d["cw"] = r.reverse_stiffness_Nm_per_rad
        peak2d = r.worst_peak_stress_MPa  # plane stress: independent of ST
        # the 2D peak convergence needs none of the 3D answers: the second core does it
        own = side is None and s3.converge_peak
        if own:
            side = _SideProcess.start()
            side.submit("peak", _peak_job_main, self, geom.params, _worse_direction(r))
        model: Solid3DModel | None = None

        def check(st: float) -> dict[str, Any]:
            assert model is not None
            c = model.compare_with_plane_stress(st)
            ratio = c["stiffness_ratio"]
            k2 = {d: k * st / st0 for d, k in k2d.items()}  # torque is proportional to ST
            return {
                "stiffness_3d": {d: k * ratio for d, k in k2.items()},
                "stiffness_2d": k2,
                "stiffness_ratio_3d_2d": ratio,
                "peak_stress_ratio_3d_2d": c["peak_stress_ratio"],
                "linear_stiffness_2d_Nm_per_rad": c["stiffness_2d"] * 1e-3,
                "linear_stiffness_3d_Nm_per_rad": c["stiffness_3d"] * 1e-3,
                "peak_stress_3d_MPa": peak2d * c["peak_stress_ratio"],
                "dofs": c["solid3d"]["n_dofs"],
                "solver": c["solid3d"]["solver"],
                "iterations": c["solid3d"]["iterations"],
                "time_s": c["solid3d"]["times_s"]["total"] + c["time_2d_s"],
            }

        try:
            m = mesh_polygon(geom.fe_outline, spec.max_edge_mm, refine=regions)
            drive = Rotate(geom.hub_region, (0.0, 0.0), self.theta, 1)
            settings = Solid3DSettings(layers=s3.layers)
            model = Solid3DModel(m, self.material, clamp, drive, settings, stress_ignore=ignore)
            corr = correct_thickness_3d(
                check,
                st0,
                self.k_target,
                target.tolerance_percent,
                s3.max_fraction_of_tolerance if s3.correct else math.inf,
                s3.max_checks,
            )
        except FeaError as exc:
            if own:
                side.close()
            return {"problem": f"3D check not made: {exc}"}
        except BaseException:
            if own:
                side.close()
            raise
        finally:
            model = None  # its factor holds ~2 GB
        checks = []
        for c in corr["checks"]:
            row = {"ST_mm": c["thickness_mm"], "stiffness_ratio_3d_2d": c["stiffness_ratio_3d_2d"]}
            for d in k2d:
                row[f"stiffness_{d}_2d_Nm_per_rad"] = c["stiffness_2d"][d]
                row[f"stiffness_{d}_3d_Nm_per_rad"] = c["stiffness_3d"][d]
                row[f"error_{d}_3d_percent"] = c["stiffness_error_percent"][d]
            row.update(
                {
                    "in_band": c["in_band"],
                    "peak_stress_ratio_3d_2d": c["peak_stress_ratio_3d_2d"],
                    "peak_stress_3d_MPa": c["peak_stress_3d_MPa"],
                    "dofs": c["dofs"],
                    "solver": c["solver"],
                    "iterations": c["iterations"],
                    "time_s": c["time_s"],
                }
            )
            checks.append(row)
        last = corr["checks"][-1]
        band = corr["band"]
        out: dict[str, Any] = {
            "method": "linear 3D / linear plane stress on the same plane mesh, applied to the "
            "nonlinear 2D answers; ST corrected by the 3D/2D ratio and re-checked in 3D",
            "corrected": corr["corrected"],
            "ST_before_mm": corr["thickness_before_mm"],
            "ST_after_mm": corr["thickness_after_mm"],
            "stopped": corr["stopped"],
            "checks": checks,
            "stiffness_ratio_3d_2d": last["stiffness_ratio_3d_2d"],
            "peak_stress_ratio_3d_2d": last["peak_stress_ratio_3d_2d"],
        }
        for d in k2d:
            out[f"stiffness_{d}_3d_Nm_per_rad"] = last["stiffness_3d"][d]
            out[f"stiffness_error_{d}_3d_percent"] = last["stiffness_error_percent"][d]
        out.update(
            {
                "stiffness_band_Nm_per_rad": [
                    self.k_target * (1 - target.tolerance_percent / 100),
                    self.k_target * (1 + target.tolerance_percent / 100),
                ],
                "stiffness_ok_3d": corr["in_band"],
                "stiffness_spread_3d_percent": band["spread_percent"],
                "max_spread_percent": band["max_spread_percent"],
                "band_reachable": band["reachable"],
                "peak_stress_2d_MPa": peak2d,
                "peak_stress_3d_MPa": last["peak_stress_3d_MPa"],
                "allowable_stress_MPa": target.allowable_stress_MPa,
                "dofs": last["dofs"],
                "solver": last["solver"],
                "time_3d_s": time.perf_counter() - t0,
            }
        )
        if s3.converge_peak:
            out["peak_convergence"] = self._converged_peak(
                geom, r, last["peak_stress_ratio_3d_2d"], side
            )
            if own:
                side.close()
            conv = out["peak_convergence"]
            if "problem" not in conv:
                out["peak_stress_3d_MPa"] = conv["peak_stress_3d_MPa"]
        out["stress_ok_3d"] = bool(out["peak_stress_3d_MPa"] <= target.allowable_stress_MPa)
        out["time_s"] = time.perf_counter() - t0
        return out

    def _converged_peak(
        self,
        geom: SpringGeometry,
        r: SpringResponse,
        ratio_3d_2d: float,
        side: _SideProcess | None = None,
    ) -> dict[str, Any]:
        """The 2D peak of the worse direction on a finely sampled outline, refined until it
        moves < 1 % (:func:`fea.solid3d.converge_peak_stress`), and the 3D peak from it.

        ``side``: a second process already computing it (its "peak" task); without one (or if
        that process could not run it) it runs here."""
        s3 = self.study.solid_3d
        t0 = time.perf_counter()
        sign = _worse_direction(r)
        try:
            c = side.get("peak") if side is not None else None
            ran = c is not None
            if c is None:
                c = _peak_convergence(self, geom.params, sign)
        except (FeaError, GeometryError) as exc:
            return {"problem": f"peak-stress convergence not made: {exc}"}
        return {
            "direction": "ccw" if sign > 0 else "cw",
            "curve_step_mm": s3.curve_step_mm,
            "converged": c["converged"],
            "status": c["status"],
            "last_two_MPa": c["last_two_MPa"],
            "peaks_MPa": c["peaks_MPa"],
            "local_edge_mm": c["local_edge_mm"],
            "peak_xy_mm": c["peak_xy_mm"],
            "corner": c["corner"],
            "peak_stress_2d_MPa": c["last_two_MPa"][-1],
            "peak_stress_3d_MPa": c["last_two_MPa"][-1] * ratio_3d_2d,
            # the convergence's own time (in the second process, beside the 3D checks) and
            # how long the report waited for it here
            "time_s": c["time_s"],
            "wait_s": time.perf_counter() - t0,
            "process": "second" if ran else "this",
        }


def _worse_direction(r: SpringResponse) -> float:
    """+1 (ccw) or -1 (cw): the direction of the larger 2D peak stress."""
    rev = r.reverse_peak_stress_MPa
    return -1.0 if rev is not None and float(rev[-1]) > float(r.peak_stress_MPa[-1]) else 1.0


def _peak_convergence(
    prob: SeaSpringProblem, params: SpringParams | ArmSpringParams, sign: float
) -> dict[str, Any]:
    """:func:`fea.solid3d.converge_peak_stress` on the design rebuilt with its arms sampled
    every ``solid_3d.curve_step_mm``, nonlinear, hub turned by ``sign`` theta_T (picklable:
    :class:`_SideProcess` runs it in a second process). Raises FeaError, GeometryError."""
    from flexopt.fea.solid3d import converge_peak_stress

    spec = prob.study.mesh
    smooth = _fine_geometry(prob, params)
    return converge_peak_stress(
        smooth.fe_outline, smooth.thickness_mm, prob.material, Clamp(smooth.pad_region),
        Rotate(smooth.hub_region, (0.0, 0.0), sign * prob.theta, 1), spec.max_edge_mm,
        refine=smooth.mesh_regions(spec.elements_through, spec.max_edge_mm),
        stress_ignore=smooth.hub_region.union(smooth.pad_region).buffer(0.05),
        kinematics="nonlinear",
    )  # fmt: skip


def _fine_geometry(
    prob: SeaSpringProblem, params: SpringParams | ArmSpringParams
) -> SpringGeometry:
    """The design as the peak-stress convergence meshes it and as its part is exported: the
    arms sampled every ``solid_3d.curve_step_mm`` (the serpentine's arcs also at 0.25 deg).
    Raises GeometryError."""
    s3 = prob.study.solid_3d
    if isinstance(params, ArmSpringParams):
        return build_arm_spring(params, prob.frame, curve_step_mm=s3.curve_step_mm)
    frame = replace(prob.frame, arc_step_deg=0.25, arc_step_mm=s3.curve_step_mm)
    return build_spring(params, frame)


def _peak_job_main(prob: SeaSpringProblem, params: Any, sign: float) -> dict[str, Any]:
    """The side process's peak convergence (module level: the pool pickles it by name)."""
    return _peak_convergence(prob, params, sign)


def _detail_analyses(
    prob: SeaSpringProblem, geom: SpringGeometry
) -> tuple[SpringResponse | None, SpringResponse]:
    """The detail's two extra 2D solves: the design re-solved at its ST (solve mode only; it
    shows the proportionality) and at 1 degree (the linear-vs-nonlinear row)."""
    spec = prob.study.mesh
    check = analyse_spring(geom, prob.material, prob.theta, spec) if prob.solve_st else None
    return check, analyse_spring(geom, prob.material, math.radians(1.0), spec)


def _side_main(conn: Any) -> None:
    """The side process: run the tasks it is sent, one after the other, until told to stop
    (None), its pipe closes or its parent is gone. Starts as pipeline.parallel's workers."""
    import os
    import signal

    from flexopt.pipeline.parallel import PARENT_CHECK_S, _limit_loaded_pools, pin_threads

    pin_threads()  # one BLAS thread: the first process factorises beside it
    _limit_loaded_pools()
    # Ctrl-C reaches the whole process group: the first process decides (and ends this one);
    # a forked child inherits the CLI's SIGTERM handler, but is ended by its parent and must
    # then end at once, as a process normally does
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    parent = os.getppid()
    while True:
        try:
            while not conn.poll(PARENT_CHECK_S):
                if os.getppid() != parent:  # orphaned (a forked copy of the pipe stays open)
                    return
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        name, func, args = task
        try:
            out: tuple[str, Any] = ("ok", func(*args))
        except Exception as exc:
            out = ("error", exc)
        try:
            conn.send((name, out))
        except Exception as exc:  # a result or an exception that does not pickle
            conn.send((name, ("error", RuntimeError(f"{type(exc).__name__}: {exc}"))))


class _SideProcess:
    """One worker process for the report's work that needs no 3D answer.

    The 3D checks keep this process busy (assembly, one factorisation, triangular solves);
    the peak convergence (nonlinear plane-stress solves on refined meshes, ~10 s CPU on the
    default study) and the detail's two extra 2D solves depend only on the design, so they
    run beside them on the second core. Where a process cannot be started (a daemonic
    worker), or dies or fails on a task, :meth:`get` gives None and the caller computes it
    itself; FeaError and GeometryError of a task come back raised.
    """

    def __init__(self, process: Any = None, conn: Any = None) -> None:
        self._process, self._conn = process, conn
        self._sent: set[str] = set()
        self._results: dict[str, tuple[str, Any]] = {}

    @classmethod
    def start(cls) -> _SideProcess:
        try:
            from flexopt.pipeline.parallel import _context

            ctx = _context()
            conn, child_conn = ctx.Pipe()
            process = ctx.Process(target=_side_main, args=(child_conn,), daemon=True,
                                  name="flexopt-report-side")  # fmt: skip
            process.start()
            child_conn.close()
            return cls(process, conn)
        except Exception as exc:  # no second process here: the callers compute in this one
            log.info("report work in this process only (%s)", exc)
            return cls()

    def submit(self, name: str, func: Any, *args: Any) -> None:
        if self._conn is None:
            return
        try:
            self._conn.send((name, func, args))
            self._sent.add(name)
        except Exception as exc:  # an argument that does not pickle: computed here
            log.info("report task %s stays in this process (%s)", name, exc)

    def get(self, name: str) -> Any:
        """The task's result, or None when the caller must compute it."""
        if name not in self._sent:
            return None
        self._sent.discard(name)
        from flexopt.pipeline.parallel import PARENT_CHECK_S

        try:
            while name not in self._results:
                if self._conn.poll(PARENT_CHECK_S):
                    done, out = self._conn.recv()
                    self._results[done] = out
                elif not self._process.is_alive():
                    raise RuntimeError(f"it ended (exit code {self._process.exitcode})")
        except Exception as exc:  # died (killed, out of memory) or a broken pipe
            log.warning("report task %s: the second process failed (%s); redone here", name,
                        exc)  # fmt: skip
            self.close()
            return None
        status, value = self._results.pop(name)
        if status == "ok":
            return value
        if isinstance(value, FeaError | GeometryError):
            raise value
        log.warning("report task %s failed in the second process (%s); redone here", name,
                    value)  # fmt: skip
        return None

    def close(self) -> None:
        """Stop the process (at once: a result not fetched is not needed)."""
        if self._process is not None:
            self._process.terminate()
            self._process.join(5.0)
            if self._process.is_alive():
                self._process.kill()
                self._process.join()
            self._conn.close()
        self._process = self._conn = None
        self._sent.clear()


def solid_3d_scalars(s3: dict[str, Any]) -> dict[str, Any]:
    """The scalars of :meth:`SeaSpringProblem.solid_3d` the verdict judges (info / summary)."""
    keys = (
        "stiffness_ccw_3d_Nm_per_rad", "stiffness_cw_3d_Nm_per_rad", "peak_stress_3d_MPa",
        "stiffness_spread_3d_percent", "stiffness_ratio_3d_2d",
    )  # fmt: skip
    out = {k: s3[k] for k in keys if k in s3}
    if "ST_after_mm" in s3:
        out["ST_3d_mm"] = s3["ST_after_mm"]
    conv = s3.get("peak_convergence") or {}
    if "converged" in conv:
        out["peak_stress_converged"] = conv["converged"]
    return out


_GEOMETRY_CONSTRAINTS = ("envelope_mm", "thinnest_mm", "slot_mm", "link_reach_mm")
_SPIRAL_CONSTRAINTS = ("envelope_mm", "thinnest_mm", "slot_mm", "hub_mm")


def _curve_table(r: SpringResponse) -> dict[str, np.ndarray]:
    """Torque-rotation rows, clockwise (negative) rows first when there are any."""
    rot, torque, stress = r.rotation_deg, r.torque_Nm, r.peak_stress_MPa
    if r.reverse_torque_Nm is not None:
        rot = np.concatenate([-rot[:0:-1], rot])
        torque = np.concatenate([r.reverse_torque_Nm[:0:-1], torque])
        stress = np.concatenate([r.reverse_peak_stress_MPa[:0:-1], stress])
    return {
        "rotation_deg": rot,
        "torque_Nm": torque,
        "torque_linear_Nm": r.linear_stiffness_Nm_per_rad * np.radians(rot),
        "peak_stress_MPa": stress,
    }


def _stage1_summary(stage1: dict[str, Any]) -> dict[str, Any]:
    keys = (
        "array", "topology", "torque_Nm", "target_rotation_deg", "cost", "runs", "anova",
        "main_effects", "best_values",
        "predicted_sn_dB", "confirmation", "additivity", "best_run", "chosen", "time_s",
    )  # fmt: skip
    return {k: stage1[k] for k in keys if k in stage1}


def _published_comparison() -> list[dict[str, Any]]:
    rows = []
    for s in PUBLISHED_SPRINGS:
        t, d = s["thickness_mm"], s["diameter_mm"]
        vol = math.pi * (0.5 * d) ** 2 * t * 1e-3 if t and d else None  # cm^3, full disc
        rows.append(
            {
                **s,
                "stiffness_per_disc_volume_Nm_per_rad_cm3": (
                    s["stiffness_Nm_per_rad"] / vol if vol else None
                ),
                "torque_per_disc_volume_Nm_per_cm3": s["torque_Nm"] / vol if vol else None,
            }
        )
    return rows


def stress_map_png(stress_map: dict[str, Any], allowable_MPa: float | None = None,
                   title: str = "") -> bytes:  # fmt: skip
    """PNG of a von Mises map of :func:`_stress_map_data` (``flexopt run`` draws the same map
    from ``DesignDetail.field_map`` as ``stress_map.png``)."""
    from flexopt.pipeline.plots import plot_field

    return plot_field(
        stress_map["points_mm"],
        stress_map["triangles"],
        stress_map["von_mises_MPa"],
        limit=allowable_MPa,
        title=title or "von Mises stress at the design torque",
    )


# --------------------------------------------------------------------------------------------
# Registry hooks


def requirements(study: SeaSpringStudy) -> list[Requirement]:
    """:func:`_builtin.sea_spring`, ST (solved or searched) inside its range (issue 22):
    ``design_space.ST``, judged on the exported ST (the 3D correction's, see :data:`FIGURES`),
    and the thinnest printed size (member or plate) at least ``geometry.min_feature_mm``."""
    space = design_space(study)
    i = variables(study).index("ST")
    lo, hi = float(space.lower[i]), float(space.upper[i])
    return [
        *_builtin.sea_spring(study),
        Range("ST_mm", "plate thickness ST in its range", "constraint", lo, hi),
        MinFeature("min_feature_mm", "printable feature", "constraint",
                   study.geometry.min_feature_mm),
    ]  # fmt: skip


#: The figures of a quantity by model (pipeline.verdict): ST as exported is the 3D correction's
#: where the run made one. The 3D stiffness and peak have rows of their own
#: (:func:`_builtin.sea_spring`), so the 2D rows keep the plane-stress figures.
FIGURES = {
    "ST_mm": (
        Figure("ST_mm", "plane-stress fit", PLANE_STRESS),
        Figure("ST_3d_mm", "3D correction", SOLID_3D),
    ),
}


def design_of(study: SeaSpringStudy) -> tuple[DesignSpace, np.ndarray]:
    """The space the problem moves in (ST left out when it is solved) and the study's
    ``design:`` in it, as given (what ``flexopt evaluate`` solves)."""
    space, names = design_space(study), variables(study)
    x = design_vector(study)
    if study.thickness != "solve":
        return space, x
    keep = [i for i in range(len(names)) if names[i] != "ST"]
    reduced = DesignSpace(tuple(space.names[i] for i in keep), space.lower[keep], space.upper[keep])
    return reduced, x[keep]


def problem(study: SeaSpringStudy) -> SeaSpringProblem:
    """The design problem ``flexopt run`` optimises (stage 1 runs here)."""
    return SeaSpringProblem(study)


def evaluate(study: SeaSpringStudy, repeat: int = 1) -> EvaluationResult:
    """``flexopt evaluate``: the torque curve of the study's ``design:`` (no Taguchi stage)."""
    prob = SeaSpringProblem(study, stage1={})
    x = design_vector(study)
    if prob.solve_st:  # ST follows from the target (the design's ST is ignored)
        x = np.delete(x, prob.names.index("ST"))
    times = []
    r = geom = p = None
    st = math.nan
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        try:
            p, geom, r, st = prob.solve(x, study.mesh.curve_steps, keep_model=True)
        except (GeometryError, FeaError) as exc:
            raise StudyError("design", str(exc)) from exc
        times.append(time.perf_counter() - t0)
    assert r is not None and geom is not None and p is not None
    table = _curve_table(r)
    summary = {
        "ST_mm": st,
        "stiffness_Nm_per_rad": r.mean_stiffness_Nm_per_rad,
        "stiffness_ccw_Nm_per_rad": r.stiffness_Nm_per_rad,
        "stiffness_cw_Nm_per_rad": r.reverse_stiffness_Nm_per_rad,
        "linear_stiffness_Nm_per_rad": r.linear_stiffness_Nm_per_rad,
        "stiffness_error_percent": (r.mean_stiffness_Nm_per_rad / prob.k_target - 1) * 100,
        "asymmetry_percent": abs(r.stiffness_Nm_per_rad / r.mean_stiffness_Nm_per_rad - 1) * 100,
        "peak_stress_MPa": r.worst_peak_stress_MPa,
        "stress_yield_ratio": r.worst_peak_stress_MPa / prob.material.yield_MPa,
        "stress_allowable_ratio": r.worst_peak_stress_MPa / study.target.allowable_stress_MPa,
        "mass_g": geom.mass_kg(prob.material.density_kg_m3) * 1e3,
        "outer_diameter_mm": 2 * geom.checks["outer_radius_mm"],
        # the thinnest printed size: the thinnest member or the plate (as flexopt run's metric)
        "min_feature_mm": min(
            margins(p, prob.frame)["thinnest_mm"] + prob.frame.min_feature_mm, st
        ),
    }
    if r.slot_gaps_mm:
        summary["slot_mm"] = r.slot_gaps_mm["undeformed"]
        summary["deformed_slot_mm"] = min(v for k, v in r.slot_gaps_mm.items() if k != "undeformed")
    diagnostics: dict[str, Any] = {}
    if study.solid_3d.check:
        diagnostics["solid_3d"] = prob.solid_3d(geom, r)
        summary.update(solid_3d_scalars(diagnostics["solid_3d"]))
    # the part as exported: the outline extruded by ST (the 3D-corrected one where made)
    depth = diagnostics.get("solid_3d", {}).get("ST_after_mm", st)
    summary.update(envelope_values(geom.outline, depth))
    return EvaluationResult(
        table=table,
        summary=summary,
        converged=r.ok,
        message=r.message,
        solve_times_s=tuple(times),
        inputs={"material": material_record(prob.material), "n_sets": prob.n_sets},
        diagnostics={
            "dofs": r.n_dofs,
            "triangles": r.n_triangles,
            "newton": r.iterations,
            **diagnostics,
        },
        plot={
            "x": "rotation_deg",
            "left": "torque_Nm",
            "right": "peak_stress_MPa",
            "allowable_MPa": study.target.allowable_stress_MPa,
            # the target stiffness as a torque line K theta, with its band
            "target_curve": {
                "x": table["rotation_deg"],
                "y": prob.k_target * np.radians(table["rotation_deg"]),
            },
            "tolerance_rel": study.target.tolerance_percent / 100.0,
            "target_label": f"target K θ, K = {prob.k_target:g} N·m/rad",
        },  # fmt: skip
        headline=tuple(summary),
    )


register(
    StudyKind(
        "sea_spring",
        SeaSpringStudy,
        check,  # type: ignore[arg-type]
        evaluate,  # type: ignore[arg-type]
        problem,  # type: ignore[arg-type],
        requirements=requirements,
        quantities=_builtin.SEA_SPRING,
        figures=FIGURES,
        design_space=design_of,
    )
)
