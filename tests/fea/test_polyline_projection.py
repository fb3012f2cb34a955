"""fea._polyline_kernels.polyline_arc_length (fea.fidelity._locate's projection) against exact
arc lengths and against shapely's line_locate_point, which it replaced (session 32)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from flexopt.fea._polyline_kernels import polyline_arc_length
from shapely.geometry import LineString


def test_known_arc_lengths_on_an_l_shaped_polyline() -> None:
    # (0, 0) -> (3, 0) -> (3, 4): segment lengths 3 and 4, total 7
    line = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]])
    points = np.array(
        [
            [1.0, -2.0],  # onto the first segment at x = 1
            [5.0, 2.0],  # onto the second at y = 2: 3 + 2
            [-1.0, -1.0],  # before the start: clamped to 0
            [3.0, 7.0],  # past the end: clamped to 7
            [4.0, -1.0],  # nearest the corner: 3
            [2.0, 1.5],  # 1.5 from the first segment, 1.0 from the second: there at y = 1.5
            [0.0, 0.0],  # the start itself
            [3.0, 4.0],  # the end itself
        ]
    )
    expected = np.array([1.0, 5.0, 0.0, 7.0, 3.0, 4.5, 0.0, 7.0])
    np.testing.assert_allclose(polyline_arc_length(line, points), expected, rtol=0, atol=1e-14)


def test_tie_takes_the_first_segment_and_a_repeated_vertex_is_harmless() -> None:
    # a point equidistant from both arms of a V: the first segment's projection (GEOS's rule)
    line = np.array([[-1.0, 1.0], [0.0, 0.0], [0.0, 0.0], [1.0, 1.0]])
    s = polyline_arc_length(line, np.array([[0.0, 1.0]]))
    np.testing.assert_allclose(s, [0.5 * np.sqrt(2.0)], rtol=1e-15)
    ref = shapely.line_locate_point(LineString(line), shapely.points([[0.0, 1.0]]))
    np.testing.assert_allclose(s, ref, rtol=0, atol=1e-14)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_same_bits_as_shapely_on_random_points(seed: int) -> None:
    rng = np.random.default_rng(seed)
    # a wiggly centreline like a beam's (x rising, y a few waves), nodes unevenly spaced
    x = np.sort(rng.uniform(0.0, 60.0, 145))
    line = np.column_stack([x, 5.0 * np.sin(x / 7.0) + rng.normal(0.0, 0.05, x.size)])
    points = np.column_stack([rng.uniform(-10.0, 70.0, 5000), rng.uniform(-12.0, 12.0, 5000)])
    points[:50] = line[rng.integers(0, len(line), 50)]  # some exactly on vertices
    ours = polyline_arc_length(line, points)
    theirs = shapely.line_locate_point(LineString(line), shapely.points(points))
    # the same bits with GEOS 3.14 (shapely 2.1), where the kernel repeats GEOS's operations
    # in GEOS's order; asserted to round-off so another GEOS release cannot fail it
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12)
    # and it is the nearest point: no vertex of the polyline is nearer than the projection
    d = np.hypot(*(points[:, None, :] - line[None]).transpose(2, 0, 1)).min(axis=1)
    at = np.column_stack(
        [np.interp(ours, *_arc(line, 0)), np.interp(ours, *_arc(line, 1))]
    )  # the projected point, from its arc length
    assert np.all(np.hypot(*(points - at).T) <= d + 1e-9)


def _arc(line: np.ndarray, c: int) -> tuple[np.ndarray, np.ndarray]:
    """(arc length at each vertex, coordinate c of the vertex) of a polyline (n, 2)."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))])
    return s, line[:, c]
