"""Planar bands after Ebert (2015, §4.4.1, §4.4.4): spans between moving rolls, rolls on planar ports.

``planar_band`` is the elastic span of :func:`elements.belt.band` whose end points are the common
tangent points of two circles: it reads the positions of the circles' centres from its planar ports
``p1``/``p2`` (a roll's centre port ``c``, a linkage output, or the frame when unconnected), knows
their radii ``r1``/``r2`` and wrap senses ``s1``/``s2`` and hands each roll the direction in which
the span leaves it (``gamma`` at ``e1``, ``gamma + pi`` at ``e2``).  ``planar_roll`` is the circular
roll of :func:`elements.belt.band_roll` whose bearing is a planar port ``a`` (a linkage output, or the
frame), ``planar_drum`` the drum derived from it; the check ``planar_band_roll`` refuses a span whose
radius, wrap sense or centre disagrees with its roll.

Geometry (signed radii, one tangent per pair of wrap senses).  With the unit vector t = (cos g,
sin g) of the span (from end 1 to end 2) and its left normal n = (-sin g, cos g), the tangent
points are K_i = C_i + rho_i n with rho_1 = -s1 r1 and rho_2 = s2 r2, so
d = C2 - C1 = l_B t - Delta n with Delta = rho_2 - rho_1 = s1 r1 + s2 r2, and

    l_B = sqrt(|d|^2 - Delta^2),   g = atan2(d_y, d_x) + atan2(Delta, l_B)       (at t = 0 only)
    n . d + Delta = 0                                                            (the closure on g)

The wrap sense s_i = cross(K_i - C_i, t_i)/r_i (t_i the direction from K_i into the span) is +1 if
a positive (counter-clockwise) rotation of the roll pays band out into this span: the roll's ``w``
at its port ``e1`` and ``-w`` at ``e2``.  The inclination ``g`` is the integral of its rate (never
wrapped), held on the tangent by the closure, solved at every evaluation; its start value is the
formula above (the half-plane choice of Ebert's table 4.16 is made by the wrap senses).

Power (derived in ``docs/belts.md``).  The true wound length delivered by a roll is
l_r = s r [(phi - phi0) - (g - g0)] (Ebert 4.95 corrected, erratum E4); with l_B' = t.d' -
Delta g', the stretch delta = l_B - l_x (l_x = l0 + l_r1 + l_r2) has the rate

    delta' = t . (v_C2 - v_C1) - s1 r1 phi1' - s2 r2 phi2'

so the band bond carries the roll's surface speed s r phi' (as for the 1-D roll), the span pulls
the centres with -F t and +F t, the rolls feel the torque s r F, and ``gamma`` carries no torque.
A roll's wrap w (gamma1 - gamma2) - pi (in (0, 2 pi) at t = 0, then integrated) feeds the monitors
of :func:`elements.belt._roll` (``band_lifts_off``, ``capstan_limit``); a drum's ``drum_paid_out``
watches the wound-off length with the span's turning.  Units: SI (m, rad, N, N*s, kg, kg*m^2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import sympy as sp

from multipole import (MTF, Closure, Diagnostic, I, ModelError, Monitor, Network, Param, Quantity, R, Se, Sketch, Tap,
                       element, junction_a, junction_b, register_check)

from .belt import _BAND, _roll, span_law
from .belt_checks import _value, band_graph
from .linkage import _zero

_S = sp.Symbol
_PLANAR = "planar bundle (x, y [m], phi [rad]; Fx, Fy [N], T [N*m])"
#: points of the polygon that draws a roll's circle
_CIRCLE = 24


def _sense(kind: str, name: str, value) -> int:
    if value not in (1, -1, 1.0, -1.0):
        raise ModelError("bad_wrap_sense", f"{kind}: {name} = {value!r} must be +1 or -1",
                         "+1 if a counter-clockwise rotation of the roll pays band out into this span "
                         "(the roll's w at its port e1, -w at e2)")
    return int(value)


def span_quantities(point: str, body: str) -> dict:
    """The quantities of a planar span whose ends touch a ``body`` ("circle", "contour") at a ``point``
    ("tangent point", "contact point"): planar_band and planar_curve_band declare the same ones."""
    return {"F": "N: band tension (>= 0)", "stretch": "m: l_B - l_x (> 0 taut, <= 0 slack)",
            "length": f"m: span length l_B between the {point}s", "free": "m: free length l_x = l_B - stretch",
            "gamma": f"rad: inclination of the span from {body} 1 to {body} 2 (continuous, not wrapped)",
            "rate": "m/s: stretch rate",
            **{f"{c}K{k}": f"m: {c} of the {point} on {body} {k}" for k in (1, 2) for c in ("x", "y")}}


def tangent(x1, y1, r1, s1, x2, y2, r2, s2):
    """The common tangent from circle 1 to circle 2 with wrap senses ``s1``, ``s2`` (see the module
    docstring): ``(l_B, gamma, K1, K2)`` [m, rad, (x, y) m] as sympy expressions (or floats).  The
    circles must leave room for the tangent: ``|C2 - C1| > |s1 r1 + s2 r2|``."""
    f = sp if any(isinstance(v, sp.Basic) for v in (x1, y1, r1, x2, y2, r2)) else math
    dx, dy, delta = x2 - x1, y2 - y1, s1 * r1 + s2 * r2
    lb = f.sqrt(dx ** 2 + dy ** 2 - delta ** 2)
    g = f.atan2(dy, dx) + f.atan2(delta, lb)
    n = (-f.sin(g), f.cos(g))
    return lb, g, (x1 - s1 * r1 * n[0], y1 - s1 * r1 * n[1]), (x2 + s2 * r2 * n[0], y2 + s2 * r2 * n[1])


@element("planar_band", "elastic band span between two circles (Ebert 4.4.1 on planar ports): the common tangent "
         "of the circles about the centres read at p1, p2 with radii r1, r2 and wrap senses s1, s2; "
         "tension-only Kelvin-Voigt band, stiffness EA/l_x",
         {"e1": f"band end at circle 1 ({_BAND}; gamma: the span's inclination); held (band tied) if not "
                "connected",
          "e2": f"band end at circle 2 ({_BAND}; gamma: the inclination + pi, the direction of the span leaving "
                "circle 2); held (band tied) if not connected",
          "p1": f"centre of circle 1 ({_PLANAR}; the span pulls it, no torque): a roll's port c, a "
                "linkage output; frame-fixed at (x1, y1) if not connected",
          "p2": f"centre of circle 2 ({_PLANAR}); frame-fixed at (x2, y2) if not connected"},
         [Param("EA", "N", "axial stiffness times length (k = EA/l_x)", 1e5, positive=True),
          Param("cd", "N*s", "axial damping times length (b = cd/l_x)", 0.0, nonnegative=True),
          Param("F0", "N", "tension at t = 0 (sets the free length l0 = EA l_B(0)/(EA + F0))", 0.0,
                nonnegative=True),
          Param("r1", "m", "radius of circle 1 (0: a point, a band end tied to a link)", 0.0, nonnegative=True),
          Param("s1", "-", "wrap sense at circle 1: +1 if a counter-clockwise rotation of roll 1 pays band out "
                "into the span (the roll's w at e1, -w at e2)", 1.0),
          Param("r2", "m", "radius of circle 2", 0.0, nonnegative=True),
          Param("s2", "-", "wrap sense at circle 2 (as s1)", 1.0),
          Param("x1", "m", "frame position x of centre 1 when p1 is not connected", 0.0),
          Param("y1", "m", "frame position y of centre 1 when p1 is not connected", 0.0),
          Param("x2", "m", "frame position x of centre 2 when p2 is not connected", 1.0),
          Param("y2", "m", "frame position y of centre 2 when p2 is not connected", 0.0)],
         span_quantities("tangent point", "circle"))
def planar_band(EA, cd, F0, r1, s1, r2, s2, x1, y1, x2, y2):
    """Planar elastic span [EA, F0 in N, cd in N*s, lengths in m]."""
    s1, s2 = _sense("planar_band", "s1", s1), _sense("planar_band", "s2", s2)
    params = {"EA": EA, "cd": cd, "F0": F0, "r1": r1, "s1": s1, "r2": r2, "s2": s2,
              "x1": x1, "y1": y1, "x2": x2, "y2": y2}
    return planar_span("planar_band", (SpanEnd.circle(1), SpanEnd.circle(2)), params)


@dataclass
class SpanEnd:
    """What a planar span knows of the contour at one of its ends (``docs/belts.md``, planar curve spans).

    ``support(nu)`` [m] and ``slope(nu)`` [m/rad]: the contour's support function p and its derivative
    p' as sympy expressions of the normal angle ``nu`` [rad] in the contour's frame; ``angle``: the
    contour's angle [rad] in the plane (a local name, e.g. a read of the roll's angle; 0: a circle,
    whose p does not depend on it); ``mean`` [m]: the radius of the circle the start value assumes;
    ``sense``: the wrap sense as a local name or +-1; ``refine``: fixed-point steps of the start value
    (0 for a circle, whose start formula is exact)."""

    support: Callable
    slope: Callable
    sense: object
    angle: object = 0
    mean: object = None
    refine: int = 0

    @classmethod
    def circle(cls, k: int) -> "SpanEnd":
        """End ``k`` on the circle of radius ``r<k>`` with wrap sense ``s<k>`` (the span's parameters)."""
        r = _S(f"r{k}")
        return cls(lambda nu: r, lambda nu: sp.Integer(0), _S(f"s{k}"), 0, r)


def planar_span(kind: str, ends: tuple, params: dict, reads=None) -> Network:
    """The elastic span on the common tangent of the contours at its two ends (:class:`SpanEnd`).

    Residual of the closure on the inclination g: n . d + s1 p1(nu1) + s2 p2(nu2) = 0 with the contact
    normals nu1 = g - s1 pi/2 - a1 and nu2 = g + s2 pi/2 - a2 in the contours' frames (a: their angles);
    span length l_B = t . d - s1 p1' - s2 p2'; contact points K1 = C1 - s1 p1 n + s1 p1' t,
    K2 = C2 + s2 p2 n - s2 p2' t; the rate of g is (n . d' - s1 p1' a1' - s2 p2' a2')/l_B (the contours'
    angles a_i, read by ``reads``, enter only at an end whose p' is not 0: its port ``p<i>.phi`` is then an
    MTF column carrying a_i', with no torque).  A circle (p = r, p' = 0) gives the tangent of
    :func:`tangent` exactly, and the element of before (planar_band).  ``params``: the element's parameters."""
    e1, e2 = ends
    xa, ya, xb, yb, g = _S("xa"), _S("ya"), _S("xb"), _S("yb"), _S("gam")
    dx, dy = xb - xa, yb - ya
    half = sp.pi / 2 if not (e1.refine or e2.refine) else sp.Float(math.pi / 2)

    def normals(at):
        return at - e1.sense * half - e1.angle, at + e2.sense * half - e2.angle

    def offset(at):                                   # Delta(g) = s1 p1(nu1) + s2 p2(nu2)
        n1, n2 = normals(at)
        return e1.sense * e1.support(n1) + e2.sense * e2.support(n2)

    n1, n2 = normals(g)
    p1, p2, d1, d2 = e1.support(n1), e2.support(n2), e1.slope(n1), e2.slope(n2)
    delta = e1.sense * p1 + e2.sense * p2
    c, s = sp.cos(g), sp.sin(g)
    lb = c * dx + s * dy - e1.sense * d1 - e2.sense * d2     # t . (K2 - K1): the span length on the tangent
    # start value: the tangent of the circles of radius `mean` (exact for circles), then Newton steps on
    # the closure, whose derivative is -l_B: g <- g + (n . d + Delta(g))/l_B(g).  The stretch at t = 0
    # takes l_B at the last step's start (its expression at the last step's result would grow by the
    # terms of the series again; docs/belts.md says what that costs in F0)
    lb0, g0, _k1, _k2 = tangent(xa, ya, e1.mean, e1.sense, xb, yb, e2.mean, e2.sense)
    radicand = dx ** 2 + dy ** 2 - (e1.sense * e1.mean + e2.sense * e2.mean) ** 2
    conditions, steps = [], max(e1.refine, e2.refine)
    if steps:
        conditions.append((radicand - 1e-10, "the contours leave no room for a tangent of positive length at their "
                           "mean radii: |C2 - C1| must exceed |s1 p1 + s2 p2|", "m^2"))
        radicand = dx ** 2 + dy ** 2 - offset(g0) ** 2       # at the circles' tangent
    for _ in range(steps):
        at = {g: g0}
        lb0 = lb.xreplace(at)
        g0 = g0 + (-sp.sin(g0) * dx + sp.cos(g0) * dy + delta.xreplace(at)) / lb0
    q = _S("delta")
    lx = lb - q
    turning = [k for k, e in ((1, d1), (2, d2)) if not sp.sympify(e).is_zero]
    rate_row = [s / lb, -c / lb, -s / lb, c / lb] + [-(e1.sense * d1 if k == 1 else e2.sense * d2) / lb
                                                    for k in turning]
    children = {
        # a1: t . (v2 - v1), the stretch rate of the span seen from the centres; a2: gamma' (with the
        # contours' turning where their contact slides: columns b5, b6)
        "K": MTF([[-c, -s, c, s] + [0] * len(turning), rate_row], ["translational", "rotational"],
                 ["translational"] * 4 + ["rotational"] * len(turning)),
        # common tension: e_s = F (the pull on the span along t), e_e1 = e_e2 = -F; x carries delta'
        "J": junction_a(["s", "e1", "e2", "x"], "translational", [1, -1, -1, -1]),
        "X": junction_b(["x", "c", "r"], "translational"),
        **span_law(_S("EA") / lx, _S("cd") / lx, _S("F0") * lb0 / (_S("EA") + _S("F0"))),
        # gamma' to both band ports (no torque) and its integral, the closure-bound inclination
        "G": junction_b(["k", "e1", "e2", "tap"], "rotational"),
        "tap": Tap("rotational", q0=g0)}
    children |= {f"t{k}": Se(0, "rotational") for k in (1, 2) if k not in turning}
    connections = [["K.a1", "J.s"], ["J.x", "X.x"], ["X.c", "c.p"], ["X.r", "r.p"], ["K.a2", "G.k"],
                   ["G.tap", "tap.p"]]
    ports = {"e1.l": "J.e1", "e1.gamma": "G.e1", "e2.l": "J.e2", "e2.gamma": "G.e2",
             "p1.x": "K.b1", "p1.y": "K.b2", "p2.x": "K.b3", "p2.y": "K.b4"}
    ports |= {f"p{k}.phi": f"K.b{5 + turning.index(k)}" if k in turning else f"t{k}.p" for k in (1, 2)}
    k1 = (xa - e1.sense * p1 * -s + e1.sense * d1 * c, ya - e1.sense * p1 * c + e1.sense * d1 * s)
    k2 = (xb + e2.sense * p2 * -s - e2.sense * d2 * c, yb + e2.sense * p2 * c - e2.sense * d2 * s)
    closure = Closure(["tap.q"], [-s * dx + c * dy + delta],
                      "the span on the common tangent of the two " + ("circles" if not turning else "contours"),
                      # (10 um)^2: a span of (nearly) zero length has no direction (atan2(0, 0) := 0 is refused)
                      conditions=conditions + [(radicand - 1e-10, "the " + ("contours" if turning else "circles") + " leave"
                                   + " no room for a tangent of positive length: |C2 - C1| must exceed "
                                   + ("|s1 r1 + s2 r2|" if not turning else "|s1 p1 + s2 p2| (the contours overlap)")
                                   + " (spans shorter than 10 um are refused)", "m^2")],
                      guard=(lb, 1e-6, "span length"))
    names = {xa, ya, xb, yb} | set().union(*(r.free_symbols for r in (e1.angle, e2.angle, e1.sense, e2.sense)
                                             if isinstance(r, sp.Basic)))

    def local(expr):
        """``expr`` in the flattened names: the position reads, the parameters and the inclination state."""
        return lambda V: sp.sympify(expr).xreplace({sym: V.param(sym.name) for sym in sp.sympify(expr).free_symbols
                                                    if sym in names or sym.name in params} | {g: V.x("tap.q")})

    def qv(expr):
        return Quantity(local(expr))

    q_ = {"F": Quantity(lambda V: V.e("J.s")), "stretch": Quantity(lambda V: V.x("c.q")),
          "length": qv(lb), "free": Quantity(lambda V: local(lb)(V) - V.x("c.q")),
          "gamma": Quantity(lambda V: V.x("tap.q")), "rate": Quantity(lambda V: V.f("c.p")),
          "xK1": qv(k1[0]), "yK1": qv(k1[1]), "xK2": qv(k2[0]), "yK2": qv(k2[1])}
    return Network(kind, children, connections, ports, params, q_, signals={"delta": "c.q", "gam": "tap.q"},
                   bundles={"e1": "band", "e2": "band", "p1": "planar", "p2": "planar"},
                   positions={"e1.gamma": g, "e2.gamma": g + sp.pi},
                   reads={"xa": ("p1.x", _S("x1")), "ya": ("p1.y", _S("y1")),
                          "xb": ("p2.x", _S("x2")), "yb": ("p2.y", _S("y2"))} | dict(reads or {}),
                   fixed=("e1.l", "e2.l", "p1.x", "p1.y", "p1.phi", "p2.x", "p2.y", "p2.phi"),
                   closures=[closure], sketch=[Sketch([k1, k2], ["", ""], style="line")])


_BEARING = {"a": f"bearing ({_PLANAR}): the axis, e.g. a lever's output; frame-fixed at (x1, y1) if not "
                 "connected; its phi component takes the pin friction torque (none when mu = 0)",
            "c": f"centre seen by the spans ({_PLANAR}): join it to the spans' p1/p2 ports; it moves with a, "
                 "and the span forces on it act on a",
            "drive": "1-D rotational port on the roll (absolute angular velocity [rad/s], torque on the roll [N*m])"}


def _roll_params(extra: list) -> list:
    return [Param("r", "m", "radius (to the band's neutral layer)", 0.05, positive=True),
            Param("J", "kg*m^2", "moment of inertia about the axis", 1e-3, positive=True),
            Param("phi0", "rad", "initial angle (absolute)", 0.0),
            Param("omega0", "rad/s", "initial angular velocity (absolute)", 0.0),
            Param("w", "-", "winding sense: +1: a counter-clockwise rotation pays band out at e1 (winds in at e2)",
                  1.0),
            Param("m", "kg", "mass on the axis (0: carried by the bearing's body only)", 0.0, nonnegative=True),
            Param("gx", "m/s^2", "gravity, x component", 0.0), Param("gy", "m/s^2", "gravity, y component", -9.81),
            Param("mu", "-", "bearing friction coefficient: torque mu*r_pin*|span forces on the axis| against "
                  "the rotation relative to the housing", 0.0, nonnegative=True),
            Param("r_pin", "m", "bearing pin radius", 0.004, nonnegative=True)] + extra + [
            Param("x1", "m", "frame position x of the axis when a is not connected", 0.0),
            Param("y1", "m", "frame position y of the axis when a is not connected", 0.0)]


_ROLL_QUANTITIES = {
    "phi": "rad: roll angle", "omega": "rad/s: angular velocity", "F1": "N: band tension at e1",
    "lr1": "m: band wound off into the span at e1, w r [(phi - phi0) - (gamma1 - gamma1(0))]",
    "Fx": "N: x force of the spans on the axis", "Fy": "N: y force of the spans on the axis",
    "x": "m: x of the axis", "y": "m: y of the axis",
    "friction": "N*m: bearing friction torque (taken from the roll, positive when it turns faster than its housing)"}


@element("planar_roll", "circular band roll on a planar bearing (Ebert 4.4.4, corrected): the roll of band_roll "
         "(no-slip winding at radius r, inertia J) whose axis is the planar port a; the spans pull its centre "
         "through the port c",
         _BEARING | {"e1": f"band port 1 ({_BAND}): a span with wrap sense s = w there",
                     "e2": f"band port 2 ({_BAND}): a span with wrap sense s = -w there"},
         _roll_params([Param("mu_c", "-", "contact friction for the capstan monitor (None: no monitor): reports a "
                             "run where one tension exceeds e^(mu_c*wrap) times the other", None)]),
         _ROLL_QUANTITIES | {
             "F2": "N: band tension at e2",
             "lr2": "m: band wound off at e2, -w r [(phi - phi0) - (gamma2 - gamma2(0))]",
             "wrap": "rad: wrap angle, from the contact where the band runs on to the one where it leaves "
                     "(in (0, 2 pi) at t = 0, continuous; the monitor band_lifts_off reports it falling to 0)"})
def planar_roll(r, J, phi0, omega0, w, m, gx, gy, mu, r_pin, mu_c, x1, y1):
    """Circular roll on a planar bearing [r in m, J in kg*m^2, angles in rad, m in kg]."""
    params = {"r": r, "J": J, "phi0": phi0, "omega0": omega0, "w": w, "m": m, "gx": gx, "gy": gy, "mu": mu,
              "r_pin": r_pin, "x1": x1, "y1": y1} | ({} if mu_c is None else {"mu_c": mu_c})
    return _planar_roll("planar_roll", 2, params, mu_c=mu_c)


@element("planar_drum", "band drum on a planar bearing (Ebert 4.4.4 derived): planar_roll with one band end "
         "fixed on it; winds band in or pays it out at e1",
         _BEARING | {"e1": f"band port ({_BAND}): a span with wrap sense s = w there"},
         _roll_params([Param("stored", "m", "band stored on the drum at t = 0 (None: no monitor): paying out "
                             "more stops the run (drum_paid_out)", None)]),
         _ROLL_QUANTITIES)
def planar_drum(r, J, phi0, omega0, w, m, gx, gy, mu, r_pin, stored, x1, y1):
    """Band drum on a planar bearing [r in m, J in kg*m^2, angles in rad, m in kg]."""
    params = {"r": r, "J": J, "phi0": phi0, "omega0": omega0, "w": w, "m": m, "gx": gx, "gy": gy, "mu": mu,
              "r_pin": r_pin, "x1": x1, "y1": y1} | ({} if stored is None else {"stored": stored})
    return _planar_roll("planar_drum", 1, params, stored=stored)


def _planar_roll(kind: str, sides: int, params: dict, mu_c=None, stored=None, contact=None,
                 outline=None) -> Network:
    """A roll (``sides`` = 2) or drum (1) of :func:`elements.belt._roll` on the planar bearing ``a``,
    its centre ``c`` handed to the spans; ``params`` the element's parameters (by name).

    ``contact(k)``: a curve roll's (lever arm, wound length) at band port k, expressions of the roll's
    angle ``phi``, the span direction ``g<k>`` read at the port and its change ``dg<k>`` since t = 0
    (:func:`elements.belt._roll`); its ``c.phi`` is then the roll's own angle (the spans read the
    contour's pose there), not the housing's.  ``outline``: (theta, r) [rad, m] of the polygon drawn."""
    w, m, mu = params["w"], params["m"], params["mu"]
    # the 1-D roll with its parameters bound to this element's (a scene's expression like
    # omega0: w*r/R is resolved once, in the scene, not inside the roll where w is the winding sense);
    # a roll's wrap is the state beta below (monitors band_lifts_off and, with mu_c, capstan_limit)
    roll = _roll(kind, sides, None if contact else _S("r"), _S("J"), _S("phi0"), _S("omega0"), w, 0, 0,
                 _S("beta") if sides == 2 else None, mu_c=None if mu_c is None else _S("mu_c"), contact=contact)
    children = {"R": roll}
    ends = range(1, sides + 1)
    connections, ports = [], {"drive": "R.drive", "a.phi": "H.a", "c.phi": "H.c"} | \
        {f"e{k}.l": f"R.e{k}.l" for k in ends}
    children["H"] = junction_b(["a", "c"], "rotational")     # the housing angle, handed from a to c
    signals = {"rphi": "R.tap.q"} | ({f"dg{k}": f"tap{k}.q" for k in ends} if contact else {})
    if contact:
        # a curve roll hands its own angle to the spans (they read the contour's pose at c.phi)
        children["H"] = Se(0, "rotational")      # the housing feels no torque (pin friction: below)
        children["D"] = junction_b(["o", "r", "c"], "rotational")
        connections.append(["D.r", "R.drive"])
        ports |= {"drive": "D.o", "c.phi": "D.c", "a.phi": "H.p"}
    if not _zero(mu):
        # pin friction between the roll and its housing, loaded by the span forces on the axis
        children["H"] = junction_b(["a"] + ([] if contact else ["c"]) + ["f"], "rotational")
        ports["a.phi"] = "H.a"
        children["D"] = junction_b(["o", "r", "f"] + (["c"] if contact else []), "rotational")
        children["F"] = junction_a(["a", "b", "x"], "rotational", [1, -1, -1])
        children["fric"] = R(law=_S("mu") * _S("r_pin") * sp.sqrt(_S("Fcx") ** 2 + _S("Fcy") ** 2) * sp.sign(_S("f")),
                             dom="rotational")
        connections += ([] if contact else [["D.r", "R.drive"]]) + [["D.f", "F.a"], ["H.f", "F.b"], ["F.x", "fric.p"]]
        ports["drive"] = "D.o"
        signals.update({"Fcx": "xJ.c.e", "Fcy": "yJ.c.e"})
    for axis in "xy":
        names = ["a", "c"] + ([] if _zero(m) else ["m", "g"])
        children[f"{axis}J"] = junction_b(names, "translational")
        ports[f"a.{axis}"], ports[f"c.{axis}"] = f"{axis}J.a", f"{axis}J.c"
        if not _zero(m):
            children[f"m{axis}"] = I(J=_S("m"), dom="translational", p0=None)
            children[f"g{axis}"] = Se(_S("m") * _S(f"g{axis}"), "translational")
            connections += [[f"{axis}J.m", f"m{axis}.p"], [f"{axis}J.g", f"g{axis}.p"]]
    # the band ports' gamma (the direction of each span leaving the roll): no torque; a tap integrates
    # gamma - gamma(0) for the wound lengths.  The contacts lie at kappa1 = gamma1 - w pi/2 and
    # kappa2 = gamma2 + w pi/2; the band runs on at e2 and off at e1, so the wrap is w (kappa1 - kappa2)
    # = w (gamma1 - gamma2) - pi, taken in (0, 2 pi) at t = 0 and integrated from the rates after it
    ws, g1, g2 = (1 if w in (1, 1.0) else -1), _S("g1"), _S("g2")
    for k in ends:
        children[f"G{k}"] = junction_b(["o", "i", "tap"] + (["w"] if sides == 2 else []), "rotational")
        children[f"tap{k}"] = Tap("rotational", q0=0)
        connections += [[f"G{k}.i", f"R.e{k}.gamma"], [f"G{k}.tap", f"tap{k}.p"]]
        ports[f"e{k}.gamma"] = f"G{k}.o"
    xa, ya, pa = _S("xa"), _S("ya"), _S("pa")
    # the band wound off at port k: w_k r [(phi - phi0) - (gamma_k - gamma_k(0))] on a circle, the
    # contour's w_k (S(nu_k(0)) - S(nu_k)) on a curve roll (w_1 = w, w_2 = -w)
    wound = {k: (1 if k == 1 else -1) * (_S("w") * contact(k)[1] if contact else
                                         _S("w") * _S("r") * (_S("rphi") - _S("phi0") - _S(f"dg{k}"))) for k in ends}
    signals |= {f"dg{k}": f"tap{k}.q" for k in ends}

    def local(expr):
        """``expr`` (the roll's local names) in the flattened names."""
        return lambda V: expr.xreplace({v: V.x("R.tap.q") if v.name in ("rphi", "phi") else
                                        V.x(f"tap{v.name[2:]}.q") if v.name.startswith("dg") else V.param(v.name)
                                        for v in expr.free_symbols})

    q = {"phi": Quantity(lambda V: V.x("R.tap.q")), "omega": Quantity(lambda V: V.f("R.drive")),
         "F1": Quantity(lambda V: V.e("R.T1.a")), "lr1": Quantity(local(wound[1])),
         "Fx": Quantity(lambda V: V.e("xJ.c")), "Fy": Quantity(lambda V: V.e("yJ.c")),
         "x": Quantity(lambda V: V.param("xa")), "y": Quantity(lambda V: V.param("ya")),
         "friction": Quantity(lambda V: V.e("fric.p") if "fric" in children else sp.Integer(0))}
    reads = {"xa": ("a.x", _S("x1")), "ya": ("a.y", _S("y1")), "pa": ("a.phi", 0)}
    if contact:
        reads |= {f"g{k}": (f"e{k}.gamma", 0) for k in ends}
    if sides == 2:
        wrap0 = ws * (g1 - g2) - sp.pi
        children["B"] = junction_a(["g1", "g2", "t"], "rotational", [ws, -ws, -1])
        children["wrap"] = Tap("rotational", q0=wrap0 - 2 * sp.pi * sp.floor(wrap0 / (2 * sp.pi)))
        connections += [["G1.w", "B.g1"], ["G2.w", "B.g2"], ["B.t", "wrap.p"]]
        signals["beta"] = "wrap.q"
        reads |= {"g1": ("e1.gamma", 0), "g2": ("e2.gamma", 0)}
        q |= {"F2": Quantity(lambda V: V.e("R.T2.a")),
              "lr2": Quantity(local(wound[2])),
              "wrap": Quantity(lambda V: V.x("wrap.q"))}
    params = dict(params) | {"w": int(w) if w in (1, -1) else w}
    monitors = []
    if stored is not None:
        # the band paid out past the anchor: the wound-off length with the turning of the span
        monitors.append(Monitor(_S("stored") - wound[1], "drum_paid_out",
                                "paid out all the band stored on it: the band end would tear off its anchor",
                                stop=True, fix="store more band on the drum (parameter stored) or pay out less"))
    ph = _S("rphi")
    th, rr = outline if outline else ([2 * math.pi * k / _CIRCLE for k in range(_CIRCLE)], [_S("r")] * _CIRCLE)
    circle = [(xa + rk * sp.cos(ph + tk), ya + rk * sp.sin(ph + tk)) for tk, rk in zip(th, rr)]
    circle.append(circle[0])
    return Network(kind, children, connections, ports, params, q, signals=signals,
                   bundles={"a": "planar", "c": "planar"} | {f"e{k}": "band" for k in ends},
                   positions={"c.x": xa, "c.y": ya, "c.phi": ph if contact else pa}, reads=reads, monitors=monitors,
                   fixed=("a.x", "a.y", "a.phi") + tuple(f"e{k}.gamma" for k in ends),
                   sketch=[Sketch(circle, [""] * len(circle), style="line"),
                           Sketch([(xa, ya), circle[0]], ["", ""], style="line"),
                           Sketch([(xa, ya)], [""], style="point")])


_PLANAR_ROLLS = ("planar_roll", "planar_drum")


def span_roll_pairs(ctx, spans: tuple, rolls: tuple):
    """Each band connection of a span (kind in ``spans``) with a roll (kind in ``rolls``):
    ``(span, roll, k, j, problems)`` with the span's end k and the roll's port j ("1"|"2") and the
    problems every planar span shares (wrap sense s_k against the roll's w, p_k not joined to c)."""
    kinds, ports = ctx.flat.elements, ctx.flat.external_ports
    node_of = {p: k for k, node in enumerate(ctx.flat.nodes) for p in node.ports}
    for a, b, data in band_graph(ctx).edges(data=True):
        ends = dict(p.rsplit(".", 1) for p in data["ports"])
        if kinds.get(a) in spans and kinds.get(b) in rolls:
            span, roll = a, b
        elif kinds.get(b) in spans and kinds.get(a) in rolls:
            span, roll = b, a
        else:
            continue
        k, j = ends[span][-1], ends[roll][-1]            # the span's end 1|2, the roll's port 1|2
        w, sk = _value(ctx, roll, "w"), _value(ctx, span, f"s{k}")
        problems = []
        if None not in (w, sk) and sk != (w if j == "1" else -w):
            problems.append(f"s{k} = {sk:+g}, the roll's w = {w:+g} at its e{j} asks for {w if j == '1' else -w:+g}")
        centre, end = ports.get(f"{roll}.c.x"), ports.get(f"{span}.p{k}.x")
        if centre and end and node_of.get(centre, "c") != node_of.get(end, "e"):
            problems.append(f"{span}.p{k} is not joined to {roll}.c (the span pulls the roll through its centre "
                            "port: bearing load, pin friction, outputs Fx, Fy)")
        yield span, roll, k, j, problems


@register_check("planar_band_roll", "error",
                "a planar_band joined to a planar_roll or planar_drum must be given its radius and wrap sense "
                "(r1 = r, s1 = w at its e1, -w at its e2) and its p port must be joined to the roll's centre c")
def planar_band_roll(ctx):
    for span, roll, k, j, problems in span_roll_pairs(ctx, ("planar_band",), _PLANAR_ROLLS):
        r, rk = _value(ctx, roll, "r"), _value(ctx, span, f"r{k}")
        if None not in (r, rk) and abs(r - rk) > 1e-12 * max(r, 1e-300):
            problems.insert(0, f"r{k} = {rk:g} m, the roll's r = {r:g} m")
        if problems:
            yield Diagnostic("planar_band_roll", f"{span}.e{k} runs onto {roll}.e{j}, but " + "; ".join(problems),
                             elements=[span, roll],
                             fix=f"give {span} the roll's radius r{k} and wrap sense s{k} (w at e1, -w at e2) and "
                                 f"join {span}.p{k} with {roll}.c")
