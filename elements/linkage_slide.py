"""Planar linkages after VDI 2729 and Ebert (2015): the linear drive SAN, the link-point guide FGP
and the dyad DDS (a link and a slider on a guide).

Built from :func:`elements.linkage.link` like DAN and DDD (read ``elements/linkage.py`` first):

* a slider is a rigid body whose angle is its guide's angle (a position read of the anchor the guide
  is welded to: no state of its own) and which travels along the guide by ``x_G`` [m], the
  integral of the flow at its 1-D ``drive`` port (the relative speed along the guide [m/s]; the
  effort there is the tangential force on the slider [N], its reaction on the guide included:
  ``x_G`` is a relative coordinate);
* the guide's 1-D ``support`` port is held (flow 0): a linear actuator between ``support`` and
  ``drive`` acts on the relative travel, and its reaction on the guide is already in ``drive``;
* the link-point guide FGP is an arm welded to the anchor's plane (angle = anchor angle +
  ``phi_rel``, a read: no state);
* the DDS dyad's link angle ``phi_L`` and slider travel ``x_G`` are closure-bound states: their rates
  come from the joint P, their values from the position closure solved at every evaluation; the
  assembly mode ``K`` is used at t = 0 only (VDI 2729 start formula).

Conventions (Ebert, reference §5.2, §5.3, §5.5, with the printed errata corrected): the guide frame
has its origin at the anchor point and its x axis at the anchor angle ``phi_U``; the foot point is
``PS = P_anchor + x_G*e(phi_U)`` (Ebert prints ``-x_G cos`` in (B.10), (B.12), (B.99), (B.101));
the pin P of the slider sits at the offset ``v`` along ``n(phi_U) = (-sin, cos)``.  Units are SI.
Reference: ``docs/linkages.md``.
"""
from __future__ import annotations

import sympy as sp

from multipole import ClosedForm, Closure, Network, Param, Quantity, Se, Sf, Sketch, element, junction_b

from .linkage import DEAD_CENTRE, _PLANAR_DOC, _anchor, _body, _gravity, _S, _zero, check_mode, link


def _guide_angle(name: str, port: str) -> Param:
    """The guide's angle parameter: against the plane the anchor is joined to, as in Ebert's A.1
    (``phi_rel`` relative to the connection frame) and in SSD, SDS and DSD; against the frame when the
    anchor is not connected."""
    return Param(name, "rad", f"angle of the guide against the plane {port} is joined to (the frame when {port} "
                 "is not connected)", 0.0)


_cos, _sin = sp.cos, sp.sin


def _travel_momenta(m, speed, phi):
    """Initial momenta of a slider travelling at ``speed`` [m/s] along ``e(phi)`` on a guide at rest
    [N*s, N*s]; its rotation is its guide's (None: from the couplings at t = 0)."""
    return (m * speed * _cos(phi), m * speed * _sin(phi), None)


def _local(expr):
    """A quantity from an expression in the element's local names (parameters, signals, reads)."""
    return Quantity(lambda V: expr.xreplace({s: V.param(s.name) for s in expr.free_symbols}))


_SLIDER_PORTS = {"drive": "1-D translational port on the slider: travel rate x_G' along the guide [m/s], "
                          "tangential force on the slider [N] (its reaction on the guide included)",
                 "support": "1-D translational port on the guide, held (flow 0): the stator side of a linear "
                            "actuator between support and drive"}


def _slider_body(prefix: str = "") -> list:
    return [Param(f"xs{prefix}", "m", "centre of mass of the slider from the foot point PS, along the guide", 0.0),
            Param(f"ys{prefix}", "m", "centre of mass of the slider from PS, across the guide", 0.0),
            Param(f"m{prefix}", "kg", "mass of the slider (0: massless)", 1.0, nonnegative=True),
            Param(f"J{prefix}", "kg*m^2", "moment of inertia of the slider about its centre of mass", 0.1,
                  nonnegative=True)]


def _nz(name: str, value):
    """The parameter's symbol, or 0 where its value is the number 0 (the body part is left out)."""
    return 0 if _zero(value) else _S(name)


@element("SAN", "VDI 2729 linear drive: a slider on a straight guide welded to the anchor a (angle phi_U), "
         "travelling x_G along it; the point P at the offset v from the slide line is the output b",
         {"a": f"anchor at P1, the rigid guide ({_PLANAR_DOC}); frame-fixed at (x1, y1, phi1) if not connected",
          "b": f"output on the slider at P, angle phi_U ({_PLANAR_DOC})", **_SLIDER_PORTS},
         [Param("v", "m", "offset of P from the slide line, along the guide's y axis", 0.0),
          Param("x0", "m", "initial slider travel x_G (P1 to the foot point PS along the guide)", 0.0),
          Param("v0", "m/s", "initial travel rate x_G'", 0.0)]
         + _slider_body() + _gravity() + _anchor("x1", "y1") + [_guide_angle("phi1", "a")],
         {"x": "m: slider travel x_G (continuous)", "v": "m/s: travel rate x_G'", "force": "N: force at the drive port",
          "xP": "m: x of the point P", "yP": "m: y of the point P"})
def SAN(v, x0, v0, xs, ys, m, J, gx, gy, x1, y1, phi1):
    """Linear drive (VDI 2729 SAN) [m, m/s, kg, kg*m^2, rad]."""
    phiU, xG, xa, ya, V_ = _S("pa") + _S("phi1"), _S("xG"), _S("xa"), _S("ya"), _S("v")
    slider = link([(0, V_)], _nz("m", m), _nz("J", J), _S("xs"), _S("ys"), None, ("a", "out"),
                  _travel_momenta(_S("m"), _S("v0"), phiU), angle=phiU, slide=_S("x0"))
    xP = xa + xG * _cos(phiU) - V_ * _sin(phiU)
    yP = ya + xG * _sin(phiU) + V_ * _cos(phiU)
    ports = {"a.x": "S.A.x", "a.y": "S.A.y", "a.phi": "S.w.a", "b.x": "S.P1.x", "b.y": "S.P1.y",
             "b.phi": "S.w.out", "drive": "S.s", "support": "G.p"}
    params = {"v": v, "x0": x0, "v0": v0, "xs": xs, "ys": ys, "m": m, "J": J, "gx": gx, "gy": gy,
              "x1": x1, "y1": y1, "phi1": phi1}
    q = {"x": _local(xG), "v": Quantity(lambda V: V.f("S.s")), "force": Quantity(lambda V: V.e("S.s")),
         "xP": _local(xP), "yP": _local(yP)}
    return Network("SAN", {"S": slider, "G": Sf(0, "translational")}, [], ports, params, q,
                   signals={"xG": "S.K.q4"}, bundles={"a": "planar", "b": "planar"},
                   positions={"b.x": xP, "b.y": yP, "b.phi": phiU},
                   reads={"xa": ("a.x", _S("x1")), "ya": ("a.y", _S("y1")), "pa": ("a.phi", 0)},
                   fixed=("a.x", "a.y", "a.phi"),
                   sketch=[Sketch([(xa, ya), (xa + xG * _cos(phiU), ya + xG * _sin(phiU))], ["P1", ""], "slide"),
                           Sketch([(xa + xG * _cos(phiU), ya + xG * _sin(phiU)), (xP, yP)], ["", "P"])])


@element("FGP", "VDI 2729 guidance of a link point: a rigid arm of length l welded to the plane of the anchor a "
         "at the angle phi_rel to it; its end P is the output b (a coupler point: FGP on DDD.b1)",
         {"a": f"anchor at P1, welded to the plane it is joined to ({_PLANAR_DOC}); frame-fixed at (x1, y1, phi1) "
               "if not connected",
          "b": f"output at the arm's end P, angle phi_a + phi_rel ({_PLANAR_DOC})"},
         [Param("l", "m", "arm length P1-P", 1.0, positive=True),
          Param("phi_rel", "rad", "angle of the arm relative to the anchor's plane", 0.0)]
         + [Param("xs", "m", "centre of mass along the arm", None),
            Param("ys", "m", "centre of mass across the arm", 0.0),
            Param("m", "kg", "mass of the arm (0: massless)", 0.0, nonnegative=True),
            Param("J", "kg*m^2", "moment of inertia about the centre of mass", 0.0, nonnegative=True)]
         + _gravity() + _anchor("x1", "y1", "phi1"),
         {"phi": "rad: arm angle", "x": "m: x of the guided point P", "y": "m: y of the guided point P"})
def FGP(l, phi_rel, xs, ys, m, J, gx, gy, x1, y1, phi1):
    """Link-point guide (VDI 2729 FGP) [m, rad, kg, kg*m^2]."""
    xs = l / 2 if xs is None else xs
    xa, ya, phi = _S("xa"), _S("ya"), _S("phiA") + _S("phi_rel")
    arm = link([(_S("l"), 0)], _nz("m", m), _nz("J", J), _S("xs"), _S("ys"), None, ("a", "out"), angle=phi)
    xP, yP = xa + _S("l") * _cos(phi), ya + _S("l") * _sin(phi)
    ports = {"a.x": "L.A.x", "a.y": "L.A.y", "a.phi": "L.w.a", "b.x": "L.P1.x", "b.y": "L.P1.y", "b.phi": "L.w.out"}
    params = {"l": l, "phi_rel": phi_rel, "xs": xs, "ys": ys, "m": m, "J": J, "gx": gx, "gy": gy,
              "x1": x1, "y1": y1, "phi1": phi1}
    return Network("FGP", {"L": arm}, [], ports, params, {"phi": _local(phi), "x": _local(xP), "y": _local(yP)},
                   bundles={"a": "planar", "b": "planar"}, positions={"b.x": xP, "b.y": yP, "b.phi": phi},
                   reads={"xa": ("a.x", _S("x1")), "ya": ("a.y", _S("y1")), "phiA": ("a.phi", _S("phi1"))},
                   fixed=("a.x", "a.y", "a.phi"), sketch=[Sketch([(xa, ya), (xP, yP)], ["", "P"], trace=True)])


def dds_start(K, l, v, xa1, ya1, xa2, ya2, phiU):
    """VDI 2729 start position of DDS (Ebert (B.71)-(B.86), compact form): the travel x_G(0) [m] and the
    link angle phi_L(0) [rad] (from P towards P1).  With u = e(phi_U), n = n(phi_U), d = P2 - P1, the
    pin P = P2 + x_G*u + v*n is at the distance l from P1:
    x_G^2 + 2 (u.d) x_G + |d|^2 + v^2 + 2 v (n.d) - l^2 = 0; K = +1 takes the larger root."""
    ux, uy = _cos(phiU), _sin(phiU)
    dx, dy = xa2 - xa1, ya2 - ya1
    ud, nd = ux * dx + uy * dy, -uy * dx + ux * dy
    xG = -ud + K * sp.sqrt(ud ** 2 - (dx ** 2 + dy ** 2 + v ** 2 + 2 * v * nd - l ** 2))
    xP, yP = xa2 + xG * ux - v * uy, ya2 + xG * uy + v * ux
    return xG, sp.atan2(ya1 - yP, xa1 - xP)


def dds_branch(K, l, v, xa1, ya1, xa2, ya2, phiU):
    """The DDS closure's solution in assembly mode ``K`` (:func:`dds_start` at every evaluation): the
    link's direction from P towards P1 as (cos phi_L, sin phi_L), and the travel x_G [m]."""
    xG, _angle = dds_start(K, l, v, xa1, ya1, xa2, ya2, phiU)
    xP, yP = xa2 + xG * _cos(phiU) - v * _sin(phiU), ya2 + xG * _sin(phiU) + v * _cos(phiU)
    return [((xa1 - xP) / l, (ya1 - yP) / l), xG]


@element("DDS", "VDI 2729 dyad with a prismatic joint as connection: a link hinged at the anchor P1 (pin) and "
         "at P to a slider on a guide welded to the anchor P2 (angle phi_U); P is at the offset v from the "
         "slide line, the foot point PS at the travel x_G from P2",
         {"a1": f"anchor at P1, a pin ({_PLANAR_DOC}; transmits no torque); frame-fixed at (x1, y1) if not "
                "connected",
          "a2": f"anchor at P2, the rigid guide ({_PLANAR_DOC}); frame-fixed at (x2, y2, phi2) if not connected",
          "b1": f"output on the plane of the link at P1, angle phi_L ({_PLANAR_DOC})",
          "b2": f"output on the slider at the foot point PS, angle phi_U ({_PLANAR_DOC})", **_SLIDER_PORTS},
         [Param("l", "m", "length of the link, P-P1", 1.0, positive=True),
          Param("v", "m", "offset of the pin P from the slide line, along the guide's y axis", 0.1),
          Param("K", "-", "assembly mode at t = 0: +1 the larger slider travel, -1 the smaller", 1.0)]
         + _body("mL", "JL", "xsL", "ysL") + _slider_body("S") + _gravity()
         + _anchor("x1", "y1") + _anchor("x2", "y2") + [_guide_angle("phi2", "a2")],
         {"phi": "rad: link angle phi_L (from P towards P1, continuous)", "omega": "rad/s: link angular velocity",
          "x": "m: slider travel x_G", "v": "m/s: travel rate x_G'", "force": "N: force at the drive port",
          "xP": "m: x of the pin P", "yP": "m: y of the pin P",
          "transmission": "-: cos(phi_L - phi_U), 0 at the dead centres (link across the guide)"})
def DDS(l, v, K, xsL, ysL, mL, JL, xsS, ysS, mS, JS, gx, gy, x1, y1, x2, y2, phi2):
    """Dyad with a prismatic joint as connection (VDI 2729 DDS) [m, rad, kg, kg*m^2].

    ``xsL``, ``ysL``: centre of mass of the link in its frame (origin P, x axis towards P1; default l/2)."""
    check_mode("DDS", K, "K = +1 takes the larger slider travel (the joint P on the side the guide's x axis "
               "points to, seen from the foot of the perpendicular from P1), K = -1 the smaller")
    xsL = l / 2 if xsL is None else xsL
    xa1, ya1, xa2, ya2 = (_S(n) for n in ("xa1", "ya1", "xa2", "ya2"))
    phiU = _S("pa2") + _S("phi2")           # the guide against the plane of its anchor (as SSD, SDS, DSD)
    L_, V_, phiL, xG = _S("l"), _S("v"), _S("phiL"), _S("xG")
    xG0, phiL0 = dds_start(_S("K"), L_, V_, xa1, ya1, xa2, ya2, phiU)
    # the link seen from P1 (its reference A): P at (-l, 0), the centre of mass at (xsL - l, ysL)
    link_ = link([(-L_, 0)], _nz("mL", mL), _nz("JL", JL), _S("xsL") - L_, _S("ysL"), phiL0, ("out",))
    slider = link([(0, V_), (0, 0)], _nz("mS", mS), _nz("JS", JS), _S("xsS"), _S("ysS"), None, ("a", "out"),
                  angle=phiU, slide=xG0)
    children = {"L": link_, "S": slider, "pin": Se(0, "rotational"), "G": Sf(0, "translational"),
                "x1": junction_b(["a", "k", "o"], "translational"), "y1": junction_b(["a", "k", "o"], "translational")}
    connections = [["L.P1.x", "S.P1.x"], ["L.P1.y", "S.P1.y"], ["x1.k", "L.A.x"], ["y1.k", "L.A.y"]]
    ports = {"a1.x": "x1.a", "a1.y": "y1.a", "a1.phi": "pin.p", "a2.x": "S.A.x", "a2.y": "S.A.y", "a2.phi": "S.w.a",
             "b1.x": "x1.o", "b1.y": "y1.o", "b1.phi": "L.w.out", "b2.x": "S.P2.x", "b2.y": "S.P2.y",
             "b2.phi": "S.w.out", "drive": "S.s", "support": "G.p"}
    params = {"l": l, "v": v, "K": K, "xsL": xsL, "ysL": ysL, "mL": mL, "JL": JL, "xsS": xsS, "ysS": ysS,
              "mS": mS, "JS": JS, "gx": gx, "gy": gy, "x1": x1, "y1": y1, "x2": x2, "y2": y2, "phi2": phi2}
    xP, yP = xa1 - L_ * _cos(phiL), ya1 - L_ * _sin(phiL)
    # the pin's line P2 + v n + s u is at the distance |n.(P1 - P2) + v| from P1: the link reaches it if <= l
    reach = L_ - sp.Abs(-_sin(phiU) * (xa1 - xa2) + _cos(phiU) * (ya1 - ya2) - V_)
    closure = Closure(["L.K.q3", "S.K.q4"],
                      [xP - (xa2 + xG * _cos(phiU) - V_ * _sin(phiU)), yP - (ya2 + xG * _sin(phiU) + V_ * _cos(phiU))],
                      "the pin P reached from P1 along the link and from P2 along the guide",
                      conditions=[(reach, "the link does not reach the line of the pin: its distance from P1 "
                                   "exceeds l", "m")],
                      guard=(_cos(phiL - phiU), DEAD_CENTRE, "cos(phi_L - phi_U)"),
                      closed_form=ClosedForm([dds_branch(K_, L_, V_, xa1, ya1, xa2, ya2, phiU) for K_ in (1, -1)],
                                             # the integrated travel beyond the foot of the perpendicular from P1
                                             xG + _cos(phiU) * (xa2 - xa1) + _sin(phiU) * (ya2 - ya1)))
    q = {"phi": _local(phiL), "omega": Quantity(lambda V: V.f("L.w.out")), "x": _local(xG),
         "v": Quantity(lambda V: V.f("S.s")), "force": Quantity(lambda V: V.e("S.s")),
         "xP": _local(xP), "yP": _local(yP), "transmission": _local(_cos(phiL - phiU))}
    return Network("DDS", children, connections, ports, params, q, signals={"phiL": "L.K.q3", "xG": "S.K.q4"},
                   bundles={"a1": "planar", "a2": "planar", "b1": "planar", "b2": "planar"},
                   positions={"b1.x": xa1, "b1.y": ya1, "b1.phi": phiL,
                              "b2.x": xa2 + xG * _cos(phiU), "b2.y": ya2 + xG * _sin(phiU), "b2.phi": phiU},
                   reads={"xa1": ("a1.x", _S("x1")), "ya1": ("a1.y", _S("y1")),
                          "xa2": ("a2.x", _S("x2")), "ya2": ("a2.y", _S("y2")), "pa2": ("a2.phi", 0)},
                   fixed=("a1.x", "a1.y", "a1.phi", "a2.x", "a2.y", "a2.phi"), closures=[closure],
                   sketch=[Sketch([(xa1, ya1), (xP, yP)], ["", "P"]),
                           Sketch([(xa2, ya2), (xa2 + xG * _cos(phiU), ya2 + xG * _sin(phiU))], ["P2", ""], "slide"),
                           Sketch([(xa2 + xG * _cos(phiU), ya2 + xG * _sin(phiU)), (xP, yP)], ["", ""])])
