"""Band spans with a nozzle or a spring after Ebert (2015, §4.4.2, §4.4.3), on planar ports.

Both elements are a band path through points read from planar ports (a linkage output, a roll's
centre port ``c``, or the frame when unconnected): ``nozzle_band`` runs P1 -> P3 -> P2 through an
ideal frictionless eyelet at P3 (ports ``p1``, ``p2``, ``p3``), ``spring_band`` runs straight from P1
to P2.  The ends are points (a band tied to a link or a rope end; no roll radius).  Each straight
section k from point A to point B has its inclination g_k as a state held on the line A -> B by a
closure (``-sin g_k (x_B - x_A) + cos g_k (y_B - y_A) = 0``, solved at every evaluation, never
wrapped), so its unit vector t_k = (cos g_k, sin g_k), its length l_k = t_k . (B - A) and

    l_k' = t_k . (v_B - v_A),        g_k' = n_k . (v_B - v_A) / l_k   (n_k the left normal).

One modulated transformer maps the point velocities to the path's length rate l_B' = sum l_k' and
the inclination rates; its transpose is the force law: the tension F pulls P1 along t_1 (towards
the path), P2 along -t_last and a nozzle P3 with F (t_2 - t_1), the resultant of the two sections
(Ebert 4.72-4.77).  The band ports ``e1``/``e2`` carry the material speed from the roll into the
path (its integral the wound length l_r) and provide the directions in which the path leaves its
ends: gamma at ``e1`` = g_1, at ``e2`` = g_last + pi (as ``planar_band``).

Law.  The stretch delta is a state with delta' = l_B' - l_r1' - l_r2' (the corrected (4.54),
erratum E1: band wound onto a roll raises the tension), the shared tension-only law
:func:`elements.belt.span_law`:

* ``nozzle_band``: the two sections are one elastic band, k = EA/l_x, b = cd/l_x with the free
  length l_x = l_B - delta (E2), delta(0) = l_B(0) - l0 (E3: l0 given; else no pretension);
* ``spring_band``: inextensible sections l_B1, l_B2 [m] and a tension spring k [N/m] with a damper
  b [N*s/m] between them on the line P1-P2 (4.78)-(4.86): the spring length
  l_F = l_BF - (l_B1 + l_r1) - (l_B2 + l_r2), delta = l_F - l0, force k*delta + b*delta' while
  delta > 0 (never compressive), 0 when slack.

Units: SI (m, rad, N, N/m, N*s/m).
"""
from __future__ import annotations

import sympy as sp

from multipole import MTF, Closure, Network, Param, Quantity, Se, Sketch, Tap, element, junction_a, junction_b

from .belt import _BAND, span_law
from .belt_planar import _PLANAR

_S = sp.Symbol
#: sections shorter than 10 um at t = 0 have no direction and are refused
_MIN_SQUARED = 1e-10


def _point_params(points: tuple) -> list:
    """Frame positions of the unconnected points ``points`` (port numbers) [m]."""
    default = {1: (0.0, 0.0), 2: (1.0, 0.0), 3: (0.5, 0.2)}
    return [Param(f"{c}{j}", "m", f"frame position {c} of P{j} when p{j} is not connected", default[j][i])
            for j in points for i, c in enumerate("xy")]


def _path(kind: str, path: tuple, law, params: dict, quantities: dict) -> Network:
    """A band path through the points of the planar ports ``p{j}``, ``j`` in ``path`` (in running
    order, the first at ``e1``, the last at ``e2``), with the stretch law ``law(lb, lb0)`` -> (k, b,
    delta(0), damped) of the current and initial path length [m]; extra ``quantities`` as expressions
    of the reads ``xp{j}``, ``yp{j}``, the inclinations ``g{k}``, the stretch ``delta``, the path length
    ``lB`` and the tension ``Fb``."""
    xy = {j: (_S(f"xp{j}"), _S(f"yp{j}")) for j in path}
    cols = [f"p{j}.{c}" for j in path for c in "xy"]
    n = len(path) - 1
    rows = [[0] * len(cols) for _ in range(n + 1)]
    lb, lb0, closures, children, connections, ports, signals = 0, 0, [], {}, [], {}, {}
    for k in range(n):
        (xa, ya), (xb, yb), g = xy[path[k]], xy[path[k + 1]], _S(f"g{k + 1}")
        dx, dy, c, s = xb - xa, yb - ya, sp.cos(g), sp.sin(g)
        lk = c * dx + s * dy
        lb, lb0 = lb + lk, lb0 + sp.sqrt(dx ** 2 + dy ** 2)
        ia, ib = 2 * k, 2 * k + 2                      # the columns of A and B
        for col, val in ((ia, -c), (ia + 1, -s), (ib, c), (ib + 1, s)):
            rows[0][col] += val
        for col, val in ((ia, s / lk), (ia + 1, -c / lk), (ib, -s / lk), (ib + 1, c / lk)):
            rows[k + 1][col] += val
        ends = (["e1"] if k == 0 else []) + (["e2"] if k == n - 1 else [])
        children[f"G{k + 1}"] = junction_b(["k", "tap"] + ends, "rotational")
        children[f"tap{k + 1}"] = Tap("rotational", q0=sp.atan2(dy, dx))
        connections += [[f"K.a{k + 2}", f"G{k + 1}.k"], [f"G{k + 1}.tap", f"tap{k + 1}.p"]]
        ports |= {f"{e}.gamma": f"G{k + 1}.{e}" for e in ends}
        signals[f"g{k + 1}"] = f"tap{k + 1}.q"
        closures.append(Closure([f"tap{k + 1}.q"], [-s * dx + c * dy],
                                f"section {k + 1} of the band on the line P{path[k]} -> P{path[k + 1]}",
                                conditions=[(dx ** 2 + dy ** 2 - _MIN_SQUARED,
                                             f"section P{path[k]} -> P{path[k + 1]} has no length, hence no direction "
                                             "(sections shorter than 10 um are refused)", "m^2")],
                                guard=(lk, 1e-6, f"length of section P{path[k]} -> P{path[k + 1]}")))
    k_, b_, q0, damped = law(lb, lb0)
    children |= {
        "K": MTF(rows, ["translational"] + ["rotational"] * n, ["translational"] * len(cols)),
        # common tension: e_s = F (the pull on the path), e_e1 = e_e2 = -F; x carries delta'
        "J": junction_a(["s", "e1", "e2", "x"], "translational", [1, -1, -1, -1]),
        "X": junction_b(["x", "c", "r"], "translational"),
        **span_law(k_, b_, q0, damped)}
    connections += [["K.a1", "J.s"], ["J.x", "X.x"], ["X.c", "c.p"], ["X.r", "r.p"]]
    ports |= {"e1.l": "J.e1", "e2.l": "J.e2"} | {col: f"K.b{i + 1}" for i, col in enumerate(cols)}
    for j in path:
        children[f"t{j}"] = Se(0, "rotational")            # the band puts no torque on its points
        ports[f"p{j}.phi"] = f"t{j}.p"
    reads = {f"{c}p{j}": (f"p{j}.{c}", _S(f"{c}{j}")) for j in path for c in "xy"}

    def local(expr):
        """``expr`` in the flattened names: the position reads and the inclination states."""
        return lambda V: sp.sympify(expr).xreplace({_S("lB"): lb}).xreplace(
            {_S(r): V.param(r) for r in reads} | {_S(f"g{k + 1}"): V.x(f"tap{k + 1}.q") for k in range(n)}
            | {_S("delta"): V.x("c.q"), _S("Fb"): V.e("J.s")} | {_S(p): V.param(p) for p in params})

    q = {"F": Quantity(lambda V: V.e("J.s")), "stretch": Quantity(lambda V: V.x("c.q")),
         "length": Quantity(local(lb)), "rate": Quantity(lambda V: V.f("c.p")),
         "gamma1": Quantity(lambda V: V.x("tap1.q")), "gamma2": Quantity(lambda V: V.x(f"tap{n}.q"))}
    q |= {name: Quantity(local(expr)) for name, expr in quantities.items()}
    return Network(kind, children, connections, ports, params, q, signals=signals | {"delta": "c.q"},
                   bundles={"e1": "band", "e2": "band"} | {f"p{j}": "planar" for j in path},
                   positions={"e1.gamma": _S("g1"), "e2.gamma": _S(f"g{n}") + sp.pi}, reads=reads,
                   fixed=("e1.l", "e2.l") + tuple(f"p{j}.{c}" for j in path for c in ("x", "y", "phi")),
                   closures=closures, sketch=[Sketch([xy[j] for j in path], [""] * len(path), style="line")])


_ENDS = {"e1": f"band end at P1 ({_BAND}; gamma: the inclination of the section leaving P1); held (band tied) "
               "if not connected",
         "e2": f"band end at P2 ({_BAND}; gamma: the direction of the section leaving P2); held (band tied) if "
               "not connected",
         "p1": f"end point P1 ({_PLANAR}; the band pulls it, no torque): a linkage output, a roll's port c; "
               "frame-fixed at (x1, y1) if not connected",
         "p2": f"end point P2 ({_PLANAR}); frame-fixed at (x2, y2) if not connected"}
_OUTPUTS = {"F": "N: band tension (>= 0)", "rate": "m/s: stretch rate",
            "gamma1": "rad: inclination of the section leaving P1 (continuous, not wrapped)",
            "gamma2": "rad: inclination of the section arriving at P2, from the P1 end (continuous)"}


@element("nozzle_band", "elastic band through a take-off nozzle (Ebert 4.4.2, corrected): one tension-only "
         "Kelvin-Voigt band on the two sections P1-P3, P3-P2, stiffness EA/l_x; the ideal frictionless "
         "eyelet at P3 takes the resultant of the section tensions",
         _ENDS | {"p3": f"nozzle P3 ({_PLANAR}; takes F (t2 - t1), no torque); frame-fixed at (x3, y3) if not "
                        "connected"},
         [Param("EA", "N", "axial stiffness times length (k = EA/l_x)", 1e5, positive=True),
          Param("cd", "N*s", "axial damping times length (b = cd/l_x)", 0.0, nonnegative=True),
          Param("l0", "m", "free (unstretched) length of the band P1-P3-P2 at t = 0; None: the path length "
                "|P3 - P1| + |P2 - P3| at t = 0 (no pretension)", None, positive=True)]
         + _point_params((1, 2, 3)),
         _OUTPUTS | {"stretch": "m: l_B - l_x (> 0 taut, <= 0 slack)",
                     "length": "m: path length l_B = |P3 - P1| + |P2 - P3|", "free": "m: free length l_x",
                     "Fx3": "N: x force of the band on the nozzle", "Fy3": "N: y force of the band on the nozzle"})
def nozzle_band(EA, cd, l0, x1, y1, x2, y2, x3, y3):
    """Elastic band through a nozzle [EA in N, cd in N*s, lengths in m]."""
    params = {"EA": EA, "cd": cd, "x1": x1, "y1": y1, "x2": x2, "y2": y2, "x3": x3, "y3": y3} | \
        ({} if l0 is None else {"l0": l0})

    def law(lb, lb0):
        lx = lb - _S("delta")
        return _S("EA") / lx, _S("cd") / lx, (0 if l0 is None else lb0 - _S("l0")), not sp.sympify(cd).is_zero

    # the resultant on the nozzle, F (t2 - t1), from the tension and the two section directions
    g1, g2, F = _S("g1"), _S("g2"), _S("Fb")
    return _path("nozzle_band", (1, 3, 2), law, params,
                 {"Fx3": F * (sp.cos(g2) - sp.cos(g1)), "Fy3": F * (sp.sin(g2) - sp.sin(g1)),
                  "free": _S("lB") - _S("delta")})


@element("spring_band", "band with a tension spring (Ebert 4.4.3, corrected): inextensible sections l_B1, l_B2 "
         "and a tension spring k with a damper b between them on the line P1-P2; force only while the spring "
         "is stretched, damping never compressive",
         _ENDS,
         [Param("k", "N/m", "spring rate", 1e3, positive=True),
          Param("b", "N*s/m", "spring damping", 0.0, nonnegative=True),
          Param("l0", "m", "unloaded spring length", 0.1, nonnegative=True),
          Param("lB1", "m", "length of the band section at P1 at t = 0", 0.45, nonnegative=True),
          Param("lB2", "m", "length of the band section at P2 at t = 0", 0.45, nonnegative=True)]
         + _point_params((1, 2)),
         _OUTPUTS | {"stretch": "m: spring extension l_F - l0 (> 0 taut, <= 0 slack)",
                     "length": "m: distance l_BF = |P2 - P1|", "spring": "m: spring length l_F = l0 + stretch"})
def spring_band(k, b, l0, lB1, lB2, x1, y1, x2, y2):
    """Band with a tension spring [k in N/m, b in N*s/m, lengths in m]."""
    params = {"k": k, "b": b, "l0": l0, "lB1": lB1, "lB2": lB2, "x1": x1, "y1": y1, "x2": x2, "y2": y2}

    def law(lb, lb0):
        return _S("k"), _S("b"), lb0 - _S("lB1") - _S("lB2") - _S("l0"), not sp.sympify(b).is_zero

    return _path("spring_band", (1, 2), law, params, {"spring": _S("l0") + _S("delta")})
