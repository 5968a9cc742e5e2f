"""Helpers shared by the set-up stages (flatten, analyse, assemble, code generation)."""
from __future__ import annotations

import functools
import gc
import operator

import numpy as np
import sympy as sp


def bulk(fn):
    """Run ``fn`` with Python's cyclic garbage collector paused (restarted when it returns or raises).

    The set-up stages build tens of thousands of sympy objects that stay alive; each automatic
    collection scans every one of them again, which took about 40 % of the set-up of a 1000-pair
    chain (3.1 s instead of 5.3 s without it).  Reference counting still frees what is dropped;
    only cyclic garbage waits until the stage returns.  Nested calls leave the collector as the
    outermost found it.
    """
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if not gc.isenabled():
            return fn(*args, **kwargs)
        gc.disable()
        try:
            return fn(*args, **kwargs)
        finally:
            gc.enable()
    return wrapper


def substitute(expr, mapping, memo=None):
    """``expr.xreplace(mapping)`` (the same result, node for node) with each distinct subexpression
    visited once.  sympy's ``xreplace`` walks a tree: an expression built by substituting positions
    into positions (a planar curve span's contact points read the lever's pose, its length reads the
    contact points) holds the same subexpression objects many times over, and each occurrence is
    walked again (the lever scene: 32 million visits, 150 s of its build).  ``memo``: a dict kept
    between calls with the *same* ``mapping`` (the subexpressions several expressions share are then
    walked once for all of them)."""
    if not mapping:
        return expr
    memo = {} if memo is None else memo

    def walk(e):
        hit = memo.get(e)
        if hit is not None:
            return hit
        if e in mapping:
            out = mapping[e], True
        else:
            args, changed = [], False
            for a in e.args:
                if getattr(a, "_xreplace", None) is None:
                    args.append(a)
                    continue
                a, c = walk(a)
                args.append(a)
                changed |= c
            out = (e.func(*args), True) if changed else (e, False)
        memo[e] = out
        return out

    return walk(expr)[0] if isinstance(expr, sp.Basic) else expr.xreplace(mapping)


@functools.lru_cache(maxsize=None)
def _plain_free_symbols(cls) -> bool:
    """Whether ``cls`` takes ``free_symbols`` from :class:`sympy.Basic` (the union over its args),
    looked up in the class's own MRO (``type(e).free_symbols`` on a function such as ``sin`` finds
    its metaclass's property instead)."""
    owner = next(k for k in cls.__mro__ if "free_symbols" in k.__dict__)
    return owner is sp.Basic


def free_symbols(expr, memo=None) -> set:
    """``expr.free_symbols`` with each distinct subexpression visited once (sympy's property walks
    every occurrence of a shared subexpression again, see :func:`substitute`).  ``memo``: a dict
    that may be kept between any calls (the answer depends on the subexpression only); the set
    returned is the caller's own."""
    memo = {} if memo is None else memo

    def walk(e):
        hit = memo.get(e)
        if hit is None:
            if e.args and _plain_free_symbols(type(e)):
                hit = set().union(*(walk(a) for a in e.args))
            else:
                hit = e.free_symbols
            memo[e] = hit
        return hit

    return set(walk(sp.sympify(expr)))


def numeric_function(symbols, exprs):
    """``f(*values)`` returning the list ``exprs`` (sympy) at ``symbols = values`` in numpy
    arithmetic: the function :func:`sympy.lambdify` writes with its numpy printer, for the set-up
    stages' numeric samples.

    Three costs of ``lambdify(..., "numpy")`` that the result does not need are left out: the
    symbols, whose names (``crank.L.K.q3``) are no Python names, are renamed once (``_s00000``, ...:
    zero-padded in their sorted order: sums and products keep the order of terms of the original
    names, where ``lambdify``'s own dummies may order them otherwise, so the values agree to rounding)
    instead of replaced node by node in every expression; no
    docstring holding the printed expressions is written; and the namespace is numpy's own (the
    module object), not ``from numpy import *``, which loads numpy.testing, f2py and unittest (0.08 s
    at the first call of a process).  The 8-link mechanism's sampled Jacobians: 0.15 s -> 0.04 s.
    Raises what ``lambdify`` raises; a function numpy lacks (``DiracDelta``) is a ``NameError`` when
    called."""
    symbols = list(symbols)
    order = sorted(range(len(symbols)), key=lambda k: symbols[k].name)
    plain = [None] * len(symbols)
    for rank, k in enumerate(order):
        plain[k] = sp.Symbol(f"_s{rank:05d}")
    renamed = dict(zip(symbols, plain))
    return sp.lambdify(plain, [sp.sympify(e).xreplace(renamed) for e in exprs], modules=[np], docstring_limit=0)


def derivative(expr, v):
    """d ``expr`` / d ``v`` for a symbol ``v``: by the power rule when ``expr`` is a sum of products
    in which ``v`` is one factor, ``v`` or ``v**n`` (``n`` a number); else by the sum, product and
    chain rules (:func:`_rules`) over numbers, symbols, numeric powers and the one-argument
    functions of :data:`CHAIN_RULE`; anything else by sympy's ``diff``.

    The same expression as ``sp.diff`` gives (the rules sympy applies, in its order), about 40
    times faster (sympy's derivative machinery queries assumptions of every new object: 2.7 ms for
    ``c*q + c3*q**3``, against 0.07 ms here; a 10,000-spring chain's Jacobian is 10,000 of them;
    a mechanism's loop relations ``x*cos(q) - y*sin(q)`` by a link angle ``q``: 0.4 ms -> 0.1 ms).
    """
    terms = []
    for term in sp.Add.make_args(expr):
        if v not in term.free_symbols:
            continue
        factors = sp.Mul.make_args(term)
        hits = [k for k, f in enumerate(factors) if v in f.free_symbols]
        f = factors[hits[0]]
        if len(hits) != 1 or not (f == v or (f.is_Pow and f.base == v and f.exp.is_Number)):
            d = _rules(term, v)
            if d is None:
                return sp.diff(expr, v)
            terms.append(d)
            continue
        rest = factors[:hits[0]] + factors[hits[0] + 1:]
        terms.append(_subset(sp.Mul, rest, sp.S.One) if f == v else sp.Mul(f.exp, *rest, v ** (f.exp - 1)))
    return sp.Add(*terms)


#: one-argument functions whose derivative :func:`derivative` takes by the chain rule
CHAIN_RULE = (sp.sin, sp.cos, sp.tan, sp.exp, sp.log, sp.sinh, sp.cosh, sp.tanh, sp.asin, sp.acos, sp.atan)


def _rules(e, v):
    """d ``e`` / d ``v`` by the sum, product, power (numeric exponent) and chain rules, as sympy's
    ``diff`` writes them (:meth:`sympy.Mul._eval_derivative`: one product per factor holding
    ``v``; a function: ``fdiff`` times the argument's derivative); None where another rule is needed."""
    if v not in e.free_symbols:
        return sp.S.Zero
    if e == v:
        return sp.S.One
    if e.is_Add or e.is_Mul:
        parts = []
        for k, a in enumerate(e.args):
            if v not in a.free_symbols:
                continue
            d = _rules(a, v)
            if d is None:
                return None
            # a product as sympy forms it: multiplied one factor at a time (a number distributes over a sum)
            parts.append(d if e.is_Add else functools.reduce(operator.mul, e.args[:k] + (d,) + e.args[k + 1:], sp.S.One))
        return sp.Add(*parts)
    if e.is_Pow and e.exp.is_Number:
        d = _rules(e.base, v)
        return None if d is None else e * (d * e.exp / e.base)
    if isinstance(e, CHAIN_RULE) and len(e.args) == 1:
        d = _rules(e.args[0], v)
        return None if d is None else e.fdiff(1) * d
    return None


def _subset(cls, args, empty):
    """``cls(*args)`` for ``args`` taken, in order, from one sum or product: already in canonical
    form, so it is not built again through sympy's flattening (the cost of a large assemble)."""
    if not args:
        return empty
    return args[0] if len(args) == 1 else cls._from_args(args)
