"""The primitives every multipole is built from.

Sources ``Se``/``Sf``, ideal couplings ``TF`` (also modulated and multiport) and ``GY``, junctions
of type a (common effort) and b (common flow), and the cross-couplings ``I``, ``R``, ``C`` and the
two-port ``CField``.  A primitive knows its ports (name -> domain), its parameters and its
constitutive equations written in its own port variables; the network layer gives the variables
global names.

Parameters are numbers or sympy expressions.  Laws are expressions of the primitive's own variable:
``R`` laws of the flow ``f``, ``C`` laws of the displacement ``q``, ``I`` laws of the momentum
``p``; source values and laws may also use the time ``t``.  Modulated ratios use ``q`` (``TF``) or
``q1 … qm`` (``MTF``), the time integrals of the flows at the ``b`` ports.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import sympy as sp

from .domains import Domain, domain
from .errors import ModelError

T = sp.Symbol("t", real=True)          #: simulation time [s]
LAW_F = sp.Symbol("f", real=True)      #: flow variable in R laws
LAW_Q = sp.Symbol("q", real=True)      #: displacement variable in C laws and modulated TF ratios
LAW_P = sp.Symbol("p", real=True)      #: momentum variable in I laws


def q_symbols(m: int) -> list[sp.Symbol]:
    """Displacement symbols ``q1 … qm`` used in multiport transformer matrices."""
    return [sp.Symbol(f"q{k + 1}", real=True) for k in range(m)]


@dataclass
class StateSpec:
    """A state a primitive integrates.

    ``rhs(V)`` returns its time derivative in global variables.  ``storage`` states (momentum of an
    I, displacement of a C) may be put into derivative causality by the analyser; displacement
    states of modulated transformers are always integrated.
    """

    name: str
    rhs: Callable
    initial: object
    storage: bool
    unit: str
    given: bool = True      #: False: no initial value was given (the consistent one is taken silently)


@dataclass
class Relation:
    """One constitutive equation ``expr == 0`` and the variable it naturally computes."""

    expr: sp.Expr
    role: str
    natural: object = None
    note: str = ""


class Primitive:
    """Base class.  Subclasses set ``kind`` and implement ``relations`` (and ``states``)."""

    kind = "primitive"
    #: parameters that become named parameter symbols (numbers or constant expressions)
    numeric_params: tuple[str, ...] = ()

    def __init__(self, ports: dict[str, Domain], params: dict | None = None, doc: str = ""):
        self.ports = {name: domain(d) for name, d in ports.items()}
        self.params = dict(params or {})
        self.doc = doc

    def relations(self, V) -> list[Relation]:
        raise NotImplementedError

    def states(self) -> list[StateSpec]:
        return []

    def __repr__(self) -> str:
        return f"{self.kind}({', '.join(self.ports)})"


def plain_sum(terms) -> sp.Expr:
    """The sum of ``terms`` (sympy symbols or products, none zero) as written, not simplified: one
    per node or junction, so built from its arguments directly (sympy's unevaluated ``Add`` costs
    about six times as much: it sympifies and caches every argument)."""
    terms = tuple(terms)
    return terms[0] if len(terms) == 1 else sp.Add._from_args(terms)


def negative(x) -> sp.Expr:
    """``-x`` for a symbol ``x``, as written (see :func:`plain_sum`)."""
    return sp.Mul._from_args((sp.S.NegativeOne, x))


def _sym(value) -> sp.Expr:
    return value if isinstance(value, sp.Basic) else sp.sympify(float(value))


class _Source(Primitive):
    """A one-port source imposing ``value(t)`` on its neighbour; ``variable`` is "e" or "f"."""

    variable = "e"

    def __init__(self, value, dom="rotational"):
        super().__init__({"p": dom}, {"value": _sym(value)})

    def relations(self, V):
        own = V.e("p") if self.variable == "e" else V.f("p")
        sign = self.ports["p"].imposed_sign(self.variable)
        word = "effort" if self.variable == "e" else "flow"
        return [Relation(own - sign * V.input(self.params["value"]), "source", own,
                         f"{word} source imposes {self.params['value']}")]


class Se(_Source):
    """Effort source: imposes ``value(t)`` as the effort its neighbour sees at port ``p``.

    In a mechanical domain a positive value accelerates a free inertia in the positive direction;
    in an electrical domain it is the potential of the connected node [domain effort unit].
    """

    kind = "Se"
    variable = "e"


class Sf(_Source):
    """Flow source: imposes ``value(t)`` as the flow its neighbour sees at port ``p``."""

    kind = "Sf"
    variable = "f"


class TF(Primitive):
    """Ideal transformer ``f_a = k*f_b``, ``e_b = -k*e_a`` (Weber (11)–(12)); lossless.

    ``ratio`` may be a constant or an expression of ``q``, the displacement of port ``b``
    (``q' = f_b``, ``q(0) = q0``): a modulated transformer such as a crank or a linkage transfer
    function.  Ports may belong to different domains (transducer: rope drum, rack and pinion).
    """

    kind = "TF"
    numeric_params = ("ratio",)

    def __init__(self, ratio, dom_a="rotational", dom_b=None, q0=0.0):
        super().__init__({"a": dom_a, "b": dom_b or dom_a}, {"ratio": _sym(ratio), "q0": _sym(q0)})

    @property
    def modulated(self) -> bool:
        return LAW_Q in self.params["ratio"].free_symbols

    def states(self):
        if not self.modulated:
            return []
        unit = self.ports["b"].displacement_unit
        return [StateSpec("q", lambda V: V.f("b"), self.params["q0"], False, unit)]

    def relations(self, V):
        k = V.expr(self.params["ratio"], {LAW_Q: V.x("q")}) if self.modulated else V.param("ratio")
        return [Relation(V.f("a") - k * V.f("b"), "constraint", None, "flow ratio f_a = k*f_b"),
                Relation(V.e("b") + k * V.e("a"), "constraint", None, "effort ratio e_b = -k*e_a")]


class MTF(Primitive):
    """Multiport transformer with a matrix ratio: ``f_a = K(q)·f_b``, ``e_b = -Kᵀ·e_a``.

    ``K`` is an n×m matrix (a Jacobian) of expressions of ``q1 … qm``, the displacements of the
    ports ``b1 … bm`` (``q' = f_b``).  Ports ``a1 … an`` and ``b1 … bm``; ``domains_a`` and
    ``domains_b`` give their domains.  Lossless by construction.
    """

    kind = "MTF"

    def __init__(self, matrix, domains_a, domains_b, q0=None):
        K = sp.Matrix(matrix)
        n, m = K.shape
        qs = {q.name: q for q in q_symbols(m)}
        K = K.xreplace({s: qs[s.name] for s in K.free_symbols if s.name in qs})
        if len(domains_a) != n or len(domains_b) != m:
            raise ModelError("bad_shape", f"MTF matrix is {n}x{m} but has {len(domains_a)} a-ports "
                             f"and {len(domains_b)} b-ports", "give one domain per matrix row/column")
        ports = {f"a{i + 1}": d for i, d in enumerate(domains_a)}
        ports.update({f"b{j + 1}": d for j, d in enumerate(domains_b)})
        super().__init__(ports, {"matrix": K, "q0": [_sym(v) for v in (q0 or [0.0] * m)]})
        self.n, self.m = n, m
        self.qs = q_symbols(m)

    def states(self):
        used = self.params["matrix"].free_symbols
        return [StateSpec(f"q{j + 1}", (lambda V, j=j: V.f(f"b{j + 1}")), self.params["q0"][j], False,
                          self.ports[f"b{j + 1}"].displacement_unit)
                for j in range(self.m) if self.qs[j] in used]

    def relations(self, V):
        used = self.params["matrix"].free_symbols
        subs = {q: V.x(q.name) for q in self.qs if q in used}
        K = self.params["matrix"].applyfunc(lambda x: V.expr(x, subs))
        fa = [V.f(f"a{i + 1}") for i in range(self.n)]
        fb = [V.f(f"b{j + 1}") for j in range(self.m)]
        ea = [V.e(f"a{i + 1}") for i in range(self.n)]
        eb = [V.e(f"b{j + 1}") for j in range(self.m)]
        rel = [Relation(fa[i] - sp.Add(*[K[i, j] * fb[j] for j in range(self.m)]), "constraint", None,
                        f"flow row {i + 1} of f_a = K*f_b") for i in range(self.n)]
        rel += [Relation(eb[j] + sp.Add(*[K[i, j] * ea[i] for i in range(self.n)]), "constraint", None,
                         f"effort row {j + 1} of e_b = -K^T*e_a") for j in range(self.m)]
        return rel


class GY(Primitive):
    """Ideal gyrator ``e_a = r*f_b``, ``e_b = -r*f_a``; lossless (DC motor constant, gyroscope)."""

    kind = "GY"
    numeric_params = ("r",)

    def __init__(self, r, dom_a="electrical", dom_b="rotational"):
        super().__init__({"a": dom_a, "b": dom_b}, {"r": _sym(r)})

    def relations(self, V):
        r = V.param("r")
        return [Relation(V.e("a") - r * V.f("b"), "constraint", None, "e_a = r*f_b"),
                Relation(V.e("b") + r * V.f("a"), "constraint", None, "e_b = -r*f_a")]


class Junction(Primitive):
    """Common junction of any number of ports, each with an orientation sign ``±1``.

    Type ``b`` (common flow, Weber's 1-junction): ``σ_i f_i`` equal, ``Σ σ_i e_i = 0``.
    Type ``a`` (common effort, Weber's 0-junction): ``σ_i e_i`` equal, ``Σ σ_i f_i = 0``.
    Power-conserving for any signs.
    """

    def __init__(self, kind: str, ports, dom="rotational", signs=None):
        ports = list(ports)
        if len(ports) < 2:
            raise ModelError("bad_junction", "a junction needs at least two ports")
        signs = list(signs) if signs is not None else [1] * len(ports)
        if len(signs) != len(ports) or any(s not in (1, -1) for s in signs):
            raise ModelError("bad_junction", "junction signs must be one +1 or -1 per port")
        super().__init__({p: dom for p in ports}, {"signs": signs})
        self.kind = "junction_" + kind
        self.type = kind

    def relations(self, V):
        names = list(self.ports)
        sig = dict(zip(names, self.params["signs"]))
        common, summed = ("f", "e") if self.type == "b" else ("e", "f")
        get = {"e": V.e, "f": V.f}

        def signed(kind, p):
            x = get[kind](p)
            return x if sig[p] == 1 else negative(x)

        def minus(x):
            return x.args[1] if isinstance(x, sp.Mul) else negative(x)
        first = signed(common, names[0])
        rel = [Relation(plain_sum((signed(common, p), minus(first))), "constraint", None,
                        f"common {'flow' if common == 'f' else 'effort'}") for p in names[1:]]
        rel.append(Relation(plain_sum(signed(summed, p) for p in names), "constraint", None,
                            f"{'efforts' if summed == 'e' else 'flows'} sum to zero"))
        return rel


def junction_a(ports, dom="electrical", signs=None) -> Junction:
    """Type-a junction (common effort, flows add)."""
    return Junction("a", ports, dom, signs)


def junction_b(ports, dom="rotational", signs=None) -> Junction:
    """Type-b junction (common flow, efforts add)."""
    return Junction("b", ports, dom, signs)


class I(Primitive):
    """Inertia: momentum ``p`` with ``p' = e`` and ``f = p/J`` (or ``f = law(p)``).

    ``J`` in kg·m² (rotational), kg (translational), H (electrical), Pa·s²/m³ (hydraulic).
    """

    kind = "I"
    numeric_params = ("J",)

    def __init__(self, J=None, dom="rotational", p0=0.0, law=None):
        self.given = p0 is not None     # p0=None: the momentum follows from the couplings at t = 0
        p0 = 0.0 if p0 is None else p0
        if (J is None) == (law is None):
            raise ModelError("bad_law", "I needs exactly one of J (linear) or law (f as a function of p)")
        super().__init__({"p": dom}, {"J": _sym(J) if J is not None else None, "law": law, "p0": _sym(p0)})

    def states(self):
        return [StateSpec("p", lambda V: V.e("p"), self.params["p0"], True, self.ports["p"].momentum_unit,
                          self.given)]

    def relations(self, V):
        p = V.x("p")
        out = p / V.param("J") if self.params["law"] is None else V.expr(self.params["law"], {LAW_P: p})
        return [Relation(V.f("p") - out, "storage", V.f("p"), "flow from momentum")]


class C(Primitive):
    """Compliance: displacement ``q`` with ``q' = f`` and ``e = c*q`` (or ``e = law(q)``).

    ``c`` is the stiffness (effort per displacement): N/m, N·m/rad, 1/F for a capacitor
    (``c = 1/C``), Pa/m³ for a hydraulic capacity.
    """

    kind = "C"
    numeric_params = ("c",)

    def __init__(self, c=None, dom="rotational", q0=0.0, law=None):
        if (c is None) == (law is None):
            raise ModelError("bad_law", "C needs exactly one of c (stiffness) or law (e as a function of q)")
        super().__init__({"p": dom}, {"c": _sym(c) if c is not None else None, "law": law, "q0": _sym(q0)})

    def states(self):
        return [StateSpec("q", lambda V: V.f("p"), self.params["q0"], True, self.ports["p"].displacement_unit)]

    def relations(self, V):
        q = V.x("q")
        out = V.param("c") * q if self.params["law"] is None else V.expr(self.params["law"], {LAW_Q: q})
        return [Relation(V.e("p") - out, "storage", V.e("p"), "effort from displacement")]


class R(Primitive):
    """Resistance: ``e = r*f`` (or ``e = law(f, t)``), dissipates ``e*f >= 0`` for a passive law."""

    kind = "R"
    numeric_params = ("r",)

    def __init__(self, r=None, dom="rotational", law=None):
        if (r is None) == (law is None):
            raise ModelError("bad_law", "R needs exactly one of r (linear) or law (e as a function of f)")
        super().__init__({"p": dom}, {"r": _sym(r) if r is not None else None, "law": law})

    def relations(self, V):
        f = V.f("p")
        out = V.param("r") * f if self.params["law"] is None else V.expr(self.params["law"], {LAW_F: f})
        return [Relation(V.e("p") - out, "law", V.e("p"), "effort from flow")]


class Tap(Primitive):
    """Displacement tap: a port that takes no effort (``e = 0``) and integrates its flow into ``q``.

    Put on a junction it measures an angle or a travel for laws elsewhere in the element
    (a mesh stiffness that varies with the mesh position, a contact point moving along the line of
    action) without changing the dynamics.
    """

    kind = "Tap"

    def __init__(self, dom="rotational", q0=0.0):
        super().__init__({"p": dom}, {"q0": _sym(q0)})

    def states(self):
        return [StateSpec("q", lambda V: V.f("p"), self.params["q0"], False, self.ports["p"].displacement_unit)]

    def relations(self, V):
        return [Relation(V.e("p"), "constraint", V.e("p"), "a tap takes no effort")]


class CField(Primitive):
    """Two-port (or n-port) compliance field: ``q' = f`` per port and ``q = S·e``.

    ``compliance`` is the symmetric matrix ``S`` (displacement per effort), e.g. Weber's piezo
    ``[[delta_P, k_P], [k_P, C_P]]`` for ports (mech, elec).  Efforts follow as ``e = S⁻¹·q``.
    """

    kind = "CField"

    def __init__(self, compliance, domains, q0=None):
        S = sp.Matrix(compliance)
        if S.shape != (len(domains), len(domains)):
            raise ModelError("bad_shape", "CField compliance must be square with one row per port")
        if (S - S.T).applyfunc(sp.simplify) != sp.zeros(*S.shape):
            raise ModelError("not_reciprocal", "CField compliance matrix must be symmetric (reciprocity)")
        names = [f"p{k + 1}" for k in range(len(domains))]
        super().__init__(dict(zip(names, domains)),
                         {"compliance": S, "q0": [_sym(v) for v in (q0 or [0.0] * len(domains))]})
        self.names = names

    def states(self):
        return [StateSpec(f"q{k + 1}", (lambda V, n=n: V.f(n)), self.params["q0"][k], True,
                          self.ports[n].displacement_unit) for k, n in enumerate(self.names)]

    def relations(self, V):
        S = self.params["compliance"].applyfunc(V.expr)
        K = S.inv()
        q = sp.Matrix([V.x(f"q{k + 1}") for k in range(len(self.names))])
        e = K * q
        return [Relation(V.e(n) - e[k], "storage", V.e(n), "effort from displacements")
                for k, n in enumerate(self.names)]
