r"""Torque and stiffness of the leaf-spring joint (paper 002) by the large-deflection beam model.

One leaf is a :class:`~fea.beam.BeamModel` clamped at the movable support O' (see
:mod:`geometry.leaf_joint` for the frame and the two structures). The joint torque and stiffness
are ``n_leaves`` times those of one leaf (paper Eq. 9).

Structure (a), ``sliding``: the tip B is kept on the arm's radial line through O, free to slide
along it and to turn; the arm pushes it only along the arm normal ``n(theta)``. That is one linear
constraint on the tip, ``n(theta) . u_B = l_j sin(theta)`` (B0 - O = l_j e_x), traced in theta with
:class:`~fea.constrained_beams.ConstrainedBeams`. Its multiplier is the normal force F, and the
torque on the arm is ``F |OB|`` (the force is normal to the arm at radius |OB|).

Structure (b), ``fixed``: the rod fixed to the arm at P = O + l_j (cos theta, sin theta) presses on
the leaf, which slides past it: the loaded length s_c (O' to the contact) is unknown and the force
is normal to the leaf at the contact. The loaded part is therefore a cantilever of length s_c with
a *follower* tip force (always normal to the tip) and no tip moment; the leaf beyond the contact is
unloaded and straight. A follower-loaded cantilever's shape depends only on ``alpha = F s^2 / EI``
and scales with its length, so the beam is traced once, at length l, under a follower force
(load stiffness in the tangent), and each state is scaled to the length that puts the tip on the
rod's circle, ``|s_c b(alpha) - O| = l_j`` with ``b`` the tip position per unit length. That is
exact for the inextensible, unshearable elastica; the beam's axial and shear compliance make the
shape depend on t/s_c as well, an O((t/l)^2 (s_c - l)/l) effect (below 1e-5 for the paper's leaf).
The torque on the arm is ``F l_j cos(theta_B - theta)``, theta_B the tip angle.

For each requested deflection the load is found by a secant iteration on alpha, every trial solved
from the last equilibrium (a few Newton iterations each). Rows past the elastic limit are still
elastic solutions (the model has no plasticity): ``elastic_limit_rad`` says where the peak stress
reaches the allowable.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.sparse as sp
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.beam_fields import Members, constrained_members
from flexopt.fea.constrained_beams import ConstrainedBeams, ConstrainedResponse
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.pivot import tangent_stiffness
from flexopt.fea.stops import ContactResponse, ContactSettings, RigidStop
from flexopt.geometry.leaf_joint import LeafJoint

__all__ = [
    "JointResponse",
    "linear_joint_stiffness_Nmm",
    "joint_response",
    "sliding_response",
    "fixed_response",
    "elastic_limit_rad",
    "joint_elastic_limit",
    "length_range_mm",
    "curve_summary",
]


@dataclass(frozen=True)
class JointResponse:
    """The joint deflected by the output arm, one row per deflection (row 0 at rest).

    Attributes
    ----------
    structure : "sliding" or "fixed".
    deflection_rad : (rows,) float, rad — joint deflection theta_j.
    torque_Nmm : (rows,) float, N·mm — joint torque (all leaves).
    stiffness_Nmm_per_rad : (rows,) float — joint tangent stiffness d torque / d theta.
    leaf_force_N : (rows,) float, N — normal force between arm and one leaf.
    tip_angle_rad : (rows,) float, rad — leaf slope at the load point (theta_B).
    loaded_length_mm : (rows,) float, mm — O' to the load point along the leaf (l for sliding).
    pin_radius_mm : (rows,) float, mm — |OB| (l_j for fixed).
    tip_mm : (rows, 2) float, mm — load point B.
    peak_stress_MPa : (rows,) float, MPa — max |N|/A + |M| c / I over the leaf.
    shapes_mm : (rows, n_nodes, 2) float, mm — the loaded part of the leaf.
    converged : (rows,) bool.
    ok : bool.
    message : str.
    linear_stiffness_Nmm_per_rad : float — n 3 E I l_j^2 / l^3, the small-deflection joint
        stiffness of both structures.
    solve_time_s : float, s.
    extra : dict.
    contact : fea.stops.ContactResponse or None — sliding structure with rigid stops
        (``sliding_response(stops=)``): the stops' forces on the leaf (N), gaps (mm) and the
        deflection (rad) at which each closes; None without stops.
    members : fea.beam_fields.Members or None — the leaf's model, its solved shapes and node
        rotations per row, for its section and fibre stresses (best.vtu); for the fixed
        structure the leaf at its rest length l, as solved, before the scaling by s / l.
    members_scale : (rows,) float or None — fixed structure: s / l per row (the solved leaf's
        shape scaled by it is ``shapes_mm``, its stresses divided by it ``peak_stress_MPa``);
        None for the sliding structure (no scaling).
    """

    structure: str
    deflection_rad: np.ndarray
    torque_Nmm: np.ndarray
    stiffness_Nmm_per_rad: np.ndarray
    leaf_force_N: np.ndarray
    tip_angle_rad: np.ndarray
    loaded_length_mm: np.ndarray
    pin_radius_mm: np.ndarray
    tip_mm: np.ndarray
    peak_stress_MPa: np.ndarray
    shapes_mm: np.ndarray
    converged: np.ndarray
    ok: bool
    message: str
    linear_stiffness_Nmm_per_rad: float
    solve_time_s: float
    extra: dict = field(default_factory=dict)
    contact: ContactResponse | None = None
    members: Members | None = None
    members_scale: np.ndarray | None = None


def linear_joint_stiffness_Nmm(joint: LeafJoint, E_MPa: float) -> float:
    """Small-deflection joint stiffness n 3 E I l_j^2 / l^3, N·mm/rad.

    Both structures start alike: the tip moves l_j theta across the leaf, which as a cantilever
    with a free tip slope needs F = 3 E I l_j theta / l^3; the lever of F about O is l_j.
    """
    l, lj = joint.effective_length_mm, joint.arm_mm
    return joint.n_leaves * 3.0 * E_MPa * joint.second_moment_mm4 * lj**2 / l**3


def elastic_limit_rad(deflection_rad: np.ndarray, stress_MPa: np.ndarray, allowable_MPa: float):
    """First deflection where the peak stress reaches ``allowable_MPa`` (linear interpolation
    between rows), rad; None when it never does on the converged rows."""
    a = np.asarray(deflection_rad, dtype=float)
    s = np.asarray(stress_MPa, dtype=float)
    ok = np.isfinite(s)
    a, s = a[ok], s[ok]
    over = np.flatnonzero(s >= allowable_MPa)
    if over.size == 0:
        return None
    k = int(over[0])
    if k == 0:
        return 0.0
    u = (allowable_MPa - s[k - 1]) / (s[k] - s[k - 1])
    return float(a[k - 1] + u * (a[k] - a[k - 1]))


def _model(joint: LeafJoint, material: Material, n_elements: int) -> BeamModel:
    return BeamModel(joint.leaf_profile(), material, settings=BeamSettings(n_elements=n_elements))


def _check(max_rad: float, steps: int, deflections_rad: np.ndarray | None = None) -> np.ndarray:
    """The rows: ``deflections_rad`` if given (0 first, increasing), else k max_rad / steps."""
    if deflections_rad is not None:
        a = np.asarray(deflections_rad, dtype=float).ravel()
        if a.size < 2 or a[0] != 0.0 or np.any(np.diff(a) <= 0) or a[-1] >= 0.5 * math.pi:
            raise FeaError(
                f"deflections_rad must start at 0 and increase, staying below pi/2; got {a[:4]}..."
            )
        return a
    if steps < 1:
        raise FeaError(f"steps = {steps} must be >= 1")
    if not (math.isfinite(max_rad) and 0.0 < max_rad < 0.5 * math.pi):
        raise FeaError(
            f"max_rad = {max_rad!r} must lie in (0, pi/2); the joint deflects by less than 90 deg"
        )
    return max_rad * np.arange(steps + 1) / steps


def sliding_response(
    joint: LeafJoint,
    material: Material,
    max_rad: float,
    steps: int = 20,
    n_elements: int = 40,
    deflections_rad: np.ndarray | None = None,
    stops: tuple[RigidStop, ...] = (),
    contact: ContactSettings | None = None,
) -> JointResponse:
    """Structure (a): the leaf tip slides in a slot along the arm (force normal to the arm).

    Parameters
    ----------
    joint : LeafJoint — geometry (its ``structure`` is not read).
    material : Material.
    max_rad : float, rad — deflection of the last row, in (0, pi/2).
    steps : int — rows after row 0, at k max_rad / steps.
    n_elements : int — beam elements along the leaf.
    deflections_rad : (rows,) float, rad, optional — explicit rows (0 first, increasing) instead
        of max_rad and steps; the stiffness is differentiated on them (second order, uneven rows
        allowed), so two close rows give an accurate stiffness there.
    stops, contact : rigid stops fixed to the ground (the leaf's frame, joint.leaf_profile) that
        the leaf meets, and their penalty (:class:`fea.constrained_beams.ConstrainedBeams`;
        frictionless, inside Newton); the arm does not touch them.

    Returns
    -------
    JointResponse
    """
    t0 = time.perf_counter()
    angles = _check(max_rad, steps, deflections_rad)
    model = _model(joint, material, n_elements)
    lj = joint.arm_mm

    def constraints(theta: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(4)
        row = system.clamp_start(C, 0, 0)
        n = joint.arm_normal(theta)
        C[row, system.dof(0, -1, 0)] = n[0]
        C[row, system.dof(0, -1, 1)] = n[1]
        d = np.zeros(4)
        d[row] = lj * math.sin(theta)  # (B0 + u - O) . n = 0 with B0 - O = l_j e_x
        return C, d

    system = ConstrainedBeams([model], 0, constraints, stops=tuple(stops), contact=contact)
    # Past s_mp sin(theta) = l the arm's line no longer comes within l of the support: only a
    # leaf that stretches could follow (the extensible beam would, at absurd force). Those rows
    # are not solved.
    limit = joint.max_sliding_deflection_rad()
    reach = angles < limit
    res = system.solve(angles[reach])
    if not reach.all():
        res = _pad(res, angles.size)
        if res.message == "":
            res = replace(
                res,
                ok=False,
                message=(
                    f"deflections from {math.degrees(limit):.4g} deg on are out of reach: the "
                    f"arm's line passes farther than l = {joint.effective_length_mm:g} mm from the "
                    f"support (s_mp sin(theta) > l, s_mp = {joint.support_offset_mm:g} mm)"
                ),
            )
    B = joint.pin_rest_mm + res.end(0)[:, :2]
    r = np.einsum(
        "ij,ij->i", B - joint.centre_mm, np.array([joint.arm_direction(a) for a in angles])
    )
    force = res.multipliers[:, 3]
    torque = joint.n_leaves * force * r
    members = constrained_members(system.beams, res)  # best.vtu's section and stresses
    return _response(
        "sliding",
        joint,
        material,
        angles,
        torque,
        force,
        res.end(0)[:, 2],
        np.where(res.converged, joint.effective_length_mm, np.nan),
        r,
        B,
        res.peak_stress_MPa[:, 0],
        res.shapes_mm[0],
        res,
        t0,
        {"newton_iterations": int(res.iterations.sum())},
        res.contact,
        members,
    )


def _follower_system(joint: LeafJoint, material: Material, n_elements: int) -> ConstrainedBeams:
    """The leaf at its rest length l, clamped, with a follower tip force alpha EI / l^2 normal to
    the tip (p = alpha)."""
    model = _model(joint, material, n_elements)
    EI = material.E_MPa * joint.second_moment_mm4
    l = joint.effective_length_mm
    n = model.n_dofs
    iu, iv, ip = n - 3, n - 2, n - 1

    def constraints(alpha: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(3)
        system.clamp_start(C, 0, 0)
        return C, np.zeros(3)

    def loads(alpha: float, z: np.ndarray) -> tuple[np.ndarray, sp.spmatrix]:
        F = alpha * EI / l**2
        phi = z[ip]
        f = np.zeros(n)
        f[iu], f[iv] = -F * math.sin(phi), F * math.cos(phi)
        dfdz = sp.coo_matrix(
            ([-F * math.cos(phi), -F * math.sin(phi)], ([iu, iv], [ip, ip])), shape=(n, n)
        )
        return f, dfdz

    system = ConstrainedBeams([model], 0, constraints, loads)
    return system


def _contact(joint: LeafJoint, b_hat: np.ndarray) -> tuple[float, float]:
    """(s_c, theta): the loaded length that puts the scaled tip s_c b_hat on the rod's circle
    |B - O| = l_j, and the deflection of the arm through that point."""
    O = joint.centre_mm
    bb = float(b_hat @ b_hat)
    bo = float(b_hat @ O)
    disc = bo * bo - bb * (float(O @ O) - joint.arm_mm**2)
    s = (bo + math.sqrt(max(disc, 0.0))) / bb  # the root that is l at rest
    B = s * b_hat
    return s, math.atan2(B[1] - O[1], B[0] - O[0])


def fixed_response(
    joint: LeafJoint,
    material: Material,
    max_rad: float,
    steps: int = 20,
    n_elements: int = 40,
    deflections_rad: np.ndarray | None = None,
    tol_rad: float = 1e-10,
) -> JointResponse:
    """Structure (b): a rod fixed to the arm presses on the leaf, which slides past it.

    Parameters
    ----------
    joint, material, max_rad, steps, n_elements, deflections_rad : as
        :func:`sliding_response`.
    tol_rad : float, rad — the deflection of each row is met to this.

    Returns
    -------
    JointResponse
        ``loaded_length_mm`` is s_c; the leaf must run at least ``max(s_c) - l`` beyond the rod
        at rest (compare ``joint.overhang_mm``).
    """
    t0 = time.perf_counter()
    angles = _check(max_rad, steps, deflections_rad)
    system = _follower_system(joint, material, n_elements)
    l, lj = joint.effective_length_mm, joint.arm_mm
    EI = material.E_MPa * joint.second_moment_mm4
    rows = angles.size
    n_nodes = system.beams[0].n_nodes
    out = {
        "torque": np.full(rows, np.nan),
        "force": np.full(rows, np.nan),
        "tip_angle": np.full(rows, np.nan),
        "s": np.full(rows, np.nan),
        "tip": np.full((rows, 2), np.nan),
        "stress": np.full(rows, np.nan),
        "shapes": np.full((rows, n_nodes, 2), np.nan),
        # the solved leaf at rest length before the scaling (best.vtu's stresses)
        "solved": np.full((rows, n_nodes, 2), np.nan),
        "rotations": np.full((rows, n_nodes), np.nan),
        "scale": np.full(rows, np.nan),
    }
    converged = np.zeros(rows, dtype=bool)
    message = ""
    iterations = 0

    def state(res: ConstrainedResponse) -> tuple[float, float, np.ndarray]:
        b_hat = (joint.pin_rest_mm + res.end(0)[-1, :2]) / l
        s, theta = _contact(joint, b_hat)
        return s, theta, b_hat

    current = system.solve([0.0])  # row 0: at rest
    iterations += int(current.iterations.sum())
    alpha_now, theta_now = 0.0, 0.0
    slope_now = 3.0 * lj / l  # d alpha / d theta at rest

    def record(k: int, res: ConstrainedResponse, alpha: float) -> None:
        s, theta, b_hat = state(res)
        scale = s / l
        F = alpha * EI / s**2
        tip_angle = float(res.end(0)[-1, 2])
        out["torque"][k] = joint.n_leaves * F * lj * math.cos(tip_angle - theta)
        out["force"][k] = F
        out["tip_angle"][k] = tip_angle
        out["s"][k] = s
        out["tip"][k] = s * b_hat
        # the same shape scaled by s/l: curvature (bending stress) scales by l/s
        out["stress"][k] = float(res.peak_stress_MPa[-1, 0]) / scale
        out["shapes"][k] = res.shapes_mm[0][-1] * scale
        out["solved"][k] = res.shapes_mm[0][-1]
        out["rotations"][k] = res.beam_state(0)[-1, 2::3]
        out["scale"][k] = scale
        converged[k] = True

    record(0, current, 0.0)
    start = (current.states[-1], current.multipliers[-1])
    for k in range(1, rows):
        target = angles[k]
        # Secant on alpha from the last row; the first guess follows the slope d alpha / d theta
        # of the last two rows (at first the small-deflection 3 l_j / l). Every trial is traced
        # from the last row's equilibrium.
        a_prev, th_prev = alpha_now, theta_now
        a = alpha_now + (target - theta_now) * slope_now
        accepted = None
        reason = "the secant on the load did not converge (past a limit of the structure?)"
        base_alpha, base = alpha_now, start
        for _ in range(30):
            res = system.solve([base_alpha, a], start=base)
            iterations += int(res.iterations.sum())
            if not res.ok:
                reason = res.message
                break
            th = state(res)[1]
            if abs(th - target) <= tol_rad:
                accepted = res
                break
            slope = (th - th_prev) / (a - a_prev)
            if not (np.isfinite(slope) and slope > 0):
                reason = "the deflection stopped growing with the load (a limit of the structure)"
                break
            # the next trial starts from this one, which is close to it
            base_alpha, base = a, (res.states[-1], res.multipliers[-1])
            a_prev, th_prev = a, th
            a = a + (target - th) / slope
        if accepted is None:
            message = (
                f"no equilibrium at deflection {math.degrees(target):.4g} deg (row {k}): {reason}"
            )
            break
        record(k, accepted, a)
        slope_now = (a - alpha_now) / (target - theta_now)
        alpha_now, theta_now = a, target
        start = (accepted.states[-1], accepted.multipliers[-1])
    return JointResponse(
        structure="fixed",
        deflection_rad=angles,
        torque_Nmm=out["torque"],
        stiffness_Nmm_per_rad=tangent_stiffness(angles, out["torque"]),
        leaf_force_N=out["force"],
        tip_angle_rad=out["tip_angle"],
        loaded_length_mm=out["s"],
        pin_radius_mm=np.where(converged, lj, np.nan),
        tip_mm=out["tip"],
        peak_stress_MPa=out["stress"],
        shapes_mm=out["shapes"],
        converged=converged,
        ok=bool(converged.all()),
        message=message,
        linear_stiffness_Nmm_per_rad=linear_joint_stiffness_Nmm(joint, material.E_MPa),
        solve_time_s=time.perf_counter() - t0,
        extra={"newton_iterations": iterations},
        members=Members((system.beams[0],), (out["solved"],), (out["rotations"],)),
        members_scale=out["scale"],
    )


def _pad(res: ConstrainedResponse, rows: int) -> ConstrainedResponse:
    """``res`` with NaN / unconverged rows appended up to ``rows``."""
    extra = rows - res.params.size

    def grow(a: np.ndarray, fill: float | bool = np.nan) -> np.ndarray:
        pad = np.full((extra, *a.shape[1:]), fill, dtype=a.dtype)
        return np.concatenate([a, pad])

    return replace(
        res,
        params=grow(res.params),
        states=grow(res.states),
        internal=grow(res.internal),
        multipliers=grow(res.multipliers),
        peak_stress_MPa=grow(res.peak_stress_MPa),
        peak_stress_s_mm=grow(res.peak_stress_s_mm),
        shapes_mm=tuple(grow(s) for s in res.shapes_mm),
        iterations=grow(res.iterations, 0),
        converged=grow(res.converged, False),
        stable=None if res.stable is None else grow(res.stable, False),
        ok=False,
        contact=None
        if res.contact is None
        else replace(
            res.contact,
            force_N=grow(res.contact.force_N),
            force_vector_N=grow(res.contact.force_vector_N),
            gap_mm=grow(res.contact.gap_mm),
            in_contact=grow(res.contact.in_contact, False),
            rows_in_contact=grow(res.contact.rows_in_contact, False),
            point_mm=grow(res.contact.point_mm),
            max_penetration_mm=grow(res.contact.max_penetration_mm, 0.0),
        ),
    )


def _response(
    structure: str,
    joint: LeafJoint,
    material: Material,
    angles: np.ndarray,
    torque: np.ndarray,
    force: np.ndarray,
    tip_angle: np.ndarray,
    loaded: np.ndarray,
    radius: np.ndarray,
    tip: np.ndarray,
    stress: np.ndarray,
    shapes: np.ndarray,
    res: ConstrainedResponse,
    t0: float,
    extra: dict,
    contact: ContactResponse | None = None,
    members: Members | None = None,
) -> JointResponse:
    return JointResponse(
        structure=structure,
        deflection_rad=angles,
        torque_Nmm=torque,
        stiffness_Nmm_per_rad=tangent_stiffness(angles, torque),
        leaf_force_N=force,
        tip_angle_rad=tip_angle,
        loaded_length_mm=loaded,
        pin_radius_mm=radius,
        tip_mm=tip,
        peak_stress_MPa=stress,
        shapes_mm=shapes,
        converged=res.converged,
        ok=res.ok,
        message=res.message,
        linear_stiffness_Nmm_per_rad=linear_joint_stiffness_Nmm(joint, material.E_MPa),
        solve_time_s=time.perf_counter() - t0,
        extra=extra,
        contact=contact,
        members=members,
    )


def joint_response(
    joint: LeafJoint,
    material: Material,
    max_rad: float,
    steps: int = 20,
    n_elements: int = 40,
    deflections_rad: np.ndarray | None = None,
    **stops: Any,
) -> JointResponse:
    """The response of ``joint.structure``: :func:`sliding_response` or :func:`fixed_response`.
    ``stops``: ``stops=`` and ``contact=`` of :func:`sliding_response` (rigid stops), if any;
    the fixed structure has none (its leaf is traced once and scaled to each loaded length, which
    a stop at a fixed place would not follow): FeaError."""
    if joint.structure == "sliding":
        return sliding_response(
            joint, material, max_rad, steps, n_elements, deflections_rad, **stops
        )
    if stops.get("stops"):
        raise FeaError("rigid stops are modelled for the sliding structure only, not 'fixed'")
    return fixed_response(joint, material, max_rad, steps, n_elements, deflections_rad)


def joint_elastic_limit(
    joint: LeafJoint,
    material: Material,
    allowable_MPa: float,
    n_elements: int = 40,
    steps: int = 15,
    **stops: Any,
) -> tuple[float | None, JointResponse]:
    """The deflection at which the leaf stress reaches ``allowable_MPa``, rad, and the trace.

    Traced to 1.5 times the small-deflection estimate ``2 l^2 sigma / (3 E t l_j)`` (from
    ``sigma = 3 E t l_j theta / (2 l^2)``), capped below 85 deg and below the sliding structure's
    geometric limit; the crossing is interpolated between rows. None when the stress stays below
    the allowable over that range (the joint reaches a geometric limit first).
    """
    l, lj, t = joint.effective_length_mm, joint.arm_mm, joint.thickness_mm
    estimate = 2.0 * l * l * allowable_MPa / (3.0 * material.E_MPa * t * lj)
    top = min(1.5 * estimate, math.radians(85.0))
    if joint.structure == "sliding":
        top = min(top, 0.999 * joint.max_sliding_deflection_rad())
    resp = joint_response(joint, material, top, steps, n_elements, **stops)
    ok = resp.converged
    return elastic_limit_rad(resp.deflection_rad[ok], resp.peak_stress_MPa[ok], allowable_MPa), resp


def length_range_mm(
    E_MPa: float,
    arm_mm: float,
    thickness_mm: float,
    width_mm: float,
    n_leaves: int,
    stiffness_range_Nmm: tuple[float, float],
) -> tuple[float, float]:
    """(l_min, l_max): free lengths whose small-deflection stiffness n 3 E I l_j^2 / l^3 is the
    top and the bottom of the range, mm."""
    c = n_leaves * 3.0 * E_MPa * width_mm * thickness_mm**3 / 12.0 * arm_mm**2
    lo, hi = stiffness_range_Nmm
    return (c / hi) ** (1.0 / 3.0), (c / lo) ** (1.0 / 3.0)


def curve_summary(
    joint: LeafJoint,
    resp: JointResponse,
    material: Material,
    allowable_MPa: float,
    n_elements: int,
    **stops: Any,
) -> dict[str, Any]:
    """Scalars of one torque-deflection curve: small-deflection stiffness (closed form and FE),
    the elastic limit (traced on its own, whatever range ``resp`` covers, with the same
    ``stops`` as ``resp``) with the torque and stiffness there, and the state at the last
    converged row of ``resp``."""
    a = resp.deflection_rad
    ok = resp.converged
    limit, trace = joint_elastic_limit(joint, material, allowable_MPa, n_elements, **stops)
    out: dict[str, Any] = {
        "linear_stiffness_Nm_per_rad": resp.linear_stiffness_Nmm_per_rad / 1000.0,
        "fe_initial_stiffness_Nm_per_rad": float(resp.stiffness_Nmm_per_rad[0]) / 1000.0,
        "elastic_limit_deg": None if limit is None else math.degrees(limit),
    }
    if limit is not None:
        t_ok = trace.converged
        x = trace.deflection_rad[t_ok]
        out["torque_at_elastic_limit_Nm"] = float(np.interp(limit, x, trace.torque_Nmm[t_ok])) / 1e3
        out["stiffness_at_elastic_limit_Nm_per_rad"] = (
            float(np.interp(limit, x, trace.stiffness_Nmm_per_rad[t_ok])) / 1e3
        )
    if ok.any():
        out["last_row_deg"] = float(np.degrees(a[ok][-1]))
        out["torque_at_last_row_Nm"] = float(resp.torque_Nmm[ok][-1]) / 1e3
        out["stiffness_at_last_row_Nm_per_rad"] = float(resp.stiffness_Nmm_per_rad[ok][-1]) / 1e3
        out["peak_stress_at_last_row_MPa"] = float(resp.peak_stress_MPa[ok][-1])
    return out
