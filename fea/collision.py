r"""Head impact of a robot arm with a series spring (paper 000, Ayoubi et al. 2019, Sec. 4).

The model of the paper's Fig. 14 (after Gao & Wampler 2009, the paper's ref. [10]): a rotor
(inertia ``I_r``, driven by a constant torque ``τ``) turns the arm (``I_a``) through a spring whose
torque ``T(θ)`` depends on the deflection ``θ = θ1 - θ2``; the arm's contact point at ``l`` hits a
head (``M``) held by the neck (``k_N``, ``d_N``) through a soft contact (``k_c``, ``d_c``)::

    I_r θ1'' = τ - T(θ)
    I_a θ2'' = T(θ) - l F
    M   x''  = F - k_N x - d_N x'
    F = max(0, k_c δ + d_c δ')  while δ = l θ2 - x >= 0, else 0

The contact acts in compression only (it is a contact, not a glue: the damper may not pull). The
arm's contact point moves ``l θ2`` (small rotations, as the paper's linear model). At ``t = 0``
the contact point touches the head (``δ = 0``) and rotor and arm turn at ``θ̇1 = θ̇2 = π rad/s``.

**Initial conditions** (the paper does not state them; its claims depend on them), option
``initial_spring``:

* ``unloaded`` (default): ``θ(0) = 0``, the rotor torque is switched on at the impact (the
  drive was cruising at constant speed with no load).
* ``accelerating``: the rotor torque was on before the impact and rotor and arm accelerated
  together, so the spring carries the arm's share, ``T(θ0) = τ I_a / (I_r + I_a)``.
* ``held``: the spring carries the whole rotor torque, ``T(θ0) = τ`` (as if the arm had been
  pushing against a load that vanished). Impossible for a threshold spring when ``τ >= T_max``.

Safety measures: HIC15 (Eq. 18; the head acceleration in g, its magnitude, over the sliding window
of at most 15 ms — exact on the sample grid, see :func:`hic`) and the peak contact force (ImpF).

Integration: classic RK4 at a fixed step on the output grid, vectorised over a batch of rotor
inertias and torques (the sweeps of Figs. 16–17 cost one integration per spring). The spring
may be any odd, monotone torque–deflection function in SI units: :class:`ThresholdSpring`
(Eq. 14), :class:`LinearSpring` or :class:`TabulatedSpring` (a designed spring's response).

Units: SI throughout (rad, s, m, kg, N, N·m), named in every field; accelerations in g only
where named ``_g``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Literal, Protocol

import numpy as np
from flexopt.fea.errors import FeaError

if TYPE_CHECKING:
    from flexopt.geometry.cam import CamProfile

__all__ = [
    "G_M_PER_S2",
    "CollisionModel",
    "CollisionResponse",
    "CollisionSettings",
    "HICResult",
    "LinearSpring",
    "SpringSafetyScore",
    "SweepResult",
    "TabulatedSpring",
    "ThresholdSpring",
    "TorqueSpring",
    "cam_impact_check",
    "equivalent_linear_spring",
    "hic",
    "initial_deflection_rad",
    "metrics_until",
    "score_spring_curve",
    "simulate_collision",
    "simulate_cases",
    "simulate_collisions",
    "sweep",
    "sweep_record",
    "sweep_result",
]

#: Standard gravity, m/s², to express the head acceleration in g for HIC.
G_M_PER_S2 = 9.80665

InitialSpring = Literal["unloaded", "accelerating", "held"]


# --------------------------------------------------------------------------------------------
# Springs


class TorqueSpring(Protocol):
    """A spring between rotor and arm: odd torque (N·m) of the deflection (rad), vectorised."""

    def __call__(self, deflection_rad: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class ThresholdSpring:
    """Paper 000, Eq. 14: ``T = T_max (1 - exp(-s |θ|)) sign θ``.

    Attributes
    ----------
    max_torque_Nm : float, N·m — T_max.
    rate_per_rad : float, 1/rad — s.
    """

    max_torque_Nm: float
    rate_per_rad: float

    def __post_init__(self) -> None:
        if not (self.max_torque_Nm > 0 and self.rate_per_rad > 0):
            raise FeaError(
                f"ThresholdSpring needs max_torque_Nm > 0 and rate_per_rad > 0; got "
                f"{self.max_torque_Nm}, {self.rate_per_rad}"
            )

    def __call__(self, deflection_rad: np.ndarray) -> np.ndarray:
        th = np.asarray(deflection_rad, dtype=float)
        return np.sign(th) * self.max_torque_Nm * -np.expm1(-self.rate_per_rad * np.abs(th))

    @property
    def sup_torque_Nm(self) -> float:
        """The torque the spring approaches but never reaches, N·m."""
        return self.max_torque_Nm

    def deflection_at(self, torque_Nm: float) -> float:
        """Deflection at which the spring carries ``torque_Nm`` (< max_torque_Nm), rad."""
        if not abs(torque_Nm) < self.max_torque_Nm:
            raise FeaError(
                f"a threshold spring never reaches {torque_Nm:g} N·m (T_max = "
                f"{self.max_torque_Nm:g} N·m); choose initial_spring: unloaded"
            )
        return math.copysign(-math.log1p(-abs(torque_Nm) / self.max_torque_Nm), torque_Nm) / (
            self.rate_per_rad
        )


@dataclass(frozen=True)
class LinearSpring:
    """A constant-stiffness spring, ``T = K θ``.

    Attributes
    ----------
    stiffness_Nm_per_rad : float, N·m/rad.
    """

    stiffness_Nm_per_rad: float

    def __post_init__(self) -> None:
        if not self.stiffness_Nm_per_rad > 0:
            raise FeaError(f"stiffness_Nm_per_rad = {self.stiffness_Nm_per_rad} must be > 0")

    def __call__(self, deflection_rad: np.ndarray) -> np.ndarray:
        return self.stiffness_Nm_per_rad * np.asarray(deflection_rad, dtype=float)

    @property
    def sup_torque_Nm(self) -> float:
        return math.inf

    def deflection_at(self, torque_Nm: float) -> float:
        return torque_Nm / self.stiffness_Nm_per_rad


@dataclass(frozen=True, eq=False)
class TabulatedSpring:
    """A tabulated torque–deflection curve (e.g. a designed spring's FE response), linear between
    points, odd (``T(-θ) = -T(θ)``).

    Beyond the table the last torque is held (a threshold that does not break); the simulation
    reports the largest deflection reached so a caller can see whether that happened
    (:attr:`CollisionResponse.max_deflection_rad` against :attr:`max_rotation_rad`).

    Attributes
    ----------
    rotation_rad : (n,) float, rad — from 0, strictly increasing.
    torque_Nm : (n,) float, N·m — 0 at rotation 0, increasing.
    """

    rotation_rad: np.ndarray
    torque_Nm: np.ndarray

    def __post_init__(self) -> None:
        th = np.array(self.rotation_rad, dtype=float).ravel()
        tq = np.array(self.torque_Nm, dtype=float).ravel()
        if th.size < 2 or th.shape != tq.shape:
            raise FeaError(
                f"a tabulated spring needs >= 2 points and one torque per rotation; got "
                f"{th.size} rotations, {tq.size} torques"
            )
        if not (np.all(np.isfinite(th)) and np.all(np.isfinite(tq))):
            raise FeaError("the tabulated spring has NaN or infinite values; clean the table")
        if abs(th[0]) > 1e-12 or abs(tq[0]) > 1e-9 * max(1.0, float(np.max(np.abs(tq)))):
            raise FeaError(
                f"the table must start at (0 rad, 0 N·m), got ({th[0]:g}, {tq[0]:g}); prepend "
                "the unloaded point (it is extended to negative deflections by symmetry)"
            )
        if np.any(np.diff(th) <= 0):
            raise FeaError("rotation_rad must increase strictly; sort the rows and drop repeats")
        if np.any(np.diff(tq) < 0):
            i = int(np.argmax(np.diff(tq) < 0))
            raise FeaError(
                f"torque falls from {tq[i]:g} to {tq[i + 1]:g} N·m at rows {i}–{i + 1}; a "
                "softening-to-negative-stiffness spring would snap through and is not modelled"
            )
        th.setflags(write=False)
        tq.setflags(write=False)
        object.__setattr__(self, "rotation_rad", th)
        object.__setattr__(self, "torque_Nm", tq)

    @classmethod
    def from_Nmm(cls, rotation_rad: Any, torque_Nmm: Any) -> TabulatedSpring:
        """From project units (N·mm), e.g. a flexopt spring response."""
        return cls(np.asarray(rotation_rad, float), np.asarray(torque_Nmm, float) / 1000.0)

    def __call__(self, deflection_rad: np.ndarray) -> np.ndarray:
        th = np.asarray(deflection_rad, dtype=float)
        return np.sign(th) * np.interp(np.abs(th), self.rotation_rad, self.torque_Nm)

    @property
    def max_rotation_rad(self) -> float:
        return float(self.rotation_rad[-1])

    @property
    def sup_torque_Nm(self) -> float:
        return float(self.torque_Nm[-1])

    def deflection_at(self, torque_Nm: float) -> float:
        if not abs(torque_Nm) <= self.sup_torque_Nm:
            raise FeaError(
                f"the tabulated spring reaches at most {self.sup_torque_Nm:g} N·m, not "
                f"{torque_Nm:g}; extend the table or choose initial_spring: unloaded"
            )
        return math.copysign(
            float(np.interp(abs(torque_Nm), self.torque_Nm, self.rotation_rad)), torque_Nm
        )


def equivalent_linear_spring(spring: Any, split_torque_Nm: float) -> LinearSpring:
    """The constant-stiffness spring with the same deflection at ``split_torque_Nm`` (paper
    Sec. 4.3: the CS spring matches V2SOM's deflection at T1 = 80 % of T_max)."""
    theta = _deflection_at(spring, split_torque_Nm)
    if not theta > 0:
        raise FeaError(f"the spring's deflection at {split_torque_Nm:g} N·m is {theta:g} rad")
    return LinearSpring(split_torque_Nm / theta)


def _deflection_at(spring: Any, torque_Nm: float) -> float:
    method = getattr(spring, "deflection_at", None)
    if callable(method):
        return float(method(torque_Nm))
    # generic monotone spring: bisection on [0, hi]
    hi = 1e-3
    while float(spring(np.array(hi))) < torque_Nm:
        hi *= 2.0
        if hi > 1e3:
            raise FeaError(f"the spring never reaches {torque_Nm:g} N·m")
    lo = 0.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if float(spring(np.array(mid))) < torque_Nm else (lo, mid)
    return 0.5 * (lo + hi)


# --------------------------------------------------------------------------------------------
# The model


@dataclass(frozen=True)
class CollisionModel:
    """Parameters of Fig. 14; defaults are the paper's (l. 252–258, Fig. 17 caption).

    Attributes
    ----------
    neck_damping_N_s_per_m : d_N = 12.
    neck_stiffness_N_per_m : k_N = 3300.
    head_mass_kg : M = 5.09.
    contact_damping_N_s_per_m : d_c = 10.
    contact_stiffness_N_per_m : k_c = 1500.
    arm_length_m : l = 0.6 (contact point on the arm).
    arm_inertia_kg_m2 : I_a = 0.14.
    rotor_inertia_kg_m2 : I_r = 0.175 (Fig. 17).
    rotor_torque_Nm : τ, constant during the impact; 15 N·m (= T_max) by default (assumed: the
        paper sweeps 7.5–30 N·m in Fig. 17 and does not give Fig. 16's value).
    speed_rad_per_s : θ̇1 = θ̇2 at impact, π rad/s.
    initial_spring : "unloaded", "accelerating" or "held" (see the module notes).
    """

    neck_damping_N_s_per_m: float = 12.0
    neck_stiffness_N_per_m: float = 3300.0
    head_mass_kg: float = 5.09
    contact_damping_N_s_per_m: float = 10.0
    contact_stiffness_N_per_m: float = 1500.0
    arm_length_m: float = 0.6
    arm_inertia_kg_m2: float = 0.14
    rotor_inertia_kg_m2: float = 0.175
    rotor_torque_Nm: float = 15.0
    speed_rad_per_s: float = math.pi
    initial_spring: InitialSpring = "unloaded"

    def __post_init__(self) -> None:
        positive = (
            "head_mass_kg",
            "contact_stiffness_N_per_m",
            "arm_length_m",
            "arm_inertia_kg_m2",
            "rotor_inertia_kg_m2",
        )
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise FeaError(f"CollisionModel.{name} = {value} must be > 0")
        for name in (
            "neck_damping_N_s_per_m",
            "neck_stiffness_N_per_m",
            "contact_damping_N_s_per_m",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise FeaError(f"CollisionModel.{name} = {value} must be >= 0")
        if self.initial_spring not in ("unloaded", "accelerating", "held"):
            raise FeaError(
                f"initial_spring = {self.initial_spring!r}; use unloaded, accelerating or held"
            )


@dataclass(frozen=True)
class CollisionSettings:
    """Integration settings, each with its reason."""

    # Output and RK4 step, s. The fastest mode (arm on the contact spring, < 100 rad/s) is
    # resolved with ω dt < 0.02, so RK4's truncation error is negligible; 0.2 ms puts 75 samples
    # in the 15 ms HIC window. Halving it changes HIC by ~3e-5 and the peak force by < 1e-6
    # relative (tests/fea/test_collision.py); one batch of cases costs ~0.3 s.
    dt_s: float = 2e-4
    # Simulated time, s: the first impact peaks within ~60 ms; 0.25 s also covers the second
    # peak when the rotor catches up through a stiff spring (period 2π sqrt(I_r/K) ≈ 0.16 s).
    duration_s: float = 0.25
    # HIC window limit, s (HIC15).
    hic_window_s: float = 0.015


@dataclass(frozen=True, eq=False)
class CollisionResponse:
    """One simulated impact.

    Attributes
    ----------
    time_s : (n,) float, s.
    head_position_m : (n,) float, m.
    head_acceleration_m_per_s2 : (n,) float, m/s².
    contact_force_N : (n,) float, N.
    deflection_rad : (n,) float, rad — θ1 - θ2.
    spring_torque_Nm : (n,) float, N·m.
    rotor_speed_rad_per_s, arm_speed_rad_per_s : (n,) float, rad/s.
    hic15 : float — HIC over windows ≤ ``hic_window_s``, s·g^2.5.
    hic_window_s : (float, float), s — the maximising window.
    peak_force_N : float, N — ImpF, the largest contact force.
    peak_force_time_s : float, s.
    max_deflection_rad : float, rad — the largest |θ| reached.
    initial_deflection_rad : float, rad.
    model : CollisionModel.
    """

    time_s: np.ndarray
    head_position_m: np.ndarray
    head_acceleration_m_per_s2: np.ndarray
    contact_force_N: np.ndarray
    deflection_rad: np.ndarray
    spring_torque_Nm: np.ndarray
    rotor_speed_rad_per_s: np.ndarray
    arm_speed_rad_per_s: np.ndarray
    hic15: float
    hic_window_s: tuple[float, float]
    peak_force_N: float
    peak_force_time_s: float
    max_deflection_rad: float
    initial_deflection_rad: float
    model: CollisionModel


def initial_deflection_rad(spring: Any, model: CollisionModel) -> float:
    """``θ(0)`` for ``model.initial_spring`` (see the module notes), rad.

    Raises
    ------
    FeaError
        When the spring cannot carry the torque the option asks for (a threshold spring under
        ``held`` with ``τ >= T_max``).
    """
    tau = model.rotor_torque_Nm
    if model.initial_spring == "unloaded":
        return 0.0
    if model.initial_spring == "accelerating":
        share = (
            tau * model.arm_inertia_kg_m2 / (model.arm_inertia_kg_m2 + model.rotor_inertia_kg_m2)
        )
        return _deflection_at(spring, share)
    return _deflection_at(spring, tau)


def simulate_collisions(
    spring: TorqueSpring,
    model: CollisionModel = CollisionModel(),
    rotor_inertia_kg_m2: Sequence[float] | np.ndarray | None = None,
    rotor_torque_Nm: Sequence[float] | np.ndarray | None = None,
    settings: CollisionSettings = CollisionSettings(),
) -> list[CollisionResponse]:
    """Simulate the impact for a batch of rotor inertias and torques with one spring.

    Parameters
    ----------
    spring : TorqueSpring
        Odd torque (N·m) of the deflection (rad), vectorised.
    model : CollisionModel
        Everything else; its ``rotor_inertia_kg_m2`` / ``rotor_torque_Nm`` are used where the
        batch arrays are not given.
    rotor_inertia_kg_m2, rotor_torque_Nm : (k,) float, optional
        The batch (broadcast against each other).
    settings : CollisionSettings

    Returns
    -------
    list of CollisionResponse
        One per batch entry.
    """
    inertia = np.atleast_1d(
        np.asarray(
            model.rotor_inertia_kg_m2 if rotor_inertia_kg_m2 is None else rotor_inertia_kg_m2,
            dtype=float,
        )
    )
    torque = np.atleast_1d(
        np.asarray(model.rotor_torque_Nm if rotor_torque_Nm is None else rotor_torque_Nm, float)
    )
    inertia, torque = np.broadcast_arrays(inertia, torque)
    if np.any(inertia <= 0):
        raise FeaError("every rotor_inertia_kg_m2 must be > 0")
    models = [
        replace(model, rotor_inertia_kg_m2=float(i), rotor_torque_Nm=float(t))
        for i, t in zip(inertia, torque, strict=True)
    ]
    theta0 = np.array([initial_deflection_rad(spring, m) for m in models])
    m = model
    l = m.arm_length_m
    w0 = m.speed_rad_per_s
    k = inertia.size
    # state rows: θ1, θ2, x, ω1, ω2, v; θ2 and x start at 0 (contact point touching the head)
    y = np.zeros((6, k))
    y[0] = theta0
    y[3] = w0
    y[4] = w0

    kn, dn = m.neck_stiffness_N_per_m, m.neck_damping_N_s_per_m
    kc, dc = m.contact_stiffness_N_per_m, m.contact_damping_N_s_per_m
    inv_head, inv_arm, inv_rotor = 1.0 / m.head_mass_kg, 1.0 / m.arm_inertia_kg_m2, 1.0 / inertia

    def rhs(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        # Lean on purpose: this runs 4 times per step, and numpy's per-call overhead dominates
        # for a batch of a few cases.
        th1, th2, x, w1, w2, v = s
        t_spring = spring(th1 - th2)
        delta = l * th2 - x
        f = np.maximum(kc * delta + dc * (l * w2 - v), 0.0) * (delta >= 0)
        acc_head = (f - kn * x - dn * v) * inv_head
        d = np.array(
            [w1, w2, v, (torque - t_spring) * inv_rotor, (t_spring - l * f) * inv_arm, acc_head]
        )
        return d, f, acc_head, t_spring

    dt = settings.dt_s
    n = int(round(settings.duration_s / dt)) + 1
    out_state = np.empty((n, 6, k))
    out_aux = np.empty((n, 3, k))
    half, sixth = 0.5 * dt, dt / 6.0
    for i in range(n):
        k1, f, acc, tq = rhs(y)
        out_state[i] = y
        out_aux[i, 0], out_aux[i, 1], out_aux[i, 2] = f, acc, tq
        if i == n - 1:
            break
        k2 = rhs(y + half * k1)[0]
        k3 = rhs(y + half * k2)[0]
        k4 = rhs(y + dt * k3)[0]
        y = y + sixth * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    time = np.arange(n) * dt
    results = []
    for j in range(k):
        acc = out_aux[:, 1, j]
        force = out_aux[:, 0, j]
        defl = out_state[:, 0, j] - out_state[:, 1, j]
        h = hic(time, np.abs(acc) / G_M_PER_S2, settings.hic_window_s)
        i_peak = int(np.argmax(force))
        results.append(
            CollisionResponse(
                time_s=time,
                head_position_m=out_state[:, 2, j].copy(),
                head_acceleration_m_per_s2=acc.copy(),
                contact_force_N=force.copy(),
                deflection_rad=defl,
                spring_torque_Nm=out_aux[:, 2, j].copy(),
                rotor_speed_rad_per_s=out_state[:, 3, j].copy(),
                arm_speed_rad_per_s=out_state[:, 4, j].copy(),
                hic15=h.hic,
                hic_window_s=(h.t1_s, h.t2_s),
                peak_force_N=float(force[i_peak]),
                peak_force_time_s=float(time[i_peak]),
                max_deflection_rad=float(np.max(np.abs(defl))),
                initial_deflection_rad=float(theta0[j]),
                model=models[j],
            )
        )
    return results


def metrics_until(
    response: CollisionResponse, end_s: float, window_s: float = 0.015
) -> tuple[float, float]:
    """HIC and peak contact force over ``[0, end_s]`` only, e.g. the first impact.

    The full-length measures of a response include what happens after the first impact (the
    robot keeps pushing; a stiff spring lets the rotor's inertia arrive later); restricting the
    time shows which phase a measure comes from.

    Returns
    -------
    (float, float)
        HIC (s·g^2.5) and peak contact force (N) over the first ``end_s`` seconds.
    """
    keep = response.time_s <= end_s + 1e-12
    if keep.sum() < 2:
        raise FeaError(f"end_s = {end_s:g} s keeps fewer than 2 samples; make it longer")
    acc = np.abs(response.head_acceleration_m_per_s2[keep]) / G_M_PER_S2
    h = hic(response.time_s[keep], acc, window_s)
    return h.hic, float(np.max(response.contact_force_N[keep]))


def simulate_collision(
    spring: TorqueSpring,
    model: CollisionModel = CollisionModel(),
    settings: CollisionSettings = CollisionSettings(),
) -> CollisionResponse:
    """One impact (see :func:`simulate_collisions`)."""
    return simulate_collisions(spring, model, settings=settings)[0]


# --------------------------------------------------------------------------------------------
# HIC


@dataclass(frozen=True)
class HICResult:
    """HIC and its window.

    Attributes
    ----------
    hic : float — max of ``(mean a)^2.5 (t2 - t1)``, a in g, t in s.
    t1_s, t2_s : float, s — the maximising window.
    """

    hic: float
    t1_s: float
    t2_s: float


def hic(time_s: Any, acceleration_g: Any, window_s: float = 0.015) -> HICResult:
    """Head Injury Criterion (paper Eq. 18): the exact maximum over sample-grid windows.

    ``HIC = max_{t1 < t2, t2 - t1 <= window} [(1/(t2 - t1)) ∫_{t1}^{t2} a dt]^2.5 (t2 - t1)``,
    with the acceleration taken as piecewise linear between samples (trapezoid integral). Every
    pair of samples no more than ``window_s`` apart is a candidate: the loop runs over the lag
    between the two samples (each lag is one vectorised pass), O(n · w) for w samples per window.

    Parameters
    ----------
    time_s : (n,) float, s — increasing (need not be uniform).
    acceleration_g : (n,) float, g — non-negative (pass the magnitude of the resultant).
    window_s : float, s — 0.015 for HIC15, 0.036 for HIC36.

    Returns
    -------
    HICResult
    """
    t = np.asarray(time_s, dtype=float)
    a = np.asarray(acceleration_g, dtype=float)
    if t.ndim != 1 or t.shape != a.shape or t.size < 2:
        raise FeaError(f"hic needs two equal 1-D arrays of >= 2 samples; got {t.shape}, {a.shape}")
    if np.any(np.diff(t) <= 0):
        raise FeaError("hic needs strictly increasing time_s")
    if np.any(a < 0):
        raise FeaError("hic needs acceleration magnitudes (>= 0); pass np.abs(a) or the resultant")
    if not window_s > 0:
        raise FeaError(f"window_s = {window_s} must be > 0")
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))])
    best, i1, i2 = 0.0, 0, 0
    tol = 1e-12 * max(1.0, window_s)
    for lag in range(1, t.size):
        dt = t[lag:] - t[:-lag]
        ok = dt <= window_s + tol
        if not ok.any():
            break
        mean = (cum[lag:] - cum[:-lag]) / dt
        value = np.where(ok, mean**2.5 * dt, -1.0)
        j = int(np.argmax(value))
        if value[j] > best:
            best, i1, i2 = float(value[j]), j, j + lag
    return HICResult(best, float(t[i1]), float(t[i2]))


# --------------------------------------------------------------------------------------------
# Sweeps and scoring


@dataclass(frozen=True, eq=False)
class SweepResult:
    """Safety measures of two springs over a swept parameter (plot data of Figs. 16–17).

    Attributes
    ----------
    parameter : str — ``rotor_inertia_kg_m2`` or ``rotor_torque_Nm``.
    values : (k,) float — the swept values.
    hic15, peak_force_N : dict of str to (k,) float — per spring label.
    max_deflection_rad : dict of str to (k,) float.
    hic_reduction, force_reduction : (k,) float — ``1 - spring / reference``, fractions.
    """

    parameter: str
    values: np.ndarray
    hic15: dict[str, np.ndarray]
    peak_force_N: dict[str, np.ndarray]
    max_deflection_rad: dict[str, np.ndarray]
    hic_reduction: np.ndarray
    force_reduction: np.ndarray


def simulate_cases(
    spring: TorqueSpring,
    model: CollisionModel,
    rotor_inertia_kg_m2: Sequence[float] | np.ndarray,
    rotor_torque_Nm: Sequence[float] | np.ndarray,
    settings: CollisionSettings = CollisionSettings(),
) -> list[CollisionResponse | None]:
    """Like :func:`simulate_collisions`, but a case whose initial condition is impossible (a
    ``held`` threshold spring at ``τ >= T_max``) comes back as None instead of raising."""
    inertia, torque = np.broadcast_arrays(
        np.atleast_1d(np.asarray(rotor_inertia_kg_m2, dtype=float)),
        np.atleast_1d(np.asarray(rotor_torque_Nm, dtype=float)),
    )
    feasible = []
    for i, (a, b) in enumerate(zip(inertia, torque, strict=True)):
        try:
            initial_deflection_rad(
                spring, replace(model, rotor_inertia_kg_m2=float(a), rotor_torque_Nm=float(b))
            )
            feasible.append(i)
        except FeaError:
            continue
    out: list[CollisionResponse | None] = [None] * inertia.size
    if feasible:
        res = simulate_collisions(spring, model, inertia[feasible], torque[feasible], settings)
        for i, r in zip(feasible, res, strict=True):
            out[i] = r
    return out


def sweep_result(
    parameter: str,
    values: Sequence[float] | np.ndarray,
    responses: dict[str, Sequence[CollisionResponse | None]],
) -> SweepResult:
    """Collect the responses of two springs (first: the spring, second: the reference) over a
    swept parameter into a :class:`SweepResult` (None entries become NaN)."""

    def column(rs: Sequence[CollisionResponse | None], attr: str) -> np.ndarray:
        return np.array([np.nan if r is None else getattr(r, attr) for r in rs], dtype=float)

    labels = list(responses)
    hic_v = {k: column(v, "hic15") for k, v in responses.items()}
    force_v = {k: column(v, "peak_force_N") for k, v in responses.items()}
    defl_v = {k: column(v, "max_deflection_rad") for k, v in responses.items()}
    a, b = labels[0], labels[1]
    return SweepResult(
        parameter=parameter,
        values=np.asarray(values, dtype=float),
        hic15=hic_v,
        peak_force_N=force_v,
        max_deflection_rad=defl_v,
        hic_reduction=1.0 - hic_v[a] / hic_v[b],
        force_reduction=1.0 - force_v[a] / force_v[b],
    )


def sweep(
    spring: TorqueSpring,
    reference: TorqueSpring,
    parameter: Literal["rotor_inertia_kg_m2", "rotor_torque_Nm"],
    values: Sequence[float] | np.ndarray,
    model: CollisionModel = CollisionModel(),
    settings: CollisionSettings = CollisionSettings(),
    labels: tuple[str, str] = ("spring", "reference"),
) -> SweepResult:
    """HIC15 and peak force of ``spring`` and ``reference`` over one model parameter (the other
    from ``model``). An impossible initial condition is NaN for that spring."""
    vals = np.asarray(values, dtype=float)
    if parameter == "rotor_inertia_kg_m2":
        inertia, torque = vals, np.full(vals.shape, model.rotor_torque_Nm)
    elif parameter == "rotor_torque_Nm":
        inertia, torque = np.full(vals.shape, model.rotor_inertia_kg_m2), vals
    else:
        raise FeaError(f"parameter {parameter!r}; sweep rotor_inertia_kg_m2 or rotor_torque_Nm")
    responses = {
        label: simulate_cases(sp, model, inertia, torque, settings)
        for label, sp in zip(labels, (spring, reference), strict=True)
    }
    return sweep_result(parameter, vals, responses)


def sweep_record(
    result: SweepResult,
    runs: dict[str, list[CollisionResponse | None]],
    early_s: float,
) -> dict[str, Any]:
    """A sweep as plain lists (``evaluation.json``'s ``inputs.sweeps``): the full-length measures
    of ``result`` and the same measures over the first ``early_s`` seconds (the first impact,
    :func:`metrics_until`), per spring label of ``runs`` (first: the spring, second: the
    reference; None entries become NaN).

    Returns
    -------
    dict
        ``early_window_ms``, ``early_hic15`` / ``early_peak_force_N`` (label -> list),
        ``early_hic_reduction`` / ``early_force_reduction`` (``1 - spring / reference``),
        ``parameter``, ``values``, ``hic15``, ``peak_force_N``, ``max_deflection_deg`` (label ->
        list, deg), ``hic_reduction``, ``force_reduction``.
    """
    early: dict[str, dict[str, list[float]]] = {"hic15": {}, "peak_force_N": {}}
    for label, responses in runs.items():
        values = [
            (math.nan, math.nan) if r is None else metrics_until(r, early_s) for r in responses
        ]
        early["hic15"][label] = [v[0] for v in values]
        early["peak_force_N"][label] = [v[1] for v in values]
    a, b = list(runs)[:2]
    return {
        "early_window_ms": early_s * 1000.0,
        "early_hic15": early["hic15"],
        "early_peak_force_N": early["peak_force_N"],
        "early_hic_reduction": [
            1.0 - x / y for x, y in zip(early["hic15"][a], early["hic15"][b], strict=True)
        ],
        "early_force_reduction": [
            1.0 - x / y
            for x, y in zip(early["peak_force_N"][a], early["peak_force_N"][b], strict=True)
        ],
        "parameter": result.parameter,
        "values": result.values.tolist(),
        "hic15": {k: v.tolist() for k, v in result.hic15.items()},
        "peak_force_N": {k: v.tolist() for k, v in result.peak_force_N.items()},
        "max_deflection_deg": {
            k: np.degrees(v).tolist() for k, v in result.max_deflection_rad.items()
        },
        "hic_reduction": result.hic_reduction.tolist(),
        "force_reduction": result.force_reduction.tolist(),
    }


def cam_impact_check(
    profile: CamProfile,
    ratio: float,
    max_deflection_rad: float,
    pressure_MPa: np.ndarray,
    onset_MPa: float,
) -> dict[str, Any]:
    """The spring realised as a cam behind an ideal reducer of ``ratio`` (joint torque / cam
    torque), checked against an impact: whether the impact's largest joint deflection drives
    the cam past its range, and the largest contact pressure over the rotation it reaches.

    Parameters
    ----------
    profile : CamProfile — the synthesised cam (torque in N·mm, rotation in rad).
    ratio : float — the reducer's ratio N (cam rotation = N x joint rotation).
    max_deflection_rad : float, rad — the joint's largest deflection in the impact.
    pressure_MPa : (n,) float, MPa — contact pressure at ``profile.rotation_rad``.
    onset_MPa : float, MPa — the pressure at which the plate starts to yield.

    Returns
    -------
    dict
        ``ratio``, ``cam_max_torque_Nm``, ``cam_range_deg``, ``joint_range_deg``,
        ``impact_cam_rotation_deg``, ``range_exceeded``, ``mechanism_diameter_mm``,
        ``max_contact_pressure_MPa``, ``onset_pressure_MPa``, ``stress_yield_ratio``.
    """
    reach = ratio * max_deflection_rad
    gmax = profile.layout.max_rotation_rad
    within = profile.rotation_rad <= min(reach, gmax) + 1e-12
    peak = float(np.max(pressure_MPa[within]))
    return {
        "ratio": ratio,
        "cam_max_torque_Nm": float(np.max(profile.torque_Nmm)) / 1000.0,
        "cam_range_deg": math.degrees(gmax),
        "joint_range_deg": math.degrees(gmax / ratio),
        "impact_cam_rotation_deg": math.degrees(reach),
        "range_exceeded": bool(reach > gmax),
        "mechanism_diameter_mm": 2 * (profile.max_radius_mm + profile.layout.roller_radius_mm),
        "max_contact_pressure_MPa": peak,
        "onset_pressure_MPa": onset_MPa,
        "stress_yield_ratio": peak / onset_MPa,
    }


@dataclass(frozen=True)
class SpringSafetyScore:
    """How a spring curve does in the head impact against its constant-stiffness equivalent.

    Attributes
    ----------
    hic15, peak_force_N : float — of the spring.
    reference_hic15, reference_peak_force_N : float — of the constant-stiffness spring.
    reference_stiffness_Nm_per_rad : float, N·m/rad.
    hic_reduction, force_reduction : float — ``1 - spring / reference`` (0.8 = 80 % lower).
    max_deflection_rad : float, rad — largest deflection of the spring during the impact.
    beyond_table : bool — the impact deflected the spring past its tabulated range (the last
        torque was held there: treat the score as optimistic).
    """

    hic15: float
    peak_force_N: float
    reference_hic15: float
    reference_peak_force_N: float
    reference_stiffness_Nm_per_rad: float
    hic_reduction: float
    force_reduction: float
    max_deflection_rad: float
    beyond_table: bool
    details: dict[str, Any] = field(default_factory=dict)


def score_spring_curve(
    rotation_rad: Any,
    torque_Nm: Any,
    model: CollisionModel = CollisionModel(),
    settings: CollisionSettings = CollisionSettings(),
    reference_stiffness_Nm_per_rad: float | None = None,
    split: float = 0.8,
) -> SpringSafetyScore:
    """Score a tabulated torque–rotation curve (e.g. a designed spring's response) by HIC15 and
    impact force against the constant-stiffness spring (the hook for the SEA spring study).

    Parameters
    ----------
    rotation_rad : (n,) float, rad — from 0, increasing.
    torque_Nm : (n,) float, N·m — from 0, non-decreasing (divide N·mm by 1000).
    model, settings : the impact (paper defaults).
    reference_stiffness_Nm_per_rad : float, optional
        The constant stiffness to compare with; default: the one with the same deflection at
        ``split`` of the table's largest torque (the paper's rule, Sec. 4.3).
    split : float — fraction of the largest torque for the default reference.

    Returns
    -------
    SpringSafetyScore
    """
    spring = TabulatedSpring(np.asarray(rotation_rad, float), np.asarray(torque_Nm, float))
    if reference_stiffness_Nm_per_rad is None:
        reference = equivalent_linear_spring(spring, split * spring.sup_torque_Nm)
    else:
        reference = LinearSpring(reference_stiffness_Nm_per_rad)
    mine = simulate_collision(spring, model, settings)
    ref = simulate_collision(reference, model, settings)
    return SpringSafetyScore(
        hic15=mine.hic15,
        peak_force_N=mine.peak_force_N,
        reference_hic15=ref.hic15,
        reference_peak_force_N=ref.peak_force_N,
        reference_stiffness_Nm_per_rad=reference.stiffness_Nm_per_rad,
        hic_reduction=1.0 - mine.hic15 / ref.hic15,
        force_reduction=1.0 - mine.peak_force_N / ref.peak_force_N,
        max_deflection_rad=mine.max_deflection_rad,
        beyond_table=mine.max_deflection_rad > spring.max_rotation_rad,
        details={"initial_spring": model.initial_spring},
    )
