"""Beams tied together and to moving supports by linear constraints (Lagrange multipliers).

:class:`fea.beam.BeamModel` drives the end of one beam along a fixed direction. Flexure pivots and
the leaf-spring joint need more: an end section turned by a prescribed angle while its position
is free (a pure moment), two leaves joined to one rigid block (a cross-axis pivot), the tip of a
leaf kept on a line that turns with a joint arm. All of these are *linear* constraints on the
beams' degrees of freedom whose coefficients may change along the load path::

    C(p) z = d(p)          z = [q_1, ..., q_B, e]   (every beam's DOFs, then extra unknowns)

with ``p`` a path parameter (a joint angle, a block rotation). Extra unknowns ``e`` are DOFs of no
beam, such as the translation of a rigid block, which appear only in constraints (and in applied
loads). Loads may follow the deformation (a force that stays normal to a beam's end), with their
derivative in the tangent. Equilibrium at each ``p`` is found by Newton's method on the KKT system::

    r(z) - f(p, z) - C^T lam = 0     (internal force = applied load + constraint forces)
    C(p) z - d(p)            = 0

    [ K - df/dz   -C^T ] [dz  ]     [ r - f - C^T lam ]
    [ C            0   ] [dlam] = - [ C z - d         ]

so ``lam`` are the constraint forces (N, or N·mm for a rotation row) acting on the beams along the
constraint rows. Starting Newton from the last converged state at a new ``p``, the first
iteration is the linearised predictor: it meets the (linear) constraints exactly, so a prescribed
motion is never jumped and then iterated.

Everything about one beam (its internal force and tangent, stress recovery) comes from
:class:`~fea.beam.BeamModel`; this module only adds the constraints and the stepping. It uses the
model's ``_assemble`` and ``_stress`` (internal to fea.beam, so a change there shows up in
``tests/geometry/test_flexures.py``). The systems are small (a few hundred unknowns).

Two implementations of the same Newton (``ConstrainedSettings.kernel``; "auto" follows the beam
kernel's switch, env FLEXOPT_BEAM_KERNEL): the compiled one (numba, fea/_constrained_kernels.py,
the default) assembles with the beam kernel, solves the KKT system by bordering the beams' band
(banded LU + a small dense Schur complement) and runs the Newton loop as machine code; the
reference (numpy) builds scipy sparse matrices and solves with SuperLU. Same decisions, answers
equal to round-off (tests/fea/test_constrained_kernels.py); where the bordering cannot take a
system (a beam no local constraint holds) the compiled path runs the reference for that sub-step.

Rigid stops (``stops=``, issue 25): frictionless penalty contact of every beam with rigid
outlines fixed to the ground, the pair search, penalty energy and exact Hessian of
:mod:`fea.stops` (one :class:`~fea.stops.BeamContact` per beam) added to every assembly, so the
contact forces enter ``r`` and their tangent ``K`` above; ``C`` is unchanged (the stops are not
constraints). The reference loop runs (the contact terms are Python), and a correction that
changes the set of acting pairs is halved while it raises the residual (as in fea.mechanism).
A path that penetrates a stop deeper than ``ContactSettings.penetration_tol`` x the thinnest
section is traced again with a 10x stiffer penalty (at most ``max_raises`` times);
``ConstrainedResponse.contact`` holds the forces, gaps and the path parameter at which each
stop closes. Without stops nothing of this runs (same code, same numbers).

Failure to converge is data (``converged`` flags, ``ok``, ``message``), never raised.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import cache
from types import ModuleType
from typing import Literal

import numpy as np
import scipy.sparse as sp
from flexopt.fea.beam import BeamModel, resolve_kernel
from flexopt.fea.errors import FeaError
from flexopt.fea.stops import (
    BeamContact,
    ContactResponse,
    ContactSettings,
    RigidStop,
    contact_over_beams,
    overlaps,
)
from scipy.linalg.lapack import dsytrf
from scipy.sparse.linalg import splu
from threadpoolctl import threadpool_limits

__all__ = [
    "ConstrainedSettings",
    "ConstrainedResponse",
    "ConstraintFunction",
    "LoadFunction",
    "ConstrainedBeams",
    "kkt_negative_count",
]

ConstraintFunction = Callable[[float], tuple[np.ndarray, np.ndarray]]
"""``p -> (C, d)``: constraint matrix (m, N) and right-hand side (m,) at path parameter ``p``."""

LoadFunction = Callable[[float, np.ndarray], tuple[np.ndarray, "sp.spmatrix | None"]]
"""``(p, z) -> (f, dfdz)``: applied loads (N,) and their derivative (N, N) or None."""

#: half-bandwidth of BeamModel's band storage (node-by-node numbering, 3 nodes x 3 fields)
BAND = 8
#: band storage of the compiled kernels: rows per column and the diagonal's row (fea/_beam_kernels)
LDAB = 3 * BAND + 1
_KV = 2 * BAND

log = logging.getLogger(__name__)


@cache
def _kernels() -> ModuleType | None:
    """fea._constrained_kernels, or None when numba cannot be imported (the reference runs)."""
    try:
        from flexopt.fea import _constrained_kernels
    except Exception as exc:  # ImportError, or a numba that fails on this platform's LLVM
        log.debug("numba constrained kernel unavailable (%s: %s)", type(exc).__name__, exc)
        return None
    return _constrained_kernels


def resolve_constrained_kernel(setting: str) -> str:
    """The path that runs for ``kernel`` = ``setting``: "numba" or "numpy" (the reference)."""
    kernel = resolve_kernel(setting)
    return "numba" if kernel == "numba" and _kernels() is not None else "numpy"


#: texts of the compiled Newton's status codes (fea/_constrained_kernels.py), as the reference's
_REASONS = {
    1: "singular system (a mechanism: add a constraint)",
    2: "the correction became NaN or inf",
    3: "the internal force became NaN or inf",
}


@dataclass(frozen=True)
class ConstrainedSettings:
    """Tolerances of the constrained solver, each with its reason.

    Attributes
    ----------
    rtol : equilibrium when the residual norm is below rtol x the force scale (constraint forces
        and applied loads); 1e-9 leaves the force error to the mesh, as in fea.beam.
    ctol : constraints met when |C z - d| is below ctol x the length scale (mm): the constraints
        are linear, so after one Newton iteration they hold to round-off; 1e-10 only guards it.
    max_iterations : Newton iterations per sub-step before the sub-step is cut back; the
        linearised predictor plus quadratic convergence needs 3-6.
    min_substep : smallest sub-step as a fraction of a row's step before giving up.
    fast_iterations : a sub-step converged in at most this many iterations doubles the next one.
    max_rotation_step : largest section rotation (rad) one Newton correction may apply (larger ones
        are scaled down), for the reason given in fea.beam: far from equilibrium a slender beam's
        full Newton step can turn sections by radians.
    dtol : a Newton correction below dtol x the length scale is round-off (converged).
    kernel : "auto", "numba" or "numpy" — the compiled Newton (fea/_constrained_kernels.py) or
        the scipy reference; same physics, answers equal to round-off. "auto" follows
        FLEXOPT_BEAM_KERNEL (numba | numpy; default numba) like ``BeamSettings.kernel``. The
        compiled path needs every beam on the compiled beam kernel, else the reference runs;
        ``ConstrainedBeams.kernel`` says which one does.
    """

    rtol: float = 1e-9
    ctol: float = 1e-10
    max_iterations: int = 25
    min_substep: float = 1e-4
    fast_iterations: int = 5
    max_rotation_step: float = 0.5
    dtol: float = 1e-13
    kernel: Literal["auto", "numba", "numpy"] = "auto"


@dataclass(frozen=True)
class ConstrainedResponse:
    """One row per requested path parameter (row 0 is the start state).

    Attributes
    ----------
    params : (rows,) float — the path parameter of each row.
    states : (rows, N) float — z = [q_1, ..., q_B, e] (beam DOFs node by node (u, v, phi) in mm,
        mm, rad; extra unknowns in their own units). NaN where a row did not converge.
    internal : (rows, N) float — internal force r(z) (N, N·mm); at a constrained DOF it is the
        force the constraints apply there (reaction).
    multipliers : (rows, m) float — constraint forces lam (N or N·mm) along the constraint rows.
    peak_stress_MPa : (rows, B) float — per beam, max |N|/A + |M| c / I.
    peak_stress_s_mm : (rows, B) float — where (arc length of that beam).
    shapes_mm : tuple of (rows, n_nodes_i, 2) float — deformed node positions of each beam.
    iterations : (rows,) int — Newton iterations spent reaching each row.
    converged : (rows,) bool.
    stable : (rows,) bool — the converged state is a stable equilibrium with the constraints in
        place: the tangent is positive definite on the null space of C (KKT inertia, see
        :func:`kkt_negative_count`); False past a bifurcation or limit point (a buckled or
        snapping design is flagged, never reported as a plain result). False where not converged.
    ok : bool — every row converged.
    message : str — why not, when not ok.
    offsets : (B + 1,) int — beam i owns z[offsets[i]:offsets[i + 1]]; extra unknowns follow.
    contact : fea.stops.ContactResponse, or None — with stops: per row and stop the resultant
        force on the beams (N), the smallest gap (mm), in contact, the contact point (mm) and
        the path parameter at which each gap closes (``closing_value``, in p's unit);
        ``extra["force_by_beam_N"]`` each beam's share, ``extra["penalty_factor"]`` and
        ``extra["raises"]`` the penalty used. The stops' forces are in ``internal`` at the
        nodes they push on (a reaction read at such a node includes them). None without stops.
    """

    params: np.ndarray
    states: np.ndarray
    internal: np.ndarray
    multipliers: np.ndarray
    peak_stress_MPa: np.ndarray
    peak_stress_s_mm: np.ndarray
    shapes_mm: tuple[np.ndarray, ...]
    iterations: np.ndarray
    converged: np.ndarray
    ok: bool
    message: str = ""
    offsets: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=int))
    stable: np.ndarray | None = None
    contact: ContactResponse | None = None

    @property
    def unstable(self) -> bool:
        """Some converged row is not a stable equilibrium (see ``stable``)."""
        return self.stable is not None and bool((self.converged & ~self.stable).any())

    def beam_state(self, i: int) -> np.ndarray:
        """(rows, n_dofs_i) DOFs of beam ``i``."""
        return self.states[:, self.offsets[i] : self.offsets[i + 1]]

    def beam_internal(self, i: int) -> np.ndarray:
        """(rows, n_dofs_i) internal force of beam ``i``."""
        return self.internal[:, self.offsets[i] : self.offsets[i + 1]]

    def end(self, i: int) -> np.ndarray:
        """(rows, 3) end DOFs (u mm, v mm, phi rad) of beam ``i`` (its last node)."""
        return self.beam_state(i)[:, -3:]

    def end_force(self, i: int) -> np.ndarray:
        """(rows, 3) force (Fx N, Fy N, M N·mm) applied to the end node of beam ``i``."""
        return self.beam_internal(i)[:, -3:]

    def start_force(self, i: int) -> np.ndarray:
        """(rows, 3) force (Fx N, Fy N, M N·mm) applied to the start node of beam ``i``."""
        return self.beam_internal(i)[:, :3]

    @property
    def extra(self) -> np.ndarray:
        """(rows, n_extra) the extra unknowns."""
        return self.states[:, self.offsets[-1] :]


class ConstrainedBeams:
    """Several :class:`~fea.beam.BeamModel` s, extra unknowns and path-dependent linear constraints.

    The beams' own ``start`` supports are ignored: every support is a constraint (see
    :meth:`clamp_start`), so that a beam may also start on a moving block.

    Parameters
    ----------
    beams : sequence of BeamModel
        Meshed beams (their settings set the mesh; the tolerances here are this solver's).
    n_extra : int
        Extra unknowns beyond the beams' DOFs.
    constraints : callable p -> (C (m, N), d (m,))
        The constraints at path parameter p; m must not change with p.
    loads : callable (p, z) -> (f, dfdz), optional
        Applied loads on z at p (N or N·mm), ``f`` (N,); ``dfdz`` (N, N) sparse or None is their
        derivative with respect to z, non-zero for loads that follow the deformation (a
        follower force). Default none.
    settings : ConstrainedSettings
    stops : sequence of fea.stops.RigidStop, optional
        Rigid outlines fixed to the ground that every beam meets (frictionless penalty contact,
        see the module). Default none: the solver without contact, exactly.
    contact : fea.stops.ContactSettings, optional
        The penalty of the stops (default ``ContactSettings()``: factor 1e3 on each element's
        own ``EI / h^3``).

    Raises
    ------
    FeaError
        When the constraint function returns arrays of the wrong shape; when a stop overlaps an
        undeformed beam deeper than the penetration tolerance (the stop and the beam named).
    """

    def __init__(
        self,
        beams: Sequence[BeamModel],
        n_extra: int,
        constraints: ConstraintFunction,
        loads: LoadFunction | None = None,
        settings: ConstrainedSettings = ConstrainedSettings(),
        stops: Sequence[RigidStop] = (),
        contact: ContactSettings | None = None,
    ) -> None:
        if not beams:
            raise FeaError("ConstrainedBeams needs at least one beam")
        if n_extra < 0:
            raise FeaError(f"n_extra = {n_extra} must be >= 0")
        self.beams = tuple(beams)
        self.offsets = np.concatenate([[0], np.cumsum([b.n_dofs for b in self.beams])])
        self.n_extra = int(n_extra)
        self.n = int(self.offsets[-1]) + self.n_extra
        self.constraints = constraints
        self.loads = loads
        self.settings = settings
        self._frame = np.eye(2)  # end-node translations stay physical (x, y)
        self._rot = np.concatenate(
            [np.arange(self.offsets[i] + 2, self.offsets[i + 1], 3) for i in range(len(beams))]
        )
        self._length = max(max(b.profile.length_mm for b in self.beams), 1.0)
        self._force_floor = max(b._force_floor for b in self.beams)
        # Band -> sparse (row, col) of each beam's tangent (rows kl.. of LAPACK gbsv storage).
        rows, cols, self._band_src = [], [], []
        for i, beam in enumerate(self.beams):
            r_i, c_i, src = band_entries(beam.n_dofs)
            rows.append(r_i + self.offsets[i])
            cols.append(c_i + self.offsets[i])
            self._band_src.append(src)
        self._k_rows = np.concatenate(rows)
        self._k_cols = np.concatenate(cols)
        #: "numba" (compiled, fea/_constrained_kernels.py) or "numpy" (the reference)
        self.kernel = resolve_constrained_kernel(settings.kernel)
        if any(b.kernel != "numba" for b in self.beams):
            self.kernel = "numpy"
        self.stops = tuple(stops)
        self.contact_settings = contact if contact is not None else ContactSettings()
        #: the contact terms of each beam against the stops (None without stops)
        self.contacts: list[BeamContact] | None = None
        if self.stops:
            self.kernel = "numpy"  # the contact terms are Python: the reference loop runs
            self.contacts = self._contacts(self.contact_settings)
            for i, c in enumerate(self.contacts):
                for j, depth in overlaps(c):
                    raise FeaError(
                        f"stop {c.names[j]!r} overlaps the undeformed beam {i} by {depth:.4g} "
                        "mm; move it clear (the gap is measured from the beam's surface, t/2 "
                        "from the centreline)"
                    )
        if self.kernel == "numba":
            self._setup_compiled()

    def _setup_compiled(self) -> None:
        """The beams' kernel tables concatenated along the elements, and the index arrays."""
        geos = [b._geo for b in self.beams]
        self._geo = tuple(
            geos[0][k] if k == 1 else np.ascontiguousarray(np.concatenate([g[k] for g in geos]))
            for k in range(len(geos[0]))
        )
        self._eoff = np.concatenate([[0], np.cumsum([b.n_elements for b in self.beams])]).astype(
            np.int64
        )
        self._offsets64 = self.offsets.astype(np.int64)
        self._rot64 = self._rot.astype(np.int64)
        self._n_beam = int(self.offsets[-1])
        st = self.settings
        self._fpar = np.array(
            [st.rtol, st.ctol, st.dtol, st.max_rotation_step, self._length, self._force_floor]
        )

    def _contacts(self, settings: ContactSettings) -> list[BeamContact]:
        return [BeamContact(b, self.stops, settings) for b in self.beams]

    def _active(self) -> tuple:
        """The contact pairs acting in the last assembly, per beam (() without stops)."""
        return () if self.contacts is None else tuple(c.active for c in self.contacts)

    # ---- helpers for building constraints --------------------------------------------------

    def dof(self, beam: int, node: int, field: int) -> int:
        """Global index of ``field`` (0 = u, 1 = v, 2 = phi) of ``node`` (negative from the end)
        of beam ``beam``."""
        n_nodes = self.beams[beam].n_nodes
        node = node % n_nodes
        return int(self.offsets[beam] + 3 * node + field)

    def extra_dof(self, k: int) -> int:
        """Global index of extra unknown ``k``."""
        if not 0 <= k < self.n_extra:
            raise FeaError(f"extra unknown {k} does not exist (n_extra = {self.n_extra})")
        return int(self.offsets[-1] + k)

    def rows(self, m: int) -> np.ndarray:
        """A zero constraint matrix (m, N) to fill in."""
        return np.zeros((m, self.n))

    def clamp_start(self, C: np.ndarray, row: int, beam: int, pinned: bool = False) -> int:
        """Write rows holding the start of ``beam`` (u = v = 0, and phi = 0 unless pinned) from
        row ``row`` on; returns the next free row (the right-hand side stays 0)."""
        for f in (0, 1) if pinned else (0, 1, 2):
            C[row, self.dof(beam, 0, f)] = 1.0
            row += 1
        return row

    # ---- physics -----------------------------------------------------------------------------

    def _assemble(self, z: np.ndarray) -> tuple[np.ndarray, sp.coo_matrix]:
        """Internal force (N,) and sparse tangent (N, N) at z."""
        r = np.zeros(self.n)
        vals = []
        for i, beam in enumerate(self.beams):
            a, b = self.offsets[i], self.offsets[i + 1]
            contact = None if self.contacts is None else self.contacts[i]
            ri, ab = beam.assemble(z[a:b], self._frame, contact)
            r[a:b] = ri
            vals.append(ab[BAND:][self._band_src[i]])
        K = sp.coo_matrix(
            (np.concatenate(vals), (self._k_rows, self._k_cols)), shape=(self.n, self.n)
        )
        return r, K

    def _stresses(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        peak = np.empty(len(self.beams))
        where = np.empty(len(self.beams))
        for i, beam in enumerate(self.beams):
            peak[i], where[i] = beam.peak_stress(z[self.offsets[i] : self.offsets[i + 1]])
        return peak, where

    def _newton(
        self, z0: np.ndarray, lam0: np.ndarray, p: float
    ) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, int, str]:
        """Equilibrium at p from (z0, lam0): (converged, z, lam, r, iterations, reason)."""
        if self.kernel == "numba":
            out = self._newton_compiled(z0, lam0, p)
            if out is not None:
                return out
        st = self.settings
        C, d = self._constraint_arrays(p)
        z, lam = z0.copy(), lam0.copy()
        r, K = self._assemble(z)
        f, Kf = self._loads(p, z)
        for it in range(1, st.max_iterations + 1):
            res = r - f - C.T @ lam
            gap = C @ z - d
            Cs = sp.csr_matrix(C)
            Kt = K if Kf is None else K - sp.csr_matrix(Kf)
            J = sp.bmat([[Kt, -Cs.T], [Cs, None]], format="csc")
            try:
                # Sparse LU: the beams' tangents are banded and the constraints are a few rows,
                # so this costs far less than a dense solve (and no BLAS threads).
                step = splu(J, permc_spec="MMD_AT_PLUS_A").solve(-np.concatenate([res, gap]))
            except RuntimeError:
                return False, z0, lam0, r, it, "singular system (a mechanism: add a constraint)"
            if not np.all(np.isfinite(step)):
                return False, z0, lam0, r, it, "the correction became NaN or inf"
            dz, dlam = step[: self.n], step[self.n :]
            # Damp corrections that turn a section by more than max_rotation_step (see settings).
            big = np.abs(dz[self._rot]).max(initial=0.0) / st.max_rotation_step
            if big > 1.0:
                dz, dlam = dz / big, dlam / big
            active = self._active()  # of the assembly at the state before the correction
            norm = float(np.linalg.norm(res))
            z = z + dz
            lam = lam + dlam
            r, K = self._assemble(z)
            f, Kf = self._loads(p, z)
            if self.contacts is not None and self._active() != active:
                z, lam, r, K, f, Kf = self._backtrack(z, lam, dz, dlam, norm, C, p, r, K, f, Kf)
            if not np.all(np.isfinite(r)):
                return False, z0, lam0, r, it, "the internal force became NaN or inf"
            res = r - f - C.T @ lam
            scale = max(
                float(np.linalg.norm(C.T @ lam)), float(np.linalg.norm(f)), self._force_floor
            )
            gap_ok = float(np.abs(C @ z - d).max(initial=0.0)) <= st.ctol * self._length
            res_ok = float(np.linalg.norm(res)) <= st.rtol * scale
            tiny = float(np.abs(dz).max()) <= st.dtol * self._length
            if gap_ok and (res_ok or tiny):
                return True, z, lam, r, it, ""
        return (
            False,
            z0,
            lam0,
            r,
            st.max_iterations,
            (f"Newton did not converge in {st.max_iterations} iterations"),
        )

    def _backtrack(self, z, lam, dz, dlam, norm, C, p, r, K, f, Kf):
        """Halve a Newton correction that changed the set of acting contact pairs while it
        raises the equilibrium residual above ``norm`` (N), at most 8 times (as
        fea.mechanism's: a pair that switches off between two iterates drops the stop's force,
        and the next full correction falls deep into the stop; plain Newton can then cycle)."""
        for _ in range(8):
            if np.all(np.isfinite(r)) and float(np.linalg.norm(r - f - C.T @ lam)) <= norm:
                break
            dz, dlam = 0.5 * dz, 0.5 * dlam
            z, lam = z - dz, lam - dlam
            r, K = self._assemble(z)
            f, Kf = self._loads(p, z)
        return z, lam, r, K, f, Kf

    def _newton_compiled(
        self, z0: np.ndarray, lam0: np.ndarray, p: float
    ) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, int, str] | None:
        """:meth:`_newton` on the compiled kernel; None when it hands the sub-step back (the
        bordered solve cannot take this system) and the reference must run it."""
        kern = _kernels()
        st = self.settings
        C, d = self._constraint_arrays(p)
        C = np.ascontiguousarray(C)
        z = np.array(z0, dtype=np.float64)
        lam = np.array(lam0, dtype=np.float64)
        r = np.empty(self.n)
        abc = np.empty((self._n_beam, LDAB))
        args = (self._geo, self._eoff, self._offsets64, self._frame, self._rot64)
        if self.loads is None:
            code, it = kern.newton(z, lam, C, d, *args, self._fpar, st.max_iterations, r, abc)
        else:
            code, it = kern.MAX_ITERATIONS, st.max_iterations
            ptr, idx, val, local = kern.constraint_rows(C, self._n_beam)
            u, work = np.empty(self.n), np.empty(self.n)
            kern.assemble_all(z, *args[:4], u, r, abc)
            rho = max(1.0, float(np.abs(abc[:, _KV]).max(initial=0.0)))
            f, kf = self._loads_coo(p, z)
            for i in range(1, st.max_iterations + 1):
                status, dmax = kern.iterate(
                    z, lam, r, abc, f, *kf, d, ptr, idx, val, local, rho, *args,
                    st.max_rotation_step, u, work,
                )  # fmt: skip
                if status != kern.OK:
                    code, it = status, i
                    break
                f, kf = self._loads_coo(p, z)
                fp = self._fpar
                if kern.converged(z, lam, r, f, d, ptr, idx, val, dmax, *fp[:3], *fp[4:], work):
                    code, it = kern.OK, i
                    break
        if code == kern.FALLBACK:
            return None
        if code == kern.OK:
            return True, z, lam, r, int(it), ""
        if code == kern.MAX_ITERATIONS:
            reason = f"Newton did not converge in {st.max_iterations} iterations"
            return False, z0, lam0, r, st.max_iterations, reason
        return False, z0, lam0, r, int(it), _REASONS[int(code)]

    def _loads_coo(
        self, p: float, z: np.ndarray
    ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Applied loads (N,) and their derivative as COO (rows, cols, values) for the kernel."""
        f, dfdz = self._loads(p, z)
        if dfdz is None:
            return np.ascontiguousarray(f), (_NO_INDEX, _NO_INDEX, _NO_VALUE)
        coo = sp.coo_matrix(dfdz)
        return np.ascontiguousarray(f), (
            coo.row.astype(np.int64),
            coo.col.astype(np.int64),
            coo.data.astype(np.float64),
        )

    def _loads(self, p: float, z: np.ndarray) -> tuple[np.ndarray, sp.spmatrix | None]:
        if self.loads is None:
            return np.zeros(self.n), None
        f, dfdz = self.loads(float(p), z)
        return np.asarray(f, dtype=float), dfdz

    def _constraint_arrays(self, p: float) -> tuple[np.ndarray, np.ndarray]:
        C, d = self.constraints(float(p))
        C = np.asarray(C, dtype=float)
        d = np.asarray(d, dtype=float).ravel()
        if C.ndim != 2 or C.shape[1] != self.n or d.shape != (C.shape[0],):
            raise FeaError(
                f"constraints({p:g}) returned C {C.shape} and d {d.shape}; expected (m, {self.n}) "
                "and (m,)"
            )
        return C, d

    # ---- tracing -----------------------------------------------------------------------------

    def solve(
        self,
        params: Sequence[float] | np.ndarray,
        start: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> ConstrainedResponse:
        """Trace equilibria at ``params`` (rows): :meth:`trace`, and with stops their contact
        response (``ConstrainedResponse.contact``), the path traced again with a 10x stiffer
        penalty where it penetrates a stop deeper than the tolerance (at most
        ``ContactSettings.max_raises`` times; still beyond it: ``contact.penetration_ok``
        False and its message appended to ``message``)."""
        if self.contacts is None:
            return self.trace(params, start)
        settings = self.contact_settings
        for raises in range(int(settings.max_raises) + 1):
            if raises:
                settings = replace(settings, penalty_factor=10.0 * settings.penalty_factor)
                self.contacts = self._contacts(settings)
            res = self.trace(params, start)
            contact = contact_over_beams(
                self.contacts, res.shapes_mm, res.params, np.asarray(res.converged)
            )
            if contact.penetration_ok or raises == settings.max_raises:
                break
        self.contacts = self._contacts(self.contact_settings)  # the next solve starts afresh
        contact.extra.update(penalty_factor=settings.penalty_factor, raises=raises)
        message = res.message
        if not contact.penetration_ok:
            message = f"{message}; contact: {contact.message}".lstrip("; ")
        return replace(res, contact=contact, message=message)

    def trace(
        self,
        params: Sequence[float] | np.ndarray,
        start: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> ConstrainedResponse:
        """Trace equilibria at ``params`` (rows), starting from the undeformed state (or ``start``
        = (z, lam), an equilibrium at ``params[0]``).

        Row 0 is solved at ``params[0]`` from the start state; each later row is reached through
        adaptive sub-steps in p (halved on failure, doubled after fast convergence).

        Parameters
        ----------
        params : (rows,) float — path parameter of each row, monotonic or not.
        start : (z (N,), lam (m,)), optional.

        Returns
        -------
        ConstrainedResponse
        """
        st = self.settings
        params = np.asarray(params, dtype=float).ravel()
        if params.size < 1:
            raise FeaError("params needs at least one value")
        C0, _ = self._constraint_arrays(params[0])
        m = C0.shape[0]
        rows = params.size
        n_nodes = [b.n_nodes for b in self.beams]
        states = np.full((rows, self.n), np.nan)
        internal = np.full((rows, self.n), np.nan)
        mult = np.full((rows, m), np.nan)
        peak = np.full((rows, len(self.beams)), np.nan)
        peak_s = np.full((rows, len(self.beams)), np.nan)
        shapes = [np.full((rows, k, 2), np.nan) for k in n_nodes]
        iterations = np.zeros(rows, dtype=int)
        converged = np.zeros(rows, dtype=bool)
        stable = np.zeros(rows, dtype=bool)

        if start is None:
            z, lam = np.zeros(self.n), np.zeros(m)
        else:
            z, lam = np.asarray(start[0], dtype=float).copy(), np.asarray(start[1], float).copy()
        message = ""
        p_now = params[0]
        ok, z, lam, r, it, reason = self._newton(z, lam, p_now)
        iterations[0] = it
        if not ok:
            message = f"no equilibrium at the start, p = {p_now:.6g}: {reason}"
        else:
            self._store(0, z, lam, r, states, internal, mult, peak, peak_s, shapes)
            converged[0] = True
            stable[0] = self.is_stable(z, p_now)
            h = 1.0  # sub-step as a fraction of the current row's step
            for k in range(1, rows):
                target = params[k]
                step = target - p_now
                done = 0.0
                while done < 1.0 - 1e-12:
                    frac = min(h, 1.0 - done)
                    p_try = p_now + (done + frac) * step
                    ok, z_new, lam_new, r_new, it, reason = self._newton(z, lam, p_try)
                    iterations[k] += it
                    if ok:
                        z, lam, r = z_new, lam_new, r_new
                        done += frac
                        if it <= st.fast_iterations:
                            h = min(2.0 * h, 1.0)
                        continue
                    h = frac / 2.0
                    if h < st.min_substep:
                        message = (
                            f"no convergence at p = {p_try:.6g} (row {k}, last converged "
                            f"p = {p_now + done * step:.6g}): {reason}"
                        )
                        break
                if message:
                    break
                p_now = target
                self._store(k, z, lam, r, states, internal, mult, peak, peak_s, shapes)
                converged[k] = True
                stable[k] = self.is_stable(z, p_now)
        return ConstrainedResponse(
            params=params,
            states=states,
            internal=internal,
            multipliers=mult,
            peak_stress_MPa=peak,
            peak_stress_s_mm=peak_s,
            shapes_mm=tuple(shapes),
            iterations=iterations,
            converged=converged,
            ok=bool(converged.all()),
            message=message,
            offsets=self.offsets.copy(),
            stable=stable,
        )

    def is_stable(self, z: np.ndarray, p: float) -> bool:
        """Whether the equilibrium z at p is stable with the constraints in place.

        The constraints are linear, so the Hessian of the Lagrangian is the tangent itself
        (minus the load derivative of follower loads, symmetrised: a follower load is not
        conservative and only its symmetric part enters an energy test). Stable when that is
        positive definite on the null space of C, i.e. the KKT matrix has exactly m negative
        eigenvalues (C of full row rank; a redundant C makes Newton's system singular first).
        An inertia that could not be computed is not claimed unstable.
        """
        if self.kernel == "numba":
            kern = _kernels()
            z = np.ascontiguousarray(z, dtype=np.float64)
            r, u = np.empty(self.n), np.empty(self.n)
            abc = np.empty((self._n_beam, LDAB))
            kern.assemble_all(z, self._geo, self._eoff, self._offsets64, self._frame, u, r, abc)
            _, kf = self._loads_coo(p, z)
            C, _ = self._constraint_arrays(p)
            negative = kern.kkt_negatives_band(abc, self.n, *kf, np.ascontiguousarray(C))
            if negative >= 0:
                return negative == C.shape[0]
            # a zero pivot: the reference's dense Bunch-Kaufman below counts
        _, K = self._assemble(z)
        _, Kf = self._loads(p, z)
        Kt = sp.csr_matrix(K) if Kf is None else sp.csr_matrix(K) - sp.csr_matrix(Kf)
        H = 0.5 * (Kt + Kt.T)
        C, _ = self._constraint_arrays(p)
        negative = kkt_negative_count(H, sp.csr_matrix(C))
        return negative < 0 or negative == C.shape[0]

    def _store(self, k, z, lam, r, states, internal, mult, peak, peak_s, shapes) -> None:
        states[k] = z
        internal[k] = r
        mult[k] = lam
        peak[k], peak_s[k] = self._stresses(z)
        for i, beam in enumerate(self.beams):
            q = z[self.offsets[i] : self.offsets[i + 1]].reshape(-1, 3)
            shapes[i][k] = beam.reference_nodes_mm + q[:, :2]


def band_entries(n: int) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """(row, col) and band-storage indices of the entries of an (n, n) banded tangent.

    The model's tangent is in LAPACK gbsv storage, A[i, j] = ab[kl + ku + i - j, j]; its rows
    kl.. are the plain band (A[i, j] = ab[ku + i - j, j] of ``ab[kl:]``).
    """
    # row by row, columns increasing (what a dense n x n mask would give, in O(n) memory)
    i = np.repeat(np.arange(n), 2 * BAND + 1).reshape(n, -1)
    j = i + np.arange(-BAND, BAND + 1)
    inside = (j >= 0) & (j < n)
    rows, cols = i[inside], j[inside]
    return rows, cols, (BAND + rows - cols, cols)


_NO_INDEX = np.zeros(0, dtype=np.int64)
_NO_VALUE = np.zeros(0)


def kkt_negative_count(H: sp.spmatrix, G: sp.spmatrix, kernel: str = "auto") -> int:
    """Negative eigenvalues of the symmetric KKT matrix [[H, G^T], [G, 0]] (Sylvester inertia).

    Adding G^T rho G to H is a congruence of the KKT matrix (it does not change the inertia),
    and makes the primal block regular where H alone is singular (a body's DOFs carry no
    stiffness). The matrix, primal DOFs first and multipliers last, is then factorised by a
    sparse LU *without pivoting* in the natural order (the beams' DOFs are numbered along each
    beam, so the fill stays within the band plus the few rows the constraints couple): for a
    symmetric matrix that is L D L^T with D = diag(U), and the signs of D are the inertia
    (Sylvester's law). When SuperLU had to pivot anyway (a zero pivot), a dense Bunch-Kaufman
    LDL^T (LAPACK dsytrf) with one BLAS thread counts instead: every 2x2 block it chooses is
    indefinite (one negative eigenvalue). Returns -1 when neither factorisation worked.

    ``kernel`` ("auto" follows FLEXOPT_BEAM_KERNEL): on "numba" the same natural-order LDL^T runs
    compiled in envelope storage (fea/_constrained_kernels.py), and only a zero pivot goes on to
    the dense count.
    """
    if resolve_constrained_kernel(kernel) == "numba":
        Hc = sp.coo_matrix(H)
        Gr = sp.csr_matrix(G)
        Gr.sum_duplicates()
        negative = _kernels().kkt_negatives_coo(
            int(H.shape[0]),
            Hc.row.astype(np.int64),
            Hc.col.astype(np.int64),
            Hc.data.astype(np.float64),
            Gr.indptr.astype(np.int64),
            Gr.indices.astype(np.int64),
            Gr.data.astype(np.float64),
        )
        if negative >= 0:
            return int(negative)
    Hc = sp.csr_matrix(H)
    rho = max(float(np.abs(Hc.diagonal()).max(initial=0.0)), 1.0)
    Kkt = sp.bmat([[Hc + rho * (G.T @ G), G.T], [G, None]], format="csc")
    try:
        lu = splu(
            Kkt,
            permc_spec="NATURAL",
            diag_pivot_thresh=0.0,
            options={"SymmetricMode": True},
        )
        if np.array_equal(lu.perm_r, np.arange(Kkt.shape[0])):
            d = lu.U.diagonal()
            if np.all(np.isfinite(d)) and np.all(d != 0.0):
                return int((d < 0.0).sum())
    except RuntimeError:
        pass
    with threadpool_limits(1):  # a dense factorisation of a few hundred rows: threads only cost
        dense = Kkt.toarray()
        lu_d, ipiv, info = dsytrf(0.5 * (dense + dense.T), lower=1, overwrite_a=1)
    if info < 0:
        return -1
    n = dense.shape[0]
    neg = 0
    k = 0
    while k < n:
        if ipiv[k] > 0:
            neg += int(lu_d[k, k] <= 0.0)  # an exactly zero pivot is not positive definite
            k += 1
        else:
            neg += 1
            k += 2
    return neg


def warm_up() -> str:
    """Compile (first call in an install) or load from numba's cache the constrained kernels now.

    Like :func:`fea.beam.warm_up` (which this calls first): a process pool calls it before it
    forks, so that workers inherit the compiled code. A tiny clamped beam is traced once with its
    tip pushed (the whole compiled Newton, the inertia) and once under a follower tip force (the
    one-iteration path), and a small KKT count runs; every compiled function the engine uses is
    then loaded.

    Returns
    -------
    str
        The path that runs: "numba", or "numpy" when numba is unavailable (nothing to do).
    """
    from flexopt.fea.beam import BeamSettings
    from flexopt.fea.beam import warm_up as beam_warm_up
    from flexopt.fea.materials import Material
    from flexopt.geometry.profile import BeamProfile

    beam_warm_up()
    kernel = resolve_constrained_kernel("auto")
    if kernel != "numba":
        return kernel
    material = Material("warm-up", E_MPa=1000.0, nu=0.3, yield_MPa=10.0)
    profile = BeamProfile(np.array([[0.0, 0.0], [10.0, 0.0]]), np.array([1.0, 1.0]), 1.0)
    model = BeamModel(profile, material, settings=BeamSettings(n_elements=2))
    n = model.n_dofs

    def constraints(v: float) -> tuple[np.ndarray, np.ndarray]:
        C = system.rows(4)
        d = np.zeros(4)
        row = system.clamp_start(C, 0, 0)
        C[row, system.dof(0, -1, 1)] = 1.0
        d[row] = v
        return C, d

    def loads(v: float, z: np.ndarray) -> tuple[np.ndarray, sp.spmatrix]:
        f = np.zeros(n)
        f[n - 2] = v * np.cos(z[n - 1])
        return f, sp.coo_matrix(([-v * np.sin(z[n - 1])], ([n - 2], [n - 1])), shape=(n, n))

    system = ConstrainedBeams([model], 0, constraints)
    system.solve([0.0, 0.1])
    held = ConstrainedBeams([model], 0, lambda v: (constraints(v)[0][:3], np.zeros(3)), loads)
    held.solve([0.0, 0.01])
    kkt_negative_count(sp.identity(3, format="csr"), sp.csr_matrix(np.array([[1.0, 0.0, 0.0]])))
    return kernel
