"""The one sparsity-pattern builder (fea/_sparse.py) against scipy.sparse, and its two DOF
patterns in fea/_plane_stress_kernels.py against scipy.sparse's pattern of the same entries.

The 3D kernel's node-block pattern (fea/_solid3d_kernels.py) is this builder's pattern on the P2
nodes; test_solid3d_kernels.py checks it against the numpy assembly of the same mesh.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("numba", reason="the compiled kernels need numba")

from flexopt.fea import _plane_stress_kernels as psk  # noqa: E402
from flexopt.fea import _sparse  # noqa: E402


def _mesh(rows: int, cols: int, seed: int) -> tuple[np.ndarray, int]:
    """A structured triangle mesh's P2 element nodes (E, 6) — 3 vertices, then the 3 edge
    midpoints — with the node numbers randomly permuted, so no row is in a convenient order."""
    vid = np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    tris = []
    for r in range(rows):
        for c in range(cols):
            a, b, d, e = vid[r, c], vid[r, c + 1], vid[r + 1, c], vid[r + 1, c + 1]
            tris += [(a, b, e), (a, e, d)]
    tris = np.array(tris)
    edges = np.sort(tris[:, [[0, 1], [1, 2], [0, 2]]], axis=2).reshape(-1, 2)
    uniq, inv = np.unique(edges, axis=0, return_inverse=True)
    n = vid.size + len(uniq)
    nodes = np.hstack([tris, vid.size + inv.reshape(-1, 3)])
    perm = np.random.default_rng(seed).permutation(n)
    return perm[nodes].astype(np.int64), n


def _scipy_pattern(dofs: np.ndarray, n: int) -> sp.csr_matrix:
    """scipy.sparse's CSR pattern of every element entry (i, j), duplicates summed."""
    m = dofs.shape[1]
    rows = np.repeat(dofs, m, axis=1).ravel()
    cols = np.tile(dofs, (1, m)).ravel()
    a = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n)).tocsr()
    a.sum_duplicates()
    a.sort_indices()
    return a


def test_node_pattern_is_scipys_pattern_with_each_nodes_elements():
    nodes, n = _mesh(4, 5, 0)
    indptr, indices, start, elems, local = _sparse.node_pattern(nodes, n)
    ref = _scipy_pattern(nodes, n)
    np.testing.assert_array_equal(indptr, ref.indptr)
    np.testing.assert_array_equal(indices, ref.indices)
    # each node's elements: every element holding it, once, ascending, at its local index
    for s in range(n):
        e = elems[start[s] : start[s + 1]]
        np.testing.assert_array_equal(e, np.flatnonzero((nodes == s).any(axis=1)))
        np.testing.assert_array_equal(nodes[e, local[start[s] : start[s + 1]]], s)


@pytest.mark.parametrize("paired", [False, True], ids=["csr_pattern", "csr_pattern_paired"])
def test_plane_stress_patterns_are_scipys_with_each_entrys_position(paired):
    """The 2-vector DOFs (2 node + component, scikit-fem's numbering) of the P2 mesh: the CSR
    structure is scipy's, and entry (e, i, j) of the element matrices lands on (dofs[e, i],
    dofs[e, j]) of it."""
    nodes, n_nodes = _mesh(3, 4, 1)
    dofs = np.hstack([2 * nodes, 2 * nodes + 1])
    n = 2 * n_nodes
    if paired:
        indptr, indices, where = psk.csr_pattern_paired(nodes, n_nodes)
    else:
        indptr, indices, where = psk.csr_pattern(dofs, n)
    ref = _scipy_pattern(dofs, n)
    np.testing.assert_array_equal(indptr, ref.indptr)
    np.testing.assert_array_equal(indices, ref.indices)
    m = dofs.shape[1]
    rows = np.repeat(dofs, m, axis=1).ravel()
    cols = np.tile(dofs, (1, m)).ravel()
    np.testing.assert_array_equal(np.searchsorted(indptr, where, side="right") - 1, rows)
    np.testing.assert_array_equal(indices[where], cols)
