"""Stress-life fatigue (fea/fatigue.py) against answers computed by hand in each test."""

from __future__ import annotations

import math

import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.fatigue import (
    LoadLevel,
    SNCurve,
    count_cycles,
    cycles_to_failure,
    equivalent_amplitude,
    levels_from_history,
    material_sn_curve,
    miner,
    shigley_sn_curve,
    surface_factor,
)
from flexopt.fea.materials import FATIGUE_DATA, MATERIALS, get_fatigue_data


def _shigley_by_hand(sut: float, ka_a: float, ka_b: float) -> tuple[float, float, float]:
    """Shigley ch. 6 by hand: (a, b, Se) of S = a N^b for a steel of tensile strength sut."""
    se_prime = 0.5 * sut if sut <= 1400.0 else 700.0
    se = min(1.0, ka_a * sut**ka_b) * se_prime
    sigma_f = sut + 345.0
    b_e = -math.log10(sigma_f / se_prime) / math.log10(2.0e6)
    f = sigma_f / sut * 2000.0**b_e
    return (f * sut) ** 2 / se, -math.log10(f * sut / se) / 3.0, se


def _cantilever_root_stress(force_N: float, length_mm: float, b_mm: float, h_mm: float) -> float:
    # sigma = M c / I = 6 F L / (b h^2) at the clamped root's surface.
    return 6.0 * force_N * length_mm / (b_mm * h_mm**2)


# -- rainflow ------------------------------------------------------------------------------------


def test_rainflow_astm_e1049_textbook_history():
    # ASTM E1049-85 Fig. 6: ranges 3, 4, 6, 8, 9 with 0.5, 1.5, 0.5, 1.0, 0.5 cycles.
    history = [-2, 1, -3, 5, -1, 3, -4, 4, -2]
    assert count_cycles(history) == [(3.0, 0.5), (4.0, 1.5), (6.0, 0.5), (8.0, 1.0), (9.0, 0.5)]
    levels = levels_from_history(history)
    by_range: dict[float, float] = {}
    for lv in levels:
        by_range[2.0 * lv.amplitude_MPa] = by_range.get(2.0 * lv.amplitude_MPa, 0.0) + lv.cycles
    assert by_range == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}


def test_miner_over_a_rainflow_counted_history_matches_hand_sum():
    # PA12 (no endurance limit), the ASTM history scaled to MPa, no mean-stress correction.
    curve = material_sn_curve("PA12")
    b = math.log10(15.0 / 48.0) / 6.0
    a = 15.0 / 1.0e6**b
    res = miner(
        curve, levels_from_history([-2, 1, -3, 5, -1, 3, -4, 4, -2]), rate_hz=1.0, correction="none"
    )
    counted = {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}
    d_hand = sum(n / (0.5 * rng / a) ** (1.0 / b) for rng, n in counted.items())
    assert res.damage_per_block == pytest.approx(d_hand, rel=1e-12)
    assert res.block_cycles == pytest.approx(4.0)
    assert res.life_cycles == pytest.approx(4.0 / d_hand, rel=1e-12)


# -- S-N curve and the cantilever ---------------------------------------------------------------


def test_marin_surface_factor_matches_shigley_example_6_3():
    # Shigley Example 6-3: Sut = 520 MPa, machined: ka = 4.51 (520)^-0.265 = 0.860.
    assert surface_factor(520.0, "machined") == pytest.approx(0.860, abs=5e-4)


def test_shigley_curve_passes_through_f_sut_at_1e3_and_se_at_1e6():
    curve = material_sn_curve("65Mn")
    a, b, se = _shigley_by_hand(980.0, 4.51, -0.265)
    assert curve.a_MPa == pytest.approx(a, rel=1e-12)
    assert curve.b == pytest.approx(b, rel=1e-12)
    assert curve.endurance_MPa == pytest.approx(se, rel=1e-12)
    assert curve.strength_MPa(1.0e6) == pytest.approx(se, rel=1e-9)
    # S(10^3) = f Sut with f of Shigley's Fig. 6-18 near 0.8 at 980 MPa.
    assert 0.75 < curve.strength_MPa(1.0e3) / 980.0 < 0.85


@pytest.mark.parametrize("correction", ["goodman", "swt"])
def test_cantilever_constant_amplitude_life_steel(correction):
    length, width, thick = 20.0, 5.0, 1.0  # mm
    f_mean, f_amp = 8.0, 12.0  # N: a tip load 8 +- 12 N, so the root stress has a tensile mean
    s_mean = _cantilever_root_stress(f_mean, length, width, thick)  # 192 MPa
    s_amp = _cantilever_root_stress(f_amp, length, width, thick)  # 288 MPa
    assert s_mean == pytest.approx(192.0) and s_amp == pytest.approx(288.0)
    a, b, _se = _shigley_by_hand(980.0, 4.51, -0.265)
    if correction == "goodman":
        s_ar = 288.0 / (1.0 - 192.0 / 980.0)
    else:
        s_ar = math.sqrt((192.0 + 288.0) * 288.0)
    n_hand = (s_ar / a) ** (1.0 / b)
    n = cycles_to_failure(material_sn_curve("65Mn"), s_amp, s_mean, correction)
    assert 1.0e3 < n_hand < 1.0e6  # a finite-life case, not the endurance branch
    assert n == pytest.approx(n_hand, rel=1e-10)


@pytest.mark.parametrize("correction", ["goodman", "swt"])
def test_cantilever_constant_amplitude_life_polymer(correction):
    # ABS: the documented estimate S(1e6) = 0.25 x 42.5 MPa, line through 42.5 MPa at N = 1.
    length, width, thick = 30.0, 8.0, 2.0
    s_mean = _cantilever_root_stress(0.5, length, width, thick)  # 2.8125 MPa
    s_amp = _cantilever_root_stress(2.0, length, width, thick)  # 11.25 MPa
    b = math.log10(0.25) / 6.0
    a = 0.25 * 42.5 / 1.0e6**b
    if correction == "goodman":
        s_ar = s_amp / (1.0 - s_mean / 42.5)
    else:
        s_ar = math.sqrt((s_mean + s_amp) * s_amp)
    n_hand = (s_ar / a) ** (1.0 / b)
    assert n_hand == pytest.approx(
        cycles_to_failure(material_sn_curve("ABS"), s_amp, s_mean, correction), rel=1e-10
    )


def test_cantilever_life_from_the_beam_solver_at_small_load():
    # The project's beam solver (fea/beam.py) at small load (P L^2 / EI ~ 0.09): the root stress
    # of a tip load cycling between -4 N and +20 N, its peak tracked at the root (s = 0), gives
    # the hand Goodman life of the closed-form stresses 6 F L / (b h^2).
    from flexopt.fea.beam import BeamSettings, EndDrive, solve_beam
    from flexopt.fea.materials import get_material
    from flexopt.geometry.profile import BeamProfile

    length, width, thick = 20.0, 5.0, 1.0
    profile = BeamProfile([[0.0, 0.0], [length, 0.0]], [thick, thick], width)
    peaks = {}
    for force in (20.0, -4.0):
        res = solve_beam(
            profile,
            get_material("65Mn"),
            EndDrive("force", (0.0, 1.0), force, steps=4, rotation="free", transverse="free"),
            settings=BeamSettings(n_elements=20),
        )
        assert res.ok, res.message
        assert res.peak_stress_s_mm[-1] == pytest.approx(0.0, abs=1e-9)  # at the root
        peaks[force] = float(res.peak_stress_MPa[-1])
    s_max, s_min = peaks[20.0], -peaks[-4.0]  # the root's top fibre: tension, then compression
    n_beam = cycles_to_failure(
        material_sn_curve("65Mn"), 0.5 * (s_max - s_min), 0.5 * (s_max + s_min), "goodman"
    )
    hand_max = _cantilever_root_stress(20.0, length, width, thick)  # 480 MPa
    hand_min = -_cantilever_root_stress(4.0, length, width, thick)  # -96 MPa
    assert s_max == pytest.approx(hand_max, rel=2e-3)
    assert s_min == pytest.approx(hand_min, rel=2e-3)
    a, b, _se = _shigley_by_hand(980.0, 4.51, -0.265)
    s_a, s_m = 0.5 * (hand_max - hand_min), 0.5 * (hand_max + hand_min)
    n_hand = ((s_a / (1.0 - s_m / 980.0)) / a) ** (1.0 / b)
    assert 1.0e3 < n_hand < 1.0e6
    assert n_beam == pytest.approx(n_hand, rel=0.03)  # N ~ S^(1/b), 1/b ~ -8.7


# -- endurance limit ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["65Mn", "17-4PH-H900", "maraging-300", "Ti-6Al-4V"])
def test_metals_have_infinite_life_below_the_endurance_limit(name):
    curve = material_sn_curve(name)
    assert curve.endurance_MPa is not None
    assert curve.cycles_to_failure(0.99 * curve.endurance_MPa) == math.inf
    n_above = curve.cycles_to_failure(1.01 * curve.endurance_MPa)
    assert math.isfinite(n_above) and n_above < 1.0e6


@pytest.mark.parametrize("name", ["ABS", "PLA", "PETG", "PA12"])
def test_polymers_have_no_endurance_limit(name):
    curve = material_sn_curve(name)
    assert curve.endurance_MPa is None
    s = 0.05 * MATERIALS[name].yield_MPa
    n = curve.cycles_to_failure(s)
    assert math.isfinite(n) and n > 1.0e6


def test_maraging_endurance_capped_at_700_mpa_times_ka():
    # Sut = 2050 MPa > 1400 MPa: Se' = 700 MPa, machined ka = 4.51 * 2050^-0.265.
    ka = 4.51 * 2050.0**-0.265
    assert material_sn_curve("maraging-300").endurance_MPa == pytest.approx(700.0 * ka)
    ground = material_sn_curve("maraging-300", surface="ground")
    assert ground.endurance_MPa == pytest.approx(700.0 * 1.58 * 2050.0**-0.085)


# -- Miner's sum --------------------------------------------------------------------------------


def test_two_level_block_against_miner_by_hand():
    a, b, se = _shigley_by_hand(1310.0, 4.51, -0.265)  # 17-4PH H900, machined
    curve = material_sn_curve("17-4PH-H900")
    s1, n1 = 1.5 * se, 1000.0
    s2, n2 = 1.2 * se, 5000.0
    s3 = 0.8 * se  # below the endurance limit: no damage
    rate = 2.0  # Hz
    d1 = n1 / (s1 / a) ** (1.0 / b)
    d2 = n2 / (s2 / a) ** (1.0 / b)
    res = miner(
        curve,
        [LoadLevel(s1, cycles=n1), LoadLevel(s2, cycles=n2), LoadLevel(s3, cycles=1.0e6)],
        rate_hz=rate,
    )
    assert res.damage_per_level[0] == pytest.approx(d1, rel=1e-12)
    assert res.damage_per_level[1] == pytest.approx(d2, rel=1e-12)
    assert res.damage_per_level[2] == 0.0
    assert res.damage_per_block == pytest.approx(d1 + d2, rel=1e-12)
    life = (n1 + n2 + 1.0e6) / (d1 + d2)
    assert res.life_cycles == pytest.approx(life, rel=1e-12)
    assert res.life_hours == pytest.approx(life / rate / 3600.0, rel=1e-12)
    assert res.in_range

    # The same duty as shares of the cycles gives the same life.
    total = n1 + n2 + 1.0e6
    shares = miner(
        curve,
        [
            LoadLevel(s1, share=n1 / total),
            LoadLevel(s2, share=n2 / total),
            LoadLevel(s3, share=1.0e6 / total),
        ],
        rate_hz=rate,
    )
    assert shares.life_cycles == pytest.approx(life, rel=1e-9)
    assert shares.block_cycles == pytest.approx(1.0)


def test_miner_flags_low_cycle_levels_as_out_of_range():
    curve = material_sn_curve("65Mn")
    res = miner(curve, [LoadLevel(0.95 * 980.0, cycles=1.0)], rate_hz=1.0)
    assert res.cycles_to_failure[0] < 1.0e3 and not res.in_range


# -- mean-stress corrections --------------------------------------------------------------------


def test_mean_stress_corrections_limits():
    # Goodman: a mean at Sut is static failure; compressive means are not credited.
    assert equivalent_amplitude(10.0, 100.0, 100.0, "goodman") == math.inf
    assert equivalent_amplitude(10.0, -50.0, 100.0, "goodman") == 10.0
    # SWT: a cycle that never opens does no damage; it credits compressive means.
    assert equivalent_amplitude(10.0, -20.0, 100.0, "swt") == 0.0
    assert equivalent_amplitude(10.0, -5.0, 100.0, "swt") == pytest.approx(math.sqrt(5.0 * 10.0))
    assert equivalent_amplitude(10.0, 0.0, 100.0, "swt") == pytest.approx(10.0)
    curve = material_sn_curve("PA12")
    assert cycles_to_failure(curve, 5.0, 48.0, "goodman") == 0.0


# -- data ---------------------------------------------------------------------------------------


def test_every_builtin_material_has_sourced_fatigue_data():
    assert set(FATIGUE_DATA) == set(MATERIALS)
    for name, data in FATIGUE_DATA.items():
        assert data.source, name
        if data.estimate:
            assert "estimate" in data.source, name
        # The Goodman intercept is at least the allowable the static check uses.
        assert data.ultimate_MPa >= MATERIALS[name].yield_MPa, name
    assert get_fatigue_data("ti6al4v") is FATIGUE_DATA["Ti-6Al-4V"]


def test_docs_table_is_what_the_module_computes():
    # docs/durability.md's data table must be today's curves (rounded as printed there).
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "durability.md").read_text()
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 9 and cells[3][:1].isdigit():
            rows[cells[0].split(" (")[0].replace(" ", "-")] = cells
    assert len(rows) == len(FATIGUE_DATA)
    for name in FATIGUE_DATA:
        cells = rows[name]
        curve = material_sn_curve(name)
        assert float(cells[3]) == pytest.approx(curve.a_MPa, abs=0.051)
        assert float(cells[4].replace("\u2212", "-")) == pytest.approx(curve.b, abs=5.1e-5)
        assert float(cells[5]) == pytest.approx(curve.strength_MPa(1.0e3), abs=0.051)
        assert float(cells[6]) == pytest.approx(curve.strength_MPa(1.0e6), abs=0.051)


# -- bad input ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: equivalent_amplitude(-1.0, 0.0, 100.0), "amplitude_MPa"),
        (lambda: equivalent_amplitude(1.0, 0.0, 100.0, "gerber"), "goodman"),
        (lambda: surface_factor(900.0, "polished-ish"), "machined"),
        (lambda: shigley_sn_curve(900.0, size_factor=1.2), "size_factor"),
        (lambda: SNCurve(a_MPa=100.0, b=0.1, ultimate_MPa=50.0), "b = 0.1"),
        (lambda: LoadLevel(10.0), "exactly one"),
        (lambda: LoadLevel(10.0, cycles=5.0, share=0.5), "exactly one"),
        (lambda: LoadLevel(float("nan"), cycles=1.0), "amplitude_MPa"),
        (lambda: LoadLevel(10.0, share=1.5), "share"),
        (
            lambda: miner(material_sn_curve("ABS"), [LoadLevel(5.0, cycles=1.0)], rate_hz=0.0),
            "rate_hz",
        ),
        (
            lambda: miner(
                material_sn_curve("ABS"),
                [LoadLevel(5.0, share=0.5), LoadLevel(4.0, share=0.4)],
                rate_hz=1.0,
            ),
            "sum to 0.9",
        ),
        (
            lambda: miner(
                material_sn_curve("ABS"),
                [LoadLevel(5.0, share=0.5), LoadLevel(4.0, cycles=3.0)],
                rate_hz=1.0,
            ),
            "mix",
        ),
        (lambda: miner(material_sn_curve("ABS"), [], rate_hz=1.0), "no load level"),
        (lambda: count_cycles([1.0, float("nan"), 2.0]), "nan at index 1"),
        (lambda: count_cycles([[1.0, 2.0]]), "1-D"),
        (lambda: material_sn_curve("unobtainium"), "no fatigue data"),
        (lambda: material_sn_curve("PLA", surface="ground"), "steels only"),
    ],
)
def test_bad_input_is_refused_with_the_fix(call, match):
    with pytest.raises(FeaError, match=match):
        call()
