"""Kt x the beam's stress over a pad fillet's flare (pipeline/studies/_constant_force_fillet.py)
against the Euler-Bernoulli closed form of a flared clamped-guided beam and the Roark fit, both
computed here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
from flexopt.fea.beam_statics import statics_stress
from flexopt.fea.materials import Material
from flexopt.geometry.mechanism import Attachment, BeamShape, as_made_beams
from flexopt.geometry.profile import BeamProfile
from flexopt.pipeline.studies._constant_force_fillet import root_stress_MPa
from scipy.integrate import quad

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
UP = np.array([0.0, 1.0])


def roark_kt(D: float, d: float, r: float) -> float:
    """Roark 7th ed. Table 17.1, square shoulder with fillet in bending, 0.1 <= h/r <= 2."""
    h = (D - d) / 2
    q = h / r
    assert 0.1 <= q <= 2
    c1 = 1.007 + 1.000 * math.sqrt(q) - 0.031 * q
    c2 = -0.270 - 2.404 * math.sqrt(q) + 0.749 * q
    c3 = 0.677 + 1.133 * math.sqrt(q) - 0.904 * q
    c4 = -0.414 + 0.271 * math.sqrt(q) + 0.186 * q
    x = 2 * h / D
    return c1 + c2 * x + c3 * x**2 + c4 * x**3


def test_root_stress_is_kt_times_the_toe_stress_of_the_flared_guided_beam():
    """A 40 mm beam, t = 1 mm, b = 5 mm, pads 4 mm thick, fillets r = 1 mm at both ends; clamped
    at s = 0, the end pushed across by delta with its rotation held and free along the beam. With
    EI(s) from the flared thickness (linear between the flare's points, as the model holds it):
    v'' = (M0 - F s) / EI, v(0) = v'(0) = v'(L) = 0, v(L) = delta give F = delta / (I2 - I1^2 /
    I0), M0 = F I1 / I0, Ik = int s^k / EI ds. Over a flare 6 |M| / (b t(s)^2) is largest at
    the toe (t grows 3x to the shoulder); the root stress is Kt x that."""
    L, t, b, r, pad, delta = 40.0, 1.0, 5.0, 1.0, 4.0, 0.02
    beam = BeamShape("b", np.array([[0.0, 0.0], [L, 0.0]]), np.array([t, t]))
    held = [Attachment("b", "start", "ground"), Attachment("b", "end", "ground")]
    made = as_made_beams([beam], (), held, pad, r)["b"]
    p, th = made.shape.points_mm, made.shape.thickness_mm
    assert made.start.root_mm == made.end.root_mm == r
    kt = roark_kt(t + 2 * 1.5, t, r)
    assert made.start.kt == pytest.approx(kt, rel=1e-12)
    settings = BeamSettings(n_elements=80, rtol=1e-11, shear_factor=1e4)
    model = BeamModel(BeamProfile(p, th, b), MAT, "clamped", settings)
    response = model.solve(EndDrive("displacement", tuple(UP), delta, 2, "fixed", "free"))
    assert response.ok
    st = statics_stress(model, response, UP)

    s_pts = p[:, 0]

    def ei(s: float) -> float:
        return MAT.E_MPa * b * float(np.interp(s, s_pts, th)) ** 3 / 12.0

    def integral(k: int) -> float:
        return sum(
            quad(lambda s: s**k / ei(s), a, c, epsabs=0, epsrel=1e-13)[0]
            for a, c in zip(s_pts[:-1], s_pts[1:], strict=True)
        )

    i0, i1, i2 = integral(0), integral(1), integral(2)
    F = delta / (i2 - i1**2 / i0)
    M0 = F * i1 / i0
    toe = 6.0 * abs(M0 - F * r) / (b * t**2)
    assert abs(M0 - F * L / 2) < 1e-9 * abs(M0)  # symmetric flares: M = 0 at mid-span
    got = root_stress_MPa(made, st)
    assert got[-1] == pytest.approx(kt * toe, rel=1e-4)
    assert got[0] == 0.0  # the undeformed row
    # the sharp beam (no junctions) has no root stress
    sharp = type(made)(made.shape, type(made.start)(), type(made.end)())
    assert np.all(root_stress_MPa(sharp, st) == 0.0)
