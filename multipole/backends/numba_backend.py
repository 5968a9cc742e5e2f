"""The ``numba`` backend: generated model functions *and* the integrator loop run compiled.

``multipole simulate FILE --backend numba`` (or ``pipeline.run(scene, backend="numba")``).

How a run goes:

1. *Translation* — the :class:`~multipole.equations.Equations` are printed as Python source by a
   subclass of the kernel's code writer (:class:`multipole.codegen.Writer`): the right-hand side,
   the forward-mode Jacobian, the outputs and the switching functions, each as a numba ``cfunc``
   ``void fun(double t, double *x, double *out, double *w)`` that writes into ``out``; numeric
   linear loops are solved by unrolled elimination (up to 8 unknowns) or Gaussian elimination in
   the work array ``w``, nonlinear loops by a damped Newton iteration warm-started from ``w``.  A
   function of more than :data:`CHUNK_STATEMENTS` statements is written as ``@njit`` chunks of
   about that many, called in turn by the cfunc (values one chunk passes to a later one go through
   the end of ``w``), so that numba's compile time grows linearly with the model (:func:`cfunc_lines`).
   The source is remembered in this process by the structure of the equations.
2. *Compilation* — the source is written to ``$MULTIPOLE_CACHE/numba/m_<hash>.py`` (default
   ``~/.cache/multipole``; the hash covers the source, the kernels, numba and Python) and
   executed; numba compiles the functions with ``cache=True``, so a later run of the same model,
   in this or another process, loads their machine code from numba's cache in the same folder
   (whatever ``NUMBA_CACHE_DIR`` says).  The folder must be private, else (and with
   ``MULTIPOLE_CACHE=off``) a private folder of the process is used (see :func:`cache_dir`).
   The integrator loops of :mod:`multipole.backends.numba_kernels` do not depend on the
   model (they call it through function addresses): they are compiled once per installation and
   kept in numba's cache.  In another process the model is rebuilt without the equations:
   :meth:`NumbaBackend.describe` gives the source and what the driver reads besides, which
   :func:`multipole.pipeline.run` keeps in an authenticated entry, and :meth:`NumbaBackend.restore`
   loads the module from it (docs/backends.md, "Model cache").
3. *Run* — the shared driver (:func:`multipole.simulate.simulate`: options, grid, ``auto``,
   time-switch schedule, progress, statistics, errors) calls :class:`NumbaIntegrator`: the
   compiled loop integrates from 0 to ``t_end``, fills the ``dt_out`` grid from the dense output
   and restarts at the zero crossings of the switching functions; the outputs are evaluated on
   the grid, also compiled (:meth:`NumbaModel.outputs_on_grid`).

``Result.stats`` keeps ``translate_time`` (sympy to source), ``compile_time`` (translation plus
numba compilation or cache load), ``run_time`` (the compiled integration and output sampling,
also reported as ``wall_time``) in seconds, ``compile_cached`` and the work counters ``nfev``,
``njev``, ``nlu``, ``steps``, ``rejected``, ``segments``, ``newton_iterations``, ``newton_solves``
(algebraic loops) and ``collocation_iterations`` (Radau's simplified Newton iterations).

Solvers: ``RK45`` (Dormand–Prince 5(4), explicit), ``Radau`` (Radau IIA order 5, implicit, analytic
Jacobian) and ``auto`` (the stiffness test of :func:`multipole.simulate.choose_solver`).  ``DOP853``
and ``RK23`` run as ``RK45``, ``BDF`` and ``LSODA`` as ``Radau``; ``Result.solver_reason`` says so.
Models numba cannot compile run on the ``numpy`` backend, visibly: a ``MultipoleWarning`` names the
reason, and so do ``stats["backend"]`` (``numpy (fallback: could not compile: reason)``) and
``solver_reason``; so do models whose generated source costs more than :data:`MAX_SOURCE_COST`, or
one of whose functions more than :data:`MAX_FUNCTION_COST` (numba would compile them for minutes),
which the backend refuses as too large (``numpy (fallback: refused as too large: ...)``, with the
cost, the limit and ``MULTIPOLE_NUMBA_MAX_COST`` or ``MULTIPOLE_NUMBA_MAX_FUNCTION_COST``).
"""
from __future__ import annotations

import ast
import hashlib
import os
import re
import sys
import time
import types
from contextlib import contextmanager
from pathlib import Path

import numba
import numpy as np
import sympy as sp
from sympy.printing.precedence import PRECEDENCE

from .. import cache, codegen
from ..simulate import MAX_EVENTS, Run, SimulationError, chattering, step_failed
from . import Backend, Refused
from . import numba_kernels as K

#: explicit and implicit method of this backend, and what the other scipy names run as
METHODS = {"RK45": "RK45", "Radau": "Radau", "DOP853": "RK45", "RK23": "RK45", "BDF": "Radau", "LSODA": "Radau"}
_DESCRIPTION = {"RK45": "Dormand-Prince 5(4)", "Radau": "Radau IIA order 5"}
#: accepted steps per call of the compiled loop while a progress bar is shown
PROGRESS_CHUNK = 200


class _Printer(codegen.Printer):
    """The kernel's printer, with ``Piecewise`` always total and every
    number a float (numba types a list mixing ints and floats as an error); a switch held on its
    side reads the side from the work array."""

    mode_ref = "w[" + str(K.W_HEAD) + " + {k}]"

    def _print_Integer(self, e):
        return repr(float(e))

    def _print_Pow(self, e, rational=False):
        if e.exp.is_Integer and e.exp > 0:        # x**3, not x**3.0: numba multiplies
            return f"{self.parenthesize(e.base, PRECEDENCE['Pow'])}**{int(e.exp)}"
        return super()._print_Pow(e, rational=rational)

    def _print_Piecewise(self, e):
        if self.modes is not None:
            return super()._print_Piecewise(e)
        parts = []
        for expr, cond in e.args:
            if cond == sp.true:
                return "(" + "".join(parts) + f"({self._print(expr)}))"
            parts.append(f"({self._print(expr)}) if ({self._print(cond)}) else ")
        return "(" + "".join(parts) + "math.nan)"


_SIG = "types.void(types.float64, types.voidptr, types.voidptr, types.voidptr)"

#: damped Newton iteration for one algebraic loop (the rule of :func:`multipole.codegen.newton`),
#: generated per loop so that it calls the loop's residual function directly; written with loops
#: and the kernels' Gaussian elimination because numba compiles numpy's array functions slowly; its
#: vectors and matrix are views of the work array w (after the loop's guess), so a call allocates
#: nothing (an allocation costs about as much as a residual evaluation of a four-bar)
_NEWTON = '''@njit(cache=True, error_model="numpy")
def _newton{k}(w):
    """Damped Newton for the loop {k}, warm-started from w[{off}:{end}], then from zero; the solution (or
    NaN if both fail) in w[{s_z}:{s_z} + {n}]."""
    z = w[{s_z}:{s_z} + {n}]
    z_new = w[{s_z} + {n}:{s_z} + {n2}]
    dz = w[{s_z} + {n2}:{s_z} + {n3}]
    F = w[{s_z} + {n3}:{s_z} + {n4}]
    J = w[{s_z} + {n4}:{s_z} + {n4} + {n} * {n}].reshape(({n}, {n}))
    total = 0
    for attempt in range(2):
        for i in range({n}):
            z[i] = w[{off} + i] if attempt == 0 else 0.0
        _blk{k}(z, w, F, J)
        norm = _k.norm2(F)
        for it in range(1, {max_warm} + 1 if attempt == 0 else {max_zero} + 1):
            if norm == 0.0:     # a zero residual is a solution, even where J is singular
                w[0] += total
                w[1] += 1
                for i in range({n}):
                    w[{off} + i] = z[i]
                return
            total += 1
            for i in range({n}):
                dz[i] = F[i]
            if not _k.gauss_solve(J, dz):    # off the root (d*f*|f| at f = 0): step off the singular point
                for i in range({n}):
                    z[i] += {nudge} * (1.0 + abs(z[i]))
                _blk{k}(z, w, F, J)
                norm = _k.norm2(F)
                continue
            step = 0.0
            big = 0.0
            for i in range({n}):
                step = max(step, abs(dz[i]))
                big = max(big, abs(z[i]))
            if step <= 1e-12 * (1.0 + big):     # converged to rounding: no line search (it halves 20 times)
                for i in range({n}):
                    z[i] -= dz[i]
                    w[{off} + i] = z[i]
                w[0] += total
                w[1] += 1
                return
            lam = 1.0
            while True:
                for i in range({n}):
                    z_new[i] = z[i] - lam * dz[i]
                _blk{k}(z_new, w, F, J)
                norm_new = _k.norm2(F)
                if norm_new <= (1 - 1e-4 * lam) * norm or lam < 1e-6:
                    break
                lam *= 0.5
            step = 0.0
            big = 0.0
            for i in range({n}):
                step = max(step, abs(lam * dz[i]))
                z[i] = z_new[i]
                big = max(big, abs(z[i]))
            norm = norm_new
            if step <= 1e-12 * (1.0 + big) or norm == 0.0:
                w[0] += total
                w[1] += 1
                for i in range({n}):
                    w[{off} + i] = z[i]
                return
    w[2] += 1
    for i in range({n}):
        z[i] = math.nan
'''
def _scalar_newton(k: int, n: int, off: int) -> list:
    """The damped Newton function ``_newton{k}(w)`` (:func:`multipole.codegen.scalar_newton_lines`) for a
    loop of up to :data:`multipole.codegen.SCALAR_NEWTON_MAX` unknowns whose residual function
    ``_blk{k}(z0, ..., w)`` returns ``(F0, ..., J00, J01, ...)``: warm-started from ``w[off:off + n]``,
    then from zero; it returns the solution (NaN if both starts fail, counted in ``w[2]``)."""
    zs = ", ".join(f"z{i}" for i in range(n)) + ","
    done = ["w[0] += total", "w[1] += 1"] + [f"w[{off + i}] = z{i}" for i in range(n)] + [f"return {zs}"]
    fail = ["w[2] += 1", "return (" + ", ".join("math.nan" for _ in range(n)) + ",)"]
    return ['@njit(cache=True, error_model="numpy")'] + codegen.scalar_newton_lines(
        f"_newton{k}", "w", n, [f"w[{off + i}]" for i in range(n)], f"_blk{k}({{z}}, w)", done, fail,
        f"Damped Newton for the loop {k} in scalars, warm-started from w[{off}:{off + n}], then from zero.")


_W_HEAD = K.W_HEAD     # layout of the work array: see numba_kernels.W_HEAD


class _Writer(codegen.Writer):
    """Prints the model as numba ``cfunc`` functions ``void fun(t, *x, *out, *w)``."""

    SINGULAR = None      # a cfunc cannot raise: the division by a zero pivot makes the values NaN
    NO_ROOT = None       # nor where a closed form has no real root: the square root is NaN

    def __init__(self, eq):
        super().__init__(eq)
        self.printer = _Printer(self.names)
        self.blocks_src: list[str] = []      # module-level residual and Newton functions of loops
        self.switches = switch_list(self)
        self.work = _W_HEAD + len(self.switches)   # the switches' sides, then the loops' parts
        self.offsets: dict = {}              # Newton loop (block index) -> offset of its guess in w
        self.deps: dict = {}                 # Newton loop -> symbols its residuals read
        self.hoisted: dict = {}              # Newton loop -> [(symbol, its residuals' terms free of z)]
        # A and b of the numeric linear loops in a scratch part of w (no allocation per call), shared:
        # the loops are solved one after the other
        self.linear_scratch = self.work
        self.work += max([len(u.variables) * (len(u.variables) + 1) for u in self.units
                          if u.kind == "linear" and len(u.variables) > codegen.UNROLL_MAX_UNKNOWNS], default=0)

    def prologue(self, units, extra=()) -> list:
        used = set(extra).union(*(u.deps for u in units)) if units else set(extra)
        lines = [f"    x{i} = x[{i}]" for i, s in enumerate(self.states) if s in used]
        lines += [f"    {self.names[u]} = {self.P(e)}" for u, e in self.eq.inputs.items() if u in used]
        for u in units:
            lines += self.unit_lines(u)
        return lines

    def unit_lines(self, u) -> list:
        if u.kind == "assign":
            return super().unit_lines(u)
        N, P = self.names, self.P
        b = self.eq.blocks[u.block]
        zs = u.variables
        n = len(zs)
        if u.kind == "linear" and n <= codegen.UNROLL_MAX_UNKNOWNS:
            return self.elimination_lines(b.matrix, b.rhs, [N[z] for z in zs])
        if u.kind == "linear":
            s = self.linear_scratch
            lines = [f"    _A = w[{s}:{s + n * n}].reshape(({n}, {n}))", f"    _b = w[{s + n * n}:{s + n * n + n}]",
                     f"    for _i in range({n * n}):", f"        w[{s} + _i] = 0.0"]
            # only the nonzero entries: each element store costs numba as much as 100 bytes of code
            entries = ((i, j, P(b.matrix[i, j])) for i in range(n) for j in range(n))
            lines += [f"    _A[{i}, {j}] = {code}" for i, j, code in entries if code not in ("0.0", "-0.0")]
            lines += [f"    _b[{i}] = {P(b.rhs[i])}" for i in range(n)]
            lines += ["    _k.gauss_solve(_A, _b)"]
            return lines + [f"    {N[z]} = _b[{i}]" for i, z in enumerate(zs)]
        if b.closed_form is not None:
            return self.closed_form_lines(b, zs, u.block)
        return self.newton_lines(u, b)

    def newton_lines(self, u, b) -> list:
        """Residual and Newton functions for the loop (once) and their call."""
        N, P = self.names, self.P
        zs = u.variables
        n = len(zs)
        k = u.block
        if k not in self.offsets:
            # w[off:] the guess, then the values the residuals read, then Newton's scratch (z first)
            res, self.hoisted[k] = codegen.loop_invariants([self.fold(r) for r in b.residuals], zs, f"_l{k}_")
            for sym, _e in self.hoisted[k]:
                N[sym] = str(sym)
            free = set().union(*(r.free_symbols for r in res)) - set(zs)
            self.deps[k] = deps = sorted(free, key=lambda s: N[s])
            off = self.offsets[k] = self.work
            s_z = off + n + len(deps)
            scalar = n <= codegen.SCALAR_NEWTON_MAX
            self.work = s_z if scalar else s_z + 4 * n + n * n
            Jz = sp.Matrix(res).jacobian(zs)
            head = f'    """Residuals of the algebraic loop for {", ".join(map(str, zs))} and their Jacobian."""'
            src = ["@njit(cache=True, error_model='numpy')",
                   f"def _blk{k}({', '.join(f'_z{i}' for i in range(n))}, w):" if scalar else
                   f"def _blk{k}(_z, w, _F, _J):", head]
            src += [f"    {N[d]} = w[{off + n + i}]" for i, d in enumerate(deps)]
            src += [f"    {N[z]} = _z{i}" if scalar else f"    {N[z]} = _z[{i}]" for i, z in enumerate(zs)]
            if scalar:
                src += ["    return (" + ", ".join([P(r) for r in res] + [P(Jz[i, j]) for i in range(n)
                                                                           for j in range(n)]) + ",)",
                        ""] + _scalar_newton(k, n, off)
                self.blocks_src += src
                return self.newton_call(u, b)
            src += [f"    _F[{i}] = {P(r)}" for i, r in enumerate(res)]
            src += [f"    _J[{i}, {j}] = {P(Jz[i, j])}" for i in range(n) for j in range(n)]
            src += ["", _NEWTON.format(k=k, off=off, end=off + n, n=n, n2=2 * n, n3=3 * n, n4=4 * n, s_z=s_z,
                                       max_warm=codegen.NEWTON_MAX_ITER[0], max_zero=codegen.NEWTON_MAX_ITER[1],
                                       nudge=codegen.NEWTON_NUDGE)]
            self.blocks_src += src
        return self.newton_call(u, b)

    def newton_call(self, u, b) -> list:
        """The call of loop ``u``'s Newton function: its inputs and start into w, the solution out."""
        N, zs, k = self.names, u.variables, u.block
        n, off, deps = len(zs), self.offsets[k], self.deps[k]
        lines = [f"    {N[sym]} = {self.P(e)}" for sym, e in self.hoisted[k]]
        lines += [f"    w[{off + n + i}] = {N[d]}" for i, d in enumerate(deps)]
        lines += [f"    w[{off + i}] = {N[v]}" for i, v in enumerate(b.start or ())]
        if n <= codegen.SCALAR_NEWTON_MAX:
            return lines + [f"    {', '.join(N[z] for z in zs)}, = _newton{k}(w)"]
        s_z = off + n + len(deps)
        return lines + [f"    _newton{k}(w)"] + [f"    {N[z]} = w[{s_z + i}]" for i, z in enumerate(zs)]

    def function(self, name, doc, needed, values, shape) -> tuple:
        """The cfunc ``name(t, x, out, w)`` writing ``values`` (code) into ``out`` of ``shape``, as
        ``(name, doc, shape, body, preamble)`` for :func:`cfunc_lines`."""
        units = codegen.closure(self.units, needed)
        body = self.shared_trig(self.prologue(units, needed) + [f"    out[{i}] = {v}" for i, v in enumerate(values)])
        return name, doc, shape, body, []

    def jacobian_function(self) -> tuple:
        """The kernel's forward-mode Jacobian (:meth:`multipole.codegen.Writer.jacobian_plan`) as a
        cfunc writing into ``out`` (numba compiles slice assignment and ``np.zeros`` slowly), as
        ``(name, doc, shape, body, preamble)`` for :func:`cfunc_lines`: the preamble sets ``out`` to
        zero in the cfunc itself (where the shape of ``out`` is a constant: twice as fast as in a chunk)."""
        n = len(self.states)
        plan = self.jacobian_plan()
        body = self.prologue(plan.units, self.eq.derivatives)
        for step in plan.steps:
            if isinstance(step, codegen.Derivative):
                body.append(f"    {step.name} = {step.code}")
                continue
            n_z = step.jz.shape[0]
            body += [f"    _Jz = np.zeros(({n_z}, {n_z}))"]
            body += [f"    _Jz[{i}, {j}] = {self.P(v)}" for (i, j), v in sorted(step.jz.todok().items())]
            body += [f"    _G = np.zeros(({n_z}, {step.n_columns}))"]
            body += [f"    _G[{r_i}, {c}] = {code}" for r_i, c, code in step.g]
            body.append("    _Dz = _k.neg_solve(_Jz, _G)")
            body += [f"    {d} = _Dz[{zi}, {c}]" for zi, c, d in step.names]
        body += [f"    out[{i}, {j}] = {d}" for i, j, d in plan.entries]
        body = self.shared_trig(body)
        zero = [f"    for _i in range({n}):", f"        for _j in range({n}):", "            out[_i, _j] = 0.0"]
        return "jac", "Jacobian d(rhs)/dx into out.", f"({n}, {n})", body, zero


switch_list = codegen.switch_list


def _kernel_digest() -> str:
    h = hashlib.sha256(Path(K.__file__).read_bytes())
    h.update(Path(__file__).read_bytes())
    h.update(numba.__version__.encode())
    h.update(sys.version.encode())
    return h.hexdigest()[:16]


# -- large functions in chunks -----------------------------------------------------------------------
#: statements (source lines) per chunk of a generated function: a function longer than this is
#: compiled as a sequence of ``@njit`` functions of at most about this many statements (a linear
#: loop's matrix and solve stay in one chunk), each called in turn by the cfunc.  LLVM's SROA pass
#: on one basic block of thousands of statements takes time quadratic in their number (measured:
#: docs/performance.md, "numba compile time against model size"); in bounded chunks it is linear.
CHUNK_STATEMENTS = 400


class _Statement:
    """One top-level statement of a generated function body: its ``text`` (source lines), the names
    it ``writes`` and ``reads``, and its ``kind``: ``"x"`` (``name = x[i]``: repeated in every chunk
    that reads it), ``"pure"`` (an assignment to names of arithmetic on names: moved to just before
    its first use, dropped if nothing uses it) or ``"ordered"`` (anything else: a store, a call of a
    loop's solver, an array: kept in its order)."""

    def __init__(self, node, text: list, pure_reads: set):
        self.text = text
        stores = {n.id for n in ast.walk(node) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
        loads = {n.id for n in ast.walk(node) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load)}
        counters = {n.id for f in ast.walk(node) if isinstance(f, ast.For) for n in ast.walk(f.target)
                    if isinstance(n, ast.Name)}
        # what it reads before it runs; a compound statement (``if _p == 1: ...``) may leave a name
        # as it was, so it reads what it writes (a loop's counter excepted); ``a -= b`` reads a
        self.writes = stores
        self.reads = loads if isinstance(node, ast.Assign) else (loads | stores) - counters
        self.arrays = {n.value.id for n in ast.walk(node) if isinstance(n, ast.Subscript)
                       and isinstance(n.value, ast.Name)}
        named = isinstance(node, ast.Assign) and all(
            isinstance(t, ast.Name) or (isinstance(t, ast.Tuple) and all(isinstance(e, ast.Name) for e in t.elts))
            for t in node.targets)
        value = node.value if named else None
        if named and isinstance(value, ast.Subscript) and isinstance(value.value, ast.Name) and value.value.id == "x":
            self.kind = "x"
        elif named and all(_harmless(n, pure_reads) for n in ast.walk(value)):
            self.kind = "pure"
        else:
            self.kind = "ordered"


def _harmless(node, pure_reads: set) -> bool:
    """True if ``node`` (part of an assigned value) neither changes nor reads anything a statement of
    the function may change: a call of ``math``'s functions or builtins, a subscript of ``x`` or a
    switch's side ``w[...]`` in ``pure_reads``, not a loop's solver (``_newton3(w)``) nor an array."""
    if isinstance(node, ast.Call):
        f = node.func
        return (isinstance(f, ast.Name) and not f.id.startswith("_")) or (
            isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "math")
    if isinstance(node, ast.Subscript):
        return (isinstance(node.value, ast.Name) and node.value.id == "x") or ast.unparse(node) in pure_reads
    if isinstance(node, ast.Attribute):
        return isinstance(node.value, ast.Name) and node.value.id == "math"
    return not isinstance(node, (ast.Lambda, ast.NamedExpr, ast.Starred))


def _statements(body: list, pure_reads: set) -> list:
    """The top-level statements of ``body`` (lines indented by four spaces)."""
    tree = ast.parse("\n".join(line[4:] for line in body))
    return [_Statement(node, body[node.lineno - 1:node.end_lineno], pure_reads) for node in tree.body]


def _schedule(stmts: list) -> list:
    """Indices of ``stmts`` in an order with the ordered statements in theirs, each pure statement
    just before its first use (depth first: what one output needs is computed together, so few
    values cross from one chunk to another), unused pure statements left out.  A statement that
    reads or writes a name assigned more than once (the unrolled elimination's ``_a0_1``, ``_p``)
    counts as ordered."""
    writers: dict = {}
    for s in stmts:
        for name in s.writes:
            writers[name] = writers.get(name, 0) + 1
    for s in stmts:
        if s.kind != "ordered" and any(writers.get(r, 0) > 1 for r in s.reads | s.writes):
            s.kind = "ordered"
    define = {name: i for i, s in enumerate(stmts) if s.kind != "ordered" for name in s.writes}
    done = [False] * len(stmts)
    order: list = []
    for root, s in enumerate(stmts):
        if s.kind != "ordered":
            continue
        stack = [(root, iter(sorted(s.reads)))]
        while stack:       # depth first, without recursion (a long chain of assignments is deep)
            i, todo = stack[-1]
            name = next((r for r in todo if r in define and not done[define[r]]), None)
            if name is None:
                stack.pop()
                done[i] = True
                order.append(i)
            else:
                d = define[name]
                done[d] = True          # (marked on entry: an assignment never reads itself)
                stack.append((d, iter(sorted(stmts[d].reads))))
    return order


def _chunks(stmts: list, order: list, limit: int) -> list:
    """``order`` cut into runs of about ``limit`` source lines, never where an array other than
    ``x``, ``out`` and ``w`` (a loop's matrix, a view of ``w``) is defined before and used after."""
    arrays = set().union(*(s.arrays for s in stmts)) - {"x", "out", "w"}
    last: dict = {}
    for pos, i in enumerate(order):
        for a in (stmts[i].arrays | stmts[i].writes | stmts[i].reads) & arrays:
            last[a] = pos
    open_until = -1
    chunks, current, size = [], [], 0
    for pos, i in enumerate(order):
        current.append(i)
        size += len(stmts[i].text)
        for a in (stmts[i].arrays | stmts[i].writes | stmts[i].reads) & arrays:
            open_until = max(open_until, last[a])
        if size >= limit and pos >= open_until:
            chunks.append(current)
            current, size = [], 0
    return chunks + ([current] if current else [])


def _split(name: str, body: list, base: int, pure_reads: set, limit: int):
    """``body`` as chunk functions ``_{name}_{k}(t, x, out, w)`` and the lines calling them, and the
    number of values passed through ``w[base:]``; None if ``body`` is no longer than ``limit``."""
    if sum(1 for line in body if line.strip()) <= limit:
        return None
    stmts = _statements(body, pure_reads)
    order = _schedule(stmts)
    chunks = _chunks(stmts, order, limit)
    owner: dict = {}                 # value -> chunk that last assigned it
    slot: dict = {}                  # value passed between chunks -> its place in w
    loads: list = []
    for c, chunk in enumerate(chunks):
        local: set = set()
        need: list = []
        for i in chunk:
            need += [r for r in sorted(stmts[i].reads) if r not in local and r in owner and r not in need]
            local |= stmts[i].writes
        loads.append(need)
        for r in need:
            if stmts[owner[r]].kind != "x":
                slot.setdefault(r, base + len(slot))
        for i in chunk:
            for v in stmts[i].writes:
                owner[v] = i
    lines, calls = [], []
    for c, chunk in enumerate(chunks):
        head = [line for r in loads[c] for line in (stmts[owner[r]].text if r not in slot else
                                                      [f"    {r} = w[{slot[r]}]"])]
        text = [line for i in chunk for line in stmts[i].text]
        stores = sorted({v for i in chunk for v in stmts[i].writes if v in slot}, key=slot.get)
        lines += ['@njit(cache=True, error_model="numpy")', f"def _{name}_{c}(t, x, out, w):",
                  f'    """Statements {c + 1} of {len(chunks)} of {name}."""'] + head + text
        lines += [f"    w[{slot[v]}] = {v}" for v in stores] + [""]
        calls.append(f"    _{name}_{c}(t, x, out, w)")
    return lines, calls, len(slot)


def cfunc_lines(name: str, doc: str, n: int, shape: str, body: list, base: int, pure_reads: set,
                limit: int | None = None, preamble=()) -> tuple[list, int]:
    """The cfunc ``name(t, xp, outp, wp)`` for ``n`` states running ``preamble`` and then ``body``
    (``out`` of ``shape``) and how many places of the work array after ``base`` it uses: ``body``
    itself if it has up to ``limit`` (default :data:`CHUNK_STATEMENTS`) statements, else calls of
    its chunks (:func:`_split`)."""
    split = _split(name, body, base, pure_reads, CHUNK_STATEMENTS if limit is None else limit)
    lines, calls, used = split if split is not None else ([], body, 0)
    return lines + [f"@cfunc({_SIG}, cache=True, error_model='numpy')", f"def {name}(t, xp, outp, wp):",
                    f'    """{doc}"""', f"    x = carray(xp, ({n},), np.float64)",
                    f"    out = carray(outp, {shape}, np.float64)", "    w = carray(wp, (N_WORK,), np.float64)"] + \
        list(preamble) + calls + [""], used


def generate(eq, outputs) -> tuple[str, list]:
    """Source of the numba module for ``eq`` and the text of its switching functions."""
    w = _Writer(eq)
    N, P = w.names, w.P
    n = len(eq.states)
    sw = w.switches
    # the integrator's functions hold every switch on its side for a segment (as the numpy backend);
    # not where a Newton loop switches, since a loop's residual function is printed once for all uses
    loops_switch = any(codegen.switching_functions(e) for u in w.units if u.kind != "assign" for e in u.exprs)
    held = codegen.modal_switches(w, sw) if sw and not loops_switch else None
    w.locked(held)
    ders = [N[d] if d in N else P(d) for d in eq.derivatives]
    funs = [w.function("rhs", "d/dt of the states " + ", ".join(eq.state_names) + ".", eq.derivatives, ders,
                       f"({n},)"), w.jacobian_function()]
    w.locked(None)
    out_exprs = [eq.output(o) for o in outputs]
    needed = set().union(*(e.free_symbols for e in out_exprs)) if out_exprs else set()
    funs.append(w.function("outputs", "The outputs " + ", ".join(outputs) + ".", needed, [P(e) for e in out_exprs],
                           f"({len(outputs)},)"))
    needed = set().union(*(e.free_symbols for e in sw)) if sw else set()
    funs.append(w.function("switches", "Switching functions: a sign change is an event.", needed, [P(s) for s in sw],
                           f"({len(sw)},)"))
    # the values passed between the chunks of a large function go to w after everything else there
    body, spill = [], 0
    pure_reads = {_Printer.mode_ref.format(k=k) for k in range(len(sw))}
    for name, doc, shape, lines, preamble in funs:
        text, used = cfunc_lines(name, doc, n, shape, lines, w.work, pure_reads, preamble=preamble)
        body += text
        spill = max(spill, used)
    head = [f'"""numba model of {eq.name!r}, generated by multipole.backends.numba_backend: do not edit."""',
            f"# kernels {_kernel_digest()}", "import math", "", "import numpy as np",
            "from numba import carray, cfunc, njit, types", "",
            "from multipole.backends import numba_kernels as _k", "", f"N_WORK = {w.work + spill}",
            f"N_SWITCHES = {len(sw)}"] + codegen.time_switch_lines(w, sw) + codegen.monitor_lines(w, sw) + [""]
    return "\n".join(head + w.blocks_src + body) + "\n", [str(s) for s in sw]


#: the largest generated module numba is asked to compile, in :func:`source_cost` units (bytes, an
#: array subscript counted as 100).  With large functions compiled in chunks (:data:`CHUNK_STATEMENTS`)
#: numba's compile time grows linearly with this cost (17 s of CPU time for the 300-pair chain, cost
#: 425,000; 33 s for the 600-pair chain, cost 855,000; docs/performance.md), so this limit bounds it
#: to about 80 s; a larger model runs on the numpy backend, visibly.  The environment variable ``MULTIPOLE_NUMBA_MAX_COST`` sets another.
MAX_SOURCE_COST = 2_000_000
#: the largest single function (a chunk, a loop's residual, a cfunc) numba is asked to compile: what
#: cannot be cut (a linear loop's matrix and solve, one long expression) still costs LLVM time
#: super-linear in its size (slope about 1.8: 61 s for the 150-pair chain written whole, whose ``jac``
#: alone costs 163,000).  ``MULTIPOLE_NUMBA_MAX_FUNCTION_COST`` sets another.
MAX_FUNCTION_COST = 150_000
#: an array subscript (``_A[3, 4] = ...``, ``x[2]``) costs numba/LLVM about as much as 100 bytes of
#: scalar code
SUBSCRIPT_COST = 100
_SUBSCRIPT = re.compile(r"[A-Za-z_]\w*\[")
_FUNCTION = re.compile(r"^(?:@.*\n)*def (\w+)\(", re.M)


class ModelTooLarge(Refused):
    """The generated source costs more than :func:`max_source_cost`, or one of its functions more than
    :func:`max_function_cost`: the backend does not start numba (the run falls back to numpy, saying
    the model was refused as too large)."""


def source_cost(source: str) -> int:
    """Predictor of numba's compile time for generated code: its size in bytes plus
    :data:`SUBSCRIPT_COST` per array subscript (measured: a dense linear-loop matrix of 2,000 element
    stores in 71 kB compiles slower than a chain's 114 kB of scalar code)."""
    return len(source.encode()) + SUBSCRIPT_COST * len(_SUBSCRIPT.findall(source))


def function_costs(source: str) -> dict:
    """:func:`source_cost` of each top-level function of a generated module (decorator included)."""
    starts = list(_FUNCTION.finditer(source))
    return {m.group(1): source_cost(source[m.start():nxt.start() if nxt else len(source)])
            for m, nxt in zip(starts, starts[1:] + [None])}


def _limit(variable: str, default: int) -> int:
    text = os.environ.get(variable, "").strip()
    return int(text) if text.isdigit() else default


def max_source_cost() -> int:
    """The limit on :func:`source_cost`: ``MULTIPOLE_NUMBA_MAX_COST`` or :data:`MAX_SOURCE_COST`."""
    return _limit("MULTIPOLE_NUMBA_MAX_COST", MAX_SOURCE_COST)


def max_function_cost() -> int:
    """The limit on one function's cost: ``MULTIPOLE_NUMBA_MAX_FUNCTION_COST`` or :data:`MAX_FUNCTION_COST`."""
    return _limit("MULTIPOLE_NUMBA_MAX_FUNCTION_COST", MAX_FUNCTION_COST)


def check_size(source: str) -> None:
    """Raise :class:`ModelTooLarge` (the caller falls back to numpy) if ``source`` or one of its
    functions is above its limit."""
    cost, limit = source_cost(source), max_source_cost()
    if cost > limit:
        raise ModelTooLarge("too large", f"generated source costs {cost:,} (bytes + {SUBSCRIPT_COST} per subscript), "
                            f"above the limit of {limit:,}",
                            "set the environment variable MULTIPOLE_NUMBA_MAX_COST above the cost to compile it "
                            "anyway, and wait")
    costs, limit = function_costs(source), max_function_cost()
    name = max(costs, key=costs.get, default=None)
    if name is not None and costs[name] > limit:
        raise ModelTooLarge("too large", f"its generated function {name} costs {costs[name]:,} (bytes + "
                            f"{SUBSCRIPT_COST} per subscript), above the limit of {limit:,} for one function "
                            "(numba's time grows faster than its size)",
                            "set the environment variable MULTIPOLE_NUMBA_MAX_FUNCTION_COST above the cost to "
                            "compile it anyway, and wait")


_SOURCES: dict = {}


def _structure(eq, outputs) -> tuple:
    """Everything the generated source depends on, as a hashable tuple of sympy objects (hashing it
    costs about 0.1 ms where printing the source costs tens of ms)."""
    def frozen(m):
        return m.as_immutable() if m is not None else None
    blocks = tuple((b.kind, tuple(b.variables), tuple(b.solution or ()), tuple(b.residuals), frozen(b.matrix),
                    frozen(b.rhs)) for b in eq.blocks)
    return (eq.name, tuple(s.symbol for s in eq.states), tuple(eq.derivatives), tuple(eq.inputs.items()),
            tuple(eq.params.items()), blocks, tuple(outputs), tuple(eq.output(o) for o in outputs),
            tuple((sp.sympify(e), m.code, m.text, m.stop, m.fix, owner) for e, m, owner in eq.monitors))


def translate(eq, outputs) -> tuple[str, list]:
    """:func:`generate`, remembered for the structure of ``eq`` within this process (and on the
    equations object itself, so that running the same equations again costs no hashing)."""
    mine = getattr(eq, "_numba_translation", None)
    if mine is not None and mine[0] == tuple(outputs):
        return mine[1]
    key = _structure(eq, outputs)
    if key not in _SOURCES:
        if len(_SOURCES) > 256:
            _SOURCES.clear()
        _SOURCES[key] = generate(eq, outputs)
    eq._numba_translation = (tuple(outputs), _SOURCES[key])
    return _SOURCES[key]


# -- compilation and cache ---------------------------------------------------------------------------
_LOADED: dict = {}


def cache_dir() -> Path:
    """Where generated modules and numba's machine code for them are kept: ``$MULTIPOLE_CACHE/numba``
    if that folder is private (:func:`multipole.cache.private_dir`), else (and with
    ``MULTIPOLE_CACHE=off``) a private folder of this process, removed at exit."""
    root = cache.root()
    folder = cache.private_dir(root) and cache.private_dir(root / "numba") if root is not None else None
    return folder if folder is not None else cache.process_dir()


@contextmanager
def _numba_cache_in(folder: Path):
    """numba's cache locator for the functions decorated meanwhile is ``folder`` (whatever
    ``NUMBA_CACHE_DIR`` says): numba picks the folder when a function is decorated and loads its
    pickled index from there, so it must be the folder :func:`cache_dir` checked."""
    from numba.core import config
    saved = config.CACHE_DIR
    config.CACHE_DIR = str(folder)
    try:
        yield
    finally:
        config.CACHE_DIR = saved


def load(source: str):
    """Import the generated module (written once per source hash): numba compiles its cfuncs, or
    loads them from its cache, as the module is executed.  The module runs from ``source`` itself,
    never from a file or a ``.pyc`` found on disk."""
    key = hashlib.sha256(source.encode()).hexdigest()[:24]
    if key in _LOADED:
        return _LOADED[key]
    folder = cache_dir()
    path = folder / f"m_{key}.py"
    if not path.is_file() or path.read_text() != source:
        tmp = folder / f".m_{key}.{os.getpid()}.tmp"
        tmp.write_text(source)
        tmp.replace(path)      # atomic: parallel runs never read a half-written file
    name = f"_multipole_numba_{key}"
    module = types.ModuleType(name)
    module.__file__ = str(path)          # numba's cache is keyed by this file (and its content hash)
    sys.modules[name] = module
    with _numba_cache_in(folder):
        exec(compile(source, str(path), "exec"), module.__dict__)
    _LOADED[key] = module
    return module


class _Work:
    """Every array the compiled loop keeps between steps (see :mod:`numba_kernels`).

    The backend keeps one per model between runs (:meth:`start` readies it for the next): the
    loop's scratch arrays (``f``, ``Q``, ``y_old``, ``J``, the LU factors, the event lists) are
    written before they are read in every run, so only the counters, options, states and the
    model's work array are reset, and ``X`` (the states on the grid, which the run's result keeps)
    is new each run."""

    def __init__(self, n: int, n_switches: int, n_work: int, grid: np.ndarray, x0, t_end, rtol, atol, max_step):
        self.fs = np.zeros(K.N_FS)
        self.iw = np.zeros(K.N_IW, dtype=np.int64)
        self.x = np.zeros(n)
        self.f = np.zeros(n)
        self.g_sign = np.zeros(n_switches)
        self.ev_t = np.zeros(MAX_EVENTS + 1)
        self.ev_k = np.zeros(MAX_EVENTS + 1, dtype=np.int64)
        self.Q = np.zeros((n, K.DENSE_COLS))
        self.y_old = np.zeros(n)
        self.J = np.zeros((n, n))
        self.LUr = np.zeros((n, n))
        self.pr = np.zeros(n, dtype=np.int64)
        self.LUc = np.zeros((n, n), dtype=np.complex128)
        self.pc = np.zeros(n, dtype=np.int64)
        self.w = np.zeros(n_work)
        self.time_only = np.zeros(n_switches, dtype=np.int64)   # switches of time alone, and
        self.sched_t = np.zeros(0)                                # their crossings (none by default)
        self.sched_k = np.zeros(0, dtype=np.int64)
        self.sched_side = np.zeros(0)
        self.t_side = np.ones(n_switches)
        self.stop = np.zeros(n_switches, dtype=np.int64)          # 1: a stop monitor (see :meth:`monitors`)
        self.crossings = None                                     # what the sched_ arrays hold
        self.start(grid, x0, t_end, rtol, atol, max_step)

    def start(self, grid: np.ndarray, x0, t_end, rtol, atol, max_step) -> None:
        """Ready for a run from ``x0`` at t = 0 over ``grid`` [s], as a new :class:`_Work` would be."""
        fs, iw = self.fs, self.iw
        fs.fill(0.0)
        fs[K.F_T_END], fs[K.F_RTOL], fs[K.F_ATOL], fs[K.F_MAX_STEP] = t_end, rtol, atol, max_step
        iw.fill(0)
        iw[K.I_FRESH] = 1
        iw[K.I_FORCED] = -1
        self.x[:] = x0
        self.g_sign.fill(0.0)
        self.w.fill(0.0)
        self.grid = grid
        self.X = np.zeros((grid.size, self.x.size))

    def monitors(self, monitors) -> None:
        """Mark the switching functions of the monitors with ``stop`` (the model's ``monitors``): the
        compiled loop ends the run where one crosses from >= 0 to < 0."""
        for k, _el, _code, _text, stop, _fix in monitors:
            self.stop[k] = int(stop)

    def schedule(self, time_only, crossings, sides) -> None:
        """The crossings ``[(t, k, side after), ...]`` of the switching functions of time alone and
        their ``sides`` at t = 0 (:func:`multipole.simulate.time_switch_schedule`); the arrays are
        made again only for other crossings than the last run's."""
        if self.crossings is None or crossings != self.crossings:
            self.time_only = np.asarray(time_only, dtype=np.int64)
            self.sched_t = np.array([c[0] for c in crossings], dtype=float)
            self.sched_k = np.array([c[1] for c in crossings], dtype=np.int64)
            self.sched_side = np.array([c[2] for c in crossings], dtype=float)
            self.crossings = crossings
        self.t_side[:] = sides

    def args(self, max_steps):
        return (self.fs, self.iw, self.x, self.f, self.grid, self.X, self.g_sign, self.ev_t, self.ev_k, self.Q,
                self.y_old, self.J, self.LUr, self.pr, self.LUc, self.pc, self.w, self.time_only, self.sched_t,
                self.sched_k, self.sched_side, self.t_side, self.stop, max_steps)


def _cfuncs(module) -> tuple:
    """Addresses of the model's right-hand side, Jacobian and switching functions."""
    return module.rhs.address, module.jac.address, module.switches.address


def _compile(module, n: int, n_switches: int) -> bool:
    """Load the integrator loops and the model (compiling what numba's cache lacks) by calling them
    once without integrating; True if nothing had to be compiled."""
    if getattr(module, "_warm", False):
        return True
    work = _Work(n, n_switches, module.N_WORK, np.zeros(0), np.zeros(n), 1.0, 1e-6, 1e-9, np.inf)
    misses = sum(sum(f.stats.cache_misses.values()) for f in (K.integrate, K.sample))
    # an empty output grid: the calls only load or compile the code, they evaluate nothing
    K.integrate(*_cfuncs(module), False, *work.args(0))
    K.sample(module.outputs.address, work.w, work.grid, work.X, np.zeros((0, 0)))
    misses = sum(sum(f.stats.cache_misses.values()) for f in (K.integrate, K.sample)) - misses
    module._warm = True
    return misses == 0 and all(f.cache_hits for f in (module.rhs, module.jac, module.switches, module.outputs))


class NumbaModel:
    """The compiled model the shared driver runs (see :class:`multipole.backends.Backend`): the
    generated module's cfuncs behind the model interface of :mod:`multipole.simulate`."""

    def __init__(self, equations, outputs, module, switch_text, x0, translate_time, compile_time, cached):
        self.module, self.name, self.x0 = module, equations.name, x0
        self.state_names, self.output_names = list(equations.state_names), list(outputs)
        self.output_units = [getattr(equations, "units", {}).get(o, "") for o in outputs]
        self.n_switches, self.switch_text = module.N_SWITCHES, switch_text
        self.switch_time_only = np.asarray(module.SWITCH_TIME_ONLY, dtype=bool)
        self.switch_rate, self.switch_roots = module.SWITCH_RATE, module.SWITCH_ROOTS
        self.monitors = list(module.MONITORS)
        self.translate_time, self.compile_time, self.cached = translate_time, compile_time, cached
        self.w0 = np.zeros(module.N_WORK)       # work array of the Jacobian at the start
        if self.n_switches:          # hold the switches on the side they are on at the start
            g = self.switches(0.0, x0)
            self.w0[_W_HEAD:_W_HEAD + self.n_switches] = np.where(g < 0, -1.0, 1.0)

    def _call(self, fun, t, x, shape, w):
        x = np.ascontiguousarray(x, dtype=float)
        out = np.zeros(shape)
        fun.ctypes(float(t), x.ctypes.data, out.ctypes.data, w.ctypes.data)
        return out

    def jac(self, t, x):
        """d(rhs)/dx at (t, x), the switches held on their sides at the start (for ``auto``)."""
        return self._call(self.module.jac, t, x, (len(x), len(x)), self.w0)

    def switches(self, t, x):
        """The switching functions at (t, x)."""
        return self._call(self.module.switches, t, x, self.n_switches, np.zeros(self.module.N_WORK))

    def outputs(self, t, x):
        return self._call(self.module.outputs, t, x, len(self.output_names), np.zeros(self.module.N_WORK))

    def outputs_on_grid(self, t_grid, states):
        """The outputs on the grid, compiled; after a run they read its work array (loop guesses)."""
        Y = np.zeros((len(t_grid), len(self.output_names)))
        w = self.__dict__.get("w_run")
        K.sample(self.module.outputs.address, np.zeros(self.module.N_WORK) if w is None else w, t_grid,
                 np.ascontiguousarray(states), Y)
        return Y


#: the smallest relative tolerance the compiled loops run with
_MIN_RTOL = 100 * np.finfo(float).eps
#: the steps of one call of the compiled loop without a progress bar (all of them)
_NO_CHUNK = np.iinfo(np.int64).max
_STATUS = {K.STEP_TOO_SMALL: "the step size fell below the resolution of t",
           K.NOT_FINITE: "the solution became infinite or NaN"}


class NumbaIntegrator:
    """The compiled integrator loops of :mod:`numba_kernels` (Dormand–Prince 5(4), Radau IIA)."""

    name = "numba"
    solvers = tuple(METHODS)
    compiled = True          # the model runs in compiled code only: no Python warnings (see Integrator)

    def method(self, solver, auto) -> tuple[str, str]:
        """This backend's method for the requested ``solver`` and the reason, for ``solver_reason``."""
        if auto is not None:
            method = METHODS.get(auto[0], "Radau")
            return method, f"{auto[1]}; compiled {_DESCRIPTION[method]} (numba)"
        method = METHODS[solver]
        if method == solver:
            return method, f"chosen by the user; compiled {_DESCRIPTION[method]} (numba)"
        return method, f"{solver} requested; the numba backend runs it as {method} ({_DESCRIPTION[method]})"

    def integrate(self, model, method, t_grid, x0, schedule, sides, t_end, rtol, atol, max_step, bar) -> Run:
        module, n = model.module, len(x0)
        rtol = max(rtol, _MIN_RTOL)
        work = model.__dict__.pop("_work", None)     # the last run's arrays; a concurrent run makes its own
        if work is None:
            work = _Work(n, model.n_switches, module.N_WORK, t_grid, x0, t_end, rtol, atol, max_step)
            work.monitors(model.monitors)
        else:
            work.start(t_grid, x0, t_end, rtol, atol, max_step)
        work.schedule(model.switch_time_only, schedule, sides)
        funcs = _cfuncs(module) + (method == "Radau",)
        chunk = PROGRESS_CHUNK if bar.enabled else _NO_CHUNK
        if n:
            try:
                while work.iw[K.I_STATUS] == K.RUNNING:
                    K.integrate(*funcs, *work.args(chunk))
                    bar.update(work.fs[K.F_T])
            except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
                raise step_failed(model, f"integration failed at t = {work.fs[K.F_T]:.6g} s: {exc}") from None
            status, t = int(work.iw[K.I_STATUS]), float(work.fs[K.F_T])
            if status == K.TOO_MANY_EVENTS:
                last = int(work.iw[K.I_NEV]) - 1
                raise chattering(float(work.ev_t[last]), model.switch_text[int(work.ev_k[last])])
            if status in _STATUS:
                msg = f"{method} (numba) stopped at t = {t:.6g} s: {_STATUS[status]}"
                if work.w[2]:
                    msg += f" (Newton's method failed {int(work.w[2])} times in an algebraic loop)"
                if status == K.NOT_FINITE:
                    raise SimulationError("not_finite", msg, "check parameters (zero inertia? negative stiffness?) "
                                          "and the check report")
                raise step_failed(model, msg)
        model.w_run = work.w
        iw = work.iw
        counters = {"steps": int(iw[K.I_STEPS]), "rejected": int(iw[K.I_REJECTED]), "nfev": int(iw[K.I_NFEV]),
                    "njev": int(iw[K.I_NJEV]), "nlu": int(iw[K.I_NLU]), "segments": int(iw[K.I_SEGMENTS]),
                    "rhs_calls": int(iw[K.I_NFEV]), "jac_calls": int(iw[K.I_NJEV]),
                    "newton_iterations": int(work.w[0]), "newton_solves": int(work.w[1]),
                    "newton_failures": int(work.w[2]), "collocation_iterations": int(iw[K.I_NEWTON_IT])}
        events = [(float(work.ev_t[i]), int(work.ev_k[i])) for i in range(int(iw[K.I_NEV]))]
        model._work = work
        return Run(work.X, events, counters)


class NumbaBackend(Backend):
    """``--backend numba``: the model's functions and the integrator loop compiled by numba."""

    name = "numba"
    integrator = NumbaIntegrator()

    def compile(self, equations, outputs) -> NumbaModel:
        """Translate (remembered per structure), load or compile the module and the loops; a
        a printer's or numba's own error makes the caller fall back to numpy."""
        outputs = list(outputs)
        mine = getattr(equations, "_numba_model", None)
        if mine is not None and mine[0] == tuple(outputs):
            mine[1].cached = True       # a warm call (pipeline.pruned remembers the equations): nothing compiled
            return mine[1]
        start = time.perf_counter()
        source, switch_text = translate(equations, outputs)
        translate_time = time.perf_counter() - start
        check_size(source)
        module = load(source)
        cached = _compile(module, len(equations.states), len(switch_text))
        model = NumbaModel(equations, outputs, module, switch_text, _initial_state(equations), translate_time,
                           time.perf_counter() - start, cached)
        equations._numba_model = (tuple(outputs), model)
        return model

    def describe(self, equations, outputs) -> dict | None:
        """The model :meth:`compile` made for ``equations`` as data for :meth:`restore` in another
        process: the generated source (which holds the model's functions, switching functions and
        monitors) and what the driver reads besides (names, units, initial state, switch texts)."""
        mine = getattr(equations, "_numba_model", None)
        if mine is None or mine[0] != tuple(outputs):
            return None
        model = mine[1]
        source, switch_text = translate(equations, outputs)      # remembered on the equations
        return {"kernels": _kernel_digest(), "source": source, "switch_text": list(switch_text),
                "name": model.name, "state_names": list(model.state_names), "outputs": list(model.output_names),
                "units": list(model.output_units), "x0": [float(v) for v in model.x0]}

    def restore(self, data) -> NumbaModel | None:
        """The model :meth:`describe` described, its functions loaded from numba's cache (compiled if
        missing), without the equations; None if ``data`` does not have the shape :meth:`describe`
        writes, was made for other kernels (or numba, or Python), or fails to load."""
        if not _valid_description(data) or data["kernels"] != _kernel_digest():
            return None
        start = time.perf_counter()
        try:
            module = load(data["source"])
            n, switch_text = len(data["state_names"]), data["switch_text"]
            if module.N_SWITCHES != len(switch_text):
                return None
            cached = _compile(module, n, len(switch_text))
        except Exception:           # noqa: BLE001 -- whatever is wrong with an entry, it is rebuilt
            return None
        described = types.SimpleNamespace(name=data["name"], state_names=data["state_names"],
                                          units=dict(zip(data["outputs"], data["units"])))
        return NumbaModel(described, data["outputs"], module, switch_text, np.array(data["x0"], dtype=float), 0.0,
                          time.perf_counter() - start, cached)


def _valid_description(data) -> bool:
    """True if ``data`` has the shape :meth:`NumbaBackend.describe` writes."""
    def strings(v):
        return isinstance(v, list) and all(isinstance(s, str) for s in v)
    return (isinstance(data, dict) and all(isinstance(data.get(k), str) for k in ("kernels", "source", "name"))
            and all(strings(data.get(k)) for k in ("switch_text", "state_names", "outputs", "units"))
            and len(data["units"]) == len(data["outputs"]) and isinstance(data.get("x0"), list)
            and len(data["x0"]) == len(data["state_names"])
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in data["x0"]))


def _initial_state(equations) -> np.ndarray:
    """``equations.initial_values()`` as an array, worked out once per equations object."""
    x0 = getattr(equations, "_numba_x0", None)
    if x0 is None:
        x0 = equations._numba_x0 = np.array(equations.initial_values(), dtype=float)
    return x0.copy()


#: the backend object the ``multipole.backends`` entry point ``numba`` names
run = NumbaBackend()
