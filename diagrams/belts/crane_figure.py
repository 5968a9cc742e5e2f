"""The crane figure of docs/belts.md: motion, rope forces and drum powers of diagrams/belts/crane.yaml.

Run from the repository root: ``python diagrams/belts/crane_figure.py`` (writes docs/figures/belts_crane.png).
"""
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from multipole import pipeline
from multipole.netlist import load

HERE = Path(__file__).resolve().parent
OUT = HERE.parents[1] / "docs" / "figures"
ROPES = {"l1": "load rope at drum D1", "l3": "load rope, carriage to right mast", "l5": "load rope, hook fall",
         "a1": "auxiliary rope at the carriage", "c2": "carrying rope (pretension, static in 1-D)"}


def travelled(t, v):
    return np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])


def crane():
    outs = ["carriage.v", "hook.v", "drive1.p.e", "drive1.p.f", "drive2.p.e", "drive2.p.f"] + [f"{r}.F" for r in ROPES]
    res = pipeline.run(load(HERE / "crane.yaml"), progress=False, outputs=outs, dt_out=0.02)
    t, o = res.t, res.outputs
    fig, (ax1, ax2, ax3) = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    ax1.plot(t, 10.0 + travelled(t, o["carriage.v"]), label="carriage x from the left mast [m]")
    ax1.plot(t, -8.0 + travelled(t, o["hook.v"]), label="hook height relative to the carriage [m]")
    for t0, what in ((1, "lift"), (13, "transport"), (30, "lower")):
        ax1.axvline(t0, color="0.7", lw=0.8)
        ax1.text(t0 + 0.3, 30, what)
    ax1.set(ylabel="position [m]", title="tilting-mast cable crane (1-D): 50 m span, 1050 kg on a two-fall hook")
    ax1.legend(loc="center right")
    for name, label in ROPES.items():
        ax2.plot(t, o[f"{name}.F"] / 1e3, label=f"{name}: {label}")
    ax2.set(ylabel="rope force [kN]", ylim=(0, 25))
    ax2.legend(loc="center right", fontsize=8)
    ax3.plot(t, -o["drive1.p.e"] * o["drive1.p.f"] / 1e3, label="drum D1 (load rope)")
    ax3.plot(t, -o["drive2.p.e"] * o["drive2.p.f"] / 1e3, label="drum D2 (auxiliary rope)")
    ax3.set(xlabel="t [s]", ylabel="power into the ropes [kW]")
    ax3.legend()
    fig.tight_layout()
    fig.savefig(OUT / "belts_crane.png", dpi=100)


if __name__ == "__main__":
    crane()
