"""The optimiser's (coarse) outline of an arm spring repeats under its turn by the pitch, so the
3D check solves one sector of the part the stiffness rows judge, and that part is the exported
(fine) one (docs/sea_spring.md, "The optimiser's outline made symmetric (session 30)"). The
exported outlines, holes included, repeat too for 2 to 8 arms (session 31: the bore, hub and pad
holes did not for 3, 5, 6, 7 or 8 arms; docs/solid3d.md)."""

from __future__ import annotations

import numpy as np
import pytest
from flexopt.fea.solid3d_sector import rotational_symmetry_problem, sector_or_reason
from flexopt.geometry.arm_spring import SPIRAL_BOUNDS, build_arm_spring, spiral_params
from flexopt.geometry.errors import GeometryError
from flexopt.geometry.sea_spring import SpringFrame
from shapely import affinity

#: fea/solid3d_sector.rotational_symmetry_problem's default: above it the 3D check solves the
#: whole part
SECTOR_RTOL = 1e-4
#: what "symmetric" means here: round-off of the turn (the outlines below are 1e-16 off),
#: far below the sector test's tolerance and below what a Douglas-Peucker simplification of
#: the whole ring leaves (1e-6 to 2e-4 of the area on the examples' designs)
SYMMETRIC_RTOL = 1e-9

#: sea-spring.yaml's design of session 29: its union of hub, arms, pads and root fills had 5
#: slits (an odd number, round-off of the half turn), the frame fillets' closing filled 0.42 mm^2
#: at one arm's hub root and not the other's, and its outline missed its half turn by 0.85 mm^2
SESSION_29 = {
    "sweep": 469.7572635353407, "R_pad": 32.49999999659438, "F1": 0.5848572426469728,
    "F2": 0.4125000001043946, "W1": 4.578124999999702, "W2": 4.051708276511209,
    "W3": 4.230989583815249, "W4": 4.4531249997973665, "ST": 19.984047733322193,
}  # fmt: skip
FRAME = SpringFrame(fillet_mm=0.3, fillet_segments=4)  # sea-spring.yaml's


def _off_turn(geom, which: str = "fe_outline") -> float:
    """Area (mm^2) of the outline's (``fe_outline``: the optimiser's, without holes;
    ``outline``: the exported one, with them) symmetric difference with its turn by the pitch,
    over its area."""
    o, pitch = getattr(geom, which), geom.params.pitch_deg
    return o.symmetric_difference(affinity.rotate(o, pitch, origin=(0.0, 0.0))).area / o.area


def _regions(geom) -> dict:
    """The regions the SEA study's 3D check asks to repeat (fea/sea_design.solid_3d_check)."""
    ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)
    return {"hub": geom.hub_region, "pads": geom.pad_region, "stress-ignore": ignore}


def _example(name: str):
    """(params, frame, plane mesh settings) of an example's recorded ``design:``."""
    from flexopt.pipeline.study import load_study

    study = load_study(name)
    if study.geometry.kind == "threshold_spring":
        import flexopt.pipeline.studies.threshold_spring as kind
    else:
        import flexopt.pipeline.studies.sea_spring as kind
    prob = kind.problem(study)
    # the plane mesh the 3D check extrudes: the SEA's mesh, threshold-spring's fidelity mesh
    mesh = study.mesh if study.geometry.kind == "sea_spring" else study.fidelity
    return prob.params(prob.nominal_design()), prob.frame, mesh


def test_the_session_29_design_repeats_under_its_half_turn():
    # fails on the code before session 30 (0.85 mm^2 of 1874: 4.5e-4 of the area)
    geom = build_arm_spring(spiral_params(SESSION_29, 2, FRAME, root_fillet_mm=1.5), FRAME)
    assert _off_turn(geom) < SYMMETRIC_RTOL
    assert rotational_symmetry_problem(geom.fe_outline, 2, regions=_regions(geom)) is None


# every example whose kind builds an arm spring (sea-spring-serpentine: serpentine topology;
# sea-window: no geometry)
ARM_EXAMPLES = ["sea-spring", "sea-spring-life", "sea-spring-quick", "threshold-spring"]


@pytest.mark.parametrize("name", ARM_EXAMPLES)
def test_recorded_designs_repeat_and_the_3d_check_solves_one_sector(name):
    p, frame, mesh = _example(name)
    geom = build_arm_spring(p, frame)
    assert _off_turn(geom) < SYMMETRIC_RTOL
    # the exported outline repeats but for the hub's bolt holes when their count is not a
    # multiple of the arms' (threshold-spring: 4 bolts, 6 arms), holes in the flange's rigid
    # footprint that the models cannot see
    repeats = frame.hub_holes % p.n_arms == 0
    assert (_off_turn(geom, "outline") < SYMMETRIC_RTOL) == repeats
    hub_holes = geom.fe_outline.difference(geom.outline).intersection(geom.hub_region)
    filled = _with(geom, "outline", geom.outline.union(hub_holes.buffer(1e-9)))
    assert _off_turn(filled, "outline") < 1e-9
    # the exported part is the same design: its fine outline within a facet's sag of it (the
    # 0.3 mm frame fillets at 2 segments a quarter circle: 0.3 (1 - cos 22.5 deg) = 0.023 mm;
    # the fill the asymmetric closing grew reached 0.6 mm out)
    fine = build_arm_spring(p, frame, curve_step_mm=0.1)
    assert _off_turn(fine) < SYMMETRIC_RTOL
    assert (_off_turn(fine, "outline") < SYMMETRIC_RTOL) == repeats
    assert geom.fe_outline.hausdorff_distance(fine.fe_outline) < 0.05
    assert abs(geom.fe_outline.area - fine.fe_outline.area) < 1e-3 * fine.fe_outline.area
    # threshold-spring's 3D check solves one sector too since session 31
    # (optimise/curve_objectives.threshold_solid_3d)
    regions = geom.mesh_regions(mesh.elements_through, mesh.max_edge_mm)
    pm, why = sector_or_reason(geom.fe_outline, p.n_arms, mesh.max_edge_mm, regions,
                               _regions(geom))  # fmt: skip
    assert pm is not None, why
    assert why.startswith(f"one sector of {p.n_arms}")


def _random_designs(count: int, seed: int, arm_counts=(2, 3, 4, 5, 6)):
    """``count`` (n_arms, values, geometry): ``arm_counts`` in turn, values drawn uniformly
    from SPIRAL_BOUNDS, one of the two frames of the SEA examples, redrawn until they build
    (many draws with 5 or 6 arms are refused: their slots close)."""
    rng = np.random.default_rng(seed)
    arm_counts = list(arm_counts)
    frames = (FRAME, SpringFrame(fillet_mm=0.3, fillet_segments=2))
    out, tries = [], 0
    while len(out) < count:
        tries += 1
        assert tries < 200 * count, "the design space builds too rarely to draw from"
        n_arms = arm_counts[len(out) % len(arm_counts)]
        values = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in SPIRAL_BOUNDS.items()}
        frame = frames[int(rng.integers(0, 2))]
        try:
            p = spiral_params(values, n_arms, frame, root_fillet_mm=1.5)
            geom = build_arm_spring(p, frame)
        except GeometryError:
            continue
        out.append((n_arms, values, geom))
    return out


def test_random_designs_of_the_sea_space_repeat_under_their_turn():
    designs = _random_designs(36, seed=30)
    assert {n for n, _, _ in designs} == {2, 3, 4, 5, 6}
    worst = max(_off_turn(g) for _, _, g in designs)
    assert worst < SYMMETRIC_RTOL, worst
    for n_arms, _, geom in designs:
        assert rotational_symmetry_problem(geom.fe_outline, n_arms, regions=_regions(geom)) is None


def test_exported_outlines_with_their_holes_repeat_for_2_to_8_arms():
    # fails on session 30's code: a 64-gon bore and 48-gon pad holes whose vertices do not turn
    # with the arms, hub holes not built to turn (the exported outline 45.7 mm^2 off its turn on
    # 6 arms), and the fine outline simplified as a whole ring (up to 1.5e-5 of its area off on
    # 3 arms). The hub holes are as many as asked: a multiple of the arm count repeats with
    # the arms; another count (the frame's 4 on 3 arms) only the hub holes do not repeat
    from dataclasses import replace

    designs = _random_designs(7, seed=31, arm_counts=range(2, 9))
    assert [n for n, _, _ in designs] == list(range(2, 9))
    for n_arms, _, geom in designs:
        for k in sorted({geom.frame.hub_holes, n_arms * -(-4 // n_arms)}):
            frame = replace(geom.frame, hub_holes=k)
            g0 = build_arm_spring(geom.params, frame)
            fine = build_arm_spring(geom.params, frame, curve_step_mm=0.1)
            for g in (g0, fine):
                assert _off_turn(g, "fe_outline") < SYMMETRIC_RTOL, (n_arms, k)
                hub_holes = g.fe_outline.difference(g.outline).intersection(g.hub_region)
                # the exported outline with the hub's bolt holes filled repeats always; with
                # them, when k is a multiple of n_arms
                filled = _with(g, "outline", g.outline.union(hub_holes.buffer(1e-9)))
                assert _off_turn(filled, "outline") < 1e-9, (n_arms, k)
                if k % n_arms == 0:
                    assert _off_turn(g, "outline") < SYMMETRIC_RTOL, (n_arms, k)
                    regions = {**_regions(g), **g.boundaries}
                    assert rotational_symmetry_problem(g.outline, n_arms, regions=regions) is None
                # the holes: bore, k hub bolt holes, one per pad, all inside the rigid
                # footprints where the FE models (which mesh fe_outline, without them) see no
                # difference
                holes = g.fe_outline.difference(g.outline)
                assert len(g.outline.interiors) == 1 + k + n_arms
                rigid = g.hub_region.union(g.pad_region).buffer(1e-6)
                assert holes.difference(rigid).area < 1e-9
                hole_area = (
                    (frame.bore_diameter_mm**2 + k * frame.hub_hole_diameter_mm**2
                     + n_arms * frame.pad_hole_diameter_mm**2) * np.pi / 4
                )  # fmt: skip
                # the polygons' chords cut a little off each circle (48- to 128-gons: < 0.3 %)
                assert hole_area * 0.99 < holes.area < hole_area


def _with(geom, which: str, value):
    """A stand-in of ``geom`` whose ``which`` is ``value`` (for :func:`_off_turn`)."""
    from types import SimpleNamespace

    return SimpleNamespace(params=geom.params, **{which: value})


@pytest.mark.parametrize(
    ("change", "words"),
    [
        ({"hub_hole_circle_diameter_mm": 14.0}, "hub bolt holes reach 8.35 mm"),
        ({"pad_hole_diameter_mm": 6.0, "pad_radius_mm": 3.5}, "pad bolt hole"),
        ({"hub_holes": 12, "hub_hole_diameter_mm": 2.7}, "hub's 12 bolt holes"),
    ],
)
def test_holes_the_models_would_not_see_are_refused(change, words):
    # the FE models mesh the outline without its holes: true of the exported part only while
    # every hole lies in a rigid footprint (hub clamp radius 8 mm, washers 2.75 mm here)
    from dataclasses import replace

    frame = replace(FRAME, **change)
    p = spiral_params(SESSION_29, 2, frame, root_fillet_mm=1.5)
    with pytest.raises(GeometryError, match=words):
        build_arm_spring(p, frame)
