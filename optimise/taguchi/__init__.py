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

The parts, by concern (every public name is importable from this package as before):

* :mod:`~optimise.taguchi.fields` — the finite fields GF(q);
* :mod:`~optimise.taguchi.arrays` — the constructions, the catalogue, orthogonality and the
  interaction columns of Rao-Hamming arrays;
* :mod:`~optimise.taguchi.screening` — choosing the array of a screening and assigning factors;
* :mod:`~optimise.taguchi.sn` — signal-to-noise ratios;
* :mod:`~optimise.taguchi.effects` — main effects, two-way interactions, the additivity check;
* :mod:`~optimise.taguchi.anova` — the ANOVA and its pooling rule;
* :mod:`~optimise.taguchi.prediction` — the whole analysis, the prediction and the confirmation.
"""

from __future__ import annotations

from flexopt.optimise.taguchi.anova import AnovaTable, Pool, anova
from flexopt.optimise.taguchi.arrays import (
    ArraySpec,
    addelman_kempthorne_array,
    array_spec,
    get_array,
    interaction_columns,
    is_orthogonal,
    list_arrays,
    non_orthogonal_pairs,
    orthogonal_array,
    paley_array,
    rao_hamming_array,
    rao_hamming_generators,
)
from flexopt.optimise.taguchi.effects import (
    AdditivityCheck,
    Interaction,
    MainEffect,
    additivity_check,
    interaction,
    main_effects,
)
from flexopt.optimise.taguchi.fields import GaloisField, galois_field
from flexopt.optimise.taguchi.prediction import (
    Confirmation,
    TaguchiResult,
    analyse,
    confirm,
    predict,
)
from flexopt.optimise.taguchi.screening import Layout, select_array
from flexopt.optimise.taguchi.sn import sn_ratio

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
