"""The generated code's small solvers (a linkage's loops, docs/performance.md "Linkages"): the
unrolled scalar elimination of numeric linear loops (codegen Writer.elimination_lines), the Gaussian
elimination kernel of the numba backend (numba_kernels.gauss_solve) and Newton's method
(codegen.newton, the generic iteration of loops larger than the generated scalar ones).  Expected
values: numpy's dense solve of the same matrix, and
the circle intersection of a four-bar's closure in closed form."""
import math

import numpy as np
import pytest
import sympy as sp

from multipole import codegen
from tests.helpers import circle_intersection, one_mass_writer



def _solve_by_printed_code(writer, pattern, values, rhs):
    """Print the elimination for a matrix of symbols with the nonzero ``pattern``, run it with the
    entries ``values`` (numpy array) and the right-hand side ``rhs``; the solution as an array."""
    n = len(pattern)
    syms = {(i, j): sp.Symbol(f"s{i}_{j}") for i in range(n) for j in range(n) if pattern[i][j]}
    rsyms = [sp.Symbol(f"r{i}") for i in range(n)]
    A = sp.Matrix(n, n, lambda i, j: syms.get((i, j), 0))
    for s in list(syms.values()) + rsyms:
        writer.names[s] = s.name
    names = [f"z{i}" for i in range(n)]
    lines = writer.elimination_lines(A, sp.Matrix(rsyms), names)
    assert not any("solve" in line for line in lines)          # straight-line code, no solver call
    env = {"np": np, "math": math}
    env.update({s.name: float(values[i, j]) for (i, j), s in syms.items()})
    env.update({s.name: float(v) for s, v in zip(rsyms, rhs)})
    exec("def _f():\n" + "\n".join(lines) + f"\n    return [{', '.join(names)}]", env)
    return np.array(env["_f"]())


# a four-bar's acceleration loop (the pattern of tests/test_linkage_dynamics.py's torque-driven
# four-bar): a zero in the first column's lower rows, zeros on the diagonal
FOURBAR = [[1, 1, 1, 1, 0], [1, 1, 1, 1, 0], [1, 1, 0, 0, 1], [0, 0, 1, 1, 1], [0, 0, 1, 1, 1]]


@pytest.mark.parametrize("seed", range(6))
def test_unrolled_elimination_equals_the_dense_solve(seed):
    """Random entries on the four-bar's pattern, some rows scaled by 1e-6 so that partial pivoting
    must swap rows at run time: the printed elimination equals numpy's solve to rounding."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(5, 5)) * np.array(FOURBAR)
    A[rng.integers(5)] *= 1e-6
    b = rng.normal(size=5)
    got = _solve_by_printed_code(one_mass_writer(), FOURBAR, A, b)
    expected = np.linalg.solve(A, b)
    cond = np.linalg.cond(A)
    assert np.allclose(got, expected, rtol=1e-13 * cond, atol=1e-13 * cond * np.abs(expected).max())


def test_unrolled_elimination_pivots_where_the_diagonal_is_zero():
    """A zero on the diagonal at run time (the entry is a symbol, so the printer cannot know): the
    row with the largest entry is the pivot, and the solution is exact."""
    pattern = [[1, 1, 1], [1, 1, 1], [1, 1, 1]]
    A = np.array([[0.0, 2.0, 1.0], [3.0, 0.0, 1.0], [1.0, 1.0, 0.0]])
    b = np.array([1.0, 2.0, 3.0])
    got = _solve_by_printed_code(one_mass_writer(), pattern, A, b)
    assert np.allclose(A @ got, b, rtol=0, atol=1e-14)


def test_unrolled_elimination_of_a_singular_matrix_raises_linalgerror():
    """A column of zeros at run time: numpy's error (the simulation reports "singular matrix in a
    linear loop"), not a division by zero somewhere in the printed code."""
    pattern = [[1, 1], [1, 1]]
    with pytest.raises(np.linalg.LinAlgError):
        _solve_by_printed_code(one_mass_writer(), pattern, np.array([[0.0, 1.0], [0.0, 2.0]]), np.ones(2))


def test_gauss_kernel_equals_the_dense_solve_and_flags_a_singular_matrix():
    numba = pytest.importorskip("numba")
    del numba
    from multipole.backends import numba_kernels as K
    rng = np.random.default_rng(7)
    for n in (1, 2, 5, 12):
        A = rng.normal(size=(n, n))
        A[0] *= 1e-8                               # row 0 is never a good pivot: rows are swapped
        b = rng.normal(size=n)
        x = b.copy()
        assert K.gauss_solve(A.copy(), x)
        cond = np.linalg.cond(A)
        assert np.allclose(x, np.linalg.solve(A, b), rtol=1e-13 * cond, atol=1e-13 * cond)
    A = np.array([[1.0, 2.0], [2.0, 4.0]])         # rank 1: the second pivot is exactly zero
    x = np.ones(2)
    assert not K.gauss_solve(A, x)
    assert np.isnan(x).all()


def _fourbar_closure(theta, l=0.2, l1=0.6, l2=0.5, bx=0.7):
    """Residuals and Jacobian of a four-bar's closure in the coupler and rocker angles (arrays)."""
    def fun(z):
        p1, p2 = z
        return (np.array([l * math.cos(theta) + l1 * math.cos(p1) - l2 * math.cos(p2) - bx,
                          l * math.sin(theta) + l1 * math.sin(p1) - l2 * math.sin(p2)]),
                np.array([[-l1 * math.sin(p1), l2 * math.sin(p2)], [l1 * math.cos(p1), -l2 * math.cos(p2)]]))
    return fun


@pytest.mark.parametrize("theta", [0.3, 1.9, -2.5])
def test_newton_finds_the_circle_intersection(theta):
    """From a start 0.1 rad off (a rejected step's trial state), Newton lands on the closed-form pose
    to 1e-12, keeps it as the next start, and counts its iterations."""
    exact = circle_intersection(theta)
    stats = {"newton_iterations": 0, "newton_solves": 0}
    store = [[exact[0] + 0.1, exact[1] - 0.1]]
    z = codegen.newton(_fourbar_closure(theta), store, 0, stats)
    assert abs(z[0] - exact[0]) < 1e-12 and abs(z[1] - exact[1]) < 1e-12
    assert store[0] is z and stats["newton_solves"] == 1 and 2 <= stats["newton_iterations"] <= 10


def test_newton_on_three_unknowns():
    """Three unknowns: x = 1, y = 2, z = 3 from
    x² + y = 3, y·z = 6, x + y + z² = 12."""
    def fun(v):
        x, y, z = v
        return (np.array([x * x + y - 3, y * z - 6, x + y + z * z - 12]),
                np.array([[2 * x, 1, 0], [0, z, y], [1, 1, 2 * z]]))
    stats = {"newton_iterations": 0, "newton_solves": 0}
    z = codegen.newton(fun, [[1.2, 1.7, 3.3]], 0, stats)
    assert np.allclose(z, [1.0, 2.0, 3.0], rtol=0, atol=1e-12)
