"""Exact pruning: a drive train observed at its load beside an unobserved chain of n mass-spring
pairs (docs/performance.md, "Exact pruning").  Prints one markdown row per n: states, operations
of the right-hand side, time per rhs call and wall time of the run, without and with pruning, and
the largest difference of the outputs.

    python benchmarks/pruning.py 10 50 100
"""
from __future__ import annotations

import sys
import time

import numpy as np

from multipole import pipeline
from multipole.netlist import loads
from multipole.pruning import prune


def scene_text(n: int) -> str:
    """The drive train of diagrams/drive_train.yaml (without the gear) and a chain of ``n`` masses
    and springs pushed by a step force, which no output observes."""
    lines = ["name: observed_drive_unobserved_chain",
             "description: drive train observed at its load, a chain of masses nobody plots", "elements:",
             '  motor: {type: torque_source, value: "10*(1 - exp(-t/0.05))"}',
             "  rotor: {type: inertia, J: 2.0e-3}", "  shaft: {type: spring, c: 2000.0}",
             "  shaft_d: {type: damper, d: 0.5}", "  load: {type: inertia, J: 0.5}",
             "  bearing: {type: damper, d: 0.8}", "  housing: {type: ground}",
             '  push: {type: force_source, value: "5*step(t - 0.3)"}',
             "  frame: {type: ground, domain: translational}"]
    for k in range(n):
        lines += [f"  m{k}: {{type: mass, m: 1.0}}", f"  k{k}: {{type: spring, c: 1.0e4, domain: translational}}",
                  f"  d{k}: {{type: damper, d: 1.0, domain: translational}}"]
    lines += ["connections:", "  - [motor.p, rotor.a]", "  - [rotor.b, shaft.a, shaft_d.a]",
              "  - [shaft.b, shaft_d.b, load.a]", "  - [load.b, bearing.a]", "  - [bearing.b, housing.p]",
              "  - [push.p, m0.a]"]
    for k in range(n):
        nxt = f"m{k + 1}.a" if k + 1 < n else "frame.p"
        lines += [f"  - [m{k}.b, k{k}.a, d{k}.a]", f"  - [k{k}.b, d{k}.b, {nxt}]"]
    lines += ["outputs: [load.omega, shaft.force]",
              "simulate: {t_end: 2.0, dt_out: 0.002, rtol: 1.0e-8, atol: 1.0e-10}"]
    return "\n".join(lines) + "\n"


def per_call(f, x, repeat: int = 2000) -> float:
    """Best of five timings of ``repeat`` calls [s per call] (the machine is shared)."""
    best = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(repeat):
            f(0.5, x)
        best = min(best, (time.perf_counter() - start) / repeat)
    return best


def row(n: int) -> str:
    sc = loads(scene_text(n), f"chain{n}.yaml")
    eq = pipeline.equations(sc)
    _small, record = prune(eq, sc.outputs)
    ref = pipeline.run(sc, progress=False, rtol=1e-12, atol=1e-14, solver="DOP853")
    cells = []
    for flag in (False, True):
        m = pipeline.model(sc, prune=flag)
        t_rhs = per_call(m.rhs, m.x0)
        start = time.perf_counter()
        res = pipeline.run(sc, progress=False, prune=flag)
        wall = time.perf_counter() - start
        err = max(float(np.max(np.abs(res.outputs[o] - ref.outputs[o]) / np.max(np.abs(ref.outputs[o]))))
                  for o in sc.outputs)
        cells.append((len(m.state_names), t_rhs * 1e6, wall, res.stats["nfev"], res.solver, err))
    (s0, r0, w0, n0, v0, e0), (s1, r1, w1, n1, v1, e1) = cells
    return (f"| {n} | {s0} → {s1} | {record.ops_before} → {record.ops_after} | {r0:.1f} → {r1:.1f} | "
            f"{v0} → {v1} | {n0} → {n1} | {w0:.3f} → {w1:.3f} | {e0:.1e} → {e1:.1e} |")


if __name__ == "__main__":
    print("| chain pairs n | states | rhs operations | rhs call [µs] | solver | nfev | run wall [s] "
          "| output error (relative) |")
    print("|---|---|---|---|---|---|---|---|")
    for n in [int(a) for a in sys.argv[1:]] or [10, 50, 100]:
        print(row(n), flush=True)
