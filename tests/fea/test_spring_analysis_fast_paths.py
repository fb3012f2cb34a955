"""The shortcuts of one SEA-spring evaluation (issue 13) give the answers of the long way round.

Each shortcut is checked against the work it replaces, done in the test: the sparsity pattern
against the sort of every element entry, the stress mask against the exact test of every
triangle, the solved-ST geometry against a rebuild at that ST, the spring analysis (both
directions, slot gaps) against fresh models per direction and the whole-ring slot measurement.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import shapely
from flexopt.fea.mesh import mesh_polygon
from flexopt.fea.plane_stress import (
    Clamp,
    PlaneStressModel,
    PlaneStressSettings,
    Rotate,
    _compiled,
)
from flexopt.fea.spring_analysis import analyse_spring, slot_gaps_mm
from flexopt.pipeline.studies.sea_spring import SeaSpringProblem, build
from flexopt.pipeline.study import load_study


@pytest.fixture(scope="module")
def problem() -> SeaSpringProblem:
    """The quick SEA study's problem (two spiral arms) on a coarse mesh (~0.1 s a design):
    the checks are of equality, not of accuracy."""
    study = load_study("sea-spring-quick")
    mesh = study.mesh.model_copy(update={"max_edge_mm": 6.0, "elements_through": 0.5})
    return SeaSpringProblem(study.model_copy(update={"mesh": mesh}))


@pytest.fixture(scope="module")
def designs(problem) -> list[np.ndarray]:
    """The study's design and another inside the bounds, both buildable."""
    x0 = problem.nominal_design()
    span = problem.space.upper - problem.space.lower
    out = [x0]
    rng = np.random.default_rng(3)
    while len(out) < 2:
        x = problem.space.clip(x0 + 0.03 * span * rng.standard_normal(x0.size))
        ev = problem.evaluate(x)
        if not ev.reason and ev.metrics.get("buildable", True):
            out.append(x)
    return out


@pytest.fixture(scope="module")
def spring(problem):
    """The study design's geometry and a kept model solved both ways."""
    p = problem.params(problem.nominal_design())
    geom = build(p, problem.frame)
    r = analyse_spring(geom, problem.material, problem.theta, problem.study.mesh, 1, True,
                       keep_model=True, both_directions=True, gaps=True)  # fmt: skip
    return geom, r


def test_paired_pattern_is_the_pattern_of_every_element_entry(spring):
    kernels = _compiled()
    if kernels is None:
        pytest.skip("numba unavailable: the numpy pattern runs")
    asm = spring[1].model._asm
    dofs = asm.dofs.astype(np.int64)
    ns = asm.ns
    assert np.array_equal(dofs[:, ns:], dofs[:, :ns] + 1)  # the paired numbering is in use
    indptr, indices, where = kernels.csr_pattern_paired(dofs[:, :ns] // 2, asm.N // 2)
    # The long way: every element entry (row, col) as one key, sorted and made unique.
    m = dofs.shape[1]
    rows = np.repeat(dofs, m, axis=1).ravel()
    cols = np.tile(dofs, (1, m)).ravel()
    keys, inverse = np.unique(rows * asm.N + cols, return_inverse=True)
    assert np.array_equal(indices, keys % asm.N)
    assert np.array_equal(indptr, np.searchsorted(keys // asm.N, np.arange(asm.N + 1)))
    assert np.array_equal(where, inverse.ravel())
    # and the general kernel agrees with both
    for a, b in zip(kernels.csr_pattern(dofs, asm.N), (indptr, indices, where), strict=True):
        assert np.array_equal(a, b)


def test_stress_mask_is_the_exact_test_of_every_triangle(spring):
    geom, r = spring
    model = r.model
    ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)
    tris = shapely.polygons(model.mesh.points[model.mesh.triangles])
    expected = ~shapely.intersects(ignore, tris)
    assert np.array_equal(model._stress_mask, expected)
    assert 0 < (~expected).sum() < expected.size  # the footprints do leave elements out


def test_both_directions_equal_a_fresh_model_per_direction(problem, spring):
    geom, r = spring
    ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)
    mesh_spec = problem.study.mesh
    # analyse_spring's mesh: the clamp and drive discs on element edges
    mesh = mesh_polygon(geom.fe_outline, mesh_spec.max_edge_mm, refine=geom.mesh_regions(
        mesh_spec.elements_through, mesh_spec.max_edge_mm), lines=geom.mesh_lines())  # fmt: skip

    def fresh(theta: float, kinematics: str, guess=None):
        model = PlaneStressModel(
            mesh, problem.material, geom.thickness_mm, Clamp(geom.pad_region),
            Rotate(geom.hub_region, (0.0, 0.0), theta, 1),
            settings=PlaneStressSettings(rtol_residual=1e-7), stress_ignore=ignore,
        )  # fmt: skip
        if guess is not None:  # the starting points analyse_spring uses, made on this model
            u_odd, u_even = model.series_predictor(theta)
            guess = guess(u_odd, u_even)
        return model, model.solve(kinematics, guess=guess)

    theta = problem.theta
    _, lin = fresh(theta, "linear")
    _, fwd = fresh(theta, "nonlinear", lambda u_odd, u_even: u_odd + u_even)
    model, back = fresh(-theta, "nonlinear", lambda u_odd, u_even: 2.0 * u_even - fwd.dofs)
    assert fwd.extra["guess"] == "used" and back.extra["guess"] == "used"
    assert r.linear_stiffness_Nm_per_rad == pytest.approx(
        lin.torque_Nmm[-1] / theta * 1e-3, rel=1e-12
    )
    assert np.allclose(r.torque_Nm, fwd.torque_Nmm * 1e-3, rtol=1e-12, atol=0)
    assert np.allclose(r.reverse_torque_Nm, back.torque_Nmm * 1e-3, rtol=1e-12, atol=0)
    assert np.allclose(r.peak_stress_MPa, fwd.peak_nodal_stress_MPa, rtol=1e-12, atol=0)
    assert np.allclose(r.reverse_peak_stress_MPa, back.peak_nodal_stress_MPa, rtol=1e-12, atol=0)
    assert np.array_equal(r.peak_stress_xy_mm, fwd.peak_nodal_stress_xy_mm)
    assert r.reverse_stiffness_Nm_per_rad == pytest.approx(
        back.torque_Nmm[-1] / -theta * 1e-3, rel=1e-12
    )
    # Row 0 (the undeformed state) is measured once per model and served to every solve.
    assert r.torque_Nm[0] == 0.0 and r.reverse_torque_Nm[0] == 0.0
    assert np.array_equal(fwd.peak_nodal_stress_xy_mm[0], lin.peak_nodal_stress_xy_mm[0])
    # The slot gaps: the whole outline ring against every node, as measured before the tree.
    states = {"ccw": r.u, "cw": r.reverse_u}
    xy, ring = np.asarray(r.model.xy), geom.fe_outline.exterior
    idx = np.flatnonzero(np.asarray(shapely.distance(shapely.points(xy), ring)) < 1e-6)
    pts = xy[idx]
    s = np.asarray(shapely.line_locate_point(ring, shapely.points(pts)))
    from scipy.spatial import cKDTree

    moved_pts = [
        pts + np.column_stack([u[r.model.ix][idx], u[r.model.iy][idx]]) for u in states.values()
    ]
    # the pairs within 3 mm unloaded or in either state (session 30: a slot wider than 3 mm
    # unloaded that closes under load is watched too)
    pairs = {
        tuple(q)
        for at in [pts, *moved_pts]
        for q in cKDTree(at).query_pairs(3.0, output_type="ndarray")
    }
    pairs = np.array(sorted(pairs))
    ds = np.abs(s[pairs[:, 0]] - s[pairs[:, 1]])
    pairs = pairs[np.minimum(ds, ring.length - ds) > 9.0]
    expected = {"undeformed": float(np.hypot(*(pts[pairs[:, 0]] - pts[pairs[:, 1]]).T).min())}
    for name, u in states.items():
        moved = pts + np.column_stack([u[r.model.ix][idx], u[r.model.iy][idx]])
        expected[name] = float(np.hypot(*(moved[pairs[:, 0]] - moved[pairs[:, 1]]).T).min())
    assert r.slot_gaps_mm == expected == slot_gaps_mm(r.model, states, geom.fe_outline)
    assert expected["ccw"] != expected["cw"]  # the two states differ: a real comparison


def test_solved_thickness_design_equals_a_rebuild_at_that_thickness(problem, designs, spring):
    for i, x in enumerate(designs):
        ev, (p, geom, r, st) = problem._evaluate(x)
        assert st == p.thickness_mm and st != problem.REFERENCE_THICKNESS_MM
        again = build(problem.params(x, st), problem.frame)  # the second build it replaces
        assert geom.outline.equals_exact(again.outline, 0.0)
        assert geom.fe_outline.equals_exact(again.fe_outline, 0.0)
        assert geom.checks == again.checks
        mass_g = again.mass_kg(problem.material.density_kg_m3) * 1e3
        assert ev.metrics["mass_g"] == pytest.approx(mass_g, rel=1e-12)
        assert ev.metrics["stiffness_Nm_per_rad"] == pytest.approx(problem.k_target, rel=1e-9)
        if i:
            continue
        # The study's design: the torque scales exactly with the thickness from the solve at
        # the reference thickness (the spring fixture's), stress and slots do not change.
        ref = spring[1]
        k = ref.mean_stiffness_Nm_per_rad * st / problem.REFERENCE_THICKNESS_MM
        assert ev.metrics["stiffness_Nm_per_rad"] == pytest.approx(k, rel=1e-12)
        assert ev.metrics["peak_stress_MPa"] == ref.worst_peak_stress_MPa
        assert ev.metrics["deformed_slot_mm"] == min(
            ref.slot_gaps_mm["ccw"], ref.slot_gaps_mm["cw"]
        )


def test_warm_up_loads_the_plane_stress_kernels_before_any_design():
    # In a fresh interpreter (what a pool forks from): no kernel is loaded until the problem's
    # warm_up, then every kernel a design's solve calls is.
    code = (
        "import json\n"
        "from flexopt.fea import _plane_stress_kernels as k\n"
        "from flexopt.pipeline.studies.sea_spring import SeaSpringProblem\n"
        "from flexopt.pipeline.study import load_study\n"
        "names = ('csr_pattern_paired', 'svk_assemble', 'von_mises')\n"
        "prob = SeaSpringProblem(load_study('sea-spring-quick'))\n"
        "before = [len(getattr(k, n).signatures) for n in names]\n"
        "prob.warm_up()\n"
        "after = [len(getattr(k, n).signatures) for n in names]\n"
        "prob.evaluate(prob.nominal_design())\n"
        "used = [len(getattr(k, n).signatures) for n in names]\n"
        "print(json.dumps([before, after, used]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    before, after, used = json.loads(out.stdout.strip().splitlines()[-1])
    assert before == [0, 0, 0]
    assert after == [1, 1, 1]
    assert used == after  # a design needs no kernel (or type signature) the warm-up missed


@pytest.mark.parametrize("elements_through", [1.0, 3.0])  # no refinement pass; several
def test_region_refined_mesh_is_the_mesh_of_testing_every_triangle(spring, elements_through):
    import triangle
    from flexopt.fea import mesh as fm

    geom = spring[0]
    regions = geom.mesh_regions(elements_through, 3.0)
    got = mesh_polygon(geom.fe_outline, 3.0, refine=regions)
    # The loop as it was: every pass sizes every triangle by the regions it touches.
    cfg = fm.MeshSettings()
    poly = shapely.geometry.polygon.orient(geom.fe_outline, sign=1.0)
    opts = f"pq{cfg.min_angle_deg:g}"
    out = triangle.triangulate(
        fm._planar_graph(poly, 3.0), f"{opts}a{fm._EQUILATERAL_AREA * 9:.17g}"
    )
    passes = 0

    def local(corners):  # every triangle against every region
        tris = shapely.polygons(np.concatenate([corners, corners[:, :1]], axis=1))
        h = np.full(len(corners), np.inf)
        for region, size in regions:
            hit = shapely.intersects(region, tris)
            h[hit] = np.minimum(h[hit], size)
        return h

    for _ in range(cfg.max_refine_passes):
        target = np.minimum(local(out["vertices"][out["triangles"]]), 3.0)
        max_area = fm._EQUILATERAL_AREA * target**2
        if np.all(
            np.abs(fm._signed_areas(out["vertices"], out["triangles"])) <= cfg.area_slack * max_area
        ):
            break
        passes += 1
        out = triangle.triangulate(
            {"vertices": out["vertices"], "triangles": out["triangles"],
             "segments": out["segments"], "triangle_max_area": max_area},
            f"r{opts}a",
        )  # fmt: skip
    assert (passes > 0) == (elements_through > 1.0)
    want = fm.TriMesh(out["vertices"], out["triangles"])
    assert np.array_equal(got.points, want.points)
    assert np.array_equal(got.triangles, want.triangles)
    # boundary edges: the unique over (sorted) rows they were found by
    tri = got.triangles
    edges = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, inverse, counts = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True,
                                   return_counts=True)  # fmt: skip
    assert np.array_equal(got.boundary_edges, edges[counts[inverse.ravel()] == 1])


def test_force_only_state_at_convergence_changes_no_iterate(problem, spring, monkeypatch):
    # The Newton loop checks a state it expects to converge on the force alone; the answers
    # must be bit for bit those of always forming the tangent, with one tangent fewer per solve.
    geom = spring[0]
    always = PlaneStressModel._state_nonlinear

    def solve_both(model_cls_patch: bool):
        if model_cls_patch:
            monkeypatch.setattr(
                PlaneStressModel, "_state_nonlinear", lambda self, u, tangent=True: always(self, u)
            )
        r = analyse_spring(geom, problem.material, problem.theta, problem.study.mesh, 1, True,
                           keep_model=True, both_directions=True)  # fmt: skip
        monkeypatch.undo()
        return r

    lazy, full = solve_both(False), solve_both(True)
    if lazy.model.assembly != "compiled":
        pytest.skip("the force-only state is the compiled assembly's")
    for name in ("torque_Nm", "reverse_torque_Nm", "peak_stress_MPa", "reverse_peak_stress_MPa"):
        assert np.array_equal(getattr(lazy, name), getattr(full, name)), name
    assert np.array_equal(lazy.u, full.u) and np.array_equal(lazy.reverse_u, full.reverse_u)
    assert lazy.iterations == full.iterations
    # one per solve, and the patch also forms a tangent at series_predictor's two force-only
    # evaluations (at +-u_odd) and at rest in each of the two guessed solves (the lazy path
    # reads only the force there since session 32: the guess is Newton's start)
    assert lazy.model.counters["tangents"] == full.model.counters["tangents"] - 2 - 2 - 2


def test_refinement_regions_given_as_an_iterator_mesh_as_a_list(spring):
    geom = spring[0]
    regions = geom.mesh_regions(3.0, 3.0)  # thin enough to refine
    a = mesh_polygon(geom.fe_outline, 3.0, refine=regions)
    b = mesh_polygon(geom.fe_outline, 3.0, refine=iter(regions))
    assert np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)
    assert a.n_triangles > mesh_polygon(geom.fe_outline, 3.0).n_triangles  # it did refine


def test_facet_table_is_scikit_fems_own(spring):
    from flexopt.fea.mesh import to_skfem
    from flexopt.fea.plane_stress import _set_facets

    model = spring[1].model
    mine = to_skfem(model.mesh)
    _set_facets(mine)
    theirs = to_skfem(model.mesh)
    facets, t2f = type(theirs).build_entities(theirs.t, theirs.elem.refdom.facets)
    assert np.array_equal(mine.facets, facets) and mine.facets.dtype == facets.dtype
    assert np.array_equal(mine.t2f, t2f) and mine.t2f.dtype == t2f.dtype
    assert np.array_equal(model.skmesh.facets, facets)  # what the model's bases were built on
