"""The sea_spring report's fast paths (issue 13) give the reference answers, computed here:
the 3D checks on one Solid3DModel (assembled once, re-checks by PCG) against
:func:`fea.solid3d.compare_with_plane_stress` at each checked ST, and the work done in the
second process (peak convergence, the two extra 2D solves) against the same calls made in
this one. A coarse four-arm spiral with one prism layer keeps it to seconds."""

from __future__ import annotations

import math
import os

import flexopt.pipeline.studies._sea_spring_peak as peak
import flexopt.pipeline.studies.sea_spring as ss
import numpy as np
import pytest
from flexopt.fea.plane_stress import Clamp, Rotate
from flexopt.fea.sea_design import worse_direction
from flexopt.fea.solid3d import Solid3DSettings, compare_with_plane_stress
from flexopt.fea.solid3d_sector import periodic_mesh
from flexopt.fea.spring_analysis import analyse_spring
from flexopt.pipeline._hugepages import without_numpy_hugepages
from flexopt.pipeline.screening import SideProcess
from flexopt.pipeline.study import validate_study

STUDY = {
    "name": "sea-fast",
    "geometry": {"kind": "sea_spring", "topology": "spiral", "n_sets": 4},
    "material": "maraging-300",
    "taguchi": {"enabled": False},
    "mesh": {"max_edge_mm": 6.0, "elements_through": 0.5, "fillet_segments": 1},
    "design": {"sweep": 300.0, "R_pad": 30.0, "F1": 1 / 3, "F2": 0.5,
               "W1": 3.0, "W2": 2.5, "W3": 2.5, "W4": 3.0},
    # a tiny max_fraction_of_tolerance: the calibration is followed by a re-check (PCG on its
    # factor) whatever the ratio
    "solid_3d": {"converge_peak": False, "max_checks": 2, "layers": 1,
                 "max_fraction_of_tolerance": 0.001},
}  # fmt: skip


def _solved(study_dict):
    study = validate_study(study_dict)
    prob = ss.SeaSpringProblem(study, stage1={})
    x = np.delete(ss.design_vector(study), prob.names.index("ST"))
    return prob, x


def test_every_3d_check_equals_the_reference_check_at_its_st():
    prob, x = _solved(STUDY)
    _, geom, r, _ = prob.solve(x, 1)
    out = prob.solid_3d(geom, r)
    assert "problem" not in out, out
    assert [c["solver"] for c in out["checks"]][1:] == ["pcg (cholmod)"] * (len(out["checks"]) - 1)
    assert len(out["checks"]) >= 2
    # the reference: the whole part on the periodic plane mesh whose sector solid_3d solves
    # (the four arms repeat: fea/solid3d_sector.py), compare_with_plane_stress at each ST
    assert out["model_3d"].startswith("one sector of 4"), out["model_3d"]
    spec = prob.study.mesh
    regions = geom.mesh_regions(spec.elements_through, spec.max_edge_mm)
    mesh = periodic_mesh(geom.fe_outline, 4, spec.max_edge_mm, refine=regions).whole
    ignore = geom.hub_region.union(geom.pad_region).buffer(0.05)
    drive = Rotate(geom.hub_region, (0.0, 0.0), prob.theta, 1)
    # the re-check (PCG on the calibration's factor; the direct first solve is fea's test)
    for c in out["checks"][1:]:
        with without_numpy_hugepages():  # as solid_3d runs (else ~4x slower here, same values)
            ref = compare_with_plane_stress(mesh, prob.material, c["ST_mm"], Clamp(geom.pad_region),
                                            drive, Solid3DSettings(layers=1), ignore)  # fmt: skip
        assert c["stiffness_ratio_3d_2d"] == pytest.approx(ref["stiffness_ratio"], rel=1e-8)
        assert c["peak_stress_ratio_3d_2d"] == pytest.approx(ref["peak_stress_ratio"], rel=1e-8)
        assert c["dofs"] < 0.3 * ref["solid3d"]["n_dofs"]  # a quarter and the cuts


@pytest.mark.slow
def test_second_process_work_equals_this_process_work(monkeypatch):
    """detail with the side process: the two extra 2D solves are the values the same calls
    give here, and the peak convergence comes back from the other process with the arguments
    it was given (the convergence itself is a stand-in here: a deterministic function of
    those arguments that names its process; fea/solid3d's tests check the real one)."""
    import multiprocessing
    import os

    import flexopt.pipeline.fork as fork

    def fake_convergence(prob, params, sign):
        peaks = [100.0 * sign + params.thickness_mm, 200.0 + prob.theta]
        return {"converged": True, "status": "converged", "last_two_MPa": peaks,
                "peaks_MPa": peaks, "local_edge_mm": [1.0, 0.5], "peak_xy_mm": [0.0, 0.0],
                "corner": None, "time_s": float(os.getpid())}  # fmt: skip

    # fork (the CLI's choice on Linux) carries the stand-in into the side process
    monkeypatch.setattr(fork, "pool_context", lambda: multiprocessing.get_context("fork"))
    monkeypatch.setattr(peak, "peak_of", fake_convergence)
    # one 3D check (correct: false): its ratio is all the peak needs
    study = {**STUDY, "solid_3d": {"converge_peak": True, "correct": False, "layers": 1}}
    prob, x = _solved(study)
    info = prob.detail(x).info
    conv = info["solid_3d"]["peak_convergence"]
    assert conv["process"] == "second" and conv["time_s"] != float(os.getpid())
    _, geom, r, _ = prob.solve(x, prob.study.mesh.curve_steps)
    here = fake_convergence(prob, geom.params, worse_direction(r))
    assert conv["peaks_MPa"] == here["peaks_MPa"]
    ratio = info["solid_3d"]["checks"][-1]["peak_stress_ratio_3d_2d"]
    assert conv["peak_stress_3d_MPa"] == here["last_two_MPa"][-1] * ratio
    assert info["peak_stress_3d_MPa"] == conv["peak_stress_3d_MPa"]
    check = analyse_spring(geom, prob.material, prob.theta, prob.study.mesh)
    small = analyse_spring(geom, prob.material, math.radians(1.0), prob.study.mesh)
    solved = info["thickness_solved"]
    assert solved["ccw_stiffness_resolved_at_ST_Nm_per_rad"] == check.stiffness_Nm_per_rad
    assert solved["ccw_peak_stress_resolved_at_ST_MPa"] == float(check.peak_stress_MPa[-1])
    lin = (small.stiffness_Nm_per_rad / small.linear_stiffness_Nm_per_rad - 1) * 100
    assert info["linear_vs_nonlinear"]["at_1_deg_percent"] == lin


def test_without_a_second_process_the_work_is_done_here(monkeypatch):
    """No process can be started (a daemonic worker): solid_3d computes it in this one."""
    import flexopt.pipeline.fork as fork

    def refuse():
        raise AssertionError("daemonic processes are not allowed to have children")

    monkeypatch.setattr(fork, "pool_context", refuse)
    monkeypatch.setattr(peak, "peak_of", lambda prob, params, sign: {
        "converged": False, "status": "not converged", "last_two_MPa": [1.0, 2.0],
        "peaks_MPa": [1.0, 2.0], "local_edge_mm": [1.0, 0.5], "peak_xy_mm": [0.0, 0.0],
        "corner": None, "time_s": 0.0})  # fmt: skip
    study = {**STUDY, "solid_3d": {"converge_peak": True, "correct": False, "layers": 1}}
    prob, x = _solved(study)
    _, geom, r, _ = prob.solve(x, 1)
    out = prob.solid_3d(geom, r)
    conv = out["peak_convergence"]
    assert conv["process"] == "this" and conv["peaks_MPa"] == [1.0, 2.0]
    assert out["peak_stress_3d_MPa"] == 2.0 * out["checks"][-1]["peak_stress_ratio_3d_2d"]


def _exit_now() -> None:
    import os

    os._exit(3)  # a process killed under its task (out of memory, a signal)


def _fail_fea() -> None:
    from flexopt.fea.errors import FeaError

    raise FeaError("the solve failed")


def test_side_process_death_and_errors_come_back(monkeypatch):
    """A side process that dies under a task gives None (the caller redoes it; no hang), a
    FeaError of a task comes back raised, a plain value comes back as it is."""
    import multiprocessing

    import flexopt.pipeline.fork as fork
    from flexopt.fea.errors import FeaError

    monkeypatch.setattr(fork, "pool_context", lambda: multiprocessing.get_context("fork"))
    side = SideProcess.start()
    side.submit("sum", sum, [1.0, 2.5])
    side.submit("fea", _fail_fea)
    assert side.get("sum") == 3.5
    with pytest.raises(FeaError, match="the solve failed"):
        side.get("fea")
    side.submit("exit", _exit_now)
    assert side.get("exit") is None
    assert side.get("never submitted") is None
    side.close()


def _stage1_stand_in() -> dict:
    """Stage 1's results as the plot reads them (two factors, five levels each)."""
    levels = [1.0, 2.0, 3.0, 4.0, 5.0]
    return {
        "array": "L25 (5^6)",
        "chosen": {"RP": 4},
        "main_effects": {"W1": {"levels": levels, "sn_dB": [1.0, 2.0, 1.5, 0.5, 0.0]},
                         "sweep": {"levels": levels, "sn_dB": [0.0, -1.0, 0.5, 2.0, 1.0]}},
        "anova": [{"source": "W1", "percent": 60.0, "pooled": False},
                  {"source": "sweep", "percent": 30.0, "pooled": False},
                  {"source": "error", "percent": 10.0, "pooled": False},
                  {"source": "total", "percent": 100.0, "pooled": False}],
    }  # fmt: skip


def test_taguchi_png_is_drawn_in_its_own_process(monkeypatch):
    """The detail's taguchi.png is drawn by a process of its own while the detail solves, and
    is the plot drawn here; where no process starts, or it dies, it is drawn here."""
    import multiprocessing

    import flexopt.pipeline.fork as fork
    from flexopt.pipeline.plots import plot_taguchi

    monkeypatch.setattr(fork, "pool_context", lambda: multiprocessing.get_context("fork"))
    stage1 = _stage1_stand_in()
    title = "stage 1: L25 (5^6) over the spiral's factors"
    here = plot_taguchi(stage1["main_effects"], stage1["anova"], title=title)
    assert here[:8] == b"\x89PNG\r\n\x1a\n"
    side = peak.start_taguchi_png(stage1, "spiral")
    assert side is not None and side._process is not None and side._process.pid != os.getpid()
    assert peak.taguchi_png(side, stage1, "spiral") == here
    assert side._process is None  # closed
    # no plot to make: no process
    assert peak.start_taguchi_png({"chosen": {"RP": 4}}, "spiral") is None
    assert peak.taguchi_png(None, {"chosen": {"RP": 4}}, "spiral") is None
    # the process dies under the plot: drawn here
    side = peak.start_taguchi_png(stage1, "spiral")
    side._process.kill()
    assert peak.taguchi_png(side, stage1, "spiral") == here

    def refuse():
        raise AssertionError("daemonic processes are not allowed to have children")

    monkeypatch.setattr(fork, "pool_context", refuse)
    assert peak.taguchi_png(peak.start_taguchi_png(stage1, "spiral"), stage1, "spiral") == here


def test_detail_files_hold_the_taguchi_png(monkeypatch):
    """detail (3D check off: seconds) with stage 1's results: taguchi.png is the plot of them."""
    import multiprocessing

    import flexopt.pipeline.fork as fork
    from flexopt.pipeline.plots import plot_taguchi

    monkeypatch.setattr(fork, "pool_context", lambda: multiprocessing.get_context("fork"))
    study = validate_study({**STUDY, "solid_3d": {"check": False}})
    stage1 = _stage1_stand_in()
    prob = ss.SeaSpringProblem(study, stage1=stage1)
    x = np.delete(ss.design_vector(study), prob.names.index("ST"))
    detail = prob.detail(x)
    title = "stage 1: L25 (5^6) over the spiral's factors"
    assert detail.files["taguchi.png"] == plot_taguchi(
        stage1["main_effects"], stage1["anova"], title=title
    )
    assert detail.info["taguchi"]["chosen"]["RP"] == 4


@pytest.mark.parametrize("here", [True, False])
def test_the_2d_solves_run_here_after_the_3d_checks_before_the_peak_wait(monkeypatch, here):
    """detail with CHOLMOD's 3D checks (``solves_here``): the peak convergence alone goes to
    the second process (the longer work); the two extra 2D solves run in this process once the
    3D checks are made, before its wait. With multigrid's (much longer) checks both go there."""
    import multiprocessing

    import flexopt.pipeline.fork as fork

    assert peak.solves_here(validate_study(STUDY).solid_3d)  # the cholmod extra is installed
    monkeypatch.setattr(peak, "solves_here", lambda s3: here)
    monkeypatch.setattr(fork, "pool_context", lambda: multiprocessing.get_context("fork"))
    monkeypatch.setattr(peak, "peak_of", lambda prob, params, sign: {
        "converged": True, "status": "converged", "last_two_MPa": [1.0, 2.0],
        "peaks_MPa": [1.0, 2.0], "local_edge_mm": [1.0, 0.5], "peak_xy_mm": [0.0, 0.0],
        "corner": None, "time_s": 0.0})  # fmt: skip
    calls = []
    solves, get = ss.detail_solves, SideProcess.get

    def solves_here(*args):
        calls.append(("2D solves", os.getpid()))
        return solves(*args)

    def wait(self, name):
        calls.append(("wait", name))
        return get(self, name)

    if here:  # (a stand-in would not pickle to the second process)
        monkeypatch.setattr(ss, "detail_solves", solves_here)
    monkeypatch.setattr(SideProcess, "get", wait)
    study = {**STUDY, "solid_3d": {"converge_peak": True, "correct": False, "layers": 1}}
    prob, x = _solved(study)
    info = prob.detail(x).info
    if here:
        assert calls == [("2D solves", os.getpid()), ("wait", "peak")]
    else:  # solved in the second process and got from it (else solved again here)
        assert calls == [("wait", "peak"), ("wait", "analyses")]
        assert info["thickness_solved"]["ccw_stiffness_resolved_at_ST_Nm_per_rad"] > 0
    assert info["solid_3d"]["peak_convergence"]["process"] == "second"
    assert len(info["solid_3d"]["checks"]) == 1 and "thickness_solved" in info
