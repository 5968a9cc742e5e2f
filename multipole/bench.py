"""``multipole bench``: speed against error (DESIGN §10).

For every benchmark scene the bench runs each solver over a ladder of tolerances and records the
error against a reference, the wall time (median of repeats) and the work counters.  It writes

* ``bench.csv`` — one row per (scene, backend, solver, rtol): errors, wall time, nfev, njev, nlu,
  steps, rejected steps, Newton iterations, energy drift, status and message.  Besides the
  ``numpy`` backend and every compiled one, the "backend" ``scipy-hand`` is the hand-written numpy
  model of the scene with ``scipy.integrate.solve_ivp`` (RK45, DOP853, Radau, BDF, LSODA; analytic
  Jacobian for the implicit ones), against the same reference;
* ``side_by_side.csv`` — generated model against a hand-written numpy right-hand side of the same
  equations (per call and whole run, same solver), and naive ``solve_ivp`` defaults against ``auto``
  (with a lower bound of the speed-up where the naive run would exceed its evaluation budget);
* ``equal_error.csv`` — per scene, compiled backend and error level: the fastest hand-written
  ``solve_ivp`` run and the fastest compiled-backend run reaching that error (each side's ladder
  extended beyond the sweep's tolerances until it does, down to rtol :data:`LADDER_FLOOR`, else the
  level is marked unreached for it), the two re-timed interleaved (A B A B …, CPU and wall time),
  the CPU-time ratio's median and spread, and a verdict that is "met" only beyond the spread;
* ``bench_<scene>.png`` — work-precision figure (error against wall time and against nfev);
* ``summary.md`` — which solver to pick for which scene and why.

Hand-written models are found through the entry point group ``multipole.hand_models``: each entry
is a callable ``f(scene) -> HandModel | None``; the first answer that is not ``None`` is used.
Without files, the bench runs the scenes offered through the entry point group
``multipole.bench_scenes`` (:func:`default_scenes`), so an installed package finds them without a
source checkout; a scene that reads data files (contour tables) comes with their texts and is
loaded from a private temporary folder holding them.  The kernel knows no element library or
fixture package by name.

Reference of a scene: the ``reference`` mapping of its netlist::

    reference:
      kind: closed_form           # or: tight
      output: load.omega          # the output compared (default: the first output)
      expression: "9.4 - exp(-0.9*t)*..."   # closed_form only: a formula of t and the scene's parameters
      energy: "0.5*J*flywheel.omega**2 + ..."  # optional: a conserved quantity of outputs and parameters
      t_end: 2.0                  # optional: horizon of the bench (default: simulate.t_end)
      hand_model: drive_train     # optional: the hand-written model the entry points pair with the scene
      no_hand_model: "why not"    # optional, instead: why the scene has none (no equal-error rows then)

``closed_form`` formulas go through :func:`multipole.expressions.parse_expression` (the netlist
whitelist; never ``eval``).  ``tight`` (and scenes without a reference) use the solution at
``rtol = 1e-13``; its own error is estimated as its distance to the solution at ``rtol = 1e-12``
and stated next to every result.

Errors are relative to the output's scale: ``err_final = |y(T) - y_ref(T)| / max|y_ref|`` and
``err_max = max_t |y(t) - y_ref(t)| / max|y_ref|`` over the output grid.  Wall time is the
integration time reported by the simulator (compilation excluded, the output grid included); for a
compiled backend, the whole call of the backend on equations derived once (building the work
arrays, integrating, sampling the outputs, the Result; compilation is cached after the first call);
for ``scipy-hand``, the whole ``solve_ivp`` call with ``t_eval`` on the same output grid.
"""
from __future__ import annotations

import csv
import math
from importlib.metadata import entry_points
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp

from . import pipeline
from .errors import MultipoleError
from .expressions import parse_expression
from .netlist import Scene, load, loads
from .network import flatten
from .primitives import T
from .simulate import IMPLICIT, SOLVERS, choose_solver, rk_stability_radius, simulate

SWEEP_SOLVERS = ["RK45", "DOP853", "Radau", "BDF", "LSODA", "GL4", "auto"]
TOLERANCES = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
QUICK_TOLERANCES = [1e-3, 1e-6, 1e-9]
EXPLICIT_RK = {"RK45", "RK23", "DOP853"}
HAND = "scipy-hand"                                   # backend label of the hand-written solve_ivp runs
HAND_SOLVERS = ["RK45", "DOP853", "Radau", "BDF", "LSODA"]
EQUAL_ERROR_LEVELS = (1e-3, 1e-6, 1e-9)
SPEEDUP_TARGET = 50.0                                 # compiled backend against hand-written scipy (issue 11)
TIMING_ROUNDS = 7                                     # interleaved rounds of the equal-error contenders
LADDER_FLOOR = 1e-14                                  # tightest rtol a contender's ladder is extended to
SLOW_RUN_S = 20.0                                     # a run this long [s] skips the tighter tolerances
HAND_MAX_NFEV = 1_000_000                             # a hand-written run stops (fails) beyond this many calls
CSV_FIELDS = ["scene", "backend", "solver", "chosen", "rtol", "atol", "status", "err_final", "err_max",
              "ref_error", "energy_drift", "wall_s", "run_s", "repeats", "nfev", "njev", "nlu", "steps", "rejected",
              "newton_iterations", "events", "message"]


# -------------------------------------------------------------------------------------------------
# stability bound of explicit Runge–Kutta methods

def explicit_stability_bound(eigenvalues, method: str, t_end: float) -> dict:
    """Fewest steps and evaluations an explicit method needs to stay stable over ``t_end`` [s].

    Every eigenvalue λ of the Jacobian with a clearly negative real part must satisfy
    ``h·|λ| <= r(arg λ)`` (:func:`rk_stability_radius`); the tightest gives ``h_max`` and
    ``steps >= t_end/h_max``, ``nfev >= stages·steps``.  A lower bound: accuracy may need more.
    """
    lam = np.asarray(eigenvalues, dtype=complex)
    lam = lam[(lam.real < -0.1 * np.abs(lam)) & (np.abs(lam) > 0)]
    if lam.size == 0:
        return {"h_max": math.inf, "steps": 0, "nfev": 0}
    h_max = min(rk_stability_radius(method, float(np.angle(z))) / abs(z) for z in lam)
    steps = int(math.ceil(t_end / h_max))
    stages = SOLVERS[method].n_stages
    return {"h_max": h_max, "steps": steps, "nfev": steps * stages}


# -------------------------------------------------------------------------------------------------
# references

@dataclass
class Reference:
    """What a scene's runs are compared with."""

    kind: str
    output: str
    t_end: float
    dt_out: float
    error: float                       # estimated relative error of the reference itself
    note: str
    energy: object = None              # callable(t, outputs dict) -> array, or None
    scale: float = 1.0
    formula: object = None             # closed form: callable(t, {}) -> array
    grid: np.ndarray | None = None     # tight: the output grid and the values on it
    values: np.ndarray | None = None

    def at(self, t) -> np.ndarray:
        """Reference values on the output grid ``t`` of a run."""
        if self.formula is not None:
            return self.formula(np.asarray(t, dtype=float), {})
        if len(t) != len(self.grid) or np.max(np.abs(np.asarray(t) - self.grid)) > 1e-9 * max(1.0, self.t_end):
            raise MultipoleError("bench_grid", "the output grid of a run does not match the reference grid")
        return self.values


def _symbols(scene: Scene, outputs) -> tuple[dict, dict]:
    """Expression symbols (parameters and output names) and the parameter values."""
    values = {s.name: v for s, v in flatten(scene.network).param_values().items()}
    symbols = {name: sp.Symbol(name) for name in list(values) + list(outputs)}
    return symbols, values


def _compile(text, scene: Scene, outputs, what: str):
    """A parsed formula as a function of ``t`` and the outputs (a dict of arrays)."""
    symbols, values = _symbols(scene, outputs)
    symbols["t"] = T
    expr = parse_expression(str(text), symbols, f"{scene.path} reference {what}")
    expr = expr.xreplace({symbols[k]: sp.Float(v) for k, v in values.items() if symbols[k] in expr.free_symbols})
    args = [T] + [symbols[o] for o in outputs]
    fn = sp.lambdify(args, expr, modules=[{"Heaviside": lambda x, h=1.0: np.heaviside(x, h)}, "numpy"])

    def evaluate(t, outs):
        return np.broadcast_to(np.asarray(fn(t, *[outs[o] for o in outputs]), dtype=float), np.shape(t)).copy()
    return evaluate


def reference_spec(scene: Scene) -> dict:
    """The scene's ``reference`` mapping, checked (kind, output, expression, energy, t_end; ``hand_model``
    names the hand-written model the ``multipole.hand_models`` entry points pair with the scene,
    ``no_hand_model`` says in words why the scene has none)."""
    spec = dict(scene.reference or {"kind": "tight"})
    allowed = {"kind", "output", "expression", "energy", "t_end", "hand_model", "no_hand_model"}
    unknown = set(spec) - allowed
    if unknown:
        raise MultipoleError("bad_reference", f"{scene.path}: unknown reference key {sorted(unknown)[0]!r}",
                             f"allowed: {', '.join(sorted(allowed))}")
    if "no_hand_model" in spec:
        why = spec["no_hand_model"]
        if not isinstance(why, str) or not why.strip():
            raise MultipoleError("bad_reference", f"{scene.path}: no_hand_model must say why the scene has no "
                                 "hand-written model", "give the reason as text")
        if "hand_model" in spec:
            raise MultipoleError("bad_reference", f"{scene.path}: a reference names a hand_model or says why it "
                                 "has none (no_hand_model), not both", "keep one of the two keys")
    kind = spec.get("kind", "tight")
    if kind not in ("closed_form", "tight"):
        raise MultipoleError("bad_reference", f"{scene.path}: reference kind must be closed_form or tight, "
                             f"got {kind!r}")
    if kind == "closed_form" and "expression" not in spec:
        raise MultipoleError("bad_reference", f"{scene.path}: a closed_form reference needs an expression")
    outputs = scene.outputs
    out = spec.get("output", outputs[0] if outputs else None)
    if out is None or (outputs and out not in outputs):
        raise MultipoleError("bad_reference", f"{scene.path}: reference output {out!r} is not among the "
                             f"scene's outputs", f"outputs: {', '.join(outputs)}")
    spec["kind"], spec["output"] = kind, out
    return spec


def build_reference(scene: Scene, model) -> Reference:
    """Evaluate the closed form, or compute the tight solution and its error estimate."""
    spec = reference_spec(scene)
    t_end = float(spec.get("t_end", scene.simulate.get("t_end", 1.0)))
    dt_out = min(float(scene.simulate.get("dt_out", t_end / 500)), t_end / 50)
    out = spec["output"]
    energy = _compile(spec["energy"], scene, model.output_names, "energy") if "energy" in spec else None
    if spec["kind"] == "closed_form":
        f = _compile(spec["expression"], scene, [], "expression")
        scale = max(float(np.max(np.abs(f(np.linspace(0.0, t_end, 20001), {})))), 1e-300)
        return Reference("closed_form", out, t_end, dt_out, 0.0, "closed form", energy, scale, formula=f)
    runs = []
    for rtol in (1e-12, 1e-13):
        _fresh(model)
        runs.append(simulate(model, t_end, dt_out, "auto", rtol, rtol * 1e-2, progress=False))
    values = runs[1][out]
    scale = max(float(np.max(np.abs(values))), 1e-300)
    err = float(np.max(np.abs(runs[0][out] - values)) / scale)
    note = f"tight: {runs[1].solver} at rtol 1e-13; its error estimated as its distance to the rtol 1e-12 solution"
    return Reference("tight", out, t_end, dt_out, err, note, energy, scale, grid=runs[1].t, values=values)


# -------------------------------------------------------------------------------------------------
# runs

@dataclass
class Run:
    scene: str
    backend: str
    solver: str
    rtol: float
    atol: float
    status: str = "ok"
    chosen: str = ""
    err_final: float = math.nan
    err_max: float = math.nan
    ref_error: float = math.nan
    energy_drift: float = math.nan
    wall_s: float = math.nan
    run_s: float = math.nan            # a compiled backend's own run time (integration + output sampling) [s]
    repeats: int = 0
    nfev: int = 0
    njev: int = 0
    nlu: int = 0
    steps: int = 0
    rejected: object = ""
    newton_iterations: int = 0
    events: int = 0
    message: str = ""

    def row(self) -> dict:
        return {k: getattr(self, k) for k in CSV_FIELDS}


def _measure(run: Run, ref: Reference, res, walls) -> None:
    s = res.stats
    dev = np.abs(res[ref.output] - ref.at(res.t)) / ref.scale
    run.err_final, run.err_max = float(dev[-1]), float(np.max(dev))
    run.ref_error = ref.error
    try:
        E = ref.energy(res.t, res.outputs) if ref.energy is not None else None
    except KeyError:                 # a hand-written model without every output the formula reads
        E = None
    if E is not None:
        run.energy_drift = float(np.max(np.abs(E - E[0])) / max(abs(E[0]), 1e-300))
    run.wall_s = statistics.median(walls)
    run.run_s = float(s.get("run_time_median", math.nan))
    run.repeats = len(walls)
    run.chosen = res.solver
    run.nfev, run.njev, run.nlu = int(s.get("nfev", 0)), int(s.get("njev", 0)), int(s.get("nlu", 0))
    run.steps = int(s.get("steps", 0))
    run.rejected = s.get("rejected", "")
    run.newton_iterations = int(s.get("newton_iterations", 0))
    run.events = len(res.events)


def _fresh(model) -> None:
    """Reset the warm-start values of the model's Newton loops, so every run starts alike.

    Work-around: the generated module keeps the last Newton solution of each nonlinear loop in a
    module-level ``_guess`` list across runs (and after a failed run).
    """
    guess = model.rhs.__globals__.get("_guess") if model is not None else None
    if guess is not None:
        guess[:] = [[0.0] * len(g) for g in guess]      # the generated initial values


def _one(fn, repeats: int, model=None, whole_call: bool = False):
    """Run ``fn`` (returns a Result) up to ``repeats`` times; wall times [s] from the simulator, or
    of the whole call of ``fn`` with ``whole_call``."""
    walls, runs, res = [], [], None
    for k in range(repeats):
        _fresh(model)
        start = time.perf_counter()
        res = fn()
        wall = time.perf_counter() - start
        if not whole_call:
            wall = res.stats.get("wall_time", wall)
        walls.append(wall)
        runs.append(res.stats.get("run_time", math.nan))
        if wall > 1.0:              # long runs: one measurement is enough
            break
    res.stats["run_time_median"] = statistics.median(runs)
    return res, walls


# -------------------------------------------------------------------------------------------------
# hand-written comparison

def _time_calls(fn, args, min_time=0.05) -> float:
    """Median time of one call of ``fn(*a)`` over the argument list ``args`` [s]."""
    reps, samples = 1, []
    for a in args:                   # warm-up (caches, lazy imports)
        fn(*a)
    while True:
        start = time.perf_counter()
        for _ in range(reps):
            for a in args:
                fn(*a)
        el = time.perf_counter() - start
        if el >= min_time / 5 or reps > 1e6:
            break
        reps *= 4
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(reps):
            for a in args:
                fn(*a)
        samples.append((time.perf_counter() - start) / (reps * len(args)))
    return statistics.median(samples)


def hand_model(scene: Scene):
    """The hand-written model of ``scene``: the first answer that is not ``None`` of the callables
    registered in the entry point group ``multipole.hand_models`` (``None`` if none answers)."""
    for _, factory in _registered("multipole.hand_models"):
        hand = factory(scene)
        if hand is not None:
            return hand
    return None


def _registered(group: str):
    """``(name, callable)`` of every entry point of ``group`` whose module imports (a fixture package
    that is not installed is left out, not an error)."""
    for ep in entry_points(group=group):
        try:
            yield ep.name, ep.load()
        except ImportError:
            continue


class _HandResult:
    """A ``solve_ivp`` solution of a hand-written model, shaped like the parts of a Result that
    :func:`_measure` reads: ``t``, ``outputs`` (every output the hand model defines), ``stats``."""

    def __init__(self, hand, sol, solver: str):
        self.t, self.solver, self.events = sol.t, solver, []
        self.outputs = {name: np.asarray(g(sol.t, sol.y), dtype=float) for name, g in hand.outputs.items()}
        self.stats = {"nfev": sol.nfev, "njev": sol.njev, "nlu": sol.nlu}

    def __getitem__(self, name):
        return self.outputs[name]


def solve_hand(hand, t_end: float, grid, solver: str, rtol: float, atol: float,
               max_nfev: int = HAND_MAX_NFEV) -> _HandResult:
    """``solve_ivp`` on the hand-written model over ``[0, t_end]`` [s], sampled on ``grid``; the
    analytic Jacobian is passed to the implicit methods.  A failed integration, or one that needs
    more than ``max_nfev`` right-hand side calls, raises RuntimeError."""
    from scipy.integrate import solve_ivp
    kw = {"jac": hand.jac} if solver in IMPLICIT and hand.jac is not None else {}
    calls = [0]
    rhs = hand.rhs

    def counted(t, x):
        calls[0] += 1
        if calls[0] > max_nfev:
            raise RuntimeError(f"solve_ivp {solver}: stopped after {max_nfev:.3g} right-hand side calls")
        return rhs(t, x)
    sol = solve_ivp(counted, (0.0, t_end), hand.x0, method=solver, t_eval=grid, rtol=rtol, atol=atol, **kw)
    if not sol.success:
        raise RuntimeError(f"solve_ivp {solver}: {sol.message}")
    return _HandResult(hand, sol, solver)


def side_by_side(scene: Scene, model, ref: Reference, chosen: str, rtol: float, atol: float,
                 naive_budget: int, hand=None) -> dict | None:
    """Generated against hand-written right-hand side; naive ``solve_ivp`` against ``auto``.

    When the naive run would need more than ``naive_budget`` evaluations by the stability bound of
    RK45, it is not run; ``naive_lower_s`` = (that many evaluations) × (time of one hand-written
    right-hand side call) is then a lower bound of its wall time [s] (RK45's own per-step work left out).
    """
    from scipy.integrate import solve_ivp
    hand = hand if hand is not None else hand_model(scene)
    if hand is None:
        return None
    idx = hand.permutation(model.state_names)
    rng = np.random.default_rng(0)
    pts = [(float(t), model.x0 + 0.1 * rng.normal(size=len(model.x0))) for t in np.linspace(0, ref.t_end, 8)]
    gen_args = [(t, x) for t, x in pts]
    hand_args = [(t, x[idx]) for t, x in pts]
    mismatch = max(float(np.max(np.abs(model.rhs(t, x)[idx] - hand.rhs(t, xh)))
                        / max(1.0, float(np.max(np.abs(hand.rhs(t, xh)))))) for (t, x), (_, xh) in zip(gen_args, hand_args))
    t_gen = _time_calls(model.rhs, gen_args)
    t_hand = _time_calls(hand.rhs, hand_args)
    jac_ratio = math.nan
    if hand.jac is not None:
        jac_ratio = _time_calls(model.jac, gen_args[:2]) / _time_calls(hand.jac, hand_args[:2])
    out = {"scene": scene.name, "n_states": len(model.x0), "rhs_generated_us": 1e6 * t_gen,
           "rhs_hand_us": 1e6 * t_hand, "rhs_ratio": t_gen / t_hand, "jac_ratio": jac_ratio,
           "rhs_mismatch": mismatch, "solver": chosen, "rtol": rtol}
    # whole run, same solver and tolerances
    res, walls = _one(lambda: simulate(model, ref.t_end, ref.dt_out, chosen, rtol, atol, progress=False), 3, model)
    kw = {"jac": hand.jac} if chosen in IMPLICIT and hand.jac is not None else {}
    method = SOLVERS[chosen]
    hw = []
    for _ in range(len(walls)):
        start = time.perf_counter()
        sol = solve_ivp(hand.rhs, (0.0, ref.t_end), hand.x0, method=method, t_eval=res.t, rtol=rtol, atol=atol, **kw)
        hw.append(time.perf_counter() - start)
    g = hand.outputs.get(ref.output)
    yref = ref.at(res.t)
    out.update({"run_generated_s": statistics.median(walls), "run_hand_s": statistics.median(hw),
                "run_ratio": statistics.median(walls) / statistics.median(hw),
                "nfev_generated": res.stats["nfev"], "nfev_hand": sol.nfev,
                "err_generated": float(np.max(np.abs(res[ref.output] - yref)) / ref.scale),
                "err_hand": float(np.max(np.abs(g(sol.t, sol.y) - yref)) / ref.scale) if g and sol.success
                else math.nan})
    # naive: solve_ivp defaults (RK45, rtol 1e-3, atol 1e-6) on the hand-written right-hand side
    lam = np.linalg.eigvals(hand.jac(0.0, hand.x0)) if hand.jac is not None else []
    bound = explicit_stability_bound(lam, "RK45", ref.t_end)
    out["naive_min_nfev"] = bound["nfev"]
    if bound["nfev"] > naive_budget:
        out.update({"naive_status": f"skipped: the stability bound needs >= {bound['nfev']:.3g} evaluations",
                    "naive_s": math.nan, "naive_err": math.nan, "naive_nfev": math.nan,
                    "naive_lower_s": bound["nfev"] * t_hand})
        return out
    start = time.perf_counter()
    sol = solve_ivp(hand.rhs, (0.0, ref.t_end), hand.x0, t_eval=res.t)
    naive_s = time.perf_counter() - start
    err = float(np.max(np.abs(g(sol.t, sol.y) - yref)) / ref.scale) if g and sol.success else math.nan
    out.update({"naive_status": "ok" if sol.success else sol.message, "naive_s": naive_s, "naive_err": err,
                "naive_nfev": sol.nfev})
    return out


# -------------------------------------------------------------------------------------------------
# the bench

@dataclass
class SceneReport:
    name: str
    path: str
    reference: Reference | None
    runs: list = field(default_factory=list)
    side: dict | None = None
    compile_s: float = math.nan
    stiffness: str = ""
    n_states: int = 0
    no_hand: str = ""                  # why the scene has no hand-written model (``reference: {no_hand_model}``)
    skipped: str = ""
    grid: np.ndarray | None = None     # output grid of the runs [s]
    equal: list = field(default_factory=list)    # rows of equal_error(), every compiled backend
    auto_method: object = None         # rtol -> the method ``auto`` runs
    calls: dict = field(default_factory=dict)    # backend -> call(solver, rtol, atol) -> Result (one run)
    attempts: dict = field(default_factory=dict)  # backend -> the sweep's attempt(solver, rtol, atol)


class _Bar:
    def __init__(self, total, enabled):
        self.total, self.done, self.enabled = max(total, 1), 0, enabled

    def tick(self, label):
        self.done += 1
        if self.enabled:
            frac = self.done / self.total
            sys.stderr.write(f"\r[{'#' * int(30 * frac):<30}] {self.done}/{self.total} {label[:50]:<50}")
            sys.stderr.flush()

    def close(self):
        if self.enabled:
            sys.stderr.write("\n")


def default_scenes() -> list[Scene]:
    """The bench's scenes when no files are given, loaded: every scene offered by the callables
    registered in the entry point group ``multipole.bench_scenes`` that is tagged ``bench: true`` and
    well-posed by declaration (no ``expect_check``).  Found through the installed package's metadata,
    so the same with or without a source checkout.

    A provider returns ``(name, yaml_text)`` pairs (the scene is labelled ``ENTRY:name`` in messages)
    or ``(name, yaml_text, {file name: text})`` triples for a scene that reads data files (contour
    tables): a netlist reads those only from its own folder, so the bench writes the scene and its
    files into a private temporary folder (removed when the process ends) and loads it from there.
    """
    out = []
    for entry, provider in _registered("multipole.bench_scenes"):
        for name, text, *files in provider():
            if files and files[0]:
                sc = loads(text, str(_scene_folder(entry, name, text, files[0])))
            else:
                sc = loads(text, f"{entry}:{name}")
            if sc.bench and not sc.expect_check:
                out.append(sc)
    return out


_SCENE_DIRS: list = []          # the temporary folders of default scenes with data files (kept while the process runs)


def _scene_folder(entry: str, name: str, text: str, files: dict) -> Path:
    """Write a default scene ``name`` of the provider ``entry`` and its data files ``{file name: text}``
    (names relative to the scene's folder) into a private temporary folder; the scene file's path."""
    if not _SCENE_DIRS:
        _SCENE_DIRS.append(tempfile.TemporaryDirectory(prefix="multipole-bench-"))
    root = Path(_SCENE_DIRS[0].name) / entry
    path = root / name
    for rel in [name, *files]:
        if Path(rel).is_absolute() or ".." in Path(rel).parts or not str(rel).strip():
            raise MultipoleError("bad_bench_scene", f"bench scene {entry}:{name}: file name {rel!r} leaves the "
                                 "scene's folder", "name data files relative to the scene, below its folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    for rel, data in files.items():
        target = path.parent / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(data, encoding="utf-8")
    return path


def _sweep(rep: SceneReport, backend: str, solvers, tolerances, ratio: float, budget, lam, bar, attempt) -> None:
    """Every solver of ``solvers`` over ``tolerances`` for one backend, appended to ``rep.runs``.

    ``attempt(solver, rtol, atol)`` returns ``(result, wall times)``.  An explicit method whose
    stability bound needs more than ``budget`` evaluations is skipped with that bound as the message
    (for ``auto``: the method it would choose); a run longer than :data:`SLOW_RUN_S` skips the
    tighter tolerances of its solver.
    """
    for solver in solvers:
        slow = False
        for rtol in tolerances:
            run = Run(rep.name, backend, solver, rtol, rtol * ratio)
            rep.runs.append(run)
            bar.tick(f"{rep.name} {backend} {solver} {rtol:g}")
            if slow:
                run.status, run.message = "skipped", "a looser tolerance already exceeded the time budget"
                continue
            method = rep.auto_method(rtol) if solver == "auto" else solver
            if method in EXPLICIT_RK:
                bound = explicit_stability_bound(lam, method, rep.reference.t_end)
                if bound["nfev"] > budget:
                    run.status = "skipped"
                    run.message = ((f"auto would run {method}: " if solver == "auto" else "")
                                   + f"stability bound: h <= {bound['h_max']:.3g} s, >= {bound['nfev']:.3g} "
                                   f"evaluations (budget {budget:.3g})")
                    continue
            try:
                res, walls = attempt(solver, rtol, run.atol)
                _measure(run, rep.reference, res, walls)
                if rep.grid is None:
                    rep.grid = np.asarray(res.t)
                if solver != "auto" and res.solver != solver:
                    run.message = f"run as {res.solver} by the {backend} backend"
                slow = run.wall_s > SLOW_RUN_S
            except MultipoleError as exc:
                unsupported = exc.code == "unknown_solver" and backend != "numpy"
                run.status = "unsupported" if unsupported else "failed"
                run.message = str(exc).splitlines()[0][:200]
            except (ArithmeticError, ValueError, np.linalg.LinAlgError, RuntimeError) as exc:
                run.status, run.message = "failed", str(exc).splitlines()[0][:200]


def bench_scene(scene: Scene, solvers, tolerances, repeats, backends, budget, bar, naive_budget) -> SceneReport:
    """Reference, solver × tolerance sweep for every backend and for the hand-written model, the
    equal-error comparison of every compiled backend with the hand-written model, and the
    side-by-side comparison of one scene."""
    rep = SceneReport(scene.name, scene.path, None)
    analysis = pipeline.check(scene)
    if not analysis.ok:
        rep.skipped = "not well-posed: " + analysis.errors[0].message
        return rep
    start = time.perf_counter()
    model = pipeline.model(scene)
    rep.compile_s = time.perf_counter() - start
    rep.n_states = len(model.x0)
    ref = build_reference(scene, model)
    rep.reference = ref
    rep.no_hand = reference_spec(scene).get("no_hand_model", "")
    rep.stiffness = choose_solver(model, ref.t_end, 1e-6)[1].replace("|lambda|max*t_end", "λmax·t_end")

    def auto_method(rtol):
        return choose_solver(model, ref.t_end, rtol)[0]
    rep.auto_method = auto_method
    try:
        lam = np.linalg.eigvals(model.jac(0.0, model.x0)) if len(model.x0) else []
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):
        lam = []
    ratio = scene.simulate.get("atol", 1e-9) / scene.simulate.get("rtol", 1e-6)

    def on_numpy(solver, rtol, atol):
        return _one(lambda: simulate(model, ref.t_end, ref.dt_out, solver, rtol, atol, progress=False), repeats, model)
    _sweep(rep, "numpy", solvers, tolerances, ratio, budget, lam, bar, on_numpy)
    compiled = [b for b in backends if b != "numpy"]
    if compiled:
        from .backends import get_backend
        eq = pipeline.equations(scene)
        outs = list(model.output_names)
    for backend in compiled:
        run_backend = get_backend(backend)
        for solver in solvers:        # untimed: compile the model, load every method's loop
            try:
                run_backend(eq, outs, ref.t_end * 1e-3, None, solver, 1e-3, 1e-3 * ratio, math.inf, False)
            except (MultipoleError, ArithmeticError, ValueError, RuntimeError):
                pass                  # the sweep reports it

        def call(solver, rtol, atol, run_backend=run_backend):
            return run_backend(eq, outs, ref.t_end, ref.dt_out, solver, rtol, atol, math.inf, False)

        def on_backend(solver, rtol, atol, call=call):
            return _one(lambda: call(solver, rtol, atol), repeats, whole_call=True)
        rep.calls[backend] = call
        rep.attempts[backend] = on_backend
        _sweep(rep, backend, solvers, tolerances, ratio, budget, lam, bar, on_backend)
    hand = hand_model(scene)
    if hand is not None:
        grid = ref.grid if ref.grid is not None else rep.grid

        def on_hand(solver, rtol, atol):
            return _one(lambda: solve_hand(hand, ref.t_end, grid, solver, rtol, atol), repeats, whole_call=True)
        rep.calls[HAND] = lambda solver, rtol, atol: solve_hand(hand, ref.t_end, grid, solver, rtol, atol)
        _sweep(rep, HAND, HAND_SOLVERS, tolerances, ratio, budget, lam, bar, on_hand)
        if compiled:            # every contender reaches every level, or says it cannot
            extend_ladder(rep, HAND, EQUAL_ERROR_LEVELS, on_hand, ratio)
        for backend in compiled:
            extend_ladder(rep, backend, EQUAL_ERROR_LEVELS, rep.attempts[backend], ratio)
            rep.equal += equal_error(rep, backend, rounds=3 if repeats == 1 else TIMING_ROUNDS)
    auto = [r for r in rep.runs if r.solver == "auto" and r.backend == "numpy" and r.status == "ok"]
    chosen = auto[len(auto) // 2].chosen if auto else "Radau"
    rtol = scene.simulate.get("rtol", 1e-6)
    rep.side = side_by_side(scene, model, ref, chosen, rtol, rtol * ratio, naive_budget, hand)
    if rep.side is not None:
        rep.side.update(_naive_vs_auto(rep))
    return rep


def run_label(r: Run) -> str:
    """The requested solver, with the method that ran when that differs (``auto→Radau``)."""
    return r.solver if not r.chosen or r.chosen == r.solver else f"{r.solver}→{r.chosen}"


@dataclass
class Timing:
    """CPU and wall times [s] of one contender, one entry per interleaved round."""
    cpu: list = field(default_factory=list)
    wall: list = field(default_factory=list)


def interleaved(contenders: dict, rounds: int = TIMING_ROUNDS) -> dict:
    """Time the contenders ``{name: call without arguments}`` in turn, A B A B ...: one untimed
    warm-up call each, then ``rounds`` rounds of one call each; ``{name: Timing}`` with the CPU time
    of the process (``time.process_time``) and the wall time of every call.  Alternating makes a
    change of the machine's load hit both sides alike, and CPU time does not count the time other
    processes hold the cores."""
    timings = {name: Timing() for name in contenders}
    for fn in contenders.values():
        fn()
    for _ in range(rounds):
        for name, fn in contenders.items():
            cpu, wall = time.process_time(), time.perf_counter()
            fn()
            timings[name].cpu.append(time.process_time() - cpu)
            timings[name].wall.append(time.perf_counter() - wall)
    return timings


def ratio_verdict(hand: Timing, comp: Timing, target: float = SPEEDUP_TARGET) -> dict:
    """The speed-up of ``comp`` over ``hand`` from interleaved timings: the ratio of CPU times of
    every round (the two ran back to back), its median and spread (lowest, highest), the median
    wall-time ratio, and the verdict: ``met`` only if even the lowest round reaches ``target``,
    ``not met`` if even the highest stays below it, else ``within noise``."""
    tiny = 1e-9                        # [s] a CPU clock reading of zero
    ratios = [h / max(c, tiny) for h, c in zip(hand.cpu, comp.cpu)]
    lo, hi = min(ratios), max(ratios)
    verdict = "met" if lo >= target else "not met" if hi < target else f"within noise ({lo:.3g}–{hi:.3g}×)"
    return {"ratio": statistics.median(ratios), "ratio_lo": lo, "ratio_hi": hi,
            "ratio_wall": statistics.median(hand.wall) / max(statistics.median(comp.wall), tiny),
            "hand_cpu_s": statistics.median(hand.cpu), "backend_cpu_s": statistics.median(comp.cpu),
            "hand_wall_s": statistics.median(hand.wall), "backend_wall_s": statistics.median(comp.wall),
            "rounds": len(ratios), "verdict": verdict}


def extend_ladder(rep: SceneReport, backend: str, levels, attempt, ratio: float, floor: float = LADDER_FLOOR) -> None:
    """For every error level (looser first) and every solver of ``backend`` whose successful runs
    all miss it: continue that solver's ladder, rtol / 10 at a time down to ``floor``, until a run
    reaches the level, a run fails, the error stops falling (less than halved: the method's own
    floor), or a run is already slower than the fastest run of ``backend`` that reaches the level (a
    tighter one would not be faster).  A solver whose ladder ended with a run that did not succeed
    (failed, skipped) is left alone.  The runs are appended to ``rep.runs`` with the message
    ``ladder extended``; a level still unreached is marked so by :func:`equal_error`.  ``attempt``
    is :func:`_sweep`'s."""
    for level in sorted(levels, reverse=True):
        if level <= 3 * rep.reference.error:
            continue
        for solver in dict.fromkeys(r.solver for r in rep.runs if r.backend == backend):
            mine = [r for r in rep.runs if r.backend == backend and r.solver == solver]
            ok = [r for r in mine if r.status == "ok" and math.isfinite(r.err_max)]
            if not ok or min(r.err_max for r in ok) <= level:
                continue
            tightest = min(ok, key=lambda r: r.rtol)
            best = fastest(rep, level, backend)
            if any(r.status != "ok" and r.rtol < tightest.rtol for r in mine) or (
                    best is not None and tightest.wall_s >= best.wall_s):
                continue
            k, last = 1, tightest.err_max
            while (rtol := tightest.rtol / 10**k) >= floor * (1 - 1e-9):
                run = Run(rep.name, backend, solver, rtol, rtol * ratio, message="ladder extended")
                rep.runs.append(run)
                try:
                    res, walls = attempt(solver, rtol, run.atol)
                    _measure(run, rep.reference, res, walls)
                except (MultipoleError, ArithmeticError, ValueError, np.linalg.LinAlgError, RuntimeError) as exc:
                    run.status, run.message = "failed", "ladder extended: " + str(exc).splitlines()[0][:160]
                    break
                if run.err_max <= level or run.err_max > 0.5 * last or (best is not None and run.wall_s >= best.wall_s):
                    break
                k, last = k + 1, run.err_max


def _tightest(rep: SceneReport, backend: str) -> str:
    tried = [r.rtol for r in rep.runs if r.backend == backend and r.status == "ok"]
    return f"down to rtol {min(tried):g}" if tried else "no successful run"


def equal_error(rep: SceneReport, backend: str, levels=EQUAL_ERROR_LEVELS, rounds: int = TIMING_ROUNDS) -> list[dict]:
    """Compiled ``backend`` against the hand-written model with ``solve_ivp`` at equal error.

    For each error level: the fastest successful hand-written run (any of :data:`HAND_SOLVERS`, any
    tolerance) with ``err_max <= level`` and the fastest successful ``backend`` run (any requested
    solver) with ``err_max <= level``, chosen by their sweep wall times (``hand_s``, ``backend_s``).
    Where ``rep.calls`` can run both again, the two are re-timed :func:`interleaved` over ``rounds``
    rounds and :func:`ratio_verdict` gives the CPU-time ratio with its spread and the verdict
    against :data:`SPEEDUP_TARGET` (``met`` only beyond the spread); otherwise ``ratio`` is the
    ratio of the sweep wall times.  ``ratio_run`` uses the backend's own run time (integration and
    output sampling, without the fixed cost of a call), for explanation only.  A level within 3×
    the reference's own error is not measurable; one a side never reached, its ladder extended
    (:func:`extend_ladder`), is marked unreached.
    """
    rows = []
    for level in levels:
        hand, comp = fastest(rep, level, HAND), fastest(rep, level, backend)
        row = {"scene": rep.name, "backend": backend, "level": level, "ratio": math.nan, "ratio_run": math.nan}
        for key, r in (("hand", hand), ("backend", comp)):
            row.update({f"{key}_solver": run_label(r) if r else "", f"{key}_rtol": r.rtol if r else math.nan, f"{key}_s": r.wall_s if r else math.nan,
                        f"{key}_err": r.err_max if r else math.nan, f"{key}_nfev": r.nfev if r else math.nan})
        row["backend_run_s"] = comp.run_s if comp else math.nan
        row["backend_newton"] = comp.newton_iterations if comp else math.nan
        if level <= 3 * rep.reference.error:
            row["verdict"] = f"not measurable (reference error {rep.reference.error:.1g})"
        elif comp is None and hand is None:
            row["verdict"] = (f"not compared: unreached by {backend} ({_tightest(rep, backend)}) and by the "
                              f"hand-written model ({_tightest(rep, HAND)})")
        elif comp is None:
            row["verdict"] = f"not met: unreached by {backend} ({_tightest(rep, backend)})"
        elif hand is None:
            row["verdict"] = f"unreached by the hand-written model ({_tightest(rep, HAND)})"
        else:
            row["ratio_run"] = hand.wall_s / comp.run_s
            if HAND in rep.calls and backend in rep.calls:
                calls = {"hand": lambda: rep.calls[HAND](hand.solver, hand.rtol, hand.atol),
                         "backend": lambda: rep.calls[backend](comp.solver, comp.rtol, comp.atol)}
                timing = interleaved(calls, rounds)
                row.update(ratio_verdict(timing["hand"], timing["backend"]))
                row["ratio_run"] = row["hand_cpu_s"] / comp.run_s
            else:
                row["ratio"] = hand.wall_s / comp.wall_s
                row["verdict"] = "met" if row["ratio"] >= SPEEDUP_TARGET else "not met"
        rows.append(row)
    return rows


def _naive_vs_auto(rep: SceneReport) -> dict:
    """Fastest ``auto`` run (numpy backend) at least as accurate as the naive run, and the wall-time ratio.

    A naive run skipped for its evaluation budget has no error to match: the lower bound of its wall
    time (``naive_lower_s``) is set against the most accurate ``auto`` run of the sweep, which
    takes at least as long as the fastest ``auto`` run reaching any error down to its own; so
    ``naive_speedup_min`` bounds the speed-up at equal error from below (unless the naive run would
    be more accurate than every ``auto`` run).
    """
    side = rep.side
    err = side.get("naive_err", math.nan)
    ok = [r for r in rep.runs if r.solver == "auto" and r.backend == "numpy" and r.status == "ok"]
    if not ok:
        return {}
    if not math.isfinite(err):
        best = min(ok, key=lambda r: r.err_max)
        return {"auto_equal_err_s": best.wall_s, "auto_equal_err": best.err_max, "auto_equal_rtol": best.rtol,
                "naive_speedup_min": side.get("naive_lower_s", math.nan) / best.wall_s}
    good = [r for r in ok if r.err_max <= err]
    if not good:
        return {"auto_equal_err_s": math.nan}
    best = min(good, key=lambda r: r.wall_s)
    return {"auto_equal_err_s": best.wall_s, "auto_equal_err": best.err_max, "auto_equal_rtol": best.rtol,
            "naive_speedup": side["naive_s"] / best.wall_s}


def run_bench(files=None, out_dir="bench_out", quick=False, quiet=False, solvers=None, tolerances=None,
              repeats=None, budget=None, figures_dir=None) -> list[SceneReport]:
    """Run the bench and write its CSV files, figures and summary into ``out_dir``.

    ``figures_dir`` (default ``out_dir``) receives the work-precision figures ``bench_<scene>.png``.
    """
    from .backends import available
    solvers = list(solvers or SWEEP_SOLVERS)
    for s in solvers:
        if s != "auto" and s not in SOLVERS:
            raise MultipoleError("unknown_solver", f"unknown solver {s!r}", f"use auto or one of {', '.join(SOLVERS)}")
    tolerances = list(tolerances or (QUICK_TOLERANCES if quick else TOLERANCES))
    repeats = repeats or (1 if quick else 3)
    budget = budget or (5e4 if quick else 4e5)
    naive_budget = 2e5 if quick else 2e7
    backends = ["numpy"] + [b for b in available() if b != "numpy"]
    scenes = [load(f) for f in files] if files else default_scenes()
    per_scene = len(tolerances) * (len(solvers) * len(backends) + len(HAND_SOLVERS))
    bar = _Bar(len(scenes) * per_scene, sys.stderr.isatty() and not quiet)
    reports = []
    for sc in scenes:
        reports.append(bench_scene(sc, solvers, tolerances, repeats, backends, budget, bar, naive_budget))
    bar.close()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(reports, out / "bench.csv")
    write_side_csv(reports, out / "side_by_side.csv")
    write_rows([row for rep in reports for row in rep.equal], EQUAL_FIELDS, out / "equal_error.csv")
    figs = Path(figures_dir) if figures_dir else out
    figs.mkdir(parents=True, exist_ok=True)
    for rep in reports:
        if rep.reference is not None:
            plot_work_precision(rep, figs / f"bench_{rep.name}.png")
    (out / "summary.md").write_text(summary(reports, quick), encoding="utf-8")
    return reports


def write_rows(rows, fields, path) -> None:
    """Dicts as CSV rows (floats to 6 significant digits; keys outside ``fields`` left out)."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fields)
        w.writeheader()
        for row in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items() if k in fields})


def write_csv(reports, path) -> None:
    write_rows([r.row() for rep in reports for r in rep.runs], CSV_FIELDS, path)


SIDE_FIELDS = ["scene", "n_states", "solver", "rtol", "rhs_generated_us", "rhs_hand_us", "rhs_ratio", "jac_ratio",
               "rhs_mismatch", "run_generated_s", "run_hand_s", "run_ratio", "nfev_generated", "nfev_hand",
               "err_generated", "err_hand", "naive_status", "naive_s", "naive_err", "naive_nfev", "naive_min_nfev",
               "auto_equal_err_s", "auto_equal_err", "auto_equal_rtol", "naive_speedup", "naive_lower_s",
               "naive_speedup_min"]
EQUAL_FIELDS = ["scene", "backend", "level", "hand_solver", "hand_rtol", "hand_s", "hand_err", "hand_nfev",
                "backend_solver", "backend_rtol", "backend_s", "backend_err", "backend_nfev", "backend_newton",
                "backend_run_s", "hand_cpu_s", "backend_cpu_s", "hand_wall_s", "backend_wall_s", "rounds",
                "ratio", "ratio_lo", "ratio_hi", "ratio_wall", "ratio_run", "verdict"]


def write_side_csv(reports, path) -> None:
    write_rows([rep.side for rep in reports if rep.side], SIDE_FIELDS, path)


_STYLE = {"RK45": ("tab:blue", "o"), "DOP853": ("tab:orange", "s"), "Radau": ("tab:green", "^"),
          "BDF": ("tab:red", "v"), "LSODA": ("tab:purple", "D"), "GL4": ("tab:brown", "P"),
          "auto": ("black", "*"), "RK23": ("tab:pink", "x")}


#: line style of each kind of run: colour is the method, the line says who ran it
_LINE = {"numpy": ("-", "numpy backend"), HAND: (":", "hand-written + solve_ivp")}


def _backend_line(backend: str) -> tuple[str, str]:
    return _LINE.get(backend, ("--", f"{backend} backend"))


def plot_work_precision(rep: SceneReport, path) -> None:
    """Three log-log panels, one curve per solver in each: (1) error against wall time on the numpy
    backend; (2) error against wall time of every compiled backend (dashed) and of the hand-written
    model with ``solve_ivp`` (dotted) — the equal-error comparison; (3) error against nfev, numpy
    backend.  Colour: the method; line style: who ran it (said in each legend)."""
    from .plotting import new_figure          # no pyplot: the caller's backend is left alone
    fig = new_figure(16.5, 7.0, layout=None)
    axes = fig.subplots(1, 3, sharey=True)
    axes[1].sharex(axes[0])            # the same wall-time scale for numpy, compiled and hand-written runs
    floor = max(rep.reference.error, 1e-16)
    panels = [(axes[0], "wall_s", {"numpy"}, "numpy backend (generated model + scipy)"),
              (axes[1], "wall_s", {b for b in {r.backend for r in rep.runs} if b != "numpy"},
               "compiled backend (dashed), no hand-written model" if rep.no_hand else
               "compiled backend (dashed) vs hand-written solve_ivp (dotted)"),
              (axes[2], "nfev", {"numpy"}, "numpy backend: work")]
    for ax, key, backends, title in panels:
        for (solver, backend) in dict.fromkeys((r.solver, r.backend) for r in rep.runs):
            runs = [r for r in rep.runs if r.solver == solver and r.backend == backend and r.status == "ok"
                    and (r.chosen == solver or solver == "auto")]          # a backend's stand-ins are not curves
            if backend not in backends or not runs:
                continue
            color, marker = _STYLE.get(solver, ("gray", "."))
            ls, who = _backend_line(backend)
            label = solver if len(backends) == 1 else f"{solver}, {who}"
            err = [max(r.err_max, floor * 0.5) for r in runs]
            ax.loglog([getattr(r, key) for r in runs], err, ls, color=color, marker=marker, label=label, ms=5)
        ax.set_xlabel("wall time [s]" if key == "wall_s" else "right-hand side evaluations (nfev)")
        ax.set_title(title, fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        if rep.reference.error > 0:
            ax.axhline(rep.reference.error, color="0.5", ls="-.", lw=1)
            ax.text(0.01, rep.reference.error, "reference error", va="bottom", fontsize=7, color="0.4",
                    transform=ax.get_yaxis_transform())
        if ax.get_legend_handles_labels()[0]:            # below the panel, so that no curve is hidden
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, title_fontsize=7,
                      title="colour: solver" + ("" if len(backends) == 1 else "; line: dashed compiled, dotted hand-written"))
    axes[0].set_ylabel(f"max relative error of {rep.reference.output}")
    skipped = sorted({r.solver for r in rep.runs if r.status == "skipped"})
    failed = sorted({f"{r.solver} [{r.backend}]" for r in rep.runs if r.status == "failed"})
    note = (f"skipped (stability/time budget): {', '.join(skipped)}" if skipped else "") + \
           (f"   failures: {', '.join(failed)}" if failed else "")
    fig.suptitle(f"{rep.name}: work-precision ({rep.reference.note.split(';')[0]}; {rep.n_states} states)",
                 fontsize=10)
    if note:
        fig.text(0.5, 0.01, note, ha="center", fontsize=8, color="0.3")
    fig.tight_layout(rect=(0, 0.03, 1, 0.96))
    fig.savefig(path, dpi=110)


# -------------------------------------------------------------------------------------------------
# summary

def _fmt(x, spec=".2g"):
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def fastest(rep: SceneReport, target: float, backend: str = "numpy"):
    """The fastest successful run of ``backend`` with ``err_max <= target`` (``None`` if none)."""
    ok = [r for r in rep.runs if r.status == "ok" and r.backend == backend and r.err_max <= target]
    return min(ok, key=lambda r: r.wall_s) if ok else None


_WHY_WINNER = {
    "RK45": "RK45: cheap low-order explicit steps suffice at this accuracy",
    "RK23": "RK23: cheap low-order explicit steps suffice at this accuracy",
    "DOP853": "DOP853: order 8, fewest explicit steps at tight tolerances",
    "LSODA": "LSODA: its stepping loop is compiled Fortran (Adams methods while non-stiff, BDF when stiff), so "
             "it pays the least Python overhead per step; only the right-hand side and Jacobian calls are Python",
    "Radau": "Radau: order-5 implicit steps with the analytic Jacobian, not limited by stability",
    "BDF": "BDF: cheap implicit multistep steps with the analytic Jacobian",
    "GL4": "GL4: implicit order-4 collocation",
}


def recommendation(rep: SceneReport) -> str:
    """One paragraph: which solver to pick for this scene and why, from the measured runs."""
    ref = rep.reference
    targets = [t for t in (1e-3, 1e-6, 1e-9) if t > 3 * ref.error]
    picks = {t: fastest(rep, t) for t in targets}
    stiff = rep.stiffness.startswith("stiff")
    numpy_ok = [r for r in rep.runs if r.status == "ok" and r.backend == "numpy"]
    events = max((r.events for r in numpy_ok), default=0)
    parts, winners = [], []
    for t, p in picks.items():
        if p:
            winners.append(p.chosen if p.solver == "auto" else p.solver)
            label = f"auto → {p.chosen}" if p.solver == "auto" else p.solver
            parts.append(f"error ≤ {t:g}: **{label}** (rtol {p.rtol:g}, {p.wall_s * 1e3:.3g} ms, nfev {p.nfev})")
        else:
            parts.append(f"error ≤ {t:g}: no run reached it")
    why = [f"{'stiff' if stiff else 'not stiff'} ({rep.stiffness.split('(', 1)[-1].rstrip(')')})"]
    skipped = sorted({r.solver for r in rep.runs if r.status == "skipped" and r.backend == "numpy"
                      and r.message.startswith("stability")})
    if skipped:
        msg = next(r.message for r in rep.runs if r.status == "skipped" and r.solver == skipped[0])
        why.append(f"explicit methods ({', '.join(skipped)}) are held to the stability limit of the fast mode "
                   f"whatever the tolerance ({msg})")
    why += [_WHY_WINNER[w] for w in dict.fromkeys(winners) if w in _WHY_WINNER]
    if events:
        why.append(f"the scene switches ({events} events per run): every event restarts the integrator — the "
                   "multistep methods (BDF, LSODA) restart at order 1, one-step methods lose only the step-size "
                   "history")
    energy = [r for r in numpy_ok if math.isfinite(r.energy_drift)]
    if energy:
        best = min(energy, key=lambda r: r.energy_drift)
        gl = [r.energy_drift for r in energy if r.solver == "GL4"]
        why.append(f"the smallest energy drift is {best.solver}'s ({best.energy_drift:.2g} at rtol {best.rtol:g})"
                   + (f"; GL4 (Gauss–Legendre) conserves a quadratic energy at its steps, what remains "
                      f"({min(gl):.2g}) is interpolation between steps" if gl and min(gl) < 1e-6 else ""))
    failed = [r for r in rep.runs if r.status == "failed" and r.backend == "numpy"]
    if failed:
        why.append(f"{len(failed)} run(s) failed ({', '.join(sorted({f'{r.solver} rtol {r.rtol:g}' for r in failed}))}): "
                   f"{failed[0].message}")
    auto = [r for r in numpy_ok if r.solver == "auto"]
    if auto:
        why.append(f"`auto` chose {', '.join(dict.fromkeys(r.chosen for r in auto))}")
    pick = max(dict.fromkeys(winners), key=winners.count) if winners else "Radau"
    return f"Pick **{pick}**. " + "; ".join(parts) + ". Why: " + "; ".join(why) + "."


def equal_error_table(rows) -> list:
    """Markdown lines of :func:`equal_error` rows (nothing for no rows)."""
    if not rows:
        return []
    lines = [f"Compiled backend against the hand-written model with `solve_ivp` at equal error (target ≥ "
             f"{SPEEDUP_TARGET:g}× less CPU time; the two runs re-timed interleaved, A B A B …; the ratio is the "
             "median over the rounds with its lowest and highest round, and \"met\" needs the lowest round to "
             "reach the target):", "",
             "| backend | error ≤ | hand-written: solver, rtol, error, CPU [ms] | backend: solver, rtol, error, CPU [ms] "
             "| CPU ratio [lowest–highest] | wall ratio | verdict | backend's run time alone [ms], ratio |",
             "|---|---|---|---|---|---|---|---|"]
    for row in rows:
        cells = []
        for key in ("hand", "backend"):
            t = row.get(key + "_cpu_s", row[key + "_s"])
            cells.append(f"{row[key + '_solver']}, {row[key + '_rtol']:g}, {row[key + '_err']:.2g}, {_fmt(t * 1e3, '.3g')}"
                         if row[key + "_solver"] else "—")
        spread = (f" [{_fmt(row['ratio_lo'], '.3g')}–{_fmt(row['ratio_hi'], '.3g')}]" if "ratio_lo" in row else "")
        lines.append(f"| {row['backend']} | {row['level']:g} | {cells[0]} | {cells[1]} | {_fmt(row['ratio'], '.3g')}{spread} | "
                     f"{_fmt(row.get('ratio_wall', math.nan), '.3g')} | {row['verdict']} | "
                     f"{_fmt(row['backend_run_s'] * 1e3, '.3g')}, {_fmt(row['ratio_run'], '.3g')} |")
    return lines + [""]


def summary(reports, quick: bool) -> str:
    lines = ["# multipole bench — speed against error", "",
             "Errors are relative to the compared output's largest magnitude: `err_max` is the largest deviation "
             "over the output grid, `err_final` the one at the end.  Wall times are the simulator's integration "
             "time (compilation excluded) for the numpy backend, the whole backend call for a compiled backend "
             "and the whole `solve_ivp` call for the hand-written model (`scipy-hand`), median of repeats.  "
             "`rejected` is reported where the integrator exposes it; `solve_ivp` with `t_eval` does not expose "
             "steps (0 in its rows).  A compiled backend runs DOP853 and RK23 as RK45, BDF and LSODA as Radau "
             "(marked `→`).", ""]
    if quick:
        lines += ["*Quick run: fewer tolerances, single repeats.*", ""]
    for rep in reports:
        lines += [f"## {rep.name}", "", f"`{rep.path}`", ""]
        if rep.skipped:
            lines += [f"Skipped: {rep.skipped}", ""]
            continue
        ref = rep.reference
        lines += [f"- states: {rep.n_states}; compile (check + equations + codegen): {rep.compile_s:.3g} s",
                  f"- reference: {ref.note}; compared output `{ref.output}`; estimated error of the reference "
                  f"{ref.error:.2g}" if ref.kind == "tight" else
                  f"- reference: closed form of `{ref.output}` (exact up to round-off)",
                  f"- stiffness: {rep.stiffness}"]
        if rep.no_hand:
            lines.append(f"- no hand-written model (so no equal-error rows): {' '.join(rep.no_hand.split())}")
        lines += ["", recommendation(rep), "",
                  "| solver | rtol | status | err_max | err_final | energy drift | wall [ms] | nfev | njev | nlu | "
                  "steps | rejected |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rep.runs:
            name = r.solver if r.backend == "numpy" else f"{r.solver} [{r.backend}]"
            if r.chosen and r.chosen != r.solver:
                name += f" → {r.chosen}"
            if r.status != "ok":
                lines.append(f"| {name} | {r.rtol:g} | {r.status} | {r.message} | | | | | | | | |")
                continue
            lines.append(f"| {name} | {r.rtol:g} | ok | {_fmt(r.err_max)} | {_fmt(r.err_final)} | "
                         f"{_fmt(r.energy_drift)} | {r.wall_s * 1e3:.3g} | {r.nfev} | {r.njev} | {r.nlu} | {r.steps} | "
                         f"{r.rejected if r.rejected != '' else 'n/a'} |")
        lines.append("")
        lines += equal_error_table(rep.equal)
        if rep.side:
            s = rep.side
            lines += ["Generated model against a hand-written numpy right-hand side of the same equations:", "",
                      f"- per call: generated {s['rhs_generated_us']:.3g} µs, hand-written {s['rhs_hand_us']:.3g} µs, "
                      f"ratio **{s['rhs_ratio']:.2f}** (Jacobian ratio {_fmt(s['jac_ratio'], '.2f')}); the two "
                      f"right-hand sides agree to {s['rhs_mismatch']:.1g}",
                      f"- whole run with {s['solver']} at rtol {s['rtol']:g}: multipole {s['run_generated_s'] * 1e3:.3g} ms "
                      f"(nfev {s['nfev_generated']}), hand-written + solve_ivp {s['run_hand_s'] * 1e3:.3g} ms "
                      f"(nfev {s['nfev_hand']}), ratio **{s['run_ratio']:.2f}**",
                      "- naive `solve_ivp` defaults (RK45, rtol 1e-3) on the hand-written model: "
                      + (f"{s['naive_s'] * 1e3:.3g} ms, error {s['naive_err']:.2g}, nfev {s['naive_nfev']}"
                         if s.get("naive_status") == "ok" else str(s.get("naive_status")))
                      + (f"; `auto` at equal or better error: {s['auto_equal_err_s'] * 1e3:.3g} ms "
                         f"(rtol {s['auto_equal_rtol']:g}, error {s['auto_equal_err']:.2g}), "
                         f"**{s['naive_speedup']:.3g}× faster**" if math.isfinite(s.get("naive_speedup", math.nan))
                         else "")
                      + (f"; lower bound of its wall time: {s['naive_lower_s']:.3g} s (stability bound × time of one "
                         f"hand-written call); the most accurate `auto` run (error {s['auto_equal_err']:.2g}, rtol "
                         f"{s['auto_equal_rtol']:g}) took {s['auto_equal_err_s'] * 1e3:.3g} ms: **≥ "
                         f"{s['naive_speedup_min']:.3g}× faster** at equal error"
                         if math.isfinite(s.get("naive_speedup_min", math.nan)) else ""), ""]
    return "\n".join(lines) + "\n"


def cmd_bench(args) -> int:
    """CLI entry: ``multipole bench [FILES...] [-o DIR] [--quick] [--quiet]``."""
    reports = run_bench(args.files or None, args.output, quick=args.quick, quiet=args.quiet)
    ok = sum(r.status == "ok" for rep in reports for r in rep.runs)
    failed = sum(r.status == "failed" for rep in reports for r in rep.runs)
    print(f"bench: {len(reports)} scene(s), {ok} run(s) ok, {failed} failed; wrote {args.output}/bench.csv, "
          f"side_by_side.csv, equal_error.csv, summary.md and {sum(r.reference is not None for r in reports)} figure(s)")
    return 0
