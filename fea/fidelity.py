"""Checking a beam model against plane stress: the same part meshed, solved from the beam's shape.

The ``constant_force`` kind's independent check (``fidelity:`` block): the outline of the beam
with its pads is meshed with quadratic triangles and solved geometrically nonlinear (total
Lagrangian SVK, :mod:`fea.plane_stress`) at chosen strokes, Newton started from the beam's deformed
shape mapped onto the mesh (:func:`beam_to_mesh`). Moved here from
``pipeline/studies/constant_force.py`` (``fidelity_check`` there reads the study and calls
:func:`plane_stress_check`).

Speed (issue 13, the constant-force run's report): Newton factorises through the model's own
solver (CHOLMOD with the pattern's analysis kept when cvxopt imports, else QDLDL's LDLᵀ the same
way; SuperLU where a tangent is not positive definite, SuperLU alone otherwise) on the reduced
matrix the assembly writes, the stability eigenvalue reuses the model's factor of the converged
tangent, and the mesh nodes are located on the beam once. Same answers to Newton tolerance
(forces 1e-10, eigenvalue 1e-8); the shipped study's check 1.2-1.7 s -> 0.27-0.31 s CPU.
Units: mm, N, MPa.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from flexopt.fea.beam import BeamModel, BeamResponse
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Translate
from flexopt.fea.plane_stress_fields import mesh_arrays, state_field
from flexopt.geometry.errors import GeometryError
from shapely.geometry import Polygon

__all__ = ["EIGEN_NCV", "beam_to_mesh", "plane_stress_check"]

#: Lanczos vectors of the stability eigenvalue's shift-invert ARPACK (see _eigenvalue_nearest_zero)
EIGEN_NCV = 6


def beam_to_mesh(beam: BeamModel, shape_mm: np.ndarray, points_mm: np.ndarray) -> np.ndarray:
    """Displacement (k, 2) mm of plane-stress nodes ``points_mm`` (k, 2) that follows the beam.

    Each node is located on the reference centreline (arc length ``s``, normal offset ``eta``)
    and carried to the deformed centreline point at ``s`` plus ``eta`` along the deformed normal
    (plane sections stay plane and normal: the beam's kinematics without shear). Nodes beyond the
    ends (the pads) take the end's motion; their values are replaced by the supports anyway.
    """
    s, eta = _locate(beam, points_mm)
    return _carry(beam, s, eta, shape_mm, points_mm)


def _frame(s_nodes: np.ndarray, xy: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centreline point (k, 2) mm and unit normal (k, 2) at arc lengths s (k,) of nodes xy."""
    angle = np.unwrap(np.arctan2(np.gradient(xy[:, 1], s_nodes), np.gradient(xy[:, 0], s_nodes)))
    a = np.interp(s, s_nodes, angle)
    base = np.column_stack([np.interp(s, s_nodes, xy[:, 0]), np.interp(s, s_nodes, xy[:, 1])])
    return base, np.column_stack([-np.sin(a), np.cos(a)])


def _locate(beam: BeamModel, points_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arc length s (k,) mm and normal offset eta (k,) mm of points (k, 2) on the reference.

    The shape-independent half of :func:`beam_to_mesh`, done once per mesh instead of once per
    checked stroke. ``s`` is the compiled projection of :mod:`fea._polyline_kernels`: the same
    bits as shapely's ``line_locate_point`` (GEOS's), ~8 ms CPU on the constant-force check's
    ~9k nodes where shapely's took 64-93 ms (session 32; not ~30 ms as this said before).
    """
    from flexopt.fea._polyline_kernels import polyline_arc_length

    ref = np.ascontiguousarray(beam.reference_nodes_mm, dtype=float)
    points_mm = np.ascontiguousarray(points_mm, dtype=float)
    s = polyline_arc_length(ref, points_mm)
    base0, n0 = _frame(beam.s_nodes, ref, s)
    return s, np.einsum("ij,ij->i", points_mm - base0, n0)


def _carry(
    beam: BeamModel, s: np.ndarray, eta: np.ndarray, shape_mm: np.ndarray, points_mm: np.ndarray
) -> np.ndarray:
    """Displacement (k, 2) mm of the points located at (s, eta) when the beam takes shape_mm."""
    base, n = _frame(beam.s_nodes, np.asarray(shape_mm, dtype=float), s)
    return base + eta[:, None] * n - points_mm


def _norm(v: np.ndarray) -> float:
    """Euclidean norm of a vector without BLAS: numpy's dot wakes OpenBLAS's threads for a
    10k-vector, which cost ~2 ms a call (CPU time on both cores) inside this Newton."""
    return float(np.sqrt(np.einsum("i,i->", v, v)))


def _eigenvalue_nearest_zero(model: PlaneStressModel, K: sp.csr_matrix) -> float:
    """Eigenvalue (N/mm) of the reduced tangent ``P^T K P`` nearest to zero, by shift-invert.

    With the model's Cholesky solver (CHOLMOD, or QDLDL's LDLᵀ), K is factorised the model's
    way (the pattern's analysis kept; SuperLU where K is not positive definite) and that factor
    is the shift-invert operator at shift 0: one numerical Cholesky instead of the SuperLU of
    ``K + 1e-9 I`` that ``eigsh`` makes by itself, which still runs for the other solvers.
    """
    reduced = model.reduced(K)
    # ncv: ARPACK's Lanczos basis. Its default for k = 1 (20 vectors) costs 21 solves with the
    # factor however fast the eigenvalue converges; here 1/lambda_min dominates the inverse's
    # spectrum (lambda_min ~2e-4 N/mm on the constant-force check, a post-buckled strip) and 6
    # vectors converge to the same tolerance (machine precision: tol=0) in 10-13 solves, the
    # eigenvalue within 4 ulp of the 20-vector one (session 32: docs/benchmarks.md, "The
    # constant-force check's cost").
    # ARPACK's own start vector comes from a generator whose state runs on through a process:
    # the same tangent gave another last digit in another call or worker. A fixed start
    # vector makes the eigenvalue a function of K alone (the same bits in every process).
    v0 = np.random.default_rng(0).standard_normal(reduced.shape[0])
    factor = model.cholesky_factor(K)  # factorises K (or keeps it)
    if factor is not None:
        inverse = spla.LinearOperator(reduced.shape, matvec=factor.solve, dtype=float)
        values = spla.eigsh(
            reduced,
            k=1,
            sigma=0.0,
            OPinv=inverse,
            which="LM",
            return_eigenvectors=False,
            v0=v0,
            ncv=min(EIGEN_NCV, reduced.shape[0]),
        )
    else:
        values = spla.eigsh(
            reduced,
            k=1,
            sigma=-1e-9,
            which="LM",
            return_eigenvectors=False,
            v0=v0,
            ncv=min(EIGEN_NCV, reduced.shape[0]),
        )
    return float(values[0])


def plane_stress_check(
    beam: BeamModel,
    shape: Polygon,
    material: Material,
    thickness_mm: float,
    pad_length_mm: float,
    pad_thickness_mm: float,
    work_direction: Sequence[float],
    response: BeamResponse,
    rows: np.ndarray,
    hi: float,
    max_edge_mm: float,
    refine: Any = None,
    eigenvalue: bool = True,
) -> dict[str, Any]:
    """Check the beam model against a plane-stress, geometrically nonlinear FEA of the outline.

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

    Newton's linear solves are the model's (``PlaneStressModel.reduced_solve``: CHOLMOD or
    QDLDL, and SuperLU for a tangent that is not positive definite); the eigenvalue is
    shift-invert Lanczos on the model's factor of the converged tangent
    (:func:`_eigenvalue_nearest_zero`). Before, every iteration and every eigenvalue made a fresh
    SuperLU factorisation (~40 ms each on the shipped study's 11k DOFs, against ~3 ms for
    CHOLMOD's numerical factorisation).

    Stresses in elements touching the pads are left out: the re-entrant pad corners are singular
    in 2D elasticity and have no counterpart in the beam. The plane-stress stress is the nodal
    (vertex-averaged) von Mises stress; the beam's is ``|N|/A + |M| c / I``.

    Parameters
    ----------
    beam : BeamModel — the beam that gave ``response`` (its reference centreline and nodes).
    shape : Polygon — the outline to mesh (beam plus pads), mm.
    material : Material
    thickness_mm : float, mm — the out-of-plane width of the part (B).
    pad_length_mm, pad_thickness_mm : float, mm — the pads at both ends of the beam.
    work_direction : (2,) float — the drive's direction (unit vector).
    response : BeamResponse — the beam's traced response.
    rows : (k,) int — the rows of ``response`` to check.
    hi : float, mm — the largest stroke (the drive's ``max_mm``; each stroke is prescribed).
    max_edge_mm : float, mm — the largest triangle edge.
    refine : optional local sizes for :func:`fea.mesh.mesh_polygon` (``(geometry, edge mm)``
        regions or a size field); None: ``max_edge_mm`` everywhere.
    eigenvalue : False: no stability eigenvalue (``stable`` and
        ``min_tangent_eigenvalue_N_per_mm`` None at every row), for a caller that reads none of
        them (the constant-force peak's refined re-solve: its factorisation and ~10 solves, ~20
        ms a row, session 32); every other figure is the same computation either way.

    Returns
    -------
    dict
        ``stroke_mm``, ``beam_force_N``, ``plane_stress_force_N``, ``relative_difference``
        (plane stress / beam - 1), ``max_abs_relative_difference``, ``within_5_percent``, peak
        stresses and transverse forces of both, ``stable``, Newton iterations, mesh size and
        time; or ``skipped`` with the reason.
    """
    t0 = time.perf_counter()
    stroke_rows = np.asarray(response.displacement_mm, dtype=float)
    try:
        pts = beam.profile.points_mm

        def pad(end: np.ndarray, outward: np.ndarray) -> Polygon:
            # The pad, grown by a hair so that nodes on its edges are inside it for the selection.
            outward = outward / np.linalg.norm(outward)
            n = np.array([-outward[1], outward[0]]) * (0.5 * pad_thickness_mm + 1e-3)
            far = end + outward * (pad_length_mm + 1e-3)
            return Polygon([end - n, far - n, far + n, end + n])

        clamp = pad(pts[0], pts[0] - pts[1])
        driven = pad(pts[-1], pts[-1] - pts[-2])
        mesh = mesh_polygon(shape, max_edge_mm, refine)
        # The drive's max_mm and steps are not used: each stroke is prescribed directly.
        model = PlaneStressModel(
            mesh,
            material,
            thickness_mm,
            Clamp(clamp),
            Translate(driven, work_direction, hi, 1, "fixed"),
            stress_ignore=clamp.union(driven),
        )
    except (GeometryError, FeaError) as exc:
        return {"skipped": f"could not build the plane-stress model: {exc}"}
    cfg = model.settings
    direction = np.asarray(work_direction, dtype=float)
    normal = np.array([-direction[1], direction[0]])
    out: dict[str, list] = {
        "force": [],
        "transverse": [],
        "stress": [],
        "iterations": [],
        "converged": [],
        "stable": [],
        "eig": [],
        "moved": [],
    }
    located = _locate(beam, model.xy)  # the nodes on the reference centreline, once
    states = []  # each checked row's field (fea/plane_stress_fields.py), for best.vtu
    for k in rows:
        guess = _carry(beam, *located, response.shapes_mm[k], model.xy)
        u = np.zeros(model.n_dofs)
        u[model.ix], u[model.iy] = guess[:, 0], guess[:, 1]
        u = model.P @ (model.PT @ u) + model.prescribed(float(stroke_rows[k]), "nonlinear")
        u_start = u.copy()
        converged = False
        iterations = 0
        for it in range(1, cfg.max_newton_iter + 1):
            iterations = it
            state = model.state(u, "nonlinear")
            residual = model.PT @ state.f
            scale = _norm(state.f)
            if _norm(residual) <= cfg.rtol_residual * scale + cfg.atol_residual_N:
                converged = state.min_det_F >= cfg.min_det_F
                break
            # The model's own factoriser: CHOLMOD with the pattern's analysis kept (when cvxopt
            # imports), SuperLU where a tangent is not positive definite; SuperLU otherwise.
            u = u + model.P @ model.reduced_solve(state.K, -residual)
        reaction = np.array([state.f[model.drive_dofs_x].sum(), state.f[model.drive_dofs_y].sum()])
        # The eigenvalue nearest to zero: negative means an unstable equilibrium.
        eig = _eigenvalue_nearest_zero(model, state.K) if eigenvalue else None
        moved = np.hypot(*(u - u_start)[np.stack([model.ix, model.iy])]).max()
        out["force"].append(float(reaction @ direction))
        out["transverse"].append(float(reaction @ normal))
        out["stress"].append(float(model.peak_stress(u, "nonlinear")[2]))
        out["iterations"].append(iterations)
        out["converged"].append(bool(converged))
        out["eig"].append(eig)
        out["stable"].append(bool(eig > 0) if eig is not None else None)
        out["moved"].append(float(moved))
        states.append(state_field(model, u, "nonlinear") | {"drive_value": float(stroke_rows[k])})
    beam_f = np.asarray(response.force_N)[rows]
    ps_f = np.array(out["force"])
    rel = ps_f / beam_f - 1.0
    ok = all(out["converged"])
    return {
        "model": "plane stress, total Lagrangian SVK, P2 triangles (fea.plane_stress), "
        "Newton from the beam's deformed shape",
        "stroke_mm": stroke_rows[rows].tolist(),
        "beam_force_N": beam_f.tolist(),
        "plane_stress_force_N": ps_f.tolist(),
        "relative_difference": rel.tolist(),
        "max_abs_relative_difference": float(np.max(np.abs(rel))),
        "within_5_percent": bool(ok and np.max(np.abs(rel)) <= 0.05),
        "beam_peak_stress_MPa": np.asarray(response.peak_stress_MPa)[rows].tolist(),
        "plane_stress_peak_nodal_von_mises_MPa": out["stress"],
        "beam_transverse_force_N": np.asarray(response.transverse_force_N)[rows].tolist(),
        "plane_stress_transverse_force_N": out["transverse"],
        "converged": out["converged"],
        "stable": out["stable"],
        "min_tangent_eigenvalue_N_per_mm": out["eig"],
        "newton_iterations": out["iterations"],
        "max_shape_change_mm": out["moved"],
        "mesh": {
            "max_edge_mm": max_edge_mm,
            "triangles": mesh.n_triangles,
            "dofs": model.n_dofs,
        },
        "time_s": time.perf_counter() - t0,  # the caller may count its own part too
        # large arrays: the kind takes them out before the record is written (pipeline/fields.py)
        "field": mesh_arrays(model) | {"steps": states},
    }
