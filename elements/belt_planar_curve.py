"""Planar curve rolls (Ebert 2015, 4.4.5 on planar ports): convex contours whose tangency comes from the geometry.

``planar_curve_roll`` / ``planar_curve_drum`` are the rolls of :mod:`elements.belt_planar` with the
convex contour of :mod:`elements.belt_contour` (a table read by :func:`~elements.belt_contour.as_contour`,
its support function p(nu) as the trigonometric series of :meth:`Contour.series`).
``planar_curve_band`` is ``planar_band``'s span (:func:`elements.belt_planar.planar_span`) whose ends
are contours: at end i the signed offset of the tangent from the centre is the support function at
the contact normal instead of a constant radius,

    nu1 = gamma - s1 pi/2 - phi1,   nu2 = gamma + s2 pi/2 - phi2      (roll frames; phi_i: the contours' angles)
    n . (C2 - C1) + s1 p1(nu1) + s2 p2(nu2) = 0                      (the closure on gamma)
    l_B = t . (C2 - C1) - s1 p1'(nu1) - s2 p2'(nu2)                  (between the contact points)
    delta' = t . (v_C2 - v_C1) - s1 p1 phi1' - s2 p2 phi2'           (the stretch rate)

so the roll is a transformer of ratio s p(nu) (torque s p F), and the band wound off it is
s (S(nu(0)) - S(nu)) (arc length S of the contour).  A circle is p = r, p' = 0: planar_band.  The
wrap senses s_i are the half-plane choice (made once, by the user); gamma is never wrapped.

The span learns its ends' contours from its own parameters ``contour1``/``contour2`` (the same table
as the roll's, no contour: a circle of radius ``r1``/``r2``) and the contours' angles from its planar
ports ``p1.phi``/``p2.phi``, where a curve roll's centre port ``c`` hands on the roll's angle.  The
check ``planar_curve_band_roll`` refuses a span whose table, tolerance, wrap sense or centre
disagrees with its roll.  Derivation: ``docs/belts.md``, "Planar curve rolls".  Units: SI (m, rad,
N, N*s, kg, kg*m^2).
"""
from __future__ import annotations

import math
import os

import sympy as sp

from multipole import Diagnostic, ModelError, Param, Quantity, element, register_check

from .belt import _BAND
from .belt_checks import _value
from .belt_contour import _CONTOUR_DOC, _sym_series, as_contour
from .belt_planar import (_BEARING, _PLANAR, _PLANAR_ROLLS, _ROLL_QUANTITIES, SpanEnd, _planar_roll, _roll_params,
                          _sense, planar_span, span_quantities, span_roll_pairs)

_S = sp.Symbol
_HALF = sp.Float(math.pi / 2)
#: points of the polygon that draws a contour
_OUTLINE = 48


def _series(kind: str, contour, arc, tol):
    """The contour and its support function's series ``(contour, p(u), u)`` as a sympy expression of
    the symbol u [rad] (terms below tol/(4 K) [m] left out, as curve_roll does)."""
    c = as_contour(contour, bool(arc))
    try:
        tol = float(tol)
    except TypeError:
        raise ModelError("bad_value", f"{kind}: tol = {tol} m must be a number", "e.g. 1e-9") from None
    a, b = c.series(tol)
    u = _S("u")
    return c, (a, b, tol / (4 * len(a))), u


def _params(extra: list) -> list:
    return [Param("contour", "", _CONTOUR_DOC, kind="file"),
            Param("arc", "", "the table is an engaged arc (a synthesis result): completed to a closed convex "
                  "contour by a closing part with C4 joins", False, "bool")] + _roll_params(
        [Param("tol", "m", "largest error of the lever arm in the elements' smooth contour form (as curve_roll)",
               1e-9, positive=True)] + extra)[1:]


_QTY = _ROLL_QUANTITIES | {
    "lr1": "m: band wound off into the span at e1, w (S(nu1(0)) - S(nu1)) (S: the contour's arc length)",
    "h1": "m: lever arm of the band force at e1 (the support function at the contact normal)"}


def _curve_roll(kind: str, sides: int, contour, arc, tol, params: dict, mu_c=None, stored=None):
    c, (a, b, drop), _u = _series(kind, contour, arc, tol)
    w = params["w"]
    if w not in (1, -1, 1.0, -1.0):
        raise ModelError("bad_winding", f"{kind}: w = {w!r} must be +1 or -1",
                         "+1: a positive rotation pays band out at e1 (and winds it in at e2)")
    ws = int(w)

    def normal(k, angle, at):
        # the contact normal at port k in the roll frame: the span leaves along gamma_k with the
        # wrap sense s_k = w (e1), -w (e2), so the outward normal has the angle gamma_k - s_k pi/2
        sk = ws if k == 1 else -ws
        return at - sk * _HALF - angle

    def contact(k):
        g, g0 = _S(f"g{k}"), _S(f"g{k}") - _S(f"dg{k}")
        lever = _sym_series(a, b, normal(k, _S("phi"), g), False, drop)
        wound = _sym_series(a, b, normal(k, _S("phi0"), g0), True, drop) \
            - _sym_series(a, b, normal(k, _S("phi"), g), True, drop)
        return lever, wound

    theta = [c.theta[0] + 2 * math.pi * k / _OUTLINE for k in range(_OUTLINE)]
    outline = (theta, [float(v) for v in c.radius(theta)])
    net = _planar_roll(kind, sides, params | {"tol": tol}, mu_c=mu_c, stored=stored, contact=contact,
                       outline=outline)
    for k in range(1, sides + 1):
        lever = contact(k)[0]
        net.quantities[f"h{k}"] = Quantity(lambda V, e=lever: e.xreplace(
            {s: V.x("R.tap.q") if s.name == "phi" else V.param(s.name) for s in e.free_symbols}))
    net.contour, net.table, net.arc = c, contour, bool(arc)
    return net


@element("planar_curve_roll", "band roll with a convex curve contour on a planar bearing (Ebert 4.4.5 on planar "
         "ports): the contact normal, lever arm and wound length follow from the span's inclination read at "
         "e1/e2; no-slip, inertia J; the spans read the contour's pose at c",
         _BEARING | {"c": f"centre seen by the spans ({_PLANAR}): x, y of the axis and phi, the roll's own angle "
                          "(the spans read the contour's pose there; no torque)",
                     "e1": f"band port 1 ({_BAND}): a planar_curve_band with wrap sense s = w there",
                     "e2": f"band port 2 ({_BAND}): a planar_curve_band with wrap sense s = -w there"},
         _params([Param("mu_c", "-", "contact friction for the capstan monitor (None: no monitor)", None)]),
         _QTY | {"F2": "N: band tension at e2",
                 "lr2": "m: band wound off at e2, -w (S(nu2(0)) - S(nu2))",
                 "h2": "m: lever arm of the band force at e2",
                 "wrap": "rad: wrap angle between the contact normals where the band runs on and off (in "
                         "(0, 2 pi) at t = 0, continuous)"})
def planar_curve_roll(contour, arc, J, phi0, omega0, w, m, gx, gy, mu, r_pin, tol, mu_c, x1, y1):
    """Curve roll on a planar bearing [contour in m, J in kg*m^2, angles in rad, m in kg]."""
    params = {"J": J, "phi0": phi0, "omega0": omega0, "w": w, "m": m, "gx": gx, "gy": gy, "mu": mu,
              "r_pin": r_pin, "x1": x1, "y1": y1} | ({} if mu_c is None else {"mu_c": mu_c})
    return _curve_roll("planar_curve_roll", 2, contour, arc, tol, params, mu_c=mu_c)


@element("planar_curve_drum", "band drum with a convex curve contour on a planar bearing (a band cam on a "
         "moving axis): planar_curve_roll with one band end fixed on it",
         _BEARING | {"e1": f"band port ({_BAND}): a planar_curve_band with wrap sense s = w there"},
         _params([Param("stored", "m", "band stored on the drum at t = 0 (None: no monitor): paying out more "
                        "stops the run (drum_paid_out)", None)]),
         _QTY)
def planar_curve_drum(contour, arc, J, phi0, omega0, w, m, gx, gy, mu, r_pin, tol, stored, x1, y1):
    """Curve drum on a planar bearing [contour in m, J in kg*m^2, angles in rad, m in kg]."""
    params = {"J": J, "phi0": phi0, "omega0": omega0, "w": w, "m": m, "gx": gx, "gy": gy, "mu": mu,
              "r_pin": r_pin, "x1": x1, "y1": y1} | ({} if stored is None else {"stored": stored})
    return _curve_roll("planar_curve_drum", 1, contour, arc, tol, params, stored=stored)


def _end(k: int, contour, tol, sense: int) -> SpanEnd:
    """End k of a curve span: the contour's series (the roll's own: same table, same tol), its angle
    read at p<k>.phi; no contour: the circle of radius r<k> (planar_band's end)."""
    if contour is None:
        return SpanEnd(lambda nu: _S(f"r{k}"), lambda nu: sp.Integer(0), sense, 0, _S(f"r{k}"))
    _c, (a, b, drop), u = _series("planar_curve_band", contour, False, tol)
    p = _sym_series(a, b, u, False, drop)
    dp = p.diff(u)
    return SpanEnd(lambda nu: p.xreplace({u: nu}), lambda nu: dp.xreplace({u: nu}), sense, _S(f"a{k}"),
                   sp.Float(a[0]), refine=2)


@element("planar_curve_band", "elastic band span between two convex contours (or circles) on planar ports: the "
         "common tangent of the contours posed at p1, p2 (centre and angle, a planar_curve_roll's c) with wrap "
         "senses s1, s2; tension-only Kelvin-Voigt band, stiffness EA/l_x",
         {"e1": f"band end at contour 1 ({_BAND}; gamma: the span's inclination); held if not connected",
          "e2": f"band end at contour 2 ({_BAND}; gamma: the inclination + pi); held if not connected",
          "p1": f"pose of contour 1 ({_PLANAR}: its centre and angle; the span pulls the centre, no torque): a "
                "planar_curve_roll's c; frame-fixed at (x1, y1, phi1) if not connected",
          "p2": f"pose of contour 2 ({_PLANAR}); frame-fixed at (x2, y2, phi2) if not connected"},
         [Param("EA", "N", "axial stiffness times length (k = EA/l_x)", 1e5, positive=True),
          Param("cd", "N*s", "axial damping times length (b = cd/l_x)", 0.0, nonnegative=True),
          Param("F0", "N", "tension at t = 0 (sets the stretch at t = 0: F0 l_B(0)/(EA + F0); with contours "
                "l_B(0) comes from the start value of gamma, see docs/belts.md)", 0.0, nonnegative=True),
          Param("contour1", "", "contour at end 1: the table of the roll there (" + _CONTOUR_DOC + "); None: "
                "the circle of radius r1", None, kind="file"),
          Param("contour2", "", "contour at end 2 (as contour1); None: the circle of radius r2", None, kind="file"),
          Param("r1", "m", "radius of circle 1 when contour1 is None (0: a point)", 0.0, nonnegative=True),
          Param("s1", "-", "wrap sense at end 1: +1 if a counter-clockwise rotation of roll 1 pays band out "
                "into the span (the roll's w at e1, -w at e2)", 1.0),
          Param("r2", "m", "radius of circle 2 when contour2 is None", 0.0, nonnegative=True),
          Param("s2", "-", "wrap sense at end 2 (as s1)", 1.0),
          Param("tol", "m", "the series tolerance of the rolls' contours (the same as theirs)", 1e-9, positive=True),
          Param("x1", "m", "frame position x of centre 1 when p1 is not connected", 0.0),
          Param("y1", "m", "frame position y of centre 1 when p1 is not connected", 0.0),
          Param("phi1", "rad", "angle of contour 1 when p1 is not connected", 0.0),
          Param("x2", "m", "frame position x of centre 2 when p2 is not connected", 1.0),
          Param("y2", "m", "frame position y of centre 2 when p2 is not connected", 0.0),
          Param("phi2", "rad", "angle of contour 2 when p2 is not connected", 0.0)],
         span_quantities("contact point", "contour"))
def planar_curve_band(EA, cd, F0, contour1, contour2, r1, s1, r2, s2, tol, x1, y1, phi1, x2, y2, phi2):
    """Planar elastic span between contours [EA, F0 in N, cd in N*s, lengths in m, angles in rad]."""
    s1, s2 = _sense("planar_curve_band", "s1", s1), _sense("planar_curve_band", "s2", s2)
    ends = (_end(1, contour1, tol, s1), _end(2, contour2, tol, s2))
    params = {"EA": EA, "cd": cd, "F0": F0, "r1": r1, "s1": s1, "r2": r2, "s2": s2, "tol": tol,
              "x1": x1, "y1": y1, "phi1": phi1, "x2": x2, "y2": y2, "phi2": phi2}
    reads = {f"a{k}": (f"p{k}.phi", _S(f"phi{k}")) for k, c in ((1, contour1), (2, contour2)) if c is not None}
    net = planar_span("planar_curve_band", ends, params, reads=reads)
    net.tables = (contour1, contour2)
    return net


_CURVE_ROLLS = ("planar_curve_roll", "planar_curve_drum")


def _same_file(a, b) -> bool:
    try:
        return os.path.realpath(os.fspath(a)) == os.path.realpath(os.fspath(b))
    except TypeError:
        return a is b


@register_check("planar_curve_band_roll", "error",
                "a planar_curve_band joined to a planar_curve_roll/drum must name the roll's contour table and "
                "tolerance at that end (contour1 = contour, tol), its wrap sense (s1 = w at the roll's e1, -w at "
                "e2), and its p port must be joined to the roll's c; at a planar_roll it needs no contour and the "
                "roll's radius; a planar_band cannot end on a curve roll")
def planar_curve_band_roll(ctx):
    children = ctx.scene.network.children if ctx.scene is not None else {}
    pairs = list(span_roll_pairs(ctx, ("planar_curve_band",), _CURVE_ROLLS + _PLANAR_ROLLS)) + \
        [(s, r, k, j, [f"{s} is a planar_band, whose ends are circles: {r} has a contour"])
         for s, r, k, j, _p in span_roll_pairs(ctx, ("planar_band",), _CURVE_ROLLS)]
    for span, roll, k, j, problems in pairs:
        roll_net, span_net = children.get(roll), children.get(span)
        if ctx.flat.elements.get(span) == "planar_curve_band" and roll_net is not None and span_net is not None:
            mine = span_net.tables[int(k) - 1]
            if ctx.flat.elements.get(roll) in _CURVE_ROLLS:
                if mine is None or not _same_file(mine, roll_net.table):
                    problems.append(f"contour{k} = {mine}, the roll's contour = {roll_net.table}")
                elif roll_net.arc:
                    problems.append(f"{roll} reads its table as an engaged arc (arc: true), which a span cannot "
                                    "follow")
                tr, tk = _value(ctx, roll, "tol"), _value(ctx, span, "tol")
                if None not in (tr, tk) and tr != tk:
                    problems.append(f"tol = {tk:g} m, the roll's tol = {tr:g} m")
            else:
                r, rk = _value(ctx, roll, "r"), _value(ctx, span, f"r{k}")
                if mine is not None:
                    problems.append(f"contour{k} = {mine}, but {roll} is a circle (leave contour{k} out)")
                elif None not in (r, rk) and abs(r - rk) > 1e-12 * max(r, 1e-300):
                    problems.append(f"r{k} = {rk:g} m, the roll's r = {r:g} m")
        if problems:
            yield Diagnostic("planar_curve_band_roll", f"{span}.e{k} runs onto {roll}.e{j}, but " + "; ".join(problems),
                             elements=[span, roll],
                             fix=f"give {span} the roll's contour table and tol (or radius) as contour{k} (r{k}) and "
                                 f"wrap sense s{k} (w at e1, -w at e2), and join {span}.p{k} with {roll}.c")
