"""Simulation backends, selectable per run (``multipole simulate --backend NAME``).

Backends register like element libraries do: an entry point in the ``multipole.backends`` group
names an object ``run(equations, outputs, t_end, dt_out, solver, rtol, atol, max_step, progress)``
returning a :class:`multipole.simulate.Result`.  The bundled ones (``pyproject.toml``)::

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
from typing import Callable

from ..errors import MultipoleError

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


def numpy_backend(equations, outputs, t_end, dt_out, solver, rtol, atol, max_step=float("inf"), progress=None):
    """The default backend: generated Python code (:func:`multipole.codegen.compile_model`) run by
    :func:`multipole.simulate.simulate` with scipy's integrators."""
    from ..codegen import compile_model
    from ..simulate import simulate
    return simulate(compile_model(equations, outputs), t_end, dt_out, solver, rtol, atol, max_step, progress)
