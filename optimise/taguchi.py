"""Taguchi screening: orthogonal arrays, signal-to-noise ratios, main effects, ANOVA, prediction.

Plain numerics: arrays in, frozen dataclasses out; no files, no clock, no plotting (the main-effect
and two-way tables are the plot *data*; ``pipeline`` draws them).

The orthogonal arrays are built from finite-field constructions, never typed in:

* ``L_{s^k}(s^((s^k - 1)/(s - 1)))`` for a prime power ``s`` by the Rao-Hamming (Bose) construction:
  one column per linear form ``a . u`` over GF(s), ``u`` running over GF(s)^k.  The column order
  reproduces the standard Taguchi tables (L4, L8, L9, L16, L16(4^5), L25, L27, ...), so textbook
  linear graphs and interaction tables apply, and :func:`interaction_columns` computes them.
* ``L_{2s^2}(2^1 s^(2s+1))`` for an odd prime power ``s`` (L18, L50) by the Addelman-Kempthorne
  construction plus the two-level "half" column; its standard form for s = 3 is the printed L18.
* ``L_{p+1}(2^p)`` for a prime ``p = 3 (mod 4)`` (L12) by the Paley construction of a Hadamard
  matrix.

Levels are 0-based everywhere (level ``l`` of a factor is ``l``; Taguchi tables print ``l + 1``).
docs/taguchi.md has the constructions, the formulas, the pooling rule and a worked example.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cache
from itertools import combinations, product

import numpy as np
from flexopt.optimise.errors import OptimiseError
from scipy import stats

__all__ = [
    "AdditivityCheck",
    "AnovaTable",
    "ArraySpec",
    "Confirmation",
    "GaloisField",
    "Interaction",
    "Layout",
    "MainEffect",
    "Pool",
    "TaguchiResult",
    "addelman_kempthorne_array",
    "additivity_check",
    "analyse",
    "anova",
    "array_spec",
    "confirm",
    "galois_field",
    "get_array",
    "interaction",
    "interaction_columns",
    "is_orthogonal",
    "list_arrays",
    "main_effects",
    "non_orthogonal_pairs",
    "orthogonal_array",
    "paley_array",
    "predict",
    "rao_hamming_array",
    "rao_hamming_generators",
    "select_array",
    "sn_ratio",
]

# ---------------------------------------------------------------------------------------------
# Finite fields
# ---------------------------------------------------------------------------------------------

# Monic irreducible polynomials x^m + c_{m-1} x^{m-1} + ... + c_0 over GF(p), as (c_0, .., c_{m-1}).
# An element of GF(p^m) is the integer whose base-p digits (least significant first) are the
# coefficients of its polynomial in x.  For GF(4) this makes 2 = x = alpha and 3 = x + 1 = alpha^2,
# the labelling of the standard L16(4^5) table.
_IRREDUCIBLE: dict[int, tuple[int, ...]] = {
    4: (1, 1),  # x^2 + x + 1
    8: (1, 1, 0),  # x^3 + x + 1
    9: (1, 0),  # x^2 + 1        (-1 is not a square mod 3)
    16: (1, 1, 0, 0),  # x^4 + x + 1
    25: (2, 1),  # x^2 + x + 2    (discriminant 3 is not a square mod 5)
    27: (1, 2, 0),  # x^3 + 2x + 1   (no root in GF(3))
}


def _prime_power(q: int) -> tuple[int, int] | None:
    """``(p, m)`` with ``q = p**m`` for a prime ``p``, or None."""
    if q < 2:
        return None
    p = next(d for d in range(2, q + 1) if q % d == 0)
    m, r = 0, q
    while r % p == 0:
        r //= p
        m += 1
    return (p, m) if r == 1 else None


@dataclass(frozen=True, eq=False)
class GaloisField:
    """The finite field GF(q) as addition and multiplication tables.

    Attributes
    ----------
    order : int — q = p**m.
    prime : int — the characteristic p.
    add, mul : (q, q) int — ``add[a, b] = a + b`` and ``mul[a, b] = a * b`` in the field; elements
        are 0..q-1 with 0 and 1 the additive and multiplicative identities.
    """

    order: int
    prime: int
    add: np.ndarray
    mul: np.ndarray

    @property
    def neg(self) -> np.ndarray:
        """(q,) int — additive inverses."""
        return np.argmin(self.add, axis=1)  # add[a, b] == 0 exactly once per row

    @property
    def inv(self) -> np.ndarray:
        """(q,) int — multiplicative inverses; ``inv[0]`` is -1 (zero has none)."""
        out = np.full(self.order, -1)
        rows, cols = np.nonzero(self.mul == 1)
        out[rows] = cols
        return out

    def squares(self) -> frozenset[int]:
        """The elements that are squares (including 0)."""
        return frozenset(int(v) for v in np.diag(self.mul))


@cache
def galois_field(q: int) -> GaloisField:
    """The field GF(q) for a prime q or a prime power q in {4, 8, 9, 16, 25, 27}.

    Raises
    ------
    OptimiseError
        q is not a prime power, or a prime power whose irreducible polynomial is not tabulated.
    """
    pm = _prime_power(int(q))
    if pm is None:
        raise OptimiseError(
            f"GF({q}) does not exist: q must be a prime power (2, 3, 4, 5, 7, 8, 9, ...)"
        )
    p, m = pm
    if m == 1:
        e = np.arange(p)
        add = (e[:, None] + e[None, :]) % p
        mul = (e[:, None] * e[None, :]) % p
    else:
        if q not in _IRREDUCIBLE:
            raise OptimiseError(
                f"GF({q}) needs an irreducible polynomial of degree {m} over GF({p}); "
                f"tabulated are q in {sorted(_IRREDUCIBLE)} and every prime"
            )
        poly = _IRREDUCIBLE[q]
        digits = [[(a // p**i) % p for i in range(m)] for a in range(q)]

        def to_int(d: Sequence[int]) -> int:
            return sum(int(c) * p**i for i, c in enumerate(d))

        add = np.array(
            [
                [to_int([(x + y) % p for x, y in zip(da, db, strict=True)]) for db in digits]
                for da in digits
            ]
        )
        mul = np.zeros((q, q), dtype=int)
        for a in range(q):
            for b in range(q):
                c = [0] * (2 * m - 1)
                for i, x in enumerate(digits[a]):
                    for j, y in enumerate(digits[b]):
                        c[i + j] = (c[i + j] + x * y) % p
                for d in range(2 * m - 2, m - 1, -1):  # x^m = -(c_0 + ... + c_{m-1} x^{m-1})
                    lead, c[d] = c[d], 0
                    for i, ci in enumerate(poly):
                        c[d - m + i] = (c[d - m + i] - lead * ci) % p
                mul[a, b] = to_int(c[:m])
    gf = GaloisField(q, p, add, mul)
    # A reducible polynomial would give zero divisors: every nonzero row must permute 1..q-1.
    nonzero = np.sort(mul[1:, 1:], axis=1)
    if not np.array_equal(nonzero, np.broadcast_to(np.arange(1, q), nonzero.shape)):
        raise OptimiseError(f"internal: the polynomial tabulated for GF({q}) is not irreducible")
    add.setflags(write=False)
    mul.setflags(write=False)
    return gf


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
    if _prime_power(p) != (p, 1) or p % 4 != 3:
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


# In order of size; for equal run counts the first is what the bare name ("L16", "L64") means.
_CATALOGUE: tuple[ArraySpec, ...] = (
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
    return tuple(spec.name for spec in _CATALOGUE)


def array_spec(name: str) -> ArraySpec:
    """The catalogue entry for ``name``: ``"L25"``, ``"L16(4^5)"``, ``"l18(2x3^7)"`` all work.

    A bare ``"L<runs>"`` means the first catalogued array with that many runs (``"L16"`` is
    ``L16(2^15)``, ``"L64"`` is ``L64(2^63)``).
    """
    runs, counts = _parse_name(str(name))
    matches = [sp for sp in _CATALOGUE if sp.runs == runs]
    if counts is not None:
        matches = [
            sp for sp in matches if {s: sp.levels.count(s) for s in set(sp.levels)} == counts
        ]
    if not matches:
        same_runs = [sp.name for sp in _CATALOGUE if sp.runs == runs]
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
    matches = [sp for sp in _CATALOGUE if sp.runs == runs]
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


def _as_design(array: np.ndarray | Sequence[Sequence[int]], what: str = "array") -> np.ndarray:
    a = np.asarray(array)
    if a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 1:
        raise OptimiseError(
            f"{what} must be a (runs, columns) table of levels with >= 2 runs, got shape {a.shape}"
        )
    if not np.issubdtype(a.dtype, np.integer):
        if not np.all(np.isfinite(a)) or not np.array_equal(a, np.round(a)):
            raise OptimiseError(f"{what} must hold integer levels 0..s-1")
        a = a.astype(int)
    if a.min() < 0:
        r, c = np.argwhere(a < 0)[0]
        raise OptimiseError(
            f"{what}[{r}, {c}] = {a[r, c]}: levels are 0-based (0..s-1); subtract 1 from a "
            "Taguchi table printed with levels 1..s"
        )
    return a.astype(int, copy=False)


def _n_levels(a: np.ndarray, what: str = "array") -> np.ndarray:
    """(n_columns,) number of levels per column; every level 0..s-1 must occur."""
    out = a.max(axis=0) + 1
    for c in range(a.shape[1]):
        missing = np.setdiff1d(np.arange(out[c]), a[:, c])
        if missing.size:
            raise OptimiseError(
                f"column {c} of the {what} never takes level {missing[0]} but has levels up to "
                f"{out[c] - 1}: levels must be 0..s-1 with each one used"
            )
    return out


def non_orthogonal_pairs(array: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of columns ``(i, j)``, i < j, that do not show every level pair equally often.

    A single column counts as ``(i, i)`` when its levels are not equally frequent.

    Parameters
    ----------
    array : (runs, n_columns) int — levels 0..s-1.
    """
    a = _as_design(array)
    s = _n_levels(a)
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


# ---------------------------------------------------------------------------------------------
# Choosing an array
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Layout:
    """Factors assigned to the columns of an orthogonal array.

    Attributes
    ----------
    array_name : str — canonical name of the array.
    array : (runs, n_columns) int — the whole array, levels 0..s-1.
    factor_names : tuple of str — one per factor.
    columns : tuple of int — the column of each factor (0-based).
    interactions : tuple of (str, str, tuple of int) — requested interactions and the columns
        reserved for them (left empty so their sum of squares is the interaction's).
    """

    array_name: str
    array: np.ndarray
    factor_names: tuple[str, ...]
    columns: tuple[int, ...]
    interactions: tuple[tuple[str, str, tuple[int, ...]], ...] = ()

    @property
    def design(self) -> np.ndarray:
        """(runs, n_factors) int — the level of every factor in every run."""
        return self.array[:, list(self.columns)]

    @property
    def empty_columns(self) -> tuple[int, ...]:
        """Columns holding neither a factor nor a reserved interaction."""
        used = set(self.columns) | {c for *_, cols in self.interactions for c in cols}
        return tuple(c for c in range(self.array.shape[1]) if c not in used)

    @property
    def n_error_dof(self) -> int:
        """Degrees of freedom left for error by one response per run (before pooling)."""
        s = self.array.max(axis=0) + 1
        used = sum(int(s[c]) - 1 for c in self.columns)
        used += sum(
            (int(s[self.columns[self.factor_names.index(a)]]) - 1)
            * (int(s[self.columns[self.factor_names.index(b)]]) - 1)
            for a, b, _ in self.interactions
        )
        return self.array.shape[0] - 1 - used


def _letters(n: int) -> tuple[str, ...]:
    return tuple(chr(ord("A") + i) if i < 26 else f"F{i + 1}" for i in range(n))


def _assign_rao_hamming(
    spec: ArraySpec, levels: Sequence[int], pairs: Sequence[tuple[int, int]]
) -> tuple[list[int], list[tuple[int, ...]]] | None:
    """Depth-first assignment of factors to columns keeping requested interactions clean.

    Hard rule: the columns of a requested interaction hold no factor and no other requested
    interaction.  Preference: columns that are not the interaction column of two assigned factors,
    and whose interactions with them do not land on assigned factors (so a 4-factor L8 gets the
    resolution-IV columns 1, 2, 4, 7).
    """
    n_cols = spec.n_columns
    inter = {}

    def cols_of(a: int, b: int) -> tuple[int, ...]:
        key = (min(a, b), max(a, b))
        if key not in inter:
            inter[key] = interaction_columns(spec.name, *key)
        return inter[key]

    chosen: list[int] = []
    budget = [20000]

    def reserved(upto: list[int]) -> list[set[int]]:
        return [set(cols_of(upto[a], upto[b])) for a, b in pairs if a < len(upto) and b < len(upto)]

    def ok(cand: list[int]) -> bool:
        sets = reserved(cand)
        taken = set(cand)
        for i, r in enumerate(sets):
            if r & taken or any(r & o for o in sets[i + 1 :]):
                return False
        return True

    def score(c: int) -> int:
        bad = sum(c in cols_of(x, y) for x, y in combinations(chosen, 2))
        bad += sum(bool(set(cols_of(c, x)) & set(chosen)) for x in chosen)
        return bad

    def dfs(f: int) -> bool:
        if f == len(levels):
            return True
        budget[0] -= 1
        if budget[0] < 0:
            return False
        cands = [c for c in range(n_cols) if c not in chosen and spec.levels[c] == levels[f]]
        for c in sorted(cands, key=lambda c: (score(c), c)):
            chosen.append(c)
            if ok(chosen) and dfs(f + 1):
                return True
            chosen.pop()
        return False

    if not dfs(0):
        return None
    return list(chosen), [cols_of(chosen[a], chosen[b]) for a, b in pairs]


def select_array(
    factor_levels: Sequence[int] | Mapping[str, int],
    interactions: Sequence[tuple[str, str]] = (),
    *,
    min_error_dof: int = 0,
) -> Layout:
    """The smallest catalogued array that holds the factors, with the factors assigned to columns.

    A factor with ``s`` levels goes to a column with ``s`` levels (no dummy levels or merged
    columns).  In Rao-Hamming arrays the columns of each requested interaction are kept free of
    factors (the linear graph, computed); other arrays accept no interactions.

    Parameters
    ----------
    factor_levels : sequence of int, or mapping name -> int — levels of each factor; a sequence
        names them A, B, C, ...
    interactions : sequence of (str, str) — pairs of factor names whose interaction is to be
        estimated.
    min_error_dof : int — degrees of freedom to leave for error in empty columns (0: saturated
        arrays allowed; the ANOVA then needs pooling).

    Returns
    -------
    Layout

    Raises
    ------
    OptimiseError
        No catalogued array fits; the message lists the largest ones.
    """
    if isinstance(factor_levels, Mapping):
        names = tuple(str(n) for n in factor_levels)
        levels = [int(v) for v in factor_levels.values()]
    else:
        levels = [int(v) for v in factor_levels]
        names = _letters(len(levels))
    if not levels:
        raise OptimiseError("select_array needs at least one factor")
    for n, s in zip(names, levels, strict=True):
        if s < 2:
            raise OptimiseError(f"factor '{n}' has {s} levels; a factor needs at least 2")
    pairs = []
    for a, b in interactions:
        for x in (a, b):
            if x not in names:
                raise OptimiseError(f"interaction ({a!r}, {b!r}) names unknown factor {x!r}")
        if a == b:
            raise OptimiseError(f"interaction ({a!r}, {b!r}) needs two different factors")
        pairs.append((names.index(a), names.index(b)))
    need = sum(s - 1 for s in levels) + sum((levels[a] - 1) * (levels[b] - 1) for a, b in pairs)
    for spec in _CATALOGUE:
        if spec.runs - 1 - need < min_error_dof:
            continue
        if any(spec.levels.count(s) < levels.count(s) for s in set(levels)):
            continue
        if spec.construction == "rao_hamming":
            found = _assign_rao_hamming(spec, levels, pairs)
            if found is None:
                continue
            cols, icols = found
        else:
            if pairs:
                continue
            free = list(range(spec.n_columns))
            cols = []
            for s in levels:
                c = next(c for c in free if spec.levels[c] == s)
                free.remove(c)
                cols.append(c)
            icols = []
        return Layout(
            spec.name,
            get_array(spec.name),
            names,
            tuple(cols),
            tuple((names[a], names[b], ic) for (a, b), ic in zip(pairs, icols, strict=True)),
        )
    raise OptimiseError(
        f"no catalogued array holds factors with levels {levels}"
        + (f" and interactions {list(interactions)}" if pairs else "")
        + (f" leaving {min_error_dof} error dof" if min_error_dof else "")
        + f"; the largest are {', '.join(list_arrays()[-4:])}. Split the screening, drop factors, "
        "or give all factors the same number of levels"
    )


# ---------------------------------------------------------------------------------------------
# Signal-to-noise ratios
# ---------------------------------------------------------------------------------------------

_KIND_ALIASES = {
    "smaller": "smaller",
    "smaller-the-better": "smaller",
    "stb": "smaller",
    "larger": "larger",
    "larger-the-better": "larger",
    "ltb": "larger",
    "nominal": "nominal",
    "nominal-the-best": "nominal",
    "ntb": "nominal",
    "nominal-variance": "nominal-variance",
    "nominal-the-best-variance": "nominal-variance",
}


def _kind(kind: str) -> str:
    key = str(kind).strip().lower().replace("_", "-").replace(" ", "-")
    if key not in _KIND_ALIASES:
        raise OptimiseError(
            f"S/N kind {kind!r} is unknown; use 'smaller', 'larger', 'nominal' or "
            "'nominal_variance' (or 'smaller-the-better', 'larger-the-better', 'nominal-the-best')"
        )
    return _KIND_ALIASES[key]


def _as_responses(responses: np.ndarray | Sequence[float], n_runs: int | None = None) -> np.ndarray:
    y = np.asarray(responses, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[0] < 1 or y.shape[1] < 1:
        raise OptimiseError(
            f"responses must be (runs,) or (runs, replicates), got shape {np.shape(responses)}"
        )
    if n_runs is not None and y.shape[0] != n_runs:
        raise OptimiseError(
            f"{y.shape[0]} response rows for an array of {n_runs} runs: give one row per run"
        )
    bad = np.argwhere(~np.isfinite(y))
    if bad.size:
        r, c = bad[0]
        raise OptimiseError(
            f"response of run {r} (replicate {c}) is {y[r, c]}: every run needs a finite "
            "response; for a failed design use the worst observed value (or a penalty) so the "
            "array stays balanced"
        )
    return y


def _sn_smaller(y: np.ndarray, target: float | None) -> np.ndarray:
    return -10.0 * np.log10(np.mean(y**2, axis=1))


def _sn_larger(y: np.ndarray, target: float | None) -> np.ndarray:
    return -10.0 * np.log10(np.mean(1.0 / y**2, axis=1))


def _sn_nominal(y: np.ndarray, target: float | None) -> np.ndarray:
    if target is not None:
        return -10.0 * np.log10(np.mean((y - target) ** 2, axis=1))
    return 10.0 * np.log10(np.mean(y, axis=1) ** 2 / np.var(y, axis=1, ddof=1))


def _sn_nominal_variance(y: np.ndarray, target: float | None) -> np.ndarray:
    return -10.0 * np.log10(np.var(y, axis=1, ddof=1))


_SN: dict[str, Callable[[np.ndarray, float | None], np.ndarray]] = {
    "smaller": _sn_smaller,
    "larger": _sn_larger,
    "nominal": _sn_nominal,
    "nominal-variance": _sn_nominal_variance,
}


def sn_ratio(
    responses: np.ndarray | Sequence[float], kind: str = "smaller", target: float | None = None
) -> np.ndarray:
    """Taguchi signal-to-noise ratio of each run, in dB (larger is always better).

    ============================  ==================================  =========================
    kind                          S/N                                 replicates
    ============================  ==================================  =========================
    ``smaller``                   ``-10 log10(mean(y^2))``            >= 1
    ``larger``                    ``-10 log10(mean(1/y^2))``          >= 1
    ``nominal`` (no target)       ``10 log10(ybar^2 / s^2)``          >= 2 (s^2 with ddof = 1)
    ``nominal`` with ``target``   ``-10 log10(mean((y - target)^2))`` >= 1
    ``nominal_variance``          ``-10 log10(s^2)``                  >= 2
    ============================  ==================================  =========================

    With a single (deterministic, e.g. FE) response per run there is no variance, so
    nominal-the-best needs the target and becomes the mean squared deviation from it.

    Parameters
    ----------
    responses : (runs,) or (runs, replicates) float — measured or computed responses.
    kind : str — see the table; aliases such as ``"smaller-the-better"`` are accepted.
    target : float, optional — the nominal value, for ``kind="nominal"`` only.

    Returns
    -------
    (runs,) float, dB.

    Raises
    ------
    OptimiseError
        Unknown kind; a target with another kind; too few replicates; an S/N that is infinite
        (a zero response for smaller-/larger-the-better, zero variance or an exact hit on the
        target).
    """
    k = _kind(kind)
    y = _as_responses(responses)
    if target is not None and k != "nominal":
        raise OptimiseError(
            f"target = {target} is only used by kind='nominal'; drop it or use kind='nominal'"
        )
    if target is not None and not np.isfinite(target):
        raise OptimiseError(f"target = {target} must be a finite number")
    if k in ("nominal", "nominal-variance") and target is None and y.shape[1] < 2:
        raise OptimiseError(
            f"kind={kind!r} needs >= 2 replicates per run to estimate the variance, got one "
            "response per run; give a target (kind='nominal', target=...) to use "
            "-10 log10((y - target)^2), or replicate the runs"
        )
    with np.errstate(divide="ignore", invalid="ignore"):
        sn = _SN[k](y, target)
    bad = np.flatnonzero(~np.isfinite(sn))
    if bad.size:
        r = int(bad[0])
        raise OptimiseError(
            f"the {k} S/N of run {r} is {sn[r]} (responses {y[r].tolist()}): a zero response, "
            "zero variance or an exact hit on the target gives an infinite ratio; add a small "
            "floor to the response (e.g. the FE tolerance) or pick another kind"
        )
    return sn


# ---------------------------------------------------------------------------------------------
# Main effects, ANOVA
# ---------------------------------------------------------------------------------------------


def _factors(
    a: np.ndarray, factor_names: Sequence[str] | None, columns: Sequence[int] | None
) -> tuple[tuple[str, ...], tuple[int, ...]]:
    n_cols = a.shape[1]
    if columns is None:
        n = n_cols if factor_names is None else len(factor_names)
        if n > n_cols:
            raise OptimiseError(
                f"{n} factor names for an array of {n_cols} columns: name at most one factor "
                "per column"
            )
        columns = range(n)
    cols = tuple(int(c) for c in columns)
    for c in cols:
        if not 0 <= c < n_cols:
            raise OptimiseError(f"column {c} is outside the array (0..{n_cols - 1})")
    if len(set(cols)) != len(cols):
        raise OptimiseError(f"columns {list(cols)} repeat a column; one factor per column")
    names = _letters(len(cols)) if factor_names is None else tuple(str(n) for n in factor_names)
    if len(names) != len(cols):
        raise OptimiseError(f"{len(names)} factor names for {len(cols)} columns")
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise OptimiseError(f"factor name {dup!r} is given twice")
    if not cols:
        raise OptimiseError("no factor to analyse: give factor_names or columns")
    return names, cols


def _level_means(col: np.ndarray, v: np.ndarray, s: int) -> np.ndarray:
    """Mean of ``v`` (runs, r) over the runs at each level of ``col``."""
    return np.bincount(col, weights=v.mean(axis=1), minlength=s) / np.bincount(col, minlength=s)


@dataclass(frozen=True)
class MainEffect:
    """Level means of one factor (the data of a main-effects plot).

    Attributes
    ----------
    name : str
    column : int — its column in the array.
    sn : (n_levels,) float — mean S/N at each level, dB.
    response : (n_levels,) float — mean response at each level (over runs and replicates).
    """

    name: str
    column: int
    sn: np.ndarray
    response: np.ndarray

    @property
    def n_levels(self) -> int:
        return int(self.sn.size)

    @property
    def delta(self) -> float:
        """Range of the level means of S/N, dB (Taguchi's response-table "delta")."""
        return float(self.sn.max() - self.sn.min())

    @property
    def best_level(self) -> int:
        """Level with the largest mean S/N (the first one on ties)."""
        return int(np.argmax(self.sn))


def main_effects(
    array: np.ndarray,
    sn: np.ndarray | Sequence[float],
    responses: np.ndarray | Sequence[float] | None = None,
    factor_names: Sequence[str] | None = None,
    *,
    columns: Sequence[int] | None = None,
) -> tuple[MainEffect, ...]:
    """Mean S/N and mean response at every level of every factor.

    Parameters
    ----------
    array : (runs, n_columns) int — the design, levels 0..s-1.
    sn : (runs,) float — S/N of each run, dB.
    responses : (runs,) or (runs, replicates) float, optional — defaults to ``sn``.
    factor_names : sequence of str, optional — names of the factors in ``columns`` (or in the
        first ``len(factor_names)`` columns); default A, B, C, ... for every column.
    columns : sequence of int, optional — the column of each factor.
    """
    a = _as_design(array)
    s = _n_levels(a)
    names, cols = _factors(a, factor_names, columns)
    v = _as_responses(sn, a.shape[0])
    y = v if responses is None else _as_responses(responses, a.shape[0])
    return tuple(
        MainEffect(
            n, c, _frozen(_level_means(a[:, c], v, s[c])), _frozen(_level_means(a[:, c], y, s[c]))
        )
        for n, c in zip(names, cols, strict=True)
    )


def _frozen(x: np.ndarray) -> np.ndarray:
    x = np.array(x)
    x.setflags(write=False)
    return x


@dataclass(frozen=True)
class Pool:
    """The pooling rule: which factor sums of squares join the error.

    Factors are pooled from the smallest sum of squares upwards, so the pooled set is always the
    ``k`` smallest (plus any named ones):

    1. every factor in ``factors``;
    2. every factor whose contribution ``100 SS / SS_total`` is below ``below_percent``;
    3. then the smallest remaining, one at a time, until the error has ``min_error_dof`` dof.

    At least one factor always stays unpooled.  Taguchi's rule of thumb is to pool about half the
    factor degrees of freedom (``min_error_dof`` ~ half the runs); with a saturated array (no empty
    column, one response per run) the error has 0 dof and pooling is the only way to F and p.

    Attributes
    ----------
    below_percent : float — pool factors contributing less than this, % (0: none).
    min_error_dof : int — pool the smallest until the error has at least this many dof.
    factors : tuple of str — pool these whatever their size.
    """

    below_percent: float = 0.0
    min_error_dof: int = 0
    factors: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not 0.0 <= float(self.below_percent) < 100.0:
            raise OptimiseError(
                f"Pool.below_percent = {self.below_percent} must be in [0, 100), a percentage"
            )
        if int(self.min_error_dof) != self.min_error_dof or self.min_error_dof < 0:
            raise OptimiseError(
                f"Pool.min_error_dof = {self.min_error_dof} must be a non-negative integer"
            )
        object.__setattr__(self, "factors", tuple(str(f) for f in self.factors))


@dataclass(frozen=True)
class AnovaTable:
    """Analysis of variance, one row per source (factors, interactions, then error and total).

    Attributes
    ----------
    source : tuple of str — factor names, ``"A×B"`` interactions, ``"error"``, ``"total"``.
    ss : (n_rows,) float — sums of squares (pooled factors also appear inside ``error``).
    dof : (n_rows,) int — degrees of freedom.
    ms : (n_rows,) float — mean squares ``ss / dof`` (nan for 0 dof).
    f : (n_rows,) float — ``ms / ms_error`` for unpooled sources (nan if pooled or 0 error dof).
    p : (n_rows,) float — ``P(F(dof, dof_error) > f)`` (scipy.stats.f.sf).
    percent : (n_rows,) float — contribution ``100 ss / ss_total``.
    percent_pure : (n_rows,) float — Taguchi's pure contribution
        ``100 (ss - dof ms_error) / ss_total`` for unpooled sources, the remainder on the error
        row (nan with 0 error dof).
    pooled : (n_rows,) bool — the source was pooled into the error.
    analysed : str — ``"sn"`` or ``"response"``.
    notes : tuple of str — what to know before reading F and p.
    """

    source: tuple[str, ...]
    ss: np.ndarray
    dof: np.ndarray
    ms: np.ndarray
    f: np.ndarray
    p: np.ndarray
    percent: np.ndarray
    percent_pure: np.ndarray
    pooled: np.ndarray
    analysed: str = "sn"
    notes: tuple[str, ...] = ()

    def rows(self) -> list[dict[str, float | int | str | bool]]:
        """The table as a list of plain dicts (for reports and YAML/JSON)."""
        return [self.row(s) for s in self.source]

    def row(self, source: str) -> dict[str, float | int | str | bool]:
        """One row by source name."""
        if source not in self.source:
            raise OptimiseError(f"no ANOVA row {source!r}; rows are {list(self.source)}")
        i = self.source.index(source)
        return {
            "source": source,
            "ss": float(self.ss[i]),
            "dof": int(self.dof[i]),
            "ms": float(self.ms[i]),
            "f": float(self.f[i]),
            "p": float(self.p[i]),
            "percent": float(self.percent[i]),
            "percent_pure": float(self.percent_pure[i]),
            "pooled": bool(self.pooled[i]),
        }

    @property
    def error_dof(self) -> int:
        return int(self.dof[self.source.index("error")])

    @property
    def error_ms(self) -> float:
        return float(self.ms[self.source.index("error")])

    @property
    def significant(self) -> tuple[str, ...]:
        """Unpooled factor and interaction sources (the ones a prediction uses)."""
        return tuple(s for s, pl in zip(self.source[:-2], self.pooled[:-2], strict=True) if not pl)


def _interaction_name(a: str, b: str) -> str:
    return f"{a}×{b}"


def anova(
    array: np.ndarray,
    values: np.ndarray | Sequence[float],
    factor_names: Sequence[str] | None = None,
    *,
    columns: Sequence[int] | None = None,
    interactions: Sequence[tuple[str, str]] = (),
    pool: Pool | None = None,
    analysed: str = "sn",
) -> AnovaTable:
    """ANOVA of an orthogonal-array experiment, with optional pooling.

    ``SS_total = sum (y - ybar)^2`` over all runs and replicates; a factor at ``s`` levels has
    ``SS = r sum_l n_l (ybar_l - ybar)^2`` with ``n_l`` runs at level ``l`` and ``r`` replicates,
    and ``s - 1`` dof; an interaction ``A×B`` has ``SS = SS_AB-cells - SS_A - SS_B`` and
    ``(s_A - 1)(s_B - 1)`` dof.  The error is what is left: empty columns, the hidden dof of mixed
    arrays (2 in the L18) and replicates; then the pooled factors join it.

    Parameters
    ----------
    array : (runs, n_columns) int — the design, levels 0..s-1; the analysed columns must be
        orthogonal (strength 2), else the sums of squares would not add up.
    values : (runs,) or (runs, replicates) float — S/N (one per run) or raw responses.
    factor_names, columns — which columns are factors (see :func:`main_effects`).
    interactions : sequence of (str, str) — interactions to give rows; their columns must be empty
        (not hold a factor), see :func:`select_array`.
    pool : Pool, optional — the pooling rule; None pools nothing.
    analysed : str — label for the table, ``"sn"`` or ``"response"``.

    Returns
    -------
    AnovaTable
    """
    a = _as_design(array)
    s = _n_levels(a)
    names, cols = _factors(a, factor_names, columns)
    bad = non_orthogonal_pairs(a[:, list(cols)])
    if bad:
        i, j = bad[0]
        raise OptimiseError(
            f"columns {cols[i]} ({names[i]}) and {cols[j]} ({names[j]}) are not orthogonal: "
            "every level pair must occur equally often for the ANOVA sums of squares to add up; "
            "use an array from get_array/select_array with all its runs"
        )
    y = _as_responses(values, a.shape[0])
    n, r = y.shape
    grand = float(y.mean())
    ss_total = float(np.sum((y - grand) ** 2))
    dof_total = n * r - 1
    if ss_total <= 0.0:
        raise OptimiseError(
            "every run has the same value: there is no variation to analyse; check that the "
            "responses depend on the factors"
        )
    sources: list[str] = []
    ss: list[float] = []
    dof: list[int] = []
    for name, c in zip(names, cols, strict=True):
        counts = np.bincount(a[:, c], minlength=s[c])
        means = _level_means(a[:, c], y, s[c])
        sources.append(name)
        ss.append(float(r * np.sum(counts * (means - grand) ** 2)))
        dof.append(int(s[c]) - 1)
    for fa, fb in interactions:
        for x in (fa, fb):
            if x not in names:
                raise OptimiseError(f"interaction ({fa!r}, {fb!r}) names unknown factor {x!r}")
        ca, cb = cols[names.index(fa)], cols[names.index(fb)]
        table = interaction(a, y, fa, fb, factor_names=names, columns=cols)
        clash = [c for c in table.aliased_columns if c in cols]
        if clash:
            other = names[cols.index(clash[0])]
            raise OptimiseError(
                f"interaction {fa}×{fb} is aliased with factor '{other}' (column {clash[0]}): "
                "its SS would hold that factor's effect; reassign with "
                f"select_array(..., interactions=[({fa!r}, {fb!r})]) or drop the interaction"
            )
        sources.append(_interaction_name(fa, fb))
        ss.append(table.ss)
        dof.append((int(s[ca]) - 1) * (int(s[cb]) - 1))
    n_src = len(sources)
    ss_arr = np.array(ss)
    dof_arr = np.array(dof)
    ss_err = ss_total - float(ss_arr.sum())
    dof_err = dof_total - int(dof_arr.sum())
    tol = 1e-9 * ss_total
    if dof_err < 0 or ss_err < -tol:
        raise OptimiseError(
            f"the sources use {int(dof_arr.sum())} dof and SS {ss_arr.sum():.6g} of the "
            f"{dof_total} dof and SS {ss_total:.6g} available: an interaction shares its columns "
            "with a factor (aliased); reassign with select_array(..., interactions=...) or drop it"
        )
    ss_err = max(ss_err, 0.0)
    pooled = np.zeros(n_src, dtype=bool)
    notes: list[str] = []
    if pool is not None:
        for fname in pool.factors:
            if fname not in sources:
                raise OptimiseError(f"Pool.factors names {fname!r}, not a source {sources}")
            pooled[sources.index(fname)] = True
        percent = 100.0 * ss_arr / ss_total
        pooled |= percent < pool.below_percent
        order = [i for i in np.argsort(ss_arr, kind="stable")]
        e_dof = dof_err + int(dof_arr[pooled].sum())
        for i in order:
            if e_dof >= pool.min_error_dof:
                break
            if not pooled[i]:
                pooled[i] = True
                e_dof += int(dof_arr[i])
        if pooled.all():
            keep = int(np.argmax(ss_arr))
            pooled[keep] = False
            notes.append(
                f"the pooling rule would pool every source; '{sources[keep]}' (largest SS) is kept"
            )
        e_dof = dof_err + int(dof_arr[pooled].sum())
        if e_dof < pool.min_error_dof:
            raise OptimiseError(
                f"Pool.min_error_dof = {pool.min_error_dof} cannot be reached: pooling all but "
                f"the largest source leaves {e_dof} error dof; lower min_error_dof or use a "
                "larger array"
            )
    ss_e = ss_err + float(ss_arr[pooled].sum())
    dof_e = dof_err + int(dof_arr[pooled].sum())
    ms_e = ss_e / dof_e if dof_e > 0 else np.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        ms = np.where(dof_arr > 0, ss_arr / np.maximum(dof_arr, 1), np.nan)
        f = np.where(pooled | (dof_e == 0), np.nan, ms / ms_e)
    p = np.where(np.isnan(f), np.nan, stats.f.sf(np.nan_to_num(f, nan=0.0), dof_arr, max(dof_e, 1)))
    if dof_e == 0:
        notes.append(
            "the error has 0 degrees of freedom (saturated array: no empty column, no replicates): "
            "F and p need pooling, e.g. pool=Pool(min_error_dof=2) or Pool(below_percent=5)"
        )
    percent = 100.0 * ss_arr / ss_total
    if dof_e > 0:
        pure = np.where(pooled, np.nan, 100.0 * (ss_arr - dof_arr * ms_e) / ss_total)
        pure_err = 100.0 * (ss_e + int(dof_arr[~pooled].sum()) * ms_e) / ss_total
    else:
        pure = np.full(n_src, np.nan)
        pure_err = np.nan
    out = AnovaTable(
        source=tuple(sources) + ("error", "total"),
        ss=_frozen(np.append(ss_arr, [ss_e, ss_total])),
        dof=_frozen(np.append(dof_arr, [dof_e, dof_total]).astype(int)),
        ms=_frozen(np.append(ms, [ms_e, ss_total / dof_total])),
        f=_frozen(np.append(f, [np.nan, np.nan])),
        p=_frozen(np.append(p, [np.nan, np.nan])),
        percent=_frozen(np.append(percent, [100.0 * ss_e / ss_total, 100.0])),
        percent_pure=_frozen(np.append(pure, [pure_err, 100.0])),
        pooled=_frozen(np.append(pooled, [False, False])),
        analysed=analysed,
        notes=tuple(notes),
    )
    return out


# ---------------------------------------------------------------------------------------------
# Interactions and additivity
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Interaction:
    """Two-way table of means of a pair of factors and its interaction sum of squares.

    Attributes
    ----------
    a, b : str — the factor names.
    table : (n_levels_a, n_levels_b) float — mean value in each level cell.
    counts : (n_levels_a, n_levels_b) int — runs in each cell.
    ss : float — ``SS_cells - SS_a - SS_b``: the part of the cell-mean variation the two main
        effects do not explain.
    dof : int — ``(s_a - 1)(s_b - 1)``.
    percent : float — ``100 ss / SS_total``.
    aliased_columns : tuple of int — other columns not balanced within the cells: their effects are
        inside ``ss`` (in a Rao-Hamming array the interaction columns of the pair).
    """

    a: str
    b: str
    table: np.ndarray
    counts: np.ndarray
    ss: float
    dof: int
    percent: float
    aliased_columns: tuple[int, ...]


def interaction(
    array: np.ndarray,
    values: np.ndarray | Sequence[float],
    a: str,
    b: str,
    factor_names: Sequence[str] | None = None,
    *,
    columns: Sequence[int] | None = None,
) -> Interaction:
    """The two-way table of two factors and the interaction sum of squares it shows.

    In a fractional array the interaction is confounded with the columns the pair determines
    (:attr:`Interaction.aliased_columns`; in L8 the A×B of columns 1 and 2 *is* column 3).  The SS
    is the interaction's only when those columns hold no factor; otherwise it also holds that
    factor's effect.

    Parameters
    ----------
    array : (runs, n_columns) int — the whole array (for the aliasing check), levels 0..s-1.
    values : (runs,) or (runs, replicates) float — S/N or responses.
    a, b : str — factor names.
    factor_names, columns — which columns are factors (see :func:`main_effects`).
    """
    arr = _as_design(array)
    s = _n_levels(arr)
    names, cols = _factors(arr, factor_names, columns)
    for x in (a, b):
        if x not in names:
            raise OptimiseError(f"factor {x!r} is not one of {list(names)}")
    if a == b:
        raise OptimiseError(f"an interaction needs two different factors, got {a!r} twice")
    y = _as_responses(values, arr.shape[0])
    n, r = y.shape
    ca, cb = cols[names.index(a)], cols[names.index(b)]
    sa, sb = int(s[ca]), int(s[cb])
    cell = arr[:, ca] * sb + arr[:, cb]
    counts = np.bincount(cell, minlength=sa * sb)
    if np.any(counts != counts[0]):
        raise OptimiseError(
            f"factors '{a}' and '{b}' do not show every level pair equally often (cell counts "
            f"{counts.tolist()}): the two-way table needs an orthogonal pair of columns"
        )
    sums = np.bincount(cell, weights=y.mean(axis=1), minlength=sa * sb)
    table = (sums / counts).reshape(sa, sb)
    grand = float(y.mean())
    ss_total = float(np.sum((y - grand) ** 2))
    ss_cells = r * float(np.sum(counts * (table.ravel() - grand) ** 2))
    ss_a = r * float(
        np.sum(np.bincount(arr[:, ca]) * (_level_means(arr[:, ca], y, sa) - grand) ** 2)
    )
    ss_b = r * float(
        np.sum(np.bincount(arr[:, cb]) * (_level_means(arr[:, cb], y, sb) - grand) ** 2)
    )
    ss = max(ss_cells - ss_a - ss_b, 0.0)
    aliased = []
    for c in range(arr.shape[1]):
        if c in (ca, cb):
            continue
        joint = np.bincount(cell * s[c] + arr[:, c], minlength=sa * sb * int(s[c]))
        joint = joint.reshape(sa * sb, int(s[c]))
        if np.any(joint != joint[:, :1]):
            aliased.append(c)
    return Interaction(
        a,
        b,
        _frozen(table),
        _frozen(counts.reshape(sa, sb)),
        ss,
        (sa - 1) * (sb - 1),
        100.0 * ss / ss_total if ss_total > 0 else np.nan,
        tuple(aliased),
    )


@dataclass(frozen=True)
class AdditivityCheck:
    """How far the values are from the additive (main-effects-only) model.

    Attributes
    ----------
    fitted : (runs,) float — ``mean + sum_f (level mean_f - mean)`` at each run.
    residuals : (runs,) float — value minus fitted (run means when replicated).
    ss_residual : float — sum of squared residuals times replicates: the SS left unexplained by
        the main effects (interactions, empty columns, replicate noise).
    dof_residual : int — its degrees of freedom (0 for a saturated array: then no interaction
        can show here, only in ``extra_*``).
    ss_total : float
    unexplained_percent : float — ``100 ss_residual / ss_total``.
    pairs : tuple of Interaction — every pair of factors, largest interaction SS first.
    extra_predicted, extra_measured, extra_residuals : (m,) float — additive prediction, measured
        value and measured minus predicted at extra level combinations (e.g. confirmation runs).
    notes : tuple of str
    """

    fitted: np.ndarray
    residuals: np.ndarray
    ss_residual: float
    dof_residual: int
    ss_total: float
    unexplained_percent: float
    pairs: tuple[Interaction, ...]
    extra_predicted: np.ndarray
    extra_measured: np.ndarray
    extra_residuals: np.ndarray
    notes: tuple[str, ...] = ()


def additivity_check(
    array: np.ndarray,
    values: np.ndarray | Sequence[float],
    factor_names: Sequence[str] | None = None,
    *,
    columns: Sequence[int] | None = None,
    extra_levels: np.ndarray | Sequence[Sequence[int]] | None = None,
    extra_values: np.ndarray | Sequence[float] | None = None,
) -> AdditivityCheck:
    """Quantify non-additivity: residuals of the main-effects model and the pair interactions.

    Taguchi's prediction assumes the factor effects add up.  When they do not (the SEA-spring
    screening of paper 004 predicted 29.6 dB and measured 22.2 dB), this shows where: the residual
    SS over the array runs, the two-way interaction SS of every pair and, at level combinations not
    in the array, the gap between the additive prediction and the measured value.

    Parameters
    ----------
    array : (runs, n_columns) int — the design, levels 0..s-1.
    values : (runs,) or (runs, replicates) float — S/N or responses.
    factor_names, columns — which columns are factors (see :func:`main_effects`).
    extra_levels : (m, n_factors) int, optional — level of each factor in extra runs.
    extra_values : (m,) float, optional — the value measured in each extra run.

    Returns
    -------
    AdditivityCheck
    """
    a = _as_design(array)
    s = _n_levels(a)
    names, cols = _factors(a, factor_names, columns)
    y = _as_responses(values, a.shape[0])
    n, r = y.shape
    grand = float(y.mean())
    means = [_level_means(a[:, c], y, s[c]) for c in cols]
    fitted = grand + sum(m[a[:, c]] - grand for m, c in zip(means, cols, strict=True))
    resid = y.mean(axis=1) - fitted
    ss_total = float(np.sum((y - grand) ** 2))
    ss_res = float(r * np.sum(resid**2) + np.sum((y - y.mean(axis=1, keepdims=True)) ** 2))
    dof_res = n * r - 1 - sum(int(s[c]) - 1 for c in cols)
    notes = []
    if dof_res == 0:
        notes.append(
            "the main effects use every degree of freedom (saturated array, one value per run): "
            "the residuals are zero by construction and interactions are aliased with the factor "
            "columns; check additivity with extra runs (extra_levels, extra_values) instead"
        )
    pairs = tuple(
        sorted(
            (
                interaction(a, y, fa, fb, factor_names=names, columns=cols)
                for fa, fb in combinations(names, 2)
            ),
            key=lambda it: -it.ss,
        )
    )
    if (extra_levels is None) != (extra_values is None):
        raise OptimiseError("give both extra_levels and extra_values, or neither")
    if extra_levels is not None:
        lv = np.atleast_2d(np.asarray(extra_levels, dtype=int))
        mv = np.asarray(extra_values, dtype=float).ravel()
        if lv.shape != (mv.size, len(cols)):
            raise OptimiseError(
                f"extra_levels has shape {lv.shape}; expected ({mv.size}, {len(cols)}): one row of "
                "factor levels per extra value"
            )
        pred = np.array([_additive(grand, means, row) for row in lv])
    else:
        mv = np.zeros(0)
        pred = np.zeros(0)
    return AdditivityCheck(
        fitted=_frozen(fitted),
        residuals=_frozen(resid),
        ss_residual=ss_res,
        dof_residual=dof_res,
        ss_total=ss_total,
        unexplained_percent=100.0 * ss_res / ss_total if ss_total > 0 else np.nan,
        pairs=pairs,
        extra_predicted=_frozen(pred),
        extra_measured=_frozen(mv),
        extra_residuals=_frozen(mv - pred),
        notes=tuple(notes),
    )


def _additive(grand: float, means: Sequence[np.ndarray], levels: Sequence[int]) -> float:
    out = grand
    for m, lv in zip(means, levels, strict=True):
        if not 0 <= lv < m.size:
            raise OptimiseError(f"level {lv} is outside 0..{m.size - 1}")
        out += float(m[lv]) - grand
    return out


# ---------------------------------------------------------------------------------------------
# The whole analysis
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TaguchiResult:
    """Result of :func:`analyse`.

    Attributes
    ----------
    array : (runs, n_columns) int — the design as given, levels 0..s-1.
    responses : (runs, replicates) float — as given.
    kind : str — canonical S/N kind (``smaller``, ``larger``, ``nominal``, ``nominal-variance``).
    target : float or None — the nominal target, if any.
    sn : (runs,) float — S/N of every run, dB.
    factor_names : tuple of str
    columns : tuple of int — column of each factor.
    main_effects : tuple of MainEffect — one per factor.
    anova : AnovaTable
    interactions : tuple of (str, str) — interactions with ANOVA rows.
    best_levels : tuple of int — best level of each factor (max predicted S/N), 0-based.
    predicted_sn : float — predicted S/N at ``best_levels`` from the significant sources, dB.
    predicted_response : float — additive prediction of the mean response at ``best_levels``
        from the same factors.
    mean_sn : float — mean S/N over the runs, dB.
    notes : tuple of str
    """

    array: np.ndarray
    responses: np.ndarray
    kind: str
    target: float | None
    sn: np.ndarray
    factor_names: tuple[str, ...]
    columns: tuple[int, ...]
    main_effects: tuple[MainEffect, ...]
    anova: AnovaTable
    interactions: tuple[tuple[str, str], ...]
    best_levels: tuple[int, ...]
    predicted_sn: float
    predicted_response: float
    mean_sn: float
    notes: tuple[str, ...] = ()

    @property
    def significant(self) -> tuple[str, ...]:
        """Sources the prediction uses: the unpooled factors and interactions."""
        return self.anova.significant

    @property
    def best_levels_by_name(self) -> dict[str, int]:
        return dict(zip(self.factor_names, self.best_levels, strict=True))

    def effect(self, name: str) -> MainEffect:
        """The main effect of factor ``name``."""
        for e in self.main_effects:
            if e.name == name:
                return e
        raise OptimiseError(f"no factor {name!r}; factors are {list(self.factor_names)}")

    def predict(
        self,
        levels: Sequence[int] | Mapping[str, int] | None = None,
        sources: Sequence[str] | None = None,
        on: str = "sn",
    ) -> float:
        """Shortcut for :func:`predict` on this result."""
        return predict(self, levels, sources, on=on)

    def interaction(self, a: str, b: str, on: str = "sn") -> Interaction:
        """Two-way table and interaction SS of factors ``a`` and ``b`` (on S/N or response)."""
        v = self.sn if on == "sn" else self.responses
        return interaction(self.array, v, a, b, self.factor_names, columns=self.columns)

    def additivity(
        self,
        extra_levels: np.ndarray | Sequence[Sequence[int]] | None = None,
        extra_sn: np.ndarray | Sequence[float] | None = None,
    ) -> AdditivityCheck:
        """:func:`additivity_check` of the S/N, optionally against measured extra runs."""
        return additivity_check(
            self.array,
            self.sn,
            self.factor_names,
            columns=self.columns,
            extra_levels=extra_levels,
            extra_values=extra_sn,
        )


def _levels_vector(
    result: TaguchiResult, levels: Sequence[int] | Mapping[str, int] | None
) -> tuple[int, ...]:
    if levels is None:
        return result.best_levels
    if isinstance(levels, Mapping):
        unknown = set(levels) - set(result.factor_names)
        if unknown:
            raise OptimiseError(
                f"levels name unknown factors {sorted(unknown)}; factors are "
                f"{list(result.factor_names)}"
            )
        missing = [n for n in result.factor_names if n not in levels]
        if missing:
            raise OptimiseError(f"levels miss factors {missing}: give a level for every factor")
        vec = tuple(int(levels[n]) for n in result.factor_names)
    else:
        vec = tuple(int(v) for v in levels)
        if len(vec) != len(result.factor_names):
            raise OptimiseError(
                f"{len(vec)} levels for {len(result.factor_names)} factors "
                f"{list(result.factor_names)}"
            )
    for name, e, lv in zip(result.factor_names, result.main_effects, vec, strict=True):
        if not 0 <= lv < e.n_levels:
            raise OptimiseError(
                f"level {lv} of factor '{name}' is outside 0..{e.n_levels - 1} (levels are 0-based)"
            )
    return vec


def _predict_raw(
    names: Sequence[str],
    sn_means: Sequence[np.ndarray],
    tables: Mapping[str, tuple[int, int, np.ndarray]],
    grand: float,
    levels: Sequence[int],
    sources: Sequence[str],
) -> float:
    out = grand
    for src in sources:
        if src in tables:
            ia, ib, tab = tables[src]
            ma, mb = sn_means[ia], sn_means[ib]
            out += float(tab[levels[ia], levels[ib]] - ma[levels[ia]] - mb[levels[ib]] + grand)
        else:
            i = list(names).index(src)
            out += float(sn_means[i][levels[i]]) - grand
    return out


def predict(
    result: TaguchiResult,
    levels: Sequence[int] | Mapping[str, int] | None = None,
    sources: Sequence[str] | None = None,
    *,
    on: str = "sn",
) -> float:
    """Additive prediction ``mean + sum (level mean - mean)`` at a level combination.

    Parameters
    ----------
    result : TaguchiResult
    levels : sequence of int or mapping name -> level, optional — 0-based; default the best levels.
    sources : sequence of str, optional — factors (and ``"A×B"`` interactions with an ANOVA row)
        to include; default the significant (unpooled) ones.  An interaction adds
        ``cell mean - level mean_A - level mean_B + mean``.
    on : str — ``"sn"`` (dB) or ``"response"`` (mean response; interactions are not used).

    Returns
    -------
    float
    """
    if on not in ("sn", "response"):
        raise OptimiseError(f"on = {on!r}: predict on 'sn' or 'response'")
    lv = _levels_vector(result, levels)
    srcs = tuple(result.significant if sources is None else sources)
    valid = set(result.factor_names) | {_interaction_name(a, b) for a, b in result.interactions}
    for src in srcs:
        if src not in valid:
            raise OptimiseError(
                f"source {src!r} is not a factor or analysed interaction: {sorted(valid)}"
            )
    if on == "response":
        grand = float(result.responses.mean())
        means = [e.response for e in result.main_effects]
        srcs = tuple(x for x in srcs if x in result.factor_names)
        return _predict_raw(result.factor_names, means, {}, grand, lv, srcs)
    return _predict_raw(
        result.factor_names,
        [e.sn for e in result.main_effects],
        _interaction_tables(result),
        result.mean_sn,
        lv,
        srcs,
    )


def _interaction_tables(result: TaguchiResult) -> dict[str, tuple[int, int, np.ndarray]]:
    out = {}
    for a, b in result.interactions:
        it = interaction(result.array, result.sn, a, b, result.factor_names, columns=result.columns)
        out[_interaction_name(a, b)] = (
            result.factor_names.index(a),
            result.factor_names.index(b),
            it.table,
        )
    return out


def analyse(
    array: np.ndarray,
    responses: np.ndarray | Sequence[float],
    kind: str = "smaller",
    factor_names: Sequence[str] | None = None,
    pool: Pool | None = None,
    *,
    columns: Sequence[int] | None = None,
    target: float | None = None,
    interactions: Sequence[tuple[str, str]] = (),
    anova_on: str = "sn",
) -> TaguchiResult:
    """Taguchi analysis of an orthogonal-array experiment.

    S/N of every run (:func:`sn_ratio`), main effects, ANOVA with pooling, best levels (max mean
    S/N per factor; jointly over factors tied by a significant interaction) and the predicted S/N
    ``mean + sum over significant sources (level mean - mean)``.

    Parameters
    ----------
    array : (runs, n_columns) int — the design, levels 0..s-1 (e.g. :func:`get_array` or
        :attr:`Layout.array`).
    responses : (runs,) or (runs, replicates) float — one row per run.
    kind : str — S/N kind: ``"smaller"``, ``"larger"``, ``"nominal"``, ``"nominal_variance"``.
    factor_names : sequence of str, optional — names of the factors in ``columns`` (or in the
        first ``len(factor_names)`` columns; the rest are empty and feed the error).  Default
        A, B, C, ... for every column.
    pool : Pool, optional — pooling rule for the ANOVA; None pools nothing (and a saturated array
        then has no F or p, see the notes).
    columns : sequence of int, optional — the column of each factor (``Layout.columns``).
    target : float, optional — nominal value for ``kind="nominal"``.
    interactions : sequence of (str, str) — interactions to give ANOVA rows (their columns must
        be empty).
    anova_on : str — ``"sn"`` (one value per run) or ``"response"`` (all replicates; the
        replicate scatter is then error).

    Returns
    -------
    TaguchiResult
    """
    a = _as_design(array)
    _n_levels(a)
    y = _as_responses(responses, a.shape[0])
    k = _kind(kind)
    names, cols = _factors(a, factor_names, columns)
    if anova_on not in ("sn", "response"):
        raise OptimiseError(f"anova_on = {anova_on!r}: analyse variance of 'sn' or 'response'")
    sn = sn_ratio(y, k, target)
    effects = main_effects(a, sn, y, names, columns=cols)
    pairs = tuple((str(x), str(z)) for x, z in interactions)
    table = anova(
        a,
        sn if anova_on == "sn" else y,
        names,
        columns=cols,
        interactions=pairs,
        pool=pool,
        analysed=anova_on,
    )
    mean_sn = float(sn.mean())
    stub = TaguchiResult(
        array=_frozen(a),
        responses=_frozen(y),
        kind=k,
        target=None if target is None else float(target),
        sn=_frozen(sn),
        factor_names=names,
        columns=cols,
        main_effects=effects,
        anova=table,
        interactions=pairs,
        best_levels=tuple(e.best_level for e in effects),
        predicted_sn=np.nan,
        predicted_response=np.nan,
        mean_sn=mean_sn,
        notes=table.notes,
    )
    best = _best_levels(stub)
    stub = replace(stub, best_levels=best)
    return replace(
        stub,
        predicted_sn=predict(stub, best),
        predicted_response=predict(stub, best, on="response"),
    )


def _best_levels(result: TaguchiResult) -> tuple[int, ...]:
    """Per-factor argmax of S/N, except jointly over the factors of significant interactions."""
    best = list(e.best_level for e in result.main_effects)
    inter = [
        (a, b) for a, b in result.interactions if _interaction_name(a, b) in result.significant
    ]
    if not inter:
        return tuple(best)
    tied = sorted({result.factor_names.index(x) for ab in inter for x in ab})
    n_combos = math.prod(result.main_effects[i].n_levels for i in tied)
    if n_combos > 200_000:  # > 7 five-level factors tied together: keep the per-factor argmax
        return tuple(best)
    tables = _interaction_tables(result)
    sn_means = [e.sn for e in result.main_effects]
    top, top_val = tuple(best), -np.inf
    for combo in product(*(range(result.main_effects[i].n_levels) for i in tied)):
        trial = list(best)
        for i, lv in zip(tied, combo, strict=True):
            trial[i] = lv
        val = _predict_raw(
            result.factor_names, sn_means, tables, result.mean_sn, trial, result.significant
        )
        if val > top_val + 1e-12:  # first of (numerically) tied maxima
            top, top_val = tuple(trial), val
    return top


@dataclass(frozen=True)
class Confirmation:
    """Predicted against measured S/N of a confirmation run.

    Attributes
    ----------
    levels : tuple of int — the confirmed level combination (0-based).
    predicted_sn, measured_sn : float — dB.
    difference : float — measured minus predicted, dB.
    half_width : float — half-width of the confidence interval of the confirmation,
        ``sqrt(F(1 - alpha; 1, dof_e) V_e (1/n_eff + 1/n_confirm))`` with
        ``n_eff = runs / (1 + sum of the dof of the sources used)``, dB; nan when the S/N ANOVA
        has no error dof or the ANOVA was on the response.
    alpha : float
    """

    levels: tuple[int, ...]
    predicted_sn: float
    measured_sn: float
    difference: float
    half_width: float
    alpha: float

    @property
    def within(self) -> bool:
        """True when the measured S/N lies inside the confidence interval of the prediction."""
        return bool(np.isfinite(self.half_width) and abs(self.difference) <= self.half_width)


def confirm(
    result: TaguchiResult,
    measured_sn: float | None = None,
    levels: Sequence[int] | Mapping[str, int] | None = None,
    *,
    responses: np.ndarray | Sequence[float] | None = None,
    alpha: float = 0.05,
    n_confirm: int = 1,
) -> Confirmation:
    """Compare the predicted S/N with a confirmation run.

    Parameters
    ----------
    result : TaguchiResult
    measured_sn : float, optional — S/N of the confirmation run, dB.
    levels : sequence of int or mapping, optional — its level combination; default the best levels.
    responses : (replicates,) float, optional — the confirmation responses instead of
        ``measured_sn`` (converted with the result's kind and target).
    alpha : float — 1 - confidence level of the interval.
    n_confirm : int — number of confirmation runs averaged into ``measured_sn``.

    Returns
    -------
    Confirmation
    """
    if (measured_sn is None) == (responses is None):
        raise OptimiseError("give the confirmation's measured_sn or its responses (one of them)")
    if not 0.0 < alpha < 1.0:
        raise OptimiseError(f"alpha = {alpha} must be in (0, 1), e.g. 0.05 for 95 % confidence")
    if n_confirm < 1:
        raise OptimiseError(f"n_confirm = {n_confirm} must be >= 1")
    if responses is not None:
        measured = float(
            sn_ratio(np.atleast_2d(np.asarray(responses, float)), result.kind, result.target)[0]
        )
    else:
        measured = float(measured_sn)
        if not np.isfinite(measured):
            raise OptimiseError(f"measured_sn = {measured_sn} must be a finite number of dB")
    lv = _levels_vector(result, levels)
    pred = predict(result, lv)
    tab = result.anova
    half = np.nan
    if tab.analysed == "sn" and tab.error_dof > 0:
        used = sum(int(tab.dof[tab.source.index(s)]) for s in result.significant)
        n_eff = result.sn.size / (1 + used)
        fq = float(stats.f.ppf(1.0 - alpha, 1, tab.error_dof))
        half = math.sqrt(fq * tab.error_ms * (1.0 / n_eff + 1.0 / n_confirm))
    return Confirmation(lv, pred, measured, measured - pred, half, alpha)
