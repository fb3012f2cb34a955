"""Exact sensitivities of a traced beam path (:class:`fea.beam.BeamModel`) to its design variables.

An elastic path is a sequence of equilibria ``R(q, p) = f`` (internal force ``R`` at the
generalised DOFs ``q``, design variables ``p``, applied end load ``f`` independent of ``p``, the
held and prescribed DOFs independent of ``p``). Differentiating one converged row along ``p``
with the path value (driven displacement or force) held::

    K_ff dq_f/dp = -dR_f/dp|_q              (free DOFs; dq = 0 on the held/prescribed ones)
    dr/dp        =  dR/dp|_q + K_{.f} dq_f/dp   (end force, moment: reactions of held DOFs)

``K`` is the tangent at the row: it is factorised once per row (banded Cholesky, the banded LU
where the row is unstable) and every variable costs one back-substitution. The explicit
derivative ``dR/dp|_q`` is analytic for the vertex thicknesses and the width (see
:func:`beam_sensitivities` and docs/sensitivities.md); for the centreline coordinates it is a
central difference of the residual at fixed ``q`` (no solve is differenced, "semi-analytic"): two
model builds per coordinate, and per row one batched evaluation of the elements each vertex moves
(:class:`_CoordinateBatch`).

The response differentiated is the compiled solve's: its rows carry the deformed node positions
(``BeamResponse.shapes_mm``), the end forces and the end rotation, not the section rotations, so
each converged row is rebuilt here (translations from the shapes, section rotations from the
discrete equilibrium at the Gauss points, see :func:`_initial_states`) and polished by a Newton
correction to equilibrium at round-off (the compiled assembly where it runs). That state is the
compiled solve's row to within its own tolerance (``rtol``; reported as ``force_mismatch``), and
the tangent there is the one factorised.

This module reads the reference-path internals of :class:`fea.beam.BeamModel` (the element
tables and the assembly of a numpy-kernel twin of the model); it lives next to it in ``fea``
for that reason, and the compiled path is untouched.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from flexopt.fea.beam import (
    BeamModel,
    BeamResponse,
    EndDrive,
    gauss_rule,
    reference_tables,
)
from flexopt.fea.errors import FeaError
from flexopt.geometry.profile import BeamProfile
from scipy.linalg import lu_factor, lu_solve
from scipy.linalg.lapack import dgbtrf, dgbtrs, dpbtrf, dpbtrs

__all__ = ["BeamSensitivity", "beam_sensitivities", "ks_aggregate"]

#: half-bandwidth of the beam's node-by-node numbering (3 nodes x 3 fields per element - 1)
_KD = 8

#: default Kreisselmeier-Steinhauser parameter, as rho = KS_RHO_YIELD / yield_MPa (1/MPa)
KS_RHO_YIELD = 100.0

#: the responses, as named in :class:`fea.beam.BeamResponse`
RESPONSES = (
    "displacement_mm",
    "force_N",
    "transverse_displacement_mm",
    "transverse_force_N",
    "moment_Nmm",
    "end_rotation_rad",
)


@dataclass(frozen=True)
class BeamSensitivity:
    """Derivatives of every row of a traced path with respect to the design variables.

    Shapes: ``n_rows`` rows of the response (row 0 undeformed), ``n_var`` variables, ``n_samp``
    stress sampling points (3 per element: both ends and the middle, as the solver samples).
    Rows that did not converge are NaN.

    Attributes
    ----------
    variables : (n_var,) str — "t[i]" (vertex thickness i, mm), "b" (width, mm), "x[i]", "y[i]"
        (centreline vertex i, mm) or the names of ``vertex_moves`` (a move's parameter), in the
        order of the last axis of every derivative.
    values : response name -> (n_rows,) — the responses at the polished states (units as in
        BeamResponse: mm, N, N mm, rad), plus "ks_stress_MPa" (the smooth peak stress, KS over
        the signed outer-fibre stresses of every sampling point, +- both) and "peak_stress_MPa"
        (their max, the solver's peak stress).
    derivatives : response name -> (n_rows, n_var) — d(value)/d(variable), unit of the value per mm.
        Names as ``values`` (the peak stress itself has no derivative: see "ks_stress_MPa").
    fibre_stress_MPa : (n_rows, n_samp, 2) — signed stress N/A + M c/I and N/A - M c/I of the two
        outer fibres at every sampling point; the solver's stress there, |N|/A + |M| c / I, is the
        larger magnitude (:attr:`stress_MPa`).
    d_fibre_stress : (n_rows, n_samp, 2, n_var) — their derivatives (MPa/mm): the stress at a fixed
        point, smooth where the solver's |.| form is not (where N or M changes sign).
    stress_s_mm : (n_samp,) — arc length of the sampling points.
    ks_rho_per_MPa : float — the KS parameter rho used (1/MPa).
    force_mismatch : float — max over rows of |driven force of the polished state - the solve's|,
        relative to the largest |driven force| of the path: the solve's own tolerance.
    counts : operation counts: "assemblies" (residual + tangent), "factorisations",
        "back_substitutions" (right-hand sides solved), "model_builds" (coordinate variables),
        "lu_rows" (rows whose tangent is not positive definite, solved by banded LU).
    """

    variables: tuple[str, ...]
    values: dict[str, np.ndarray]
    derivatives: dict[str, np.ndarray]
    fibre_stress_MPa: np.ndarray
    d_fibre_stress: np.ndarray
    stress_s_mm: np.ndarray
    ks_rho_per_MPa: float
    force_mismatch: float
    counts: dict = field(default_factory=dict)

    @property
    def stress_MPa(self) -> np.ndarray:
        """(n_rows, n_samp) MPa: |N|/A + |M| c / I at every sampling point, the solver's stress."""
        return np.abs(self.fibre_stress_MPa).max(axis=-1)


def ks_aggregate(sigma: np.ndarray, rho: float) -> tuple[float, np.ndarray]:
    """Kreisselmeier-Steinhauser aggregate ``1/rho ln sum exp(rho sigma_j)`` and its weights.

    ``sigma`` (n,) MPa, ``rho`` 1/MPa. Returns ``(KS, w)``: KS (MPa) with
    ``max <= KS <= max + ln(n) / rho`` and ``w = dKS/dsigma`` (n,), the softmax weights (sum 1).
    Computed shifted by the max, so it does not overflow.
    """
    m = float(np.max(sigma))
    e = np.exp(rho * (sigma - m))
    total = float(e.sum())
    return m + np.log(total) / rho, e / total


def _frame(drive: EndDrive) -> np.ndarray:
    """(2, 2) rows: the end node's generalised axes (direction, normal), as BeamModel uses."""
    d = np.asarray(drive.direction, dtype=float)
    d = d / np.hypot(*d)
    return np.array([d, [-d[1], d[0]]])


class _Factor:
    """The tangent with the held DOFs replaced by identity rows/columns, factorised once.

    ``ab`` is BeamModel's band storage (2 kl + ku + 1, n), ``A[i, j] = ab[kl + ku + i - j, j]``,
    kl = ku = 8; ``zero`` the (rows, cols) of ``ab`` in the held rows and columns and ``diag``
    the columns of the held diagonal (:func:`_held_entries`). Banded Cholesky (LAPACK dpbtrf)
    when positive definite (a stable row), banded LU (dgbtrf) otherwise.
    """

    def __init__(
        self, ab: np.ndarray, zero: tuple[np.ndarray, np.ndarray], diag: np.ndarray
    ) -> None:
        # the upper band and diagonal alone (what dpbtrf reads) copied and factorised in place:
        # the same numbers as from the whole band's copy, without it (why: ~2 x 40 rows per
        # Jacobian, the copies were half of the factorisation's cost)
        upper = zero[0] <= 2 * _KD
        chol = np.array(ab[_KD : 2 * _KD + 1], order="F")
        chol[zero[0][upper] - _KD, zero[1][upper]] = 0.0
        chol[_KD, diag] = 1.0
        self.chol, info = dpbtrf(chol, lower=0, overwrite_ab=1)
        self.lu = None
        if info != 0:  # not positive definite: an unstable row
            self.chol = None
            full = np.array(ab, order="F")
            full[zero] = 0.0
            full[2 * _KD, diag] = 1.0
            self.lu, self.piv, info = dgbtrf(full, _KD, _KD)
            if info != 0:
                raise FeaError(f"singular tangent at a converged row (dgbtrf info {info})")

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve for (n,) or (n, m) right-hand sides (held DOFs of ``rhs`` must be 0)."""
        b = rhs.reshape(rhs.shape[0], -1)
        if self.chol is not None:
            x, info = dpbtrs(self.chol, b, lower=0)
        else:
            x, info = dgbtrs(self.lu, _KD, _KD, b, self.piv)
        if info != 0:
            raise FeaError(f"banded back-substitution failed (info {info})")
        return x.reshape(rhs.shape)


def _held_entries(fixed: np.ndarray, n: int) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """Band-storage (rows, cols) of the held rows and columns, and the held diagonal's columns."""
    rows, cols = [], []
    for c in fixed:
        j = np.arange(max(0, c - _KD), min(n, c + _KD + 1))
        rows += [2 * _KD + c - j, 2 * _KD + j - c]  # row c: A[c, j]; column c: A[j, c]
        cols += [j, np.full(j.size, c)]
    return (np.concatenate(rows), np.concatenate(cols)), np.asarray(fixed)


def _reactions(ab: np.ndarray, dofs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(len(dofs), m): rows ``dofs`` of the full tangent (band storage as BeamModel's) times x."""
    n = ab.shape[1]
    out = np.empty((len(dofs), x.shape[1]))
    for k, c in enumerate(dofs):
        j = np.arange(max(0, c - _KD), min(n, c + _KD + 1))
        out[k] = ab[2 * _KD + c - j, j] @ x[j]
    return out


class _Twin:
    """The numpy reference path of a model (same mesh, same numbers) and what it needs here."""

    def __init__(self, model: BeamModel) -> None:
        self.model = (
            model
            if model.kernel == "numpy"
            else BeamModel(
                model.profile, model.material, model.start, replace(model.settings, kernel="numpy")
            )
        )
        #: the model whose assembly polishes the states: the compiled one where it runs (the same
        #: numbers as the reference path to round-off, and faster)
        self.solver = model
        m = self.model
        # arc length of the Gauss points (E, Q) and of the stress sampling points (E, 3)
        s_vert = m.mesh.p[0]
        h = np.diff(s_vert)
        self.s_samp = m.tables.s_samples
        # Gauss positions: the sampling points are at xi = 0, 1/2, 1 and the model's table
        # extrapolates Gauss values linearly to them (xi_s = g2s^T xi_g for the linear function
        # xi), so xi_g follows by least squares, exactly.
        xi_g = np.linalg.lstsq(m.tables.gauss_to_samples.T, np.array([0.0, 0.5, 1.0]), rcond=None)[
            0
        ]
        self.s_gauss = s_vert[:-1, None] + xi_g[None, :] * h[:, None]
        self.assemblies = 0
        #: mm: :func:`_polish`'s length scale (the profile's length, at least 1)
        self.length_scale = max(m.profile.length_mm, 1.0)

    def rotation_system(self) -> Callable[[np.ndarray], np.ndarray]:
        """Solver of the (2 E + 1) square system: the P2 interpolation of the nodal rotations at
        the Gauss points (rows 2 e + g) and the end rotation (last row); factorised once."""
        if not hasattr(self, "_rot"):
            m = self.model
            n_el, n_q = m.tables.theta0.shape
            a = np.zeros((n_el * n_q + 1, m.n_nodes))
            for e in range(n_el):
                a[e * n_q : (e + 1) * n_q, 2 * e : 2 * e + 3] = m.tables.N
            a[-1, -1] = 1.0
            lu = lu_factor(a)
            self._rot = lambda rhs: lu_solve(lu, rhs)
        return self._rot

    def hats(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Hat functions of the vertices in arc length at the Gauss points (E, Q, n_pts) and the
        sampling points (E, 3, n_pts), and the thickness at the Gauss points (E, Q) mm."""
        if not hasattr(self, "_hats"):
            prof = self.model.profile
            s_pts = prof.arc_length_mm
            eye = np.eye(prof.n_points)
            self._hats = (
                np.stack([np.interp(self.s_gauss, s_pts, e) for e in eye], -1),
                np.stack([np.interp(self.s_samp, s_pts, e) for e in eye], -1),
                np.interp(self.s_gauss, s_pts, prof.thickness_mm),
            )
        return self._hats

    def assemble(self, q: np.ndarray, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.assemblies += 1
        r, ab = self.solver.assemble(q, frame)
        return r, np.asfortranarray(ab)

    def physical(self, q: np.ndarray, frame: np.ndarray) -> np.ndarray:
        return self.model.physical(q, frame)

    def fields(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """Per Gauss point (E, Q): cos, sin of theta, 1 + Gamma1, Gamma2, kappa; (E, 3, 3) qe."""
        m = self.model
        qe = u[m.tables.edofs3]
        grad = m.tables.dN @ qe
        theta = m.tables.theta0 + qe[:, :, 2] @ m.tables.N.T
        c, s = np.cos(theta), np.sin(theta)
        x1 = m.tables.cos_theta0 + grad[..., 0]
        x2 = m.tables.sin_theta0 + grad[..., 1]
        return {
            "c": c,
            "s": s,
            "h1": c * x1 + s * x2,
            "g2": c * x2 - s * x1,
            "kappa": grad[..., 2],
            "qe": qe,
        }

    def section_terms(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed axial strain Gamma1 and bending term (EI / Z) kappa [MPa] at the sampling points,
        (E, 3) each: the stress there is ``E |Gamma1| + |(EI / Z) kappa|``."""
        m = self.model
        f = self.fields(u)
        g1s = (f["h1"] - 1.0) @ m.tables.gauss_to_samples
        kap = np.einsum("eqk,ek->eq", m.tables.dN_samples, f["qe"][:, :, 2])
        return g1s, m.tables.EI_samples / m.tables.section_modulus_samples * kap

    def fibre_terms(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The two terms of the fibre stresses at the sampling points and their derivatives.

        Returns ``a = E Gamma1`` and ``c = (EI / Z) kappa = E t kappa / 2`` (E, 3) MPa, and
        ``da``, ``dc`` (E, 3, 9) by the element's physical DOFs (MPa/mm, MPa/rad). The outer
        fibres carry ``a + c`` and ``a - c``; the solver's stress is ``|a| + |c|``, the larger of
        their magnitudes (BeamModel.peak_stress, the same formula).
        """
        m = self.model
        f = self.fields(u)
        E = m.material.E_MPa
        g2s = m.tables.gauss_to_samples  # (Q, 3)
        g1s, bend = self.section_terms(u)
        # dGamma1/dq at the Gauss points: (E, Q, node, field)
        dg1 = np.empty(m.tables.dN.shape + (3,))
        dg1[..., 0] = f["c"][..., None] * m.tables.dN
        dg1[..., 1] = f["s"][..., None] * m.tables.dN
        dg1[..., 2] = f["g2"][..., None] * m.tables.N[None]
        da = E * np.einsum("gm,egkf->emkf", g2s, dg1)  # (E, 3, node, field)
        dc = np.zeros_like(da)
        dc[..., 2] = (m.tables.EI_samples / m.tables.section_modulus_samples)[
            ..., None
        ] * m.tables.dN_samples
        n_el = g1s.shape[0]
        return E * g1s, bend, da.reshape(n_el, 3, 9), dc.reshape(n_el, 3, 9)


def _initial_states(
    twin: _Twin,
    shapes: np.ndarray,
    end_rotation: np.ndarray,
    end_force: np.ndarray,
    frame: np.ndarray,
) -> np.ndarray:
    """Generalised DOFs (R, n) of R rows from their node positions (R, n_nodes, 2) mm, end
    rotations (R,) rad and end forces (R, 2) N in the drive's frame (driven, transverse).

    The section rotations are not in the response; they follow from the discrete equilibrium.
    With no load along the span, the u, v equations make the stress resultant
    N e1 + Q e2 at every Gauss point equal to the end force (the interior node's equation of a
    P2 element with two Gauss points equates the two, the vertex equations chain them to the
    end). The deformed tangent there is x' = (1 + Gamma1) e1 + Gamma2 e2 with Gamma1 = N / EA,
    Gamma2 = Q / kGA, so theta = angle(x') - atan2(Gamma2, 1 + Gamma1) at the 2 E Gauss points
    (e1, e2 taken at angle(x'): an error of Gamma2^2), and with the end rotation these are
    2 E + 1 linear equations for the 2 E + 1 nodal rotations (:meth:`_Twin.rotation_system`).
    The estimate is at the solve's tolerance; :func:`_polish` then takes it to round-off.
    """
    m = twin.model
    u = shapes - m.reference_nodes_mm  # (R, n_nodes, 2), physical
    ue = u[:, 2 * np.arange(m.n_elements)[:, None] + np.arange(3)[None, :]]  # (R, E, 3, 2)
    d = m.tables.dN @ ue  # (R, E, Q, 2): u', v' at the Gauss points
    ang = np.arctan2(m.tables.sin_theta0 + d[..., 1], m.tables.cos_theta0 + d[..., 0])
    n_xy = (end_force @ frame)[:, None, None, :]  # the stress resultant, physical x, y (N)
    c, s = np.cos(ang), np.sin(ang)
    axial = (n_xy[..., 0] * c + n_xy[..., 1] * s) / m.tables.EA
    shear = (n_xy[..., 1] * c - n_xy[..., 0] * s) / m.tables.kGA
    phi_g = np.angle(np.exp(1j * (ang - np.arctan2(shear, 1.0 + axial) - m.tables.theta0)))
    phi_g = np.unwrap(phi_g.reshape(len(u), -1), axis=1)  # along s: the Gauss points in order
    phi_g += 2 * np.pi * np.round((end_rotation - phi_g[:, -1]) / (2 * np.pi))[:, None]
    phi = twin.rotation_system()(np.concatenate([phi_g, end_rotation[:, None]], axis=1).T).T
    q = np.zeros((len(u), m.n_dofs))
    q[:, 0::3], q[:, 1::3], q[:, 2::3] = u[..., 0], u[..., 1], phi
    q[:, -3:-1] = u[:, -1] @ frame.T  # generalised end translations (direction, normal)
    q[:, -1] = end_rotation
    return q


def _polish(
    twin: _Twin,
    q: np.ndarray,
    frame: np.ndarray,
    fixed: np.ndarray,
    held: tuple,
    f_ext: np.ndarray,
    counts: dict,
    max_iterations: int = 12,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, _Factor]:
    """Newton from ``q`` (held DOFs kept) to equilibrium at round-off; the final tangent factorised.

    Stops after a correction below 1e-6 of the length scale: from :func:`_initial_states`'s
    estimate (at the solve's tolerance, a first correction of ~1e-7 mm) quadratic convergence
    leaves ~C delta^2, round-off; a worse start (a load along the span, which the estimate does
    not know) only costs iterations. Returns (q, r, ab, factor) at the final state.
    """
    scale = twin.length_scale
    q = q.copy()
    for _ in range(max_iterations):
        r, ab = twin.assemble(q, frame)
        fac = _Factor(ab, *held)
        counts["factorisations"] += 1
        res = f_ext - r
        res[fixed] = 0.0
        delta = fac.solve(res)
        q += delta
        if np.abs(delta).max() <= 1e-6 * scale:
            r, ab = twin.assemble(q, frame)
            fac = _Factor(ab, *held)
            counts["factorisations"] += 1
            counts["lu_rows"] += fac.chol is None
            return q, r, ab, fac
    raise FeaError("the row state did not polish to equilibrium (is the row converged?)")


def _thickness_terms(twin: _Twin, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dR/dt_i at fixed physical DOFs ``u``: (E, 9, n_pts) element vectors, physical DOFs; and
    the explicit derivative of the bending term c = E t kappa / 2 of the fibre stresses,
    (E, 3, n_pts) MPa/mm (the axial term E Gamma1 does not depend on t at fixed DOFs).

    With t(s) = sum_i psi_i(s) t_i (psi_i the hat function of vertex i in arc length), A = b t,
    I = b t^3 / 12: d(EA)/dt_i = E b psi_i, d(kGA)/dt_i = k G b psi_i, d(EI)/dt_i = E b t^2/4 psi_i.
    The residual is linear in (EA, kGA, EI) at fixed strains, with the element scalars
    (N c - Q s, N s + Q c, M, N Gamma2 - Q h), N = EA Gamma1, Q = kGA Gamma2, M = EI kappa.
    """
    m = twin.model
    prof = m.profile
    psi_g, psi_s, t_g = twin.hats()
    b = prof.width_mm
    E, G = m.material.E_MPa, m.material.G_MPa
    f = twin.fields(u)
    g1, g2, c, s = f["h1"] - 1.0, f["g2"], f["c"], f["s"]
    z = np.zeros_like(g1)
    d_ea = np.stack([g1 * c, g1 * s, z, g1 * g2], -1)  # (E, Q, 4): d(scalars)/d(EA)
    d_kga = np.stack([-g2 * s, g2 * c, z, -g2 * f["h1"]], -1)
    d_ei = np.stack([z, z, f["kappa"], z], -1)
    drs = (
        d_ea[..., None] * (E * b)
        + d_kga[..., None] * (m.settings.shear_factor * G * b)
        + d_ei[..., None] * (E * b * t_g**2 / 4.0)[..., None, None]
    ) * psi_g[:, :, None, :]  # (E, Q, 4, n_pts)
    n_el, n_q = g1.shape
    # (E, 9, Q * 4) @ (E, Q * 4, n_pts): the element residual map applied to every column
    dre = np.matmul(m.residual_map.transpose(0, 2, 1), drs.reshape(n_el, n_q * 4, -1))
    kap_s = np.einsum("eqk,ek->eq", m.tables.dN_samples, f["qe"][:, :, 2])
    dbend = (0.5 * E * kap_s)[..., None] * psi_s  # (EI / Z) kappa = E t kappa / 2
    return dre, dbend


def _to_generalised_rows(dre_last: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """The last element's (9, m) physical residual derivative in generalised DOFs."""
    out = dre_last.copy()
    out[6:8] = frame @ dre_last[6:8]  # T^T r with T's end block = frame.T
    return out


def _segment_of_elements(model: BeamModel) -> np.ndarray:
    """(E,) int: the profile segment each element lies on."""
    s_vert = model.mesh.p[0]
    mid = 0.5 * (s_vert[:-1] + s_vert[1:])
    seg = np.searchsorted(model.profile.arc_length_mm, mid, side="right") - 1
    return np.clip(seg, 0, model.profile.n_points - 2)


def _centreline_at(
    profile: BeamProfile, s_pts: np.ndarray, theta_seg: np.ndarray, s: np.ndarray
) -> np.ndarray:
    """``fea.beam._centreline_points(profile, s)`` (m, 2) mm with the profile's arc lengths
    ``s_pts`` (n,) and segment start angles ``theta_seg`` (n - 1,) given (the same formulas: it
    recomputes both, twice, per call)."""
    seg = np.clip(np.searchsorted(s_pts, s, side="right") - 1, 0, profile.n_points - 2)
    sigma = s - s_pts[seg]
    th = theta_seg[seg]
    kap = profile.curvature_per_mm[seg]
    p0 = profile.points_mm[seg]
    straight = np.abs(kap) < 1e-14
    safe = np.where(straight, 1.0, kap)
    dx = np.where(straight, sigma * np.cos(th), (np.sin(th + kap * sigma) - np.sin(th)) / safe)
    dy = np.where(straight, sigma * np.sin(th), (np.cos(th) - np.cos(th + kap * sigma)) / safe)
    return p0 + np.stack([dx, dy], axis=-1)


def _perturbed_tables(
    model: BeamModel, profile: BeamProfile, els: np.ndarray, seg: np.ndarray
) -> dict | None:
    """The element tables :class:`BeamModel` ``(profile, model.material, model.start,
    model.settings)`` would have at its elements ``els`` (k,), without building that model
    (:class:`_CoordinateBatch` needs 4 of them per vertex move, and a full build with its
    assembly tables was most of a Jacobian's cost); None when ``profile`` does not mesh like
    ``model`` (another element count, or elements on other segments than ``seg`` (E,), the
    model's :func:`_segment_of_elements`).

    The same formulas in the same order as ``BeamModel.__init__`` on the full mesh (so the same
    numbers, bit for bit; tests/fea/test_beam_sensitivity.py checks it), ``np.linspace`` of each
    segment written out as its ``k (stop - start) / n + start``. Returns "dN" (k, Q, 3), "w",
    "theta0", "cos_theta0", "sin_theta0" (k, Q), "EA", "kGA", "EI" (k, Q), "dN_samples"
    (k, 3, 3), "ratio" (k, 3) EI / Z at the sampling points and "xref" (k, 3, 2) mm, the
    element's reference nodes.
    """
    settings, material = model.settings, model.material
    seg_len = profile.segment_lengths_mm
    chord_angle = np.diff(profile.points_mm, axis=0)
    # profile.segment_start_angles_rad(), with the lengths above
    theta_seg = (
        np.arctan2(chord_angle[:, 1], chord_angle[:, 0]) - profile.curvature_per_mm * seg_len / 2
    )
    s_pts = np.concatenate([[0.0], np.cumsum(seg_len)])  # profile.arc_length_mm
    n_seg = np.maximum(1, np.rint(settings.n_elements * seg_len / seg_len.sum())).astype(int)
    if int(n_seg.sum()) != model.n_elements:
        return None
    seg_of_el = np.repeat(np.arange(len(seg_len)), n_seg)
    k = np.arange(model.n_elements) - np.repeat(np.cumsum(n_seg) - n_seg, n_seg)
    step = (s_pts[1:] - s_pts[:-1]) / n_seg  # linspace's (stop - start) / div
    s_vert = np.concatenate([k * step[seg_of_el] + s_pts[seg_of_el], s_pts[-1:]])
    mid = 0.5 * (s_vert[:-1] + s_vert[1:])  # as _segment_of_elements
    if np.any(
        np.clip(np.searchsorted(s_pts, mid, side="right") - 1, 0, profile.n_points - 2) != seg
    ):
        return None
    # from here on every formula is element by element: evaluated at ``els`` only (the same
    # operations on the same numbers as over the whole mesh and then taking ``els``)
    h = np.diff(s_vert)[els]
    start = s_vert[els]  # s_vert[:-1][els]
    seg_el = seg_of_el[els]
    xg, wg = gauss_rule()
    _, dng = reference_tables(tuple(xg))
    dN = dng[None, :, :] / h[:, None, None]
    w = wg[None, :] * h[:, None]
    s_gauss = start[:, None] + xg[None, :] * h[:, None]
    kappa_seg = profile.curvature_per_mm
    theta0 = theta_seg[seg_el, None] + kappa_seg[seg_el, None] * (s_gauss - s_pts[seg_el, None])
    b = profile.width_mm
    t_g = np.interp(s_gauss, s_pts, profile.thickness_mm)
    E, G = material.E_MPa, material.G_MPa
    xs = np.array([0.0, 0.5, 1.0])
    _, dns = reference_tables(tuple(xs))
    dNs = dns[None, :, :] / h[:, None, None]
    s_samp = start[:, None] + xs[None, :] * h[:, None]
    t_s = np.interp(s_samp, s_pts, profile.thickness_mm)
    EI_s = E * b * t_s**3 / 12.0
    Z_s = b * t_s**2 / 6.0
    s_nodes = np.empty(2 * model.n_elements + 1)
    s_nodes[0::2] = s_vert
    s_nodes[1::2] = 0.5 * (s_vert[:-1] + s_vert[1:])
    nodes = 2 * els[:, None] + np.arange(3)
    return {
        "dN": dN,
        "w": w,
        "theta0": theta0,
        "cos_theta0": np.cos(theta0),
        "sin_theta0": np.sin(theta0),
        "EA": E * b * t_g,
        "kGA": settings.shear_factor * G * b * t_g,
        "EI": E * b * t_g**3 / 12.0,
        "dN_samples": dNs,
        "ratio": EI_s / Z_s,
        "xref": _centreline_at(profile, s_pts, theta_seg, s_nodes[nodes]),
    }


def _perturbed_tables_many(
    model: BeamModel,
    profile: BeamProfile,
    points: np.ndarray,
    els_of: list[np.ndarray],
    seg: np.ndarray,
) -> tuple[dict | None, int]:
    """:func:`_perturbed_tables` for P moved copies of ``profile`` at once: ``points`` (P, n, 2)
    mm their centreline vertices (thicknesses, width and curvatures are ``profile``'s),
    ``els_of`` (P,) the elements of each. Returns the tables of every copy's elements
    concatenated in that order (copy by copy, ``els_of[p]`` within), and -1; or ``(None, p)``
    with p the first copy that does not mesh like ``model``.

    Why: :class:`_CoordinateBatch` needs 4 copies per vertex move (40 on the constant-force
    beam), and one call per copy was ~0.4 ms of numpy overhead on arrays of a few dozen
    entries, 16 ms of a Jacobian. The same formulas in the same order, each element-wise
    operation on a leading copy axis (the same operations on the same numbers: bit for bit,
    tests/fea/test_beam_sensitivity.py checks it against :func:`_perturbed_tables`); the
    segment-length sums, ``np.interp`` and the mesh check copy by copy. Where a copy's element
    counts per segment are not the model's, each copy goes through :func:`_perturbed_tables`.
    """
    settings, material = model.settings, model.material
    kappa_seg = profile.curvature_per_mm
    n_copies = len(points)
    # profile.segment_lengths_mm of each copy
    chord = np.linalg.norm(np.diff(points, axis=1), axis=2)  # (P, n - 1)
    half = np.abs(kappa_seg) * chord / 2
    with np.errstate(invalid="ignore", divide="ignore"):
        seg_len = np.where(half > 1e-12, 2 * np.arcsin(half) / np.abs(kappa_seg), chord)
    chord_angle = np.diff(points, axis=1)
    theta_seg = np.arctan2(chord_angle[..., 1], chord_angle[..., 0]) - kappa_seg * seg_len / 2
    s_pts = np.concatenate([np.zeros((n_copies, 1)), np.cumsum(seg_len, axis=1)], axis=1)
    totals = np.array([row.sum() for row in seg_len])  # each copy's sum, as the 1-D one
    n_seg = np.maximum(1, np.rint(settings.n_elements * seg_len / totals[:, None])).astype(int)
    if np.any(n_seg != n_seg[:1]):  # copies mesh differently: one at a time, as the reference
        out: dict[str, list[np.ndarray]] = {}
        for p in range(n_copies):
            moved = BeamProfile(
                points[p], profile.thickness_mm, profile.width_mm, profile.curvature_per_mm
            )
            own = _perturbed_tables(model, moved, els_of[p], seg)
            if own is None:
                return None, p
            for key, value in own.items():
                out.setdefault(key, []).append(value)
        return {k: np.concatenate(v) for k, v in out.items()}, -1
    n_seg = n_seg[0]
    if int(n_seg.sum()) != model.n_elements:
        return None, 0
    seg_of_el = np.repeat(np.arange(seg_len.shape[1]), n_seg)
    k = np.arange(model.n_elements) - np.repeat(np.cumsum(n_seg) - n_seg, n_seg)
    step = (s_pts[:, 1:] - s_pts[:, :-1]) / n_seg
    s_vert = np.concatenate(
        [k * step[:, seg_of_el] + s_pts[:, seg_of_el], s_pts[:, -1:]], axis=1
    )  # (P, E + 1)
    mid = 0.5 * (s_vert[:, :-1] + s_vert[:, 1:])
    # searchsorted(s_pts[p], mid[p], "right") is the count of s_pts[p] <= mid (sorted)
    found = (s_pts[:, None, :] <= mid[:, :, None]).sum(axis=2) - 1
    bad = np.flatnonzero(np.any(np.clip(found, 0, profile.n_points - 2) != seg, axis=1))
    if bad.size:
        return None, int(bad[0])
    pv = np.concatenate([np.full(len(els), p) for p, els in enumerate(els_of)])  # copy
    els = np.concatenate(els_of)  # element
    h = np.diff(s_vert, axis=1)[pv, els]
    start = s_vert[pv, els]
    seg_el = seg_of_el[els]
    xg, wg = gauss_rule()
    _, dng = reference_tables(tuple(xg))
    dN = dng[None, :, :] / h[:, None, None]
    w = wg[None, :] * h[:, None]
    s_gauss = start[:, None] + xg[None, :] * h[:, None]
    s_seg = s_pts[pv, seg_el]
    theta0 = theta_seg[pv, seg_el][:, None] + kappa_seg[seg_el, None] * (s_gauss - s_seg[:, None])
    b = profile.width_mm
    E, G = material.E_MPa, material.G_MPa
    xs = np.array([0.0, 0.5, 1.0])
    _, dns = reference_tables(tuple(xs))
    dNs = dns[None, :, :] / h[:, None, None]
    s_samp = start[:, None] + xs[None, :] * h[:, None]
    t_g = np.empty_like(s_gauss)
    t_s = np.empty_like(s_samp)
    bounds = np.concatenate([[0], np.cumsum([len(e) for e in els_of])])
    for p in range(n_copies):
        sl = slice(bounds[p], bounds[p + 1])
        t_g[sl] = np.interp(s_gauss[sl], s_pts[p], profile.thickness_mm)
        t_s[sl] = np.interp(s_samp[sl], s_pts[p], profile.thickness_mm)
    EI_s = E * b * t_s**3 / 12.0
    Z_s = b * t_s**2 / 6.0
    s_nodes = np.empty((n_copies, 2 * model.n_elements + 1))
    s_nodes[:, 0::2] = s_vert
    s_nodes[:, 1::2] = 0.5 * (s_vert[:, :-1] + s_vert[:, 1:])
    s = s_nodes[pv[:, None], 2 * els[:, None] + np.arange(3)]  # (V, 3)
    # _centreline_at(copy, s_pts, theta_seg, s), its formulas on every copy's nodes at once
    at = np.clip((s_pts[pv][:, None, :] <= s[..., None]).sum(axis=2) - 1, 0, profile.n_points - 2)
    pv3 = np.broadcast_to(pv[:, None], at.shape)
    sigma = s - s_pts[pv3, at]
    th = theta_seg[pv3, at]
    kap = kappa_seg[at]
    p0 = points[pv3, at]
    straight = np.abs(kap) < 1e-14
    safe = np.where(straight, 1.0, kap)
    dx = np.where(straight, sigma * np.cos(th), (np.sin(th + kap * sigma) - np.sin(th)) / safe)
    dy = np.where(straight, sigma * np.sin(th), (np.cos(th) - np.cos(th + kap * sigma)) / safe)
    return {
        "dN": dN,
        "w": w,
        "theta0": theta0,
        "cos_theta0": np.cos(theta0),
        "sin_theta0": np.sin(theta0),
        "EA": E * b * t_g,
        "kGA": settings.shear_factor * G * b * t_g,
        "EI": E * b * t_g**3 / 12.0,
        "dN_samples": dNs,
        "ratio": EI_s / Z_s,
        "xref": p0 + np.stack([dx, dy], axis=-1),
    }, -1


#: central-difference stencils of dR/dx|_q: (offset in steps, weight per step) pairs. The residual
#: is far more curved in a vertex coordinate than the response (the axial term EA (l/l0 - 1) of
#: a stiff, short element): on paper 003's beam the second-order stencil at 1.3e-4 mm was 1.4e-4
#: off a row's dF/da (O(h^2), 3.6e-5 at 1e-3 mm); the fourth-order one is not, at no extra solve
_STENCILS = {
    2: ((1.0, 0.5), (-1.0, -0.5)),
    4: ((1.0, 8.0 / 12.0), (-1.0, -8.0 / 12.0), (2.0, -1.0 / 12.0), (-2.0, 1.0 / 12.0)),
}


class _CoordinateBatch:
    """The explicit derivatives by the centreline coordinates, at fixed DOFs, for all of them at
    once: central differences between models with one vertex moved by +-``step``.

    Moving vertex i changes only the elements of segments i - 1 and i (their lengths, reference
    angles and hat functions; the arc length further on shifts, which the element integrals do
    not see). Those elements of every perturbed model are gathered once into one batch of
    "virtual elements" (element, variable, sign), so each row needs one vectorised residual and
    stress evaluation over the batch instead of two full assemblies per coordinate.
    """

    def __init__(
        self,
        model: BeamModel,
        step: float,
        counts: dict,
        moves: np.ndarray | None = None,
        names: tuple[str, ...] | None = None,
        stencil: int = 4,
    ) -> None:
        prof = model.profile
        seg = _segment_of_elements(model)
        keys = ("dN", "w", "theta0", "cos_theta0", "sin_theta0", "EA", "kGA", "EI", "dN_samples")
        tables: dict[str, list[np.ndarray]] = {k: [] for k in (*keys, "ratio", "xref")}
        e_idx, col, sign = [], [], []
        if moves is None:  # every coordinate on its own: x[i], y[i]
            moves = np.zeros((2 * prof.n_points, prof.n_points, 2))
            for i in range(prof.n_points):
                moves[2 * i, i, 0] = moves[2 * i + 1, i, 1] = 1.0
            names = tuple(f"{axis}[{i}]" for i in range(prof.n_points) for axis in "xy")
        self.names: list[str] = list(names or ())
        copies, els_of = [], []
        for m, move in enumerate(moves):
            # the vertices the move carries, and the elements on the segments either side of them
            moved = np.flatnonzero(np.any(move != 0.0, axis=1))
            els = np.flatnonzero(np.isin(seg, moved - 1) | np.isin(seg, moved))
            # the parameter's step, so that the largest vertex moves by ``step`` mm
            h = step / max(float(np.abs(move).max()), 1e-300)
            for sgn, weight in _STENCILS[stencil]:
                copies.append(np.array(prof.points_mm) + sgn * h * move)
                els_of.append(els)
                counts["model_builds"] += 1
                e_idx.append(els)
                col.append(np.full(els.size, m))
                sign.append(np.full(els.size, weight / h))
        # every copy's tables in one pass (the copies in the order above)
        if copies:
            self.t, bad = _perturbed_tables_many(model, prof, np.array(copies), els_of, seg)
        else:
            self.t, bad = {k: np.zeros((0,)) for k in tables}, -1
        if self.t is None:
            raise FeaError(
                f"coordinate step {step:g} mm changes the mesh "
                f"(move {self.names[bad // len(_STENCILS[stencil])]}); "
                "pass a smaller coordinate_step_mm"
            )
        self.e = np.concatenate(e_idx)
        self.col = np.concatenate(col)
        self.weight = np.concatenate(sign)
        self.N = model.tables.N  # (Q, 3), the same reference table for every model
        self.g2s = model.tables.gauss_to_samples
        self.edofs = model.tables.edofs
        self.last = self.e == model.n_elements - 1
        self.n_el = model.n_elements
        self.E = model.material.E_MPa
        # explicit derivatives of the sampling points' geometry (the stress from statics,
        # fea/beam_statics.py): reference position (E, 3, 2, n_coord) mm, reference section
        # angle (E, 3, n_coord) rad and thickness (E, 3, n_coord) mm per unit of each variable
        nc = len(self.names)
        sidx = ((3 * self.e[:, None] + np.arange(3)) * nc + self.col[:, None]).ravel()
        size = 3 * self.n_el * nc
        w = self.weight[:, None]

        def gather(values: np.ndarray) -> np.ndarray:
            return np.bincount(sidx, (values * w).ravel(), size).reshape(self.n_el, 3, nc)

        self.d_xref = np.stack(
            [gather(self.t["xref"][..., 0]), gather(self.t["xref"][..., 1])], axis=2
        )
        self.d_theta0 = gather(self.t["theta0"] @ self.g2s)
        self.d_thickness = gather(2.0 * self.t["ratio"] / self.E)  # E t / 2 -> t

    def terms(
        self, u: np.ndarray, frame: np.ndarray, n: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """dR/dx (n, n_coord) in generalised DOFs, and the explicit derivatives of the fibre
        stress terms a = E Gamma1 and c = E t kappa / 2, (E, 3, n_coord) each, at physical
        DOFs ``u`` (n,)."""
        t, nc = self.t, len(self.names)
        qe = u[self.edofs[self.e].reshape(-1, 3, 3)]  # (V, node, field)
        grad = t["dN"] @ qe  # (V, Q, field)
        theta = t["theta0"] + qe[:, :, 2] @ self.N.T
        c, s = np.cos(theta), np.sin(theta)
        x1 = t["cos_theta0"] + grad[..., 0]
        x2 = t["sin_theta0"] + grad[..., 1]
        h1 = c * x1 + s * x2
        g2 = c * x2 - s * x1
        nf = t["EA"] * (h1 - 1.0)
        qf = t["kGA"] * g2
        wd = t["w"][..., None] * t["dN"]  # (V, Q, 3)
        wn = t["w"][..., None] * self.N[None]
        re = np.empty(qe.shape)
        re[..., 0] = np.einsum("vqk,vq->vk", wd, nf * c - qf * s)
        re[..., 1] = np.einsum("vqk,vq->vk", wd, nf * s + qf * c)
        re[..., 2] = np.einsum("vqk,vq->vk", wd, t["EI"] * grad[..., 2]) + np.einsum(
            "vqk,vq->vk", wn, nf * g2 - qf * h1
        )
        re[self.last, 2, :2] = re[self.last, 2, :2] @ frame.T  # end node: (direction, normal)
        w = self.weight
        idx = self.edofs[self.e] * nc + self.col[:, None]  # (V, 9)
        dR = np.bincount(idx.ravel(), (re.reshape(-1, 9) * w[:, None]).ravel(), n * nc)
        g1s = (h1 - 1.0) @ self.g2s  # (V, 3)
        kap = np.einsum("vmk,vk->vm", t["dN_samples"], qe[:, :, 2])
        sidx = ((3 * self.e[:, None] + np.arange(3)) * nc + self.col[:, None]).ravel()
        size = 3 * self.n_el * nc
        da = np.bincount(sidx, (self.E * g1s * w[:, None]).ravel(), size)
        dc = np.bincount(sidx, (t["ratio"] * kap * w[:, None]).ravel(), size)
        shape = (self.n_el, 3, nc)
        return dR.reshape(n, nc), da.reshape(shape), dc.reshape(shape)

    def terms_rows(
        self,
        U: np.ndarray,
        frame: np.ndarray,
        n: int,
        compiled: bool = False,
        out: tuple[np.ndarray, np.ndarray, np.ndarray, int] | None = None,
        fibres: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`terms` for K rows at once: ``U`` (K, n) physical DOFs; returns dR/dx
        (K, n, n_coord) and the fibre terms' explicit derivatives (K, E, 3, n_coord) each (each
        row's sums in the same order as :meth:`terms`). ``compiled``: by the numba kernel
        (fea/_sensitivity_kernels.py), the same formulas element by element; with ``out`` =
        (dR (K, n, m), da, dc (K, E, 3, m), col) C-contiguous, zero in columns col .. col +
        n_coord - 1, it adds into those columns and returns them (the same numbers; why: three
        arrays of ~1.3 MB fewer to fault in and copy per call). ``fibres`` False (compiled): the
        fibre terms are not formed (zero)."""
        t, nc = self.t, len(self.names)
        k_rows = len(U)
        if compiled:
            from flexopt.fea._sensitivity_kernels import coordinate_terms

            if out is None:
                dR = np.zeros((k_rows, n, nc))
                da = np.zeros((k_rows, self.n_el, 3, nc))
                dc = np.zeros((k_rows, self.n_el, 3, nc))
                col0 = 0
            else:
                dR, da, dc, col0 = out
            c = np.ascontiguousarray
            coordinate_terms(
                c(U),
                c(frame),
                c(self.edofs[self.e]),
                c(t["dN"]),
                c(t["theta0"]),
                c(t["cos_theta0"]),
                c(t["sin_theta0"]),
                c(t["EA"]),
                c(t["kGA"]),
                c(t["EI"]),
                c(t["w"]),
                c(self.N),
                c(self.g2s),
                c(t["dN_samples"]),
                c(t["ratio"]),
                float(self.E),
                c(self.weight),
                c(self.col + col0),
                c(self.e),
                c(self.last),
                dR,
                da,
                dc,
                fibres,
            )
            cols = slice(col0, col0 + nc)
            return dR[..., cols], da[..., cols], dc[..., cols]
        qe = U[:, self.edofs[self.e].reshape(-1, 3, 3)]  # (K, V, node, field)
        grad = t["dN"] @ qe  # (K, V, Q, field)
        theta = t["theta0"] + qe[..., 2] @ self.N.T
        c, s = np.cos(theta), np.sin(theta)
        x1 = t["cos_theta0"] + grad[..., 0]
        x2 = t["sin_theta0"] + grad[..., 1]
        h1 = c * x1 + s * x2
        g2 = c * x2 - s * x1
        nf = t["EA"] * (h1 - 1.0)
        qf = t["kGA"] * g2
        wd = t["w"][..., None] * t["dN"]  # (V, Q, 3)
        wn = t["w"][..., None] * self.N[None]
        re = np.empty(qe.shape)
        re[..., 0] = np.einsum("vqk,rvq->rvk", wd, nf * c - qf * s)
        re[..., 1] = np.einsum("vqk,rvq->rvk", wd, nf * s + qf * c)
        re[..., 2] = np.einsum("vqk,rvq->rvk", wd, t["EI"] * grad[..., 2]) + np.einsum(
            "vqk,rvq->rvk", wn, nf * g2 - qf * h1
        )
        last = re[:, self.last, 2, :2]  # end node: (direction, normal)
        re[:, self.last, 2, :2] = last @ frame.T
        w = self.weight
        idx = self.edofs[self.e] * nc + self.col[:, None]  # (V, 9)
        offset = (np.arange(k_rows) * (n * nc))[:, None, None]
        dR = np.bincount(
            (idx[None] + offset).ravel(),
            (re.reshape(k_rows, -1, 9) * w[:, None]).ravel(),
            k_rows * n * nc,
        )
        g1s = (h1 - 1.0) @ self.g2s  # (K, V, 3)
        kap = np.einsum("vmk,rvk->rvm", t["dN_samples"], qe[..., 2])
        sidx = ((3 * self.e[:, None] + np.arange(3)) * nc + self.col[:, None]).ravel()
        size = 3 * self.n_el * nc
        soff = (np.arange(k_rows) * size)[:, None]
        da = np.bincount(
            (sidx[None] + soff).ravel(), (self.E * g1s * w[:, None]).ravel(), k_rows * size
        )
        dc = np.bincount(
            (sidx[None] + soff).ravel(), (t["ratio"] * kap * w[:, None]).ravel(), k_rows * size
        )
        shape = (k_rows, self.n_el, 3, nc)
        return dR.reshape(k_rows, n, nc), da.reshape(shape), dc.reshape(shape)


def _statics_terms(
    twin: _Twin,
    u: np.ndarray,
    du: np.ndarray,
    r: np.ndarray,
    dr: np.ndarray,
    frame: np.ndarray,
    names: list[str],
    coords: _CoordinateBatch | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The fibre stress terms from statics and their derivatives (``stress="statics"``).

    ``a = N / (b t)`` and ``c = M / (b t^2 / 6)`` (E, 3) MPa at the sampling points, with ``M =
    M_end + (r_end - r) x F`` and ``N = F . (cos theta, sin theta)`` (fea/beam_statics.py), and
    ``da``, ``dc`` (E, 3, n_var) by the variables ``names``: through the state ``du`` (n, n_var)
    (physical), the end force and moment ``dr`` (n, n_var) (generalised: along the rows of
    ``frame``) and explicitly through the width, the vertex thicknesses and (``coords``) the
    reference geometry of the sampling points. ``u`` (n,) physical DOFs, ``r`` (n,) the forces.
    """
    m = twin.model
    tab = m.tables
    n_el = m.n_elements
    n_var = du.shape[1]
    node = 2 * np.arange(n_el)[:, None] + np.arange(3)[None, :]  # (E, 3)
    b = m.profile.width_mm
    Z = tab.section_modulus_samples  # (E, 3) b t^2 / 6
    t = np.sqrt(6.0 * Z / b)
    theta0 = tab.theta0 @ tab.gauss_to_samples  # (E, 3), exact: linear along an element
    pos = m.reference_nodes_mm + u.reshape(-1, 3)[:, :2]  # (n_nodes, 2)
    dpos = du.reshape(len(u) // 3, 3, n_var)[:, :2, :]  # (n_nodes, 2, n_var)
    ia, it, ir = len(u) - 3, len(u) - 2, len(u) - 1
    F = r[ia] * frame[0] + r[it] * frame[1]  # (2,) N in x, y
    dF = np.outer(frame[0], dr[ia]) + np.outer(frame[1], dr[it])  # (2, n_var)
    arm = pos[-1] - pos[node]  # (E, 3, 2)
    darm = dpos[-1][None, None] - dpos[node]  # (E, 3, 2, n_var)
    theta = theta0 + u.reshape(-1, 3)[node, 2]
    dtheta = du.reshape(len(u) // 3, 3, n_var)[node, 2, :]  # (E, 3, n_var)
    dt = np.zeros((n_el, 3, n_var))
    db = np.zeros(n_var)
    if coords is not None:
        cols = [names.index(k) for k in coords.names]
        darm[..., cols] += coords.d_xref[-1, 2][None, None] - coords.d_xref
        dtheta[..., cols] += coords.d_theta0
        dt[..., cols] += coords.d_thickness
    if "b" in names:
        db[names.index("b")] = 1.0
    thick = [k for k, v in enumerate(names) if v.startswith("t[")]
    if thick:
        dt[..., thick] += twin.hats()[1]  # t is linear between vertices: the hat functions
    M = r[ir] + arm[..., 0] * F[1] - arm[..., 1] * F[0]
    dM = (
        dr[ir][None, None]
        + darm[..., 0, :] * F[1]
        + arm[..., 0, None] * dF[1]
        - darm[..., 1, :] * F[0]
        - arm[..., 1, None] * dF[0]
    )
    cos, sin = np.cos(theta), np.sin(theta)
    N = F[0] * cos + F[1] * sin
    dN = (
        cos[..., None] * dF[0]
        + sin[..., None] * dF[1]
        + (-F[0] * sin + F[1] * cos)[..., None] * dtheta
    )
    a = N / (b * t)
    c = M / Z
    da = dN / (b * t)[..., None] - a[..., None] * (db / b + dt / t[..., None])
    dc = dM / Z[..., None] - c[..., None] * (db / b + 2.0 * dt / t[..., None])
    return a, c, da, dc


def _fields_rows(twin: _Twin, U: np.ndarray) -> dict[str, np.ndarray]:
    """:meth:`_Twin.fields` for K rows at once: ``U`` (K, n) physical DOFs; every array gains a
    leading row axis, (K, E, Q) and qe (K, E, 3, 3)."""
    tab = twin.model.tables
    qe = U[:, tab.edofs3]
    grad = tab.dN @ qe
    theta = tab.theta0 + qe[..., 2] @ tab.N.T
    c, s = np.cos(theta), np.sin(theta)
    x1 = tab.cos_theta0 + grad[..., 0]
    x2 = tab.sin_theta0 + grad[..., 1]
    return {
        "c": c,
        "s": s,
        "h1": c * x1 + s * x2,
        "g2": c * x2 - s * x1,
        "kappa": grad[..., 2],
        "qe": qe,
    }


def _thickness_terms_rows(twin: _Twin, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_thickness_terms` for K rows at once (``U`` (K, n)): (K, E, 9, n_pts) and
    (K, E, 3, n_pts), the same formulas with a leading row axis."""
    m = twin.model
    prof = m.profile
    psi_g, psi_s, t_g = twin.hats()
    b = prof.width_mm
    E, G = m.material.E_MPa, m.material.G_MPa
    f = _fields_rows(twin, U)
    g1, g2, c, s = f["h1"] - 1.0, f["g2"], f["c"], f["s"]
    z = np.zeros_like(g1)
    d_ea = np.stack([g1 * c, g1 * s, z, g1 * g2], -1)  # (K, E, Q, 4)
    d_kga = np.stack([-g2 * s, g2 * c, z, -g2 * f["h1"]], -1)
    d_ei = np.stack([z, z, f["kappa"], z], -1)
    drs = (
        d_ea[..., None] * (E * b)
        + d_kga[..., None] * (m.settings.shear_factor * G * b)
        + d_ei[..., None] * (E * b * t_g**2 / 4.0)[..., None, None]
    ) * psi_g[:, :, None, :]  # (K, E, Q, 4, n_pts)
    k, n_el, n_q = g1.shape
    dre = np.matmul(m.residual_map.transpose(0, 2, 1), drs.reshape(k, n_el, n_q * 4, -1))
    kap_s = np.einsum("eqk,rek->req", m.tables.dN_samples, f["qe"][..., 2])
    dbend = (0.5 * E * kap_s)[..., None] * psi_s
    return dre, dbend


def _thickness_columns(
    twin: _Twin, U: np.ndarray, frame: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The numpy reference of :func:`_compiled_thickness`: :func:`_thickness_terms_rows`
    assembled, dR/dt_i (K, n, n_pts) in generalised DOFs and the bending term's (K, E, 3,
    n_pts)."""
    k_rows, n = U.shape
    n_el = twin.model.n_elements
    dre, dc_t = _thickness_terms_rows(twin, U)
    npt = dre.shape[-1]
    dre[:, -1, 6:8] = frame @ dre[:, -1, 6:8]  # the last element's rows, generalised
    # element e's DOFs are 6 e .. 6 e + 8: its first six rows are its own, its last three
    # those of element e + 1's first node (the reference loop's sums in its order: the
    # next element's entry, then this one's)
    block = np.empty((k_rows, n, npt))
    block[:, : 6 * n_el].reshape(k_rows, n_el, 6, npt)[:] = dre[:, :, :6]
    block[:, 6 * n_el :] = dre[:, -1, 6:]
    block[:, 6 : 6 * n_el].reshape(k_rows, n_el - 1, 6, npt)[:, :, :3] += dre[:, :-1, 6:]
    return block, dc_t


def _compiled_thickness(
    twin: _Twin,
    U: np.ndarray,
    frame: np.ndarray,
    col: int,
    dR: np.ndarray,
    dc: np.ndarray,
    fibres: bool = True,
) -> None:
    """:func:`_thickness_terms_rows` compiled (fea/_sensitivity_kernels.py), assembled straight
    into columns ``col`` .. of ``dR`` (K, n, n_var) and ``dc`` (K, E, 3, n_var), as
    :func:`_batched_rows` assembles the reference's element vectors (``fibres`` False: ``dc``
    left alone)."""
    from flexopt.fea._sensitivity_kernels import thickness_terms

    m = twin.model
    tab = m.tables
    psi_g, psi_s, t_g = twin.hats()
    b = m.profile.width_mm
    E, G = m.material.E_MPa, m.material.G_MPa
    c = np.ascontiguousarray
    thickness_terms(
        c(U),
        c(tab.edofs3),
        c(tab.edofs),
        c(tab.dN),
        c(tab.N),
        c(tab.theta0),
        c(tab.cos_theta0),
        c(tab.sin_theta0),
        c(m.residual_map),
        c(psi_g),
        c(t_g),
        float(E * b),
        float(m.settings.shear_factor * G * b),
        c(tab.dN_samples),
        c(psi_s),
        float(E),
        c(frame),
        int(col),
        dR,
        dc,
        bool(fibres),
    )


def _statics_terms_rows(
    twin: _Twin,
    U: np.ndarray,
    dU: np.ndarray,
    R: np.ndarray,
    dr: np.ndarray,
    frame: np.ndarray,
    names: list[str],
    coords: _CoordinateBatch | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_statics_terms` for K rows at once: ``U`` (K, n), ``dU`` (K, n, n_var), ``R``
    (K, n), ``dr`` (K, n, n_var); returns a, c (K, E, 3) MPa and da, dc (K, E, 3, n_var), the
    same formulas with a leading row axis (the design's explicit parts computed once)."""
    m = twin.model
    tab = m.tables
    n_el = m.n_elements
    k_rows, n, n_var = dU.shape
    node = 2 * np.arange(n_el)[:, None] + np.arange(3)[None, :]  # (E, 3)
    b = m.profile.width_mm
    Z = tab.section_modulus_samples  # (E, 3) b t^2 / 6
    t = np.sqrt(6.0 * Z / b)
    theta0 = tab.theta0 @ tab.gauss_to_samples  # (E, 3)
    u3 = U.reshape(k_rows, -1, 3)
    du3 = dU.reshape(k_rows, n // 3, 3, n_var)
    pos = m.reference_nodes_mm + u3[..., :2]  # (K, n_nodes, 2)
    dpos = du3[:, :, :2, :]  # (K, n_nodes, 2, n_var)
    ia, it, ir = n - 3, n - 2, n - 1
    F = R[:, ia, None] * frame[0] + R[:, it, None] * frame[1]  # (K, 2) N in x, y
    dF = frame[0][None, :, None] * dr[:, None, ia] + frame[1][None, :, None] * dr[:, None, it]
    arm = pos[:, -1][:, None, None] - pos[:, node]  # (K, E, 3, 2)
    darm = dpos[:, -1][:, None, None] - dpos[:, node]  # (K, E, 3, 2, n_var)
    theta = theta0 + u3[:, node, 2]
    dtheta = du3[:, node, 2, :]  # (K, E, 3, n_var)
    dt = np.zeros((n_el, 3, n_var))
    db = np.zeros(n_var)
    if coords is not None:
        cols = [names.index(k) for k in coords.names]
        darm[..., cols] += coords.d_xref[-1, 2][None, None] - coords.d_xref
        dtheta[..., cols] += coords.d_theta0
        dt[..., cols] += coords.d_thickness
    if "b" in names:
        db[names.index("b")] = 1.0
    thick = [k for k, v in enumerate(names) if v.startswith("t[")]
    if thick:
        dt[..., thick] += twin.hats()[1]
    f0, f1 = F[:, 0, None, None], F[:, 1, None, None]  # (K, 1, 1)
    df0, df1 = dF[:, None, None, 0], dF[:, None, None, 1]  # (K, 1, 1, n_var)
    M = R[:, ir, None, None] + arm[..., 0] * f1 - arm[..., 1] * f0
    dM = (
        dr[:, ir][:, None, None]
        + darm[..., 0, :] * f1[..., None]
        + arm[..., 0, None] * df1
        - darm[..., 1, :] * f0[..., None]
        - arm[..., 1, None] * df0
    )
    cos, sin = np.cos(theta), np.sin(theta)
    N = f0 * cos + f1 * sin
    dN = cos[..., None] * df0 + sin[..., None] * df1 + (-f0 * sin + f1 * cos)[..., None] * dtheta
    a = N / (b * t)
    c = M / Z
    da = dN / (b * t)[..., None] - a[..., None] * (db / b + dt / t[..., None])
    dc = dM / Z[..., None] - c[..., None] * (db / b + 2.0 * dt / t[..., None])
    return a, c, da, dc


def _compiled_statics(
    twin: _Twin,
    U: np.ndarray,
    dU: np.ndarray,
    R: np.ndarray,
    dr: np.ndarray,
    frame: np.ndarray,
    names: list[str],
    coords: _CoordinateBatch | None,
    fibre: np.ndarray,
    d_fibre: np.ndarray,
    at: np.ndarray | None = None,
) -> None:
    """:func:`_statics_terms_rows` compiled (fea/_sensitivity_kernels.py), the fibre values
    written into rows ``at`` (K,) (default 0 .. K - 1) of ``fibre`` (n_rows, 3 E, 2) and
    ``d_fibre`` (n_rows, 3 E, 2, n_var): the design's explicit parts here (as the reference
    forms them), the rows' in the kernel."""
    from flexopt.fea._sensitivity_kernels import statics_fibres

    m = twin.model
    tab = m.tables
    n_el = m.n_elements
    n_var = dU.shape[2]
    b = m.profile.width_mm
    Z = tab.section_modulus_samples
    t = np.sqrt(6.0 * Z / b)
    theta0 = tab.theta0 @ tab.gauss_to_samples
    dt = np.zeros((n_el, 3, n_var))
    db = np.zeros(n_var)
    xarm = np.zeros((n_el, 3, 2, n_var))
    xtheta = np.zeros((n_el, 3, n_var))
    if coords is not None:
        cols = [names.index(k) for k in coords.names]
        xarm[..., cols] = coords.d_xref[-1, 2][None, None] - coords.d_xref
        xtheta[..., cols] = coords.d_theta0
        dt[..., cols] += coords.d_thickness
    if "b" in names:
        db[names.index("b")] = 1.0
    thick = [k for k, v in enumerate(names) if v.startswith("t[")]
    if thick:
        dt[..., thick] += twin.hats()[1]
    statics_fibres(
        U,
        np.ascontiguousarray(dU),
        R,
        np.ascontiguousarray(dr),
        np.ascontiguousarray(frame),
        np.ascontiguousarray(m.reference_nodes_mm),
        np.ascontiguousarray(theta0),
        float(b),
        np.ascontiguousarray(t),
        np.ascontiguousarray(Z),
        dt,
        db,
        xarm,
        xtheta,
        fibre,
        d_fibre,
        np.arange(len(U)) if at is None else np.asarray(at, dtype=np.int64),
    )


def _batched_rows(
    twin: _Twin,
    drive: EndDrive,
    response: BeamResponse,
    done: np.ndarray,
    starts: np.ndarray,
    frame: np.ndarray,
    fixed: np.ndarray,
    held: tuple,
    names: list[str],
    variables: tuple[str, ...],
    coords: _CoordinateBatch | None,
    stress: str,
    rho: float,
    counts: dict,
    values: dict,
    derivs: dict,
    fibre: np.ndarray,
    d_fibre: np.ndarray,
) -> float:
    """The rows ``done`` of :func:`beam_sensitivities` in one vectorised pass (fills
    ``values``, ``derivs``, ``fibre``, ``d_fibre`` in place; returns the largest |driven force
    of the polished state - the solve's|, N). Each row is polished and back-substituted with its
    own factorised tangent (n_var right-hand sides in one banded solve); the explicit
    derivatives, the reactions, the fibre stresses and the KS go over every row at once, the
    formulas of the reference loop with a leading row axis (why: ~30 rows x ~20 small numpy
    calls each were most of a Jacobian's time)."""
    m = twin.model
    prof = m.profile
    n = m.n_dofs
    n_el = m.n_elements
    n_var = len(names)
    ia, it, ir = n - 3, n - 2, n - 1
    is_disp = drive.control == "displacement"
    k_rows = len(done)
    if k_rows == 0:
        return 0.0
    Q = np.empty((k_rows, n))
    R = np.empty((k_rows, n))
    abs_ = np.empty((k_rows, 2 * _KD + _KD + 1, n))
    facs = []
    mismatch = 0.0
    for i, row in enumerate(done):
        f_ext = np.zeros(n)
        if not is_disp:
            f_ext[ia] = response.force_N[row]
        q0 = starts[row]
        if is_disp:
            q0[ia] = response.displacement_mm[row]
        for dof in fixed:  # held DOFs at their prescribed values
            if dof != ia:
                q0[dof] = 0.0
        Q[i], R[i], abs_[i], fac = _polish(twin, q0, frame, fixed, held, f_ext, counts)
        facs.append(fac)
        mismatch = max(mismatch, abs(R[i, ia] - response.force_N[row]))
    U = Q.copy()  # physical DOFs: the end node's translations out of the drive's frame
    U[:, n - 3 : n - 1] = Q[:, n - 3 : n - 1] @ frame

    #: the compiled kernels (fea/_sensitivity_kernels.py) where the model runs compiled code
    compiled = twin.solver.kernel == "numba"
    # explicit derivatives at fixed q (K, n, n_var), and of the fibre stress terms (K, E, 3, n_var)
    dR = np.zeros((k_rows, n, n_var))
    # the sampled stress's explicit terms: the stress from statics forms its own, and the
    # compiled kernels then leave these (lazily zeroed, so never faulted in) alone
    fibres = not (compiled and stress == "statics")
    da_x = np.zeros((k_rows, n_el, 3, n_var))
    dc_x = np.zeros((k_rows, n_el, 3, n_var))
    edofs = m.tables.edofs
    col = 0
    if "thickness" in variables and compiled:
        _compiled_thickness(twin, U, frame, col, dR, dc_x, fibres)
        col += prof.n_points
    elif "thickness" in variables:
        npt = prof.n_points
        dR[..., col : col + npt], dc_x[..., col : col + npt] = _thickness_columns(twin, U, frame)
        col += npt
    if "width" in variables:
        dR[:, :, col] = R / prof.width_mm  # every stiffness is proportional to b
        col += 1
    if coords is not None:
        nc = len(coords.names)
        if compiled:  # straight into their columns
            coords.terms_rows(U, frame, n, compiled, out=(dR, da_x, dc_x, col), fibres=fibres)
        else:
            dR[..., col : col + nc], da_x[..., col : col + nc], dc_x[..., col : col + nc] = (
                coords.terms_rows(U, frame, n, compiled)
            )
        col += nc

    # one back-substitution per variable with each row's factorised tangent; dR negated in
    # place as the right-hand sides (K x n x n_var: a copy is ~1 ms), its held rows kept first
    dR_held = dR[:, fixed]  # (K, len(fixed), n_var), for the reactions below
    rhs = np.negative(dR, out=dR)
    rhs[:, fixed] = 0.0
    if compiled:
        from flexopt.fea._sensitivity_kernels import pbtrs_many
    dq = rhs  # solved in place, row by row
    for i, fac in enumerate(facs):
        if compiled and fac.chol is not None:
            pbtrs_many(fac.chol, dq[i])
        else:
            dq[i] = fac.solve(rhs[i])
    counts["back_substitutions"] += n_var * k_rows
    # reactions of the held DOFs: rows ``fixed`` of each full tangent times dq
    dr = np.zeros((k_rows, n, n_var))
    for i, c in enumerate(fixed):
        j = np.arange(max(0, c - _KD), min(n, c + _KD + 1))
        dr[:, c] = dR_held[:, i] + np.einsum("kj,kjv->kv", abs_[:, 2 * _KD + c - j, j], dq[:, j])

    rows = done
    for key, vals, ders in (
        ("displacement_mm", Q[:, ia], dq[:, ia]),
        ("transverse_displacement_mm", Q[:, it], dq[:, it]),
        ("end_rotation_rad", Q[:, ir], dq[:, ir]),
        ("force_N", R[:, ia], dr[:, ia]),
        ("transverse_force_N", R[:, it], dr[:, it]),
        ("moment_Nmm", R[:, ir], dr[:, ir]),
    ):
        values[key][rows] = vals
        derivs[key][rows] = ders

    du = dq  # generalised -> physical end translations, in place (dq is not read again)
    du[:, n - 3 : n - 1] = np.einsum("ij,kiv->kjv", frame, dq[:, n - 3 : n - 1])
    if stress == "statics" and compiled:
        # straight into the rows of the returned arrays: no (K, 3 E, 2, n_var) array of its own
        # to fault in and copy (~4.5 MB on the constant-force beam)
        _compiled_statics(twin, U, du, R, dr, frame, names, coords, fibre, d_fibre, rows)
        fib, dfib = fibre[rows], None
    else:
        if stress == "statics":
            a, c, da, dc = _statics_terms_rows(twin, U, du, R, dr, frame, names, coords)
        else:  # the sampled stress: the implicit part through du, row by row
            a = np.empty((k_rows, n_el, 3))
            c = np.empty_like(a)
            da, dc = np.empty_like(da_x), np.empty_like(dc_x)
            for i in range(k_rows):
                a[i], c[i], da_du, dc_du = twin.fibre_terms(U[i])
                due = du[i][edofs]  # (E, 9, n_var)
                da[i] = np.matmul(da_du, due) + da_x[i]
                dc[i] = np.matmul(dc_du, due) + dc_x[i]
        fib = np.stack([a + c, a - c], -1).reshape(k_rows, -1, 2)
        dfib = np.stack([da + dc, da - dc], 3).reshape(k_rows, 3 * n_el, 2, n_var)
        fibre[rows] = fib
        d_fibre[rows] = dfib
    # KS over the four signed fibre values +-(a + c), +-(a - c) of every sampling point, per
    # row; its gradient as (w+ - w-) . d(fibre), the four values' weights folded onto the two
    # fibres (no (K, 12 E, n_var) array of the signed derivatives)
    signed = np.concatenate([fib, -fib], axis=2)  # (K, 3 E, 4)
    top = signed.reshape(k_rows, -1).max(axis=1)
    e = np.exp(rho * (signed - top[:, None, None]))
    total = e.reshape(k_rows, -1).sum(axis=1)
    w = e / total[:, None, None]
    values["ks_stress_MPa"][rows] = top + np.log(total) / rho
    values["peak_stress_MPa"][rows] = top
    if dfib is not None:
        derivs["ks_stress_MPa"][rows] = np.einsum("ksf,ksfv->kv", w[..., :2] - w[..., 2:], dfib)
    else:  # row by row on the returned array's rows (views, no copy of them)
        for i, row in enumerate(rows):
            derivs["ks_stress_MPa"][row] = np.einsum(
                "sf,sfv->v", w[i, :, :2] - w[i, :, 2:], d_fibre[row]
            )
    return mismatch


def beam_sensitivities(
    model: BeamModel,
    drive: EndDrive,
    response: BeamResponse,
    variables: tuple[str, ...] = ("thickness", "width"),
    ks_rho_per_MPa: float | None = None,
    coordinate_step_mm: float | None = None,
    vertex_moves: np.ndarray | None = None,
    move_names: tuple[str, ...] | None = None,
    rows: np.ndarray | None = None,
    coordinate_stencil: int = 4,
    stress: str = "sampled",
    batched: bool = True,
) -> BeamSensitivity:
    """Derivatives of every converged row of ``response`` (``model.solve(drive)``).

    Parameters
    ----------
    model, drive, response : the model, the drive and the path it traced (either kernel).
    variables : any of "thickness" (every vertex thickness t_i, mm), "width" (b, mm) and
        "coordinates" (x_i, y_i of every centreline vertex, mm; arcs keep their curvature) or
        "moves" (the directional derivatives along ``vertex_moves``).
    ks_rho_per_MPa : KS parameter rho (1/MPa) of the smooth peak stress; default
        ``KS_RHO_YIELD / yield_MPa`` (100 / yield): KS exceeds the max by at most
        ln(n_samp) / rho, about 5 % of the yield stress for 180 sampling points, and much less
        when one point dominates.
    coordinate_step_mm : the central-difference step of dR/dx|_q for "coordinates" (no solve is
        differenced, only the residual at fixed q); default 1e-6 of the beam length. For
        "moves", the largest vertex of a move moves by this much.
    vertex_moves : (n_moves, n_points, 2) mm per unit of the move's parameter — with "moves":
        each row is the velocity of every centreline vertex along one design parameter (e.g. a
        generator's variable that slides a vertex along a line); its derivative is d(.)/d(param),
        one variable per move instead of 2 per vertex, and only the elements next to the moved
        vertices are evaluated.
    move_names : (n_moves,) names of the moves (default "move[k]").
    coordinate_stencil : 4 (default) or 2: the order of the central difference of dR/dx|_q
        (4: four model builds per coordinate or move, 2: two; see :data:`_STENCILS`).
    rows : (k,) int, the rows to differentiate (default every converged row); the others are
        NaN. Each row costs two assemblies and factorisations and its back-substitutions, so a
        response that reads a few rows (samples of the curve, the rows near the peak stress)
        asks for those only.
    stress : "sampled" (default: the solver's stress, from the elements' curvature and axial
        strain, :meth:`BeamModel.peak_stress`) or "statics" (the section forces from the end
        load and the deformed centreline, :func:`fea.beam_statics.statics_stress`; only for a
        beam loaded at its ends): which fibre stresses, and their derivatives, are returned.
    batched : True (default): every row's explicit derivatives, reactions and stresses in one
        vectorised pass over the rows (:func:`_batched_rows`; each row still polished and
        back-substituted with its own factorised tangent); False: the reference loop, one row at
        a time (the same numbers to round-off; kept as the check of the batched pass).

    Returns
    -------
    BeamSensitivity
    """
    if coordinate_stencil not in _STENCILS:
        raise FeaError(f"coordinate_stencil = {coordinate_stencil!r}; use 2 or 4")
    if stress not in ("sampled", "statics"):
        raise FeaError(f"stress = {stress!r}; use 'sampled' or 'statics'")
    for v in variables:
        if v not in ("thickness", "width", "coordinates", "moves"):
            raise FeaError(f"variable {v!r}; use 'thickness', 'width', 'coordinates' or 'moves'")
    if ("coordinates" in variables) and ("moves" in variables):
        raise FeaError("'coordinates' and 'moves' both move the vertices: use one of them")
    twin = _Twin(model)
    m = twin.model
    prof = m.profile
    n = m.n_dofs
    frame = _frame(drive)
    fixed = m.fixed_dofs(drive)
    held = _held_entries(fixed, n)
    ia, it, ir = n - 3, n - 2, n - 1
    is_disp = drive.control == "displacement"
    rho = KS_RHO_YIELD / m.material.yield_MPa if ks_rho_per_MPa is None else ks_rho_per_MPa

    names: list[str] = []
    if "thickness" in variables:
        names += [f"t[{i}]" for i in range(prof.n_points)]
    if "width" in variables:
        names.append("b")
    counts = {
        "assemblies": 0,
        "factorisations": 0,
        "back_substitutions": 0,
        "model_builds": 0,
        "lu_rows": 0,
    }
    coords = None
    if "coordinates" in variables or "moves" in variables:
        step = 1e-6 * prof.length_mm if coordinate_step_mm is None else coordinate_step_mm
        if "moves" in variables:
            moves = np.asarray(vertex_moves, dtype=float)
            if moves.ndim != 3 or moves.shape[1:] != (prof.n_points, 2):
                raise FeaError(
                    f"vertex_moves must be (n_moves, {prof.n_points}, 2), got {moves.shape}"
                )
            labels = move_names or tuple(f"move[{k}]" for k in range(len(moves)))
            if len(labels) != len(moves):
                raise FeaError(f"{len(labels)} move_names for {len(moves)} vertex_moves")
            coords = _CoordinateBatch(m, step, counts, moves, tuple(labels), coordinate_stencil)
        else:
            coords = _CoordinateBatch(m, step, counts, stencil=coordinate_stencil)
        names += coords.names
    n_var = len(names)

    n_rows = len(response.force_N)
    n_el = m.n_elements
    nan = np.full(n_rows, np.nan)
    values = {k: nan.copy() for k in (*RESPONSES, "ks_stress_MPa", "peak_stress_MPa")}
    derivs = {k: np.full((n_rows, n_var), np.nan) for k in (*RESPONSES, "ks_stress_MPa")}
    fibre = np.full((n_rows, 3 * n_el, 2), np.nan)
    d_fibre = np.full((n_rows, 3 * n_el, 2, n_var), np.nan)
    edofs = m.tables.edofs  # (E, 9)
    mismatch = 0.0

    done = np.flatnonzero(response.converged)
    if rows is not None:
        done = np.intersect1d(done, np.asarray(rows, dtype=int))
    starts = np.zeros((n_rows, n))
    starts[done] = _initial_states(
        twin,
        response.shapes_mm[done],
        response.end_rotation_rad[done],
        np.stack([response.force_N[done], response.transverse_force_N[done]], axis=1),
        frame,
    )
    if batched:
        mismatch = _batched_rows(
            twin,
            drive,
            response,
            done,
            starts,
            frame,
            fixed,
            held,
            names,
            variables,
            coords,
            stress,
            rho,
            counts,
            values,
            derivs,
            fibre,
            d_fibre,
        )
    for row in done if not batched else ():
        f_ext = np.zeros(n)
        if not is_disp:
            f_ext[ia] = response.force_N[row]
        q0 = starts[row]
        if is_disp:
            q0[ia] = response.displacement_mm[row]
        for dof in fixed:  # held DOFs at their prescribed values
            if dof != ia:
                q0[dof] = 0.0
        q, r, ab, fac = _polish(twin, q0, frame, fixed, held, f_ext, counts)
        mismatch = max(mismatch, abs(r[ia] - response.force_N[row]))
        u = twin.physical(q, frame)

        # explicit derivatives at fixed q: residual (n, n_var), and the two terms of the fibre
        # stresses, axial a = E Gamma1 and bending c = E t kappa / 2 (E, 3, n_var)
        dR = np.zeros((n, n_var))
        da_x = np.zeros((n_el, 3, n_var))
        dc_x = np.zeros((n_el, 3, n_var))
        col = 0
        if "thickness" in variables:
            dre, dc_t = _thickness_terms(twin, u)
            dre[-1] = _to_generalised_rows(dre[-1], frame)
            npt = prof.n_points
            for k in range(9):  # distinct DOFs within one local index: plain fancy += is safe
                dR[edofs[:, k], col : col + npt] += dre[:, k]
            dc_x[..., col : col + npt] = dc_t
            col += npt
        if "width" in variables:
            dR[:, col] = r / prof.width_mm  # every stiffness is proportional to b
            col += 1
        if coords is not None:
            nc = len(coords.names)
            dR[:, col : col + nc], da_x[..., col : col + nc], dc_x[..., col : col + nc] = (
                coords.terms(u, frame, n)
            )
            col += nc

        # one back-substitution per variable with the row's factorised tangent
        rhs = -dR
        rhs[fixed] = 0.0
        dq = fac.solve(rhs)
        counts["back_substitutions"] += n_var
        # reactions of the held DOFs; a free DOF's force is the applied load (0 or prescribed)
        dr = np.zeros((n, n_var))
        dr[fixed] = dR[fixed] + _reactions(ab, fixed, dq)

        values["displacement_mm"][row] = q[ia]
        values["transverse_displacement_mm"][row] = q[it]
        values["end_rotation_rad"][row] = q[ir]
        values["force_N"][row] = r[ia]
        values["transverse_force_N"][row] = r[it]
        values["moment_Nmm"][row] = r[ir]
        derivs["displacement_mm"][row] = dq[ia]
        derivs["transverse_displacement_mm"][row] = dq[it]
        derivs["end_rotation_rad"][row] = dq[ir]
        derivs["force_N"][row] = dr[ia]
        derivs["transverse_force_N"][row] = dr[it]
        derivs["moment_Nmm"][row] = dr[ir]

        # fibre stresses: the implicit part through dq (generalised -> physical end translations)
        a, c, da_du, dc_du = twin.fibre_terms(u)  # (E, 3), (E, 3), (E, 3, 9), (E, 3, 9)
        du = dq.copy()
        du[n - 3 : n - 1] = frame.T @ dq[n - 3 : n - 1]
        due = du[edofs]  # (E, 9, n_var)
        da = np.matmul(da_du, due) + da_x
        dc = np.matmul(dc_du, due) + dc_x
        if stress == "statics":
            a, c, da, dc = _statics_terms(twin, u, du, r, dr, frame, names, coords)
        fibre[row] = np.stack([a + c, a - c], -1).reshape(-1, 2)
        d_fibre[row] = np.stack([da + dc, da - dc], 2).reshape(3 * n_el, 2, n_var)
        # KS over the four signed fibre values +-(a + c), +-(a - c) of every sampling point: its
        # max is the solver's |a| + |c|, and unlike |.| it is smooth where a term changes sign
        signed = np.concatenate([fibre[row], -fibre[row]], axis=1).ravel()
        d_signed = np.concatenate([d_fibre[row], -d_fibre[row]], axis=1).reshape(12 * n_el, n_var)
        ks, w = ks_aggregate(signed, rho)
        values["ks_stress_MPa"][row] = ks
        values["peak_stress_MPa"][row] = signed.max()
        derivs["ks_stress_MPa"][row] = w @ d_signed

    counts["assemblies"] += twin.assemblies
    f_scale = max(float(np.nanmax(np.abs(response.force_N))), 1e-300)
    return BeamSensitivity(
        variables=tuple(names),
        values=values,
        derivatives=derivs,
        fibre_stress_MPa=fibre,
        d_fibre_stress=d_fibre,
        stress_s_mm=twin.s_samp.ravel(),
        ks_rho_per_MPa=float(rho),
        force_mismatch=mismatch / f_scale,
        counts=counts,
    )
