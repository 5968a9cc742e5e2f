"""Crane benchmark (docs/performance.md, "Belts"): check and model build of
diagrams/belts/crane.yaml in a fresh process with an empty cache (CPU time, medians of 3), for the
scene's spans and 10x longer ones, then the full run of both (model warm).

    python benchmarks/crane_bench.py
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "diagrams" / "belts" / "crane.yaml"
SPANS = ((50.0, 30.0), (500.0, 300.0))
BUILD = """
import time
t0 = time.process_time()
from multipole import pipeline
from multipole.netlist import load
t1 = time.process_time()
scene = load({scene!r}, {{'L': {L}, 'l_s': {ls}}})
pipeline.check(scene)
t2 = time.process_time()
model = pipeline.model(scene)
t3 = time.process_time()
print(t1 - t0, t2 - t1, t3 - t2, len(model.state_names))
"""


def build_times(L: float, ls: float, repeats: int = 3) -> list:
    """Medians of (import, check, model build) [s CPU] and the number of states."""
    rows = []
    for _ in range(repeats):
        env = dict(os.environ, MULTIPOLE_CACHE=tempfile.mkdtemp())
        out = subprocess.run([sys.executable, "-c", BUILD.format(scene=str(SCENE), L=L, ls=ls)], env=env,
                             capture_output=True, text=True, check=True).stdout.split()
        rows.append([float(x) for x in out])
    return [statistics.median(r[i] for r in rows) for i in range(4)]


def main() -> None:
    from multipole import pipeline
    from multipole.netlist import load
    print("spans L, l_s [m] | import | check | model build | check + build [s CPU] | states")
    for L, ls in SPANS:
        imp, chk, build, n = build_times(L, ls)
        print(f"{L:g}, {ls:g} | {imp:.2f} | {chk:.2f} | {build:.2f} | {chk + build:.2f} | {n:.0f}")
    print("spans L, l_s [m] | run [s CPU] | steps | events")
    for L, ls in SPANS:
        scene = load(SCENE, {"L": L, "l_s": ls})
        pipeline.model(scene)
        t0 = time.process_time()
        res = pipeline.run(scene, progress=False)
        print(f"{L:g}, {ls:g} | {time.process_time() - t0:.2f} | {res.stats['steps']} | {res.stats['events']}")


if __name__ == "__main__":
    main()
