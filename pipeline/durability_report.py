"""The durability of one design as one record: fatigue life, creep hold and contact at stops.

A study's ``duty_cycle:`` (fatigue), ``hold:`` (creep) and ``stops:`` (contact) blocks put their
results in the design's summary and info (:func:`pipeline.verdict.with_life`,
:func:`pipeline.verdict.with_hold`, :func:`fea.beam_response.contact_summary`). This module
gathers them into one JSON-ready record (:func:`durability_record`) that report.md, report.html,
best.json and the API (``Result.durability``, ``BestDesign.durability``) all show, so every
reader sees the same numbers with the method and the data source named. No I/O, no solve.

Units: stresses in MPa, forces in N, gaps and penetrations in mm, times in h, temperatures in
deg C, lives in cycles and hours, rates in Hz. The methods and their limits: docs/durability.md.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = [
    "durability_html",
    "durability_markdown",
    "durability_record",
]

_CONTACT_METHOD = (
    "frictionless penalty contact between the beam and rigid stops, enforced inside the Newton "
    "solve (docs/contact.md)"
)


def _finite(value: Any) -> float | None:
    if value is None or isinstance(value, bool):
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


# --------------------------------------------------------------------------------------------
# The record


def _sn_data(study: Any) -> dict[str, Any]:
    """The S–N curve the life used, its data source and its surface factor (empty when the
    material has no built-in fatigue data)."""
    from flexopt.fea.errors import FeaError
    from flexopt.fea.fatigue import material_sn_curve, surface_factor
    from flexopt.fea.materials import get_fatigue_data

    spec = study.duty_cycle
    name = str(getattr(study.material, "name", study.material))
    try:
        data = get_fatigue_data(name)
        curve = material_sn_curve(name, surface=spec.surface)
    except FeaError:
        return {}
    out: dict[str, Any] = {
        "law": "Basquin S = a N^b (fully reversed amplitude S, MPa; N cycles)",
        "a_MPa": curve.a_MPa,
        "b": curve.b,
        "sigma_f_prime_MPa": curve.sigma_f_prime_MPa,
        "ultimate_MPa": curve.ultimate_MPa,
        "endurance_MPa": curve.endurance_MPa,
        "strength_1e6_MPa": curve.strength_MPa(1.0e6),
        "estimate": bool(curve.estimate),
        "data_method": data.method,
    }
    if data.method == "shigley":
        finish = spec.surface or data.surface
        out["surface"] = finish
        out["surface_factor"] = surface_factor(data.ultimate_MPa, finish)
    else:
        out["surface"] = "as printed (in the specimen data)"
        out["surface_factor"] = None
    return out


def _critical_location(result: Any, levels: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Where the most damaging level's peak stress sits: the response row nearest its extreme
    drive, with the kind's location column of the peak (``peak_stress_s_mm``: arc length from
    the start, mm) when it has one."""
    table = getattr(result, "table", None) or {}
    x_col = (getattr(result, "plot", None) or {}).get("x")
    if not levels or not x_col or x_col not in table:
        return {}
    damage = [(_finite(lv.get("damage")) or 0.0, -i) for i, lv in enumerate(levels)]
    worst = levels[-max(damage)[1]]
    lo, hi = _finite(worst.get("stress_min_MPa")) or 0.0, _finite(worst.get("stress_max_MPa"))
    drive = worst.get("drive_max") if abs(hi or 0.0) >= abs(lo) else worst.get("drive_min")
    x = np.asarray(table[x_col], dtype=float)
    if _finite(drive) is None or not np.isfinite(x).any():
        return {}
    # the table traces one sign; a reversed level's other extreme is its mirror
    row = int(np.nanargmin(np.abs(np.abs(x) - abs(float(drive)))))
    out: dict[str, Any] = {"level": levels.index(worst) + 1, "drive": float(drive),
                           "drive_column": str(x_col), "row": row}  # fmt: skip
    for col in ("peak_stress_s_mm", "peak_stress_x_mm", "peak_stress_y_mm"):
        if col in table:
            out[col] = _finite(np.asarray(table[col], dtype=float)[row])
    return out


def _stress_model(study: Any, scale: Any, figure: Any) -> str:
    """Which model's stress the life used: the figure the beam's peak was scaled to (``plane
    stress``, ``3D solid``), else the model of the response table's own ``peak_stress_MPa``
    (``beam``), as the kind names its figures (:func:`pipeline.verdict.figures_of`)."""
    from flexopt.pipeline.verdict import figures_of

    ladder = figures_of(study).get("peak_stress_MPa", ())
    if _finite(scale) not in (None, 1.0):
        for f in sorted(ladder, key=lambda f: -f.rank):
            if str(figure or "").startswith(f.model):
                return f.model
    own = [f.model for f in ladder if f.quantity == "peak_stress_MPa"]
    return own[0] if own else f"the {study.kind} kind's own solve"


def _fatigue(study: Any, result: Any) -> dict[str, Any]:
    summary = getattr(result, "summary", None) or {}
    info = getattr(result, "info", None) or {}
    spec = study.duty_cycle
    fat = info.get("fatigue")
    if not isinstance(fat, Mapping):  # the life could not be computed: say why
        return {"note": summary.get("fatigue_note") or "the life was not computed",
                "correction": spec.correction, "rate_hz": spec.rate_hz}  # fmt: skip
    levels = [dict(lv) for lv in fat.get("levels") or ()]
    rows = [
        {
            "level": i + 1,
            "drive_min": lv.get("drive_min"),
            "drive_max": lv.get("drive_max"),
            "amplitude_MPa": lv.get("amplitude_MPa"),
            "mean_MPa": lv.get("mean_MPa"),
            "cycles": lv.get("cycles"),
            "cycles_to_failure": lv.get("cycles_to_failure"),
            "damage": lv.get("damage"),
            # a kind with a stress per setting (a leaf joint): the setting the level ran at
            **({"setting": lv["setting"]} if lv.get("setting") else {}),
        }
        for i, lv in enumerate(levels)
    ]
    return {
        "levels": rows,
        **({"setting_note": fat["life_setting"]} if fat.get("life_setting") else {}),
        "miner_sum": fat.get("fatigue_damage_per_cycle_block"),
        "life_cycles": fat.get("life_cycles"),
        "life_hours": fat.get("life_hours"),
        "life_infinite": fat.get("life_infinite"),
        "life_in_range": fat.get("life_in_range"),
        "rate_hz": spec.rate_hz,
        "stress_model": _stress_model(study, fat.get("scale"), fat.get("life_stress_figure")),
        "stress_figure": fat.get("life_stress_figure"),
        "stress_scale": fat.get("scale"),
        "critical_location": _critical_location(result, levels),
        "correction": spec.correction,
        "method": fat.get("life_method"),
        "source": fat.get("fatigue_data_source"),
        "sn_curve": _sn_data(study),
    }


def _hold(result: Any) -> dict[str, Any]:
    summary = getattr(result, "summary", None) or {}
    info = getattr(result, "info", None) or {}
    rec = info.get("hold")
    if not isinstance(rec, Mapping):
        return {"note": summary.get("hold_note") or "the hold was not computed"}
    law = dict(rec.get("law") or {})
    at = rec.get("at")
    held = next((k for k in rec if k.startswith("held_") and k not in ("held_drive",
                 "held_force")), None)  # fmt: skip
    initial = next((k for k in rec if k.startswith("hold_initial_")), None)
    return {
        "at": at,
        "time_h": rec.get("hold_time_h"),
        "temperature_C": rec.get("hold_temperature_C"),
        "reduced_time_h": rec.get("reduced_time_h"),
        "held_name": held,
        "held_value": rec.get(held) if held else None,
        "held_drive": rec.get("held_drive"),
        "held_force": rec.get("held_force"),
        "initial_name": initial,
        "initial_value": rec.get(initial) if initial else None,
        "retention": rec.get("relaxation_ratio"),
        "compliance_ratio": rec.get("compliance_ratio"),
        "stress_MPa": rec.get("stress_MPa"),
        "stress_ratio": rec.get("hold_stress_ratio"),
        "max_stress_ratio": law.get("max_stress_ratio"),
        "in_range": rec.get("hold_in_range"),
        "note": rec.get("hold_note") or "",
        "law": {"name": "Findley power law J(t) = (1 + (t/tau)^n) / E0", **law},
        "assumed": bool(law.get("assumed")),
        "source": rec.get("creep_data_source"),
        "method": rec.get("hold_method"),
    }


def _contact(study: Any, result: Any) -> dict[str, Any]:
    summary = getattr(result, "summary", None) or {}
    names = [str(s.name) for s in study.stops.outlines]
    # the driven value's unit: a beam's force or displacement, a pivot's or leaf joint's angle
    units = ("force_N", "rotation_deg", "deflection_deg")
    unit = next((u for u in units if f"first_contact_{u}" in summary), "displacement_mm")
    stops = [
        {
            "stop": name,
            "max_contact_force_N": summary.get(f"{name}_max_contact_force_N"),
            f"first_contact_{unit}": summary.get(f"{name}_first_contact_{unit}"),
            "min_gap_mm": summary.get(f"{name}_min_gap_mm"),
        }
        for name in names
    ]
    return {
        "stops": stops,
        "first_contact_column": f"first_contact_{unit}",
        f"first_contact_{unit}": summary.get(f"first_contact_{unit}"),
        "max_contact_force_N": summary.get("max_contact_force_N"),
        "max_penetration_mm": summary.get("max_penetration_mm"),
        "penetration_tolerance_mm": summary.get("contact_penetration_tolerance_mm"),
        "penetration_ok": summary.get("contact_penetration_ok"),
        "penalty_factor": summary.get("contact_penalty_factor"),
        "penalty_raises": summary.get("contact_penalty_raises"),
        "rows_in_contact": summary.get("contact_rows"),
        "message": summary.get("contact_message") or "",
        "method": _CONTACT_METHOD,
    }


def _slot_contact(result: Any) -> dict[str, Any]:
    """A SEA spring's self-contact across its slots (``contact:``; its kind's
    ``info["slot_contact"]``, pipeline/studies/_sea_spring_contact.py): one row per direction."""
    rec = (getattr(result, "info", None) or {}).get("slot_contact")
    if not rec:
        return {"note": "no overload curve (the design was not solved with contact)"}
    values = {**(getattr(result, "info", None) or {}), **(getattr(result, "summary", None) or {})}
    keys = ("first_contact_deg", "first_contact_torque_Nm", "peak_stress_at_first_contact_MPa",
            "overload_deg", "overload_torque_Nm", "overload_peak_stress_MPa",
            "max_contact_force_N", "min_gap_mm", "rows_in_contact", "converged")  # fmt: skip
    return {
        "slots": [
            {"direction": name, **{k: d.get(k) for k in keys}}
            for name, d in rec["directions"].items()
        ],  # fmt: skip
        "working_range_gap_mm": rec.get("working_range_gap_mm"),
        "slots_clear_in_working_range": values.get("slots_clear_in_working_range"),
        "penalty_factor": rec.get("penalty_factor"),
        "method": rec.get("method"),
        "message": values.get("slots_clear_in_working_range_message") or "",
    }


def durability_record(study: Any, result: Any) -> dict[str, Any]:
    """The durability of ``result`` under the study's blocks, JSON-ready.

    Parameters
    ----------
    study : the study (its ``duty_cycle``, ``hold``, ``stops`` and ``material``).
    result : the design's result or detail (:class:`optimise.problem.DesignResult`): its
        ``summary``, ``info`` (``info["fatigue"]``, ``info["hold"]``), ``table`` and ``plot``.

    Returns
    -------
    dict
        ``fatigue`` (with a ``duty_cycle:``): ``levels`` (one record per level: ``level``,
        ``drive_min``/``drive_max`` in the driven unit, ``amplitude_MPa``, ``mean_MPa``,
        ``cycles`` per block, ``cycles_to_failure``, ``damage``), ``miner_sum`` (damage per
        block), ``life_cycles``, ``life_hours`` (None: infinite or no rate), ``stress_figure``,
        ``critical_location``, ``correction``, ``method``, ``source`` and ``sn_curve`` (``a_MPa``,
        ``b``, ``endurance_MPa``, ``surface``, ``surface_factor``, ...); ``hold`` (with a
        ``hold:``): ``time_h``, ``temperature_C``, ``held_name``/``held_value``,
        ``initial_value``, ``retention``, ``stress_ratio`` against ``max_stress_ratio``,
        ``law`` (its parameters), ``assumed``, ``source``, ``method``; ``contact`` (with
        ``stops:``): ``stops`` (per stop ``max_contact_force_N``, ``first_contact_...``,
        ``min_gap_mm``), ``max_penetration_mm``, ``penalty_factor``, ``method``. Each block only
        when the study has it; empty without any. A block whose figures could not be computed
        holds a ``note`` saying why.
    """
    out: dict[str, Any] = {}
    if study is None or result is None:
        return out
    blocks = (("duty_cycle", "fatigue", lambda: _fatigue(study, result)),
              ("hold", "hold", lambda: _hold(result)),
              ("stops", "contact", lambda: _contact(study, result)),
              ("contact", "contact", lambda: _slot_contact(result)))  # fmt: skip
    for key, name, make in blocks:
        if getattr(study, key, None) is None:
            continue
        try:
            out[name] = make()
        except Exception as exc:  # a report must not cost the run: say why, keep the rest
            out[name] = {"note": f"not reported: {type(exc).__name__}: {exc}"}
    return out


# --------------------------------------------------------------------------------------------
# The report's words: one list of blocks (paragraphs and tables) for Markdown and HTML alike


def _fmt(value: Any) -> str:
    """One cell as report.md's ``format_value`` writes it (6 significant digits, yes/no, ``–``
    for None); repeated here because pipeline.report imports this module."""
    if isinstance(value, np.generic):
        value = value.item()
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.6g}" if math.isfinite(value) else str(value)
    if isinstance(value, list | tuple | np.ndarray):
        return "[" + ", ".join(_fmt(v) for v in np.asarray(value, dtype=object).ravel()) + "]"
    return " ".join(str(value).split()).replace("|", "\\|")


def _life(cycles: Any, infinite: Any = None) -> str:
    if cycles is None and infinite:
        return "infinite (every level below the endurance limit)"
    return _fmt(cycles)


def _blocks(record: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """``(kind, content)`` items: ``("h", title)``, ``("p", text)``, ``("table", (header,
    rows))``, in reading order."""
    out: list[tuple[str, Any]] = []
    fat = record.get("fatigue")
    if fat is not None:
        out.append(("h", "Fatigue (duty_cycle)"))
        if "levels" not in fat:
            out.append(("p", f"The life was not computed: {fat.get('note')}"))
        else:
            rows = [
                [lv["level"], lv["drive_min"], lv["drive_max"], lv["amplitude_MPa"],
                 lv["mean_MPa"], lv["cycles"],
                 "infinite" if lv["cycles_to_failure"] is None else lv["cycles_to_failure"],
                 lv["damage"]]
                for lv in fat["levels"]
            ]  # fmt: skip
            header = ["level", "drive min", "drive max", "amplitude (MPa)", "mean (MPa)",
                      "cycles per block", "cycles to failure", "damage per block"]  # fmt: skip
            if any("setting" in lv for lv in fat["levels"]):  # a stress per setting
                header.insert(1, "setting")
                for row, lv in zip(rows, fat["levels"], strict=True):
                    row.insert(1, lv.get("setting") or "–")
            out.append(("table", (header, rows)))
            if fat.get("setting_note"):
                out.append(("p", f"Settings: {fat['setting_note']}."))
            hours = fat.get("life_hours")
            where = fat.get("critical_location") or {}
            place = ", ".join(
                f"{k.removeprefix('peak_stress_').removesuffix('_mm')} = {_fmt(v)} mm"
                for k, v in where.items()
                if k.startswith("peak_stress_")
            )
            location = (
                f"level {where['level']} at {where['drive_column']} = {_fmt(where['drive'])}"
                + (f" ({place})" if place else "")
                if where
                else "–"
            )
            sn = fat.get("sn_curve") or {}
            curve = (
                f"S = {_fmt(sn.get('a_MPa'))} N^{_fmt(sn.get('b'))} MPa, S(10^6) = "
                f"{_fmt(sn.get('strength_1e6_MPa'))} MPa, endurance limit "
                + (f"{_fmt(sn['endurance_MPa'])} MPa" if sn.get("endurance_MPa") else "none")
                + f", Sut = {_fmt(sn.get('ultimate_MPa'))} MPa"
                + (" (an estimate)" if sn.get("estimate") else "")
                if sn
                else "–"
            )
            surface = (
                f"{sn.get('surface')}"
                + (f", ka = {_fmt(sn['surface_factor'])}" if sn.get("surface_factor") else "")
                if sn
                else "–"
            )
            out.append(("table", (["", ""], [
                ["Miner's sum (damage per block)", _fmt(fat.get("miner_sum"))],
                ["life, cycles", _life(fat.get("life_cycles"), fat.get("life_infinite"))],
                ["life, hours", _life(hours, fat.get("life_infinite")) if hours is not None
                 or fat.get("life_infinite") else "– (no rate_hz)"],
                ["rate", f"{_fmt(fat.get('rate_hz'))} Hz" if fat.get("rate_hz") else "–"],
                ["within the stress-life range (N ≥ 10^3)", _fmt(fat.get("life_in_range"))],
                ["stress figure", f"{fat.get('stress_model')}: "
                 f"{fat.get('stress_figure') or 'the response table'}"],
                ["critical location", location],
                ["mean-stress correction", fat.get("correction")],
                ["S-N curve", curve],
                ["surface", surface],
                ["S-N data source", fat.get("source") or "–"],
                ["method", fat.get("method") or "–"],
            ])))  # fmt: skip
    hold = record.get("hold")
    if hold is not None:
        out.append(("h", "Creep (hold)"))
        if "law" not in hold:
            out.append(("p", f"The hold was not computed: {hold.get('note')}"))
        else:
            law = hold["law"]
            label = "ASSUMED, illustrative creep law (not measured)" if hold["assumed"] else ""
            temp = hold.get("temperature_C")
            ref = law.get("reference_temperature_C")
            rows = [
                ["creep law", f"{law['name']}" + (f" — **{label}**" if label else "")],
                ["parameters", f"tau = {_fmt(law.get('tau_h'))} h, n = {_fmt(law.get('n'))}, "
                 f"fitted at {_fmt(ref)} C up to {_fmt(law.get('max_stress_ratio'))} x strength"],
                ["creep data source", law.get("source") or "–"],
                ["held", f"the {hold.get('at')} for {_fmt(hold.get('time_h'))} h at "
                 + (f"{_fmt(temp)} C" if temp is not None else f"the law's {_fmt(ref)} C")],
                [f"start: {hold.get('initial_name') or '–'}", _fmt(hold.get("initial_value"))],
                [f"after the hold: {hold.get('held_name') or '–'}", _fmt(hold.get("held_value"))],
                ["retention E_R(t)/E0", _fmt(hold.get("retention"))],
                ["creep compliance ratio E0 J(t)", _fmt(hold.get("compliance_ratio"))],
                ["stress of the hold (MPa)", _fmt(hold.get("stress_MPa"))],
                ["stress ratio / the law's limit",
                 f"{_fmt(hold.get('stress_ratio'))} / {_fmt(hold.get('max_stress_ratio'))} ("
                 + ("within" if hold.get("in_range") else "**beyond: out of range**") + ")"],
                ["method", hold.get("method") or "–"],
            ]  # fmt: skip
            out.append(("table", (["", ""], rows)))
            if hold.get("note"):
                out.append(("p", str(hold["note"])))
    contact = record.get("contact")
    if contact is not None and "slots" in contact:
        out += _slot_blocks(contact)
    elif contact is not None and "stops" not in contact:
        out += [("h", "Contact (stops)"), ("p", f"Contact: {contact.get('note')}")]
    elif contact is not None:
        out.append(("h", "Contact (stops)"))
        col = contact["first_contact_column"]
        unit = col.rsplit("_", 1)[-1]  # mm, N or deg (a pivot's rotation)
        rows = [
            [s["stop"], s.get("max_contact_force_N"), s.get(col), s.get("min_gap_mm")]
            for s in contact["stops"]
        ]
        out.append(("table", (["stop", "largest force (N)",
                               f"first contact ({col.removeprefix('first_contact_')})",
                               "smallest gap (mm)"], rows)))  # fmt: skip
        tol = contact.get("penetration_tolerance_mm")
        ok = contact.get("penetration_ok")
        rows = [
            [f"first contact (any stop), {unit}", _fmt(contact.get(col))],
            ["largest contact force, N", _fmt(contact.get("max_contact_force_N"))],
            ["largest penetration (all stops), mm",
             f"{_fmt(contact.get('max_penetration_mm'))} (tolerance {_fmt(tol)} mm: "
             + ("within" if ok else "**exceeded**") + ")"],
            ["penalty factor (k = factor x EI / h^3)",
             f"{_fmt(contact.get('penalty_factor'))} (raised "
             f"{_fmt(contact.get('penalty_raises'))} times)"],
            ["rows in contact", _fmt(contact.get("rows_in_contact"))],
            ["method", contact.get("method")],
        ]  # fmt: skip
        out.append(("table", (["", ""], rows)))
        if contact.get("message"):
            out.append(("p", str(contact["message"])))
    return out


def _slot_blocks(contact: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """The SEA spring's contact across its slots: first contact and overload per direction."""
    rows = [[s["direction"], s.get("first_contact_deg"), s.get("first_contact_torque_Nm"),
             s.get("peak_stress_at_first_contact_MPa"), s.get("overload_deg"),
             s.get("overload_torque_Nm"), s.get("overload_peak_stress_MPa"),
             s.get("max_contact_force_N"), s.get("rows_in_contact")]
            for s in contact["slots"]]  # fmt: skip
    out: list[tuple[str, Any]] = [("h", "Contact (slots)")]
    out.append(("table", (["direction", "first contact (deg)", "torque there (N m)",
                           "peak stress there (MPa)", "overload (deg)", "torque (N m)",
                           "peak stress with contact (MPa)", "largest contact force (N)",
                           "rows in contact"], rows)))  # fmt: skip
    out.append(("table", (["", ""], [
        ["slots clear in the working range", _fmt(contact.get("slots_clear_in_working_range"))],
        ["gap at +-theta_T without contact, mm",
         ", ".join(f"{k} {_fmt(v)}" for k, v in (contact.get("working_range_gap_mm") or {}).items())
         or "–"],
        ["penalty factor (eps = factor x E / h)", _fmt(contact.get("penalty_factor"))],
        ["method", contact.get("method")],
    ])))  # fmt: skip
    if contact.get("message"):
        out.append(("p", str(contact["message"])))
    return out


def durability_markdown(record: Mapping[str, Any]) -> list[str]:
    """report.md lines of the ``## Durability`` section (empty without a block)."""
    if not record:
        return []
    lines = ["## Durability", "", "Fatigue, creep and contact of the design under the study's "
             "duty_cycle, hold and stops (docs/durability.md); the same records are in "
             "best.json's `durability`.", ""]  # fmt: skip
    for kind, content in _blocks(record):
        if kind == "h":
            lines += [f"### {content}", ""]
        elif kind == "p":
            lines += [" ".join(str(content).split()), ""]
        else:
            header, rows = content
            lines.append("| " + " | ".join(header) + " |")
            lines.append("|" + "|".join("---" for _ in header) + "|")
            lines += ["| " + " | ".join(_fmt(v) for v in r) + " |" for r in rows]
            lines.append("")
    return lines


def durability_html(record: Mapping[str, Any]) -> str:
    """The body of report.html's ``Durability`` section ("" without a block)."""
    if not record:
        return ""

    def cell(value: Any) -> str:
        text = html.escape(value if isinstance(value, str) else _fmt(value), quote=True)
        return text.replace("**", "")  # Markdown emphasis is for report.md only

    parts = []
    for kind, content in _blocks(record):
        if kind == "h":
            parts.append(f"<h3>{html.escape(content)}</h3>")
        elif kind == "p":
            parts.append(f"<p class='note'>{cell(str(content))}</p>")
        else:
            header, rows = content
            head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
            body = "".join(
                "<tr>" + "".join(f"<td>{cell(v)}</td>" for v in r) + "</tr>" for r in rows
            )
            parts.append(f"<table class='num'><thead><tr>{head}</tr></thead>"
                         f"<tbody>{body}</tbody></table>")  # fmt: skip
    return "".join(parts)
