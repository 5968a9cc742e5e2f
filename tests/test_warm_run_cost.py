"""A warm run on the numba backend reuses the compiled loop's work arrays (docs/performance.md,
"Linkages (issue 12)": what surrounds the compiled loop).  Counted results, not time.

The backend keeps one set of work arrays per model between runs and readies it for the next run
instead of allocating it again.  A run on kept arrays must give, bit for bit, what a run on new
arrays gives (the reference: the same model with its kept arrays dropped, i.e. the allocating path)
whatever ran before it (another tolerance, horizon, output grid or method), with located events
(a one-sided contact), scheduled crossings (a square-wave torque, an odd number of them before),
a nonlinear algebraic loop solved by Newton's method (its guesses and counters live in the work
arrays) and the linkage benchmark's four-bar; and a result must not change when the model runs
again.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

from multipole import pipeline                                       # noqa: E402
from multipole.backends import numba_backend                         # noqa: E402
from multipole.netlist import loads                                  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import linkage_bench                                                 # noqa: E402
from test_events import CONTACT            # noqa: E402  (a mass hitting a one-sided spring: events)

SQUARE_WAVE = """
name: square_wave
parameters: {J: 1.0e-3, T: 1.0, w: 2.0e3}
elements:
  drive: {type: torque_source, value: "T*sign(sin(w*t))"}
  body:  {type: inertia, J: J}
connections:
  - [drive.p, body.a]
outputs: [body.omega]
simulate: {t_end: 0.02, dt_out: 1.0e-4}
"""

#: (fraction of t_end, dt_out / the scene's, solver, rtol, atol) of the runs before the compared one
BEFORE = [(1.0, 1.0, "RK45", 1e-5, 1e-8), (0.6, 1.0, "Radau", 1e-6, 1e-9), (0.35, 3.0, "RK45", 1e-9, 1e-12)]
LOOP = (Path(__file__).resolve().parents[1] / "diagrams" / "hard" / "nonlinear_loop.yaml").read_text()
SCENES = {"contact": CONTACT, "square_wave": SQUARE_WAVE, "nonlinear_loop": LOOP, "four-bar": linkage_bench.SCENE}


def model_of(text):
    """The numba model of a scene, with its default options ``(t_end, dt_out)``."""
    sc = loads(text, "scene.yaml")
    eq, outs, _ = pipeline.pruned(sc)
    return numba_backend.run.compile(eq, outs), sc.simulate["t_end"], sc.simulate["dt_out"]


def run(model, t_end, dt_out, solver="RK45", rtol=1e-8, atol=1e-11):
    return numba_backend.run.run_model(model, t_end, dt_out, solver, rtol, atol, progress=False)


def fingerprint(res):
    """Everything a run reports that does not depend on the clock."""
    stats = {k: v for k, v in res.stats.items() if not k.endswith("_time")}
    return (res.t.tobytes(), res.states.tobytes(), {k: v.tobytes() for k, v in res.outputs.items()}, stats,
            res.events, res.solver, res.monitors)


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("solver", ["RK45", "Radau"])
def test_a_run_on_kept_work_arrays_equals_a_run_on_new_ones(name, solver):
    model, t_end, dt_out = model_of(SCENES[name])
    horizon = min(t_end, 0.5)
    model.__dict__.pop("_work", None)
    reference = fingerprint(run(model, horizon, dt_out, solver))          # new arrays
    assert "_work" in model.__dict__                                       # kept for the next run
    for part, dt, other, rtol, atol in BEFORE:
        run(model, part * horizon, min(dt * dt_out, part * horizon), other, rtol, atol)
        kept = model.__dict__["_work"]
        again = run(model, horizon, dt_out, solver)
        assert model.__dict__["_work"] is kept                             # the same arrays were used
        assert fingerprint(again) == reference
    if name == "contact":                # the runs compared had events (in and out of the contact)
        assert len(again.events) >= 2
    if name == "square_wave":            # sin(w t) = 0 in (0, t_end); 7 in the run over 0.6 t_end before
        assert len(again.events) == int(np.floor(2.0e3 * horizon / np.pi)) == 12
    if name == "nonlinear_loop":
        assert again.stats["newton_iterations"] > 0


def test_a_result_does_not_change_when_the_model_runs_again():
    model, t_end, dt_out = model_of(CONTACT)
    first = run(model, t_end, dt_out)
    kept = fingerprint(first)
    second = run(model, t_end / 2, dt_out / 2, "Radau", 1e-6, 1e-9)
    assert not np.shares_memory(first.states, second.states)
    assert fingerprint(first) == kept


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_warm_compiled_run_enters_no_warnings_context(backend, monkeypatch):
    """The driver collects the run's Python warnings (``stats["warnings"]``) inside a warnings
    context; a run of the compiled integrator whose method and time-switch schedule are already
    known has no Python code that could warn and skips it (counted: contexts entered per run).  The
    first run (the method chosen and the time switches' crossings found by evaluating the model in
    Python) and every numpy run enter it."""
    import warnings
    sim = sys.modules["multipole.simulate"]
    entered = []

    class Counting(warnings.catch_warnings):
        def __enter__(self):
            entered.append(1)
            return super().__enter__()
    sc = loads(SQUARE_WAVE.replace("square_wave", "square_wave_warnings"), "scene.yaml")
    eq, outs, _ = pipeline.pruned(sc)                # derived and compiled before counting
    numba_backend.run.compile(eq, outs) if backend == "numba" else pipeline.model(sc)
    monkeypatch.setattr(sim.warnings, "catch_warnings", Counting)
    counts = []
    for _ in range(3):
        entered.clear()
        res = pipeline.run(sc, backend=backend, progress=False)
        counts.append(len(entered))
    assert res.stats["backend"] == backend
    assert counts == ([1, 0, 0] if backend == "numba" else [1, 1, 1])
