"""One state of a plane-stress model as a field on its mesh's vertices: the von Mises stress and
the displacement of a solve, for best.vtu, stress_deformed.png and report.html's stress view
(issue #26 item 5).

The stress is the one the checks judge (:meth:`fea.plane_stress.PlaneStressModel.peak_stress`'s
nodal value): the von Mises Cauchy stress at every triangle's corners, averaged over the
triangles meeting at a vertex. Units: mm, MPa.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from flexopt.fea.plane_stress import PlaneStressModel

__all__ = ["mesh_arrays", "state_field"]


def mesh_arrays(model: PlaneStressModel) -> dict[str, np.ndarray]:
    """The model's drawn mesh: ``points_mm`` (n, 2) mm, its vertices; ``triangles`` (m, 3) int;
    ``stress_counted`` (n,) bool, the vertices of the elements the model's peak stress counts
    (the model's ``stress_ignore`` leaves out the elements touching clamps and drives, whose
    re-entrant corners are singular)."""
    t = model.skmesh.t.T
    counted = np.zeros(model.mesh.n_points, dtype=bool)
    counted[t[model.stress_mask].ravel()] = True
    return {
        "points_mm": np.asarray(model.mesh.points, dtype=float),
        "triangles": np.asarray(model.mesh.triangles, dtype=np.int64),
        "stress_counted": counted,
    }


def state_field(model: PlaneStressModel, u: np.ndarray, kinematics: str) -> dict[str, Any]:
    """The von Mises stress and displacement of the state ``u`` at the mesh's vertices.

    Parameters
    ----------
    model : the model that solved ``u``.
    u : (n_dofs,) float, mm — its full solution vector (scikit-fem DOF order).
    kinematics : "linear" or "nonlinear" — the solve's (the stress measure follows it).

    Returns
    -------
    dict
        ``von_mises_MPa`` (n,) MPa, vertex-averaged; ``displacement_mm`` (n, 2) mm, the
        vertices' displacement (points + displacement is the deformed part).
    """
    vc = model.von_mises(u, kinematics, model.corner_basis)  # (nel, 3), corners in t order
    t = model.skmesh.t.T
    n = model.mesh.n_points
    total = np.bincount(t.ravel(), weights=vc.ravel(), minlength=n)
    count = np.bincount(t.ravel(), minlength=n)
    # the vertices' DOFs: the P2 mid-side nodes are not points of the drawn mesh
    nodal = model.basis.nodal_dofs
    return {
        "von_mises_MPa": total / np.maximum(count, 1),
        "displacement_mm": np.column_stack([u[nodal[0]], u[nodal[1]]]),
    }
