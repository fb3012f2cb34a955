"""The constant-force generator's derivatives: how the beam profile moves with the 23 design
variables (issue 27, the chain rule from the study's variables to the beam's).

:func:`geometry.constant_force.beam_profile` maps a design vector ``x`` (23,) = (a1..a10,
t1..t10, T1, T6, B) to a :class:`~geometry.profile.BeamProfile`: centreline vertices S1, p1..p10,
S6 (12, 2), vertex thicknesses (12,) and the width. Every part of that map is linear in ``x``
(Eq. 13: ``p_j = S_i + a_j (S_{i+1} - S_i)`` with the reference points S1..S6 fixed by the PRB
layout, not by the design; the thicknesses and the width are copied), so its derivatives are
constants and exact:

* ``d p_j / d a_j = S_{i+1} - S_i`` (the interval p_j lies on, i = (j - 1) // 2 + 1), the only
  vertex that ``a_j`` moves; S1 and S6 do not move;
* ``d T1 = d t[0]``, ``d t_j = d t[j]``, ``d T6 = d t[11]`` of the vertex thicknesses;
* ``d b / d B = 1``.

Units: mm per unit of ``a_j`` (a fraction), 1 for the thicknesses and the width.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from flexopt.geometry.constant_force import (
    DESIGN_VARIABLE_NAMES,
    TABLE1,
    PRBParams,
    reference_points,
)

__all__ = ["ProfileDerivatives", "profile_derivatives"]


@dataclass(frozen=True)
class ProfileDerivatives:
    """The derivatives of :func:`~geometry.constant_force.beam_profile` by the design vector.

    Attributes
    ----------
    points : (23, 12, 2) mm per unit of the variable — d(vertex S1, p1..p10, S6)/d(x_k).
    thickness : (23, 12) — d(vertex thickness)/d(x_k) (mm/mm for t, T1, T6; 0 for a and B).
    width : (23,) — d(width)/d(x_k) (1 for B, else 0).
    names : (23,) the design variables (:data:`~geometry.constant_force.DESIGN_VARIABLE_NAMES`).
    """

    points: np.ndarray
    thickness: np.ndarray
    width: np.ndarray
    names: tuple[str, ...] = DESIGN_VARIABLE_NAMES

    @property
    def moving(self) -> np.ndarray:
        """(k,) int: the variables that move a vertex (a1..a10), in order."""
        return np.flatnonzero(np.any(self.points != 0.0, axis=(1, 2)))


def profile_derivatives(
    prb_params: PRBParams = TABLE1,
    end_flexures: Literal["centred", "outboard"] = "centred",
) -> ProfileDerivatives:
    """The constant derivatives of the beam profile by the 23 design variables (the map is
    linear, so they do not depend on the design; only the frame and the layout fix them)."""
    s = reference_points(prb_params, end_flexures=end_flexures)  # (6, 2) mm
    n = len(DESIGN_VARIABLE_NAMES)
    points = np.zeros((n, 12, 2))
    for j in range(10):  # a_{j+1} moves p_{j+1}, vertex j + 1, along its interval
        i = j // 2
        points[j, j + 1] = s[i + 1] - s[i]
    thickness = np.zeros((n, 12))
    for j in range(10):  # t_{j+1}: vertex j + 1
        thickness[10 + j, j + 1] = 1.0
    thickness[20, 0] = 1.0  # T1 at S1
    thickness[21, 11] = 1.0  # T6 at S6
    width = np.zeros(n)
    width[22] = 1.0
    return ProfileDerivatives(points, thickness, width)
