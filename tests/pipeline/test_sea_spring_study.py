"""The ``sea_spring`` study kind: schema errors, the two stages' contract, a quick smoke run."""

from __future__ import annotations

import copy
import math
import pickle
from pathlib import Path

import flexopt.pipeline as pipeline
import flexopt.pipeline.studies.sea_spring as ss
import numpy as np
import pytest
import yaml
from flexopt.fea.spring_analysis import analyse_spring, slot_gaps_mm, stress_map_data
from flexopt.geometry.arm_spring import SPIRAL_VARIABLES
from flexopt.geometry.sea_spring import (
    GA_VARIABLES,
    TABLE9_BOUNDS,
    build_spring,
    params_from_vector,
)
from flexopt.optimise import DesignProblem
from flexopt.optimise.sea_cost import levels_to_values
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.plots import plot_field, plot_field_deformed
from flexopt.pipeline.study import list_examples, load_study, validate_study

EXAMPLES = Path(pipeline.__file__).parent / "examples"
MINIMAL = {
    "name": "sea",
    "geometry": {"kind": "sea_spring", "n_sets": 4},
    "material": "maraging-300",
    "taguchi": {"enabled": False},
}
MID = np.array([0.5 * (lo + hi) for lo, hi in TABLE9_BOUNDS.values()])
SPIRAL_GEOMETRY = {"kind": "sea_spring", "topology": "spiral", "n_sets": 4}


def study_with(**changes):
    raw = copy.deepcopy(MINIMAL)
    raw.update(changes)
    return validate_study(raw)


@pytest.mark.parametrize(
    ("changes", "path", "words"),
    [
        ({"design_space": {"s1": [1, 2]}}, "design_space.s1", ["unknown design variable", "'S1'"]),
        ({"design_space": {"S1": [2, 1]}}, "design_space.S1", ["swap"]),
        ({"design_space": {"alpha": [50, 95]}}, "design_space.alpha", ["4 sets", "90"]),
        ({"target": {"stiffnes_Nm_per_rad": 275}}, "target.stiffnes_Nm_per_rad", ["unknown key"]),
        ({"target": {"stiffness_Nm_per_rad": None}}, "", ["stiffness_window"]),
        ({"design": {"R9": 3.0}}, "design.R9", ["unknown design variable"]),
        ({"design": {"R5": 35.5}}, "design", ["envelope"]),
        (
            {"geometry": SPIRAL_GEOMETRY, "design_space": {"R1": [9, 12]}},
            "design_space.R1",
            ["unknown design variable", "sweep", "R_pad"],
        ),
        (
            {"geometry": SPIRAL_GEOMETRY, "design_space": {"F1": [0.2, 1.1]}},
            "design_space.F1",
            ["fraction"],
        ),
        ({"geometry": SPIRAL_GEOMETRY, "design": {"R_pad": 34.0}}, "design", ["envelope_mm"]),
        (
            {"geometry": {"kind": "sea_spring", "topology": "helix"}},
            "geometry.topology",
            ["serpentine", "spiral"],
        ),
    ],
)
def test_bad_studies_name_the_key(changes, path, words):
    with pytest.raises(StudyError) as info:
        study_with(**changes)
    assert info.value.path == path
    for w in words:
        assert w in str(info.value)


def test_examples_validate():
    assert {"sea-spring", "sea-spring-quick", "sea-spring-serpentine"} <= set(list_examples())
    for name in ("sea-spring", "sea-spring-quick", "sea-spring-serpentine"):
        study = load_study(name)
        assert study.kind == "sea_spring"
        assert study.target.stiffness_Nm_per_rad == 275.0
    for name in ("sea-spring", "sea-spring-serpentine"):
        raw = yaml.safe_load((EXAMPLES / f"{name}.yaml").read_text())
        assert raw["taguchi"]["torque_Nm"] == 10.0
    assert load_study("sea-spring").geometry.topology == "spiral"
    assert load_study("sea-spring-serpentine").geometry.topology == "serpentine"


def test_stiffness_target_from_the_window():
    s = study_with(
        target={"stiffness_Nm_per_rad": None},
        stiffness_window={"required_bandwidth_Hz": 4.0, "pick": "k_max"},
    )
    k, src = ss.target_stiffness_Nm_per_rad(s)
    # docs/sea_window.md: walking impact at 46.86 rpm, no spring torque -> K_max 240.5
    assert k == pytest.approx(240.5, rel=5e-3) and src["k_min"] == pytest.approx(207.5, rel=5e-3)


COARSE = {"max_edge_mm": 4.0, "fillet_segments": 1}  # keeps the FE tests quick


def test_problem_contract_and_geometry_violations_skip_the_fe():
    prob = ss.SeaSpringProblem(study_with())
    assert isinstance(prob, DesignProblem)
    # thickness: solve (default): ST is computed, 17 variables, objectives stress and mass
    assert prob.space.n_var == 17 and prob.space.names[-1] == "alpha_deg"
    assert prob.objective_names == ("peak_stress_MPa", "mass_g")
    assert prob.theta == pytest.approx(math.radians(11.04), rel=2e-3)
    pickle.loads(pickle.dumps(prob))
    x = MID[:-1].copy()
    x[GA_VARIABLES.index("R5")] = 35.5
    ev = prob.evaluate(x)
    assert not ev.feasible and ev.reason == "" and ev.g[0] > 0 and ev.time_s < 0.5
    search = ss.SeaSpringProblem(study_with(thickness="search"))
    assert search.space.n_var == 18 and search.objective_names[1] == "stiffness_error_percent"


def test_stage1_runs_on_first_use_and_never_for_flexopt_evaluate(monkeypatch):
    """Building the problem runs no Taguchi stage (flexopt evaluate, export and the API build it
    too); the first use that needs it (the run's initial designs, the sets of a design) runs it
    once, and a pickled problem carries its result. flexopt evaluate's result (the nominal
    design, :func:`pipeline.problems.study_result`) never runs it: its sets are the study's."""
    from flexopt.pipeline.problems import study_result

    calls = []

    def stage1(study):
        calls.append(study.name)
        return {"chosen": {"RP": 3}}

    monkeypatch.setattr(ss, "run_taguchi", stage1)
    raw = {**MINIMAL, "geometry": {"kind": "sea_spring", "n_sets": None},
           "mesh": {**COARSE, "curve_steps": 1}, "taguchi": {"enabled": True},
           "target": {"directions": "positive"}, "solid_3d": {"check": False}}  # fmt: skip
    prob = ss.SeaSpringProblem(validate_study(raw))
    assert calls == []
    assert prob.n_sets == 3 and calls == ["sea"]
    again = pickle.loads(pickle.dumps(prob))
    assert again.n_sets == 3 and again.stage1 == {"chosen": {"RP": 3}} and calls == ["sea"]
    assert ss.SeaSpringProblem(validate_study(raw), stage1={}).n_sets == 4  # design_sets
    monkeypatch.setattr(ss, "run_taguchi", lambda study: pytest.fail("stage 1 ran"))
    result = study_result(validate_study(raw))
    assert result.inputs["n_sets"] == 4 and result.converged, result.message
    assert result.summary["stiffness_Nm_per_rad"] == pytest.approx(275.0, rel=1e-9)


def test_solved_thickness_meets_the_stiffness_and_linear_agrees_at_one_degree():
    prob = ss.SeaSpringProblem(study_with(mesh=COARSE, target={"directions": "positive"}))
    geom = build_spring(params_from_vector(MID, 4), prob.frame)
    small = analyse_spring(geom, prob.material, math.radians(1.0), prob.study.mesh)
    assert small.ok
    # 2 % required; geometric nonlinearity at 1 degree is about 0.6 % (chiral serpentine)
    assert small.stiffness_Nm_per_rad == pytest.approx(small.linear_stiffness_Nm_per_rad, rel=0.02)
    ev = prob.evaluate(MID[:-1])
    assert ev.reason == "", ev.reason
    # torque is proportional to ST in plane stress, so the solved ST hits the target exactly
    assert ev.metrics["stiffness_Nm_per_rad"] == pytest.approx(275.0, rel=1e-9)
    assert ev.f[0] == ev.metrics["peak_stress_MPa"] and ev.f[1] == ev.metrics["mass_g"]
    p = params_from_vector(prob.full_vector(MID[:-1], ev.metrics["ST_mm"]), 4)
    again = analyse_spring(build_spring(p, prob.frame), prob.material, prob.theta, prob.study.mesh)
    assert again.stiffness_Nm_per_rad == pytest.approx(275.0, rel=1e-5)
    assert again.peak_stress_MPa[-1] == pytest.approx(ev.f[0], rel=1e-5)


def test_stress_map_png_is_drawn():
    prob = ss.SeaSpringProblem(study_with(mesh={"max_edge_mm": 4.0, "fillet_segments": 1}))
    geom = build_spring(params_from_vector(MID, 4), prob.frame)
    r = analyse_spring(geom, prob.material, 0.05, prob.study.mesh, keep_model=True)
    data = stress_map_data(r)
    assert len(data["von_mises_MPa"]) == len(data["points_mm"])
    png = plot_field(data["points_mm"], data["triangles"], data["von_mises_MPa"], limit=800.0)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    # the displacement of the same solve at the vertices: the hub turned by 0.05 rad about
    # the centre (the nonlinear rigid rotation), the pads held
    p, u = np.asarray(data["points_mm"]), np.asarray(data["displacement_mm"])
    c, s = np.cos(0.05), np.sin(0.05)
    rigid = p @ np.array([[c, -s], [s, c]]).T - p
    assert u.shape == p.shape
    assert np.sum(np.hypot(*(u - rigid).T) < 1e-4) > 20  # points rounded to 1e-4 mm
    assert np.sum(np.hypot(*u.T) == 0) > 10
    png = plot_field_deformed(p, data["triangles"], data["von_mises_MPa"], u, limit=800.0)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
@pytest.mark.e2e
def test_quick_example_runs_end_to_end(tmp_path):
    """`flexopt run sea-spring-quick --quick`, on a coarse mesh and one direction to stay quick."""
    import json

    import trimesh
    from flexopt.pipeline.cli import main

    raw = yaml.safe_load((EXAMPLES / "sea-spring-quick.yaml").read_text())
    raw["mesh"].update(COARSE, curve_steps=1)
    raw["target"]["directions"] = "positive"
    raw["optimiser"].update(quick_pop_size=3, quick_n_gen=1)
    study = tmp_path / "quick.yaml"
    study.write_text(yaml.safe_dump(raw))
    out = tmp_path / "run"
    assert main(["run", str(study), "--quick", "--out", str(out), "-q"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished"
    best = json.loads((out / "best.json").read_text())
    info = best["info"]
    assert info["outer_diameter_mm"] <= 72.0 + 1e-6
    assert {
        "best.stl",
        "force_displacement.png",
        "stress_map.png",
        "stress_deformed.png",
        "report.md",
        "best.vtu",
    } <= set(record["files"])
    assert "stress_map" not in info  # drawn as stress_map.png, not stored in best.json
    assert trimesh.load(out / "best.stl").is_watertight


SPIRAL = {"name": "sea-spiral", "geometry": SPIRAL_GEOMETRY, "material": "maraging-300",
          "taguchi": {"enabled": False}}  # fmt: skip
SPIRAL_DESIGN = {"sweep": 300.0, "R_pad": 30.0, "F1": 1 / 3, "F2": 0.5,
                 "W1": 3.0, "W2": 2.5, "W3": 2.5, "W4": 3.0}  # fmt: skip


def test_spiral_problem_contract_and_solved_thickness():
    raw = copy.deepcopy(SPIRAL)
    raw.update(mesh=COARSE, design=SPIRAL_DESIGN)
    prob = ss.SeaSpringProblem(validate_study(raw))
    assert isinstance(prob, DesignProblem)
    assert prob.space.names == ("sweep_deg", "R_pad_mm", "F1_fraction", "F2_fraction",
                                "W1_mm", "W2_mm", "W3_mm", "W4_mm")  # fmt: skip
    assert prob.constraint_names[:4] == ("envelope_mm", "thinnest_mm", "slot_mm", "hub_mm")
    pickle.loads(pickle.dumps(prob))
    x0 = prob.initial_designs()[0]
    assert np.allclose(x0, [SPIRAL_DESIGN[n] for n in SPIRAL_VARIABLES[:-1]])
    ev = prob.evaluate(x0)
    assert ev.reason == "", ev.reason  # solved (feasible or not: ST may leave 8-20 mm)
    # both directions: the solved ST makes the mean secant stiffness the target
    assert ev.metrics["stiffness_Nm_per_rad"] == pytest.approx(275.0, rel=1e-9)
    k_ccw, k_cw = ev.metrics["stiffness_ccw_Nm_per_rad"], ev.metrics["stiffness_cw_Nm_per_rad"]
    assert 0.5 * (k_ccw + k_cw) == pytest.approx(275.0, rel=1e-9) and k_ccw != k_cw
    # the geometric check comes before the FE: a pad outside the envelope costs no solve
    bad = x0.copy()
    bad[prob.names.index("R_pad")] = 34.0
    ev_bad = prob.evaluate(bad)
    assert not ev_bad.feasible and ev_bad.g[0] > 0 and ev_bad.time_s < 0.5


def test_spiral_screening_run_builds_or_explains_every_l25_row():
    from flexopt.optimise.taguchi import select_array

    study = validate_study(SPIRAL)
    frame = ss.spring_frame(study)
    table = ss.topology(study).levels
    lay = select_array({n: len(v) for n, v in table.items()})
    built = 0
    for row in lay.design:
        values = levels_to_values(row, table)
        p = ss.topology(study).screen_params(values, frame)
        try:
            ss.build(p, frame)
            built += 1
        except ss.GeometryError as exc:
            assert "fails by" in str(exc) or "polygon" in str(exc) or "holes" in str(exc)
    assert built >= 12  # most of the array is a spring; the rest imputes the worst cost


def test_spiral_taguchi_stage_effects_contributions_and_plot():
    raw = copy.deepcopy(SPIRAL)
    raw["geometry"] = {**SPIRAL_GEOMETRY, "n_sets": None}
    raw.update(mesh=COARSE, taguchi={"enabled": True, "extra_runs": 2})
    stage1 = ss.run_taguchi(validate_study(raw))
    assert stage1["array"].startswith("L25") and stage1["topology"] == "spiral"
    sn = np.array(stage1["runs"]["sn_dB"])
    for name, effect in stage1["main_effects"].items():
        assert len(effect["sn_dB"]) == 5 == len(effect["levels"]), name
        # a balanced array: the mean of the level means is the grand mean
        assert np.mean(effect["sn_dB"]) == pytest.approx(sn.mean(), abs=1e-9), name
    parts = [r["percent"] for r in stage1["anova"] if r["source"] not in ("total", "error")]
    pooled = [r for r in stage1["anova"] if r.get("pooled")]
    error = next(r for r in stage1["anova"] if r["source"] == "error")
    total = sum(parts) + error["percent"] - sum(r["percent"] for r in pooled)
    assert total == pytest.approx(100.0, abs=1e-6)
    assert stage1["chosen"]["RP"] in (2, 3, 4, 5, 6)
    from flexopt.pipeline.plots import plot_taguchi

    png = plot_taguchi(stage1["main_effects"], stage1["anova"])
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_slot_gap_of_a_u_shape_closes_by_what_the_prong_moves():
    # A U: two 2 mm prongs 20 mm long, a 1.0 mm slot between them, joined at x < 0.
    from flexopt.fea.materials import get_material
    from flexopt.fea.mesh import mesh_polygon
    from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Translate
    from shapely.geometry import LineString, box

    u_shape = box(-3.0, 0.0, 20.0, 5.0).difference(box(0.0, 2.0, 21.0, 3.0))
    mesh = mesh_polygon(u_shape, 0.5)
    model = PlaneStressModel(
        mesh, get_material("PLA"), 1.0, Clamp(LineString([(-3, 0), (-3, 5)])),
        Translate(LineString([(20, 3), (20, 5)]), (0.0, 1.0), 0.1, 1),
    )  # fmt: skip
    zero = np.zeros(model.n_dofs)
    move = np.zeros(model.n_dofs)
    upper = model.xy[:, 1] > 2.5  # the upper prong (and the top of the join)
    move[model.iy[upper]] = -0.3 * np.clip(model.xy[upper, 0] / 20.0, 0.0, 1.0)  # tip down 0.3
    shift = np.zeros(model.n_dofs)
    shift[model.ix], shift[model.iy] = 0.7, -0.4  # a rigid translation changes nothing
    g = slot_gaps_mm(model, {"zero": zero, "tip": move, "shift": shift}, u_shape)
    assert g["undeformed"] == pytest.approx(1.0, abs=1e-9)
    assert g["zero"] == pytest.approx(1.0, abs=1e-9) and g["shift"] == pytest.approx(1.0, abs=1e-9)
    assert g["tip"] == pytest.approx(0.7, abs=0.01)


def test_a_slot_wider_than_the_reach_unloaded_is_watched_when_it_closes():
    # A U with a 4.0 mm slot (wider than slot_pairs' 3 mm reach) whose upper prong's tip moves
    # down by 3.6 mm (the prong bent as a cantilever, v = d (x/L)^2 (3 - x/L) / 2): the loaded
    # slot is the tip's 0.4 mm, which the pairs of the unloaded part alone did not see
    # (session 30: sea-spring's windings passed into each other across a 3.26 mm slot).
    from flexopt.fea.materials import get_material
    from flexopt.fea.mesh import mesh_polygon
    from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Translate
    from flexopt.fea.spring_analysis import slot_pairs
    from shapely.geometry import LineString, box

    u_shape = box(-3.0, 0.0, 20.0, 8.0).difference(box(0.0, 2.0, 21.0, 6.0))
    mesh = mesh_polygon(u_shape, 0.5)
    model = PlaneStressModel(
        mesh, get_material("PLA"), 1.0, Clamp(LineString([(-3, 0), (-3, 8)])),
        Translate(LineString([(20, 6), (20, 8)]), (0.0, 1.0), 0.1, 1),
    )  # fmt: skip
    bend = np.zeros(model.n_dofs)
    upper = model.xy[:, 1] > 4.0
    r = np.clip(model.xy[upper, 0] / 20.0, 0.0, 1.0)
    bend[model.iy[upper]] = -3.6 * r**2 * (3.0 - r) / 2.0
    # the pairs within 3 mm unloaded (across the 2 mm prongs, around the corners) miss it
    base = slot_pairs(model, u_shape)
    moved = model.xy + np.column_stack([bend[model.ix], bend[model.iy]])
    assert np.hypot(*(moved[base[:, 0]] - moved[base[:, 1]]).T).min() > 1.5
    g = slot_gaps_mm(model, {"bent": bend, "zero": np.zeros(model.n_dofs)}, u_shape)
    # the bottom corners of the tip (y = 6 - 3.6) against the lower prong's top (y = 2)
    assert g["bent"] == pytest.approx(0.4, abs=1e-9)
    assert g["undeformed"] == g["zero"]  # unloaded: the prongs' 2 mm, as before
    # the unloaded pairs come first and in their order: a slot within reach is measured as it was
    narrow = box(-3.0, 0.0, 20.0, 5.0).difference(box(0.0, 2.0, 21.0, 3.0))
    m2 = PlaneStressModel(
        mesh_polygon(narrow, 0.5), get_material("PLA"), 1.0,
        Clamp(LineString([(-3, 0), (-3, 5)])),
        Translate(LineString([(20, 3), (20, 5)]), (0.0, 1.0), 0.1, 1),
    )  # fmt: skip
    base = slot_pairs(m2, narrow)
    down = np.zeros(m2.n_dofs)
    down[m2.iy[m2.xy[:, 1] > 2.5]] = -2.5  # the upper prong's top within 3 mm of the bottom
    more = slot_pairs(m2, narrow, [down])
    assert len(more) > len(base)
    np.testing.assert_array_equal(more[: len(base)], base)


def test_slot_gaps_from_the_segment_tree_equal_the_whole_ring_measurement():
    # A serpentine with round bends (a ring of ~100 vertices, slots 1.2 mm wide) under random
    # displacements: the nodes found on the outline through the ring's segment tree, and their
    # positions along it, must give exactly the gaps of measuring every node against the ring.
    import math

    import shapely
    from flexopt.fea.materials import get_material
    from flexopt.fea.mesh import mesh_polygon
    from flexopt.fea.plane_stress import Clamp, PlaneStressModel, Translate
    from scipy.spatial import cKDTree
    from shapely.geometry import LineString

    path = LineString([(0, 0), (20, 0), (20, 3), (0, 3), (0, 6), (20, 6)])
    shape = path.buffer(0.9, cap_style="flat", quad_segs=8)
    model = PlaneStressModel(
        mesh_polygon(shape, 0.5), get_material("PLA"), 1.0,
        Clamp(LineString([(0, -0.9), (0, 0.9)])),
        Translate(LineString([(20, 5.1), (20, 6.9)]), (0.0, 1.0), 0.1, 1),
    )  # fmt: skip
    rng = np.random.default_rng(4)
    states = {f"s{k}": 0.2 * rng.standard_normal(model.n_dofs) for k in range(3)}

    def whole_ring(states):  # the measurement as it was: every node against the whole ring
        xy, ring = np.asarray(model.xy), shape.exterior
        idx = np.flatnonzero(np.asarray(shapely.distance(shapely.points(xy), ring)) < 1e-6)
        pts = xy[idx]
        s = np.asarray(shapely.line_locate_point(ring, shapely.points(pts)))
        pairs = cKDTree(pts).query_pairs(3.0, output_type="ndarray")
        ds = np.abs(s[pairs[:, 0]] - s[pairs[:, 1]])
        pairs = pairs[np.minimum(ds, ring.length - ds) > 9.0]
        out = {"undeformed": float(np.hypot(*(pts[pairs[:, 0]] - pts[pairs[:, 1]]).T).min())}
        for name, u in states.items():
            p = pts + np.column_stack([u[model.ix][idx], u[model.iy][idx]])
            out[name] = float(np.hypot(*(p[pairs[:, 0]] - p[pairs[:, 1]]).T).min())
        return out

    got = slot_gaps_mm(model, states, shape)
    assert got == whole_ring(states)
    assert math.isclose(got["undeformed"], 1.2, abs_tol=0.05)  # 3 mm pitch - 1.8 mm legs
    assert len(set(got.values())) == 4  # the states move the gap: a real comparison
