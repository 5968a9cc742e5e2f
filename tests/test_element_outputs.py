"""Every documented element output against theory, at random states.

For each element type of the catalogue, a small scene is compiled with all of the element's
documented quantities (``multipole elements TYPE``) as outputs, the model is evaluated at random
states and times, and every output is compared with the value computed here from first principles:
the element's constitutive law and kinematics, written out in the test (closed forms, Weber's piezo
relations (50)-(55), the gear's mesh-force and power relations), with the states read by name.  The
right-hand side is checked the same way where an output alone could not catch a wrong sign (the
momentum balance of the bodies the element pushes).

Tolerances: these are evaluations of the same algebra in floating point, relative to the size of
the terms that make up each value.  Measured over all 635 comparisons below: at most 3.0e-15
(inverting the piezo's 2x2 compliance matrix would lose digits if ``k_P**2`` came close to
``delta_P*C_P``; the parameters keep it well conditioned).  RTOL is 1e-13, about 30 times that.

``test_every_documented_output_is_checked`` keeps this file complete: a new documented quantity
fails it until a theory check is added here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import scene
from multipole import catalogue, pipeline

RTOL = 1e-13          # measured max relative error 3.0e-15 (see the module docstring)
N_DRAWS = 5           # random states per scene


def model_for(text: str, outputs: list):
    return pipeline.model(scene(text), outputs, prune=False)    # every state: the tests read their derivatives


def draws(model, scales: dict, seed: int):
    """Random (t, states by name, outputs by name, derivatives by name) at ``N_DRAWS`` points."""
    rng = np.random.default_rng(seed)
    for _ in range(N_DRAWS):
        t = float(rng.uniform(0.1, 2.0))
        x = {n: float(rng.normal()) * scales[n] for n in model.state_names}
        vec = np.array([x[n] for n in model.state_names])
        out = dict(zip(model.output_names, np.asarray(model.outputs(t, vec), dtype=float)))
        der = dict(zip(model.state_names, np.asarray(model.rhs(t, vec), dtype=float)))
        yield t, x, out, der


def close(actual, expected, scale=None, what=""):
    """|actual - expected| <= RTOL * scale (scale: the size of the terms that make up the value)."""
    scale = abs(expected) if scale is None else scale
    assert abs(actual - expected) <= RTOL * max(scale, 1e-300), (what, actual, expected)


# -- 1-D mechanics: inertia, mass, spring, damper, sources ------------------------------------------

ROT_CHAIN = """
name: rot_chain
elements:
  motor:  {type: torque_source, value: "3*sin(2*t) + 1"}
  body1:  {type: inertia, J: 0.25}
  spring: {type: spring, c: 400.0}
  damper: {type: damper, d: 1.5}
  body2:  {type: inertia, J: 0.8}
  load:   {type: torque_source, value: "-0.5*t"}
connections:
  - [motor.p, body1.a]
  - [body1.b, spring.a, damper.a]
  - [spring.b, damper.b, body2.a]
  - [body2.b, load.p]
"""

TRANS_CHAIN = ROT_CHAIN.replace("torque_source", "force_source").replace("inertia, J", "mass, m") \
    .replace("c: 400.0}", "c: 400.0, domain: translational}").replace("d: 1.5}", "d: 1.5, domain: translational}")


@pytest.mark.parametrize("domain", ["rotational", "translational"])
def test_bodies_springs_dampers(domain):
    text, speed = (ROT_CHAIN, "omega") if domain == "rotational" else (TRANS_CHAIN, "v")
    J1, J2, c, d = 0.25, 0.8, 400.0, 1.5
    outs = [f"body1.{speed}", "body1.p", f"body2.{speed}", "body2.p", "spring.force", "spring.deflection",
            "damper.force", "damper.power"]
    m = model_for(text, outs)
    assert sorted(m.state_names) == ["body1.p", "body2.p", "spring.q"]
    for t, x, out, der in draws(m, {"body1.p": 2.0, "body2.p": 3.0, "spring.q": 0.01}, 1):
        w1, w2, q = x["body1.p"] / J1, x["body2.p"] / J2, x["spring.q"]
        close(out[f"body1.{speed}"], w1)
        close(out[f"body2.{speed}"], w2)
        close(out["body1.p"], x["body1.p"])
        close(out["body2.p"], x["body2.p"])
        close(out["spring.deflection"], q)
        close(out["spring.force"], c * q)                       # force = c * deflection
        close(out["damper.force"], d * (w1 - w2))               # force = d * (f_a - f_b)
        close(out["damper.power"], d * (w1 - w2) ** 2)          # dissipated power >= 0
        assert out["damper.power"] >= 0
        # momentum balance: the source accelerates body 1 positively, the coupling brakes it
        drive, load = 3 * math.sin(2 * t) + 1, -0.5 * t
        coupling = c * q + d * (w1 - w2)
        close(der["body1.p"], drive - coupling, abs(drive) + abs(coupling))
        close(der["body2.p"], load + coupling, abs(load) + abs(coupling))
        close(der["spring.q"], w1 - w2, abs(w1) + abs(w2))


# -- electrical two-pins and sources -------------------------------------------------------------

CIRCUIT = """
name: circuit
elements:
  supply: {type: voltage_source, value: "12*cos(3*t)"}
  R1:     {type: resistor, R: 4.0}
  L1:     {type: inductor, L: 0.05}
  C1:     {type: capacitor, C: 2.0e-3}
  gnd:    {type: ground, domain: electrical}
  cs:     {type: current_source, value: "0.7 + t"}
  R2:     {type: resistor, R: 30.0}
connections:
  - [supply.p, R1.a]
  - [R1.b, L1.a]
  - [L1.b, C1.a]
  - [C1.b, supply.n, gnd.p, cs.n, R2.b]
  - [cs.p, R2.a]
"""


def test_resistor_inductor_capacitor_and_sources():
    R, L, C, R2 = 4.0, 0.05, 2.0e-3, 30.0
    outs = ["R1.i", "R1.v", "L1.i", "L1.v", "C1.v", "C1.i", "supply.i", "supply.v", "cs.i", "cs.v", "R2.i", "R2.v"]
    m = model_for(CIRCUIT, outs)
    assert sorted(m.state_names) == ["C1.q", "L1.p"]
    for t, x, out, der in draws(m, {"L1.p": 0.1, "C1.q": 0.02}, 2):
        i, vc, V, Ics = x["L1.p"] / L, x["C1.q"] / C, 12 * math.cos(3 * t), 0.7 + t
        for name in ("R1.i", "L1.i", "C1.i", "supply.i"):      # one loop current, out of the source's p
            close(out[name], i, what=name)
        close(out["R1.v"], R * i)
        close(out["C1.v"], vc)
        close(out["supply.v"], V)
        close(out["L1.v"], V - R * i - vc, abs(V) + abs(R * i) + abs(vc))     # Kirchhoff's voltage law
        close(der["L1.p"], V - R * i - vc, abs(V) + abs(R * i) + abs(vc))
        close(der["C1.q"], i)
        # the current source drives its value out of p, through R2 from a to b, back into n
        close(out["cs.i"], Ics)
        close(out["R2.i"], Ics)
        close(out["R2.v"], R2 * Ics)
        close(out["cs.v"], R2 * Ics)


# -- DC motor --------------------------------------------------------------------------------------

MOTOR = """
name: motor
elements:
  supply: {type: voltage_source, value: "24*step(t) + 2*t"}
  offset: {type: voltage_source, value: "{offset}"}
  gnd:    {type: ground, domain: electrical}
  motor:  {type: dc_motor, k: 0.05, R: 1.2, L: 2.0e-3, J: 4.0e-5, d: 1.0e-4, grounded: {grounded}}
  load:   {type: torque_source, value: "-0.02*t"}
connections:
  - [supply.p, motor.elec]
  - [supply.n, gnd.p, offset.n]
  - [motor.shaft, load.p]
"""


@pytest.mark.parametrize("grounded", [True, False])
def test_dc_motor(grounded):
    k, R, L, J, d = 0.05, 1.2, 2.0e-3, 4.0e-5, 1.0e-4
    offset = 0.0 if grounded else 3.5
    text = MOTOR.replace("{grounded}", str(grounded).lower()).replace("{offset}", str(offset))
    if not grounded:
        text += "  - [offset.p, motor.elec_n]\n"
    m = model_for(text, ["motor.omega", "motor.current", "motor.torque", "motor.back_emf", "motor.voltage"])
    assert sorted(m.state_names) == ["motor.coil.p", "motor.inertia.p"]
    for t, x, out, der in draws(m, {"motor.coil.p": 0.01, "motor.inertia.p": 0.01}, 3):
        i, w = x["motor.coil.p"] / L, x["motor.inertia.p"] / J
        U = 24 + 2 * t - offset                      # e(elec) - e(elec_n)
        close(out["motor.current"], i)
        close(out["motor.omega"], w)
        close(out["motor.torque"], k * i)
        close(out["motor.back_emf"], k * w)
        close(out["motor.voltage"], U)
        # U = R*i + L*i' + k*omega and J*omega' = k*i - d*omega + M_shaft
        close(der["motor.coil.p"], U - R * i - k * w, abs(U) + abs(R * i) + abs(k * w))
        M = -0.02 * t
        close(der["motor.inertia.p"], k * i - d * w + M, abs(k * i) + abs(d * w) + abs(M))


# -- spur gear stage -------------------------------------------------------------------------------

GEAR = """
name: gear
elements:
  motor:  {type: torque_source, value: "2 + sin(t)"}
  pinion: {type: inertia, J: 1.0e-3}
  mesh:   {type: spur_stage, r1: 0.02, r2: 0.05, MESH}
  wheel:  {type: inertia, J: 2.0e-2}
  load:   {type: torque_source, value: "-3*t"}
connections:
  - [motor.p, pinion.a]
  - [pinion.b, mesh.a]
  - [mesh.b, wheel.a]
  - [wheel.b, load.p]
"""

R1, R2, J1, J2 = 0.02, 0.05, 1.0e-3, 2.0e-2


def gear(mesh: str) -> str:
    return GEAR.replace("MESH", mesh)


@pytest.mark.parametrize("internal", [False, True])
def test_spur_stage_elastic_mesh_force(internal):
    """Mesh force = c*deflection + d*(v_u1 - v_u2), v_u1 = r1*w1, v_u2 = -r2*w2 (external) or +r2*w2
    (internal); the massless wheel 1 passes it on as the circumferential force M1/r1; the pinion is
    braked by r1*F, the wheel driven by -/+ r2*F."""
    c, d = 2.0e5, 30.0
    sense = 1 if internal else -1
    m = model_for(gear(f"level: elastic, c: {c}, d: {d}, internal: {str(internal).lower()}"),
                  ["mesh.force", "mesh.force_u", "mesh.deflection", "mesh.stiffness"])
    assert sorted(m.state_names) == ["mesh.q", "pinion.p", "wheel.p"]
    for t, x, out, der in draws(m, {"pinion.p": 0.1, "wheel.p": 0.5, "mesh.q": 1e-4}, 4):
        w1, w2, q = x["pinion.p"] / J1, x["wheel.p"] / J2, x["mesh.q"]
        slip = R1 * w1 - sense * R2 * w2
        F = c * q + d * slip
        scale = abs(c * q) + abs(d * slip)
        close(out["mesh.deflection"], q)
        close(out["mesh.stiffness"], c)
        close(out["mesh.force"], F, scale)
        close(out["mesh.force_u"], F, scale)
        close(der["mesh.q"], slip, abs(R1 * w1) + abs(R2 * w2))
        M, ML = 2 + math.sin(t), -3 * t
        close(der["pinion.p"], M - R1 * F, abs(M) + R1 * scale)
        close(der["wheel.p"], ML + sense * R2 * F, abs(ML) + R2 * scale)


def test_spur_stage_elastic_phase_dependent_stiffness():
    """Mesh phase q = z1*phi1 (+ phase0), stiffness c0*(1 + eps*cos(q)), force = stiffness*deflection."""
    c0, eps, z1, phase0 = 2.0e5, 0.3, 17, 0.4
    m = model_for(gear(f'level: elastic, c: "{c0}*(1 + {eps}*cos(q))", z1: {z1}, phase0: {phase0}'),
                  ["mesh.force", "mesh.force_u", "mesh.deflection", "mesh.stiffness", "mesh.phase"])
    assert sorted(m.state_names) == ["mesh.angle1.q", "mesh.q", "pinion.p", "wheel.p"]
    assert m.x0[m.state_names.index("mesh.angle1.q")] == pytest.approx(phase0 / z1, rel=1e-15)
    for t, x, out, der in draws(m, {"pinion.p": 0.1, "wheel.p": 0.5, "mesh.q": 1e-4, "mesh.angle1.q": 3.0}, 5):
        phase = z1 * x["mesh.angle1.q"]
        stiffness = c0 * (1 + eps * math.cos(phase))
        close(out["mesh.phase"], phase)
        close(out["mesh.stiffness"], stiffness)
        close(out["mesh.force"], stiffness * x["mesh.q"])
        close(out["mesh.force_u"], stiffness * x["mesh.q"])
        close(der["mesh.angle1.q"], x["pinion.p"] / J1)       # the tap integrates the pinion's speed


def test_spur_stage_ideal_mesh_force_from_the_equations_of_motion():
    """Rigid mesh, w1 = -(r2/r1)*w2: J1*w1' = M - r1*F, J2*w2' = ML - r2*F, so
    w1' = (r2**2*M - r1*r2*ML)/(J1*r2**2 + J2*r1**2) and F = (M - J1*w1')/r1 (independent of the state)."""
    m = model_for(gear("level: ideal"), ["mesh.force", "mesh.force_u", "mesh.deflection"])
    assert m.state_names == ["pinion.p"]
    for t, x, out, der in draws(m, {"pinion.p": 0.1}, 6):
        M, ML = 2 + math.sin(t), -3 * t
        dw1 = (R2 ** 2 * M - R1 * R2 * ML) / (J1 * R2 ** 2 + J2 * R1 ** 2)
        F = (M - J1 * dw1) / R1
        scale = (abs(M) + abs(J1 * dw1)) / R1
        close(der["pinion.p"], J1 * dw1, abs(M) + abs(ML))
        close(out["mesh.force"], F, scale)
        close(out["mesh.force_u"], F, scale)
        assert out["mesh.deflection"] == 0.0


def test_spur_stage_normal_level():
    """Weber Bild 25: normal force F_n = c_n*q_n + d*(v_n1 - v_n2) with v_n = cos(alpha)*v_u; sliding
    velocity v_t = rho1*w1 + rho2*w2 (rho1 = r1*sin(alpha) + s, rho2 = r2*sin(alpha) - s, s the contact
    position (r1*cos(alpha)/z1)*wrap(q)), tooth friction F_t = mu*|c_n*q_n|*tanh(v_t/v_reg) + d_t*v_t;
    circumferential force at wheel 1 from the power balance of its flank:
    F_u*v_u1 = F_n*v_n1 + F_t*v_t1, i.e. F_u = cos(alpha)*F_n + (rho1/r1)*F_t."""
    c_n, d, z1, alpha, mu, v_reg, d_t = 3.0e5, 20.0, 19, 0.35, 0.08, 0.01, 4.0
    m = model_for(gear(f"level: normal, c_n: {c_n}, d: {d}, z1: {z1}, alpha: {alpha}, mu: {mu}, "
                       f"v_reg: {v_reg}, d_t: {d_t}"),
                  ["mesh.force", "mesh.force_u", "mesh.deflection", "mesh.stiffness", "mesh.phase",
                   "mesh.sliding_velocity", "mesh.friction_force", "mesh.loss", "mesh.contact_position"])
    assert sorted(m.state_names) == ["mesh.angle1.q", "mesh.q", "pinion.p", "wheel.p"]
    for t, x, out, der in draws(m, {"pinion.p": 0.05, "wheel.p": 0.5, "mesh.q": 1e-4, "mesh.angle1.q": 1.0}, 7):
        w1, w2, qn, phase = x["pinion.p"] / J1, x["wheel.p"] / J2, x["mesh.q"], z1 * x["mesh.angle1.q"]
        wrapped = math.atan2(math.sin(phase), math.cos(phase))
        s = R1 * math.cos(alpha) / z1 * wrapped
        rho1, rho2 = R1 * math.sin(alpha) + s, R2 * math.sin(alpha) - s
        vn = math.cos(alpha) * (R1 * w1 + R2 * w2)
        Fn = c_n * qn + d * vn
        vt = rho1 * w1 + rho2 * w2
        Ft = mu * abs(c_n * qn) * math.tanh(vt / v_reg) + d_t * vt
        close(out["mesh.phase"], phase)
        close(out["mesh.contact_position"], s, R1 / z1)
        close(out["mesh.stiffness"], c_n)
        close(out["mesh.deflection"], qn)
        close(der["mesh.q"], vn, R1 * abs(w1) + R2 * abs(w2))
        close(out["mesh.force"], Fn, abs(c_n * qn) + abs(d * vn))
        close(out["mesh.sliding_velocity"], vt, abs(rho1 * w1) + abs(rho2 * w2))
        close(out["mesh.friction_force"], Ft, abs(mu * c_n * qn) + abs(d_t * vt))
        close(out["mesh.loss"], Ft * vt, (abs(mu * c_n * qn) + abs(d_t * vt)) * abs(vt))
        assert out["mesh.loss"] >= 0
        Fu = math.cos(alpha) * Fn + rho1 / R1 * Ft
        Fu_scale = abs(c_n * qn) + abs(d * vn) + abs(mu * c_n * qn) + abs(d_t * vt)
        close(out["mesh.force_u"], Fu, Fu_scale)
        M = 2 + math.sin(t)
        close(der["pinion.p"], M - R1 * Fu, abs(M) + R1 * Fu_scale)


# -- gear train ------------------------------------------------------------------------------------

TRAIN = """
name: train
elements:
  motor:  {type: torque_source, value: "1 + t"}
  input:  {type: inertia, J: 1.0e-3}
  train:  {type: gear_train, TRAIN}
  output: {type: inertia, J: 5.0e-2}
connections:
  - [motor.p, input.a]
  - [input.b, train.a]
  - [train.b, output.a]
"""


@pytest.mark.parametrize("r1, r2, internal", [([0.02], [0.05], False), ([0.02, 0.03], [0.05, 0.04], False),
                                              ([0.02, 0.03, 0.01], [0.05, 0.04, 0.03], False),
                                              ([0.02], [0.05], True)])
def test_gear_train_ratio_is_the_speed_ratio(r1, r2, internal):
    """Rigid stages: ratio = omega_a/omega_b = product of the stage ratios -r2/r1 (internal +r2/r1),
    read here from the kinematics the kernel derived (the output inertia's speed)."""
    m = model_for(TRAIN.replace("TRAIN", f"r1: {r1}, r2: {r2}, internal: {str(internal).lower()}"),
                  ["train.ratio", "input.omega", "output.omega"])
    expected = math.prod((1 if internal else -1) * b / a for a, b in zip(r1, r2))
    for t, x, out, der in draws(m, {n: 0.1 for n in m.state_names}, 8):
        close(out["train.ratio"], expected)
        close(out["input.omega"] / out["output.omega"], expected)


def test_gear_train_elastic_stage_forces():
    """Two elastic stages with an intermediate shaft: stage k's force = c*q_k + d*(r1_k*w_in - (-r2_k)*w_out)."""
    c, d = 1.0e5, 5.0
    m = model_for(TRAIN.replace("TRAIN", f"r1: [0.02, 0.03], r2: [0.05, 0.04], level: elastic, c: {c}, d: {d}, "
                                         "J: [2.0e-3]"),
                  ["train.s1.force", "train.s1.deflection", "train.s1.stiffness",
                   "train.s2.force", "train.s2.deflection", "train.s2.stiffness"])
    assert sorted(m.state_names) == ["input.p", "output.p", "train.s1.q", "train.s2.q", "train.shaft1.p"]
    scales = {"input.p": 0.1, "output.p": 1.0, "train.s1.q": 1e-4, "train.s2.q": 1e-4, "train.shaft1.p": 0.1}
    for t, x, out, der in draws(m, scales, 9):
        w = [x["input.p"] / 1.0e-3, x["train.shaft1.p"] / 2.0e-3, x["output.p"] / 5.0e-2]
        for k, (a, b) in enumerate(((0.02, 0.05), (0.03, 0.04))):
            q = x[f"train.s{k + 1}.q"]
            slip = a * w[k] + b * w[k + 1]
            close(out[f"train.s{k + 1}.deflection"], q)
            close(out[f"train.s{k + 1}.stiffness"], c)
            close(out[f"train.s{k + 1}.force"], c * q + d * slip, abs(c * q) + abs(d * slip))


def test_gear_train_phase():
    """Stage k's mesh phase is z1[k] times the angle of its own input shaft."""
    m = model_for(TRAIN.replace("TRAIN", 'r1: [0.02, 0.03], r2: [0.05, 0.04], level: elastic, '
                                         'c: "1.0e5*(1 + 0.2*cos(q))", J: [2.0e-3], z1: [13, 21]'),
                  ["train.s1.phase", "train.s2.phase", "train.s1.stiffness", "train.s2.stiffness"])
    for t, x, out, der in draws(m, {n: 0.3 for n in m.state_names}, 10):
        for k, z in ((1, 13), (2, 21)):
            phase = z * x[f"train.s{k}.angle1.q"]
            close(out[f"train.s{k}.phase"], phase)
            close(out[f"train.s{k}.stiffness"], 1.0e5 * (1 + 0.2 * math.cos(phase)))
        close(der["train.s2.angle1.q"], x["train.shaft1.p"] / 2.0e-3)


# -- planetary gear --------------------------------------------------------------------------------

PLANETARY = """
name: planetary
elements:
  drive:   {type: torque_source, value: "1 + t"}
  sun:     {type: inertia, J: 1.0e-4}
  gear:    {type: planetary, z_sun: 24, z_ring: 72, module: 2.0e-3, c: 1.0e6, J_p: 2.0e-5}
  ring:    {type: inertia, J: 3.0e-3}
  carrier: {type: inertia, J: 5.0e-3}
  brake:   {type: torque_source, value: "-2"}
connections:
  - [drive.p, sun.a]
  - [sun.b, gear.sun]
  - [gear.ring, ring.a]
  - [gear.carrier, carrier.a]
  - [carrier.b, brake.p]
"""


def test_planetary_outputs():
    """Simple planetary, module 2 mm: r_sun = 24 mm, r_planet = 24 mm, r_ring = 72 mm; i0 = -z_ring/z_sun;
    mesh forces c*q; the sun wheel is massless, so the torque on the gear at the sun is M_I = r_sun*F12,
    rolling power M_I*(w_I - w_s), coupling power M_I*w_s (their sum is the power into the sun)."""
    c, r_sun = 1.0e6, 2.0e-3 * 24 / 2
    m = model_for(PLANETARY, ["gear.i0", "gear.rolling_power", "gear.coupling_power", "gear.mesh12.force",
                              "gear.mesh34.force"])
    scales = {n: (1e-5 if n.endswith(".q") else 0.01) for n in m.state_names}
    assert {"gear.mesh12.q", "gear.mesh34.q", "sun.p", "carrier.p"} <= set(m.state_names)
    for t, x, out, der in draws(m, scales, 11):
        F12, F34 = c * x["gear.mesh12.q"], c * x["gear.mesh34.q"]
        wI, ws = x["sun.p"] / 1.0e-4, x["carrier.p"] / 5.0e-3
        MI = r_sun * F12
        close(out["gear.i0"], -72 / 24)
        close(out["gear.mesh12.force"], F12)
        close(out["gear.mesh34.force"], F34)
        close(out["gear.rolling_power"], MI * (wI - ws), abs(MI) * (abs(wI) + abs(ws)))
        close(out["gear.coupling_power"], MI * ws)
        M = 1 + t
        close(der["sun.p"], M - MI, abs(M) + abs(MI))             # the gear brakes the sun with M_I


def test_planetary_stepped_ratio():
    """Stepped planets, external second mesh: i0 = (-r2/r1)*(-r4/r3)."""
    text = PLANETARY.replace("z_sun: 24, z_ring: 72, module: 2.0e-3", "r1: 0.02, r2: 0.04, r3: 0.03, r4: 0.025")
    m = model_for(text, ["gear.i0"])
    for t, x, out, der in draws(m, {n: 1e-3 for n in m.state_names}, 12):
        close(out["gear.i0"], (-0.04 / 0.02) * (-0.025 / 0.03))


# -- piezo element and stack (Weber (50)-(55)) -----------------------------------------------------

K_P, DELTA_P, C_P, M_TIP, R_EL = 2.0e-9, 1.0e-8, 1.0e-6, 0.01, 5.0

PIEZO = f"""
name: piezo
elements:
  supply: {{type: voltage_source, value: "100*sin(50*t)"}}
  gnd:    {{type: ground, domain: electrical}}
  wall:   {{type: ground, domain: translational}}
  pz:     {{type: TYPE, k_P: {K_P}, delta_P: {DELTA_P}, C_P: {C_P}, m: {M_TIP}, R: {R_EL}}}
  push:   {{type: force_source, value: "20 + 5*t"}}
connections:
  - [supply.p, pz.elec_a]
  - [supply.n, pz.elec_b, gnd.p]
  - [wall.p, pz.mech_a]
  - [pz.mech_b, push.p]
"""


def field_efforts(q1, q2):
    """Weber (50)/(54): [stroke, charge] = S·[T, U] with S = [[delta_P, k_P], [k_P, C_P]]; solved for
    the tension T [N] and the field voltage U [V] by Cramer's rule."""
    det = DELTA_P * C_P - K_P ** 2
    return (C_P * q1 - K_P * q2) / det, (DELTA_P * q2 - K_P * q1) / det


PIEZO_SCALES = {"field.q1": 1e-7, "field.q2": 1e-5, "mass.p": 1e-3}


def test_piezo_element():
    """T and U from the field's charge and extension; terminal voltage U + R*I (Weber (55)); the tip mass
    obeys (53): m*a1 = F1 - T."""
    m = model_for(PIEZO.replace("TYPE", "piezo_element"),
                  ["pz.stroke", "pz.force", "pz.charge", "pz.voltage", "pz.current", "pz.field_voltage"])
    assert sorted(m.state_names) == ["pz.field.q1", "pz.field.q2", "pz.mass.p"]
    scales = {f"pz.{k}": v for k, v in PIEZO_SCALES.items()}
    for t, x, out, der in draws(m, scales, 13):
        q1, q2 = x["pz.field.q1"], x["pz.field.q2"]
        T, U = field_efforts(q1, q2)
        V = 100 * math.sin(50 * t)
        I = (V - U) / R_EL
        det_scale = (C_P * abs(q1) + K_P * abs(q2)) / (DELTA_P * C_P - K_P ** 2)
        close(out["pz.stroke"], q1)
        close(out["pz.charge"], q2)
        close(out["pz.force"], T, det_scale)
        close(out["pz.field_voltage"], U, (DELTA_P * abs(q2) + K_P * abs(q1)) / (DELTA_P * C_P - K_P ** 2))
        close(out["pz.voltage"], V)
        close(out["pz.current"], I, (abs(V) + abs(U)) / R_EL)
        close(der["pz.field.q2"], I, (abs(V) + abs(U)) / R_EL)                 # Q' = I
        F1 = 20 + 5 * t
        close(der["pz.mass.p"], F1 - T, abs(F1) + det_scale)                    # m*a1 = F1 - T
        close(der["pz.field.q1"], x["pz.mass.p"] / M_TIP)                       # base at rest: s1' = v_tip


def test_piezo_stack():
    """Two elements in series (one force path, strokes add) and in parallel (one voltage, charges and
    currents add); the stack's force is the tension of the base element, which differs from the tip
    element's by the mass of element 1 times its acceleration."""
    m = model_for(PIEZO.replace("TYPE", "piezo_stack, n: 2"),
                  ["pz.stroke", "pz.force", "pz.charge", "pz.voltage", "pz.current"])
    assert sorted(m.state_names) == sorted(f"pz.e{k}.{s}" for k in (1, 2) for s in PIEZO_SCALES)
    scales = {f"pz.e{k}.{s}": v for k in (1, 2) for s, v in PIEZO_SCALES.items()}
    for t, x, out, der in draws(m, scales, 14):
        T, U = zip(*(field_efforts(x[f"pz.e{k}.field.q1"], x[f"pz.e{k}.field.q2"]) for k in (1, 2)))
        V = 100 * math.sin(50 * t)
        tension_scale = (C_P * 1e-7 + K_P * 1e-5) / (DELTA_P * C_P - K_P ** 2)
        assert abs(T[0] - T[1]) > 1e-3 * tension_scale       # the draw tells base from tip
        close(out["pz.force"], T[0], tension_scale)
        close(out["pz.stroke"], x["pz.e1.field.q1"] + x["pz.e2.field.q1"], 2e-7)
        close(out["pz.charge"], x["pz.e1.field.q2"] + x["pz.e2.field.q2"], 2e-5)
        close(out["pz.voltage"], V)
        close(out["pz.current"], sum((V - u) / R_EL for u in U), (2 * abs(V) + sum(map(abs, U))) / R_EL)
        # element 2's tip mass is pushed by the source and pulled back by its own tension;
        # element 1's tip mass sits between the two active parts: m*a = T2 - T1
        close(der["pz.e2.mass.p"], 20 + 5 * t - T[1], 25 + 5 * t + tension_scale)
        close(der["pz.e1.mass.p"], T[1] - T[0], 2 * tension_scale)


# -- primitives: their quantities are their states -------------------------------------------------

PRIMITIVES = """
name: primitives
elements:
  src:   {type: Se, value: "sin(t)", domain: rotational}
  node:  {type: junction_b, ports: [s, i, c, tap, tf, cf, mtf], domain: rotational}
  body:  {type: I, J: 0.5, p0: 0.1}
  spr:   {type: C, c: 20.0, q0: 0.2}
  angle: {type: Tap, q0: 0.3}
  tf:    {type: TF, ratio: "2 + 0.1*cos(q)", q0: 0.4}
  tfl:   {type: C, c: 3.0}
  cf:    {type: CField, compliance: [[0.5, 0.1], [0.1, 0.4]], domains: [rotational, rotational], q0: [0.5, 0.6]}
  cfl:   {type: R, r: 2.0}
  mtf:   {type: MTF, matrix: [["1 + 0.2*sin(q1)", "0.5 + 0.1*cos(q2)"]], domains_a: [rotational],
          domains_b: [rotational, rotational], q0: [0.7, 0.8]}
  m1:    {type: C, c: 4.0}
  m2:    {type: R, r: 1.0}
connections:
  - [src.p, node.s]
  - [node.i, body.p]
  - [node.c, spr.p]
  - [node.tap, angle.p]
  - [node.tf, tf.a]
  - [tf.b, tfl.p]
  - [node.cf, cf.p1]
  - [cf.p2, cfl.p]
  - [node.mtf, mtf.a1]
  - [mtf.b1, m1.p]
  - [mtf.b2, m2.p]
"""


def test_primitive_quantities_are_their_states():
    outs = ["body.p", "spr.q", "angle.q", "tf.q", "cf.q1", "cf.q2", "mtf.q1", "mtf.q2"]
    m = model_for(PRIMITIVES, outs)
    x0 = dict(zip(m.state_names, m.x0))
    for name, value in (("body.p", 0.1), ("spr.q", 0.2), ("angle.q", 0.3), ("tf.q", 0.4), ("cf.q1", 0.5),
                        ("cf.q2", 0.6), ("mtf.q1", 0.7), ("mtf.q2", 0.8)):
        assert x0[name] == value, name
    for t, x, out, der in draws(m, {n: 1.0 for n in m.state_names}, 15):
        for name in outs:
            close(out[name], x[name], what=name)


# -- completeness ----------------------------------------------------------------------------------

CHECKED = {
    "inertia": {"omega", "p"}, "mass": {"v", "p"}, "spring": {"force", "deflection"},
    "damper": {"force", "power"}, "resistor": {"i", "v"}, "capacitor": {"v", "i"}, "inductor": {"i", "v"},
    "voltage_source": {"i", "v"}, "current_source": {"i", "v"},
    "dc_motor": {"omega", "current", "torque", "back_emf", "voltage"},
    "spur_stage": {"force", "deflection", "force_u", "stiffness", "phase", "sliding_velocity", "friction_force",
                   "loss", "contact_position"},
    "gear_train": {"ratio", "s<k>.force", "s<k>.deflection", "s<k>.stiffness", "s<k>.phase"},
    "planetary": {"i0", "rolling_power", "coupling_power", "mesh12.force", "mesh34.force"},
    "piezo_element": {"stroke", "force", "charge", "voltage", "current", "field_voltage"},
    "piezo_stack": {"stroke", "force", "charge", "voltage", "current"},
    "I": {"p"}, "C": {"q"}, "Tap": {"q"}, "TF": {"q"}, "CField": {"q1..qn"}, "MTF": {"q1..qm"},
}


#: element types whose outputs are checked against theory in their own test modules: each documented
#: quantity must be read there (as ``.name`` of an output)
CHECKED_IN = {**{k: ("test_linkage_dynamics.py", "test_linkage_slide.py", "test_linkage_guides.py")
                 for k in ("DAN", "DDD", "SAN", "FGP", "DDS", "DSD", "SSD", "SDS")},
              **{k: ("test_belts.py",) for k in ("band", "band_roll", "drum")},
              "belt_pulley": ("test_belt_friction.py",),
              **{k: ("test_belt_planar.py",) for k in ("planar_band", "planar_roll", "planar_drum")},
              **{k: ("test_belt_spans.py",) for k in ("nozzle_band", "spring_band")},
              **{k: ("test_belt_contour.py",) for k in ("curve_roll", "curve_drum")},
              **{k: ("test_belt_planar_curve.py",) for k in ("planar_curve_roll", "planar_curve_drum",
                                                             "planar_curve_band")}}


def test_every_documented_output_is_checked():
    """Each quantity ``multipole elements TYPE`` documents has a theory check in this file, or in the
    element library's own test module (planar linkages, belts)."""
    import re
    from pathlib import Path
    here = Path(__file__).parent

    def elsewhere(name):
        text = "".join((here / f).read_text(encoding="utf-8") for f in CHECKED_IN.get(name, ()))
        return {q for q in catalogue()[name].quantities if re.search(r"\." + re.escape(q) + r"\b", text)}
    missing = {name: set(et.quantities) - CHECKED.get(name, set()) - elsewhere(name)
               for name, et in catalogue().items()}
    missing = {k: v for k, v in missing.items() if v}
    assert not missing, f"documented outputs without a theory check here: {missing}"
