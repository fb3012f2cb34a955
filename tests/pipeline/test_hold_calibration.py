"""``flexopt calibrate`` of a hold test (pipeline/hold_calibration.py, fea/creep.py's fits and
intervals): a simulated coupon record of a hidden Findley law with noise is fitted, the law
recovered inside its 95 % intervals, written into a material's creep: block, and a hold study
using that material holds the force the hidden law gives.

The hidden law has n = 1/2, whose relaxation ratio is in closed form:
E_R(t)/E0 = erfcx(Gamma(3/2) sqrt(t/tau)) (scipy.special.erfcx), so the records and the
expected held force are computed without the Mittag-Leffler code under test; the held force of
the small-deflection cantilever is F = 3 E_R(t) I delta / L^3.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from flexopt.optimise.calibration import CalibrationError
from flexopt.pipeline.cli import main
from flexopt.pipeline.hold_calibration import calibrate_hold, read_hold_csv
from scipy import special

TAU_H, N, F0_N, D0_MM = 200.0, 0.5, 4.0, 2.0
L_MM, H_MM, B_MM, E_MPA = 60.0, 1.5, 8.0, 1800.0
TIMES_H = np.concatenate([[0.0], np.geomspace(0.05, 500.0, 24)])


def retention(t_h):
    """E_R(t)/E0 of the hidden law, by its closed form."""
    return special.erfcx(math.gamma(1.5) * np.sqrt(np.asarray(t_h, dtype=float) / TAU_H))


def record(path, test: str = "relaxation", noise: float = 0.002, seed: int = 5) -> None:
    """A simulated hold record of the hidden law, multiplicative noise of ``noise`` (1 sigma)."""
    rng = np.random.default_rng(seed)
    jitter = 1.0 + noise * rng.standard_normal(TIMES_H.size)
    if test == "relaxation":
        col, values = "force_N", F0_N * retention(TIMES_H) * jitter
    else:
        col, values = "displacement_mm", D0_MM * (1.0 + (TIMES_H / TAU_H) ** N) * jitter
    pairs = zip(TIMES_H.tolist(), values.tolist(), strict=True)
    lines = [f"time_h,{col}"] + [f"{t!r},{v!r}" for t, v in pairs]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


@pytest.mark.parametrize("test", ["relaxation", "creep"])
def test_the_hidden_law_is_recovered_inside_its_95_percent_intervals(tmp_path, test):
    csv = tmp_path / "hold.csv"
    record(csv, test)
    got = calibrate_hold(csv, 0.3)
    fit = got.fit
    assert got.test == test and fit.n_points == TIMES_H.size
    assert fit.tau_h_ci95[0] <= TAU_H <= fit.tau_h_ci95[1]
    assert abs(fit.n - N) <= fit.n_ci95
    initial = F0_N if test == "relaxation" else D0_MM
    assert abs(fit.initial - initial) <= fit.initial_ci95
    # the intervals are the noise's, not wide open: a few percent on tau, a few hundredths on n
    assert fit.tau_h_ci95[1] / fit.tau_h_ci95[0] < 1.3 and fit.n_ci95 < 0.03
    # without noise, the fit is the law itself
    record(csv, test, noise=0.0)
    exact = calibrate_hold(csv, 0.3).fit
    assert exact.tau_h == pytest.approx(TAU_H, rel=1e-5) and exact.n == pytest.approx(N, abs=1e-6)


def test_calibrate_writes_the_creep_block_and_a_hold_study_holds_the_hidden_force(tmp_path, capsys):
    (tmp_path / "materials.yaml").write_text(
        "my-abs:\n  E_MPa: 1800\n  nu: 0.35\n  yield_MPa: 42.5\n  source: coupon curve\n",
        encoding="utf-8",
    )
    record(tmp_path / "hold.csv")
    argv = ["calibrate", str(tmp_path / "hold.csv"), "--stress-ratio", "0.3", "--name", "my-abs"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "relaxation test: Findley tau" in out and "my-abs" in out
    written = yaml.safe_load((tmp_path / "materials.yaml").read_text("utf-8"))["my-abs"]
    assert written["E_MPa"] == 1800 and written["source"] == "coupon curve"  # kept
    creep = written["creep"]
    assert creep["max_stress_ratio"] == 0.3 and creep["fit"]["test"] == "relaxation"
    assert creep["fit"]["data"]["time_h"] == pytest.approx(TIMES_H.tolist())
    lo, hi = creep["fit"]["tau_h_ci95"]
    assert lo <= TAU_H <= hi and abs(creep["n"] - N) <= creep["fit"]["n_ci95"]
    assert (tmp_path / "creep_fit.json").is_file()

    delta = 0.5
    study = {
        "name": "held-my-abs",
        "geometry": {
            "kind": "polyline_beam", "points_mm": [[0, 0], [30, 0], [60, 0]],
            "thickness_mm": [H_MM] * 3, "width_mm": B_MM, "elements": 30,
        },
        "material": "my-abs",
        "boundary": {
            "start": "clamped",
            "end": {
                "control": "displacement", "direction": [0, 1], "max_mm": 1.0, "steps": 4,
                "rotation": "free", "transverse": "free",
            },
        },
        "hold": {"time_h": 24.0, "at": "displacement", "level": delta},
    }  # fmt: skip
    (tmp_path / "held.yaml").write_text(yaml.safe_dump(study), encoding="utf-8")
    assert main(["evaluate", str(tmp_path / "held.yaml"), "--out", str(tmp_path / "ev")]) == 0
    summary = yaml.safe_load((tmp_path / "ev" / "evaluation.json").read_text("utf-8"))["summary"]
    i_mm4 = B_MM * H_MM**3 / 12.0
    hidden = 3.0 * E_MPA * float(retention(24.0)) * i_mm4 * delta / L_MM**3
    # the fit's error (noise 0.2 %) and small-deflection theory (delta/L < 1 %): within 0.3 %
    assert summary["held_force_N"] == pytest.approx(hidden, rel=3e-3)
    assert "relaxation test hold.csv" in summary["creep_data_source"]


def write(tmp_path, text: str):
    path = tmp_path / "bad.csv"
    path.write_text(text, encoding="utf-8")
    return path


GOOD = [(0.0, 4.0), (0.1, 3.9), (1.0, 3.8), (10.0, 3.6), (100.0, 3.3), (300.0, 3.1)]


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("time_s,force_N\n" + "".join(f"{t},{f}\n" for t, f in GOOD), "in hours"),
        ("time_h,force_kN\n" + "".join(f"{t},{f}\n" for t, f in GOOD), "give one of force_N"),
        ("time_h,force_N\n" + "".join(f"{t},{f}\n" for t, f in GOOD[:4]), "at least 6"),
        (
            "time_h,force_N\n" + "".join(f"{t},{f}\n" for t, f in [*GOOD[:3], GOOD[1], *GOOD[4:]]),
            "not strictly increasing",
        ),
        ("time_h,force_N\n" + "".join(f"{t},{-f if t == 10 else f}\n" for t, f in GOOD), "sign"),
        ("time_h,force_N\n" + "".join(f"{t},{4.0 + t}\n" for t, _ in GOOD), "does not fall"),
    ],
)
def test_bad_hold_records_get_one_line_and_exit_2(tmp_path, capsys, text, fragment):
    path = write(tmp_path, text)
    with pytest.raises(CalibrationError, match=fragment):
        if "force_N" in text.splitlines()[0] and "time_h" in text.splitlines()[0]:
            calibrate_hold(path, 0.3)
        else:
            read_hold_csv(path)
    assert main(["calibrate", str(path), "--stress-ratio", "0.3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("flexopt calibrate: error:") and fragment in err[0]


def test_a_hold_test_needs_its_stress_ratio_and_a_known_material(tmp_path, capsys):
    record(tmp_path / "hold.csv")
    assert main(["calibrate", str(tmp_path / "hold.csv")]) == 2
    assert "--stress-ratio" in capsys.readouterr().err
    args = ["calibrate", str(tmp_path / "hold.csv"), "--stress-ratio", "0.3", "--name", "nope"]
    assert main(args) == 2
    assert "has no material 'nope'" in capsys.readouterr().err
    assert main([*args[:4], "--stress-ratio", "1.5"]) == 2
    assert "(0, 1]" in capsys.readouterr().err
