"""Flexure pivots under a pure moment: the beam model (every type) and plane stress (checks).

A pivot is loaded the way its rotational stiffness is defined: the moving block is turned by a
prescribed angle and is otherwise free, with no force on it, so the only load is the couple that
holds the angle (Paros & Weisbord's and Lobontiu's compliance ``theta / M``). Reported per row:

* torque (N·mm) and its tangent stiffness dM/dtheta (N·mm/rad);
* peak stress (MPa);
* the *centre shift*: how far the point of the moving block that sat on the nominal centre has
  moved (mm) — the parasitic motion of the rotation centre, zero for an ideal hinge.

:func:`beam_pivot` uses :class:`fea.constrained_beams.ConstrainedBeams`: every compliant member is
a :class:`~fea.beam.BeamModel` clamped to the ground and tied to the moving block, whose two
translations are unknowns and whose rotation is prescribed. Notch hinges enter as their
equivalent variable-thickness beam (the Euler–Bernoulli idealisation of the closed forms, with
shear and axial compliance added by the Reissner beam).

:func:`plane_stress_pivot` meshes the outline and turns the moving block about the nominal centre
(:class:`fea.plane_stress.Rotate`, ground block clamped). That also holds the centre in place, so
it reports the force this takes (``centre_force_N``): near zero when the nominal centre is where
the pivot turns by itself, and then the torque is the pure-moment torque.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.beam_fields import Members, constrained_members
from flexopt.fea.constrained_beams import ConstrainedBeams, ConstrainedSettings
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.stops import ContactResponse, ContactSettings, RigidStop
from flexopt.geometry.flexures import Flexure

__all__ = [
    "PivotResponse",
    "beam_pivot",
    "plane_stress_pivot",
    "pure_moment_centre",
    "tangent_stiffness",
]

#: Angle of the extra row used for the small-angle stiffness, rad: small enough that the torque is
#: linear to 1e-8, large enough that it is far above round-off.
SMALL_ANGLE_RAD = 1e-4


@dataclass(frozen=True)
class PivotResponse:
    """A pivot turned by its moving block, one row per angle (row 0 undeformed).

    Attributes
    ----------
    rotation_rad : (rows,) float, rad.
    torque_Nmm : (rows,) float, N·mm — couple on the moving block (counter-clockwise +).
    stiffness_Nmm_per_rad : (rows,) float — tangent dM/dtheta (finite differences of the rows).
    small_angle_stiffness_Nmm_per_rad : float — beam: M/theta at 1e-4 rad (the linear
        stiffness); plane stress: M/theta of the first row (exact for linear kinematics).
    peak_stress_MPa : (rows,) float — beam: max |N|/A + |M| c/I; plane stress: von Mises at the
        mesh vertices (surface value).
    centre_shift_mm : (rows,) float, mm — displacement of the moving block's point that started on
        the nominal centre (0 for plane stress, which turns the block about a fixed point).
    centre_displacement_mm : (rows, 2) float, mm — the same as a vector.
    centre_force_N : (rows,) float, N — force needed to hold the centre (0 for the beam model,
        which leaves it free).
    shapes_mm : (rows, n, 2) float or None — deformed beam nodes (members one after another, a NaN
        row between them), for plotting.
    converged : (rows,) bool.
    ok : bool.
    message : str.
    model : str — "beam" or "plane_stress".
    solve_time_s : float, s.
    extra : dict — mesh and solver counts.
    stable : (rows,) bool or None — beam: the row is a stable equilibrium with the block's
        rotation held (:attr:`fea.constrained_beams.ConstrainedResponse.stable`: False past a
        bifurcation, e.g. a pivot whose members buckle); None for plane stress (not checked).
    contact : fea.stops.ContactResponse or None — beam model with stops (``beam_pivot(stops=)``):
        the stops' forces on the members (N), gaps (mm) and the rotation (rad) at which each
        closes; None without stops.
    field : dict or None — plane stress: the mesh and, under ``steps``, every converged row's
        von Mises and displacement (:func:`fea.plane_stress_fields.state_field`; ``drive_value``
        in rad; the last is the range of motion); None for the beam model.
    members : fea.beam_fields.Members or None — beam model: the members' models, shapes and
        rotations per row, for their section and fibre stresses (best.vtu); None for plane stress.
    """

    rotation_rad: np.ndarray
    torque_Nmm: np.ndarray
    stiffness_Nmm_per_rad: np.ndarray
    small_angle_stiffness_Nmm_per_rad: float
    peak_stress_MPa: np.ndarray
    centre_shift_mm: np.ndarray
    centre_displacement_mm: np.ndarray
    centre_force_N: np.ndarray
    shapes_mm: np.ndarray | None
    converged: np.ndarray
    ok: bool
    message: str
    model: str
    solve_time_s: float
    extra: dict = field(default_factory=dict)
    stable: np.ndarray | None = None
    contact: ContactResponse | None = None
    field: dict | None = None
    members: Members | None = None


def tangent_stiffness(angle_rad: np.ndarray, torque_Nmm: np.ndarray) -> np.ndarray:
    """dM/dtheta at each row by second-order finite differences (np.gradient), N·mm/rad."""
    a = np.asarray(angle_rad, dtype=float)
    m = np.asarray(torque_Nmm, dtype=float)
    if a.size < 2:
        return np.full(a.size, np.nan)
    ok = np.isfinite(m)
    out = np.full(a.size, np.nan)
    if ok.sum() >= 2:
        out[ok] = np.gradient(m[ok], a[ok], edge_order=2 if ok.sum() > 2 else 1)
    return out


def _rotation(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def _pivot_system(
    flexure: Flexure,
    material: Material,
    n_elements: int,
    stops: tuple[RigidStop, ...] = (),
    contact: ContactSettings | None = None,
) -> tuple[ConstrainedBeams, list[np.ndarray]]:
    """The beams clamped to the ground, tied to a moving block turned about the nominal centre."""
    profiles = flexure.beams()
    models = [
        BeamModel(p, material, settings=BeamSettings(n_elements=n_elements)) for p in profiles
    ]
    centre = flexure.centre_mm
    arms = [p.points_mm[-1] - centre for p in profiles]  # block reference point -> member end

    def constraints(theta: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(6 * len(models))
        d = np.zeros(C.shape[0])
        row = 0
        moved = _rotation(theta) - np.eye(2)
        tx, ty = system.extra_dof(0), system.extra_dof(1)
        for i, arm in enumerate(arms):
            row = system.clamp_start(C, row, i)
            # end translation = block translation + (R(theta) - I) arm; end rotation = theta
            offset = moved @ arm
            for f, t_dof in ((0, tx), (1, ty)):
                C[row, system.dof(i, -1, f)] = 1.0
                C[row, t_dof] = -1.0
                d[row] = offset[f]
                row += 1
            C[row, system.dof(i, -1, 2)] = 1.0
            d[row] = theta
            row += 1
        return C, d

    system = ConstrainedBeams(
        models, 2, constraints, settings=ConstrainedSettings(), stops=stops, contact=contact
    )
    return system, arms


def _block_torque(res, arms: list[np.ndarray], k: int) -> float:
    theta = res.params[k]
    R = _rotation(theta)
    torque = 0.0
    for i, arm in enumerate(arms):
        fx, fy, m = res.end_force(i)[k]
        lever = R @ arm
        torque += m + lever[0] * fy - lever[1] * fx
    return float(torque)


def beam_pivot(
    flexure: Flexure,
    material: Material,
    max_rad: float,
    steps: int = 10,
    n_elements: int = 40,
    stops: tuple[RigidStop, ...] = (),
    contact: ContactSettings | None = None,
) -> PivotResponse:
    """Turn the moving block by ``max_rad`` under a pure moment, traced with the beam model.

    Parameters
    ----------
    flexure : Flexure — any type (notches as their equivalent beam).
    material : Material — E and nu.
    max_rad : float, rad — rotation at the last row (sign gives the sense).
    steps : int — rows after row 0, at k max_rad / steps.
    n_elements : int — elements per member (at least one per profile segment). 40 keeps the
        sampled stress within 0.6 % at 1.5 rad (the axial-strain sampling at element ends).
    stops, contact : rigid stops fixed to the ground that the members meet, and their penalty
        (:class:`fea.constrained_beams.ConstrainedBeams`); the moving block does not touch them.

    Returns
    -------
    PivotResponse
    """
    if steps < 1:
        raise FeaError(f"steps = {steps} must be >= 1")
    if not np.isfinite(max_rad) or max_rad == 0.0:
        raise FeaError(f"max_rad = {max_rad!r} must be a non-zero angle in radians")
    t0 = time.perf_counter()
    system, arms = _pivot_system(flexure, material, n_elements, tuple(stops), contact)
    small = system.solve([0.0, np.sign(max_rad) * SMALL_ANGLE_RAD])
    k0 = _block_torque(small, arms, 1) / small.params[1] if small.ok else float("nan")
    angles = max_rad * np.arange(steps + 1) / steps
    res = system.solve(angles)
    rows = angles.size
    torque = np.full(rows, np.nan)
    for k in np.flatnonzero(res.converged):
        torque[k] = _block_torque(res, arms, k)
    extra = res.extra  # (rows, 2): block translation = motion of the nominal centre point
    shift = np.hypot(extra[:, 0], extra[:, 1])
    shapes = [s for s in res.shapes_mm]
    gap = np.full((rows, 1, 2), np.nan)
    joined = np.concatenate([x for s in shapes for x in (s, gap)][:-1], axis=1)
    stress = np.nanmax(res.peak_stress_MPa, axis=1) if res.converged.any() else res.peak_stress_MPa
    stress = np.where(res.converged, stress, np.nan)
    return PivotResponse(
        rotation_rad=angles,
        torque_Nmm=torque,
        stiffness_Nmm_per_rad=tangent_stiffness(angles, torque),
        small_angle_stiffness_Nmm_per_rad=float(k0),
        peak_stress_MPa=stress,
        centre_shift_mm=np.where(res.converged, shift, np.nan),
        centre_displacement_mm=np.where(res.converged[:, None], extra, np.nan),
        centre_force_N=np.zeros(rows),
        shapes_mm=joined,
        converged=res.converged,
        ok=res.ok,
        message=res.message,
        model="beam",
        members=constrained_members(system.beams, res),  # best.vtu's section and stresses
        stable=res.stable,
        contact=res.contact,
        solve_time_s=time.perf_counter() - t0,
        extra={
            "members": len(arms),
            "elements_per_member": [m.n_elements for m in system.beams],
            "newton_iterations": int(res.iterations.sum()),
        },
    )


def pure_moment_centre(
    centre_mm: np.ndarray, angle_rad: float, displacement_mm: np.ndarray
) -> np.ndarray:
    """The fixed point a rotation by ``angle_rad`` must turn about to carry the point
    ``centre_mm`` by ``displacement_mm`` (a rotation about C0 plus a translation t is a rotation
    about C0 + (I - R)^-1 t), mm.

    Raises
    ------
    FeaError
        For a zero angle (a translation has no centre).
    """
    if abs(angle_rad) < 1e-12:
        raise FeaError("a zero rotation has no centre; give a non-zero angle_rad")
    A = np.eye(2) - _rotation(angle_rad)
    return np.asarray(centre_mm, dtype=float) + np.linalg.solve(A, displacement_mm)


def plane_stress_pivot(
    flexure: Flexure,
    material: Material,
    max_rad: float,
    steps: int = 4,
    kinematics: str = "nonlinear",
    max_edge_mm: float | None = None,
    web_edge_mm: float | None = None,
    centre_mm: np.ndarray | None = None,
) -> PivotResponse:
    """Turn the moving block about a fixed point in a plane-stress model of the outline.

    The ground block is clamped and the moving block rotated as a rigid body; elements touching
    either block are left out of the peak stress (their corners are singular in 2D elasticity).
    Turning about a fixed point also fixes where the block goes: at large angles a long flexure
    whose free rotation centre wanders is then stretched (its torque and stress rise far above
    the pure-moment ones). :func:`pure_moment_centre` gives the point to turn about so that the
    block lands where the beam model's pure moment puts it; ``centre_force_N`` then shows how
    far from a pure moment the plane-stress state is.

    Parameters
    ----------
    flexure : Flexure — a planar type (``flexure.is_planar``).
    material : Material.
    max_rad : float, rad.
    steps : int — rows after row 0.
    kinematics : "linear" or "nonlinear".
    max_edge_mm : float, mm, optional — element edge away from the web; default a quarter of the
        block height.
    web_edge_mm : float, mm, optional — element edge at the thinnest section; default a quarter
        of it (4 quadratic elements through it), and as many through the local thickness
        elsewhere in the compliant part.
    centre_mm : (2,) float, mm, optional — the fixed point; default the nominal centre.

    Returns
    -------
    PivotResponse
        ``centre_force_N`` is the force that holds the nominal centre (small when the pivot
        turns about it by itself); ``centre_shift_mm`` is zero by construction.
    """
    from flexopt.fea.mesh import mesh_polygon
    from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Rotate
    from flexopt.fea.plane_stress_fields import mesh_arrays, state_field

    if not flexure.is_planar:
        raise FeaError(
            f"a {flexure.kind} pivot is not planar (its leaves cross in separate layers); "
            "plane stress of its outline would join them: use beam_pivot"
        )
    t0 = time.perf_counter()
    outline = flexure.outline()
    t_min = flexure.min_thickness_mm
    ground, moving = flexure.ground_block(), flexure.moving_block()
    h_block = max(ground.bounds[3] - ground.bounds[1], t_min)
    coarse = max_edge_mm if max_edge_mm is not None else max(h_block / 4.0, t_min / 4.0)
    fine = web_edge_mm if web_edge_mm is not None else t_min / 4.0
    per_thickness = t_min / fine  # elements through the local thickness

    def size(xy: np.ndarray) -> np.ndarray:
        # Elements scale with the local thickness of the compliant part (per_thickness through
        # it), the blocks get the coarse size.
        local = flexure.local_thickness_mm(xy[:, 0]) / per_thickness
        return np.where(np.isfinite(local), np.clip(local, fine, coarse), coarse)

    mesh = mesh_polygon(outline, coarse, refine=size)
    grow = 1e-6
    model = PlaneStressModel(
        mesh,
        material,
        flexure.width_mm,
        Clamp(ground.buffer(grow)),
        Rotate(
            moving.buffer(grow),
            centre_mm=tuple(
                float(v) for v in (flexure.centre_mm if centre_mm is None else centre_mm)
            ),
            max_rad=float(max_rad),
            steps=int(steps),
        ),
        # filleted leaf roots are smooth: their elements count (sharp ones are singular)
        stress_ignore=None if getattr(flexure, "root_fillet_mm", 0.0) > 0 else ground.union(moving),
    )
    res = model.solve(kinematics, keep_states=True)  # type: ignore[arg-type]
    angles = np.asarray(res.drive_value, dtype=float)
    torque = np.asarray(res.torque_Nmm, dtype=float)
    small = float(torque[1] / angles[1]) if res.converged[1] else float("nan")
    done = np.flatnonzero(res.converged)
    rows_u = res.row_dofs or ()
    return PivotResponse(
        rotation_rad=angles,
        torque_Nmm=torque,
        stiffness_Nmm_per_rad=tangent_stiffness(angles, torque),
        small_angle_stiffness_Nmm_per_rad=small,
        peak_stress_MPa=np.asarray(res.peak_nodal_stress_MPa, dtype=float),
        centre_shift_mm=np.zeros(angles.size),
        centre_displacement_mm=np.zeros((angles.size, 2)),
        centre_force_N=np.hypot(res.reaction_N[:, 0], res.reaction_N[:, 1]),
        shapes_mm=None,
        converged=np.asarray(res.converged, dtype=bool),
        ok=bool(res.ok),
        message=res.message,
        model="plane_stress",
        solve_time_s=time.perf_counter() - t0,
        # every converged row's field (best.pvd's load steps; the last is the range of motion)
        field=mesh_arrays(model)
        | {
            "steps": [
                state_field(model, rows_u[k], kinematics) | {"drive_value": float(angles[k])}
                for k in done
            ]
        },
        extra={
            "kinematics": kinematics,
            "triangles": mesh.n_triangles,
            "dofs": res.n_dofs,
            "max_edge_mm": coarse,
            "web_edge_mm": fine,
        },
    )
