"""Exact derivatives of a ``sea_spring`` study's plane-stress responses by its design variables
(issue 27 item 1; :meth:`SeaSpringProblem.jacobian`, docs/sensitivities.md, "Plane stress").

The chain, at a design ``x`` (n_var,) of a spiral spring with ``thickness: solve``:

1. ``x`` -> the mesh's vertices ``X`` (n, 2) mm: the design is built and meshed as
   :func:`fea.spring_analysis.analyse_spring` does it, and the mesh is moved with the shape at
   fixed topology (:class:`fea.mesh_morph.SpiralMorph`); ``dX/dx`` is a central difference of
   that smooth map (the generator's shapely unions, closings and simplification are not
   differentiable; the morph is, and costs no FE);
2. ``X`` -> every row's torque, both directions, and the KS stress of the last rows
   (:func:`fea.plane_stress_sensitivity.node_sensitivities`: the adjoint on the converged path,
   one back-substitution per response and row with the row's tangent);
3. -> the study's figures: the secant stiffnesses ``K = T(±theta) / ±theta``, their mean, the
   solved thickness ``ST = ST_ref K_target / K_mean`` (a robustness sample's held ST: constant),
   the torque rows at ST (``T ST / ST_ref``), the mass (outline area times ST; the area's
   derivative is the meshed area's, the holes being rigid), the asymmetry, and the peak stress
   as ``KS2 = ln(sum_d exp(rho KS_d)) / rho`` over the directions' KS (``rho = 500 / yield``,
   :data:`fea.plane_stress_sensitivity.KS_RHO_YIELD`), an upper bound of the judged peak.

What is differentiated is the response of the **morphed** mesh, which equals the re-meshed
design's at ``x`` exactly and near it up to the discretisation error and the morph's outline
against the rebuilt polygon (um at the fillets): 0.03 % of a 3 % change of W4 at 4, 2, 1 and
0.5 mm edges (tests/pipeline/test_sea_spring_gradient.py). Both meshes have the hub's drive disc
and the pads' clamp discs on element edges (``ArmSpringGeometry.mesh_lines``), so the nodes held
are the same discs in both. The geometric margins' rows are central differences
of the generator's margins (distances between polygons, not smooth to better than the polygon's
resolution); the loaded-slot row (``deformed_slot_mm``) is the narrowest deformed distance of
the slot's node pairs (:func:`fea.spring_analysis.slot_pairs`, those within 3 mm unloaded or
loaded) over both directions, its derivative the closest pair's by the adjoint
(:func:`fea.plane_stress_sensitivity.gap_sensitivity`; a min: not differentiable where two
pairs tie). Not differentiated at all (the hook answers None): the serpentine topology (no
morph), ``thickness: search``, a design that cannot be built, meshed, morphed or solved.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace
from typing import Any

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.mesh import TriMesh, mesh_polygon
from flexopt.fea.mesh_morph import SpiralMorph
from flexopt.fea.plane_stress import Clamp, PlaneStressModel, PlaneStressSettings, Rotate
from flexopt.fea.plane_stress_sensitivity import gap_sensitivity, ks_rho, node_sensitivities
from flexopt.fea.sea_design import build_any, spring_margins
from flexopt.fea.spring_analysis import slot_pairs
from flexopt.geometry.arm_spring import ArmSpringParams
from flexopt.geometry.errors import GeometryError
from flexopt.optimise.design_jacobian import DesignJacobian

__all__ = ["morphed_responses", "sea_spring_jacobian", "spring_sensitivities"]

log = logging.getLogger(__name__)

#: the step of the geometric margins' central difference, as a fraction of each variable's range
MARGIN_STEP = 1e-4
#: the solver's tolerance for the derivatives: the adjoint assumes equilibrium, so the residual
#: left at each row is the derivative's error (analyse_spring's 1e-7 of the force: ~1e-7)
SETTINGS = PlaneStressSettings(rtol_residual=1e-10, atol_residual_N=1e-6)


class _Spring:
    """A design's mesh and model as :func:`fea.spring_analysis.analyse_spring` makes them."""

    def __init__(self, problem: Any, x: np.ndarray, settings: PlaneStressSettings) -> None:
        self.problem = problem
        self.p = problem.params(x)  # at the reference thickness (solve mode)
        if not isinstance(self.p, ArmSpringParams):
            raise FeaError("plane-stress sensitivities: only the spiral topology has a morph")
        self.geom = build_any(self.p, problem.frame)
        mesh = problem.study.mesh
        self.mesh = mesh_polygon(
            self.geom.fe_outline,
            mesh.max_edge_mm,
            refine=self.geom.mesh_regions(mesh.elements_through, mesh.max_edge_mm),
            lines=self.geom.mesh_lines(),
        )
        self.settings = settings

    def model(self, points: np.ndarray, steps: int, geom: Any = None) -> PlaneStressModel:
        """The model on the mesh with its vertices at ``points`` (n, 2) mm, the rigid regions
        of ``geom`` (default the design's own: the morphed design's pads have moved)."""
        g = self.geom if geom is None else geom
        return PlaneStressModel(
            TriMesh(points, self.mesh.triangles, self.mesh.boundary_edges),
            self.problem.material,
            self.p.thickness_mm,
            Clamp(g.pad_region),
            Rotate(g.hub_region, (0.0, 0.0), self.problem.theta, steps),
            self.settings,
            g.hub_region.union(g.pad_region).buffer(0.05),
        )


def _solve_both(model: PlaneStressModel, theta: float, both: bool) -> dict[str, Any]:
    """The nonlinear solves (kept rows) ccw and, with ``both``, cw, from the series predictor
    as analyse_spring starts them; {"ccw": response, "cw": response}."""
    steps = model.drive.steps
    model.solve("linear")  # factorises the linear stiffness the predictor solves with
    u_odd, u_even = model.series_predictor(theta / steps)
    out = {"ccw": model.solve("nonlinear", guess=u_odd + u_even, keep_states=True)}
    if both:
        model.drive = replace(model.drive, max_rad=-theta)
        out["cw"] = model.solve("nonlinear", guess=u_even - u_odd, keep_states=True)
        model.drive = replace(model.drive, max_rad=theta)
    for d, r in out.items():
        if not r.ok:
            raise FeaError(f"plane-stress sensitivities: the {d} solve failed: {r.message}")
    return out


def _area_gradient(points: np.ndarray, tri: np.ndarray) -> tuple[float, np.ndarray]:
    """The meshed area, mm^2, and its gradient (n, 2) mm by the vertices."""
    x = points[tri]
    d1, d2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    # d(area_e)/d(vertex) = 0.5 * (perpendicular of the opposite edge), ccw triangles
    grad = np.zeros_like(points)
    for a, (b, c) in enumerate(((1, 2), (2, 0), (0, 1))):
        e = x[:, c] - x[:, b]
        for i, col in enumerate((-e[:, 1], e[:, 0])):
            grad[:, i] += np.bincount(tri[:, a], weights=0.5 * col, minlength=points.shape[0])
    return float(0.5 * det.sum()), grad


def _figures(problem: Any, torques: dict[str, np.ndarray], ks: dict[str, float], area: float):
    """The study's figures from the torques (rows, N·mm at ST_ref), the KS stresses (MPa) and
    the outline area (mm^2): ST, the torque rows at ST (N m), K's, KS2, mass (g), asymmetry."""
    theta = problem.theta
    st_ref = problem.REFERENCE_THICKNESS_MM
    k = {"ccw": torques["ccw"][-1] * 1e-3 / theta}
    if "cw" in torques:
        k["cw"] = torques["cw"][-1] * 1e-3 / -theta
    k_mean = sum(k.values()) / len(k)
    st = (
        problem.held_st_mm if problem.held_st_mm is not None else st_ref * problem.k_target / k_mean
    )
    rho = ks_rho(problem.material.yield_MPa)
    vals = np.array(list(ks.values()))
    top = vals.max()
    ks2 = float(top + math.log(np.exp(rho * (vals - top)).sum()) / rho)
    mass = area * st * 1e-9 * problem.material.density_kg_m3 * 1e3
    asym = abs(k["ccw"] / k_mean - 1.0) * 100.0
    return {
        "ST_mm": st,
        "stiffness_Nm_per_rad": k_mean,
        **{f"stiffness_{d}_Nm_per_rad": v for d, v in k.items()},
        **{f"torque_{d}_Nm": t * 1e-3 * st / st_ref for d, t in torques.items()},
        "ks_MPa": ks2,
        "mass_g": mass,
        "asymmetry_percent": asym,
    }


def morphed_responses(
    problem: Any,
    x0: np.ndarray,
    x: np.ndarray,
    settings: PlaneStressSettings = SETTINGS,
    steps: int = 1,
) -> dict[str, Any]:
    """The study's figures (:func:`_figures`) of design ``x`` solved on the mesh of ``x0`` moved
    to ``x`` (:class:`fea.mesh_morph.SpiralMorph`), the hub turned in ``steps`` rows: the
    function :func:`spring_sensitivities` differentiates, for checking it by differences.
    Raises FeaError, GeometryError."""
    s = _Spring(problem, np.asarray(x0, dtype=float), settings)
    morph = SpiralMorph(s.mesh, s.p, problem.frame)
    p = problem.params(np.asarray(x, dtype=float))
    pts = morph.points(p)
    # the pads' washer footprints where the pads went: the morph moved them rigidly, so the
    # clamp holds the same vertices (checked: the derivatives are those of this model)
    model = s.model(pts, steps, build_any(p, problem.frame))
    same = s.model(s.mesh.points, steps)
    if not (
        np.array_equal(model.clamp_nodes, same.clamp_nodes)
        and np.array_equal(model.drive_nodes, same.drive_nodes)
        and np.array_equal(model.stress_mask, same.stress_mask)
    ):
        raise FeaError("the morphed mesh's clamp, drive or stress search is not the design's")
    solved = _solve_both(model, problem.theta, problem.study.target.directions == "both")
    # x0's pairs (the topology is fixed) and those that come within reach loaded at x
    pairs = slot_pairs(same, s.geom.fe_outline, _last_states(solved))
    gap, _ = _loaded_gap(model, solved, problem.theta, pairs)
    torques = {d: np.asarray(r.torque_Nmm[1:]) for d, r in solved.items()}
    rho = ks_rho(problem.material.yield_MPa)
    ks = {d: float(node_sensitivities(_drive(model, d, problem.theta), r, rho,
                                      rows=np.array([len(r.torque_Nmm) - 1])).ks_MPa[0])
          for d, r in solved.items()}  # fmt: skip
    model.drive = replace(model.drive, max_rad=problem.theta)
    area0, _ = _area_gradient(s.mesh.points, s.mesh.triangles)
    area, _ = _area_gradient(pts, s.mesh.triangles)
    out = _figures(problem, torques, ks, s.geom.area_mm2 + area - area0)
    out["peak_stress_MPa"] = max(float(r.peak_nodal_stress_MPa[-1]) for r in solved.values())
    out["deformed_slot_mm"] = gap
    return out


def _loaded_gap(
    model: PlaneStressModel, solved: dict[str, Any], theta: float, pairs: np.ndarray | None
) -> tuple[float, np.ndarray | None]:
    """The narrowest loaded slot over the solved directions' last rows, mm (1e3 where there is
    no slot, as :func:`optimise.sea_cost.spring_scores` caps it), and its derivative (n, 2) by
    the vertices (None without a slot): the closest pair's in the direction where it is
    narrowest (:func:`fea.plane_stress_sensitivity.gap_sensitivity`)."""
    if pairs is None:
        return 1e3, None
    best: tuple[float, np.ndarray | None] = (1e3, None)
    for d, r in solved.items():
        gap, grad = gap_sensitivity(_drive(model, d, theta), r, len(r.torque_Nmm) - 1, pairs)
        if gap < best[0]:
            best = (gap, grad)
    model.drive = replace(model.drive, max_rad=theta)
    return best


def _last_states(solved: dict[str, Any]) -> list[np.ndarray]:
    """The displacements (N,) mm at each solved direction's last row: the states whose slots
    :func:`fea.spring_analysis.slot_pairs` also watches (as analyse_spring's slot gaps do)."""
    return [np.asarray(r.row_dofs[-1]) for r in solved.values()]


def _drive(model: PlaneStressModel, direction: str, theta: float) -> PlaneStressModel:
    """The model with its drive turned the way ``direction`` was solved."""
    model.drive = replace(model.drive, max_rad=theta if direction == "ccw" else -theta)
    return model


def spring_sensitivities(
    problem: Any, x: np.ndarray, settings: PlaneStressSettings = SETTINGS, steps: int = 1
) -> dict[str, Any]:
    """The study's figures at ``x`` (n_var,) and their derivatives by ``x``: ``values`` (as
    :func:`morphed_responses` at ``x0 = x``) and ``gradients`` (each figure's (n_var,) or, for a
    row array (k,), (k, n_var) array, in its unit per unit of the variable), ``cpu_s``. The hub
    is turned in ``steps`` rows (1: the evaluation's; ``mesh.curve_steps``: the report's curve),
    every row's torque differentiated. Raises FeaError, GeometryError."""
    t0 = time.process_time()
    x = np.asarray(x, dtype=float)
    s = _Spring(problem, x, settings)
    morph = SpiralMorph(s.mesh, s.p, problem.frame)
    dX = morph.jacobian(problem.params, x)  # (n, 2, n_var)
    model = s.model(s.mesh.points, steps)
    t_solve = time.process_time()
    solved = _solve_both(model, problem.theta, problem.study.target.directions == "both")
    t_solve = time.process_time() - t_solve
    rho = ks_rho(problem.material.yield_MPa)
    torques, d_torques, ks, d_ks = {}, {}, {}, {}
    for d, r in solved.items():
        sens = node_sensitivities(_drive(model, d, problem.theta), r, rho)
        torques[d] = sens.torque_Nmm
        d_torques[d] = np.einsum("knj,njv->kv", sens.d_torque, dX)  # (rows, n_var) N·mm
        ks[d] = float(sens.ks_MPa[-1])
        d_ks[d] = np.einsum("nj,njv->v", sens.d_ks[-1], dX)
    model.drive = replace(model.drive, max_rad=problem.theta)
    gap, d_gap_X = 1e3, None
    if problem.min_gap is not None:
        pairs = slot_pairs(model, s.geom.fe_outline, _last_states(solved))
        gap, d_gap_X = _loaded_gap(model, solved, problem.theta, pairs)
    _, d_area = _area_gradient(s.mesh.points, s.mesh.triangles)
    area = s.geom.area_mm2
    d_area = np.einsum("nj,njv->v", d_area, dX)
    values = _figures(problem, torques, ks, area)
    # the chain of _figures, by hand: every figure is a closed form of the four inputs
    theta, st_ref, st = problem.theta, problem.REFERENCE_THICKNESS_MM, values["ST_mm"]
    sign = {"ccw": 1.0, "cw": -1.0}
    dk = {d: d_torques[d][-1] * 1e-3 / (sign[d] * theta) for d in torques}
    k = {d: values[f"stiffness_{d}_Nm_per_rad"] for d in torques}
    k_mean = values["stiffness_Nm_per_rad"]
    dk_mean = sum(dk.values()) / len(dk)
    dst = np.zeros(x.size) if problem.held_st_mm is not None else -st / k_mean * dk_mean
    vals = np.array([ks[d] for d in torques])
    w = np.exp(rho * (vals - vals.max()))
    w /= w.sum()
    d_ks2 = sum(wi * d_ks[d] for wi, d in zip(w, torques, strict=True))
    dens = 1e-9 * problem.material.density_kg_m3 * 1e3
    ratio = k["ccw"] / k_mean
    grads = {
        "ST_mm": dst,
        "stiffness_Nm_per_rad": dk_mean,
        **{f"stiffness_{d}_Nm_per_rad": dk[d] for d in torques},
        **{
            f"torque_{d}_Nm": (d_torques[d] * st + np.outer(torques[d], dst)) * 1e-3 / st_ref
            for d in torques
        },
        "ks_MPa": d_ks2,
        "mass_g": dens * (d_area * st + area * dst),
        "asymmetry_percent": math.copysign(100.0, ratio - 1.0)
        * (dk["ccw"] / k_mean - k["ccw"] * dk_mean / k_mean**2),
    }
    values["peak_stress_MPa"] = max(float(r.peak_nodal_stress_MPa[-1]) for r in solved.values())
    if problem.min_gap is not None:
        values["deformed_slot_mm"] = gap
        grads["deformed_slot_mm"] = (
            np.zeros(x.size) if d_gap_X is None else np.einsum("nj,njv->v", d_gap_X, dX)
        )
    return {
        "values": values,
        "gradients": grads,
        "rho_per_MPa": rho,
        "unmapped_vertices": int(morph.unmapped.size),
        "n_vertices": int(s.mesh.n_points),
        "solve_cpu_s": t_solve,
        "cpu_s": time.process_time() - t0,
    }


def sea_spring_jacobian(problem: Any, x: np.ndarray) -> DesignJacobian | None:
    """The :class:`optimise.DesignJacobian` of design ``x`` (n_var,) of a ``sea_spring``
    problem: ``f`` (2, n_var) — the peak stress's (as KS2, module docstring) and the mass's;
    ``g`` (n_con, n_var) in :attr:`constraint_names` order; None where the design or the study
    is not differentiated (module docstring)."""
    x = np.asarray(x, dtype=float)
    if not problem.solve_st or problem.topology != "spiral" or x.size == 0:
        return None
    try:
        sens = spring_sensitivities(problem, x)
    except (FeaError, GeometryError) as exc:
        log.debug("sea_spring jacobian: not differentiated (%s)", exc)
        return None
    v, dv = sens["values"], sens["gradients"]
    span = np.asarray(problem.space.upper, float) - np.asarray(problem.space.lower, float)
    rows, g0 = [], []
    geo_names = tuple(problem.geometry_constraints)
    for i in range(x.size):
        e = MARGIN_STEP * span[i]
        ends = []
        for s in (e, -e):
            xs = x.copy()
            xs[i] += s
            m = spring_margins(problem.params(xs), problem.frame)
            ends.append(np.array([-m[n] for n in geo_names]))
        rows.append((ends[0] - ends[1]) / (2 * e))
    m0 = spring_margins(problem.params(x), problem.frame)
    g0 = [-m0[n] for n in geo_names]
    G = [np.array(rows).T]
    lo, hi = problem.st_range
    g0 += [v["ST_mm"] - hi, lo - v["ST_mm"]]
    G += [dv["ST_mm"][None, :], -dv["ST_mm"][None, :]]
    not_diff: list[str] = []
    if problem.study.target.max_asymmetry_percent is not None:
        g0.append(v["asymmetry_percent"] - problem.study.target.max_asymmetry_percent)
        G.append(dv["asymmetry_percent"][None, :])
    if problem.min_gap is not None:
        g0.append(problem.min_gap - v["deformed_slot_mm"])
        G.append(-dv["deformed_slot_mm"][None, :])
    F = np.vstack([dv["ks_MPa"], dv["mass_g"]])
    info = {
        "ks_MPa": v["ks_MPa"],
        "peak_stress_MPa": v["peak_stress_MPa"],
        "rho_per_MPa": sens["rho_per_MPa"],
        "ST_mm": v["ST_mm"],
        "ST_gradient": dv["ST_mm"],
        "not_differentiated": not_diff,
        "margins": f"central differences of the generator's margins, step {MARGIN_STEP} of range",
        "unmapped_vertices": sens["unmapped_vertices"],
        "solve_cpu_s": sens["solve_cpu_s"],
        "cpu_s": sens["cpu_s"],
    }
    return DesignJacobian(
        x=x,
        f=F,
        g=np.vstack(G),
        values={"f": np.array([v["ks_MPa"], v["mass_g"]]), "g": np.array(g0)},
        info=info,
    )
