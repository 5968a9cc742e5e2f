"""Simulation: integrate a compiled :class:`~multipole.codegen.Model` and return a :class:`Result`.

The driver steps scipy's ``OdeSolver`` classes itself, so that it can

* sample the outputs on the ``dt_out`` grid from the dense output,
* find the zero crossings of the switching functions (steps, max/min, abs, sign, tables) and
  restart the integrator exactly there (switching laws are events, not kinks inside a step):
  during a segment every switch is held on the side it started on (``Model.rhs_in_mode``), so
  the integrator sees a smooth right-hand side; the crossings of the switching functions of
  time alone are found before the run (:func:`time_switch_schedule`) and end segments, the others
  are checked at :data:`PROBES` points of every step and the earliest crossing ends the segment
  at the root of its switching function,
* count accepted steps (and, for explicit Runge–Kutta methods, rejected ones),
* show a progress bar on a terminal.

Solver ``auto`` estimates stiffness from the eigenvalues of the analytic Jacobian at the start and
picks an implicit method (Radau, with the Jacobian) or an explicit one (DOP853 for tight
tolerances, RK45 otherwise); the reason is kept in ``Result.solver_reason``.
"""
from __future__ import annotations

import ast
import functools
import math
import re
import sys
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .diagnostics import names_list
from .errors import Interrupted, LongRunWarning, MultipoleError, NewtonError, RunError
from .files import atomic_output
IMPLICIT = {"Radau", "BDF", "LSODA", "GL4"}
_STAGES = {"RK45": 6, "RK23": 3, "DOP853": 12}


class SimulationError(RunError):
    """The integration failed (exit code 3; the message says where, when and why).

    ``element`` is the user's element responsible where known (the CLI then names its file:line)."""

    element: str | None = None


def _failed(model, code: str, message: str, fix: str = "", element: str | None = None) -> SimulationError:
    """A :class:`SimulationError` located at ``element`` (else at the model)."""
    err = SimulationError(code, message, fix, f"element '{element}'" if element else model.name)
    err.element = element
    return err


#: Most rows an output grid may have (``t_end/dt_out + 1``); a longer grid is refused before
#: anything is allocated.  10 million rows of a few columns are a few hundred MB.
MAX_OUTPUT_ROWS = 10_000_000

#: A run that the stiffness estimate says needs more integration steps than this is warned about
#: before it starts (at some µs per step, 1e8 steps take minutes to hours).
MANY_STEPS = 1e8


#: most outputs listed in the notebook view of a :class:`Result`
HTML_ROWS = 50


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
    #: the monitors that fired (:class:`multipole.network.Monitor`), in time order
    monitors: list = field(default_factory=list)

    def __getitem__(self, name):
        if name in self.outputs:
            return self.outputs[name]
        if name in self.state_names:
            return self.states[:, self.state_names.index(name)]
        raise KeyError(name)

    def to_csv(self, path) -> None:
        """CSV: ``t [s]`` then one column per output, headed ``name [unit]`` (``rotor.omega [rad/s]``;
        the name alone where the unit is not known); :func:`read_csv` reads it back."""
        names = list(self.outputs)
        data = np.column_stack([self.t] + [self.outputs[n] for n in names])
        header = [column_label("t", "s")] + [column_label(n, self.units.get(n, "")) for n in names]
        with atomic_output(path) as tmp:     # an interrupted write leaves no short file behind
            np.savetxt(tmp, data, delimiter=",", header=",".join(header), comments="", fmt="%.12g")

    def to_pandas(self):
        """A :class:`pandas.DataFrame`: index ``t`` [s], one column per output (SI values), the units
        in ``df.attrs["units"]`` (``{"t": "s", "rotor.omega": "rad/s", ...}``)."""
        import pandas as pd
        df = pd.DataFrame({n: np.asarray(v) for n, v in self.outputs.items()}, index=pd.Index(self.t, name="t"))
        df.attrs["units"] = {"t": "s", **{n: self.units.get(n, "") for n in self.outputs}}
        return df

    def to_xarray(self):
        """An :class:`xarray.Dataset`: coordinate ``t`` [s], one variable per output, each with
        ``attrs["units"]``.  Needs xarray (``pip install "multipole[xarray]"``)."""
        try:
            import xarray as xr
        except ImportError:
            raise MultipoleError("missing_package", "Result.to_xarray needs the xarray package, which is not "
                                 "installed", 'pip install "multipole[xarray]" (or pip install xarray); '
                                 "Result.to_pandas needs no extra package") from None
        t = xr.DataArray(self.t, dims="t", attrs={"units": "s"})
        return xr.Dataset({n: ("t", np.asarray(v), {"units": self.units.get(n, "")}) for n, v in self.outputs.items()},
                          coords={"t": t})

    def __repr__(self) -> str:
        """One short line (a notebook shows it for ``result``): the time span, the outputs with
        their units, the states, the solver and its counters."""
        span = f"t = 0 … {_seconds(self.t[-1])}, {len(self.t)} samples" if len(self.t) else "no samples"
        outs = names_list([column_label(n, self.units.get(n, "")) for n in self.outputs])
        s = self.stats
        return (f"<Result {span}; outputs {outs or '-'}; {len(self.state_names)} state(s); solver {self.solver}, "
                f"{s.get('steps', 0)} steps, {len(self.events)} events"
                + (f", {len(s['warnings'])} warning(s)" if s.get("warnings") else "")
                + (f", {len(self.monitors)} monitor finding(s)" if self.monitors else "") + ">")

    def _repr_html_(self) -> str:
        """The notebook view: outputs (unit, final, min, max; the first :data:`HTML_ROWS`), states,
        solver statistics, warnings."""
        from html import escape
        rows = "".join(f"<tr><td>{escape(n)}</td><td>{escape(self.units.get(n, ''))}</td><td>{v[-1]:.6g}</td>"
                       f"<td>{np.min(v):.6g}</td><td>{np.max(v):.6g}</td></tr>"
                       for n, v in list(self.outputs.items())[:HTML_ROWS] if len(v))
        if len(self.outputs) > HTML_ROWS:
            rows += f"<tr><td colspan=5>… {len(self.outputs) - HTML_ROWS} more outputs</td></tr>"
        span = f"t = 0 … {_seconds(self.t[-1])}, {len(self.t)} samples" if len(self.t) else "no samples"
        notes = "".join(f"<li>{escape(w)}</li>" for w in self.stats.get("warnings", []) + [monitor_line(m) for m in
                                                                                            self.monitors])
        return (f"<div><b>multipole Result</b>: {escape(span)}"
                "<table><tr><th>output</th><th>unit</th><th>final</th><th>min</th><th>max</th></tr>"
                f"{rows}</table>"
                f"<p>states ({len(self.state_names)}): {escape(names_list(self.state_names, 20)) or '-'}</p>"
                f"<p>{escape(self.summary())}</p>"
                + (f"<p>warnings during the run:</p><ul>{notes}</ul>" if notes else "") + "</div>")

    def summary(self) -> str:
        s = self.stats
        parts = [f"solver {self.solver} ({self.solver_reason})",
                 f"steps {s.get('steps', 0)}",
                 f"rejected {s['rejected'] if s.get('rejected') is not None else 'n/a'}",
                 f"nfev {s.get('nfev', 0)}", f"njev {s.get('njev', 0)}", f"nlu {s.get('nlu', 0)}",
                 f"events {len(self.events)}", f"wall {s.get('wall_time', 0):.3g} s"]
        if s.get("model_cached"):
            parts.append("model from cache")
        elif "compile_time" in s:
            parts.append(f"compile {s['compile_time']:.3g} s")
        if s.get("newton_solves"):
            parts.append(f"newton {s['newton_iterations']} it / {s['newton_solves']} solves")
        if s.get("states_pruned"):
            parts.append(f"{s['states_pruned']} state(s) pruned (no output needs them)")
        return ", ".join(parts)

    def plot(self, path=None, title: str = ""):
        """One panel per output over time (:func:`multipole.plotting.time_plot`); saved to ``path``
        when given (written atomically).  Returns the figure."""
        from .plotting import time_plot
        return time_plot(self, path, title)


def column_label(name: str, unit: str) -> str:
    """A CSV column heading: ``rotor.omega [rad/s]``, or the name alone without a unit."""
    return f"{name} [{unit}]" if unit else name


def parse_column_label(label: str) -> tuple[str, str]:
    """``(name, unit)`` of a heading written by :func:`column_label` (unit "" where none)."""
    m = re.fullmatch(r"(.*?) \[([^\[\]]*)\]", label.strip())
    return (m.group(1), m.group(2)) if m else (label.strip(), "")


def read_csv(path):
    """A results CSV written by ``simulate --out`` (or :meth:`Result.to_csv`) as a
    :class:`pandas.DataFrame` shaped like :meth:`Result.to_pandas`: index ``t`` [s], one column per
    output named without its unit, the units in ``df.attrs["units"]``."""
    import pandas as pd
    df = pd.read_csv(path)
    labels = [parse_column_label(c) for c in df.columns]
    df.columns = [name for name, _ in labels]
    df = df.set_index(df.columns[0])
    df.attrs["units"] = dict(labels)
    return df


def _seconds(t: float) -> str:
    """A time with the unit that reads best: ``2 s``, ``250 ms``, ``40 µs``."""
    from .plotting import time_unit
    scale, unit = time_unit(t)
    return f"{t / scale:.4g} {unit}"


class _Progress:
    def __init__(self, t_end, enabled):
        self.t_end, self.enabled, self.last, self.t = t_end, enabled, 0.0, 0.0

    def update(self, t, force=False):
        self.t = t                        # the time reached, for the message of an interruption
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


#: Up to this many states ``auto`` takes every eigenvalue of the dense Jacobian (``eigvals`` is
#: O(n³): 0.02 s at 200 states, 34 s at 2000); above, an Arnoldi estimate of the extreme ones.
EXACT_EIGEN_STATES = 200
#: Krylov dimension of that estimate: this many products with the Jacobian, O(nnz) each.
KRYLOV_DIM = 40
#: Up to this many states the estimate multiplies with the generated Jacobian (one evaluation, kept
#: as a sparse matrix); above, with directional differences of the right-hand side, so that no
#: n×n array is made (20,000 states would be 3.2 GB).
DENSE_JACOBIAN_STATES = 4000
#: Time scales closer than this are one time scale: a model is not stiff below this ratio of its
#: largest to its smallest nonzero |eigenvalue| (after the fast transient, what the solution does
#: is set by the inputs, which the Jacobian does not know).
MIN_STIFFNESS_RATIO = 10.0
#: Above this ratio, and with ``|λ|max·t_end`` above :data:`LONG_HORIZON`, a model is stiff even when
#: the accuracy estimate would allow an explicit method (its fast modes may never be excited).
WIDE_STIFFNESS_RATIO = 1e3
LONG_HORIZON = 2e4
#: Order of the local error estimate plus one (``q``) of the explicit candidates.
_ERROR_ORDER = {"RK45": 5, "DOP853": 8}


@dataclass
class Stiffness:
    """What ``auto`` knows about a model at t = 0 over a horizon ``t_end`` (see :func:`stiffness`).

    A mode ``exp(λt)`` must be resolved with steps ``h = c/|λ|``, ``c = (q!·rtol)^(1/q)`` (the local
    error ``(h|λ|)^q/q!`` at ``rtol``) for as long as it matters: over the whole horizon if it does
    not decay, else while it dies out — with the step growing as its amplitude falls, about
    ``q/(c·|Re λ|)`` seconds' worth of ``|λ|`` (``q/c`` steps for a real mode, many more for a lightly
    damped oscillation).  The most expensive mode gives ``steps_accuracy``.  An explicit method must
    in addition keep ``h·|λ| <= r(arg λ)`` for every damped mode (``r``: the radius of its stability
    region, :func:`rk_stability_radius`): ``steps_stability``.  The model is stiff for the explicit
    candidate when stability forces more steps than accuracy needs (the method would run at its
    stability limit, where its step-size control and dense output are no longer accurate) and its
    time scales are at least :data:`MIN_STIFFNESS_RATIO` apart; or when the stability bound alone is
    large (``|λ|max·t_end > 2e4``) and the time scales are :data:`WIDE_STIFFNESS_RATIO` apart: fast
    modes the inputs may never excite, for which an explicit method would pay all the same.
    """

    eigenvalues: np.ndarray       # all of them, or the Ritz values of the estimate [1/s]
    method: str                   # how they were found
    lam_max: float                # largest |λ| [1/s]
    ratio: float                  # largest / smallest nonzero |λ|
    explicit: str                 # the explicit candidate at this tolerance
    steps_accuracy: float         # steps the tolerance implies over t_end
    steps_stability: float        # steps the explicit candidate's stability forces over t_end
    t_end: float                  # the horizon [s]

    @property
    def stiff(self) -> bool:
        if self.lam_max * self.t_end > LONG_HORIZON and self.ratio > WIDE_STIFFNESS_RATIO:
            return True
        return bool(self.steps_stability > self.steps_accuracy and self.ratio >= MIN_STIFFNESS_RATIO)


def __getattr__(name: str):
    """``SOLVERS`` (:data:`multipole.solvers.SOLVERS`), imported when first asked for: scipy's
    integrators (with scipy.optimize, sparse, interpolate, ...) are not loaded by a run on a compiled
    backend, which does not use them (docs/performance.md, "A new process on the numba backend")."""
    if name == "SOLVERS":
        from .solvers import SOLVERS
        return SOLVERS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _brentq(*args, **kwargs) -> float:
    """scipy's Brent's method (``scipy.optimize.brentq``), imported on the first crossing located."""
    from scipy.optimize import brentq
    return brentq(*args, **kwargs)


#: stability polynomials (highest power first) of ``auto``'s explicit candidates, so that ``auto``
#: on a compiled backend needs no scipy integrator: ``1/k!`` up to the method's order, then the
#: tableau's own terms (Dormand–Prince 5(4): z⁶/600; DOP853: z⁹ … z¹², from scipy's tableau by
#: :func:`_tableau_polynomial`, which ``tests/test_warm_imports.py`` checks them against)
_STABILITY_POLYNOMIALS = {
    "RK45": (1 / 600, *(1 / math.factorial(k) for k in range(5, -1, -1))),
    "DOP853": (3.613324578128244e-10, 1.494736485459155e-08, 2.3413451082097813e-07, 2.6916922001690827e-06,
               *(1 / math.factorial(k) for k in range(8, -1, -1))),
}


def _stability_polynomial(method: str) -> np.ndarray:
    """Coefficients (highest power first) of the stability function ``R(z)`` of ``method``:
    :data:`_STABILITY_POLYNOMIALS`, else :func:`_tableau_polynomial`."""
    known = _STABILITY_POLYNOMIALS.get(method)
    return np.array(known) if known is not None else _tableau_polynomial(method)


@functools.lru_cache(maxsize=None)
def _tableau_polynomial(method: str) -> np.ndarray:
    """Coefficients (highest power first) of ``R(z) = 1 + z bᵀ(I - zA)⁻¹·1`` of scipy's explicit
    tableau of ``method`` (``A`` strictly lower triangular, so ``R(z) = 1 + Σ_k z^(k+1) bᵀA^k·1``)."""
    from .solvers import SOLVERS
    cls = SOLVERS[method]
    s = cls.n_stages
    A = np.zeros((s, s))
    A[:, :cls.A.shape[1]] = cls.A
    coef, v = [1.0], np.ones(s)
    for _ in range(s):
        coef.append(float(np.asarray(cls.B, dtype=float) @ v))
        v = A @ v
    return np.array(coef[::-1])


def rk_stability_radius(method: str, angle: float) -> float:
    """Largest ``r`` with ``|R(r·e^{iθ})| <= 1`` on the ray from 0 at angle ``θ`` (π: negative real axis).

    ``R(z) = 1 + z bᵀ(I - zA)⁻¹·1`` is the stability function of scipy's tableau of ``method``,
    sampled on ``r`` in (0, 10].
    """
    rs = np.linspace(1e-3, 10.0, 4000)
    ok = np.abs(np.polyval(_stability_polynomial(method), rs * np.exp(1j * angle))) <= 1 + 1e-12
    if not ok[0]:
        return 0.0
    return float(rs[np.argmin(ok)] if not ok.all() else rs[-1])


def _jacobian_product(model, n: int):
    """``v -> J·v`` at (0, x0), O(nnz) per product, and what it uses: the generated sparse Jacobian
    (any size), the dense one kept sparse (up to :data:`DENSE_JACOBIAN_STATES`), else differences."""
    sparse = getattr(model, "jac_sparse", None)
    if sparse is not None or n <= DENSE_JACOBIAN_STATES or not hasattr(model, "rhs"):
        from scipy.sparse import csr_array
        J = (sparse(0.0, model.x0) if sparse is not None
             else csr_array(np.asarray(model.jac(0.0, model.x0), dtype=float)))
        return (lambda v: J @ v), "Jacobian products"
    x0 = np.asarray(model.x0, dtype=float)
    f0 = np.asarray(model.rhs(0.0, x0), dtype=float)
    step = np.sqrt(np.finfo(float).eps) * max(1.0, float(np.max(np.abs(x0))))

    def product(v):
        h = step / max(float(np.max(np.abs(v))), 1e-300)
        return (np.asarray(model.rhs(0.0, x0 + h * v), dtype=float) - f0) / h
    return product, "differences of the right-hand side"


def _ritz_values(product, n: int, m: int) -> np.ndarray:
    """Eigenvalues of the Arnoldi projection of ``J`` on an ``m``-dimensional Krylov space from a
    fixed random start: the extreme eigenvalues of ``J`` (largest |λ| first to converge); all of
    them when ``m >= n``."""
    m = min(m, n)
    V = np.zeros((m + 1, n))
    H = np.zeros((m + 1, m))
    v = np.random.default_rng(0).standard_normal(n)
    V[0] = v / np.linalg.norm(v)
    for j in range(m):
        w = product(V[j])
        for _ in range(2):                        # Gram–Schmidt, repeated once for orthogonality
            c = V[:j + 1] @ w
            w = w - V[:j + 1].T @ c
            H[:j + 1, j] += c
        H[j + 1, j] = np.linalg.norm(w)
        if not np.all(np.isfinite(H[:j + 2, j])):
            raise ValueError("the Jacobian product is not finite")
        if H[j + 1, j] <= 1e-12 * np.linalg.norm(H[:j + 2, :j + 1]):
            m = j + 1                             # an invariant subspace: its eigenvalues are exact
            break
        V[j + 1] = w / H[j + 1, j]
    return np.linalg.eigvals(H[:m, :m])


def stiffness(model, t_end: float, rtol: float, exact_states: int = EXACT_EIGEN_STATES) -> Stiffness:
    """Eigenvalues of the Jacobian at (0, x0) — all of them up to ``exact_states`` states, else an
    Arnoldi estimate (:data:`KRYLOV_DIM` Ritz values, O(nnz) each) — and the step counts of
    :class:`Stiffness`.  Raises ``ArithmeticError``, ``LinAlgError`` or ``ValueError`` when the
    Jacobian cannot be evaluated."""
    n = len(model.x0)
    if n <= exact_states:
        lam = np.linalg.eigvals(np.asarray(model.jac(0.0, model.x0), dtype=float))
        how = f"all {n} eigenvalues"
    else:
        product, via = _jacobian_product(model, n)
        lam = _ritz_values(product, n, KRYLOV_DIM)
        how = f"Arnoldi estimate: {len(lam)} Ritz values of {n} from {via}"
    if not np.all(np.isfinite(lam)):
        raise ValueError("the Jacobian is not finite")
    explicit = "DOP853" if rtol <= 1e-6 else "RK45"
    q = _ERROR_ORDER[explicit]
    tol = min(rtol, 0.5)
    c = (math.factorial(q) * tol) ** (1.0 / q)
    mags = np.abs(lam)
    lam_max = float(mags.max(initial=0.0))
    nonzero = mags[mags > 1e-12 * max(lam_max, 1e-300)]
    ratio = lam_max / float(nonzero.min()) if nonzero.size else 1.0
    rate = -lam.real                                                  # decay rate [1/s]
    lasts = np.minimum(t_end, q / np.where(rate > 0, rate, q / t_end))  # how long each mode matters [s]
    steps_accuracy = max(float(np.max(mags * lasts, initial=0.0)), q) / c
    damped = lam[rate > 0]
    damped = damped[np.abs(damped) >= np.abs(damped).max(initial=0.0) / 8]   # r varies < 8x with the angle
    h_stab = min((rk_stability_radius(explicit, float(np.angle(z))) / abs(z) for z in damped), default=math.inf)
    return Stiffness(lam, how, lam_max, ratio, explicit, steps_accuracy, t_end / h_stab, t_end)


def choose_solver(model, t_end: float, rtol: float, stiff: Stiffness | None = None) -> tuple[str, str]:
    """``auto``: Radau when the model is stiff for the explicit candidate (:class:`Stiffness`; the
    one given, else it is estimated), else DOP853 (``rtol <= 1e-6``) or RK45; the reason names the
    figures and which estimate ran."""
    if len(model.x0) == 0:
        return "RK45", "no states"
    s = stiff or _stiffness_or_none(model, t_end, rtol)
    if s is None:
        return "Radau", "Jacobian not available at t=0; implicit to be safe"
    figures = (f"|lambda|max*t_end = {s.lam_max * t_end:.3g}, stiffness ratio {s.ratio:.3g}, "
               f"{s.explicit} steps for stability {s.steps_stability:.3g} / for accuracy {s.steps_accuracy:.3g}; "
               f"{s.method}")
    return ("Radau", f"stiff: {figures}") if s.stiff else (s.explicit, f"non-stiff: {figures}")


def _size(n_bytes: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if n_bytes < 1000 or unit == "PB":
            return f"{n_bytes:.3g} {unit}"
        n_bytes /= 1000


def output_grid(t_end: float, dt_out: float | None, n_columns: int = 1) -> np.ndarray:
    """0, dt_out, 2 dt_out, ... and ``t_end`` itself (both ends included) [s].

    ``dt_out`` defaults to ``t_end/500``.  A grid of more than :data:`MAX_OUTPUT_ROWS` rows is
    refused before it is allocated, with its size in memory for ``n_columns`` float columns."""
    if not (isinstance(t_end, (int, float)) and math.isfinite(t_end) and t_end > 0):
        raise MultipoleError("bad_time", f"t_end must be a positive finite time in s, got {t_end}",
                             "e.g. simulate: {t_end: 1.0}")
    if dt_out is None:
        dt_out = t_end / 500
    if not (isinstance(dt_out, (int, float)) and math.isfinite(dt_out) and dt_out > 0):
        raise MultipoleError("bad_dt_out", f"dt_out must be a positive finite time in s, got {dt_out}",
                             f"e.g. dt_out: {t_end / 500:.3g} (500 rows)")
    rows = np.floor(t_end / dt_out) + 2
    if rows > MAX_OUTPUT_ROWS:
        raise MultipoleError("grid_too_large", f"the output grid t_end/dt_out = {t_end:g} s / {dt_out:g} s has "
                             f"{rows:.3g} rows ({_size(rows * max(n_columns, 1) * 8)} for {n_columns} columns); "
                             f"at most {MAX_OUTPUT_ROWS:,} rows are served",
                             f"use dt_out >= {t_end / (MAX_OUTPUT_ROWS - 1):.3g} s or a shorter t_end")
    n_out = int(round(t_end / dt_out))
    if abs(n_out * dt_out - t_end) > 1e-9 * t_end:
        n_out = int(np.floor(t_end / dt_out))
    last = n_out * dt_out                  # the grid's last point, as np.arange(n_out + 1) * dt_out has it
    if abs(last - t_end) > 1e-9 * t_end:
        grid = np.empty(n_out + 2)
        grid[:-1] = np.arange(n_out + 1) * dt_out
        grid[-1] = t_end
    else:
        grid = np.arange(n_out + 1) * dt_out
        grid[-1] = min(last, t_end)
    return grid


def expected_steps(model, solver: str, t_end: float,
                   stiff: Stiffness | None = None) -> tuple[float, str] | None:
    """A rough lower bound of the integration steps from the Jacobian's eigenvalues at the start
    (``stiff``, else :func:`stiffness` is asked): ``(steps, why)``, or None where they are not known
    (no states, no Jacobian).

    An explicit method needs about ``|λ|max·t_end/4`` steps (its stability limit); any method
    needs about five steps per period of the fastest oscillation, ``0.8·max|Im λ|·t_end``."""
    if stiff is None:
        stiff = _stiffness_or_none(model, t_end, 1e-6)
    if stiff is None:
        return None
    lam = stiff.eigenvalues
    explicit = solver not in IMPLICIT and solver != "auto"
    rate = float(np.abs(lam).max(initial=0.0)) / 4 if explicit else 0.8 * float(np.abs(lam.imag).max(initial=0.0))
    what = "|lambda|max/4" if explicit else "0.8*max|Im lambda|"
    return rate * t_end, f"{what} = {rate:.3g} 1/s over t_end = {t_end:g} s"


def _stiffness_or_none(model, t_end: float, rtol: float) -> Stiffness | None:
    """:func:`stiffness`, or None for a model without states or without a Jacobian at the start."""
    if len(model.x0) == 0:
        return None
    try:
        with np.errstate(all="ignore"):
            return stiffness(model, t_end, rtol)
    except (ArithmeticError, np.linalg.LinAlgError, ValueError):
        return None


def simulate(model, t_end: float, dt_out: float | None = None, solver: str = "auto", rtol: float = 1e-6,
             atol: float = 1e-9, max_step: float = np.inf, progress: bool | None = None,
             x0=None, integrator=None) -> Result:
    """Integrate ``model`` from 0 to ``t_end`` [s] and sample its outputs every ``dt_out`` [s].

    This is the one driver of every backend (docs/backends.md): it checks the options, builds the
    output grid, chooses the method (``auto``: :func:`choose_solver`), schedules the crossings of
    the switching functions of time alone, shows the progress bar, lets ``integrator`` (default
    :data:`SCIPY`, scipy's methods stepped in Python; a backend may supply a compiled one, see
    :class:`multipole.backends.Integrator`) fill the states on the grid and report its events and
    counters, then samples the outputs, refuses non-finite values and builds the :class:`Result`
    with the statistics of :data:`STATS_KEYS`.

    Errors: :class:`~multipole.errors.MultipoleError` for options that cannot be served (an
    output grid of more than :data:`MAX_OUTPUT_ROWS` rows, an unknown solver);
    :class:`SimulationError` (a :class:`~multipole.errors.RunError`) for a run that fails,
    naming the element, the variable and the time: an arithmetic error in the model (``1/t`` at
    t = 0, the root of a negative number, an overflow), Newton's method failing in an algebraic
    loop, a step the integrator cannot take, a state or output that becomes infinite or NaN, and a
    stop monitor of an element that fired (:class:`~multipole.network.Monitor`: the error has the
    monitor's code).  The findings of the other monitors are listed in ``Result.monitors``.
    Warnings of numpy and scipy during the run are collected in ``Result.stats["warnings"]``
    instead of being printed; a run the stiffness estimate says takes more than
    :data:`MANY_STEPS` steps is announced with a :class:`~multipole.errors.LongRunWarning`.
    Ctrl-C raises :class:`~multipole.errors.Interrupted` with the time reached.
    """
    integrator = integrator or SCIPY
    n_columns = 1 + len(model.x0) + len(model.output_names)
    t_grid = output_grid(t_end, dt_out, n_columns)
    if solver != "auto" and solver not in integrator.solvers:
        raise MultipoleError("unknown_solver", f"unknown solver {solver!r}",
                             f"use auto or one of {', '.join(integrator.solvers)}")
    plans = model.__dict__.setdefault("_plans", {})      # per model: the stiffness estimate, the choice, the steps
    key = (integrator.name, solver, t_end, rtol)
    if key not in plans:
        stiff = _stiffness_or_none(model, t_end, rtol)
        plans[key] = stiff, None, expected_steps(model, solver, t_end, stiff) if stiff else None
    estimate = plans[key][2]
    if estimate is not None and estimate[0] > MANY_STEPS:
        warnings.warn(f"{model.name}: the stiffness estimate says this run takes about {estimate[0]:.2g} steps "
                      f"({estimate[1]}); it may run for hours (shorten t_end, or soften the stiffest coupling)",
                      LongRunWarning, stacklevel=2)
    if progress is None:
        progress = sys.stderr.isatty()
    bar = _Progress(t_end, progress)
    # nothing can warn in a run of a compiled integrator whose method and time-switch schedule are
    # known (the driver's own evaluations of the model are done): no warnings context (36 us right
    # after other Python work, 3.5 us back to back)
    quiet = getattr(integrator, "compiled", False) and plans[key][1] is not None and \
        (not model.n_switches or t_end in model.__dict__.get("_schedules", {}))
    try:
        if quiet:
            caught = []
            result = _drive(model, integrator, t_end, t_grid, solver, rtol, atol, max_step, bar, x0)
        else:
            with warnings.catch_warnings(record=True) as caught, np.errstate(all="ignore"):
                warnings.simplefilter("always")
                result = _drive(model, integrator, t_end, t_grid, solver, rtol, atol, max_step, bar, x0)
    except BaseException as exc:
        if progress:                       # end the progress bar's line before the error line
            sys.stderr.write("\n")
        if isinstance(exc, KeyboardInterrupt) and not isinstance(exc, Interrupted):
            raise Interrupted(float(bar.t)) from None
        if isinstance(exc, (ArithmeticError, ValueError, np.linalg.LinAlgError)) and \
                not isinstance(exc, MultipoleError):
            failure = model_failure(model, exc)
            if failure is not None:
                raise failure from None
        if isinstance(exc, MemoryError):
            raise _failed(model, "out_of_memory", "not enough memory for the run",
                          "use a coarser dt_out or a shorter t_end") from None
        raise
    notes = list(dict.fromkeys(str(w.message).splitlines()[0] for w in caught))
    if notes:
        result.stats["warnings"] = notes
    return result


@dataclass
class Run:
    """What an integrator hands back to the driver: the states on the output grid (shape
    ``(len(t_grid), n_states)``), the events ``[(t [s], switching function index), ...]`` in time
    order, and its work counters (keys of :data:`STATS_KEYS`; ``steps``, ``nfev`` ... )."""

    states: np.ndarray
    events: list
    counters: dict


def _drive(model, integrator, t_end, t_grid, solver, rtol, atol, max_step, bar, x0) -> Result:
    """What every backend shares around its integrator (see :func:`simulate`)."""
    start = time.perf_counter()
    x = np.array(model.x0 if x0 is None else x0, dtype=float)
    if not np.isfinite(x).all():
        bad = [model.state_names[k] for k in np.nonzero(~np.isfinite(x))[0]]
        raise SimulationError("not_finite", f"the initial state is infinite or NaN: {', '.join(bad[:5])}",
                              "check the initial values and the parameters they are computed from")
    key = (integrator.name, solver, t_end, rtol)
    stiff, plan, estimate = model._plans[key]
    if plan is None:                       # the choice, once per model and run setting
        auto = choose_solver(model, t_end, rtol, stiff) if solver == "auto" else None
        plan = integrator.method(solver, auto)
        model._plans[key] = stiff, plan, estimate
    method, reason = plan
    schedule, sides = _time_switches(model, x, t_end)
    run = integrator.integrate(model, method, t_grid, x, schedule, sides, t_end, rtol, atol, max_step, bar)
    fired = monitor_findings(model, run.events, x, t_end)
    bar.close()
    outs = sample_outputs(model, t_grid, run.states)
    run_time = time.perf_counter() - start
    watched = {k for k, *_rest in getattr(model, "monitors", [])}       # listed in Result.monitors
    events = [(float(t), model.switch_text[k]) for t, k in run.events if k not in watched]
    cached = bool(getattr(model, "cached", False))
    stats = solver_stats(run.counters, backend=integrator.name, events=len(events), run_time=run_time,
                         wall_time=run_time, translate_time=getattr(model, "translate_time", None),
                         compile_time=getattr(model, "compile_time", None), compile_cached=cached,
                         model_cached=cached)
    outputs = {name: outs[:, k].copy() for k, name in enumerate(model.output_names)}
    units = dict(zip(model.output_names, getattr(model, "output_units", [])))
    return Result(t_grid, outputs, run.states, list(model.state_names), method, reason, stats, events, units, fired)


def _time_switches(model, x, t_end) -> tuple[list, np.ndarray]:
    """:func:`time_switch_schedule` of the model over ``[0, t_end]``, found once per horizon."""
    if not model.n_switches:
        return [], np.ones(0)
    schedules = model.__dict__.setdefault("_schedules", {})
    if t_end not in schedules:
        schedules[t_end] = time_switch_schedule(lambda tt: model.switches(tt, x),
                                                getattr(model, "switch_time_only", [False] * model.n_switches),
                                                getattr(model, "switch_rate", []), t_end, model.switch_text,
                                                getattr(model, "switch_roots", None))
    schedule, sides = schedules[t_end]
    return schedule, sides.copy()


_REASONS = {ZeroDivisionError: "division by zero", OverflowError: "overflow (a value beyond 1.8e308, "
            "e.g. exp of more than 709)", np.linalg.LinAlgError: "singular matrix in a linear loop"}
_FUNCTIONS = {"rhs": "the right-hand side", "rhs_in_mode": "the right-hand side", "jac": "the Jacobian",
              "jac_in_mode": "the Jacobian", "jac_sparse": "the Jacobian", "jac_in_mode_sparse": "the Jacobian",
              "outputs": "the outputs", "switches": "the switching functions",
              "values": "the port values"}


def _variable_names(model) -> dict:
    """{identifier in the generated code: variable name} (``src_u`` -> ``src.u``, ``x0`` -> the
    first state), read from the ``values`` function whose return lists ``VALUE_NAMES`` in order."""
    names = getattr(model, "_variable_names", None)
    if names is None:
        names = {f"x{i}": s for i, s in enumerate(model.state_names)}
        for node in ast.walk(ast.parse(model.source)):
            if isinstance(node, ast.FunctionDef) and node.name == "values":
                ret = node.body[-1]
                if isinstance(ret, ast.Return) and isinstance(ret.value, ast.List):
                    names.update({e.id: v for e, v in zip(ret.value.elts, model.value_names)
                                  if isinstance(e, ast.Name)})
        model._variable_names = names
    return names


def element_of(variable: str) -> str:
    """The user's element a variable belongs to: ``src.p.e`` -> ``src``, ``der(rotor.p)`` -> ``rotor``."""
    inner = variable[4:-1] if variable.startswith("der(") else variable
    return inner.split(".", 1)[0]


def _assigned(model, lineno: int) -> tuple[str, str | None] | None:
    """(variable name, code) of the assignment at ``lineno`` of the generated source, or of the
    first named variable a helper line (common subexpression, loop matrix) feeds; for a line that
    feeds no named variable (a Jacobian entry), the first named variable it reads, and no code."""
    names = _variable_names(model)
    lines = model.source.splitlines()

    def readable(code):        # identifiers of the generated code -> the user's variable names
        return re.sub(r"\b\w+\b", lambda m: names.get(m.group(), m.group()), code.replace("math.", ""))
    for line in lines[lineno - 1:]:
        if line.startswith("def ") or line.strip().startswith("return"):
            break
        m = re.match(r"\s+([\w, ]+?),? = (.*)", line)
        if m:
            for ident in m.group(1).split(","):
                if ident.strip() in names:
                    return names[ident.strip()], readable(m.group(2).strip())
    if 0 < lineno <= len(lines):
        read = [names[w] for w in re.findall(r"\b\w+\b", lines[lineno - 1].split("=", 1)[-1]) if w in names]
        if read:
            return read[0], None
    return None


def model_failure(model, exc: BaseException) -> SimulationError | None:
    """A :class:`SimulationError` for an exception raised in the generated code of ``model``,
    naming the element, the variable, its code and the time; None if the exception did not come
    from the model (a bug elsewhere is not disguised as a model failure)."""
    frames = []
    tb = exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code.co_filename.startswith("<multipole model"):
            frames.append((tb.tb_frame, tb.tb_lineno))
        tb = tb.tb_next
    if not frames:
        return None
    t = None
    where, function, element = "", "", None
    for frame, lineno in reversed(frames):     # the deepest line that assigns a named variable
        t = frame.f_locals.get("t", t) if t is None else t
        function = function or _FUNCTIONS.get(frame.f_code.co_name, "")
        found = _assigned(model, lineno)
        if found:
            name, code = found
            if code is None:
                where = f"{_FUNCTIONS.get(frame.f_code.co_name, 'the model')} near {name}"
            elif re.match(r"_?newton\w*\(", code):     # the loop's unknown, not the solver call
                where = f"the algebraic loop for {name}"
            else:
                where = f"{name} = {code if len(code) <= 80 else code[:77] + '...'}"
            element = element_of(name)
            break
    frame = frames[-1][0]
    if element is None and frame.f_code.co_name != "values" and "x" in frame.f_locals:
        try:              # a switching function or output written inline: the variable it reads fails
            model.values(frame.f_locals.get("t", 0.0), frame.f_locals["x"])
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as again:
            inner = model_failure(model, again)
            if inner is not None and inner.element:
                return inner
    where = where or function or "the model"
    when = f" at t = {float(t):.6g} s" if isinstance(t, (int, float)) else ""
    if isinstance(exc, NewtonError):
        return _failed(model, exc.code, f"no solution{when} in {where} ({exc.message})", exc.fix, element)
    reason = next((r for cls, r in _REASONS.items() if isinstance(exc, cls)), None)
    if reason is None:
        text = str(exc)
        reason = ("outside the domain of a function (root or logarithm of a negative number, acos or asin "
                  "beyond +-1)" if "domain" in text else text or type(exc).__name__)
    fix = ("the law's derivative is infinite there (sqrt(f), log(f) at f = 0): start away from that point "
           "(an initial value) or use an explicit solver, which needs no Jacobian (--solver RK45)"
           if where.startswith("the Jacobian") else
           "check that element's expression and parameters at that time (e.g. 1/t at t = 0, "
           "sqrt of a negative value); shift, clamp or regularise it")
    return _failed(model, "arithmetic_error", f"{reason}{when} in {where}", fix, element)


def locate_non_finite(model, t: float, x) -> tuple[str, str | None]:
    """``(text, element)``: which variable is first infinite or NaN (or fails) at (t, x) in
    evaluation order, and the user's element it belongs to."""
    x = np.asarray(x, dtype=float)
    bad = [s for s, v in zip(model.state_names, x) if not np.isfinite(v)]
    if bad:
        return f"state {bad[0]}", element_of(bad[0])
    try:
        vals = model.values(t, x)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        failure = model_failure(model, exc)
        return (failure.message, failure.element) if failure is not None else (str(exc), None)
    for name, v in zip(model.value_names, vals):
        if not np.isfinite(v):
            return f"{name} = {v}", element_of(name)
    return "no variable of the model (the solver's own arithmetic)", None


class ScipyIntegrator:
    """scipy's ``OdeSolver`` classes stepped in Python (the ``numpy`` backend's integrator).

    Every switch is held on its side for a segment (``Model.rhs_in_mode``); segments end at the
    scheduled crossings of the switching functions of time alone and at the earliest crossing of
    the others, checked at :data:`PROBES` points of every step."""

    name = "numpy"

    @property
    def solvers(self) -> tuple:
        """The names of :data:`multipole.solvers.SOLVERS` (imported when asked for)."""
        from .solvers import SOLVERS
        return tuple(SOLVERS)

    def method(self, solver: str, auto: tuple | None) -> tuple[str, str]:
        """``(method, reason)`` for the requested ``solver``; ``auto``: what :func:`choose_solver` said."""
        return auto if auto is not None else (solver, "chosen by the user")

    def integrate(self, model, solver, t_grid, x, schedule, t_sides, t_end, rtol, atol, max_step, bar) -> Run:
        """The states on ``t_grid`` from ``x`` at t = 0 (see :class:`Run`)."""
        from .solvers import SOLVERS
        cls = SOLVERS[solver]
        n = len(x)
        model.reset_stats()
        stops = _stop_monitors(model)
        states = np.empty((len(t_grid), n))
        k_out = 0
        stats = {"steps": 0, "nfev": 0, "njev": 0, "nlu": 0, "segments": 0, "dense_calls": 0}
        events: list = []
        t = 0.0
        forced: dict = {}
        rhs, newton_failures = _rejecting_unsolvable_loops(model)
        time_only = np.array(getattr(model, "switch_time_only", [False] * model.n_switches), dtype=bool)
        watch = ~time_only                     # the switches checked after every step
        i_sched = 0
        while n and k_out < len(t_grid):
            while i_sched < len(schedule) and schedule[i_sched][0] <= t:     # a scheduled crossing
                _, k, side = schedule[i_sched]
                t_sides[k] = side
                events.append((float(t), k))
                i_sched += 1
                _check_chattering(events, model.switch_text)
            t_bound = schedule[i_sched][0] if i_sched < len(schedule) else t_end
            kw = {"rtol": rtol, "atol": atol, "max_step": max_step}
            if solver in IMPLICIT:
                kw["jac"] = jacobian_for(model, solver)
            g_sign = np.sign(np.array(model.switches(t, x), dtype=float))
            for k, sgn in forced.items():      # just past an event: the new side's sign
                g_sign[k] = sgn
            forced = {}
            if model.n_switches:               # hold every switch on its side for this segment
                g_sign = _sides(model, t, x, g_sign, t_end)
                g_sign[time_only] = t_sides[time_only]
                model.set_mode(g_sign)
            ode = cls(rhs, t, x, t_bound, **kw)
            stats["segments"] += 1
            event = None
            while ode.status == "running" and event is None:
                try:
                    msg = ode.step()
                except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
                    raise model_failure(model, exc) or SimulationError(
                        "step_failed", f"integration failed at t = {ode.t:.6g} s: {exc}") from None
                if ode.status == "failed":
                    element = None
                    if newton_failures:
                        last = newton_failures[-1]
                        msg += f"; Newton's method failed {len(newton_failures)} times, last: {last.message}"
                        element = last.element
                    elif not np.all(np.isfinite(rhs(ode.t, ode.y))):
                        cause, element = locate_non_finite(model, ode.t, ode.y)
                        msg += f"; infinite or NaN: {cause}"
                    raise step_failed(model, f"{solver} failed at t = {ode.t:.6g} s: {msg}", element)
                stats["steps"] += 1
                dense = _Dense(ode, stats)
                t_stop = ode.t
                if watch.any():
                    event = _first_crossing(model, dense, g_sign, watch, ode.t_old, ode.t)
                    if event is not None:
                        t_stop = event[0]
                k_end = int(np.searchsorted(t_grid, t_stop + 1e-12 * max(1.0, t_end), side="right"))
                if k_end > k_out:           # the grid points inside the step, in one dense evaluation
                    states[k_out:k_end] = dense.many(np.minimum(t_grid[k_out:k_end], ode.t))
                    k_out = k_end
                bar.update(t_stop)
            _accumulate(stats, ode, solver)
            if event is None:
                t, x = ode.t, ode.y
                if ode.status == "finished" and t_bound >= t_end:
                    states[k_out:] = ode.y
                    k_out = len(t_grid)
                continue
            t, k_ev = event
            x = dense(t)
            forced = {k_ev: -g_sign[k_ev]}
            # switches that crossed at the same instant (a monitor on a law's own switching function):
            # each is an event of its own, or the next segment would hold it on its old side
            now = np.sign(np.array(model.switches(t, x), dtype=float))
            crossed = [k_ev] + [int(k) for k in np.nonzero(watch & (now != 0) & (now != g_sign))[0] if k != k_ev]
            for k in crossed[1:]:
                forced[k] = now[k]
            events.extend((t, k) for k in crossed)
            if any(stops[k] and g_sign[k] > 0 for k in crossed):   # a stop monitor crossed downwards: the run ends
                break
            _check_chattering(events, model.switch_text)
        stats.update({k: v for k, v in model.stats.items()})
        dense_calls = stats.pop("dense_calls")
        if solver in _STAGES:
            extra = dense_calls * (3 if solver == "DOP853" else 0)
            # every segment starts with two evaluations: f(t0) and the one of the initial step size
            attempts = (stats["nfev"] - 2 * stats["segments"] - extra) / _STAGES[solver]
            stats["rejected"] = max(int(round(attempts - stats["steps"])), 0)
        stats["newton_failures"] = len(newton_failures)
        return Run(states, events, stats)


#: the numpy backend's integrator (the default of :func:`simulate`)
SCIPY = ScipyIntegrator()

#: scipy's methods that take a sparse Jacobian (they factorise it with ``splu``); LSODA and GL4 need a
#: dense array
SPARSE_JACOBIAN_SOLVERS = frozenset({"Radau", "BDF"})


def jacobian_for(model, solver: str):
    """The Jacobian function the implicit ``solver`` is given: the model's sparse one (``jac_sparse``,
    a large model, :data:`multipole.codegen.SPARSE_JACOBIAN_STATES`) where the method takes it
    (:data:`SPARSE_JACOBIAN_SOLVERS`), else the dense ``jac``; the ``*_in_mode`` variant (switches
    held on their sides) for a model with switches."""
    if model.n_switches:
        dense, sparse = model.jac_in_mode, getattr(model, "jac_sparse_in_mode", None)
    else:
        dense, sparse = model.jac, getattr(model, "jac_sparse", None)
    return sparse if sparse is not None and solver in SPARSE_JACOBIAN_SOLVERS else dense


def step_failed(model, message: str, element: str | None = None) -> SimulationError:
    """The error of an integrator that cannot take a step (every backend; exit code 3)."""
    return _failed(model, "step_failed", message, "try solver auto or Radau, or tighter tolerances", element)


def _stop_monitors(model) -> np.ndarray:
    """Per switching function of ``model``: it is a monitor with ``stop`` (the integrators end the run
    where it crosses from >= 0 to < 0)."""
    stops = np.zeros(model.n_switches, dtype=bool)
    for k, _el, _code, _text, stop, _fix in getattr(model, "monitors", []):
        stops[k] = stop
    return stops


def monitor_findings(model, events, x0, t_end) -> list:
    """The monitors that fired in a run (every backend): ``[(t [s], element, code, text), ...]`` for
    each crossing of a monitor's expression from >= 0 to < 0 among the run's ``events``
    ``[(t, switching function index), ...]``.  A monitor's events alternate between the two
    directions from its side at the start (as the integrators hold it: its sign, or where it is 0, the
    sign just after).  A stop monitor that fired (the integrators end the run there) raises its
    :class:`SimulationError` with the monitor's code, the time and the element."""
    if not events:
        return []
    monitors = {k: rest for k, *rest in getattr(model, "monitors", [])}
    if not monitors:
        return []
    sides = _sides(model, 0.0, x0, np.sign(np.array(model.switches(0.0, x0), dtype=float)), t_end)
    found = []
    for t, k in events:
        if k not in monitors:
            continue
        falling = sides[k] > 0
        sides[k] = -sides[k]
        if not falling:
            continue
        el, code, text, stop, fix = monitors[k]
        if stop:
            raise _failed(model, code, f"{el} at t = {float(t):.6g} s: {text}", fix or "see the element's "
                          "documentation for the range it works in", el.split(".", 1)[0])
        found.append((float(t), el, code, text))
    return found


def monitor_line(finding) -> str:
    """One line for a monitor that fired: ``t = 1.234 s: <element>: <text> [<code>]``."""
    t, el, code, text = finding
    return f"t = {t:.6g} s: {el}: {text} [{code}]"


def check_finite(t_grid, states, outs, state_names, output_names, model=None) -> None:
    """Refuse sampled states or outputs that are infinite or NaN, naming the first time and the
    variable and element responsible (both backends; with the compiled ``model``, an output is
    traced to the first non-finite variable of the evaluation order)."""
    for what, data, names in (("state", states, state_names), ("output", outs, output_names)):
        finite = np.isfinite(data)
        if not finite.all():
            row, col = np.argwhere(~finite)[0]
            var = names[col]
            cause, element = locate_non_finite(model, t_grid[row], states[row]) \
                if what == "output" and model is not None else ("", None)
            err = SimulationError("not_finite", f"{what} {var} became infinite or NaN at t = {t_grid[row]:.6g} s"
                                  + (f" ({cause})" if cause else ""),
                                  "check parameters (zero inertia? negative stiffness?), the laws' domains "
                                  "and the check report", f"element '{element or element_of(var)}'")
            err.element = element or element_of(var)
            raise err


def sample_outputs(model, t_grid, states) -> np.ndarray:
    """The outputs on the grid, shape ``(len(t_grid), n_outputs)`` (``model.outputs_on_grid`` when
    the model has it, e.g. compiled; else ``model.outputs`` row by row); non-finite values refused
    (traced to the element through ``model.values`` where the model has it)."""
    on_grid = getattr(model, "outputs_on_grid", None)
    if not model.output_names:
        outs = np.empty((len(t_grid), 0))
    elif on_grid is not None:
        outs = on_grid(t_grid, states)
    else:
        outs = np.array([model.outputs(tt, xx) for tt, xx in zip(t_grid, states)])
    check_finite(t_grid, states, outs, model.state_names, model.output_names,
                 model if hasattr(model, "values") else None)
    return outs


#: The keys of ``Result.stats`` that every backend fills, with the same meaning (docs/backends.md,
#: "Statistics"); a figure a backend cannot count is None (scipy does not report the rejected steps
#: of its implicit methods, nor Radau's Newton iterations).  ``warnings`` is added when there were any.
STATS_KEYS = ("backend", "steps", "rejected", "nfev", "njev", "nlu", "segments", "events", "rhs_calls",
              "jac_calls", "newton_iterations", "newton_solves", "newton_failures", "collocation_iterations",
              "translate_time", "compile_time", "run_time", "wall_time", "compile_cached", "model_cached",
              "states_pruned", "equations_derived")


def solver_stats(counted: dict, **more) -> dict:
    """``Result.stats``: every key of :data:`STATS_KEYS` (None where not counted), from ``counted``
    and ``more``."""
    values = {**counted, **more}
    return {**{k: values.get(k) for k in STATS_KEYS}, **values}


#: the switching functions watched after a step are evaluated at this many equispaced points of
#: the step (the last is its end): a sign change and back inside one step is found when a point
#: falls between, which is certain for an excursion longer than a fifth of the step
PROBES = 5
#: a time-only switching function is sampled at least this many times over the run, and at least
#: this many times per half period of the fastest sine inside it
TIME_SAMPLES, SAMPLES_PER_HALF_PERIOD = 4096, 8
#: samples of a time-only switching function with an argument not linear in t (rate unknown)
TIME_SAMPLES_UNKNOWN_RATE = 65536
#: more samples than this are refused (the crossings come too often to be events)
MAX_TIME_SAMPLES = 2_000_000
MAX_EVENTS = 5000


def _check_chattering(events, texts):
    """Refuse a run past :data:`MAX_EVENTS` events ``[(t, k), ...]`` (every backend)."""
    if len(events) > MAX_EVENTS:
        t, k = events[-1]
        raise chattering(t, texts[k])


def chattering(t: float, text: str) -> SimulationError:
    """The error of a run with more than :data:`MAX_EVENTS` events, the last at ``t`` [s] of ``text``."""
    return SimulationError("chattering", f"more than {MAX_EVENTS} switching events by t = {t:.6g} s "
                           f"(last: {text})", "regularise the law or check the model")


def time_switch_schedule(g, time_only, rate, t_end, texts=None, roots=None) -> tuple[list, np.ndarray]:
    """The crossings of the switching functions that depend on time alone, found before the run.

    ``g(t)`` gives every switching function at time t [s] (the state does not matter for these);
    ``time_only[k]`` marks them and ``rate[k]`` is the fastest angular rate of a sine inside
    function k [rad/s] (0: none, inf: unknown).  Where ``roots[k]`` lists its crossings
    ``[(t, side after), ...]`` (a polynomial in t, :func:`multipole.codegen.time_switches`) those
    are taken.  The others are sampled at ``t_end/TIME_SAMPLES`` or ``SAMPLES_PER_HALF_PERIOD``
    points per half period of that sine, whichever is finer, and at those crossings, and every sign
    change between samples is located by Brent's method (to 1e-14 s).  Returns
    ``([(t, k, side after), ...] in time order, sides)``, ``sides[k]`` being the side (±1) of
    function k at the start (its first non-zero sign).
    Sampling stops after ``MAX_EVENTS + 1`` crossings (the run then stops as chattering)."""
    time_only = np.array(time_only, dtype=bool)       # a copy: cleared below where roots are known
    sides = np.ones(len(time_only))
    known: list = []
    for k in np.nonzero(time_only)[0]:
        if roots is None or roots[k] is None:
            continue
        inside = [(float(t), int(k), float(side)) for t, side in roots[k] if 0 < t < t_end]
        first = inside[0][0] if inside else t_end      # the sign is constant before the first crossing
        sides[k] = np.sign(np.asarray(g(0.5 * first), dtype=float)[k]) or 1.0
        known += inside
        time_only[k] = False                           # nothing to sample
    ks = np.nonzero(time_only)[0]
    if not ks.size:
        return sorted(known), sides
    fastest = max(float(rate[k]) for k in ks) if len(rate) else 0.0
    h = t_end / (TIME_SAMPLES_UNKNOWN_RATE if np.isinf(fastest) else TIME_SAMPLES)
    if 0 < fastest < np.inf:
        h = min(h, np.pi / fastest / SAMPLES_PER_HALF_PERIOD)
    n = int(np.ceil(t_end / h))
    if n > MAX_TIME_SAMPLES:
        k = max(ks, key=lambda k: rate[k])
        name = texts[k] if texts is not None else f"switching function {k}"
        raise SimulationError("switching_too_fast", f"{name} oscillates at {fastest:.4g} rad/s: finding its "
                              f"crossings over t_end = {t_end:.6g} s needs {n} samples (limit {MAX_TIME_SAMPLES})",
                              "shorten t_end or regularise the law (a smooth function instead of a switch)")
    out: list = []
    last = np.zeros(len(ks))          # sign of the last non-zero sample of each function, and its time
    t_last = np.zeros(len(ks))
    # the crossings of the polynomial ones are sampled too: a narrow feature at a kink (a notch
    # step(abs(t - tc) - a)) is seen there whatever the spacing
    t_all = np.union1d(np.minimum(np.arange(n + 1) * h, t_end), [c[0] for c in known])
    for start in range(0, len(t_all), 4096):
        ts = t_all[start:start + 4096]
        vals = np.array([np.asarray(g(tt), dtype=float)[ks] for tt in ts]).reshape(len(ts), len(ks))
        if not np.all(np.isfinite(vals)):          # compiled code gives NaN/inf where Python raises
            i, j = np.argwhere(~np.isfinite(vals))[0]
            name = texts[ks[j]] if texts is not None else f"switching function {ks[j]}"
            raise SimulationError("not_finite", f"the switching function {name} is {vals[i, j]} at t = {ts[i]:.6g} s",
                                  "check the expression's domain at that time (root or logarithm of a negative "
                                  "number, division by zero)")
        signs = np.sign(vals)
        for j, k in enumerate(ks):
            nz = np.nonzero(signs[:, j])[0]
            if not nz.size:
                continue
            seq, t_seq = signs[nz, j], ts[nz]
            if last[j] == 0:
                sides[k] = last[j] = seq[0]
                t_last[j] = t_seq[0]
            seq = np.concatenate(([last[j]], seq))
            t_seq = np.concatenate(([t_last[j]], t_seq))
            for i in np.nonzero(seq[1:] != seq[:-1])[0]:
                tc = _brentq(lambda tt: np.asarray(g(tt), dtype=float)[k], t_seq[i], t_seq[i + 1],
                            xtol=1e-14 * max(1.0, t_end), rtol=4 * np.finfo(float).eps)
                if tc < t_end:
                    out.append((float(tc), int(k), float(seq[i + 1])))
            last[j], t_last[j] = seq[-1], t_seq[-1]
        if len(out) > MAX_EVENTS:
            break
    return sorted(out + known), sides


def _first_crossing(model, dense, g_sign, watch, t0, t1):
    """``(t, k)``: the earliest crossing inside the step [t0, t1] of a watched switching function
    away from the side ``g_sign`` it is held on, or None.  The functions are evaluated at
    :data:`PROBES` equispaced points of the dense output, and the first sub-interval where one has
    left its side is searched, so two crossings inside one step are not missed."""
    a = t0
    for j in range(1, PROBES + 1):
        b = t1 if j == PROBES else t0 + (t1 - t0) * j / PROBES
        s = np.sign(np.array(model.switches(b, dense(b)), dtype=float))
        hit = np.nonzero(watch & (s != 0) & (s != g_sign))[0]
        if hit.size:
            return min((_root(model, dense, k, a, b), k) for k in hit)
        a = b
    return None


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
    shorter one (a NaN error estimate is a rejection); the located errors are kept in ``failures``.
    A failure at an accepted state still ends the run, with the Newton message."""
    failures: list = []
    base = model.rhs_in_mode if model.n_switches else model.rhs
    if not re.search(r"\b(_?newton\w*|closure_failed)\(", getattr(model, "source", "")):     # no loop that can fail
        return base, failures

    def rhs(t, x):
        try:
            return base(t, x)
        except NewtonError as exc:
            failures.append(model_failure(model, exc) or _failed(model, exc.code, exc.message))
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

    def _solution(self):
        if self.sol is None:
            self.sol = self.ode.dense_output()
            self.stats["dense_calls"] += 1
        return self.sol

    def __call__(self, tt):
        if tt == self.ode.t:
            return self.ode.y
        return self._solution()(tt)

    def many(self, tt: np.ndarray) -> np.ndarray:
        """The states at the times ``tt`` [s] inside the step, one row each (the step's end exact)."""
        at_end = tt == self.ode.t
        if at_end.all():
            return np.broadcast_to(self.ode.y, (len(tt), len(self.ode.y)))
        rows = np.array(self._solution()(tt).T)
        rows[at_end] = self.ode.y
        return rows


def _root(model, dense, k, t0, t1):
    """Time of the sign change of switching function ``k`` inside the step [t0, t1], on its new side
    (the side it has at ``t1``): a function that crosses at the same instant has crossed there too."""
    def g(tt):
        return model.switches(tt, dense(tt))[k]
    xtol = 1e-14 * max(1.0, abs(t1))
    try:
        root = _brentq(g, t0, t1, xtol=xtol, rtol=4 * np.finfo(float).eps)
    except ValueError:
        return t1
    new_side, nudge = np.sign(g(t1)), xtol
    while root < t1 and np.sign(g(root)) != new_side:
        root, nudge = min(root + nudge, t1), 2 * nudge
    return root
