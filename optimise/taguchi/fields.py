"""Finite fields GF(q) as addition and multiplication tables (the orthogonal arrays' arithmetic)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache

import numpy as np
from flexopt.optimise.errors import OptimiseError

__all__ = [
    "galois_field",
    "GaloisField",
    "prime_power",
]

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


def prime_power(q: int) -> tuple[int, int] | None:
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
    pm = prime_power(int(q))
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
