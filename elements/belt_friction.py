"""Friction belt drives: a pulley whose belt may slip on it (Euler-Eytelwein, issue 13).

The ``belt_pulley`` joins two ``band`` spans (ports ``e1``, ``e2``, the band bundle of
``multipole.domains``) like a ``band_roll``, but the belt on its wrap is a body of its own: the
belt arc (mass ``m``, the belt on the wrap, speed ``u`` along the pulley's surface) and the pulley
(inertia ``J``, angular velocity ``omega``) are joined by the friction of the wrap, a force ``F_c``
on the arc against the relative speed ``slip = u - r*omega``.  The arc obeys

    m u' = w (F1 - F2) - F_c,        J omega' = r F_c + T_drive,

and carries the material: speed ``w u`` out of the wrap into the span at ``e1``, ``-w u`` at ``e2``
(the wound lengths are ``+-w`` times the arc's travel).

Friction law (Euler-Eytelwein): sliding over the whole wrap ``beta`` of a massless belt holds the
tension ratio at ``F_tight/F_slack = exp(mu beta)``; with ``F_tight - F_slack = F_c`` this is the
force limit ``F_lim = (F1 + F2) tanh(mu beta/2)``, written without knowing which side is tight.
The contact sticks below it and slips at it:

    F_c = F_lim * max(-1, min(1, slip/v_s))

Stick is the middle branch: a steep viscous law whose relative speed never exceeds the creep
speed ``v_s`` [m/s] (a parameter, 1e-4 m/s by default); slip is the outer branches, the force at
the limit.  ``max``/``min`` are switching laws, so the change of mode is an event of the run,
located at ``slip = +-v_s``, i.e. where the tension ratio reaches ``exp(mu beta)`` (up to the
arc's inertia ``m u'``).  Why not an exact rigid stick: in stick the belt's speed is the
pulley's, in slip it is fixed by the ratio condition on the two spans' tensions (a constraint on
the neighbours' states); the kernel keeps one causal structure for a whole run, so the stick
phase is the steep viscous branch instead; its error (the creep, at most ``v_s``) is measured in
``docs/belts.md``.  Each onset of slip is reported as the run-time monitor ``belt_slips``
(``Result.monitors``: time, pulley, code).
"""
from __future__ import annotations

import sympy as sp

from multipole import I, R, TF, ModelError, Monitor, Network, Param, Quantity, Se, Tap, element, junction_a, junction_b

_S = sp.Symbol
_BAND = "band bundle (l: tension [N] / material speed [m/s], wound length [m]; gamma: inclination [rad])"


def _limit(mu, beta):
    """``tanh(mu beta / 2)``: the friction force limit per unit of ``F1 + F2`` (Euler-Eytelwein)."""
    return sp.tanh(mu * beta / 2)


def _grip(slip, v_s):
    """``max(-1, min(1, slip/v_s))``: the friction force over its limit (+-1: slipping)."""
    return sp.Max(-1, sp.Min(1, slip / v_s))


@element("belt_pulley", "friction belt pulley (Euler-Eytelwein): belt arc of mass m on a pulley of inertia J, "
         "joined by wrap friction limited to (F1 + F2) tanh(mu*wrap/2); stick (|slip| < v_s) and slip are "
         "modes switched by events",
         {"e1": f"band port 1 ({_BAND})", "e2": f"band port 2 ({_BAND})",
          "drive": "1-D rotational port on the pulley (angular velocity [rad/s], torque on the pulley [N*m])"},
         [Param("r", "m", "pulley radius (to the belt's neutral layer)", 0.05, positive=True),
          Param("J", "kg*m^2", "moment of inertia of the pulley about its axis", 1e-3, positive=True),
          Param("mu", "-", "friction coefficient between belt and pulley", 0.3, nonnegative=True),
          Param("wrap", "rad", "wrap angle beta of the belt on the pulley", 3.141592653589793, positive=True),
          Param("m", "kg", "mass of the belt on the wrap (linear density * r * wrap)", 0.01, positive=True),
          Param("v_s", "m/s", "creep speed: largest relative speed while the contact sticks", 1e-4, positive=True),
          Param("phi0", "rad", "initial pulley angle", 0.0),
          Param("omega0", "rad/s", "initial angular velocity (the belt arc starts at r*omega0: sticking)", 0.0),
          Param("w", "-", "winding sense: +1: belt moving with a positive rotation leaves at e1 (enters at e2)", 1.0)],
         {"phi": "rad: pulley angle", "omega": "rad/s: pulley angular velocity",
          "speed": "m/s: belt speed u on the wrap (along the pulley surface, positive with omega)",
          "slip": "m/s: relative speed of the belt on the pulley u - r*omega (|slip| < v_s: sticking)",
          "grip": "-: friction force over its limit, F_c/F_lim in [-1, 1] (+-1: slipping)",
          "slipping": "-: 1 while the contact slips (|slip| >= v_s), 0 while it sticks",
          "friction": "N: friction force F_c of the pulley on the belt arc, against the slip",
          "limit": "N: friction force limit F_lim = (F1 + F2) tanh(mu*wrap/2)",
          "torque": "N*m: torque of the belt on the pulley r*F_c",
          "F1": "N: band tension at e1", "F2": "N: band tension at e2"})
def belt_pulley(r, J, mu, wrap, m, v_s, phi0, omega0, w):
    """Friction belt pulley [r in m, J in kg*m^2, wrap in rad, m in kg, v_s in m/s]."""
    if w not in (1, -1):
        raise ModelError("bad_winding", f"belt_pulley: w = {w!r} must be +1 or -1",
                         "+1: belt moving with a positive rotation leaves the pulley at e1")
    ws = int(w)
    F1, F2, slip = _S("F1"), _S("F2"), _S("f")
    F_lim = (F1 + F2) * _limit(_S("mu"), _S("wrap"))
    children = {
        # belt arc: common speed u; material speed w*u out at e1, -w*u at e2
        "A": junction_b(["e1", "e2", "arc", "x", "s"], "translational", [ws, -ws, 1, 1, 1]),
        "arc": I(J=_S("m"), dom="translational", p0=_S("m") * _S("r") * _S("omega0")),
        "s": Tap("translational"),
        # relative speed: f_fr = u - r*omega, one force F_c on arc and pulley surface
        "D": junction_a(["x", "y", "fr"], "translational", [1, -1, -1]),
        "fr": R(law=F_lim * _grip(slip, _S("v_s")), dom="translational"),
        "T": TF(_S("r"), "translational", "rotational"),
        # pulley: common omega
        "W": junction_b(["drive", "J", "tap", "t"], "rotational"),
        "J": I(J=_S("J"), dom="rotational", p0=_S("J") * _S("omega0")),
        "tap": Tap("rotational", q0=_S("phi0")),
        "g1": Se(0, "rotational"), "g2": Se(0, "rotational")}
    connections = [["A.arc", "arc.p"], ["A.s", "s.p"], ["A.x", "D.x"], ["D.fr", "fr.p"], ["D.y", "T.a"],
                   ["T.b", "W.t"], ["W.J", "J.p"], ["W.tap", "tap.p"]]
    ports = {"e1.l": "A.e1", "e1.gamma": "g1.p", "e2.l": "A.e2", "e2.gamma": "g2.p", "drive": "W.drive"}
    s = _S("s")
    params = {"r": r, "J": J, "mu": mu, "wrap": wrap, "m": m, "v_s": v_s, "phi0": phi0, "omega0": omega0}
    q = {"phi": Quantity(lambda V: V.x("tap.q")), "omega": Quantity(lambda V: V.f("W.drive")),
         "speed": Quantity(lambda V: V.f("A.arc")), "slip": Quantity(lambda V: V.f("fr.p")),
         "friction": Quantity(lambda V: V.e("fr.p")),
         "limit": Quantity(lambda V: (V.e("A.e1") + V.e("A.e2")) * _limit(V.param("mu"), V.param("wrap"))),
         "grip": Quantity(lambda V: _grip(V.f("fr.p"), V.param("v_s"))),
         "slipping": Quantity(lambda V: sp.Heaviside(sp.Abs(V.f("fr.p")) - V.param("v_s"), 1)),
         "torque": Quantity(lambda V: V.param("r") * V.e("fr.p")),
         "F1": Quantity(lambda V: V.e("A.e1")), "F2": Quantity(lambda V: V.e("A.e2"))}
    # reported in Result.monitors each time the contact starts to slip: where |slip| passes 1.01 v_s,
    # just after the switch (a monitor crossing zero at the switch's own root makes the driver chatter)
    slips = Monitor(1.01 - sp.Abs(_S("slip")) / _S("v_s"), "belt_slips",
                    "the belt starts slipping on the pulley: the tension ratio reached exp(mu*wrap)")
    return Network("belt_pulley", children, connections, ports, params, q,
                   signals={"s": "s.q", "F1": "A.e1.e", "F2": "A.e2.e", "slip": "fr.p.f"},
                   bundles={"e1": "band", "e2": "band"},
                   positions={"e1.l": ws * s, "e2.l": -ws * s}, fixed=("e1.gamma", "e2.gamma"),
                   monitors=[slips])
