"""One plane-stress FE analysis of a torsional spring: hub turned, pads held.

The analysis the spring kinds share (``sea_spring`` and ``threshold_spring``): linear stiffness,
the nonlinear torque curve in one or both directions, the peak von Mises stress away from the
rigid regions, the narrowest loaded slot (:func:`slot_gaps_mm`) and the stress map's data
(:func:`stress_map_data`), the torque-rotation table (:func:`curve_table`). Moved here from
``pipeline/studies/sea_spring.py`` unchanged.
Units: mm, N, MPa inside; torques in N m and rotations in degrees at the edges (as named).
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import (
    Clamp,
    PlaneStressModel,
    PlaneStressSettings,
    Rotate,
)
from flexopt.geometry.sea_spring import SpringGeometry

__all__ = [
    "MeshSize",
    "SpringMesh",
    "SpringResponse",
    "analyse_spring",
    "curve_table",
    "slot_gaps_mm",
    "slot_pairs",
    "stress_map_data",
]


class MeshSize(Protocol):
    """What :func:`analyse_spring` reads of a mesh setting (a study's ``mesh:`` block has it)."""

    @property
    def max_edge_mm(self) -> float: ...

    @property
    def elements_through(self) -> float: ...


@dataclass(frozen=True)
class SpringMesh:
    """The default mesh setting: the defaults of the spring kinds' ``mesh:`` block.

    Attributes
    ----------
    max_edge_mm : float, mm — largest triangle edge.
    elements_through : float — P2 triangles across a member (1: stiffness to 0.1 %).
    """

    max_edge_mm: float = 3.0
    elements_through: float = 1.0


@dataclass(frozen=True)
class SpringResponse:
    """What one analysis of a spring gives (N m, degrees at the edges; see :func:`analyse_spring`).

    Attributes
    ----------
    rotation_deg : (k + 1,) float, degrees — the hub rotation rows (0 ... theta).
    torque_Nm : (k + 1,) float, N m — nonlinear torque on the hub (nan where not converged).
    peak_stress_MPa : (k + 1,) float, MPa — nonlinear peak vertex-averaged von Mises.
    linear_stiffness_Nm_per_rad : float — K_lin.
    stiffness_Nm_per_rad : float — secant T(theta) / theta of the nonlinear model.
    linear_peak_stress_MPa : float — linear peak at theta.
    ok : bool; message : str
    n_dofs, n_triangles, iterations : int
    solve_time_s : float — model build, linear and nonlinear solves.
    model : PlaneStressModel or None — kept only when asked (for maps).
    u : (N,) float or None — the last nonlinear state when the model is kept.
    row_u, reverse_row_u : tuple of (N,) float (mm) or None, or None — the state at every row
        (rows of ``rotation_deg``; None at a row that did not converge) of the counter-clockwise
        and clockwise solves, kept with the model (the per-load-step fields of best.pvd).
    """

    rotation_deg: np.ndarray
    torque_Nm: np.ndarray
    peak_stress_MPa: np.ndarray
    peak_stress_xy_mm: np.ndarray
    linear_stiffness_Nm_per_rad: float
    stiffness_Nm_per_rad: float
    linear_peak_stress_MPa: float
    ok: bool
    message: str
    n_dofs: int
    n_triangles: int
    iterations: int
    solve_time_s: float
    model: Any = None
    u: np.ndarray | None = None
    reverse_torque_Nm: np.ndarray | None = None
    reverse_peak_stress_MPa: np.ndarray | None = None
    reverse_stiffness_Nm_per_rad: float = math.nan
    reverse_u: np.ndarray | None = None
    slot_gaps_mm: dict[str, float] | None = None
    row_u: tuple[np.ndarray | None, ...] | None = None
    reverse_row_u: tuple[np.ndarray | None, ...] | None = None

    @property
    def mean_stiffness_Nm_per_rad(self) -> float:
        """Mean of the two secant stiffnesses (the forward one alone without a reverse solve)."""
        if self.reverse_torque_Nm is None:
            return self.stiffness_Nm_per_rad
        return 0.5 * (self.stiffness_Nm_per_rad + self.reverse_stiffness_Nm_per_rad)

    @property
    def worst_peak_stress_MPa(self) -> float:
        """Peak stress at the last row, the worse of the two directions."""
        peak = float(self.peak_stress_MPa[-1])
        if self.reverse_peak_stress_MPa is not None:
            peak = max(peak, float(self.reverse_peak_stress_MPa[-1]))
        return peak

    def scaled(self, factor: float) -> SpringResponse:
        """The same response for a thickness ``factor`` times larger (torques scale with ST)."""
        rev = None if self.reverse_torque_Nm is None else self.reverse_torque_Nm * factor
        return replace(
            self,
            torque_Nm=self.torque_Nm * factor,
            stiffness_Nm_per_rad=self.stiffness_Nm_per_rad * factor,
            linear_stiffness_Nm_per_rad=self.linear_stiffness_Nm_per_rad * factor,
            reverse_torque_Nm=rev,
            reverse_stiffness_Nm_per_rad=self.reverse_stiffness_Nm_per_rad * factor,
        )


def analyse_spring(
    geom: SpringGeometry,
    material: Material,
    theta_rad: float,
    mesh: MeshSize | None = None,
    steps: int = 1,
    nonlinear: bool = True,
    keep_model: bool = False,
    settings: PlaneStressSettings | None = None,
    both_directions: bool = False,
    gaps: bool = False,
) -> SpringResponse:
    """Linear stiffness and (optionally) the nonlinear torque curve of a spring up to theta.

    The hub's flange footprint is turned rigidly about the axis, the pads' washer footprints are
    held; elements touching those rigid regions are left out of the peak stress (their edges are
    where the rigid body meets steel, not a feature of the part).

    Parameters
    ----------
    geom : SpringGeometry
    material : Material
    theta_rad : float, rad — the largest hub rotation.
    mesh : MeshSize, optional — the largest edge and elements across a member (a study's
        ``mesh:`` block; default :class:`SpringMesh`).
    steps : int — nonlinear load steps (rows) to theta.
    nonlinear : bool — skip the nonlinear solve when False (stage 1).
    keep_model : bool — keep the model and last state (for stress maps).
    settings : PlaneStressSettings, optional — solver tolerances.
    gaps : bool — measure the narrowest slot undeformed and at +-theta (:func:`slot_gaps_mm`).
    both_directions : bool — also turn the hub by -theta (a second nonlinear solve on the same
        model and factorisation pattern).

    Raises
    ------
    FeaError
        When the mesh or model cannot be built (a geometry problem, not a convergence one).
    """
    t0 = time.perf_counter()
    rev_torque = rev_stress = rev_u = rev_rows = None
    mesh = mesh or SpringMesh()
    # the clamp's and the drive's discs on element edges where the geometry names them
    # (geometry.arm_spring.ArmSpringGeometry.mesh_lines): the held nodes are those discs
    lines = geom.mesh_lines() if hasattr(geom, "mesh_lines") else None
    m = mesh_polygon(geom.fe_outline, mesh.max_edge_mm, refine=geom.mesh_regions(
        mesh.elements_through, mesh.max_edge_mm), lines=lines)  # fmt: skip
    # The nonlinear solve needs only the torque to ~1e-5; 1e-7 of the force saves an iteration.
    cfg = settings or PlaneStressSettings(rtol_residual=1e-7)
    ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)
    model = PlaneStressModel(
        m,
        material,
        geom.thickness_mm,
        Clamp(geom.pad_region),
        Rotate(geom.hub_region, (0.0, 0.0), theta_rad, steps),
        settings=cfg,
        stress_ignore=ignore,
    )
    # every row's state is kept with the model (a detailed design's per-step fields)
    lin = model.solve("linear", keep_states=keep_model and not nonlinear)
    k_lin = float(lin.torque_Nmm[-1] / theta_rad) * 1e-3
    rows = np.degrees(lin.drive_value)
    if nonlinear:
        # Newton's first row starts from the second-order expansion of the equilibrium path
        # (PlaneStressModel.series_predictor; two solves with the linear stiffness the linear
        # solve has just factorised) instead of the linearised step: a SEA spring turned 11
        # degrees in one row then needs 3 tangents instead of 5 (docs/plane_stress.md).
        u_odd, u_even = model.series_predictor(theta_rad / steps)
        nl = model.solve("nonlinear", guess=u_odd + u_even, keep_states=keep_model)
        torque = np.asarray(nl.torque_Nmm) * 1e-3
        stress = np.asarray(nl.peak_nodal_stress_MPa)
        where = np.asarray(nl.peak_nodal_stress_xy_mm)
        ok, message, its, u = nl.ok, nl.message, int(nl.iterations.sum()), nl.dofs
        rows_u = nl.row_dofs
        rows = np.degrees(nl.drive_value)
        if both_directions and ok:
            # Same regions, opposite rotation: the model's constraint maps and the solver's
            # symbolic analysis are reused.
            model.drive = replace(model.drive, max_rad=-theta_rad)
            # u(-v) = 2 u_even - u(v) + O(v^4) from the solved u(v) when the first row is the
            # whole turn (the odd orders cancel): 2-3 tangents instead of 5 and no
            # refactorisation of the linear stiffness; else the expansion itself.
            guess = 2.0 * u_even - nl.dofs if steps == 1 else u_even - u_odd
            back = model.solve("nonlinear", guess=guess, keep_states=keep_model)
            rev_u, rev_rows = back.dofs, back.row_dofs
            model.drive = replace(model.drive, max_rad=theta_rad)
            rev_torque = np.asarray(back.torque_Nmm) * 1e-3
            rev_stress = np.asarray(back.peak_nodal_stress_MPa)
            its += int(back.iterations.sum())
            if not back.ok:
                ok, message = False, f"reverse direction: {back.message}"
    else:
        torque = np.asarray(lin.torque_Nmm) * 1e-3
        stress = np.asarray(lin.peak_nodal_stress_MPa)
        where = np.asarray(lin.peak_nodal_stress_xy_mm)
        ok, message, its, u = lin.ok, lin.message, 0, lin.dofs
        rows_u = lin.row_dofs
    slot_gaps = None
    if gaps and nonlinear and ok:
        states = {"ccw": u}
        if rev_u is not None:
            states["cw"] = rev_u
        slot_gaps = slot_gaps_mm(model, states, geom.fe_outline)
    return SpringResponse(
        rotation_deg=rows,
        torque_Nm=torque,
        peak_stress_MPa=stress,
        peak_stress_xy_mm=where,
        linear_stiffness_Nm_per_rad=k_lin,
        stiffness_Nm_per_rad=float(torque[-1] / theta_rad),
        linear_peak_stress_MPa=float(lin.peak_nodal_stress_MPa[-1]),
        ok=bool(ok),
        message=message,
        n_dofs=int(model.n_dofs),
        n_triangles=int(m.n_triangles),
        iterations=its,
        solve_time_s=time.perf_counter() - t0,
        slot_gaps_mm=slot_gaps,
        model=model if keep_model else None,
        u=u if keep_model else None,
        reverse_u=rev_u if keep_model else None,
        row_u=rows_u if keep_model else None,
        reverse_row_u=rev_rows if keep_model else None,
        reverse_torque_Nm=rev_torque,
        reverse_peak_stress_MPa=rev_stress,
        reverse_stiffness_Nm_per_rad=(
            float(rev_torque[-1] / -theta_rad) if rev_torque is not None else math.nan
        ),
    )


def slot_gaps_mm(model: Any, states: dict[str, np.ndarray], outline: Any) -> dict[str, float]:
    """Narrowest gap across the slots of a solved spring, undeformed and in each given state.

    A slot is where the outline comes back close to itself: two boundary nodes of the FE mesh
    closer than 3 mm, unloaded or in any of the given states, whose distance along the outline
    is more than 9 mm (so they lie on two members facing each other, not on one edge;
    :func:`slot_pairs`). Measured node to node (P2 nodes 0.25 mm apart near the edges), which
    overstates a 0.9 mm gap by under 0.01 mm.

    Parameters
    ----------
    model : PlaneStressModel — its FE node locations ``xy`` (n, 2) mm and displacement indices.
    states : name -> (N,) displacement vector, mm.
    outline : Polygon — the FE outline (no holes), mm.

    Returns
    -------
    dict — ``undeformed`` and one entry per state, mm (inf where no slot is found).
    """
    pairs = slot_pairs(model, outline, states.values())
    if pairs is None:
        return {"undeformed": math.inf, **{k: math.inf for k in states}}
    xy = np.asarray(model.xy)

    def gap(points: np.ndarray) -> float:
        d = points[pairs[:, 0]] - points[pairs[:, 1]]
        return float(np.hypot(d[:, 0], d[:, 1]).min())

    out = {"undeformed": gap(xy)}
    for name, u in states.items():
        out[name] = gap(xy + np.column_stack([u[model.ix], u[model.iy]]))
    return out


def slot_pairs(model: Any, outline: Any, states: Any = ()) -> np.ndarray | None:
    """(p, 2) int: the pairs of FE nodes (indices into ``model.xy``) facing each other across a
    slot (:func:`slot_gaps_mm`), or None where there is none. The narrowest slot of a state
    ``u`` is the pair whose moved nodes are closest (the loaded slot's derivative,
    :func:`fea.plane_stress_sensitivity.gap_sensitivity`, differentiates that pair's distance).

    ``states`` : iterable of (N,) displacement vectors, mm. The pairs closer than 3 mm
    unloaded come first, in the order they always had; then those that come closer than 3 mm
    in one of the states and were farther unloaded (sorted). Without the states a slot wider
    than 3 mm unloaded that closes under load was not watched at all (session 30: the hybrid
    took sea-spring's windings 0.078 mm into each other across a slot 3.26 mm wide unloaded,
    with the loaded-slot constraint reading 0.267 mm; the verdict's contact search, which
    looks at the whole deformed outline, caught it).
    """
    from scipy.spatial import cKDTree

    xy = np.asarray(model.xy)
    ring = outline.exterior
    # The FE nodes in a k-d tree: the nodes near a segment (within half its length plus 1e-5 mm
    # of its midpoint: a superset of those within 1e-5 mm of it) are found from the index, and
    # each such (node, segment) pair gets its exact distance and the node's projection on the
    # segment. A node's nearest candidate segment is its nearest of the ring (every segment
    # within 1e-5 mm is a candidate), so the nodes on the ring (< 1e-6 mm) and their position
    # along it come from the one pass. Measuring every node against the whole ring was
    # O(nodes x ring vertices), 0.1-0.3 s a design; a shapely tree of the segments queried
    # with a point geometry per node then cost ~30 ms of which ~15 ms made the points.
    coords = np.asarray(ring.coords)  # (m + 1, 2), closed
    a, b = coords[:-1], coords[1:]
    seg = b - a
    seg_len2 = np.einsum("ij,ij->i", seg, seg)
    start = np.concatenate([[0.0], np.cumsum(np.sqrt(seg_len2))[:-1]])
    near = cKDTree(xy).query_ball_point(0.5 * (a + b), 0.5 * np.sqrt(seg_len2) + 1e-5)
    counts = np.fromiter(map(len, near), dtype=np.intp, count=len(near))
    which = np.repeat(np.arange(len(near)), counts)
    node = np.fromiter(itertools.chain.from_iterable(near), dtype=np.intp, count=counts.sum())
    # Position along the ring: the projection on the nearest segment (the first of equally near
    # ones, as the ring's own projection takes), arc length to that segment's start added.
    p = xy[node] - a[which]
    len2 = np.where(seg_len2[which] > 0, seg_len2[which], 1.0)
    t = np.clip(np.einsum("ij,ij->i", p, seg[which]) / len2, 0.0, 1.0)
    d = p - t[:, None] * seg[which]
    dist = np.hypot(d[:, 0], d[:, 1])
    order = np.lexsort((which, dist, node))  # per node: nearest, then lowest segment
    node, which, t, dist = node[order], which[order], t[order], dist[order]
    first = np.concatenate([[True], node[1:] != node[:-1]]) if node.size else node.astype(bool)
    on = dist[first] < 1e-6
    idx = node[first][on]  # sorted: node is the first sort key
    if len(idx) == 0:
        return None
    pts = xy[idx]
    w = which[first][on]
    s = start[w] + t[first][on] * np.sqrt(seg_len2[w])
    length = ring.length
    reach = 3.0

    def facing(pairs: np.ndarray) -> np.ndarray:
        # two members facing each other, not neighbours on one edge
        ds = np.abs(s[pairs[:, 0]] - s[pairs[:, 1]])
        ds = np.minimum(ds, length - ds)
        return pairs[ds > 3.0 * reach]

    pairs = facing(cKDTree(pts).query_pairs(reach, output_type="ndarray").reshape(-1, 2))
    extra = []
    for u in states:
        u = np.asarray(u)
        moved = pts + np.column_stack([u[model.ix][idx], u[model.iy][idx]])
        extra.append(
            facing(cKDTree(moved).query_pairs(reach, output_type="ndarray").reshape(-1, 2))
        )
    if extra:
        # the pairs that only come close under load, after the unloaded ones (whose order,
        # and so the closest pair on a tie, stays as it was)
        n = len(pts)
        new = np.unique(np.concatenate(extra)[:, 0] * n + np.concatenate(extra)[:, 1])
        new = np.setdiff1d(new, pairs[:, 0] * n + pairs[:, 1], assume_unique=False)
        pairs = np.concatenate([pairs, np.column_stack([new // n, new % n])])
    if len(pairs) == 0:
        return None
    return idx[pairs]


def stress_map_data(r: SpringResponse) -> dict[str, Any]:
    """The stress map's data at the last row: vertex-averaged von Mises and the displacement
    of the same solve (the state ``r.u``), on the undeformed mesh.

    Returns
    -------
    dict, empty when the model was not kept: ``points_mm`` (n, 2) mm, the mesh's vertices;
    ``triangles`` (m, 3) int; ``von_mises_MPa`` (n,) MPa; ``displacement_mm`` (n, 2) mm, the
    vertices' displacement (points + displacement is the deformed part), all as lists.
    """
    model = r.model
    if model is None or r.u is None:
        return {}
    kinematics = "nonlinear" if r.iterations > 0 else "linear"
    vc = model.von_mises(r.u, kinematics, model.corner_basis)
    t = model.skmesh.t.T
    n = model.mesh.n_points
    total = np.bincount(t.ravel(), weights=vc.ravel(), minlength=n)
    count = np.bincount(t.ravel(), minlength=n)
    # the vertices' DOFs (nodal_dofs, in the mesh's vertex order): the P2 mid-side nodes are
    # not points of the drawn mesh
    nodal = model.basis.nodal_dofs
    u = np.column_stack([r.u[nodal[0]], r.u[nodal[1]]])
    return {
        "points_mm": np.round(model.mesh.points, 4).tolist(),
        "triangles": model.mesh.triangles.tolist(),
        "von_mises_MPa": np.round(total / np.maximum(count, 1), 2).tolist(),
        "displacement_mm": u.tolist(),
    }


def curve_table(r: SpringResponse) -> dict[str, np.ndarray]:
    """Torque-rotation rows of a response, clockwise (negative) rows first when there are any.

    Returns
    -------
    dict of (m,) float arrays, m = k + 1 (one direction) or 2 k + 1 (both): ``rotation_deg``
    (degrees), ``torque_Nm`` (nonlinear, N m), ``torque_linear_Nm`` (K_lin theta, N m),
    ``peak_stress_MPa`` (MPa). Moved here from ``pipeline/studies/sea_spring.py``.
    """
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
