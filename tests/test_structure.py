"""Structural diagnostics: each has a netlist that triggers it and one that does not."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from helpers import check, codes, run, scene
from multipole import pipeline

SPLIT = """
name: split
elements:
  motor:  {type: torque_source, value: 5}
  input:  {type: inertia, J: 1.0e-3}
  path_A: {type: ideal_gear, i: -3}
  path_B: {type: ideal_gear, i: {iB}}
  output: {type: inertia, J: 2.0e-2}
connections:
  - [motor.p, input.a]
  - [input.b, path_A.a, path_B.a]
  - [path_A.b, path_B.b, output.a]
outputs: [input.omega]
"""


def test_rigid_power_split_equal_ratios():
    an = check(SPLIT.replace("{iB}", "-3"))
    assert not an.ok
    [d] = [d for d in an.diagnostics if d.severity == "error"]
    assert d.code == "kinematic_overdetermination"
    assert "static under-determination" in d.message
    assert d.fix == "make one coupling in this loop elastic"
    assert {"path_A", "path_B", "input", "output"} <= set(d.path) and d.path[0] == d.path[-1]


def test_rigid_power_split_unequal_ratios_is_locked():
    an = check(SPLIT.replace("{iB}", "-2.5"))
    [d] = [d for d in an.diagnostics if d.severity == "error"]
    assert d.code == "locked_loop"
    assert {"path_A", "path_B"} <= set(d.path)


ELASTIC_SPLIT = """
name: elastic_split
parameters: {cA: 4000.0, cB: 1000.0}
elements:
  motor:   {type: torque_source, value: "2*(1 - cos(t))"}
  input:   {type: inertia, J: 1.0e-3}
  gear_A:  {type: ideal_gear, i: -3}
  gear_B:  {type: ideal_gear, i: -3}
  mesh_A:  {type: spring, c: cA}
  mesh_B:  {type: spring, c: cB}
  output:  {type: inertia, J: 2.0e-2}
  load:    {type: damper, d: 0.3}
  housing: {type: ground}
connections:
  - [motor.p, input.a]
  - [input.b, gear_A.a, gear_B.a]
  - [gear_A.b, mesh_A.a]
  - [gear_B.b, mesh_B.a]
  - [mesh_A.b, mesh_B.b, output.a]
  - [output.b, load.a]
  - [load.b, housing.p]
outputs: [mesh_A.force, mesh_B.force, output.omega]
simulate: {t_end: 1.0, dt_out: 0.001, rtol: 1.0e-10, atol: 1.0e-12}
"""


def test_elastic_power_split_follows_the_compliances():
    an = check(ELASTIC_SPLIT)
    assert an.ok
    res = run(ELASTIC_SPLIT)
    fa, fb = res["mesh_A.force"], res["mesh_B.force"]
    mask = np.abs(fb) > 1e-3 * np.abs(fb).max()
    assert np.allclose(fa[mask] / fb[mask], 4000.0 / 1000.0, rtol=1e-7)


def test_one_elastic_coupling_in_the_loop_is_enough():
    text = ELASTIC_SPLIT.replace("gear_B.b, mesh_B.a", "gear_B.b, mesh_B.a").replace(
        "mesh_A:  {type: spring, c: cA}", "mesh_A:  {type: ideal_gear, i: 1}")
    an = check(text)
    assert an.ok, an.report()


def test_two_speed_sources_on_one_rigid_node():
    text = """
    elements:
      s1: {type: speed_source, value: 1}
      s2: {type: speed_source, value: 2}
      body: {type: inertia, J: 1}
    connections:
      - [s1.p, s2.p, body.a]
    """
    an = check(text)
    [d] = [d for d in an.diagnostics if d.severity == "error"]
    assert d.code == "source_conflict"
    assert "s1" in d.message and "s2" in d.message and "angular velocity" in d.message
    assert pipeline_exit(text) == 1


@pytest.mark.parametrize("shaft", ["direct", "rigid"])
def test_two_torque_sources_on_a_massless_shaft(shaft):
    if shaft == "direct":
        body = "connections:\n  - [t1.p, t2.p]\n"
        extra = ""
    else:
        extra = "  shaft: {type: ideal_gear, i: 1}\n"
        body = "connections:\n  - [t1.p, shaft.a]\n  - [shaft.b, t2.p]\n"
    text = "elements:\n  t1: {type: torque_source, value: 1}\n  t2: {type: torque_source, value: -1}\n" + extra + body
    an = check(text)
    [d] = [d for d in an.diagnostics if d.severity == "error"]
    assert d.code == "source_conflict"
    assert "t1" in d.message and "t2" in d.message and "torque" in d.message
    assert "kinematic under-determination" in d.message


def test_a_single_speed_source_is_fine():
    an = check("elements:\n  s1: {type: speed_source, value: 1}\n  body: {type: inertia, J: 1}\n"
               "connections:\n  - [s1.p, body.a]\n")
    assert an.ok


DAMPERS = """
name: dampers_in_series
parameters: {m: 1.0, d1: 2.0, d2: 3.0, k3: {k3}}
elements:
  belt: {type: velocity_source, value: 1.0}
  d_1:  {type: damper, d: d1, domain: translational}
  d_2:  {type: damper, {law}, domain: translational}
  body: {type: mass, m: m}
connections:
  - [belt.p, d_1.a]
  - [d_1.b, d_2.a]
  - [d_2.b, body.a]
outputs: [body.v, d_1.force, d_2.force]
simulate: {t_end: 3.0, dt_out: 0.01, rtol: 1.0e-10, atol: 1.0e-12}
"""


def test_linear_algebraic_loop_is_solved_and_reported():
    text = DAMPERS.replace("{k3}", "0").replace("{law}", "d: d2")
    sc = scene(text)
    eq = pipeline.equations(sc)
    loops = [d for d in eq.diagnostics if d.code == "algebraic_loop"]
    assert loops and "linear" in loops[0].message and loops[0].severity == "info"
    res = run(text)
    d_eq = 2.0 * 3.0 / 5.0
    assert np.max(np.abs(res["body.v"] - (1 - np.exp(-d_eq * res.t)))) <= 1e-8


def test_nonlinear_algebraic_loop_converges():
    k3 = 5.0
    sc = scene(DAMPERS.replace("{k3}", str(k3)).replace("{law}", 'law: "d2*f + k3*f**3"'))
    eq = pipeline.equations(sc)
    assert any(d.code == "algebraic_loop" and "nonlinear" in d.message for d in eq.diagnostics)
    res = pipeline.run(sc, progress=False)
    assert res.stats["newton_solves"] > 0

    def force(v):                 # independent solution: series force from a scalar root
        return brentq(lambda F: (1.0 - v) - F / 2.0 - _inv(F, k3), -50, 50, xtol=1e-15)

    ref = solve_ivp(lambda t, y: [force(y[0]) / 1.0], (0, 3.0), [0.0], t_eval=res.t, rtol=1e-11, atol=1e-13)
    assert np.max(np.abs(res["body.v"] - ref.y[0])) <= 1e-7
    assert np.allclose(res["d_1.force"], res["d_2.force"], rtol=1e-9, atol=1e-10)


def _inv(F, k3):
    """Relative velocity of the nonlinear damper for force F: 3 f + k3 f^3 = F."""
    return brentq(lambda f: 3.0 * f + k3 * f**3 - F, -50, 50, xtol=1e-15)


def test_step_into_derivative_causal_storage_is_reported():
    text = "elements:\n  s: {type: speed_source, value: 'step(t - 0.1)'}\n  body: {type: inertia, J: 1}\n" \
           "connections:\n  - [s.p, body.a]\n"
    an = check(text)
    assert "input_differentiation" in [d.code for d in an.errors]
    smooth = text.replace("step(t - 0.1)", "1 - exp(-t)")
    assert check(smooth).ok


def test_unconnected_ports_are_listed():
    an = check("elements:\n  m: {type: torque_source, value: 1}\n  body: {type: inertia, J: 1}\n"
               "connections:\n  - [m.p, body.a]\n")
    d = [d for d in an.diagnostics if d.code == "unconnected_port"]
    assert [x.ports for x in d] == [["body.b"]]
    connected = check("elements:\n  m: {type: torque_source, value: 1}\n  body: {type: inertia, J: 1}\n"
                      "  free: {type: torque_source, value: 0}\n"
                      "connections:\n  - [m.p, body.a]\n  - [body.b, free.p]\n")
    assert "unconnected_port" not in [x.code for x in connected.diagnostics]


def test_circuit_without_ground_is_underdetermined():
    text = """
    elements:
      v: {type: voltage_source, value: 1}
      r: {type: resistor, R: 5}
    connections:
      - [v.p, r.a]
      - [r.b, v.n]
    """
    an = check(text)
    [d] = an.errors
    assert d.code == "underdetermined" and "ground" in d.fix


def pipeline_exit(text: str) -> int:
    return 0 if pipeline.check(scene(text)).ok else 1


PARALLEL_TRANSFORMERS = """
name: parallel_transformers
parameters: {n: 2.0}
elements:
  supply: {type: voltage_source, value: "10"}
  t1: {type: TF, ratio: n, domain_a: electrical, domain_b: electrical}
  t2: {type: TF, ratio: n, domain_a: electrical, domain_b: electrical}
  load: {type: resistor, R: 5}
  gnd: {type: ground, domain: electrical}
connections:
  - [supply.p, t1.a, t2.a]
  - [t1.b, t2.b, load.a]
  - [load.b, supply.n, gnd.p]
"""


CANCELLING_RESISTANCES = """
name: cancelling_resistances
elements:
  supply: {type: Se, value: "1", domain: electrical}
  loop: {type: junction_b, ports: [s, r1, r2], signs: [1, -1, -1], domain: electrical}
  r1: {type: R, r: 2.0, domain: electrical}
  r2: {type: R, r: -2.0, domain: electrical}
connections:
  - [supply.p, loop.s]
  - [loop.r1, r1.p]
  - [loop.r2, r2.p]
"""


def test_parallel_electrical_transformers_are_a_static_overdetermination():
    """Weber's dual of the rigid power split: two ideal transformers between the same two electrical
    nodes impose the secondary voltage twice; nothing decides how the current splits."""
    an = check(PARALLEL_TRANSFORMERS)
    [d] = [d for d in an.diagnostics if d.severity == "error"]
    assert d.code == "static_overdetermination"
    assert "kinematic under-determination" in d.message and "voltage" in d.message
    assert d.fix == "add a storage element (an inductor or a capacitor) in this loop"
    assert {"t1", "t2"} <= set(d.path) and d.path[0] == d.path[-1]
    # the same circuit with one transformer is well-posed
    one = PARALLEL_TRANSFORMERS.replace("  t2: {type: TF, ratio: n, domain_a: electrical, domain_b: electrical}\n", "")
    one = one.replace("t1.a, t2.a]", "t1.a]").replace("t1.b, t2.b, load.a]", "t1.b, load.a]")
    assert check(one).ok


def test_cancelling_resistances_make_a_singular_loop():
    """r1 + r2 = 0 in a zero-storage series loop: (r1 + r2)·i = U has no unique solution."""
    from multipole import IllPosedError
    with pytest.raises(IllPosedError) as exc:
        pipeline.equations(scene(CANCELLING_RESISTANCES))
    assert exc.value.code == "singular_loop" and "r1" in exc.value.fix and "r2" in exc.value.fix
    fine = CANCELLING_RESISTANCES.replace("r: -2.0", "r: 3.0")
    res = run(fine + "outputs: [r1.p.f]\nsimulate: {t_end: 0.1}\n")
    assert np.allclose(res["r1.p.f"], 1.0 / (2.0 + 3.0), rtol=1e-12)
