"""The print settings a design assumes, and its one-page print sheet (issue #26 item 5).

flexopt's models take the drawn section as the printed one. An FDM printer lays a wall as whole
lines of its line width, so the drawn section is printed as drawn only when it is a whole number
of lines (0.8 mm: two 0.4 mm lines, the default ``min_feature_mm``); a section of 2.6 lines is
printed as two wider lines or two lines and a gap, depending on the slicer, and its stiffness
(which goes with the cube of the section) is not the model's. Along z the part's out-of-plane
thickness is printed in whole layers, and every force is proportional to it.

:class:`PrintSettings` names the settings (nozzle and line width, layer height, 100 % infill,
the part laid flat as best.stl); :func:`sections` counts the lines in each section the design
names (its in-plane thickness variables and its thinnest section); :func:`print_sheet` writes
``print_sheet.md`` (what to print, how, what to measure after printing: the coupon / compare /
re-trim loop of docs/print_to_part.md); :func:`slicer_config` and :func:`print_metadata` are what
``best.3mf`` carries (:mod:`pipeline.threemf`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "PrintSettings",
    "Section",
    "sections",
    "layers",
    "is_printed_polymer",
    "print_metadata",
    "slicer_config",
    "print_sheet",
    "PRINT_SHEET",
]

#: The print sheet's file name in a run folder (``design_print_sheet.md`` in an evaluate folder).
PRINT_SHEET = "print_sheet.md"

#: A material stiffer than this (MPa) is not an FDM filament (steels are 190-210 GPa, the
#: stiffest filled filaments ~10 GPa): its sheet says the settings do not apply.
MAX_FILAMENT_E_MPA = 15000.0


@dataclass(frozen=True)
class PrintSettings:
    """The FDM settings a design assumes (what the models' drawn sections stand for).

    Attributes
    ----------
    nozzle_mm, line_width_mm : float, mm
        0.4 mm: the nozzle ``min_feature_mm = 0.8`` (two lines) is written for.
    layer_height_mm : float, mm
        0.2 mm: a common layer for a 0.4 mm nozzle; the out-of-plane thickness is printed in
        whole layers of it.
    infill_percent : float, %
        100: the models take the part as solid; sparse infill makes a different part.
    whole_tolerance : float, lines
        A section within this many lines of a whole number counts as whole (0.05 lines = 0.02
        mm at 0.4 mm, about a printer's extrusion scatter).
    max_perimeters : int
        3: a section of more than 6 lines is perimeters and 100 % infill whatever the count
        (a thick-walled part needs no more loops).
    orientation : str
        How the part lies on the bed (as best.stl).
    """

    nozzle_mm: float = 0.4
    line_width_mm: float = 0.4
    layer_height_mm: float = 0.2
    infill_percent: float = 100.0
    whole_tolerance: float = 0.05
    max_perimeters: int = 3
    orientation: str = (
        "flat: the outline on the bed, its out-of-plane thickness along z (as the STL is "
        "written: laid flat, turned to the bed axes); every layer is a whole section of the "
        "part, so the flexures bend in the plane of the layers and no layer line is loaded across"
    )

    def lines(self, section_mm: float) -> float:
        """A section in lines of the line width (float)."""
        return float(section_mm) / self.line_width_mm

    def is_whole(self, section_mm: float) -> bool:
        n = self.lines(section_mm)
        return abs(n - round(n)) <= self.whole_tolerance and round(n) >= 1

    def perimeters(self, thinnest_mm: float) -> int:
        """Perimeter loops so the thinnest section is perimeters only: half its lines (a loop
        lays one line on each side of a wall), at least 1 and at most :attr:`max_perimeters`;
        thicker sections are filled by the 100 % infill between the loops."""
        n = int(math.floor(self.lines(thinnest_mm) / 2.0 + self.whole_tolerance))
        return min(self.max_perimeters, max(1, n))


@dataclass(frozen=True)
class Section:
    """One in-plane section of the part and the lines it is printed with.

    Attributes
    ----------
    name : str — the design variable, or ``thinnest section``.
    meaning : str — what it is.
    thickness_mm : float, mm.
    lines : float — thickness / line width.
    whole : bool — within :attr:`PrintSettings.whole_tolerance` of a whole number (>= 1).
    """

    name: str
    meaning: str
    thickness_mm: float
    lines: float
    whole: bool

    def note(self, settings: PrintSettings) -> str:
        """The sheet's words on the section: fine, or what the slicer will do instead."""
        if self.whole:
            return f"{round(self.lines)} lines"
        if self.lines < 1.0 - settings.whole_tolerance:
            return "WARNING: thinner than one line; the slicer drops or widens it"
        low = math.floor(self.lines)
        return (
            f"WARNING: {self.lines:.2f} lines, not whole: printed as {low} wider or {low + 1} "
            f"narrower lines (Arachne), or with a gap (classic walls); whole: "
            f"{low * settings.line_width_mm:.3g} or {(low + 1) * settings.line_width_mm:.3g} mm"
        )


def sections(
    names: tuple[str, ...],
    x: np.ndarray,
    meanings: Mapping[str, str],
    thinnest_mm: float | None,
    settings: PrintSettings = PrintSettings(),
) -> list[Section]:
    """The in-plane sections a design names, in lines of the line width.

    Parameters
    ----------
    names : the design variables; x : (n_var,) their values.
    meanings : ``words (unit)`` of each (:func:`pipeline.labels.variable_meanings`): a variable
        whose meaning names a thickness in mm that is not out-of-plane is a section.
    thinnest_mm : float, mm, optional
        The thinnest section of the outline (the kind's ``min_feature_mm`` metric, else the
        geometric estimate), listed first.

    Returns
    -------
    list of Section
    """
    from flexopt.pipeline.labels import split_meaning

    out = []
    if thinnest_mm is not None and np.isfinite(thinnest_mm) and thinnest_mm > 0:
        t = float(thinnest_mm)
        out.append(
            Section(
                "thinnest section",
                "the thinnest wall of the outline",
                t,
                settings.lines(t),
                settings.is_whole(t),
            )
        )
    for name, value in zip(names, np.asarray(x, dtype=float), strict=True):
        words, unit = split_meaning(meanings.get(name, name))
        text = words.lower()
        if unit != "mm" or "thickness" not in text or "out-of-plane" in text:
            continue
        out.append(
            Section(name, words, float(value), settings.lines(value), settings.is_whole(value))
        )
    return out


def layers(height_mm: float, settings: PrintSettings = PrintSettings()) -> tuple[int, float]:
    """Whole layers a height is printed in, and the printed height's error, % (the force error
    it causes: every force is proportional to the out-of-plane thickness)."""
    n = max(1, round(float(height_mm) / settings.layer_height_mm))
    return n, 100.0 * (n * settings.layer_height_mm / float(height_mm) - 1.0)


def is_printed_polymer(material: Any) -> bool:
    """Whether the study's material can be an FDM filament (E below :data:`MAX_FILAMENT_E_MPA`)."""
    return float(material.E_MPa) < MAX_FILAMENT_E_MPA


def print_metadata(
    material: Any,
    thickness_mm: float,
    thinnest_mm: float | None,
    settings: PrintSettings = PrintSettings(),
) -> dict[str, str]:
    """The print settings as ``name: text`` pairs (best.3mf's metadata, the sheet's table)."""
    n_layers, _ = layers(thickness_mm, settings)
    meta = {
        "material": str(material.name),
        "material_E_MPa": f"{float(material.E_MPa):g}",
        "orientation": settings.orientation,
        "nozzle_mm": f"{settings.nozzle_mm:g}",
        "line_width_mm": f"{settings.line_width_mm:g}",
        "layer_height_mm": f"{settings.layer_height_mm:g}",
        "layers": str(n_layers),
        "infill_percent": f"{settings.infill_percent:g}",
        "part_thickness_z_mm": f"{float(thickness_mm):.6g}",
    }
    if thinnest_mm is not None and np.isfinite(thinnest_mm):
        meta["thinnest_section_mm"] = f"{float(thinnest_mm):.4g}"
        meta["thinnest_section_lines"] = f"{settings.lines(thinnest_mm):.3g}"
        meta["perimeters"] = str(settings.perimeters(thinnest_mm))
    return meta


def slicer_config(
    material: Any, thinnest_mm: float | None, settings: PrintSettings = PrintSettings()
) -> dict[str, str]:
    """PrusaSlicer's names for the settings the design assumes (best.3mf's
    ``Metadata/Slic3r_PE.config``; a slicer takes the rest from its profile).

    The Arachne wall generator varies the line width, so a section that is not a whole number of
    lines is filled rather than left with a gap; 100 % rectilinear infill fills the sections
    thicker than the perimeters."""
    w = f"{settings.line_width_mm:g}"
    config = {
        "layer_height": f"{settings.layer_height_mm:g}",
        "first_layer_height": f"{settings.layer_height_mm:g}",
        "nozzle_diameter": f"{settings.nozzle_mm:g}",
        "extrusion_width": w,
        "perimeter_extrusion_width": w,
        "external_perimeter_extrusion_width": w,
        "infill_extrusion_width": w,
        "solid_infill_extrusion_width": w,
        "top_infill_extrusion_width": w,
        "fill_density": f"{settings.infill_percent:g}%",
        "fill_pattern": "rectilinear",
        "perimeter_generator": "arachne",
        "filament_type": str(material.name),
    }
    if thinnest_mm is not None and np.isfinite(thinnest_mm):
        config["perimeters"] = str(settings.perimeters(thinnest_mm))
    return config


def _table(rows: list[list[str]], head: list[str]) -> list[str]:
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


def print_sheet(
    *,
    title: str,
    run_dir: str,
    material: Any,
    part: Any,
    section_list: list[Section],
    response: Mapping[str, Any],
    files: Mapping[str, str],
    settings: PrintSettings = PrintSettings(),
) -> str:
    """The one-page print sheet (Markdown): what to print, how, the walls per section, what to
    measure after printing.

    Parameters
    ----------
    title : the study and design; run_dir : the folder (for the commands).
    material : fea.materials.Material (name, E_MPa, density_kg_m3).
    part : geometry.solid.FlatPart laid flat (best.stl's): footprint, thickness along z, outline.
    section_list : :func:`sections`.
    response : ``x``, ``y`` (the response table's drive and output columns), ``x_range`` (min,
        max) of the drive, ``table`` (the response file's name).
    files : ``stl``, ``3mf``, ``cad``, ``step``, ``dxf`` names of the part's files.
    settings : PrintSettings

    Returns
    -------
    str
        Markdown, one page.
    """
    w, h = part.footprint_mm
    t = float(part.thickness_mm)
    volume = float(part.outline.area) * t
    n_layers, layer_err = layers(t, settings)
    thinnest = section_list[0].thickness_mm if section_list else None
    lines = [f"# Print sheet — {title}", ""]
    if not is_printed_polymer(material):
        # a steel part is cut or machined: no printer settings, only what to measure
        lines += [
            f"**{material.name} (E {float(material.E_MPa):g} MPa) is not an FDM filament:** "
            f"make the part from `{files['step']}` or the outline `{files['dxf']}` "
            f"({w:.4g} x {h:.4g} mm, {t:.4g} mm thick, volume {volume:.5g} mm³); "
            f"`{files['cad']}` rebuilds it with its named dimensions. No print settings apply.",
            "",
        ]
        return "\n".join(lines + _measure(material, volume, response, run_dir, 1))
    lines += [
        "## What to print",
        f"- `{files['3mf']}` (the settings below are in it) or `{files['stl']}`: one part, "
        f"footprint {w:.4g} x {h:.4g} mm, {t:.4g} mm high, volume {volume:.5g} mm³.",
        f"- Material: **{material.name}** — the spool the design assumes (E "
        f"{float(material.E_MPa):g} MPa); a different spool gives a different force: calibrate "
        "it first (`flexopt coupon`, `flexopt calibrate`, docs/print_to_part.md).",
        f"- CAD: `{files['step']}` (solid), `{files['cad']}` (build123d script with the named "
        "dimensions: change one and run it).",
        "",
        "## How",
        f"- Orientation: {settings.orientation}.",
        f"- Nozzle {settings.nozzle_mm:g} mm, line width {settings.line_width_mm:g} mm (every "
        f"line type), layer height {settings.layer_height_mm:g} mm, infill "
        f"{settings.infill_percent:g} % rectilinear, Arachne walls"
        + (f", {settings.perimeters(thinnest)} perimeter(s)" if thinnest else "")
        + ".",
        f"- Height {t:.4g} mm = {t / settings.layer_height_mm:.2f} layers: printed as "
        f"{n_layers} layers ({n_layers * settings.layer_height_mm:.4g} mm, "
        f"{layer_err:+.2f} % force: every force is proportional to this height)"
        + (
            "."
            if abs(layer_err) < 0.5
            else "; WARNING: over 0.5 %, re-trim the height to whole layers."
        ),
        "",
        "## Walls per section",
        f"Each in-plane section in lines of {settings.line_width_mm:g} mm (the model takes the "
        "drawn section; a section that is not a whole number of lines is printed otherwise):",
        "",
    ]
    rows = [
        [s.name, s.meaning, f"{s.thickness_mm:.4g}", f"{s.lines:.2f}", s.note(settings)]
        for s in section_list
    ]
    if rows:
        lines += _table(rows, ["section", "what", "mm", "lines", "printed as"])
    else:
        lines.append("(the kind names no sections; measure the thinnest wall in the STL)")
    bad = [s.name for s in section_list if not s.whole]
    if bad:
        lines += [
            "",
            f"**{len(bad)} of {len(section_list)} sections are not a whole number of lines.** "
            "Check the slicer's preview of them (a tapered beam passes through every section "
            "between its ends: Arachne varies the line width along it). The calibrated thickness "
            "offset and a re-trim absorb what is left.",
        ]
    return "\n".join([*lines, "", *_measure(material, volume, response, run_dir)])


def _measure(
    material: Any, volume: float, response: Mapping[str, Any], run_dir: str, level: int = 2
) -> list[str]:
    """The sheet's last section: what to measure after printing, and the commands."""
    mass = volume * float(material.density_kg_m3) * 1e-6  # mm^3 x kg/m^3 -> g
    x, y = response.get("x"), response.get("y")
    x_lo, x_hi = response.get("x_range") or (float("nan"), float("nan"))
    lines = [
        f"{'#' * level} Measure after {'printing' if level == 2 else 'making'}",
        "1. Before testing: the height along z and the thinnest section (calipers / micrometer, "
        f"mm) against {'the table above' if level == 2 else 'the drawing'}"
        + (f"; the mass ({mass:.3g} g solid)." if np.isfinite(mass) else "."),
    ]
    if x and y:
        lines += [
            f"2. The response: drive `{x}` from {x_lo:.4g} to {x_hi:.4g} as the study does "
            f"(its boundary block), record `{y}` — a CSV with the columns `{x},{y}` (the units "
            f"are the names' suffixes), one row per reading, the drive increasing, at least 5 "
            f"rows. The prediction is `{response.get('table', 'best_response.csv')}`.",
            f"3. `flexopt compare {run_dir} measured.csv`: force and stiffness error in %.",
            f"4. Off by a common factor (a spool's E, a width): `flexopt retrim {run_dir} "
            "measured.csv` writes the corrected design; print it and measure again.",
        ]
    else:
        lines.append("2. The kind gives no response table to measure against.")
    lines.append("")
    return lines
