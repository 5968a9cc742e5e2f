"""Stage 1 of a block diagram: the order of things.

:func:`order` decides, from the :class:`~multipole.diagram.topology.Topology` alone, the column
and lane of every top-level element (the chain of connections runs left to right, parallel paths
stack in lanes, terminals sit beside the element they act on), the order of the items inside
each element (primitives on the rows, inner nodes, cross-couplings, terminals, placeholders of
collapsed repeats), which cross-couplings hang under a junction, and which junctions are drawn
as a bus outside the rows.  The result is an :class:`Ordering`; it holds no geometry.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import sympy as sp

from .topology import Topology


@dataclass
class Ordering:
    """Where each element goes, as grid cells, and the order inside each element.

    ``col``/``lane``: top-level element -> column and lane index (0-based, columns left to right,
    lanes top to bottom); ``n_cols``, ``n_lanes`` their counts.  ``node_parent``: node joining
    elements -> the element it sits after; ``node_gap_at``: node -> gap index forced when a
    terminal was placed below its host.  ``items``: element -> its drawn items on the rows, left to
    right (buses left out); ``hang``: element -> {host item: cross-couplings hanging under it};
    ``buses``: element -> junctions drawn as a bus; ``entries``: element -> items whose ports
    face left.
    """

    col: dict
    lane: dict
    n_cols: int
    n_lanes: int
    node_parent: dict
    node_gap_at: dict
    items: dict
    hang: dict
    buses: dict
    entries: dict


def order(topo: Topology) -> Ordering:
    """Columns and lanes of the elements and the order of the items inside each element."""
    o = _Orderer(topo)
    o.order_elements()
    items, hang, buses = {}, {}, {}
    for el in topo.elements:
        its, hangs = o.element_items(el)
        bus = o.find_buses(el, its, hangs)
        items[el] = [it for it in its if it not in bus]
        hang[el], buses[el] = hangs, bus
    return Ordering(o.col, o.lane, o.n_cols, o.n_lanes, o.node_parent, o.node_gap_at, items, hang, buses,
                    dict(o.entries))


class _Orderer:
    """The work of :func:`order`; the state it builds up becomes the :class:`Ordering`."""

    def __init__(self, topo: Topology):
        self.topo = topo
        self._items_cache: dict = {}
        self.entries: dict = {}             # element -> items whose ports face left

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
        flat = self.topo.flat
        nodes_of = defaultdict(list)
        for n in self.topo.top_nodes:
            for p in n.ports:
                el = flat.element_of(p)
                if n not in nodes_of[el]:
                    nodes_of[el].append(n)
        self.nodes_of = nodes_of
        self.col, self.lane, self.parent_node, self.node_parent = {}, {}, {}, {}
        self.node_gap_at = {}               # node -> gap index chosen when its terminal was placed
        cells = {}
        terminal = {el: len(nodes_of[el]) <= 1 for el in self.topo.elements}
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
            for path, prim in self.topo.prims.items():
                if flat.element_of(path) == el and prim.kind in ("Se", "Sf"):
                    return not driving or sp.sympify(prim.params["value"]).is_zero is not True
            return False

        named = [flat.element_of(p) for n in self.topo.top_nodes for p in n.ports]
        pending = ([e for e in dict.fromkeys(named) if is_source(e, False)]
                   + [e for e in self.topo.elements if is_source(e, True)] + self.topo.elements)
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
        flat = self.topo.flat
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
        return {self.topo.flat.element_of(p) for n in self.nodes_of.get(el, []) for p in n.ports} - {el}


    def item_of_port(self, el, port_path):
        """The drawn item that carries ``port_path`` of element ``el``."""
        prim = port_path.rsplit(".", 1)[0]
        if prim in self.topo.hidden:
            return self.topo.hidden[prim]
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
        flat = self.topo.flat
        prims = [p for p in self.topo.prims if flat.element_of(p) == el and p not in self.topo.hidden]
        hang = defaultdict(list)           # host item -> middle primitives below it
        host_of = {}
        for p in prims:
            prim = self.topo.prims[p]
            if not self.topo.is_middle(p) or len(prim.ports) != 1:
                continue
            n = self.topo.node_of.get(f"{p}.p")
            if n is None or n.name in self.topo.top_set or n.origin == "termination":
                continue
            others = [q for q in n.ports if q != f"{p}.p"]
            if len(others) >= 2:
                host_of[p] = n.name
            else:
                q = others[0].rsplit(".", 1)[0]
                if not self.topo.is_middle(q) and q not in self.topo.hidden:
                    host_of[p] = q
            if p in host_of:
                hang[host_of[p]].append(p)
        inner = [n for n in self.topo.inner_nodes if flat.element_of(n.ports[0]) == el and len(n.ports) >= 3
                 and not all(q.rsplit(".", 1)[0] in self.topo.hidden for q in n.ports)]
        phs = [ph for ph in self.topo.placeholders if flat.element_of(ph) == el]
        items = [p for p in prims if p not in host_of] + [n.name for n in inner] + phs
        term_of = defaultdict(list)
        for n in self.topo.terminations:
            prim = n.ports[0].rsplit(".", 1)[0]
            if flat.element_of(prim) == el and prim not in self.topo.hidden:
                term_of[prim].append(n.name)
        item_of = {p: host_of.get(p, p) for p in prims}
        item_of.update(self.topo.hidden)
        inner_names = {n.name for n in inner}
        adj = defaultdict(list)
        for n in self.topo.inner_nodes:
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
            n = self.topo.node_of.get(pp)
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
            if it in self.topo.prims:
                return {d.name for d in self.topo.prims[it].ports.values()}
            if it in self.topo.node_by_name:
                return {self.topo.node_by_name[it].domain.name}
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
                here, dom = self.topo.subnet(x), domains(x)
                nbs = sorted((nb for nb in adj[x] if nb not in seen and nb in allowed),
                             key=lambda nb: (leads_on(nb, x), not domains(nb) <= dom, dist.get(nb) == 0,
                                             -dist.get(nb, 0), self.topo.subnet(nb) != here,
                                             nb in self.topo.prims and self.topo.is_middle(nb), rank.get(nb, 0)))
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
            return [ph for ph, (_p, _s, gone) in self.topo.placeholders.items() if m in gone]

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
            if it in self.topo.placeholders:
                return self.topo.placeholders[it][0] if self.topo.placeholders[it][0] != el else it
            sub = self.topo.subnet(it)
            if sub == el or not sub.startswith(el + "."):
                return None
            return ".".join(sub.split(".")[:2])

        family_of, ph_of = {}, {}
        for fam in self.topo.families.get(el, []):
            for sub in fam:
                family_of[sub] = fam
        for ph, (parent, subs, gone) in self.topo.placeholders.items():
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
                if ph is not None and sub in self.topo.placeholders[ph][2]:
                    if ph not in done:
                        done.add(ph)
                        out.append(ph)
                    continue
                its = members.get(sub, [])
                alike = tuple(self.topo.alike.get(sub, [sub]))
                if len(alike) > 1:
                    if alike not in template:
                        m, its_m = self.chain_template(group, members, adj)
                        template[alike] = [rel(x, m) for x in its_m]
                    pos = {r: k for k, r in enumerate(template[alike])}
                    its = sorted(its, key=lambda x: pos.get(rel(x, sub), len(pos)))
                out += its
        return out


    def find_buses(self, el, order, hang):
        """Junctions (and nodes) on the rows joined to three or more items that are not their
        neighbours: drawn as a bus outside the rows instead of one track per connection."""
        pos = {it: k for k, it in enumerate(order)}
        rows_at = [pos[it] for it in order if it not in self.topo.placeholders
                   and (it in self.topo.node_by_name or (it in self.topo.prims and not self.topo.is_middle(it)))]
        far = defaultdict(set)
        for _key, a, b in self.topo.connections(el):
            if a not in pos or b not in pos or a == b:
                continue
            lo, hi = sorted((pos[a], pos[b]))
            if any(lo < k < hi for k in rows_at):
                far[a].add(b)
                far[b].add(a)
        buses = []
        for it, others in far.items():
            junction = (it in self.topo.prims and self.topo.prims[it].kind.startswith("junction_")) or \
                (it in self.topo.node_by_name and self.topo.node_by_name[it].origin != "termination")
            if junction and len(others) >= 3 and not hang.get(it) and it not in self.topo.placeholders:
                buses.append(it)
        return buses
