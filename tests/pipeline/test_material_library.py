"""The material library as studies see it (fea/materials.py is maintained with the pipeline)."""

from __future__ import annotations

import math

import pytest
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import MATERIALS, get_material
from flexopt.pipeline.study import MaterialSpec


@pytest.mark.parametrize("name", list(MATERIALS))
def test_library_records_are_complete(name):
    mat = MATERIALS[name]
    assert mat.name == name
    assert mat.E_MPa > 0 and 0 < mat.nu < 0.5 and mat.yield_MPa > 0
    assert math.isfinite(mat.density_kg_m3) and mat.density_kg_m3 > 0
    assert len(mat.source) > 10, "every number needs a named source"
    # Sanity: yield strain between 0.2 % (metals) and 5 % (polymers).
    assert 2e-3 < mat.yield_MPa / mat.E_MPa < 5e-2


def test_required_materials_are_in_the_library():
    for name in ("ABS", "PLA", "PETG", "PA12", "65Mn", "17-4PH H900", "maraging 300", "ti6al4v"):
        assert get_material(name).name in MATERIALS


def test_lookup_ignores_case_and_separators():
    assert get_material("ti_6al_4v") is MATERIALS["Ti-6Al-4V"]
    assert get_material("pla") is MATERIALS["PLA"]
    with pytest.raises(FeaError, match="choose one of"):
        get_material("unobtainium")


def test_library_name_resolves_to_the_full_record():
    from flexopt.pipeline.study import Study

    class _Only(Study):
        geometry: None = None  # type: ignore[assignment]

    study = _Only.model_validate({"name": "m", "material": "petg"})
    assert study.material == MaterialSpec(
        **{
            k: getattr(MATERIALS["PETG"], k)
            for k in ("name", "E_MPa", "nu", "yield_MPa", "density_kg_m3", "source")
        }
    )
    assert study.material.to_material() == MATERIALS["PETG"]
