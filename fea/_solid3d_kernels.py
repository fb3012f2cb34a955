"""Compiled (numba) kernels of the 3D model's build in :mod:`fea.solid3d`.

The numpy path (``Solid3DSettings(assembly="numpy")``) builds the P2 tables with scikit-fem's
generic ``Basis`` and finds the node-block pattern by a global sort of the 100 node pairs of
every element; on the SEA spring's 405k-DOF model that is ~6 s. Here:

* :func:`p2_tables`: the quadratic tetrahedron's gradients from the vertex coordinates (the
  mesh is affine: each element's barycentric gradients are constant), with the quadrature
  weights and points, in one pass over the elements;
* :func:`block_pattern_parts`: the node-block sparsity pattern (fea/_sparse.py's
  :func:`~fea._sparse.node_pattern`: per node row its elements' nodes, deduplicated, sorted)
  and the twelve stiffness "parts" of each node block (:func:`fea.solid3d._stiffness_parts`),
  summed row by row into the pattern;
* :func:`reduced_lower_count`, :func:`reduced_lower_fill`: where the reduced matrix's lower
  triangle sits in the node blocks, in compressed columns (rows ascending): CHOLMOD's
  matrix is made from them without cvxopt's triplet constructor;
* :func:`von_mises`: the stress at the quadrature points and corners of a solution.

Notation: ``G[e, q, a, j]`` is ``d phi_a / d x_j`` of local P2 function ``a`` (4 vertices, then
the edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3): scikit-fem's ElementTetP2) at quadrature
point ``q`` of element ``e``, 1/mm; ``dx[e, q]`` its weight times the Jacobian, mm^3.

Every function is ``@njit(cache=True)``: compiled once per install (the cache sits in
``fea/__pycache__`` or ``NUMBA_CACHE_DIR``), not per process. ``fastmath`` stays off, so the
sums run in a fixed order and agree with the numpy path to round-off.
"""

from __future__ import annotations

import numpy as np
from flexopt.fea._sparse import node_pattern
from numba import njit

# local P2 edge functions: (first vertex, second vertex), in scikit-fem's order
_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]], dtype=np.int64)


@njit(cache=True)
def p2_tables(p: np.ndarray, t: np.ndarray, X: np.ndarray, w: np.ndarray, edges: np.ndarray):
    """Gradients, weights and points of the P2 functions of affine tetrahedra.

    Parameters
    ----------
    p : (3, nv) float, mm — vertices; t : (nel, 4) int — each element's vertices.
    X : (3, nq) float — points in the reference tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1).
    w : (nq,) float — their weights (sum 1/6).
    edges : (6, 2) int — the local edges, as :data:`_EDGES`.

    Returns
    -------
    G : (nel, nq, 10, 3) float, 1/mm; dx : (nel, nq) float, mm^3 (|det J| w);
    xyz : (3, nel, nq) float, mm — the points mapped into each element.
    """
    nel = t.shape[0]
    nq = X.shape[1]
    G = np.empty((nel, nq, 10, 3))
    dx = np.empty((nel, nq))
    xyz = np.empty((3, nel, nq))
    J = np.empty((3, 3))
    gl = np.empty((4, 3))  # barycentric gradients
    lam = np.empty(4)
    for e in range(nel):
        v0 = t[e, 0]
        for i in range(3):
            for k in range(3):
                J[i, k] = p[i, t[e, k + 1]] - p[i, v0]
        # inverse by cofactors: row k of J^-1 is grad lambda_(k+1)
        c00 = J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1]
        c01 = J[1, 2] * J[2, 0] - J[1, 0] * J[2, 2]
        c02 = J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]
        det = J[0, 0] * c00 + J[0, 1] * c01 + J[0, 2] * c02
        inv = 1.0 / det
        gl[1, 0] = c00 * inv
        gl[1, 1] = (J[0, 2] * J[2, 1] - J[0, 1] * J[2, 2]) * inv
        gl[1, 2] = (J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1]) * inv
        gl[2, 0] = c01 * inv
        gl[2, 1] = (J[0, 0] * J[2, 2] - J[0, 2] * J[2, 0]) * inv
        gl[2, 2] = (J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2]) * inv
        gl[3, 0] = c02 * inv
        gl[3, 1] = (J[0, 1] * J[2, 0] - J[0, 0] * J[2, 1]) * inv
        gl[3, 2] = (J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]) * inv
        for k in range(3):
            gl[0, k] = -(gl[1, k] + gl[2, k] + gl[3, k])
        adet = abs(det)
        for q in range(nq):
            lam[1] = X[0, q]
            lam[2] = X[1, q]
            lam[3] = X[2, q]
            lam[0] = 1.0 - X[0, q] - X[1, q] - X[2, q]
            dx[e, q] = adet * w[q]
            for i in range(3):
                xyz[i, e, q] = p[i, v0] + J[i, 0] * X[0, q] + J[i, 1] * X[1, q] + J[i, 2] * X[2, q]
            for a in range(4):  # lambda_a (2 lambda_a - 1)
                f = 4.0 * lam[a] - 1.0
                for k in range(3):
                    G[e, q, a, k] = f * gl[a, k]
            for m in range(6):  # 4 lambda_i lambda_j
                i = edges[m, 0]
                j = edges[m, 1]
                for k in range(3):
                    G[e, q, 4 + m, k] = 4.0 * (lam[i] * gl[j, k] + lam[j] * gl[i, k])
    return G, dx, xyz


@njit(cache=True)
def block_pattern_parts(dofs: np.ndarray, n: int, G: np.ndarray, dx: np.ndarray, lam: float,
                        mu: float):  # fmt: skip
    """Node-block pattern of the P2 stiffness and its twelve parts per block.

    ``M_(ab)[c, d] = sum_q dx g_ac g_bd`` for the local functions a, b of an element; the parts
    are (as :func:`fea.solid3d._stiffness_parts`, columns in the order of _PP, _PZ, _ZZ):
    (0,0), (1,1): ``lam M[c,c] + mu M[c,c] + mu (M00 + M11)``; (0,1), (1,0):
    ``lam M[c,d] + mu M[d,c]``; (2,2) in-plane: ``mu (M00 + M11)``; (0,2), (1,2), (2,0),
    (2,1): ``lam M[c,d] + mu M[d,c]``; (0,0), (1,1) out-of-plane: ``mu M22``; (2,2):
    ``(lam + 2 mu) M22``.

    Parameters
    ----------
    dofs : (nel, 10) int64 — scalar P2 nodes of each element; n : int — their number.
    G : (nel, nq, 10, 3) float, 1/mm; dx : (nel, nq) float, mm^3; lam, mu : float, MPa.

    Returns
    -------
    indptr : (n + 1,) int64, indices : (nnzb,) int64 — node rows, sorted columns;
    parts : (nnzb, 12) float, N/mm.
    """
    indptr, indices, start, elems, local = node_pattern(dofs, n)
    indices = indices.copy()  # the pattern's buffer has room for every element pair
    parts = _block_parts(dofs, n, G, dx, lam, mu, indptr, indices, start, elems, local)
    return indptr, indices, parts


@njit(cache=True)
def _block_parts(dofs, n, G, dx, lam, mu, indptr, indices, start, elems, local):
    """block_pattern_parts' parts on its pattern; ``elems[start[s]:start[s + 1]]`` are node s's
    elements and ``local`` its local index in each."""
    nel, m = dofs.shape
    nq = dx.shape[1]
    nz = indices.size
    # Parts, row by row: each (element, a = the row's node, b) adds its block at b's rank.
    parts = np.zeros((nz, 12))
    rank = np.zeros(n, np.int64)
    Gf = G.reshape(nel, nq, 3 * m)  # (e, q, 3 b + j)
    Mt = np.empty((3, 3 * m))  # Mt[i, 3 b + j] = M_(ab)[i, j]
    for s in range(n):
        for k in range(indptr[s], indptr[s + 1]):
            rank[indices[k]] = k
        for k in range(start[s], start[s + 1]):
            e = elems[k]
            a = local[k]
            Mt[:] = 0.0
            for q in range(nq):  # the sum over q in order, each a contiguous row of 30
                for i in range(3):
                    wa = G[e, q, a, i] * dx[e, q]
                    for bj in range(3 * m):
                        Mt[i, bj] += wa * Gf[e, q, bj]
            for b in range(m):
                M = Mt[:, 3 * b : 3 * b + 3]
                inplane = mu * (M[0, 0] + M[1, 1])
                P = parts[rank[dofs[e, b]]]
                # _PP: (0,0), (0,1), (1,0), (1,1), (2,2)
                P[0] += lam * M[0, 0] + mu * M[0, 0] + inplane
                P[1] += lam * M[0, 1] + mu * M[1, 0]
                P[2] += lam * M[1, 0] + mu * M[0, 1]
                P[3] += lam * M[1, 1] + mu * M[1, 1] + inplane
                P[4] += inplane
                # _PZ: (0,2), (1,2), (2,0), (2,1)
                P[5] += lam * M[0, 2] + mu * M[2, 0]
                P[6] += lam * M[1, 2] + mu * M[2, 1]
                P[7] += lam * M[2, 0] + mu * M[0, 2]
                P[8] += lam * M[2, 1] + mu * M[1, 2]
                # _ZZ: (0,0), (1,1), (2,2)
                P[9] += mu * M[2, 2]
                P[10] += mu * M[2, 2]
                P[11] += (lam + 2.0 * mu) * M[2, 2]
    return parts


@njit(cache=True)
def reduced_lower_count(indptr: np.ndarray, indices: np.ndarray, red: np.ndarray) -> np.ndarray:
    """Column pointers of the reduced matrix's lower triangle (see :func:`reduced_lower_fill`).

    Parameters
    ----------
    indptr, indices : the node-block pattern (sorted columns); red : (3 n,) int64 — each DOF's
        reduced index, -1 where prescribed (the unknowns are a selection of DOFs, in order).

    Returns
    -------
    colptr : (nfree + 1,) int64 — where each reduced column starts; colptr[-1] = nnz.
    """
    n = indptr.size - 1
    nfree = 0
    for i in range(red.size):
        if red[i] >= 0:
            nfree += 1
    colptr = np.zeros(nfree + 1, np.int64)
    for br in range(n):
        for c in range(3):
            col = red[3 * br + c]
            if col < 0:
                continue
            cnt = 0
            for k in range(indptr[br], indptr[br + 1]):
                bc = indices[k]
                if bc < br:
                    continue
                for d in range(c if bc == br else 0, 3):
                    if red[3 * bc + d] >= 0:
                        cnt += 1
            colptr[col + 1] = cnt
    for j in range(nfree):
        colptr[j + 1] += colptr[j]
    return colptr


@njit(cache=True)
def reduced_lower_fill(indptr: np.ndarray, indices: np.ndarray, red: np.ndarray,
                       colptr: np.ndarray, flat: np.ndarray, rows: np.ndarray) -> None:  # fmt: skip
    """The reduced matrix's lower triangle in the node blocks, column by column.

    The lower triangle of K is the upper of its transpose: block (br, bc) with bc >= br, entry
    (c, d), is the lower entry (3 bc + d, 3 br + c). Walking the block rows br, then c, then the
    row's blocks bc (ascending), then d lists the entries sorted by reduced column and, within
    a column, by row: the compressed-column order (CHOLMOD's), so the matrix is built without
    a sort.

    Parameters
    ----------
    indptr, indices, red : as :func:`reduced_lower_count`; colptr : its answer.
    flat, rows : (nnz,) int (int32 or int64), written — index into the (nnzb, 3, 3) block
        values (C order) and reduced row (>= the column) of each entry; column j's are
        ``colptr[j]:colptr[j+1]``.
    """
    n = indptr.size - 1
    for br in range(n):
        for c in range(3):
            col = red[3 * br + c]
            if col < 0:
                continue
            p = colptr[col]
            for k in range(indptr[br], indptr[br + 1]):
                bc = indices[k]
                if bc < br:
                    continue
                for d in range(c if bc == br else 0, 3):
                    row = red[3 * bc + d]
                    if row >= 0:
                        flat[p] = 9 * k + 3 * c + d
                        rows[p] = row
                        p += 1


@njit(cache=True)
def von_mises(u: np.ndarray, dofs: np.ndarray, G: np.ndarray, mu: float,
              z_scale: float) -> np.ndarray:  # fmt: skip
    """Von Mises stress at each point of ``G`` (as :func:`fea.solid3d._von_mises`), MPa.

    u : (3 n,) mm, DOF ``3 s + c``; dofs : (nel, 10) int64; G : (nel, nq, 10, 3) 1/mm;
    mu : float, MPa (the deviatoric stress is 2 mu dev(eps)); z_scale : the mesh stretched by
    this along z (the z gradients divided by it).
    Returns (nel, nq) MPa.
    """
    nel, nq = G.shape[0], G.shape[1]
    m = dofs.shape[1]
    out = np.empty((nel, nq))
    ue = np.empty((m, 3))
    H = np.empty((3, 3))
    for e in range(nel):
        for a in range(m):
            for c in range(3):
                ue[a, c] = u[3 * dofs[e, a] + c]
        for q in range(nq):
            for c in range(3):  # H[c, j] = du_c / dx_j
                for j in range(3):
                    acc = 0.0
                    for a in range(m):
                        acc += ue[a, c] * G[e, q, a, j]
                    H[c, j] = acc
            for c in range(3):
                H[c, 2] /= z_scale
            tr3 = (H[0, 0] + H[1, 1] + H[2, 2]) / 3.0
            # deviatoric stress 2 mu (eps - tr eps / 3 I); von Mises sqrt(3/2 s:s)
            ss = 0.0
            for i in range(3):
                for j in range(3):
                    eps = 0.5 * (H[i, j] + H[j, i])
                    if i == j:
                        eps -= tr3
                    sij = 2.0 * mu * eps
                    ss += sij * sij
            out[e, q] = np.sqrt(1.5 * ss)
    return out


@njit(cache=True)
def stiffness_blocks(parts: np.ndarray, s: float) -> np.ndarray:
    """The node blocks of ``K(s) = s K_pp + K_pz + K_zz / s`` from the parts (nnzb, 12).

    Each entry of a 3x3 block is one part, or (on the diagonal) an in-plane part times s plus
    an out-of-plane one over s: the product of the parts with fea.solid3d's (12, 9) table
    without its zeros (nothing larger than a block is formed). Returns (nnzb, 3, 3), N/mm.
    """
    nb = parts.shape[0]
    B = np.empty((nb, 3, 3))
    inv = 1.0 / s
    for k in range(nb):
        P = parts[k]
        B[k, 0, 0] = P[0] * s + P[9] * inv
        B[k, 0, 1] = P[1] * s
        B[k, 1, 0] = P[2] * s
        B[k, 1, 1] = P[3] * s + P[10] * inv
        B[k, 2, 2] = P[4] * s + P[11] * inv
        B[k, 0, 2] = P[5]
        B[k, 1, 2] = P[6]
        B[k, 2, 0] = P[7]
        B[k, 2, 1] = P[8]
    return B


@njit(cache=True)
def parts_matvec(indptr: np.ndarray, indices: np.ndarray, parts: np.ndarray, s: float,
                 x: np.ndarray) -> np.ndarray:  # fmt: skip
    """``K(s) @ x`` from the parts without forming K(s)'s blocks (nnzb, 3, 3).

    Each block is made as :func:`stiffness_blocks` makes it and multiplied in scipy's
    ``bsr_matvec`` order (block rows ascending, a row's blocks in pattern order, each block row
    summed from the running value over its three columns), so the product is
    ``bsr_matrix((stiffness_blocks(parts, s), indices, indptr)) @ x`` bit for bit (fastmath
    off: no reordering). What it saves is that matrix: 72 bytes a block (0.14 GB on the SEA
    spring's sector) held beside CHOLMOD's factor during a re-check (docs/solid3d.md, "Memory").

    indptr (nb + 1,), indices (nnzb,) — the node-block pattern; parts (nnzb, 12) N/mm;
    s — thickness / reference thickness; x (3 nb,) mm. Returns (3 nb,) N.
    """
    nb = indptr.size - 1
    y = np.zeros(3 * nb)
    inv = 1.0 / s
    B = np.empty((3, 3))
    for i in range(nb):
        y0 = y[3 * i]
        y1 = y[3 * i + 1]
        y2 = y[3 * i + 2]
        for k in range(indptr[i], indptr[i + 1]):
            P = parts[k]
            B[0, 0] = P[0] * s + P[9] * inv
            B[0, 1] = P[1] * s
            B[1, 0] = P[2] * s
            B[1, 1] = P[3] * s + P[10] * inv
            B[2, 2] = P[4] * s + P[11] * inv
            B[0, 2] = P[5]
            B[1, 2] = P[6]
            B[2, 0] = P[7]
            B[2, 1] = P[8]
            j = 3 * indices[k]
            x0 = x[j]
            x1 = x[j + 1]
            x2 = x[j + 2]
            y0 = y0 + B[0, 0] * x0
            y0 = y0 + B[0, 1] * x1
            y0 = y0 + B[0, 2] * x2
            y1 = y1 + B[1, 0] * x0
            y1 = y1 + B[1, 1] * x1
            y1 = y1 + B[1, 2] * x2
            y2 = y2 + B[2, 0] * x0
            y2 = y2 + B[2, 1] * x1
            y2 = y2 + B[2, 2] * x2
        y[3 * i] = y0
        y[3 * i + 1] = y1
        y[3 * i + 2] = y2
    return y


@njit(cache=True)
def full_from_lower(colptr: np.ndarray, rows: np.ndarray, vals: np.ndarray):
    """A symmetric matrix in compressed rows (both triangles) from its lower triangle in
    compressed columns (:func:`reduced_lower_fill`'s order): the multigrid solver's matrix.

    Column j of the lower triangle is row j's entries from the diagonal on; its entries
    below the diagonal, (i, j), are also (j, i) of row i. Walking the columns in order fills
    every row with its columns ascending, so no sort is needed.

    Parameters
    ----------
    colptr : (n + 1,) int64; rows : (nnz,) int32 or int64, rows >= their column, sorted in
    each column; vals : (nnz,) float, N/mm.

    Returns
    -------
    indptr (n + 1,) int64, indices (2 nnz - n,) int32, data (2 nnz - n,) float, N/mm.
    """
    n = colptr.size - 1
    count = np.zeros(n + 1, np.int64)
    for j in range(n):
        count[j + 1] += colptr[j + 1] - colptr[j]
        for p in range(colptr[j], colptr[j + 1]):
            if rows[p] > j:
                count[rows[p] + 1] += 1
    for i in range(n):
        count[i + 1] += count[i]
    indices = np.empty(count[n], np.int32)
    data = np.empty(count[n])
    pos = count[:n].copy()
    for j in range(n):
        for p in range(colptr[j], colptr[j + 1]):
            i = rows[p]
            indices[pos[j]] = i
            data[pos[j]] = vals[p]
            pos[j] += 1
            if i > j:
                indices[pos[i]] = j
                data[pos[i]] = vals[p]
                pos[i] += 1
    return count, indices, data


@njit(cache=True)
def symmetric_gauss_seidel(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                           diagonal: np.ndarray, b: np.ndarray, x: np.ndarray) -> None:  # fmt: skip
    """One forward and one backward Gauss-Seidel sweep on ``A x = b``, ``x`` updated in place.

    A in compressed rows (indptr (n + 1,), indices (nnz,), data (nnz,) N/mm), ``diagonal``
    (n,) its diagonal, N/mm; b (n,) N; x (n,) mm. A forward sweep followed by a backward one
    is a symmetric smoother: the multigrid preconditioner stays symmetric, as conjugate
    gradients needs.

    The backward sweep reads each row from its last entry to its first, so that the matrix
    is one descending stream: rows descending with their entries ascending ran at ~2.4x the
    forward sweep's time on the SEA spring's 31M-entry matrix (the hardware prefetch does not
    follow that pattern), reversed ~1.1x (benchmarks/multigrid_check.py; docs/solid3d.md).
    Only the order of the row's sum changes: round-off.
    """
    n = b.size
    for i in range(n):
        acc = b[i]
        for k in range(indptr[i], indptr[i + 1]):
            acc -= data[k] * x[indices[k]]
        x[i] += acc / diagonal[i]
    _backward_sweep(indptr, indices, data, diagonal, b, x)


@njit(cache=True)
def _backward_sweep(indptr, indices, data, diagonal, b, x) -> None:
    """The backward Gauss-Seidel sweep of :func:`symmetric_gauss_seidel` (rows from the last,
    each row's entries from its last: one descending stream)."""
    for i in range(b.size - 1, -1, -1):
        acc = b[i]
        for k in range(indptr[i + 1] - 1, indptr[i] - 1, -1):
            acc -= data[k] * x[indices[k]]
        x[i] += acc / diagonal[i]


@njit(cache=True)
def diagonal_positions(indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Where each row's diagonal entry sits, (n,) int64 into ``indices`` (columns ascending in
    each row, as :func:`full_from_lower` makes them): the entries before it are the row's
    strictly lower part. -1 where a row has none (a zero diagonal: not positive definite)."""
    n = indptr.size - 1
    out = np.full(n, -1, np.int64)
    for i in range(n):
        for k in range(indptr[i], indptr[i + 1]):
            if indices[k] == i:
                out[i] = k
                break
    return out


@njit(cache=True)
def smooth_from_zero(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                     dpos: np.ndarray, diagonal: np.ndarray, b: np.ndarray,
                     x: np.ndarray) -> None:  # fmt: skip
    """:func:`symmetric_gauss_seidel` from x = 0 (the multigrid cycle's pre-smoothing,
    :meth:`fea.solid3d.Solid3DModel._solve_multigrid`): from zero the forward sweep reads
    only each row's strictly lower part, as the entries after the diagonal multiply zeros
    (~0.6 of a full sweep's time on the SEA spring's matrix). The same answer, bit for bit:
    the skipped terms are exact zeros.

    A (n, n) in compressed rows, columns ascending, N/mm; dpos (n,) :func:`diagonal_positions`;
    diagonal (n,) N/mm; b (n,) N; x (n,) mm, overwritten with the answer.
    """
    for i in range(b.size):
        acc = b[i]
        for k in range(indptr[i], dpos[i]):
            acc -= data[k] * x[indices[k]]
        x[i] = acc / diagonal[i]
    _backward_sweep(indptr, indices, data, diagonal, b, x)
