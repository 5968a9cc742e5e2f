"""Compiled backend (``--backend numba``): agreement with theory and with the numpy backend.

Expected values come from closed forms (RLC step response, the linear drive train through the
matrix exponential, the geared inertias' effective inertia, the contact's event times) or from the
numpy backend, which runs the same algorithms in scipy.  No test looks at wall-clock time.

Run as a script, this file measures the speed-against-error figures of docs/backends.md:

    python tests/test_backends.py [-o docs/figures]
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

sys.path.insert(0, str(Path(__file__).parent))
from helpers import scene  # noqa: E402

from multipole import pipeline  # noqa: E402
from multipole.cli import main  # noqa: E402
from multipole.netlist import load  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DRIVE = ROOT / "diagrams" / "drive_train.yaml"
RLC = ROOT / "diagrams" / "rlc_series.yaml"


@pytest.fixture
def nb():
    """The numba backend module (the tests using it are skipped without numba)."""
    pytest.importorskip("numba")
    from multipole.backends import numba_backend
    return numba_backend


# -- hand-written models of the same physics (independent of the kernel) ------------------------
class DriveTrain:
    """Motor torque 10(1 - exp(-t/0.05)) N·m -> rotor J1 -> gear i -> shaft (c, d) -> load J2 -> bearing.

    States (as the kernel orders them): rotor momentum p1 [N·m·s], shaft twist q [rad], load
    momentum p2 [N·m·s]."""

    n_states = 3

    def __init__(self, c=2000.0, J1=2e-3, i=3.0, d=0.5, J2=0.5, db=0.8):
        self.c, self.J1, self.i, self.d, self.J2, self.db = c, J1, i, d, J2, db
        self.A = np.array([[-d / (i * i * J1), -c / i, d / (i * J2)],
                           [1 / (i * J1), 0.0, -1 / J2],
                           [d / (i * J1), c, -(d + db) / J2]])
        self.b = np.array([1.0, 0.0, 0.0])

    def terms(self, t, x, exp=math.exp):
        """d/dt of the states; ``exp`` is math.exp, or casadi.exp for a symbolic model."""
        c, J1, i, d, J2, db = self.c, self.J1, self.i, self.d, self.J2, self.db
        w1, w2 = x[0] / J1, x[2] / J2
        rel = w1 / i - w2
        torque = c * x[1] + d * rel
        return [10.0 * (1.0 - exp(-t / 0.05)) - torque / i, rel, torque - db * w2]

    def rhs(self, t, x):
        return np.array(self.terms(t, x))

    def jac(self, t, x):
        return self.A

    def outputs(self, X):
        """rotor.omega, load.omega, shaft.force over the rows of X."""
        return {"rotor.omega": X[:, 0] / self.J1, "load.omega": X[:, 2] / self.J2, "shaft.force": self.c * X[:, 1]}

    def exact(self, t):
        """Closed form: x' = A x + b (u1 - u2), u1 = 10, u2' = -20 u2, u2(0) = 10, by expm."""
        M = np.zeros((5, 5))
        M[:3, :3] = self.A
        M[:3, 3], M[:3, 4] = self.b, -self.b
        M[4, 4] = -1 / 0.05
        z0 = np.array([0, 0, 0, 10.0, 10.0])
        return self.outputs(np.array([(expm(M * tt) @ z0)[:3] for tt in t]))


class RLCSeries:
    """12 V step into R = 10 Ω, L = 0.1 H, C = 100 µF; states L1.p [V·s], C1.q [C]."""

    V, R, L, C = 12.0, 10.0, 0.1, 1.0e-4
    n_states = 2

    def terms(self, t, x, exp=math.exp):
        return [self.V - self.R * x[0] / self.L - x[1] / self.C, x[0] / self.L]

    def rhs(self, t, x):
        return np.array(self.terms(t, x))

    def jac(self, t, x):
        return np.array([[-self.R / self.L, -1 / self.C], [1 / self.L, 0.0]])

    def outputs(self, X):
        return {"C1.v": X[:, 1] / self.C, "L1.i": X[:, 0] / self.L}

    def exact(self, t):
        a = self.R / (2 * self.L)
        w0 = 1 / math.sqrt(self.L * self.C)
        wd = math.sqrt(w0 ** 2 - a ** 2)
        e = np.exp(-a * t)
        return {"C1.v": self.V * (1 - e * (np.cos(wd * t) + a / wd * np.sin(wd * t))),
                "L1.i": self.V / (self.L * wd) * e * np.sin(wd * t)}


def rel_error(res, ref: dict) -> float:
    """max over outputs of max_t |y - y_ref| / max_t |y_ref|."""
    return max(float(np.max(np.abs(res[k] - v)) / np.max(np.abs(v))) for k, v in ref.items())


def run_numba(path_or_scene, **kw):
    """``pipeline.run`` of a diagram path or a scene on the numba backend, which must have run (a
    fallback to numpy would pass most comparisons unnoticed)."""
    sc = load(path_or_scene) if isinstance(path_or_scene, Path) else path_or_scene
    res = pipeline.run(sc, progress=False, backend="numba", **kw)
    assert res.stats["backend"] == "numba", res.stats["backend"]
    return res


# -- agreement with theory ---------------------------------------------------------------------------
@pytest.mark.parametrize("solver", ["RK45", "Radau"])
def test_rlc_step_response_matches_the_closed_form(nb, solver):
    res = run_numba(RLC, solver=solver)            # rtol 1e-9, atol 1e-12 from the scene
    assert res.solver == solver and "numba" in res.solver_reason
    assert rel_error(res, RLCSeries().exact(res.t)) <= 1000 * 1e-9   # global error within 1000 rtol
    assert res.t[0] == 0.0 and res.t[-1] == pytest.approx(0.1, abs=1e-15) and len(res.t) == 1001


@pytest.mark.parametrize("solver", ["RK45", "Radau"])
def test_drive_train_matches_the_matrix_exponential(nb, solver):
    res = run_numba(DRIVE, solver=solver, dt_out=0.02, rtol=1e-10, atol=1e-12)
    assert rel_error(res, DriveTrain().exact(res.t)) <= 1000 * 1e-10


GEARED = """
name: geared
parameters: {J1: 0.01, J2: 0.3, i: 4.0, T: 2.0, d: 0.05}
elements:
  drive:   {type: torque_source, value: T}
  J_2:     {type: inertia, J: J2}
  gear:    {type: ideal_gear, i: i}
  J_1:     {type: inertia, J: J1}
  brake:   {type: damper, d: d}
  housing: {type: ground}
connections:
  - [drive.p, J_2.a]
  - [J_2.b, gear.b]
  - [gear.a, J_1.a]
  - [J_1.b, brake.a]
  - [brake.b, housing.p]
outputs: [J_1.omega, J_2.omega]
simulate: {t_end: 2.0, dt_out: 0.01, rtol: 1.0e-10, atol: 1.0e-12}
"""


@pytest.mark.parametrize("solver", ["RK45", "Radau"])
def test_geared_inertias_in_derivative_causality(nb, solver):
    """J_1 is rigidly geared to J_2: one state, effective inertia J2 + i² J1, damping i² d."""
    J1, J2, i, T, d = 0.01, 0.3, 4.0, 2.0, 0.05
    res = run_numba(scene(GEARED), solver=solver)
    assert len(res.state_names) == 1
    J_eff, d_eff = J2 + i ** 2 * J1, i ** 2 * d
    w2 = T / d_eff * (1 - np.exp(-d_eff * res.t / J_eff))
    assert np.max(np.abs(res["J_2.omega"] - w2)) / w2.max() <= 1e-8
    assert np.allclose(res["J_1.omega"], i * res["J_2.omega"], rtol=1e-12, atol=1e-12)


def test_contact_events_at_the_closed_form_times(nb):
    """Mass into a compression-only spring: contact at gap/v0 for half a period pi*sqrt(m/k)."""
    from test_events import CONTACT
    m, k, v0, gap = 0.5, 2.0e4, 1.5, 0.01
    for solver in ("RK45", "Radau"):
        res = run_numba(scene(CONTACT), solver=solver)
        times = [t for t, _ in res.events]
        assert len(times) == 2 and res.stats["segments"] == 3
        t_in, t_out = gap / v0, gap / v0 + np.pi * np.sqrt(m / k)
        assert abs(times[0] - t_in) < 1e-9 and abs(times[1] - t_out) < 1e-9
        after = res.t > t_out + 1e-4
        assert np.allclose(res["body.v"][after], -v0, rtol=1e-6)


SIGN_LAW = """
name: sign_law
parameters: {d: 0.2, v: 3.0}
elements:
  drive: {type: speed_source, value: v}
  brake: {type: damper, law: "d*f + 0.5*(sign(f) + 1)"}
  body:  {type: inertia, J: 1.0}
  housing: {type: ground}
connections:
  - [drive.p, body.a]
  - [body.b, brake.a]
  - [brake.b, housing.p]
outputs: [brake.force]
simulate: {t_end: 0.1, dt_out: 0.05}
"""


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_sign_inside_a_sum_is_evaluated_as_written(backend):
    """force = d*v + 0.5*(sign(v) + 1) = 0.2*3 + 1 for v = 3 m/s (the numpy backend printed the
    conditional expression of sign unparenthesised and gave 0.2*3 + 0.5)."""
    if backend == "numba":
        pytest.importorskip("numba")
    res = pipeline.run(scene(SIGN_LAW), progress=False, backend=backend)
    assert res.stats["backend"] == backend
    assert np.allclose(res["brake.force"], 0.2 * 3.0 + 1.0, rtol=1e-12)


# -- agreement with the numpy backend ------------------------------------------------------------------
NONLINEAR_LOOP = """
name: nonlinear_dampers_in_series
parameters: {J: 0.1}
elements:
  drive: {type: torque_source, value: "2*(1 - exp(-t/0.1))"}
  body:  {type: inertia, J: J}
  d1:    {type: damper, law: "0.5*f + 0.2*f**3"}
  d2:    {type: damper, law: "0.3*f + 0.1*sinh(f)"}
  gnd:   {type: ground}
connections:
  - [drive.p, body.a]
  - [body.b, d1.a]
  - [d1.b, d2.a]
  - [d2.b, gnd.p]
outputs: [body.omega, d1.force, d2.force]
simulate: {t_end: 2.0, dt_out: 0.01, rtol: 1.0e-8}
"""


@pytest.mark.parametrize("solver", ["RK45", "Radau"])
def test_same_algorithms_as_the_numpy_backend(nb, solver):
    """Both backends run Dormand–Prince 5(4) / Radau IIA(5) with scipy's step control: the same
    solution within the tolerance, and about the same work."""
    for sc in (load(DRIVE), load(RLC), scene(NONLINEAR_LOOP)):
        a = pipeline.run(sc, solver=solver, progress=False)
        b = run_numba(sc, solver=solver)
        assert a.stats["backend"] == "numpy"
        assert np.array_equal(a.t, b.t) and b.state_names == a.state_names and b.units == a.units
        rtol = sc.simulate["rtol"]
        for name in a.outputs:
            assert np.max(np.abs(a[name] - b[name])) <= 100 * rtol * np.max(np.abs(a[name])), name
        assert abs(b.stats["steps"] - a.stats["steps"]) <= 0.1 * a.stats["steps"]


def test_nonlinear_loop_is_solved_by_newton_in_compiled_code(nb):
    res = run_numba(scene(NONLINEAR_LOOP), solver="RK45")
    assert "numpy" not in res.stats["backend"]
    # every evaluation of the right-hand side solves the loop once
    assert res.stats["newton_solves"] >= res.stats["nfev"] > 0
    assert res.stats["newton_iterations"] >= res.stats["newton_solves"]
    # the loop: both dampers carry the same force (massless node between them)
    assert np.allclose(res["d1.force"], res["d2.force"], rtol=1e-9, atol=1e-12)


def test_auto_picks_radau_for_a_stiff_shaft_like_the_numpy_backend(nb):
    sc = load(DRIVE, {"c_shaft": "1e8"})
    a = pipeline.run(sc, t_end=0.5, rtol=1e-6, progress=False)
    b = run_numba(sc, t_end=0.5, rtol=1e-6)
    assert a.solver == b.solver == "Radau" and b.solver_reason.startswith("stiff")
    exact = DriveTrain(c=1e8).exact(b.t[::25])
    for res in (a, b):                              # global error within 1000 rtol, as above
        assert max(float(np.max(np.abs(res[k][::25] - v)) / np.max(np.abs(v))) for k, v in exact.items()) <= 1e-3
    b2 = run_numba(DRIVE, t_end=0.5)
    assert b2.solver == "RK45" and b2.solver_reason.startswith("non-stiff")


def test_other_scipy_names_map_to_the_two_methods(nb):
    sc = load(RLC)
    for asked, runs in (("DOP853", "RK45"), ("BDF", "Radau"), ("LSODA", "Radau"), ("RK23", "RK45")):
        res = run_numba(sc, t_end=0.01, solver=asked)
        assert res.solver == runs and asked in res.solver_reason


# -- statistics, cache, progress, errors -------------------------------------------------------------
def test_stats_are_filled(nb):
    first = run_numba(DRIVE, solver="Radau", t_end=0.5)
    s = first.stats
    for key in ("nfev", "njev", "nlu", "steps", "rejected", "compile_time", "run_time", "translate_time",
                "wall_time", "segments"):
        assert key in s, key
    assert s["steps"] > 0 and s["nfev"] > 3 * s["steps"] and s["njev"] >= 1 and s["nlu"] >= 2
    assert s["compile_time"] > s["translate_time"] > 0 and s["run_time"] > 0
    again = run_numba(DRIVE, solver="Radau", t_end=0.5)
    assert again.stats["compile_cached"]
    assert np.array_equal(again["shaft.force"], first["shaft.force"])
    rk = run_numba(DRIVE, solver="RK45", t_end=0.5).stats
    assert rk["njev"] == 0 and rk["nlu"] == 0 and rk["nfev"] >= 6 * rk["steps"] + 2
    assert "wall" in first.summary() and "compile" in first.summary()


def test_generated_source_is_the_same_in_every_process(nb):
    """The cache key is the source's hash: it must not depend on Python's hash seed."""
    code = ("from multipole.netlist import load; from multipole import pipeline; import hashlib;"
            "from multipole.backends.numba_backend import generate;"
            f"sc = load({str(DRIVE)!r}); "
            "print(hashlib.sha256(generate(pipeline.equations(sc), sc.outputs)[0].encode()).hexdigest())")
    keys = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONHASHSEED": seed}).stdout for seed in ("1", "2")}
    assert len(keys) == 1


def test_progress_chunks_do_not_change_the_result(nb, monkeypatch, capsys):
    plain = run_numba(RLC, solver="Radau", t_end=0.03)
    monkeypatch.setattr(nb, "PROGRESS_CHUNK", 7)
    chunked = pipeline.run(load(RLC), solver="Radau", t_end=0.03, progress=True, backend="numba")
    assert chunked.stats["backend"] == "numba"
    assert "100.0%" in capsys.readouterr().err
    assert np.array_equal(plain.states, chunked.states) and plain.stats["nfev"] == chunked.stats["nfev"]


def test_output_grid_is_the_numpy_backends(nb):
    for t_end, dt in ((0.1, 0.03), (0.1, 0.01), (2.0, None)):
        a = pipeline.run(load(RLC), t_end=t_end, dt_out=dt, progress=False)
        b = run_numba(RLC, t_end=t_end, dt_out=dt)
        assert np.array_equal(a.t, b.t)


@pytest.fixture
def fresh_equations(monkeypatch, tmp_path):
    """Equations derived anew in this test: pipeline.pruned remembers them per scene in the process,
    and the numba backend its compiled model on them, so a scene an earlier test ran on numba would
    never reach the patched compiler; nor would a model restored from the disk cache (an empty one
    here) or from memory, nor equations assembled by an earlier check of the scene."""
    monkeypatch.setattr(pipeline, "_CHECKED", {})
    monkeypatch.setattr(pipeline, "_PRUNED", {})
    monkeypatch.setattr(pipeline, "_RESTORED", {})
    monkeypatch.setenv("MULTIPOLE_CACHE", str(tmp_path / "cache"))


def _numba_cannot_compile(nb, monkeypatch):
    def broken(source):
        import numba
        raise numba.core.errors.TypingError("no typing for this construct\nsecond line of numba's report")
    monkeypatch.setattr(nb, "load", broken)


def test_a_model_numba_cannot_compile_runs_on_numpy_visibly(nb, monkeypatch, fresh_equations):
    """The fallback is announced (a warning naming the reason) and recorded in ``stats["backend"]``
    and ``solver_reason``; the numpy run gives the right answer."""
    from multipole.errors import MultipoleWarning
    _numba_cannot_compile(nb, monkeypatch)
    with pytest.warns(MultipoleWarning, match=r"numba backend could not compile this model \(TypingError: no typing") as rec:
        res = pipeline.run(load(RLC), t_end=0.01, progress=False, backend="numba")
    assert not any("refused" in str(w.message) for w in rec)
    reason = "TypingError: no typing for this construct"
    assert res.stats["backend"] == f"numpy (fallback: could not compile: {reason})"
    assert f"({reason}), ran numpy instead" in res.solver_reason
    assert rel_error(res, RLCSeries().exact(res.t)) <= 1e-6


def test_a_model_the_numba_printer_cannot_translate_runs_on_numpy_visibly(nb, monkeypatch, fresh_equations):
    from multipole.errors import MultipoleWarning

    def untranslatable(eq, outputs):
        raise NotImplementedError("the numba printer has no rule for this function")
    monkeypatch.setattr(nb, "translate", untranslatable)
    with pytest.warns(MultipoleWarning, match="NotImplementedError"):
        res = pipeline.run(load(RLC), t_end=0.01, progress=False, backend="numba")
    assert res.stats["backend"].startswith("numpy (fallback: could not compile: NotImplementedError: the numba "
                                           "printer has no rule")
    assert rel_error(res, RLCSeries().exact(res.t)) <= 1e-6


def test_a_model_above_the_compile_size_limit_runs_on_numpy_visibly(nb, monkeypatch, fresh_equations):
    """numba is not started on a module whose source cost is above the limit (its compile time grows
    super-linearly): the run falls back saying the model was *refused as too large* (not that it
    failed to compile), with the cost, the limit and the variable that raises it; below it, numba runs."""
    from multipole.errors import MultipoleWarning
    monkeypatch.setenv("MULTIPOLE_NUMBA_MAX_COST", "1000")
    with pytest.warns(MultipoleWarning, match=r"numba backend refused this model as too large \(generated source "
                      r"costs [\d,]+ .*above the limit of 1,000; set the environment variable "
                      r"MULTIPOLE_NUMBA_MAX_COST above the cost") as rec:
        res = pipeline.run(load(RLC), t_end=0.01, progress=False, backend="numba")
    assert not any("could not compile" in str(w.message) for w in rec)
    assert res.stats["backend"].startswith("numpy (fallback: refused as too large: generated source costs ")
    assert res.stats["backend"].endswith("above the limit of 1,000)")
    assert "refused this model as too large" in res.solver_reason
    assert rel_error(res, RLCSeries().exact(res.t)) <= 1e-6
    monkeypatch.delenv("MULTIPOLE_NUMBA_MAX_COST")
    assert run_numba(RLC, t_end=0.01).stats["backend"] == "numba"


def test_a_100_state_chain_is_below_the_compile_size_limit(nb):
    """The target of a 100-state model on numba: the 50-pair mass-spring chain's generated source is
    under the default limits, and so is the 150-pair chain's (compiled in chunks: test_numba_chunks.py)."""
    import multipole_models
    cost = {}
    for n in (50, 150):
        sc = scene(multipole_models.mass_spring_chain(n))
        cost[n] = nb.source_cost(nb.translate(pipeline.equations(sc), sc.outputs)[0])
        nb.check_size(nb.translate(pipeline.equations(sc), sc.outputs)[0])
    assert cost[50] < cost[150] <= nb.MAX_SOURCE_COST, cost


def test_the_cli_shows_a_fallback_as_one_warning_line(nb, monkeypatch, fresh_equations, capsys):
    _numba_cannot_compile(nb, monkeypatch)
    assert main(["simulate", str(RLC), "--backend", "numba", "--quiet", "--t-end", "0.01"]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("multipole: warning:") and "TypingError" in err[0], err


def test_both_backends_report_the_same_stats_and_events(nb):
    """One set of statistics keys (simulate.STATS_KEYS, documented in docs/backends.md) and the
    same events on a scene with a time switch and a state switch."""
    from multipole.simulate import STATS_KEYS
    sc = scene(EVENT_SCENE)
    a = pipeline.run(sc, solver="RK45", progress=False)
    b = run_numba(sc, solver="RK45")
    assert set(a.stats) == set(b.stats) == set(STATS_KEYS)
    assert a.stats["backend"] == "numpy"
    assert [text for _, text in a.events] == [text for _, text in b.events] and len(a.events) == 3
    assert np.allclose([t for t, _ in a.events], [t for t, _ in b.events], rtol=0, atol=1e-9)
    for s in (a.stats, b.stats):
        assert s["events"] == 3 and s["segments"] == 4
        for key in ("steps", "rejected", "nfev", "newton_failures"):
            assert isinstance(s[key], int) and s[key] >= 0, key
        assert s["wall_time"] > 0 and s["compile_time"] > 0


#: the contact of tests/test_events.py, pushed by a force that starts at t = 5 ms (a time switch)
EVENT_SCENE = """
name: pushed_contact
parameters: {m: 0.5, k: 2.0e4, v0: 1.5, gap: 0.01, F: 2.0}
elements:
  push:   {type: force_source, value: "F*step(t - 0.005)"}
  body:   {type: mass, m: m, v0: v0}
  stop_j: {type: junction_a, ports: [a, b, c], signs: [1, -1, -1], domain: translational}
  stop:   {type: C, law: "k*max(q, 0)", q0: "-gap", domain: translational}
  wall:   {type: ground, domain: translational}
connections:
  - [push.p, body.a]
  - [body.b, stop_j.a]
  - [stop_j.b, wall.p]
  - [stop_j.c, stop.p]
outputs: [body.v, stop.q]
simulate: {t_end: 0.05, dt_out: 1.0e-4, rtol: 1.0e-10, atol: 1.0e-13}
"""


SQRT_BRAKE = """
name: sqrt_brake
elements:
  body:    {type: inertia, J: 1.0, omega0: 1.0}
  brake:   {type: damper, law: "sqrt(f)"}
  housing: {type: ground}
connections:
  - [body.b, brake.a]
  - [brake.b, housing.p]
outputs: [body.omega]
simulate: {t_end: 3.0, dt_out: 0.1}
"""


def test_integration_failure_is_a_simulation_error(nb):
    """omega' = -sqrt(omega) reaches 0 at t = 2 s; beyond, sqrt of a negative speed is NaN."""
    from multipole.simulate import SimulationError
    with pytest.raises(SimulationError) as err:
        run_numba(scene(SQRT_BRAKE), solver="RK45")
    assert err.value.code in ("not_finite", "step_failed") and "t = 2" in err.value.message


def test_cli_backend_option(nb, tmp_path, capsys):
    out = tmp_path / "r.csv"
    assert main(["simulate", str(DRIVE), "--backend", "numba", "--quiet", "--t-end", "0.1", "--dt-out", "0.01",
                 "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "(numba)" in captured.out and "ran numpy instead" not in captured.out and "warning" not in captured.err
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape == (11, 4) and np.allclose(data[:, 0], np.linspace(0, 0.1, 11))


def test_cli_unknown_backend_is_a_clean_error(capsys):
    assert main(["simulate", str(DRIVE), "--backend", "no_such_backend", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "unknown backend 'no_such_backend'" in err and "numpy" in err and "Traceback" not in err



CHATTER = """
name: square_wave_torque
parameters: {J: 1.0e-3, T: 1.0, w: 100000.0}
elements:
  drive: {type: torque_source, value: "T*sign(sin(w*t))"}
  body:  {type: inertia, J: J}
connections:
  - [drive.p, body.a]
outputs: [body.omega]
simulate: {t_end: 0.2, dt_out: 1.0e-4}
"""


def test_both_backends_end_a_chattering_run_with_one_error_text(nb):
    """The shared driver words the event limit once: the square wave's crossings are k*pi/w, so
    the (MAX_EVENTS + 1)-th ends the run at (MAX_EVENTS + 1)*pi/w on either backend, same text."""
    from multipole.simulate import MAX_EVENTS, SimulationError
    messages = {}
    for backend in ("numpy", "numba"):
        with pytest.raises(SimulationError) as err:
            pipeline.run(scene(CHATTER), progress=False, backend=backend)
        assert err.value.code == "chattering"
        messages[backend] = err.value.message
    t_last = (MAX_EVENTS + 1) * math.pi / 1e5
    assert messages["numpy"] == messages["numba"]
    assert f"more than {MAX_EVENTS} switching events by t = {t_last:.6g} s" in messages["numba"]


# a Newton loop, and a Newton and a linear loop (the piezo stack's linear loops are assignments since
# rigid couplings are eliminated before the loop is solved, c72e300)
@pytest.mark.parametrize("path", ["hard/nonlinear_loop.yaml", "linkages/motor_gear_crank.yaml"])
def test_compiled_jacobian_through_algebraic_loops_matches_differences(nb, path):
    """The numba Jacobian is printed from the kernel's structured plan (codegen.JacobianPlan,
    including the loops' Dz = -Jz^-1 G): against central differences of the numpy backend's
    right-hand side, error O(h^2) with h = 1e-6 relative."""
    from multipole import codegen
    eq = pipeline.equations(load(ROOT / "diagrams" / path))
    assert any(isinstance(s, codegen.LoopDerivatives) for s in codegen.Writer(eq).jacobian_plan().steps)
    compiled, reference = nb.run.compile(eq, []), codegen.compile_model(eq, [])
    x = np.asarray(reference.x0, dtype=float) + 0.1
    J = compiled.jac(0.01, x)
    for j in range(len(x)):
        h = 1e-6 * max(1.0, abs(x[j]))
        up, down = x.copy(), x.copy()
        up[j] += h
        down[j] -= h
        column = (np.asarray(reference.rhs(0.01, up)) - np.asarray(reference.rhs(0.01, down))) / (2 * h)
        assert np.allclose(J[:, j], column, rtol=1e-5, atol=1e-6 * max(1.0, np.abs(column).max()))


def test_ctrl_c_in_the_compiled_loop_is_interrupted_at_the_time_reached(nb, monkeypatch):
    """The shared driver turns Ctrl-C into Interrupted(t) on every backend: here the compiled loop
    runs 5 steps, then Ctrl-C arrives; t is where those steps ended."""
    from multipole.errors import Interrupted
    K, real, reached = nb.K, nb.K.integrate, []

    def integrate_then_ctrl_c(*args):
        if reached:
            raise KeyboardInterrupt
        real(*args[:-1], 5)
        reached.append(float(args[4][K.F_T]))       # fs[F_T]: the time reached
    sc = load(DRIVE)
    eq = pipeline.equations(sc)
    nb.run.compile(eq, sc.outputs)                 # compiled (and kept on eq) before the patch
    monkeypatch.setattr(K, "integrate", integrate_then_ctrl_c)
    with pytest.raises(Interrupted) as err:
        nb.run(eq, sc.outputs, 1.0, None, "RK45", progress=False)
    assert 0.0 < reached[0] < 1.0 and err.value.t == reached[0]

def test_backends_are_loaded_from_their_entry_point_group(monkeypatch):
    """Both bundled backends come from the ``multipole.backends`` entry points of the installed
    distribution (pyproject.toml), not from a list inside the kernel."""
    from importlib.metadata import entry_points

    from multipole import backends
    group = {ep.name: ep.value for ep in entry_points(group="multipole.backends")}
    assert group.get("numpy") == "multipole.backends:numpy_backend"
    assert group.get("numba") == "multipole.backends.numba_backend:run"
    monkeypatch.setattr(backends, "_BACKENDS", {})
    assert backends.get_backend("numpy") is backends.numpy_backend
    assert "numpy" in backends.available()


def test_a_backend_whose_package_is_missing_is_refused_by_name(monkeypatch):
    from importlib.metadata import EntryPoint

    from multipole import backends
    from multipole.errors import MultipoleError
    missing = EntryPoint("ghost", "no_such_package_h11.backend:run", backends.GROUP)
    monkeypatch.setattr(backends, "_entry_points", lambda: {"ghost": missing})
    with pytest.raises(MultipoleError) as exc:
        backends.get_backend("ghost")
    assert exc.value.code == "backend_unavailable" and "no_such_package_h11" in str(exc.value)
    with pytest.raises(MultipoleError) as exc:
        backends.get_backend("nothing_registered")
    assert exc.value.code == "unknown_backend"

# -- the kernels' numerical building blocks ---------------------------------------------------------------
def test_tableaus_satisfy_their_order_conditions(nb):
    from multipole.backends import numba_kernels as K
    b, c, A = K.DP_B, K.DP_C, K.DP_A
    for k, exact in enumerate((1, 1 / 2, 1 / 3, 1 / 4, 1 / 5)):     # quadrature order 5
        assert np.dot(b, c ** k) == pytest.approx(exact, abs=1e-15)
    assert np.allclose(A.sum(axis=1), c, atol=1e-15)
    assert K.DP_E[:6] @ np.ones(6) + K.DP_E[6] == pytest.approx(0, abs=1e-16)   # weights of two estimates of y
    # Radau IIA: the collocation conditions sum_j a_ij c_j^(k-1) = c_i^k / k, k = 1..3
    for k in (1, 2, 3):
        assert np.allclose(K.RA_A @ K.RA_C ** (k - 1), K.RA_C ** k / k, atol=1e-14)
    Lam = np.array([[K.RA_MU_REAL, 0, 0], [0, K.RA_MU_COMPLEX.real, -K.RA_MU_COMPLEX.imag],
                    [0, K.RA_MU_COMPLEX.imag, K.RA_MU_COMPLEX.real]])
    assert np.allclose(K.RA_T @ Lam @ K.RA_TI, np.linalg.inv(K.RA_A), atol=1e-12)


def test_small_lu_solves_real_and_complex_systems(nb):
    from multipole.backends import numba_kernels as K
    rng = np.random.default_rng(1)
    for dtype in (float, complex):
        A = rng.normal(size=(6, 6)) + (1j * rng.normal(size=(6, 6)) if dtype is complex else 0)
        A[0, 0] = 0.0                                     # needs pivoting
        b = rng.normal(size=6).astype(dtype)
        LU, piv, z = A.copy(), np.zeros(6, dtype=np.int64), b.copy()
        K.lu_factor(LU, piv)
        K.lu_solve(LU, piv, z)
        assert np.allclose(A @ z, b, atol=1e-12)


# =====================================================================================================
# Speed against error (python tests/test_backends.py): not part of the test run.
# =====================================================================================================
def _best_time(fun, budget=0.5, most=30):
    """Smallest wall time of repeated whole calls [s] (at least 3, until ``budget`` s or ``most``).

    The first call is not timed: it compiles (numba) or loads the model, which is reported apart."""
    import time
    value = fun()
    times, spent = [], 0.0
    while len(times) < 3 or (spent < budget and len(times) < most):
        t0 = time.perf_counter()
        value = fun()
        times.append(time.perf_counter() - t0)
        spent += times[-1]
    return min(times), value


def _bench_scene(name, path, overrides, hand, stiff, rtol0, atol0, rtols):
    """Work-precision data of (a) hand-written scipy, (b) numpy backend, (c) numba backend and,
    if casadi is installed, (d) CasADi's CVODES on the hand-written equations."""
    from scipy.integrate import solve_ivp

    from multipole.backends import numba_backend as nbk
    from multipole.simulate import output_grid, simulate
    sc = load(path, overrides)
    eq = pipeline.equations(sc)
    outs = sc.outputs
    t_end, dt_out = sc.simulate["t_end"], sc.simulate["dt_out"]
    model = pipeline.model(sc)
    grid = output_grid(t_end, dt_out)
    exact = hand.exact(grid)
    x0 = np.zeros(len(eq.states))
    methods = ["Radau"] if stiff else ["RK45", "DOP853"]
    curves: dict = {}

    class _Hand:
        def __init__(self, sol):
            self.t, self.outputs = sol.t, hand.outputs(sol.y.T)

        def __getitem__(self, k):
            return self.outputs[k]

    def add(label, fun, r):
        sec, res = _best_time(fun)
        curves.setdefault(label, []).append((r, rel_error(res, exact), sec))

    for r in rtols:
        a = atol0 * r / rtol0
        for m in methods:
            kw = {"jac": hand.jac} if m == "Radau" else {}
            add(f"(a) hand-written scipy {m}",
                lambda: _Hand(solve_ivp(hand.rhs, (0, t_end), x0, m, t_eval=grid, rtol=r, atol=a, **kw)), r)
            add(f"(b) numpy backend {m}", lambda: simulate(model, t_end, dt_out, m, r, a, progress=False), r)
        m = "Radau" if stiff else "RK45"
        add(f"(c) numba backend {m}", lambda: nbk.run(eq, outs, t_end, dt_out, m, r, a, progress=False), r)
        cvodes = _casadi_integrator(hand, grid, stiff, r, a)
        if cvodes is not None:
            add(f"(d) CasADi CVODES {'BDF' if stiff else 'Adams'}", cvodes, r)
    return curves


def _casadi_integrator(hand, grid, stiff, rtol, atol):
    """The hand-written model as CasADi expressions, integrated by SUNDIALS CVODES (BDF with
    Newton and the automatic Jacobian when stiff, else Adams with functional iteration)."""
    try:
        import casadi as ca
    except ImportError:
        return None
    x, t = ca.SX.sym("x", hand.n_states), ca.SX.sym("t")
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": 10 ** 6}
    if not stiff:
        opts.update(linear_multistep_method="adams", nonlinear_solver_iteration="functional")
    F = ca.integrator("F", "cvodes", {"x": x, "t": t, "ode": ca.vertcat(*hand.terms(t, x, ca.exp))},
                      0.0, grid[1:], opts)

    class _Run:
        def __init__(self):
            X = np.hstack([np.zeros((x.numel(), 1)), np.array(F(x0=0)["xf"])]).T
            self.outputs = hand.outputs(X)

        def __getitem__(self, k):
            return self.outputs[k]
    return _Run


def _time_at_error(points, err):
    """Wall time at error ``err`` interpolated log-log along a work-precision curve."""
    pts = sorted(points, key=lambda p: p[1])
    e = np.log([p[1] for p in pts])
    s = np.log([p[2] for p in pts])
    if err <= pts[0][1]:
        return float(np.exp(s[0])) if err == pts[0][1] else float("nan")
    return float(np.exp(np.interp(np.log(err), e, s)))


def _compile_times(path):
    """translate/compile/run [s] of one run in fresh processes: cold numba cache, new model, cached."""
    import json
    import tempfile
    code = textwrap.dedent(f"""
        import json, sys
        from multipole.netlist import load
        from multipole import pipeline
        res = pipeline.run(load({str(path)!r}, dict(a.split("=") for a in sys.argv[1:])), progress=False,
                           backend="numba")
        print(json.dumps({{k: res.stats[k] for k in ("translate_time", "compile_time", "run_time",
                                                     "compile_cached")}}))""")
    numba_dir, model_dir = tempfile.mkdtemp(), tempfile.mkdtemp()
    env = {**os.environ, "NUMBA_CACHE_DIR": numba_dir, "MULTIPOLE_CACHE": model_dir}
    rows = {}
    for label, args in (("cold (kernels and model compiled)", []), ("new model (kernels cached)", ["i=3.5"]),
                        ("cached", ["i=3.5"])):
        out = subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True, text=True,
                             check=True).stdout
        rows[label] = json.loads(out.strip().splitlines()[-1])
    return rows


def bench(outdir: Path) -> str:
    """Measure every scene, draw the work-precision figure, return the markdown tables."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    scenes = [("drive_train", DRIVE, None, DriveTrain(), False, 1e-8, 1e-9, [1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]),
              ("rlc_series", RLC, None, RLCSeries(), False, 1e-9, 1e-12, [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]),
              ("stiff drive train (c_shaft = 1e6)", DRIVE, {"c_shaft": "1e6"}, DriveTrain(c=1e6), True, 1e-6, 1e-9,
               [1e-4, 1e-5, 1e-6, 1e-7, 1e-8])]
    lines = ["| scene | tolerance | (a) hand-written scipy | error | (b) numpy backend | (c) numba backend "
             "| (d) CasADi CVODES | (a)/(c) | (b)/(c) |", "|---|---|---|---|---|---|---|---|---|"]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    for ax, (name, path, over, hand, stiff, rtol0, atol0, rtols) in zip(axes, scenes):
        curves = _bench_scene(name, path, over, hand, stiff, rtol0, atol0, rtols)
        at_tol = {lab: next(p for p in pts if p[0] == rtol0) for lab, pts in curves.items()}
        hand_best = min((lab for lab in at_tol if lab.startswith("(a)")), key=lambda lab: at_tol[lab][2])
        _, err_a, t_a = at_tol[hand_best]
        t_b = _time_at_error(curves[hand_best.replace("(a) hand-written scipy", "(b) numpy backend")], err_a)
        equal = {}
        for tag in ("(c)", "(d)"):
            lab = next((lab for lab in curves if lab.startswith(tag)), None)
            equal[tag] = f"{lab[lab.index(' ', 10) + 1:]}: {1e3 * _time_at_error(curves[lab], err_a):.3g} ms" \
                if lab else "n/a"
        t_c = _time_at_error(curves[next(lab for lab in curves if lab.startswith("(c)"))], err_a)
        lines.append(f"| {name} | rtol {rtol0:g}, atol {atol0:g} | {hand_best[23:]}: {1e3 * t_a:.3g} ms | "
                     f"{err_a:.2g} | {1e3 * t_b:.3g} ms | {equal['(c)']} | {equal['(d)']} | "
                     f"**{t_a / t_c:.0f}×** | {t_b / t_c:.0f}× |")
        for lab, pts in curves.items():
            style = {"(a)": ":^", "(b)": "--s", "(c)": "-o", "(d)": "-.x"}[lab[:3]]
            ax.loglog([p[2] * 1e3 for p in pts], [p[1] for p in pts], style, ms=4, label=lab)
        ax.axhline(err_a, color="0.6", lw=0.8, ls="--")
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("wall time of the whole simulation [ms]")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("max relative error of the outputs (vs closed form)")
    fig.suptitle("Speed against error, times at equal error read along the curves "
                 "(grey line: error of the fastest (a) at the scene's tolerance)", fontsize=10)
    fig.tight_layout()
    outdir.mkdir(parents=True, exist_ok=True)
    fig.savefig(outdir / "backend_work_precision.png", dpi=110)
    rows = _compile_times(DRIVE)
    lines += ["", "| drive_train, fresh process | translate [s] | compile incl. translate [s] | run [ms] |",
              "|---|---|---|---|"]
    for label, s in rows.items():
        lines.append(f"| {label} | {s['translate_time']:.3f} | {s['compile_time']:.2f} | {1e3 * s['run_time']:.2f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    import argparse
    parser = argparse.ArgumentParser(description="speed against error of the backends (docs/backends.md)")
    parser.add_argument("-o", "--output", default=str(ROOT / "docs" / "figures"))
    print(bench(Path(parser.parse_args().output)))


def test_switches_are_held_on_their_side_in_compiled_segments(nb):
    """The compiled loop holds every switch on its side for a segment, as the numpy backend does, so
    the slack rope's arcs are smooth: at most one rejected step per restart, and the same events."""
    path = ROOT / "diagrams" / "hard" / "slack_rope.yaml"
    res = run_numba(path, solver="RK45")
    ref = pipeline.run(load(path), solver="RK45", progress=False)
    assert res.stats["rejected"] <= res.stats["segments"]
    assert len(res.events) == len(ref.events) and np.allclose([t for t, _ in res.events],
                                                               [t for t, _ in ref.events], atol=1e-9)


def test_arithmetic_failure_in_compiled_code_is_one_line_not_ignored(nb, tmp_path, capfd, monkeypatch):
    """A compiled function cannot raise into the integrator: a division by zero there used to be
    printed as an ignored exception while the run went on.  With numpy's error model it yields a
    non-finite value, which the driver refuses in one line (exit 3)."""
    path = tmp_path / "inv.yaml"
    path.write_text(textwrap.dedent("""\
        name: inv
        elements:
          src: {type: torque_source, value: "1.0"}
          J: {type: inertia, J: 1.0}
          d: {type: damper, law: "1/f"}
          g: {type: ground}
        connections:
          - [src.p, J.a]
          - [J.b, d.a]
          - [d.b, g.p]
        outputs: [J.omega]
        simulate: {t_end: 1.0, dt_out: 0.25}
        """), encoding="utf-8")
    ignored = []
    monkeypatch.setattr(sys, "unraisablehook", ignored.append)   # where compiled code's exceptions go
    code = main(["simulate", str(path), "--backend", "numba", "--quiet"])
    err = capfd.readouterr().err.strip().splitlines()
    assert code == 3 and not ignored, [str(u.exc_value) for u in ignored]
    assert len(err) == 1 and err[0].startswith("error[") and "inv.yaml" in err[0], err
