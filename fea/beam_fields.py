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

Units: mm, MPa, rad.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from flexopt.fea.beam import BeamModel, BeamResponse

__all__ = ["beam_field"]


def beam_field(model: BeamModel, response: BeamResponse) -> dict[str, Any] | None:
    """The section and the fibre stresses of ``response`` (traced by ``model``) per node.

    Returns
    -------
    dict or None (None when the response carries no rotations: a stand-in response)
        ``s_mm`` (n_nodes,) mm, the nodes' arc length; ``thickness_mm`` (n_nodes,) mm, the
        section thickness at the nodes (the profile's, as analysed); ``segment_thickness_mm``
        (n_nodes - 1,) mm, the profile's mean thickness over each segment between consecutive
        nodes (the thickness is linear between profile points, so its value at the segment's
        middle); ``width_mm`` (n_nodes - 1,) mm, the out-of-plane width per segment;
        ``fibre_left_MPa``, ``fibre_right_MPa`` and ``equivalent_MPa`` (n_rows, n_nodes) MPa,
        signed outer-fibre stresses and the equivalent stress (see the module docstring), NaN on
        rows that did not converge.
    """
    rotations = getattr(response, "rotations_rad", None)
    if rotations is None:
        return None
    profile = model.profile
    tab = model.tables
    shapes = np.asarray(response.shapes_mm, dtype=float)  # (R, N, 2)
    rotations = np.asarray(rotations, dtype=float)  # (R, N)
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
