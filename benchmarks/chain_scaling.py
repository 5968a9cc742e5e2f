"""Scaling of the compile path, of auto's stiffness estimate and of the generated right-hand side
with the model size.

Chains of N = 10, 100, 1000 mass-spring pairs (multipole_models.mass_spring_chain).  For each N:
check time (flatten + analyse), compile time (flatten + analyse + assemble + codegen, split by
stage; the repeat with the median compile time of ``--repeats``), the time of ``auto``'s stiffness
estimate (:func:`multipole.simulate.choose_solver`: all eigenvalues up to 200 states, an Arnoldi
estimate above) and which estimate ran, time per right-hand-side call (generated and hand-written
numpy), time per Jacobian call, one short simulation (its cost per accepted step [µs]), and the
whole process ``multipole simulate chain.yaml --t-end 0.01`` with a fresh model cache (wall time and
peak memory, what a user waits for).  Log-log slopes between consecutive sizes.

    python benchmarks/chain_scaling.py [--sizes 10 100 1000] [--repeats 3] [--out docs/bench] [--report]
    python benchmarks/chain_scaling.py --estimate-only 1000 10000 [--before]
    python benchmarks/chain_scaling.py --stack 10 100
    python benchmarks/chain_scaling.py --plot-only        # redraw the figure from the CSV
    python benchmarks/chain_scaling.py --process-only 2000 10000 --c3 1e6 --solver Radau

``--stack`` times check + compile of ``diagrams/weber/piezo_stack.yaml`` with n discs as written and
with m: 0 and R: 0 (storages in derivative causality).  Every run stays inside the loader's input
limits (docs/netlist.md, Limits): a 10,000-pair chain is 20,002 elements and 1.3 MB.

``--process-only`` runs only the whole process, on chains with hardening springs ``c3*q**3`` (not
affine: the generated Jacobian is a sparse matrix of the plan's nonzeros, docs/performance.md §3) when
``--c3`` is given, with ``--solver``; a 10,000-pair such chain is 30,002 elements and 2.5 MB.

``--estimate-only`` times the stiffness estimate alone on the hand-written chain (no compile), and
with ``--before`` also the dense ``eigvals`` of the full Jacobian the estimate replaced.

Writes chain_scaling.csv and docs/figures/bench_chain_scaling.png; with ``--report`` also the table of
docs/performance.md section 3 (between its ``chain-scaling-table`` markers).  Section 3 belongs to this
script: ``benchmarks/run_all.py`` carries it over unchanged and does not touch the CSV or the figure.
"""
from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from multipole_models import hand_model, mass_spring_chain
from multipole.bench import _time_calls, write_rows
from multipole.causality import analyse
from multipole.codegen import compile_model
from multipole.equations import assemble
from multipole.netlist import loads
from multipole.network import flatten
from multipole.simulate import choose_solver, simulate

ROOT = Path(__file__).resolve().parents[1]
FIELDS = ["N", "states", "load_s", "flatten_s", "analyse_s", "check_s", "assemble_s", "codegen_s", "compile_s",
          "choose_s", "choose_estimate", "rhs_generated_us", "rhs_hand_us", "rhs_ratio", "jac_generated_us", "sim_solver", "sim_s", "sim_nfev",
          "sim_steps", "per_call_in_run_us", "per_step_us", "sim_max_dev", "process_s", "process_rss_mb", "load_avg"]
#: horizon of the whole-process run [s]: short, so that set-up dominates as in the issue's measurement
PROCESS_T_END = 0.01
#: a dense generated Jacobian (a model without ``jac_sparse``) is an n x n array: its per-call time is
#: measured up to this many states
JAC_MAX_STATES = 4000


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
    jac = model.jac_sparse or model.jac           # the sparse one from SPARSE_JACOBIAN_STATES on
    jac_gen = _time_calls(jac, pts[:1], min_time=0.02) if model.jac_sparse or 2 * n <= JAC_MAX_STATES else math.nan
    dev = max(float(np.max(np.abs(model.rhs(t, x)[idx] - hand.rhs(t, x[idx])))) for t, x in pts)
    t6 = time.perf_counter()
    _, reason = choose_solver(model, 1.0, 1e-6)
    choose_s = time.perf_counter() - t6
    res = simulate(model, 1.0, 0.01, "auto", 1e-6, 1e-9, progress=False)
    per_call = res.stats["wall_time"] / max(res.stats["nfev"] + res.stats.get("njev", 0), 1)
    return {"N": n, "states": 2 * n, "load_s": t1 - t0, "flatten_s": t2 - t1, "analyse_s": t3 - t2,
            "check_s": t3 - t1, "assemble_s": t4 - t3, "codegen_s": t5 - t4, "compile_s": t5 - t1,
            "choose_s": choose_s, "choose_estimate": reason.rpartition("; ")[2], "rhs_generated_us": 1e6 * rhs_gen, "rhs_hand_us": 1e6 * rhs_hand, "rhs_ratio": rhs_gen / rhs_hand,
            "jac_generated_us": 1e6 * jac_gen, "sim_solver": res.solver, "sim_s": res.stats["wall_time"],
            "sim_nfev": res.stats["nfev"], "sim_steps": res.stats["steps"], "per_call_in_run_us": 1e6 * per_call,
            "per_step_us": 1e6 * res.stats["wall_time"] / max(res.stats["steps"], 1), "sim_max_dev": dev}


def whole_process(n: int, c3: float = 0.0, solver: str = "auto") -> tuple[float, float, float]:
    """Wall time [s], peak resident memory [MB] and CPU time (user + system) [s] of ``multipole
    simulate`` on a chain of ``n`` pairs (hardening springs with ``c3`` [N/m³] not zero) with
    ``--solver solver`` and a fresh model cache, in its own process (``os.wait4`` gives that child's
    own peak and CPU time; on a shared machine the CPU time is the figure that does not depend on
    the load)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"chain{n}.yaml"
        path.write_text(mass_spring_chain(n, c3=c3), encoding="utf-8")
        cmd = [sys.executable, "-m", "multipole.cli", "simulate", str(path), "--t-end", str(PROCESS_T_END),
               "--solver", solver, "--quiet", "--out", str(Path(tmp) / "r.csv")]
        env = {**os.environ, "MULTIPOLE_CACHE": str(Path(tmp) / "cache")}
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        if status != 0:
            raise RuntimeError(f"multipole simulate failed on chain {n} (status {status})")
    return wall, usage.ru_maxrss / 1024.0, usage.ru_utime + usage.ru_stime


def estimate_only(sizes, before=False) -> None:
    """Time the stiffness estimate alone on the hand-written chains (no compile) [s]; with ``before``
    also dense ``eigvals`` of the full Jacobian (O(n³): minutes from 2000 states on)."""
    for n in sizes:
        hand = hand_model(loads(mass_spring_chain(n), f"chain{n}.yaml"))
        t0 = time.perf_counter()
        name, reason = choose_solver(hand, 1.0, 1e-6)
        line = f"N = {n}: estimate {time.perf_counter() - t0:.3g} s ({name}; {reason.rpartition('; ')[2]})"
        if before:
            J = hand.jac(0.0, hand.x0)
            t0 = time.perf_counter()
            np.linalg.eigvals(J)
            line += f"; dense eigvals {time.perf_counter() - t0:.3g} s"
        print(line, flush=True)


STACK = ROOT / "diagrams" / "weber" / "piezo_stack.yaml"
#: variants of the stack scene: storages in derivative causality without the discs' masses (m: 0) or
#: without the electrodes' resistance (R: 0, the discs' capacitances in parallel)
STACK_VARIANTS = {"as written": {}, "m: 0": {"m: 5.0e-4,": "m: 0.0,"}, "R: 0": {"R: 10.0}": "R: 0.0}"}}


def stack(n: int) -> None:
    """Check + compile time [s] of the piezo stack scene with ``n`` discs, per variant (``n`` at most
    the loader's ``piezo_stack`` limit, 100: the issue's target is stated for 100 discs): wall time
    per stage, and the CPU time of the whole (this process, BLAS threads included), the figure that
    does not depend on other jobs on the machine."""
    base = STACK.read_text(encoding="utf-8").replace("n: 10,", f"n: {n},")
    for name, edits in STACK_VARIANTS.items():
        text = base
        for old, new in edits.items():
            text = text.replace(old, new)
        times = {}
        cpu = time.process_time()
        t = time.perf_counter()
        scene = loads(text, "piezo_stack.yaml")
        times["load"] = time.perf_counter() - t
        t = time.perf_counter()
        flat = flatten(scene.network)
        times["flatten"] = time.perf_counter() - t
        t = time.perf_counter()
        analysis = analyse(flat)
        times["analyse"] = time.perf_counter() - t
        t = time.perf_counter()
        eq = assemble(analysis, scene.name)
        times["assemble"] = time.perf_counter() - t
        t = time.perf_counter()
        model = compile_model(eq, scene.outputs)
        times["codegen"] = time.perf_counter() - t
        cpu = time.process_time() - cpu
        stages = ", ".join(f"{k} {v:.3g}" for k, v in times.items())
        print(f"piezo stack n = {n}, {name}: {len(model.state_names)} states; {stages}; "
              f"check + compile {sum(times.values()):.3g} s wall, {cpu:.3g} s CPU; load {os.getloadavg()[0]:.1f}",
              flush=True)


REPORT = ROOT / "docs" / "performance.md"
TABLE_BEGIN, TABLE_END = "<!-- chain-scaling-table:begin -->", "<!-- chain-scaling-table:end -->"


def table_lines(rows, command: str) -> list:
    """The stage table of docs/performance.md section 3 for ``rows`` of :func:`run`, and a line naming
    the ``command`` that measured them, the date and the machine's load."""
    def g(x):
        return "—" if not isinstance(x, (int, float)) or not math.isfinite(x) else f"{x:.3g}"
    lines = ["| N | states | load [s] | flatten [s] | analyse [s] | assemble [s] | codegen [s] | compile total [s] | "
             "estimate [s] | whole process [s], peak [MB] | rhs [µs/call] | Jacobian [µs/call] | run: per step [µs] "
             "(solver, steps) |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['N']} | {r['states']} | {g(r['load_s'])} | {g(r['flatten_s'])} | {g(r['analyse_s'])} | "
                     f"{g(r['assemble_s'])} | {g(r['codegen_s'])} | {g(r['compile_s'])} | {g(r['choose_s'])} | "
                     f"{g(r['process_s'])}, {r['process_rss_mb']:.0f} | {g(r['rhs_generated_us'])} | "
                     f"{g(r['jac_generated_us'])} | {g(r['per_step_us'])} ({r['sim_solver']}, {r['sim_steps']}) |")
    loads_ = [float(r["load_avg"]) for r in rows]
    lines += ["", f"Written by `{command}` on {time.strftime('%Y-%m-%d %H:%M')} at a load average of "
              f"{min(loads_):.1f}–{max(loads_):.1f}."]
    return lines


def write_report(text: str, lines) -> str:
    """``text`` (docs/performance.md) with the lines between its ``chain-scaling-table`` markers replaced."""
    begin, end = text.find(TABLE_BEGIN), text.find(TABLE_END)
    if begin < 0 or end < begin:
        raise SystemExit(f"{REPORT}: no {TABLE_BEGIN} … {TABLE_END} markers in section 3")
    return text[:begin + len(TABLE_BEGIN)] + "\n" + "\n".join(lines) + "\n" + text[end:]


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
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.6))
    ax = axes[0]
    for key, label, style in (("check_s", "check (flatten + analyse)", "o-"), ("assemble_s", "assemble", "s-"),
                              ("codegen_s", "codegen + compile", "^-"), ("compile_s", "total compile", "k*-"),
                              ("choose_s", "auto's stiffness estimate", "v-"),
                              ("process_s", "whole process (multipole simulate)", "kD--")):
        ax.loglog(N, [r[key] for r in rows], style, label=label)
    ref = rows[0]["compile_s"]
    ax.loglog(N, [ref * n / N[0] for n in N], ":", color="0.5", label="linear growth")
    ax.axhline(5.0, color="tab:red", lw=0.8, ls="--")
    ax.text(N[0], 5.6, " 5 s target for the whole process at N = 1000", color="tab:red", fontsize=8, va="bottom",
            ha="left")
    ax.set_xlabel("N (mass-spring pairs)")
    ax.set_ylabel("time [s]")
    ax.set_title("set-up: compile path, estimate, whole process", fontsize=10)
    ax.legend(fontsize=8, **LEGEND_BELOW)
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
    ax.legend(fontsize=8, **LEGEND_BELOW)
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("mass-spring chains: cost against model size (2N states)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


#: legends under the axes (inside, they covered curves)
LEGEND_BELOW = {"loc": "upper center", "bbox_to_anchor": (0.5, -0.14), "ncol": 2, "frameon": False}


def read_rows(path) -> list:
    """The rows of a chain_scaling.csv this script wrote (numbers as floats, empty cells as nan)."""
    import csv
    rows = []
    with open(path, newline="") as f:
        for raw in csv.DictReader(f):
            row = {}
            for k, v in raw.items():
                try:
                    row[k] = float(v) if v != "" else math.nan
                except ValueError:
                    row[k] = v
            rows.append(row)
    return rows


def run(sizes=(10, 100, 1000), out=ROOT / "docs" / "bench", figures=ROOT / "docs" / "figures", verbose=True,
        repeats=3):
    """Measure every size ``repeats`` times and keep, per size, the repeat whose compile time is the
    median (a whole repeat, so that its stage times add up); one untimed warm-up first (imports)."""
    rows = []
    measure(sizes[0])
    for n in sizes:
        runs = sorted((measure(n) for _ in range(repeats)), key=lambda r: r["compile_s"])
        row = runs[len(runs) // 2]
        row["process_s"], row["process_rss_mb"], _cpu = whole_process(n)
        row["load_avg"] = os.getloadavg()[0]       # other jobs on the machine: read the times with it
        rows.append(row)
        if verbose:
            print(f"N = {n:5d}: check {row['check_s']:.3g} s, compile {row['compile_s']:.3g} s, "
                  f"estimate {row['choose_s']:.3g} s, rhs {row['rhs_generated_us']:.3g} µs "
                  f"(hand {row['rhs_hand_us']:.3g} µs), whole process {row['process_s']:.3g} s, "
                  f"{row['process_rss_mb']:.0f} MB", flush=True)
    out, figures = Path(out), Path(figures)
    out.mkdir(parents=True, exist_ok=True)
    figures.mkdir(parents=True, exist_ok=True)
    write_rows(rows, FIELDS, out / "chain_scaling.csv")
    plot(rows, figures / "bench_chain_scaling.png")
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "docs" / "bench"))
    ap.add_argument("--estimate-only", type=int, nargs="+", metavar="N")
    ap.add_argument("--before", action="store_true", help="with --estimate-only: also dense eigvals")
    ap.add_argument("--stack", type=int, nargs="+", metavar="n", help="check + compile of the piezo stack only")
    ap.add_argument("--plot-only", action="store_true", help="redraw the figure from OUT/chain_scaling.csv")
    ap.add_argument("--process-only", type=int, nargs="+", metavar="N", help="whole process only (time, memory)")
    ap.add_argument("--c3", type=float, default=0.0, help="with --process-only: hardening springs [N/m^3]")
    ap.add_argument("--solver", default="auto", help="with --process-only: the solver")
    ap.add_argument("--report", action="store_true", help="also write the table of docs/performance.md section 3")
    args = ap.parse_args()
    if args.process_only:
        rows = []
        for n in args.process_only:
            wall, peak, cpu = whole_process(n, args.c3, args.solver)
            rows.append({"N": n, "wall": wall, "cpu": cpu})
            print(f"N = {n}, c3 = {args.c3:g}, {args.solver}: whole process {wall:.3g} s (CPU {cpu:.3g} s), "
                  f"peak {peak:.0f} MB, load {os.getloadavg()[0]:.1f}", flush=True)
        for key in ("wall", "cpu") if len(rows) > 1 else ():
            print(f"slope of {key}: " + ", ".join(f"{s:.2f}" for s in slopes(rows, key)))
        sys.exit(0)
    if args.plot_only:
        plot(read_rows(Path(args.out) / "chain_scaling.csv"), ROOT / "docs" / "figures" / "bench_chain_scaling.png")
        sys.exit(0)
    if args.stack:
        for n in args.stack:
            stack(n)
        sys.exit(0)
    if args.estimate_only:
        estimate_only(args.estimate_only, args.before)
        sys.exit(0)
    rows = run(args.sizes, args.out, repeats=args.repeats)
    if args.report:
        command = "python benchmarks/chain_scaling.py " + " ".join(sys.argv[1:])
        REPORT.write_text(write_report(REPORT.read_text(encoding="utf-8"), table_lines(rows, command)),
                          encoding="utf-8")
        print(f"wrote the table of {REPORT} section 3")
    for key in ("check_s", "compile_s", "choose_s", "rhs_generated_us", "rhs_hand_us", "per_step_us", "process_s"):
        print(f"slope of {key}: " + ", ".join(f"{s:.2f}" for s in slopes(rows, key)))
