"""Pitch curves of the toothed belt with two non-circular wheels (Ebert 7.3.2) and its figure.

    python diagrams/belts/toothed_belt_design.py          # writes the two tables and the figure

Design (derivation in docs/belts.md, "Toothed belt with two non-circular wheels"): wheel 1 (small,
driving) turns phi1, wheel 2 phi2; the prescribed ratio is i(phi1) = phi1'/phi2' = c (1 + e cos 2 phi1)
with e = 0.2 (i_max/i_min = 1.5) and c = 2/sqrt(1 - e^2) (wheel 2 turns once per two turns of
wheel 1: mean ratio 2:1).  Both pitch curves are centrally symmetric, so the upper and the lower
span see the same lever arms and one rolling condition serves both spans:

    p2(nu)                   = R2 (1 + e2 cos 4 nu)                    (wheel 2, four gentle lobes)
    p1(pi/2 - phi1)          = p2(pi/2 - phi2(phi1)) / i(phi1)         (wheel 1, two lobes)
    phi2(phi1)               = (1/2) atan2(q sin phi1, cos phi1) unwrapped, q = sqrt((1 - e)/(1 + e))

p are support functions (lever arms), turned into polar tables by the contact point p e + p' e'.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from elements.belt_contour import Contour, read_table  # noqa: E402
# the design (ratio, pitch curves, tables) lives in the package, so that the default bench set
# (multipole.bench_scenes) writes the same tables an installed package has no diagrams/ to read from
from multipole_models.toothed_belt import A, phi2_of, ratio, table_texts  # noqa: E402,F401


def tables(out=HERE):
    """Write toothed_belt_wheel1.csv and toothed_belt_wheel2.csv (polar, roll frame)."""
    for name, text in table_texts().items():
        (out / name).write_text(text, encoding="utf-8")


def open_belt_length(c1: Contour, c2: Contour, phi1, phi2):
    """Length [m] of the real open belt around the two pitch curves (centres (0, 0) and (A, 0)):
    the two common outer tangents (normal angles alpha near +-pi/2, solved by Newton) plus the arcs."""
    def tangent(alpha):              # the line n(alpha).x = p1 = A cos(alpha) + p2 touches both
        for _ in range(50):
            f = c1.support(alpha - phi1) - c2.support(alpha - phi2) - A * math.cos(alpha)
            d = slope(c1, alpha - phi1) - slope(c2, alpha - phi2) + A * math.sin(alpha)
            alpha -= f / d
            if abs(f) < 1e-15:
                break
        return alpha
    up, down = tangent(math.pi / 2), tangent(-math.pi / 2)
    # contact points along the tangent t = (-sin, cos): p1' on wheel 1, -A sin(alpha) + p2' on wheel 2
    seg = lambda al: abs(-A * math.sin(al) + slope(c2, al - phi2) - slope(c1, al - phi1))
    arc1 = c1.arc(down + 2 * math.pi - phi1) - c1.arc(up - phi1)          # around the left
    arc2 = c2.arc(up - phi2) - c2.arc(down - phi2)                        # around the right
    return float(arc1 + arc2 + seg(up) + seg(down))


def slope(c: Contour, nu):
    """dp/dnu [m] of a contour's support function: r sin(theta - nu) at the contact point."""
    th = c.contact(nu)
    return float(c.radius(th) * np.sin(th - nu))


def simulate():
    """The scene's run: wheel angles, speeds and strand forces over 720 deg of wheel 1."""
    from multipole import pipeline
    from multipole.netlist import load
    return pipeline.run(load(HERE / "toothed_belt.yaml"), progress=False)


def figure(res, path=HERE.parents[1] / "docs" / "figures" / "belts_toothed_belt.png"):
    """Pitch curves, ratio over the drive angle (prescribed and simulated), strand forces."""
    from multipole.plotting import new_figure, save
    c1, c2 = read_table(HERE / "toothed_belt_wheel1.csv"), read_table(HERE / "toothed_belt_wheel2.csv")
    fig = new_figure(15, 4.4)
    ax1, ax2, ax3 = fig.subplots(1, 3)
    th = np.linspace(0, 2 * math.pi, 721)
    for c, x0, label in ((c1, 0.0, "wheel 1 (driving)"), (c2, A, "wheel 2")):
        r = c.radius(th)
        ax1.plot(x0 + r * np.cos(th), r * np.sin(th), label=label)
        ax1.plot([x0], [0], "k+")
    for y in (1, -1):                                   # the model's parallel spans at phi = 0
        ax1.plot([0, A], [y * c1.support(y * math.pi / 2), y * c2.support(y * math.pi / 2)], "k:", lw=1)
    ax1.set_aspect("equal")
    ax1.set_xlabel("x [m]")
    ax1.set_ylabel("y [m]")
    ax1.set_title("pitch curves at phi = 0 (centre distance 0.8 m)")
    ax1.legend(loc="upper center", fontsize=8)
    o = res.outputs
    deg = np.degrees(o["wheel1.phi"])
    ax2.plot(deg, ratio(o["wheel1.phi"]), "k-", lw=4, alpha=0.3, label="prescribed i(phi1)")
    ax2.plot(deg, o["wheel1.omega"] / o["wheel2.omega"], "C3-", lw=1, label="simulated omega1/omega2")
    ax2.set_xlabel("drive angle phi1 [deg]")
    ax2.set_ylabel("ratio i [-]")
    ax2.set_title("ratio (i_max/i_min = 1.5, mean 2)")
    ax2.legend(fontsize=8)
    ax3.plot(deg, o["top.F"], label="upper span (tight: load on wheel 2)")
    ax3.plot(deg, o["bottom.F"], label="lower span")
    ax3.set_xlabel("drive angle phi1 [deg]")
    ax3.set_ylabel("strand force [N]")
    ax3.set_title("strand forces (EA = 1e5 N, cd = 50 N s)")
    ax3.legend(fontsize=8)
    save(fig, path, dpi=100)


def length_error(n=145):
    """Largest change [m] of the real open belt's length over one turn of wheel 2 (the model's
    spans are parallel; the real ones are the common tangents), and the mean length [m]."""
    c1, c2 = read_table(HERE / "toothed_belt_wheel1.csv"), read_table(HERE / "toothed_belt_wheel2.csv")
    phi1 = np.linspace(0, 4 * math.pi, n)
    L = np.array([open_belt_length(c1, c2, p, float(phi2_of(p))) for p in phi1])
    return float(L.max() - L.min()), float(L.mean())


if __name__ == "__main__":
    tables()
    figure(simulate())
    dL, L = length_error()
    print(f"tables and figure written; real open belt: length {L:.6f} m, changes by {dL * 1e3:.3f} mm over a turn")
