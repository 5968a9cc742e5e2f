"""Linkage benchmarks (docs/performance.md, "Linkages"): the torque-driven four-bar of
tests/test_linkage_dynamics.py and a torque-driven slider-crank.

1. Cost per right-hand-side call, both scenes: the generated model (numpy backend: Python code;
   numba backend: compiled) against a hand-written closed-form right-hand side in the same language
   (minimal coordinate: the crank angle; four-bar: coupler and rocker from the circle intersection;
   slider-crank: the rod's sine from the pin height, the travel by one square root; the reduced
   inertia and its velocity terms by virtual power), in Python floats (no numpy scalar or array).
   Each call at a new state (the crank angle moved by 1e-9 rad, at most 1e-6 from the start: a
   closure solved by Newton's method then starts 1e-9 to 1e-6 off and takes 2 iterations, as in a
   run at rtol 1e-9; one solved by formula does not iterate), CPU time, the two timed interleaved,
   medians of 7 rounds; in Python each result converted by ``np.asarray`` as scipy's ``solve_ivp``
   converts it (``--per-call-only``: only this part).
2. Whole runs at equal error: `multipole` with the numba backend against the hand-written model
   under scipy's solve_ivp (RK45, DOP853 and LSODA; at each error the fastest), each over a ladder
   of tolerances; error = max |crank angle - reference| over the output grid (reference: the hand
   model at rtol 1e-13); timed twice: one run of each contender per round (each right after the
   others') and 3 runs in a row per round, the last timed (``--equal-error-only``: only this).
3. check + model build (CPU time, an empty cache) of the scenes in diagrams/linkages/.

    python benchmarks/linkage_bench.py

4. Only import, check and model build of one scene in fresh processes, optionally interleaved with
   another checkout (the 8-link target, docs/performance.md "Linkages"):

    git archive fbbbfaa | tar -x -C /tmp/mp-before        # an empty folder
    python benchmarks/linkage_bench.py --fresh diagrams/linkages/eight_link.yaml --before /tmp/mp-before
"""
from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parents[1]
L, L1, L2, BX = 0.2, 0.6, 0.5, 0.7
M = (1.0, 2.0, 1.5)
J = (0.01, 0.06, 0.03)
G, TAU, PHI0, T_END = 9.81, 0.8, 0.3, 2.0

SCENE = f"""
name: fourbar_torque
elements:
  src: {{type: torque_source, value: {TAU}}}
  crank: {{type: DAN, l: {L}, phi0: {PHI0}, m: {M[0]}, J: {J[0]}}}
  rocker: {{type: DDD, l1: {L1}, l2: {L2}, K: 1, m1: {M[1]}, J1: {J[1]}, m2: {M[2]}, J2: {J[2]}, x2: {BX}}}
connections:
  - [src.p, crank.drive]
  - [crank.b, rocker.a1]
outputs: [crank.phi]
simulate: {{t_end: {T_END}, dt_out: 0.01}}
"""


def hand_rhs(t, y):
    """Closed-form four-bar: y = (theta, omega); dependent angles from the circle intersection."""
    th, w = y.tolist()                 # Python floats: numpy scalars make every operation slower
    return [w, hand_accel(th, w)]


def hand_accel(th, w):
    """Crank acceleration [rad/s^2] at crank angle ``th`` [rad] and rate ``w`` [rad/s] (scalar code,
    also compiled by numba for the per-call comparison)."""
    c, s = math.cos(th), math.sin(th)
    ax, ay = L * c, L * s
    dx, dy = BX - ax, -ay
    d2 = dx * dx + dy * dy
    d = math.sqrt(d2)
    along = (L1 * L1 - L2 * L2 + d2) / (2 * d)
    across = math.sqrt(L1 * L1 - along * along)
    ux, uy = dx / d, dy / d
    px, py = ax + along * ux - across * uy, ay + along * uy + across * ux
    # the links' directions as unit vectors (no atan2 and sine/cosine of the angle again)
    c1, s1, c2, s2 = (px - ax) / L1, (py - ay) / L1, (px - BX) / L2, py / L2
    # velocity ratios k1 = dp1/dth, k2 = dp2/dth: L1 n1 k1 - L2 n2 k2 = -L n(th)
    det = L1 * L2 * (s1 * c2 - c1 * s2)
    rx, ry = L * s, -L * c                      # -L n(th)
    k1 = (rx * (-L2 * c2) - ry * (-L2 * -s2)) / det
    k2 = (L1 * -s1 * ry - L1 * c1 * rx) / det
    # accelerations at zero crank acceleration: bias b1, b2 (same matrix, rhs of centripetal terms)
    bx = L * w * w * c + L1 * (k1 * w) ** 2 * c1 - L2 * (k2 * w) ** 2 * c2
    by = L * w * w * s + L1 * (k1 * w) ** 2 * s1 - L2 * (k2 * w) ** 2 * s2
    b1 = (bx * (-L2 * c2) - by * (-L2 * -s2)) / det
    b2 = (L1 * -s1 * by - L1 * c1 * bx) / det
    # centres of mass: Jacobians JS = dr_S/dth and biases of their accelerations
    jc = (-0.5 * L * s, 0.5 * L * c)
    bc = (-0.5 * L * w * w * c, -0.5 * L * w * w * s)
    j1 = (-L * s - 0.5 * L1 * s1 * k1, L * c + 0.5 * L1 * c1 * k1)
    w1 = k1 * w
    b_1 = (-L * w * w * c - 0.5 * L1 * (s1 * b1 + c1 * w1 * w1), -L * w * w * s + 0.5 * L1 * (c1 * b1 - s1 * w1 * w1))
    j2 = (-0.5 * L2 * s2 * k2, 0.5 * L2 * c2 * k2)
    w2 = k2 * w
    b_2 = (-0.5 * L2 * (s2 * b2 + c2 * w2 * w2), 0.5 * L2 * (c2 * b2 - s2 * w2 * w2))
    mass = J[0] + J[1] * k1 * k1 + J[2] * k2 * k2
    force = TAU - J[1] * k1 * b1 - J[2] * k2 * b2
    for m, (jx, jy), (ex, ey) in zip(M, (jc, j1, j2), (bc, b_1, b_2)):
        mass += m * (jx * jx + jy * jy)
        force += -m * (jx * ex + jy * ey) - m * G * jy
    return force / mass


# -- the slider-crank (DAN + DDS): crank R about the origin, rod LR, pin P at the height E above the
# slide line (the x axis through the frame-fixed guide anchor), driven by the constant torque TAU_SC
R, LR, E = 0.1, 0.35, 0.02
M_SC, J_SC = (0.5, 0.8, 1.2), (0.002, 0.01)        # crank, rod, slider masses; crank, rod inertias
TAU_SC = 0.5

SCENE_SC = f"""
name: slider_crank_torque
elements:
  src: {{type: torque_source, value: {TAU_SC}}}
  crank: {{type: DAN, l: {R}, phi0: {PHI0}, m: {M_SC[0]}, J: {J_SC[0]}}}
  rod: {{type: DDS, l: {LR}, v: {E}, K: 1, mL: {M_SC[1]}, JL: {J_SC[1]}, mS: {M_SC[2]}, JS: 0.001}}
connections:
  - [src.p, crank.drive]
  - [crank.b, rod.a1]
outputs: [crank.phi, rod.x]
simulate: {{t_end: {T_END}, dt_out: 0.01}}
"""


def hand_rhs_sc(t, y):
    """Closed-form slider-crank: y = (theta, omega)."""
    th, w = y.tolist()
    return [w, hand_accel_sc(th, w)]


def hand_accel_sc(th, w):
    """Crank acceleration [rad/s^2] of the slider-crank at crank angle ``th`` [rad] and rate ``w``
    [rad/s]: the rod angle phi from the pin height (A - P = LR (cos phi, sin phi), P beyond the
    crank pin: cos phi < 0), the travel x = R cos th - LR cos phi."""
    c, s = math.cos(th), math.sin(th)
    sl = (R * s - E) / LR
    cl = -math.sqrt(1.0 - sl * sl)
    k1 = R * c / (LR * cl)                                   # dphi/dth
    b1 = (-R * s * w * w / LR + sl * (k1 * w) ** 2) / cl     # phi'' at zero crank acceleration
    kx = -R * s + LR * sl * k1                               # dx/dth
    bx = -R * c * w * w + LR * cl * (k1 * w) ** 2 + LR * sl * b1
    jcx, jcy, bcx, bcy = -0.5 * R * s, 0.5 * R * c, -0.5 * R * c * w * w, -0.5 * R * s * w * w
    jlx, jly = 0.5 * (-R * s + kx), 0.5 * R * c             # rod centre: midway between A and P
    blx, bly = 0.5 * (-R * c * w * w + bx), -0.5 * R * s * w * w
    mass = (J_SC[0] + M_SC[0] * (jcx * jcx + jcy * jcy) + J_SC[1] * k1 * k1
            + M_SC[1] * (jlx * jlx + jly * jly) + M_SC[2] * kx * kx)
    force = (TAU_SC - M_SC[0] * (jcx * bcx + jcy * bcy + G * jcy) - J_SC[1] * k1 * b1
             - M_SC[1] * (jlx * blx + jly * bly + G * jly) - M_SC[2] * kx * bx)
    return force / mass


#: per-call scenes: name, netlist, hand right-hand side, hand acceleration (scalar code)
PER_CALL = (("four-bar", SCENE, hand_rhs, hand_accel), ("slider-crank", SCENE_SC, hand_rhs_sc, hand_accel_sc))


def _cpu_per_call(fun, x, n):
    """CPU time per call of ``np.asarray(fun(0, x))`` [s] over ``n`` calls, each at a new state
    (``x[0]`` moved by 1e-9: the integrated start of the position closure is then off the closure, as
    in a run).  The result is converted as scipy's ``solve_ivp`` converts every right-hand side's
    (``np.asarray(fun(t, y))``): the hand model returns a list, whose conversion the solver pays; the
    generated model returns an array already."""
    x = np.array(x, dtype=float)
    asarray = np.asarray
    t0 = time.process_time()
    for _ in range(n):
        x[0] += 1e-9
        asarray(fun(0.0, x))
    return (time.process_time() - t0) / n


def per_call(rounds=7, n=1000):
    """``[(scene, code, generated [s], hand-written [s], ratio, spread, Newton iterations per call)]``:
    medians over ``rounds`` interleaved rounds of CPU time per call; the spread is the ratio's lowest
    and highest over the rounds."""
    import multipole as mp
    from multipole import pipeline
    rows = []
    for name, scene, rhs, accel in PER_CALL:
        sc = mp.loads(scene, "scene.yaml")
        model = pipeline.model(sc)
        x = np.array(model.x0, dtype=float)
        y = np.array([PHI0, 0.0])
        times = {"generated": [], "hand": []}
        model.reset_stats()
        for _ in range(rounds):                            # interleaved: A B A B ...
            times["generated"].append(_cpu_per_call(model.rhs, x, n))
            times["hand"].append(_cpu_per_call(rhs, y, n))
        its = model.stats["newton_iterations"] / max(model.stats["newton_solves"], 1)   # 0: closures by formula
        rows.append((name, "Python (numpy backend)") + _summary(times) + (its,))
        rows.append((name, "numba (compiled loop)") + per_call_compiled(sc, accel))
    return rows


def _summary(times):
    gen, hand = np.array(times["generated"]), np.array(times["hand"])
    ratios = gen / hand
    return float(np.median(gen)), float(np.median(hand)), float(np.median(ratios)), (float(ratios.min()),
                                                                                     float(ratios.max()))


def per_call_compiled(sc, hand, n=200_000, rounds=7):
    """Generated right-hand side (numba backend: a cfunc called through its address, as the
    compiled integrator calls it) against the hand-written scalar code ``hand`` compiled by numba,
    each called ``n`` times in a compiled loop; rounds interleaved, medians of CPU time per call [s],
    and the generated code's Newton iterations per call."""
    import numba
    from multipole import pipeline
    from multipole.backends import numba_backend, numba_kernels as K
    eq, outs, _ = pipeline.pruned(sc)
    m = numba_backend.run.compile(eq, outs)
    accel = numba.njit(hand)

    @numba.njit
    def loop_generated(address, n, x, out, w):
        acc = 0.0
        start = x[0]
        for i in range(n):
            x[0] = start + 1e-9 * (i & 1023)     # a new state each call, at most 1e-6 from the start
            K.call_model(address, 0.0, x, out, w)
            acc += out[1]
        return acc

    @numba.njit
    def loop_hand(n, x, out):
        acc = 0.0
        start = x[0]
        for i in range(n):
            x[0] = start + 1e-9 * (i & 1023)
            out[0] = x[1]
            out[1] = accel(x[0], x[1])
            acc += out[1]
        return acc
    x0, y0 = np.array(m.x0, dtype=float), np.array([PHI0, 0.0])
    w = np.zeros(m.module.N_WORK)
    runs = {"generated": lambda: loop_generated(m.module.rhs.address, n, x0.copy(), np.zeros(len(x0)), w),
            "hand": lambda: loop_hand(n, y0.copy(), np.zeros(2))}
    times = {k: [] for k in runs}
    for fn in runs.values():
        fn()                                   # compile
    w[:] = 0.0
    for _ in range(rounds):                    # interleaved: A B A B ...
        for k, fn in runs.items():
            t0 = time.process_time()
            fn()
            times[k].append((time.process_time() - t0) / n)
    return _summary(times) + (w[0] / max(w[1], 1.0),)   # w[0], w[1]: Newton iterations, solves (numba_kernels.W_HEAD)


#: the hand model's scipy methods (the comparison takes the fastest at each error) and the ladder of
#: relative tolerances every contender runs (atol = rtol/100)
HAND_METHODS = ("RK45", "DOP853", "LSODA")
LADDER = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)


def equal_error(repeat=1, rounds=5, rtols=LADDER, methods=HAND_METHODS):
    """``{contender: [(rtol, error, CPU median [s], (lowest, highest))]}``: the hand model under
    ``solve_ivp`` with each of ``methods`` (contender ``hand METHOD``) and the numba backend
    (``numba``: a warm ``pipeline.run``, equations and compiled model remembered), each over the
    ladder ``rtols``; error = max |crank angle - reference| on the 201-point output grid (reference:
    the hand model, DOP853 at rtol 1e-13).  Per rung ``rounds`` rounds, each running the
    contenders in turn (interleaved); in a round a contender runs ``repeat`` times in a row and the
    last run's CPU time counts: ``repeat=1`` is one run right after the other contenders' runs
    (scipy's code and data in the caches: a run after other Python work), ``repeat=3`` a user
    calling the same run again and again (as ``timeit`` does)."""
    import functools
    import multipole as mp
    from multipole import pipeline
    t_eval = np.linspace(0, T_END, 201)
    ref = solve_ivp(hand_rhs, (0, T_END), [PHI0, 0.0], method="DOP853", rtol=1e-13, atol=1e-13,
                    t_eval=t_eval).y[0]
    sc = mp.loads(SCENE, "fourbar.yaml")

    def hand(method, rtol):
        return solve_ivp(hand_rhs, (0, T_END), [PHI0, 0.0], method=method, rtol=rtol, atol=rtol * 1e-2,
                         t_eval=t_eval).y[0]

    def numba(rtol):
        return pipeline.run(sc, rtol=rtol, atol=rtol * 1e-2, dt_out=0.01, backend="numba", progress=False)["crank.phi"]
    runs = {f"hand {m}": functools.partial(hand, m) for m in methods}
    runs["numba"] = numba
    numba(rtols[0])                                    # compiled (or loaded from numba's cache) once, not timed
    out = {who: [] for who in runs}
    for rtol in rtols:
        samples = {who: [] for who in runs}
        err = {}
        for _ in range(rounds):
            for who, fn in runs.items():
                for _ in range(repeat):
                    t0 = time.process_time()
                    phi = fn(rtol)
                    cpu = time.process_time() - t0
                samples[who].append(cpu)
                err[who] = float(np.abs(phi - ref).max())
        for who, v in samples.items():
            out[who].append((rtol, err[who], float(np.median(v)), (float(np.min(v)), float(np.max(v)))))
    return out


def _cpu_at(ladder, target, cpu=lambda rung: rung[2]):
    """CPU time [s] at error ``target`` interpolated linearly in log(error)-log(CPU) between the
    rungs of ``ladder`` (``cpu(rung)`` of each); None outside the ladder's errors."""
    pts = sorted((math.log(rung[1]), math.log(cpu(rung))) for rung in ladder)
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    lt = math.log(target)
    return math.exp(float(np.interp(lt, xs, ys))) if xs[0] <= lt <= xs[-1] else None


def at_equal_error(ladders, targets=(1e-6, 1e-8, 1e-9)):
    """``[(error, fastest hand method, its CPU, numba CPU, numba CPU of its slowest rounds)]`` [s]:
    each contender's CPU time at the same error (:func:`_cpu_at`), the hand model's with the method
    fastest there; a target outside numba's ladder or every hand method's is left out."""
    rows = []
    for target in targets:
        hand = {who.split(" ", 1)[1]: _cpu_at(ladder, target) for who, ladder in ladders.items() if who != "numba"}
        hand = {m: c for m, c in hand.items() if c is not None}
        numba = _cpu_at(ladders["numba"], target)
        if hand and numba is not None:
            best = min(hand, key=hand.get)
            rows.append((target, best, hand[best], numba, _cpu_at(ladders["numba"], target, lambda r: r[3][1])))
    return rows


def print_equal_error(rounds=5):
    """The whole-run tables of :func:`equal_error`, single interleaved runs and 3 runs in a row."""
    for repeat, what in ((1, "one run per round, each right after the other contenders' runs"),
                         (3, "3 runs in a row per round, the last timed")):
        ladders = equal_error(repeat, rounds)
        print(f"\n## whole runs, {what} (crank angle over 2 s, CPU time, contenders interleaved, medians of "
              f"{rounds} [lowest-highest])")
        print("| rtol | " + " | ".join(f"{who}: error, CPU [ms]" for who in ladders) + " |")
        print("| --- |" + " --- |" * len(ladders))
        for i, rtol in enumerate(ladders["numba"]):
            cells = [f"{r[1]:.1e}, {r[2] * 1e3:.3g} [{r[3][0] * 1e3:.3g}-{r[3][1] * 1e3:.3g}]"
                     for r in (ladder[i] for ladder in ladders.values())]
            print(f"| {rtol[0]:.0e} | " + " | ".join(cells) + " |")
        print(f"\n### at equal error ({what}; CPU interpolated log-log along each ladder)")
        print("| error | fastest hand method | hand [ms] | numba [ms] | hand / numba | with numba's slowest rounds |")
        print("| --- | --- | --- | --- | --- | --- |")
        for target, method, hand, numba, slowest in at_equal_error(ladders):
            print(f"| {target:.0e} | {method} | {hand * 1e3:.3g} | {numba * 1e3:.3g} | {hand / numba:.0f} | "
                  f"{hand / slowest:.0f} |")


def check_compile():
    import multipole as mp
    from multipole import pipeline
    rows = []
    for path in sorted((ROOT / "diagrams" / "linkages").glob("*.yaml")):
        os.environ["MULTIPOLE_CACHE"] = tempfile.mkdtemp()
        t0 = time.process_time()
        sc = mp.load(path)
        pipeline.check(sc)
        t1 = time.process_time()
        pipeline.model(sc)
        rows.append((path.name, t1 - t0, time.process_time() - t1))
    return rows


#: one fresh process (argv: the scene): CPU time [s] of the import, the check and the model build
_PROCESS = """
import os, sys, tempfile, time
os.environ["MULTIPOLE_CACHE"] = tempfile.mkdtemp()
t0 = time.process_time()
import multipole as mp
from multipole import pipeline
t1 = time.process_time()
sc = mp.load(sys.argv[1])
pipeline.check(sc)
t2 = time.process_time()
pipeline.model(sc)
t3 = time.process_time()
print(t1 - t0, t2 - t1, t3 - t2)
"""


def fresh_processes(scene, repeats=7, before=None):
    """``{tree: [(import, check, model build) CPU time [s] per process]}``: ``repeats`` fresh processes
    (an empty cache each, so what ``multipole check`` and a first run pay) for this checkout and,
    with ``before`` (the root of another checkout, e.g. ``git archive <commit> | tar -x -C DIR``),
    for that one too, the two interleaved (the same load).  A relative ``scene`` is each tree's own."""
    import subprocess
    import sys
    trees = {"this checkout": ROOT}
    if before is not None:
        trees = {f"before ({before})": Path(before), **trees}
    out = {name: [] for name in trees}
    for _ in range(repeats):
        for name, root in trees.items():
            env = dict(os.environ, PYTHONPATH=str(root))
            res = subprocess.run([sys.executable, "-c", _PROCESS, str(scene)], capture_output=True, text=True,
                                 env=env, cwd=root, check=True)
            out[name].append(tuple(float(v) for v in res.stdout.split()))
    return out


def print_fresh_processes(scene, repeats, before):
    print(f"## {Path(scene).name}: fresh processes, empty cache, CPU time, medians of {repeats} [lowest-highest]")
    print("| tree | import [s] | check [s] | model build [s] | check + build [s] | import + check + build [s] |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, rows in fresh_processes(scene, repeats, before).items():   # a relative SCENE: each tree's own
        a = np.array(rows)
        cols = [a[:, 0], a[:, 1], a[:, 2], a[:, 1] + a[:, 2], a.sum(axis=1)]
        print(f"| {name} | " + " | ".join(f"{np.median(c):.2f} [{c.min():.2f}-{c.max():.2f}]" for c in cols) + " |")


def main():
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fresh", metavar="SCENE", help="only time import, check and model build of SCENE in "
                        "fresh processes (e.g. diagrams/linkages/eight_link.yaml)")
    parser.add_argument("--repeats", type=int, default=7, help="processes per tree with --fresh (default 7)")
    parser.add_argument("--before", metavar="DIR", help="with --fresh: also time the checkout at DIR, interleaved")
    parser.add_argument("--per-call-only", action="store_true", help="only the cost per right-hand-side call")
    parser.add_argument("--equal-error-only", action="store_true", help="only the whole runs at equal error (~15 s)")
    args = parser.parse_args()
    if args.fresh:
        print_fresh_processes(args.fresh, args.repeats, args.before)
        return
    if args.equal_error_only:
        print_equal_error()
        return
    print("## cost per right-hand-side call (torque-driven four-bar and slider-crank, CPU time, interleaved, "
          "medians of 7)")
    print("| scene | code | generated [µs] | hand-written [µs] | generated / hand [lowest-highest] | "
          "Newton iterations per call |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, lang, gen, hand, ratio, (lo, hi), its in per_call():
        print(f"| {name} | {lang} | {gen * 1e6:.3g} | {hand * 1e6:.3g} | {ratio:.2f} [{lo:.2f}-{hi:.2f}] | {its:.2f} |")
    if args.per_call_only:
        return
    print_equal_error()
    print("\n## check and model build (numpy backend's code), new cache, CPU time")
    print("| scene | check [s] | compile [s] |")
    print("| --- | --- | --- |")
    for name, tc, tm in check_compile():
        print(f"| {name} | {tc:.2f} | {tm:.2f} |")


if __name__ == "__main__":
    main()
