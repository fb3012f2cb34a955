"""Write tests/golden/<example>.json from the best.json of a full run of a built-in example.

    python tests/golden/make_golden.py [--commit SHA] RUN_DIR [RUN_DIR ...]

RUN_DIR is the folder of ``flexopt run <example> --out RUN_DIR`` (a full run, not ``--quick``:
tests/test_golden_examples.py runs the example the same way and compares). The golden file keeps
the chosen design's variables (``parameters``, by name, and ``x``), its objectives, constraints
and feasibility, its scalar metrics, and where it came from (the commit of the code, the
command and the run's wall time, which no test compares). ``--commit`` names the commit the
runs were made with (default: this checkout's HEAD). Re-make a golden file only when a
change of the chosen design is intended, and say why in the commit.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def scalar_metrics(metrics: dict) -> dict:
    """The metrics that are one number, flag or label (arrays and tables stay in best.json)."""
    return {
        k: v for k, v in metrics.items() if isinstance(v, bool | int | float | str) or v is None
    }


def golden(run_dir: Path, commit: str) -> dict:
    best = json.loads((run_dir / "best.json").read_text(encoding="utf-8"))
    run = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
    if run.get("quick") or run.get("status") != "finished":
        raise SystemExit(f"{run_dir}: not a finished full run ({run.get('status')}, quick?)")
    flexopt = run.get("versions", {}).get("flexopt", "")
    return {
        "example": run["study"],
        "made_from": {
            "command": run.get("command_line", ""),
            "flexopt": flexopt,
            "commit": commit,
            "seed": run.get("seed"),
            "baseline_wall_s": run.get("wall_s"),
        },
        "feasible": best["feasible"],
        "parameters": best["parameters"],
        "x": best["x"],
        "objectives": best["objectives"],
        "constraints": best["constraints"],
        "metrics": scalar_metrics(best.get("metrics") or {}),
    }


def _commit() -> str:
    try:
        return subprocess.run(
            ["git", "-C", str(HERE), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def main(argv: list[str]) -> None:
    commit = _commit()
    if argv[:1] == ["--commit"]:
        commit, argv = argv[1], argv[2:]
    for arg in argv:
        record = golden(Path(arg), commit)
        path = HERE / f"{record['example']}.json"
        path.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
        print(f"wrote {path}")


if __name__ == "__main__":
    main(sys.argv[1:])
