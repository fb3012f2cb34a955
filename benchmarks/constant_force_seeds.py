"""The constant-force example's hybrid over several seeds: rounds, designs, RMS, verdict, wall
(session 33, docs/constant_force.md "The Gauss-Newton stage on the stress ridge").

    python benchmarks/constant_force_seeds.py [--seeds 1 2 3 4 5] [--hybrid '{"max_iter": 40}']
        [--study '{"fidelity": {"beam_stress_factor": 1.04}}'] [--flexopt PATH] [--reference]

Each seed is one ``flexopt run`` of pipeline/examples/constant-force.yaml (with the
``optimiser.hybrid`` keys of ``--hybrid``, and any keys of ``--study``, laid over the example's)
into a temporary folder that is removed; printed per seed: the rounds (the run's generations: GA
generations plus gradient batches), the designs solved, the best RMS error (N), the verdict's
requirements met, the wall time (s, of the whole command; the machine is shared, so read it
beside the load average), and each start's iterations and why it stopped. ``--reference`` runs
on the recorded results' numerics (tests/reference_numerics.py), so seed 1 reproduces
tests/golden/constant-force.json. The rounds, designs and RMS are deterministic on given
numerics; the wall is not.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "pipeline" / "examples" / "constant-force.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--hybrid", default="{}", help="optimiser.hybrid keys, as JSON")
    parser.add_argument("--study", default="{}", help="other study keys, as JSON (merged)")
    parser.add_argument("--flexopt", default=str(Path(sys.executable).with_name("flexopt")))
    parser.add_argument("--reference", action="store_true", help="the reference numerics")
    args = parser.parse_args()
    env = dict(os.environ)
    if args.reference:
        sys.path.insert(0, str(ROOT / "tests"))
        import reference_numerics

        reference_numerics.apply(env)
    study = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    study["optimiser"].setdefault("hybrid", {}).update(json.loads(args.hybrid))
    overlay = json.loads(args.study)
    _merge(study, overlay)
    print(
        f"optimiser.hybrid: {study['optimiser']['hybrid']}"
        + (f"; {overlay}" if overlay else "")
        + f"; load {os.getloadavg()[0]:.2f}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "constant-force.yaml"
        path.write_text(yaml.safe_dump(study), encoding="utf-8")
        for seed in args.seeds:
            out = Path(tmp) / f"seed{seed}"
            t0 = time.perf_counter()
            cmd = [args.flexopt, "run", str(path), "--seed", str(seed), "--out", str(out), "-q"]
            done = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
            wall = time.perf_counter() - t0
            if done.returncode:
                print(f"seed {seed}: exit {done.returncode}: {done.stderr.strip()[-300:]}")
                continue
            run = json.loads((out / "run.json").read_text(encoding="utf-8"))
            met = re.search(r"(\d+) of (\d+) requirements met", (out / "report.md").read_text())
            hybrid = run.get("hybrid", {})
            starts = [(s.get("iterations"), s.get("stop", "")) for s in hybrid.get("starts", [])]
            print(
                f"seed {seed}: rounds {run['generations_done']}, designs {run['n_evaluations']}, "
                f"RMS {hybrid.get('best_f', float('nan')):.6f} N, "
                f"MET {met.group(1) if met else '?'}/{met.group(2) if met else '?'}, "
                f"wall {wall:.2f} s, load {os.getloadavg()[0]:.2f}; starts {starts}",
                flush=True,
            )
            shutil.rmtree(out, ignore_errors=True)


def _merge(into: dict, keys: dict) -> None:
    """Lay ``keys`` over ``into`` (nested mappings merged, other values replaced)."""
    for key, value in keys.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            _merge(into[key], value)
        else:
            into[key] = value


if __name__ == "__main__":
    main()
