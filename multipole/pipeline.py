"""The stages chained for a scene: check, equations, model, simulation.

Each function takes a :class:`~multipole.netlist.Scene` and returns the object of its stage.
Compiled models are cached in memory and on disk (``$MULTIPOLE_CACHE``, default
``~/.cache/multipole``) by the scene's digest (netlist text and overrides), the requested outputs
and a hash of the kernel's and the element libraries' source, so a second ``simulate`` of an
unchanged scene skips analysis and code generation.  ``MULTIPOLE_CACHE=off`` disables the disk cache.  Disk entries are
authenticated with the user's key and the folder must be private (:mod:`multipole.cache`).
"""
from __future__ import annotations

import hashlib
import json
import time
import warnings
from functools import lru_cache
from pathlib import Path

from . import cache
from .causality import Analysis, analyse
from .checks import Context
from .diagnostics import run_checks
from .codegen import Model, compile_model
from .equations import Equations, assemble
from .errors import IllPosedError, MultipoleError, MultipoleWarning, NetlistError
from .netlist import Scene, validate_simulate_options
from .network import flatten
from .pruning import Pruning, prune as prune_equations
from .simulate import Result, simulate
from .backends import get_backend

_MODELS: dict = {}
_PRUNED: dict = {}
#: backends' compiled models restored from the disk cache in this process (see :func:`run`; the
#: last :data:`MAX_PRUNED` of them)
_RESTORED: dict = {}
#: how many times this process derived a scene's equations (:func:`check`); :func:`run` reports in
#: ``stats["equations_derived"]`` whether it did
_DERIVATIONS = [0]
#: how many scenes' derived equations :func:`pruned` keeps in memory
MAX_PRUNED = 16
#: the analysis of the last :func:`check` of each scene digest (at most :data:`MAX_PRUNED` of them)
_CHECKED: dict = {}


def check(scene: Scene) -> Analysis:
    """Flatten, analyse and run every registered check (:mod:`multipole.checks`).

    ``.diagnostics`` holds everything ``multipole check`` reports, in report order: the structural
    findings and, when there is no structural error, those of the assembled equations (algebraic
    loops, a singular loop, a source that can deliver no power).  The assembled equations are kept
    in ``.assembled`` for :func:`equations`.
    """
    _DERIVATIONS[0] += 1
    try:
        flat = flatten(scene.network)
    except MultipoleError as exc:
        raise NetlistError(exc.code, exc.message, exc.fix, scene.path) from None
    states = {s.name for s in flat.states if s.storage}
    for name in flat.prefer_state:
        if name not in states:
            raise NetlistError("unknown_state", f"prefer_state names {name!r}, which is not a storage state",
                               f"storage states: {', '.join(sorted(states))}", scene.path)
    analysis = analyse(flat, diagnose=False)
    context = Context(analysis, scene, lambda: assemble(analysis, scene.name))
    analysis.diagnostics = run_checks(context)
    analysis.assembled = context.equations() if analysis.ok else None
    if len(_CHECKED) >= MAX_PRUNED:
        del _CHECKED[next(iter(_CHECKED))]
    _CHECKED[scene.digest] = analysis
    return analysis


def equations(scene: Scene, analysis: Analysis | None = None) -> Equations:
    """The explicit ODE; :class:`IllPosedError` if the check found errors.  The analysis of this
    scene's last :func:`check` in this process is used if there was one (``multipole check`` then a
    model build derives the equations once: the 8-link mechanism's check took as long as its build)."""
    analysis = analysis or _CHECKED.get(scene.digest) or check(scene)
    eq = analysis.assembled or assemble(analysis, scene.name)
    for out in scene.outputs:
        try:
            eq.output(out)
        except MultipoleError as exc:
            raise NetlistError("unknown_output", exc.message, exc.fix, scene.where(key=out)) from None
    return eq


def pruned(scene: Scene, outputs=None, prune: bool = True):
    """``(equations, outputs, record)``: the scene's equations restricted to what ``outputs``
    (default: the scene's outputs, else the states) need, with the :class:`~multipole.pruning.Pruning`
    record of what was dropped (:func:`multipole.pruning.prune`); ``prune`` False keeps everything.

    Remembered in this process per scene digest, outputs and ``prune`` (the last
    :data:`MAX_PRUNED` of them), so a warm run on a backend that compiles from the equations
    (numba, which keeps its compiled model on them) derives nothing again."""
    key = (scene.digest, tuple(outputs) if outputs is not None else None, bool(prune))
    if key not in _PRUNED:
        if len(_PRUNED) >= MAX_PRUNED:
            del _PRUNED[next(iter(_PRUNED))]        # the oldest: a sweep of overrides stays bounded
        _PRUNED[key] = _prune(scene, outputs, prune)
    small, outs, record = _PRUNED[key]
    return small, list(outs), record


def _prune(scene: Scene, outputs, prune: bool):
    eq = equations(scene)
    outs = list(outputs) if outputs is not None else (scene.outputs or eq.state_names)
    if not prune:
        return eq, outs, Pruning(outs, len(eq.states))
    memo = eq.__dict__.setdefault("_pruned", {})     # per equations object: a backend caches on it
    if tuple(outs) not in memo:
        memo[tuple(outs)] = prune_equations(eq, outs)
    small, record = memo[tuple(outs)]
    return small, outs, record


def model(scene: Scene, outputs=None, prune: bool = True) -> Model:
    """Compiled model for ``outputs`` (default: the scene's outputs, else the states), computing
    only what they need (:func:`pruned`; ``prune`` False: everything, e.g. for ``port_values``).

    ``model.compile_time`` is the time spent analysing and generating code [s] (0 when restored
    from the disk cache, then ``model.cached`` is True); ``model.meta["pruning"]`` is the record
    of what was dropped (:meth:`~multipole.pruning.Pruning.to_dict`).
    """
    key = (scene.digest, tuple(outputs) if outputs is not None else None, bool(prune))
    if key in _MODELS:
        return _MODELS[key]
    slot = _cache_slot(key)
    m = _restore(*slot) if slot is not None else None
    if m is None:
        start = time.perf_counter()
        eq, outs, record = pruned(scene, outputs, prune)
        m = compile_model(eq, outs)
        m.meta["pruning"] = record.to_dict()
        m.compile_time = time.perf_counter() - start
        m.meta["warnings"] = _warning_lines(eq.analysis)
        if slot is not None:
            _store(*slot, {"source": m.source, "meta": m.meta})
    _MODELS[key] = m
    return m


@lru_cache(maxsize=1)
def _code_hash() -> str:
    """Hash of the kernel's source and of every module that registered element types."""
    import inspect
    import sys
    from .catalogue import catalogue
    files = set(Path(__file__).parent.rglob("*.py"))
    for et in catalogue().values():
        module = sys.modules.get(getattr(et.build, "__module__", ""), None)
        path = inspect.getsourcefile(module) if module is not None else None
        if path:
            files.update(Path(path).parent.glob("*.py"))
    h = hashlib.sha256()
    for f in sorted(files):
        h.update(f.read_bytes())
    return h.hexdigest()


def _cache_path(key, prefix: str = "model") -> Path | None:
    """Where the model for ``key`` is kept: ``<cache>/<prefix>-<digest>.entry`` (None: no disk cache)."""
    folder = cache.root()
    folder = cache.private_dir(folder) if folder is not None else None
    if folder is None:
        return None
    digest = hashlib.sha256(repr((key, _code_hash())).encode()).hexdigest()
    return folder / f"{prefix}-{digest[:32]}.entry"


def _cache_slot(key, prefix: str = "model"):
    """``(path, user key)`` of the disk cache entry for ``key``, or None without a usable cache."""
    path = _cache_path(key, prefix)
    secret = cache.user_key(path.parent) if path is not None else None
    return (path, secret) if secret is not None else None


def _is_str_list(value) -> bool:
    return isinstance(value, list) and all(isinstance(v, str) for v in value)


def _valid_meta(meta) -> bool:
    """True if ``meta`` has the shape :func:`~multipole.codegen.compile_model` writes."""
    if not (isinstance(meta, dict) and isinstance(meta.get("name"), str) and _is_str_list(meta.get("state_names"))
            and _is_str_list(meta.get("outputs")) and isinstance(meta.get("units"), dict)
            and isinstance(meta.get("aliases"), dict) and isinstance(meta.get("x0"), list)):
        return False
    x0, units = meta["x0"], meta["units"]
    return (len(x0) == len(meta["state_names"])
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x0)
            and all(isinstance(units.get(o, ""), str) for o in meta["outputs"])
            and all(isinstance(a, str) and isinstance(r, list) and len(r) == 2 and isinstance(r[0], str)
                    and r[1] in (1, -1) and not isinstance(r[1], bool) for a, r in meta["aliases"].items()))


def _restore(path: Path, secret: bytes) -> Model | None:
    """The model kept at ``path``, or None: an entry that is missing, fails its MAC (never
    executed) or has a damaged payload of any shape is ignored and rewritten."""
    payload = cache.read_entry(path, secret)
    if payload is None:
        return None
    try:
        data = json.loads(payload.decode())
        if not (isinstance(data, dict) and isinstance(data.get("source"), str) and _valid_meta(data.get("meta"))):
            return None
        m = Model(data["source"], data["meta"])      # authenticated: written by this user's multipole
    except Exception:           # noqa: BLE001 -- whatever is wrong with an entry, it is rebuilt
        return None
    m.cached = True
    return m


def _store(path: Path, secret: bytes, payload: dict) -> None:
    """Write ``payload`` as JSON to the authenticated entry at ``path``."""
    try:
        cache.write_entry(path, secret, json.dumps(payload).encode())
    except OSError:
        pass                    # a full or read-only disk must not stop a simulation


def run(scene: Scene, t_end=None, dt_out=None, solver=None, rtol=None, atol=None, progress=None,
        outputs=None, backend=None, prune: bool = True) -> Result:
    """Simulate with the scene's ``simulate`` options, overridden by the arguments given.

    ``backend`` (default: the scene's ``simulate.backend``, else ``numpy``) selects how the model
    runs; see :mod:`multipole.backends`.  ``prune`` (default True) computes only what the outputs
    need (:func:`pruned`); ``result.stats["states_pruned"]`` says how many states were dropped.
    """
    opts = dict(scene.simulate)
    if t_end is not None and dt_out is None and opts.get("dt_out", 0.0) > t_end:
        del opts["dt_out"]          # the scene's grid was chosen for its own, longer t_end
    for key, value in (("t_end", t_end), ("dt_out", dt_out), ("solver", solver), ("rtol", rtol), ("atol", atol)):
        if value is not None:
            opts[key] = value
    opts = validate_simulate_options(opts, scene.path)   # the loader's rules for command-line values too
    if "t_end" not in opts:
        raise NetlistError("no_t_end", "no simulation time given", "add simulate: {t_end: ...} or use --t-end",
                           scene.path)
    backend = backend or opts.get("backend", "numpy")
    derivations = _DERIVATIONS[0]
    if backend != "numpy":
        options = (opts["t_end"], opts.get("dt_out"), opts.get("solver", "auto"), opts.get("rtol", 1e-6),
                   opts.get("atol", 1e-9), opts.get("max_step", float("inf")), progress)
        result = _run_backend(get_backend(backend), scene, outputs, prune, options)
        result.stats["equations_derived"] = _DERIVATIONS[0] > derivations
        return result
    m = model(scene, outputs, prune)
    _warn(m.meta.get("warnings", []))
    result = simulate(m, opts["t_end"], opts.get("dt_out"), opts.get("solver", "auto"), opts.get("rtol", 1e-6),
                      opts.get("atol", 1e-9), opts.get("max_step", float("inf")), progress=progress)
    result.stats["compile_time"] = m.compile_time
    result.stats["model_cached"] = m.cached
    pruned_states = m.meta.get("pruning", {}).get("states_pruned", 0)
    result.stats["states_pruned"] = pruned_states if isinstance(pruned_states, int) else 0
    result.stats["equations_derived"] = _DERIVATIONS[0] > derivations
    return result


@lru_cache(maxsize=None)
def _version() -> str:
    """The package's version (looked up once: an import statement in a function costs 2 us per
    run, 25 us right after other Python work)."""
    from . import __version__
    return __version__


def _run_backend(backend, scene: Scene, outputs, prune: bool, options) -> Result:
    """A run on a backend other than numpy.  A backend that can describe its compiled model
    (:meth:`~multipole.backends.Backend.describe`, numba) keeps the description in the disk cache
    under the scene's digest, the outputs, ``prune`` and the code's hash (prefix ``<backend>-``,
    authenticated like every entry), so that another process restores the model
    (:meth:`~multipole.backends.Backend.restore`) without deriving the equations again.  Equations
    already derived in this process (:func:`pruned`) are run as they are (the backend keeps its
    model on them), without reading or writing the disk entry."""
    keeps = all(hasattr(backend, a) for a in ("name", "describe", "restore", "run_model"))   # a plain callable does not
    key = (getattr(backend, "name", None), _version(), scene.digest, tuple(outputs) if outputs is not None else None,
           bool(prune))
    entry = _RESTORED.get(key) if keeps else None
    in_memory = (scene.digest, key[3], bool(prune)) in _PRUNED      # equations derived in this process: used
    slot = _cache_slot(key, backend.name) if keeps and entry is None and not in_memory else None
    if slot is not None:
        entry = _restore_backend_entry(backend, *slot)
    if entry is not None:
        if key not in _RESTORED and len(_RESTORED) >= MAX_PRUNED:
            del _RESTORED[next(iter(_RESTORED))]    # the oldest: a sweep of overrides stays bounded
        _RESTORED[key] = entry
        model, warning_lines, states_pruned = entry
        _warn(warning_lines)
        result = backend.run_model(model, *options)
        result.stats["states_pruned"] = states_pruned
        return result
    eq, outs, record = pruned(scene, outputs, prune)
    warning_lines = _warning_lines(eq.analysis)
    _warn(warning_lines)
    result = backend(eq, outs, *options)
    result.stats["states_pruned"] = record.states_pruned
    data = backend.describe(eq, outs) if slot is not None and result.stats.get("backend") == backend.name else None
    if data is not None:
        _store(*slot, {"model": data, "warnings": warning_lines, "states_pruned": record.states_pruned})
    return result


def _restore_backend_entry(backend, path: Path, secret: bytes):
    """``(model, warning lines, states pruned)`` from the entry at ``path``, or None: an entry that is
    missing, fails its MAC (never executed) or does not rebuild is ignored (and rewritten)."""
    payload = cache.read_entry(path, secret)
    if payload is None:
        return None
    try:
        data = json.loads(payload.decode())
        if not (isinstance(data, dict) and _is_str_list(data.get("warnings"))
                and isinstance(data.get("states_pruned"), int) and not isinstance(data["states_pruned"], bool)):
            return None
        model = backend.restore(data.get("model"))      # authenticated: written by this user's multipole
    except Exception:           # noqa: BLE001 -- whatever is wrong with an entry, it is rebuilt
        return None
    return (model, data["warnings"], data["states_pruned"]) if model is not None else None


def _warning_lines(analysis) -> list:
    """The check's warnings (an open ground, a part nothing drives) as one line each."""
    return [f"[{d.code}] {d.message} (fix: {d.fix})" for d in analysis.diagnostics if d.severity == "warning"]


def _warn(lines) -> None:
    """Repeat the check's warnings before a run: a simulation of a source cut off by an open pin
    otherwise ends with zeros and exit 0 (one ``multipole: warning:`` line each from the CLI)."""
    for line in lines:
        warnings.warn(line, MultipoleWarning, stacklevel=3)


__all__ = ["check", "equations", "pruned", "model", "run", "IllPosedError"]
