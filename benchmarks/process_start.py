"""Whole-process cost of ``multipole simulate`` per backend (docs/performance.md, "Issue 11: a
new process").

Each case is one ``multipole simulate FILE --backend B --quiet`` in a fresh Python process, timed
from outside: CPU time (user + system of the child, ``resource.getrusage(RUSAGE_CHILDREN)``) and
wall time.  Cases are run interleaved (A B C A B C ...), medians with [lowest-highest] of the
rounds.  The model cache is a private temporary folder:

* ``numpy warm``, ``numba warm``: the scene was simulated once before in that cache (by a warm-up
  run that is not timed);
* ``numba new scene``: each round gets an empty model cache (a new temporary ``MULTIPOLE_CACHE``),
  so the scene's model is derived, translated and its functions compiled; the integrator kernels
  stay in numba's cache (compiled once per installation).

    python benchmarks/process_start.py [FILE] [--rounds 5] [--warm-only]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(cmd, env) -> tuple[float, float]:
    """(CPU [s], wall [s]) of one child process; raises if it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, wall


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", nargs="?", default=str(ROOT / "diagrams" / "drive_train.yaml"))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--warm-only", action="store_true", help="leave out the new-scene case")
    args = ap.parse_args(argv)
    warm = tempfile.mkdtemp(prefix="multipole-bench-")
    base = [sys.executable, "-m", "multipole.cli", "simulate", args.file, "--quiet", "--backend"]
    env = dict(os.environ, MULTIPOLE_CACHE=warm)
    for backend in ("numpy", "numba"):          # fill the warm cache (and numba's kernel cache)
        timed(base + [backend], env)
    cases = {"numpy warm": (["numpy"], False), "numba warm": (["numba"], False), "numba new scene": (["numba"], True)}
    if args.warm_only:
        del cases["numba new scene"]
    times: dict = {name: [] for name in cases}
    for _ in range(args.rounds):
        for name, (backend, fresh) in cases.items():
            case_env = dict(env, MULTIPOLE_CACHE=tempfile.mkdtemp(prefix="multipole-bench-")) if fresh else env
            times[name].append(timed(base + backend, case_env))
    print(f"{Path(args.file).name}, {args.rounds} rounds interleaved, medians [lowest-highest]")
    print("| case | CPU [s] | wall [s] |\n|---|---|---|")
    for name, rows in times.items():
        cells = []
        for k in (0, 1):
            v = [r[k] for r in rows]
            cells.append(f"{statistics.median(v):.2f} [{min(v):.2f}-{max(v):.2f}]")
        print(f"| {name} | {cells[0]} | {cells[1]} |")


if __name__ == "__main__":
    main()
