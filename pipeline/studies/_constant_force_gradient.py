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
     exact where the max is unique) is given too (``info["peak_stress_gradient"]``);
   * the band row ``force_band_excess`` (``method: hybrid`` only; :mod:`._constant_force_band`,
     :func:`optimise.curve_objectives.force_band_ratio`) ``g = (max_k |F_k - target| -
     max(share tol target, reach rms)) / target`` over the judged rows k: a max, piecewise
     smooth, so its derivative is the active pieces', like the peak stress's: the worst judged
     row k (a traced row, no interpolation; differentiated besides the rows above) and the
     larger allowance, ``dg = (sign(F_k - target) dF_k - [reach d rms if reach rms > share tol
     target]) / target``; exact where the worst row and the larger allowance are unique.

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
from flexopt.fea.beam_statics import with_statics_stress
from flexopt.fea.errors import FeaError
from flexopt.geometry.constant_force import DESIGN_VARIABLE_NAMES, design_from_vector
from flexopt.geometry.constant_force_map import profile_derivatives
from flexopt.geometry.errors import GeometryError
from flexopt.optimise.curve_objectives import (
    BAND_REACH,
    BAND_ROW,
    BAND_SHARE,
    force_band_ratio,
)
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.pipeline.studies import _constant_force_fillet as pads
from flexopt.pipeline.studies import _constant_force_solved
from flexopt.pipeline.studies._constant_force_flare_map import flare_derivatives

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
    band: bool = False,
    window: bool = False,
) -> dict[str, Any] | None:
    """The study's responses at ``x`` (23,) and their derivatives by x, or None when the design
    cannot be built or its path did not converge.

    ``window``: of the stress rows the KS needs (:func:`_stress_rows`), only those within
    :data:`WINDOW_ROWS` of the path's peak are differentiated (:func:`_window_rows`): the
    Gauss-Newton problem's Jacobian (:meth:`ConstantForceProblem.jacobian` on the
    ``with_residuals`` copy), whose step reads the stress row as its pieces (all within
    :data:`PIECE_WINDOW` of the peak), never the KS row. The residuals, the objective, the
    pieces, the peak's and the band row's derivatives are the same to the bit; the KS (value
    and derivative) is then over those rows only (on the example's recorded design 38 rows
    become 27, the KS's derivative moves 1.2e-7 of its size, and the Jacobian takes ~30 ms
    instead of ~42; session 34).

    ``problem`` is the :class:`ConstantForceProblem`; ``beam(design)`` and ``drive(max_mm,
    steps)`` are its own builders (so the model is the one ``evaluate`` solves). ``band``: the
    band row's value and derivative too (its worst judged row is differentiated besides; the
    other responses are the same with or without it).

    Returns
    -------
    dict
        "residuals_N" (samples,), "d_residuals" (samples, 23) N per unit; "rms_error_N" and
        "d_rms" (23,); "ks_stress_MPa" (KS over every row and fibre) and "d_ks" (23,) MPa per
        unit; "peak_stress_MPa" (the max) and "d_peak" (23,) (the active point's derivative);
        "force_N" (rows,) and "d_force" (rows, 23) of the path; "rho" (1/MPa); "sensitivity"
        (the :class:`fea.beam_sensitivity.BeamSensitivity`); "time_s". With ``band``:
        "band_excess" (the row's value, a fraction of the target force) and "d_band" (23,) per
        unit, "band_row" (the worst judged row), "band_reach_active" (3 x the RMS error is the
        larger allowance).
    """
    t0 = time.perf_counter()
    study = problem.study
    x = np.asarray(x, dtype=float)
    fillet = study.geometry.pad_fillet_mm > 0
    # the path this process just solved at x (the trial design the stage accepted), when the
    # builders are the problem's own (_constant_force_solved: the same model and response)
    own = _builds(problem, beam, "_beam") and _builds(problem, drive, "_drive")
    kept = _constant_force_solved.kept(problem, x) if own else None
    try:
        path = drive(study.boundary.stroke_mm, study.boundary.rows)
        if kept is not None:
            design, model, response = kept
        else:
            design = design_from_vector(x)
            model = beam(design)
            solved_path = model.solve(path)
            # the study's stress: from statics (fea/beam_statics.py), with fillets the larger of
            # it and Kt x the stress over each flare; the rows are picked by it
            if fillet:
                response = pads.with_root_stress(problem, design, model, solved_path)
            else:
                response = with_statics_stress(model, solved_path, np.asarray(path.direction))
    except (GeometryError, FeaError):
        return None
    if not response.ok:
        return None
    if fillet:
        flare = flare_derivatives(problem, x)
        if flare is None:
            return None
        d_points, d_thick, d_width = flare.points, flare.thickness, flare.width
    else:
        flare = None
        maps = profile_derivatives(problem.frame, study.geometry.end_flexures)
        d_points, d_thick, d_width = maps.points, maps.thickness, maps.width
    moving = np.flatnonzero(np.any(d_points != 0.0, axis=(1, 2)))  # one directional derivative each
    rho = KS_RHO_YIELD / problem.material.yield_MPa if ks_rho_per_MPa is None else ks_rho_per_MPa
    stroke = np.asarray(response.displacement_mm, dtype=float)  # prescribed: design-independent
    t = study.target
    probes = stroke[-1] * np.arange(1, t.samples + 1) / t.samples
    W = interpolation_matrix(stroke, probes)
    stress_rows = _stress_rows(response, rho)
    if window:
        stress_rows = np.intersect1d(stress_rows, _window_rows(response))
    rows = np.union1d(np.flatnonzero(np.any(W != 0.0, axis=0)), stress_rows)
    worst = _band_row(study, response) if band else None
    near = _band_near_rows(study, response) if band else np.zeros(0, dtype=int)
    # the band's worst row and those near it are differentiated besides; the KS stays over
    # ``rows`` (the same KS with or without the band row)
    solved = rows if worst is None else np.union1d(np.union1d(rows, [worst]), near)
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
                vertex_moves=d_points[moving],
                move_names=tuple(DESIGN_VARIABLE_NAMES[k] for k in moving),
                rows=solved,
                stress="statics",
            )
            break
        except FeaError:
            continue
    if sens is None:
        return None
    # chain: d/dx = d/dt (n_rows, n_pts) @ dt/dx (n_pts, 23) + d/db dB/dx + d/dmove (one per
    # moving variable)
    n_pts = model.profile.n_points
    chain = np.zeros((len(sens.variables), len(x)))
    chain[:n_pts] = d_thick.T
    chain[n_pts] = d_width
    chain[n_pts + 1 + np.arange(len(moving)), moving] = 1.0

    def by_x(key: str) -> np.ndarray:
        return sens.derivatives[key] @ chain

    force, d_force = sens.values["force_N"], by_x("force_N")
    used = W[:, rows]  # the rows not differentiated (NaN) have zero weight
    r = used @ force[rows] - t.force_N
    dr = used @ d_force[rows]
    rms = float(np.sqrt(np.mean(r**2)))
    d_rms = r @ dr / (len(r) * rms) if rms > 0 else np.zeros(len(x))
    # the study's signed fibre values (rows, points, 2) and their derivatives by x: with
    # fillets, Kt x the beam's over each flare (the larger, so the peak is the study's)
    fibre, d_fibre = _judged_fibres(sens, chain, rows, flare, model.profile.length_mm)
    signed = np.concatenate([fibre, -fibre], axis=2)  # (k, S, 4): +-(a + c), +-(a - c)
    ks, w = ks_aggregate(signed.ravel(), rho)
    # the four values' weights folded onto the two fibres' derivatives (no (k, S, 4, 23) array
    # of the signed ones: ~6 MB of fresh pages a call, whose faults cost more than the sums)
    w = w.reshape(signed.shape)
    d_ks = (w[..., :2] - w[..., 2:]).ravel() @ d_fibre.reshape(-1, len(x))
    # the max's derivative: the active (row, point, fibre, sign) of the signed fibre values
    active = int(np.argmax(signed))
    row_k, samp, side = np.unravel_index(active, signed.shape)
    d_peak = _signed_derivative(d_fibre, row_k, samp, side)
    extra: dict[str, Any] = {}
    if worst is not None:
        extra = _band_sensitivity(study, response, worst, force, d_force, rms, d_rms, near)
    pieces = _stress_pieces(signed, d_fibre, sens.stress_s_mm, rows)
    return {
        "residuals_N": r,
        "d_residuals": dr,
        "rms_error_N": rms,
        "d_rms": d_rms,
        "ks_stress_MPa": float(ks),
        "d_ks": d_ks,
        "peak_stress_MPa": float(signed.max()),
        "d_peak": d_peak,
        "peak_row": int(rows[row_k]),
        "stress_pieces_MPa": pieces[0],
        "d_stress_pieces": pieces[1],
        "stress_pieces_where": pieces[2],
        "force_N": force,
        "d_force": d_force,
        "rho": float(rho),
        "rows": rows,
        "sensitivity": sens,
        "time_s": time.perf_counter() - t0,
        **extra,
    }


def _builds(problem: Any, builder: Callable[..., Any], name: str) -> bool:
    """``builder`` is ``problem``'s own method ``name`` (bound to it or to a copy of it): what
    :meth:`ConstantForceProblem._solve` built the kept solves with."""
    func = getattr(builder, "__func__", None)
    return func is not None and func is getattr(type(problem), name, None)


def _judged_fibres(
    sens: Any, chain: np.ndarray, rows: np.ndarray, flare: Any, length_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """The signed fibre stresses the study judges at ``rows`` (k,): (k, S, 2) MPa and their
    derivatives by the 23 variables (k, S, 2, 23) MPa per unit. Without fillets (``flare``
    None) the beam's (statics); with them each flare's sampling points (``s <= root_mm`` from
    S1, ``s >= L - root_mm`` from S6, as :func:`._constant_force_fillet.root_stress_MPa` takes
    them) carry Kt x the beam's, ``d(Kt sigma) = sigma dKt + Kt d sigma`` (the larger of the
    two, since Kt >= 1 and the signs agree)."""
    fibre = sens.fibre_stress_MPa[rows]
    # one (k S 2, n_var) @ (n_var, 23) product: the stacked 4-D matmul ran one small product
    # per (row, point), ~3x slower
    picked = sens.d_fibre_stress[rows]
    d_fibre = (picked.reshape(-1, chain.shape[0]) @ chain).reshape(*picked.shape[:-1], -1)
    if flare is None:
        return fibre, d_fibre
    s = np.asarray(sens.stress_s_mm, dtype=float)
    factor = np.ones(len(s))
    d_factor = np.zeros((len(s), chain.shape[1]))
    # 1e-9 mm: the toe is a node (a sampling point) of the flared beam
    for near, e in (
        (s <= flare.root_mm[0] + 1e-9, 0),
        (s >= length_mm - flare.root_mm[1] - 1e-9, 1),
    ):
        if flare.root_mm[e] > 0:
            factor[near] = flare.kt[e]
            d_factor[near] = flare.d_kt[e]
    # only the flares' points change (elsewhere Kt = 1, dKt = 0): those written over d_fibre, a
    # new array (k, S, 2, 23), in place of two more of its size
    at = np.flatnonzero((factor != 1.0) | np.any(d_factor != 0.0, axis=1))
    d_fibre[:, at] = (
        d_fibre[:, at] * factor[None, at, None, None]
        + fibre[:, at, :, None] * d_factor[None, at, None, :]
    )
    return fibre * factor[None, :, None], d_fibre


#: the stress pieces handed to the gradient stage: (row, element) maxima within this fraction of
#: the path's peak below it, at most :data:`MAX_PIECES` of them (the highest)
PIECE_WINDOW = 0.1
#: the Gauss-Newton Jacobian's stress rows (``window``): within this fraction of the peak, half
#: as much again as :data:`PIECE_WINDOW` (a row's peak and its judged fibre values are the same
#: stress, so the pieces' rows are all inside it)
WINDOW_ROWS = 1.5 * PIECE_WINDOW
MAX_PIECES = 48


def _signed_derivative(d_fibre: np.ndarray, row: Any, point: Any, value: Any) -> np.ndarray:
    """The derivative of signed fibre value(s) ``value`` (0..3: +(a + c), +(a - c), -(a + c),
    -(a - c)) at (``row``, ``point``) from the two fibres' ``d_fibre`` (k, S, 2, 23): the fibre's
    or its negation, exactly."""
    value = np.asarray(value)
    d = d_fibre[row, point, value % 2]
    return np.where((value < 2)[..., None], d, -d)


def _stress_pieces(
    signed: np.ndarray, d_fibre: np.ndarray, s_mm: np.ndarray, rows: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The peak stress as pieces for an active-set step (:mod:`optimise.hybrid`): the path's
    peak is the max of them, and each is a smooth function of the design. Why: the peak switches
    between the clamp and mid-beam, and one linearised row (the active point's, or the KS's
    blend) cannot see the other place rise. The (row, element) pairs whose largest value (of
    their 3 points x 4 signed fibre values; k rows, S = 3 E points) is within
    :data:`PIECE_WINDOW` of the peak (relative), at most :data:`MAX_PIECES` of them, highest
    first, give the pieces: each of their sampling points within the window is one, its value
    the largest of its 4 signed values.

    Why each sampling point, not only the element's largest (session 33): an element's points
    tie as the optimiser walks the design onto a ridge of the max, and a piece that is the
    element's largest point hides its neighbour rising. Measured on constant-force seed 1: the
    step held the element's active point (s = 7.43 mm, row 60) flat while the point beside it
    (6.41 mm, 1e-6 MPa lower) rose, so every trial of the last 14 iterations broke the stress
    row by up to 0.15 % and was rejected, whatever the radius. The elements are still chosen
    as before (at most 48): 48 points instead would cover a third of the beam's places, and a
    restoring start's step then missed a far place rising (a test's 16 x 2 GA start stayed
    infeasible). A point's 4 values (the two fibres, each signed) tie only where the stress is
    ~0, far below the peak.

    ``d_fibre`` (k, S, 2, 23): the two fibres' derivatives (a signed value's is one of them or its
    negation). Returns (p,) values MPa (p <= 3 MAX_PIECES; the elements' order, each element's
    points in order), (p, 23) derivatives MPa per unit, (p, 2) (row, arc length mm)."""
    k, n_s = signed.shape[:2]
    best = np.argmax(signed, axis=2)  # (rows, points): which of the 4 signed values
    point_value = np.take_along_axis(signed, best[..., None], axis=2)[..., 0]  # (rows, points)
    per_el = point_value.reshape(k, n_s // 3, 3)
    value = per_el.max(axis=2)  # (rows, elements)
    peak = float(value.max())
    floor = peak - PIECE_WINDOW * abs(peak)
    cand = np.flatnonzero(value.ravel() >= floor)
    cand = cand[np.argsort(-value.ravel()[cand], kind="stable")][:MAX_PIECES]
    row_i, el = np.unravel_index(cand, value.shape)
    # every point of the chosen elements within the window (the element's largest always)
    row_i = np.repeat(row_i, 3)
    point = (3 * np.repeat(el, 3) + np.tile(np.arange(3), len(el))).astype(int)
    keep = point_value[row_i, point] >= floor
    row_i, point = row_i[keep], point[keep]
    d = _signed_derivative(d_fibre, row_i, point, best[row_i, point])
    where = np.column_stack([rows[row_i], s_mm[point]])
    return point_value[row_i, point], d, where


def _band_row(study: Any, response: Any) -> int:
    """The band row's active row: the judged row (from the first, ``stroke / rows`` mm: the
    verdict's, as :func:`._constant_force_band.band_rows` passes it) farthest from the target
    force, by the traced forces ``evaluate`` judges (the first of equals, as ``np.max`` finds
    the value)."""
    s = np.asarray(response.displacement_mm, dtype=float)
    f = np.asarray(response.force_N, dtype=float)
    first_mm = study.boundary.stroke_mm / study.boundary.rows
    judged = np.flatnonzero(s >= first_mm - 1e-9 * max(1.0, abs(first_mm)))
    return int(judged[np.argmax(np.abs(f[judged] - study.target.force_N))])


#: the band row's pieces: the judged rows whose |F - target| is within this fraction of the
#: allowance below the worst row's, at most :data:`MAX_BAND_PIECES` of them (the worst first)
BAND_WINDOW = 0.5
MAX_BAND_PIECES = 24


def _band_near_rows(study: Any, response: Any) -> np.ndarray:
    """(p,) int: the judged rows whose ``|F - target|`` is within :data:`BAND_WINDOW` x the
    held share of the band below the worst row's, the worst first, at most
    :data:`MAX_BAND_PIECES` (the band row's pieces: the worst row switches as the design moves,
    and the gradient stage is to see the next one coming)."""
    t = study.target
    s = np.asarray(response.displacement_mm, dtype=float)
    f = np.asarray(response.force_N, dtype=float)
    first_mm = study.boundary.stroke_mm / study.boundary.rows
    judged = np.flatnonzero(s >= first_mm - 1e-9 * max(1.0, abs(first_mm)))
    error = np.abs(f[judged] - t.force_N)
    held = BAND_SHARE * t.tolerance_percent / 100.0 * abs(t.force_N)
    order = np.argsort(-error, kind="stable")
    keep = order[error[order] >= error.max() - BAND_WINDOW * held][:MAX_BAND_PIECES]
    return judged[keep]


def _band_sensitivity(
    study: Any,
    response: Any,
    k: int,
    force: np.ndarray,
    d_force: np.ndarray,
    rms: float,
    d_rms: np.ndarray,
    near: np.ndarray | None = None,
) -> dict[str, Any]:
    """The band row's value and its derivative (23,) at the active pieces: the worst judged row
    ``k`` (``force`` (rows,) N and ``d_force`` (rows, 23) N per unit of the polished rows) and
    the larger allowance (the held share of the band, fixed, or ``BAND_REACH`` x the RMS error
    ``rms`` N with derivative ``d_rms`` (23,)). With ``near`` (p,) rows: the row as pieces too,
    one per row, ``(|F_j - target| - allowance) / target`` and its derivative (the active
    allowance's), "band_pieces" (p,) and "d_band_pieces" (p, 23)."""
    t = study.target
    target = abs(t.force_N)
    tol = t.tolerance_percent / 100.0
    reach_active = BAND_REACH * rms > BAND_SHARE * tol * target
    d_band = np.sign(force[k] - t.force_N) * d_force[k]
    if reach_active:
        d_band = d_band - BAND_REACH * d_rms
    value = force_band_ratio(
        response.displacement_mm,
        response.force_N,
        t.force_N,
        tol,
        study.boundary.stroke_mm / study.boundary.rows,
        rms_error_N=rms,
    )
    extra: dict[str, Any] = {}
    if near is not None and len(near):
        sign = np.sign(force[near] - t.force_N)
        allowed = max(BAND_SHARE * tol * target, BAND_REACH * rms)
        d_allowed = BAND_REACH * d_rms if reach_active else np.zeros_like(d_rms)
        extra = {
            "band_pieces": (np.abs(force[near] - t.force_N) - allowed) / target,
            "d_band_pieces": (sign[:, None] * d_force[near] - d_allowed[None, :]) / target,
        }
    return {
        **extra,
        "band_excess": float(value),
        "d_band": d_band / target,
        "band_row": int(k),
        "band_reach_active": bool(reach_active),
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


def _window_rows(response: Any) -> np.ndarray:
    """(k,) int: the converged rows whose peak stress lies within :data:`WINDOW_ROWS` of the
    path's peak (below it): every row that holds a stress piece (:func:`_stress_pieces` takes
    the sampling points within :data:`PIECE_WINDOW` of the peak), with room to spare. (Where the
    peak is far above the yield, ~114 MPa for ABS, the KS's rows (:data:`KS_ROW_CUT`) are fewer
    than the pieces' window: a row beyond them is not differentiated and holds no piece, with
    or without ``window``.)"""
    peak = np.where(response.converged, np.asarray(response.peak_stress_MPa, float), -np.inf)
    return np.flatnonzero(peak >= (1.0 - WINDOW_ROWS) * peak.max())


def jacobian(
    problem: Any,
    x: np.ndarray,
    beam: Callable[[Any], BeamModel],
    drive: Callable[[float, int], EndDrive],
    window: bool = False,
) -> DesignJacobian | None:
    """:meth:`ConstantForceProblem.jacobian`: the residuals', the objective's, the stress
    constraint's and (``method: hybrid``) the band row's derivatives at ``x`` (23,); None for
    what is not differentiated (see the module's docstring). ``window``: the stress row's KS
    over the rows near the peak only (:func:`study_sensitivities`), for a Gauss-Newton step,
    which reads its pieces."""
    study = problem.study
    names = tuple(problem.constraint_names)
    if study.objective != "rms_error" or names not in (
        ("stress_ratio_minus_1",),
        ("stress_ratio_minus_1", BAND_ROW),
    ):
        return None
    band = names[-1] == BAND_ROW
    try:
        out = study_sensitivities(problem, x, beam, drive, band=band, window=window)
    except Exception:  # a Jacobian is an aid: its failure must not end the run (FD instead)
        log.exception("constant_force: the Jacobian at %s raised; forward differences instead", x)
        return None
    if out is None:
        return None
    scale = study.fidelity.beam_stress_factor / problem.allowable_MPa
    counts = out["sensitivity"].counts
    g = [scale * out["d_ks"]]
    g_values = [out["peak_stress_MPa"] * scale - 1.0]
    # the stress row as pieces (its max): an active-set step sees where the peak may move
    pieces = {
        0: {
            "values": scale * out["stress_pieces_MPa"] - 1.0,
            "gradients": scale * out["d_stress_pieces"],
        }
    }
    band_info: dict[str, Any] = {}
    if band:
        if not np.all(np.isfinite(out["d_band"])):  # the worst row not differentiated
            return None
        g.append(out["d_band"])
        g_values.append(out["band_excess"])
        if "band_pieces" in out and np.all(np.isfinite(out["d_band_pieces"])):
            pieces[1] = {"values": out["band_pieces"], "gradients": out["d_band_pieces"]}
        band_info = {"band_row": out["band_row"], "band_reach_active": out["band_reach_active"]}
    return DesignJacobian(
        x=np.asarray(x, dtype=float).copy(),
        f=out["d_rms"][None, :],
        g=np.stack(g),
        residuals=out["d_residuals"],
        values={
            "f": np.array([out["rms_error_N"]]),
            "g": np.array(g_values),
            "residuals": out["residuals_N"],
        },
        info={
            # "KS near the peak": over the rows within WINDOW_ROWS of it (``window``)
            "stress_aggregate": "KS near the peak" if window else "KS",
            "ks_rho_per_MPa": out["rho"],
            "ks_stress_MPa": out["ks_stress_MPa"],
            "peak_stress_MPa": out["peak_stress_MPa"],
            "peak_stress_gradient": scale * out["d_peak"],
            "time_s": out["time_s"],
            "back_substitutions": counts.get("back_substitutions", 0),
            "g_pieces": pieces,
            **band_info,
        },
    )
