"""Stage 0 of a block diagram: the scene as the diagram sees it.

:class:`Topology` collects, once, what every later stage asks of the analysed flat network: the
primitives and nodes, which nodes join elements and which sit inside one, which side computes
each port variable (:func:`orientation`), the elements in conflict, and the families of
identical sub-elements that are drawn collapsed.  It holds no geometry.
"""
from __future__ import annotations

import re
from collections import defaultdict

from ..causality import Analysis, _alias_pair
from .model import COLLAPSE_ABOVE, DRAWN_HEAD, MIDDLE_KINDS, ROW_KINDS


def _port_of(var_name: str) -> tuple[str, str, str]:
    """``"rotor.j.a.e"`` -> (primitive path, port, ``"e"``)."""
    pp, kind = var_name.rsplit(".", 1)
    prim, port = pp.rsplit(".", 1)
    return prim, port, kind


def orientation(an: Analysis) -> dict:
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


class Topology:
    """The analysed scene's structure, read by every stage (no geometry).

    Attributes: ``an`` (the :class:`~multipole.causality.Analysis`), ``flat`` (its flat network),
    ``types`` (top-level element -> type name for the frame labels), ``prims`` (path ->
    primitive), ``node_of`` (port path -> node), ``node_by_name``, ``elements`` (top-level
    elements in netlist order), ``out`` (:func:`orientation`), ``values`` (parameter symbol ->
    value), ``red`` (elements named by an error diagnostic), ``demoted`` (storages in derivative
    causality), ``top_nodes`` (nodes joining elements; ``top_set`` their names), ``inner_nodes``
    (nodes inside one element), ``terminations`` (unconnected ports), and the repeated
    sub-elements: ``families`` (parent path -> chains of identical siblings), ``alike``
    (sub-network -> its identical siblings), ``placeholders`` (placeholder path -> (parent, members,
    hidden members)) and ``hidden`` (primitive of a hidden member -> its placeholder).
    """

    def __init__(self, an: Analysis, types: dict | None):
        self.an = an
        self.flat = flat = an.flat
        self.types = dict(types or {})
        self.prims = flat.primitives
        self.node_of = {p: n for n in flat.nodes for p in n.ports}
        self.elements = list(dict.fromkeys(flat.element_of(p) for p in self.prims))
        self.out = orientation(an)
        self.values = flat.param_values()
        self.red = {e for d in an.errors for e in d.elements}
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

    def group_label(self, el):
        typ = self.types.get(el) or self.flat.elements.get(el) or self.prims.get(el, None)
        typ = typ.kind if hasattr(typ, "kind") else typ
        return f"{el} ({typ})" if typ else el
