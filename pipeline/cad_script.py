"""A parametric CAD script of a design's part: a build123d Python script (issue #26 item 5).

``best_cad.py`` of a run folder (``design_cad.py`` of an evaluate folder, ``flexopt export
--format cad``) is written by :func:`cad_script`. At its top it names the part's dimensions: the
study's design variables with this design's values (``DESIGN``) and the numbers of the study's
``geometry:`` block (``FIXED``: pads, lengths, ... that the optimiser does not move). Run, it
rebuilds the part's solid and writes it as STEP beside itself; an engineer changes a dimension
and runs it again.

Why the outline is drawn by flexopt and not by build123d sketch operations in the script: every
kind's outline is its own construction (a tapered beam offset from a spline through design
points, a spiral of arms, a mechanism's joints), which the solvers and best.step share. Writing it
again in build123d would be a second implementation that can drift from the one the design was
solved on. So the script calls :func:`outline_of` (the kind's own geometry: the study's detail,
without the checks that do not draw the part, :data:`SKIPPED_BLOCKS` and :data:`FAST_CHECKS`;
~0.3 s for the constant-force part)
and makes with build123d the solid :func:`geometry.solid.step_bytes` writes as best.step (since
session 29 directly, geometry/step_writer.py, the same topology): one planar face bounded by the
outline's rings, extruded along z by the part's thickness, in the design frame.

The outline as exported is kept in the script (``OUTLINE_AS_EXPORTED``) with the dimensions and
the study it was drawn from (``EXPORTED_DESIGN``, ``EXPORTED_FIXED``, the study text's SHA-256):
while they are unchanged the script builds that outline and solves nothing (a second; the
threshold spring's and a mechanism's outlines come from a solve: 9.6 min and 1.3 min here), and
only a changed dimension (or ``--redraw``) calls :func:`outline_of`. Without flexopt installed,
the unchanged script still builds the part, and a changed dimension is refused rather than
ignored.

A kind whose design gives no outline and height has no script (:data:`NO_OUTLINE`).
"""

from __future__ import annotations

import hashlib
import pprint
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = [
    "SKIPPED_BLOCKS",
    "FAST_CHECKS",
    "NO_OUTLINE",
    "fixed_dimensions",
    "cad_script",
    "outline_of",
]

#: Study blocks left out when the script rebuilds the outline: the robustness scatter and the
#: fatigue duty cycle are judged after the design is drawn and never change its outline. If a
#: study does not validate without them, the script keeps them (slower, same outline).
SKIPPED_BLOCKS = ("robustness", "duty_cycle")

#: Checks a kind's outline does not depend on, switched off when the script rebuilds it (the
#: constant-force part's plane-stress check is 18 s of its 18.6 s detail). Only where the
#: outline is the same with and without (tests/pipeline/test_handoff.py checks the volumes):
#: the SEA and threshold springs export the outline their 3D check's peak converged on, and
#: the mechanism kind's check re-solves the shared width (parallel-guide: 7.7 % thicker
#: without it), so their checks stay on.
FAST_CHECKS: dict[str, dict[str, dict[str, Any]]] = {
    "constant_force": {"fidelity": {"enabled": False}},
    "flexure_pivot": {"fidelity": {"plane_stress": False}},
}

#: The one line a kind without an outline gets instead of a script.
NO_OUTLINE = "kind '{kind}' gives no outline and height_mm: no parametric CAD script of its part"


def fixed_dimensions(
    geometry: Mapping[str, Any], variables: tuple[str, ...] = ()
) -> dict[str, float | int]:
    """The numbers of a study's ``geometry:`` block (its dump), in order: the script's FIXED.

    Parameters
    ----------
    geometry : mapping
        ``study.model_dump(mode="json")["geometry"]``.
    variables : tuple of str
        The design variables' names: a geometry key of the same name is the variable's (the
        design replaces it), so it is not listed as fixed.

    Returns
    -------
    dict of str to float or int
        Every scalar number (not a bool, not the kind, not a list or block: those stay in the
        embedded study, changed there if at all).
    """
    return {
        key: value
        for key, value in geometry.items()
        if isinstance(value, int | float) and not isinstance(value, bool) and key not in variables
    }


def _study_without(raw: dict[str, Any], blocks: tuple[str, ...]) -> dict[str, Any]:
    return {key: value for key, value in raw.items() if key not in blocks}


def outline_of(
    study_yaml: str,
    design: Mapping[str, float],
    fixed: Mapping[str, float] | None = None,
    base: str | None = None,
) -> tuple[list[list[tuple[float, float]]], float]:
    """The part's outline and thickness from a study and named dimensions (what the script runs).

    Parameters
    ----------
    study_yaml : str
        The resolved study (a run folder's study.yaml).
    design : mapping of str to float
        Every design variable of the study's design space, by name, in its own unit.
    fixed : mapping of str to float, optional
        Numbers of the ``geometry:`` block to replace.
    base : str, optional
        The folder the study's table files are relative to (the run folder).

    Returns
    -------
    (rings, thickness_mm)
        rings: the outline in the design frame (mm), cleaned of collinear vertices, exterior
        first (counter-clockwise) then its holes, each a list of (x, y) without the closing
        point; thickness_mm: the extrusion along z (mm).

    Raises
    ------
    StudyError
        For a changed study that does not validate (the message names the key).
    KeyError
        For a design variable missing from ``design`` or a name that is not one.
    ExportError
        When the kind gives no outline and height for the design.
    """
    import contextlib
    from pathlib import Path

    import yaml
    from flexopt.geometry.solid import SHEET_HINT, flat_part
    from flexopt.pipeline.errors import StudyError
    from flexopt.pipeline.problems import ExportError
    from flexopt.pipeline.run.setup import build_problem
    from flexopt.pipeline.study import validate_study
    from flexopt.pipeline.targets import table_root

    raw = yaml.safe_load(study_yaml)
    geometry = dict(raw.get("geometry") or {})
    unknown = sorted(set(fixed or {}) - set(geometry))
    if unknown:
        raise KeyError(f"FIXED names {', '.join(unknown)}, not in the study's geometry block")
    raw["geometry"] = {**geometry, **dict(fixed or {})}
    fast = _study_without(raw, SKIPPED_BLOCKS)
    for key, values in FAST_CHECKS.get(str(geometry.get("kind")), {}).items():
        fast[key] = {**(fast.get(key) or {}), **values}
    where = table_root(Path(base)) if base else contextlib.nullcontext()
    with where:
        try:
            study = validate_study(fast)
        except StudyError:
            study = validate_study(raw)
        problem = build_problem(study)
    names = tuple(problem.space.names)
    missing = [n for n in names if n not in design]
    extra = sorted(set(design) - set(names))
    if missing or extra:
        raise KeyError(
            f"DESIGN must name every design variable ({', '.join(names)}); missing "
            f"{', '.join(missing) or 'none'}, not variables: {', '.join(extra) or 'none'}"
        )
    x = np.array([float(design[n]) for n in names], dtype=float)
    detail = problem.detail(x)
    if detail.outline is None or not detail.height_mm:
        raise ExportError(NO_OUTLINE.format(kind=study.kind))
    # as pipeline.run.export.part_of lays it (that module imports this one: no cycle)
    sheet = bool((detail.info or {}).get(SHEET_HINT))
    part = flat_part(detail.outline, float(detail.height_mm or 0.0), sheet=sheet, frame="design")
    rings = [
        [(float(px), float(py)) for px, py in np.asarray(ring.coords)[:-1]]
        for ring in (part.outline.exterior, *part.outline.interiors)
    ]
    return rings, float(part.thickness_mm)


def _python_text(text: str) -> str:
    """A Python literal of ``text``: a triple-quoted block that reads as the YAML it holds, or
    its repr when the text has a backslash or a triple quote (which the block would change)."""
    if "\\" in text or '"""' in text or not text.endswith("\n"):
        return repr(text)
    return '"""\\\n' + text + '"""'


def _dict_lines(values: Mapping[str, float], notes: Mapping[str, str]) -> str:
    lines = []
    for name, value in values.items():
        note = notes.get(name, "")
        lines.append(f"    {name!r}: {value!r},{f'  # {note}' if note else ''}")
    return "\n".join(lines)


_TEMPLATE = '''#!/usr/bin/env python3
"""{title}: a parametric build123d script of the part (flexopt export --format cad).

Change a dimension in DESIGN or FIXED below and run it:

    python {script}           # writes {step} beside this file and prints the solid's volume
    python {script} --redraw  # the same, the outline drawn again by flexopt even if unedited
    freecadcmd {script}       # FreeCAD (or Macro > Execute): {step} and a .FCStd document

Units: mm (and each variable's own unit, in its comment). build123d (or FreeCAD's Part, when
FreeCAD runs this file as a macro) makes the solid: the outline in the x-y plane of the design
frame (where the kind draws the part), extruded along z from 0 by its out-of-plane thickness.

Where the outline comes from: while DESIGN, FIXED and STUDY_YAML are as recorded
(EXPORTED_DESIGN, EXPORTED_FIXED, STUDY_SHA256_AS_EXPORTED), from OUTLINE_AS_EXPORTED, the
outline of the exported part kept in this file: no solve, flexopt not needed. Once a dimension
differs from its recorded value, flexopt's geometry of the `{kind}` kind draws it again from
the dimensions (the code that drew best.step; needs `pip install flexopt[step]`), which takes
as long as the kind's detail: a solve where the outline comes from one (the SEA and threshold
springs' plate thickness, a mechanism's solved width: minutes). Without flexopt (FreeCAD's own
Python has none unless it is installed there) a changed dimension is refused. This script
draws the part; it does not check it: solve a changed design with `flexopt evaluate` of the
study (`flexopt export RUN --format yaml`).
"""

from __future__ import annotations

import sys
from pathlib import Path

# ---- design variables: the study's design space, the values of design {design} --------------
DESIGN = {{
{design_lines}
}}

# ---- fixed dimensions: the numbers of the study's geometry block (not optimised) -------------
FIXED = {{
{fixed_lines}
}}

# ---- below: how the part is made (no dimensions to change) ----------------------------------
KIND = {kind!r}
#: The resolved study (the run folder's study.yaml); the dimensions above replace its values.
STUDY_YAML = {study_yaml}
#: The design and fixed dimensions this file was written with, and the outline they give (mm,
#: design frame, exterior counter-clockwise then the holes) and its thickness along z (mm).
EXPORTED_DESIGN = {exported_design}
EXPORTED_FIXED = {exported_fixed}
STUDY_SHA256_AS_EXPORTED = {study_sha256!r}
OUTLINE_AS_EXPORTED = {outline}
THICKNESS_AS_EXPORTED_MM = {thickness!r}
#: The exported solid's volume (mm^3, outline area x thickness), to compare a rebuild with.
VOLUME_AS_EXPORTED_MM3 = {volume!r}


def as_exported():
    """Whether every dimension and the study are the recorded ones (the exported part)."""
    import hashlib

    study = hashlib.sha256(STUDY_YAML.encode("utf-8")).hexdigest()
    same = DESIGN == EXPORTED_DESIGN and FIXED == EXPORTED_FIXED
    return same and study == STUDY_SHA256_AS_EXPORTED


def outline(redraw=False):
    """The outline's rings (exterior first, then holes; (x, y) mm) and its thickness (mm): the
    exported one while nothing is changed (unless ``redraw``), else drawn by flexopt."""
    if as_exported() and not redraw:
        return OUTLINE_AS_EXPORTED, THICKNESS_AS_EXPORTED_MM
    try:
        from flexopt.pipeline.cad_script import outline_of
    except ImportError:
        if not as_exported():
            sys.exit(
                "changed dimensions need flexopt to draw the outline: pip install 'flexopt[step]'"
            )
        sys.exit("--redraw needs flexopt to draw the outline: pip install 'flexopt[step]'")
    return outline_of(STUDY_YAML, DESIGN, FIXED, base=str(Path(__file__).resolve().parent))


def build(redraw=False):
    """The part as a build123d solid: one face bounded by the rings, extruded along z."""
    import build123d as bd

    rings, thickness_mm = outline(redraw)
    wires = [bd.Wire.make_polygon([(x, y, 0.0) for x, y in ring], close=True) for ring in rings]
    face = bd.Face(wires[0], wires[1:])
    return bd.extrude(face, amount=thickness_mm)


def build_freecad():
    """The part as a FreeCAD document (FreeCAD's Python: ``freecadcmd {script}`` or Macro >
    Macros... > Execute): a spreadsheet ``Dimensions`` listing DESIGN, FIXED and the thickness
    (a record: the dimensions are changed above, in this file), the outline as a face
    (``Outline``) and the part (``Part``), the face extruded along z by the thickness."""
    import FreeCAD as App
    import Part

    try:
        rings, thickness_mm = outline()
    except SystemExit as exc:  # FreeCAD's window stays open: an error, not an exit
        raise RuntimeError(str(exc)) from None
    doc = App.newDocument(Path(__file__).stem)
    sheet = doc.addObject("Spreadsheet::Sheet", "Dimensions")
    rows = [("dimension", "value", "")]
    rows += [(name, repr(float(value)), "design variable") for name, value in DESIGN.items()]
    rows += [(name, repr(float(value)), "fixed") for name, value in FIXED.items()]
    rows += [("thickness_mm", repr(float(thickness_mm)), "extrusion along z")]
    for i, row in enumerate(rows, start=1):
        for column, text in zip("ABC", row):
            sheet.set(f"{{column}}{{i}}", text)
    wires = [Part.makePolygon([App.Vector(x, y, 0.0) for x, y in [*r, r[0]]]) for r in rings]
    base = doc.addObject("Part::Feature", "Outline")
    base.Shape = Part.makeFace(wires, "Part::FaceMakerBullseye")  # the first ring's holes
    part = doc.addObject("Part::Feature", "Part")
    part.Shape = base.Shape.extrude(App.Vector(0.0, 0.0, thickness_mm))
    doc.recompute()
    return doc, part


def main_freecad():
    """Run by FreeCAD: the document saved as .FCStd and the part as STEP beside this file."""
    doc, part = build_freecad()
    out = Path(__file__).with_suffix(".step")
    part.Shape.exportStep(str(out))
    doc.saveAs(str(Path(__file__).with_suffix(".FCStd")))
    exported = VOLUME_AS_EXPORTED_MM3
    print(f"wrote {{out}}: volume {{part.Shape.Volume:.9g}} mm^3 (as exported: {{exported:.9g}})")


if "FreeCAD" in sys.modules and "build123d" not in sys.modules:  # run by FreeCAD (a macro)
    main_freecad()
elif __name__ == "__main__":
    import build123d as bd

    solid = build(redraw="--redraw" in sys.argv[1:])
    out = Path(__file__).with_suffix(".step")
    if not bd.export_step(solid, str(out)):
        sys.exit(f"build123d could not write {{out}}")
    exported = VOLUME_AS_EXPORTED_MM3
    print(f"wrote {{out}}: volume {{solid.volume:.9g}} mm^3 (as exported: {{exported:.9g}})")
'''


def cad_script(
    study: Any,
    problem: Any,
    x: np.ndarray,
    part: Any,
    design: str = "best",
    script_name: str = "best_cad.py",
) -> str:
    """The parametric build123d script of a design's part.

    Parameters
    ----------
    study : Study
        The run's resolved study (embedded as YAML; its geometry numbers become FIXED).
    problem : DesignProblem
        Its design space names the variables of DESIGN (bounds and meanings in comments).
    x : (n_var,) float
        The design's values, in the space's order and units.
    part : geometry.solid.FlatPart
        The part in the design frame (best.step's), kept in the script for use without flexopt.
    design : str
        ``best``, an evaluation index or ``evaluated`` (named in the script's docstring).
    script_name : str
        The file's name (the STEP it writes is named after it).

    Returns
    -------
    str
        The script's text (Python, runs with build123d; with flexopt for changed dimensions).
    """
    from flexopt.pipeline.labels import variable_meanings
    from flexopt.pipeline.study import study_to_yaml

    space = problem.space
    names = tuple(space.names)
    values = {n: float(v) for n, v in zip(names, np.asarray(x, dtype=float), strict=True)}
    meanings = variable_meanings(study.kind, names, problem)
    notes = {
        n: f"{meanings.get(n) or n}; range {lo:.6g} … {hi:.6g}".strip()
        for n, lo, hi in zip(names, space.lower, space.upper, strict=True)
    }
    geometry = study.model_dump(mode="json", exclude_none=True)["geometry"]
    fixed = fixed_dimensions(geometry, names)
    fixed_notes = {
        k: "mm" if k.endswith("_mm") else "not a length: a count or a model setting" for k in fixed
    }
    poly = part.outline
    rings = [
        [(float(px), float(py)) for px, py in np.asarray(ring.coords)[:-1]]
        for ring in (poly.exterior, *poly.interiors)
    ]
    study_yaml = study_to_yaml(study)
    return _TEMPLATE.format(
        title=f"{study.name}: design {design}",
        script=script_name,
        step=script_name.removesuffix(".py") + ".step",
        kind=study.kind,
        design=design,
        design_lines=_dict_lines(values, notes),
        fixed_lines=_dict_lines(fixed, fixed_notes),
        study_yaml=_python_text(study_yaml),
        study_sha256=hashlib.sha256(study_yaml.encode("utf-8")).hexdigest(),
        exported_design=pprint.pformat(values, sort_dicts=False, width=100),
        exported_fixed=pprint.pformat(fixed, sort_dicts=False, width=100),
        outline=pprint.pformat(rings, width=100, compact=True),
        thickness=float(part.thickness_mm),
        volume=float(poly.area * part.thickness_mm),
    )
