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
   when a run first needs it (:meth:`SeaSpringProblem.initial_designs`, as ``flexopt run``
   sets up; 31 linear solves, under a minute), fixes RP for stage 2 and seeds its first
   population; its results are in ``detail().info["taguchi"]`` and ``taguchi.png``.
   ``flexopt evaluate`` (:meth:`SeaSpringProblem.result`) never runs it.
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
    contact: null                   # or {overload_deg: 36}: slot contact (docs/durability.md)

The study file's models and their reading (design space, target, the ``design:``) are
pipeline/studies/_sea_spring_schema.py.
"""

from __future__ import annotations

import contextlib
import copy
import math
import time
from typing import Any

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.sea_design import (
    PUBLISHED_SPRINGS,
    correct_3d,
    detail_solves,
    screen_spring,
    solve_spring,
    spring_margins,
    taguchi_seed,
    worse_direction,
)
from flexopt.fea.sea_design import build_any as build
from flexopt.fea.spring_analysis import SpringResponse, analyse_spring, curve_table
from flexopt.geometry.arm_spring import ArmSpringParams
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import SpringFrame, SpringGeometry, SpringParams
from flexopt.optimise.evaluation import INFEASIBLE_VALUE, Evaluation
from flexopt.optimise.problem import DesignProblem, DesignResult
from flexopt.optimise.requirements import (
    PLANE_STRESS,
    SOLID_3D,
    Figure,
    MinFeature,
    Range,
    Requirement,
)
from flexopt.optimise.sea_cost import (
    detail_values,
    evaluation_summary,
    levels_to_values,
    solid_3d_scalars,
    spring_scores,
    stage1_summary,
)
from flexopt.pipeline._hugepages import no_numpy_hugepages
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.fields import spring_field_map, take_solid_field
from flexopt.pipeline.screening import SideProcess, one_blas_thread, taguchi_stage
from flexopt.pipeline.studies import StudyKind, _builtin, register
from flexopt.pipeline.studies import _sea_spring_contact as slot_contact
from flexopt.pipeline.studies import _sea_spring_peak as peak
from flexopt.pipeline.studies._sea_spring_schema import (
    SeaSpringStudy,
    check,
    design_of,
    design_sets,
    design_space,
    design_vector,
    problem_space,
    spring_frame,
    target_stiffness_Nm_per_rad,
    topology,
    variables,
)
from flexopt.pipeline.study import material_record
from flexopt.pipeline.verdict import envelope_values

__all__ = [
    "PUBLISHED_SPRINGS",
    "SeaSpringStudy",
    "SeaSpringProblem",
    "SpringResponse",
    "analyse_spring",
    "build",
    "run_taguchi",
    "design_space",
    "target_stiffness_Nm_per_rad",
    "problem",
    "check",
]

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
    # solved by this process and a forked child beside it (pipeline.screening)
    stage1 = taguchi_stage(
        topology(study).levels, lambda levels: _screen_one(levels, frame, material, study),
        study.taguchi, torque, math.degrees(torque / k_target), study.geometry.topology,
        fork=TAGUCHI_FORK,
    )  # fmt: skip
    stage1["time_s"] = time.perf_counter() - t0  # wall time of the whole stage
    return stage1


# --------------------------------------------------------------------------------------------
# Stage 2: the design problem


class SeaSpringProblem(DesignProblem):
    """The NSGA-II problem of stage 2 (picklable; stage 1 runs on first use, :attr:`stage1`).

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

    ``stage1``: stage 1's results when known (``{}``: none); None runs it on first use when
    ``taguchi.enabled``.
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
        self.space = problem_space(study)  # ST left out when it is solved
        if self.solve_st:
            self.objective_names = ("peak_stress_MPa", "mass_g")
            extra: tuple[str, ...] = ("thickness_over_mm", "thickness_under_mm")
        else:
            self.objective_names = ("peak_stress_MPa", "stiffness_error_percent")
            extra = ("stiffness_band_percent",)
        if study.target.max_asymmetry_percent is not None:
            extra = (*extra, "asymmetry_percent")
        self.min_gap = study.geometry.min_deformed_slot_mm
        if self.min_gap is not None:
            extra = (*extra, "deformed_slot_mm")
        self.geometry_constraints = topology(study).constraints
        self.constraint_names = (*self.geometry_constraints, *extra)
        # Not run here: flexopt evaluate, export and the API build this problem and need none
        # of it. None: to be run (stage1).
        self._stage1 = stage1 if stage1 is not None or study.taguchi.enabled else {}
        # a robustness sample holds the nominal design's solved ST (hold_solved), mm
        self.held_st_mm: float | None = None

    @property
    def stage1(self) -> dict[str, Any]:
        """Stage 1's results (:func:`run_taguchi`; ``{}`` without it), run on first use: in a
        run, where it sets up (:meth:`initial_designs`), before its workers get the problem."""
        if self._stage1 is None:
            # One BLAS thread, as in the pool's workers: CHOLMOD's supernodes of a 30k-DOF
            # spring are too small for a second thread to pay (the 31 screening runs took
            # ~4.7 s CPU / 3.8 s wall with two threads, 3.3 s both with one; same answers).
            with one_blas_thread():
                self._stage1 = run_taguchi(self.study)
        return self._stage1

    @property
    def n_sets(self) -> int:
        """RP, the sets (arms) of every design: ``geometry.n_sets``, else stage 1's choice,
        else the study's ``design:`` (:func:`design_sets`)."""
        if self.study.geometry.n_sets:
            return int(self.study.geometry.n_sets)
        return int(self.stage1["chosen"]["RP"]) if self.stage1 else design_sets(self.study)

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
        return design_of(self.study)[1]  # as given: outside its range it is judged NOT MET

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
        """Build and analyse a design (:func:`fea.sea_design.solve_spring`: in solve mode at
        the reference thickness, then rescaled to the ST of the target or the held one);
        returns (params, geometry, response, ST mm). Raises GeometryError, FeaError."""
        return solve_spring(
            lambda st: self.params(x, st), self.frame, self.material, self.theta,
            self.study.mesh, steps, keep_model, self.study.target.directions == "both",
            keep_model or self.min_gap is not None, self.k_target if self.solve_st else None,
            self.held_st_mm,
        )  # fmt: skip

    # -- the contract ----------------------------------------------------------------------

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return self._evaluate(x)[0]

    def jacobian(self, x: np.ndarray) -> Any:
        """Exact derivatives (spiral, ``thickness: solve``; else None): _sea_spring_gradient.py."""
        from flexopt.pipeline.studies._sea_spring_gradient import sea_spring_jacobian

        return sea_spring_jacobian(self, x)

    def evaluate_response(self, x: np.ndarray) -> tuple[Evaluation, dict | None, str]:
        """The evaluation and the torque-rotation table of one solve, ``mesh.curve_steps`` rows
        per direction as the report's (a life constraint's stresses: verdict.LifeConstraints)."""
        ev, solved = self._evaluate(x, self.study.mesh.curve_steps)
        return ev, (None if solved is None else curve_table(solved[2])), "rotation_deg"

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
    def detail(self, x: np.ndarray) -> DesignResult:
        x = np.asarray(x, dtype=float)
        study = self.study
        plots = peak.start_taguchi_png(self.stage1, self.topology) if self.stage1 else None
        # One solve serves the evaluation and the curve (the last row is the design point);
        # taguchi.png is drawn meanwhile by a process of its own (_sea_spring_peak.py).
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
        if solved is None:
            peak.taguchi_png(plots, {}, self.topology)  # (its process closed)
            info["problem"] = evaluation.reason or "not buildable (see the constraints)"
            return DesignResult(evaluation, info=info)
        p, geom, r, st = solved
        info["design"] = dict(zip(self.names, map(float, self.full_vector(x, st)), strict=True))
        # 3D checks here, the peak convergence in a second process; 2D solves: peak.solves_here
        s3, side, got, here = study.solid_3d, SideProcess(), [], peak.solves_here(study.solid_3d)
        solves = (geom, self.material, self.theta, study.mesh, self.solve_st)
        if s3.check and s3.converge_peak:
            side = SideProcess.start()
            side.submit("peak", peak.peak_job, self, geom.params, worse_direction(r))
            if not here:
                side.submit("analyses", detail_solves, *solves)

        def meanwhile() -> None:  # after the 3D checks, before the wait for the peak
            with contextlib.suppress(FeaError, GeometryError):  # raised below, solved again
                got.extend([detail_solves(*solves)] if here else [])

        try:
            solid = self.solid_3d(geom, r, side, meanwhile) if s3.check else None
            got = got or [side.get("analyses")]
        finally:
            side.close()  # (a SideProcess() without a process: nothing)
        check, small = got[0] or detail_solves(*solves)
        if self.solve_st:
            # ST was computed from a solve at the reference thickness; solving again at ST shows
            # the proportionality (the target to solver precision; one direction shows it).
            assert check is not None
            info["thickness_solved"] = {
                "ST_mm": st,
                "ccw_stiffness_scaled_from_reference_Nm_per_rad": r.stiffness_Nm_per_rad,
                "ccw_stiffness_resolved_at_ST_Nm_per_rad": check.stiffness_Nm_per_rad,
                "ccw_peak_stress_resolved_at_ST_MPa": float(check.peak_stress_MPa[-1]),
            }
        target = study.target
        info.update(
            detail_values(
                r, small, geom, thickness_mm=p.thickness_mm,
                density_kg_m3=self.material.density_kg_m3, target_Nm_per_rad=self.k_target,
                torque_Nm=target.torque_Nm, allowable_MPa=target.allowable_stress_MPa,
                envelope_diameter_mm=study.geometry.envelope_diameter_mm,
            )
        )  # fmt: skip
        height_mm, part_outline = p.thickness_mm, geom.outline
        solid_field = take_solid_field(solid)  # best_3d.vtu's arrays, out of the record
        if solid is not None:
            info["solid_3d"] = solid
            info.update(solid_3d_scalars(info["solid_3d"]))
            # the part to make is the corrected one (its STL, DXF, footprint)
            height_mm = info["solid_3d"].get("ST_after_mm", height_mm)
            if "problem" not in solid.get("peak_convergence", {"problem": ""}):
                # ... and the outline whose peak stress converged (issue 22): its arms sampled
                # every curve_step_mm, not the optimiser's facets (on those the peak is higher)
                part_outline = peak.fine_geometry_of(self, geom.params).outline
        field_map = self._field_map(r)
        png = peak.taguchi_png(plots, self.stage1, self.topology) if self.stage1 else None
        files.update({"taguchi.png": png} if png is not None else {})
        plot = {
            "x": "rotation_deg",
            "y": "torque_Nm",
            "stress": "peak_stress_MPa",
            "target": target.torque_Nm,
            "tolerance": target.tolerance_percent / 100.0 * target.torque_Nm,
            # the band where the design torque must be met: near +theta_T
            "band_x": [0.9 * math.degrees(self.theta), math.degrees(self.theta)],
            "allowable_MPa": target.allowable_stress_MPa,
            "x_label": "hub rotation (deg)",
            "y_label": "torque on the hub (N m)",
        }
        return slot_contact.finish(self, geom, r, height_mm, DesignResult(
            evaluation=evaluation,
            table=curve_table(r),
            plot=plot,
            outline=part_outline,
            height_mm=height_mm,
            info=info,
            field_map=field_map,
            solid_field=solid_field,
            files=files,
        ))  # fmt: skip

    def _field_map(self, r: SpringResponse) -> dict[str, Any] | None:
        """The DesignResult's ``field_map``: every row's state of ``r`` (the model kept), the last
        on top (pipeline/fields.py); None without the model."""
        label = "von Mises stress at +theta_T, counter-clockwise (MPa)"
        return spring_field_map(r, label, self.study.target.allowable_stress_MPa)

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        """``flexopt evaluate``: the torque curve of the design ``x`` (n_var,) (the study's
        ``design:``, :meth:`nominal_design`), solved ``repeat`` times, with the study's sets
        (:func:`design_sets`): no Taguchi stage. The 3D check where ``solid_3d.check``.

        Raises
        ------
        StudyError
            At ``design`` when the design cannot be built or solved.
        """
        prob = copy.copy(self)
        prob._stage1 = {}  # evaluate solves the study's design as given, without stage 1
        study, material, target = self.study, self.material, self.study.target
        x = np.asarray(x, dtype=float)
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
        summary = evaluation_summary(
            r, st_mm=st, mass_g=geom.mass_kg(material.density_kg_m3) * 1e3,
            outer_diameter_mm=2 * geom.checks["outer_radius_mm"],
            thinnest_mm=spring_margins(p, self.frame)["thinnest_mm"] + self.frame.min_feature_mm,
            target_Nm_per_rad=self.k_target, yield_MPa=material.yield_MPa,
            allowable_MPa=target.allowable_stress_MPa,
        )  # fmt: skip
        diagnostics: dict[str, Any] = {}
        if study.solid_3d.check:
            diagnostics["solid_3d"] = prob.solid_3d(geom, r)
            solid_field = take_solid_field(diagnostics["solid_3d"])  # design_3d.vtu
            summary.update(solid_3d_scalars(diagnostics["solid_3d"]))
        # the part as exported: the outline extruded by ST (the 3D-corrected one where made)
        depth = diagnostics.get("solid_3d", {}).get("ST_after_mm", st)
        summary.update(envelope_values(geom.outline, depth))
        return slot_contact.finish(prob, geom, r, depth, DesignResult(
            table=table,
            summary=summary,
            converged=r.ok,
            message=r.message,
            solve_times_s=tuple(times),
            inputs={"material": material_record(material), "n_sets": prob.n_sets},
            diagnostics={
                "dofs": r.n_dofs,
                "triangles": r.n_triangles,
                "newton": r.iterations,
                **diagnostics,
            },  # fmt: skip
            plot={
                "x": "rotation_deg",
                "y": "torque_Nm",
                "stress": "peak_stress_MPa",
                "allowable_MPa": target.allowable_stress_MPa,
                # the target stiffness as a torque line K theta, with its band
                "target_curve": {
                    "x": table["rotation_deg"],
                    "y": self.k_target * np.radians(table["rotation_deg"]),
                },
                "tolerance_rel": target.tolerance_percent / 100.0,
                "target_label": f"target K θ, K = {self.k_target:g} N·m/rad",
            },
            headline=tuple(summary),
            field_map=self._field_map(r),  # stress_deformed.png and design.vtu of evaluate
            solid_field=solid_field if study.solid_3d.check else None,
        ))  # fmt: skip

    @no_numpy_hugepages  # the 3D model's arrays (pipeline/_hugepages.py)
    def solid_3d(
        self, geom: SpringGeometry, r: SpringResponse, side: SideProcess | None = None,
        meanwhile: Any = None,
    ) -> dict[str, Any]:  # fmt: skip
        """The design as a 3D solid, its thickness corrected for it, its peak stress converged
        (issue 15; docs/solid3d.md; the study's ``solid_3d:`` block): :func:`fea.sea_design.
        correct_3d`. The peak convergence, which needs no 3D answer, runs meanwhile in a second
        process (``side``'s "peak" task when the caller started one, else its own); without
        one (or if that process could not run it) it runs here. ``meanwhile()``, if given, is
        called once the 3D checks are made, before the peak convergence is waited for.

        Returns
        -------
        dict — N m/rad, MPa, mm, s; ``problem`` alone when the 3D model cannot be built.
        """
        s3, target = self.study.solid_3d, self.study.target
        sign = worse_direction(r)
        own = side is None and s3.converge_peak
        if own:
            side = SideProcess.start()
            side.submit("peak", peak.peak_job, self, geom.params, sign)

        def converged_peak() -> tuple[dict[str, Any], bool]:
            if meanwhile is not None:
                meanwhile()
            c = side.get("peak") if side is not None else None
            if c is None:
                return peak.peak_of(self, geom.params, sign), False
            return c, True

        try:
            return correct_3d(
                geom, r, self.material, self.theta, self.k_target, target.tolerance_percent,
                target.allowable_stress_MPa, self.study.mesh, s3, converged_peak,
            )  # fmt: skip
        finally:
            if own:
                side.close()


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
                   study.geometry.min_feature_mm), *slot_contact.requirements(study),
    ]  # fmt: skip


#: The figures of a quantity by model (pipeline.verdict): ST as exported is the 3D correction's
#: where made. The 3D stiffness and peak have rows of their own (:func:`_builtin.sea_spring`):
#: the 2D rows keep the 2D figures; the life takes the 3D peak (verdict.life_of_result).
_PEAK_3D = Figure("peak_stress_3d_MPa", "3D solid", SOLID_3D)
_PEAK_2D = Figure("peak_stress_2d_refined_MPa", "plane stress, refined", PLANE_STRESS)
_PEAK = Figure("peak_stress_MPa", "plane stress", PLANE_STRESS)
_ST_3D = Figure("ST_3d_mm", "3D correction", SOLID_3D)
FIGURES = {
    "ST_mm": (Figure("ST_mm", "plane-stress fit", PLANE_STRESS), _ST_3D),
    # the 2D peak the 3D check refined on the exported outline first (threshold_spring's too)
    "peak_stress_MPa": (_PEAK_2D, _PEAK, _PEAK_3D),
}


def problem(study: SeaSpringStudy) -> SeaSpringProblem:
    """The design problem ``flexopt run`` optimises (stage 1 runs on its first use)."""
    return SeaSpringProblem(study)


register(
    StudyKind(
        "sea_spring",
        SeaSpringStudy,
        check,  # type: ignore[arg-type]
        None,  # flexopt evaluate: the nominal design's SeaSpringProblem.result
        problem,  # type: ignore[arg-type]
        requirements=requirements,
        quantities=_builtin.SEA_SPRING,
        # `flexopt list`'s line: the study model's module is _sea_spring_schema
        summary=__doc__.split("\n\n")[0].removeprefix("Study kind ``sea_spring``:"),
        figures=FIGURES,
        design_space=design_of,
        # thickness: search without the 3D check: the plane-stress torque is proportional to ST;
        # solved from the target, or judged on a 3D solid, ST is no exact width (print_to_part.md)
        width_key=lambda study: (
            "design.ST" if study.thickness == "search" and not study.solid_3d.check else None
        ),
    )
)
