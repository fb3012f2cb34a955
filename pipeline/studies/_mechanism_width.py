"""The ``mechanism`` kind's out-of-plane width key (``StudyKind.width_key``, ``flexopt retrim``).

Every force, moment and stiffness of the beam model is proportional to the shared width
``geometry.width_mm`` at a given in-plane motion (each section's A and I scale with it; a stop's
penalty follows the beams' stiffness to ~1e-7), and so is the plane-stress check's (its sheet is
that thick, its stresses do not move). A written width is therefore the exact re-trim key of a
study, except where one of these breaks the proportion:

- ``solve_width_from``: the width is solved from a requirement; a written value is replaced;
- a beam with its own ``width_mm``: the shared width does not reach it;
- the 3D solid check judging a figure: its force ratio to the beam model moves with the width
  (the anticlastic and edge effects of a wider section; docs/mechanism.md), so a scaled width
  does not scale the judged force exactly. It judges unless ``fidelity.enabled`` is false,
  ``fidelity.solid`` is ``never`` or the study has ``stops`` (the check is skipped there). With
  ``solid: auto`` it runs from a width of three times the thinnest beam, which a re-trim may
  cross, so ``auto`` counts as judging.

Under a force- or moment-driven load case the rows are at given loads: the load-motion path
scales (what a re-trim compares), not the rows (docs/print_to_part.md, section 4).
"""

from __future__ import annotations

from typing import Any

__all__ = ["WIDTH_KEY", "width_key"]

#: the shared out-of-plane width, mm
WIDTH_KEY = "geometry.width_mm"


def width_key(study: Any) -> str | None:
    """``geometry.width_mm`` where every force of the study is proportional to it, else None
    (module docstring)."""
    if study.solve_width_from is not None:
        return None
    if any(beam.width_mm is not None for beam in study.geometry.beams.values()):
        return None
    fidelity = study.fidelity
    judged_in_3d = fidelity.enabled and fidelity.solid != "never" and study.stops is None
    return None if judged_in_3d else WIDTH_KEY
