"""The peak stress a constant-force verdict judges: the plane-stress check's and the beam's at
the pads, whichever is larger (docs/constant_force.md, "Stress at the clamp").

Why both: the plane-stress check leaves out the elements touching the pads (the exported part
has sharp re-entrant corners where the beam meets a pad, singular in 2D elasticity: their stress
grows without bound under mesh refinement), so it does not see the clamp section, where a
tapered design's peak stress can sit. The beam's stress from statics (fea/beam_statics.py) sees
the clamp section's nominal stress N/A + M c/I, converged at the study's mesh. Judging the
larger of the two never calls a design MET on a figure that left its peak out; what neither
sees (the concentration at the sharp corner itself, a nominal-stress figure is not) is said in
the docs; the model name says which figures were compared.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from flexopt.optimise.curve_objectives import plane_stress_peak_figures

#: the fidelity record's key of the peak re-solved on a refined mesh (_constant_force_kinks.py)
REFINED_PEAK = "plane_stress_refined_peak_MPa"

__all__ = ["CHECKED_PEAK", "CHECKED_PEAK_MODEL", "REFINED_PEAK", "checked_peak_figures"]

#: the metric the verdict's peak-stress row judges when a plane-stress check ran (MPa)
CHECKED_PEAK = "checked_peak_stress_MPa"

#: the model name the verdict shows for it: what it covers and what it does not
CHECKED_PEAK_MODEL = "plane stress and the beam's nominal stress at the pads"


def checked_peak_figures(check: Mapping[str, Any], beam_peak_MPa: Any) -> dict[str, Any]:
    """The plane-stress figures of ``check`` (a fidelity-check record) and, when there is one,
    ``checked_peak_stress_MPa`` = max(its peak, the refined re-solve's peak
    ``plane_stress_refined_peak_MPa`` when the record has one, the beam's peak over the drive):
    ``beam_peak_MPa`` is the beam response's ``peak_stress_MPa`` (rows,) MPa, from statics (NaN
    rows ignored). ``plane_stress_peak_stress_MPa`` is the larger of the two plane-stress
    figures."""
    out = plane_stress_peak_figures(check)
    if "plane_stress_peak_stress_MPa" in out:
        beam = float(np.nanmax(np.asarray(beam_peak_MPa, dtype=float)))
        # the peak's row re-solved on a locally refined mesh (_constant_force_kinks.py): the
        # larger one, so a peak not converged at the study's mesh is not judged on the lower
        refined = check.get(REFINED_PEAK)
        if refined is not None and np.isfinite(refined):
            out[REFINED_PEAK] = float(refined)
            out["plane_stress_peak_stress_MPa"] = max(out["plane_stress_peak_stress_MPa"], refined)
        out[CHECKED_PEAK] = max(out["plane_stress_peak_stress_MPa"], beam)
    return out
