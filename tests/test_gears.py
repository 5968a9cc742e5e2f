"""Weber's spur gear stage (elements/gears.py) against theory (reference W6/W7/W10).

Conventions (docs/weber-gears.md): port efforts are torques acting ON the stage, flows angular
velocities, both shafts positive in the same sense; mesh force positive when shaft a drives b.
Expected values come from closed forms (ratios, natural frequencies, load sharing by branch
compliance), conservation laws and a hand-written scipy model — never from the code under test.
"""
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import RK45, solve_ivp

from helpers import check, codes, run, scene
from multipole import pipeline
from multipole.cli import main
from multipole.netlist import load

ROOT = Path(__file__).resolve().parents[1]
WEBER = ROOT / "diagrams" / "weber"
R1, R2 = 0.02, 0.06
ALPHA = np.radians(20.0)


def zero_crossing_frequency(t, x):
    """Angular frequency [rad/s] from the zero crossings of x(t) (linear interpolation)."""
    k = np.nonzero(np.sign(x[1:]) != np.sign(x[:-1]))[0]
    tz = t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    return np.pi * (len(tz) - 1) / (tz[-1] - tz[0])


def stage_scene(mesh, shaft_a="{type: torque_source, value: 5}", shaft_b="{type: speed_source, value: 0}",
                j1="1.0e-3", j2="2.0e-2", outputs="[pinion.omega, wheel.omega, mesh.force]", omega0=(0.0, 0.0)):
    """source -> pinion (J1) -> mesh -> wheel (J2) -> source, as inline YAML."""
    return f"""
    elements:
      src_a:  {shaft_a}
      pinion: {{type: inertia, J: {j1}, omega0: {omega0[0]}}}
      mesh:   {mesh}
      wheel:  {{type: inertia, J: {j2}, omega0: {omega0[1]}}}
      src_b:  {shaft_b}
    connections:
      - [src_a.p, pinion.a]
      - [pinion.b, mesh.a]
      - [mesh.b, wheel.a]
      - [wheel.b, src_b.p]
    outputs: {outputs}
    """


# -- ideal level (Weber (23)-(26)) ---------------------------------------------------------------

@pytest.mark.parametrize("internal, sign", [(False, -1.0), (True, 1.0)])
def test_rigid_stage_ratio_direction_and_power(internal, sign):
    """Speed into shaft a, load torque on shaft b: ω_a = i·ω_b, (−M_b) = i·M_a, Σ M·ω = 0."""
    w_a, m_b = 10.0, 3.0
    i = sign * R2 / R1                       # −r2/r1 external, +r2/r1 internal (ring gear)
    res = run(f"""
    elements:
      drive: {{type: speed_source, value: {w_a}}}
      mesh:  {{type: spur_stage, r1: {R1}, r2: {R2}, internal: {str(internal).lower()}}}
      brake: {{type: torque_source, value: {m_b}}}
    connections:
      - [drive.p, mesh.a]
      - [mesh.b, brake.p]
    outputs: [mesh.a.f, mesh.b.f, mesh.a.e, mesh.b.e, mesh.force]
    simulate: {{t_end: 0.1, dt_out: 0.1}}
    """)
    w_b, m_a = res["mesh.b.f"][-1], res["mesh.a.e"][-1]
    assert res["mesh.a.f"][-1] == pytest.approx(w_a, rel=1e-12)
    assert w_b == pytest.approx(w_a / i, rel=1e-12)
    assert np.sign(w_b) == (1.0 if internal else -1.0) * np.sign(w_a)      # external mesh reverses
    assert -res["mesh.b.e"][-1] == pytest.approx(i * m_a, rel=1e-12)
    assert m_a * w_a + res["mesh.b.e"][-1] * w_b == pytest.approx(0.0, abs=1e-12)
    assert res["mesh.force"][-1] == pytest.approx(m_a / R1, rel=1e-12)


def test_rigid_stage_between_inertias_gives_the_effective_inertia():
    """Torque on J1, rigid mesh, J2 free: ω1 = M·t/(J1 + J2·(r1/r2)²), ω2 = −(r1/r2)·ω1."""
    M, J1, J2 = 5.0, 1e-3, 2e-2
    res = run(stage_scene(f"{{type: spur_stage, r1: {R1}, r2: {R2}}}", shaft_b="{type: torque_source, value: 0}",
                          outputs="[pinion.omega, wheel.omega, mesh.a.e, mesh.a.f, mesh.b.e, mesh.b.f]")
              + "simulate: {t_end: 0.5, dt_out: 0.01, rtol: 1.0e-10, atol: 1.0e-12}\n")
    expected = M * res.t / (J1 + J2 * (R1 / R2) ** 2)
    assert np.allclose(res["pinion.omega"], expected, rtol=1e-9, atol=1e-9)
    assert np.allclose(res["wheel.omega"], -R1 / R2 * expected, rtol=1e-9, atol=1e-9)
    power = res["mesh.a.e"] * res["mesh.a.f"] + res["mesh.b.e"] * res["mesh.b.f"]
    assert np.max(np.abs(power)) <= 1e-9 * np.max(np.abs(res["mesh.a.e"] * res["mesh.a.f"]))


# -- elastic level (Weber (27)-(32)) -------------------------------------------------------------

def test_output_held_rings_at_r1_sqrt_c_over_J1_and_peaks_at_twice_the_static_force():
    sc = load(WEBER / "spur_elastic.yaml")
    res = pipeline.run(sc, solver="DOP853", progress=False)
    c, J1, M = 2e8, 1e-3, 5.0
    omega_n = R1 * np.sqrt(c / J1)
    F_static = M / R1
    F = res["mesh.force"]
    assert zero_crossing_frequency(res.t, F - F_static) == pytest.approx(omega_n, rel=1e-3)
    assert F.max() == pytest.approx(2 * F_static, rel=5e-3)
    # independent of the time response, the linearised model has the same mode
    m = pipeline.model(sc)
    lam = np.linalg.eigvals(m.jac(0.0, m.x0))
    assert np.max(np.abs(lam.imag)) == pytest.approx(omega_n, rel=1e-9)


def test_weber_32_torque_equation_with_wheel_inertias():
    """(30) back-calculated: (−M2) = −(r2/r1)·(M1 + d/dt(−J1·ω1)) + d/dt(−J2·ω2), M2 the torque on the
    wheel's outer end.  (The printed (32) has −(r2/r1)·J1·ω̇1; the sign of that term follows (30).)"""
    J1, J2 = 1e-3, 2e-2
    res = run(stage_scene(f"{{type: spur_stage, r1: {R1}, r2: {R2}, level: elastic, c: 2.0e8}}",
                          shaft_a="{type: torque_source, value: '5*(1 - cos(300*t))'}",
                          shaft_b="{type: speed_source, value: '-40*t'}",
                          outputs="[pinion.omega, wheel.omega, wheel.b.e, src_a.p.e]")
              + "simulate: {t_end: 0.002, dt_out: 2.0e-7, solver: DOP853, rtol: 1.0e-11, atol: 1.0e-13}\n")
    M1 = 5 * (1 - np.cos(300 * res.t))
    dw1 = np.gradient(res["pinion.omega"], res.t)
    dw2 = np.gradient(res["wheel.omega"], res.t)
    minus_M2 = -res["wheel.b.e"]
    weber_30 = -(R2 / R1) * (M1 - J1 * dw1) - J2 * dw2
    inner = slice(5, -5)
    scale = np.max(np.abs(minus_M2))
    assert np.max(np.abs(minus_M2 - weber_30)[inner]) <= 1e-4 * scale
    printed_32 = -(R2 / R1) * M1 - (R2 / R1) * J1 * dw1 - J2 * dw2
    assert np.max(np.abs(minus_M2 - printed_32)[inner]) > 0.1 * scale     # the printed sign does not fit


def test_free_free_mesh_frequency():
    """Both wheels free, started with inconsistent speeds: ω = sqrt(c·(r1²/J1 + r2²/J2))."""
    c, J1, J2 = 5e7, 1e-3, 2e-2
    omega_n = np.sqrt(c * (R1**2 / J1 + R2**2 / J2))
    res = run(stage_scene(f"{{type: spur_stage, r1: {R1}, r2: {R2}, level: elastic, c: {c}}}",
                          shaft_a="{type: torque_source, value: 0}", shaft_b="{type: torque_source, value: 0}",
                          omega0=(10.0, 0.0))
              + "simulate: {t_end: 0.01, dt_out: 1.0e-6, solver: DOP853, rtol: 1.0e-10, atol: 1.0e-12}\n")
    F = res["mesh.force"]
    assert zero_crossing_frequency(res.t, F) == pytest.approx(omega_n, rel=1e-3)   # F(0) = 0, no static part
    # momentum about the mesh is not conserved, but the rigid-body mode is: J1ω1·r2 ... via energy
    energy = 0.5 * J1 * res["pinion.omega"] ** 2 + 0.5 * J2 * res["wheel.omega"] ** 2 + 0.5 * F**2 / c
    assert np.max(np.abs(energy - 0.5 * J1 * 100.0)) <= 1e-7 * 0.5 * J1 * 100.0


def test_elastic_stage_converges_to_the_rigid_one():
    """W10: torque step on J1, J2 free.  Exact elastic solution:
    ω1 = M·t/J_eff + (M/(J1·ω_n))·κ·sin(ω_n·t), κ = (r1²/J1)/(r1²/J1 + r2²/J2), ω_n² = c·(r1²/J1 + r2²/J2);
    the deviation from the rigid stage (M·t/J_eff) therefore falls like c^(-1/2)."""
    M, J1, J2 = 5.0, 1e-3, 2e-2
    J_eff = J1 + J2 * (R1 / R2) ** 2
    k = R1**2 / J1 + R2**2 / J2
    errors = []
    for c in (1e6, 1e7, 1e8, 1e9):
        res = run(stage_scene(f"{{type: spur_stage, r1: {R1}, r2: {R2}, level: elastic, c: {c}}}",
                              shaft_b="{type: torque_source, value: 0}")
                  + "simulate: {t_end: 0.005, dt_out: 1.0e-5, solver: DOP853, rtol: 1.0e-10, atol: 1.0e-12}\n")
        rigid = M * res.t / J_eff
        w_n = np.sqrt(c * k)
        exact = rigid + M / (J1 * w_n) * (R1**2 / J1 / k) * np.sin(w_n * res.t)
        assert np.max(np.abs(res["pinion.omega"] - exact)) <= 1e-6 * rigid[-1]
        errors.append(np.max(np.abs(res["pinion.omega"] - rigid)) / rigid[-1])
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.allclose(ratios, np.sqrt(10.0), rtol=0.02), errors
    assert errors[-1] < 0.02


def test_time_varying_mesh_stiffness_gives_the_quasi_static_transmission_error():
    """Constant torque, slow constant speed: φ1 − φ1_rigid = M1/(r1²·c(q)) with c(q) = c0(1 + ε cos q)."""
    res = pipeline.run(load(WEBER / "spur_elastic_varying.yaml"), progress=False)
    c0, eps, M1, w1, z1 = 1e8, 0.2, 10.0, 1.0, 20
    x0 = M1 / (R1 * c0 * (1 + eps))
    phi1 = res["mesh.phase"] / z1                      # pinion angle from the stage's tap
    lag = phi1 - (w1 * res.t - x0 / R1)                # against the unloaded rigid kinematics
    expected = M1 / (R1**2 * c0 * (1 + eps * np.cos(res["mesh.phase"])))
    assert res["mesh.phase"][-1] >= 2 * np.pi * 3        # at least three tooth engagements
    assert np.max(np.abs(lag - expected)) <= 1e-3 * expected.max()
    assert np.allclose(res["mesh.stiffness"], c0 * (1 + eps * np.cos(res["mesh.phase"])), rtol=1e-12)


def test_time_varying_mesh_stiffness_equals_the_mesh_built_from_primitives():
    """A stiffness that varies with time, c(t) = c0·(1 + ε·cos(W·t)) (a parametric excitation, not a
    law of the mesh phase), runs and gives the motion of the same mesh written from primitives:
    wheel transducers 1/r1 and −1/r2, a type-a junction and a C with the law c(t)·q."""
    law = "c0*(1 + eps*cos(W*t))"
    head = f"""
    parameters: {{c0: 1.0e8, eps: 0.3, W: 900.0}}
    simulate: {{t_end: 0.03, dt_out: 1.0e-5, rtol: 1.0e-10, atol: 1.0e-12}}
    """
    drive = dict(shaft_a="{type: torque_source, value: '5*(1 - exp(-t/0.002))'}",
                 shaft_b="{type: torque_source, value: '-8*(1 - exp(-t/0.004))'}")
    stage = scene(head + stage_scene(f'{{type: spur_stage, r1: {R1}, r2: {R2}, level: elastic, c: "{law}"}}', **drive,
                                     outputs="[pinion.omega, wheel.omega, mesh.force, mesh.stiffness]"))
    parts = head + f"""
    elements:
      src_a:  {drive["shaft_a"]}
      pinion: {{type: inertia, J: 1.0e-3}}
      wheel1: {{type: TF, ratio: {1 / R1}, domain_b: translational}}
      contact: {{type: junction_a, ports: [u1, u2, k], signs: [1, -1, -1], domain: translational}}
      spring: {{type: C, law: "{law}*q", domain: translational}}
      wheel2: {{type: TF, ratio: {-1 / R2}, domain_b: translational}}
      wheel:  {{type: inertia, J: 2.0e-2}}
      src_b:  {drive["shaft_b"]}
    connections:
      - [src_a.p, pinion.a]
      - [pinion.b, wheel1.a]
      - [wheel1.b, contact.u1]
      - [contact.k, spring.p]
      - [contact.u2, wheel2.b]
      - [wheel2.a, wheel.a]
      - [wheel.b, src_b.p]
    outputs: [pinion.omega, wheel.omega, contact.u1.e]
    """
    ref = pipeline.run(scene(parts), progress=False)
    res = pipeline.run(stage, progress=False)
    for out, other in (("pinion.omega", "pinion.omega"), ("wheel.omega", "wheel.omega"), ("mesh.force", "contact.u1.e")):
        scale = np.abs(ref[other]).max()
        assert scale > 0 and np.max(np.abs(res[out] - ref[other])) <= 1e-6 * scale, out
    assert np.allclose(res["mesh.stiffness"], 1e8 * (1 + 0.3 * np.cos(900.0 * res.t)), rtol=1e-12)


def _wrapped_table(q, points, values):
    """The stiffness table evaluated independently: distance of q from the middle of the tooth
    engagement, |q mod 2π| in [0, π], then straight lines through the points (numpy)."""
    return np.interp(np.abs(np.arctan2(np.sin(q), np.cos(q))), points, values)


def test_mesh_stiffness_table_gives_the_quasi_static_transmission_error():
    """c(q) from a table (single/double tooth contact, linear between the points): on the plateaus
    the pinion lags the rigid kinematics by exactly M1/(r1²·c(q)) with c from the table.

    Each kink of the table excites the mesh mode (ω_n = r1·sqrt(c/J1) ≈ 6.3e3 rad/s); the scene's
    mesh damping (ζ ≈ 0.03, decay rate ≈ 200 1/s) lets it die out within 20 ms, i.e. 0.4 rad of mesh
    phase at 20 rad/s, so the plateau check starts 0.4 rad after a kink.  In between (during the
    ramps) the lag is bounded by the ramp's excitation, Δẋ/ω_n ≲ 1 % of the error."""
    res = pipeline.run(load(WEBER / "spur_elastic_table.yaml"), progress=False)
    c1, c2, M1, w1, z1 = 1e8, 1.6e8, 10.0, 1.0, 20
    points, values = [1.1, 1.4], [c1, c2]
    q = res["mesh.phase"]
    c = _wrapped_table(q, points, values)
    assert q[-1] >= 2 * np.pi * 3                                   # three tooth engagements
    assert np.allclose(res["mesh.stiffness"], c, rtol=1e-12)         # the table, exactly
    lag = q / z1 - (w1 * res.t - M1 / (R1 * c1) / R1)                # against the unloaded rigid kinematics
    expected = M1 / (R1**2 * c)
    qw = np.abs(np.arctan2(np.sin(q), np.cos(q)))
    settled = (qw < points[0] - 0.4) | (qw > points[1] + 0.4)
    for plateau, level in ((qw < points[0], c1), (qw > points[1], c2)):      # both contact zones reached
        assert np.count_nonzero(settled & plateau) > 100, level
    assert np.max(np.abs(lag - expected)[settled]) <= 2e-4 * expected.max()
    assert np.max(np.abs(lag - expected)) <= 1e-2 * expected.max()
    assert np.ptp(lag) == pytest.approx(M1 / R1**2 * (1 / c1 - 1 / c2), rel=0.02)   # the table's contrast


def test_gear_train_stages_have_their_own_mesh_phase():
    """gear_train z1: stage k's mesh phase is z1[k] times the angle of its own input shaft, so a
    stiffness law of q runs at each stage's tooth frequency (constant speed: q_k = z1[k]·ω_k·t)."""
    w_in = 3.0
    res = run(f"""
    elements:
      drive:   {{type: speed_source, value: {w_in}}}
      gearbox: {{type: gear_train, r1: [0.02, 0.025], r2: [0.05, 0.08], level: elastic, z1: [20, 25],
                 c: "1.0e8*(1 + 0.2*cos(q))", d: 2000}}
      out:     {{type: inertia, J: 1.0e-2, omega0: {w_in * 0.02 / 0.05 * 0.025 / 0.08}}}
    connections:
      - [drive.p, gearbox.a]
      - [gearbox.b, out.a]
    outputs: [gearbox.s1.phase, gearbox.s2.phase, gearbox.s1.stiffness]
    simulate: {{t_end: 0.5, dt_out: 0.01, rtol: 1.0e-9, atol: 1.0e-12}}
    """)
    w_mid = -w_in * 0.02 / 0.05                                       # countershaft, reversed
    assert np.allclose(res["gearbox.s1.phase"], 20 * w_in * res.t, rtol=1e-9, atol=1e-9)
    assert np.allclose(res["gearbox.s2.phase"], 25 * w_mid * res.t, rtol=1e-4, atol=1e-4)
    assert np.allclose(res["gearbox.s1.stiffness"], 1e8 * (1 + 0.2 * np.cos(20 * w_in * res.t)), rtol=1e-9)


def test_weber_27_with_varying_stiffness_and_constant_torque():
    """Four-pole (no inertias), M1 constant: ω1 = −(r2/r1)·ω2 + (1/r1²)·d/dt(M1/c(q)), and with
    d/dt(1/c) = −c'(q)·z1·ω1/c² this is ω1·(1 − M1·c0·ε·z1·sin q/(r1²·c²)) = −(r2/r1)·ω2."""
    res = pipeline.run(load(WEBER / "spur_elastic_fourpole_varying.yaml"), progress=False)
    M1, w2, c0, eps, z1 = 5.0, -10.0, 2e8, 0.2, 20
    q = res["mesh.phase"]
    c = c0 * (1 + eps * np.cos(q))
    expected = -(R2 / R1) * w2 / (1 - M1 * c0 * eps * z1 * np.sin(q) / (R1**2 * c**2))
    assert q[-1] > 2 * np.pi * 10
    assert np.allclose(res["mesh.a.f"], expected, rtol=1e-10)
    assert np.ptp(res["mesh.a.f"]) > 1e-4 * 30.0           # non-uniform transmission
    assert np.allclose(res["mesh.b.e"], R2 / R1 * M1, rtol=1e-12)   # (28) unchanged


# -- normal level (Weber (33)-(41)) --------------------------------------------------------------

@pytest.mark.parametrize("g", [0.0, 0.002, -0.003])
def test_sliding_velocity_is_zero_at_the_pitch_point_and_g_times_the_speed_sum(g):
    """Rigid kinematics (ω1 = −(r2/r1)·ω2): Δv_t = g·(|ω1| + |ω2|) (Weber (37), steady part)."""
    J1 = 1e-3
    for w2 in (-10.0, 4.0):
        sc = load(WEBER / "spur_normal_teaching.yaml", {"g": str(g), "w2": str(w2)})
        m = pipeline.model(sc, ["mesh.sliding_velocity"])
        w1 = -R2 / R1 * w2
        x = np.zeros(len(m.state_names))
        x[m.state_names.index("pinion.p")] = J1 * w1
        x[m.state_names.index("mesh.q")] = 1e-6
        v_t = m.outputs(0.3, x)[0]
        assert abs(v_t) == pytest.approx(abs(g) * (abs(w1) + abs(w2)), rel=1e-12, abs=1e-15)


def test_sliding_velocity_along_the_involute_contact_path():
    """Involute: Δv_t = ρ1·ω1 + ρ2·ω2 = s·(ω1 − ω2) + tan(α)·q' at every instant, s sweeping ±p_b/2."""
    res = pipeline.run(load(WEBER / "spur_normal.yaml"), progress=False, t_end=0.1,
                       outputs=["mesh.sliding_velocity", "mesh.contact_position", "pinion.omega", "wheel.omega",
                                "mesh.p.f"])
    s, w1, w2 = res["mesh.contact_position"], res["pinion.omega"], res["wheel.omega"]
    expected = s * (w1 - w2) + np.tan(ALPHA) * res["mesh.p.f"]
    assert np.max(np.abs(res["mesh.sliding_velocity"] - expected)) <= 1e-9 * np.max(np.abs(expected))
    half_base_pitch = np.pi * R1 * np.cos(ALPHA) / 20
    assert s.max() == pytest.approx(half_base_pitch, rel=0.05) and s.min() == pytest.approx(-half_base_pitch, rel=0.05)


def test_normal_level_power_balance_with_inertias():
    """M1·ω1 + M2·ω2 = friction loss + power into the normal spring/damper, at every instant."""
    res = pipeline.run(load(WEBER / "spur_normal.yaml"), progress=False,
                       outputs=["mesh.a.e", "mesh.a.f", "mesh.b.e", "mesh.b.f", "mesh.loss", "mesh.force",
                                "mesh.p.f"])
    p_in = res["mesh.a.e"] * res["mesh.a.f"] + res["mesh.b.e"] * res["mesh.b.f"]
    p_out = res["mesh.loss"] + res["mesh.force"] * res["mesh.p.f"]
    assert np.max(res["mesh.loss"]) > 0.1 and np.min(res["mesh.loss"]) >= 0.0
    assert np.max(np.abs(p_in - p_out)) <= 1e-9 * np.max(np.abs(res["mesh.a.e"] * res["mesh.a.f"]))


def test_normal_level_without_inertias_follows_weber_39():
    """J = 0 (torque into shaft 1, speed on shaft 2): (−M2) = −(r2/r1)·M1 − r2·[ρ1/r1 − ρ2/r2]·F_t^W
    with Weber's F_t^W = −F_t, and M1·ω1 + M2·ω2 = F_t·Δv_t + F_n·q'."""
    g, d_t = 0.0015, 80.0
    res = run(f"""
    parameters: {{g: {g}}}
    elements:
      drive: {{type: torque_source, value: "3*(1 - exp(-t/0.002))"}}
      mesh:  {{type: spur_stage, r1: {R1}, r2: {R2}, level: normal, c_n: 1.0e8, s: g, d_t: {d_t}}}
      held:  {{type: speed_source, value: "-5 - 20*t"}}
    connections:
      - [drive.p, mesh.a]
      - [mesh.b, held.p]
    outputs: [mesh.a.e, mesh.a.f, mesh.b.e, mesh.b.f, mesh.friction_force, mesh.sliding_velocity, mesh.force,
              mesh.p.f, mesh.loss]
    simulate: {{t_end: 0.02, dt_out: 1.0e-4, solver: Radau, rtol: 1.0e-10, atol: 1.0e-14}}
    """)
    rho1, rho2 = R1 * np.sin(ALPHA) + g, R2 * np.sin(ALPHA) - g
    F_t = res["mesh.friction_force"]
    m1, m2 = res["mesh.a.e"], res["mesh.b.e"]
    assert np.max(np.abs(-m2 - (-R2 / R1 * m1 + R2 * (rho1 / R1 - rho2 / R2) * F_t))) <= 1e-9 * np.max(np.abs(m2))
    power = m1 * res["mesh.a.f"] + m2 * res["mesh.b.f"]
    assert np.allclose(power, F_t * res["mesh.sliding_velocity"] + res["mesh.force"] * res["mesh.p.f"],
                       rtol=1e-9, atol=1e-9 * np.max(np.abs(power)))
    assert np.all(res["mesh.loss"] >= 0)


def test_normal_level_output_held_rings_at_the_base_radius_frequency():
    """Frictionless normal level (mu = 0), shaft 2 held: ω_n = r1·cos(α)·sqrt(c_n/J1) (Weber (41-inv))."""
    c_n, J1 = 2e8, 1e-3
    res = run(stage_scene(f"{{type: spur_stage, r1: {R1}, r2: {R2}, level: normal, c_n: {c_n}, s: 0, mu: 0}}")
              + "simulate: {t_end: 0.01, dt_out: 1.0e-6, solver: DOP853, rtol: 1.0e-10, atol: 1.0e-12}\n")
    F = res["mesh.force"]
    F_static = 5.0 / (R1 * np.cos(ALPHA))
    assert zero_crossing_frequency(res.t, F - F_static) == pytest.approx(R1 * np.cos(ALPHA) * np.sqrt(c_n / J1),
                                                                        rel=1e-3)


def test_normal_split_without_tangential_resistance_is_not_well_posed(capsys):
    """Weber Bild 25 top: with no R in the tangential branch nothing determines the tangential force,
    so the flank force sums lack an input.  The check says so in Weber's terms and names the fix."""
    path = WEBER / "spur_normal_no_friction.yaml"
    assert main(["check", str(path)]) == 1
    report = capsys.readouterr().out
    assert "error[missing_cross_coupling] mesh: the tangential branch" in report
    assert "lacks a cross-coupling" in report and "Bild 25" in report
    assert "fix: give mesh a tooth-friction law: mu (with v_reg) or d_t" in report
    assert "add a storage element" not in report            # not the generic under-determination
    an = pipeline.check(load(path))
    assert [d.code for d in an.errors] == ["missing_cross_coupling"]
    err = an.errors[0]
    assert err.elements == ["mesh"] and err.ports == []          # the friction branch is inside mesh
    assert "force sums at flank1 and flank2 inside mesh" in err.message   # the two sums short of an input
    # the same split with a (zero) tangential resistance is well-posed: it is the missing R, not friction
    for law in ({"mesh.mu": "0"}, {"mesh.d_t": "0"}):
        ok = pipeline.check(load(path, law))
        assert ok.ok, ok.report()


def test_placeholder_words_come_from_the_primitive_not_from_the_kernel():
    """The kernel's placeholder protocol is generic: any primitive with ``needs``/``fix`` that an
    under-determined part reaches is reported in its own words; other gaps keep the generic report."""
    from multipole import Network, Primitive, R, Sf, analyse, flatten, junction_b

    class Gap(Primitive):
        kind = "gap"
        needs = "the second branch lacks a cross-coupling"
        fix = "give {element} a damper (owner {owner})"

        def __init__(self):
            super().__init__({"p": "translational"})

        def relations(self, V):
            return []

    # a velocity source drives a rigid body (type-b junction) with a damper on one branch and the
    # placeholder on the other: the force sum of the junction lacks one input
    inner = Network("box", {"j": junction_b(["a", "b", "c"], "translational"), "gap": Gap(),
                            "damper": R(r=2.0, dom="translational")},
                    [["j.b", "gap.p"], ["j.c", "damper.p"]], {"a": "j.a"})
    net = Network("scene", {"drive": Sf(1.0, "translational"), "box": inner}, [["drive.p", "box.a"]])
    an = analyse(flatten(net))
    assert [d.code for d in an.errors] == ["missing_cross_coupling"]
    err = an.errors[0]
    assert err.message.startswith("box: the second branch lacks a cross-coupling")
    assert "the force inside box" in err.message and "sums at j inside box" in err.message
    assert err.fix == "give box a damper (owner box)" and err.ports == []
    # without the words the same structure gets the generic report
    Gap.needs = ""
    an = analyse(flatten(net))
    assert [d.code for d in an.errors] == ["underdetermined"]


# -- internal mesh (ring gear) at the elastic and normal levels -----------------------------------

R_RING = 0.08                                   # ring gear radius [m], r2 > r1


def _internal_step_solution(t, M, J1, J2, c_u):
    """Torque step M on J1, ring J2 free, circumferential stiffness c_u, internal mesh (v_u2 = +r2·ω2).

    Deflection rate x' = r1·ω1 − r2·ω2, J1·ω1' = M − r1·c_u·x, J2·ω2' = +r2·c_u·x, so
    x'' + ω_n²·x = r1·M/J1 with ω_n² = c_u·(r1²/J1 + r2²/J2):  x = (r1·M/(J1·ω_n²))·(1 − cos ω_n t)
    and ω2 = (r2·c_u/J2)·∫x dt = (r2·c_u/J2)·(r1·M/(J1·ω_n²))·(t − sin(ω_n t)/ω_n) >= 0 (same sense)."""
    w_n = np.sqrt(c_u * (R1**2 / J1 + R_RING**2 / J2))
    x_static = R1 * M / (J1 * w_n**2)
    F_u = c_u * x_static * (1 - np.cos(w_n * t))
    w2 = R_RING * c_u / J2 * x_static * (t - np.sin(w_n * t) / w_n)
    return w_n, F_u, w2


def test_internal_elastic_mesh_keeps_the_direction_and_rings_at_the_free_free_frequency():
    M, J1, J2, c = 5.0, 1e-3, 4e-2, 5e7
    res = run(stage_scene(f"{{type: spur_stage, r1: {R1}, r2: {R_RING}, internal: true, level: elastic, c: {c}}}",
                          shaft_b="{type: torque_source, value: 0}", j2=str(J2))
              + "simulate: {t_end: 0.01, dt_out: 2.0e-6, solver: DOP853, rtol: 1.0e-11, atol: 1.0e-13}\n")
    w_n, F_u, w2 = _internal_step_solution(res.t, M, J1, J2, c)
    assert np.max(np.abs(res["mesh.force"] - F_u)) <= 1e-6 * F_u.max()
    assert np.max(np.abs(res["wheel.omega"] - w2)) <= 1e-6 * w2.max()
    assert zero_crossing_frequency(res.t, res["mesh.force"] - F_u.mean()) == pytest.approx(w_n, rel=1e-3)
    # both shafts turn in the direction of the torque; on average ω2 = (r1/r2)·ω1 (i = +r2/r1)
    assert res["pinion.omega"][-1] > 0 and np.all(res["wheel.omega"] >= -1e-12)
    J_eff = J1 + J2 * (R1 / R_RING) ** 2
    assert np.mean(res["wheel.omega"][-500:]) == pytest.approx(R1 / R_RING * M * np.mean(res.t[-500:]) / J_eff,
                                                               rel=2e-3)


def test_internal_normal_mesh_keeps_the_direction_and_rings_at_the_base_radius_frequency():
    """Frictionless normal level, contact at the pitch point: the circumferential stiffness is
    c_n·cos²α, the normal force F_u/cos α; ring free as above, ring held: ω_n = r1·cos α·sqrt(c_n/J1)."""
    M, J1, J2, c_n = 5.0, 1e-3, 4e-2, 5e7
    mesh = f"{{type: spur_stage, r1: {R1}, r2: {R_RING}, internal: true, level: normal, c_n: {c_n}, s: 0, mu: 0}}"
    opts = "simulate: {t_end: 0.01, dt_out: 2.0e-6, solver: DOP853, rtol: 1.0e-11, atol: 1.0e-13}\n"
    res = run(stage_scene(mesh, shaft_b="{type: torque_source, value: 0}", j2=str(J2)) + opts)
    w_n, F_u, w2 = _internal_step_solution(res.t, M, J1, J2, c_n * np.cos(ALPHA) ** 2)
    assert np.max(np.abs(res["mesh.force"] - F_u / np.cos(ALPHA))) <= 1e-6 * F_u.max() / np.cos(ALPHA)
    assert np.max(np.abs(res["wheel.omega"] - w2)) <= 1e-6 * w2.max()
    assert np.all(res["wheel.omega"] >= -1e-12) and res["pinion.omega"][-1] > 0
    held = run(stage_scene(mesh, j2=str(J2)) + opts)
    F_static = M / (R1 * np.cos(ALPHA))
    assert zero_crossing_frequency(held.t, held["mesh.force"] - F_static) == pytest.approx(
        R1 * np.cos(ALPHA) * np.sqrt(c_n / J1), rel=1e-3)
    assert held["mesh.force"].max() == pytest.approx(2 * F_static, rel=5e-3)


@pytest.mark.parametrize("g", [0.0, 0.002, -0.003])
def test_internal_mesh_slides_with_the_difference_of_the_speeds(g):
    """Internal mesh, rigid kinematics (r1·ω1 = r2·ω2): ρ1 = r1·sin α + g, ρ2 = r2·sin α + g, so
    Δv_t = (ρ1/r1)·r1·ω1 − (ρ2/r2)·r2·ω2 = g·(ω1 − ω2): the difference, not the sum, of the speeds."""
    J1, w2 = 1e-3, 4.0
    sc = scene(stage_scene(f"{{type: spur_stage, r1: {R1}, r2: {R_RING}, internal: true, level: normal, "
                           f"c_n: 2.0e8, s: {g}, d_t: 50}}", shaft_b=f"{{type: speed_source, value: {w2}}}",
                           outputs="[mesh.sliding_velocity]"))
    m = pipeline.model(sc)
    w1 = R_RING / R1 * w2
    x = np.zeros(len(m.state_names))
    x[m.state_names.index("pinion.p")] = J1 * w1
    v_t = m.outputs(0.0, x)[0]
    assert v_t == pytest.approx(g * (w1 - w2), rel=1e-12, abs=1e-15)


# -- power split (Weber §5.6, Bild 28/29) --------------------------------------------------------

def test_rigid_power_split_is_reported_with_both_paths():
    an = pipeline.check(load(WEBER / "power_split_rigid.yaml"))
    err = [d for d in an.errors if d.code == "kinematic_overdetermination"]
    assert len(err) == 1
    for name in ("mesh12A", "mesh34A", "mesh12B", "mesh34B"):
        assert name in err[0].elements and name in err[0].path
    assert "split" in err[0].message and "elastic" in err[0].fix


def _path_compliance(c12, c34, r2=0.05, r3=0.025):
    """Compliance of one branch referred to the first mesh: δ = 1/c12 + (r2/r3)²/c34 [m/N]."""
    return 1 / c12 + (r2 / r3) ** 2 / c34


@pytest.mark.parametrize("c12B", [2.0e8, 1.0e8, 5.0e7])
def test_elastic_power_split_shares_the_load_by_branch_compliance(c12B):
    sc = load(WEBER / "power_split_elastic.yaml", {"c12B": str(c12B)})
    res = pipeline.run(sc, t_end=0.3, progress=False)
    r1, M = 0.02, 20.0
    dA, dB = _path_compliance(2e8, 3e8), _path_compliance(c12B, 3e8)
    F_total = M / r1
    assert res["mesh12A.force"][-1] == pytest.approx(F_total * dB / (dA + dB), rel=1e-6)
    assert res["mesh12B.force"][-1] == pytest.approx(F_total * dA / (dA + dB), rel=1e-6)
    # each countershaft is in equilibrium: F34 = −(r2/r3)·F12
    assert res["mesh34A.force"][-1] == pytest.approx(-2.0 * res["mesh12A.force"][-1], rel=1e-6)


def test_mounting_error_gives_a_circulating_preload_and_shifts_the_split():
    """x0 in mesh 12B: preload F_A = −F_B = −x0/(δA + δB) at M = 0; under load F_A = F/2 − x0/(δA + δB)."""
    x0, r1 = 2e-5, 0.02
    d = _path_compliance(2e8, 3e8)
    preload = x0 / (2 * d)
    for M in (0.0, 20.0):
        res = pipeline.run(load(WEBER / "power_split_mounting_error.yaml", {"M": str(M)}), t_end=0.3,
                           progress=False)
        assert res["mesh12A.force"][-1] == pytest.approx(M / r1 / 2 - preload, rel=1e-6, abs=1e-6)
        assert res["mesh12B.force"][-1] == pytest.approx(M / r1 / 2 + preload, rel=1e-6, abs=1e-6)


# -- gear trains ---------------------------------------------------------------------------------

def test_two_stage_gear_ratio_and_torques():
    """Bild 27: i = (−r2/r1)·(−r4/r3); with the output at rest the stage forces are M/r1 and −(r2/r3)·M/r1."""
    sc = load(WEBER / "two_stage.yaml")
    res = pipeline.run(sc, progress=False)
    i = (-0.05 / 0.02) * (-0.08 / 0.025)
    assert np.allclose(res["input.omega"][1:], i * res["output.omega"][1:], rtol=1e-9)
    assert res["gearbox.ratio"][0] == pytest.approx(i)
    # the countershaft and the output are in derivative causality; the one state obeys
    # J_eff·ω_in' = M(t) − d·ω_in/i², J_eff = J_in + J_shaft·(r1/r2)² + J_out/i²
    J_in, J_shaft, J_out, d = 2e-4, 5e-4, 2e-2, 0.1
    J_eff = J_in + J_shaft * (0.02 / 0.05) ** 2 + J_out / i**2
    m = pipeline.model(sc)
    assert m.state_names == ["input.p"]
    for t, w in ((0.1, 5.0), (0.5, -10.0)):
        M = 1 - np.exp(-t / 0.05)
        assert m.rhs(t, np.array([J_in * w]))[0] == pytest.approx(J_in / J_eff * (M - d * w / i**2), rel=1e-12)
    res = run("""
    elements:
      motor:   {type: torque_source, value: 2}
      gearbox: {type: gear_train, r1: [0.02, 0.025], r2: [0.05, 0.08], level: elastic, c: 1.0e8, d: 5000}
      held:    {type: speed_source, value: 0}
      input:   {type: inertia, J: 2.0e-4}
    connections:
      - [motor.p, input.a]
      - [input.b, gearbox.a]
      - [gearbox.b, held.p]
    outputs: [gearbox.s1.force, gearbox.s2.force]
    simulate: {t_end: 0.05, dt_out: 1.0e-3, rtol: 1.0e-8, atol: 1.0e-12}
    """)
    assert res["gearbox.s1.force"][-1] == pytest.approx(2.0 / 0.02, rel=1e-6)
    assert res["gearbox.s2.force"][-1] == pytest.approx(-(0.05 / 0.025) * 2.0 / 0.02, rel=1e-6)


# -- hard case: stiff mesh, solver auto ----------------------------------------------------------

def _imaginary_axis_stability_limit(method):
    """Largest β with |R(iy)| <= 1 for all 0 <= y <= β, from the method's Butcher tableau."""
    b = method.B
    A = np.zeros((len(b), len(b)))
    A[:, :method.A.shape[1]] = method.A          # scipy stores the strictly lower part only
    one = np.ones(len(b))
    for y in np.arange(0.001, 10.0, 0.001):
        z = 1j * y
        R = 1 + z * b @ np.linalg.solve(np.eye(len(b)) - z * A, one)
        if abs(R) > 1 + 1e-12:
            return y - 0.001
    return 10.0


def test_stiff_mesh_runs_with_solver_auto_within_its_work_budget():
    """c = 2e8 N/m, J1 = 1e-3 kg·m², slow load.  Budget: 3000 rhs evaluations for 5 s.

    An explicit Runge–Kutta method must keep h·|λ|max inside its stability region; along the
    imaginary axis (the lightly damped mesh mode, λ ≈ −6 ± 10770i 1/s) that is h <= β/|λ|max with
    β ≈ 1.0 for RK45's Dormand–Prince weights (computed below from the tableau), i.e. at least
    t_end·|λ|max/β ≈ 5.4e4 steps of 6 evaluations: about 3.2e5 evaluations (a plain RK45 run of
    this scene takes 3.2e5).  Solver auto must stay more than 30 times below that explicit bound —
    and still be right.
    """
    sc = load(WEBER / "stiff_mesh_auto.yaml")
    m = pipeline.model(sc)
    lam_max = np.max(np.abs(np.linalg.eigvals(m.jac(0.0, m.x0))))
    J1, J2, c = 1e-3, 2e-2, 2e8
    assert lam_max == pytest.approx(np.sqrt(c * (R1**2 / J1 + R2**2 / J2)), rel=1e-3)
    t_end = sc.simulate["t_end"]
    beta = _imaginary_axis_stability_limit(RK45)
    explicit_nfev = 6 * t_end * lam_max / beta
    res = pipeline.run(sc, progress=False)
    assert res.solver == "Radau"
    assert res.stats["nfev"] <= 3000 and res.stats["nfev"] * 30 <= explicit_nfev
    # against a hand-written rigid model (the mesh mode is never excited by the slow load):
    # J_eff·ω̇2 = −(r2/r1)·M(t) − d·ω2 with J_eff = J2 + J1·(r2/r1)²
    J_eff, d = J2 + J1 * (R2 / R1) ** 2, 0.2
    ref = solve_ivp(lambda t, w: [(-(R2 / R1) * 2 * (1 - np.exp(-t / 0.5)) - d * w[0]) / J_eff],
                    (0, t_end), [0.0], t_eval=res.t, rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(res["wheel.omega"] - ref.y[0])) <= 2e-3 * np.max(np.abs(ref.y[0]))


def test_coulomb_tooth_friction_does_not_chatter():
    """Regularised Coulomb friction reverses at the pitch point every tooth: sharper regularisation
    must not make the step size collapse (no switching events, step count independent of v_reg)."""
    base = (WEBER / "stiff_mesh_coulomb.yaml").read_text()
    steps = {}
    for v_reg in ("1.0e-4", "1.0e-6"):
        res = pipeline.run(scene(base.replace("v_reg: 1.0e-4", f"v_reg: {v_reg}")), progress=False)
        assert not res.events
        steps[v_reg] = res.stats["steps"]
        teeth = 20 * np.trapezoid(res["pinion.omega"], res.t) / (2 * np.pi)
        assert teeth > 50 and np.ptp(np.sign(res["mesh.sliding_velocity"])) == 2   # it did reverse
        assert res.stats["steps"] <= 40 * teeth
    assert steps["1.0e-6"] <= 1.2 * steps["1.0e-4"], steps


# -- netlist interface ---------------------------------------------------------------------------

def test_level_parameters_are_checked(capsys):
    assert "missing_parameter" in _netlist_error("{type: spur_stage, r1: 0.02, r2: 0.06, level: elastic}")
    assert "bad_parameter" in _netlist_error("{type: spur_stage, r1: 0.02, r2: 0.06, c: 1.0e8}")
    assert "bad_value" in _netlist_error("{type: spur_stage, r1: 0.02, r2: 0.01, internal: true}")
    assert "bad_value" in _netlist_error("{type: spur_stage, r1: 0.02, r2: 0.06, level: normal, c_n: 1e8, "
                                         "z1: 5, mu: 0.1}")


def _netlist_error(mesh):
    from multipole.errors import NetlistError
    with pytest.raises(NetlistError) as exc:
        scene(stage_scene(mesh))
    return exc.value.code


def test_catalogue_documents_every_parameter_with_units(capsys):
    from multipole import catalogue
    for name in ("spur_stage", "gear_train", "planetary"):
        et = catalogue()[name]
        assert et.doc and et.quantities
        for p in et.params:
            assert p.doc, (name, p.name)
    assert main(["elements", "spur_stage"]) == 0
    text = capsys.readouterr().out
    assert "r1 [m]" in text and "c_n [N/m]" in text and "sliding_velocity" in text


# -- mechatronic scene ---------------------------------------------------------------------------

def test_dc_motor_through_an_elastic_stage_reaches_the_steady_state_of_the_hand_calculation():
    """U = R·i + k·ω_m, k·i = d_L·(r1/r2)²·ω_m  =>  ω_m = U/(k + R·d_L·(r1/r2)²/k); mesh force k·i/r1."""
    sc = load(WEBER / "dc_motor_gear_load.yaml")
    res = pipeline.run(sc, t_end=5.0, progress=False)
    U, k, R_a, d_L, r1, r2 = 24.0, 0.05, 1.2, 1e-3, 0.01, 0.04
    w_m = U / (k + R_a * d_L * (r1 / r2) ** 2 / k)
    i = (U - k * w_m) / R_a
    assert res["motor.omega"][-1] == pytest.approx(w_m, rel=1e-6)
    assert res["load.omega"][-1] == pytest.approx(-r1 / r2 * w_m, rel=1e-6)
    assert res["motor.current"][-1] == pytest.approx(i, rel=1e-5)
    assert res["mesh.force"][-1] == pytest.approx(k * i / r1, rel=1e-5)
