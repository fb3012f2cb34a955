"""Compiled (numba) projection of points onto a polyline: :func:`fea.fidelity._locate`'s.

The same nearest point and arc length as shapely's ``line_locate_point`` (GEOS's
``LengthIndexOfPoint``), computed in the same floating-point operations in the same order, so
the answers agree to the bit (tests/fea/test_polyline_projection.py): for each point, the first
segment at the smallest distance (GEOS's point-to-segment distance), and the arc length of the
point's projection on it (clamped to the segment) from the polyline's start, the segments'
lengths summed in order. GEOS spends ~50-90 ms on the constant-force check's ~9k mesh nodes
against a 145-node centreline (one Python call, but a GEOS geometry per point and a virtual
iterator per segment); this loop ~8 ms.

``@njit(cache=True)`` and no ``fastmath``: the operations are not reordered or fused.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def polyline_arc_length(line: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Arc length (k,) mm along the polyline ``line`` (n, 2) mm of the nearest point to each
    of ``points`` (k, 2) mm (shapely's ``line_locate_point``, to the bit; a polyline of one
    point or none: 0)."""
    n = line.shape[0]
    k = points.shape[0]
    out = np.zeros(k)
    if n < 2:
        return out
    start = np.empty(n - 1)  # arc length at each segment's start, summed in order as GEOS
    acc = 0.0
    for i in range(n - 1):
        start[i] = acc
        dx = line[i + 1, 0] - line[i, 0]
        dy = line[i + 1, 1] - line[i, 1]
        acc += np.sqrt(dx * dx + dy * dy)
    for p in range(k):
        px = points[p, 0]
        py = points[p, 1]
        best = np.inf
        at = 0.0
        for i in range(n - 1):
            ax = line[i, 0]
            ay = line[i, 1]
            bx = line[i + 1, 0]
            by = line[i + 1, 1]
            dx = bx - ax
            dy = by - ay
            len2 = dx * dx + dy * dy
            # GEOS Distance::pointToSegment
            if ax == bx and ay == by:
                d = np.sqrt((px - ax) * (px - ax) + (py - ay) * (py - ay))
                r = 0.0
            else:
                r = ((px - ax) * dx + (py - ay) * dy) / len2
                if r <= 0.0:
                    d = np.sqrt((px - ax) * (px - ax) + (py - ay) * (py - ay))
                elif r >= 1.0:
                    d = np.sqrt((px - bx) * (px - bx) + (py - by) * (py - by))
                else:
                    s = ((ay - py) * dx - (ax - px) * dy) / len2
                    d = abs(s) * np.sqrt(len2)
            if d < best:  # strict: the first segment at the smallest distance
                best = d
                # GEOS segmentNearestMeasure (LineSegment::projectionFactor, clamped)
                if (px == ax and py == ay) or r <= 0.0:
                    at = start[i]
                elif (px == bx and py == by) or r > 1.0:
                    at = start[i] + np.sqrt(len2)
                else:
                    at = start[i] + r * np.sqrt(len2)
        out[p] = at
    return out
