"""The friction-drive figure of docs/belts.md: strand forces, tension ratio against exp(mu*wrap),
slip speeds of the two-pulley friction drive (diagrams/belts/friction_drive.yaml).

Run from the repository root: ``python diagrams/belts/friction_figure.py`` (writes
docs/figures/belts_friction_drive.png).
"""
from math import asin, exp, pi
from pathlib import Path

import matplotlib.pyplot as plt

from multipole import pipeline
from multipole.netlist import load

HERE = Path(__file__).resolve().parent
OUT = HERE.parents[1] / "docs" / "figures"


def friction_drive():
    res = pipeline.run(load(HERE / "friction_drive.yaml"), progress=False,
                       outputs=["tight.F", "slack.F", "p1.slip", "p2.slip", "p1.omega", "p2.omega"])
    mu, r1, r2, a = 0.3, 0.05, 0.1, 0.8
    wrap1, wrap2 = pi - 2 * asin((r2 - r1) / a), pi + 2 * asin((r2 - r1) / a)
    t_slip = [t for t, what in res.events if "p1.fr" in what][0]
    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(14, 4))
    ax1.plot(res.t, res["tight.F"], label="tight span")
    ax1.plot(res.t, res["slack.F"], label="slack span")
    ax1.set(xlabel="t [s]  (load torque 10 t N*m)", ylabel="span force [N]", title="strand forces")
    ratio = res["tight.F"] / res["slack.F"]
    ax2.plot(res.t, ratio, label="F_tight / F_slack")
    ax2.axhline(exp(mu * wrap1), color="k", ls="--",
                label=f"exp(mu wrap1) = {exp(mu * wrap1):.3f} (small pulley)")
    ax2.axhline(exp(mu * wrap2), color="gray", ls=":", label=f"exp(mu wrap2) = {exp(mu * wrap2):.3f} (large pulley)")
    ax2.set(xlabel="t [s]", ylabel="F_tight / F_slack [-]", title="tension ratio against Euler-Eytelwein",
            ylim=(0.9, 2.8))
    ax3.plot(res.t, res["p1.slip"], label="small pulley (driver)")
    ax3.plot(res.t, res["p2.slip"], label="large pulley (load)")
    ax3.set(xlabel="t [s]", ylabel="slip speed u - r omega [m/s]", title="slip (|slip| < v_s = 1e-4 m/s: sticking)")
    for ax in (ax1, ax2, ax3):
        ax.axvline(t_slip, color="r", lw=0.8, label=f"slip event t = {t_slip:.4f} s")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "belts_friction_drive.png", dpi=110)


if __name__ == "__main__":
    friction_drive()
