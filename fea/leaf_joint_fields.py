"""A leaf-spring joint's leaf as best.vtu draws it: its centreline per deflection with its
section and outer-fibre stresses (issue #26 item 5).

The joint's response keeps the leaf's model, solved shapes and node rotations
(:attr:`fea.leaf_joint.JointResponse.members`); the stresses are
:func:`fea.beam_fields.section_field` of them, the solver's own samples. The sliding structure
solves the leaf as drawn. The fixed structure solves a leaf of rest length l and scales its
shape by s / l per row (the loaded length s the rod sits at); the scaled leaf's curvature, and
the stress the response reports, are the solved ones divided by s / l, so the nodes' stresses
are divided by the same factor. Either way each row's largest node value is that row's
``peak_stress_MPa`` of the response.

Units: mm, MPa, rad.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from flexopt.fea.beam_fields import members_field

__all__ = ["critical_curve_vtu", "joint_vtu"]


def joint_vtu(response: Any, note: str = "") -> dict[str, Any]:
    """DesignResult keywords for best.vtu of one joint response (a
    :class:`fea.leaf_joint.JointResponse`): ``shapes_mm`` (n_rows, n_nodes, 2) mm, the loaded
    leaf per row as the response draws it, and ``beam_field`` (:func:`fea.beam_fields.
    members_field` of its one member, stresses per row divided by ``members_scale`` where the
    response has one), with ``note`` (which curve of the study it is) among its ``notes``.
    Empty when the response kept no members (a stand-in)."""
    members = getattr(response, "members", None)
    if members is None:
        return {}
    field = members_field(members)
    assert field is not None
    scale = getattr(response, "members_scale", None)
    if scale is not None:  # fixed structure: the leaf scaled by s / l (module docstring)
        per_row = np.asarray(scale, dtype=float)[:, None]
        for key in ("fibre_left_MPa", "fibre_right_MPa", "equivalent_MPa"):
            field[key] = field[key] / per_row
        field["notes"] = (
            "fixed structure: the leaf solved at rest length l scaled by s/l per load step; "
            "stresses divided by s/l, section as solved",
        )
    if note:
        field["notes"] = (*field.get("notes", ()), note)
    return {"shapes_mm": np.asarray(response.shapes_mm, dtype=float), "beam_field": field}


def critical_curve_vtu(curves: dict[str, tuple[Any, Any]]) -> dict[str, Any]:
    """:func:`joint_vtu` of the curve (``curves``: name -> (joint, JointResponse), the
    evaluation's structures and lengths) whose largest stress is the study's peak (the figure
    the verdict judges): best.vtu draws one leaf, the critical one, and says which."""
    peaks = {
        name: float(np.nanmax(r.peak_stress_MPa))
        for name, (_, r) in curves.items()
        if np.isfinite(r.peak_stress_MPa).any()
    }
    if not peaks:
        return {}
    name = max(peaks, key=peaks.__getitem__)
    note = f"the leaf of curve {name}, the largest stress of the study (stress_MPa_{name})"
    return joint_vtu(curves[name][1], note)
