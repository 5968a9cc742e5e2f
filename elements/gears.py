"""Weber's spur gear stage and gear trains, built from kernel primitives (Weber 2005, §5.1–5.6).

The stage is a chain two-port: port ``a`` is shaft 1 (wheel radius ``r1``), port ``b`` is shaft 2
(wheel radius ``r2``).  Nothing in here is a hand-written transfer function: each level is the
multipole of Weber's block diagram and the kernel derives the equations.

Structure per level (Weber's Bild numbers):

* ``ideal`` (Bild 19): ``wheel1`` (TF, ω1 = v_u/r1) and ``wheel2`` (TF, ω2 = ∓v_u/r2) joined by a
  rigid node — the special case c⁻¹ = 0 of the cross-coupling.  The kernel gives ω1 = i·ω2 and
  (−M2) = i·M1 with i = −r2/r1 (external) or +r2/r1 (internal ring gear), eqs. (23)–(26).
* ``elastic`` (Bild 21/22): the rigid node becomes a type-a junction ``contact`` (common mesh
  force, relative circumferential velocity) with the mesh spring ``C`` on its third port (and a
  damper in parallel if ``d`` is given).  The stiffness may depend on the mesh phase, which a
  ``Tap`` on shaft 1 integrates (time-varying mesh stiffness, eqs. (27)–(32)).
* ``normal`` (Bild 25): each wheel's circumferential port goes to a type-b junction ``flank1`` /
  ``flank2`` (one velocity per flank, forces add) that splits into a normal branch (TF cos α) and a
  tangential branch (TF ρ_X/r, modulated by the contact position).  The normal branches meet at
  the type-a junction ``contact`` with the tooth normal spring, the tangential branches at the
  type-a junction ``sliding`` with the tooth friction ``R`` (eqs. (33)–(41)).

Sign conventions (docs/weber-gears.md): port efforts are torques acting ON the stage, flows are
angular velocities, both shafts counted positive in the same sense.  The circumferential velocity
v_u is the pitch-point velocity in the direction wheel 1 moves there when it turns positively:
v_u1 = r1·ω1, v_u2 = −r2·ω2 (external) or +r2·ω2 (internal).  The mesh deflection grows with
v_u1 − v_u2 and the mesh force is positive when wheel 1 drives wheel 2 with a positive torque.

Mesh phase: laws of the stiffness ``c``/``c_n`` and the contact position ``s`` are written in the
variable ``q``, the mesh phase q = z1·φ1 [rad] (φ1 the angle of shaft 1 since t = 0 plus
``phase0``/z1).  One tooth engagement is one period 2π of q.  Without ``z1``, q = φ1.
"""
from __future__ import annotations

import math

import sympy as sp

from multipole import (LAW_Q, TF, C, ModelError, Network, Param, Primitive, Quantity, R, Reduction, Tap, element,
                       junction_a, junction_b)

from .basic import inertia

LEVELS = ("ideal", "elastic", "normal")
MAX_STAGES = 20     # longest gear_train a netlist may ask for (checked by the loader)

_R1, _R2, _C, _CN, _D, _X0 = (sp.Symbol(n) for n in ("r1", "r2", "c", "c_n", "d", "x0"))
_Z1, _PHASE0, _ALPHA = (sp.Symbol(n) for n in ("z1", "phase0", "alpha"))
_MU, _VREG, _DT = (sp.Symbol(n) for n in ("mu", "v_reg", "d_t"))
PHI = sp.Symbol("phi")          #: signal: angle of shaft 1 [rad] (integrated by the tap)
QN = sp.Symbol("qn")            #: signal: deflection of the mesh spring [m]

MECH = "translational"


# -- helpers ----------------------------------------------------------------------------------

def mesh_phase_var(expr):
    """Replace the netlist law variable ``q`` (mesh phase) in ``expr`` by ``z1*phi``."""
    expr = sp.sympify(expr)
    return expr.xreplace({s: _Z1 * PHI for s in expr.free_symbols if s.name == "q"})


def depends_on_phase(expr) -> bool:
    return expr is not None and any(s.name == "q" for s in sp.sympify(expr).free_symbols)


def varies(expr) -> bool:
    """True for a law of the mesh phase ``q`` or of the time ``t`` (a stiffness that is no constant)."""
    return expr is not None and any(s.name in ("q", "t") for s in sp.sympify(expr).free_symbols)


def _is_zero(x) -> bool:
    return x is None or (sp.sympify(x).is_number and float(x) == 0.0)


def wheel(radius, sense=1):
    """A wheel body as transducer shaft -> pitch circle: ω = sense·v_u/radius (ports a: rotational, b: translational)."""
    return TF(sense / radius, "rotational", MECH)


def cross_coupling(children: dict, connections: list, junction: str, ports: tuple, stiffness, d):
    """Weber's elastic cross-coupling (Bild 14, plus optional damping) between two velocities.

    Adds a type-a junction ``junction`` with ports ``ports`` = (side 1, side 2): common force,
    deflection rate = f(side 1) − f(side 2), which goes to the spring ``spring`` (a ``C`` with
    ``stiffness`` either a parameter symbol or a law of its displacement; initial deflection the
    parameter ``x0``) — in parallel with a
    damper ``damper`` (``R``, coefficient symbol ``d``) through a type-b junction ``kv`` when ``d``
    is not zero (Kelvin–Voigt).
    """
    p1, p2 = ports
    children[junction] = junction_a([p1, p2, "k"], MECH, [1, -1, -1])
    spring = C(c=stiffness, dom=MECH, q0=_X0) if isinstance(stiffness, sp.Symbol) else \
        C(law=stiffness, dom=MECH, q0=_X0)
    children["spring"] = spring
    if _is_zero(d):
        connections.append([f"{junction}.k", "spring.p"])
        return
    children["kv"] = junction_b(["k", "c", "d"], MECH)
    children["damper"] = R(r=_D, dom=MECH)
    connections += [[f"{junction}.k", "kv.k"], ["kv.c", "spring.p"], ["kv.d", "damper.p"]]


def _stiffness(value, symbol, params):
    """``symbol`` (and its value in ``params``) for a constant, or a C law for a value that depends on
    the mesh phase or on the time."""
    if varies(value):
        return mesh_phase_var(value) * LAW_Q
    params[symbol.name] = value
    return symbol


def _resolver(V):
    """Map the network's symbols in a quantity expression to global symbols."""
    def resolve(expr):
        expr = sp.sympify(expr)
        subs = {}
        for s in expr.free_symbols:
            if s.name == "t":
                continue
            if s == PHI:
                subs[s] = V.x("angle1.q")
            elif s == QN:
                subs[s] = V.x("spring.q")
            else:
                subs[s] = V.param(s.name)
        return expr.xreplace(subs)
    return resolve


def _numeric(*values) -> bool:
    return all(v is not None and sp.sympify(v).is_number for v in values)


class MissingCrossCoupling(Primitive):
    """The end of a branch that Weber's structure needs closed by a cross-coupling the user left out.

    It contributes no equation: unlike an unconnected port (which the kernel terminates as a free
    end, effort 0 — Weber's special case of a resistance-free relative motion, Bild 13), nothing
    here determines the branch's effort or flow, so ``multipole check`` finds the network
    under-determined — exactly Weber's "open arrows" of Bild 25 top.  It is a kernel
    *placeholder*: ``needs`` says what is missing and ``fix`` how to add it, and the analyser
    reports both (code ``missing_cross_coupling``) instead of its generic under-determination.
    """

    kind = "missing"

    def __init__(self, dom, needs: str, fix: str = ""):
        super().__init__({"p": dom}, {}, doc=f"missing cross-coupling: {needs}")
        self.needs = needs
        self.fix = fix

    def relations(self, V):
        return []


# -- declarations ---------------------------------------------------------------------------------

_LAW_DOC = ("a number or an expression of the mesh phase q = z1*phi1 [rad] (one tooth engagement = 2*pi), "
            "e.g. 'c0*(1 + 0.2*cos(q))', or of the time t (parametric excitation, e.g. 'c0*(1 + 0.2*cos(W*t))'), "
            "or a table over one engagement, symmetric about its middle: "
            "'interp(acos(cos(q)), [1.1, 1.4], [c_single, c_double])'")

SPUR_PARAMS = [
    Param("r1", "m", "operating pitch radius of wheel 1 (port a)", positive=True),
    Param("r2", "m", "operating pitch radius of wheel 2 (port b); the ring gear's radius if internal", positive=True),
    Param("level", "", "ideal (rigid TF pair), elastic (mesh spring along the circumference), normal (normal "
          "spring + tangential tooth friction)", "ideal", "choice", LEVELS),
    Param("internal", "", "wheel 2 is an internal ring gear: the shafts turn the same way, i = +r2/r1", False,
          "bool"),
    Param("c", "N/m", "elastic: circumferential mesh stiffness, " + _LAW_DOC, None, "law", law_var="q",
          positive=True),
    Param("c_n", "N/m", "normal: tooth normal stiffness, " + _LAW_DOC, None, "law", law_var="q", positive=True),
    Param("d", "N*s/m", "elastic/normal: mesh damping in parallel with the mesh spring", 0.0),
    Param("x0", "m", "elastic/normal: initial mesh deflection (mounting error, preload)", 0.0),
    Param("z1", "-", "teeth of wheel 1; the mesh phase is q = z1*phi1 (normal: required unless s is given)", None,
          positive=True),
    Param("phase0", "rad", "initial mesh phase q(0)", 0.0),
    Param("alpha", "rad", "normal: operating pressure angle (involute: constant)", math.radians(20.0)),
    Param("s", "m", "normal: contact point on the line of action, measured from the pitch point towards wheel 2's "
          "tangent point, as an expression of the mesh phase q; default: involute single contact "
          "(r1*cos(alpha)/z1)*atan2(sin(q), cos(q))", None, "law", law_var="q"),
    Param("mu", "-", "normal: Coulomb tooth friction coefficient, F_t = mu*|F_n|*tanh(v_t/v_reg) with F_n the "
          "tooth spring force", None, nonnegative=True),
    Param("v_reg", "m/s", "normal: sliding velocity of the Coulomb regularisation", 1e-3, positive=True),
    Param("d_t", "N*s/m", "normal: viscous tooth friction in the tangential branch", None),
]


def _spur_level(entry: dict, level: str) -> dict | None:
    """A spur_stage netlist entry moved to the simpler ``level`` (``multipole reduce``): from
    normal to elastic, the circumferential mesh stiffness and damping are the normal ones projected
    on the circumference, ``c = c_n·cos²(alpha)`` and ``d·cos²(alpha)`` (the normal deflection is
    the circumferential one times cos(alpha), the circumferential force the normal one times
    cos(alpha)); None where alpha is not a number."""
    out = dict(entry)
    if level == "elastic" and entry.get("level") == "normal":
        alpha = entry.get("alpha", math.radians(20.0))
        if isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or entry.get("c_n") is None:
            return None
        k = math.cos(alpha) ** 2
        for name, to in (("c_n", "c"), ("d", "d")):
            value = entry.get(name)
            if value is not None:
                out[to] = value * k if isinstance(value, (int, float)) and not isinstance(value, bool) \
                    else f"({value})*{k!r}"
    return out


#: parameters that belong only to the levels above each simpler level (removed when dropping to it)
_NORMAL_ONLY = ("c_n", "mu", "d_t", "s", "alpha", "v_reg")
_SPUR_REDUCTION = Reduction("level", level="level", levels=("normal", "elastic", "ideal"),
                            drop=(("elastic", _NORMAL_ONLY), ("ideal", _NORMAL_ONLY + ("c", "d", "x0", "z1", "phase0"))),
                            adapt=_spur_level)


# -- the spur gear stage -----------------------------------------------------------------------

def default_contact_position(r1, alpha, z1):
    """Involute single-contact model: s(q) = (r_b1/z1)·wrap(q), one base pitch per tooth, centred on
    the pitch point (``wrap`` maps the phase to (−π, π])."""
    q = sp.Symbol("q")
    return r1 * sp.cos(alpha) / z1 * sp.atan2(sp.sin(q), sp.cos(q))


@element("spur_stage", "spur gear stage (Weber §5): ideal i = -r2/r1 (internal +r2/r1), elastic mesh, or "
         "normal/tangential split with tooth friction",
         {"a": "shaft 1 (rotational): torque on the stage [N*m], angular velocity [rad/s]",
          "b": "shaft 2 (rotational)"},
         SPUR_PARAMS,
         {"force": "N: mesh force (circumferential; normal level: tooth normal force), positive when a drives b",
          "deflection": "m: mesh spring deflection (state q; 0 for ideal)",
          "force_u": "N: circumferential force at wheel 1, M1/r1 when massless",
          "stiffness": "N/m: current mesh stiffness (elastic, normal)",
          "phase": "rad: mesh phase q = z1*phi1 (variable stiffness, normal)",
          "sliding_velocity": "m/s: sliding velocity of flank 1 relative to flank 2 (normal)",
          "friction_force": "N: tooth friction force against the sliding of flank 1 (normal)",
          "loss": "W: friction loss F_t*v_t >= 0 (normal)",
          "contact_position": "m: contact point on the line of action from the pitch point (normal)"},
         reductions=(_SPUR_REDUCTION,))
def spur_stage(r1, r2, level, internal, c, c_n, d, x0, z1, phase0, alpha, s, mu, v_reg, d_t):
    """Build the spur gear stage multipole (see the module docstring for the structure).

    Radii in m, stiffnesses in N/m, damping in N·s/m, angles in rad.  Level ``normal`` without a
    tooth friction law (neither ``mu`` nor ``d_t``) builds Weber's incomplete Bild 25 top: the
    tangential branch ends open, and ``multipole check`` reports it as not well-posed.
    """
    if level not in LEVELS:
        raise ModelError("bad_value", f"spur_stage level must be one of {', '.join(LEVELS)}, got {level!r}")
    if _numeric(r1, r2):
        if float(r1) <= 0 or float(r2) <= 0:
            raise ModelError("bad_value", "spur_stage radii r1, r2 must be positive")
        if internal and float(r2) <= float(r1):
            raise ModelError("bad_value", "an internal (ring) gear needs r2 > r1", "r2 is the ring gear's radius")
    if level != "elastic" and c is not None:
        raise ModelError("bad_parameter", f"spur_stage: c is the circumferential stiffness of level elastic; "
                         f"level {level} does not use it", "use c_n for level normal" if level == "normal" else
                         "remove c or choose level: elastic")
    if level == "ideal" and not (_is_zero(d) and _is_zero(x0)):
        raise ModelError("bad_parameter", "spur_stage: d and x0 belong to the mesh spring of levels elastic and "
                         "normal", "remove them or choose level: elastic")
    if level != "normal":
        for name, value in (("c_n", c_n), ("mu", mu), ("d_t", d_t), ("s", s)):
            if value is not None:
                raise ModelError("bad_parameter", f"spur_stage: {name} belongs to level normal", f"remove {name} "
                                 "or choose level: normal")
    sense = 1 if internal else -1          # ω2 = sense·v_u2/r2
    params = {"r1": r1, "r2": r2}
    children: dict = {"wheel1": wheel(_R1), "wheel2": wheel(_R2, sense)}
    connections: list = []
    quantities = {"force_u": Quantity(lambda V: -V.e("wheel1.b"))}
    signals = {}
    uses_phase = depends_on_phase(c) or depends_on_phase(c_n) or (level == "normal" and
                                                                  (s is None or depends_on_phase(s)))
    if uses_phase:
        params.update({"z1": 1.0 if z1 is None else z1, "phase0": phase0})
        children["shaft1"] = junction_b(["a", "tap", "w"], "rotational")
        children["angle1"] = Tap("rotational", q0=_PHASE0 / _Z1)
        connections += [["shaft1.tap", "angle1.p"], ["shaft1.w", "wheel1.a"]]
        signals["phi"] = "angle1.q"
        port_a = "shaft1.a"
        quantities["phase"] = Quantity(lambda V: V.param("z1") * V.x("angle1.q"))
    else:
        port_a = "wheel1.a"
    if level == "ideal":
        connections.append(["wheel1.b", "wheel2.b"])
        quantities["force"] = Quantity(lambda V: -V.e("wheel1.b"))
        quantities["deflection"] = Quantity(lambda V: sp.Integer(0))
        body = None
    elif level == "elastic":
        if c is None:
            raise ModelError("missing_parameter", "spur_stage level elastic needs the mesh stiffness c [N/m]",
                             "add c: <N/m> (a number or an expression of the mesh phase q)")
        params.update({"d": d, "x0": x0})
        cross_coupling(children, connections, "contact", ("u1", "u2"), _stiffness(c, _C, params), d)
        connections += [["wheel1.b", "contact.u1"], ["wheel2.b", "contact.u2"]]
        quantities["force"] = Quantity(lambda V: V.e("contact.u1"))
        quantities["deflection"] = Quantity(lambda V: V.x("spring.q"))
        body = "spring"
    else:
        body = "spring"
        _normal_level(children, connections, params, quantities, signals, r1, r2, sense, c_n, d, x0, z1,
                      alpha, s, mu, v_reg, d_t)
    if body:
        value, name = (c, "c") if level == "elastic" else (c_n, "c_n")
        law = mesh_phase_var(value)
        quantities["stiffness"] = Quantity(
            (lambda V: _resolver(V)(law)) if varies(value) else (lambda V: V.param(name)))
    ports = {"a": port_a, "b": "wheel2.a"}
    return Network("spur_stage", children, connections, ports, params=params, quantities=quantities,
                   body=body, signals=signals,
                   doc=f"spur gear stage, level {level}{' (internal)' if internal else ''}")


def _normal_level(children, connections, params, quantities, signals, r1, r2, sense, c_n, d, x0, z1, alpha, s,
                  mu, v_reg, d_t):
    """Normal/tangential split of Bild 25 (see the module docstring)."""
    if c_n is None:
        raise ModelError("missing_parameter", "spur_stage level normal needs the tooth normal stiffness c_n [N/m]",
                         "add c_n: <N/m> (a number or an expression of the mesh phase q)")
    if s is None:
        if z1 is None:
            raise ModelError("missing_parameter", "spur_stage level normal needs z1 (teeth of wheel 1) for the "
                             "involute contact path, or an explicit contact position s(q)", "add z1: <teeth>")
        if _numeric(r1, r2, alpha, z1):
            half = math.pi * float(r1) * math.cos(float(alpha)) / float(z1)
            limit = min(float(r1), float(r2)) * math.sin(float(alpha)) if sense < 0 else \
                float(r1) * math.sin(float(alpha))
            if half >= limit:
                raise ModelError("bad_value", f"spur_stage: the contact path (±{half:.4g} m about the pitch point) "
                                 f"leaves the line of action between the tangent points (±{limit:.4g} m)",
                                 "use more teeth z1 or a larger pressure angle alpha")
        s = default_contact_position(_R1, _ALPHA, _Z1)
    params.update({"alpha": alpha, "d": d, "x0": x0})
    s_phi = mesh_phase_var(s)
    rho1 = _R1 * sp.sin(_ALPHA) + s_phi
    rho2 = _R2 * sp.sin(_ALPHA) + sense * s_phi
    for k, rho, radius in ((1, rho1, _R1), (2, rho2, _R2)):
        children[f"flank{k}"] = junction_b(["u", "n", "t"], MECH)
        children[f"normal{k}"] = TF(sp.cos(_ALPHA), MECH, MECH)
        children[f"tangent{k}"] = TF(rho / radius, MECH, MECH)
        connections += [[f"wheel{k}.b", f"flank{k}.u"], [f"flank{k}.n", f"normal{k}.b"],
                        [f"flank{k}.t", f"tangent{k}.b"]]
    cross_coupling(children, connections, "contact", ("n1", "n2"), _stiffness(c_n, _CN, params), d)
    connections += [["normal1.a", "contact.n1"], ["normal2.a", "contact.n2"]]
    signals["qn"] = "spring.q"
    normal_force = (mesh_phase_var(c_n) if varies(c_n) else _CN) * QN
    laws = []
    if mu is not None:
        params.update({"mu": mu, "v_reg": v_reg})
        laws.append(_MU * sp.Abs(normal_force) * sp.tanh(sp.Symbol("f") / _VREG))
    if d_t is not None:
        params["d_t"] = d_t
        laws.append(_DT * sp.Symbol("f"))
    children["sliding"] = junction_a(["t1", "t2", "r"], MECH, [1, -1, -1])
    connections += [["tangent1.a", "sliding.t1"], ["tangent2.a", "sliding.t2"], ["sliding.r", "friction.p"]]
    if not laws:                     # Weber's Bild 25 top: nothing closes the tangential branch
        children["friction"] = MissingCrossCoupling(
            MECH, "the tangential branch of the normal/tangential split lacks a cross-coupling: no resistance R "
                  "(tooth friction) turns the sliding velocity between the flanks into the tangential force "
                  "(Weber, Bild 25 top)",
            "give {element} a tooth-friction law: mu (with v_reg) or d_t")
    else:
        children["friction"] = R(law=sp.Add(*laws), dom=MECH)
        quantities["sliding_velocity"] = Quantity(lambda V: V.f("friction.p"))
        quantities["friction_force"] = Quantity(lambda V: V.e("friction.p"))
        quantities["loss"] = Quantity(lambda V: V.e("friction.p") * V.f("friction.p"))
    quantities["force"] = Quantity(lambda V: V.e("contact.n1"))
    quantities["deflection"] = Quantity(lambda V: V.x("spring.q"))
    quantities["contact_position"] = Quantity(lambda V, s_phi=s_phi: _resolver(V)(s_phi))


# -- gear trains -------------------------------------------------------------------------------

@element("gear_train", "spur stages in series (lists r1, r2; shared level, c, d); overall ratio = product of the "
         "stage ratios",
         {"a": "input shaft (rotational)", "b": "output shaft (rotational)"},
         [Param("r1", "m", "pitch radii of the driving wheels, one per stage", kind="numbers", positive=True,
                max_items=MAX_STAGES),
          Param("r2", "m", "pitch radii of the driven wheels, one per stage", kind="numbers", positive=True,
                max_items=MAX_STAGES),
          Param("level", "", "ideal or elastic (all stages)", "ideal", "choice", ("ideal", "elastic")),
          Param("internal", "", "all stages internal meshes", False, "bool"),
          Param("c", "N/m", "elastic: mesh stiffness of every stage, " + _LAW_DOC, None, "law", law_var="q",
                positive=True),
          Param("d", "N*s/m", "elastic: mesh damping of every stage", 0.0),
          Param("J", "kg*m^2", "inertias of the intermediate shafts (n-1 values); massless if omitted", None,
                "numbers", positive=True),
          Param("z1", "-", "teeth of the driving wheel of each stage (n values); the mesh phase of stage k is "
                "q = z1[k]*phi of its input shaft", None, "numbers", positive=True)],
         {"ratio": "-: overall ratio omega_a/omega_b", "s<k>.force": "N: mesh force of stage k",
          "s<k>.deflection": "m: mesh deflection of stage k (elastic)",
          "s<k>.stiffness": "N/m: current mesh stiffness of stage k (elastic)",
          "s<k>.phase": "rad: mesh phase of stage k (stiffness law of q)"})
def gear_train(r1, r2, level, internal, c, d, J, z1):
    """Spur stages in series: stage k has radii r1[k], r2[k] [m]; ``J`` (optional, kg·m²) are the
    inertias of the n−1 intermediate shafts (massless without); ``z1`` (optional) the teeth of each
    stage's driving wheel, so that a stiffness law of the mesh phase q runs at each stage's own
    tooth frequency (q = z1[k]·φ of that stage's input shaft)."""
    if len(r1) != len(r2) or not r1:
        raise ModelError("bad_value", "gear_train needs lists r1 and r2 of the same, non-zero length")
    n = len(r1)
    if J is not None and len(J) != n - 1:
        raise ModelError("bad_value", f"gear_train with {n} stages needs {n - 1} intermediate inertias J")
    if z1 is not None and len(z1) != n:
        raise ModelError("bad_value", f"gear_train with {n} stages needs {n} tooth numbers z1 (one per stage)")
    children, connections = {}, []
    for k in range(n):
        children[f"s{k + 1}"] = spur_stage(r1[k], r2[k], level, internal, c=c if level == "elastic" else None,
                                           d=d if level == "elastic" else 0.0, z1=None if z1 is None else z1[k])
        if k == 0:
            continue
        if J is None:
            connections.append([f"s{k}.b", f"s{k + 1}.a"])
        else:
            children[f"shaft{k}"] = inertia(J[k - 1])
            connections += [[f"s{k}.b", f"shaft{k}.a"], [f"shaft{k}.b", f"s{k + 1}.a"]]
    sense = 1 if internal else -1
    ratio = math.prod(sense * b / a for a, b in zip(r1, r2))   # stage ratio -r2/r1, internal +r2/r1
    return Network("gear_train", children, connections, {"a": "s1.a", "b": f"s{n}.b"},
                   quantities={"ratio": Quantity(lambda V: sp.Float(ratio))},
                   doc=f"{n}-stage gear train")
