"""Every figure of results the package draws: time plots of a run and Bode plots of a linearisation.

Rules kept here once:

* The user's matplotlib backend is never switched (no ``matplotlib.use``).  A figure that is saved
  to a file is a bare :class:`~matplotlib.figure.Figure` on an Agg canvas, outside pyplot (nothing
  opens a window, nothing is left in pyplot's list of figures); a figure asked for without a file
  (``result.plot()`` in a notebook) is made by pyplot, so the user's backend shows it.
* Time axes are scaled to the run: seconds, ms, µs or ns, whichever puts the end of the run between
  1 and 1000, with the unit in the label (``t [ms]``).
* Every axis is labelled with its quantity and SI unit; legends sit outside the axes (above the
  panels of a time plot, below those of a Bode plot), so they never cover a curve.
* Bode: one column of panels (magnitude above phase) per pair of output unit and input unit, so
  that curves on one axis have the same unit, at most :data:`BODE_COLUMNS` side by side; the inputs are the sources the netlist drives
  (:func:`multipole.linearize.driven_inputs`: grounds are not inputs).
"""
from __future__ import annotations

import textwrap
from collections import defaultdict

import numpy as np

from .files import atomic_output

#: most columns of (magnitude, phase) panels side by side in a Bode plot; more unit pairs wrap
BODE_COLUMNS = 3
#: the time units of a time axis: (seconds per unit, unit)
TIME_UNITS = ((1.0, "s"), (1e-3, "ms"), (1e-6, "µs"), (1e-9, "ns"))


def time_unit(t_end: float) -> tuple[float, str]:
    """``(scale [s], unit)`` for a time axis from 0 to ``t_end`` [s]: the largest unit of
    :data:`TIME_UNITS` in which ``t_end`` is at least 1 (seconds for 1 s and longer runs)."""
    t_end = abs(float(t_end))
    for scale, unit in TIME_UNITS:
        if t_end >= scale:
            return scale, unit
    return TIME_UNITS[-1]


def new_figure(width: float, height: float, show: bool = False, layout: str | None = "constrained"):
    """A figure of ``width`` x ``height`` inches (``layout``: matplotlib's layout engine, None for a
    figure placed by hand).  ``show``: made by pyplot (the user's backend displays it); else a bare
    Figure on an Agg canvas, outside pyplot.  Every figure of the package is made here."""
    if show:
        import matplotlib.pyplot as plt
        return plt.figure(figsize=(width, height), layout=layout)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width, height), layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save(fig, path, dpi: int = 120) -> None:
    """Write ``fig`` to ``path`` atomically, in the format of its suffix (png, svg, pdf)."""
    with atomic_output(path) as tmp:       # an interrupted write leaves no short file behind
        fig.savefig(tmp, dpi=dpi, format=str(path).rsplit(".", 1)[-1].lower())


def _label(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def time_plot(result, path=None, title: str = "", footer: str | None = None):
    """One panel per output over time, events as dotted lines, the solver's summary as a footer.

    ``result`` is a :class:`~multipole.simulate.Result` (its states where it has no outputs), or a
    mapping ``{label: Result}`` to compare runs (a full and a reduced model, two solvers): the first
    one's outputs make the panels, the first is drawn thick and grey, the others dashed on top, with
    a legend above the panels.  ``footer`` replaces the first run's summary.  Saved to ``path``
    when given; returns the figure."""
    runs = dict(result) if isinstance(result, dict) else {"": result}
    first = next(iter(runs.values()))
    names = list(first.outputs) or list(first.state_names)
    n = max(len(names), 1)
    footer = textwrap.fill(first.summary() if footer is None else footer, 160)   # never cut
    legend = 0.35 if len(runs) > 1 else 0.0
    fig = new_figure(8.0, 1.7 * n + 1.2 + legend + 0.12 * footer.count("\n"), show=path is None)
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    t_end = max((r.t[-1] for r in runs.values() if len(r.t)), default=1.0)
    scale, unit = time_unit(t_end)
    styles = [{"lw": 1.4}] if len(runs) == 1 else [{"lw": 2.4, "color": "0.7"}] + \
        [{"lw": 1.1, "ls": "--", "color": f"C{k}"} for k in range(len(runs) - 1)]
    for ax, name in zip(axes, names):
        for (label, run), style in zip(runs.items(), styles):
            if name in run.outputs or name in run.state_names:
                ax.plot(run.t / scale, run[name], label=label or None, **style)
        ax.set_ylabel(_label(name, first.units.get(name, "")), fontsize=9)
        ax.grid(alpha=0.3)
        for te, _ in first.events[:50]:
            ax.axvline(te / scale, color="0.6", lw=0.6, ls=":")
    axes[-1].set_xlabel(f"t [{unit}]")
    axes[-1].set_xlim(0, t_end / scale)
    if len(runs) > 1:                       # above the panels: never over a curve
        axes[0].legend(loc="lower left", bbox_to_anchor=(0.0, 1.02), ncols=len(runs), fontsize=8, frameon=False)
    fig.align_ylabels(axes)
    fig.suptitle(textwrap.fill(title or "simulation", 90), fontsize=10)
    fig.supxlabel(footer, fontsize=6, color="0.35", ha="center")
    if path:
        save(fig, path)
    return fig


def _ratio_unit(out_unit: str, in_unit: str) -> str:
    """The unit of ``output / input``: ``(rad/s)/(N*m)``; ``-`` when both are the same."""
    if out_unit == in_unit:
        return "-"
    wrap = (lambda u: f"({u})" if any(c in u for c in "*/") else u)
    return f"{wrap(out_unit or '-')}/{wrap(in_unit or '-')}"


def frequency_response(lin, freqs) -> np.ndarray:
    """``G[k, i, j]``: the complex response of output i to input j at frequency ``freqs[k]`` [Hz],
    ``C (jωI − A)⁻¹ B + D`` of the :class:`~multipole.linearize.Linearization` ``lin``."""
    n = lin.A.shape[0]
    out = np.empty((len(freqs), lin.C.shape[0], lin.B.shape[1]), dtype=complex)
    for k, f in enumerate(freqs):
        s = 2j * np.pi * f
        out[k] = lin.D + (lin.C @ np.linalg.solve(s * np.eye(n) - lin.A, lin.B) if n else 0.0)
    return out


def bode(lin, path=None, title: str = ""):
    """Bode plot of every driven input → output pair of ``lin`` (a
    :class:`~multipole.linearize.Linearization`) over 1/30 of the lowest to 30 times the highest
    natural frequency (dotted lines), one column per output unit and input unit; pairs with no
    response are left out.  Saved to ``path`` when given; returns the figure."""
    modes = [m[1] for m in lin.modes() if m[1] > 0]
    lo = min(modes) / 30 if modes else 0.01
    hi = max(modes) * 30 if modes else 100.0
    freqs = np.logspace(np.log10(lo), np.log10(hi), 600)
    G = frequency_response(lin, freqs)
    units = getattr(lin, "units", {}) or {}
    groups = defaultdict(list)                  # (output unit, input unit) -> [(i, j), ...]
    for j, u in enumerate(lin.inputs):
        for i, y in enumerate(lin.outputs):
            if np.any(np.abs(G[:, i, j]) > 0):
                groups[(units.get(y, ""), units.get(u, ""))].append((i, j))
    cols = min(max(len(groups), 1), BODE_COLUMNS)
    rows = max(-(-len(groups) // cols), 1)           # rows of (magnitude, phase) pairs
    fig = new_figure(max(4.2 * cols, 7.0), 6.2 * rows, show=path is None)
    axes = fig.subplots(2 * rows, cols, sharex=True, squeeze=False)
    for k in range(len(groups), rows * cols):         # the unused places of the last row
        axes[2 * (k // cols), k % cols].set_visible(False)
        axes[2 * (k // cols) + 1, k % cols].set_visible(False)
    for c, ((out_unit, in_unit), pairs) in enumerate(groups.items()):
        ax_m, ax_p = axes[2 * (c // cols), c % cols], axes[2 * (c // cols) + 1, c % cols]
        for i, j in pairs:
            g = G[:, i, j]
            ax_m.loglog(freqs, np.abs(g), label=f"{lin.inputs[j]} → {lin.outputs[i]}")
            ax_p.semilogx(freqs, np.degrees(np.unwrap(np.angle(g))))
        ax_m.set_ylabel(f"|G| [{_ratio_unit(out_unit, in_unit)}]")
        ax_m.set_title(f"output in {out_unit or '-'}, input in {in_unit or '-'}", fontsize=9)
        ax_p.set_ylabel("phase [deg]")
        ax_p.set_xlabel("frequency [Hz]")
        ax_p.tick_params(labelbottom=True)            # sharex hides them above the last row
        for ax in (ax_m, ax_p):
            ax.grid(which="both", alpha=0.3)
            for f in modes:
                ax.axvline(f, color="0.7", lw=0.7, ls=":")
        ax_p.legend(*ax_m.get_legend_handles_labels(), fontsize=7, loc="upper center",
                    bbox_to_anchor=(0.5, -0.25))          # below the panels: never over a curve
    if not groups:
        axes[0, 0].text(0.5, 0.5, "no input drives an output", ha="center", va="center",
                        transform=axes[0, 0].transAxes)
    fig.suptitle(f"{title}: Bode plot (dotted: natural frequencies)" if title else
                 "Bode plot (dotted: natural frequencies)", fontsize=10)
    if path:
        save(fig, path)
    return fig
