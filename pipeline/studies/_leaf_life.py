"""The ``leaf_spring_joint`` kind's fatigue life (issue 25): a duty cycle whose levels name the
stiffness setting they run at.

A variable-stiffness joint has no one peak stress per deflection: each stiffness setting (the
support's place, so the leaf's free length) is its own nonlinear solve with its own leaf
stress. The kind therefore names its settings' stress columns in the result's
``info["stress_settings"]`` (:data:`optimise.durability.STRESS_SETTINGS`), and the life
(:func:`pipeline.verdict.life_of_settings`) takes each level's stress from its setting's solve;
the levels that name none run at the **worst** setting (the largest damage per block), named in
the verdict's life rows and the report.

Settings, by name (``duty_cycle.levels[i].setting`` or ``duty_cycle.setting``):

* ``flexopt run`` (a design's two settings, :meth:`LeafJointProblem.detail`): ``stiff`` (alias
  ``lmin``: the shortest free length l_min, the top of the stiffness range) and ``soft``
  (``lmax``: l_max, the bottom). Columns ``stress_MPa_lmin`` / ``stress_MPa_lmax``.
* ``flexopt evaluate`` (every analysed curve, :func:`leaf_spring_joint._analyse`): each curve
  ``<structure>_l<l>`` (``sliding_l28``), and ``stiff`` / ``soft`` for the shortest / longest
  effective length of ``target.structure`` (of the first structure analysed when the target's
  is not among them). Columns ``stress_MPa_<curve>``.

The drives are the joint deflection (``deflection_deg``, the kind's plot x), within the traced
stroke of the mode (``boundary.max_deflection_deg`` in evaluate, ``target.max_deflection_deg``
in a run); ``fraction`` is of that stroke. Units: deg, MPa. docs/durability.md.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from flexopt.optimise.durability import STRESS_SETTINGS
from flexopt.pipeline.errors import StudyError

__all__ = ["DESIGN_SETTINGS", "analysis_info", "check", "design_info"]

#: The settings of a run's design, by name -> its stress column (aliases share a column).
DESIGN_SETTINGS = {
    "stiff": "stress_MPa_lmin",
    "soft": "stress_MPa_lmax",
    "lmin": "stress_MPa_lmin",
    "lmax": "stress_MPa_lmax",
}


def _analysis_settings(study: Any, curves: Iterable[str]) -> dict[str, str]:
    """``stiff`` / ``soft`` and every curve of ``flexopt evaluate`` -> its stress column."""
    g = study.geometry
    structure = study.target.structure if study.target.structure in g.structures else None
    structure = structure or g.structures[0]
    lengths = sorted(g.effective_lengths_mm)
    out = {
        "stiff": f"stress_MPa_{structure}_l{lengths[0]:g}",
        "soft": f"stress_MPa_{structure}_l{lengths[-1]:g}",
    }
    out.update({name: f"stress_MPa_{name}" for name in curves})
    return out


def _curves(study: Any) -> list[str]:
    g = study.geometry
    return [f"{s}_l{l:g}" for s in g.structures for l in g.effective_lengths_mm]


def analysis_info(study: Any, curves: Iterable[str]) -> dict[str, Any]:
    """The ``info`` entry of ``flexopt evaluate``'s result naming its settings' stress columns
    (empty without ``duty_cycle:``, so that a study without one writes what it did)."""
    if getattr(study, "duty_cycle", None) is None:
        return {}
    return {STRESS_SETTINGS: _analysis_settings(study, curves)}


def design_info(study: Any) -> dict[str, Any]:
    """The ``info`` entry of a run's design naming its two settings' stress columns (empty
    without ``duty_cycle:``)."""
    if getattr(study, "duty_cycle", None) is None:
        return {}
    return {STRESS_SETTINGS: dict(DESIGN_SETTINGS)}


def check(study: Any) -> None:
    """Refuse a duty-cycle setting the joint does not have, at load time.

    Raises
    ------
    StudyError
        At ``duty_cycle.levels[i].setting`` (or ``duty_cycle.setting``), naming the settings.
    """
    spec = getattr(study, "duty_cycle", None)
    if spec is None:
        return
    known = [*DESIGN_SETTINGS, *_curves(study)]
    named = [("duty_cycle.setting", spec.setting)]
    named += [
        (f"duty_cycle.levels[{i}].setting", lv.setting) for i, lv in enumerate(spec.levels or ())
    ]
    for path, name in named:
        if name is not None and name not in known:
            raise StudyError(
                path,
                f"'{name}' is no setting of this joint; use stiff or soft (a run's l_min / "
                f"l_max, and in flexopt evaluate the target structure's shortest / longest "
                f"length) or a curve of flexopt evaluate: {', '.join(_curves(study))}",
            )
