"""Study kind ``threshold_spring``: a compliant spring shaped to paper 000's threshold profile.

Issue 7, item 4 (docs/threshold_torque.md, section 4). A planar arm spring
(:mod:`geometry.arm_spring`, parameterised by :mod:`geometry.threshold_spring`: ``n`` curved arms
from the hub to held pads) is shaped so that its nonlinear torque–rotation curve follows a torque
target (normally Eq. 14, ``T = Tmax (1 - exp(-s theta))``) within a tolerance over the design
range, then scored by HIC15 and impact force (:func:`fea.collision.score_spring_curve`) against
the constant-stiffness spring and against the ideal profile.

* **Search model**: one arm as a geometrically exact beam (:mod:`fea.arm_beam`, about 0.05 s per
  curve); the hub turns counter-clockwise only (the spring is one-directional: its arms are
  compressed struts that bow out, which is what levels the torque off).
* **Thickness solved**: the torque is proportional to the thickness ST, so ST is the factor that
  minimises the error measure for the shape (a one-dimensional convex search), not a variable.
* **GA**: one objective, the error measure; constraints the tolerance, the peak stress over the
  allowable, the ST range, the arm spring's clearances (envelope, thinnest arm, slot, hub) and
  the fold margin of the centreline (geometry.threshold_spring.fold_margin_mm).
* **Fidelity check** (``detail``, ``flexopt evaluate``): the chosen design in plane stress
  (:func:`flexopt.fea.spring_analysis.analyse_spring`, the printable outline with
  fillets), its torque error against the same target and its von Mises peak.

YAML (every key optional but ``name``, ``geometry.kind``, ``material`` and ``target``)::

    geometry: {kind: threshold_spring, n_arms: 6, envelope_diameter_mm: 100,
               thickness_range_mm: [2, 20], min_feature_mm: 0.5}
    material: PA12
    target: {kind: threshold, max_torque_Nm: 1.5, rate_per_rad: 37, measure: max_normalised,
             window_deg: [0, 6]}
    tolerance: 0.05                 # on the error measure (max_normalised: 5 % of Tmax)
    allowable_stress_MPa: 43.2      # default 0.9 x the material's yield
    beam: {elements: 24, rows: 24}
    fidelity: {enabled: true, max_edge_mm: 2.0, elements_through: 2.0, steps: 6}
    solid_3d: {check: true, layers: 4, correct: true}  # the design as a 3D solid, ST corrected
                                    # for it (docs/solid3d.md)
    stack_plates: 10                # plates on one hub in the impact (torque x 10)
    impact: {rotor_torque_Nm: 1.0}  # fea.collision's paper defaults otherwise
    design_space: {sweep_deg: [20, 120]}
    design: {sweep_deg: ..., ...}   # the design flexopt evaluate traces
    optimiser: {algorithm: ga, pop_size: 40, n_gen: 40}

Files of ``flexopt evaluate``: ``curve.png``, ``shape.png``, ``stress_map.png`` (plane stress)
and ``spring.stl`` (one plate). Numbers and the choice of target: docs/threshold_torque.md,
section 4.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np
from flexopt.fea.arm_beam import ArmBeamResponse, arm_beam_torque
from flexopt.fea.beam_fields import arm_field
from flexopt.fea.errors import FeaError
from flexopt.fea.scaling import at_thickness
from flexopt.fea.spring_analysis import analyse_spring
from flexopt.geometry.arm_spring import ArmSpringParams, arm_clearances, build_arm_spring
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.solid import extrude, stl_bytes
from flexopt.geometry.threshold_spring import (
    THRESHOLD_VARIABLES,
    arm_profile,
    fold_margin_mm,
    threshold_params,
)
from flexopt.optimise.curve_objectives import (
    SpringCheckSpec,
    impact_record,
    threshold_constraints,
    threshold_curve_scores,
    threshold_plane_stress_figures,
    threshold_solid_3d,
    threshold_solid_3d_scalars,
)
from flexopt.optimise.evaluation import INFEASIBLE_VALUE, Evaluation
from flexopt.optimise.problem import DesignDetail, DesignProblem, DesignResult
from flexopt.optimise.requirements import BEAM, PLANE_STRESS, SOLID_3D
from flexopt.optimise.requirements import Figure as FigureOf
from flexopt.optimise.targets import curve_error, measure_key
from flexopt.optimise.thickness_fit import fit_thickness
from flexopt.pipeline.fields import spring_field_map, take_solid_field
from flexopt.pipeline.plot_targets import measure_band
from flexopt.pipeline.plots import plot_field, spring_shape_png, threshold_curve_png
from flexopt.pipeline.studies import StudyKind, _builtin, register
from flexopt.pipeline.studies._blocks import MeshSpec as PlaneStressMesh
from flexopt.pipeline.studies._threshold_spring_schema import (
    BeamSpec,
    FidelitySpec,
    ThresholdSpringGeometry,
    ThresholdSpringStudy,
    check,
    design_space,
    design_vector,
)
from flexopt.pipeline.study import material_record
from flexopt.pipeline.verdict import envelope_values

__all__ = [
    "BeamSpec",
    "FidelitySpec",
    "ThresholdSpringGeometry",
    "ThresholdSpringStudy",
    "ThresholdSpringProblem",
    "design_space",
    "design_vector",
    "check",
    "problem",
]

#: Reference thickness of the search solves, mm (torques scale with ST, stresses do not).
_REFERENCE_ST_MM = 10.0

#: Geometric constraints (signed margins, mm: geometry.arm_spring.arm_clearances, then
#: geometry.threshold_spring.fold_margin_mm).
_MARGINS = ("envelope_mm", "thinnest_mm", "slot_mm", "hub_mm", "fold_mm")

# the study file's models and its design space are _threshold_spring_schema's
# (ThresholdSpringStudy, design_space, design_vector, check)


# --------------------------------------------------------------------------------------------
# The design problem


class ThresholdSpringProblem(DesignProblem):
    """GA over the arm shape; ST solved from the target; beam model per design.

    Objective: the error measure (``f[0]``). Constraints (``g <= 0``): error − tolerance,
    peak stress / allowable − 1, ST − ST_max, ST_min − ST, then the negated clearance margins
    (mm).
    """

    def __init__(self, study: ThresholdSpringStudy) -> None:
        check(study)
        self.study = study
        self.material = study.material.to_material()
        self.frame = study.geometry.frame()
        self.curve = study.target.to_curve()
        self.window = study.target.window  # rad
        self.measure = study.target.measure
        self.range_rad = float(self.window[1])  # type: ignore[index]
        self.rotation_rad = np.linspace(0.0, self.range_rad, study.beam.rows + 1)
        self.allowable_MPa = study.allowable_stress_MPa or 0.9 * self.material.yield_MPa
        self.st_range = study.geometry.thickness_range_mm
        self.space = design_space(study)
        self.error_name = measure_key(self.measure, self.curve)
        self.objective_names = (self.error_name,)
        self.constraint_names = (
            "error_minus_tolerance",
            "stress_ratio_minus_1",
            "ST_above_max_mm",
            "ST_below_min_mm",
            *(f"{k[:-3]}_shortfall_mm" for k in _MARGINS),
        )
        # a robustness sample holds the nominal design's solved ST (hold_solved), mm
        self.held_st_mm: float | None = None

    # -- robustness samples (pipeline/robustness.py) -------------------------------------------

    def scatter_design(
        self, x: np.ndarray, thickness_delta_mm: float, width_delta_mm: float
    ) -> np.ndarray:
        """(10,) ``x`` as cut or printed off by a tolerance: the in-plane arm widths W1..W4
        plus ``thickness_delta_mm``; sweep, pad radius and the fractions stay (ST, solved, is
        held and moved by ``width_delta_mm``: :meth:`hold_solved`)."""
        x = np.array(x, dtype=float)
        for i, name in enumerate(THRESHOLD_VARIABLES):
            if name.startswith("W") and name.endswith("_mm"):
                x[i] += thickness_delta_mm
        return x

    #: The solved quantity a robustness sample holds and the scatter that moves it.
    held_scatter = {"ST": "width"}

    def held_state(self, evaluation: Evaluation) -> dict[str, float]:
        """ST solved for the nominal design (``{}`` when it was not solved)."""
        st = evaluation.metrics.get("ST_mm")
        return {"ST_mm": float(st)} if st is not None and math.isfinite(st) else {}

    def hold_solved(
        self, held: dict[str, float], thickness_delta_mm: float, width_delta_mm: float
    ) -> None:
        """Solve at the held ST plus ``width_delta_mm`` (the plate's thickness tolerance)
        instead of fitting ST to the target; an empty ``held`` fits ST again."""
        st = held.get("ST_mm")
        self.held_st_mm = None if st is None else float(st) + width_delta_mm

    def params(self, x: np.ndarray, st_mm: float = _REFERENCE_ST_MM) -> ArmSpringParams:
        values = dict(zip(THRESHOLD_VARIABLES, map(float, x), strict=True))
        g = self.study.geometry
        return threshold_params(values, g.n_arms, st_mm, self.frame, g.root_fillet_mm)

    def initial_designs(self) -> np.ndarray | None:
        """The study's ``design:`` seeded into the first population (when given)."""
        if self.study.design is None:
            return None
        return self.space.clip(design_vector(self.study))[None, :]

    def solve(self, x: np.ndarray) -> tuple[ArmSpringParams, ArmBeamResponse, float, float]:
        """Beam curve of a design at the solved thickness: (params, response, ST mm, error).

        Raises
        ------
        GeometryError, FeaError
        """
        p = self.params(x)
        prof = arm_profile(p, self.frame)
        r = arm_beam_torque(
            prof, self.material, p.n_arms, self.rotation_rad, n_elements=self.study.beam.elements
        )
        if not r.ok:
            return p, r, math.nan, math.inf
        if self.held_st_mm is None:
            st, err = fit_thickness(
                r.rotation_rad, r.torque_Nmm / p.thickness_mm, self.curve, self.measure, self.window
            )
        else:  # a robustness sample: the nominal design's ST, moved by the scatter
            st = self.held_st_mm
            torque = at_thickness(r.torque_Nmm, p.thickness_mm, st)
            err = float(curve_error(self.curve, r.rotation_rad, torque, self.measure, self.window))
        # replace, not rebuild: the response keeps every field (members, fibres) for best.vtu
        r = dataclasses.replace(r, torque_Nmm=at_thickness(r.torque_Nmm, p.thickness_mm, st))
        return self.params(x, st), r, st, err

    def evaluate(self, x: np.ndarray) -> Evaluation:
        return self._evaluate(x)[0]

    def _evaluate(self, x: np.ndarray) -> tuple[Evaluation, tuple | None]:
        t0 = time.perf_counter()
        x = np.asarray(x, dtype=float)
        n_obj, n_con = len(self.objective_names), len(self.constraint_names)
        try:
            p = self.params(x)
            m = {**arm_clearances(p, self.frame), "fold_mm": fold_margin_mm(p)}
            g_geo = -np.array([m[k] for k in _MARGINS])
        except GeometryError as exc:
            return Evaluation.failed(x, n_obj, n_con, f"cannot build: {exc}"), None
        except Exception as exc:  # noqa: BLE001 - shapely/GEOS on a degenerate arm band
            # geometry.arm_spring reads .exterior of a MultiPolygon (AttributeError) or hands
            # GEOS a ring of coincident points (GEOSException) for degenerate bands: the design
            # cannot be drawn, which is an infeasible design, not a crash.
            reason = f"cannot build: the arm band is degenerate ({type(exc).__name__}: {exc})"
            return Evaluation.failed(x, n_obj, n_con, reason), None
        if np.any(g_geo > 1e-9):
            # Not buildable: no FE, but graded violations lead the GA back.
            g = np.concatenate([np.full(4, INFEASIBLE_VALUE), g_geo])
            f = np.full(n_obj, INFEASIBLE_VALUE)
            return Evaluation(x, f, g, {"buildable": False}, "", time.perf_counter() - t0), None
        try:
            p, r, st, err = self.solve(x)
        except (GeometryError, FeaError) as exc:
            return Evaluation.failed(x, n_obj, n_con, f"cannot build: {exc}"), None
        if not r.ok:
            reason = f"beam solve: {r.message}"
            return Evaluation.failed(x, n_obj, n_con, reason, time.perf_counter() - t0), None
        if not math.isfinite(err):
            reason = "the torque is not positive anywhere in the range"
            return Evaluation.failed(x, n_obj, n_con, reason, time.perf_counter() - t0), None
        peak = float(np.nanmax(r.peak_stress_MPa))
        g = threshold_constraints(
            err, self.study.tolerance, peak, self.allowable_MPa, st, self.st_range, g_geo
        )
        metrics = {
            "ST_mm": st,
            # the thinnest printed size: the narrowest arm section or the plate itself
            "min_feature_mm": min(m["thinnest_mm"] + self.frame.min_feature_mm, st),
            self.error_name: err,
            "peak_stress_MPa": peak,
            "torque_at_range_Nm": float(r.torque_Nmm[-1]) * 1e-3,
            "initial_stiffness_Nm_per_rad": float(r.torque_Nmm[1] / r.rotation_rad[1]) * 1e-3,
            "beam_time_s": r.solve_time_s,
        }
        ev = Evaluation(x, np.array([err]), g, metrics, "", time.perf_counter() - t0)
        return ev, (p, r, st, err)

    # -- report ------------------------------------------------------------------------------

    def detail(self, x: np.ndarray) -> DesignDetail:
        x = np.asarray(x, dtype=float)
        evaluation, solved = self._evaluate(x)
        study = self.study
        info: dict[str, Any] = {
            "material": material_record(self.material),
            "allowable_stress_MPa": self.allowable_MPa,
            "target": study.target.model_dump(exclude_none=True),
            "direction": "counter-clockwise only (the arms are compressed struts)",
        }
        if solved is None:
            info["problem"] = evaluation.reason or "not buildable (see the constraints)"
            return DesignDetail(evaluation, info=info)
        p, r, st, err = solved
        info["design"] = {
            **dict(zip(THRESHOLD_VARIABLES, map(float, x), strict=True)),
            "ST_mm": st,
        }
        rot_deg = np.degrees(r.rotation_rad)
        target_Nm = np.asarray(self.curve(r.rotation_rad)) * 1e-3
        level = float(np.max(np.abs(target_Nm[self._in_window(r.rotation_rad)])))
        table: dict[str, np.ndarray] = {
            "rotation_deg": rot_deg,
            "target_torque_Nm": target_Nm,
            "torque_Nm": r.torque_Nmm * 1e-3,
            "error_percent_of_max": (r.torque_Nmm * 1e-3 - target_Nm) / level * 100.0,
            "peak_stress_MPa": r.peak_stress_MPa,
            "converged": r.converged,
        }
        outline = height = None
        try:
            geom = build_arm_spring(p, self.frame)
            outline, height = geom.outline, st
            info["mass_g"] = geom.mass_kg(self.material.density_kg_m3) * 1e3
            info["checks"] = geom.checks
        except GeometryError as exc:
            geom = None
            info["outline_problem"] = str(exc)
        field_map = solid_field = None
        if geom is not None and study.fidelity.enabled:
            info["plane_stress"], ps_rows, smap = self._fidelity(geom, r.rotation_rad)
            info.update(threshold_plane_stress_figures(info["plane_stress"], self.error_name))
            field_map = smap  # every row's state, the last on top (pipeline/fields.py)
            if ps_rows is not None:
                table["plane_stress_torque_Nm"] = ps_rows[0]
                table["plane_stress_peak_stress_MPa"] = ps_rows[1]
            if study.solid_3d.check:
                info["solid_3d"] = self.solid_3d(geom, info["plane_stress"])
                solid_field = take_solid_field(info["solid_3d"])  # best_3d.vtu's arrays
                info.update(threshold_solid_3d_scalars(info["solid_3d"], self.error_name))
                # the part to make is the corrected one (its STL, DXF), as in sea_spring
                height = info["solid_3d"].get("ST_after_mm", height)
                if "problem" not in info["solid_3d"].get("peak_convergence", {"problem": ""}):
                    # ... and the outline whose peak stress converged (issue 22)
                    outline = self._fine_geometry(geom, float(height)).outline
        info["impact"] = impact_record(
            r.rotation_rad, r.torque_Nmm * 1e-3, study.impact.model(), study.impact.settings(),
            study.stack_plates, self.curve,
        )  # fmt: skip
        plot = {
            "x": "rotation_deg",
            "y": "torque_Nm",
            "stress": "peak_stress_MPa",
            "target_curve": "target_torque_Nm",
            **measure_band(self.measure, study.tolerance),
            "allowable_MPa": self.allowable_MPa,
            "x_label": "hub rotation (deg)",
            "y_label": "torque on the hub (N m)",
        }
        return DesignDetail(
            evaluation=evaluation,
            table=table,
            plot=plot,
            shapes_mm=r.shapes_mm,
            outline=outline,
            height_mm=height,
            info=info,
            field_map=field_map,
            solid_field=solid_field,
            beam_field=arm_field(r.members, height or st, "plane_stress" in info, r.fibres),
        )

    def _in_window(self, rot_rad: np.ndarray) -> np.ndarray:
        w = self.window
        return (rot_rad >= w[0] - 1e-12) & (rot_rad <= w[1] + 1e-12)  # type: ignore[index]

    def _fidelity(self, geom: Any, rot_rad: np.ndarray) -> tuple[dict[str, Any], Any, Any]:
        """Plane stress of the drawn spring at ``fidelity.steps`` rows: (record, its columns on
        the beam rows (2, rows) with NaN between the plane-stress rows, the von Mises map at the
        last row)."""
        fs = self.study.fidelity
        mesh = PlaneStressMesh(
            max_edge_mm=fs.max_edge_mm,
            elements_through=fs.elements_through,
            fillet_segments=fs.fillet_segments,
            curve_steps=fs.steps,
        )
        try:
            ps = analyse_spring(
                geom, self.material, self.range_rad, mesh, steps=fs.steps, keep_model=True
            )
        except FeaError as exc:
            return {"skipped": f"mesh or model failed: {exc}"}, None, None
        ps_rad = np.radians(ps.rotation_deg)
        torque_Nmm = np.asarray(ps.torque_Nm) * 1e3
        rec: dict[str, Any] = {
            "converged": bool(ps.ok),
            "message": ps.message,
            "rotation_deg": ps.rotation_deg.tolist(),
            "torque_Nm": np.asarray(ps.torque_Nm).tolist(),
            "peak_stress_MPa": np.asarray(ps.peak_stress_MPa).tolist(),
            # where, in undeformed coordinates (rows, 2) mm: the 3D check's sector cuts keep
            # off them (optimise.curve_objectives.threshold_solid_3d)
            "peak_stress_xy_mm": np.asarray(ps.peak_stress_xy_mm).tolist(),
            "n_dofs": ps.n_dofs,
            "solve_time_s": ps.solve_time_s,
        }
        rec.update(
            threshold_curve_scores(
                self.curve, self.measure, self.window, self.study.tolerance, self.allowable_MPa,
                self.error_name, ps_rad, torque_Nmm, ps.peak_stress_MPa,
            )
        )  # fmt: skip
        cols = np.full((2, rot_rad.size), np.nan)
        for k, a in enumerate(ps_rad):
            j = int(np.argmin(np.abs(rot_rad - a)))
            if abs(rot_rad[j] - a) < 1e-9:
                cols[0, j] = ps.torque_Nm[k]
                cols[1, j] = ps.peak_stress_MPa[k]
        label = "von Mises stress at the end of the design range (MPa)"
        smap = spring_field_map(ps, label, self.allowable_MPa) if ps.ok else None
        return rec, cols, smap

    def _check_spec(self) -> SpringCheckSpec:
        """The target, limits, material, drive and mesh of the chosen design's checks."""
        fs, s3 = self.study.fidelity, self.study.solid_3d
        return SpringCheckSpec(
            self.material, self.range_rad, self.curve, self.measure, self.window,
            self.study.tolerance, self.allowable_MPa, self.error_name, fs.max_edge_mm,
            fs.elements_through, fs.steps, s3.layers, s3.correct, s3.converge_peak,
            s3.curve_step_mm, s3.solver,
        )  # fmt: skip

    def solid_3d(self, geom: Any, ps: dict[str, Any]) -> dict[str, Any]:
        """The chosen design as a 3D solid beside plane stress (the :meth:`_fidelity` record
        ``ps``), ST corrected for it: :func:`optimise.curve_objectives.threshold_solid_3d`."""
        return threshold_solid_3d(self._check_spec(), self._fine_geometry, geom, ps)

    def _fine_geometry(self, geom: Any, st_mm: float) -> Any:
        """The design as the peak-stress convergence meshes it and as its part is exported:
        the arms sampled every ``solid_3d.curve_step_mm``, at thickness ``st_mm`` (mm).
        Raises GeometryError."""
        from dataclasses import replace

        return build_arm_spring(
            replace(geom.params, thickness_mm=float(st_mm)), self.frame,
            curve_step_mm=self.study.solid_3d.curve_step_mm,
        )  # fmt: skip

    def nominal_design(self) -> np.ndarray:
        """(10,) the study's ``design:`` (unlisted variables at the middle of their range): what
        ``flexopt evaluate`` solves. As given: one outside design_space is solved and judged NOT
        MET on the design-range row (pipeline.verdict), never moved into the space unsaid."""
        return design_vector(self.study)

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        """Trace the design ``x`` (10,) (the study's ``design:``: :meth:`nominal_design`): beam,
        plane-stress check, impact, with plots and an STL."""
        prob, study = self, self.study
        x = np.asarray(x, dtype=float)
        times = []
        for _ in range(max(1, repeat)):
            t0 = time.perf_counter()
            d = prob.detail(x)
            times.append(time.perf_counter() - t0)
        ev = d.evaluation
        plot = {
            "x": "rotation_deg",
            "y": "torque_Nm",
            "stress": "peak_stress_MPa",
            "allowable_MPa": prob.allowable_MPa,
            "target_curve": "target_torque_Nm",  # drawn with its band (pipeline.plot_targets)
            **measure_band(prob.measure, study.tolerance),
        }
        if not d.table:
            empty = np.zeros(0)
            reasons = ev.reason or ", ".join(
                n
                for n, g in zip(prob.constraint_names, ev.g, strict=True)
                if 0 < g < INFEASIBLE_VALUE
            )
            return DesignResult(
                table={"rotation_deg": empty, "torque_Nm": empty, "peak_stress_MPa": empty},
                summary={"feasible": False, "reason": f"not buildable: {reasons}"},
                converged=False,
                message=f"design not buildable: {reasons}",
                solve_times_s=tuple(times),
                inputs={
                    "info": d.info,
                    "constraints": dict(zip(prob.constraint_names, map(float, ev.g), strict=True)),
                },
                plot=plot,
            )
        files: dict[str, bytes] = {
            "curve.png": threshold_curve_png(
                d.table, study.tolerance, d.plot.get("allowable_MPa"), study.name
            ),
            "shape.png": spring_shape_png(d.outline, d.shapes_mm),
        }
        if d.outline is not None and d.height_mm:
            files["spring.stl"] = stl_bytes(extrude(d.outline, d.height_mm))
        if d.field_map:
            f = d.field_map
            files["stress_map.png"] = plot_field(
                f["points_mm"], f["triangles"], f["values"], f["label"], f.get("limit"), study.name
            )
        summary = _summary(prob, d)
        summary.update(envelope_values(d.outline, d.height_mm))  # the part as exported
        for key in (prob.error_name, "peak_stress_MPa", "min_feature_mm"):  # as flexopt run
            summary.setdefault(key, ev.metrics.get(key))
        ps = d.info.get("plane_stress", {})
        return DesignResult(
            table=d.table,
            summary=summary,
            converged=bool(np.all(d.table["converged"])) and ps.get("converged", True),
            message=ps.get("message", "") or "",
            solve_times_s=tuple(times),
            inputs={
                "design": d.info.get("design"),
                "constraints": dict(zip(prob.constraint_names, map(float, ev.g), strict=True)),
                "info": {k: v for k, v in d.info.items() if k not in ("design",)},
            },
            diagnostics={"beam_time_s": ev.metrics.get("beam_time_s")},
            plot=plot,
            headline=tuple(k for k in summary if summary[k] is not None),
            files=files,
            field_map=d.field_map,  # stress_deformed.png and design.vtu of the evaluate folder
            solid_field=d.solid_field,  # design_3d.vtu
            shapes_mm=d.shapes_mm,  # design.vtu: arm 0 with its section and stresses
            beam_field=d.beam_field,
        )


#: the peak-stress row's best figure where the 3D check converged it: listed first of its rank
CONVERGED_2D = FigureOf("peak_stress_2d_refined_MPa", "plane stress, refined", PLANE_STRESS)


def figures(study: ThresholdSpringStudy) -> dict[str, tuple[FigureOf, ...]]:
    """The figures of a quantity by model (pipeline.verdict): the error measure and the peak
    stress are judged on the plane-stress check's where the run made one (the 3D figures have
    rows of their own, :func:`_builtin.threshold_spring`, so they are not borrowed)."""
    curve = study.target.to_curve() if study.target.kind != "table" else None
    measure = getattr(study, "measure", None) or getattr(study.target, "measure", "rms")
    name = measure_key(measure, curve) if curve is not None else f"{measure}_error"
    out = {
        q: (
            FigureOf(q, "beam", BEAM),
            FigureOf(f"plane_stress_{q}", "plane stress", PLANE_STRESS),
            FigureOf(f"{q}_3d" if q == name else "peak_stress_3d_MPa", "3D solid", SOLID_3D),
        )
        for q in (name, "peak_stress_MPa")
    }
    # the 2D peak the 3D check refined on the exported outline outranks the check mesh's (#22)
    out["peak_stress_MPa"] = (CONVERGED_2D, *out["peak_stress_MPa"])
    # ST as exported: the 3D check's corrected ST where it made one (the STL's thickness)
    out["ST_mm"] = (
        FigureOf("ST_mm", "beam fit", BEAM),
        FigureOf("ST_after_mm", "3D correction", SOLID_3D),
    )
    return out


def problem(study: ThresholdSpringStudy) -> ThresholdSpringProblem:
    """The GA problem of a validated study."""
    return ThresholdSpringProblem(study)


# --------------------------------------------------------------------------------------------
# flexopt evaluate


def _summary(prob: ThresholdSpringProblem, d: DesignDetail) -> dict[str, Any]:
    m = d.evaluation.metrics
    info = d.info
    s: dict[str, Any] = {
        "feasible": d.evaluation.feasible,
        "ST_mm": m.get("ST_mm"),
        f"beam_{prob.error_name}": m.get(prob.error_name),
        "tolerance": prob.study.tolerance,
        "beam_peak_stress_MPa": m.get("peak_stress_MPa"),
        "allowable_stress_MPa": prob.allowable_MPa,
        "initial_stiffness_Nm_per_rad": m.get("initial_stiffness_Nm_per_rad"),
        "torque_at_range_Nm": m.get("torque_at_range_Nm"),
        "design_range_deg": math.degrees(prob.range_rad),
        "mass_g": info.get("mass_g"),
        "outer_diameter_mm": 2 * info["checks"]["outer_radius_mm"] if "checks" in info else None,
    }
    ps = info.get("plane_stress", {})
    s[f"plane_stress_{prob.error_name}"] = None
    s["plane_stress_peak_stress_MPa"] = None
    s.update(threshold_plane_stress_figures(ps, prob.error_name))
    peaks = [v for v in (m.get("peak_stress_MPa"), ps.get("peak_stress_max_MPa")) if v is not None]
    s["stress_yield_ratio"] = max(peaks) / prob.material.yield_MPa if peaks else None
    s.update(threshold_solid_3d_scalars(info.get("solid_3d", {}), prob.error_name))
    imp = info.get("impact", {})
    if "spring" in imp:
        s.update(
            {
                "impact_rotor_torque_Nm": imp["case"]["rotor_torque_Nm"],
                "hic15": imp["spring"]["hic15"],
                "peak_force_N": imp["spring"]["peak_force_N"],
                "impact_deflection_deg": imp["spring"]["max_deflection_deg"],
                "beyond_table": imp["spring"]["beyond_table"],
                "cs_hic15": imp["constant_stiffness"]["hic15"],
                "cs_peak_force_N": imp["constant_stiffness"]["peak_force_N"],
                "hic_reduction_vs_cs": imp["hic_reduction"],
                "force_reduction_vs_cs": imp["force_reduction"],
            }
        )
        if "ideal_threshold" in imp:
            s["ideal_hic15"] = imp["ideal_threshold"]["hic15"]
            s["ideal_peak_force_N"] = imp["ideal_threshold"]["peak_force_N"]
    return s


register(
    StudyKind(
        "threshold_spring",
        ThresholdSpringStudy,
        check,
        None,  # flexopt evaluate: the nominal design's ThresholdSpringProblem.result
        problem,
        requirements=_builtin.threshold_spring,
        quantities=_builtin.THRESHOLD_SPRING,
        figures=figures,
        design_space=lambda study: (design_space(study), design_vector(study)),
        # `flexopt list`'s line: the model's module is _threshold_spring_schema
        summary=(__doc__ or "").split("\n\n")[0].removeprefix("Study kind ``threshold_spring``:"),
    )  # type: ignore[arg-type]
)
