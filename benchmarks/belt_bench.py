"""Belt benchmarks (docs/performance.md, "Belts"): the two-pulley friction drive
diagrams/belts/friction_drive.yaml (load ramp until the small pulley slips, then the large pulley
is pulled back).

1. Whole runs at equal error: ``multipole`` with the numba backend (Radau IIA, the kernel's
   events) against a hand-written scipy model of the same seven equations (``solve_ivp`` with
   Radau, BDF and LSODA, analytic Jacobian, the stick/slip switches located by terminal events and
   the run restarted there, as the kernel does), each over a ladder of tolerances; runs interleaved,
   CPU time (``time.process_time``), medians of 3.  Error = max over the output grid (dt 5 ms) of the
   relative error of the driven pulley's speed and of the tight span's force against a reference
   (the numba backend at rtol 1e-12, checked against the hand model at rtol 1e-12).  For each error
   level the fastest run of each contender reaching it is compared.
2. The error of the stick regularisation: slip time against the closed form (quasi-static statics
   of tests/test_belt_friction.py) and the creep (speed-ratio error) for creep speeds v_s and belt
   arc masses m.

    python benchmarks/belt_bench.py
"""
from __future__ import annotations

import os
import tempfile
import time
from math import asin, pi, tanh
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "diagrams" / "belts" / "friction_drive.yaml"
# the scene's values
W1, F0, EA, L, CD, RATE, MU, A, R1, R2, J2 = 10.0, 200.0, 1.0e5, 0.8, 20.0, 10.0, 0.3, 0.8, 0.05, 0.1, 0.05
M_ARC, V_S, T_END, DT = 0.01, 1e-4, 2.2, 0.005
L0 = L / (1 + F0 / EA)
TH1 = tanh(MU * (pi - 2 * asin((R2 - R1) / A)) / 2)
TH2 = tanh(MU * (pi + 2 * asin((R2 - R1) / A)) / 2)


# -- the hand-written model -------------------------------------------------------------------
# states y = (u1, u2, w2, d_t, d_s, s1, s2): belt speeds on the wraps of pulley 1 and 2 [m/s],
# angular velocity of pulley 2 [rad/s], stretches of the tight and slack span [m], travel of the
# belt on each wrap [m] (the wound lengths: free lengths l0 + s2 - s1 and l0 + s1 - s2).
# Pulley 1 turns at W1 (speed source).  mode = (c1, c2): 0 stick (viscous branch), +-1 slipping.

def _spans(y):
    u1, u2, _, dt, ds, s1, s2 = y
    lxt, lxs = L0 + s2 - s1, L0 + s1 - s2
    return (EA * dt + CD * (u1 - u2)) / lxt, (EA * ds + CD * (u2 - u1)) / lxs, lxt, lxs


def hand_rhs(t, y, mode):
    u1, u2, w2 = y[0], y[1], y[2]
    Ft, Fs, _, _ = _spans(y)
    S, D = Ft + Fs, Ft - Fs
    c1 = mode[0] or (u1 - R1 * W1) / V_S
    c2 = mode[1] or (u2 - R2 * w2) / V_S
    Fc1, Fc2 = S * TH1 * c1, S * TH2 * c2
    return np.array([(-D - Fc1) / M_ARC, (D - Fc2) / M_ARC, (R2 * Fc2 - RATE * t) / J2,
                     u1 - u2, u2 - u1, u1, u2])


def hand_jac(t, y, mode):
    u1, u2, w2 = y[0], y[1], y[2]
    Ft, Fs, lxt, lxs = _spans(y)
    dFt = np.array([CD / lxt, -CD / lxt, 0, EA / lxt, 0, Ft / lxt, -Ft / lxt])
    dFs = np.array([-CD / lxs, CD / lxs, 0, 0, EA / lxs, -Fs / lxs, Fs / lxs])
    S, dS, dD = Ft + Fs, dFt + dFs, dFt - dFs
    c1 = mode[0] or (u1 - R1 * W1) / V_S
    c2 = mode[1] or (u2 - R2 * w2) / V_S
    dc1, dc2 = np.zeros(7), np.zeros(7)
    if not mode[0]:
        dc1[0] = 1 / V_S
    if not mode[1]:
        dc2[1], dc2[2] = 1 / V_S, -R2 / V_S
    dFc1, dFc2 = TH1 * (c1 * dS + S * dc1), TH2 * (c2 * dS + S * dc2)
    Jm = np.zeros((7, 7))
    Jm[0], Jm[1], Jm[2] = (-dD - dFc1) / M_ARC, (dD - dFc2) / M_ARC, R2 * dFc2 / J2
    Jm[3, 0], Jm[3, 1], Jm[4, 0], Jm[4, 1], Jm[5, 0], Jm[6, 1] = 1, -1, -1, 1, 1, 1
    return Jm


def _switches(y):
    """The four switching functions: slip/v_s -+ 1 of each contact."""
    g1, g2 = (y[0] - R1 * W1) / V_S, (y[1] - R2 * y[2]) / V_S
    return (g1 - 1, g1 + 1, g2 - 1, g2 + 1)


def hand_run(method, rtol, atol, t_eval):
    """The hand model over [0, T_END], restarted at every stick/slip switch; returns (y on t_eval,
    switch times, rhs evaluations)."""
    y = np.array([R1 * W1, R1 * W1, R1 * W1 / R2, L - L0, L - L0, 0.0, 0.0])
    t, mode, out, switches, nfev = 0.0, [0, 0], [], [], 0
    while True:
        evs = []
        for k in range(4):
            contact, side = divmod(k, 2)
            sign = 1 if side == 0 else -1            # g - 1 bounds +1 slip, g + 1 bounds -1 slip
            ev = (lambda tt, yy, _mode, k=k: _switches(yy)[k])
            ev.terminal = True
            # leaving stick: g - 1 rises through 0 (g + 1 falls); back to stick: the opposite
            stick = mode[contact] == 0
            ev.direction = sign if stick else -sign
            if stick or mode[contact] == sign:
                evs.append((k, ev))
        te = t_eval[t_eval > t] if t > 0 else t_eval     # an output time at a switch: kept once
        sol = solve_ivp(hand_rhs, (t, T_END), y, method=method, rtol=rtol, atol=atol, t_eval=te,
                        args=(tuple(mode),), jac=hand_jac,
                        events=[e for _, e in evs])
        nfev += sol.nfev
        if sol.status < 0:
            raise RuntimeError(f"{method} at rtol {rtol:g}: {sol.message} (t = {t:.6g} s)")
        out.append(np.reshape(sol.y, (7, -1)))          # no output time in a short segment: empty
        hit = [(sol.t_events[i][0], k) for i, (k, _) in enumerate(evs) if len(sol.t_events[i])]
        if sol.status != 1 or not hit:
            break
        t, k = min(hit)
        y = sol.y_events[[i for i, (kk, _) in enumerate(evs) if kk == k][0]][0]
        contact, side = divmod(k, 2)
        sign = 1 if side == 0 else -1
        mode[contact] = sign if mode[contact] == 0 else 0
        switches.append(t)
        if len(switches) > 100:
            raise RuntimeError(f"{method} at rtol {rtol:g}: more than 100 switches by t = {t:.6g} s")
    y = np.concatenate(out, axis=1)
    assert y.shape[1] == len(t_eval), (y.shape, len(t_eval))
    return y, switches, nfev


# -- multipole ----------------------------------------------------------------------------------

def scene(**overrides):
    from multipole.netlist import load
    return load(SCENE, overrides)


def mp_run(sc, rtol, atol, solver="Radau"):
    from multipole import pipeline
    res = pipeline.run(sc, rtol=rtol, atol=atol, solver=solver, dt_out=DT, backend="numba", progress=False,
                       outputs=["p2.omega", "tight.F"])
    return res


def _error(w2, Ft, ref):
    return max(np.max(abs(w2 - ref[0])) / np.max(abs(ref[0])), np.max(abs(Ft - ref[1])) / np.max(abs(ref[1])))


def equal_error(repeats=3):
    t_eval = np.linspace(0.0, T_END, int(round(T_END / DT)) + 1)
    sc = scene()
    ref_res = mp_run(sc, 1e-12, 1e-14)
    ref = (ref_res["p2.omega"], ref_res["tight.F"])
    yh, sw, _ = hand_run("Radau", 1e-12, 1e-14, t_eval)
    Ft_h = _spans(yh)[0]
    ref_gap = _error(yh[2], Ft_h, ref)
    runs = {}
    ladder = (1e-3, 1e-4, 1e-6, 1e-8, 1e-10)
    configs = [("numba", "Radau", r) for r in ladder] + [("hand", m, r) for m in ("Radau", "BDF", "LSODA")
                                                         for r in ladder]
    for who, method, rtol in configs:      # warm-up: compile, caches
        if who == "numba":
            mp_run(sc, rtol, rtol * 1e-3)
    times = {c: [] for c in configs}
    errors = {}
    for _ in range(repeats):               # interleaved: every configuration once per round
        for c in configs:
            who, method, rtol = c
            t0 = time.process_time()
            if who == "numba":
                res = mp_run(sc, rtol, rtol * 1e-3)
                w2, Ft = res["p2.omega"], res["tight.F"]
            else:
                try:
                    y, _, _ = hand_run(method, rtol, rtol * 1e-3, t_eval)
                    w2, Ft = y[2], _spans(y)[0]
                except RuntimeError:                      # failed or chattering: reaches no level
                    w2 = Ft = np.full(len(t_eval), np.inf)
            times[c].append(time.process_time() - t0)
            errors[c] = _error(w2, Ft, ref)
    for c in configs:
        runs[c] = (errors[c], float(np.median(times[c])))
    return runs, ref_gap, ref_res.events, sw


def regularisation():
    """Slip time and creep against the closed form for creep speeds v_s and arc masses m."""
    from multipole import pipeline
    t_slip = _closed_form_slip_time()
    rows = []
    for m, v_s in [(0.01, 1e-2), (0.01, 1e-3), (0.01, 1e-4), (0.01, 1e-5), (0.01, 1e-6), (0.1, 1e-4), (0.001, 1e-4)]:
        text = SCENE.read_text().replace("omega0: w}", f"omega0: w, m: {m}, v_s: {v_s}}}").replace(
            "omega0: w*r1/r2}", f"omega0: w*r1/r2, m: {m}, v_s: {v_s}}}")
        assert text.count(f"m: {m}, v_s: {v_s}") == 2, "the scene's pulleys are no longer written as expected"
        from multipole.netlist import loads
        sc = loads(text, "friction_drive.yaml")
        res = pipeline.run(sc, rtol=1e-9, atol=1e-12, dt_out=DT, progress=False,    # numpy: no compile per model
                           outputs=["p2.omega", "p1.slip", "p2.slip"])
        t_ev = [t for t, what in res.events if "p1.fr" in what][0]
        k = int(np.argmin(abs(res.t - 1.0)))
        creep = abs(res["p1.slip"][k]) + abs(res["p2.slip"][k])
        rows.append((m, v_s, t_ev - t_slip, creep / (R1 * W1), res.stats["steps"]))
    return t_slip, rows


def _closed_form_slip_time():
    """As tests/test_belt_friction.py: material conservation, torque balance, span dampers' quasi-static
    forces, F_t = exp(mu wrap1) F_s."""
    ratio = (1 + TH1) / (1 - TH1)

    def el(lx):
        return EA * (L - lx) / lx

    def tensions(x):
        xs = 2 * L0 - x
        x_rate = -(RATE / R2) / (EA * L / x ** 2 + EA * L / xs ** 2)
        return el(x) - CD * x_rate / x, el(xs) + CD * x_rate / xs
    lx = brentq(lambda x: tensions(x)[0] - ratio * tensions(x)[1], L0 * (1 - 1e-2), L0)
    Ft, Fs = tensions(lx)
    return R2 * (Ft - Fs) / RATE


def main():
    os.environ.setdefault("MULTIPOLE_CACHE", tempfile.mkdtemp())
    t0, c0 = time.time(), time.process_time()
    runs, gap, ev, sw = equal_error()
    print(f"reference: numba Radau rtol 1e-12; hand model at rtol 1e-12 differs by {gap:.2g}; "
          f"slip event {ev[0][0]:.10f} s (hand model {sw[0]:.10f} s)")
    print("\n| contender | solver | rtol | error | CPU [ms] |\n|---|---|---|---|---|")
    for (who, method, rtol), (err, cpu) in runs.items():
        print(f"| {who} | {method} | {rtol:g} | {err:.2g} | {cpu * 1e3:.3g} |")
    print("\n| error <= | hand-written: solver, rtol, CPU [ms], error | numba: rtol, CPU [ms], error | ratio |")
    print("|---|---|---|---|")
    for level in (1e-3, 1e-6, 1e-9):
        if level < 3 * gap:
            print(f"| {level:g} | not measurable (reference gap {gap:.1g}) | | |")
            continue
        best = {}
        for (who, method, rtol), (err, cpu) in runs.items():
            if err <= level and (who not in best or cpu < best[who][2]):
                best[who] = (method, rtol, cpu, err)
        h, n = best.get("hand"), best.get("numba")
        fmt = (lambda b: f"{b[0]}, {b[1]:g}, {b[2] * 1e3:.3g}, {b[3]:.2g}" if b else "—")
        ratio = f"{h[2] / n[2]:.0f}x" if h and n else "—"
        print(f"| {level:g} | {fmt(h)} | {fmt(n)[len(n[0]) + 2:] if n else '—'} | {ratio} |")
    t_slip, rows = regularisation()
    print(f"\nclosed-form slip time {t_slip:.10f} s")
    print("\n| arc mass m [kg] | creep speed v_s [m/s] | slip time - closed form [s] | creep / belt speed at t = 1 s "
          "| Radau steps (rtol 1e-9) |\n|---|---|---|---|---|")
    for m, v_s, dt, creep, steps in rows:
        print(f"| {m:g} | {v_s:g} | {dt:+.2e} | {creep:.2e} | {steps} |")
    print(f"\n(total {time.time() - t0:.1f} s wall, {time.process_time() - c0:.1f} s CPU)")


if __name__ == "__main__":
    main()
