"""Energy drift of the conservative two-mass oscillator over 10^4 periods, per solver.

    python benchmarks/long_horizon.py [--periods 10000] [--rtol 1e-6]

The scene is diagrams/hard/two_mass_long.yaml (multipole_models.two_mass_oscillator).  Energy
``E = m1 v1²/2 + m2 v2²/2 + k1 q1²/2 + k2 q2²/2`` is evaluated on the output grid (four samples per
slow period); reported: the largest relative energy error in the first and the last tenth of the
run and at the end, the final error of ``m1.v`` against the closed form, wall time and nfev.
Writes long_horizon.csv and docs/figures/bench_long_horizon.png.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from multipole_models import _TWO_MASS, _two_mass_matrix, _two_mass_x0, linear_response, two_mass_oscillator
from multipole.bench import write_rows
from multipole import pipeline
from multipole.netlist import loads
from multipole.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
#: (solver, factor on rtol, fraction of the periods): GL4 at a 100x looser tolerance; the slow implicit
#: multistep/collocation runs over a tenth of the horizon (their drift grows linearly, see the figure)
SOLVERS = [("RK45", 1.0, 1.0), ("DOP853", 1.0, 1.0), ("LSODA", 1.0, 1.0), ("GL4", 1e2, 1.0), ("GL4", 1.0, 0.1),
           ("BDF", 1.0, 0.1), ("Radau", 1.0, 0.1)]
FIELDS = ["solver", "rtol", "periods", "drift_first_tenth", "drift_last_tenth", "drift_end", "err_final",
          "wall_s", "nfev", "njev", "nlu", "steps"]


def run(periods=1e4, rtol=1e-6, out=ROOT / "docs" / "bench", figures=ROOT / "docs" / "figures",
        solvers=SOLVERS, verbose=True):
    scene = loads(two_mass_oscillator(periods=periods, name="two_mass_long", bench=False), "two_mass_long.yaml")
    p = dict(_TWO_MASS)
    model = pipeline.model(scene)
    period = scene.simulate["t_end"] / periods
    rows, curves = [], {}
    for solver, factor, fraction in solvers:
        tol = rtol * factor
        n_periods = periods * fraction
        t_end = n_periods * period
        res = simulate(model, t_end, period / 4, solver, tol, tol * 1e-3, progress=False)
        E = (0.5 * p["m1"] * res["m1.v"] ** 2 + 0.5 * p["m2"] * res["m2.v"] ** 2
             + 0.5 * p["k1"] * res["k1.deflection"] ** 2 + 0.5 * p["k2"] * res["k2.deflection"] ** 2)
        dE = np.abs(E / E[0] - 1)
        n = len(dE) // 10
        exact = linear_response(_two_mass_matrix(p), _two_mass_x0(p), [0, 1 / p["m1"], 0, 0], t=res.t[-1:])
        scale = np.max(np.abs(res["m1.v"]))
        row = {"solver": solver, "rtol": tol, "periods": n_periods, "drift_first_tenth": dE[:n].max(),
               "drift_last_tenth": dE[-n:].max(), "drift_end": dE[-1],
               "err_final": abs(res["m1.v"][-1] - exact[0]) / scale, "wall_s": res.stats["wall_time"],
               "nfev": res.stats["nfev"], "njev": res.stats["njev"], "nlu": res.stats["nlu"],
               "steps": res.stats["steps"]}
        rows.append(row)
        curves[f"{solver} rtol {tol:g}"] = (res.t / period, dE)
        if verbose:
            print(f"{solver:7s} rtol {tol:7.1e}: drift first/last tenth {row['drift_first_tenth']:.2e} / "
                  f"{row['drift_last_tenth']:.2e}, end {row['drift_end']:.2e}, wall {row['wall_s']:.3g} s, "
                  f"nfev {row['nfev']}", flush=True)
    out, figures = Path(out), Path(figures)
    out.mkdir(parents=True, exist_ok=True)
    figures.mkdir(parents=True, exist_ok=True)
    write_rows(rows, FIELDS, out / "long_horizon.csv")
    plot(curves, periods, figures / "bench_long_horizon.png")
    return rows


def plot(curves, periods, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(9, 4.8))
    for label, (x, dE) in curves.items():
        # the envelope per period keeps the figure readable: running maximum over blocks of 4 samples
        k = 4 * max(1, len(x) // 2000)
        m = len(x) // k
        xs, ys = x[:m * k].reshape(m, k)[:, -1], dE[:m * k].reshape(m, k).max(axis=1)
        ax.loglog(xs, np.maximum(ys, 1e-17), label=label, lw=1.3, ls="--" if label.startswith("GL4") else "-")
    ax.set_xlabel("time [slow periods]")
    ax.set_ylabel("relative energy error |E/E0 - 1|")
    ax.set_title(f"two-mass oscillator, {periods:g} periods: energy drift per solver", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=float, default=1e4)
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--out", default=str(ROOT / "docs" / "bench"))
    args = ap.parse_args()
    run(args.periods, args.rtol, args.out)
