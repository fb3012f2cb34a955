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

Loads along the beam (rigid stops, :mod:`fea.stops`): every active contact pair of a converged
row is a point force ``f = -k g grad g`` (N) on the centreline at ``x_c = sum_j w_j x_j`` (its
shares ``f_j = -k g grad_j g`` on the pair's nodes j, weights ``w_j = f_j . f / |f|^2``: the
P2 shape functions at the contact point for a stop vertex pressing between nodes, 1 for a node
on a stop face), at arc length ``s_c = sum_j w_j s_j``. A section at s then carries, besides the
end load, every contact force beyond it::

    F(s) = F + sum_{s_c > s} f
    M(s) = M_end + (r_end - r(s)) x F + sum_{s_c > s} (x_c - r(s)) x f

exact for the penalty solution (the forces are those the solve put in equilibrium). At a section
on a contact point (a node pressed on a face) the axial force jumps; the larger |N| counts.
The moment has a kink at every load, in general between two sampling points (a stop's vertex
pressing inside an element, or a node that slid past it), so each load point is also a section
of its own for the peak (``peak_stress_MPa``): the per-point arrays and the fibres (at the nodes)
may then read a little less than the peak (cantilever-stop: 4.4995 at the node at 30 mm, the
peak at the apex 0.045 mm beyond it).
The beam has no distributed load (polyline_beam: end drive and stops only).

Sampling points are the model's (both ends and the middle of every P2 element: its nodes), so the
arc lengths are :attr:`fea.beam.BeamTables.s_samples`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from flexopt.fea.beam import BeamModel, BeamResponse
from flexopt.fea.errors import FeaError

if TYPE_CHECKING:
    from flexopt.fea.stops import BeamContact

__all__ = [
    "StaticsStress",
    "contact_point_loads",
    "start_loaded_samples",
    "start_loaded_stress",
    "node_fibres",
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


def contact_point_loads(
    model: BeamModel, contact: BeamContact, shapes_mm: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The contact forces of one row as point loads on the centreline (module docstring).

    ``shapes_mm`` (n_nodes, 2) mm: the row's node positions. Returns the arc length of each
    active pair's contact point (P,) mm, that point on the centreline (P, 2) mm and the force
    the stop puts on the beam there (P, 2) N (P = 0 without contact).
    """
    x = np.asarray(shapes_mm, dtype=float)
    s_nodes = np.empty(model.n_nodes)
    samples = np.asarray(model.tables.s_samples, dtype=float)  # (E, 3): node 2 e + j
    for j in range(3):
        s_nodes[2 * np.arange(samples.shape[0]) + j] = samples[:, j]
    s_c, x_c, f_c = [], [], []
    for p in contact.pairs(x):
        shares = -p.k * p.gap * np.asarray(p.grad, dtype=float).reshape(-1, 2)  # (m, 2) N
        f = shares.sum(axis=0)
        f2 = float(f @ f)
        if f2 == 0.0:
            continue
        w = shares @ f / f2  # (m,): sum to 1; the P2 shape functions at a vertex's point
        s_c.append(float(w @ s_nodes[p.nodes]))
        x_c.append(w @ x[p.nodes])
        f_c.append(f)
    if not s_c:
        return np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2))
    return np.array(s_c), np.array(x_c), np.array(f_c)


def statics_stress(
    model: BeamModel,
    response: BeamResponse,
    direction: np.ndarray,
    contact: BeamContact | None = None,
) -> StaticsStress:
    """The stress from statics (module docstring) of every row of ``response``, traced by
    ``model`` with its start clamped or pinned, loaded at the driven end along ``direction``
    (2,) (the :class:`fea.beam.EndDrive`'s) and, with ``contact`` (the
    :class:`fea.stops.BeamContact` the response was solved with, its final penalty), by the
    stops' forces along the beam.

    Raises
    ------
    FeaError
        When the response carries no rotations (a stand-in response) or has contact but no
        ``contact`` is given (stops put forces along the beam that statics must include).
    """
    if response.rotations_rad is None:
        raise FeaError("statics_stress needs the response's rotations_rad (a solved response)")
    if response.contact is not None and contact is None:
        raise FeaError("statics_stress: a response with contact needs the stops' BeamContact")
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
    # the moment's kinks sit at the point loads, between the sampling points in general: each
    # load point is a section of its own (R,) MPa and mm (NaN without loads)
    load_peak = np.full(shapes.shape[0], np.nan)
    load_s = np.full(shapes.shape[0], np.nan)
    if contact is not None:
        s_pts = np.asarray(model.tables.s_samples, dtype=float).ravel()  # (S,)
        m_end = np.asarray(response.moment_Nmm, dtype=float)
        for k in np.flatnonzero(np.asarray(response.converged, dtype=bool)):
            s_c, x_c, f_c = contact_point_loads(model, contact, shapes[k])
            if s_c.size == 0:
                continue
            load_peak[k], load_s[k] = _load_point_peak(
                s_c, x_c, f_c, shapes[k, -1], F[k], m_end[k], s_pts, theta[k], thickness, b
            )
            beyond = s_c[None, :] > s_pts[:, None]  # (S, P)
            at = s_c[None, :] >= s_pts[:, None]  # a load on the section: N jumps there
            lever = x_c[None, :, :] - shapes[k, node][:, None, :]  # (S, P, 2)
            torque = lever[..., 0] * f_c[None, :, 1] - lever[..., 1] * f_c[None, :, 0]
            moment[k] += np.sum(np.where(beyond, torque, 0.0), axis=1)
            along = (
                f_c[None, :, 0] * np.cos(theta[k])[:, None]
                + f_c[None, :, 1] * np.sin(theta[k])[:, None]
            )  # (S, P) N
            n_out = axial_force[k] + np.sum(np.where(beyond, along, 0.0), axis=1)
            n_in = axial_force[k] + np.sum(np.where(at, along, 0.0), axis=1)
            axial_force[k] = np.where(np.abs(n_in) > np.abs(n_out), n_in, n_out)
    axial = axial_force / (b * thickness)[None, :]
    bending = moment / (b * thickness**2 / 6.0)[None, :]
    sigma = np.abs(axial) + np.abs(bending)
    s = np.asarray(model.tables.s_samples, dtype=float).ravel()
    ok = np.asarray(response.converged, dtype=bool) & np.all(np.isfinite(sigma), axis=1)
    k = np.argmax(np.where(np.isfinite(sigma), sigma, -np.inf), axis=1)
    rows = np.arange(sigma.shape[0])
    peak = np.where(ok, sigma[rows, k], np.nan)
    where = np.where(ok, s[k], np.nan)
    higher = ok & (load_peak > peak)
    peak = np.where(higher, load_peak, peak)
    where = np.where(higher, load_s, where)
    return StaticsStress(axial, bending, peak, where, s)


def _load_point_peak(s_c, x_c, f_c, r_end, F, m_end, s_pts, theta, thickness, b):
    """The largest |N|/A + |M|/Z (MPa) over the point loads' own sections and its arc length
    (mm): loads at ``s_c`` (P,) mm, ``x_c`` (P, 2) mm, ``f_c`` (P, 2) N; the end load ``F``
    (2,) N and ``m_end`` N mm at ``r_end`` (2,) mm; the section angle and thickness
    interpolated from the sampling points ``s_pts`` (S,) mm, ``theta`` (S,) rad and
    ``thickness`` (S,) mm (exact for a linear taper), width ``b`` mm."""
    best, where = -np.inf, np.nan
    for p in range(s_c.size):
        beyond = s_c > s_c[p]
        lever = x_c[beyond] - x_c[p]
        arm = r_end - x_c[p]
        moment = (
            m_end
            + arm[0] * F[1]
            - arm[1] * F[0]
            + np.sum(lever[:, 0] * f_c[beyond, 1] - lever[:, 1] * f_c[beyond, 0])
        )
        th = np.interp(s_c[p], s_pts, theta)
        t = np.interp(s_c[p], s_pts, thickness)
        tangent = np.array([np.cos(th), np.sin(th)])
        n_out = (F + f_c[beyond].sum(axis=0)) @ tangent
        n_in = n_out + f_c[p] @ tangent
        sigma = max(abs(n_out), abs(n_in)) / (b * t) + abs(moment) / (b * t**2 / 6.0)
        if sigma > best:
            best, where = sigma, float(s_c[p])
    return best, where


def with_statics_stress(
    model: BeamModel,
    response: BeamResponse,
    direction: np.ndarray,
    contact: BeamContact | None = None,
) -> BeamResponse:
    """``response`` with its ``peak_stress_MPa`` and ``peak_stress_s_mm`` (R,) taken from
    statics (:func:`statics_stress`, with the stops' forces of ``contact``) on every converged
    row; the other rows keep the solver's. A response without rotations (a stand-in), or with
    contact but no ``contact`` given, comes back unchanged."""
    if response.rotations_rad is None or (response.contact is not None and contact is None):
        return response
    st = statics_stress(model, response, direction, contact)
    ok = np.isfinite(st.peak_stress_MPa)
    return replace(
        response,
        peak_stress_MPa=np.where(ok, st.peak_stress_MPa, response.peak_stress_MPa),
        peak_stress_s_mm=np.where(ok, st.peak_stress_s_mm, response.peak_stress_s_mm),
    )


def statics_fibres(
    field: dict | None,
    model: BeamModel,
    response: BeamResponse,
    direction: np.ndarray,
    contact: BeamContact | None = None,
) -> dict | None:
    """A :func:`fea.beam_fields.beam_field` dict with its fibre stresses from statics: per node
    and row (R, n_nodes) MPa, ``fibre_left_MPa`` = N/A - M/Z (the fibre at +t/2 along the
    normal), ``fibre_right_MPa`` = N/A + M/Z, ``equivalent_MPa`` = |N/A| + |M/Z|. Where two
    elements meet at a kink their section angles (so N) differ and the larger equivalent stress
    wins, so that each row's largest equivalent stress is the row's peak of
    :func:`with_statics_stress` (``contact``: as there). None, or a field of a response without
    rotations or with contact but no ``contact`` given, comes back unchanged."""
    if field is None or response.rotations_rad is None:
        return field
    if response.contact is not None and contact is None:
        return field
    st = statics_stress(model, response, direction, contact)
    out = dict(field)
    out.update(node_fibres(model, st.axial_MPa, st.bending_MPa, response.converged))
    return out


def node_fibres(
    model: BeamModel, axial_MPa: np.ndarray, bending_MPa: np.ndarray, converged: np.ndarray
) -> dict[str, np.ndarray]:
    """The sampled section stresses of ``model`` (its sampling points: both ends and the middle
    of every P2 element, which are its nodes) at the nodes: ``axial_MPa`` N/A and
    ``bending_MPa`` M/Z (R, S) MPa, signed as :func:`statics_stress` gives them (the beam's
    end form), ``converged`` (R,) bool. Returns ``fibre_left_MPa`` = N/A - M/Z,
    ``fibre_right_MPa`` = N/A + M/Z and ``equivalent_MPa`` (R, n_nodes) MPa; where two elements
    meet the larger equivalent stress wins (so each row's largest node value is the row's
    largest sampled |N/A| + |M/Z|); NaN on rows that did not converge."""
    n_rows = np.asarray(axial_MPa).shape[0]
    n_el = model.n_elements
    n_nodes = 2 * n_el + 1
    lo = (axial_MPa - bending_MPa).reshape(n_rows, n_el, 3)
    hi = (axial_MPa + bending_MPa).reshape(n_rows, n_el, 3)
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
    bad = ~np.asarray(converged, dtype=bool)
    left[bad] = right[bad] = np.nan
    return {
        "fibre_left_MPa": left,
        "fibre_right_MPa": right,
        "equivalent_MPa": np.maximum(np.abs(left), np.abs(right)),
    }


def start_loaded_stress(
    model: BeamModel,
    shapes_mm: np.ndarray,
    rotations_rad: np.ndarray,
    start_force: np.ndarray,
    converged: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The peak stress from statics of a beam loaded only at its two ends, from the load at its
    start (a threshold spring's arm: the hub drives the start, the pad clamps the end).

    The part [0, s] carries the start load, so the section at s has ``|M(s)| = |M0 + (r0 -
    r(s)) x F0|`` and ``|N(s)| = |F0 . (cos theta, sin theta)|`` (the signs of the module
    docstring's end form flip; the stress |N|/A + |M|/Z does not).

    Parameters
    ----------
    model : BeamModel — the beam as solved (its sampling points: both ends and the middle of
        every P2 element).
    shapes_mm : (R, n_nodes, 2) float, mm — deformed node positions per row.
    rotations_rad : (R, n_nodes) float, rad — the nodes' section rotation per row.
    start_force : (R, 3) float — (Fx N, Fy N, M N·mm) applied to the start node per row.
    converged : (R,) bool.

    Returns
    -------
    peak_stress_MPa : (R,) float, MPa — max over the points of |N|/A + |M|/Z (NaN where not
        converged).
    peak_stress_s_mm : (R,) float, mm — its arc length (NaN likewise).
    """
    axial, bending = start_loaded_samples(model, shapes_mm, rotations_rad, start_force)
    sigma = np.abs(axial) + np.abs(bending)
    s = np.asarray(model.tables.s_samples, dtype=float).ravel()
    ok = np.asarray(converged, dtype=bool) & np.all(np.isfinite(sigma), axis=1)
    k = np.argmax(np.where(np.isfinite(sigma), sigma, -np.inf), axis=1)
    rows = np.arange(sigma.shape[0])
    return np.where(ok, sigma[rows, k], np.nan), np.where(ok, s[k], np.nan)


def start_loaded_samples(
    model: BeamModel, shapes_mm: np.ndarray, rotations_rad: np.ndarray, start_force: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`start_loaded_stress`'s section stresses at every sampling point, signed as
    :func:`statics_stress` signs them (the end form: the part beyond the section, loaded by
    minus the start load): ``axial_MPa`` N/A and ``bending_MPa`` M/Z, both (R, S) MPa. The
    start form ``M0 + (r0 - r(s)) x F0`` and ``F0 . (cos theta, sin theta)`` is the force the
    part [0, s] puts on the section, so the end form is its negative; the stress
    |N|/A + |M|/Z is the same either way. Arguments as :func:`start_loaded_stress`."""
    node, theta0, thickness = sample_geometry(model)
    b = model.profile.width_mm
    shapes = np.asarray(shapes_mm, dtype=float)
    phi = np.asarray(rotations_rad, dtype=float)
    load = np.asarray(start_force, dtype=float)
    F = load[:, :2]
    arm = shapes[:, :1, :] - shapes[:, node, :]  # (R, S, 2): r0 - r(s)
    moment = load[:, 2:3] + arm[..., 0] * F[:, 1:2] - arm[..., 1] * F[:, 0:1]
    theta = theta0[None, :] + phi[:, node]
    axial_force = F[:, 0:1] * np.cos(theta) + F[:, 1:2] * np.sin(theta)
    return (
        -axial_force / (b * thickness)[None, :],
        -moment / (b * thickness**2 / 6.0)[None, :],
    )
