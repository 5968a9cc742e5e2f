"""Machine limit of the compiled integrator loop (issue 11; docs/performance.md, "Machine limit").

For each scene: the hand-written scipy model of the bench (``multipole_models``, ``solve_ivp``), the
``numba`` backend (generated model, whole backend call on equations derived once, as the bench
times it), and the **machine limit**: a hand-written scalar right-hand side (and Jacobian) compiled
by numba as a ``cfunc`` with the generated model's C signature ``void f(t, *x, *out, *w)`` and run
through the *same* compiled loops (:func:`multipole.backends.numba_kernels.integrate`, Dormand–Prince
5(4) and Radau IIA) with nothing around them but the work arrays and the output sampling.  For the
stiff scene also CasADi's CVODES (``pip install casadi``; reported "not installed" without it) with
the same hand-written right-hand side as a CasADi expression.

Method (that of :mod:`multipole.bench`, whose functions are used): error = max over the scene's
output grid of the reference output against the bench's reference (closed form or rtol 1e-13),
relative to its largest magnitude; every contender sweeps its solvers over the tolerance ladder
(CPU time per run, median of 3 samples), extended per solver until it reaches every error level
(:func:`multipole.bench.extend_ladder`); at each level the fastest run of each
contender that reaches it is re-timed interleaved (A B C … A B C …, CPU time), each sample
repeating the call until it lasts about :data:`SAMPLE_S`; medians with the lowest and highest
round.  Two diagnostic contenders explain the numba/limit ratio: the generated model in the bare
loop (``numba loop``: numba / numba loop is the backend's per-run set-up, numba loop / limit the
right-hand side) and the cost per call of the generated and the hand-written right-hand side, both
called through their addresses in a compiled loop.

    python benchmarks/machine_limit.py drive_train stiff_drive_train   # about 17 s CPU
    python benchmarks/machine_limit.py slider_crank                    # about 63 s CPU
    python benchmarks/machine_limit.py drive_train --quick   # ladder 1e-3, 1e-6, 1e-9 (extended), 3 rounds
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import time
import types as pytypes
from pathlib import Path

import numba
import numpy as np
from numba import carray, cfunc, types

import multipole as mp
from multipole import bench, pipeline
from multipole.backends import get_backend, numba_backend
from multipole.backends import numba_kernels as K
from multipole.simulate import output_grid, simulate as drive
import multipole_models as mm

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"drive_train": "diagrams/drive_train.yaml", "stiff_drive_train": "diagrams/hard/stiff_drive_train.yaml",
          "slider_crank": "diagrams/hard/slider_crank.yaml"}
NUMBA, LIMIT, LOOP, CVODES = "numba", "limit", "numba loop", "CVODES"
COMPILED_SOLVERS = ["RK45", "Radau"]          # the methods of numba_kernels
LIMIT_TARGET = 1.3                            # numba backend within 1.3x of the machine limit (issue 11)
SAMPLE_S = 0.004                              # [s] a timed sample repeats a call until about this long
SIG = types.void(types.float64, types.voidptr, types.voidptr, types.voidptr)   # the generated cfuncs' signature


# -------------------------------------------------------------------------------------------------
# hand-written scalar models

def geared_drive(i, c, J1, J2, d_s, d_b, T0, tau, exp=math.exp):
    """Right-hand side ``f(t, p1, q, p2) -> (p1', q', p2')`` of motor rotor J1 [kg·m²] – ideal gear
    ``i`` – shaft (stiffness c [N·m/rad], damping d_s [N·m·s/rad]) – load J2 on a bearing damper d_b,
    motor torque ``T0 (1 - exp(-t/tau))`` [N·m]; states: rotor momentum p1 [N·m·s], shaft twist q
    [rad], load momentum p2.  Shaft torque ``c q + d_s (ω1/i - ω2)`` drives the load and brakes the
    rotor through the gear.  Written once for numba (``exp=math.exp``) and CasADi (``casadi.exp``);
    the reciprocals are taken once, as the generated code does with its constants."""
    inv_i, inv_J1, inv_J2, inv_tau = 1.0 / i, 1.0 / J1, 1.0 / J2, 1.0 / tau

    def f(t, p1, q, p2):
        w1, w2 = p1 * inv_J1, p2 * inv_J2
        rel = w1 * inv_i - w2
        torque = c * q + d_s * rel
        return T0 - T0 * exp(-t * inv_tau) - torque * inv_i, rel, torque - d_b * w2
    return f


def geared_drive_jac(i, c, J1, J2, d_s, d_b):
    """The constant Jacobian of :func:`geared_drive` (rows p1', q', p2'; columns p1, q, p2)."""
    return ((-d_s / (i * i * J1), -c / i, d_s / (i * J2)),
            (1.0 / (i * J1), 0.0, -1.0 / J2),
            (d_s / (i * J1), c, -(d_s + d_b) / J2))


def _geared_cfuncs(p, outputs, i=1.0, c_key="c"):
    """cfuncs of :func:`geared_drive` for the parameter dict ``p``; ``outputs`` names the scene's
    outputs in order (rotor.omega, load.omega, shaft.force)."""
    c, J1, J2 = p[c_key], p["J1"], p["J2"]
    f = numba.njit(geared_drive(i, c, J1, J2, p["d_s"], p["d_b"], p["T0"], p["tau"]))
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = geared_drive_jac(i, c, J1, J2, p["d_s"], p["d_b"])
    inv_J1, inv_J2 = 1.0 / J1, 1.0 / J2
    k_rotor, k_load, k_force = (outputs.index(n) for n in ("rotor.omega", "load.omega", "shaft.force"))

    @cfunc(SIG, error_model="numpy")
    def rhs(t, xp, outp, wp):
        x, out = carray(xp, (3,), np.float64), carray(outp, (3,), np.float64)
        out[0], out[1], out[2] = f(t, x[0], x[1], x[2])

    @cfunc(SIG, error_model="numpy")
    def jac(t, xp, outp, wp):
        J = carray(outp, (3, 3), np.float64)
        J[0, 0], J[0, 1], J[0, 2] = a00, a01, a02
        J[1, 0], J[1, 1], J[1, 2] = a10, a11, a12
        J[2, 0], J[2, 1], J[2, 2] = a20, a21, a22

    @cfunc(SIG, error_model="numpy")
    def outs(t, xp, outp, wp):
        x, out = carray(xp, (3,), np.float64), carray(outp, (3,), np.float64)
        out[k_rotor], out[k_load], out[k_force] = x[0] * inv_J1, x[2] * inv_J2, c * x[1]
    return rhs, jac, outs


def _slider_crank_cfuncs(p, outputs):
    """cfuncs of the slider-crank (states flywheel.p = J ω, crank.q = φ): Lagrange with
    ``T = (J + m x'²) ω²/2`` and the gas force's potential ``F0 x``, the piston kinematics
    ``x'(φ), x''(φ), x'''(φ)`` of :func:`multipole_models._crank_kinematics` compiled by numba."""
    r, l, J, m, F0 = p["r"], p["l"], p["J"], p["m"], p["F0"]
    inv_J = 1.0 / J
    kin = numba.njit(mm._crank_kinematics)
    k_w, k_q, k_v = (outputs.index(n) for n in ("flywheel.omega", "crank.q", "piston.v"))

    @cfunc(SIG, error_model="numpy")
    def rhs(t, xp, outp, wp):
        x, out = carray(xp, (2,), np.float64), carray(outp, (2,), np.float64)
        w = x[0] * inv_J
        d1, d2, _ = kin(x[1], r, l)
        out[0] = -J * d1 * (F0 + m * d2 * w * w) / (J + m * d1 * d1)
        out[1] = w

    @cfunc(SIG, error_model="numpy")
    def jac(t, xp, outp, wp):
        x, out = carray(xp, (2,), np.float64), carray(outp, (2, 2), np.float64)
        w = x[0] * inv_J
        d1, d2, d3 = kin(x[1], r, l)
        den = J + m * d1 * d1
        num = -J * d1 * (F0 + m * d2 * w * w)
        out[0, 0] = -2.0 * m * d1 * d2 * w / den
        dnum = -J * (d2 * (F0 + m * d2 * w * w) + d1 * m * d3 * w * w)
        out[0, 1] = (dnum * den - num * 2.0 * m * d1 * d2) / (den * den)
        out[1, 0] = inv_J
        out[1, 1] = 0.0

    @cfunc(SIG, error_model="numpy")
    def outs(t, xp, outp, wp):
        x, out = carray(xp, (2,), np.float64), carray(outp, (3,), np.float64)
        d1, _, _ = kin(x[1], r, l)
        out[k_w], out[k_q], out[k_v] = x[0] * inv_J, x[1], d1 * x[0] * inv_J
    return rhs, jac, outs


@cfunc(SIG)
def _no_switches(t, xp, outp, wp):
    pass


def _params(scene, defaults) -> dict:
    """The scene's parameter values over the hand model's defaults (as the bench's hand models)."""
    return mm._values({k: float(v) for k, v in scene.network.params.items()}, defaults)


def hand_module(scene):
    """The hand-written model of a scene of :data:`SCENES` shaped like a generated numba module (the
    attributes :class:`numba_backend.NumbaModel` and the loops read), and its state names."""
    outputs = list(scene.outputs)
    key = scene.reference["hand_model"]
    if key == "drive_train":
        p = _params(scene, mm._DRIVE)
        funcs, names = _geared_cfuncs(p, outputs, i=p["i"], c_key="c_shaft"), ["rotor.p", "shaft.q", "load.p"]
    elif key == "stiff_drive_train":
        funcs, names = _geared_cfuncs(_params(scene, mm._STIFF), outputs), ["rotor.p", "shaft.q", "load.p"]
    elif key == "slider_crank":
        funcs, names = _slider_crank_cfuncs(_params(scene, mm._CRANK), outputs), ["flywheel.p", "crank.q"]
    else:
        raise KeyError(f"no hand-written compiled model of {key!r}")
    rhs, jac, outs = funcs
    module = pytypes.SimpleNamespace(rhs=rhs, jac=jac, outputs=outs, switches=_no_switches, N_WORK=K.W_HEAD,
                                     N_SWITCHES=0, SWITCH_TIME_ONLY=[], SWITCH_RATE=[], SWITCH_ROOTS=[], MONITORS=[])
    return module, names


def casadi_rhs(scene):
    """``(x, t, ode)`` CasADi SX symbols and expression of the hand-written right-hand side (the
    drive trains only), or None when CasADi is not installed."""
    try:
        import casadi as ca
    except ImportError:
        return None
    key = scene.reference["hand_model"]
    p = _params(scene, mm._STIFF if key == "stiff_drive_train" else mm._DRIVE)
    i, c = (1.0, p["c"]) if key == "stiff_drive_train" else (p["i"], p["c_shaft"])
    f = geared_drive(i, c, p["J1"], p["J2"], p["d_s"], p["d_b"], p["T0"], p["tau"], exp=ca.exp)
    x, t = ca.SX.sym("x", 3), ca.SX.sym("t")
    return x, t, ca.vertcat(*f(t, x[0], x[1], x[2]))


# -------------------------------------------------------------------------------------------------
# contenders: each a call(solver, rtol, atol) -> a result the bench's _measure reads

class _Result:
    """What :func:`multipole.bench._measure` reads of a run: t, outputs, stats, solver, events."""

    def __init__(self, t, outputs, stats, solver):
        self.t, self.outputs, self.stats, self.solver, self.events = t, outputs, stats, solver, []

    def __getitem__(self, name):
        return self.outputs[name]


class BareLoop:
    """A model's cfuncs (generated or hand-written) run by :func:`numba_kernels.integrate` and
    :func:`numba_kernels.sample` with nothing else: the work arrays of the backend
    (:class:`numba_backend._Work`), one call of the loop, the outputs sampled on the grid."""

    def __init__(self, module, x0, grid, t_end, outputs):
        self.module, self.x0, self.grid, self.t_end, self.outputs = module, np.asarray(x0, float), grid, t_end, outputs
        self.addresses = (module.rhs.address, module.jac.address, module.switches.address)

    def __call__(self, solver, rtol, atol):
        n, m = len(self.x0), self.module
        work = numba_backend._Work(n, 0, m.N_WORK, self.grid, self.x0, self.t_end, rtol, atol, math.inf)
        K.integrate(*self.addresses, solver == "Radau", *work.args(np.iinfo(np.int64).max))
        if work.iw[K.I_STATUS] != K.FINISHED:
            raise RuntimeError(f"bare loop {solver}: status {int(work.iw[K.I_STATUS])} at t = {work.fs[K.F_T]:g} s")
        Y = np.zeros((self.grid.size, len(self.outputs)))
        K.sample(m.outputs.address, work.w, self.grid, work.X, Y)
        iw = work.iw
        stats = {"nfev": int(iw[K.I_NFEV]), "njev": int(iw[K.I_NJEV]), "nlu": int(iw[K.I_NLU]),
                 "steps": int(iw[K.I_STEPS]), "rejected": int(iw[K.I_REJECTED])}
        return _Result(self.grid, {o: Y[:, k] for k, o in enumerate(self.outputs)}, stats, solver)


class Cvodes:
    """CasADi's CVODES (BDF, Newton with the dense Jacobian CasADi derives) on the CasADi
    expression of the hand-written right-hand side; outputs from the bench's hand model."""

    solvers = ("BDF",)

    def __init__(self, expr, grid, hand):
        self.expr, self.grid, self.hand, self.made = expr, grid, hand, {}

    def __call__(self, solver, rtol, atol):
        import casadi as ca
        if (rtol, atol) not in self.made:        # built once per tolerance, outside the timing
            x, t, ode = self.expr
            self.made[(rtol, atol)] = ca.integrator("F", "cvodes", {"x": x, "t": t, "ode": ode}, 0.0,
                                                     self.grid[1:], {"abstol": atol, "reltol": rtol})
        F = self.made[(rtol, atol)]
        X = np.hstack([np.reshape(self.hand.x0, (-1, 1)), np.array(F(x0=self.hand.x0)["xf"])])
        st = F.stats()
        outs = {name: np.asarray(g(self.grid, X), dtype=float) for name, g in self.hand.outputs.items()}
        return _Result(self.grid, outs, {"nfev": int(st["nfevals"]), "njev": int(st["n_call_jacF"]),
                                         "nlu": int(st["nlinsetups"]), "steps": int(st["nsteps"])}, "CVODES")


# -------------------------------------------------------------------------------------------------
# timing

@numba.njit
def _call_loop(address, n, x, out, w):
    """``n`` calls of the model function at ``address`` in a compiled loop, each at a new time and
    state (nothing can be hoisted out of the loop)."""
    acc, t = 0.0, 0.0
    for _ in range(n):
        t += 1e-9
        x[0] += 1e-9 * (1.0 + abs(x[0]))
        K.call_model(address, t, x, out, w)
        acc += out[0]
    return acc


def per_call(generated, hand, x0, rounds=7, n=200_000):
    """CPU time per right-hand-side call [s] of the generated and the hand-written model, both
    through their addresses in :func:`_call_loop`, interleaved: ``{name: Timing}``."""
    n_x = len(x0)
    calls = {name: (lambda m=m: _call_loop(m.rhs.address, n, np.array(x0, float), np.zeros(n_x),
                                           np.zeros(m.N_WORK)))
             for name, m in (("generated", generated), ("hand", hand))}
    timing = bench.interleaved(calls, rounds)
    for t in timing.values():
        t.cpu = [c / n for c in t.cpu]
        t.wall = [c / n for c in t.wall]
    return timing


def _repeats(fn, first: float) -> int:
    """How often to repeat ``fn`` (which took ``first`` s of CPU) so a sample lasts about :data:`SAMPLE_S`."""
    return max(1, math.ceil(SAMPLE_S / max(first, 1e-6)))


def cpu_attempt(fn, repeats: int = 3):
    """``(result, CPU times per call [s])`` of ``fn`` for the sweep (the attempt of
    :func:`multipole.bench._sweep`, CPU instead of wall time): one call, then ``repeats`` samples of
    :func:`_repeats` calls each; a call longer than 0.2 s is measured once."""
    t0 = time.process_time()
    res = fn()
    first = time.process_time() - t0
    if first > 0.2:
        return res, [first]
    k, cpus = _repeats(fn, first), []
    for _ in range(repeats):
        t0 = time.process_time()
        for _ in range(k):
            fn()
        cpus.append((time.process_time() - t0) / k)
    return res, cpus


def timed(contenders: dict, rounds: int) -> dict:
    """:func:`multipole.bench.interleaved` with every sample repeating its call (:func:`_repeats`,
    so that the clock's resolution and one-off delays do not decide a short run's time); times per
    call."""
    reps = {}
    for name, fn in contenders.items():
        fn()
        t0 = time.process_time()
        fn()
        reps[name] = _repeats(fn, time.process_time() - t0)
    looped = {name: (lambda fn=fn, k=reps[name]: [fn() for _ in range(k)]) for name, fn in contenders.items()}
    timing = bench.interleaved(looped, rounds)
    for name, t in timing.items():
        t.cpu = [c / reps[name] for c in t.cpu]
        t.wall = [c / reps[name] for c in t.wall]
    return timing


def at_most(a: bench.Timing, b: bench.Timing, target: float) -> dict:
    """Ratio ``a / b`` of interleaved timings against an upper bound ``target``: median and spread,
    verdict ``met`` only if even the highest round stays within it."""
    v = bench.ratio_verdict(b, a, 1.0 / target)             # b / a >= 1/target  <=>  a / b <= target
    lo, hi = 1.0 / v["ratio_hi"], 1.0 / v["ratio_lo"]
    verdict = "met" if hi <= target else "not met" if lo > target else f"within noise ({lo:.3g}–{hi:.3g}×)"
    return {"ratio": statistics.median([x / max(y, 1e-9) for x, y in zip(a.cpu, b.cpu)]), "lo": lo, "hi": hi,
            "verdict": verdict}


def at_least(a: bench.Timing, b: bench.Timing, target: float) -> dict:
    """Speed-up ``a / b`` against a lower bound ``target`` (:func:`multipole.bench.ratio_verdict`)."""
    v = bench.ratio_verdict(a, b, target)
    return {"ratio": v["ratio"], "lo": v["ratio_lo"], "hi": v["ratio_hi"], "verdict": v["verdict"]}


# -------------------------------------------------------------------------------------------------
# one scene

#: runs within this factor of a contender's fastest sweep time at a level are re-timed to choose
CANDIDATE_FACTOR, CANDIDATES = 2.0, 3


def fastest(rep, level: float, who: str, call):
    """The fastest run of contender ``who`` reaching ``level``: the sweep's choice
    (:func:`multipole.bench.fastest`), unless up to :data:`CANDIDATES` runs come within
    :data:`CANDIDATE_FACTOR` of it, which are then re-timed interleaved (3 rounds) and the lowest
    median wins: on a loaded machine one sweep sample can make a slower tolerance look faster."""
    first = bench.fastest(rep, level, who)
    if first is None:
        return None
    near = sorted((r for r in rep.runs if r.backend == who and r.status == "ok" and r.err_max <= level
                   and r.wall_s <= CANDIDATE_FACTOR * first.wall_s), key=lambda r: r.wall_s)[:CANDIDATES]
    if len(near) < 2:
        return first
    t = timed({k: (lambda r=r: call(r.solver, r.rtol, r.atol)) for k, r in enumerate(near)}, 3)
    return near[min(t, key=lambda k: statistics.median(t[k].cpu))]

def measure(name: str, quick: bool = False, rounds: int = bench.TIMING_ROUNDS) -> dict:
    """Sweeps, ladder extension and the interleaved timing of one scene of :data:`SCENES`."""
    scene = mp.load(ROOT / SCENES[name])
    model = pipeline.model(scene)
    ref = bench.build_reference(scene, model)
    hand = bench.hand_model(scene)
    sim = scene.simulate
    ratio = sim.get("atol", 1e-9) / sim.get("rtol", 1e-6)
    tolerances = bench.QUICK_TOLERANCES if quick else bench.TOLERANCES
    budget = 5e4 if quick else 4e5
    lam = np.linalg.eigvals(model.jac(0.0, model.x0))
    grid = output_grid(ref.t_end, ref.dt_out)
    outs = list(model.output_names)
    eq = pipeline.equations(scene)
    run_numba = get_backend("numba")
    generated = numba_backend.run.compile(eq, outs)
    mine, names = hand_module(scene)
    assert list(generated.state_names) == names == list(hand.state_names), "state orders differ"
    calls = {
        bench.HAND: lambda s, r, a: bench.solve_hand(hand, ref.t_end, grid, s, r, a),
        NUMBA: lambda s, r, a: run_numba(eq, outs, ref.t_end, ref.dt_out, s, r, a, math.inf, False),
        LIMIT: BareLoop(mine, hand.x0, grid, ref.t_end, outs),
    }
    solvers = {bench.HAND: bench.HAND_SOLVERS, NUMBA: COMPILED_SOLVERS, LIMIT: COMPILED_SOLVERS}
    expr = casadi_rhs(scene) if name == "stiff_drive_train" else None
    if expr is not None:
        calls[CVODES], solvers[CVODES] = Cvodes(expr, grid, hand), list(Cvodes.solvers)
    rep = bench.SceneReport(scene.name, str(SCENES[name]), ref)
    bar = bench._Bar(1, False)
    for who, call in calls.items():
        def attempt(s, r, a, call=call):
            return cpu_attempt(lambda: call(s, r, a), 1 if quick else 3)
        # the explicit stability bound of the hand-written model in Python also skips the compiled RK45
        # on the stiff scene (a million steps, the method is the wrong one there)
        bench._sweep(rep, who, solvers[who], tolerances, ratio, budget, lam, bar, attempt)
        bench.extend_ladder(rep, who, bench.EQUAL_ERROR_LEVELS, attempt, ratio)
    loop = BareLoop(generated.module, generated.x0, grid, ref.t_end, outs)
    rows = []
    for level in bench.EQUAL_ERROR_LEVELS:
        best = {who: fastest(rep, level, who, calls[who]) for who in calls}
        row = {"scene": name, "level": level, "best": best, "measurable": level > 3 * ref.error}
        rows.append(row)
        if not row["measurable"] or best[bench.HAND] is None or best[NUMBA] is None or best[LIMIT] is None:
            continue
        contenders = {who: (lambda call=calls[who], r=r: call(r.solver, r.rtol, r.atol))
                      for who, r in best.items() if r is not None}
        nb = best[NUMBA]
        contenders[LOOP] = lambda: loop(nb.chosen, nb.rtol, nb.atol)
        t = timed(contenders, rounds)
        row["cpu"] = {who: statistics.median(v.cpu) for who, v in t.items()}
        row["spread"] = {who: (min(v.cpu), max(v.cpu)) for who, v in t.items()}
        row["scipy/numba"] = at_least(t[bench.HAND], t[NUMBA], bench.SPEEDUP_TARGET)
        row["scipy/limit"] = at_least(t[bench.HAND], t[LIMIT], bench.SPEEDUP_TARGET)
        row["numba/limit"] = at_most(t[NUMBA], t[LIMIT], LIMIT_TARGET)
        row["numba/loop"] = at_most(t[NUMBA], t[LOOP], LIMIT_TARGET)
        row["loop/limit"] = at_most(t[LOOP], t[LIMIT], LIMIT_TARGET)
        if CVODES in t:
            row["numba/cvodes"] = at_most(t[NUMBA], t[CVODES], LIMIT_TARGET)
            row["scipy/cvodes"] = at_least(t[bench.HAND], t[CVODES], bench.SPEEDUP_TARGET)
    pc = per_call(generated.module, mine, generated.x0, rounds)
    first = next((row["best"][NUMBA] for row in rows if "cpu" in row), None)
    driver = driver_costs(generated, eq, outs, ref, grid, first, rounds) if first is not None else None
    return {"scene": name, "rows": rows, "reference": ref, "per_call": pc, "cvodes": expr is not None,
            "runs": rep.runs, "driver": (first, driver)}


def driver_costs(generated, eq, outs, ref, grid, run, rounds) -> dict:
    """Where a numba backend call spends the time the bare loop does not, for the backend's ``run``
    (a :class:`multipole.bench.Run`), interleaved: ``{part: Timing}`` for the whole backend call, the
    shared driver :func:`multipole.simulate.simulate` around an integrator that returns a finished
    run at once (options, grid, plan, output sampling, checks, the Result), the backend's integrator
    (:class:`numba_backend.NumbaIntegrator`: work arrays and the compiled loop), the bare loop
    (work arrays, compiled loop, output sampling) and the compiled output sampling alone."""
    method, x0 = run.chosen, np.asarray(generated.x0, float)
    integ = numba_backend.run.integrator

    def integrate():
        return integ.integrate(generated, method, grid, x0.copy(), [], np.ones(0), ref.t_end, run.rtol, run.atol,
                               math.inf, _NoBar())
    done = integrate()

    class Finished:                     # the integrator interface, its run already made
        name, solvers = integ.name, integ.solvers

        def method(self, solver, auto):
            return integ.method(solver, auto)

        def integrate(self, *args):
            return done
    loop = BareLoop(generated.module, x0, grid, ref.t_end, outs)
    parts = {"whole call": lambda: numba_backend.run(eq, outs, ref.t_end, ref.dt_out, run.solver, run.rtol, run.atol,
                                                      math.inf, False),
             "shared driver": lambda: drive(generated, ref.t_end, ref.dt_out, method, run.rtol, run.atol, math.inf,
                                                  False, integrator=Finished()),
             "NumbaIntegrator": integrate,
             "bare loop": lambda: loop(method, run.rtol, run.atol),
             "output sampling": lambda: generated.outputs_on_grid(grid, done.states)}
    return timed(parts, rounds)


class _NoBar:
    enabled = False

    def update(self, t):
        pass


# -------------------------------------------------------------------------------------------------
# report

def _ms(x):
    return f"{x * 1e3:.3g}"


def _run(r):
    return "—" if r is None else f"{bench.run_label(r)} {r.rtol:.0e}"


def _ratio(v):
    return f"{v['ratio']:.3g} [{v['lo']:.3g}–{v['hi']:.3g}]"


def report(res: dict) -> str:
    name, cv = res["scene"], res["cvodes"]
    lines = [f"### {name}", ""]
    head = "| error ≤ | scipy (hand) | numba backend | machine limit |" + (" CVODES |" if cv else "") + \
        " numba loop | scipy / numba | scipy / limit | numba / limit | numba / numba loop | numba loop / limit |" + \
        (" numba / CVODES |" if cv else "")
    lines += [head, "|" + "---|" * (head.count("|") - 1)]
    for row in res["rows"]:
        best = row["best"]
        if "cpu" not in row:
            why = "not measurable (reference error)" if not row["measurable"] else \
                "unreached by " + ", ".join(w for w in (bench.HAND, NUMBA, LIMIT) if best[w] is None)
            lines.append(f"| {row['level']:.0e} | {why} |")
            continue
        cpu, sp = row["cpu"], row["spread"]

        def cell(who):
            r = best.get(who)
            if who == LOOP:
                return f"{_ms(cpu[LOOP])} [{_ms(sp[LOOP][0])}–{_ms(sp[LOOP][1])}]"
            return (f"{_run(r)}: {_ms(cpu[who])} [{_ms(sp[who][0])}–{_ms(sp[who][1])}], nfev {r.nfev}, "
                    f"err {r.err_max:.1e}")
        cells = [cell(bench.HAND), cell(NUMBA), cell(LIMIT)] + ([cell(CVODES) if best.get(CVODES) else "unreached"]
                                                                if cv else []) + [cell(LOOP)]
        ratios = [f"{_ratio(row['scipy/numba'])} {row['scipy/numba']['verdict']}",
                  f"{_ratio(row['scipy/limit'])} {row['scipy/limit']['verdict']}",
                  f"{_ratio(row['numba/limit'])} {row['numba/limit']['verdict']}",
                  _ratio(row["numba/loop"]), _ratio(row["loop/limit"])]
        if cv:
            ratios.append(f"{_ratio(row['numba/cvodes'])} {row['numba/cvodes']['verdict']}" if "numba/cvodes" in row
                          else "—")
        lines.append(f"| {row['level']:.0e} | " + " | ".join(cells + ratios) + " |")
    pc = res["per_call"]
    g, h = statistics.median(pc["generated"].cpu), statistics.median(pc["hand"].cpu)
    ratios = [a / b for a, b in zip(pc["generated"].cpu, pc["hand"].cpu)]
    lines += ["", f"Right-hand side per call through its address (compiled loop, CPU, medians of "
              f"{len(ratios)}): generated {g * 1e9:.3g} ns, hand-written {h * 1e9:.3g} ns, ratio "
              f"{statistics.median(ratios):.3g} [{min(ratios):.3g}–{max(ratios):.3g}].", ""]
    run, parts = res["driver"]
    if parts is not None:
        med = {k: statistics.median(v.cpu) for k, v in parts.items()}
        lines += [f"Where a numba backend call goes ({bench.run_label(run)}, rtol {run.rtol:.0e}, CPU [ms], medians "
                  "of interleaved rounds): " + ", ".join(f"{k} {_ms(v)}" for k, v in med.items())
                  + f"; the shared driver without the output sampling: "
                  f"{_ms(med['shared driver'] - med['output sampling'])}, the backend's integrator minus the bare "
                  f"loop without sampling: {_ms(med['NumbaIntegrator'] - med['bare loop'] + med['output sampling'])}, "
                  f"the whole call minus the driver and the integrator: "
                  f"{_ms(med['whole call'] - med['shared driver'] - med['NumbaIntegrator'])}.", ""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", metavar="SCENE", help=f"scenes (default: all of {', '.join(SCENES)})")
    ap.add_argument("--quick", action="store_true", help="ladder 1e-3, 1e-6, 1e-9 (and its extension), 3 rounds")
    args = ap.parse_args(argv)
    unknown = [s for s in args.scenes if s not in SCENES]
    if unknown:
        ap.error(f"unknown scene {unknown[0]!r}: use {', '.join(SCENES)}")
    try:
        import casadi
        print(f"CasADi {casadi.__version__}")
    except ImportError:
        print("CasADi: not installed (pip install casadi): no CVODES column")
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    print(f"machine limit, {time.strftime('%Y-%m-%d %H:%M')}, load average {load}\n")
    for name in args.scenes or list(SCENES):
        t0, c0 = time.perf_counter(), time.process_time()
        res = measure(name, quick=args.quick, rounds=3 if args.quick else bench.TIMING_ROUNDS)
        print(report(res))
        print(f"({name}: {time.process_time() - c0:.0f} s CPU, {time.perf_counter() - t0:.0f} s wall)\n", flush=True)


if __name__ == "__main__":
    main()
