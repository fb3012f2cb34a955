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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from flexopt.optimise.requirements import AllowableStress, Verdict
from flexopt.pipeline.stroke_verdict import UNBOUNDED_STRESS

__all__ = ["FILLET_KEY", "SHARP_ROOTS", "SHARP_ROOT_TYPES", "RootStress", "sharp"]

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


def sharp(kind: str, study: Any) -> bool:
    """Whether a design of type ``kind`` in ``study`` (a flexure_pivot study) is exported with
    sharp roots: a leaf type with ``geometry.leaf_root_fillet_mm`` 0."""
    return kind in SHARP_ROOT_TYPES and not study.geometry.leaf_root_fillet_mm > 0


@dataclass(frozen=True)
class RootStress(AllowableStress):
    """The allowable stress of a pivot (MPa): NOT MET for a design of a type with sharp roots
    (:data:`SHARP_ROOT_TYPES`; the flag ``unbounded_stress`` the kind's result sets), with
    :data:`SHARP_ROOTS` as its detail and no margin (the stress at the roots is not computed);
    else :class:`AllowableStress`'s verdict."""

    def check(self, metrics: Any, curves: Any = None) -> Verdict:
        verdict = super().check(metrics, curves)
        if not metrics.get(UNBOUNDED_STRESS):
            return verdict
        detail = "; ".join(filter(None, (verdict.detail, SHARP_ROOTS)))
        return replace(
            verdict,
            bound=f"{verdict.bound} (leaf roots sharp: not bounded by the model)",
            margin=math.nan,
            margin_rel=None,
            met=False,
            detail=detail,
        )
