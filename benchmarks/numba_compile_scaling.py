"""numba compile time of the generated model against its size, functions written whole (before) and
in chunks of bounded size (after, ``numba_backend.CHUNK_STATEMENTS``), and what the chunks cost per
call (docs/performance.md, "numba compile time against model size").

Models: chains of N mass-spring pairs (``multipole_models.mass_spring_chain``, 2N states) and the
piezo stack ``diagrams/weber/piezo_stack.yaml`` with n discs.  For each model and each way of
writing it, a fresh process with an empty model cache loads the generated module through
``numba_backend.load`` (numba compiles every cfunc and saves it in its cache): its CPU time (one
core: the figure that depends least on other jobs; stopped at ``CPU_LIMIT``) and wall time; a
second process loads the module from the cache the first one wrote.  "before" is skipped above
``--before-max`` states.  Log-log slopes of the compile CPU time against the states and the
source cost.  ``--per-call`` times the right-hand side and the Jacobian of chains, whole against
chunks, in one process, alternately, called through their addresses in a compiled loop as the
integrator calls them.

    python benchmarks/numba_compile_scaling.py [--chains 50 150 300 600] [--stacks 20 100]
                                               [--before-max 300]
    python benchmarks/numba_compile_scaling.py --per-call 50 150     # rhs and jac per call, A B A B
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STACK = ROOT / "diagrams" / "weber" / "piezo_stack.yaml"
#: CPU-time limit of one compiling process [s] (a "before" compile that takes longer is reported as
#: such), and the wall-time limit (the machine may be shared)
CPU_LIMIT = 120
TIMEOUT = 1200


def _cpu_limit() -> None:
    resource.setrlimit(resource.RLIMIT_CPU, (CPU_LIMIT, CPU_LIMIT + 5))


def child(path: str) -> None:
    """Load the module in ``path``, compiling it unless numba's cache has it: CPU and wall time."""
    from multipole.backends import numba_backend as nb
    source = Path(path).read_text(encoding="utf-8")
    cpu, wall = time.process_time(), time.perf_counter()
    module = nb.load(source)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    hits = all(f.cache_hits for f in (module.rhs, module.jac))
    print(json.dumps({"cpu": cpu, "wall": wall, "cached": hits}))


def per_call(pairs: int, rounds: int = 7) -> None:
    """Time per call of rhs and jac of the ``pairs`` chain, written whole and in chunks, loaded in this
    process and called alternately (A B A B ...) through their addresses in a compiled loop, each
    round at least 0.1 s of CPU time; medians with [lowest-highest]."""
    import numpy as np
    from numba import njit

    from multipole import pipeline
    from multipole.backends import numba_backend as nb
    from multipole.backends.numba_kernels import call_model
    from multipole.netlist import loads
    from multipole_models import mass_spring_chain

    @njit
    def loop(address, count, x, out, w):
        acc = 0.0
        for i in range(count):
            call_model(address, 1e-6 * i, x, out, w)
            acc += out.ravel()[i % out.size]
        return acc

    eq, outs, _ = pipeline.pruned(loads(mass_spring_chain(pairs, t_end=0.01), "chain.yaml"))
    n = len(eq.states)
    modules = {}
    for way, limit in (("whole", 10**9), ("chunks", nb.CHUNK_STATEMENTS)):
        saved, nb.CHUNK_STATEMENTS = nb.CHUNK_STATEMENTS, limit
        try:
            modules[way] = nb.load(nb.generate(eq, outs)[0])
        finally:
            nb.CHUNK_STATEMENTS = saved
    x = np.linspace(-1e-3, 1e-3, n)
    for name, shape in (("rhs", (n,)), ("jac", (n, n))):
        args = {way: (getattr(m, name).address, np.zeros(shape), np.zeros(m.N_WORK)) for way, m in modules.items()}
        sums = {way: loop(a, 3, x, o, w) for way, (a, o, w) in args.items()}
        assert sums["whole"] == sums["chunks"], sums           # the same values, bit for bit
        count, elapsed = 1, 0.0
        while elapsed < 0.1:
            count *= 2
            start = time.process_time()
            loop(args["whole"][0], count, x, args["whole"][1], args["whole"][2])
            elapsed = time.process_time() - start
        times: dict = {way: [] for way in args}
        for _ in range(rounds):
            for way, (a, o, w) in args.items():
                start = time.process_time()
                loop(a, count, x, o, w)
                times[way].append((time.process_time() - start) / count * 1e9)
        med = {way: statistics.median(v) for way, v in times.items()}
        print(f"chain of {pairs} pairs, {name}: " + ", ".join(
            f"{way} {med[way]:.4g} ns [{min(v):.4g}-{max(v):.4g}]" for way, v in times.items())
            + f"; chunks / whole {med['chunks'] / med['whole']:.3f}", flush=True)


def models(chains, stacks) -> list:
    """(family, label, scene text, file name) of every model measured."""
    from multipole_models import mass_spring_chain
    out = [("chain", f"mass-spring chain, {n} pairs", mass_spring_chain(n, t_end=0.01), "chain.yaml") for n in chains]
    base = STACK.read_text(encoding="utf-8")
    out += [("stack", f"piezo_stack n = {n}", base.replace("n: 10,", f"n: {n},"), "piezo_stack.yaml")
            for n in stacks]
    return out


def measure(path: Path) -> dict | None:
    """Compile in a fresh process with an empty cache, then load from that cache in another."""
    env = dict(os.environ, MULTIPOLE_CACHE=tempfile.mkdtemp(prefix="p6-bench-"))
    cmd = [sys.executable, __file__, "--child", str(path)]
    first = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=TIMEOUT, preexec_fn=_cpu_limit)
    if first.returncode != 0:         # killed at the CPU limit
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
    ap.add_argument("--per-call", type=int, nargs="*", metavar="PAIRS",
                    help="only the time per call of rhs and jac, whole against chunks, on these chains")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.per_call:
        for pairs in args.per_call:
            per_call(pairs)
        return
    if args.child:
        child(args.child)
        return
    from multipole import pipeline
    from multipole.backends import numba_backend as nb
    from multipole.netlist import loads
    folder = Path(tempfile.mkdtemp(prefix="p6-src-"))
    print("| model | states | cost before / after | functions before / after | compile CPU before [s] | "
          "compile CPU after [s] | wall before / after [s] | cached load after [s] |")
    print("|---|---|---|---|---|---|---|---|")
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
            row[way] = (functions, measure(path), nb.source_cost(source))
            print(f"  {label}, {way}: {row[way]}", file=sys.stderr, flush=True)
        b, a = row["before"][1], row["after"][1]
        cost = row["after"][2]
        if b is not None:
            series.setdefault((family, "before"), []).append((n, b["cpu"]))
            series.setdefault((family, "before", "cost"), []).append((row["before"][2], b["cpu"]))
        series.setdefault((family, "after"), []).append((n, a["cpu"]))
        series.setdefault((family, "after", "cost"), []).append((cost, a["cpu"]))

        before_cpu = f"{b['cpu']:.1f}" if b else ("not run" if n > args.before_max else f"> {CPU_LIMIT}")
        before_wall = f"{b['wall']:.1f}" if b else "—"
        print(f"| {label} | {n} | {row['before'][2]:,} / {cost:,} | {row['before'][0]} / {row['after'][0]} | "
              f"{before_cpu} | {a['cpu']:.1f} | {before_wall} / {a['wall']:.1f} | "
              f"{a['cached_load']:.2f}{'' if a['cache_hit'] else ' (miss!)'} |", flush=True)
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
