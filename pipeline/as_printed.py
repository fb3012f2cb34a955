"""The part as made: a calibrated material's thickness offset applied to every printed section.

``flexopt calibrate`` measures how much thicker (or thinner) a printer lays a wall than it is
drawn, ``dt`` (mm), and writes it into the material (``thickness_offset_mm``, issue #26). A study
whose material carries it is analysed as printed: every model of every kind (beam, plane stress,
3D solid, closed forms) sees each printed section at its drawn thickness plus ``dt``. The drawing
does not change: the design vector, the study, the run's best design and every exported file
(STL, DXF, STEP, the outline of the report) stay as drawn, because that is what is sent to the
printer.

One place for every kind
------------------------
:func:`pipeline.problems.kind_problem` and :func:`pipeline.problems.study_result` hand a study
with an offset to this module. It moves the same numbers a print-scatter sample of
``robustness:`` moves by its thickness delta (:mod:`pipeline.robustness`), with ``dt`` as the
delta and nothing else changed:

- in the **study**: every number under a key ending in ``thickness_mm`` outside
  ``design_space``, ``requirements``, ``optimiser``, ``parallel`` and ``robustness``, and the
  printable minimum ``min_feature_mm``: it is a rule on the drawing (every wall at least two
  extrusion lines as drawn), so it moves with the print and a printable drawing stays printable
  as printed, neither more nor less; with it the bounds of a ``design_space`` entry ending in
  ``thickness_mm`` (a kind checks them against the minimum), while the design vector's space
  stays the drawn one; not a key that is no wall in the bed plane (:data:`OUT_OF_PLANE_KEYS`:
  a cam plate's thickness is its print height);
- in the **design vector**: the problem's own
  :meth:`~optimise.problem.DesignProblem.scatter_design` when it has one (constant_force: t1..t10,
  T1, T6); else each variable that sets a ``*thickness_mm`` key (variables on key paths), else
  each variable whose name contains ``thickness``.

A kind whose problem solves another study with its material (:data:`LINKED_KINDS`: the
gripper, whose beam is the constant-force study it resolves) is not moved here: its problem is
built from the calibrated study as it is, its linked study inherits the material with the offset
and is analysed as printed by this module in turn (the gripper's width ``B`` is then rescaled to
the target from the printed beam's plateau, so the drawing holds the force as printed).

The result records what moved (``info["as printed"]``) and the offset (``summary
["thickness_offset_mm"]``); every verdict's ``detail`` says the design was judged as printed
(:func:`pipeline.verdict.judge_result`, :func:`pipeline.materials_file.with_as_printed_verdicts`).

Units: mm.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignProblem, DesignResult, ProblemWrapper
from flexopt.optimise.variables import DesignVariables
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.materials_file import thickness_offset_mm
from flexopt.pipeline.study import Study, validate_study

__all__ = [
    "AS_PRINTED_INFO",
    "LINKED_KINDS",
    "OFFSET_SUMMARY_KEY",
    "AsPrintedProblem",
    "as_printed_evaluate",
    "as_printed_problem",
    "printed_design",
    "printed_study",
]

#: the result's ``info`` entry that says what the offset moved
AS_PRINTED_INFO = "as printed"
#: the result's ``summary`` key of the offset applied, mm
OFFSET_SUMMARY_KEY = "thickness_offset_mm"

#: key endings moved by the offset: the same as a scatter sample's
#: (``pipeline.robustness.THICKNESS_KEYS``, which cannot be imported here: robustness builds its
#: problems through pipeline.problems, which imports this module; a test keeps them equal)
THICKNESS_KEYS = ("thickness_mm", "min_feature_mm")
#: top-level blocks the offset leaves alone (``pipeline.robustness.UNPERTURBED_BLOCKS``)
UNPERTURBED_BLOCKS = ("design_space", "requirements", "optimiser", "parallel", "robustness")
#: keys ending in ``thickness_mm`` that are not walls in the bed plane, by kind: a cam plate's
#: thickness is its contact width, the print's height (set by the layers, not by the wall
#: error the coupon measures); the offset leaves them as drawn
OUT_OF_PLANE_KEYS: dict[str, tuple[str, ...]] = {
    "cam": ("geometry.thickness_mm",),
    "collision": ("cam.geometry.thickness_mm",),
}
#: kinds whose problem solves another study with the study's material (the gripper: the
#: constant-force study it resolves, ``constant_force.study``): the offset travels with the
#: material into that study, which this module analyses as printed; moving the outer study too
#: would apply the offset twice
LINKED_KINDS = ("gripper",)
#: cross-checks switched off in the study that only draws the outline (they draw nothing)
OUTLINE_SWITCHES: tuple[tuple[tuple[str, ...], Any], ...] = (
    (("fidelity", "enabled"), False),
    (("check_3d",), False),
    (("solid_3d", "check"), False),
)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _study_data(study: Study, offset_mm: float, outline_only: bool) -> tuple[dict, list[str]]:
    """The study's plain data without the material's offset, its thicknesses moved by
    ``offset_mm``, and the key paths moved; ``outline_only`` also switches the cross-checks off."""
    data = study.model_dump(mode="json", exclude_none=True)
    material = data.get("material")
    if isinstance(material, dict):
        material.pop("thickness_offset_mm", None)  # the inner study is solved as given
    changed: list[str] = []
    skipped = OUT_OF_PLANE_KEYS.get(study.kind, ())

    def shift(node: Any, path: str, delta: float) -> Any:
        if _is_number(node):
            changed.append(path)
            return float(node) + delta
        if isinstance(node, list):
            return [shift(v, f"{path}[{i}]", delta) for i, v in enumerate(node)]
        return node

    def walk(node: Any, path: str) -> None:
        if isinstance(node, list):
            for i, item in enumerate(node):
                walk(item, f"{path}[{i}]")
            return
        if not isinstance(node, dict):
            return
        for key, value in node.items():
            where = f"{path}.{key}" if path else str(key)
            if not path and key == "design_space" and isinstance(value, dict):
                # the bounds of a thickness checked against the printable minimum move with it
                # (flexure_pivot); the design vector's space stays the drawn one
                for k, v in value.items():
                    if str(k).endswith(THICKNESS_KEYS[0]) and offset_mm != 0.0:
                        value[k] = shift(v, f"{where}.{k}", offset_mm)
                continue
            if not path and key in UNPERTURBED_BLOCKS:
                continue
            if where in skipped:
                continue
            if str(key).endswith(THICKNESS_KEYS) and offset_mm != 0.0:
                node[key] = shift(value, where, offset_mm)
            else:
                walk(value, where)

    walk(data, "")
    if outline_only:
        for keys, value in OUTLINE_SWITCHES:
            node: Any = data
            for key in keys[:-1]:
                node = node.get(key) if isinstance(node, dict) else None
            if isinstance(node, dict) and keys[-1] in node:
                node[keys[-1]] = value
    return data, changed


def printed_study(study: Study, outline_only: bool = False) -> tuple[Study, tuple[str, ...]]:
    """The study as printed (its thicknesses plus the material's offset, the offset itself
    taken out of the material) and the key paths moved; with ``outline_only`` the study as
    drawn with its cross-checks off (what draws the exported outline).

    Raises
    ------
    StudyError
        At ``material.thickness_offset_mm`` when the printed study is invalid (a section the
        offset makes zero or negative), naming the refusal.
    """
    dt = 0.0 if outline_only else thickness_offset_mm(study)
    data, changed = _study_data(study, dt, outline_only)
    try:
        return validate_study(data), tuple(changed)
    except StudyError as exc:
        raise StudyError(
            "material.thickness_offset_mm",
            f"the part as printed ({dt:+.4g} mm on every section) is not a valid study: "
            f"{exc.path or 'study'}: {exc.problem}",
        ) from None


def printed_design(problem: DesignProblem, x: np.ndarray, offset_mm: float) -> np.ndarray:
    """(n_var,) the design vector ``x`` as printed: its in-plane thicknesses plus ``offset_mm``
    (the rule of a scatter sample's thickness delta, module docstring)."""
    x = np.array(x, dtype=float)
    own = problem.scatter_design(x.copy(), offset_mm, 0.0)
    if own is not None:
        out = np.asarray(own, dtype=float)
        if out.shape != x.shape:
            raise TypeError(f"scatter_design() gave shape {out.shape}, expected {x.shape}")
        return out
    variables = problem.variables
    if isinstance(variables, DesignVariables):  # variables on key paths (the mechanism kind)
        for i, targets in enumerate(variables.targets):
            key = next((p for p in reversed(targets[0].path) if isinstance(p, str)), "")
            if key.endswith(THICKNESS_KEYS[0]):
                x[i] += offset_mm / targets[0].factor
        return x
    for i, name in enumerate(problem.space.names):
        if "thickness" in name.lower():
            x[i] += offset_mm
    return x


def _annotated(
    study: Study, result: DesignResult, changed: tuple[str, ...], moved: tuple[str, ...]
) -> DesignResult:
    dt = thickness_offset_mm(study)
    record = {
        "thickness_offset_mm": dt,
        # nothing moved: the kind holds no section under a thickness key or variable (sea_window
        # has none): said, not hidden
        "applied": bool(changed or moved),
        "material": study.material.name,
        "study keys moved": list(changed),
        "design variables moved": list(moved),
        "exported geometry": "as drawn",
    }
    headline = (*result.headline, OFFSET_SUMMARY_KEY) if result.headline else ()
    return replace(
        result,
        info={**result.info, AS_PRINTED_INFO: record},
        summary={**result.summary, OFFSET_SUMMARY_KEY: dt},
        headline=headline,
    )


class AsPrintedProblem(ProblemWrapper):
    """A kind's problem whose designs are analysed as printed (module docstring).

    ``inner`` is the kind's problem of the printed study; ``drawn`` the kind's problem of the
    study as drawn with its cross-checks off, which gives the exported outline. Design vectors
    in and out (``Evaluation.x``) are the drawn ones. Picklable.
    """

    def __init__(
        self,
        study: Study,
        printed: DesignProblem,
        drawn: DesignProblem,
        changed: tuple[str, ...],
    ) -> None:
        super().__init__(printed)
        self.space = drawn.space  # the design vector is the drawn one (its bounds as drawn)
        self.drawn = drawn
        self.offset_mm = thickness_offset_mm(study)
        self.changed = changed
        self._study = study

    @property  # type: ignore[override]
    def study(self) -> Any:
        return self._study

    def printed(self, x: np.ndarray) -> np.ndarray:
        """(n_var,) the drawn design ``x`` as printed."""
        return printed_design(self.drawn, x, self.offset_mm)

    def evaluate(self, x: np.ndarray) -> Evaluation:
        x = np.asarray(x, dtype=float)
        return replace(self.inner.evaluate(self.printed(x)), x=x.copy())

    def detail(self, x: np.ndarray) -> DesignResult:
        x = np.asarray(x, dtype=float)
        return self._as_drawn(x, self.inner.detail(self.printed(x)))

    def result(self, x: np.ndarray, repeat: int = 1) -> DesignResult:
        x = np.asarray(x, dtype=float)
        return self._as_drawn(x, self.inner.result(self.printed(x), repeat))

    def _as_drawn(self, x: np.ndarray, result: DesignResult) -> DesignResult:
        """The printed design's result with the drawn design vector and the drawn outline."""
        xp = self.printed(x)
        names = self.space.names
        moved = tuple(n for n, a, b in zip(names, x, xp, strict=True) if a != b)
        evaluation = result.evaluation
        outline = result.outline
        if outline is not None:
            # the drawing: the same solved quantities (the SEA spring's plate thickness) as the
            # printed design, so its outline is drawn, not solved, again
            held = self.inner.held_state(evaluation) if evaluation is not None else {}
            self.drawn.hold_solved(held, 0.0, 0.0)
            outline = self.drawn.detail(x).outline
        if evaluation is not None:
            evaluation = replace(evaluation, x=x.copy())
        result = replace(result, evaluation=evaluation, outline=outline)
        return _annotated(self._study, result, self.changed, moved)

    def nominal_design(self) -> np.ndarray | None:
        return self.drawn.nominal_design()

    def initial_designs(self) -> np.ndarray | None:
        return self.drawn.initial_designs()

    def scatter_design(
        self, x: np.ndarray, thickness_delta_mm: float, width_delta_mm: float
    ) -> np.ndarray | None:
        return self.drawn.scatter_design(x, thickness_delta_mm, width_delta_mm)

    def study_values(self, x: np.ndarray) -> dict[str, Any] | None:
        return self.drawn.study_values(x)


def as_printed_problem(study: Study, build: Callable[[Study], DesignProblem]) -> DesignProblem:
    """The problem of ``study`` analysed as printed; ``build`` makes a kind's problem of a study
    (:func:`pipeline.problems.kind_problem`). A :data:`LINKED_KINDS` study's problem is the
    kind's own, built from the calibrated study: its linked study carries the offset.

    Raises
    ------
    StudyError
        When the printed study is invalid (:func:`printed_study`) or the kind refuses it.
    """
    if study.kind in LINKED_KINDS:
        from flexopt.pipeline.studies import get_kind  # the kind registry imports pipeline

        kind = get_kind(study.kind)
        assert kind.problem is not None  # only kinds with a problem are listed
        return kind.problem(study)  # not build(): it would hand the study back here
    printed, changed = printed_study(study)
    drawn, _ = printed_study(study, outline_only=True)
    return AsPrintedProblem(study, build(printed), build(drawn), changed)


def as_printed_evaluate(
    study: Study, evaluate: Callable[[Study, int], DesignResult], repeat: int = 1
) -> DesignResult:
    """The result of a kind's own ``evaluate(study, repeat)`` (a kind without a design problem)
    for the study as printed; its outline, when it has one, as drawn.

    Raises
    ------
    StudyError
        As :func:`printed_study`, or when the kind refuses the study.
    """
    printed, changed = printed_study(study)
    result = evaluate(printed, repeat)
    if result.outline is not None:
        drawn, _ = printed_study(study, outline_only=True)
        result = replace(result, outline=evaluate(drawn, 1).outline)
    return _annotated(study, result, changed, ())
