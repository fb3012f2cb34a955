"""best.step of a run's part: the direct writer (geometry.step_writer, what ``step_bytes`` uses)
against OpenCascade's (build123d's extrude and export_step, ``step_bytes``'s fallback).

    nice python benchmarks/step_write_speed.py --run RUN_DIR [--rounds 3] [--which direct occ]

RUN_DIR is a ``flexopt run`` folder with a ``best_cad.py`` (its ``OUTLINE_AS_EXPORTED`` and
``THICKNESS_AS_EXPORTED_MM``: the part best.step is written of). Each writer runs ``--rounds``
times in this process, alternating; printed per writer: the file's size and faces, the median
and every round's CPU (``time.process_time``) and wall (``time.perf_counter``), s, with the load
average before and after. build123d's import is done before the timing (the early STEP child
imported it before the part arrived). Numbers only; nothing is written.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path


def _part(run_dir: Path):
    from flexopt.geometry.solid import FlatPart
    from shapely.geometry import Polygon

    src = (run_dir / "best_cad.py").read_text()
    names: dict = {}
    exec(compile(src.split("\ndef ")[0].split("if __name__")[0], "best_cad.py", "exec"), names)
    rings = names["OUTLINE_AS_EXPORTED"]  # exterior first, then the holes
    poly = Polygon(rings[0], rings[1:])
    return FlatPart(poly, float(names["THICKNESS_AS_EXPORTED_MM"]), (0.0, 0.0), frame="design")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--which", nargs="+", default=["direct", "occ"], choices=["direct", "occ"])
    args = ap.parse_args()
    from flexopt.geometry.solid import _occ_step_bytes, clean_outline, step_bytes
    from shapely.geometry.polygon import orient

    part = _part(args.run)
    cleaned = orient(clean_outline(part.outline), sign=1.0)
    rings = (cleaned.exterior, *cleaned.interiors)
    print(
        f"outline: {sum(len(r.coords) - 1 for r in rings)} edges in {len(rings)} rings, "
        f"thickness {part.thickness_mm:.6g} mm; load average "
        + " ".join(f"{x:.2f}" for x in os.getloadavg())
    )
    if "occ" in args.which:
        import build123d  # noqa: F401 - not timed

    makers = {
        "direct": lambda: step_bytes(part),
        "occ": lambda: _occ_step_bytes(cleaned, part.thickness_mm),
    }
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in args.which}
    size: dict[str, tuple[int, int]] = {}
    for _ in range(args.rounds):
        for which in args.which:
            t0, c0 = time.perf_counter(), time.process_time()
            data = makers[which]()
            times[which].append((time.process_time() - c0, time.perf_counter() - t0))
            size[which] = (len(data), data.count(b"ADVANCED_FACE("))
    for which in args.which:
        cpu = [c for c, _ in times[which]]
        wall = [w for _, w in times[which]]
        print(
            f"{which:6s}: {size[which][0] / 1e6:.1f} MB, {size[which][1]} faces; CPU median "
            f"{statistics.median(cpu):.2f} s ({', '.join(f'{c:.2f}' for c in cpu)}), wall "
            f"median {statistics.median(wall):.2f} s ({', '.join(f'{w:.2f}' for w in wall)})"
        )
    print("load average at the end " + " ".join(f"{x:.2f}" for x in os.getloadavg()))


if __name__ == "__main__":
    main()
