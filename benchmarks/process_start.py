"""Whole-process cost of ``multipole simulate`` per backend (docs/performance.md, "A new process on
the numba backend").

Each case is one ``multipole simulate FILE --backend B --quiet`` in a fresh Python process, timed
from outside: CPU time (user + system of the child, ``resource.getrusage(RUSAGE_CHILDREN)``) and
wall time.  Cases are run interleaved (A B C A B C ...), medians with [lowest-highest] of the
rounds.  The model cache is a private temporary folder:

* ``numpy warm``, ``numba warm``: the scene was simulated once before in that cache (by a warm-up
  run that is not timed);
* ``numba new scene``: each round gets an empty model cache (a new temporary ``MULTIPOLE_CACHE``),
  so the scene's model is derived, translated and its functions compiled; the integrator kernels
  stay in numba's cache (compiled once per installation).

``--before REF`` also times the source of the git revision ``REF`` (exported with ``git archive``
into a temporary folder and put first on ``PYTHONPATH``, with a model cache of its own), its cases
interleaved with the working tree's: before and after side by side in one run, under the same load
(``REF`` may also be a folder holding a source tree, used as it is).
The first warm-up run of that tree compiles numba's integrator kernels for it (about 20 s CPU).

    python benchmarks/process_start.py [FILE] [--rounds 5] [--warm-only] [--before REF]
"""
from __future__ import annotations

import argparse
import atexit
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


#: every folder this script makes (model caches, the exported revision) is made in here, removed at exit
WORK = tempfile.mkdtemp(prefix="multipole-process-start-")
atexit.register(shutil.rmtree, WORK, True)
#: the children's working folder: empty, so that ``python -m`` (which puts it first on ``sys.path``)
#: imports multipole from ``PYTHONPATH`` or the installation, never from the folder it was started in
NEUTRAL = tempfile.mkdtemp(dir=WORK, prefix="multipole-cwd-")


def timed(cmd, env) -> tuple[float, float]:
    """(CPU [s], wall [s]) of one child process; raises if it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(cmd, env=env, cwd=NEUTRAL, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, wall


def exported(ref: str) -> Path:
    """The files of git revision ``ref`` in a new temporary folder (``git archive``)."""
    folder = Path(tempfile.mkdtemp(dir=WORK, prefix="multipole-before-"))
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
    return folder


def new_cache() -> str:
    """An empty model cache folder."""
    return tempfile.mkdtemp(dir=WORK, prefix="multipole-bench-")


def trees(before: str | None) -> dict:
    """``{label: environment}``: the working tree and, with ``before``, that revision's source first
    on ``PYTHONPATH``; each with a model cache of its own."""
    out = {}
    if before:
        folder = Path(before) if Path(before).is_dir() else exported(before)
        path = os.pathsep.join(p for p in (str(folder), os.environ.get("PYTHONPATH", "")) if p)
        out[f"{before}: "] = dict(os.environ, PYTHONPATH=path, MULTIPOLE_CACHE=new_cache())
    out["" if not before else "working tree: "] = dict(os.environ, MULTIPOLE_CACHE=new_cache())
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", nargs="?", default=str(ROOT / "diagrams" / "drive_train.yaml"))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--warm-only", action="store_true", help="leave out the new-scene case")
    ap.add_argument("--before", metavar="REF", help="also time this git revision (or source folder), interleaved")
    args = ap.parse_args(argv)
    base = [sys.executable, "-m", "multipole.cli", "simulate", str(Path(args.file).resolve()), "--quiet", "--backend"]
    cases = {}
    for label, env in trees(args.before).items():
        for backend in ("numpy", "numba"):          # fill the warm cache (and numba's kernel cache)
            timed(base + [backend], env)
        cases[f"{label}numpy warm"] = (env, "numpy", False)
        cases[f"{label}numba warm"] = (env, "numba", False)
        if not args.warm_only:
            cases[f"{label}numba new scene"] = (env, "numba", True)
    times: dict = {name: [] for name in cases}
    for _ in range(args.rounds):
        for name, (env, backend, fresh) in cases.items():
            case_env = dict(env, MULTIPOLE_CACHE=new_cache()) if fresh else env
            times[name].append(timed(base + [backend], case_env))
    load = os.getloadavg()[0]
    print(f"{Path(args.file).name}, {args.rounds} rounds interleaved, medians [lowest-highest], "
          f"load average {load:.1f}")
    print("| case | CPU [s] | wall [s] |\n|---|---|---|")
    for name, rows in times.items():
        cells = []
        for k in (0, 1):
            v = [r[k] for r in rows]
            cells.append(f"{statistics.median(v):.2f} [{min(v):.2f}-{max(v):.2f}]")
        print(f"| {name} | {cells[0]} | {cells[1]} |")


if __name__ == "__main__":
    main()
