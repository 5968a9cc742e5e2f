"""Assembly of the explicit ODE from a causal analysis (DESIGN §8).

The assigned equations are ordered by their dependencies; strongly connected components are
algebraic loops.  Each :class:`Block` computes some variables from states, inputs and earlier
blocks:

* ``explicit`` — one equation solved for one variable (symbolically);
* ``linear`` — a linear loop, solved symbolically when small (the constrained-state form of
  derivative causality lands here and gives the effective inertia), otherwise kept as ``A·z = b``
  and solved numerically in the generated code;
* ``newton`` — a nonlinear loop, solved by Newton's method in the generated code (a position
  closure whose element gives a formula, :class:`multipole.network.ClosedForm`, by that formula).

:class:`Equations` holds the states, inputs, parameters, blocks and outputs, and prints them as
text, LaTeX or Python (the generated code), and as Weber-style back-calculation chains.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import math

import networkx as nx
import numpy as np
import sympy as sp
from sympy.solvers.solveset import NonlinearError

from .causality import Analysis, der
from .diagnostics import Diagnostic
from .errors import IllPosedError, ModelError
from .network import map_closed_form, closure_order, var
from .primitives import T
from .stages import _subset, bulk, derivative, numeric_function, substitute

#: linear loops up to this size are solved symbolically
SYMBOLIC_LIMIT = 8
#: the core left after eliminating the constant pivots of a larger loop is solved symbolically up to
#: this size (its entries are compound expressions: a 5 x 5 symbolic solve of a four-bar's took minutes)
CORE_SYMBOLIC_LIMIT = 2


@dataclass
class Block:
    """Variables computed together, in evaluation order."""

    kind: str                     # explicit | linear | newton
    variables: list
    solution: list | None         # symbolic values (explicit, small linear)
    residuals: list               # the block's equations, expr == 0
    owners: list
    notes: list
    matrix: sp.Matrix | None = None   # numeric linear blocks: A z = b
    rhs: sp.Matrix | None = None
    start: list | None = None         # newton blocks: symbols whose values are the first start
    #: a position closure solved by formula (:class:`multipole.network.ClosedForm` in the closed
    #: values of earlier closures; ``select`` in this closure's integrated states ``start``)
    closed_form: object = None

    def reads(self) -> list:
        """Every expression the block reads: equations, solution, loop matrix, start, closed form."""
        exprs = list(self.residuals) + list(self.solution or ()) + list(self.start or ())
        if self.matrix is not None:
            exprs += list(self.matrix) + list(self.rhs)
        if self.closed_form is not None:
            cf = self.closed_form
            exprs += [e for branch in cf.branches for v in branch for e in (v if isinstance(v, tuple) else (v,))]
            exprs += [] if cf.select is None else [cf.select]
        return exprs


@dataclass
class Equations:
    """The explicit ODE ``x' = f(t, x, u)`` with outputs ``y = g(t, x, u)``."""

    name: str
    states: list                  # State objects (integrated)
    derivatives: list             # symbol computing d/dt of each state
    inputs: dict                  # input symbol -> expression of t
    params: dict                  # parameter symbol -> value (float)
    blocks: list
    available: dict               # output name -> expression
    diagnostics: list = field(default_factory=list)
    units: dict = field(default_factory=dict)   # output name -> SI unit
    analysis: Analysis | None = None
    #: ``(expr, Monitor, element)`` of the elements' run-time monitors (:class:`multipole.network.Monitor`;
    #: states are their integrated values), the closures' dead-centre guards among them
    monitors: list = field(default_factory=list)

    # -- look-ups --------------------------------------------------------------------------------
    @property
    def state_names(self) -> list[str]:
        return [s.name for s in self.states]

    def initial_values(self) -> list[float]:
        key = tuple(self.params.items())
        cached = self.__dict__.get("_x0")
        if cached is None or cached[0] != key:       # a mechanism's start values nest the start formulas of
            vals = dict(self.params)                 # every module before it: worked out once per parameters
            memo: dict = {}
            cached = self._x0 = (key, [float(substitute(sp.sympify(s.initial), vals, memo)) for s in self.states])
        return list(cached[1])

    def output(self, name: str) -> sp.Expr:
        """Expression of a named output (element quantity, port variable, state, input)."""
        try:
            return self.available[name]
        except KeyError:
            element = name.split(".")[0]
            offered = self.user_outputs()
            close = [k for k in offered if k.split(".")[0] == element]
            fix = f"available for {element}: {', '.join(close[:16])}{', …' if len(close) > 16 else ''}" if close else \
                f"no element {element!r} has outputs; elements: {', '.join(sorted({k.split('.')[0] for k in offered})[:16])}"
            raise ModelError("unknown_output", f"unknown output {name!r}", fix) from None

    def user_outputs(self) -> list:
        """The output names a netlist can ask for, in its own words: each element's quantities, then
        the effort and flow of its ports, then the states (the port variables of the primitives an
        element is built of are outputs too, but not offered)."""
        if self.analysis is None:
            return sorted(self.available)
        flat = self.analysis.flat
        names = list(flat.quantities) + [f"{p}.{k}" for p in sorted(flat.external_ports) for k in "ef"] + \
            [s.name for s in self.states]
        return [n for n in dict.fromkeys(names) if n in self.available]

    def definitions(self) -> dict:
        """variable -> symbolic value for every explicitly solved variable."""
        out = {}
        for b in self.blocks:
            if b.solution is not None:
                out.update(zip(b.variables, b.solution))
        return out

    def substituted(self, expr, max_ops: int = 400) -> sp.Expr:
        """``expr`` in states, inputs and parameters only (where every block is symbolic), as far as
        that stays printable: substitution stops once the expression passes ``max_ops`` operations
        (a mechanism's torque, substituted to the end, had 190,000 characters and took minutes), and
        the variables left are defined in the evaluation order."""
        defs = self.definitions()
        expr = sp.sympify(expr)
        for b in reversed(self.blocks):
            if b.solution is None:
                continue
            free = expr.free_symbols
            hit = {v: defs[v] for v in b.variables if v in free}
            if hit:
                grown = expr.xreplace(hit)
                if sp.count_ops(grown) > max_ops:
                    break
                expr = grown
        expr = sp.expand(expr) if sp.count_ops(expr) < max_ops else expr
        if sp.count_ops(expr) >= max_ops // 4 or expr.atoms(sp.Function):
            return expr      # sympy's simplify of functions of the unknowns (tanh(73 + f) - pi/f) can run for
        return sp.simplify(expr)   # minutes (a fuzzed netlist); it only tidies the printed text

    # -- printing ---------------------------------------------------------------------------------
    def to_text(self, outputs=(), steps: bool = False) -> str:
        lines = [f"# {self.name}: explicit ODE x' = f(t, x, u), {len(self.states)} state(s)", "", "States:"]
        for s, x0 in zip(self.states, self.initial_values()):
            lines.append(f"  {s.name}  [{s.unit}]  initial {x0:g}")
        show, who = self.netlist_names()
        show = _capped(show)
        if self.inputs:
            lines += ["", "Inputs:"] + [f"  {u} = {show(e)}" for u, e in self.inputs.items()]
        values = {str(e): show(e) for e in self.inputs.values() if str(e) != show(e)}

        def note(text):         # a source's note quotes its value: with steps as the netlist wrote them
            for raw, shown in values.items():
                text = text.replace(raw, shown)
            return text
        lines += ["", "Parameters:"] + [f"  {p} = {v:g}" for p, v in sorted(self.params.items(), key=lambda kv: str(kv[0]))]
        size = sum(len(b.variables) for b in self.blocks)
        lines += ["", "State equations:"]
        if size > 400:
            lines.append(f"  not expanded: {size} variables; the evaluation order below computes them in turn")
        else:
            for s, d in zip(self.states, self.derivatives):
                lines.append(f"  d/dt {s.name} = {show(self.substituted(d))}")
            for name in outputs:
                lines.append(f"  {name} = {show(self.substituted(self.output(name)))}")
            numeric = [b for b in self.blocks if b.solution is None]
            if numeric:
                unknowns = [show(v) for b in numeric for v in b.variables]
                verb = "solves" if len(unknowns) == 1 else "solve"
                lines.append(f"  where {', '.join(unknowns)} {verb} the algebraic loop(s) below at every "
                             "evaluation (no closed form)")
        lines += ["", "Evaluation order (causal assignments):"]
        for b in self.blocks:
            if b.kind == "explicit":
                lines.append(f"  {show(b.variables[0])} = {show(b.solution[0])}    [{who(b.owners[0])}: {note(b.notes[0])}]")
            else:
                how = "solved symbolically" if b.solution is not None else \
                    "solved numerically (LU)" if b.kind == "linear" else \
                    "solved by its element's formula" if b.closed_form is not None else "solved by Newton"
                what = "position closure" if b.start is not None else f"{b.kind} loop"
                lines.append(f"  {what} for ({', '.join(map(show, b.variables))}), {how}:")
                for r, o in zip(b.residuals, b.owners):
                    lines.append(f"      0 = {show(r)}    [{who(o)}]")
                if b.closed_form is not None and b.closed_form.select is not None:
                    lines.append(f"    => the branch where {show(b.closed_form.select)} >= 0, else the other")
                if b.solution is not None:
                    lines += [f"    => {show(v)} = {show(s)}" for v, s in zip(b.variables, b.solution)]
        if steps:
            lines += ["", "Back-calculation (Weber's chains):"]
            targets = list(outputs) + [f"d/dt {s.name}" for s in self.states]
            for name, expr in zip(targets, [self.output(o) for o in outputs] + list(self.derivatives)):
                lines += self.chain(name, expr, (show, who))
        return "\n".join(lines)

    def netlist_names(self):
        """``(show, who)`` for printing the evaluation order in the netlist's names: ``show(expr)``
        writes a port variable as the netlist port that carries it (``load.a.e``, not the inner
        junction's ``load.j.a.e``), else as the element quantity equal to it (``shaft.force``), else
        as ``element.innerN.e`` (a variable inside an element that no port shows), and steps as
        ``step()``; ``who(owner)`` names an equation's element, or a node by the ports it joins."""
        if self.analysis is None:
            return str, str
        from .checks import Names, user_expression
        names, flat, aliases = Names(self.analysis), self.analysis.flat, self.analysis.aliases
        quantity = {}
        for q in flat.quantities:
            quantity.setdefault(self.available.get(q), q)
        mapping, count = {}, {}

        def port_variable(sym):
            name = sym.name
            if name.startswith("der(") and name.endswith(")"):
                inner = port_variable(var(name[4:-1]))
                return f"der({inner})" if inner else None
            if name[-2:] not in (".e", ".f") or name[:-2] not in flat.port_domains:
                return None
            kind, (rep, sign) = name[-1], aliases.get(sym, (sym, 1))
            element = flat.element_of(name)
            for v in [sym] + sorted(names.members.get(rep, []), key=lambda v: (flat.element_of(v.name) != element,
                                                                                v.name)):
                if v.name.endswith("." + kind) and aliases.get(v, (v, 1))[1] == sign and names.port(v.name[:-2]):
                    return f"{names.port(v.name[:-2])}.{kind}"
            if sym in quantity:
                return quantity[sym]
            count[element] = count.get(element, 0) + 1
            return f"{element}.inner{count[element]}.{kind}"

        def show(expr):
            expr = sp.sympify(expr)
            for sym in sorted(expr.free_symbols - set(mapping), key=lambda s: s.name):
                text = port_variable(sym)
                mapping[sym] = sp.Symbol(text) if text else sym
            return user_expression(expr.xreplace(mapping))

        def who(owner):
            if owner.startswith("node(") and owner.endswith(")"):
                ports = [names.port(p) or flat.element_of(p) for p in owner[5:-1].split(", ")]
                return "node " + ", ".join(dict.fromkeys(ports))
            return owner if owner == "loop" else flat.element_of(owner)
        return show, who

    def chain(self, name, expr, shown=None) -> list[str]:
        """One substitution per line from ``expr`` back to states and inputs."""
        show, who = shown or self.netlist_names()
        show = _capped(show)
        defs = self.definitions()
        owner = {v: (b.owners[0] if b.kind == "explicit" else "loop") for b in self.blocks for v in b.variables}
        lines = [f"  {name}", f"    = {show(expr)}"]
        seen = 0
        while seen < 200:
            pending = [v for v in sp.sympify(expr).free_symbols if v in defs]
            if not pending:
                break
            v = max(pending, key=lambda s: self._order(s))
            expr = sp.sympify(expr).xreplace({v: defs[v]})
            text = show(expr)
            lines.append(f"    = {text}    [{show(v)} from {who(owner.get(v, '?'))}]")
            seen += 1
            if text.endswith(_CUT):          # longer with every substitution: the rest is code, not reading
                break
        return lines

    def _order(self, sym) -> int:
        for k, b in enumerate(self.blocks):
            if sym in b.variables:
                return k
        return -1

    def to_latex(self, outputs=()) -> str:
        """The state equations and outputs as a LaTeX ``aligned`` block; names set upright, products
        with a centred dot, so that ``shaft.q`` and ``J_1`` read as written in the netlist."""
        pairs = [(s.symbol, self.substituted(d)) for s, d in zip(self.states, self.derivatives)]
        pairs_out = [(name, self.substituted(self.output(name))) for name in outputs]
        symbols = set().union(*(e.free_symbols | {x} for x, e in pairs), *(e.free_symbols for _, e in pairs_out))
        names = {x: _latex_name(x.name) for x in symbols if isinstance(x, sp.Symbol)}

        def tex(e):
            return sp.latex(e, symbol_names=names, mul_symbol="dot")
        rows = [rf"\frac{{d}}{{dt}} {names[x]} &= {tex(e)}" for x, e in pairs]
        rows += [rf"{_latex_name(name)} &= {tex(e)}" for name, e in pairs_out]
        unsolved = [v for b in self.blocks if b.solution is None for v in b.variables]
        text = "\\begin{aligned}\n" + " \\\\\n".join(rows) + "\n\\end{aligned}"
        if unsolved:
            text += ("\n% " + ", ".join(map(str, unsolved)) + ": solution of the algebraic loop(s), "
                     "computed numerically at every evaluation (see the text format)")
        return text


def _latex_name(name: str) -> str:
    """A dotted netlist name as upright LaTeX text (``d_1.force`` → ``\\mathrm{d\\_1.force}``)."""
    return r"\mathrm{" + name.replace("\\", "").replace("_", r"\_").replace(" ", r"\ ") + "}"


# ---------------------------------------------------------------------------------------------

def linear_coefficient(expr, v):
    """``(a, rest)`` with ``expr == a*v + rest`` and neither containing ``v``; None if not linear.

    A fast path over the terms of a sum (the common case: node balances, ratios, storage laws);
    anything else falls back to sympy's differentiation.
    """
    coeffs, rest = [], []
    for term in sp.Add.make_args(expr):
        if v not in term.free_symbols:
            rest.append(term)
            continue
        factors = sp.Mul.make_args(term)
        if factors.count(v) != 1 or any(v in f.free_symbols for f in factors if f != v):
            a = derivative(expr, v)
            if v in a.free_symbols:
                return None
            return a, sp.expand(expr - a * v)
        coeffs.append(_subset(sp.Mul, [f for f in factors if f != v], sp.S.One))
    return sp.Add(*coeffs), _subset(sp.Add, rest, sp.S.Zero)


def _solve_single(expr, v):
    """Solve ``expr == 0`` for ``v``; None if it is not explicitly solvable."""
    split = linear_coefficient(expr, v)
    if split is None or split[0] == 0:
        return None
    a, rest = split
    if a == 1:
        return -rest
    if a == -1:
        return rest
    return -rest / a


def _solve_linear(residuals, zs):
    try:
        A, b = sp.linear_eq_to_matrix([sp.expand(r) for r in residuals], zs)
    except NonlinearError:
        return None, None
    unknowns = set(zs)
    if any(a.free_symbols & unknowns for a in A.values()):       # the nonzero entries
        return None, None
    return A, b


def _constant_pivots(A, b, zs, owners, notes, params: dict):
    """Eliminate from the linear block ``A z = b`` every unknown that some row determines with a
    constant coefficient (a number or a parameter expression: the aliases, balances and rigid
    couplings of a network), cheapest row first (Markowitz).  Returns ``(core, eliminated)``: the
    remaining block ``(A', b', zs', owners', notes')`` (possibly empty) and the eliminated unknowns
    ``[(z, expression, owner, note)]`` in elimination order, each an expression of the core and of
    the unknowns eliminated after it — so they are computed after the core, in reverse order.  A
    mechanism's derivative-causality block of 46 unknowns keeps one or two (its reduced inertia);
    nothing is approximated."""
    n = len(zs)
    rows: dict = {i: {} for i in range(n)}
    for (i, j), a in A.todok().items():
        if a != 0:
            rows[i][j] = a
    rhs = {i: b[i] for i in range(n)}
    cols: dict = {j: set() for j in range(n)}
    for i, r in rows.items():
        for j in r:
            cols[j].add(i)
    known = set(params)

    def pivot_ok(a):
        if a.free_symbols - known:
            return False
        value = float(a.xreplace(params)) if a.free_symbols else float(a)
        return value != 0.0 and math.isfinite(value)

    eliminated = []
    while True:
        best, cost = None, None
        for i, r in rows.items():
            for j, a in r.items():
                c = (len(r) - 1) * (len(cols[j]) - 1)
                if (cost is None or c < cost) and pivot_ok(a):
                    best, cost = (i, j), c
                    if c == 0:
                        break
            if cost == 0:
                break
        if best is None:
            break
        i, j = best
        row = rows.pop(i)
        a_ij = row.pop(j)
        b_i = rhs.pop(i)
        cols[j].discard(i)
        for k in row:
            cols[k].discard(i)
        eliminated.append((zs[j], (b_i - sp.Add(*[a * zs[k] for k, a in row.items()])) / a_ij, owners[i], notes[i]))
        for r in list(cols.pop(j)):
            f = rows[r].pop(j) / a_ij
            for k, a in row.items():
                new = rows[r].get(k, sp.Integer(0)) - f * a
                if new == 0:
                    rows[r].pop(k, None)
                    cols[k].discard(r)
                else:
                    rows[r][k] = new
                    cols[k].add(r)
            rhs[r] = rhs[r] - f * b_i
    keep_rows = sorted(rows)
    keep_cols = sorted(cols)
    index = {j: c for c, j in enumerate(keep_cols)}
    A2 = sp.zeros(len(keep_rows), len(keep_cols))
    for r_new, r in enumerate(keep_rows):
        for j, a in rows[r].items():
            A2[r_new, index[j]] = a
    b2 = sp.Matrix([rhs[r] for r in keep_rows])
    core = (A2, b2, [zs[j] for j in keep_cols], [owners[r] for r in keep_rows], [notes[r] for r in keep_rows])
    return core, eliminated


@bulk
def assemble(analysis: Analysis, name: str = "model") -> Equations:
    """Order and solve the assigned equations; raise :class:`IllPosedError` if not well-posed."""
    if not analysis.ok:
        first = analysis.errors[0]
        raise IllPosedError(first.code, f"the network is not well-posed: {first.message}", first.fix)
    eqs = analysis.equations
    assigned = analysis.assignment
    by_var = {v: i for i, v in assigned.items()}
    g = nx.DiGraph()
    g.add_nodes_from(assigned)
    for i, v in assigned.items():
        for w in eqs[i].expr.free_symbols:
            j = by_var.get(w)
            if j is not None and j != i:
                g.add_edge(j, i)
    cond = nx.condensation(g)
    params = analysis.flat.param_values()
    blocks, closed = _closure_blocks(analysis)
    diagnostics: list[Diagnostic] = []
    for c in nx.topological_sort(cond):
        members = sorted(cond.nodes[c]["members"])
        zs = [assigned[i] for i in members]
        res = [eqs[i].expr for i in members]
        owners = [eqs[i].owner for i in members]
        notes = [eqs[i].note for i in members]
        if len(members) == 1:
            sol = _solve_single(res[0], zs[0])
            if sol is not None:
                blocks.append(Block("explicit", zs, [sol], res, owners, notes))
                continue
            blocks.append(Block("newton", zs, None, res, owners, notes))
            diagnostics.append(_loop_diag(analysis, owners, zs, "nonlinear", res))
            continue
        A, b = _solve_linear(res, zs)
        if A is None:
            kept, torn = _tear(res, zs, owners, notes, analysis.flat.param_values())
            blocks.append(Block("newton", *kept))
            blocks += [Block("explicit", [z], [sol], [r], [o], [n]) for z, sol, r, o, n in reversed(torn)]
            diagnostics.append(_loop_diag(analysis, owners, zs, "nonlinear", res, kept[0]))
            continue
        numeric = A.xreplace(analysis.flat.param_values())
        side = None if any(x.free_symbols for x in numeric) else {} if _singular_matrix(numeric) else None
        if side is None:
            side = _singular_switch_side(A, analysis.flat.param_values())
        if side is not None:
            from .checks import Names, listing, user_expression
            names = Names(analysis)
            els = names.elements_of(owners)
            where = " and ".join(f"{user_expression(a)} {'>' if on else '<'} 0" for a, on in side.items())
            err = IllPosedError("singular_loop", f"the algebraic loop through {', '.join(els)} is singular"
                                f"{' while ' + where if where else ''}: it does not determine "
                                f"{names.variables(zs)} uniquely",
                                f"put a storage element (a mass, an inertia) between {listing(els)} so the loop is "
                                "determined on every side of their switching laws, or combine them into one element "
                                "whose law covers both" if where else
                                f"check the parameters of {listing(els)} (a loop gain or a resistance sum that is "
                                "zero) or add a storage element to the loop")
            err.variables, err.owners = zs, owners      # for the check's wording (multipole.checks)
            raise err
        derivative = any(eqs[i].role == "differentiated" for i in members)
        first = len(blocks)
        if len(zs) <= CRAMER_LIMIT:
            blocks.append(Block("linear", zs, _cramer(A, b), res, owners, notes, A, b))
        elif len(zs) <= SYMBOLIC_LIMIT:
            sol = A.LUsolve(b)
            # cancel removes common factors that vanish at a mechanism's dead centres (0/0 in the
            # uncancelled quotient of the slider-crank); it costs the 8-link mechanism's check 12 s
            sol = [sp.cancel(sp.together(s)) if sp.count_ops(s) < 300 else s for s in sol]
            blocks.append(Block("linear", zs, sol, res, owners, notes, A, b))
        else:
            blocks += _split_block(A, b, zs, owners, notes, analysis.flat.param_values())
        if not derivative:
            diagnostics.append(_loop_diag(analysis, owners, zs, "linear", res,
                                          symbolic=all(b.solution is not None for b in blocks[first:])))
    states = analysis.states
    available, units = _available(analysis)
    if closed:
        _use_closed(blocks, available, closed)
    # a monitor may read a port variable the analysis merged into another (an alias): read that one
    aliased = {v: r if sign == 1 else -r for v, (r, sign) in analysis.aliases.items() if v != r} \
        if analysis.flat.monitors else {}
    eq = Equations(name, states, [der(s.symbol) for s in states], dict(analysis.flat.inputs),
                   analysis.flat.param_values(), blocks, available, diagnostics, units=units, analysis=analysis,
                   monitors=[(sp.sympify(e).xreplace(aliased), m, o) for e, m, o in analysis.flat.monitors])
    _loops_at_start(eq)
    if analysis.demoted:
        report = _consistent_start(eq, analysis.demoted)
        if report is not None:
            diagnostics.append(report)
    return eq


#: small linear loops whose matrix depends on more than parameters (a mechanism's velocity relations
#: on its angles) are solved by Cramer's rule up to this size (see :func:`_cramer`)
CRAMER_LIMIT = 4


def _cramer(A, b) -> list:
    """``A⁻¹ b`` as ``det(A_i) / det(A)`` (``A_i``: column i replaced by ``b``), each ``det(A_i)``
    expanded along that column: ``sum_k adj(A)[i, k] b_k`` with the cofactors of ``A`` (division-free
    determinants of the loop's coefficients, worked out once; the right-hand sides, long expressions
    of the rest of the network, enter once per unknown instead of multiplied through every
    determinant: the 8-link mechanism's nine loops 0.12 s -> 0.02 s, their solutions 2782 -> 1759
    operations).  The denominator is the determinant itself, zero only where the loop is singular:
    an LU solution divides by pivots that vanish at regular poses too (0/0 at the slider-crank's dead
    centres) and needs ``cancel``, which cost the 8-link mechanism's check a third of its time."""
    det = A.det(method="berkowitz")
    adj = A.adjugate(method="berkowitz")
    n = A.shape[0]
    return [sp.Add(*[adj[i, k] * b[k] for k in range(n) if adj[i, k] != 0]) / det for i in range(n)]


def _split_block(A, b, zs, owners, notes, params) -> list:
    """A large linear block as its core (after :func:`_constant_pivots`; solved symbolically when it
    is small, numerically otherwise) followed by the eliminated unknowns, explicit."""
    (A2, b2, core, c_owners, c_notes), gone = _constant_pivots(A, b, zs, owners, notes, params)
    out = []
    if core:
        res = [sp.Add(*[A2[r, k] * core[k] for k in range(len(core)) if A2[r, k] != 0]) - b2[r]
               for r in range(len(core))]
        sol = None
        if len(core) <= CORE_SYMBOLIC_LIMIT:      # its entries are compound already: symbolic only when tiny
            sol = [sp.cancel(sp.together(x)) if sp.count_ops(x) < 300 else x for x in A2.LUsolve(b2)]
        out.append(Block("linear", core, sol, res, c_owners, c_notes, A2, b2))
    out += [Block("explicit", [z], [expr], [z - expr], [o], [note]) for z, expr, o, note in reversed(gone)]
    return out


#: printed expressions are cut at this many characters (a mechanism's substituted torque ran to 190,000)
PRINT_LIMIT = 1500
_CUT = "(cut: see --format python)"


def _capped(show):
    """``show`` with texts longer than :data:`PRINT_LIMIT` cut and marked."""
    if getattr(show, "capped", False):
        return show

    def capped(expr):
        text = show(expr)
        return text if len(text) <= PRINT_LIMIT else f"{text[:PRINT_LIMIT]} … {_CUT}"
    capped.capped = True
    return capped


def closed_symbol(state) -> sp.Symbol:
    """The symbol of a closure-bound state's value on the closure (``crank.L1.q3*``)."""
    return var(state.name + "*")


def _closure_blocks(analysis: Analysis) -> tuple[list, dict]:
    """One Newton block per closure of the flat network (:class:`multipole.network.Closure`), in
    the order their residuals need each other, and the map state -> its value on the closure.

    The block solves the closure's residuals for the closed values of its states, started from the
    integrated values; everything the equations compute from those states then reads the closed
    values (see :func:`_use_closed`), so a position never drifts off its closure."""
    closures = analysis.flat.closures
    closed = {s: closed_symbol(s) for states, _r, _o in closures for s in states}
    order = closure_order(closures)
    if order is None:
        raise IllPosedError("position_loop", "the position closures of "
                            + ", ".join(sorted({o for _s, _r, o in closures})) + " need each other in a circle",
                            "build the mechanism in structural order (each group anchored on bodies determined "
                            "before it)")
    blocks = []
    for k in order:
        states, residuals, owner = closures[k]
        res = [sp.sympify(r).xreplace(closed) for r in residuals]
        cf = analysis.flat.closed_forms.get(k)
        if cf is not None:      # earlier closures' states by their closed values; the select by its own integrated ones
            earlier = {s: c for s, c in closed.items() if s not in states}
            cf = map_closed_form(cf, lambda e: sp.sympify(e).xreplace(earlier))
        blocks.append(Block("newton", [closed[s] for s in states], None, res, [owner] * len(res),
                            ["position closure"] * len(res), start=list(states), closed_form=cf))
    return blocks, closed


def _use_closed(blocks: list, available: dict, closed: dict) -> None:
    """Make every block after the closures, and every output, read the closed state values."""
    def swap(e):
        e = sp.sympify(e)
        return e.xreplace(closed) if e.free_symbols & closed.keys() else e
    for b in blocks:
        if b.start is not None:
            continue
        b.residuals = [swap(r) for r in b.residuals]
        if b.solution is not None:
            b.solution = [swap(x) for x in b.solution]
        if b.matrix is not None:
            b.matrix = b.matrix.applyfunc(swap)
            b.rhs = b.rhs.applyfunc(swap)
    for name, e in list(available.items()):
        available[name] = swap(e)


def evaluate_blocks(eq: Equations, t: float, x, wanted) -> dict:
    """Numeric values of the variables ``wanted`` at time ``t`` and integrated states ``x``, each as
    ``(value, magnitude)``: the magnitude is the size of the terms the value was computed from
    (sums of absolute values), a scale for its rounding error.

    Only the blocks ``wanted`` depends on are evaluated, in order: explicit and symbolic linear
    blocks by substitution, numeric linear ones by a dense solve, nonlinear ones by Newton's method
    (scipy, from a few starts).  Raises ``ArithmeticError`` if a value is not a finite real number
    (:class:`LoopFailure` if a nonlinear loop has no unique solution there).
    """
    values, mags = block_values(eq, t, x, wanted, magnitudes=True)
    return {v: (values[v], mags[v]) for v in wanted}


def block_values(eq: Equations, t: float, x, wanted=None, magnitudes=False):
    """``(values, magnitudes)``: symbol -> float for the parameters, ``t``, the states, the inputs
    and every variable the blocks compute (only those ``wanted`` depends on, if given); the
    magnitudes (see :func:`evaluate_blocks`) only if asked for, else None."""
    values = {p: float(v) for p, v in eq.params.items()}
    values[T] = float(t)
    values.update({s.symbol: float(v) for s, v in zip(eq.states, x)})
    for u, e in eq.inputs.items():
        values[u] = _real(sp.sympify(e).xreplace(values))
    mags = {k: abs(v) for k, v in values.items()} if magnitudes else None
    if wanted is None:
        todo = list(eq.blocks)
    else:
        needed = set(wanted)
        todo = []
        for b in reversed(eq.blocks):
            if needed & set(b.variables):
                todo.append(b)
                needed |= set().union(*(sp.sympify(r).free_symbols for r in b.residuals))
        todo.reverse()
    for b in todo:
        if b.solution is not None:
            for v, sol in zip(b.variables, b.solution):
                values[v] = _real(sp.sympify(sol).xreplace(values))
                if magnitudes:
                    mags[v] = _magnitude(sp.sympify(sol), mags)
        elif b.kind == "linear":
            A = np.array(b.matrix.xreplace(values).evalf(), dtype=float)
            rhs = np.array(b.rhs.xreplace(values).evalf(), dtype=float).ravel()
            z = np.linalg.solve(A, rhs)
            values.update(zip(b.variables, (float(v) for v in z)))
            if magnitudes:
                size = np.abs(np.linalg.inv(A)) @ (np.abs(A) @ np.abs(z) + np.abs(rhs))
                mags.update(zip(b.variables, (float(v) for v in size)))
        else:
            z = _newton_block(b, values)
            values.update(zip(b.variables, (float(v) for v in z)))
            if magnitudes:
                mags.update(zip(b.variables, (abs(float(v)) for v in z)))
    return values, mags


class LoopFailure(ArithmeticError):
    """A nonlinear algebraic loop without a unique solution at the point evaluated."""

    def __init__(self, block: Block, reason: str):
        self.block = block
        self.reason = reason
        super().__init__(reason)


def _newton_block(b: Block, values: dict):
    """Solve a nonlinear block at known ``values`` of everything else (scipy's hybrid Newton from a
    few starts); :class:`LoopFailure` if no start converges or the loop's Jacobian is singular at
    the solution (the unknowns are not determined there).  A position closure is solved by
    :func:`_closure_newton` from the integrated values instead (no scipy: its import was a quarter
    of a mechanism's check)."""
    res = [sp.sympify(r).xreplace(values) for r in b.residuals]
    if any(r.free_symbols - set(b.variables) for r in res):
        raise ArithmeticError("the loop needs values that are not available")
    try:
        residuals = numeric_function(b.variables, res)
        jacobian = numeric_function(b.variables, list(sp.Matrix(res).jacobian(b.variables)))
        fun, jac = (lambda z: residuals(*z)), (lambda z: jacobian(*z))
    except Exception as exc:      # noqa: BLE001 -- sympy cannot print it for numpy: not computable here
        raise ArithmeticError(f"the loop cannot be evaluated numerically here ({exc})") from None

    def guarded(g, shape=None):
        def call(z):
            try:
                out = np.asarray(g(z), dtype=float)
            except (NameError, TypeError, ValueError, ZeroDivisionError, OverflowError, AttributeError) as exc:
                # a function numpy does not have (DiracDelta of a differentiated step), a complex value
                raise ArithmeticError(f"the loop cannot be evaluated numerically here ({exc})") from None
            return out.reshape(shape) if shape else out
        return call
    f = guarded(fun)
    fprime = guarded(jac, (len(res), len(b.variables)))
    n = len(b.variables)
    rng = np.random.default_rng(0)
    starts = [np.zeros(n), np.ones(n), -np.ones(n)] + [rng.normal(scale=10.0, size=n) for _ in range(3)]
    if b.start is not None:         # a closure: from the integrated values only (the branch they are on)
        starts = [np.array([float(values[s]) for s in b.start])]
    for z0 in starts:
        with np.errstate(all="ignore"):
            if b.start is not None:
                z, ok = _closure_newton(f, fprime, z0), 1
            else:
                from scipy.optimize import fsolve
                z, _info, ok, _msg = fsolve(f, z0, fprime=fprime, full_output=True)
            if z is None or ok != 1 or not np.all(np.isfinite(z)) or not np.all(np.isfinite(f(z))):
                continue
            J = fprime(z)
        if not np.all(np.isfinite(J)):
            continue
        if _singular(J):
            # an isolated root may have a singular Jacobian (e = d·f·|f| at f = 0); a loop that stays
            # singular all around the solution does not determine its unknowns (a continuum of roots)
            around = [z + rng.normal(scale=max(1.0, float(np.abs(z).max())), size=n) for _ in range(3)]
            with np.errstate(all="ignore"):
                if all(_singular(fprime(w)) for w in around):
                    raise LoopFailure(b, "its equations do not depend on its unknowns there, so the loop leaves "
                                      "them undetermined")
        return z
    raise LoopFailure(b, "its equations have no solution there (Newton's method converged from none of "
                      f"{len(starts)} starts)")


def _closure_newton(f, fprime, z, tol: float = 1e-12, max_iter: int = 50):
    """The root of the residuals ``f`` (Jacobian ``fprime``) by Newton's iteration from ``z``, with
    the step rule of the generated code's closure solve (converged when the step is at most
    ``tol``·(1 + max |z|)), or None (no convergence, or a Jacobian that is exactly singular off the
    root).  A start whose residual is already zero stays where it is, even on a dead centre."""
    for _ in range(max_iter):
        F = f(z)
        if not np.all(np.isfinite(F)):
            return None
        if not np.any(F):
            return z
        J = fprime(z)
        if not np.all(np.isfinite(J)):
            return None
        try:
            step = np.linalg.solve(J, F)
        except np.linalg.LinAlgError:
            return None
        z = z - step
        if np.abs(step).max() <= tol * (1.0 + np.abs(z).max()):
            return z
    return None


def _singular_matrix(A) -> bool:
    """True if the numeric square matrix ``A`` (sympy numbers) is singular: its rank in floating
    point is short of its size (numpy's SVD; sympy's exact determinant is O(k³) in sympy objects,
    minutes for a loop of a few hundred unknowns)."""
    M = np.array(A.tolist(), dtype=float)
    if not np.all(np.isfinite(M)):
        return True
    for axis in (1, 0):                # equilibrate: loops mix units (1e-9 m/V beside 1e7 N/m)
        scale = np.abs(M).max(axis=axis, keepdims=True)
        if np.any(scale == 0):
            return True
        M = M / scale
    return np.linalg.matrix_rank(M) < M.shape[0]


#: a linear loop's switching factors are tried on both sides up to this many of them (2**n matrices)
_MAX_SWITCHES = 8


def _singular_switch_side(A, params) -> dict | None:
    """The side of the switches on which the loop matrix ``A`` is singular, ``{argument: on}`` for
    each ``Heaviside(argument)`` factor in it, or None.  A compression-only stop in derivative
    causality brings its law's slope ``k·Heaviside(q)`` into the constrained-state loop: on the
    flat side of every switch the effective compliance divides by zero and the split of the motion
    between the storages is undetermined.  Only matrices whose every non-parameter symbol sits in a
    switch are decided; sides that make the matrix contain another symbol are left alone."""
    steps = sorted(A.atoms(sp.Heaviside), key=sp.default_sort_key)
    if not steps or len(steps) > _MAX_SWITCHES:
        return None
    numeric = A.xreplace(params)
    for bits in range(2 ** len(steps)):
        side = {h: sp.S((bits >> k) & 1) for k, h in enumerate(steps)}
        M = numeric.xreplace({h.xreplace(params): v for h, v in side.items()})
        if not any(x.free_symbols for x in M) and _singular_matrix(M):
            return {h.args[0]: bool(v) for h, v in side.items()}
    return None


def _singular(J) -> bool:
    """True for a Jacobian with a zero column or rank deficient after scaling its columns."""
    if not np.all(np.isfinite(J)):
        return False
    norms = np.linalg.norm(J, axis=0)
    if norms.min() == 0:
        return True
    sv = np.linalg.svd(J / norms, compute_uv=False)
    return bool(sv.min() <= 1e-12 * sv.max())


def _loops_at_start(eq: Equations) -> None:
    """Refuse a nonlinear algebraic loop that has no unique solution at t = 0 in the initial state:
    the generated code's Newton iteration would stop the run at its first evaluation (a massless
    shaft whose only connection is a saturating friction law, say, with no normal force yet)."""
    wanted = [v for b in eq.blocks if b.kind == "newton" for v in b.variables]
    if not wanted:
        return
    try:
        block_values(eq, 0.0, eq.initial_values(), wanted)        # values only: no magnitudes needed
    except LoopFailure as exc:
        b = exc.block
        from .checks import Names
        els = Names(eq.analysis).elements_of(b.owners)
        err = IllPosedError("singular_loop", f"the nonlinear algebraic loop through {', '.join(els)} has no "
                            f"unique solution at t = 0 in the initial state: {exc.reason}",
                            f"give the massless part next to {els[0]} an inertia, or {els[0]} a law that is "
                            "strictly monotonic over the whole range (a viscous part, damping)")
        err.variables, err.owners = b.variables, b.owners      # for the check's wording (multipole.checks)
        raise err from None
    except (ArithmeticError, TypeError, ValueError, np.linalg.LinAlgError):
        return                      # not computable here (an input undefined at t = 0): the run will tell


def _real(expr) -> float:
    value = complex(sp.sympify(expr).evalf())
    if value.imag != 0 or not np.isfinite(value.real):
        raise ArithmeticError(f"not a finite real number: {expr}")
    return value.real


def _magnitude(expr, mags) -> float:
    """``expr`` evaluated with every sum replaced by the sum of its terms' absolute values."""
    if expr.is_Symbol:
        return mags.get(expr, 0.0)
    if expr.is_Number:
        return abs(float(expr))
    args = [_magnitude(a, mags) for a in expr.args]
    if expr.is_Add:
        return sum(args)
    if expr.is_Mul:
        return float(np.prod(args))
    if expr.is_Pow and expr.exp.is_Number:
        base = args[0]
        return base ** float(expr.exp) if base > 0 or float(expr.exp) > 0 else 0.0
    return abs(_real(expr.xreplace({s: sp.Float(m) for s, m in mags.items() if s in expr.free_symbols})))


def _consistent_start(eq: Equations, demoted) -> Diagnostic | None:
    """Compare the initial values given for the states in derivative causality with the values
    the rigid couplings impose at t = 0 (computed from the constraints, given the integrated states
    and the inputs at t = 0); an info diagnostic lists the ones that differ (they start at the
    consistent value), None if all agree or the values cannot be computed."""
    try:
        got = evaluate_blocks(eq, 0.0, eq.initial_values(), [s.symbol for s in demoted])
    except (ArithmeticError, TypeError, ValueError, np.linalg.LinAlgError):
        return None
    vals = {p: v for p, v in eq.params.items()}
    changed = []
    for s in demoted:
        if not s.given:         # nothing was given (a dependent link of a mechanism): nothing to report
            continue
        given = float(sp.sympify(s.initial).xreplace(vals))
        value, size = got[s.symbol]
        if abs(value - given) > 1e-9 * max(size, abs(given)):
            changed.append((s, value, given))
    if not changed:
        return None
    elements = sorted({eq.analysis.flat.element_of(s.owner) for s, _, _ in changed})
    listing = ", ".join(f"{s.name} = {v:.6g} {s.unit} (given {g:.6g})" for s, v, g in changed)
    return Diagnostic("derivative_causality", "initial values made consistent with the rigid couplings at "
                      f"t = 0: {listing}; the simulation starts there", elements=elements)


def _tear(res, zs, owners, notes, values):
    """Split a nonlinear loop: a residual that is linear in one of the loop's variables, with a
    coefficient that is a nonzero number and free of the loop's variables, gives that variable
    explicitly; it is substituted into the other residuals, until one unknown is left or no such
    pair remains.  Returns ``(variables, None, residuals, owners, notes)`` for Newton's method and
    the torn ``(variable, solution, residual, owner, note)`` in the order they were torn (compute
    them in reverse after the Newton solve)."""
    res, zs, owners, notes = list(res), list(zs), list(owners), list(notes)
    torn = []
    while len(zs) > 1:
        pick = None
        for i, r in enumerate(res):
            for z in zs:
                split = linear_coefficient(r, z)
                if split is None or split[0].free_symbols & set(zs):
                    continue
                a = sp.sympify(sp.sympify(split[0]).xreplace(values))   # a bare parameter maps to a float
                if a.is_number and a != 0:
                    pick = i, z, -split[1] / split[0]
                    break
            if pick:
                break
        if pick is None:
            break
        i, z, sol = pick
        torn.append((z, sol, res[i], owners[i], notes[i]))
        del res[i], owners[i], notes[i]
        zs.remove(z)
        res = [r.xreplace({z: sol}) for r in res]
    return (zs, None, res, owners, notes), torn


def _loop_diag(analysis, owners, zs, kind, res, iterated=None, symbolic=True):
    """The ``algebraic_loop`` info in the netlist's names (``multipole check`` shows it)."""
    from .checks import Names
    names = Names(analysis)
    els = names.elements_of(owners)
    how = ("solved symbolically" if symbolic else "solved numerically in the generated code") if kind == "linear" \
        else "iterated by Newton's method in the generated code"
    if iterated is not None and len(iterated) < len(zs):
        how += f" on {names.variables(iterated, 2)}, the others explicit from it"
    unknowns = list(dict.fromkeys(names.variable(z) for z in zs))
    return Diagnostic("algebraic_loop", f"{kind} algebraic loop through {', '.join(els)} "
                      f"({len(unknowns)} unknown(s): {names.variables(zs, 4)}): {how}", elements=els)


def _available(analysis: Analysis) -> dict:
    flat = analysis.flat
    out = {}
    units = {}

    def rep(name):
        r, sign = analysis.aliases[var(name)]
        return r if sign == 1 else -r
    for path, pp in [(pp, pp) for pp in flat.port_domains] + list(flat.external_ports.items()):
        dom = flat.port_domains[pp]
        for k, unit in (("e", dom.effort_unit), ("f", dom.flow_unit)):
            out[f"{path}.{k}"] = rep(f"{pp}.{k}")
            units[f"{path}.{k}"] = unit
    for s in flat.states:
        out[s.name] = s.symbol
        units[s.name] = s.unit
    for u in flat.inputs:
        out[u.name] = u
    for name, (expr, unit, _doc) in flat.quantities.items():
        out[name] = analysis.substitute(expr)
        units[name] = unit
    return out, units


def switching_functions(expr) -> list:
    """Expressions whose sign change makes ``expr`` switch (steps, max/min, abs, sign, tables)."""
    out = []
    for node in sp.preorder_traversal(expr):
        if isinstance(node, (sp.Heaviside, sp.sign, sp.Abs)):
            out.append(node.args[0])
        elif isinstance(node, (sp.Max, sp.Min)) and len(node.args) == 2:
            out.append(node.args[0] - node.args[1])
        elif isinstance(node, sp.Piecewise):
            for _e, c in node.args:
                if isinstance(c, sp.core.relational.Relational):
                    out.append(c.lhs - c.rhs)
    return out
