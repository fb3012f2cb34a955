"""A design's mesh and results as a VTU file (VTK XML unstructured grid) for ParaView.

``best.vtu`` of a run folder, ``design.vtu`` of an evaluate folder and ``flexopt export
--format vtu`` are made here from a :class:`optimise.problem.DesignResult` (issue #26 item 5).

What the file holds (one unstructured grid, coordinates in mm, z = 0 in the plane of the part):

- the beam model's centreline (``shapes_mm``) as ``line`` cells. Its points are the centreline
  nodes of the first load step (the rest state where the drive is 0; the field data says which
  drive the reference is at). Point data ``displacement_mm`` (n, 3) per load step, named
  ``displacement_mm step KKK DRIVE=VALUE``, and the last step again as plain
  ``displacement_mm`` (ParaView's Warp By Vector picks it up). points + ``displacement_mm`` of
  step k are the kind's deformed centreline of row k.
- the plane-stress model's triangles (``field_map``) as ``triangle`` cells with point data
  ``von_mises_MPa`` at the state the kind's label names (the end of the design range) and, where
  the field carries it (``displacement_mm``), the displacement of that same solve as
  ``displacement_mm`` (points + displacement_mm is the deformed part of that state).
- cell data ``model``: 0 on the beam's lines, 1 on the plane-stress triangles.
- field data (``<FieldData>`` of the grid, numbers only: VTK's ASCII string arrays cannot be
  read back by meshio, so each array's *name* carries the text): the units, the drive of every
  load step, the response table's columns per step, and the gaps, each as an array named
  ``gap: ...``. meshio 5.3's VTU writer drops ``field_data``, so :func:`vtu_bytes` inserts the
  block itself (ASCII Float64 arrays, which meshio and ParaView read).

The gaps, said in the file rather than filled with invented numbers: the beam model gives its
peak stress per load step (the ``peak_stress_MPa`` column), not a stress per node, so the beam's
points carry ``von_mises_MPa`` = NaN; a field without ``displacement_mm`` (a plugin's) leaves
the triangles' points at ``displacement_mm`` = NaN; a field has one state, so the beam's
per-step displacement arrays are NaN on the triangles (the plain ``displacement_mm`` holds the
field's state there); the beam's thickness and width are not in the result, so the lines are
bare centrelines.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

#: The name of the beams' displacement arrays (the plain one is the last load step).
DISPLACEMENT = "displacement_mm"
#: The name of the plane-stress stress array.
VON_MISES = "von_mises_MPa"
#: Cell data: which model a cell belongs to (values in :data:`MODELS`).
MODEL = "model"
#: The value of :data:`MODEL` per model.
MODELS = {"beam": 0, "plane_stress": 1}

UNITS = "units: coordinates and displacement_mm in mm, stress in MPa, force in N, moment in N mm"
GAP_BEAM_STRESS = (
    "gap: no per-node stress along the beam (the beam model reports its peak stress per load "
    "step only, see the table columns); von_mises_MPa is NaN on the beam's points"
)
GAP_FIELD_DISPLACEMENT = (
    "gap: the plane-stress result has no displacement; displacement_mm is NaN on the triangles' "
    "points (the triangles are the undeformed part)"
)
GAP_FIELD_STEPS = (
    "gap: the plane-stress field is one state (its label says which); the beam's per-step "
    "displacement arrays are NaN on the triangles' points, displacement_mm holds that state"
)
GAP_SECTION = "gap: beam thickness and width not in the result; lines are bare centrelines"


def has_mesh(result: Any) -> bool:
    """Whether ``result`` (a DesignResult) has anything to write: beam shapes or a field."""
    shapes = getattr(result, "shapes_mm", None)
    return (shapes is not None and np.asarray(shapes).ndim == 3) or bool(
        getattr(result, "field_map", None)
    )


def step_name(k: int, drive: str | None, value: float | None) -> str:
    """The point-data name of load step ``k``'s displacement (its drive and value if known)."""
    if drive is None or value is None:
        return f"{DISPLACEMENT} step {k:03d}"
    return f"{DISPLACEMENT} step {k:03d} {drive}={value:.6g}"


def _drive(result: Any, n_rows: int) -> tuple[str | None, np.ndarray | None]:
    """The drive column (the plot's ``x``) and its (n_rows,) values, when the table has them."""
    name = (getattr(result, "plot", None) or {}).get("x")
    values = (getattr(result, "table", None) or {}).get(name) if name else None
    if values is None or np.shape(values) != (n_rows,):
        return None, None
    return str(name), np.asarray(values, dtype=float)


def vtu_mesh(result: Any) -> Any:
    """The :class:`meshio.Mesh` of a design (see the module docstring), None when it has
    neither shapes nor a field.

    Parameters
    ----------
    result : DesignResult
        ``shapes_mm`` (n_rows, n_nodes, 2) mm, optional; ``field_map`` with ``points_mm``
        (m, 2) mm, ``triangles`` (t, 3) int, ``values`` (m,) MPa, ``displacement_mm`` (m, 2) mm
        (optional), optional; ``table`` of
        (n_rows,) columns; ``plot['x']`` the drive column.
    """
    import meshio

    shapes = getattr(result, "shapes_mm", None)
    shapes = np.asarray(shapes, dtype=float) if shapes is not None else None
    if shapes is not None and (shapes.ndim != 3 or shapes.shape[2] != 2 or not shapes.size):
        shapes = None
    fmap = getattr(result, "field_map", None) or None
    if shapes is None and fmap is None:
        return None
    points: list[np.ndarray] = []
    cells: list[tuple[str, np.ndarray]] = []
    model: list[np.ndarray] = []
    point_data: dict[str, list[np.ndarray]] = {}
    field_data: dict[str, np.ndarray] = {UNITS: np.zeros(1)}
    n_beam = 0
    if shapes is not None:
        n_rows, n_beam = shapes.shape[:2]
        ref = shapes[0]
        points.append(np.column_stack([ref, np.zeros(n_beam)]))
        lines = np.column_stack([np.arange(n_beam - 1), np.arange(1, n_beam)])
        cells.append(("line", lines))
        model.append(np.full(len(lines), MODELS["beam"], dtype=np.int32))
        drive, values = _drive(result, n_rows)
        disp = np.zeros((n_rows, n_beam, 3))
        disp[:, :, :2] = shapes - ref
        for k in range(n_rows):
            name = step_name(k, drive, None if values is None else float(values[k]))
            point_data[name] = [disp[k]]
        point_data[DISPLACEMENT] = [disp[-1]]
        point_data[VON_MISES] = [np.full(n_beam, np.nan)]
        if drive is not None and values is not None:
            field_data[f"reference: the points are load step 000, {drive}={values[0]:.6g}"] = (
                values[:1].copy()
            )
        for column, data in (getattr(result, "table", None) or {}).items():
            arr = np.asarray(data)
            if arr.shape == (n_rows,) and arr.dtype.kind in "biuf":
                field_data[f"per load step: {column}"] = arr.astype(float)
        field_data[GAP_BEAM_STRESS] = np.zeros(1)
        field_data[GAP_SECTION] = np.zeros(1)
    if fmap is not None:
        xy = np.asarray(fmap["points_mm"], dtype=float).reshape(-1, 2)
        tri = np.asarray(fmap["triangles"], dtype=np.int64).reshape(-1, 3)
        vm = np.asarray(fmap["values"], dtype=float).reshape(-1)
        points.append(np.column_stack([xy, np.zeros(len(xy))]))
        cells.append(("triangle", tri + n_beam))
        model.append(np.full(len(tri), MODELS["plane_stress"], dtype=np.int32))
        nan3 = np.full((len(xy), 3), np.nan)
        u = fmap.get("displacement_mm")
        u = None if u is None else np.asarray(u, dtype=float).reshape(-1, 2)
        if u is not None and len(u) != len(xy):
            u = None  # not the mesh's: said as a gap rather than misdrawn
        for name in point_data:
            if name not in (VON_MISES, DISPLACEMENT):
                point_data[name].append(nan3)
        point_data.setdefault(VON_MISES, []).append(vm)
        if u is not None or DISPLACEMENT in point_data:  # a field alone without u: no array
            disp = nan3 if u is None else np.column_stack([u, np.zeros(len(u))])
            point_data.setdefault(DISPLACEMENT, []).append(disp)
        label = str(fmap.get("label", "von Mises stress (MPa)"))
        field_data[f"plane stress {VON_MISES}: {label}; peak"] = np.array([float(np.max(vm))])
        limit = fmap.get("limit")
        if limit is not None:
            field_data[f"plane stress {VON_MISES}: allowable (MPa)"] = np.array([float(limit)])
        if u is None and shapes is not None:
            field_data[GAP_FIELD_DISPLACEMENT] = np.zeros(1)
        elif u is not None:
            field_data[f"plane stress {DISPLACEMENT}: max |u| (mm)"] = np.array(
                [float(np.max(np.hypot(u[:, 0], u[:, 1])))]
            )
        if shapes is not None:
            field_data[GAP_FIELD_STEPS] = np.zeros(1)
    field_data[f"{MODEL}: 0 beam centreline (lines), 1 plane stress (triangles)"] = np.zeros(1)
    return meshio.Mesh(
        np.vstack(points),
        cells,
        point_data={name: np.concatenate(parts) for name, parts in point_data.items()},
        cell_data={MODEL: model},
        field_data=field_data,
    )


def vtu_bytes(result: Any) -> bytes | None:
    """The VTU file of a design (binary zlib-compressed arrays, the field data in ASCII), None
    when it has neither shapes nor a field (:func:`vtu_mesh`)."""
    mesh = vtu_mesh(result)
    if mesh is None:
        return None
    with tempfile.TemporaryDirectory() as tmp:  # meshio's VTU writer wants a file name
        path = Path(tmp) / "design.vtu"
        mesh.write(path, file_format="vtu")
        data = path.read_bytes()
    return _with_field_data(data, mesh.field_data)


def _with_field_data(data: bytes, field_data: dict[str, np.ndarray]) -> bytes:
    """``data`` (a VTU file by meshio) with a ``<FieldData>`` block before its ``<Piece>``."""
    if not field_data:
        return data
    arrays = []
    for name, values in field_data.items():
        flat = np.asarray(values, dtype=float).reshape(-1)
        text = " ".join(repr(float(v)) if np.isfinite(v) else "nan" for v in flat)
        arrays.append(
            f'<DataArray type="Float64" Name={quoteattr(name)} NumberOfTuples="{len(flat)}" '
            f'format="ascii">{text}</DataArray>'
        )
    block = ("<FieldData>" + "".join(arrays) + "</FieldData>").encode("utf-8")
    at = data.index(b"<Piece")  # base64 and the header comment hold no '<'
    return data[:at] + block + data[at:]
