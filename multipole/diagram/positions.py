"""Stage 6 of a block diagram: position closures and the position signals of modulated transformers.

Elements that hand positions through their connections (planar linkages, bands) hold *displacement
states* (a link angle, a travel) that modulate their transformers, and *position closures*
(:class:`multipole.network.Closure`): residuals the equations stage solves, by the element's formula or by Newton's method, for
some of those states at every evaluation.  This stage draws

* one **closure block** per closure above the lanes ("position closure", with the states it solves
  for), and
* a **position signal** (green, dash-dotted, with a head at the receiving block) for every value a
  block needs that is neither a flow nor an effort: each displacement state a closure's residuals
  read (from the block that integrates it, or from the closure that solves it), and each state a
  modulated transformer's ratio reads that it does not integrate itself (from the closure that
  solves it, or from the block that integrates it).

A transformer modulated only by its own integrated state needs no wire (its block says ``K(q)``).
Signals run up from their source to a horizontal track of their own above the diagram, along it and
down into their target (beside the element, in the gap right of its column, for a block below the
first lane); the signals leaving one closure share its track.  Nothing here changes the
port-variable arrows.  Coordinates in drawing units.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

import sympy as sp

from .blocks import _text_width
from .model import Block
from .ordering import Ordering
from .placement import Placement
from .topology import Topology

#: spacing of the horizontal tracks of position signals above the diagram [drawing units]
SIGNAL_TRACK = 0.22


@dataclass
class Signal:
    """A position signal: ``states`` (full state names) sent from block ``source`` to block
    ``target``; ``points`` is the drawn route from source to target, ``branch`` the point where it
    leaves a track it shares with other signals of the same source (``None`` if it does not)."""

    source: str
    target: str
    states: list
    points: list = field(default_factory=list)
    branch: tuple | None = None


@dataclass
class Closure:
    """A drawn position closure: its block id, the element that owns it, the states it solves
    for (``unknowns``, full names), the states its residuals read from elsewhere (``reads``), and
    whether a formula solves it (``formula``, :class:`multipole.network.ClosedForm`) or Newton's method."""

    block: str
    owner: str
    unknowns: list
    reads: list
    formula: bool = False


def _short(name: str, owner: str) -> str:
    """A state name relative to the element that owns the closure."""
    return name[len(owner) + 1:] if owner and name.startswith(owner + ".") else name


def positions(topo: Topology, ordering: Ordering, placed: Placement, top: float):
    """The closure blocks (added to the placement's blocks), the :class:`Closure` records and the
    routed :class:`Signal` list.  ``top`` is the highest y of the diagram drawn so far; everything
    here goes above it.  A wire to or from a block below the first lane rises beside its element,
    in the gap right of its column, not through the lanes above; one that would cross its frame's
    label moves right of it first."""
    blocks = placed.blocks
    flat = topo.flat
    closed = {}                                   # state symbol -> closure index
    for k, (states, _res, _owner) in enumerate(flat.closures):
        for s in states:
            closed[s] = k
    owner_of = {s.symbol: s.owner for s in flat.states}

    def block_of_state(sym):              # every state belongs to a primitive (flatten makes them)
        return f"closure:{closed[sym]}" if sym in closed else topo.block_id(owner_of[sym], "f")

    wanted = defaultdict(list)                    # (source block, target block) -> states
    records = []
    for k, (states, residuals, owner) in enumerate(flat.closures):
        bid = f"closure:{k}"
        reads = sorted({v for r in residuals for v in sp.sympify(r).free_symbols
                        if v in owner_of and v not in states}, key=lambda v: v.name)
        for v in reads:
            wanted[(block_of_state(v), bid)].append(v.name)
        records.append(Closure(bid, owner, [s.name for s in states], [v.name for v in reads], k in flat.closed_forms))
    for path, prim in topo.prims.items():
        if prim.kind in ("I", "C", "CField", "Tap") or path in topo.hidden:
            continue                             # storages read their own states only
        used = set()
        for eq in flat.equations:
            if eq.owner == path:
                used |= eq.expr.free_symbols & owner_of.keys()
        for v in sorted(used, key=lambda v: v.name):
            if v not in closed and owner_of[v] == path:
                continue                         # its own integrated state: the K(q) of its block
            src = block_of_state(v)
            target = topo.block_id(path, "f")
            if src != target:
                wanted[(src, target)].append(v.name)
    if not records and not wanted:
        return [], []
    for rec in records:
        text = ", ".join(_short(u, rec.owner) for u in rec.unknowns)
        label = f"position closure ({rec.owner})"
        note = f"formula for {text}" if rec.formula else f"Newton on {text}"
        w = max(_text_width(label, 9), _text_width(note, 7.5)) + 0.3
        el = rec.owner.split(".")[0] if rec.owner != "<root>" else ""
        blocks[rec.block] = Block(rec.block, "closure", label, "p", rec.owner, el, note, w=w, h=0.58,
                                  conflict=el in topo.red)
    frames = {g.element: g for g in placed.groups}

    def riser(b, k, x):
        el = b.element
        if el not in ordering.lane:
            return None
        if ordering.lane[el] == 0:            # nothing above the lane's top row but the tracks ...
            g = frames[el]
            label_end = g.x0 + 0.16 + _text_width(g.label, 9) * 1.15 + 0.12
            if x > label_end:
                return None
            return label_end + 0.07 * (k % 4), b.y + b.h / 2 + 0.3    # ... and the frame's label
        c = ordering.col[el]
        return placed.col_x[c] + placed.col_w[c] + 0.12 + 0.07 * (k % 4), b.y + b.h / 2 + 0.3

    return records, _route(blocks, records, wanted, top, riser)


def _route(blocks, records, wanted, top, riser):
    """Place the closure blocks above the tracks and route every signal over its own track.
    ``riser(block, k, x)``: ``None`` for a block whose wire may go straight up at ``x`` (nothing
    drawn above it), else the x of the k-th vertical wire beside its element (in the gap right of
    its column, or right of its frame's label) and the height at which a wire leaves the block's
    top to reach it."""
    by_source = defaultdict(list)
    for (src, dst), states in wanted.items():
        by_source[src].append((dst, states))
    sources = sorted(by_source, key=lambda s: (not s.startswith("closure:"), blocks[s].x if s in blocks and
                                               not s.startswith("closure:") else 0.0, s))
    # a track per closure (its outputs share it) and one per other source
    track = {s: top + 0.45 + SIGNAL_TRACK * k for k, s in enumerate(sources)}
    yc = top + 0.45 + SIGNAL_TRACK * max(len(sources), 1) + 0.55
    # closures: centred over what they feed, pushed apart where they would overlap
    placed = []
    for rec in records:
        b = blocks[rec.block]
        xs = [blocks[d].x for d, _s in by_source.get(rec.block, []) if not d.startswith("closure:")]
        xs = xs or [blocks[s].x for (s, d) in wanted if d == rec.block and not s.startswith("closure:")] or [0.0]
        b.x, b.y = sum(xs) / len(xs), yc
        placed.append(b)
    placed.sort(key=lambda b: b.x)
    for left, right in zip(placed, placed[1:]):
        gap = left.w / 2 + right.w / 2 + 0.4
        if right.x - left.x < gap:
            right.x = left.x + gap
    # inputs of a closure enter its bottom edge side by side
    entries = defaultdict(list)
    for (src, dst) in sorted(wanted, key=lambda k: blocks[k[0]].x if not k[0].startswith("closure:") else 0):
        if dst.startswith("closure:"):
            entries[dst].append(src)
    risers = {}                               # block id -> its riser (x, y), one per block

    def leg(bid, y):
        """From the top of block ``bid`` (not a closure) up to the track at ``y``: points bottom-up."""
        b = blocks[bid]
        x = b.x + b.w / 2 - 0.06
        if bid not in risers:
            risers[bid] = riser(b, len(risers), x)
        r = risers[bid]
        if r is None:
            return [(x, b.y + b.h / 2), (x, y)]
        rx, ry = r
        return [(x, b.y + b.h / 2), (x, ry), (rx, ry), (rx, y)]

    signals = []
    for src in sources:
        sb = blocks[src]
        y = track[src]
        outs = sorted(by_source[src], key=lambda d: blocks[d[0]].x)
        shared = len(outs) > 1
        head = [(sb.x, sb.y - sb.h / 2), (sb.x, y)] if src.startswith("closure:") else leg(src, y)
        for dst, states in outs:
            db = blocks[dst]
            if dst.startswith("closure:"):
                ins = entries[dst]
                ex = db.x - db.w / 2 + db.w * (ins.index(src) + 1) / (len(ins) + 1)
                tail = [(ex, y), (ex, db.y - db.h / 2)]
            else:
                tail = leg(dst, y)[::-1]
            pts = [p for k, p in enumerate(head + tail) if k == 0 or p != (head + tail)[k - 1]]
            signals.append(Signal(src, dst, list(states), pts, tail[0] if shared else None))
    return signals
