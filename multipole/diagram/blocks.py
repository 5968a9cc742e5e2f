"""Stage 2 of a block diagram: what every item is drawn as, and how wide.

:func:`make_blocks` creates the :class:`~multipole.diagram.model.Block` of every drawn item in
the :class:`~multipole.diagram.ordering.Ordering` (Σ boxes and dots of junctions and nodes, ratio
and gyrator blocks, cross-couplings with their parameter, terminals, placeholders of collapsed
repeats) with its label and its size, and from the sizes the slot of each item inside its
element.  Labels too long for their block become footnotes, and the parameter symbols written in
labels are remembered with their values.  Blocks get their positions in the placement stage.
Sizes are in drawing units, font sizes in points.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from fractions import Fraction

import sympy as sp

from ..network import var
from ..primitives import T
from .model import DRAWN_HEAD, DY, FONT, HANG, NOTE_CHARS, RATIO_CHARS, SCALE, SUB, Block
from .ordering import Ordering
from .topology import Topology


@dataclass
class BlockSet:
    """The blocks of a diagram, sized but not yet placed.

    ``blocks``: block id -> :class:`~multipole.diagram.model.Block` (id ``path:f``, ``path:e`` or
    ``path:x`` for the flow row, effort row or between them), in drawing order.  ``items``:
    element -> (items left to right, {host item: hanging cross-couplings}, {item: (x offset, width)}
    inside the element's frame); ``widths``: element -> frame width.  ``footnotes``: (what, full
    text) of labels too long for their block, numbered from 1 in this order; ``symbols``: (scope,
    shown name) -> value of every parameter written in a label.  Lengths in drawing units.
    """

    blocks: dict
    items: dict
    widths: dict
    footnotes: list
    symbols: dict


def make_blocks(topo: Topology, ordering: Ordering) -> BlockSet:
    """The blocks of every element's items (and of the nodes joining three or more ports) with
    their labels and sizes, and each item's slot in its element."""
    m = _BlockMaker(topo)
    items, widths = {}, {}
    for el in topo.elements:
        order, hang, buses = ordering.items[el], ordering.hang[el], ordering.buses[el]
        xs, x = {}, 0.25
        for it in order:
            if it in topo.placeholders:
                b = m.placeholder_block(it)
                w = max(SUB, b.w + 0.4)
            elif it in topo.prims and topo.is_middle(it):
                b = m.middle_block(it)
                w = max(SUB, b.w + 0.3)
            elif it in topo.prims:
                m.row_blocks(it)
                hs = [m.middle_block(h) for h in hang.get(it, [])]
                w = max(SUB, sum(max(HANG, hb.w + 0.2) for hb in hs), m.blocks[f"{it}:f"].w + 0.4)
            elif topo.node_by_name[it].origin == "termination":
                b = m.terminal_block(topo.node_by_name[it])
                w = max(SUB, b.w + 0.3)
            else:
                m.node_blocks(topo.node_by_name[it], el)
                hs = [m.middle_block(h) for h in hang.get(it, [])]
                w = max(SUB, sum(max(HANG, hb.w + 0.2) for hb in hs))
            xs[it] = (x, w)
            x += w
        for j in buses:
            if j in topo.prims:
                m.row_blocks(j)
            else:
                m.node_blocks(topo.node_by_name[j], el)
            for row in ("f", "e"):
                m.blocks[f"{j}:{row}"].bus = True
        items[el] = (order, hang, xs)
        widths[el] = max(x + 0.25, _text_width(topo.group_label(el), 9) + 0.4)
    for n in topo.top_nodes:                # a node of three or more ports: a dot and a Σ in the gap
        if len(n.ports) >= 3:
            m.node_blocks(n, "")
    return BlockSet(m.blocks, items, widths, m.footnotes, m.symbols)


def footnote_lines(topo: Topology, blockset: BlockSet) -> list:
    """Footnotes below the legend: collapsed repeats, labels too long for their block, and the
    values of the symbols written in ratio blocks."""
    lines = []
    for ph, (parent, subs, gone) in topo.placeholders.items():
        short = [x.rsplit(".", 1)[1] for x in subs]
        drawn = [x for x in short if f"{parent}.{x}" not in gone]
        typ = topo.flat.elements[subs[0]]
        lines.append(f"{parent}: {len(subs)} × {typ}, drawn: {len(drawn)} ({', '.join(drawn)}); "
                     f"{short[DRAWN_HEAD]} … {short[-2]} are identical to those drawn, their "
                     f"{len(gone)} parallel wires drawn once and marked ×{len(gone)}")
    for k, (what, text) in enumerate(blockset.footnotes, 1):
        lines.append(f"[{k}] {what}: {text}")
    if blockset.symbols:
        lines.append("symbols in the blocks: " + _group_symbols(blockset.symbols))
    return lines


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


def _text_width(text: str, size: float = FONT) -> float:
    """Estimated width of the longest line of ``text`` at font size ``size`` [pt], in drawing units."""
    longest = max((len(line) for line in text.split("\n")), default=0)
    return longest * 0.58 * size / 72.0 / SCALE


def _group_symbols(symbols: dict) -> str:
    """``r1 = 0.02, r2 = 0.06; in pg.mesh12: r1 = 0.024`` from {(scope, name): value}."""
    scopes = defaultdict(list)
    for (scope, name), value in sorted(symbols.items()):
        scopes[scope].append(f"{_pretty_name(name)} = {_num(value)}")
    parts = [", ".join(items) if not scope else f"in {scope}: " + ", ".join(items)
             for scope, items in sorted(scopes.items())]
    return "; ".join(parts)


class _BlockMaker:
    """The work of :func:`make_blocks`: creates blocks and collects footnotes and symbols."""

    def __init__(self, topo: Topology):
        self.topo = topo
        self.blocks: dict = {}
        self.footnotes: list = []           # (what, full text) of labels too long for a block
        self.symbols: dict = {}             # (scope, shown name) -> value of a symbol in a label

    def _block(self, bid, kind, label, row, owner, element, note="", identity=False, w=None, h=None):
        default = {"sum": (0.42, 0.38), "dot": (0.0, 0.0), "ratio": (0.62, 0.38), "gyrator": (0.95, 0.38)}
        dw, dh = default.get(kind, (0.98, 0.58))
        text_w = 0.0 if kind == "dot" else max(_text_width(label, 9), _text_width(note, 7.5)) + 0.22
        b = Block(bid, kind, label, row, owner, element, note, w=max(w or dw, text_w), h=h or dh, identity=identity)
        b.conflict = element in self.topo.red
        self.blocks[bid] = b
        return b

    def _relation(self, path, natural):
        """The flat equation of primitive ``path`` whose natural output is ``natural``."""
        for eq in self.topo.flat.equations:
            if eq.owner == path and eq.natural is not None and eq.natural.name == natural:
                return eq
        return None

    def _coefficient_note(self, path, name):
        """``"J = 0.002"``: the linear coefficient of an I (J), C (c) or R (r) as the flat equation
        has it, named after its parameter symbol; ``None`` for a nonlinear law."""
        state = {"I": "p", "C": "q"}.get(self.topo.prims[path].kind)
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
        if coef.free_symbols and coef.free_symbols <= set(self.topo.values):
            value = float(coef.xreplace({s: sp.Float(self.topo.values[s]) for s in coef.free_symbols}))
            label = _pretty_name(coef.name.rsplit(".", 1)[-1]) if isinstance(coef, sp.Symbol) else name
            return self.fit(f"{label} = {_num(value)}", NOTE_CHARS, path)
        return self.fit(f"{name} = {_expr_text(self.symbolic(coef))}", NOTE_CHARS, path)

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
            while scope and sym not in self.topo.values:
                scope = scope.rpartition(".")[0]
                full = sp.Symbol(f"{scope}.{sym.name}" if scope else sym.name)
                if full in self.topo.values:
                    scoped[sym] = full
                    break
        expr = expr.xreplace(scoped)
        own = {sym: sp.Float(self.topo.values[sym]) for sym in expr.free_symbols
               if sym in self.topo.values and path and sym.name.rpartition(".")[0] == path}
        expr = expr.xreplace(own)
        params = [sym for sym in expr.free_symbols if sym in self.topo.values]
        shorts = defaultdict(list)
        for sym in params:
            shorts[sym.name.rpartition(".")[2]].append(sym)
        subs = {}
        for short, syms in shorts.items():
            for sym in syms:
                name = short if len(syms) == 1 else sym.name
                subs[sym] = sp.Symbol(name)
                self.symbols[(sym.name.rpartition(".")[0] if len(syms) == 1 else "", name)] = self.topo.values[sym]
        return expr.xreplace(subs)

    def middle_block(self, path):
        prim = self.topo.prims[path]
        el = self.topo.flat.element_of(path)
        k = prim.kind
        pr = prim.params
        deriv = path in self.topo.demoted
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
            note = self.fit(_expr_text(pr["value"]), NOTE_CHARS, path, f"{var_} = ")
        elif k == "Tap":
            label, note, kind = "Tap  ∫", "", "tap"
        else:                               # a kind an element library defines
            label, kind = k, "other"
            note = self.fit(prim.doc.split(":")[0] if prim.doc else "", NOTE_CHARS, path)
        b = self._block(f"{path}:x", kind, label, "x", path, el, note)
        b.derivative = deriv
        return b

    def placeholder_block(self, ph):
        """The block that stands for a collapsed run of identical sub-elements."""
        parent, subs, gone = self.topo.placeholders[ph]
        typ = self.topo.flat.elements[subs[0]]
        short = [g.rsplit(".", 1)[1] for g in gone]
        b = self._block(f"{ph}:x", "repeat", f"{len(gone)} × {typ}", "x", ph, self.topo.flat.element_of(ph),
                        f"{short[0]} … {short[-1]}: as drawn", h=2 * DY + 0.3)
        return b

    def row_blocks(self, path):
        """Blocks of a primitive that lives on the rows (junction, TF, MTF, GY)."""
        prim = self.topo.prims[path]
        el = self.topo.flat.element_of(path)
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
            fa, fb = self.topo.out.get(f"{path}.a.f"), self.topo.out.get(f"{path}.b.f")
            ea, eb = self.topo.out.get(f"{path}.a.e"), self.topo.out.get(f"{path}.b.e")
            flow = 1 / base if fb and not fa else base
            effort = -1 / base if ea and not eb else -base
            flow_label = self.fit(_short_form(flow), RATIO_CHARS, f"{path}, flows")
            if moving:                      # a modulated transformer: its ratio in a footnote
                entry = (path, f"{base} = {_expr_text(ratio)}")
                if entry not in self.footnotes:
                    self.footnotes.append(entry)
                flow_label += f" [{self.footnotes.index(entry) + 1}]"
            self._block(f"{path}:f", "ratio", flow_label, "f", path, el)
            self._block(f"{path}:e", "ratio", self.fit(_short_form(effort), RATIO_CHARS, f"{path}, efforts"), "e",
                        path, el)
            return
        if k == "GY":
            r = self.fit(_expr_text(self.symbolic(prim.params["r"], path)), RATIO_CHARS - 3,
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
        for eq in self.topo.flat.equations:
            if eq.owner == path and eq.expr.has(fa) and eq.expr.has(fb):
                k = -sp.diff(eq.expr, fb) / sp.diff(eq.expr, fa)
                states = {v: sp.Symbol(v.name.rsplit(".", 1)[-1]) for v in k.free_symbols
                          if v not in self.topo.values and v != T}
                moving = sorted(s.name for s in states.values())
                k = self.symbolic(k, path).xreplace(states)
                # a modulated ratio (a contour table, a band's geometry) can be large: simplifying
                # it takes minutes and it is only printed in a footnote
                return (k if moving else sp.simplify(k)), moving
        return sp.Symbol("k"), []

    def node_blocks(self, node, element):
        common = node.domain.across
        for row in ("f", "e"):
            dot = row == common
            self._block(f"{node.name}:{row}", "dot" if dot else "sum", "" if dot else "Σ", row, node.name,
                        element, identity=dot)

    def terminal_block(self, node):
        pp = node.ports[0]
        el = self.topo.flat.element_of(pp)
        free = node.domain.free_variable
        label = "free end" if free == "e" else "open"
        return self._block(f"{node.name}:x", "terminal", label, "x", node.name, el,
                           f"{free} = 0 at {pp.split('.', 1)[-1]}")
