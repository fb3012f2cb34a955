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

Where the result has them (:attr:`DesignResult.beam_field`, :func:`fea.beam_fields.beam_field`),
the beam's points carry the last step's ``von_mises_MPa`` (the larger magnitude of the two
fibre stresses), ``stress_fibre_left_MPa`` / ``stress_fibre_right_MPa`` (signed, MPa) and
``thickness_mm``, and its lines the cell data ``thickness_mm`` and ``width_mm`` (mm). The
plane-stress vertices carry ``stress_counted`` (1 where the check's peak counts them). A part
of several members (a pivot's leaves, a mechanism's beams: :func:`fea.beam_fields.members_field`)
is one centreline with one separator node between two members: no line uses it (its arrays
NaN, its point put on its neighbour so no coordinate is NaN), and the lines carry the cell data
``member`` (the member's index). A mechanism's beams also carry ``stress_judged_MPa``
(fea/mechanism_fields.py: the stress the verdict reads at each node).

The gaps, said in the file rather than filled with invented numbers: a result without beam
stresses leaves the beam's ``von_mises_MPa`` NaN and its lines bare centrelines; a field without
``displacement_mm`` (a plugin's) leaves the triangles' points at ``displacement_mm`` = NaN; the
beam's per-step displacement arrays are NaN on the triangles (the plain ``displacement_mm``
holds the field's last state there).

Beside it (:func:`vtu_files`): ``best.pvd``, the ParaView collection of the load steps
(timestep = the drive value, in the drive column's unit), one ``best_steps/best_KKK.vtu`` per
step (:func:`step_mesh`: that step's beam state and, where the check solved it, its
plane-stress state, under plain names), and ``best_3d.vtu``, the 3D check's P2 tetrahedra
(:func:`solid_vtu_bytes`). A kind of several load cases (a mechanism) draws its first case
there and every other case in ``best_CASE.vtu`` / ``best_CASE.pvd`` with its steps in
``best_steps/best_CASE_KKK.vtu`` (:func:`load_case_series`; field data ``load case: NAME``).
docs/print_to_part.md says what each holds and how to open them.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path
from types import SimpleNamespace
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

#: Point data on the beam's nodes (fea/beam_fields.py): the signed stress of the outer fibre at
#: +t/2 along the normal (the tangent turned 90 degrees counter-clockwise) and at -t/2 (MPa).
FIBRE_LEFT = "stress_fibre_left_MPa"
FIBRE_RIGHT = "stress_fibre_right_MPa"
#: The beam's section: point data (at the nodes) and cell data (per line segment), mm.
THICKNESS = "thickness_mm"
#: Cell data: the beam's out-of-plane width per line segment, mm.
WIDTH = "width_mm"
#: Point data on the plane-stress vertices: 1 where the check's peak stress counts the vertex,
#: 0 on the elements it leaves out (touching clamps and drives: singular corners); NaN elsewhere.
STRESS_COUNTED = "stress_counted"

UNITS = "units: coordinates and displacement_mm in mm, stress in MPa, force in N, moment in N mm"
BEAM_STRESS_NOTE = (
    "beam: von_mises_MPa on the beam's points is the larger magnitude of its two outer-fibre "
    "stresses (uniaxial), sampled by the solver at the node (fea/beam_fields.py)"
)
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
#: Cell data on the beam's lines of a part of several members: the member's index (0, 1, ...
#: in the kind's order; NaN on the plane-stress triangles).
MEMBER = "member"
#: Point data on a mechanism's beams: the equivalent stress times the factor the verdict
#: applies there (a filleted root's K_t over its flare, at least the fidelity check's stress
#: ratio: fea/mechanism_fields.py), MPa; per load step its largest is the verdict's figure.
JUDGED = "stress_judged_MPa"
#: Field data: what the kind's verdict multiplies the beam's largest von_mises_MPa by.
STRESS_FACTOR_NOTE = (
    "beam: the verdict's peak_stress_MPa is the largest von_mises_MPa on the beam's points "
    "times this factor (a notch hinge's K_t: the nodes carry its equivalent beam's nominal stress)"
)
GAP_SECTION = "gap: beam thickness and width not in the result; lines are bare centrelines"
SOLID_NOTE = (
    "3D check: linear elasticity on P2 tetrahedra at the check's drive (the hub turned "
    "counter-clockwise: sea_spring by +theta_T, threshold_spring to the end of the design "
    "range), the last thickness checked (the part's ST); von_mises_MPa at a vertex averaged "
    "over its tetrahedra, at an edge node the mean of its two vertices"
)
SOLID_HALF = (
    "3D check: the half model z >= 0 (symmetric about the mid-plane z = 0): ParaView's Reflect "
    "filter about z gives the whole part"
)
SOLID_VERDICT = (
    "3D peak_stress_3d_MPa the verdict reads (MPa): the nonlinear 2D peak (refined where "
    "converged) times the linear 3D / 2D peak ratio, not this linear state's own peak"
)
#: Field data of a kind with several load cases: the case a file draws (its name follows).
LOAD_CASE_NOTE = "load case: "
GAP_STEP_FIELD = "gap: the plane-stress field was not solved at this load step (see best.pvd)"


def has_mesh(result: Any) -> bool:
    """Whether ``result`` (a DesignResult) has anything to write: beam shapes or a field."""
    shapes = getattr(result, "shapes_mm", None)
    return (
        (shapes is not None and np.asarray(shapes).ndim == 3)
        or bool(getattr(result, "field_map", None))
        or bool(getattr(result, "solid_field", None))
    )


def vtu_mesh_possible(result: Any) -> bool:
    """Whether :func:`vtu_mesh` has anything to write (beam shapes or a plane field)."""
    shapes = getattr(result, "shapes_mm", None)
    return (shapes is not None and np.asarray(shapes).ndim == 3) or bool(
        getattr(result, "field_map", None)
    )


def solid_vtu_bytes(result: Any) -> bytes | None:
    """best_3d.vtu: the 3D check's P2 tetrahedra (VTK quadratic tetrahedra) with the
    displacement and von Mises stress of its last state (:meth:`fea.solid3d.Solid3DModel.
    last_field`), None without a 3D check. Written as zlib-compressed binary; the field's
    arrays go to meshio as they are (already 3D: no padded copies of the 400k-DOF state)."""
    import meshio

    sf = getattr(result, "solid_field", None)
    if not sf:
        return None
    counted = np.asarray(sf["stress_counted"], dtype=np.uint8)
    mesh = meshio.Mesh(
        sf["points_mm"],
        [("tetra10", sf["tetra10"])],
        point_data={
            DISPLACEMENT: sf["displacement_mm"],
            VON_MISES: sf["von_mises_MPa"],
            STRESS_COUNTED: counted,
        },
        field_data={
            UNITS: np.zeros(1),
            SOLID_NOTE: np.zeros(1),
            **({SOLID_HALF: np.zeros(1)} if sf.get("symmetric") else {}),
            f"3D {VON_MISES}: peak over the counted vertices": np.array(
                [float(np.max(np.asarray(sf["von_mises_MPa"])[counted.astype(bool)]))]
                if counted.any()
                else [np.nan]
            ),
            **(
                {SOLID_VERDICT: np.array([float(sf["verdict_peak_MPa"])])}
                if sf.get("verdict_peak_MPa") is not None
                else {}
            ),
        },
    )
    return _mesh_bytes(mesh)


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
    cell_data: dict[str, list[np.ndarray]] = {}
    field_data: dict[str, np.ndarray] = {UNITS: np.zeros(1)}
    n_beam = 0
    if shapes is not None:
        n_rows, n_beam = shapes.shape[:2]
        ref, lines, keep = beam_points(shapes)
        points.append(np.column_stack([ref, np.zeros(n_beam)]))
        cells.append(("line", lines))
        model.append(np.full(len(lines), MODELS["beam"], dtype=np.int32))
        drive, values = _drive(result, n_rows)
        disp = np.zeros((n_rows, n_beam, 3))
        disp[:, :, :2] = np.where(separators(shapes)[None, :, None], 0.0, shapes - ref)
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
        bfield = beam_arrays(result, n_rows, n_beam)
        if bfield is None:
            field_data[GAP_BEAM_STRESS] = np.zeros(1)
            field_data[GAP_SECTION] = np.zeros(1)
        else:  # the last load step's stresses, as the plain displacement_mm is the last step's
            point_data[VON_MISES] = [bfield["equivalent_MPa"][-1]]
            point_data[FIBRE_LEFT] = [bfield["fibre_left_MPa"][-1]]
            point_data[FIBRE_RIGHT] = [bfield["fibre_right_MPa"][-1]]
            point_data[THICKNESS] = [bfield["thickness_mm"]]
            cell_data[THICKNESS] = [bfield["segment_thickness_mm"][keep]]
            cell_data[WIDTH] = [bfield["width_mm"][keep]]
            field_data[BEAM_STRESS_NOTE] = np.zeros(1)
            field_data.update(beam_notes(bfield))
            if "member_of_segment" in bfield:
                cell_data[MEMBER] = [bfield["member_of_segment"][keep]]
            if "as_made_MPa" in bfield:
                point_data[JUDGED] = [bfield["as_made_MPa"][-1]]
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
                point_data[name].append(nan3 if point_data[name][0].ndim == 2 else nan3[:, 0])
        for name in cell_data:
            cell_data[name].append(np.full(len(tri), np.nan))
        if fmap.get("stress_counted") is not None:
            point_data[STRESS_COUNTED] = [np.full(n_beam, np.nan), _counted(fmap, len(xy))]
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
        cell_data={MODEL: model, **cell_data},
        field_data=field_data,
    )


def vtu_bytes(result: Any) -> bytes | None:
    """The VTU file of a design (binary zlib-compressed arrays, the field data in ASCII), None
    when it has neither shapes nor a field (:func:`vtu_mesh`)."""
    mesh = vtu_mesh(result)
    if mesh is None:
        return None
    return _mesh_bytes(mesh)


def _mesh_bytes(mesh: Any) -> bytes:
    """A meshio mesh as VTU bytes (zlib-compressed binary arrays, field data in ASCII)."""
    data = _in_memory_vtu(mesh)
    if data is None:
        with tempfile.TemporaryDirectory() as tmp:  # meshio's VTU writer wants a file name
            path = Path(tmp) / "design.vtu"
            mesh.write(path, file_format="vtu", compression="zlib")
            data = path.read_bytes()
    return _with_field_data(data, mesh.field_data)


def _in_memory_vtu(mesh: Any) -> bytes | None:
    """meshio's VTU of ``mesh`` written to an anonymous in-memory file (Linux's
    ``memfd_create``, opened by name through ``/proc/self/fd``); None where there is none.

    Why: meshio's writer wants a file name, and a temporary folder per file costs a mkdir and
    an rmdir on the disk. While the run's writer thread fsyncs the report's files, ext4 makes
    each rmdir wait for the journal: 62 of them (one per load step) took ~0.17 s of the
    report's critical path, against ~4 ms for the same files in memory.
    """
    create = getattr(os, "memfd_create", None)
    if create is None or not os.path.isdir("/proc/self/fd"):
        return None
    try:
        fd = create("flexopt-vtu", getattr(os, "MFD_CLOEXEC", 0))
    except OSError:
        return None
    try:
        mesh.write(f"/proc/self/fd/{fd}", file_format="vtu", compression="zlib")
        size = os.fstat(fd).st_size
        return os.pread(fd, size, 0) if size else b""
    finally:
        os.close(fd)


def _with_field_data(data: bytes, field_data: dict[str, np.ndarray]) -> bytes:
    """``data`` (a VTU file by meshio) with a ``<FieldData>`` block before its ``<Piece>``."""
    if not field_data:
        return data
    arrays = []
    for name, values in field_data.items():
        flat = np.asarray(values, dtype=float).reshape(-1)
        text = " ".join(repr(float(v)) if np.isfinite(v) else "nan" for v in flat)
        # the newline after the values: VTK's ASCII reader fails on a last value "nan" that
        # runs into the closing tag (vtk 9.7: vtkXMLUnstructuredGridReader error 20008)
        arrays.append(
            f'<DataArray type="Float64" Name={quoteattr(name)} NumberOfTuples="{len(flat)}" '
            f'format="ascii">{text}\n</DataArray>'
        )
    block = ("<FieldData>" + "".join(arrays) + "</FieldData>").encode("utf-8")
    at = data.index(b"<Piece")  # base64 and the header comment hold no '<'
    return data[:at] + block + data[at:]


# ------------------------------------------------------------------------ the beam's section


def beam_lines(ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The line cells (k, 2) int between consecutive points of the centreline ``ref`` (n, 2) mm
    and which of the n - 1 segments they are (k,) int: a segment with a NaN end (the separator
    between the members of a multi-member beam) is no line."""
    finite = np.all(np.isfinite(ref), axis=1)
    keep = np.flatnonzero(finite[:-1] & finite[1:])
    return np.column_stack([keep, keep + 1]), keep


def separators(shapes: np.ndarray) -> np.ndarray:
    """(n,) bool: the nodes of ``shapes`` (n_rows, n, 2) mm that are NaN in every row, the NaN
    node between two members of a multi-member part (fea/beam_fields.py)."""
    return ~np.isfinite(shapes).any(axis=(0, 2))


def beam_points(shapes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The beam's points, line cells and kept segments of ``shapes`` (n_rows, n, 2) mm: the
    points are row 0's nodes (n, 2) mm, a separator node (:func:`separators`) placed on its
    neighbour (no cell uses it; a NaN coordinate would spoil a reader's bounds, as ParaView's
    camera reset), and the lines are :func:`beam_lines` of row 0."""
    ref = np.array(shapes[0], dtype=float)
    lines, keep = beam_lines(ref)
    sep = np.flatnonzero(separators(shapes))
    for i in sep:  # the node before it, or after it at the start (a separator is never last)
        j = i - 1 if i > 0 else i + 1
        ref[i] = ref[j] if np.all(np.isfinite(ref[j])) else 0.0
    return ref, lines, keep


def beam_notes(bfield: dict[str, Any]) -> dict[str, np.ndarray]:
    """Field data a beam field adds: its ``verdict_stress_factor`` (:data:`STRESS_FACTOR_NOTE`)
    and its ``notes`` (each a text, as an array's name)."""
    out: dict[str, np.ndarray] = {}
    if "verdict_stress_factor" in bfield:
        out[STRESS_FACTOR_NOTE] = np.atleast_1d(np.asarray(bfield["verdict_stress_factor"], float))
    for note in bfield.get("notes", ()):
        out[f"beam: {note}"] = np.zeros(1)
    return out


def beam_arrays(result: Any, n_rows: int, n_nodes: int) -> dict[str, np.ndarray] | None:
    """``result.beam_field`` (:func:`fea.beam_fields.beam_field`) when it fits the result's
    shapes (n_rows rows of n_nodes nodes), else None (said as gaps in the file)."""
    bf = getattr(result, "beam_field", None)
    if not bf:
        return None
    try:
        ok = np.shape(bf["equivalent_MPa"]) == (n_rows, n_nodes) and np.shape(
            bf["thickness_mm"]
        ) == (n_nodes,)
    except KeyError:
        return None
    if not ok:
        return None
    out = {k: v if k == "notes" else np.asarray(v, dtype=float) for k, v in bf.items()}
    if np.shape(out.get("as_made_MPa", out["equivalent_MPa"])) != (n_rows, n_nodes):
        out.pop("as_made_MPa")  # not the shapes' rows: left out rather than misdrawn
    return out


# ------------------------------------------------------------------------ load steps: best.pvd


def _field_states(fmap: dict[str, Any]) -> list[dict[str, Any]]:
    """The field's states: its ``steps`` (pipeline/fields.py) or its one top-level state (drive
    value None: the label says which)."""
    steps = fmap.get("steps")
    if steps:
        return list(steps)
    return [
        {
            "drive_value": None,
            "values": fmap["values"],
            "displacement_mm": fmap.get("displacement_mm"),
        }
    ]


def load_steps(result: Any) -> list[dict[str, Any]]:
    """The load steps of best.pvd, in time order: each a dict with ``time`` (the drive value in
    the drive column's unit, or the step's index where the drive is unknown or not increasing),
    ``row`` (the beam's row of ``shapes_mm``, or None) and ``state`` (the field's state solved
    at that drive value, or None). A field state at a drive value the beam has no row for is a
    step of its own."""
    shapes = getattr(result, "shapes_mm", None)
    shapes = np.asarray(shapes, dtype=float) if shapes is not None else None
    if shapes is not None and (shapes.ndim != 3 or shapes.shape[2] != 2 or not shapes.size):
        shapes = None
    fmap = getattr(result, "field_map", None) or None
    steps: list[dict[str, Any]] = []
    if shapes is not None:
        drive, values = _drive(result, len(shapes))
        for k in range(len(shapes)):
            steps.append({"time": None if values is None else float(values[k]), "row": k})
    if fmap is not None:
        for state in _field_states(fmap):
            v = state.get("drive_value")
            match = [
                st
                for st in steps
                if v is not None
                and st["time"] is not None
                and "state" not in st
                and abs(st["time"] - v) <= 1e-6 * max(1.0, abs(v))
            ]
            if match:
                match[0]["state"] = state
            elif v is None and steps and shapes is not None:
                steps[-1]["state"] = state  # one state, no drive value: the label's, the last
            else:
                steps.append({"time": None if v is None else float(v), "row": None})
                steps[-1]["state"] = state
    for st in steps:
        st.setdefault("state", None)
    times = [st["time"] for st in steps]
    if any(t is None for t in times) or np.any(np.diff(np.asarray(times, dtype=float)) <= 0):
        if all(t is not None for t in times):
            steps.sort(key=lambda st: st["time"])
            times = [st["time"] for st in steps]
        if any(t is None for t in times) or np.any(np.diff(np.asarray(times, dtype=float)) <= 0):
            for k, st in enumerate(steps):
                st["index_time"] = True
                st["time"] = float(k)
    return steps


def step_mesh(result: Any, step: dict[str, Any], k: int) -> Any:
    """The :class:`meshio.Mesh` of one load step (see :func:`vtu_files`)."""
    import meshio

    shapes = getattr(result, "shapes_mm", None)
    fmap = getattr(result, "field_map", None) or None
    points: list[np.ndarray] = []
    cells: list[tuple[str, np.ndarray]] = []
    cell_data: dict[str, list[np.ndarray]] = {MODEL: [], THICKNESS: [], WIDTH: []}
    point_data: dict[str, list[np.ndarray]] = {
        DISPLACEMENT: [],
        VON_MISES: [],
        FIBRE_LEFT: [],
        FIBRE_RIGHT: [],
        THICKNESS: [],
        STRESS_COUNTED: [],
    }
    field_data: dict[str, np.ndarray] = {UNITS: np.zeros(1)}
    drive = (getattr(result, "plot", None) or {}).get("x")
    if step.get("index_time"):
        field_data["time: the load step's index (the drive is not known or not increasing)"] = (
            np.array([step["time"]])
        )
    elif drive or (fmap or {}).get("drive"):
        field_data[f"time: {drive or fmap.get('drive')}"] = np.array([step["time"]])
    n = 0
    row = step["row"]
    if row is not None:
        shapes = np.asarray(shapes, dtype=float)
        ref, lines, keep = beam_points(shapes)
        nb = len(ref)
        points.append(np.column_stack([ref, np.zeros(nb)]))
        cells.append(("line", lines))
        cell_data[MODEL].append(np.full(len(lines), MODELS["beam"], dtype=np.int32))
        disp = np.zeros((nb, 3))
        disp[:, :2] = np.where(separators(shapes)[:, None], 0.0, shapes[row] - ref)
        point_data[DISPLACEMENT].append(disp)
        bf = beam_arrays(result, len(shapes), nb)
        nan = np.full(nb, np.nan)
        point_data[STRESS_COUNTED].append(nan)
        if bf is None:
            for name in (VON_MISES, FIBRE_LEFT, FIBRE_RIGHT, THICKNESS):
                point_data[name].append(nan)
            cell_data[THICKNESS].append(np.full(len(lines), np.nan))
            cell_data[WIDTH].append(np.full(len(lines), np.nan))
            field_data[GAP_BEAM_STRESS] = np.zeros(1)
            field_data[GAP_SECTION] = np.zeros(1)
        else:
            point_data[VON_MISES].append(bf["equivalent_MPa"][row])
            point_data[FIBRE_LEFT].append(bf["fibre_left_MPa"][row])
            point_data[FIBRE_RIGHT].append(bf["fibre_right_MPa"][row])
            point_data[THICKNESS].append(bf["thickness_mm"])
            cell_data[THICKNESS].append(bf["segment_thickness_mm"][keep])
            cell_data[WIDTH].append(bf["width_mm"][keep])
            field_data[BEAM_STRESS_NOTE] = np.zeros(1)
            field_data.update(beam_notes(bf))
            if "member_of_segment" in bf:
                cell_data[MEMBER] = [bf["member_of_segment"][keep]]
            if "as_made_MPa" in bf:
                point_data[JUDGED] = [bf["as_made_MPa"][row]]
        for column, data in (getattr(result, "table", None) or {}).items():
            arr = np.asarray(data)
            if arr.shape == (len(shapes),) and arr.dtype.kind in "biuf":
                field_data[f"this load step: {column}"] = arr[row : row + 1].astype(float)
        n = nb
    state = step["state"]
    if state is not None:
        xy = np.asarray(fmap["points_mm"], dtype=float).reshape(-1, 2)
        tri = np.asarray(fmap["triangles"], dtype=np.int64).reshape(-1, 3)
        points.append(np.column_stack([xy, np.zeros(len(xy))]))
        cells.append(("triangle", tri + n))
        cell_data[MODEL].append(np.full(len(tri), MODELS["plane_stress"], dtype=np.int32))
        cell_data[THICKNESS].append(np.full(len(tri), np.nan))
        cell_data[WIDTH].append(np.full(len(tri), np.nan))
        if MEMBER in cell_data:
            cell_data[MEMBER].append(np.full(len(tri), np.nan))
        u = state.get("displacement_mm")
        u = None if u is None else np.asarray(u, dtype=float).reshape(-1, 2)
        disp = np.full((len(xy), 3), np.nan)
        if u is not None and len(u) == len(xy):
            disp[:, :2], disp[:, 2] = u, 0.0
        else:
            field_data[GAP_FIELD_DISPLACEMENT] = np.zeros(1)
        point_data[DISPLACEMENT].append(disp)
        point_data[VON_MISES].append(np.asarray(state["values"], dtype=float).reshape(-1))
        for name in (FIBRE_LEFT, FIBRE_RIGHT, THICKNESS):
            point_data[name].append(np.full(len(xy), np.nan))
        if JUDGED in point_data:
            point_data[JUDGED].append(np.full(len(xy), np.nan))
        point_data[STRESS_COUNTED].append(_counted(fmap, len(xy)))
        if state.get("drive_value") is None:  # the field's one state: its label says which
            label = str(fmap.get("label", "von Mises stress (MPa)"))
        else:  # (the label names the top-level state, the last one)
            label = "the plane-stress solve's state at this load step (MPa)"
        field_data[f"plane stress {VON_MISES}: {label}"] = np.zeros(1)
    elif fmap is not None:
        field_data[GAP_STEP_FIELD] = np.zeros(1)
    return meshio.Mesh(
        np.vstack(points),
        cells,
        point_data={name: np.concatenate(parts) for name, parts in point_data.items()},
        cell_data=cell_data,
        field_data=field_data,
    )


def _counted(fmap: dict[str, Any], n: int) -> np.ndarray:
    """(n,) float: the field's ``stress_counted`` as 1 / 0, NaN where the field has none."""
    counted = fmap.get("stress_counted")
    if counted is None or np.shape(counted) != (n,):
        return np.full(n, np.nan)
    return np.asarray(counted, dtype=float)


def pvd_text(entries: list[tuple[float, str]]) -> str:
    """A ParaView collection (.pvd) of ``(time, relative file name)`` entries."""
    rows = "".join(
        f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(name)}/>\n'
        for t, name in entries
    )
    return (
        '<?xml version="1.0"?>\n'
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
        f"  <Collection>\n{rows}  </Collection>\n</VTKFile>\n"
    )


def vtu_files(result: Any, stem: str) -> dict[str, bytes]:
    """Every VTU file of a design by its name relative to the folder: ``{stem}.vtu``
    (:func:`vtu_bytes`: the whole response in one grid, the plain arrays at the last step),
    ``{stem}.pvd`` (the ParaView collection of the load steps, timestep = the drive value) and
    one ``{stem}_steps/{stem}_KKK.vtu`` per load step (:func:`step_mesh`: that step's
    displacement and stresses as plain arrays), and ``{stem}_3d.vtu`` where the result has a
    3D check's state (:func:`solid_vtu_bytes`). A kind with several load cases (a mechanism)
    draws its first in those and every other case ``CASE`` in ``{stem}_CASE.vtu``,
    ``{stem}_CASE.pvd`` and ``{stem}_steps/{stem}_CASE_KKK.vtu`` (:func:`load_case_series`).
    Empty when it has none of them."""
    out: dict[str, bytes] = {}
    for prefix, series, case in load_case_series(result, stem):
        mesh = vtu_mesh(series)
        if mesh is None:
            continue
        note = _case_note(case)
        mesh.field_data.update(note)
        out[f"{prefix}.vtu"] = _mesh_bytes(mesh)
        entries = []
        for k, step in enumerate(load_steps(series)):
            mesh = step_mesh(series, step, k)
            mesh.field_data.update(note)
            name = f"{stem}_steps/{prefix}_{k:03d}.vtu"
            out[name] = _mesh_bytes(mesh)
            entries.append((step["time"], name))
        out[f"{prefix}.pvd"] = pvd_text(entries).encode("utf-8")
    solid = solid_vtu_bytes(result)
    if solid is not None:
        out[f"{stem}_3d.vtu"] = solid
    return out


def case_slug(case: str) -> str:
    """A load case's name as a file name's part: runs of characters other than letters,
    digits, ``-`` and ``_`` become one ``_``."""
    return re.sub(r"[^A-Za-z0-9_-]+", "_", str(case)).strip("_") or "case"


def load_case_series(result: Any, stem: str) -> list[tuple[str, Any, str | None]]:
    """The response series best.vtu / best.pvd draw: ``(file stem, result-like, load case)``.

    The first is ``(stem, result, first case)``: the result's own shapes, beam field and plane
    field, which a kind of several load cases fills with its first case (the case None for a
    kind of one). Every further case of :attr:`DesignResult.cases` whose ``vtu`` holds its
    ``shapes_mm`` (and ``beam_field``) follows as ``(stem_CASE, that case's shapes, table and
    plot, CASE)``: one ParaView collection per case, since each case has its own drive (its
    own time axis and unit), as ParaView's time-series reader expects."""
    cases = dict(getattr(result, "cases", None) or {})
    names = list(cases)
    first = names[0] if len(names) > 1 else None
    series: list[tuple[str, Any, str | None]] = [(stem, result, first)]
    used = {stem, f"{stem}_3d"}
    for case in names[1:]:
        vtu = getattr(cases[case], "vtu", None) or {}
        if vtu.get("shapes_mm") is None:
            continue
        prefix = f"{stem}_{case_slug(case)}"
        while prefix in used:  # two names alike once slugged: kept apart
            prefix += "_"
        used.add(prefix)
        view = SimpleNamespace(
            shapes_mm=vtu["shapes_mm"],
            beam_field=vtu.get("beam_field"),
            table=cases[case].table,
            plot=cases[case].plot,
            field_map=None,
            solid_field=None,
        )
        series.append((prefix, view, case))
    return series


def _case_note(case: str | None) -> dict[str, np.ndarray]:
    """Field data naming the load case a file draws (none for a kind of one case)."""
    if case is None:
        return {}
    return {f"{LOAD_CASE_NOTE}{case}": np.zeros(1)}


def write_vtu_files(folder: Path, result: Any, stem: str, write: Any) -> list[str]:
    """Write :func:`vtu_files` into ``folder`` with ``write(path, data)`` (an atomic writer),
    making the steps' folder; the names written (relative to ``folder``)."""
    files = vtu_files(result, stem)
    if files:
        (Path(folder) / f"{stem}_steps").mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        write(Path(folder) / name, data)
    return list(files)


def vtu_makers(result: Any, stem: str) -> dict[str, Any]:
    """:func:`vtu_files` as one maker per file name (a run folder's artefacts): the files are
    made once, on the first call, by whichever maker runs first. The names are known without
    making them (:func:`load_steps`). Empty when the design has neither shapes nor a field."""
    if not has_mesh(result):
        return {}
    names = []
    for prefix, series, _ in load_case_series(result, stem):
        if vtu_mesh_possible(series):
            n = len(load_steps(series))
            names += [f"{prefix}.vtu", *(f"{stem}_steps/{prefix}_{k:03d}.vtu" for k in range(n))]
            names.append(f"{prefix}.pvd")
    if getattr(result, "solid_field", None):
        names.append(f"{stem}_3d.vtu")
    made: dict[str, bytes] = {}
    failed: list[Exception] = []

    def maker(name: str) -> Any:
        def make() -> bytes | None:
            if failed:  # said once, by the first file's maker: not once per load step
                return None
            if not made:
                try:
                    made.update(vtu_files(result, stem))
                except Exception as exc:
                    failed.append(exc)
                    raise
            return made.get(name)

        return make

    return {name: maker(name) for name in names}
