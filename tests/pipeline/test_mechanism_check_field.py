"""The mechanism kind's plane-stress check keeps its field for the reported design (issue #26
item 5): best.vtu / design.vtu draw the exported outline's triangles with the check's state at
every row, beside the beams' lines (docs/mechanism.md, "the check of the part as exported")."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import meshio
import numpy as np
import pytest
from flexopt.pipeline.cli import main

pytestmark = pytest.mark.timeout(600)


def test_parallel_guide_vtu_carries_the_checks_plane_stress_field(tmp_path: Path) -> None:
    """Each load step's largest von Mises over the counted vertices of the triangles is the
    check's plane-stress peak over the vertices times that row's drive (the check is linear),
    read from evaluation.json and response.csv; that vertex peak is at most the check's peak at
    the quadrature points, the figure its stress ratio (and so the verdict) is built from."""
    out = tmp_path / "ev"
    assert main(["evaluate", "parallel-guide", "--out", str(out)]) == 0
    record = json.loads((out / "evaluation.json").read_text())
    check = record["inputs"]["fidelity"]["checks"]["stroke"]
    assert "field" not in check  # the mesh stays out of the json
    nodal = check["plane_stress_peak_nodal_MPa"]  # MPa per mm of drive
    assert 0.0 < nodal <= check["plane_stress_peak_stress_MPa"]
    with (out / "response.csv").open() as fh:
        drive = [float(r["drive_mm"]) for r in csv.DictReader(fh)]
    steps = sorted((out / "design_steps").glob("design_*.vtu"))
    assert len(steps) == len(drive)
    for path, d in zip(steps, drive, strict=True):
        mesh = meshio.read(path)
        assert {c.type for c in mesh.cells} == {"line", "triangle"}
        tri = np.unique(
            np.concatenate([c.data.ravel() for c in mesh.cells if c.type == "triangle"])
        )
        counted = np.zeros(len(mesh.points), dtype=bool)
        counted[tri] = np.asarray(mesh.point_data["stress_counted"])[tri] == 1
        vm = np.asarray(mesh.point_data["von_mises_MPa"], dtype=float)
        peak = float(np.max(vm[counted]))
        assert peak == pytest.approx(nodal * abs(d), rel=1e-9, abs=1e-12)
    assert (out / "stress_deformed.png").is_file()
