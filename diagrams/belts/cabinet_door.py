"""Cabinet door balancing (Ebert 6.4 / 7.2.1): synthesis -> contour table -> analysis -> residual.

Run from the repository root: ``python diagrams/belts/cabinet_door.py``.  Writes the contour table
``diagrams/belts/cabinet_door_contour.csv`` (``theta [rad], r [m]``, cam frame: the arc the band
touches, spring pivot B0 as in the thesis), the closed contour ``cabinet_door_cam.csv`` of the guided
version the scene ``cabinet_door.yaml`` simulates (band in a fixed direction), and the figure
``docs/figures/belts_cabinet_door.png``; prints the assessments and the residual torques.
"""
from pathlib import Path

import numpy as np

from elements.belt_synthesis import (DBSD, CabinetDoor, band_curve, close_contour, read_contour_table,
                                     spring_band_analysis, synthesise_contour, write_contour_table)
from multipole import pipeline, plotting
from multipole.netlist import load

HERE = Path(__file__).resolve().parent
TABLE = HERE / "cabinet_door_contour.csv"
CAM = HERE / "cabinet_door_cam.csv"
SCENE = HERE / "cabinet_door.yaml"
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


def guided_cam(door=CabinetDoor(), table=CAM, n=1201):
    """The guided version (band leaving horizontally, DB~SD with the spring pivot at infinity):
    its contour, closed convexly (:func:`close_contour`), written to ``table``."""
    bal = door.balance(MARGIN)
    phi = np.linspace(-MARGIN, door.travel + MARGIN, n)
    curve = band_curve(DBSD(door.p1, None, K=1, gamma=0.0).trace(phi, bal.x))
    write_contour_table(table, close_contour(curve))
    return curve


def simulate_scene(door=CabinetDoor()):
    """Run cabinet_door.yaml; returns (phi, spring torque F1*h1, gravity torque m g L cos psi)."""
    res = pipeline.run(load(SCENE), progress=False)
    phi = res.outputs["cam.phi"]
    return phi, res.outputs["cam.F1"] * res.outputs["cam.h1"], door.m * door.g * door.L * np.cos(door.psi_open - phi)


def figure(door=CabinetDoor()):
    bal, syn = synthesise(door)
    phi, an, grav = analyse(door)
    guided = guided_cam(door)
    phs, ts, gs = simulate_scene(door)
    fig = plotting.new_figure(14, 8)
    grid = fig.add_gridspec(2, 6)
    ax1, ax5, ax2 = (fig.add_subplot(grid[0, 2 * k:2 * k + 2]) for k in range(3))
    ax3, ax4 = fig.add_subplot(grid[1, :3]), fig.add_subplot(grid[1, 3:])
    c, e = syn.curve.contour, syn.curve.involute
    ax1.plot(c[:, 0] * 1e3, c[:, 1] * 1e3, "k-", lw=2, label="contour (evolute)")
    ax1.plot(e[:, 0] * 1e3, e[:, 1] * 1e3, "C0--", lw=1, label="band point (involute)")
    for k in np.linspace(0, len(c) - 1, 7).astype(int):       # band from contact toward the spring
        ax1.plot([c[k, 0] * 1e3, e[k, 0] * 1e3], [c[k, 1] * 1e3, e[k, 1] * 1e3], "C1-", lw=0.7)
    ax1.plot([0], [0], "k+", ms=10)
    ax1.set(xlabel="x [mm] (cam frame)", ylabel="y [mm]", title="synthesised cam contour, DB~SD", aspect="equal")
    deg = np.degrees(phi)
    ax2.plot(deg, bal.x(phi) * 1e3, label="spring travel x_S [mm]")
    ax2.plot(deg, bal.x(phi, 1) * 1e3, label="lever arm h = x_S' [mm]")
    ax2.plot(deg, grav * 10, label="gravity torque x10 [N m]")
    ax2.set(xlabel="drive angle phi [deg] (0: door open)", title="transfer functions (ch. 6 quadrature)")
    ax2.legend(fontsize=8)
    ax3.plot(deg, (an.torque - grav) * 1e12, "k.-", ms=3)
    ax3.set(xlabel="drive angle phi [deg]", ylabel="spring torque - gravity torque [pN m]",
            title="residual torque through the contour table")
    th, r = read_contour_table(CAM)
    ax5.plot(r * np.cos(th) * 1e3, r * np.sin(th) * 1e3, "k-", lw=1, label="closed cam (table of the scene)")
    g = guided.contour
    ax5.plot(g[:, 0] * 1e3, g[:, 1] * 1e3, "C3-", lw=2.5, alpha=0.6, label="synthesised arc (band touches)")
    ax5.plot([0], [0], "k+", ms=10)
    ax5.set(xlabel="x [mm] (cam frame)", ylabel="y [mm]", aspect="equal",
            title="guided band (scene): closed convex cam")
    ax5.legend(fontsize=8, loc="lower right")
    ax4.plot(np.degrees(phs), (ts - gs) * 1e3, "k.-", ms=3)
    ax4.set(xlabel="drive angle phi [deg]", ylabel="F1 h1 - gravity torque [mN m]",
            title="scene cabinet_door.yaml (guided band, closed cam): residual")
    plotting.save(fig, FIGURE)
    return syn, an, grav, (phs, ts, gs)


if __name__ == "__main__":
    syn, an, grav, (phs, ts, gs) = figure()
    print(syn.report())
    print(f"scene: largest |F1 h1 - m g L cos psi| {np.max(np.abs(ts - gs)):.3g} N m over {len(phs)} outputs")
    print(f"largest residual torque {np.max(np.abs(an.torque - grav)):.3g} N m "
          f"(gravity torque up to {np.max(grav):.4g} N m); lever arm {np.min(an.h) * 1e3:.4g} .. "
          f"{np.max(an.h) * 1e3:.4g} mm; table {TABLE.name}, figure {FIGURE.name}")
