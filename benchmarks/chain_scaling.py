"""Scaling of the compile path and of the generated right-hand side with the model size.

Chains of N = 10, 100, 1000 mass-spring pairs (elements/scenes.py: mass_spring_chain).  For each N:
check time (flatten + analyse), compile time (flatten + analyse + assemble + codegen, split by
stage; the repeat with the median compile time of three), time per right-hand-side call (generated and hand-written numpy), time per Jacobian call,
and one short simulation (its cost per accepted step [µs]).  Log-log slopes between consecutive sizes.

    python benchmarks/chain_scaling.py [--sizes 10 100 1000] [--out docs/bench]

Writes chain_scaling.csv and docs/figures/bench_chain_scaling.png.
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from elements.scenes import hand_model, mass_spring_chain
from multipole.bench import _time_calls, write_rows
from multipole.causality import analyse
from multipole.codegen import compile_model
from multipole.equations import assemble
from multipole.netlist import loads
from multipole.network import flatten
from multipole.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
FIELDS = ["N", "states", "load_s", "flatten_s", "analyse_s", "check_s", "assemble_s", "codegen_s", "compile_s",
          "rhs_generated_us", "rhs_hand_us", "rhs_ratio", "jac_generated_us", "sim_solver", "sim_s", "sim_nfev",
          "sim_steps", "per_call_in_run_us", "per_step_us", "sim_max_dev"]


def measure(n: int) -> dict:
    """Times of every stage for a chain of ``n`` pairs [s, µs per call]."""
    text = mass_spring_chain(n)
    t0 = time.perf_counter()
    scene = loads(text, f"chain{n}.yaml")
    t1 = time.perf_counter()
    flat = flatten(scene.network)
    t2 = time.perf_counter()
    analysis = analyse(flat)
    t3 = time.perf_counter()
    eq = assemble(analysis, scene.name)
    t4 = time.perf_counter()
    model = compile_model(eq, scene.outputs)
    t5 = time.perf_counter()
    hand = hand_model(scene)
    idx = hand.permutation(model.state_names)
    rng = np.random.default_rng(0)
    pts = [(0.1 * k, rng.normal(size=2 * n)) for k in range(4)]
    rhs_gen = _time_calls(model.rhs, pts)
    rhs_hand = _time_calls(hand.rhs, [(t, x[idx]) for t, x in pts])
    jac_gen = _time_calls(model.jac, pts[:1], min_time=0.02)
    dev = max(float(np.max(np.abs(model.rhs(t, x)[idx] - hand.rhs(t, x[idx])))) for t, x in pts)
    res = simulate(model, 1.0, 0.01, "auto", 1e-6, 1e-9, progress=False)
    per_call = res.stats["wall_time"] / max(res.stats["nfev"] + res.stats.get("njev", 0), 1)
    return {"N": n, "states": 2 * n, "load_s": t1 - t0, "flatten_s": t2 - t1, "analyse_s": t3 - t2,
            "check_s": t3 - t1, "assemble_s": t4 - t3, "codegen_s": t5 - t4, "compile_s": t5 - t1,
            "rhs_generated_us": 1e6 * rhs_gen, "rhs_hand_us": 1e6 * rhs_hand, "rhs_ratio": rhs_gen / rhs_hand,
            "jac_generated_us": 1e6 * jac_gen, "sim_solver": res.solver, "sim_s": res.stats["wall_time"],
            "sim_nfev": res.stats["nfev"], "sim_steps": res.stats["steps"], "per_call_in_run_us": 1e6 * per_call,
            "per_step_us": 1e6 * res.stats["wall_time"] / max(res.stats["steps"], 1), "sim_max_dev": dev}


def slopes(rows, key) -> list:
    """Log-log slopes of ``key`` against N between consecutive sizes."""
    out = []
    for a, b in zip(rows, rows[1:]):
        out.append(math.log(b[key] / a[key]) / math.log(b["N"] / a["N"]) if a[key] > 0 and b[key] > 0 else math.nan)
    return out


def plot(rows, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    N = [r["N"] for r in rows]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
    ax = axes[0]
    for key, label, style in (("check_s", "check (flatten + analyse)", "o-"), ("assemble_s", "assemble", "s-"),
                              ("codegen_s", "codegen + compile", "^-"), ("compile_s", "total compile", "k*-")):
        ax.loglog(N, [r[key] for r in rows], style, label=label)
    ref = rows[0]["compile_s"]
    ax.loglog(N, [ref * n / N[0] for n in N], ":", color="0.5", label="linear growth")
    ax.axhline(10.0, color="tab:red", lw=0.8, ls="--")
    ax.text(N[0], 10.0, " 10 s target at N = 1000", color="tab:red", fontsize=8, va="bottom")
    ax.set_xlabel("N (mass-spring pairs)")
    ax.set_ylabel("time [s]")
    ax.set_title("compile path", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax = axes[1]
    ax.loglog(N, [r["rhs_generated_us"] for r in rows], "o-", label="generated rhs (per call)")
    ax.loglog(N, [r["rhs_hand_us"] for r in rows], "s-", label="hand-written numpy rhs (per call)")
    ax.loglog(N, [r["jac_generated_us"] for r in rows], "^-", label="generated Jacobian (per call)")
    ax.loglog(N, [r["per_call_in_run_us"] for r in rows], "k*-", label="whole run / (nfev + njev)")
    ax.loglog(N, [r["per_step_us"] for r in rows], "kD--", label="whole run / accepted steps")
    ax.set_xlabel("N (mass-spring pairs)")
    ax.set_ylabel("time per call or step [µs]")
    ax.set_title("per evaluation", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("mass-spring chains: cost against model size (2N states)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(sizes=(10, 100, 1000), out=ROOT / "docs" / "bench", figures=ROOT / "docs" / "figures", verbose=True,
        repeats=3):
    """Measure every size ``repeats`` times and keep, per size, the repeat whose compile time is the
    median (a whole repeat, so that its stage times add up); one untimed warm-up first (imports)."""
    rows = []
    measure(sizes[0])
    for n in sizes:
        runs = sorted((measure(n) for _ in range(repeats)), key=lambda r: r["compile_s"])
        row = runs[len(runs) // 2]
        rows.append(row)
        if verbose:
            print(f"N = {n:5d}: check {row['check_s']:.3g} s, compile {row['compile_s']:.3g} s, "
                  f"rhs {row['rhs_generated_us']:.3g} µs (hand {row['rhs_hand_us']:.3g} µs)", flush=True)
    out, figures = Path(out), Path(figures)
    out.mkdir(parents=True, exist_ok=True)
    figures.mkdir(parents=True, exist_ok=True)
    write_rows(rows, FIELDS, out / "chain_scaling.csv")
    plot(rows, figures / "bench_chain_scaling.png")
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--out", default=str(ROOT / "docs" / "bench"))
    args = ap.parse_args()
    rows = run(args.sizes, args.out)
    for key in ("check_s", "compile_s", "rhs_generated_us", "rhs_hand_us", "per_step_us"):
        print(f"slope of {key}: " + ", ".join(f"{s:.2f}" for s in slopes(rows, key)))
