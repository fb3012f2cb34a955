"""How slender a polyline beam must be for the beam model's figures (#27, session 27).

The beam model (fea/beam.py: geometrically exact, shear-deformable, k = 5/6) reads a strip as
its centreline with a section. Plane stress of the same strip (fea/plane_stress.py, P2, ideal
clamp at the start, the end driven as a rigid edge) gives what the strip does as a 2D solid.
Measured (tests/pipeline/test_polyline_slenderness.py, ABS, t = 2 mm, 1e-4 L of transverse
end motion, linear; plane stress at t/8 elements, within 0.25 % of t/4): the beam's transverse
stiffness against plane stress, the end's rotation held (clamped-guided) and free (cantilever,
the end driven at its mid-thickness node):

========  ===================  ============
L / t     clamped-guided       cantilever
========  ===================  ============
2         -2.73 %              +2.80 %
3         -1.87 %              +0.45 %
4         -1.39 %              -0.07 %
5         -1.09 %              -0.21 %
6         -0.90 %              -0.24 %
8         -0.66 %              -0.23 %
10        -0.52 %              -0.21 %
20        -0.25 %              -0.11 %
========  ===================  ============

(measured 2026-12-06 21:08 UTC, load average ~2, by the test's ``beam_stiffness`` and
``plane_stress_stiffness`` at each L/t; the cantilever by the same with the end driven at the
node (L, 0)). The surface stress at
mid-span of the cantilever matches M c / I within 0.2 % at every L/t (Saint-Venant: away from
the ends the beam's stress is the elastic one). What grows as the strip gets stubby is the end
zones, each about one thickness long, where the stress is not M c / I (at a sharp clamp it is
unbounded): at L/t = 2 the two zones are the whole strip and the beam's peak, taken at the
ends, is a figure of no section that follows beam theory.

The bound: **L/t >= 6**, L the centreline's arc length and t its largest thickness: the
stiffness within 1 % of plane stress for either end condition, and at least four thicknesses
of span outside the two end zones. Below it the row "slender enough for the beam model" is NOT
MET with the reason, so the verdict is NOT MET. Why the whole beam and not each segment: a
segment is a stretch of one continuous beam (a finely drawn curve has segments shorter than
its thickness), and the beam model's error is set by the span between the ends.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from flexopt.optimise.requirements import MinValue, Verdict

__all__ = ["MIN_SLENDERNESS", "SLENDERNESS", "SLENDER_ROW", "Slenderness", "slenderness_ratio"]

#: the least L/t the polyline beam's figures are judged at (see the module docstring)
MIN_SLENDERNESS = 6.0

#: the summary's key: arc length over the largest thickness
SLENDERNESS = "slenderness_ratio"

#: the row's name (the mechanism kind adds the member's name in brackets)
SLENDER_ROW = "slender enough for the beam model"

#: what a polyline beam's user can do below the bound
_POLYLINE_FIX = "(docs/usage.md, polyline_beam); judge the strip in plane stress or lengthen it"


def slenderness_ratio(length_mm: float, thickness_mm: Any) -> float:
    """L/t: the centreline's arc length ``length_mm`` (mm) over the largest of ``thickness_mm``
    ((n_points,) mm)."""
    return float(length_mm) / max(float(t) for t in thickness_mm)


@dataclass(frozen=True)
class Slenderness(MinValue):
    """``slenderness_ratio >= MIN_SLENDERNESS``; NOT MET says why the figures do not hold.

    The one place of the bound and its reason: the ``polyline_beam`` kind judges its strip
    with the defaults, the ``mechanism`` kind each beam (``quantity`` and ``name`` naming the
    member, ``fix`` its way out; pipeline/studies/_mechanism_slenderness.py)."""

    quantity: str = SLENDERNESS
    name: str = SLENDER_ROW
    minimum: float = MIN_SLENDERNESS
    #: the docs to read and what to change, appended to the reason
    fix: str = _POLYLINE_FIX

    def check(self, metrics: Any, curves: Any = None) -> Verdict:
        from dataclasses import replace

        verdict = super().check(metrics, curves)
        if verdict.met or verdict.value != verdict.value:  # met, or not computed (NaN)
            return verdict
        why = (
            f"L/t = {verdict.value:.3g} below {MIN_SLENDERNESS:g}: the beam's end zones (about "
            "one thickness each, where the stress is not M c / I) cover most of the strip, so "
            f"its peak stress and stiffness are not the part's {self.fix}"
        )
        return replace(verdict, detail=why)
