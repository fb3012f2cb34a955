"""A planar compliant mechanism as data: beams, rigid bodies, joints, one drive per load case.

Skeleton (API only); the solver follows. See docs/mechanism_engine.md.

Units: mm, N, N·mm, rad, MPa.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from fea.errors import FeaError
from fea.materials import Material

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
    """

    name: str
    points_mm: np.ndarray
    thickness_mm: np.ndarray
    width_mm: float
    elements: int = 0
    curvature_per_mm: np.ndarray | None = None


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

    Attributes
    ----------
    a : str — "beamname.start" or "beamname.end"; also a body name when ``b`` is "ground" (a body
        clamped to the ground, or pinned to it at its reference point: an ideal revolute joint).
    b : str — "ground", a body name, or another beam end "otherbeam.start" / "otherbeam.end".
    type : "clamped" (positions and section angles tied; to a body the end moves with it rigidly)
        or "pinned" (positions tied, rotations independent).
    """

    a: str
    b: str
    type: Literal["clamped", "pinned"] = "clamped"


@dataclass(frozen=True)
class MechDrive:
    """The one drive of a load case.

    Attributes
    ----------
    part : str — "bodyname" (acts at its reference point) or "beamname.end" / "beamname.start".
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
        "displacement" — mm, motion of the body reference point / beam end node along direction.
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
    """

    beams: tuple[MechBeam, ...]
    bodies: tuple[MechBody, ...]
    joints: tuple[MechJoint, ...]
    material: Material


@dataclass(frozen=True)
class MechanismSettings:
    """Discretisation and solver tolerances (see the solver for the reasons)."""

    default_elements: int = 30


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


def check_mechanism(mech: Mechanism, case: LoadCase | None = None) -> None:
    """Raise FeaError naming the problem: unknown or duplicate names, beam ends joined that do not
    meet, and (with a case) a part free to move without deforming any beam."""
    raise FeaError("not implemented yet")


def solve_mechanism(
    mech: Mechanism,
    case: LoadCase,
    outputs: Sequence[MechOutput] = (),
    settings: MechanismSettings | None = None,
) -> MechanismResponse:
    """Trace the equilibrium path of ``mech`` under ``case`` (not implemented yet)."""
    raise FeaError("not implemented yet")


def mass_g(mech: Mechanism, body_thickness_mm: float = 0.0) -> float:
    """Mass (g) of the beams (thickness x width x length x density), plus the bodies' outline
    area x ``body_thickness_mm`` x density when that is > 0 (bodies without an outline count 0)."""
    raise FeaError("not implemented yet")
