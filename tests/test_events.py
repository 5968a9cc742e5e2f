"""Switching laws are events: the integrator stops at the crossing and restarts on the other side."""
import numpy as np

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
