"""Sparsity pattern of a finite-element matrix, compiled (numba): the one builder the plane-stress
and 3D kernels share.

:func:`node_pattern` finds, for a mesh given as the nodes of each element, which nodes share an
element with each node: the pattern of the node-by-node matrix (compressed rows, columns sorted),
and for each node the elements it belongs to with its local index there, which is what the
assemblies walk to sum element entries row by row. :mod:`fea._plane_stress_kernels` expands it to
the DOF pattern of a 2-vector (``csr_pattern_paired``) or uses it on DOFs directly
(``csr_pattern``); :mod:`fea._solid3d_kernels` uses it as the node-block pattern of the P2
stiffness (``block_pattern_parts``). A row is gathered with a marker and sorted in place
(insertion sort: a row has tens of entries, where ``np.sort`` is ~10x slower), without the global
sort of all element pairs the numpy paths use.

``@njit(cache=True)`` as its callers (fastmath off; integer work only). A caller in another module
compiles this into its own cached code; numba's cache of a caller is keyed on the caller's file
only, so after an edit here clear ``fea/__pycache__/_*kernels*.nb*`` (or ``NUMBA_CACHE_DIR``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def node_pattern(nodes: np.ndarray, n: int):
    """Node-by-node sparsity pattern of a mesh, with each node's elements.

    Parameters
    ----------
    nodes : (E, m) int64 — the nodes (or DOFs) of each element, in ``0 .. n-1``; an element may
        not list a node twice.
    n : int — number of nodes.

    Returns
    -------
    indptr : (n + 1,) int64, indices : (nnz,) int64 — compressed rows: row s's columns are the
        nodes sharing an element with s (s included), sorted ascending, each once. ``indices``
        is a view into a larger buffer (copy it to keep it long).
    start : (n + 1,) int64, elems : (E * m,) int64, local : (E * m,) int64 — node s belongs to
        elements ``elems[start[s]:start[s + 1]]`` (ascending), as their local node
        ``local[...]``.
    """
    E, m = nodes.shape
    # Elements of each node (and the node's local index there), in element order.
    count = np.zeros(n + 1, np.int64)
    for e in range(E):
        for a in range(m):
            count[nodes[e, a] + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    elems = np.empty(start[-1], np.int64)
    local = np.empty(start[-1], np.int64)
    for e in range(E):
        for a in range(m):
            s = nodes[e, a]
            elems[fill[s]] = e
            local[fill[s]] = a
            fill[s] += 1
    # Node rows: the nodes of the node's elements, deduplicated with a marker, then sorted.
    mark = np.full(n, -1, np.int64)
    indptr = np.zeros(n + 1, np.int64)
    cols = np.empty(m * start[-1], np.int64)  # upper bound: no node shared
    nz = 0
    for s in range(n):
        row0 = nz
        for k in range(start[s], start[s + 1]):
            e = elems[k]
            for b in range(m):
                c = nodes[e, b]
                if mark[c] != s:
                    mark[c] = s
                    cols[nz] = c
                    nz += 1
        for i in range(row0 + 1, nz):  # insertion sort: a row has tens of nodes
            c = cols[i]
            j = i
            while j > row0 and cols[j - 1] > c:
                cols[j] = cols[j - 1]
                j -= 1
            cols[j] = c
        indptr[s + 1] = nz
    return indptr, cols[:nz], start, elems, local
