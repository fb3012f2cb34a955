"""A planar compliant mechanism as data: beams, rigid bodies, joints, one drive per load case.

Formulation (docs/mechanism_engine.md has the derivations)
---------------------------------------------------------
Unknowns ``z = [q_1, ..., q_B, (U, V, theta)_1, ..., (U, V, theta)_K]``: every beam's DOFs
(u, v in mm and the section rotation phi in rad at each node of its geometrically exact
Simo-Reissner mesh, :class:`fea.beam.BeamModel`), then every rigid body's motion (its reference
point's displacement U, V in mm and its rotation theta in rad). Joints, the case's supports and
the drive are constraint rows ``g(z, p) = 0`` (p the drive value); all are linear except the
position of a beam end attached to a body::

    X_end + u_end = ref + (U, V) + R(theta) (X_end - ref)        (nonlinear in theta)
    phi_end = theta                                              (clamped; none when pinned)

Equilibrium ``r(z) - f(p) - G(z)^T lam = 0`` with ``G = dg/dz`` is solved by Newton on::

    [ H   -G^T ] [dz  ]     [ r - f - G^T lam ]
    [ G    0   ] [dlam] = - [ g               ]      H = K - sum_i lam_i d2g_i/dz2

(the constraint-Hessian term is what keeps Newton quadratic when a body turns). ``lam`` are the
constraint forces (N, N·mm) acting on the parts along the rows: the multiplier of a displacement
drive row is the force the actuator applies along the drive direction.

The steps are adaptive with the branch guards of :mod:`fea.beam` (secant predictor, a sub-step
whose increment turns away from the prediction or that crosses from a stable to an unstable
state is retried smaller), so a buckling-type mechanism starts on the branch its geometry
selects. Stability is the inertia of the KKT matrix (see :func:`solve_mechanism`).

Rigid stops (``Mechanism.stops``): frictionless penalty contact of every beam with rigid outlines
fixed to the ground, the pair search, penalty energy and exact Hessian of :mod:`fea.stops` added
to every assembly (``r`` and ``H`` above); see :func:`solve_mechanism` and docs/contact.md.

Failure to converge is data (``converged``, ``ok``, ``message``), never raised; bad input (unknown
parts, free rigid-body motions, redundant constraints) raises :class:`fea.errors.FeaError` before
any solve. Units: mm, N, N·mm, rad, MPa, g.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cache
from types import ModuleType
from typing import Literal, NamedTuple

import numpy as np
import scipy.sparse as sp
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.constrained_beams import (
    BAND,
    LDAB,
    band_entries,
    kkt_negative_count,
    resolve_constrained_kernel,
)
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.stops import (
    BeamContact,
    BeamPairContact,
    ContactResponse,
    ContactSettings,
    RigidStop,
    contact_over_beams,
    overlaps,
)
from flexopt.geometry.profile import BeamProfile
from scipy.sparse.linalg import splu

__all__ = [
    "MechBeam",
    "MechBody",
    "MechJoint",
    "MechDrive",
    "MechOutput",
    "LoadCase",
    "Mechanism",
    "MechanismSettings",
    "MechanismResponse",
    "check_mechanism",
    "solve_mechanism",
    "mass_g",
    "stable_positions",
    "warm_up",
    "imperfect_mechanism",
    "first_unstable_row",
]


@dataclass(frozen=True)
class MechBeam:
    """One flexible beam.

    Attributes
    ----------
    name : str — unique among beams and bodies; must not contain "." and must not be "ground".
    points_mm : (n, 2) float, mm — centreline from the ``start`` end to the ``end`` end, n >= 2.
    thickness_mm : (n,) float, mm — in-plane thickness at each point (linear in arc length between).
    width_mm : float, mm — out-of-plane width.
    elements : int — P2 elements of this beam; 0 chooses automatically (see MechanismSettings).
    curvature_per_mm : (n - 1,) float, 1/mm, optional — signed curvature of each segment (an exact
        circular arc between two points, as geometry.profile.BeamProfile); None: straight segments.
    root_mm : (2,) float, mm — arc length from the start / end over which
        ``MechanismResponse.root_stress_MPa`` takes its largest stress (a filleted root's
        flare, whose stress a concentration factor multiplies; 0: the end section only).
    """

    name: str
    points_mm: np.ndarray
    thickness_mm: np.ndarray
    width_mm: float
    elements: int = 0
    curvature_per_mm: np.ndarray | None = None
    root_mm: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class MechBody:
    """One rigid body.

    Attributes
    ----------
    name : str — unique among beams and bodies.
    ref_mm : (2,) float, mm — reference point: drives and outputs on the body act at / read it.
    outline_mm : (k, 2) float, mm, optional — closed outline of the part's solid (drawing and mass
        only; the solver treats the body as rigid whatever its shape).
    """

    name: str
    ref_mm: np.ndarray
    outline_mm: np.ndarray | None = None


@dataclass(frozen=True)
class MechJoint:
    """A joint: beam end ``a`` attached to ``b``.

    Part references: "beam.start" / "beam.end" (a beam end), "body" (a body's reference point),
    "body@x,y" (the point of a body at x, y mm in undeformed coordinates, e.g. a lever's pivot).

    Attributes
    ----------
    a : str — a beam end; also a body or a body point when ``b`` is "ground" (clamped to the
        ground, or pinned to it at that point: an ideal revolute joint).
    b : str — "ground", a body (the end is carried rigidly at its own position; "body@x,y" means
        the same body), or another beam end "otherbeam.start" / "otherbeam.end" (the two ends
        must meet).
    type : "clamped" (positions tied and the angle between the end tangent and the body / the
        other tangent kept) or "pinned" (positions tied, rotations independent).
    """

    a: str
    b: str
    type: Literal["clamped", "pinned"] = "clamped"


@dataclass(frozen=True)
class MechDrive:
    """The one drive of a load case.

    Attributes
    ----------
    part : str — "bodyname" (acts at its reference point), "bodyname@x,y" (a point of the body,
        displacement / rotation control only) or "beamname.end" / "beamname.start".
    control : "displacement" (mm, along ``direction``), "rotation" (rad, counter-clockwise),
        "force" (N, along ``direction``) or "moment" (N·mm, counter-clockwise).
    max_value : float — mm | rad | N | N·mm, the value of the last row.
    steps : int — rows after the first; row k is at min_value + k (max_value - min_value) / steps.
    direction : (2,) float — for displacement / force (normalised internally).
    transverse : "held" or "free" — for displacement / force: the part's motion across
        ``direction``; for rotation / moment: the part's translation (both components; "held"
        turns it about its reference point / end node).
    rotation : "held" or "free" — for displacement / force: the part's rotation.
    min_value : float — value of row 0 (reached from the undeformed state first; may be nonzero
        or negative, e.g. a bistable's return stroke).
    """

    part: str
    control: Literal["displacement", "rotation", "force", "moment"]
    max_value: float
    steps: int
    direction: tuple[float, float] = (1.0, 0.0)
    transverse: Literal["held", "free"] = "free"
    rotation: Literal["held", "free"] = "free"
    min_value: float = 0.0


@dataclass(frozen=True)
class MechOutput:
    """A named quantity read from every row of the solution.

    Attributes
    ----------
    name : str
    quantity : one of
        "reaction" — part "": the drive's reaction along the drive (N under displacement / force,
        N·mm under rotation / moment; equals the applied value under force / moment control);
        part "x": as "reaction_force".
        "reaction_force" — force (N) along ``direction`` applied on ``part`` by the ground (its
        joints to ground and the case's supports); part "": applied by the drive.
        "reaction_moment" — moment (N·mm, counter-clockwise) applied on ``part`` by the ground
        (about the beam end node / body reference point); part "": by the drive.
        "displacement" — mm, motion of the body reference point / body point ("body@x,y") /
        beam end node along direction (a geometric advantage is the ratio of two of these).
        "rotation" — rad, rotation of the body / beam end section.
        "peak_stress" — MPa, max |N|/A + |M| c/I over the beam ``part`` ("" : over all beams).
    part : str — see quantity.
    direction : (2,) float — for reaction_force / displacement (normalised internally).
    """

    name: str
    quantity: Literal[
        "reaction", "displacement", "rotation", "peak_stress", "reaction_force", "reaction_moment"
    ]
    part: str = ""
    direction: tuple[float, float] = (1.0, 0.0)


@dataclass(frozen=True)
class LoadCase:
    """One load case: a drive, and supports that hold in this case only.

    Attributes
    ----------
    name : str
    drive : MechDrive
    supports : tuple of MechJoint — extra joints of this case (``b`` must be "ground"), e.g. a
        gripper's jaw held for a blocked-force case.
    """

    name: str
    drive: MechDrive
    supports: tuple[MechJoint, ...] = ()


@dataclass(frozen=True)
class Mechanism:
    """Beams, bodies and joints, and the material of the beams.

    Attributes
    ----------
    beams : tuple of MechBeam
    bodies : tuple of MechBody
    joints : tuple of MechJoint
    material : fea.materials.Material — E_MPa, nu, yield_MPa, density_kg_m3.
    stops : tuple of fea.stops.RigidStop — rigid outlines fixed to the ground (points, open
        polylines, polygons; mm, the mechanism's coordinates): every beam (its centreline swept
        by t/2) is kept clear of them by frictionless penalty contact inside Newton
        (:mod:`fea.stops`; the penalty is ``MechanismSettings.contact``), and so is every body
        with an ``outline_mm`` that is not clamped to the ground (:mod:`fea.body_contact`).
        Empty: the solve is the one without contact, exactly.
    beam_contacts : tuple of (name, name) — pairs of parts that may touch each other:
        frictionless penalty contact between them inside Newton, its force and gap in
        ``MechanismResponse.beam_contact``: two beams (:class:`fea.stops.BeamPairContact`,
        node-to-curve both ways), a body and a body or a beam (by the body's outline), or one
        beam named twice, its self contact (:mod:`fea.body_contact`); the penalty of
        ``MechanismSettings.contact``. Parts of no declared pair pass through each other (the
        kind's interference check says NOT MET). Empty: no such contact.
    """

    beams: tuple[MechBeam, ...]
    bodies: tuple[MechBody, ...]
    joints: tuple[MechJoint, ...]
    material: Material
    stops: tuple[RigidStop, ...] = ()
    beam_contacts: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class MechanismSettings:
    """Discretisation and solver tolerances, each with its reason.

    Attributes
    ----------
    default_elements : P2 elements of a beam whose ``elements`` is 0. 30 P2 elements put the tip
        force of a clamped-guided leaf at 1.5 rad within 1e-4 of the converged value; a mechanism
        with many beams costs ~3 x 61 DOFs per beam per 30 elements.
    shear_factor : k of k G A (5/6, rectangular section).
    rtol : equilibrium when the residual norm is below rtol x the force scale (constraint forces
        and applied loads); 1e-9 leaves the force error to the mesh.
    ctol : constraints met when max |g| is below ctol x the length scale (mm); the position rows
        of a beam end on a rotating body are nonlinear, and Newton meets them quadratically.
    max_iterations : Newton iterations per sub-step before the sub-step is cut back.
    first_substep : first sub-step as a fraction of a row step (the branch guards below make the
        sub-steps as small as a buckling-type start needs).
    min_substep : smallest sub-step as a fraction of a row step before giving up.
    fast_iterations : a sub-step converged in at most this many iterations doubles the next one.
    max_rotation_step : largest rotation (rad) of a beam section or a body one Newton correction
        may apply (larger corrections are scaled down: far from equilibrium a slender beam's full
        Newton step can turn sections by radians, onto another branch).
    dtol : a Newton correction below dtol x the length scale is round-off (converged).
    min_path_cosine : a converged sub-step whose increment makes an angle with the secant
        prediction whose cosine is below this is retried smaller (it jumped to another branch).
    min_critical_substep : a sub-step leading from a stable to an unstable state crossed a
        bifurcation or a limit point; it is retried smaller down to this fraction of a row step,
        then the crossing is accepted as genuine (and the rows are flagged unstable).
    check_stability : compute the KKT inertia at every accepted state (``stable``); False skips
        it (all rows report stable=True, the crossing guard is off): faster for big meshes.
    kernel : "auto", "numba" or "numpy" — the compiled Newton (fea/_mechanism_kernels.py: the
        beam kernel's assembly, the KKT system solved by bordering the beams' band, the loop as
        machine code) or the reference (scipy sparse matrices and SuperLU every iteration, the
        loop in Python). "auto" follows FLEXOPT_BEAM_KERNEL (numba | numpy; default numba) like
        ``BeamSettings.kernel``. Same decisions, answers equal to round-off
        (tests/fea/test_mechanism_kernels.py); where the bordering cannot take a system the
        compiled path runs the reference for that sub-step. A mechanism with stops always runs
        the reference loop (the contact terms are Python; the beams' element kernel still
        assembles).
    contact : fea.stops.ContactSettings — penalty of the stops (``Mechanism.stops``):
        k = penalty_factor x EI / h^3 per element with h the beam's mean element length
        (``element_length="mean"``: the beams as made have graded meshes, whose tiny root
        elements would make a local EI / h^3 a penalty Newton cannot converge with), the
        penetration tolerance and its raises.
    """

    default_elements: int = 30
    shear_factor: float = 5.0 / 6.0
    rtol: float = 1e-9
    ctol: float = 1e-10
    max_iterations: int = 25
    first_substep: float = 1.0
    min_substep: float = 1e-5
    fast_iterations: int = 5
    max_rotation_step: float = 0.5
    dtol: float = 1e-13
    min_path_cosine: float = 0.8
    min_critical_substep: float = 1e-3
    check_stability: bool = True
    kernel: Literal["auto", "numba", "numpy"] = "auto"
    contact: ContactSettings = ContactSettings(element_length="mean")


@dataclass(frozen=True)
class MechanismResponse:
    """One row per drive value (row 0 = min_value).

    Attributes
    ----------
    case : str — the load case's name.
    drive : (rows,) float — drive value of each row (mm | rad | N | N·mm).
    outputs : dict name -> (rows,) float — the requested outputs (NaN where not converged).
    peak_stress_MPa : (rows, n_beams) float — per beam.
    shapes_mm : tuple per beam of (rows, nodes, 2) float — deformed centreline node positions, mm.
    thickness_at_nodes_mm : tuple per beam of (nodes,) float — thickness at those nodes, mm.
    body_poses : (rows, n_bodies, 3) float — reference point x mm, y mm and rotation rad.
    converged : (rows,) bool.
    stable : (rows,) bool — stable equilibrium under the case's control (see solve_mechanism).
    ok : bool — every row converged.
    message : str — why not, when not ok (and stability notes).
    stable_released : (rows,) bool — stable with the drive released to a dead load equal to its
        reaction (what force control would see); equals ``stable`` under force / moment control.
    critical_drive : float — drive value where a stable path first became unstable (bracketed to
        ``min_critical_substep`` of a row step); NaN when it never did.
    root_stress_MPa : (rows, n_beams, 2) float — per beam, the largest |N|/A + |M| c/I within
        ``MechBeam.root_mm`` of its start and of its end (NaN where not converged).
    critical_mode : tuple per beam of (nodes, 2) float, or None — the buckling mode at the
        first unstable state (the eigenvector of the constrained Hessian Z^T H Z with the
        lowest eigenvalue), as the (u, v) translation of each beam's FE nodes, scaled so that
        the largest is 1 (no unit: multiply by an amplitude in mm); None when the path never
        became unstable.
    reference_nodes_mm : tuple per beam of (nodes, 2) float, mm — the FE nodes' undeformed
        positions (where ``shapes_mm`` and ``critical_mode`` are given).
    critical_body_mode : (n_bodies, 3) float, or None — the same mode's body motion (U, V per
        unit amplitude, theta in rad per mm of amplitude).
    rotations_rad : tuple per beam of (rows, nodes) float, rad — the FE nodes' section rotation
        (NaN where not converged); with ``beam_models`` (the beams' BeamModels) what
        fea/mechanism_fields.py turns into the beams' fibre stresses per node (best.vtu), and
        ``beam_roots_mm`` the ``MechBeam.root_mm`` (start, end) mm each beam was solved with.
    contact : fea.stops.ContactResponse, or None — with stops (``Mechanism.stops``): per row
        and stop the resultant force the stop exerts on all beams and bodies (N), the smallest
        gap of any of them (mm), in contact, the contact point; the drive value at which each
        gap closes (``closing_value``, in the drive's unit: mm, rad, N or N·mm); the
        penetration check.
        ``extra["force_by_beam_N"]`` (rows, n_beams, n_stops) N is each beam's share, with
        moving bodies ``extra["force_by_bodies_N"]`` (rows, n_stops) N theirs. None without
        stops.
    beam_contact : dict or None — with ``Mechanism.beam_contacts``: per pair ``"a/b"`` a dict of
        (rows,) arrays ``force_N`` (the magnitude of the contact's resultant force on part a,
        N; b carries the opposite; a beam with itself: the sum of its pairs' normal forces),
        ``gap_mm`` (the smallest gap between the two surfaces, mm; negative: penetration),
        ``in_contact`` (bool); NaN where not converged. None without.
    """

    case: str
    drive: np.ndarray
    outputs: dict[str, np.ndarray]
    peak_stress_MPa: np.ndarray
    shapes_mm: tuple[np.ndarray, ...]
    thickness_at_nodes_mm: tuple[np.ndarray, ...]
    body_poses: np.ndarray
    converged: np.ndarray
    stable: np.ndarray
    ok: bool
    message: str
    stable_released: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    critical_drive: float = float("nan")
    root_stress_MPa: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    critical_mode: tuple[np.ndarray, ...] | None = None
    critical_body_mode: np.ndarray | None = None
    rotations_rad: tuple[np.ndarray, ...] = ()
    beam_models: tuple[BeamModel, ...] = ()
    beam_roots_mm: tuple[tuple[float, float], ...] = ()
    reference_nodes_mm: tuple[np.ndarray, ...] = ()
    contact: ContactResponse | None = None
    beam_contact: dict[str, dict[str, np.ndarray]] | None = None


# ==================================================================================== model

_GROUND = "ground"
_ENDS = ("start", "end")

log = logging.getLogger(__name__)


@cache
def _kernels() -> ModuleType | None:
    """fea._mechanism_kernels, or None when numba cannot be imported (the reference runs)."""
    try:
        from flexopt.fea import _mechanism_kernels
    except Exception as exc:  # ImportError, or a numba that fails on this platform's LLVM
        log.debug("numba mechanism kernel unavailable (%s: %s)", type(exc).__name__, exc)
        return None
    return _mechanism_kernels


#: texts of the compiled Newton's status codes (fea/_mechanism_kernels.py), as the reference's
_REASONS = {
    1: "singular system (a mechanism or a limit point)",
    2: "singular system (a mechanism or a limit point)",
    3: "the internal force became NaN or inf",
    6: "Newton diverged",
}


@dataclass
class _Rows:
    """Constraint rows ``g(z, p) = A z + h(z) - b0 - p bp = 0`` (m rows).

    ``A`` holds the linear part; ``h`` the terms of points on rotating bodies,
    ``h = w . (R(theta) o - o)`` (offset ``o`` (2,) mm of the point from the body's reference
    point, weights ``w`` (2,), body rotation DOF ``theta``), at most one per row. ``group`` names
    the joint, support or drive each row comes from (for messages and reactions).
    """

    A: list[dict[int, float]] = field(default_factory=list)
    b0: list[float] = field(default_factory=list)
    bp: list[float] = field(default_factory=list)
    group: list[int] = field(default_factory=list)
    nonlinear: list[tuple[int, int, np.ndarray, np.ndarray]] = field(default_factory=list)

    def add(
        self,
        coefs: dict[int, float],
        group: int,
        bp: float = 0.0,
        nl: tuple[int, np.ndarray, np.ndarray] | None = None,
    ) -> int:
        """Add a row; ``nl`` = (theta DOF, o, w) adds w . (R(theta) o - o) when o is not 0."""
        row = len(self.A)
        merged: dict[int, float] = {}
        for k, v in coefs.items():
            merged[k] = merged.get(k, 0.0) + v
        self.A.append(merged)
        self.b0.append(0.0)
        self.bp.append(bp)
        self.group.append(group)
        if nl is not None and np.any(np.asarray(nl[1]) != 0.0) and np.any(np.asarray(nl[2]) != 0):
            self.nonlinear.append((row, nl[0], np.asarray(nl[1], float), np.asarray(nl[2], float)))
        return row


class _Point(NamedTuple):
    """A point of a part: its (x, y, rotation) DOFs and, on a body, its offset from the
    reference point (mm; zero at the reference point and for beam ends)."""

    x: int
    y: int
    r: int
    offset: np.ndarray  # (2,) mm
    on_body: bool
    where: np.ndarray  # (2,) mm, undeformed position

    def row(self, w: np.ndarray) -> tuple[dict[int, float], tuple[int, np.ndarray, np.ndarray]]:
        """Coefficients and nonlinear term of w . (displacement of the point)."""
        return {self.x: float(w[0]), self.y: float(w[1])}, (self.r, self.offset, np.asarray(w))


@dataclass(frozen=True)
class _Group:
    """Where constraint rows come from: a joint, a support or the drive."""

    label: str
    kind: Literal["joint", "support", "drive"]
    ground_part: str = ""  # the part a joint/support holds to the ground ("" otherwise)


def _part_name(ref: str) -> str:
    """The part a reference names: "body@x,y" -> "body"; beam ends and bodies unchanged."""
    return ref if _parse_end(ref) is not None else ref.partition("@")[0]


def _parse_end(ref: str) -> tuple[str, str] | None:
    """``"beam.start"`` -> ("beam", "start"); None when ``ref`` is not a beam-end reference."""
    if "." not in ref:
        return None
    name, _, end = ref.rpartition(".")
    return (name, end) if end in _ENDS else None


class _Model:
    """The meshed beams, the unknowns z = [q_1 .. q_B, (U, V, theta) per body] and the rows."""

    def __init__(self, mech: Mechanism, case: LoadCase | None, settings: MechanismSettings):
        self.mech = mech
        self.case = case
        self.settings = settings
        beams = tuple(mech.beams)
        bodies = tuple(mech.bodies)
        names = [b.name for b in beams] + [b.name for b in bodies]
        for nm in names:
            if not isinstance(nm, str) or not nm or "." in nm or "@" in nm or nm == _GROUND:
                raise FeaError(
                    f"part name {nm!r}: names must be non-empty, without '.' or '@' (they build "
                    "'beam.end' and 'body@x,y'), and not 'ground'"
                )
        dup = sorted({nm for nm in names if names.count(nm) > 1})
        if dup:
            raise FeaError(f"duplicate part names {dup}: beams and bodies need unique names")
        if not beams:
            raise FeaError("a mechanism needs at least one beam")
        self.beam_index = {b.name: i for i, b in enumerate(beams)}
        self.body_index = {b.name: i for i, b in enumerate(bodies)}

        self.models: list[BeamModel] = []
        for b in beams:
            try:
                profile = BeamProfile(
                    points_mm=np.asarray(b.points_mm, dtype=float),
                    thickness_mm=np.asarray(b.thickness_mm, dtype=float),
                    width_mm=float(b.width_mm),
                    curvature_per_mm=(
                        None if b.curvature_per_mm is None else np.asarray(b.curvature_per_mm)
                    ),
                )
            except ValueError as exc:  # GeometryError: say which beam
                raise FeaError(f"beam {b.name!r}: {exc}") from exc
            n_el = int(b.elements) if int(b.elements) > 0 else int(settings.default_elements)
            bs = BeamSettings(n_elements=n_el, shear_factor=settings.shear_factor)
            self.models.append(BeamModel(profile, mech.material, "clamped", bs))
        self.body_ref = np.array(
            [np.asarray(b.ref_mm, dtype=float).reshape(2) for b in bodies]
        ).reshape(-1, 2)
        if not np.all(np.isfinite(self.body_ref)):
            raise FeaError("body ref_mm must be finite [x, y] pairs")
        self.offsets = np.concatenate([[0], np.cumsum([m.n_dofs for m in self.models])])
        self.n_beam_dofs = int(self.offsets[-1])
        self.n = self.n_beam_dofs + 3 * len(bodies)
        self.length = max(max(m.profile.length_mm for m in self.models), 1.0)
        self.force_floor = max(m.force_floor for m in self.models)
        self.rot_dofs = np.concatenate(
            [np.arange(self.offsets[i] + 2, self.offsets[i + 1], 3) for i in range(len(beams))]
            + [self.n_beam_dofs + 3 * np.arange(len(bodies)) + 2]
        )
        rows, cols, self._band_src = [], [], []
        for i, m in enumerate(self.models):
            r_i, c_i, src = band_entries(m.n_dofs)
            rows.append(r_i + self.offsets[i])
            cols.append(c_i + self.offsets[i])
            self._band_src.append(src)
        self._k_rows = np.concatenate(rows)
        self._k_cols = np.concatenate(cols)
        #: the contact terms of each beam against the stops (None without stops: the old path)
        self.contacts: list[BeamContact] | None = None
        if mech.stops:
            self.contacts = [BeamContact(m, mech.stops, settings.contact) for m in self.models]
            for b, c in zip(beams, self.contacts, strict=True):
                for i, depth in overlaps(c):
                    raise FeaError(
                        f"stop {c.names[i]!r} overlaps beam {b.name!r} undeformed by "
                        f"{depth:.4g} mm; move it clear (the gap is measured from the beam's "
                        "surface, t/2 from the centreline)"
                    )
        #: declared beam-beam contact pairs: (index of a, index of b, the pair's terms)
        self.pairs: list[tuple[int, int, BeamPairContact]] = []
        rigid_pairs = [p for p in mech.beam_contacts if _rigid_pair(p, self.body_index)]
        for a_name, b_name in mech.beam_contacts:
            if (a_name, b_name) in rigid_pairs:
                continue  # a body, or a beam with itself: fea.body_contact
            ia, ib = (self._beam_of_pair(nm, a_name, b_name) for nm in (a_name, b_name))
            if ia == ib:
                raise FeaError(f"beam contact [{a_name}, {b_name}]: a beam with itself")
            pair = BeamPairContact(self.models[ia], self.models[ib], settings.contact)
            pair.name = f"{a_name}/{b_name}"
            _, gap0, _ = pair.state(
                self.models[ia].reference_nodes_mm, self.models[ib].reference_nodes_mm
            )
            if gap0 < -pair.tolerance_mm:
                raise FeaError(
                    f"beam contact [{a_name}, {b_name}]: the beams overlap undeformed by "
                    f"{-gap0:.4g} mm (joined, or crossing); declare only beams that are apart"
                )
            self.pairs.append((ia, ib, pair))
        #: the bodies' contact (stops, declared pairs) and self contact (None: none declared)
        self.rigid = _rigid_contacts(self, mech, rigid_pairs, settings)

        self.rows = _Rows()
        self.groups: list[_Group] = []
        self.f0 = np.zeros(self.n)
        self.fp = np.zeros(self.n)
        for j in mech.joints:
            self._joint(j, "joint")
        self.drive_row = -1
        self.drive_group = -1
        if case is not None:
            for j in case.supports:
                if j.b != _GROUND:
                    raise FeaError(
                        f"support {j.a!r} -> {j.b!r} of case {case.name!r}: a support holds a "
                        "part to the ground (b must be 'ground')"
                    )
                self._joint(j, "support")
            self._drive(case.drive)
        self._freeze()

    # ---- parts ------------------------------------------------------------------------------

    def point(self, ref: str, what: str) -> _Point:
        """A beam end ("beam.start" / "beam.end"), a body's reference point ("body") or a point
        of a body given in undeformed coordinates ("body@x,y", mm)."""
        end = _parse_end(ref)
        if end is not None and end[0] in self.beam_index:
            i = self.beam_index[end[0]]
            m = self.models[i]
            node = 0 if end[1] == "start" else m.n_nodes - 1
            base = int(self.offsets[i]) + 3 * node
            return _Point(base, base + 1, base + 2, np.zeros(2), False, m.reference_nodes_mm[node])
        name, at, xy = ref.partition("@")
        if name in self.body_index:
            k = self.body_index[name]
            base = self.n_beam_dofs + 3 * k
            where = self.body_ref[k]
            if at:
                try:
                    where = np.array([float(v) for v in xy.split(",")])
                except ValueError:
                    where = np.zeros(0)
                if where.shape != (2,) or not np.all(np.isfinite(where)):
                    raise FeaError(f"{what}: {ref!r}: a body point is 'body@x,y' (mm)")
            return _Point(base, base + 1, base + 2, where - self.body_ref[k], True, where)
        known = [f"{b}.start" for b in self.beam_index] + [f"{b}.end" for b in self.beam_index]
        raise FeaError(
            f"{what}: unknown part {ref!r}; beam ends are {known[:6]}"
            f"{' ...' if len(known) > 6 else ''}, bodies are {sorted(self.body_index)}"
        )

    def part_dofs(self, ref: str, what: str) -> tuple[int, int, int]:
        """(x, y, rotation) DOF indices of a beam end or a body."""
        pt = self.point(ref, what)
        return pt.x, pt.y, pt.r

    # ---- constraints ------------------------------------------------------------------------

    def _joint(self, j: MechJoint, kind: Literal["joint", "support"]) -> None:
        label = f"{kind} {j.a!r} -> {j.b!r} ({j.type})"
        if j.type not in ("clamped", "pinned"):
            raise FeaError(f"{label}: type must be 'clamped' or 'pinned'")
        a = self.point(j.a, label)
        g = len(self.groups)
        rw = self.rows
        ex, ey = np.eye(2)
        if j.b == _GROUND:
            self.groups.append(_Group(label, kind, ground_part=j.a))
            for w in (ex, ey):
                rw.add(*_row(a, w, g))
            if j.type == "clamped":
                rw.add({a.r: 1.0}, g)
            return
        if a.on_body:
            raise FeaError(
                f"{label}: a body can only be joined to the ground (as 'a'); attach beam ends to "
                "bodies instead (a = 'beam.end', b = body)"
            )
        self.groups.append(_Group(label, kind))
        b = self.point(j.b, label)
        if b.on_body:
            # X_end + u = ref + U + R(theta) o with o = X_end - ref: the end's offset from the
            # body's reference point, whatever point of the body ``b`` names.
            k = self.body_index[j.b.partition("@")[0]]
            o = a.where - self.body_ref[k]
            for w in (ex, ey):
                rw.add({a.x: w[0], a.y: w[1], b.x: -w[0], b.y: -w[1]}, g, nl=(b.r, o, -w))
            if j.type == "clamped":
                rw.add({a.r: 1.0, b.r: -1.0}, g)
            return
        if (a.x, a.y) == (b.x, b.y):
            raise FeaError(f"{label}: a beam end cannot be joined to itself")
        gap = float(np.hypot(*(a.where - b.where)))
        if gap > 1e-6 * self.length:
            raise FeaError(
                f"{label}: the beam ends are {gap:.6g} mm apart; joined ends must meet "
                "(or attach both to a body)"
            )
        # phi is the rotation from the reference, so a welded joint keeps the initial angle
        rw.add({a.x: 1.0, b.x: -1.0}, g)
        rw.add({a.y: 1.0, b.y: -1.0}, g)
        if j.type == "clamped":
            rw.add({a.r: 1.0, b.r: -1.0}, g)

    def _drive(self, d: MechDrive) -> None:
        label = f"drive of {d.part!r} ({d.control})"
        if d.control not in ("displacement", "rotation", "force", "moment"):
            raise FeaError(f"{label}: control must be displacement, rotation, force or moment")
        for nm in ("transverse", "rotation"):
            if getattr(d, nm) not in ("held", "free"):
                raise FeaError(f"{label}: {nm} = {getattr(d, nm)!r}; use 'held' or 'free'")
        if int(d.steps) < 1:
            raise FeaError(f"{label}: steps = {d.steps} must be >= 1")
        if not (np.isfinite(d.max_value) and np.isfinite(d.min_value)):
            raise FeaError(f"{label}: min_value and max_value must be finite")
        if d.max_value == d.min_value:
            raise FeaError(f"{label}: max_value must differ from min_value")
        pt = self.point(d.part, label)
        self.drive_point = pt
        g = len(self.groups)
        self.groups.append(_Group(label, "drive"))
        self.drive_group = g
        rw = self.rows
        if d.control in ("displacement", "force"):
            u = _unit(d.direction, label)
            n = np.array([-u[1], u[0]])
            if d.control == "displacement":
                coefs, nl = pt.row(u)
                self.drive_row = rw.add(coefs, g, bp=1.0, nl=nl)
            else:
                if np.any(pt.offset != 0.0):
                    raise FeaError(
                        f"{label}: a force drives a body at its reference point (put ref_mm "
                        "where the force acts)"
                    )
                self.fp[[pt.x, pt.y]] = u
            if d.transverse == "held":
                rw.add(*_row(pt, n, g))
            if d.rotation == "held":
                rw.add({pt.r: 1.0}, g)
        else:
            if d.control == "rotation":
                self.drive_row = rw.add({pt.r: 1.0}, g, bp=1.0)
            else:
                self.fp[pt.r] = 1.0
            if d.transverse == "held":
                for w in np.eye(2):
                    rw.add(*_row(pt, w, g))

    def _freeze(self) -> None:
        rw = self.rows
        self.m = len(rw.A)
        ii = [i for i, c in enumerate(rw.A) for _ in c]
        jj = [k for c in rw.A for k in c]
        vv = [v for c in rw.A for v in c.values()]
        self.A = sp.csr_matrix((vv, (ii, jj)), shape=(self.m, self.n))
        self.b0 = np.asarray(rw.b0, dtype=float)
        self.bp = np.asarray(rw.bp, dtype=float)
        self.row_group = np.asarray(rw.group, dtype=int)
        nl = rw.nonlinear
        self.nl_row = np.array([t[0] for t in nl], dtype=int)
        self.nl_theta = np.array([t[1] for t in nl], dtype=int)
        self.nl_off = np.array([t[2] for t in nl], dtype=float).reshape(-1, 2)
        self.nl_w = np.array([t[3] for t in nl], dtype=float).reshape(-1, 2)

    def constraints(self, z: np.ndarray, p: float) -> tuple[np.ndarray, sp.csr_matrix, np.ndarray]:
        """g (m,), G = dg/dz (m, N), and d2g/dtheta2 (n_nonlinear,) of the nonlinear terms."""
        g = self.A @ z - self.b0 - p * self.bp
        if self.nl_row.size == 0:
            return g, self.A, np.zeros(0)
        th = z[self.nl_theta]
        c, s = np.cos(th), np.sin(th)
        ox, oy = self.nl_off[:, 0], self.nl_off[:, 1]
        wx, wy = self.nl_w[:, 0], self.nl_w[:, 1]
        # w . R(theta) o, w . R'(theta) o; and R'' = -R
        wro = wx * (c * ox - s * oy) + wy * (s * ox + c * oy)
        wdro = wx * (-s * ox - c * oy) + wy * (c * ox - s * oy)
        g += np.bincount(self.nl_row, wro - (wx * ox + wy * oy), minlength=self.m)
        G = self.A + sp.csr_matrix((wdro, (self.nl_row, self.nl_theta)), shape=(self.m, self.n))
        return g, G.tocsr(), -wro

    def point_displacement(self, z: np.ndarray, pt: _Point) -> np.ndarray:
        """(2,) displacement (mm) of a point at state z (rows of z: (..., N) -> (..., 2))."""
        d = np.stack([z[..., pt.x], z[..., pt.y]], axis=-1)
        if pt.on_body and np.any(pt.offset != 0.0):
            th = z[..., pt.r]
            c, s = np.cos(th), np.sin(th)
            ox, oy = pt.offset
            d = d + np.stack([c * ox - s * oy - ox, s * ox + c * oy - oy], axis=-1)
        return d

    def loads(self, p: float) -> np.ndarray:
        """Applied dead loads (N,), N and N·mm, at drive value p."""
        return self.f0 + p * self.fp

    # ---- physics ----------------------------------------------------------------------------

    def assemble(self, z: np.ndarray) -> tuple[np.ndarray, sp.coo_matrix]:
        """Internal force r (N,) and the beams' tangent K (N, N) at z (bodies carry none)."""
        r = np.zeros(self.n)
        vals = []
        frame = np.eye(2)
        for i, m in enumerate(self.models):
            a, b = self.offsets[i], self.offsets[i + 1]
            contact = None if self.contacts is None else self.contacts[i]
            ri, ab = m.assemble(z[a:b], frame, contact)
            r[a:b] = ri
            vals.append(ab[BAND:][self._band_src[i]])
        if not self.pairs and self.rigid is None:
            K = sp.coo_matrix(
                (np.concatenate(vals), (self._k_rows, self._k_cols)), shape=(self.n, self.n)
            )
            return r, K
        rows, cols = [self._k_rows], [self._k_cols]
        for ia, ib, pair in self.pairs:
            offs = (int(self.offsets[ia]), int(self.offsets[ib]))
            xa, xb = (self.node_positions(z, i) for i in (ia, ib))
            for p in pair.pairs(xa, xb):
                dofs, k, g = pair.dofs(p, offs), p[6], p[3]
                np.add.at(r, dofs, k * g * p[4])  # d(1/2 k g^2)/dz, N
                kt = k * (np.outer(p[4], p[4]) + g * p[5])
                rows.append(np.repeat(dofs, dofs.size))
                cols.append(np.tile(dofs, dofs.size))
                vals.append(kt.ravel())
        if self.rigid is not None:
            self.rigid.add(z, r, rows, cols, vals)
        K = sp.coo_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(self.n, self.n),
        )
        return r, K

    def node_positions(self, z: np.ndarray, i: int) -> np.ndarray:
        """(n_nodes, 2) mm: the deformed nodes of beam ``i`` at state ``z``."""
        q = z[self.offsets[i] : self.offsets[i + 1]].reshape(-1, 3)
        return self.models[i].reference_nodes_mm + q[:, :2]

    def _beam_of_pair(self, name: str, a: str, b: str) -> int:
        if name not in self.beam_index:
            raise FeaError(f"beam contact [{a}, {b}]: {name!r} is not a beam of the mechanism")
        return self.beam_index[name]

    @property
    def has_contact(self) -> bool:
        """Stops or declared beam pairs: Python contact terms (the reference loop runs)."""
        return self.contacts is not None or bool(self.pairs) or self.rigid is not None

    def contact_active(self) -> tuple:
        """The contact pairs acting in the last :meth:`assemble`, per beam (() without stops)."""
        stops = () if self.contacts is None else tuple(c.active for c in self.contacts)
        rigid = () if self.rigid is None else (self.rigid.active,)
        return stops + tuple(p.active for _, _, p in self.pairs) + rigid

    def hessian(self, K: sp.spmatrix, lam: np.ndarray, ro: np.ndarray) -> sp.csr_matrix:
        """Hessian of the Lagrangian, H = K - sum_i lam_i d2g_i/dz2 (N, N)."""
        if self.nl_row.size == 0:
            return sp.csr_matrix(K)
        diag = np.bincount(self.nl_theta, lam[self.nl_row] * ro, minlength=self.n)
        return (sp.csr_matrix(K) - sp.diags(diag)).tocsr()

    def stresses(self, z: np.ndarray) -> np.ndarray:
        """(B,) peak stress (MPa) of each beam."""
        return np.array(
            [
                m.peak_stress(z[self.offsets[i] : self.offsets[i + 1]])[0]
                for i, m in enumerate(self.models)
            ]
        )

    def root_stresses(self, z: np.ndarray) -> np.ndarray:
        """(B, 2) largest stress (MPa) within ``root_mm`` of each beam's start and end."""
        out = np.empty((len(self.models), 2))
        for i, m in enumerate(self.models):
            sigma, s = _stress_samples(m, z[self.offsets[i] : self.offsets[i + 1]])
            root = self.mech.beams[i].root_mm
            length = float(m.profile.length_mm)
            out[i, 0] = sigma[s <= float(root[0]) + 1e-9].max()
            out[i, 1] = sigma[s >= length - float(root[1]) - 1e-9].max()
        return out

    # ---- checks -----------------------------------------------------------------------------

    def check_rank(self) -> None:
        """Refuse redundant constraints and free rigid-body motions, naming the parts.

        Redundant rows: the undeformed Jacobian G0 (m, N) must have full row rank (otherwise the
        multipliers are not unique and the KKT system is singular). Free motions: a motion with
        G0 dz = 0 and K dz = 0 strains no beam; K's null space is exactly the rigid motions of
        each beam (reduced integration is rank sufficient), so dz = T a with a the rigid motion
        (translation, rotation) of every beam and body, and the free motions are the null space
        of the small matrix G0 T (m, 3 (B + bodies)).
        """
        _, G0, _ = self.constraints(np.zeros(self.n), 0.0)
        G0 = G0.toarray()
        if self.m:
            # m <= N rows here (else rank < m anyway): U (m, m) holds every left null vector
            u, s, _ = np.linalg.svd(G0, full_matrices=False)
            tol = 1e-10 * max(float(s.max(initial=0.0)), 1.0)
            rank = int((s > tol).sum())
            if rank < self.m:
                left = u[:, rank:]  # combinations of rows that vanish
                involved = np.flatnonzero(np.abs(left).max(axis=1) > 1e-6)
                labels = sorted({self.groups[self.row_group[i]].label for i in involved})
                raise FeaError(
                    "redundant constraints (they hold the same motion twice): "
                    + "; ".join(labels)
                    + ". Remove one of them."
                )
        # rigid motions of each part, rotations scaled by the length so the columns compare
        parts: list[tuple[str, np.ndarray]] = []
        cols = []
        L = self.length
        for i, m in enumerate(self.models):
            X = m.reference_nodes_mm
            c = X[0]
            T = np.zeros((self.n, 3))
            sl = slice(self.offsets[i], self.offsets[i + 1])
            Ti = np.zeros((m.n_nodes, 3, 3))
            Ti[:, 0, 0] = 1.0
            Ti[:, 1, 1] = 1.0
            Ti[:, 0, 2] = -(X[:, 1] - c[1]) / L
            Ti[:, 1, 2] = (X[:, 0] - c[0]) / L
            Ti[:, 2, 2] = 1.0 / L
            T[sl] = Ti.reshape(-1, 3)
            parts.append((f"beam {self.mech.beams[i].name!r}", c))
            cols.append(T)
        for k, b in enumerate(self.mech.bodies):
            T = np.zeros((self.n, 3))
            base = self.n_beam_dofs + 3 * k
            T[base, 0] = T[base + 1, 1] = 1.0
            T[base + 2, 2] = 1.0 / L
            parts.append((f"body {b.name!r}", self.body_ref[k]))
            cols.append(T)
        M = G0 @ np.hstack(cols) if self.m else np.zeros((0, 3 * len(parts)))
        _, s, vt = np.linalg.svd(np.vstack([M, np.zeros((1, M.shape[1]))]), full_matrices=True)
        s_full = np.zeros(M.shape[1])
        s_full[: s.size] = s
        free = vt[s_full <= 1e-9 * max(float(s_full.max(initial=0.0)), 1.0)]
        if free.size == 0:
            return
        notes = []
        for k, (label, c) in enumerate(parts):
            a = free[:, 3 * k : 3 * k + 3]
            if np.abs(a).max() < 1e-6:
                continue
            if free.shape[0] == 1 and abs(a[0, 2]) > 1e-6:
                w = a[0, 2] / L
                centre = c + np.array([-a[0, 1], a[0, 0]]) / w
                notes.append(f"{label} (turns about ({centre[0]:.4g}, {centre[1]:.4g}) mm)")
            elif free.shape[0] == 1:
                notes.append(f"{label} (translates along ({a[0, 0]:.3g}, {a[0, 1]:.3g}))")
            else:
                notes.append(label)
        raise FeaError(
            f"free rigid-body motion ({free.shape[0]} degree(s) of freedom no beam resists): "
            + ", ".join(notes)
            + " can move without deforming any beam; add a joint or a support, or drive that "
            "motion under displacement/rotation control"
        )


def _stress_samples(m: BeamModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|N|/A + |M| c/I (MPa) at every stress sampling point of a beam and their arc lengths (mm),
    both flat: the numbers :meth:`fea.beam.BeamModel.peak_stress` takes the largest of (its numpy
    path, whichever kernel the model runs)."""
    t = m.tables
    qe = q[t.edofs3]
    grad = t.dN @ qe
    theta = t.theta0 + qe[:, :, 2] @ t.NgT
    g1 = (
        np.cos(theta) * (t.cos_theta0 + grad[..., 0])
        + np.sin(theta) * (t.sin_theta0 + grad[..., 1])
        - 1.0
    )
    kappa = np.einsum("eqk,ek->eq", t.dN_samples, qe[:, :, 2])
    sigma = (
        m.material.E_MPa * np.abs(g1 @ t.gauss_to_samples)
        + np.abs(t.EI_samples * kappa) / t.section_modulus_samples
    )
    return sigma.ravel(), t.s_samples.ravel()


def _row(pt: _Point, w: np.ndarray, group: int) -> tuple:
    """Arguments of _Rows.add for the row w . (displacement of pt) = 0."""
    coefs, nl = pt.row(w)
    return coefs, group, 0.0, nl


def _unit(direction: Sequence[float], what: str) -> np.ndarray:
    d = np.asarray(direction, dtype=float)
    if d.shape != (2,) or not np.all(np.isfinite(d)) or np.hypot(*d) < 1e-12:
        raise FeaError(f"{what}: direction = {direction!r} must be a non-zero [dx, dy] pair")
    return d / np.hypot(*d)


# ==================================================================================== solver


class _State(NamedTuple):
    """A converged state: z (N,), lam (m,), internal force r (N,), and the Hessian of the
    Lagrangian and the constraint Jacobian, as scipy matrices H (N, N), G (m, N) (reference) or
    as the compiled kernel's arrays: the beams' band tangent ``abc`` (N_b, LDAB), the
    constraint-Hessian term ``kf`` (k,) on the nonlinear rows' theta DOFs and G dense (m, N)."""

    z: np.ndarray
    lam: np.ndarray
    r: np.ndarray
    H: sp.csr_matrix | None
    G: sp.csr_matrix | np.ndarray
    abc: np.ndarray | None = None
    kf: np.ndarray | None = None


class _Solver:
    """Newton on the KKT system and the stability test, for one _Model."""

    def __init__(self, model: _Model) -> None:
        self.model = model
        self.st = model.settings
        kernel = resolve_constrained_kernel(self.st.kernel)
        if kernel == "numba" and (
            _kernels() is None
            or any(m.kernel != "numba" for m in model.models)
            or model.has_contact  # the contact terms are Python: the reference loop
        ):
            kernel = "numpy"
        #: "numba" (compiled, fea/_mechanism_kernels.py) or "numpy" (the reference)
        self.kernel = kernel
        if kernel == "numba":
            self._setup_compiled()

    def _setup_compiled(self) -> None:
        """The beams' kernel tables concatenated along the elements, the constraint rows as
        dense arrays, the index arrays in the kernel's types."""
        md = self.model
        geos = [m._geo for m in md.models]
        self._geo = tuple(
            geos[0][k] if k == 1 else np.ascontiguousarray(np.concatenate([g[k] for g in geos]))
            for k in range(len(geos[0]))
        )
        self._eoff = np.concatenate([[0], np.cumsum([m.n_elements for m in md.models])]).astype(
            np.int64
        )
        self._offsets = md.offsets.astype(np.int64)
        self._rot = md.rot_dofs.astype(np.int64)
        self._frame = np.eye(2)
        self._A = np.ascontiguousarray(md.A.toarray())
        self._nl_row = md.nl_row.astype(np.int64)
        self._nl_theta = md.nl_theta.astype(np.int64)
        self._nl_off = np.ascontiguousarray(md.nl_off)
        self._nl_w = np.ascontiguousarray(md.nl_w)
        st = self.st
        self._fpar = np.array(
            [st.rtol, st.ctol, st.dtol, st.max_rotation_step, md.length, md.force_floor]
        )

    def _newton_compiled(
        self, z0: np.ndarray, lam0: np.ndarray, p: float, predictor: tuple | None
    ) -> tuple[bool, _State | None, np.ndarray | None, int, str] | None:
        """:meth:`newton` on the compiled kernel; None when it hands the sub-step back (the
        bordered solve cannot take this system) and the reference must run it."""
        md = self.model
        start = (z0, lam0) if predictor is None else predictor
        z = np.array(start[0], dtype=np.float64)
        lam = np.array(start[1], dtype=np.float64)
        r = np.empty(md.n)
        abc = np.empty((md.n_beam_dofs, LDAB))
        G = np.empty((md.m, md.n))
        kf = np.empty(self._nl_row.shape[0])
        z_pred = np.empty(md.n)
        status, it = _kernels().newton(
            z, lam, float(p), md.loads(p), predictor is not None, self._A, md.b0, md.bp,
            self._nl_row, self._nl_theta, self._nl_off, self._nl_w, self._geo, self._eoff,
            self._offsets, self._frame, self._rot, self._fpar, int(self.st.max_iterations), r,
            abc, G, kf, z_pred,
        )  # fmt: skip
        kern = _kernels()
        if status == kern.OK:
            return True, _State(z, lam, r, None, G, abc, kf), z_pred, int(it), ""
        if status == kern.FALLBACK:
            return None
        if status == kern.MAX_ITERATIONS:
            reason = f"Newton did not converge in {self.st.max_iterations} iterations"
        else:
            reason = _REASONS[int(status)]
        return False, None, None, int(it), reason

    def newton(
        self, z0: np.ndarray, lam0: np.ndarray, p: float, predictor: tuple | None
    ) -> tuple[bool, _State | None, np.ndarray | None, int, str]:
        """Equilibrium at p: (converged, state, predicted z, iterations, reason)."""
        if self.kernel == "numba":
            out = self._newton_compiled(z0, lam0, p, predictor)
            if out is not None:
                return out
        md, st = self.model, self.st
        if predictor is not None:
            z, lam = predictor
            z_pred = z
        else:
            z, lam = z0.copy(), lam0.copy()
            z_pred = None
        f = md.loads(p)
        first = None
        for it in range(1, st.max_iterations + 1):
            r, K = md.assemble(z)
            if not np.all(np.isfinite(r)):
                return False, None, None, it, "the internal force became NaN or inf"
            g, G, ro = md.constraints(z, p)
            H = md.hessian(K, lam, ro)
            res = r - f - G.T @ lam
            scale = max(float(np.linalg.norm(G.T @ lam)), float(np.linalg.norm(f)), md.force_floor)
            norm = float(np.linalg.norm(res))
            res_ok = norm <= st.rtol * scale
            first = norm if first is None else first
            if it > 4 and norm > 1e6 * max(first, st.rtol * scale):
                # far off the path (a snap the sub-step jumped over): a smaller sub-step, now
                return False, None, None, it, "Newton diverged"
            gap_ok = float(np.abs(g).max(initial=0.0)) <= st.ctol * md.length
            if res_ok and gap_ok and (it > 1 or predictor is not None):
                return True, _State(z, lam, r, H, G), z_pred, it - 1, ""
            J = sp.bmat([[H, -G.T], [G, None]], format="csc")
            try:
                step = splu(J, permc_spec="MMD_AT_PLUS_A").solve(-np.concatenate([res, g]))
            except RuntimeError:
                return False, None, None, it, "singular system (a mechanism or a limit point)"
            if not np.all(np.isfinite(step)) or np.abs(step[: md.n]).max() > 1e3 * md.length:
                return False, None, None, it, "singular system (a mechanism or a limit point)"
            dz, dlam = step[: md.n], step[md.n :]
            big = np.abs(dz[md.rot_dofs]).max(initial=0.0) / st.max_rotation_step
            if big > 1.0:
                dz, dlam = dz / big, dlam / big
            z = z + dz
            lam = lam + dlam
            if md.has_contact:
                z, lam, dz = self._backtrack(z, lam, dz, dlam, norm, f, p)
            if z_pred is None:
                z_pred = z  # the linearised predictor (first Newton iterate from the last state)
            if np.abs(dz).max() <= st.dtol * md.length:
                r, K = md.assemble(z)
                g, G, ro = md.constraints(z, p)
                if float(np.abs(g).max(initial=0.0)) <= st.ctol * md.length:
                    return True, _State(z, lam, r, md.hessian(K, lam, ro), G), z_pred, it, ""
        return (
            False,
            None,
            None,
            st.max_iterations,
            (f"Newton did not converge in {st.max_iterations} iterations"),
        )

    def _backtrack(self, z, lam, dz, dlam, norm, f, p):
        """Halve a Newton correction that changed the set of acting contact pairs while it
        raises the equilibrium residual above ``norm`` (N), at most 8 times (as
        :meth:`fea.beam.BeamModel._backtrack`: a pair that switches off between two iterates
        drops the stop's force, and the next full correction falls deep into the stop; plain
        Newton can then cycle on and off). Returns ``(z, lam, dz)``."""
        md = self.model
        active = md.contact_active()  # of the assembly at the state before the correction
        r, _ = md.assemble(z)
        if md.contact_active() == active:
            return z, lam, dz
        for _ in range(8):
            _, G, _ = md.constraints(z, p)
            if float(np.linalg.norm(r - f - G.T @ lam)) <= norm:
                break
            dz, dlam = 0.5 * dz, 0.5 * dlam
            z, lam = z - dz, lam - dlam
            r, _ = md.assemble(z)
        return z, lam, dz

    def is_stable(self, s: _State, drop_row: int = -1) -> bool:
        """Constrained stability: Z^T H Z positive definite on the null space of G (see module)."""
        if not self.st.check_stability:
            return True
        if s.abc is not None:
            md = self.model
            C = s.G if drop_row < 0 else np.delete(s.G, drop_row, axis=0)
            negative = _kernels().kkt_negatives_band(
                s.abc, md.n, self._nl_theta, self._nl_theta, s.kf, np.ascontiguousarray(C)
            )
            if negative >= 0:
                return negative == C.shape[0]
            # a zero pivot: the reference's count (dense Bunch-Kaufman) below decides
            _, K = md.assemble(s.z)
            _, G, ro = md.constraints(s.z, 0.0)  # G and its curvature do not depend on p
            s = s._replace(H=md.hessian(K, s.lam, ro), G=G)
        G = s.G
        if drop_row >= 0:
            keep = np.setdiff1d(np.arange(G.shape[0]), [drop_row])
            G = G[keep]
        return kkt_negative_count(s.H, G) == G.shape[0]


def solve_mechanism(
    mech: Mechanism,
    case: LoadCase,
    outputs: Sequence[MechOutput] = (),
    settings: MechanismSettings | None = None,
) -> MechanismResponse:
    """Trace the equilibrium path of ``mech`` under ``case``, one row per drive value.

    The unknowns are every beam's DOFs (u, v mm, phi rad per node) and every body's (U, V mm of
    its reference point, theta rad). Joints, supports and the drive are constraint rows
    g(z, p) = 0 with Lagrange multipliers (the constraint forces, N or N·mm); equilibrium
    r(z) - f(p) - G(z)^T lam = 0 is solved by Newton on the KKT system with the constraint
    Hessian term in the tangent. Rows are reached through adaptive sub-steps with the branch
    guards of fea.beam (secant predictor, path-turn and stability-crossing retries).

    Stability (``stable``): an equilibrium is stable when the Hessian of the Lagrangian is
    positive definite on the null space of the constraint Jacobian (Z^T H Z > 0), with the
    constraints of the case: under displacement / rotation control the drive is a constraint
    (an actuator holding the part), so a snap-through traced under displacement control is
    stable wherever the held part cannot escape, and unstable only past a bifurcation of the
    constrained system (e.g. an asymmetric mode of a symmetric arch). ``stable_released`` is the
    same test with the drive row dropped: the equilibrium under a dead load equal to the
    reaction, i.e. what force control would see (False on a negative-stiffness stretch).
    Computed by the inertia of the KKT matrix: with G of full row rank m, it has exactly m
    negative eigenvalues iff Z^T H Z is positive definite.

    Parameters
    ----------
    mech : Mechanism
    case : LoadCase
    outputs : sequence of MechOutput — names must be unique.
    settings : MechanismSettings, optional.

    Returns
    -------
    MechanismResponse — failure to converge is data (``converged``, ``ok``, ``message``).

    Stops (``mech.stops``): frictionless penalty contact of every beam with the rigid stops
    (:class:`fea.stops.BeamContact` per beam, its forces and exact tangent added to every
    assembly; the reference loop runs, with a correction that changes the acting pairs halved
    while it raises the residual). ``response.contact`` holds the stops' forces, gaps and
    closing drive values. A path that penetrates a stop deeper than
    ``settings.contact.penetration_tol`` x the thinnest beam is traced again with a 10x
    stiffer penalty (at most ``max_raises`` times; ``contact.extra`` says the factor and the
    raises; still beyond it: ``contact.penetration_ok`` False with its message). Without stops
    the solve is the one it always was (same code, same numbers).

    Raises
    ------
    FeaError
        Bad input: unknown parts, duplicate names, joined ends apart, redundant constraints, a
        free rigid-body motion (the part named), bad outputs, a stop overlapping a beam.
    """
    st = settings or MechanismSettings()
    if not mech.stops:
        return _trace(mech, case, outputs, st)
    contact = st.contact
    for raises in range(int(contact.max_raises) + 1):
        st = replace(st, contact=contact)
        response = _trace(mech, case, outputs, st)
        if response.contact.penetration_ok or raises == contact.max_raises:
            break
        # deeper than the tolerance: the same path with a 10x stiffer penalty
        contact = replace(contact, penalty_factor=10.0 * contact.penalty_factor)
    response.contact.extra.update(penalty_factor=contact.penalty_factor, raises=raises)
    if not response.contact.penetration_ok:
        note = f"contact: {response.contact.message}"
        response = replace(response, message=f"{response.message}; {note}".lstrip("; "))
    return response


def _trace(
    mech: Mechanism, case: LoadCase, outputs: Sequence[MechOutput], st: MechanismSettings
) -> MechanismResponse:
    """:func:`solve_mechanism` with the settings ``st`` (one penalty; no raises)."""
    md = _Model(mech, case, st)
    md.check_rank()
    readers = _output_readers(md, outputs)
    solver = _Solver(md)
    drv = case.drive
    steps = int(drv.steps)
    targets = drv.min_value + (drv.max_value - drv.min_value) * np.arange(steps + 1) / steps
    step_size = abs(targets[1] - targets[0])
    n_rows = steps + 1
    nb = len(mech.beams)
    Z = np.full((n_rows, md.n), np.nan)
    LAM = np.full((n_rows, md.m), np.nan)
    R = np.full((n_rows, md.n), np.nan)
    peak = np.full((n_rows, nb), np.nan)
    roots = np.full((n_rows, nb, 2), np.nan)
    converged = np.zeros(n_rows, dtype=bool)
    stable = np.zeros(n_rows, dtype=bool)
    released = np.zeros(n_rows, dtype=bool)

    z = np.zeros(md.n)
    lam = np.zeros(md.m)
    ok, state, _, _, reason = solver.newton(z, lam, 0.0, None)
    message = ""
    critical = float("nan")
    lost_state = None
    if not ok:
        message = f"no equilibrium in the undeformed state: {reason}"
    else:
        is_stab = solver.is_stable(state)
        value = 0.0
        history: list[tuple[float, np.ndarray, np.ndarray]] = [(0.0, state.z, state.lam)]
        h = st.first_substep * step_size
        lost: tuple[int, float, float] | None = None
        # targets[0] may be nonzero: it is reached first, through sub-steps like any row
        for k in range(n_rows):
            target = targets[k]
            row_stable = is_stab
            sign = np.sign(target - value) or 1.0
            while abs(target - value) > 1e-9 * step_size:
                inc = sign * min(h, abs(target - value))
                p_try = value + inc
                pred = None
                if len(history) >= 2 and history[-1][0] != history[-2][0]:
                    (v1, z1, l1), (v2, z2, l2) = history[-2], history[-1]
                    t = inc / (v2 - v1)
                    pred = (z2 + (z2 - z1) * t, l2 + (l2 - l1) * t)
                ok, new, z_pred, it, reason = solver.newton(state.z, state.lam, p_try, pred)
                if ok and pred is not None:
                    dp, dc = z_pred - state.z, new.z - state.z
                    if dp @ dc < st.min_path_cosine * np.sqrt((dp @ dp) * (dc @ dc)):
                        ok, reason = False, "the sub-step left the path"
                new_stable = False
                if ok:
                    new_stable = solver.is_stable(new)
                    if (
                        is_stab
                        and not new_stable
                        and abs(inc) > st.min_critical_substep * step_size
                    ):
                        ok, reason = False, "crossed a critical point"
                if ok:
                    if is_stab and not new_stable and lost is None:
                        lost = (k, value, p_try)
                        lost_state = (new, p_try)
                    state, value, is_stab = new, p_try, new_stable
                    row_stable = row_stable and new_stable
                    history = [*history[-1:], (value, state.z, state.lam)]
                    if it <= st.fast_iterations:
                        h = min(2.0 * h, step_size)
                    continue
                h = abs(inc) / 4.0
                history = history[-1:]
                if h < st.min_substep * step_size:
                    message = (
                        f"no convergence at drive = {p_try:.6g} (row {k}, last converged "
                        f"{value:.6g}) after cutting the sub-step to {abs(inc):.3g}: {reason}"
                    )
                    break
            if message:
                break
            Z[k], LAM[k], R[k] = state.z, state.lam, state.r
            peak[k] = md.stresses(state.z)
            roots[k] = md.root_stresses(state.z)
            converged[k] = True
            stable[k] = row_stable
            released[k] = solver.is_stable(state, md.drive_row) if md.drive_row >= 0 else row_stable
        if lost is None and converged[0] and not stable[0]:
            note = (
                "unstable from row 0: the constrained tangent is not positive definite there "
                "(a prestressed start past a critical point?)"
            )
            message = f"{message}; {note}" if message else note
        if lost is not None:
            k, a, b = lost
            critical = 0.5 * (a + b)
            note = (
                f"unstable from row {k} (drive between {a:.6g} and {b:.6g}): the constrained "
                "tangent stopped being positive definite (a bifurcation or limit point)"
            )
            message = f"{message}; {note}" if message else note

    mode = body_mode = None
    if lost_state is not None:
        mode, body_mode = _critical_mode(md, *lost_state)
    outs = {name: fn(Z, LAM, R, peak, targets) for name, fn in readers.items()}
    for v in outs.values():
        v[~converged] = np.nan
    shapes = []
    thick = []
    rotations = []  # with the models: the beams' fibre stresses per node (best.vtu)
    body_poses = np.full((n_rows, len(mech.bodies), 3), np.nan)
    for i, m in enumerate(md.models):
        q = Z[:, md.offsets[i] : md.offsets[i + 1]].reshape(n_rows, -1, 3)
        shapes.append(m.reference_nodes_mm[None] + q[:, :, :2])
        rotations.append(q[:, :, 2])
        thick.append(np.interp(m.s_nodes, m.profile.arc_length_mm, m.profile.thickness_mm))
    for k in range(len(mech.bodies)):
        base = md.n_beam_dofs + 3 * k
        body_poses[:, k, :2] = md.body_ref[k] + Z[:, base : base + 2]
        body_poses[:, k, 2] = Z[:, base + 2]
    return MechanismResponse(
        case=case.name,
        drive=targets,
        outputs=outs,
        peak_stress_MPa=peak,
        shapes_mm=tuple(shapes),
        thickness_at_nodes_mm=tuple(thick),
        body_poses=body_poses,
        converged=converged,
        stable=stable & converged,
        ok=bool(converged.all()),
        message=message,
        stable_released=released & converged,
        critical_drive=critical,
        root_stress_MPa=roots,
        critical_mode=mode,
        critical_body_mode=body_mode,
        reference_nodes_mm=tuple(m.reference_nodes_mm.copy() for m in md.models),
        rotations_rad=tuple(rotations),
        beam_models=tuple(md.models),
        beam_roots_mm=tuple((float(b.root_mm[0]), float(b.root_mm[1])) for b in mech.beams),
        contact=None if md.contacts is None else _contact(md, shapes, targets, converged, Z),
        beam_contact=_beam_contact(md, shapes, converged, Z) if md.mech.beam_contacts else None,
    )


def _beam_contact(
    md: _Model, shapes: list[np.ndarray], converged: np.ndarray, Z: np.ndarray
) -> dict[str, dict[str, np.ndarray]]:
    """Per declared pair the force on part a (N), the smallest gap (mm) and in contact at every
    converged row (``shapes`` per beam (rows, nodes, 2) mm, ``Z`` (rows, N) the states)."""
    out = {} if md.rigid is None else md.rigid.pair_rows(Z, converged)
    rows = converged.shape[0]
    for ia, ib, pair in md.pairs:
        force, gap = np.full(rows, np.nan), np.full(rows, np.nan)
        for k in np.flatnonzero(converged):
            force[k], gap[k], _ = pair.state(shapes[ia][k], shapes[ib][k])
        out[pair.name] = {"force_N": force, "gap_mm": gap, "in_contact": force > 0.0}
    return out


def _contact(
    md: _Model, shapes: list[np.ndarray], drive: np.ndarray, converged: np.ndarray, Z: np.ndarray
) -> ContactResponse:
    """The stops' forces, gaps and contact points at every converged row, over all beams
    (:func:`fea.stops.contact_over_beams`); ``shapes`` per beam (rows, nodes, 2) mm, ``drive``
    (rows,) the drive values."""
    assert md.contacts is not None
    bodies = None if md.rigid is None or not md.rigid.movable else md.rigid.stop_rows(Z, converged)
    return contact_over_beams(md.contacts, shapes, drive, converged, bodies)


def _rigid_pair(pair: tuple[str, str], bodies: dict[str, int]) -> bool:
    """A declared contact pair naming a body, or one beam twice (fea.body_contact's)."""
    return pair[0] == pair[1] or pair[0] in bodies or pair[1] in bodies


def _rigid_contacts(md: _Model, mech: Mechanism, pairs: list, st: MechanismSettings):
    """fea.body_contact.MechanismContacts of the bodies with outlines against the stops and of
    the declared pairs with a body or a beam's self contact; None when there are none."""
    outlined = any(b.outline_mm is not None for b in mech.bodies)
    if not pairs and not (mech.stops and outlined):
        return None
    from flexopt.fea.body_contact import MechanismContacts

    grounded = {j.a for j in mech.joints if j.b == _GROUND and j.type == "clamped"}
    names = [b.name for b in mech.beams]
    return MechanismContacts(
        md.models, md.offsets, mech.bodies, md.n_beam_dofs, mech.stops, pairs, grounded,
        st.contact, names,
    )  # fmt: skip


def _critical_mode(
    md: _Model, state: _State, p: float
) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """The buckling mode at the first unstable state: the eigenvector of Z^T H Z (Z a basis of
    the null space of G) with the lowest eigenvalue, mapped back to z = Z v. Dense: a few hundred
    unknowns, computed once per solve that loses stability. Returns the beams' nodal
    translations (nodes, 2) and the bodies' (U, V, theta) (n_bodies, 3), scaled so that the
    largest beam-node translation is 1 and its largest component is positive (a deterministic
    sign)."""
    from scipy.linalg import eigh, null_space

    _, K = md.assemble(state.z)
    _, G, ro = md.constraints(state.z, p)
    H = md.hessian(K, state.lam, ro).toarray()
    Zb = null_space(np.asarray(G.todense()))
    A = Zb.T @ H @ Zb
    vals, vecs = eigh(0.5 * (A + A.T))
    # A repeated lowest eigenvalue (parts that buckle independently at the same load, e.g. the
    # two halves of a guided switch) has no one eigenvector: round-off would pick the mix. The
    # imperfection is then the projection of a fixed pseudo-random pattern on that eigenspace
    # (the same whatever basis eigh returns): every part in it imperfect, deterministically.
    cluster = vals <= vals[0] + 1e-8 * float(np.max(np.abs(vals)))
    V = vecs[:, cluster]
    if V.shape[1] == 1:
        v = Zb @ V[:, 0]
    else:
        pattern = np.random.default_rng(0).standard_normal(md.n)
        v = Zb @ (V @ (V.T @ (Zb.T @ pattern)))
    trans = v[: md.n_beam_dofs].reshape(-1, 3)[:, :2]
    size = float(np.max(np.hypot(trans[:, 0], trans[:, 1]), initial=0.0))
    if size > 0:
        v = v / size
    trans = v[: md.n_beam_dofs].reshape(-1, 3)[:, :2]
    big = np.unravel_index(int(np.argmax(np.abs(trans))), trans.shape)
    if trans[big] < 0:
        v = -v
    modes = tuple(
        v[md.offsets[i] : md.offsets[i + 1]].reshape(-1, 3)[:, :2].copy()
        for i in range(len(md.models))
    )
    return modes, v[md.n_beam_dofs :].reshape(-1, 3).copy()


def first_unstable_row(response: MechanismResponse) -> int | None:
    """Index of the first converged row flagged unstable (None when every converged row is
    stable): where the path the solver traced stops being the one a part can follow."""
    bad = np.flatnonzero(np.asarray(response.converged, bool) & ~np.asarray(response.stable, bool))
    return int(bad[0]) if bad.size else None


def imperfect_mechanism(
    mech: Mechanism, response: MechanismResponse, amplitude_mm: float
) -> Mechanism:
    """``mech`` with its stress-free shape moved by ``amplitude_mm`` times the response's
    buckling mode (``critical_mode``): the geometric imperfection that a made part always has,
    in the shape that matters most (the classical Koiter / Riks imperfection). The perfect,
    symmetric mechanism follows its fundamental path through the bifurcation (the solver flags
    the rows beyond it unstable); the imperfect one follows the branch a real part takes.

    Parameters
    ----------
    mech : Mechanism — the perfect mechanism that gave ``response``.
    response : MechanismResponse — with ``critical_mode`` (the path lost stability).
    amplitude_mm : float, mm — largest displacement of a beam point in the imperfection.

    Returns
    -------
    Mechanism — beams' points moved by the mode, bodies' reference points and outlines moved
    and turned with it; same joints, material, thicknesses, widths, roots (``root_mm``) and
    arcs (each drawn segment's curvature on the FE nodes' pieces within it): every other
    attribute is the drawn part's, so the imperfect path is judged as the drawn one.

    Raises
    ------
    FeaError
        When the response has no buckling mode (its path never became unstable).
    """
    if response.critical_mode is None or response.critical_body_mode is None:
        raise FeaError("the response has no buckling mode: its path never became unstable")
    a = float(amplitude_mm)
    beams = []
    for b, mode, nodes in zip(
        mech.beams, response.critical_mode, response.reference_nodes_mm, strict=True
    ):
        # the beam drawn through its FE nodes (a polyline of 2 n_el + 1 points on the original
        # centreline: a mode needs more points than a straight beam's two), each moved by the
        # mode; the thickness at each node from the original's (linear in arc length)
        pts = np.asarray(b.points_mm, dtype=float)
        s_pts = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
        s_nodes = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(nodes, axis=0).T))])
        s_nodes *= s_pts[-1] / s_nodes[-1]
        t = np.interp(s_nodes, s_pts, np.asarray(b.thickness_mm, dtype=float))
        n_el = (len(nodes) - 1) // 2
        kappa = None
        if b.curvature_per_mm is not None:
            # each node-to-node piece lies on one drawn segment (the mesh has a vertex at every
            # drawn point): it keeps that segment's arc, so no imperfection is the drawn shape
            mid = 0.5 * (s_nodes[:-1] + s_nodes[1:])
            seg = np.clip(np.searchsorted(s_pts, mid, side="right") - 1, 0, len(s_pts) - 2)
            kappa = np.asarray(b.curvature_per_mm, dtype=float)[seg]
        # replace, not a new MechBeam: every other attribute (root_mm, the flares whose stress
        # the as-made verdict multiplies by K_t, ...) is the drawn beam's (issue: false MET)
        beams.append(
            replace(
                b, points_mm=nodes + a * mode, thickness_mm=t, elements=n_el, curvature_per_mm=kappa
            )
        )
    bodies = []
    for b, (du, dv, dth) in zip(mech.bodies, response.critical_body_mode, strict=True):
        ref = np.asarray(b.ref_mm, dtype=float)
        new_ref = ref + a * np.array([du, dv])
        outline = None
        if b.outline_mm is not None:
            c, s = np.cos(a * dth), np.sin(a * dth)
            rel = np.asarray(b.outline_mm, dtype=float) - ref
            outline = rel @ np.array([[c, s], [-s, c]]) + new_ref
        bodies.append(replace(b, ref_mm=new_ref, outline_mm=outline))
    return replace(mech, beams=tuple(beams), bodies=tuple(bodies))


def _output_readers(md: _Model, outputs: Sequence[MechOutput]) -> dict:
    """name -> function (Z, LAM, R, peak, drive) -> (rows,) for each requested output."""
    readers = {}
    control = md.case.drive.control
    for o in outputs:
        what = f"output {o.name!r} ({o.quantity})"
        if o.name in readers:
            raise FeaError(f"{what}: duplicate output name")
        q = o.quantity
        if q == "peak_stress":
            if o.part == "":
                readers[o.name] = lambda Z, L, R, P, D: P.max(axis=1)
            elif o.part in md.beam_index:
                i = md.beam_index[o.part]
                readers[o.name] = lambda Z, L, R, P, D, i=i: P[:, i].copy()
            else:
                raise FeaError(f"{what}: part must be a beam name or '' (all beams)")
            continue
        if q == "reaction" and o.part == "":
            if control in ("displacement", "rotation"):
                row = md.drive_row
                readers[o.name] = lambda Z, L, R, P, D, row=row: L[:, row].copy()
            else:
                readers[o.name] = lambda Z, L, R, P, D: D.astype(float).copy()
            continue
        if q in ("displacement", "rotation"):
            pt = md.point(o.part, what)
            if q == "rotation":
                readers[o.name] = lambda Z, L, R, P, D, r=pt.r: Z[:, r].copy()
            else:
                u = _unit(o.direction, what)
                readers[o.name] = lambda Z, L, R, P, D, pt=pt, u=u: md.point_displacement(Z, pt) @ u
            continue
        if q in ("reaction", "reaction_force", "reaction_moment"):
            if o.part == "":
                groups = [md.drive_group]
                x, y, r = md.part_dofs(md.case.drive.part, what)
                with_load = True
            else:
                x, y, r = md.part_dofs(o.part, what)
                # a body held at any of its points: all its ground rows, read about its
                # reference point
                groups = [
                    g
                    for g, gr in enumerate(md.groups)
                    if gr.ground_part and _part_name(gr.ground_part) == _part_name(o.part)
                ]
                if not groups:
                    raise FeaError(
                        f"{what}: {o.part!r} is not held to the ground by a joint or a support"
                    )
                with_load = False
            rows = np.flatnonzero(np.isin(md.row_group, groups))
            u = _unit(o.direction, what)
            moment = q == "reaction_moment"
            readers[o.name] = _reaction_reader(md, rows, (x, y, r), u, moment, with_load)
            continue
        raise FeaError(
            f"{what}: quantity must be reaction, reaction_force, reaction_moment, displacement, "
            "rotation or peak_stress"
        )
    return readers


def _reaction_reader(md: _Model, rows: np.ndarray, dofs, u: np.ndarray, moment: bool, load: bool):
    """Force (N, along u) or moment (N·mm) applied on a part by the constraint rows ``rows``
    (plus the drive's applied load when ``load``): (G_rows^T lam_rows) at the part's DOFs."""
    x, y, r = dofs

    def read(Z, L, R, P, D):
        out = np.full(Z.shape[0], np.nan)
        for k in range(Z.shape[0]):
            if not np.all(np.isfinite(Z[k])):
                continue
            _, G, _ = md.constraints(Z[k], float(D[k]))
            F = G[rows].T @ L[k, rows]
            if load:
                F = F + md.fp * D[k]
            out[k] = F[r] if moment else F[x] * u[0] + F[y] * u[1]
        return out

    return read


def check_mechanism(mech: Mechanism, case: LoadCase | None = None) -> None:
    """Refuse a mechanism (or a mechanism under a load case) that cannot be solved.

    Raises FeaError naming the problem: a bad or duplicate part name, an unknown part in a joint,
    a support or the drive, joined beam ends that do not meet, redundant constraints, and, with
    ``case``, a free rigid-body motion (a part that can move without deforming any beam, with
    its rotation centre or translation direction). Without ``case`` the free-motion test is
    skipped: a case's supports and drive may be what holds a part.
    """
    md = _Model(mech, case, MechanismSettings(default_elements=2))
    if case is not None:
        md.check_rank()


def mass_g(mech: Mechanism, body_thickness_mm: float = 0.0) -> float:
    """Mass (g) of the beams, plus the bodies when ``body_thickness_mm`` > 0.

    Beams: integral of thickness x width over the arc length (exact: thickness is linear in arc
    length) x density. Bodies: outline area (shoelace) x ``body_thickness_mm`` x density; bodies
    without an outline count 0. NaN when the material has no density.
    """
    rho = mech.material.density_kg_m3 * 1e-6  # kg/m^3 -> g/mm^3
    vol = 0.0
    for b in mech.beams:
        prof = BeamProfile(
            points_mm=np.asarray(b.points_mm, dtype=float),
            thickness_mm=np.asarray(b.thickness_mm, dtype=float),
            width_mm=float(b.width_mm),
            curvature_per_mm=None if b.curvature_per_mm is None else np.asarray(b.curvature_per_mm),
        )
        t = prof.thickness_mm
        vol += float(np.sum(prof.segment_lengths_mm * 0.5 * (t[:-1] + t[1:]))) * prof.width_mm
    if body_thickness_mm > 0:
        for bd in mech.bodies:
            if bd.outline_mm is None:
                continue
            xy = np.asarray(bd.outline_mm, dtype=float)
            x, y = xy[:, 0], xy[:, 1]
            area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
            vol += area * body_thickness_mm
    return vol * rho


def warm_up() -> str:
    """Compile (first call in an install) or load from numba's cache the mechanism kernels now.

    Like :func:`fea.constrained_beams.warm_up` (which this calls first): a process pool calls it
    before it forks, so that workers inherit the compiled code. A tiny lever (a body pinned to
    the ground, turned through a leaf: the nonlinear rows) is traced two rows on the compiled
    path, with its stability counted.

    Returns
    -------
    str
        The path that runs: "numba", or "numpy" when numba is unavailable (nothing to do).
    """
    from flexopt.fea.constrained_beams import warm_up as constrained_warm_up

    constrained_warm_up()
    kernel = resolve_constrained_kernel("auto")
    if kernel != "numba" or _kernels() is None:
        return "numpy"
    material = Material("warm-up", E_MPa=1000.0, nu=0.3, yield_MPa=10.0)
    leaf = MechBeam("leaf", np.array([[2.0, 0.0], [-8.0, 0.0]]), np.array([1.0, 1.0]), 1.0, 2)
    mech = Mechanism(
        (leaf,),
        (MechBody("arm", np.zeros(2)),),
        (
            MechJoint("arm", "ground", "pinned"),
            MechJoint("leaf.start", "arm@2,0", "pinned"),
            MechJoint("leaf.end", "ground"),
        ),
        material,
    )
    case = LoadCase("warm-up", MechDrive("arm@-2,0", "displacement", 0.1, 2, (0.0, 1.0)))
    solve_mechanism(mech, case, (), MechanismSettings(kernel="numba"))
    return kernel


def stable_positions(drive: np.ndarray, reaction: np.ndarray) -> tuple[int, float | None]:
    """Equilibria the drive can be released at (reaction 0 with positive stiffness): the
    undeformed state, plus every upward zero crossing of the reaction along the drive."""
    ok = np.isfinite(reaction)
    x, f = drive[ok], reaction[ok]
    if x.size < 2:
        return 0, None
    order = np.argsort(x)
    x, f = x[order], f[order]
    count, second = 1, None
    for k in range(len(x) - 1):
        if f[k] < 0.0 <= f[k + 1] and not (x[k] <= 0.0 <= x[k + 1]):
            at = float(x[k] - f[k] * (x[k + 1] - x[k]) / (f[k + 1] - f[k]))
            count += 1
            second = at if second is None else second
    return count, second


def sensitivity_model(
    mech: Mechanism,
    case: LoadCase,
    outputs: Sequence[MechOutput] = (),
    settings: MechanismSettings | None = None,
):
    """``(model, readers, newton)``: the meshed model of ``mech`` under ``case`` (the solver's
    unknowns, constraint rows, assembly), its output readers and the solver's Newton at a drive
    value, for :mod:`fea.mechanism_sensitivity` (which differentiates the converged rows with
    the solver's own numbering)."""
    md = _Model(mech, case, settings or MechanismSettings())
    return md, _output_readers(md, outputs), _Solver(md).newton
