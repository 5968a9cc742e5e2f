"""Figure and figures of merit of the planar toothed belt (``toothed_belt_planar.yaml``).

    python diagrams/belts/toothed_belt_planar_figure.py      # writes docs/figures/belts_toothed_belt_planar.png

Left: the pitch curves and the spans on their real common tangents at three instants (the contact
points the model computes). Middle: the ratio omega1/omega2 of the planar model, of the 1-D scene
(``toothed_belt.yaml``, horizontal spans) and the synthesis input i(phi1) = c (1 + e cos 2 phi1).
Right: the strand forces of both models.  Printed: the real belt length's variation over a turn of
wheel 1 (spans + the arcs wrapped on the wheels) and the ratio's deviation from the input.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from elements.belt_contour import read_table  # noqa: E402
from multipole import pipeline  # noqa: E402
from multipole.netlist import load  # noqa: E402

OUT = ["wheel1.phi", "wheel1.omega", "wheel2.phi", "wheel2.omega", "top.F", "bottom.F", "top.gamma", "bottom.gamma",
       "top.length", "bottom.length", "wheel1.wrap", "wheel2.wrap", "top.xK1", "top.yK1", "top.xK2", "top.yK2",
       "bottom.xK1", "bottom.yK1", "bottom.xK2", "bottom.yK2"]


def figures_of_merit(res, wheels):
    """(real belt length [m] per output time, its variation over the first turn of wheel 1 [m],
    largest relative deviation of omega1/omega2 from the synthesis input after 0.2 s)."""
    o, t = res.outputs, res.t
    real = o["top.length"] + o["bottom.length"]
    leave = {"wheel1": (o["bottom.gamma"] + math.pi, o["top.gamma"]),
             "wheel2": (o["top.gamma"] + math.pi, o["bottom.gamma"])}
    for c, name in zip(wheels, ("wheel1", "wheel2")):
        nu_off = leave[name][0] - math.pi / 2 - o[f"{name}.phi"]
        nu_on = leave[name][1] + math.pi / 2 - o[f"{name}.phi"]
        real = real + c.arc(nu_on + np.mod(nu_off - nu_on, 2 * math.pi)) - c.arc(nu_on)
    turn = t <= 1.0 + 1e-12
    e, c = 0.2, 2 / math.sqrt(1 - 0.2 ** 2)
    late = t > 0.2
    ratio = o["wheel1.omega"] / o["wheel2.omega"]
    dev = np.max(np.abs(ratio[late] / (c * (1 + e * np.cos(2 * o["wheel1.phi"][late]))) - 1))
    return real, float(np.ptp(real[turn])), float(dev)


def main():
    import matplotlib.pyplot as plt

    wheels = [read_table(HERE / f"toothed_belt_wheel{k}.csv") for k in (1, 2)]
    res = pipeline.run(load(HERE / "toothed_belt_planar.yaml"), progress=False, outputs=OUT)
    flat = pipeline.run(load(HERE / "toothed_belt.yaml"), progress=False)
    real, var, dev = figures_of_merit(res, wheels)
    o, t = res.outputs, res.t
    print(f"real belt length {np.mean(real):.4f} m, variation over a turn of wheel 1 {var * 1e3:.2f} mm "
          f"({var / np.mean(real) * 100:.3f} %); ratio against the synthesis input: largest deviation {dev:.3f}; "
          f"strand forces {min(o['top.F'].min(), o['bottom.F'].min()):.0f} .. "
          f"{max(o['top.F'].max(), o['bottom.F'].max()):.0f} N; "
          f"wheel 2 turned {math.degrees(o['wheel2.phi'][-1]):.2f} deg")
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.6))
    th = np.linspace(0, 2 * math.pi, 721)
    for k, colour in zip(np.searchsorted(t, [0.0, 0.125, 0.25]), ("C0", "C1", "C2")):
        for c, centre, name in zip(wheels, ((0.0, 0.0), (0.8, 0.0)), ("wheel1", "wheel2")):
            r, ph = c.radius(th), o[f"{name}.phi"][k]
            ax[0].plot(centre[0] + r * np.cos(th + ph), centre[1] + r * np.sin(th + ph), color=colour, lw=0.8)
        for span in ("top", "bottom"):
            ax[0].plot([o[f"{span}.xK1"][k], o[f"{span}.xK2"][k]], [o[f"{span}.yK1"][k], o[f"{span}.yK2"][k]],
                       color=colour, lw=1.2, label=f"t = {t[k]:.3f} s" if span == "top" else None)
    ax[0].set_aspect("equal")
    ax[0].set_xlabel("x [m]")
    ax[0].set_ylabel("y [m]")
    ax[0].set_title("pitch curves and the spans on their tangents")
    ax[0].legend(fontsize=8, loc="lower center")
    e, c = 0.2, 2 / math.sqrt(1 - 0.2 ** 2)
    deg = np.degrees(o["wheel1.phi"])
    ax[1].plot(deg, o["wheel1.omega"] / o["wheel2.omega"], label="planar model")
    ax[1].plot(np.degrees(flat.outputs["wheel1.phi"]), flat.outputs["wheel1.omega"] / flat.outputs["wheel2.omega"],
               "--", label="1-D model (horizontal spans)")
    ax[1].plot(deg, c * (1 + e * np.cos(2 * o["wheel1.phi"])), ":", color="k", label="synthesis input i(phi1)")
    ax[1].set_xlabel("phi1 [deg]")
    ax[1].set_ylabel("omega1/omega2")
    ax[1].set_title("ratio")
    ax[1].legend(fontsize=8)
    ax[2].plot(t, o["top.F"], label="top (planar)")
    ax[2].plot(t, o["bottom.F"], label="bottom (planar)")
    ax[2].plot(flat.t, flat.outputs["top.F"], "--", label="top (1-D)")
    ax[2].plot(flat.t, flat.outputs["bottom.F"], "--", label="bottom (1-D)")
    ax[2].set_xlabel("t [s]")
    ax[2].set_ylabel("F [N]")
    ax[2].set_title("strand forces")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    out = HERE.parents[1] / "docs" / "figures" / "belts_toothed_belt_planar.png"
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
