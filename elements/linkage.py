"""Planar linkages after VDI 2729 and Ebert (2015): drives, dyads and the link-point guide.

Every module is a multipole of kernel primitives joined at ``planar`` bundle ports (x, y [m] and
the angle phi [rad] of a point and its plane; loads Fx, Fy [N] and T [N*m]):

* a rigid link is a modulated multiport transformer (:class:`multipole.MTF`) from the velocity of
  its reference point and its angular velocity to the velocities of its centre of mass and its
  joint points, modulated by the link angle (the transformer's own integrated displacement);
  its transpose carries the loads back: the kinetostatics of Ebert's body equilibria comes out of
  the transformer, with no force equation written by hand;
* the mass (x and y) and the moment of inertia about the centre of mass are inertias on the
  transformer's centre-of-mass ports, gravity an effort source ``m*g`` beside them;
* a revolute joint is a node of the two links' joint-point velocities (common velocity, forces sum
  to zero), a pin anchor a torque-free port;
* a dyad's two link angles are closure-bound states (:class:`multipole.Closure`): their rates come
  from the joint nodes (the kernel's algebraic loop), their values from the position closure,
  solved at every evaluation from the integrated values, so the closure never drifts and the
  assembly mode is the branch the integration follows.  The assembly mode ``K`` is used at t = 0
  only (VDI 2729's start formulas).

Positions travel through the bundle ports: a module provides the pose of its output ports and reads
the pose of whatever its anchors are joined to (the frame pose it is given if the anchor is not
connected: an unconnected anchor is fixed to the frame).  Units are SI: m, rad, kg, kg*m^2, m/s^2.
Reference: ``docs/linkages.md``.
"""
from __future__ import annotations

import networkx as nx
import sympy as sp

from multipole import (MTF, ClosedForm, Closure, Diagnostic, I, Network, Param, Quantity, Se, Sketch, element, junction_b,
                       position_graph, register_check)

_cos, _sin = sp.cos, sp.sin


def _S(name: str) -> sp.Symbol:
    return sp.Symbol(name)


def _gravity() -> list:
    return [Param("gx", "m/s^2", "gravity, x component (set it from a scene parameter to share it)", 0.0),
            Param("gy", "m/s^2", "gravity, y component", -9.81)]


def _body(mass: str, inertia: str, xs: str, ys: str) -> list:
    return [Param(xs, "m", "centre of mass along the link (body x axis)", None),
            Param(ys, "m", "centre of mass across the link (body y axis)", 0.0),
            Param(mass, "kg", "mass of the link (0: massless)", 1.0, nonnegative=True),
            Param(inertia, "kg*m^2", "moment of inertia about the centre of mass", 0.1, nonnegative=True)]


def _anchor(x: str, y: str, phi: str | None = None) -> list:
    out = [Param(x, "m", "frame position x of the anchor when it is not connected", 0.0),
           Param(y, "m", "frame position y of the anchor when it is not connected", 0.0)]
    if phi:
        out.append(Param(phi, "rad", "frame angle of the anchor when it is not connected", 0.0))
    return out


def _zero(value) -> bool:
    return isinstance(value, (int, float, sp.Number)) and float(value) == 0.0   # sympy: Float(0.0) != 0


def link(points: list, m, J, xs, ys, phi0, omega_ports=(), p0=(None, None, None), angle=None, slide=None) -> Network:
    """A rigid link turning about its reference point A at the angle ``phi`` (the state ``K.q3``).

    ``points``: body-frame offsets ``(rx, ry)`` [m] of the joint points P1, P2, … from A (local
    names or numbers).  External ports: ``A.x``, ``A.y`` (the reference point: the link's velocity
    there in, the force on the link there out), ``P<k>.x``, ``P<k>.y`` (the joint points),
    ``w.<name>`` for each name in ``omega_ports`` (all at the link's angular velocity [rad/s]).
    ``m`` [kg] and ``J`` [kg*m^2] (about the centre of mass at ``(xs, ys)`` [m] in the body frame)
    are left out where they are the number 0; gravity ``(gx, gy)`` [m/s^2] acts on ``m``.
    ``p0``: initial momenta of the x, y and rotational inertias [N*s, N*s, N*m*s]; None (the default)
    where they follow from the mechanism's couplings at t = 0 (a dependent link).
    ``angle``: an expression in local names (a position read) used as the link angle instead of the
    link's own integrated angle: a body welded to a neighbour's plane (no ``phi`` signal then).
    ``slide``: initial travel [m] of a slider: the body then moves along its x axis by the travel
    ``s`` (state ``K.q4``, signal ``s``, rate and tangential force at the port ``s`` [m/s, N]), and
    every offset (points, centre of mass) is measured from the foot point A + s*e(angle).
    """
    q, s = (_S("q3") if angle is None else sp.sympify(angle)), (0 if slide is None else _S("q4"))
    rows = []
    for rx, ry in [(xs, ys)] + list(points):
        rx, ry = sp.sympify(rx) + s, sp.sympify(ry)
        rows.append([1, 0, -(rx * _sin(q) + ry * _cos(q))] + ([] if slide is None else [_cos(q)]))
        rows.append([0, 1, rx * _cos(q) - ry * _sin(q)] + ([] if slide is None else [_sin(q)]))
    b_doms = ["translational", "translational", "rotational"] + ([] if slide is None else ["translational"])
    children = {"K": MTF(rows, ["translational"] * len(rows), b_doms,
                         q0=[0, 0, 0 if phi0 is None else phi0] + ([] if slide is None else [slide])),
                "W": junction_b(["k", "J"] + list(omega_ports), "rotational")}
    connections = [["K.b3", "W.k"]]
    if not _zero(m):
        for axis, k, g, mom in (("x", 1, "gx", p0[0]), ("y", 2, "gy", p0[1])):
            children[f"m{axis}"] = I(J=sp.sympify(m), dom="translational", p0=mom)
            children[f"g{axis}"] = Se(sp.sympify(m) * _S(g), "translational")
            connections.append([f"K.a{k}", f"m{axis}.p", f"g{axis}.p"])
    if not _zero(J):
        children["J"] = I(J=sp.sympify(J), dom="rotational", p0=p0[2])
        connections.append(["W.J", "J.p"])
    else:
        children["J"] = Se(0, "rotational")
        connections.append(["W.J", "J.p"])
    ports = {"A.x": "K.b1", "A.y": "K.b2"}
    for k in range(len(points)):
        ports[f"P{k + 1}.x"] = f"K.a{2 * k + 3}"
        ports[f"P{k + 1}.y"] = f"K.a{2 * k + 4}"
    ports.update({f"w.{n}": f"W.{n}" for n in omega_ports})
    if slide is not None:
        ports["s"] = "K.b4"
    signals = ({} if angle is not None else {"phi": "K.q3"}) | ({} if slide is None else {"s": "K.q4"})
    return Network("link", children, connections, ports, signals=signals)


#: |sine of the transmission angle| below which a dyad is reported at its dead centre during a run
DEAD_CENTRE = 0.1

def check_mode(kind: str, K, meaning: str) -> None:
    """Refuse an assembly mode other than +1 or -1 (``bad_assembly_mode``); ``meaning`` says what the
    two modes are for this module."""
    if K not in (1, -1, 1.0, -1.0):
        from multipole import ModelError
        raise ModelError("bad_assembly_mode", f"{kind}: K = {K!r} must be +1 or -1", meaning)


def _drive_state(m, J) -> list:
    """The momentum a drive keeps as a state when its mechanism is driven by a torque or a force:
    the drive coordinate is regular through every position of the mechanism, a dependent link's
    rate passes through zero at the dead centres of the drive (``prefer_state`` of the network)."""
    return ["L.J.p"] if not _zero(J) else ["L.mx.p"] if not _zero(m) else []


_PLANAR_DOC = "planar bundle (x, y [m], phi [rad]; Fx, Fy [N], T [N*m])"


@element("DAN", "VDI 2729 rotary drive: a crank of length l hinged at P1 (anchor a) turning at the absolute "
         "angle phi set through its 1-D port drive; P at its tip is the output b",
         {"a": f"anchor at P1, the rigid bearing housing ({_PLANAR_DOC}); frame-fixed at (x1, y1) if not connected",
          "b": f"output on the crank at its tip P, angle phi ({_PLANAR_DOC})",
          "drive": "1-D rotational port on the crank: angular velocity phi' [rad/s], torque on the crank [N*m]",
          "support": "1-D rotational port on the housing (the reaction of a motor mounted on it)"},
         [Param("l", "m", "crank length P1-P", 1.0, positive=True),
          Param("phi0", "rad", "initial crank angle (absolute, from the x axis)", 0.0),
          Param("omega0", "rad/s", "initial angular velocity", 0.0)]
         + _body("m", "J", "xs", "ys") + _gravity() + _anchor("x1", "y1"),
         {"phi": "rad: crank angle (continuous, not wrapped)", "omega": "rad/s: crank angular velocity",
          "alpha": "rad/s^2: crank angular acceleration (needs J > 0)",
          "x": "m: x of the crank tip P", "y": "m: y of the crank tip P", "torque": "N*m: torque at the drive port"})
def DAN(l, phi0, omega0, xs, ys, m, J, gx, gy, x1, y1):
    """Rotary drive (VDI 2729 DAN) [lengths m, angles rad, m kg, J kg*m^2 about the centre of mass]."""
    xs = l / 2 if xs is None else xs
    phi, w = _S("phi0"), _S("omega0")
    xs_, ys_ = _S("xs"), _S("ys")
    p0 = (_S("m") * w * -(xs_ * _sin(phi) + ys_ * _cos(phi)), _S("m") * w * (xs_ * _cos(phi) - ys_ * _sin(phi)),
          _S("J") * w)
    crank = link([(_S("l"), 0)], 0 if _zero(m) else _S("m"), 0 if _zero(J) else _S("J"), xs_, ys_, phi,
                 ("drive", "out"), p0)
    housing = junction_b(["a", "support"], "rotational")
    params = {"l": l, "phi0": phi0, "omega0": omega0, "xs": xs, "ys": ys, "m": m, "J": J, "gx": gx, "gy": gy,
              "x1": x1, "y1": y1}
    ports = {"a.x": "L.A.x", "a.y": "L.A.y", "a.phi": "H.a", "support": "H.support",
             "b.x": "L.P1.x", "b.y": "L.P1.y", "b.phi": "L.w.out", "drive": "L.w.drive"}
    xa, ya, ph = _S("xa"), _S("ya"), _S("phiL")
    q = {"phi": Quantity(lambda V: V.x("L.K.q3")), "omega": Quantity(lambda V: V.f("L.w.drive")),
         "x": Quantity(lambda V: V.param("xa") + V.param("l") * sp.cos(V.x("L.K.q3"))),
         "y": Quantity(lambda V: V.param("ya") + V.param("l") * sp.sin(V.x("L.K.q3"))),
         "torque": Quantity(lambda V: V.e("L.w.drive"))}
    if not _zero(J):
        q["alpha"] = Quantity(lambda V: V.e("L.J.p") / V.param("J"))
    return Network("DAN", {"L": crank, "H": housing}, [], ports, params, q, signals={"phiL": "L.K.q3"},
                   bundles={"a": "planar", "b": "planar"},
                   positions={"b.x": xa + _S("l") * _cos(ph), "b.y": ya + _S("l") * _sin(ph), "b.phi": ph},
                   reads={"xa": ("a.x", _S("x1")), "ya": ("a.y", _S("y1"))},
                   fixed=("a.x", "a.y", "a.phi"), prefer_state=_drive_state(m, J),
                   sketch=[Sketch([(xa, ya), (xa + _S("l") * _cos(ph), ya + _S("l") * _sin(ph))], ["P1", "P"])])


@element("DDD", "VDI 2729 dyad with three revolute joints: link 1 (P1-P) and link 2 (P2-P) hinged at the anchors "
         "P1 (pin) and P2 (housing) and to each other at P",
         {"a1": f"anchor at P1, a pin ({_PLANAR_DOC}; transmits no torque); frame-fixed at (x1, y1) if not "
                "connected",
          "a2": f"anchor at P2, the rigid housing of link 2 ({_PLANAR_DOC}); frame-fixed at (x2, y2) if not "
                "connected",
          "b1": f"output on the plane of link 1 at P1, angle phi1 ({_PLANAR_DOC})",
          "b2": f"output on the plane of link 2 at P2, angle phi2 ({_PLANAR_DOC})",
          "drive": "1-D rotational port on link 2 (absolute angle phi2)",
          "support": "1-D rotational port on the housing at P2"},
         [Param("l1", "m", "length of link 1, P1-P", 1.0, positive=True),
          Param("l2", "m", "length of link 2, P2-P", 1.0, positive=True),
          Param("K", "-", "assembly mode at t = 0: +1 puts P left of the line P1 -> P2, -1 right", 1.0)]
         + _body("m1", "J1", "xs1", "ys1") + _body("m2", "J2", "xs2", "ys2") + _gravity()
         + _anchor("x1", "y1") + _anchor("x2", "y2"),
         {"phi1": "rad: angle of link 1 (P1 -> P)", "phi2": "rad: angle of link 2 (P2 -> P)",
          "omega1": "rad/s: angular velocity of link 1", "omega2": "rad/s: angular velocity of link 2",
          "alpha1": "rad/s^2: angular acceleration of link 1 (needs J1 > 0)",
          "alpha2": "rad/s^2: angular acceleration of link 2 (needs J2 > 0)",
          "x": "m: x of the joint P", "y": "m: y of the joint P",
          "transmission": "-: sin(phi2 - phi1), the sine of the transmission angle (0 at the dead centre)"})
def DDD(l1, l2, K, xs1, ys1, m1, J1, xs2, ys2, m2, J2, gx, gy, x1, y1, x2, y2):
    """Dyad with three revolute joints (VDI 2729 DDD) [m, rad, kg, kg*m^2]."""
    check_mode("DDD", K, "K = +1 puts the joint P left of the line from P1 to P2, K = -1 right of it")
    xs1 = l1 / 2 if xs1 is None else xs1
    xs2 = l2 / 2 if xs2 is None else xs2
    xa1, ya1, xa2, ya2 = (_S(n) for n in ("xa1", "ya1", "xa2", "ya2"))
    L1, L2 = _S("l1"), _S("l2")
    # VDI 2729 start position (B.42-B.52), at t = 0 only
    h1, h2 = xa2 - xa1, ya2 - ya1
    h3 = h1 ** 2 + h2 ** 2
    h4 = L1 ** 2 - L2 ** 2 + h3
    h5 = _S("K") * sp.sqrt(4 * h3 * L1 ** 2 - h4 ** 2)
    h6 = (h1 * h4 - h2 * h5) / (2 * h3)
    h7 = (h2 * h4 + h1 * h5) / (2 * h3)
    phi1_0, phi2_0 = sp.atan2(h7, h6), sp.atan2(h7 - h2, h6 - h1)

    def branch(k):
        """The closure's solution in assembly mode ``k``: the directions of links 1 and 2 (the start
        formula, P - P1 = (h6, h7), at every evaluation)."""
        root = k * sp.sqrt(4 * h3 * L1 ** 2 - h4 ** 2)
        x, y = (h1 * h4 - h2 * root) / (2 * h3), (h2 * h4 + h1 * root) / (2 * h3)
        return [(x / L1, y / L1), ((x - h1) / L2, (y - h2) / L2)]
    link1 = link([(L1, 0)], 0 if _zero(m1) else _S("m1"), 0 if _zero(J1) else _S("J1"), _S("xs1"), _S("ys1"),
                 phi1_0, ("out",))
    link2 = link([(L2, 0)], 0 if _zero(m2) else _S("m2"), 0 if _zero(J2) else _S("J2"), _S("xs2"), _S("ys2"),
                 phi2_0, ("out", "drive"))
    children = {"L1": link1, "L2": link2, "H": junction_b(["a", "support"], "rotational"),
                "pin": Se(0, "rotational")}
    for k in (1, 2):
        for axis in "xy":
            children[f"{axis}{k}"] = junction_b(["a", "k", "o"], "translational")
    connections = [["L1.P1.x", "L2.P1.x"], ["L1.P1.y", "L2.P1.y"],
                   ["x1.k", "L1.A.x"], ["y1.k", "L1.A.y"], ["x2.k", "L2.A.x"], ["y2.k", "L2.A.y"]]
    ports = {"a1.x": "x1.a", "a1.y": "y1.a", "a1.phi": "pin.p",
             "a2.x": "x2.a", "a2.y": "y2.a", "a2.phi": "H.a", "support": "H.support",
             "b1.x": "x1.o", "b1.y": "y1.o", "b1.phi": "L1.w.out",
             "b2.x": "x2.o", "b2.y": "y2.o", "b2.phi": "L2.w.out", "drive": "L2.w.drive"}
    p1, p2 = _S("phi1"), _S("phi2")
    params = {"l1": l1, "l2": l2, "K": K, "xs1": xs1, "ys1": ys1, "m1": m1, "J1": J1, "xs2": xs2, "ys2": ys2,
              "m2": m2, "J2": J2, "gx": gx, "gy": gy, "x1": x1, "y1": y1, "x2": x2, "y2": y2}
    closure = Closure(["L1.K.q3", "L2.K.q3"],
                      [xa1 + L1 * _cos(p1) - xa2 - L2 * _cos(p2), ya1 + L1 * _sin(p1) - ya2 - L2 * _sin(p2)],
                      "the joint P reached from P1 along link 1 and from P2 along link 2",
                      conditions=[(L1 + L2 - sp.sqrt(h3), "the links do not reach: |P1P2| exceeds l1 + l2", "m"),
                                  (sp.sqrt(h3) - sp.Abs(L1 - L2), "the links do not reach: |P1P2| is shorter than "
                                   "|l1 - l2|", "m")],
                      guard=(sp.sin(p2 - p1), DEAD_CENTRE, "sin(phi2 - phi1)"),
                      closed_form=ClosedForm([branch(K_) for K_ in (1, -1)],
                                             # the side of P1P2 the integrated link 1 points to: <= 0 for K = +1
                                             -(h2 * _cos(p1) - h1 * _sin(p1))))
    q = {"phi1": Quantity(lambda V: V.x("L1.K.q3")), "phi2": Quantity(lambda V: V.x("L2.K.q3")),
         "omega1": Quantity(lambda V: V.f("L1.w.out")), "omega2": Quantity(lambda V: V.f("L2.w.out")),
         "x": Quantity(lambda V: V.param("xa1") + V.param("l1") * sp.cos(V.x("L1.K.q3"))),
         "y": Quantity(lambda V: V.param("ya1") + V.param("l1") * sp.sin(V.x("L1.K.q3"))),
         "transmission": Quantity(lambda V: sp.sin(V.x("L2.K.q3") - V.x("L1.K.q3")))}
    for k, inertia in ((1, J1), (2, J2)):
        if not _zero(inertia):
            q[f"alpha{k}"] = Quantity(lambda V, k=k: V.e(f"L{k}.J.p") / V.param(f"J{k}"))
    return Network("DDD", children, connections, ports, params, q, signals={"phi1": "L1.K.q3", "phi2": "L2.K.q3"},
                   bundles={"a1": "planar", "a2": "planar", "b1": "planar", "b2": "planar"},
                   positions={"b1.x": xa1, "b1.y": ya1, "b1.phi": p1, "b2.x": xa2, "b2.y": ya2, "b2.phi": p2},
                   reads={"xa1": ("a1.x", _S("x1")), "ya1": ("a1.y", _S("y1")),
                          "xa2": ("a2.x", _S("x2")), "ya2": ("a2.y", _S("y2"))},
                   fixed=("a1.x", "a1.y", "a1.phi", "a2.x", "a2.y", "a2.phi"), closures=[closure],
                   sketch=[Sketch([(xa1, ya1), (xa1 + L1 * _cos(p1), ya1 + L1 * _sin(p1))], ["", "P"]),
                           Sketch([(xa2, ya2), (xa2 + L2 * _cos(p2), ya2 + L2 * _sin(p2))], ["P2", ""])])


# ---------------------------------------------------------------------------------------------
# the VDI 2729 reading of a mechanism (a check of the element library, registered in the kernel)

#: module -> (what it is, moving links it adds, joints it adds, Assur class; 0: a point on a known plane)
VDI_MODULES = {"DAN": ("rotary drive", 1, 1, 1), "SAN": ("linear drive", 1, 1, 1),
               "FGP": ("link-point guide", 0, 0, 0),
               **{k: ("dyad", 2, 3, 2) for k in ("DDD", "DDS", "DSD", "SSD", "SDS")}}


@register_check("vdi_structure", "info",
                "a mechanism of VDI 2729 modules: the modules in structural order with their Assur classes, "
                "Grübler's mobility F = 3(n - 1) - 2g and whether it equals the number of drives (forced motion)")
def vdi_structure(ctx):
    kinds = {el: ctx.flat.elements.get(el) for el in ctx.flat.elements}
    g = position_graph(ctx.flat)
    modules = [el for el in g.nodes if kinds.get(el) in VDI_MODULES]
    if not modules or ctx.flat.position_problems or not nx.is_directed_acyclic_graph(g):
        return                          # no modules, or the position checks report what is wrong
    order = [el for el in nx.topological_sort(g) if el in modules]
    n = 1 + sum(VDI_MODULES[kinds[el]][1] for el in order)
    joints = sum(VDI_MODULES[kinds[el]][2] for el in order)
    drives = sum(VDI_MODULES[kinds[el]][3] == 1 for el in order)
    F = 3 * (n - 1) - 2 * joints
    steps = []
    for el in order:
        what, _links, _joints, cls = VDI_MODULES[kinds[el]]
        steps.append(f"{el} ({kinds[el]}: {what}" + (f", class {cls}" if cls else "") + ")")
    verdict = "forced motion" if F == drives else \
        f"not forced: {F - drives} more drive(s) needed" if F > drives else \
        f"over-constrained by {drives - F}"
    yield Diagnostic("vdi_structure",
                     f"VDI 2729: {' -> '.join(steps)}; n = {n} links with the frame, g = {joints} joints: "
                     f"F = 3(n - 1) - 2g = {F}, {drives} drive(s): {verdict}", elements=order)
