"""The ``flexure_pivot`` kind's peak-stress requirement and its sharp leaf roots (#22 class).

A ``leaf`` or ``variable_leaf`` pivot as exported (``Leaf.outline``, its STL) meets each block
in two sharp 90° steps. No figure of the kind bounds the stress there:

* the beam model and the closed form give the leaf's nominal stress (Kt = 1 for leaves);
* the plane-stress check leaves the elements touching the blocks out of its peak (their corners
  are singular in 2D elasticity, fea/pivot.py), and the peak next to them still rises without
  bound under refinement. The flexure-pivot leaf (PETG, 25 x 2.15 mm, 6 mm wide), turned 2°
  linearly, element edge at the roots t/4, t/8, t/16, t/32 of the thickness: 2.2477, 2.2512,
  2.6311, ... MPa against 6 M / (b t²) = 2.2515 MPa; a corner-filleted hinge of the same web
  (r = 1.5 mm) reads 2.797, 2.790, 2.793, 2.793 MPa (tests/pipeline/test_pivot_sharp_roots.py,
  docs/flexures.md "Sharp leaf roots").

So a design of those types is NOT MET on the peak-stress row, with the reason: the part as
exported has a stress the run did not compute; for the same reason its fatigue life is not
computed (the summary flag ``unbounded_stress``, pipeline/stroke_verdict.py: its life rows NOT
MET with that reason). Not a refusal: the design can still be
evaluated, its nominal figure is shown.

The way out is the key ``geometry.leaf_root_fillet_mm`` (:data:`FILLET_KEY`, default 1 mm):
the outline rounds each root with a fillet of that radius (``Leaf.root_fillet_mm``), the beam
carries the fillets' flare, and its stress is multiplied by the roots' shoulder Kt
(``Leaf.root_kt``, geometry/mechanism.py ``shoulder_kt``), so the GA's constraint, the
verdict, the life and best.vtu read Kt x nominal; the plane-stress check counts the root
elements (a fillet's stress converges under refinement, tests/pipeline/test_pivot_root_fillet.py).
Only ``leaf_root_fillet_mm: 0`` (sharp) keeps the NOT MET rule above.

A ``cross_axis`` pivot (issue 27, session 27) is NOT MET the same way, whatever the fillet key
says, with its own reason (:data:`CROSS_AXIS`): its leaves meet the block faces at the half
angle (45°: an acute and an obtuse corner at each root), for which the shoulder fit of the
leaves (a 90° step) gives no Kt, and no part of it is exported at all: its leaves pass each
other in separate layers, which the planar outline does not draw, so no STL is written and no
plane-stress check is made. So its stiffness band and envelope rows are NOT MET too (the flag
``part_not_exported``, :data:`NO_PART`; :class:`PartRange`, :class:`PartMax`): they would
judge the beam model of a part of which no file is written. In the GA such a design (and a
sharp-rooted leaf) violates the stress constraint (:func:`ga_stress_row`), so a run picks it
only when no design meets every constraint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from flexopt.optimise.requirements import AllowableStress, MaxValue, Range, Verdict
from flexopt.pipeline.stroke_verdict import UNBOUNDED_STRESS

__all__ = [
    "CROSS_AXIS",
    "FILLET_KEY",
    "NO_PART",
    "NO_PART_TYPES",
    "SHARP_ROOTS",
    "SHARP_ROOT_TYPES",
    "PartMax",
    "PartRange",
    "RootStress",
    "ga_stress_row",
    "no_part",
    "sharp",
]

#: the description of ``geometry.leaf_root_fillet_mm``
FILLET_KEY = (
    "fillet radius where a leaf / variable_leaf meets each block, mm (0: sharp roots, whose "
    "stress is not bounded: the peak-stress row NOT MET); its shoulder Kt multiplies the stress"
)

#: the pivot types whose exported outline meets the blocks in sharp corners (geometry/flexures.py
#: ``Leaf.outline``, which ``VariableLeaf`` inherits)
SHARP_ROOT_TYPES = ("leaf", "variable_leaf")

#: the peak-stress row's word on a design of those types
SHARP_ROOTS = (
    "leaf roots sharp: the leaf meets its blocks in 90° steps, whose stress no figure of this "
    "kind bounds (the beam and closed form have no Kt there, the plane-stress check leaves the "
    "root elements out and rises without bound under refinement at them); the figure shown is "
    "the nominal stress away from the roots; give geometry.leaf_root_fillet_mm > 0 (root "
    "fillets, their Kt modelled) or use type corner_filleted"
)


#: the pivot types of which no part is exported (their outline is a projection, not the part)
NO_PART_TYPES = ("cross_axis",)

#: the summary flag of a design of which no part is exported
NO_PART = "part_not_exported"

#: the peak-stress row's word on a cross_axis design
CROSS_AXIS = (
    "cross_axis: no part is exported (its leaves pass each other in separate layers, which the "
    "planar outline does not draw: no STL is written, no plane-stress check is made) and its "
    "leaves meet the blocks at the half angle in sharp corners (an acute and an obtuse one at "
    "each root), for which no Kt is modelled (the leaves' shoulder fit is for a 90° step); the "
    "figure shown is the beam's nominal stress; use a planar type (leaf, variable_leaf with "
    "root fillets, or a notch hinge)"
)

#: the other rows' word on a design of which no part is exported
NO_PART_ROW = (
    "no part is exported for a cross_axis design (its leaves cross in separate layers, which "
    "the planar outline does not draw): the figure is the beam model's of a part of which no "
    "file is written"
)


def sharp(kind: str, study: Any) -> bool:
    """Whether a design of type ``kind`` in ``study`` (a flexure_pivot study) has a stress no
    figure of the kind bounds: a leaf type with ``geometry.leaf_root_fillet_mm`` 0 (sharp
    roots), or a cross_axis pivot (oblique sharp roots, no part exported: :data:`CROSS_AXIS`)."""
    if kind in NO_PART_TYPES:
        return True
    return kind in SHARP_ROOT_TYPES and not study.geometry.leaf_root_fillet_mm > 0


def no_part(kind: str) -> bool:
    """Whether no part is exported for a design of type ``kind`` (:data:`NO_PART_TYPES`)."""
    return kind in NO_PART_TYPES


def ga_stress_row(kind: str, study: Any, g: np.ndarray, index: int) -> np.ndarray:
    """The GA's constraints ``g`` (n_con,) with the stress row ``g[index]`` violated (at least
    1, i.e. twice the allowable) for a design whose stress the kind does not bound
    (:func:`sharp`): the verdict's peak-stress row of such a design is NOT MET whatever its
    nominal stress, so the GA must not count it feasible. Unchanged otherwise."""
    if not sharp(kind, study):
        return g
    g = np.array(g, dtype=float)
    g[index] = max(float(g[index]), 1.0)
    return g


def _no_part_verdict(verdict: Verdict, metrics: Any) -> Verdict:
    if not metrics.get(NO_PART):
        return verdict
    detail = "; ".join(filter(None, (verdict.detail, NO_PART_ROW)))
    return replace(verdict, met=False, margin=math.nan, margin_rel=None, detail=detail)


@dataclass(frozen=True)
class PartRange(Range):
    """:class:`Range`, NOT MET (with :data:`NO_PART_ROW`) for a design of which no part is
    exported (the summary flag :data:`NO_PART`)."""

    def check(self, metrics: Any, curves: Any = None) -> Verdict:
        return _no_part_verdict(super().check(metrics, curves), metrics)


@dataclass(frozen=True)
class PartMax(MaxValue):
    """:class:`MaxValue`, NOT MET (with :data:`NO_PART_ROW`) for a design of which no part is
    exported (the summary flag :data:`NO_PART`)."""

    def check(self, metrics: Any, curves: Any = None) -> Verdict:
        return _no_part_verdict(super().check(metrics, curves), metrics)


@dataclass(frozen=True)
class RootStress(AllowableStress):
    """The allowable stress of a pivot (MPa): NOT MET for a design of a type with sharp roots
    (:data:`SHARP_ROOT_TYPES` without fillets, or cross_axis; the flag ``unbounded_stress`` the
    kind's result sets), with :data:`SHARP_ROOTS` (:data:`CROSS_AXIS`) as its detail and no
    margin (the stress at the roots is not computed); else :class:`AllowableStress`'s verdict."""

    def check(self, metrics: Any, curves: Any = None) -> Verdict:
        verdict = super().check(metrics, curves)
        if not metrics.get(UNBOUNDED_STRESS):
            return verdict
        cross = bool(metrics.get(NO_PART))  # a cross_axis design (the flag its result sets)
        detail = "; ".join(filter(None, (verdict.detail, CROSS_AXIS if cross else SHARP_ROOTS)))
        why = "cross_axis: no part, roots" if cross else "leaf roots"
        return replace(
            verdict,
            bound=f"{verdict.bound} ({why} sharp: not bounded by the model)",
            margin=math.nan,
            margin_rel=None,
            met=False,
            detail=detail,
        )
