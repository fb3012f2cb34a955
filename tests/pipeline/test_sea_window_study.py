"""The ``sea_window`` study kind: the window's two bounds hold what they promise, plots, errors."""

from __future__ import annotations

import json
import math

import pytest
from flexopt.fea.sea_window import Gearbox, Motor, rpm_to_rad_per_s, simulate_impact
from flexopt.fea.sea_window import torque_bandwidth_rad_per_s as bandwidth
from flexopt.pipeline.cli import main
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies import sea_window as sw
from flexopt.pipeline.study import load_study, validate_study


def test_example_window_bounds_meet_their_definitions(tmp_path):
    out = tmp_path / "win"
    assert main(["evaluate", "sea-window", "--out", str(out)]) == 0
    record = json.loads((out / "evaluation.json").read_text())
    s = record["summary"]
    lo, hi = s["k_min_Nm_per_rad"], s["k_max_Nm_per_rad"]
    assert 0 < lo < hi
    # K_min: exactly the required bandwidth at the required torque
    bw = bandwidth(lo, Motor(), Gearbox(), 53.0) / (2 * math.pi)
    assert bw == pytest.approx(4.0, rel=1e-6)
    # K_max: the peak spring torque after the collision is exactly the gearbox limit
    hit = simulate_impact(hi, Motor(), Gearbox(), rpm_to_rad_per_s(46.86), 0.0)
    assert hit.peak_spring_torque_Nm == pytest.approx(Gearbox().momentary_peak_torque_Nm, rel=1e-3)
    # the paper's 275 N m/rad is stiffer than K_max for this impact (docs/sea_window.md)
    assert s["in_window"] is False and s["peak_spring_torque_Nm"] > 69.0
    assert s["bandwidth_Hz"] > 4.0
    for name in ("bode.png", "peak_torque.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert name in record["files"]
    rows = (out / "response.csv").read_text().splitlines()
    assert rows[0].startswith("stiffness_Nm_per_rad,peak_spring_torque_Nm")
    assert len(rows) == 1 + load_study("sea-window").points


def test_peak_torque_grows_and_bandwidth_grows_with_stiffness():
    study = load_study("sea-window")
    r = sw.evaluate(study)
    t, b = r.table["peak_spring_torque_Nm"], r.table["bandwidth_Hz"]
    assert all(t[1:] > t[:-1]) and all(b[1:] > b[:-1])


@pytest.mark.parametrize(
    ("changes", "path", "words"),
    [
        ({"motor": {"rotor_inertia": 1e-4}}, "motor.rotor_inertia", ["unknown field"]),
        ({"gearbox": {"ratio": -50}}, "gearbox.ratio", [">= 0"]),
        ({"sweep_Nm_per_rad": [500, 100]}, "", ["lowest < highest"]),
    ],
)
def test_bad_input_names_the_key(changes, path, words):
    raw = {"name": "w", "geometry": {"kind": "sea_window"}, **changes}
    with pytest.raises(StudyError) as info:
        study = validate_study(raw)
        sw.check(study)
    assert info.value.path == path
    for w in words:
        assert w in str(info.value)
