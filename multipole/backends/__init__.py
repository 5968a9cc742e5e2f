"""Simulation backends, selectable per run (``multipole simulate --backend NAME``).

A backend is a callable ``run(equations, outputs, t_end, dt_out, solver, rtol, atol, progress)``
returning a :class:`multipole.simulate.Result`.  ``numpy`` (generated Python code with scipy's
integrators, :mod:`multipole.simulate`) is the default and the fallback.
"""
from __future__ import annotations

from typing import Callable

from ..errors import MultipoleError

_BACKENDS: dict[str, Callable] = {}


def register_backend(name: str, run: Callable) -> None:
    """Make a backend available under ``name``."""
    _BACKENDS[name] = run


def get_backend(name: str) -> Callable:
    """The backend called ``name``; importing optional ones on first use."""
    if name not in _BACKENDS:
        _load_optional(name)
    try:
        return _BACKENDS[name]
    except KeyError:
        raise MultipoleError("unknown_backend", f"unknown backend {name!r}",
                             f"available: {', '.join(available())}") from None


def available() -> list[str]:
    for name in _OPTIONAL:
        try:
            _load_optional(name)
        except MultipoleError:
            pass
    return sorted(_BACKENDS)


#: optional backends: name -> module that registers it when imported
_OPTIONAL: dict[str, str] = {"numba": "multipole.backends.numba_backend"}


def _load_optional(name: str) -> None:
    module = _OPTIONAL.get(name)
    if module is None:
        return
    import importlib
    try:
        importlib.import_module(module)
    except ImportError as exc:
        raise MultipoleError("backend_unavailable", f"backend {name!r} needs a package that is not installed: {exc}",
                             "pip install the backend's extra (see README)") from None


def _numpy_backend(equations, outputs, t_end, dt_out, solver, rtol, atol, max_step=float("inf"), progress=None):
    from ..codegen import compile_model
    from ..simulate import simulate
    return simulate(compile_model(equations, outputs), t_end, dt_out, solver, rtol, atol, max_step, progress)


register_backend("numpy", _numpy_backend)
