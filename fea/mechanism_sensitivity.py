"""Exact sensitivities of a traced mechanism path (issue 27, item 1: the constrained engine).

The direct method on the KKT system of :mod:`fea.mechanism`, row by row along the converged
path. At a converged row (drive value ``p`` fixed: a displacement / rotation drive is a
constraint row, a force / moment drive a dead load) the unknowns ``z`` (every beam's u, v mm and
phi rad per node, every body's U, V mm and theta rad) and the multipliers ``lam`` (constraint
forces, N and N·mm) satisfy, for design parameters ``x``::

    Res(z, lam, x) = r(z, x) - f(p) - G(z, x)^T lam = 0       (N,)   equilibrium
    g(z, x)        = A z + h(z, x) - b0 - p bp     = 0       (m,)   joints, supports, drive

Differentiating along ``x_i`` at fixed ``p``::

    [ H   -G^T ] [dz/dx_i  ]     [ dRes/dx_i |_(z, lam) ]
    [ G    0   ] [dlam/dx_i] = - [ dg/dx_i   |_z        ]      H = K - sum_j lam_j d2g_j/dz2

the solver's own Newton matrix (the constraint-Hessian term included), factorised once per row
and back-substituted once per variable. ``dRes/dx_i`` and ``dg/dx_i`` at fixed ``(z, lam)`` are
central differences (fourth order) of the residual between models of the mechanism built at
``x +- h e_i, x +- 2 h e_i``: no solve is differenced, so the step is free of the path's noise
("semi-analytic"; the same device as :mod:`fea.beam_sensitivity`'s coordinates). A design
parameter may move anything the model is built from: thicknesses and widths (the stiffness),
centreline points and body reference points (the mesh, the offsets of points on bodies, i.e.
the nonlinear constraint rows), so the map from a study's ``variables:`` to the mechanism is
differentiated with it (``mech_of``). ``z`` is the displacement from the reference, so "fixed z"
is the same state of every built model; the mesh (element count per beam segment) must not
change with the step (checked: :class:`fea.errors.FeaError`).

Every response read from a row is a smooth function ``y(z, lam, x)``; its total derivative is
the same stencil along ``(z + s dz, lam + s dlam, x + s e_i)``: the outputs (reactions are
``G^T lam`` at a part, the drive's reaction is its multiplier, motions read ``z``), each beam's
peak and root stresses (the max over the sampling points: the active point's derivative), the
node positions and body poses, and every beam's signed outer-fibre stresses ``+-(a + m)``,
``+-(a - m)`` (``a = E Gamma1``, ``m = M c / I``; smooth where ``|a| + |m|`` is not), which
the Kreisselmeier-Steinhauser aggregate over the path reads::

    KS = 1/rho ln sum_(rows, beams, points, 4) exp(rho sigma),  max <= KS <= max + ln(n) / rho

with ``rho = KS_RHO_YIELD / yield_MPa`` (100 / yield: 2.08 /MPa for PA12) by default.

Each converged row is taken from the solver's response and polished: translations from
``shapes_mm``, body poses from ``body_poses``, the section rotations from the deformed tangent,
then Newton at the row's drive value on the full KKT system (the reference assembly, scipy's
sparse LU) to round-off. ``force_mismatch`` says how far the polished row's outputs are from
the response's (the solve's tolerance). Units: mm, N, N·mm, rad, MPa.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from flexopt.fea.beam_sensitivity import KS_RHO_YIELD, ks_aggregate
from flexopt.fea.errors import FeaError
from flexopt.fea.mechanism import (
    LoadCase,
    Mechanism,
    MechanismResponse,
    MechanismSettings,
    MechOutput,
    sensitivity_model,
    solve_mechanism,
)
from scipy.sparse.linalg import splu

__all__ = ["MechanismSensitivity", "mechanism_sensitivities", "signed_fibre_stresses"]

#: central stencils by order: (offset in steps, weight per step)
_STENCILS = {
    2: ((1.0, 0.5), (-1.0, -0.5)),
    4: ((1.0, 8.0 / 12.0), (-1.0, -8.0 / 12.0), (2.0, -1.0 / 12.0), (-2.0, 1.0 / 12.0)),
}


@dataclass(frozen=True)
class MechanismSensitivity:
    """The derivatives of a traced path's rows by the design parameters.

    Shapes: ``rows`` the differentiated rows (``n_rows``), ``n_var`` parameters.

    Attributes
    ----------
    rows : (n_rows,) int — the response's rows differentiated (converged ones).
    drive : (n_rows,) float — their drive values (mm | rad | N | N·mm).
    values : dict name -> (n_rows, ...) — the polished rows' responses: each output's name
        ((n_rows,), its unit), "peak_stress_MPa" (n_rows, n_beams), "root_stress_MPa"
        (n_rows, n_beams, 2), "nodes_mm" (n_rows, n_nodes_all, 2) every beam's deformed nodes
        in beam order, "body_poses" (n_rows, n_bodies, 3) mm, mm, rad, "fibre_MPa"
        (n_rows, n_values) the signed outer-fibre stresses.
    derivatives : dict name -> (n_rows, ..., n_var) — d(value)/d(x_i), the value's unit per
        unit of x_i.
    dz : (n_rows, N, n_var) — d(state)/d(x) (mm, rad per unit).
    dlam : (n_rows, m, n_var) — d(multipliers)/d(x) (N, N·mm per unit).
    ks_MPa : float — the KS aggregate of every row's signed fibre stresses, MPa.
    d_ks : (n_var,) MPa per unit — its derivative.
    rho : float — the KS parameter, 1/MPa.
    force_mismatch : float — largest |output polished - output of the response| over the
        rows, relative to each output's largest |value| (the solve's tolerance).
    counts : dict — "factorisations" (polishing and final), "back_substitutions", "models".
    """

    rows: np.ndarray
    drive: np.ndarray
    values: dict[str, np.ndarray]
    derivatives: dict[str, np.ndarray]
    dz: np.ndarray
    dlam: np.ndarray
    ks_MPa: float
    d_ks: np.ndarray
    rho: float
    force_mismatch: float
    counts: dict[str, int] = field(default_factory=dict)


def signed_fibre_stresses(model: Any, q: np.ndarray) -> np.ndarray:
    """(4 n_samples,) MPa: ``a + m, -(a + m), a - m, -(a - m)`` at every stress sampling point
    of a beam (``model`` a :class:`fea.beam.BeamModel`, ``q`` (n_dofs,) its DOFs), with
    ``a = E Gamma1`` the axial and ``m = E I kappa / Z`` the bending stress; their max is the
    solver's ``|a| + |m|`` peak exactly, and each is smooth in the state and the design."""
    t = model.tables
    qe = q[t.edofs3]
    grad = t.dN @ qe
    theta = t.theta0 + qe[:, :, 2] @ t.NgT
    g1 = (
        np.cos(theta) * (t.cos_theta0 + grad[..., 0])
        + np.sin(theta) * (t.sin_theta0 + grad[..., 1])
        - 1.0
    )
    kappa = np.einsum("eqk,ek->eq", t.dN_samples, qe[:, :, 2])
    a = (model.material.E_MPa * (g1 @ t.gauss_to_samples)).ravel()
    m = (t.EI_samples * kappa / t.section_modulus_samples).ravel()
    return np.concatenate([a + m, -(a + m), a - m, m - a])


class _Built:
    """One model of the mechanism at a design: the solver's model and its output readers."""

    def __init__(self, mech: Mechanism, case: LoadCase, outputs, settings) -> None:
        self.model, self.readers, self.newton = sensitivity_model(mech, case, outputs, settings)
        if self.model.has_contact:
            raise FeaError(
                "sensitivities of a mechanism with stops or beam contact are not computed "
                "(the contact terms' pair search is not smooth)"
            )

    def kkt_residual(self, z: np.ndarray, lam: np.ndarray, p: float) -> np.ndarray:
        """(N + m,) ``[r - f - G^T lam, g]`` at the state (N, N·mm; mm, rad)."""
        md = self.model
        r, _ = md.assemble(z)
        g, G, _ = md.constraints(z, p)
        return np.concatenate([r - md.loads(p) - G.T @ lam, g])

    def fields(self, z: np.ndarray, lam: np.ndarray, p: float) -> dict[str, np.ndarray]:
        """Every response of the state (see :class:`MechanismSensitivity` ``values``)."""
        md = self.model
        peak = md.stresses(z)
        one = np.array([p], dtype=float)
        out = {
            name: np.asarray(fn(z[None], lam[None], z[None], peak[None], one), float)[0]
            for name, fn in self.readers.items()
        }
        out["peak_stress_MPa"] = peak
        out["root_stress_MPa"] = md.root_stresses(z)
        out["nodes_mm"] = np.concatenate([md.node_positions(z, i) for i in range(len(md.models))])
        out["thickness_at_nodes_mm"] = np.concatenate(
            [np.interp(m.s_nodes, m.profile.arc_length_mm, m.profile.thickness_mm)
             for m in md.models]
        )  # fmt: skip
        nb = len(md.mech.bodies)
        out["body_poses"] = np.column_stack(
            [md.body_ref + z[md.n_beam_dofs :].reshape(nb, 3)[:, :2],
             z[md.n_beam_dofs :].reshape(nb, 3)[:, 2]]
        ) if nb else np.zeros((0, 3))  # fmt: skip
        out["fibre_MPa"] = np.concatenate(
            [
                signed_fibre_stresses(m, z[md.offsets[i] : md.offsets[i + 1]])
                for i, m in enumerate(md.models)
            ]
        )
        return out


def _segments(model: Any) -> np.ndarray:
    """(E,) int: the profile segment each element of a beam model lies on."""
    s_vert = model.mesh.p[0]
    mid = 0.5 * (s_vert[:-1] + s_vert[1:])
    seg = np.searchsorted(model.profile.arc_length_mm, mid, side="right") - 1
    return np.clip(seg, 0, model.profile.n_points - 2)


def _same_mesh(a: _Built, b: _Built) -> bool:
    ma, mb = a.model, b.model
    if (ma.n, ma.m) != (mb.n, mb.m) or len(ma.models) != len(mb.models):
        return False
    return all(
        x.n_elements == y.n_elements and np.array_equal(_segments(x), _segments(y))
        for x, y in zip(ma.models, mb.models, strict=True)
    )


def _kkt(md: Any, z: np.ndarray, lam: np.ndarray, p: float):
    """The KKT matrix ``[[H, -G^T], [G, 0]]`` (csc) and the residual ``[Res, g]`` at a state."""
    r, K = md.assemble(z)
    g, G, ro = md.constraints(z, p)
    H = md.hessian(K, lam, ro)
    J = sp.bmat([[H, -G.T], [G, None]], format="csc")
    return J, np.concatenate([r - md.loads(p) - G.T @ lam, g])


def _guess(md: Any, response: MechanismResponse, k: int) -> np.ndarray:
    """(N,) a row's state from the response: node translations, body poses, and the section
    rotations from the deformed tangent against the reference one (the shear angle and the
    tangent's discretisation off: Newton removes them)."""
    z = np.zeros(md.n)
    for i, m in enumerate(md.models):
        x0 = m.reference_nodes_mm
        x1 = np.asarray(response.shapes_mm[i][k], dtype=float)
        q = np.zeros((m.n_nodes, 3))
        q[:, :2] = x1 - x0
        t0, t1 = np.gradient(x0, axis=0), np.gradient(x1, axis=0)
        phi = np.arctan2(t1[:, 1], t1[:, 0]) - np.arctan2(t0[:, 1], t0[:, 0])
        q[:, 2] = np.unwrap(phi)
        z[md.offsets[i] : md.offsets[i + 1]] = q.ravel()
    for b in range(len(md.mech.bodies)):
        base = md.n_beam_dofs + 3 * b
        z[base : base + 2] = response.body_poses[k, b, :2] - md.body_ref[b]
        z[base + 2] = response.body_poses[k, b, 2]
    return z


def _polish(built: _Built, z: np.ndarray, p: float, max_iterations: int = 30):
    """Newton at drive value ``p`` from ``z`` to round-off; returns ``(z, lam, lu, count)``
    with ``lu`` the factorised KKT matrix at the converged state.

    The solver's own Newton (compiled where it runs) takes the guess to its tolerance first;
    the corrections below (scipy's sparse LU of the same KKT matrix) then take it to round-off
    and give the factorisation: one on a row the solver's Newton converged."""
    md = built.model
    r, _ = md.assemble(z)
    _, G, _ = md.constraints(z, p)
    lam = np.linalg.lstsq(G.T.toarray(), r - md.loads(p), rcond=None)[0]
    ok, state, _, _, _ = built.newton(z, lam, p, None)
    if ok:
        z, lam = np.array(state.z, dtype=float), np.array(state.lam, dtype=float)
    count = 0
    for _ in range(max_iterations):
        J, res = _kkt(md, z, lam, p)
        lu = splu(J, permc_spec="MMD_AT_PLUS_A")
        count += 1
        step = lu.solve(-res)
        z, lam = z + step[: md.n], lam + step[md.n :]
        if np.abs(step[: md.n]).max() <= 1e-9 * md.length:
            # the matrix at the state this correction (< 1e-9 L) left: its change is of that
            # order relative, below what a derivative needs; the state is now at round-off
            # (Newton's quadratic convergence)
            return z, lam, lu, count
    raise FeaError(f"the row at drive {p:.6g} did not polish in {max_iterations} Newton steps")


def mechanism_sensitivities(
    mech_of: Callable[[np.ndarray], Mechanism],
    x: np.ndarray,
    case: LoadCase,
    outputs: Sequence[MechOutput] = (),
    settings: MechanismSettings | None = None,
    response: MechanismResponse | None = None,
    steps: np.ndarray | None = None,
    rows: Sequence[int] | None = None,
    rho: float | None = None,
    stencil: int = 4,
) -> MechanismSensitivity:
    """The derivatives of every converged row of ``mech_of(x)`` under ``case``.

    Parameters
    ----------
    mech_of : x (n_var,) -> Mechanism — the design's mechanism (a study's map from its
        variables; it must build the same mesh for the stencil's designs).
    x : (n_var,) — the design.
    case, outputs, settings : as :func:`fea.mechanism.solve_mechanism`.
    response : the path of ``mech_of(x)`` (solved here when None).
    steps : (n_var,) — the stencil's step per parameter, in its unit (default 1e-4 max(|x_i|, 1)):
        the residual at fixed state is smooth in the design, so the fourth-order stencil's
        truncation (~h^4) and round-off (~1e-16 |r| / h) are both far below 1e-9 there.
    rows : the rows to differentiate (default: every converged row).
    rho : KS parameter, 1/MPa (default ``KS_RHO_YIELD / yield_MPa``).
    stencil : 4 (default) or 2, the order of the central stencil in the design (4 or 2 built
        models per parameter).

    Raises
    ------
    FeaError — contact, a mesh that changes with the step, a row that does not polish.
    """
    x = np.asarray(x, dtype=float)
    n_var = x.size
    st = settings or MechanismSettings()
    base_mech = mech_of(x)
    if response is None:
        response = solve_mechanism(base_mech, case, outputs, st)
    base = _Built(base_mech, case, outputs, st)
    md = base.model
    nodes = tuple(np.asarray(n, float) for n in response.reference_nodes_mm)
    if len(nodes) != len(md.models) or any(
        n.shape != m.reference_nodes_mm.shape or not np.allclose(n, m.reference_nodes_mm)
        for n, m in zip(nodes, md.models, strict=False)
    ):
        raise FeaError(
            "the response is not the path of mech_of(x) (another mesh or shape: a path solved "
            "again with an imperfection?)"
        )
    h = 1e-4 * np.maximum(np.abs(x), 1.0) if steps is None else np.asarray(steps, float)
    built: list[list[tuple[float, float, _Built]]] = []
    for i in range(n_var):
        variants = []
        for off, w in _STENCILS[stencil]:
            xi = x.copy()
            xi[i] += off * h[i]
            b = _Built(mech_of(xi), case, outputs, st)
            if not _same_mesh(base, b):
                raise FeaError(
                    f"parameter {i}: the mesh changes within {2 * h[i]:.3g} of the design; "
                    "give the beams fixed element counts (elements:)"
                )
            variants.append((off * h[i], w / h[i], b))
        built.append(variants)
    conv = np.flatnonzero(np.asarray(response.converged, bool))
    rows_arr = conv if rows is None else np.asarray([r for r in rows if r in set(conv)], int)
    if rho is None:
        rho = KS_RHO_YIELD / float(base_mech.material.yield_MPa)
    n_rows = rows_arr.size
    dZ = np.zeros((n_rows, md.n, n_var))
    dL = np.zeros((n_rows, md.m, n_var))
    values: dict[str, list] = {}
    derivs: dict[str, list] = {}
    counts = {"factorisations": 0, "back_substitutions": 0, "models": 1 + stencil * n_var}
    mismatch = 0.0
    for j, k in enumerate(rows_arr):
        p = float(response.drive[k])
        z, lam, lu, count = _polish(base, _guess(md, response, int(k)), p)
        counts["factorisations"] += count
        rhs = np.zeros((md.n + md.m, n_var))
        for i in range(n_var):
            for _s, w, b in built[i]:
                rhs[:, i] += w * b.kkt_residual(z, lam, p)
        sol = lu.solve(-rhs)
        counts["back_substitutions"] += n_var
        dZ[j], dL[j] = sol[: md.n], sol[md.n :]
        f0 = base.fields(z, lam, p)
        for name, v in f0.items():
            values.setdefault(name, []).append(v)
            derivs.setdefault(name, []).append(np.zeros((*np.shape(v), n_var)))
        for i in range(n_var):
            acc: dict[str, np.ndarray] = {}
            for s, w, b in built[i]:
                fs = b.fields(z + s * dZ[j, :, i], lam + s * dL[j, :, i], p)
                for name, v in fs.items():
                    acc[name] = acc.get(name, 0.0) + w * v
            for name, v in acc.items():
                derivs[name][-1][..., i] = v
        for name in base.readers:
            ref = np.asarray(response.outputs[name], dtype=float)
            scale = max(float(np.nanmax(np.abs(ref))), 1e-300)
            mismatch = max(mismatch, abs(float(f0[name]) - float(ref[k])) / scale)
    vals = {n: np.array(v) for n, v in values.items()}
    ders = {n: np.array(v) for n, v in derivs.items()}
    if n_rows:
        ks, w = ks_aggregate(vals["fibre_MPa"].ravel(), rho)
        d_ks = np.einsum("j,jv->v", w, ders["fibre_MPa"].reshape(-1, n_var))
    else:
        ks, d_ks = float("nan"), np.full(n_var, np.nan)
    return MechanismSensitivity(
        rows=rows_arr,
        drive=np.asarray(response.drive, float)[rows_arr],
        values=vals,
        derivatives=ders,
        dz=dZ,
        dlam=dL,
        ks_MPa=float(ks),
        d_ks=d_ks,
        rho=float(rho),
        force_mismatch=float(mismatch),
        counts=counts,
    )
