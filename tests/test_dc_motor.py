"""DC motor (gyrator k with R, L on the electrical side and J, d on the rotor) against theory.

Model equations (textbook permanent-magnet DC motor; Weber §4.1 gyrator with cross-couplings):

    U = R·i + L·di/dt + k·omega                       (armature circuit)
    J·domega/dt = k·i − d·omega − M_L                 (rotor, load torque M_L braking)

Steady state: omega = (k·U − R·M_L)/(k² + R·d), i = (M_L + d·omega)/k.
Time constants: electrical L/R (rotor locked), mechanical J·R/k² (L = 0, d = 0); in general the
eigenvalues are the roots of L·J·s² + (R·J + L·d)·s + (R·d + k²) = 0.
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from helpers import run, scene
from multipole import pipeline
from multipole.errors import NetlistError

K, R, L, J, D = 0.05, 1.2, 2.0e-3, 1.0e-4, 2.0e-5       # N*m/A, Ohm, H, kg*m^2, N*m*s/rad
U, ML = 12.0, 0.02                                       # V, N*m


def motor_scene(u="U*step(t)", l=L, d=D, ml=ML, shaft="load", j_load=2.0e-4, t_end=1.0, dt=1e-3,
                motor_extra="", supply="grounded"):
    """Supply -> motor -> (load inertia + braking torque | locked shaft | free shaft)."""
    mech = {
        "load": ("load: {type: inertia, J: %r}\n  brake: {type: torque_source, value: %r}" % (j_load, -ml),
                 "- [motor.shaft, load.a]\n  - [load.b, brake.p]"),
        "locked": ("housing: {type: ground}", "- [motor.shaft, housing.p]"),
        "free": ("", ""),
    }[shaft]
    elec = {
        "grounded": ("supply: {type: voltage_source, value: \"%s\"}" % u,
                     "- [supply.p, motor.elec]\n  - [supply.n, gnd.p]"),
        "floating": ("supply: {type: voltage_source, value: \"%s\"}\n"
                     "  offset: {type: voltage_source, value: \"5 + 3*sin(100*t)\"}" % u,
                     "- [supply.p, motor.elec]\n  - [supply.n, motor.elec_n, offset.p]\n"
                     "  - [offset.n, gnd.p]"),
    }[supply]
    return f"""
name: dc_motor_test
parameters: {{U: {U}}}
elements:
  motor: {{type: dc_motor, k: {K}, R: {R}, L: {l}, J: {J}, d: {d}{motor_extra}}}
  gnd: {{type: ground, domain: electrical}}
  {elec[0]}
  {mech[0]}
connections:
  {elec[1]}
  {mech[1]}
outputs: [motor.omega, motor.current, motor.torque, motor.back_emf, motor.voltage]
simulate: {{t_end: {t_end:.9e}, dt_out: {dt:.9e}, rtol: 1.0e-10, atol: 1.0e-12}}
"""


@pytest.mark.parametrize("d,ml", [(0.0, 0.0), (D, 0.0), (D, ML), (0.0, ML)])
def test_steady_state_speed_and_current(d, ml):
    """omega = (k·U − R·M_L)/(k² + R·d), i = (M_L + d·omega)/k: set omega' = i' = 0 in the model
    equations.  Simulated for 30 slowest time constants (e^-30 ~ 1e-13)."""
    tau = (J + 2.0e-4) * R / (K**2 + R * d)
    res = run(motor_scene(d=d, ml=ml, t_end=30 * tau, dt=tau))
    w = (K * U - R * ml) / (K**2 + R * d)
    i = (ml + d * w) / K
    assert res["motor.omega"][-1] == pytest.approx(w, rel=1e-8)
    assert res["motor.current"][-1] == pytest.approx(i, rel=1e-8, abs=1e-9 * U / R)   # scale: stall current
    assert res["motor.back_emf"][-1] == pytest.approx(K * w, rel=1e-8)
    assert res["motor.torque"][-1] == pytest.approx(K * i, rel=1e-8, abs=1e-9 * K * U / R)


def test_electrical_time_constant_locked_rotor():
    """Rotor locked (omega = 0, no back-emf): L·i' = U − R·i, so i = U/R·(1 − exp(−t·R/L));
    the rotor inertia is in derivative causality against the housing."""
    tau = L / R
    res = run(motor_scene(shaft="locked", t_end=8 * tau, dt=tau / 50))
    i = U / R * (1 - np.exp(-res.t / tau))
    assert np.max(np.abs(res["motor.current"] - i)) <= 1e-8 * U / R
    assert np.max(np.abs(res["motor.omega"])) <= 1e-12
    assert np.allclose(res["motor.torque"], K * res["motor.current"], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("d", [0.0, D])
def test_mechanical_time_constant_without_inductance(d):
    """L = 0: i = (U − k·omega)/R, so J·omega' = k·(U − k·omega)/R − d·omega — first order with
    tau = J·R/(k² + R·d) (= J·R/k² without friction) and omega_inf = k·U/(k² + R·d)."""
    tau = J * R / (K**2 + R * d)
    w_inf = K * U / (K**2 + R * d)
    res = run(motor_scene(l=0, d=d, shaft="free", t_end=6 * tau, dt=tau / 50))
    w = w_inf * (1 - np.exp(-res.t / tau))
    assert np.max(np.abs(res["motor.omega"] - w)) <= 1e-6 * w_inf
    i = (U - K * w) / R
    assert np.max(np.abs(res["motor.current"][1:] - i[1:])) <= 1e-6 * U / R


def test_eigenvalues_are_the_two_time_constants():
    """The kernel's linear model (Jacobian) has the roots of L·J·s² + (R·J + L·d)·s + (R·d + k²);
    with L small (tau_e = L/R << tau_m = J·R/k²) they tend to −R/L and −k²/(J·R), the slow one
    within a relative tau_e/tau_m (first-order perturbation of the quadratic)."""
    l_small = 1.0e-4
    sc = scene(motor_scene(l=l_small, d=0.0, shaft="free"))
    model = pipeline.model(sc)
    lam = np.sort(np.linalg.eigvals(model.jac(0.0, model.x0)).real)
    roots = np.sort(np.roots([l_small * J, R * J, K**2]).real)
    assert np.allclose(lam, roots, rtol=1e-9)
    tau_e, tau_m = l_small / R, J * R / K**2
    assert abs(-1 / lam[1] - tau_m) / tau_m <= 2 * tau_e / tau_m
    assert abs(-1 / lam[0] - tau_e) / tau_e <= 2 * tau_e / tau_m


def test_response_matches_independent_scipy_model():
    """Full model with load inertia, friction and load torque, voltage ramp then step, against a
    hand-written scipy right-hand side of the same two equations."""
    j_load, u_expr = 2.0e-4, "U*min(t/0.02, 1) + 3*step(t - 0.1)"
    # Radau: the output grid lies inside the steps, and DOP853's interpolant between its steps is
    # not held to rtol (on these equations scipy's own DOP853 at rtol 1e-10 is 7.5e-9 off at its
    # step ends and 1.5e-6 between them); this test compares the model, not the interpolant
    text = motor_scene(u=u_expr, j_load=j_load, t_end=0.3, dt=1e-4)
    res = run(text.replace("rtol: 1.0e-10,", "rtol: 1.0e-10, solver: Radau,", 1))
    assert res.solver == "Radau"

    def volt(t):
        return U * min(t / 0.02, 1.0) + (3.0 if t >= 0.1 else 0.0)

    def rhs(t, x):
        i, w = x
        return [(volt(t) - R * i - K * w) / L, (K * i - D * w - ML) / (J + j_load)]

    ref = {}
    for a, b in ((0.0, 0.02), (0.02, 0.1), (0.1, 0.3)):     # restart at the kinks of the input
        grid = res.t[(res.t >= a) & (res.t <= b)]
        x0 = [0.0, 0.0] if not ref else [ref["i"][-1], ref["w"][-1]]
        sol = solve_ivp(rhs, (a, b), x0, method="Radau", t_eval=grid, rtol=1e-11, atol=1e-13,
                        first_step=1e-9 if a else None)
        sl = slice(1 if ref else 0, None)
        ref.setdefault("t", []).extend(sol.t[sl])
        ref.setdefault("i", []).extend(sol.y[0][sl])
        ref.setdefault("w", []).extend(sol.y[1][sl])
    assert np.allclose(ref["t"], res.t)
    assert np.max(np.abs(res["motor.omega"] - ref["w"])) <= 1e-6 * np.max(np.abs(ref["w"]))
    assert np.max(np.abs(res["motor.current"] - ref["i"])) <= 1e-6 * np.max(np.abs(ref["i"]))


def test_energy_balance():
    """Supplied energy = stored (L·i²/2 + J_tot·omega²/2) + dissipated (R·i², d·omega²) + load work
    (M_L·omega), integrated over a step response (trapezoidal rule on a fine output grid)."""
    j_load = 2.0e-4
    res = run(motor_scene(j_load=j_load, t_end=0.2, dt=2e-6))
    t, i, w = res.t, res["motor.current"], res["motor.omega"]
    supplied = np.trapezoid(res["motor.voltage"] * i, t)
    stored = 0.5 * L * i[-1] ** 2 + 0.5 * (J + j_load) * w[-1] ** 2
    lost = np.trapezoid(R * i**2 + D * w**2 + ML * w, t)
    assert abs(supplied - stored - lost) <= 1e-6 * supplied


def test_floating_terminals_follow_the_voltage_difference():
    """grounded: false exposes elec_n; only e(elec) − e(elec_n) drives the motor, so lifting both
    terminals by a varying potential changes nothing."""
    a = run(motor_scene(t_end=0.1, dt=1e-4))
    b = run(motor_scene(t_end=0.1, dt=1e-4, motor_extra=", grounded: false", supply="floating"))
    assert np.allclose(b["motor.voltage"], a["motor.voltage"], rtol=0, atol=1e-9)
    assert np.max(np.abs(b["motor.omega"] - a["motor.omega"])) <= 1e-7 * np.abs(a["motor.omega"]).max()


def test_grounded_motor_has_no_negative_port():
    """By default the negative terminal is at 0 V inside the motor; wiring elec_n is refused with
    the list of ports."""
    with pytest.raises(NetlistError, match="elec_n") as err:
        scene(motor_scene(supply="floating"))
    assert err.value.code == "unknown_port"


def test_catalogue_entry():
    """Every parameter has an SI unit (bool excepted) and the quantities of the issue exist."""
    from multipole import catalogue
    et = catalogue()["dc_motor"]
    assert all(p.unit for p in et.params if p.kind != "bool")
    assert {"omega", "current", "torque", "back_emf"} <= set(et.quantities)
    assert {"elec", "shaft"} <= set(et.ports)
