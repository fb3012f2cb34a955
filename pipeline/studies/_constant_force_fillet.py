"""The stress at the constant-force beam's pad fillets: the shoulder's Kt times the beam's stress
over each fillet's flare (docs/constant_force.md, "Fillets at the pads").

Why: with fillets drawn (:func:`geometry.constant_force.filleted_beam`) the beam model carries
the flare as a thickening beam, whose stress at the fillet's toe is the nominal stress of the
shoulder; the concentration on the arc is the fit's Kt times it (as the mechanism kind's roots,
fea/mechanism_design.py ``as_made_stress``). Not wired into the study yet: no
``pad_fillet_mm`` key (the next step, in the docs); ``benchmarks/pad_fillet.py`` reads it.
"""

from __future__ import annotations

import numpy as np
from flexopt.fea.beam_statics import StaticsStress
from flexopt.geometry.mechanism import AsMadeBeam

__all__ = ["root_stress_MPa"]


def root_stress_MPa(made: AsMadeBeam, stress: StaticsStress) -> np.ndarray:
    """(R,) MPa: per row, the larger over the two ends of Kt times the largest ``|axial| +
    |bending|`` (``stress``: (R, S) MPa at arc lengths ``s_mm`` (S,) mm) over that end's flare
    (``s <= root_mm`` from S1, ``s >= L - root_mm`` from S6); 0 where an end has no fillet.
    ``made`` is the beam ``stress`` was computed on (its ``start`` / ``end`` junctions)."""
    sigma = np.abs(stress.axial_MPa) + np.abs(stress.bending_MPa)
    s = np.asarray(stress.s_mm, dtype=float)
    total = float(s[-1])
    out = np.zeros(sigma.shape[0])
    # 1e-9 mm: the toe is a node (a sampling point) of the flared beam
    for end, near in (
        (made.start, s <= made.start.root_mm + 1e-9),
        (made.end, s >= total - made.end.root_mm - 1e-9),
    ):
        if end.root_mm > 0:
            out = np.fmax(out, end.kt * np.max(sigma[:, near], axis=1))
    return out
