"""Stability of the constrained-beam engine (pivots, leaf joints) against Euler loads computed here.

The same struts as tests/fea/test_beam_stability.py, but built from constraints of
:class:`fea.constrained_beams.ConstrainedBeams` (a clamp at the start, the end's axial shortening
prescribed, its transverse motion and rotation held): the perfect strut stays straight past its
Euler load, and every row past it must be flagged ``stable = False``. The clamped-clamped Euler
load is P = 4 pi^2 EI / L^2, reached at the shortening d = P L / EA (uniform compression);
shear lowers it by P / kGA (Engesser, 4e-3 here), inside the bracket tested.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.constrained_beams import ConstrainedBeams, kkt_negative_count
from flexopt.fea.materials import Material
from flexopt.fea.pivot import beam_pivot
from flexopt.geometry.flexures import Leaf
from flexopt.geometry.profile import BeamProfile

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
L, T, B = 50.0, 1.0, 8.0  # mm
EI = MAT.E_MPa * B * T**3 / 12.0  # N mm^2
EA = MAT.E_MPa * B * T  # N
P_CLAMPED = 4.0 * np.pi**2 * EI / L**2  # N
D_CLAMPED = P_CLAMPED * L / EA  # mm, the critical end shortening


def strut_system() -> ConstrainedBeams:
    model = BeamModel(
        BeamProfile([[0.0, 0.0], [L, 0.0]], [T, T], B), MAT, settings=BeamSettings(n_elements=10)
    )

    def constraints(shortening: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(6)
        d = np.zeros(6)
        row = system.clamp_start(C, 0, 0)
        for field, value in ((0, -shortening), (1, 0.0), (2, 0.0)):
            C[row, system.dof(0, -1, field)] = 1.0
            d[row] = value
            row += 1
        return C, d

    system = ConstrainedBeams([model], 0, constraints)
    return system


def test_a_strut_driven_past_its_euler_load_is_flagged_row_by_row():
    ratios = np.array([0.0, 0.5, 0.9, 0.98, 1.02, 1.1, 1.5, 2.0])
    res = strut_system().solve(ratios * D_CLAMPED)
    assert res.ok
    assert res.stable is not None
    # the straight branch: the end force is the uniform compression EA d / L
    force = -res.end_force(0)[:, 0]
    np.testing.assert_allclose(force, EA * ratios * D_CLAMPED / L, rtol=1e-6)
    np.testing.assert_array_equal(res.stable, ratios < 1.0)
    assert res.unstable


def test_the_kkt_inertia_matches_the_reduced_tangent():
    # independent check: the smallest eigenvalue of the tangent on the null space of C
    system = strut_system()
    for ratio in (0.5, 1.5):
        res = system.solve([0.0, ratio * D_CLAMPED])
        z = res.states[1]
        _, K = system._assemble(z)
        C, _ = system._constraint_arrays(ratio * D_CLAMPED)
        _, _, vt = np.linalg.svd(C)
        Z = vt[C.shape[0] :].T  # (N, N - m) basis of the null space of C
        H = K.toarray()
        lowest = np.linalg.eigvalsh(Z.T @ (0.5 * (H + H.T)) @ Z)[0]
        negative = kkt_negative_count(K, sp.csr_matrix(C))
        assert (lowest > 0) == (ratio < 1.0)
        assert (negative == C.shape[0]) == (ratio < 1.0)


@pytest.mark.parametrize("max_rad", [0.3, -0.3])
def test_a_leaf_pivot_turned_by_a_moment_is_stable(max_rad):
    leaf = Leaf(width_mm=5.0, length_mm=20.0, thickness_mm=0.8)
    res = beam_pivot(leaf, MAT, max_rad, steps=4, n_elements=20)
    assert res.converged.all() and res.stable.all()
