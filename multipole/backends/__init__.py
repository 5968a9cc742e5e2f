"""Simulation backends, selectable per run (``multipole simulate --backend NAME``).

The seam (docs/backends.md):

* a **backend** is a :class:`Backend`: ``compile(equations, outputs) -> model`` turns the derived
  equations into a model, and ``integrator`` optionally supplies its own :class:`Integrator`
  (default: scipy's methods stepped in Python, :data:`multipole.simulate.SCIPY`);
* calling the backend runs the one shared driver, :func:`multipole.simulate.simulate`: options,
  output grid, the ``auto`` choice, the schedule of the time-switches, progress bar, events,
  statistics (:data:`multipole.simulate.STATS_KEYS`), output sampling, non-finite check, errors;
* a model that ``compile`` refuses (:class:`Refused`, e.g. too large to compile in bounded time)
  or cannot build (any other exception that is not a :class:`~multipole.errors.MultipoleError`)
  runs on the ``numpy`` backend instead, visibly, and the message says which of the two happened
  (:func:`fallback`).

Backends register like element libraries do: an entry point in the ``multipole.backends`` group
names the backend object.  The bundled ones (``pyproject.toml``)::

    [project.entry-points."multipole.backends"]
    numpy = "multipole.backends:numpy_backend"
    numba = "multipole.backends.numba_backend:run"

``numpy`` (generated Python code with scipy's integrators, :mod:`multipole.simulate`) is the
default and the fallback.  An entry point is loaded on first use; one whose module needs a package
that is not installed (numba) is refused with ``backend_unavailable``, an unknown name with
``unknown_backend`` and the list of installed backends (exit code 2 from the CLI).
"""
from __future__ import annotations

from importlib.metadata import entry_points
import warnings
from typing import Callable, Protocol

from ..errors import MultipoleError, MultipoleWarning
from ..simulate import simulate

#: the entry-point group backends register in
GROUP = "multipole.backends"

_BACKENDS: dict[str, Callable] = {}


def register_backend(name: str, run: Callable) -> None:
    """Make a backend available under ``name`` in this process (without an entry point, e.g. in a
    test or a notebook); an entry point of the same name is then not loaded."""
    _BACKENDS[name] = run


def _entry_points() -> dict:
    """{name: entry point} of the ``multipole.backends`` group (the first of a name wins)."""
    found: dict = {}
    for ep in entry_points(group=GROUP):
        found.setdefault(ep.name, ep)
    return found


def get_backend(name: str) -> Callable:
    """The backend called ``name``, loading its entry point on first use."""
    if name in _BACKENDS:
        return _BACKENDS[name]
    ep = _entry_points().get(name)
    if ep is None:
        raise MultipoleError("unknown_backend", f"unknown backend {name!r}",
                             f"installed: {', '.join(available())}")
    try:
        backend = ep.load()
    except ImportError as exc:
        raise MultipoleError("backend_unavailable", f"backend {name!r} needs a package that is not installed: {exc}",
                             "pip install the backend's extra (see docs/backends.md)") from None
    _BACKENDS[name] = backend
    return backend


def available() -> list[str]:
    """Names of the backends that load here (registered, and entry points whose packages are installed)."""
    names = set(_BACKENDS)
    for name in _entry_points():
        try:
            get_backend(name)
            names.add(name)
        except MultipoleError:
            pass
    return sorted(names)


class Integrator(Protocol):
    """What a backend's own integrator implements (:class:`multipole.simulate.ScipyIntegrator` is
    the default one, :class:`multipole.backends.numba_backend.NumbaIntegrator` a compiled one)."""

    name: str               # stats["backend"]
    solvers: tuple          # the solver names it accepts (besides auto)
    #: optional, default False: ``integrate`` evaluates the model in compiled code only and raises
    #: no Python warning, so the driver enters no warnings context for a run whose method and
    #: time-switch schedule it has already worked out (nothing else in such a run can warn)
    compiled: bool

    def method(self, solver: str, auto: tuple | None) -> tuple[str, str]:
        """``(method that runs, reason)`` for ``solver``; ``auto`` is ``(method, reason)`` from
        :func:`multipole.simulate.choose_solver` when ``solver == "auto"``, else None."""

    def integrate(self, model, method, t_grid, x0, schedule, sides, t_end, rtol, atol, max_step, bar):
        """The states on ``t_grid`` [s] from ``x0`` at t = 0 as a :class:`multipole.simulate.Run`
        (states, events ``[(t, k)]``, counters).  ``schedule`` ``[(t, k, side after)]`` and ``sides``
        (at t = 0) are the crossings of the switching functions of time alone, which must end
        segments; ``bar.update(t)`` reports progress.  Raises
        :class:`multipole.simulate.SimulationError` (use ``simulate.step_failed``, ``simulate.chattering``)."""


class Backend:
    """A simulation backend: :meth:`compile` and, optionally, an :attr:`integrator`.

    The model ``compile`` returns has what :func:`multipole.simulate.simulate` reads:
    ``name``, ``x0``, ``state_names``, ``output_names``, ``output_units``, ``jac(t, x)`` (for
    ``auto``; a dense array), optionally ``jac_sparse(t, x)`` (a ``scipy.sparse`` matrix, used for
    ``auto``'s estimate and given to Radau and BDF), ``n_switches``, ``switch_text``, ``switches(t, x)``,
    ``switch_time_only``,
    ``switch_rate``, ``switch_roots`` (the time-switches), ``outputs(t, x)`` or
    ``outputs_on_grid(t_grid, states)``, and optionally ``compile_time``, ``translate_time`` [s]
    and ``cached``; with the default integrator also what :class:`multipole.codegen.Model` has
    (``rhs``, ``rhs_in_mode``, ``set_mode``, ...)."""

    name = "numpy"
    #: the backend's own integrator; None: scipy's (:data:`multipole.simulate.SCIPY`)
    integrator: Integrator | None = None

    def compile(self, equations, outputs):
        """The model of ``equations`` with the named ``outputs``."""
        from ..codegen import compile_model
        return compile_model(equations, outputs)

    def describe(self, equations, outputs) -> dict | None:
        """What :meth:`restore` needs to rebuild the model :meth:`compile` made for ``equations`` in
        another process without deriving them again, as JSON data (``pipeline.run`` keeps it in the
        authenticated model cache, docs/backends.md "Model cache"); None: nothing to keep (the
        default)."""
        return None

    def restore(self, data):
        """The model described by ``data`` (from :meth:`describe`, authenticated by the cache), or
        None if it cannot be rebuilt (the caller then derives and compiles as usual)."""
        return None

    def run_model(self, model, t_end, dt_out=None, solver="auto", rtol=1e-6, atol=1e-9, max_step=float("inf"),
                  progress=None):
        """Simulate a compiled ``model`` from 0 to ``t_end`` [s] with the shared driver."""
        return simulate(model, t_end, dt_out, solver, rtol, atol, max_step, progress, integrator=self.integrator)

    def __call__(self, equations, outputs, t_end, dt_out=None, solver="auto", rtol=1e-6, atol=1e-9,
                 max_step=float("inf"), progress=None):
        """Simulate ``equations`` from 0 to ``t_end`` [s]: :meth:`compile`, then the shared driver."""
        outputs = list(outputs)
        try:
            model = self.compile(equations, outputs)
        except MultipoleError:
            raise
        except Exception as exc:       # a refusal, or a compiler's own failure (numba: TypingError, internal errors)
            if self.name == "numpy":
                raise
            return fallback(self.name, equations, outputs, exc, t_end, dt_out, solver, rtol, atol, max_step, progress)
        return self.run_model(model, t_end, dt_out, solver, rtol, atol, max_step, progress)


class Refused(Exception):
    """Raised by a backend's ``compile`` for a model it declines to start on (not a failure of its
    compiler): :func:`fallback` says the model was refused, with ``reason`` (what and the figures)
    and ``fix`` (how to make the backend take it)."""

    def __init__(self, what: str, reason: str, fix: str):
        super().__init__(f"{what}: {reason}")
        self.what, self.reason, self.fix = what, reason, fix


def fallback(name, equations, outputs, exc, *options):
    """Run on the numpy backend because backend ``name`` refused the model (:class:`Refused`: e.g.
    too large to compile in bounded time) or failed to compile it (any other exception), visibly: a
    :class:`~multipole.errors.MultipoleWarning` (one line on stderr from the CLI) says which and why,
    and so do ``solver_reason`` and ``stats["backend"]``: ``numpy (fallback: refused as WHAT:
    reason)`` or ``numpy (fallback: could not compile: ExceptionType: first line)``."""
    if isinstance(exc, Refused):
        why = f"refused as {exc.what}: {exc.reason}"
        said = f"the {name} backend refused this model as {exc.what} ({exc.reason}; {exc.fix})"
    else:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        detail = f"{type(exc).__name__}: {first}"[:160]
        why = f"could not compile: {detail}"
        said = f"the {name} backend could not compile this model ({detail})"
    warnings.warn(f"{equations.name}: {said}; running the numpy backend instead", MultipoleWarning, stacklevel=3)
    result = get_backend("numpy")(equations, outputs, *options)
    result.solver_reason += f"; {said}, ran numpy instead"
    result.stats["backend"] = f"numpy (fallback: {why})"
    return result


#: the default backend: generated Python code (:func:`multipole.codegen.compile_model`) run by
#: :func:`multipole.simulate.simulate` with scipy's integrators
numpy_backend = Backend()
