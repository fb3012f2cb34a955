"""Study kind ``polyline_beam``: one planar beam along a polyline, driven at its end.

YAML (units in the key names; see docs/usage.md)::

    geometry: {kind: polyline_beam, points_mm: [[0, 0], [60, 0]], thickness_mm: [1.5, 1.5],
               width_mm: 8, curvature_per_mm: [0.0], elements: 40}
    boundary:
      start: clamped                     # or pinned
      end: {control: displacement, direction: [0, 1], max_mm: 20, steps: 20,
            rotation: free, transverse: free}
    stops:                               # optional rigid stops (docs/contact.md)
      penalty_factor: 1000               # optional
      outlines:
        - {name: anvil, points_mm: [[29, -3], [31, -3], [30, -1.25]], closed: true}

``stops:`` may also be the plain list of outlines (the default penalty then).
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import asdict, replace
from typing import Annotated, ClassVar, Literal

import numpy as np
from flexopt.fea.beam import BeamModel, BeamResponse, BeamSettings, EndDrive
from flexopt.fea.beam_fields import beam_field
from flexopt.fea.beam_response import (
    contact_summary,
    response_table,
    stability_summary,
    summarise,
)
from flexopt.fea.beam_statics import statics_fibres, with_statics_stress
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material
from flexopt.fea.stops import BeamContact, ContactSettings, RigidStop, overlaps, solve_with_stops
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.profile import BeamProfile, first_crossing
from flexopt.optimise.requirements import Requirement
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import EvaluationResult, StudyKind, _builtin, register
from flexopt.pipeline.studies._polyline_clamp import (
    CLAMP_KT_KEY,
    CLAMP_STRESS,
    clamp_rows,
    clamp_stress_MPa,
    clamped_nodes,
)
from flexopt.pipeline.studies._polyline_slenderness import (
    SLENDERNESS,
    Slenderness,
    slenderness_ratio,
)
from flexopt.pipeline.studies._stops import PenetrationWithin, StopOutline, StopsSpec
from flexopt.pipeline.study import STUDY_CONFIG, Study, material_record
from pydantic import (
    BaseModel,
    Field,
    ValidationInfo,
    field_validator,
)

__all__ = [
    "BeamBoundary",
    "EndSpec",
    "PolylineBeamGeometry",
    "PolylineBeamStudy",
    "StopOutline",
    "StopsSpec",
    "build_drive",
    "build_profile",
    "build_stops",
    "response_table",
    "stability_summary",
    "summarise",
]

PositiveFloat = Annotated[float, Field(gt=0)]


class PolylineBeamGeometry(BaseModel):
    """The ``geometry:`` block of a ``polyline_beam`` study (mm)."""

    model_config = STUDY_CONFIG

    kind: Literal["polyline_beam"] = Field(description="polyline_beam")
    points_mm: tuple[tuple[float, float], ...] = Field(
        min_length=2, description="centreline points [x, y] from start to end, mm"
    )
    thickness_mm: tuple[PositiveFloat, ...] = Field(
        description="in-plane thickness at each point, mm (one per point)"
    )
    width_mm: float = Field(gt=0, description="out-of-plane width of the section, mm")
    curvature_per_mm: tuple[float, ...] | None = Field(
        None, description="signed curvature of each segment, 1/mm (one per segment; 0 = straight)"
    )
    elements: int = Field(
        20,
        ge=1,
        le=5000,
        description="target number of beam elements, at least 1 per segment",
    )

    @field_validator("points_mm")
    @classmethod
    def _no_zero_length_segment(
        cls, points: tuple[tuple[float, float], ...]
    ) -> tuple[tuple[float, float], ...]:
        for i in range(len(points) - 1):
            if math.dist(points[i], points[i + 1]) <= 1e-9:
                raise ValueError(
                    f"points [{i}] and [{i + 1}] coincide at {list(points[i])} (zero-length "
                    "segment); remove the duplicate point"
                )
        crossing = first_crossing(points)
        if crossing is not None:
            i, j, at = crossing
            raise ValueError(
                f"the centreline crosses itself: segment [{i}]-[{i + 1}] meets segment "
                f"[{j}]-[{j + 1}] at [{at[0]:.4g}, {at[1]:.4g}]; reorder or move the points"
            )
        return points

    @field_validator("thickness_mm")
    @classmethod
    def _one_thickness_per_point(
        cls, thickness: tuple[float, ...], info: ValidationInfo
    ) -> tuple[float, ...]:
        points = info.data.get("points_mm")
        if points is not None and len(thickness) != len(points):
            raise ValueError(
                f"needs one value per point: {len(points)} points but {len(thickness)} "
                f"thickness values; give {len(points)} values"
            )
        return thickness

    @field_validator("curvature_per_mm")
    @classmethod
    def _one_curvature_per_segment(
        cls, curvature: tuple[float, ...] | None, info: ValidationInfo
    ) -> tuple[float, ...] | None:
        points = info.data.get("points_mm")
        if curvature is not None and points is not None and len(curvature) != len(points) - 1:
            raise ValueError(
                f"needs one value per segment: {len(points)} points make {len(points) - 1} "
                f"segments but {len(curvature)} curvature values were given"
            )
        return curvature


class EndSpec(BaseModel):
    """The ``boundary.end:`` block: how the end (last point) is driven."""

    model_config = STUDY_CONFIG

    control: Literal["displacement", "force"] = Field(
        "displacement", description="displacement (give max_mm) or force (give max_N)"
    )
    direction: tuple[float, float] = Field(
        description="[dx, dy] of the driven direction (normalised; its length does not matter)"
    )
    max_mm: float | None = Field(
        None, validate_default=True, description="end displacement at the last step, mm"
    )
    max_N: float | None = Field(
        None, validate_default=True, description="end force at the last step, N"
    )
    steps: int = Field(20, ge=1, le=2000, description="number of load steps = rows after row 0")
    rotation: Literal["fixed", "free"] = Field(
        "free", description="fixed holds the end section's rotation at 0"
    )
    transverse: Literal["fixed", "free"] = Field(
        "free", description="fixed holds the end motion perpendicular to direction at 0"
    )

    @field_validator("direction")
    @classmethod
    def _direction_has_length(cls, direction: tuple[float, float]) -> tuple[float, float]:
        if math.hypot(*direction) < 1e-12:
            raise ValueError(f"{list(direction)} has no length; give e.g. [0, 1] for +y")
        return direction

    @field_validator("max_mm", "max_N")
    @classmethod
    def _max_matches_control(cls, value: float | None, info: ValidationInfo) -> float | None:
        control = info.data.get("control")
        key = info.field_name
        wanted = {"displacement": "max_mm", "force": "max_N"}.get(control or "")
        if wanted is None:  # control itself is invalid and reported on its own
            return value
        if key != wanted and value is not None:
            raise ValueError(
                f"{key} does not go with control: {control}; give {wanted} instead "
                f"or set control: {'force' if key == 'max_N' else 'displacement'}"
            )
        if key == wanted and value is None:
            unit = "mm" if key == "max_mm" else "N"
            raise ValueError(
                f"control: {control} needs {key} (the value at the last step, {unit}); add it"
            )
        if value is not None and not value > 0:
            raise ValueError(
                f"{key} = {value:g} must be > 0; reverse direction for the opposite sense"
            )
        return value


class BeamBoundary(BaseModel):
    """The ``boundary:`` block of a beam study."""

    model_config = STUDY_CONFIG

    start: Literal["clamped", "pinned"] = Field(
        "clamped", description="support of the first point: clamped or pinned"
    )
    end: EndSpec = Field(description="how the last point is driven")
    clamp_kt: float | None = Field(None, ge=1, description=CLAMP_KT_KEY)


class PolylineBeamStudy(Study):
    """A whole ``polyline_beam`` study file."""

    geometry: PolylineBeamGeometry = Field(
        description="kind: polyline_beam, points_mm, thickness_mm, width_mm"
    )
    boundary: BeamBoundary = Field(description="start support and end drive: {start, end}")
    stops: StopsSpec | None = Field(
        None,
        description="rigid stops the beam meets: {outlines: [{name, points_mm, closed}], "
        "penalty_factor} (or the list of outlines)",
    )

    # a study without stops dumps as it did before the block existed (Study's serializer)
    OPTIONAL_BLOCKS: ClassVar[tuple[str, ...]] = (*Study.OPTIONAL_BLOCKS, "stops")


# --------------------------------------------------------------------------------------------
# From the study to the solver's inputs

_GEOMETRY_KEYS = ("points_mm", "thickness_mm", "width_mm", "curvature_per_mm")

# Words in a FeaError message → the key path a user can change. The earliest match wins.
_FEA_WORDS = {
    "n_elements": "geometry.elements",
    "elements": "geometry.elements",
    "direction": "boundary.end.direction",
    "max_value": "boundary.end",
    "steps": "boundary.end.steps",
    "rotation": "boundary.end.rotation",
    "transverse": "boundary.end.transverse",
    "start": "boundary.start",
    "E_MPa": "material.E_MPa",
    "nu": "material.nu",
    "yield_MPa": "material.yield_MPa",
    "thickness": "geometry.thickness_mm",
    "width": "geometry.width_mm",
    "points": "geometry.points_mm",
    "curvature": "geometry.curvature_per_mm",
}


def fea_error_path(message: str) -> str:
    """The key path a :class:`FeaError` message is most likely about (``study`` if unsure)."""
    best: tuple[int, str] | None = None
    for word, path in _FEA_WORDS.items():
        match = re.search(rf"\b{re.escape(word)}", message)
        if match and (best is None or match.start() < best[0]):
            best = (match.start(), path)
    return best[1] if best else "study"


def build_profile(geometry: PolylineBeamGeometry) -> BeamProfile:
    """The :class:`BeamProfile` of a validated geometry block.

    Raises
    ------
    StudyError
        At ``geometry.<key>`` when the profile refuses the numbers.
    """
    try:
        return BeamProfile(
            points_mm=np.array(geometry.points_mm, dtype=float),
            thickness_mm=np.array(geometry.thickness_mm, dtype=float),
            width_mm=geometry.width_mm,
            curvature_per_mm=None
            if geometry.curvature_per_mm is None
            else np.array(geometry.curvature_per_mm, dtype=float),
        )
    except GeometryError as exc:
        match = re.match(r"(\w+)(\[\d+\])?", str(exc))
        path = "geometry"
        if match and match.group(1) in _GEOMETRY_KEYS:
            path = f"geometry.{match.group(1)}{match.group(2) or ''}"
        raise StudyError(path, str(exc)) from exc


def build_material(study: PolylineBeamStudy) -> Material:
    """The solver's material record; :class:`FeaError` becomes a StudyError at ``material``."""
    try:
        return study.material.to_material()
    except FeaError as exc:
        raise StudyError(fea_error_path(str(exc)), str(exc)) from exc


def build_drive(end: EndSpec) -> EndDrive:
    """The solver's :class:`EndDrive` for a validated ``boundary.end`` block.

    Raises
    ------
    StudyError
        At ``boundary.end.<key>`` if the solver refuses what the study model let through.
    """
    max_value = end.max_mm if end.control == "displacement" else end.max_N
    try:
        return EndDrive(
            control=end.control,
            direction=(float(end.direction[0]), float(end.direction[1])),
            max_value=float(max_value),  # type: ignore[arg-type]  # EndSpec guarantees it
            steps=end.steps,
            rotation=end.rotation,
            transverse=end.transverse,
        )
    except FeaError as exc:
        raise StudyError(fea_error_path(str(exc)), str(exc)) from exc


def build_settings(geometry: PolylineBeamGeometry) -> BeamSettings:
    """Solver settings: the study sets the element count, the solver's defaults do the rest."""
    return BeamSettings(n_elements=geometry.elements)


def build_stops(study: PolylineBeamStudy) -> tuple[tuple[RigidStop, ...], ContactSettings]:
    """The solver's rigid stops and contact settings of a validated ``stops:`` block (no stops:
    an empty tuple and the default settings)."""
    spec = study.stops
    if spec is None:
        return (), ContactSettings()
    stops = tuple(
        RigidStop(np.array(o.points_mm, dtype=float), o.closed, o.name) for o in spec.outlines
    )
    return stops, ContactSettings(penalty_factor=spec.penalty_factor)


def check_stops_clear(study: PolylineBeamStudy, model: BeamModel) -> None:
    """Refuse a stop that overlaps the undeformed beam (fea.stops.overlaps).

    Raises
    ------
    StudyError
        At ``stops.outlines[i]``, with the overlap depth (mm).
    """
    stops, contact_settings = build_stops(study)
    if not stops:
        return
    contact = BeamContact(model, stops, contact_settings)
    for i, depth in overlaps(contact):
        raise StudyError(
            f"stops.outlines[{i}]",
            f"stop '{stops[i].name}' overlaps the undeformed beam by {depth:.4g} mm (the beam's "
            f"surface is t/2 from its centreline); move the stop clear of the beam",
        )


def check(study: PolylineBeamStudy) -> None:
    """Build geometry, material and drive once so every refusal is reported before a solve."""
    profile = build_profile(study.geometry)
    material = build_material(study)
    build_drive(study.boundary.end)
    if study.stops is not None:
        try:
            model = BeamModel(
                profile, material, study.boundary.start, build_settings(study.geometry)
            )
        except FeaError as exc:
            raise StudyError(fea_error_path(str(exc)), str(exc)) from exc
        check_stops_clear(study, model)


# --------------------------------------------------------------------------------------------
# Solve and summarise (the response's columns and figures: fea/beam_response.py)


def evaluate(study: PolylineBeamStudy, repeat: int = 1) -> EvaluationResult:
    """Solve the study ``repeat`` times (for timing) and summarise the last solve.

    The time of each repeat covers building the :class:`BeamModel` and solving; nothing else.

    Raises
    ------
    StudyError
        When the solver refuses the inputs (:class:`FeaError`), naming the likely key path.
        Non-convergence is not an error: it comes back as ``converged=False`` with the message.
    """
    profile = build_profile(study.geometry)
    material = build_material(study)
    drive = build_drive(study.boundary.end)
    settings = build_settings(study.geometry)
    stops, contact_settings = build_stops(study)
    times = []
    response: BeamResponse | None = None
    for _ in range(max(1, repeat)):
        start = time.perf_counter()
        try:
            model = BeamModel(profile, material, study.boundary.start, settings)
            if stops:
                check_stops_clear(study, model)
                response = solve_with_stops(model, drive, stops, contact_settings)
            else:
                response = model.solve(drive)
        except FeaError as exc:
            raise StudyError(fea_error_path(str(exc)), str(exc)) from exc
        times.append(time.perf_counter() - start)
    assert response is not None
    # the stress from statics (end load and stop forces): converged where the curvature is not
    contact = statics_contact(model, stops, contact_settings, response)
    response = with_statics_stress(model, response, np.asarray(drive.direction), contact)
    table = response_table(response)
    converged = bool(response.ok)
    message = response.message or ("" if converged else "not every step converged")
    summary = summarise(table, material, profile)
    # L/t: below its bound the beam's figures are not the strip's (_polyline_slenderness.py)
    summary[SLENDERNESS] = slenderness_ratio(profile.length_mm, study.geometry.thickness_mm)
    # design.vtu: the centreline per step with its section and fibre stresses
    field = statics_fibres(beam_field(model, response), model, response, drive.direction, contact)
    # the beam's stress at its ideal clamps, for the row of the clamp as made (_polyline_clamp.py)
    nodes = clamped_nodes(study.boundary.start, drive.rotation)
    if nodes:
        summary[CLAMP_STRESS] = clamp_stress_MPa(field, nodes)
    files: dict[str, bytes] = {}
    if stops:
        summary.update(contact_summary(response, drive.control))
        if summary["contact_message"]:
            message = "; ".join(m for m in (message, summary["contact_message"]) if m)
        files["contact_shapes.png"] = stops_png(response, stops)
    # A path that passed a bifurcation (a strut pushed past its Euler load stays straight in the
    # solver) is never reported as a plain result: the summary says stable = False and the message
    # names the step. ``converged`` keeps meaning that every row is an equilibrium.
    stability = stability_summary(response)
    summary.update(stability)
    if not stability["stable"]:
        message = "; ".join(m for m in (message, stability["unstable_message"]) if m)
    return EvaluationResult(
        table=table,
        summary=summary,
        converged=converged,
        message=message,
        solve_times_s=tuple(times),
        inputs={
            "material": material_record(material) | {"G_MPa": material.G_MPa},
            "drive": {
                "control": drive.control,
                "direction": list(drive.direction),
                "max_value": drive.max_value,
                "max_unit": "mm" if drive.control == "displacement" else "N",
                "steps": drive.steps,
                "rotation": drive.rotation,
                "transverse": drive.transverse,
            },
            "start": study.boundary.start,
            "settings": asdict(settings),
            "profile": {
                "length_mm": profile.length_mm,
                "arc_length_mm": profile.arc_length_mm.tolist(),
            },
        },
        diagnostics=dict(response.extra),
        plot={
            "x": "displacement_mm",
            "y": "force_N",
            "stress": "peak_stress_MPa",
            "allowable_MPa": material.yield_MPa,
        },
        headline=(
            "max_abs_force_N",
            "max_abs_displacement_mm",
            "initial_stiffness_N_per_mm",
            "max_abs_moment_Nmm",
            "max_abs_end_rotation_deg",
            "max_peak_stress_MPa",
            "stress_yield_ratio",
            "mass_g",
            "stable",
            *(_CONTACT_HEADLINE[drive.control] if stops else ()),
        ),
        files=files,
        **{"shapes_mm": response.shapes_mm, "beam_field": field},
    )


def statics_contact(
    model: BeamModel,
    stops: tuple[RigidStop, ...],
    settings: ContactSettings,
    response: BeamResponse,
) -> BeamContact | None:
    """The :class:`BeamContact` ``response`` was solved with (its final penalty factor, after
    any raise by :func:`fea.stops.solve_with_stops`), for the stress from statics; None
    without stops."""
    if not stops or response.contact is None:
        return None
    factor = response.contact.extra.get("penalty_factor", settings.penalty_factor)
    return BeamContact(model, stops, replace(settings, penalty_factor=factor))


_CONTACT_HEADLINE = {
    control: (f"first_contact_{unit}", "max_contact_force_N", "max_penetration_mm")
    for control, unit in (("displacement", "displacement_mm"), ("force", "force_N"))
}


def stops_png(response: BeamResponse, stops: tuple[RigidStop, ...]) -> bytes:
    """The deformed centrelines with the stops (pipeline.plots.stops_shapes_png), PNG."""
    from flexopt.pipeline import plots  # matplotlib only when there is a figure to draw

    ok = np.asarray(response.converged, dtype=bool)
    return plots.stops_shapes_png(
        np.asarray(response.shapes_mm, dtype=float)[ok],
        [(st.name, st.outline_mm, st.closed) for st in stops],
        np.asarray(response.displacement_mm, dtype=float)[ok],
        np.asarray(response.contact.rows_in_contact, dtype=bool)[ok],
    )


# --------------------------------------------------------------------------------------------
# Requirements and quantities with stops


def penetration_tolerance_mm(study: PolylineBeamStudy) -> float:
    """fea's penetration tolerance for the study's beam, mm: ContactSettings.penetration_tol x
    the thinnest section (the thickness is linear between the points)."""
    return ContactSettings().penetration_tol * float(min(study.geometry.thickness_mm))


def requirements(study: PolylineBeamStudy) -> list[Requirement]:
    """The built-in requirements; with stops also "contact penetration within tolerance"."""
    reqs = [*_builtin.polyline_beam(study), Slenderness()]
    # an ideal clamp where the part as made has a corner (#22, _polyline_clamp.py)
    reqs += clamp_rows(study, build_material(study).yield_MPa)
    if study.stops is not None:
        reqs.append(
            PenetrationWithin(
                "max_penetration_mm",
                "contact penetration within tolerance",
                "check",
                penetration_tolerance_mm(study),
            )
        )
    return reqs


def quantities(study: PolylineBeamStudy) -> tuple[str, ...]:
    """The names a requirement may judge; with stops, each stop's columns and figures too."""
    names = [*_builtin.POLYLINE_BEAM, SLENDERNESS, CLAMP_STRESS]
    if study.stops is None:
        return tuple(names)
    unit = "displacement_mm" if study.boundary.end.control == "displacement" else "force_N"
    names += [f"first_contact_{unit}", "max_contact_force_N", "max_penetration_mm", "contact_rows"]
    for stop in study.stops.outlines:
        n = stop.name
        names += [
            f"{n}_contact_force_N", f"{n}_gap_mm", f"{n}_in_contact",
            f"{n}_first_contact_{unit}", f"{n}_max_contact_force_N", f"{n}_min_gap_mm",
        ]  # fmt: skip
    return tuple(names)


register(
    StudyKind(
        "polyline_beam",
        PolylineBeamStudy,
        check,
        evaluate,
        requirements=requirements,
        quantities=quantities,
        # A and I of every section scale with it: every force and moment at a given motion
        width_key="geometry.width_mm",
    )
)  # type: ignore[arg-type]
