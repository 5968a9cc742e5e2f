"""Figures of docs/weber-gears.md: every ``docs/figures/gears_*.png``.

Run from anywhere (the paths are taken relative to this file)::

    python docs/scripts/make_gear_figures.py            # all figures
    python docs/scripts/make_gear_figures.py sliding    # only the ones whose name contains "sliding"

Each curve comes from a scene in ``diagrams/weber/`` run through the public API (``multipole.load``,
``multipole.pipeline.run``); the dashed curves are the hand calculations quoted in the page, with the
parameter values read from the same scene files.  Units: SI, plotted in ms, µrad, N/µm where marked.
"""
from __future__ import annotations

import sys

import matplotlib.pyplot as plt
import numpy as np

from figure_helpers import finish, main, parameters, run, save

DASHED = {"color": "k", "ls": "--", "lw": 0.9}


# -- 1. load sharing in the elastic power split (§6) ---------------------------------------------

def branch_compliance(c12, c34, r2, r3):
    """Compliance of one power-split branch referred to its first mesh [m/N]: 1/c12 + (r2/r3)²/c34."""
    return 1 / c12 + (r2 / r3) ** 2 / c34


def load_sharing():
    cases = [("equal paths (c12B = c12A)", "power_split_elastic.yaml", {"c12B": "2.0e8"}),
             ("path B softer: c12B = 1e8 N/m", "power_split_elastic.yaml", {}),
             ("mounting error x0 = 20 µm in mesh 12B", "power_split_mounting_error.yaml", {})]
    fig, axes = plt.subplots(1, 3, figsize=(12.5, 4.0))
    for ax, (title, scene, overrides) in zip(axes, cases):
        p = parameters(scene)
        p.update({k: float(v) for k, v in overrides.items()})
        res = run(scene, overrides, t_end=0.1, dt_out=5e-5)
        dA = branch_compliance(p["c12A"], p["c34A"], p["r2"], p["r3"])
        dB = branch_compliance(p["c12B"], p["c34B"], p["r2"], p["r3"])
        F = p["M"] * (1 - np.exp(-res.t / 0.01)) / p["r1"]           # the scene's torque M(1 − e^(−t/10 ms))
        preload = p.get("x0B", 0.0) / (dA + dB)
        FA, FB = F * dB / (dA + dB) - preload, F * dA / (dA + dB) + preload
        t = res.t * 1e3
        ax.plot(t, res["mesh12A.force"], lw=2.6, alpha=0.6, label="mesh 12A (simulated)")
        ax.plot(t, res["mesh12B.force"], lw=1.3, label="mesh 12B (simulated)")
        ax.plot(t, FA, **DASHED, label="quasi-static hand calculation")
        ax.plot(t, FB, **DASHED)
        simA, simB = res["mesh12A.force"][-1], res["mesh12B.force"][-1]
        if abs(simA - simB) < 1.0:
            ax.annotate(f"{simA:.0f} N each", (t[-1], simA), xytext=(-4, -14), textcoords="offset points",
                        ha="right", fontsize=8.5)
        else:
            for value, color in ((simA, "C0"), (simB, "C1")):
                ax.annotate(f"{value:.0f} N", (t[-1], value), xytext=(-4, 5 if value > min(simA, simB) else -14),
                            textcoords="offset points", ha="right", fontsize=8.5, color=color)
        if preload:
            # the assembly shock (the whole error starts in mesh 12B) is much larger than the
            # settled forces: clip it so that the split stays readable, and say how large it is
            lo, hi = min(FA.min(), FB.min()), max(FA.max(), FB.max())
            ax.set_ylim(lo - 0.8 * (hi - lo), hi + 0.6 * (hi - lo))
            peak = max(np.abs(res["mesh12A.force"]).max(), np.abs(res["mesh12B.force"]).max())
            ax.text(0.97, 0.04, f"assembly shock at t = 0 clipped\n(peak {peak / 1e3:.1f} kN)",
                    transform=ax.transAxes, ha="right", va="bottom", fontsize=8, color="0.35")
        else:
            ax.set_ylim(-30, 1.25 * max(FA.max(), FB.max()))
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("t [ms]")
        ax.set_ylabel("mesh force of the first stage [N]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="lower right")
    fig.suptitle("Power-split gear, all meshes elastic: the split follows the branch compliances "
                 "(each panel on its own scale)", fontsize=11)
    fig.tight_layout()
    save(fig, "gears_load_sharing.png")


# -- 2. quasi-static transmission error: smooth law and table (§3) -------------------------------

def transmission_error():
    smooth = parameters("spur_elastic_varying.yaml")
    table = parameters("spur_elastic_table.yaml")
    z1 = 20                                    # both scenes: z1: 20
    points = [1.1, 1.4]                        # spur_elastic_table.yaml: interp(acos(cos(q)), [1.1, 1.4], ...)
    fig, axes = plt.subplots(2, 2, figsize=(11.5, 5.8), sharex="col")
    cases = [
        ("c(q) = c0·(1 + ε·cos q)", "spur_elastic_varying.yaml", smooth,
         lambda q: smooth["c0"] * (1 + smooth["eps"] * np.cos(q)),
         smooth["M1"] / (smooth["r1"] * smooth["c0"] * (1 + smooth["eps"]))),
        ("table: c = interp(acos(cos q), [1.1, 1.4], [c1, c2]) (single/double contact)",
         "spur_elastic_table.yaml", table,
         lambda q: np.interp(np.abs(np.arctan2(np.sin(q), np.cos(q))), points, [table["c1"], table["c2"]]),
         table["M1"] / (table["r1"] * table["c1"])),
    ]
    for col, (title, scene, p, law, x0) in enumerate(cases):
        res = run(scene)
        q = res["mesh.phase"]
        teeth = q / (2 * np.pi)
        top, bottom = axes[0, col], axes[1, col]
        top.plot(teeth, res["mesh.stiffness"] / 1e6, lw=1.3, label="mesh.stiffness (simulated)")
        top.plot(teeth, law(q) / 1e6, **DASHED, label="law / table evaluated by numpy")
        lag = q / z1 - (p["w1"] * res.t - x0 / p["r1"])      # pinion angle against the unloaded rigid kinematics
        theory = p["M1"] / (p["r1"] ** 2 * law(q))
        bottom.plot(teeth, lag * 1e6, lw=2.5, alpha=0.55, label="simulated φ1 − φ1,rigid")
        bottom.plot(teeth, theory * 1e6, **DASHED, label="M1/(r1²·c(q))")
        for ax, values in ((top, law(q) / 1e6), (bottom, theory * 1e6)):
            lo, hi = values.min(), values.max()
            ax.set_ylim(lo - 0.08 * (hi - lo), hi + 0.45 * (hi - lo))          # headroom for the legend
            ax.legend(fontsize=8, loc="upper right", ncol=2)
            ax.grid(alpha=0.3)
        top.set_title(title, fontsize=10)
        bottom.set_xlabel("mesh phase q/2π [tooth engagements]")
    axes[0, 0].set_ylabel("mesh stiffness c(q) [N/µm]")
    axes[1, 0].set_ylabel("transmission error [µrad]")
    fig.suptitle("Time-varying mesh stiffness: quasi-static transmission error (constant torque, slow rotation)",
                 fontsize=11)
    fig.tight_layout()
    save(fig, "gears_transmission_error.png")


# -- 3. level normal: contact point, sliding, friction, normal force (§4) ------------------------

def normal_sliding():
    res = run("spur_normal.yaml", t_end=0.2, dt_out=2e-5)
    sel = res.t >= 0.17
    t = res.t[sel] * 1e3
    s = res["mesh.contact_position"][sel]
    w1, w2 = res["pinion.omega"][sel], res["wheel.omega"][sel]
    fig, axes = plt.subplots(4, 1, figsize=(8.5, 8.2), sharex=True)
    axes[0].plot(t, s * 1e3)
    axes[0].axhline(0, color="0.5", lw=0.7)
    axes[0].set_ylabel("contact point s [mm]\n(0: pitch point)")
    axes[1].plot(t, res["mesh.sliding_velocity"][sel], lw=2.2, alpha=0.6, label="Δv_t (simulated)")
    axes[1].plot(t, s * (w1 - w2), **DASHED, label="s·(ω1 − ω2) = s·(|ω1| + |ω2|), Weber (37)")
    axes[1].axhline(0, color="0.5", lw=0.7)
    axes[1].legend(fontsize=8, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=2, frameon=False,
                   borderaxespad=0.1)
    axes[1].set_ylabel("sliding velocity\nΔv_t [m/s]")
    axes[2].plot(t, res["mesh.friction_force"][sel])
    axes[2].axhline(0, color="0.5", lw=0.7)
    axes[2].set_ylabel("tooth friction\nF_t [N]")
    axes[3].plot(t, res["mesh.force"][sel])
    axes[3].set_ylabel("normal force\nF_n [N]")
    axes[3].set_xlabel("t [ms]")
    finish(fig, "gears_normal_sliding.png",
           "Level normal (involute, Coulomb μ = 0.05): contact point, sliding, friction and normal force",
           axes)


FIGURES_BY_NAME = {"gears_load_sharing": load_sharing, "gears_transmission_error": transmission_error,
                   "gears_normal_sliding": normal_sliding}


if __name__ == "__main__":
    main(FIGURES_BY_NAME, sys.argv[1:])
