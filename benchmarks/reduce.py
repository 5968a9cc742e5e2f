"""``multipole reduce`` against its tolerance (docs/performance.md, "Model reduction").

One markdown row per scene and tolerance: states of the full and the reduced model, the measured
output error, the integration wall time of both (the solver ``auto`` picks for each), and the
simplifications kept.  Each scene takes well under a minute on its own:

    python benchmarks/reduce.py stiff      # diagrams/hard/stiff_drive_train.yaml, the two speeds
    python benchmarks/reduce.py spur       # diagrams/weber/spur_normal.yaml, speeds, mu = 1e-5 and 0.05
    python benchmarks/reduce.py chain      # a free chain of stiff springs and masses, observed at its far end
    python benchmarks/reduce.py piezo      # diagrams/weber/piezo_stack.yaml observed at its tip
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from multipole.reduce import reduce

ROOT = Path(__file__).resolve().parents[1]


def free_chain(n: int, m: float = 0.1, c: float = 1.0e6) -> str:
    """``n`` masses ``m`` [kg] joined by ``n - 1`` springs ``c`` [N/m], pushed at the first by a
    smooth step force and held at the last by a damper to the ground; ``2n - 1`` states."""
    lines = ["name: free_chain", f"description: {n} masses, stiff springs, pushed at one end, observed at the other",
             "elements:", '  push: {type: force_source, value: "10*(1 - exp(-t/0.1))"}',
             "  brake: {type: damper, d: 5.0, domain: translational}", "  frame: {type: ground, domain: translational}"]
    lines += [f"  m{i}: {{type: mass, m: {m}}}" for i in range(1, n + 1)]
    lines += [f"  k{i}: {{type: spring, c: {c}, domain: translational}}" for i in range(1, n)]
    lines += ["connections:", "  - [push.p, m1.a]"]
    lines += [f"  - [m{i}.b, k{i}.a]\n  - [k{i}.b, m{i + 1}.a]" for i in range(1, n)]
    lines += [f"  - [m{n}.b, brake.a]", "  - [brake.b, frame.p]", f"outputs: [m{n}.v]",
              "simulate: {t_end: 1.0, dt_out: 0.002, rtol: 1.0e-6, atol: 1.0e-9}"]
    return "\n".join(lines) + "\n"


def row(label, path, tol, outputs, overrides=None) -> str:
    _scene, rep = reduce(path, tol=tol, outputs=outputs, progress=False, overrides=overrides)
    kept = "; ".join(f"{s.element} {s.action}" for s in rep.accepted) or "nothing"
    if len(kept) > 90:
        kept = f"{len(rep.accepted)} steps: " + ", ".join(dict.fromkeys(s.action for s in rep.accepted))
    return (f"| {label} | {tol:g} | {rep.states_full} → {rep.states_reduced} | {rep.error:.2g} | "
            f"{rep.full.solver} {rep.wall_full:.3f} → {rep.reduced.solver} {rep.wall_reduced:.3f} | "
            f"{len(rep.steps)} | {kept} |")


def main(which) -> None:
    print("| scene | tol | states | output error | integration [s] | runs | kept |")
    print("|---|---|---|---|---|---|---|")
    if "stiff" in which:
        for tol in (1e-2, 1e-3, 1e-4):
            print(row("stiff_drive_train", ROOT / "diagrams/hard/stiff_drive_train.yaml", tol,
                      ["load.omega", "rotor.omega"]), flush=True)
    if "spur" in which:
        for mu in ("1e-5", "0.05"):
            for tol in (1e-2, 1e-3):
                print(row(f"spur_normal, mu = {mu}", ROOT / "diagrams/weber/spur_normal.yaml", tol,
                          ["pinion.omega", "wheel.omega"], {"mesh.mu": mu}), flush=True)
    if "piezo" in which:
        print(row("piezo_stack, n = 10", ROOT / "diagrams/weber/piezo_stack.yaml", 1e-2, ["piezo.stroke", "load.v"]),
              flush=True)
    if "chain" in which:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "chain.yaml"
            path.write_text(free_chain(10))
            for tol in (1e-2, 1e-3):
                print(row("free chain of 10, c = 1e6 N/m", path, tol, ["m10.v"]), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["stiff", "spur", "chain", "piezo"])
