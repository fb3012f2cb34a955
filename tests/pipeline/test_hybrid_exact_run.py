"""A hybrid ``flexopt run`` of the constant-force example takes the study's exact Jacobians
(the runner passes DesignProblem.jacobian to the optimiser), records them in run.json, and its
report shows the best design's sensitivities from them."""

from __future__ import annotations

import json
from pathlib import Path

from flexopt.pipeline.parallel import ParallelSettings
from flexopt.pipeline.run import prepare_run, run_study
from flexopt.pipeline.study import HybridSpec, load_study

ROOT = Path(__file__).resolve().parents[2]


def test_a_hybrid_constant_force_run_uses_exact_jacobians(tmp_path):
    study = load_study(ROOT / "pipeline" / "examples" / "constant-force.yaml")
    optimiser = study.optimiser.model_copy(
        update={
            "method": "hybrid",
            "hybrid": HybridSpec(ga_n_gen=2, starts=1, max_iter=3, max_evaluations=10),
            "pop_size": 12,
            "n_gen": 4,
        }
    )
    study = study.model_copy(
        update={
            "optimiser": optimiser,
            "fidelity": study.fidelity.model_copy(update={"enabled": False}),
            # the hybrid's exact Jacobian is the sharp beam's: refused with a pad fillet
            "geometry": study.geometry.model_copy(update={"pad_fillet_mm": 0.0}),
        }
    )
    run_study(prepare_run(study), out=tmp_path / "run", parallel=ParallelSettings("serial"))
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    hybrid = record["hybrid"]
    assert hybrid["local"] == "gauss_newton"
    assert hybrid["jacobians"]["exact"] >= 1 and hybrid["jacobians"]["finite_differences"] == 0
    # no Jacobian batch: every gradient-stage design is a trial step, one per batch
    assert hybrid["n_evaluations"]["gradient"] <= 3
    report = (tmp_path / "run" / "report.md").read_text()
    assert "## Sensitivity of the best design" in report and "exact derivatives" in report
    html = (tmp_path / "run" / "report.html").read_text()
    assert 'id="plot-gradient"' in html
