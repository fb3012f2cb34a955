"""Exact derivatives of a ``mechanism`` study's objectives and constraint rows by its design
variables (issue 27 items 1-2; :meth:`MechanismProblem.jacobian`, docs/sensitivities.md).

The chain:

1. variables -> the solver's mechanism: :func:`design_mechanism`, the kind's own map (the
   ``variables:`` applied to the geometry, the beams as made (:func:`as_made_beams`, the first
   step of :func:`build_outline`), the solver's mechanism of them (:func:`build_mechanism`))
   evaluated at the stencil's designs inside
   :func:`fea.mechanism_sensitivity.mechanism_sensitivities`: the design terms of the KKT
   system are central differences of the residual at a fixed state between models built at
   ``x +- h e_i, x +- 2 h e_i``, so whatever the variables move (thicknesses, end points, the
   shuttle's reference point, the flares of the roots) is differentiated with the map;
2. mechanism -> every converged row of every load case: the direct method on the engine's KKT
   matrix (one factorisation per row, one back-substitution per variable): the outputs, the
   drive's reaction, each beam's peak and root stress (the active point's derivative), the
   node positions and body poses, and the KS aggregate of the signed fibre stresses;
3. rows -> the study's objectives and constraint rows: the kind's own evaluation (width solved
   from its requirement, slopes, the as-made stress with the roots' Kt, the optimiser's stress
   factor, the metrics and verdicts) applied to the *linearised* responses ``y(x) + s dy/dx_i``
   at the design ``x + s e_i`` (``MechanismProblem.given_responses``), central differences in
   ``s``. No solve is differenced: the evaluation after the solve is a cheap, explicit function
   of the responses and the geometry, and a difference of it at a step of 1e-6 of the range
   is exact to ~1e-9 where it is smooth. Where a metric is a max (the peak stress over rows and
   beams, the extreme stiffness), the result is the derivative of the active piece: exact where
   the max is unique, as the optimiser's linearisation of the max it is judged by.

The KS aggregate (``rho = 100 / yield``) and its gradient are in ``info`` besides the max's,
for comparison, and so are the solved width and its gradient (``width_mm``, ``width_gradient``
(n_var,) mm per unit). Not differentiated (the hook answers None; the hybrid takes forward
differences): a study with stops or beam contact, a path that loses stability (solved again
with an imperfection, or cut), a design that cannot be built or solved, a mesh that changes
within the stencil (a beam without ``elements:`` whose element count follows its length).
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
import time
from typing import Any

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.mechanism import first_unstable_row
from flexopt.fea.mechanism_sensitivity import MechanismSensitivity, mechanism_sensitivities
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.mechanism import BeamShape, BodyShape, as_made_beams, attachments
from flexopt.optimise.design_jacobian import DesignJacobian
from flexopt.pipeline.studies._mechanism_schema import (
    MechanismGeometry,
    build_load_case,
    build_mechanism,
    build_outputs,
)
from flexopt.pipeline.studies._mechanism_stops import with_stops
from pydantic import ValidationError

__all__ = ["case_sensitivities", "design_mechanism", "mechanism_jacobian"]

log = logging.getLogger(__name__)

#: the step of the evaluation's central difference, as a fraction of each variable's range
POST_STEP = 1e-6
#: the step of the residual's stencil (fea.mechanism_sensitivity), as a fraction of the range:
#: the residual at a fixed state is far more curved in a vertex's position than the response
#: (short, stiff elements at the flares): on constant-force-mechanism's a3 the second-order
#: stencil was 5.7e-4 off at 1e-4 of the range, 6e-6 at 1e-5, within the reference's 3e-7 at
#: 1e-6 (falling as h^2), and the fourth-order one at 1e-4 met a switch of the mesh at 2h
MAP_STEP = 1e-6
#: its order (2: two models of the design per variable; see docs/sensitivities.md)
MAP_STENCIL = 2


def design_mechanism(problem: Any, x: np.ndarray) -> Any:
    """The solver's :class:`fea.mechanism.Mechanism` of design ``x`` (n_var,), as
    :meth:`MechanismProblem.solve` builds it: the beams as made, the geometry's width, the
    study's stops. Raises GeometryError / ValidationError where it cannot be built."""
    study = problem.study
    raw = problem.variables.apply(
        {"geometry": study.geometry.model_dump(mode="json", exclude_none=True)}, x
    )
    geometry = MechanismGeometry.model_validate(raw["geometry"])
    # the beams as made, as build_outline makes them (its first step), without the outline's
    # polygons and checks (shapely: ~3/4 of its time), which the solver does not read
    shapes = [BeamShape(n, b.centreline(), b.thickness()) for n, b in geometry.beams.items()]
    bodies = [
        BodyShape(n, np.array(b.outline_mm, dtype=float))
        for n, b in geometry.bodies.items()
        if b.outline_mm is not None
    ]
    joined = attachments([(j.a, j.b) for j in geometry.joints], list(geometry.bodies))
    made = as_made_beams(
        shapes, bodies, joined, geometry.pad_thickness_mm, geometry.fillet_mm,
        geometry.max_corner_deg, math.inf,
    )  # fmt: skip
    mech = build_mechanism(geometry, study.material.to_material(), None, made)
    return with_stops(mech, study)


def case_sensitivities(
    problem: Any,
    x: np.ndarray,
    case: str,
    response: Any = None,
    rows: Any = None,
    stencil: int | None = None,
) -> MechanismSensitivity:
    """:func:`fea.mechanism_sensitivities` of load case ``case`` of design ``x`` (n_var,) through
    the study's map; steps ``MAP_STEP`` of each variable's range."""
    space = problem.space
    steps = MAP_STEP * (np.asarray(space.upper, float) - np.asarray(space.lower, float))
    return mechanism_sensitivities(
        lambda xx: design_mechanism(problem, xx),
        np.asarray(x, dtype=float),
        build_load_case(problem.study, case),
        build_outputs(problem.study, case),
        None,
        response,
        steps,
        rows,
        stencil=MAP_STENCIL if stencil is None else stencil,
    )


def _shifted(response: Any, sens: MechanismSensitivity, i: int, s: float) -> Any:
    """``response`` with every differentiated field moved by ``s`` times its derivative by
    variable ``i`` on the rows differentiated (the linearised response at ``x + s e_i``)."""
    rows = sens.rows
    d = sens.derivatives
    outputs = {}
    for name, col in response.outputs.items():
        col = np.array(col, dtype=float)
        col[rows] += s * d[name][:, i]
        outputs[name] = col
    peak = np.array(response.peak_stress_MPa, dtype=float)
    peak[rows] += s * d["peak_stress_MPa"][..., i]
    roots = np.array(response.root_stress_MPa, dtype=float)
    roots[rows] += s * d["root_stress_MPa"][..., i]
    poses = np.array(response.body_poses, dtype=float)
    poses[rows] += s * d["body_poses"][..., i]
    thick, shapes, start = [], [], 0
    for shape in response.shapes_mm:
        shape = np.array(shape, dtype=float)
        n = shape.shape[1]
        shape[rows] += s * d["nodes_mm"][:, start : start + n, :, i]
        shapes.append(shape)
        # the band's thickness depends on the design only: every row's derivative is the same
        t = d["thickness_at_nodes_mm"][0, start : start + n, i] if rows.size else 0.0
        thick.append(np.asarray(response.thickness_at_nodes_mm[len(thick)], float) + s * t)
        start += n
    return dataclasses.replace(
        response,
        outputs=outputs,
        peak_stress_MPa=peak,
        root_stress_MPa=roots,
        body_poses=poses,
        shapes_mm=tuple(shapes),
        thickness_at_nodes_mm=tuple(thick),
    )


def _post(
    problem: Any, x: np.ndarray, responses: dict[str, Any], extend: Any = None
) -> tuple[np.ndarray, ...]:
    """(f, g, [width_mm]) of the kind's evaluation of ``x`` with the given responses (no solve),
    with a wrapper's rows (``extend``: Evaluation -> Evaluation) where given."""
    given = copy.copy(problem)
    given.given_responses = responses
    ev = given.evaluate(np.asarray(x, dtype=float))
    if extend is not None and not ev.reason:
        ev = extend(ev)
    if ev.reason:
        raise FeaError(f"the evaluation of the linearised responses failed: {ev.reason}")
    width = ev.metrics.get("width_mm")
    width = np.array([float(width) if width is not None else math.nan])
    return np.asarray(ev.f, dtype=float), np.asarray(ev.g, dtype=float), width


def mechanism_jacobian(problem: Any, x: np.ndarray, extend: Any = None) -> DesignJacobian | None:
    """The :class:`optimise.DesignJacobian` of design ``x`` (n_var,): ``f`` (n_obj, n_var),
    ``g`` (n_con, n_var), each row in its own unit per unit of the variable; None where the
    design or the study is not differentiated (module docstring). ``extend`` (Evaluation ->
    Evaluation): a wrapper's extra rows of the metrics (pipeline.verdict.RequirementConstraints),
    differentiated with the rest."""
    t0 = time.process_time()
    x = np.asarray(x, dtype=float)
    if problem.variables is None or x.size == 0:
        return None
    solved = problem.solve(x)
    if isinstance(solved, tuple) or solved.reason:
        return None
    sens: dict[str, MechanismSensitivity] = {}
    try:
        for case, response in solved.responses.items():
            if first_unstable_row(response) is not None:
                return None  # solved again with an imperfection, or cut: not this path's
            sens[case] = case_sensitivities(problem, x, case, response)
    except (FeaError, GeometryError, ValidationError) as exc:
        log.debug("mechanism jacobian: not differentiated (%s)", exc)
        return None
    span = np.asarray(problem.space.upper, float) - np.asarray(problem.space.lower, float)
    try:
        f0, g0, w0 = _post(problem, x, dict(solved.responses), extend)
        F = np.zeros((f0.size, x.size))
        G = np.zeros((g0.size, x.size))
        W = np.zeros(x.size)  # d(width_mm)/dx: the width solved from its requirement
        for i in range(x.size):
            e = POST_STEP * span[i]
            ends = []
            for s in (e, -e):
                xs = x.copy()
                xs[i] += s
                shifted = {c: _shifted(r, sens[c], i, s) for c, r in solved.responses.items()}
                ends.append(_post(problem, xs, shifted, extend))
            F[:, i], G[:, i], W[i : i + 1] = ((a - b) / (2 * e) for a, b in zip(*ends, strict=True))
    except (FeaError, GeometryError, ValidationError) as exc:
        log.debug("mechanism jacobian: the linearised evaluation failed (%s)", exc)
        return None
    info = {
        "ks_MPa": {c: s.ks_MPa for c, s in sens.items()},
        "ks_gradient": {c: s.d_ks for c, s in sens.items()},
        "rho_per_MPa": next(iter(sens.values())).rho,
        "force_mismatch": max(s.force_mismatch for s in sens.values()),
        "width_mm": float(w0[0]),
        "width_gradient": W,
        "cpu_s": time.process_time() - t0,
    }
    return DesignJacobian(x=x, f=F, g=G, values={"f": f0, "g": g0}, info=info)
