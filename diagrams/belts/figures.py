"""The figures of docs/belts.md: pulley-block strand forces and efficiency over mu, belt-drive spans.

Run from the repository root: ``python diagrams/belts/figures.py`` (writes docs/figures/belts_*.png).
"""
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from multipole import pipeline
from multipole.netlist import load

HERE = Path(__file__).resolve().parent
OUT = HERE.parents[1] / "docs" / "figures"
W = 100.0 * 9.81


def k(r, mu, r_pin=0.004):
    return (r + mu * r_pin) / (r - mu * r_pin)


def pulley_block():
    res = pipeline.run(load(HERE / "pulley_block.yaml"), progress=False)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    for n in "ABCDE":
        ax1.plot(res.t, res.outputs[f"{n}.F"], label=f"section {n}")
    ax1.set(xlabel="t [s]", ylabel="rope force [N]", title="pulley block, mu = 0.25: strand forces")
    ax1.legend()
    mus = np.linspace(0.0, 0.4, 9)
    eta_sim, util = [], []
    for mu in mus:
        r = pipeline.run(load(HERE / "pulley_block.yaml", {"mu": float(mu)}), progress=False)
        eta_sim.append(W / (4 * r.outputs["E.F"][-1]))
        util.append(r.outputs["A.F"][-1] / r.outputs["E.F"][-1])
    mu_f = np.linspace(0, 0.4, 100)
    ka, kb = k(0.05, mu_f), k(0.06, mu_f)
    eta = (1 + ka + ka * kb + ka * kb * ka) / (4 * ka * kb * ka * kb)
    ax2.plot(mu_f, eta, "k-", label="first principles (quasi-static)")
    ax2.plot(mus, eta_sim, "o", label="simulation, efficiency W/(4 F_E)")
    ax2.plot(mus, util, "s", mfc="none", label="simulation, F_A / F_E")
    ax2.set(xlabel="pin friction coefficient mu", ylabel="efficiency, force ratio [-]", title="efficiency (bolt 8 mm, r = 50/60 mm)")
    ax2.legend()
    fig.tight_layout()
    fig.savefig(OUT / "belts_pulley_block.png", dpi=110)


def belt_drive():
    res = pipeline.run(load(HERE / "belt_drive.yaml", {"rate": 2.5, "cd": 4.0}), t_end=20.0, progress=False)
    T = 2.5 * res.t
    EA, l, F0, r2 = 1.0e5, 0.8, 200.0, 0.1
    d0 = F0 * l / EA
    fig, ax = plt.subplots(figsize=(6.5, 4))
    ax.plot(T, res.outputs["tight.F"], label="tight span")
    ax.plot(T, res.outputs["slack.F"], label="slack span")
    ax.axvline(r2 * EA * 2 * d0 / (l - 2 * d0), color="k", ls=":", label="predicted slack onset T*")
    ax.set(xlabel="load torque on the driven pulley [N*m]", ylabel="span force [N]",
           title="two-pulley belt drive, pretension 200 N")
    ax.legend()
    fig.tight_layout()
    fig.savefig(OUT / "belts_belt_drive.png", dpi=110)


if __name__ == "__main__":
    pulley_block()
    belt_drive()
