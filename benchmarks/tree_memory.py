"""Peak resident memory of a command's whole process tree, process by process (issue 27 item 5).

    python benchmarks/tree_memory.py [--every 0.1] -- flexopt run sea-spring -q --out DIR

``/usr/bin/time -v`` reports the largest process's peak only; a run forks workers, the report's
second process and the STEP child. This samples the resident set (RSS, psutil) of the command
and every descendant each ``--every`` seconds and prints: the wall time, the tree's largest sum
of RSS and when, each process's peak (GB), when it was reached (s from the start) and its first
and last sample time (what it lived through), and the load average before and after. Samples
miss a peak shorter than the interval; the largest process's ``ru_maxrss`` (/usr/bin/time) is
exact. Pages a forked child shares with its parent count in both.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time


def main(argv: list[str]) -> None:
    import psutil

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=float, default=0.1, help="sampling interval, s")
    ap.add_argument("command", nargs=argparse.REMAINDER)
    args = ap.parse_args(argv)
    cmd = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not cmd:
        print("benchmarks/tree_memory.py: give a command after --", file=sys.stderr)
        raise SystemExit(2)
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd)
    root = psutil.Process(proc.pid)
    peaks: dict[int, list[float]] = {}  # pid -> [peak bytes, at s, first s, last s]
    best = (0.0, 0.0)
    while proc.poll() is None:
        now = time.perf_counter() - t0
        try:
            tree = [root, *root.children(recursive=True)]
        except psutil.NoSuchProcess:
            break
        total = 0.0
        for q in tree:
            try:
                rss = float(q.memory_info().rss)
            except psutil.Error:
                continue
            total += rss
            row = peaks.setdefault(q.pid, [0.0, now, now, now])
            row[3] = now
            if rss > row[0]:
                row[0], row[1] = rss, now
        best = max(best, (total, now))
        time.sleep(args.every)
    proc.wait()
    wall = time.perf_counter() - t0
    load1 = " ".join(f"{v:.2f}" for v in os.getloadavg())
    print(
        f"exit {proc.returncode}, wall {wall:.1f} s; load {' '.join(f'{v:.2f}' for v in load0)}"
        f" -> {load1}"
    )
    print(f"tree's largest sum {best[0] / 1e9:.2f} GB at {best[1]:.1f} s")
    print("pid      peak GB  at s   lived s")
    for pid, (peak, at, first, last) in sorted(peaks.items(), key=lambda kv: -kv[1][0]):
        tag = " (the command)" if pid == proc.pid else ""
        print(f"{pid:<8} {peak / 1e9:7.3f} {at:6.1f}   {first:.1f}-{last:.1f}{tag}")


if __name__ == "__main__":
    main(sys.argv[1:])
