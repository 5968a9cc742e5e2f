"""The pieces that keep the set-up linear in the model size (docs/performance.md §3) decide what the
slower code they replaced decided."""
import gc

import numpy as np
import pytest
import sympy as sp

import multipole_models
from multipole import codegen, pipeline
from multipole.causality import _Analyser
from multipole.equations import _singular_matrix, derivative
from multipole.netlist import loads
from multipole.stages import bulk


def test_bulk_pauses_the_collector_and_restores_it():
    seen = []

    @bulk
    def stage(fail=False):
        seen.append(gc.isenabled())
        if fail:
            raise ValueError("stage failed")
        return 42

    assert gc.isenabled()
    assert stage() == 42 and seen == [False] and gc.isenabled()
    with pytest.raises(ValueError):
        stage(fail=True)
    assert gc.isenabled()
    gc.disable()
    try:
        stage()                       # nested in a paused region: leaves the collector paused
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_singular_matrix_by_rank_of_the_equilibrated_matrix():
    """Loops mix units: a regular matrix with entries from 1e-9 to 1e7 is regular (its determinant,
    computed by hand, is nonzero), and one whose third row is a combination of the first two is
    singular whatever the scales of its rows and columns."""
    regular = sp.Matrix([[1e7, 0, 1e-9], [0, 2e-9, 0], [3e-9, 0, 4e7]])
    assert 1e7 * 2e-9 * 4e7 - 1e-9 * 2e-9 * 3e-9 != 0
    assert not _singular_matrix(regular)
    rows = np.array([[1e7, 2.0, 1e-9], [3e-3, 1e5, 5e-9]])
    third = 2.0 * rows[0] - 7.0 * rows[1]
    singular = np.vstack([rows, third]) * np.array([[1e-6], [1.0], [1e8]]) * np.array([1.0, 1e-4, 1e9])
    assert _singular_matrix(sp.Matrix(singular.tolist()))
    assert _singular_matrix(sp.Matrix([[1.0, 0.0], [0.0, 0.0]]))        # a zero row


def _reference_rows_by_trial(nulls, d):
    """The earlier greedy choice: rows in weight order, each kept if ``matrix_rank`` grows."""
    weight = np.min([np.abs(N[:, :d]).max(axis=1) / max(np.abs(N).max(), 1e-300) for N in nulls], axis=0)
    rows: list = []
    for _ in range(d):
        for i in [i for i in np.argsort(-weight) if i not in rows]:
            if np.linalg.matrix_rank(nulls[0][rows + [i], :d]) == len(rows) + 1:
                rows.append(i)
                break
    return rows


@pytest.mark.parametrize("seed", range(6))
def test_reference_rows_match_the_trial_by_rank(seed):
    """Null bases with repeated and proportional rows (equations that carry the same combination):
    the one-pass choice takes the same rows as the rank test of every trial."""
    rng = np.random.default_rng(seed)
    d = 4
    base = rng.normal(size=(6, d))
    rows = [base[i] for i in range(6)] + [3.0 * base[1], -base[4], base[0] + base[2], np.zeros(d)]
    order = rng.permutation(len(rows))
    N0 = np.array(rows)[order]
    nulls = [N0, N0 * rng.uniform(0.5, 2.0, size=(len(rows), 1))]
    assert _Analyser.reference_rows(nulls, d) == _reference_rows_by_trial(nulls, d)


# --- non-affine models: the Jacobian and the printing without sympy's slow paths (issue 10) ---

_q, _a, _b, _y = sp.symbols("q a b y")


@pytest.mark.parametrize("expr", [
    _a * _q + 3 * _b * _q**3,                  # the hardening spring c*q + c3*q**3
    _q**2 * _a / _b, -_q, sp.Float(2.5) * _q**-2, _q**sp.Rational(1, 2) * _a, _a * _y,
    sp.sin(_q) * _a, _q * sp.exp(_q), (_q + _a) * (_q - _b), _q**_q,     # sympy's diff: the fallback
])
def test_derivative_is_sympys(expr):
    """The power rule gives the very expression sympy's ``diff`` gives (structurally equal)."""
    assert derivative(expr, _q) == sp.diff(expr, _q)


def _cubic_chain(n):
    scene = loads(multipole_models.mass_spring_chain(n, c3=1e6), f"cubic_chain_{n}.yaml")
    eq, outs, _record = pipeline.pruned(scene)
    return eq, outs


def test_cubic_chain_is_generated_without_sympy_diff_and_with_bounded_printing(monkeypatch):
    """A chain of hardening springs (not affine: the Jacobian is one line per nonzero): no call of
    sympy's ``diff`` (2.7 ms per spring law) and a number of expressions through sympy's printer (and
    the parameter folding before it, 1 ms per expression) that does not grow with the chain."""
    getattr(codegen._diff, "cache_clear", lambda: None)()        # derivatives of an earlier test
    diffs, prints = [0], [0]
    real_diff, real_print = sp.diff, codegen._Printer.doprint

    def counting_diff(*args, **kw):
        diffs[0] += 1
        return real_diff(*args, **kw)

    def counting_print(self, *args, **kw):
        prints[0] += 1
        return real_print(self, *args, **kw)
    monkeypatch.setattr(sp, "diff", counting_diff)
    monkeypatch.setattr(codegen._Printer, "doprint", counting_print)
    counts = {}
    for n in (25, 50):                       # 50 and 100 states: the sparse Jacobian path
        diffs[0] = prints[0] = 0
        eq, outs = _cubic_chain(n)
        src = codegen.generate(eq, outs)
        counts[n] = diffs[0], prints[0]
        assert src.count("**2") == n         # one derivative c + 3*c3*q**2 per spring, in jac_sparse
    assert counts[25][0] == counts[50][0] == 0
    assert counts[25][1] == counts[50][1] <= 10


def test_direct_printing_is_sympys_folded_value():
    """A product of integers, parameters, one over a parameter and a variable (or its power) is
    printed with the float that sympy's folding of the parameters gives: bit for bit the same value."""
    values = {_a: 0.1, _b: 3.0}
    printer = codegen._Printer({_q: "q"})
    cases = [3 * _a * _b * _q**2, -_a * _q, -_q, _a * _q**3 / _b, -7 * _a * _q / _b, _a * _q + _b * _q**2]
    for expr in cases:
        text = codegen._plain(expr, printer, values)
        assert text is not None, expr
        folded = printer.doprint(expr.xreplace({p: sp.Float(v) for p, v in values.items()}))
        for q in (0.37, -1.3e3):
            assert eval(text, {"q": q}) == eval(folded, {"q": q}), (expr, text, folded)
    assert codegen._plain(2 * _q, printer, values) is None          # an integer alone: sympy prints it
    assert codegen._plain(_a * _q * _y, printer, values) is None    # two variables
