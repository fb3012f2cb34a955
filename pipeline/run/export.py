"""``flexopt export``: one design of a run or evaluate folder as STL, DXF, STEP, VTU, a hand-off
file (a parametric CAD script, a 3MF with print settings, a print sheet) or a study."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignDetail
from flexopt.optimise.space import DesignSpace
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.parallel import one_line as _one_line
from flexopt.pipeline.problems import ExportError
from flexopt.pipeline.problems import nominal_design as _nominal_design
from flexopt.pipeline.run.folder import (
    Columns,
    csv_fix,
    evaluations_csv,
    read_run_record,
    run_folder_study,
)
from flexopt.pipeline.run.setup import build_problem
from flexopt.pipeline.runfolder import echo, load_folder_study, read_folder_json, write_atomic
from flexopt.pipeline.studies import get_kind
from flexopt.pipeline.study import Study, study_to_yaml

if TYPE_CHECKING:  # geometry.solid (manifold3d, trimesh) is imported when a part is made
    from flexopt.geometry.solid import FlatPart

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------------
# flexopt export


#: The parts ``flexopt export --format`` writes: binary STL (to print), DXF (the outline, to
#: cut) and STEP (a solid for CAD; needs the optional extra ``flexopt[step]``).
EXPORT_FORMATS = ("stl", "dxf", "step")
#: ``flexopt export --format vtu``: not a part but the design's mesh and results for ParaView
#: (the beam's deformed shapes, the stress field; :mod:`pipeline.vtu`), always in the design
#: frame; kept out of :data:`EXPORT_FORMATS`, whose formats have a frame and a part.
VTU_FORMAT = "vtu"

#: File name endings taken as a format when ``--format`` is not given.
_SUFFIX_FORMATS = {
    ".stl": "stl",
    ".dxf": "dxf",
    ".step": "step",
    ".stp": "step",
    ".vtu": "vtu",
    ".py": "cad",
    ".3mf": "3mf",
    ".md": "sheet",
}
#: ``flexopt export --format cad|3mf|sheet``: the hand-off files of a part (issue #26 item 5):
#: its parametric build123d script (:mod:`pipeline.cad_script`), a 3MF laid flat with the print
#: settings the design assumes (:mod:`pipeline.threemf`) and the one-page print sheet
#: (:mod:`pipeline.print_sheet`). Each has its own name, after the design's (:func:`handoff_name`).
HANDOFF_FORMATS = ("cad", "3mf", "sheet")

STEP_EXTRA_FIX = "--format step needs the optional extra: pip install 'flexopt[step]'"
#: The frame each format is written in unless ``--frame`` says otherwise (docs/usage.md): STL is
#: the file to print, laid flat on the bed; DXF and STEP are for CAD and assemblies, in the
#: kind's own coordinates. A sheet part's DXF is always its flat profile (what is cut).
DEFAULT_FRAMES = {"stl": "bed", "dxf": "design", "step": "design"}


def export_frame(fmt: str, frame: str | None = None, sheet: bool = False) -> str:
    """The frame a part in ``fmt`` is written in: ``frame`` if given, else the format's
    (:data:`DEFAULT_FRAMES`); ``bed`` for the DXF of a sheet part (its flat profile)."""
    if fmt == "dxf" and sheet:
        return "bed"
    return frame or DEFAULT_FRAMES[fmt]


@dataclass(frozen=True)
class ExportOutcome:
    """What ``flexopt export`` wrote.

    Attributes
    ----------
    path : the file written.
    design : ``"best"``, the evaluation index, or ``"evaluated"`` (an evaluate folder's design).
    x : (n_var,) float, the design vector.
    evaluation : the design re-evaluated by ``problem.detail``.
    volume_mm3 : mm^3 (area x thickness), triangles : count (STL only, else 0),
    size_mm : size (x, y, z) of the part as written (in its frame), mm.
    format : ``stl``, ``dxf``, ``step`` or ``vtu`` (a VTU has no part: volume, size, footprint
        and thickness are 0, frame ``design``).
    footprint_mm : (x, y) mm, the size in its frame; thickness_mm : mm along z.
    rotation_deg : deg the kind's outline was turned to align it; sheet : laid flat from a sheet
        standing on its edge (its flat profile).
    frame : ``design`` (the kind's coordinates) or ``bed`` (laid flat).
    """

    path: Path
    design: str
    x: np.ndarray
    evaluation: Evaluation
    volume_mm3: float
    triangles: int
    size_mm: tuple[float, float, float]
    format: str = "stl"
    footprint_mm: tuple[float, float] = (0.0, 0.0)
    thickness_mm: float = 0.0
    rotation_deg: float = 0.0
    sheet: bool = False
    frame: str = "bed"


def _design_vector(
    run_dir: Path, design: str, space: DesignSpace, columns: Columns | None = None
) -> tuple[np.ndarray, dict[str, Any]]:
    """The design vector of ``best`` or of evaluation INDEX, and where it came from.

    Raises
    ------
    StudyError
        For a design that is not in the run, or a damaged best.json or evaluations.csv (naming
        the file, what is wrong and what to do).
    """
    if design == "best":
        path = run_dir / "best.json"
        fix = f"rebuild it with flexopt report {run_dir}"
        data = read_folder_json(path, "RUN_DIR", fix)
        if data is None:
            raise StudyError(
                "--design",
                f"'{run_dir}' has no best.json (the run did not finish); export one of its "
                "evaluations with --design INDEX (the index column of evaluations.csv), or "
                f"write it with flexopt report {run_dir}",
            )
        if not isinstance(data, dict) or not isinstance(data.get("parameters"), dict):
            what = echo(data.get("parameters")) if isinstance(data, dict) else echo(data)
            raise StudyError(
                "RUN_DIR",
                f"'{path}' has no parameters mapping (found {what}); {fix}",
            )
        values: Mapping[str, Any] = data["parameters"]
        source = f"'{path}'"
    else:
        try:
            index = int(design)
        except ValueError:
            raise StudyError(
                "--design",
                f"got {echo(design)}; give 'best' or a whole number (an evaluation index)",
            ) from None
        path = run_dir / "evaluations.csv"
        columns = columns or Columns.of_space(space)
        rows = evaluations_csv(run_dir, columns, "RUN_DIR")
        if rows is None:
            raise StudyError("RUN_DIR", f"'{run_dir}' has no evaluations.csv; is it a run folder?")
        if not 0 <= index < len(rows):
            last = f"0 … {len(rows) - 1}" if rows else "none yet"
            raise StudyError(
                "--design",
                f"no evaluation {index}: the run has {len(rows)} ({last}); pick an index from "
                "the index column of evaluations.csv",
            )
        # a variable's column is not always its name (one named `feasible` is written as
        # `x_feasible`, see Columns): read each by the column the writer gave it
        row = rows[index]
        values = {n: row[c] for n, c in zip(space.names, columns.variables, strict=True)}
        source = f"'{path}' row {index}"
        fix = csv_fix(run_dir)
    missing = [name for name in space.names if name not in values]
    if missing:
        raise StudyError(
            "RUN_DIR",
            f"{source} has no value for {', '.join(echo(m) for m in missing[:3])}; the study.yaml "
            f"of this run folder does not match its results (was it edited?); {fix}",
        )
    for name in space.names:
        value = values[name]
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if isinstance(value, str):
            with contextlib.suppress(ValueError):
                number = bool(float(value) == float(value))  # not nan
        if not number or not np.isfinite(float(value)):
            raise StudyError(
                "RUN_DIR", f"{source}: {name} is {echo(value)}, not a finite number; {fix}"
            )
    x = np.array([float(values[name]) for name in space.names], dtype=float)
    return x, {"source": source}


def step_available() -> bool:
    """Whether the optional STEP writer (build123d) is installed (not imported here)."""
    import importlib.util

    return importlib.util.find_spec("build123d") is not None


def part_of(detail: DesignDetail, frame: str = "bed") -> FlatPart:
    """A design's part laid flat or in the design ``frame`` (:func:`geometry.solid.flat_part`),
    the kind's sheet hint (``info[SHEET_HINT]``) honoured.

    Raises
    ------
    GeometryError
        When the outline is not one valid polygon (or a sheet's edge view is not a rectangle).
    """
    from flexopt.geometry.solid import SHEET_HINT, flat_part

    sheet = bool((detail.info or {}).get(SHEET_HINT))
    return flat_part(detail.outline, float(detail.height_mm or 0.0), sheet=sheet, frame=frame)


def part_bytes(part: FlatPart, fmt: str, comment: str = "") -> bytes:
    """The file of a part (laid flat or in the design frame) in ``fmt`` (one of
    :data:`EXPORT_FORMATS`).

    Raises
    ------
    GeometryError
        When the solid fails its checks.
    geometry.solid.StepUnavailable
        For ``step`` without build123d.
    """
    from flexopt.geometry.solid import extrude, step_bytes, stl_bytes

    if fmt == "stl":
        return stl_bytes(extrude(part.outline, part.thickness_mm))
    if fmt == "dxf":
        from flexopt.geometry.dxf import dxf_bytes

        return dxf_bytes(part.outline, comment)
    if fmt == "step":
        return step_bytes(part)
    raise ValueError(f"unknown export format {fmt!r}; use one of {', '.join(EXPORT_FORMATS)}")


def is_evaluate_folder(run_dir: Path) -> bool:
    """A folder of ``flexopt evaluate`` (evaluation.json, no run.json)."""
    return (run_dir / "evaluation.json").is_file() and not (run_dir / "run.json").exists()


def _export_format(fmt: str | None, out: Path | None) -> str:
    """The format asked for, else the one ``--out`` ends in, else STL; a clash is refused."""
    implied = _SUFFIX_FORMATS.get(out.suffix.lower()) if out is not None else None
    if fmt is None:
        return implied or "stl"
    if fmt not in (*EXPORT_FORMATS, VTU_FORMAT, *HANDOFF_FORMATS):
        known = ", ".join((*EXPORT_FORMATS, VTU_FORMAT, *HANDOFF_FORMATS))
        raise StudyError("--format", f"got {echo(fmt)}; use one of {known}")
    if implied is not None and implied != fmt:
        ending = next((k for k, v in _SUFFIX_FORMATS.items() if v == fmt), f".{fmt}")
        raise StudyError(
            "--out",
            f"'{out}' ends in {out.suffix} but --format is {fmt}; name the file {ending} or drop "  # type: ignore[union-attr]
            "--format",
        )
    return fmt


def _evaluate_folder_study(run_dir: Path) -> Study:
    path = run_dir / "study.yaml"
    if not path.is_file():
        raise StudyError(
            "RUN_DIR",
            f"'{run_dir}' has evaluation.json but no study.yaml file; restore it from a copy, or "
            "evaluate the study again with flexopt evaluate",
        )
    return load_folder_study(run_dir, path)


def export_design(
    run_dir: Path,
    design: str = "best",
    out: Path | None = None,
    fmt: str | None = None,
    frame: str | None = None,
) -> ExportOutcome:
    """Rebuild one design of a run or evaluate folder and write its part: STL, DXF or STEP; or
    its mesh and results for ParaView: VTU (:func:`pipeline.vtu.vtu_bytes`, in the design
    frame; ``frame`` does not apply).

    The part is the kind's outline extruded by its height, in the ``design`` frame (where the
    kind draws it) or laid flat on the ``bed`` (turned so its minimum-area rectangle is aligned
    with x and y, moved into the first quadrant); a kind that marks its outline as a sheet
    standing on its edge (``info[geometry.solid.SHEET_HINT]``) gets its flat profile on the bed
    (and as DXF in either frame).

    Parameters
    ----------
    run_dir : Path
        A folder written by ``flexopt run`` (its study.yaml rebuilds the problem), or by
        ``flexopt evaluate`` (its study.yaml is the design).
    design : str
        ``"best"`` (best.json) or an evaluation index (the ``index`` column of evaluations.csv);
        an evaluate folder holds one design, so only ``"best"`` (the default).
    out : Path, optional
        The file; default ``run_dir/best.<fmt>``, ``run_dir/design-<INDEX>.<fmt>`` or, in an
        evaluate folder, ``run_dir/design.<fmt>``.
    fmt : str, optional
        ``stl``, ``dxf``, ``step`` or ``vtu``; default the one ``out`` ends in, else ``stl``.
    frame : str, optional
        ``design`` or ``bed``; default the format's (:data:`DEFAULT_FRAMES`: STL on the bed,
        DXF and STEP in the design frame).

    Raises
    ------
    StudyError
        For a missing or unusable folder (a damaged run.json, study.yaml, best.json or
        evaluations.csv), a design that is not in it, a bad format, or ``step`` without the
        optional extra (bad arguments). Export takes no lock: it reads files that are replaced
        atomically, also while a run writes the folder.
    ExportError
        When the design cannot be rebuilt or has no outline to make a part of (for ``vtu``: no
        beam shapes and no stress field).
    OSError
        When the file cannot be written.
    """
    fmt = _export_format(fmt, out)
    if fmt in HANDOFF_FORMATS and frame is not None:
        raise StudyError("--frame", f"--format {fmt} chooses its own frame; drop --frame")
    if fmt == VTU_FORMAT and frame == "bed":
        raise StudyError("--frame", "a VTU is written in the design frame only; drop --frame")
    if frame is not None and frame not in DEFAULT_FRAMES.values():
        raise StudyError("--frame", f"got {echo(frame)}; use design or bed")
    if fmt == "step" and not step_available():
        raise StudyError("", STEP_EXTRA_FIX)
    evaluate = run_dir.is_dir() and is_evaluate_folder(run_dir)
    if evaluate:
        if design != "best":
            raise StudyError(
                "--design",
                f"'{run_dir}' is a folder of flexopt evaluate, which holds one design; drop "
                "--design",
            )
        study = _evaluate_folder_study(run_dir)
        if get_kind(study.kind).problem is None:
            raise ExportError(f"kind '{study.kind}' gives no part outline to export")
        problem = build_problem(study)
        x = _nominal_design(problem, study)
        design = "evaluated"
        default = handoff_name("design", fmt) if fmt in HANDOFF_FORMATS else f"design.{fmt}"
    else:
        read_run_record(run_dir)  # a folder of flexopt run, its run.json readable
        study = run_folder_study(run_dir, "RUN_DIR")
        problem = build_problem(study)
        x, _ = _design_vector(run_dir, design, problem.space, Columns.of(problem))
        stem = "best" if design == "best" else f"design-{int(design)}"
        default = handoff_name(stem, fmt) if fmt in HANDOFF_FORMATS else f"{stem}.{fmt}"
    target = out or run_dir / default
    if target.is_dir():
        ending = next((k for k, v in _SUFFIX_FORMATS.items() if v == fmt), f".{fmt}")
        raise StudyError("--out", f"'{target}' is a folder; give a file name ending in {ending}")
    if not target.parent.is_dir():
        raise StudyError("--out", f"folder '{target.parent}' does not exist; create it first")
    try:
        detail = problem.detail(x)
    except Exception as exc:
        raise ExportError(
            f"design {design} could not be rebuilt: {_one_line(f'{type(exc).__name__}: {exc}')}"
        ) from exc
    if fmt == VTU_FORMAT:
        return _export_vtu(target, design, x, detail, study.kind)
    if detail.outline is None or not detail.height_mm:
        if fmt == "cad":
            from flexopt.pipeline.cad_script import NO_OUTLINE

            raise ExportError(NO_OUTLINE.format(kind=study.kind))
        raise ExportError(f"kind '{study.kind}' gives no outline and height_mm to extrude")
    if fmt in HANDOFF_FORMATS:
        return _export_handoff(target, design, fmt, study, problem, x, detail, run_dir, evaluate)
    from flexopt.geometry.solid import StepUnavailable

    try:
        bed = part_of(detail)
        used = export_frame(fmt, frame, bed.sheet)
        part = bed if used == "bed" else part_of(detail, used)
        data = part_bytes(part, fmt, f"{study.name}: design {design}")
    except StepUnavailable:
        raise StudyError("", STEP_EXTRA_FIX) from None
    except ValueError as exc:  # GeometryError
        raise ExportError(f"design {design} cannot be made a part: {exc}") from exc
    triangles = 0
    if fmt == "stl":
        import trimesh

        triangles = len(trimesh.load(trimesh.util.wrap_as_stream(data), file_type="stl").faces)
    write_atomic(target, data)
    w, h = part.footprint_mm
    log.info("wrote %s (%s)", target, fmt)
    return ExportOutcome(
        target,
        design,
        x,
        detail.evaluation,
        float(part.outline.area * part.thickness_mm),
        triangles,
        (w, h, part.thickness_mm),
        fmt,
        (w, h),
        part.thickness_mm,
        part.rotation_deg,
        part.sheet,
        part.frame,
    )


def _export_vtu(
    target: Path, design: str, x: np.ndarray, detail: DesignDetail, kind: str
) -> ExportOutcome:
    """Write the VTU of a rebuilt design (:func:`export_design` with ``fmt='vtu'``)."""
    from flexopt.pipeline.vtu import vtu_files

    # the file itself, and beside it STEM.pvd with STEM_steps/ (one VTU per load step) and,
    # after a 3D check, STEM_3d.vtu
    try:
        files = vtu_files(detail, target.stem)
    except Exception as exc:
        why = _one_line(f"{type(exc).__name__}: {exc}")
        raise ExportError(f"design {design} cannot be written as VTU: {why}") from exc
    single = files.pop(f"{target.stem}.vtu", None)
    if single is None:
        raise ExportError(f"kind '{kind}' gives no beam shapes and no stress field to write as VTU")
    write_atomic(target, single)
    (target.parent / f"{target.stem}_steps").mkdir(exist_ok=True)
    for name, data in files.items():
        write_atomic(target.parent / name, data)
    log.info("wrote %s (vtu)", target)
    zero = (0.0, 0.0, 0.0)  # no part: no volume, size or triangles
    return ExportOutcome(
        target, design, x, detail.evaluation, 0.0, 0, zero, VTU_FORMAT, frame="design"
    )


# --------------------------------------------------------------------------------------------
# Hand-off files: the parametric CAD script, the 3MF with print settings, the print sheet


def handoff_name(stem: str, fmt: str) -> str:
    """The file name of a hand-off file of design ``stem`` (``best``, ``design-INDEX`` or
    ``design``): ``best_cad.py``, ``best.3mf``, ``print_sheet.md`` (``STEM_print_sheet.md``
    for any other design)."""
    if fmt == "cad":
        return f"{stem}_cad.py"
    if fmt == "3mf":
        return f"{stem}.3mf"
    if fmt == "sheet":
        from flexopt.pipeline.print_sheet import PRINT_SHEET

        return PRINT_SHEET if stem == "best" else f"{stem}_{PRINT_SHEET}"
    raise ValueError(f"{fmt!r} is not a hand-off format ({', '.join(HANDOFF_FORMATS)})")


def _thinnest_mm(detail: DesignDetail, part: FlatPart) -> float | None:
    """The part's thinnest in-plane section, mm: the kind's ``min_feature_mm`` metric, else the
    outline's estimate (:func:`geometry.solid.min_feature_mm`); None when neither works."""
    metrics = detail.evaluation.metrics if detail.evaluation is not None else {}
    value = (metrics or {}).get("min_feature_mm")
    if isinstance(value, int | float) and not isinstance(value, bool) and np.isfinite(value):
        return float(value)
    from flexopt.geometry.solid import min_feature_mm

    try:
        return float(min_feature_mm(part.outline))
    except Exception:  # an outline the estimate cannot read: the sheet says no thinnest section
        log.info("no thinnest section of the outline", exc_info=True)
        return None


def handoff_files(
    study: Study,
    problem: Any,
    x: np.ndarray,
    detail: DesignDetail,
    bed: FlatPart,
    design_part: FlatPart,
    stem: str = "best",
    response_table: str = "best_response.csv",
    run_dir: str = "RUN_DIR",
) -> dict[str, Any]:
    """The hand-off files of a design's part, each as a function that makes its bytes.

    Parameters
    ----------
    study, problem : the run's study and problem; x : (n_var,) the design.
    detail : the design's detail (its outline, metrics and response table).
    bed : the part laid flat (best.stl's, the 3MF's); design_part : in the design frame
        (best.step's, the CAD script's).
    stem : ``best``, ``design-INDEX`` or ``design`` (names the files: :func:`handoff_name`).
    response_table : the file of the predicted response (named by the print sheet).
    run_dir : the folder as the print sheet's commands name it (its absolute path: the same
        sheet from a run and from flexopt export).

    Returns
    -------
    dict of file name to callable returning bytes (``cad``, ``3mf``, ``sheet`` in that order).
    """
    import functools

    from flexopt.pipeline.cad_script import cad_script
    from flexopt.pipeline.labels import variable_meanings
    from flexopt.pipeline.print_sheet import (
        print_metadata,
        print_sheet,
        sections,
        slicer_config,
    )
    from flexopt.pipeline.threemf import threemf_bytes

    names = {fmt: handoff_name(stem, fmt) for fmt in HANDOFF_FORMATS}
    # once for the 3MF and the sheet: the outline's estimate takes seconds on a large outline
    thinnest_mm = functools.cache(lambda: _thinnest_mm(detail, bed))
    material = study.material.to_material()
    title = f"{study.name}: {'best design' if stem == 'best' else stem}"

    def cad() -> bytes:
        text = cad_script(study, problem, x, design_part, stem, names["cad"])
        return text.encode("utf-8")

    def threemf() -> bytes:
        from flexopt.geometry.solid import extrude

        mesh = extrude(bed.outline, bed.thickness_mm)
        thinnest = thinnest_mm()
        return threemf_bytes(
            mesh.vertices,
            mesh.faces,
            title,
            print_metadata(material, bed.thickness_mm, thinnest),
            slicer_config(material, thinnest),
            f"{study.kind} part laid flat as {stem}.stl; the print settings it assumes",
        )

    def sheet() -> bytes:
        spec = dict(detail.plot or {})  # the run's defaults when the kind names no columns
        xc, yc = spec.get("x", "displacement_mm"), spec.get("y", "force_N")
        column = (detail.table or {}).get(xc) if xc else None
        values = np.asarray(column, dtype=float) if column is not None else np.array([])
        values = values[np.isfinite(values)]
        response = {
            "x": xc if values.size else None,
            "y": yc if yc in (detail.table or {}) else None,
            "x_range": (float(values.min()), float(values.max())) if values.size else None,
            "table": response_table,
        }
        space = problem.space
        meanings = variable_meanings(study.kind, space.names, problem)
        text = print_sheet(
            title=title,
            run_dir=run_dir,
            material=material,
            part=bed,
            section_list=sections(tuple(space.names), x, meanings, thinnest_mm()),
            response=response,
            files={
                "stl": f"{stem}.stl",
                "3mf": names["3mf"],
                "cad": names["cad"],
                "step": f"{stem}.step",
                "dxf": f"{stem}.dxf",
            },
        )
        return text.encode("utf-8")

    return {names["cad"]: cad, names["3mf"]: threemf, names["sheet"]: sheet}


def _export_handoff(
    target: Path,
    design: str,
    fmt: str,
    study: Study,
    problem: Any,
    x: np.ndarray,
    detail: DesignDetail,
    run_dir: Path,
    evaluate: bool,
) -> ExportOutcome:
    """Write one hand-off file of a rebuilt design (:func:`export_design` with ``fmt`` one of
    :data:`HANDOFF_FORMATS`)."""
    stem = "design" if design == "evaluated" else "best" if design == "best" else f"design-{design}"
    try:
        bed = part_of(detail)
        part = part_of(detail, "design")
        files = handoff_files(
            study,
            problem,
            x,
            detail,
            bed,
            part,
            stem,
            "response.csv" if evaluate else "best_response.csv",
            str(run_dir.resolve()),
        )
        data = files[handoff_name(stem, fmt)]()
    except ValueError as exc:  # GeometryError
        raise ExportError(f"design {design} cannot be made a part: {exc}") from exc
    write_atomic(target, data)
    log.info("wrote %s (%s)", target, fmt)
    used = part if fmt == "cad" else bed
    w, h = used.footprint_mm
    return ExportOutcome(
        target,
        design,
        x,
        detail.evaluation,
        float(used.outline.area * used.thickness_mm),
        0,
        (w, h, used.thickness_mm),
        fmt,
        (w, h),
        used.thickness_mm,
        used.rotation_deg,
        used.sheet,
        used.frame,
    )


# --------------------------------------------------------------------------------------------
# A design as a study (flexopt export --format yaml)

#: File name endings taken as ``--format yaml``.
STUDY_SUFFIXES = (".yaml", ".yml")


@dataclass(frozen=True)
class StudyExportOutcome:
    """What ``flexopt export --format yaml`` wrote.

    Attributes
    ----------
    path : the study file written.
    design : ``"best"``, the evaluation index, or ``"evaluated"`` (an evaluate folder's design).
    study : the study written (``flexopt evaluate`` of it solves the design).
    x : (n_var,) float, the design vector (None for an evaluate folder: its study as it is).
    """

    path: Path
    design: str
    study: Study
    x: np.ndarray | None


def design_study_of(run_dir: Path, design: str = "best") -> tuple[Study, str, np.ndarray | None]:
    """The study that describes one design of a run folder (``best`` or an evaluation index),
    or an evaluate folder's own study: ``flexopt evaluate`` of it gives the design's numbers.

    Raises
    ------
    StudyError
        For a folder or design that is not there or is damaged (as :func:`export_design`).
    ExportError
        When the kind cannot keep the design in its study (:mod:`pipeline.design_study`).
    """
    from flexopt.pipeline.design_study import design_study

    if run_dir.is_dir() and is_evaluate_folder(run_dir):
        if design != "best":
            raise StudyError(
                "--design",
                f"'{run_dir}' is a folder of flexopt evaluate, which holds one design; drop "
                "--design",
            )
        return _evaluate_folder_study(run_dir), "evaluated", None
    read_run_record(run_dir)
    study = run_folder_study(run_dir, "RUN_DIR")
    problem = build_problem(study)
    x, _ = _design_vector(run_dir, design, problem.space, Columns.of(problem))
    return design_study(study, problem, x), design, x


def export_study(
    run_dir: Path, design: str = "best", out: Path | None = None
) -> StudyExportOutcome:
    """Write one design of a run (or an evaluate folder's design) as a study YAML file.

    The file is the run's study with the design's values where the kind keeps its design (the
    variables' ``initial``, the ``design:`` block, ...; :mod:`pipeline.design_study`), so
    ``flexopt evaluate FILE`` solves that design and gives the numbers of best.json.

    Parameters
    ----------
    out : Path, optional
        Default ``run_dir/best.yaml``, ``run_dir/design-<INDEX>.yaml`` or, in an evaluate
        folder, ``run_dir/design.yaml``; it must end in .yaml or .yml.

    Raises
    ------
    StudyError
        As :func:`design_study_of`, and for an ``out`` that is a folder, in a missing folder, or
        not a .yaml file.
    ExportError
        When the kind cannot keep the design in its study.
    OSError
        When the file cannot be written.
    """
    if out is not None and out.suffix.lower() not in STUDY_SUFFIXES:
        raise StudyError(
            "--out", f"'{out}' does not end in .yaml; name the study file .yaml (--format yaml)"
        )
    study, design, x = design_study_of(run_dir, design)
    names = {"best": "best.yaml", "evaluated": "design.yaml"}
    target = out or run_dir / (names.get(design) or f"design-{int(design)}.yaml")
    if target.is_dir():
        raise StudyError("--out", f"'{target}' is a folder; give a file name ending in .yaml")
    if not target.parent.is_dir():
        raise StudyError("--out", f"folder '{target.parent}' does not exist; create it first")
    header = (
        f"Design {design} of {run_dir}, written by flexopt export as a study\n"
        f"(the design's values where the {study.kind} kind keeps its design);\n"
        f"solve it with: flexopt evaluate {target}"
    )
    write_atomic(target, study_to_yaml(study, header))
    log.info("wrote %s (yaml)", target)
    return StudyExportOutcome(target, design, study, x)
