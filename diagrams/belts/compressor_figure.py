"""The compressor figure of docs/belts.md (Ebert 2015, section 8.2): strand forces, tensioner angle,
speeds and the speed ratio against the slip-free ratio r_M/r_P.

Run from the repository root: ``python diagrams/belts/compressor_figure.py`` (writes
docs/figures/belts_compressor.png and the drawing docs/figures/belts_compressor_drawing.png, the
figure of ``multipole draw diagrams/belts/compressor.yaml --t-end 2.1 --at 0,2.1``).
"""
from pathlib import Path

import numpy as np

from multipole import pipeline
from multipole.drawing import mechanism_figure, sample
from multipole.netlist import load
from multipole.plotting import new_figure, save

HERE = Path(__file__).resolve().parent
OUT = HERE.parents[1] / "docs" / "figures"


def compressor():
    res = pipeline.run(load(HERE / "compressor.yaml"), progress=False)
    t, o = res.t, res.outputs
    fig = new_figure(11, 7)
    ax = fig.subplots(2, 2)
    for name, label in (("tight", "tight span P -> M"), ("span2", "span M -> tensioner"),
                        ("span3", "span tensioner -> P")):
        ax[0, 0].plot(t, o[f"{name}.F"], lw=0.8, label=label)
    ax[0, 0].set(xlabel="t [s]", ylabel="strand force [N]", title="strand forces (clutch closed 2 s - 10 s)")
    ax[0, 0].legend(fontsize=8)
    ax[0, 1].plot(t, np.degrees(o["lever.phi"]), lw=0.8)
    ax[0, 1].set(xlabel="t [s]", ylabel="lever angle [deg]", title="tensioner lever")
    for name, label in (("motor.omega", "motor"), ("M.omega", "motor pulley M"), ("P.omega", "compressor pulley P")):
        ax[1, 0].plot(t, o[name], lw=0.8, label=label)
    ax[1, 0].set(xlabel="t [s]", ylabel="angular velocity [rad/s]", title="speeds")
    ax[1, 0].legend(fontsize=8)
    run = (t > 2.5) & (t < 10.0)
    ax[1, 1].plot(t[run], o["P.omega"][run] / o["M.omega"][run], lw=0.8, label="omega_P / omega_M")
    ax[1, 1].axhline(0.05 / 0.15, color="k", ls=":", label="slip-free r_M / r_P = 1/3")
    ax[1, 1].set(xlabel="t [s]", ylabel="omega_P / omega_M [-]", title="speed ratio while driven")
    ax[1, 1].set_ylim(0.3330, 0.3342)
    ax[1, 1].legend(fontsize=8, loc="upper right")
    save(fig, OUT / "belts_compressor.png", dpi=110)
    return res


def drawing():
    scene = load(HERE / "compressor.yaml")
    res, drawn = sample(scene, t_end=2.1)
    mechanism_figure(res, drawn, OUT / "belts_compressor_drawing.png", at=[0.0, 2.1], title="compressor")


if __name__ == "__main__":
    compressor()
    drawing()
