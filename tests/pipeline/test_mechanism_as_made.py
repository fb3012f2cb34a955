"""The mechanism kind analyses the part as made: beams clipped at the bodies they enter, sharp
corners refused, clamps where the pads are, filleted roots with their stress-concentration
factor, and interference of the deformed parts over every row of every load case."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from flexopt.geometry.mechanism import shoulder_kt
from flexopt.pipeline.errors import StudyError
from flexopt.pipeline.studies.mechanism import MechanismProblem
from flexopt.pipeline.study import validate_study


def _hub(inner_x: float = 5.0, max_deg: float = 5.0, frames=(), **geometry) -> dict:
    """A square hub (10 x 10 mm) turned about its centre by two radial leaves, each clamped to
    the ground 35 mm out: a rotary flexure. ``inner_x``: where the leaves start (5 = the hub's
    edge, less = inside the hub)."""
    raw = {
        "name": "hub",
        "geometry": {
            "kind": "mechanism",
            "width_mm": 5.0,
            "beams": {
                "right": {
                    "points_mm": [[inner_x, 0], [40, 0]],
                    "thickness_mm": 1.2,
                    "elements": 12,
                },
                "left": {
                    "points_mm": [[-inner_x, 0], [-40, 0]],
                    "thickness_mm": 1.2,
                    "elements": 12,
                },
            },  # fmt: skip
            "bodies": {
                "hub": {"ref_mm": [0, 0], "outline_mm": [[-5, -5], [5, -5], [5, 5], [-5, 5]]}
            },
            "joints": [
                {"a": "right.start", "b": "hub"},
                {"a": "left.start", "b": "hub"},
                {"a": "right.end", "b": "ground"},
                {"a": "left.end", "b": "ground"},
            ],
            "ground_outlines_mm": [list(map(list, f)) for f in frames],
            **geometry,
        },
        "material": "PA12",
        "load_cases": {
            "turn": {
                "drive": {
                    "part": "hub",
                    "control": "rotation",
                    "max_deg": max_deg,
                    "steps": 10,
                    "transverse": "held",
                },
            }  # fmt: skip
        },
        "outputs": {"torque_Nmm": {"quantity": "reaction"}},
        "requirements": [{"quantity": "max_torque_Nmm", "max": 1e6}],
    }
    return raw


def _solve(raw: dict):
    prob = MechanismProblem(validate_study(raw))
    solved = prob.solve(None)
    assert not isinstance(solved, tuple), solved
    return prob, solved


def test_a_leaf_run_into_its_hub_is_clipped_at_the_hubs_outline():
    _, edge = _solve(_hub(5.0))
    _, inside = _solve(_hub(0.4))  # 4.6 mm of each leaf inside the hub
    made = inside.outline.beams["right"]
    assert made.start.clipped_mm == pytest.approx(4.6, abs=1e-12)
    assert made.shape.points_mm[0] == pytest.approx([5.0, 0.0], abs=1e-12)
    assert edge.outline.beams["right"].start.clipped_mm == 0.0
    t_edge = edge.tables["turn"]["torque_Nmm"]
    t_in = inside.tables["turn"]["torque_Nmm"]
    assert np.max(np.abs(t_in[1:] / t_edge[1:] - 1.0)) < 0.01  # the bar; here exact:
    np.testing.assert_allclose(t_in, t_edge, rtol=1e-9, atol=1e-12)
    # the info says what was clipped; the printed outline is the same part
    assert inside.outline.polygon.symmetric_difference(edge.outline.polygon).area < 1e-6
    # solved as flexible (the defect this guards against), the leaves would be 4.6/35 longer:
    # the torque of a leaf turned at its end falls as ~1/L, far more than 1 %
    from flexopt.pipeline.studies._mechanism_schema import build_load_case
    from flexopt.pipeline.studies.mechanism import _mechanism

    study = validate_study(_hub(0.4))
    fm = __import__("flexopt.fea.mechanism", fromlist=["solve_mechanism"])
    flexible = fm.solve_mechanism(
        _mechanism(study, study.geometry), build_load_case(study, "turn"),
        [fm.MechOutput("t", "reaction")],
    )  # fmt: skip
    assert flexible.outputs["t"][-1] < 0.9 * t_edge[-1]


def test_a_leaf_ending_outside_its_hub_or_a_hairpin_corner_is_refused():
    raw = _hub(6.0)  # 1 mm short of the hub
    with pytest.raises(StudyError, match=r"ends 1 mm outside body 'hub'"):
        validate_study(raw)
    raw = _hub()
    raw["geometry"]["beams"]["right"]["points_mm"] = [[5, 0], [30, 0], [12, 2.5]]
    raw["geometry"]["beams"]["right"]["thickness_mm"] = 1.2
    raw["geometry"]["joints"][2] = {"a": "right.end", "b": "ground"}
    with pytest.raises(StudyError) as err:
        validate_study(raw)
    assert err.value.path == "geometry.beams.right.points_mm[1]"
    assert "turns 172 deg at point [1] (30, 0) mm, sharper than 90 deg" in err.value.problem
    assert "round the corner" in err.value.problem
    raw["geometry"]["max_corner_deg"] = 175.0  # stricter only: past 90 deg the legs merge
    with pytest.raises(StudyError) as err:
        validate_study(raw)
    assert err.value.path == "geometry.max_corner_deg"
    raw["geometry"]["max_corner_deg"] = 60.0
    raw["geometry"]["beams"]["right"]["points_mm"] = [[5, 0], [30, 0], [40, 10]]  # 45 deg: fine
    raw["geometry"]["beams"]["left"]["points_mm"] = [[-5, 0], [-30, 0], [-40, -10]]
    validate_study(raw)


def test_a_hub_turn_that_drives_a_leaf_through_a_ground_outline_is_not_met_with_the_row():
    # a ground bar 0.9 mm above the right leaf, tied to its clamping pad
    bar = [[8, 1.5], [46, 1.5], [46, 3.5], [8, 3.5]]
    prob, solved = _solve(_hub(5.0, max_deg=20.0, frames=[bar]))
    verdict = next(v for v in prob.verdicts(solved) if v.name == "no_interference")
    assert not verdict.met and verdict.value > 0
    assert "load case turn, row" in verdict.detail
    assert "beam right passes through ground outline [0]" in verdict.detail
    row = int(verdict.detail.split("row ")[1].split(" ")[0])
    assert 0 < row <= 10
    ev = prob._evaluation(np.zeros(0), solved, 0.0)  # noqa: SLF001
    assert ev.metrics["verdict"] == "NOT MET"
    # a smaller turn keeps clear of it: MET, and the clearance is reported
    prob, solved = _solve(_hub(5.0, max_deg=2.0, frames=[bar]))
    verdict = next(v for v in prob.verdicts(solved) if v.name == "no_interference")
    assert verdict.met and solved.metrics["interference_mm2"] == 0.0


def test_smallest_clearance_of_a_parallel_guide_is_its_closed_form():
    # leaves 1.2 mm thick at y = +-10, 4 mm pads at x < 0: the closest parts that are not joined
    # are a leaf and the other leaf's pad. The leaf's root (a disc of 0.6 + 1.5 r + 0.001 mm,
    # its fillets, r = 0.01 mm here) is left out, so its edge y = 9.4 starts at
    # x0 = sqrt(R^2 - 0.6^2) and the pad's corner (0, -8) is sqrt(x0^2 + 17.4^2) away
    from tests.pipeline.test_mechanism_study import _guide

    prob, solved = _solve(_guide())
    radius = 0.6 + 1.5 * 0.01 + 1e-3
    expected = math.hypot(math.sqrt(radius**2 - 0.36), 17.4)
    assert solved.metrics["min_clearance_mm"] == pytest.approx(expected, abs=1e-4)
    assert "pad" in solved.clearance["clearance_at"]
    assert solved.metrics["interference_mm2"] == 0.0


def test_shoulder_kt_follows_the_fit_and_its_limits():
    # continuous where the fit changes coefficients (h/r = 2), within the fit's stated accuracy
    for d in (1.0, 2.0):
        r = 0.5
        below = shoulder_kt(d + 2 * (2 * r) * (1 - 1e-9), d, r)
        above = shoulder_kt(d + 2 * (2 * r) * (1 + 1e-9), d, r)
        assert below == pytest.approx(above, rel=0.02)
    # no shoulder, no concentration; a smaller fillet concentrates more; a body (an unbounded
    # shoulder) is the fit's h/r = 20
    assert shoulder_kt(1.2, 1.2, 0.5) == 1.0
    kts = [shoulder_kt(4.0, 1.0, r) for r in (1.5, 1.0, 0.5, 0.2, 0.1)]
    assert all(a < b for a, b in zip(kts, kts[1:], strict=False))
    assert shoulder_kt(1e6, 1.0, 0.5) == shoulder_kt(1.0 + 40 * 0.5, 1.0, 0.5)
    for r in (0.05, 0.1, 0.2, 0.5, 1.0, 2.0):  # levelled off there: a body's shoulder
        assert shoulder_kt(1 + 40 * r, 1.0, r) == pytest.approx(shoulder_kt(1 + 20 * r, 1.0, r),
                                                                rel=4e-3)  # fmt: skip
    # the fit's own value at D/d = 2, r/d = 0.1 (h/r = 5): Kt = 1.917 from its coefficients
    q, w = 5.0, math.sqrt(5.0)
    c = (1.042 + 0.982 * w - 0.036 * q, -3.599 + 1.619 * w - 0.431 * q,
         6.084 - 5.607 * w + 1.158 * q, -2.527 + 3.006 * w - 0.691 * q)  # fmt: skip
    x = 0.5
    assert shoulder_kt(2.0, 1.0, 0.1) == pytest.approx(
        c[0] + c[1] * x + c[2] * x**2 + c[3] * x**3, rel=1e-12
    )


def test_the_verdicts_stress_carries_the_roots_concentration_factor():
    from tests.pipeline.test_mechanism_study import _guide

    raw = copy.deepcopy(_guide())
    raw["geometry"]["fillet_mm"] = 0.5
    prob, solved = _solve(raw)
    resp = solved.responses["push"]
    made = solved.outline.beams
    kt = made["upper"].start.kt
    assert kt == pytest.approx(shoulder_kt(4.0, 1.2, 0.5))
    # a clamped-guided leaf bends most at its roots: the as-made peak is Kt x the stress over
    # the flare at the pad (the shuttle's root has a smaller Kt: its shoulder is a body's)
    last = [
        max(resp.peak_stress_MPa[-1, i], m.start.kt * resp.root_stress_MPa[-1, i, 0],
            m.end.kt * resp.root_stress_MPa[-1, i, 1])
        for i, m in enumerate(made.values())
    ]  # fmt: skip
    assert solved.tables["push"]["peak_stress_MPa"][-1] == pytest.approx(max(last), rel=1e-12)
    assert solved.tables["push"]["peak_stress_MPa"][-1] > 1.2 * resp.peak_stress_MPa[-1].max()
    # the root stress is the beam model's at the fillet's toe: a clamped-guided leaf of length
    # L between the toes, deflected delta = 0.4 mm: sigma = (6 E I delta / L^2) / (b t^2 / 6) =
    # 3 E t delta / L^2 (the flares, the shear and the free shuttle: within 10 %)
    length = 40.0 - 2 * 0.5
    sigma = 3 * 1650.0 * 1.2 * 0.4 / length**2
    assert resp.root_stress_MPa[-1, 0, 0] == pytest.approx(sigma, rel=0.1)


def test_the_fillets_stiffen_the_leaves_as_a_beam_of_their_thickness_would():
    # two 40 mm leaves, 1.2 mm thick, 1 mm fillets at both roots (a 4 mm pad: shoulder 1.4 mm;
    # the shuttle: a body): each leaf is symmetric, so a guided leaf has its inflection at mid
    # length and M(s) = F (L/2 - s): delta / F = int (L/2 - s)^2 / EI(s) ds + int ds / kGA(s)
    # (Timoshenko), with t(s) the flared thickness the model is given. The fillets make the
    # leaves 7 % stiffer than 2 x 12 EI / L^3 (what a model without them would say).
    from tests.pipeline.test_mechanism_study import E_PA12, _guide

    raw = copy.deepcopy(_guide())
    raw["geometry"]["fillet_mm"] = 1.0
    # the shuttle guided (its rotation held, which the leaves' axial strain would otherwise
    # allow) and pushed 0.02 mm: the linear, guided case the formula is for
    raw["load_cases"]["push"]["drive"].update({"rotation": "held", "max_mm": 0.02})
    prob, solved = _solve(raw)
    made = solved.outline.beams["upper"]
    assert made.start.fillet_mm == made.end.fillet_mm == 1.0
    p, t = made.shape.points_mm, made.shape.thickness_mm
    s_pts = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
    length = s_pts[-1]
    s = np.linspace(0.0, length, 200001)
    ts = np.interp(s, s_pts, t)
    b, g = 6.0, E_PA12 / (2 * (1 + 0.39))
    bending = np.trapezoid((0.5 * length - s) ** 2 / (E_PA12 * b * ts**3 / 12), s)
    shear = np.trapezoid(1.0 / (5 / 6 * g * b * ts), s)
    k = 2.0 / (bending + shear)
    got = solved.metrics["start_stiffness_N_per_mm"]
    assert got == pytest.approx(k, rel=1e-4)  # 3.5e-6 measured, 20 to 80 elements alike
    plain = 2 * 12 * E_PA12 * (b * 1.2**3 / 12) / 40.0**3
    assert got > 1.05 * plain


def test_root_stress_over_the_whole_beam_is_its_peak():
    # the fea hook samples the same points as the beam's own peak stress: over a root as long
    # as the beam it is the peak (both kernels' numbers), over none the end section's
    from flexopt.fea import mechanism as fm
    from flexopt.fea.materials import get_material

    mat = get_material("PA12")
    for root in ((40.0, 40.0), (0.0, 0.0)):
        beam = fm.MechBeam("leaf", np.array([[0, 0], [40, 0]]), np.array([1.2, 1.2]), 6.0, 12,
                           None, root)  # fmt: skip
        mech = fm.Mechanism((beam,), (), (fm.MechJoint("leaf.start", "ground"),), mat)
        case = fm.LoadCase("tip", fm.MechDrive("leaf.end", "displacement", 4.0, 2, (0.0, 1.0)))
        resp = fm.solve_mechanism(mech, case, [fm.MechOutput("f", "reaction")])
        peak = resp.peak_stress_MPa[1:, 0]
        if root[0] > 0:
            np.testing.assert_allclose(resp.root_stress_MPa[1:, 0, 0], peak, rtol=1e-12)
            np.testing.assert_allclose(resp.root_stress_MPa[1:, 0, 1], peak, rtol=1e-12)
        else:  # a cantilever bends most at its clamp, least (zero moment) at its loaded tip
            np.testing.assert_allclose(resp.root_stress_MPa[1:, 0, 0], peak, rtol=1e-12)
            assert np.all(resp.root_stress_MPa[1:, 0, 1] < 0.05 * peak)
