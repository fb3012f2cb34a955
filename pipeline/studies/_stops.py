"""The ``stops:`` block shared by the kinds that solve with rigid stops (``polyline_beam``,
``mechanism``): its pydantic models (:class:`StopsSpec`, :class:`StopOutline`; docs/contact.md)
and the built-in requirement "contact penetration within tolerance" (:class:`PenetrationWithin`).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace

from flexopt.fea.stops import ContactSettings
from flexopt.optimise.requirements import MaxValue, Verdict
from flexopt.pipeline.study import STUDY_CONFIG
from pydantic import BaseModel, Field, field_validator, model_validator

__all__ = ["PenetrationWithin", "StopOutline", "StopsSpec"]

_STOP_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,39}")


class StopOutline(BaseModel):
    """One rigid stop of the ``stops:`` block: an outline in the beam's plane (mm)."""

    model_config = STUDY_CONFIG

    name: str = Field(
        description="label of the stop; names its columns (<name>_contact_force_N ...)"
    )
    points_mm: tuple[tuple[float, float], ...] = Field(
        min_length=1,
        description="[x, y] points: one (a pin), an open polyline (a wall) or a polygon, mm",
    )
    closed: bool = Field(False, description="the points bound a rigid body (polygon, >= 3 points)")

    @field_validator("name")
    @classmethod
    def _name_is_a_column_prefix(cls, value: str) -> str:
        if not _STOP_NAME.fullmatch(value):
            raise ValueError(
                f"'{value}' is not a stop name: a letter, then letters, digits or _ "
                "(at most 40; it starts the stop's column names)"
            )
        return value

    @field_validator("points_mm")
    @classmethod
    def _no_repeated_point(
        cls, points: tuple[tuple[float, float], ...]
    ) -> tuple[tuple[float, float], ...]:
        for i in range(len(points) - 1):
            if math.dist(points[i], points[i + 1]) <= 1e-9:
                raise ValueError(
                    f"points [{i}] and [{i + 1}] coincide at {list(points[i])}; remove one"
                )
        return points

    @model_validator(mode="after")
    def _polygon_has_an_area(self) -> StopOutline:
        if self.closed and len(self.points_mm) < 3:
            raise ValueError(
                f"closed: true needs at least 3 points_mm (a polygon), got "
                f"{len(self.points_mm)}; add points or set closed: false"
            )
        return self


class StopsSpec(BaseModel):
    """The ``stops:`` block: rigid stops the beam meets (frictionless penalty contact, see
    docs/contact.md). A plain list is read as ``outlines``."""

    model_config = STUDY_CONFIG

    outlines: tuple[StopOutline, ...] = Field(
        min_length=1, max_length=50, description="the stops: a list of {name, points_mm, closed}"
    )
    penalty_factor: float = Field(
        ContactSettings().penalty_factor,
        gt=0,
        description="penalty stiffness k = penalty_factor x EI / h^3 per element",
    )

    @model_validator(mode="before")
    @classmethod
    def _a_list_is_the_outlines(cls, value: object) -> object:
        return {"outlines": value} if isinstance(value, list | tuple) else value

    @field_validator("outlines")
    @classmethod
    def _unique_names(cls, outlines: tuple[StopOutline, ...]) -> tuple[StopOutline, ...]:
        seen: dict[str, int] = {}
        for i, stop in enumerate(outlines):
            if stop.name in seen:
                raise ValueError(
                    f"[{i}].name '{stop.name}' is already the name of [{seen[stop.name]}]; "
                    "give every stop its own name"
                )
            seen[stop.name] = i
        return outlines


class PenetrationWithin(MaxValue):
    """``max_penetration_mm <= tolerance``: the penalty held the beam out of the stops to within
    fea's tolerance (ContactSettings.penetration_tol x the thinnest section). Not met when even
    the raised penalty (solve_with_stops raises it 10x at most max_raises times) left a deeper
    penetration; the detail says with which penalty factor."""

    def check(self, metrics, curves=None) -> Verdict:  # type: ignore[no-untyped-def]
        verdict = super().check(metrics, curves)
        if verdict.met or not math.isfinite(verdict.value):
            return verdict
        factor = metrics.get("contact_penalty_factor")
        raises = metrics.get("contact_penalty_raises")
        detail = (
            f"the penalty could not hold the beam out of the stops: penetration "
            f"{verdict.value:.4g} mm > {self.maximum:.4g} mm with penalty_factor {factor:g} "
            f"(raised {raises} time(s)); raise stops.penalty_factor or refine geometry.elements"
            if isinstance(factor, int | float)
            else "the penalty could not hold the beam out of the stops"
        )
        return replace(verdict, detail=detail)
