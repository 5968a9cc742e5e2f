"""Curve contours, the curve roll and the curve drum (issue 13, Ebert 4.4.5 corrected).

Expected values: the circle (band_roll's own formulas), the ellipse's closed forms (support function
sqrt(a^2 cos^2 nu + b^2 sin^2 nu), its integral a*E(nu | m) and its arc length by the incomplete
elliptic integral, its tangent point (a cos t, b sin t) with tan t = (b/a) tan nu), a transfer
function prescribed in closed form and turned into a contour (synthesis round trip), the polar
curvature formula, and energy balances computed from the states.
"""
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipeinc

from elements.belt_contour import Contour, read_table, write_table
from multipole import ModelError, MultipoleError, NetlistError, pipeline
from multipole.netlist import load, loads

BELTS = Path(__file__).resolve().parents[1] / "diagrams" / "belts"
A_, B_ = 0.12, 0.08                     # ellipse half axes [m]
M_ = 1 - (B_ / A_) ** 2                 # parameter of the elliptic integrals


def _ellipse_r(theta):
    return A_ * B_ / np.sqrt((B_ * np.cos(theta)) ** 2 + (A_ * np.sin(theta)) ** 2)


def _ellipse_support(nu):
    return np.sqrt((A_ * np.cos(nu)) ** 2 + (B_ * np.sin(nu)) ** 2)


def _ellipse_t(nu):
    """Ellipse parameter t of the point with outward normal nu (tan t = (b/a) tan nu), unwrapped."""
    base = np.arctan2(B_ * np.sin(nu), A_ * np.cos(nu))
    return base + 2 * np.pi * np.round((nu - base) / (2 * np.pi))


def _ellipse_arc(nu):
    """Arc length from the point of normal 0 (t = 0) to that of normal nu: a * int_0^t sqrt(1 - m cos^2)."""
    t = _ellipse_t(nu)
    return A_ * (ellipeinc(np.pi / 2, M_) - ellipeinc(np.pi / 2 - t, M_))


@pytest.fixture(scope="module")
def ellipse():
    return Contour.from_function(_ellipse_r, 720, "ellipse")


# -- the contour -----------------------------------------------------------------------------------

def test_ellipse_support_function_arc_length_and_tangent_point_against_closed_forms(ellipse):
    """The spline through 720 points of the ellipse: its radius is O(h^4) off (h = 0.0087 rad: a few
    1e-11 m measured on p and on the perimeter 4 a E(m)), its tangent direction O(h^3), which moves the
    contact point of a given normal along the contour and so the arc length S (5.4e-9 m measured):
    1e-9 m and 2e-8 m bound them."""
    nu = np.linspace(-7.0, 7.0, 203)             # more than two turns: unwrapped
    np.testing.assert_allclose(ellipse.support(nu), _ellipse_support(nu), rtol=0, atol=1e-9)
    np.testing.assert_allclose(ellipse.arc(nu), _ellipse_arc(nu), rtol=0, atol=2e-8)
    assert ellipse.perimeter == pytest.approx(4 * A_ * ellipeinc(np.pi / 2, M_), abs=1e-9)
    # the tangent point for a roll turned by phi and a span of inclination gamma, roll on the right
    phi, gamma = 0.7, 0.3
    nu0 = gamma + np.pi / 2 - phi
    t = _ellipse_t(nu0)
    local = np.array([A_ * np.cos(t), B_ * np.sin(t)])
    rot = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    np.testing.assert_allclose(ellipse.tangent_point(phi, gamma, 1), rot @ local, atol=2e-8)
    # the lever arm is the distance from the axis to the span line through that point
    u = np.array([np.cos(gamma), np.sin(gamma)])
    point = rot @ local
    assert ellipse.lever(phi, gamma, 1) == pytest.approx(abs(point[0] * u[1] - point[1] * u[0]), abs=2e-8)
    # wound length: material between the contact points, w*(S(nu0) - S(nu))
    assert ellipse.wound(1.9, gamma, 1, 1, phi0=0.2) == pytest.approx(
        _ellipse_arc(gamma + np.pi / 2 - 0.2) - _ellipse_arc(gamma + np.pi / 2 - 1.9), abs=4e-8)


def test_series_of_the_elements_follows_the_spline(ellipse):
    """The elements' trigonometric form of p meets its tolerance against the spline; the perimeter is
    2 pi a0 (Cauchy), and a circle is its constant."""
    a, b = ellipse.series(1e-10)
    assert ellipse.series_error[0] <= 1e-10
    assert 2 * np.pi * a[0] == pytest.approx(ellipse.perimeter, abs=1e-9)
    assert np.all(np.abs(a[1::2]) < 1e-12) and np.all(np.abs(b) < 1e-12)     # symmetric: even cosines only
    a, b = Contour.circle(0.05).series()
    assert a[0] == pytest.approx(0.05, rel=1e-15) and len(a) == 1


def test_non_convex_contour_is_refused_with_the_angle_and_the_curvature():
    """r = 0.1 (1 + 0.3 cos 3 theta): at theta = pi/3 (r = 0.07, r' = 0, r'' = 0.27) the polar
    curvature (r^2 + 2 r'^2 - r r'')/(r^2 + r'^2)^1.5 is (0.0049 - 0.0189)/0.07^3 = -40.8163 1/m,
    the minimum (by symmetry also at pi and 5 pi/3)."""
    with pytest.raises(ModelError) as exc:
        Contour.from_function(lambda th: 0.1 * (1 + 0.3 * np.cos(3 * th)), 720, "trefoil")
    assert exc.value.code == "contour_not_convex"
    theta, kappa = (float(v) for v in re.search(r"theta = ([-\d.e]+) rad .*kappa = ([-\d.e+]+) 1/m",
                                                 exc.value.message).groups())
    assert min(abs(theta - c) for c in (np.pi / 3, np.pi, 5 * np.pi / 3)) < 1e-3
    assert kappa == pytest.approx((0.07 ** 2 - 0.07 * 0.27) / 0.07 ** 3, rel=1e-4)
    assert "trefoil" in exc.value.message


def _table(tmp_path, rows, name="t.csv"):
    path = tmp_path / name
    path.write_text("theta [rad], r [m]\n" + "".join(f"{t}, {r}\n" for t, r in rows))
    return path


@pytest.mark.parametrize("rows, code, where", [
    ([(0, 0.1), (2, 0.1), (1, 0.1), (4, 0.1)], "contour_not_increasing", "line 4"),
    ([(0, 0.1), (1, 0.1), (2, -0.1), (4, 0.1)], "contour_negative_radius", "line 4"),
    ([(0, 0.1), (2, 0.1), (4, 0.1), (2 * math.pi, 0.12)], "contour_not_periodic", "line 5"),
    ([(0, 0.1), (2, 0.1), (4, 0.1), (7, 0.1)], "contour_not_periodic", "more than one turn"),
    ([(0, 0.1), (2, "x"), (4, 0.1)], "bad_contour_table", "line 3"),
    ([(0, 0.1), (2, 0.1)], "bad_contour", "at least 3"),
    ([(1.5, 0.05), (1.7, 0.05), (1.9, 0.05), (2.1, 0.05)], "contour_not_closed", "covers theta = 1.5 .. 2.1"),
])
def test_bad_tables_are_refused_with_the_file_and_line(tmp_path, rows, code, where):
    with pytest.raises(ModelError) as exc:
        read_table(_table(tmp_path, rows))
    assert exc.value.code == code and "t.csv" in exc.value.message and where in exc.value.message


def test_table_round_trip_and_closing_row(tmp_path, ellipse):
    """write_table / read_table keep every digit; a closing row at theta0 + 2 pi with the first radius
    is accepted and dropped."""
    path = tmp_path / "e.csv"
    write_table(path, ellipse.theta, ellipse.r, "an ellipse")
    back = read_table(path)
    assert np.array_equal(back.theta, ellipse.theta) and np.array_equal(back.r, ellipse.r)
    closed = read_table(_table(tmp_path, [(0, 0.1), (2, 0.1), (4, 0.1), (2 * math.pi, 0.1)]))
    assert len(closed.theta) == 3


# -- the elements ---------------------------------------------------------------------------------

WINCH = """
name: winch
parameters: {EA: 2.0e4, l: 1.0, l0: 0.99, w: 0.5}
elements:
  motor: {type: speed_source, value: -w}
  drum: {DRUM}
  rope: {type: band, EA: EA, cd: 0.0, l: l, l0: l0, gamma: 0.3}
connections:
  - [motor.p, drum.drive]
  - [drum.e1, rope.e1]
outputs: [rope.F, rope.free, rope.stretch, rope.length, rope.lr1, drum.phi, drum.omega, drum.F1, drum.friction]
simulate: {t_end: 1.0, rtol: 1e-11, atol: 1e-13, dt_out: 0.05}
"""


def _winch(tmp_path, drum, **kw):
    return pipeline.run(loads(WINCH.replace("{DRUM}", drum), str(tmp_path / "winch.yaml")), progress=False, **kw)


def test_circle_contour_reproduces_band_roll_and_drum_exactly(tmp_path):
    """A circle table gives the circular roll's lever arm r and wound length r (phi - phi0): the same
    run as drum and band_roll, output for output, to rounding."""
    write_table(tmp_path / "circle.csv", np.linspace(0, 2 * np.pi, 12, endpoint=False), np.full(12, 0.1))
    ref = _winch(tmp_path, "{type: drum, r: 0.1, J: 0.01}")
    got = _winch(tmp_path, "{type: curve_drum, contour: circle.csv, J: 0.01, side1: -1}")
    for name, values in ref.outputs.items():
        np.testing.assert_allclose(got.outputs[name], values, rtol=1e-12, atol=1e-15, err_msg=name)
    text = (BELTS / "belt_drive.yaml").read_text()
    curve = "type: curve_roll, contour: c{}.csv, side1: -1, side2: -1,"
    curved = text.replace("type: band_roll, r: 0.05,", curve.format("05")).replace("type: band_roll, r: 0.1,",
                                                                                  curve.format("10"))
    assert curved.count("curve_roll") == 2
    for name, r in (("c05.csv", 0.05), ("c10.csv", 0.1)):
        write_table(tmp_path / name, np.linspace(0, 2 * np.pi, 12, endpoint=False), np.full(12, r))
    ref = pipeline.run(loads(text, str(tmp_path / "a.yaml")), t_end=0.5, progress=False)
    got = pipeline.run(loads(curved, str(tmp_path / "b.yaml")), t_end=0.5, progress=False)
    for name, values in ref.outputs.items():
        np.testing.assert_allclose(got.outputs[name], values, rtol=1e-10, atol=1e-12, err_msg=name)


def test_ellipse_drum_lever_arm_and_wound_length_against_closed_forms(tmp_path, ellipse):
    """An elliptic drum turning backwards at 0.5 rad/s, its rope of inclination 0.3 rad tied at P2; the
    drum at the rope's P1 end pays out under a positive rotation (w = +1), so it lies to the left of
    the span (side1 = -1: the band leaves the contact along the span's direction).
    The span's free length grows at w p(nu) omega, so the stretch is d0 + a (E(nu|m) - E(nu0|m))
    (nu = gamma + pi/2 - phi, the integral of the support function); the wound length is the arc
    between the contact points; the span's geometric length shrinks by the contact point's travel
    along the span (the tangent point of the closed form).  Tolerances: the elements' series (tol
    1e-10 m on p, its measured error on S) and the integration (rtol 1e-11)."""
    write_table(tmp_path / "ellipse.csv", ellipse.theta, ellipse.r)
    res = _winch(tmp_path, "{type: curve_drum, contour: ellipse.csv, J: 0.01, tol: 1.0e-10, side1: -1}",
                 outputs=["rope.stretch", "rope.lr1", "rope.length", "rope.F", "drum.phi", "drum.h1", "drum.omega",
                          "drum.F1", "drum.friction"])
    ellipse.series(1e-10)
    s_err = ellipse.series_error[1]
    phi = res.outputs["drum.phi"]
    np.testing.assert_allclose(phi, -0.5 * res.t, rtol=1e-12, atol=1e-14)
    gamma = 0.3
    nu, nu0 = gamma - np.pi / 2 - phi, gamma - np.pi / 2       # the drum lies left of the span (side -1)
    np.testing.assert_allclose(res.outputs["drum.h1"], _ellipse_support(nu), rtol=0, atol=2e-10)
    stretch = 0.01 + A_ * (ellipeinc(nu, M_) - ellipeinc(nu0, M_))
    np.testing.assert_allclose(res.outputs["rope.stretch"], stretch, rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.outputs["rope.lr1"], _ellipse_arc(nu0) - _ellipse_arc(nu), rtol=0,
                               atol=2 * s_err + 4e-8)
    t0, t = _ellipse_t(nu0), _ellipse_t(nu)
    u = np.array([np.cos(gamma), np.sin(gamma)])

    def point(tt, ph):           # contact point in the frame, projected on the span direction
        return (np.cos(ph) * A_ * np.cos(tt) - np.sin(ph) * B_ * np.sin(tt)) * u[0] + \
               (np.sin(ph) * A_ * np.cos(tt) + np.cos(ph) * B_ * np.sin(tt)) * u[1]
    np.testing.assert_allclose(res.outputs["rope.length"], 1.0 - (point(t, phi) - point(t0, 0.0)), rtol=0,
                               atol=2 * s_err + 4e-8)
    assert res.outputs["rope.F"][-1] > res.outputs["rope.F"][0]          # winding in raises the tension
    np.testing.assert_allclose(res.outputs["drum.omega"], -0.5, rtol=1e-12)
    np.testing.assert_allclose(res.outputs["drum.F1"], res.outputs["rope.F"], rtol=1e-12)
    np.testing.assert_allclose(res.outputs["drum.friction"], 0.0, atol=0)


def test_transfer_function_round_trip_from_a_prescribed_cam(tmp_path):
    """Synthesis by hand: the band cam that draws the band in by X(phi) = h0 phi - (A/2) sin 2 phi
    has the lever arm X' = h0 - A cos 2 phi, i.e. the support function p(nu) = h0 - A cos 2(nu0 - nu)
    (convex: p + p'' = h0 + 3 A cos > 0); its contact points give the polar table.  Read back as a
    curve drum and turned over 1.5 turns, the band's displacement (the stretch with the far end
    tied) is X(phi) to 1e-8 of the stroke."""
    h0, amp, gamma = 0.1, 0.02, 0.0
    nu0 = gamma - np.pi / 2
    cam = Contour.from_support(lambda nu: h0 - amp * np.cos(2 * (nu0 - nu)),
                               lambda nu: -2 * amp * np.sin(2 * (nu0 - nu)), 1440, "cam")
    write_table(tmp_path / "cam.csv", cam.theta, cam.r, "synthesised band cam")
    text = WINCH.replace("{DRUM}", "{type: curve_drum, contour: cam.csv, J: 0.01, side1: -1}").replace(
        "value: -w", "value: w").replace("t_end: 1.0", "t_end: 18.85")
    text = text.replace("gamma: 0.3", "gamma: 0.0")
    res = pipeline.run(loads(text, str(tmp_path / "cam.yaml")), progress=False,
                       outputs=["rope.stretch", "drum.phi"])
    phi = res.outputs["drum.phi"]
    X = h0 * phi - amp / 2 * np.sin(2 * phi)
    stroke = X[-1] - X[0]
    assert stroke > 0.9
    # the drum pays out (w = +1, positive rotation): the stretch falls by X (slack after a while:
    # the state still integrates the material balance)
    np.testing.assert_allclose(0.01 - res.outputs["rope.stretch"], X, rtol=0, atol=1e-8 * stroke)


def test_toothed_belt_ratio_and_strand_forces_follow_the_rigid_belt_kinetostatics():
    """Ebert 7.3.2: over 720 deg of the small wheel the big wheel turns 360 deg (mean ratio 2:1);
    omega1/omega2 follows the prescribed i(phi1) up to the belt's elasticity (measured 1.6e-3
    relative); the strand forces differ by the torque on wheel 2 over its lever arm,
    F_top - F_bottom = (T + J2 omega2')/p2 with omega2' = -omega1^2 i'/i^2 of the rigid belt (the
    residue is the elastic vibration: 0.23 N of about 30 N measured); the lever arms are the
    contours' support functions at the spans' normals."""
    import sys
    sys.path.insert(0, str(BELTS))
    import toothed_belt_design as design
    outs = ["wheel1.phi", "wheel1.omega", "wheel2.phi", "wheel2.omega", "top.F", "bottom.F", "wheel1.h1",
            "wheel2.h1", "wheel2.h2", "wheel1.F1", "wheel1.F2", "wheel2.friction", "wheel2.F1", "wheel2.F2"]
    res = pipeline.run(load(BELTS / "toothed_belt.yaml", {"wheel2.mu": 0.05}), progress=False, outputs=outs)
    o = res.outputs
    phi1, w1, T, J2 = o["wheel1.phi"], 2 * np.pi, 5.0, 0.05
    # elastic deflection: F/k over the lever arm, a few 1e-4 rad
    np.testing.assert_allclose(o["wheel2.phi"], design.phi2_of(phi1), rtol=0, atol=1e-3)
    assert o["wheel2.phi"][-1] == pytest.approx(2 * np.pi, abs=1e-3)
    i = 2 / np.sqrt(1 - 0.2 ** 2) * (1 + 0.2 * np.cos(2 * phi1))
    np.testing.assert_allclose(o["wheel1.omega"] / o["wheel2.omega"], i, rtol=5e-3)
    c1, c2 = (read_table(BELTS / f"toothed_belt_wheel{k}.csv") for k in (1, 2))
    p2 = c2.support(np.pi / 2 - o["wheel2.phi"])
    di = -2 / np.sqrt(1 - 0.2 ** 2) * 0.4 * np.sin(2 * phi1)
    friction = o["wheel2.friction"]
    np.testing.assert_allclose(o["top.F"] - o["bottom.F"], (T + friction + J2 * (-w1 ** 2 * di / i ** 2)) / p2,
                               rtol=0, atol=1.0)
    np.testing.assert_allclose(o["wheel1.h1"], c1.support(-np.pi / 2 - phi1), atol=1e-9)
    np.testing.assert_allclose(o["wheel2.h1"], p2, atol=1e-9)
    np.testing.assert_allclose(o["wheel2.h2"], c2.support(-np.pi / 2 - o["wheel2.phi"]), atol=1e-9)
    # e1 of wheel 1 is the lower span's P2 end, e2 the upper span's P1 end; pin friction of wheel 2
    # mu r_pin (F1 + F2) with parallel spans (wrap pi), against omega > 0
    np.testing.assert_allclose(o["wheel1.F1"], o["bottom.F"], rtol=1e-12)
    np.testing.assert_allclose(o["wheel1.F2"], o["top.F"], rtol=1e-12)
    np.testing.assert_allclose(friction, 0.05 * 0.004 * (o["wheel2.F1"] + o["wheel2.F2"]), rtol=1e-12)
    assert o["top.F"].min() > 0 and o["bottom.F"].min() > 0


def test_real_open_belt_length_of_the_design_script_against_circles():
    """The design script's planar belt length (common tangents and arcs) for two circles is the
    closed form 2 sqrt(a^2 - d^2) + pi (R1 + R2) + 2 d asin(d/a), d = R2 - R1, at any angles: the
    function that measures the documented length error of the parallel-span model."""
    import sys
    sys.path.insert(0, str(BELTS))
    import toothed_belt_design as design
    a, R1, R2 = 0.8, 0.08, 0.16
    exact = 2 * math.sqrt(a * a - (R2 - R1) ** 2) + math.pi * (R1 + R2) + 2 * (R2 - R1) * math.asin((R2 - R1) / a)
    got = design.open_belt_length(Contour.circle(R1), Contour.circle(R2), 0.3, 1.1)
    assert got == pytest.approx(exact, rel=1e-12)


def test_toothed_belt_design_has_the_prescribed_ratio_and_a_constant_model_length():
    """The pitch curves from the tables: p2(pi/2 - phi2)/p1(pi/2 - phi1) = i(phi1) on the upper span and
    the same on the lower one (central symmetry), so in the model with parallel spans the belt length
    is invariant; i_max/i_min = 1.5, mean ratio 2 (wheel perimeters 1:2)."""
    import sys
    sys.path.insert(0, str(BELTS))
    import toothed_belt_design as design
    c1, c2 = (read_table(BELTS / f"toothed_belt_wheel{k}.csv") for k in (1, 2))
    phi1 = np.linspace(0.0, 4 * np.pi, 97)
    phi2 = design.phi2_of(phi1)
    i = 2 / np.sqrt(1 - 0.2 ** 2) * (1 + 0.2 * np.cos(2 * phi1))
    for normal in (np.pi / 2, -np.pi / 2):
        np.testing.assert_allclose(c2.support(normal - phi2) / c1.support(normal - phi1), i, rtol=1e-8)
    assert i.max() / i.min() == pytest.approx(1.5, rel=1e-3)
    assert c2.perimeter / c1.perimeter == pytest.approx(2.0, rel=1e-9)


# -- power balance ------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", range(2))
def test_power_balance_of_the_curve_roll_at_random_states(seed):
    """Toothed belt with pin friction on both wheels, random states: the power into each roll at its
    band and drive ports equals d/dt p^2/(2J) + mu r_pin (F1 + F2) |omega| (the contour's
    transformer is lossless: the torque is w p F), to 1e-10."""
    rng = np.random.default_rng(seed)
    sc = load(BELTS / "toothed_belt.yaml", {"wheel1.mu": 0.2, "wheel2.mu": 0.2})
    model = pipeline.model(sc, prune=False)
    names = list(model.state_names)
    J = {"wheel1": 2.0e-3, "wheel2": 0.05}
    for _trial in range(3):
        x = np.asarray(model.x0, dtype=float).copy()
        for k, n in enumerate(names):
            if n.endswith("c.q"):
                x[k] = rng.uniform(2e-4, 1.5e-3)                     # both spans taut
            elif n.endswith("J.p"):
                x[k] *= rng.uniform(0.5, 1.5)
            elif n.endswith("tap.q"):
                x[k] = rng.uniform(-4, 4)
        vals, dx, st = model.port_values(0.3, x), dict(zip(names, model.rhs(0.3, x))), dict(zip(names, x))
        for roll in ("wheel1", "wheel2"):
            ports = ["T1.a", "T2.a", "W.drive"]
            ext = sum(vals[f"{roll}.{p}.e"] * vals[f"{roll}.{p}.f"] for p in ports)
            if f"{roll}.J.p" in st:
                omega = st[f"{roll}.J.p"] / J[roll]
                dE = omega * dx[f"{roll}.J.p"]
            else:                                   # the driven wheel's momentum is not a state
                omega, dE = vals[f"{roll}.W.drive.f"], vals[f"{roll}.J.p.f"] * vals[f"{roll}.J.p.e"]
            F1, F2 = vals[f"{roll}.T1.a.e"], vals[f"{roll}.T2.a.e"]
            loss = 0.2 * 0.004 * (F1 + F2) * abs(omega)
            scale = abs(dE) + abs(loss) + sum(abs(vals[f"{roll}.{p}.e"] * vals[f"{roll}.{p}.f"]) for p in ports)
            assert abs(ext - (dE + loss)) <= 1e-10 * scale, roll


# -- netlist errors ----------------------------------------------------------------------------------

def test_table_errors_name_the_netlist_the_element_and_the_table(tmp_path):
    _table(tmp_path, [(0, 0.1), (2, -0.1), (4, 0.1)], "bad.csv")
    with pytest.raises(NetlistError) as exc:
        _winch(tmp_path, "{type: curve_drum, contour: bad.csv}")
    assert exc.value.code == "contour_negative_radius"
    text = str(exc.value)
    assert "winch.yaml:6" in text and "'drum'" in text and "bad.csv line 3" in text
    with pytest.raises(NetlistError) as exc:
        _winch(tmp_path, "{type: curve_drum, contour: missing.csv}")
    assert exc.value.code == "no_file" and "missing.csv" in str(exc.value)
    with pytest.raises(NetlistError) as exc:
        _winch(tmp_path, "{type: curve_drum, contour: 0.1}")
    assert exc.value.code == "bad_value"
    write_table(tmp_path / "circle.csv", np.linspace(0, 2 * np.pi, 12, endpoint=False), np.full(12, 0.1))
    with pytest.raises(NetlistError) as exc:
        _winch(tmp_path, "{type: curve_drum, contour: circle.csv, side1: 0}")
    assert exc.value.code == "bad_side" and "'drum'" in str(exc.value)


def test_a_changed_table_is_a_different_scene_for_the_model_cache(tmp_path):
    """The scene's digest (the model cache's key) covers the contents of the table, not only the
    netlist text: after the table changes, the run uses the new contour (lever arm 0.1 -> 0.2 m)."""
    path = tmp_path / "c.csv"
    text = WINCH.replace("{DRUM}", "{type: curve_drum, contour: c.csv, J: 0.01, side1: -1}")
    outs = []
    for r in (0.1, 0.2):
        write_table(path, np.linspace(0, 2 * np.pi, 12, endpoint=False), np.full(12, r))
        sc = loads(text, str(tmp_path / "winch.yaml"))
        outs.append((sc.digest, pipeline.run(sc, progress=False, outputs=["drum.h1"]).outputs["drum.h1"][-1]))
    assert outs[0][0] != outs[1][0]
    assert outs[0][1] == pytest.approx(0.1, rel=1e-12) and outs[1][1] == pytest.approx(0.2, rel=1e-12)


def test_a_device_is_not_read_as_a_table():
    """Netlists are untrusted: a contour naming a device (endless) is refused, not read."""
    with pytest.raises(ModelError) as exc:
        read_table("/dev/zero")
    assert exc.value.code == "bad_contour_table"


def contour_triggers() -> dict:
    """The curve roll's static check's triggering netlist, for tests/test_diagnostics_text.py."""
    return {"curve_roll_side": (lambda: load(BELTS / "toothed_belt.yaml", {"wheel1.side2": -1}),
                                ["wheel1.e2", "P1 end of top", "side2 = +1"])}


def test_an_inconsistent_side_is_reported_and_the_scene_is_consistent():
    """The toothed belt's four contacts follow the rule (side = -w_k at a P1 end, +w_k at a P2 end);
    flipping one side, or the winding sense (both ports then disagree), is reported."""
    codes = lambda sc: [d for d in pipeline.check(sc).diagnostics if d.code == "curve_roll_side"]
    assert codes(load(BELTS / "toothed_belt.yaml")) == []
    found = codes(contour_triggers()["curve_roll_side"][0]())
    assert [d.elements for d in found] == [["wheel1", "top"]]
    assert len(codes(load(BELTS / "toothed_belt.yaml", {"wheel2.w": -1}))) == 2


# -- engaged arcs (synthesis results) ----------------------------------------------------------------

def test_an_engaged_arc_is_completed_without_changing_the_arc():
    """An arc of the ellipse (theta 0.3 .. 2.5 rad, 500 points) completed by the C2 closing part: over
    the normals the arc covers, the support function is the ellipse's (measured 2e-12 m; the
    periodic spline and the arc's own spline agree there), and the closed contour is convex."""
    th = np.linspace(0.3, 2.5, 500)
    c = Contour.from_arc(th, _ellipse_r(th), "ellipse arc")
    nu = np.linspace(c.normal_angle(0.3), c.normal_angle(2.5), 301)
    np.testing.assert_allclose(c.support(nu), _ellipse_support(nu), rtol=0, atol=1e-10)
    assert c.kappa_min > 0
    with pytest.raises(ModelError) as exc:              # an arc whose ends cannot be joined convexly
        Contour.from_arc(th, 0.05 + 0.2 * (th - 0.3) ** 2, "spiral")
    assert exc.value.code in ("contour_not_closed", "contour_not_convex")
    assert c.joins == "C4"                              # a C4 join exists here: no fallback taken


def test_one_arc_closure_falls_back_to_c2_joins_and_says_so():
    """The cabinet door's engaged arc (diagrams/belts/cabinet_door_contour.csv, Ebert 7.2.1): its C4
    closing part would pass the axis, so ``arc: true`` closes it with C2 joins and warns
    (ClosureWarning), never silently.  The closed contour keeps the arc's points unchanged, is
    convex (curvature > 0 everywhere) and stays clear of the axis."""
    from elements.belt_contour import ClosureWarning, read_points
    path = Path(__file__).resolve().parents[1] / "diagrams" / "belts" / "cabinet_door_contour.csv"
    th, r = read_points(path)
    with pytest.warns(ClosureWarning, match="C2 joins"):
        c = read_table(path, arc=True)
    assert c.joins == "C2" and c.kappa_min > 0
    assert np.array_equal(c.theta[:len(th)], th) and np.array_equal(c.r[:len(th)], r)
    assert np.all(c.radius(th) > 0) and np.min(c.r) > 0.1 * np.min(r)


def test_transfer_function_round_trip_through_an_engaged_arc(tmp_path):
    """The cam of X(phi) = h0 phi - (A/2) sin 2 phi synthesised only over the normals the band uses
    (a turn of 200 deg plus 10 deg each side), written as an arc table, read with arc: true and
    turned by 200 deg: the band travel is X to 1e-8 of the stroke."""
    h0, amp, span = 0.1, 0.02, np.radians(200.0)
    nu0 = -np.pi / 2
    nu = np.linspace(nu0 - span - np.radians(10), nu0 + np.radians(10), 801)
    p = h0 - amp * np.cos(2 * (nu0 - nu))
    dp = -2 * amp * np.sin(2 * (nu0 - nu))
    from elements.belt_contour import polar_from_support
    th, r = polar_from_support(p, dp, nu)
    th = np.unwrap(th)
    order = np.argsort(th)
    write_table(tmp_path / "arc.csv", th[order], r[order], "engaged arc")
    text = WINCH.replace("{DRUM}", "{type: curve_drum, contour: arc.csv, arc: true, J: 0.01, side1: -1}").replace(
        "value: -w", "value: w").replace("t_end: 1.0", f"t_end: {float(span) / 0.5!r}")
    text = text.replace("gamma: 0.3", "gamma: 0.0")
    res = pipeline.run(loads(text, str(tmp_path / "arc.yaml")), progress=False, outputs=["rope.stretch", "drum.phi"])
    phi = res.outputs["drum.phi"]
    X = h0 * phi - amp / 2 * np.sin(2 * phi)
    assert phi[-1] == pytest.approx(span, rel=1e-9)
    np.testing.assert_allclose(0.01 - res.outputs["rope.stretch"], X, rtol=0, atol=1e-8 * X[-1])


def test_half_plane_choice_gives_the_side_of_the_contact_normal():
    """Ebert's enumHE made once at t = 0: the contact normal gamma0 + side*pi/2 points into the chosen
    half-plane (a horizontal span from left to right touches a roll below it at its top: 'upper',
    side +1); on the half-plane's boundary both contacts qualify."""
    from elements.belt_contour import side_from_half_plane
    assert side_from_half_plane(0.0, "upper") == 1 and side_from_half_plane(0.0, "lower") == -1
    assert side_from_half_plane(np.pi, "upper") == -1             # the span runs right to left
    assert side_from_half_plane(np.pi / 2, "left") == 1 and side_from_half_plane(np.pi / 2, "right") == -1
    assert side_from_half_plane(0.3, "right") == -1               # normal at 0.3 - pi/2 points right
    with pytest.raises(ModelError) as exc:
        side_from_half_plane(0.0, "left")
    assert exc.value.code == "half_plane_ambiguous"


# -- run-time monitors -----------------------------------------------------------------------------

def test_elliptic_drum_stops_when_its_band_is_paid_out(tmp_path, ellipse):
    """0.05 m of band stored on the elliptic drum, paid out at 0.5 rad/s: the run stops when the arc
    between the contact points reaches 0.05 m, at the time the closed-form arc length gives."""
    from scipy.optimize import brentq
    write_table(tmp_path / "ellipse.csv", ellipse.theta, ellipse.r)
    text = WINCH.replace("{DRUM}", "{type: curve_drum, contour: ellipse.csv, J: 0.01, side1: -1, stored: 0.05}"
                         ).replace("value: -w", "value: w").replace("cd: 0.0", "cd: 1.0")   # (the rope goes slack)
    with pytest.raises(MultipoleError) as exc:
        pipeline.run(loads(text, str(tmp_path / "winch.yaml")), progress=False)
    assert exc.value.code == "drum_paid_out" and "drum" in str(exc.value)
    nu0 = 0.3 - np.pi / 2
    t_out = brentq(lambda t: _ellipse_arc(nu0) - _ellipse_arc(nu0 - 0.5 * t) - 0.05, 0.01, 1.0)
    t = float(str(exc.value).split("at t = ")[1].split(" s")[0])
    assert t == pytest.approx(t_out, abs=2e-6)            # printed with 6 digits; the arc's series error ~1e-8 m


def test_curve_roll_reports_the_capstan_limit():
    """The toothed belt with a load torque growing by 40 N*m/s on wheel 2 and a contact friction mu_c
    there: with mu_c = 0.2 the limit e^(0.2 pi) = 1.87 of the tension ratio is crossed (near
    T = 10 N*m: spans 100 +- 30 N), and the run reports it on wheel 2; with mu_c = 0.5 (limit 4.8)
    it stays silent over 0.3 s (T = 17 N*m: about 151/49 N)."""
    text = (BELTS / "toothed_belt.yaml").read_text().replace("value: -T}", "value: -T - 40*t}")
    assert "40*t" in text
    found = {}
    for mu_c in (0.2, 0.5):
        res = pipeline.run(loads(text, str(BELTS / "ramp.yaml"), {"wheel2.mu_c": mu_c}), progress=False, t_end=0.3)
        found[mu_c] = [m for m in res.monitors if m[2] == "capstan_limit"]
    assert found[0.5] == [] and found[0.2] and found[0.2][0][1] == "wheel2"
    assert 0.08 < found[0.2][0][0] < 0.2


def test_a_contour_the_series_cannot_follow_is_refused():
    """A coarse table (90 points) whose spline ripples between its knots, asked for 1e-13 m: the left-out
    harmonics stay above that beyond 400 (they decay like k^-4 from the knots' jumps of r''')."""
    coarse = Contour.from_function(_ellipse_r, 90, "coarse")
    with pytest.raises(ModelError) as exc:
        coarse.series(1e-13)
    assert exc.value.code == "contour_too_rough" and "coarse" in exc.value.message
    a, _b = coarse.series(1e-6)                                    # a looser tolerance is met
    assert len(a) <= 401 and coarse.series_error[0] <= 1e-6


def test_an_undamped_rope_goes_slack_once_off_a_cam(tmp_path):
    """A drum whose contour is a circle of 0.1 m off its axis by 0.02 m (support function
    p = 0.1 + 0.02 cos nu) pays out its rope (cd = 0, stretch 0.01 m): the rope goes slack once, when
    the paid-out X(phi) = 0.1 phi + 0.02 (sin nu0 - sin(nu0 - phi)) reaches 0.01 m (nu0 = 0.3 - pi/2).
    With the damper's clamp switching at the spring's root too, the run chattered."""
    from scipy.optimize import brentq
    cam = Contour.from_support(lambda nu: 0.1 + 0.02 * np.cos(nu), lambda nu: -0.02 * np.sin(nu), 720, "offset")
    write_table(tmp_path / "offset.csv", cam.theta, cam.r)
    text = WINCH.replace("{DRUM}", "{type: curve_drum, contour: offset.csv, J: 0.01, side1: -1}").replace(
        "value: -w", "value: w")
    res = pipeline.run(loads(text, str(tmp_path / "w.yaml")), progress=False, outputs=["rope.F", "rope.stretch"])
    nu0 = 0.3 - np.pi / 2
    t_slack = brentq(lambda t: 0.1 * 0.5 * t + 0.02 * (np.sin(nu0) - np.sin(nu0 - 0.5 * t)) - 0.01, 0.0, 1.0)
    assert len(res.events) == 1 and res.events[0][0] == pytest.approx(t_slack, abs=1e-8)
    assert res.outputs["rope.F"][-1] == 0.0 and res.outputs["rope.stretch"][-1] < 0
