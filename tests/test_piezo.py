"""Piezo element and stack translator (Weber §6, eqs. (50)–(55), Bild 36/38) against theory.

Sign convention (Weber, DESIGN §4): the force at a port acts on the element; positive direction from
the base ``mech_a`` to the tip ``mech_b``, so a pull on the tip is a positive tension ``T``.
Weber's static relations, for one element with voltage ``U`` on its capacitance and tension ``T``:

    (51)  Δs = k_P·U + delta_P·T          (50)  Q = k_P·T + C_P·U

so ``delta_P`` is the compliance at constant voltage (shorted electrodes) and ``C_P`` the
capacitance at constant force (mechanically free).  Eliminating one variable gives the other two
classical constants: blocked capacitance ``C_P − k_P²/delta_P`` (Δs = 0) and open-circuit
compliance ``delta_P − k_P²/C_P`` (Q = 0).  A stack of ``n`` elements (Bild 38) has the same force in
every element and the same voltage on every element, so strokes and charges add:
``Δs = n·(k_P·U + delta_P·T)``, ``Q = n·(k_P·T + C_P·U)`` ([W] §6, reference W9).

Static values are taken from the equilibrium of the compiled model (``rhs = 0``; states whose rate
is identically zero, such as the extension of a clamped element, keep their initial value).
"""
import numpy as np
import pytest

from helpers import check, run, scene
from multipole import pipeline

K_P, DELTA_P, C_P, M_TIP, R_EL = 5.0e-10, 1.0e-10, 5.0e-9, 4.0e-4, 10.0   # one PZT disc, coupling 0.5
C_BLOCKED = C_P - K_P**2 / DELTA_P           # 2.5e-9 F
DELTA_OPEN = DELTA_P - K_P**2 / C_P          # 5e-11 m/N
U, F = 100.0, 50.0                           # V, N

ELEC = {  # electrical side: connections and extra elements
    "source": ("supply: {type: voltage_source, value: %s}\n  gnd: {type: ground, domain: electrical}",
               "- [supply.p, piezo.elec_a]\n  - [supply.n, piezo.elec_b, gnd.p]"),
    "short": ("gnd: {type: ground, domain: electrical}", "- [piezo.elec_a, piezo.elec_b, gnd.p]"),
    "open": ("gnd: {type: ground, domain: electrical}", "- [piezo.elec_b, gnd.p]"),
}
TIP = {  # mechanical termination of the tip
    "free": ("", ""),
    "held": ("clamp: {type: ground, domain: translational}", "- [piezo.mech_b, clamp.p]"),
    "force": ("pull: {type: force_source, value: %s}", "- [pull.p, piezo.mech_b]"),
    "mass": ("load: {type: mass, m: %s}\n  pull: {type: force_source, value: %s}",
             "- [piezo.mech_b, load.a]\n  - [load.b, pull.p]"),
}


def piezo_scene(kind="element", n=1, elec="source", tip="free", u="U", f="F", m=M_TIP, r=R_EL, load=0.1,
                k=K_P, delta=DELTA_P, c=C_P, t_end=1e-6, dt=1e-8):
    """A scene: base on the ground, the given electrical side and tip termination."""
    typ = "piezo_element" if kind == "element" else f"piezo_stack, n: {n}"
    e_el, e_conn = ELEC[elec]
    t_el, t_conn = TIP[tip]
    e_el = e_el % u if "%s" in e_el else e_el
    t_el = t_el % ((load, f) if tip == "mass" else f) if "%s" in t_el else t_el
    return f"""
name: piezo_test
parameters: {{U: {U}, F: {F}}}
elements:
  piezo: {{type: {typ}, k_P: {k}, delta_P: {delta}, C_P: {c}, m: {m}, R: {r}}}
  base: {{type: ground, domain: translational}}
  {e_el}
  {t_el}
connections:
  - [base.p, piezo.mech_a]
  {e_conn}
  {t_conn}
outputs: [piezo.stroke, piezo.force, piezo.charge, piezo.voltage, piezo.current]
simulate: {{t_end: {t_end:.9e}, dt_out: {dt:.9e}, rtol: 1.0e-10, atol: 1.0e-20}}
"""


def equilibrium(text, t=1.0):
    """Static solution of the compiled (linear) model: the outputs at ``rhs(t, x) = A·x + b = 0``.

    Linear invariants of the motion (``L·A = 0``: the extension of a clamped stack, the total
    charge of an open one) keep their initial values ``L·x = L·x0``.  Rows and columns are scaled
    first, because piezo states and rates span twenty orders of magnitude.
    """
    sc = scene(text)
    model = pipeline.model(sc)
    x0 = np.asarray(model.x0, dtype=float)
    if x0.size == 0:
        return dict(zip(sc.outputs, model.outputs(t, x0)))
    A = np.asarray(model.jac(t, x0), dtype=float)
    b = np.asarray(model.rhs(t, np.zeros_like(x0)), dtype=float)
    row, col = np.ones(len(x0)), np.ones(len(x0))
    for _ in range(8):                                   # equilibrate D·A·E
        S = np.abs(row[:, None] * A * col[None, :])
        row /= np.where(S.max(axis=1) > 0, S.max(axis=1), 1.0)
        S = np.abs(row[:, None] * A * col[None, :])
        col /= np.where(S.max(axis=0) > 0, S.max(axis=0), 1.0)
    As = row[:, None] * A * col[None, :]
    Uv, sv, _ = np.linalg.svd(As)
    rank = int(np.sum(sv > 1e-10 * sv.max()))
    Ls = Uv[:, rank:].T                                   # Ls·As = 0  ->  (Ls·D)·A = 0
    assert np.allclose(Ls @ (row * b), 0, atol=1e-9 * np.abs(row * b).max()), "no equilibrium"
    Le = (Ls * row) * col[None, :]                        # invariants in the scaled variables y = x/col
    norm = np.linalg.norm(Le, axis=1, keepdims=True)
    lhs = np.vstack([As, Le / norm])
    rhs = np.concatenate([-row * b, ((Ls * row) @ x0) / norm[:, 0]])
    y = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    x = col * y
    assert np.allclose(row * model.rhs(t, x), 0, atol=1e-9 * np.abs(row * b).max())
    return dict(zip(sc.outputs, model.outputs(t, x)))


KINDS = [("element", 1), ("stack", 4)]


def close(a, b, rel=1e-9, scale=None):
    return abs(a - b) <= rel * (scale if scale is not None else abs(b))


@pytest.mark.parametrize("kind,n", KINDS)
def test_free_stroke(kind, n):
    """Free stroke: T = 0 in (51) gives s = n·k_P·U; (50) gives Q = n·C_P·U (free capacitance)."""
    y = equilibrium(piezo_scene(kind, n, "source", "free"))
    assert close(y["piezo.stroke"], n * K_P * U)
    assert close(y["piezo.charge"], n * C_P * U)
    assert close(y["piezo.force"], 0.0, scale=K_P * U / DELTA_P)
    assert close(y["piezo.voltage"], U)


@pytest.mark.parametrize("kind,n", KINDS)
def test_blocking_force(kind, n):
    """Held at both ends: Δs = 0 in (51) gives T = −k_P·U/delta_P (the element pushes on the
    clamp with k_P·U/delta_P, the same for a stack: n·k_P·U/(n·delta_P)); (50) then gives the
    blocked capacitance Q = n·(C_P − k_P²/delta_P)·U."""
    y = equilibrium(piezo_scene(kind, n, "source", "held"))
    assert close(-y["piezo.force"], K_P * U / DELTA_P)
    assert close(y["piezo.stroke"], 0.0, scale=K_P * U)
    assert close(y["piezo.charge"], n * C_BLOCKED * U)


@pytest.mark.parametrize("kind,n", KINDS)
def test_short_circuit_charge(kind, n):
    """Sensor, electrodes shorted (U = 0): (50) Q = n·k_P·F, (51) s = n·delta_P·F."""
    y = equilibrium(piezo_scene(kind, n, "short", "force"))
    assert close(y["piezo.charge"], n * K_P * F)
    assert close(y["piezo.stroke"], n * DELTA_P * F)
    assert close(y["piezo.force"], F)
    assert close(y["piezo.voltage"], 0.0, scale=K_P * F / C_P)


@pytest.mark.parametrize("kind,n", KINDS)
def test_open_circuit_voltage(kind, n):
    """Sensor, electrodes open (Q = 0): (50) gives U = −k_P·F/C_P (magnitude k_P·F/C_P, the same for
    a stack: n·k_P·F/(n·C_P)); (51) then gives the open-circuit compliance n·(delta_P − k_P²/C_P)."""
    y = equilibrium(piezo_scene(kind, n, "open", "force"))
    assert close(y["piezo.voltage"], -K_P * F / C_P)
    assert close(y["piezo.charge"], 0.0, scale=K_P * F)
    assert close(y["piezo.stroke"], n * DELTA_OPEN * F)


@pytest.mark.parametrize("kind,n", KINDS)
def test_reciprocity_and_superposition(kind, n):
    """Reciprocity (Weber: the same k_P in (50) and (51)): ∂Q/∂F at U = 0 equals ∂s/∂U at F = 0, both
    n·k_P, from finite differences of static solutions; with U and F together the responses add."""
    q = [equilibrium(piezo_scene(kind, n, "short", "force", f=f))["piezo.charge"] for f in (10.0, 30.0)]
    s = [equilibrium(piezo_scene(kind, n, "source", "free", u=u))["piezo.stroke"] for u in (20.0, 60.0)]
    dq_df = (q[1] - q[0]) / 20.0
    ds_du = (s[1] - s[0]) / 40.0
    assert close(dq_df, ds_du, 1e-9)
    assert close(dq_df, n * K_P, 1e-9)
    both = equilibrium(piezo_scene(kind, n, "source", "force"))
    assert close(both["piezo.stroke"], n * (K_P * U + DELTA_P * F))
    assert close(both["piezo.charge"], n * (K_P * F + C_P * U))


def _step_into_mass(kind, n, elec, m, r):
    """Force step F on a load mass M at the tip: stroke = delta_eff·F·(1 − cos ωt)."""
    M = 0.1
    res = run(piezo_scene(kind, n, elec, "mass", m=m, r=r, load=M, t_end=6e-5, dt=2e-8))
    return res, M


@pytest.mark.parametrize("elec,compliance", [("short", DELTA_P), ("open", DELTA_OPEN)])
def test_resonance_with_tip_mass(elec, compliance):
    """Element with moving mass m plus a load mass M, base fixed: ω² = 1/(delta_eff·(m + M)).
    Shorted electrodes (ideal, R = 0): delta_eff = delta_P; open: delta_P − k_P²/C_P (stiffer).
    The tip mass and the load are joined rigidly, so one of them is in derivative causality."""
    res, M = _step_into_mass("element", 1, elec, M_TIP, 0 if elec == "short" else R_EL)
    w = np.sqrt(1.0 / (compliance * (M_TIP + M)))
    expected = compliance * F * (1 - np.cos(w * res.t))
    assert np.max(np.abs(res["piezo.stroke"] - expected)) <= 1e-6 * compliance * F * 2


@pytest.mark.parametrize("elec,compliance", [("short", DELTA_P), ("open", DELTA_OPEN)])
def test_stack_resonance_with_load_mass(elec, compliance):
    """Massless stack (m = 0) under a load mass M: the n compliances are in series, so
    ω² = 1/(n·delta_eff·M); shorted and open as for one element."""
    n = 4
    res, M = _step_into_mass("stack", n, elec, 0, 0 if elec == "short" else R_EL)
    w = np.sqrt(1.0 / (n * compliance * M))
    expected = n * compliance * F * (1 - np.cos(w * res.t))
    assert np.max(np.abs(res["piezo.stroke"] - expected)) <= 1e-6 * n * compliance * F * 2


def test_stack_eigenfrequencies_match_an_independent_chain_model():
    """Stack with moving masses, shorted (R = 0), load M: the kernel's linear model has the
    eigenfrequencies of the chain base–spring–m–spring–m…–(m + M) with spring rate 1/delta_P,
    computed here independently as sqrt(eig(M⁻¹K))."""
    n, M = 5, 0.1
    sc = scene(piezo_scene("stack", n, "short", "mass", m=M_TIP, r=0, load=M))
    model = pipeline.model(sc)
    lam = np.linalg.eigvals(model.jac(0.0, model.x0))
    w_kernel = np.sort(np.abs(lam.imag[lam.imag > 0]))
    c = 1.0 / DELTA_P
    K = 2 * c * np.eye(n) - c * np.eye(n, k=1) - c * np.eye(n, k=-1)
    K[-1, -1] = c
    masses = np.full(n, M_TIP)
    masses[-1] += M
    w_chain = np.sort(np.sqrt(np.linalg.eigvals(K / masses[:, None]).real))
    assert np.allclose(w_kernel, w_chain, rtol=1e-8)


@pytest.mark.parametrize("kind,n,tip,m,cap", [
    ("element", 1, "held", M_TIP, C_BLOCKED), ("element", 1, "free", 0, C_P),
    ("stack", 3, "held", M_TIP, C_BLOCKED), ("stack", 3, "free", 0, C_P)])
def test_electrical_time_constant(kind, n, tip, m, cap):
    """Voltage step U through the electrode resistance R: Q = n·C·U·(1 − exp(−t/(R·C))).
    Mechanics blocked (held): C is the blocked capacitance C_P − k_P²/delta_P (Δs = 0 in (51),
    substituted in (50)); massless and free (T = 0): C is C_P.  In the stack every element has
    its own R, so the branches are identical and τ is that of one element."""
    tau = R_EL * cap
    res = run(piezo_scene(kind, n, "source", tip, u="U*step(t)", m=m, t_end=8 * tau, dt=tau / 50))
    t = res.t
    q = n * cap * U * (1 - np.exp(-t / tau))
    i = n * U / R_EL * np.exp(-t / tau)
    assert np.max(np.abs(res["piezo.charge"] - q)) <= 1e-7 * n * cap * U
    assert np.max(np.abs(res["piezo.current"][1:] - i[1:])) <= 1e-6 * n * U / R_EL


def test_stack_equals_lumped_element():
    """Weber Bild 38 reduced by hand: n massless elements (k_P, delta_P, C_P, R) in series/parallel
    behave exactly like one element with (n·k_P, n·delta_P, n·C_P, R/n) — same force and voltage in
    every element, strokes and charges add, n resistors in parallel.  Compared over a voltage-step
    response against a load mass."""
    n = 6
    common = dict(elec="source", tip="mass", u="U*step(t)", m=0, load=0.05, t_end=4e-5, dt=4e-8)
    stack = run(piezo_scene("stack", n, r=R_EL, **common))
    lumped = run(piezo_scene("element", 1, r=R_EL / n, k=n * K_P, delta=n * DELTA_P, c=n * C_P, **common))
    # electrical modes of 2e7-4e7 1/s die out next to a 1.8e5 rad/s load mode: DOP853 would run at its
    # stability limit (its charge came out 3.7e-6 off); auto must take the implicit method for both
    assert stack.solver == lumped.solver == "Radau", (stack.solver_reason, lumped.solver_reason)
    for out in ("piezo.stroke", "piezo.charge", "piezo.current", "piezo.force"):
        scale = np.abs(lumped[out]).max()
        assert np.max(np.abs(stack[out] - lumped[out])) <= 1e-6 * scale, out


@pytest.mark.parametrize("kind,n,r", [("element", 1, 0), ("element", 1, R_EL), ("stack", 2, 0), ("stack", 3, R_EL),
                                       ("stack", 4, 0)])
def test_open_circuit_force_present_from_the_start(kind, n, r):
    """Massless sensor, electrodes open, the force F acting from t = 0 (no ramp): no current can
    flow, so the charge stays 0 and the extension, not the charge, takes the value the constraint
    imposes at t = 0: U = −k_P·F/C_P and s = n·(delta_P − k_P²/C_P)·F at every output time, current 0.
    The analyser says which initial values it made consistent: the extensions, never a charge."""
    text = piezo_scene(kind, n, "open", "force", m=0, r=r, t_end=1e-6, dt=1e-7)
    an = check(text)
    eq = pipeline.equations(scene(text), an)
    made = [d.message for d in eq.diagnostics if d.code == "derivative_causality" and "consistent" in d.message]
    assert len(made) == 1 and ".q1 = 2.5e-09 m (given 0)" in made[0] and ".q2" not in made[0], made
    res = run(text)
    assert np.allclose(res["piezo.voltage"], -K_P * F / C_P, rtol=1e-9, atol=0)
    assert np.allclose(res["piezo.stroke"], n * DELTA_OPEN * F, rtol=1e-9, atol=0)
    assert np.max(np.abs(res["piezo.charge"])) <= 1e-9 * n * K_P * F
    assert np.max(np.abs(res["piezo.current"])) == 0.0


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_open_ideal_stack_under_a_force_step_equals_the_lumped_element(n):
    """Massless ideal stack (m = 0, R = 0), electrodes open, load mass M, force step F: the state
    choice must keep one charge integrated (their sum is what the open terminal conserves).  The
    stack behaves like one element (n·k_P, n·delta_P, n·C_P) and both like a spring of compliance
    n·(delta_P − k_P²/C_P) under M: s = n·delta_open·F·(1 − cos ωt), ω² = 1/(n·delta_open·M), and
    U = −k_P·T/C_P with the tension T = F − M·s̈ = F·(1 − cos ωt) (Q = 0 in (50))."""
    M = 0.1
    common = dict(elec="open", tip="mass", f="F*step(t)", m=0, r=0, load=M, t_end=6e-5, dt=2e-8)
    stack = run(piezo_scene("stack", n, **common))
    lumped = run(piezo_scene("element", 1, k=n * K_P, delta=n * DELTA_P, c=n * C_P, **common))
    w = np.sqrt(1.0 / (n * DELTA_OPEN * M))
    t = stack.t
    closed = {"piezo.stroke": n * DELTA_OPEN * F * (1 - np.cos(w * t)),
              "piezo.voltage": -K_P * F * (1 - np.cos(w * t)) / C_P}
    for out, expected in closed.items():
        scale = np.abs(expected).max()
        assert np.max(np.abs(stack[out] - expected)) <= 1e-6 * scale, out
        assert np.max(np.abs(stack[out] - lumped[out])) <= 1e-6 * scale, out
    assert np.max(np.abs(stack["piezo.charge"])) <= 1e-9 * n * K_P * F


@pytest.mark.parametrize("m,r,tip,states", [
    (M_TIP, R_EL, "free", 12),        # 4 elements × (extension, charge, tip momentum)
    (0, R_EL, "mass", 4 + 2),         # series compliances share one force: n-1 extensions resolved
    (M_TIP, 0, "mass", 4 + 4),        # parallel fields share one voltage: n charges resolved; tip + load
    (0, 0, "free", 0),                # nothing left: statics only (all fields resolved)
])
def test_stack_is_well_posed(m, r, tip, states):
    """4-element stack: with masses and resistances every storage is independent; a massless
    series chain or an ideal parallel connection puts storage in derivative causality, which the
    analyser resolves (expected state counts from counting independent storages)."""
    an = check(piezo_scene("stack", 4, "source", tip, u="U*(1 - exp(-t/1e-6))", m=m, r=r))
    assert an.ok, an.report()
    assert len(an.states) == states


def test_piezo_quantities_and_catalogue():
    """Every documented parameter has an SI unit, and the quantities exist on both types."""
    from multipole import catalogue
    for name in ("piezo_element", "piezo_stack"):
        et = catalogue()[name]
        assert all(p.unit for p in et.params if p.name != "n")
        assert set(et.ports) == {"mech_a", "mech_b", "elec_a", "elec_b"}
        assert {"stroke", "force", "charge", "voltage", "current"} <= set(et.quantities)


@pytest.mark.parametrize("n", ["2.5", "0", "nn"])
def test_stack_refuses_a_count_that_is_not_a_whole_number(n):
    """n must be a literal whole number >= 1; the netlist error names the element."""
    from multipole.errors import NetlistError
    text = piezo_scene("stack", 1).replace("n: 1,", f"n: {n},").replace("{U: ", "{nn: 3, U: ")
    with pytest.raises(NetlistError) as err:
        scene(text)
    assert err.value.code == "bad_value" and "element 'piezo'" in str(err.value)
