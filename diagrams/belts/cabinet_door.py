"""Cabinet door balancing (Ebert 6.4 / 7.2.1): synthesis -> contour table -> analysis -> residual.

Run from the repository root: ``python diagrams/belts/cabinet_door.py``.  Writes the contour table
``diagrams/belts/cabinet_door_contour.csv`` (``theta [rad], r [m]``, cam frame) and the figure
``docs/figures/belts_cabinet_door.png``, and prints the assessment and the residual torque.
"""
from pathlib import Path

import numpy as np

from elements.belt_synthesis import CabinetDoor, spring_band_analysis, synthesise_contour
from multipole import plotting

HERE = Path(__file__).resolve().parent
TABLE = HERE / "cabinet_door_contour.csv"
FIGURE = HERE.parents[1] / "docs" / "figures" / "belts_cabinet_door.png"
MARGIN = 0.05    # rad: the contour is synthesised a little beyond the door's travel


def synthesise(door=CabinetDoor(), table=TABLE, n=1201):
    """The door's spring travel, its contour (written to ``table``) and the synthesis result."""
    bal = door.balance(MARGIN)
    phi = np.linspace(-MARGIN, door.travel + MARGIN, n)
    syn = synthesise_contour(door.structure(), bal.x, phi, table, torque=door.torque())
    return bal, syn


def analyse(door=CabinetDoor(), table=TABLE, n=121):
    """Spring torque through the contour table over the travel and the door's gravity torque
    m g L cos(psi) (closed form); returns (phi, analysis, gravity torque)."""
    phi = np.linspace(0.0, door.travel, n)
    an = spring_band_analysis(table, phi, door.p1, door.p2, door.c, door.x_start, K=door.K)
    psi = door.psi_open - phi
    return phi, an, door.m * door.g * door.L * np.cos(psi)


def figure(door=CabinetDoor()):
    bal, syn = synthesise(door)
    phi, an, grav = analyse(door)
    fig = plotting.new_figure(12, 4.2)
    ax1, ax2, ax3 = fig.subplots(1, 3)
    c, e = syn.curve.contour, syn.curve.involute
    ax1.plot(c[:, 0] * 1e3, c[:, 1] * 1e3, "k-", lw=2, label="contour (evolute)")
    ax1.plot(e[:, 0] * 1e3, e[:, 1] * 1e3, "C0--", lw=1, label="band point (involute)")
    for k in np.linspace(0, len(c) - 1, 7).astype(int):       # band from contact toward the spring
        ax1.plot([c[k, 0] * 1e3, e[k, 0] * 1e3], [c[k, 1] * 1e3, e[k, 1] * 1e3], "C1-", lw=0.7)
    ax1.plot([0], [0], "k+", ms=10)
    ax1.set(xlabel="x [mm] (cam frame)", ylabel="y [mm]", title="synthesised cam contour, DB~SD", aspect="equal")
    ax1.legend(fontsize=8, loc="lower left")
    deg = np.degrees(phi)
    ax2.plot(deg, bal.x(phi) * 1e3, label="spring travel x_S [mm]")
    ax2.plot(deg, bal.x(phi, 1) * 1e3, label="lever arm h = x_S' [mm]")
    ax2.plot(deg, grav * 10, label="gravity torque x10 [N m]")
    ax2.set(xlabel="drive angle phi [deg] (0: door open)", title="transfer functions (ch. 6 quadrature)")
    ax2.legend(fontsize=8)
    ax3.plot(deg, (an.torque - grav) * 1e12, "k.-", ms=3)
    ax3.set(xlabel="drive angle phi [deg]", ylabel="spring torque - gravity torque [pN m]",
            title="residual torque through the contour table")
    plotting.save(fig, FIGURE)
    return syn, an, grav


if __name__ == "__main__":
    syn, an, grav = figure()
    print(syn.report())
    print(f"largest residual torque {np.max(np.abs(an.torque - grav)):.3g} N m "
          f"(gravity torque up to {np.max(grav):.4g} N m); lever arm {np.min(an.h) * 1e3:.4g} .. "
          f"{np.max(an.h) * 1e3:.4g} mm; table {TABLE.name}, figure {FIGURE.name}")
