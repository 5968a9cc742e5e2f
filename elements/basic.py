"""Basic elements every scene may use (DESIGN §5): 1-D mechanics, sources, electrical parts.

Each element is a small multipole of kernel primitives:

* ``inertia`` / ``mass``: a type-b junction (common speed of ports a, b) with an I on its third
  port; the net effort on the body changes its momentum ``p``.
* ``spring`` / ``damper``: a type-a junction (the same force at a and b, relative speed
  ``f_a - f_b``) with a C or an R on its third port.
* electrical two-pins (``resistor``, ``capacitor``, ``inductor``): a type-b junction (one current
  through both pins, voltage ``e_a - e_b``) with R, C or I.
* sources and grounds: Se / Sf primitives.
"""
from __future__ import annotations

import sympy as sp

from multipole import C, I, R, TF, ElementType, Network, Param, Quantity, Se, Sf, junction_a, junction_b, register

_C, _D, _L = (sp.Symbol(n) for n in ("c", "d", "L"))

_MECH = {"rotational": ("omega", "rad/s", "angular velocity", "torque", "N*m"),
         "translational": ("v", "m/s", "velocity", "force", "N")}


def _two_port(kind, junction, storage, quantities, params, signs=(1, -1, -1)):
    """Chain two-port a/b: ``junction`` over (a, b, x) with ``storage`` on x (the body)."""
    j = junction(["a", "b", "x"], storage.ports["p"].name, list(signs))
    return Network(kind, {"law": storage, "j": j}, [["j.x", "law.p"]], {"a": "j.a", "b": "j.b"},
                   params=params, quantities=quantities, body="law")


def inertia(J, omega0=0.0, domain="rotational"):
    """Rigid body: ports a and b share the speed; ``J`` [kg·m²] or mass ``m`` [kg]; initial speed."""
    speed, unit, what = _MECH[domain][:3]
    mass, speed0 = ("J", "omega0") if domain == "rotational" else ("m", "v0")
    quantities = {speed: Quantity(lambda V: V.f("law.p"), unit, what),
                  "p": Quantity(lambda V: V.x("law.p"), "", "momentum")}
    body = I(J=sp.Symbol(mass), dom=domain, p0=sp.Symbol(mass) * sp.Symbol(speed0))
    return _two_port("inertia" if domain == "rotational" else "mass", junction_b, body, quantities,
                     {mass: J, speed0: omega0}, (1, 1, 1))


def spring(c, x0=0.0, domain="rotational"):
    """Elastic coupling: ``force = c·deflection``, ``deflection' = f_a - f_b`` [c in N/m or N·m/rad]."""
    quantities = {"force": Quantity(lambda V: V.e("law.p"), _MECH[domain][4], "effort in the spring"),
                  "deflection": Quantity(lambda V: V.x("law.q"), "m | rad", "deflection")}
    return _two_port("spring", junction_a, C(c=_C, dom=domain, q0=sp.Symbol("x0")), quantities,
                     {"c": c, "x0": x0})


def damper(d=None, law=None, domain="rotational"):
    """Viscous (``force = d·(f_a - f_b)``) or nonlinear (``law`` of the relative flow ``f``) damper."""
    quantities = {"force": Quantity(lambda V: V.e("law.p"), _MECH[domain][4], "effort in the damper"),
                  "power": Quantity(lambda V: V.e("law.p") * V.f("law.p"), "W", "dissipated power")}
    prim = R(r=_D, dom=domain) if law is None else R(law=law, dom=domain)
    return _two_port("damper", junction_a, prim, quantities, {"d": d} if law is None else {})


def resistor(R_):
    """Resistor between pins a and b: ``e_a - e_b = R·i``, i the current into a [Ω]."""
    q = {"i": Quantity(lambda V: V.f("law.p"), "A", "current from a to b"),
         "v": Quantity(lambda V: V.e("law.p"), "V", "voltage e_a - e_b")}
    return _two_port("resistor", junction_b, R(r=sp.Symbol("R"), dom="electrical"), q, {"R": R_})


def capacitor(C_, v0=0.0):
    """Capacitor [F] between pins a and b; initial voltage ``v0`` [V]."""
    q = {"v": Quantity(lambda V: V.e("law.p"), "V", "voltage e_a - e_b"),
         "i": Quantity(lambda V: V.f("law.p"), "A", "current from a to b")}
    Cs = sp.Symbol("C")
    return _two_port("capacitor", junction_b, C(c=1 / Cs, dom="electrical", q0=Cs * sp.Symbol("v0")), q,
                     {"C": C_, "v0": v0})


def inductor(L, i0=0.0):
    """Inductor [H] between pins a and b; initial current ``i0`` [A]."""
    q = {"i": Quantity(lambda V: V.f("law.p"), "A", "current from a to b"),
         "v": Quantity(lambda V: V.e("law.p"), "V", "voltage e_a - e_b")}
    return _two_port("inductor", junction_b, I(J=_L, dom="electrical", p0=_L * sp.Symbol("i0")), q,
                     {"L": L, "i0": i0})


def _pin_source(kind, prim, params):
    q = {"i": Quantity(lambda V: -V.f("j.p"), "A", "current delivered out of pin p"),
         "v": Quantity(lambda V: V.e("j.p") - V.e("j.n"), "V", "voltage e_p - e_n")}
    j = junction_b(["p", "n", "x"], "electrical", [1, -1, -1])
    return Network(kind, {"src": prim, "j": j}, [["j.x", "src.p"]], {"p": "j.p", "n": "j.n"},
                   params=params, quantities=q, body="src")


_DOMAIN_MECH = Param("domain", "", "rotational or translational", "rotational", "choice",
                     ("rotational", "translational"))
_DOMAIN_ANY = Param("domain", "", "energy domain", "rotational", "choice",
                    ("rotational", "translational", "electrical", "hydraulic"))
_TWO = {"a": "port a", "b": "port b"}

register(ElementType(
    "inertia", lambda J, omega0: inertia(J, omega0, "rotational"),
    "rigid rotating body: ports a and b turn together, J*omega' = torque at a + torque at b", _TWO,
    [Param("J", "kg*m^2", "moment of inertia", positive=True), Param("omega0", "rad/s", "initial angular velocity", 0.0)],
    {"omega": "rad/s: angular velocity", "p": "N*m*s: angular momentum (state)"}))
register(ElementType(
    "mass", lambda m, v0: inertia(m, v0, "translational"),
    "rigid body in translation: ports a and b move together, m*v' = force at a + force at b", _TWO,
    [Param("m", "kg", "mass", positive=True), Param("v0", "m/s", "initial velocity", 0.0)],
    {"v": "m/s: velocity", "p": "N*s: momentum (state)"}))
register(ElementType(
    "spring", lambda c, x0, domain: spring(c, x0, domain),
    "linear spring: force = c*deflection, deflection' = f_a - f_b", _TWO,
    [Param("c", "N*m/rad | N/m", "stiffness", positive=True), Param("x0", "rad | m", "initial deflection", 0.0), _DOMAIN_MECH],
    {"force": "N*m | N: effort in the spring (positive when compressed from a)",
     "deflection": "rad | m: deflection (state q)"}))
register(ElementType(
    "damper", lambda d, law, domain: damper(d, law, domain),
    "damper: force = d*(f_a - f_b), or law(f) of the relative flow f", _TWO,
    [Param("d", "N*m*s/rad | N*s/m", "viscous coefficient (or give law)", None),
     Param("law", "N*m | N", "force as a function of the relative flow f (and t)", None, "law", law_var="f"),
     _DOMAIN_MECH],
    {"force": "N*m | N: effort in the damper", "power": "W: dissipated power"}, one_of=(("d", "law"),)))


def _source(name, prim, doc, domain, param_doc, unit):
    register(ElementType(name, lambda value: prim(value, domain), doc, {"p": "imposes the value on its neighbour"},
                         [Param("value", unit, param_doc, kind="time")]))


_source("torque_source", Se, "torque source: a positive torque accelerates a free inertia positively",
        "rotational", "torque as a function of t", "N*m")
_source("force_source", Se, "force source: a positive force accelerates a free mass positively",
        "translational", "force as a function of t", "N")
_source("speed_source", Sf, "speed source: imposes its angular velocity on the connected port",
        "rotational", "angular velocity as a function of t", "rad/s")
_source("velocity_source", Sf, "velocity source: imposes its velocity on the connected port",
        "translational", "velocity as a function of t", "m/s")
register(ElementType(
    "ground", lambda domain: Se(0, domain) if domain in ("electrical", "hydraulic") else Sf(0, domain),
    "reference: zero speed (mechanical) or zero potential/pressure (electrical, hydraulic)",
    {"p": "the grounded port"}, [_DOMAIN_ANY]))
register(ElementType(
    "ideal_gear", lambda i: TF(i, "rotational", "rotational"),
    "rigid gear stage: f_a = i*f_b, e_b = -i*e_a (i < 0 reverses the direction)", _TWO,
    [Param("i", "-", "ratio omega_a/omega_b", nonzero=True)]))
register(ElementType("resistor", lambda R: resistor(R), "resistor: e_a - e_b = R*i", _TWO,
                     [Param("R", "Ohm", "resistance", positive=True)],
                     {"i": "A: current from a to b", "v": "V: voltage e_a - e_b"}))
register(ElementType("capacitor", lambda C, v0: capacitor(C, v0), "capacitor: C*(e_a - e_b)' = i", _TWO,
                     [Param("C", "F", "capacitance", positive=True), Param("v0", "V", "initial voltage", 0.0)],
                     {"v": "V: voltage e_a - e_b", "i": "A: current from a to b"}))
register(ElementType("inductor", lambda L, i0: inductor(L, i0), "inductor: L*i' = e_a - e_b", _TWO,
                     [Param("L", "H", "inductance", positive=True), Param("i0", "A", "initial current", 0.0)],
                     {"i": "A: current from a to b", "v": "V: voltage e_a - e_b"}))
register(ElementType(
    "voltage_source", lambda value: _pin_source("voltage_source", Se(value, "electrical"), {}),
    "voltage source: e_p - e_n = value(t)", {"p": "positive pin", "n": "negative pin"},
    [Param("value", "V", "voltage as a function of t", kind="time")],
    {"i": "A: current delivered out of pin p", "v": "V: voltage e_p - e_n"}))
register(ElementType(
    "current_source", lambda value: _pin_source("current_source", Sf(value, "electrical"), {}),
    "current source: drives value(t) out of pin p through the circuit back into pin n",
    {"p": "pin the current leaves", "n": "pin the current returns to"},
    [Param("value", "A", "current as a function of t", kind="time")],
    {"i": "A: current delivered out of pin p", "v": "V: voltage e_p - e_n"}))
