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

import textwrap
from fractions import Fraction
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import sympy as sp

from .causality import Analysis, _alias_pair
from .errors import MultipoleError
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


@dataclass
class Block:
    """One drawn block.

    ``kind``: ``sum`` (Σ), ``dot`` (branching point), ``ratio`` (TF/MTF), ``gyrator``, ``storage``
    (I, C, C-field), ``resistance`` (R), ``source`` (Se, Sf), ``tap``, ``terminal`` (an unconnected
    port), ``other`` (a one-port kind defined by an element library).
    ``row``: ``"f"`` (flow row), ``"e"`` (effort row) or ``"x"`` (between the rows).
    ``owner`` is the primitive path or the node name whose equations the block stands for;
    ``element`` the top-level element it belongs to (``""`` for a node joining elements).
    ``identity`` marks blocks that only pass a value on (dots, two-port sums).
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


@dataclass
class Arrow:
    """The signal of one port variable: from the block that computes it to the one that uses it.

    ``determined`` is False when no equation computes the variable (then ``source``/``target``
    are just the two ends and the wire is drawn red and dashed without a head).
    ``points`` is the drawn route from source to target; ``drawn`` is False for the second
    variable of a two-port connection inside an element (same wire as its partner).
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


def _expr_text(expr, limit: int = 22) -> str:
    """Short readable form of a sympy expression: round floats, cut long ones."""
    expr = sp.sympify(expr).replace(sp.Heaviside, lambda *a: sp.Function("step")(a[0]))
    if expr.is_number:
        try:
            return _num(float(expr))
        except TypeError:
            pass
    floats = {}
    for f in expr.atoms(sp.Float):
        r = float(f"{float(f):.4g}")
        floats[f] = sp.Integer(int(r)) if r == int(r) else sp.Float(r, 4)
    return _short(str(expr.xreplace(floats)).replace("**", "^"), limit)


def _short(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[:limit - 1] + "…"


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
        """Columns along the drive chain from the first driving source (breadth first); elements
        reached through the same node share a column and are stacked in lanes."""
        nodes_of = defaultdict(list)
        for n in self.top_nodes:
            for p in n.ports:
                el = self.flat.element_of(p)
                if n not in nodes_of[el]:
                    nodes_of[el].append(n)
        self.col, self.lane, self.parent_node, self.node_parent = {}, {}, {}, {}
        used = defaultdict(set)             # column -> used lanes

        def place(el, c, want):
            lane = want
            while lane in used[c]:
                lane += 1
            used[c].add(lane)
            self.col[el], self.lane[el] = c, lane

        n_ports = defaultdict(int)
        for pp in self.flat.external_ports:
            n_ports[pp.split(".", 1)[0]] += 1

        def chain_first(n):
            """Nodes that lead on to multi-port elements before those that only attach grounds."""
            new = {self.flat.element_of(p) for p in n.ports} - set(self.col)
            return 0 if any(n_ports[e] > 1 for e in new) else 1

        def expand(el, nodes, queue):
            for n in sorted(nodes, key=chain_first):
                if n.name in self.node_parent:
                    continue
                els = list(dict.fromkeys(self.flat.element_of(p) for p in n.ports))
                parent = min((e for e in els if e in self.col), key=lambda e: (self.col[e], e != el))
                self.node_parent[n.name] = parent          # the node sits after its leftmost element
                for e in els:
                    if e not in self.col:
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

        def is_drive(el):
            for path, prim in self.prims.items():
                if self.flat.element_of(path) == el and prim.kind in ("Se", "Sf"):
                    return sp.sympify(prim.params["value"]) != 0
            return False

        start = 0
        pending = [e for e in self.elements if is_drive(e)] + self.elements
        for root in pending:
            if root in self.col:
                continue
            place(root, start, 0)
            visit(root)
            start = max(self.col.values()) + 1
        self.n_cols = max(self.col.values()) + 1
        self.n_lanes = max(self.lane.values()) + 1

    # -- items inside an element ------------------------------------------------------------------
    def element_items(self, el):
        """Ordered items of an element (primitives on the rows, inner nodes, middle blocks that
        do not hang under a junction, unconnected-port terminals) and the hanging ones."""
        prims = [p for p in self.prims if self.flat.element_of(p) == el]
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
                if not self.is_middle(q):
                    host_of[p] = q
            if p in host_of:
                hang[host_of[p]].append(p)
        inner = [n for n in self.inner_nodes if self.flat.element_of(n.ports[0]) == el and len(n.ports) >= 3]
        items = [p for p in prims if p not in host_of] + [n.name for n in inner]
        term_of = defaultdict(list)
        for n in self.terminations:
            if self.flat.element_of(n.ports[0]) == el:
                term_of[n.ports[0].rsplit(".", 1)[0]].append(n.name)
        # adjacency between items through inner nodes
        item_of = {p: host_of.get(p, p) for p in prims}
        adj = defaultdict(list)
        for n in self.inner_nodes:
            if self.flat.element_of(n.ports[0]) != el:
                continue
            its = [item_of[q.rsplit(".", 1)[0]] for q in n.ports]
            if len(n.ports) >= 3:
                its = its + [n.name]
                for a in its[:-1]:
                    if a != n.name:
                        adj[a].append(n.name)
                        adj[n.name].append(a)
            else:
                a, b = its
                if a != b:
                    adj[a].append(b)
                    adj[b].append(a)
        # entry: the item at the port through which the element was reached
        entry = items[0] if items else None
        pn = self.parent_node.get(el)
        if pn is not None:
            p = next(q for q in pn.ports if self.flat.element_of(q) == el)
            entry = item_of[p.rsplit(".", 1)[0]]
        order = []

        def dfs(it):
            if it in order:
                return
            order.append(it)
            for t in term_of.get(it, []):
                order.append(t)
            for h in hang.get(it, []):
                order.extend(t for t in term_of.get(h, []) if t not in order)
            # within the same sub-network first, along the row primitives before cross-couplings
            here = self.subnet(it)
            for nb in sorted(adj[it], key=lambda x: (self.subnet(x) != here,
                                                     x in self.prims and self.is_middle(x))):
                dfs(nb)

        if entry is not None:
            dfs(entry)
        for it in items:
            dfs(it)
        for ts in term_of.values():
            order.extend(t for t in ts if t not in order)
        first_seen = {}                     # keep each nested network's items together
        for it in order:
            first_seen.setdefault(self.subnet(it), len(first_seen))
        order.sort(key=lambda it: first_seen[self.subnet(it)])
        return order, hang

    # -- blocks -------------------------------------------------------------------------------------
    def _block(self, bid, kind, label, row, owner, element, note="", identity=False, w=None, h=None):
        default = {"sum": (0.42, 0.38), "dot": (0.0, 0.0), "ratio": (0.62, 0.38), "gyrator": (0.62, 0.38)}
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
        return self._param_text(coef, name)

    def _param_text(self, coef, name):
        coef = sp.sympify(coef)
        if coef.free_symbols and coef.free_symbols <= set(self.values):
            value = float(coef.xreplace({s: sp.Float(self.values[s]) for s in coef.free_symbols}))
            label = coef.name.rsplit(".", 1)[-1] if isinstance(coef, sp.Symbol) else name
            return f"{label} = {_num(value)}"
        return f"{name} = {_expr_text(coef, 12)}"

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
            label, note, kind = k, ("e" if k == "Se" else "f") + " = " + _expr_text(pr["value"]), "source"
        elif k == "Tap":
            label, note, kind = "Tap  ∫", "", "tap"
        else:                               # a kind an element library defines
            label, note, kind = k, _short(prim.doc.split(":")[0] if prim.doc else "", 24), "other"
        b = self._block(f"{path}:x", kind, label, "x", path, el, note)
        b.derivative = deriv
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
            self._block(f"{path}:f", "ratio", _expr_text(flow, 9), "f", path, el)
            self._block(f"{path}:e", "ratio", _expr_text(effort, 9), "e", path, el)
            return
        if k == "GY":
            r = _expr_text(prim.params["r"], 7)
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
                moving = sorted({v.name.rsplit(".", 1)[-1] for v in k.free_symbols
                                 if v not in self.values and v != T})
                subs = {}
                for sym in k.free_symbols:
                    if sym in self.values and "." in sym.name:
                        subs[sym] = sp.Float(self.values[sym])     # element-local constants
                    elif sym in self.values:
                        subs[sym] = sp.Symbol(sym.name)            # scene parameters by name
                return sp.simplify(k.xreplace(subs)), moving
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
        """Block of primitive ``path`` that carries its variables of ``row``."""
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
            xs, x = {}, 0.25
            for it in order:
                if it in self.prims and self.is_middle(it):
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
            label = self.group_label(el)
            width = max(x + 0.25, _text_width(label, 9) + 0.4)
            self.items[el] = (order, hang, xs)
            self.widths[el] = width
            self.inner_tracks(el, order)
        self.col_w = [max([self.widths[e] for e in self.elements if self.col[e] == c] or [1.0])
                      for c in range(self.n_cols)]
        self.plan_wires()
        self.pad = {el: 0.13 * max(0, n - 1) for el, n in self.n_tracks.items()}
        extra = max(self.pad.values(), default=0.0)
        self.lane_h = _LANE + 2 * extra
        self.top_base = 0.8 + extra + 0.55
        self.place()
        self.route()

    def inner_tracks(self, el, order):
        """Connections inside an element whose ends are not neighbours on the rows run over a
        track outside the rows (above the flows, below the efforts); number them."""
        pos = {it: k for k, it in enumerate(order)}
        rows_at = [pos[it] for it in order if f"{it}:f" in self.blocks]
        count = 0
        for n in self.inner_nodes:
            if self.flat.element_of(n.ports[0]) != el:
                continue
            prims = [q.rsplit(".", 1)[0] for q in n.ports]
            if len(n.ports) == 2:
                pairs = [(n.name, prims[0], prims[1])]
            else:
                pairs = [((n.name, q), n.name, pr) for q, pr in zip(n.ports, prims)]
            for key, a, b in pairs:
                if a not in pos or b not in pos:
                    continue            # hanging under a junction: a short vertical wire
                lo, hi = sorted((pos[a], pos[b]))
                if any(lo < k < hi for k in rows_at):
                    self.track[key] = count
                    count += 1
        self.n_tracks[el] = count

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
            self.track[key] = self.n_tracks[el]
            self.n_tracks[el] += 1
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
            g = self.col[parent]
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
            self.groups.append(Group(el, self.group_label(el), x0, ye - 0.5 - pad, x0 + self.widths[el], yf + 0.8 + pad,
                                     el in self.red))
            run = []                       # consecutive items of one nested network: a sub-frame
            for it in order + [None]:
                net = self.subnet(it) if it is not None else None
                if run and net != run[0][0]:
                    sub = run[0][0]
                    if sub != el and sub.startswith(el + "."):
                        left, right = xs[run[0][1]][0], sum(xs[run[-1][1]])
                        self.subgroups.append(Group(sub, f"{sub[len(el) + 1:]} ({self.flat.elements[sub]})",
                                                    x0 + left + 0.05, ye - 0.42, x0 + right - 0.05, yf + 0.42,
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
        # nodes joining elements; where several share a gap in one lane, the multi-port ones move
        # off the row line (between the rows) so straight wires through the gap miss their blocks
        self.node_pt = {}
        sharing = defaultdict(list)
        for n in self.top_nodes:
            sharing[self.node_gap[n.name]].append(n)
        shift = {}
        for group in sharing.values():
            multi = [n for n in group if len(n.ports) >= 3]
            movers = multi if len(multi) < len(group) else multi[1:]
            for j, n in enumerate(movers, 1):
                shift[n.name] = 0.4 * j
        for n in self.top_nodes:
            g, lane = self.node_gap[n.name]
            xf = self.gap_x.get(("node", n.name, "f"), self.gap_x.get(("node", n.name, "fe")))
            xe = self.gap_x.get(("node", n.name, "e"), xf)
            dy = shift.get(n.name, 0.0)
            self.node_pt[n.name] = {"f": (xf, self.y_row(lane, "f") - dy), "e": (xe, self.y_row(lane, "e") + dy)}
            if len(n.ports) >= 3:
                self.node_blocks(n, "")
                for row in ("f", "e"):
                    b = self.blocks[f"{n.name}:{row}"]
                    b.x, b.y = self.node_pt[n.name][row]

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
        for pp in self.flat.port_domains:
            prim = pp.rsplit(".", 1)[0]
            n = self.node_of[pp]
            for row in ("f", "e"):
                v = f"{pp}.{row}"
                own = self.block_id(prim, row)
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
                else:
                    key = n.name if len(n.ports) == 2 else (n.name, pp)
                    if key in self.track:
                        pts = self.track_route(own, other, row, self.track[key])
                    else:
                        a = self.pin(own, self.centre(other), row)
                        b = self.pin(other, self.centre(own), row)
                        pts = self.path_between(a, b, self.y_row(self.lane_of_block(own), row))
                    arrow.points = pts if src == own else pts[::-1]
                    arrow.drawn = n.origin == "termination" or len(n.ports) != 2 or pp == n.ports[0]
                if not arrow.determined:
                    arrow.head = False
                self.arrows.append(arrow)
        self.top_y = top_y + _CORRIDOR * corridor["top"]
        self.bottom_y = bottom_y - _CORRIDOR * corridor["bottom"]

    def pad_max(self):
        return max(self.pad.values(), default=0.0)

    def track_route(self, own, other, row, k):
        """Route over inner track ``k``: out of the row away from the cross-couplings and back."""
        up = row == "f"
        a, b = self.blocks[own], self.blocks[other]
        yc = self.y_row(self.lane_of_block(own), row) + (0.28 + 0.13 * k) * (1 if up else -1)

        def end(blk):
            return (blk.x, blk.y) if blk.kind == "dot" else (blk.x, blk.y + (blk.h / 2 if up else -blk.h / 2))
        return [end(a), (a.x, yc), (b.x, yc), end(b)]

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
            legs.sort(key=lambda lg: abs(self.node_pt[lg["node"].name][lg["row"]][1]
                                         - self.y_row(self.lane[lg["el"]], lg["row"])))
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
            end = (b.x, b.y) if b.kind == "dot" else (b.x, b.y + (b.h / 2 if up else -b.h / 2))
            return _simplify([(sx, sy), (nx_, yt), (b.x, yt), end])
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
    ys = [b.y for b in lay.blocks.values()] + [g.y0 for g in lay.groups] + [g.y1 for g in lay.groups]
    ys += [p[1] for a in lay.arrows for p in a.points]
    xs = [p[0] for a in lay.arrows for p in a.points] + [g.x1 for g in lay.groups] + [0.0]
    extent = (min(xs) - 0.2, max(xs) + 0.3, min(ys) - 0.3, max(ys) + 0.25)
    return Diagram(title, subtitle, lay.blocks, lay.arrows, lay.groups, _messages(analysis), lay.n_lanes,
                   extent, bool(lay.demoted), bool(analysis.errors), _captions(analysis), lay.lane_h,
                   lay.subgroups)


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

def render(diagram: Diagram, path) -> None:
    """Draw ``diagram`` into ``path`` (``.png`` or ``.svg``) with matplotlib's Agg backend."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import FancyBboxPatch, Patch

    xmin, xmax, ymin, ymax = diagram.extent
    margin_l = 1.45                      # row captions [in]
    width_in = max((xmax - xmin) * SCALE + margin_l + 0.3, 9.0)
    chars = int(width_in * 72 / (9.0 * 0.56))
    msg_lines = []
    for colour, text in diagram.messages:
        for line in textwrap.wrap(text, chars, subsequent_indent="    ", break_on_hyphens=False):
            msg_lines.append((colour, line))
    title_lines = [diagram.title] + textwrap.wrap(diagram.subtitle, chars + 10)
    head_in = 0.3 + 0.22 * len(title_lines)
    legend_in = 0.75
    msg_in = 0.2 + 0.19 * len(msg_lines) if msg_lines else 0.0
    diag_in = (ymax - ymin) * SCALE
    height_in = head_in + diag_in + legend_in + msg_in + 0.15
    fig = Figure(figsize=(width_in, height_in))     # Agg canvas; pyplot's global state untouched
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
        ax.text(g.x0 + 0.06, g.y0 + 0.04, g.label, fontsize=7, va="bottom", ha="left", color="#666666", zorder=7,
                bbox=dict(boxstyle="square,pad=0.1", fc="#f6f6f3", ec="none"))

    for a in diagram.arrows:
        if not a.drawn or len(a.points) < 2:
            continue
        xs, ys = zip(*a.points)
        style = "--" if not a.determined else "-"
        colour = a.colour
        ax.plot(xs, ys, color=colour, lw=1.1, ls=style, zorder=2, solid_capstyle="butt")
        if a.head and a.determined:
            tb = diagram.blocks.get(a.target)
            end = a.points[-1]
            prev = a.points[-2]
            shrink = 3.2 if tb is not None and tb.kind == "dot" and abs(end[0] - tb.x) < 1e-6 else 0.0
            ax.annotate("", xy=end, xytext=prev,
                        arrowprops=dict(arrowstyle="-|>,head_length=0.55,head_width=0.28", color=colour, lw=1.1,
                                        shrinkA=0, shrinkB=shrink), zorder=3)
        if not a.determined:
            segs = list(zip(a.points[:-1], a.points[1:]))
            (x0, y0), (x1, y1) = max(segs, key=lambda s: abs(s[1][0] - s[0][0]) + abs(s[1][1] - s[0][1]))
            vertical = abs(x1 - x0) < 1e-9
            ax.text((x0 + x1) / 2 + (0.07 if vertical else 0), (y0 + y1) / 2 + (0 if vertical else 0.06), "?",
                    color=CONFLICT, fontsize=10, weight="bold", ha="left" if vertical else "center",
                    va="center" if vertical else "bottom", zorder=6)

    for b in diagram.blocks.values():               # a gyrator couples each row to the other
        if b.kind == "gyrator" and b.row == "f":
            other = diagram.blocks.get(b.id[:-2] + ":e")
            if other is not None:
                ax.plot([b.x, other.x], [b.y, other.y], color="#888888", lw=0.9, ls=(0, (2, 2)), zorder=1)
                ax.text(b.x + 0.06, (b.y + other.y) / 2, "e ↔ f", fontsize=7.5, color="#555555", ha="left",
                        va="center", zorder=6)

    for b in diagram.blocks.values():
        edge = CONFLICT if b.conflict else DERIVATIVE if b.derivative else "#222222"
        text_colour = CONFLICT if b.conflict else DERIVATIVE if b.derivative else "#111111"
        if b.kind == "dot":
            colour = CONFLICT if b.conflict else (FLOW if b.row == "f" else EFFORT)
            if b.w > 0:                             # a bus: a branching point at every wire on it
                ax.plot([b.x - b.w / 2, b.x + b.w / 2], [b.y, b.y], color=colour, lw=2.2, zorder=4)
                taps = {round(p[0], 6) for a in diagram.arrows if b.id in (a.source, a.target)
                        for p in (a.points[0], a.points[-1])
                        if abs(p[1] - b.y) < 1e-6 and abs(p[0] - b.x) <= b.w / 2 + 1e-6}
                for x in taps | {b.x - b.w / 2, b.x + b.w / 2}:
                    ax.plot([x], [b.y], "o", ms=6.5, color=colour, zorder=5)
            else:
                ax.plot([b.x], [b.y], "o", ms=6.5, color=colour, zorder=5)
            continue
        face = "#fff4f4" if b.conflict else "#f7f0fb" if b.derivative else "white"
        ls = "--" if b.derivative else "-"
        shape = "round,pad=0,rounding_size=0.08" if b.row == "x" else "square,pad=0"
        ax.add_patch(FancyBboxPatch((b.x - b.w / 2, b.y - b.h / 2), b.w, b.h, boxstyle=shape, fc=face, ec=edge,
                                    lw=1.5 if b.derivative or b.conflict else 1.0, ls=ls, zorder=4))
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
    if diagram.has_conflict:
        handles.append(Patch(fc="#fdeaea", ec=CONFLICT, lw=1.4, label="conflict (error diagnostic)"))
    if any(not a.determined for a in diagram.arrows):
        handles.append(Line2D([], [], color=CONFLICT, ls="--", lw=1.2, label="? undetermined variable"))
    leg_ax = fig.add_axes([0.02, (msg_in + 0.08) / height_in, 0.96, legend_in / height_in])
    leg_ax.set_axis_off()
    ncol = 4 if width_in > 14 else 3 if width_in > 10.5 else 2
    leg_ax.legend(handles=handles, loc="center", ncol=ncol, fontsize=7.5, frameon=False,
                  handlelength=2.2, columnspacing=1.6)
    for k, (colour, line) in enumerate(msg_lines):
        fig.text(0.5 / width_in, (msg_in - 0.15 - 0.19 * k) / height_in, line, fontsize=9, color=colour,
                 va="top", family="DejaVu Sans")
    fmt = Path(path).suffix.lower().lstrip(".")
    # SVG: text stays searchable text; fixed ids and no date, so a regenerated figure is identical
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "multipole"}):
        fig.savefig(path, format=fmt, dpi=130 if width_in < 25 else 90,
                    metadata={"Date": None} if fmt == "svg" else None)


# ---------------------------------------------------------------------------------------------
# command

def cmd_diagram(args) -> int:
    """``multipole diagram FILE -o figure.png|svg``: exit 0 well-posed, 1 not well-posed (the
    figure is still written, conflicts in red); bad input raises :class:`MultipoleError`."""
    from . import pipeline
    from .cli import _overrides
    from .netlist import load

    out = Path(args.output)
    if out.suffix.lower() not in (".png", ".svg"):
        raise MultipoleError("bad_output", f"cannot write a diagram to {args.output!r}",
                             "give a file name ending in .png or .svg")
    if not out.parent.exists():
        raise MultipoleError("bad_output", f"directory {str(out.parent)!r} does not exist",
                             "create it or write the figure elsewhere")
    scene = load(args.file, _overrides(args.set))
    analysis = pipeline.check(scene)
    diagram = layout(analysis, scene.element_types, f"{scene.name}: Weber block diagram", scene.description)
    render(diagram, out)
    print(f"wrote {out}" + ("" if analysis.ok else f" ({len(analysis.errors)} conflict(s) in red)"))
    return 0 if analysis.ok else 1


__all__ = ["Arrow", "Block", "Diagram", "Group", "cmd_diagram", "layout", "render"]
