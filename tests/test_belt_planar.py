"""Planar bands (issue 13): spans on the common tangent of two circles, rolls on planar ports.

Expected values come from plane geometry written here (tangent lengths of two circles and of a
point and a circle, tangent points perpendicular to the span), the 1-D band of elements/belt.py on
the same fixed geometry, the kinematics of the lever that carries the roll, energy balances and the
static moment balance of a tensioner lever.
"""
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson
from scipy.interpolate import CubicSpline

from multipole import MultipoleError, pipeline
from multipole.netlist import load
from tests.helpers import codes, run, scene

BELTS = Path(__file__).resolve().parents[1] / "diagrams" / "belts"


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


# -- tangent geometry ---------------------------------------------------------------------------

SPAN = """
name: span
elements:
  s: {type: planar_band, F0: 10.0, r1: 0.05, s1: %d, r2: 0.1, s2: %d, x1: 0.0, y1: 0.0, x2: 0.3, y2: 0.2}
outputs: [s.length, s.gamma, s.xK1, s.yK1, s.xK2, s.yK2, s.F]
simulate: {t_end: 0.01}
"""


@pytest.mark.parametrize("s1, s2", [(1, -1), (-1, 1), (1, 1), (-1, -1)])
def test_span_lies_on_the_common_tangent_of_the_two_circles(s1, s2):
    """Circles (0, 0), r1 = 50 mm and (0.3, 0.2), r2 = 100 mm: an open belt (s1 = -s2) runs on an
    external tangent of length sqrt(d^2 - (r1 - r2)^2), a crossed belt (s1 = s2) on an internal one,
    sqrt(d^2 - (r1 + r2)^2); the tangent points lie on the circles with radii perpendicular to the
    span, and the wrap sense s_i = cross(K_i - C_i, direction into the span)/r_i is the one asked for."""
    res = run(SPAN % (s1, s2))
    o = {k: v[0] for k, v in res.outputs.items()}
    C1, C2, r1, r2 = np.array([0.0, 0.0]), np.array([0.3, 0.2]), 0.05, 0.1
    d2 = 0.3 ** 2 + 0.2 ** 2
    expected = math.sqrt(d2 - (r1 - r2) ** 2) if s1 == -s2 else math.sqrt(d2 - (r1 + r2) ** 2)
    K1, K2 = np.array([o["s.xK1"], o["s.yK1"]]), np.array([o["s.xK2"], o["s.yK2"]])
    span = K2 - K1
    assert o["s.length"] == pytest.approx(expected, rel=1e-12)
    assert np.linalg.norm(span) == pytest.approx(expected, rel=1e-12)
    assert np.linalg.norm(K1 - C1) == pytest.approx(r1, rel=1e-12)
    assert np.linalg.norm(K2 - C2) == pytest.approx(r2, rel=1e-12)
    assert abs(np.dot(K1 - C1, span)) < 1e-12 and abs(np.dot(K2 - C2, span)) < 1e-12
    assert _cross(K1 - C1, span / expected) == pytest.approx(s1 * r1, rel=1e-12)
    assert _cross(K2 - C2, -span / expected) == pytest.approx(s2 * r2, rel=1e-12)
    g = math.atan2(span[1], span[0])
    assert math.remainder(o["s.gamma"] - g, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    assert res.outputs["s.F"][-1] == pytest.approx(10.0, rel=1e-9)      # nothing moves: the pretension


# -- a roll on a lever: the tensioner -----------------------------------------------------------

#: band from the frame point A over a roll on a lever (DAN pivoted at O) to the frame point B; a
#: preloaded torsion spring and a damper on the lever's joint press the roll into the band
TENSIONER = """
name: tensioner
parameters: {k: 200.0, x0: -0.5, EA: 2.0e4, dl: 2.0, cd: 5.0, F0: 300.0}
elements:
  lever: {type: DAN, l: 0.18, phi0: 1.5707963267948966, m: 0.0, J: 1.0e-3, x1: 0.2, y1: -0.2}
  spring: {type: spring, c: k, x0: x0}
  damper: {type: damper, d: dl}
  roll: {type: planar_roll, r: 0.03, J: 1.0e-4}
  left: {type: planar_band, EA: EA, cd: cd, F0: F0, r2: 0.03, s2: -1, x1: 0.0, y1: 0.0}
  right: {type: planar_band, EA: EA, cd: cd, F0: F0, r1: 0.03, s1: 1, x2: 0.4, y2: 0.0}
connections:
  - [lever.drive, spring.a, damper.a]
  - [spring.b, damper.b, lever.support]
  - [lever.b, roll.a]
  - [roll.c, left.p2, right.p1]
  - [roll.e2, left.e2]
  - [roll.e1, right.e1]
outputs: [lever.phi, lever.omega, roll.omega, spring.deflection, left.F, right.F, left.free, right.free,
          left.stretch, right.stretch, left.length, right.length, left.gamma, right.gamma,
          left.xK2, left.yK2, right.xK1, right.yK1, roll.x, roll.y, roll.Fx, roll.Fy, roll.lr1, roll.lr2]
simulate: {t_end: 2.0, rtol: 1.0e-9}
"""
O, L_LEVER, A, B, R_ROLL, J_LEVER, J_ROLL, K_SPRING = (np.array([0.2, -0.2]), 0.18, np.array([0.0, 0.0]),
                                                       np.array([0.4, 0.0]), 0.03, 1e-3, 1e-4, 200.0)


def _point_circle_tangent(P, C, r, sense):
    """The tangent from the point P to the circle (C, r) whose radius at the tangent point K satisfies
    cross(K - C, K - P) = sense * r * |K - P|: (K, unit vector P -> K)."""
    d = C - P
    L = np.linalg.norm(d)
    a = math.asin(r / L)
    for sign in (1, -1):
        c, s = math.cos(sign * a), math.sin(sign * a)
        t = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]]) / L
        K = P + t * math.sqrt(L ** 2 - r ** 2)
        if _cross(K - C, t) * sense > 0:
            return K, t
    raise AssertionError("no tangent")


def _tangents(phi):
    """Roll centre on the lever at the angle phi; the left span A -> K_l (wrap sense -1 at the roll:
    cross(K_l - C, t_l) = +r), the right span K_r -> B (sense +1 at the roll)."""
    C = O + L_LEVER * np.array([math.cos(phi), math.sin(phi)])
    K_l, t_l = _point_circle_tangent(A, C, R_ROLL, +1)
    K_r, t_back = _point_circle_tangent(B, C, R_ROLL, -1)        # from B back to the roll
    return C, (K_l, t_l), (K_r, -t_back)


def test_tensioner_spans_follow_the_roll_on_the_lever():
    """At every output time the spans' lengths are the point-circle tangent lengths
    sqrt(|C - A|^2 - r^2) for the roll centre C on the lever (C = O + l e(phi)), the tangent points
    those of the plane construction, and the inclinations continuous."""
    res = run(TENSIONER)
    o = res.outputs
    for k in range(0, len(res.t), 25):
        C, (K_l, t_l), (K_r, t_r) = _tangents(o["lever.phi"][k])
        assert o["roll.x"][k] == pytest.approx(C[0], abs=1e-12) and o["roll.y"][k] == pytest.approx(C[1], abs=1e-12)
        assert o["left.length"][k] == pytest.approx(math.sqrt(np.sum((C - A) ** 2) - R_ROLL ** 2), rel=1e-10)
        assert o["right.length"][k] == pytest.approx(math.sqrt(np.sum((C - B) ** 2) - R_ROLL ** 2), rel=1e-10)
        np.testing.assert_allclose([o["left.xK2"][k], o["left.yK2"][k]], K_l, atol=1e-10)
        np.testing.assert_allclose([o["right.xK1"][k], o["right.yK1"][k]], K_r, atol=1e-10)
        assert o["left.gamma"][k] == pytest.approx(math.atan2(t_l[1], t_l[0]), abs=1e-10)
        assert o["right.gamma"][k] == pytest.approx(math.atan2(t_r[1], t_r[0]), abs=1e-10)
    assert np.max(np.abs(np.diff(o["left.gamma"]))) < 0.1     # never wrapped


def test_tensioner_band_material_is_conserved():
    """The band is tied at A and B: its free lengths plus the arc r*beta wrapped on the roll (beta:
    the angle from the left to the right tangent point, constructed from the tangent points) stay
    constant, and each span's free length l_B - delta changes by the roll's wound length
    l_r = s r [(phi - phi0) - (gamma - gamma0)] (Ebert 4.95 corrected: without the gamma term the
    lever's swing would be missing)."""
    res = run(TENSIONER)
    o = res.outputs
    C = np.stack([o["roll.x"], o["roll.y"]], axis=1)
    K_l = np.stack([o["left.xK2"], o["left.yK2"]], axis=1) - C
    K_r = np.stack([o["right.xK1"], o["right.yK1"]], axis=1) - C
    beta = np.unwrap(np.arctan2(K_r[:, 1], K_r[:, 0]) - np.arctan2(K_l[:, 1], K_l[:, 0]))
    assert 0 < beta.min() and np.ptp(beta) > 0.1                 # wrapped, and the wrap changes
    total = o["left.free"] + o["right.free"] + R_ROLL * beta
    # measured 1.2e-11 m over a change of the free lengths of 0.06 m (rtol 1e-9 of the run)
    np.testing.assert_allclose(total, total[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(o["left.free"] - o["left.free"][0], o["roll.lr2"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(o["right.free"] - o["right.free"][0], o["roll.lr1"], rtol=0, atol=1e-9)
    assert np.ptp(o["roll.lr1"]) > 0.05


def test_tensioner_tension_against_the_static_moment_balance():
    """After the damped start the lever rests: the frictionless roll carries the same tension F on
    both sides, the resultant F (t_r - t_l) acts on its centre C, and its moment about the pivot O
    balances the spring torque: (C - O) x F (t_r - t_l) = c q with the deflection q = x0 + phi - phi0
    (t_l, t_r: the tangent directions constructed here at the final lever angle)."""
    res = run(TENSIONER)
    o = {k: v[-1] for k, v in res.outputs.items()}
    assert abs(o["lever.omega"]) < 1e-6 and abs(o["roll.omega"]) < 1e-6           # at rest
    C, (_K_l, t_l), (_K_r, t_r) = _tangents(o["lever.phi"])
    q = -0.5 + o["lever.phi"] - math.pi / 2
    F = K_SPRING * q / _cross(C - O, t_r - t_l)
    assert F > 0
    assert o["left.F"] == pytest.approx(F, rel=1e-6)
    assert o["right.F"] == pytest.approx(F, rel=1e-6)
    # the span forces on the roll's centre, as its outputs report them
    assert o["roll.Fx"] == pytest.approx(F * (t_r - t_l)[0], rel=1e-6)
    assert o["roll.Fy"] == pytest.approx(F * (t_r - t_l)[1], rel=1e-6)


@pytest.mark.parametrize("m", [0.0, 0.3])
def test_free_motion_of_the_lever_conserves_energy(m):
    """No damping: kinetic energies of lever and roll (its mass m on the lever tip, in gravity) +
    spring energy + band strain energies EA delta^2/(2 l_x) + the strain energy carried across the
    band ends with the material, integral of F^2/(2 EA) dl_x (the wrapped band is inextensible, see
    docs/belts.md), is constant.  The last term is integrated here from the sampled run (cubic
    spline of l_x, Simpson): its quadrature error falls as dt_out^4 (5e-7 J at dt_out = 1e-4 s,
    measured; 4e-11 relative at the 2.5e-5 s used)."""
    text = TENSIONER.replace("roll: {type: planar_roll, r: 0.03, J: 1.0e-4}",
                             f"roll: {{type: planar_roll, r: 0.03, J: 1.0e-4, m: {m}}}")
    res = pipeline.run(scene(text, {"dl": 0.0, "cd": 0.0, "x0": -0.1}), progress=False,
                       rtol=1e-12, atol=1e-14, t_end=0.2, dt_out=2.5e-5)
    o, EA = res.outputs, 2.0e4
    assert min(o["left.F"].min(), o["right.F"].min()) > 100        # stays taut (no switching)
    assert np.ptp(o["lever.phi"]) > 0.05 and np.ptp(o["roll.omega"]) > 10   # the lever swings, the roll turns
    energy = 0.5 * J_LEVER * o["lever.omega"] ** 2 + 0.5 * J_ROLL * o["roll.omega"] ** 2 \
        + 0.5 * K_SPRING * o["spring.deflection"] ** 2 \
        + 0.5 * m * (L_LEVER * o["lever.omega"]) ** 2 + m * 9.81 * o["roll.y"]
    for span in ("left", "right"):
        lx = o[f"{span}.free"]
        energy = energy + EA * o[f"{span}.stretch"] ** 2 / (2 * lx)
        energy = energy + cumulative_simpson(o[f"{span}.F"] ** 2 / (2 * EA) * CubicSpline(res.t, lx)(res.t, 1),
                                             x=res.t, initial=0)
    drift = np.max(np.abs(energy - energy[0]))
    assert drift <= 1e-8 * energy[0], drift


# -- power balance at random states -------------------------------------------------------------

def _power(vals, path, ports):
    return sum(vals[f"{path}.{p}.e"] * vals[f"{path}.{p}.f"] for p in ports)


@pytest.mark.parametrize("seed, mu", [(0, 0.0), (1, 0.0), (2, 0.3), (3, 0.3)])
def test_power_balance_of_span_and_roll_at_random_states(seed, mu):
    """Tensioner model at random states: the lever angle and speed give the roll centre C and its
    velocity v_C = l omega e_perp; the span's stretch rate is t . (v_2 - v_1) - s r omega_roll
    (tangent directions constructed here); the tension F = max(0, EA delta/l_x + cd delta'/l_x)
    (delta > 0, l_x = l_B - delta); the sum of each span's port powers is F delta' with no power at
    its gamma ports; the sum of the roll's port powers is d/dt J omega^2/2 plus, with pin friction,
    the loss mu r_pin |F_r t_r - F_l t_l| |omega_roll - omega_lever| (the housing turns with the lever)."""
    rng = np.random.default_rng(seed)
    outs = ["left.rate", "right.rate", "roll.phi", "roll.F1", "roll.F2", "roll.friction"]
    text = TENSIONER.replace("roll: {type: planar_roll, r: 0.03, J: 1.0e-4}",
                             f"roll: {{type: planar_roll, r: 0.03, J: 1.0e-4, mu: {mu}, r_pin: 0.005}}")
    model = pipeline.model(scene(text), outs, prune=False)
    names = list(model.state_names)
    EA, cd = 2.0e4, 5.0
    for _trial in range(3):
        x = np.asarray(model.x0, dtype=float).copy()
        st = dict(zip(names, x))
        st.update({"lever.L.K.q3": rng.uniform(1.5, 2.0), "lever.L.J.p": rng.uniform(-0.02, 0.02),
                   "spring.q": rng.uniform(-0.5, 0.0), "roll.R.J.p": rng.uniform(-0.02, 0.02),
                   "roll.R.tap.q": rng.uniform(-3, 3), "left.c.q": rng.uniform(-1e-4, 1e-2),
                   "right.c.q": rng.uniform(-1e-4, 1e-2)})
        x = np.array([st[n] for n in names])
        vals, dx = model.port_values(0.1, x), dict(zip(names, model.rhs(0.1, x)))
        phi, omega, w_roll = st["lever.L.K.q3"], st["lever.L.J.p"] / J_LEVER, st["roll.R.J.p"] / J_ROLL
        C, (_K_l, t_l), (_K_r, t_r) = _tangents(phi)
        v_C = L_LEVER * omega * np.array([-math.sin(phi), math.cos(phi)])
        rates = {"left": np.dot(t_l, v_C) + R_ROLL * w_roll, "right": -np.dot(t_r, v_C) - R_ROLL * w_roll}
        lengths = {"left": math.sqrt(np.sum((C - A) ** 2) - R_ROLL ** 2),
                   "right": math.sqrt(np.sum((C - B) ** 2) - R_ROLL ** 2)}
        tension = {}
        for span in ("left", "right"):
            delta, rate = st[f"{span}.c.q"], rates[span]
            assert dx[f"{span}.c.q"] == pytest.approx(rate, rel=1e-10, abs=1e-12), span
            lx = lengths[span] - delta
            F = max(0.0, EA * delta / lx + cd * rate / lx) if delta > 0 else 0.0
            tension[span] = F
            assert vals[f"{span}.J.s.e"] == pytest.approx(F, rel=1e-10, abs=1e-9), span
            ports = ["K.b1", "K.b2", "K.b3", "K.b4", "J.e1", "J.e2", "G.e1", "G.e2", "t1.p", "t2.p"]
            assert _power(vals, span, ["G.e1", "G.e2"]) == 0
            assert _power(vals, span, ports) == pytest.approx(F * rate, rel=1e-10, abs=1e-9), span
        out = dict(zip(model.output_names, np.asarray(model.outputs(0.1, x), dtype=float)))
        for span in ("left", "right"):
            assert out[f"{span}.rate"] == pytest.approx(rates[span], rel=1e-10, abs=1e-12), span
        assert out["roll.phi"] == st["roll.R.tap.q"]
        assert out["roll.F1"] == pytest.approx(tension["right"], rel=1e-10, abs=1e-9)     # e1: the right span
        assert out["roll.F2"] == pytest.approx(tension["left"], rel=1e-10, abs=1e-9)
        ports = ["xJ.a", "yJ.a", "H.a", "xJ.c", "yJ.c", "H.c", "R.T1.a", "R.T2.a", "G1.o", "G2.o",
                 "D.o" if mu else "R.W.drive"]
        dE = w_roll * dx["roll.R.J.p"]
        load = np.linalg.norm(tension["right"] * t_r - tension["left"] * t_l)
        friction = mu * 0.005 * load * np.sign(w_roll - omega)
        assert out["roll.friction"] == pytest.approx(friction, rel=1e-10, abs=1e-12)
        loss = friction * (w_roll - omega)
        assert _power(vals, "roll", ports) == pytest.approx(dE + loss, rel=1e-10, abs=1e-9)
        # the roll's torque from the band: r (F_right - F_left) (w = +1: e1 pays out into the right span)
        assert dx["roll.R.J.p"] == pytest.approx(R_ROLL * (tension["right"] - tension["left"]) - friction,
                                                 rel=1e-10, abs=1e-9)


# -- fixed geometry: the 1-D band and roll ------------------------------------------------------

PLANAR_DRIVE = """
name: drive_planar
parameters: {w: 10.0, F0: 200.0, EA: 1.0e5, cd: 20.0, rate: 25.0}
elements:
  motor: {type: speed_source, value: w}
  p1: {type: planar_roll, r: 0.05, J: 1.0e-3}
  p2: {type: planar_roll, r: 0.1, J: 4.0e-3, omega0: w*0.05/0.1, x1: 0.8}
  tight: {type: planar_band, EA: EA, cd: cd, F0: F0, r1: 0.1, s1: 1, r2: 0.05, s2: -1}
  slack: {type: planar_band, EA: EA, cd: cd, F0: F0, r1: 0.05, s1: 1, r2: 0.1, s2: -1}
  load: {type: torque_source, value: -rate*t}
connections:
  - [motor.p, p1.drive]
  - [p1.e1, slack.e1]
  - [slack.e2, p2.e2]
  - [p2.e1, tight.e1]
  - [tight.e2, p1.e2]
  - [load.p, p2.drive]
  - [p1.c, slack.p1, tight.p2]
  - [p2.c, slack.p2, tight.p1]
outputs: [p2.omega, tight.F, slack.F, tight.length]
simulate: {t_end: 0.5, rtol: 1.0e-10}
"""
LINE_DRIVE = """
name: drive_1d
parameters: {w: 10.0, F0: 200.0, EA: 1.0e5, cd: 20.0, rate: 25.0, l: %r}
elements:
  motor: {type: speed_source, value: w}
  p1: {type: band_roll, r: 0.05, J: 1.0e-3}
  p2: {type: band_roll, r: 0.1, J: 4.0e-3, omega0: w*0.05/0.1}
  tight: {type: band, EA: EA, cd: cd, l: l, l0: l*EA/(EA + F0)}
  slack: {type: band, EA: EA, cd: cd, l: l, l0: l*EA/(EA + F0)}
  load: {type: torque_source, value: -rate*t}
connections:
  - [motor.p, p1.drive]
  - [p1.e1, slack.e1]
  - [slack.e2, p2.e2]
  - [p2.e1, tight.e1]
  - [tight.e2, p1.e2]
  - [load.p, p2.drive]
outputs: [p2.omega, tight.F, slack.F]
simulate: {t_end: 0.5, rtol: 1.0e-10}
""" % math.sqrt(0.8 ** 2 - 0.05 ** 2)


@pytest.mark.parametrize("seed", range(2))
def test_fixed_axes_reproduce_the_one_dimensional_band_and_roll(seed):
    """Two frame-fixed rolls (r = 50 and 100 mm, 0.8 m apart) with an open belt: the planar spans
    have the external tangent length sqrt(0.8^2 - 0.05^2) and do not turn, so the model is the 1-D
    belt drive with that span length: the same state derivatives and tensions at random states
    (random roll angles and speed, the stretches those of the same free lengths)."""
    planar = pipeline.model(scene(PLANAR_DRIVE), prune=False)
    line = pipeline.model(scene(LINE_DRIVE), prune=False)
    rng = np.random.default_rng(seed)
    common = {"p2.J.p": "p2.R.J.p", "p1.tap.q": "p1.R.tap.q", "p2.tap.q": "p2.R.tap.q",
              "tight.c.q": "tight.c.q", "slack.c.q": "slack.c.q"}
    x1 = {n: v for n, v in zip(line.state_names, line.x0)}
    x2 = {n: v for n, v in zip(planar.state_names, planar.x0)}
    # the 1-D span keeps its free length l0 + l_r1 + l_r2 from the rolls' angles, the planar one
    # l_B - delta from its stretch: states on one trajectory have delta = l_B - l0 - l_r1 - l_r2
    lb = math.sqrt(0.8 ** 2 - 0.05 ** 2)
    l0 = lb * 1.0e5 / (1.0e5 + 200.0)
    phi1, phi2 = rng.uniform(-0.01, 0.01, 2)
    x1["p2.J.p"] = x2["p2.R.J.p"] = rng.uniform(0.0, 0.04)
    x1["p1.tap.q"], x1["p2.tap.q"] = x2["p1.R.tap.q"], x2["p2.R.tap.q"] = phi1, phi2
    x1["tight.c.q"] = x2["tight.c.q"] = lb - l0 - (0.1 * phi2 - 0.05 * phi1)
    x1["slack.c.q"] = x2["slack.c.q"] = lb - l0 - (0.05 * phi1 - 0.1 * phi2)
    assert set(line.state_names) <= set(common)
    t = 0.3
    d1 = dict(zip(line.state_names, line.rhs(t, np.array([x1[n] for n in line.state_names]))))
    d2 = dict(zip(planar.state_names, planar.rhs(t, np.array([x2[n] for n in planar.state_names]))))
    for one in line.state_names:
        assert d2[common[one]] == pytest.approx(d1[one], rel=1e-12, abs=1e-12), one
    v1 = line.port_values(t, np.array([x1[n] for n in line.state_names]))
    v2 = planar.port_values(t, np.array([x2[n] for n in planar.state_names]))
    for span in ("tight", "slack"):
        assert v2[f"{span}.J.s.e"] == pytest.approx(-v1[f"{span}.J.x.e"], rel=1e-12, abs=1e-12)
    res = run(PLANAR_DRIVE)
    assert res.outputs["tight.length"][-1] == pytest.approx(math.sqrt(0.8 ** 2 - 0.05 ** 2), rel=1e-14)


# -- bad input ----------------------------------------------------------------------------------

def test_wrap_sense_other_than_plus_or_minus_one_is_refused():
    with pytest.raises(MultipoleError) as exc:
        pipeline.check(scene(SPAN.replace("s1: %d", "s1: 0.5") % (1,)))
    assert exc.value.code == "bad_wrap_sense"


@pytest.mark.parametrize("centre, r1, senses", [("x2: 0.15, y2: 0.0", "r1: 0.15", (1, 1)),
                                                ("x2: 0.0, y2: 0.0", "r1: 0.1", (1, -1))])
def test_circles_without_room_for_the_tangent_cannot_assemble(centre, r1, senses):
    """Internal tangent of circles 0.15 m apart with r1 + r2 = 0.15 + 0.05: no tangent exists; equal
    concentric circles: an external tangent of zero length (no direction). Both are refused by check
    with the condition's text, naming the span."""
    text = SPAN.replace("x2: 0.3, y2: 0.2", centre).replace("r1: 0.05", r1) % senses
    found = [d for d in pipeline.check(scene(text)).diagnostics if d.code == "cannot_assemble"]
    assert found and "no room for a tangent" in found[0].message and "s " in found[0].message


@pytest.mark.parametrize("change", [("r2: 0.03, s2: -1", "r2: 0.04, s2: -1"), ("r2: 0.03, s2: -1", "r2: 0.03, s2: 1"),
                                    ("[roll.c, left.p2, right.p1]", "[roll.c, right.p1]")])
def test_span_that_disagrees_with_its_roll_is_refused(change):
    """The span must know the roll's radius and wrap sense and pull its centre: a wrong radius, a wrong
    sense (the other tangent: a crossed instead of an open wrap) or a p port joined elsewhere (here
    left frame-fixed at the origin, the tangent of a circle about A) is an error of check."""
    assert "planar_band_roll" not in codes(TENSIONER)
    text = TENSIONER.replace(*change)
    if "left.p2" not in text:
        text = text.replace("r2: 0.03, s2: -1, x1: 0.0, y1: 0.0", "r2: 0.03, s2: -1, x1: 0.0, y1: 0.0, x2: 0.5")
    assert "planar_band_roll" in codes(text)


def planar_triggers() -> dict:
    """The planar span's static check's triggering netlist, for tests/test_diagnostics_text.py."""
    return {"planar_band_roll": (lambda: scene(TENSIONER.replace("r2: 0.03, s2: -1", "r2: 0.03, s2: 1")),
                                 ["left.e2", "roll.e2", "s2 = +1"])}


# -- run-time monitors on a moving wrap ---------------------------------------------------------

def test_band_lifting_off_a_roll_on_a_lever_is_reported():
    """The lever (pivot now at (0.2, -0.12)) swings the roll up through the line AB (y = 0): the wrap
    w (gamma1 - gamma2) - pi falls to 0 when the line AB is tangent to the roll from below, i.e. at
    the roll centre's height y = r; band_lifts_off is reported there (the run goes on)."""
    text = TENSIONER.replace("phi0: 1.5707963267948966, m: 0.0, J: 1.0e-3, x1: 0.2, y1: -0.2",
                             "phi0: 0.6, m: 0.0, J: 1.0e-3, x1: 0.2, y1: -0.12") \
        .replace("k: 200.0, x0: -0.5", "k: 20.0, x0: -1.0").replace("roll.lr2]", "roll.lr2, roll.wrap]")
    res = pipeline.run(scene(text), progress=False, t_end=1.0)
    assert res.outputs["roll.wrap"][0] > 1.0 and res.outputs["roll.wrap"][-1] < 0
    found = [m for m in res.monitors if m[2] == "band_lifts_off"]
    assert len(found) == 1 and found[0][1].startswith("roll")
    at = pipeline.run(scene(text), progress=False, t_end=found[0][0])
    # measured 1.1e-12 m: the crossing is located to the event tolerance
    assert at.outputs["roll.y"][-1] == pytest.approx(R_ROLL, abs=1e-9)
    assert at.outputs["roll.wrap"][-1] == pytest.approx(0.0, abs=1e-9)
    # the wrap is the angle between the tangent points, as the material test constructs it
    assert "band_lifts_off" not in [m[2] for m in run(TENSIONER).monitors]


def test_capstan_limit_on_a_planar_roll():
    """A torque ramp on the tensioner roll; with the contact friction mu_c = 0.05 capstan_limit is
    reported (first at e1 in the start transient, later at e2 as the torque grows) exactly where the
    tension at that port reaches e^(mu_c*wrap) times the other.  The wrap and both tensions are
    outputs: a pruned model drops a monitor whose inputs no output needs (reported, kernel)."""
    text = TENSIONER.replace("roll: {type: planar_roll, r: 0.03, J: 1.0e-4}",
                             "roll: {type: planar_roll, r: 0.03, J: 1.0e-4, mu_c: 0.05}\n  torque: "
                             "{type: torque_source, value: 2.0*t}") \
        .replace("  - [roll.e1, right.e1]", "  - [roll.e1, right.e1]\n  - [torque.p, roll.drive]") \
        .replace("roll.lr2]", "roll.lr2, roll.wrap, roll.F1, roll.F2]")
    res = pipeline.run(scene(text), progress=False, t_end=2.0)
    found = [m for m in res.monitors if m[2] == "capstan_limit"]
    assert len(found) >= 2 and "e1" in found[0][3] and "e2" in found[-1][3]
    for when, tight, slack in ((found[0][0], "F1", "F2"), (found[-1][0], "F2", "F1")):
        at = pipeline.run(scene(text), progress=False, t_end=when).outputs
        assert at[f"roll.{tight}"][-1] / at[f"roll.{slack}"][-1] == pytest.approx(
            math.exp(0.05 * at["roll.wrap"][-1]), rel=1e-6)


# -- the compressor scene -----------------------------------------------------------------------

def test_compressor_belt_length_is_invariant_while_the_tensioner_swings():
    """Compressor (Ebert 8.2) through the clutch engagement at 2 s: the closed belt's length, the
    spans' free lengths plus the wrapped arcs r*beta of the three rolls, stays constant while the
    tensioner lever swings; the belt turns once around: beta_M + beta_P - beta_T = 2 pi (the
    tensioner roll is wrapped the other way round)."""
    outs = ["tight.free", "span2.free", "span3.free", "M.wrap", "P.wrap", "T.wrap", "lever.phi", "tight.F"]
    res = pipeline.run(load(BELTS / "compressor.yaml"), progress=False, t_end=3.0, outputs=outs)
    o = res.outputs
    assert np.ptp(o["lever.phi"]) > 0.05 and o["tight.F"].max() > 1000     # the engagement's peak
    length = o["tight.free"] + o["span2.free"] + o["span3.free"] \
        + 0.05 * o["M.wrap"] + 0.15 * o["P.wrap"] + 0.03 * o["T.wrap"]
    # measured 1.0e-11 m (rtol 1e-6 of the run: the free lengths come from the same integrated states)
    np.testing.assert_allclose(length, length[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(o["M.wrap"] + o["P.wrap"] - o["T.wrap"], 2 * math.pi, rtol=0, atol=1e-9)


# -- a planar drum ------------------------------------------------------------------------------

WINCH = """
name: winch
# a drum at the origin winds in a rope tied to the tip of a hanging lever (DAN pivoted at (0.5, 0.3))
parameters: {wd: -1.0, stored: 10.0}
elements:
  motor: {type: speed_source, value: wd}
  drum: {type: planar_drum, r: 0.1, J: 0.01, stored: stored}
  rope: {type: planar_band, EA: 1.0e4, cd: 50.0, F0: 5.0, r1: 0.1, s1: 1}
  lever: {type: DAN, l: 0.4, phi0: -1.5707963267948966, m: 1.0, J: 0.02, x1: 0.5, y1: 0.3}
  damp: {type: damper, d: 0.5}
connections:
  - [motor.p, drum.drive]
  - [drum.c, rope.p1]
  - [drum.e1, rope.e1]
  - [rope.p2, lever.b]
  - [lever.drive, damp.a]
  - [damp.b, lever.support]
outputs: [rope.F, rope.free, rope.gamma, drum.lr1, drum.F1, lever.phi]
simulate: {t_end: 1.0, rtol: 1.0e-9}
"""


def test_planar_drum_winds_in_the_rope_of_a_swinging_lever():
    """The drum winds in at 1 rad/s and swings the lever toward it: the rope's free length changes
    by the drum's wound-off length w r [(phi - phi0) - (gamma - gamma0)] (1e-9 m), which is the
    drum's r*omega*t corrected by the rope's turning; the drum feels the rope's tension."""
    res = run(WINCH)
    o = res.outputs
    assert np.ptp(o["lever.phi"]) > 0.1 and np.ptp(o["rope.gamma"]) > 0.01
    np.testing.assert_allclose(o["rope.free"] - o["rope.free"][0], o["drum.lr1"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(o["drum.lr1"], 0.1 * (-1.0 * res.t - (o["rope.gamma"] - o["rope.gamma"][0])),
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose(o["drum.F1"], o["rope.F"], rtol=1e-12)


def test_planar_drum_paying_out_its_store_stops_the_run():
    """Paying out at 0.1 m/s with 0.02 m stored: the run stops with drum_paid_out at 0.2 s (the rope
    barely turns: the wound-off length is r*omega*t to 1e-3)."""
    with pytest.raises(MultipoleError) as exc:
        pipeline.run(scene(WINCH, {"wd": 1.0, "stored": 0.02}), progress=False)
    assert exc.value.code == "drum_paid_out" and "t = 0.2 s" in exc.value.message
    res = pipeline.run(scene(WINCH, {"wd": 1.0, "stored": 0.02}), progress=False, t_end=0.19)
    assert res.outputs["drum.lr1"][-1] < 0.02
