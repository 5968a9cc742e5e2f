"""Storage in derivative causality is resolved into effective inertia / compliance."""
import numpy as np
import pytest

from helpers import check, run, scene
from multipole import pipeline

GEARED = """
name: geared
parameters: {J1: 0.01, J2: 0.3, i: 4.0, T: 2.0, d: 0.05}
elements:
  drive: {type: torque_source, value: T}
  J_2:   {type: inertia, J: J2}
  gear:  {type: ideal_gear, i: i}
  J_1:   {type: inertia, J: J1}
  {extra}
connections:
  - [drive.p, J_2.a]
  - [J_2.b, gear.b]
  - [gear.a, J_1.a]
  {extra_conn}
outputs: [J_1.omega, J_2.omega]
simulate: {t_end: 2.0, dt_out: 0.01, rtol: 1.0e-10, atol: 1.0e-12}
"""


def _geared(damper: bool) -> str:
    extra = "brake: {type: damper, d: d}\n  housing: {type: ground}" if damper else ""
    conn = "- [J_1.b, brake.a]\n  - [brake.b, housing.p]" if damper else ""
    return GEARED.replace("{extra}", extra).replace("{extra_conn}", conn)


def test_rigid_gear_is_resolved_as_derivative_causality():
    an = check(_geared(False))
    assert an.ok
    dc = [d for d in an.diagnostics if d.code == "derivative_causality"]
    assert len(dc) == 1 and dc[0].severity == "info"
    assert "effective inertia" in dc[0].message
    assert len(an.states) == 1 and len(an.demoted) == 1


def test_effective_inertia_J2_plus_i2_J1():
    J1, J2, i, T = 0.01, 0.3, 4.0, 2.0
    res = run(_geared(False))
    J_eff = J2 + i**2 * J1          # referred to shaft 2 (f_a = i*f_b: shaft 1 turns i times faster)
    assert np.allclose(res["J_2.omega"], T * res.t / J_eff, rtol=1e-9, atol=1e-12)
    assert np.allclose(res["J_1.omega"], i * res["J_2.omega"], rtol=1e-12, atol=1e-12)


def test_damper_to_housing_on_the_same_node_keeps_working():
    J1, J2, i, T, d = 0.01, 0.3, 4.0, 2.0, 0.05
    res = run(_geared(True))
    J_eff = J2 + i**2 * J1
    d_eff = i**2 * d                 # damper on shaft 1, referred to shaft 2
    w2 = T / d_eff * (1 - np.exp(-d_eff * res.t / J_eff))
    assert np.max(np.abs(res["J_2.omega"] - w2)) / w2.max() <= 1e-8


SERIES_SPRINGS = """
name: springs_in_series
parameters: {m: 0.5, c1: 300.0, c2: 600.0, v0: 0.2}
elements:
  body: {type: mass, m: m, v0: v0}
  s1:   {type: spring, c: c1, domain: translational}
  s2:   {type: spring, c: c2, domain: translational}
  wall: {type: ground, domain: translational}
connections:
  - [body.b, s1.a]
  - [s1.b, s2.a]
  - [s2.b, wall.p]
outputs: [body.v, s1.force, s2.force]
simulate: {t_end: 1.0, dt_out: 0.001, rtol: 1.0e-10, atol: 1.0e-13}
"""


def test_springs_in_series_give_equivalent_compliance():
    m, c1, c2, v0 = 0.5, 300.0, 600.0, 0.2
    an = check(SERIES_SPRINGS)
    assert an.ok and [d.code for d in an.diagnostics].count("derivative_causality") == 1
    assert "effective compliance" in next(d.message for d in an.diagnostics if d.code == "derivative_causality")
    res = run(SERIES_SPRINGS)
    w = np.sqrt(c1 * c2 / (c1 + c2) / m)
    assert np.max(np.abs(res["body.v"] - v0 * np.cos(w * res.t))) / v0 <= 1e-7
    assert np.allclose(res["s1.force"], res["s2.force"], rtol=1e-9, atol=1e-12)   # massless middle node


PARALLEL_CAPS = """
name: parallel_capacitors
parameters: {R: 1000.0, C1: 1.0e-6, C2: 3.0e-6, v0: 5.0}
elements:
  Ca:  {type: capacitor, C: C1, v0: v0}
  Cb:  {type: capacitor, C: C2, v0: v0}
  Rl:  {type: resistor, R: R}
  gnd: {type: ground, domain: electrical}
connections:
  - [Ca.a, Cb.a, Rl.a]
  - [Ca.b, Cb.b, Rl.b, gnd.p]
outputs: [Ca.v, Cb.v, Ca.i, Cb.i]
simulate: {t_end: 0.01, dt_out: 1.0e-5, rtol: 1.0e-10, atol: 1.0e-14}
"""


def test_parallel_capacitors_add_up():
    R, C1, C2, v0 = 1000.0, 1e-6, 3e-6, 5.0
    an = check(PARALLEL_CAPS)
    assert an.ok and "derivative_causality" in [d.code for d in an.diagnostics]
    res = run(PARALLEL_CAPS)
    v = v0 * np.exp(-res.t / (R * (C1 + C2)))
    assert np.max(np.abs(res["Ca.v"] - v)) / v0 <= 1e-7
    assert np.allclose(res["Ca.v"], res["Cb.v"], rtol=1e-12, atol=1e-12)
    assert np.allclose(res["Cb.i"], C2 / C1 * res["Ca.i"], rtol=1e-8, atol=1e-12)


def test_inconsistent_initial_speeds_are_made_consistent_and_reported():
    """J_2 starts at 1.5 rad/s, J_1 (joined rigidly, ω1 = i·ω2) at rest: the analyser keeps the given
    value of the integrated inertia and computes the one in derivative causality from the gear
    constraint at t = 0, p1 = J1·i·ω2(0) (the given 0 is replaced), and says so (info); the run then
    starts there and follows ω2 = ω2(0) + T·t/J_eff."""
    J1, J2, i, T, w0 = 0.01, 0.3, 4.0, 2.0, 1.5
    text = _geared(False).replace("J_2:   {type: inertia, J: J2}", f"J_2:   {{type: inertia, J: J2, omega0: {w0}}}")
    eq = pipeline.equations(scene(text))
    made = [d for d in eq.diagnostics if "made consistent" in d.message]
    assert len(made) == 1 and made[0].severity == "info" and made[0].elements == ["J_1"]
    assert f"J_1.p = {J1 * i * w0:g} N*m*s (given 0)" in made[0].message
    res = run(text)
    assert np.allclose(res["J_2.omega"], w0 + T * res.t / (J2 + i**2 * J1), rtol=1e-9)
    assert np.allclose(res["J_1.omega"], i * res["J_2.omega"], rtol=1e-12)
    consistent = _geared(False)
    assert not [d for d in pipeline.equations(scene(consistent)).diagnostics if "made consistent" in d.message]


MASSLESS_PINION = """
name: massless_pinion
elements:
  motor:   {type: torque_source, value: "2*(1 - exp(-t/0.05))"}
  mesh:    {type: spur_stage, r1: 0.02, r2: 0.06, level: normal, c_n: 2.0e8, d: DAMPING, z1: 20, mu: 0.05,
            v_reg: 1.0e-4}
  wheel:   {type: inertia, J: 2.0e-2}
  load:    {type: damper, d: 0.2}
  housing: {type: ground}
connections:
  - [motor.p, mesh.a]
  - [mesh.b, wheel.a]
  - [wheel.b, load.a]
  - [load.b, housing.p]
outputs: [wheel.omega, mesh.force]
simulate: {t_end: 0.02, dt_out: 1.0e-4, rtol: 1.0e-6, atol: 1.0e-10}
"""


def test_massless_pinion_with_coulomb_teeth_is_refused_when_its_loop_has_no_solution():
    """A torque on a massless pinion meshing through Coulomb tooth friction and an undamped tooth
    spring: at t = 0 the normal force is 0, so nothing fixes the sliding velocity (the friction
    law's slope μ·|F_n|/v_reg is 0) and no sliding velocity gives a tangential force with
    |F_t| > μ·|F_n| afterwards.  Refused by check and simulate in one line naming the mesh (exit 1),
    instead of a Newton failure in the run; with mesh damping the loop is solvable and it runs."""
    from multipole.errors import IllPosedError
    with pytest.raises(IllPosedError) as exc:
        pipeline.equations(scene(MASSLESS_PINION.replace("DAMPING", "0.0")))
    assert exc.value.code == "singular_loop" and "through mesh " in exc.value.message
    res = run(MASSLESS_PINION.replace("DAMPING", "100.0"))
    assert res.t[-1] == pytest.approx(0.02) and np.all(np.isfinite(res["wheel.omega"]))
    assert res["wheel.omega"][-1] < 0 < res["mesh.force"][-1]       # the wheel turns the other way


def test_an_isolated_singular_root_of_a_loop_is_not_refused():
    """A quadratic damper e = d·f·|f| computes its flow by Newton's method; at t = 0 the torque is 0,
    so the root f = 0 has a singular Jacobian, but it is the only root (the loop is singular only
    there): the equations are built, no singular_loop."""
    text = """
    name: quadratic_damper
    elements:
      src: {type: torque_source, value: "t"}
      j:   {type: inertia, J: 0.01}
      spr: {type: spring, c: 100.0}
      dmp: {type: damper, law: "0.5*f*abs(f)"}
      gnd: {type: ground}
    connections:
      - [src.p, j.a]
      - [j.b, spr.a]
      - [spr.b, dmp.a]
      - [dmp.b, gnd.p]
    """
    eq = pipeline.equations(scene(text))
    assert any(b.kind == "newton" for b in eq.blocks)


def test_a_loop_numpy_cannot_evaluate_is_left_to_the_run():
    """Found by the fuzz test: a damper law ramp(sign(2f) − c) behind a DC motor makes a Newton loop
    whose Jacobian contains DiracDelta, which numpy cannot evaluate; the start-up look at the loops
    must not end in a traceback (the equations are built; the run reports what it finds)."""
    text = """
    name: fuzz_case
    elements:
      src:    {type: voltage_source, value: 2801.2}
      gnd:    {type: ground, domain: electrical}
      motor0: {type: dc_motor, k: 0.2315, R: 0.8312, L: 0.004016, J: 8.908e-05, grounded: false}
      load0:  {type: damper, law: "ramp(sign((f + f)) - 0.0097)"}
    connections:
      - [motor0.shaft, load0.a]
      - [src.p, motor0.elec]
      - [motor0.elec_n, src.n, gnd.p]
    """
    eq = pipeline.equations(scene(text))
    assert any(b.kind == "newton" for b in eq.blocks)
