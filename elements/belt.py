"""Belts, bands and ropes after Ebert (2015), first version: straight spans along fixed lines.

Band-type and roll-type elements meet at ``band`` bundle ports (``multipole.domains``): the
component ``l`` is a power bond, effort = band tension F [N] as seen by the element (the roll
side feels +F, the span side -F: each feels the force in the direction of the material flow),
flow = material speed [m/s] from the roll into the span; its integral, the wound length l_r [m]
(0 at t = 0, > 0 when band leaves the roll), is the position the roll provides.  The component
``gamma`` carries the inclination angle of the span [rad] (a position the span provides) and no
torque.  A band connection is point-to-point (``band_branching`` otherwise).

Restrictions of this version (documented in ``docs/belts.md``): every span keeps its direction (its
inclination ``gamma`` is a parameter) and its end points move along one global line (1-D ports
``p1``/``p2``, the component of the end-point velocity along that line, held when unconnected);
the wrap is fixed; a roll's axis is the node its spans' end ports are joined to.  This covers
pulley blocks with parallel ropes and belt drives with fixed axes; planar spans and rolls on
linkages are ``elements/belt_planar.py``.

The wound length is Ebert's corrected (4.95): l_r = w*r*(phi - phi0) at e1 and -w*r*(phi - phi0)
at e2 (w = +1: a positive roll rotation pays band out at e1 and winds it in at e2); the span's
stretch is the corrected (4.54), delta = l_B - l_x with the free length l_x = l0 + l_r1 + l_r2,
so band wound onto a roll (l_r < 0) raises the tension.
"""
from __future__ import annotations

import sympy as sp

from multipole import C, I, R, TF, ModelError, Monitor, Network, Param, Quantity, Se, Sf, Tap, element, junction_a, junction_b

_S = sp.Symbol
_BAND = "band bundle (l: tension [N] / material speed [m/s], wound length [m]; gamma: inclination [rad])"


@element("band", "elastic band span (Ebert 4.4.1, corrected): tension-only Kelvin-Voigt band between the "
         "end points P1 and P2, stiffness EA/l_x, pretension through the free length l0",
         {"e1": f"band end at P1 ({_BAND}); held (band tied) if not connected",
          "e2": f"band end at P2 ({_BAND}); held (band tied) if not connected",
          "p1": "1-D translational: P1 along the global line (velocity [m/s], force on the band [N]); "
                "frame-fixed if not connected",
          "p2": "1-D translational: P2 along the global line; frame-fixed if not connected"},
         [Param("EA", "N", "axial stiffness times length (k = EA/l_x)", 1e5, positive=True),
          Param("cd", "N*s", "axial damping times length (b = cd/l_x)", 0.0, nonnegative=True),
          Param("l", "m", "geometric span length |P1P2| at t = 0", 1.0, positive=True),
          Param("l0", "m", "free (unstretched) length at t = 0; None: l (no pretension)", None),
          Param("dir", "-", "+1 if P2 lies in the positive direction of the global line from P1, -1 if not",
                1.0),
          Param("gamma", "rad", "inclination angle of the span P1 -> P2 (handed to the rolls)", 0.0)],
         {"F": "N: band tension (>= 0)", "stretch": "m: l_B - l_x (> 0 taut, <= 0 slack)",
          "length": "m: geometric span length l_B", "free": "m: free length l_x = l0 + l_r1 + l_r2",
          "lr1": "m: wound length delivered at e1", "lr2": "m: wound length delivered at e2",
          "rate": "m/s: stretch rate d(l_B - l_x)/dt"})
def band(EA, cd, l, l0, dir, gamma):
    """Elastic band span [EA in N, cd in N*s, lengths in m, gamma in rad]."""
    l0 = l if l0 is None else l0
    if isinstance(l0, (int, float, sp.Number)) and float(l0) <= 0:
        raise ModelError("bad_length", f"band: free length l0 = {l0!r} m must be > 0",
                         "give the unstretched length of the span in metres (None: the span length l)")
    if dir not in (1, -1):
        raise ModelError("bad_direction", f"band: dir = {dir!r} must be +1 or -1",
                         "+1 if P2 lies in the positive direction of the global line from P1")
    d, lr1, lr2 = int(dir), _S("lr1"), _S("lr2")
    lx = _S("l0") + lr1 + lr2
    children = {
        # common tension: e_p1 = -d*F, e_p2 = +d*F, e_e1 = e_e2 = -F; flows sum: x carries delta'
        "J": junction_a(["p1", "p2", "e1", "e2", "x"], "translational", [-d, d, -1, -1, -1]),
        "K": junction_b(["x", "c", "r"], "translational"),
        **span_law(_S("EA") / lx, _S("cd") / lx, _S("l") - _S("l0"), damped=not sp.sympify(cd).is_zero),
        "g1": Sf(0, "rotational"), "g2": Sf(0, "rotational")}
    connections = [["J.x", "K.x"], ["K.c", "c.p"], ["K.r", "r.p"]]
    ports = {"e1.l": "J.e1", "e1.gamma": "g1.p", "e2.l": "J.e2", "e2.gamma": "g2.p", "p1": "J.p1", "p2": "J.p2"}
    params = {"EA": EA, "cd": cd, "l": l, "l0": l0, "dir": d, "gamma": gamma}
    q_ = {"F": Quantity(lambda V: -V.e("J.x")),
          "stretch": Quantity(lambda V: V.x("c.q")),
          "free": Quantity(lambda V: V.param("l0") + V.param("lr1") + V.param("lr2")),
          "length": Quantity(lambda V: V.param("l0") + V.param("lr1") + V.param("lr2") + V.x("c.q")),
          "lr1": Quantity(lambda V: V.param("lr1")), "lr2": Quantity(lambda V: V.param("lr2")),
          "rate": Quantity(lambda V: V.f("c.p"))}
    return Network("band", children, connections, ports, params, q_, signals={"delta": "c.q"},
                   bundles={"e1": "band", "e2": "band"},
                   positions={"e1.gamma": _S("gamma"), "e2.gamma": _S("gamma")},
                   reads={"lr1": ("e1.l", 0), "lr2": ("e2.l", 0)},
                   fixed=("e1.l", "e2.l", "p1", "p2"))


def span_law(k, b, q0, damped=True) -> dict:
    """The tension-only Kelvin-Voigt law of a span, children ``c`` and ``r`` of its stretch junction.

    ``c``: the spring, force ``k*max(delta, 0)`` [N] of its state ``delta`` [m] (the stretch, start
    value ``q0``; the network names it as signal ``delta``); ``r``: the damper ``b*delta'`` while
    ``delta > 0``, clamped so that the tension never turns compressive.  ``k`` [N/m], ``b`` [N*s/m]
    are expressions of the network's local names.  ``damped=False`` (damping 0): no damper law at
    all; its clamp would switch at the same root as the spring (q and k q), and two switches
    crossing at one instant chatter at the slack onset."""
    q, f = _S("delta"), _S("f")
    return {"c": C(law=k * sp.Max(q, 0), dom="translational", q0=q0),
            "r": R(law=sp.Heaviside(q) * sp.Max(-k * q, b * f) if damped else 0, dom="translational")}


def _roll(kind: str, sides: int, r, J, phi0, omega0, w, mu, r_pin, wrap, contact=None, reads=None,
          mu_c=None, stored=None) -> Network:
    """A roll with ``sides`` band ports (2: roll, 1: drum): no-slip winding, inertia J.

    ``contact(k)``: (lever arm [m], wound length [m]) at band port k as expressions of the local
    names (the roll angle ``phi``, ``reads``); default: the circle of radius ``r`` (a curve roll,
    ``elements/belt_contour.py``, gives its contour's and leaves ``r`` None).  Run-time monitors
    (:func:`_monitors`): ``mu_c`` the capstan limit, ``stored`` a drum's rope, a ``wrap`` that is
    not a constant its lift-off."""
    if w not in (1, -1):
        raise ModelError("bad_winding", f"{kind}: w = {w!r} must be +1 or -1",
                         "+1: a positive rotation pays band out at e1 (and winds it in at e2)")
    phi, ws = _S("phi"), int(w)
    F1, F2 = _S("F1"), _S("F2")
    # the wrap angle: a parameter, or an expression of the roll's local names (a wrap that changes)
    moving_wrap = sides == 2 and not isinstance(wrap, (int, float, sp.Number))
    beta = wrap if moving_wrap else _S("wrap")
    # the resultant of the two band forces on the roll: |F1 e1 + F2 e2| with the angle between the
    # span directions pi - wrap (parallel spans for wrap = pi: F1 + F2); a drum carries F1 only
    radial_load = sp.Abs(F1) if sides == 1 else sp.sqrt(F1 ** 2 + F2 ** 2 - 2 * F1 * F2 * sp.cos(beta))
    names = ["drive", "J", "tap"] + [f"t{k}" for k in range(1, sides + 1)] + ["fric"]
    children = {"J": I(J=_S("J"), dom="rotational", p0=_S("J") * _S("omega0")), "tap": Tap("rotational", q0=_S("phi0"))}
    connections = [["W.J", "J.p"], ["W.tap", "tap.p"]]
    if isinstance(mu, (int, float)) and mu == 0:        # frictionless: no switching function
        names.remove("fric")
    else:
        children["fric"] = R(law=_S("mu") * _S("r_pin") * radial_load * sp.sign(_S("f")), dom="rotational")
        connections.append(["W.fric", "fric.p"])
    children["W"] = junction_b(names, "rotational")
    ports, positions, fixed = {"drive": "W.drive"}, {}, []
    for k in range(1, sides + 1):
        sign = ws if k == 1 else -ws
        lever, wound = contact(k) if contact else (_S("r"), _S("r") * (phi - _S("phi0")))
        children[f"T{k}"] = TF(sign * lever, "translational", "rotational")
        children[f"g{k}"] = Se(0, "rotational")
        connections.append([f"T{k}.b", f"W.t{k}"])
        ports.update({f"e{k}.l": f"T{k}.a", f"e{k}.gamma": f"g{k}.p"})
        positions[f"e{k}.l"] = sign * wound
        fixed.append(f"e{k}.gamma")
    params = ({} if r is None else {"r": r}) | {"J": J, "phi0": phi0, "omega0": omega0, "w": ws, "mu": mu,
                                                "r_pin": r_pin}
    if sides == 2 and not moving_wrap:
        params["wrap"] = wrap
    monitors = _monitors(sides, beta if sides == 2 else None, moving_wrap, mu_c, stored, positions.get("e1.l"), params)
    q = {"phi": Quantity(lambda V: V.x("tap.q")), "omega": Quantity(lambda V: V.f("W.drive")),
         "F1": Quantity(lambda V: V.e("T1.a")),
         "friction": Quantity(lambda V: V.e("fric.p") if "fric" in children else sp.Integer(0))}
    if sides == 2:
        q["F2"] = Quantity(lambda V: V.e("T2.a"))
    signals = {"phi": "tap.q"} | {f"F{k}": f"T{k}.a.e" for k in range(1, sides + 1)}
    return Network(kind, children, connections, ports, params, q, signals=signals,
                   bundles={f"e{k}": "band" for k in range(1, sides + 1)}, positions=positions, fixed=fixed,
                   reads=reads, monitors=monitors)


def _monitors(sides: int, beta, moving_wrap: bool, mu_c, stored, paid_out, params: dict) -> list:
    """The run-time monitors of a roll (docs/belts.md, "Monitors"); adds their parameters to ``params``.

    * ``band_lifts_off``: the wrap angle ``beta`` [rad] falls to 0 (only a wrap that is an
      expression of the motion can: a constant wrap is checked at load time);
    * ``capstan_limit`` (``mu_c`` given): one band tension exceeds e^(mu_c*wrap) times the other, so
      a real band would slip on the roll (Euler-Eytelwein); the no-slip model goes on;
    * ``drum_paid_out`` (``stored`` given, a drum): the wound-out length at e1 [m] passes the rope
      stored on the drum at t = 0: the rope end would tear off its anchor; the run stops."""
    out = []
    F1, F2 = _S("F1"), _S("F2")
    if moving_wrap:
        out.append(Monitor(beta, "band_lifts_off", "the wrap angle fell to 0: the band lifts off the roll"))
    if sides == 2 and mu_c is not None:
        params["mu_c"] = mu_c
        grip = sp.exp(_S("mu_c") * beta)
        for tight, slack, k in ((F1, F2, 1), (F2, F1, 2)):
            out.append(Monitor(grip * slack - tight, "capstan_limit",
                               f"the band tension at e{k} exceeds e^(mu_c*wrap) times the other side's: "
                               "a real band would slip here (the model keeps no-slip)"))
    if sides == 1 and stored is not None:
        params["stored"] = stored
        out.append(Monitor(_S("stored") - paid_out, "drum_paid_out",
                           "paid out all the rope stored on it: the rope end would tear off its anchor", stop=True,
                           fix="store more rope on the drum (parameter stored) or pay out less"))
    return out


_ROLL_PARAMS = [Param("r", "m", "roll radius (to the band's neutral layer)", 0.05, positive=True),
                Param("J", "kg*m^2", "moment of inertia about the axis", 1e-3, positive=True),
                Param("phi0", "rad", "initial roll angle", 0.0),
                Param("omega0", "rad/s", "initial angular velocity", 0.0),
                Param("w", "-", "winding sense: +1: a positive rotation pays band out at e1 (winds in at e2)", 1.0),
                Param("mu", "-", "bearing friction coefficient (torque -mu*r_pin*radial load*sign(omega))", 0.0,
                      nonnegative=True),
                Param("r_pin", "m", "bearing pin radius", 0.004, nonnegative=True)]
_ROLL_QTY = {"phi": "rad: roll angle", "omega": "rad/s: angular velocity",
             "F1": "N: band tension at e1", "friction": "N*m: bearing friction torque (taken from the roll, positive when omega > 0)"}


@element("band_roll", "circular band roll (Ebert 4.4.4, corrected): no-slip winding at radius r, inertia J, "
         "massless housing; bearing friction mu*r_pin*radial",
         {"e1": f"band port 1 ({_BAND})", "e2": f"band port 2 ({_BAND})",
          "drive": "1-D rotational port on the roll (angular velocity [rad/s], torque on the roll [N*m])"},
         _ROLL_PARAMS + [Param("wrap", "rad", "wrap angle (angle between the spans' directions: pi - wrap); "
                               "the radial load is |F1 e1 + F2 e2|", 3.141592653589793, positive=True),
                         Param("mu_c", "-", "band-roll contact friction for the capstan monitor: the run reports "
                               "capstan_limit when one tension exceeds e^(mu_c*wrap) times the other; None: not "
                               "monitored", None, nonnegative=True)],
         _ROLL_QTY | {"F2": "N: band tension at e2"})
def band_roll(r, J, phi0, omega0, w, mu, r_pin, wrap, mu_c):
    """Circular roll [r, r_pin in m, J in kg*m^2, angles in rad]."""
    return _roll("band_roll", 2, r, J, phi0, omega0, w, mu, r_pin, wrap, mu_c=mu_c)


@element("drum", "band drum (Ebert 4.4.4 derived): a circular roll with one band end fixed on it; winds band "
         "in or pays it out at e1", {"e1": f"band port ({_BAND})",
                                      "drive": "1-D rotational port on the drum"},
         _ROLL_PARAMS + [Param("stored", "m", "rope stored on the drum at t = 0 (wound-out length it can pay out "
                               "at e1); paying out more stops the run with drum_paid_out; None: not monitored", None,
                               nonnegative=True)], _ROLL_QTY)
def drum(r, J, phi0, omega0, w, mu, r_pin, stored):
    """Band drum [r in m, J in kg*m^2, angles in rad]."""
    return _roll("drum", 1, r, J, phi0, omega0, w, mu, r_pin, None, stored=stored)
