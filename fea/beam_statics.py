"""Section forces of an end-loaded beam from statics, and the stress they give.

A beam loaded only at its ends (no distributed load, no stops, no contact) carries at every
section the same force, the one applied at the driven end, and a moment that follows from it and
the deformed centreline exactly::

    F     = force_N d + transverse_force_N n      (d the drive's direction, n: d turned +90 deg)
    M(s)  = M_end + (r_end - r(s)) x F             (counter-clockwise positive, N mm)
    N(s)  = F . (cos theta, sin theta)             (axial force along the section's normal)
    sigma = |N| / (b t) + |M| / (b t^2 / 6)        (MPa)

with ``r`` the deformed positions and ``theta = theta0 + phi`` the section angle of the solved
state. Why: the element's own bending moment ``EI phi'`` is a linear curvature times a stiffness
that varies as t^3, and on a strongly tapered segment (the constant-force beam's clamp flexure,
0.81 -> 1.21 mm over 7.7 mm) a 60-element mesh misses the moment at the clamp by 4 % and swings
by 18 % between neighbouring elements (docs/constant_force.md, "Stress at the clamp"). The
reactions and the positions converge far faster (the force to 4 digits at 60 elements), so the
moment from statics is converged where the curvature is not: the hybrid's design reads 42.33 /
42.32 / 42.32 MPa bending at the clamp on 60 / 120 / 480 elements from statics against 40.64 /
41.99 / 42.30 from the curvature.

Sampling points are the model's (both ends and the middle of every P2 element: its nodes), so the
arc lengths are :attr:`fea.beam.BeamTables.s_samples`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from flexopt.fea.beam import BeamModel, BeamResponse
from flexopt.fea.errors import FeaError

__all__ = [
    "StaticsStress",
    "end_force",
    "sample_geometry",
    "statics_fibres",
    "statics_stress",
    "with_statics_stress",
]


@dataclass(frozen=True)
class StaticsStress:
    """Stress from statics per row (R rows) and sampling point (S = 3 E points).

    Attributes
    ----------
    axial_MPa : (R, S) float, MPa — N / (b t), signed (tension positive).
    bending_MPa : (R, S) float, MPa — M / (b t^2 / 6), signed (counter-clockwise M positive).
    peak_stress_MPa : (R,) float, MPa — max over the points of |axial| + |bending| (NaN on a row
        that did not converge).
    peak_stress_s_mm : (R,) float, mm — the arc length where it occurs (NaN likewise).
    s_mm : (S,) float, mm — arc length of the sampling points.
    """

    axial_MPa: np.ndarray
    bending_MPa: np.ndarray
    peak_stress_MPa: np.ndarray
    peak_stress_s_mm: np.ndarray
    s_mm: np.ndarray


def sample_geometry(model: BeamModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The model's sampling points as node indices (S,) int (sample j of element e is node 2 e +
    j), their reference section angle (S,) rad (per element: at a kink the two elements meeting
    there keep their own) and thickness (S,) mm."""
    t = model.tables
    n_el = t.theta0.shape[0]
    node = (2 * np.arange(n_el)[:, None] + np.arange(3)[None, :]).ravel()
    # theta0 is linear in s along an element (straight or arc): the Gauss-to-sample
    # extrapolation is exact for it
    theta0 = (t.theta0 @ t.gauss_to_samples).ravel()
    thickness = (6.0 * t.section_modulus_samples / model.profile.width_mm).ravel() ** 0.5
    return node, theta0, thickness


def end_force(response: BeamResponse, direction: np.ndarray) -> np.ndarray:
    """(R, 2) N: the force applied at the driven end in x, y, from its components along the
    drive ``direction`` (2,) and its normal (``direction`` turned +90 degrees)."""
    d = np.asarray(direction, dtype=float)
    d = d / np.hypot(*d)
    n = np.array([-d[1], d[0]])
    f = np.asarray(response.force_N, dtype=float)
    ft = np.asarray(response.transverse_force_N, dtype=float)
    return f[:, None] * d[None, :] + ft[:, None] * n[None, :]


def statics_stress(
    model: BeamModel, response: BeamResponse, direction: np.ndarray
) -> StaticsStress:
    """The stress from statics (module docstring) of every row of ``response``, traced by
    ``model`` with its start clamped or pinned and loads only at the driven end along
    ``direction`` (2,) (the :class:`fea.beam.EndDrive`'s).

    Raises
    ------
    FeaError
        When the response carries no rotations (a stand-in response) or has contact (stops put
        forces along the beam, which statics from the end would leave out).
    """
    if response.rotations_rad is None:
        raise FeaError("statics_stress needs the response's rotations_rad (a solved response)")
    if response.contact is not None:
        raise FeaError("statics_stress: a response with contact has loads along the beam")
    node, theta0, thickness = sample_geometry(model)
    b = model.profile.width_mm
    shapes = np.asarray(response.shapes_mm, dtype=float)  # (R, n_nodes, 2)
    phi = np.asarray(response.rotations_rad, dtype=float)  # (R, n_nodes)
    F = end_force(response, direction)  # (R, 2)
    arm = shapes[:, -1:, :] - shapes[:, node, :]  # (R, S, 2): r_end - r(s)
    moment = (
        np.asarray(response.moment_Nmm, dtype=float)[:, None]
        + arm[..., 0] * F[:, 1:2]
        - arm[..., 1] * F[:, 0:1]
    )
    theta = theta0[None, :] + phi[:, node]
    axial_force = F[:, 0:1] * np.cos(theta) + F[:, 1:2] * np.sin(theta)
    axial = axial_force / (b * thickness)[None, :]
    bending = moment / (b * thickness**2 / 6.0)[None, :]
    sigma = np.abs(axial) + np.abs(bending)
    s = np.asarray(model.tables.s_samples, dtype=float).ravel()
    ok = np.asarray(response.converged, dtype=bool) & np.all(np.isfinite(sigma), axis=1)
    k = np.argmax(np.where(np.isfinite(sigma), sigma, -np.inf), axis=1)
    rows = np.arange(sigma.shape[0])
    peak = np.where(ok, sigma[rows, k], np.nan)
    where = np.where(ok, s[k], np.nan)
    return StaticsStress(axial, bending, peak, where, s)


def with_statics_stress(
    model: BeamModel, response: BeamResponse, direction: np.ndarray
) -> BeamResponse:
    """``response`` with its ``peak_stress_MPa`` and ``peak_stress_s_mm`` (R,) taken from
    statics (:func:`statics_stress`) on every converged row; the other rows keep the solver's.
    A response without rotations (a stand-in) or with contact comes back unchanged."""
    if response.rotations_rad is None or response.contact is not None:
        return response
    st = statics_stress(model, response, direction)
    ok = np.isfinite(st.peak_stress_MPa)
    return replace(
        response,
        peak_stress_MPa=np.where(ok, st.peak_stress_MPa, response.peak_stress_MPa),
        peak_stress_s_mm=np.where(ok, st.peak_stress_s_mm, response.peak_stress_s_mm),
    )


def statics_fibres(
    field: dict | None, model: BeamModel, response: BeamResponse, direction: np.ndarray
) -> dict | None:
    """A :func:`fea.beam_fields.beam_field` dict with its fibre stresses from statics: per node
    and row (R, n_nodes) MPa, ``fibre_left_MPa`` = N/A - M/Z (the fibre at +t/2 along the
    normal), ``fibre_right_MPa`` = N/A + M/Z, ``equivalent_MPa`` = |N/A| + |M/Z|. Where two
    elements meet at a kink their section angles (so N) differ and the larger equivalent stress
    wins, so that each row's largest equivalent stress is the row's peak of
    :func:`with_statics_stress`. None, or a field of a response without rotations or with
    contact, comes back unchanged."""
    if field is None or response.rotations_rad is None or response.contact is not None:
        return field
    st = statics_stress(model, response, direction)
    n_rows, n_nodes = np.asarray(response.rotations_rad).shape
    n_el = model.n_elements
    lo = (st.axial_MPa - st.bending_MPa).reshape(n_rows, n_el, 3)
    hi = (st.axial_MPa + st.bending_MPa).reshape(n_rows, n_el, 3)
    eq = np.abs(lo).clip(min=np.abs(hi))  # |N/A| + |M/Z| = max(|lo|, |hi|)
    left = np.empty((n_rows, n_nodes))
    right = np.empty((n_rows, n_nodes))
    best = np.full((n_rows, n_nodes), -np.inf)
    for j in range(3):  # sample j of element e is node 2 e + j
        idx = 2 * np.arange(n_el) + j
        take = eq[:, :, j] > best[:, idx]
        left[:, idx] = np.where(take, lo[:, :, j], left[:, idx])
        right[:, idx] = np.where(take, hi[:, :, j], right[:, idx])
        best[:, idx] = np.where(take, eq[:, :, j], best[:, idx])
    bad = ~np.asarray(response.converged, dtype=bool)
    left[bad] = right[bad] = np.nan
    out = dict(field)
    out["fibre_left_MPa"] = left
    out["fibre_right_MPa"] = right
    out["equivalent_MPa"] = np.maximum(np.abs(left), np.abs(right))
    return out
