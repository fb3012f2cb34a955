"""One arm of a rotationally symmetric torsional spring as a geometrically exact beam.

An arm spring (:mod:`geometry.arm_spring`) is ``n`` identical arms from a hub to held pads. The
hub turns rigidly by ``p`` about the axis (the origin) and every arm is loaded the same way, so
one arm carries ``1/n`` of the hub torque and the others follow by symmetry. The arm is a
:class:`fea.beam.BeamModel` from the hub rim (its start, a point ``X0`` of the rigid hub) to the
pad boss (its end, clamped). The hub rotation is linear in the beam's start DOFs::

    u(start) = (R(p) - I) X0,     phi(start) = p,     u(end) = 0, phi(end) = 0

which :class:`fea.constrained_beams.ConstrainedBeams` imposes exactly (no extra unknowns). The
torque the drive applies to the hub is what the hub applies to the arms::

    T = n (M + x Fy - y Fx),   x, y = R(p) X0   (the start's current position)

with ``(Fx, Fy, M)`` the constraint force on the arm's start node (N, N·mm). Units: mm, N, N·mm,
rad, MPa. Failure to converge is data (``ok``, ``message``), never raised.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.beam_fields import constrained_members
from flexopt.fea.beam_statics import node_fibres, start_loaded_samples, start_loaded_stress
from flexopt.fea.constrained_beams import ConstrainedBeams, ConstrainedSettings
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.geometry.profile import BeamProfile

__all__ = ["ArmBeamResponse", "arm_beam_torque"]


@dataclass(frozen=True)
class ArmBeamResponse:
    """A hub turned by prescribed angles, one row per angle (row 0 at the first angle).

    Attributes
    ----------
    rotation_rad : (rows,) float, rad — hub rotation (counter-clockwise +).
    torque_Nmm : (rows,) float, N·mm — torque on the hub, all ``n`` arms; NaN where not converged.
    peak_stress_MPa : (rows,) float, MPa — max |N|/A + |M| c / I along the arm, N and M from
        statics (the hub's force on the arm: :func:`fea.beam_statics.start_loaded_stress`).
    shapes_mm : (rows, nodes, 2) float, mm — deformed nodes of arm 0.
    converged : (rows,) bool.
    ok : bool — every row converged.
    message : str — why not, when not ok.
    solve_time_s : float, s.
    extra : dict — element count, Newton iterations and ``curvature_peak_stress_MPa`` (rows,)
        MPa, the peak from the elements' curvature (EI phi'), for comparison.
    members : fea.beam_fields.Members, optional — arm 0's model, shapes and rotations (no copy
        of the solve beyond the rotations), for its section and fibre stresses in best.vtu.
    fibres : dict, optional — arm 0's fibre stresses from statics at its nodes
        (:func:`fea.beam_statics.node_fibres`: ``fibre_left_MPa``, ``fibre_right_MPa``,
        ``equivalent_MPa``, each (rows, n_nodes) MPa), the figures ``peak_stress_MPa`` reads.
    """

    rotation_rad: np.ndarray
    torque_Nmm: np.ndarray
    peak_stress_MPa: np.ndarray
    shapes_mm: np.ndarray
    converged: np.ndarray
    ok: bool
    message: str
    solve_time_s: float
    extra: dict = field(default_factory=dict)
    members: Any = None
    fibres: Any = None


def _rotation(p: float) -> np.ndarray:
    c, s = np.cos(p), np.sin(p)
    return np.array([[c, -s], [s, c]])


def arm_beam_torque(
    profile: BeamProfile,
    material: Material,
    n_arms: int,
    rotation_rad: np.ndarray,
    n_elements: int = 24,
    settings: ConstrainedSettings | None = None,
) -> ArmBeamResponse:
    """Torque of an ``n_arms`` spring whose hub turns through ``rotation_rad``.

    Parameters
    ----------
    profile : BeamProfile — arm 0 from the hub rim (start, fixed to the hub) to the pad (end,
        clamped); points in mm in the spring's frame (axis at the origin), in-plane width as
        ``thickness_mm``, the spring's thickness as ``width_mm``.
    material : Material.
    n_arms : int — identical arms around the axis.
    rotation_rad : (rows,) float, rad — hub angles of the rows, from 0 or near it, in order.
    n_elements : int — P2 elements along the arm.
    settings : ConstrainedSettings, optional — Newton tolerances and sub-stepping.

    Returns
    -------
    ArmBeamResponse

    Raises
    ------
    FeaError
        For a bad argument (not for non-convergence).
    """
    if int(n_arms) != n_arms or n_arms < 1:
        raise FeaError(f"n_arms = {n_arms} must be a whole number >= 1")
    angles = np.asarray(rotation_rad, dtype=float).ravel()
    if angles.size < 1 or not np.all(np.isfinite(angles)):
        raise FeaError("rotation_rad must be one or more finite angles (rad)")
    t0 = time.perf_counter()
    beam = BeamModel(profile, material, settings=BeamSettings(n_elements=n_elements))
    x0 = np.asarray(profile.points_mm[0], dtype=float)

    def constraints(p: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(6)
        d = np.zeros(6)
        move = (_rotation(p) - np.eye(2)) @ x0
        for f in range(3):
            C[f, system.dof(0, 0, f)] = 1.0
            C[3 + f, system.dof(0, -1, f)] = 1.0
        d[0], d[1], d[2] = move[0], move[1], p
        return C, d

    system = ConstrainedBeams([beam], 0, constraints, settings=settings or ConstrainedSettings())
    res = system.solve(angles)
    torque = np.full(angles.size, np.nan)
    start = res.start_force(0)
    for k in np.flatnonzero(res.converged):
        fx, fy, m = start[k]
        x, y = _rotation(angles[k]) @ x0
        torque[k] = n_arms * (m + x * fy - y * fx)
    # the stress from statics (fea/beam_statics.py): the arm is loaded at its ends only (hub
    # and pad), so the start's constraint force gives every section's N and M exactly, where
    # the elements' curvature is an h^2 approximation on the tapered arm
    phi = res.beam_state(0).reshape(angles.size, -1, 3)[..., 2]
    stress, _ = start_loaded_stress(beam, res.shapes_mm[0], phi, start, res.converged)
    fibres = node_fibres(
        beam, *start_loaded_samples(beam, res.shapes_mm[0], phi, start), res.converged
    )
    return ArmBeamResponse(
        rotation_rad=angles,
        torque_Nmm=torque,
        peak_stress_MPa=stress,
        shapes_mm=res.shapes_mm[0],
        converged=res.converged,
        ok=res.ok,
        message=res.message,
        solve_time_s=time.perf_counter() - t0,
        extra={
            "elements": beam.n_elements,
            "newton_iterations": int(res.iterations.sum()),
            # the elements' own figure, kept for comparison (docs/beam.md, "Stress from statics")
            "curvature_peak_stress_MPa": np.where(res.converged, res.peak_stress_MPa[:, 0], np.nan),
        },
        members=constrained_members([beam], res),
        fibres=fibres,
    )
