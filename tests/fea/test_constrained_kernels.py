"""The compiled constrained-beam Newton (fea/_constrained_kernels.py) against the scipy reference.

Both paths solve the same KKT systems with the same decisions (sub-steps, Newton tests, damping,
stability), so the traced states must agree to round-off. "Agree to 1e-9" is relative to the
scale of each quantity over the curve (largest |value| over the rows), as in
tests/fea/test_beam_kernels.py. The beams run on the compiled beam kernel in both (the beam kernel
has its own agreement test); only ``ConstrainedSettings.kernel`` differs. Cases: a strut driven
past its Euler load (rows flagged unstable: the flags must agree), a cross-axis pivot (two beams,
two extra unknowns, path-dependent constraints), a leaf joint's tip on a turning line and its
follower tip force (applied loads with a derivative: the one-iteration-at-a-time path), and two
beams numbered so that the tie between them is not local (the bordering cannot take it and must
hand each sub-step to the reference).

Then the tests of the pivot, leaf-joint, mechanism and constrained-stability modules that use
the engine run once more here with FLEXOPT_BEAM_KERNEL=numpy (the reference everywhere); in
their own modules they run on the compiled paths.
"""

from __future__ import annotations

import importlib.util
import inspect
import math
from dataclasses import replace
from pathlib import Path

import flexopt.fea.beam as beam_mod
import flexopt.fea.constrained_beams as cb
import numpy as np
import pytest
import scipy.sparse as sp
from flexopt.fea.beam import BeamModel, BeamSettings
from flexopt.fea.constrained_beams import (
    ConstrainedBeams,
    ConstrainedResponse,
    ConstrainedSettings,
    kkt_negative_count,
)
from flexopt.fea.leaf_joint import _follower_system
from flexopt.fea.materials import Material, get_material
from flexopt.fea.pivot import _pivot_system
from flexopt.geometry.flexures import CrossAxis
from flexopt.geometry.leaf_joint import LeafJoint
from flexopt.geometry.profile import BeamProfile

numba = pytest.importorskip("numba", reason="the compiled kernel needs numba")

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
TOL = 1e-9


def _with_kernel(system: ConstrainedBeams, kernel: str) -> ConstrainedBeams:
    """The same beams, constraints and loads on the other path (the closures read ``system``
    only for its numbering, which both share)."""
    return ConstrainedBeams(
        system.beams,
        system.n_extra,
        system.constraints,
        system.loads,
        replace(system.settings, kernel=kernel),
    )


def _strut() -> tuple[ConstrainedBeams, np.ndarray]:
    """A clamped-clamped strut shortened to twice its Euler shortening (P = 4 pi^2 EI / L^2)."""
    L, t, b = 50.0, 1.0, 8.0
    model = BeamModel(
        BeamProfile([[0.0, 0.0], [L, 0.0]], [t, t], b), MAT, settings=BeamSettings(n_elements=10)
    )
    d_euler = 4.0 * np.pi**2 * t**2 / 12.0 / L

    def constraints(shortening: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(6)
        d = np.zeros(6)
        row = system.clamp_start(C, 0, 0)
        for f, value in ((0, -shortening), (1, 0.0), (2, 0.0)):
            C[row, system.dof(0, -1, f)] = 1.0
            d[row] = value
            row += 1
        return C, d

    system = ConstrainedBeams([model], 0, constraints)
    return system, np.array([0.0, 0.5, 0.9, 1.02, 1.5, 2.0]) * d_euler


def _cross_axis() -> tuple[ConstrainedBeams, np.ndarray]:
    f = CrossAxis(length_mm=14.0, thickness_mm=0.6, width_mm=5.0)
    system, _ = _pivot_system(f, MAT, 20)
    return system, np.radians(np.linspace(0.0, 30.0, 7))


def _sliding_leaf() -> tuple[ConstrainedBeams, np.ndarray]:
    """The leaf joint's structure (a): the leaf tip on the arm's line, which turns by theta."""
    joint = LeafJoint(arm_mm=56.0, effective_length_mm=28.0)
    model = BeamModel(
        BeamProfile([[0.0, 0.0], [28.0, 0.0]], [0.5, 0.5], 11.0),
        get_material("65Mn"),
        settings=BeamSettings(n_elements=20),
    )

    def constraints(theta: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(4)
        row = system.clamp_start(C, 0, 0)
        n = joint.arm_normal(theta)
        C[row, system.dof(0, -1, 0)] = n[0]
        C[row, system.dof(0, -1, 1)] = n[1]
        d = np.zeros(4)
        d[row] = joint.arm_mm * math.sin(theta)
        return C, d

    system = ConstrainedBeams([model], 0, constraints)
    return system, np.radians(np.linspace(0.0, 30.0, 7))


def _follower() -> tuple[ConstrainedBeams, np.ndarray]:
    """A clamped leaf under a follower tip force alpha EI / l^2 (loads with a derivative)."""
    joint = LeafJoint(arm_mm=56.0, effective_length_mm=28.0)
    return _follower_system(joint, get_material("65Mn"), 20), np.linspace(0.0, 2.0, 6)


def _non_local() -> tuple[ConstrainedBeams, np.ndarray]:
    """Beam 1 clamped at the ground, beam 0 welded to its end and carrying a pushed tip: beam 0
    comes first in z, so the weld ties DOFs a whole beam apart (not local) and no local row holds
    beam 0: every sub-step goes to the reference."""
    prof = BeamProfile([[0.0, 0.0], [20.0, 0.0]], [0.8, 0.8], 5.0)
    second = BeamProfile([[20.0, 0.0], [40.0, 0.0]], [0.8, 0.8], 5.0)
    models = [BeamModel(p, MAT, settings=BeamSettings(n_elements=6)) for p in (second, prof)]

    def constraints(v: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(7)
        d = np.zeros(7)
        row = system.clamp_start(C, 0, 1)
        for f in (0, 1, 2):
            C[row, system.dof(0, 0, f)] = 1.0
            C[row, system.dof(1, -1, f)] = -1.0
            row += 1
        C[row, system.dof(0, -1, 1)] = 1.0
        d[row] = v
        return C, d

    system = ConstrainedBeams(models, 0, constraints)
    return system, np.linspace(0.0, 8.0, 5)


CASES = {
    "strut_past_euler": _strut,
    "cross_axis_pivot": _cross_axis,
    "sliding_leaf": _sliding_leaf,
    "follower_tip_force": _follower,
    "non_local_tie": _non_local,
}


def _agree(a: np.ndarray, b: np.ndarray, what: str) -> None:
    scale = max(float(np.nanmax(np.abs(b), initial=0.0)), 1e-300)
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=what)
    diff = float(np.nanmax(np.abs(a - b), initial=0.0))
    assert diff <= TOL * scale, f"{what}: differs by {diff:.3g} of scale {scale:.3g}"


def _assert_same(fast: ConstrainedResponse, ref: ConstrainedResponse) -> None:
    assert fast.ok == ref.ok and fast.message == ref.message
    np.testing.assert_array_equal(fast.converged, ref.converged)
    np.testing.assert_array_equal(fast.stable, ref.stable)
    for i in range(len(fast.offsets) - 1):
        q_f, q_r = fast.beam_state(i).reshape(-1, 3), ref.beam_state(i).reshape(-1, 3)
        _agree(q_f[:, :2], q_r[:, :2], f"beam {i} translations")
        _agree(q_f[:, 2], q_r[:, 2], f"beam {i} rotations")
        f_f, f_r = fast.beam_internal(i).reshape(-1, 3), ref.beam_internal(i).reshape(-1, 3)
        _agree(f_f[:, :2], f_r[:, :2], f"beam {i} nodal forces")
        _agree(f_f[:, 2], f_r[:, 2], f"beam {i} nodal moments")
    _agree(fast.extra, ref.extra, "extra unknowns")
    _agree(fast.multipliers, ref.multipliers, "constraint forces")
    _agree(fast.peak_stress_MPa, ref.peak_stress_MPa, "peak stress")


@pytest.mark.parametrize("case", sorted(CASES))
def test_compiled_and_reference_paths_agree(case, monkeypatch):
    monkeypatch.delenv(beam_mod.KERNEL_ENV, raising=False)
    system, params = CASES[case]()
    fast, ref = _with_kernel(system, "numba"), _with_kernel(system, "numpy")
    assert fast.kernel == "numba" and ref.kernel == "numpy"
    handed_back = []
    compiled = fast._newton_compiled

    def spy(*args):
        out = compiled(*args)
        handed_back.append(out is None)
        return out

    monkeypatch.setattr(fast, "_newton_compiled", spy)
    r_fast, r_ref = fast.solve(params), ref.solve(params)
    assert r_ref.ok, r_ref.message
    _assert_same(r_fast, r_ref)
    # the bordering takes every sub-step of the held systems and none of the non-local one
    assert handed_back and all(handed_back) == (case == "non_local_tie")
    assert not any(handed_back) or case == "non_local_tie"
    if case == "strut_past_euler":
        assert r_fast.unstable and not r_fast.stable[-1] and r_fast.stable[1]


def test_the_non_local_tie_is_the_single_beam_it_welds():
    # the two welded halves are one 40 mm cantilever pushed at its tip, on either path
    system, params = _non_local()
    one = BeamModel(
        BeamProfile([[0.0, 0.0], [40.0, 0.0]], [0.8, 0.8], 5.0),
        MAT,
        settings=BeamSettings(n_elements=12),
    )

    def constraints(v: float) -> tuple[np.ndarray, np.ndarray]:
        C = single.rows(4)
        d = np.zeros(4)
        row = single.clamp_start(C, 0, 0)
        C[row, single.dof(0, -1, 1)] = 1.0
        d[row] = v
        return C, d

    single = ConstrainedBeams([one], 0, constraints)
    welded, alone = system.solve(params), single.solve(params)
    assert welded.ok and alone.ok
    # the tip force (the multiplier of the push) of the same mesh: equal to the solver tolerance
    np.testing.assert_allclose(welded.multipliers[:, -1], alone.multipliers[:, -1], rtol=1e-7)


def _random_kkt(rng: np.random.Generator, n: int, m: int, shift: float):
    """A banded symmetric H with eigenvalues shifted by ``shift`` and a sparse G (m, n)."""
    A = np.zeros((n, n))
    for k in range(4):
        v = rng.normal(size=n - k)
        A += np.diag(v, k) + (np.diag(v, -k) if k else 0)
    H = A + (shift - np.linalg.eigvalsh(A)[0]) * np.eye(n)
    G = np.zeros((m, n))
    for r in range(m):
        cols = rng.choice(n, size=3, replace=False)
        G[r, cols] = rng.normal(size=3)
    return H, G


@pytest.mark.parametrize("shift", [1.0, -0.5, -3.0])
def test_the_compiled_inertia_counts_what_the_reduced_hessian_says(shift):
    # exact count computed here: m + (negative eigenvalues of Z^T H Z), Z the null space of G
    rng = np.random.default_rng(7)
    for _ in range(5):
        H, G = _random_kkt(rng, 40, 6, shift)
        _, _, vt = np.linalg.svd(G)
        Z = vt[G.shape[0] :].T
        expected = G.shape[0] + int((np.linalg.eigvalsh(Z.T @ H @ Z) < 0).sum())
        Hs, Gs = sp.csr_matrix(H), sp.csr_matrix(G)
        assert kkt_negative_count(Hs, Gs, kernel="numba") == expected
        assert kkt_negative_count(Hs, Gs, kernel="numpy") == expected


def test_the_kernel_setting_and_the_environment_variable(monkeypatch):
    system, _ = _strut()
    monkeypatch.setenv(beam_mod.KERNEL_ENV, "numpy")
    assert _with_kernel(system, "auto").kernel == "numpy"
    monkeypatch.setenv(beam_mod.KERNEL_ENV, "numba")
    assert _with_kernel(system, "auto").kernel == "numba"
    # beams on the numpy beam kernel: the compiled Newton has no tables, the reference runs
    monkeypatch.setenv(beam_mod.KERNEL_ENV, "numpy")
    slow, _ = _strut()
    assert _with_kernel(slow, "numba").kernel == "numpy"
    monkeypatch.setattr(cb, "_kernels", lambda: None)
    monkeypatch.setenv(beam_mod.KERNEL_ENV, "numba")
    assert _with_kernel(system, "numba").kernel == "numpy"


def test_settings_default_follows_the_beam_switch():
    assert ConstrainedSettings().kernel == "auto"


def test_warm_up_compiles_the_constrained_kernels():
    from flexopt.fea.constrained_beams import warm_up

    assert warm_up() == cb.resolve_constrained_kernel("auto")


# -- the engine's own tests once more, on the reference path -------------------------------------

_HERE = Path(__file__).resolve().parent
_USES_ENGINE = (
    "beam_pivot",
    "ConstrainedBeams",
    "_response",
    "joint_elastic_limit",
    "solve_mechanism",
    "kkt_negative_count",
    "strut_system",
)


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(autouse=True)
def _reference_for_the_rerun(request, monkeypatch):
    """The re-collected tests below (named test_reference_*) run with FLEXOPT_BEAM_KERNEL=numpy."""
    if request.node.originalname.startswith("test_reference_"):
        monkeypatch.setenv(beam_mod.KERNEL_ENV, "numpy")


def _rerun(path: Path, only_engine: bool) -> None:
    module = _load(path, f"_rerun_{path.stem}")
    for name, obj in vars(module).items():
        if not (name.startswith("test_") and callable(obj)):
            continue
        if only_engine and not any(w in inspect.getsource(obj) for w in _USES_ENGINE):
            continue
        globals()[f"test_reference_{path.stem}_{name[5:]}"] = obj


_rerun(_HERE / "test_constrained_stability.py", False)
_rerun(_HERE / "test_mechanism.py", False)
_rerun(_HERE.parent / "geometry" / "test_flexures.py", True)
_rerun(_HERE.parent / "geometry" / "test_leaf_joint.py", True)
