"""DSD, SSD and SDS dyads (elements/linkage_guides.py) against theory written here.

Every module hangs on the tip A of a speed-driven crank (DAN, pivot at the origin, l = 0.2 m,
phi = 0.3 rad + 2 rad/s * t).  The expected values come from closed forms of the loop closure written
in this file with sympy (an explicit solution, not the module's Newton iteration on its MTF
chain): positions to 1e-10, the simulated rates against central finite differences of those
positions, and the drive torque against the rate of kinetic plus potential energy of all bodies
(differentiated symbolically here) to 1e-8.  The printed-errata tests evaluate the printed and the
corrected forms of Ebert's equations (App. B.6-B.8) with the simulated joint forces and show that
only the corrected ones hold.
"""
import math
from pathlib import Path
import numpy as np
import pytest
import sympy as sp

import multipole as mp
from multipole import pipeline
from multipole.cli import main

W, PHI0, L, G = 2.0, 0.3, 0.2, 9.81
CRANK = (1.0, 0.01)                     # m [kg], J [kg*m^2] of the crank, centre of mass at l/2
t = sp.Symbol("t", real=True)


def e(a):
    return sp.Matrix([sp.cos(a), sp.sin(a)])


def n(a):
    return sp.Matrix([-sp.sin(a), sp.cos(a)])


def rot(a, x, y):
    return sp.Matrix([x * sp.cos(a) - y * sp.sin(a), x * sp.sin(a) + y * sp.cos(a)])


def cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


PHI = PHI0 + W * t
A = L * e(PHI)                           # crank tip, anchor a1 of every dyad here

# module parameters (SI) and the closed-form solution of each: the bodies (m, J, centre of mass, angle)
# and the module's outputs as expressions of t
DSD = dict(v=0.05, mU=2.0, JU=0.05, xsU=0.2, ysU=0.01, mS=0.5, JS=0.002, xsS=0.03, ysS=-0.02, x2=0.6, y2=0.1)
SSD = dict(v1=0.04, v2=-0.03, phiv=1.0, phi1=0.2, m1=0.8, J1=0.004, xs1=0.02, ys1=0.01, m2=0.3, J2=0.001,
           xs2=-0.01, ys2=0.02, x2=0.5, y2=0.3)
SDS = dict(v1=0.03, v2=0.02, phi1=0.0, phi2=2.2, m1=0.8, J1=0.004, xs1=0.02, ys1=0.01, m2=0.3, J2=0.001,
           xs2=-0.01, ys2=0.02, x2=0.4, y2=-0.1)


def closed_dsd(p):
    """P2 - A = x_G e(phiU) + v n(phiU): |P2 - A|^2 = x_G^2 + v^2, and the angle of P2 - A is
    phiU + atan2(v, x_G)."""
    d = sp.Matrix([p["x2"], p["y2"]]) - A
    xg = sp.sqrt(d.dot(d) - p["v"] ** 2)
    phiu = sp.atan2(d[1], d[0]) - sp.atan2(p["v"], xg)
    bodies = [(p["mU"], p["JU"], A + rot(phiu, p["xsU"], p["ysU"]), phiu),
              (p["mS"], p["JS"], A + xg * e(phiu) + rot(phiu, p["xsS"], p["ysS"]), phiu)]
    geo = {"PS": A + xg * e(phiu), "P2": d + A, "th": phiu, "xG": xg}
    return bodies, {"dyad.phiU": phiu, "dyad.xG": xg}, {"dyad.omega": "dyad.phiU", "dyad.vG": "dyad.xG"}, geo


def closed_ssd(p):
    """A + x_G1 e1 + v1 n1 + x_G2 e2 + v2 n2 = P2, solved as a 2x2 linear system."""
    th1 = PHI + p["phi1"]
    th2 = th1 + p["phiv"]
    rhs = sp.Matrix([p["x2"], p["y2"]]) - A - p["v1"] * n(th1) - p["v2"] * n(th2)
    xg1, xg2 = sp.Matrix.hstack(e(th1), e(th2)).solve(rhs)
    P = A + xg1 * e(th1) + p["v1"] * n(th1)
    bodies = [(p["m1"], p["J1"], A + xg1 * e(th1) + rot(th1, p["xs1"], p["ys1"]), th1),
              (p["m2"], p["J2"], P + xg2 * e(th2) + rot(th2, p["xs2"], p["ys2"]), th1)]
    geo = {"PS1": A + xg1 * e(th1), "P": P, "PS2": P + xg2 * e(th2), "P2": sp.Matrix([p["x2"], p["y2"]]),
           "th1": th1, "th2": th2, "xG1": xg1, "xG2": xg2}
    return bodies, {"dyad.xG1": xg1, "dyad.xG2": xg2, "dyad.x": P[0], "dyad.y": P[1], "dyad.phiU1": th1}, \
        {"dyad.vG1": "dyad.xG1", "dyad.vG2": "dyad.xG2"}, geo


def closed_sds(p):
    """A + x_G1 e1 + v1 n1 = P2 + x_G2 e2 + v2 n2, solved as a 2x2 linear system."""
    th1, th2 = PHI + p["phi1"], sp.Float(p["phi2"])
    P2 = sp.Matrix([p["x2"], p["y2"]])
    rhs = P2 + p["v2"] * n(th2) - A - p["v1"] * n(th1)
    xg1, xg2 = sp.Matrix.hstack(e(th1), -e(th2)).solve(rhs)
    P = A + xg1 * e(th1) + p["v1"] * n(th1)
    bodies = [(p["m1"], p["J1"], A + xg1 * e(th1) + rot(th1, p["xs1"], p["ys1"]), th1),
              (p["m2"], p["J2"], P2 + xg2 * e(th2) + rot(th2, p["xs2"], p["ys2"]), th2)]
    geo = {"PS1": A + xg1 * e(th1), "P": P, "PS2": P2 + xg2 * e(th2), "th1": th1, "th2": th2, "xG1": xg1,
           "xG2": xg2}
    return bodies, {"dyad.xG1": xg1, "dyad.xG2": xg2, "dyad.x": P[0], "dyad.y": P[1], "dyad.phiU1": th1,
                    "dyad.phiU2": th2, "dyad.transmission": sp.sin(th2 - th1)}, {"dyad.vG1": "dyad.xG1", "dyad.vG2": "dyad.xG2"}, geo


CASES = {"DSD": (DSD, closed_dsd, 1.0), "SSD": (SSD, closed_ssd, 2.0), "SDS": (SDS, closed_sds, 0.4)}


def scene_text(kind, params, t_end, outputs=(), extra_elements="", extra_connections=""):
    values = ", ".join(f"{k}: {v!r}" for k, v in params.items())
    outs = ["crank.phi", "crank.torque"] + list(outputs)
    return f"""
name: {kind.lower()}_test
elements:
  motor: {{type: speed_source, value: {W}}}
  crank: {{type: DAN, l: {L}, phi0: {PHI0}, m: {CRANK[0]}, J: {CRANK[1]}}}
  dyad: {{type: {kind}, {values}}}
{extra_elements}
connections:
  - [motor.p, crank.drive]
  - [crank.b, dyad.a1]
{extra_connections}
outputs: [{', '.join(outs)}]
simulate: {{t_end: {t_end}, dt_out: {t_end / 40}, rtol: 1e-11, atol: 1e-12}}
"""


_RUNS: dict = {}


def run(kind, outputs=()):
    """Simulate the module's test mechanism once per output set (cached within the test session)."""
    params, closed, t_end = CASES[kind]
    _bodies, coords, rates, _geo = closed(params)
    outs = tuple(coords) + tuple(rates) + tuple(outputs)
    key = (kind, outs)
    if key not in _RUNS:
        res = pipeline.run(mp.loads(scene_text(kind, params, t_end, outs), f"{kind}.yaml"))
        _RUNS[key] = {"t": res.t, **{name: np.asarray(res[name]) for name in ["crank.phi", "crank.torque", *outs]}}
    return _RUNS[key]


def numeric(expr):
    return sp.lambdify(t, expr, "numpy")


@pytest.mark.parametrize("kind", sorted(CASES))
def test_positions_match_closed_form(kind):
    params, closed, _ = CASES[kind]
    _bodies, coords, _rates, _geo = closed(params)
    r = run(kind)
    assert np.allclose(r["crank.phi"], PHI0 + W * r["t"], rtol=0, atol=1e-12)
    for name, expr in coords.items():
        expected = numeric(expr)(r["t"]) * np.ones_like(r["t"])
        diff = r[name] - expected
        if name.endswith("phiU"):
            diff = np.angle(np.exp(1j * diff))           # the closed form's atan2 wraps, the state does not
        assert np.max(np.abs(diff)) < 1e-10, (name, np.max(np.abs(diff)))


@pytest.mark.parametrize("kind", sorted(CASES))
def test_rates_match_finite_differences_of_positions(kind):
    """The module's velocity Jacobian (its MTF rows, solved through the joint nodes) against central
    differences of the closed-form positions (h = 1e-5 s: truncation ~1e-10, round-off ~1e-11)."""
    params, closed, _ = CASES[kind]
    _bodies, coords, rates, _geo = closed(params)
    r = run(kind)
    h = 1e-5
    for rate, pos in rates.items():
        f = numeric(coords[pos])
        fd = (f(r["t"] + h) - f(r["t"] - h)) / (2 * h)
        if pos.endswith("phiU"):
            fd = np.angle(np.exp(1j * (f(r["t"] + h) - f(r["t"] - h)))) / (2 * h)
        assert np.max(np.abs(r[rate] - fd)) < 1e-7 * max(1.0, np.max(np.abs(fd))), rate


def energy_rate(bodies):
    """d/dt (kinetic + potential energy) of the crank and the module's bodies [W], as a function of t."""
    crank = (CRANK[0], CRANK[1], L / 2 * e(PHI), PHI)
    total = 0
    for m, J, rs, ang in [crank] + list(bodies):
        v, a = rs.diff(t), rs.diff(t, 2)
        total += m * (v.dot(a) + G * v[1]) + J * ang.diff(t) * ang.diff(t, 2)
    return numeric(total)


@pytest.mark.parametrize("kind", sorted(CASES))
def test_drive_torque_is_energy_rate(kind):
    """Kinetostatics: drive power = d/dt (KE + PE) with gravity (0, -9.81) m/s^2, to 1e-8."""
    params, closed, _ = CASES[kind]
    bodies, _coords, _rates, _geo = closed(params)
    r = run(kind)
    expected = energy_rate(bodies)(r["t"]) / W
    assert np.max(np.abs(expected)) > 0.1                  # the mechanism really loads the drive
    assert np.max(np.abs(r["crank.torque"] - expected)) < 1e-8 * np.max(np.abs(expected))


# -- printed errata of Ebert App. B.6-B.8 (reference §9): the corrected form holds, the printed one does not --

FORCES = ("dyad.a1.x.e", "dyad.a1.y.e", "dyad.a1.phi.e", "dyad.a2.x.e", "dyad.a2.y.e", "dyad.a2.phi.e")


def kinetics(kind):
    """The simulated anchor loads (forces and torques on the module at a1 and a2) with the closed-form
    geometry and inertia terms G_k = m_k (a_Sk - g), Ta_k = J_k phi_k'' of every body at the same times."""
    params, closed, _ = CASES[kind]
    bodies, _coords, _rates, geo = closed(params)
    r = run(kind, FORCES)
    tt = r["t"]

    def val(ex):
        return np.broadcast_to(np.asarray(numeric(ex)(tt), dtype=float), tt.shape).copy()

    def vec(M):
        return np.array([val(c) for c in M])

    k = {"r": r, "F1": np.array([r["dyad.a1.x.e"], r["dyad.a1.y.e"]]), "T1": r["dyad.a1.phi.e"],
         "F2": np.array([r["dyad.a2.x.e"], r["dyad.a2.y.e"]]), "T2": r["dyad.a2.phi.e"],
         "G": [m * (vec(rs.diff(t, 2)) + np.array([[0.0], [G]])) for m, _J, rs, _th in bodies],
         "Ta": [J * val(th.diff(t, 2)) for _m, J, _rs, th in bodies], "S": [vec(rs) for _m, _J, rs, _th in bodies],
         "A": vec(A)}
    for name, ex in geo.items():
        k[name] = vec(ex) if isinstance(ex, sp.MatrixBase) else val(ex)
    k["scale"] = max(np.max(np.abs(k["F1"])), np.max(np.abs(k["F2"])))
    return k


def ev(a):
    return np.array([np.cos(a), np.sin(a)])


def nv(a):
    return np.array([-np.sin(a), np.cos(a)])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1]


def moment(r, F):
    """(r x F) of arrays of 2-vectors."""
    return r[0] * F[1] - r[1] * F[0]


def dsd_b130(k):
    """(B.130/131): p_PS'' = p_P1'' + (x_G'' - x_G phi'^2) e + ... ; the print loses the x_G'' e term.  The
    whole dyad's balance F_P1 + F_P2 = G_U + G_S holds with the simulated anchor forces only if G_S has it."""
    GU, GS = k["G"]
    xg_dd = np.gradient(np.gradient(k["xG"], k["r"]["t"]), k["r"]["t"])   # only to build the printed form
    printed_GS = GS - DSD["mS"] * xg_dd * ev(k["th"])
    return k["F1"] + k["F2"] - GU - GS, k["F1"] + k["F2"] - GU - printed_GS


def _dsd_normal(k, FPS):
    return dot(FPS, nv(k["th"]))


def dsd_b141(k):
    """(B.141/142) guide: 0 = F_P1 - Fn n(phiU) - G_U (Ft_U = 0); the print has +Fn cos phiU in y."""
    GU, GS = k["G"]
    fn = _dsd_normal(k, GS - k["F2"])
    ours = k["F1"] - fn * nv(k["th"]) - GU
    printed_y = k["F1"][1] + fn * np.cos(k["th"]) - GU[1]
    return ours, printed_y


def dsd_b144(k):
    """(B.144/145) slider: 0 = F_P2 + F_PS - G_S with F_PS the guide's force on the slider (§4.3); the print
    writes F_P2 - F_PS, which with that convention breaks the guide's balance."""
    GU, GS = k["G"]
    ours = k["F1"] - _dsd_normal(k, GS - k["F2"]) * nv(k["th"]) - GU
    printed = k["F1"] - _dsd_normal(k, k["F2"] - GS) * nv(k["th"]) - GU
    return ours, printed


def dsd_b147(k):
    """(B.147/148): Fn = F_PS . n, Ft_S = F_PS . e (a rotation); frictionless with a free drive port, Ft_S = 0.
    The printed Ft_S = Fx cos - Fy sin is not."""
    _GU, GS = k["G"]
    FPS, th = GS - k["F2"], k["th"]
    return dot(FPS, ev(th)), FPS[0] * np.cos(th) - FPS[1] * np.sin(th)


def ssd_v1(k):
    """Text L3827 names v_2 as slider 1's offset: P = PS1 + v1 n1 (B.164), not PS1 + v2 n1."""
    r, th = k["r"], k["th1"]
    P = np.array([r["dyad.x"], r["dyad.y"]])
    PS1 = k["A"] + r["dyad.xG1"] * ev(th)
    return P - PS1 - SSD["v1"] * nv(th), P - PS1 - SSD["v2"] * nv(th)


def _ssd_fn1(k):
    GS1, GS2 = k["G"]
    return dot(GS1 + GS2 - k["F2"], nv(k["th1"]))       # slider 2 then slider 1 balances: Fn1 n1 = G_S1 + G_S2 - F_P2


def ssd_b182(k):
    """(B.182/183) guide 1: 0 = F_P1 - Fn1 n1; the print has +(-Fn1) sin phiU1 in x."""
    fn1, th = _ssd_fn1(k), k["th1"]
    return k["F1"] - fn1 * nv(th), k["F1"][0] - fn1 * np.sin(th)


def _ssd_tps2(k, ps_y):
    """T_PS2 from slider 2's moments about PS2 (B.190) with the y coordinate ``ps_y`` of the foot point."""
    _GS1, GS2 = k["G"]
    F2, PS2, SS2 = k["F2"], k["PS2"], k["S"][1]
    return k["Ta"][1] + F2[0] * (k["P2"][1] - ps_y) - F2[1] * (k["P2"][0] - PS2[0]) \
        - GS2[0] * (SS2[1] - PS2[1]) + GS2[1] * (SS2[0] - PS2[0])


def _ssd_b187(k, tps1, tps2):
    """Slider 1's moments about PS1 (B.187, printed correctly; guide 1 gets +T_PS1, slider 1 -T_PS1)."""
    GS1, GS2 = k["G"]
    fn2 = dot(GS2 - k["F2"], nv(k["th2"]))
    PS1, SS1 = k["PS1"], k["S"][0]
    return -fn2 * dot(k["PS2"] - PS1, ev(k["th2"])) + GS1[0] * (SS1[1] - PS1[1]) - GS1[1] * (SS1[0] - PS1[0]) \
        - k["Ta"][0] - tps1 - tps2


def _ssd_tps1(k, sign):
    """T_PS1 (printed sign convention) from guide 1's moments about P1 (B.184); ``sign`` -1 is the print's
    lever arm (y_P1 - y_PS1)."""
    fn1, th, d = _ssd_fn1(k), k["th1"], k["PS1"] - k["A"]
    return fn1 * (d[0] * np.cos(th) + sign * d[1] * np.sin(th)) - k["T1"]


def ssd_b184(k):
    tps2 = _ssd_tps2(k, k["PS2"][1])
    return _ssd_b187(k, _ssd_tps1(k, 1), tps2), _ssd_b187(k, _ssd_tps1(k, -1), tps2)


def ssd_b190(k):
    """(B.190): slider 2's moments about PS2; the print uses y_PS (slider 1's foot point) for y_PS2."""
    tps1 = _ssd_tps1(k, 1)
    return _ssd_b187(k, tps1, _ssd_tps2(k, k["PS2"][1])), _ssd_b187(k, tps1, _ssd_tps2(k, k["PS1"][1]))


def _sds_loads(k):
    """Guides (B.221-B.226): Fn_i = F_Pi . n_i, T_PSi = T_Pi - Fn_i x_Gi; slider 2 (B.230/231): the force of
    slider 2 on slider 1 at P is F_P = Fn2 n2 - G_S2."""
    fn1, fn2 = dot(k["F1"], nv(k["th1"])), dot(k["F2"], nv(k["th2"]))
    FP = fn2 * nv(k["th2"]) - k["G"][1]
    return FP, k["T1"] - fn1 * k["xG1"], k["T2"] - fn2 * k["xG2"]


def sds_b229(k):
    """(B.229) slider 1's moments about PS1: the print leaves out the moment of F_P and T_PS1."""
    FP, tps1, _ = _sds_loads(k)
    G1, S1, PS1 = k["G"][0], k["S"][0], k["PS1"]
    inertia = G1[0] * (S1[1] - PS1[1]) - G1[1] * (S1[0] - PS1[0]) - k["Ta"][0]
    return moment(k["P"] - PS1, FP) + inertia + tps1, inertia


def sds_b232(k):
    """(B.232) slider 2's moments about PS2: Fx_P (y_P - y_PS2) - Fy_P (x_P - x_PS2) + ...; the print has
    (-Fy_P)(x_PS2 - x_P), the opposite sign of that term."""
    FP, _, tps2 = _sds_loads(k)
    G2, S2, PS2, P = k["G"][1], k["S"][1], k["PS2"], k["P"]
    rest = G2[0] * (S2[1] - PS2[1]) - G2[1] * (S2[0] - PS2[0]) - k["Ta"][1] + tps2
    return FP[0] * (P[1] - PS2[1]) - FP[1] * (P[0] - PS2[0]) + rest, \
        FP[0] * (P[1] - PS2[1]) - FP[1] * (PS2[0] - P[0]) + rest


ERRATA = {("DSD", "B.130/131"): dsd_b130, ("DSD", "B.141/142"): dsd_b141, ("DSD", "B.144/145"): dsd_b144,
          ("DSD", "B.147/148"): dsd_b147, ("SSD", "L3827 v2"): ssd_v1, ("SSD", "B.182/183"): ssd_b182,
          ("SSD", "B.184"): ssd_b184, ("SSD", "B.190"): ssd_b190, ("SDS", "B.229"): sds_b229,
          ("SDS", "B.232"): sds_b232}


@pytest.mark.parametrize("kind,erratum", sorted(ERRATA))
def test_printed_erratum_fails_corrected_form_holds(kind, erratum):
    k = kinetics(kind)
    ours, printed = ERRATA[(kind, erratum)](k)
    scale = k["scale"] * (1.0 if erratum != "L3827 v2" else 1e-2 / k["scale"])   # forces [N] or lengths [m]
    assert np.max(np.abs(ours)) < 1e-7 * scale, (erratum, np.max(np.abs(ours)))
    assert np.max(np.abs(printed)) > 1e-3 * scale, (erratum, np.max(np.abs(printed)))


def test_dsd_start_orientation_uses_corrected_b124():
    """(B.124): the start angle seeds the closure's Newton iteration at t = 0.  With the corrected sign
    (H2 H4 - v H1)/H3, (H5, H6) is e(phiU) and closes the loop exactly; the printed + v H1 does not."""
    sc = mp.loads(scene_text("DSD", DSD, 1.0), "dsd.yaml")
    flat = pipeline.check(sc).flat
    start = {str(s.symbol): float(sp.sympify(s.initial).subs(flat.params).subs(flat.params)) for s in flat.states}
    phiu, xg = start["dyad.C.K.q3"], start["dyad.C.K.q4"]
    A0 = L * np.array([math.cos(PHI0), math.sin(PHI0)])
    d = np.array([DSD["x2"], DSD["y2"]]) - A0
    residual = A0 + xg * ev(phiu) + DSD["v"] * nv(phiu) - np.array([DSD["x2"], DSD["y2"]])
    assert np.max(np.abs(residual)) < 1e-14
    h1, h2 = d
    h3 = h1 ** 2 + h2 ** 2
    h4 = math.sqrt(h3 - DSD["v"] ** 2)
    printed = math.atan2((h2 * h4 + DSD["v"] * h1) / h3, (h1 * h4 + DSD["v"] * h2) / h3)
    residual_printed = A0 + xg * ev(printed) + DSD["v"] * nv(printed) - np.array([DSD["x2"], DSD["y2"]])
    assert np.max(np.abs(residual_printed)) > 1e-3


def test_dsd_drive_port_on_slider_support_on_guide():
    """Tables B.16/B.18 swap ctrT1 and ctrT2; here ``drive`` sits on the slider (its speed is the travel rate
    x_G') and ``support`` on the guide (held: speed 0).  A constant force F on the drive port acts between
    slider and guide (action on one, reaction on the other), so crank power + F x_G' = d/dt (KE + PE)."""
    F = 3.0
    params, closed, t_end = CASES["DSD"]
    bodies, _c, _r, _g = closed(params)
    text = scene_text("DSD", params, t_end, ["dyad.vG", "dyad.support.f", "dyad.drive.f", "dyad.drive.e"],
                      f"  push: {{type: force_source, value: {F}}}", "  - [push.p, dyad.drive]")
    res = pipeline.run(mp.loads(text, "dsd_push.yaml"))
    tt = np.asarray(res.t)
    vg = np.asarray(res["dyad.vG"])
    assert np.max(np.abs(np.asarray(res["dyad.drive.f"]) - vg)) == 0.0 and np.max(np.abs(vg)) > 0.1
    assert np.max(np.abs(np.asarray(res["dyad.support.f"]))) == 0.0
    assert np.allclose(res["dyad.drive.e"], F, rtol=1e-12)
    expected = energy_rate(bodies)(tt)
    power = np.asarray(res["crank.torque"]) * W + F * vg
    assert np.max(np.abs(power - expected)) < 1e-8 * np.max(np.abs(expected))


# -- bad input -----------------------------------------------------------------------------------------------

def test_ssd_parallel_slides_refused_at_build():
    with pytest.raises(mp.MultipoleError) as exc:
        pipeline.check(mp.loads(scene_text("SSD", {**SSD, "phiv": 0.0}, 1.0), "ssd.yaml"))
    assert exc.value.code == "parallel_slides"
    with pytest.raises(mp.MultipoleError) as exc:
        pipeline.check(mp.loads(scene_text("SSD", {**SSD, "phiv": math.pi}, 1.0), "ssd.yaml"))
    assert exc.value.code == "parallel_slides"




@pytest.mark.parametrize("kind,params,code", [
    ("SSD", {**SSD, "phiv": 0.0}, "parallel_slides"),
    # |P1P2| = |(0.6, 0.1) - A(0)| = 0.411 m <= |v| = 0.5 m: the slider cannot reach P2 at t = 0
    ("DSD", {**DSD, "v": 0.5}, "cannot_assemble"),
    # slide line 1 along the crank (0.3 rad at t = 0) and slide line 2 at 0.3 + pi: parallel at t = 0
    ("SDS", {**SDS, "phi2": PHI0 + math.pi}, "cannot_assemble")])
def test_bad_geometry_is_one_line_error_via_cli(tmp_path, capsys, kind, params, code):
    path = tmp_path / "bad.yaml"
    path.write_text(scene_text(kind, params, 0.1))
    status = main(["check", str(path)])
    out = "".join(capsys.readouterr())
    assert status in (1, 2), out
    assert "Traceback" not in out
    assert f"error[{code}]" in out and "dyad" in out, out
    assert out.count("error[") == 1, out                    # that finding alone, no follow-up noise


# -- the 8-link mechanism of Ebert §7.1's structure (diagrams/linkages/eight_link.yaml) --------------------------

EIGHT = Path(__file__).resolve().parents[1] / "diagrams" / "linkages" / "eight_link.yaml"
# inertia states of the scene and the parameter (element, name) holding their mass [kg] or inertia [kg*m^2]
EIGHT_INERTIAS = {"crank.L.m{}.p": ("crank", "m"), "crank.L.J.p": ("crank", "J"),
                  "dsd.C.m{}0.p": ("dsd", "mU"), "dsd.C.J0.p": ("dsd", "JU"),
                  "dsd.C.m{}1.p": ("dsd", "mS"), "dsd.C.J1.p": ("dsd", "JS"),
                  "sds.C1.m{}0.p": ("sds", "m1"), "sds.C1.J0.p": ("sds", "J1"),
                  "sds.C2.m{}0.p": ("sds", "m2"), "sds.C2.J0.p": ("sds", "J2"),
                  "ssd.C.m{}0.p": ("ssd", "m1"), "ssd.C.J0.p": ("ssd", "J1"),
                  "ssd.C.m{}1.p": ("ssd", "m2"), "ssd.C.J1.p": ("ssd", "J2")}


def test_eight_link_checks_and_balances_energy():
    """check: well-posed, mobility 1, only the crank angle and the six closure-bound travels/angles are
    integrated.  simulate one revolution at 1.5 rad/s: the drive power equals d/dt (KE + PE), with KE from
    the bodies' momenta (p^2 / 2m) and dPE/dt = g * (sum of the y momenta), differentiated here by central
    differences of 4th order on a 1 ms grid (truncation ~ dt^4 KE^(5) / 30, far below the 3e-9 W bound
    against a drive power of 0.03 W);
    over the revolution the drive work is zero (the motion is periodic)."""
    import yaml
    spec = yaml.safe_load(EIGHT.read_text())["elements"]
    scene = mp.load(EIGHT)
    analysis = pipeline.check(scene)
    assert analysis.ok
    assert sorted(str(s.symbol) for s in analysis.states) == sorted(
        ["crank.L.K.q3", "dsd.C.K.q3", "dsd.C.K.q4", "sds.C1.K.q4", "sds.C2.K.q4", "ssd.C.K.q4", "ssd.C.K.q5"])
    names, inertia, y_momenta = [], [], []
    for pattern, (el, par) in EIGHT_INERTIAS.items():
        if float(spec[el].get(par, 0.0)) == 0.0:
            continue                        # a body part left out (massless, or a slider that cannot turn)
        for axis in ("x", "y") if "{}" in pattern else ("",):
            names.append(pattern.format(axis))
            inertia.append(float(spec[el][par]))
            if axis == "y":
                y_momenta.append(names[-1])
    res = pipeline.run(scene, dt_out=1e-3, outputs=["crank.torque", *names])
    tt = np.asarray(res.t)
    p = {n: np.asarray(res[n]) for n in names}
    ke = sum(p[n] ** 2 / (2 * j) for n, j in zip(names, inertia))
    dpe = G * sum(p[n] for n in y_momenta)
    h = tt[1] - tt[0]
    n = int(np.sum(np.abs(np.diff(tt) - h) < 1e-12 * h)) + 1           # the uniform part of the grid
    k = ke[:n]
    dke = (-k[4:] + 8 * k[3:-1] - 8 * k[1:-3] + k[:-4]) / (12 * h)     # 4th order: error ~ h^4 KE^(5) / 30
    power = np.asarray(res["crank.torque"]) * 1.5
    assert np.max(np.abs(power)) > 0.01
    assert np.max(np.abs(power[2:n - 2] - dke - dpe[2:n - 2])) < 1e-7 * np.max(np.abs(power))
    work = np.sum((power[1:] + power[:-1]) / 2 * np.diff(tt))   # trapezoid: error ~ dt^2 * T * P'' / 12
    assert abs(work) < 1e-6 * np.sum(np.abs(power[1:]) * np.diff(tt))


def test_zero_mass_and_inertia_in_a_netlist_leave_the_body_part_out():
    """``mS: 0`` and ``JS: 0`` in a netlist (sympy zeros after loading) build no inertia for the slider."""
    sc = mp.loads(scene_text("DSD", {**DSD, "mS": 0, "JS": 0.0}, 1.0), "dsd.yaml")
    names = {str(s.symbol) for s in pipeline.check(sc).flat.states}
    assert "dyad.C.mx0.p" in names and "dyad.C.J0.p" in names          # the guide keeps its mass
    assert not names & {"dyad.C.mx1.p", "dyad.C.my1.p", "dyad.C.J1.p"}
