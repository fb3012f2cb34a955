"""Creep and relaxation of printed polymers: a linear-viscoelastic power law (Findley).

The law
-------
Findley's power law of creep, ``eps(t) = eps0 + m t^n`` under a constant stress ``sigma``,
written for linear viscoelasticity (``eps0`` and ``m`` both proportional to ``sigma``) as the
creep compliance

    J(t) = (1 / E0) (1 + (t / tau)^n)          0 < n <= 1, tau > 0 (h)

with ``E0 = sigma / eps0`` the instantaneous modulus and ``tau = (eps0 / m)^(1/n)`` the time at
which the creep strain equals the elastic strain. Its relaxation modulus, by exact
interconversion (the Volterra identity ``int_0^t E_R(t - s) dJ(s) = 1``, in the Laplace domain
``s^2 J(s) E(s) = 1``: the Carson transforms ``s J(s)`` and ``s E(s)`` are reciprocal), is

    E_R(t) = E0 E_n(-Gamma(1 + n) (t / tau)^n)

where ``E_n`` is the one-parameter Mittag-Leffler function (:func:`mittag_leffler`). The factor
``Gamma(1 + n)`` is exact: the Laplace transform of ``(t/tau)^n`` is ``Gamma(1+n) tau^-n
s^-(n+1)``, so ``E(s) = E0 s^(n-1) / (s^n + Gamma(1+n) tau^-n)``, the transform of
``E0 E_n(-Gamma(1+n) t^n / tau^n)``. (Without it, ``E0 E_n(-(t/tau)^n)`` is the relaxation of
``J = (1/E0)(1 + (t/tau)^n / Gamma(1+n))``, a different law.) For ``n = 1`` the law is the
Maxwell-like ``J = (1 + t/tau)/E0`` and ``E_R = E0 exp(-t/tau)``.

Temperature
-----------
Time-temperature superposition: the law is fitted at ``reference_temperature_C``; at another
temperature the hold time is replaced by the reduced time ``t / a_T`` with an Arrhenius
(``log10 a_T = Ea / (R ln 10) (1/T - 1/T_ref)``, T in K) or WLF (``log10 a_T = -C1 (T - T_ref)
/ (C2 + T - T_ref)``) shift factor given with the law. Without a shift, a hold at another
temperature is refused (:class:`CreepLaw.reduced_time`).

Structures: the quasi-elastic method
------------------------------------
For a part held at a fixed displacement from ``t = 0`` its force after ``t`` is, by the
correspondence principle, the elastic force with ``E`` replaced by ``E_R(t)``: exact for
linear geometry and a linear-viscoelastic material with one relaxation function for all
stress components (a constant Poisson's ratio). Every model in flexopt scales its forces with
``E`` at fixed geometry and displacement (the beam: stiffness ``E I``, ``E A``; plane stress
and 3D: stress ``= E f(strain, nu)``), so the held force curve is the elastic curve times
``E_R(t) / E0`` (:func:`relaxed_force`).

For large deflection (geometrically nonlinear, small strain) the same substitution is the
**quasi-elastic approximation** (Schapery). It is exact for a displacement applied as a step
and then held: every strain in the part is then a step, every stress relaxes by the same
factor ``E_R(t)/E0``, every internal force too, so the deformed geometry stays in equilibrium
with the same (held) boundary displacement and the reaction scales by that factor. What it
neglects: the loading ramp before the hold (a ramp of length ``t_r`` relaxes the part during
loading; negligible for ``t_r`` much shorter than the hold) and, in a geometrically nonlinear
part, that points of the part loaded along different strain paths during the ramp would relax
differently.

For a part held at a fixed force the deflection after ``t`` is the elastic deflection with
``E`` replaced by ``1 / J(t)``: the force that gives that deflection with ``E0`` is the held
force times ``E0 J(t)`` (:func:`crept_drive`). Exact for linear geometry (correspondence);
with large deflection it is quasi-elastic (the secant compliance): the geometry changes as the
part creeps, so the strains are not steps and superposition is only approximated.

Limits: the law holds below the stress ratio it was fitted to (``max_stress_ratio`` of the
material's strength); above it printed polymers creep nonlinearly (Findley's ``m`` and ``eps0``
grow faster than the stress) and the method is not applied.

Units: time in h, temperature in deg C, moduli in MPa.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from flexopt.fea.errors import FeaError

__all__ = [
    "GAS_CONSTANT_J_MOL_K",
    "CreepFit",
    "CreepLaw",
    "crept_drive",
    "fit_creep",
    "fit_relaxation",
    "mittag_leffler",
    "relaxed_force",
]

#: R, J/(mol K)
GAS_CONSTANT_J_MOL_K = 8.314462618

#: below this argument |z| the Mittag-Leffler series is summed (its terms then only decrease in
#: magnitude after the first few, so there is no cancellation); above it the integral is used
_SERIES_LIMIT = 0.5


def _ml_series(alpha: float, x: float) -> float:
    """E_alpha(-x) by its power series sum_k (-x)^k / Gamma(alpha k + 1), 0 <= x <= 0.5."""
    from scipy import special  # here: a study's start-up (every CLI command) skips scipy.special

    total, k = 0.0, 0
    while True:
        term = math.exp(k * math.log(x) - special.gammaln(alpha * k + 1.0)) if x > 0 else 0.0
        total += term if k % 2 == 0 else -term
        k += 1
        if x == 0.0 or (term < 1e-18 and k > 3) or k > 5000:
            return total + (1.0 if x == 0.0 else 0.0)


def _ml_integral(alpha: float, x: float) -> float:
    """E_alpha(-x), 0 < alpha < 1, x > 0, by the spectral (Laplace) representation

        E_alpha(-s^alpha) = int_0^inf exp(-r s) K(r) dr,
        K(r) = sin(alpha pi) / pi * r^(alpha-1) / (r^(2 alpha) + 2 r^alpha cos(alpha pi) + 1),

    with s = x^(1/alpha): a positive integrand (the function is completely monotone), summed in
    w = r s on a log scale, split where the two factors peak (w ~ 1 and w ~ s)."""
    s = x ** (1.0 / alpha)
    sin_a, cos_a = math.sin(alpha * math.pi), math.cos(alpha * math.pi)

    def integrand(v: float) -> float:
        w = math.exp(v)
        r = w / s
        ra = r**alpha
        kernel = sin_a / math.pi * ra / (ra * ra + 2.0 * ra * cos_a + 1.0)  # K(r) r
        return math.exp(-w) * kernel

    ls = math.log(s)
    # K peaks at r = 1 (v = ln s) with a width of about pi (1 - alpha) in v: narrow near
    # alpha = 1 (the spectrum tends to a delta, E_1 = exp), so its flanks are split too
    width = min(1.0, 10.0 * math.pi * (1.0 - alpha))
    points = sorted({-1.0, 0.0, 1.0, ls - 1.0, ls - width, ls, ls + width, ls + 1.0})
    edges = [-math.inf, *points, 4.0]  # exp(-e^4) ~ 2e-24: nothing beyond
    from scipy import integrate  # here: start-up skips scipy.integrate (~0.3 s, issue 27)

    total = 0.0
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        if b <= a:
            continue
        with warnings.catch_warnings():
            # near alpha = 1 quad reports roundoff at 1e-12 of the peaked flank; the result is
            # checked against the series and closed forms in tests/fea/test_creep.py
            warnings.simplefilter("ignore", integrate.IntegrationWarning)
            val, _ = integrate.quad(integrand, a, b, limit=200, epsabs=1e-16, epsrel=1e-12)
        total += val
    return total


def mittag_leffler(alpha: float, z: float | np.ndarray) -> float | np.ndarray:
    """The Mittag-Leffler function E_alpha(z) = sum_k z^k / Gamma(alpha k + 1) for real z <= 0.

    Parameters
    ----------
    alpha : 0 < alpha <= 1.
    z : scalar or array of z <= 0 (the relaxation argument ``-Gamma(1+n) (t/tau)^n``).

    Returns
    -------
    float or array (shape of ``z``), in (0, 1]: completely monotone in -z, E_1(z) = exp(z),
    E_(1/2)(-x) = exp(x^2) erfc(x), and E_alpha(-x) ~ x^-1 / Gamma(1 - alpha) for large x.

    Notes
    -----
    |z| <= 0.5: the power series; above, the spectral integral (:func:`_ml_integral`), whose
    integrand is positive (no cancellation at any z). Accurate to about 1e-12 for
    alpha <= 0.999, 1e-10 at 0.9999, 1e-8 at 0.99999 (the spectrum becomes a spike; alpha = 1
    is exact: exp) (tests: tests/fea/test_creep.py).

    Raises
    ------
    FeaError
        For alpha outside (0, 1] or z > 0 (not needed by relaxation, not implemented).
    """
    if not 0.0 < alpha <= 1.0:
        raise FeaError(f"creep: Mittag-Leffler order {alpha!r} must lie in (0, 1]")
    arr = np.asarray(z, dtype=float)
    if np.any(arr > 0.0) or not np.all(np.isfinite(arr)):
        raise FeaError("creep: the Mittag-Leffler function is implemented for finite z <= 0")
    out = np.empty(arr.shape)
    for idx, value in np.ndenumerate(arr):
        x = -float(value)
        if alpha == 1.0:
            out[idx] = math.exp(-x)
        elif x <= _SERIES_LIMIT:
            out[idx] = _ml_series(alpha, x)
        else:
            out[idx] = _ml_integral(alpha, x)
    return float(out) if np.ndim(z) == 0 else out


@dataclass(frozen=True)
class CreepLaw:
    """A Findley power-law creep compliance ``J(t) = (1/E0)(1 + (t/tau)^n)`` (module docstring).

    Attributes
    ----------
    tau_h : float, h — the time at which the creep strain equals the elastic strain.
    n : float — Findley's time exponent, 0 < n <= 1.
    max_stress_ratio : float — the largest stress over the material's strength the law was
        fitted at (the method's limit; above it the verdict says out of range).
    source : str — where the numbers come from (a test, a paper with its table).
    E0_MPa : float or None, MPa — the instantaneous modulus of the fit (recorded; the part's
        own E is the one relaxed: only the ratios ``E_R(t)/E0`` and ``E0 J(t)`` are used).
    reference_temperature_C : float, deg C — the temperature of the fit.
    activation_energy_kJ_mol : float or None, kJ/mol — Arrhenius shift (or give WLF).
    wlf_C1, wlf_C2 : float or None — WLF shift constants (C2 in K), about the reference.
    assumed : bool — an assumed, illustrative law (not a measurement): said in every verdict.
    """

    tau_h: float
    n: float
    max_stress_ratio: float
    source: str
    E0_MPa: float | None = None
    reference_temperature_C: float = 23.0
    activation_energy_kJ_mol: float | None = None
    wlf_C1: float | None = None
    wlf_C2: float | None = None
    assumed: bool = False

    def __post_init__(self) -> None:
        if not (self.tau_h > 0.0 and math.isfinite(self.tau_h)):
            raise FeaError(f"creep: tau_h = {self.tau_h!r} must be a positive time (h)")
        if not 0.0 < self.n <= 1.0:
            raise FeaError(f"creep: n = {self.n!r} must lie in (0, 1] (Findley's exponent)")
        if not 0.0 < self.max_stress_ratio <= 1.0:
            raise FeaError(
                f"creep: max_stress_ratio = {self.max_stress_ratio!r} must lie in (0, 1] (the "
                "largest stress over strength the law was fitted at)"
            )
        if (self.wlf_C1 is None) != (self.wlf_C2 is None):
            raise FeaError("creep: give both wlf_C1 and wlf_C2, or neither")
        if self.activation_energy_kJ_mol is not None and self.wlf_C1 is not None:
            raise FeaError("creep: give one shift: activation_energy_kJ_mol or wlf_C1/wlf_C2")

    @property
    def label(self) -> str:
        """One line naming the law and its source (and ``ASSUMED`` for an illustrative one)."""
        head = "ASSUMED, illustrative creep law (not measured)" if self.assumed else "creep law"
        return f"{head}: tau {self.tau_h:g} h, n {self.n:g}; {self.source}"

    def shift_log10(self, temperature_C: float | None) -> float:
        """``log10 a_T`` at ``temperature_C`` (0 at the reference or when None).

        Raises
        ------
        FeaError
            For a temperature away from the reference (by more than 0.5 K) without a shift,
            or one past the WLF singularity.
        """
        if temperature_C is None or abs(temperature_C - self.reference_temperature_C) <= 0.5:
            return 0.0
        dT = temperature_C - self.reference_temperature_C
        if self.activation_energy_kJ_mol is not None:
            t_k, ref_k = temperature_C + 273.15, self.reference_temperature_C + 273.15
            if t_k <= 0.0:
                raise FeaError(f"creep: temperature {temperature_C:g} C is below absolute zero")
            ea = self.activation_energy_kJ_mol * 1e3
            return ea / (GAS_CONSTANT_J_MOL_K * math.log(10.0)) * (1.0 / t_k - 1.0 / ref_k)
        if self.wlf_C1 is not None and self.wlf_C2 is not None:
            if self.wlf_C2 + dT <= 0.0:
                raise FeaError(
                    f"creep: {temperature_C:g} C lies past the WLF shift's singularity "
                    f"(T_ref - C2 = {self.reference_temperature_C - self.wlf_C2:g} C)"
                )
            return -self.wlf_C1 * dT / (self.wlf_C2 + dT)
        raise FeaError(
            f"creep: the law was fitted at {self.reference_temperature_C:g} C; a hold at "
            f"{temperature_C:g} C needs a time-temperature shift (activation_energy_kJ_mol, or "
            "wlf_C1 and wlf_C2) with the law"
        )

    def reduced_time(self, time_h: float, temperature_C: float | None = None) -> float:
        """The hold time at the reference temperature equivalent to ``time_h`` at
        ``temperature_C``: ``t / a_T``, h (see :meth:`shift_log10`)."""
        return float(time_h) / 10.0 ** self.shift_log10(temperature_C)

    def compliance_ratio(self, time_h: float | np.ndarray) -> float | np.ndarray:
        """``E0 J(t) = 1 + (t/tau)^n`` (>= 1; t in h, reduced): the growth of a force-held
        part's strain, shape of ``time_h``."""
        t = np.asarray(time_h, dtype=float)
        out = 1.0 + (np.maximum(t, 0.0) / self.tau_h) ** self.n
        return float(out) if np.ndim(time_h) == 0 else out

    def relaxation_ratio(self, time_h: float | np.ndarray) -> float | np.ndarray:
        """``E_R(t) / E0 = E_n(-Gamma(1+n) (t/tau)^n)`` (in (0, 1]; t in h, reduced): the
        retained share of a displacement-held part's force, shape of ``time_h``."""
        t = np.asarray(time_h, dtype=float)
        z = -math.gamma(1.0 + self.n) * (np.maximum(t, 0.0) / self.tau_h) ** self.n
        return mittag_leffler(self.n, z)


def relaxed_force(force: Sequence[float] | np.ndarray, retention: float) -> np.ndarray:
    """The force (or moment) of a displacement-held part after the hold: the elastic force at
    each held displacement times ``E_R(t)/E0`` (the quasi-elastic method, module docstring).

    Parameters
    ----------
    force : (n,) forces of the elastic solve at the held displacements, any unit.
    retention : ``E_R(t)/E0`` (:meth:`CreepLaw.relaxation_ratio`).

    Returns
    -------
    (n,) the held forces, unit of ``force``.
    """
    return np.asarray(force, dtype=float) * float(retention)


def crept_drive(
    drive: Sequence[float] | np.ndarray,
    force: Sequence[float] | np.ndarray,
    held_force: float,
    growth: float,
) -> tuple[float, float]:
    """The drive (displacement, rotation) of a force-held part at ``t = 0`` and after the hold.

    With ``E`` replaced by ``1/J(t)`` the part holding ``held_force`` deflects as the elastic
    part (modulus E0) does under ``held_force * E0 J(t)`` (forces scale with E at fixed
    geometry), so both drives are read in the elastic table by inverse interpolation.

    Parameters
    ----------
    drive : (n_rows,) the driven column of the elastic solve, from the unloaded state.
    force : (n_rows,) its force column, same rows.
    held_force : the held force, unit of ``force`` (its sign selects the branch).
    growth : ``E0 J(t)`` (:meth:`CreepLaw.compliance_ratio`), >= 1.

    Returns
    -------
    (drive at t = 0, drive after the hold), unit of ``drive``.

    Raises
    ------
    FeaError
        When the force is not monotone from the unloaded row up to the crept force (a snap or
        a peak: the held state is not defined by the force), or the crept force lies beyond
        the traced curve.
    """
    x = np.asarray(drive, dtype=float)
    f = np.asarray(force, dtype=float)
    ok = np.isfinite(x) & np.isfinite(f)
    x, f = x[ok], f[ok]
    sign = 1.0 if held_force >= 0.0 else -1.0
    order = np.argsort(np.abs(x), kind="stable")
    x, f = x[order], f[order] * sign
    target = abs(held_force) * growth
    if x.size == 0 or x[0] != 0.0:
        x, f = np.concatenate([[0.0], x]), np.concatenate([[0.0], f])
    # the rows from the unloaded state up to the first where the force reaches the target
    reach = np.nonzero(f >= target * (1.0 - 1e-12))[0]
    if reach.size == 0:
        raise FeaError(
            f"creep: the crept force {target:g} (held {abs(held_force):g} x E0 J(t) = "
            f"{growth:.4g}) lies beyond the traced curve (largest force {f.max():g}); trace a "
            "longer stroke"
        )
    last = int(reach[0])
    if np.any(np.diff(f[: last + 1]) <= 0.0):
        raise FeaError(
            "creep: the force is not rising from the unloaded state up to the crept force (a "
            "peak or a snap): a force hold is not defined there"
        )
    x0 = float(np.interp(abs(held_force), f[: last + 1], x[: last + 1]))
    x1 = float(np.interp(target, f[: last + 1], x[: last + 1]))
    return x0, x1


@dataclass(frozen=True)
class CreepFit:
    """A Findley law fitted to a hold test (:func:`fit_relaxation`, :func:`fit_creep`).

    Attributes
    ----------
    tau_h, n : the law's parameters (h, -).
    initial : float — the fitted value at t = 0 (force of a relaxation test, unit of the
        record; strain of a creep test).
    rms : float — root-mean-square residual, unit of the record.
    tau_h_ci95 : (low, high) h — 95 % interval of tau (linearised, on log tau).
    n_ci95 : float — half-width of n's 95 % interval.
    initial_ci95 : float — half-width of the initial value's 95 % interval, unit of the record.
    n_points : int — points fitted.
    """

    tau_h: float
    n: float
    initial: float
    rms: float
    tau_h_ci95: tuple[float, float] = (math.nan, math.nan)
    n_ci95: float = math.nan
    initial_ci95: float = math.nan
    n_points: int = 0

    def record(self) -> dict[str, float | list[float] | int]:
        """The fit as JSON-ready numbers (the 95 % intervals with their parameters)."""
        return {
            "tau_h": self.tau_h,
            "tau_h_ci95": [self.tau_h_ci95[0], self.tau_h_ci95[1]],
            "n": self.n,
            "n_ci95": self.n_ci95,
            "initial": self.initial,
            "initial_ci95": self.initial_ci95,
            "rms": self.rms,
            "n_points": self.n_points,
        }

    def law(self, max_stress_ratio: float, source: str, **kw: object) -> CreepLaw:
        """The :class:`CreepLaw` of this fit (the stress range and the source are the test's)."""
        return CreepLaw(
            tau_h=self.tau_h, n=self.n, max_stress_ratio=max_stress_ratio, source=source, **kw
        )  # type: ignore[arg-type]


def _check_record(time_h: Sequence[float] | np.ndarray, value: Sequence[float] | np.ndarray):
    t = np.asarray(time_h, dtype=float).ravel()
    y = np.asarray(value, dtype=float).ravel()
    if t.shape != y.shape or t.size < 4:
        raise FeaError("creep: give at least 4 (time, value) pairs of the same length")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))) or np.any(t < 0):
        raise FeaError("creep: the record holds a NaN, an inf or a negative time")
    if np.count_nonzero(t > 0) < 3:
        raise FeaError("creep: give at least 3 times after the start of the hold")
    return t, y


def _intervals(
    model, p: np.ndarray, t: np.ndarray, y: np.ndarray
) -> tuple[tuple[float, float], float, float]:
    """95 % intervals of a three-parameter fit ``p = (initial, log tau, n)`` of ``model(p, t)``
    to ``y`` (each (n_points,)): the linearised least-squares covariance
    ``s^2 (J^T J)^-1`` with ``s^2`` the residual variance on ``n_points - 3`` degrees of
    freedom and Student's t; tau's interval is exp of log tau's (asymmetric, > 0). Returns
    ((tau low, tau high) h, n half-width, initial half-width); NaN where the Jacobian is
    singular (a record that cannot tell the parameters apart)."""
    from scipy import stats

    dof = t.size - 3
    nan = ((math.nan, math.nan), math.nan, math.nan)
    if dof <= 0:
        return nan
    r0 = model(p, t) - y
    jac = np.empty((t.size, 3))
    for k in range(3):
        h = 1e-6 * max(abs(p[k]), 1e-3)
        dp = np.zeros(3)
        dp[k] = h
        jac[:, k] = (model(p + dp, t) - model(p - dp, t)) / (2.0 * h)
    s2 = float(r0 @ r0) / dof
    try:
        cov = s2 * np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return nan
    half = float(stats.t.ppf(0.975, dof)) * np.sqrt(np.maximum(np.diag(cov), 0.0))
    tau = (math.exp(p[1] - half[1]), math.exp(p[1] + half[1]))
    return tau, float(half[2]), float(half[0])


def _relaxation_model(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``F0 E_n(-Gamma(1+n) (t/tau)^n)`` of ``p = (F0, log tau, n)`` at ``t`` (h)."""
    amp, log_tau, n = p
    z = -math.gamma(1.0 + n) * (t / math.exp(log_tau)) ** n
    return amp * np.asarray(mittag_leffler(n, z), dtype=float)


def _creep_model(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``eps0 (1 + (t/tau)^n)`` of ``p = (eps0, log tau, n)`` at ``t`` (h)."""
    e0, log_tau, n = p
    return e0 * (1.0 + (t / math.exp(log_tau)) ** n)


def fit_relaxation(
    time_h: Sequence[float] | np.ndarray, force: Sequence[float] | np.ndarray
) -> CreepFit:
    """Fit Findley's law to a relaxation test: the force of a coupon held at a displacement,
    ``F(t) = F0 E_n(-Gamma(1+n) (t/tau)^n)`` (least squares in ``F0``, ``log tau``, ``n``).

    Parameters
    ----------
    time_h : (n_points,) h, from the start of the hold (the step).
    force : (n_points,) the force (any unit, one sign).

    Raises
    ------
    FeaError
        For a record too short, not finite, or that does not relax.
    """
    from scipy import optimize

    t, f = _check_record(time_h, force)
    sign = 1.0 if np.mean(f) >= 0 else -1.0
    f = f * sign
    f0 = float(f[np.argmin(t)])
    if not f0 > 0 or f[np.argmax(t)] >= f0:
        raise FeaError("creep: the force does not fall during the hold; nothing to fit")
    tmax = float(t.max())

    def residual(p: np.ndarray) -> np.ndarray:
        amp, log_tau, n = p
        z = -math.gamma(1.0 + n) * (t / math.exp(log_tau)) ** n
        return amp * mittag_leffler(n, z) - f

    best = None
    for n0 in (0.15, 0.35, 0.6):
        for tau0 in (tmax, 10.0 * tmax, 100.0 * tmax):
            got = optimize.least_squares(
                residual, [f0, math.log(tau0), n0],
                bounds=([0.0, math.log(tmax) - 30.0, 0.01], [np.inf, math.log(tmax) + 30.0, 1.0]),
                x_scale=[f0, 1.0, 0.1], xtol=1e-14, ftol=1e-14, gtol=1e-14,
            )  # fmt: skip
            if best is None or got.cost < best.cost:
                best = got
    amp, log_tau, n = best.x
    rms = float(np.sqrt(np.mean(best.fun**2)))
    tau_ci, n_ci, amp_ci = _intervals(_relaxation_model, np.asarray(best.x, dtype=float), t, f)
    return CreepFit(
        tau_h=math.exp(log_tau), n=float(n), initial=sign * float(amp), rms=rms,
        tau_h_ci95=tau_ci, n_ci95=n_ci, initial_ci95=amp_ci, n_points=int(t.size),
    )  # fmt: skip


def fit_creep(
    time_h: Sequence[float] | np.ndarray, strain: Sequence[float] | np.ndarray
) -> CreepFit:
    """Fit Findley's law to a creep test: the strain (or deflection) of a coupon under a held
    load, ``eps(t) = eps0 + m t^n`` (linear least squares in ``eps0, m`` for each ``n``, the
    best ``n`` by a bounded scalar search); ``tau = (eps0/m)^(1/n)``.

    Parameters
    ----------
    time_h : (n_points,) h from the start of the hold.
    strain : (n_points,) strain or deflection (any unit, one sign).

    Raises
    ------
    FeaError
        For a record too short, not finite, or that does not creep.
    """
    from scipy import optimize

    t, e = _check_record(time_h, strain)
    sign = 1.0 if np.mean(e) >= 0 else -1.0
    e = e * sign

    def solve(n: float) -> tuple[float, float, float]:
        a = np.column_stack([np.ones_like(t), t**n])
        (e0, m), *_ = np.linalg.lstsq(a, e, rcond=None)
        return float(e0), float(m), float(np.sum((a @ np.array([e0, m]) - e) ** 2))

    got = optimize.minimize_scalar(lambda n: solve(n)[2], bounds=(0.01, 1.0), method="bounded",
                                   options={"xatol": 1e-10})  # fmt: skip
    n = float(got.x)
    e0, m, sq = solve(n)
    if not (e0 > 0 and m > 0):
        raise FeaError("creep: the record does not creep (eps0 and m must be > 0); check it")
    tau = (e0 / m) ** (1.0 / n)
    p = np.array([e0, math.log(tau), n])
    tau_ci, n_ci, e0_ci = _intervals(_creep_model, p, t, e)
    return CreepFit(
        tau_h=tau, n=n, initial=sign * e0, rms=math.sqrt(sq / t.size),
        tau_h_ci95=tau_ci, n_ci95=n_ci, initial_ci95=e0_ci, n_points=int(t.size),
    )  # fmt: skip
