"""A mechanism's beams as best.vtu draws them: every beam's centreline per load step with its
section and outer-fibre stresses (issue #26 item 5).

The mechanism engine keeps each beam's model and its nodes' rotations per row
(:attr:`fea.mechanism.MechanismResponse.rotations_rad`, ``beam_models``); the stresses are
:func:`fea.beam_fields.section_field` of them, the solver's own samples, so each row's largest
node value over a beam is that beam's ``peak_stress_MPa`` in the response. The beams are joined
one after another in the mechanism's beam order with one NaN node between two beams
(:func:`fea.beam_fields.members_field`). The rigid bodies are not drawn (they carry no stress
in the model).

What the verdict reads can be more than the beams' largest node value, and the file says so:
the mechanism kind's ``peak_stress_MPa`` column is, per row, the larger of the beam model's peak
and each filleted root's K_t times the stress over its flare (fea/mechanism_design.py
``as_made_stress``), and with a plane-stress check that as-made peak times the check's ratio to
it where the ratio is above 1 (pipeline/studies/_mechanism_fidelity.py). The column itself is
in the file's field data per load step (``per load step: peak_stress_MPa``).

Units: mm, MPa, rad.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from flexopt.fea.beam import BeamModel
from flexopt.fea.beam_fields import Members, join_members, members_field

__all__ = ["VERDICT_NOTE", "as_made_factors", "mechanism_vtu", "solved_vtu"]

#: What the kind's verdict reads beside the nodes' stresses (field data of best.vtu).
VERDICT_NOTE = (
    "stress_judged_MPa is von_mises_MPa times a filleted root's K_t over its flare, times the "
    "fidelity check's peak-stress ratio to the as-made peak where above 1 (1 without); its "
    "largest value per load step is the verdict's peak_stress_MPa (field data: per load step)"
)


def solved_vtu(solved: Any, case: str) -> dict[str, Any]:
    """:func:`mechanism_vtu` of load case ``case`` of the mechanism kind's solved design
    (pipeline/studies/_mechanism_result.py ``Solved``: its ``responses``, ``width_mm``,
    ``outline.beams`` and, with a fidelity check, the stress ratio the verdict applied to that
    case, ``fidelity["applied"][case]["stress_ratio_reported"]``)."""
    applied = ((getattr(solved, "fidelity", None) or {}).get("applied") or {}).get(case) or {}
    out = mechanism_vtu(
        solved.responses[case],
        solved.width_mm,
        solved.outline.beams,
        applied.get("stress_ratio_reported"),
    )
    field_map = getattr(solved, "field_map", None)  # the check's plane-stress triangles
    return {**out, "field_map": field_map} if field_map else out


def mechanism_vtu(
    response: Any,
    width_mm: float | None = None,
    made: Mapping[str, Any] | None = None,
    check_ratio: float | None = None,
) -> dict[str, Any]:
    """DesignResult keywords for best.vtu of a mechanism's load case: ``shapes_mm`` (n_rows,
    N, 2) mm, its beams joined (N = the beams' nodes plus one NaN node between two beams), and
    ``beam_field`` (:func:`fea.beam_fields.members_field`: the section per node and segment,
    the signed fibre stresses and the equivalent stress per node and row, MPa, the member index
    per segment; and ``as_made_MPa`` (n_rows, N) MPa, :func:`as_made_nodes`). Empty when
    ``response`` (a :class:`fea.mechanism.MechanismResponse`) kept no models (a stand-in) or
    has no beam.

    ``width_mm`` : the part's out-of-plane width as made (mm) where the kind rescaled it after
    the solve (the stresses under a prescribed motion do not depend on the width).
    ``made`` : the beams as made (``geometry.mechanism.MechanismOutline.beams``, in the
    mechanism's beam order), whose filleted ends carry a K_t; None: every factor 1.
    ``check_ratio`` : the fidelity check's peak-stress ratio to the beam model's (no unit),
    which the verdict applies to the beam's peak at every row where it gives more; None: none.
    """
    models = tuple(getattr(response, "beam_models", ()) or ())
    if not models:
        return {}
    shapes = tuple(np.asarray(s, dtype=float) for s in response.shapes_mm)
    members = Members(models, shapes, tuple(response.rotations_rad))
    field = members_field(members, width_mm)
    assert field is not None
    factors = join_members(
        [f[None] for f in as_made_factors(models, made, getattr(response, "beam_roots_mm", None))]
    )[0]
    if check_ratio is not None and np.isfinite(check_ratio):
        # the verdict's as-made peak x max(1, ratio) per row (the ratio is the check's to the
        # as-made peak) is the largest node value of the as-made stress times that same factor
        factors = factors * max(1.0, float(check_ratio))
        field["check_stress_ratio"] = float(check_ratio)
    field["as_made_MPa"] = field["equivalent_MPa"] * factors
    field["notes"] = (VERDICT_NOTE,)
    return {"shapes_mm": join_members(shapes), "beam_field": field}


def as_made_factors(
    models: Sequence[BeamModel],
    made: Mapping[str, Any] | None,
    roots_mm: Sequence[tuple[float, float]] | None = None,
) -> list[np.ndarray]:
    """Per beam (n_nodes_i,) the factor the kind's verdict multiplies the beam-model stress at
    each node by (fea/mechanism_design.py ``as_made_stress``): the end's K_t (``made``) at the
    nodes within the root the solver took that end's root stress over (``roots_mm``: per beam
    (start, end) arc length from that end, mm, as solved,
    :attr:`fea.mechanism.MechanismResponse.beam_roots_mm`; None: the ends' ``root_mm`` as
    made), else 1. The solver's root stress is the largest sample within the root
    (fea/mechanism.py root_stresses) and the samples sit on the nodes, so the largest node value
    of equivalent x factor is the as-made peak the verdict reads."""
    out = [np.ones(m.n_nodes) for m in models]
    if made is None or len(made) != len(models):
        return out
    if not roots_mm or len(roots_mm) != len(models):
        roots_mm = [(b.start.root_mm, b.end.root_mm) for b in made.values()]
    for f, m, beam, root in zip(out, models, made.values(), roots_mm, strict=True):
        s = np.asarray(m.s_nodes, dtype=float)
        length = float(m.profile.length_mm)
        start = s <= float(root[0]) + 1e-9  # the tolerance root_stresses uses
        end = s >= length - float(root[1]) - 1e-9
        f[start] = np.maximum(f[start], float(beam.start.kt))
        f[end] = np.maximum(f[end], float(beam.end.kt))
    return out
