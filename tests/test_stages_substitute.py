"""stages.substitute and stages.free_symbols: sympy's xreplace and free_symbols, with each distinct
subexpression visited once (positions substituted into positions share their subexpressions)."""
import pytest
import sympy as sp

from multipole.stages import free_symbols, substitute

x, y, z, a = sp.symbols("x y z a")


def _nested(levels, e=z):
    """e_k = sin(e_{k-1}) * x + cos(e_{k-1}) + y, e_0 = ``e``: each e_{k-1} object occurs twice in
    e_k, so the tree has about 2**levels nodes, but only 7 new distinct subexpressions per level."""
    for _ in range(levels):
        e = sp.sin(e) * x + sp.cos(e) + y
    return e


class _Counting(dict):
    """A mapping that counts its look-ups (one per node visited)."""
    lookups = 0

    def __contains__(self, key):
        type(self).lookups += 1
        return dict.__contains__(self, key)


@pytest.mark.parametrize("mapping", [{z: a + 1}, {x: sp.Integer(2), y: z}, {y: y}, {sp.sin(z): a}, {}])
def test_substitute_gives_xreplace(mapping):
    e = _nested(6) + sp.Piecewise((x, z > 0), (sp.Abs(sp.Function("f")(z)), True))
    assert substitute(e, mapping) == e.xreplace(mapping)
    memo = {}
    assert substitute(e, mapping, memo) == e.xreplace(mapping)
    assert substitute(e * 2, mapping, memo) == (e * 2).xreplace(mapping)   # memo kept for one mapping


def test_substitute_visits_each_distinct_subexpression_once():
    levels = 16                       # about 2**16 tree nodes, 7 * 16 distinct ones
    e = _nested(levels)
    _Counting.lookups = 0
    out = substitute(e, _Counting({z: a}))
    assert _Counting.lookups <= 7 * levels + 1
    assert free_symbols(out) == {a, x, y}
    assert hash(out) == hash(_nested(levels, a))     # built independently (== would walk the tree)


def test_free_symbols_gives_sympys():
    e = _nested(6) + sp.Integral(a * z, (a, 0, 1)) + sp.Lambda(y, y * x)(z)
    assert free_symbols(e) == e.free_symbols
    memo = {}
    assert free_symbols(e, memo) == e.free_symbols and free_symbols(x * a, memo) == {x, a}
    free_symbols(e, memo).add(sp.Symbol("w"))              # the set returned is the caller's own
    assert free_symbols(e, memo) == e.free_symbols
    assert free_symbols(_nested(60)) == {x, y, z}           # about 2**60 tree nodes
