"""The part as exported against the beam model: a mechanism's outline in plane stress, as a solid.

The mechanism engine (:mod:`fea.mechanism`) sees beams as centrelines: it cannot see where a pad
or a body really clamps a beam, the material of a root, or a deep part's restrained Poisson
contraction (docs/solid3d.md). This check solves the printed outline itself, linearly, in the
same load case, and compares its stiffness and peak stress with the beam model's:

Plane stress (always)
    The outline is meshed with quadratic triangles (:func:`fea.mesh.mesh_polygon`: the beams at
    ``thickness / elements_through`` and the rigid parts coarse) and its linear stiffness taken
    from :class:`fea.plane_stress.PlaneStressModel`.
3D solid (where the part is deep)
    The same plane mesh extruded to the width (:class:`fea.solid3d.Solid3DModel`, quadratic
    tetrahedra, half the depth with a symmetry plane), when the width is at least
    ``solid_depth_ratio`` times the thinnest beam: docs/solid3d.md's rule (a part 3 or more
    member widths deep, held by rigid clamps or hubs, is 2-7 % stiffer as a solid).

The supports are the mechanism's, as rigid regions of the mesh: every node in a clamping pad, a
ground outline or a body held to the ground is fixed; every node in a body moves with the body's
rigid motion ``u = (U, V) + theta e_z x (X - c)`` (and ``w = 0`` in 3D: the same rigid region
through the depth). A body pinned to the ground turns about its pin. The drive is the case's: a
body (or a body point ``body@x,y``) moved along its direction (the motion across it and the
rotation held or free) or turned (its translation held or free), by a small value; the
reaction on the prescribed coordinate over that value is the stiffness (N/mm or N·mm/rad).

The beam model's figures are computed here too, by :func:`fea.mechanism.solve_mechanism` at
``1e-4`` of the same drive (linear to ~1e-4). The ratio of each model's stiffness to the beam's
is a property of the clamps and cross-sections (docs/solid3d.md: the SEA spring's 3D/2D ratio is
the same at 1 and 11 degrees); the study applies the highest-fidelity ratio to the beam model's
nonlinear response (forces, their slopes, peak stress).

Stresses: the peak von Mises stress over the elements that do not touch a rigid region (the
re-entrant corners where a beam meets a rigid clamp are singular in elasticity and have no
counterpart in the beam; as the constant-force kind's check); its ratio to the beam's peak
``|N|/A + |M|c/I`` at the same drive. Passed the beams as made (``made``), the beam model is the
part as made (its beams clipped and flared into their roots' fillets, the peak with the roots'
Kt): the exported outline has those fillets, so both ratios compare one part in two models.

What is refused (``skipped`` with the reason, the study then judges on the beam model and says
so): a drive on a beam end or under force / moment control, a pinned beam end (the outline prints
a pad: a clamp), a case with supports.

Units: mm, N, MPa, N·mm, rad.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import shapely
from flexopt.fea.errors import FeaError
from flexopt.fea.mechanism import LoadCase, Mechanism, MechDrive, MechOutput, solve_mechanism
from flexopt.fea.mesh import TriMesh, mesh_polygon
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Translate
from shapely.geometry import Point, Polygon
from shapely.geometry.base import BaseGeometry

__all__ = [
    "FidelitySettings",
    "check_summary",
    "corrected_columns",
    "highest_fidelity",
    "mechanism_fidelity_check",
]


@dataclass(frozen=True)
class FidelitySettings:
    """The check's discretisation, each choice with its reason.

    elements_through : P2 triangles across the thinnest beam (edge = thickness / this): 2 put
        the parallel guide's stiffness ratios within 0.3 % of 3 and 4 (docs/mechanism.md).
    coarse_edge_mm : edge in the rigid parts (bodies, pads), whose nodes follow a rigid motion:
        their elements only carry the outline.
    simplify_mm : the outline is simplified to this (mm) before meshing (see ``_clean``).
    root_refinement : within half a thickness of where a beam meets a rigid part (a singular
        re-entrant corner) the edge is the beam's divided by this.
    solid_depth_ratio : the 3D check runs when the width is at least this many times the thinnest
        beam (docs/solid3d.md: within 0.5 % below 1, 2-7 % stiffer from 3 on).
    layers : prism layers through half the depth (graded towards the face): 2 keep the 3D/2D
        stiffness ratio within 1e-3 of 4 layers (docs/solid3d.md's table: 3e-4 on the SEA spring).
    drive_fraction : the drive value of the beam model's linear solve, as a fraction of the
        case's range (geometric nonlinearity ~ this squared for a symmetric part, this for a
        pre-curved one).
    """

    elements_through: float = 2.0
    coarse_edge_mm: float = 4.0
    simplify_mm: float = 2e-3
    root_refinement: float = 4.0
    solid_depth_ratio: float = 3.0
    layers: int = 2
    drive_fraction: float = 1e-4


def _select(xy: np.ndarray, region: BaseGeometry, tol: float = 1e-6) -> np.ndarray:
    """(n,) bool: the points on or inside ``region`` (within tol, mm)."""
    return shapely.distance(region, shapely.points(xy)) <= tol


def _clean(outline: Polygon, tol_mm: float) -> Polygon:
    """The outline snapped to a 1 um grid and simplified to ``tol_mm`` (one polygon).

    The beams' bands are unions of trapezoids and discs: their edges leave vertices a few um
    apart, which Triangle must keep, grading the mesh down to them (the shipped bistable
    switch: 4279 triangles, half of them < 0.002 mm^2, against 2919 simplified to 2 um).
    """
    snapped = shapely.set_precision(outline, 1e-3)
    simple = shapely.simplify(snapped, tol_mm, preserve_topology=True).buffer(0)
    for candidate in (simple, snapped):
        if isinstance(candidate, Polygon) and candidate.is_valid and not candidate.is_empty:
            # a plain copy: a geometry keeps its precision grid, and the mesher's segmentize
            # would then snap the points it adds on a slanted edge off that edge
            return Polygon(candidate.exterior.coords, [r.coords for r in candidate.interiors])
    parts = sorted(shapely.get_parts(shapely.make_valid(snapped)), key=lambda g: -g.area)
    if not parts or not isinstance(parts[0], Polygon):
        raise FeaError("the outline does not survive a 1 um grid (slivers)")
    return parts[0]


def _drive_point(mech: Mechanism, drive: MechDrive) -> tuple[str, np.ndarray]:
    """The driven body's name and the point (mm) the drive acts at."""
    name, at, xy = drive.part.partition("@")
    bodies = {b.name: b for b in mech.bodies}
    if name not in bodies:
        raise FeaError(f"drive on '{drive.part}': the check drives bodies only")
    if at:
        return name, np.array([float(v) for v in xy.split(",")], dtype=float)
    return name, np.asarray(bodies[name].ref_mm, dtype=float)


def _rigid_map(
    xy: np.ndarray,
    ground: BaseGeometry,
    bodies: Mapping[str, tuple[BaseGeometry, np.ndarray, str]],
    drive: MechDrive,
    driven: str,
    drive_at: np.ndarray,
    n_comp: int,
) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray, np.ndarray]:
    """u = T q + value * ubar on the nodes ``xy`` (n, 2) with ``n_comp`` (2 or 3) components each.

    Returns T (n * n_comp, n_q), ubar (n * n_comp,) for a unit drive, the prescribed
    coordinate's column (n * n_comp,) (its generalised force is the reaction: col^T K u), and the
    rigid mask (n,) (nodes of the ground or of a body).
    """
    n = xy.shape[0]
    is_ground = _select(xy, ground) if not ground.is_empty else np.zeros(n, dtype=bool)
    owner = np.full(n, -1)
    names = list(bodies)
    for k, name in enumerate(names):
        hit = _select(xy, bodies[name][0]) & ~is_ground & (owner < 0)
        owner[hit] = k
    rigid = is_ground | (owner >= 0)
    free_nodes = np.flatnonzero(~rigid)
    rows, cols, vals = [], [], []
    nq = 0
    for c in range(n_comp):  # free nodes: one unknown per component
        rows.append(n_comp * free_nodes + c)
        cols.append(nq + np.arange(free_nodes.size))
        vals.append(np.ones(free_nodes.size))
        nq += free_nodes.size
    ubar = np.zeros(n * n_comp)
    presc = np.zeros(n * n_comp)
    d = np.asarray(drive.direction, dtype=float)
    d = d / np.linalg.norm(d)
    nrm = np.array([-d[1], d[0]])
    for k, name in enumerate(names):
        nodes = np.flatnonzero(owner == k)
        if nodes.size == 0:
            continue
        _, ref, hold = bodies[name]
        centre = drive_at if name == driven else np.asarray(ref, dtype=float)
        r = xy[nodes] - centre
        # rigid in-plane motions of the body, each a (nodes, 2) field: along e1, e2, turn
        if name == driven and drive.control == "displacement":
            modes = {"presc": np.tile(d, (nodes.size, 1))}
            if drive.transverse == "free":
                modes["slide"] = np.tile(nrm, (nodes.size, 1))
            if drive.rotation == "free":
                modes["turn"] = np.column_stack([-r[:, 1], r[:, 0]])
        elif name == driven:  # rotation control about the drive point
            modes = {"presc": np.column_stack([-r[:, 1], r[:, 0]])}
            if drive.transverse == "free":
                modes["x"] = np.tile([1.0, 0.0], (nodes.size, 1))
                modes["y"] = np.tile([0.0, 1.0], (nodes.size, 1))
        elif hold == "pinned":  # turns about its pin (ref is the pin)
            modes = {"turn": np.column_stack([-r[:, 1], r[:, 0]])}
        else:
            modes = {
                "x": np.tile([1.0, 0.0], (nodes.size, 1)),
                "y": np.tile([0.0, 1.0], (nodes.size, 1)),
                "turn": np.column_stack([-r[:, 1], r[:, 0]]),
            }
        for key, field in modes.items():
            if key == "presc":
                for c in range(2):
                    ubar[n_comp * nodes + c] = field[:, c]
                    presc[n_comp * nodes + c] = field[:, c]
                continue
            for c in range(2):
                rows.append(n_comp * nodes + c)
                cols.append(np.full(nodes.size, nq))
                vals.append(field[:, c])
            nq += 1
    T = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n * n_comp, nq)
    )
    return T, ubar, presc, rigid


def _solve(K: sp.spmatrix, T: sp.csr_matrix, ubar: np.ndarray) -> np.ndarray:
    """u (N,) minimising the energy with u = T q + ubar: (T^T K T) q = -T^T K ubar."""
    from flexopt.fea.solid3d import SparseSolver  # the project's Cholesky (CHOLMOD / QDLDL / LU)

    K = sp.csr_matrix(K)
    Kr = (T.T @ K @ T).tocsc()
    b = -(T.T @ (K @ ubar))
    q = SparseSolver(Kr, "auto").solve(b)
    return T @ q + ubar


def _beam_linear(
    mech: Mechanism, case: LoadCase, fraction: float, made: Mapping[str, Any] | None = None
) -> tuple[float, float]:
    """The beam model's stiffness (reaction / drive) and peak stress per unit drive, from a
    solve at ``fraction`` of the case's range; with ``made`` (``MechanismOutline.beams``, the
    beams ``mech`` was built as made) the peak is the part's as made, the roots' Kt included
    (:func:`fea.mechanism_design.as_made_stress`): the stress the verdict multiplies."""
    from flexopt.fea.mechanism_design import as_made_stress

    drv = case.drive
    value = fraction * max(abs(drv.max_value - drv.min_value), 1e-12)
    small = MechDrive(drv.part, drv.control, value, 1, drv.direction, drv.transverse,
                      drv.rotation, 0.0)  # fmt: skip
    resp = solve_mechanism(mech, LoadCase(case.name, small, case.supports),
                           [MechOutput("F", "reaction")])  # fmt: skip
    if not resp.ok:
        raise FeaError(f"the beam model's linear solve failed: {resp.message}")
    peak = as_made_stress(resp, made)[-1]
    return float(resp.outputs["F"][-1]) / value, float(np.nanmax(peak)) / value


def _refusal(mech: Mechanism, case: LoadCase) -> str | None:
    if case.supports:
        return "the case has supports (a held jaw): the check models the joints only"
    if case.drive.control not in ("displacement", "rotation"):
        return f"a {case.drive.control}-controlled drive (the check prescribes a motion)"
    if "@" not in case.drive.part and case.drive.part not in {b.name for b in mech.bodies}:
        return f"the drive acts on '{case.drive.part}', not a body"
    bodies = {b.name for b in mech.bodies}
    for j in mech.joints:
        if j.type == "pinned" and j.a.split("@")[0] not in bodies:
            return f"joint {j.a} -> {j.b} is pinned (the outline prints it as a clamp or a weld)"
        if j.type == "pinned" and j.b != "ground":
            return f"joint {j.a} -> {j.b} is pinned to a part, not the ground"
    return None


def mechanism_fidelity_check(
    mech: Mechanism,
    case: LoadCase,
    outline: Polygon,
    ground_regions: Sequence[BaseGeometry],
    body_regions: Mapping[str, BaseGeometry],
    beam_regions: Sequence[BaseGeometry],
    depth_mm: float | Sequence[float],
    settings: FidelitySettings = FidelitySettings(),
    solid: bool | None = None,
    made: Mapping[str, Any] | None = None,
    keep_field: bool = False,
) -> dict[str, Any]:
    """Stiffness and peak stress of the exported outline in plane stress (and as a solid where
    the part is deep) against the beam model's, in one load case, linearly.

    Parameters
    ----------
    mech : Mechanism — the beams (their thickness and widths), bodies, joints and material.
    case : LoadCase — the case whose drive is checked.
    outline : Polygon, mm — the part as exported (one body).
    ground_regions : shapely geometries, mm — held parts: the clamping pads, the ground outlines.
    body_regions : body name -> its region, mm (bodies held to the ground are held).
    beam_regions : shapely geometries, mm — the beams' bands (meshed finer).
    depth_mm : mm — the out-of-plane width the part is extruded to; several: the 3D model is
        solved at each (one assembly; a width solved from these figures moves it).
    settings : FidelitySettings
    solid : force the 3D check on (True) or off (False); None: by ``solid_depth_ratio``.
    made : ``MechanismOutline.beams`` when ``mech``'s beams are the part's as made (clipped,
        flared into their roots' fillets): the beam peak the ratios divide by is then the as-made
        peak with the roots' Kt, like for like with the exported outline, which has the fillets.
    keep_field : keep the plane-stress state per unit drive under ``field`` (the reported design
        only: best.vtu draws it): ``points_mm`` (n, 2) mm, ``triangles`` (m, 3), ``stress_counted``
        (n,) bool (the vertices of the elements the peak counts), ``von_mises_MPa`` (n,) MPa and
        ``displacement_mm`` (n, 2) mm per unit drive (1 mm or 1 rad; linear: both scale with it).

    Returns
    -------
    dict
        ``beam_stiffness``, ``plane_stress_stiffness``, ``plane_stress_ratio`` (to the beam),
        ``beam_peak_stress_MPa``, ``plane_stress_peak_stress_MPa``, ``plane_stress_stress_ratio``,
        ``plane_stress_peak_nodal_MPa`` (the peak over the vertices) (all per unit drive: N/mm
        or N·mm/rad, MPa/mm or MPa/rad); ``solid`` (a list, one entry per depth: ``depth_mm``,
        ``stiffness``, ``ratio``, ``peak_stress_MPa``,
        ``stress_ratio``) or None; ``stiffness_unit``; the mesh and the time; or ``skipped``
        with the reason.
    """
    t0 = time.perf_counter()
    why = _refusal(mech, case)
    if why is not None:
        return {"skipped": why}
    depths = np.atleast_1d(np.asarray(depth_mm, dtype=float))
    t_min = min(float(np.min(b.thickness_mm)) for b in mech.beams)
    widths = {float(b.width_mm) for b in mech.beams}
    if len(widths) > 1:
        return {"skipped": "beams of different widths (the outline is extruded to one width)"}
    try:
        driven, drive_at = _drive_point(mech, case.drive)
        grounded = {}
        for j in mech.joints:
            body = j.a.split("@")[0]
            if j.b == "ground" and body in body_regions:
                if j.type == "clamped":
                    grounded[body] = None
                else:
                    xy = j.a.partition("@")[2]
                    ref = next(b.ref_mm for b in mech.bodies if b.name == body)
                    pin = np.array([float(v) for v in xy.split(",")]) if xy else ref
                    grounded[body] = np.asarray(pin, dtype=float)
        ground = shapely.union_all(
            [*ground_regions, *(body_regions[b] for b, pin in grounded.items() if pin is None)]
        )
        bodies: dict[str, tuple[BaseGeometry, np.ndarray, str]] = {}
        for b in mech.bodies:
            if b.name not in body_regions or grounded.get(b.name, 0) is None:
                continue
            pin = grounded.get(b.name)
            if pin is not None:
                bodies[b.name] = (body_regions[b.name], pin, "pinned")
            else:
                bodies[b.name] = (body_regions[b.name], np.asarray(b.ref_mm, float), "free")
        if driven not in bodies:
            return {"skipped": f"the driven body '{driven}' has no outline (or is held)"}
        h_beam = t_min / settings.elements_through
        rigid_all = shapely.union_all([ground, *(v[0] for v in bodies.values())])
        # where a beam meets a rigid part its corners are singular (re-entrant, 270 degrees): the
        # strain energy there converges slowly, so the mesh is graded down around them
        bands = shapely.union_all(list(beam_regions))
        roots = shapely.intersection(rigid_all.boundary, bands.buffer(1e-6))
        refine = [(r, h_beam) for r in beam_regions]
        if not roots.is_empty:
            refine.append((roots.buffer(0.5 * t_min), h_beam / settings.root_refinement))
        # on a 1 um grid, simplified to 2 um: the outline's unions leave sub-micrometre edges
        # that Triangle merges (its area check then fails) or grades the mesh down to; far below
        # any printer's resolution
        cleaned = _clean(outline, settings.simplify_mm)
        try:
            mesh = mesh_polygon(cleaned, settings.coarse_edge_mm, refine=refine)
        except FeaError:
            cleaned = _clean(outline, 0.0)
            mesh = mesh_polygon(cleaned, settings.coarse_edge_mm, refine=refine)
        outline = cleaned
        k_beam, s_beam = _beam_linear(mech, case, settings.drive_fraction, made)
    except (FeaError, ValueError) as exc:
        return {"skipped": f"could not build the check: {exc}"}
    width = float(widths.pop())
    out: dict[str, Any] = {
        "model": "linear elastic, the exported outline; rigid pads, ground outlines and bodies",
        "stiffness_unit": "N/mm" if case.drive.control == "displacement" else "N·mm/rad",
        "beam_stiffness": k_beam,
        "beam_peak_stress_MPa": s_beam,
    }
    # ---- plane stress
    t1 = time.perf_counter()
    try:
        ps, T, ubar, presc = _plane_stress(mesh, mech, ground, bodies, case.drive, driven,
                                           drive_at, rigid_all, width)  # fmt: skip
        K = ps.linear_stiffness()
        u = _solve(K, T, ubar)
        k_ps = float(presc @ (K @ u))
        s_ps, _, s_nodal, _ = ps.peak_stress(u, "linear")
        s_ps, s_nodal = float(s_ps), float(s_nodal)
    except FeaError as exc:
        return {"skipped": f"the plane-stress solve failed: {exc}"}
    out.update(
        plane_stress_stiffness=k_ps,
        plane_stress_ratio=k_ps / k_beam,
        plane_stress_peak_stress_MPa=s_ps,
        plane_stress_stress_ratio=s_ps / s_beam,
        # the same peak over the vertices (averaged corner values): what a drawn field shows
        plane_stress_peak_nodal_MPa=s_nodal,
        mesh={
            "beam_edge_mm": h_beam,
            "coarse_edge_mm": settings.coarse_edge_mm,
            "triangles": int(mesh.n_triangles),
            "plane_stress_dofs": int(ps.n_dofs),
        },
        plane_stress_time_s=time.perf_counter() - t1,
    )
    if keep_field:
        from flexopt.fea.plane_stress_fields import mesh_arrays, state_field

        out["field"] = {**mesh_arrays(ps), **state_field(ps, u, "linear")}
    run_solid = solid if solid is not None else width >= settings.solid_depth_ratio * t_min
    out["solid_rule"] = (
        f"width {width:.4g} mm / thinnest beam {t_min:.4g} mm = {width / t_min:.3g} "
        f"{'>=' if width >= settings.solid_depth_ratio * t_min else '<'} "
        f"{settings.solid_depth_ratio:g}"
    )
    out["solid"] = None
    if run_solid:
        t2 = time.perf_counter()
        try:
            # the beam model's forces are linear in the width: its stiffness at each depth
            out["solid"] = _solid(mesh, mech, ground, bodies, case.drive, driven, drive_at,
                                  rigid_all, depths, settings, k_beam / width, s_beam)  # fmt: skip
        except FeaError as exc:
            return {**out, "solid": None, "solid_skipped": f"the 3D solve failed: {exc}"}
        out["solid_time_s"] = time.perf_counter() - t2
    out["time_s"] = time.perf_counter() - t0
    return out


def _plane_stress(mesh: TriMesh, mech, ground, bodies, drive, driven, drive_at, rigid_all, width):
    # The model is built with a clamp and a drive only to number its DOFs and assemble K; the
    # supports used are this module's rigid map.
    body_region = bodies[driven][0]
    clamp = ground if not ground.is_empty else Point(mesh.points[0]).buffer(1e-9)
    ps = PlaneStressModel(mesh, mech.material, width, Clamp(clamp), Translate(body_region),
                          stress_ignore=rigid_all)  # fmt: skip
    n = ps.xy.shape[0]
    T2, ubar2, presc2, _ = _rigid_map(ps.xy, ground, bodies, drive, driven, drive_at, 2)
    # this module numbers DOF 2 s + c; the model ix[s], iy[s]: permute
    perm = np.empty(2 * n, dtype=int)
    perm[0::2], perm[1::2] = ps.ix, ps.iy
    P = sp.csr_matrix((np.ones(2 * n), (perm, np.arange(2 * n))), shape=(ps.n_dofs, 2 * n))
    ubar = P @ ubar2
    presc = P @ presc2
    return ps, (P @ T2).tocsr(), ubar, presc


def _solid(mesh, mech, ground, bodies, drive, driven, drive_at, rigid_all, depths, settings,
           k_beam_per_mm, s_beam) -> list[dict]:  # fmt: skip
    from flexopt.fea import solid3d as s3

    st = s3.Solid3DSettings(layers=settings.layers)
    ref = float(depths[0])
    clamp = ground if not ground.is_empty else Point(mesh.points[0]).buffer(1e-9)
    model = s3.Solid3DModel(mesh, mech.material, Clamp(clamp), Translate(bodies[driven][0]), st,
                            stress_ignore=rigid_all, reference_thickness_mm=ref)  # fmt: skip
    # the P2 node locations in the model's numbering (its own tables, rebuilt)
    tmesh = s3.extrude_mesh(mesh, s3.extrude_layers_mm(ref, st))
    if model.kernels is not None:
        locs = s3.p2_tables(tmesh, model.kernels)[2]
    else:
        from skfem import Basis, ElementTetP2

        locs = Basis(tmesh, ElementTetP2(), intorder=2).doflocs.T
    T, ubar, presc, rigid = _rigid_map(locs[:, :2], ground, bodies, drive, driven, drive_at, 3)
    # w = 0 on the rigid regions (held through the depth, as fea.solid3d's supports) and on the
    # mid-plane (symmetry: half the depth is meshed)
    drop = np.zeros(T.shape[0], dtype=bool)
    drop[3 * np.flatnonzero(rigid | (np.abs(locs[:, 2]) <= 1e-6)) + 2] = True
    keep_rows = sp.diags((~drop).astype(float))
    T = keep_rows @ T
    T = T[:, np.flatnonzero(np.asarray(abs(T).sum(axis=0)).ravel() > 0)].tocsr()
    out = []
    for depth in depths:
        K = model.stiffness_matrix(float(depth))
        u = _solve(K, T, ubar)
        k_3d = 2.0 * float(presc @ (K @ u))  # the half model carries half the force
        peaks = model.peak_stresses(u, float(depth))
        out.append({
            "depth_mm": float(depth),
            "stiffness": k_3d,
            "beam_stiffness": k_beam_per_mm * float(depth),
            "ratio": k_3d / (k_beam_per_mm * float(depth)),
            "peak_stress_MPa": float(peaks[0]),
            "stress_ratio": float(peaks[0]) / s_beam,
            "dofs": int(model.n_dofs),
            "layers": int(st.layers),
        })  # fmt: skip
    return out


# --------------------------------------------------------------------------------------------
# The beam model's response judged on the check


def highest_fidelity(check: Mapping[str, Any]) -> tuple[str, float, float]:
    """(model, stiffness ratio, peak stress ratio) of the highest-fidelity model of a
    :func:`mechanism_fidelity_check` (the 3D solid where it ran, else plane stress), each ratio
    to the beam model's (no unit)."""
    if check.get("solid"):
        s = check["solid"][0]
        return "3D solid", float(s["ratio"]), float(s["stress_ratio"])
    return (
        "plane stress",
        float(check["plane_stress_ratio"]),
        float(check["plane_stress_stress_ratio"]),
    )


def corrected_columns(
    table: Mapping[str, np.ndarray],
    control: str,
    outputs: Sequence[Any],
    ratio: float,
    stress: float,
) -> dict[str, np.ndarray]:
    """A case's columns (:func:`fea.mechanism_design.case_table`) with the force-like ones
    times the stiffness ``ratio`` to the power they scale with the width (under displacement or
    rotation control only: under force control the force is given) and the stresses times
    ``stress``. ``outputs`` are the case's :class:`fea.mechanism_design.OutputColumn` (their
    ``quantity`` and ``exponent``)."""
    by_name = {o.name: o for o in outputs}
    out = dict(table)
    force_like = control in ("displacement", "rotation")
    for key in table:
        if key.startswith("drive_reaction_") and force_like:
            out[key] = np.asarray(table[key], float) * ratio
        elif key == "peak_stress_MPa":
            out[key] = np.asarray(table[key], float) * stress
        elif key in by_name:
            o = by_name[key]
            if o.quantity == "peak_stress":
                out[key] = np.asarray(table[key], float) * stress
            elif force_like:
                out[key] = np.asarray(table[key], float) * ratio**o.exponent
    return out


def check_summary(checks: Mapping[str, Any], applied: Mapping[str, Any]) -> dict[str, Any]:
    """One flat line per figure of every case's check (the report shows flat mappings as
    tables): the model judged on, the stiffness (its unit in the key) and the ratios."""
    out: dict[str, Any] = {}
    for case, check in checks.items():
        if "skipped" in check:
            out[f"{case}: judged on"] = f"the beam model (check skipped: {check['skipped']})"
            continue
        out[f"{case}: judged on"] = applied[case]["model"]
        out[f"{case}: stiffness {check['stiffness_unit']}, beam model"] = check["beam_stiffness"]
        out[f"{case}: stiffness, plane stress / beam"] = check["plane_stress_ratio"]
        if check.get("solid"):
            solid = check["solid"][0]
            out[f"{case}: stiffness, 3D solid / beam"] = solid["ratio"]
            out[f"{case}: 3D depth mm"] = solid["depth_mm"]
            out[f"{case}: peak stress, 3D / beam"] = solid["stress_ratio"]
        else:
            out[f"{case}: 3D solid"] = f"not run ({check['solid_rule']})"
            out[f"{case}: peak stress, plane stress / beam"] = check["plane_stress_stress_ratio"]
        out[f"{case}: check time s"] = check["time_s"]
    return out
