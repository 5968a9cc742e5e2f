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

import multipole as mp
from multipole import DOMAINS, I, TF, ElementType, Network, Param, Quantity, Reduction, Se, Sf, element, junction_a, \
    junction_b, register

_C, _D, _L = (sp.Symbol(n) for n in ("c", "d", "L"))

_DOMAIN_MECH = Param("domain", "", "rotational or translational", "rotational", "choice",
                     ("rotational", "translational"))
_DOMAIN_ANY = Param("domain", "", "energy domain", "rotational", "choice",
                    ("rotational", "translational", "electrical", "hydraulic"))
_TWO = {"a": "port a", "b": "port b"}
_PIN_QTY = {"i": "A: current from a to b", "v": "V: voltage e_a - e_b"}


def _two_port(kind, junction, storage, quantities, params, signs=(1, -1, -1)):
    """Chain two-port a/b: ``junction`` over (a, b, x) with ``storage`` on x (the body)."""
    j = junction(["a", "b", "x"], storage.ports["p"].name, list(signs))
    return Network(kind, {"law": storage, "j": j}, [["j.x", "law.p"]], {"a": "j.a", "b": "j.b"},
                   params=params, quantities=quantities, body="law")


def _body(kind, domain, speed, params):
    """Rigid body: ports a and b share the speed; ``params`` = {mass name: value, initial speed name: value}."""
    (mass, m), (speed0, v0) = params.items()
    quantities = {speed: Quantity(lambda V: V.f("law.p")), "p": Quantity(lambda V: V.x("law.p"))}
    body = I(J=sp.Symbol(mass), dom=domain, p0=sp.Symbol(mass) * sp.Symbol(speed0))
    return _two_port(kind, junction_b, body, quantities, {mass: m, speed0: v0}, (1, 1, 1))


@element("inertia", "rigid rotating body: ports a and b turn together, J*omega' = torque at a + torque at b", _TWO,
         [Param("J", "kg*m^2", "moment of inertia", positive=True),
          Param("omega0", "rad/s", "initial angular velocity", 0.0)],
         {"omega": "rad/s: angular velocity", "p": "N*m*s: angular momentum (state)"},
         reductions=(Reduction("massless", join=("a", "b")),))
def inertia(J, omega0):
    """Rigid rotating body [J in kg·m², omega0 in rad/s]."""
    return _body("inertia", "rotational", "omega", {"J": J, "omega0": omega0})


@element("mass", "rigid body in translation: ports a and b move together, m*v' = force at a + force at b", _TWO,
         [Param("m", "kg", "mass", positive=True), Param("v0", "m/s", "initial velocity", 0.0)],
         {"v": "m/s: velocity", "p": "N*s: momentum (state)"}, reductions=(Reduction("massless", join=("a", "b")),))
def mass(m, v0):
    """Rigid body in translation [m in kg, v0 in m/s]."""
    return _body("mass", "translational", "v", {"m": m, "v0": v0})


@element("spring", "linear spring: force = c*deflection, deflection' = f_a - f_b", _TWO,
         [Param("c", "N*m/rad | N/m", "stiffness", positive=True), Param("x0", "rad | m", "initial deflection", 0.0),
          _DOMAIN_MECH],
         {"force": "N*m | N: effort in the spring (positive when compressed from a)",
          "deflection": "rad | m: deflection (state q)"}, reductions=(Reduction("rigid", join=("a", "b")),))
def spring(c, x0, domain):
    """Elastic coupling: ``force = c·deflection``, ``deflection' = f_a - f_b`` [c in N/m or N·m/rad]."""
    quantities = {"force": Quantity(lambda V: V.e("law.p"), DOMAINS[domain].effort_unit),
                  "deflection": Quantity(lambda V: V.x("law.q"), DOMAINS[domain].displacement_unit)}
    return _two_port("spring", junction_a, mp.C(c=_C, dom=domain, q0=sp.Symbol("x0")), quantities,
                     {"c": c, "x0": x0})


@element("damper", "damper: force = d*(f_a - f_b), or law(f) of the relative flow f", _TWO,
         [Param("d", "N*m*s/rad | N*s/m", "viscous coefficient (or give law)", None),
          Param("law", "N*m | N", "force as a function of the relative flow f (and t)", None, "law", law_var="f"),
          _DOMAIN_MECH],
         {"force": "N*m | N: effort in the damper", "power": "W: dissipated power"}, one_of=(("d", "law"),),
         reductions=(Reduction("removed"),))
def damper(d, law, domain):
    """Viscous (``force = d·(f_a - f_b)``) or nonlinear (``law`` of the relative flow ``f``) damper."""
    quantities = {"force": Quantity(lambda V: V.e("law.p"), DOMAINS[domain].effort_unit),
                  "power": Quantity(lambda V: V.e("law.p") * V.f("law.p"))}
    prim = mp.R(r=_D, dom=domain) if law is None else mp.R(law=law, dom=domain)
    return _two_port("damper", junction_a, prim, quantities, {"d": d} if law is None else {})


def _pin_quantities():
    return {"i": Quantity(lambda V: V.f("law.p")), "v": Quantity(lambda V: V.e("law.p"))}


@element("resistor", "resistor: e_a - e_b = R*i", _TWO, [Param("R", "Ohm", "resistance", positive=True)], _PIN_QTY,
         reductions=(Reduction("shorted", join=("a", "b")),))
def resistor(R):
    """Resistor between pins a and b: ``e_a - e_b = R·i``, i the current into a [Ω]."""
    return _two_port("resistor", junction_b, mp.R(r=sp.Symbol("R"), dom="electrical"), _pin_quantities(), {"R": R})


@element("capacitor", "capacitor: C*(e_a - e_b)' = i", _TWO,
         [Param("C", "F", "capacitance", positive=True), Param("v0", "V", "initial voltage", 0.0)],
         {"v": _PIN_QTY["v"], "i": _PIN_QTY["i"]})
def capacitor(C, v0):
    """Capacitor [F] between pins a and b; initial voltage ``v0`` [V]."""
    Cs = sp.Symbol("C")
    return _two_port("capacitor", junction_b, mp.C(c=1 / Cs, dom="electrical", q0=Cs * sp.Symbol("v0")),
                     _pin_quantities(), {"C": C, "v0": v0})


@element("inductor", "inductor: L*i' = e_a - e_b", _TWO,
         [Param("L", "H", "inductance", positive=True), Param("i0", "A", "initial current", 0.0)], _PIN_QTY,
         reductions=(Reduction("shorted", join=("a", "b")),))
def inductor(L, i0):
    """Inductor [H] between pins a and b; initial current ``i0`` [A]."""
    return _two_port("inductor", junction_b, I(J=_L, dom="electrical", p0=_L * sp.Symbol("i0")), _pin_quantities(),
                     {"L": L, "i0": i0})


_SOURCE_QTY = {"i": "A: current delivered out of pin p", "v": "V: voltage e_p - e_n"}


def _pin_source(kind, prim):
    q = {"i": Quantity(lambda V: -V.f("j.p")), "v": Quantity(lambda V: V.e("j.p") - V.e("j.n"))}
    j = junction_b(["p", "n", "x"], "electrical", [1, -1, -1])
    return Network(kind, {"src": prim, "j": j}, [["j.x", "src.p"]], {"p": "j.p", "n": "j.n"},
                   quantities=q, body="src")


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
register(ElementType(
    "voltage_source", lambda value: _pin_source("voltage_source", Se(value, "electrical")),
    "voltage source: e_p - e_n = value(t)", {"p": "positive pin", "n": "negative pin"},
    [Param("value", "V", "voltage as a function of t", kind="time")], _SOURCE_QTY))
register(ElementType(
    "current_source", lambda value: _pin_source("current_source", Sf(value, "electrical")),
    "current source: drives value(t) out of pin p through the circuit back into pin n",
    {"p": "pin the current leaves", "n": "pin the current returns to"},
    [Param("value", "A", "current as a function of t", kind="time")], _SOURCE_QTY))
