"""Piezo element and piezo stack translator (Weber §6, eqs. (50)–(55), Bild 34–38).

Longitudinal effect only, linear (or linearised about the operating point).

``piezo_element`` — the eight-pole of Weber Bild 36, built from primitives::

    mech_a ──┤ gap (type a) ├── tip (type b) ── mech_b          translational
                   │                 │
                field.p1          mass (I, m)
                   │
                 field  (CField, compliance [[delta_P, k_P], [k_P, C_P]])
                   │
                field.p2
                   │
    elec_a ──┤ loop (type b) ├── elec_b                          electrical
                   │
                 res (R)

* Mechanical side: the type-a junction ``gap`` carries the same force through the element (the
  force at the base is minus the force behind the tip mass) and adds the element's own extension
  ``Δs*`` to the motion of the base: ``s1 = s0 + Δs*`` (Weber (51)/(52)).  The field's mechanical
  effort is the tension ``T`` (positive when the element is pulled), its displacement the
  extension ``Δs* = delta_P·T + k_P·U``.
* Moving mass: Weber (53) ``(−F0) = F1 − m·a1`` accelerates the mass with the tip, ``a1 = s̈1``.
  So the mass sits at the tip, between the active part and ``mech_b`` (type-b junction ``tip``);
  the active part carries ``T = F1 − m·a1 = −F0`` and the extension is ``delta_P·T + k_P·U``.
  In statics (``a1 = 0``) this is exactly Weber's (52) with ``F1``; in dynamics it is the force
  that actually reaches the active part, the one (53) passes on to the base.
* Electrical side: the kernel's electrical ports are pins (potentials), so the two electrodes are
  ``elec_a`` (+) and ``elec_b`` (−); one current ``I`` flows in at ``elec_a`` and out at
  ``elec_b`` (type-b junction ``loop``) through the series resistance ``R`` into the field:
  ``e_a − e_b = R·I + U`` (Weber (55)), ``U`` the voltage on the piezo capacitance and
  ``Q' = I`` its charge, ``Q = k_P·T + C_P·U`` (Weber (50)/(54)).  Weber's electrical type-a
  junction ("charges add at common voltage") is the electrical node an element's pin joins: in the
  stack it is the bus that connects all ``elec_a`` (and all ``elec_b``) in parallel.

Signs (Weber's convention, DESIGN §4): the force at a port acts on the element; positive
direction from ``mech_a`` (base) to ``mech_b`` (tip), so a pull on the tip is a positive tension.
Positive voltage ``e_a − e_b`` extends the element (``k_P > 0``); a positive tension pushes
positive charge ``k_P·T`` in at ``elec_a`` when the electrodes are shorted, and with open
electrodes (``Q = 0``) gives ``U = −k_P·T/C_P``.

``m = 0`` (literal) leaves the mass out (Weber Bild 11: the force passes straight through);
``R = 0`` (literal) leaves the resistor out.

``piezo_stack`` — Weber Bild 37/38: ``n`` ``piezo_element`` networks, mechanically in series (tip
of element k on the base of element k+1: the same force, the extensions add) and electrically in
parallel through two type-a junctions ``plus``/``minus`` (the same voltage, the charges add).
"""
from __future__ import annotations

from dataclasses import replace

import sympy as sp

import multipole as mp
from multipole import CField, I, ModelError, Network, Param, Quantity, Reduction, element, junction_a, junction_b

MAX_STACK = 100      # largest piezo_stack n a netlist may ask for (checked by the loader)


def literal_zero(value) -> bool:
    """True for a literal zero parameter (not for a scene parameter that happens to be zero)."""
    return sp.sympify(value).is_zero is True


_PORTS = {"mech_a": "translational: base (Weber port 0); force on the element, velocity of the base",
          "mech_b": "translational: tip (Weber port 1); the moving mass m moves with it",
          "elec_a": "electrical: positive electrode (current into it charges the element)",
          "elec_b": "electrical: negative electrode"}
_PARAMS = [
    Param("k_P", "m/V = C/N", "piezo constant: extension per volt = charge per newton (reciprocal)", nonzero=True),
    Param("delta_P", "m/N", "compliance at constant voltage (shorted); open: delta_P - k_P^2/C_P", positive=True),
    Param("C_P", "F", "capacitance at constant force (free); blocked: C_P - k_P^2/delta_P", positive=True),
    Param("m", "kg", "moving mass at the tip (literal 0: massless, Weber Bild 11)", 0.0, nonnegative=True),
    Param("R", "Ohm", "series resistance of electrodes and leads (literal 0: ideal)", 0.0, nonnegative=True),
]
_S = {p.name: sp.Symbol(p.name) for p in _PARAMS}        # the element's parameters as symbols
_TERMINALS = {"voltage": "V: terminal voltage e(elec_a) - e(elec_b)", "current": "A: current into elec_a"}


@element("piezo_element",
         "piezo element (Weber (50)-(55)): s1 = s0 + k_P*U + delta_P*T, Q = k_P*T + C_P*U, "
         "(-F0) = F1 - m*a1, U_terminal = U + R*I",
         _PORTS, _PARAMS,
         {"stroke": "m: extension s1 - s0 (Weber Δs*)",
          "force": "N: tension in the active part, (-F0) of Weber (53); = force at mech_b in statics",
          "charge": "C: charge that entered at elec_a (Weber ΔQ*)", **_TERMINALS,
          "field_voltage": "V: voltage U on the piezo capacitance (terminal voltage minus R*I)"})
def piezo_element(k_P, delta_P, C_P, m, R) -> Network:
    """One piezo element (Weber Bild 36) with ports mech_a, mech_b, elec_a, elec_b.

    ``k_P`` [m/V = C/N] piezo constant, ``delta_P`` [m/N] compliance at constant voltage (shorted
    electrodes), ``C_P`` [F] capacitance at constant force (mechanically free; blocked it is
    ``C_P − k_P²/delta_P``), ``m`` [kg] moving mass at the tip,
    ``R`` [Ω] series resistance of the electrodes and leads.
    """
    S = sp.Matrix([[_S["delta_P"], _S["k_P"]], [_S["k_P"], _S["C_P"]]])
    resistive = not literal_zero(R)
    loop_ports = ["a", "b", "field"] + (["res"] if resistive else [])
    children = {
        "gap": junction_a(["base", "tip", "field"], "translational", [1, -1, 1]),
        "field": CField(S, ["translational", "electrical"]),
        "loop": junction_b(loop_ports, "electrical", [1, -1] + [-1] * (len(loop_ports) - 2)),
    }
    connections = [["gap.field", "field.p1"], ["loop.field", "field.p2"]]
    ports = {"mech_a": "gap.base", "mech_b": "gap.tip", "elec_a": "loop.a", "elec_b": "loop.b"}
    params = {"k_P": k_P, "delta_P": delta_P, "C_P": C_P}
    if not literal_zero(m):
        children["tip"] = junction_b(["active", "out", "mass"], "translational", [1, 1, 1])
        children["mass"] = I(J=_S["m"], dom="translational")
        connections += [["gap.tip", "tip.active"], ["tip.mass", "mass.p"]]
        ports["mech_b"] = "tip.out"
        params["m"] = m
    if resistive:
        children["res"] = mp.R(r=_S["R"], dom="electrical")
        connections.append(["loop.res", "res.p"])
        params["R"] = R
    quantities = {
        "stroke": Quantity(lambda V: V.x("field.q1")),
        "force": Quantity(lambda V: V.e("field.p1")),
        "charge": Quantity(lambda V: V.x("field.q2")),
        "field_voltage": Quantity(lambda V: V.e("field.p2")),
        "voltage": Quantity(lambda V: V.e("loop.a") - V.e("loop.b")),
        "current": Quantity(lambda V: V.f("loop.a")),
    }
    return Network("piezo_element", children, connections, ports, params=params, quantities=quantities,
                   doc="Weber Bild 36: piezo element with tip mass and electrode resistance")


def _scaled(value, factor: float):
    """``value`` (a number or a netlist expression) times ``factor``."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value * factor
    return f"({value})*{factor!r}"


def _lumped(entry: dict, _level=None) -> dict | None:
    """A piezo_stack netlist entry as one element (``multipole reduce``): n elements in series
    mechanically and in parallel electrically have, quasi-statically, the stroke, compliance,
    capacitance and charge of one element with ``n·k_P``, ``n·delta_P``, ``n·C_P`` and ``R/n``; the
    tip masses (the k-th moves with k/n of the stroke) count with their kinetic energy in that
    shape, ``m·(n+1)(2n+1)/(6n)``.  None where n is not a literal whole number above 1."""
    n = entry.get("n")
    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        return None
    out = dict(entry, n=1)
    for name, factor in (("k_P", n), ("delta_P", n), ("C_P", n), ("R", 1.0 / n),
                         ("m", (n + 1) * (2 * n + 1) / (6.0 * n))):
        if name in entry:
            out[name] = _scaled(entry[name], factor)
    return out


@element("piezo_stack",
         "piezo stack translator (Weber Bild 38): n piezo_elements, mechanically in series, "
         "electrically in parallel",
         _PORTS, [Param("n", "-", "number of elements (whole number)", positive=True, maximum=MAX_STACK)] +
         [replace(p, doc=p.doc + " (of one element)") for p in _PARAMS],
         {"stroke": "m: extension of the stack, the sum of the elements' strokes",
          "force": "N: tension in the base element, (-F0) at mech_a",
          "charge": "C: charge that entered at elec_a (sum over the elements)", **_TERMINALS},
         reductions=(Reduction("lumped", adapt=_lumped),))
def piezo_stack(n, k_P, delta_P, C_P, m, R) -> Network:
    """``n`` piezo elements, mechanically in series and electrically in parallel (Weber Bild 38).

    The parameters are those of one element (see :func:`piezo_element`); the stack has the same
    ports.  Expected behaviour: stroke ``n·k_P·U``, charge ``n·k_P·F``, capacitance ``n·C_P``,
    compliance ``n·delta_P``.
    """
    count = sp.sympify(n)
    if count.free_symbols or not count.is_number or count != int(count) or int(count) < 1:
        raise ModelError("bad_value", f"piezo_stack: n must be a whole number >= 1, got {n}",
                         "give the number of elements as a literal integer, e.g. n: 20")
    count = int(count)
    names = [f"e{k + 1}" for k in range(count)]
    params = {"k_P": k_P, "delta_P": delta_P, "C_P": C_P, "m": m, "R": R}
    # literal zeros go to the elements as zeros (so they leave the mass/resistor out)
    inner = {k: (0 if literal_zero(v) else _S[k]) for k, v in params.items()}
    children = {name: piezo_element(inner["k_P"], inner["delta_P"], inner["C_P"], inner["m"], inner["R"])
                for name in names}
    children["plus"] = junction_a(["ext"] + names, "electrical")
    children["minus"] = junction_a(["ext"] + names, "electrical")
    connections = [[f"{a}.mech_b", f"{b}.mech_a"] for a, b in zip(names, names[1:])]
    connections += [[f"plus.{name}", f"{name}.elec_a"] for name in names]
    connections += [[f"minus.{name}", f"{name}.elec_b"] for name in names]
    ports = {"mech_a": f"{names[0]}.mech_a", "mech_b": f"{names[-1]}.mech_b",
             "elec_a": "plus.ext", "elec_b": "minus.ext"}

    def total(name):
        return lambda V: sp.Add(*[V.quantity(f"{el}.{name}") for el in names])

    quantities = {
        "stroke": Quantity(total("stroke")),
        "force": Quantity(lambda V: V.quantity(f"{names[0]}.force")),
        "charge": Quantity(total("charge")),
        "voltage": Quantity(lambda V: V.e("plus.ext") - V.e("minus.ext")),
        "current": Quantity(lambda V: V.f("plus.ext")),
    }
    # Without electrode resistance the parallel fields share one voltage, without masses the series
    # fields share one force: the analyser puts the surplus field states into derivative causality
    # and chooses them itself (no prefer_state: which ones depends on what drives the stack, e.g. the
    # charges of an open stack must keep their sum integrated).
    return Network("piezo_stack", children, connections, ports,
                   params={k: v for k, v in params.items() if not literal_zero(v)}, quantities=quantities,
                   doc="Weber Bild 38: piezo stack translator")
