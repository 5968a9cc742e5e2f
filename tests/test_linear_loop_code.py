"""The printed code of numeric linear loops (codegen Writer.elimination_lines, docs/performance.md
"Linkages"): the loop's entries with their common subexpressions named once and sin² + cos² folded
(Writer.loop_entry_lines, codegen._pythagoras), then Cramer's rule over the printed entries
(Writer.cramer_lines) or the unrolled elimination with partial pivoting (Writer.pivot_lines),
whichever takes fewer operations for what the right-hand side reads.  Expected values: numpy's dense
solve of the loop's matrix evaluated from the equations (not from the printed code), and
sin² + cos² = 1."""
import math
import re
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import multipole as mp
from multipole import codegen, pipeline
from tests.helpers import one_mass_writer

ROOT = Path(__file__).resolve().parents[1]

def _numeric_loops(eq):
    return [b for b in eq.blocks if b.kind == "linear" and b.solution is None]


@pytest.mark.parametrize("name, n, method", [("engine_flywheel", 3, "_det"), ("motor_gear_crank", 5, "_det"),
                                             ("six_link", 7, "_p = ")])
def test_printed_loops_equal_the_dense_solve_at_random_states(name, n, method):
    """The acceleration loops of three mechanisms (3, 5 and 7 unknowns: Cramer's rule, Cramer's rule,
    elimination; all with shared subexpressions) at 40 random states (crank angle, momenta and
    fluxes): every unknown the generated
    ``values`` computes equals ``np.linalg.solve`` of the loop's matrix and right-hand side evaluated
    from the equations at the same state, and ``rhs`` returns the derivatives ``values`` has."""
    sc = mp.load(ROOT / "diagrams" / "linkages" / f"{name}.yaml")
    model = pipeline.model(sc)                     # (restored from the cache: without its equations)
    eq = pipeline.pruned(sc)[0]                      # the equations it was generated from
    (loop,) = _numeric_loops(eq)
    assert len(loop.variables) == n
    rhs_src = model.source[model.source.index("def rhs("):model.source.index("def outputs(")]
    assert method in rhs_src and re.search(r"\n    _e\d+_0 = ", rhs_src)     # the paths under test are printed
    names = list(model.value_names)
    params = {p: float(v) for p, v in eq.params.items()}
    A = loop.matrix.xreplace(params)
    b = loop.rhs.xreplace(params)
    syms = sorted(A.free_symbols | b.free_symbols, key=str)
    states = [s.symbol for s in eq.states]
    f_A, f_b = sp.lambdify(syms, list(A), "math"), sp.lambdify(syms, list(b), "math")
    ders = [(k, names.index(d.name)) for k, d in enumerate(eq.derivatives) if d.name in names]
    rng = np.random.default_rng(3)
    for _ in range(40):
        x = model.x0.copy()                   # the crank anywhere, momenta at random; closures by formula
        x[model.state_names.index("crank.L.K.q3")] = rng.uniform(-math.pi, math.pi)
        moving = [i for i, s in enumerate(model.state_names) if s.endswith(".p")]
        x[moving] += rng.normal(0.0, 1.0, size=len(moving))
        vals = model.values(0.0, x)
        env = [x[states.index(s)] if s in states else vals[names.index(s.name)] for s in syms]
        An, bn = np.array(f_A(*env), dtype=float).reshape(n, n), np.array(f_b(*env), dtype=float)
        expected = np.linalg.solve(An, bn)
        got = np.array([vals[names.index(z.name)] for z in loop.variables])
        tol = 1e-13 * np.linalg.cond(An) * np.abs(expected).max()
        assert np.allclose(got, expected, rtol=0, atol=tol), (got - expected, tol)
        dx = model.rhs(0.0, x)
        assert [dx[k] for k, _i in ders] == [vals[i] for _k, i in ders]      # the same lines




def _run(lines, names, entries):
    """Run printed ``lines`` with the entries ``{name: value}``; the values of ``names``."""
    env = {"np": np, "math": math, **entries}
    exec("def _f():\n" + "\n".join(lines) + f"\n    return [{', '.join(names)}]", env)
    return np.array(env["_f"]())


def _entries(A, b):
    n = len(b)
    return {**{f"_a{i}_{j}": float(A[i, j]) for i in range(n) for j in range(n) if A[i, j] != 0},
            **{f"_r{i}": float(b[i]) for i in range(n)}}


# a four-bar's acceleration loop (tests/test_small_solvers.py): zeros on the diagonal
FOURBAR = [[1, 1, 1, 1, 0], [1, 1, 1, 1, 0], [1, 1, 0, 0, 1], [0, 0, 1, 1, 1], [0, 0, 1, 1, 1]]


@pytest.mark.parametrize("seed", range(8))
def test_cramer_lines_equal_the_dense_solve(seed):
    """Cramer's rule printed over the entries of a random pattern (1 to 5 unknowns, the four-bar's
    among them, a nonzero diagonal or not) equals numpy's solve to rounding, every unknown."""
    rng = np.random.default_rng(seed)
    n = 1 + seed % 5
    while True:
        pattern = FOURBAR if seed == 4 else (rng.random((n, n)) < 0.6) | np.eye(n, k=seed % n, dtype=bool)
        A = rng.normal(size=(n, n)) * np.array(pattern)
        if abs(np.linalg.det(A)) > 1e-3:
            break
    b = rng.normal(size=n)
    nz = {i: {j for j in range(n) if A[i, j] != 0} for i in range(n)}
    names = [f"z{i}" for i in range(n)]
    got = _run(one_mass_writer().cramer_lines(nz, names, "t"), names, _entries(A, b))
    expected = np.linalg.solve(A, b)
    cond = np.linalg.cond(A)
    assert np.allclose(got, expected, rtol=0, atol=1e-13 * cond * np.abs(expected).max())


def test_cramer_lines_of_a_singular_matrix_raise_linalgerror():
    """A zero determinant at run time: numpy's error, as the elimination raises it."""
    A = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 1.0, 3.0]])
    nz = {i: {j for j in range(3) if A[i, j] != 0} for i in range(3)}
    with pytest.raises(np.linalg.LinAlgError):
        _run(one_mass_writer().cramer_lines(nz, ["z0", "z1", "z2"], "t"), ["z0", "z1", "z2"], _entries(A, np.ones(3)))


@pytest.mark.parametrize("pattern, wanted, cramer", [(FOURBAR, 1, True), ([[1] * 5] * 5, 5, False)])
def test_the_cheaper_solution_is_printed(pattern, wanted, cramer):
    """Cramer's rule where the right-hand side reads one unknown of the sparse four-bar pattern (3
    cofactors of 5 × 5 minors, most of them structural zeros); the elimination for a dense 5 × 5
    loop whose every unknown is read (Cramer's rule would need all 25 cofactors).  Either solves."""
    n = len(pattern)
    w = one_mass_writer()
    syms = {(i, j): sp.Symbol(f"s{i}_{j}") for i in range(n) for j in range(n) if pattern[i][j]}
    rsyms = [sp.Symbol(f"r{i}") for i in range(n)]
    for s in list(syms.values()) + rsyms:
        w.names[s] = s.name
    names = [f"z{i}" for i in range(n)]
    w._rhs_names = set(names[n - wanted:])          # what the right-hand side reads
    lines = w.elimination_lines(sp.Matrix(n, n, lambda i, j: syms.get((i, j), 0)), sp.Matrix(rsyms), names)
    assert any(line.startswith("    _det") for line in lines) == cramer
    assert any(line.startswith("    _p = ") for line in lines) != cramer
    rng = np.random.default_rng(1)
    A = rng.normal(size=(n, n)) * np.array(pattern)
    b = rng.normal(size=n)
    env = {s.name: float(A[i, j]) for (i, j), s in syms.items()} | {s.name: float(v) for s, v in zip(rsyms, b)}
    got = _run(lines, names, env)
    cond = np.linalg.cond(A)
    assert np.allclose(got, np.linalg.solve(A, b), rtol=0, atol=1e-13 * cond * np.abs(got).max())


def test_pythagoras_folds_squares_of_the_same_angle_and_factor():
    """``a sin²u R + b cos²u R`` becomes ``b R + (a - b) sin²u R``, ``a R`` when a == b (a pivoted
    body's inertia ``m l² (sin² + cos²) + J`` is a number); other terms are left alone.  The folded
    expression equals the original at random points (sin² + cos² = 1)."""
    u, v, w = sp.symbols("u v w")
    expr = (0.09 * sp.sin(u) ** 2 + 0.09 * sp.cos(u) ** 2 + 0.01
            + 0.3 * w * sp.sin(v) ** 2 - 0.7 * w * sp.cos(v) ** 2 + 0.2 * sp.cos(u) * sp.sin(v))
    folded = codegen._pythagoras(expr)
    assert sp.cos(v) ** 2 not in folded.atoms(sp.Pow) and sp.sin(u) ** 2 not in folded.atoms(sp.Pow)
    assert folded.coeff(sp.cos(u) * sp.sin(v)) == 0.2
    rng = np.random.default_rng(0)
    f0, f1 = sp.lambdify((u, v, w), expr), sp.lambdify((u, v, w), folded)
    for p in rng.normal(0.0, 3.0, size=(20, 3)):
        assert math.isclose(f0(*p), f1(*p), rel_tol=1e-14, abs_tol=1e-14)
    assert float(codegen._pythagoras(0.09 * sp.sin(u) ** 2 + 0.09 * sp.cos(u) ** 2 + 0.01)) == pytest.approx(0.1)


def test_loop_entries_share_their_subexpressions():
    """Entries that repeat a product (the velocity terms of a mechanism's rows) compute it once: the
    printed lines hold it once, and evaluate to the entries' values."""
    a, b_, c, d = sp.symbols("a b c d")
    w = one_mass_writer()
    for s in (a, b_, c, d):
        w.names[s] = s.name
    shared = a * b_ * sp.cos(c) + 9.81
    entries = [("_a0_0", 2 * shared * d), ("_a0_1", -3 * shared * sp.sin(c)), ("_r0", shared + d)]
    lines = w.loop_entry_lines(entries, "x")
    assert sum("9.81" in line for line in lines) == 1
    assert not any(line.split(" = ")[1] == "math.cos(c)" for line in lines)   # shared by shared_trig instead
    env = {"a": 0.3, "b": -1.2, "c": 0.7, "d": 2.5}
    got = _run(lines, [n for n, _e in entries], env)
    expected = [float(e.subs({a: 0.3, b_: -1.2, c: 0.7, d: 2.5})) for _n, e in entries]
    assert np.allclose(got, expected, rtol=1e-15, atol=0)
