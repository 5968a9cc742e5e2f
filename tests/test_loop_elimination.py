"""Large linear loops are split: unknowns with constant coefficients are eliminated symbolically and
computed after the remaining core (multipole.equations._split_block).  The values must equal the
solution of the whole system (numpy's dense solve of the same matrix, evaluated independently)."""
import numpy as np
import sympy as sp

from multipole.equations import _split_block


def _evaluate(blocks, values):
    values = dict(values)
    for b in blocks:
        if b.solution is not None:
            for z, s in zip(b.variables, b.solution):
                values[z] = float(sp.sympify(s).xreplace(values))
        else:
            A = np.array(b.matrix.xreplace(values), dtype=float)
            rhs = np.array(b.rhs.xreplace(values), dtype=float).ravel()
            values.update(zip(b.variables, np.linalg.solve(A, rhs)))
    return values


def test_split_block_equals_the_dense_solve():
    """A 12-unknown block: chains of aliases and balances (constant pivots) around a core whose entries
    depend on a state (sin q): the split solution equals the dense solve at several q, and the core is
    smaller than the block."""
    q, k = sp.symbols("q k", real=True)
    zs = list(sp.symbols("z0:12", real=True))
    rng = np.random.default_rng(3)
    A = sp.zeros(12, 12)
    b = sp.zeros(12, 1)
    for i in range(12):
        A[i, i] = 1 if i % 3 else sp.sin(q) + 2          # every third diagonal entry depends on the state
        A[i, (i + 1) % 12] = -1 if i % 2 else k * sp.cos(q)
        A[i, (i + 5) % 12] = float(rng.normal())
        b[i] = float(rng.normal()) + (sp.cos(q) if i == 4 else 0)
    blocks = _split_block(A, b, zs, ["o"] * 12, ["n"] * 12, {k: 0.7})
    core = [blk for blk in blocks if blk.kind == "linear"]
    assert core and len(core[0].variables) < 12
    for qv in (0.1, 1.3, -2.0):
        got = _evaluate(blocks, {q: qv, k: 0.7})
        An = np.array(A.xreplace({q: qv, k: 0.7}), dtype=float)
        bn = np.array(b.xreplace({q: qv, k: 0.7}), dtype=float).ravel()
        expected = np.linalg.solve(An, bn)
        assert np.allclose([got[z] for z in zs], expected, rtol=1e-10, atol=1e-12)


def test_a_block_of_constant_couplings_is_solved_without_a_core():
    """Aliases and sums only (a rigid chain): everything is eliminated, nothing is left to solve."""
    zs = list(sp.symbols("y0:10", real=True))
    A = sp.eye(10)
    for i in range(9):
        A[i, i + 1] = -1                  # y_i - y_{i+1} = b_i
    b = sp.Matrix([float(i) for i in range(10)])
    blocks = _split_block(A, b, zs, ["o"] * 10, ["n"] * 10, {})
    assert all(blk.kind == "explicit" for blk in blocks)
    got = _evaluate(blocks, {})
    expected = np.linalg.solve(np.array(A, dtype=float), np.array(b, dtype=float).ravel())
    assert np.allclose([got[z] for z in zs], expected, rtol=1e-12)
