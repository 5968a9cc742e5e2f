"""The stages chained for a scene: check, equations, model, simulation.

Each function takes a :class:`~multipole.netlist.Scene` and returns the object of its stage.
Compiled models are cached in memory by the scene's digest and the requested outputs.
"""
from __future__ import annotations

from .causality import Analysis, analyse
from .codegen import Model, compile_model
from .equations import Equations, assemble
from .errors import IllPosedError, MultipoleError, NetlistError
from .netlist import Scene
from .network import flatten
from .simulate import Result, simulate

_MODELS: dict = {}


def check(scene: Scene) -> Analysis:
    """Flatten and analyse; structural findings are in ``.diagnostics``."""
    try:
        flat = flatten(scene.network)
    except MultipoleError as exc:
        raise NetlistError(exc.code, exc.message, exc.fix, scene.path) from None
    states = {s.name for s in flat.states if s.storage}
    for name in flat.prefer_state:
        if name not in states:
            raise NetlistError("unknown_state", f"prefer_state names {name!r}, which is not a storage state",
                               f"storage states: {', '.join(sorted(states))}", scene.path)
    analysis = analyse(flat)
    return analysis


def equations(scene: Scene, analysis: Analysis | None = None) -> Equations:
    """The explicit ODE; :class:`IllPosedError` if the check found errors."""
    analysis = analysis or check(scene)
    eq = assemble(analysis, scene.name)
    for out in scene.outputs:
        try:
            eq.output(out)
        except MultipoleError as exc:
            raise NetlistError("unknown_output", exc.message, exc.fix, scene.where(key=out)) from None
    return eq


def model(scene: Scene, outputs=None) -> Model:
    """Compiled model for ``outputs`` (default: the scene's outputs, else the states)."""
    key = (scene.digest, tuple(outputs) if outputs is not None else None)
    if key not in _MODELS:
        eq = equations(scene)
        outs = list(outputs) if outputs is not None else (scene.outputs or eq.state_names)
        _MODELS[key] = compile_model(eq, outs)
    return _MODELS[key]


def run(scene: Scene, t_end=None, dt_out=None, solver=None, rtol=None, atol=None, progress=None,
        outputs=None, backend=None) -> Result:
    """Simulate with the scene's ``simulate`` options, overridden by the arguments given.

    ``backend`` (default: the scene's ``simulate.backend``, else ``numpy``) selects how the model
    runs; see :mod:`multipole.backends`.
    """
    opts = dict(scene.simulate)
    for key, value in (("t_end", t_end), ("dt_out", dt_out), ("solver", solver), ("rtol", rtol), ("atol", atol)):
        if value is not None:
            opts[key] = value
    if "t_end" not in opts:
        raise NetlistError("no_t_end", "no simulation time given", "add simulate: {t_end: ...} or use --t-end",
                           scene.path)
    backend = backend or opts.get("backend", "numpy")
    if backend != "numpy":
        from .backends import get_backend
        outs = list(outputs) if outputs is not None else (scene.outputs or equations(scene).state_names)
        return get_backend(backend)(equations(scene), outs, opts["t_end"], opts.get("dt_out"),
                                    opts.get("solver", "auto"), opts.get("rtol", 1e-6), opts.get("atol", 1e-9),
                                    opts.get("max_step", float("inf")), progress)
    m = model(scene, outputs)
    return simulate(m, opts["t_end"], opts.get("dt_out"), opts.get("solver", "auto"), opts.get("rtol", 1e-6),
                    opts.get("atol", 1e-9), opts.get("max_step", float("inf")), progress=progress)


__all__ = ["check", "equations", "model", "run", "IllPosedError"]
