"""The 8-link mechanism's check and model build (issue 12: "check + compile of the 8-link mechanism,
target <= 2 s"; docs/performance.md "Linkages") do each piece of set-up work once and without the
costly general routes: counts of that work, so that a regression fails (no time is asserted), and
the shortcuts' results against independent computations."""
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import multipole as mp
from multipole import equations as equations_module
from multipole import pipeline
from multipole.equations import block_values
from multipole.stages import derivative, numeric_function

ROOT = Path(__file__).resolve().parents[1]
EIGHT_LINK = ROOT / "diagrams" / "linkages" / "eight_link.yaml"


@pytest.fixture(scope="module")
def counted():
    """``(counts of sympy's diff, cancel and lambdify during check + model build, equations, model)``
    of the 8-link mechanism (a fresh scene object: nothing remembered from other tests)."""
    counts = {"diff": 0, "cancel": 0, "lambdify": 0}
    mp_ = pytest.MonkeyPatch()
    for name in counts:
        real = getattr(sp, name)

        def counting(*args, _real=real, _name=name, **kw):
            counts[_name] += 1
            return _real(*args, **kw)
        mp_.setattr(sp, name, counting)
    try:
        sc = mp.load(EIGHT_LINK)
        analysis = pipeline.check(sc)
        model = pipeline.model(sc, prune=False)
    finally:
        mp_.undo()
    return counts, analysis.assembled, model


def test_check_and_build_cancel_nothing_and_differentiate_by_the_rules(counted):
    """No ``cancel`` (6 of them, a third of the check, before the loops whose matrix holds only
    parameters went by Cramer's rule too) and sympy's ``diff`` only where the element library calls
    it while the elements are built (104 of them in elements/linkage_guides.py); the analysis, the
    differentiated constraints and the generated Jacobian take every derivative by
    :func:`multipole.stages.derivative` (before: about 550 more calls of ``diff``)."""
    counts, _eq, _model = counted
    assert counts["cancel"] == 0
    assert counts["diff"] <= 110
    assert counts["lambdify"] <= 16          # two sampled Jacobians, the closures' residuals and Jacobians at t = 0


def test_check_imports_neither_scipy_optimize_nor_numpy_testing():
    """The closures at t = 0 are solved without scipy (its import was a quarter of the check) and
    the sampled Jacobians are evaluated in numpy's own namespace (``lambdify(..., "numpy")`` runs
    ``from numpy import *``, which loads numpy.testing, f2py and unittest)."""
    code = ("import sys, multipole as mp\nfrom multipole import pipeline\n"
            f"sc = mp.load({str(EIGHT_LINK)!r})\nassert pipeline.check(sc).ok\npipeline.model(sc)\n"
            "print(sorted(m for m in ('scipy.optimize', 'numpy.testing') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT,
                         env={"MULTIPOLE_CACHE": "off", "PATH": "/usr/bin:/bin"})
    assert out.stdout.strip() == "[]"


def test_each_closure_is_solved_by_newton_at_most_twice_at_the_start(monkeypatch):
    """Three position closures; the start check and the consistent start values solve each once
    (the closures' Newton from the integrated values, no scipy ``fsolve``)."""
    calls = [0]
    real = equations_module._closure_newton

    def counting(*args, **kw):
        calls[0] += 1
        return real(*args, **kw)
    monkeypatch.setattr(equations_module, "_closure_newton", counting)
    analysis = pipeline.check(mp.load(EIGHT_LINK))
    assert analysis.ok
    closures = [b for b in analysis.assembled.blocks if b.start is not None]
    assert len(closures) == 3
    assert 3 <= calls[0] <= 6


def test_symbolic_loop_solutions_solve_their_loops(counted):
    """Every linear loop solved symbolically (Cramer's rule) satisfies ``A z = b`` at sampled
    states: the solution against numpy's solve of the same matrix (an independent computation)."""
    _counts, eq, _model = counted
    x0 = np.array(eq.initial_values(), dtype=float)
    rng = np.random.default_rng(3)
    loops = [b for b in eq.blocks if b.kind == "linear" and b.solution is not None and b.matrix is not None]
    assert len(loops) == 9
    for k in range(2):
        x = x0 + 1e-2 * rng.normal(size=x0.size)
        values, _ = block_values(eq, 0.1 * k, x)
        for b in loops:
            A = np.array(b.matrix.xreplace(values).evalf(), dtype=float)
            rhs = np.array(b.rhs.xreplace(values).evalf(), dtype=float).ravel()
            expected = np.linalg.solve(A, rhs)
            got = np.array([values[v] for v in b.variables])
            scale = np.abs(np.linalg.inv(A)) @ (np.abs(A) @ np.abs(expected) + np.abs(rhs))
            # rounding of the two routes, relative to the largest term of the loop
            assert np.all(np.abs(got - expected) <= 1e-12 * scale.max()), b.variables


def test_generated_model_matches_the_equations_solved_numerically(counted):
    """The generated right-hand side at sampled states against the equations evaluated with every
    linear loop solved numerically from its matrix (no symbolic solution, no generated code) and
    the closures by :func:`multipole.equations._closure_newton`: the same equations."""
    _counts, eq, model = counted
    numeric = [replace(b, solution=None) if b.kind == "linear" and b.matrix is not None else b for b in eq.blocks]
    plain = replace(eq, blocks=numeric)
    assert model.state_names == eq.state_names
    x0 = np.array(model.x0, dtype=float)
    rng = np.random.default_rng(5)
    for k in range(2):
        x = x0 + 1e-2 * rng.normal(size=x0.size)
        t = 0.3 * k
        values, mags = block_values(plain, t, x, eq.derivatives, magnitudes=True)
        expected = np.array([values[d] for d in eq.derivatives])
        size = np.array([mags[d] for d in eq.derivatives])
        got = np.asarray(model.rhs(t, x), dtype=float)
        # both solve the closures to the step tolerance 1e-12 (rad, m): the derivatives agree to that
        # relative to the sizes of the terms they are computed from
        assert np.all(np.abs(got - expected) <= 1e-9 * (size + 1e-12)), np.abs(got - expected) / (size + 1e-12)


def test_closure_newton_roots_and_a_dead_centre_start():
    """A root from a start (sqrt 2 of z**2 - 2, and the circle-line intersection of a 2-unknown
    closure), and a start whose residual is zero where the Jacobian is singular stays put."""
    newton = equations_module._closure_newton
    z = newton(lambda z: np.array([z[0] ** 2 - 2.0]), lambda z: np.array([[2.0 * z[0]]]), np.array([1.0]))
    assert abs(z[0] - math.sqrt(2.0)) <= 1e-15
    # link of length 1 from the origin meeting the line x = 0.6: angle acos(0.6), height 0.8
    f = lambda z: np.array([math.cos(z[0]) - 0.6, math.sin(z[0]) - z[1]])                 # noqa: E731
    J = lambda z: np.array([[-math.sin(z[0]), 0.0], [math.cos(z[0]), -1.0]])                # noqa: E731
    z = newton(f, J, np.array([0.8, 0.5]))
    assert abs(z[0] - math.acos(0.6)) <= 1e-14 and abs(z[1] - 0.8) <= 1e-14
    z = newton(lambda z: np.array([z[0] ** 2]), lambda z: np.array([[2.0 * z[0]]]), np.array([0.0]))
    assert z[0] == 0.0
    assert newton(lambda z: np.array([z[0] ** 2 + 1.0]), lambda z: np.array([[2.0 * z[0]]]), np.array([1.0])) is None


_q, _x, _y, _J, _l, _phi = sp.symbols("crank.L.K.q3 x y J l phi")


@pytest.mark.parametrize("expr", [
    _x * sp.cos(_q) - _y * sp.sin(_q),                         # a loop relation in a link angle
    -_J * (_x * sp.sin(_q + _phi) + _y * sp.cos(_q + _phi)),   # a velocity ratio times a rate
    _x / (_l * sp.sin(_q - _phi)),                              # a Cramer quotient's denominator
    sp.sqrt(_l ** 2 - (_x * sp.sin(_q) - _y) ** 2),              # the slider-crank's square root
    _x * sp.exp(-_q / _l) * sp.tanh(_q) + sp.atan(_q) * sp.log(_l + _q ** 2),
])
def test_derivative_takes_the_rules_sympy_takes(expr, monkeypatch):
    """Sums, products, numeric powers and sin, cos, exp, ... by the chain rule: the expression
    sympy's ``diff`` gives (structurally equal), without calling it."""
    expected = sp.diff(expr, _q)
    calls = [0]
    real = sp.diff

    def counting(*args, **kw):
        calls[0] += 1
        return real(*args, **kw)
    monkeypatch.setattr(sp, "diff", counting)
    got = derivative(expr, _q)
    assert calls[0] == 0
    assert got == expected


def test_derivative_leaves_other_functions_to_sympy():
    """A step's derivative is sympy's (DiracDelta): no rule of its own for it."""
    t = sp.Symbol("t")
    assert derivative(3 * sp.Heaviside(t - 1) * _x, t) == 3 * _x * sp.DiracDelta(t - 1)


def test_numeric_function_is_lambdifys():
    """Dotted names (no Python names), a step, a maximum, atan2: the values sympy's own
    ``lambdify(..., "numpy")`` gives, to rounding; a function numpy lacks fails when called."""
    a, b, c = sp.symbols("dsd.C.K.q3 dsd.C.K.q4* sds.phi2")
    exprs = [b * sp.cos(a) + 0.01 * sp.sin(a) + 0.018 * sp.cos(c) + 0.048, sp.Heaviside(a - c) * b ** 2,
             sp.Max(a, c) - sp.atan2(b, a) / sp.sqrt(1 + b ** 2), sp.Integer(7), a * b * c - c / (a + 2)]
    fn = numeric_function([a, b, c], exprs)
    reference = sp.lambdify([a, b, c], exprs, "numpy")
    rng = np.random.default_rng(7)
    for _ in range(20):
        point = rng.normal(size=3).tolist()
        got, expected = [float(v) for v in fn(*point)], [float(v) for v in reference(*point)]
        # the same arithmetic; lambdify's dummies may order a sum's terms otherwise: rounding
        assert all(abs(g - e) <= 1e-14 * max(1.0, abs(e)) for g, e in zip(got, expected))
    with pytest.raises(NameError):
        numeric_function([a], [sp.DiracDelta(a)])(0.5)
