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
from flexopt.fea.sea_design import (
    PUBLISHED_SPRINGS,
    SpringTopology,
    correct_3d,
    fine_geometry,
    peak_convergence,
    published_comparison,
    screen_spring,
    solve_for_stiffness,
    spring_margins,
    taguchi_seed,
    worse_direction,
)
from flexopt.fea.sea_design import build_any as build
from flexopt.fea.spring_analysis import SpringResponse, analyse_spring, curve_table
from flexopt.fea.spring_analysis import stress_map_data as _stress_map_data
from flexopt.geometry.arm_spring import ArmSpringParams
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import SpringFrame, SpringGeometry, SpringParams
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
from flexopt.optimise.sea_cost import (
    levels_to_values,
    screening_plan,
    solid_3d_scalars,
    spring_scores,
    stage1_summary,
    taguchi_analysis,
)
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline._hugepages import no_numpy_hugepages
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.screening import Screening, SideProcess, one_blas_thread
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
    "design_space",
    "target_stiffness_Nm_per_rad",
    "problem",
    "evaluate",
    "check",
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
            build(topology(study).params(x, n_sets, frame), frame)
        except GeometryError as exc:
            raise StudyError("design", str(exc)) from exc
    target_stiffness_Nm_per_rad(study)


# --------------------------------------------------------------------------------------------
# Stage 1: Taguchi L25 (paper section 5, Tables 6-8)


def _screen_one(
    levels: tuple[int, ...], frame: SpringFrame, material: Material, study: SeaSpringStudy
) -> tuple[float, float, str]:
    """(stiffness N m/rad, peak stress per radian MPa/rad, reason) of one level combination:
    :func:`fea.sea_design.screen_spring`."""
    topo = topology(study)
    return screen_spring(levels_to_values(levels, topo.levels), topo, frame, material, study.mesh)


#: Stage 1 solves its screening runs in two processes where fork is available (this one and a
#: forked child, each on one core); False: all in this process, in order. The results are the
#: same bit for bit (each run is an independent solve; tests/pipeline/test_sea_spring_stage1.py).
TAGUCHI_FORK = True


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
    t0 = time.perf_counter()
    frame = spring_frame(study)
    material = study.material.to_material()
    k_target, _ = target_stiffness_Nm_per_rad(study)
    torque = study.taguchi.torque_Nm or study.target.torque_Nm / 5.0
    theta_t = math.degrees(torque / k_target)
    table, spec = topology(study).levels, study.taguchi
    lay, extra, jobs = screening_plan(table, spec.extra_runs, spec.seed)
    n_array = len(lay.design)
    # solved by this process and a forked child beside it (pipeline.screening)
    screening = Screening(
        jobs, lambda levels: _screen_one(levels, frame, material, study), fork=TAGUCHI_FORK,
        label="stage 1", name="flexopt-taguchi",
    )  # fmt: skip
    try:
        runs = screening.get(n_array)
        # the confirmation run solved here while the child goes on with the extra runs
        stage1 = taguchi_analysis(
            lay, table, runs, extra, screening.solve,
            lambda: screening.get(len(screening.jobs))[n_array:], torque, theta_t,
            spec.pool_below_percent, spec.min_error_dof, study.geometry.topology,
        )  # fmt: skip
    finally:
        screening.close()
    stage1["time_s"] = time.perf_counter() - t0  # wall time of the whole stage
    return stage1


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
        self.geometry_constraints = topology(study).constraints
        self.constraint_names = (*self.geometry_constraints, *extra)
        if stage1 is None and study.taguchi.enabled:
            # One BLAS thread, as in the pool's workers: CHOLMOD's supernodes of a 30k-DOF
            # spring are too small for a second thread to pay (the 31 screening runs took
            # ~4.7 s CPU / 3.8 s wall with two threads, 3.3 s both with one; same answers).
            with one_blas_thread():
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
        return topology(self.study).params(self.full_vector(x, st_mm), self.n_sets, self.frame)

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
            x = self.full_space.clip(
                taguchi_seed(self.stage1["chosen"], self.frame, self.n_arcs, self.topology)
            )
        elif self.study.design is not None:
            x = self.full_space.clip(design_vector(self.study))
        else:
            return None
        if self.solve_st:
            x = np.delete(x, self.names.index("ST"))
        return x[None, :]

    def _margins_g(self, p: SpringParams | ArmSpringParams) -> np.ndarray:
        m = spring_margins(p, self.frame)
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
        scale, st = solve_for_stiffness(
            p.thickness_mm, r.mean_stiffness_Nm_per_rad, self.k_target, self.held_st_mm
        )
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
        target = self.study.target
        f, g, metrics = spring_scores(
            r,
            mass_g=geom.mass_kg(self.material.density_kg_m3) * 1e3,
            st_mm=st,
            g_geo=g_geo,
            thinnest_index=self.geometry_constraints.index("thinnest_mm"),
            min_feature_mm=self.frame.min_feature_mm,
            target_Nm_per_rad=self.k_target,
            st_range_mm=self.st_range if self.solve_st else None,
            tolerance_percent=target.tolerance_percent,
            max_asymmetry_percent=target.max_asymmetry_percent,
            min_slot_mm=self.min_gap,
        )
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
            info["taguchi"] = stage1_summary(self.stage1)
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
        # the peak convergence and the two 2D solves below (SideProcess).
        s3, side = study.solid_3d, None
        if s3.check and s3.converge_peak:
            side = SideProcess.start()
            side.submit("peak", _peak_job_main, self, geom.params, worse_direction(r))
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
        table = curve_table(r)
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
                "published_springs": published_comparison(),
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
        self, geom: SpringGeometry, r: SpringResponse, side: SideProcess | None = None
    ) -> dict[str, Any]:
        """The design as a 3D solid, its thickness corrected for it, its peak stress converged
        (issue 15; docs/solid3d.md; the study's ``solid_3d:`` block): :func:`fea.sea_design.
        correct_3d`. The peak convergence, which needs no 3D answer, runs meanwhile in a second
        process (``side``'s "peak" task when the caller started one, else its own); without
        one (or if that process could not run it) it runs here.

        Returns
        -------
        dict — N m/rad, MPa, mm, s; ``problem`` alone when the 3D model cannot be built.
        """
        s3, target = self.study.solid_3d, self.study.target
        sign = worse_direction(r)
        own = side is None and s3.converge_peak
        if own:
            side = SideProcess.start()
            side.submit("peak", _peak_job_main, self, geom.params, sign)

        def converged_peak() -> tuple[dict[str, Any], bool]:
            c = side.get("peak") if side is not None else None
            if c is None:
                return _peak_convergence(self, geom.params, sign), False
            return c, True

        try:
            return correct_3d(
                geom, r, self.material, self.theta, self.k_target, target.tolerance_percent,
                target.allowable_stress_MPa, self.study.mesh, s3, converged_peak,
            )  # fmt: skip
        finally:
            if own:
                side.close()


def _peak_convergence(
    prob: SeaSpringProblem, params: SpringParams | ArmSpringParams, sign: float
) -> dict[str, Any]:
    """:func:`fea.sea_design.peak_convergence` of a design of ``prob`` (the worse direction
    ``sign``). Raises FeaError, GeometryError."""
    return peak_convergence(
        params, prob.frame, prob.material, prob.theta, sign, prob.study.mesh,
        prob.study.solid_3d.curve_step_mm,
    )  # fmt: skip


def _fine_geometry(
    prob: SeaSpringProblem, params: SpringParams | ArmSpringParams
) -> SpringGeometry:
    """:func:`fea.sea_design.fine_geometry`: the outline the peak converged on, exported."""
    return fine_geometry(params, prob.frame, prob.study.solid_3d.curve_step_mm)


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
    table = curve_table(r)
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
            spring_margins(p, prob.frame)["thinnest_mm"] + prob.frame.min_feature_mm, st
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
