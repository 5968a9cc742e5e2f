"""Run-time monitors (:class:`multipole.Monitor`, issues 10/12/13): an element declares an
expression whose crossing from >= 0 to < 0 the run reports (or stops at), located like a switching
event on both backends.

The kernel-only scene is a mass m on a spring k started at x = A at rest, so x = A cos(w t) with
w = sqrt(k/m); a monitor on ``x - x0`` fires at t_n = (acos(x0/A) + 2 pi n)/w.  The dead centre of a
speed-driven four-bar (the same closed form as tests/test_linkage_checks.py) checks the closures'
guard, which is expressed through the same monitors, on both backends."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest
import sympy as sp

from multipole import (C, I, ModelError, Monitor, Network, Quantity, RunError, analyse, assemble, compile_model,
                       flatten, junction_b, pipeline, simulate)
from multipole.catalogue import _REGISTRY, ElementType, Param, catalogue
from multipole.cli import main
from test_events import BACKENDS
from test_linkage_checks import THETA0, rocker_driven, theta_at

M, K, A = 2.0, 50.0, 0.1
W = math.sqrt(K / M)
PERIOD = 2 * math.pi / W
RTOL, ATOL = 1e-10, 1e-13


def crossing_times(x0: float, t_end: float) -> list:
    """The downward crossings of x = A cos(w t) through x0 in [0, t_end] [s]."""
    first = math.acos(x0 / A) / W
    return [first + n * PERIOD for n in range(int((t_end - first) // PERIOD) + 1)]


def event_tolerance(x0: float) -> float:
    """How far [s] a located crossing may be from the closed form: the bisection stops at 1e-14 s;
    the integrated x is off by at most about 100 rtol·A (a global error over a few periods), and
    |dx/dt| = w sqrt(A^2 - x0^2) at the crossing turns that into time."""
    return 100 * RTOL * A / (W * math.sqrt(A ** 2 - x0 ** 2)) + 1e-12


def oscillator(x0=0.05, stop=False, expr=None, code="passed_x0") -> Network:
    """The mass-spring (a 1-junction joining the inertia and the spring) with a monitor on x - x0."""
    x, lim = sp.Symbol("x"), sp.Symbol("x0")
    return Network("monitored_oscillator", {
        "mass": I(J=M, dom="translational"), "spring": C(c=K, dom="translational", q0=A),
        "j": junction_b(["m", "s"], "translational")}, [["j.m", "mass.p"], ["j.s", "spring.p"]],
        params={"x0": x0}, signals={"x": "spring.q", "F": "spring.p.e"},
        quantities={"x": Quantity(lambda V: V.x("spring.q"), "m")},
        monitors=[Monitor(x - lim if expr is None else expr, code, "the spring passed x0", stop=stop)])


def run(net: Network, t_end: float, backend: str = "numpy", **kw):
    eq = assemble(analyse(flatten(Network("scene", {"osc": net}))))
    if backend == "numpy":
        return simulate(compile_model(eq, ["osc.x"]), t_end, t_end / 200, rtol=RTOL, atol=ATOL, progress=False, **kw)
    from multipole.backends.numba_backend import run as numba
    model = numba.compile(eq, ["osc.x"])
    return simulate(model, t_end, t_end / 200, rtol=RTOL, atol=ATOL, progress=False, integrator=numba.integrator,
                    **kw)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("x0", [0.05, -0.08])
def test_a_monitor_fires_at_each_downward_crossing_at_the_closed_form_time(backend, x0):
    t_end = 3.0 * PERIOD
    res = run(oscillator(x0), t_end, backend)
    expected = crossing_times(x0, t_end)
    assert len(expected) == 3
    assert [(el, code) for _t, el, code, _text in res.monitors] == [("osc", "passed_x0")] * 3
    times = np.array([t for t, *_ in res.monitors])
    assert np.max(np.abs(times - expected)) <= event_tolerance(x0), (times, expected)
    assert np.allclose(res["osc.x"], A * np.cos(W * res.t), rtol=0, atol=100 * RTOL * A)
    assert res.events == []              # a monitor switches no law: no switching event is listed


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_monitor_negative_at_the_start_fires_only_when_it_falls_again(backend):
    """x0 - x starts at x0 - A < 0, rises through 0 at acos(x0/A)/w (not reported) and falls where x
    climbs back through x0, at (2 pi - acos(x0/A))/w + n 2 pi/w."""
    x0, t_end = 0.05, 3.0 * PERIOD
    res = run(oscillator(x0, expr=sp.Symbol("x0") - sp.Symbol("x")), t_end, backend)
    expected = [(2 * math.pi - math.acos(x0 / A)) / W + n * PERIOD for n in range(3)]
    times = np.array([t for t, *_ in res.monitors])
    assert len(times) == 3 and np.max(np.abs(times - expected)) <= event_tolerance(x0), (times, expected)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_monitor_does_not_change_the_integration(backend):
    """Same samples as the run without a monitor (to the method's error) and bounded work: each of
    the six crossings (three down, three up) restarts the method once, nothing more."""
    t_end = 3.0 * PERIOD
    plain = run(oscillator(expr=sp.Integer(1)), t_end, backend)        # a monitor that is never crossed
    watched = run(oscillator(), t_end, backend)
    assert plain.monitors == [] and len(watched.monitors) == 3
    assert np.allclose(watched["osc.x"], plain["osc.x"], rtol=0, atol=100 * RTOL * A)
    assert watched.stats["segments"] <= plain.stats["segments"] + 6
    assert watched.stats["steps"] <= 1.5 * plain.stats["steps"] + 6 * 10
    assert watched.stats["rejected"] <= plain.stats["rejected"] + 6 * 2


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_monitor_that_never_crosses_reports_nothing(backend):
    """x0 below -A: x - x0 stays positive; x0 above A: it is negative from the start (no crossing)."""
    for x0 in (-1.5 * A, 1.5 * A):
        res = run(oscillator(x0), 3.0 * PERIOD, backend)
        assert res.monitors == []


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_stop_monitor_ends_the_run_with_its_code_time_and_element(backend):
    x0 = 0.05
    with pytest.raises(RunError) as exc:
        run(oscillator(x0, stop=True), 3.0 * PERIOD, backend)
    assert exc.value.code == "passed_x0" and exc.value.element == "osc"
    t = float(re.search(r"at t = (\S+) s", exc.value.message).group(1))
    first = crossing_times(x0, PERIOD)[0]
    assert abs(t - first) <= 5e-6 * first          # printed to 6 significant digits


def test_a_monitor_on_a_port_effort_fires_where_the_force_crosses():
    """The signal F (the spring's effort) = k x: F - k x0 crosses where x does."""
    x0 = 0.03
    res = run(oscillator(x0, expr=sp.Symbol("F") - K * sp.Symbol("x0")), PERIOD)
    [(t, el, code, _text)] = res.monitors
    assert abs(t - crossing_times(x0, PERIOD)[0]) <= event_tolerance(x0)


# -- bad declarations: clean errors ------------------------------------------------------------------

def test_an_unknown_name_in_a_monitor_is_a_clean_error_naming_element_and_monitor():
    with pytest.raises(ModelError) as exc:
        flatten(Network("scene", {"osc": oscillator(expr=sp.Symbol("nowhere") - 1)}))
    assert exc.value.code == "unknown_name"
    assert "osc monitor passed_x0" in exc.value.message and "nowhere" in exc.value.message


@pytest.mark.parametrize("kw", [{"expr": "x - x0"}, {"code": "passed x0"}])
def test_a_string_expression_or_a_bad_code_is_refused(kw):
    with pytest.raises(ModelError) as exc:
        oscillator(**kw)
    assert exc.value.code == "bad_monitor"


def test_a_monitor_list_of_something_else_is_refused():
    with pytest.raises(ModelError) as exc:
        Network("n", {"spring": C(c=1.0)}, monitors=[("x", "code", "text")])
    assert exc.value.code == "bad_monitor"


# -- the command line --------------------------------------------------------------------------------

@pytest.fixture
def oscillator_type(monkeypatch):
    """The oscillator as a netlist element type, registered for one test only."""
    def build(x0, stop):
        return oscillator(x0, bool(stop))
    etype = ElementType("monitored_oscillator", build, "mass-spring with a monitor on x - x0 (tests)",
                        {}, [Param("x0", "m", "monitored position"),
                             Param("stop", "", "stop the run there", False, kind="bool")],
                        {"x": "m: spring displacement"})
    catalogue()
    monkeypatch.setitem(_REGISTRY, etype.name, etype)
    return etype


NETLIST = f"""
name: watched
elements:
  osc: {{type: monitored_oscillator, x0: 0.05, stop: STOP}}
outputs: [osc.x]
simulate: {{t_end: {2.2 * PERIOD!r}, dt_out: 0.01, rtol: {RTOL!r}, atol: {ATOL!r}}}
"""


def test_cli_prints_one_warning_line_per_crossing(tmp_path, capsys, oscillator_type):
    path = tmp_path / "watched.yaml"
    path.write_text(NETLIST.replace("STOP", "false"))
    assert main(["simulate", str(path), "--quiet"]) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines() if "passed_x0" in ln]
    expected = crossing_times(0.05, 2.2 * PERIOD)
    assert len(lines) == len(expected) == 3
    for line, t in zip(lines, expected):
        m = re.fullmatch(r"multipole: warning: t = (\S+) s: osc: the spring passed x0 \[passed_x0\]", line)
        assert m and abs(float(m.group(1)) - t) <= 5e-6 * t


def test_cli_stop_monitor_exits_with_the_run_error_code_in_one_line(tmp_path, capsys, oscillator_type):
    path = tmp_path / "watched.yaml"
    path.write_text(NETLIST.replace("STOP", "true"))
    assert main(["simulate", str(path), "--quiet"]) == RunError.exit_code == 3
    err = capsys.readouterr().err.strip().splitlines()
    [line] = [ln for ln in err if ln.startswith("error[")]
    assert line.startswith("error[passed_x0] ") and "element 'osc'" in line and "Traceback" not in "\n".join(err)


# -- the closures' dead-centre guard is a stop monitor on both backends ------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_a_speed_driven_four_bar_stops_at_its_dead_centre_on_every_backend(backend):
    """The rocker-driven four-bar of tests/test_linkage_checks.py at 1 rad/s: the guard |sin(phi2 -
    phi1)| reaches 0.1 (near_dead_centre, reported) and 1e-4 (dead_centre, stop) at rocker angles
    the triangle closes in closed form."""
    with pytest.raises(RunError) as exc:
        pipeline.run(rocker_driven(), t_end=1.0, rtol=1e-8, progress=False, backend=backend)
    assert exc.value.code == "dead_centre" and exc.value.element == "dyad"
    t_stop = float(re.search(r"at t = (\S+) s", exc.value.message).group(1))
    assert abs(t_stop - (theta_at(1e-4) - THETA0)) <= 5e-6 * t_stop
    t_guard = theta_at(0.1) - THETA0
    res = pipeline.run(rocker_driven(), t_end=t_guard + 1e-3, rtol=1e-8, progress=False, backend=backend)
    [(t, el, code, _text)] = res.monitors
    assert (el, code) == ("dyad", "near_dead_centre") and abs(t - t_guard) <= 1e-6


def test_pruning_keeps_what_a_monitor_reads_and_drops_an_unwatched_subsystem():
    """Only ``osc.x`` is requested: a second oscillator with a monitor stays (its crossings are
    reported at the closed-form times), a third one without a monitor is pruned away."""
    from multipole.pruning import prune
    plain = oscillator()
    plain.monitors = []
    scene = Network("scene", {"osc": oscillator(), "watched": oscillator(x0=-0.08), "unwatched": plain})
    eq = assemble(analyse(flatten(scene)))
    small, record = prune(eq, ["osc.x"])
    assert sorted(name.split(".")[0] for name, _el, _why in record.dropped_states) == ["unwatched", "unwatched"]
    t_end = 1.5 * PERIOD
    res = simulate(compile_model(small, ["osc.x"]), t_end, t_end / 200, rtol=RTOL, atol=ATOL, progress=False)
    watched = [t for t, el, _code, _text in res.monitors if el == "watched"]
    assert np.max(np.abs(np.array(watched) - crossing_times(-0.08, t_end))) <= event_tolerance(-0.08)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_monitor_on_a_laws_own_switching_function_fires_once_per_crossing(backend):
    """A mass between a spring (50 N/m) and a one-sided spring (200 N/m while x > 0), the monitor on
    x itself: the monitor and the one-sided spring's switch cross at the same instants.  Each
    downward crossing is reported once, at t_n = pi/(2 w1) + n (pi/w1 + pi/w2) with w1 = sqrt(250/m),
    w2 = sqrt(50/m), and the work is that of the run without the monitor (it used to chatter)."""
    q, x = sp.Symbol("q"), sp.Symbol("x")

    def scene(monitors):
        return Network("osc", {"mass": I(J=M, dom="translational"), "s1": C(c=50.0, dom="translational", q0=A),
                               "s2": C(law=200 * sp.Max(q, 0), dom="translational", q0=A),
                               "j": junction_b(["m", "a", "b"], "translational")},
                       [["j.m", "mass.p"], ["j.a", "s1.p"], ["j.b", "s2.p"]], signals={"x": "s1.q"},
                       quantities={"x": Quantity(lambda V: V.x("s1.q"), "m")}, monitors=monitors)

    w1, w2 = math.sqrt(250 / M), math.sqrt(50 / M)
    t_end = 3.0
    expected = [math.pi / (2 * w1) + n * (math.pi / w1 + math.pi / w2) for n in range(4)]
    assert expected[-1] < t_end < expected[-1] + math.pi / w1 + math.pi / w2
    watched = run(scene([Monitor(x, "crossed", "x fell below 0")]), t_end, backend)
    plain = run(scene([]), t_end, backend)
    times = np.array([t for t, *_ in watched.monitors])
    assert len(times) == 4 and np.max(np.abs(times - expected)) <= 100 * RTOL * A / (w1 * A) + 1e-12, times
    assert len(watched.events) == len(plain.events)
    assert watched.stats["steps"] <= plain.stats["steps"] + 2 * len(times)
