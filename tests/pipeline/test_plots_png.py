"""The plots' PNG files are written by the Agg canvas's ``print_png`` with the figure laid out
once (pipeline/plots.py ``_png_at``), not by ``savefig``, which lays a figure with a layout
engine out twice: the file must be the one savefig writes, byte for byte, for every kind of
plot a run draws (lines, a log axis, a field with its colour bar, the field on the deformed
part, shapes, a Pareto front, a 110-dpi figure)."""

from __future__ import annotations

import io

import numpy as np
import pytest
from flexopt.pipeline import plots

pytest.importorskip("matplotlib")

D = np.linspace(0.0, 30.0, 31)
TABLE = {
    "displacement_mm": D,
    "force_N": 1.5 * np.tanh(D / 3.0),
    "peak_stress_MPa": 40.0 * np.sqrt(D / 30.0),
    "converged": np.ones(31, bool),
}
XS, YS = np.meshgrid(np.linspace(0, 30, 7), np.linspace(0, 5, 3))
POINTS = np.column_stack([XS.ravel(), YS.ravel()])
TRIANGLES = np.array(
    [[j * 7 + i, j * 7 + i + 1, (j + 1) * 7 + i + 1] for j in range(2) for i in range(6)]
    + [[j * 7 + i, (j + 1) * 7 + i + 1, (j + 1) * 7 + i] for j in range(2) for i in range(6)]
)
SHAPES = np.stack([np.column_stack([D, s * np.sin(D / 10.0)]) for s in np.linspace(0, 2, 5)])
RNG = np.random.default_rng(1)
FRONT = RNG.uniform(0.0, 1.0, (40, 2))

PLOTS = {
    "response": lambda: plots.plot_response(TABLE, allowable_MPa=42.5, title="t"),
    "stress": lambda: plots.plot_stress(TABLE, allowable_MPa=42.5, title="t"),
    "convergence (log axis)": lambda: plots.plot_convergence(
        np.arange(1, 38), np.geomspace(3.0, 0.0028, 37)[:, None], np.ones(37, bool),
        np.ones(37), ("rms_error_N",), title="t",
    ),
    "shapes": lambda: plots.plot_shapes(SHAPES, D[:5], "displacement (mm)", title="t"),
    "field": lambda: plots.plot_field(POINTS, TRIANGLES, POINTS[:, 0], limit=25.0, title="t"),
    "field deformed": lambda: plots.plot_field_deformed(
        POINTS, TRIANGLES, POINTS[:, 0],
        np.column_stack([np.zeros(21), (POINTS[:, 0] / 30) ** 2]), limit=25.0, title="t",
    ),
    "front": lambda: plots.plot_front(FRONT, FRONT[:5], ("rms_error_N", "mass_g"), FRONT[0]),
    "110 dpi": lambda: plots.spring_shape_png(None, SHAPES),
}  # fmt: skip


def _savefig(fig, dpi: int) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


@pytest.mark.parametrize("name", PLOTS)
def test_the_png_is_savefigs_byte_for_byte(name, monkeypatch):
    made = PLOTS[name]()
    assert made.startswith(b"\x89PNG")
    monkeypatch.setattr(plots, "_png_at", _savefig)
    assert PLOTS[name]() == made
