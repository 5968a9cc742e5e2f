"""FMU export: a scene as an FMI 2.0 Model Exchange unit (``multipole export FILE --fmu model.fmu``).

One stage, :func:`export`: :class:`~multipole.equations.Equations` → C source → shared library →
``model.fmu`` (a zip of ``modelDescription.xml``, ``binaries/<platform>/<modelIdentifier>.so``
and the C source under ``sources/``).

* **C source.** The evaluation order of the kernel's code writer (:class:`multipole.codegen.Writer`)
  is printed by sympy's C99 printer, with the parameters *not* folded in: each parameter is an FMI
  parameter (``causality="parameter"``, ``variability="tunable"``) read from the instance.  The
  derivatives are computed with every switching function held on its side (``mode[k]``, as the
  ``numpy`` backend holds them for a segment); the switching functions themselves are the event
  indicators, and at an event (``fmi2NewDiscreteStates``) each switch takes the side its function
  is on (where it is zero, the side it moves to: the rule of :func:`multipole.simulate._sides`).
  Numeric linear loops are solved by a generated call of a small Gaussian elimination with partial
  pivoting.  ``fmi2GetDirectionalDerivative`` prints the writer's forward-mode Jacobian plan
  (:meth:`multipole.codegen.Writer.jacobian_plan`) for the derivatives and the outputs.  The FMI 2.0
  API functions are written here (``_RUNTIME``), with our own minimal FMI type definitions.
* **Refusals.** What the C code would not compute exactly as ``multipole simulate`` does is refused
  at export time with an :class:`FmuError` naming the element: nonlinear algebraic loops (Newton's
  method, ``fmu_newton_loop``), tables (``interp``, sympy ``Piecewise``: ``fmu_table``) and any
  expression the C printer has no form for (``fmu_unsupported``).
* **Compiler.** ``$CC``, else ``cc``, ``gcc`` or ``clang`` on the ``PATH``; none gives
  ``no_c_compiler`` naming what to install.

Units and descriptions come from the element catalogue (:mod:`multipole.catalogue`): a parameter
of an element takes its declared unit and meaning, a scene parameter the unit of the element
parameters it is given to (when they agree).
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

import sympy as sp
from sympy.printing.c import C99CodePrinter

from . import codegen
from .equations import Equations
from .errors import MultipoleError
from .files import atomic_output
from .primitives import T


class FmuError(MultipoleError):
    """A scene that cannot be exported as an FMU, or a missing or failing C compiler (exit code 2)."""


#: SI base units of FMI 2.0 ``BaseUnit`` (in its attribute names) and the derived units the
#: catalogue uses, as exponents of them
_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_UNITS = {
    "kg": {"kg": 1}, "m": {"m": 1}, "s": {"s": 1}, "A": {"A": 1}, "K": {"K": 1}, "mol": {"mol": 1},
    "cd": {"cd": 1}, "rad": {"rad": 1},
    "N": {"kg": 1, "m": 1, "s": -2}, "J": {"kg": 1, "m": 2, "s": -2}, "W": {"kg": 1, "m": 2, "s": -3},
    "Pa": {"kg": 1, "m": -1, "s": -2}, "C": {"A": 1, "s": 1}, "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "Ohm": {"kg": 1, "m": 2, "s": -3, "A": -2}, "F": {"kg": -1, "m": -2, "s": 4, "A": 2},
    "H": {"kg": 1, "m": 2, "s": -2, "A": -2}, "Hz": {"s": -1},
}
_FACTOR = re.compile(r"^([A-Za-z]+)(?:\^(-?\d+))?$")


def base_units(unit: str) -> dict | None:
    """``{base unit: exponent}`` of a unit written as the catalogue writes them (``N*m*s/rad``,
    ``kg*m^2``, ``m/s^2``), or None where it is not such a product of known units."""
    text = unit.strip()
    if not text or text in ("-", "1"):
        return None
    out: dict = {}
    parts = re.split(r"([*/])", text)        # read left to right: a/b*c is (a/b)*c
    sign = 1
    for i, part in enumerate(parts):
        if i % 2:
            sign = 1 if part == "*" else -1
            continue
        m = _FACTOR.match(part.strip())
        if m is None or m.group(1) not in _UNITS:
            return None
        power = sign * int(m.group(2) or 1)
        for b, e in _UNITS[m.group(1)].items():
            out[b] = out.get(b, 0) + power * e
    return {b: e for b, e in out.items() if e}


def _unit(unit: str) -> str:
    """The unit as an FMI unit name, '' where it is none or not a product of known units (the
    alternatives ``N*m | N`` of a configurable element, a dimensionless ``-``)."""
    return unit.strip() if base_units(unit) else ""


def _derivative_unit(unit: str) -> str:
    """The unit of the time derivative of a quantity in ``unit`` (``N*m*s`` → ``N*m``, ``rad`` → ``rad/s``)."""
    if not _unit(unit):
        return ""
    return unit[:-2] if unit.endswith("*s") else f"{unit}/s"


class CPrinter(C99CodePrinter):
    """sympy's C99 printer with the project's rules: symbols by the writer's names, every number a
    finite ``double`` literal, switches (steps, sign, abs, max/min) either plain or held on the side
    ``mode[k]`` says (the rule of :class:`multipole.codegen.Printer`), no tables."""

    modes: dict | None = None
    mode_ref = "mode[{k}]"
    _side = codegen.Printer._side

    def __init__(self, names):
        super().__init__({"strict": True})
        self.names = names

    def _print_Symbol(self, s):
        try:
            return self.names[s]
        except KeyError:
            raise FmuError("fmu_codegen", f"no value for symbol {s} in the generated C code") from None

    def _print_Float(self, x):
        value = float(x)
        if not math.isfinite(value):
            raise FmuError("infinite_value", f"the number {sp.Float(x, 4)} is beyond the float range (1.8e308)",
                           "rescale the expression or its units")
        return repr(value)

    def _print_Rational(self, x):
        return repr(float(x))

    def _print_Integer(self, x):
        return repr(float(x))

    def _print_Pow(self, e):
        if e.exp.is_Integer and 1 < int(e.exp) <= 4:     # x*x: exact, and no pow() call
            base = self.parenthesize(e.base, 100)
            return "(" + "*".join([base] * int(e.exp)) + ")"
        return super()._print_Pow(e)

    def _print_Pi(self, e):
        return repr(math.pi)

    def _print_Exp1(self, e):
        return repr(math.e)

    def _print_Mod(self, e):          # sympy's Mod has the sign of the divisor, C's fmod that of the dividend
        a, b = (self._print(x) for x in e.args)
        return f"(({a}) - ({b})*floor(({a})/({b})))"

    def _print_Heaviside(self, e):
        side = self._side(e.args[0])
        if side is not None:
            return f"({side} > 0 ? 1.0 : 0.0)"
        a = self._print(e.args[0])
        at0 = e.args[1] if len(e.args) > 1 else sp.Rational(1, 2)
        return f"(({a}) > 0 ? 1.0 : (({a}) == 0 ? {float(at0)!r} : 0.0))"

    def _print_sign(self, e):
        side = self._side(e.args[0])
        if side is not None:
            return side
        a = self._print(e.args[0])
        return f"(({a}) > 0 ? 1.0 : (({a}) < 0 ? -1.0 : 0.0))"

    def _print_DiracDelta(self, e):
        return "0.0"          # the slope of a held step (see multipole.codegen.Printer._print_DiracDelta)

    def _print_Abs(self, e):
        side = self._side(e.args[0])
        if side is not None:
            return f"({side}*({self._print(e.args[0])}))"
        return f"fabs({self._print(e.args[0])})"

    def _pick(self, e, first_if_positive: bool):
        a, b = e.args
        side = self._side(a - b) if len(e.args) == 2 else None
        if side is None:
            return None
        return f"({side} {'>' if first_if_positive else '<'} 0 ? ({self._print(a)}) : ({self._print(b)}))"

    def _print_Max(self, e):
        return self._pick(e, True) or super()._print_Max(e)

    def _print_Min(self, e):
        return self._pick(e, False) or super()._print_Min(e)

    def _print_Piecewise(self, e):
        raise FmuError("fmu_table", "a table (Piecewise) has no C form here")


#: linear loops up to this many unknowns keep their matrix on the stack (8 bytes × n², 32 kB at 64);
#: larger ones allocate it for each solve
STACK_MAX_UNKNOWNS = 64


class CWriter(codegen.Writer):
    """The kernel's code writer with C output and the parameters kept as symbols (tunable)."""

    def __init__(self, eq: Equations):
        self.params = list(eq.params)
        super().__init__(eq, runtime=self.params)     # nothing folded in: parameters stay tunable
        names = {s: "v_" + n for s, n in self.names.items() if s is not T}   # never a C keyword
        taken = set(names.values()) | {"t"}
        for k, p in enumerate(self.params):
            base = "p_" + re.sub(r"\W", "_", p.name)
            name, n = base, 1
            while name in taken:
                n += 1
                name = f"{base}_{n}"
            taken.add(name)
            names[p] = name
        names[T] = "t"
        self.names = names
        self.printer = CPrinter(names)
        self._cse = 0

    def assignment(self, name: str, expr) -> list:
        """``double name = expr;``, a large expression split by common-subexpression elimination."""
        expr = sp.sympify(expr)
        if sp.count_ops(expr) <= codegen.CSE_MIN_OPS:
            return [f"    double {name} = {self.P(expr)};"]
        self._cse += 1
        temps, (reduced,) = sp.cse([expr], symbols=sp.numbered_symbols(f"c{self._cse}_"))
        lines = []
        for sym, sub in temps:
            self.names[sym] = f"v_{sym}"
            lines.append(f"    double v_{sym} = {self.P(sub)};")
        return lines + [f"    double {name} = {self.P(reduced)};"]

    def c_unit(self, u) -> list:
        """The C lines computing one unit of the evaluation order."""
        if u.kind == "assign":
            return self.assignment(self.names[u.variables[0]], u.exprs[0])
        b = self.eq.blocks[u.block]
        n, k = len(u.variables), u.block
        heap = n > STACK_MAX_UNKNOWNS          # a large loop's matrix is not put on the stack
        if heap:
            lines = [f"    double *A{k} = (double *)calloc({n * n}, sizeof(double));",
                     f"    double *b{k} = (double *)calloc({n}, sizeof(double));",
                     f"    if (A{k} == NULL || b{k} == NULL) {{ free(A{k}); free(b{k}); return 1; }}"]
        else:
            lines = [f"    double A{k}[{n * n}] = {{0.0}};", f"    double b{k}[{n}];"]
        lines += [f"    A{k}[{i * n + j}] = {self.P(v)};" for (i, j), v in sorted(b.matrix.todok().items())]
        lines += [f"    b{k}[{i}] = {self.P(b.rhs[i])};" for i in range(n)]
        lines.append(f"    int bad{k} = mp_solve({n}, A{k}, b{k});")
        lines += [f"    double {self.names[z]} = b{k}[{i}];" for i, z in enumerate(u.variables)]
        if heap:
            lines.append(f"    free(A{k}); free(b{k});")
        return lines + [f"    if (bad{k}) return 1;"]

    def c_prologue(self, name: str, doc: str, units, used, target: str, extra_args: str) -> list:
        """The head of ``static int name(p, t, x[, mode], target)``: the parameters, states and inputs
        in ``used`` (all of them if None), then the ``units``."""
        if used is not None:
            used |= set().union(*(sp.sympify(e).free_symbols for u, e in self.eq.inputs.items() if u in used))
        lines = [f"/* {doc} */",
                 f"static int {name}(const double *p, double t, const double *x{extra_args}, double *{target}) {{",
                 "    (void)p; (void)t; (void)x;"]
        lines += [f"    const double {self.names[q]} = p[{i}];" for i, q in enumerate(self.params)
                  if used is None or q in used]
        lines += [f"    const double {self.names[s]} = x[{i}];" for i, s in enumerate(self.states)
                  if used is None or s in used]
        lines += [f"    const double {self.names[u]} = {self.P(e)};" for u, e in self.eq.inputs.items()
                  if used is None or u in used]
        for u in units:
            lines += self.c_unit(u)
        return lines

    def c_function(self, name: str, doc: str, needed, target: str, values, extra_args: str = "") -> list:
        """``static int name(p, t, x[, mode], target)``: the units ``needed`` takes, then
        ``target[i] = values[i]``; returns 1 where a linear loop is singular."""
        units = codegen.closure(self.units, needed)
        used = set(needed).union(*(u.deps for u in units))
        lines = self.c_prologue(name, doc, units, used, target, extra_args)
        lines += [f"    {target}[{i}] = {v};" for i, v in enumerate(values)]
        return lines + ["    return 0;", "}", ""]

    def c_jacobian(self, name: str, doc: str, extra_args: str = "") -> list:
        """``static int name(p, t, x[, mode], J)``: d(targets)/dx into ``J`` (row-major, one row per
        target of ``self.eq.derivatives``, one column per state), by the forward-mode plan of the
        kernel's writer (:meth:`multipole.codegen.Writer.jacobian_plan`); a loop's derivatives
        ``Dz = -Jz⁻¹ G`` are solved column by column.  Returns 1 where a loop matrix is singular."""
        plan = self.jacobian_plan()
        n_x = len(self.states)
        lines = self.c_prologue(name, doc, plan.units, None, "J", extra_args)
        for step in plan.steps:
            if isinstance(step, codegen.Derivative):
                lines.append(f"    double {step.name} = {step.code};")
                continue
            n, m, k = step.jz.shape[0], step.n_columns, step.block
            arrays = (f"jd_Jz{k}", f"jd_G{k}", f"jd_T{k}", f"jd_c{k}")
            lines += [f"    double *jd_Jz{k} = (double *)calloc({n * n}, sizeof(double));",
                      f"    double *jd_G{k} = (double *)calloc({n * m}, sizeof(double));",
                      f"    double *jd_T{k} = (double *)calloc({n * n}, sizeof(double));",
                      f"    double *jd_c{k} = (double *)calloc({n}, sizeof(double));",
                      f"    int jd_bad{k} = jd_Jz{k} == NULL || jd_G{k} == NULL || jd_T{k} == NULL || jd_c{k} == NULL;"]
            lines.append(f"    if (!jd_bad{k}) {{")
            lines += [f"        jd_Jz{k}[{i * n + j}] = {self.P(v)};" for (i, j), v in sorted(step.jz.todok().items())]
            lines += [f"        jd_G{k}[{r_i * m + c}] = {code};" for r_i, c, code in step.g]
            lines += [f"        for (int col = 0; col < {m} && !jd_bad{k}; col++) {{",
                      f"            memcpy(jd_T{k}, jd_Jz{k}, {n * n} * sizeof(double));",
                      f"            for (int i = 0; i < {n}; i++) jd_c{k}[i] = jd_G{k}[i * {m} + col];",
                      f"            jd_bad{k} = mp_solve({n}, jd_T{k}, jd_c{k});",
                      f"            for (int i = 0; i < {n}; i++) jd_G{k}[i * {m} + col] = -jd_c{k}[i];",
                      "        }", "    }"]
            lines += [f"    double {d} = jd_bad{k} ? 0.0 : jd_G{k}[{zi * m + c}];" for zi, c, d in step.names]
            lines += ["    " + " ".join(f"free({a});" for a in arrays), f"    if (jd_bad{k}) return 1;"]
        rows = len(self.eq.derivatives)
        lines.append(f"    for (int q = 0; q < {rows * n_x}; q++) J[q] = 0.0;")
        lines += [f"    J[{i * n_x + j}] = {d};" for i, j, d in plan.entries]
        return lines + ["    return 0;", "}", ""]


def _refuse_unsupported(w: CWriter, eq: Equations, needed) -> None:
    """Refuse, naming the element, what the C code would not compute as ``multipole simulate``
    does: a nonlinear loop (Newton's method), a table (Piecewise), a value the parameters make
    infinite (a division by a parameter that is 0)."""
    from .checks import Names
    names = Names(eq.analysis) if eq.analysis is not None else None

    def elements(owners):
        return ", ".join(names.elements_of(owners)) if names is not None else ", ".join(owners)
    values = {q: sp.Float(v) for q, v in eq.params.items()}
    for u in codegen.closure(w.units, needed):
        b = eq.blocks[u.block]
        if u.kind == "newton" and b.start is not None:
            raise FmuError("fmu_newton_loop", f"the position closure of {elements(b.owners)} (a linkage or band "
                           "loop, solved at every evaluation) is not evaluated by the exported C code",
                           "simulate with multipole, or export a model without position closures")
        if u.kind == "newton":
            raise FmuError("fmu_newton_loop", f"the nonlinear algebraic loop through {elements(b.owners)} needs "
                           "Newton's method, which the exported C code does not do",
                           "make the loop linear (a linear law, or an inertia or compliance that breaks it), "
                           "or simulate with multipole")
        if any(sp.sympify(e).has(sp.Piecewise) for e in u.exprs):
            raise _table_error(elements(b.owners))
        for e in u.exprs:          # what multipole's code generation refuses (codegen.Writer.P), refused here too
            if sp.sympify(e).xreplace(values).has(sp.zoo, sp.oo, sp.nan):
                zero = sorted(str(q) for q in sp.sympify(e).free_symbols if q in values and values[q] == 0)
                raise FmuError("infinite_value", f"the parameters make a value of element {elements(b.owners)} "
                               "infinite" + (f" ({', '.join(zero)} = 0)" if zero else ""),
                               "a zero inertia, stiffness or resistance divides; "
                               "use a node or a rigid coupling instead")
    for u, e in eq.inputs.items():
        if sp.sympify(e).has(sp.Piecewise):
            raise _table_error(u.name.split(".")[0])


def _table_error(element: str) -> FmuError:
    return FmuError("fmu_table", f"element {element} uses a table (interp), which the FMU export does not support",
                    "replace the table by a formula, or simulate with multipole")


def _printed(what, owners: str):
    """``what()`` with a code printer failure turned into ``fmu_unsupported`` naming the element."""
    try:
        return what()
    except FmuError:
        raise
    except MultipoleError as exc:
        raise FmuError("fmu_unsupported", f"no C code for part of the model: {exc.message}",
                       "regularise or simplify the law, or simulate with multipole") from None
    except (ValueError, TypeError, NotImplementedError) as exc:
        raise FmuError("fmu_unsupported", f"no C code for part of {owners}: {str(exc).splitlines()[0][:120]}",
                       "regularise or simplify the law, or simulate with multipole") from None


def model_source(eq: Equations, outputs) -> tuple[str, int]:
    """C source of the model functions (``mp_derivatives``, ``mp_outputs``, ``mp_switches``,
    ``mp_initial``) and the number of switching functions (event indicators)."""
    w = CWriter(eq)
    sw = codegen.switch_list(w)
    out_exprs = [eq.output(o) for o in outputs]
    need_out = set().union(*(e.free_symbols for e in out_exprs)) if out_exprs else set()
    need_sw = set().union(*(sp.sympify(s).free_symbols for s in sw)) if sw else set()
    _refuse_unsupported(w, eq, set(eq.derivatives) | need_out | need_sw)
    N, P = w.names, w.P
    held = codegen.modal_switches(w, sw) if sw else None

    def build():
        src = []
        w.locked(held)
        ders = [N[d] if d in N else P(d) for d in eq.derivatives]
        src += w.c_function("mp_derivatives", "d/dt of the states, every switch held on the side mode[k] says",
                            set(eq.derivatives), "dx", ders, ", const double *mode")
        w.locked(None)
        src += w.c_function("mp_outputs", "the outputs " + ", ".join(outputs).replace("*/", "* /"), need_out, "y",
                            [P(e) for e in out_exprs])
        src += w.c_function("mp_switches", "the switching functions: the event indicators", need_sw, "g",
                            [P(s) for s in sw])
        w.locked(held)
        src += w.c_jacobian("mp_jac_derivatives", "d(derivatives)/dx, every switch held on its side",
                            ", const double *mode")
        w.locked(None)
        src += _output_writer(eq, out_exprs).c_jacobian("mp_jac_outputs", "d(outputs)/dx")
        init = ["/* the start values of the states that depend on parameters */",
                "static void mp_initial(const double *p, double *x) {", "    (void)p; (void)x;"]
        for i, q in enumerate(w.params):
            init.append(f"    const double {N[q]} = p[{i}]; (void){N[q]};")
        for i, s in enumerate(eq.states):
            if _calculated(s):
                init.append(f"    x[{i}] = {P(s.initial)};")
        return src + init + ["}", ""]
    return "\n".join(_printed(build, "the model")), len(sw)


def _output_writer(eq: Equations, out_exprs) -> CWriter:
    """A writer whose ``eq.derivatives`` are the outputs (each an extra assignment ``y_k = expr``),
    so that its Jacobian plan is d(outputs)/dx."""
    w = CWriter(eq)
    ys = [sp.Symbol(f"_fmu_output{k}") for k in range(len(out_exprs))]
    for k, (y, e) in enumerate(zip(ys, out_exprs)):
        w.names[y] = f"y_out{k}"
        w.units.append(codegen.Unit("assign", [y], [sp.sympify(e)], -1))
    w.eq = dataclasses.replace(eq, derivatives=ys)
    return w


def _calculated(state) -> bool:
    """True if the state's start value depends on parameters (then computed at initialisation)."""
    return bool(sp.sympify(state.initial).free_symbols)


# -- model description -----------------------------------------------------------------------------

def _identifier(name: str) -> str:
    """The modelIdentifier: a C identifier and file name made from the scene name."""
    ident = re.sub(r"\W", "_", name, flags=re.ASCII).strip("_") or "model"
    return ident if not ident[0].isdigit() else "m_" + ident


def _param_info(scene, eq: Equations) -> dict:
    """``{parameter name: (unit, description)}`` from the element catalogue: an element parameter
    ``rotor.J`` has the unit and meaning its type declares; a scene parameter the unit of the
    element parameters it is given to, where they agree."""
    from .catalogue import catalogue
    types = catalogue()
    declared = {}
    for element, type_name in getattr(scene, "element_types", {}).items():
        et = types.get(type_name)
        if et is not None:
            for p in et.params:
                declared[(element, p.name)] = (p, type_name)
    uses: dict = {}
    for element, values in getattr(scene, "element_values", {}).items():
        for pname, text in values.items():
            uses.setdefault(str(text).strip(), []).append((element, pname))
    out = {}
    for sym in eq.params:
        name = sym.name
        element, _, pname = name.rpartition(".")
        if (element, pname) in declared:
            p, type_name = declared[(element, pname)]
            out[name] = (_unit(p.unit), f"{p.doc} of {element} ({type_name})" if p.doc else f"{element} ({type_name})")
            continue
        targets = [declared[u] for u in uses.get(name, []) if u in declared]
        units = {_unit(p.unit) for p, _ in targets}
        where = ", ".join(f"{e}.{n}" for e, n in uses.get(name, []))
        out[name] = (units.pop() if len(units) == 1 else "",
                     "scene parameter" + (f", given to {where}" if where else ""))
    return out


def _output_info(eq: Equations, name: str) -> str:
    """The meaning of an output: the element quantity's documentation, else what it is."""
    flat = eq.analysis.flat if eq.analysis is not None else None
    if flat is not None and name in flat.quantities:
        doc = flat.quantities[name][2]
        if doc:
            return f"{doc} ({name.split('.')[0]})"
    if name.endswith(".e"):
        return f"effort at port {name[:-2]}"
    if name.endswith(".f"):
        return f"flow at port {name[:-2]}"
    return f"output {name}"


def _num(value: float) -> str:
    return repr(float(value))


#: ``simulate``'s default tolerances (:func:`multipole.pipeline.run`), for a scene that sets none
DEFAULT_RTOL, DEFAULT_ATOL = 1e-6, 1e-9


def nominal(scene) -> float:
    """The states' nominal value: the scene's ``atol / rtol``.  An importer that scales its absolute
    tolerance by the nominals (``rtol × nominal``, as FMPy's CVode does) then controls the error as
    ``multipole simulate`` does at the scene's tolerances (``atol + rtol·|x|``): the author of a
    piezo scene with strokes of 1e-9 m sets ``atol: 1e-14`` and gets nominals of 1e-6, not 1."""
    sim = getattr(scene, "simulate", {}) or {}
    return float(sim.get("atol", DEFAULT_ATOL)) / float(sim.get("rtol", DEFAULT_RTOL))


def model_description(scene, eq: Equations, outputs, identifier: str, guid: str, n_events: int) -> tuple[str, dict]:
    """``(modelDescription.xml text, layout)``; ``layout`` gives the value references:
    0 time, then the parameters, the states, their derivatives and the outputs in this order."""
    info = _param_info(scene, eq)
    params = list(eq.params)
    x0 = eq.initial_values()
    variables = []          # (name, vr, attributes, real attributes, description)
    vr = 0
    variables.append(("time", vr, 'causality="independent" variability="continuous"', 'unit="s"',
                      "simulation time"))
    units = {"s"}
    for p in params:
        vr += 1
        unit, doc = info[p.name]
        units.add(unit)
        variables.append((p.name, vr, 'causality="parameter" variability="tunable" initial="exact"',
                          (f'unit={quoteattr(unit)} ' if unit else "") + f'start="{_num(eq.params[p])}"', doc))
    state_index = {}
    for s, v in zip(eq.states, x0):
        vr += 1
        unit = _unit(s.unit)
        units.add(unit)
        state_index[s.name] = len(variables) + 1
        start = ("" if _calculated(s) else f' start="{_num(v)}"') + f' nominal="{_num(nominal(scene))}"'
        initial = "calculated" if _calculated(s) else "exact"
        variables.append((s.name, vr, f'causality="local" variability="continuous" initial="{initial}"',
                          (f'unit={quoteattr(unit)} ' if unit else "") + start.lstrip(),
                          f"state of {s.owner.split('.')[0]} [{s.unit}]" +
                          (f", start value {sp.sympify(s.initial)}" if _calculated(s) else "")))
    derivative_index = []
    for s in eq.states:
        vr += 1
        unit = _derivative_unit(s.unit)
        units.add(unit)
        derivative_index.append(len(variables) + 1)
        variables.append((f"der({s.name})", vr, 'causality="local" variability="continuous" initial="calculated"',
                          (f'unit={quoteattr(unit)} ' if unit else "") + f'derivative="{state_index[s.name]}"',
                          f"time derivative of {s.name}"))
    output_index = []
    for o in outputs:
        vr += 1
        unit = _unit(eq.units.get(o, ""))
        units.add(unit)
        output_index.append(len(variables) + 1)
        variables.append((o, vr, 'causality="output" variability="continuous" initial="calculated"',
                          f'unit={quoteattr(unit)}' if unit else "", _output_info(eq, o)))
    units.discard("")
    unit_lines = []
    for u in sorted(units):
        exps = base_units(u) or {}
        attrs = " ".join(f'{b}="{exps[b]}"' for b in _BASE if b in exps)
        unit_lines.append(f"    <Unit name={quoteattr(u)}><BaseUnit {attrs}/></Unit>")
    initial_unknowns = sorted(output_index + derivative_index +
                              [state_index[s.name] for s in eq.states if _calculated(s)])
    sim = getattr(scene, "simulate", {}) or {}
    experiment = ['startTime="0.0"'] + ([f'stopTime="{_num(sim["t_end"])}"'] if "t_end" in sim else []) + \
        ([f'tolerance="{_num(sim["rtol"])}"'] if "rtol" in sim else [])
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f'<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(eq.name)} guid="{guid}"',
             f'  description={quoteattr(getattr(scene, "description", "") or eq.name)}',
             '  generationTool="multipole" variableNamingConvention="flat"'
             f' numberOfEventIndicators="{n_events}">',
             f'  <ModelExchange modelIdentifier="{identifier}" canNotUseMemoryManagementFunctions="true"'
             ' canGetAndSetFMUstate="false" canSerializeFMUstate="false" providesDirectionalDerivative="true"'
             ' needsExecutionTool="false" completedIntegratorStepNotNeeded="true">',
             '    <SourceFiles>', f'      <File name="{identifier}.c"/>', '    </SourceFiles>',
             '  </ModelExchange>']
    if unit_lines:
        lines += ["  <UnitDefinitions>"] + unit_lines + ["  </UnitDefinitions>"]
    lines += [f"  <DefaultExperiment {' '.join(experiment)}/>", "  <ModelVariables>"]
    for k, (name, ref, attrs, real, doc) in enumerate(variables, 1):
        lines.append(f"    <!-- {k} -->")
        lines.append(f"    <ScalarVariable name={quoteattr(name)} valueReference=\"{ref}\" "
                     f"description={quoteattr(doc)} {attrs}>")
        lines.append(f"      <Real {real}/>" if real else "      <Real/>")
        lines.append("    </ScalarVariable>")
    lines += ["  </ModelVariables>", "  <ModelStructure>"]
    for tag, indices in (("Outputs", output_index), ("Derivatives", derivative_index),
                         ("InitialUnknowns", initial_unknowns)):
        if indices:
            lines += [f"    <{tag}>"] + [f'      <Unknown index="{i}"/>' for i in indices] + [f"    </{tag}>"]
    lines += ["  </ModelStructure>", "</fmiModelDescription>", ""]
    layout = {"n_params": len(params), "n_states": len(eq.states), "n_outputs": len(outputs)}
    return "\n".join(lines), layout


# -- compiling and packing ---------------------------------------------------------------------------

def find_compiler() -> str:
    """Path of the C compiler: ``$CC``, else ``cc``, ``gcc`` or ``clang`` on the PATH."""
    for name in (os.environ.get("CC", "").strip(), "cc", "gcc", "clang"):
        if name:
            found = shutil.which(name)
            if found:
                return found
    raise FmuError("no_c_compiler", "no C compiler found (looked for $CC, cc, gcc and clang on the PATH); "
                   "the FMU's binary is compiled on this machine",
                   "install one: 'apt-get install gcc' (Debian, Ubuntu), 'dnf install gcc' (Fedora), "
                   "'xcode-select --install' (macOS), or set CC")


def platform_folder() -> tuple[str, str]:
    """``(binaries/ folder, library suffix)`` of FMI 2.0 for this machine."""
    bits = "64" if sys.maxsize > 2 ** 32 else "32"
    if sys.platform.startswith("linux"):
        return f"linux{bits}", ".so"
    if sys.platform == "darwin":
        return f"darwin{bits}", ".dylib"
    raise FmuError("fmu_platform", f"FMU export compiles with a Unix C compiler; not supported on {sys.platform}",
                   "export on Linux or macOS")


def compile_library(source: str, identifier: str, folder: Path) -> Path:
    """Compile ``source`` into the shared library ``<identifier><suffix>`` in ``folder``."""
    compiler = find_compiler()
    _, suffix = platform_folder()
    c_file = folder / f"{identifier}.c"
    c_file.write_text(source)
    lib = folder / f"{identifier}{suffix}"
    cmd = [compiler, "-shared", "-fPIC", "-O2", "-std=c99", "-o", str(lib), str(c_file), "-lm"]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise FmuError("c_compile_failed", f"the C compiler {compiler} could not run: {exc}",
                       "check the compiler installation") from None
    if done.returncode != 0:
        first = next((ln for ln in done.stderr.splitlines() if "error" in ln), done.stderr.strip()[:200])
        raise FmuError("c_compile_failed", f"{compiler} failed on the generated C code: {first[:200]}",
                       "report this as a bug in multipole's FMU export, with the netlist")
    return lib


def build_source(eq: Equations, outputs, state_nominal: float = 1.0) -> tuple[str, str, int]:
    """``(complete C source, guid, number of event indicators)``; ``state_nominal``: what
    ``fmi2GetNominalsOfContinuousStates`` returns for every state."""
    body, n_events = model_source(eq, outputs)
    x0 = eq.initial_values()
    head = [f"/* FMI 2.0 Model Exchange unit of {eq.name!r}, generated by multipole: do not edit. */",
            "#include <math.h>", "#include <stddef.h>", "#include <stdlib.h>", "#include <string.h>", "",
            f"#define MP_NP {len(eq.params)}", f"#define MP_NX {len(eq.states)}", f"#define MP_NY {len(outputs)}",
            f"#define MP_NZ {n_events}", f"#define MP_NOMINAL {_num(state_nominal)}",
            "static const double mp_p_start[MP_NP + 1] = {" + ", ".join(_num(v) for v in eq.params.values())
            + ("," if eq.params else "") + " 0.0};",
            "static const double mp_x_start[MP_NX + 1] = {" + ", ".join(_num(v) for v in x0)
            + ("," if x0 else "") + " 0.0};", "",
            "static int mp_solve(int n, double *A, double *b);", ""]
    model = "\n".join(head) + "\n" + body
    guid = "{" + _uuid(model) + "}"
    return model + f'\n#define MP_GUID "{guid}"\n' + _RUNTIME, guid, n_events


def _uuid(text: str) -> str:
    h = hashlib.sha256(text.encode()).hexdigest()
    return f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}"


def export(scene, path, outputs=None, eq: Equations | None = None) -> Path:
    """Write ``scene`` as an FMI 2.0 Model Exchange FMU at ``path`` (written atomically).

    ``outputs``: the FMU's outputs (default: the scene's outputs, else the states).  Raises
    :class:`FmuError` (``fmu_newton_loop``, ``fmu_table``, ``fmu_unsupported``, ``no_c_compiler``,
    ``c_compile_failed``) and :class:`~multipole.errors.IllPosedError` for a scene the check rejects.
    """
    from . import pipeline
    eq = eq or pipeline.equations(scene)
    outputs = list(dict.fromkeys(outputs if outputs is not None else (scene.outputs or eq.state_names)))
    taken = set(eq.state_names) | {p.name for p in eq.params} | {"time"}
    outputs = [o for o in outputs if o not in taken]      # a state is already a variable of the FMU
    source, guid, n_events = build_source(eq, outputs, nominal(scene))
    identifier = _identifier(eq.name)
    xml, _layout = model_description(scene, eq, outputs, identifier, guid, n_events)
    find_compiler()
    plat, suffix = platform_folder()
    with tempfile.TemporaryDirectory(prefix="multipole-fmu-") as tmp:
        lib = compile_library(source, identifier, Path(tmp))
        with atomic_output(path) as part:
            with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
                zf.writestr("modelDescription.xml", xml)
                zf.write(lib, f"binaries/{plat}/{identifier}{suffix}")
                zf.writestr(f"sources/{identifier}.c", source)
    return Path(path)


def cmd_export(args) -> int:
    """``multipole export FILE --fmu model.fmu``: exit 0, 1 with the check's diagnostics for an
    ill-posed scene, 2 for a scene the FMU cannot represent or a missing C compiler."""
    from . import pipeline
    from .cli import _overrides, check_output_path
    from .errors import IllPosedError
    from .netlist import load
    check_output_path(args.fmu, (".fmu",), "--fmu")
    scene = load(args.file, _overrides(args.set))
    try:
        eq = pipeline.equations(scene)
    except IllPosedError:
        analysis = pipeline.check(scene)
        print(f"{args.file}: not well-posed, nothing exported (see 'multipole check {args.file}')", file=sys.stderr)
        for d in analysis.errors:
            print("  " + str(d).replace("\n", "\n  "), file=sys.stderr)
        return 1
    try:
        export(scene, args.fmu, eq=eq)
    except MultipoleError as exc:
        if not exc.where:
            exc.where = scene.path
        raise
    print(f"wrote {args.fmu} (FMI 2.0 Model Exchange: {len(eq.states)} state(s), {len(eq.params)} parameter(s))")
    return 0


#: The FMI 2.0 API for the model functions above, written for multipole (FMI's types and function
#: signatures declared here, after the FMI 2.0 standard, section 2.1).
_RUNTIME = r"""
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- FMI 2.0 types (fmi2TypesPlatform.h, fmi2FunctionTypes.h of the standard) ---- */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
#define fmi2True 1
#define fmi2False 0
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);
typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;
typedef struct {
    fmi2Boolean newDiscreteStatesNeeded;
    fmi2Boolean terminateSimulation;
    fmi2Boolean nominalsOfContinuousStatesChanged;
    fmi2Boolean valuesOfContinuousStatesChanged;
    fmi2Boolean nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;

#if defined(__GNUC__)
#define MP_EXPORT __attribute__((visibility("default")))
#else
#define MP_EXPORT
#endif

/* ---- the instance ---- */
enum { MP_INSTANTIATED, MP_INITIALIZATION, MP_EVENT, MP_CONTINUOUS, MP_TERMINATED };
typedef struct {
    char *name;
    fmi2CallbackFunctions cb;
    int phase;
    int logging;
    double t, stop;
    int stop_defined;
    double p[MP_NP + 1], x[MP_NX + 1], mode[MP_NZ + 1];
} mp_instance;

static void mp_log(mp_instance *m, fmi2Status status, const char *category, const char *format, ...) {
    char text[512];
    va_list args;
    if (m == NULL || m->cb.logger == NULL || (status == fmi2OK && !m->logging)) return;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    m->cb.logger(m->cb.componentEnvironment, m->name, status, category, "%s", text);
}

/* A z = b by Gaussian elimination with partial pivoting (A row-major n x n, overwritten; the
   solution in b); 1 if A is singular. */
static int mp_solve(int n, double *A, double *b) {
    int i, j, k;
    for (k = 0; k < n; k++) {
        int piv = k;
        double big = fabs(A[k * n + k]);
        for (i = k + 1; i < n; i++)
            if (fabs(A[i * n + k]) > big) { big = fabs(A[i * n + k]); piv = i; }
        if (!(big > 0.0)) return 1;
        if (piv != k) {
            for (j = 0; j < n; j++) { double s = A[k * n + j]; A[k * n + j] = A[piv * n + j]; A[piv * n + j] = s; }
            { double s = b[k]; b[k] = b[piv]; b[piv] = s; }
        }
        for (i = k + 1; i < n; i++) {
            double f = A[i * n + k] / A[k * n + k];
            if (f == 0.0) continue;
            for (j = k; j < n; j++) A[i * n + j] -= f * A[k * n + j];
            b[i] -= f * b[k];
        }
    }
    for (k = n - 1; k >= 0; k--) {
        double s = b[k];
        for (j = k + 1; j < n; j++) s -= A[k * n + j] * b[j];
        b[k] = s / A[k * n + k];
    }
    return 0;
}

/* Every switch on the side its function is on; where it is zero, the side it takes just after t
   (first from t alone, then along the motion): the rule of multipole.simulate._sides.  Returns 1
   if a side changed. */
static int mp_sides(mp_instance *m) {
    double g[MP_NZ + 1], later[MP_NZ + 1], dx[MP_NX + 1], moved[MP_NX + 1], side[MP_NZ + 1];
    double span = m->stop_defined ? fabs(m->stop) : fabs(m->t);
    int k, i, zero = 0, changed = 0;
    if (MP_NZ == 0) return 0;
    if (span < 1.0) span = 1.0;
    mp_switches(m->p, m->t, m->x, g);
    for (k = 0; k < MP_NZ; k++) {
        side[k] = g[k] > 0 ? 1.0 : (g[k] < 0 ? -1.0 : 0.0);
        zero |= side[k] == 0.0;
    }
    if (zero) {
        mp_switches(m->p, m->t + 1e-9 * span, m->x, later);
        zero = 0;
        for (k = 0; k < MP_NZ; k++) {
            if (side[k] == 0.0) side[k] = later[k] > 0 ? 1.0 : (later[k] < 0 ? -1.0 : 0.0);
            zero |= side[k] == 0.0;
        }
    }
    if (zero) {
        double held[MP_NZ + 1];
        for (k = 0; k < MP_NZ; k++) held[k] = side[k] == 0.0 ? 1.0 : side[k];
        if (mp_derivatives(m->p, m->t, m->x, held, dx) == 0) {
            for (i = 0; i < MP_NX; i++) moved[i] = m->x[i] + 1e-6 * span * dx[i];
            mp_switches(m->p, m->t, moved, later);
            for (k = 0; k < MP_NZ; k++)
                if (side[k] == 0.0) side[k] = later[k] > 0 ? 1.0 : (later[k] < 0 ? -1.0 : 0.0);
        }
    }
    for (k = 0; k < MP_NZ; k++) {
        if (side[k] == 0.0) side[k] = 1.0;
        changed |= side[k] != m->mode[k];
        m->mode[k] = side[k];
    }
    return changed;
}

#define MP_VR_PARAMS 1u
#define MP_VR_STATES (MP_VR_PARAMS + MP_NP)
#define MP_VR_DERS (MP_VR_STATES + MP_NX)
#define MP_VR_OUTS (MP_VR_DERS + MP_NX)
#define MP_VR_END (MP_VR_OUTS + MP_NY)

static fmi2Status mp_fail(mp_instance *m, const char *function, const char *what) {
    mp_log(m, fmi2Error, "logStatusError", "%s: %s", function, what);
    return fmi2Error;
}

/* ---- common functions ---- */
MP_EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
MP_EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

MP_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n,
                                         const fmi2String categories[]) {
    mp_instance *m = (mp_instance *)c;
    (void)n; (void)categories;
    if (m == NULL) return fmi2Error;
    m->logging = loggingOn;
    return fmi2OK;
}

MP_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                        fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                        fmi2Boolean visible, fmi2Boolean loggingOn) {
    mp_instance *m;
    (void)fmuResourceLocation; (void)visible;
    if (functions == NULL || instanceName == NULL) return NULL;
    if (fmuType != fmi2ModelExchange || fmuGUID == NULL || strcmp(fmuGUID, MP_GUID) != 0) {
        if (functions->logger != NULL)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "fmi2Instantiate: %s", fmuType != fmi2ModelExchange ?
                              "this FMU supports Model Exchange only" : "the GUID does not match this binary");
        return NULL;
    }
    m = (mp_instance *)calloc(1, sizeof(mp_instance));
    if (m == NULL) return NULL;
    m->name = (char *)malloc(strlen(instanceName) + 1);
    if (m->name == NULL) { free(m); return NULL; }
    strcpy(m->name, instanceName);
    m->cb = *functions;
    m->logging = loggingOn;
    m->phase = MP_INSTANTIATED;
    memcpy(m->p, mp_p_start, sizeof m->p);
    memcpy(m->x, mp_x_start, sizeof m->x);
    return m;
}

MP_EXPORT void fmi2FreeInstance(fmi2Component c) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return;
    free(m->name);
    free(m);
}

MP_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                         fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    mp_instance *m = (mp_instance *)c;
    (void)toleranceDefined; (void)tolerance;
    if (m == NULL) return fmi2Error;
    if (m->phase != MP_INSTANTIATED) return mp_fail(m, "fmi2SetupExperiment", "only allowed after fmi2Instantiate");
    m->t = startTime;
    m->stop_defined = stopTimeDefined;
    m->stop = stopTime;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    if (m->phase != MP_INSTANTIATED)
        return mp_fail(m, "fmi2EnterInitializationMode", "only allowed after fmi2Instantiate");
    m->phase = MP_INITIALIZATION;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    if (m->phase != MP_INITIALIZATION) return mp_fail(m, "fmi2ExitInitializationMode", "not in initialization mode");
    mp_initial(m->p, m->x);
    mp_sides(m);
    m->phase = MP_EVENT;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    m->phase = MP_TERMINATED;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    m->phase = MP_INSTANTIATED;
    m->t = 0.0;
    m->stop_defined = 0;
    memcpy(m->p, mp_p_start, sizeof m->p);
    memcpy(m->x, mp_x_start, sizeof m->x);
    memset(m->mode, 0, sizeof m->mode);
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    mp_instance *m = (mp_instance *)c;
    double x[MP_NX + 1], dx[MP_NX + 1], y[MP_NY + 1];
    int have_dx = 0, have_y = 0;
    size_t i;
    if (m == NULL) return fmi2Error;
    if (m->phase == MP_INSTANTIATED || m->phase == MP_INITIALIZATION) {
        mp_initial(m->p, m->x);              /* start values that depend on parameters, and the */
        mp_sides(m);                         /* switches' sides there (done again on leaving)   */
    }
    memcpy(x, m->x, sizeof x);
    for (i = 0; i < nvr; i++) {
        fmi2ValueReference r = vr[i];
        if (r == 0) value[i] = m->t;
        else if (r < MP_VR_STATES) value[i] = m->p[r - MP_VR_PARAMS];
        else if (r < MP_VR_DERS) value[i] = x[r - MP_VR_STATES];
        else if (r < MP_VR_OUTS) {
            if (!have_dx && mp_derivatives(m->p, m->t, x, m->mode, dx))
                return mp_fail(m, "fmi2GetReal", "singular linear loop");
            have_dx = 1;
            value[i] = dx[r - MP_VR_DERS];
        } else if (r < MP_VR_END) {
            if (!have_y && mp_outputs(m->p, m->t, x, y)) return mp_fail(m, "fmi2GetReal", "singular linear loop");
            have_y = 1;
            value[i] = y[r - MP_VR_OUTS];
        } else return mp_fail(m, "fmi2GetReal", "unknown value reference");
    }
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    mp_instance *m = (mp_instance *)c;
    size_t i;
    if (m == NULL) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        fmi2ValueReference r = vr[i];
        if (r >= MP_VR_PARAMS && r < MP_VR_STATES) {
            if (m->phase == MP_CONTINUOUS || m->phase == MP_TERMINATED)
                return mp_fail(m, "fmi2SetReal", "a parameter can be set before initialisation or in event mode");
            m->p[r - MP_VR_PARAMS] = value[i];
        } else if (r >= MP_VR_STATES && r < MP_VR_DERS) {
            if (m->phase != MP_INSTANTIATED && m->phase != MP_INITIALIZATION)
                return mp_fail(m, "fmi2SetReal", "states are set with fmi2SetContinuousStates after initialisation");
            m->x[r - MP_VR_STATES] = value[i];
        } else return mp_fail(m, "fmi2SetReal", "the value reference is not a parameter or a state start value");
    }
    return fmi2OK;
}

/* The FMU has Real variables only: the other types' functions accept empty lists. */
#define MP_NO_VARIABLES(function, type, qualifier)                                                   \
    MP_EXPORT fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,      \
                                  qualifier type value[]) {                                        \
        (void)vr; (void)value;                                                                     \
        return nvr == 0 ? fmi2OK : mp_fail((mp_instance *)c, #function, "the FMU has Real variables only"); \
    }
MP_NO_VARIABLES(fmi2GetInteger, fmi2Integer, )
MP_NO_VARIABLES(fmi2GetBoolean, fmi2Boolean, )
MP_NO_VARIABLES(fmi2GetString, fmi2String, )
MP_NO_VARIABLES(fmi2SetInteger, fmi2Integer, const)
MP_NO_VARIABLES(fmi2SetBoolean, fmi2Boolean, const)
MP_NO_VARIABLES(fmi2SetString, fmi2String, const)

/* not supported (canGetAndSetFMUstate and canSerializeFMUstate are false) */
MP_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    (void)s; return mp_fail((mp_instance *)c, "fmi2GetFMUstate", "not supported");
}
MP_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    (void)s; return mp_fail((mp_instance *)c, "fmi2SetFMUstate", "not supported");
}
MP_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    (void)s; return mp_fail((mp_instance *)c, "fmi2FreeFMUstate", "not supported");
}
MP_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    (void)s; (void)size; return mp_fail((mp_instance *)c, "fmi2SerializedFMUstateSize", "not supported");
}
MP_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte bytes[], size_t size) {
    (void)s; (void)bytes; (void)size; return mp_fail((mp_instance *)c, "fmi2SerializeFMUstate", "not supported");
}
MP_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *s) {
    (void)s; (void)bytes; (void)size; return mp_fail((mp_instance *)c, "fmi2DeSerializeFMUstate", "not supported");
}
/* The exact partial derivatives of the state derivatives (switches held) and of the outputs by the
   states (the knowns of Model Exchange: this FMU has no inputs). */
MP_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                                  const fmi2ValueReference k[], size_t nk, const fmi2Real dk[],
                                                  fmi2Real du[]) {
    mp_instance *m = (mp_instance *)c;
    const char *fn = "fmi2GetDirectionalDerivative";
    double *J;
    int need_d = 0, need_y = 0;
    size_t i, j;
    if (m == NULL) return fmi2Error;
    if (m->phase == MP_INSTANTIATED || m->phase == MP_TERMINATED)
        return mp_fail(m, fn, "only between fmi2EnterInitializationMode and fmi2Terminate");
    for (j = 0; j < nk; j++)
        if (k[j] < MP_VR_STATES || k[j] >= MP_VR_DERS) return mp_fail(m, fn, "the knowns must be states");
    for (i = 0; i < nu; i++) {
        if (u[i] >= MP_VR_DERS && u[i] < MP_VR_OUTS) need_d = 1;
        else if (u[i] >= MP_VR_OUTS && u[i] < MP_VR_END) need_y = 1;
        else return mp_fail(m, fn, "the unknowns must be state derivatives or outputs");
    }
    if (m->phase == MP_INITIALIZATION) { mp_initial(m->p, m->x); mp_sides(m); }
    J = (double *)calloc((size_t)(MP_NX + MP_NY) * MP_NX + 1, sizeof(double));
    if (J == NULL) return mp_fail(m, fn, "out of memory");
    if ((need_d && mp_jac_derivatives(m->p, m->t, m->x, m->mode, J)) ||
        (need_y && mp_jac_outputs(m->p, m->t, m->x, J + MP_NX * MP_NX))) {
        free(J);
        return mp_fail(m, fn, "singular linear loop");
    }
    for (i = 0; i < nu; i++) {
        size_t row = u[i] - MP_VR_DERS;          /* the derivatives' rows, then the outputs' */
        double s = 0.0;
        for (j = 0; j < nk; j++) s += J[row * MP_NX + (k[j] - MP_VR_STATES)] * dk[j];
        du[i] = s;
    }
    free(J);
    return fmi2OK;
}

/* ---- Model Exchange ---- */
MP_EXPORT fmi2Status fmi2EnterEventMode(fmi2Component c) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    m->phase = MP_EVENT;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL || info == NULL) return fmi2Error;
    if (m->phase != MP_EVENT) return mp_fail(m, "fmi2NewDiscreteStates", "not in event mode");
    mp_sides(m);             /* the switches are plain functions of (t, x): one pass settles them */
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    if (m->phase != MP_EVENT) return mp_fail(m, "fmi2EnterContinuousTimeMode", "not in event mode");
    m->phase = MP_CONTINUOUS;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                                 fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)c; (void)noSetFMUStatePriorToCurrentPoint;
    if (enterEventMode) *enterEventMode = fmi2False;
    if (terminateSimulation) *terminateSimulation = fmi2False;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    m->t = time;
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    if (nx != MP_NX) return mp_fail(m, "fmi2SetContinuousStates", "wrong number of states");
    if (nx) memcpy(m->x, x, nx * sizeof(double));
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    mp_instance *m = (mp_instance *)c;
    if (m == NULL) return fmi2Error;
    if (nx != MP_NX) return mp_fail(m, "fmi2GetContinuousStates", "wrong number of states");
    if (nx) memcpy(x, m->x, nx * sizeof(double));
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    mp_instance *m = (mp_instance *)c;
    double out[MP_NX + 1];
    if (m == NULL) return fmi2Error;
    if (nx != MP_NX) return mp_fail(m, "fmi2GetDerivatives", "wrong number of states");
    if (mp_derivatives(m->p, m->t, m->x, m->mode, out)) return mp_fail(m, "fmi2GetDerivatives", "singular linear loop");
    if (nx) memcpy(dx, out, nx * sizeof(double));
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    mp_instance *m = (mp_instance *)c;
    double g[MP_NZ + 1];
    if (m == NULL) return fmi2Error;
    if (nz != MP_NZ) return mp_fail(m, "fmi2GetEventIndicators", "wrong number of event indicators");
    if (mp_switches(m->p, m->t, m->x, g)) return mp_fail(m, "fmi2GetEventIndicators", "singular linear loop");
    if (nz) memcpy(z, g, nz * sizeof(double));
    return fmi2OK;
}

MP_EXPORT fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real nominal[], size_t nx) {
    size_t i;
    (void)c;
    for (i = 0; i < nx; i++) nominal[i] = MP_NOMINAL;
    return fmi2OK;
}
"""
