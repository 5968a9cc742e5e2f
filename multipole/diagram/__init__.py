"""Weber-style block diagrams of a scene (``multipole diagram FILE -o figure.png|svg|pdf``).

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
* **position closures** (planar linkages, bands) as green blocks above the lanes ("position
  closure: formula for" or "Newton on" the states they solve for), with green dash-dotted **position signals** from
  the states they read and to the transformers whose ratios their states modulate;
* the elements named in **error diagnostics** drawn in red, with the diagnostic's words below.

Two steps, both public: :func:`layout` turns an :class:`~multipole.causality.Analysis` into a
:class:`Diagram` (blocks with kind/label/row/position, arrows with source/target/colour/route)
and :func:`render` draws it with matplotlib (Agg).  Tests assert on the :class:`Diagram`.

:func:`layout` runs the stages in order, each a module that reads only the results of the
stages before it:

1. :mod:`.topology`: the analysed scene as the diagram sees it (nodes between and inside
   elements, which side computes each port variable, collapsed repeats);
2. :mod:`.ordering`: columns and lanes of the elements, the order of the items inside each;
3. :mod:`.blocks`: the block of every item with its label and size, footnotes;
4. :mod:`.placement`: tracks reserved for wires, then positions of frames, blocks and nodes;
5. :mod:`.routing`: one arrow per port variable with its route, gyrator links;
6. :mod:`.positions`: position closures and the position signals of modulated transformers;

and :mod:`.rendering` draws the result.  :mod:`.model` holds the drawing model and the sizes
and colours the stages share.  Geometry is in drawing units (one unit is :data:`SCALE` inches in
the figure).
"""
from __future__ import annotations

from pathlib import Path

from ..causality import Analysis
from .blocks import footnote_lines, make_blocks
from .model import (COLLAPSE_ABOVE, CONFLICT, DERIVATIVE, DRAWN_HEAD, EFFORT, FLOW, MIDDLE_KINDS, POSITION, ROW_KINDS,
                    SCALE, Arrow, Block, Diagram, Group)
from .ordering import order
from .placement import place
from .positions import positions
from .rendering import figure, render
from .routing import route
from .topology import Topology


def _messages(an: Analysis, closures=(), signals=()) -> list:
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
    for c in closures:
        how = "its formula gives" if c.formula else "Newton's method solves its residuals for"
        text = f"position closure of {c.owner}: {how} {', '.join(c.unknowns)}"
        if c.reads:
            text += f", reading {', '.join(c.reads)}"
        feeds = sorted({s.target.rsplit(':', 1)[0] for s in signals if s.source == c.block})
        if feeds:
            text += f"; the solved values modulate {', '.join(feeds)}"
        lines.append((POSITION, text))
    return lines


def layout(analysis: Analysis, types: dict | None = None, title: str = "", subtitle: str = "") -> Diagram:
    """The drawing model of an analysed scene.

    ``types`` maps top-level element names to their type names (``scene.element_types``) for the
    frame labels.  Every port variable of the flat network gets exactly one :class:`Arrow`; the
    position closures of the scene get one block each and the states they read or solve for travel
    as position signals (:mod:`.positions`).
    """
    topo = Topology(analysis, types)
    ordering = order(topo)
    blockset = make_blocks(topo, ordering)
    placed = place(topo, ordering, blockset)
    routed = route(topo, ordering, placed)
    blocks, groups = placed.blocks, placed.groups
    ys = [b.y for b in blocks.values()] + [g.y0 for g in groups] + [g.y1 for g in groups]
    ys += [p[1] for a in routed.arrows for p in a.points]
    closures, signals = positions(topo, ordering, placed, max(ys))
    ys += [b.y + b.h / 2 for b in blocks.values() if b.row == "p"] + [p[1] for s in signals for p in s.points]
    xs = [p[0] for a in routed.arrows for p in a.points] + [g.x1 for g in groups] + [0.0]
    xs += [b.x + sgn * b.w / 2 for b in blocks.values() if b.row == "p" for sgn in (-1, 1)]
    extent = (min(xs) - 0.2, max(xs) + 0.3, min(ys) - 0.3, max(ys) + 0.25)
    return Diagram(title, subtitle, blocks, routed.arrows, groups, _messages(analysis, closures, signals),
                   ordering.n_lanes,
                   extent, bool(topo.demoted), bool(analysis.errors), _captions(analysis), placed.lane_h,
                   placed.subgroups, footnote_lines(topo, blockset), routed.links,
                   {f"{ph}:x": gone for ph, (_p, _s, gone) in topo.placeholders.items()}, closures, signals)


def _captions(an: Analysis) -> tuple:
    """Row captions: Weber's words for mechanics, the quantities' names otherwise."""
    doms = {d.name: d for d in an.flat.port_domains.values()}
    if set(doms) <= {"rotational", "translational"}:
        return "(Bewegungen)", "(Kräfte)"
    if len(doms) == 1:
        d = next(iter(doms.values()))
        return f"({d.flow})", f"({d.effort})"
    return "", ""


def cmd_diagram(args) -> int:
    """``multipole diagram FILE -o figure.png|svg|pdf``: exit 0 well-posed, 1 not well-posed (the
    figure is still written, conflicts in red); bad input raises :class:`MultipoleError`."""
    from .. import pipeline
    from ..cli import FIGURE_FORMATS, _overrides, check_output_path
    from ..files import atomic_output
    from ..netlist import load

    check_output_path(args.output, FIGURE_FORMATS, "-o")
    out = Path(args.output)
    scene = load(args.file, _overrides(args.set))
    analysis = pipeline.check(scene)
    diagram = layout(analysis, scene.element_types, f"{scene.name}: Weber block diagram", scene.description)
    with atomic_output(out) as tmp:        # an interrupted write leaves no short figure behind
        render(diagram, tmp)
    print(f"wrote {out}" + ("" if analysis.ok else f" ({len(analysis.errors)} conflict(s) in red)"))
    return 0 if analysis.ok else 1


__all__ = ["Arrow", "Block", "Diagram", "Group", "cmd_diagram", "figure", "layout", "render",
           "COLLAPSE_ABOVE", "CONFLICT", "DERIVATIVE", "DRAWN_HEAD", "EFFORT", "FLOW", "MIDDLE_KINDS", "POSITION",
           "ROW_KINDS", "SCALE"]
