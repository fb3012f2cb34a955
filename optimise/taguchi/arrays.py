"""Orthogonal arrays: the finite-field constructions, the catalogue by name, orthogonality checks
and the interaction columns of Rao-Hamming arrays (see the package docstring).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache
from itertools import combinations

import numpy as np
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.taguchi._common import as_design, level_counts
from flexopt.optimise.taguchi.fields import galois_field, prime_power

__all__ = [
    "addelman_kempthorne_array",
    "array_spec",
    "ArraySpec",
    "CATALOGUE",
    "get_array",
    "interaction_columns",
    "is_orthogonal",
    "list_arrays",
    "non_orthogonal_pairs",
    "orthogonal_array",
    "paley_array",
    "rao_hamming_array",
    "rao_hamming_generators",
]

# ---------------------------------------------------------------------------------------------
# Constructions
# ---------------------------------------------------------------------------------------------


def rao_hamming_generators(s: int, k: int) -> np.ndarray:
    """Coefficient vectors of the columns of the Rao-Hamming array ``L_{s^k}``.

    One vector ``a`` per point of the projective space PG(k-1, s): its last nonzero coordinate is
    1.  They are grouped by the position of that coordinate (the basic column ``e_m`` first), and
    within a group ordered by ``sum(a_i s^i)`` over the earlier coordinates.  This is the column
    order of the standard Taguchi tables: L8 = (A, B, AB, C, AC, BC, ABC),
    L9 = (u1, u2, u1+u2, 2u1+u2).

    Parameters
    ----------
    s : int — prime power, the number of levels.
    k : int — number of basic (independent) columns; the array has ``s**k`` runs.

    Returns
    -------
    (n_columns, k) int — ``n_columns = (s**k - 1) / (s - 1)``; entries are GF(s) elements.
    """
    galois_field(s)
    if k < 1:
        raise OptimiseError(f"k = {k}: a Rao-Hamming array needs k >= 1 basic columns")
    rows = []
    for m in range(k):
        for v in range(s**m):
            a = [(v // s**i) % s for i in range(m)] + [1] + [0] * (k - m - 1)
            rows.append(a)
    return np.array(rows, dtype=int)


@cache
def _rao_hamming(s: int, k: int) -> np.ndarray:
    gf = galois_field(s)
    gen = rao_hamming_generators(s, k)
    runs = np.arange(s**k)
    # u_1 is the most significant digit of the run index, so column 1 reads 0..0 1..1 ...
    u = np.stack([(runs // s ** (k - 1 - i)) % s for i in range(k)], axis=1)
    out = np.zeros((runs.size, gen.shape[0]), dtype=int)
    for i in range(k):
        out = gf.add[out, gf.mul[u[:, i][:, None], gen[:, i][None, :]]]
    out.setflags(write=False)
    return out


def rao_hamming_array(s: int, k: int) -> np.ndarray:
    """The Rao-Hamming (Bose) orthogonal array ``OA(s^k, (s^k-1)/(s-1), s, 2)``.

    Run ``r`` is the vector ``u`` of base-``s`` digits of ``r`` (most significant first); column
    ``c`` holds ``a_c . u`` in GF(s) with ``a_c`` from :func:`rao_hamming_generators`.  Two
    columns with linearly independent ``a`` (always, as they are distinct projective points) take
    every pair of values equally often: strength 2.

    Returns
    -------
    (s**k, (s**k - 1) // (s - 1)) int — levels 0..s-1.
    """
    return _rao_hamming(int(s), int(k)).copy()


@cache
def _addelman_kempthorne(s: int) -> np.ndarray:
    gf = galois_field(s)
    if gf.prime == 2:
        raise OptimiseError(
            f"the Addelman-Kempthorne construction needs an odd prime power s, got s = {s}"
        )
    add, mul, neg, inv = gf.add, gf.mul, gf.neg, gf.inv
    v = min(set(range(1, s)) - gf.squares())  # a non-square
    four = add[add[1, 1], add[1, 1]]  # 1 + 1 + 1 + 1 in GF(s); nonzero as p is odd
    vm1 = add[v, neg[1]]  # v - 1
    rows = []
    for half in (0, 1):
        for i in range(s):
            sq = mul[i, i]
            for j in range(s):
                lin, quad = [], []
                for m in range(1, s):  # i + m j (+ b_m), scaled by 1/m (a relabelling)
                    x = add[i, mul[m, j]]
                    if half:
                        b_m = mul[vm1, inv[mul[four, mul[v, m]]]]  # (v-1) / (4 v m)
                        x = add[x, b_m]
                    lin.append(mul[inv[m], x])
                for m in range(s):  # i^2 + m i + j   |   v i^2 + k_m i + j + c_m
                    if half:
                        k_m = mul[v, m]
                        c_m = mul[mul[mul[m, m], vm1], inv[four]]  # m^2 (v-1) / 4
                        x = add[add[add[mul[v, sq], mul[k_m, i]], j], c_m]
                    else:
                        x = add[add[sq, mul[m, i]], j]
                    quad.append(x)
                rows.append([half, i, quad[0], *lin, *quad[1:], j])
    out = np.array(rows, dtype=int)
    out = out[np.lexsort((out[:, 2], out[:, 1], out[:, 0]))]
    out.setflags(write=False)
    return out


def addelman_kempthorne_array(s: int) -> np.ndarray:
    """The mixed array ``OA(2 s^2, 2^1 s^(2s+1), 2)`` for an odd prime power ``s`` (L18, L50).

    Runs are ``(h, i, j)`` with ``h`` in {0, 1} and ``i, j`` in GF(s); ``v`` is a non-square.
    Addelman and Kempthorne (1961; Hedayat, Sloane and Stufken, *Orthogonal Arrays*, Thm 3.16)
    give ``2s + 1`` columns of ``s`` levels:

    ========================  ===========================  ==================================
    column                    h = 0                        h = 1
    ========================  ===========================  ==================================
    ``i``                     ``i``                        ``i``
    ``q_0``                   ``i^2 + j``                  ``v i^2 + j``
    ``l_m`` (m = 1..s-1)      ``i + m j``                  ``i + m j + b_m``
    ``q_m`` (m = 1..s-1)      ``i^2 + m i + j``            ``v i^2 + k_m i + j + c_m``
    ``j``                     ``j``                        ``j``
    ========================  ===========================  ==================================

    with ``b_m = (v-1)/(4vm)``, ``k_m = vm``, ``c_m = m^2 (v-1)/4``; ``h`` itself is the two-level
    column.  Every ``s``-level column is balanced within each half, so ``h`` keeps strength 2, and
    within each ``(h, i)`` block every other column is a bijection of ``j``, so the first two
    columns form a ``2s``-level factor orthogonal to the rest (in the L18 the 1x2 interaction is
    free).  Standard form: columns ``h, i, q_0, l_1.., q_1.., j``, each ``l_m`` divided by ``m``
    (a relabelling) and the runs sorted by ``(h, i, q_0)``; for ``s = 3`` this is, entry by entry,
    the printed Taguchi L18.

    Returns
    -------
    (2 s**2, 2 s + 2) int — column 0 has levels 0..1, the others 0..s-1.
    """
    return _addelman_kempthorne(int(s)).copy()


@cache
def _paley(p: int) -> np.ndarray:
    if prime_power(p) != (p, 1) or p % 4 != 3:
        raise OptimiseError(
            f"the Paley construction needs a prime p = 3 (mod 4) (3, 7, 11, 19, ...), got {p}"
        )
    residues = {(x * x) % p for x in range(1, p)}
    chi = np.array([0] + [1 if a in residues else -1 for a in range(1, p)])
    idx = np.arange(p)
    q = chi[(idx[None, :] - idx[:, None]) % p]  # Jacobsthal matrix, skew-symmetric for p = 3 mod 4
    s = np.zeros((p + 1, p + 1), dtype=int)
    s[0, 1:] = 1
    s[1:, 0] = -1
    s[1:, 1:] = q
    h = np.eye(p + 1, dtype=int) + s  # Hadamard: h h^T = (p+1) I
    h = h * h[:, :1]  # first column all +1
    h = h * h[:1, :]  # first row all +1
    out = ((1 - h[:, 1:]) // 2).astype(int)
    out.setflags(write=False)
    return out


def paley_array(p: int) -> np.ndarray:
    """The two-level array ``OA(p+1, p, 2, 2)`` from the Paley Hadamard matrix (L12 for p = 11).

    ``H = I + S`` with ``S`` the bordered Jacobsthal matrix ``Q[i, j] = chi(j - i)`` (``chi`` the
    quadratic character mod p), normalised so its first row and column are +1; the other columns,
    with +1 -> 0 and -1 -> 1, are the array.  Interactions of two columns are spread over all the
    others (partial aliasing): use it for main effects only.

    Returns
    -------
    (p + 1, p) int — levels 0..1; run 0 is all zeros.
    """
    return _paley(int(p)).copy()


# ---------------------------------------------------------------------------------------------
# Catalogue
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ArraySpec:
    """A catalogued orthogonal array.

    Attributes
    ----------
    name : str — canonical name, e.g. ``"L18(2^1 3^7)"``.
    runs : int — number of runs (rows).
    levels : tuple of int — number of levels of each column.
    construction : str — ``"rao_hamming"``, ``"addelman_kempthorne"`` or ``"paley"``.
    parameters : tuple of int — the construction's arguments, ``(s, k)``, ``(s,)`` or ``(p,)``.
    """

    name: str
    runs: int
    levels: tuple[int, ...]
    construction: str
    parameters: tuple[int, ...]

    @property
    def n_columns(self) -> int:
        return len(self.levels)


_BUILDERS: dict[str, Callable[..., np.ndarray]] = {
    "rao_hamming": _rao_hamming,
    "addelman_kempthorne": _addelman_kempthorne,
    "paley": _paley,
}


def _level_signature(levels: Sequence[int]) -> str:
    counts: dict[int, int] = {}
    for s in levels:
        counts[s] = counts.get(s, 0) + 1
    return " ".join(f"{s}^{counts[s]}" for s in sorted(counts))


def _spec(construction: str, *parameters: int) -> ArraySpec:
    if construction == "rao_hamming":
        s, k = parameters
        runs, levels = s**k, (s,) * ((s**k - 1) // (s - 1))
    elif construction == "addelman_kempthorne":
        (s,) = parameters
        runs, levels = 2 * s * s, (2,) + (s,) * (2 * s + 1)
    else:
        (p,) = parameters
        runs, levels = p + 1, (2,) * p
    name = f"L{runs}({_level_signature(levels)})"
    return ArraySpec(name, runs, levels, construction, tuple(parameters))


#: The catalogued arrays, in order of size; for equal run counts the first is what the bare name
#: ("L16", "L64") means.
CATALOGUE: tuple[ArraySpec, ...] = (
    _spec("rao_hamming", 2, 2),  # L4(2^3)
    _spec("rao_hamming", 2, 3),  # L8(2^7)
    _spec("rao_hamming", 3, 2),  # L9(3^4)
    _spec("paley", 11),  # L12(2^11)
    _spec("rao_hamming", 2, 4),  # L16(2^15)
    _spec("rao_hamming", 4, 2),  # L16(4^5)
    _spec("addelman_kempthorne", 3),  # L18(2^1 3^7)
    _spec("rao_hamming", 5, 2),  # L25(5^6)
    _spec("rao_hamming", 3, 3),  # L27(3^13)
    _spec("rao_hamming", 2, 5),  # L32(2^31)
    _spec("rao_hamming", 7, 2),  # L49(7^8)
    _spec("addelman_kempthorne", 5),  # L50(2^1 5^11)
    _spec("rao_hamming", 2, 6),  # L64(2^63)
    _spec("rao_hamming", 4, 3),  # L64(4^21)
    _spec("rao_hamming", 8, 2),  # L64(8^9)
    _spec("rao_hamming", 3, 4),  # L81(3^40)
)

_NAME = re.compile(r"^\s*L\s*(\d+)\s*(?:\((.*)\))?\s*$", re.IGNORECASE)


def _parse_name(name: str) -> tuple[int, dict[int, int] | None]:
    m = _NAME.match(name)
    if m is None:
        raise OptimiseError(
            f"array name {name!r} is not of the form 'L<runs>' or 'L<runs>(<s>^<n> ...)', "
            f"e.g. 'L25' or 'L16(4^5)'; known: {', '.join(list_arrays())}"
        )
    runs = int(m.group(1))
    if m.group(2) is None:
        return runs, None
    counts: dict[int, int] = {}
    text = m.group(2).replace("**", "^")
    for term in re.split(r"[\s×x·*]+", text.strip()):
        if not term:
            continue
        tm = re.fullmatch(r"(\d+)(?:\^(\d+))?", term)
        if tm is None:
            raise OptimiseError(
                f"cannot read the levels {m.group(2)!r} of array {name!r}; write them as "
                "'<levels>^<columns>' terms, e.g. 'L18(2^1 3^7)'"
            )
        s, n = int(tm.group(1)), int(tm.group(2) or 1)
        counts[s] = counts.get(s, 0) + n
    return runs, counts


def list_arrays() -> tuple[str, ...]:
    """Canonical names of the catalogued arrays, smallest first."""
    return tuple(spec.name for spec in CATALOGUE)


def array_spec(name: str) -> ArraySpec:
    """The catalogue entry for ``name``: ``"L25"``, ``"L16(4^5)"``, ``"l18(2x3^7)"`` all work.

    A bare ``"L<runs>"`` means the first catalogued array with that many runs (``"L16"`` is
    ``L16(2^15)``, ``"L64"`` is ``L64(2^63)``).
    """
    runs, counts = _parse_name(str(name))
    matches = [sp for sp in CATALOGUE if sp.runs == runs]
    if counts is not None:
        matches = [
            sp for sp in matches if {s: sp.levels.count(s) for s in set(sp.levels)} == counts
        ]
    if not matches:
        same_runs = [sp.name for sp in CATALOGUE if sp.runs == runs]
        hint = f"with {runs} runs there is {', '.join(same_runs)}" if same_runs else ""
        raise OptimiseError(
            f"no orthogonal array {name!r} in the catalogue{'; ' + hint if hint else ''}; "
            f"known: {', '.join(list_arrays())}"
        )
    return matches[0]


def get_array(name: str) -> np.ndarray:
    """The orthogonal array called ``name`` (see :func:`array_spec`).

    Returns
    -------
    (runs, n_columns) int — levels 0..s-1 in each column; a fresh, writable copy.
    """
    spec = array_spec(name)
    return _BUILDERS[spec.construction](*spec.parameters).copy()


def orthogonal_array(
    name_or_runs: str | int, levels: int | Sequence[int] | None = None
) -> np.ndarray:
    """An orthogonal array by name (``"L25"``) or by run count and levels (``16, 4``).

    Parameters
    ----------
    name_or_runs : str or int — a name for :func:`get_array`, or the number of runs.
    levels : int or sequence of int, optional — with a run count: the number of levels of every
        column (``4`` picks L16(4^5)), or the distinct level counts of a mixed array (``(2, 3)``
        picks L18).  Without it the first catalogued array with that many runs.

    Returns
    -------
    (runs, n_columns) int — levels 0..s-1.
    """
    if isinstance(name_or_runs, str):
        spec = array_spec(name_or_runs)
        if levels is not None:
            want = {int(levels)} if isinstance(levels, int) else {int(s) for s in levels}
            if set(spec.levels) != want:
                raise OptimiseError(
                    f"{spec.name} has columns of {sorted(set(spec.levels))} levels, "
                    f"not {sorted(want)}"
                )
        return get_array(spec.name)
    runs = int(name_or_runs)
    matches = [sp for sp in CATALOGUE if sp.runs == runs]
    if levels is not None:
        want = {int(levels)} if isinstance(levels, int) else {int(s) for s in levels}
        matches = [sp for sp in matches if set(sp.levels) == want]
    if not matches:
        raise OptimiseError(
            f"no catalogued array with {runs} runs"
            + (f" and {levels} levels" if levels is not None else "")
            + f"; known: {', '.join(list_arrays())}"
        )
    return get_array(matches[0].name)


# ---------------------------------------------------------------------------------------------
# Orthogonality
# ---------------------------------------------------------------------------------------------


def non_orthogonal_pairs(array: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of columns ``(i, j)``, i < j, that do not show every level pair equally often.

    A single column counts as ``(i, i)`` when its levels are not equally frequent.

    Parameters
    ----------
    array : (runs, n_columns) int — levels 0..s-1.
    """
    a = as_design(array)
    s = level_counts(a)
    n = a.shape[0]
    bad = [(c, c) for c in range(a.shape[1]) if len(set(np.bincount(a[:, c]))) > 1]
    for i, j in combinations(range(a.shape[1]), 2):
        cells = s[i] * s[j]
        counts = np.bincount(a[:, i] * s[j] + a[:, j], minlength=cells)
        if n % cells or np.any(counts != n // cells):
            bad.append((i, j))
    return bad


def is_orthogonal(array: np.ndarray) -> bool:
    """True when ``array`` has strength 2: every column pair shows each level pair equally often.

    Parameters
    ----------
    array : (runs, n_columns) int — levels 0..s-1 (mixed level counts allowed).
    """
    return not non_orthogonal_pairs(array)


def interaction_columns(name: str, column_a: int, column_b: int) -> tuple[int, ...]:
    """The columns that carry the interaction of two columns of a Rao-Hamming array.

    For columns with coefficient vectors ``a`` and ``b`` the interaction lives in the ``s - 1``
    columns ``a + t b`` (t = 1..s-1, rescaled so the last nonzero coordinate is 1): one column for
    two-level arrays (L8: 1x2 -> 3), two for three-level ones (L27: 1x2 -> 3, 4).  This is the
    textbook interaction table; columns are 0-based here.

    Raises
    ------
    OptimiseError
        The array is not a Rao-Hamming array (L12, L18, L50 spread interactions over many columns).
    """
    spec = array_spec(name)
    if spec.construction != "rao_hamming":
        raise OptimiseError(
            f"{spec.name} is not a Rao-Hamming array: its two-factor interactions are partially "
            "aliased with many columns; use an L4/L8/L9/L16/L25/L27/... array to study interactions"
        )
    s, k = spec.parameters
    for c in (column_a, column_b):
        if not 0 <= c < spec.n_columns:
            raise OptimiseError(f"column {c} is outside {spec.name} (0..{spec.n_columns - 1})")
    if column_a == column_b:
        raise OptimiseError(f"the interaction needs two different columns, got {column_a} twice")
    gf = galois_field(s)
    gen = rao_hamming_generators(s, k)
    index = {tuple(g): c for c, g in enumerate(gen.tolist())}
    inv = gf.inv
    out = []
    for t in range(1, s):
        w = gf.add[gen[column_a], gf.mul[t, gen[column_b]]]
        lead = w[np.nonzero(w)[0][-1]]
        out.append(index[tuple(gf.mul[inv[lead], w].tolist())])
    return tuple(sorted(out))
