"""A gripper's robustness samples perturb the part as made (issue 25, session 25 item 4).

The gripper resolves its constant-force study per study: with ``rescale_width`` it scales the
beam's width B so that the base design's plateau holds the target force. A scatter sample of E
rebuilds the gripper's problem from the perturbed study, and that resolution re-scales B for the
sample's E: if the sample's design took that B, an E x 1.1 sample would be put back on the
target and the E scatter cancelled (an optimistic robustness share). The printed part does not
get re-solved per sample: the sample solves the *design vector* of the nominal design (its B
included, solved once at the nominal E), moved only by the print's thickness and width
tolerances. The exact check: the beam is driven by displacement and is linear elastic, so at a
fixed geometry every force and stress is proportional to E: an E x 1.1 sample's force and peak
stress are the nominal's times 1.1, row by row.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml
from flexopt.pipeline.problems import build_base_problem, nominal_design
from flexopt.pipeline.robustness import SampleProblem, WorstCaseProblem
from flexopt.pipeline.study import validate_study

ROOT = Path(__file__).resolve().parents[2]
RAW = yaml.safe_load((ROOT / "pipeline/examples/gripper.yaml").read_text("utf-8"))


@pytest.fixture(scope="module")
def gripper():
    raw = copy.deepcopy(RAW)
    raw["robustness"] = {"E_percent": 10.0}  # corners: the nominal, E x 0.9, E x 1.1
    study = validate_study(raw)
    problem = build_base_problem(study)
    return study, problem, nominal_design(problem, study)


def test_an_E_sample_scales_the_force_and_stress_by_E_exactly(gripper):
    study, _, x = gripper
    samples = SampleProblem(study, "design", x)
    nominal = samples.evaluate(np.array([1.0, 0.0, 0.0])).metrics["robustness"].table
    stiffer = samples.evaluate(np.array([1.1, 0.0, 0.0])).metrics["robustness"].table
    np.testing.assert_array_equal(stiffer["displacement_mm"], nominal["displacement_mm"])
    loaded = np.abs(np.asarray(nominal["force_N"])) > 1e-9
    for column in ("force_N", "peak_stress_MPa"):
        ratio = np.asarray(stiffer[column])[loaded] / np.asarray(nominal[column])[loaded]
        np.testing.assert_allclose(ratio, 1.1, rtol=1e-9)


def test_the_worst_case_optimiser_samples_the_same_part(gripper):
    """``objective: worst`` (optimise each design by its worst sample) rebuilds each sample's
    problem from the perturbed study too; the design vector still carries the GA's B."""
    study, problem, x = gripper
    worst = WorstCaseProblem(problem, study)
    rows = [tuple(r) for r in np.asarray(worst.samples)]
    plateau = {}
    for e in (1.0, 1.1):
        row = rows.index((e, 0.0, 0.0))
        sample = worst.inner if row == 0 else worst._problem(row)
        plateau[e] = sample.evaluate(x).metrics["plateau_mean_force_N"]
    assert plateau[1.1] == pytest.approx(1.1 * plateau[1.0], rel=1e-9)
