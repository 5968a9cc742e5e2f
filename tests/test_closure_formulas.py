"""Position closures solved by formula (multipole.network.ClosedForm; issue 12, per-call cost).

DDD and DDS declare their closure's solution: the generated code evaluates the formula, picks the
branch the integrated values are on, continues each angle to the turn of its integrated value and
reads the angle's cosine and sine from the formula.  Expected values: the four-bar's circle
intersection (tests/helpers.py) and the slider-crank's pin height, written independently here; the
branch from the assembly mode K at t = 0; the residuals of the closure itself at the solved values.
"""
import dataclasses
import importlib.util
import math
import re
from pathlib import Path

import numpy as np
import pytest

import multipole as mp
from multipole import codegen, pipeline
from multipole.errors import ModelError, NewtonError

from helpers import circle_intersection

needs_numba = pytest.mark.skipif(importlib.util.find_spec("numba") is None, reason="numba not installed")

L, L1, L2, BX = 0.2, 0.6, 0.5, 0.7          # four-bar: crank, coupler, rocker, frame pivot x [m]
R, LR, E = 0.1, 0.35, 0.02                  # slider-crank: crank, rod, pin height over the slide [m]


def fourbar(k=1, l1=L1, l2=L2, outputs="[crank.phi, rocker.phi1, rocker.phi2]"):
    return mp.loads(f"""
name: fourbar_closed
elements:
  src: {{type: torque_source, value: 0.8}}
  crank: {{type: DAN, l: {L}, phi0: 0.3, m: 1.0, J: 0.01}}
  rocker: {{type: DDD, l1: {l1}, l2: {l2}, K: {k}, m1: 2.0, J1: 0.06, m2: 1.5, J2: 0.03, x2: {BX}}}
connections:
  - [src.p, crank.drive]
  - [crank.b, rocker.a1]
outputs: {outputs}
simulate: {{t_end: 2.0, dt_out: 0.01}}
""", "fourbar.yaml")


def slider_crank(k=1):
    return mp.loads(f"""
name: slider_crank_closed
elements:
  src: {{type: torque_source, value: 0.5}}
  crank: {{type: DAN, l: {R}, phi0: 0.3, m: 0.5, J: 0.002}}
  rod: {{type: DDS, l: {LR}, v: {E}, K: {k}, mL: 0.8, JL: 0.01, mS: 1.2, JS: 0.001}}
connections:
  - [src.p, crank.drive]
  - [crank.b, rod.a1]
outputs: [crank.phi, rod.phi, rod.x]
simulate: {{t_end: 2.0, dt_out: 0.01}}
""", "slider.yaml")


def solved(model, x):
    return dict(zip(model.value_names, model.values(0.0, np.array(x, dtype=float))))


def fourbar_lower(theta):
    """The four-bar's other assembly (K = -1): P mirrored across the line from the crank pin to the
    rocker pivot, written out independently of the upper one."""
    ax, ay = L * math.cos(theta), L * math.sin(theta)
    dx, dy = BX - ax, -ay
    d = math.hypot(dx, dy)
    along = (L1 * L1 - L2 * L2 + d * d) / (2 * d)
    across = -math.sqrt(L1 * L1 - along * along)
    px, py = ax + along * dx / d - across * dy / d, ay + along * dy / d + across * dx / d
    return math.atan2(py - ay, px - ax), math.atan2(py, px - BX)


@pytest.mark.parametrize("theta", [0.3, 1.9, -2.5, 3.1])
def test_fourbar_formula_equals_the_circle_intersection_from_far_starts(theta):
    """Integrated angles 0.4 rad off the closure (far beyond a Newton step's reach in one
    iteration): the formula gives the circle intersection to rounding, with no Newton iteration."""
    model = pipeline.model(fourbar())
    exact = circle_intersection(theta)
    model.reset_stats()
    v = solved(model, [theta, 0.0, exact[0] + 0.4, exact[1] - 0.4])
    assert abs(v["rocker.L1.K.q3*"] - exact[0]) < 1e-13
    assert abs(v["rocker.L2.K.q3*"] - exact[1]) < 1e-13
    assert model.stats["newton_solves"] == 0 and "_newton" not in model.source


@pytest.mark.parametrize("turns", [-3, 1, 40])
def test_angles_continue_the_turn_of_their_integrated_values(turns):
    """Integrated angles some whole turns on (a crank that went round): the solved angles are the
    circle intersection plus the same turns, never wrapped back to (-pi, pi]."""
    model = pipeline.model(fourbar())
    theta = 2.0
    exact = circle_intersection(theta)
    shift = 2 * math.pi * turns
    v = solved(model, [theta, 0.0, exact[0] + shift + 0.1, exact[1] + shift - 0.1])
    assert abs(v["rocker.L1.K.q3*"] - (exact[0] + shift)) < 1e-12 * (1 + abs(shift))
    assert abs(v["rocker.L2.K.q3*"] - (exact[1] + shift)) < 1e-12 * (1 + abs(shift))


def test_the_branch_follows_the_integrated_values():
    """Assembled with K = -1 the four-bar is on the lower intersection, and stays there at other crank
    angles; integrated values near the upper one pick the upper one (the side they are on)."""
    model = pipeline.model(fourbar(k=-1))
    x0 = np.array(model.x0, dtype=float)
    lower0 = fourbar_lower(0.3)
    assert abs(x0[2] - lower0[0]) < 1e-12 and abs(x0[3] - lower0[1]) < 1e-12
    for theta in (0.3, 1.0, -2.0):
        lower, upper = fourbar_lower(theta), circle_intersection(theta)
        v = solved(model, [theta, 0.0, lower[0] + 0.05, lower[1]])
        assert abs(v["rocker.L1.K.q3*"] - lower[0]) < 1e-13 and abs(v["rocker.L2.K.q3*"] - lower[1]) < 1e-13
        v = solved(model, [theta, 0.0, upper[0] - 0.05, upper[1]])
        assert abs(v["rocker.L1.K.q3*"] - upper[0]) < 1e-13 and abs(v["rocker.L2.K.q3*"] - upper[1]) < 1e-13


@pytest.mark.parametrize("k", [1, -1])
def test_slider_crank_formula_against_the_pin_height(k):
    """The rod angle from sin(phi) = (R sin(theta) - E) / LR, the travel x = R cos(theta) - LR
    cos(phi); K = +1: P beyond the crank pin (cos(phi) < 0), K = -1: the mirror assembly."""
    model = pipeline.model(slider_crank(k))
    for theta in (0.3, 2.0, -1.2):
        sin_phi = (R * math.sin(theta) - E) / LR
        phi = math.pi - math.asin(sin_phi) if k == 1 else math.asin(sin_phi)
        x = R * math.cos(theta) - LR * math.cos(phi)
        v = solved(model, [theta, 0.0, phi + 0.3, x + 0.02 * k])
        assert abs(v["rod.L.K.q3*"] - phi) < 1e-13 and abs(v["rod.S.K.q4*"] - x) < 1e-13


@pytest.mark.parametrize("backend", ["numpy", pytest.param("numba", marks=needs_numba)])
@pytest.mark.parametrize("make", [fourbar, slider_crank], ids=["four-bar", "slider-crank"])
def test_runs_hold_the_closure_without_newton(make, backend):
    """A 2 s run on either backend: no Newton solve at all, and the outputs on the closure (the
    four-bar's dependent angles equal the circle intersection of the crank angle to 1e-12; the
    slider-crank's travel equals R cos(theta) - LR cos(phi) and its pin height closes)."""
    res = pipeline.run(make(), rtol=1e-8, atol=1e-10, backend=backend, progress=False)
    assert res.stats["newton_solves"] == 0 and res.stats["nfev"] > 100
    if make is fourbar:
        exact = np.array([circle_intersection(th) for th in res["crank.phi"]])
        assert np.abs(res["rocker.phi1"] - exact[:, 0]).max() < 1e-12
        assert np.abs(res["rocker.phi2"] - exact[:, 1]).max() < 1e-12
    else:
        th, phi, x = res["crank.phi"], res["rod.phi"], res["rod.x"]
        assert np.abs(R * np.sin(th) - LR * np.sin(phi) - E).max() < 1e-13
        assert np.abs(R * np.cos(th) - LR * np.cos(phi) - x).max() < 1e-13


@needs_numba
def test_both_backends_print_the_formula_alike():
    """The numba backend's right-hand side and Jacobian at a state off the closure equal the numpy
    backend's (same formula, rounding only)."""
    from multipole.backends import numba_backend
    sc = slider_crank()
    model = pipeline.model(sc)
    eq, outs, _ = pipeline.pruned(sc)
    compiled = numba_backend.run.compile(eq, outs)
    x = np.array(model.x0, dtype=float) + [0.2, 0.01, 0.05, -0.01]
    rhs = compiled._call(compiled.module.rhs, 0.0, x, (len(x),), compiled.w0.copy())
    np.testing.assert_allclose(model.rhs(0.0, x), rhs, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(model.jac(0.0, x), compiled.jac(0.0, x), rtol=1e-9, atol=1e-12)


def test_the_jacobian_of_a_formula_closure_matches_differences():
    """The generated Jacobian (implicit differentiation of the residuals) against central differences
    of the right-hand side, which now runs through the formula."""
    model = pipeline.model(fourbar())
    x = np.array(model.x0, dtype=float) + [0.7, 0.02, 0.0, 0.0]
    exact = circle_intersection(x[0])
    x[2:] = exact                         # on the closure: the states' columns are the formula's
    J = model.jac(0.0, x)
    for j in (0, 1):
        h = 1e-6
        e = np.zeros(4)
        e[j] = h
        fd = (np.asarray(model.rhs(0.0, x + e)) - np.asarray(model.rhs(0.0, x - e))) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-6, atol=1e-7)


def test_a_closure_that_cannot_assemble_is_closure_unreachable():
    """Coupler and rocker of 0.4 m cannot reach across 0.9 m at theta = pi: the formula's radicand is
    negative, the numpy backend raises closure_unreachable naming the loop and the radicand."""
    model = pipeline.model(fourbar(l1=0.4, l2=0.4))
    x = np.array(model.x0, dtype=float)
    x[0] = math.pi
    with pytest.raises(NewtonError) as exc:
        model.rhs(0.0, x)
    assert exc.value.code == "closure_unreachable"
    # 4 |P1P2|^2 l1^2 - (l1^2 - l2^2 + |P1P2|^2)^2 at |P1P2| = 0.9 m
    radicand = 4 * 0.81 * 0.16 - 0.81 ** 2
    shown = re.search(r"radicand of its formula is (\S+),", exc.value.message)
    assert shown and math.isclose(float(shown.group(1)), radicand, rel_tol=5e-3)     # printed to 3 digits


def test_a_closed_form_of_the_wrong_shape_is_a_model_error():
    """A branch with fewer entries than the closure has states: bad_closed_form, naming the element."""
    from elements import linkage
    net = linkage.DDD(l1=0.6, l2=0.5, x2=0.7)
    closure = net.closures[0]
    closure.closed_form = dataclasses.replace(closure.closed_form,
                                              branches=[b[:1] for b in closure.closed_form.branches])
    with pytest.raises(ModelError) as exc:
        mp.flatten(net)
    assert exc.value.code == "bad_closed_form"
    assert "2 entries" in exc.value.message


def test_generated_formula_reads_a_runtime_parameter():
    """The coupler length as a runtime parameter: the formula reads it from _P, and after
    set_parameters the solved angles are the circle intersection of the new length."""
    eq = pipeline.equations(fourbar())
    l1 = next(p for p in eq.params if str(p) == "rocker.l1")
    model = codegen.compile_model(eq, ["crank.phi"], runtime=[l1])
    model.set_parameters([0.65])
    exact = circle_intersection(1.1, l1=0.65)
    v = solved(model, [1.1, 0.0, exact[0] + 0.2, exact[1] - 0.2])
    assert abs(v["rocker.L1.K.q3*"] - exact[0]) < 1e-13 and abs(v["rocker.L2.K.q3*"] - exact[1]) < 1e-13


LINKAGE_SCENES = sorted((Path(__file__).resolve().parents[1] / "diagrams" / "linkages").glob("*.yaml"))


@pytest.mark.parametrize("path", LINKAGE_SCENES, ids=lambda p: p.stem)
def test_every_dyad_formula_is_the_newton_root_of_its_residuals(path):
    """Every scene of diagrams/linkages (DDD, DDS, DSD, SSD, SDS among them): at states near the
    start (integrated values 1e-3 off, crank moved), the closures' values by formula equal the root
    Newton's method finds for the same residuals (the formula taken out), to 1e-10, and the formula
    model does no Newton solve."""
    sc = mp.load(path)
    eq, outs, _ = pipeline.pruned(sc, prune=False)
    assert any(b.closed_form is not None for b in eq.blocks)
    formula = codegen.compile_model(eq, outs)
    newton = codegen.compile_model(dataclasses.replace(eq, blocks=[dataclasses.replace(b, closed_form=None)
                                                                    for b in eq.blocks]), outs)
    rng = np.random.default_rng(3)
    closed = [i for i, n in enumerate(formula.value_names) if n.endswith("*")]
    for _ in range(5):
        x = np.array(formula.x0, dtype=float) + rng.normal(scale=1e-3, size=len(formula.x0))
        a, b = np.asarray(formula.values(0.0, x))[closed], np.asarray(newton.values(0.0, x))[closed]
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10)
    assert formula.stats["newton_solves"] == 0 and newton.stats["newton_solves"] > 0
