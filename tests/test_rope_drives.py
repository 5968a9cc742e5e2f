"""Rope drives assembled from band_roll and band (issue 13): factor, power and differential pulley blocks.

Expected values come from the statics and kinematics of the rope written here: force equality across
frictionless rolls, the per-roll loss factor of a roll with pin friction in quasi-static lifting
(torque balance r F_out = r F_in + mu r_pin (F_in + F_out)), equilibrium of every loose block, and
material conservation of the rope (a span's length changes at (1 + strain) times the net inflow of
unstrained rope, the strain being F/EA).  The pulley block of Ebert 7.3.1 at mu = 0.25 and its
rope kinematics are tested in tests/test_belts.py; here: n sections, the power and differential
blocks, and the efficiency of the 7.3.1 block over a range of mu.
"""
from pathlib import Path

import numpy as np
import pytest

from multipole import pipeline
from multipole.netlist import load
from tests.helpers import scene

BELTS = Path(__file__).resolve().parents[1] / "diagrams" / "belts"
G, M, V, EA, R_PIN = 9.81, 100.0, 1.0, 1.0e6, 0.004
W = M * G


def _k(r, mu, r_pin=R_PIN):
    """Loss factor of a roll with 180 deg wrap in quasi-static motion: F_out = k F_in toward the side
    the rope runs to (torque balance r F_out = r F_in + mu r_pin (F_in + F_out))."""
    return (r + mu * r_pin) / (r - mu * r_pin)


def _final(res, name):
    return res.outputs[name][-1]


# -- factor pulley block: n load-carrying sections ------------------------------------------------

def factor_block(n: int) -> str:
    """Scene text of a factor block with n sections S1..Sn and the pull section P (the layout of
    diagrams/belts/factor_pulley.yaml, which is this text for n = 6): roll R_j joins S_j and S_(j+1),
    R_n is in the upper block, the rolls alternate downwards; the rope is tied to the upper block for
    even n and to the lower block for odd n."""
    upper = [(n - j) % 2 == 0 for j in range(1, n + 1)]
    lines = ["name: factor_pulley",
             "parameters: {m: 100.0, g: 9.81, EA: 1.0e6, cd: 2.0e4, v: 1.0, l: 2.0, mu: 0.0, r_pin: 0.004, "
             "r_up: 0.06, r_low: 0.05}", "elements:"]
    lines += [f"  S{j}: {{type: band, EA: EA, cd: cd, l: l, l0: l/(1 + m*g/{n}/EA), dir: -1}}" for j in range(1, n + 1)]
    lines.append(f"  P: {{type: band, EA: EA, cd: cd, l: 1.0, l0: 1.0/(1 + m*g/{n}/EA), dir: -1}}")
    conns = []
    for j in range(1, n + 1):
        r, end = ("r_up", "e1") if upper[j - 1] else ("r_low", "e2")
        lines.append(f"  R{j}: {{type: band_roll, r: {r}, J: 0.01, omega0: {j}*v/{n}/{r}, mu: mu, r_pin: r_pin}}")
        conns += [f"  - [S{j}.{end}, R{j}.e2]", f"  - [R{j}.e1, {f'S{j + 1}' if j < n else 'P'}.{end}]"]
    lines += [f"  load: {{type: mass, m: m, v0: v/{n}}}", "  weight: {type: force_source, value: -m*g}",
              "  pull: {type: velocity_source, value: -v}", "connections:"] + conns
    lines += ["  - [" + ", ".join(f"S{j}.p2" for j in range(1, n + 1)) + ", load.a, weight.p]", "  - [P.p2, pull.p]",
              "outputs: [load.v, P.F, " + ", ".join(f"S{j}.F" for j in range(1, n + 1)) + "]",
              "simulate: {t_end: 1.0, rtol: 1e-10, dt_out: 0.01}"]
    return "\n".join(lines) + "\n"


def _factor(n, **overrides):
    if n == 6:
        return load(BELTS / "factor_pulley.yaml", overrides)
    return scene(factor_block(n), overrides)


def test_factor_pulley_scene_is_the_six_section_block():
    """The scene file is the generated six-section block (plus its comments): the tests on n = 6 run it."""
    text = (BELTS / "factor_pulley.yaml").read_text()
    body = "\n".join(line for line in text.splitlines() if not line.startswith("#")) + "\n"
    assert body == factor_block(6)


@pytest.mark.parametrize("n", [1, 3, 6])
def test_factor_block_ideal_force_and_travel_ratio_is_one_over_n(n):
    """Frictionless rolls: every section and the pull carry W/n, and since every span then has the
    same strain the rope kinematics give the load speed v/n exactly (material conservation)."""
    res = pipeline.run(_factor(n), progress=False)
    for name in [f"S{j}" for j in range(1, n + 1)] + ["P"]:
        # measured <= 2e-11 relative at t = 1 s: the start transient has decayed
        assert _final(res, f"{name}.F") == pytest.approx(W / n, rel=1e-8), name
    assert _final(res, "load.v") == pytest.approx(V / n, rel=1e-9)


@pytest.mark.parametrize("n", [3, 6])
def test_factor_block_efficiency_with_pin_friction_from_first_principles(n):
    """mu = 0.25: each roll R_j multiplies the force toward the pull, F_(j+1) = k_j F_j; the lower
    block carries the sections, F_1 + ... + F_n = W; efficiency W/(n F_P)."""
    mu = 0.25
    res = pipeline.run(_factor(n, mu=mu), progress=False)
    radii = [0.06 if (n - j) % 2 == 0 else 0.05 for j in range(1, n + 1)]
    chain = np.cumprod([1.0] + [_k(r, mu) for r in radii])        # F_j / F_1, j = 1..n+1
    F1 = W / chain[:n].sum()
    for j in range(1, n + 1):
        assert _final(res, f"S{j}.F") == pytest.approx(F1 * chain[j - 1], rel=1e-6), j
    eta = W / (n * _final(res, "P.F"))
    assert eta == pytest.approx(chain[:n].sum() / (n * chain[n]), rel=1e-6)
    assert eta < 1 - 0.02 * n / 3          # every roll loses about 1.5 % (0.9147 for the 4-section block)


# -- power pulley block: k loose rolls ------------------------------------------------------------

def power_block(k: int) -> str:
    """Scene text of a power block with k loose rolls (diagrams/belts/power_pulley.yaml for k = 3)."""
    lines = ["name: power_pulley",
             "parameters: {m: 100.0, g: 9.81, m_roll: 1.0, EA: 1.0e6, cd: 2.0e4, v: 1.0, l: 2.0, mu: 0.0, "
             "r_pin: 0.004, r: 0.05, r_guide: 0.06}", "elements:"]
    conns = []
    for i in range(1, k + 1):
        F, u = f"m*g/{2 ** i}", f"v/{2 ** (k - i + 1)}"
        lines += [f"  a{i}: {{type: band, EA: EA, cd: cd, l: l, l0: l/(1 + {F}/EA), dir: -1}}",
                  f"  b{i}: {{type: band, EA: EA, cd: cd, l: 1.0, l0: 1.0/(1 + {F}/EA), dir: -1}}",
                  f"  L{i}: {{type: band_roll, r: r, J: 0.01, omega0: {u}/r, mu: mu, r_pin: r_pin}}"]
        node = ["load.a", "weight.p"] if i == 1 else [f"axle{i}.a", f"b{i - 1}.p1"]
        if i > 1:
            lines.append(f"  axle{i}: {{type: mass, m: m_roll, v0: {u}}}")
        conns += [f"  - [a{i}.e2, L{i}.e2]", f"  - [L{i}.e1, b{i}.e2]",
                  "  - [" + ", ".join([f"a{i}.p2", f"b{i}.p2"] + node) + "]"]
    lines += ["  G: {type: band_roll, r: r_guide, J: 0.01, omega0: v/r_guide, mu: mu, r_pin: r_pin}",
              f"  P: {{type: band, EA: EA, cd: cd, l: 1.0, l0: 1.0/(1 + m*g/{2 ** k}/EA), dir: -1}}",
              f"  load: {{type: mass, m: m, v0: v/{2 ** k}}}", "  weight: {type: force_source, value: -m*g}",
              "  pull: {type: velocity_source, value: -v}"]
    conns += [f"  - [b{k}.e1, G.e2]", "  - [G.e1, P.e1]", "  - [P.p2, pull.p]"]
    lines += ["connections:"] + conns
    lines += ["outputs: [load.v, P.F, " + ", ".join(f"a{i}.F, b{i}.F" for i in range(1, k + 1)) + "]",
              "simulate: {t_end: 1.0, rtol: 1e-10, dt_out: 0.01}"]
    return "\n".join(lines) + "\n"


def _power(k, **overrides):
    if k == 3:
        return load(BELTS / "power_pulley.yaml", overrides)
    return scene(power_block(k), overrides)


def test_power_pulley_scene_is_the_three_roll_block():
    text = (BELTS / "power_pulley.yaml").read_text()
    body = "\n".join(line for line in text.splitlines() if not line.startswith("#")) + "\n"
    assert body == power_block(3)


@pytest.mark.parametrize("k", [1, 3])
def test_power_block_ideal_force_and_travel_ratio_is_one_over_two_to_the_k(k):
    """Frictionless: rope i carries W/2^i in both sections (L_i hangs in it, b_(i-1) hangs on its
    axle), the pull W/2^k; the axle of L_i rises at twice the speed of L_(i-1) (a_i shortens as much
    as b_(i-1) lengthens, same strain), the load at v/2^k."""
    res = pipeline.run(_power(k), progress=False,
                       outputs=["load.v", "P.F"] + [f"{s}{i}.F" for i in range(1, k + 1) for s in "ab"]
                       + [f"axle{i}.v" for i in range(2, k + 1)])
    for i in range(1, k + 1):
        for s in "ab":
            assert _final(res, f"{s}{i}.F") == pytest.approx(W / 2 ** i, rel=1e-8), f"{s}{i}"
    assert _final(res, "P.F") == pytest.approx(W / 2 ** k, rel=1e-8)
    assert _final(res, "load.v") == pytest.approx(V / 2 ** k, rel=1e-9)
    for i in range(2, k + 1):
        assert _final(res, f"axle{i}.v") == pytest.approx(V / 2 ** (k - i + 1), rel=1e-9)


def test_power_block_efficiency_with_pin_friction_from_first_principles():
    """mu = 0.25, k = 3: roll L_i turns toward b_i, F_b = k_r F_a, and carries F_a + F_b = load_i
    (load_1 = W, load_(i+1) = F_b of rope i); the guide roll multiplies by k_g: the pull
    F_P = k_g W prod(k_r/(1 + k_r)), efficiency W/(8 F_P)."""
    mu, r, r_guide = 0.25, 0.05, 0.06
    res = pipeline.run(_power(3, mu=mu), progress=False)
    kr, kg = _k(r, mu), _k(r_guide, mu)
    load_i = W
    for i in range(1, 4):
        Fa = load_i / (1 + kr)
        assert _final(res, f"a{i}.F") == pytest.approx(Fa, rel=1e-6), i
        assert _final(res, f"b{i}.F") == pytest.approx(kr * Fa, rel=1e-6), i
        load_i = kr * Fa
    assert _final(res, "P.F") == pytest.approx(kg * load_i, rel=1e-6)
    eta = W / (8 * _final(res, "P.F"))
    assert eta == pytest.approx((1 + kr) ** 3 / (8 * kr ** 3 * kg), rel=1e-6)


# -- differential pulley block ---------------------------------------------------------------------

def _diff(**overrides):
    return load(BELTS / "differential_pulley.yaml", overrides)


def test_differential_block_force_ratio_and_travel_from_the_rope_kinematics():
    """R = 0.1 m, r = 0.08 m, frictionless: S1 and S2 carry W/2, the torque balance of the upper
    rolls R F_H + r F_S2 = R F_S1 gives F_H = W (R - r)/(2 R): advantage 2R/(R - r) = 10.  Rope
    kinematics with the strains e = F/EA: the hand section lengthens at v = (1 + e_H) R omega, S1
    and S2 shorten together by 2u = (1 + e_S)(R - r) omega, so u = v (R - r)/(2R) (1 + e_S)/(1 + e_H):
    the ratio (R - r)/(2R) of a rigid rope, stretched by the strain difference (4e-4 here)."""
    R, r = 0.1, 0.08
    res = pipeline.run(_diff(), progress=False)
    F_H = W * (R - r) / (2 * R)
    assert _final(res, "S1.F") == pytest.approx(W / 2, rel=1e-8)
    assert _final(res, "S2.F") == pytest.approx(W / 2, rel=1e-8)
    assert _final(res, "H.F") == pytest.approx(F_H, rel=1e-8)
    e_S, e_H = W / 2 / EA, F_H / EA
    assert _final(res, "big.omega") == pytest.approx(V / (R * (1 + e_H)), rel=1e-9)
    assert _final(res, "load.v") == pytest.approx(V * (R - r) / (2 * R) * (1 + e_S) / (1 + e_H), rel=1e-9)
    # the rigid-rope ratio is the limit: a 1000x stiffer rope moves the load within 1e-6 of it
    stiff = pipeline.run(_diff(EA=1e9, cd=2e7), progress=False)
    assert _final(stiff, "load.v") == pytest.approx(V * (R - r) / (2 * R), rel=1e-6)


def test_differential_block_efficiency_with_pin_friction_from_first_principles():
    """mu = 0.25: the loose roll turns toward S1, F_S1 = k_L F_S2 with F_S1 + F_S2 = W; the upper
    rolls (one shaft, pin loads F_H + F_S1 on the big and F_S2 on the small roll, all parallel):
    R F_H = R F_S1 - r F_S2 + mu r_pin (F_H + F_S1 + F_S2); efficiency W (R - r)/(2 R F_H).
    (0.825 here: R - r = 20 mm is large against mu r_pin = 1 mm.)"""
    mu, R, r, r_low = 0.25, 0.1, 0.08, 0.09
    res = pipeline.run(_diff(mu=mu), progress=False)
    kL = _k(r_low, mu)
    F_S2 = W / (1 + kL)
    F_S1 = kL * F_S2
    F_H = (R * F_S1 - r * F_S2 + mu * R_PIN * (F_S1 + F_S2)) / (R - mu * R_PIN)
    assert _final(res, "S1.F") == pytest.approx(F_S1, rel=1e-6)
    assert _final(res, "S2.F") == pytest.approx(F_S2, rel=1e-6)
    assert _final(res, "H.F") == pytest.approx(F_H, rel=1e-6)
    eta = W * (R - r) / (2 * R * _final(res, "H.F"))
    assert eta == pytest.approx(W * (R - r) / (2 * R * F_H), rel=1e-6)
    assert 0.8 < eta < 0.85


# -- Ebert 7.3.1: efficiency falls linearly with mu ------------------------------------------------

def test_pulley_block_efficiency_falls_linearly_with_mu():
    """The 7.3.1 block (100 kg, 4 sections, bolt 8 mm) for mu = 0.05 ... 0.4: each efficiency
    against the first-principles chain (1e-6); the efficiencies lie on a straight line (Ebert Bild
    7.24) whose slope is the first-principles slope: the curvature of eta(mu) is second order in
    mu r_pin/r <= 0.032: the points leave the line by 1 % of the fall of eta over the range."""
    mus = np.array([0.05, 0.15, 0.25, 0.4])
    radii = (0.05, 0.06, 0.05, 0.06)
    etas, theory = [], []
    for mu in mus:
        res = pipeline.run(load(BELTS / "pulley_block.yaml", {"mu": float(mu)}), progress=False, outputs=["E.F"])
        etas.append(W / (4 * _final(res, "E.F")))
        chain = np.cumprod([1.0] + [_k(r, mu) for r in radii])
        theory.append(chain[:4].sum() / (4 * chain[4]))
    etas, theory = np.array(etas), np.array(theory)
    np.testing.assert_allclose(etas, theory, rtol=1e-6)
    slope, icept = np.polyfit(mus, etas, 1)
    t_slope, t_icept = np.polyfit(mus, theory, 1)
    assert slope == pytest.approx(t_slope, rel=1e-4)
    assert slope == pytest.approx(-0.326, rel=0.01)              # about 3.3 % per 0.1 of mu
    # linear: the points leave the line by at most 1.2e-3 (first principles: 1.15e-3) while
    # the efficiency falls by 0.114 over the range, and the line starts at 1 within 3e-3
    assert np.max(np.abs(etas - (slope * mus + icept))) < 1.2e-3
    assert icept == pytest.approx(1.0, abs=3e-3)


# -- the tilting-mast cable crane (Ebert 8.1) ------------------------------------------------------

CRANE_SPANS = ["c1", "c2", "c3", "l1", "l2", "l3", "l4", "l5", "l6", "a1", "a2", "a3"]
CRANE_ROLLS = ["MC1", "MC2", "ML", "MR", "C1", "C2", "H", "MF", "MA"]


def test_crane_has_the_same_states_with_ten_times_longer_spans():
    """A rope's size does not grow with its length: the drum hands the wound length on as a position
    and each free rope is one span (one stretch state), so 10x longer spans (L = 500 m, the valley
    ropes 300 m) give the same 34 states: 12 stretches, 9 rolls x 2, 2 drum angles, carriage, hook."""
    short = pipeline.check(load(BELTS / "crane.yaml"))
    long = pipeline.check(load(BELTS / "crane.yaml", {"L": 500.0, "l_s": 300.0}))
    assert short.ok and long.ok
    assert long.assembled.state_names == short.assembled.state_names
    assert len(short.assembled.state_names) == 12 + 2 * 9 + 2 + 2
    assert {f"{s}.c.q" for s in CRANE_SPANS} <= set(short.assembled.state_names)


def test_crane_energy_balance_over_the_lift():
    """Lift (0 .. 12.5 s: D1 winds 9 m of rope in with ramps of 2 s, the hook rises 4.5 m): the work
    of the two drum drives equals the change of kinetic energy (carriage, hook with load, rolls,
    drums), potential energy of the hook and strain energy EA delta^2/(2 l_x) of the 12 spans, plus
    the damper losses and the strain energy of the rope material entering a span unstrained from a
    roll, F_k^2/(2 EA) l_x'
    (docs/belts.md).  Quadrature: trapezoids on the output grid; the drum torques jump at the ramp
    corners (drum inertia), which makes the trapezoid error first order in dt: the balance is
    extrapolated from dt and 2 dt (Richardson), and must close to 2e-6 of the work (measured 6e-8;
    without the convected strain term it misses by 2e-4)."""
    outs = ["carriage.v", "hook.v", "drive1.p.e", "drive1.p.f", "drive2.p.e", "drive2.p.f", "D1.omega", "D2.omega"]
    outs += [f"{r}.omega" for r in CRANE_ROLLS]
    outs += [f"{s}.{q}" for s in CRANE_SPANS for q in ("F", "stretch", "free", "rate", "e1.l.f", "e2.l.f")]
    res = pipeline.run(load(BELTS / "crane.yaml"), progress=False, outputs=outs, t_end=12.5, dt_out=0.01, rtol=1e-8)
    o, t = res.outputs, res.t
    EA, m_move, m_hook, J_m, J_d = 1.2e7, 1200.0, 1050.0, 0.02, 20.0

    def integral(f, step):
        return np.concatenate([[0.0], np.cumsum(0.5 * (f[step::step] + f[:-step:step]) * np.diff(t[::step]))])

    Fk = {s: EA * np.maximum(o[f"{s}.stretch"], 0.0) / o[f"{s}.free"] for s in CRANE_SPANS}
    kinetic = (0.5 * m_move * o["carriage.v"] ** 2 + 0.5 * m_hook * o["hook.v"] ** 2
               + sum(0.5 * J_m * o[f"{r}.omega"] ** 2 for r in CRANE_ROLLS)
               + 0.5 * J_d * (o["D1.omega"] ** 2 + o["D2.omega"] ** 2))
    strain = sum(Fk[s] ** 2 * o[f"{s}.free"] / (2 * EA) for s in CRANE_SPANS)
    work_in = -(o["drive1.p.e"] * o["drive1.p.f"] + o["drive2.p.e"] * o["drive2.p.f"])   # into the drums
    loss = sum((o[f"{s}.F"] - Fk[s]) * o[f"{s}.rate"] for s in CRANE_SPANS)
    convected = sum(Fk[s] ** 2 / (2 * EA) * (o[f"{s}.e1.l.f"] + o[f"{s}.e2.l.f"]) for s in CRANE_SPANS)
    assert np.all(loss >= -1e-9 * np.abs(work_in).max())
    balance = {}
    for step in (1, 2):
        height = integral(o["hook.v"], step)
        energy = (kinetic + strain)[::step] + m_hook * G * height
        balance[step] = integral(work_in - loss - convected, step) - (energy - energy[0])
        without = integral(work_in - loss, step) - (energy - energy[0])
    work = integral(work_in, 1)[-1]
    assert work == pytest.approx(m_hook * G * 4.5, rel=5e-3)            # the hook rose 4.5 m
    extrapolated = 2 * balance[1][-1] - balance[2][-1]
    assert abs(extrapolated) < 2e-6 * work
    assert abs(without[-1]) > 1e-4 * work
