"""The compiled beam kernel (numba, fea/_beam_kernels.py) against the numpy reference path.

Both paths run the same formulation and make the same decisions (sub-steps, Newton iterations,
branch guards, stability checks), so they must return the same response to round-off. "Agree to
1e-9" is relative to the scale of each quantity over the traced curve (largest |value| over the
rows; forces against the largest end force, moments against it times L): a pointwise relative
difference is meaningless where a force crosses zero or a free end's moment is a residual. The
round-off both paths carry grows with the slenderness (an axial force is EA times a strain
computed to ~1e-16, against bending forces ~EI/L^2: a ratio 12 (L/t)^2), so the designs here have
t/L >= 1/100 as the shipped examples do; at t/L = 1/1000 (benchmarks/beam_vs_opensees.py) the
forces agree to ~3e-9 of the end force, the rest to 1e-12.

Then every test of tests/fea/test_beam.py and tests/fea/test_beam_stability.py runs again here
with the numpy reference path (FLEXOPT_BEAM_KERNEL=numpy); in their own modules they run with the
default kernel, the compiled one.
"""

from __future__ import annotations

import flexopt.fea.beam as beam_mod
import numpy as np
import pytest
import test_beam
import test_beam_stability
from flexopt.fea.beam import BeamModel, BeamSettings, EndDrive
from flexopt.fea.errors import FeaError
from flexopt.fea.materials import Material, get_material
from flexopt.geometry.profile import BeamProfile

numba = pytest.importorskip("numba", reason="the compiled kernel needs numba")

MAT = Material("test", E_MPa=2000.0, nu=0.3, yield_MPa=50.0)
TOL = 1e-9


def _straight(L: float, t: float, b: float) -> BeamProfile:
    return BeamProfile([[0.0, 0.0], [L, 0.0]], [t, t], b)


def _half_cosine(span: float, rise: float, t: float, b: float, points: int = 21) -> BeamProfile:
    """Half of a cosine-shaped clamped-clamped arch: level at its start and at its apex."""
    x = np.linspace(0.0, span, points)
    y = 0.5 * rise * (1.0 - np.cos(np.pi * x / span))
    return BeamProfile(np.stack([x, y], axis=1), [t] * points, b)


def _constant_force_profile() -> BeamProfile:
    """Paper 003's constant-force beam (Table 3 optimum) as the constant_force study builds it."""
    from flexopt.geometry.constant_force import TABLE3_OPTIMUM, beam_profile

    return beam_profile(TABLE3_OPTIMUM, end_flexures="centred")


def _cases() -> dict[str, tuple]:
    """(profile, material, start, drive, n_elements) of the agreement designs."""
    L, t, b = 100.0, 1.0, 2.0
    ei = MAT.E_MPa * b * t**3 / 12.0
    strut_L, strut_t, strut_b = 50.0, 1.0, 8.0
    p_euler = np.pi**2 * MAT.E_MPa * strut_b * strut_t**3 / 12.0 / (4.0 * strut_L**2)
    d_clamped = 4.0 * np.pi**2 * strut_t**2 / 12.0 / strut_L  # P_cr L / EA, clamped-clamped
    return {
        # dead tip force to alpha = 10: 82 degrees of tip rotation
        "cantilever-force": (
            _straight(L, t, b),
            MAT,
            "clamped",
            EndDrive("force", (0.0, 1.0), 10.0 * ei / L**2, 20, "free", "free"),
            20,
        ),
        "fixed-guided": (
            _straight(L, t, b),
            MAT,
            "clamped",
            EndDrive("displacement", (0.0, 1.0), 0.8 * L, 20, "fixed", "free"),
            20,
        ),
        "constant-force": (
            _constant_force_profile(),
            get_material("ABS"),
            "clamped",
            EndDrive("displacement", (-1.0, 0.0), 30.0, 60, "fixed", "fixed"),
            60,
        ),
        # a straight strut pushed past its Euler load (force control): stays straight, flagged
        "strut-force": (
            _straight(strut_L, strut_t, strut_b),
            MAT,
            "clamped",
            EndDrive("force", (-1.0, 0.0), 1.5 * p_euler, 10, "free", "free"),
            10,
        ),
        # a clamped-clamped strip shortened 3 x past its critical shortening
        "strut-displacement": (
            _straight(strut_L, strut_t, strut_b),
            MAT,
            "clamped",
            EndDrive("displacement", (-1.0, 0.0), 3.0 * d_clamped, 10, "fixed", "fixed"),
            10,
        ),
        # half a pre-shaped bistable beam pushed down through its snap to the second position
        "snap-through": (
            _half_cosine(28.0, 3.0, 0.9, 10.0),
            get_material("PETG"),
            "clamped",
            EndDrive("displacement", (0.0, -1.0), 6.0, 30, "fixed", "fixed"),
            30,
        ),
        # a bowed strip followed on its stable buckled branch (the imperfection selects it)
        "bowed-strip": (
            BeamProfile(
                [[0.0, 0.0], [strut_L, 0.0]],
                [strut_t, strut_t],
                strut_b,
                curvature_per_mm=[-1.0 / ((strut_L**2 / 4.0 + 0.05**2) / 0.1)],
            ),
            MAT,
            "clamped",
            EndDrive("displacement", (-1.0, 0.0), 15.0 * d_clamped, 10, "fixed", "fixed"),
            20,
        ),
    }


CASES = _cases()
#: designs whose peak stress sits at one sampling point (not tied by a symmetry)
UNIQUE_PEAK = {"cantilever-force", "constant-force"}


def _solve(case: str, kernel: str):
    profile, material, start, drive, n_el = CASES[case]
    model = BeamModel(profile, material, start, BeamSettings(n_elements=n_el, kernel=kernel))
    assert model.kernel == kernel
    return model.solve(drive), profile.length_mm


def _scale(*arrays: np.ndarray) -> float:
    return max(float(np.nanmax(np.abs(a))) for a in arrays)


@pytest.mark.parametrize("case", list(CASES))
def test_compiled_and_reference_paths_agree(case):
    ref, L = _solve(case, "numpy")
    fast, _ = _solve(case, "numba")
    assert ref.extra["kernel"] == "numpy" and fast.extra["kernel"] == "numba"
    # the same decisions: rows, iterations, sub-steps, stability, messages
    assert fast.ok == ref.ok and fast.message == ref.message
    np.testing.assert_array_equal(fast.converged, ref.converged)
    np.testing.assert_array_equal(fast.iterations, ref.iterations)
    np.testing.assert_array_equal(fast.stable, ref.stable)
    assert fast.extra["substeps"] == ref.extra["substeps"]
    assert fast.unstable == ref.unstable
    assert fast.unstable_message == ref.unstable_message
    np.testing.assert_equal(fast.critical_value, ref.critical_value)
    # the same numbers, to 1e-9 of each quantity's scale over the curve
    force = _scale(ref.force_N, ref.transverse_force_N)
    scales = {
        "force_N": force,
        "transverse_force_N": force,
        "moment_Nmm": force * L,
        "displacement_mm": L,
        "transverse_displacement_mm": L,
        "shapes_mm": _scale(ref.shapes_mm),
        "end_rotation_rad": max(1.0, _scale(ref.end_rotation_rad)),
        "peak_stress_MPa": _scale(ref.peak_stress_MPa),
    }
    for name, scale in scales.items():
        a, b = getattr(ref, name), getattr(fast, name)
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
        ok = ~np.isnan(a)
        worst = float(np.max(np.abs(a[ok] - b[ok]), initial=0.0)) / scale
        assert worst <= TOL, (name, worst)
    # Where the peak sits: the same sampling point, unless two carry the same peak to round-off
    # (both ends of a symmetric design, every point of a uniformly compressed strut), where either
    # path may pick either one, as the reference itself would on another BLAS.
    if case in UNIQUE_PEAK:
        np.testing.assert_array_equal(fast.peak_stress_s_mm, ref.peak_stress_s_mm)


def test_the_cases_exercise_what_they_are_named_for():
    """The buckling-type designs really are: flagged struts, a snap with a falling force."""
    strut, _ = _solve("strut-force", "numba")
    assert strut.unstable and not strut.stable[-1] and strut.stable[0]
    squeezed, _ = _solve("strut-displacement", "numba")
    assert squeezed.unstable
    snap, _ = _solve("snap-through", "numba")
    assert snap.ok
    peak = int(np.argmax(snap.force_N))
    assert 0 < peak < len(snap.force_N) - 1 and snap.force_N.min() < 0.0 < snap.force_N.max()
    bowed, _ = _solve("bowed-strip", "numba")
    assert bowed.ok and not bowed.unstable


def test_assemble_and_stress_agree_with_the_reference_on_a_random_state():
    """The semi-private ``_assemble`` / ``_stress`` that fea/constrained_beams.py and
    fea/mechanism.py call: same layout, same values to round-off, on a kinked arc beam."""
    profile = BeamProfile(
        [[0.0, 0.0], [60.0, 30.0], [100.0, 0.0]],
        [1.0, 2.0, 1.5],
        3.0,
        curvature_per_mm=[0.01, -0.005],
    )
    models = {
        k: BeamModel(profile, MAT, settings=BeamSettings(n_elements=7, kernel=k))
        for k in ("numpy", "numba")
    }
    n = models["numpy"].n_dofs
    rng = np.random.default_rng(3)
    frame = np.array([[0.6, 0.8], [-0.8, 0.6]])
    for _ in range(3):
        q = rng.normal(size=n) * 0.3
        (r0, ab0), (r1, ab1) = (models[k]._assemble(q, frame) for k in ("numpy", "numba"))
        assert ab1.shape == ab0.shape and ab1.flags.f_contiguous
        np.testing.assert_allclose(r1, r0, rtol=0, atol=1e-12 * np.abs(r0).max())
        np.testing.assert_allclose(ab1, ab0, rtol=0, atol=1e-12 * np.abs(ab0).max())
        s0, s1 = (models[k]._stress(q) for k in ("numpy", "numba"))
        assert s1[0] == pytest.approx(s0[0], rel=1e-12) and s1[1] == s0[1]
    # a slice of a longer vector (how the constrained engines pass their beams' DOFs)
    z = np.concatenate([np.zeros(5), q])
    np.testing.assert_allclose(models["numba"]._assemble(z[5:], frame)[0], r1, rtol=0, atol=0)


def test_the_kernel_setting_and_the_environment_variable(monkeypatch):
    profile = _straight(50.0, 1.0, 2.0)
    monkeypatch.setenv(beam_mod.KERNEL_ENV, "numpy")
    assert BeamModel(profile, MAT).kernel == "numpy"
    assert BeamModel(profile, MAT, settings=BeamSettings(kernel="numba")).kernel == "numba"
    monkeypatch.setenv(beam_mod.KERNEL_ENV, "numba")
    assert BeamModel(profile, MAT).kernel == "numba"
    monkeypatch.delenv(beam_mod.KERNEL_ENV)
    assert BeamModel(profile, MAT).kernel == "numba"  # the default when numba imports
    monkeypatch.setenv(beam_mod.KERNEL_ENV, "fortran")
    with pytest.raises(FeaError, match="FLEXOPT_BEAM_KERNEL"):
        BeamModel(profile, MAT)
    with pytest.raises(FeaError, match="kernel"):
        BeamModel(profile, MAT, settings=BeamSettings(kernel="c"))


def test_without_numba_the_reference_path_runs(monkeypatch):
    """A platform where numba does not import falls back silently to the numpy path."""
    monkeypatch.setattr(beam_mod, "_compiled", lambda: None)
    monkeypatch.delenv(beam_mod.KERNEL_ENV, raising=False)
    profile = _straight(50.0, 1.0, 2.0)
    model = BeamModel(profile, MAT, settings=BeamSettings(kernel="numba"))
    assert model.kernel == "numpy"
    res = model.solve(EndDrive("displacement", (0.0, 1.0), 5.0, 2, "free", "free"))
    assert res.ok and res.extra["kernel"] == "numpy"


# -- the existing beam tests once more, on the numpy reference path ------------------------------


@pytest.fixture(autouse=True)
def _reference_kernel_for_the_rerun(request, monkeypatch):
    """The re-collected tests below (named test_reference_*) run with FLEXOPT_BEAM_KERNEL=numpy."""
    if request.node.originalname.startswith("test_reference_"):
        monkeypatch.setenv(beam_mod.KERNEL_ENV, "numpy")


def _rerun(module) -> None:
    for name, obj in vars(module).items():
        if name.startswith("test_") and callable(obj):
            globals()[f"test_reference_{module.__name__}_{name[5:]}"] = obj


_rerun(test_beam)
_rerun(test_beam_stability)


def test_warm_up_compiles_the_kernel_the_models_use():
    # the process pool calls warm_up before it forks, so workers inherit the compiled code
    from flexopt.fea.beam import BeamSettings, resolve_kernel, warm_up

    assert warm_up() == resolve_kernel(BeamSettings().kernel)


# -- the linear solve: banded Cholesky first, the pivoting LU when it fails ----------------------


def _band_matrix(n: int, rng: np.random.Generator, shift: float) -> np.ndarray:
    """Dense symmetric matrix with half-bandwidth 8, rows scaled like a beam's (u, v, theta)
    fields (1e4 : 1e4 : 1): ``shift`` moves its spectrum (positive definite for a large shift)."""
    a = rng.normal(size=(n, n))
    a = np.triu(np.tril(a, 8), -8)
    a = a + a.T + shift * np.eye(n)
    s = np.tile([1e2, 1e2, 1.0], n // 3 + 1)[:n]
    return a * s[:, None] * s[None, :]


def _to_gbsv(a: np.ndarray) -> np.ndarray:
    """Dense -> LAPACK gbsv storage (kl = ku = 8), Fortran-ordered."""
    n, k = a.shape[0], beam_mod._BAND
    ab = np.zeros((3 * k + 1, n), order="F")
    for j in range(n):
        for i in range(max(0, j - k), min(n, j + k + 1)):
            ab[2 * k + i - j, j] = a[i, j]
    return ab


@pytest.mark.parametrize("shift", [40.0, -3.0], ids=["definite", "indefinite"])
def test_the_band_solve_takes_cholesky_or_falls_back_to_lu(shift):
    """Both paths solve A x = b exactly (to round-off of a dense solve) whether A is positive
    definite (banded Cholesky) or indefinite (Cholesky refuses: b untouched, then the LU)."""
    from flexopt.fea import _beam_kernels as bk

    rng = np.random.default_rng(7)
    n = 45
    a = _band_matrix(n, rng, shift)
    definite = bool(np.all(np.linalg.eigvalsh(a) > 0))
    assert definite == (shift > 0)  # the two cases are what they are named for
    b = rng.normal(size=n)
    exact = np.linalg.solve(a, b)
    ab = _to_gbsv(a)

    # the compiled Cholesky alone: solves, or refuses without touching b
    up = np.empty((n, bk.KD + 1))
    x = b.copy()
    assert bk.pbsv(ab.T.copy(), x, up) == definite
    if definite:
        np.testing.assert_allclose(x, exact, rtol=0, atol=1e-10 * np.abs(exact).max())
    else:
        np.testing.assert_array_equal(x, b)

    # the held solve on both paths (nothing held): same solution either way
    x = b.copy()
    info = bk._solve_held(
        ab.T.copy(), x, np.zeros(0, np.int64), -1, 0.0,
        np.empty(n, np.int64), up,
    )  # fmt: skip
    assert info == 0
    np.testing.assert_allclose(x, exact, rtol=0, atol=1e-10 * np.abs(exact).max())
    none = np.zeros(0, int)
    bc = beam_mod._Constraints(none, np.arange(n), none, none, none, -1, -1)
    x, info = beam_mod._solve_constrained(ab.copy(order="F"), b.copy(), bc, 0.0)
    assert info == 0
    np.testing.assert_allclose(x, exact, rtol=0, atol=1e-10 * np.abs(exact).max())


def test_most_newton_solves_of_a_constant_force_design_are_cholesky(monkeypatch):
    """The speed of the kernel rests on the held tangent being symmetric positive definite in
    most Newton iterations (a stable post-buckled path): count the numpy path's LAPACK calls on
    paper 003's Table 3 design. A tangent that lost its symmetry, or a solve that stopped trying
    Cholesky first, would show here as LU solves."""
    calls = {"cholesky": 0, "lu": 0}
    pbtrs, gbsv = beam_mod.dpbtrs, beam_mod.dgbsv

    def count(key, fn):
        def wrapped(*args, **kwargs):
            calls[key] += 1
            return fn(*args, **kwargs)

        return wrapped

    monkeypatch.setattr(beam_mod, "dpbtrs", count("cholesky", pbtrs))
    monkeypatch.setattr(beam_mod, "dgbsv", count("lu", gbsv))
    model = BeamModel(
        _constant_force_profile(),
        get_material("PLA"),
        settings=BeamSettings(n_elements=60, kernel="numpy"),
    )
    response = model.solve(EndDrive("displacement", (-1.0, 0.0), 30.0, 30, "fixed", "fixed"))
    assert response.ok
    total = calls["cholesky"] + calls["lu"]
    assert total > 60 and calls["cholesky"] >= 0.8 * total, calls
