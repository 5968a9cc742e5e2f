"""Four-bar linkage (VDI 2729 DAN + DDD) against theory written here: the circle intersection and
its derivatives (kinematics), energy conservation (free motion under gravity), the energy rate
(kinetostatic drive torque) and an independent constrained Lagrangian model (dynamics).

Geometry: crank pivot at the origin, crank l = 0.2 m; coupler l1 = 0.6 m from the crank tip A to P;
rocker l2 = 0.5 m from the frame pivot B = (0.7, 0) to P; centres of mass at mid-link.
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import multipole as mp
from multipole import pipeline

L, L1, L2, BX = 0.2, 0.6, 0.5, 0.7
M = (1.0, 2.0, 1.5)          # crank, coupler, rocker [kg]
J = (0.01, 0.06, 0.03)       # about the centres of mass [kg*m^2]
G = 9.81


def scene(drive: str, omega0=0.0, phi0=0.3, gy=-G, t_end=2.0, rtol=1e-11, outputs=None):
    outputs = outputs or ["crank.phi", "crank.omega", "rocker.phi1", "rocker.phi2", "rocker.omega1",
                          "rocker.omega2", "rocker.alpha1", "rocker.alpha2", "crank.torque", "crank.alpha", "rocker.transmission"]
    text = f"""
name: fourbar
elements:
  crank: {{type: DAN, l: {L}, phi0: {phi0}, omega0: {omega0}, m: {M[0]}, J: {J[0]}, gy: {gy}}}
  rocker: {{type: DDD, l1: {L1}, l2: {L2}, K: 1, m1: {M[1]}, J1: {J[1]}, m2: {M[2]}, J2: {J[2]}, x2: {BX},
           gy: {gy}}}
{drive}
connections:
  - [crank.b, rocker.a1]
{'  - [src.p, crank.drive]' if drive else ''}
outputs: [{', '.join(outputs)}]
simulate: {{t_end: {t_end}, rtol: {rtol}, atol: 1e-12, dt_out: 0.01}}
"""
    return mp.loads(text, "fourbar.yaml")


def run(sc, backend="numpy"):
    res = pipeline.run(sc, backend=backend) if backend != "numpy" else pipeline.run(sc)
    return {"t": res.t, **{name: res[name] for name in sc.outputs}}


def e(p):
    return np.array([np.cos(p), np.sin(p)])


def n(p):
    return np.array([-np.sin(p), np.cos(p)])


def circle_intersection(phi):
    """Joint P for crank angle phi, left of the line A -> B (K = +1)."""
    A = L * e(phi)
    d = np.array([BX, 0.0])[:, None] - A
    dist = np.hypot(*d)
    along = (L1 ** 2 - L2 ** 2 + dist ** 2) / (2 * dist)
    across = np.sqrt(L1 ** 2 - along ** 2)
    u = d / dist
    return A + along * u + across * np.array([-u[1], u[0]])


def coupler_rocker(phi, omega, alpha):
    """Coupler and rocker angles, rates and accelerations from the loop closure and its derivatives
    (2x2 solves written here: A + l1 e1 = B + l2 e2)."""
    P = circle_intersection(phi)
    A = L * e(phi)
    p1 = np.arctan2(P[1] - A[1], P[0] - A[0])
    p2 = np.arctan2(P[1], P[0] - BX)
    w1, w2, a1, a2 = (np.empty_like(phi) for _ in range(4))
    for k in range(len(phi)):
        Mk = np.column_stack([L1 * n(p1[k]), -L2 * n(p2[k])])
        rhs = -L * omega[k] * n(phi[k])
        w1[k], w2[k] = np.linalg.solve(Mk, rhs)
        rhs2 = -(L * alpha[k] * n(phi[k]) - L * omega[k] ** 2 * e(phi[k])) \
            + L1 * w1[k] ** 2 * e(p1[k]) - L2 * w2[k] ** 2 * e(p2[k])
        a1[k], a2[k] = np.linalg.solve(Mk, rhs2)
    return p1, p2, w1, w2, a1, a2


def energy(r):
    pc, wc, p1, p2, w1, w2 = (r[k] for k in ("crank.phi", "crank.omega", "rocker.phi1", "rocker.phi2",
                                              "rocker.omega1", "rocker.omega2"))
    vc = 0.5 * L * wc * n(pc)
    v1 = L * wc * n(pc) + 0.5 * L1 * w1 * n(p1)
    v2 = 0.5 * L2 * w2 * n(p2)
    yc, y1, y2 = 0.5 * L * np.sin(pc), L * np.sin(pc) + 0.5 * L1 * np.sin(p1), 0.5 * L2 * np.sin(p2)
    kinetic = sum(0.5 * m * (v ** 2).sum(0) for m, v in zip(M, (vc, v1, v2))) \
        + 0.5 * (J[0] * wc ** 2 + J[1] * w1 ** 2 + J[2] * w2 ** 2)
    return kinetic + G * (M[0] * yc + M[1] * y1 + M[2] * y2)


def test_speed_driven_kinematics_match_the_loop_closure():
    """Prescribed crank speed w(t) = 2 + sin(3t): angles, rates and accelerations of coupler and rocker
    equal the closure solution and its derivatives; positions to 1e-10, accelerations to 1e-8."""
    r = run(scene("  src: {type: speed_source, value: 2 + sin(3*t)}"))
    t = r["t"]
    phi = 0.3 + 2 * t - np.cos(3 * t) / 3 + 1 / 3
    omega, alpha = 2 + np.sin(3 * t), 3 * np.cos(3 * t)
    assert np.abs(r["crank.phi"] - phi).max() < 1e-9
    assert np.abs(r["crank.alpha"] - alpha).max() < 1e-9
    p1, p2, w1, w2, a1, a2 = coupler_rocker(phi, omega, alpha)
    assert np.abs(r["rocker.phi1"] - p1).max() < 1e-9
    assert np.abs(r["rocker.phi2"] - p2).max() < 1e-9
    assert np.abs(r["rocker.omega1"] - w1).max() < 1e-8
    assert np.abs(r["rocker.omega2"] - w2).max() < 1e-8
    assert np.abs(r["rocker.alpha1"] - a1).max() < 1e-7
    assert np.abs(r["rocker.alpha2"] - a2).max() < 1e-7
    assert np.abs(r["rocker.transmission"] - np.sin(p2 - p1)).max() < 1e-9


def test_constant_speed_positions_to_1e_10():
    """At constant crank speed the crank angle is exact and the closure is solved per evaluation:
    the joint P is the circle intersection to 1e-10 m."""
    r = run(scene("  src: {type: speed_source, value: 5.0}", t_end=3.0))
    phi = 0.3 + 5.0 * r["t"]
    P = circle_intersection(phi)
    Px = L * np.cos(r["crank.phi"]) + L1 * np.cos(r["rocker.phi1"])
    Py = L * np.sin(r["crank.phi"]) + L1 * np.sin(r["rocker.phi1"])
    assert np.abs(Px - P[0]).max() < 1e-10 and np.abs(Py - P[1]).max() < 1e-10


def test_kinetostatic_drive_torque_equals_the_energy_rate():
    """Speed-driven crank under inertia and gravity: drive torque * omega = d/dt (kinetic + potential
    energy), the energy rate computed here from the closure kinematics (relative 1e-8)."""
    r = run(scene("  src: {type: speed_source, value: 2 + sin(3*t)}"))
    t = r["t"]
    phi = 0.3 + 2 * t - np.cos(3 * t) / 3 + 1 / 3
    omega, alpha = 2 + np.sin(3 * t), 3 * np.cos(3 * t)
    p1, p2, w1, w2, a1, a2 = coupler_rocker(phi, omega, alpha)
    # d/dt E = sum m v.a + J w alpha + m g vy, from the exact kinematics
    vc, ac = 0.5 * L * omega * n(phi), 0.5 * L * (alpha * n(phi) - omega ** 2 * e(phi))
    vA, aA = L * omega * n(phi), L * (alpha * n(phi) - omega ** 2 * e(phi))
    v1, a1v = vA + 0.5 * L1 * w1 * n(p1), aA + 0.5 * L1 * (a1 * n(p1) - w1 ** 2 * e(p1))
    v2, a2v = 0.5 * L2 * w2 * n(p2), 0.5 * L2 * (a2 * n(p2) - w2 ** 2 * e(p2))
    rate = sum(m * ((v * a).sum(0) + G * v[1]) for m, v, a in zip(M, (vc, v1, v2), (ac, a1v, a2v))) \
        + J[0] * omega * alpha + J[1] * w1 * a1 + J[2] * w2 * a2
    power = r["crank.torque"] * omega
    assert np.abs(power - rate).max() < 1e-8 * np.abs(rate).max()


def test_free_motion_under_gravity_conserves_energy_and_closure():
    """No drive: the four-bar swings under gravity from omega0 = 3 rad/s; relative energy drift <= 1e-8
    over 10 s, loop closure <= 1e-9 of the link lengths."""
    r = run(scene("", omega0=3.0, t_end=10.0))
    E = energy(r)
    assert np.abs(E - E[0]).max() <= 1e-8 * abs(E[0])
    closure = L * e(r["crank.phi"]) + L1 * e(r["rocker.phi1"]) - np.array([BX, 0])[:, None] \
        - L2 * e(r["rocker.phi2"])
    assert np.abs(closure).max() <= 1e-9 * L2


def lagrangian(tau, phi0, t_eval):
    """Independent model: coordinates q = (crank, coupler, rocker angle), constraint forces by
    Lagrange multipliers, [[M, C^T], [C, 0]] [q''; lambda] = [Q - h; -C' q'] (index-1 DAE as an ODE)."""
    def rhs(t, y):
        q, qd = y[:3], y[3:]
        pc, p1, p2 = q
        wc, w1, w2 = qd
        Jc = np.column_stack([0.5 * L * n(pc), [0, 0], [0, 0]])
        J1 = np.column_stack([L * n(pc), 0.5 * L1 * n(p1), [0, 0]])
        J2 = np.column_stack([[0, 0], [0, 0], 0.5 * L2 * n(p2)])
        hc = -0.5 * L * wc ** 2 * e(pc)
        h1 = -L * wc ** 2 * e(pc) - 0.5 * L1 * w1 ** 2 * e(p1)
        h2 = -0.5 * L2 * w2 ** 2 * e(p2)
        Mq = np.diag(J).astype(float)
        Q = np.array([tau, 0.0, 0.0])
        h = np.zeros(3)
        for m, Jb, hb in zip(M, (Jc, J1, J2), (hc, h1, h2)):
            Mq += m * Jb.T @ Jb
            Q += m * Jb.T @ np.array([0.0, -G])
            h += m * Jb.T @ hb
        C = np.column_stack([L * n(pc), L1 * n(p1), -L2 * n(p2)])
        Cdot_qd = -L * wc ** 2 * e(pc) - L1 * w1 ** 2 * e(p1) + L2 * w2 ** 2 * e(p2)
        K = np.block([[Mq, C.T], [C, np.zeros((2, 2))]])
        sol = np.linalg.solve(K, np.concatenate([Q - h, -Cdot_qd]))
        return np.concatenate([qd, sol[:3]])
    P = circle_intersection(np.array([phi0]))[:, 0]
    A = L * e(phi0)
    y0 = [phi0, np.arctan2(P[1] - A[1], P[0] - A[0]), np.arctan2(P[1], P[0] - BX), 0, 0, 0]
    return solve_ivp(rhs, (0, t_eval[-1]), y0, t_eval=t_eval, method="DOP853", rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_torque_driven_dynamics_match_a_constrained_lagrangian_model(backend):
    """Constant torque 0.8 N*m on the crank, gravity: the crank angle and speed agree with the Lagrange-
    multiplier model to 1e-7 over 2 s; the drive angle is the state (no dependent coordinate)."""
    if backend == "numba":
        pytest.importorskip("numba")
    sc = scene("  src: {type: torque_source, value: 0.8}")
    an = pipeline.check(sc)
    states = [s.name for s in an.states]
    assert "crank.L.J.p" in states and not any(s.startswith("rocker.") and s.endswith(".p") for s in states)
    r = run(sc, backend)
    ref = lagrangian(0.8, 0.3, r["t"])
    assert ref.success
    assert np.abs(r["crank.phi"] - ref.y[0]).max() < 1e-7
    assert np.abs(r["crank.omega"] - ref.y[3]).max() < 1e-7
    assert np.abs(r["rocker.phi2"] - ref.y[2]).max() < 1e-7


def test_flywheel_engine_passes_both_dead_centres_for_1000_revolutions_with_energy_closed():
    """diagrams/linkages/engine_flywheel.yaml: a conservative slider-crank (flywheel, adiabatic gas
    spring) passes both dead centres 2000 times; kinetic + gas energy (computed here from the outputs)
    stays constant to 1e-8 relative and the rod length |P - P1| stays l to 1e-9 of l."""
    pytest.importorskip("numba")
    sc = mp.load("diagrams/linkages/engine_flywheel.yaml")
    r0, l, J, m, mL, JL, mS = 0.05, 0.18, 0.5, 2.0, 0.6, 0.003, 0.4
    p0A, L0 = 400.0, 0.03
    res = pipeline.run(sc, t_end=1000 * 2 * np.pi / 30.4, dt_out=0.01, rtol=1e-12, atol=1e-14, backend="numba",
                       progress=False)
    phi, w, x, v, wr, q = (res[k] for k in ("crank.phi", "crank.omega", "rod.x", "rod.v", "rod.omega", "gas.q"))
    assert phi[-1] > 1000 * 2 * np.pi * 0.99               # a thousand revolutions, monotonic
    assert np.all(np.diff(phi) > 0)
    vP1 = r0 * w * np.array([-np.sin(phi), np.cos(phi)])
    v_rod = 0.5 * (np.array([v, np.zeros_like(v)]) + vP1)
    kinetic = 0.5 * J * w ** 2 + 0.5 * m * (0.5 * r0 * w) ** 2 + 0.5 * mL * (v_rod ** 2).sum(0) \
        + 0.5 * JL * wr ** 2 + 0.5 * mS * v ** 2
    gas = p0A * L0 / 0.4 * ((L0 / (L0 - q)) ** 0.4 - 1.0)
    E = kinetic + gas
    assert np.abs(E - E[0]).max() <= 1e-8 * E[0]
    rod_length = np.hypot(x - r0 * np.cos(phi), r0 * np.sin(phi))
    assert np.abs(rod_length - l).max() <= 1e-9 * l


def _constrained_dae(bodies, constraints, forces, q0, t_eval):
    """An independent multibody model in maximal coordinates: q = (x, y, theta) of every body's centre
    of mass, M q'' + Phi_q^T lambda = Q, Phi_q q'' = -(Phi_q q')_q q'.  Phi_q by complex steps (exact),
    the second directional derivative by a central difference of complex-step directional derivatives."""
    n = 3 * len(bodies)
    Mdiag = np.concatenate([[m, m, J_] for m, J_ in bodies])

    def jac(q):
        h = 1e-30
        return np.column_stack([np.imag(constraints(q + 1j * h * np.eye(n)[k])) / h for k in range(n)])

    def rhs(t, y):
        q, qd = y[:n], y[n:]
        C = jac(q)
        eps = 1e-6 / max(np.linalg.norm(qd), 1e-12)
        d2 = (jac(q + eps * qd) @ qd - jac(q - eps * qd) @ qd) / (2 * eps) if np.any(qd) else np.zeros(len(C))
        K = np.block([[np.diag(Mdiag), C.T], [C, np.zeros((len(C), len(C)))]])
        sol = np.linalg.solve(K, np.concatenate([forces(q), -d2]))
        return np.concatenate([qd, sol[:n]])
    return solve_ivp(rhs, (0, t_eval[-1]), np.concatenate([q0, np.zeros(n)]), t_eval=t_eval, method="DOP853",
                     rtol=1e-11, atol=1e-12)


def test_six_link_dynamics_match_a_maximal_coordinate_multibody_model():
    """diagrams/linkages/six_link.yaml (DAN + DDD + FGP + DDS, torque 0.5 N*m, gravity): the crank
    angle and the slider travel agree with a maximal-coordinate model written here (five bodies,
    fourteen constraints, Lagrange multipliers) to 1e-6 over 1.5 s."""
    sc = mp.load("diagrams/linkages/six_link.yaml")
    r = run(sc)
    P2, guide_y, lrod, larm = np.array([BX, 0.0]), -0.5, 0.5, 0.3
    bodies = [(M[0], J[0]), (M[1], J[1]), (M[2], J[2]), (0.8, 0.02), (1.0, 0.001)]

    def E(a):
        return np.array([np.cos(a), np.sin(a)])

    def constraints(q):
        rc, tc, r1, t1, r2, t2, r3, t3, r4, t4 = (q[0:2], q[2], q[3:5], q[5], q[6:8], q[8], q[9:11], q[11],
                                                   q[12:14], q[14])
        Q = r2 - 0.25 * E(t2) - larm * E(t2)            # the arm's end, opposite to the rocker
        return np.concatenate([rc - 0.5 * L * E(tc),                      # crank pivot at the origin
                               rc + 0.5 * L * E(tc) - (r1 - 0.5 * L1 * E(t1)),   # crank tip = coupler start
                               r1 + 0.5 * L1 * E(t1) - (r2 + 0.5 * L2 * E(t2)),  # joint P
                               r2 - 0.5 * L2 * E(t2) - P2,                # rocker pivot
                               r3 + 0.5 * lrod * E(t3) - Q,               # rod end at Q (rod angle: slider -> Q)
                               r3 - 0.5 * lrod * E(t3) - r4,              # rod pin on the slider
                               [r4[1] - guide_y, t4]])                    # slider on the guide, not turning

    def forces(q):
        f = np.zeros(15)
        for k, (m, _J) in enumerate(bodies):
            f[3 * k + 1] = -m * G
        f[2] += 0.5
        return f
    # initial pose from closed forms: circle intersection (K = +1), the larger slider travel (K = +1)
    tc = 0.3
    A = L * E(tc)
    P = circle_intersection(np.array([tc]))[:, 0]
    t1, t2 = np.arctan2(*(P - A)[::-1]), np.arctan2(*(P - P2)[::-1])
    Q = P2 - larm * E(t2)
    xs = Q[0] + np.sqrt(lrod ** 2 - (Q[1] - guide_y) ** 2)
    t3 = np.arctan2(Q[1] - guide_y, Q[0] - xs)
    q0 = np.concatenate([0.5 * A, [tc], A + 0.5 * L1 * E(t1), [t1], P2 + 0.5 * L2 * E(t2), [t2],
                         [xs, guide_y] + 0.5 * lrod * E(t3), [t3], [xs, guide_y], [0.0]])
    assert np.abs(constraints(q0)).max() < 1e-12
    ref = _constrained_dae(bodies, constraints, forces, q0, r["t"])
    assert ref.success
    assert np.abs(r["crank.phi"] - ref.y[2]).max() < 1e-6
    assert np.abs(r["rod.x"] - (ref.y[12] - 0.7)).max() < 1e-6


def test_dwell_six_bar_dwells_where_the_coupler_point_runs_on_its_arc():
    """diagrams/linkages/dwell_six_bar.yaml: the coupler point runs within 2e-4 R (R = 0.7523 m, a fit of
    the closed-form coupler curve) of a circle about D0 for crank angles 260-360 degrees; a rod of
    length R holds the output pin at D0 there, so the output rocker (0.12 m) stays at pi within
    about 2e-4 R / 0.12 m = 1.3e-3 rad, and swings by more than 0.15 rad elsewhere."""
    sc = mp.load("diagrams/linkages/dwell_six_bar.yaml")
    r = run(sc)
    crank = np.mod(r["crank.phi"], 2 * np.pi)
    dwell = (crank > np.radians(262)) & (crank < np.radians(358))
    assert dwell.sum() > 50
    assert np.abs(r["output.phi2"][dwell] - np.pi).max() < 3e-3
    assert np.abs(r["output.phi2"] - np.pi).max() > 0.15
