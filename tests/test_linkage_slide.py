"""SAN, FGP and DDS (elements/linkage_slide.py) against closed forms, finite differences and energy.

Expected values come from closed forms written here with sympy (the slider-crank
x = r cos(theta) + sqrt(l^2 - (r sin(theta) - e)^2), and its general form for a guide that moves and
turns), differentiated symbolically; the kinetic and potential energy of every body is computed
here from those closed forms, so the drive torques are checked against d/dt (kinetic + potential).
Runs use rtol 1e-10 with constant drive speeds (the drive angles are integrated exactly) and the
closure's Newton tolerance 1e-12.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from helpers import run, scene
from multipole import MultipoleError

t = sp.Symbol("t", real=True)
G = 9.81


def e(phi):
    return sp.Matrix([sp.cos(phi), sp.sin(phi)])


def n(phi):
    return sp.Matrix([-sp.sin(phi), sp.cos(phi)])


def dds_closed(P1, P2, phiU, l, v, K=1):
    """The DDS pin P, foot point PS, travel x_G and link angle phi_L (from P towards P1) in closed form:
    P = P2 + x_G u + v n with |P - P1| = l (written here from the geometry, not taken from the module)."""
    u, nn, d = e(phiU), n(phiU), P2 - P1
    ud, nd = u.dot(d), nn.dot(d)
    xG = -ud + K * sp.sqrt(ud ** 2 - (d.dot(d) + v ** 2 + 2 * v * nd - l ** 2))
    PS = P2 + xG * u
    P = PS + v * nn
    return P, PS, xG, sp.atan2(P1[1] - P[1], P1[0] - P[0])


def rot(phi):
    return sp.Matrix([[sp.cos(phi), -sp.sin(phi)], [sp.sin(phi), sp.cos(phi)]])


def body(m, J, S, phi):
    """Kinetic and potential energy of a body with centre of mass S(t) and angle phi(t) [J]."""
    vS = S.diff(t)
    return m * vS.dot(vS) / 2 + J * phi.diff(t) ** 2 / 2 + m * G * S[1]


def f(expr):
    return sp.lambdify(t, expr, "numpy")


def sample(expr, tt):
    return np.broadcast_to(np.asarray(f(expr)(tt), dtype=float), tt.shape)


def wrapped(angle):
    """An angle difference brought to (-pi, pi] (the module's angles are continuous, atan2's are not)."""
    return np.angle(np.exp(1j * angle))


def fd(y, h):
    """Central differences of samples on a grid of step h (inner points)."""
    return (y[2:] - y[:-2]) / (2 * h)


# ---------------------------------------------------------------------------------------------------
# slider-crank: DAN (r, speed-driven) + DDS (link l, pin offset e above the frame-fixed guide y = 0)

R_, L_, E_, W_, PHI0 = 0.1, 0.35, 0.02, 10.0, 0.3
CRANK = dict(m=0.5, J=0.002, xs=0.04, ys=0.01)
ROD = dict(mL=0.8, JL=0.01, xsL=0.12, ysL=-0.01, mS=1.2, JS=0.001, xsS=0.01, ysS=0.005)

SLIDER_CRANK = f"""
name: slider_crank_test
parameters: {{w: {W_}}}
elements:
  motor: {{type: speed_source, value: w}}
  crank: {{type: DAN, l: {R_}, phi0: {PHI0}, m: {CRANK['m']}, J: {CRANK['J']}, xs: {CRANK['xs']}, ys: {CRANK['ys']}}}
  rod: {{type: DDS, l: {L_}, v: {E_}, K: 1, mL: {ROD['mL']}, JL: {ROD['JL']}, xsL: {ROD['xsL']}, ysL: {ROD['ysL']},
         mS: {ROD['mS']}, JS: {ROD['JS']}, xsS: {ROD['xsS']}, ysS: {ROD['ysS']}}}
connections:
  - [motor.p, crank.drive]
  - [crank.b, rod.a1]
outputs: [crank.phi, crank.torque, rod.x, rod.v, rod.phi, rod.omega, rod.xP, rod.yP, rod.S.mx.p.e, rod.L.J.p.e,
          rod.b2.x.f, rod.b2.y.f, rod.transmission]
simulate: {{t_end: 0.7, dt_out: 0.01, rtol: 1e-10, atol: 1e-12}}
"""


@pytest.fixture(scope="module")
def slider_crank():
    return run(SLIDER_CRANK)


def slider_crank_closed():
    th = PHI0 + W_ * t
    P1 = R_ * e(th)
    P, PS, xG, phiL = dds_closed(P1, sp.Matrix([0, 0]), 0, L_, E_)
    return th, P1, P, PS, xG, phiL


def test_slider_crank_textbook_closed_form():
    """The general closed form used here reduces to x = r cos + sqrt(l^2 - (r sin - e)^2)."""
    th, _, P, _, xG, _ = slider_crank_closed()
    text = R_ * sp.cos(th) + sp.sqrt(L_ ** 2 - (R_ * sp.sin(th) - E_) ** 2)
    tt = np.linspace(0, 1, 7)
    assert np.allclose(sample(xG, tt), sample(text, tt), atol=1e-15, rtol=0)
    assert np.allclose(sample(P[1], tt), E_, atol=1e-15, rtol=0)


def test_slider_crank_position_velocity_acceleration(slider_crank):
    r = slider_crank
    _, _, _, _, xG, phiL = slider_crank_closed()
    tt = r.t
    assert np.max(np.abs(r["crank.phi"] - (PHI0 + W_ * tt))) < 1e-12
    assert np.max(np.abs(r["rod.x"] - sample(xG, tt))) < 1e-10
    assert np.max(np.abs(r["rod.v"] - sample(xG.diff(t), tt))) < 1e-10
    # the slider's acceleration from its inertia's effort: m_S * x'' (the guide does not turn)
    assert np.max(np.abs(r["rod.S.mx.p.e"] / ROD["mS"] - sample(xG.diff(t, 2), tt))) < 1e-10
    assert np.max(np.abs(wrapped(r["rod.phi"] - sample(phiL, tt)))) < 1e-10
    assert np.all(np.abs(np.diff(r["rod.phi"])) < 0.1)          # continuous, never re-wrapped
    assert np.max(np.abs(r["rod.omega"] - sample(phiL.diff(t), tt))) < 1e-10
    assert np.max(np.abs(r["rod.L.J.p.e"] / ROD["JL"] - sample(phiL.diff(t, 2), tt))) < 1e-9
    # transmission: cos of the angle between the link and the guide (the guide along x here)
    assert np.max(np.abs(r["rod.transmission"] - np.cos(sample(phiL, tt)))) < 1e-10


def test_slider_crank_drive_torque_is_the_energy_rate(slider_crank):
    r = slider_crank
    th, P1, P, PS, xG, phiL = slider_crank_closed()
    E = (body(CRANK["m"], CRANK["J"], rot(th) * sp.Matrix([CRANK["xs"], CRANK["ys"]]), th)
         + body(ROD["mL"], ROD["JL"], P + rot(phiL) * sp.Matrix([ROD["xsL"], ROD["ysL"]]), phiL)
         + body(ROD["mS"], ROD["JS"], PS + sp.Matrix([ROD["xsS"], ROD["ysS"]]), sp.Integer(0)))
    expected = sample(E.diff(t), r.t)
    power = r["crank.torque"] * W_
    assert np.max(np.abs(power - expected)) < 1e-8 * max(1.0, np.max(np.abs(expected)))


# ---------------------------------------------------------------------------------------------------
# moving anchors: SAN on a turning crank, FGP on a four-bar's coupler, DDS with its guide on a crank

H = 1e-4                     # finite-difference step [s] of the Jacobian checks (grid of the run)
W1, W2, U = 3.0, 1.5, 0.4    # crank speeds [rad/s] and the SAN travel rate [m/s]

SAN_ON_CRANK = f"""
name: san_on_crank
elements:
  m1: {{type: speed_source, value: {W1}}}
  m2: {{type: velocity_source, value: {U}}}
  crank: {{type: DAN, l: 0.3, phi0: 0.4, m: 0.7, J: 0.01, x1: 0.1, y1: -0.2}}
  san: {{type: SAN, v: 0.05, x0: 0.1, xs: 0.02, ys: -0.01, m: 1.1, J: 0.004}}
connections:
  - [m1.p, crank.drive]
  - [m2.p, san.drive]
  - [crank.b, san.a]
outputs: [crank.phi, crank.torque, crank.b.x.f, crank.b.y.f, crank.b.phi.f, san.x, san.v, san.force, san.xP,
          san.yP, san.b.x.f, san.b.y.f, san.b.phi.f]
simulate: {{t_end: 0.3, dt_out: {H}, rtol: 1e-10, atol: 1e-12}}
"""

FGP_ON_COUPLER = f"""
name: fgp_on_coupler
elements:
  motor: {{type: speed_source, value: {W1}}}
  crank: {{type: DAN, l: 0.2, phi0: 0.3, m: 1.0, J: 0.01}}
  rocker: {{type: DDD, l1: 0.6, l2: 0.5, K: 1, m1: 2.0, J1: 0.06, m2: 1.5, J2: 0.03, x2: 0.7, y2: 0}}
  cp: {{type: FGP, l: 0.3, phi_rel: 0.5, m: 0.4, J: 0.003, xs: 0.1, ys: 0.02}}
connections:
  - [motor.p, crank.drive]
  - [crank.b, rocker.a1]
  - [rocker.b1, cp.a]
outputs: [crank.torque, rocker.x, rocker.y, rocker.phi1, rocker.phi2, cp.x, cp.y, cp.phi, cp.b.x.f, cp.b.y.f,
          cp.b.phi.f, rocker.b1.phi.f]
simulate: {{t_end: 0.3, dt_out: {H}, rtol: 1e-10, atol: 1e-12}}
"""

DDS_MOVING_GUIDE = f"""
name: dds_moving_guide
elements:
  m1: {{type: speed_source, value: {W1}}}
  m2: {{type: speed_source, value: {W2}}}
  crank: {{type: DAN, l: 0.1, phi0: 0.3, m: 0.5, J: 0.002}}
  guide: {{type: DAN, l: 0.05, phi0: 0.1, m: 0.3, J: 0.001, x1: 0.4, y1: -0.05}}
  rod: {{type: DDS, l: 0.35, v: 0.02, K: 1, mL: 0.8, JL: 0.01, ysL: 0.01, mS: 1.2, JS: 0.002, xsS: 0.02, ysS: 0.01}}
connections:
  - [m1.p, crank.drive]
  - [m2.p, guide.drive]
  - [crank.b, rod.a1]
  - [guide.b, rod.a2]
outputs: [crank.torque, guide.torque, rod.x, rod.v, rod.phi, rod.omega, rod.xP, rod.yP, rod.b1.x.f, rod.b1.y.f,
          rod.b1.phi.f, rod.b2.x.f, rod.b2.y.f, rod.b2.phi.f]
simulate: {{t_end: 0.3, dt_out: {H}, rtol: 1e-10, atol: 1e-12}}
"""


@pytest.fixture(scope="module")
def san_on_crank():
    return run(SAN_ON_CRANK)


@pytest.fixture(scope="module")
def fgp_on_coupler():
    return run(FGP_ON_COUPLER)


@pytest.fixture(scope="module")
def dds_moving_guide():
    return run(DDS_MOVING_GUIDE)


def assert_flows_match_fd(r, pairs, tol=1e-6):
    """Each output velocity (a port flow) against central differences of the matching position."""
    for flow, position in pairs:
        expected = fd(np.unwrap(r[position]) if "phi" in position else r[position], H)
        got = r[flow][1:-1]
        assert np.max(np.abs(got - expected)) < tol * max(1.0, np.max(np.abs(expected))), (flow, position)


def test_san_velocity_jacobian_matches_finite_differences(san_on_crank):
    assert_flows_match_fd(san_on_crank, [("san.b.x.f", "san.xP"), ("san.b.y.f", "san.yP"),
                                         ("san.b.phi.f", "crank.phi"), ("san.v", "san.x")])


def test_fgp_velocity_jacobian_matches_finite_differences(fgp_on_coupler):
    r = fgp_on_coupler
    assert_flows_match_fd(r, [("cp.b.x.f", "cp.x"), ("cp.b.y.f", "cp.y"), ("cp.b.phi.f", "cp.phi")])
    # the coupler point is welded to link 1: its angle is phi1 + phi_rel, its position P1 + l e(phi1 + 0.5)
    assert np.max(np.abs(r["cp.phi"] - r["rocker.phi1"] - 0.5)) < 1e-12
    x1, y1 = 0.2 * np.cos(0.3 + W1 * r.t), 0.2 * np.sin(0.3 + W1 * r.t)
    assert np.max(np.abs(r["cp.x"] - x1 - 0.3 * np.cos(r["cp.phi"]))) < 1e-12
    assert np.max(np.abs(r["cp.y"] - y1 - 0.3 * np.sin(r["cp.phi"]))) < 1e-12


def test_dds_velocity_jacobian_matches_finite_differences(dds_moving_guide):
    r = dds_moving_guide
    phiU = 0.1 + W2 * r.t
    xa2, ya2 = 0.4 + 0.05 * np.cos(phiU), -0.05 + 0.05 * np.sin(phiU)
    r.outputs["PS.x"], r.outputs["PS.y"] = xa2 + r["rod.x"] * np.cos(phiU), ya2 + r["rod.x"] * np.sin(phiU)
    r.outputs["P1.x"], r.outputs["P1.y"] = 0.1 * np.cos(0.3 + W1 * r.t), 0.1 * np.sin(0.3 + W1 * r.t)
    r.outputs["guide.phi"] = phiU
    assert_flows_match_fd(r, [("rod.v", "rod.x"), ("rod.omega", "rod.phi"), ("rod.b1.phi.f", "rod.phi"),
                              ("rod.b1.x.f", "P1.x"), ("rod.b1.y.f", "P1.y"),
                              ("rod.b2.x.f", "PS.x"), ("rod.b2.y.f", "PS.y"), ("rod.b2.phi.f", "guide.phi")])


def test_dds_moving_guide_positions_match_the_closed_form(dds_moving_guide):
    r = dds_moving_guide
    th1, th2 = 0.3 + W1 * t, 0.1 + W2 * t
    P, PS, xG, phiL = dds_closed(0.1 * e(th1), sp.Matrix([0.4, -0.05]) + 0.05 * e(th2), th2, 0.35, 0.02)
    assert np.max(np.abs(r["rod.x"] - sample(xG, r.t))) < 1e-10
    assert np.max(np.abs(r["rod.xP"] - sample(P[0], r.t))) < 1e-10
    assert np.max(np.abs(r["rod.yP"] - sample(P[1], r.t))) < 1e-10
    assert np.max(np.abs(wrapped(r["rod.phi"] - sample(phiL, r.t)))) < 1e-10


def energy_rate_check(r, E, power):
    expected = sample(E.diff(t), r.t)
    assert np.max(np.abs(power - expected)) < 1e-8 * max(1.0, np.max(np.abs(expected)))


def test_san_on_a_turning_guide_drive_power_is_the_energy_rate(san_on_crank):
    """Crank torque * speed + slider force * travel rate = d/dt (kinetic + potential energy): the
    slider's Coriolis and centripetal loads on the turning guide go back to the crank."""
    r = san_on_crank
    th = 0.4 + W1 * t
    P1 = sp.Matrix([0.1, -0.2]) + 0.3 * e(th)
    xG = 0.1 + U * t
    E = (body(0.7, 0.01, sp.Matrix([0.1, -0.2]) + 0.15 * e(th), th)
         + body(1.1, 0.004, P1 + (xG + 0.02) * e(th) - 0.01 * n(th), th))
    assert np.max(np.abs(r["san.x"] - sample(xG, r.t))) < 1e-12
    assert np.max(np.abs(r["san.xP"] - sample((P1 + xG * e(th) + 0.05 * n(th))[0], r.t))) < 1e-12
    energy_rate_check(r, E, r["crank.torque"] * W1 + r["san.force"] * U)


def test_fgp_on_a_coupler_drive_torque_is_the_energy_rate(fgp_on_coupler):
    r = fgp_on_coupler
    th = 0.3 + W1 * t
    P1 = 0.2 * e(th)
    # the four-bar's joint P in closed form (circle intersection, P left of the line P1 -> P2)
    P2 = sp.Matrix([0.7, 0])
    d = P2 - P1
    dist = sp.sqrt(d.dot(d))
    a = (0.6 ** 2 - 0.5 ** 2 + dist ** 2) / (2 * dist)
    P = P1 + a * d / dist + sp.sqrt(0.6 ** 2 - a ** 2) * sp.Matrix([-d[1], d[0]]) / dist
    phi1, phi2 = sp.atan2(P[1] - P1[1], P[0] - P1[0]), sp.atan2(P[1], P[0] - 0.7)
    assert np.max(np.abs(r["rocker.x"] - sample(P[0], r.t))) < 1e-10
    phic = phi1 + 0.5
    E = (body(1.0, 0.01, 0.1 * e(th), th) + body(2.0, 0.06, P1 + 0.3 * e(phi1), phi1)
         + body(1.5, 0.03, P2 + 0.25 * e(phi2), phi2) + body(0.4, 0.003, P1 + rot(phic) * sp.Matrix([0.1, 0.02]), phic))
    energy_rate_check(r, E, r["crank.torque"] * W1)


def test_dds_moving_guide_drive_power_is_the_energy_rate(dds_moving_guide):
    """Both cranks' power = d/dt energy: the guide torque (Ebert (B.116): -Fn x_G + T_P2 - T_PS = 0)
    reaches the guide crank through the rigid anchor a2."""
    r = dds_moving_guide
    th1, th2 = 0.3 + W1 * t, 0.1 + W2 * t
    P2 = sp.Matrix([0.4, -0.05]) + 0.05 * e(th2)
    P, PS, xG, phiL = dds_closed(0.1 * e(th1), P2, th2, 0.35, 0.02)
    E = (body(0.5, 0.002, 0.05 * e(th1), th1) + body(0.3, 0.001, sp.Matrix([0.4, -0.05]) + 0.025 * e(th2), th2)
         + body(0.8, 0.01, P + rot(phiL) * sp.Matrix([0.175, 0.01]), phiL)
         + body(1.2, 0.002, PS + rot(th2) * sp.Matrix([0.02, 0.01]), th2))
    energy_rate_check(r, E, r["crank.torque"] * W1 + r["guide.torque"] * W2)


# ---------------------------------------------------------------------------------------------------
# printed errata of Ebert's appendix B (reference §9) for these modules: each printed form fails the
# relation the corrected one (and the module) satisfies

def test_erratum_B10_B12_san_foot_point_is_along_the_guide(san_on_crank):
    """(B.10)/(B.12) print x_PS = x_P1 - x_G cos(phi_U) and x_PS' = x_P1' - x_G' cos - x_G phi_U' sin."""
    r = san_on_crank
    phi, x, xd = r["crank.phi"], r["san.x"], r["san.v"]
    x1, x1d = 0.1 + 0.3 * np.cos(phi), r["crank.b.x.f"]
    ps_x = r["san.xP"] + 0.05 * np.sin(phi)                 # P = PS + v n(phi_U), v = 0.05
    ps_xd = r["san.b.x.f"] + 0.05 * W1 * np.cos(phi)
    assert np.max(np.abs(ps_x - (x1 + x * np.cos(phi)))) < 1e-12
    assert np.max(np.abs(ps_xd - (x1d + xd * np.cos(phi) - x * W1 * np.sin(phi)))) < 1e-10
    printed_x = x1 - x * np.cos(phi)
    printed_xd = x1d - xd * np.cos(phi) - x * W1 * np.sin(phi)
    assert np.min(np.abs(ps_x - printed_x)) > 0.05 and np.max(np.abs(ps_xd - printed_xd)) > 0.1
    # and the printed pair contradicts itself: (B.12) is not the derivative of (B.10)
    assert np.max(np.abs(fd(printed_x, H) - printed_xd[1:-1])) > 0.1


def test_erratum_B99_B101_dds_foot_point_velocity(dds_moving_guide):
    """(B.99)/(B.101) repeat the SAN sign error for the DDS slider on its turning guide."""
    r = dds_moving_guide
    phiU = 0.1 + W2 * r.t
    x, xd = r["rod.x"], r["rod.v"]
    x2d = -0.05 * W2 * np.sin(phiU)                         # the guide crank's tip, P2
    corrected = x2d + xd * np.cos(phiU) - x * W2 * np.sin(phiU)
    printed = x2d - xd * np.cos(phiU) - x * W2 * np.sin(phiU)
    assert np.max(np.abs(r["rod.b2.x.f"] - corrected)) < 1e-10
    assert np.max(np.abs(r["rod.b2.x.f"] - printed)) > 0.05


def test_erratum_B92_dds_pin_acceleration_sign(slider_crank):
    """(B.92) prints y_P'' = y_P1'' - l phi_L'^2 sin(phi_L) - l phi_L'' cos(phi_L); the pin of the slider-
    crank runs on the line y = e, so y_P'' = 0 exactly: only +l phi_L'^2 sin(phi_L) gives it."""
    r = slider_crank
    phi, om, al = r["rod.phi"], r["rod.omega"], r["rod.L.J.p.e"] / ROD["JL"]
    y1dd = -R_ * W_ ** 2 * np.sin(PHI0 + W_ * r.t)
    corrected = y1dd + L_ * om ** 2 * np.sin(phi) - L_ * al * np.cos(phi)
    printed = y1dd - L_ * om ** 2 * np.sin(phi) - L_ * al * np.cos(phi)
    assert np.max(np.abs(corrected)) < 1e-8 * R_ * W_ ** 2
    assert np.max(np.abs(printed)) > 0.1           # [m/s^2]: 2 l phi_L'^2 sin(phi_L), up to 0.9 here


def test_erratum_B110_load_on_the_link_output_at_P1():
    """(B.110) leaves out the moment of the load at ctr2D3, which sits at P1, not at P.  A slider-crank
    with a massless link and slider (guide tilted by phi_U = 0.3) and a point mass m on the link's output
    b1 (an FGP with its centre of mass at P1) loads the link at P1 with F = m (g - a_P1).  The printed
    moment balance about P makes the pin force F_P1 parallel to the link; with the slider's force on the
    link normal to the guide, the link's force balance a e(phi_L) + b n(phi_U) = -F fixes F_P1 = a e(phi_L)
    and the crank torque r e(theta) x F_P1.  The correct balance puts the whole load on the pin
    (F_P1 = -F), and virtual power agrees: torque = -r e(theta) x F."""
    m, phiU = 2.0, 0.3
    r = run(f"""
name: b110
elements:
  motor: {{type: speed_source, value: {W_}}}
  crank: {{type: DAN, l: {R_}, phi0: {PHI0}, m: 0, J: 0}}
  rod: {{type: DDS, l: {L_}, v: {E_}, mL: 0, JL: 0, mS: 0, JS: 0, phi2: {phiU}}}
  bob: {{type: FGP, l: 0.05, m: {m}, J: 0, xs: 0}}
connections:
  - [motor.p, crank.drive]
  - [crank.b, rod.a1]
  - [rod.b1, bob.a]
outputs: [crank.torque, rod.phi]
simulate: {{t_end: 0.6, dt_out: 0.01, rtol: 1e-10, atol: 1e-12}}
""")
    th, phiL = PHI0 + W_ * r.t, r["rod.phi"]
    F = m * np.stack([R_ * W_ ** 2 * np.cos(th), -G + R_ * W_ ** 2 * np.sin(th)])      # m (g - a_P1)
    arm = R_ * np.stack([np.cos(th), np.sin(th)])
    cross = lambda a, b: a[0] * b[1] - a[1] * b[0]  # noqa: E731
    correct = -cross(arm, F)
    printed = np.empty_like(correct)
    for k in range(len(th)):
        A = np.array([[np.cos(phiL[k]), -np.sin(phiU)], [np.sin(phiL[k]), np.cos(phiU)]])
        a_, _b = np.linalg.solve(A, -F[:, k])
        printed[k] = cross(arm[:, k], a_ * np.array([np.cos(phiL[k]), np.sin(phiL[k])]))
    scale = m * R_ * (G + R_ * W_ ** 2)
    assert np.max(np.abs(r["crank.torque"] - correct)) < 1e-10 * scale
    assert np.max(np.abs(r["crank.torque"] - printed)) > 0.1 * scale


def test_dds_on_a_horizontal_guide_carries_a_further_body():
    """The slider's y inertia on a horizontal frame-fixed guide is locked (its flow is sin(phi2) x_G' = 0)
    beside the held rotation of its guide: the check must still demote every inertia in one group (it
    took two nearly equal rows as reference rows and reported a false kinematic_overdetermination)."""
    from helpers import check
    text = f"""
name: horizontal
elements:
  motor: {{type: speed_source, value: {W_}}}
  crank: {{type: DAN, l: {R_}, phi0: {PHI0}, m: 0.5, J: 0.002}}
  rod: {{type: DDS, l: {L_}, v: {E_}}}
  bob: {{type: FGP, l: 0.05, m: 2, J: 0.01, xs: 0.01}}
connections:
  - [motor.p, crank.drive]
  - [crank.b, rod.a1]
  - [rod.b1, bob.a]
"""
    assert [d.code for d in check(text).diagnostics if d.severity == "error"] == []


# ---------------------------------------------------------------------------------------------------
# unconnected anchors are frame-fixed at their parameters; bad input

def test_unconnected_anchors_sit_at_their_frame_poses():
    x1, y1, phi1, x2, y2, phi2 = 0.2, -0.1, 0.7, 0.05, -0.03, 0.25
    r = run(f"""
name: frame_fixed
elements:
  push: {{type: velocity_source, value: {U}}}
  san: {{type: SAN, v: 0.04, x0: 0.3, x1: {x1}, y1: {y1}, phi1: {phi1}}}
  arm: {{type: FGP, l: 0.3, phi_rel: 0.4, x1: {x1}, y1: {y1}, phi1: {phi1}}}
  up: {{type: DDS, l: 0.35, v: 0.02, K: 1, x1: 0.1, y1: 0.03, x2: {x2}, y2: {y2}, phi2: {phi2}}}
  down: {{type: DDS, l: 0.35, v: 0.02, K: -1, x1: 0.1, y1: 0.03, x2: {x2}, y2: {y2}, phi2: {phi2}}}
connections:
  - [push.p, san.drive]
outputs: [san.x, san.xP, san.yP, arm.x, arm.y, arm.b.x.f, up.x, up.xP, up.yP, down.x, down.xP, down.yP]
simulate: {{t_end: 0.2, dt_out: 0.05, rtol: 1e-10, atol: 1e-12}}
""")
    xg = 0.3 + U * r.t
    assert np.max(np.abs(r["san.x"] - xg)) < 1e-12
    assert np.max(np.abs(r["san.xP"] - (x1 + xg * np.cos(phi1) - 0.04 * np.sin(phi1)))) < 1e-12
    assert np.max(np.abs(r["san.yP"] - (y1 + xg * np.sin(phi1) + 0.04 * np.cos(phi1)))) < 1e-12
    assert np.max(np.abs(r["arm.x"] - (x1 + 0.3 * np.cos(phi1 + 0.4)))) < 1e-15
    assert np.max(np.abs(r["arm.y"] - (y1 + 0.3 * np.sin(phi1 + 0.4)))) < 1e-15
    assert np.max(np.abs(r["arm.b.x.f"])) == 0
    for name, K in (("up", 1), ("down", -1)):
        P, _PS, xG, _phi = dds_closed(sp.Matrix([0.1, 0.03]), sp.Matrix([x2, y2]), phi2, 0.35, 0.02, K)
        assert abs(r[f"{name}.x"][0] - float(xG)) < 1e-12
        assert abs(r[f"{name}.xP"][0] - float(P[0])) < 1e-12 and abs(r[f"{name}.yP"][0] - float(P[1])) < 1e-12
        assert np.ptp(r[f"{name}.x"]) < 1e-12           # nothing drives it: it stays where it was assembled
    assert r["up.x"][0] > r["down.x"][0] + 0.1           # K = +1: the larger travel


@pytest.mark.parametrize("spec, code", [
    ("{type: DDS, K: 0.5}", "bad_assembly_mode"), ("{type: DDS, K: 0}", "bad_assembly_mode"),
    ("{type: DDS, l: 0}", "bad_value"), ("{type: DDS, l: -0.2}", "bad_value"),
    ("{type: FGP, l: 0}", "bad_value"), ("{type: FGP, l: -1}", "bad_value"),
    ("{type: SAN, m: -1}", "bad_value")])
def test_bad_parameters_are_one_line_errors(spec, code):
    with pytest.raises(MultipoleError) as exc:
        scene(f"name: bad\nelements:\n  el: {spec}\nsimulate: {{t_end: 1}}\n")
    assert exc.value.code == code
    assert "\n" not in str(exc.value) and "el" in str(exc.value)


def test_dds_that_cannot_reach_its_guide_is_reported_by_how_much():
    from helpers import check
    a = check("name: far\nelements:\n  rod: {type: DDS, l: 0.2, v: 0.0, x1: 0, y1: 0.5, x2: 0, y2: 0}\n")
    errors = [d for d in a.diagnostics if d.severity == "error"]
    assert [d.code for d in errors] == ["cannot_assemble"]
    assert "0.3 m" in errors[0].message                  # |0.5 - 0| - 0.2
    a = check("name: near\nelements:\n  rod: {type: DDS, l: 0.6, v: 0.0, x1: 0, y1: 0.5, x2: 0, y2: 0}\n")
    assert not [d for d in a.diagnostics if d.severity == "error"]


def test_san_force_driven_on_an_inclined_frame_guide_accelerates_by_newton():
    """A force F on the drive of a slider (mass m) on a frame guide inclined by phi1:
    x_G'' = F/m - g sin(phi1), from x0 and v0."""
    m, F, phi1, x0, v0 = 2.0, 3.0, 0.5, 0.1, 0.4
    r = run(f"""
name: san_force
elements:
  push: {{type: force_source, value: {F}}}
  san: {{type: SAN, v: 0.03, x0: {x0}, v0: {v0}, m: {m}, J: 0.01, xs: 0.02, ys: 0.01, phi1: {phi1}}}
connections:
  - [push.p, san.drive]
outputs: [san.x, san.v]
simulate: {{t_end: 1.0, dt_out: 0.1, rtol: 1e-10, atol: 1e-12}}
""")
    a = F / m - G * np.sin(phi1)
    assert np.max(np.abs(r["san.v"] - (v0 + a * r.t))) < 1e-8
    assert np.max(np.abs(r["san.x"] - (x0 + v0 * r.t + a * r.t ** 2 / 2))) < 1e-8
