"""The kinds' declared out-of-plane width (``StudyKind.width_key``, ``flexopt retrim``'s default
``--key``): doubling it doubles every force, moment, torque and stiffness column of ``flexopt
evaluate`` (stresses and motions stay), and ``flexopt retrim`` writes the scaled width."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest
import yaml
from flexopt.pipeline.studies import get_kind

#: the SEA spring with ST a design variable, and rows enough for a measured curve (>= 5 rows
#: at positive angles: optimise.calibration.compare_curves)
SEARCH = {"thickness": "search", "mesh.curve_steps": 5}
#: (example, changes to it, the kind's width key, the measured curve's two columns)
CASES = [
    ("cantilever", {}, "geometry.width_mm", ("displacement_mm", "force_N")),
    ("cantilever-stop", {}, "geometry.width_mm", ("displacement_mm", "force_N")),
    ("flexure-pivot", {}, "geometry.width_mm", ("rotation_deg", "torque_Nmm")),
    ("leaf-spring-joint", {}, "geometry.width_mm", ("deflection_deg", "torque_Nm_sliding_l28")),
    # ST a variable, no 3D check: plane stress only (its torque is proportional to ST)
    ("sea-spring-quick", SEARCH, "design.ST", ("rotation_deg", "torque_Nm")),
    # mechanism: a written width, no 3D check judging (stops skip the check; solid: never keeps
    # plane stress); the guide is driven to -6 mm (the measured curve on the negative side)
    ("parallel-guide-stop", {}, "geometry.width_mm", ("drive_mm", "force_N")),
    (
        "constant-force-mechanism",
        {"fidelity.solid": "never"},
        "geometry.width_mm",
        ("drive_mm", "force_N"),
    ),
]
FORCE_LIKE = re.compile(r"force|torque|moment|stiffness")


def value_at(study, key):
    from flexopt.pipeline.study_edit import study_data

    node = study_data(study)
    for part in key.split("."):
        node = node[part]
    return float(node)


def measured_csv(tmp_path, curve, factor):
    """measured.csv: the evaluate folder's (tmp_path/base) curve ``curve`` (x, y column names),
    y times ``factor``, without its unloaded row (x = 0: no force error to take)."""
    with open(tmp_path / "base" / "response.csv", newline="") as f:
        rows = [(float(r[curve[0]]), float(r[curve[1]])) for r in csv.DictReader(f)]
    lines = [",".join(curve)] + [f"{x!r},{factor * y!r}" for x, y in rows if x != 0]
    (tmp_path / "measured.csv").write_text("\n".join(lines) + "\n")


def width_key_of(study):
    key = get_kind(study.kind).width_key
    return key(study) if callable(key) else key


@pytest.mark.parametrize(("example", "changes", "key", "curve"), CASES, ids=[c[0] for c in CASES])
def test_doubling_the_width_doubles_every_force(tmp_path, example, changes, key, curve):
    import flexopt
    from flexopt.pipeline.cli import main
    from flexopt.pipeline.study import load_study, resolve_study_path

    study = load_study(resolve_study_path(example))
    base = flexopt.evaluate(study.with_values(changes), out=tmp_path / "base")
    assert width_key_of(base.study) == key
    width = value_at(base.study, key)
    wide = flexopt.evaluate(base.study.with_values({key: 2 * width}), out=tmp_path / "wide")
    names = [n for n in base.table if FORCE_LIKE.search(n)]
    assert names and curve[1] in names
    # columns that are zero up to round-off (a free end's moment, ~1e-11 N mm) are compared
    # against the largest force-like value of the table, not against their own noise
    scale = max(float(np.nanmax(np.abs(np.asarray(base.table[n], float)))) for n in names)
    for name in names:
        old = np.asarray(base.table[name], dtype=float)
        new = np.asarray(wide.table[name], dtype=float)
        # a stop's penalty is not scaled with the width: its contact force to ~1e-7
        np.testing.assert_allclose(new, 2 * old, rtol=1e-6, atol=1e-9 * scale, err_msg=name)
    for name in base.table:
        if "stress" in name:  # sigma = M c / I: M and I both scale with the width
            np.testing.assert_allclose(
                np.asarray(wide.table[name], float), np.asarray(base.table[name], float), rtol=1e-6
            )

    # a "print" 20 % weaker than predicted: re-trim by the kind's key, width / 0.8
    measured_csv(tmp_path, curve, 0.8)
    assert main(["retrim", str(tmp_path / "base"), str(tmp_path / "measured.csv")]) == 0
    written = yaml.safe_load((tmp_path / "base" / "retrimmed.yaml").read_text())
    node = written
    for part in key.split("."):
        node = node[part]
    assert float(node) == pytest.approx(width / 0.8, rel=1e-6)


def test_no_width_key_where_the_thickness_is_solved_or_judged_in_3d(tmp_path):
    """sea_spring declares ``design.ST`` only with ``thickness: search`` and no 3D check;
    threshold_spring (ST solved from the torque target), gripper and cam none; mechanism only
    with a written width that reaches every beam and no 3D check judging (docs/print_to_part.md,
    section 4); retrim then asks for ``--key``."""
    from flexopt.optimise.calibration import CalibrationError
    from flexopt.pipeline.print_to_part import retrim_run
    from flexopt.pipeline.study import load_study, resolve_study_path

    quick = load_study(resolve_study_path("sea-spring-quick"))
    assert width_key_of(quick) is None  # thickness: solve
    assert width_key_of(quick.with_values({"thickness": "search"})) == "design.ST"
    assert width_key_of(quick.with_values({"thickness": "search", "solid_3d.check": True})) is None
    for example in ("threshold-spring", "gripper", "threshold-cam"):
        assert width_key_of(load_study(resolve_study_path(example))) is None, example
    # mechanism: a solved width (parallel-guide, bistable-switch), the 3D check that may judge
    # (solid: auto, the default: constant-force-mechanism, gripper-amplifier), a beam's own width
    for example in ("parallel-guide", "bistable-switch"):
        mech = load_study(resolve_study_path(example))
        assert mech.solve_width_from is not None and width_key_of(mech) is None, example
        unsolved = mech.with_values({"solve_width_from": None, "fidelity.solid": "never"})
        assert width_key_of(unsolved) == "geometry.width_mm", example
    for example in ("constant-force-mechanism", "gripper-amplifier"):
        mech = load_study(resolve_study_path(example))
        assert mech.fidelity.solid == "auto" and width_key_of(mech) is None, example
        for off in ({"fidelity.solid": "never"}, {"fidelity.enabled": False}):
            assert width_key_of(mech.with_values(off)) == "geometry.width_mm", (example, off)
        assert width_key_of(mech.with_values({"fidelity.solid": "always"})) is None
    guide = load_study(resolve_study_path("parallel-guide-stop"))
    assert width_key_of(guide) == "geometry.width_mm"  # stops: the check is skipped
    own = guide.with_values({"geometry.beams.upper.width_mm": 5.0})
    assert width_key_of(own) is None
    # an evaluate folder of a kind without one: retrim names --key
    import flexopt

    flexopt.evaluate(quick.with_values({"mesh.curve_steps": 5}), out=tmp_path / "base")
    measured_csv(tmp_path, ("rotation_deg", "torque_Nm"), 1.0)
    with pytest.raises(CalibrationError, match="--key"):
        retrim_run(tmp_path / "base", tmp_path / "measured.csv")
