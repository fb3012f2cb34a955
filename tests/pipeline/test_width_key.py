"""The kinds' declared out-of-plane width (``StudyKind.width_key``, ``flexopt retrim``'s default
``--key``): doubling it doubles every force, moment, torque and stiffness column of ``flexopt
evaluate`` (stresses and motions stay), and ``flexopt retrim`` writes the scaled width."""

from __future__ import annotations

import re

import numpy as np
import pytest
import yaml
from flexopt.pipeline.studies import get_kind

#: (example, the kind's width key, the measured curve's two columns)
CASES = [
    ("cantilever", "geometry.width_mm", ("displacement_mm", "force_N")),
    ("cantilever-stop", "geometry.width_mm", ("displacement_mm", "force_N")),
    ("flexure-pivot", "geometry.width_mm", ("rotation_deg", "torque_Nmm")),
    ("leaf-spring-joint", "geometry.width_mm", ("deflection_deg", "torque_Nm_sliding_l28")),
]
FORCE_LIKE = re.compile(r"force|torque|moment|stiffness")


def value_at(study, key):
    from flexopt.pipeline.study_edit import study_data

    node = study_data(study)
    for part in key.split("."):
        node = node[part]
    return float(node)


@pytest.mark.parametrize(("example", "key", "curve"), CASES, ids=[c[0] for c in CASES])
def test_doubling_the_width_doubles_every_force(tmp_path, example, key, curve):
    import flexopt
    from flexopt.pipeline.cli import main

    base = flexopt.evaluate(example, out=tmp_path / "base")
    assert get_kind(base.study.kind).width_key == key
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
    x = np.asarray(base.table[curve[0]], dtype=float)[1:]
    y = 0.8 * np.asarray(base.table[curve[1]], dtype=float)[1:]
    lines = [",".join(curve)] + [f"{a:.9g},{b:.9g}" for a, b in zip(x, y, strict=True)]
    (tmp_path / "measured.csv").write_text("\n".join(lines) + "\n")
    assert main(["retrim", str(tmp_path / "base"), str(tmp_path / "measured.csv")]) == 0
    written = yaml.safe_load((tmp_path / "base" / "retrimmed.yaml").read_text())
    node = written
    for part in key.split("."):
        node = node[part]
    assert float(node) == pytest.approx(width / 0.8, rel=1e-6)
