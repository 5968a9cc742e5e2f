"""Band through a take-off nozzle and band with a tension spring (issue 13, Ebert 4.4.2, 4.4.3).

Expected values come from plane geometry written here (section lengths and directions of the
points a lever carries), the tension-only Kelvin-Voigt law and the linear spring written here,
the power balance (sum of port powers = F delta', the rate of the strain energy plus the damper
loss), the resultant of two equal tensions on an eyelet, and the straight span of ``planar_band``.
"""
import math

import numpy as np
import pytest

from multipole import MultipoleError, pipeline
from tests.helpers import refusal, run, scene

O, L_LEVER, J_LEVER = np.array([0.5, 0.6]), 0.15, 1e-3
P1, P2 = np.array([0.0, 0.0]), np.array([1.0, 0.1])
R_ROLL, J_ROLL = 0.04, 2e-4

NOZZLE = """
name: nozzle
elements:
  lever: {type: DAN, l: 0.15, phi0: -1.0, m: 0.0, J: 1.0e-3, x1: 0.5, y1: 0.6}
  r1: {type: band_roll, r: 0.04, J: 2.0e-4}
  r2: {type: band_roll, r: 0.04, J: 2.0e-4}
  n: {type: nozzle_band, EA: 2.0e4, cd: 5.0, l0: 1.5, x1: 0.0, y1: 0.0, x2: 1.0, y2: 0.1}
connections:
  - [lever.b, n.p3]
  - [r1.e1, n.e1]
  - [r2.e2, n.e2]
outputs: [n.F, n.Fx3, n.Fy3, n.length, n.rate, n.gamma1, n.gamma2]
simulate: {t_end: 0.01}
"""
SPRING = """
name: spring_band
elements:
  lever: {type: DAN, l: 0.15, phi0: -1.0, m: 0.0, J: 1.0e-3, x1: 0.5, y1: 0.6}
  r1: {type: band_roll, r: 0.04, J: 2.0e-4}
  r2: {type: band_roll, r: 0.04, J: 2.0e-4}
  s: {type: spring_band, k: 800.0, b: 3.0, l0: 0.1, lB1: 0.3, lB2: 0.25, x1: 0.0, y1: 0.0}
connections:
  - [lever.b, s.p2]
  - [r1.e1, s.e1]
  - [r2.e2, s.e2]
outputs: [s.F, s.stretch, s.spring, s.length, s.rate, s.gamma1]
simulate: {t_end: 0.01}
"""


def _external(vals, path, ports):
    return sum(vals[f"{path}.{p}.e"] * vals[f"{path}.{p}.f"] for p in ports)


def _random_state(model, rng):
    names = list(model.state_names)
    st = dict(zip(names, np.asarray(model.x0, dtype=float)))
    st.update({"lever.L.K.q3": rng.uniform(-1.5, -0.5), "lever.L.J.p": rng.uniform(-0.02, 0.02),
               "r1.J.p": rng.uniform(-0.02, 0.02), "r2.J.p": rng.uniform(-0.02, 0.02)})
    return names, st


def _lever(st):
    phi, omega = st["lever.L.K.q3"], st["lever.L.J.p"] / J_LEVER
    return (O + L_LEVER * np.array([math.cos(phi), math.sin(phi)]),
            L_LEVER * omega * np.array([-math.sin(phi), math.cos(phi)]))


@pytest.mark.parametrize("seed", range(3))
def test_nozzle_power_balance_and_resultant_at_random_states(seed):
    """The nozzle P3 on a lever, the ends fixed, band paid out by two rolls (w = +1: r1 pays out at
    e1 with r omega1, r2 winds in at e2, paying out -r omega2): delta' = t1 . v3 - t2 . v3 - r omega1
    + r omega2 with t_k the section directions written here; F = max(0, EA delta/l_x + cd delta'/l_x)
    (delta > 0, l_x = l_B - delta), 0 slack; the element's port powers sum to F delta'; the force on
    the nozzle is F (t2 - t1) and the section inclinations are those of P3 - P1 and P2 - P3."""
    rng = np.random.default_rng(seed)
    model = pipeline.model(scene(NOZZLE), ["n.F", "n.Fx3", "n.Fy3", "n.gamma1", "n.gamma2", "n.stretch", "n.free",
                                           "n.length", "n.rate"], prune=False)
    EA, cd = 2.0e4, 5.0
    for _trial in range(3):
        names, st = _random_state(model, rng)
        st["n.c.q"] = rng.uniform(-1e-3, 1e-2)
        x = np.array([st[n] for n in names])
        vals, dx = model.port_values(0.1, x), dict(zip(names, model.rhs(0.1, x)))
        P3, v3 = _lever(st)
        t1, t2 = (P3 - P1) / np.linalg.norm(P3 - P1), (P2 - P3) / np.linalg.norm(P2 - P3)
        rate = np.dot(t1, v3) - np.dot(t2, v3) - R_ROLL * st["r1.J.p"] / J_ROLL + R_ROLL * st["r2.J.p"] / J_ROLL
        assert dx["n.c.q"] == pytest.approx(rate, rel=1e-10, abs=1e-12)
        delta = st["n.c.q"]
        lx = np.linalg.norm(P3 - P1) + np.linalg.norm(P2 - P3) - delta
        F = max(0.0, EA * delta / lx + cd * rate / lx) if delta > 0 else 0.0
        out = dict(zip(model.output_names, np.asarray(model.outputs(0.1, x), dtype=float)))
        assert out["n.F"] == pytest.approx(F, rel=1e-10, abs=1e-9)
        assert out["n.stretch"] == delta and out["n.rate"] == pytest.approx(rate, rel=1e-10, abs=1e-12)
        assert out["n.free"] == pytest.approx(lx, rel=1e-12)
        assert out["n.length"] == pytest.approx(lx + delta, rel=1e-12)
        ports = ["K.b1", "K.b2", "K.b3", "K.b4", "K.b5", "K.b6", "J.e1", "J.e2", "G1.e1", "G2.e2", "t1.p", "t2.p",
                 "t3.p"]
        assert _external(vals, "n", ports) == pytest.approx(F * rate, rel=1e-10, abs=1e-9)
        force = F * (t2 - t1)
        assert out["n.Fx3"] == pytest.approx(force[0], rel=1e-10, abs=1e-9)
        assert out["n.Fy3"] == pytest.approx(force[1], rel=1e-10, abs=1e-9)
        # the ports at P3 (columns 3, 4) carry the force on the band there: minus the force on the nozzle
        assert vals["n.K.b3.e"] == pytest.approx(-force[0], rel=1e-10, abs=1e-9)
        assert vals["n.K.b4.e"] == pytest.approx(-force[1], rel=1e-10, abs=1e-9)
        assert out["n.gamma1"] == pytest.approx(math.atan2(*(P3 - P1)[::-1]), abs=1e-10)
        assert out["n.gamma2"] == pytest.approx(math.atan2(*(P2 - P3)[::-1]), abs=1e-10)


@pytest.mark.parametrize("seed", range(3))
def test_spring_band_power_balance_and_force_law_at_random_states(seed):
    """P2 on a lever, P1 fixed, rolls at both ends: delta' = t . v2 - r omega1 + r omega2 (t = (P2 - P1)/
    |P2 - P1|); F = max(0, k delta + b delta') while delta > 0, 0 slack; port powers sum to F delta'."""
    rng = np.random.default_rng(10 + seed)
    model = pipeline.model(scene(SPRING), ["s.F", "s.spring", "s.length", "s.gamma1", "s.gamma2", "s.stretch", "s.rate"],
                           prune=False)
    k, b = 800.0, 3.0
    for _trial in range(3):
        names, st = _random_state(model, rng)
        st["s.c.q"] = rng.uniform(-0.01, 0.05)
        x = np.array([st[n] for n in names])
        vals, dx = model.port_values(0.1, x), dict(zip(names, model.rhs(0.1, x)))
        P, v = _lever(st)
        t = (P - P1) / np.linalg.norm(P - P1)
        rate = np.dot(t, v) - R_ROLL * st["r1.J.p"] / J_ROLL + R_ROLL * st["r2.J.p"] / J_ROLL
        assert dx["s.c.q"] == pytest.approx(rate, rel=1e-10, abs=1e-12)
        delta = st["s.c.q"]
        F = max(0.0, k * delta + b * rate) if delta > 0 else 0.0
        out = dict(zip(model.output_names, np.asarray(model.outputs(0.1, x), dtype=float)))
        assert out["s.F"] == pytest.approx(F, rel=1e-10, abs=1e-9)
        assert out["s.spring"] == pytest.approx(0.1 + delta, rel=1e-12)
        assert out["s.stretch"] == delta and out["s.rate"] == pytest.approx(rate, rel=1e-10, abs=1e-12)
        assert out["s.length"] == pytest.approx(np.linalg.norm(P - P1), rel=1e-12)
        gamma = math.atan2(P[1] - P1[1], P[0] - P1[0])
        assert out["s.gamma1"] == pytest.approx(gamma, abs=1e-10) and out["s.gamma2"] == pytest.approx(gamma, abs=1e-10)
        ports = ["K.b1", "K.b2", "K.b3", "K.b4", "J.e1", "J.e2", "G1.e1", "G1.e2", "t1.p", "t2.p"]
        assert _external(vals, "s", ports) == pytest.approx(F * rate, rel=1e-10, abs=1e-9)


# -- closed forms on runs -------------------------------------------------------------------------

STRAIGHT = """
name: straight
parameters: {a: 0.0}
elements:
  n: {type: nozzle_band, EA: 1.0e4, cd: 2.0, l0: 0.99, x1: 0.0, y1: 0.0, x2: 0.8, y2: 0.6, x3: 0.32, y3: 0.24}
  p: {type: planar_band, EA: 1.0e4, cd: 2.0, F0: 1.0e4*(1.0 - 0.99)/0.99, x1: 0.0, y1: 0.0, x2: 0.8, y2: 0.6}
  r: {type: band_roll, r: 0.05, J: 1.0e-4, omega0: 3.0}
  q: {type: band_roll, r: 0.05, J: 1.0e-4, omega0: 3.0}
connections:
  - [r.e1, n.e1]
  - [q.e1, p.e1]
outputs: [n.F, p.F, n.Fx3, n.Fy3, n.gamma1, n.gamma2, p.gamma]
simulate: {t_end: 0.05, rtol: 1.0e-10, atol: 1.0e-12}
"""


def test_nozzle_on_the_straight_line_reproduces_the_plain_span():
    """A nozzle at 40 % of the straight line P1-P2 (length 1 m, free length 0.99 m) is no nozzle: the
    tension history equals that of planar_band with the same free length (F0 = EA (1 - 0.99)/0.99)
    while a roll winds band off at e1, both sections keep the span's inclination atan2(0.6, 0.8), and
    the nozzle carries no force."""
    res = run(STRAIGHT)
    o = res.outputs
    F_n, F_p = o["n.F"], o["p.F"]
    assert np.max(F_p) > 50.0 and np.min(F_p) < 1.0         # the run crosses from taut to slack
    np.testing.assert_allclose(F_n, F_p, rtol=0, atol=1e-6 * np.max(F_p))
    np.testing.assert_allclose(o["n.gamma1"], math.atan2(0.6, 0.8), atol=1e-12)
    np.testing.assert_allclose(o["n.gamma2"], math.atan2(0.6, 0.8), atol=1e-12)
    np.testing.assert_allclose(o["n.Fx3"], 0.0, atol=1e-9 * np.max(F_p))
    np.testing.assert_allclose(o["n.Fy3"], 0.0, atol=1e-9 * np.max(F_p))


def test_eyelet_takes_the_resultant_of_two_equal_tensions():
    """Symmetric V: P1 (0, 0), P2 (1, 0), P3 (0.5, -0.3): the nozzle is pulled by 2 F sin(alpha) upwards
    (alpha the sections' angle to the horizontal, tan alpha = 0.3/0.5) and by nothing sideways; the
    tension is EA (l_B - l0)/l0 at t = 0."""
    text = NOZZLE.replace("x2: 1.0, y2: 0.1", "x2: 1.0, y2: 0.0, x3: 0.5, y3: -0.3").replace("l0: 1.5", "l0: 1.1").replace(
        "  - [lever.b, n.p3]\n", "")
    model = pipeline.model(scene(text), ["n.F", "n.Fx3", "n.Fy3"], prune=False)
    out = dict(zip(model.output_names, np.asarray(model.outputs(0.0, np.asarray(model.x0, float)), dtype=float)))
    lb = 2 * math.hypot(0.5, 0.3)
    F = 2.0e4 * (lb - 1.1) / 1.1
    assert out["n.F"] == pytest.approx(F, rel=1e-12)
    assert out["n.Fx3"] == pytest.approx(0.0, abs=1e-9 * F)
    assert out["n.Fy3"] == pytest.approx(2 * F * 0.3 / math.hypot(0.5, 0.3), rel=1e-12)


MOVING = """
name: spring_slack
parameters: {v: 0.2}
elements:
  drive: {type: speed_source, value: v}
  r: {type: band_roll, r: 0.05, J: 1.0e-4}
  s: {type: spring_band, k: 800.0, b: 0.0, l0: 0.1, lB1: 0.3, lB2: 0.25, x2: 0.7}
connections:
  - [drive.p, r.drive]
  - [r.e2, s.e1]
outputs: [s.F, s.stretch, s.spring]
simulate: {t_end: 1.5, rtol: 1.0e-10, atol: 1.0e-12}
"""


def test_spring_band_force_and_slack_onset():
    """|P1P2| = 0.7 m, sections 0.3 + 0.25 m, spring free length 0.1 m: extension 0.05 m at t = 0. A
    roll (w = +1, r = 0.05 m) turning at 0.2 rad/s winds the band in at its e2 (wound length -r phi,
    0.01 m/s), which is joined to the span's e1: the section at P1 shortens and the extension grows
    as 0.05 + 0.01 t; turning backwards it shrinks as 0.05 - 0.01 t and the spring goes slack at
    t = 5 s. F = k * extension while stretched, 0 slack."""
    res = run(MOVING)
    t = res.t
    np.testing.assert_allclose(res.outputs["s.stretch"], 0.05 + 0.01 * t, atol=1e-9)
    np.testing.assert_allclose(res.outputs["s.F"], 800.0 * (0.05 + 0.01 * t), rtol=1e-9)
    back = run(MOVING.replace("v: 0.2", "v: -0.2").replace("t_end: 1.5", "t_end: 8.0"))
    t, F, ext = back.t, back.outputs["s.F"], back.outputs["s.stretch"]
    np.testing.assert_allclose(ext, 0.05 - 0.01 * t, atol=1e-9)
    np.testing.assert_allclose(F, 800.0 * np.maximum(0.05 - 0.01 * t, 0.0), atol=1e-7)
    onset = t[np.argmax(F <= 0.0)]
    assert onset == pytest.approx(5.0, abs=0.05)
    assert np.all(F[t > 5.0 + 1e-6] == 0.0)


# -- bad input ------------------------------------------------------------------------------------

def test_negative_spring_rate_is_refused_naming_the_element():
    err = refusal("spring_band", "k: -5.0", name="tensioner")
    assert err.code == "bad_value" and "parameter 'k'" in str(err)


@pytest.mark.parametrize("kind, params, section", [
    ("nozzle_band", "x3: 0.0, y3: 0.0", "P1 -> P3"), ("nozzle_band", "x3: 1.0, y3: 0.0", "P3 -> P2"),
    ("spring_band", "x2: 0.0", "P1 -> P2")])
def test_zero_length_section_at_the_start_is_refused(kind, params, section):
    text = f"name: bad\nelements:\n  eyelet: {{type: {kind}, {params}}}\nsimulate: {{t_end: 0.1}}\n"
    found = [d for d in pipeline.check(scene(text)).diagnostics if d.code == "cannot_assemble"]
    assert found and f"section {section} has no length" in found[0].message and "eyelet" in found[0].message


def test_run_refuses_a_zero_length_section():
    text = "name: bad\nelements:\n  eyelet: {type: nozzle_band, x3: 0.0, y3: 0.0}\nsimulate: {t_end: 0.1}\n"
    with pytest.raises(MultipoleError) as exc:
        pipeline.run(scene(text), progress=False)
    assert exc.value.code == "cannot_assemble"
