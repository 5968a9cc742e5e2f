"""The registered checks: each turns what the causality analyser found (or the assembled
equations) into diagnostics in the user's words.

The analyser (:mod:`multipole.causality`) is the algorithm: it records *findings* — equations
that are redundant, a locked loop, states it put into derivative causality, variables nothing
determines — as :class:`~multipole.causality.Finding` objects in internal names.  A check here is
a function registered with :func:`multipole.diagnostics.register` under its diagnostic code; it
reads a :class:`Context` and yields :class:`~multipole.diagnostics.Diagnostic` objects.  Every
message names the netlist's elements, ports and expressions (:class:`Names`), never the
primitives and nodes an element is built of.

Registration order is report order: the warnings about open terminals come first.
"""
from __future__ import annotations

import re
from collections import defaultdict

import networkx as nx
import numpy as np
import sympy as sp

from .diagnostics import Diagnostic, register
from .domains import bundle
from .errors import IllPosedError
from .network import PositionProblem, closure_order, var
from .primitives import T
from .stages import substitute


def listing(names) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    names = list(names)
    if not names:
        return ""
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def article(word: str) -> str:
    """``a torque``, ``an angular velocity``."""
    return f"{'an' if word[:1].lower() in 'aeiou' else 'a'} {word}"


def user_expression(expr) -> str:
    """A sympy expression in netlist syntax: ``Heaviside(x, 1)`` is written ``step(x)``, ``Max``,
    ``Min`` and ``Abs`` as ``max``, ``min`` and ``abs``."""
    expr = sp.sympify(expr)
    step = sp.Function("step")
    text = str(expr.replace(sp.Heaviside, lambda x, *_: step(x)))
    return re.sub(r"\b(Max|Min|Abs)\(", lambda m: m.group(1).lower() + "(", text)


# ---------------------------------------------------------------------------------------------
# names the user wrote

class Names:
    """Translates the analyser's internal names (primitive paths, node names, port variables)
    into the elements, ports and expressions of the netlist."""

    def __init__(self, analysis, scene=None):
        self.analysis = analysis
        self.flat = analysis.flat
        self.scene = scene
        self.user_port: dict = {}            # primitive port path -> "element.port" of the netlist
        for name, pp in self.flat.external_ports.items():
            self.user_port.setdefault(pp, name)
        self.members: dict = defaultdict(list)   # representative -> port variables aliased to it
        for v, (rep, _sign) in analysis.aliases.items():
            self.members[rep].append(v)

    def elements(self, owner: str) -> list:
        """The netlist elements an equation owner belongs to (a node: the elements it joins)."""
        if owner.startswith("node(") and owner.endswith(")"):
            return sorted({self.flat.element_of(p) for p in owner[5:-1].split(", ")})
        return [self.flat.element_of(owner)]

    def elements_of(self, owners) -> list:
        return sorted({e for o in owners for e in self.elements(o)})

    def port(self, port_path: str) -> str | None:
        """``element.port`` of the netlist for a primitive port path, None for an inner port."""
        return self.user_port.get(port_path)

    def variable(self, sym) -> str:
        """A port variable as ``the torque at shaft.b`` (or ``… inside mesh`` when no netlist port
        carries it); other symbols (states, inputs) by their own names."""
        name = sym.name
        if name.startswith("der(") and name.endswith(")"):
            return "the rate of change of " + self.variable(var(name[4:-1]))
        if name[-2:] not in (".e", ".f") or name[:-2] not in self.flat.port_domains:
            return name
        kind = name[-1]
        rep = self.analysis.aliases.get(sym, (sym, 1))[0]
        ports = sorted({self.user_port[v.name[:-2]] for v in self.members.get(rep, [sym])
                        if v.name.endswith("." + kind) and v.name[:-2] in self.user_port})
        dom = self.flat.port_domains[name[:-2]]
        noun = dom.effort if kind == "e" else dom.flow
        if ports:
            return f"the {noun} at {ports[0]}"
        return f"the {noun} inside {self.flat.element_of(name)}"

    def variables(self, syms, limit: int = 6) -> str:
        words = list(dict.fromkeys(self.variable(s) for s in syms))
        return listing(words[:limit] + (["…"] if len(words) > limit else []))

    def expression(self, element: str, expr) -> str:
        """``element``'s parameter with a step or pulse as the netlist wrote it (``value w0*step(t)``),
        else ``expr`` in netlist syntax."""
        texts = getattr(self.scene, "element_values", {}).get(element, {}) if self.scene is not None else {}
        for key, text in texts.items():
            if re.search(r"\b(step|pulse)\s*\(", str(text)):
                return f"{key} {text}"
        return "input " + user_expression(expr)


class Context:
    """What the checks read: the analysis, its user names, the scene (optional) and, on request,
    the assembled equations (``assemble()`` given by the pipeline; checks of the ``equations``
    stage run only when it is)."""

    def __init__(self, analysis, scene=None, assemble=None):
        self.analysis = analysis
        self.flat = analysis.flat
        self.scene = scene
        self.names = Names(analysis, scene)
        self._assemble = assemble
        self._equations = None
        self.assembly_error: IllPosedError | None = None

    @property
    def can_assemble(self) -> bool:
        return self._assemble is not None

    def equations(self):
        """The assembled equations, or None if assembling failed (see ``assembly_error``)."""
        if self._equations is None and self.assembly_error is None and self._assemble is not None:
            try:
                self._equations = self._assemble()
            except IllPosedError as exc:
                self.assembly_error = exc
        return self._equations

    def findings(self, kind: str) -> list:
        return [f for f in self.analysis.findings if f.kind == kind]


# ---------------------------------------------------------------------------------------------
# wording shared by several checks

def element_graph(flat) -> nx.Graph:
    """Bipartite graph of top-level elements and the nodes joining them."""
    g = nx.Graph()
    for node in flat.nodes:
        if node.origin != "connection":
            continue
        for p in node.ports:
            g.add_edge(("n", node.name), ("el", flat.element_of(p)))
    return g


def loop_path(flat, elements) -> list:
    """The loop through ``elements`` as element names, closed (first == last).  A node of the loop
    is shown by an element hanging on it outside the loop (e.g. the shaft inertia) and left out
    when there is none; with no loop in the graph the elements are listed."""
    els = set(elements)
    g = element_graph(flat)
    best: list = []
    for cyc in nx.cycle_basis(g):
        members = {n for k, n in cyc if k == "el"}
        if len(els & members) > len(els & {n for k, n in best if k == "el"}):
            best = cyc
    if not best:
        return sorted(els)
    loop_elements = {n for k, n in best if k == "el"}
    start = next((i for i, (k, _) in enumerate(best) if k == "n"), 0)
    best = best[start:] + best[:start]
    names = []
    for k, n in best:
        if k == "el":
            names.append(n)
            continue
        outside = sorted({m for _kk, m in g.neighbors((k, n)) if m not in loop_elements})
        if outside:
            names.append(outside[0])
    names = [n for i, n in enumerate(names) if i == 0 or n != names[i - 1]]
    return names + names[:1]


def _redundancy(ctx: Context, finding) -> Diagnostic:
    """Redundant equations with no unknown to absorb them: two sources, or a rigid loop."""
    flat, names = ctx.flat, ctx.names
    eqs = [ctx.analysis.equations[i] for i in finding.equations]
    elements = names.elements_of(e.owner for e in eqs)
    sources = sorted({flat.element_of(e.owner) for e in eqs if e.role == "source"})
    kinds = {s.name.rsplit(".", 1)[1] for e in eqs for s in e.expr.free_symbols if "." in s.name}
    flows = "f" in kinds and "e" not in kinds
    if sources:
        dom = flat.port_domains[next(p for p in flat.port_domains if flat.element_of(p) == sources[0])]
        word = dom.flow if flows else dom.effort
        other = dom.effort if flows else dom.flow
        where = ("rigid node" if flows else "massless node") if dom.node_kind == "b" else \
            ("series branch" if flows else "node")
        return Diagnostic(
            "source_conflict",
            f"{listing(sources)} {'both' if len(sources) == 2 else 'all'} impose the {word} on the same "
            f"{where} ({' + '.join(elements)}): {'kinematic' if flows else 'static'} over-determination; "
            f"the {other} there is left undetermined ({'static' if flows else 'kinematic'} under-determination)",
            f"remove one source or put {dom.compliance} between them" if flows else
            f"put {dom.inertia} between the sources or drive one side with {article(dom.flow + ' source')} instead",
            elements=elements)
    path = loop_path(flat, elements)
    outer = [flat.port_domains[pp] for name, pp in flat.external_ports.items()
             if flat.element_of(name) in elements]      # the domain of the loop's netlist ports
    dom = max(outer, key=outer.count) if outer else next(iter(flat.port_domains.values()))
    if flows:
        return Diagnostic(
            "kinematic_overdetermination",
            f"kinematic over-determination: the rigid loop through {', '.join(elements)} imposes the same "
            f"{dom.flow} twice (consistent ratios); static under-determination: nothing decides how the "
            f"{dom.effort} splits between the parallel paths",
            "make one coupling in this loop elastic", elements=elements, path=path)
    return Diagnostic(
        "static_overdetermination",
        f"static over-determination: the {dom.effort} around {', '.join(elements)} is imposed twice; "
        f"kinematic under-determination: nothing decides how the {dom.flow} splits",
        f"add a storage element ({dom.inertia} or {dom.compliance}) in this loop", elements=elements,
        path=path)


def _redundancies(ctx: Context, code: str):
    for f in ctx.findings("redundant"):
        d = _redundancy(ctx, f)
        if d.code == code:
            yield d


def _zero_value(flat, expr) -> bool:
    """True if a source's value is identically zero (a ground)."""
    try:
        value = sp.sympify(sp.sympify(expr).xreplace(flat.param_values()))
        return bool(value == 0) or (not value.free_symbols and float(value) == 0.0)
    except (TypeError, ValueError):
        return False


def _sources(flat):
    """``(primitive path, primitive)`` of every source that imposes a nonzero value."""
    for path, prim in flat.primitives.items():
        if prim.kind in ("Se", "Sf") and not _zero_value(flat, prim.params.get("value", 0)):
            yield path, prim


# ---------------------------------------------------------------------------------------------
# the checks, in report order

def _zeros(eq, flat, kept=frozenset()) -> set:
    """Variables the solved equations make identically zero: grounds (zero inputs) and the
    terminations of unconnected ports, propagated through the explicit solutions.  A block owned by
    an equation in ``kept`` is treated as nonzero (to see which termination causes a zero).  Zeros
    do not pass through time derivatives (state equations, differentiated constraints): a constant
    force on an open-circuit piezo gives zero velocity because the force is constant, which is
    physics, not a forgotten connection."""
    zeros = {u for u, e in flat.inputs.items() if _zero_value(flat, e)}
    for block in eq.blocks:
        if block.solution is None or kept & set(block.owners) or any(n.startswith("d/dt ") for n in block.notes):
            continue
        for v, sol in zip(block.variables, block.solution):
            sol = sp.sympify(sol)
            if sol.xreplace({z: 0 for z in sol.free_symbols & zeros}) == 0:
                zeros.add(v)
    return zeros


#: at most this many unconnected ports are tried one by one to name the one that silences a source
_MAX_CULPRITS = 24


@register("powerless_source", "warning",
          "a source whose power variable is forced to zero by an open pin or a free end the netlist "
          "left unconnected (a forgotten ground): it delivers no power and the simulation stays at rest",
          stage="equations")
def powerless_source(ctx: Context):
    eq = ctx.equations()
    if eq is None:
        return
    flat, names, aliases = ctx.flat, ctx.names, ctx.analysis.aliases
    terminations = {node.name: node for node in flat.nodes
                    if node.origin == "termination" and names.port(node.ports[0])}
    if not terminations:
        return
    zeros = _zeros(eq, flat)
    unforced = None                     # zeros with every termination treated as connected
    comp = {}
    for k, part in enumerate(nx.connected_components(element_graph(flat))):
        comp.update({n: k for kind, n in part if kind == "el"})
    for path, prim in _sources(flat):
        conj = "f" if prim.kind == "Se" else "e"
        sym = var(f"{path}.p.{conj}")
        rep = aliases.get(sym, (sym, 1))[0]
        if rep not in zeros:
            continue
        unforced = _zeros(eq, flat, frozenset(terminations)) if unforced is None else unforced
        if rep in unforced:
            continue                    # zero whatever is connected (a floating reference): by design
        element = flat.element_of(path)
        near = sorted((n for n, node in terminations.items()
                       if comp.get(flat.element_of(node.ports[0])) == comp.get(element)),
                      key=lambda n: (flat.element_of(terminations[n].ports[0]) != element, n))
        culprits = [names.port(terminations[n].ports[0]) for n in near[:_MAX_CULPRITS]
                    if rep not in _zeros(eq, flat, frozenset([n]))]
        culprits = culprits or [names.port(terminations[n].ports[0]) for n in near]
        if not culprits:
            continue
        dom = prim.ports["p"]
        first = culprits[0]
        odom = flat.port_domains[flat.external_ports[first]]
        how = f"open: no {odom.flow} flows through it" if odom.free_variable == "f" \
            else f"a free end: nothing takes up {article(odom.effort)} there"
        fix = f"connect {first} to ground (or to the rest of the circuit)" if odom.name in ("electrical", "hydraulic") \
            else f"connect {first} to the part it should drive, or to a ground"
        yield Diagnostic(
            "powerless_source",
            f"{element} can deliver no power: its {dom.flow if conj == 'f' else dom.effort} is forced to zero "
            f"because {listing(culprits[:3])} {'is' if len(culprits) == 1 else 'are'} not connected ({how}), "
            "so everything it should drive stays at rest",
            fix, elements=[element], ports=culprits[:3])


@register("isolated_subnetwork", "warning",
          "elements joined to no source, starting at rest: nothing will ever move them (a missing "
          "connection)")
def isolated_subnetwork(ctx: Context):
    flat = ctx.flat
    g = element_graph(flat)
    for name in flat.elements:
        if name and name != "<root>" and "." not in name:
            g.add_node(("el", name))
    parts = [sorted(n for k, n in part if k == "el") for part in nx.connected_components(g)]
    driven = {flat.element_of(path) for path, _ in _sources(flat)}
    if len(parts) < 2 or not driven:
        return
    values = flat.param_values()
    for part in parts:
        if set(part) & driven:
            continue
        states = [s for s in flat.states if s.storage and flat.element_of(s.owner) in part]
        if any(float(sp.sympify(s.initial).xreplace(values)) != 0.0 for s in states):
            continue            # it moves from its initial values: a separate free system
        yield Diagnostic(
            "isolated_subnetwork",
            f"{listing(part)} {'is' if len(part) == 1 else 'are'} connected to no source and "
            f"start{'s' if len(part) == 1 else ''} at rest: nothing will move there",
            "connect them to the part that is driven (a connection is probably missing), or remove them",
            elements=part)


@register("source_conflict", "error", "two sources impose the same variable (or the balance of a massless node)")
def source_conflict(ctx: Context):
    return _redundancies(ctx, "source_conflict")


@register("kinematic_overdetermination", "error",
          "a rigid loop imposes a flow twice (consistent ratios): the junction gets two flow inputs and "
          "its effort sum is one input short — static under-determination")
def kinematic_overdetermination(ctx: Context):
    return _redundancies(ctx, "kinematic_overdetermination")


@register("static_overdetermination", "error",
          "the dual: an effort is imposed twice and the corresponding flow is undetermined")
def static_overdetermination(ctx: Context):
    return _redundancies(ctx, "static_overdetermination")


@register("locked_loop", "error", "a rigid loop with inconsistent ratios: the only motion it admits is standstill")
def locked_loop(ctx: Context):
    for f in ctx.findings("locked"):
        elements = ctx.names.elements_of(ctx.analysis.equations[i].owner for i in f.equations)
        rigid = sorted({ctx.flat.element_of(ctx.analysis.equations[i].owner) for i in f.equations})
        yield Diagnostic(
            "locked_loop",
            f"locked loop: the rigid couplings {', '.join(rigid)} impose inconsistent ratios around the loop, "
            "so it admits only standstill (kinematic over-determination with no consistent motion)",
            "check the ratios (their product around the loop must be 1) or make one coupling in this loop elastic",
            elements=rigid, path=loop_path(ctx.flat, elements))


@register("input_differentiation", "error",
          "resolving derivative causality needs the time derivative of an input that has none (a step or "
          "a pulse): the response would be an impulse")
def input_differentiation(ctx: Context):
    flat = ctx.flat
    for f in ctx.findings("impulse"):
        eq = ctx.analysis.equations[f.equations[0]]
        element = flat.element_of(eq.owner)
        inputs = [u for u in eq.expr.free_symbols if u in flat.inputs]
        expr = flat.inputs[inputs[0]] if inputs else eq.expr
        yield Diagnostic(
            "input_differentiation",
            f"{element}: resolving the rigid coupling needs d/dt of its {ctx.names.expression(element, expr)}, "
            "which contains a step or pulse: the effort would be an impulse",
            "give the input a finite rise time (ramp or smooth function) or make the coupling elastic",
            elements=[element])


@register("overdetermined", "error", "equations that impose more than they can, with no storage to resolve it")
def overdetermined(ctx: Context):
    for f in ctx.findings("overdetermined"):
        owners = ctx.names.elements_of(ctx.analysis.equations[i].owner for i in f.equations)
        yield Diagnostic(
            "overdetermined", f"the equations of {', '.join(owners)} impose more than they can "
            "(structurally over-determined) and the analyser found no storage to resolve it",
            "look for two rigid paths or two sources acting on the same variable", elements=owners)


@register("missing_cross_coupling", "error",
          "variables no equation determines because a branch ends where the element's structure needs a "
          "cross-coupling the parameters leave out; the element names it and says how to add it")
def missing_cross_coupling(ctx: Context):
    flat, names = ctx.flat, ctx.names
    for f in ctx.findings("placeholder"):
        element = flat.element_of(f.path)
        owner = f.path.rsplit(".", 1)[0] if "." in f.path else f.path
        needs, fix = f.words
        nouns = set()
        for sym in f.variables:
            dom = flat.port_domains[sym.name[:-2]]
            nouns.add(dom.effort if sym.name.endswith(".e") else dom.flow)
        sums = [s[len(element) + 1:] if s.startswith(element + ".") else s for s in f.sums]
        where = (f"the {'/'.join(sorted(nouns))} sums at {' and '.join(sums)} inside {element} are" if sums else
                 "the junctions that need it are")
        ports = sorted({names.port(s.name[:-2]) for s in f.variables if names.port(s.name[:-2])})
        yield Diagnostic(
            "missing_cross_coupling",
            f"{element}: {needs}. Nothing determines {names.variables(f.variables)}, so {where} one input short "
            f"(under-determined)",
            fix.format(element=element, owner=owner) if fix else
            f"complete {element} so that its {f.path[len(element) + 1:] or 'placeholder'} is a cross-coupling (I, R or C)",
            elements=[element], ports=ports)


@register("underdetermined", "error", "variables no equation determines")
def underdetermined(ctx: Context):
    flat, names = ctx.flat, ctx.names
    for f in ctx.findings("undetermined"):
        missing = f.variables
        electrical = any(s.name[:-2] in flat.port_domains and s.name.endswith(".e")      # a floating potential
                         and flat.port_domains[s.name[:-2]].name in ("electrical", "hydraulic")
                         for s in list(missing) + list(f.related))
        ports = sorted({names.port(s.name[:-2]) for s in missing if names.port(s.name[:-2])})
        elements = sorted({flat.element_of(s.name) for s in missing if "." in s.name})
        yield Diagnostic(
            "underdetermined",
            f"nothing determines {names.variables(missing)}",
            "add a ground (reference potential) to the circuit" if electrical else
            "add a storage element, a source or a ground where these variables live",
            elements=elements, ports=ports)


# ---------------------------------------------------------------------------------------------
# positions and closures (multipole.network: bundles, positions, reads, Closure)

def _user_ports(ctx: Context, pps) -> list:
    """The netlist ports of primitive port paths, a bundle's components folded into the bundle
    (``rocker.b2.x``, ``rocker.b2.y`` -> ``rocker.b2``)."""
    out = []
    for pp in pps:
        port = ctx.names.port(pp) or pp
        head = port.rsplit(".", 1)[0]
        out.append(head if head in ctx.flat.bundles else port)
    return list(dict.fromkeys(out))


_FRAME = "the frame"


def position_graph(flat) -> nx.DiGraph:
    """Which element's positions each element reads: an edge ``provider -> reader`` (the frame,
    ``"the frame"``, provides the pose of every anchor left unconnected)."""
    g = nx.DiGraph()
    g.add_nodes_from(set(flat.position_providers.values()))
    for reader, provider, _default in flat.position_reads.values():
        g.add_edge(provider or _FRAME, reader)
    return g


def _closed_chain(flat, a: str, b: str) -> list:
    """The loop two elements close when both determine one position: from their nearest common
    ancestor in the position graph (or the frame) down to ``a``, across to ``b`` and back up."""
    g = position_graph(flat)
    g.add_edges_from((_FRAME, n) for n in list(g.nodes) if n != _FRAME and not g.in_degree(n))
    best = None
    for c in (nx.ancestors(g, a) | {a}) & (nx.ancestors(g, b) | {b}):
        pa, pb = nx.shortest_path(g, c, a), nx.shortest_path(g, c, b)
        if best is None or (len(pa) + len(pb), c == _FRAME) < (len(best[0]) + len(best[1]), best[0][0] == _FRAME):
            best = pa, pb
    pa, pb = best or ([_FRAME, a], [_FRAME, b])
    return pa + pb[::-1]


@register("position_overdetermined", "error",
          "two elements determine the same position (two outputs joined): the loop they close is "
          "over-constrained, a passive constraint whose joint forces are indeterminate")
def position_overdetermined(ctx: Context):
    groups: dict = {}
    for p in ctx.flat.position_problems:
        if p.code == "position_overdetermined":
            groups.setdefault(tuple(p.owners), []).extend(p.ports)
    for (first, second), pps in groups.items():
        ports = _user_ports(ctx, pps)
        chain = _closed_chain(ctx.flat, first, second)
        yield Diagnostic(
            "position_overdetermined",
            f"{first} and {second} both determine the position of the node joining {listing(ports)}: the loop "
            f"{' -> '.join(chain)} is closed twice (over-constrained: a passive constraint, so its joint forces "
            "are indeterminate)",
            f"join {ports[-1]} to an anchor (an input) of an element that follows {second} instead of to an output "
            f"of {first}, or remove {second}", elements=sorted({first, second}), ports=ports, path=chain)


@register("position_loop", "error",
          "positions that depend on each other in a closed chain of elements: no structural order "
          "(a group of class 3 or higher that the elements cannot solve one after the other)")
def position_loop(ctx: Context):
    found = [p for p in ctx.flat.position_problems if p.code == "position_loop"]
    if not found and ctx.flat.closures and closure_order(ctx.flat.closures) is None:
        found = [PositionProblem("position_loop", sorted({o for _s, _r, o in ctx.flat.closures}), [])]
    told = set()
    for p in found:
        owners = p.owners or sorted(set(ctx.flat.position_providers.values()))
        if not p.ports and frozenset(owners) in told:
            continue        # the start values' circle that follows from a loop already reported
        told.add(frozenset(owners))
        yield Diagnostic(
            "position_loop",
            f"the positions of {listing(owners)} depend on each other in a closed chain"
            + (f" (through {listing(_user_ports(ctx, p.ports))})" if p.ports else "")
            + ": there is no structural order in which each element is anchored on bodies determined before it "
            "(a group of class 3 or higher)",
            "anchor every element on the frame or on outputs of elements before it in the chain; a group of "
            "higher class needs one element that solves the whole group", elements=sorted(set(owners)),
            ports=_user_ports(ctx, p.ports), path=owners + owners[:1] if len(owners) > 1 else [])


@register("position_undetermined", "error",
          "an anchor joined to ports none of which determines a position (no output of a moving element)")
def position_undetermined(ctx: Context):
    for p in ctx.flat.position_problems:
        if p.code == "position_undetermined":
            port = _user_ports(ctx, p.ports)[0]
            yield Diagnostic(
                "position_undetermined", f"no element determines the position of {port}, which {p.owners[0]} "
                "reads: it is joined only to ports that carry no position",
                "join it to an output port of a moving element, or leave it unconnected to fix it to the frame",
                elements=p.owners, ports=[port])


def _start_value(flat, expr) -> complex | None:
    """``expr`` at t = 0 in the initial state (states by their initial values), or None."""
    initial = {s.symbol: s.initial for s in flat.states}
    try:
        value = substitute(sp.sympify(substitute(sp.sympify(expr), initial)), initial)
        value = substitute(sp.sympify(substitute(sp.sympify(value), flat.param_values())), {T: 0})
        return complex(value.evalf())
    except (TypeError, ValueError, ArithmeticError):
        return None


@register("cannot_assemble", "error",
          "a closure that cannot be assembled at t = 0: its elements do not reach (the start formula has "
          "no real solution); the element and by how much are named")
def cannot_assemble(ctx: Context):
    flat = ctx.flat
    failed = set()
    for expr, text, unit, owner in flat.conditions:
        value = _start_value(flat, expr)
        if owner in failed or value is None or abs(value.imag) > 1e-12 * (1 + abs(value.real)) or value.real >= -1e-12:
            continue
        failed.add(owner)
        yield Diagnostic("cannot_assemble", f"{owner} cannot be assembled at t = 0: {text} by {-value.real:.3g}"
                         + (f" {unit}" if unit else ""),
                         f"change the lengths or the anchor positions of {owner} (or the start pose of the elements "
                         "before it) so that it closes", elements=[owner])
    if failed:
        return          # the start values downstream of a failed closure are not real either
    for states, _res, owner in flat.closures:
        start = {s.symbol: s.initial for s in flat.states if s.symbol in states}
        bad = [s for s, e in start.items() if (v := _start_value(flat, e)) is None or not np.isfinite(v)
               or abs(v.imag) > 1e-9 * (1 + abs(v.real))]
        if bad:
            yield Diagnostic("cannot_assemble", f"{owner} cannot be assembled at t = 0: the start value of "
                             f"{listing(s.name for s in bad)} is not a real number",
                             f"change the lengths or anchor positions of {owner} so that it closes", elements=[owner])


@register("redundant_closure", "error",
          "a closure whose relations are not independent (a passive constraint): the positions are consistent "
          "but the joint forces it carries are indeterminate")
def redundant_closure(ctx: Context):
    flat = ctx.flat
    claimed: dict = {}
    values = flat.param_values()
    rng = np.random.default_rng(1)
    for states, residuals, owner in flat.closures:
        twice = [s for s in states if s in claimed]
        for s in states:
            claimed.setdefault(s, owner)
        J = sp.Matrix(residuals).jacobian(list(states)).xreplace(values)
        ranks = []
        for _ in range(3):
            point = {v: sp.Float(rng.uniform(-3, 3)) for v in J.free_symbols}
            try:
                M = np.array(J.xreplace(point).evalf(), dtype=float)
            except (TypeError, ValueError):
                continue
            if np.all(np.isfinite(M)):
                ranks.append(np.linalg.matrix_rank(M) if M.size else 0)
        rank = max(ranks) if ranks else len(residuals)
        if twice or rank < len(residuals):
            what = (f"{listing(s.name for s in twice)} {'is' if len(twice) == 1 else 'are'} already bound by "
                    f"the closure of {claimed[twice[0]]}") if twice else \
                f"only {rank} of its {len(residuals)} position relations are independent"
            yield Diagnostic("redundant_closure", f"{owner}: {what}, so the loop is over-constrained (a passive "
                             "constraint: the joint forces it carries are indeterminate)",
                             f"remove the redundant relation (a joint or link) from {owner}, or free one of its joints",
                             elements=sorted({flat.element_of(o) for o in {owner} | {claimed[s] for s in twice}}))


@register("singular_loop", "error", "an algebraic loop whose equations are singular: it has no unique solution",
          stage="equations")
def singular_loop(ctx: Context):
    ctx.equations()
    exc = ctx.assembly_error
    if exc is None or exc.code != "singular_loop":
        return
    owners = getattr(exc, "owners", None)    # the assembly words it in the netlist's names
    yield Diagnostic("singular_loop", exc.message, exc.fix, elements=ctx.names.elements_of(owners) if owners else [])


@register("derivative_causality", "info",
          "storage elements coupled rigidly: one is put into derivative causality and resolved into an "
          "effective inertia or compliance")
def derivative_causality(ctx: Context):
    flat = ctx.flat
    for f in ctx.findings("demoted"):
        elements = ctx.names.elements_of(ctx.analysis.equations[i].owner for i in f.equations)
        states = {s.symbol: s for s in flat.states}
        prims = [flat.primitives[states[s].owner] for s in f.states]
        kinds = {p.kind for p in prims}
        inertia = {"electrical": "inductance", "hydraulic": "inertance"}     # mechanical: inertia
        domains = {next(iter(p.ports.values())).name for p in prims}
        what = f"an effective {inertia.get(domains.pop(), 'inertia') if len(domains) == 1 else 'inertia'}" \
            if kinds <= {"I"} else "an effective compliance" if kinds <= {"C", "CField"} else "effective storage"
        yield Diagnostic(
            "derivative_causality",
            f"storage joined rigidly through {', '.join(elements)}: "
            f"{', '.join(s.name for s in f.states)} in derivative causality, resolved into {what} "
            f"(constrained-state form)", elements=elements)


@register("initial_values", "info",
          "initial values of storages in derivative causality made consistent with the rigid couplings "
          "at t = 0 (the simulation starts there)", stage="equations")
def initial_values(ctx: Context):
    eq = ctx.equations()
    for d in (eq.diagnostics if eq is not None else []):
        if d.code == "derivative_causality":       # the consistent start the assembly computed
            yield Diagnostic("initial_values", d.message, d.fix, elements=d.elements)


@register("algebraic_loop", "info", "a loop without storage: solved symbolically when linear, by Newton otherwise",
          stage="equations")
def algebraic_loop(ctx: Context):
    eq = ctx.equations()        # the assembly words its loops (multipole.equations._loop_diag, via Names)
    yield from (d for d in (eq.diagnostics if eq is not None else []) if d.code == "algebraic_loop")


@register("mobility", "info",
          "the mechanism's degrees of freedom from its position graph (displacement states minus closure "
          "relations) and the structural order: which element determines which bodies, anchored on what")
def mobility(ctx: Context):
    flat = ctx.flat
    if not flat.closures:               # nothing closes a loop (a drive alone, a 1-D band): no mobility to count
        return
    g = position_graph(flat)
    if not nx.is_directed_acyclic_graph(g):
        return                          # position_loop says why
    relations = defaultdict(int)
    own = {o: set(states) for o, states in flat.position_states.items()}
    for states, residuals, owner in flat.closures:
        relations[owner] += len(residuals)
        own.setdefault(owner, set()).update(states)
    outputs = defaultdict(list)
    for pp, owner in flat.position_providers.items():
        outputs[owner].append(pp)
    steps, total_states, total_rel = [], 0, 0
    for owner in nx.topological_sort(g):
        if owner == _FRAME:
            continue
        n, k = len(own.get(owner, ())), relations[owner]
        total_states, total_rel = total_states + n, total_rel + k
        on = sorted(g.predecessors(owner), key=lambda o: (o == _FRAME, o))
        free = (f"{n} displacement(s) bound by {k} closure relation(s)" + (f", {n - k} free" if n != k else "")
                if k else f"{n} free displacement(s)")
        made = listing(_user_ports(ctx, outputs[owner])) if outputs[owner] else "no output"
        steps.append(f"{owner} ({flat.elements.get(owner, '?')}: {free}) on {listing(on) or _FRAME} "
                     f"determines {made}")
    F = total_states - total_rel
    yield Diagnostic(
        "mobility",
        f"mobility F = {F} ({total_states} displacement state(s) - {total_rel} closure relation(s)); structural "
        f"order: {'; '.join(steps)}", elements=[s.split(" ", 1)[0] for s in steps])


def _termination(node, held_by=None) -> str:
    """How an unconnected port is terminated; ``held_by``: the netlist port of a held termination its
    flow is rigidly tied to (a bearing's support on a frame-fixed housing), if any."""
    if node.held:
        return "held: fixed to the frame (flow 0)"
    if held_by:
        return f"held by the frame (its motion is that of {held_by}, fixed to the frame; no load taken: effort 0)"
    return "free end (effort 0)" if node.domain.free_variable == "e" else "open (flow 0)"


def _held_by(ctx: Context) -> dict:
    """``{primitive port path: netlist port}``: the unconnected free ports whose flow is rigidly tied
    (one alias of the analysis) to the flow of a held termination, i.e. frame-fixed too, and that
    held port."""
    aliases = ctx.analysis.aliases

    def rep(pp):
        v = var(pp + ".f")
        return aliases.get(v, (v, 1))[0]
    held = {rep(n.ports[0]): ctx.names.port(n.ports[0]) for n in ctx.flat.nodes
            if n.origin == "termination" and n.held}
    return {n.ports[0]: held[rep(n.ports[0])] for n in ctx.flat.nodes
            if n.origin == "termination" and not n.held and rep(n.ports[0]) in held and held[rep(n.ports[0])]}


@register("unconnected_port", "info", "a port nobody connected takes its default termination (a bundle port "
          "is listed once: an anchor left unconnected is fixed to the frame at its frame pose)")
def unconnected_port(ctx: Context):
    flat = ctx.flat
    held_by = _held_by(ctx)
    loose: dict = {}                                  # netlist port -> its termination node
    for node in flat.nodes:
        port = ctx.names.port(node.ports[0]) if node.origin == "termination" else None
        if port:
            loose[port] = node
    shown = set()
    for port, node in loose.items():
        head = port.rsplit(".", 1)[0]
        if head in flat.bundles and head not in shown:
            parts = bundle(flat.bundles[head]).ports(head)
            texts = {_termination(loose[p]) for p in parts if p in loose}
            if all(p in loose for p in parts) and len(texts) == 1:
                shown.add(head)
                pose = [(p.rsplit(".", 1)[1], flat.position_reads.get(flat.external_ports.get(p))) for p in parts]
                pose = [(c, _start_value(flat, r[2])) for c, r in pose if r is not None]
                at = ", ".join(f"{c} = {v.real:.6g}" for c, v in pose if v is not None)
                yield Diagnostic("unconnected_port", f"{head} is not connected: {texts.pop()}"
                                 + (f", at its frame pose {at}" if at and node.held else ""),
                                 elements=[head.split(".")[0]], ports=[head])
                continue
        if head in shown:
            continue
        yield Diagnostic("unconnected_port", f"{port} is not connected: {_termination(node, held_by.get(node.ports[0]))}",
                         elements=[port.split('.')[0]], ports=[port])


@register("degrees_of_freedom", "info", "the states the simulation integrates")
def degrees_of_freedom(ctx: Context):
    an = ctx.analysis
    yield Diagnostic(
        "degrees_of_freedom",
        f"{len(an.states)} state(s) integrated: {', '.join(s.name for s in an.states) or 'none'}"
        + (f"; in derivative causality: {', '.join(s.name for s in an.demoted)}" if an.demoted else ""))
