"""Exact derivatives of a ``constant_force`` study's responses by its 23 design variables
(issue 27 items 1-2; :meth:`ConstantForceProblem.jacobian`, docs/sensitivities.md).

The chain, each link exact:

1. study variables -> beam profile: :func:`geometry.constant_force_map.profile_derivatives`
   (a linear map: ``a_j`` slides vertex p_j along its interval, the thicknesses and the width
   are copied);
2. beam profile -> every row of the traced path: :func:`fea.beam_sensitivity.beam_sensitivities`
   (direct method on the converged rows; the ``a_j`` as vertex moves, one variable each);
3. rows -> the study's responses:

   * Eq. 8's residuals ``r_i = F(s_i) - target`` with ``F(s_i)`` interpolated linearly between
     the rows at the probes ``s_i = stroke * i / samples``. Under displacement control the rows'
     strokes are prescribed, the same for every design, so the interpolation is a fixed matrix
     ``W`` (samples, rows) and ``dr/dx = W dF/dx`` exactly (a probe on a row reads that row);
   * the objective ``rms_error_N = sqrt(mean(r^2))``: ``d rms = r . dr / (n rms)``;
   * the constraint ``stress_ratio_minus_1 = peak * beam_stress_factor / allowable - 1``: the
     peak stress (max over rows and sampling points) is not differentiable where the maximum
     changes place, so its derivative is that of the KS aggregate over the signed outer-fibre
     stresses of every row and point, ``KS = 1/rho ln sum exp(rho sigma)``, with ``rho =
     KS_RHO_YIELD / yield_MPa`` (100 / yield; 2.35 /MPa for ABS): ``max <= KS <= max + ln(n) /
     rho``. The KS of the rows' KS values is the KS of all values (same rho), so it is
     aggregated from the per-row ones. The derivative of the max itself (the active point's,
     exact where the max is unique) is given too (``info["peak_stress_gradient"]``).

Rows after the beam's buckling onset (the branch guards' rows) are smooth in the design and are
differentiated like any other; the onset itself (the first rows, ~0.03 mm) is not a probe.
Returned as :class:`optimise.design_jacobian.DesignJacobian` in the problem's variable order.
Not differentiated (the hook answers None, the optimiser takes finite differences): the
``operative_stroke`` objective and the ``operative_stroke_shortfall_mm`` constraint (the band's
window ends are where the curve crosses the band: piecewise, and empty for most designs), a
design that cannot be built or whose path did not converge.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from flexopt.fea.beam import BeamModel, EndDrive
from flexopt.fea.beam_sensitivity import KS_RHO_YIELD, beam_sensitivities, ks_aggregate
from flexopt.fea.errors import FeaError
from flexopt.geometry.constant_force import design_from_vector
from flexopt.geometry.constant_force_map import profile_derivatives
from flexopt.geometry.errors import GeometryError
from flexopt.optimise.design_jacobian import DesignJacobian

__all__ = ["interpolation_matrix", "jacobian", "study_sensitivities"]

log = logging.getLogger(__name__)


def interpolation_matrix(stroke_mm: np.ndarray, probes_mm: np.ndarray) -> np.ndarray:
    """(n_probes, n_rows) W with ``W @ F == np.interp(probes_mm, stroke_mm, F)`` for every F
    (n_rows,): linear interpolation between the rows (strokes increasing, mm)."""
    s = np.asarray(stroke_mm, dtype=float)
    eye = np.eye(len(s))
    return np.stack([np.interp(probes_mm, s, eye[k]) for k in range(len(s))], axis=1)


def study_sensitivities(
    problem: Any,
    x: np.ndarray,
    beam: Callable[[Any], BeamModel],
    drive: Callable[[float, int], EndDrive],
    ks_rho_per_MPa: float | None = None,
) -> dict[str, Any] | None:
    """The study's responses at ``x`` (23,) and their derivatives by x, or None when the design
    cannot be built or its path did not converge.

    ``problem`` is the :class:`ConstantForceProblem`; ``beam(design)`` and ``drive(max_mm,
    steps)`` are its own builders (so the model is the one ``evaluate`` solves).

    Returns
    -------
    dict
        "residuals_N" (samples,), "d_residuals" (samples, 23) N per unit; "rms_error_N" and
        "d_rms" (23,); "ks_stress_MPa" (KS over every row and fibre) and "d_ks" (23,) MPa per
        unit; "peak_stress_MPa" (the max) and "d_peak" (23,) (the active point's derivative);
        "force_N" (rows,) and "d_force" (rows, 23) of the path; "rho" (1/MPa); "sensitivity"
        (the :class:`fea.beam_sensitivity.BeamSensitivity`); "time_s".
    """
    t0 = time.perf_counter()
    study = problem.study
    x = np.asarray(x, dtype=float)
    try:
        design = design_from_vector(x)
        model = beam(design)
        path = drive(study.boundary.stroke_mm, study.boundary.rows)
        response = model.solve(path)
    except (GeometryError, FeaError):
        return None
    if not response.ok:
        return None
    maps = profile_derivatives(problem.frame, study.geometry.end_flexures)
    moving = maps.moving  # a1..a10: one directional derivative each
    rho = KS_RHO_YIELD / problem.material.yield_MPa if ks_rho_per_MPa is None else ks_rho_per_MPa
    stroke = np.asarray(response.displacement_mm, dtype=float)  # prescribed: design-independent
    t = study.target
    probes = stroke[-1] * np.arange(1, t.samples + 1) / t.samples
    W = interpolation_matrix(stroke, probes)
    rows = np.union1d(np.flatnonzero(np.any(W != 0.0, axis=0)), _stress_rows(response, rho))
    sens = None
    # the semi-analytic vertex moves need the mesh (elements per segment, rounded from the
    # lengths) to stay the same over +-2 steps: a design that close to a switch of the rounding
    # gets a smaller step, and at the switch itself no derivative (the response jumps there)
    for scale in COORDINATE_STEPS:
        try:
            sens = beam_sensitivities(
                model,
                path,
                response,
                ("thickness", "width", "moves"),
                ks_rho_per_MPa=rho,
                coordinate_step_mm=scale * model.profile.length_mm,
                vertex_moves=maps.points[moving],
                move_names=tuple(maps.names[k] for k in moving),
                rows=rows,
            )
            break
        except FeaError:
            continue
    if sens is None:
        return None
    # chain: d/dx = d/dt (n_rows, 12) @ dt/dx (12, 23) + d/db dB/dx + d/dmove (one per a_j)
    n_pts = model.profile.n_points
    chain = np.zeros((len(sens.variables), len(x)))
    chain[:n_pts] = maps.thickness.T
    chain[n_pts] = maps.width
    chain[n_pts + 1 + np.arange(len(moving)), moving] = 1.0

    def by_x(key: str) -> np.ndarray:
        return sens.derivatives[key] @ chain

    force, d_force = sens.values["force_N"], by_x("force_N")
    used = W[:, rows]  # the rows not differentiated (NaN) have zero weight
    r = used @ force[rows] - t.force_N
    dr = used @ d_force[rows]
    rms = float(np.sqrt(np.mean(r**2)))
    d_rms = r @ dr / (len(r) * rms) if rms > 0 else np.zeros(len(x))
    ks_rows, d_ks_rows = sens.values["ks_stress_MPa"][rows], by_x("ks_stress_MPa")[rows]
    ks, w = ks_aggregate(ks_rows, rho)  # KS of the rows' KS = KS of every value (same rho)
    # the max's derivative: the active (row, point, fibre, sign) of the signed fibre stresses
    fibre = np.where(np.isnan(sens.fibre_stress_MPa), 0.0, sens.fibre_stress_MPa)
    row, samp, side = np.unravel_index(int(np.argmax(np.abs(fibre))), fibre.shape)
    sign = np.sign(fibre[row, samp, side])
    d_peak = sign * sens.d_fibre_stress[row, samp, side] @ chain
    return {
        "residuals_N": r,
        "d_residuals": dr,
        "rms_error_N": rms,
        "d_rms": d_rms,
        "ks_stress_MPa": float(ks),
        "d_ks": w @ d_ks_rows,
        "peak_stress_MPa": float(np.abs(fibre[row, samp, side])),
        "d_peak": d_peak,
        "peak_row": int(row),
        "force_N": force,
        "d_force": d_force,
        "rho": float(rho),
        "rows": rows,
        "sensitivity": sens,
        "time_s": time.perf_counter() - t0,
    }


#: the vertex moves' difference steps tried in turn, as fractions of the beam's length (the first
#: is beam_sensitivities' default; a smaller one only where the larger changes the mesh, at
#: the cost of round-off: ~1e-5 of a_j's column at 1e-7, ~1e-3 at 1e-8)
COORDINATE_STEPS = (1e-6, 1e-7, 1e-8)

#: rows whose largest stress lies more than (KS_ROW_CUT + ln(values per row)) / rho below the
#: path's peak are left out of the KS: a row's KS exceeds its max by at most ln(n) / rho, so its
#: weight in the path's KS is below exp(-KS_ROW_CUT) = 2e-9, and the ~60 rows together change
#: the KS gradient by < 1.2e-7 of its size (each row costs ~1.5 ms; 36 rows of 61 are kept on
#: the example's design instead of 44 at a cut of 36, and the tests' 1e-6 still hold)
KS_ROW_CUT = 20.0


def _stress_rows(response: Any, rho: float) -> np.ndarray:
    """(k,) int: the converged rows the KS of the whole path needs (see :data:`KS_ROW_CUT`)."""
    peak = np.where(response.converged, np.asarray(response.peak_stress_MPa, float), -np.inf)
    n_el = (np.asarray(response.shapes_mm).shape[1] - 1) // 2  # P2 elements: 2E + 1 nodes
    n_values = 4 * 3 * n_el  # 3 sampling points per element, 4 signed fibre values each
    return np.flatnonzero(peak >= peak.max() - (KS_ROW_CUT + np.log(n_values)) / rho)


def jacobian(
    problem: Any,
    x: np.ndarray,
    beam: Callable[[Any], BeamModel],
    drive: Callable[[float, int], EndDrive],
) -> DesignJacobian | None:
    """:meth:`ConstantForceProblem.jacobian`: the residuals', the objective's and the stress
    constraint's derivatives at ``x`` (23,); None for what is not differentiated (see the
    module's docstring)."""
    study = problem.study
    if study.objective != "rms_error" or tuple(problem.constraint_names) != (
        "stress_ratio_minus_1",
    ):
        return None
    try:
        out = study_sensitivities(problem, x, beam, drive)
    except Exception:  # a Jacobian is an aid: its failure must not end the run (FD instead)
        log.exception("constant_force: the Jacobian at %s raised; forward differences instead", x)
        return None
    if out is None:
        return None
    scale = study.fidelity.beam_stress_factor / problem.allowable_MPa
    counts = out["sensitivity"].counts
    return DesignJacobian(
        x=np.asarray(x, dtype=float).copy(),
        f=out["d_rms"][None, :],
        g=scale * out["d_ks"][None, :],
        residuals=out["d_residuals"],
        values={
            "f": np.array([out["rms_error_N"]]),
            "g": np.array([out["peak_stress_MPa"] * scale - 1.0]),
            "residuals": out["residuals_N"],
        },
        info={
            "stress_aggregate": "KS",
            "ks_rho_per_MPa": out["rho"],
            "ks_stress_MPa": out["ks_stress_MPa"],
            "peak_stress_MPa": out["peak_stress_MPa"],
            "peak_stress_gradient": scale * out["d_peak"],
            "time_s": out["time_s"],
            "back_substitutions": counts.get("back_substitutions", 0),
        },
    )
