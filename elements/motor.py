"""Permanent-magnet DC motor: a gyrator with R and L on the electrical side, J (and d) on the shaft.

Structure (Weber's multipole form; the gyrator couples the effort of one side to the flow of the
other)::

    elec ──┤ loop (type b) ├── elec_n (or internal ground)    electrical: one armature current i
              │       │
           res (R)  coil (I, L)
              │
           gy (GY, k):   back_emf = k·omega,   torque = k·i
              │
    shaft ─┤ rotor (type b) ├                                  rotational: one speed omega
              │        │
          inertia (I, J)  friction (R, d)

* ``loop``: type-b junction (series circuit): ``e(elec) − e(elec_n) = R·i + L·i' + k·omega``.
* ``rotor``: type-b junction (rigid rotor): ``J·omega' = k·i − d·omega + M_shaft``, where
  ``M_shaft`` is the torque acting on the motor at ``shaft`` (a load that brakes the motor gives a
  negative ``M_shaft``).
* ``gy``: ``GY`` with modulus ``k`` [N·m/A = V·s/rad]; lossless: ``k·i·omega`` leaves the
  electrical side and arrives at the rotor.

Electrical terminals: ``elec`` is the positive terminal (current into it drives the motor
forward).  By default (``grounded: true``) the negative terminal is tied to the electrical reference
(0 V) inside the motor, as for a single-ended motor driver: wire ``elec`` to the supply's positive
pin and ground the supply's negative pin.  With ``grounded: false`` the negative terminal is the
port ``elec_n`` and the motor floats (H-bridge, series circuits); then both terminals must be wired.

Literal zeros leave parts out: ``L = 0`` (the current follows the voltage algebraically),
``J = 0`` (massless rotor, the load's inertia carries the motion), ``d = 0`` (no friction).
"""
from __future__ import annotations

import sympy as sp

import multipole as mp
from multipole import GY, I, Network, Param, Quantity, Se, element, junction_b

from .piezo import literal_zero   # shared "leave the part out" rule of this library

_k, _R, _L, _J, _d = (sp.Symbol(n) for n in ("k", "R", "L", "J", "d"))


@element("dc_motor", "permanent-magnet DC motor: U = R*i + L*i' + k*omega, J*omega' = k*i - d*omega + M_shaft",
         {"elec": "electrical: positive terminal (current in drives the motor forward)",
          "elec_n": "electrical: negative terminal, only with grounded: false (else tied to 0 V inside)",
          "shaft": "rotational: the shaft; torque acting on the motor, rotor speed"},
         [Param("k", "N*m/A", "torque constant (= back-emf constant in V*s/rad)", nonzero=True),
          Param("R", "Ohm", "armature resistance", nonnegative=True),
          Param("L", "H", "armature inductance (literal 0: current follows the voltage)", nonnegative=True),
          Param("J", "kg*m^2", "rotor inertia (literal 0: massless rotor)", nonnegative=True),
          Param("d", "N*m*s/rad", "viscous friction of the rotor bearings", 0.0, nonnegative=True),
          Param("omega0", "rad/s", "initial angular velocity", 0.0),
          Param("i0", "A", "initial armature current", 0.0),
          Param("grounded", "", "negative terminal at 0 V inside the motor (false: port elec_n)", True, "bool")],
         {"omega": "rad/s: rotor angular velocity", "current": "A: armature current into elec",
          "torque": "N*m: electromagnetic torque k*i on the rotor", "back_emf": "V: induced voltage k*omega",
          "voltage": "V: terminal voltage e(elec) - e(elec_n)"})
def dc_motor(k, R, L, J, d, omega0, i0, grounded) -> Network:
    """DC motor with ports ``elec`` (+), ``elec_n`` (−, only if not ``grounded``) and ``shaft``.

    ``k`` [N·m/A] torque (= back-emf) constant, ``R`` [Ω] armature resistance, ``L`` [H] armature
    inductance, ``J`` [kg·m²] rotor inertia, ``d`` [N·m·s/rad] viscous friction, ``omega0`` [rad/s]
    and ``i0`` [A] initial speed and current.
    """
    loop = ["p", "n", "res", "gy"]
    rotor = ["gy", "shaft"]
    children = {"res": mp.R(r=_R, dom="electrical"), "gy": GY(_k, "electrical", "rotational")}
    connections = [["loop.res", "res.p"], ["loop.gy", "gy.a"], ["gy.b", "rotor.gy"]]
    params = {"k": k, "R": R}
    if not literal_zero(L):
        loop.append("coil")
        children["coil"] = I(J=_L, dom="electrical", p0=_L * sp.Symbol("i0"))
        connections.append(["loop.coil", "coil.p"])
        params.update(L=L, i0=i0)
    if not literal_zero(J):
        rotor.append("inertia")
        children["inertia"] = I(J=_J, dom="rotational", p0=_J * sp.Symbol("omega0"))
        connections.append(["rotor.inertia", "inertia.p"])
        params.update(J=J, omega0=omega0)
    if not literal_zero(d):
        rotor.append("friction")
        children["friction"] = mp.R(r=_d, dom="rotational")
        connections.append(["rotor.friction", "friction.p"])
        params["d"] = d
    # series loop: i into p, out of n, through every branch; e_p - e_n = sum of the branch voltages
    children["loop"] = junction_b(loop, "electrical", [1, -1] + [-1] * (len(loop) - 2))
    children["rotor"] = junction_b(rotor, "rotational")
    ports = {"elec": "loop.p", "shaft": "rotor.shaft"}
    if grounded:
        children["ground"] = Se(0, "electrical")
        connections.append(["loop.n", "ground.p"])
    else:
        ports["elec_n"] = "loop.n"
    quantities = {
        "omega": Quantity(lambda V: V.f("rotor.shaft")),
        "current": Quantity(lambda V: V.f("loop.p")),
        "torque": Quantity(lambda V: -V.e("gy.b")),
        "back_emf": Quantity(lambda V: V.e("gy.a")),
        "voltage": Quantity(lambda V: V.e("loop.p") - V.e("loop.n")),
    }
    return Network("dc_motor", children, connections, ports, params=params, quantities=quantities,
                   doc="DC motor: gyrator k with R, L (electrical) and J, d (rotor)")
