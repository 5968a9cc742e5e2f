"""Networks: multipoles built from primitives and other networks, and their flattening.

A :class:`Network` has named children (primitives or networks), internal connections, named
external ports, parameters and documented quantities.  :func:`flatten` turns a root network into
a :class:`FlatNetwork`: primitive equations in global variables, one node per connection, the
default termination of every port nobody connected, the states, the parameter table and a
networkx graph of primitives and nodes.

Global names follow DESIGN §4: port variables ``elem.port.e`` / ``elem.port.f``, states
``elem.p`` / ``elem.q``, parameters ``elem.J``, quantities ``elem.omega``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Callable

import networkx as nx
import sympy as sp

from .domains import Domain, bundle
from .errors import ModelError
from .primitives import LAW_F, LAW_P, LAW_Q, T, Primitive, Relation, negative, plain_sum
from .stages import bulk, free_symbols, substitute


@lru_cache(maxsize=None)
def var(name: str) -> sp.Symbol:
    """The global real symbol called ``name`` (port variables, states, parameters)."""
    return sp.Symbol(name, real=True)


@dataclass
class Quantity:
    """A documented output of an element: ``build(V)`` returns its expression."""

    build: Callable
    unit: str = ""
    doc: str = ""


@dataclass
class ClosedForm:
    """A :class:`Closure`'s residuals solved by formula: the generated code evaluates it instead of
    iterating (Newton's method solves a closure without one).

    ``branches``: one or two candidate solutions, each a list with one entry per closure state, in
    the closure's local names (parameters, signals, position reads; not the closure's own states):
    the state's value, or for an angle ``(cos, sin)``, its direction as a unit vector.  An angle's
    value is ``atan2(sin, cos)`` continued to the turn of its integrated value (never wrapped), and
    the code reads the pair wherever the angle's cosine or sine is wanted (no trigonometric call).
    ``select`` (two branches): an expression in the same names and the closure's *integrated* states
    whose sign tells the branch the mechanism is on, the first where ``select >= 0``.  Where a square
    root in a branch has a negative radicand the closure has no real solution: the evaluation fails as
    a Newton solve that found none does (the integrator rejects the step)."""

    branches: list
    select: object = None


@dataclass
class Closure:
    """A holonomic closure: residuals ``g = 0`` that pin the values of some displacement states.

    ``states`` are references ``"child.state"`` to integrated displacement states (the angles of a
    modulated transformer, say) whose rates the network's velocity relations already determine;
    ``residuals`` (as many, expressions in the network's local names: parameters, signals and
    position reads) are the position-level relations those rates are the time derivative of.  The
    equations stage solves ``g = 0`` for the states at every evaluation (Newton's method, started
    from the integrated values), so the positions never drift from the closure; the integrated values
    only keep track of the branch (the assembly mode).
    """

    states: list
    residuals: list
    doc: str = ""
    #: ``(expr, text[, unit])``: the closure can be assembled at t = 0 only if ``expr >= 0`` there
    #: (``expr`` in the same local names; the check reports ``text`` and by how much, ``-expr``
    #: in ``unit``, it fails: a radicand of the start formula, a reach minus a distance)
    conditions: list = field(default_factory=list)
    #: ``(expr, threshold, text)``: the closure's Jacobian with respect to its states is singular
    #: (a dead centre) where ``expr`` is 0; flattening turns it into two :class:`Monitor` records
    #: (:func:`guard_monitors`): a run in which ``|expr|`` falls below ``threshold`` reports
    #: ``near_dead_centre``, one in which it falls below :data:`DEAD_STOP` times it stops with ``dead_centre``
    guard: tuple | None = None
    #: the residuals solved by formula (:class:`ClosedForm`), or None: Newton's method
    closed_form: ClosedForm | None = None


#: a closure's dead-centre guard stops the run once ``|expr|`` falls below this fraction of its
#: threshold (beyond it the rates grow like 1/guard and the steps shrink to nothing)
DEAD_STOP = 1e-3


@dataclass
class Monitor:
    """A run-time check an element declares: the run reports it when ``expr`` crosses from ``>= 0``
    to ``< 0``.

    ``expr``: an expression in the network's local names (parameters, signals, position reads, as a
    :class:`Closure` residual; states are their integrated values); ``code``: the diagnostic's code
    (``band_lifts_off``); ``text``: what happened, one line without the element's name (the run
    prefixes it).  The crossing is located like a switching event (to the event tolerance) on every
    backend, but switches no law.  ``stop=False``: the finding ``(t [s], element, code, text)`` is
    listed in :attr:`multipole.simulate.Result.monitors`, once per crossing, and the run goes on;
    ``stop=True``: the run ends there with a run-time error carrying ``code``, the time and the
    element (``fix``: what the user can do, for that error)."""

    expr: object
    code: str
    text: str
    stop: bool = False
    fix: str = ""


def guard_monitors(expr, threshold: float, text: str) -> list:
    """The two monitors of a closure's dead-centre guard (:attr:`Closure.guard`): ``near_dead_centre``
    where ``|expr|`` falls below ``threshold`` (the run goes on) and ``dead_centre`` where it falls
    below :data:`DEAD_STOP` times it (the run stops)."""
    threshold = float(threshold)
    stop = DEAD_STOP * threshold
    return [Monitor(sp.Abs(expr) - threshold, "near_dead_centre",
                    f"comes near its dead centre (|{text}| below {threshold:g}): forces and rates there grow "
                    f"like 1/{text}"),
            Monitor(sp.Abs(expr) - stop, "dead_centre",
                    f"reached its dead centre (|{text}| below {stop:g}): its closure cannot be solved beyond it, "
                    "so the run stops", stop=True,
                    fix="the motion prescribed upstream pushes the element through a position it cannot pass: "
                        "drive the mechanism only over the range it can assemble (see the transfer function), "
                        "or drive it at this element itself")]


@dataclass
class PositionProblem:
    """A position found over- or under-determined while flattening (reported by the check)."""

    code: str                   #: position_overdetermined | position_loop | position_undetermined
    owners: list                #: the element paths involved
    ports: list                 #: the primitive port paths involved
    detail: str = ""


@dataclass
class Sketch:
    """A piece of an element's drawing (``multipole draw``): a polyline through points ``(x, y)``
    [m], expressions in the network's local names (parameters, signals, position reads).

    ``style``: ``link`` (a bar with joints at its ends), ``slide`` (a guide line), ``point``,
    ``line`` (a thin solid polyline: a band span, a roll's outline).
    ``labels``: a text per point ('' for none).  ``trace``: draw the path of the last point over the
    whole run (a coupler curve)."""

    points: list
    labels: list = field(default_factory=list)
    style: str = "link"
    trace: bool = False


def expand_connection(conn, children) -> list:
    """The component connections of a connection entry: an entry joining bundle ports (``[crank.out,
    coupler.a]``) becomes one entry per component (``[crank.out.x, coupler.a.x]``, …); an entry of
    plain ports is returned as it is.  Mixing a bundle with a plain port, or bundles of different
    kinds, is a ``bundle_mismatch`` error naming both ports and their kinds."""
    def bundle_of(ref):
        el, port = ref.split(".", 1)
        return (getattr(children.get(el), "bundles", None) or {}).get(port)

    kinds = [bundle_of(ref) for ref in conn]
    if not any(kinds):
        return [list(conn)]
    if kinds[0] == "band" and len(conn) > 2:
        _refuse_band_branching([conn], children)
    for ref, kind in zip(conn, kinds):
        if kind != kinds[0]:
            first, other = (conn[0], kinds[0]), (ref, kind)
            words = [f"a {k} bundle port" if k else f"a {_plain_kind(r, children)} port" for r, k in (first, other)]
            raise ModelError("bundle_mismatch", f"cannot join {first[0]} ({words[0]}) and {ref} ({words[1]})",
                             "join a bundle port only with bundle ports of the same kind; a one-dimensional "
                             "element attaches to an element's one-dimensional sub-ports")
    return [[f"{ref}.{c}" for ref in conn] for c, _ in bundle(kinds[0]).components]


def _refuse_band_branching(connections, children) -> None:
    """A band connection is point-to-point: a ``band`` bundle port joined to more than one other
    port (in one entry or over several) is a ``band_branching`` error naming the ports."""
    joined: dict = {}
    for conn in connections:
        refs = [r for r in conn if "." in r]
        for ref in refs:
            el, port = ref.split(".", 1)
            if (getattr(children.get(el), "bundles", None) or {}).get(port) == "band":
                joined.setdefault(ref, set()).update(r for r in refs if r != ref)
    for ref, others in joined.items():
        if len(others) > 1:
            names = ", ".join(sorted({ref} | others))
            raise ModelError("band_branching", f"the band connection {ref} branches: it joins {names}",
                             "a band runs from one element to exactly one other: join each band port to one "
                             "band port only")


def _plain_kind(ref, children) -> str:
    """The domain name of a one-dimensional port ``child.port`` for messages."""
    el, port = ref.split(".", 1)
    child = children.get(el)
    try:
        dom = child.ports[port] if isinstance(child, Primitive) else child.port_domain(port)
        return f"one-dimensional {dom.name}"
    except (KeyError, AttributeError, ModelError):
        return "unknown"


class Network:
    """A multipole made of children joined by connections, with named external ports.

    ``children``: name -> Primitive or Network.  ``connections``: lists of ``"child.port"``
    strings; two or more ports per entry form a node of the domain's kind.  ``ports``: external
    name -> ``"child.port"``.  ``params``: local parameter values (numbers or sympy expressions
    of outer parameters); primitives refer to them by bare symbols.  ``quantities``: name ->
    :class:`Quantity`.  ``body``: a child whose names take the network's own path (so the
    inertia's momentum is ``pinion.p``, not ``pinion.I.p``).  ``signals``: name -> ``"child.state"``;
    laws and ratios of the children may use the name for that state (e.g. the mesh position
    ``phi`` of a gear stage, integrated by a :class:`~multipole.primitives.Tap`); a name for
    ``"child.port.e"`` / ``"child.port.f"`` stands for that port's effort / flow (a law modulated
    by a force elsewhere in the element: a bearing friction torque proportional to the radial load).

    Port bundles and positions (used by planar mechanisms, but not specific to them):
    ``bundles``: name -> bundle kind (``"planar"``); the bundle ``out`` consists of the external
    ports ``out.x``, ``out.y``, ``out.phi`` and a connection entry may name ``child.out`` to join all
    components.  ``positions``: external port -> expression of its displacement (a position [m] or
    an angle [rad]) in local names: the network determines the position of whatever that port is
    joined to.  ``reads``: local name -> ``(external port, default)``: the name stands for the
    position of the node the port is joined to, as determined by the one element that provides it,
    or ``default`` if the port is not connected.  ``fixed``: external ports that are held (flow 0)
    when nobody connects them, instead of being free (effort 0): a bearing that is frame-fixed
    unless attached.  ``closures``: :class:`Closure` records.  ``monitors``: :class:`Monitor` records
    (run-time checks in the same local names).
    """

    def __init__(self, kind: str, children: dict, connections=(), ports=None, params=None,
                 quantities=None, body: str | None = None, doc: str = "", prefer_state=None, signals=None,
                 bundles=None, positions=None, reads=None, fixed=(), closures=(), sketch=(), monitors=()):
        self.kind = kind
        self.children = dict(children)
        self.connections = [part for c in connections for part in expand_connection(list(c), self.children)]
        self.ports = dict(ports or {})
        self.params = dict(params or {})
        self.quantities = dict(quantities or {})
        self.body = body
        self.doc = doc
        self.prefer_state = list(prefer_state or [])
        self.signals = dict(signals or {})
        self.bundles = dict(bundles or {})
        self.positions = dict(positions or {})
        self.reads = dict(reads or {})
        self.fixed = list(fixed)
        self.closures = list(closures)
        self.sketch = list(sketch)
        self.monitors = list(monitors)
        for m in self.monitors:
            if not isinstance(m, Monitor) or not isinstance(m.expr, (sp.Basic, int, float)) \
                    or isinstance(m.expr, bool) or not (isinstance(m.code, str) and m.code.isidentifier()):
                what = (f"{type(m).__name__}" if not isinstance(m, Monitor) else
                        f"code {m.code!r}" if not (isinstance(m.code, str) and m.code.isidentifier())
                        else f"expression {m.expr!r} ({type(m.expr).__name__})")
                raise ModelError("bad_monitor", f"{kind}: a monitor needs a sympy expression and an identifier "
                                 f"as its code, not {what}",
                                 "declare each as Monitor(expr, code, text, stop=False) with expr a sympy "
                                 "expression of the element's local names (never a string)")
        _refuse_band_branching(connections, self.children)
        for name, kind in self.bundles.items():
            missing = [p for p in bundle(kind).ports(name) if p not in self.ports]
            if missing:
                raise ModelError("bad_bundle", f"{kind}: bundle {name!r} lacks the ports {', '.join(missing)}")
        for ref in list(self.ports.values()) + [r for c in self.connections for r in c]:
            child = ref.split(".", 1)[0]
            if child not in self.children:
                raise ModelError("unknown_child", f"{kind}: port reference {ref!r} names no child",
                                 f"children are {', '.join(self.children)}")

    def port_domain(self, name: str) -> Domain:
        if name not in self.ports and name in self.bundles:
            raise ModelError("bundle_mismatch", f"{self.kind}.{name} is a {self.bundles[name]} bundle port, "
                             "not a one-dimensional port")
        child, port = self.ports[name].split(".", 1)
        c = self.children[child]
        return c.ports[port] if isinstance(c, Primitive) else c.port_domain(port)

    def port_names(self) -> list[str]:
        return list(self.ports)


@dataclass
class Equation:
    """A residual ``expr == 0`` with its origin, for analysis and for the user's eyes."""

    expr: sp.Expr
    owner: str
    role: str
    natural: object = None
    note: str = ""


@dataclass
class State:
    """A state of the flat network: its symbol, derivative expression and initial value."""

    symbol: sp.Symbol
    rhs: sp.Expr
    initial: sp.Expr
    storage: bool
    owner: str
    unit: str
    given: bool = True      #: an initial value was given (see :class:`multipole.primitives.StateSpec`)

    @property
    def name(self) -> str:
        return self.symbol.name


@dataclass
class Node:
    """Ports joined by one connection (or one port left alone: a termination)."""

    ports: list
    domain: Domain
    origin: str = "connection"
    held: bool = False          #: a termination that holds the port (flow 0) instead of leaving it free

    @property
    def name(self) -> str:
        return "node(" + ", ".join(self.ports) + ")"


@dataclass
class FlatNetwork:
    """The primitive graph of a network with all equations in global variables."""

    primitives: dict = field(default_factory=dict)      # path -> Primitive
    port_domains: dict = field(default_factory=dict)    # "path.port" -> Domain
    equations: list = field(default_factory=list)
    states: list = field(default_factory=list)
    nodes: list = field(default_factory=list)
    params: dict = field(default_factory=dict)          # Symbol -> value expression
    inputs: dict = field(default_factory=dict)          # Symbol -> expression of t
    quantities: dict = field(default_factory=dict)      # name -> (expr, unit, doc)
    elements: dict = field(default_factory=dict)        # element path -> kind
    external_ports: dict = field(default_factory=dict)  # "elem.port" -> primitive port path
    prefer_state: list = field(default_factory=list)
    closures: list = field(default_factory=list)        # (state symbols, residual expressions, owner)
    #: closure index -> its :class:`ClosedForm` in global names (the closures that have one)
    closed_forms: dict = field(default_factory=dict)
    sketches: list = field(default_factory=list)        # (owner, Sketch, [(x, y) global expressions])
    conditions: list = field(default_factory=list)      # (expr >= 0 at t = 0, text, unit, owner)
    monitors: list = field(default_factory=list)        # (expr, Monitor, owner)
    bundles: dict = field(default_factory=dict)         # "elem.port" of a bundle -> bundle kind
    #: the position graph: primitive port path -> owner of the position it provides, and
    #: primitive port path of a read -> (owner that reads it, providing owner or None: the frame)
    position_providers: dict = field(default_factory=dict)
    position_states: dict = field(default_factory=dict)    # owner -> states its provided positions use
    position_reads: dict = field(default_factory=dict)
    position_problems: list = field(default_factory=list)   # PositionProblem, worded by multipole.checks
    graph: nx.Graph = field(default_factory=nx.Graph)

    def variables(self) -> list:
        """All port variables, in a stable order."""
        out = []
        for pp in self.port_domains:
            out += [var(pp + ".e"), var(pp + ".f")]
        return out

    def param_values(self) -> dict:
        """Numeric value of every parameter symbol, with parameter expressions resolved (cached)."""
        cached = getattr(self, "_values", None)
        if cached is not None and len(cached) == len(self.params):
            return dict(cached)
        values: dict = {}

        def value(s):
            if s not in values:
                ex = sp.sympify(self.params[s])
                deps = [d for d in ex.free_symbols if d in self.params]
                values[s] = float(ex.xreplace({d: sp.Float(value(d)) for d in deps})) if deps else float(ex)
            return values[s]

        for s in self.params:
            value(s)
        self._values = values
        return dict(values)

    def element_of(self, path: str) -> str:
        """The top-level element a primitive path or port path belongs to."""
        return path.split(".", 1)[0]


class _Scope:
    def __init__(self, path: str, params: dict, parent: "_Scope | None", signals=None):
        self.path, self.params, self.parent = path, params, parent
        self.signals = dict(signals or {})

    def lookup(self, name: str):
        scope = self
        while scope is not None:
            if name in scope.params or name in scope.signals:
                return scope
            scope = scope.parent
        return None


def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


class _Flattener:
    def __init__(self):
        self.flat = FlatNetwork()
        self.used: dict[str, str] = {}
        self.positions: dict = {}      # primitive port path -> (expression, element path)
        self.reads: dict = {}          # placeholder symbol -> (primitive port path, default, element path)
        self.fixed: set = set()        # primitive port paths held (flow 0) when unconnected

    # -- symbols -----------------------------------------------------------------------------
    def resolve(self, expr, scope: _Scope, where: str, subs=None):
        """Replace bare symbols by global parameter symbols (declaring them)."""
        expr = sp.sympify(expr)
        mapping = dict(subs or {})
        by_name = {k.name: v for k, v in mapping.items()}
        for s in free_symbols(expr):
            if s in mapping or s == T:
                continue
            if s.name in by_name:          # the same law variable without assumptions
                mapping[s] = by_name[s.name]
                continue
            if s.name == T.name:
                mapping[s] = T
                continue
            if s.name in (LAW_F.name, LAW_Q.name, LAW_P.name) and s not in mapping:
                raise ModelError("bad_law", f"{where}: variable {s.name!r} is not available here",
                                 "R laws use f, C laws and modulated ratios use q, I laws use p")
            owner = scope.lookup(s.name)
            if owner is None:
                raise ModelError("unknown_name", f"{where}: unknown parameter {s.name!r}")
            if s.name in owner.signals:
                mapping[s] = owner.signals[s.name]
                continue
            value = owner.params[s.name]
            if isinstance(value, sp.Symbol) and value != T:      # an alias of an outer parameter
                mapping[s] = self.resolve(value, owner.parent or owner, where)
                continue
            g = var(_join(owner.path, s.name))
            if g not in self.flat.params:
                self.flat.params[g] = None  # placeholder against recursion
                self.flat.params[g] = self.resolve(owner.params[s.name], owner.parent or owner, where) \
                    if isinstance(owner.params[s.name], sp.Basic) else owner.params[s.name]
            mapping[s] = g
        return substitute(expr, mapping)

    # -- walking -------------------------------------------------------------------------------
    def port_path(self, net: Network, path: str, ref: str) -> str:
        """Resolve ``child.port`` inside ``net`` (at ``path``) to a primitive port path."""
        child, port = ref.split(".", 1)
        c = net.children[child]
        cpath = path if net.body == child else _join(path, child)
        if isinstance(c, Primitive):
            if port not in c.ports:
                raise ModelError("unknown_port", f"{_join(path, child)} ({c.kind}) has no port {port!r}",
                                 f"ports are {', '.join(c.ports)}")
            return f"{cpath}.{port}"
        if port not in c.ports:
            if port.split(".", 1)[0] in c.children and "." in port:     # a port inside the child (quantities)
                return self.port_path(c, cpath, port)
            raise ModelError("unknown_port", f"{_join(path, child)} ({c.kind}) has no port {port!r}",
                             f"ports are {', '.join(c.ports)}")
        return self.port_path(c, cpath, c.ports[port])

    def state_path(self, net: Network, path: str, ref: str) -> str:
        child, rest = ref.split(".", 1)
        c = net.children[child]
        cpath = path if net.body == child else _join(path, child)
        if isinstance(c, Primitive):
            return f"{cpath}.{rest}"
        return self.state_path(c, cpath, rest)

    def walk(self, net: Network, path: str, scope: _Scope | None):
        signals = {name: var(self.port_path(net, path, ref[:-2]) + ref[-2:]) if ref.endswith((".e", ".f"))
                   else var(self.state_path(net, path, ref)) for name, ref in net.signals.items()}
        for local, (port, _default) in net.reads.items():
            signals[local] = var(f"position({self.port_path(net, path, net.ports[port])})")
        scope = _Scope(path, net.params, scope, signals)
        where = path or "<root>"
        for local, (port, default) in net.reads.items():
            pp = self.port_path(net, path, net.ports[port])
            self.reads[signals[local]] = (pp, self.resolve(default, scope, f"{where} position {port}"), where)
        for port, expr in net.positions.items():
            self.positions[self.port_path(net, path, net.ports[port])] = \
                (self.resolve(expr, scope, f"{where} position {port}"), where)
        self.fixed |= {self.port_path(net, path, net.ports[port]) for port in net.fixed}
        for sk in net.sketch:
            pts = [tuple(self.resolve(v, scope, f"{where} sketch") for v in pt) for pt in sk.points]
            self.flat.sketches.append((where, sk, pts))
        for c in net.closures:
            states = [var(self.state_path(net, path, ref)) for ref in c.states]
            residuals = [self.resolve(r, scope, f"{where} closure") for r in c.residuals]
            if c.closed_form is not None:
                self.flat.closed_forms[len(self.flat.closures)] = map_closed_form(
                    c.closed_form, lambda e: self.resolve(e, scope, f"{where} closure"), len(states), where)
            self.flat.closures.append((states, residuals, where))
            for cond in c.conditions:
                expr, text, unit = (tuple(cond) + ("",))[:3]
                self.flat.conditions.append((self.resolve(expr, scope, f"{where} closure"), text, unit, where))
            if c.guard is not None:
                expr, threshold, text = c.guard
                for m in guard_monitors(self.resolve(expr, scope, f"{where} closure"), threshold, text):
                    self.flat.monitors.append((m.expr, m, where))
        for m in net.monitors:
            self.flat.monitors.append((self.resolve(m.expr, scope, f"{where} monitor {m.code}"), m, where))
        self.flat.elements[path or "<root>"] = net.kind
        self.flat.prefer_state += [_join(path, r) for r in net.prefer_state]
        for name, child in net.children.items():
            cpath = path if net.body == name else _join(path, name)
            if isinstance(child, Primitive):
                self.add_primitive(child, cpath, scope)
            else:
                self.walk(child, cpath, scope)
        for conn in net.connections:
            pps = [self.port_path(net, path, r) for r in conn]
            self.add_node(pps, f"{_join(path, '')}connection {conn}")
        for qname, q in net.quantities.items():
            V = _NetVars(self, net, path, scope)
            self.flat.quantities[_join(path, qname)] = (sp.sympify(q.build(V)), q.unit, q.doc)

    def add_primitive(self, prim: Primitive, path: str, scope: _Scope):
        if path in self.flat.primitives:
            raise ModelError("duplicate_name", f"two primitives are called {path!r}")
        self.flat.primitives[path] = prim
        self.flat.graph.add_node(path, kind=prim.kind)
        for port, dom in prim.ports.items():
            self.flat.port_domains[f"{path}.{port}"] = dom
        V = _PrimVars(self, prim, path, scope)
        for spec in prim.states():
            sym = var(f"{path}.{spec.name}")
            init = self.resolve(spec.initial, scope, f"{path} initial {spec.name}")
            self.flat.states.append(State(sym, sp.sympify(spec.rhs(V)), init, spec.storage, path, spec.unit,
                                          spec.given))
        for rel in prim.relations(V):
            self.flat.equations.append(Equation(sp.sympify(rel.expr), path, rel.role, rel.natural, rel.note))

    def add_node(self, pps: list, where: str):
        doms = {self.flat.port_domains[p].name for p in pps}
        if len(doms) > 1:
            raise ModelError("domain_mismatch", f"{where}: cannot join ports of different domains "
                             f"({', '.join(f'{p}: {self.flat.port_domains[p].name}' for p in pps)})",
                             "put a transducer (TF or GY) between them")
        for p in pps:
            if p in self.used:
                raise ModelError("port_used_twice", f"port {p} is used in two connections",
                                 "list all ports of one node in a single connection entry")
            self.used[p] = where
        dom = self.flat.port_domains[pps[0]]
        node = Node(pps, dom)
        self.flat.nodes.append(node)
        self.flat.graph.add_node(node.name, kind="node")
        for p in pps:
            self.flat.graph.add_edge(node.name, p.rsplit(".", 1)[0], port=p)
        common, summed = ("f", "e") if dom.node_kind == "b" else ("e", "f")
        first = var(f"{pps[0]}.{common}")
        minus_first = negative(first)
        for p in pps[1:]:
            self.flat.equations.append(Equation(plain_sum((var(f"{p}.{common}"), minus_first)),
                                                node.name, "node", None,
                                                "common " + ("speed" if common == "f" else "effort")))
        self.flat.equations.append(Equation(plain_sum(var(f"{p}.{summed}") for p in pps), node.name,
                                            "node", None, "balance at the node"))

    def terminate(self):
        for pp, dom in self.flat.port_domains.items():
            if pp in self.used:
                continue
            held = pp in self.fixed
            v = var(f"{pp}.{'f' if held else dom.free_variable}")
            node = Node([pp], dom, origin="termination", held=held)
            self.flat.nodes.append(node)
            self.flat.equations.append(Equation(v, node.name, "termination", v,
                                                "held, not connected (flow 0)" if held else
                                                "free end (effort 0)" if dom.free_variable == "e"
                                                else "open port (flow 0)"))

    def resolve_positions(self):
        """Replace every position read by the expression of the one element that determines the
        position of its node (or the read's default where the port is not connected), then the states'
        initial values that refer to other states by those states' initial values.  Two providers of one
        node, a read that depends on itself and a node no element positions are recorded as
        :class:`PositionProblem` records (the check words them; the first provider or the frame pose
        stands in meanwhile), and the position graph is kept in ``position_providers``,
        ``position_reads`` and ``position_states``."""
        if not self.reads and not self.positions:
            return
        node_of = {p: n for n in self.flat.nodes for p in n.ports}
        fl = self.flat
        states = {s.symbol for s in fl.states}
        symbols_memo: dict = {}       # free_symbols of the shared subexpressions, worked out once

        def symbols(e):
            return free_symbols(e, symbols_memo)

        provider: dict = {}
        for pp, (expr, owner) in self.positions.items():
            fl.position_providers[pp] = owner
            fl.position_states.setdefault(owner, set()).update(
                v for v in symbols(expr) if v not in self.reads and v in states)
            node = node_of[pp]
            if node.name in provider:        # two outputs joined: reported by the check, the first one kept
                fl.position_problems.append(PositionProblem("position_overdetermined",
                                                            [provider[node.name][2], owner],
                                                            [provider[node.name][0], pp]))
                continue
            provider[node.name] = (pp, expr, owner)
        resolved: dict = {}
        looped: set = set()

        def value(ph, stack):
            if ph in resolved:
                return resolved[ph]
            pp, default, owner = self.reads[ph]
            if ph in stack:                  # reported by the check; the frame pose stands in meanwhile
                cycle = stack[stack.index(ph):]
                if frozenset(self.reads[c][2] for c in cycle) not in looped:
                    looped.add(frozenset(self.reads[c][2] for c in cycle))
                    fl.position_problems.append(PositionProblem(
                        "position_loop", list(dict.fromkeys(self.reads[c][2] for c in cycle)),
                        [self.reads[c][0] for c in cycle]))
                return default
            node = node_of[pp]
            prov = provider.get(node.name)
            fl.position_reads[pp] = (owner, None if prov is None else prov[2], default)
            if prov is None and len(node.ports) > 1:
                fl.position_problems.append(PositionProblem("position_undetermined", [owner], [pp]))
            expr = default if prov is None else prov[1]
            subs = {s: value(s, stack + (ph,)) for s in symbols(expr) if s in self.reads}
            resolved[ph] = substitute(expr, subs)
            return resolved[ph]

        for ph in self.reads:
            value(ph, ())
        memo: dict = {}        # one walk of each subexpression the expressions below share

        def put(e):
            return substitute(sp.sympify(e), resolved, memo)

        for eq in fl.equations:
            if symbols(eq.expr) & resolved.keys():
                eq.expr = put(eq.expr)
        fl.closures = [(st, [put(r) for r in res], owner) for st, res, owner in fl.closures]
        fl.closed_forms = {k: map_closed_form(cf, put) for k, cf in fl.closed_forms.items()}
        fl.conditions = [(put(e), *rest) for e, *rest in fl.conditions]
        fl.monitors = [(put(e), *rest) for e, *rest in fl.monitors]
        fl.quantities = {k: (put(e), u, d) for k, (e, u, d) in fl.quantities.items()}
        fl.sketches = [(o, sk, [tuple(put(v) for v in pt) for pt in pts]) for o, sk, pts in fl.sketches]
        for s in fl.states:
            s.rhs = put(s.rhs)
            s.initial = put(s.initial)
        # initial values that read other states' initial values (a dyad's start pose from its drive's):
        # substituted once each, in dependency order; a circle (only after a position loop, which the
        # check reports) is left unsubstituted, since repeated substitution around it grows without end
        by_symbol = {s.symbol: s for s in fl.states}
        reads = nx.DiGraph()
        reads.add_nodes_from(by_symbol)
        reads.add_edges_from((d, s.symbol) for s in fl.states for d in symbols(s.initial) & by_symbol.keys())
        if not nx.is_directed_acyclic_graph(reads):
            circle = [a for a, _b in nx.find_cycle(reads)]
            fl.position_problems.append(PositionProblem(
                "position_loop", sorted({fl.element_of(str(v)) for v in circle}), [],
                "initial values of states depend on each other in a circle"))
            return
        for sym in nx.topological_sort(reads):
            s = by_symbol[sym]
            deps = symbols(s.initial) & by_symbol.keys()
            if deps:
                s.initial = substitute(s.initial, {d: by_symbol[d].initial for d in deps})


def map_closed_form(cf: ClosedForm, f, n: int | None = None, where: str = "") -> ClosedForm:
    """``cf`` with ``f`` applied to every expression (an angle's pair entry by entry); with ``n``,
    checked against a closure of ``n`` states (``where``: the element, for the error)."""
    if n is not None and (not 1 <= len(cf.branches) <= 2 or any(len(b) != n for b in cf.branches)
                          or (len(cf.branches) == 2) != (cf.select is not None)):
        raise ModelError("bad_closed_form", f"{where}: a closed form needs one or two branches of {n} entries "
                         "each, and a select expression exactly when it has two",
                         "give one entry per closure state in every branch")
    branches = [[tuple(f(e) for e in v) if isinstance(v, (tuple, list)) else f(v) for v in b] for b in cf.branches]
    return ClosedForm(branches, None if cf.select is None else f(cf.select))


def closure_order(closures) -> list | None:
    """The indices of ``closures`` (``FlatNetwork.closures``) in an order in which every closure's
    residuals need only the states of closures before it; None if some need each other in a circle
    (no structural order: a group the closures cannot solve one after the other)."""
    order = nx.DiGraph()
    order.add_nodes_from(range(len(closures)))
    owner_of = {s: k for k, (states, _r, _o) in enumerate(closures) for s in states}
    for k, (_s, residuals, _o) in enumerate(closures):
        for r in residuals:
            for v in sp.sympify(r).free_symbols:
                if v in owner_of and owner_of[v] != k:
                    order.add_edge(owner_of[v], k)
    if not nx.is_directed_acyclic_graph(order):
        return None
    return list(nx.topological_sort(order))


def _component(pp: str) -> str:
    """``"crank.b.x"`` -> ``"x of crank.b"`` for messages."""
    head, comp = pp.rsplit(".", 1)
    return f"{comp} of {head}"


class _PrimVars:
    """Variable resolver handed to a primitive: local names -> global symbols."""

    t = T

    def __init__(self, fl: _Flattener, prim: Primitive, path: str, scope: _Scope):
        self.fl, self.prim, self.path, self.scope = fl, prim, path, scope

    def e(self, port):
        return var(f"{self.path}.{port}.e")

    def f(self, port):
        return var(f"{self.path}.{port}.f")

    def x(self, state):
        return var(f"{self.path}.{state}")

    def expr(self, e, subs=None):
        return self.fl.resolve(e, self.scope, f"{self.path} ({self.prim.kind})", subs)

    def input(self, value, name="u"):
        """A named input ``path.u`` whose value is the expression ``value`` of time."""
        sym = var(f"{self.path}.{name}")
        self.fl.flat.inputs[sym] = self.expr(value)
        return sym

    def param(self, name):
        value = self.prim.params[name]
        if isinstance(value, sp.Basic) and value.free_symbols:
            return self.expr(value)
        g = var(f"{self.path}.{name}")
        self.fl.flat.params[g] = float(value)
        return g


class _NetVars:
    """Resolver for network quantities: ``child.port`` / ``child.state`` -> global symbols."""

    t = T

    def __init__(self, fl: _Flattener, net: Network, path: str, scope: _Scope):
        self.fl, self.net, self.path, self.scope = fl, net, path, scope

    def e(self, ref):
        return var(self.fl.port_path(self.net, self.path, ref) + ".e")

    def f(self, ref):
        return var(self.fl.port_path(self.net, self.path, ref) + ".f")

    def x(self, ref):
        return var(self.fl.state_path(self.net, self.path, ref))

    def param(self, name):
        return self.fl.resolve(sp.Symbol(name), self.scope, self.path or "<root>")

    def quantity(self, ref):
        return self.fl.flat.quantities[_join(self.path, ref)][0]


@bulk
def flatten(root: Network) -> FlatNetwork:
    """Flatten ``root`` (a scene) into its primitive graph and equations."""
    fl = _Flattener()
    fl.walk(root, "", None)
    for name, child in root.children.items():
        ports = child.ports if isinstance(child, Primitive) else child.ports
        for port in ports:
            fl.flat.external_ports[f"{name}.{port}"] = fl.port_path(root, "", f"{name}.{port}")
    for name, child in root.children.items():
        for port, kind in (getattr(child, "bundles", None) or {}).items():
            fl.flat.bundles[f"{name}.{port}"] = kind
    fl.terminate()
    fl.resolve_positions()
    for k, (owner, _sk, pts) in enumerate(fl.flat.sketches):      # drawable as outputs (multipole.drawing)
        for j, (x, y) in enumerate(pts):
            fl.flat.quantities[f"{owner}.sketch{k}.{j}.x"] = (x, "m", "drawing point x")
            fl.flat.quantities[f"{owner}.sketch{k}.{j}.y"] = (y, "m", "drawing point y")
    return fl.flat
