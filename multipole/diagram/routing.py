"""Stage 4 of a block diagram: the wires.

:func:`route` gives every port variable of the flat network its :class:`~multipole.diagram.model.Arrow`:
which block computes it (from the :class:`~multipole.diagram.topology.Topology`'s orientation),
which receives it, and the orthogonal polyline between them through the tracks, gaps, corridors
and node points the :class:`~multipole.diagram.placement.Placement` reserved.  Wires that leave
one block side by side get their own slot or tap (a dot with several taps becomes a short bar,
so this stage may widen blocks), and each gyrator gets its two crossing links.  The result is a
:class:`Routing`.  Coordinates in drawing units.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

from .model import CONFLICT, CORRIDOR, DY, EFFORT, FLOW, Arrow
from .ordering import Ordering
from .placement import Placement
from .topology import Topology


@dataclass
class Routing:
    """``arrows``: one :class:`~multipole.diagram.model.Arrow` per port variable, with its route;
    ``links``: gyrator couplings as (points, colour, head) between a flow and an effort block."""

    arrows: list
    links: list


def route(topo: Topology, ordering: Ordering, placed: Placement) -> Routing:
    """The arrows of all port variables with their routes, and the gyrator links."""
    r = _Router(topo, ordering, placed)
    r.route()
    r.gyrator_links()
    return Routing(r.arrows, r.links)


class _Router:
    """The work of :func:`route`.  The legs and node points of the :class:`Placement` are copied
    (slots shift node points); the blocks are shared (taps may widen them)."""

    def __init__(self, topo: Topology, ordering: Ordering, placed: Placement):
        self.topo, self.ordering, self.placed = topo, ordering, placed
        self.blocks = placed.blocks
        self.legs = [dict(leg) for leg in placed.legs]
        self.node_pt = {name: dict(pts) for name, pts in placed.node_pt.items()}
        self.arrows: list = []
        self.links: list = []

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
        top_y = self.placed.top_base
        bottom_y = self.placed.y_row(self.ordering.n_lanes - 1, "e") - 0.85 - self.pad_max()
        self.assign_slots()
        self.assign_taps()
        multi = {}                          # (own, other, row) -> arrow standing for a collapsed run
        top_pairs = defaultdict(list)
        for pp in self.topo.flat.port_domains:
            prim = pp.rsplit(".", 1)[0]
            n = self.topo.node_of[pp]
            for row in ("f", "e"):
                v = f"{pp}.{row}"
                own = self.topo.block_id(prim, row)
                if prim in self.topo.hidden:     # inside a collapsed run: no wire of its own
                    self.arrows.append(Arrow(v, row, own, own, v in self.topo.out or pp in self.topo.out, EFFORT,
                                             head=False, drawn=False, hidden=True))
                    continue
                if n.origin == "termination":
                    other = f"{n.name}:x"
                elif len(n.ports) >= 3 and f"{n.name}:{row}" in self.blocks:   # its dot and Σ
                    other = f"{n.name}:{row}"
                else:
                    q = next(p for p in n.ports if p != pp)
                    other = self.topo.block_id(q.rsplit(".", 1)[0], row)
                inside = self.topo.out.get(v)
                src, dst = (own, other) if inside or inside is None else (other, own)
                colour = FLOW if row == "f" else EFFORT
                arrow = Arrow(v, row, src, dst, inside is not None, colour if inside is not None else CONFLICT)
                if n.name in self.topo.top_set:
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
                    elif key in self.placed.track:
                        pts = self.track_route(own, other, row, self.placed.track[key], key)
                    else:
                        a = self.pin(own, self.centre(other), row)
                        b = self.pin(other, self.centre(own), row)
                        pts = self.path_between(a, b, self.placed.y_row(self.lane_of_block(own), row))
                    arrow.points = pts if src == own else pts[::-1]
                    visible = [p for p in n.ports if p.rsplit(".", 1)[0] not in self.topo.hidden]
                    arrow.drawn = n.origin == "termination" or len(n.ports) != 2 or pp == visible[0]
                    if other.endswith(":x") and other[:-2] in self.topo.placeholders and arrow.drawn:
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

    def gyrator_links(self) -> None:
        """A gyrator ties the effort of each side to the flow of the other: two crossing links
        between its flow and effort blocks, pointing the way the analyser computes them."""
        arrows = {a.variable: a for a in self.arrows}
        for p, prim in self.topo.prims.items():
            if prim.kind != "GY" or p in self.topo.hidden:
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
                computed_f = self.topo.out.get(f"{p}.{port}.f")
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
        for el in self.topo.elements:
            for key, a, b in self.topo.connections(el):
                for row in ("f", "e"):
                    ids = [self.topo.block_id(x, row) if x in self.topo.prims or x in self.topo.hidden else
                           f"{x}:x" if x in self.topo.placeholders else f"{x}:{row}" for x in (a, b)]
                    if any(i not in self.blocks for i in ids):
                        continue
                    blk = [self.blocks[i] for i in ids]
                    tracked = key in self.placed.track
                    for k in (0, 1):
                        me, there = blk[k], blk[1 - k]
                        if me.row == "x" or me.bus or not (tracked or there.bus):
                            continue
                        level = self.placed.bus[there.owner][1] if there.bus else self.placed.track[key]
                        order_key = (there.x, -level if there.x > me.x else level)
                        legs[(me.id, row)].append((order_key, (key, ids[1 - k])))
        for leg in self.legs:
            if leg["track"] is not None:
                own = self.topo.block_id(leg["port"].rsplit(".", 1)[0], leg["row"])
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
        return max(self.placed.pad.values(), default=0.0)

    def track_route(self, own, other, row, k, key=None):
        """Route over inner track ``k``: out of the row away from the cross-couplings and back."""
        up = row == "f"
        a, b = self.blocks[own], self.blocks[other]
        yc = self.placed.y_row(self.lane_of_block(own), row) + (0.28 + 0.13 * k) * (1 if up else -1)

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
        return round(-(b.y - {"f": 0, "x": -DY, "e": -2 * DY}[b.row]) / self.placed.lane_h)

    def assign_slots(self):
        """Legs that leave the same row block on the same side run beside each other: the first
        (the one staying in its lane) on the row line, the others shifted toward their node (a box
        with three or more of them on one side grows taller so that every run enters its side)."""
        shared = defaultdict(list)

        def own_of(leg):
            return self.topo.block_id(leg["port"].rsplit(".", 1)[0], leg["row"])

        for leg in self.legs:
            own = own_of(leg)
            leg["slot"] = 0
            if self.blocks[own].row == "x" or leg["corridor"] is not None or leg["track"] is not None:
                continue
            nx_, ny = self.node_pt[leg["node"].name][leg["row"]]
            shared[(own, nx_ < self.blocks[own].x)].append(leg)
        for legs in shared.values():
            legs.sort(key=lambda lg: (lg["node"].name in self.placed.hop,
                                      abs(self.node_pt[lg["node"].name][lg["row"]][1]
                                          - self.placed.y_row(self.ordering.lane[lg["el"]], lg["row"]))))
            for k, leg in enumerate(legs):
                leg["slot"] = k
            b = self.blocks[own_of(legs[0])]
            if b.kind != "dot":             # every run enters the box's side: tall enough for all
                b.h = max(b.h, 2 * (0.11 * (len(legs) - 1) + 0.07))
        for leg in self.legs:
            n, row = leg["node"], leg["row"]
            row_y = self.placed.y_row(self.ordering.lane[leg["el"]], row)
            if len(n.ports) == 2:           # toward the partner's lane
                other = next(p for p in n.ports if p != leg["port"])
                ty = self.placed.y_row(self.ordering.lane[self.topo.flat.element_of(other)], row)
            else:
                ty = self.node_pt[n.name][row][1]
            leg["dir"] = 1 if ty > row_y + 1e-9 else -1
            if n.name in self.placed.hop:          # hopping wires leave outward, away from the rows
                leg["dir"] = 1 if row == "f" else -1
            if leg["slot"] and len(n.ports) == 2 and abs(self.node_pt[n.name][row][1] - row_y) < 1e-9:
                box = self.blocks[self.topo.block_id(leg["port"].rsplit(".", 1)[0], row)].kind != "dot"
                x, _ = self.node_pt[n.name][row]    # the invisible node point moves onto the shifted run
                self.node_pt[n.name][row] = (x, row_y + (0.11 if box else 0.2) * leg["slot"] * leg["dir"])

    def leg_route(self, leg, own, row, corridor, top_y, bottom_y):
        """Route from the node point of a connection between elements to the port's block."""
        n = leg["node"]
        nx_, ny = self.node_pt[n.name][row]
        row_y = self.placed.y_row(self.ordering.lane[leg["el"]], row)
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
            yc = top_y + CORRIDOR * k if up else bottom_y - CORRIDOR * k
            xv = self.placed.gap_x[("chan", leg["port"], row)]      # vertical beside the element
            y_run = row_y + (0.11 if box else 0.22) * (1 if up else -1)
            mid = [(nx_, yc), (xv, yc), (xv, y_run)]
            node_aim = (nx_, yc)
        elif n.name in self.placed.hop:           # around a node sitting on the row in this gap
            _g, node_lane = self.placed.node_gap[n.name]
            y_hop = ny
            y_run = row_y + (0.11 if box else 0.2) * leg["slot"] * leg["dir"]
            if self.ordering.lane[leg["el"]] == node_lane:
                c = self.ordering.col[leg["el"]]
                col_x, col_w = self.placed.col_x[c], self.placed.col_w[c]
                xv = col_x - 0.2 if leg["right"] is False else col_x + col_w + 0.2
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
