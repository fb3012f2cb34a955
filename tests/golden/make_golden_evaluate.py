"""Write tests/golden/evaluate/<example>.json from a ``flexopt evaluate`` folder of an example.

    python tests/golden/make_golden_evaluate.py [--commit SHA] EVAL_DIR [EVAL_DIR ...]

EVAL_DIR is the folder of ``flexopt evaluate <example> --out EVAL_DIR``. The golden file keeps
the example's recorded design's verdict (each requirement's verdict, value and the model it was
judged on), its scalar summary and whether it converged, and where it came from (the commit,
which no test compares). tests/test_golden_examples.py evaluates the example again and
compares. Re-make a golden file only when a change of an example's answer is intended, and say
why in the commit.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def golden(eval_dir: Path, commit: str) -> dict:
    record = json.loads((eval_dir / "evaluation.json").read_text(encoding="utf-8"))
    summary = {
        k: v
        for k, v in record["summary"].items()
        if isinstance(v, bool | int | float | str) or v is None
    }
    verdict = record.get("verdict") or {}
    rows = [
        {k: row.get(k) for k in ("name", "quantity", "verdict", "value", "model")}
        for row in verdict.get("requirements", [])
    ]
    return {
        "example": record["study"],
        "made_from": {"command": "flexopt evaluate", "commit": commit},
        "converged": record["converged"],
        "overall": verdict.get("overall"),
        "requirements": rows,
        "summary": summary,
    }


def main(argv: list[str]) -> None:
    commit = ""
    if argv[:1] == ["--commit"]:
        commit, argv = argv[1], argv[2:]
    if not commit:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
        ).stdout.strip()
    for folder in map(Path, argv):
        data = golden(folder, commit)
        name = folder.name
        (HERE / "evaluate" / f"{name}.json").write_text(
            json.dumps(data, indent=1, sort_keys=True) + "\n", encoding="utf-8"
        )
        print(f"wrote evaluate/{name}.json")


if __name__ == "__main__":
    main(sys.argv[1:])
