"""Figures of docs/weber-piezo-motor.md: every ``docs/figures/piezo_*.png`` and ``dc_motor*.png``.

Run from anywhere (the paths are taken relative to this file)::

    python docs/scripts/make_piezo_motor_figures.py             # all figures
    python docs/scripts/make_piezo_motor_figures.py dc_motor    # only those whose name contains "dc_motor"

Each simulated curve comes from a scene in ``diagrams/weber/`` run through the public API
(``multipole.load``, ``multipole.pipeline.run``, overrides as with ``--set``).  The dashed/dotted
curves are the closed forms quoted in the page, with the parameter values read from the same scene
files; the sensor's quasi-static curve is its first-order ODE solved separately with scipy.
"""
from __future__ import annotations

import sys

import matplotlib.pyplot as plt
import numpy as np
from scipy.integrate import solve_ivp

from figure_helpers import element, finish, main, parameters, run, save

THEORY = {"color": "k", "ls": "--", "lw": 0.9}
LEVEL = {"color": "0.45", "ls": ":", "lw": 1.0}


# -- piezo: sensor ------------------------------------------------------------------------------

def piezo_sensor():
    scene = "piezo_sensor.yaml"
    p, pz = parameters(scene), element(scene, "piezo")
    k_P, C_P, R = pz["k_P"], pz["C_P"], pz["R"]

    def force(t):
        return p["F0"] * (1 - np.cos(np.pi * np.minimum(t / p["t_r"], 1.0))) / 2

    runs = [(p["R_L"], f"R_L = {p['R_L'] / 1e3:g} kΩ", "C0"), (1e9, "R_L = 1 GΩ (practically open)", "C1")]
    fig, axes = plt.subplots(3, 1, figsize=(8.2, 8.0), sharex=True)
    for R_L, label, color in runs:
        res = run(scene, {"R_L": repr(R_L)})
        t = res.t
        axes[0].plot(t * 1e3, res["piezo.force"], color=color, lw=1.3, label=f"multipole, {label}")
        axes[1].plot(t * 1e3, res["piezo.voltage"], color=color, lw=2.4 if color == "C0" else 1.3,
                     alpha=0.6 if color == "C0" else 1.0, label=f"multipole, {label}")
        axes[2].plot(t * 1e3, res["piezo.charge"] * 1e6, color=color, lw=1.3, label=f"multipole, {label}")
        if R_L == p["R_L"]:
            # quasi-static theory (below the mechanical resonance, force-controlled, free capacitance):
            # dQ/dt = k_P·dF/dt + C_P·dU/dt = −U/(R_L + R); terminal voltage U·R_L/(R_L + R)
            dF = np.gradient(force(t), t)
            sol = solve_ivp(lambda tt, u: [(-u[0] / (R_L + R) - k_P * np.interp(tt, t, dF)) / C_P],
                            (0, t[-1]), [0.0], t_eval=t, rtol=1e-10, atol=1e-12, max_step=p["t_r"] / 50)
            axes[1].plot(t * 1e3, sol.y[0] * R_L / (R_L + R), **THEORY,
                         label=f"quasi-static theory, τ = (R_L + R)·C_P = {(R_L + R) * C_P * 1e3:.2f} ms")
    U_open = -k_P * p["F0"] / C_P
    axes[1].axhline(U_open, **LEVEL)
    axes[1].text(4.0, U_open, f"−k_P·F/C_P = −{abs(U_open):.0f} V", ha="right", va="bottom", fontsize=8,
                 color="0.35")
    axes[2].axhline(k_P * p["F0"] * 1e6, **LEVEL)
    axes[2].text(4.0, k_P * p["F0"] * 1e6, f"k_P·F = {k_P * p['F0'] * 1e6:.0f} µC for t ≫ τ",
                 ha="right", va="bottom", fontsize=8, color="0.35")
    axes[0].set_ylabel("force (tension) [N]")
    axes[1].set_ylabel("voltage at the electrodes [V]")
    axes[2].set_ylabel("charge ΔQ* [µC]\n(= charge through the meter)")
    axes[2].set_xlabel("t [ms]")
    axes[0].set_ylim(-5, 130)
    axes[0].legend(fontsize=8, loc="upper right", ncol=2)
    axes[1].set_ylim(U_open * 1.12, -U_open * 0.55)
    axes[1].legend(fontsize=8, loc="upper right")
    axes[2].set_ylim(-0.3, 6.8)
    axes[2].legend(fontsize=8, loc="upper left", ncol=2)
    finish(fig, "piezo_sensor.png",
           "piezo_sensor.yaml: a force pulls on the element, the electrodes feed a measuring resistor",
           axes)


# -- piezo: resonance, shorted and open electrodes -------------------------------------------------

def piezo_resonance():
    fig, ax = plt.subplots(figsize=(8.2, 3.9))
    for scene, word, color in (("piezo_resonance.yaml", "shorted", "C0"), ("piezo_resonance_open.yaml", "open",
                                                                            "C1")):
        pz, F, M = element(scene, "piezo"), parameters(scene)["F"], element(scene, "load")["m"]
        delta = pz["delta_P"] if word == "shorted" else pz["delta_P"] - pz["k_P"] ** 2 / pz["C_P"]
        w = np.sqrt(1 / (delta * (pz["m"] + M)))
        res = run(scene)
        formula = "δ_P" if word == "shorted" else "δ_P − k_P²/C_P"
        ax.plot(res.t * 1e6, res["piezo.stroke"] * 1e9, color=color, lw=2.2, alpha=0.7,
                label=f"{word}: δ_eff = {formula}, f = {w / (2 * np.pi) / 1e3:.1f} kHz")
        ax.plot(res.t * 1e6, delta * F * (1 - np.cos(w * res.t)) * 1e9, color="k", ls=":", lw=1.0)
    ax.plot([], [], color="k", ls=":", lw=1.0,
            label="closed form δ_eff·F·(1 − cos ωt), ω² = 1/(δ_eff·(m + M))")
    ax.set_ylim(-0.4, 16.5)                  # headroom: the legend sits above the highest peaks
    ax.legend(fontsize=8, loc="upper center", ncol=1, title="electrodes", title_fontsize=8)
    ax.set_xlabel("t [µs]")
    ax.set_ylabel("stroke [nm]")
    ax.grid(alpha=0.3)
    ax.set_title("Force step 50 N on a 0.1 kg load at the tip of one disc: shorted vs open electrodes", fontsize=10)
    fig.tight_layout()
    save(fig, "piezo_resonance.png")


# -- piezo: actuator, lumped element and stack -----------------------------------------------------

def piezo_actuator():
    scene = "piezo_actuator.yaml"
    p, pz = parameters(scene), element(scene, "piezo")
    c_L = element(scene, "spring")["c"]
    lumped, stack = run(scene), run("piezo_stack.yaml")
    free = pz["k_P"] * p["U0"]
    loaded = free / (1 + c_L * pz["delta_P"])
    fig, axes = plt.subplots(3, 1, figsize=(8.2, 8.0), sharex=True)
    for res, label, style in ((lumped, "piezo_element (lumped)", {"lw": 1.4}),
                              (stack, "piezo_stack, n = 10", {"ls": "--", "lw": 1.4})):
        t = res.t * 1e3
        axes[0].plot(t, res["piezo.stroke"] * 1e6, label=label, **style)
        axes[1].plot(t, res["piezo.force"], label=label, **style)
        axes[2].plot(t, res["piezo.current"], label=label, **style)
    end = lumped.t[-1] * 1e3
    levels = ((axes[0], free * 1e6, f"free stroke k_P·U = {free * 1e6:.2f} µm", 3),
              (axes[0], loaded * 1e6, f"k_P·U/(1 + c_L·δ_P) = {loaded * 1e6:.2f} µm", -11),
              (axes[1], -c_L * loaded, f"−c_L·s = −{c_L * loaded:.0f} N", -11))
    for ax, value, text, dy in levels:
        ax.axhline(value, **LEVEL)
        ax.annotate(text, (end, value), xytext=(0, dy), textcoords="offset points", ha="right", fontsize=8,
                    color="0.3")
    axes[0].set_ylim(-0.3, 8.6)
    axes[0].set_ylabel("stroke [µm]")
    axes[1].set_ylabel("force in the element [N]\n(tension > 0)")
    axes[2].set_ylabel("current [A]")
    axes[2].set_xlabel("t [ms]")
    axes[0].legend(fontsize=8, loc="lower right")
    axes[1].legend(fontsize=8, loc="upper right")
    axes[2].legend(fontsize=8, loc="upper right")
    finish(fig, "piezo_actuator.png",
           "piezo_actuator.yaml / piezo_stack.yaml: 150 V ramp, load 0.5 kg on a 20 N/µm spring",
           axes)


# -- DC motor -------------------------------------------------------------------------------------

def motor_constants(scene: str) -> dict:
    m = element(scene, "motor")
    return {"k": m["k"], "R": m["R"], "L": m["L"], "J": m["J"], "d": m.get("d", 0.0)}


def dc_motor():
    scene = "dc_motor.yaml"
    p, m = parameters(scene), motor_constants(scene)
    k, R, J = m["k"], m["R"], m["J"]
    J_L, d = element(scene, "load")["J"], element(scene, "bearing")["d"]
    U, M_L, t_L = p["U"], p["M_L"], 0.8
    res = run(scene)
    t = res.t
    tau = (J + J_L) * R / (k**2 + R * d)
    w_free = k * U / (k**2 + R * d)
    w_load = (k * U - R * M_L) / (k**2 + R * d)
    w_at_load = w_free * (1 - np.exp(-t_L / tau))
    # first order (L neglected): the run-up, then the approach to the loaded speed from t_L on
    first = np.where(t < t_L, w_free * (1 - np.exp(-t / tau)),
                     w_load + (w_at_load - w_load) * np.exp(-(t - t_L) / tau))
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8.2, 6.0), sharex=True)
    a1.plot(t, res["motor.omega"], lw=2.4, alpha=0.6, label="multipole")
    a1.plot(t, first, **THEORY, label=f"1st order, τ = (J + J_L)·R/(k² + R·d) = {tau * 1e3:.0f} ms")
    for value, text, dy in ((w_free, f"no load: k·U/(k² + R·d) = {w_free:.1f} rad/s", 3),
                            (w_load, f"loaded: (k·U − R·M_L)/(k² + R·d) = {w_load:.1f} rad/s", -12)):
        a1.axhline(value, **LEVEL)
        a1.annotate(text, (t[-1], value), xytext=(0, dy), textcoords="offset points", ha="right", fontsize=8,
                    color="0.3")
    a1.set_ylim(-20, 620)
    a1.legend(fontsize=8, loc="upper left")
    a1.set_ylabel("omega [rad/s]")
    a2.plot(t, res["motor.current"], lw=1.3)
    a2.axhline((M_L + d * w_load) / k, **LEVEL)
    a2.annotate(f"loaded: (M_L + d·ω)/k = {(M_L + d * w_load) / k:.2f} A", (t[-1], (M_L + d * w_load) / k),
                xytext=(0, 3), textcoords="offset points", ha="right", fontsize=8, color="0.3")
    a2.set_ylabel("current [A]")
    a2.set_xlabel("t [s]")
    inset = a2.inset_axes([0.36, 0.38, 0.3, 0.52])
    fine = run(scene, t_end=0.02, dt_out=2e-5)
    inset.plot(fine.t * 1e3, fine["motor.current"], lw=1.2)
    inset.axhline(U / R, **LEVEL)
    inset.set_title(f"start: U/R = {U / R:.0f} A, L/R = {m['L'] / R * 1e3:.2f} ms", fontsize=7.5)
    inset.set_xlabel("t [ms]", fontsize=7.5)
    inset.tick_params(labelsize=7)
    finish(fig, "dc_motor.png",
           f"dc_motor.yaml: {U:.0f} V step, load torque {M_L} N·m from t = {t_L} s",
           (a1, a2))


def mark_time_constant(ax, tau, name, title):
    """Vertical line at t = τ (63 % of the step), the panel's title, axis label, legend and grid."""
    ax.axvline(tau * 1e3, color="0.6", lw=0.8)
    ax.text(tau * 1e3, 0.5, f" t = {name} (63 %)", transform=ax.get_xaxis_transform(), fontsize=8, color="0.35")
    ax.set_title(title, fontsize=9.5)
    ax.set_xlabel("t [ms]")
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)


def dc_motor_time_constants():
    m, free = motor_constants("dc_motor_locked.yaml"), motor_constants("dc_motor_no_load.yaml")
    U = parameters("dc_motor_locked.yaml")["U"]
    k, R, L = m["k"], m["R"], m["L"]
    tau_e, tau_m = L / R, free["J"] * free["R"] / free["k"] ** 2
    assert parameters("dc_motor_no_load.yaml")["U"] == U and free["k"] == k
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.9))
    locked = run("dc_motor_locked.yaml")
    a1.plot(locked.t * 1e3, locked["motor.current"], lw=2.4, alpha=0.6, label="multipole")
    a1.plot(locked.t * 1e3, U / R * (1 - np.exp(-locked.t / tau_e)), color="k", ls=":", lw=1.1,
            label="U/R·(1 − e^(−t·R/L))")
    mark_time_constant(a1, tau_e, "τ_e", f"rotor locked (dc_motor_locked.yaml): τ_e = L/R = {tau_e * 1e3:.2f} ms")
    a1.set_ylabel("current [A]")
    for L_run, label, style in (("0", "multipole, L = 0", {"lw": 2.4, "alpha": 0.6}),
                                (None, f"multipole, L = {L * 1e3:g} mH", {"lw": 1.2})):
        res = run("dc_motor_no_load.yaml", {"motor.L": L_run} if L_run else None)
        a2.plot(res.t * 1e3, res["motor.omega"], label=label, **style)
    a2.plot(res.t * 1e3, U / k * (1 - np.exp(-res.t / tau_m)), color="k", ls=":", lw=1.1,
            label="U/k·(1 − e^(−t/τ_m))")
    mark_time_constant(a2, tau_m, "τ_m", f"no load (dc_motor_no_load.yaml): τ_m = J·R/k² = {tau_m * 1e3:.0f} ms")
    a2.set_ylabel("omega [rad/s]")
    fig.tight_layout()
    save(fig, "dc_motor_time_constants.png")


FIGURES_BY_NAME = {"piezo_sensor": piezo_sensor, "piezo_resonance": piezo_resonance,
                   "piezo_actuator": piezo_actuator, "dc_motor": dc_motor,
                   "dc_motor_time_constants": dc_motor_time_constants}


if __name__ == "__main__":
    main(FIGURES_BY_NAME, sys.argv[1:])
