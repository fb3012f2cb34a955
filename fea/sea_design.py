"""The SEA torsional spring's design physics (paper 004; the ``sea_spring`` study kind).

Moved here from ``pipeline/studies/sea_spring.py`` unchanged in its numbers:

- :func:`solve_for_stiffness` — the plate thickness ST at which the spring meets a stiffness
  target, from one plane-stress solve at a reference thickness (torque is proportional to ST);
  :func:`solve_spring` a design built, solved and so rescaled.
- :func:`taguchi_seed` — the screening stage's closed-form spring as a full design vector.
- :func:`correct_3d` — the 3D check of a design, its thickness correction loop and the
  converged peak stress (issue 15; docs/solid3d.md), with :func:`peak_convergence` and
  :func:`fine_geometry` (the outline the converged peak is meshed on and the part exported);
  :func:`detail_solves` the report's two extra 2D solves of a design.
- :class:`SpringTopology` — the two topologies (the paper's serpentine, the spiral arms)
  behind one interface: variables, bounds, parameters, building, margins, screening factors;
  :func:`screen_spring` one linear screening run.
- :data:`PUBLISHED_SPRINGS` and :func:`published_comparison` — paper 004's Table 1.

Units: mm, N, MPa inside; torques N m, stiffnesses N m/rad, angles rad unless named ``_deg``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Literal, Protocol

import numpy as np
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import Clamp, Rotate
from flexopt.fea.spring_analysis import MeshSize, SpringResponse, analyse_spring
from flexopt.geometry.arm_spring import (
    SPIRAL_BOUNDS,
    SPIRAL_LEVELS,
    SPIRAL_VARIABLES,
    ArmSpringParams,
    arm_clearances,
    build_arm_spring,
    spiral_level_values,
    spiral_params,
)
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import (
    TABLE6_LEVELS,
    SpringFrame,
    SpringGeometry,
    SpringParams,
    build_spring,
    clearances,
    ga_bounds,
    ga_variables,
    params_from_vector,
    taguchi_params,
)

__all__ = [
    "PUBLISHED_SPRINGS",
    "Solid3DOptions",
    "SpringTopology",
    "build_any",
    "correct_3d",
    "detail_solves",
    "fine_geometry",
    "peak_convergence",
    "published_comparison",
    "screen_spring",
    "spring_margins",
    "solve_for_stiffness",
    "solve_spring",
    "taguchi_seed",
    "worse_direction",
]

#: Paper 004, Table 1: published SEA springs (stiffness N m/rad, max torque N m, thickness mm,
#: diameter mm; None where the paper gives none). Row "t" is the template the paper follows.
_TABLE1 = (  # ref, stiffness N m/rad, max torque N m, thickness mm, diameter mm
    ("a [5]", 46, 15, 2.75, 60),
    ("b [8]", 219, 100, 15, 75),
    ("p [7]", 98, 7.7, 3, 85),
    ("t [11] (template)", 500, 60, 11, 90),
    ("s [12]", 110, 25, 12, 80),
    ("j [13]", 84, 15, 6, 125),
    ("ch [14]", 645, 45, None, None),
    ("h [15]", 9.7, 7.5, 10, 71),
    ("kh [16]", 172, 12, None, None),
)
PUBLISHED_SPRINGS: tuple[dict[str, Any], ...] = tuple(
    dict(zip(("ref", "stiffness_Nm_per_rad", "torque_Nm", "thickness_mm", "diameter_mm"), row,
             strict=True))
    for row in _TABLE1
)  # fmt: skip


def published_comparison() -> list[dict[str, Any]]:
    """:data:`PUBLISHED_SPRINGS` with the stiffness and the torque per full-disc volume
    (N m/rad/cm^3, N m/cm^3; None where the paper gives no thickness or diameter)."""
    rows = []
    for s in PUBLISHED_SPRINGS:
        t, d = s["thickness_mm"], s["diameter_mm"]
        vol = math.pi * (0.5 * d) ** 2 * t * 1e-3 if t and d else None  # cm^3, full disc
        rows.append(
            {
                **s,
                "stiffness_per_disc_volume_Nm_per_rad_cm3": (
                    s["stiffness_Nm_per_rad"] / vol if vol else None
                ),
                "torque_per_disc_volume_Nm_per_cm3": s["torque_Nm"] / vol if vol else None,
            }
        )
    return rows


# --------------------------------------------------------------------------------------------
# Both topologies behind one interface


@dataclass(frozen=True)
class SpringTopology:
    """The serpentine (:mod:`geometry.sea_spring`, paper 004 Tables 6 and 9; ``arcs`` arcs per
    set) or the spiral (:mod:`geometry.arm_spring`, one curved arm per set; ``root_fillet_mm``
    at its roots, mm) behind one interface."""

    name: Literal["serpentine", "spiral"] = "serpentine"
    arcs: int = 5
    root_fillet_mm: float = 1.5

    @property
    def variables(self) -> tuple[str, ...]:
        """Names of the design variables (ST included, in vector order; mm, deg, fractions)."""
        return SPIRAL_VARIABLES if self.name == "spiral" else ga_variables(self.arcs)

    @property
    def bounds(self) -> dict[str, tuple[float, float]]:
        """Default bounds by variable name (Table 9's, or the spiral's)."""
        return dict(SPIRAL_BOUNDS) if self.name == "spiral" else ga_bounds(self.arcs)

    @property
    def constraints(self) -> tuple[str, ...]:
        """The geometric margins of :func:`spring_margins` that are constraints, in order."""
        if self.name == "spiral":
            return ("envelope_mm", "thinnest_mm", "slot_mm", "hub_mm")
        return ("envelope_mm", "thinnest_mm", "slot_mm", "link_reach_mm")

    @property
    def levels(self) -> dict[str, tuple[float, ...]]:
        """The screening factors and their five levels: Table 6, or the spiral's."""
        return SPIRAL_LEVELS if self.name == "spiral" else TABLE6_LEVELS

    def params(
        self, x: np.ndarray, n_sets: int, frame: SpringFrame
    ) -> SpringParams | ArmSpringParams:
        """The spring parameters of a full (n_var,) vector (ST included) with ``n_sets`` sets."""
        x = np.asarray(x, dtype=float).ravel()
        if self.name == "spiral":
            values = dict(zip(SPIRAL_VARIABLES, map(float, x), strict=True))
            return spiral_params(values, n_sets, frame, self.root_fillet_mm)
        return params_from_vector(x, n_sets, self.arcs)

    def screen_params(
        self, values: dict[str, float], frame: SpringFrame
    ) -> SpringParams | ArmSpringParams:
        """The spring of one screening run: its factor values (:attr:`levels`' names)."""
        v = values
        if self.name == "spiral":
            return spiral_params(spiral_level_values(v), int(v["RP"]), frame, self.root_fillet_mm)
        return taguchi_params(v["RP"], v["RR"], v["ST"], v["A"], v["RT"], v["D"], frame)


def build_any(p: SpringParams | ArmSpringParams, frame: SpringFrame) -> SpringGeometry:
    """Build either topology (:func:`build_spring` or :func:`build_arm_spring`)."""
    if isinstance(p, ArmSpringParams):
        return build_arm_spring(p, frame)
    return build_spring(p, frame)


def spring_margins(p: SpringParams | ArmSpringParams, frame: SpringFrame) -> dict[str, float]:
    """Signed geometric margins (mm, >= 0 where met) of either topology."""
    if isinstance(p, ArmSpringParams):
        return arm_clearances(p, frame)
    return clearances(p, frame)


def screen_spring(
    values: dict[str, float], topology: SpringTopology, frame: SpringFrame, material: Material,
    mesh: MeshSize,
) -> tuple[float, float, str]:  # fmt: skip
    """One screening run: the linear plane-stress stiffness (N m/rad) and peak von Mises stress
    per radian of hub rotation (MPa/rad) of the spring of ``values`` (factor values), and why
    it cannot be built or solved ("" when it can; nan and nan then)."""
    try:
        p = topology.screen_params(values, frame)
        geom = build_any(p, frame)
        theta = math.radians(1.0)  # linear: any angle; 1 degree keeps the numbers readable
        r = analyse_spring(geom, material, theta, mesh, nonlinear=False)
    except (GeometryError, FeaError) as exc:
        return math.nan, math.nan, str(exc)
    return r.linear_stiffness_Nm_per_rad, r.linear_peak_stress_MPa / theta, ""


# --------------------------------------------------------------------------------------------
# The thickness from the stiffness target, the screening seed


def solve_for_stiffness(
    thickness_mm: float,
    stiffness_Nm_per_rad: float,
    target_Nm_per_rad: float,
    held_thickness_mm: float | None = None,
) -> tuple[float, float]:
    """The plate thickness at which a plane-stress spring has the target stiffness.

    Under displacement control the plane-stress displacement field does not depend on the
    thickness and every torque is proportional to it, so the (secant) stiffness
    ``stiffness_Nm_per_rad`` solved at ``thickness_mm`` scales exactly: the thickness is
    ``thickness_mm * target / stiffness``. ``held_thickness_mm`` (a robustness sample holding
    its nominal design's thickness) replaces the target's.

    Returns
    -------
    (scale, thickness_mm) — the factor on the torques (:meth:`SpringResponse.scaled`) and the
    thickness, mm.
    """
    scale = target_Nm_per_rad / stiffness_Nm_per_rad
    if held_thickness_mm is not None:
        scale = held_thickness_mm / thickness_mm
    return scale, thickness_mm * scale


def solve_spring(
    params_at: Callable[[float | None], SpringParams | ArmSpringParams],
    frame: SpringFrame,
    material: Material,
    theta_rad: float,
    mesh: MeshSize,
    steps: int,
    keep_model: bool,
    both_directions: bool,
    gaps: bool,
    target_Nm_per_rad: float | None,
    held_st_mm: float | None = None,
) -> tuple[SpringParams | ArmSpringParams, SpringGeometry, SpringResponse, float]:
    """Build and analyse a design: the hub turned to ``theta_rad`` in ``steps`` (both ways
    with ``both_directions``; ``gaps``: measure the loaded slots), the model kept with
    ``keep_model`` (a stress map reads it).

    ``params_at(st_mm)`` gives the design's parameters at a plate thickness (None: its own,
    or the reference thickness when ST is solved). With ``target_Nm_per_rad`` (N m/rad) ST is
    solved: the analysis is made at the reference thickness and ST is the thickness at which
    the (mean) secant stiffness is the target, or ``held_st_mm`` when given
    (:func:`solve_for_stiffness`); the response is rescaled to it (torques scale with ST,
    displacements and stresses do not).

    Returns
    -------
    (params, geometry, response, ST mm). Raises GeometryError, FeaError.
    """
    p = params_at(None)
    geom = build_any(p, frame)
    r = analyse_spring(geom, material, theta_rad, mesh, steps, True, keep_model,
                       both_directions=both_directions, gaps=gaps)  # fmt: skip
    if target_Nm_per_rad is None or not r.ok:
        return p, geom, r, p.thickness_mm
    scale, st = solve_for_stiffness(
        p.thickness_mm, r.mean_stiffness_Nm_per_rad, target_Nm_per_rad, held_st_mm
    )
    p = params_at(st)
    # ST is the extrusion: the outline, regions and checks do not depend on it, so the
    # built geometry only takes the new parameters (a second build cost ~25 ms a design).
    geom = replace(geom, params=p)
    r = r.scaled(scale)
    if r.model is not None:
        r.model.thickness_mm = st  # only the stress map reads it; stresses do not change
    return p, geom, r, st


def taguchi_seed(
    chosen: dict[str, float], frame: SpringFrame, n_arcs: int = 5, topology: str = "serpentine"
) -> np.ndarray:
    """The screening stage's spring as a full design vector (ST included, not clipped).

    ``chosen``: the factor values of the screening (serpentine: RP, RR, ST, A, RT, D of
    Table 6; spiral: :data:`geometry.arm_spring.SPIRAL_LEVELS`' names). The serpentine gets
    ``n_arcs`` arcs (its other levels kept, arcs spread evenly as in the screening), the
    vector in :func:`geometry.sea_spring.ga_variables` order; the spiral its
    :data:`geometry.arm_spring.SPIRAL_VARIABLES`. mm and degrees as the variables are named.
    """
    if topology == "spiral":
        v = spiral_level_values(chosen)
        return np.array([v[n] for n in SPIRAL_VARIABLES])
    n = int(n_arcs)
    p = taguchi_params(
        chosen["RP"], (n - 1) // 2, chosen["ST"], chosen["A"], chosen["RT"], chosen["D"], frame
    )
    return np.array(
        [*p.radii_mm, *p.arc_thickness_mm, *p.link_width_mm, p.hub_link_mm, p.pad_link_mm,
         p.span_deg, p.thickness_mm]
    )  # fmt: skip


# --------------------------------------------------------------------------------------------
# The 3D check, the thickness correction, the converged peak


class Solid3DOptions(Protocol):
    """What :func:`correct_3d` reads of a study's ``solid_3d:`` block."""

    layers: int  # P2 tetrahedra layers through half the thickness
    solver: str  # fea.solid3d.Solid3DSettings.solver: "auto", "multigrid", "cholmod", ...
    correct: bool  # correct ST by the 3D/2D ratio
    max_fraction_of_tolerance: float  # a ratio off 1 by less than this of the band: no change
    max_checks: int  # 3D checks at most
    converge_peak: bool  # converge the 2D peak on a finely sampled outline
    curve_step_mm: float  # arm sampling of that outline, mm


def worse_direction(r: SpringResponse) -> float:
    """+1 (ccw) or -1 (cw): the direction of the larger 2D peak stress."""
    rev = r.reverse_peak_stress_MPa
    return -1.0 if rev is not None and float(rev[-1]) > float(r.peak_stress_MPa[-1]) else 1.0


def fine_geometry(
    params: SpringParams | ArmSpringParams, frame: SpringFrame, curve_step_mm: float
) -> SpringGeometry:
    """The design as the peak-stress convergence meshes it and as its part is exported: the
    arms sampled every ``curve_step_mm`` (the serpentine's arcs also at 0.25 deg).
    Raises GeometryError."""
    if isinstance(params, ArmSpringParams):
        return build_arm_spring(params, frame, curve_step_mm=curve_step_mm)
    return build_spring(params, replace(frame, arc_step_deg=0.25, arc_step_mm=curve_step_mm))


def peak_convergence(
    params: SpringParams | ArmSpringParams, frame: SpringFrame, material: Material,
    theta_rad: float, sign: float, mesh: MeshSize, curve_step_mm: float,
) -> dict[str, Any]:  # fmt: skip
    """:func:`fea.solid3d.converge_peak_stress` on the design rebuilt with its arms sampled
    every ``curve_step_mm`` (:func:`fine_geometry`), nonlinear, hub turned by ``sign *
    theta_rad``, pads held. Raises FeaError, GeometryError."""
    from flexopt.fea.solid3d import converge_peak_stress

    smooth = fine_geometry(params, frame, curve_step_mm)
    return converge_peak_stress(
        smooth.fe_outline, smooth.thickness_mm, material, Clamp(smooth.pad_region),
        Rotate(smooth.hub_region, (0.0, 0.0), sign * theta_rad, 1), mesh.max_edge_mm,
        refine=smooth.mesh_regions(mesh.elements_through, mesh.max_edge_mm),
        stress_ignore=smooth.hub_region.union(smooth.pad_region).buffer(0.05),
        kinematics="nonlinear",
    )  # fmt: skip


def detail_solves(
    geom: SpringGeometry, material: Material, theta_rad: float, mesh: MeshSize, resolve: bool
) -> tuple[SpringResponse | None, SpringResponse]:
    """A report's two extra 2D solves of a built design: at ``theta_rad`` again when
    ``resolve`` (the design re-solved at its solved ST: it shows that torque is proportional
    to ST), and at 1 degree (the linear-vs-nonlinear row). Raises FeaError."""
    check = analyse_spring(geom, material, theta_rad, mesh) if resolve else None
    return check, analyse_spring(geom, material, math.radians(1.0), mesh)


def correct_3d(
    geom: SpringGeometry,
    r: SpringResponse,
    material: Material,
    theta_rad: float,
    target_Nm_per_rad: float,
    tolerance_percent: float,
    allowable_MPa: float,
    mesh: MeshSize,
    s3: Solid3DOptions,
    converged_peak: Callable[[], tuple[dict[str, Any], bool]] | None = None,
) -> dict[str, Any]:
    """The design as a 3D solid, its thickness corrected for it, its peak stress converged
    (issue 15; docs/solid3d.md).

    1. **3D check** (:func:`fea.solid3d.compare_with_plane_stress`): the plane mesh of the
       2D model extruded to ST (P2 tetrahedra, ``s3.layers`` through half the thickness, hub
       turned rigidly by ``theta_rad``, pads held through the thickness), linear, beside
       linear plane stress on the same mesh. The stiffness ratio multiplies each direction's
       nonlinear 2D stiffness (of ``r``), the vertex-averaged peak-stress ratio the 2D peak:
       the ratio is a property of the cross-sections, the same at 1 and 11 degrees (issue 15:
       1.022 by CalculiX, both).
    2. **Correction** (``s3.correct``, :func:`fea.solid3d.correct_thickness_3d`): when the
       ratio is off 1 by more than ``s3.max_fraction_of_tolerance`` of the band, ST becomes
       ST x K_target / mean K_3D (plane stress is linear in ST, so the 2D answers scale
       exactly) and is checked in 3D again, until both directions are in the band and the
       mean is centred, the spread of the directions makes the band unreachable, or
       ``s3.max_checks`` checks were made. The part is the last checked ST.
    3. **Converged peak** (``s3.converge_peak``): ``converged_peak()`` gives the
       :func:`peak_convergence` of the worse direction (:func:`worse_direction`) and whether
       another process computed it (the caller may have started it beside the 3D checks,
       which it needs none of); the 3D peak is its last value times the last check's 3D/2D
       peak ratio. Its FeaError or GeometryError becomes the ``problem`` of that entry.

    Cost (docs/solid3d.md): the checks share one 3D model (:class:`fea.solid3d.Solid3DModel`:
    the mesh extruded and assembled once, ST only scales its parts; the first check
    factorises, the re-checks solve by conjugate gradients preconditioned with that factor).

    Returns
    -------
    dict — N m/rad, MPa, mm, s; ``problem`` alone when the 3D model cannot be built.
    """
    from flexopt.fea.solid3d import Solid3DModel, Solid3DSettings, correct_thickness_3d
    from flexopt.fea.solid3d_sector import sector_or_reason

    t0 = time.perf_counter()
    st0 = float(geom.thickness_mm)
    ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)
    clamp = Clamp(geom.pad_region)
    regions = geom.mesh_regions(mesh.elements_through, mesh.max_edge_mm)
    k2d = {"ccw": r.stiffness_Nm_per_rad}
    if math.isfinite(r.reverse_stiffness_Nm_per_rad):
        k2d["cw"] = r.reverse_stiffness_Nm_per_rad
    peak2d = r.worst_peak_stress_MPa  # plane stress: independent of ST
    model: Solid3DModel | None = None

    def check(st: float) -> dict[str, Any]:
        assert model is not None
        c = model.compare_with_plane_stress(st)
        ratio = c["stiffness_ratio"]
        k2 = {d: k * st / st0 for d, k in k2d.items()}  # torque is proportional to ST
        return {
            "stiffness_3d": {d: k * ratio for d, k in k2.items()},
            "stiffness_2d": k2,
            "stiffness_ratio_3d_2d": ratio,
            "peak_stress_ratio_3d_2d": c["peak_stress_ratio"],
            "linear_stiffness_2d_Nm_per_rad": c["stiffness_2d"] * 1e-3,
            "linear_stiffness_3d_Nm_per_rad": c["stiffness_3d"] * 1e-3,
            "peak_stress_3d_MPa": peak2d * c["peak_stress_ratio"],
            "dofs": c["solid3d"]["n_dofs"],
            "solver": c["solid3d"]["solver"],
            "iterations": c["solid3d"]["iterations"],
            "time_s": c["solid3d"]["times_s"]["total"] + c["time_2d_s"],
        }

    try:
        # one sector of the RP arms where the part repeats (fea/solid3d_sector.py: half the
        # memory of the whole for two arms, the same answer on its periodic mesh)
        repeat = {"hub": geom.hub_region, "pads": geom.pad_region, "stress-ignore": ignore}
        # the cuts kept off the plane-stress peak (a line of cut nodes through it changes the
        # mesh there most: fea/solid3d_sector.choose_cut_angle)
        pm, model_3d = sector_or_reason(geom.fe_outline, geom.params.n_sets, mesh.max_edge_mm,
                                        regions, repeat, s3.solver,
                                        avoid_mm=r.peak_stress_xy_mm)  # fmt: skip
        m = (
            mesh_polygon(geom.fe_outline, mesh.max_edge_mm, refine=regions)
            if pm is None
            else pm.sector
        )
        drive = Rotate(geom.hub_region, (0.0, 0.0), theta_rad, 1)
        settings = Solid3DSettings(layers=s3.layers, solver=s3.solver)
        model = Solid3DModel(m, material, clamp, drive, settings, stress_ignore=ignore, periodic=pm)
        corr = correct_thickness_3d(
            check,
            st0,
            target_Nm_per_rad,
            tolerance_percent,
            s3.max_fraction_of_tolerance if s3.correct else math.inf,
            s3.max_checks,
        )
        # the last check's state (the part's ST), kept by the model: best_3d.vtu, no new solve
        field = model.last_field(corr["checks"][-1]["thickness_mm"]) if corr["checks"] else None
    except FeaError as exc:
        return {"problem": f"3D check not made: {exc}"}
    finally:
        model = None  # its factor holds 1.04 GB (docs/solid3d.md, "Memory")
    checks = []
    for c in corr["checks"]:
        row = {"ST_mm": c["thickness_mm"], "stiffness_ratio_3d_2d": c["stiffness_ratio_3d_2d"]}
        for d in k2d:
            row[f"stiffness_{d}_2d_Nm_per_rad"] = c["stiffness_2d"][d]
            row[f"stiffness_{d}_3d_Nm_per_rad"] = c["stiffness_3d"][d]
            row[f"error_{d}_3d_percent"] = c["stiffness_error_percent"][d]
        row.update(
            {
                "in_band": c["in_band"],
                "peak_stress_ratio_3d_2d": c["peak_stress_ratio_3d_2d"],
                "peak_stress_3d_MPa": c["peak_stress_3d_MPa"],
                "dofs": c["dofs"],
                "solver": c["solver"],
                "iterations": c["iterations"],
                "time_s": c["time_s"],
            }
        )
        checks.append(row)
    last = corr["checks"][-1]
    band = corr["band"]
    out: dict[str, Any] = {
        "method": "linear 3D / linear plane stress on the same plane mesh, applied to the "
        "nonlinear 2D answers; ST corrected by the 3D/2D ratio and re-checked in 3D",
        "corrected": corr["corrected"],
        "ST_before_mm": corr["thickness_before_mm"],
        "ST_after_mm": corr["thickness_after_mm"],
        "stopped": corr["stopped"],
        "checks": checks,
        "stiffness_ratio_3d_2d": last["stiffness_ratio_3d_2d"],
        "peak_stress_ratio_3d_2d": last["peak_stress_ratio_3d_2d"],
    }
    for d in k2d:
        out[f"stiffness_{d}_3d_Nm_per_rad"] = last["stiffness_3d"][d]
        out[f"stiffness_error_{d}_3d_percent"] = last["stiffness_error_percent"][d]
    out.update(
        {
            "stiffness_band_Nm_per_rad": [
                target_Nm_per_rad * (1 - tolerance_percent / 100),
                target_Nm_per_rad * (1 + tolerance_percent / 100),
            ],
            "stiffness_ok_3d": corr["in_band"],
            "stiffness_spread_3d_percent": band["spread_percent"],
            "max_spread_percent": band["max_spread_percent"],
            "band_reachable": band["reachable"],
            "peak_stress_2d_MPa": peak2d,
            "peak_stress_3d_MPa": last["peak_stress_3d_MPa"],
            "allowable_stress_MPa": allowable_MPa,
            "dofs": last["dofs"],
            "model_3d": model_3d,  # one sector of RP (its DOFs above) or the whole and why
            "solver": last["solver"],
            "time_3d_s": time.perf_counter() - t0,
        }
    )
    if s3.converge_peak:
        assert converged_peak is not None, "converge_peak needs converged_peak"
        out["peak_convergence"] = _peak_record(
            converged_peak, worse_direction(r), s3.curve_step_mm, last["peak_stress_ratio_3d_2d"]
        )
        conv = out["peak_convergence"]
        if "problem" not in conv:
            out["peak_stress_3d_MPa"] = conv["peak_stress_3d_MPa"]
    out["stress_ok_3d"] = bool(out["peak_stress_3d_MPa"] <= allowable_MPa)
    out["time_s"] = time.perf_counter() - t0
    if field is not None:  # large arrays: the kind takes them out (pipeline/fields.py)
        out["field"] = field
    return out


def _peak_record(
    converged_peak: Callable[[], tuple[dict[str, Any], bool]], sign: float,
    curve_step_mm: float, ratio_3d_2d: float,
) -> dict[str, Any]:  # fmt: skip
    """The ``peak_convergence`` entry of :func:`correct_3d`: the 2D peak of the worse
    direction converged (``converged_peak()``) and the 3D peak from it."""
    t0 = time.perf_counter()
    try:
        c, ran = converged_peak()
    except (FeaError, GeometryError) as exc:
        return {"problem": f"peak-stress convergence not made: {exc}"}
    return {
        "direction": "ccw" if sign > 0 else "cw",
        "curve_step_mm": curve_step_mm,
        "converged": c["converged"],
        "status": c["status"],
        "last_two_MPa": c["last_two_MPa"],
        "peaks_MPa": c["peaks_MPa"],
        "local_edge_mm": c["local_edge_mm"],
        "peak_xy_mm": c["peak_xy_mm"],
        "corner": c["corner"],
        "peak_stress_2d_MPa": c["last_two_MPa"][-1],
        "peak_stress_3d_MPa": c["last_two_MPa"][-1] * ratio_3d_2d,
        # the convergence's own time (in the second process, beside the 3D checks) and
        # how long the report waited for it here
        "time_s": c["time_s"],
        "wait_s": time.perf_counter() - t0,
        "process": "second" if ran else "this",
    }
