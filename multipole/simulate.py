"""Simulation: integrate a compiled :class:`~multipole.codegen.Model` and return a :class:`Result`.

The driver steps scipy's ``OdeSolver`` classes itself, so that it can

* sample the outputs on the ``dt_out`` grid from the dense output,
* find the zero crossings of the switching functions (steps, max/min, abs, sign, tables) and
  restart the integrator exactly there (switching laws are events, not kinks inside a step):
  during a segment every switch is held on the side it started on (``Model.rhs_in_mode``), so
  the integrator sees a smooth right-hand side, and a crossing found after a step ends the
  segment at the root of the switching function,
* count accepted steps (and, for explicit Runge–Kutta methods, rejected ones),
* show a progress bar on a terminal.

Solver ``auto`` estimates stiffness from the eigenvalues of the analytic Jacobian at the start and
picks an implicit method (Radau, with the Jacobian) or an explicit one (DOP853 for tight
tolerances, RK45 otherwise); the reason is kept in ``Result.solver_reason``.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau
from scipy.optimize import brentq

from .errors import MultipoleError, NewtonError
from .solvers import GL4

SOLVERS = {"RK45": RK45, "RK23": RK23, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA, "GL4": GL4}
IMPLICIT = {"Radau", "BDF", "LSODA", "GL4"}
_STAGES = {"RK45": 6, "RK23": 3, "DOP853": 12}


class SimulationError(MultipoleError):
    """The integration failed (the message says where and why)."""


@dataclass
class Result:
    """Sampled outputs and solver statistics of one run."""

    t: np.ndarray
    outputs: dict                 # name -> array over t
    states: np.ndarray            # shape (len(t), n_states)
    state_names: list
    solver: str
    solver_reason: str
    stats: dict = field(default_factory=dict)
    events: list = field(default_factory=list)   # (t, switching function text)
    units: dict = field(default_factory=dict)    # output name -> SI unit

    def __getitem__(self, name):
        if name in self.outputs:
            return self.outputs[name]
        if name in self.state_names:
            return self.states[:, self.state_names.index(name)]
        raise KeyError(name)

    def to_csv(self, path) -> None:
        """CSV: ``t`` then one column per output (DESIGN §6)."""
        names = list(self.outputs)
        data = np.column_stack([self.t] + [self.outputs[n] for n in names])
        np.savetxt(path, data, delimiter=",", header=",".join(["t"] + names), comments="", fmt="%.12g")

    def summary(self) -> str:
        s = self.stats
        parts = [f"solver {self.solver} ({self.solver_reason})",
                 f"steps {s.get('steps', 0)}", f"rejected {s.get('rejected', 'n/a')}",
                 f"nfev {s.get('nfev', 0)}", f"njev {s.get('njev', 0)}", f"nlu {s.get('nlu', 0)}",
                 f"events {len(self.events)}", f"wall {s.get('wall_time', 0):.3g} s"]
        if s.get("model_cached"):
            parts.append("model from cache")
        elif "compile_time" in s:
            parts.append(f"compile {s['compile_time']:.3g} s")
        if s.get("newton_solves"):
            parts.append(f"newton {s['newton_iterations']} it / {s['newton_solves']} solves")
        return ", ".join(parts)

    def plot(self, path=None, title: str = ""):
        """One panel per output over time; saved to ``path`` when given. Returns the figure."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        names = list(self.outputs) or self.state_names
        n = len(names)
        fig, axes = plt.subplots(n, 1, figsize=(8, 1.9 * n + 1.0), sharex=True, squeeze=False)
        for ax, name in zip(axes[:, 0], names):
            ax.plot(self.t, self[name], lw=1.4)
            unit = self.units.get(name, "")
            ax.set_ylabel(f"{name}\n[{unit}]" if unit else name, rotation=0, ha="right", va="center", fontsize=9)
            ax.grid(alpha=0.3)
            for te, _ in self.events[:50]:
                ax.axvline(te, color="0.6", lw=0.6, ls=":")
        axes[-1, 0].set_xlabel("t [s]")
        import textwrap
        fig.suptitle(textwrap.fill(title or "simulation", 90), fontsize=10)
        fig.text(0.99, 0.005, self.summary(), ha="right", va="bottom", fontsize=6, color="0.35")
        fig.tight_layout(rect=(0, 0.02, 1, 1))
        if path:
            fig.savefig(path, dpi=120)
            plt.close(fig)
        return fig


class _Progress:
    def __init__(self, t_end, enabled):
        self.t_end, self.enabled, self.last = t_end, enabled, 0.0

    def update(self, t, force=False):
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self.last < 0.1:
            return
        self.last = now
        frac = min(max(t / self.t_end, 0.0), 1.0) if self.t_end > 0 else 1.0
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r[{bar:<30}] {100 * frac:5.1f}%  t = {t:.4g} s")
        sys.stderr.flush()

    def close(self):
        if self.enabled:
            self.update(self.t_end, force=True)
            sys.stderr.write("\n")


def choose_solver(model, t_end: float, rtol: float) -> tuple[str, str]:
    """Pick a solver from the Jacobian's eigenvalues at the initial state."""
    if len(model.x0) == 0:
        return "RK45", "no states"
    try:
        lam = np.linalg.eigvals(model.jac(0.0, model.x0))
    except (ArithmeticError, np.linalg.LinAlgError, ValueError):
        return "Radau", "Jacobian not available at t=0; implicit to be safe"
    mags = np.abs(lam)
    lam_max = float(mags.max(initial=0.0))
    nonzero = mags[mags > 1e-12 * max(lam_max, 1e-300)]
    ratio = lam_max / float(nonzero.min()) if nonzero.size else 1.0
    horizon = lam_max * t_end
    if horizon > 2e4 and ratio > 1e3:
        return "Radau", f"stiff: |lambda|max*t_end = {horizon:.3g}, stiffness ratio {ratio:.3g}"
    name = "DOP853" if rtol <= 1e-6 else "RK45"
    return name, f"non-stiff: |lambda|max*t_end = {horizon:.3g}, stiffness ratio {ratio:.3g}"


def simulate(model, t_end: float, dt_out: float | None = None, solver: str = "auto", rtol: float = 1e-6,
             atol: float = 1e-9, max_step: float = np.inf, progress: bool | None = None,
             x0=None) -> Result:
    """Integrate ``model`` from 0 to ``t_end`` and sample its outputs every ``dt_out``."""
    if t_end <= 0:
        raise SimulationError("bad_time", f"t_end must be positive, got {t_end}")
    dt_out = dt_out or t_end / 500
    n_out = int(round(t_end / dt_out))
    if abs(n_out * dt_out - t_end) > 1e-9 * t_end:
        n_out = int(np.floor(t_end / dt_out))
    t_grid = np.append(np.arange(n_out + 1) * dt_out, [] if abs(n_out * dt_out - t_end) <= 1e-9 * t_end else [t_end])
    t_grid[-1] = min(t_grid[-1], t_end)
    reason = "chosen by the user"
    if solver == "auto":
        solver, reason = choose_solver(model, t_end, rtol)
    if solver not in SOLVERS:
        raise SimulationError("unknown_solver", f"unknown solver {solver!r}", f"use auto or one of {', '.join(SOLVERS)}")
    cls = SOLVERS[solver]
    x = np.array(model.x0 if x0 is None else x0, dtype=float)
    n = len(x)
    model.reset_stats()
    if progress is None:
        progress = sys.stderr.isatty()
    bar = _Progress(t_end, progress)
    states = np.empty((len(t_grid), n))
    k_out = 0
    stats = {"steps": 0, "nfev": 0, "njev": 0, "nlu": 0, "segments": 0, "dense_calls": 0}
    events = []
    t = 0.0
    start = time.perf_counter()
    forced: dict = {}
    rhs, newton_failures = _rejecting_unsolvable_loops(model)
    while n and k_out < len(t_grid):
        kw = {"rtol": rtol, "atol": atol, "max_step": max_step}
        if solver in IMPLICIT:
            kw["jac"] = model.jac_in_mode if model.n_switches else model.jac
        g_sign = np.sign(np.array(model.switches(t, x), dtype=float))
        for k, sgn in forced.items():      # just past an event: the new side's sign
            g_sign[k] = sgn
        forced = {}
        if model.n_switches:               # hold every switch on its side for this segment
            g_sign = _sides(model, t, x, g_sign, t_end)
            model.set_mode(g_sign)
        ode = cls(rhs, t, x, t_end, **kw)
        stats["segments"] += 1
        event = None
        while ode.status == "running" and event is None:
            try:
                msg = ode.step()
            except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
                raise SimulationError("step_failed", f"integration failed at t = {ode.t:.6g} s: {exc}") from None
            if ode.status == "failed":
                if newton_failures:
                    msg += (f"; Newton's method failed {len(newton_failures)} times in an algebraic loop "
                            f"(last: {newton_failures[-1]})")
                raise SimulationError("step_failed", f"{solver} failed at t = {ode.t:.6g} s: {msg}",
                                      "try solver auto or Radau, or tighter tolerances")
            stats["steps"] += 1
            dense = _Dense(ode, stats)
            t_stop = ode.t
            if model.n_switches:
                g_new = np.sign(np.array(model.switches(ode.t, ode.y), dtype=float))
                crossed = np.nonzero((g_new != g_sign) & (g_sign != 0) & (g_new != 0))[0]
                if crossed.size:
                    event = min((_root(model, dense, k, ode.t_old, ode.t), k) for k in crossed)
                    t_stop = event[0]
                g_sign = np.where(g_sign == 0, g_new, g_sign)
            while k_out < len(t_grid) and t_grid[k_out] <= t_stop + 1e-12 * max(1.0, t_end):
                states[k_out] = dense(min(t_grid[k_out], ode.t))
                k_out += 1
            bar.update(t_stop)
        _accumulate(stats, ode, solver)
        if event is None:
            t, x = ode.t, ode.y
            if ode.status == "finished":
                states[k_out:] = ode.y
                k_out = len(t_grid)
            continue
        t, k_ev = event
        x = dense(t)
        forced = {k_ev: -g_sign[k_ev]}
        events.append((t, model.switch_text[k_ev]))
        if len(events) > 5000:
            raise SimulationError("chattering", f"more than 5000 switching events by t = {t:.6g} s "
                                  f"(last: {events[-1][1]})", "regularise the law or check the model")
    bar.close()
    stats["wall_time"] = time.perf_counter() - start
    stats.update({k: v for k, v in model.stats.items()})
    if newton_failures:
        stats["newton_failures"] = len(newton_failures)
    dense_calls = stats.pop("dense_calls")
    if solver in _STAGES:
        extra = dense_calls * (3 if solver == "DOP853" else 0)
        attempts = (stats["nfev"] - stats["segments"] - extra) / _STAGES[solver]
        stats["rejected"] = max(int(round(attempts - stats["steps"])), 0)
    outs = np.array([model.outputs(tt, xx) for tt, xx in zip(t_grid, states)]) if model.output_names else \
        np.empty((len(t_grid), 0))
    if not np.all(np.isfinite(states)):
        raise SimulationError("not_finite", "the solution became infinite or NaN",
                              "check parameters (zero inertia? negative stiffness?) and the check report")
    outputs = {name: outs[:, k] for k, name in enumerate(model.output_names)}
    units = dict(zip(model.output_names, getattr(model, "output_units", [])))
    return Result(t_grid, outputs, states, list(model.state_names), solver, reason, stats, events, units)


def _sides(model, t, x, signs, t_end):
    """The side of every switching function for the segment starting at (t, x): its sign, or where
    it is zero, the sign it takes just after t (first from t alone, then along the motion)."""
    signs = np.array(signs, dtype=float)
    zero = signs == 0
    if zero.any():
        dt = 1e-9 * max(1.0, abs(t_end))
        later = np.sign(np.array(model.switches(t + dt, x), dtype=float))
        signs[zero] = later[zero]
    zero = signs == 0
    if zero.any():
        model.set_mode(np.where(signs == 0, 1.0, signs))
        moved = np.asarray(x) + 1e-6 * max(1.0, abs(t_end)) * model.rhs_in_mode(t, x)
        later = np.sign(np.array(model.switches(t, moved), dtype=float))
        signs[zero] = later[zero]
    return np.where(signs == 0, 1.0, signs)


def _rejecting_unsolvable_loops(model):
    """``(rhs, failures)``: the model's right-hand side, returning NaN where an algebraic loop has
    no Newton solution at a trial state, so that the integrator rejects that step and retries a
    shorter one (a NaN error estimate is a rejection); the messages are kept in ``failures``.
    A failure at an accepted state still ends the run, with the Newton message."""
    failures: list = []
    base = model.rhs_in_mode if model.n_switches else model.rhs
    if "newton(" not in getattr(model, "source", ""):
        return base, failures

    def rhs(t, x):
        try:
            return base(t, x)
        except NewtonError as exc:
            failures.append(str(exc))
            return np.full(len(x), np.nan)
    return rhs, failures


def _accumulate(stats, ode, solver):
    stats["nfev"] += ode.nfev
    stats["njev"] += getattr(ode, "njev", 0)
    stats["nlu"] += getattr(ode, "nlu", 0)


class _Dense:
    """The step's dense output, built only when something asks for a value inside the step."""

    def __init__(self, ode, stats):
        self.ode, self.stats, self.sol = ode, stats, None

    def __call__(self, tt):
        if tt == self.ode.t:
            return self.ode.y
        if self.sol is None:
            self.sol = self.ode.dense_output()
            self.stats["dense_calls"] += 1
        return self.sol(tt)


def _root(model, dense, k, t0, t1):
    """Time of the sign change of switching function ``k`` inside the step [t0, t1]."""
    def g(tt):
        return model.switches(tt, dense(tt))[k]
    try:
        return brentq(g, t0, t1, xtol=1e-14 * max(1.0, abs(t1)), rtol=4 * np.finfo(float).eps)
    except ValueError:
        return t1
