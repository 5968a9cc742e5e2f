"""The Mathieu stability chart of docs/sweeps.md: a 2-D study of diagrams/hard/mathieu.yaml.

x'' + (delta + eps*cos(t))*x = 0 is swept over the mean stiffness delta and the modulation depth
eps; the metric is the largest deflection over 20 excitation periods (the run starts at x = 1), so
the instability tongues show as large values.  The analytic first instability boundary,
delta = 1/4 ± eps/2 - eps²/8 (two-term expansion of the transition curves a = 1 ± q of the
Mathieu equation in its standard form, mapped by t = 2*tau), is drawn over the heat map.

Run:  python benchmarks/sweep_mathieu.py [-o docs/figures/sweep_mathieu.png] [--workers 2]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "diagrams" / "hard" / "mathieu.yaml"


def boundary(eps):
    """The first tongue's edges: delta = 1/4 - eps/2 - eps²/8 and 1/4 + eps/2 - eps²/8."""
    return 0.25 - eps / 2 - eps ** 2 / 8, 0.25 + eps / 2 - eps ** 2 / 8


def main() -> None:
    from multipole.sweep import Study
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", default=str(ROOT / "docs" / "figures" / "sweep_mathieu.png"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--n-delta", type=int, default=31)
    ap.add_argument("--n-eps", type=int, default=17)
    args = ap.parse_args()
    study = Study(SCENE, {"delta": f"0..0.6:lin:{args.n_delta}", "eps": f"0..0.8:lin:{args.n_eps}"},
                  metrics=["spring.q.max"])
    start = time.perf_counter()
    study.run("process", workers=args.workers)
    wall = time.perf_counter() - start
    print(study.summary())
    print(f"{len(study.rows)} runs in {wall:.1f} s on {args.workers} worker(s)")

    def overlay(ax):
        eps = np.linspace(0, 0.8, 200)
        lo, hi = boundary(eps)
        ax.plot(lo, eps, "w--", lw=1.6, label="analytic first boundary\n" r"$\delta = 1/4 \pm \epsilon/2 - \epsilon^2/8$")
        ax.plot(hi, eps, "w--", lw=1.6)
        ax.set_xlim(0, 0.6)
        ax.set_ylim(0, 0.8)
        ax.set_xlabel(r"mean stiffness $\delta$ [1/s²] (per unit mass)")
        ax.set_ylabel(r"modulation depth $\epsilon$ [1/s²]")
        ax.legend(loc="lower right", fontsize=8, facecolor="0.3", labelcolor="w", framealpha=0.8)

    study.figure(args.output, "spring.q.max", overlay=overlay)
    # how well the chart and the boundary agree: a run inside the analytic tongue should grow (max > 10),
    # one well outside should not, except near the tongue's edge where the growth is slow
    inside = outside = agree_in = agree_out = 0
    for r in study.rows:
        lo, hi = boundary(r["eps"])
        if r["eps"] > 0.05 and lo + 0.02 < r["delta"] < hi - 0.02:
            inside += 1
            agree_in += r["spring.q.max"] > 10
        elif r["delta"] < lo - 0.05 or r["delta"] > hi + 0.05:
            outside += 1
            agree_out += r["spring.q.max"] < 10
    print(f"inside the analytic tongue: {agree_in}/{inside} runs grow past 10; "
          f"well outside: {agree_out}/{outside} stay below 10")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
