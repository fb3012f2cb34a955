"""A traced beam's section and outer-fibre stresses at every node and load step: what best.vtu
draws on the beam's lines (issue #26 item 5).

The stresses are the solver's own sampled ones (:meth:`fea.beam.BeamModel.peak_stress`): in
every P2 element the beam samples its stress at both ends and the middle, which are the
element's three nodes. At a sampling point the axial term ``a = E g1`` (the axial strain taken
at the two Gauss points and extrapolated linearly, as the solver does) and the bending term
``c = E t kappa / 2`` (``kappa = phi'``, exact there) give the two outer fibres:

- ``left``: the fibre at ``+t/2`` along the normal (the tangent turned 90 degrees
  counter-clockwise), ``a - c`` (its strain is ``g1 - (t/2) kappa``);
- ``right``: the fibre at ``-t/2``, ``a + c``;
- ``equivalent``: ``|a| + |c|``, the larger magnitude of the two: the solver's stress (the
  section is uniaxial; the shear of the Timoshenko term is not part of the solver's stress).

How nodes get them: a mid-side node is one element's middle sampling point; an end node of
the beam is its element's end; an interior vertex is the end of two elements whose curvatures
differ (``phi'`` jumps between P2 elements), and it takes the sample of the element with the
larger equivalent stress, so that the largest equivalent stress over the nodes of a row is the
row's ``peak_stress_MPa`` (the value the verdicts read).

A part of several members (a pivot's leaves, a mechanism's beams: :func:`members_field`) is
one centreline of the members one after another with one NaN node between two members (the
layout of :attr:`fea.pivot.PivotResponse.shapes_mm`), so that no line joins two members; each
member's nodes carry its own section and stresses, computed from that member's state exactly
as for one beam, and the NaN node carries NaN.

Units: mm, MPa, rad.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from flexopt.fea.beam import BeamModel, BeamResponse

__all__ = [
    "ARM_NOTE",
    "ARM_JUDGED_ELSEWHERE",
    "Members",
    "arm_field",
    "beam_field",
    "constrained_members",
    "join_members",
    "members_field",
    "section_field",
]


def beam_field(model: BeamModel, response: BeamResponse) -> dict[str, Any] | None:
    """The section and the fibre stresses of ``response`` (traced by ``model``) per node
    (:func:`section_field` of its shapes and rotations); None when the response carries no
    rotations (a stand-in response)."""
    rotations = getattr(response, "rotations_rad", None)
    if rotations is None:
        return None
    return section_field(model, response.shapes_mm, rotations)


def section_field(
    model: BeamModel, shapes_mm: np.ndarray, rotations_rad: np.ndarray
) -> dict[str, Any]:
    """The section and the fibre stresses of one beam traced by ``model`` per node.

    Parameters
    ----------
    model : BeamModel — the beam as solved (its profile, material and mesh).
    shapes_mm : (n_rows, n_nodes, 2) float, mm — the deformed node positions per row.
    rotations_rad : (n_rows, n_nodes) float, rad — the nodes' section rotation per row (the
        model's third DOF); a row with a NaN is a row that did not converge.

    Returns
    -------
    dict
        ``s_mm`` (n_nodes,) mm, the nodes' arc length; ``thickness_mm`` (n_nodes,) mm, the
        section thickness at the nodes (the profile's, as analysed); ``segment_thickness_mm``
        (n_nodes - 1,) mm, the profile's mean thickness over each segment between consecutive
        nodes (the thickness is linear between profile points, so its value at the segment's
        middle); ``width_mm`` (n_nodes - 1,) mm, the out-of-plane width per segment;
        ``fibre_left_MPa``, ``fibre_right_MPa`` and ``equivalent_MPa`` (n_rows, n_nodes) MPa,
        signed outer-fibre stresses and the equivalent stress (see the module docstring), NaN on
        rows that did not converge.
    """
    profile = model.profile
    tab = model.tables
    shapes = np.asarray(shapes_mm, dtype=float)  # (R, N, 2)
    rotations = np.asarray(rotations_rad, dtype=float)  # (R, N)
    n_rows, n_nodes = rotations.shape
    n_el = model.n_elements
    E = float(model.material.E_MPa)
    left = np.full((n_rows, n_nodes), np.nan)
    right = np.full((n_rows, n_nodes), np.nan)
    ngt = np.ascontiguousarray(tab.N.T)  # (3, Q)
    thickness_ratio = tab.EI_samples / tab.section_modulus_samples  # E t / 2, (E, 3) MPa
    for k in range(n_rows):
        if not np.all(np.isfinite(rotations[k])):
            continue  # a row that did not converge: no state
        u = np.column_stack([shapes[k] - model.reference_nodes_mm, rotations[k]]).ravel()
        qe = u[tab.edofs3]  # (E, 3 nodes, 3 fields)
        grad = tab.dN @ qe  # (E, Q, 3): d/ds of u, v, phi at the Gauss points
        theta = tab.theta0 + qe[:, :, 2] @ ngt
        g1 = (
            np.cos(theta) * (tab.cos_theta0 + grad[..., 0])
            + np.sin(theta) * (tab.sin_theta0 + grad[..., 1])
            - 1.0
        )
        a = E * (g1 @ tab.gauss_to_samples)  # (E, 3) MPa, the axial term N/A
        kappa = np.einsum("eqk,ek->eq", tab.dN_samples, qe[:, :, 2])  # (E, 3) 1/mm
        c = thickness_ratio * kappa  # (E, 3) MPa, the bending term M c / I
        eq = np.abs(a) + np.abs(c)
        # sample j of element e sits on node 2e + j; where two elements meet (node 2e + 2 =
        # node 2(e + 1)), the larger equivalent stress wins (the module docstring says why)
        lo = a - c
        hi = a + c
        node_left = np.empty(n_nodes)
        node_right = np.empty(n_nodes)
        node_eq = np.full(n_nodes, -np.inf)
        for j in range(3):
            idx = 2 * np.arange(n_el) + j
            take = eq[:, j] > node_eq[idx]
            node_left[idx[take]] = lo[take, j]
            node_right[idx[take]] = hi[take, j]
            node_eq[idx[take]] = eq[take, j]
        left[k] = node_left
        right[k] = node_right
    s = np.asarray(model.s_nodes, dtype=float)
    s_mid = 0.5 * (s[:-1] + s[1:])
    return {
        "s_mm": s,
        "thickness_mm": np.interp(s, profile.arc_length_mm, profile.thickness_mm),
        "segment_thickness_mm": np.interp(s_mid, profile.arc_length_mm, profile.thickness_mm),
        "width_mm": np.full(n_nodes - 1, float(profile.width_mm)),
        "fibre_left_MPa": left,
        "fibre_right_MPa": right,
        "equivalent_MPa": np.maximum(np.abs(left), np.abs(right)),
    }


def join_members(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """Per-member node arrays joined along the node axis (axis 1) with one NaN node between two
    members (the layout of :attr:`fea.pivot.PivotResponse.shapes_mm`).

    ``arrays``: one per member, each (n_rows, n_nodes_i, ...) (the trailing axes alike); returns
    (n_rows, sum(n_nodes_i) + n_members - 1, ...) float."""
    parts = [np.asarray(a, dtype=float) for a in arrays]
    gap = np.full((parts[0].shape[0], 1, *parts[0].shape[2:]), np.nan)
    return np.concatenate([x for a in parts for x in (a, gap)][:-1], axis=1)


class Members(NamedTuple):
    """What a multi-member engine keeps of its solve for the members' fields: its models and
    the shapes and rotations it has anyway (references or small copies, no extra solve).

    models : the members' BeamModels, in the part's order.
    shapes_mm : per member (n_rows, n_nodes_i, 2) float, mm — deformed node positions.
    rotations_rad : per member (n_rows, n_nodes_i) float, rad — the nodes' section rotation (NaN
        on rows that did not converge).
    """

    models: tuple[BeamModel, ...]
    shapes_mm: tuple[np.ndarray, ...]
    rotations_rad: tuple[np.ndarray, ...]


def members_field(
    members: Members | None, width_mm: float | None = None, stress_factor: float = 1.0
) -> dict[str, Any] | None:
    """:func:`section_field` of every member of a part, joined as :func:`join_members` joins
    their shapes (one NaN node between two members; the module docstring); None without
    ``members`` (a response that kept none).

    Parameters
    ----------
    members : Members — the members' models, shapes and rotations.
    width_mm : float, mm, optional — the out-of-plane width of the part as made where it is not
        the width the members were solved with (a kind that rescales the width after the solve:
        its stresses under a prescribed motion do not depend on the width); default the
        members' own.
    stress_factor : float, no unit — what the kind's verdict multiplies the beams' peak stress
        by (a notch hinge's K_t: the notch is modelled as its equivalent beam, whose nominal
        stress the nodes carry); kept as ``verdict_stress_factor`` when it is not 1.

    Returns
    -------
    dict
        the keys of :func:`section_field` over the joined nodes (N = sum(n_nodes_i) +
        n_members - 1; segments N - 1), NaN at the separator nodes and on the two segments
        touching each, ``s_mm`` each member's own arc length, and ``member_of_segment``
        (N - 1,) float, the member index of each segment (NaN on the separators' segments).
    """
    if members is None:
        return None
    fields = [
        section_field(m, s, r)
        for m, s, r in zip(members.models, members.shapes_mm, members.rotations_rad, strict=True)
    ]
    node_keys = ("fibre_left_MPa", "fibre_right_MPa", "equivalent_MPa")
    out: dict[str, Any] = {k: join_members([f[k] for f in fields]) for k in node_keys}
    for key in ("s_mm", "thickness_mm"):
        out[key] = join_members([f[key][None] for f in fields])[0]
    for key in ("segment_thickness_mm", "width_mm"):
        out[key] = _join_segments([f[key] for f in fields])
    out["member_of_segment"] = _join_segments(
        [np.full(len(f["width_mm"]), float(i)) for i, f in enumerate(fields)]
    )
    if width_mm is not None:
        out["width_mm"] = np.where(np.isfinite(out["width_mm"]), float(width_mm), np.nan)
    if stress_factor != 1.0:
        out["verdict_stress_factor"] = float(stress_factor)
    return out


def _join_segments(per_member: Sequence[np.ndarray]) -> np.ndarray:
    """Per-member segment arrays (n_nodes_i - 1,) joined as the members' nodes are: between two
    members the two segments to and from the separator node, NaN."""
    gap = np.full(2, np.nan)
    return np.concatenate([x for a in per_member for x in (np.asarray(a, float), gap)][:-1])


def constrained_members(models: Sequence[BeamModel], response: Any) -> Members:
    """The :class:`Members` of a :class:`fea.constrained_beams.ConstrainedResponse` solved with
    the beams ``models``: their shapes as the response has them and the rotations out of its
    states (each beam's DOFs node by node u, v, phi: a (rows, n_nodes) copy, no solve)."""
    rows = len(response.params)
    rotations = tuple(
        response.beam_state(i).reshape(rows, -1, 3)[..., 2] for i in range(len(models))
    )
    return Members(tuple(models), tuple(response.shapes_mm), rotations)


#: A note on an arm spring's beam field (fea/arm_beam.py): the file draws one arm of ``n``.
ARM_NOTE = (
    "arm 0 of the spring's identical arms (the others are it turned about the axis); its "
    "largest von_mises_MPa per load step is the beam model's peak_stress_MPa of that row"
)
#: ... and where the kind judges its stress on a finer model than the beam.
ARM_JUDGED_ELSEWHERE = (
    "the verdict does not read these beam stresses: it judges the plane-stress check's peak "
    "(plane_stress_peak_stress_MPa, the triangles) and, where it ran, the 3D check's"
)


def arm_field(
    members: Members | None,
    width_mm: float,
    judged_elsewhere: bool,
    fibres: dict[str, np.ndarray] | None = None,
) -> dict[str, Any] | None:
    """:func:`section_field` of an arm spring's one traced arm (:attr:`fea.arm_beam.
    ArmBeamResponse.members`), None where the response kept no members.

    Parameters
    ----------
    members : Members — one member, arm 0 (the others follow by symmetry).
    width_mm : float, mm — the plate thickness of the part as made (the solved ST, or the 3D
        check's corrected ST where it ran; the arm was solved at a
        nominal thickness and its torque rescaled: under a prescribed hub rotation its stresses
        do not depend on the plate thickness, :func:`fea.scaling.at_thickness`).
    judged_elsewhere : bool — the kind's verdict judges a plane-stress or 3D figure, not the
        beam's: said in the field's ``notes``.
    fibres : dict, optional — the arm's fibre stresses from statics
        (:attr:`fea.arm_beam.ArmBeamResponse.fibres`), which replace the elements' curvature
        figures so that each row's largest node value is the arm's ``peak_stress_MPa``.

    Returns
    -------
    dict
        the keys of :func:`section_field` (``width_mm`` (n_nodes - 1,) = ``width_mm``) and
        ``notes`` (tuple of str, the field data's texts).
    """
    if members is None or len(members.models) != 1:
        return None
    out = section_field(members.models[0], members.shapes_mm[0], members.rotations_rad[0])
    if fibres is not None:
        out.update(fibres)
    out["width_mm"] = np.full_like(out["width_mm"], float(width_mm))
    out["notes"] = (ARM_NOTE, ARM_JUDGED_ELSEWHERE) if judged_elsewhere else (ARM_NOTE,)
    return out
