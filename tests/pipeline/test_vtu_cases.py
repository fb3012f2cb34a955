"""Every load case of a mechanism in design.vtu / best.vtu (issue #26 item 5): the first case
in ``design.vtu`` / ``design.pvd``, every other case ``CASE`` in ``design_CASE.vtu`` /
``design_CASE.pvd`` with its steps in ``design_steps/design_CASE_KKK.vtu``, each file naming
its case in the field data.

gripper-amplifier has two cases (``free``, ``blocked``); per load step of each, read back with
meshio, the largest ``stress_judged_MPa`` is that case's row of ``peak_stress_MPa`` (the figure
the verdict reads) and the collection's timesteps are the case's drive column.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest
from flexopt.pipeline.problems import study_result
from flexopt.pipeline.study import load_study
from flexopt.pipeline.vtu import JUDGED, LOAD_CASE_NOTE, case_slug, vtu_files, vtu_makers


@pytest.fixture(scope="module")
def two_cases():
    study = load_study("gripper-amplifier")
    assert list(study.load_cases) == ["free", "blocked"]
    return study_result(study, 1)


def _write(files: dict[str, bytes], folder: Path) -> None:
    for name, data in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)


def test_every_load_case_is_its_own_collection(two_cases, tmp_path: Path) -> None:
    result = two_cases
    files = vtu_files(result, "design")
    assert {"design.vtu", "design.pvd", "design_blocked.vtu", "design_blocked.pvd"} <= set(files)
    assert sorted(files) == sorted(vtu_makers(result, "design"))  # a run folder's names alike
    _write(files, tmp_path)
    for stem, case in (("design", "free"), ("design_blocked", "blocked")):
        table = result.cases[case].table
        drive = np.asarray(table[result.cases[case].plot["x"]], dtype=float)
        root = ET.parse(tmp_path / f"{stem}.pvd").getroot()
        sets = list(root.iter("DataSet"))
        assert len(sets) == len(drive)
        np.testing.assert_allclose([float(d.get("timestep")) for d in sets], drive, rtol=1e-12)
        peaks = []
        for d in sets:
            assert d.get("file").startswith(f"design_steps/{stem}_")
            mesh = meshio.read(tmp_path / d.get("file"), file_format="vtu")
            assert f"{LOAD_CASE_NOTE}{case}" in mesh.field_data
            nodes = np.unique(mesh.cells_dict["line"])
            peaks.append(np.nanmax(mesh.point_data[JUDGED][nodes]))
        np.testing.assert_allclose(peaks, table["peak_stress_MPa"], rtol=1e-9, atol=1e-9)
        whole = meshio.read(tmp_path / f"{stem}.vtu", file_format="vtu")
        assert f"{LOAD_CASE_NOTE}{case}" in whole.field_data
    # the blocked jaw ends elsewhere than the free one: not the first case drawn twice
    # (on the beams' line nodes: the first case's file also carries the plane-stress check's
    # triangles, the other cases' do not)
    moved = []
    for stem in ("design", "design_blocked"):
        mesh = meshio.read(tmp_path / f"{stem}.vtu", file_format="vtu")
        moved.append(mesh.point_data["displacement_mm"][np.unique(mesh.cells_dict["line"])])
    assert moved[0].shape == moved[1].shape
    assert not np.allclose(moved[0], moved[1], equal_nan=True)


def test_case_names_become_file_names() -> None:
    assert case_slug("blocked") == "blocked"
    assert case_slug("jaw closed / 2") == "jaw_closed_2"
    assert case_slug("///") == "case"
