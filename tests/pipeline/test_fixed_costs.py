"""Issue 27 item 4, the report's fixed costs: cuts that must not change a file."""

from __future__ import annotations

import json
import os

import pytest
from flexopt.pipeline.run.split_makes import SplitMakes


def _make(name: str) -> bytes:
    if name == "bad":
        raise ValueError("no such plot")
    # the process that made it, so that the test sees two children did the work
    return f"{name}:{os.getpid()}".encode()


def test_split_makes_returns_every_file_in_queued_order():
    names = ["a", "b", "bad", "d", "e"]
    items = [(n, lambda n=n: _make(n)) for n in names]
    out = SplitMakes(items).results()
    assert [name for name, _, _ in out] == names
    assert out[2] == ("bad", None, "ValueError: no such plot")
    made = {name: data.decode().split(":") for name, data, _ in out if data is not None}
    assert all(made[n][0] == n for n in made)
    pids = {made[n][1] for n in made}
    if hasattr(os, "fork"):  # every other file in each of two children, none here
        assert len(pids) == 2 and str(os.getpid()) not in pids
        assert made["a"][1] == made["e"][1] != made["b"][1] == made["d"][1]


def test_templates_put_in_at_embed_are_what_plotly_writes():
    """A figure built as JSON (pipeline/figure_json.py) naming WHITE, finished by
    finish_template, is the figure plotly's classes write with "plotly_white" named, and one
    naming no template gets plotly's default, as plotly applies it to a new figure (the
    templates read from plotly's files, not made by its classes)."""
    go = pytest.importorskip("plotly.graph_objects")
    from flexopt.pipeline import figure_json as fj
    from flexopt.pipeline import html_templates
    from flexopt.pipeline.html_templates import WHITE, finish_template

    html_templates._json_text.cache_clear()

    def build(module, template):
        fig = module.Figure(module.Scatter(x=[0.0, 1.5], y=[2.0, -1.0], name="a"))
        layout = {"title": {"text": "t"}, "height": 300}
        fig.update_layout({**layout, "template": template} if template else layout)
        return fig

    for template in ("plotly_white", None):
        want = json.loads(build(go, template).to_json())
        spec = build(fj, WHITE if template else None).to_plotly_json()
        finish_template(spec)
        assert json.loads(fj.dumps(spec)) == want
        assert list(spec["layout"])[0] == "template"  # first, where plotly writes it
    import plotly.io as pio

    default = pio.templates.default
    try:  # a default a program set is the one a figure naming none gets
        pio.templates.default = "plotly_dark"
        spec = build(fj, None).to_plotly_json()
        finish_template(spec)
        assert (
            spec["layout"]["template"]
            == json.loads(build(go, None).to_json())["layout"]["template"]
        )
        pio.templates.default = None
        spec = build(fj, None).to_plotly_json()
        finish_template(spec)
        assert "template" not in spec["layout"]
    finally:
        pio.templates.default = default


def test_figure_json_writes_numpy_and_gaps_as_plotly_does():
    """pipeline/figure_json.py's JSON of numpy arrays (typed arrays, int64 narrowed), numpy
    scalars and NaN / ±inf (null) is the JSON plotly's classes write for the same figure."""
    go = pytest.importorskip("plotly.graph_objects")
    import numpy as np
    from flexopt.pipeline import figure_json as fj

    def build(module):
        fig = module.Figure()
        fig.add_trace(
            module.Scatter(
                x=np.array([0.0, 1.5, np.nan, 4.0]),
                y=[1.0, float("nan"), float("inf"), np.float64(2.5)],
                marker={"color": np.array([1, 2, 300, 4]), "size": np.int64(4)},
                customdata=np.array([[1, -70000], [2, 3], [4, 5], [6, 7]]),
                name="a",
            )
        )
        fig.add_trace(module.Mesh3d(x=[0, 1, 0], y=[0, 0, 1], z=[0, 0, 0],
                                    i=np.array([0]), j=np.array([1]), k=np.array([2], np.uint64),
                                    intensity=np.array([1.0, 2.0, 3.0], np.float32)))  # fmt: skip
        fig.update_layout({"height": 300, "xaxis": {"title": {"text": "x"}}})
        fig.update_layout(xaxis={"range": [0, 2]}, margin={"l": 10})  # merged, as plotly does
        return fig

    want = build(go)
    want.layout.template = None
    got = build(fj).to_plotly_json()
    text = fj.dumps(got)
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text) == json.loads(want.to_json())


def test_loading_a_constant_force_study_leaves_the_solid_and_scipy_solvers_unimported():
    """load_study of the default study (and so every run's start, and the pool's workers, which
    fork from it) imports no STL/3D-solid library and none of the scipy solvers it only uses
    later: trimesh with scipy.spatial and manifold3d (~0.4 s CPU), scipy.optimize,
    scipy.interpolate and scipy.integrate (geometry.solid, fea.prb, fea.contact, geometry.cam,
    optimise.thickness_fit, fea.constant_force_estimate import them where they are used)."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from flexopt.pipeline.study import load_study, resolve_study_path\n"
        "load_study(resolve_study_path('constant-force'))\n"
        "names = ('trimesh', 'manifold3d', 'scipy.optimize', 'scipy.interpolate',\n"
        "         'scipy.integrate', 'scipy.spatial')\n"
        "print(' '.join(n for n in names if n in sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == []


def test_the_part_solid_still_imports_what_it_needs():
    """geometry.solid's lazy imports: extrude and its STL work in a fresh process."""
    import subprocess
    import sys

    code = (
        "from shapely.geometry import box\n"
        "from flexopt.geometry.solid import extrude, stl_bytes\n"
        "mesh = extrude(box(0.0, 0.0, 10.0, 4.0), 2.0)\n"
        "print(round(float(mesh.volume), 9), len(stl_bytes(mesh)))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    volume, size = done.stdout.split()
    # 10 x 4 x 2 mm box: 12 triangles of 50 bytes after the 84-byte header
    assert float(volume) == pytest.approx(80.0, rel=1e-6) and int(size) == 84 + 12 * 50


def test_the_cli_starts_best_steps_child_before_the_study_and_ends_a_refused_run_at_once(
    monkeypatch, tmp_path, capsys
):
    """`flexopt run`: best.step's child is forked before load_study (its import of the STEP
    writer then uses the core that idles while the study loads); a study refused after that
    ends the child at once (abort, no wait for its import) and exits 2."""
    from flexopt.pipeline import cli
    from flexopt.pipeline.run import runner

    events = []

    class Child:
        def abort(self):
            events.append("abort")

        def close(self):
            events.append("close")

    def start():
        events.append("start")
        return Child()

    monkeypatch.setattr(runner, "start_early_step", start)

    def refuse(path):
        events.append("load_study")
        raise cli.StudyError("geometry.kind", "refused for the test")

    monkeypatch.setattr(cli, "load_study", refuse)
    study = tmp_path / "s.yaml"
    study.write_text("name: s\n")
    assert cli.main(["run", str(study), "--out", str(tmp_path / "run")]) == 2
    assert events == ["start", "load_study", "abort"]
    assert "refused for the test" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_an_early_step_child_aborted_mid_import_ends_at_once(monkeypatch):
    """EarlyStep.abort: a child still busy before its part (here: waiting a minute for an
    idle core, as a long import would keep it) is killed, not waited for."""
    import time

    from flexopt.pipeline.run import step_child

    if step_child.fork_context() is None:
        pytest.skip("no fork on this platform")
    monkeypatch.setattr(step_child, "_wait_for_idle_core", lambda *a, **k: time.sleep(60.0))
    early = step_child.EarlyStep.start()
    assert early is not None and early.process.is_alive()
    t0 = time.monotonic()
    early.abort()
    assert time.monotonic() - t0 < 4.0
    assert not early.process.is_alive()
    early.abort()  # again: nothing left to end


def test_evaluate_makes_its_plots_in_a_child_and_remakes_here_what_the_child_could_not(
    monkeypatch, tmp_path
):
    """`flexopt evaluate` draws force_displacement.png and makes the VTU files in a forked
    child while it writes report.html. A file the child fails to make is made again in this
    process: the same bytes as a plot made here; a plot that fails here too ends the evaluate
    with its own error, as before the child."""
    from flexopt.pipeline import plots
    from flexopt.pipeline.evaluate import evaluate_study
    from flexopt.pipeline.fork import fork_context
    from flexopt.pipeline.study import load_study

    study = load_study("cantilever")
    here = os.getpid()
    real = plots.plot_response
    where = []

    def only_here(*args, **kwargs):
        where.append(os.getpid())
        if os.getpid() != here:
            raise RuntimeError("not in the child")
        return real(*args, **kwargs)

    monkeypatch.setattr(plots, "plot_response", only_here)
    out = evaluate_study(study, out=tmp_path / "a").run_dir
    if fork_context() is not None:  # the child's attempt is not seen here; the remake is
        assert where == [here]
    monkeypatch.setattr(plots, "plot_response", real)
    again = evaluate_study(study, out=tmp_path / "b").run_dir
    for name in ("force_displacement.png", "design.vtu", "design.pvd"):
        assert (out / name).read_bytes() == (again / name).read_bytes()
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in again.iterdir())

    def broken(*args, **kwargs):
        raise ValueError("no plot today")

    monkeypatch.setattr(plots, "plot_response", broken)
    with pytest.raises(ValueError, match="no plot today"):
        evaluate_study(study, out=tmp_path / "c")


def test_an_early_step_child_gets_the_runs_priority_back_when_it_is_sent_the_part(monkeypatch):
    """A lowered EarlyStep (nice 19, SCHED_IDLE) is put back at the run's priority by the run
    the moment it is sent the part, even while its own import is still going on: on a busy
    machine a SCHED_IDLE child gets no CPU time, and the run's end waited for it."""
    import sys
    import time

    from flexopt.pipeline.run import step_child

    if step_child.fork_context() is None or not step_child.can_restore_priority():
        pytest.skip("no fork here, or this user may not raise a process's priority")

    class SlowFinder:  # the child's import of the STEP writer takes a minute
        @staticmethod
        def find_spec(name, path=None, target=None):
            if name == "build123d":
                time.sleep(60.0)
            return None

    monkeypatch.delitem(sys.modules, "build123d", raising=False)
    monkeypatch.setattr(sys, "meta_path", [SlowFinder, *sys.meta_path])
    early = step_child.EarlyStep.start(nice=step_child.EARLY_STEP_NICE)
    assert early is not None
    pid, ours = early.process.pid, os.getpriority(os.PRIO_PROCESS, 0)
    try:
        deadline = time.monotonic() + 30.0  # it lowers itself first thing
        while os.sched_getscheduler(pid) != os.SCHED_IDLE:
            assert time.monotonic() < deadline, "the child did not lower its priority"
            time.sleep(0.01)
        assert early.send("plate")
        assert os.sched_getscheduler(pid) == os.SCHED_OTHER
        # the nice level polled: once in CI (session 35, a loaded host) it read 19 right after
        # the restore, the scheduler already SCHED_OTHER; the cause was not found
        deadline = time.monotonic() + 5.0
        while os.getpriority(os.PRIO_PROCESS, pid) != ours:
            assert time.monotonic() < deadline, os.getpriority(os.PRIO_PROCESS, pid)
            time.sleep(0.01)
    finally:
        early.abort()


def test_the_timeline_deals_each_batch_to_two_workers_largest_first(capsys):
    """benchmarks/fixed_costs.py --parts timeline: a GA batch of designs (CPU 3, 2, 2 s) is
    dealt 3 | 2 + 2, so two workers need 4 s and leave 1 core-second idle; a gradient batch of
    one call (CPU 1 s) and one design (0.5 s) needs 1 s and leaves 0.5 idle; the preload
    thread's CPU and start are printed against the first batch's start."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "fixed_costs.py"
    spec = importlib.util.spec_from_file_location("fixed_costs_bench", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)

    def span(label, t0, t1, cpu):
        return {"label": label, "t0": t0, "t1": t1, "cpu": cpu}

    designs = [span("design", 10.0 + i, 10.5 + i, 0.0) for i in range(8)]  # 8 designs of 0 s
    rows = [
        span("batch", 10.0, 20.0, 0.0),
        span("design", 10.0, 13.0, 3.0),
        span("design", 10.0, 12.0, 2.0),
        span("design", 12.0, 14.0, 2.0),
        *designs,
        span("batch", 21.0, 22.0, 0.0),
        span("call", 21.0, 22.0, 1.0),
        span("design", 21.0, 21.5, 0.5),
        span("design", 25.0, 26.0, 9.0),  # outside every batch (the report's detail)
        span("preload", 12.5, 30.0, 1.25),
    ]
    bench._timeline_table(rows)
    lines = capsys.readouterr().out.splitlines()
    ga = next(line.split() for line in lines if line.strip().startswith("GA"))
    gradient = next(line.split() for line in lines if line.strip().startswith("gradient"))
    assert ga[1:] == ["1", "11", "0", "7.000", "4.000", "1.000", "10.000"]
    assert gradient[1:] == ["1", "1", "1", "1.500", "1.000", "0.500", "1.000"]
    assert any("1.250 s CPU, from 2.50 s to 20.00 s" in line for line in lines)
