"""Switching laws are events: the integrator stops at the crossing and restarts on the other side."""
import numpy as np
import pytest

from helpers import run

CONTACT = """
name: contact
parameters: {m: 0.5, k: 2.0e4, v0: 1.5, gap: 0.01}
elements:
  body:   {type: mass, m: m, v0: v0}
  stop_j: {type: junction_a, ports: [a, b, c], signs: [1, -1, -1], domain: translational}
  stop:   {type: C, law: "k*max(q, 0)", q0: "-gap", domain: translational}
  wall:   {type: ground, domain: translational}
connections:
  - [body.b, stop_j.a]
  - [stop_j.b, wall.p]
  - [stop_j.c, stop.p]
outputs: [body.v, stop.q]
simulate: {t_end: 0.05, dt_out: 1.0e-5, solver: DOP853, rtol: 1.0e-11, atol: 1.0e-13}
"""


def test_one_sided_contact_is_found_as_two_events():
    """A mass flies across a gap into a compression-only spring and bounces back.

    Closed form: contact starts at gap/v0, lasts half a period pi*sqrt(m/k), and the mass leaves
    with -v0 (no loss)."""
    m, k, v0, gap = 0.5, 2.0e4, 1.5, 0.01
    res = run(CONTACT)
    times = [t for t, _ in res.events]
    assert len(times) == 2
    t_in = gap / v0
    t_out = t_in + np.pi * np.sqrt(m / k)
    assert abs(times[0] - t_in) < 1e-9 and abs(times[1] - t_out) < 1e-9
    after = res.t > t_out + 1e-4
    assert np.allclose(res["body.v"][after], -v0, rtol=1e-8)
    before = res.t < t_in - 1e-4
    assert np.allclose(res["body.v"][before], v0, rtol=1e-12)
    assert np.all(res["stop.q"][after] < 0)


STEP_PUSH = """
name: step_push
parameters: {m: 2.0, F: 3.0, t1: 0.0123}
elements:
  push: {type: force_source, value: "F*step(t - t1)"}
  body: {type: mass, m: m}
connections:
  - [push.p, body.a]
outputs: [body.v]
simulate: {t_end: 0.05, dt_out: 1.0e-3, solver: RK45, rtol: 1.0e-9, atol: 1.0e-12}
"""


def test_a_step_in_a_source_is_an_event_and_each_segment_is_smooth():
    """v = F/m·max(t − t1, 0): the step's time is found exactly, and with the switch held on its
    side in each segment both arcs are polynomials the method integrates without a rejection."""
    m, F, t1 = 2.0, 3.0, 0.0123
    res = run(STEP_PUSH)
    assert [round(t, 12) for t, _ in res.events] == [t1]
    assert np.allclose(res["body.v"], F / m * np.maximum(res.t - t1, 0.0), rtol=0, atol=1e-12)
    assert res.stats["segments"] == 2 and res.stats["rejected"] == 0


# -- events that cannot be missed (both backends) ------------------------------------------------------
def _backends():
    """numpy always; numba where it is installed."""
    try:
        import numba  # noqa: F401
        return ["numpy", "numba"]
    except ImportError:
        return ["numpy", pytest.param("numba", marks=pytest.mark.skip(reason="numba not installed"))]


BACKENDS = _backends()

SQUARE_WAVE = """
name: square_wave_torque
parameters: {J: 1.0e-3, T: 1.0, w: 100000.0}
elements:
  drive: {type: torque_source, value: "T*sign(sin(w*t))"}
  body:  {type: inertia, J: J}
connections:
  - [drive.p, body.a]
outputs: [body.omega]
simulate: {t_end: 0.02, dt_out: 1.0e-6, rtol: 1.0e-9, atol: 1.0e-12}
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_square_wave_torque_switches_at_every_sign_change(backend):
    """T·sign(sin(w t)) on a free inertia: the speed is a triangle wave of amplitude T/J·pi/w,
    omega(t) = T/J·(phase folded into [0, pi])/w, phase = w t mod 2 pi, and the torque switches
    at every zero of sin(w t) in (0, t_end): k pi/w for k = 1 .. floor(w t_end/pi).  Once 2 events
    and an amplitude 440 times too large: the steps jumped over the sign changes."""
    J, T, w, t_end = 1.0e-3, 1.0, 1.0e5, 0.02
    res = run(SQUARE_WAVE, backend=backend)
    assert res.stats["backend"] == backend       # no silent fallback
    n_changes = int(np.floor(w * t_end / np.pi))
    times = np.array([t for t, _ in res.events])
    assert len(times) == n_changes == 636
    assert np.allclose(times, np.arange(1, n_changes + 1) * np.pi / w, rtol=0, atol=1e-12)
    phase = np.mod(w * res.t, 2 * np.pi)
    triangle = T / J * np.where(phase < np.pi, phase, 2 * np.pi - phase) / w
    # each segment is a straight line the method integrates exactly: only round-off remains
    assert np.max(np.abs(res["body.omega"] - triangle)) < 1e-9 * T / J * np.pi / w
    assert res.stats["events"] == n_changes and res.stats["segments"] == n_changes + 1
    # straight lines need no rejected step; the count once took each segment's start for 1/6 of one
    assert res.stats["rejected"] <= 0.01 * res.stats["steps"]


PULSE = """
name: short_pulse
parameters: {m: 2.0, F: 3.0, t1: 0.4, width: 1.0e-6}
elements:
  push: {type: force_source, value: "F*pulse(t, t1, width)"}
  body: {type: mass, m: m}
connections:
  - [push.p, body.a]
outputs: [body.v]
simulate: {t_end: 1.0, dt_out: 0.1, rtol: 1.0e-9, atol: 1.0e-12}
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pulse_much_shorter_than_any_step_is_not_missed(backend):
    """F·pulse(t, t1, width) on a free mass: the impulse F·width gives v = F·width/m after t1 + width,
    and both edges are events, although the pulse is 1e-6 of the run."""
    m, F, t1, width = 2.0, 3.0, 0.4, 1.0e-6
    res = run(PULSE, backend=backend)
    assert res.stats["backend"] == backend       # no silent fallback
    assert np.allclose([t for t, _ in res.events], [t1, t1 + width], rtol=0, atol=1e-13)
    assert np.allclose(res["body.v"], np.where(res.t > t1, F * width / m, 0.0), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("backend", BACKENDS)
def test_more_scheduled_crossings_than_the_event_limit_end_as_chattering(backend):
    """0.2 s of the square wave has floor(1e5*0.2/pi) = 6366 sign changes, more than MAX_EVENTS."""
    from multipole.simulate import MAX_EVENTS, SimulationError
    assert np.floor(1e5 * 0.2 / np.pi) > MAX_EVENTS
    with pytest.raises(SimulationError) as err:
        run(SQUARE_WAVE.replace("t_end: 0.02, dt_out: 1.0e-6", "t_end: 0.2, dt_out: 1.0e-4"), backend=backend)
    assert err.value.code == "chattering"


def test_a_time_switch_too_fast_to_resolve_is_refused():
    from multipole.simulate import SimulationError
    with pytest.raises(SimulationError) as err:
        run(SQUARE_WAVE.replace("w: 100000.0", "w: 1.0e9").replace("t_end: 0.02", "t_end: 1.0"))
    assert err.value.code == "switching_too_fast"


GRAZE = """
name: graze
parameters: {m: 1.0, F: 1.0, v0: 1.0, d: 0.4999, k: 10.0}
elements:
  push:   {type: force_source, value: "-F"}
  body:   {type: mass, m: m, v0: v0}
  stop_j: {type: junction_a, ports: [a, b, c], signs: [1, -1, -1], domain: translational}
  stop:   {type: C, law: "k*max(q, 0)", q0: "-d", domain: translational}
  wall:   {type: ground, domain: translational}
connections:
  - [push.p, body.a]
  - [body.b, stop_j.a]
  - [stop_j.b, wall.p]
  - [stop_j.c, stop.p]
outputs: [body.v, stop.q]
simulate: {t_end: 2.0, dt_out: 0.01, solver: RK45, rtol: 1.0e-10, atol: 1.0e-12, max_step: 0.1}
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_contact_entered_and_left_inside_one_step_is_found(backend):
    """A mass thrown (v0) against a constant force F just reaches a soft stop at d: free flight is a
    parabola the method integrates exactly in steps of max_step = 0.1 s, and the 0.028 s contact
    lies inside one such step (the switching function is negative at both ends of the step).

    Closed form: contact at t_in = (v0 - v_in)·m/F, v_in = sqrt(v0² - 2Fd/m); in contact the mass
    oscillates about d - F/k at w = sqrt(k/m) and leaves after 2·atan2(v_in/w, F/k)/w with -v_in."""
    m, F, v0, d, k = 1.0, 1.0, 1.0, 0.4999, 10.0
    res = run(GRAZE, backend=backend)
    assert res.stats["backend"] == backend       # no silent fallback
    v_in = np.sqrt(v0 ** 2 - 2 * F * d / m)
    t_in = (v0 - v_in) * m / F
    w = np.sqrt(k / m)
    t_out = t_in + 2 * np.arctan2(v_in / w, F / k) / w
    times = [t for t, _ in res.events]
    assert len(times) == 2
    assert abs(times[0] - t_in) < 1e-9 and abs(times[1] - t_out) < 1e-9
    after = res.t > t_out
    assert np.allclose(res["body.v"][after], -v_in - F / m * (res.t[after] - t_out), rtol=0, atol=1e-9)


TWO_STOPS = """
name: two_stops
parameters: {m: 1.0, v0: 1.0, d1: 0.5, d2: 0.5001, k1: 1.0e4, k2: 1.0e4}
elements:
  body:   {type: mass, m: m, v0: v0}
  stop_j: {type: junction_a, ports: [a, b, c], signs: [1, -1, -1], domain: translational}
  stops:  {type: C, law: "k1*max(q, 0) + k2*max(q - (d2 - d1), 0)", q0: "-d1", domain: translational}
  wall:   {type: ground, domain: translational}
connections:
  - [body.b, stop_j.a]
  - [stop_j.b, wall.p]
  - [stop_j.c, stops.p]
outputs: [body.v]
simulate: {t_end: 1.0, dt_out: 0.01, solver: RK45, rtol: 1.0e-10, atol: 1.0e-12}
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_two_contacts_inside_one_step_in_order(backend):
    """A mass in free flight (v0) meets two compression-only stops 1e-4 m apart (one law with two
    kinks, at q = 0 and q = d2 - d1, on the gap q measured from the first stop): both switching
    functions change sign inside the same (long) free-flight step, and the earlier crossing must
    be taken.  Closed form: stop 1 at t1 = d1/v0; on stop 1 alone (w1 = sqrt(k1/m)) the mass reaches
    d2 at t2 = t1 + asin(w1 (d2 - d1)/v0)/w1 with v2 = v0 cos(w1 (t2 - t1)); on both (w = sqrt((k1+k2)/m),
    centre xe = (k1 d1 + k2 d2)/(k1 + k2)) it is back at d2 after 2·atan2(v2/w, d2 - xe)/w, and by
    symmetry leaves stop 1 t2 - t1 later, with -v0."""
    m, v0, d1, d2, k1, k2 = 1.0, 1.0, 0.5, 0.5001, 1.0e4, 1.0e4
    res = run(TWO_STOPS, backend=backend)
    assert res.stats["backend"] == backend       # no silent fallback
    w1 = np.sqrt(k1 / m)
    t1 = d1 / v0
    t2 = t1 + np.arcsin(w1 * (d2 - d1) / v0) / w1
    v2 = v0 * np.cos(w1 * (t2 - t1))
    w = np.sqrt((k1 + k2) / m)
    xe = (k1 * d1 + k2 * d2) / (k1 + k2)
    t3 = t2 + 2 * np.arctan2(v2 / w, d2 - xe) / w
    t4 = t3 + (t2 - t1)
    order = [text for _, text in res.events]
    assert len(order) == 4 and order[0] == order[3] and order[1] == order[2] and order[0] != order[1]
    assert np.allclose([t for t, _ in res.events], [t1, t2, t3, t4], rtol=0, atol=1e-9)
    assert np.allclose(res["body.v"][res.t > t4], -v0, rtol=1e-8)


NOTCH = """
name: notch
parameters: {m: 2.0, F: 3.0, tc: 0.5, half: 1.0e-4}
elements:
  push: {type: force_source, value: "F*step(NOTCH)"}
  body: {type: mass, m: m}
connections:
  - [push.p, body.a]
outputs: [body.v]
simulate: {t_end: 10.0, dt_out: 0.05, rtol: 1.0e-9, atol: 1.0e-12}
"""


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("notch", ["(t - tc)**2 - half**2", "abs(t - tc) - half"])
def test_a_notch_much_narrower_than_the_samples_is_found(backend, notch):
    """The force is off for |t - tc| < half: two crossings 2e-4 s apart, 12 times closer than the
    samples of a general time function over 10 s.  As a polynomial in t the roots are exact; with
    abs the function is sampled, and at the kink t = tc too (the root of abs's argument), where the
    notch is.  v = F/m·(t - time off)."""
    m, F, tc, half = 2.0, 3.0, 0.5, 1.0e-4
    res = run(NOTCH.replace("NOTCH", notch), backend=backend)
    assert res.stats["backend"] == backend
    edges = [t for t, text in res.events if "half" in text]
    assert np.allclose(edges, [tc - half, tc + half], rtol=0, atol=1e-12)
    off = np.clip(res.t - (tc - half), 0.0, 2 * half)
    assert np.allclose(res["body.v"], F / m * (res.t - off), rtol=1e-9, atol=1e-15)


STOPS_IN_SERIES = """
name: stops_in_series
parameters: {m: 1.0, v0: 1.0, d1: 0.5, d2: 0.5001, k1: 1.0e4, k2: 1.0e4}
elements:
  body:   {type: mass, m: m, v0: v0}
  stop_j: {type: junction_a, ports: [a, b, c, d], signs: [1, -1, -1, -1], domain: translational}
  stop1:  {type: C, law: "k1*max(q, 0)", q0: "-d1", domain: translational}
  stop2:  {type: C, law: "k2*max(q - (d2 - d1), 0)", q0: 0, domain: translational}
  wall:   {type: ground, domain: translational}
connections:
  - [body.b, stop_j.a]
  - [stop_j.b, wall.p]
  - [stop_j.c, stop1.p]
  - [stop_j.d, stop2.p]
outputs: [body.v]
simulate: {t_end: 1.0, dt_out: 0.01, solver: RK45, rtol: 1.0e-10, atol: 1.0e-12}
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_two_compression_only_stops_in_series_are_refused_in_one_line(backend):
    """Two compression-only springs on one common-force junction carry one force, so stop2.q is in
    derivative causality and its constrained-state loop holds k1·step(stop1.q) + k2·step(...): while
    both are free (the start) the split of the motion between them is undetermined and the effective
    compliance divides by zero.  Was an event at 0.414 s (numpy) and a ZeroDivisionError printed from
    compiled code (numba); now the assembly refuses it, naming the switch side."""
    from multipole.errors import MultipoleError
    with pytest.raises(MultipoleError) as err:
        run(STOPS_IN_SERIES, backend=backend)
    assert err.value.code == "singular_loop"
    text = str(err.value)
    assert "\n" not in text.split("(fix:")[0]
    assert "stop1.q < 0" in text and "stop1" in text and "stop2" in text


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_stop_in_series_with_a_linear_spring_gives_the_series_stiffness(backend):
    """The same pair with stop2 linear (k2·q) is determined on both sides: free flight until the gap
    d1 closes at t1 = d1/v0 (stop2 carries no force, so it stays undeflected), then half a period
    pi·sqrt(m/k) of the series stiffness k = k1·k2/(k1 + k2), and the mass leaves with -v0."""
    m, v0, d1, k1, k2 = 1.0, 1.0, 0.5, 1.0e4, 1.0e4
    res = run(STOPS_IN_SERIES.replace("k2*max(q - (d2 - d1), 0)", "k2*q"), backend=backend)
    assert res.stats["backend"] == backend
    k = k1 * k2 / (k1 + k2)
    t1 = d1 / v0
    t2 = t1 + np.pi * np.sqrt(m / k)
    assert np.allclose([t for t, _ in res.events], [t1, t2], rtol=0, atol=1e-9)
    assert np.allclose(res["body.v"][res.t > t2], -v0, rtol=1e-8)
    assert np.allclose(res["body.v"][res.t < t1], v0, rtol=1e-12)


QUADRATIC_DAMPER = """
name: quadratic_damper
parameters: {d: 2.0}
elements:
  drive: {type: torque_source, value: "t"}
  damp:  {type: damper, law: "d*f*abs(f)", domain: rotational}
  fix:   {type: ground, domain: rotational}
connections:
  - [drive.p, damp.a]
  - [damp.b, fix.p]
outputs: [damp.power]
simulate: {t_end: 1.0, dt_out: 0.1}
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_newton_accepts_a_zero_residual_where_the_jacobian_is_singular(backend):
    """A quadratic damper d·f·|f| driven by the torque t: at t = 0 the loop's root f = 0 has a zero
    residual and a zero Jacobian 2d|f| (was newton_failed with |F| = 0), and from that root the next
    solve starts on the singular point.  Closed form: f = sqrt(t/d), power t·f = t^1.5/sqrt(d)."""
    d = 2.0
    res = run(QUADRATIC_DAMPER, backend=backend)
    assert res.stats["backend"] == backend
    assert np.allclose(res["damp.power"], res.t ** 1.5 / np.sqrt(d), rtol=1e-10, atol=1e-14)


def test_damped_newton_returns_a_start_with_zero_residual_untouched():
    """At a root where the Jacobian vanishes (2d·z·|z| at z = 0) the start is the solution: no
    step is taken (a nudge off the singular point would move it)."""
    from multipole.codegen import _damped_newton
    def fun(z):
        return 2.0 * z * np.abs(z), np.array([[4.0 * abs(z[0])]])
    z, iterations = _damped_newton(fun, np.zeros(1), 1e-12, 10)
    assert z == 0.0 and iterations == 0
