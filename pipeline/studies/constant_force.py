"""Study kind ``constant_force``: the long-stroke constant-force beam of paper 003.

The paper's beam-based design (Bilancia, Geraci, Berselli, SMASIS 2019; reconstruction in
``docs/constant_force.md``): a tapered beam through the reference points S1..S6 of the Table-1
PRB slider-crank, 23 design variables (a1..a10, t1..t10, T1, T6, B), S1 clamped, S6 driven along
the work direction with its transverse motion (and, by default, its rotation) held. A design is
good when its output force stays at ``target.force_N`` within ``target.tolerance_percent`` over a
long stroke without the peak stress passing the allowable.

YAML (every key optional but ``name``, ``geometry.kind`` and ``material``; see
``docs/constant_force.md``, section "Study")::

    geometry: {kind: constant_force, end_flexures: centred, elements: 60, min_feature_mm: 0.8}
    material: ABS
    boundary: {stroke_mm: 30, rows: 60, rotation: fixed}
    target: {force_N: 1.5, tolerance_percent: 2, samples: 10, allowable_stress_MPa: 42.5}
    objective: rms_error                # or operative_stroke
    design_space: {B: [4, 12]}          # Table 3 bounds unless overridden, by variable name
    initial: table3                     # seed the GA with the paper's optimum (or design, none)
    optimiser: {pop_size: 40, n_gen: 60}
    prb: {target_force_N: 1.5, stroke_mm: 35}
    fidelity: {points: 4, max_edge_mm: 0.5}
    # or, instead of the paper's frame, target and stroke, a user's spec (section 7):
    # spec: {force_N: 5, stroke_mm: 15, envelope: {length_mm: 90, height_mm: 60}, width_max_mm: 10}

``problem(study)`` returns a picklable :class:`ConstantForceProblem` (the
:class:`optimise.DesignProblem` that ``flexopt run`` optimises); its ``result(x)`` analyses one
design (the study's ``design:``, by default Table 3) for ``flexopt evaluate``.
"""

from __future__ import annotations

import copy
import logging
import time
from typing import Any

import numpy as np
from flexopt.fea.beam import BeamModel, BeamResponse, EndDrive
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.prb import prb_frame_comparison, prb_report, prb_report_once
from flexopt.geometry.constant_force import (
    DESIGN_VARIABLE_NAMES,
    TABLE3_OPTIMUM,
    WORK_DIRECTION,
    ConstantForceDesign,
    beam_profile,
    design_from_vector,
    design_to_vector,
    outline,
)
from flexopt.geometry.constant_force import min_feature_mm as design_min_feature_mm
from flexopt.geometry.errors import GeometryError
from flexopt.optimise.curve_metrics import CurveMetrics, curve_metrics
from flexopt.optimise.curve_objectives import (
    check_rows,
    compared_over,
    force_band_constraints,
    force_band_metrics,
    force_band_objective,
    plane_stress_force_column,
)
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignDetail, DesignProblem, DesignResult
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.fields import constant_force_fields
from flexopt.pipeline.studies import StudyKind, _builtin, _constant_force_solved, register
from flexopt.pipeline.studies import _constant_force_fillet as pads  # geometry.pad_fillet_mm
from flexopt.pipeline.studies import _constant_force_kinks as kinks  # the refined peak
from flexopt.pipeline.studies._constant_force_band import band_names, band_rows
from flexopt.pipeline.studies._constant_force_clamp import checked_peak_figures
from flexopt.pipeline.studies._constant_force_schema import (
    FRACTIONS,
    ConstantForceBoundary,
    ConstantForceGeometry,
    ConstantForceStudy,
    FidelitySpec,
    ForceTarget,
    PRBSpec,
    check,
    design_space,
    design_vector,
)
from flexopt.pipeline.studies._constant_force_spec import check_spec, study_frame
from flexopt.pipeline.study import material_record
from flexopt.pipeline.verdict import envelope_values

__all__ = [
    "ConstantForceGeometry",
    "ConstantForceBoundary",
    "ForceTarget",
    "PRBSpec",
    "FidelitySpec",
    "ConstantForceStudy",
    "ConstantForceProblem",
    "design_space",
    "design_vector",
    "outline",  # the sharp outline, as before (the study's: _constant_force_fillet)
    "fidelity_check",
    "prb_report",
    "prb_synthesis",
    "problem",
    "check",
]

log = logging.getLogger(__name__)

# the study file's models and its design space are _constant_force_schema's (ConstantForceStudy,
# design_space, design_vector, check)


# --------------------------------------------------------------------------------------------
# The design problem


def _thinnest(design: ConstantForceDesign) -> tuple[str, float]:
    names = ("T1", *(f"t{j}" for j in range(1, 11)), "T6")
    t = design.vertex_thickness_mm
    i = int(np.argmin(t))
    return names[i], float(t[i])


class ConstantForceProblem(DesignProblem):
    """The :class:`optimise.DesignProblem` of a ``constant_force`` study.

    Holds only the validated study and plain numbers, so it pickles small and each worker
    rebuilds nothing but the beam of the design it evaluates. ``evaluate`` is deterministic and
    never raises for a bad design.

    Objectives (minimised)
    ----------------------
    ``rms_error``: ``rms_error_N`` — the paper's Eq. 8 over ``target.samples`` strokes.
    ``operative_stroke``: ``negative_operative_stroke_mm`` = ``-operative_stroke_mm + stroke_mm *
    rms_error_N / force_N``. The second term is a tie-breaker: it orders the many designs that
    have no window at all (most of a random population) by how close they are to the target, and
    among designs with equal windows prefers the flatter one; it is worth ~0.1 mm for a design
    that holds the band.

    Constraints (g <= 0)
    --------------------
    ``stress_ratio_minus_1`` = peak stress / allowable - 1, over the whole drive for
    ``rms_error`` (the paper's constraint: the mechanism must survive the stroke it is driven
    through) and over ``[0, window end]`` for ``operative_stroke`` (the window is the stroke used;
    a stop ends the travel there). ``operative_stroke_shortfall_mm`` = ``min_operative_stroke_mm
    - operative_stroke_mm`` when ``target.min_operative_stroke_mm > 0``.
    """

    def __init__(self, study: ConstantForceStudy) -> None:
        self.study = study
        self.space = design_space(study)
        self.material: Material = study.material.to_material()
        self.allowable_MPa = study.allowable_MPa
        self.frame = study_frame(study)  # Table 1, or paper 003's frame scaled to a spec's envelope
        self.objective_names: tuple[str, ...] = (
            ("rms_error_N",)
            if study.objective == "rms_error"
            else ("negative_operative_stroke_mm",)
        )
        names = ["stress_ratio_minus_1"]
        if study.target.min_operative_stroke_mm > 0:
            names.append("operative_stroke_shortfall_mm")
        names += band_names(study)  # the force band at every judged row (issue 27)
        self.constraint_names: tuple[str, ...] = tuple(names)
        self.checks = kinks.CheckMemo()  # the calibration's checks, for detail (copies share it)

    # ---- what the run pipeline may ask besides evaluate/detail

    #: evaluations carry Eq. 8's residuals as metrics (set on the copy :meth:`with_residuals`)
    residual_metrics = False
    adopt_check, check_parts = kinks.adopt_check, kinks.CHECK_PARTS  # a worker's check kept; split

    def with_residuals(self) -> ConstantForceProblem | None:
        """This problem, its evaluations carrying the force residuals F(s_i) - target (N) at
        the ``target.samples`` strokes of Eq. 8 as ``residual_1`` ...: ``rms_error_N`` is their
        RMS (a Gauss-Newton step of ``method: hybrid``); None for ``operative_stroke``."""
        if self.study.objective != "rms_error":
            return None
        other = copy.copy(self)
        other.residual_metrics = True
        return other

    def jacobian(self, x: np.ndarray) -> Any:
        """Exact derivatives at ``x`` (23,): :mod:`._constant_force_gradient` (imported here,
        ~0.1 s); the Gauss-Newton copy (:meth:`with_residuals`) with ``window`` (session 34)."""
        from flexopt.pipeline.studies._constant_force_gradient import jacobian  # fillets too

        return jacobian(self, x, self._beam, self._drive, window=self.residual_metrics)

    def check_constraints(self, x: np.ndarray, part: Any = None) -> Any:
        """The verdict's peak-stress figure at ``x`` (23,) for the hybrid's calibration, or a
        ``part`` of it (check_parts): :mod:`._constant_force_calibration`'s ConstraintCheck."""
        from flexopt.pipeline.studies._constant_force_calibration import check_constraints as c

        return c(self, x, self._solve, self._metrics, lambda *a: self._check(x, *a), part)

    def _check(self, x: np.ndarray, *args: Any) -> dict[str, Any]:
        """The verdict's check of ``x`` (args: design, response, lo, hi), kept (CheckMemo)."""
        return self.checks.record(self, x, args, lambda: _guarded(fidelity_check, self, *args))

    def warm_up_detail(self) -> None:
        """Load what :meth:`detail` needs beyond the beam: the plane-stress check's modules and
        compiled kernels (a run calls this in a thread while its workers solve, so the report
        does not start with ~1.5 s of imports and kernel loading)."""
        if self.study.fidelity.enabled:
            from flexopt.fea.plane_stress import warm_up

            warm_up()
        if self.study.prb is not None:  # the detail's PRB synthesis (~0.2 s CPU), kept
            _guarded(prb_synthesis, self.study)

    def nominal_design(self) -> np.ndarray:
        """(23,) the design the study file describes (what ``flexopt evaluate`` solves)."""
        return design_vector(self.study)

    def initial_designs(self) -> np.ndarray | None:
        """(k, 23) designs for the first population (``initial:``), or None."""
        if self.study.initial == "none":
            return None
        if self.study.initial == "table3":
            x = design_to_vector(TABLE3_OPTIMUM)
        else:
            x = design_vector(self.study)
        # Table 3 lies outside a narrowed space; the nearest design in it seeds instead.
        return self.space.clip(x)[None, :]

    def scatter_design(
        self, x: np.ndarray, thickness_delta_mm: float, width_delta_mm: float
    ) -> np.ndarray:
        """(23,) ``x`` as printed off by a tolerance (robustness samples, pipeline/robustness):
        every in-plane thickness (t1..t10, T1, T6) plus ``thickness_delta_mm``, the width B plus
        ``width_delta_mm``; the positions a1..a10 stay."""
        x = np.array(x, dtype=float)
        for i, name in enumerate(DESIGN_VARIABLE_NAMES):
            if name == "B":
                x[i] += width_delta_mm
            elif name not in FRACTIONS:
                x[i] += thickness_delta_mm
        return x

    # ---- building and solving

    def _design(self, x: np.ndarray) -> ConstantForceDesign:
        return design_from_vector(np.asarray(x, dtype=float))

    def _drive(self, max_mm: float, steps: int) -> EndDrive:
        return EndDrive(
            "displacement",
            WORK_DIRECTION,
            float(max_mm),
            int(steps),
            self.study.boundary.rotation,
            "fixed",
        )

    def _beam(self, design: ConstantForceDesign) -> BeamModel:
        return pads.beam_model(self, design)  # with geometry.pad_fillet_mm's fillets

    def _printability(self, design: ConstantForceDesign) -> str:
        """Empty when printable, else the reason (a check on the design vector: exact, as the
        thickness is linear between vertices, and far cheaper than a solve)."""
        limit = self.study.geometry.min_feature_mm
        name, t = _thinnest(design)
        if t < limit:
            return f"not printable: {name} = {t:.4g} mm is thinner than min_feature_mm = {limit:g}"
        if design.B < limit:
            return (
                f"not printable: B = {design.B:.4g} mm is thinner than min_feature_mm = {limit:g}"
            )
        return ""

    def _solve(self, x: np.ndarray) -> tuple[ConstantForceDesign | None, BeamResponse | None, str]:
        try:
            design = self._design(x)
        except GeometryError as exc:
            return None, None, f"cannot build: {exc}"
        reason = self._printability(design)
        if reason:
            return design, None, reason
        drive = self._drive(self.study.boundary.stroke_mm, self.study.boundary.rows)
        try:
            beam = self._beam(design)  # the stress from statics: converged at the clamp
            response = pads.with_root_stress(self, design, beam, beam.solve(drive))  # + Kt x root
        except (GeometryError, FeaError) as exc:
            return design, None, f"cannot build: {exc}"
        if not response.ok:
            return design, response, f"did not converge: {response.message}"
        return _constant_force_solved.keep(self, x, design, beam, response)  # for a Jacobian at x

    def _metrics(self, design: ConstantForceDesign, response: BeamResponse) -> CurveMetrics:
        t = self.study.target
        return curve_metrics(
            response.displacement_mm,
            response.force_N,
            response.peak_stress_MPa,
            t.force_N,
            t.tolerance_percent / 100.0,
            self.allowable_MPa,
            t.samples,
        )

    def _evaluation(
        self,
        x: np.ndarray,
        design: ConstantForceDesign,
        m: CurveMetrics,
        time_s: float,
        response: BeamResponse,
    ) -> Evaluation:
        """The design's objectives, constraints and metrics. A design whose traced path passed a
        bifurcation or limit point (``response.unstable``: some row's constrained tangent is not
        positive definite, so the beam would snap or buckle away from the traced rows) keeps its
        numbers but is infeasible, with the solver's ``unstable: ...`` message as the reason."""
        study = self.study
        f = [
            force_band_objective(study.objective, m, study.boundary.stroke_mm, study.target.force_N)
        ]
        g = force_band_constraints(
            study.objective,
            m,
            self.allowable_MPa,
            study.fidelity.beam_stress_factor,
            study.target.min_operative_stroke_mm,
        ) + band_rows(study, response, m.rms_error_N)
        metrics: dict[str, Any] = {
            **force_band_metrics(m),
            "min_feature_mm": design_min_feature_mm(design),
            "stable": not response.unstable,
            "unstable_rows": _unstable_rows(response),
        }
        if self.residual_metrics:  # with_residuals(): Eq. 8's terms, rms_error_N = RMS of them
            t = study.target
            s = np.asarray(response.displacement_mm, dtype=float)
            probes = s[-1] * np.arange(1, t.samples + 1) / t.samples
            r = np.interp(probes, s, np.asarray(response.force_N, dtype=float)) - t.force_N
            metrics.update({f"residual_{i + 1}": float(v) for i, v in enumerate(r)})
        reason = response.unstable_message if response.unstable else ""
        return Evaluation(
            np.asarray(x, dtype=float), np.array(f), np.array(g), metrics, reason, time_s
        )

    def _failed(self, x: np.ndarray, reason: str, t0: float, design: Any = None) -> Evaluation:
        metrics = {} if design is None else {"min_feature_mm": design_min_feature_mm(design)}
        return Evaluation.failed(
            x,
            len(self.objective_names),
            len(self.constraint_names),
            reason,
            time.perf_counter() - t0,
            metrics,
        )

    def evaluate(self, x: np.ndarray) -> Evaluation:
        """Evaluate one design vector (23,); a bad design comes back infeasible with a reason."""
        t0 = time.perf_counter()
        x = np.asarray(x, dtype=float)
        try:
            design, response, reason = self._solve(x)
            if reason or response is None or design is None:
                return self._failed(x, reason or "failed", t0, design)
            m = self._metrics(design, response)
            return self._evaluation(x, design, m, time.perf_counter() - t0, response)
        except Exception as exc:  # never let one design end the run
            log.exception("constant_force: evaluating %s raised", x)
            return self._failed(x, f"raised {type(exc).__name__}: {exc}", t0)

    # ---- the report of one design

    def detail(self, x: np.ndarray) -> DesignDetail:
        """Full response, outline, plane-stress fidelity check and PRB comparison of a design.

        ``table``: the traced rows (``displacement_mm``, ``force_N``, ``force_error_percent``,
        ``transverse_force_N``, ``moment_Nmm``, ``end_rotation_deg``, ``peak_stress_MPa``,
        ``peak_stress_s_mm``, ``in_window``); ``shapes_mm``: deformed beam nodes per row;
        ``outline``: the printable polygon with its clamping pads, extruded by ``height_mm`` = B;
        ``plot``: target force and its band half-width ``tolerance`` (N), allowable stress;
        ``info``: the design by name, the plane-stress ``fidelity`` check, the ``prb_frame``
        comparison and, with a ``prb:`` block, the ``prb`` synthesis.
        """
        x = np.asarray(x, dtype=float)
        evaluation = self.evaluate(x)
        study = self.study
        info: dict[str, Any] = {
            "design": {n: float(v) for n, v in zip(DESIGN_VARIABLE_NAMES, x, strict=True)},
            "objective": study.objective,
            "end_flexures": study.geometry.end_flexures,
            "allowable_stress_MPa": self.allowable_MPa,
            "band_N": [
                study.target.force_N * (1 - study.target.tolerance_percent / 100),
                study.target.force_N * (1 + study.target.tolerance_percent / 100),
            ],
        }
        try:
            design = self._design(x)
        except GeometryError as exc:
            info["problem"] = f"cannot build: {exc}"
            return DesignDetail(evaluation, info=info)
        g = study.geometry
        shape = pads.study_outline(self, design)  # with the pad fillets
        profile = beam_profile(design, self.frame, g.end_flexures)
        info["beam_length_mm"] = profile.length_mm
        info["outline_area_mm2"] = shape.area
        _, response, reason = self._solve(x)
        if response is None:
            info["problem"] = reason
            return DesignDetail(evaluation, outline=shape, height_mm=design.B, info=info)
        table = _response_table(response, study.target.force_N)
        m = self._metrics(design, response)
        a, b = m.window_mm
        table["in_window"] = (
            (table["displacement_mm"] >= a) & (table["displacement_mm"] <= b)
            if m.operative_stroke_mm > 0
            else np.zeros(len(table["displacement_mm"]), dtype=bool)
        )
        lo, hi = compared_over(m, study.boundary.stroke_mm)
        info["compared_over_mm"] = [lo, hi]
        info["prb_frame"] = (
            prb_frame_comparison(table["displacement_mm"], table["force_N"], lo, hi)
            if study.spec is None
            else {"skipped": "the frame is scaled to spec.envelope, not Table 1's"}
        )
        if study.spec is not None:  # the closed-form figures the spec was judged on
            info["spec_estimate"] = check_spec(study).as_dict()  # type: ignore[union-attr]
        # The checks are reported, never fatal: a report without them beats no report.
        if study.fidelity.enabled:
            info["fidelity"] = self._check(x, design, response, lo, hi)  # the hybrid's, if made
            info.update(checked_peak_figures(info["fidelity"], response.peak_stress_MPa))
            column = plane_stress_force_column(table, info["fidelity"])
            if column is not None:
                table["plane_stress_force_N"] = column
        else:
            info["fidelity"] = {"skipped": "fidelity.enabled is false"}
        if study.prb is not None:
            info["prb"] = _guarded(prb_synthesis, study)
        tol_N = study.target.force_N * study.target.tolerance_percent / 100.0
        plot = {
            "x": "displacement_mm",
            "y": "force_N",
            "stress": "peak_stress_MPa",
            "target": study.target.force_N,
            "tolerance": tol_N,
            "allowable_MPa": self.allowable_MPa,
            "x_label": "stroke of S6 along the work direction (mm)",
            "y_label": "output force (N)",
        }
        fields = constant_force_fields(info["fidelity"], self._beam(design), response, self)
        return DesignDetail(
            evaluation=evaluation,
            table=table,
            plot=plot,
            shapes_mm=np.asarray(response.shapes_mm),
            outline=shape,
            height_mm=design.B,
            info=info,
            **fields,  # field_map and beam_field (best.vtu, stress_deformed.png)
        )

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        """``flexopt evaluate``: trace the design ``x`` (23,) (the study's ``design:``, Table 3 by
        default: :meth:`nominal_design`) once per repeat.

        Raises
        ------
        StudyError
            When the design cannot be built or is not printable, naming ``design``.
        """
        prob, study = self, self.study
        x = np.asarray(x, dtype=float)
        times: list[float] = []
        evaluation = None
        response = None
        design = None
        for _ in range(max(1, repeat)):
            t0 = time.perf_counter()
            design, response, reason = prob._solve(x)
            times.append(time.perf_counter() - t0)
            if response is None:
                raise StudyError("design", reason)
        evaluation = prob.evaluate(x)
        assert response is not None and design is not None
        table = _response_table(response, study.target.force_N)
        table["converged"] = np.asarray(response.converged, dtype=bool)
        summary = dict(evaluation.metrics)
        peak = float(np.max(response.peak_stress_MPa))
        summary["stress_yield_ratio"] = peak / study.material.yield_MPa
        summary["feasible"] = evaluation.feasible
        # ``stable`` (bool) and ``unstable_rows`` come with the metrics; the message names the step.
        summary["stable"] = not response.unstable
        summary["unstable_rows"] = _unstable_rows(response)
        summary["unstable_message"] = response.unstable_message
        summary.update(
            {name: float(v) for name, v in zip(prob.objective_names, evaluation.f, strict=True)}
        )
        summary.update(
            {name: float(v) for name, v in zip(prob.constraint_names, evaluation.g, strict=True)}
        )
        shape = pads.study_outline(prob, design)  # the part as exported (best.stl's): its envelope
        summary.update(envelope_values(shape, design.B))
        diagnostics = dict(response.extra)
        if study.fidelity.enabled:  # the figure the verdict judges, as flexopt run's report does
            lo, hi = compared_over(prob._metrics(design, response), study.boundary.stroke_mm)
            check = _guarded(fidelity_check, prob, design, response, lo, hi)
            diagnostics["fidelity"] = check
            summary.update(checked_peak_figures(check, response.peak_stress_MPa))
            column = plane_stress_force_column(table, check)
            if column is not None:
                table["plane_stress_force_N"] = column
        profile = beam_profile(design, prob.frame, study.geometry.end_flexures)
        fields = constant_force_fields(
            diagnostics.get("fidelity"), prob._beam(design), response, prob
        )
        return DesignResult(
            shapes_mm=np.asarray(response.shapes_mm),  # design.vtu of the evaluate folder
            **fields,
            table=table,
            summary=summary,
            converged=bool(response.ok),
            message="; ".join(m for m in (response.message, response.unstable_message) if m),
            solve_times_s=tuple(times),
            inputs={
                "material": material_record(prob.material) | {"G_MPa": prob.material.G_MPa},
                "design": {n: float(v) for n, v in zip(DESIGN_VARIABLE_NAMES, x, strict=True)},
                "beam_length_mm": profile.length_mm,
                "allowable_stress_MPa": prob.allowable_MPa,
            },
            diagnostics=diagnostics,
            plot={
                "x": "displacement_mm",
                "y": "force_N",
                "stress": "peak_stress_MPa",
                "allowable_MPa": prob.allowable_MPa,
                "target": study.target.force_N,  # the force band, drawn (pipeline.plot_targets)
                "tolerance": study.target.force_N * study.target.tolerance_percent / 100.0,
            },
            headline=(
                "mean_force_N",
                "flatness_percent",
                "operative_stroke_mm",
                "plateau_mean_force_N",
                "plateau_flatness_percent",
                "stress_limit_stroke_mm",
                "peak_stress_MPa",
                "rms_error_N",
            ),
            outline=shape,  # the part as exported: report.html's 3D view draws it, no re-solve
            height_mm=design.B,
        )


def _guarded(check: Any, *args: Any) -> dict[str, Any]:
    try:
        return check(*args)
    except Exception as exc:
        log.exception("constant_force: %s raised", check.__name__)
        return {"skipped": f"raised {type(exc).__name__}: {exc}"}


def _unstable_rows(response: BeamResponse) -> int:
    """Converged rows that are not stable equilibria (see :class:`fea.beam.BeamResponse`)."""
    if response.stable is None:
        return 0
    return int(np.sum(np.asarray(response.converged, bool) & ~np.asarray(response.stable, bool)))


def _stable_column(response: BeamResponse) -> np.ndarray:
    """(rows,) bool: the row is a stable equilibrium (converged rows when not assessed)."""
    if response.stable is None:
        return np.asarray(response.converged, dtype=bool).copy()
    return np.asarray(response.stable, dtype=bool)


def _response_table(response: BeamResponse, target_N: float) -> dict[str, np.ndarray]:
    """The traced response as named columns (row 0 unloaded). The output force is the force
    that pushes S6 along the work direction, positive in compression like the paper's plots.
    ``stable`` is False on rows past a bifurcation or limit point (see fea.beam)."""
    force = np.asarray(response.force_N, dtype=float)
    return {
        "displacement_mm": np.asarray(response.displacement_mm, dtype=float),
        "force_N": force,
        "force_error_percent": (force - target_N) / target_N * 100.0,
        "transverse_force_N": np.asarray(response.transverse_force_N, dtype=float),
        "moment_Nmm": np.asarray(response.moment_Nmm, dtype=float),
        "end_rotation_deg": np.degrees(np.asarray(response.end_rotation_rad, dtype=float)),
        "peak_stress_MPa": np.asarray(response.peak_stress_MPa, dtype=float),
        "peak_stress_s_mm": np.asarray(response.peak_stress_s_mm, dtype=float),
        "stable": _stable_column(response),
    }


# --------------------------------------------------------------------------------------------
# Independent checks


def fidelity_check(
    problem: ConstantForceProblem,
    design: ConstantForceDesign,
    response: BeamResponse,
    lo: float,
    hi: float,
) -> dict[str, Any]:
    """Check the beam model against a plane-stress, geometrically nonlinear FEA of the outline.

    The study's part: the rows and the outline; the FEA is :func:`fea.fidelity.plane_stress_check`,
    its peak's row re-solved on a locally refined mesh (:mod:`._constant_force_kinks`).
    The outline (beam plus pads) is meshed with quadratic triangles; the S1 pad is clamped and
    the S6 pad translated along the work direction as a rigid body (transverse motion and
    rotation held: the beam's boundary conditions). At ``fidelity.points`` strokes spread over
    ``[lo, hi]`` (the operative window; the rows of ``response`` nearest to them) the plane-stress
    equilibrium is solved by Newton's method **started from the beam's deformed shape** mapped
    onto the mesh, and its force and peak stress are compared with the beam's.

    Why start from the beam: the post-buckled beam is one of several equilibria at a given
    stroke (higher buckling modes carry 5-10x the force). The plane-stress solver's own path
    following (uniform load steps from the straight state, no stability check) lands on such a
    higher branch for some designs even with 1 mm steps. The beam's shape only selects the branch;
    the force is the plane-stress model's own equilibrium, and the smallest eigenvalue of its
    tangent (``stable``) confirms that equilibrium is stable, i.e. the physical one.
    ``max_shape_change_mm`` is how far Newton moved the mesh from the beam's shape.

    Stresses in elements touching the pads are left out: the re-entrant pad corners are singular
    in 2D elasticity and have no counterpart in the beam. The plane-stress stress is the nodal
    (vertex-averaged) von Mises stress; the beam's is ``|N|/A + |M| c / I``.

    Returns
    -------
    dict
        ``stroke_mm``, ``beam_force_N``, ``plane_stress_force_N``, ``relative_difference``
        (plane stress / beam - 1), ``max_abs_relative_difference``, ``within_5_percent``, peak
        stresses and transverse forces of both, ``stable``, Newton iterations, mesh size and
        time; or ``skipped`` with the reason.
    """
    study = problem.study
    spec = study.fidelity
    if study.boundary.rotation != "fixed":
        return {
            "skipped": "boundary.rotation is free: a rigid drive pad holds the rotation, so the "
            "plane-stress model cannot represent a free end rotation"
        }
    t0 = time.perf_counter()
    stroke_rows = np.asarray(response.displacement_mm, dtype=float)
    rows = check_rows(
        stroke_rows, response.converged, response.peak_stress_MPa, lo, hi, spec.points
    )
    try:
        shape = pads.study_outline(problem, design)  # the pad fillets and the blended kinks
        beam = problem._beam(design)
    except (GeometryError, FeaError) as exc:
        return {"skipped": f"could not build the plane-stress model: {exc}"}
    # fea.fidelity.plane_stress_check, and its peak's row re-solved on a locally refined mesh
    hi = max(hi, float(stroke_rows[rows].max()))
    result = kinks.refined_check(problem, design, beam, shape, response, rows, hi)
    if "skipped" not in result:
        result["time_s"] = time.perf_counter() - t0  # the rows' choice counted as before
    return result


#: The figures of a quantity by model (pipeline.verdict): the peak stress and the force band
#: are judged on the plane-stress check's figures where the run made one.
FIGURES = _builtin.CONSTANT_FORCE_FIGURES


def prb_synthesis(study: ConstantForceStudy) -> dict[str, Any]:
    """:func:`prb_report` for the study's ``prb:`` block (defaults: the study's target force and
    drive stroke, its material, allowable stress and printable minimum thickness)."""
    spec = study.prb or PRBSpec()
    return prb_report_once(  # once per process: warm_up_detail makes it while workers solve
        spec.target_force_N or study.target.force_N, spec.stroke_mm or study.boundary.stroke_mm,
        study.material.E_MPa, study.allowable_MPa, study.geometry.min_feature_mm,
        spec.x_in_mm, spec.e_mm,
    )  # fmt: skip


# --------------------------------------------------------------------------------------------
# Registry hooks


def problem(study: ConstantForceStudy) -> ConstantForceProblem:
    """The design problem ``flexopt run`` optimises (built once per run)."""
    return ConstantForceProblem(study)


register(
    StudyKind(
        "constant_force",
        ConstantForceStudy,
        check,  # type: ignore[arg-type]
        None,  # flexopt evaluate: the nominal design's ConstantForceProblem.result
        problem,  # type: ignore[arg-type],
        requirements=_builtin.constant_force,
        quantities=_builtin.CONSTANT_FORCE,
        figures=FIGURES,
        design_space=lambda study: (design_space(study), design_vector(study)),
        width_key="design.B",  # B, the out-of-plane width, scales every force (flexopt retrim)
        # `flexopt list`'s line: the model's module is _constant_force_schema
        summary=(__doc__ or "").split("\n\n")[0].removeprefix("Study kind ``constant_force``:"),
    )
)
