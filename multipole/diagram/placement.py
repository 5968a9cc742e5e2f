"""Stage 3 of a block diagram: where everything sits.

:func:`place` turns the grid of the :class:`~multipole.diagram.ordering.Ordering` and the sizes
of the :class:`~multipole.diagram.blocks.BlockSet` into coordinates.  First it reserves the room
wires need: the tracks inside each element (connections whose ends are not neighbours on the
rows, buses) and, for every connection between elements, the gap its node sits in, its tracks
there and the *legs* from the node to each port (with a return corridor above or below the lanes
where a leg has to run back against the chain).  Then it places the columns, the element frames,
the dashed frames of nested networks, every block, the bars of buses and the node points in the
gaps.  The result is a :class:`Placement`; the blocks now have positions.  Coordinates are in
drawing units, y up, the flow row of lane 0 at y = 0.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

from .blocks import BlockSet
from .model import DY, HANG, LANE, TRACK, Group
from .ordering import Ordering
from .topology import Topology


@dataclass
class Placement:
    """Positions of blocks, frames and nodes, and the tracks reserved for the wires.

    ``blocks``: the :class:`~multipole.diagram.blocks.BlockSet`'s blocks, now with ``x``/``y``
    (centre) and final sizes; ``groups``/``subgroups``: element frames and frames of nested
    networks; ``lane_h``: distance between lanes; ``top_base``: y of the first return corridor
    above the lanes; ``pad``: element -> extra margin its tracks need; ``col_x``/``col_w``: left
    edge and width of each column; ``gap_x``: track key in a gap -> its x; ``node_pt``: node
    joining elements -> {row: (x, y) of its node point}; ``node_gap``: node -> (gap, lane);
    ``hop``: two-port nodes whose wires hop over a multi-port node in the same gap; ``legs``: one
    dict per (port of a node joining elements, row) with keys ``node``, ``port``, ``row``, ``el``,
    ``right`` (the node lies right of the element), ``corridor`` (``None`` or (``"top"`` or
    ``"bottom"``, gap)), ``track`` (inner track level or ``None``); ``track``: connection inside
    an element -> its track level; ``bus``: bus junction -> (element, track level, side of its
    external port or ``None``).  Lengths in drawing units.
    """

    blocks: dict
    groups: list
    subgroups: list
    lane_h: float
    top_base: float
    pad: dict
    col_x: list
    col_w: list
    gap_x: dict
    node_pt: dict
    node_gap: dict
    hop: set
    legs: list
    track: dict
    bus: dict

    def y_row(self, lane, row):
        """y of row ``row`` (``"f"``, ``"x"`` or ``"e"``) in lane ``lane``."""
        return row_y(lane, row, self.lane_h)


def row_y(lane, row, lane_h):
    """y of row ``row`` (``"f"``, ``"x"`` or ``"e"``) in lane ``lane`` when lanes are ``lane_h`` apart."""
    y0 = -lane * lane_h
    return {"f": y0, "x": y0 - DY, "e": y0 - 2 * DY}[row]


def place(topo: Topology, ordering: Ordering, blockset: BlockSet) -> Placement:
    """Reserve the tracks, then place columns, frames, blocks and node points."""
    p = _Placer(topo, ordering, blockset)
    for el in topo.elements:
        order, _hang, _xs = p.items[el]
        p.inner_tracks(el, order, ordering.buses[el])
    p.col_w = [max([p.widths[e] for e in topo.elements if ordering.col[e] == c] or [1.0])
               for c in range(ordering.n_cols)]
    p.plan_wires()
    p.pad = {el: 0.13 * max(0, n - 1) for el, n in p.n_tracks.items()}
    p.sub_strip = {el: 0.22 if any(topo.subnet(it) != el for it in p.items[el][0]
                                   if it in topo.prims) else 0.0 for el in topo.elements}
    extra = max((p.pad[el] + p.sub_strip[el] for el in topo.elements), default=0.0)
    p.lane_h = LANE + 2 * extra
    p.top_base = 0.8 + extra + 0.55
    p.place()
    return Placement(p.blocks, p.groups, p.subgroups, p.lane_h, p.top_base, p.pad, p.col_x, p.col_w, p.gap_x,
                     p.node_pt, p.node_gap, p.hop, p.legs, p.track, p.bus)


class _Placer:
    """The work of :func:`place`; the state it builds up becomes the :class:`Placement`."""

    def __init__(self, topo: Topology, ordering: Ordering, blockset: BlockSet):
        self.topo, self.ordering = topo, ordering
        self.blocks, self.items, self.widths = blockset.blocks, blockset.items, blockset.widths
        self.track: dict = {}               # connection -> inner track index (outside the rows)
        self.n_tracks: dict = {}            # element -> number of inner tracks
        self.levels: dict = {}              # element -> [(first item, last item, track level)]
        self.bus: dict = {}                 # junction drawn as a bus -> (element, level, side)

    def y_row(self, lane, row):
        return row_y(lane, row, self.lane_h)

    def inner_tracks(self, el, order, buses):
        """Connections inside an element whose ends are not neighbours on the rows run over a
        track outside the rows (above the flows, below the efforts).  Shorter connections get the
        inner tracks and connections that do not overlap share one, so nested spans never
        cross; a bus gets one track for all its connections."""
        pos = {it: k for k, it in enumerate(order)}
        rows_at = [pos[it] for it in order if f"{it}:f" in self.blocks]
        spans, seen = [], {}
        for key, a, b in self.topo.connections(el):
            if a in buses or b in buses:
                continue
            if a not in pos or b not in pos or a == b:
                continue            # hanging under a junction: a short vertical wire
            lo, hi = sorted((pos[a], pos[b]))
            if not any(lo < k < hi for k in rows_at):
                continue
            pair = (lo, hi)
            if pair in seen and (a in self.topo.placeholders or b in self.topo.placeholders):
                self.track[key] = seen[pair]          # the same wire: one drawn for the run
                continue
            seen[pair] = key
            spans.append((lo, hi, key))
        ends = {}
        for j in buses:
            its = [b if a == j else a for _k, a, b in self.topo.connections(el) if j in (a, b)]
            idx = [pos[i] for i in its if i in pos]
            side = None
            for k, pp in self.topo.flat.external_ports.items():
                if pp.rsplit(".", 1)[0] == j:
                    side = "left" if j in self.ordering.entries.get(el, ()) else "right"
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
        """A track for a leg whose port block (on the rows, or a cross-coupling drawn as an item of
        its own) has row blocks between it and the element's edge toward the leg (the leg then runs
        outside the rows instead of through them)."""
        order = self.items[el][0]
        on_rows = [it for it in order if f"{it}:f" in self.blocks]
        if prim not in order:           # hanging under a junction: its wire comes through the host
            return None
        pos = order.index(prim)
        if not any(order.index(it) > pos if right else order.index(it) < pos for it in on_rows if it != prim):
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

    def plan_wires(self):
        """Decide for every connection between elements where its node sits (the gap after the
        element it was reached from) and which legs need a return corridor."""
        self.gap_tracks = defaultdict(list)      # gap -> list of track keys
        self.node_gap, self.legs = {}, []
        for n in self.topo.top_nodes:
            parent = self.ordering.node_parent.get(n.name, self.topo.flat.element_of(n.ports[0]))
            g = self.ordering.node_gap_at.get(n.name, self.ordering.col[parent])
            self.node_gap[n.name] = (g, self.ordering.lane[parent])
        for n in self.topo.top_nodes:
            g, lane = self.node_gap[n.name]
            stagger = False
            for p in n.ports:
                el = self.topo.flat.element_of(p)
                c = self.ordering.col[el]
                right = g >= c
                adjacent = (right and g == c) or (not right and g == c - 1)
                for row in ("f", "e"):
                    leg = {"node": n, "port": p, "row": row, "el": el, "right": right, "corridor": None,
                           "track": self.blocked_track(el, p.rsplit(".", 1)[0], right) if adjacent else None}
                    if not adjacent:
                        chan_gap = c if right else c - 1
                        top = row == "f" and lane == 0 and self.ordering.lane[el] == 0
                        leg["corridor"] = ("top" if top else "bottom", chan_gap)
                        self.gap_tracks[chan_gap].append(("chan", p, row))
                        stagger = True
                    elif self.ordering.lane[el] != lane:
                        stagger = True
                    self.legs.append(leg)
            keys = [("node", n.name, "f"), ("node", n.name, "e")] if stagger else [("node", n.name, "fe")]
            self.gap_tracks[g][:0] = keys

    def place(self):
        # columns
        self.col_x, x = [], 0.0
        self.gap_x = {}
        for c in range(self.ordering.n_cols):
            self.col_x.append(x)
            x += self.col_w[c]
            tracks = self.gap_tracks.get(c, [])
            width = max(0.9, 0.45 + TRACK * len(tracks) + 0.2)
            for k, key in enumerate(tracks):
                self.gap_x[key] = x + 0.4 + TRACK * k
            x += width
        # element groups and blocks inside
        self.groups, self.subgroups = [], []
        for el in self.topo.elements:
            order, hang, xs = self.items[el]
            x0, lane = self.col_x[self.ordering.col[el]], self.ordering.lane[el]
            yf, ye = self.y_row(lane, "f"), self.y_row(lane, "e")
            pad = self.pad[el]
            self.groups.append(Group(el, self.topo.group_label(el), x0, ye - 0.5 - pad - self.sub_strip[el],
                                     x0 + self.widths[el], yf + 0.8 + pad, el in self.topo.red))
            # sub-frames reach below the element's tracks: their labels sit in a strip no wire uses
            n_tr = self.n_tracks.get(el, 0)
            sub_y0 = ye - (0.28 + 0.13 * (n_tr - 1) + 0.06 if n_tr else 0.22) - 0.24
            run = []                       # consecutive items of one nested network: a sub-frame
            for it in order + [None]:
                net = self.topo.subnet(it) if it is not None and it not in self.topo.placeholders else None
                if run and net != run[0][0]:
                    sub = run[0][0]
                    if sub is not None and sub != el and sub.startswith(el + "."):
                        left, right = xs[run[0][1]][0], sum(xs[run[-1][1]])
                        self.subgroups.append(Group(sub, f"{sub[len(el) + 1:]} ({self.topo.flat.elements[sub]})",
                                                    x0 + left + 0.05, sub_y0, x0 + right - 0.05, yf + 0.42,
                                                    el in self.topo.red))
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
                widths = [max(HANG, self.blocks[f"{h}:x"].w + 0.2) for h in hs]
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
        for n in self.topo.top_nodes:
            sharing[self.node_gap[n.name]].append(n)
        shift, self.hop = {}, set()
        for (_g, lane), group in sharing.items():
            multi = [n for n in group if len(n.ports) >= 3]
            for j, n in enumerate(multi[1:], 1):    # a second node on the row would sit in the way
                shift[n.name] = 0.7 * j
            if multi:                               # straight wires hop over the node's blocks
                self.hop |= {n.name for n in group if len(n.ports) == 2}
        for n in self.topo.top_nodes:
            g, lane = self.node_gap[n.name]
            xf = self.gap_x.get(("node", n.name, "f"), self.gap_x.get(("node", n.name, "fe")))
            xe = self.gap_x.get(("node", n.name, "e"), xf)
            dy = shift.get(n.name, 0.34 if n.name in self.hop else 0.0)    # outward: above flows, below efforts
            self.node_pt[n.name] = {"f": (xf, self.y_row(lane, "f") + dy), "e": (xe, self.y_row(lane, "e") - dy)}
            if len(n.ports) >= 3:               # its dot and Σ (made with the other blocks)
                for row in ("f", "e"):
                    b = self.blocks[f"{n.name}:{row}"]
                    b.x, b.y = self.node_pt[n.name][row]

    def place_bus(self, j, el, level, side, x0, yf, ye):
        """Bars of a bus junction: over the flows and under the efforts at its track level, from
        its first to its last connected item and, for a port of the element, on to that edge."""
        xs = []
        for _key, a, b in self.topo.connections(el):
            if j in (a, b):
                other = b if a == j else a
                xs.append(self.blocks[self.topo.block_id(other, "f") if other in self.topo.prims else f"{other}:x"
                                      if other in self.topo.placeholders else f"{other}:f"].x)
        lo, hi = min(xs) - 0.3, max(xs) + 0.3
        if side == "left":
            lo = x0 + 0.12
        elif side == "right":
            hi = x0 + self.widths[el] - 0.12
        off = 0.28 + 0.13 * level
        for row, y in (("f", yf + off), ("e", ye - off)):
            b = self.blocks[f"{j}:{row}"]
            b.x, b.y, b.w, b.h = (lo + hi) / 2, y, hi - lo, 0.0 if b.kind == "dot" else 0.1
