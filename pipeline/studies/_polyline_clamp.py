"""The polyline beam's clamps as made (#22, session 28): the row "peak stress at the clamp as
made".

The beam model clamps the strip ideally (fea/beam.py): at a ``clamped`` start, and at an end
whose ``rotation`` is ``fixed``, the section stays square to the support and the stress there
is the beam's nominal ``|N|/A + |M| c/I`` (Kt 1). The kind exports no part (``flexopt export``
refuses it: "kind 'polyline_beam' gives no part outline to export"; ``flexopt evaluate`` writes
the response, the VTU of the centreline and the plot only), so what holds the strip is the
user's: a clamp's edge, or a base the strip grows out of, where the part as made has a
re-entrant corner. At a sharp corner the stress does not converge under refinement (2D
elasticity; measured in tests/pipeline/test_polyline_clamp.py: a strip grown out of a block
in plane stress reads a peak at the corner that rises without bound as the elements there
shrink, above the beam's M c / I); a filleted or clamped one has a Kt the model does not see.
The strip's largest moment is at a clamp in the common cases (a cantilever, a clamped-guided
strip), so the "stress within yield" row stands on the ideal clamp's figure there.

Decision (as the leaf joint's support, pipeline/studies/_leaf_support.py): a study with a
clamped section states the clamp's stress-concentration factor as built,
``boundary.clamp_kt`` (>= 1; from a handbook for a filleted shoulder, e.g. Roark's Table 17.1
as ``geometry.mechanism.shoulder_kt`` fits it, or from a test); the row then judges
``clamp_kt x clamp_stress_MPa <= yield_MPa``, ``clamp_stress_MPa`` the beam's largest stress
at the clamped sections over the converged rows. Without it the row is NOT MET with the
reason and the Kt-1 figure. A ``pinned`` start with a free end rotation clamps nothing: no row.
The row is a check (the kind has no optimiser).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from flexopt.optimise.requirements import Requirement, Verdict

__all__ = [
    "CLAMP_KT_KEY",
    "CLAMP_ROW",
    "CLAMP_STRESS",
    "ClampAsMade",
    "clamp_rows",
    "clamp_stress_MPa",
    "clamped_nodes",
]

#: the row's name
CLAMP_ROW = "peak stress at the clamp as made"

#: the summary's key: the beam's largest stress at the clamped sections, MPa
CLAMP_STRESS = "clamp_stress_MPa"

#: the description of ``boundary.clamp_kt``
CLAMP_KT_KEY = (
    "stress-concentration factor of the clamps as built (>= 1): the clamped start and an end "
    "whose rotation is fixed (the model clamps ideally, Kt 1); without it the row 'peak stress "
    "at the clamp as made' is NOT MET (docs/beam.md)"
)


def clamped_nodes(start: str, rotation: str) -> dict[str, int]:
    """The clamped sections of a strip: ``{"start": 0}`` for a ``clamped`` start, ``{"end": -1}``
    for an end whose ``rotation`` is ``fixed`` (node indices of the beam's field)."""
    nodes = {}
    if start == "clamped":
        nodes["start"] = 0
    if rotation == "fixed":
        nodes["end"] = -1
    return nodes


def clamp_stress_MPa(field: dict | None, nodes: dict[str, int]) -> float | None:
    """The largest ``equivalent_MPa`` (``|N|/A + |M|c/I``, (n_rows, n_nodes) MPa, NaN on rows
    that did not converge: :func:`fea.beam_statics.statics_fibres`) at ``nodes`` over the rows,
    MPa; None without a field, without clamped nodes or without a converged row."""
    if field is None or not nodes or "equivalent_MPa" not in field:
        return None
    eq = np.asarray(field["equivalent_MPa"], dtype=float)[:, list(nodes.values())]
    if not np.any(np.isfinite(eq)):
        return None
    return float(np.nanmax(eq))


@dataclass(frozen=True)
class ClampAsMade(Requirement):
    """``clamp_kt x clamp_stress_MPa <= allowable_MPa`` (MPa); NOT MET with the reason when
    ``clamp_kt`` is None. ``where``: the clamped sections, in words."""

    quantity: str = CLAMP_STRESS
    name: str = CLAMP_ROW
    allowable_MPa: float = math.inf
    clamp_kt: float | None = None
    where: str = "the start"

    def bound_text(self) -> str:
        return f"<= {self.allowable_MPa:g} MPa"

    def scale(self) -> float:
        return self.allowable_MPa

    def check(self, metrics: Any, curves: Any = None) -> Verdict:
        stress = _value_of(metrics, CLAMP_STRESS)
        if self.clamp_kt is None:
            return self.missing(
                self.bound_text(),
                f"the model clamps the strip ideally (Kt 1) at {self.where}, but the part as "
                "made is held there by a clamp or grows out of a base: a corner whose stress "
                "concentration the model does not see (sharp, it has no bound); state it as "
                "boundary.clamp_kt (>= 1, for the clamp as built) to judge the clamp's "
                f"stress ({_num(stress)} MPa on Kt 1) with it (docs/beam.md)",
            )
        if stress is None:
            return self.missing(self.bound_text())
        value = self.clamp_kt * stress
        margin = self.allowable_MPa - value
        return Verdict(
            self.label, self.quantity, value, self.bound_text(), margin,
            margin / self.allowable_MPa, margin >= 0, "MPa", self.role,
            f"stated clamp_kt {self.clamp_kt:g} x the beam's stress at {self.where} "
            f"{stress:.4g} MPa",
        )  # fmt: skip


def _value_of(metrics: Any, quantity: str) -> float | None:
    """``metrics[quantity]`` as a finite float, else None (missing, text or not finite)."""
    value = metrics.get(quantity)
    if value is None or isinstance(value, str | bool):
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def _num(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.4g}"


def clamp_rows(study: Any, yield_MPa: float) -> list[Requirement]:
    """The row of a polyline beam's clamps as made, or none when nothing is clamped."""
    boundary = study.boundary
    nodes = clamped_nodes(boundary.start, boundary.end.rotation)
    if not nodes:
        return []
    where = " and ".join({"start": "the start", "end": "the end (its rotation fixed)"}[k]
                         for k in nodes)  # fmt: skip
    kt = getattr(boundary, "clamp_kt", None)
    return [ClampAsMade(allowable_MPa=float(yield_MPa), clamp_kt=kt, where=where)]
