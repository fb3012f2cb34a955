"""Plots for run folders (matplotlib, off-screen: no pyplot, no display needed)."""

from __future__ import annotations

import io
from collections.abc import Mapping

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["plot_response"]

_LABELS = {
    "displacement_mm": "end displacement along direction (mm)",
    "force_N": "end force along direction (N)",
    "peak_stress_MPa": "peak stress (MPa)",
}


def plot_response(
    table: Mapping[str, np.ndarray],
    x: str = "displacement_mm",
    left: str = "force_N",
    right: str = "peak_stress_MPa",
    allowable_MPa: float | None = None,
    title: str = "",
) -> bytes:
    """Two panels against ``x``: ``left`` (force) and ``right`` (stress, with the allowable line).

    Only converged rows are drawn; a title note says when some are missing.

    Parameters
    ----------
    table : mapping of str to (n,) array
        Response columns, including ``x``, ``left``, ``right`` and ``converged``.
    allowable_MPa : float, MPa, optional
        Drawn as a dashed horizontal line on the stress panel.

    Returns
    -------
    bytes
        The PNG file.
    """
    ok = np.asarray(table.get("converged", np.ones(len(table[x]), bool)), dtype=bool)
    xs = np.asarray(table[x], dtype=float)[ok]
    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax_f, ax_s = fig.subplots(1, 2)
    ax_f.plot(xs, np.asarray(table[left], dtype=float)[ok], "o-", ms=3, color="tab:blue")
    ax_f.set_xlabel(_LABELS.get(x, x))
    ax_f.set_ylabel(_LABELS.get(left, left))
    ax_f.set_title("force – displacement")
    ax_s.plot(xs, np.asarray(table[right], dtype=float)[ok], "o-", ms=3, color="tab:red")
    if allowable_MPa is not None:
        ax_s.axhline(allowable_MPa, ls="--", color="k", lw=1, label=f"yield {allowable_MPa:g} MPa")
        ax_s.legend(loc="best")
    ax_s.set_xlabel(_LABELS.get(x, x))
    ax_s.set_ylabel(_LABELS.get(right, right))
    ax_s.set_title("stress – displacement")
    for ax in (ax_f, ax_s):
        ax.grid(True, alpha=0.3)
    note = "" if ok.all() else f"  ({int((~ok).sum())} of {ok.size} rows not converged)"
    if title or note:
        fig.suptitle(title + note)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    return buffer.getvalue()
