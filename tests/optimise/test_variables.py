"""Design variables addressed by key path: parsing, expansion, ties, bounds, errors."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.optimise.variables import (
    DesignVariables,
    VariableError,
    VariableSpec,
    format_path,
    parse_path,
    resolve_variables,
)
from pydantic import ValidationError


def _root() -> dict:
    return {
        "geometry": {
            "width_mm": 6.0,
            "elements": 20,
            "beams": {
                "leaf1": {
                    "points_mm": [[0.0, 5.0], [20.0, 5.0], [40.0, 5.0]],
                    "thickness_mm": [1.0, 1.2, 1.4],
                },
                "leaf2": {
                    "points_mm": [[0.0, -5.0], [20.0, -5.0], [40.0, -5.0]],
                    "thickness_mm": [1.0, 1.2, 1.4],
                },
            },
            "bodies": {"shuttle": {"ref_mm": [40.0, 0.0]}},
        }
    }


def _vars(*items: dict) -> DesignVariables:
    return resolve_variables([VariableSpec(**i) for i in items], _root())


def test_parse_and_format_round_trip():
    text = "geometry.beams.leaf1.points_mm[1][0]"
    assert parse_path(text) == ("geometry", "beams", "leaf1", "points_mm", 1, 0)
    assert format_path(parse_path(text)) == text
    assert parse_path("geometry.beams.b.thickness_mm[*]")[-1] == ("*",)
    # the dotted form of list items (no YAML quoting needed in flow mappings)
    assert parse_path("geometry.beams.leaf1.points_mm.1.0") == parse_path(text)
    assert parse_path("geometry.beams.b.thickness_mm.*") == parse_path(
        "geometry.beams.b.thickness_mm[*]"
    )
    for bad in ("", ".geometry", "geometry..x", "geometry.x[a]", "geometry x", "[0].x"):
        with pytest.raises(ValueError):
            parse_path(bad)


def test_one_coordinate_with_a_mirrored_tie():
    dv = _vars(
        {
            "path": "geometry.beams.leaf1.points_mm[1][1]",
            "bounds": [2.0, 8.0],
            "tie": [{"path": "geometry.beams.leaf2.points_mm[1][1]", "factor": -1.0}],
        }
    )
    assert dv.names == ("beams.leaf1.points_mm[1][1]",)
    assert dv.initial.tolist() == [5.0]  # the value the geometry holds
    out = dv.apply(_root(), np.array([7.5]))
    assert out["geometry"]["beams"]["leaf1"]["points_mm"][1] == [20.0, 7.5]
    assert out["geometry"]["beams"]["leaf2"]["points_mm"][1] == [20.0, -7.5]
    # apply copies: the mapping it was given is untouched
    root = _root()
    dv.apply(root, np.array([3.0]))
    assert root == _root()


def test_star_sets_every_thickness_and_a_tie_with_offset():
    dv = _vars(
        {
            "path": "geometry.beams.leaf1.thickness_mm[*]",
            "bounds": [0.8, 2.0],
            "tie": ["geometry.beams.leaf2.thickness_mm[*]"],
        },
        {
            "path": "geometry.bodies.shuttle.ref_mm[0]",
            "bounds": [30, 50],
            "tie": [{"path": "geometry.beams.leaf1.points_mm[2][0]", "offset": 0.5}],
            "initial": 41,
            "name": "shuttle_x_mm",
        },
    )
    assert dv.initial.tolist() == [1.0, 41.0]  # the first thickness; the given initial
    out = dv.apply(_root(), np.array([1.6, 45.0]))["geometry"]
    assert out["beams"]["leaf1"]["thickness_mm"] == [1.6, 1.6, 1.6]
    assert out["beams"]["leaf2"]["thickness_mm"] == [1.6, 1.6, 1.6]
    assert out["bodies"]["shuttle"]["ref_mm"] == [45.0, 0.0]
    assert out["beams"]["leaf1"]["points_mm"][2] == [45.5, 5.0]
    space = dv.space
    assert space.names == ("beams.leaf1.thickness_mm[*]", "shuttle_x_mm")
    assert space.lower.tolist() == [0.8, 30.0] and space.upper.tolist() == [2.0, 50.0]


def test_a_missing_path_names_the_nearest_valid_one():
    with pytest.raises(VariableError) as err:
        _vars({"path": "geometry.beams.leaf1.thicknes_mm[2]", "bounds": [1, 2]})
    assert err.value.path == "variables[0].path"
    assert "geometry.beams.leaf1.thicknes_mm" in err.value.problem
    assert "nearest valid path is geometry.beams.leaf1.thickness_mm" in err.value.problem
    with pytest.raises(VariableError) as err:
        _vars({"path": "geometry.beams.leaf3.points_mm[0][1]", "bounds": [1, 2]})
    assert "leaf3" in err.value.problem and "nearest valid path" in err.value.problem
    with pytest.raises(VariableError, match=r"has 3 items \(0..2\)"):
        _vars({"path": "geometry.beams.leaf1.thickness_mm[3]", "bounds": [1, 2]})
    with pytest.raises(VariableError) as err:
        _vars({"path": "geometry.beams.leaf1.thickness_mm", "bounds": [1, 2]})
    assert "thickness_mm[*]" in err.value.problem
    with pytest.raises(VariableError) as err:
        _vars(
            {
                "path": "geometry.beams.leaf1.points_mm[0][0]",
                "bounds": [-1, 1],
                "tie": [{"path": "geometry.beams.leaf9.points_mm[0][0]"}],
            }
        )
    assert err.value.path == "variables[0].tie[0].path"


def test_bounds_outside_the_physical_range():
    with pytest.raises(VariableError) as err:
        _vars({"path": "geometry.beams.leaf1.thickness_mm[0]", "bounds": [0.0, 2.0]})
    assert err.value.path == "variables[0].bounds" and "must be > 0" in err.value.problem
    with pytest.raises(VariableError, match="must be > 0"):  # a factor can flip the sign
        _vars(
            {
                "path": "geometry.beams.leaf1.points_mm[0][0]",
                "bounds": [0.5, 2.0],
                "tie": [{"path": "geometry.width_mm", "factor": -1}],
            }
        )
    # coordinates may be any sign
    _vars({"path": "geometry.beams.leaf1.points_mm[1][1]", "bounds": [-8.0, 8.0]})
    with pytest.raises(VariableError, match="outside the bounds"):
        _vars({"path": "geometry.width_mm", "bounds": [8.0, 12.0]})  # holds 6
    with pytest.raises(ValidationError, match="swap"):
        VariableSpec(path="geometry.width_mm", bounds=[5, 2])


def test_a_key_takes_one_variable_and_counts_are_not_variables():
    with pytest.raises(VariableError, match="already set by variables\\[0\\]"):
        _vars(
            {"path": "geometry.beams.leaf1.thickness_mm[*]", "bounds": [0.8, 2]},
            {"path": "geometry.beams.leaf1.thickness_mm[1]", "bounds": [0.8, 2]},
        )
    with pytest.raises(VariableError, match="whole number"):
        _vars({"path": "geometry.elements", "bounds": [10, 40]})
    with pytest.raises(VariableError, match="distinct name"):
        _vars(
            {"path": "geometry.width_mm", "bounds": [4, 8], "name": "w"},
            {"path": "geometry.beams.leaf1.thickness_mm[0]", "bounds": [0.8, 2], "name": "w"},
        )


def test_a_point_sliding_along_a_line_is_one_variable_with_factors_and_offsets():
    # p = S + a (E - S) with S = (0, 5), E = (40, 5) + (0, 8): x and y both follow a
    dv = _vars(
        {
            "path": "geometry.beams.leaf1.points_mm[1][0]",
            "factor": 40.0,
            "offset": 0.0,
            "bounds": [0.1, 0.9],
            "tie": [{"path": "geometry.beams.leaf1.points_mm[1][1]", "factor": 8.0, "offset": 5.0}],
        }
    )
    assert dv.initial.tolist() == [0.5]  # (20 - 0) / 40: the geometry's own point
    out = dv.apply(_root(), np.array([0.25]))
    assert out["geometry"]["beams"]["leaf1"]["points_mm"][1] == [10.0, 7.0]
    with pytest.raises(ValidationError, match="factor 0"):
        VariableSpec(path="geometry.width_mm", bounds=[1, 2], factor=0)
