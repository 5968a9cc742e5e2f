"""Weber-style block diagrams of a scene (``multipole diagram FILE -o figure.png|svg``).

The diagram shows the flattened primitives of a scene the way Weber draws multipoles
(Mehrpol-Blockschaltbilder): two rows per element, the flows ("Bewegungen") on top and the efforts
("Kräfte") below, with

* a **Σ box** where a junction or node sums its efforts (type b) or flows (type a) and a **dot**
  ("Verzweigungspunkt") where it distributes the common variable;
* **ratio blocks** for transformers in both rows (the effort block works against the flow block);
* **cross-couplings** I, R, C (and sources, taps, C-fields) as blocks between the two rows;
* an **arrow for every port variable** pointing away from the side that computes it, as found by
  the causality analyser (:func:`multipole.pipeline.check`);
* storage in **derivative causality** drawn dashed in purple (``d/dt`` instead of ``∫``);
* the elements named in **error diagnostics** drawn in red, with the diagnostic's words below.

Two steps, both public: :func:`layout` turns an :class:`~multipole.causality.Analysis` into a
:class:`Diagram` (blocks with kind/label/row/position, arrows with source/target/colour/route)
and :func:`render` draws it with matplotlib (Agg).  Tests assert on the :class:`Diagram`.

Geometry is in drawing units (one unit is :data:`SCALE` inches in the figure).
"""
from __future__ import annotations

import re
import textwrap
from fractions import Fraction
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import sympy as sp

from .causality import Analysis, _alias_pair
from .network import var
from .primitives import T

#: inches per drawing unit
SCALE = 0.8

FLOW = "#1f5fa8"        #: colour of flow signals (Bewegungen)
EFFORT = "#303030"      #: colour of effort signals (Kräfte)
CONFLICT = "#d62728"    #: elements named by an error diagnostic, undetermined variables
DERIVATIVE = "#7b3fa0"  #: storage in derivative causality

#: primitives drawn as one block between the two rows (cross-couplings, sources, taps); any other
#: one-port kind an element library defines is drawn there too
MIDDLE_KINDS = ("I", "C", "R", "Se", "Sf", "Tap", "CField")
#: primitives drawn with a block in each row
ROW_KINDS = ("TF", "MTF", "GY", "junction_a", "junction_b")

_DY = 1.0            # flow row -> middle -> effort row spacing
_LANE = 2 * _DY + 1.55
_SUB = 1.25          # width of one item inside an element
_HANG = 1.1          # spacing of cross-couplings hanging under the same junction
_TRACK = 0.32        # spacing of vertical tracks in a gap between columns
_CORRIDOR = 0.28     # spacing of horizontal return tracks above/below the lanes
_FONT = 8.0          # block labels [pt]
_RATIO_CHARS = 14    # longest label written into a ratio block; longer ones go to a footnote
_NOTE_CHARS = 24     # longest second line of a block
COLLAPSE_ABOVE = 4   #: families of identical sub-elements longer than this are drawn collapsed
DRAWN_HEAD = 2       #: members drawn before the placeholder of a collapsed family (plus the last)


@dataclass
class Block:
    """One drawn block.

    ``kind``: ``sum`` (Σ), ``dot`` (branching point), ``ratio`` (TF/MTF), ``gyrator``, ``storage``
    (I, C, C-field), ``resistance`` (R), ``source`` (Se, Sf), ``tap``, ``terminal`` (an unconnected
    port), ``other`` (a one-port kind defined by an element library), ``repeat`` (the placeholder
    of identical sub-elements drawn collapsed).
    ``row``: ``"f"`` (flow row), ``"e"`` (effort row) or ``"x"`` (between the rows).
    ``owner`` is the primitive path or the node name whose equations the block stands for;
    ``element`` the top-level element it belongs to (``""`` for a node joining elements).
    ``identity`` marks blocks that only pass a value on (dots, two-port sums).
    ``bus``: a junction with many connections drawn as a line outside the rows (a branching bar
    for its common variable, a collecting line ending in a Σ for its sum).
    """

    id: str
    kind: str
    label: str
    row: str
    owner: str
    element: str
    note: str = ""
    x: float = 0.0
    y: float = 0.0
    w: float = 0.0
    h: float = 0.0
    identity: bool = False
    conflict: bool = False
    derivative: bool = False
    bus: bool = False


@dataclass
class Arrow:
    """The signal of one port variable: from the block that computes it to the one that uses it.

    ``determined`` is False when no equation computes the variable (then ``source``/``target``
    are just the two ends and the wire is drawn red and dashed without a head).
    ``points`` is the drawn route from source to target; ``drawn`` is False for the second
    variable of a two-port connection inside an element (same wire as its partner).
    ``hidden``: the variable belongs to a collapsed sub-element (no route); ``multiplicity`` > 1:
    the drawn wire stands for that many wires to or from a collapsed run.
    """

    variable: str
    row: str
    source: str
    target: str
    determined: bool = True
    colour: str = ""
    points: list = field(default_factory=list)
    head: bool = True
    drawn: bool = True
    hidden: bool = False
    multiplicity: int = 1


@dataclass
class Group:
    """The frame of one top-level element around its blocks."""

    element: str
    label: str
    x0: float
    y0: float
    x1: float
    y1: float
    conflict: bool = False


@dataclass
class Diagram:
    """Drawing model of a scene: what :func:`render` draws and what the tests inspect."""

    title: str
    subtitle: str
    blocks: dict
    arrows: list
    groups: list
    messages: list          # (colour, text) lines shown below the diagram
    lanes: int
    extent: tuple           # xmin, xmax, ymin, ymax in drawing units
    has_derivative: bool = False
    has_conflict: bool = False
    captions: tuple = ("", "")   # what the flows and efforts are, for the row captions
    lane_h: float = _LANE        # vertical distance between stacked lanes
    subgroups: list = field(default_factory=list)   # frames of networks nested inside an element
    footnotes: list = field(default_factory=list)   # full texts of labels too long for their block
    links: list = field(default_factory=list)       # gyrator couplings: (points, colour) flow row <-> effort row
    collapsed: dict = field(default_factory=dict)   # placeholder block id -> hidden sub-element paths

    def arrow_of(self, variable: str) -> Arrow:
        """The arrow of a port variable (``"rotor.j.a.e"``)."""
        for a in self.arrows:
            if a.variable == variable:
                return a
        raise KeyError(variable)

    def red_elements(self) -> set:
        """Top-level elements that have at least one red block."""
        return {b.element for b in self.blocks.values() if b.conflict}


# ---------------------------------------------------------------------------------------------
# text helpers

def _num(value: float) -> str:
    """Compact number: integers plain, thirds and sevenths as fractions, else 3 digits."""
    value = float(value)
    if value == int(value) and abs(value) < 1e6:
        return str(int(value))
    frac = Fraction(value).limit_denominator(12)
    if frac.denominator > 1 and len(repr(value)) > 8 and abs(float(frac) - value) <= 1e-12 * abs(value):
        return f"{frac.numerator}/{frac.denominator}"
    return f"{value:.3g}"


_GREEK = {name: chr(code) for name, code in (
    ("alpha", 0x3B1), ("beta", 0x3B2), ("gamma", 0x3B3), ("delta", 0x3B4), ("epsilon", 0x3B5),
    ("zeta", 0x3B6), ("eta", 0x3B7), ("theta", 0x3B8), ("kappa", 0x3BA), ("lambda", 0x3BB),
    ("mu", 0x3BC), ("nu", 0x3BD), ("xi", 0x3BE), ("rho", 0x3C1), ("sigma", 0x3C3), ("tau", 0x3C4),
    ("phi", 0x3C6), ("chi", 0x3C7), ("psi", 0x3C8), ("omega", 0x3C9))}


def _pretty_name(name: str) -> str:
    """``alpha`` -> ``α``, ``delta_P`` -> ``δ_P``; other names unchanged."""
    head, sep, tail = name.partition("_")
    return _GREEK[head] + sep + tail if head in _GREEK else name


def _expr_text(expr) -> str:
    """Readable form of a sympy expression: floats rounded to 4 digits, ``**`` as ``^``, Greek
    names as letters.  Never shortened: a label too long for its block goes to a footnote."""
    expr = sp.sympify(expr).replace(sp.Heaviside, lambda *a: sp.Function("step")(a[0]))
    if expr.is_number:
        try:
            return _num(float(expr))
        except TypeError:
            pass
    subs = {}
    for f in expr.atoms(sp.Float):
        r = float(f"{float(f):.4g}")
        subs[f] = sp.Integer(int(r)) if r == int(r) else sp.Float(r, 4)
    for sym in expr.free_symbols:
        pretty = _pretty_name(sym.name)
        if pretty != sym.name:
            subs[sym] = sp.Symbol(pretty)
    text = str(expr.xreplace(subs)).replace("**", "^")
    return text.replace("Min(", "min(").replace("Max(", "max(")


def _short_form(expr) -> str:
    """The shortest of a few equivalent printings of ``expr`` (``1/(g/r1 + 1)`` or
    ``r1/(g + r1)``)."""
    forms = {_expr_text(expr)}
    for f in (sp.together, sp.simplify):
        try:
            forms.add(_expr_text(f(expr)))
        except (TypeError, ValueError, AttributeError):
            pass
    return min(forms, key=lambda t: (len(t), t))


def _text_width(text: str, size: float = _FONT) -> float:
    """Estimated width of one line of text in drawing units."""
    longest = max((len(line) for line in text.split("\n")), default=0)
    return longest * 0.58 * size / 72.0 / SCALE


# ---------------------------------------------------------------------------------------------
# causality: which side computes each port variable

def _port_of(var_name: str) -> tuple[str, str, str]:
    """``"rotor.j.a.e"`` -> (primitive path, port, ``"e"``)."""
    pp, kind = var_name.rsplit(".", 1)
    prim, port = pp.rsplit(".", 1)
    return prim, port, kind


def _orientation(an: Analysis) -> dict:
    """Port variable name -> True if its own primitive computes it, False if it is received.

    The analyser merges variables joined by identities (node and junction equations) into one
    representative computed by one equation.  Starting from the port where that equation's owner
    produces the value, the value travels through the identities: through a junction's dot it
    stays an output of that junction, through a node it becomes an input of the next primitive.
    Variables no equation computes are missing from the result.
    """
    flat = an.flat
    port_vars = set(flat.variables())
    adj: dict = defaultdict(list)
    for eq in flat.equations:
        if eq.role not in ("node", "constraint"):
            continue
        pair = _alias_pair(eq.expr, port_vars)
        if pair is not None:
            x, y, _ = pair
            adj[x].append((y, eq.owner))
            adj[y].append((x, eq.owner))
    members: dict = defaultdict(list)
    for v, (rep, _sign) in an.aliases.items():
        members[rep].append(v)
    node_ports = {n.name: set(n.ports) for n in flat.nodes}
    out: dict = {}
    for i, rep in an.assignment.items():
        if rep not in port_vars:
            continue
        owner = an.equations[i].owner
        cls = sorted(members.get(rep, [rep]), key=lambda s: s.name)
        if owner in flat.primitives:
            start = [v for v in cls if _port_of(v.name)[0] == owner]
            inside = True
        else:
            start = [v for v in cls if v.name.rsplit(".", 1)[0] in node_ports.get(owner, ())]
            inside = False
        queue = list(start)
        for v in start:
            out[v.name] = inside
        while queue:
            v = queue.pop(0)
            for u, via in adj[v]:
                if u.name in out:
                    continue
                out[u.name] = via == _port_of(u.name)[0]   # through its own junction: output
                queue.append(u)
    return out


# ---------------------------------------------------------------------------------------------
# layout

class _Layout:
    def __init__(self, an: Analysis, types: dict | None):
        self.an = an
        self.flat = flat = an.flat
        self.types = dict(types or {})
        self.prims = flat.primitives
        self.node_of = {p: n for n in flat.nodes for p in n.ports}
        self.elements = list(dict.fromkeys(flat.element_of(p) for p in self.prims))
        self.out = _orientation(an)
        self.values = flat.param_values()
        self.blocks: dict[str, Block] = {}
        self.arrows: list[Arrow] = []
        errs = an.errors
        self.red = {e for d in errs for e in d.elements}
        self.demoted = {s.owner for s in an.demoted}
        # nodes joining different elements ("top-level") and inside one element
        self.top_nodes, self.inner_nodes, self.terminations = [], [], []
        for n in flat.nodes:
            els = {flat.element_of(p) for p in n.ports}
            if n.origin == "termination":
                self.terminations.append(n)
            elif len(els) > 1:
                self.top_nodes.append(n)
            else:
                self.inner_nodes.append(n)
        self.top_set = {n.name for n in self.top_nodes}
        self.node_by_name = {n.name: n for n in flat.nodes}
        self.track: dict = {}               # connection -> inner track index (outside the rows)
        self.n_tracks: dict = {}            # element -> number of inner tracks
        self.footnotes: list = []           # (what, full text) of labels too long for a block
        self.symbols: dict = {}             # (scope, shown name) -> value of a symbol in a label
        self.links: list = []
        self.bus: dict = {}                 # junction drawn as a bus -> (element, level, side)
        self._items_cache: dict = {}
        self.levels: dict = {}              # element -> [(first item, last item, track level)]
        self.entries: dict = {}             # element -> items whose ports face left
        self.find_families()

    def subnet(self, item):
        """The innermost network a primitive (or an inner node) belongs to."""
        path = item
        if item in self.node_by_name:
            ports = [q.rsplit(".", 1)[0] for q in self.node_by_name[item].ports]
            path = ports[0]
            while not all(q == path or q.startswith(path + ".") for q in ports) and "." in path:
                path = path.rsplit(".", 1)[0]
        while path not in self.flat.elements and "." in path:
            path = path.rsplit(".", 1)[0]
        return path

    # -- element order: columns and lanes ---------------------------------------------------------
    def order_elements(self):
        """Columns along the chain of connections, lanes for parallel paths, terminals packed.

        1. The root is the first source named in the connections (a driving one if no source
           is named); its columns run left to right, breadth first: elements reached through the
           same node share a column and are stacked in lanes (parallel paths).
        2. *Terminals* (elements with a single connection, such as sources and grounds) are placed
           afterwards next to the element they act on, in its lane: on the side of the port they
           attach to, else the other side, else after a row of terminals already there, and only
           when all of that is taken in the next lane.
        """
        flat = self.flat
        nodes_of = defaultdict(list)
        for n in self.top_nodes:
            for p in n.ports:
                el = flat.element_of(p)
                if n not in nodes_of[el]:
                    nodes_of[el].append(n)
        self.nodes_of = nodes_of
        self.col, self.lane, self.parent_node, self.node_parent = {}, {}, {}, {}
        self.node_gap_at = {}               # node -> gap index chosen when its terminal was placed
        cells = {}
        terminal = {el: len(nodes_of[el]) <= 1 for el in self.elements}
        self.terminal = terminal

        def place(el, c, lane):
            while (c, lane) in cells:
                lane += 1
            cells[(c, lane)] = el
            self.col[el], self.lane[el] = c, lane

        def chain_first(n):
            """Nodes that lead on to multi-port elements before those that only attach terminals."""
            new = {flat.element_of(p) for p in n.ports} - set(self.col)
            return 0 if any(not terminal[e] for e in new) else 1

        waiting = []                        # terminals, placed once the chain stands

        def expand(el, nodes, queue):
            for n in sorted(nodes, key=chain_first):
                if n.name in self.node_parent:
                    continue
                els = list(dict.fromkeys(flat.element_of(p) for p in n.ports))
                parent = min((e for e in els if e in self.col), key=lambda e: (self.col[e], e != el))
                self.node_parent[n.name] = parent          # the node sits after its leftmost element
                for e in els:
                    if e in self.col:
                        continue
                    if terminal[e]:
                        if e not in [w[0] for w in waiting]:
                            waiting.append((e, n))
                        continue
                    place(e, self.col[parent] + 1, self.lane[parent])
                    self.parent_node[e] = n
                    queue.append((e, nodes_of[e]))

        def visit(root):
            """Breadth first, so parallel paths run side by side; the root's other ports come
            last, so a ring through the source is drawn as a chain with one return wire."""
            first, rest = nodes_of[root][:1], nodes_of[root][1:]
            queue = [(root, first)]
            while queue:
                el, nodes = queue.pop(0)
                expand(el, nodes, queue)
                if not queue and rest:
                    queue.append((root, rest))
                    rest = []

        def is_source(el, driving):
            for path, prim in self.prims.items():
                if flat.element_of(path) == el and prim.kind in ("Se", "Sf"):
                    return not driving or sp.sympify(prim.params["value"]).is_zero is not True
            return False

        named = [flat.element_of(p) for n in self.top_nodes for p in n.ports]
        pending = ([e for e in dict.fromkeys(named) if is_source(e, False)]
                   + [e for e in self.elements if is_source(e, True)] + self.elements)
        start = 0
        for root in pending:
            if root in self.col:
                continue
            waiting[:] = [w for w in waiting if w[0] not in self.col]
            place(root, start, 0)
            visit(root)
            self.place_terminals(waiting, cells, place)
            start = max(self.col.values()) + 1
        low = min(self.col.values())
        for el in self.col:
            self.col[el] -= low
        self.node_gap_at = {k: g - low for k, g in self.node_gap_at.items()}
        self.n_cols = max(self.col.values()) + 1
        self.n_lanes = max(self.lane.values()) + 1

    def place_terminals(self, waiting, cells, place):
        """Put each terminal next to the element it acts on (see :meth:`order_elements`)."""
        flat = self.flat
        jobs = []
        for el, n in waiting:
            if el in self.col:
                continue
            placed = [e for e in dict.fromkeys(flat.element_of(p) for p in n.ports) if e in self.col]
            if not placed:
                continue
            if len(placed) == 1:
                host = placed[0]
                side = self.port_side(host, next(p for p in n.ports if flat.element_of(p) == host))
            else:                           # a node of several elements: beside its gap
                host = min(placed, key=lambda e: self.col[e])
                side = None
            jobs.append((el, n, host, side))
        # terminals at a node of several elements first (they have the least choice)
        jobs.sort(key=lambda j: j[3] is not None)
        for el, n, host, side in jobs:
            c, lane = self.col[host], self.lane[host]
            if side is None:                # gap after the host: the cell right of it or below
                options = [(c + 1, lane + k) for k in range(1, 50)]
                options = [(c + 1, lane)] + [x for pair in zip([(c, lane + k) for k in range(1, 50)], options)
                                             for x in pair]
            else:
                near, far = (c - 1, c + 1) if side == "left" else (c + 1, c - 1)
                options = [(near, lane), (far, lane)]
                step = -1 if side == "left" else 1
                k = near
                while (k, lane) in cells and self.terminal.get(cells[(k, lane)]):
                    k += step                # continue a row of terminals
                below = [(near, lane + 1), (c, lane + 1), (far, lane + 1)]
                if any(l2 == lane + 1 for _c2, l2 in cells):
                    options += below         # that lane is drawn anyway
                if k != near:
                    options.append((k, lane))
                options += below
                for extra in range(2, 50):
                    options += [(near, lane + extra), (c, lane + extra), (far, lane + extra)]
            cell = next(x for x in options if x not in cells)
            place(el, *cell)
            self.parent_node[el] = n
            members = {flat.element_of(p) for p in n.ports if flat.element_of(p) in self.col}
            self.node_parent[n.name] = min(members, key=lambda e: (self.col[e], e != host))
            if side is not None and cell[0] == c:       # straight below its host: the gap on its side
                self.node_gap_at[n.name] = c - 1 if side == "left" else c

    def port_side(self, el, port_path):
        """``"left"`` if ``port_path`` of element ``el`` lies in the first half of its drawn
        items, else ``"right"``."""
        order = self.element_items(el)[0]
        if len(order) <= 1:
            return "left" if not any(self.col.get(e, 1e9) < self.col[el] for e in self.neighbours(el)) else "right"
        item = self.item_of_port(el, port_path)
        k = order.index(item) if item in order else len(order) - 1
        return "left" if k < (len(order) - 1) / 2 else "right"

    def neighbours(self, el):
        return {self.flat.element_of(p) for n in self.nodes_of.get(el, []) for p in n.ports} - {el}

    # -- repeated sub-elements ------------------------------------------------------------------------
    def find_families(self):
        """Sibling networks of the same type and structure (the discs of a stack): parent path ->
        list of families, each a list of sibling paths in the order of the chain they form.
        A family longer than :data:`COLLAPSE_ABOVE` with equal parameters is drawn collapsed:
        its first :data:`DRAWN_HEAD` members, a placeholder, and its last member."""
        flat = self.flat
        prims_under = defaultdict(list)
        for p in self.prims:
            parts = p.split(".")
            for k in range(1, len(parts)):
                prims_under[".".join(parts[:k])].append(p)
        values = {s.name: v for s, v in self.values.items()}

        def signature(sub):
            rel = tuple(sorted((p[len(sub) + 1:], self.prims[p].kind) for p in prims_under[sub]))
            return flat.elements[sub], rel

        def param_signature(sub):
            return tuple(sorted((k[len(sub) + 1:], v) for k, v in values.items() if k.startswith(sub + ".")))

        groups = defaultdict(list)
        for sub in flat.elements:
            if "." not in sub or not prims_under[sub]:
                continue
            groups[(sub.rsplit(".", 1)[0], signature(sub))].append(sub)
        families, hidden, placeholders = defaultdict(list), {}, {}
        self.alike = {}                     # sub-network -> its identical siblings (same inner order)
        for (parent, _sig), subs in groups.items():
            if len(subs) < 2:
                continue
            for sub in subs:
                self.alike[sub] = subs
            for subs in self.chains(subs):
                if len(subs) < 2:
                    continue
                families[parent].append(subs)
                same = len({param_signature(x) for x in subs}) == 1
                if len(subs) > COLLAPSE_ABOVE and same:       # draw the head, a placeholder, the last
                    gone = subs[DRAWN_HEAD:-1]
                    ph = f"{parent}.{gone[0].rsplit('.', 1)[1]}…{gone[-1].rsplit('.', 1)[1]}"
                    placeholders[ph] = (parent, subs, gone)
                    for g in gone:
                        for p in prims_under[g]:
                            hidden[p] = ph
        self.families, self.hidden, self.placeholders = families, hidden, placeholders

    def chains(self, subs):
        """Identical siblings split into the chains their direct connections form, each in chain
        order from the end that holds the element's earliest external port (else the first name,
        numbers by value)."""
        def natural(name):
            return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]
        subs = sorted(subs, key=natural)
        member = {}
        for sub in subs:
            for p in self.prims:
                if p.startswith(sub + "."):
                    member[p] = sub
        adj = defaultdict(set)
        for n in self.flat.nodes:
            touched = {member.get(q.rsplit(".", 1)[0]) for q in n.ports} - {None}
            for x in touched:
                adj[x] |= touched - {x}
        ext = list(self.flat.external_ports.values())
        rank = {}
        for k, pp in enumerate(ext):
            sub = member.get(pp.rsplit(".", 1)[0])
            if sub is not None:
                rank.setdefault(sub, k)
        out, seen = [], set()
        while len(seen) < len(subs):
            rest = [x for x in subs if x not in seen]
            ends = [x for x in rest if len(adj[x] - seen) <= 1]
            start = min(ends or rest, key=lambda x: (rank.get(x, len(ext)), subs.index(x)))
            order, todo = [], [start]
            while todo:                       # along the chain, depth first
                x = todo.pop()
                if x in seen:
                    continue
                seen.add(x)
                order.append(x)
                todo += sorted(adj[x] - seen, key=lambda y: -subs.index(y))
            out.append(order)
        return out

    # -- items inside an element ------------------------------------------------------------------
    def item_of_port(self, el, port_path):
        """The drawn item that carries ``port_path`` of element ``el``."""
        prim = port_path.rsplit(".", 1)[0]
        if prim in self.hidden:
            return self.hidden[prim]
        _order, hang = self.element_items(el)
        for host, hs in hang.items():
            if prim in hs:
                return host
        return prim

    def element_items(self, el):
        """Ordered items of an element (primitives on the rows, inner nodes, middle blocks that
        do not hang under a junction, unconnected-port terminals, placeholders of collapsed
        repeats) and the hanging ones.

        The order follows the chain of connections from the ports facing left (the *entries*:
        the port the element was reached through and ports joined to elements left of it) to the
        others: at each branch a neighbour with a port that leads on comes last (so such ports end
        up at the right edge), then the same physical domain comes first, then items without a
        port, then the one farthest from the ports.  A nested network
        is kept together where it is first met, identical siblings are drawn in the order of the
        chain they form and with the same inner order."""
        key = (el, tuple(sorted(self.col.items())),
               tuple(sorted((k, v.name) for k, v in self.parent_node.items())))
        cached = self._items_cache.get(key)
        if cached is not None:
            self.entries[el] = cached[2]
            return cached[:2]
        flat = self.flat
        prims = [p for p in self.prims if flat.element_of(p) == el and p not in self.hidden]
        hang = defaultdict(list)           # host item -> middle primitives below it
        host_of = {}
        for p in prims:
            prim = self.prims[p]
            if not self.is_middle(p) or len(prim.ports) != 1:
                continue
            n = self.node_of.get(f"{p}.p")
            if n is None or n.name in self.top_set or n.origin == "termination":
                continue
            others = [q for q in n.ports if q != f"{p}.p"]
            if len(others) >= 2:
                host_of[p] = n.name
            else:
                q = others[0].rsplit(".", 1)[0]
                if not self.is_middle(q) and q not in self.hidden:
                    host_of[p] = q
            if p in host_of:
                hang[host_of[p]].append(p)
        inner = [n for n in self.inner_nodes if flat.element_of(n.ports[0]) == el and len(n.ports) >= 3
                 and not all(q.rsplit(".", 1)[0] in self.hidden for q in n.ports)]
        phs = [ph for ph in self.placeholders if flat.element_of(ph) == el]
        items = [p for p in prims if p not in host_of] + [n.name for n in inner] + phs
        term_of = defaultdict(list)
        for n in self.terminations:
            prim = n.ports[0].rsplit(".", 1)[0]
            if flat.element_of(prim) == el and prim not in self.hidden:
                term_of[prim].append(n.name)
        item_of = {p: host_of.get(p, p) for p in prims}
        item_of.update(self.hidden)
        inner_names = {n.name for n in inner}
        adj = defaultdict(list)
        for n in self.inner_nodes:
            if flat.element_of(n.ports[0]) != el:
                continue
            its = list(dict.fromkeys(item_of[q.rsplit(".", 1)[0]] for q in n.ports))
            if n.name in inner_names:
                its = [x for x in its if x != n.name]
                for a in its:
                    adj[a].append(n.name)
                    adj[n.name].append(a)
            elif len(its) == 2:
                a, b = its
                adj[a].append(b)
                adj[b].append(a)
        # entries (ports facing left) and exits
        entries, exits = [], []
        my_col = self.col.get(el, 0)
        for k, pp in flat.external_ports.items():
            if k.split(".", 1)[0] != el or pp.rsplit(".", 1)[0] not in item_of:
                continue
            it = item_of[pp.rsplit(".", 1)[0]]
            n = self.node_of.get(pp)
            left = n is not None and (n is self.parent_node.get(el) or any(
                self.col.get(flat.element_of(q), my_col) < my_col for q in n.ports))
            (entries if left else exits).append(it)
        self.entries[el] = set(entries)
        order = self.walk(items, adj, entries, [it for it in exits if it not in entries])
        order = self.group_nested(el, order, adj)
        out = []
        for it in order:
            out.append(it)
            out += term_of.get(it, [])
            for h in hang.get(it, []):
                out += [t for t in term_of.get(h, []) if t not in out]
        for ts in term_of.values():
            out += [t for t in ts if t not in out]
        self._items_cache[key] = (out, hang, self.entries[el])
        return out, hang

    def walk(self, items, adj, entries, exits):
        """Depth-first order of ``items`` (joined by ``adj``) from ``entries``; at each branch a
        neighbour holding one of the ``exits`` that leads on comes last, the same physical
        domain first, then items that are no exit, then the one farthest from the exits."""
        allowed = set(items)
        dist = {it: 0 for it in exits if it in allowed}
        frontier = list(dist)
        while frontier:
            nxt = []
            for it in frontier:
                for nb in adj[it]:
                    if nb not in dist and nb in allowed:
                        dist[nb] = dist[it] + 1
                        nxt.append(nb)
            frontier = nxt
        rank = {it: k for k, it in enumerate(items)}
        order, seen = [], set()

        def domains(it):
            if it in self.prims:
                return {d.name for d in self.prims[it].ports.values()}
            if it in self.node_by_name:
                return {self.node_by_name[it].domain.name}
            return set()

        def leads_on(nb, x):               # a neighbour with a port that does not end the branch
            return dist.get(nb) == 0 and any(m not in seen and m != x for m in adj[nb])

        for start in list(dict.fromkeys(entries)) + list(items):
            stack = [start] if start in allowed else []
            while stack:
                x = stack.pop()
                if x in seen:
                    continue
                seen.add(x)
                order.append(x)
                here, dom = self.subnet(x), domains(x)
                nbs = sorted((nb for nb in adj[x] if nb not in seen and nb in allowed),
                             key=lambda nb: (leads_on(nb, x), not domains(nb) <= dom, dist.get(nb) == 0,
                                             -dist.get(nb, 0), self.subnet(nb) != here,
                                             nb in self.prims and self.is_middle(nb), rank.get(nb, 0)))
                stack += nbs[::-1]
        return order

    def chain_template(self, group, members, adj):
        """Inner order shared by identical siblings, as (member, items): for a chain of them, a
        member walked from the item joined to its predecessor to the one joined to its successor
        (the second member if drawn, else the first); otherwise the order they were met in."""
        def drawn(m):                       # the items standing for member m (a placeholder if hidden)
            got = members.get(m)
            if got:
                return got
            return [ph for ph, (_p, _s, gone) in self.placeholders.items() if m in gone]

        if len(group) < 2:
            return group[0], members.get(group[0], [])
        k = 1 if len(group) >= 3 and members.get(group[1]) else 0
        sub = group[k]
        its = members.get(sub, [])
        before = set(drawn(group[k - 1])) if k else set()
        after = set(drawn(group[k + 1]))
        entry = [x for x in its if any(nb in before for nb in adj[x])]
        exit_ = [x for x in its if any(nb in after for nb in adj[x])]
        return sub, self.walk(its, adj, entry or its[:1], exit_)

    def group_nested(self, el, order, adj):
        """Keep the items of each nested network together where the first of them is met; the
        members of a family of identical siblings follow each other in chain order, each with
        the inner order of the first, and a collapsed run is replaced by its placeholder."""
        def top(it):                        # the network directly inside ``el`` an item belongs to
            if it in self.placeholders:
                return self.placeholders[it][0] if self.placeholders[it][0] != el else it
            sub = self.subnet(it)
            if sub == el or not sub.startswith(el + "."):
                return None
            return ".".join(sub.split(".")[:2])

        family_of, ph_of = {}, {}
        for fam in self.families.get(el, []):
            for sub in fam:
                family_of[sub] = fam
        for ph, (parent, subs, gone) in self.placeholders.items():
            if parent == el:
                for sub in subs:
                    ph_of[sub] = ph
        members = defaultdict(list)
        for it in order:
            members[top(it) or it].append(it)
        template = {}

        def rel(it, sub):
            return it.replace(sub + ".", "§.")

        out, done = [], set()
        for it in order:
            t = top(it)
            if t is None:
                out.append(it)
                continue
            if t in done:
                continue
            group = family_of.get(t, [t])
            for sub in group:
                if sub in done:
                    continue
                done.add(sub)
                ph = ph_of.get(sub)
                if ph is not None and sub in self.placeholders[ph][2]:
                    if ph not in done:
                        done.add(ph)
                        out.append(ph)
                    continue
                its = members.get(sub, [])
                alike = tuple(self.alike.get(sub, [sub]))
                if len(alike) > 1:
                    if alike not in template:
                        m, its_m = self.chain_template(group, members, adj)
                        template[alike] = [rel(x, m) for x in its_m]
                    pos = {r: k for k, r in enumerate(template[alike])}
                    its = sorted(its, key=lambda x: pos.get(rel(x, sub), len(pos)))
                out += its
        return out

    # -- blocks -------------------------------------------------------------------------------------
    def _block(self, bid, kind, label, row, owner, element, note="", identity=False, w=None, h=None):
        default = {"sum": (0.42, 0.38), "dot": (0.0, 0.0), "ratio": (0.62, 0.38), "gyrator": (0.95, 0.38)}
        dw, dh = default.get(kind, (0.98, 0.58))
        text_w = 0.0 if kind == "dot" else max(_text_width(label, 9), _text_width(note, 7.5)) + 0.22
        b = Block(bid, kind, label, row, owner, element, note, w=max(w or dw, text_w), h=h or dh, identity=identity)
        b.conflict = element in self.red
        self.blocks[bid] = b
        return b

    def _relation(self, path, natural):
        """The flat equation of primitive ``path`` whose natural output is ``natural``."""
        for eq in self.flat.equations:
            if eq.owner == path and eq.natural is not None and eq.natural.name == natural:
                return eq
        return None

    def _coefficient_note(self, path, name):
        """``"J = 0.002"``: the linear coefficient of an I (J), C (c) or R (r) as the flat equation
        has it, named after its parameter symbol; ``None`` for a nonlinear law."""
        state = {"I": "p", "C": "q"}.get(self.prims[path].kind)
        out_var = f"{path}.p.f" if state == "p" else f"{path}.p.e"
        eq = self._relation(path, out_var)
        if eq is None:
            return None
        out = var(out_var) - eq.expr
        x = var(f"{path}.{state}") if state else var(f"{path}.p.f")
        slope = sp.diff(out, x)
        if slope.has(x) or slope == 0:
            return None
        coef = 1 / slope if state == "p" else slope
        return self._param_text(coef, name, path)

    def _param_text(self, coef, name, path=""):
        coef = sp.sympify(coef)
        if coef.free_symbols and coef.free_symbols <= set(self.values):
            value = float(coef.xreplace({s: sp.Float(self.values[s]) for s in coef.free_symbols}))
            label = _pretty_name(coef.name.rsplit(".", 1)[-1]) if isinstance(coef, sp.Symbol) else name
            return self.fit(f"{label} = {_num(value)}", _NOTE_CHARS, path)
        return self.fit(f"{name} = {_expr_text(self.symbolic(coef))}", _NOTE_CHARS, path)

    def fit(self, text, limit, what, prefix=""):
        """``prefix + text`` if it fits a block (``limit`` characters), else ``prefix`` and a
        footnote mark ``[n]``; the full text becomes footnote n.  Labels are never cut."""
        if len(prefix + text) <= limit:
            return prefix + text
        entry = (what, prefix + text)
        if entry not in self.footnotes:
            self.footnotes.append(entry)
        return f"{prefix}[{self.footnotes.index(entry) + 1}]"

    def symbolic(self, expr, path=""):
        """``expr`` with its parameters by their short names (the part after the last dot, the
        scope is the frame the block sits in); every name shown is remembered with its value for
        the symbol footnote.  A name local to the primitive ``path`` is looked up in its scopes;
        the primitive's own parameters (not named by any network) are written as numbers."""
        expr = sp.sympify(expr)
        scoped = {}
        for sym in expr.free_symbols:
            scope = path
            while scope and sym not in self.values:
                scope = scope.rpartition(".")[0]
                full = sp.Symbol(f"{scope}.{sym.name}" if scope else sym.name)
                if full in self.values:
                    scoped[sym] = full
                    break
        expr = expr.xreplace(scoped)
        own = {sym: sp.Float(self.values[sym]) for sym in expr.free_symbols
               if sym in self.values and path and sym.name.rpartition(".")[0] == path}
        expr = expr.xreplace(own)
        params = [sym for sym in expr.free_symbols if sym in self.values]
        shorts = defaultdict(list)
        for sym in params:
            shorts[sym.name.rpartition(".")[2]].append(sym)
        subs = {}
        for short, syms in shorts.items():
            for sym in syms:
                name = short if len(syms) == 1 else sym.name
                subs[sym] = sp.Symbol(name)
                self.symbols[(sym.name.rpartition(".")[0] if len(syms) == 1 else "", name)] = self.values[sym]
        return expr.xreplace(subs)

    def middle_block(self, path):
        prim = self.prims[path]
        el = self.flat.element_of(path)
        k = prim.kind
        pr = prim.params
        deriv = path in self.demoted
        mark = "d/dt" if deriv else "∫"
        if k == "I":
            label = f"I  {mark}"
            note = self._coefficient_note(path, "J") or "f = law(p)"
            kind = "storage"
        elif k == "C":
            label = f"C  {mark}"
            note = self._coefficient_note(path, "c") or "e = law(q)"
            kind = "storage"
        elif k == "CField":
            label, note, kind = f"C-field  {mark}", f"{len(prim.ports)} ports", "storage"
        elif k == "R":
            label = "R"
            note = self._coefficient_note(path, "r") or "e = law(f)"
            kind = "resistance"
        elif k in ("Se", "Sf"):
            var_ = "e" if k == "Se" else "f"
            label, kind = k, "source"
            note = self.fit(_expr_text(pr["value"]), _NOTE_CHARS, path, f"{var_} = ")
        elif k == "Tap":
            label, note, kind = "Tap  ∫", "", "tap"
        else:                               # a kind an element library defines
            label, kind = k, "other"
            note = self.fit(prim.doc.split(":")[0] if prim.doc else "", _NOTE_CHARS, path)
        b = self._block(f"{path}:x", kind, label, "x", path, el, note)
        b.derivative = deriv
        return b

    def placeholder_block(self, ph):
        """The block that stands for a collapsed run of identical sub-elements."""
        parent, subs, gone = self.placeholders[ph]
        typ = self.flat.elements[subs[0]]
        short = [g.rsplit(".", 1)[1] for g in gone]
        b = self._block(f"{ph}:x", "repeat", f"{len(gone)} × {typ}", "x", ph, self.flat.element_of(ph),
                        f"{short[0]} … {short[-1]}: as drawn", h=2 * _DY + 0.3)
        return b

    def row_blocks(self, path):
        """Blocks of a primitive that lives on the rows (junction, TF, MTF, GY)."""
        prim = self.prims[path]
        el = self.flat.element_of(path)
        k = prim.kind
        if k.startswith("junction_"):
            common = "f" if prim.type == "b" else "e"
            two = len(prim.ports) == 2
            for row in ("f", "e"):
                dot = row == common
                self._block(f"{path}:{row}", "dot" if dot else "sum", "" if dot else "Σ", row, path, el,
                            identity=dot or two)
            return
        if k == "TF":
            ratio, moving = self._tf_ratio(path)
            base = sp.Symbol(f"k({','.join(moving)})") if moving else ratio
            fa, fb = self.out.get(f"{path}.a.f"), self.out.get(f"{path}.b.f")
            ea, eb = self.out.get(f"{path}.a.e"), self.out.get(f"{path}.b.e")
            flow = 1 / base if fb and not fa else base
            effort = -1 / base if ea and not eb else -base
            flow_label = self.fit(_short_form(flow), _RATIO_CHARS, f"{path}, flows")
            if moving:                      # a modulated transformer: its ratio in a footnote
                entry = (path, f"{base} = {_short_form(ratio)}")
                if entry not in self.footnotes:
                    self.footnotes.append(entry)
                flow_label += f" [{self.footnotes.index(entry) + 1}]"
            self._block(f"{path}:f", "ratio", flow_label, "f", path, el)
            self._block(f"{path}:e", "ratio", self.fit(_short_form(effort), _RATIO_CHARS, f"{path}, efforts"), "e",
                        path, el)
            return
        if k == "GY":
            r = self.fit(_expr_text(self.symbolic(prim.params["r"], path)), _RATIO_CHARS - 3,
                         f"{path}, gyrator ratio")
            self._block(f"{path}:f", "gyrator", f"GY {r}", "f", path, el)
            self._block(f"{path}:e", "gyrator", f"GY {r}", "e", path, el)
            return
        label = {"MTF": ("K(q)", "-Kᵀ")}.get(k, (k, k))
        self._block(f"{path}:f", "ratio", label[0], "f", path, el)
        self._block(f"{path}:e", "ratio", label[1], "e", path, el)

    def _tf_ratio(self, path):
        """Ratio k of a TF (``f_a = k*f_b``) from its flat equation, parameters by short name, and
        the short names of the states it depends on (a modulated transformer)."""
        fa, fb = var(f"{path}.a.f"), var(f"{path}.b.f")
        for eq in self.flat.equations:
            if eq.owner == path and eq.expr.has(fa) and eq.expr.has(fb):
                k = -sp.diff(eq.expr, fb) / sp.diff(eq.expr, fa)
                states = {v: sp.Symbol(v.name.rsplit(".", 1)[-1]) for v in k.free_symbols
                          if v not in self.values and v != T}
                moving = sorted(s.name for s in states.values())
                return sp.simplify(self.symbolic(k, path).xreplace(states)), moving
        return sp.Symbol("k"), []

    def node_blocks(self, node, element):
        common = node.domain.across
        for row in ("f", "e"):
            dot = row == common
            self._block(f"{node.name}:{row}", "dot" if dot else "sum", "" if dot else "Σ", row, node.name,
                        element, identity=dot)

    def terminal_block(self, node):
        pp = node.ports[0]
        el = self.flat.element_of(pp)
        free = node.domain.free_variable
        label = "free end" if free == "e" else "open"
        return self._block(f"{node.name}:x", "terminal", label, "x", node.name, el,
                           f"{free} = 0 at {pp.split('.', 1)[-1]}")

    def block_id(self, path, row):
        """Block of primitive ``path`` that carries its variables of ``row`` (for a primitive of
        a collapsed sub-element: the placeholder)."""
        if path in self.hidden:
            return f"{self.hidden[path]}:x"
        return f"{path}:x" if self.is_middle(path) else f"{path}:{row}"

    def is_middle(self, path):
        """True for primitives drawn between the rows (see :data:`MIDDLE_KINDS`)."""
        prim = self.prims[path]
        return prim.kind in MIDDLE_KINDS or (prim.kind not in ROW_KINDS and len(prim.ports) == 1)

    # -- main ---------------------------------------------------------------------------------------
    def build(self):
        self.order_elements()
        # element contents and widths
        self.items, self.widths = {}, {}
        for el in self.elements:
            order, hang = self.element_items(el)
            buses = self.find_buses(el, order, hang)
            order = [it for it in order if it not in buses]
            xs, x = {}, 0.25
            for it in order:
                if it in self.placeholders:
                    b = self.placeholder_block(it)
                    w = max(_SUB, b.w + 0.4)
                elif it in self.prims and self.is_middle(it):
                    b = self.middle_block(it)
                    w = max(_SUB, b.w + 0.3)
                elif it in self.prims:
                    self.row_blocks(it)
                    hs = [self.middle_block(h) for h in hang.get(it, [])]
                    w = max(_SUB, sum(max(_HANG, hb.w + 0.2) for hb in hs),
                            self.blocks[f"{it}:f"].w + 0.4)
                elif self.node_by_name[it].origin == "termination":
                    b = self.terminal_block(self.node_by_name[it])
                    w = max(_SUB, b.w + 0.3)
                else:
                    self.node_blocks(self.node_by_name[it], el)
                    hs = [self.middle_block(h) for h in hang.get(it, [])]
                    w = max(_SUB, sum(max(_HANG, hb.w + 0.2) for hb in hs))
                xs[it] = (x, w)
                x += w
            for j in buses:
                if j in self.prims:
                    self.row_blocks(j)
                else:
                    self.node_blocks(self.node_by_name[j], el)
                for row in ("f", "e"):
                    self.blocks[f"{j}:{row}"].bus = True
            label = self.group_label(el)
            width = max(x + 0.25, _text_width(label, 9) + 0.4)
            self.items[el] = (order, hang, xs)
            self.widths[el] = width
            self.inner_tracks(el, order, buses)
        self.col_w = [max([self.widths[e] for e in self.elements if self.col[e] == c] or [1.0])
                      for c in range(self.n_cols)]
        self.plan_wires()
        self.pad = {el: 0.13 * max(0, n - 1) for el, n in self.n_tracks.items()}
        self.sub_strip = {el: 0.22 if any(self.subnet(it) != el for it in self.items[el][0]
                                           if it in self.prims) else 0.0 for el in self.elements}
        extra = max((self.pad[el] + self.sub_strip[el] for el in self.elements), default=0.0)
        self.lane_h = _LANE + 2 * extra
        self.top_base = 0.8 + extra + 0.55
        self.place()
        self.route()

    def connections(self, el):
        """Connections inside element ``el`` as (key, item, item): a two-port node is one
        connection, a node of three or more ports one connection per port (to the node's item).
        Primitives of a collapsed run stand for their placeholder."""
        out = []
        for n in self.inner_nodes:
            if self.flat.element_of(n.ports[0]) != el:
                continue
            prims = [self.hidden.get(q.rsplit(".", 1)[0], q.rsplit(".", 1)[0]) for q in n.ports]
            if len(n.ports) == 2:
                out.append((n.name, prims[0], prims[1]))
            else:
                out += [((n.name, q), n.name, pr) for q, pr in zip(n.ports, prims)]
        return out

    def find_buses(self, el, order, hang):
        """Junctions (and nodes) on the rows joined to three or more items that are not their
        neighbours: drawn as a bus outside the rows instead of one track per connection."""
        pos = {it: k for k, it in enumerate(order)}
        rows_at = [pos[it] for it in order if it not in self.placeholders
                   and (it in self.node_by_name or (it in self.prims and not self.is_middle(it)))]
        far = defaultdict(set)
        for _key, a, b in self.connections(el):
            if a not in pos or b not in pos or a == b:
                continue
            lo, hi = sorted((pos[a], pos[b]))
            if any(lo < k < hi for k in rows_at):
                far[a].add(b)
                far[b].add(a)
        buses = []
        for it, others in far.items():
            junction = (it in self.prims and self.prims[it].kind.startswith("junction_")) or \
                (it in self.node_by_name and self.node_by_name[it].origin != "termination")
            if junction and len(others) >= 3 and not hang.get(it) and it not in self.placeholders:
                buses.append(it)
        return buses

    def inner_tracks(self, el, order, buses):
        """Connections inside an element whose ends are not neighbours on the rows run over a
        track outside the rows (above the flows, below the efforts).  Shorter connections get the
        inner tracks and connections that do not overlap share one, so nested spans never
        cross; a bus gets one track for all its connections."""
        pos = {it: k for k, it in enumerate(order)}
        rows_at = [pos[it] for it in order if f"{it}:f" in self.blocks]
        spans, seen = [], {}
        for key, a, b in self.connections(el):
            if a in buses or b in buses:
                continue
            if a not in pos or b not in pos or a == b:
                continue            # hanging under a junction: a short vertical wire
            lo, hi = sorted((pos[a], pos[b]))
            if not any(lo < k < hi for k in rows_at):
                continue
            pair = (lo, hi)
            if pair in seen and (a in self.placeholders or b in self.placeholders):
                self.track[key] = seen[pair]          # the same wire: one drawn for the run
                continue
            seen[pair] = key
            spans.append((lo, hi, key))
        ends = {}
        for j in buses:
            its = [b if a == j else a for _k, a, b in self.connections(el) if j in (a, b)]
            idx = [pos[i] for i in its if i in pos]
            side = None
            for k, pp in self.flat.external_ports.items():
                if pp.rsplit(".", 1)[0] == j:
                    side = "left" if j in self.entries.get(el, ()) else "right"
            lo, hi = min(idx), max(idx)
            lo, hi = (-1 if side == "left" else lo), (len(order) if side == "right" else hi)
            ends[j] = side
            spans.append((lo, hi, ("bus", j)))
        self.levels[el] = []
        for lo, hi, key in sorted(spans, key=lambda s: (s[1] - s[0], s[0])):
            level = 1 + max((lv for l2, h2, lv in self.levels[el] if lo <= h2 and l2 <= hi), default=-1)
            if isinstance(key, tuple) and key[0] == "bus":    # a bus takes three tracks: room for its Σ
                self.levels[el] += [(lo, hi, level), (lo, hi, level + 1), (lo, hi, level + 2)]
                self.bus[key[1]] = (el, level + 1, ends[key[1]])
            else:
                self.levels[el].append((lo, hi, level))
                self.track[key] = level
        for key, alias in list(self.track.items()):
            if not isinstance(alias, int):
                self.track[key] = self.track[alias]
        self.n_tracks[el] = 1 + max((lv for _l, _h, lv in self.levels[el]), default=-1)

    def blocked_track(self, el, prim, right):
        """A track for a leg whose port block has other row blocks between it and the element's
        edge toward the leg (the leg then runs outside the rows instead of through them)."""
        order = self.items[el][0]
        on_rows = [it for it in order if f"{it}:f" in self.blocks]
        if prim not in on_rows:
            return None
        k = on_rows.index(prim)
        if (right and k == len(on_rows) - 1) or (not right and k == 0):
            return None
        key = ("leg", prim, right)
        if key not in self.track:
            pos = order.index(prim)
            lo, hi = (pos, len(order)) if right else (-1, pos)
            level = 1 + max((lv for l2, h2, lv in self.levels[el] if lo <= h2 and l2 <= hi), default=-1)
            self.levels[el].append((lo, hi, level))
            self.track[key] = level
            self.n_tracks[el] = max(self.n_tracks[el], level + 1)
        return self.track[key]

    def group_label(self, el):
        typ = self.types.get(el) or self.flat.elements.get(el) or self.prims.get(el, None)
        typ = typ.kind if hasattr(typ, "kind") else typ
        return f"{el} ({typ})" if typ else el

    def y_row(self, lane, row):
        y0 = -lane * self.lane_h
        return {"f": y0, "x": y0 - _DY, "e": y0 - 2 * _DY}[row]

    # -- wiring between elements: which gap and which track ----------------------------------------
    def plan_wires(self):
        """Decide for every connection between elements where its node sits (the gap after the
        element it was reached from) and which legs need a return corridor."""
        self.gap_tracks = defaultdict(list)      # gap -> list of track keys
        self.node_gap, self.legs = {}, []
        for n in self.top_nodes:
            parent = self.node_parent.get(n.name, self.flat.element_of(n.ports[0]))
            g = self.node_gap_at.get(n.name, self.col[parent])
            self.node_gap[n.name] = (g, self.lane[parent])
        for n in self.top_nodes:
            g, lane = self.node_gap[n.name]
            stagger = False
            for p in n.ports:
                el = self.flat.element_of(p)
                c = self.col[el]
                right = g >= c
                adjacent = (right and g == c) or (not right and g == c - 1)
                for row in ("f", "e"):
                    leg = {"node": n, "port": p, "row": row, "el": el, "right": right, "corridor": None,
                           "track": self.blocked_track(el, p.rsplit(".", 1)[0], right) if adjacent else None}
                    if not adjacent:
                        chan_gap = c if right else c - 1
                        top = row == "f" and lane == 0 and self.lane[el] == 0
                        leg["corridor"] = ("top" if top else "bottom", chan_gap)
                        self.gap_tracks[chan_gap].append(("chan", p, row))
                        stagger = True
                    elif self.lane[el] != lane:
                        stagger = True
                    self.legs.append(leg)
            keys = [("node", n.name, "f"), ("node", n.name, "e")] if stagger else [("node", n.name, "fe")]
            self.gap_tracks[g][:0] = keys

    def place(self):
        # columns
        self.col_x, x = [], 0.0
        self.gap_x = {}
        for c in range(self.n_cols):
            self.col_x.append(x)
            x += self.col_w[c]
            tracks = self.gap_tracks.get(c, [])
            width = max(0.9, 0.45 + _TRACK * len(tracks) + 0.2)
            for k, key in enumerate(tracks):
                self.gap_x[key] = x + 0.4 + _TRACK * k
            x += width
        self.x_max = x
        # element groups and blocks inside
        self.groups, self.subgroups = [], []
        for el in self.elements:
            order, hang, xs = self.items[el]
            x0, lane = self.col_x[self.col[el]], self.lane[el]
            yf, ye = self.y_row(lane, "f"), self.y_row(lane, "e")
            pad = self.pad[el]
            self.groups.append(Group(el, self.group_label(el), x0, ye - 0.5 - pad - self.sub_strip[el],
                                     x0 + self.widths[el], yf + 0.8 + pad, el in self.red))
            # sub-frames reach below the element's tracks: their labels sit in a strip no wire uses
            n_tr = self.n_tracks.get(el, 0)
            sub_y0 = ye - (0.28 + 0.13 * (n_tr - 1) + 0.06 if n_tr else 0.22) - 0.24
            run = []                       # consecutive items of one nested network: a sub-frame
            for it in order + [None]:
                net = self.subnet(it) if it is not None and it not in self.placeholders else None
                if run and net != run[0][0]:
                    sub = run[0][0]
                    if sub is not None and sub != el and sub.startswith(el + "."):
                        left, right = xs[run[0][1]][0], sum(xs[run[-1][1]])
                        self.subgroups.append(Group(sub, f"{sub[len(el) + 1:]} ({self.flat.elements[sub]})",
                                                    x0 + left + 0.05, sub_y0, x0 + right - 0.05, yf + 0.42,
                                                    el in self.red))
                    run = []
                if it is not None:
                    run.append((net, it))
            for it in order:
                xi, w = xs[it]
                cx = x0 + xi + w / 2
                for row in ("f", "e", "x"):
                    b = self.blocks.get(f"{it}:{row}")
                    if b is not None:
                        b.x, b.y = cx, self.y_row(lane, row)
                hs = hang.get(it, [])
                widths = [max(_HANG, self.blocks[f"{h}:x"].w + 0.2) for h in hs]
                left = cx - sum(widths) / 2
                for h, hw in zip(hs, widths):
                    b = self.blocks[f"{h}:x"]
                    b.x, b.y = left + hw / 2, self.y_row(lane, "x")
                    left += hw
                if len(hs) > 1:
                    span = self.blocks[f"{hs[-1]}:x"].x - self.blocks[f"{hs[0]}:x"].x
                    for row in ("f", "e"):
                        b = self.blocks[f"{it}:{row}"]
                        b.w = span if b.kind == "dot" else max(b.w, span + 0.42)
            for j, (bel, level, side) in self.bus.items():
                if bel == el:
                    self.place_bus(j, el, level, side, x0, yf, ye)
        # nodes joining elements; where several share a gap in one lane, the multi-port ones move
        # off the row line (between the rows) so straight wires through the gap miss their blocks
        self.node_pt = {}
        sharing = defaultdict(list)
        for n in self.top_nodes:
            sharing[self.node_gap[n.name]].append(n)
        shift, self.hop = {}, set()
        for (_g, lane), group in sharing.items():
            multi = [n for n in group if len(n.ports) >= 3]
            for j, n in enumerate(multi[1:], 1):    # a second node on the row would sit in the way
                shift[n.name] = 0.7 * j
            if multi:                               # straight wires hop over the node's blocks
                self.hop |= {n.name for n in group if len(n.ports) == 2}
        for n in self.top_nodes:
            g, lane = self.node_gap[n.name]
            xf = self.gap_x.get(("node", n.name, "f"), self.gap_x.get(("node", n.name, "fe")))
            xe = self.gap_x.get(("node", n.name, "e"), xf)
            dy = shift.get(n.name, 0.34 if n.name in self.hop else 0.0)    # outward: above flows, below efforts
            self.node_pt[n.name] = {"f": (xf, self.y_row(lane, "f") + dy), "e": (xe, self.y_row(lane, "e") - dy)}
            if len(n.ports) >= 3:
                self.node_blocks(n, "")
                for row in ("f", "e"):
                    b = self.blocks[f"{n.name}:{row}"]
                    b.x, b.y = self.node_pt[n.name][row]

    def place_bus(self, j, el, level, side, x0, yf, ye):
        """Bars of a bus junction: over the flows and under the efforts at its track level, from
        its first to its last connected item and, for a port of the element, on to that edge."""
        xs = []
        for _key, a, b in self.connections(el):
            if j in (a, b):
                other = b if a == j else a
                xs.append(self.blocks[self.block_id(other, "f") if other in self.prims else f"{other}:x"
                                      if other in self.placeholders else f"{other}:f"].x)
        lo, hi = min(xs) - 0.3, max(xs) + 0.3
        if side == "left":
            lo = x0 + 0.12
        elif side == "right":
            hi = x0 + self.widths[el] - 0.12
        off = 0.28 + 0.13 * level
        for row, y in (("f", yf + off), ("e", ye - off)):
            b = self.blocks[f"{j}:{row}"]
            b.x, b.y, b.w, b.h = (lo + hi) / 2, y, hi - lo, 0.0 if b.kind == "dot" else 0.1

    # -- pins and routes ------------------------------------------------------------------------------
    def pin(self, bid, toward, row):
        """Point where a wire of ``row`` leaves block ``bid`` toward the point ``toward``;
        returns (x, y, vertical) — vertical if the wire leaves through the top or bottom."""
        b = self.blocks[bid]
        tx, ty = toward
        if b.row == "x":
            y = b.y + b.h / 2 if row == "f" else b.y - b.h / 2
            return b.x, y, True
        half = b.w / 2
        if b.kind == "dot":
            if abs(tx - b.x) <= half + 1e-6:
                return tx, b.y, True
            return (b.x - half if tx < b.x else b.x + half), b.y, False
        if tx < b.x - half - 1e-6:
            return b.x - half, b.y, False
        if tx > b.x + half + 1e-6:
            return b.x + half, b.y, False
        return tx, (b.y + b.h / 2 if ty > b.y else b.y - b.h / 2), True

    def centre(self, bid):
        b = self.blocks[bid]
        return b.x, b.y

    def path_between(self, a, b, row_y):
        """Orthogonal route between two pins (x, y, vertical) at a row whose level is ``row_y``."""
        (ax, ay, av), (bx, by, bv) = a, b
        pts = [(ax, ay)]
        if av and abs(ay - row_y) > 1e-9 and abs(ax - bx) > 1e-9:
            pts.append((ax, row_y))
            ay = row_y
        tail = []
        if bv and abs(by - row_y) > 1e-9 and abs(ax - bx) > 1e-9:
            tail = [(bx, row_y)]
            by_mid = row_y
        else:
            by_mid = by
        if abs(ay - by_mid) > 1e-9 and abs(ax - bx) > 1e-9:
            xm = (ax + bx) / 2
            pts += [(xm, ay), (xm, by_mid)]
        return pts + tail + [(bx, by)]

    def route(self):
        """One arrow per port variable, with its drawn route."""
        legs = {(leg["port"], leg["row"]): leg for leg in self.legs}
        corridor = {"top": 0, "bottom": 0}
        top_y = self.top_base
        bottom_y = self.y_row(self.n_lanes - 1, "e") - 0.85 - self.pad_max()
        self.assign_slots()
        self.assign_taps()
        multi = {}                          # (own, other, row) -> arrow standing for a collapsed run
        top_pairs = defaultdict(list)
        for pp in self.flat.port_domains:
            prim = pp.rsplit(".", 1)[0]
            n = self.node_of[pp]
            for row in ("f", "e"):
                v = f"{pp}.{row}"
                own = self.block_id(prim, row)
                if prim in self.hidden:     # inside a collapsed run: no wire of its own
                    self.arrows.append(Arrow(v, row, own, own, v in self.out or pp in self.out, EFFORT,
                                             head=False, drawn=False, hidden=True))
                    continue
                if n.origin == "termination":
                    other = f"{n.name}:x"
                elif n.name in self.top_set and len(n.ports) >= 3:
                    other = f"{n.name}:{row}"
                else:
                    q = next(p for p in n.ports if p != pp)
                    other = self.block_id(q.rsplit(".", 1)[0], row)
                inside = self.out.get(v)
                src, dst = (own, other) if inside or inside is None else (other, own)
                colour = FLOW if row == "f" else EFFORT
                arrow = Arrow(v, row, src, dst, inside is not None, colour if inside is not None else CONFLICT)
                if n.name in self.top_set:
                    pts = self.leg_route(legs[(pp, row)], own, row, corridor, top_y, bottom_y)  # node -> own
                    arrow.points = pts[::-1] if inside or inside is None else pts
                    # a two-port connection is one wire: the head sits on the receiving leg only
                    arrow.head = len(n.ports) >= 3 or not inside
                    if len(n.ports) == 2:
                        top_pairs[(n.name, row)].append(arrow)
                else:
                    key = n.name if len(n.ports) == 2 else (n.name, pp)
                    if self.blocks[own].bus or self.blocks[other].bus:
                        pts = self.bus_route(own, other, row, key)
                    elif key in self.track:
                        pts = self.track_route(own, other, row, self.track[key], key)
                    else:
                        a = self.pin(own, self.centre(other), row)
                        b = self.pin(other, self.centre(own), row)
                        pts = self.path_between(a, b, self.y_row(self.lane_of_block(own), row))
                    arrow.points = pts if src == own else pts[::-1]
                    visible = [p for p in n.ports if p.rsplit(".", 1)[0] not in self.hidden]
                    arrow.drawn = n.origin == "termination" or len(n.ports) != 2 or pp == visible[0]
                    if other.endswith(":x") and other[:-2] in self.placeholders and arrow.drawn:
                        first = multi.get((own, other, row))
                        if first is None:
                            multi[(own, other, row)] = arrow
                        else:
                            first.multiplicity += 1
                            arrow.drawn = False
                if not arrow.determined:
                    arrow.head = False
                self.arrows.append(arrow)
        for pair in top_pairs.values():
            if len(pair) == 2:
                _despike(*pair)
        self.top_y = top_y + _CORRIDOR * corridor["top"]
        self.bottom_y = bottom_y - _CORRIDOR * corridor["bottom"]

    def footnote_lines(self) -> list:
        """Footnotes below the legend: collapsed repeats, labels too long for their block, and the
        values of the symbols written in ratio blocks."""
        lines = []
        for ph, (parent, subs, gone) in self.placeholders.items():
            short = [x.rsplit(".", 1)[1] for x in subs]
            drawn = [x for x in short if f"{parent}.{x}" not in gone]
            typ = self.flat.elements[subs[0]]
            lines.append(f"{parent}: {len(subs)} × {typ}, drawn: {len(drawn)} ({', '.join(drawn)}); "
                         f"{short[DRAWN_HEAD]} … {short[-2]} are identical to those drawn, their "
                         f"{len(gone)} parallel wires drawn once and marked ×{len(gone)}")
        for k, (what, text) in enumerate(self.footnotes, 1):
            lines.append(f"[{k}] {what}: {text}")
        if self.symbols:
            lines.append("symbols in the blocks: " + _group_symbols(self.symbols))
        return lines


    def gyrator_links(self) -> None:
        """A gyrator ties the effort of each side to the flow of the other: two crossing links
        between its flow and effort blocks, pointing the way the analyser computes them."""
        arrows = {a.variable: a for a in self.arrows}
        for p, prim in self.prims.items():
            if prim.kind != "GY" or p in self.hidden:
                continue
            bf, be = self.blocks[f"{p}:f"], self.blocks[f"{p}:e"]
            side = {}
            for port in ("a", "b"):
                a = arrows[f"{p}.{port}.f"]
                if not a.points:
                    side[port] = -1 if port == "a" else 1
                    continue
                end = a.points[0] if a.source == bf.id else a.points[-1]
                side[port] = -1 if end[0] < bf.x else 1
            for port, other in (("a", "b"), ("b", "a")):
                computed_f = self.out.get(f"{p}.{port}.f")
                top = (bf.x + side[port] * bf.w * 0.35, bf.y - bf.h / 2)
                bottom = (be.x + side[other] * be.w * 0.35, be.y + be.h / 2)
                if computed_f is None:
                    self.links.append(([top, bottom], CONFLICT, False))
                else:           # flow received -> the other side's effort computed, else the reverse
                    self.links.append(([top, bottom] if not computed_f else [bottom, top], "#555555", True))

    def assign_taps(self):
        """Wires that leave a row block vertically (to a track or a bus) get their own x on it,
        in the order of where they go, so they neither overlap nor cross near the block; a dot
        with several such wires becomes a short bar."""
        legs = defaultdict(list)            # (block, side) -> [(order key, tap key)]
        for el in self.elements:
            for key, a, b in self.connections(el):
                for row in ("f", "e"):
                    ids = [self.block_id(x, row) if x in self.prims or x in self.hidden else
                           f"{x}:x" if x in self.placeholders else f"{x}:{row}" for x in (a, b)]
                    if any(i not in self.blocks for i in ids):
                        continue
                    blk = [self.blocks[i] for i in ids]
                    tracked = key in self.track
                    for k in (0, 1):
                        me, there = blk[k], blk[1 - k]
                        if me.row == "x" or me.bus or not (tracked or there.bus):
                            continue
                        level = self.bus[there.owner][1] if there.bus else self.track[key]
                        order_key = (there.x, -level if there.x > me.x else level)
                        legs[(me.id, row)].append((order_key, (key, ids[1 - k])))
        for leg in self.legs:
            if leg["track"] is not None:
                own = self.block_id(leg["port"].rsplit(".", 1)[0], leg["row"])
                far = 1e9 if leg["right"] else -1e9
                lv = leg["track"]
                legs[(own, leg["row"])].append(((far, -lv if leg["right"] else lv), ("leg", leg["port"])))
        self.tap = {}
        for (bid, _row), items in legs.items():
            b = self.blocks[bid]
            items = sorted(set(items))
            n = len(items)
            if n == 1:
                self.tap[(bid, items[0][1])] = b.x
                continue
            step = 0.14
            if b.kind == "dot":
                b.w = max(b.w, step * (n - 1))
            else:
                b.w = max(b.w, step * (n - 1) + 0.2)
            span = step * (n - 1)
            for k, (_order, tkey) in enumerate(items):
                self.tap[(bid, tkey)] = b.x - span / 2 + step * k

    def tap_x(self, bid, key):
        return self.tap.get((bid, key), self.blocks[bid].x)

    def pad_max(self):
        return max(self.pad.values(), default=0.0)

    def track_route(self, own, other, row, k, key=None):
        """Route over inner track ``k``: out of the row away from the cross-couplings and back."""
        up = row == "f"
        a, b = self.blocks[own], self.blocks[other]
        yc = self.y_row(self.lane_of_block(own), row) + (0.28 + 0.13 * k) * (1 if up else -1)

        def end(blk, there):
            x = self.tap_x(blk.id, (key, there.id))
            return (x, blk.y) if blk.kind == "dot" else (x, blk.y + (blk.h / 2 if up else -blk.h / 2))
        ea, eb = end(a, b), end(b, a)
        return [ea, (ea[0], yc), (eb[0], yc), eb]

    def bus_route(self, own, other, row, key):
        """Straight out of the row block to the bus bar above (flows) or below (efforts)."""
        up = row == "f"
        a, b = self.blocks[own], self.blocks[other]
        bar, blk = (a, b) if a.bus else (b, a)
        x = self.tap_x(blk.id, (key, bar.id))
        start = (x, blk.y) if blk.kind == "dot" else (x, blk.y + (blk.h / 2 if up else -blk.h / 2))
        if blk.row == "x":
            start = (blk.x, blk.y + (blk.h / 2 if up else -blk.h / 2))
            x = blk.x
        pts = [start, (x, bar.y + (-bar.h / 2 if up else bar.h / 2))]
        return pts if blk is a else pts[::-1]

    def lane_of_block(self, bid):
        b = self.blocks[bid]
        return round(-(b.y - {"f": 0, "x": -_DY, "e": -2 * _DY}[b.row]) / self.lane_h)

    def assign_slots(self):
        """Legs that leave the same row block on the same side run beside each other: the first
        (the one staying in its lane) on the row line, the others shifted toward their node."""
        shared = defaultdict(list)
        for leg in self.legs:
            own = self.block_id(leg["port"].rsplit(".", 1)[0], leg["row"])
            leg["slot"] = 0
            if self.blocks[own].row == "x" or leg["corridor"] is not None or leg["track"] is not None:
                continue
            nx_, ny = self.node_pt[leg["node"].name][leg["row"]]
            shared[(own, nx_ < self.blocks[own].x)].append(leg)
        for legs in shared.values():
            legs.sort(key=lambda lg: (lg["node"].name in self.hop,
                                      abs(self.node_pt[lg["node"].name][lg["row"]][1]
                                          - self.y_row(self.lane[lg["el"]], lg["row"]))))
            for k, leg in enumerate(legs):
                leg["slot"] = k
        for leg in self.legs:
            n, row = leg["node"], leg["row"]
            row_y = self.y_row(self.lane[leg["el"]], row)
            if len(n.ports) == 2:           # toward the partner's lane
                other = next(p for p in n.ports if p != leg["port"])
                ty = self.y_row(self.lane[self.flat.element_of(other)], row)
            else:
                ty = self.node_pt[n.name][row][1]
            leg["dir"] = 1 if ty > row_y + 1e-9 else -1
            if n.name in self.hop:          # hopping wires leave outward, away from the rows
                leg["dir"] = 1 if row == "f" else -1
            if leg["slot"] and len(n.ports) == 2 and abs(self.node_pt[n.name][row][1] - row_y) < 1e-9:
                box = self.blocks[self.block_id(leg["port"].rsplit(".", 1)[0], row)].kind != "dot"
                x, _ = self.node_pt[n.name][row]    # the invisible node point moves onto the shifted run
                self.node_pt[n.name][row] = (x, row_y + (0.11 if box else 0.2) * leg["slot"] * leg["dir"])

    def leg_route(self, leg, own, row, corridor, top_y, bottom_y):
        """Route from the node point of a connection between elements to the port's block."""
        n = leg["node"]
        nx_, ny = self.node_pt[n.name][row]
        row_y = self.y_row(self.lane[leg["el"]], row)
        b = self.blocks[own]
        box = b.row != "x" and b.kind != "dot"
        if leg["track"] is not None:       # out of the row away from the cross-couplings, then along
            up = row == "f"
            yt = row_y + (0.28 + 0.13 * leg["track"]) * (1 if up else -1)
            if len(n.ports) >= 3:
                sx, sy, _ = self.pin(f"{n.name}:{row}", (nx_, yt), row)
            else:
                sx, sy = nx_, ny
            x = self.tap_x(own, ("leg", leg["port"]))
            end = (x, b.y) if b.kind == "dot" else (x, b.y + (b.h / 2 if up else -b.h / 2))
            return _simplify([(sx, sy), (nx_, yt), (x, yt), end])
        if b.bus:                           # up or down to the bus, then along it into its end
            if len(n.ports) >= 3:
                sx, sy, _ = self.pin(f"{n.name}:{row}", (nx_, b.y), row)
            else:
                sx, sy = nx_, ny
            edge = b.x - b.w / 2 if nx_ < b.x else b.x + b.w / 2
            return _simplify([(sx, sy), (nx_, b.y), (edge, b.y)])
        if leg["corridor"] is not None:
            side, _gap = leg["corridor"]
            k = corridor[side]
            corridor[side] += 1
            up = side == "top"
            yc = top_y + _CORRIDOR * k if up else bottom_y - _CORRIDOR * k
            xv = self.gap_x[("chan", leg["port"], row)]      # vertical beside the element
            y_run = row_y + (0.11 if box else 0.22) * (1 if up else -1)
            mid = [(nx_, yc), (xv, yc), (xv, y_run)]
            node_aim = (nx_, yc)
        elif n.name in self.hop:           # around a node sitting on the row in this gap
            _g, node_lane = self.node_gap[n.name]
            y_hop = ny
            y_run = row_y + (0.11 if box else 0.2) * leg["slot"] * leg["dir"]
            if self.lane[leg["el"]] == node_lane:
                c = self.col[leg["el"]]
                xv = self.col_x[c] - 0.2 if leg["right"] is False else self.col_x[c] + self.col_w[c] + 0.2
                mid = [(nx_, y_hop), (xv, y_hop), (xv, y_run)]
            else:
                xv, mid = nx_, [(nx_, y_run)]
            node_aim = (nx_, y_hop)
        else:
            step = 0.11 if box else 0.2
            y_run = row_y + step * leg["slot"] * leg["dir"]
            xv = nx_
            mid = [(nx_, y_run)]
            node_aim = (b.x, row_y) if abs(row_y - ny) < 1e-9 and leg["slot"] == 0 else (nx_, y_run)
        if len(n.ports) >= 3:
            sx, sy, _ = self.pin(f"{n.name}:{row}", node_aim, row)
        else:
            sx, sy = nx_, ny
        pts = [(sx, sy)] + mid
        ex, ey, vertical = self.pin(own, (xv, row_y), row)
        if box:
            pts.append((ex, y_run))                  # into the side of the box, at the run's level
        elif b.kind == "dot":
            pts += [(b.x, y_run), (b.x, b.y)]
        else:                                       # a block between the rows: up or down into it
            pts += [(ex, y_run), (ex, ey)]
        return _simplify(pts)


def _despike(first, second):
    """The two legs of a two-port connection between elements meet at an invisible node point;
    where both leave it the same way the wire would run out to the point and back (a stub that
    ends in nothing).  Cut the spike and move the meeting point to where the legs part."""
    p1, p2 = list(first.points), list(second.points)
    if len(p1) < 2 or len(p2) < 2:
        return
    ends1, ends2 = (p1[0], p1[-1]), (p2[0], p2[-1])
    shared = [(i, j) for i in (0, 1) for j in (0, 1) if _same(ends1[i], ends2[j])]
    if not shared:
        return
    i, j = shared[0]
    a = p1[::-1] if i == 0 else p1          # ... -> node
    b = p2 if j == 0 else p2[::-1]          # node -> ...
    while len(a) >= 2 and len(b) >= 2:
        (ax, ay), (nx_, ny), (bx, by) = a[-2], a[-1], b[1]
        da, db = (nx_ - ax, ny - ay), (bx - nx_, by - ny)
        opposite = (abs(da[0]) < 1e-9 and abs(db[0]) < 1e-9 and da[1] * db[1] < 0) or \
                   (abs(da[1]) < 1e-9 and abs(db[1]) < 1e-9 and da[0] * db[0] < 0)
        if not opposite:
            break
        # the shorter arm ends on the longer one: the meeting point moves to its far end
        if abs(da[0]) + abs(da[1]) <= abs(db[0]) + abs(db[1]):
            a.pop()
            b[0] = a[-1]
            if len(a) < 2:
                break
        else:
            b.pop(0)
            a[-1] = b[0]
            if len(b) < 2:
                break
    a, b = _simplify(a) if len(a) > 1 else a * 2, _simplify(b) if len(b) > 1 else b * 2
    first.points = a[::-1] if i == 0 else a
    second.points = b if j == 0 else b[::-1]


def _same(p, q):
    return abs(p[0] - q[0]) < 1e-9 and abs(p[1] - q[1]) < 1e-9


def _group_symbols(symbols: dict) -> str:
    """``r1 = 0.02, r2 = 0.06; in pg.mesh12: r1 = 0.024`` from {(scope, name): value}."""
    scopes = defaultdict(list)
    for (scope, name), value in sorted(symbols.items()):
        scopes[scope].append(f"{_pretty_name(name)} = {_num(value)}")
    parts = [", ".join(items) if not scope else f"in {scope}: " + ", ".join(items)
             for scope, items in sorted(scopes.items())]
    return "; ".join(parts)


def _simplify(pts):
    """Drop repeated and collinear points of a polyline."""
    out = []
    for p in pts:
        if out and abs(out[-1][0] - p[0]) < 1e-9 and abs(out[-1][1] - p[1]) < 1e-9:
            continue
        out.append(p)
    k = 1
    while k < len(out) - 1:
        (x0, y0), (x1, y1), (x2, y2) = out[k - 1], out[k], out[k + 1]
        if (abs(x0 - x1) < 1e-9 and abs(x1 - x2) < 1e-9) or (abs(y0 - y1) < 1e-9 and abs(y1 - y2) < 1e-9):
            out.pop(k)
        else:
            k += 1
    return out


def _messages(an: Analysis) -> list:
    lines = []
    for d in an.errors:
        text = f"error[{d.code}] {d.message}"
        if d.path:
            text += " — loop: " + " → ".join(d.path)
        if d.fix:
            text += f" — fix: {d.fix}"
        lines.append((CONFLICT, text))
    for d in an.diagnostics:
        if d.code == "derivative_causality":
            lines.append((DERIVATIVE, f"derivative causality: {d.message}"))
    return lines


def layout(analysis: Analysis, types: dict | None = None, title: str = "", subtitle: str = "") -> Diagram:
    """The drawing model of an analysed scene.

    ``types`` maps top-level element names to their type names (``scene.element_types``) for the
    frame labels.  Every port variable of the flat network gets exactly one :class:`Arrow`.
    """
    lay = _Layout(analysis, types)
    lay.build()
    lay.gyrator_links()
    ys = [b.y for b in lay.blocks.values()] + [g.y0 for g in lay.groups] + [g.y1 for g in lay.groups]
    ys += [p[1] for a in lay.arrows for p in a.points]
    xs = [p[0] for a in lay.arrows for p in a.points] + [g.x1 for g in lay.groups] + [0.0]
    extent = (min(xs) - 0.2, max(xs) + 0.3, min(ys) - 0.3, max(ys) + 0.25)
    return Diagram(title, subtitle, lay.blocks, lay.arrows, lay.groups, _messages(analysis), lay.n_lanes,
                   extent, bool(lay.demoted), bool(analysis.errors), _captions(analysis), lay.lane_h,
                   lay.subgroups, lay.footnote_lines(), lay.links,
                   {f"{ph}:x": gone for ph, (_p, _s, gone) in lay.placeholders.items()})


def _captions(an: Analysis) -> tuple:
    """Row captions: Weber's words for mechanics, the quantities' names otherwise."""
    doms = {d.name: d for d in an.flat.port_domains.values()}
    if set(doms) <= {"rotational", "translational"}:
        return "(Bewegungen)", "(Kräfte)"
    if len(doms) == 1:
        d = next(iter(doms.values()))
        return f"({d.flow})", f"({d.effort})"
    return "", ""


# ---------------------------------------------------------------------------------------------
# drawing

def figure(diagram: Diagram):
    """The matplotlib :class:`~matplotlib.figure.Figure` of ``diagram`` (Agg canvas, pyplot's
    global state untouched).  Wires are ``Line2D`` with gid ``wire``; every text is a ``Text``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import FancyBboxPatch, Patch

    xmin, xmax, ymin, ymax = diagram.extent
    margin_l = 1.45                      # row captions [in]
    width_in = max((xmax - xmin) * SCALE + margin_l + 0.3, 9.0)
    chars = int((width_in - 0.8) * 72 / (9.0 * 0.6))
    msg_lines = []
    for colour, text in diagram.messages:
        for line in textwrap.wrap(text, chars, subsequent_indent="    ", break_on_hyphens=False):
            msg_lines.append((colour, line, 9))
    foot_chars = int((width_in - 0.8) * 72 / (8.0 * 0.6))
    for text in diagram.footnotes:
        for line in textwrap.wrap(text, foot_chars, subsequent_indent="      ", break_on_hyphens=False):
            msg_lines.append(("#444444", line, 8))
    title_lines = [diagram.title] + textwrap.wrap(diagram.subtitle, chars + 10)
    head_in = 0.3 + 0.22 * len(title_lines)
    legend_in = 0.75
    msg_in = 0.2 + 0.19 * len(msg_lines) if msg_lines else 0.0
    diag_in = (ymax - ymin) * SCALE
    height_in = head_in + diag_in + legend_in + msg_in + 0.15
    fig = Figure(figsize=(width_in, height_in))
    FigureCanvasAgg(fig)
    ax = fig.add_axes([margin_l / width_in, (legend_in + msg_in + 0.1) / height_in,
                       (xmax - xmin) * SCALE / width_in, diag_in / height_in])
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_axis_off()

    for k, line in enumerate(title_lines):
        fig.text(0.5 / width_in, 1 - (0.3 + 0.22 * k) / height_in, line, fontsize=12 if k == 0 else 9,
                 weight="bold" if k == 0 else "normal", va="baseline", color="#222222")

    # row captions per lane
    flows, efforts = diagram.captions
    for lane in range(diagram.lanes):
        y0 = -lane * diagram.lane_h
        for dy, text, colour in ((0, f"flows\n{flows}", FLOW), (-_DY, "cross-\ncouplings", "#777777"),
                                 (-2 * _DY, f"efforts\n{efforts}", EFFORT)):
            ax.annotate(text, (xmin, y0 + dy), xytext=(-8, 0), textcoords="offset points", ha="right",
                        va="center", fontsize=8, color=colour, annotation_clip=False)

    for g in diagram.groups:
        edge = CONFLICT if g.conflict else "#b8b8b8"
        face = "#fdeaea" if g.conflict else "#f6f6f3"
        ax.add_patch(FancyBboxPatch((g.x0 + 0.04, g.y0), g.x1 - g.x0 - 0.08, g.y1 - g.y0,
                                    boxstyle="round,pad=0,rounding_size=0.12", fc=face, ec=edge,
                                    lw=1.4 if g.conflict else 0.8, zorder=0))
        ax.text(g.x0 + 0.16, g.y1 - 0.1, g.label, fontsize=9, va="top", ha="left",
                color=CONFLICT if g.conflict else "#222222", weight="bold", zorder=5)

    for g in diagram.subgroups:
        ax.add_patch(FancyBboxPatch((g.x0, g.y0), g.x1 - g.x0, g.y1 - g.y0, boxstyle="round,pad=0,rounding_size=0.08",
                                    fc="none", ec=CONFLICT if g.conflict else "#9a9a9a", lw=0.8, ls=(0, (3, 2)),
                                    zorder=1))
        ax.text(g.x0 + 0.06, g.y0 + 0.04, g.label, fontsize=7, va="bottom", ha="left", color="#666666", zorder=7)

    for a in diagram.arrows:
        if not a.drawn or len(a.points) < 2:
            continue
        xs, ys = zip(*a.points)
        style = "--" if not a.determined else "-"
        colour = a.colour
        ax.add_line(Line2D(xs, ys, color=colour, lw=1.1, ls=style, zorder=2, solid_capstyle="butt", gid="wire"))
        if a.head and a.determined:
            tb = diagram.blocks.get(a.target)
            end = a.points[-1]
            prev = a.points[-2]
            shrink = 3.2 if tb is not None and tb.kind == "dot" and abs(end[0] - tb.x) < 1e-6 and tb.w == 0 else 0.0
            ax.annotate("", xy=end, xytext=prev,
                        arrowprops=dict(arrowstyle="-|>,head_length=0.55,head_width=0.28", color=colour, lw=1.1,
                                        shrinkA=0, shrinkB=shrink), zorder=3)
        segs = list(zip(a.points[:-1], a.points[1:]))
        (x0, y0), (x1, y1) = max(segs, key=lambda s: abs(s[1][0] - s[0][0]) + abs(s[1][1] - s[0][1]))
        vertical = abs(x1 - x0) < 1e-9
        if not a.determined:
            ax.text((x0 + x1) / 2 + (0.07 if vertical else 0), (y0 + y1) / 2 + (0 if vertical else 0.06), "?",
                    color=CONFLICT, fontsize=10, weight="bold", ha="left" if vertical else "center",
                    va="center" if vertical else "bottom", zorder=6)
        if a.multiplicity > 1:              # one wire for a collapsed run
            ax.text((x0 + x1) / 2 + (0.06 if vertical else 0), (y0 + y1) / 2 + (0 if vertical else 0.04),
                    f"×{a.multiplicity}", color=colour, fontsize=7, ha="left" if vertical else "center",
                    va="center" if vertical else "bottom", zorder=6,
                    bbox=dict(boxstyle="square,pad=0.05", fc="white", ec="none", alpha=0.85))

    for pts, colour, head in diagram.links:       # gyrators: each effort from the other side's flow
        (x0, y0), (x1, y1) = pts
        ax.annotate("", xy=(x1, y1), xytext=(x0, y0), zorder=3,
                    arrowprops=dict(arrowstyle="-|>,head_length=0.55,head_width=0.28" if head else "-",
                                    color=colour, lw=1.0, shrinkA=0, shrinkB=0, ls="-" if head else "--"))

    for b in diagram.blocks.values():
        edge = CONFLICT if b.conflict else DERIVATIVE if b.derivative else "#222222"
        text_colour = CONFLICT if b.conflict else DERIVATIVE if b.derivative else "#111111"
        if b.kind == "dot" or (b.kind == "sum" and b.bus):
            colour = CONFLICT if b.conflict else (FLOW if b.row == "f" else EFFORT)
            mine = [a for a in diagram.arrows if b.id in (a.source, a.target) and a.drawn and a.points]
            ends = {round(p[0], 6) for a in mine for p in (a.points[0], a.points[-1])
                    if abs(p[1] - b.y) < 0.06 and abs(p[0] - b.x) <= b.w / 2 + 1e-6}
            if b.w > 0:                             # a bus: a line with a branch at every wire on it
                ax.plot([b.x - b.w / 2, b.x + b.w / 2], [b.y, b.y], color=colour, lw=2.2 if b.kind == "dot" else 1.6,
                        zorder=4)
            if b.kind == "dot":
                for x in (ends | {b.x - b.w / 2, b.x + b.w / 2}) if b.w > 0 else {b.x}:
                    ax.plot([x], [b.y], "o", ms=6.5, color=colour, zorder=5)
                continue
            out = [a.points[0][0] for a in mine if a.source == b.id]     # the Σ sits where its result leaves
            sx = out[0] if out else b.x - b.w / 2
            sx = min(max(sx, b.x - b.w / 2 + 0.21), b.x + b.w / 2 - 0.21)
            ax.add_patch(FancyBboxPatch((sx - 0.21, b.y - 0.17), 0.42, 0.34, boxstyle="square,pad=0", fc="white",
                                        ec=edge, lw=1.0, zorder=5))
            ax.text(sx, b.y, "Σ", fontsize=10, ha="center", va="center", color=text_colour, zorder=6)
            continue
        face = "#fff4f4" if b.conflict else "#f7f0fb" if b.derivative else "white"
        ls = "--" if b.derivative or b.kind == "repeat" else "-"
        shape = "round,pad=0,rounding_size=0.08" if b.row == "x" else "square,pad=0"
        ax.add_patch(FancyBboxPatch((b.x - b.w / 2, b.y - b.h / 2), b.w, b.h, boxstyle=shape, fc=face, ec=edge,
                                    lw=1.5 if b.derivative or b.conflict else 1.0, ls=ls, zorder=4))
        if b.kind == "repeat":
            ax.text(b.x, b.y + 0.5, "⋯", fontsize=16, ha="center", va="center", color="#555555", zorder=6)
        if b.note:
            ax.text(b.x, b.y + 0.09, b.label, fontsize=9, ha="center", va="center", color=text_colour, zorder=6)
            ax.text(b.x, b.y - 0.14, b.note, fontsize=7.5, ha="center", va="center", color=text_colour, zorder=6)
        else:
            size = 11 if b.kind == "sum" else 9
            ax.text(b.x, b.y, b.label, fontsize=size, ha="center", va="center", color=text_colour, zorder=6)

    flow_label = f"flow{' ' + flows if flows else ''}: arrow leaves the side that computes it"
    handles = [
        Line2D([], [], color=FLOW, lw=1.3, marker=">", ms=6, label=flow_label),
        Line2D([], [], color=EFFORT, lw=1.3, marker=">", ms=6, label=f"effort{' ' + efforts if efforts else ''}"),
        Line2D([], [], ls="", marker=r"$\Sigma$", ms=9, color="#222222", label="Σ: summation (computes one)"),
        Line2D([], [], ls="", marker="o", ms=6.5, color="#222222", label="branching point: common variable"),
        Patch(fc="white", ec="#222222", label="ratio / cross-coupling I, R, C (∫ integral causality)"),
        Patch(fc="#f7f0fb", ec=DERIVATIVE, ls="--", lw=1.5,
              label="derivative causality (d/dt): resolved into effective storage"),
    ]
    if diagram.links:
        handles.append(Line2D([], [], color="#555555", lw=1.0, marker=">", ms=5,
                              label="gyrator: effort of one side from the flow of the other"))
    if diagram.has_conflict:
        handles.append(Patch(fc="#fdeaea", ec=CONFLICT, lw=1.4, label="conflict (error diagnostic)"))
    if any(not a.determined for a in diagram.arrows):
        handles.append(Line2D([], [], color=CONFLICT, ls="--", lw=1.2, label="? undetermined variable"))
    leg_ax = fig.add_axes([0.02, (msg_in + 0.08) / height_in, 0.96, legend_in / height_in])
    leg_ax.set_axis_off()
    ncol = 4 if width_in > 14 else 3 if width_in > 10.5 else 2
    leg_ax.legend(handles=handles, loc="center", ncol=ncol, fontsize=7.5, frameon=False,
                  handlelength=2.2, columnspacing=1.6)
    for k, (colour, line, size) in enumerate(msg_lines):
        fig.text(0.5 / width_in, (msg_in - 0.15 - 0.19 * k) / height_in, line, fontsize=size, color=colour,
                 va="top", family="DejaVu Sans")
    return fig


def render(diagram: Diagram, path) -> None:
    """Draw ``diagram`` into ``path`` (``.png`` or ``.svg``) with matplotlib's Agg backend."""
    import matplotlib

    fig = figure(diagram)
    width_in = fig.get_size_inches()[0]
    fmt = Path(path).suffix.lower().lstrip(".")
    # SVG: text stays searchable text; fixed ids and no date, so a regenerated figure is identical
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "multipole"}):
        fig.savefig(path, format=fmt, dpi=130 if width_in < 25 else 90,
                    metadata={"Date": None} if fmt == "svg" else None)


# ---------------------------------------------------------------------------------------------
# command

def cmd_diagram(args) -> int:
    """``multipole diagram FILE -o figure.png|svg|pdf``: exit 0 well-posed, 1 not well-posed (the
    figure is still written, conflicts in red); bad input raises :class:`MultipoleError`."""
    from . import pipeline
    from .cli import FIGURE_FORMATS, _overrides, check_output_path
    from .files import atomic_output
    from .netlist import load

    check_output_path(args.output, FIGURE_FORMATS, "-o")
    out = Path(args.output)
    scene = load(args.file, _overrides(args.set))
    analysis = pipeline.check(scene)
    diagram = layout(analysis, scene.element_types, f"{scene.name}: Weber block diagram", scene.description)
    with atomic_output(out) as tmp:        # an interrupted write leaves no short figure behind
        render(diagram, tmp)
    print(f"wrote {out}" + ("" if analysis.ok else f" ({len(analysis.errors)} conflict(s) in red)"))
    return 0 if analysis.ok else 1


__all__ = ["Arrow", "Block", "Diagram", "Group", "cmd_diagram", "figure", "layout", "render"]
