"""DXF of a planar part's outline, for shops that cut rather than print (laser, waterjet,
wire EDM): closed polylines in mm, written and read with ezdxf.

:func:`dxf_bytes` writes the outline's exterior as one closed LWPOLYLINE on layer
:data:`OUTLINE_LAYER` and every hole as one on :data:`HOLES_LAYER`, with the drawing units set to
mm (``$INSUNITS = 4``, ``$MEASUREMENT = 1``), so a CAM program neither guesses inches nor mixes
the cut path with the holes. :func:`dxf_polygon` reads such a file back (round-trip tests, and a
check of a file someone else made). Choosing the frame (the design's coordinates or laid flat)
and cleaning the outline is the caller's job (:func:`geometry.solid.flat_part`).
"""

from __future__ import annotations

import io

import ezdxf
import numpy as np
from flexopt.geometry.errors import GeometryError
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

__all__ = ["OUTLINE_LAYER", "HOLES_LAYER", "INSUNITS_MM", "dxf_bytes", "dxf_polygon"]

#: Layer of the part's outer contour.
OUTLINE_LAYER = "OUTLINE"
#: Layer of its holes (inner contours).
HOLES_LAYER = "HOLES"
#: DXF ``$INSUNITS`` code of millimetres.
INSUNITS_MM = 4


def dxf_bytes(polygon: Polygon, comment: str = "") -> bytes:
    """One outline as a DXF drawing (R2010, ASCII, mm).

    Parameters
    ----------
    polygon : shapely Polygon, mm
        The outline; holes become closed contours on :data:`HOLES_LAYER`. Arcs come as the
        polygon's straight segments (the outline is already discretised).
    comment : str
        Written into the header as a DXF comment (what the part is); one line.

    Returns
    -------
    bytes
        The DXF file (UTF-8 text).

    Raises
    ------
    GeometryError
        When the outline is not one valid, non-empty polygon.
    """
    if not isinstance(polygon, Polygon) or polygon.is_empty or not polygon.is_valid:
        raise GeometryError(
            f"dxf_bytes needs one valid, non-empty shapely Polygon, got {type(polygon).__name__}"
        )
    poly = orient(polygon, sign=1.0)  # counter-clockwise outside, clockwise holes
    doc = ezdxf.new("R2010", setup=False)
    doc.units = INSUNITS_MM
    doc.header["$MEASUREMENT"] = 1  # metric
    doc.layers.add(OUTLINE_LAYER, color=7)
    doc.layers.add(HOLES_LAYER, color=1)
    msp = doc.modelspace()
    for layer, ring in [(OUTLINE_LAYER, poly.exterior)] + [
        (HOLES_LAYER, r) for r in poly.interiors
    ]:
        points = np.asarray(ring.coords, dtype=float)[:-1, :2]
        msp.add_lwpolyline(points.tolist(), format="xy", close=True, dxfattribs={"layer": layer})
    stream = io.StringIO()
    doc.write(stream)
    text = stream.getvalue()
    if comment:
        text = f"999\n{' '.join(comment.split())}\n" + text
    return text.encode("utf-8")


def dxf_polygon(data: bytes) -> Polygon:
    """Read an outline written by :func:`dxf_bytes` back.

    Parameters
    ----------
    data : bytes
        A DXF file whose closed LWPOLYLINEs on :data:`OUTLINE_LAYER` (one) and
        :data:`HOLES_LAYER` (any) form the part.

    Returns
    -------
    shapely Polygon, mm

    Raises
    ------
    GeometryError
        When the drawing is not in mm or does not hold exactly one closed outline.
    """
    try:
        doc = ezdxf.read(io.StringIO(data.decode("utf-8")))
    except (UnicodeDecodeError, ezdxf.DXFError) as exc:
        raise GeometryError(f"not a readable DXF file: {exc}") from exc
    if doc.units != INSUNITS_MM:
        raise GeometryError(f"the DXF's $INSUNITS is {doc.units}, not {INSUNITS_MM} (mm)")
    rings: dict[str, list[list[tuple[float, float]]]] = {OUTLINE_LAYER: [], HOLES_LAYER: []}
    for entity in doc.modelspace().query("LWPOLYLINE"):
        if entity.dxf.layer in rings:
            if not entity.closed:
                raise GeometryError(f"an open polyline on layer {entity.dxf.layer}")
            rings[entity.dxf.layer].append([(x, y) for x, y in entity.get_points("xy")])
    if len(rings[OUTLINE_LAYER]) != 1:
        raise GeometryError(
            f"expected one closed outline on layer {OUTLINE_LAYER}, found "
            f"{len(rings[OUTLINE_LAYER])}"
        )
    return Polygon(rings[OUTLINE_LAYER][0], rings[HOLES_LAYER])
