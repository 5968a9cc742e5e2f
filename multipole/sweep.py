"""Parameter studies: one analysis and code generation, many runs (``multipole sweep``).

A study varies scene parameters (``k1``) or element parameters (``mesh.c``) over a design and
records one row per run: the parameter values, the metrics, the solver statistics, a status and a
diagnostic.  A run that fails is a row (``status`` ``failed`` or ``invalid``), never a crashed
study.  ``docs/sweeps.md`` is the user's page.

How it runs
-----------
* SPECs (:func:`parse_spec`): a list ``1e7,2e7``, a range ``a..b:lin|log:n``, or a distribution
  ``normal(mu, sigma)`` / ``uniform(a, b)`` for a sampled design.  Every number goes through the
  netlist's expression whitelist (:func:`multipole.expressions.parse_expression`); nothing is
  evaluated as Python.
* Numeric parameters become *runtime* parameters of one compiled model
  (:func:`multipole.codegen.compile_model` with ``runtime``): an element parameter is made a scene
  parameter first (``mesh.c`` set to an added parameter), so it stays a symbol of the equations;
  parameters computed from it follow.  Parameters that change the structure (a fidelity
  ``level``, a choice, anything that does not survive as a symbol) are *structural*: the runs are
  grouped by their structural values and each group is analysed and compiled once.
* Workers receive the generated source, its meta record and parameter vectors (plain data),
  never closures; each worker process builds the model once per source.
* The executor is any ``concurrent.futures.Executor``: :class:`SerialExecutor`, a process pool
  (the default; BLAS threads capped at one per worker), or Dask
  (``Client(...).get_executor()``, ``pip install multipole[cluster]``).
"""
from __future__ import annotations

import concurrent.futures as cf
import csv
import hashlib
import itertools
import math
import os
import re
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp

from .errors import MultipoleError
from .expressions import parse_expression
from .netlist import METRIC_KINDS, Scene, load

#: the environment variables that cap the threads of BLAS/OpenMP libraries in a worker
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                    "NUMEXPR_NUM_THREADS")


def _confirm_default() -> int:
    """``$MULTIPOLE_SWEEP_CONFIRM`` if it is a whole number >= 1, else 1000."""
    text = os.environ.get("MULTIPOLE_SWEEP_CONFIRM", "").strip()
    return int(text) if text.isdigit() and int(text) >= 1 else 1000


#: studies with more runs than this need ``--yes`` on the command line (``MULTIPOLE_SWEEP_CONFIRM``)
CONFIRM_RUNS = _confirm_default()
#: most runs one study may have
MAX_RUNS = 1_000_000
#: seconds to wait for a Dask scheduler to answer
SCHEDULER_TIMEOUT = 10.0
#: default band of the settling time: the output stays within this fraction of its total change
SETTLE_TOL = 0.02
#: solver statistics copied into each row (``nfev`` ... as :data:`multipole.simulate.STATS_KEYS`)
ROW_STATS = ("solver", "steps", "rejected", "nfev", "njev", "nlu", "events", "wall_time")
#: the columns every row has after the parameters and the metrics
STATUS_COLUMNS = ("status", "diagnostic")

_NUMBER_KINDS = ("number", "time", "law")    # element parameter kinds a study may make runtime values
_DIST = re.compile(r"^\s*(normal|uniform)\s*\((.*)\)\s*$", re.S)
_RANGE = re.compile(r"^(.+?)\.\.(.+?)(?::(lin|log):(\d+))?$", re.S)
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class SweepError(MultipoleError):
    """An invalid study (exit code 2): a malformed SPEC, an unknown parameter or metric, too many
    runs, an executor or scheduler that cannot be used."""


# -- SPECs -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Spec:
    """What one ``--set NAME=SPEC`` says: ``kind`` ``list``/``range`` with ``values``, or
    ``normal``/``uniform`` with ``args`` (mean and standard deviation; lower and upper bound)."""

    name: str
    kind: str
    values: tuple = ()
    args: tuple = ()
    scale: str = "lin"
    text: str = ""

    @property
    def random(self) -> bool:
        return self.kind in ("normal", "uniform")

    @property
    def numeric(self) -> bool:
        return self.random or all(not isinstance(v, str) for v in self.values)

    def sample(self, rng: np.random.Generator, n: int) -> list:
        """``n`` values drawn with ``rng`` (a list or range: uniformly among its values)."""
        if self.kind == "normal":
            return [float(v) for v in rng.normal(self.args[0], self.args[1], n)]
        if self.kind == "uniform":
            return [float(v) for v in rng.uniform(self.args[0], self.args[1], n)]
        return [self.values[k] for k in rng.integers(0, len(self.values), n)]


def _bad(name: str, text: str, why: str, fix: str = "") -> SweepError:
    return SweepError("bad_spec", f"--set {name}={text}: {why}",
                      fix or "write a list 1e7,2e7, a range 1e7..1e9:log:20 or 0..1:lin:11, "
                      "or normal(mu, sigma) / uniform(a, b) with --samples N", "command line")


def _number(name: str, text: str, part: str) -> float:
    """One number of a SPEC, read by the netlist's expression whitelist (``2e8``, ``2*pi``); an
    integer literal stays an int (an element may need a whole number, e.g. piezo_stack n)."""
    try:
        value = parse_expression(part.strip(), {}, f"--set {name}")
    except MultipoleError as exc:
        raise _bad(name, text, f"{part.strip()!r} is not a number ({exc.message})") from None
    if value.is_Integer:
        return int(value)
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise _bad(name, text, f"{part.strip()!r} is not a number") from None
    if not math.isfinite(number):
        raise _bad(name, text, f"{part.strip()!r} is not finite")
    return number


def parse_spec(name: str, text) -> Spec:
    """The :class:`Spec` of ``--set NAME=SPEC`` (see the module docstring); a number or a list of
    numbers may be given directly (the Python API).  Error code ``bad_spec`` for a malformed SPEC."""
    if isinstance(text, (list, tuple, np.ndarray)):
        values = tuple(v if isinstance(v, str) else int(v) if isinstance(v, int) and not isinstance(v, bool)
                       else float(v) for v in text)
        if not values:
            raise _bad(name, "[]", "no values")
        if any(isinstance(v, float) and not math.isfinite(v) for v in values):
            raise _bad(name, str(list(text)), "a value is not finite")
        return Spec(name, "list", values, text=",".join(str(v) for v in values))
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return parse_spec(name, [text])
    if not isinstance(text, str) or not text.strip():
        raise _bad(name, str(text), "empty SPEC")
    text = text.strip()
    if len(text) > 2000:
        raise _bad(name, text[:40] + "...", "SPEC longer than 2000 characters")
    m = _DIST.match(text)
    if m:
        parts = m.group(2).split(",")
        if len(parts) != 2:
            raise _bad(name, text, f"{m.group(1)}() takes two numbers, got {len(parts)}")
        a, b = (_number(name, text, p) for p in parts)
        if m.group(1) == "normal" and not b > 0:
            raise _bad(name, text, f"the standard deviation must be positive, got {b:g}")
        if m.group(1) == "uniform" and not b > a:
            raise _bad(name, text, f"uniform(a, b) needs a < b, got {a:g} and {b:g}")
        return Spec(name, m.group(1), args=(a, b), text=text)
    if ".." in text:
        m = _RANGE.match(text)
        if not m:
            raise _bad(name, text, "a range is a..b:lin:n or a..b:log:n")
        if m.group(3) is None:
            raise _bad(name, text, "a range needs its spacing and count", f"e.g. {text}:lin:11")
        a, b, n = _number(name, text, m.group(1)), _number(name, text, m.group(2)), int(m.group(4))
        if not 1 <= n <= MAX_RUNS:
            raise _bad(name, text, f"the count must be 1 to {MAX_RUNS}, got {n}")
        if m.group(3) == "log":
            if not (a > 0 and b > 0):
                raise _bad(name, text, "a log range needs positive ends", "use :lin: or positive numbers")
            values = np.geomspace(a, b, n)
        else:
            values = np.linspace(a, b, n)
        return Spec(name, "range", tuple(float(v) for v in values), scale=m.group(3), text=text)
    values = []
    for part in text.split(","):
        word = part.strip()
        if not word:
            raise _bad(name, text, "an empty entry in the list")
        if _IDENT.match(word) and word != "pi":   # a level or choice such as 'elastic'
            values.append(word)
        else:
            values.append(_number(name, text, word))
    return Spec(name, "list", tuple(values), text=text)


def design(specs: list, samples: int | None = None, seed: int | None = None) -> list:
    """The runs as ``[{name: value}]``: the full grid of the lists and ranges (the first ``--set``
    varies slowest), or ``samples`` draws with ``numpy.random.default_rng(seed)``, parameter by
    parameter in the order given (the same seed gives the same design)."""
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise SweepError("bad_design", f"parameter {dup!r} is set twice", "give one --set per parameter",
                         "command line")
    if samples is None:
        random = [s.name for s in specs if s.random]
        if random:
            raise SweepError("bad_design", f"{random[0]} is a distribution: a grid needs lists or ranges",
                             "add --samples N --seed S for a sampled design", "command line")
        count = math.prod(len(s.values) for s in specs)
        if count > MAX_RUNS:
            raise SweepError("too_many_runs", f"the grid has {count} runs (limit {MAX_RUNS})",
                             "use fewer values or a sampled design", "command line")
        return [dict(zip(names, combo)) for combo in itertools.product(*(s.values for s in specs))]
    if not 1 <= samples <= MAX_RUNS:
        raise SweepError("bad_design", f"--samples must be 1 to {MAX_RUNS}, got {samples}", "", "command line")
    rng = np.random.default_rng(seed)
    columns = [s.sample(rng, samples) for s in specs]
    return [dict(zip(names, row)) for row in zip(*columns)]


# -- metrics -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Metric:
    """A metric of a run: ``output.kind`` (:data:`METRIC_KINDS`) or a named formula of them."""

    name: str
    formula: object = None           # sympy expression of symbols "output.kind" (named metrics)

    def needs(self) -> set:
        return {str(s) for s in self.formula.free_symbols} if self.formula is not None else {self.name}


def metric_list(scene: Scene, names=None) -> list:
    """The :class:`Metric` objects for ``names`` (``output.kind`` or a name of the scene's
    ``metrics:`` section); default: final, max, min and rms of every output, then the named ones."""
    outputs = scene.outputs
    if not outputs:
        raise SweepError("bad_metric", "the scene lists no outputs to take metrics of", "add outputs: [...]",
                         scene.path)
    if names is None:
        return [Metric(f"{o}.{k}") for o in outputs for k in ("final", "max", "min", "rms")] + \
            [Metric(n, f) for n, f in scene.metrics.items()]
    out = []
    for name in names:
        name = name.strip()
        if name in scene.metrics:
            out.append(Metric(name, scene.metrics[name]))
            continue
        output, _, kind = name.rpartition(".")
        if output in outputs and kind in METRIC_KINDS:
            out.append(Metric(name))
            continue
        named = ", ".join(scene.metrics) or "none"
        raise SweepError("unknown_metric", f"unknown metric {name!r}",
                         f"use OUTPUT.KIND with an output of the scene ({', '.join(outputs)}) and KIND one of "
                         f"{', '.join(METRIC_KINDS)}, or a name of its metrics: section ({named})", scene.path)
    if len({m.name for m in out}) != len(out):
        raise SweepError("unknown_metric", "a metric is listed twice", "list each metric once", scene.path)
    return out


def reduce_output(t: np.ndarray, y: np.ndarray, kind: str, settle_tol: float = SETTLE_TOL) -> float:
    """One number of an output sampled on the grid ``t`` [s]: ``final``, ``max``, ``min``, ``mean``
    and ``rms`` (trapezoidal time averages over the run), or ``settling``: the first grid time [s]
    after which ``y`` stays within ``settle_tol`` times its total change ``|y_end - y_0|`` of the
    final value (NaN if only the last sample is inside the band; 0 if it never leaves it)."""
    if kind == "final":
        return float(y[-1])
    if kind == "max":
        return float(np.max(y))
    if kind == "min":
        return float(np.min(y))
    span = float(t[-1] - t[0])
    if kind == "mean":
        return float(_trapezoid(y, t) / span) if span > 0 else float(y[-1])
    if kind == "rms":
        return float(math.sqrt(_trapezoid(y * y, t) / span)) if span > 0 else float(abs(y[-1]))
    if kind == "settling":
        band = settle_tol * abs(float(y[-1] - y[0]))
        outside = np.nonzero(np.abs(y - y[-1]) > band)[0]
        if len(outside) == 0:
            return float(t[0])
        k = int(outside[-1]) + 1
        return float(t[k]) if k < len(t) - 1 else math.nan
    raise ValueError(f"unknown metric kind {kind!r}")


def _trapezoid(y: np.ndarray, t: np.ndarray) -> float:
    """The trapezoidal integral of samples ``y`` over ``t``."""
    return float(np.sum((y[1:] + y[:-1]) * np.diff(t)) / 2.0)


def evaluate_metrics(metrics: list, t, outputs: dict, settle_tol: float = SETTLE_TOL) -> dict:
    """{metric name: value} of one run's sampled outputs."""
    reduced: dict = {}
    for m in metrics:
        for key in m.needs():
            if key not in reduced:
                output, _, kind = key.rpartition(".")
                reduced[key] = reduce_output(t, np.asarray(outputs[output], dtype=float), kind, settle_tol)
    out = {}
    for m in metrics:
        if m.formula is None:
            out[m.name] = reduced[m.name]
            continue
        value = m.formula.xreplace({s: sp.Float(reduced[str(s)]) for s in m.formula.free_symbols})
        try:
            out[m.name] = float(value)
        except (TypeError, ValueError):
            out[m.name] = math.nan
    return out


# -- the worker side -----------------------------------------------------------------------------
_WORKER_MODELS: dict = {}
_CAPPED: list = []


def cap_threads() -> None:
    """Cap BLAS/OpenMP threads at one in this process (the initializer of every worker, and the
    first task a Dask worker runs): the environment variables for libraries loaded later, and
    ``threadpoolctl`` for those already loaded, where it is installed."""
    if _CAPPED:
        return
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"
    try:
        import threadpoolctl
        _CAPPED.append(threadpoolctl.threadpool_limits(1))
    except ImportError:
        _CAPPED.append(None)


def _worker_init() -> None:
    """Process-pool initializer: one BLAS thread, and Ctrl-C is the parent's to handle (it keeps
    the finished rows and cancels the rest)."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    cap_threads()


def _worker_model(source: str, meta: dict):
    from .codegen import Model
    key = hashlib.sha256(source.encode()).hexdigest()
    m = _WORKER_MODELS.get(key)
    if m is None:
        if len(_WORKER_MODELS) > 32:
            _WORKER_MODELS.clear()
        m = _WORKER_MODELS[key] = Model(source, meta)
    return m


def run_chunk(job: dict, runs: list) -> list:
    """Simulate ``runs`` = ``[(index, runtime vector)]`` of the model in ``job`` (plain data: the
    generated ``source``, its ``meta``, the simulate options and the metrics) and return one row
    ``{"run": index, metrics..., stats..., "status", "diagnostic"}`` per run.  Runs in a worker;
    every failure of a run becomes its row."""
    from .simulate import simulate
    cap_threads()
    model = _worker_model(job["source"], job["meta"])
    rows = []
    for index, vector in runs:
        row = {"run": index}
        try:
            if model.runtime:
                model.set_parameters(vector)
            with warnings.catch_warnings(record=True) as caught:      # one per row, not one per run on stderr
                warnings.simplefilter("always")
                result = simulate(model, job["t_end"], job.get("dt_out"), job.get("solver", "auto"),
                                  job.get("rtol", 1e-6), job.get("atol", 1e-9), job.get("max_step", math.inf),
                                  progress=False)
            notes = [str(w.message).splitlines()[0] for w in caught] + list(result.stats.get("warnings", []))
            row.update(evaluate_metrics(job["metrics"], result.t, result.outputs, job.get("settle_tol", SETTLE_TOL)))
            if job.get("keep_trajectories"):
                row["_trajectory"] = (result.t, result.outputs)
            s = result.stats
            row.update({"solver": result.solver, "steps": s.get("steps"), "rejected": s.get("rejected"),
                        "nfev": s.get("nfev"), "njev": s.get("njev"), "nlu": s.get("nlu"),
                        "events": len(result.events), "wall_time": s.get("wall_time")})
            row["status"], row["diagnostic"] = "ok", (f"warning: {notes[0]}"[:300] if notes else "")
        except KeyboardInterrupt:
            raise
        except MultipoleError as exc:
            row["status"], row["diagnostic"] = "failed", str(exc)
        except Exception as exc:       # noqa: BLE001 -- a study records every failure of a run as its row
            row["status"], row["diagnostic"] = "failed", f"error[{type(exc).__name__}] {exc}"[:300]
        rows.append(row)
    return rows


# -- executors --------------------------------------------------------------------------------
class SerialExecutor(cf.Executor):
    """Runs each task in this process when it is submitted (``concurrent.futures`` interface)."""

    def submit(self, fn, /, *args, **kwargs):
        future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except KeyboardInterrupt:
            raise
        except BaseException as exc:      # noqa: BLE001 -- handed to whoever waits on the future
            future.set_exception(exc)
        return future


@dataclass
class _Executor:
    """An executor with what the study needs to know about it."""

    executor: cf.Executor
    workers: int
    owned: list = field(default_factory=list)      # things to close at the end (client, cluster)
    label: str = ""
    mine: bool = True                              # False: the caller's executor, left running

    def close(self, cancel: bool = False) -> None:
        if self.mine:
            try:
                self.executor.shutdown(wait=not cancel, cancel_futures=cancel)
            except TypeError:                     # executors without cancel_futures
                self.executor.shutdown(wait=not cancel)
        for thing in reversed(self.owned):
            try:
                thing.close()
            except Exception:                     # noqa: BLE001 -- closing what is already gone
                pass


class _Environment:
    """Puts back the environment variables a process pool changed while it ran."""

    def __init__(self, saved: dict):
        self.saved = saved

    def close(self) -> None:
        for name, value in self.saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _dask_client(scheduler: str | None, workers: int, timeout: float):
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise SweepError("missing_dependency", "--executor dask needs dask.distributed",
                         'pip install "multipole[cluster]"', "command line") from None
    if scheduler:
        try:
            client = Client(scheduler, timeout=timeout)
        except (OSError, TimeoutError) as exc:
            raise SweepError("scheduler_unreachable", f"no Dask scheduler answered at {scheduler} within "
                             f"{timeout:g} s ({type(exc).__name__})",
                             "start one with 'dask scheduler' and 'dask worker ADDRESS', or check the address "
                             "(tcp://host:8786)", "command line") from None
        except ValueError as exc:
            raise SweepError("bad_scheduler", f"--scheduler {scheduler!r}: {exc}",
                             "write the address as tcp://host:8786", "command line") from None
        n = max(1, sum(w.get("nthreads", 1) for w in client.scheduler_info().get("workers", {}).values()))
        return client, [client], n
    import logging
    logging.getLogger("distributed").setLevel(logging.ERROR)   # its shutdown notes are not the user's concern
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster, timeout=timeout)
    return client, [client, cluster], workers


def make_executor(kind="process", workers: int | None = None, scheduler: str | None = None,
                  timeout: float = SCHEDULER_TIMEOUT) -> _Executor:
    """The executor of a study: ``serial``, ``process`` (a local process pool, ``workers`` defaults
    to the CPU count), ``dask`` (a ``LocalCluster`` of ``workers`` processes, or the scheduler at
    ``scheduler``, waiting at most ``timeout`` s for it), or any ``concurrent.futures.Executor``."""
    if isinstance(kind, cf.Executor):
        return _Executor(kind, workers or os.cpu_count() or 1, label=type(kind).__name__, mine=False)
    if workers is not None and workers < 1:
        raise SweepError("bad_option", f"--workers must be at least 1, got {workers}", "", "command line")
    if not (timeout > 0 and math.isfinite(timeout)):
        raise SweepError("bad_option", f"--timeout must be a positive number of seconds, got {timeout:g}", "",
                         "command line")
    if scheduler and kind != "dask":
        raise SweepError("bad_option", "--scheduler needs --executor dask", "add --executor dask", "command line")
    if kind == "serial":
        return _Executor(SerialExecutor(), 1, label="serial")
    if kind == "process":
        import multiprocessing as mp
        n = workers or os.cpu_count() or 1
        # workers forked from a server that imported multipole once (fast to start, no threads of
        # this process copied), started with one BLAS thread in its environment
        kind_ = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        ctx = mp.get_context(kind_)
        if kind_ == "forkserver":
            ctx.set_forkserver_preload(["multipole.sweep"])
        saved = {name: os.environ.get(name) for name in THREAD_VARIABLES}
        os.environ.update({name: "1" for name in THREAD_VARIABLES})
        pool = cf.ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_worker_init)
        return _Executor(pool, n, [_Environment(saved)], label=f"process pool, {n} worker(s)")
    if kind == "dask":
        client, owned, n = _dask_client(scheduler, workers or 2, timeout)
        return _Executor(client.get_executor(), n, owned, label=f"dask ({client.scheduler.address})")
    raise SweepError("bad_option", f"unknown executor {kind!r}", "use serial, process or dask", "command line")


# -- planning ---------------------------------------------------------------------------------------
@dataclass
class Group:
    """Runs that share their structural values: one analysis and one compiled model."""

    structural: dict
    runs: list                         # indices into the design
    job: dict | None = None            # what a worker needs (None: the group failed to build)
    error: str = ""
    vectors: dict = field(default_factory=dict)     # run index -> runtime vector
    invalid: dict = field(default_factory=dict)     # run index -> diagnostic (value refused)


def _synthetic(name: str, taken: set) -> str:
    base = "sweep_" + re.sub(r"[^A-Za-z0-9_]", "_", name)
    out, k = base, 1
    while out in taken:
        k += 1
        out = f"{base}_{k}"
    taken.add(out)
    return out


def _text(value) -> str:
    """A design value as ``--set`` text (an int stays whole)."""
    return value if isinstance(value, str) else repr(value) if isinstance(value, int) else repr(float(value))


class Study:
    """A parameter study of one scene (see the module docstring); :meth:`run` fills ``rows``."""

    def __init__(self, path, specs: dict, metrics=None, samples: int | None = None, seed: int | None = None,
                 overrides: dict | None = None, t_end=None, dt_out=None, solver=None, rtol=None, atol=None,
                 settle_tol: float = SETTLE_TOL):
        self.path = str(path)
        self.overrides = dict(overrides or {})
        self.base = load(self.path, self.overrides)
        self.specs = [s if isinstance(s, Spec) else parse_spec(n, s) for n, s in specs.items()]
        if not self.specs:
            raise SweepError("bad_design", "nothing to vary", "add --set NAME=SPEC", "command line")
        if not 0 < settle_tol < 1:
            raise SweepError("bad_option", f"--settle-tol must be between 0 and 1, got {settle_tol:g}",
                             "e.g. 0.02 for a 2 % band", "command line")
        self._params: dict = {}          # swept element parameter -> its catalogue Param
        self.kinds = {s.name: self._classify(s) for s in self.specs}
        self.points = design(self.specs, samples, seed)
        self.metrics = metric_list(self.base, metrics)
        self.settle_tol = settle_tol
        opts = dict(self.base.simulate)
        for key, value in (("t_end", t_end), ("dt_out", dt_out), ("solver", solver), ("rtol", rtol), ("atol", atol)):
            if value is not None:
                opts[key] = value
        if t_end is not None and dt_out is None and opts.get("dt_out", 0.0) > t_end:
            del opts["dt_out"]
        from .netlist import validate_simulate_options
        self.options = validate_simulate_options(opts, self.path)
        if "t_end" not in self.options:
            raise SweepError("no_t_end", "no simulation time given", "add simulate: {t_end: ...} or use --t-end",
                             self.path)
        self.groups: list = []
        self.rows: list = []
        #: run index -> (t [s], {output: values}) when ``keep_trajectories`` (``--keep-trajectories``)
        self.keep_trajectories = False
        self.trajectories: dict = {}
        self.interrupted = False
        self.compile_time = 0.0

    @property
    def names(self) -> list:
        return [s.name for s in self.specs]

    def _classify(self, spec: Spec) -> str:
        """``runtime`` or ``structural`` for one swept parameter; ``unknown_parameter`` if the scene
        has no such scene or element parameter."""
        from .catalogue import catalogue
        name, scene = spec.name, self.base
        if "." not in name:
            if name not in scene.network.params:
                raise SweepError("unknown_parameter", f"--set {name}: the scene has no parameter {name!r}",
                                 f"scene parameters: {', '.join(scene.network.params) or 'none'}; element "
                                 "parameters are written ELEMENT.PARAM", self.path)
            return "runtime" if spec.numeric else "structural"
        element, _, pname = name.partition(".")
        etype = catalogue().get(scene.element_types.get(element, ""))
        if etype is None:
            raise SweepError("unknown_parameter", f"--set {name}: the scene has no element {element!r}",
                             f"elements: {', '.join(scene.element_types)}", self.path)
        param = etype.param(pname)
        if param is None:
            raise SweepError("unknown_parameter", f"--set {name}: {etype.name} has no parameter {pname!r}",
                             f"parameters of {etype.name}: {', '.join(p.name for p in etype.params)}", self.path)
        self._params[name] = param
        return "runtime" if spec.numeric and param.kind in _NUMBER_KINDS else "structural"

    # -- building ---------------------------------------------------------------------------------
    def plan(self) -> list:
        """Group the runs by their structural values and build each group's model once."""
        structural = [n for n in self.names if self.kinds[n] == "structural"]
        by_key: dict = {}
        for k, point in enumerate(self.points):
            by_key.setdefault(tuple(point[n] for n in structural), []).append(k)
        self.groups = [Group(dict(zip(structural, key)), runs) for key, runs in by_key.items()]
        start = time.perf_counter()
        for g in self.groups:
            self._build(g)
        self.compile_time = time.perf_counter() - start
        return self.groups

    def _build(self, group: Group) -> None:
        from . import pipeline
        from .codegen import compile_model
        runtime = [n for n in self.names if self.kinds[n] == "runtime"]
        overrides = dict(self.overrides)
        overrides.update({n: _text(v) for n, v in group.structural.items()})
        extra, symbol_of = {}, {}
        taken = set(self.base.network.params)
        for n in runtime:
            if "." in n:                 # an element parameter becomes a scene parameter of the study
                syn = _synthetic(n, taken)
                element, _, pname = n.partition(".")
                # a number (a formula or a bare name would make the added parameter an alias that
                # the flattening resolves away): the first of the group's values the element accepts
                values = [float(self.points[k][n]) for k in group.runs]
                extra[syn] = next((v for v in values if not self._params[n].problem(v)), values[0])
                overrides[n] = syn
                symbol_of[n] = syn
            else:
                symbol_of[n] = n
        try:
            try:
                scene = load(self.path, overrides, extra)
            except MultipoleError as exc:
                if not self._loads_with_numbers(group, runtime):
                    raise                # the group's own error, with numbers too
                # an element that needs a number (piezo_stack n): its swept parameters are structural
                mine = [n for n in runtime if "." in n and f"element '{n.partition('.')[0]}'" in exc.where]
                for n in mine or [n for n in runtime if "." in n]:
                    self.kinds[n] = "structural"
                raise _Replan() from None
            eq = pipeline.equations(scene)
            by_name = {str(p): p for p in eq.params}
            missing = [n for n in runtime if symbol_of[n] not in by_name]
            if missing:                  # a value the element builder did not keep as a symbol
                for n in missing:
                    self.kinds[n] = "structural"
                raise _Replan()
            flat = eq.analysis.flat
            swept = [by_name[symbol_of[n]] for n in runtime]
            order, exprs = _dependents(flat, swept)
            model = compile_model(eq, scene.outputs, order)
        except _Replan:
            raise
        except MultipoleError as exc:
            group.error = str(exc)
            return
        group.job = {"source": model.source, "meta": model.meta, "metrics": self.metrics,
                     "settle_tol": self.settle_tol, "keep_trajectories": self.keep_trajectories, **self.options}
        for k in group.runs:
            point = self.points[k]
            problem = self._refused(point, runtime)
            if problem:
                group.invalid[k] = problem
                continue
            values = {s: float(point[n]) for n, s in zip(runtime, swept)}
            try:
                for s in order[len(swept):]:
                    values[s] = float(exprs[s].xreplace(values))
            except (TypeError, ValueError, OverflowError) as exc:
                group.invalid[k] = f"error[bad_value] a parameter computed from the swept ones is not a number ({exc})"
                continue
            vector = [values[s] for s in order]
            if not all(math.isfinite(v) for v in vector):
                group.invalid[k] = "error[bad_value] a parameter computed from the swept ones is not finite"
                continue
            group.vectors[k] = vector

    def _loads_with_numbers(self, group: Group, runtime: list) -> bool:
        """True if the group's first run loads with its runtime element parameters written as
        numbers (then it was the symbols an element could not build with)."""
        if not any("." in n for n in runtime):
            return False
        point = self.points[group.runs[0]]
        overrides = dict(self.overrides)
        overrides.update({n: _text(point[n]) for n in self.names})
        try:
            load(self.path, overrides)
        except MultipoleError:
            return False
        return True

    def _refused(self, point: dict, runtime: list) -> str:
        """Why the loader would refuse a runtime value (an element parameter's own rules), or ''."""
        for n in runtime:
            param = self._params.get(n)
            if param is None:
                continue
            problem = param.problem(float(point[n]))
            if problem:
                return f"error[bad_value] {self.path} {n} [{param.unit or '-'}] {problem}, got {float(point[n]):g}"
        return ""

    # -- running -----------------------------------------------------------------------------------
    def run(self, executor="process", workers: int | None = None, scheduler: str | None = None,
            progress=None, chunk: int | None = None, timeout: float = SCHEDULER_TIMEOUT) -> list:
        """Run every group on ``executor`` (see :func:`make_executor`) and return the rows in run
        order.  ``progress``: a callable ``(done, failed, total, eta_seconds)`` or None.  Ctrl-C
        keeps the finished rows (``self.interrupted`` is set, the rest are cancelled)."""
        while True:
            try:
                self.plan()
                break
            except _Replan:
                continue
        rows: dict = {}
        for g in self.groups:
            for k in g.runs:
                if g.job is None:
                    rows[k] = {"run": k, "status": "failed", "diagnostic": g.error}
                elif k in g.invalid:
                    rows[k] = {"run": k, "status": "invalid", "diagnostic": g.invalid[k]}
        tasks = []
        ex = make_executor(executor, workers, scheduler, timeout) if not isinstance(executor, _Executor) else executor
        size = chunk or max(1, min(50, math.ceil(len(self.points) / (8 * ex.workers))))
        for g in self.groups:
            if g.job is None:
                continue
            todo = [(k, g.vectors[k]) for k in g.runs if k in g.vectors]
            tasks += [(g.job, todo[i:i + size]) for i in range(0, len(todo), size)]
        total, start = len(self.points), time.perf_counter()
        failed = sum(1 for r in rows.values() if r["status"] != "ok")

        def report():
            if progress is not None:
                done = len(rows)
                rate = (time.perf_counter() - start) / max(1, done - pre)
                progress(done, failed, total, rate * (total - done) if done > pre else math.nan)
        pre = len(rows)
        pending: dict = {}                       # future -> the runs of its chunk
        queue = iter(tasks)
        limit = 2 * ex.workers
        interrupted = False

        def lost(runs, exc):
            """A chunk whose worker could not run it (a worker killed, a cluster gone): its runs
            are failed rows, the study goes on with the others."""
            nonlocal failed
            for k, _ in runs:
                rows[k] = {"run": k, "status": "failed",
                           "diagnostic": f"error[worker_failed] {type(exc).__name__}: {exc}"[:300]}
                failed += 1
        try:
            report()
            while True:
                while len(pending) < limit:
                    task = next(queue, None)
                    if task is None:
                        break
                    try:
                        pending[ex.executor.submit(run_chunk, *task)] = task[1]
                    except (RuntimeError, OSError) as exc:      # a broken pool refuses new work
                        lost(task[1], exc)
                if not pending:
                    break
                finished, _ = cf.wait(list(pending), return_when=cf.FIRST_COMPLETED)
                for f in finished:
                    runs = pending.pop(f)
                    try:
                        chunk_rows = f.result()
                    except KeyboardInterrupt:
                        raise
                    except Exception as exc:     # noqa: BLE001 -- the executor's failure, not a run's
                        lost(runs, exc)
                        continue
                    for row in chunk_rows:
                        if "_trajectory" in row:
                            self.trajectories[row["run"]] = row.pop("_trajectory")
                        rows[row["run"]] = row
                        failed += row["status"] != "ok"
                report()
        except KeyboardInterrupt:
            interrupted = True
            for f in pending:
                f.cancel()
        finally:
            ex.close(cancel=interrupted)
        self.interrupted = interrupted
        self.wall_time = time.perf_counter() - start
        self.rows = [self._row(k, rows[k]) for k in sorted(rows)]
        return self.rows

    def _row(self, k: int, row: dict) -> dict:
        out = {"run": k}
        out.update(self.points[k])
        for m in self.metrics:
            out[m.name] = row.get(m.name, math.nan)
        for key in ROW_STATS:
            out[key] = row.get(key, "" if key == "solver" else math.nan)
        out["status"], out["diagnostic"] = row["status"], row["diagnostic"]
        return out

    # -- results -----------------------------------------------------------------------------------
    @property
    def columns(self) -> list:
        return ["run"] + self.names + [m.name for m in self.metrics] + list(ROW_STATS) + list(STATUS_COLUMNS)

    @property
    def failed(self) -> int:
        return sum(1 for r in self.rows if r["status"] != "ok")

    def summary(self) -> str:
        """A few lines: runs, failures, groups and compile time, wall time, metric ranges."""
        n, bad = len(self.rows), self.failed
        lines = [f"{self.base.name}: {n} of {len(self.points)} run(s) done, {n - bad} ok, {bad} failed"
                 + (" (interrupted)" if self.interrupted else ""),
                 f"parameters: " + ", ".join(f"{s.name} ({self.kinds[s.name]}: {s.text})" for s in self.specs),
                 f"{len(self.groups)} model(s) compiled in {self.compile_time:.3g} s; runs took "
                 f"{getattr(self, 'wall_time', 0.0):.3g} s"]
        for m in self.metrics:
            vals = np.array([r[m.name] for r in self.rows if r["status"] == "ok"], dtype=float)
            vals = vals[np.isfinite(vals)]
            if len(vals):
                lines.append(f"  {m.name}: min {vals.min():.6g}, max {vals.max():.6g}, mean {vals.mean():.6g}")
        kinds: dict = {}
        for r in self.rows:
            if r["status"] != "ok":
                kinds.setdefault(r["diagnostic"].split("]")[0] + "]", []).append(r["run"])
        for code, runs in kinds.items():
            lines.append(f"  {len(runs)} run(s) {code}: e.g. run {runs[0]}")
        return "\n".join(lines)

    def to_csv(self, path) -> None:
        """The rows as CSV (a header of :attr:`columns`; floats with 17 significant digits, so the
        numbers read back exactly)."""
        from .files import atomic_output
        with atomic_output(path) as tmp:
            with open(tmp, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(self.columns)
                for r in self.rows:
                    w.writerow([repr(r[c]) if isinstance(r[c], float) else r[c] for c in self.columns])

    def trajectory_rows(self):
        """The kept trajectories as rows ``(run, t, output values...)`` in run and time order."""
        outputs = self.base.outputs
        for k in sorted(self.trajectories):
            t, values = self.trajectories[k]
            for i, ti in enumerate(t):
                yield (k, float(ti)) + tuple(float(values[o][i]) for o in outputs)

    def trajectories_to_csv(self, path) -> None:
        """Every kept trajectory in one long table: ``run,t,<outputs>`` (SI units; pandas reads it
        directly, ``df.set_index(["run", "t"]).to_xarray()`` makes it an xarray Dataset)."""
        from .files import atomic_output
        with atomic_output(path) as tmp:
            with open(tmp, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["run", "t"] + list(self.base.outputs))
                w.writerows([repr(v) if isinstance(v, float) else v for v in row] for row in self.trajectory_rows())

    def trajectory_frame(self):
        """The kept trajectories as a long pandas DataFrame (columns ``run``, ``t``, the outputs)."""
        import pandas as pd
        return pd.DataFrame(list(self.trajectory_rows()), columns=["run", "t"] + list(self.base.outputs))

    def frame(self):
        """The rows as a pandas DataFrame (pandas is a dependency of multipole)."""
        import pandas as pd
        return pd.DataFrame(self.rows, columns=self.columns)

    def label(self, name: str) -> str:
        """``name [unit]`` for a swept element parameter or a metric of an output with a known SI
        unit (``settling`` in s), else the name alone."""
        unit = ""
        if name in self._params:
            unit = self._params[name].unit
        else:
            output, _, kind = name.rpartition(".")
            if kind == "settling":
                unit = "s"
            elif output in self.base.outputs:
                meta = next((g.job["meta"] for g in self.groups if g.job is not None), {})
                unit = meta.get("units", {}).get(output, "")
        return f"{name} [{unit}]" if unit and unit != "-" else name

    def figure(self, path, metric: str | None = None, overlay=None):
        """Metric against parameter (one parameter), a heat map (two parameters on a grid; a
        scatter coloured by the metric for a sampled design), or the metric against each parameter
        (more); failed runs are marked with red crosses.  ``overlay(ax)`` may draw on the axes."""
        from matplotlib.colors import LogNorm

        from .plotting import new_figure
        from .files import atomic_output
        metric = metric or self.metrics[0].name
        if metric not in {m.name for m in self.metrics}:
            raise SweepError("unknown_metric", f"--plot-metric {metric!r} is not a metric of the study",
                             f"one of {', '.join(m.name for m in self.metrics)}", "command line")
        ok = [r for r in self.rows if r["status"] == "ok"]
        bad = [r for r in self.rows if r["status"] != "ok"]
        numeric = [s for s in self.specs if s.numeric]
        log = {s.name: s.scale == "log" for s in self.specs}
        y = np.array([r[metric] for r in ok], dtype=float)
        title = f"{self.base.name}: {metric}"
        if len(numeric) == 2 and len(self.specs) == 2:
            a, b = numeric
            fig = new_figure(7, 5.2, layout=None)
            ax = fig.subplots()
            finite = y[np.isfinite(y)]
            log_colour = len(finite) > 0 and finite.min() > 0 and finite.max() > 1e3 * finite.min()
            norm = LogNorm() if log_colour else None
            if not a.random and not b.random:
                grid = np.full((len(b.values), len(a.values)), np.nan)
                for r in ok:
                    grid[b.values.index(r[b.name]), a.values.index(r[a.name])] = r[metric]
                mesh = ax.pcolormesh(_edges(a), _edges(b), grid, shading="flat", cmap="viridis", norm=norm)
            else:
                mesh = ax.scatter([r[a.name] for r in ok], [r[b.name] for r in ok], c=y, s=14, cmap="viridis",
                                  norm=norm)
            fig.colorbar(mesh, ax=ax, label=self.label(metric) + (" (log scale)" if log_colour else ""))
            if bad:
                ax.plot([r[a.name] for r in bad], [r[b.name] for r in bad], "rx", ms=5, label="failed run")
                ax.legend(loc="upper right")
            ax.set_xlabel(self.label(a.name))
            ax.set_ylabel(self.label(b.name))
            ax.set_xscale("log" if log[a.name] else "linear")
            ax.set_yscale("log" if log[b.name] else "linear")
        else:
            params = self.specs[:4]
            fig = new_figure(5.5 * len(params), 4.2, layout=None)
            axes = fig.subplots(1, len(params), squeeze=False)
            for ax, s in zip(axes[0], params):
                x = [r[s.name] for r in ok]
                if s.numeric and len(self.specs) == 1:
                    order = np.argsort(np.array(x, dtype=float))
                    ax.plot(np.array(x, dtype=float)[order], y[order], ".-")
                else:
                    ax.plot(x, y, ".")
                if bad:
                    lo = np.nanmin(y) if np.isfinite(y).any() else 0.0
                    ax.plot([r[s.name] for r in bad], [lo] * len(bad), "rx", ms=6, label="failed run")
                    ax.legend()
                ax.set_xlabel(self.label(s.name))
                ax.set_ylabel(self.label(metric))
                ax.set_xscale("log" if log[s.name] else "linear")
                ax.grid(True, alpha=0.3)
            ax = axes[0][0]
        if overlay is not None:
            overlay(ax)
        ax.set_title(title[:90])
        fig.tight_layout()
        with atomic_output(path) as tmp:
            fig.savefig(tmp, dpi=120)


class _Replan(Exception):
    """A runtime parameter turned out structural: plan again."""


def _edges(spec: Spec) -> np.ndarray:
    """Cell edges around the grid values (geometric means on a log range)."""
    v = np.array(spec.values, dtype=float)
    if len(v) == 1:
        return np.array([v[0] * 0.9, v[0] * 1.1]) if v[0] else np.array([-0.5, 0.5])
    if spec.scale == "log":
        mid = np.sqrt(v[1:] * v[:-1])
        return np.concatenate(([v[0] ** 2 / mid[0]], mid, [v[-1] ** 2 / mid[-1]]))
    mid = (v[1:] + v[:-1]) / 2
    return np.concatenate(([2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]))


def _dependents(flat, swept: list):
    """``(order, exprs)``: the swept parameter symbols, then every parameter computed from them in
    an order where each comes after what it uses; ``exprs[s]`` is the formula of a dependent one
    with every other parameter replaced by its value."""
    values = flat.param_values()
    formulas = {s: sp.sympify(v) for s, v in flat.params.items() if v is not None}
    runtime = list(swept)
    known = set(swept)
    changed = True
    while changed:
        changed = False
        for s, f in formulas.items():
            if s not in known and f.free_symbols & known:
                known.add(s)
                runtime.append(s)
                changed = True
    order = list(swept)
    placed = set(swept)
    rest = [s for s in runtime if s not in placed]
    while rest:
        progress = False
        for s in list(rest):
            if not (formulas[s].free_symbols & known) - placed:
                order.append(s)
                placed.add(s)
                rest.remove(s)
                progress = True
        if not progress:                        # cannot happen: the loader refuses cycles
            raise MultipoleError("parameter_cycle", "the parameters depend on each other in a cycle")
    fixed = {s: sp.Float(v) for s, v in values.items() if s not in known}
    exprs = {s: formulas[s].xreplace(fixed) for s in order[len(swept):]}
    return order, exprs


# -- the Python API ----------------------------------------------------------------------------
def sweep(scene, parameters: dict, metrics=None, executor="process", samples: int | None = None,
          seed: int | None = None, workers: int | None = None, scheduler: str | None = None, **options):
    """Run a parameter study and return its table as a pandas DataFrame.

    ``scene``: a netlist path (or a :class:`~multipole.netlist.Scene` loaded from a file);
    ``parameters``: ``{name: SPEC}`` with SPEC text as on the command line (``"1e7..1e9:log:20"``,
    ``"normal(2e8, 1e7)"``) or a list of values; ``metrics``: names ``output.kind`` or of the
    scene's ``metrics:`` section (default: final, max, min, rms of every output and the named
    metrics); ``executor``: ``"serial"``, ``"process"``, ``"dask"`` or a
    ``concurrent.futures.Executor``; ``options``: ``t_end``, ``dt_out``, ``solver``, ``rtol``,
    ``atol``, ``settle_tol``, ``overrides``.  One row per run (see docs/sweeps.md); a failed run
    is a row with its ``status`` and ``diagnostic``.
    """
    path = scene.path if isinstance(scene, Scene) else scene
    if not Path(str(path)).is_file():
        raise SweepError("no_file", f"a study needs the netlist file; {path!r} is not one",
                         "pass the path of the netlist")
    study = Study(path, parameters, metrics, samples, seed, **options)
    study.run(executor, workers, scheduler)
    return study.frame()


# -- the command line --------------------------------------------------------------------------
class _Bar:
    """``runs 120/900, 3 failed, ETA 12 s`` on one line of stderr."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.last = 0.0

    def __call__(self, done, failed, total, eta):
        now = time.perf_counter()
        if not self.enabled or (now - self.last < 0.2 and done < total):
            return
        self.last = now
        width = 30
        fill = int(width * done / total) if total else width
        eta_text = f"ETA {eta:.0f} s" if math.isfinite(eta) else "ETA --"
        sys.stderr.write(f"\r[{'#' * fill}{'.' * (width - fill)}] runs {done}/{total}, {failed} failed, {eta_text}   ")
        sys.stderr.flush()

    def end(self):
        if self.enabled:
            sys.stderr.write("\n")


def _sets(items) -> dict:
    out = {}
    for item in items or []:
        if "=" not in item:
            raise SweepError("bad_spec", f"--set {item!r} is not NAME=SPEC", "e.g. --set mesh.c=1e7..1e9:log:20",
                             "command line")
        name, text = item.split("=", 1)
        if name.strip() in out:
            raise SweepError("bad_design", f"parameter {name.strip()!r} is set twice",
                             "give one --set per parameter", "command line")
        out[name.strip()] = text.strip()
    return out


#: exit status of a study in which some runs failed (the table is written all the same)
EXIT_SOME_FAILED = 3


def cmd_sweep(args) -> int:
    """``multipole sweep``: exit 0 all runs ok, 3 some runs failed (the table has them), 2 invalid
    input, 130 Ctrl-C (the finished rows are written)."""
    from .cli import EXIT_INTERRUPTED
    from .files import atomic_output
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise SweepError("bad_output", f"-o {out}: is a file, not a folder", "give a folder name", "command line")
    metrics = [m for m in args.metrics.split(",") if m.strip()] if args.metrics else None
    if args.seed is not None and args.samples is None:
        raise SweepError("bad_design", "--seed needs --samples N", "add --samples N", "command line")
    study = Study(args.file, _sets(args.set), metrics, args.samples, args.seed, {}, args.t_end, args.dt_out,
                  args.solver, args.rtol, args.atol, args.settle_tol)
    study.keep_trajectories = args.keep_trajectories
    if args.plot_metric and args.plot_metric not in {m.name for m in study.metrics}:
        raise SweepError("unknown_metric", f"--plot-metric {args.plot_metric!r} is not a metric of the study",
                         f"one of {', '.join(m.name for m in study.metrics)}", "command line")
    n = len(study.points)
    if n > args.confirm and not args.yes:
        raise SweepError("too_many_runs", f"the study has {n} runs, more than {args.confirm} (--confirm)",
                         "add --yes to run it, or use fewer values", "command line")
    out.mkdir(parents=True, exist_ok=True)
    if not os.access(out, os.W_OK | os.X_OK):
        raise SweepError("bad_output", f"-o {out}: not writable", "write elsewhere", "command line")
    bar = _Bar(not args.quiet and sys.stderr.isatty())
    try:
        study.run(args.executor, args.workers, args.scheduler, bar, timeout=args.timeout)
    finally:
        bar.end()
    written = []
    study.to_csv(out / "runs.csv")
    written.append(out / "runs.csv")
    try:
        import pyarrow  # noqa: F401 -- only to know whether Parquet can be written
    except ImportError:
        pass
    else:
        with atomic_output(out / "runs.parquet") as tmp:
            study.frame().to_parquet(tmp)
        written.append(out / "runs.parquet")
    if study.keep_trajectories:
        study.trajectories_to_csv(out / "trajectories.csv")
        written.append(out / "trajectories.csv")
    if study.rows and any(r["status"] == "ok" for r in study.rows):
        study.figure(out / "figure.png", args.plot_metric)
        written.append(out / "figure.png")
    text = study.summary()
    with atomic_output(out / "summary.txt") as tmp:
        Path(tmp).write_text(text + "\n")
    written.append(out / "summary.txt")
    for name in ("runs.parquet", "trajectories.csv", "figure.png"):    # none left from an earlier study
        if out / name not in written and (out / name).is_file():
            (out / name).unlink()
    print(text)
    print("wrote " + ", ".join(str(w) for w in written))
    if study.interrupted:
        print(f"{args.file}: interrupted; {len(study.rows)} finished run(s) kept", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_SOME_FAILED if study.failed else 0


def add_arguments(p) -> None:
    """The options of ``multipole sweep`` (called by :mod:`multipole.cli`)."""
    p.add_argument("file")
    p.add_argument("--set", action="append", metavar="NAME=SPEC", required=True,
                   help="vary a parameter: list 1e7,2e7; range 1e7..1e9:log:20; normal(mu, sigma); uniform(a, b)")
    design_ = p.add_mutually_exclusive_group()
    design_.add_argument("--grid", action="store_true", help="full grid of the lists and ranges (default)")
    design_.add_argument("--samples", type=int, metavar="N", help="a sampled design of N runs")
    p.add_argument("--seed", type=int, help="seed of the sampled design (same seed, same runs)")
    p.add_argument("--metrics", help="comma-separated OUTPUT.KIND (final, max, min, rms, mean, settling) or names "
                   "of the netlist's metrics: section")
    p.add_argument("--settle-tol", type=float, default=SETTLE_TOL, help="band of the settling time (default 0.02)")
    p.add_argument("--executor", default="process", choices=("serial", "process", "dask"))
    p.add_argument("--workers", type=int, help="worker processes (default: the CPU count)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--timeout", type=float, default=SCHEDULER_TIMEOUT, help="seconds to wait for the scheduler")
    p.add_argument("-o", "--output", default="sweep_out", help="folder for runs.csv, figure.png, summary.txt")
    p.add_argument("--plot-metric", help="metric of the figure (default: the first)")
    p.add_argument("--keep-trajectories", action="store_true",
                   help="also write every run's outputs to trajectories.csv (run, t, outputs)")
    p.add_argument("--yes", action="store_true", help="run a study of more than --confirm runs")
    p.add_argument("--confirm", type=int, default=CONFIRM_RUNS, help="runs allowed without --yes (default 1000)")
    p.add_argument("--t-end", type=float)
    p.add_argument("--dt-out", type=float)
    p.add_argument("--solver")
    p.add_argument("--rtol", type=float)
    p.add_argument("--atol", type=float)
    p.add_argument("--quiet", action="store_true", help="no progress bar")


class _CallableModule(type(sys)):
    """This module, callable: ``multipole.sweep(scene, {...})`` is :func:`sweep`, while
    ``multipole.sweep.Study`` and ``import multipole.sweep`` still reach the module (a function
    of the same name in the package would hide the module from ``import multipole.sweep as s``)."""

    def __call__(self, *args, **kwargs):
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
