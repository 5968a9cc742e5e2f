"""numba compile time of the generated model against its size, functions written whole (before) and
in chunks of bounded size (after, ``numba_backend.CHUNK_STATEMENTS``), and what the chunks cost per
call (docs/performance.md, "numba compile time against model size").

Models: chains of N mass-spring pairs (``multipole_models.mass_spring_chain``, 2N states) and the
piezo stack ``diagrams/weber/piezo_stack.yaml`` with n discs.  For each model and each way of
writing it, a fresh process with an empty model cache loads the generated module through
``numba_backend.load`` (numba compiles every cfunc and saves it in its cache): its CPU time (one
core: the figure that depends least on other jobs) and wall time; then, in the same process, the
right-hand side and the Jacobian are called through their addresses in a compiled loop (as the
integrator calls them), medians with [lowest-highest] of 5 rounds; a second process loads the
module from the cache the first one wrote.  "before" is skipped above ``--before-max`` states (it
takes minutes).  Log-log slopes of the compile CPU time against the states and the source cost.

    python benchmarks/numba_compile_scaling.py [--chains 50 150 300 600] [--stacks 20 100]
                                               [--before-max 300] [--calls 2000]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STACK = ROOT / "diagrams" / "weber" / "piezo_stack.yaml"
#: wall-time limit of one compile [s]: a "before" compile that takes longer is reported as such
TIMEOUT = 240


def child(path: str, n: int, calls: int) -> None:
    """Load the module in ``path`` (compiling it unless cached) and time calls of rhs and jac."""
    import numpy as np
    from numba import njit

    from multipole.backends import numba_backend as nb
    from multipole.backends.numba_kernels import call_model
    source = Path(path).read_text(encoding="utf-8")
    cpu, wall = time.process_time(), time.perf_counter()
    module = nb.load(source)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    hits = all(f.cache_hits for f in (module.rhs, module.jac))

    @njit
    def loop(address, count, x, out, w):
        acc = 0.0
        for i in range(count):
            call_model(address, 1e-6 * i, x, out, w)
            acc += out.ravel()[0]
        return acc

    x, w = np.linspace(-1e-3, 1e-3, n), np.zeros(module.N_WORK)
    per_call = {}
    for name, shape in (("rhs", (n,)), ("jac", (n, n))):
        out = np.zeros(shape)
        address = getattr(module, name).address
        loop(address, 1, x, out, w)
        count = calls if name == "rhs" else max(1, calls // max(1, n // 10))
        times = []
        for _ in range(5):
            start = time.process_time()
            loop(address, count, x, out, w)
            times.append((time.process_time() - start) / count * 1e6)
        per_call[name] = (statistics.median(times), min(times), max(times))
    print(json.dumps({"cpu": cpu, "wall": wall, "cached": hits, "per_call": per_call}))


def models(chains, stacks) -> list:
    """(family, label, scene text, file name) of every model measured."""
    from multipole_models import mass_spring_chain
    out = [("chain", f"mass-spring chain, {n} pairs", mass_spring_chain(n, t_end=0.01), "chain.yaml") for n in chains]
    base = STACK.read_text(encoding="utf-8")
    out += [("stack", f"piezo_stack n = {n}", base.replace("n: 10,", f"n: {n},"), "piezo_stack.yaml")
            for n in stacks]
    return out


def measure(path: Path, n: int, calls: int) -> dict | None:
    """Compile in a fresh process with an empty cache, then load from that cache in another."""
    env = dict(os.environ, MULTIPOLE_CACHE=tempfile.mkdtemp(prefix="p6-bench-"))
    cmd = [sys.executable, __file__, "--child", str(path), str(n), str(calls)]
    try:
        first = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=TIMEOUT, check=True)
    except subprocess.TimeoutExpired:
        return None
    second = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=TIMEOUT, check=True)
    res = json.loads(first.stdout.strip().splitlines()[-1])
    again = json.loads(second.stdout.strip().splitlines()[-1])
    res["cached_load"], res["cache_hit"] = again["cpu"], again["cached"]
    return res


def slope(points) -> str:
    """Log-log slope between the first and the last point ``(x, y)``."""
    if len(points) < 2:
        return "—"
    (x0, y0), (x1, y1) = points[0], points[-1]
    return f"{math.log(y1 / y0) / math.log(x1 / x0):.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", type=int, nargs="*", default=[50, 150, 300, 600])
    ap.add_argument("--stacks", type=int, nargs="*", default=[20, 100])
    ap.add_argument("--before-max", type=int, default=300, help="largest model (states) compiled whole")
    ap.add_argument("--calls", type=int, default=20000, help="rhs calls per timing round")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child[0], int(args.child[1]), int(args.child[2]))
        return
    from multipole import pipeline
    from multipole.backends import numba_backend as nb
    from multipole.netlist import loads
    folder = Path(tempfile.mkdtemp(prefix="p6-src-"))
    print("| model | states | cost | functions before / after | compile CPU before [s] | compile CPU after [s] | "
          "wall after [s] | cached load after [s] | rhs call before / after [µs] | jac call before / after [µs] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    series: dict = {}
    for family, label, text, name in models(args.chains, args.stacks):
        eq, outs, _ = pipeline.pruned(loads(text, name))
        n = len(eq.states)
        row = {}
        for way, limit in (("before", 10**9), ("after", nb.CHUNK_STATEMENTS)):
            saved = nb.CHUNK_STATEMENTS
            nb.CHUNK_STATEMENTS = limit
            try:
                source, _ = nb.generate(eq, outs)
            finally:
                nb.CHUNK_STATEMENTS = saved
            path = folder / f"{way}_{abs(hash(label))}.py"
            path.write_text(source, encoding="utf-8")
            functions = source.count("\ndef ")
            if way == "before" and n > args.before_max:
                row[way] = (functions, None, nb.source_cost(source))
                continue
            row[way] = (functions, measure(path, n, args.calls), nb.source_cost(source))
            print(f"  {label}, {way}: {row[way]}", file=sys.stderr, flush=True)
        b, a = row["before"][1], row["after"][1]
        cost = row["after"][2]
        if b is not None:
            series.setdefault((family, "before"), []).append((n, b["cpu"]))
            series.setdefault((family, "before", "cost"), []).append((row["before"][2], b["cpu"]))
        series.setdefault((family, "after"), []).append((n, a["cpu"]))
        series.setdefault((family, "after", "cost"), []).append((cost, a["cpu"]))

        def call(r, key):
            return f"{r['per_call'][key][0]:.3g}" if r else "—"
        before_cpu = f"{b['cpu']:.1f}" if b else ("not run" if n > args.before_max else f"> {TIMEOUT} wall")
        print(f"| {label} | {n} | {cost:,} | {row['before'][0]} / {row['after'][0]} | {before_cpu} | {a['cpu']:.1f} | "
              f"{a['wall']:.1f} | {a['cached_load']:.2f}{'' if a['cache_hit'] else ' (miss!)'} | "
              f"{call(b, 'rhs')} / {call(a, 'rhs')} | {call(b, 'jac')} / {call(a, 'jac')} |", flush=True)
    print()
    for family in ("chain", "stack"):
        if (family, "after") in series:
            print(f"{family}s: log-log slope of compile CPU time (first to last measured) against states: before "
                  f"{slope(series.get((family, 'before'), []))}, after {slope(series[family, 'after'])}; against "
                  f"cost: before {slope(series.get((family, 'before', 'cost'), []))}, after "
                  f"{slope(series[family, 'after', 'cost'])}")
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
