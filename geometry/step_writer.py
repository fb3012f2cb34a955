"""A STEP file (ISO 10303-21, AP214) of a straight prism of a polygon with holes, written directly.

Why not OpenCascade: its STEP writer (``STEPControl_Writer.Transfer``, what build123d's
``export_step`` calls) took 14.5 s of the 17 s best.step of the SEA spring cost (9 279 outline
edges, its root fillets sampled at 0.25 deg per facet), growing as ~n^1.25 in the number of
edges (1 161 edges 1.0 s, 9 279 edges 17 s); none of its options changed that (docs/benchmarks.md,
"best.step written directly"). A prism of straight edges needs none of OpenCascade's geometry:
every face is planar and every edge a line, so the B-rep is written here in one pass, ~24
entities per outline vertex, in well under a second.

The topology is OpenCascade's for the same prism (``BRepPrimAPI_MakePrism`` of the planar face):

* per outline vertex ``i`` (every ring): a bottom vertex at z = 0 and a top vertex at
  z = ``thickness_mm``, a vertical edge between them, and the bottom and top edges to the
  ring's next vertex;
* one planar side face per outline edge (its outward normal to the right of the edge, the
  rings oriented so the material is on their left: exterior counter-clockwise, holes
  clockwise);
* the bottom face (normal -z) and the top face (normal +z), each bounded by every ring.

Each edge is a ``LINE`` through its start vertex's point (no parameter-space curves), each
face an ``ADVANCED_FACE`` on a ``PLANE`` with its outward normal and ``same_sense`` true. The
coordinates are written with Python's shortest round-trip repr, so the file holds the outline's
binary coordinates exactly: the part as exported is the analysed outline, vertex for vertex.

:func:`prism_step` refuses (:class:`PrismRefused`) what it cannot write as a solid an
OpenCascade-based reader would rebuild vertex for vertex: an edge or a gap between rings
shorter than :data:`MIN_FEATURE_MM` (a reader merges points within its tolerance, 1e-7 mm),
non-finite coordinates, rings of fewer than 3 vertices or oriented the wrong way. The caller
(:func:`geometry.solid.step_bytes`) then falls back to OpenCascade.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from flexopt.geometry.errors import GeometryError

__all__ = ["MIN_FEATURE_MM", "PrismRefused", "prism_step"]

#: mm. Shortest edge, and smallest distance between two rings, that :func:`prism_step` writes:
#: ten times the uncertainty the file declares (1e-7 mm, OpenCascade's ``Precision::Confusion``,
#: within which a reader merges two points).
MIN_FEATURE_MM = 1e-6

#: Entities written per outline vertex (see :func:`_ring_entities` for their order).
_PER_VERTEX = 24


class PrismRefused(GeometryError):
    """The outline cannot be written as a prism by :func:`prism_step` (the reason says why)."""


def _real(x: float) -> str:
    """A float as a STEP REAL: Python's shortest round-trip repr, with the decimal point and
    the upper-case exponent letter ISO 10303-21 requires (``1e-05`` -> ``1.E-05``)."""
    s = repr(x)
    if "e" in s:
        mantissa, exponent = s.split("e")
        if "." not in mantissa:
            mantissa += "."
        return f"{mantissa}E{exponent}"
    return s


def _signed_area(xy: np.ndarray) -> float:
    """Shoelace area (mm^2) of a ring given as (n, 2) vertices without the closing repeat,
    positive counter-clockwise."""
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _check_rings(rings: Sequence[np.ndarray], thickness_mm: float) -> list[np.ndarray]:
    if not (np.isfinite(thickness_mm) and thickness_mm >= MIN_FEATURE_MM):
        raise PrismRefused(f"thickness {thickness_mm} mm is not >= {MIN_FEATURE_MM} mm")
    if not rings:
        raise PrismRefused("no rings")
    out = []
    for k, ring in enumerate(rings):
        xy = np.asarray(ring, dtype=float)
        if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 3:
            raise PrismRefused(f"ring {k} is not (n >= 3, 2) vertices: shape {xy.shape}")
        if len(xy) > 3 and np.array_equal(xy[0], xy[-1]):
            xy = xy[:-1]  # the closing repeat of a shapely ring
        if not np.all(np.isfinite(xy)):
            raise PrismRefused(f"ring {k} has non-finite coordinates")
        edge = np.hypot(*(np.roll(xy, -1, axis=0) - xy).T)
        if edge.min() < MIN_FEATURE_MM:
            raise PrismRefused(
                f"ring {k} has an edge of {edge.min():.3g} mm, shorter than {MIN_FEATURE_MM} mm"
            )
        area = _signed_area(xy)
        if (area <= 0.0) if k == 0 else (area >= 0.0):
            raise PrismRefused(
                f"ring {k} is oriented the wrong way (signed area {area:.6g} mm^2; the exterior "
                "must be counter-clockwise, the holes clockwise)"
            )
        out.append(xy)
    return out


def prism_step(
    rings: Sequence[np.ndarray], thickness_mm: float, name: str = "flexopt part"
) -> bytes:
    """The STEP file (AP214, mm) of ``rings`` extruded from z = 0 to z = ``thickness_mm``.

    Parameters
    ----------
    rings : sequence of (n_k, 2) float arrays, mm
        The exterior ring first (counter-clockwise), then the holes (clockwise); a closing
        vertex equal to the first is dropped. The caller guarantees a valid polygon (simple
        rings, holes inside the exterior and apart from each other): this function checks the
        edges' lengths, the orientation and the coordinates, not the rings' intersections.
    thickness_mm : float, mm
        The extrusion along +z.
    name : str
        The product's name in the file (ASCII; quotes are dropped).

    Returns
    -------
    bytes
        The file's text: one MANIFOLD_SOLID_BREP with sum(n_k) + 2 faces.

    Raises
    ------
    PrismRefused
        When the rings cannot be written as such a solid (see the module's docstring).
    """
    xys = _check_rings(rings, float(thickness_mm))
    h = float(thickness_mm)
    r = _real
    name = "".join(c for c in name if c.isascii() and c.isprintable() and c not in "'\\")
    lines: list[str] = []
    add = lines.append

    # ---- product, context and the shared geometry: #1 .. #N0 ----
    add("#1=APPLICATION_PROTOCOL_DEFINITION('international standard','automotive_design',2000,#2);")
    add("#2=APPLICATION_CONTEXT('core data for automotive mechanical design processes');")
    add("#3=SHAPE_DEFINITION_REPRESENTATION(#4,#10);")
    add("#4=PRODUCT_DEFINITION_SHAPE('','',#5);")
    add("#5=PRODUCT_DEFINITION('design','',#6,#9);")
    add("#6=PRODUCT_DEFINITION_FORMATION('','',#7);")
    add(f"#7=PRODUCT('{name}','{name}','',(#8));")
    add("#8=PRODUCT_CONTEXT('',#2,'mechanical');")
    add("#9=PRODUCT_DEFINITION_CONTEXT('part definition',#2,'design');")
    # #10 (the representation) and #11 (the solid), #12 (its shell) are written last: they
    # list what follows
    add("#13=PRODUCT_RELATED_PRODUCT_CATEGORY('part',$,(#7));")
    add(
        "#14=(GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT((#18)) "
        "GLOBAL_UNIT_ASSIGNED_CONTEXT((#15,#16,#17)) REPRESENTATION_CONTEXT('Context #1',"
        "'3D Context with UNIT and UNCERTAINTY'));"
    )
    add("#15=(LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.));")
    add("#16=(NAMED_UNIT(*) PLANE_ANGLE_UNIT() SI_UNIT($,.RADIAN.));")
    add("#17=(NAMED_UNIT(*) SI_UNIT($,.STERADIAN.) SOLID_ANGLE_UNIT());")
    add(
        "#18=UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-07),#15,"
        "'distance_accuracy_value','confusion accuracy');"
    )
    add("#19=CARTESIAN_POINT('',(0.,0.,0.));")
    add("#20=DIRECTION('',(0.,0.,1.));")
    add("#21=DIRECTION('',(1.,0.,0.));")
    add("#22=AXIS2_PLACEMENT_3D('',#19,#20,#21);")  # the representation's frame
    add("#23=VECTOR('',#20,1.);")  # every vertical edge's direction
    add("#24=DIRECTION('',(0.,0.,-1.));")
    add("#25=AXIS2_PLACEMENT_3D('',#19,#24,#21);")
    add("#26=PLANE('',#25);")  # the bottom face's, normal -z
    add(f"#27=CARTESIAN_POINT('',(0.,0.,{r(h)}));")
    add("#28=AXIS2_PLACEMENT_3D('',#27,#20,#21);")
    add("#29=PLANE('',#28);")  # the top face's, normal +z
    top_face, bottom_face = 30, 31  # written after the rings: they list every ring's loop
    first = 32 + 2 * len(xys)  # top and bottom face bounds (2 per ring: loop and bound)

    side_faces: list[str] = []
    top_bounds: list[int] = []
    bottom_bounds: list[int] = []
    base = first
    hz = r(h)
    for k, xy in enumerate(xys):
        n = len(xy)
        d = np.roll(xy, -1, axis=0) - xy
        d /= np.hypot(d[:, 0], d[:, 1])[:, None]
        xs = [r(v) for v in xy[:, 0].tolist()]
        ys = [r(v) for v in xy[:, 1].tolist()]
        dxs = [r(v) for v in d[:, 0].tolist()]
        dys = [r(v) for v in d[:, 1].tolist()]
        ndxs = [r(v) for v in (-d[:, 0]).tolist()]
        for i in range(n):
            # entity i's offsets: 0 pB, 1 vB, 2 pT, 3 vT, 4 d, 5 vec, 6 lineB, 7 edgeB,
            # 8 lineT, 9 edgeT, 10 lineV, 11 edgeV, 12 normal, 13 axis, 14 plane,
            # 15-18 the side face's oriented edges, 19 loop, 20 bound, 21 face,
            # 22 the top's oriented edge, 23 the bottom's
            e = base + _PER_VERTEX * i
            j = base + _PER_VERTEX * ((i + 1) % n)  # the next vertex's entities
            x, y = xs[i], ys[i]
            add(f"#{e}=CARTESIAN_POINT('',({x},{y},0.));")
            add(f"#{e + 1}=VERTEX_POINT('',#{e});")
            add(f"#{e + 2}=CARTESIAN_POINT('',({x},{y},{hz}));")
            add(f"#{e + 3}=VERTEX_POINT('',#{e + 2});")
            add(f"#{e + 4}=DIRECTION('',({dxs[i]},{dys[i]},0.));")
            add(f"#{e + 5}=VECTOR('',#{e + 4},1.);")
            add(f"#{e + 6}=LINE('',#{e},#{e + 5});")
            add(f"#{e + 7}=EDGE_CURVE('',#{e + 1},#{j + 1},#{e + 6},.T.);")
            add(f"#{e + 8}=LINE('',#{e + 2},#{e + 5});")
            add(f"#{e + 9}=EDGE_CURVE('',#{e + 3},#{j + 3},#{e + 8},.T.);")
            add(f"#{e + 10}=LINE('',#{e},#23);")
            add(f"#{e + 11}=EDGE_CURVE('',#{e + 1},#{e + 3},#{e + 10},.T.);")
            # outward normal: to the right of the edge (the material is on its left)
            add(f"#{e + 12}=DIRECTION('',({dys[i]},{ndxs[i]},0.));")
            add(f"#{e + 13}=AXIS2_PLACEMENT_3D('',#{e},#{e + 12},#{e + 4});")
            add(f"#{e + 14}=PLANE('',#{e + 13});")
            # counter-clockwise seen from outside: along the bottom edge, up the next
            # vertical, back along the top edge, down this vertical
            add(f"#{e + 15}=ORIENTED_EDGE('',*,*,#{e + 7},.T.);")
            add(f"#{e + 16}=ORIENTED_EDGE('',*,*,#{j + 11},.T.);")
            add(f"#{e + 17}=ORIENTED_EDGE('',*,*,#{e + 9},.F.);")
            add(f"#{e + 18}=ORIENTED_EDGE('',*,*,#{e + 11},.F.);")
            add(f"#{e + 19}=EDGE_LOOP('',(#{e + 15},#{e + 16},#{e + 17},#{e + 18}));")
            add(f"#{e + 20}=FACE_OUTER_BOUND('',#{e + 19},.T.);")
            add(f"#{e + 21}=ADVANCED_FACE('',(#{e + 20}),#{e + 14},.T.);")
            add(f"#{e + 22}=ORIENTED_EDGE('',*,*,#{e + 9},.T.);")
            add(f"#{e + 23}=ORIENTED_EDGE('',*,*,#{e + 7},.F.);")
        ids = range(base, base + _PER_VERTEX * n, _PER_VERTEX)
        side_faces.append(_refs(e + 21 for e in ids))
        # the top face (+z) runs along the ring as given (material on the left); the bottom
        # face (-z) runs the other way: its edges reversed, in reverse order
        loop_t, loop_b = 32 + 2 * k, 33 + 2 * k
        bound = "FACE_OUTER_BOUND" if k == 0 else "FACE_BOUND"
        lines.append(f"#{loop_t}=EDGE_LOOP('',({_refs(e + 22 for e in ids)}));")
        lines.append(f"#{loop_b}=EDGE_LOOP('',({_refs(e + 23 for e in reversed(ids))}));")
        base += _PER_VERTEX * n
        lines.append(f"#{base}={bound}('',#{loop_t},.T.);")
        lines.append(f"#{base + 1}={bound}('',#{loop_b},.T.);")
        top_bounds.append(base)
        bottom_bounds.append(base + 1)
        base += 2
    add(f"#{top_face}=ADVANCED_FACE('',({_refs(top_bounds)}),#29,.T.);")
    add(f"#{bottom_face}=ADVANCED_FACE('',({_refs(bottom_bounds)}),#26,.T.);")
    add(f"#12=CLOSED_SHELL('',({','.join(side_faces)},#{top_face},#{bottom_face}));")
    add("#11=MANIFOLD_SOLID_BREP('',#12);")
    add("#10=ADVANCED_BREP_SHAPE_REPRESENTATION('',(#22,#11),#14);")

    stamp = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime())
    head = (
        "ISO-10303-21;\nHEADER;\n"
        "FILE_DESCRIPTION(('a prism of a polygon with holes'),'2;1');\n"
        f"FILE_NAME('{name}','{stamp}',(''),(''),'flexopt','flexopt','');\n"
        "FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));\nENDSEC;\nDATA;\n"
    )
    return (head + "\n".join(lines) + "\nENDSEC;\nEND-ISO-10303-21;\n").encode("ascii")


def _refs(ids) -> str:
    """Entity references, comma-separated, a line break every 16 (a line of a list of ten
    thousand faces stays readable)."""
    refs = [f"#{i}" for i in ids]
    return ",\n".join(",".join(refs[i : i + 16]) for i in range(0, len(refs), 16))
