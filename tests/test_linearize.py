"""Linearisation (multipole/linearize.py) of every well-posed scene, with or without closed-form loops.

Expected values: the symbolic path (the substituted ODE differentiated by sympy) where every loop has
a closed form; closed-form eigenfrequencies of drive trains with rigid couplings (effective inertias
referred through the ratio), where it has none; central differences of the compiled right-hand side
for a nonlinear loop.
"""
from pathlib import Path

import numpy as np
import pytest

from helpers import scene
from multipole import pipeline
from multipole.errors import IllPosedError
from multipole.linearize import linearize
from multipole.netlist import load

ROOT = Path(__file__).resolve().parents[1]


def _equations(path_or_text):
    sc = load(ROOT / path_or_text) if str(path_or_text).endswith(".yaml") else scene(path_or_text)
    return sc, pipeline.equations(sc)


def _frequencies(lin):
    """Natural frequencies [rad/s] of the oscillating modes (positive imaginary parts)."""
    lam = np.linalg.eigvals(lin.A)
    return np.sort(lam.imag[lam.imag > 0])


@pytest.mark.parametrize("path", ["diagrams/rlc_series.yaml", "diagrams/hard/two_mass_oscillator.yaml",
                                  "diagrams/weber/piezo_actuator.yaml", "diagrams/weber/power_split_elastic.yaml",
                                  "diagrams/weber/dc_motor_gear_load.yaml", "diagrams/hard/slack_rope.yaml"])
def test_numeric_path_equals_the_symbolic_one(path):
    """Where every loop has a closed form both paths run: the same A, B, C, D to rounding (the
    slack rope is nonlinear, linearised about its initial state)."""
    sc, eq = _equations(path)
    outputs = sc.outputs or eq.state_names
    num = linearize(eq, outputs)
    sym = linearize(eq, outputs, method="symbolic")
    for name in "ABCD":
        a, b = getattr(num, name), getattr(sym, name)
        assert a.shape == b.shape
        if b.size:
            assert np.max(np.abs(a - b)) <= 1e-9 * max(np.abs(b).max(), 1e-300), name


GEARED_SPRING = """
name: geared_spring
parameters: {J1: 2.0e-3, Jw: 5.0e-3, J2: 0.04, c: 800.0}
elements:
  drive:  {type: torque_source, value: 1.0}
  pinion: {type: inertia, J: J1}
  MESH
  wheel:  {type: inertia, J: Jw}
  shaft:  {type: spring, c: c}
  load:   {type: inertia, J: J2}
connections:
  - [drive.p, pinion.a]
  - [pinion.b, mesh.IN]
  - [mesh.OUT, wheel.a]
  - [wheel.b, shaft.a]
  - [shaft.b, load.a]
outputs: [load.omega, shaft.force]
"""


@pytest.mark.parametrize("mesh,ratio", [
    ("mesh: {type: spur_stage, r1: 0.02, r2: 0.05}", 0.05 / 0.02),            # ideal spur: |i| = r2/r1
    ("mesh: {type: planetary, z_sun: 20, z_ring: 70}", 1 + 70 / 20),          # ring held: 1 + z_r/z_s
])
def test_rigid_gear_between_inertias_and_a_spring_rings_at_the_closed_form(mesh, ratio):
    """Pinion (J1) rigidly geared to the wheel (Jw), then a shaft spring c to a load J2: one
    oscillating mode with ω² = c·(1/J1' + 1/J2), J1' = Jw + J1·i² the inertias referred to the
    wheel shaft, plus the rigid-body mode (eigenvalues 0).  The rigid mesh puts one inertia in
    derivative causality; its loop's constant couplings are eliminated in closed form, so the symbolic
    path linearises these scenes as well as the numeric one."""
    J1, Jw, J2, c = 2.0e-3, 5.0e-3, 0.04, 800.0
    text = GEARED_SPRING.replace("MESH", mesh)
    if "planetary" in mesh:       # sun in, carrier out, ring held
        text = text.replace("mesh.IN", "mesh.sun").replace("mesh.OUT", "mesh.carrier")
        text = text.replace("load:   {type: inertia, J: J2}",
                            "load:   {type: inertia, J: J2}\n  housing: {type: ground}")
        text = text.replace("  - [shaft.b, load.a]", "  - [shaft.b, load.a]\n  - [mesh.ring, housing.p]")
    else:
        text = text.replace("mesh.IN", "mesh.a").replace("mesh.OUT", "mesh.b")
    sc, eq = _equations(text)
    lin = linearize(eq, sc.outputs)
    w = np.sqrt(c * (1 / (Jw + J1 * ratio**2) + 1 / J2))
    assert np.allclose(_frequencies(lin), [w], rtol=1e-9)
    assert np.allclose(_frequencies(linearize(eq, sc.outputs, method="symbolic")), [w], rtol=1e-9)
    lam = np.linalg.eigvals(lin.A)
    assert np.sum(np.abs(lam) <= 1e-9 * w) == len(lam) - 2        # the rest is the rigid-body mode
    modes = lin.modes()                   # reported without round-off: rigid-body 0 Hz, no damping
    assert [m[1] for m in modes[:-2]] == [0.0] * (len(lam) - 2)
    assert [m[2] for m in modes[-2:]] == [0.0, 0.0]
    assert modes[-1][1] == pytest.approx(w / (2 * np.pi), rel=1e-9)


def test_many_layer_stack_rings_at_the_series_compliance():
    """Massless ideal stack of 10 discs (20 was checked by hand the same way; its check alone takes
    ~15 s), driven by a voltage source, under a load mass M: the discs' compliances add,
    ω² = 1/(n·delta_P·M) (shorted through the source, so delta_P).  Many storages in derivative
    causality give a large loop of constant couplings, eliminated in closed form: both paths linearise it."""
    n, delta, M = 10, 1.0e-10, 0.1
    text = f"""
    name: stack20
    elements:
      piezo: {{type: piezo_stack, n: {n}, k_P: 5.0e-10, delta_P: {delta}, C_P: 5.0e-9}}
      base:  {{type: ground, domain: translational}}
      amp:   {{type: voltage_source, value: 100.0}}
      gnd:   {{type: ground, domain: electrical}}
      load:  {{type: mass, m: {M}}}
    connections:
      - [base.p, piezo.mech_a]
      - [amp.p, piezo.elec_a]
      - [amp.n, piezo.elec_b, gnd.p]
      - [piezo.mech_b, load.a]
    outputs: [piezo.stroke, load.v]
    """
    sc, eq = _equations(text)
    lin = linearize(eq, sc.outputs)
    assert np.allclose(_frequencies(lin), [1 / np.sqrt(n * delta * M)], rtol=1e-9)
    assert np.allclose(_frequencies(linearize(eq, sc.outputs, method="symbolic")), [1 / np.sqrt(n * delta * M)],
                       rtol=1e-9)
    # the input: a volt more on the stack moves the static stroke by n·k_P; B and C carry it
    static = -lin.C @ np.linalg.pinv(lin.A) @ lin.B + lin.D
    assert static[0, lin.inputs.index("amp.u")] == pytest.approx(n * 5.0e-10, rel=1e-9)


def test_nonlinear_loop_matches_central_differences_of_the_compiled_model():
    """A scene iterated by Newton's method: A equals the central differences of the compiled
    right-hand side (an independent evaluation path) to the accuracy of the differences."""
    sc, eq = _equations("diagrams/hard/nonlinear_loop.yaml")
    assert any(b.kind == "newton" for b in eq.blocks)
    lin = linearize(eq, sc.outputs or eq.state_names)
    model = pipeline.model(sc)
    x0 = np.asarray(model.x0, dtype=float)
    A = np.zeros((len(x0), len(x0)))
    for k in range(len(x0)):
        h = 1e-6 * max(abs(x0[k]), 1.0)
        e = np.zeros_like(x0)
        e[k] = h
        A[:, k] = (np.asarray(model.rhs(0.0, x0 + e)) - np.asarray(model.rhs(0.0, x0 - e))) / (2 * h)
    assert np.allclose(lin.A, A, rtol=1e-6, atol=1e-6 * np.abs(A).max())


@pytest.mark.parametrize("path", ["diagrams/weber/spur_ideal.yaml", "diagrams/weber/two_stage.yaml"])
def test_cli_linearizes_the_scenes_it_used_to_refuse(path, capsys):
    from multipole.cli import main
    assert main(["linearize", str(ROOT / path)]) == 0
    assert "Modes (eigenvalue" in capsys.readouterr().out


def test_symbolic_path_refuses_a_loop_left_numeric():
    """A torque-driven four-bar keeps state-dependent loop cores of 4 and 5 unknowns, solved
    numerically: the symbolic path refuses with not_symbolic, the numeric one linearises (the crank
    angle and momentum: a pendulum-like pair of eigenvalues under gravity, finite)."""
    text = """
    name: fourbar
    elements:
      src: {type: torque_source, value: 0.0}
      crank: {type: DAN, l: 0.2, phi0: 0.3, m: 1.0, J: 0.01}
      rocker: {type: DDD, l1: 0.6, l2: 0.5, K: 1, m1: 2.0, J1: 0.06, m2: 1.5, J2: 0.03, x2: 0.7}
    connections:
      - [src.p, crank.drive]
      - [crank.b, rocker.a1]
    outputs: [crank.phi]
    """
    sc, eq = _equations(text)
    assert any(b.solution is None for b in eq.blocks)
    with pytest.raises(IllPosedError) as exc:
        linearize(eq, sc.outputs, method="symbolic")
    assert exc.value.code == "not_symbolic"
    assert np.all(np.isfinite(linearize(eq, sc.outputs).A))
