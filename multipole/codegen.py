"""Code generation: from :class:`~multipole.equations.Equations` to a fast :class:`Model`.

One flat Python function each for the right-hand side ``f(t, x)``, its Jacobian (forward-mode
differentiation through the evaluation order, so it stays sparse for long chains), the outputs and
the switching functions.  Parameters are inlined as numbers, except the ``runtime`` parameters a
study names (:func:`compile_model`): those are read from the list ``_P`` in the generated module
and set per run with :meth:`Model.set_parameters` (no new code).  Intermediate variables are plain
Python floats; sympy is not on the hot path.  Algebraic loops that are not solved symbolically
become a numeric linear solve or a Newton iteration (warm-started, iterations counted).
"""
from __future__ import annotations

import functools
import hashlib
import math
import re
import sys
from dataclasses import dataclass

import numpy as np
import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from .equations import Equations, derivative, switching_functions
from .errors import ModelError, NewtonError
from .primitives import T
from .stages import bulk


def _residual(fun, z):
    """``fun(z)``, or None where the residual cannot be evaluated (overflow of exp/sinh, a root or
    logarithm of a negative number): the damped step then shortens."""
    try:
        return fun(z)
    except (OverflowError, ValueError, ZeroDivisionError):
        return None


#: relative size of the step off a point where the loop's Jacobian is singular (sqrt of float eps)
NEWTON_NUDGE = 1.5e-8


def _newton_step(F, J):
    """The Newton step ``J⁻¹F``, or None where ``J`` is singular."""
    try:
        with np.errstate(divide="raise", invalid="raise"):
            dz = np.linalg.solve(J, F)
    except (np.linalg.LinAlgError, FloatingPointError):
        return None
    return dz if np.all(np.isfinite(dz)) else None


def _maxabs(v) -> float:
    return float(np.max(np.abs(v)))


def _nudge(z):
    """``z`` moved off a point where the loop's Jacobian is singular."""
    return z + NEWTON_NUDGE * (1.0 + np.abs(z))


def _damped_newton(fun, z, tol: float, max_iter: int):
    """Damped Newton from the array ``z``: ``(solution, iterations)``, or ``(None, iterations)`` if it
    fails (``fun(z)`` returns the residual array and its Jacobian).  Loops of up to three unknowns do
    not come here: their generated scalar functions (:func:`scalar_newton_lines`) take the same steps."""
    start = _residual(fun, z)
    if start is None:
        return None, 0
    F, J = start
    norm = np.linalg.norm(F)
    nudges = 0
    for it in range(1, max_iter + 1):
        if norm == 0.0:               # a zero residual is a solution, even where J is singular
            return z, it - 1
        dz = _newton_step(F, J)
        if dz is None:                # singular J off the root (d·f·|f| at f = 0): step off the point
            trial = _residual(fun, _nudge(z)) if nudges < 3 else None
            if trial is None:
                return None, it
            nudges += 1
            z = _nudge(z)
            F, J = trial
            norm = np.linalg.norm(F)
            continue
        if _maxabs(dz) <= tol * (1.0 + _maxabs(z)):
            return z - dz, it     # converged to rounding: a line search would only halve the step 20 times
        lam = 1.0
        while True:
            z_new = z - lam * dz
            trial = _residual(fun, z_new)
            if trial is None and lam >= 1e-6:
                lam *= 0.5
                continue
            if trial is None:
                return None, it
            F_new, J_new = trial
            if np.linalg.norm(F_new) <= (1 - 1e-4 * lam) * norm or lam < 1e-6:
                break
            lam *= 0.5
        z, F, J, norm = z_new, F_new, J_new, np.linalg.norm(F_new)
        if lam * _maxabs(dz) <= tol * (1.0 + _maxabs(z)) or norm == 0.0:
            return z, it
    return None, max_iter


#: Newton iterations allowed from the warm start, and then from zero
NEWTON_MAX_ITER = (60, 200)

def newton(fun, store: list, k: int, stats: dict, tol: float = 1e-12):
    """Solve ``fun(z) = (F, J)`` for ``F = 0`` (damped Newton) for algebraic loop ``k``.

    Starts from the last solution ``store[k]``; a trial state of the integrator far from the last
    one (a rejected step) can put that start on the flat side of a steep law (sinh, cubic), so a
    failed warm start is retried once from zero before giving up.
    """
    total = 0
    n = len(store[k])
    starts = (np.array(store[k], dtype=float), np.zeros(n))
    for z0, max_iter in zip(starts, NEWTON_MAX_ITER):
        z, it = _damped_newton(fun, z0, tol, max_iter)
        total += it
        if z is not None:
            stats["newton_iterations"] += total
            stats["newton_solves"] += 1
            store[k] = z
            return z
    last = _residual(fun, np.asarray(store[k], dtype=float))
    norm = f"{np.linalg.norm(last[0]):.3g}" if last is not None else "not computable"
    raise NewtonError(f"Newton's method did not converge in algebraic loop {k} "
                      f"(|F| = {norm} at the last solution, {total} iterations)")


def newton_failed(k: int, residuals, total: int) -> NewtonError:
    """The error of a generated scalar Newton function (:func:`scalar_newton_lines`) whose two starts
    failed: ``residuals`` at the warm start, ``total`` iterations."""
    norm = math.sqrt(sum(f * f for f in residuals))
    shown = f"{norm:.3g}" if math.isfinite(norm) else "not computable"
    return NewtonError(f"Newton's method did not converge in algebraic loop {k} "
                       f"(|F| = {shown} at the last solution, {total} iterations)")


def closure_failed(k: int, radicand: float) -> NewtonError:
    """The error of a position closure solved by formula (:meth:`Writer.closed_form_lines`) where a
    square root of its formula has the negative radicand ``radicand``: no real solution."""
    return NewtonError(f"the position closure of loop {k} has no real solution (a radicand of its formula is "
                       f"{radicand:.3g}, below zero: the links do not reach)",
                       "the mechanism is driven beyond a position it can take: check the drive's motion and "
                       "the link lengths", code="closure_unreachable")


#: loops up to this many unknowns get a Newton function of their own in scalar variables, printed once
#: per loop by :func:`scalar_newton_lines` (both backends; the dyads of a mechanism have two unknowns)
SCALAR_NEWTON_MAX = 3


@functools.lru_cache(maxsize=None)
def cramer(n: int) -> tuple[str, tuple]:
    """Code of ``det(J)`` and of ``det(J_i)`` (column i replaced by ``F``) for the scalars ``J{i}{j}``
    and ``F{i}``: the Newton step is ``d_i = det(J_i) / det(J)``."""
    J = sp.Matrix(n, n, lambda i, j: sp.Symbol(f"J{i}{j}"))
    F = sp.Matrix(n, 1, lambda i, _j: sp.Symbol(f"F{i}"))
    cols = []
    for i in range(n):
        Ji = J.copy()
        Ji[:, i] = F
        cols.append(str(sp.expand(Ji.det(method="berkowitz"))))
    return str(sp.expand(J.det(method="berkowitz"))), tuple(cols)


def scalar_newton_lines(name: str, params: str, n: int, start: list, residual: str, done: list,
                        fail: list, doc: str) -> list:
    """Lines of ``def name(params)``: the damped Newton iteration of :func:`_damped_newton` (same steps,
    same tests, tolerance 1e-12, at most 3 nudges off a singular Jacobian) for a loop of ``n`` unknowns
    in scalars ``z0, z1, ...`` with Cramer's step, started from the code ``start`` (one per unknown),
    then from zero (:data:`NEWTON_MAX_ITER`).  ``residual``: the call returning ``(F0, ..., J00, J01,
    ...)`` with ``{z}`` for the unknowns, NaN where the residuals cannot be computed (the attempt then
    fails where :func:`_damped_newton` gets None).  ``done``: the lines run with the solution in ``z0,
    ...`` and the iteration count in ``total`` (unindented, ending in a return); ``fail``: the lines
    after both attempts failed (unindented).  Written once per loop, it is the whole solve: no list,
    array or call besides the residual's and a few builtins (in Python the generic :func:`newton`
    costs three times as much for two iterations)."""
    r = range(n)
    zs, news, ds = [f"z{i}" for i in r], [f"n{i}" for i in r], [f"d{i}" for i in r]
    out = ", ".join([f"F{i}" for i in r] + [f"J{i}{j}" for i in r for j in r]) + ","
    det, cols = cramer(n)
    tup = ", ".join(zs) + ","
    norm = "abs(F0)" if n == 1 else "math.hypot(F0, F1)"      # no overflow of the squares
    for i in range(2, n):
        norm = f"math.hypot({norm}, F{i})"
    big, size = ("max(" + ", ".join(f"abs({v})" for v in vs) + ")" if n > 1 else f"abs({vs[0]})" for vs in (zs, ds))
    finite = f"<= {sys.float_info.max!r}"        # false for inf and NaN; a literal, no lookup in Python
    at = lambda names: residual.format(z=", ".join(names))      # noqa: E731
    ind = " " * 16
    lines = [f"def {name}({params}):", f'    """{doc}"""',
             "    total = 0", "    for attempt in range(2):",
             f"        {tup} = ({', '.join(start)},) if attempt == 0 else ({', '.join('0.0' for _ in r)},)",
             f"        {out} = {at(zs)}", f"        norm = {norm}",
             f"        if not norm {finite}:     # not computable at the start",
             "            continue",
             "        nudges = 0",
             f"        for it in range(1, {NEWTON_MAX_ITER[0]} + 1 if attempt == 0 else {NEWTON_MAX_ITER[1]} + 1):",
             "            if norm == 0.0:     # a zero residual is a solution, even where J is singular"]
    lines += [ind + line for line in done]
    lines += ["            total += 1", f"            det = {det}", "            if det != 0.0:"]
    lines += [f"                {d} = ({c}) / det" for d, c in zip(ds, cols)] + [f"                step = {size}"]
    lines += [f"            if det == 0.0 or not step {finite}:",
              "                # off the root (d*f*|f| at f = 0): step off the singular point",
              "                if nudges == 3:", "                    break", "                nudges += 1"]
    lines += [f"                {z} += {NEWTON_NUDGE} * (1.0 + abs({z}))" for z in zs]
    lines += [f"                {out} = {at(zs)}", f"                norm = {norm}",
              f"                if not norm {finite}:", "                    break", "                continue",
              f"            if step <= 1e-12 * (1.0 + {big}):     # converged to rounding: no line search"]
    lines += [f"                {z} -= {d}" for z, d in zip(zs, ds)] + [ind + line for line in done]
    lines += ["            lam = 1.0", "            while True:"]
    lines += [f"                {m} = {z} - lam * {d}" for m, z, d in zip(news, zs, ds)]
    lines += [f"                {out} = {at(news)}", f"                norm_new = {norm}",
              "                if norm_new <= (1 - 1e-4 * lam) * norm or lam < 1e-6:", "                    break",
              "                lam *= 0.5",
              f"            if not norm_new {finite}:     # not computable even at the shortest step",
              "                break",
              f"            {tup} = {', '.join(news)},", "            norm = norm_new",
              f"            if lam * step <= 1e-12 * (1.0 + {big}) or norm == 0.0:"]
    lines += [ind + line for line in done]
    return lines + ["    " + line for line in fail] + [""]


def loop_invariants(residuals, zs, prefix: str):
    """A loop's residuals without their terms that do not depend on the unknowns ``zs`` (the crank's
    position in a dyad's closure): ``(residuals, [(symbol, terms)])``, each residual ``symbol + rest``
    where it has such terms (with symbols), so that they are computed once per solve instead of once
    per Newton iteration; the symbols are named ``prefix0, prefix1, ...``."""
    out, hoisted = [], []
    for r in residuals:
        r = sp.sympify(r)
        if isinstance(r, sp.Add):
            fixed, rest = r.as_independent(*zs, as_Add=True)
            if fixed.free_symbols and rest != 0:
                sym = sp.Symbol(f"{prefix}{len(hoisted)}")
                hoisted.append((sym, fixed))
                r = sym + rest
        out.append(r)
    return out, hoisted


class _Printer(PythonCodePrinter):
    def __init__(self, names):
        super().__init__({"fully_qualified_modules": True, "standard": "python3"})
        self.names = names

    def _print_Symbol(self, s):
        try:
            return self.names[s]
        except KeyError:
            raise ModelError("codegen", f"no value for symbol {s} in generated code") from None

    def _print_Float(self, x):
        value = float(x)
        if not math.isfinite(value):
            raise ModelError("infinite_value", f"the number {sp.Float(x, 4)} is beyond the float range (1.8e308)",
                             "rescale the expression or its units")
        return repr(value)

    def _print_Rational(self, x):
        return repr(float(x))

    #: {switching function (parameters folded): index} while printing a function that runs in a
    #: fixed mode: every switch then reads the side it is on from ``_mode[index]`` (±1) instead of
    #: the sign of its argument, so the function is smooth inside one integration segment
    modes: dict | None = None
    mode_ref = "_mode[{k}]"           #: where the generated code reads the side of switch k

    def _side(self, g) -> str | None:
        """The side (±1) of a held switching function ``g`` as code (or its negative), else None."""
        if self.modes is None:
            return None
        if g in self.modes:
            return self.mode_ref.format(k=self.modes[g])
        if -g in self.modes:
            return "(-" + self.mode_ref.format(k=self.modes[-g]) + ")"
        return None

    def _print_Heaviside(self, e):
        side = self._side(e.args[0])
        if side is not None:
            return f"(1.0 if {side} > 0 else 0.0)"
        a = self._print(e.args[0])
        at0 = e.args[1] if len(e.args) > 1 else sp.Rational(1, 2)
        return f"(1.0 if ({a}) > 0 else ({float(at0)!r} if ({a}) == 0 else 0.0))"

    def _print_sign(self, e):
        side = self._side(e.args[0])
        if side is not None:
            return side
        a = self._print(e.args[0])
        return f"(math.copysign(1.0, {a}) if ({a}) != 0 else 0.0)"    # parenthesised: 1 + sign(f)

    def _print_DiracDelta(self, e):
        """The derivative of a step or sign (an ideal Coulomb law ``sign(f)``): 0.  Every step and
        sign is a switching function, so the model is integrated in segments with each switch held
        on its side, and inside a segment the derivative is exactly zero; the jump itself is an
        event, not a slope."""
        return "0.0"

    def _print_Abs(self, e):
        side = self._side(e.args[0])
        if side is not None:
            return f"({side}*({self._print(e.args[0])}))"
        return f"abs({self._print(e.args[0])})"

    def _pick(self, e, first_if_positive: bool):
        a, b = e.args
        side = self._side(a - b) if len(e.args) == 2 else None
        if side is None:
            return None
        return f"(({self._print(a)}) if {side} {'>' if first_if_positive else '<'} 0 else ({self._print(b)}))"

    def _print_Max(self, e):
        return self._pick(e, True) or "max(" + ", ".join(self._print(a) for a in e.args) + ")"

    def _print_Min(self, e):
        return self._pick(e, False) or "min(" + ", ".join(self._print(a) for a in e.args) + ")"

    def _print_Piecewise(self, e):
        if self.modes is None:
            return super()._print_Piecewise(e)
        text = "math.nan"
        for expr, cond in reversed(e.args):
            if cond == sp.true:
                text = f"({self._print(expr)})"
                continue
            side = self._side(cond.lhs - cond.rhs) if isinstance(cond, sp.core.relational.Relational) else None
            test = (f"{side} {'<' if cond.rel_op in ('<', '<=') else '>'} 0" if side is not None and
                    cond.rel_op in ('<', '<=', '>', '>=') else self._print(cond))
            text = f"(({self._print(expr)}) if {test} else {text})"
        return text


#: ``math.sin(name)`` or ``math.cos(name)`` of a plain name in generated code (:meth:`_Writer.shared_trig`)
_TRIG_CALL = re.compile(r"math\.(sin|cos)\(([A-Za-z_]\w*)\)")


_ASSIGNED = re.compile(r"    ([A-Za-z_]\w*) = ")
_WORD = re.compile(r"[A-Za-z_]\w*")
_SOLVE = re.compile(r"\b_?newton\w*\(")


def _live(body: list) -> list:
    """``body`` (the lines of one generated function, straight-line code, each name assigned once)
    without the top-level assignments ``name = ...`` of a name no other line reads (a constant
    folded into every use, a value this function does not return); a loop's solve is kept."""
    count: dict = {}
    for line in body:
        for w in _WORD.findall(line):
            count[w] = count.get(w, 0) + 1
    keep = [True] * len(body)
    for i in range(len(body) - 1, -1, -1):           # last first: a dropped line frees what it read
        m = _ASSIGNED.match(body[i])
        if m and count[m.group(1)] == 1 and not _SOLVE.search(body[i]):
            keep[i] = False
            for w in _WORD.findall(body[i]):
                count[w] -= 1
    return [line for line, k in zip(body, keep) if k]


def _ident(name: str, taken: set) -> str:
    base = re.sub(r"\W", "_", name).strip("_") or "v"
    if base[0].isdigit():
        base = "v_" + base
    cand, k = base, 1
    while cand in taken:
        k += 1
        cand = f"{base}_{k}"
    taken.add(cand)
    return cand


def switch_list(writer) -> list:
    """The model's switching functions in a fixed order: those of the evaluation order's steps and
    of the inputs (a step in a source is an event too); constant ones are left out.  A function and
    its negative are one switch (``max(q, 0)`` switches on ``-q``, its slope ``Heaviside(q)`` on
    ``q``): two would cross at the same instant and each restart would flip the other back."""
    exprs = [e for u in writer.units for e in u.exprs] + [sp.sympify(e) for e in writer.eq.inputs.values()]
    out: dict = {}
    for s in (s for e in exprs for s in switching_functions(e) if s.free_symbols):
        if s not in out and -s not in out:
            out[s] = None
    return list(out) + [sp.sympify(e) for e, _m, _o in computable_monitors(writer.eq)]


def computable_monitors(eq) -> list:
    """The monitors ``(expr, Monitor, element)`` of ``eq`` (:class:`multipole.network.Monitor`), every one
    of them (pruning keeps what they read; one the equations cannot compute is a ``ModelError``).  They follow the switching functions of the laws in :func:`switch_list`: a monitor is
    located like a switching event on every backend, but no law reads its side."""
    known = {s.symbol for s in eq.states} | set(eq.params) | set(eq.inputs) | {T}
    known |= {v for b in eq.blocks for v in b.variables}
    monitors = getattr(eq, "monitors", [])
    for expr, m, owner in monitors:
        unknown = sp.sympify(expr).free_symbols - known
        if unknown:         # pruning keeps what monitors read: this is a defect, never a silent drop
            raise ModelError("monitor_not_computable",
                             f"{owner}: run-time monitor {m.code} reads {', '.join(sorted(map(str, unknown)))}, "
                             "which the equations do not compute",
                             "report this: the monitor would be lost")
    return list(monitors)


def modal_switches(writer, sw) -> dict:
    """``{switching function: index}`` of the switches in ``sw`` that laws hold on a side (the
    monitors at its end are left out)."""
    n = len(sw) - len(computable_monitors(writer.eq))
    return {g: k for k, g in enumerate(sw[:n])}


def monitor_lines(writer, sw) -> list:
    """``MONITORS``, generated code: ``(switch index, element, code, text, stop, fix)`` per monitor."""
    mons = computable_monitors(writer.eq)
    first = len(sw) - len(mons)
    return ["MONITORS = " + repr([(first + k, owner, m.code, m.text, bool(m.stop), m.fix)
                                  for k, (_e, m, owner) in enumerate(mons)])]


_PERIODIC = (sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc)


def time_switches(writer, sw) -> tuple[list, list, list]:
    """``(time_only, rate, roots)`` for the switching functions ``sw``: whether each depends on time
    alone (no state, through the intermediate variables and inputs it is computed from); for those
    the fastest angular rate of a sine/cosine/tangent of time inside it [rad/s] (0.0 if there is
    none, ``inf`` if an argument is not linear in t), and, where the function is a polynomial in t
    with simple real roots (``t - t1`` of a step, the edges of a pulse, a table's breakpoints), its
    crossings ``[(t, side after), ...]``, else None.  The driver finds the crossings of these
    functions before integrating (:func:`multipole.simulate.time_switch_schedule`)."""
    states = set(writer.states)
    inputs = {u: sp.sympify(e) for u, e in writer.eq.inputs.items()}
    time_only, rate, roots = [], [], []
    first_monitor = len(sw) - len(computable_monitors(writer.eq))
    for k, g in enumerate(sw):
        units = _closure(writer.units, g.free_symbols)
        if k >= first_monitor:          # a monitor is always watched: a stop ends the run where it crosses
            time_only.append(False)
            rate.append(0.0)
            roots.append(None)
            continue
        syms = set(g.free_symbols).union(*(u.deps for u in units))
        syms |= set().union(*(inputs[u].free_symbols for u in syms if u in inputs))
        if syms & states or syms & set(writer.runtime) or any(u.kind != "assign" for u in units):
            time_only.append(False)     # (a runtime parameter: its crossings move from run to run)
            rate.append(0.0)
            roots.append(None)
            continue
        subs = dict(inputs)
        subs.update({v: e for u in units for v, e in zip(u.variables, u.exprs)})
        expr = sp.sympify(g)
        for _ in range(len(units) + 2):          # inline the evaluation order (it is acyclic)
            expr = expr.xreplace(subs).xreplace(writer.pvals)
        fastest = 0.0
        for node in sp.preorder_traversal(expr):
            if isinstance(node, _PERIODIC) and node.args[0].has(T):
                slope = sp.diff(node.args[0], T)
                fastest = max(fastest, abs(float(slope)) if not slope.free_symbols else math.inf)
        time_only.append(True)
        rate.append(fastest)
        roots.append(_polynomial_crossings(expr))
    return time_only, rate, roots


def _polynomial_crossings(expr) -> list | None:
    """``[(t, side after), ...]``: the simple real roots of ``expr`` if it is a polynomial in t, else
    None (also where a root is multiple: the sign may not change there)."""
    if not expr.is_polynomial(T):
        return None
    try:
        coeffs = [float(c) for c in sp.Poly(expr, T).all_coeffs()]
    except (TypeError, ValueError, sp.PolynomialError):
        return None
    if len(coeffs) < 2 or not all(math.isfinite(c) for c in coeffs) or coeffs[0] == 0.0:
        return None
    if len(coeffs) == 2:
        a, b = coeffs
        return [(-b / a, math.copysign(1.0, a))] if math.isfinite(-b / a) else None
    out = []
    slope = np.polyder(coeffs)
    for r in np.roots(coeffs):
        if abs(r.imag) > 1e-12 * max(1.0, abs(r.real)):
            continue
        s = float(np.polyval(slope, r.real))
        if abs(s) <= 1e-9 * max(abs(c) for c in coeffs):
            return None
        out.append((float(r.real), math.copysign(1.0, s)))
    return sorted(out)


def time_switch_lines(writer, sw) -> list:
    """``SWITCH_TIME_ONLY``, ``SWITCH_RATE`` and ``SWITCH_ROOTS`` (see :func:`time_switches`) as
    generated code."""
    time_only, rate, roots = time_switches(writer, sw)
    return [f"SWITCH_TIME_ONLY = {time_only!r}",
            "SWITCH_RATE = [" + ", ".join("math.inf" if math.isinf(r) else repr(float(r)) for r in rate) + "]",
            f"SWITCH_ROOTS = {roots!r}"]


class Model:
    """Compiled model: ``rhs(t, x)``, ``jac(t, x)``, ``outputs(t, x)``, ``switches(t, x)``.

    Built from the generated ``source`` and a small ``meta`` record (names, initial state, units,
    aliases), so a model can also be restored from the on-disk cache without sympy.
    """

    def __init__(self, source: str, meta: dict, equations: Equations | None = None):
        self.equations = equations
        self.meta = meta
        self.name = meta["name"]
        self.state_names = list(meta["state_names"])
        self.output_names = list(meta["outputs"])
        self.output_units = [meta["units"].get(o, "") for o in self.output_names]
        self.x0 = np.array(meta["x0"], dtype=float)
        self.source = source
        self.compile_time = 0.0
        self.cached = False
        key = hashlib.sha256(source.encode()).hexdigest()
        code = _CACHE.get(key)
        if code is None:
            code = _CACHE[key] = compile(source, f"<multipole model {self.name} {key[:8]}>", "exec")
        namespace = {"newton": newton, "math": math, "np": np}
        exec(code, namespace)   # our own generated source: numbers and sanitised names only
        self.stats = namespace["_stats"]
        self.rhs = namespace["rhs"]
        self.jac = namespace["jac"]
        self.outputs = namespace["outputs"]
        self.switches = namespace["switches"]
        self.n_switches = namespace["N_SWITCHES"]
        self.mode = namespace.get("_mode")              # the sides the *_in_mode functions use
        self.rhs_in_mode = namespace.get("rhs_in_mode", self.rhs)
        self.jac_in_mode = namespace.get("jac_in_mode", self.jac)
        #: the Jacobian as a csc_array (large models, :data:`SPARSE_JACOBIAN_STATES`), else None
        self.jac_sparse = namespace.get("jac_sparse")
        self.jac_sparse_in_mode = namespace.get("jac_in_mode_sparse", self.jac_sparse)
        self.switch_text = namespace["SWITCH_TEXT"]
        #: per switching function: depends on time alone, and its fastest sine rate [rad/s]
        self.switch_time_only = list(namespace.get("SWITCH_TIME_ONLY", [False] * self.n_switches))
        self.switch_rate = list(namespace.get("SWITCH_RATE", [0.0] * self.n_switches))
        self.switch_roots = list(namespace.get("SWITCH_ROOTS", [None] * self.n_switches))
        self.values = namespace["values"]
        self.value_names = namespace["VALUE_NAMES"]
        #: the monitors: ``(switch index, element, code, text, stop, fix)`` (see :func:`monitor_lines`)
        self.monitors = list(namespace.get("MONITORS", []))
        self._namespace = namespace
        #: names of the parameters read at run time from ``_P`` (see :meth:`set_parameters`)
        self.runtime = list(meta.get("runtime", []))

    def set_parameters(self, values) -> None:
        """Give the runtime parameters (``self.runtime``, in SI units) new values for the next run:
        the initial state is recomputed, and the per-run memory (Newton warm starts, the stiffness
        estimate and the time-switch schedule the driver keeps on the model) is cleared, so a run
        depends only on its parameter vector, not on the runs before it."""
        values = [float(v) for v in values]
        if len(values) != len(self.runtime):
            raise ModelError("bad_parameters", f"{len(values)} values for {len(self.runtime)} runtime parameters",
                             f"give one value each for {', '.join(self.runtime)}")
        ns = self._namespace
        ns["_P"][:] = values
        for guess in ns["_guess"]:
            guess[:] = [0.0] * len(guess)
        self.x0 = np.array(ns["initial"](), dtype=float)
        self.__dict__.pop("_plans", None)
        self.__dict__.pop("_schedules", None)

    def port_values(self, t: float, x) -> dict:
        """Value of every port variable ``path.port.e`` / ``.f`` (and states, inputs) at (t, x)."""
        known = dict(zip(self.value_names, self.values(t, np.asarray(x, dtype=float))))
        known.update(zip(self.state_names, np.asarray(x, dtype=float).tolist()))
        out = dict(known)
        for name, (rep, sign) in self.meta["aliases"].items():
            if rep in known:
                out[name] = sign * known[rep]
        return out

    def set_mode(self, sides) -> None:
        """Hold switching function k on side ``sides[k]`` (±1) in ``rhs_in_mode``/``jac_in_mode``."""
        if self.mode is not None:
            self.mode[:] = [1.0 if s > 0 else -1.0 for s in sides]

    def reset_stats(self):
        for k in self.stats:
            self.stats[k] = 0


class _Unit:
    """One step of the evaluation order: an assignment, or a numeric loop solved as a whole."""

    def __init__(self, kind, variables, exprs, block):
        self.kind, self.variables, self.exprs, self.block = kind, variables, exprs, block
        self.deps = set().union(*(e.free_symbols for e in exprs)) if exprs else set()


def _units(eq: Equations) -> list:
    units = []
    for k, b in enumerate(eq.blocks):
        if b.solution is not None:
            units += [_Unit("assign", [v], [s], k) for v, s in zip(b.variables, b.solution)]
        else:
            units.append(_Unit(b.kind, list(b.variables), b.reads(), k))
    return units


def _closure(units: list, needed) -> list:
    """The units needed to compute ``needed``, in evaluation order."""
    keep, need = [], set(needed)
    for u in reversed(units):
        if need & set(u.variables):
            keep.append(u)
            need |= u.deps
    return keep[::-1]


@dataclass
class Derivative:
    """One step of a :class:`JacobianPlan`: ``name = code``, a derivative of a variable by a state."""

    name: str
    code: str


@dataclass
class LoopDerivatives:
    """One step of a :class:`JacobianPlan`: the derivatives of an algebraic loop's unknowns z by the
    states, ``Dz = -Jz⁻¹ G``, where ``Jz`` = d(residuals)/dz (a sympy matrix, parameters not folded:
    print it with the writer's ``P``) and ``G`` = d(residuals)/dx of shape ``(len(z), n_columns)``,
    given by its nonzero entries ``g = [(row, column, code)]``; ``names = [(row of z, column, name)]``
    are then set to ``Dz[row, column]``."""

    block: int
    jz: sp.Matrix
    g: list
    n_columns: int
    names: list


@dataclass
class JacobianPlan:
    """The forward-mode Jacobian of a model as data (:meth:`Writer.jacobian_plan`): the evaluation
    ``units`` the prologue must compute, the ``steps`` (:class:`Derivative`, :class:`LoopDerivatives`)
    in order, and the nonzero ``entries = [(i, j, name)]``: ``J[i, j] = name``."""

    units: list
    steps: list
    entries: list


class _Writer:
    """Prints the pieces of the generated module."""

    def __init__(self, eq: Equations, runtime=()):
        self.eq = eq
        self.states = [s.symbol for s in eq.states]
        self.index = {s: i for i, s in enumerate(self.states)}
        #: parameter symbols read from ``_P[k]`` at run time instead of being inlined
        self.runtime = list(runtime)
        self.pvals = {p: sp.Float(v) for p, v in eq.params.items() if p not in self.runtime}
        names: dict = {T: "t"}
        names.update({p: f"_P[{k}]" for k, p in enumerate(self.runtime)})
        taken = {"t"}
        for i, s in enumerate(self.states):
            names[s] = f"x{i}"
            taken.add(f"x{i}")
        for u in eq.inputs:
            names[u] = _ident(u.name, taken)
        for b in eq.blocks:
            for v in b.variables:
                names[v] = _ident(v.name, taken)
        self.names = names
        self.printer = _Printer(names)
        self.units = _units(eq)
        self._printed: dict = {}
        self._lines: dict = {}
        self._folded: dict = {}
        #: module-level functions the loops' code calls (their residual and Newton functions)
        self.blocks_src: list = []
        self._loop_functions: dict = {}      # loop -> {its residuals' code: suffix of its functions}
        self.values = {p: float(v) for p, v in eq.params.items() if p not in self.runtime}
        self._constants()

    def _constants(self) -> None:
        """Inputs and computed variables whose value is a number (a constant source, a port held at
        zero, their negatives, ...) join the parameters in ``pvals``/``values``: every expression is
        printed with the number, so the terms they zero vanish and their assignments are dead code
        (:meth:`function` drops them)."""
        for u, e in self.eq.inputs.items():
            self._constant(u, e)
        for unit in self.units:
            if unit.kind == "assign":
                self._constant(unit.variables[0], unit.exprs[0])

    def _constant(self, v, e) -> None:
        value = sp.sympify(e).xreplace(self.pvals)
        if value.is_number and value.is_finite and value.is_real:
            number = float(value)           # (sympy's Float does not take a symbolic number like 62*pi)
            self.pvals[v], self.values[v] = sp.Float(number), number

    def locked(self, modes: dict | None):
        """Print in fixed switching modes (``modes``: switching function → index) or, with None, as
        plain functions of the state."""
        self.printer.modes = None if modes is None else {sp.sympify(g).xreplace(self.pvals): k
                                                           for g, k in modes.items()}

    def fold(self, e):
        """``e`` with the parameters replaced by their values (cached: the same expression is printed
        in several functions)."""
        folded = self._folded.get(e)
        if folded is None:
            folded = self._folded[e] = sp.sympify(e).xreplace(self.pvals)
        return folded

    def P(self, e) -> str:
        e = sp.sympify(e)
        key = (e, self.printer.modes is not None)
        text = self._printed.get(key)
        if text is None:
            text = _plain(e, self.printer, self.values)
        if text is None:
            folded = self.fold(e)
            if folded.has(sp.zoo, sp.oo, sp.nan):
                bad = sorted(str(p) for p in e.free_symbols if p in self.pvals and float(self.pvals[p]) == 0.0)
                raise ModelError("infinite_value", f"the parameters make {e} infinite"
                                 + (f" ({', '.join(bad)} = 0)" if bad else ""),
                                 "a zero inertia, stiffness or resistance divides; use a node or a rigid coupling instead")
            try:
                text = self.printer.doprint(folded)
            except (ValueError, TypeError, NotImplementedError) as exc:   # sympy's printers raise these
                owners = sorted({v.name.split(".")[0] for v in e.free_symbols if "." in v.name})
                text = str(e) if len(str(e)) <= 100 else str(e)[:97] + "..."
                raise ModelError("unsupported_expression", f"no code can be generated for {text}"
                                 + (f" (element {', '.join(owners)})" if owners else "")
                                 + f": the code printer has no form for part of it ({str(exc).splitlines()[0][:80]})",
                                 "simplify the law (e.g. no function of a discontinuous function), or regularise "
                                 "it (tanh instead of sign)") from None
        self._printed[key] = text
        return text

    def prologue(self, units, extra=()) -> list:
        n = len(self.states)
        lines = []
        if n == 1:
            lines.append("    x0 = float(x[0])")
        elif n:
            lines.append(f"    {', '.join(self.names[s] for s in self.states)}, = x.tolist()")
        used = set(extra).union(*(u.deps for u in units)) if units else set(extra)
        lines += [f"    {self.names[u]} = {self.P(e)}" for u, e in self.eq.inputs.items() if u in used]
        for u in units:
            lines += self.unit_lines(u)
        return lines

    def unit_lines(self, u: _Unit) -> list:
        key = (id(u), self.printer.modes is not None)
        if key not in self._lines:
            self._lines[key] = self._unit_lines(u)
        return self._lines[key]

    def assignment(self, name: str, expr) -> list:
        """``name = expr``; a large expression (the effective inertia of a mechanism, say) is split
        by common-subexpression elimination into temporaries ``_cN`` computed once."""
        if _plain(sp.sympify(expr), self.printer, self.values) is not None:
            return [f"    {name} = {self.P(expr)}"]
        folded = self.fold(expr)
        if _small(folded) or sp.count_ops(folded) <= CSE_MIN_OPS:
            return [f"    {name} = {self.P(expr)}"]
        self._cse_count = getattr(self, "_cse_count", 0) + 1
        temps, (reduced,) = sp.cse([folded], symbols=sp.numbered_symbols(f"_c{self._cse_count}_"))
        lines = []
        for sym, sub in temps:
            self.names[sym] = str(sym)
            lines.append(f"    {sym} = {self.P(sub)}")
        return lines + [f"    {name} = {self.P(reduced)}"]

    def _unit_lines(self, u: _Unit) -> list:
        N, P = self.names, self.P
        zs = u.variables
        if u.kind == "assign":
            return self.assignment(N[zs[0]], u.exprs[0])
        b = self.eq.blocks[u.block]
        n = len(zs)
        lhs = f"    {', '.join(N[z] for z in zs)}, ="
        if u.kind == "linear" and n <= UNROLL_MAX_UNKNOWNS:
            return self.elimination_lines(b.matrix, b.rhs, [N[z] for z in zs])
        if u.kind == "linear":
            return self.matrix_lines("_A", b.matrix) + [f"    _b = np.array([{', '.join(P(x) for x in b.rhs)}])",
                                                        f"{lhs} np.linalg.solve(_A, _b).tolist()"]
        k = u.block
        if b.closed_form is not None:
            return self.closed_form_lines(b, zs, k)
        if n <= SCALAR_NEWTON_MAX:
            return self.scalar_newton(b, zs, k)
        Jz = _jacobian(b.residuals, zs)
        seed = [f"    _guess[{k}] = [{', '.join(N[v] for v in b.start)}]"] if b.start else []
        return seed + self._newton_lines(b, zs, Jz, k, lhs)

    #: what the generated code does where a closed form's square root has a negative radicand
    #: (``{k}``: the loop, ``{r}``: the radicand's name; numba: nothing, the root is NaN and the
    #: integrator rejects the step)
    NO_ROOT = "raise closure_failed({k}, {r})"

    def closed_form_lines(self, b, zs, k) -> list:
        """Position closure ``k`` (unknowns ``zs``) by its formula (:class:`multipole.network.ClosedForm`):
        the branches' common subexpressions once, every square root's radicand named and tested
        (:attr:`NO_ROOT`), each unknown picked from the branch the sign of ``select`` names; an angle
        is ``atan2`` continued to the turn of its integrated value, and its cosine and sine are the
        branch's pair, named as :meth:`shared_trig` names them, so nothing calls a trigonometric
        function of it."""
        N, P = self.names, self.P
        cf = b.closed_form
        entries = [[v if isinstance(v, tuple) else (v,) for v in branch] for branch in cf.branches]
        exprs = [self.fold(e) for branch in entries for v in branch for e in v]
        if cf.select is not None:
            exprs.append(self.fold(cf.select))
        prefix = f"_k{k}_"
        roots: dict = {}

        def root(arg):
            if arg not in roots:
                roots[arg] = sp.Symbol(f"{prefix}q{len(roots)}")
            return roots[arg]
        exprs = [e.replace(lambda x: x.is_Pow and x.exp == sp.S.Half, lambda x: root(x.base)) for e in exprs]
        radicands = list(roots)
        temps, reduced = cse_keeping_trig(radicands + exprs, f"{prefix}c")
        items = list(temps)
        for i, (arg, sym) in enumerate(roots.items()):
            rad = sp.Symbol(f"{prefix}r{i}")
            items += [(rad, reduced[i]), (sym, sp.sqrt(rad))]
        reduced = reduced[len(radicands):]
        for sym, _e in items:
            N[sym] = str(sym)
        lines, done = [], set()
        pending = items
        while pending:                   # in dependency order (a radicand before its root before its uses)
            later = []
            for sym, e in pending:
                if (e.free_symbols & {s for s, _e in items}) - done:
                    later.append((sym, e))
                    continue
                if sym in roots.values() and self.NO_ROOT is not None:
                    rad = N[e.args[0]] if e.is_Pow else N[e]
                    lines += [f"    if not {rad} >= 0.0:", "        " + self.NO_ROOT.format(k=k, r=rad)]
                lines.append(f"    {N[sym]} = {P(e)}")
                done.add(sym)
            if len(later) == len(pending):
                raise ModelError("codegen", f"the closed form of loop {k} cannot be ordered")
            pending = later
        width = sum(len(v) for v in entries[0])
        picks = [P(e) for e in reduced[:width]]
        if len(entries) == 2:
            sel = f"{prefix}s"
            lines.append(f"    {sel} = {P(reduced[-1])}")
            picks = [f"({a} if {sel} >= 0.0 else {c})" for a, c in zip(picks, (P(e) for e in reduced[width:2 * width]))]
        at = 0
        for z, start, v in zip(zs, b.start, entries[0]):
            if len(v) == 1:
                lines.append(f"    {N[z]} = {picks[at]}")
            else:
                angle = f"{prefix}a{at}"
                lines += [f"    _cos_{N[z]} = {picks[at]}", f"    _sin_{N[z]} = {picks[at + 1]}",
                          f"    {angle} = math.atan2(_sin_{N[z]}, _cos_{N[z]})",
                          f"    {N[z]} = {angle} + {2 * math.pi!r} * math.floor(({N[start]} - {angle}) / "
                          f"{2 * math.pi!r} + 0.5)"]
            at += len(v)
        return lines

    def scalar_newton(self, b, zs, k) -> list:
        """The call of loop ``k``'s Newton function (up to :data:`SCALAR_NEWTON_MAX` unknowns ``zs``),
        after the residuals' terms free of the unknowns (:func:`loop_invariants`); the first call in
        each printing mode adds the module-level residual function ``_blk{k}`` (the residuals and
        their Jacobian as one tuple, sines and cosines shared, NaN where not computable) and Newton
        function ``_newton{k}`` (:func:`scalar_newton_lines`) to :attr:`blocks_src` (again, as
        ``_newton{k}_m``, only where the residuals print otherwise in fixed switching modes)."""
        N, P = self.names, self.P
        n = len(zs)
        res, hoisted = loop_invariants([self.fold(r) for r in b.residuals], zs, f"_l{k}_")
        for sym, _e in hoisted:
            N[sym] = str(sym)
        Jz = sp.Matrix(res).jacobian(zs)
        free = set().union(*(e.free_symbols for e in list(res) + list(Jz)))
        deps = sorted(free - set(zs) - set(self.runtime), key=lambda v: N[v])     # (runtime: _P, a global)
        start = [N[v] for v in b.start] if b.start else [f"_guess[{k}][{i}]" for i in range(n)]
        values = [P(r) for r in res] + [P(Jz[i, j]) for i in range(n) for j in range(n)]
        body = self.shared_trig([f"    return ({', '.join(values)},)"])
        printed = self._loop_functions.setdefault(k, {})
        known = body[-1] in printed
        mode = printed.setdefault(body[-1], "_m" if printed else "")
        lines = [f"    {N[sym]} = {P(e)}" for sym, e in hoisted]
        lines.append(f"    {', '.join(N[z] for z in zs)}, = _newton{k}{mode}({', '.join(start + [N[d] for d in deps])})")
        if known:
            return lines
        names = ", ".join(N[v] for v in list(zs) + deps)
        self.blocks_src += [f"def _blk{k}{mode}({names}):",
                            f'    """Residuals of the algebraic loop {k} and their Jacobian (NaN where not computable)."""',
                            "    try:"] + ["    " + line for line in body] + \
            ["    except (OverflowError, ValueError, ZeroDivisionError):",
             f"        return ({', '.join('math.nan' for _ in values)},)", ""]
        args = "".join(f", _a{i}" for i in range(len(deps)))
        params = ", ".join(f"s{i}" for i in range(n)) + args
        zs_ = ", ".join(f"z{i}" for i in range(n)) + ","
        done = ["_stats['newton_iterations'] += total", "_stats['newton_solves'] += 1"]
        done += [] if b.start else [f"_guess[{k}] = [{zs_}]"]
        self.blocks_src += scalar_newton_lines(
            f"_newton{k}{mode}", params, n, [f"s{i}" for i in range(n)], f"_blk{k}{mode}({{z}}{args})",
            done + [f"return {zs_}"],
            [f"raise newton_failed({k}, _blk{k}{mode}({', '.join(f's{i}' for i in range(n))}{args})[:{n}], total)"],
            f"Damped Newton for the loop {k} from (s0, ...), then from zero; its solution as a tuple.")
        return lines

    def _newton_lines(self, b, zs, Jz, k, lhs) -> list:
        N, P = self.names, self.P
        n = len(zs)
        residuals = f"np.array([{', '.join(P(r) for r in b.residuals)}])"
        if n <= DENSE_MAX_UNKNOWNS:
            rows = ", ".join("[" + ", ".join(P(Jz[i, j]) for j in range(n)) + "]" for i in range(n))
            body = [f"        return ({residuals}, np.array([{rows}]))"]
        else:
            body = self.matrix_lines("_Jz", Jz, "        ") + [f"        return ({residuals}, _Jz)"]
        return [f"    def _blk{k}(_z):", f"        {', '.join(N[z] for z in zs)}, = _z.tolist()"] + body + \
            [f"{lhs} newton(_blk{k}, _guess, {k}, _stats).tolist()"]

    #: what the generated code does where a pivot column is zero (numba: nothing, the division makes
    #: the values NaN and the integrator stops)
    SINGULAR = "raise np.linalg.LinAlgError('singular matrix')"

    def elimination_lines(self, A, b, names: list) -> list:
        """``names = A⁻¹ b`` as straight-line scalar code, no arrays and no solver call: the entries of
        ``A`` and ``b`` (:meth:`loop_entry_lines`), then Cramer's rule (:meth:`cramer_lines`, up to
        :data:`CRAMER_UNROLL_MAX` unknowns) or Gaussian elimination with partial pivoting
        (:meth:`pivot_lines`), whichever takes fewer operations for the unknowns the right-hand side
        reads (:func:`_operations`): the slider-crank's and the four-bar's acceleration loops read one
        of 3 and 5 unknowns, which Cramer's rule gets in a third of the elimination's operations."""
        n = len(names)
        nz = {i: {j for j in range(n) if A[i, j] != 0} for i in range(n)}     # row id -> its nonzero columns
        self._cse_count = tag = getattr(self, "_cse_count", 0) + 1     # this loop's temporaries: _e{tag}_...
        lines = self.loop_entry_lines([(f"_a{i}_{j}", A[i, j]) for i in range(n) for j in sorted(nz[i])]
                                      + [(f"_r{i}", b[i]) for i in range(n)], tag)
        pivots = self.pivot_lines({i: set(c) for i, c in nz.items()}, names)
        if n > CRAMER_UNROLL_MAX:
            return lines + pivots
        cramer = self.cramer_lines(nz, names, tag)
        wanted = [v for v in names if v in self._rhs_reads()] or names
        if _operations(cramer, wanted) >= _operations(pivots, wanted):
            return lines + pivots
        # Cramer's rule only reads the entries: one that is a name (a shared temporary, a variable) is
        # read as that name, not copied
        copies = dict(m.groups() for m in map(_COPY.fullmatch, lines) if m)
        return [line for line in lines if not _COPY.fullmatch(line)] + \
            [_ENTRY.sub(lambda m: copies.get(m.group(0), m.group(0)), line) for line in cramer]

    def pivot_lines(self, nz, names: list) -> list:
        """``names = A⁻¹ b`` over the entries ``_ai_j`` (nonzero columns ``nz[i]`` of row ``i``, updated
        here with the fill-in) and ``_ri`` printed before: Gaussian elimination with partial pivoting,
        unrolled over the sparsity pattern of ``A`` (a structural zero is never multiplied; a column
        with one candidate pivot is swapped while printing, one with several chooses the largest at
        run time)."""
        n = len(names)
        lines: list = []
        rows = list(range(n))            # position -> row id
        for k in range(n):
            cand = [i for i in range(k, n) if k in nz[rows[i]]]
            if not cand:
                raise ModelError("singular_loop", "a linear loop's matrix is structurally singular",
                                 "report this: the causality analysis should have refused the network")
            rows[k], rows[cand[0]] = rows[cand[0]], rows[k]      # the first candidate: swapped while printing
            if len(cand) > 1:
                ids = [rows[k]] + [rows[i] for i in cand[1:]]
                union = set().union(*(nz[r] for r in ids)) - set(range(k))
                for r in ids:
                    lines += [f"    _a{r}_{j} = 0.0" for j in sorted(union - nz[r])]
                    nz[r] = set(union)
                first = ids[0]
                lines += [f"    _p = {first}", f"    _m = abs(_a{first}_{k})"]
                for r in ids[1:]:
                    lines += [f"    if abs(_a{r}_{k}) > _m:", f"        _p = {r}", f"        _m = abs(_a{r}_{k})"]
                if self.SINGULAR:
                    lines += ["    if _m == 0.0:", f"        {self.SINGULAR}"]
                cols = sorted(union)
                mine = [f"_a{first}_{j}" for j in cols] + [f"_r{first}"]
                for r in ids[1:]:
                    theirs = [f"_a{r}_{j}" for j in cols] + [f"_r{r}"]
                    lines += [f"    if _p == {r}:",
                              f"        {', '.join(mine + theirs)} = {', '.join(theirs + mine)}"]
            rk = rows[k]
            below = [rows[i] for i in range(k + 1, n) if k in nz[rows[i]]]
            if below:
                lines.append(f"    _d = 1.0 / _a{rk}_{k}")
            for r in below:
                lines.append(f"    _f = _a{r}_{k} * _d")
                for j in sorted(c for c in nz[rk] if c > k):
                    lines.append(f"    _a{r}_{j} -= _f * _a{rk}_{j}" if j in nz[r] else f"    _a{r}_{j} = -_f * _a{rk}_{j}")
                    nz[r].add(j)
                lines.append(f"    _r{r} -= _f * _r{rk}")
        for k in range(n - 1, -1, -1):
            rk = rows[k]
            terms = "".join(f" - _a{rk}_{j} * {names[j]}" for j in sorted(c for c in nz[rk] if c > k))
            lines.append(f"    {names[k]} = (_r{rk}{terms}) / _a{rk}_{k}")
        return lines

    def cramer_lines(self, nz, names: list, tag) -> list:
        """``names = A⁻¹ b`` by Cramer's rule over the entries ``_ai_j`` (nonzero columns ``nz[i]`` of
        row ``i``) and ``_ri`` printed before: each unknown ``Σ_k r_k C_ki / det A`` with the cofactors
        ``C_ki`` of ``A``, minors named ``_m{tag}_N`` once each (a structural zero is never multiplied), and
        ``det A`` expanded along the column of an unknown the right-hand side reads, whose cofactors it
        computes anyway (:meth:`Python functions <function>` drop the lines nothing reads: the
        slider-crank's 3 × 3 acceleration loop costs 3 cofactors, the determinant and one quotient
        where the elimination had 28 lines with its pivot search)."""
        n = len(names)
        lines: list = []
        minors: dict = {}

        def entry(r, c):
            return f"_a{r}_{c}" if c in nz[r] else None

        def minor(rows, cols):           # the determinant of A[rows, cols] as code, None if structurally 0
            if not rows:
                return "1.0"             # (of a 1 × 1 loop's cofactor)
            if len(rows) == 1:
                return entry(rows[0], cols[0])
            key = (rows, cols)
            if key not in minors:
                terms = []
                for at, c in enumerate(cols):     # along the first row
                    sub = None if c not in nz[rows[0]] else minor(rows[1:], cols[:at] + cols[at + 1:])
                    if sub is not None:
                        terms.append(("-" if at % 2 else "+", f"_a{rows[0]}_{c} * {sub}"))
                minors[key] = None
                if terms:
                    name = f"_m{tag}_{len(lines)}"
                    lines.append(f"    {name} = " + _signed_sum(terms))
                    minors[key] = name
            return minors[key]

        def cofactor(k, i):
            m = minor(tuple(r for r in range(n) if r != k), tuple(c for c in range(n) if c != i))
            return None if m is None else ("-" if (k + i) % 2 else "+", m)
        wanted = self._rhs_reads()
        along = next((j for j in range(n) if names[j] in wanted), 0)
        terms = [(s, f"_a{k}_{along} * {m}") for k in range(n) if along in nz[k]
                 for s, m in [cofactor(k, along) or ("", None)] if m is not None]
        if not terms:
            raise ModelError("singular_loop", "a linear loop's matrix is structurally singular",
                             "report this: the causality analysis should have refused the network")
        det = f"_det{tag}"
        lines.append(f"    {det} = " + _signed_sum(terms))
        if self.SINGULAR:
            lines += [f"    if {det} == 0.0:", f"        {self.SINGULAR}"]
        for i in range(n):
            num = [(s, f"_r{k} * {m}") for k in range(n) for s, m in [cofactor(k, i) or ("", None)] if m is not None]
            lines.append(f"    {names[i]} = ({_signed_sum(num) if num else '0.0'}) / {det}")
        return lines

    def _rhs_reads(self) -> set:
        """Names of the values the right-hand side reads (states' derivatives and every unit they need)."""
        if getattr(self, "_rhs_names", None) is None:
            units = _closure(self.units, self.eq.derivatives)
            read = set().union(*(u.deps - set(u.variables) for u in units),     # (a loop's residuals read its own)
                               *(sp.sympify(d).free_symbols for d in self.eq.derivatives))
            self._rhs_names = {self.names[v] for v in read if v in self.names}
        return self._rhs_names

    def loop_entry_lines(self, entries, tag) -> list:
        """``name = expr`` for the entries ``[(name, expr)]`` of one linear loop (its matrix and
        right-hand side), with their common subexpressions computed once, as temporaries ``_eN_k``
        (the rows of a mechanism's acceleration loop repeat the same velocity products and the mass
        matrix is symmetric; ``tag`` names the loop), and ``a·sin²u + b·cos²u`` folded to ``b + (a - b)·sin²u``
        (:func:`_pythagoras`).  Sines and cosines of a named value stay calls for :meth:`shared_trig`."""
        P = self.P
        temps, reduced = cse_keeping_trig([_pythagoras(self.fold(e)) for _name, e in entries], f"_e{tag}_")
        lines = []
        for sym, sub in temps:
            self.names[sym] = str(sym)
            lines.append(f"    {sym} = {P(sub)}")
        return lines + [f"    {name} = {P(e)}" for (name, _e), e in zip(entries, reduced)]

    def matrix_lines(self, name: str, M, indent: str = "    ") -> list:
        """``name = M`` as code: a literal array up to :data:`DENSE_MAX_UNKNOWNS` rows, else zeros and
        one assignment per nonzero entry (a loop of k unknowns has O(k) of its k² entries)."""
        r, c = M.shape
        if r <= DENSE_MAX_UNKNOWNS:
            rows = ", ".join("[" + ", ".join(self.P(M[i, j]) for j in range(c)) + "]" for i in range(r))
            return [f"{indent}{name} = np.array([{rows}])"]
        return [f"{indent}{name} = np.zeros(({r}, {c}))"] + \
            [f"{indent}{name}[{i}, {j}] = {self.P(v)}" for (i, j), v in sorted(M.todok().items())]

    def affine_rows(self):
        """Rows of ``M`` with ``rhs = M @ [x, u, 1]``, or None where the model is not affine.

        Affine means: every step of the right-hand side is a sum of constant multiples of states,
        inputs that depend on time only, and constants (springs, masses, dampers, ideal gears).
        Returns ``(rows, inputs)``: per derivative a ``{column: coefficient}`` map, and the input
        symbols in column order (after the states; the last column is the constant 1).
        """
        n = len(self.states)
        units = _closure(self.units, self.eq.derivatives)
        if any(u.kind != "assign" for u in units):
            return None
        used = set().union(*(u.deps for u in units), *(sp.sympify(d).free_symbols for d in self.eq.derivatives))
        inputs = [u for u, e in self.eq.inputs.items() if u in used]
        if any(sp.sympify(self.eq.inputs[u]).xreplace(self.pvals).free_symbols - {T} for u in inputs):
            return None
        one = n + len(inputs)
        col: dict = {s: {i: 1.0} for i, s in enumerate(self.states)}
        col.update({u: {n + k: 1.0} for k, u in enumerate(inputs)})

        def combine(expr):
            terms = _linear_form(sp.sympify(expr), self.values)
            if terms is None:
                terms = _affine_terms(self.fold(expr))
            if terms is None:
                return None
            acc: dict = {}
            for sym, c in terms:
                src = {one: 1.0} if sym is None else col.get(sym)
                if src is None:
                    return None
                for j, v in src.items():
                    acc[j] = acc.get(j, 0.0) + c * v
            return {j: v for j, v in acc.items() if v != 0.0}

        for u in units:
            acc = combine(u.exprs[0])
            if acc is None:
                return None
            col[u.variables[0]] = acc
        rows = [combine(d) for d in self.eq.derivatives]
        return None if any(r is None for r in rows) else (rows, inputs)

    def affine_rhs(self, affine) -> list:
        """``rhs`` as one sparse product ``M @ [x, u, 1]`` (see :meth:`affine_rows`)."""
        rows, inputs = affine
        n = len(self.states)
        data, indices, indptr = [], [], [0]
        for r in rows:
            for j in sorted(r):
                indices.append(j)
                data.append(r[j])
            indptr.append(len(indices))
        shape = (n, n + len(inputs) + 1)
        ext = ", ".join([self.names[u] for u in inputs] + ["1.0"])
        head = [f"_M = csr_array((np.array({data!r}), np.array({indices!r}), np.array({indptr!r})), shape={shape!r})",
                "", "def rhs(t, x):",
                f'    """d/dt of the states {", ".join(self.eq.state_names)} as M @ [x, inputs, 1]."""',
                "    _stats['rhs_calls'] += 1"]
        body = [f"    {self.names[u]} = {self.P(self.eq.inputs[u])}" for u in inputs]
        return head + body + [f"    return _M @ np.concatenate((x, [{ext}]))", ""]

    def affine_jacobian(self, sparse: bool = False) -> list:
        """``jac`` of an affine right-hand side (see :meth:`affine_rhs`): the state columns of ``M``,
        constant.  The forward-mode code it replaces has a line per nonzero, and compiling that
        function (60,000 lines for 20,000 states) took gigabytes.  ``sparse``: also ``jac_sparse``,
        the same columns as a ``csc_array`` (and ``jac`` its dense copy)."""
        n = len(self.states)
        if sparse:
            return [f"_M_STATES = _M[:, :{n}].tocsc()", "", "def jac_sparse(t, x):",
                    '    """Jacobian d(rhs)/dx as a csc_array: the state columns of M (an affine model)."""',
                    "    _stats['jac_calls'] += 1", "    return _M_STATES.copy()", ""] + self._dense_view("jac")
        return [f"_M_STATES = _M[:, :{n}]", "", "def jac(t, x):",
                '    """Jacobian d(rhs)/dx: the state columns of M (an affine model)."""',
                "    _stats['jac_calls'] += 1", "    return _M_STATES.toarray()", ""]

    @staticmethod
    def _dense_view(name: str) -> list:
        """``name(t, x)``: the dense array of ``name_sparse(t, x)`` (for eigenvalues, LSODA, GL4)."""
        return [f"def {name}(t, x):", f'    """Jacobian d(rhs)/dx as a dense array (of {name}_sparse)."""',
                f"    return {name}_sparse(t, x).toarray()", ""]

    def function(self, name, doc, needed, ret, extra=()) -> list:
        units = _closure(self.units, needed)
        return [f"def {name}(t, x):", f'    """{doc}"""'] + list(extra) + \
            _live(self.shared_trig(self.prologue(units, needed) + [f"    return {ret}"])) + [""]

    def shared_trig(self, body: list) -> list:
        """``body`` (the lines of one Python function) with every ``math.sin(v)`` and ``math.cos(v)`` of
        a named value ``v`` (a state, an input, a computed variable: each assigned once) in its
        top-level statements computed once, as ``_sin_v``/``_cos_v`` just before its first use (a
        mechanism's equations repeat the sine and cosine of each angle dozens of times; Python's
        interpreter does not share them, numba's compiler does).  Lines of a nested function
        (a loop's residual, indented deeper) are left alone: their names are the iteration's own."""
        named = set(self.names.values())
        done: set = set()
        out = []
        given = re.compile(r"    _(sin|cos)_(\w+) = ")     # a closed form's direction (closed_form_lines)

        def share(m):
            fn, v = m.group(1), m.group(2)
            if v not in named:
                return m.group(0)
            if (fn, v) not in done:
                done.add((fn, v))
                out.append(f"    _{fn}_{v} = math.{fn}({v})")
            return f"_{fn}_{v}"
        nested = False
        for line in body:
            top = line.startswith("    ") and not line.startswith("     ")
            nested = line.startswith("    def ") or (nested and not top)
            out.append(line if nested or not top else _TRIG_CALL.sub(share, line))   # temporaries first
            m = given.match(line)
            if m:
                done.add((m.group(1), m.group(2)))
        return out

    def jacobian_plan(self) -> "JacobianPlan":
        """The forward-mode Jacobian d(rhs)/dx through the evaluation order (sparse in the states)
        as structured steps that any printer writes out (:class:`JacobianPlan`); expressions are
        already printed by this writer's printer."""
        units = _closure(self.units, self.eq.derivatives)
        steps: list = []
        D: dict = {}
        count = 0
        for u in units:
            if u.kind == "assign":
                D[u.variables[0]] = {}
                for j, code in self.grad(u.exprs[0], (), D).items():
                    count += 1
                    steps.append(Derivative(f"_d{count}", code))
                    D[u.variables[0]][j] = f"_d{count}"
                continue
            b = self.eq.blocks[u.block]
            zs = u.variables
            cols: dict = {}
            for r_i, r in enumerate(b.residuals):
                for j, code in self.grad(r, zs, D).items():
                    cols.setdefault(j, {})[r_i] = code
            for z in zs:
                D[z] = {}
            if not cols:
                continue
            js = sorted(cols)
            g = [(r_i, c, code) for c, j in enumerate(js) for r_i, code in cols[j].items()]
            names = []
            for zi, z in enumerate(zs):
                for c, j in enumerate(js):
                    count += 1
                    names.append((zi, c, f"_d{count}"))
                    D[z][j] = f"_d{count}"
            steps.append(LoopDerivatives(u.block, _jacobian(b.residuals, zs), g, len(js), names))
        entries = [(i, j, name) for i, d in enumerate(self.eq.derivatives) for j, name in D.get(d, {}).items()]
        return JacobianPlan(units, steps, entries)

    def jacobian(self, name: str = "jac", sparse: bool = False) -> list:
        """The Jacobian function of the numpy backend, printed from :meth:`jacobian_plan`; with
        ``sparse``, ``name_sparse`` returns it as a ``csc_array`` of the plan's nonzero pattern (no
        n×n array: O(nonzeros) memory per call) and ``name`` is its dense copy."""
        plan = self.jacobian_plan()
        if sparse:
            return self._sparse_jacobian(name, plan)
        out = [f"def {name}(t, x):", '    """Jacobian d(rhs)/dx."""', "    _stats['jac_calls'] += 1"]
        n = len(self.states)
        out += _live(self.shared_trig(self.prologue(plan.units, self.eq.derivatives) + self._step_lines(plan)
                                      + [f"    _J = np.zeros(({n}, {n}))"]
                                      + [f"    _J[{i}, {j}] = {d}" for i, j, d in plan.entries] + ["    return _J"]))
        return out + [""]

    def _step_lines(self, plan: "JacobianPlan") -> list:
        """The steps of ``plan`` as code: afterwards every name in ``plan.entries`` is set."""
        out = []
        for step in plan.steps:
            if isinstance(step, Derivative):
                out.append(f"    {step.name} = {step.code}")
                continue
            n = step.jz.shape[0]
            out += self.matrix_lines("_Jz", step.jz) + [f"    _G = np.zeros(({n}, {step.n_columns}))"]
            out += [f"    _G[{r_i}, {c}] = {code}" for r_i, c, code in step.g]
            out.append("    _Dz = -np.linalg.solve(_Jz, _G)")
            out += [f"    {d} = _Dz[{zi}, {c}]" for zi, c, d in step.names]
        return out

    def _sparse_jacobian(self, name: str, plan: "JacobianPlan") -> list:
        """``name_sparse``: the entries of ``plan`` in column-major order as the data of a ``csc_array``
        whose pattern (row indices, column pointers) is fixed when the module is generated."""
        n = len(self.states)
        entries = sorted(plan.entries, key=lambda e: (e[1], e[0]))
        indptr = np.searchsorted([j for _, j, _ in entries], np.arange(n + 1)).tolist()
        pattern = f"_{name.upper()}_PATTERN"
        out = [f"{pattern} = (np.array({[i for i, _, _ in entries]!r}, dtype=np.int64), "
               f"np.array({indptr!r}, dtype=np.int64))", "",
               f"def {name}_sparse(t, x):", '    """Jacobian d(rhs)/dx as a csc_array."""',
               "    _stats['jac_calls'] += 1"]
        data = ", ".join(d for _, _, d in entries)
        out += _live(self.shared_trig(self.prologue(plan.units, self.eq.derivatives) + self._step_lines(plan)
                                      + [f"    _data = np.array([{data}], dtype=float)",
                                         f"    return csc_array((_data, {pattern}[0].copy(), {pattern}[1].copy()), "
                                         f"shape=({n}, {n}))"]))
        out += [""]
        return out + self._dense_view(name)

    def grad(self, expr, exclude, D) -> dict:
        """{state index: code} of d expr/dx through the symbols of ``expr`` not in ``exclude``."""
        acc: dict = {}
        # sorted: set order follows the hash seed, and the generated text must not
        for w in sorted(expr.free_symbols - set(exclude), key=sp.default_sort_key):
            if w in self.index:
                acc.setdefault(self.index[w], []).append(self.P(_diff(expr, w)))
            elif D.get(w):
                d = _diff(expr, w).xreplace(self.pvals)
                for j, name in D[w].items():
                    acc.setdefault(j, []).append(name if d == 1 else f"-{name}" if d == -1
                                                 else f"({self.P(d)})*{name}")
        return {j: " + ".join(acc[j]) for j in sorted(acc)}


def cse_keeping_trig(exprs, prefix: str):
    """``sympy.cse`` of ``exprs`` with temporaries named ``prefix0, prefix1, ...``, ``(temps,
    reduced)``, where a sine or cosine of a named value (a symbol) stays a call in the results
    instead of becoming a temporary of its own: :meth:`Writer.shared_trig` names those calls once
    per function, shared with the rest of it."""
    calls = set().union(*(e.atoms(sp.sin, sp.cos) for e in exprs)) if exprs else set()
    trig = {f: sp.Dummy() for f in sorted(calls, key=sp.default_sort_key) if f.args[0].is_Symbol}
    back = {d: f for f, d in trig.items()}
    temps, reduced = sp.cse([e.xreplace(trig) for e in exprs], symbols=sp.numbered_symbols(prefix),
                            optimizations=None)
    return [(s, e.xreplace(back)) for s, e in temps], [e.xreplace(back) for e in reduced]


def _operations(lines: list, wanted: list) -> int:
    """Arithmetic operations, comparisons and branches in the ``lines`` of a loop's solution that
    computing the names ``wanted`` needs (the lines a Python function keeps, :func:`_live`)."""
    live = _live(list(lines) + [f"    return {', '.join(wanted)}"])
    return sum(len(_OPERATION.findall(line)) for line in live)


_OPERATION = re.compile(r"[-+*/]|\babs\(|\bif\b")
_ENTRY = re.compile(r"\b_[ar]\d+(?:_\d+)?\b")                  # a loop's entry, _ai_j or _ri
_COPY = re.compile(r"    (_[ar]\d+(?:_\d+)?) = ([A-Za-z_]\w*)")   # an entry that is a name


def _signed_sum(terms) -> str:
    """``[(sign, code)]`` as one sum, e.g. ``a*b - c*d`` (a leading minus kept)."""
    first, rest = terms[0], terms[1:]
    return ("-" if first[0] == "-" else "") + first[1] + "".join(f" {s} {c}" for s, c in rest)


def _pythagoras(expr):
    """``expr`` with each pair of terms ``a·sin(u)²·R + b·cos(u)²·R`` of a sum (the same ``u`` and
    factor ``R``, numbers ``a`` and ``b``) replaced by ``b·R + (a - b)·sin(u)²·R`` — just ``a·R`` when
    ``a == b``: a body's inertia about a pivot, ``m·l²·(sin² + cos²) + J``, becomes a number.  Equal to
    ``expr`` to rounding; sums inside products and powers are folded too."""
    if not expr.has(sp.sin) or not expr.has(sp.cos):
        return expr
    if not expr.is_Add:
        return expr.func(*[_pythagoras(a) for a in expr.args]) if expr.args else expr
    terms = [_pythagoras(a) for a in expr.args]
    squares: dict = {}               # (u, R) -> {sin or cos: (index, coefficient)}
    for i, t in enumerate(terms):
        coeff, rest = t.as_coeff_Mul()
        factors = sp.Mul.make_args(rest)
        for f in factors:
            if f.is_Pow and f.exp == 2 and isinstance(f.base, (sp.sin, sp.cos)):
                others = sp.Mul(*[g for g in factors if g is not f])
                squares.setdefault((f.base.args[0], others), {})[f.base.func] = (i, coeff)
                break
    for (u, rest), pair in squares.items():
        if len(pair) < 2:
            continue
        (i, a), (j, c) = pair[sp.sin], pair[sp.cos]
        terms[j] = c * rest
        terms[i] = (a - c) * sp.sin(u) ** 2 * rest if a != c else sp.S.Zero
    return sp.Add(*terms)


def _const(e, values: dict) -> float | None:
    """Value of a float, a parameter or one over a parameter (nonzero, finite), else None."""
    if e.is_Float:
        v = float(e)
    elif e.is_Symbol and e in values:
        v = values[e]
    elif e.is_Pow and e.exp is sp.S.NegativeOne and e.base.is_Symbol and values.get(e.base):
        v = 1.0 / values[e.base]
    else:
        return None
    return v if v != 0.0 and math.isfinite(v) else None


def _term(e, printer, values: dict) -> str | None:
    """``e`` as code if it is a variable, a constant (see :func:`_const`), or a product of constants
    (integers among them) and one variable or a variable to an integer power ≥ 2 (``-w`` included),
    else None.  The parameters' values are printed as sympy would print the folded expression, with
    the same float products (sympy multiplies a product's numbers in the order of its arguments)."""
    if e.is_Symbol and e not in values:
        return printer._print_Symbol(e)
    c = _const(e, values)
    if c is not None:
        return printer._print_Float(c)
    if not e.is_Mul:
        return None
    w, coeff, folded = None, 1.0, False
    for f in e.args:
        v = _const(f, values)
        if v is not None:
            coeff, folded = coeff * v, True
        elif f.is_Integer:
            coeff *= float(f)
        elif w is None and (f.is_Symbol and f not in values or f.is_Pow and f.base.is_Symbol
                            and f.base not in values and f.exp.is_Integer and f.exp > 1):
            w = f
        else:
            return None
    if w is None:
        return None
    var = printer._print_Symbol(w) if w.is_Symbol else f"{printer._print_Symbol(w.base)}**{int(w.exp)}"
    if folded:
        return f"{printer._print_Float(coeff)}*{var}"
    return "-" + var if e.args[0] is sp.S.NegativeOne and len(e.args) == 2 else None


def _plain(e, printer, values: dict) -> str | None:
    """Code of the most common expressions of a network (a port variable, a constant times one, the
    sum or difference of two such terms) without folding the parameters in and without sympy's
    printer (both build sympy objects: about 0.5 ms per expression); None for anything else.  Two
    terms are exact in either order."""
    text = _term(e, printer, values)
    if text is not None or not (e.is_Add and len(e.args) == 2):
        return text
    a, b = (_term(x, printer, values) for x in e.args)
    if a is None or b is None:
        return None
    return f"{a} - {b[1:]}" if b.startswith("-") else f"{a} + {b}"


def _small(expr) -> bool:
    """True if ``expr`` certainly has at most :data:`CSE_MIN_OPS` operations: at most a third as
    many tree nodes (``count_ops`` counts at most about three operations per node, e.g. a negative
    rational: a division, a negation and its product), found without walking a large tree whole."""
    limit = CSE_MIN_OPS // 3
    for k, _ in enumerate(sp.preorder_traversal(expr)):
        if k >= limit:
            return False
    return True


def _linear_form(expr, values: dict):
    """``[(symbol or None, coefficient)]`` with ``expr == Σ coefficient·symbol`` once the parameter
    symbols (keys of ``values``) take their values, found by one walk of the tree (no expansion);
    None where ``expr`` is not evidently such a sum (the caller then expands)."""
    form = _form(expr, values)
    if form is None or not all(math.isfinite(c) for c in form.values()):
        return None
    return list(form.items())


def _form(e, values: dict):
    """``{symbol or None: coefficient}`` of a linear form ``e`` (see :func:`_linear_form`)."""
    if e.is_Number:
        return {None: float(e)}
    if e.is_Symbol:
        return {None: values[e]} if e in values else {e: 1.0}
    if e.is_Add:
        acc: dict = {}
        for a in e.args:
            f = _form(a, values)
            if f is None:
                return None
            for k, v in f.items():
                acc[k] = acc.get(k, 0.0) + v
        return acc
    if e.is_Mul:
        scale, var_part = 1.0, None
        for a in e.args:
            f = _form(a, values)
            if f is None:
                return None
            if set(f) == {None}:
                scale *= f[None]
            elif var_part is None:
                var_part = f
            else:
                return None           # a product of two non-constant factors
        return {None: scale} if var_part is None else {k: scale * v for k, v in var_part.items()}
    if e.is_Pow:
        base, ex = _form(e.base, values), _form(e.exp, values)
        if base is None or ex is None or set(base) != {None} or set(ex) != {None}:
            return None
        try:
            return {None: float(base[None] ** ex[None])}
        except (ZeroDivisionError, OverflowError, TypeError):
            return None
    return None


def _affine_terms(expr):
    """``[(symbol or None, coefficient)]`` with ``expr == Σ coefficient·symbol`` (None: the constant
    1); None if ``expr`` is not such a sum with numeric coefficients."""
    for candidate in (expr, sp.expand(expr)):
        terms = []
        for term in sp.Add.make_args(candidate):
            c, rest = term.as_coeff_Mul()
            if not (c.is_Number and math.isfinite(float(c))):
                break
            if rest == 1:
                terms.append((None, float(c)))
            elif rest.is_Symbol:
                terms.append((rest, float(c)))
            else:
                break
        else:
            return terms
    return None


def _jacobian(residuals, zs) -> sp.Matrix:
    """d residuals / d zs, differentiating each residual only by the unknowns it contains (a loop
    of k unknowns whose equations each hold a few of them: O(k) derivatives, not k²)."""
    col = {z: j for j, z in enumerate(zs)}
    J = sp.zeros(len(residuals), len(zs))
    for i, r in enumerate(residuals):
        for z in r.free_symbols & col.keys():
            J[i, col[z]] = _diff(r, z)
    return J


@functools.lru_cache(maxsize=8192)       # the same derivatives for jac and jac_in_mode
def _diff(expr, w):
    """d expr / d w, term by term: a term ``c*w`` gives ``c`` without differentiating, any other
    term that holds ``w`` is differentiated alone (not the whole sum twice and expanded, as through
    :func:`linear_coefficient`: that was a fifth of the 8-link mechanism's check and build)."""
    parts = []
    for term in sp.Add.make_args(expr):
        if w not in term.free_symbols:
            continue
        factors = sp.Mul.make_args(term)
        if factors.count(w) == 1 and not any(w in f.free_symbols for f in factors if f != w):
            parts.append(sp.Mul(*[f for f in factors if f != w]))
        else:
            parts.append(derivative(term, w))
    return sp.Add(*parts)


#: Loop matrices up to this many rows are printed as array literals; larger ones entry by entry.
DENSE_MAX_UNKNOWNS = 8

#: Numeric linear loops up to this many unknowns are solved by unrolled scalar elimination
#: (:meth:`Writer.elimination_lines`), larger ones by a solver call on an array.
UNROLL_MAX_UNKNOWNS = 8

#: Numeric linear loops up to this many unknowns are solved by Cramer's rule over their printed
#: entries (:meth:`Writer.cramer_lines`), larger ones by elimination with partial pivoting.
CRAMER_UNROLL_MAX = 5

#: Expressions with more operations than this are printed after common-subexpression elimination.
CSE_MIN_OPS = 40

#: From this many states on, an affine right-hand side is generated as one sparse matrix product:
#: flat scalar code costs about 0.15 µs per line, the product about 3 ns per nonzero plus 6 µs.
AFFINE_MIN_STATES = 40

#: From this many states on (a large model, as for :data:`AFFINE_MIN_STATES`) the module also has
#: ``jac_sparse(t, x)``, the Jacobian as a ``scipy.sparse.csc_array`` of its nonzero pattern, which
#: the driver hands to Radau and BDF (:func:`multipole.simulate.jacobian_for`); ``jac`` is then its
#: dense copy.  A dense n×n Jacobian is 3.2 GB at 20,000 states, and its LU O(n³).
SPARSE_JACOBIAN_STATES = AFFINE_MIN_STATES


def generate(eq: Equations, outputs=(), runtime=()) -> str:
    """Python source of the model functions for ``eq``.

    ``rhs`` is flat scalar code; for an affine model with at least :data:`AFFINE_MIN_STATES`
    states it is a sparse product ``M @ [x, u(t), 1]`` instead (same values, less time per call).
    ``runtime``: parameter symbols of ``eq.params`` read from the list ``_P`` (their current values
    to start with) instead of being inlined; ``initial()`` then returns the initial state.
    """
    w = _Writer(eq, runtime)
    N, P = w.names, w.P

    def ders():
        return ", ".join(N[d] if d in N else P(d) for d in eq.derivatives)
    src = ["import math", "import numpy as np", "", "from multipole.codegen import closure_failed, newton, newton_failed", "",
           "_stats = {'rhs_calls': 0, 'jac_calls': 0, 'newton_iterations': 0, 'newton_solves': 0}",
           f"_guess = {[[0.0] * len(b.variables) for b in eq.blocks]!r}", ""]
    if w.runtime:
        src += [f"_P = {[float(eq.params[p]) for p in w.runtime]!r}", "", "def initial():",
                '    """The initial state for the runtime parameters in _P."""',
                f"    return [{', '.join(P(s.initial) for s in eq.states)}]", ""]
    affine = w.affine_rows() if len(w.states) >= AFFINE_MIN_STATES and not w.runtime else None
    sparse = len(w.states) >= SPARSE_JACOBIAN_STATES
    if sparse:
        src.insert(2, "from scipy.sparse import csc_array")
    if affine is not None:
        src.insert(2, "from scipy.sparse import csr_array")
        src += w.affine_rhs(affine)
    else:
        src += w.function("rhs", "d/dt of the states " + ", ".join(eq.state_names) + ".", eq.derivatives,
                          f"np.array([{ders()}])", ["    _stats['rhs_calls'] += 1"])
    out_exprs = [eq.output(o) for o in outputs]
    needed = set().union(*(e.free_symbols for e in out_exprs)) if out_exprs else set()
    src += w.function("outputs", "The outputs " + ", ".join(outputs) + ".", needed,
                      f"np.array([{', '.join(P(e) for e in out_exprs)}], dtype=float)")
    every = list(eq.inputs) + [v for b in eq.blocks for v in b.variables]
    src += ["VALUE_NAMES = " + repr([v.name for v in every])]
    src += w.function("values", "Every input and computed variable, in evaluation order.", every,
                      f"[{', '.join(N[v] for v in every)}]")
    sw = switch_list(w)
    needed = set().union(*(e.free_symbols for e in sw)) if sw else set()
    src += [f"N_SWITCHES = {len(sw)}", f"SWITCH_TEXT = {[str(s) for s in sw]!r}"] + time_switch_lines(w, sw)
    src += monitor_lines(w, sw)
    src += w.function("switches", "Switching functions: a sign change is an event.", needed,
                      f"[{', '.join(P(s) for s in sw)}]")
    src += w.affine_jacobian(sparse) if affine is not None else w.jacobian("jac", sparse)
    if sw:        # the same right-hand side and Jacobian with every switch held on one side
        w.locked(modal_switches(w, sw))
        src += ["_mode = [1.0] * N_SWITCHES", ""]
        src += w.function("rhs_in_mode", "d/dt of the states with every switch on the side _mode says.",
                          eq.derivatives, f"np.array([{ders()}])", ["    _stats['rhs_calls'] += 1"])
        src += w.jacobian("jac_in_mode", sparse)
        w.locked(None)
    return "\n".join(src + w.blocks_src) + "\n"


_CACHE: dict = {}


@bulk
def compile_model(eq: Equations, outputs=(), runtime=()) -> Model:
    """Generate, compile (cached by source hash) and wrap the model functions.

    ``runtime``: parameter symbols (keys of ``eq.params``) that stay variables of the generated
    code, set per run by :meth:`Model.set_parameters` (a parameter study compiles once)."""
    source = generate(eq, outputs, runtime)
    meta = {"name": eq.name, "state_names": eq.state_names, "x0": [float(v) for v in eq.initial_values()],
            "outputs": list(outputs), "units": {o: eq.units.get(o, "") for o in outputs},
            "aliases": {v.name: [r.name, int(s)] for v, (r, s) in eq.analysis.aliases.items()}
            if eq.analysis is not None else {}}
    if runtime:
        meta["runtime"] = [str(p) for p in runtime]
    return Model(source, meta, eq)


#: The code-writer API backends print their models with (docs/backends.md, "The seam"): the
#: printer of expressions, the writer of the evaluation order (``units``, ``prologue``,
#: ``unit_lines``, ``function``, :meth:`~_Writer.jacobian_plan`) and the evaluation units a set
#: of variables needs, in order.
Printer, Writer, Unit, closure = _Printer, _Writer, _Unit, _closure
