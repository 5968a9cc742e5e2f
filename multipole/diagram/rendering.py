"""Stage 5 of a block diagram: drawing it.

:func:`figure` draws a :class:`~multipole.diagram.model.Diagram` into a matplotlib figure (Agg
canvas, pyplot's global state untouched) and :func:`render` writes it to a file.  Nothing here
changes the diagram.  Figure sizes and margins are in inches, font sizes in points; the axes
are in drawing units (one unit is :data:`~multipole.diagram.model.SCALE` inches).
"""
from __future__ import annotations

import textwrap
from pathlib import Path

from ..plotting import new_figure
from .model import CONFLICT, DERIVATIVE, DY, EFFORT, FLOW, POSITION, SCALE, Diagram


def figure(diagram: Diagram):
    """The matplotlib :class:`~matplotlib.figure.Figure` of ``diagram`` (Agg canvas, pyplot's
    global state untouched).  Wires are ``Line2D`` with gid ``wire``; every text is a ``Text``."""
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
    fig = new_figure(width_in, height_in, layout=None)
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
        for dy, text, colour in ((0, f"flows\n{flows}", FLOW), (-DY, "cross-\ncouplings", "#777777"),
                                 (-2 * DY, f"efforts\n{efforts}", EFFORT)):
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

    for s in diagram.signals:               # position signals: closures and modulated transformers
        xs, ys = zip(*s.points)
        ax.add_line(Line2D(xs, ys, color=POSITION, lw=1.0, ls="-.", zorder=2, gid="signal"))
        ax.annotate("", xy=s.points[-1], xytext=s.points[-2], zorder=3,
                    arrowprops=dict(arrowstyle="-|>,head_length=0.5,head_width=0.25", color=POSITION, lw=1.0,
                                    shrinkA=0, shrinkB=0))
    for src in {s.source for s in diagram.signals}:
        mine = [s for s in diagram.signals if s.source == src and s.branch is not None]
        if mine:                            # branching points where a shared track splits
            x0 = mine[0].points[0][0]
            xs = [s.branch[0] for s in mine]
            lo, hi = min(xs + [x0]), max(xs + [x0])
            for s in mine:
                if lo + 1e-6 < s.branch[0] < hi - 1e-6 or abs(s.branch[0] - x0) < 1e-6:
                    ax.plot([s.branch[0]], [s.branch[1]], "o", ms=4.5, color=POSITION, zorder=5)

    for b in diagram.blocks.values():
        edge = CONFLICT if b.conflict else DERIVATIVE if b.derivative else POSITION if b.kind == "closure" \
            else "#222222"
        text_colour = CONFLICT if b.conflict else DERIVATIVE if b.derivative else POSITION if b.kind == "closure" \
            else "#111111"
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
    if diagram.signals or diagram.closures:
        handles.append(Line2D([], [], color=POSITION, lw=1.0, ls="-.", marker=">", ms=5,
                              label="position signal: state read by a closure or modulating a ratio"))
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
