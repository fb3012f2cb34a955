"""The leaf joint's support as made (#27, session 27): the row "peak stress at the support as
made".

The leaf is a beam clamped ideally at the movable support O' (fea/leaf_joint.py: theta(0) = 0,
the section square to the support, Kt 1), and its peak stress is there, at the root of the
free length (the largest moment of a tip-loaded leaf). The part as made is a strip held in a
support whose edge is a corner: the bending stress at a clamp's edge is raised by the edge's
contact (the clamp pressure, the edge's radius) and fretting, which the model does not see.
The shipped joint's peak stress at its stiffest setting is 772.1 MPa of 785 MPa (1.6 % to
spare), so any concentration above x1.016 would take it past the yield.

Decision: a study states the support edge's stress-concentration factor,
``geometry.support_kt`` (>= 1; from a test or a handbook for the clamp as built); the row then
judges ``support_kt x peak_stress_MPa <= allowable``. Without it the row is NOT MET with the
reason: the figure the verdict would stand on is the ideal clamp's. The row is a check (the
optimiser's stress constraint stays the beam's; a run with ``support_kt`` finds the same
design and judges it with the factor).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from flexopt.optimise.requirements import Requirement, Verdict

__all__ = ["SUPPORT_ROW", "SupportAsMade", "support_rows"]

#: the row's name
SUPPORT_ROW = "peak stress at the support as made"


@dataclass(frozen=True)
class SupportAsMade(Requirement):
    """``support_kt x peak_stress_MPa <= allowable_MPa`` (MPa); NOT MET with the reason when
    ``support_kt`` is None."""

    quantity: str = "support_peak_stress_MPa"
    name: str = SUPPORT_ROW
    allowable_MPa: float = math.inf
    support_kt: float | None = None

    def bound_text(self) -> str:
        return f"<= {self.allowable_MPa:g} MPa"

    def scale(self) -> float:
        return self.allowable_MPa

    def check(self, metrics: Any, curves: Any = None) -> Verdict:
        peak = _value_of(metrics, "peak_stress_MPa")
        if self.support_kt is None:
            return self.missing(
                self.bound_text(),
                "the support clamps the leaf ideally in the model (Kt 1), but the part as made "
                "has the support's edge there, whose stress concentration the model does not "
                "see; state it as geometry.support_kt (>= 1, for the clamp as built) to judge "
                f"the peak ({_num(peak)} MPa on Kt 1) with it (docs/leaf_joint.md)",
            )
        if peak is None:
            return self.missing(self.bound_text())
        value = self.support_kt * peak
        margin = self.allowable_MPa - value
        return Verdict(
            self.label, self.quantity, value, self.bound_text(), margin,
            margin / self.allowable_MPa, margin >= 0, "MPa", self.role,
            f"stated support_kt {self.support_kt:g} x the beam's peak {peak:.4g} MPa",
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


def support_rows(study: Any, allowable_MPa: float) -> list[Requirement]:
    """The row of the leaf joint's support as made (see the module docstring)."""
    kt = getattr(study.geometry, "support_kt", None)
    return [SupportAsMade(allowable_MPa=float(allowable_MPa), support_kt=kt)]
