"""Displacement-modulated transformer: a crank driving a mass conserves energy."""
import numpy as np

from helpers import check, run

YOKE = """
name: scotch_yoke
parameters: {r: 0.05, J: 0.02, m: 1.5, k: 400.0, w0: 12.0}
elements:
  flywheel: {type: inertia, J: J, omega0: w0}
  yoke:     {type: TF, ratio: "r*cos(q)", domain_a: translational, domain_b: rotational}
  slider:   {type: mass, m: m}
  spring:   {type: spring, c: k, domain: translational}
  frame:    {type: ground, domain: translational}
connections:
  - [flywheel.b, yoke.b]
  - [yoke.a, slider.a]
  - [slider.b, spring.a]
  - [spring.b, frame.p]
outputs: [flywheel.omega, slider.v, spring.deflection, yoke.q]
simulate: {t_end: 60.0, dt_out: 0.01, solver: DOP853, rtol: 1.0e-12, atol: 1.0e-14}
"""


def test_crank_keeps_the_crank_as_state_and_the_slider_in_derivative_causality():
    an = check(YOKE)
    assert an.ok
    assert [s.name for s in an.demoted] == ["slider.p"]       # the well-conditioned choice
    assert "flywheel.p" in [s.name for s in an.states]


def test_crank_driving_a_mass_conserves_energy_over_100_periods():
    r, J, m, k, w0 = 0.05, 0.02, 1.5, 400.0, 12.0
    res = run(YOKE)
    w, v, x, q = res["flywheel.omega"], res["slider.v"], res["spring.deflection"], res["yoke.q"]
    assert q[-1] / (2 * np.pi) >= 100                          # at least 100 crank revolutions
    assert np.allclose(v, r * np.cos(q) * w, rtol=1e-9, atol=1e-9)   # the kinematics of the yoke
    assert np.allclose(x, r * np.sin(q), atol=1e-8)
    energy = 0.5 * J * w**2 + 0.5 * m * v**2 + 0.5 * k * x**2
    assert np.max(np.abs(energy - energy[0])) / energy[0] <= 1e-8


def test_large_expressions_are_printed_with_common_subexpressions_once():
    """The slider-crank's effective inertia is a long expression in sin, cos and a square root of the
    crank angle; after common-subexpression elimination each is evaluated once per call of rhs."""
    from pathlib import Path

    from multipole import load, pipeline
    scene = load(Path(__file__).resolve().parents[1] / "diagrams" / "hard" / "slider_crank.yaml")
    source = pipeline.model(scene).source
    rhs = source.split("def rhs(t, x):")[1].split("\ndef ")[0]
    assert rhs.count("math.sin(") == 1 and rhs.count("math.cos(") == 1 and rhs.count("math.sqrt(") == 1
