"""Robustness core: corner and Monte Carlo samples, shares and the response band."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from flexopt.optimise.errors import OptimiseError
from flexopt.optimise.robustness import (
    RobustnessSpec,
    corner_samples,
    met_robustly,
    monte_carlo_samples,
    response_band,
    samples_of,
    share_met,
)
from pydantic import ValidationError


@pytest.mark.parametrize(
    ("scatter", "k"),
    [((10.0, 0.1, 0.2), 3), ((10.0, 0.0, 0.2), 2), ((0.0, 0.1, 0.0), 1), ((5.0, 0.0, 0.0), 1)],
)
def test_corners_are_the_nominal_and_every_sign_combination(scatter, k):
    rows = corner_samples(*scatter)
    assert rows.shape == (2**k + 1, 3)
    np.testing.assert_array_equal(rows[0], [1.0, 0.0, 0.0])
    amp = np.array([scatter[0] / 100.0, scatter[1], scatter[2]])
    active = np.flatnonzero(amp > 0)
    expected = set()
    for signs in itertools.product((-1.0, 1.0), repeat=k):
        row = np.zeros(3)
        row[active] = np.array(signs) * amp[active]
        row[0] += 1.0
        expected.add(tuple(np.round(row, 12)))
    assert {tuple(np.round(r, 12)) for r in rows[1:]} == expected
    # an inactive scatter stays at its nominal value in every row
    inactive = np.flatnonzero(amp == 0)
    assert np.all(rows[:, inactive] == (inactive == 0).astype(float))


def test_monte_carlo_is_reproducible_and_inside_the_band():
    a = monte_carlo_samples(20.0, 0.1, 0.3, 500, seed=7)
    b = monte_carlo_samples(20.0, 0.1, 0.3, 500, seed=7)
    c = monte_carlo_samples(20.0, 0.1, 0.3, 500, seed=8)
    assert a.shape == (501, 3)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    np.testing.assert_array_equal(a[0], [1.0, 0.0, 0.0])
    draws = a[1:]
    lo, hi = np.array([0.8, -0.1, -0.3]), np.array([1.2, 0.1, 0.3])
    assert np.all(draws >= lo) and np.all(draws <= hi)
    # uniform: 500 draws reach well into both halves of every band (P(miss) ~ 2^-500)
    mid = (lo + hi) / 2
    assert np.all((draws < mid).any(axis=0)) and np.all((draws > mid).any(axis=0))
    # the spread of a uniform on [-a, a] is a/sqrt(3): within 15 % for 500 draws
    np.testing.assert_allclose(draws.std(axis=0), (hi - lo) / 2 / np.sqrt(3), rtol=0.15)


def test_share_arithmetic():
    met = np.array(
        [
            [True, True, False],
            [True, False, False],
            [True, True, False],
            [False, True, False],
        ]
    )
    share = share_met(met)
    np.testing.assert_allclose(share, [75.0, 75.0, 0.0])
    np.testing.assert_array_equal(met_robustly(share, 75.0), [True, True, False])
    np.testing.assert_array_equal(met_robustly(share, 75.1), [False, False, False])
    # 19 of 20 samples is 95 % exactly, met at 95 % despite the float division
    share20 = share_met(np.arange(20)[:, None] != 3)
    assert met_robustly(share20, 95.0)[0]
    with pytest.raises(OptimiseError):
        share_met(np.zeros((0, 2), dtype=bool))


def test_band_is_the_per_row_min_and_max():
    x = np.linspace(0.0, 3.0, 4)
    tables = [
        {"displacement_mm": x, "force_N": np.array([0.0, 1.0, 2.0, 3.0]), "ok": np.ones(4, bool)},
        {"displacement_mm": x, "force_N": np.array([0.0, 1.5, 1.0, 3.5])},
        {"displacement_mm": x[:2], "force_N": np.array([0.0, 0.5])},  # stopped after row 1
        None,  # a sample that failed
    ]
    band = response_band(tables)
    assert set(band) == {"displacement_mm", "force_N"}  # booleans are not banded
    low, high = band["force_N"]
    np.testing.assert_array_equal(low, [0.0, 0.5, 1.0, 3.0])
    np.testing.assert_array_equal(high, [0.0, 1.5, 2.0, 3.5])
    np.testing.assert_array_equal(band["displacement_mm"][0], x)
    # a row no sample reached is NaN
    band2 = response_band([{"f": np.array([1.0, np.nan])}, {"f": np.array([2.0, np.nan])}])
    assert band2["f"][0][0] == 1.0 and np.isnan(band2["f"][0][1]) and np.isnan(band2["f"][1][1])


def test_spec_counts_and_refusals():
    spec = RobustnessSpec(E_percent=10, thickness_mm=0.1, width_mm=0.1)
    assert spec.n_samples == 9 and samples_of(spec).shape == (9, 3)
    mc = RobustnessSpec(method="monte_carlo", samples=16, seed=3, E_percent=10)
    assert mc.n_samples == 17
    np.testing.assert_array_equal(samples_of(mc), monte_carlo_samples(10, 0, 0, 16, 3))
    for bad in (
        {},  # no scatter at all
        {"method": "monte_carlo", "E_percent": 10},  # no sample count
        {"samples": 8, "E_percent": 10},  # a count for corners
        {"E_percent": 100},
        {"thickness_mm": -0.1},
        {"E_percent": 10, "share_percent": 0},
        {"E_percent": 10, "colour": "red"},
    ):
        with pytest.raises(ValidationError):
            RobustnessSpec(**bad)
    with pytest.raises(OptimiseError):
        corner_samples(10, -0.1, 0)
    with pytest.raises(OptimiseError):
        monte_carlo_samples(10, 0.1, 0, 0, 1)
