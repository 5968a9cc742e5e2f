"""DB~DS with the slider in the frame (Ebert 7.2.2): synthesis -> contour table -> analysis round trip.

Run from the repository root: ``python diagrams/belts/db_ds_slider.py``.  Writes the engaged arc
``diagrams/belts/db_ds_slider_contour.csv`` and the closed cam ``db_ds_slider_cam.csv`` (``theta
[rad], r [m]``, cam frame), the figure ``docs/figures/belts_db_ds_slider.png``, and prints the
assessment and the round trip's largest slider error.

The scene (numbers Ebert gives: horizontal guide through the cam pivot P1, slider start xS0 =
100 mm, band wound on by a counter-clockwise cam, a 5th-degree transition between two constant
speeds; the rest is ours, Bild 7.15 is missing): the cam turns clockwise (K = -1) by the drive
angle phi = 0 .. 2.9 rad and pays the band out, a load on the slider keeps it taut; the slider
runs 0.05 m/rad up to phi = 0.3 rad, the quintic transition (speed 0.05 + 0.075 (10 s^3 - 15 s^4
+ 6 s^5) m/rad, s = (phi - 0.3)/2) up to 2.3 rad, then 0.125 m/rad.

The round trip (:func:`slider_through_table`) does not use the synthesis: it reads the closed cam
table as a curve roll does (``elements.belt_contour.Contour``: periodic C2 spline, support function,
arc length) and, for every cam angle, places the slider where the band, tangent to the contour,
keeps its length (free span + the arc wrapped on the cam).  The network elements cannot simulate
this scene yet: a span of varying inclination on a curve contour needs a planar curve span
(``planar_band`` takes circles only); see docs/belts.md.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import optimize

from elements.belt_contour import read_table
from elements.belt_synthesis import DBDS, DBSD, Transfer, band_curve, close_contour, synthesise_contour, \
    write_contour_table

HERE = Path(__file__).resolve().parent
ARC = HERE / "db_ds_slider_contour.csv"
CAM = HERE / "db_ds_slider_cam.csv"
GUIDED_CAM = HERE / "db_ds_slider_guided_cam.csv"
GUIDED_SCENE = HERE / "db_ds_slider_guided.yaml"
FIGURE = HERE.parents[1] / "docs" / "figures" / "belts_db_ds_slider.png"


@dataclass(frozen=True)
class SliderScene:
    """Ebert 7.2.2 as numbers [m, rad]: slider start ``x0`` (his xS0 = 100 mm), the slider speeds
    ``a1``, ``a2`` [m/rad] before and after the quintic transition over ``phi1`` .. ``phi2``, the
    drive range 0 .. ``phi_end``, the cam's turning sense ``K`` (-1: clockwise, paying out) and the
    side of the guide the band leaves the cam on (``side`` = +1: above; a mounting choice like
    Ebert's half-plane)."""

    x0: float = 0.1
    a1: float = 0.05
    a2: float = 0.125
    phi1: float = 0.3
    phi2: float = 2.3
    phi_end: float = 2.9
    K: int = -1
    side: int = 1

    def transfer(self) -> Transfer:
        """Slider position x(phi) [m] from P1 along the guide and its derivatives (closed form)."""
        a1, da, p1, T = self.a1, self.a2 - self.a1, self.phi1, self.phi2 - self.phi1

        def s(phi):
            return np.clip((np.asarray(phi, float) - p1) / T, 0.0, 1.0)

        def inside(phi):
            return (np.asarray(phi, float) > p1) & (np.asarray(phi, float) < p1 + T)

        def x(phi):
            q = s(phi)      # integral of the smoothstep over the transition, then the straight part
            extra = np.maximum(np.asarray(phi, float) - p1 - T, 0.0)
            return self.x0 + a1 * np.asarray(phi, float) + da * ((2.5 * q ** 4 - 3 * q ** 5 + q ** 6) * T + extra)

        return Transfer(x,
                        lambda phi: a1 + da * (10 * s(phi) ** 3 - 15 * s(phi) ** 4 + 6 * s(phi) ** 5),
                        lambda phi: da * 30 * s(phi) ** 2 * (1 - s(phi)) ** 2 / T * inside(phi),
                        lambda phi: da * (60 * s(phi) - 180 * s(phi) ** 2 + 120 * s(phi) ** 3) / T ** 2 * inside(phi))

    def structure(self) -> DBDS:
        """The slider on the horizontal guide through the cam pivot (0, 0)."""
        return DBDS((0.0, 0.0), None, 0.0, K=self.K)


def synthesise(scene=SliderScene(), n=1201, arc=ARC, cam=CAM):
    """The contour for the scene's transfer function: the arc (written to ``arc``), closed convexly
    (written to ``cam``); returns the :class:`~elements.belt_synthesis.Synthesis`."""
    phi = np.linspace(0.0, scene.phi_end, n)
    syn = synthesise_contour(scene.structure(), scene.transfer(), phi, arc)
    write_contour_table(cam, close_contour(syn.curve))
    return syn


def guided_cam(scene=SliderScene(), table=GUIDED_CAM, n=1201, margin=0.05):
    """The 1-D limit of the scene (``db_ds_slider_guided.yaml``): the guide parallel to the band, so
    the band keeps its direction (DB~SD with the pivot at infinity, horizontal band below the axis
    as in cabinet_door.yaml) and the band travel onto the cam is the slider's travel x(phi) - x0;
    the cam winds counter-clockwise.  Synthesised a little beyond 0 .. phi_end, closed convexly,
    written to ``table``; returns the band curve."""
    x = scene.transfer()
    travel = Transfer(lambda p: x(p) - scene.x0, lambda p: x(p, 1), lambda p: x(p, 2), lambda p: x(p, 3))
    phi = np.linspace(-margin, scene.phi_end + margin, n)
    curve = band_curve(DBSD((0.0, 0.0), None, K=1, gamma=0.0).trace(phi, travel))
    write_contour_table(table, close_contour(curve))
    return curve


def run_guided(scene_file=GUIDED_SCENE):
    """Run db_ds_slider_guided.yaml; returns (phi [rad], slider travel toward the cam [m] from the
    spring's deflection, band stretch [m], the run's outputs)."""
    from multipole import pipeline
    from multipole.netlist import load

    res = pipeline.run(load(scene_file), progress=False)
    o = res.outputs
    return o["cam.phi"], -(o["spring.deflection"] - o["spring.deflection"][0]), o["band.stretch"], o


def slider_through_table(table, phi, x0: float, K: int = -1, side: int = 1):
    """Slider positions [m] a contour table makes for the cam angles K*phi [rad] (analysis, Ebert
    4.4.5 geometry): the band from the joint S = (x, 0) is tangent to the contour turned by K*phi
    about the origin (support function p: x cos(nu + K phi) = p(nu), nu the contour normal in the
    cam frame) and its length, free span |S - C| plus the arc S(nu) wrapped on the contour, keeps
    the value it has at the start x(phi[0]) = ``x0``.  Returns ``(x, theta)``, theta the contact
    point's polar angle in the cam frame [rad] (to check that the band stays on the synthesised arc)."""
    cont = read_table(table)
    c0 = K * float(phi[0])

    def place(nu, c):
        """Joint position x, contact point C (frame) and free length for the tangent of normal nu."""
        x = float(cont.support(nu)) / math.cos(nu + c)
        th = float(cont.contact(nu))
        rr = float(cont.radius(th))
        C = rr * np.array([math.cos(th + c), math.sin(th + c)])
        return x, C, float(np.hypot(x - C[0], C[1])), th

    # the start: the tangents from S0 = (x0, 0); the one touching on the band's side of the guide
    grid = np.linspace(-math.pi, math.pi, 721)
    f = x0 * np.cos(grid + c0) - cont.support(grid)
    roots = [optimize.brentq(lambda n: x0 * math.cos(n + c0) - float(cont.support(n)), grid[k], grid[k + 1],
                             xtol=1e-15) for k in np.flatnonzero(np.sign(f[:-1]) != np.sign(f[1:]))]
    nu = next(n for n in roots if side * place(n, c0)[1][1] > 0)
    x, C, free, th = place(nu, c0)
    tau = np.array([-math.sin(nu + c0), math.cos(nu + c0)])      # the contour's counter-clockwise tangent
    sigma = 1.0 if (np.array([x, 0.0]) - C) @ tau > 0 else -1.0   # + : wrapped arc ends at S(nu)
    length = free + sigma * float(cont.arc(nu))
    xs, ths = [], []
    for p in phi:
        c = K * float(p)
        nu = optimize.newton(lambda n: place(n, c)[2] + sigma * float(cont.arc(n)) - length, nu, tol=1e-14,
                             maxiter=100)
        x, _, _, th = place(nu, c)
        xs.append(x)
        ths.append(th)
    return np.array(xs), np.array(ths)


def figure(scene=SliderScene(), syn=None, path=FIGURE):
    """Contour with the band at a few angles, and the slider travel through the table vs the
    prescribed one."""
    import matplotlib.pyplot as plt

    syn = syn or synthesise(scene)
    phi = np.linspace(0.0, scene.phi_end, 59)
    x, _ = slider_through_table(CAM, phi, scene.x0, scene.K, scene.side)
    xp = scene.transfer()(phi)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.6))
    cam = read_table(CAM)
    t = np.linspace(cam.theta[0], cam.theta[0] + 2 * math.pi, 721)
    ax1.plot(cam.radius(t) * np.cos(t), cam.radius(t) * np.sin(t), color="0.6", label="closed cam (table)")
    c = syn.curve.contour
    ax1.plot(c[:, 0], c[:, 1], "C0", lw=2, label="synthesised arc")
    e = syn.curve.involute
    ax1.plot(e[:, 0], e[:, 1], "C1--", lw=1, label="slider joint seen from the cam (involute)")
    for k in range(0, len(syn.curve.phi), 300):
        ax1.plot([c[k, 0], e[k, 0]], [c[k, 1], e[k, 1]], "C2", lw=0.8)
    ax1.plot(0, 0, "k+")
    ax1.set_aspect("equal")
    ax1.set_xlabel("x [m] (cam frame)")
    ax1.set_ylabel("y [m]")
    ax1.set_title("DB~DS cam (Ebert 7.2.2), band at 5 angles")
    ax1.legend(fontsize=7, loc="lower left")
    ax2.plot(phi, xp, "k-", label="prescribed x(phi)")
    ax2.plot(phi, x, "C3o", ms=3, label="through the cam table")
    ax2.set_xlabel("drive angle phi [rad] (cam turns clockwise)")
    ax2.set_ylabel("slider position x [m]")
    ax3 = ax2.twinx()
    ax3.plot(phi, (x - xp) * 1e6, "C0", lw=0.8)
    ax3.set_ylabel("difference [um]", color="C0")
    ax2.legend(loc="upper left", fontsize=8)
    ax2.set_title("slider travel: round trip")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


if __name__ == "__main__":
    s = SliderScene()
    result = synthesise(s)
    print(result.report())
    guided_cam(s)
    ph = np.linspace(0.0, s.phi_end, 59)
    xt, _ = slider_through_table(CAM, ph, s.x0, s.K, s.side)
    print(f"round trip: largest slider error {np.max(np.abs(xt - s.transfer()(ph))):.3g} m")
    print("figure:", figure(s, result))
