"""Drawings of a scene's moving geometry from a simulation: ``multipole draw``.

Elements declare what they look like with :class:`multipole.network.Sketch` records (polylines
through points given as expressions of the states).  Flattening makes every point an output
(``<element>.sketch<k>.<j>.x`` / ``.y`` [m]); this module runs the scene with those outputs and
draws

* the mechanism at chosen instants (later instants darker), its joints and labels, pivots that do
  not move over the run drawn as frame bearings, and the path of every traced point (a coupler
  curve);
* optionally the transfer functions of 0th, 1st and 2nd order of outputs against a drive
  coordinate (``q(p)``, ``dq/dp``, ``d2q/dp2``), from the sampled run;
* optionally an animated GIF.

It knows nothing about linkages or belts: whatever an element sketches is drawn.  Figures are made
with matplotlib's object interface; the user's backend is never changed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import NetlistError
from .plotting import new_figure, save

#: instants drawn when none are given
DEFAULT_INSTANTS = 5


@dataclass
class Drawn:
    """One sketch with its sampled points: ``xy`` has shape (samples, points, 2) [m]."""

    owner: str
    style: str
    labels: list
    trace: bool
    xy: np.ndarray


def sketch_outputs(flat) -> list:
    """``(owner, sketch, [(x output, y output), ...])`` for every sketch of a flat network."""
    return [(owner, sk, [(f"{owner}.sketch{k}.{j}.x", f"{owner}.sketch{k}.{j}.y") for j in range(len(pts))])
            for k, (owner, sk, pts) in enumerate(flat.sketches)]


def sample(scene, t_end=None, dt_out=None, backend=None, extra=()):
    """Run ``scene`` with its sketch points (and the outputs ``extra``) as outputs.

    Returns ``(result, drawn)`` with one :class:`Drawn` per sketch; ``no_sketch`` (exit 2) if no
    element of the scene declares a drawing."""
    from . import pipeline
    from .network import flatten
    flat = flatten(scene.network)
    sketches = sketch_outputs(flat)
    if not sketches:
        raise NetlistError("no_sketch", "nothing to draw: no element of the scene declares a drawing",
                           "draw scenes with planar elements (linkage modules); use 'simulate --plot' for "
                           "time plots", scene.path)
    names = [n for _o, _s, pts in sketches for pt in pts for n in pt]
    result = pipeline.run(scene, t_end, dt_out, outputs=list(dict.fromkeys(list(extra) + names)), backend=backend,
                          progress=False)
    drawn = [Drawn(owner, sk.style, list(sk.labels), sk.trace,
                   np.stack([np.column_stack([result[x], result[y]]) for x, y in pts], axis=1))
             for owner, sk, pts in sketches]
    return result, drawn


def _instants(t, at, count) -> list[int]:
    if at:
        return [int(np.argmin(np.abs(t - a))) for a in at]
    return sorted(set(np.linspace(0, len(t) - 1, count).round().astype(int).tolist()))


def _limits(drawn) -> tuple:
    pts = np.concatenate([d.xy.reshape(-1, 2) for d in drawn])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.08 * max(float((hi - lo).max()), 1e-9)
    return lo - pad, hi + pad


def _draw_frame(ax, drawn, k, shade) -> list:
    """The mechanism at sample ``k`` into ``ax`` (``shade`` 0 light … 1 dark); returns its labels
    as ``(x, y, text)`` for :func:`_place_labels`."""
    colour = (0.1, 0.2, 0.75, 0.2 + 0.8 * shade)
    labels = []
    for d in drawn:
        xy = d.xy[k]
        if d.style == "slide":
            ax.plot(xy[:, 0], xy[:, 1], "-", color=colour, lw=1.0, alpha=0.8, dashes=(6, 3))
        elif d.style == "point":
            ax.plot(xy[:, 0], xy[:, 1], "o", color=colour, ms=4)
        elif d.style == "line":
            ax.plot(xy[:, 0], xy[:, 1], "-", color=colour, lw=1.5)
        else:
            ax.plot(xy[:, 0], xy[:, 1], "-o", color=colour, lw=3.0, ms=5, mfc="white", mec=colour, mew=1.5,
                    solid_capstyle="round")
        labels += [(x, y, f"{d.owner}.{text}") for (x, y), text in zip(xy, d.labels) if text]
    return labels


#: where a label may sit relative to its point [pt], in the order tried: the four corners close by,
#: then farther out above and below
LABEL_OFFSETS = [(5, 5), (5, -5), (-5, 5), (-5, -5)] + [(sx * 5, sy * (5 + 9 * k)) for k in (1, 2, 3)
                                                        for sy in (1, -1) for sx in (1, -1)]
LABEL_SIZE = 8       #: font size of the labels [pt]


def _place_labels(ax, labels) -> None:
    """Write the labels ``(x, y, text)`` (data coordinates) next to their points, each at the first
    of :data:`LABEL_OFFSETS` whose box overlaps no label placed before it (else where it overlaps
    least): labels of points that lie close together are pushed apart instead of printed over each
    other.  Call it when everything else is drawn (the layout engine has placed the axes)."""
    ax.figure.draw_without_rendering()
    ax.apply_aspect()
    scale = ax.figure.dpi / 72.0                        # pixels per point
    boxes = []

    def box(px, py, dx, dy, text):
        w, h = len(text) * 0.6 * LABEL_SIZE * scale, 1.25 * LABEL_SIZE * scale
        x0 = px + dx * scale - (w if dx < 0 else 0.0)
        y0 = py + dy * scale - (h if dy < 0 else 0.0)
        return x0, y0, x0 + w, y0 + h

    def overlap(a, b):
        return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))

    for x, y, text in labels:
        px, py = ax.transData.transform((x, y))
        best = None
        for dx, dy in LABEL_OFFSETS:
            b = box(px, py, dx, dy, text)
            cost = sum(overlap(b, o) for o in boxes)
            if best is None or cost < best[0]:
                best = (cost, dx, dy, b)
            if cost == 0.0:
                break
        _cost, dx, dy, b = best
        boxes.append(b)
        ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset points", fontsize=LABEL_SIZE,
                    ha="left" if dx > 0 else "right", va="bottom" if dy > 0 else "top")


def _frame_pivots(drawn) -> np.ndarray:
    """Sketch points that do not move over the run (frame bearings)."""
    fixed = []
    for d in drawn:
        if d.style != "link":
            continue
        span = np.ptp(d.xy, axis=0).max(axis=1)
        fixed += [d.xy[0, j] for j in np.flatnonzero(span < 1e-12)]
    return np.array(fixed).reshape(-1, 2)


def _decorate(ax, drawn, lo, hi, pivots):
    size = float((hi - lo).max())
    for x, y in pivots:
        ax.fill([x, x - 0.03 * size, x + 0.03 * size], [y, y - 0.045 * size, y - 0.045 * size],
                color="0.55", zorder=0)
        ax.plot([x - 0.05 * size, x + 0.05 * size], [y - 0.045 * size] * 2, color="0.35", lw=1.5, zorder=0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)


def mechanism_figure(result, drawn, path, at=None, instants=DEFAULT_INSTANTS, title=""):
    """The mechanism at the chosen instants with its traced paths, written to ``path``."""
    fig = new_figure(7.5, 6.0)
    ax = fig.subplots()
    ks = _instants(result.t, at, instants)
    for d in drawn:
        if d.trace:
            ax.plot(d.xy[:, -1, 0], d.xy[:, -1, 1], "-", color="tab:orange", lw=1.2,
                    label=f"path of {d.labels[-1] if d.labels and d.labels[-1] else d.owner} ({d.owner})")
    labels = []
    for i, k in enumerate(ks):
        labels = _draw_frame(ax, drawn, k, (i + 1) / len(ks))     # the last instant's are written
    lo, hi = _limits(drawn)
    _decorate(ax, drawn, lo, hi, _frame_pivots(drawn))
    times = ", ".join(f"{result.t[k]:.3g}" for k in ks)
    ax.set_title((title + "\n" if title else "") + f"at t = {times} s (light to dark)", fontsize=10)
    if any(d.trace for d in drawn):
        fig.legend(loc="outside lower center", fontsize=8, frameon=False)
    _place_labels(ax, labels)
    save(fig, path)


def transfer_figure(result, pairs, path, units=None):
    """Transfer functions of 0th, 1st and 2nd order ``q(p)``, ``dq/dp``, ``d2q/dp2`` for each
    ``(p, q)`` output pair, from the sampled run (central differences over the drive coordinate)."""
    units = units or {}
    fig = new_figure(7.5, 7.5)
    axes = fig.subplots(3, 1, sharex=True)
    for p_name, q_name in pairs:
        p, q = np.asarray(result[p_name]), np.asarray(result[q_name])
        d1 = np.gradient(q, p, edge_order=2)
        d2 = np.gradient(d1, p, edge_order=2)
        up, uq = units.get(p_name, ""), units.get(q_name, "")
        for ax, y in zip(axes, (q, d1, d2)):
            ax.plot(p, y, label=q_name)
        axes[0].set_ylabel(f"q [{uq}]" if uq else "q")
        axes[1].set_ylabel(f"dq/dp [{uq}/{up}]" if uq else "dq/dp")
        axes[2].set_ylabel(f"d²q/dp² [{uq}/{up}²]" if uq else "d²q/dp²")
        axes[2].set_xlabel(f"{p_name} [{up}]" if up else p_name)
    for ax, order in zip(axes, ("0th", "1st", "2nd")):
        ax.grid(alpha=0.3)
        ax.set_title(f"transfer function of {order} order", fontsize=9, loc="left")
    axes[0].legend(fontsize=8, loc="best")
    save(fig, path)


def animation(result, drawn, path, frames=60):
    """An animated GIF of the run (``frames`` evenly spaced samples), written with Pillow."""
    from PIL import Image
    lo, hi = _limits(drawn)
    pivots = _frame_pivots(drawn)
    images = []
    for k in _instants(result.t, None, frames):
        fig = new_figure(5, 4)
        fig.set_dpi(80)
        ax = fig.subplots()
        for d in drawn:
            if d.trace:
                ax.plot(d.xy[:, -1, 0], d.xy[:, -1, 1], "-", color="tab:orange", lw=1.0)
        labels = _draw_frame(ax, drawn, k, 1.0)
        _decorate(ax, drawn, lo, hi, pivots)
        ax.set_title(f"t = {result.t[k]:.3f} s", fontsize=9)
        _place_labels(ax, labels)
        fig.canvas.draw()
        images.append(Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3]))
    images[0].save(path, save_all=True, append_images=images[1:], duration=80, loop=0)


def _numbers(text: str, option: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise NetlistError("bad_option", f"{option} {text!r}: give numbers separated by commas",
                           f"e.g. {option} 0,0.5,1") from None
    if not values or not all(np.isfinite(values)) or min(values) < 0:
        raise NetlistError("bad_option", f"{option} {text!r}: give finite times >= 0 [s]", f"e.g. {option} 0,0.5,1")
    return values


def _pairs(text: str) -> list[tuple[str, str]]:
    pairs = []
    for item in text.split(","):
        p, sep, q = item.strip().partition(":")
        if not sep or not p or not q:
            raise NetlistError("bad_option", f"--transfer {text!r}: give DRIVE:OUTPUT pairs separated by commas",
                               "e.g. --transfer crank.phi:rocker.phi2,crank.phi:rocker.x")
        pairs.append((p, q))
    return pairs


def cmd_draw(args) -> int:
    """``multipole draw FILE -o figure.png [--at T,...] [--transfer P:Q,...] [--gif anim.gif]``."""
    from .cli import FIGURE_FORMATS, _overrides, check_output_path
    from .netlist import load
    check_output_path(args.output, FIGURE_FORMATS, "-o")
    check_output_path(args.transfer_plot, FIGURE_FORMATS, "--transfer-plot")
    check_output_path(args.gif, (".gif",), "--gif")
    at = _numbers(args.at, "--at") if args.at else None
    pairs = _pairs(args.transfer) if args.transfer else []
    if pairs and not args.transfer_plot:
        raise NetlistError("bad_option", "--transfer needs --transfer-plot FILE for the figure",
                           "add --transfer-plot transfer.png")
    scene = load(args.file, _overrides(args.set))
    extra = [n for pq in pairs for n in pq]
    result, drawn = sample(scene, args.t_end, None, args.backend, extra)
    if at and max(at) > result.t[-1] * (1 + 1e-12):
        raise NetlistError("bad_option", f"--at {max(at):g} s is after the end of the run ({result.t[-1]:g} s)",
                           "give instants within the simulated time, or a longer --t-end")
    mechanism_figure(result, drawn, args.output, at, args.instants, title=scene.name)
    print(f"wrote {args.output}")
    if pairs:
        transfer_figure(result, pairs, args.transfer_plot, result.units)
        print(f"wrote {args.transfer_plot}")
    if args.gif:
        animation(result, drawn, args.gif)
        print(f"wrote {args.gif}")
    return 0


def add_arguments(p) -> None:
    """The command-line options of ``multipole draw``."""
    p.add_argument("file")
    p.add_argument("-o", "--output", required=True, help="figure of the mechanism (png, svg, pdf)")
    p.add_argument("--at", help="instants to draw [s], comma-separated (default: 5 over the run)")
    p.add_argument("--instants", type=int, default=DEFAULT_INSTANTS, help="how many instants when --at is not given")
    p.add_argument("--transfer", metavar="P:Q,...", help="transfer functions q(p), dq/dp, d2q/dp2 of outputs")
    p.add_argument("--transfer-plot", help="figure for --transfer (png, svg, pdf)")
    p.add_argument("--gif", help="animated GIF of the run")
    p.add_argument("--t-end", type=float)
    p.add_argument("--backend", help="numpy (default) or numba")
    p.add_argument("--set", action="append", metavar="NAME=VALUE")
