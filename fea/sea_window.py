r"""Stiffness window of a series elastic actuator (paper 004, Ardakanian & Akbarzadeh, section 4).

The spring of an SEA must be soft enough that a collision of the output with a rigid wall, with the
motor still pushing, does not overload the gearbox (**upper bound**, Eqs. 9–16), and stiff enough
that the saturated motor can still produce the required output torque at the frequencies of the
gait (**lower bound**, Eqs. 17–25). This module rebuilds both bounds for the paper's drive (Maxon
flat brushless 160 W 24 V + Harmonic Drive SHD-20-50) and returns plot data; see
``docs/sea_window.md`` for the derivations and the slips of the printed equations.

Units: SI throughout, because the data sheets and the paper are in it — N·m, rad, s, kg·m²,
N·m·s/rad, N·m/rad; speeds from data sheets in rpm are named ``_rpm``. Quantities of the motor and
of the gearbox *input* are on the motor shaft (high-speed side, the paper's overbar); everything
the dynamics use is reflected to the gearbox output (low-speed side) by :func:`reflect`:
inertia and viscous friction × R², Coulomb friction × R (Eqs. 4–6), angle and speed ÷ R.

Line numbers ("l. 139") refer to ``/work/shared/seeds/004_4bc0ae606913aafd.txt``.

Corrections to the paper (each derived in the function that applies it and in the docs):

* Eqs. 13/16 give the speed at impact as ω/R; Eqs. 9–10 are output-side, so it is ω. As printed
  no spring up to 1e6 N·m/rad reaches the 69 N·m limit (:func:`simulate_impact`).
* Eqs. 11/14 set the gearbox twist to τ_s/G_k; steady motion needs (τ_s + friction of the output
  gearbox half)/G_k, so that t = 0 is an equilibrium (negligible numerically).
* l. 244 cites "initial conditions of Eqs. 9 and 10": they are Eqs. 11–16.
* G_k is never given (assumed, see :class:`Gearbox`); the held motor torque is taken as the
  steady-state torque before the impact.
* Figs. 8–9 bound the gearbox torque, the text the spring torque: both are offered
  (``criterion``); they differ by the output half's friction.
* Eq. 24: 53/395.5 = 0.1340, not 0.1416 (:func:`torque_bandwidth_rad_per_s` uses the ratio of the
  torques it is given).
* Eq. 21 leaves I_e, b_e undefined: they are the coefficients of Eq. 20.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from flexopt.fea.errors import FeaError
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

__all__ = [
    "PAPER_BANDWIDTH_rad_per_s",
    "PAPER_MAX_TORQUE_Nm",
    "PAPER_STIFFNESS_Nm_per_rad",
    "PAPER_TORQUE_RATIO_PRINTED",
    "KNEE_MAX_SPEED_rpm",
    "BodeData",
    "Gearbox",
    "ImpactResponse",
    "ImpactSettings",
    "Motor",
    "PeakTorqueCurve",
    "ReflectedDrive",
    "StiffnessWindow",
    "WindowDetails",
    "bode_data",
    "max_stiffness_for_impact",
    "min_stiffness_for_bandwidth",
    "paper_report",
    "peak_torque_curve",
    "peak_torque_rigid_Nm",
    "reflect",
    "rpm_to_rad_per_s",
    "saturation_speed_rad_per_s",
    "saturation_torque_Nm",
    "simulate_impact",
    "spring_deflection_rad",
    "stiffness_window",
    "torque_bandwidth_rad_per_s",
    "torque_transfer",
]

# --- numbers the paper prints (for checks and reports, not defaults of any computation) -----------
PAPER_STIFFNESS_Nm_per_rad = 275.0  # safety bound and chosen spring, l. 246, l. 336, Table 10
PAPER_MAX_TORQUE_Nm = 53.0  # required output torque, Eq. 24 (l. 288) and Eq. 26 (l. 340)
PAPER_BANDWIDTH_rad_per_s = 32.25  # Eq. 25, l. 330 (5.13 Hz)
PAPER_TORQUE_RATIO_PRINTED = 0.1416  # Eq. 24, l. 288; 53 / 395.5 is 0.1340 (a slip)
# Largest knee speed at the gearbox output with 50 % assistance (slow walking), l. 105: the
# "walking" operating point of the impact analysis (Eq. 16) uses the knee only (l. 198).
KNEE_MAX_SPEED_rpm = 46.86


def rpm_to_rad_per_s(speed_rpm: float) -> float:
    """Convert a data-sheet speed in rev/min to rad/s (the tables write ``rpm · 2π/60``)."""
    return speed_rpm * 2.0 * math.pi / 60.0


# --- data sheets ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Motor:
    """Motor data on the motor shaft (high-speed side). Defaults: paper Table 3 (l. 133–145).

    Attributes
    ----------
    name : str
        Catalogue name.
    power_W : float, W
        Rated power (Table 3, 160 W).
    nominal_voltage_V : float, V
        Nominal voltage (24 V).
    rotor_inertia_kg_m2 : float, kg·m²
        Rotor inertia M Ī, printed ``3170 * 10^-7`` (l. 139). Its digits repeat the no-load speed
        (3170 rpm, l. 145) but 3.17e-4 kg·m² is the right size for a Ø90 mm flat motor, so it is
        taken as printed.
    viscous_Nm_s_per_rad : float, N·m·s/rad
        Viscous friction M b̄ (0, l. 140; the table's unit kg·m²/(rad·s) means N·m·s/rad).
    coulomb_friction_Nm : float, N·m
        Coulomb friction M τ̄_c = no-load current × torque constant = 0.0468 N·m (l. 141).
    stall_torque_Nm : float, N·m
        Stall torque at nominal voltage, 7.91 N·m (l. 142).
    nominal_torque_Nm : float, N·m
        Maximum continuous torque, 0.457 N·m (l. 143).
    nominal_speed_rpm : float, rpm
        Nominal speed, 2720 rpm (l. 144).
    no_load_speed_rpm : float, rpm
        No-load speed at nominal voltage, 3170 rpm (l. 145).
    """

    name: str = "Maxon flat brushless 160 W 24 V"
    power_W: float = 160.0
    nominal_voltage_V: float = 24.0
    rotor_inertia_kg_m2: float = 3170e-7
    viscous_Nm_s_per_rad: float = 0.0
    coulomb_friction_Nm: float = 0.0468
    stall_torque_Nm: float = 7.91
    nominal_torque_Nm: float = 0.457
    nominal_speed_rpm: float = 2720.0
    no_load_speed_rpm: float = 3170.0

    def __post_init__(self) -> None:
        _check_positive(self, "rotor_inertia_kg_m2", "stall_torque_Nm", "no_load_speed_rpm")
        _check_non_negative(self, "viscous_Nm_s_per_rad", "coulomb_friction_Nm")

    @property
    def no_load_speed_rad_per_s(self) -> float:
        """No-load speed ω̄_nl on the motor shaft, rad/s."""
        return rpm_to_rad_per_s(self.no_load_speed_rpm)

    @property
    def nominal_speed_rad_per_s(self) -> float:
        """Nominal speed on the motor shaft, rad/s."""
        return rpm_to_rad_per_s(self.nominal_speed_rpm)


# The paper gives no torsional stiffness for the gearbox (G_k in Eqs. 9–11 has no value anywhere).
# 1.3e4 N·m/rad is the order of the low-torque stiffness K1 that Harmonic Drive lists for size-20,
# ratio-50 cup/hat units; it is an assumption, not a data-sheet value checked here. The upper bound
# barely depends on it because the SEA spring (~300 N·m/rad) is ~50x softer (docs: sensitivity).
_ASSUMED_GEARBOX_STIFFNESS_Nm_per_rad = 1.3e4


@dataclass(frozen=True)
class Gearbox:
    """Gearbox data. Defaults: paper Table 4 (l. 147–158), Harmonic Drive SHD-20-50-2SH.

    Attributes
    ----------
    name : str
        Catalogue name.
    ratio : float, -
        Reduction ratio R = motor speed / output speed (50, l. 151).
    input_inertia_kg_m2 : float, kg·m²
        Inertia on the input shaft G Ī, 0.09e-4 kg·m² (l. 152).
    viscous_Nm_s_per_rad : float, N·m·s/rad
        Viscous friction on the input side G b̄, 0.00032 (l. 153).
    coulomb_friction_Nm : float, N·m
        Coulomb friction on the input side G τ̄_c, 0.066 N·m (l. 154).
    average_input_speed_limit_rpm : float, rpm
        Limit for the average input speed, 3500 rpm (l. 155).
    max_input_speed_limit_rpm : float, rpm
        Limit for the maximum input speed, 6500 rpm (l. 156).
    momentary_peak_torque_Nm : float, N·m
        Momentary (collision) peak torque at the output, 69 N·m (l. 157): the upper-bound limit.
    average_torque_limit_Nm : float, N·m
        Limit for the average load torque at the output, 24 N·m (l. 158).
    stiffness_Nm_per_rad : float, N·m/rad
        Torsional stiffness G_k at the output. **Not in the paper**; 1.3e4 N·m/rad is an assumed
        catalogue-order value. ``math.inf`` makes the gearbox rigid (one-DOF impact model).
    """

    name: str = "Harmonic Drive SHD-20-50-2SH"
    ratio: float = 50.0
    input_inertia_kg_m2: float = 0.09e-4
    viscous_Nm_s_per_rad: float = 0.00032
    coulomb_friction_Nm: float = 0.066
    average_input_speed_limit_rpm: float = 3500.0
    max_input_speed_limit_rpm: float = 6500.0
    momentary_peak_torque_Nm: float = 69.0
    average_torque_limit_Nm: float = 24.0
    stiffness_Nm_per_rad: float = _ASSUMED_GEARBOX_STIFFNESS_Nm_per_rad

    def __post_init__(self) -> None:
        _check_positive(self, "ratio", "momentary_peak_torque_Nm", "stiffness_Nm_per_rad")
        _check_non_negative(
            self, "input_inertia_kg_m2", "viscous_Nm_s_per_rad", "coulomb_friction_Nm"
        )


def _check_positive(obj: object, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not value > 0.0:
            raise FeaError(f"{type(obj).__name__}.{name} = {value!r} must be > 0")


def _check_non_negative(obj: object, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (value >= 0.0 and math.isfinite(value)):
            raise FeaError(f"{type(obj).__name__}.{name} = {value!r} must be finite and >= 0")


@dataclass(frozen=True)
class ReflectedDrive:
    """Motor + gearbox reflected to the gearbox output (low-speed side), Eqs. 4–6.

    Attributes
    ----------
    motor_inertia_kg_m2 : float, kg·m²
        M I = M Ī R².
    gearbox_inertia_kg_m2 : float, kg·m²
        G I = G Ī R² (split in halves between the two gearbox bodies of the impact model).
    motor_viscous_Nm_s_per_rad, gearbox_viscous_Nm_s_per_rad : float, N·m·s/rad
        M b = M b̄ R², G b = G b̄ R².
    motor_coulomb_Nm, gearbox_coulomb_Nm : float, N·m
        M τ_c = M τ̄_c R, G τ_c = G τ̄_c R.
    gearbox_stiffness_Nm_per_rad : float, N·m/rad
        G_k (already an output-side value in catalogues); ``inf`` for a rigid gearbox.
    """

    motor_inertia_kg_m2: float
    gearbox_inertia_kg_m2: float
    motor_viscous_Nm_s_per_rad: float
    gearbox_viscous_Nm_s_per_rad: float
    motor_coulomb_Nm: float
    gearbox_coulomb_Nm: float
    gearbox_stiffness_Nm_per_rad: float

    @property
    def inertia_kg_m2(self) -> float:
        """Total reflected inertia I_e = (M Ī + G Ī) R², kg·m² (Eq. 4, Eq. 20)."""
        return self.motor_inertia_kg_m2 + self.gearbox_inertia_kg_m2

    @property
    def viscous_Nm_s_per_rad(self) -> float:
        """Total reflected viscous friction b_e = (M b̄ + G b̄) R², N·m·s/rad (Eq. 5, Eq. 20)."""
        return self.motor_viscous_Nm_s_per_rad + self.gearbox_viscous_Nm_s_per_rad

    @property
    def coulomb_Nm(self) -> float:
        """Total reflected Coulomb friction (M τ̄_c + G τ̄_c) R, N·m (Eq. 6)."""
        return self.motor_coulomb_Nm + self.gearbox_coulomb_Nm


def reflect(motor: Motor, gearbox: Gearbox) -> ReflectedDrive:
    """Reflect motor and gearbox data to the gearbox output (paper Eqs. 4–6, l. 180–184).

    Parameters
    ----------
    motor : Motor
        Motor data on the motor shaft.
    gearbox : Gearbox
        Gearbox data (input-side friction and inertia, output-side stiffness).

    Returns
    -------
    ReflectedDrive
        Output-side inertias (× R²), viscous coefficients (× R²) and Coulomb torques (× R).
    """
    r = gearbox.ratio
    return ReflectedDrive(
        motor_inertia_kg_m2=motor.rotor_inertia_kg_m2 * r**2,
        gearbox_inertia_kg_m2=gearbox.input_inertia_kg_m2 * r**2,
        motor_viscous_Nm_s_per_rad=motor.viscous_Nm_s_per_rad * r**2,
        gearbox_viscous_Nm_s_per_rad=gearbox.viscous_Nm_s_per_rad * r**2,
        motor_coulomb_Nm=motor.coulomb_friction_Nm * r,
        gearbox_coulomb_Nm=gearbox.coulomb_friction_Nm * r,
        gearbox_stiffness_Nm_per_rad=gearbox.stiffness_Nm_per_rad,
    )


# --- upper bound: collision with a rigid wall (Eqs. 9–16) -----------------------------------------


@dataclass(frozen=True)
class ImpactSettings:
    """Numerical settings of the impact simulation, each with the reason for its value.

    Attributes
    ----------
    rtol : float
        Relative tolerance of ``solve_ivp``. 1e-10 keeps the energy of the undamped model constant
        to ~1e-8 of the kinetic energy at impact, far below anything that moves K_max.
    atol_angle_rad : float, rad
        Absolute tolerance on angles; the gearbox twist is ~1e-3 rad, so 1e-13 resolves it to 1e-10.
    atol_speed_rad_per_s : float, rad/s
        Absolute tolerance on speeds (impact speeds are ~1 rad/s).
    sign_speed_rad_per_s : float, rad/s
        Coulomb friction is ``τ_c · tanh(ω / sign_speed)`` instead of ``τ_c · sign(ω)`` so the
        right-hand side is smooth. 1e-4 rad/s is 1e-4 of a typical impact speed: friction is at full
        strength except in the last 1e-8 of the approach's kinetic energy.
    max_periods : float
        Longest simulated time, in periods 2π·sqrt(I_e/K_series) of the slow (spring) mode. The
        run normally ends earlier, when the motor first stops (see ``gearbox_periods_after_stop``);
        the first stop comes within half a period.
    gearbox_periods_after_stop : float
        The run goes on this many gearbox-mode periods 2π·sqrt((G/2 I)/(G_k + K)) after the motor
        first stops, to catch the last ripple of the gearbox mode on the spring torque. It stops
        there because that first stop is the largest spring torque of the whole response: later
        swings lose 2 τ_c per half cycle to Coulomb friction (or the drive sticks), and beyond it
        the tanh friction would let the drive creep towards K θ = τ_m, a regularisation artefact
        that real stiction forbids (it would add up to τ_c to the peak).
    method : str
        ``solve_ivp`` method. LSODA switches to BDF where the regularised friction or the
        stiff gearbox mode (~1 kHz against ~3 Hz) make the system stiff.
    """

    rtol: float = 1e-10
    atol_angle_rad: float = 1e-13
    atol_speed_rad_per_s: float = 1e-11
    sign_speed_rad_per_s: float = 1e-4
    max_periods: float = 1.0
    gearbox_periods_after_stop: float = 3.0
    method: str = "LSODA"


@dataclass(frozen=True)
class ImpactResponse:
    """Time history of one collision (output-side quantities, t = 0 at the impact).

    Attributes
    ----------
    stiffness_Nm_per_rad : float, N·m/rad
        SEA spring stiffness K.
    motor_torque_Nm : float, N·m
        Constant output-side motor torque after the impact.
    t_s : (n,) float, s
        The integrator's steps (non-uniform; they resolve the gearbox mode), from the impact to
        shortly after the motor first stops (the largest spring torque; see ImpactSettings).
    motor_angle_rad : (n,) float, rad
        θ1 of the motor + first gearbox half (= θ2 + gearbox twist).
    output_half_angle_rad : (n,) float, rad
        θ2 of the second gearbox half = spring deflection (the wall is at 0).
    motor_speed_rad_per_s, output_half_speed_rad_per_s : (n,) float, rad/s
        dθ1/dt, dθ2/dt.
    spring_torque_Nm : (n,) float, N·m
        K θ2.
    gearbox_torque_Nm : (n,) float, N·m
        G_k (θ1 − θ2) (equal to the spring torque for a rigid gearbox).
    peak_spring_torque_Nm, peak_gearbox_torque_Nm : float, N·m
        Largest values over the simulated time (solver steps refined on the dense output).
    time_of_peak_s : float, s
        Time of the spring-torque peak.
    converged : bool
        False if the integrator failed or the motor had not stopped by ``max_periods``.
    message : str
        Integrator message or the reason for ``converged = False``.
    """

    stiffness_Nm_per_rad: float
    motor_torque_Nm: float
    t_s: np.ndarray
    motor_angle_rad: np.ndarray
    output_half_angle_rad: np.ndarray
    motor_speed_rad_per_s: np.ndarray
    output_half_speed_rad_per_s: np.ndarray
    spring_torque_Nm: np.ndarray
    gearbox_torque_Nm: np.ndarray
    peak_spring_torque_Nm: float
    peak_gearbox_torque_Nm: float
    time_of_peak_s: float
    converged: bool
    message: str


@dataclass(frozen=True)
class _ImpactModel:
    """Parameters of Eqs. 9–10 (corrected), output side."""

    i1: float  # M I + G I / 2
    i2: float  # G I / 2
    b1: float  # M b + G b / 2
    b2: float  # G b / 2
    c1: float  # M τ_c + G τ_c / 2
    c2: float  # G τ_c / 2
    kg: float  # G_k
    k: float  # SEA spring K
    tau_m: float  # constant motor torque
    v_s: float  # regularisation speed of sign()

    @property
    def rigid(self) -> bool:
        return math.isinf(self.kg)


def _impact_model(
    k: float, drive: ReflectedDrive, motor_torque_Nm: float, settings: ImpactSettings
) -> _ImpactModel:
    half_i = drive.gearbox_inertia_kg_m2 / 2.0
    half_b = drive.gearbox_viscous_Nm_s_per_rad / 2.0
    half_c = drive.gearbox_coulomb_Nm / 2.0
    return _ImpactModel(
        i1=drive.motor_inertia_kg_m2 + half_i,
        i2=half_i,
        b1=drive.motor_viscous_Nm_s_per_rad + half_b,
        b2=half_b,
        c1=drive.motor_coulomb_Nm + half_c,
        c2=half_c,
        kg=drive.gearbox_stiffness_Nm_per_rad,
        k=k,
        tau_m=motor_torque_Nm,
        v_s=settings.sign_speed_rad_per_s,
    )


_Rhs = Callable[[float, np.ndarray], np.ndarray]
_Jac = Callable[[float, np.ndarray], np.ndarray]


def _steady_motor_torque(m: _ImpactModel, spring_torque: float, speed: float) -> float:
    """Motor torque that keeps the drive at constant ``speed`` against ``spring_torque``."""
    sgn = math.tanh(speed / m.v_s)
    return spring_torque + (m.b1 + m.b2) * speed + (m.c1 + m.c2) * sgn


def _initial_state(m: _ImpactModel, spring_torque: float, speed: float) -> np.ndarray:
    """State just before the impact: steady motion at ``speed`` carrying ``spring_torque``.

    The gearbox twist carries the spring torque plus the friction of the second gearbox half
    (corrected Eq. 11: the paper's ``τ_s / G_k`` leaves that friction out, a ~1e-4 rad difference).
    """
    theta2 = spring_torque / m.k
    if m.rigid:
        return np.array([theta2, speed])
    gear_torque = spring_torque + m.b2 * speed + m.c2 * math.tanh(speed / m.v_s)
    return np.array([theta2 + gear_torque / m.kg, theta2, speed, speed])


def _rhs_2dof(m: _ImpactModel) -> tuple[_Rhs, _Jac]:
    """Right-hand side and Jacobian of corrected Eqs. 9–10, state (θ1, θ2, θ1', θ2')."""

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        th1, th2, w1, w2 = y
        gear = m.kg * (th1 - th2)
        a1 = (m.tau_m - m.b1 * w1 - m.c1 * math.tanh(w1 / m.v_s) - gear) / m.i1
        a2 = (gear - m.b2 * w2 - m.c2 * math.tanh(w2 / m.v_s) - m.k * th2) / m.i2
        return np.array([w1, w2, a1, a2])

    def jac(_t: float, y: np.ndarray) -> np.ndarray:
        # d/dw of c·tanh(w/v_s) is c/(v_s cosh²); beyond 40 v_s it is < 1e-34 c/v_s (and cosh
        # would overflow further out), so it is dropped there.
        _, _, w1, w2 = y
        d1 = m.b1 + m.c1 / (m.v_s * math.cosh(w1 / m.v_s) ** 2) if abs(w1) < 40 * m.v_s else m.b1
        d2 = m.b2 + m.c2 / (m.v_s * math.cosh(w2 / m.v_s) ** 2) if abs(w2) < 40 * m.v_s else m.b2
        return np.array(
            [
                [0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
                [-m.kg / m.i1, m.kg / m.i1, -d1 / m.i1, 0.0],
                [m.kg / m.i2, -(m.kg + m.k) / m.i2, 0.0, -d2 / m.i2],
            ]
        )

    return rhs, jac


def _rhs_1dof(m: _ImpactModel) -> tuple[_Rhs, _Jac]:
    """Rigid gearbox: one inertia I_e on the spring, state (θ, θ')."""

    i, b, c = m.i1 + m.i2, m.b1 + m.b2, m.c1 + m.c2

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        th, w = y
        return np.array([w, (m.tau_m - b * w - c * math.tanh(w / m.v_s) - m.k * th) / i])

    def jac(_t: float, y: np.ndarray) -> np.ndarray:
        w = y[1]
        d = b + c / (m.v_s * math.cosh(w / m.v_s) ** 2) if abs(w) < 40 * m.v_s else b
        return np.array([[0.0, 1.0], [-m.k / i, -d / i]])

    return rhs, jac


def simulate_impact(
    stiffness_Nm_per_rad: float,
    motor: Motor,
    gearbox: Gearbox,
    impact_speed_rad_per_s: float,
    spring_torque_Nm: float,
    motor_torque_Nm: float | None = None,
    settings: ImpactSettings | None = None,
) -> ImpactResponse:
    r"""Collision of the SEA output with a rigid wall while the motor keeps its torque (Eqs. 9–16).

    Two bodies on the output side: body 1 = motor + first gearbox half (θ1), body 2 = second
    gearbox half (θ2), joined by the gearbox stiffness G_k; the SEA spring K joins body 2 to the
    wall (output fixed at 0 from t = 0)::

        (M I + G I/2) θ1'' = τ_m − (M b + G b/2) θ1' − (M τ_c + G τ_c/2) sgn θ1' − G_k (θ1 − θ2)
        (G I/2)       θ2'' = G_k (θ1 − θ2) − (G b/2) θ2' − (G τ_c/2) sgn θ2' − K θ2

    Initial conditions (corrected Eqs. 11–16): steady motion at the output speed ω0 carrying the
    spring torque τ_s — θ2 = τ_s/K, θ1 = θ2 + (τ_s + G b/2 ω0 + G τ_c/2)/G_k, θ1' = θ2' = ω0
    (the paper prints ω0/R, a slip: all quantities here are output-side). A rigid gearbox
    (``gearbox.stiffness_Nm_per_rad = inf``) gives the single-DOF model with I = I_e.

    Coulomb friction is regularised (tanh); the run ends a few gearbox-mode periods after the
    motor first stops, which is the largest spring torque of the response (see
    :class:`ImpactSettings` for why running on would be wrong, not only slow).

    Parameters
    ----------
    stiffness_Nm_per_rad : float, N·m/rad
        SEA spring stiffness K > 0.
    motor, gearbox : Motor, Gearbox
        Drive data (reflected with :func:`reflect`).
    impact_speed_rad_per_s : float, rad/s
        Output (joint) speed ω0 at the impact, towards the wall (≥ 0).
    spring_torque_Nm : float, N·m
        Spring torque τ_s at the impact (the assistance torque being delivered; the preload).
    motor_torque_Nm : float or None, N·m
        Output-side motor torque held after the impact. None: the torque of the steady motion
        before the impact, τ_s + b_e ω0 + τ_c,e ("equal to the torque applied before the impact",
        l. 198), so nothing accelerates at t = 0⁺.
    settings : ImpactSettings or None
        Tolerances; defaults when None.

    Returns
    -------
    ImpactResponse
        Histories and the peak spring and gearbox torques.
    """
    settings = settings or ImpactSettings()
    k = float(stiffness_Nm_per_rad)
    if not (k > 0.0 and math.isfinite(k)):
        raise FeaError(f"spring stiffness {k!r} N·m/rad must be finite and > 0")
    w0 = float(impact_speed_rad_per_s)
    if not (w0 >= 0.0 and math.isfinite(w0)):
        raise FeaError(
            f"impact speed {w0!r} rad/s must be finite and >= 0 (speed towards the wall; "
            "give the output-side joint speed, not the motor speed)"
        )
    drive = reflect(motor, gearbox)
    model = _impact_model(k, drive, 0.0, settings)
    tau_m = (
        _steady_motor_torque(model, spring_torque_Nm, w0)
        if motor_torque_Nm is None
        else float(motor_torque_Nm)
    )
    model = _impact_model(k, drive, tau_m, settings)
    y0 = _initial_state(model, spring_torque_Nm, w0)

    i_total = drive.inertia_kg_m2
    k_series = k if model.rigid else k * model.kg / (k + model.kg)
    t_end = settings.max_periods * 2.0 * math.pi * math.sqrt(i_total / k_series)
    t_after = (
        0.0
        if model.rigid
        else settings.gearbox_periods_after_stop
        * 2.0
        * math.pi
        * math.sqrt(model.i2 / (model.kg + k))
    )

    if model.rigid:
        rhs, jac = _rhs_1dof(model)
        atol = np.array([settings.atol_angle_rad, settings.atol_speed_rad_per_s])
    else:
        rhs, jac = _rhs_2dof(model)
        atol = np.array([settings.atol_angle_rad] * 2 + [settings.atol_speed_rad_per_s] * 2)
    i_speed = 1 if model.rigid else 2

    def motor_stops(_t: float, y: np.ndarray) -> float:
        return y[i_speed]

    motor_stops.terminal = True  # type: ignore[attr-defined]
    motor_stops.direction = -1.0  # type: ignore[attr-defined]

    kwargs = {"jac": jac} if settings.method in ("LSODA", "BDF", "Radau") else {}
    common = {"method": settings.method, "rtol": settings.rtol, "atol": atol, **kwargs}
    # No dense output over the whole run: LSODA builds an interpolant per step in Python, which
    # costs 4x the integration itself. The solver's steps resolve the gearbox mode; each peak is
    # then refined by re-integrating only the two steps around it with dense output.
    sol = solve_ivp(rhs, (0.0, t_end), y0, events=[motor_stops], **common)
    stopped = sol.status == 1
    ts, ys = sol.t, sol.y
    if stopped and t_after > 0.0:
        tail = solve_ivp(rhs, (sol.t[-1], sol.t[-1] + t_after), sol.y[:, -1], **common)
        ts = np.concatenate([ts, tail.t[1:]])
        ys = np.concatenate([ys, tail.y[:, 1:]], axis=1)
        sol.success = sol.success and tail.success
        if not tail.success:
            sol.message = tail.message

    def torques(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if model.rigid:
            spring = k * y[0]
            return spring, spring
        return k * y[1], model.kg * (y[0] - y[1])

    spring, gear = torques(ys)

    def refine(which: int, values: np.ndarray) -> tuple[float, float]:
        i = int(values.argmax())
        if not sol.success or len(ts) < 3:
            return float(values[i]), float(ts[i])
        i0, i1 = max(i - 1, 0), min(i + 1, len(ts) - 1)
        local = solve_ivp(rhs, (ts[i0], ts[i1]), ys[:, i0], dense_output=True, **common)
        res = minimize_scalar(
            lambda t: -float(torques(local.sol(t))[which]),
            bounds=(ts[i0], ts[i1]),
            method="bounded",
            options={"xatol": 1e-12 * t_end},
        )
        if local.success and -res.fun > values[i]:
            return float(-res.fun), float(res.x)
        return float(values[i]), float(ts[i])

    peak_s, t_peak = refine(0, spring)
    peak_g, _ = refine(1, gear)
    th1, th2 = (ys[0], ys[0]) if model.rigid else (ys[0], ys[1])
    w1, w2 = (ys[1], ys[1]) if model.rigid else (ys[2], ys[3])

    converged = bool(sol.success)
    message = "the motor stopped: first spring peak passed" if stopped else str(sol.message)
    moved = peak_s > spring[0] + 1e-9 * max(1.0, abs(peak_s))
    if converged and moved and not stopped:
        converged = False
        message = (
            f"the motor was still moving towards the wall after {ts[-1]:.3g} s: "
            "raise ImpactSettings.max_periods"
        )
    return ImpactResponse(
        stiffness_Nm_per_rad=k,
        motor_torque_Nm=tau_m,
        t_s=ts,
        motor_angle_rad=np.asarray(th1),
        output_half_angle_rad=np.asarray(th2),
        motor_speed_rad_per_s=np.asarray(w1),
        output_half_speed_rad_per_s=np.asarray(w2),
        spring_torque_Nm=spring,
        gearbox_torque_Nm=gear,
        peak_spring_torque_Nm=peak_s,
        peak_gearbox_torque_Nm=peak_g,
        time_of_peak_s=t_peak,
        converged=converged,
        message=message,
    )


def peak_torque_rigid_Nm(
    stiffness_Nm_per_rad: float | np.ndarray,
    inertia_kg_m2: float,
    impact_speed_rad_per_s: float,
    spring_torque_Nm: float,
    net_motor_torque_Nm: float,
) -> float | np.ndarray:
    r"""Closed-form peak spring torque of the rigid-gearbox, viscous-free impact.

    One inertia I on a spring K to the wall, driven by a constant net torque τ_n (motor torque
    minus the Coulomb friction, which keeps its sign until the speed first vanishes). Work from the
    impact (spring torque τ_s = K θ0, speed ω0) to the turning point (K θp, speed 0)::

        ½ K (θp² − θ0²) − τ_n (θp − θ0) = ½ I ω0²
        ⇒  K θp = τ_n + sqrt((τ_n − τ_s)² + K I ω0²)

    With the steady-state motor torque (τ_n = τ_s) this is τ_s + ω0 sqrt(K I); from rest without
    preload it is 2 τ_n (the dynamic doubling of a suddenly applied torque).

    Parameters
    ----------
    stiffness_Nm_per_rad : float or (n,) float, N·m/rad
        Spring stiffness K.
    inertia_kg_m2 : float, kg·m²
        Output-side inertia I.
    impact_speed_rad_per_s : float, rad/s
        ω0.
    spring_torque_Nm : float, N·m
        τ_s at the impact.
    net_motor_torque_Nm : float, N·m
        τ_n.

    Returns
    -------
    float or (n,) float, N·m
        Peak spring torque K θp.
    """
    k = np.asarray(stiffness_Nm_per_rad, dtype=float)
    tn, ts = net_motor_torque_Nm, spring_torque_Nm
    out = tn + np.sqrt((tn - ts) ** 2 + k * inertia_kg_m2 * impact_speed_rad_per_s**2)
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class PeakTorqueCurve:
    """Peak torques after the impact against spring stiffness (the paper's Figs. 8–9).

    Attributes
    ----------
    stiffness_Nm_per_rad : (n,) float, N·m/rad
        Spring stiffnesses K.
    peak_spring_torque_Nm : (n,) float, N·m
        Peak K θ2 from the simulation.
    peak_gearbox_torque_Nm : (n,) float, N·m
        Peak G_k (θ1 − θ2) (what Figs. 8–9 are captioned with: torque on the gearbox).
    rigid_frictionless_Nm : (n,) float, N·m
        :func:`peak_torque_rigid_Nm` with I = I_e, τ_n = τ_s: the one-line estimate.
    torque_limit_Nm : float, N·m
        The gearbox momentary limit (horizontal line of the figures).
    converged : (n,) bool
        Per-point simulation status.
    """

    stiffness_Nm_per_rad: np.ndarray
    peak_spring_torque_Nm: np.ndarray
    peak_gearbox_torque_Nm: np.ndarray
    rigid_frictionless_Nm: np.ndarray
    torque_limit_Nm: float
    converged: np.ndarray


def peak_torque_curve(
    stiffnesses_Nm_per_rad: Sequence[float] | np.ndarray,
    motor: Motor,
    gearbox: Gearbox,
    impact_speed_rad_per_s: float,
    spring_torque_Nm: float,
    motor_torque_Nm: float | None = None,
    settings: ImpactSettings | None = None,
) -> PeakTorqueCurve:
    """Plot data: peak torques after the impact for each stiffness (see :func:`simulate_impact`).

    Parameters
    ----------
    stiffnesses_Nm_per_rad : (n,) float, N·m/rad
        Spring stiffnesses.
    motor, gearbox, impact_speed_rad_per_s, spring_torque_Nm, motor_torque_Nm, settings
        As in :func:`simulate_impact`.

    Returns
    -------
    PeakTorqueCurve
    """
    ks = np.asarray(stiffnesses_Nm_per_rad, dtype=float)
    spring, gear, ok = [], [], []
    for k in ks:
        r = simulate_impact(
            k, motor, gearbox, impact_speed_rad_per_s, spring_torque_Nm, motor_torque_Nm, settings
        )
        spring.append(r.peak_spring_torque_Nm)
        gear.append(r.peak_gearbox_torque_Nm)
        ok.append(r.converged)
    rigid = peak_torque_rigid_Nm(
        ks,
        reflect(motor, gearbox).inertia_kg_m2,
        impact_speed_rad_per_s,
        spring_torque_Nm,
        spring_torque_Nm,
    )
    return PeakTorqueCurve(
        stiffness_Nm_per_rad=ks,
        peak_spring_torque_Nm=np.array(spring),
        peak_gearbox_torque_Nm=np.array(gear),
        rigid_frictionless_Nm=np.atleast_1d(rigid),
        torque_limit_Nm=gearbox.momentary_peak_torque_Nm,
        converged=np.array(ok, dtype=bool),
    )


# Bracket search for K_max: stiffness range the search may explore before it concludes that no
# (0) or every (inf) spring stiffness keeps the peak under the limit. 1 N·m/rad is far softer than
# any SEA spring (and slow to simulate: the period grows as 1/sqrt(K) while the gearbox mode still
# needs ~20 steps per ms); 1e6 is 100x the gearbox itself, beyond which the "spring" is rigid.
_K_SEARCH_LO = 1.0
_K_SEARCH_HI = 1e6
_K_XTOL_REL = 1e-7  # K_max to 1e-7 relative: well inside the ~1e-6 scatter of the simulated peak


def max_stiffness_for_impact(
    motor: Motor,
    gearbox: Gearbox,
    impact_speed_rad_per_s: float,
    spring_torque_Nm: float,
    motor_torque_Nm: float | None = None,
    torque_limit_Nm: float | None = None,
    criterion: str = "spring",
    settings: ImpactSettings | None = None,
) -> float:
    """Largest spring stiffness whose peak impact torque stays at or under the gearbox limit.

    Parameters
    ----------
    motor, gearbox, impact_speed_rad_per_s, spring_torque_Nm, motor_torque_Nm, settings
        As in :func:`simulate_impact`.
    torque_limit_Nm : float or None, N·m
        Limit; None uses ``gearbox.momentary_peak_torque_Nm`` (69 N·m).
    criterion : {"spring", "gearbox"}
        Which peak is held to the limit: the spring torque K θ2 or the gearbox torque
        G_k (θ1 − θ2) (they differ by the inertia torque of the second gearbox half).

    Returns
    -------
    float, N·m/rad
        K_max; ``0.0`` if even a vanishing stiffness exceeds the limit (e.g. preload ≥ limit),
        ``inf`` if no stiffness up to 1e6 N·m/rad (100x the gearbox) reaches the limit (e.g. a very
        slow impact with a small motor torque).
    """
    limit = gearbox.momentary_peak_torque_Nm if torque_limit_Nm is None else torque_limit_Nm
    if criterion not in ("spring", "gearbox"):
        raise FeaError(f"criterion {criterion!r} must be 'spring' or 'gearbox'")

    def excess(log_k: float) -> float:
        r = simulate_impact(
            math.exp(log_k),
            motor,
            gearbox,
            impact_speed_rad_per_s,
            spring_torque_Nm,
            motor_torque_Nm,
            settings,
        )
        peak = r.peak_spring_torque_Nm if criterion == "spring" else r.peak_gearbox_torque_Nm
        return peak - limit

    if spring_torque_Nm >= limit:
        return 0.0  # the spring torque at the impact is already a lower bound of the peak
    # Start from the rigid, frictionless estimate and widen geometrically: the peak grows with K.
    drive = reflect(motor, gearbox)
    w0 = impact_speed_rad_per_s
    headroom = limit - spring_torque_Nm
    if w0 > 0.0 and headroom > 0.0:
        guess = headroom**2 / (drive.inertia_kg_m2 * w0**2)
    else:
        guess = PAPER_STIFFNESS_Nm_per_rad
    lo = hi = math.log(min(max(guess, 10 * _K_SEARCH_LO), _K_SEARCH_HI / 10))
    f_lo = f_hi = excess(lo)
    while f_lo > 0.0:
        if lo <= math.log(_K_SEARCH_LO):
            return 0.0
        hi, f_hi = lo, f_lo
        lo = max(lo - math.log(2.0), math.log(_K_SEARCH_LO))
        f_lo = excess(lo)
    while f_hi <= 0.0:
        if hi >= math.log(_K_SEARCH_HI):
            return math.inf
        lo, f_lo = hi, f_hi
        hi = min(hi + math.log(2.0), math.log(_K_SEARCH_HI))
        f_hi = excess(hi)
    return math.exp(brentq(excess, lo, hi, xtol=_K_XTOL_REL))


# --- lower bound: torque bandwidth with the output locked (Eqs. 17–25) ----------------------------


def saturation_torque_Nm(motor: Motor, gearbox: Gearbox) -> float:
    """τ_sat = τ_stall R (Eq. 22, l. 276): 7.91 × 50 = 395.5 N·m for the paper's drive."""
    return motor.stall_torque_Nm * gearbox.ratio


def saturation_speed_rad_per_s(motor: Motor, gearbox: Gearbox) -> float:
    """ω_sat = ω_no-load / R (Eq. 23, l. 278), output side, rad/s (6.64 rad/s for the paper)."""
    return motor.no_load_speed_rad_per_s / gearbox.ratio


def _bandwidth_coefficients(motor: Motor, gearbox: Gearbox) -> tuple[float, float]:
    """(I_e, b_e + τ_sat/ω_sat) of Eq. 21, output side."""
    drive = reflect(motor, gearbox)
    back_emf = saturation_torque_Nm(motor, gearbox) / saturation_speed_rad_per_s(motor, gearbox)
    return drive.inertia_kg_m2, drive.viscous_Nm_s_per_rad + back_emf


def torque_transfer(
    stiffness_Nm_per_rad: float, motor: Motor, gearbox: Gearbox, s: complex | np.ndarray
) -> complex | np.ndarray:
    r"""τ_s/τ_sat = K / (I_e s² + (b_e + τ_sat/ω_sat) s + K) (Eq. 21, l. 274).

    Locked output: the spring torque per unit saturated motor torque, with the motor's
    torque–speed line τ = τ_sat − (τ_sat/ω_sat) ω acting as damping (back-EMF of a
    voltage-saturated amplifier, ref. [20]). I_e = (M Ī + G Ī) R², b_e = (M b̄ + G b̄) R² (Eq. 20).

    Parameters
    ----------
    stiffness_Nm_per_rad : float, N·m/rad
        K.
    motor, gearbox : Motor, Gearbox
        Drive data.
    s : complex or array of complex, 1/s
        Laplace variable (``1j * ω`` for the frequency response).

    Returns
    -------
    complex or array of complex, -
    """
    i_e, b = _bandwidth_coefficients(motor, gearbox)
    s = np.asarray(s)
    out = stiffness_Nm_per_rad / (i_e * s**2 + b * s + stiffness_Nm_per_rad)
    return complex(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class BodeData:
    """Frequency response of Eq. 21 (plot data for the paper's Fig. 11).

    Attributes
    ----------
    stiffness_Nm_per_rad : float, N·m/rad
        K.
    frequency_Hz : (n,) float, Hz
    omega_rad_per_s : (n,) float, rad/s
    magnitude : (n,) float, -
        |τ_s/τ_sat|: the output-torque amplitude the saturated motor reaches, per τ_sat.
    magnitude_dB : (n,) float, dB
        20 log10 of ``magnitude``.
    phase_deg : (n,) float, degree
    required_ratio : float, -
        τ_required / τ_sat (the horizontal line of Fig. 11).
    bandwidth_rad_per_s : float, rad/s
        Where ``magnitude`` falls to ``required_ratio``.
    """

    stiffness_Nm_per_rad: float
    frequency_Hz: np.ndarray
    omega_rad_per_s: np.ndarray
    magnitude: np.ndarray
    magnitude_dB: np.ndarray
    phase_deg: np.ndarray
    required_ratio: float
    bandwidth_rad_per_s: float


def _torque_ratio(motor: Motor, gearbox: Gearbox, required_torque_Nm: float) -> float:
    tau_sat = saturation_torque_Nm(motor, gearbox)
    ratio = required_torque_Nm / tau_sat
    if not 0.0 < ratio < 1.0:
        raise FeaError(
            f"required torque {required_torque_Nm!r} N·m must lie in (0, τ_sat = {tau_sat:.4g} "
            "N·m): the saturated motor cannot hold more than τ_sat even at 0 Hz; pick a larger "
            "motor or gear ratio"
        )
    return ratio


def torque_bandwidth_rad_per_s(
    stiffness_Nm_per_rad: float | np.ndarray,
    motor: Motor,
    gearbox: Gearbox,
    required_torque_Nm: float,
) -> float | np.ndarray:
    r"""Highest frequency at which the saturated drive still delivers ``required_torque_Nm``.

    |H(jω)|² = K² / ((K − I ω²)² + b² ω²) = r², r = τ_req/τ_sat < 1, is a quadratic in x = ω²::

        I² x² + (b² − 2 K I) x + K² (1 − 1/r²) = 0

    whose constant term is negative, so it has exactly one positive root; |H| > r below it and
    < r above it, so the bandwidth is well defined even when a resonance peak exists.

    Parameters
    ----------
    stiffness_Nm_per_rad : float or (n,) float, N·m/rad
        K.
    motor, gearbox : Motor, Gearbox
        Drive data.
    required_torque_Nm : float, N·m
        Output torque amplitude to be reached (53 N·m in the paper).

    Returns
    -------
    float or (n,) float, rad/s
    """
    r = _torque_ratio(motor, gearbox, required_torque_Nm)
    i_e, b = _bandwidth_coefficients(motor, gearbox)
    k = np.asarray(stiffness_Nm_per_rad, dtype=float)
    qa = i_e**2
    qb = b**2 - 2.0 * k * i_e
    qc = k**2 * (1.0 - 1.0 / r**2)  # < 0
    disc = np.sqrt(qb**2 - 4.0 * qa * qc)
    # Stable root: avoid −qb + disc cancelling when qb > 0 (heavily damped drives).
    x = np.where(qb > 0.0, 2.0 * qc / (-qb - disc), (-qb + disc) / (2.0 * qa))
    out = np.sqrt(x)
    return float(out) if out.ndim == 0 else out


def min_stiffness_for_bandwidth(
    motor: Motor, gearbox: Gearbox, required_torque_Nm: float, required_bandwidth_Hz: float
) -> float:
    r"""Smallest K whose torque bandwidth reaches ``required_bandwidth_Hz`` (closed form).

    The same condition |H(jω)| = r read as a quadratic in K at ω = 2π f::

        (1/r² − 1) K² + 2 I ω² K − (I² ω⁴ + b² ω²) = 0
        ⇒  K = c / (I ω² + sqrt(I² ω⁴ + (1/r² − 1) c)),   c = I² ω⁴ + b² ω²

    One positive root for every ω, and K → 0 as ω → 0, so the bandwidth grows monotonically
    with K and every K ≥ K_min meets the requirement.

    Parameters
    ----------
    motor, gearbox : Motor, Gearbox
        Drive data.
    required_torque_Nm : float, N·m
        Output torque amplitude to be reached.
    required_bandwidth_Hz : float, Hz
        Highest significant frequency of the joint torque (> 0).

    Returns
    -------
    float, N·m/rad
    """
    if not (required_bandwidth_Hz > 0.0 and math.isfinite(required_bandwidth_Hz)):
        raise FeaError(f"required bandwidth {required_bandwidth_Hz!r} Hz must be finite and > 0")
    r = _torque_ratio(motor, gearbox, required_torque_Nm)
    i_e, b = _bandwidth_coefficients(motor, gearbox)
    w2 = (2.0 * math.pi * required_bandwidth_Hz) ** 2
    c = i_e**2 * w2**2 + b**2 * w2
    return c / (i_e * w2 + math.sqrt(i_e**2 * w2**2 + (1.0 / r**2 - 1.0) * c))


def bode_data(
    stiffness_Nm_per_rad: float,
    motor: Motor,
    gearbox: Gearbox,
    required_torque_Nm: float,
    frequency_Hz: np.ndarray | None = None,
) -> BodeData:
    """Bode magnitude and phase of Eq. 21 with the required-torque line (Fig. 11 plot data).

    Parameters
    ----------
    stiffness_Nm_per_rad : float, N·m/rad
        K.
    motor, gearbox : Motor, Gearbox
        Drive data.
    required_torque_Nm : float, N·m
        Output torque amplitude to be reached.
    frequency_Hz : (n,) float or None, Hz
        Frequencies; None: 200 points log-spaced over 0.01–100 Hz.

    Returns
    -------
    BodeData
    """
    f = np.logspace(-2, 2, 200) if frequency_Hz is None else np.asarray(frequency_Hz, float)
    w = 2.0 * math.pi * f
    h = np.asarray(torque_transfer(stiffness_Nm_per_rad, motor, gearbox, 1j * w))
    mag = np.abs(h)
    return BodeData(
        stiffness_Nm_per_rad=float(stiffness_Nm_per_rad),
        frequency_Hz=f,
        omega_rad_per_s=w,
        magnitude=mag,
        magnitude_dB=20.0 * np.log10(mag),
        phase_deg=np.degrees(np.unwrap(np.angle(h))),
        required_ratio=_torque_ratio(motor, gearbox, required_torque_Nm),
        bandwidth_rad_per_s=float(
            torque_bandwidth_rad_per_s(stiffness_Nm_per_rad, motor, gearbox, required_torque_Nm)
        ),
    )


# --- the window -----------------------------------------------------------------------------------


def spring_deflection_rad(torque_Nm: float, stiffness_Nm_per_rad: float) -> float:
    """Deflection of a linear torsional spring, θ = τ/K, rad (Eq. 26: 53/275 = 0.193 rad)."""
    if not stiffness_Nm_per_rad > 0.0:
        raise FeaError(f"spring stiffness {stiffness_Nm_per_rad!r} N·m/rad must be > 0")
    return torque_Nm / stiffness_Nm_per_rad


@dataclass(frozen=True)
class WindowDetails:
    """The numbers behind a :class:`StiffnessWindow` (all output-side).

    Attributes
    ----------
    required_torque_Nm : float, N·m
        Output torque amplitude the SEA must deliver (spring's design torque).
    impact_speed_rad_per_s : float, rad/s
        Output speed at the collision.
    impact_spring_torque_Nm : float, N·m
        Spring torque at the collision (preload).
    torque_limit_Nm : float, N·m
        Gearbox momentary limit used for K_max.
    criterion : str
        Which peak set ``k_max``: "spring" (K θ2) or "gearbox" (G_k (θ1 − θ2)).
    k_max_spring_criterion_Nm_per_rad, k_max_gearbox_criterion_Nm_per_rad : float, N·m/rad
        K_max under each criterion (they differ by the friction of the output gearbox half).
    required_bandwidth_Hz : float, Hz
        Bandwidth required at the required torque.
    saturation_torque_Nm : float, N·m
        τ_sat = τ_stall R.
    saturation_speed_rad_per_s : float, rad/s
        ω_sat = ω_no-load / R.
    torque_ratio : float, -
        τ_required / τ_sat.
    inertia_kg_m2 : float, kg·m²
        I_e.
    damping_Nm_s_per_rad : float, N·m·s/rad
        b_e + τ_sat/ω_sat (Eq. 21).
    bandwidth_at_k_max_Hz : float, Hz
        Torque bandwidth of the stiffest admissible spring (nan if K_max is 0 or inf).
    deflection_at_k_min_rad, deflection_at_k_max_rad : float, rad
        Spring deflection at the required torque for the window's ends (what the spring
        geometry must allow).
    """

    required_torque_Nm: float
    impact_speed_rad_per_s: float
    impact_spring_torque_Nm: float
    torque_limit_Nm: float
    criterion: str
    k_max_spring_criterion_Nm_per_rad: float
    k_max_gearbox_criterion_Nm_per_rad: float
    required_bandwidth_Hz: float
    saturation_torque_Nm: float
    saturation_speed_rad_per_s: float
    torque_ratio: float
    inertia_kg_m2: float
    damping_Nm_s_per_rad: float
    bandwidth_at_k_max_Hz: float
    deflection_at_k_min_rad: float
    deflection_at_k_max_rad: float


@dataclass(frozen=True)
class StiffnessWindow:
    """Admissible SEA spring stiffness: bandwidth lower bound, collision-safety upper bound.

    Attributes
    ----------
    k_min_Nm_per_rad : float, N·m/rad
        Lower bound (bandwidth, Eqs. 17–25).
    k_max_Nm_per_rad : float, N·m/rad
        Upper bound (impact, Eqs. 9–16).
    details : WindowDetails
        Inputs and intermediate numbers.
    """

    k_min_Nm_per_rad: float
    k_max_Nm_per_rad: float
    details: WindowDetails = field(repr=False)

    @property
    def is_empty(self) -> bool:
        """True when no stiffness satisfies both bounds (change motor, gearbox or requirements)."""
        return not self.k_min_Nm_per_rad <= self.k_max_Nm_per_rad

    def contains(self, stiffness_Nm_per_rad: float) -> bool:
        """Whether ``stiffness_Nm_per_rad`` lies in [k_min, k_max]."""
        return self.k_min_Nm_per_rad <= stiffness_Nm_per_rad <= self.k_max_Nm_per_rad


def stiffness_window(
    motor: Motor,
    gearbox: Gearbox,
    required_torque_Nm: float,
    impact_speed_rad_per_s: float,
    required_bandwidth_Hz: float,
    impact_spring_torque_Nm: float | None = None,
    motor_torque_Nm: float | None = None,
    torque_limit_Nm: float | None = None,
    criterion: str = "spring",
    settings: ImpactSettings | None = None,
) -> StiffnessWindow:
    """Stiffness window of the SEA spring (section 4 of paper 004), the spring study's target.

    Parameters
    ----------
    motor, gearbox : Motor, Gearbox
        Drive data.
    required_torque_Nm : float, N·m
        Output torque amplitude to be delivered (53 N·m in the paper).
    impact_speed_rad_per_s : float, rad/s
        Output speed at the collision (worst operating point of the impact analysis).
    required_bandwidth_Hz : float, Hz
        Highest significant frequency of the joint torque at ``required_torque_Nm``.
    impact_spring_torque_Nm : float or None, N·m
        Spring torque at the collision; None: ``required_torque_Nm`` (collision at the torque peak).
    motor_torque_Nm : float or None, N·m
        Held motor torque after the collision; None: steady-state torque (see
        :func:`simulate_impact`).
    torque_limit_Nm : float or None, N·m
        None: ``gearbox.momentary_peak_torque_Nm``.
    criterion : {"spring", "gearbox"}
        Peak held to the limit for ``k_max`` (see :func:`max_stiffness_for_impact`); the other
        one is reported in ``details``. "gearbox" is the more conservative.
    settings : ImpactSettings or None
        Impact-simulation tolerances.

    Returns
    -------
    StiffnessWindow
        ``k_min``, ``k_max`` and the details; check ``is_empty``.
    """
    tau_imp = required_torque_Nm if impact_spring_torque_Nm is None else impact_spring_torque_Nm
    limit = gearbox.momentary_peak_torque_Nm if torque_limit_Nm is None else torque_limit_Nm
    k_min = min_stiffness_for_bandwidth(motor, gearbox, required_torque_Nm, required_bandwidth_Hz)
    k_max_by = {
        c: max_stiffness_for_impact(
            motor, gearbox, impact_speed_rad_per_s, tau_imp, motor_torque_Nm, limit, c, settings
        )
        for c in ("spring", "gearbox")
    }
    if criterion not in k_max_by:
        raise FeaError(f"criterion {criterion!r} must be 'spring' or 'gearbox'")
    k_max = k_max_by[criterion]
    i_e, b = _bandwidth_coefficients(motor, gearbox)
    bw_max = (
        float(torque_bandwidth_rad_per_s(k_max, motor, gearbox, required_torque_Nm)) / (2 * math.pi)
        if 0.0 < k_max < math.inf
        else math.nan
    )
    details = WindowDetails(
        required_torque_Nm=required_torque_Nm,
        impact_speed_rad_per_s=impact_speed_rad_per_s,
        impact_spring_torque_Nm=tau_imp,
        torque_limit_Nm=limit,
        criterion=criterion,
        k_max_spring_criterion_Nm_per_rad=k_max_by["spring"],
        k_max_gearbox_criterion_Nm_per_rad=k_max_by["gearbox"],
        required_bandwidth_Hz=required_bandwidth_Hz,
        saturation_torque_Nm=saturation_torque_Nm(motor, gearbox),
        saturation_speed_rad_per_s=saturation_speed_rad_per_s(motor, gearbox),
        torque_ratio=_torque_ratio(motor, gearbox, required_torque_Nm),
        inertia_kg_m2=i_e,
        damping_Nm_s_per_rad=b,
        bandwidth_at_k_max_Hz=bw_max,
        deflection_at_k_min_rad=spring_deflection_rad(required_torque_Nm, k_min),
        deflection_at_k_max_rad=(
            spring_deflection_rad(required_torque_Nm, k_max) if k_max > 0.0 else math.inf
        ),
    )
    return StiffnessWindow(k_min_Nm_per_rad=k_min, k_max_Nm_per_rad=k_max, details=details)


def paper_report() -> str:
    """The paper-004 numbers as reproduced here, as a text table (the docs' command prints it).

    Returns
    -------
    str
        Multi-line report; no side effects.
    """
    m, g = Motor(), Gearbox()
    d = reflect(m, g)
    tau_sat = saturation_torque_Nm(m, g)
    w_sat = saturation_speed_rad_per_s(m, g)
    i_e, b = _bandwidth_coefficients(m, g)
    k_p, tau_p = PAPER_STIFFNESS_Nm_per_rad, PAPER_MAX_TORQUE_Nm
    r_true = tau_p / tau_sat
    lines = [
        "paper 004 stiffness window, reproduced by fea.sea_window",
        f"reflected inertia I_e = {i_e:.4f} kg m^2 (motor {d.motor_inertia_kg_m2:.4f}, gearbox "
        f"{d.gearbox_inertia_kg_m2:.4f}); viscous b_e = {d.viscous_Nm_s_per_rad:.3f} N m s/rad; "
        f"Coulomb {d.coulomb_Nm:.3f} N m",
        f"tau_sat = {tau_sat:.2f} N m, omega_sat = {w_sat:.4f} rad/s, "
        f"tau_sat/omega_sat = {tau_sat / w_sat:.3f} N m s/rad, b_e + that = {b:.3f}",
        "",
        "lower bound (bandwidth, Eq. 21)",
        f"  ratio 53/395.5 = {r_true:.4f} (paper prints {PAPER_TORQUE_RATIO_PRINTED})",
    ]
    for label, ratio in (("53/395.5", r_true), ("paper 0.1416", PAPER_TORQUE_RATIO_PRINTED)):
        w_bw = torque_bandwidth_rad_per_s(k_p, m, g, ratio * tau_sat)
        lines.append(
            f"  K = 275, ratio {label}: bandwidth {w_bw:.2f} rad/s = {w_bw / (2 * math.pi):.3f} Hz"
            f" (paper {PAPER_BANDWIDTH_rad_per_s} rad/s = 5.13 Hz)"
        )
    for f_req in (1.0, 2.0, 3.0, 4.0, PAPER_BANDWIDTH_rad_per_s / (2 * math.pi)):
        k_min = min_stiffness_for_bandwidth(m, g, tau_p, f_req)
        lines.append(f"  K_min for {f_req:.3f} Hz at 53 N m: {k_min:.1f} N m/rad")
    lines += [
        "",
        "upper bound (impact, Eqs. 9-16, limit 69 N m, G_k = 1.3e4 N m/rad assumed)",
        "  K_max by peak spring torque / by peak gearbox torque; rigid frictionless estimate",
    ]
    w_knee = rpm_to_rad_per_s(KNEE_MAX_SPEED_rpm)
    cases = [
        (f"walking, knee max speed {w_knee:.3f} rad/s, 0 N m", w_knee, 0.0),
        (f"walking, {w_knee:.3f} rad/s, 10 N m", w_knee, 10.0),
        ("sit-to-stand, 1.0 rad/s, 53 N m", 1.0, tau_p),
        ("sit-to-stand, 0.5 rad/s, 53 N m", 0.5, tau_p),
        (
            f"walking as printed (Eq. 16, w/R = {w_knee / g.ratio:.4f} rad/s), 0 N m",
            w_knee / g.ratio,
            0.0,
        ),
    ]
    for label, w0, ts in cases:
        k_s = max_stiffness_for_impact(m, g, w0, ts)
        k_g = max_stiffness_for_impact(m, g, w0, ts, criterion="gearbox")
        k_rigid = (g.momentary_peak_torque_Nm - ts) ** 2 / (i_e * w0**2)
        lines.append(f"  {label}: {k_s:.1f} / {k_g:.1f} N m/rad (estimate {k_rigid:.1f})")
    for label, gk in (("rigid gearbox", math.inf), ("G_k = 5e3 N m/rad", 5e3)):
        g_alt = replace(g, stiffness_Nm_per_rad=gk)
        k_s = max_stiffness_for_impact(m, g_alt, w_knee, 0.0)
        lines.append(f"  walking, knee max speed, 0 N m, {label}: {k_s:.1f} N m/rad")
    for ts in (0.0, tau_p):
        speed = _speed_for_k_max(m, g, k_p, ts)
        lines.append(
            f"  impact speed that makes K_max = 275 with {ts:.0f} N m spring torque: "
            f"{speed:.3f} rad/s = {speed * 60 / (2 * math.pi):.2f} rpm"
        )
    window = stiffness_window(m, g, tau_p, w_knee, 4.0, impact_spring_torque_Nm=0.0)
    lines.append(
        f"  window for 53 N m, 4 Hz, walking impact at {w_knee:.3f} rad/s with 0 N m: "
        f"[{window.k_min_Nm_per_rad:.1f}, {window.k_max_Nm_per_rad:.1f}] N m/rad"
    )
    theta = spring_deflection_rad(tau_p, k_p)
    lines += [
        "",
        f"spring spec: theta_max = 53/275 = {theta:.4f} rad = {math.degrees(theta):.2f} deg "
        "(paper 0.193 rad = 11.04 deg)",
    ]
    return "\n".join(lines)


def _speed_for_k_max(
    motor: Motor, gearbox: Gearbox, stiffness_Nm_per_rad: float, spring_torque_Nm: float
) -> float:
    """Impact speed at which the peak spring torque just reaches the gearbox limit."""

    def excess(w0: float) -> float:
        r = simulate_impact(stiffness_Nm_per_rad, motor, gearbox, w0, spring_torque_Nm)
        return r.peak_spring_torque_Nm - gearbox.momentary_peak_torque_Nm

    return brentq(excess, 0.0, 50.0, xtol=1e-9)
