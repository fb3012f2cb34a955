"""Taguchi screening: built arrays are the textbook ones and orthogonal; the analysis is exact.

Each synthetic response below is built from known effects, so the expected main effects, sums of
squares, percent contributions and predictions are computed here from those effects, not copied.
"""

from itertools import product

import numpy as np
import pytest
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.taguchi import (
    Pool,
    additivity_check,
    analyse,
    anova,
    array_spec,
    confirm,
    galois_field,
    get_array,
    interaction,
    interaction_columns,
    is_orthogonal,
    list_arrays,
    main_effects,
    non_orthogonal_pairs,
    orthogonal_array,
    paley_array,
    rao_hamming_array,
    select_array,
    sn_ratio,
)
from scipy import stats


def table(text: str) -> np.ndarray:
    """A Taguchi table as printed (levels 1..s) -> 0-based levels."""
    return np.array([[int(v) for v in line.split()] for line in text.strip().splitlines()]) - 1


# Printed in every Taguchi handbook (e.g. Roy, *A Primer on the Taguchi Method*, appendix).
L8_BOOK = table(
    """
    1 1 1 1 1 1 1
    1 1 1 2 2 2 2
    1 2 2 1 1 2 2
    1 2 2 2 2 1 1
    2 1 2 1 2 1 2
    2 1 2 2 1 2 1
    2 2 1 1 2 2 1
    2 2 1 2 1 1 2
    """
)
L9_BOOK = table(
    """
    1 1 1 1
    1 2 2 2
    1 3 3 3
    2 1 2 3
    2 2 3 1
    2 3 1 2
    3 1 3 2
    3 2 1 3
    3 3 2 1
    """
)
L16_4_BOOK = table(
    """
    1 1 1 1 1
    1 2 2 2 2
    1 3 3 3 3
    1 4 4 4 4
    2 1 2 3 4
    2 2 1 4 3
    2 3 4 1 2
    2 4 3 2 1
    3 1 3 4 2
    3 2 4 3 1
    3 3 1 2 4
    3 4 2 1 3
    4 1 4 2 3
    4 2 3 1 4
    4 3 2 4 1
    4 4 1 3 2
    """
)
L18_BOOK = table(
    """
    1 1 1 1 1 1 1 1
    1 1 2 2 2 2 2 2
    1 1 3 3 3 3 3 3
    1 2 1 1 2 2 3 3
    1 2 2 2 3 3 1 1
    1 2 3 3 1 1 2 2
    1 3 1 2 1 3 2 3
    1 3 2 3 2 1 3 1
    1 3 3 1 3 2 1 2
    2 1 1 3 3 2 2 1
    2 1 2 1 1 3 3 2
    2 1 3 2 2 1 1 3
    2 2 1 2 3 1 3 2
    2 2 2 3 1 2 1 3
    2 2 3 1 2 3 2 1
    2 3 1 3 2 3 1 2
    2 3 2 1 3 1 2 3
    2 3 3 2 1 2 3 1
    """
)

SHAPES = {
    "L4": (4, 3, {2}),
    "L8": (8, 7, {2}),
    "L9": (9, 4, {3}),
    "L12": (12, 11, {2}),
    "L16": (16, 15, {2}),
    "L16(4^5)": (16, 5, {4}),
    "L18": (18, 8, {2, 3}),
    "L25": (25, 6, {5}),
    "L27": (27, 13, {3}),
}


# --- arrays --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list_arrays())
def test_every_catalogued_array_has_strength_two_and_its_advertised_shape(name):
    a = get_array(name)
    spec = array_spec(name)
    assert a.shape == (spec.runs, spec.n_columns)
    assert a.dtype.kind == "i"
    assert tuple(int(v) for v in a.max(axis=0) + 1) == spec.levels
    assert a.min() == 0
    assert is_orthogonal(a), non_orthogonal_pairs(a)


@pytest.mark.parametrize("name", SHAPES)
def test_the_required_arrays(name):
    runs, cols, levels = SHAPES[name]
    a = get_array(name)
    assert a.shape == (runs, cols)
    assert set((a.max(axis=0) + 1).tolist()) == levels
    assert is_orthogonal(a)


def test_built_arrays_are_the_printed_taguchi_tables():
    assert np.array_equal(get_array("L8"), L8_BOOK)
    assert np.array_equal(get_array("L9"), L9_BOOK)
    assert np.array_equal(get_array("L16(4^5)"), L16_4_BOOK)
    assert np.array_equal(get_array("L18"), L18_BOOK)


def test_l25_is_the_linear_forms_over_gf5():
    a = get_array("L25")
    u1, u2 = np.divmod(np.arange(25), 5)
    expected = np.stack([u1, u2] + [(t * u1 + u2) % 5 for t in range(1, 5)], axis=1)
    assert np.array_equal(a, expected)


def test_l18_first_two_columns_form_a_six_level_factor_orthogonal_to_the_rest():
    a = get_array("L18")
    six = a[:, 0] * 3 + a[:, 1]
    assert is_orthogonal(np.column_stack([six, a[:, 2:]]))


def test_l50_is_two_by_five_to_the_eleven():
    a = get_array("L50(2^1 5^11)")
    assert a.shape == (50, 12)
    assert (a.max(axis=0) + 1).tolist() == [2] + [5] * 11


def test_names_and_run_counts_pick_the_same_arrays():
    assert np.array_equal(get_array("L16"), rao_hamming_array(2, 4))
    assert np.array_equal(get_array("l16 (4**5)"), orthogonal_array(16, 4))
    assert np.array_equal(get_array("L18(2x3^7)"), orthogonal_array(18, (2, 3)))
    assert np.array_equal(orthogonal_array("L27"), rao_hamming_array(3, 3))
    assert np.array_equal(get_array("L12"), paley_array(11))
    with pytest.raises(OptimiseError, match="L16"):
        get_array("L16(3^5)")
    with pytest.raises(OptimiseError, match="known"):
        get_array("L7")
    with pytest.raises(OptimiseError, match="not of the form"):
        get_array("orthogonal")


def test_returned_arrays_are_copies():
    a = get_array("L9")
    a[0, 0] = 2
    assert get_array("L9")[0, 0] == 0


@pytest.mark.parametrize("q", [2, 3, 4, 5, 7, 8, 9])
def test_field_tables_satisfy_the_field_axioms(q):
    gf = galois_field(q)
    e = np.arange(q)
    add, mul = gf.add, gf.mul
    assert np.array_equal(add[0], e) and np.array_equal(mul[1], e)
    assert np.array_equal(add, add.T) and np.array_equal(mul, mul.T)
    for a, b, c in product(range(q), repeat=3):
        assert mul[a, add[b, c]] == add[mul[a, b], mul[a, c]]
        assert mul[a, mul[b, c]] == mul[mul[a, b], c]
        assert add[a, add[b, c]] == add[add[a, b], c]
    assert all(mul[a, gf.inv[a]] == 1 for a in range(1, q))
    assert all(add[a, gf.neg[a]] == 0 for a in range(q))


def test_gf4_is_zero_one_alpha_alpha_squared():
    gf = galois_field(4)
    alpha, alpha2 = 2, 3
    assert gf.mul[alpha, alpha] == alpha2  # alpha^2 = alpha + 1
    assert gf.add[alpha, 1] == alpha2
    assert gf.mul[alpha, alpha2] == 1  # alpha^3 = 1
    assert gf.add[alpha, alpha] == 0  # characteristic 2
    with pytest.raises(OptimiseError, match="prime power"):
        galois_field(6)


def test_is_orthogonal_finds_a_broken_pair():
    a = get_array("L9")
    a[0, 3] = 1
    assert not is_orthogonal(a)
    assert (0, 3) in non_orthogonal_pairs(a)


def test_interaction_columns_are_the_textbook_interaction_table():
    # 1-based textbook: L8 1x2 -> 3, 1x4 -> 5, 2x4 -> 6; L27 1x2 -> 3,4; 1x5 -> 6,7; 2x5 -> 8,11
    assert interaction_columns("L8", 0, 1) == (2,)
    assert interaction_columns("L8", 0, 3) == (4,)
    assert interaction_columns("L8", 1, 3) == (5,)
    assert interaction_columns("L27", 0, 1) == (2, 3)
    assert interaction_columns("L27", 0, 4) == (5, 6)
    assert interaction_columns("L27", 1, 4) == (7, 10)
    assert interaction_columns("L16(4^5)", 0, 1) == (2, 3, 4)
    with pytest.raises(OptimiseError, match="Rao-Hamming"):
        interaction_columns("L18", 0, 1)


def test_interaction_columns_hold_the_product_contrast():
    # In L8 the A x B contrast (+1 when A == B) is exactly column 3 read as +-1.
    a = get_array("L8")
    c = interaction_columns("L8", 0, 1)[0]
    assert np.array_equal(a[:, 0] ^ a[:, 1], a[:, c])


# --- choosing an array ---------------------------------------------------------------------------


def test_select_array_takes_the_smallest_and_the_resolution_iv_columns():
    lay = select_array([2, 2, 2, 2])
    assert lay.array_name == "L8(2^7)"
    assert lay.columns == (0, 1, 3, 6)  # textbook 1, 2, 4, 7
    assert lay.design.shape == (8, 4)
    assert lay.n_error_dof == 3
    assert select_array({"RP": 5, "RR": 5, "ST": 5, "A": 5, "RT": 5, "D": 5}).array_name == (
        "L25(5^6)"
    )
    assert select_array([2, 3, 3, 3]).array_name == "L18(2^1 3^7)"
    assert select_array([3] * 4).array_name == "L9(3^4)"
    # seven two-level factors fill L8; asking for one error dof moves to L12
    assert select_array([2] * 7, min_error_dof=1).array_name == "L12(2^11)"


def test_select_array_keeps_requested_interaction_columns_empty():
    lay = select_array([3, 3, 3], interactions=[("A", "B")])
    assert lay.array_name == "L27(3^13)"  # 6 + 4 dof do not fit the 8 of L9
    (a, b, cols) = lay.interactions[0]
    assert (a, b) == ("A", "B")
    assert cols == interaction_columns("L27", lay.columns[0], lay.columns[1])
    assert not set(cols) & set(lay.columns)
    lay = select_array([2] * 5, interactions=[("A", "B"), ("A", "C"), ("B", "C")])
    used = [c for *_, cs in lay.interactions for c in cs]
    assert len(set(used)) == 3 and not set(used) & set(lay.columns)


def test_select_array_says_when_nothing_fits():
    with pytest.raises(OptimiseError, match="no catalogued array"):
        select_array([2] * 70)
    with pytest.raises(OptimiseError, match="unknown factor"):
        select_array([2, 2], interactions=[("A", "Z")])


# --- S/N ratios ----------------------------------------------------------------------------------


def test_sn_formulas_by_hand():
    y = [[1.0, 2.0, 3.0]]
    assert sn_ratio(y, "smaller")[0] == pytest.approx(-10 * np.log10((1 + 4 + 9) / 3))
    assert sn_ratio(y, "larger")[0] == pytest.approx(-10 * np.log10((1 + 1 / 4 + 1 / 9) / 3))
    assert sn_ratio(y, "nominal")[0] == pytest.approx(10 * np.log10(2.0**2 / 1.0))  # s^2 = 1
    assert sn_ratio(y, "nominal_variance")[0] == pytest.approx(0.0)
    assert sn_ratio(y, "nominal", target=2.5)[0] == pytest.approx(
        -10 * np.log10((1.5**2 + 0.5**2 + 0.5**2) / 3)
    )
    # a single deterministic response per run
    assert sn_ratio([2.5, 0.1], "nominal", target=2.0) == pytest.approx(
        [-10 * np.log10(0.25), -10 * np.log10(1.9**2)]
    )
    assert sn_ratio([0.5], "smaller-the-better")[0] == pytest.approx(20 * np.log10(2))
    assert sn_ratio([10.0], "LTB")[0] == pytest.approx(20.0)


def test_sn_refuses_what_it_cannot_compute():
    with pytest.raises(OptimiseError, match="target"):
        sn_ratio([1.0, 2.0], "nominal")
    with pytest.raises(OptimiseError, match="only used by kind='nominal'"):
        sn_ratio([1.0], "smaller", target=1.0)
    with pytest.raises(OptimiseError, match="run 1"):
        sn_ratio([1.0, 0.0], "larger")
    with pytest.raises(OptimiseError, match="kind"):
        sn_ratio([1.0], "biggest")
    with pytest.raises(OptimiseError, match="finite"):
        sn_ratio([1.0, np.nan], "smaller")


# --- the analysis on an exactly additive response -----------------------------------------------

EFFECTS = {  # zero-sum level effects on the S/N, dB
    "A": np.array([1.0, -2.0, 1.0]),
    "B": np.array([0.5, 0.0, -0.5]),
    "C": np.array([3.0, -1.0, -2.0]),
    "D": np.array([0.0, 0.2, -0.2]),
}
MU = 20.0


def additive_l9():
    a = get_array("L9")
    sn = MU + sum(EFFECTS[n][a[:, i]] for i, n in enumerate(EFFECTS))
    y = 10 ** (-sn / 20)  # smaller-the-better, one response per run: S/N = -20 log10 y
    return a, sn, y


def test_l9_recovers_the_exact_main_effects_and_contributions():
    a, sn, y = additive_l9()
    r = analyse(a, y, "smaller", factor_names=list(EFFECTS))
    assert r.sn == pytest.approx(sn, abs=1e-10)
    assert r.mean_sn == pytest.approx(MU)
    ss = {n: 3 * np.sum(e**2) for n, e in EFFECTS.items()}  # 3 runs per level
    total = sum(ss.values())
    for e in r.main_effects:
        assert e.sn == pytest.approx(MU + EFFECTS[e.name], abs=1e-10)
        assert e.delta == pytest.approx(np.ptp(EFFECTS[e.name]))
        row = r.anova.row(e.name)
        assert row["ss"] == pytest.approx(ss[e.name])
        assert row["dof"] == 2
        assert row["percent"] == pytest.approx(100 * ss[e.name] / total)
    assert r.anova.row("total")["ss"] == pytest.approx(total)


def test_l9_predicts_the_best_combination_exactly():
    a, _, y = additive_l9()
    r = analyse(a, y, "smaller", factor_names=list(EFFECTS))
    best = tuple(int(np.argmax(e)) for e in EFFECTS.values())
    assert r.best_levels == best
    true_best = MU + sum(e.max() for e in EFFECTS.values())
    assert r.predicted_sn == pytest.approx(true_best)
    # the best combination is not one of the nine runs, and beats all of them
    assert not any(tuple(row) == best for row in a)
    assert r.predicted_sn > r.sn.max()
    # and every one of the 81 combinations is predicted exactly
    for combo in product(range(3), repeat=4):
        truth = MU + sum(e[lv] for e, lv in zip(EFFECTS.values(), combo, strict=True))
        assert r.predict(combo) == pytest.approx(truth)


def test_saturated_array_has_no_error_until_pooled():
    a, _, y = additive_l9()
    r = analyse(a, y, "smaller", factor_names=list(EFFECTS))
    assert r.anova.error_dof == 0
    assert np.isnan(r.anova.row("A")["f"])
    assert any("pooling" in n for n in r.notes)
    pooled = analyse(a, y, "smaller", factor_names=list(EFFECTS), pool=Pool(min_error_dof=2))
    assert pooled.anova.error_dof == 2
    assert pooled.anova.row("D")["pooled"]  # the smallest SS goes first
    assert pooled.significant == ("A", "B", "C")
    # prediction from the significant factors only: D's best level is left out
    assert pooled.predicted_sn == pytest.approx(MU + 1.0 + 0.5 + 3.0)


def test_additive_response_means_are_recovered_on_the_response_scale():
    a = get_array("L9")
    rng = np.random.default_rng(3)
    f = [rng.normal(size=3) for _ in range(4)]
    f = [x - x.mean() for x in f]
    y = 50.0 + sum(fi[a[:, i]] for i, fi in enumerate(f))
    r = analyse(a, y, "larger", anova_on="response")
    for e, fi in zip(r.main_effects, f, strict=True):
        assert e.response == pytest.approx(50.0 + fi)
    for combo in [(0, 1, 2, 0), (2, 2, 2, 2)]:
        truth = 50.0 + sum(fi[lv] for fi, lv in zip(f, combo, strict=True))
        assert r.predict(combo, on="response") == pytest.approx(truth)
    assert r.anova.analysed == "response"


# --- interactions and additivity -----------------------------------------------------------------


def test_interaction_shows_in_the_non_additivity_check():
    a = get_array("L9")
    fa, fb = np.array([2.0, 0.0, -2.0]), np.array([-1.0, 0.5, 0.5])
    u, v = np.array([1.0, -2.0, 1.0]), np.array([1.0, 0.0, -1.0])
    g = np.outer(u, v)  # a pure (double-centred) interaction: no main-effect part
    add = 10.0 + fa[a[:, 0]] + fb[a[:, 1]]
    y = add + g[a[:, 0], a[:, 1]]
    names = ["A", "B"]
    plain = additivity_check(a, add, names)
    assert plain.ss_residual == pytest.approx(0.0, abs=1e-20)
    check = additivity_check(a, y, names)
    assert check.dof_residual == 4
    assert check.residuals == pytest.approx(g[a[:, 0], a[:, 1]])
    assert check.ss_residual == pytest.approx(np.sum(g**2))  # each (A, B) cell once in L9
    assert check.unexplained_percent == pytest.approx(100 * np.sum(g**2) / check.ss_total)
    pair = check.pairs[0]
    assert (pair.a, pair.b) == ("A", "B")
    assert pair.ss == pytest.approx(np.sum(g**2))
    assert pair.table == pytest.approx(10.0 + fa[:, None] + fb[None, :] + g)
    assert pair.aliased_columns == (2, 3)  # the L9 interaction columns of 1 and 2
    # main effects are untouched by a pure interaction
    eff = main_effects(a, y, factor_names=names)
    assert eff[0].sn == pytest.approx(10.0 + fa)


def test_saturated_array_hides_interactions_extra_runs_show_them():
    a = get_array("L9")
    g = 3.0 * np.outer([1.0, -2.0, 1.0], [1.0, 0.0, -1.0])
    base = np.array([0.0, 1.0, -1.0])

    def model(levels, with_g):
        lv = np.atleast_2d(levels)
        out = 5.0 + base[lv[:, 0]] + base[lv[:, 2]]
        return out + (g[lv[:, 0], lv[:, 1]] if with_g else 0.0)

    combos = np.array(list(product(range(3), repeat=4)))
    for with_g in (False, True):
        check = additivity_check(
            a, model(a, with_g), extra_levels=combos, extra_values=model(combos, with_g)
        )
        assert check.dof_residual == 0 and check.notes
        assert check.ss_residual == pytest.approx(0.0, abs=1e-20)
        gap = np.abs(check.extra_residuals).max()
        assert (gap > 1.0) if with_g else gap == pytest.approx(0.0, abs=1e-12)


def test_l8_two_way_interaction_is_the_third_column():
    a = get_array("L8")
    y = np.random.default_rng(0).normal(size=8)
    it = interaction(a, y, "A", "B")
    col3 = anova(a, y, ["X"], columns=[2]).row("X")["ss"]
    assert it.ss == pytest.approx(col3)
    assert it.aliased_columns == (2,)
    assert it.counts.tolist() == [[2, 2], [2, 2]]


def test_interaction_row_in_the_anova_and_the_joint_best_levels():
    lay = select_array([3, 3, 3], interactions=[("A", "B")])
    d = lay.design
    fa, fb, fc = np.array([1.0, 0, -1]), np.array([-1.0, 0.5, 0.5]), np.array([0.3, 0, -0.3])
    g = 2.0 * np.outer([1.0, 0.0, -1.0], [-1.0, 0.0, 1.0])  # best cell flips A and B
    sn = 30.0 + fa[d[:, 0]] + fb[d[:, 1]] + fc[d[:, 2]] + g[d[:, 0], d[:, 1]]
    r = analyse(
        lay.array,
        10 ** (-sn / 20),
        "smaller",
        factor_names=lay.factor_names,
        columns=lay.columns,
        interactions=[("A", "B")],
    )
    row = r.anova.row("A×B")
    assert row["dof"] == 4
    assert row["ss"] == pytest.approx(3 * np.sum(g**2))  # 27 runs, 3 per (A, B) cell
    truth = {
        combo: 30.0 + fa[combo[0]] + fb[combo[1]] + fc[combo[2]] + g[combo[0], combo[1]]
        for combo in product(range(3), repeat=3)
    }
    for combo, value in truth.items():
        assert r.predict(combo) == pytest.approx(value)
    best = max(truth, key=truth.get)
    assert r.best_levels == best
    assert r.predicted_sn == pytest.approx(truth[best])
    # main effects alone would pick another combination, worse than the joint one
    by_effects = tuple(e.best_level for e in r.main_effects)
    assert by_effects != best and truth[by_effects] < truth[best]


def test_an_interaction_aliased_with_a_factor_is_refused():
    a, _, y = additive_l9()
    with pytest.raises(OptimiseError, match="aliased"):
        analyse(a, y, "smaller", interactions=[("A", "B")])


# --- pooling, F and p ----------------------------------------------------------------------------


def dummies(col: np.ndarray) -> np.ndarray:
    """One-hot columns for levels 1..s-1 (level 0 absorbed by the intercept)."""
    return (col[:, None] == np.arange(1, col.max() + 1)[None, :]).astype(float)


def rss(x: np.ndarray, y: np.ndarray) -> float:
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    return float(np.sum((y - x @ beta) ** 2))


def test_pooled_f_and_p_match_a_direct_least_squares_computation():
    a = get_array("L27")
    names = ["A", "B", "C", "D", "E", "F"]
    cols = [0, 1, 4, 8, 9, 12]
    rng = np.random.default_rng(11)
    strength = [3.0, 0.2, 1.5, 0.05, 0.8, 0.1]
    y = sum(s * rng.normal(size=3)[a[:, c]] for s, c in zip(strength, cols, strict=True))
    y = y + 0.3 * rng.normal(size=27)
    pool = Pool(below_percent=2.0, min_error_dof=12)
    tab = anova(a, y, names, columns=cols, pool=pool)
    kept = [n for n in names if not tab.row(n)["pooled"]]
    assert 0 < len(kept) < len(names)
    ss = {n: tab.row(n)["ss"] for n in names}
    pooled_set = set(names) - set(kept)
    assert max(ss[n] for n in pooled_set) <= min(ss[n] for n in kept)  # smallest first
    x_full = np.column_stack([np.ones(27)] + [dummies(a[:, cols[names.index(n)]]) for n in kept])
    ss_e = rss(x_full, y)
    dof_e = 27 - x_full.shape[1]
    assert tab.error_dof == dof_e >= 12
    assert tab.row("error")["ss"] == pytest.approx(ss_e)
    for n in kept:
        others = [m for m in kept if m != n]
        x_red = np.column_stack(
            [np.ones(27)] + [dummies(a[:, cols[names.index(m)]]) for m in others]
        )
        ss_n = rss(x_red, y) - ss_e
        f = (ss_n / 2) / (ss_e / dof_e)
        assert tab.row(n)["ss"] == pytest.approx(ss_n)
        assert tab.row(n)["f"] == pytest.approx(f)
        assert tab.row(n)["p"] == pytest.approx(stats.f.sf(f, 2, dof_e))
    assert sum(tab.row(n)["percent_pure"] for n in kept) + tab.row("error")[
        "percent_pure"
    ] == pytest.approx(100.0)


def test_replicates_give_error_without_pooling():
    a = get_array("L9")
    rng = np.random.default_rng(5)
    y = 3.0 + a[:, :1] * 0.5 + 0.1 * rng.normal(size=(9, 3))
    tab = anova(a, y)
    assert tab.error_dof == 27 - 1 - 8
    assert tab.row("error")["ss"] == pytest.approx(np.sum((y - y.mean(axis=1, keepdims=True)) ** 2))
    assert tab.row("A")["p"] < 1e-6


def test_pool_rules():
    a, _, y = additive_l9()
    by_share = analyse(a, y, pool=Pool(below_percent=3.0))  # B 2.4 %, D 0.4 %
    assert [n for n in "ABCD" if by_share.anova.row(n)["pooled"]] == ["B", "D"]
    named = analyse(a, y, pool=Pool(factors=("A",)))
    assert named.anova.row("A")["pooled"] and named.anova.error_dof == 2
    with pytest.raises(OptimiseError, match="cannot be reached"):
        analyse(a, y, pool=Pool(min_error_dof=8))
    with pytest.raises(OptimiseError, match="percentage"):
        Pool(below_percent=150)


# --- confirmation --------------------------------------------------------------------------------


def test_confirmation_reports_the_gap_and_the_interval():
    a, _, y = additive_l9()
    r = analyse(a, y, "smaller", pool=Pool(min_error_dof=2))
    c = confirm(r, measured_sn=r.predicted_sn - 1.0)
    assert c.levels == r.best_levels
    assert c.predicted_sn == pytest.approx(r.predicted_sn)
    assert c.difference == pytest.approx(-1.0)
    n_eff = 9 / (1 + 6)  # three unpooled factors of 2 dof each
    ve = r.anova.error_ms
    assert c.half_width == pytest.approx(np.sqrt(stats.f.ppf(0.95, 1, 2) * ve * (1 / n_eff + 1)))
    assert c.within == (1.0 <= c.half_width)
    # from responses, at given levels
    c2 = confirm(r, levels={"A": 0, "B": 0, "C": 0, "D": 0}, responses=[10 ** (-24.5 / 20)])
    assert c2.measured_sn == pytest.approx(24.5)
    assert c2.predicted_sn == pytest.approx(MU + 1.0 + 0.5 + 3.0)
    # no error dof: no interval
    assert np.isnan(confirm(analyse(a, y), measured_sn=20.0).half_width)


# --- input checks and immutability ---------------------------------------------------------------


def test_bad_inputs_name_the_problem():
    a = get_array("L9")
    y = np.ones(9) + a[:, 0]
    with pytest.raises(OptimiseError, match="8 response rows"):
        analyse(a, y[:8])
    with pytest.raises(OptimiseError, match="0-based"):
        analyse(a + 1 - 2, y)
    with pytest.raises(OptimiseError, match="not orthogonal"):
        analyse(a[:8], y[:8])
    with pytest.raises(OptimiseError, match="same value"):
        analyse(a, np.ones(9))
    with pytest.raises(OptimiseError, match="5 factor names"):
        analyse(a, y, factor_names=list("ABCDE"))


def test_result_is_frozen():
    a, _, y = additive_l9()
    r = analyse(a, y)
    with pytest.raises(ValueError):
        r.sn[0] = 0.0
    with pytest.raises(AttributeError):
        r.predicted_sn = 0.0
    assert r.best_levels_by_name == {"A": 0, "B": 0, "C": 0, "D": 1}


def test_the_package_keeps_every_public_name_of_the_former_module():
    # optimise/taguchi.py became a package split by concern; the names import as before
    import flexopt.optimise.taguchi as taguchi

    before = {
        "AdditivityCheck", "AnovaTable", "ArraySpec", "Confirmation", "GaloisField",
        "Interaction", "Layout", "MainEffect", "Pool", "TaguchiResult",
        "addelman_kempthorne_array", "additivity_check", "analyse", "anova", "array_spec",
        "confirm", "galois_field", "get_array", "interaction", "interaction_columns",
        "is_orthogonal", "list_arrays", "main_effects", "non_orthogonal_pairs",
        "orthogonal_array", "paley_array", "predict", "rao_hamming_array",
        "rao_hamming_generators", "select_array", "sn_ratio",
    }  # fmt: skip
    assert set(taguchi.__all__) == before
    for name in before:
        assert getattr(taguchi, name).__module__.startswith("flexopt.optimise.taguchi.")
