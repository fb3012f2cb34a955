"""A robustness sample outside a variable's bounds (issue 23, class 10): docs/robustness.md says
a sample that cannot be built "meets nothing and is named in the record"; it must not make
``flexopt evaluate`` refuse the study with a message about bounds the user did not get wrong.
"""

from __future__ import annotations

import json
import re

from flexopt.pipeline.cli import main
from flexopt.pipeline.study import resolve_study_path


def _at_the_bound(tmp_path):
    """parallel-guide with its leaves at the upper bound of their thickness variable (2.5 mm),
    small meshes, and a thickness scatter of +-0.1 mm: the + sample is 2.6 mm."""
    text = resolve_study_path("parallel-guide").read_text(encoding="utf-8")
    for old, new in (
        ("thickness_mm: 1.8, elements: 20", "thickness_mm: 2.5, elements: 4"),
        ("steps: 20", "steps: 6"),
    ):
        assert old in text, old
        text = text.replace(old, new)
    # the thickness variable (the first) starts from the geometry's 2.5 mm, not its seed
    text, n = re.subn(r"(?m)^(    )(initial: [-0-9.]+)", r"\1# \2", text, count=1)
    assert n == 1
    text += "robustness: {method: corners, thickness_mm: 0.1, share_percent: 95}\n"
    text += "parallel: {workers: 1}\n"  # the samples in this process: no pool to start
    path = tmp_path / "guide.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_sample_past_a_variables_bound_is_a_failed_sample_not_a_refused_study(tmp_path, capsys):
    out = tmp_path / "ev"
    assert main(["evaluate", str(_at_the_bound(tmp_path)), "--out", str(out)]) == 0, (
        capsys.readouterr().err
    )
    record = json.loads((out / "evaluation.json").read_text())["robustness"]
    assert record["n_failed"] == 1
    reasons = {s["thickness_delta_mm"]: s["reason"] for s in record["samples"]}
    assert reasons[0.0] == "" and reasons[-0.1] == ""
    assert "the sample cannot be built" in reasons[0.1] and "2.6" in reasons[0.1]
    bad = next(s for s in record["samples"] if s["thickness_delta_mm"] == 0.1)
    assert bad["met"] == 0  # it meets nothing
    assert "thickness ±0.1 mm: geometry.beams.upper.thickness_mm" in record["perturbed"][0]
