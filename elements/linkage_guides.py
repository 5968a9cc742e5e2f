"""VDI 2729 dyads with prismatic joints on moving guides: DSD, SSD and SDS (Ebert 2015, B.6-B.8).

Each module is built like the revolute dyads of :mod:`elements.linkage`: the bodies that share one
angle form a *chain*, one modulated multiport transformer (:class:`multipole.MTF`) from the
velocity of a reference point, the common angular velocity and the slider travel rates to the
velocities of the centres of mass and of the joint points.  Its matrix is the Jacobian of the point
positions, written once as positions (VDI's point-direction form) and differentiated here, so
velocities, accelerations and, through the transpose, the kinetostatic joint forces of Ebert's body
equilibria all come from one expression per point (no force equation by hand, hence none of the
printed sign errors of B.130/131, B.141-B.148, B.182-B.194 or B.229/B.232).  The slider travels
are closure-bound states (:class:`multipole.Closure`): solved from the position closure at every
evaluation, so a mechanism never drifts off its closure.

Conventions (``docs/linkages.md``): e(phi) = (cos phi, sin phi), n(phi) = (-sin phi, cos phi);
a slider's foot point PS lies on its slide line at the travel x_G from the guide origin, the
joint point at the offset v along n.  Units SI: m, rad, kg, kg*m^2, m/s^2, N.
"""
from __future__ import annotations

import math

import sympy as sp

from multipole import MTF, ClosedForm, Closure, I, ModelError, Network, Param, Quantity, Se, Sf, element, junction_b

from .linkage import _PLANAR_DOC, DEAD_CENTRE, _S, _anchor, _gravity, _zero

_cos, _sin = sp.cos, sp.sin
_X, _Y, _TH = sp.Symbol("_X"), sp.Symbol("_Y"), sp.Symbol("_TH")


def _e(th):
    return sp.Matrix([_cos(th), _sin(th)])


def _n(th):
    return sp.Matrix([-_sin(th), _cos(th)])


def _rot(th, x, y):
    """R(th)·(x, y): a body-frame offset in the global frame."""
    return sp.Matrix([x * _cos(th) - y * _sin(th), x * _sin(th) + y * _cos(th)])


def chain(points: list, bodies: list, angle, travels: int, omega_ports=(), q0=None) -> Network:
    """Rigid bodies turning together at one angle, with ``travels`` slider travels along their guides.

    ``points``: position expressions ``(x, y)`` [m] of points in the symbols ``_X``, ``_Y`` (the
    reference point A), ``_TH`` (the common angle) and ``q4``, ``q5``, … (the travels [m]); the
    first ``len(bodies)`` points are the bodies' centres of mass.  ``bodies``: ``(m, J)`` per body
    [kg, kg*m^2], left out where they are the number 0; gravity ``(gx, gy)`` acts on every m.
    ``angle``: what ``_TH`` stands for, ``q3`` (the chain's own integrated angle) or an expression of
    position reads (a guide welded to its anchor).  ``q0``: initial displacements of the MTF's b
    ports (A.x, A.y, angle, travels).
    External ports: ``A.x``, ``A.y`` (reference point), ``s1``, ``s2``, … (travel rates [m/s],
    generalised forces [N]), ``P<k>.x``, ``P<k>.y`` (the points after the centres of mass, k from 1)
    and ``w.<name>`` for each ``omega_ports`` name (all at the common angular velocity [rad/s]).
    """
    qs = [sp.Symbol(f"q{4 + k}") for k in range(travels)]
    coords = [_X, _Y, _TH] + qs
    rows = [[sp.diff(p, c).subs(_TH, angle) for c in coords] for pt in points for p in pt]
    n_rows = len(rows)
    children = {"K": MTF(rows, ["translational"] * n_rows,
                         ["translational", "translational", "rotational"] + ["translational"] * travels,
                         q0=q0 or [0] * (3 + travels))}
    rot = [f"J{k}" for k, (_m, J) in enumerate(bodies) if not _zero(J)]
    children["W"] = junction_b(["k"] + rot + list(omega_ports), "rotational")
    connections = [["K.b3", "W.k"]]
    for k, (m, J) in enumerate(bodies):
        if not _zero(m):
            for axis, row, g in (("x", 2 * k + 1, "gx"), ("y", 2 * k + 2, "gy")):
                children[f"m{axis}{k}"] = I(J=sp.sympify(m), dom="translational")
                children[f"g{axis}{k}"] = Se(sp.sympify(m) * _S(g), "translational")
                connections.append([f"K.a{row}", f"m{axis}{k}.p", f"g{axis}{k}.p"])
        if not _zero(J):
            children[f"J{k}"] = I(J=sp.sympify(J), dom="rotational")
            connections.append([f"W.J{k}", f"J{k}.p"])
    ports = {"A.x": "K.b1", "A.y": "K.b2"}
    ports.update({f"s{k + 1}": f"K.b{4 + k}" for k in range(travels)})
    for k in range(len(points) - len(bodies)):
        row = 2 * (len(bodies) + k)
        ports[f"P{k + 1}.x"], ports[f"P{k + 1}.y"] = f"K.a{row + 1}", f"K.a{row + 2}"
    ports.update({f"w.{n}": f"W.{n}" for n in omega_ports})
    return Network("chain", children, connections, ports)


def _body(mass: str, inertia: str, xs: str, ys: str, what: str) -> list:
    return [Param(xs, "m", f"centre of mass of {what}, along the slide (body x axis)", 0.0),
            Param(ys, "m", f"centre of mass of {what}, across the slide (body y axis)", 0.0),
            Param(mass, "kg", f"mass of {what} (0: massless)", 1.0, nonnegative=True),
            Param(inertia, "kg*m^2", f"moment of inertia of {what} about its centre of mass", 0.1,
                  nonnegative=True)]


def _guide_angle(name: str, anchor: str) -> Param:
    return Param(name, "rad", f"angle of the slide line at {anchor}: against the frame when {anchor} is not "
                 f"connected, against the plane {anchor} is joined to when it is", 0.0)


def _number(value):
    """The float value of a parameter, or None where it is an expression of scene parameters."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _rigid_anchor_angle(read: str, offset: str):
    return _S(read) + _S(offset)


def _mass(m, name):
    return 0 if _zero(m) else _S(name)


#: |sine of the angle between two slide lines| up to which they count as parallel (no assembly)
_PARALLEL = 1e-9

_PIN = "({doc}; a pin: transmits no torque); frame-fixed at ({x}, {y}) if not connected"
_RIGID = "({doc}; rigid: the guide turns with it); frame-fixed at ({x}, {y}) if not connected"


@element("DSD", "VDI 2729 dyad with a prismatic joint as coupling: a massive guide hinged at P1 (anchor a1) and a "
         "massive slider hinged at P2 (anchor a2) slide on each other; P2 lies at the offset v from the slide line",
         {"a1": "anchor at P1, the guide's pin " + _PIN.format(doc=_PLANAR_DOC, x="x1", y="y1"),
          "a2": "anchor at P2, the slider's pin " + _PIN.format(doc=_PLANAR_DOC, x="x2", y="y2"),
          "b1": f"output on the guide plane at P1, angle phiU ({_PLANAR_DOC})",
          "b2": f"output on the slider plane at P2, angle phiU ({_PLANAR_DOC})",
          "drive": "1-D translational port on the slider: travel rate x_G' [m/s] along the slide, force on the "
                   "slider along the slide [N] (its reaction on the guide is included)",
          "support": "1-D translational port on the guide (held: x = 0, speed 0): the fixed end of a 1-D element "
                     "acting between guide and slider"},
         [Param("v", "m", "offset of P2 from the slide line, along the guide's y axis (|P1P2| > |v| at t = 0)", 0.1)]
         + _body("mU", "JU", "xsU", "ysU", "the guide (from P1 in the guide frame)")
         + _body("mS", "JS", "xsS", "ysS", "the slider (from the foot point PS in the slider frame)")
         + _gravity() + _anchor("x1", "y1") + _anchor("x2", "y2"),
         {"phiU": "rad: angle of the slide line (guide and slider)", "omega": "rad/s: angular velocity of guide "
          "and slider", "xG": "m: travel of the foot point PS from P1 along the slide (0 at the dead centre)",
          "vG": "m/s: travel rate", "force": "N: force at the drive port"})
def DSD(v, xsU, ysU, mU, JU, xsS, ysS, mS, JS, gx, gy, x1, y1, x2, y2):
    """Dyad with a prismatic joint as coupling (VDI 2729 DSD) [m, rad, kg, kg*m^2]."""
    V_ = _S("v")
    xa1, ya1, xa2, ya2 = (_S(n) for n in ("xa1", "ya1", "xa2", "ya2"))
    # start orientation (B.119-B.125) with the corrected sign of (B.124): (H5, H6) = e(phiU)
    h1, h2 = xa2 - xa1, ya2 - ya1
    h3 = h1 ** 2 + h2 ** 2
    h4 = sp.sqrt(h3 - V_ ** 2)
    h5, h6 = (h1 * h4 + V_ * h2) / h3, (h2 * h4 - V_ * h1) / h3
    th, s = _S("q3"), _S("q4")
    p1 = sp.Matrix([_X, _Y])
    ps = p1 + s * _e(_TH)
    points = [p1 + _rot(_TH, _S("xsU"), _S("ysU")), ps + _rot(_TH, _S("xsS"), _S("ysS")), ps + V_ * _n(_TH)]
    body = chain([tuple(p) for p in points], [(_mass(mU, "mU"), _mass(JU, "JU")), (_mass(mS, "mS"), _mass(JS, "JS"))],
                 th, 1, ("out1", "out2"), [0, 0, sp.atan2(h6, h5), h4])
    children = {"C": body, "pin1": Se(0, "rotational"), "pin2": Se(0, "rotational"), "Z": Sf(0, "translational")}
    for k in (1, 2):
        for axis in "xy":
            children[f"{axis}{k}"] = junction_b(["a", "k", "o"], "translational")
    connections = [["x1.k", "C.A.x"], ["y1.k", "C.A.y"], ["x2.k", "C.P1.x"], ["y2.k", "C.P1.y"]]
    ports = {"a1.x": "x1.a", "a1.y": "y1.a", "a1.phi": "pin1.p", "a2.x": "x2.a", "a2.y": "y2.a", "a2.phi": "pin2.p",
             "b1.x": "x1.o", "b1.y": "y1.o", "b1.phi": "C.w.out1", "b2.x": "x2.o", "b2.y": "y2.o",
             "b2.phi": "C.w.out2", "drive": "C.s1", "support": "Z.p"}
    phi, xg = _S("phiU"), _S("xG")
    closure = Closure(["C.K.q3", "C.K.q4"],
                      list(sp.Matrix([xa1, ya1]) + xg * _e(phi) + V_ * _n(phi) - sp.Matrix([xa2, ya2])),
                      "P2 reached from P1 along the slide line (travel x_G) and the offset v",
                      conditions=[(sp.sqrt(h3) - sp.Abs(V_), "the slider cannot reach: |P1P2| is not longer than "
                                   "|v|", "m")],
                      guard=(xg / sp.sqrt(xg ** 2 + V_ ** 2), DEAD_CENTRE, "x_G/|P1P2|"),
                      # the start formula with the travel's sign from the integrated travel (through its dead centre)
                      closed_form=ClosedForm([[((h1 * g + V_ * h2) / h3, (h2 * g - V_ * h1) / h3), g]
                                              for g in (h4, -h4)], xg))
    params = {"v": v, "xsU": xsU, "ysU": ysU, "mU": mU, "JU": JU, "xsS": xsS, "ysS": ysS, "mS": mS, "JS": JS,
              "gx": gx, "gy": gy, "x1": x1, "y1": y1, "x2": x2, "y2": y2}
    q = {"phiU": Quantity(lambda V: V.x("C.K.q3")), "omega": Quantity(lambda V: V.f("C.w.out1")),
         "xG": Quantity(lambda V: V.x("C.K.q4")), "vG": Quantity(lambda V: V.f("C.s1")),
         "force": Quantity(lambda V: V.e("C.s1"))}
    return Network("DSD", children, connections, ports, params, q, signals={"phiU": "C.K.q3", "xG": "C.K.q4"},
                   bundles={"a1": "planar", "a2": "planar", "b1": "planar", "b2": "planar"},
                   positions={"b1.x": xa1, "b1.y": ya1, "b1.phi": phi, "b2.x": xa2, "b2.y": ya2, "b2.phi": phi},
                   reads={"xa1": ("a1.x", _S("x1")), "ya1": ("a1.y", _S("y1")),
                          "xa2": ("a2.x", _S("x2")), "ya2": ("a2.y", _S("y2"))},
                   fixed=("a1.x", "a1.y", "a1.phi", "a2.x", "a2.y", "a2.phi"), closures=[closure])


@element("SSD", "VDI 2729 dyad with prismatic joints as connection and coupling: slider 1 runs on a guide welded to "
         "anchor a1 and carries, through P (offset v1), a second slide line at the fixed angle phiv; slider 2 runs "
         "on it and is hinged to anchor a2 at P2 (offset v2)",
         {"a1": "anchor at P1, origin of slide line 1 " + _RIGID.format(doc=_PLANAR_DOC, x="x1", y="y1"),
          "a2": "anchor at P2, slider 2's pin " + _PIN.format(doc=_PLANAR_DOC, x="x2", y="y2"),
          "b1": f"output on the plane of slider 1 at P, angle phiU1 ({_PLANAR_DOC})",
          "b2": f"output on the plane of slider 2 at P2, angle phiU1 + phiv ({_PLANAR_DOC})"},
         [Param("v1", "m", "offset of P from slide line 1 (along its normal)", 0.1),
          Param("v2", "m", "offset of P2 from slide line 2 (along its normal)", 0.1),
          Param("phiv", "rad", "angle of slide line 2 against slide line 1 (sin(phiv) != 0)", math.radians(15)),
          _guide_angle("phi1", "a1")]
         + _body("m1", "J1", "xs1", "ys1", "slider 1 (from its foot point PS1)")
         + _body("m2", "J2", "xs2", "ys2", "slider 2 (from its foot point PS2)")
         + _gravity() + _anchor("x1", "y1") + _anchor("x2", "y2"),
         {"phiU1": "rad: angle of slide line 1", "omega": "rad/s: angular velocity of both sliders",
          "xG1": "m: travel of PS1 from P1 along slide line 1", "xG2": "m: travel of PS2 from P along slide line 2",
          "vG1": "m/s: rate of xG1", "vG2": "m/s: rate of xG2", "x": "m: x of P", "y": "m: y of P"})
def SSD(v1, v2, phiv, phi1, xs1, ys1, m1, J1, xs2, ys2, m2, J2, gx, gy, x1, y1, x2, y2):
    """Dyad with prismatic joints as connection and coupling (VDI 2729 SSD) [m, rad, kg, kg*m^2]."""
    sv = _number(phiv)
    if sv is not None and abs(math.sin(sv)) <= _PARALLEL:
        raise ModelError("parallel_slides", f"SSD: phiv = {phiv!r} rad makes the two slide lines parallel "
                         "(sin(phiv) = 0): the travels are undetermined in every position",
                         "give phiv an angle away from 0 and pi (VDI's default is 15 degrees)")
    xa1, ya1, xa2, ya2 = (_S(n) for n in ("xa1", "ya1", "xa2", "ya2"))
    th = _rigid_anchor_angle("pa1", "phi1")
    V1, V2, PV = _S("v1"), _S("v2"), _S("phiv")
    # closed-form start: xG1 e1 + xG2 e2 = b (linear; e1 x e2 = sin(phiv))
    b = sp.Matrix([xa2 - xa1, ya2 - ya1]) - V1 * _n(th) - V2 * _n(th + PV)
    e1, e2 = _e(th), _e(th + PV)
    xg1_0 = (b[0] * e2[1] - b[1] * e2[0]) / sp.sin(PV)
    xg2_0 = (e1[0] * b[1] - e1[1] * b[0]) / sp.sin(PV)
    s1, s2 = _S("q4"), _S("q5")
    ps1 = sp.Matrix([_X, _Y]) + s1 * _e(_TH)
    p = ps1 + V1 * _n(_TH)
    ps2 = p + s2 * _e(_TH + PV)
    points = [ps1 + _rot(_TH, _S("xs1"), _S("ys1")), ps2 + _rot(_TH + PV, _S("xs2"), _S("ys2")), p,
              ps2 + V2 * _n(_TH + PV)]
    body = chain([tuple(q) for q in points], [(_mass(m1, "m1"), _mass(J1, "J1")), (_mass(m2, "m2"), _mass(J2, "J2"))],
                 th, 2, ("a", "out1", "out2"), [0, 0, 0, xg1_0, xg2_0])
    children = {"C": body, "pin2": Se(0, "rotational"), "x2": junction_b(["a", "k", "o"], "translational"),
                "y2": junction_b(["a", "k", "o"], "translational")}
    connections = [["x2.k", "C.P2.x"], ["y2.k", "C.P2.y"]]
    ports = {"a1.x": "C.A.x", "a1.y": "C.A.y", "a1.phi": "C.w.a", "a2.x": "x2.a", "a2.y": "y2.a", "a2.phi": "pin2.p",
             "b1.x": "C.P1.x", "b1.y": "C.P1.y", "b1.phi": "C.w.out1", "b2.x": "x2.o", "b2.y": "y2.o",
             "b2.phi": "C.w.out2"}
    g1, g2 = _S("xG1"), _S("xG2")
    phi_ = th
    pos_p = sp.Matrix([xa1, ya1]) + g1 * _e(phi_) + V1 * _n(phi_)
    closure = Closure(["C.K.q4", "C.K.q5"],
                      list(pos_p + g2 * _e(phi_ + PV) + V2 * _n(phi_ + PV) - sp.Matrix([xa2, ya2])),
                      "P2 reached along slide line 1 (travel xG1, offset v1) and slide line 2 (xG2, v2)",
                      closed_form=ClosedForm([[xg1_0, xg2_0]]))
    params = {"v1": v1, "v2": v2, "phiv": phiv, "phi1": phi1, "xs1": xs1, "ys1": ys1, "m1": m1, "J1": J1,
              "xs2": xs2, "ys2": ys2, "m2": m2, "J2": J2, "gx": gx, "gy": gy, "x1": x1, "y1": y1, "x2": x2, "y2": y2}
    q = {"phiU1": Quantity(lambda V: V.param("pa1") + V.param("phi1")), "omega": Quantity(lambda V: V.f("C.w.out1")),
         "xG1": Quantity(lambda V: V.x("C.K.q4")), "xG2": Quantity(lambda V: V.x("C.K.q5")),
         "vG1": Quantity(lambda V: V.f("C.s1")), "vG2": Quantity(lambda V: V.f("C.s2")),
         "x": Quantity(lambda V: V.param("xa1") + V.x("C.K.q4") * sp.cos(V.param("pa1") + V.param("phi1"))
                       - V.param("v1") * sp.sin(V.param("pa1") + V.param("phi1"))),
         "y": Quantity(lambda V: V.param("ya1") + V.x("C.K.q4") * sp.sin(V.param("pa1") + V.param("phi1"))
                       + V.param("v1") * sp.cos(V.param("pa1") + V.param("phi1")))}
    return Network("SSD", children, connections, ports, params, q, signals={"xG1": "C.K.q4", "xG2": "C.K.q5"},
                   bundles={"a1": "planar", "a2": "planar", "b1": "planar", "b2": "planar"},
                   positions={"b1.x": pos_p[0], "b1.y": pos_p[1], "b1.phi": th, "b2.x": xa2, "b2.y": ya2,
                              "b2.phi": th + PV},
                   reads={"xa1": ("a1.x", _S("x1")), "ya1": ("a1.y", _S("y1")), "pa1": ("a1.phi", 0),
                          "xa2": ("a2.x", _S("x2")), "ya2": ("a2.y", _S("y2"))},
                   fixed=("a1.x", "a1.y", "a1.phi", "a2.x", "a2.y", "a2.phi"), closures=[closure])


@element("SDS", "VDI 2729 dyad with two prismatic joints as connections: slider 1 on a guide welded to anchor a1 and "
         "slider 2 on a guide welded to anchor a2, hinged to each other at P (offsets v1, v2 from the slide lines)",
         {"a1": "anchor at P1, origin of slide line 1 " + _RIGID.format(doc=_PLANAR_DOC, x="x1", y="y1"),
          "a2": "anchor at P2, origin of slide line 2 " + _RIGID.format(doc=_PLANAR_DOC, x="x2", y="y2"),
          "b1": f"output on the plane of slider 1 at P, angle phiU1 ({_PLANAR_DOC})",
          "b2": f"output on the plane of slider 2 at its foot point PS2, angle phiU2 ({_PLANAR_DOC})"},
         [Param("v1", "m", "offset of P from slide line 1 (along its normal)", 0.1),
          Param("v2", "m", "offset of P from slide line 2 (along its normal)", 0.1),
          _guide_angle("phi1", "a1"), _guide_angle("phi2", "a2")]
         + _body("m1", "J1", "xs1", "ys1", "slider 1 (from its foot point PS1)")
         + _body("m2", "J2", "xs2", "ys2", "slider 2 (from its foot point PS2)")
         + _gravity() + _anchor("x1", "y1") + _anchor("x2", "y2"),
         {"phiU1": "rad: angle of slide line 1", "phiU2": "rad: angle of slide line 2",
          "xG1": "m: travel of PS1 from P1 along slide line 1", "xG2": "m: travel of PS2 from P2 along slide line 2",
          "vG1": "m/s: rate of xG1", "vG2": "m/s: rate of xG2", "x": "m: x of P", "y": "m: y of P",
          "transmission": "-: sin(phiU2 - phiU1), 0 where the guides are parallel"})
def SDS(v1, v2, phi1, phi2, xs1, ys1, m1, J1, xs2, ys2, m2, J2, gx, gy, x1, y1, x2, y2):
    """Dyad with two prismatic joints as connections (VDI 2729 SDS) [m, rad, kg, kg*m^2]."""
    xa1, ya1, xa2, ya2 = (_S(n) for n in ("xa1", "ya1", "xa2", "ya2"))
    th1, th2 = _rigid_anchor_angle("pa1", "phi1"), _rigid_anchor_angle("pa2", "phi2")
    V1, V2 = _S("v1"), _S("v2")
    e1, e2 = _e(th1), _e(th2)
    # closed-form start: xG1 e1 - xG2 e2 = b (linear)
    b = sp.Matrix([xa2, ya2]) + V2 * _n(th2) - sp.Matrix([xa1, ya1]) - V1 * _n(th1)
    cross = e1[0] * e2[1] - e1[1] * e2[0]
    # parallel slide lines at t = 0 are reported by the closure's condition; the start values stay finite
    safe = sp.Piecewise((cross, sp.Abs(cross) > _PARALLEL), (1, True))
    xg1_0 = (b[0] * e2[1] - b[1] * e2[0]) / safe
    xg2_0 = (b[0] * e1[1] - b[1] * e1[0]) / safe
    s = _S("q4")
    a = sp.Matrix([_X, _Y])
    side1 = chain([tuple(a + s * _e(_TH) + _rot(_TH, _S("xs1"), _S("ys1"))), tuple(a + s * _e(_TH) + V1 * _n(_TH))],
                  [(_mass(m1, "m1"), _mass(J1, "J1"))], th1, 1, ("a", "out"), [0, 0, 0, xg1_0])
    side2 = chain([tuple(a + s * _e(_TH) + _rot(_TH, _S("xs2"), _S("ys2"))), tuple(a + s * _e(_TH) + V2 * _n(_TH)),
                   tuple(a + s * _e(_TH))],
                  [(_mass(m2, "m2"), _mass(J2, "J2"))], th2, 1, ("a", "out"), [0, 0, 0, xg2_0])
    children = {"C1": side1, "C2": side2, "px": junction_b(["k1", "k2", "o"], "translational"),
                "py": junction_b(["k1", "k2", "o"], "translational")}
    connections = [["px.k1", "C1.P1.x"], ["py.k1", "C1.P1.y"], ["px.k2", "C2.P1.x"], ["py.k2", "C2.P1.y"]]
    ports = {"a1.x": "C1.A.x", "a1.y": "C1.A.y", "a1.phi": "C1.w.a", "a2.x": "C2.A.x", "a2.y": "C2.A.y",
             "a2.phi": "C2.w.a", "b1.x": "px.o", "b1.y": "py.o", "b1.phi": "C1.w.out",
             "b2.x": "C2.P2.x", "b2.y": "C2.P2.y", "b2.phi": "C2.w.out"}
    g1, g2 = _S("xG1"), _S("xG2")
    pos_p = sp.Matrix([xa1, ya1]) + g1 * e1 + V1 * _n(th1)
    pos_ps2 = sp.Matrix([xa2, ya2]) + g2 * e2
    closure = Closure(["C1.K.q4", "C2.K.q4"], list(pos_p - pos_ps2 - V2 * _n(th2)),
                      "P reached along slide line 1 (travel xG1, offset v1) and slide line 2 (xG2, v2)",
                      conditions=[(sp.Abs(cross) - _PARALLEL, "the slide lines are parallel: |sin(phiU2 - phiU1)| "
                                   f"is not above {_PARALLEL}", "-")],
                      guard=(cross, DEAD_CENTRE, "sin(phiU2 - phiU1)"),
                      closed_form=ClosedForm([[(b[0] * e2[1] - b[1] * e2[0]) / cross,
                                               (b[0] * e1[1] - b[1] * e1[0]) / cross]]))
    params = {"v1": v1, "v2": v2, "phi1": phi1, "phi2": phi2, "xs1": xs1, "ys1": ys1, "m1": m1, "J1": J1,
              "xs2": xs2, "ys2": ys2, "m2": m2, "J2": J2, "gx": gx, "gy": gy, "x1": x1, "y1": y1, "x2": x2, "y2": y2}

    def angle(V, k):
        return V.param(f"pa{k}") + V.param(f"phi{k}")

    q = {"phiU1": Quantity(lambda V: angle(V, 1)), "phiU2": Quantity(lambda V: angle(V, 2)),
         "xG1": Quantity(lambda V: V.x("C1.K.q4")), "xG2": Quantity(lambda V: V.x("C2.K.q4")),
         "vG1": Quantity(lambda V: V.f("C1.s1")), "vG2": Quantity(lambda V: V.f("C2.s1")),
         "x": Quantity(lambda V: V.param("xa1") + V.x("C1.K.q4") * sp.cos(angle(V, 1))
                       - V.param("v1") * sp.sin(angle(V, 1))),
         "y": Quantity(lambda V: V.param("ya1") + V.x("C1.K.q4") * sp.sin(angle(V, 1))
                       + V.param("v1") * sp.cos(angle(V, 1))),
         "transmission": Quantity(lambda V: sp.sin(angle(V, 2) - angle(V, 1)))}
    return Network("SDS", children, connections, ports, params, q, signals={"xG1": "C1.K.q4", "xG2": "C2.K.q4"},
                   bundles={"a1": "planar", "a2": "planar", "b1": "planar", "b2": "planar"},
                   positions={"b1.x": pos_p[0], "b1.y": pos_p[1], "b1.phi": th1, "b2.x": pos_ps2[0],
                              "b2.y": pos_ps2[1], "b2.phi": th2},
                   reads={"xa1": ("a1.x", _S("x1")), "ya1": ("a1.y", _S("y1")), "pa1": ("a1.phi", 0),
                          "xa2": ("a2.x", _S("x2")), "ya2": ("a2.y", _S("y2")), "pa2": ("a2.phi", 0)},
                   fixed=("a1.x", "a1.y", "a1.phi", "a2.x", "a2.y", "a2.phi"), closures=[closure])
