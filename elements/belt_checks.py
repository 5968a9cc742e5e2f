"""Static checks of band and rope scenes (registered with ``multipole.register_check``; run by ``check``).

* ``belt_loop`` (info): a closed loop of band connections (spans and rolls, each joined at its two
  band ports) with its belt length, the free lengths of its spans against their span lengths and
  the mean pretension.  The belt length is the loop's invariant: the rolls hand the wound length
  from one span to the next, so the spans' free lengths add to the same sum at every instant.
* ``belt_loop_slack`` (warning): the free lengths of a loop's spans add to at least their span
  lengths: the belt is too long to be taut anywhere at rest.
* ``capstan_at_rest`` (warning): a roll with a contact friction ``mu_c`` whose spans' pretensions
  already exceed the capstan limit e^(mu_c*wrap) at t = 0 (the run-time monitor ``capstan_limit``
  reports only a crossing during the run).

Values are read from the scene's element parameters (numbers or formulas of the scene parameters);
a loop whose lengths are not numbers, or that contains elements other than ``band`` spans and
``band_roll`` rolls (a ``belt_pulley``, planar spans), is listed without them; ``capstan_at_rest``
passes over a roll whose spans' pretensions are not numbers.
"""
from __future__ import annotations

import math

import networkx as nx
import sympy as sp

from multipole import Diagnostic, register_check

SPANS = ("band",)          # span kinds with the parameters l, l0 (None: l), EA
ROLLS = ("band_roll",)     # circular rolls with r and wrap


def band_graph(ctx) -> nx.Graph:
    """Elements joined by band connections: an edge per connection, labelled with both ports."""
    owner = {prim: ext.rsplit(".", 1)[0] for ext, prim in ctx.flat.external_ports.items() if ext.endswith(".l")
             and ctx.flat.bundles.get(ext.rsplit(".", 1)[0]) == "band"}
    g = nx.Graph()
    for node in ctx.flat.nodes:
        ends = [owner[p] for p in node.ports if p in owner]
        if node.origin == "connection" and len(ends) == 2:
            (a, pa), (b, pb) = (e.rsplit(".", 1) for e in ends)
            g.add_edge(a, b, ports=(f"{a}.{pa}", f"{b}.{pb}"))
    return g


def _value(ctx, element: str, name: str):
    """The number a parameter of a top-level element stands for, or None (not a number, no scene)."""
    if ctx.scene is None or element not in ctx.scene.network.children:
        return None
    expr = ctx.scene.network.children[element].params.get(name)
    if expr is None:
        return None
    scene = {sp.Symbol(k): v for k, v in ctx.scene.network.params.items()}
    try:
        value = float(sp.sympify(expr).xreplace(scene))
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _span(ctx, el):
    """(l, l0, EA) of a span (l0 not given: l), or None."""
    if ctx.scene is None or el not in ctx.scene.network.children:
        return None
    l, l0, EA = (_value(ctx, el, n) for n in ("l", "l0", "EA"))
    if l0 is None and ctx.scene.network.children[el].params.get("l0") is None:
        l0 = l
    return None if None in (l, l0, EA) else (l, l0, EA)


def loops(ctx) -> list:
    """The closed loops: lists of elements in the order the band runs through them."""
    g = band_graph(ctx)
    out = []
    for comp in nx.connected_components(g):
        sub = g.subgraph(comp)
        if len(comp) >= 2 and all(d == 2 for _, d in sub.degree()):
            out.append([e for e, _ in nx.find_cycle(sub, source=min(comp))] if len(comp) > 2 else sorted(comp))
    return out


def _loop_lengths(ctx, loop):
    """(free lengths, span lengths, belt length, mean pretension) of a loop, or None."""
    kinds = ctx.flat.elements
    spans = [e for e in loop if kinds.get(e) in SPANS]
    if not spans or any(kinds.get(e) not in SPANS + ROLLS for e in loop):
        return None
    data = [_span(ctx, e) for e in spans]
    arcs = [(_value(ctx, e, "r"), _value(ctx, e, "wrap")) for e in loop if kinds.get(e) in ROLLS]
    if None in data or any(None in a for a in arcs):
        return None
    free, length = sum(d[1] for d in data), sum(d[0] for d in data)
    EA = sum(d[2] for d in data) / len(data)
    return free, length, free + sum(r * w for r, w in arcs), EA * (length - free) / free


@register_check("belt_loop", "info",
                "a closed loop of band connections (a belt): its spans and rolls in order, the belt length (free "
                "lengths plus wrapped arcs: the loop's invariant), the free lengths against the span lengths and "
                "the mean pretension")
def belt_loop(ctx):
    for loop in loops(ctx):
        lengths = _loop_lengths(ctx, loop)
        text = f"closed belt {' -> '.join(loop)} -> {loop[0]}"
        if lengths:
            free, length, belt, F0 = lengths
            text += (f": belt length {belt:.6g} m (free lengths {free:.6g} m + wrapped arcs; kept constant), "
                     f"span lengths {length:.6g} m, mean pretension {F0:.4g} N")
        yield Diagnostic("belt_loop", text, elements=loop)


@register_check("belt_loop_slack", "warning",
                "the free lengths of a closed belt's spans add to at least their span lengths: the belt is too long "
                "to be taut anywhere at rest")
def belt_loop_slack(ctx):
    for loop in loops(ctx):
        lengths = _loop_lengths(ctx, loop)
        if lengths and lengths[0] >= lengths[1]:
            free, length = lengths[:2]
            yield Diagnostic("belt_loop_slack",
                             f"closed belt {' -> '.join(loop)}: its spans' free lengths add to {free:.6g} m, at least "
                             f"their span lengths {length:.6g} m: no span can be taut at t = 0 (the belt is too long)",
                             elements=loop,
                             fix="shorten the free lengths l0 (pretension: l0 < l) or lengthen the spans")


def _tension_at_rest(ctx, span):
    data = _span(ctx, span) if ctx.flat.elements.get(span) in SPANS else None
    return None if data is None else max(0.0, data[2] * (data[0] - data[1]) / data[1])


@register_check("capstan_at_rest", "warning",
                "a roll with a contact friction mu_c whose spans' pretensions exceed the capstan limit "
                "e^(mu_c*wrap) at t = 0: a real band would slip from the start")
def capstan_at_rest(ctx):
    g = band_graph(ctx)
    for roll, kind in ctx.flat.elements.items():
        mu_c, wrap = _value(ctx, roll, "mu_c"), _value(ctx, roll, "wrap")
        if kind not in ROLLS or mu_c is None or wrap is None or roll not in g:
            continue
        tension = {}
        for other in g[roll]:
            ports = g[roll][other]["ports"]
            mine = ports[0] if ports[0].startswith(roll + ".") else ports[1]
            tension[mine.rsplit(".", 1)[1]] = _tension_at_rest(ctx, other)
        F1, F2 = tension.get("e1", 0.0), tension.get("e2", 0.0)
        if F1 is None or F2 is None or max(F1, F2) == 0:
            continue
        limit = math.exp(mu_c * wrap)
        if max(F1, F2) > limit * min(F1, F2):
            ratio = "infinite" if min(F1, F2) == 0 else f"{max(F1, F2) / min(F1, F2):.4g}"
            yield Diagnostic("capstan_at_rest",
                             f"{roll}: the pretensions at its band ports, {F1:.4g} N at e1 and {F2:.4g} N at e2 "
                             f"(ratio {ratio}), exceed the capstan limit e^(mu_c*wrap) = {limit:.4g} at t = 0: "
                             "a real band would slip from the start", elements=[roll],
                             fix="pretension both spans alike, or raise the wrap or mu_c")
