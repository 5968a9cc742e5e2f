"""The causality analyser (DESIGN §7).

Works on the equations of a :class:`~multipole.network.FlatNetwork`:

1. *Aliases.* Node and junction identities (``x = ±y``) merge variables, so a rigid node has one
   speed and a chain two-port one through-torque.
2. *Assignment.* Every equation is assigned the variable it computes (a bipartite matching with
   states and inputs known).  Sources and storage laws take their natural output first, so the
   result reads like Weber's arrows: integral causality for I and C wherever possible.
3. *Over-determined parts* (equations left without a variable) are examined numerically at a few
   sample points.  A part that only constrains storage states is *derivative causality*: the best
   conditioned states are demoted and the constraint is differentiated (Pantelides), which yields
   the constrained-state form ``E(x)·x' = F(x, u)`` and so effective inertias and compliances.
   A part whose equations are redundant without any state is a structural error: two sources on
   one variable, or a rigid loop (kinematic over-determination with static under-determination);
   a loop whose kinematic constraints alone force standstill is a locked loop.
4. What no equation determines is reported as under-determined.  If an under-determined part
   reaches a *placeholder* — a primitive an element library put where its structure needs a part
   the user left out — the report uses the placeholder's own words instead of the generic ones
   (see :func:`placeholder_needs`).  The kernel knows nothing about what is missing; the element
   says it.

The result is an :class:`Analysis`: the final equations, their assignment, the states that are
integrated, the demoted ones and the *findings* (:class:`Finding`, internal names).  This module is
the algorithm only: the registered checks of :mod:`multipole.checks` turn the findings into the
diagnostics the user reads.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import networkx as nx
import numpy as np
import sympy as sp

from .diagnostics import names_list, run_checks
from .network import Equation, FlatNetwork, State, var
from .primitives import T
from .stages import bulk, derivative, numeric_function

_ROLE_RANK = {"storage": 0, "law": 0, "source": 0}


def placeholder_needs(prim) -> tuple[str, str] | None:
    """``(needs, fix)`` if ``prim`` is a placeholder primitive, else None.

    The protocol for element libraries: a :class:`~multipole.primitives.Primitive` subclass that
    stands for a part of the element's structure which the chosen parameters leave out contributes
    no equations and sets

    * ``needs`` — what is missing there, as a phrase that completes "<element>: …", in the
      element's own terms (e.g. "the … branch lacks a cross-coupling: …");
    * ``fix`` (optional) — what the user should change; ``{element}`` is replaced by the name of
      the top-level element the user wrote in the netlist, ``{owner}`` by the path of the network
      that contains the placeholder.

    When the analyser finds variables no equation determines and they reach a placeholder's port,
    it reports the code ``missing_cross_coupling`` with these words instead of the generic
    ``underdetermined`` report.
    """
    needs = getattr(prim, "needs", None)
    if not isinstance(needs, str) or not needs.strip():
        return None
    fix = getattr(prim, "fix", "")
    return needs.strip(), fix if isinstance(fix, str) else ""


def der(sym: sp.Symbol) -> sp.Symbol:
    """Symbol for the time derivative of ``sym``."""
    return var(f"der({sym.name})")


@dataclass
class Finding:
    """A structural fact the analyser found, in internal names; :mod:`multipole.checks` words it.

    ``kind``: ``redundant`` (equations that repeat each other with nothing to absorb them),
    ``locked`` (the rigid constraints of a locked loop), ``impulse`` (a differentiated equation
    whose input has a step), ``demoted`` (equations resolved by putting ``states`` into derivative
    causality), ``overdetermined`` (equations left over), ``undetermined`` (``variables`` nothing
    determines), ``placeholder`` (a placeholder primitive at ``path`` reached by undetermined
    ``variables``; ``words`` = (needs, fix), ``sums`` = the nearest junctions and nodes).
    """

    kind: str
    equations: list = field(default_factory=list)
    states: list = field(default_factory=list)
    variables: list = field(default_factory=list)
    path: str = ""
    words: tuple = ("", "")
    sums: list = field(default_factory=list)
    related: list = field(default_factory=list)   # undetermined: every unknown left undetermined with them


#: findings that make the network ill-posed (the analyser stops resolving after one)
ERROR_FINDINGS = ("redundant", "locked", "impulse", "overdetermined", "undetermined", "placeholder")


@dataclass
class Analysis:
    """What the analyser found; the input of :func:`multipole.equations.assemble`."""

    flat: FlatNetwork
    equations: list            # Equation, after alias substitution, incl. state and differentiated ones
    assignment: dict           # equation index -> the unknown it computes
    unknowns: list
    states: list               # integrated State objects (substituted rhs)
    demoted: list              # State objects put into derivative causality
    aliases: dict              # port variable -> (representative, sign)
    diagnostics: list = field(default_factory=list)
    findings: list = field(default_factory=list)   # Finding objects, worded by multipole.checks
    assembled: object = field(default=None, repr=False)  # Equations, when the pipeline's check built them
    _alias_map: dict | None = field(default=None, repr=False)

    @property
    def errors(self) -> list:
        return [d for d in self.diagnostics if d.severity == "error"]

    @property
    def ok(self) -> bool:
        return not self.errors

    def substitute(self, expr) -> sp.Expr:
        """Rewrite an expression of port variables in representatives."""
        if self._alias_map is None:
            self._alias_map = _alias_substitution(self.aliases)
        return sp.sympify(expr).xreplace(self._alias_map)

    def computed_by(self, variable: sp.Symbol) -> str:
        """Owner (primitive path or node) of the equation that computes a port variable."""
        rep, _ = self.aliases.get(variable, (variable, 1))
        for i, v in self.assignment.items():
            if v == rep:
                return self.equations[i].owner
        return ""

    def report(self) -> str:
        lines = [str(d) for d in self.diagnostics]
        n_err = len(self.errors)
        lines.append(f"{'well-posed' if n_err == 0 else 'NOT well-posed'}: {n_err} error(s), "
                     f"{sum(d.severity == 'warning' for d in self.diagnostics)} warning(s), "
                     f"{len(self.states)} state(s)")
        return "\n".join(lines)

    def __repr__(self) -> str:
        """One short line: the verdict, the counts of findings by severity and the states."""
        counts = ", ".join(f"{sum(d.severity == s for d in self.diagnostics)} {s}(s)" for s in ("error", "warning"))
        names = [s.name for s in self.states]
        shown = names_list(names)
        codes = sorted({d.code for d in self.diagnostics if d.severity == "error"})
        return (f"<Analysis {'well-posed' if self.ok else 'NOT well-posed'}: {counts}"
                + (f" ({', '.join(codes[:5])})" if codes else "") + f"; {len(names)} state(s): {shown or '-'}>")

    def _repr_html_(self) -> str:
        """The notebook view: the verdict, the states and every finding with its fix."""
        from html import escape
        rows = "".join(f"<tr><td>{escape(d.severity)}</td><td>{escape(d.code)}</td><td>{escape(d.message)}</td>"
                       f"<td>{escape(d.fix)}</td></tr>" for d in self.diagnostics)
        names = [s.name for s in self.states]
        return (f"<div><b>{'well-posed' if self.ok else 'NOT well-posed'}</b>: {escape(repr(self)[10:-1])}"
                f"<p>states ({len(names)}): {escape(names_list(names, 50))}</p>"
                "<table><tr><th>severity</th><th>code</th><th>finding</th><th>fix</th></tr>"
                f"{rows}</table></div>")


# ---------------------------------------------------------------------------------------------
# aliases

def _alias_pair(expr, port_vars):
    """``(x, y, s)`` with ``x = s*y`` if ``expr`` is ``a*x + b*y`` with ``a = ±b``, else None."""
    if not isinstance(expr, sp.Add) or len(expr.args) != 2:
        return None
    terms = []
    for term in expr.args:
        c, v = term.as_coeff_Mul()
        if v not in port_vars or not c.is_Number:
            return None
        terms.append((c, v))
    (c1, x), (c2, y) = terms
    if abs(c1) != abs(c2) or x == y:
        return None
    return x, y, int(-c2 / c1)


def _alias_substitution(aliases: dict) -> dict:
    """``{variable: ±representative}`` for every variable that is not its own representative."""
    return {v: r if s == 1 else -r for v, (r, s) in aliases.items() if v != r}


class _UnionFind:
    def __init__(self, rank):
        self.parent: dict = {}
        self.rank = rank

    def find(self, x):
        sign = 1
        path = []
        while x in self.parent:
            p, s = self.parent[x]
            path.append((x, sign))
            sign *= s
            x = p
        for node, s_before in path:      # path compression
            self.parent[node] = (x, sign * s_before)
        return x, sign

    def union(self, x, y, s):
        """Record ``x = s*y``; returns None, or the residual sign if the two already merge."""
        rx, sx = self.find(x)
        ry, sy = self.find(y)
        if rx == ry:
            return sx - s * sy          # 0: redundant identity; else x_root*(sx - s*sy) == 0
        # x = sx*rx, y = sy*ry, x = s*y  ->  rx = sx*s*sy*ry
        if self.rank(rx) < self.rank(ry):
            self.parent[ry] = (rx, sx * s * sy)
        else:
            self.parent[rx] = (ry, sx * s * sy)
        return None


def _port_rank(flat: FlatNetwork):
    order = {"I": 0, "C": 0, "CField": 0, "R": 1, "Se": 2, "Sf": 2, "TF": 3, "MTF": 3, "GY": 3}

    def rank(sym):
        path = sym.name.rsplit(".", 2)[0]
        prim = flat.primitives.get(path)
        return order.get(prim.kind, 4) if prim is not None else 5
    return rank


# ---------------------------------------------------------------------------------------------
# matching

def _linear_vars(expr, unknown_set) -> set:
    """Unknowns that appear in ``expr`` only linearly with coefficients free of unknowns."""
    linear, nonlinear = set(), set()
    for term in sp.Add.make_args(expr):
        factors = sp.Mul.make_args(term)
        hits = [f for f in factors if f.free_symbols & unknown_set]
        if len(hits) == 1 and hits[0] in unknown_set:
            linear.add(hits[0])
        else:
            for f in hits:
                nonlinear |= f.free_symbols & unknown_set
    return linear - nonlinear


def _match(adj: list, order: list):
    """Maximum matching equation -> unknown, greedy in preference order, then augmented (BFS)."""
    m_eq: dict = {}
    m_var: dict = {}
    for i in order:
        for v in adj[i]:
            if v not in m_var:
                m_eq[i], m_var[v] = v, i
                break
    for i in order:
        if i in m_eq:
            continue
        parent = {i: None}
        queue = deque([i])
        found = None
        while queue and found is None:
            j = queue.popleft()
            for v in adj[j]:
                k = m_var.get(v)
                if k is None:
                    found = (j, v)
                    break
                if k not in parent:
                    parent[k] = (j, v)
                    queue.append(k)
        if found is None:
            continue
        j, v = found
        while True:                     # flip the augmenting path back to the root
            m_eq[j], m_var[v] = v, j
            if parent[j] is None:
                break
            j, v = parent[j]
    return m_eq, m_var


# ---------------------------------------------------------------------------------------------

class _Analyser:
    def __init__(self, flat: FlatNetwork, samples: int = 12, seed: int = 1):
        self.flat = flat
        self.findings: list[Finding] = []
        self.values = flat.param_values()
        self.rng = np.random.default_rng(seed)
        self.n_samples = samples

    # -- set-up ----------------------------------------------------------------------------------
    def build(self):
        flat = self.flat
        port_vars = set(flat.variables())
        uf = _UnionFind(_port_rank(flat))
        eqs: list[Equation] = []
        for eq in flat.equations:
            pair = _alias_pair(eq.expr, port_vars) if eq.role in ("node", "constraint") else None
            if pair is None:
                eqs.append(eq)
                continue
            residual = uf.union(*pair)
            if residual:                # x = -x: the variable is forced to zero
                eqs.append(Equation(pair[0], eq.owner, eq.role, None, eq.note + " (closes a loop)"))
        self.aliases = {v: uf.find(v) for v in port_vars}
        subs = _alias_substitution(self.aliases)
        self.equations = []
        for eq in eqs:
            e = eq.expr.xreplace(subs)
            if e == 0:
                continue
            nat = self.aliases.get(eq.natural, (eq.natural, 1))[0] if eq.natural is not None else None
            self.equations.append(Equation(e, eq.owner, eq.role, nat, eq.note))
        self.states = [State(s.symbol, s.rhs.xreplace(subs), s.initial, s.storage, s.owner, s.unit, s.given)
                       for s in flat.states]
        for st in self.states:
            self.equations.append(Equation(der(st.symbol) - st.rhs, st.owner, "state", der(st.symbol),
                                           f"d/dt {st.name}"))
        self.unknowns = list(dict.fromkeys(r for r, _ in self.aliases.values()))
        self.unknowns += [der(s.symbol) for s in self.states]
        self.demoted: list[State] = []
        self.resolved: list = []        # (equations, algebraic unknowns, demoted states) per group
        self.rates = None

    # -- matching ----------------------------------------------------------------------------------
    def match(self):
        unknown_set = set(self.unknowns)
        adj, order_key = [], []
        for i, eq in enumerate(self.equations):
            vs = [v for v in eq.expr.free_symbols if v in unknown_set]
            lin = _linear_vars(eq.expr, unknown_set) if len(vs) > 1 else set(vs)
            vs.sort(key=lambda v: (v != eq.natural, v not in lin, v.name))
            adj.append(vs)
            order_key.append((0 if eq.role == "state" else 1 if eq.natural is not None else 2, i))
        order = [i for _, i in sorted(order_key)]
        self.adj = adj
        self.m_eq, self.m_var = _match(adj, order)

    def over_groups(self):
        """Connected groups of the over-determined part (Dulmage–Mendelsohn)."""
        unmatched = [i for i in range(len(self.equations)) if i not in self.m_eq]
        seen_eq, seen_var = set(), set()
        queue = deque(unmatched)
        seen_eq.update(unmatched)
        while queue:
            i = queue.popleft()
            for v in self.adj[i]:
                if v in seen_var:
                    continue
                seen_var.add(v)
                k = self.m_var.get(v)
                if k is not None and k not in seen_eq:
                    seen_eq.add(k)
                    queue.append(k)
        g = nx.Graph()
        for i in seen_eq:
            g.add_node(("e", i))
            for v in self.adj[i]:
                g.add_edge(("e", i), ("v", v))
        groups = []
        for comp in nx.connected_components(g):
            eqs = sorted(i for k, i in comp if k == "e")
            vs = sorted((v for k, v in comp if k == "v"), key=lambda s: s.name)
            groups.append((eqs, vs))
        return groups

    def equations_of(self) -> dict:
        """Unknown -> indices of the equations it appears in (after the last matching)."""
        rev: dict = {}
        for i, vs in enumerate(self.adj):
            for v in vs:
                rev.setdefault(v, []).append(i)
        return rev

    def under_vars(self):
        """Unknowns left unmatched, and all unknowns they leave undetermined with them."""
        start = [v for v in self.unknowns if v not in self.m_var]
        return start, self.reach_of(start)

    def reach_of(self, start) -> set:
        """Unknowns left undetermined together with the unmatched unknowns ``start`` (alternating
        paths: an equation using one of them cannot determine the unknown matched to it)."""
        rev = self.equations_of()
        seen = set(start)
        queue = deque(start)
        while queue:
            v = queue.popleft()
            for i in rev.get(v, []):
                w = self.m_eq.get(i)
                if w is not None and w not in seen:
                    seen.add(w)
                    queue.append(w)
        return seen

    # -- numerics on a group ---------------------------------------------------------------------
    def sample_points(self, symbols):
        """``n_samples`` points ``{symbol: float}`` (Python floats: a sympy Float per symbol and point
        was a tenth of a mechanism's analysis; :meth:`sample_values` makes them only to evaluate an
        entry numpy cannot)."""
        pts = []
        states = {s.symbol: s for s in self.flat.states}
        starts: dict = {}           # initial values of displacement states, worked out once per group
        for k in range(self.n_samples):
            pt = {T: 0.1 * k}
            for s in symbols:
                if s in self.values:
                    pt[s] = self.values[s]
                elif s in states and not states[s].storage:
                    if s not in starts:
                        start = sp.sympify(sp.sympify(states[s].initial).xreplace({p: self.values[p] for p in self.values}))
                        starts[s] = complex(start) if start.is_number else 0j
                    q0 = starts[s]
                    # a start value that is not real (a closure that cannot be assembled: the check
                    # reports it as cannot_assemble) is sampled from its real part; one that reads
                    # itself around a position loop (reported as position_loop) from 0
                    pt[s] = q0.real + 2 * np.pi * k / self.n_samples + 0.1
                else:
                    pt[s] = float(self.rng.normal())
            pts.append({k: float(v) for k, v in pt.items()})
        return pts

    def jacobians(self, eq_ids, alg, stvars):
        exprs = [self.equations[i].expr for i in eq_ids]
        syms = set().union(*(e.free_symbols for e in exprs)) | set(alg) | set(stvars)
        wrt = list(alg) + list(stvars)
        present = [e.free_symbols for e in exprs]
        entries = [sp.sympify(derivative(e, v)) if v in fs else sp.Integer(0) for e, fs in zip(exprs, present) for v in wrt]
        pts = self.sample_points(syms)
        values = self.sample_values(entries, pts).reshape(len(pts), len(exprs), len(wrt))
        bad = ~np.isfinite(values)
        if bad.any():          # an entry that is not identically zero but overflows or is undefined at a
            values[bad] = self.rng.uniform(0.5, 1.5, size=int(bad.sum()))   # sample: generic nonzero
        return [(M[:, :len(alg)], M[:, len(alg):]) for M in values]

    @staticmethod
    def sample_values(entries, pts) -> np.ndarray:
        """``entries`` (sympy expressions) at every sample point, shape ``(len(pts), len(entries))``:
        numbers directly, the others through one generated function per call (sympy's evaluation of
        each entry at each point is what made the check of large stacks slow); an entry that cannot
        be evaluated so is evaluated by sympy, and one that sympy cannot evaluate either is NaN."""
        out = np.full((len(pts), len(entries)), np.nan)
        symbolic = []
        for k, x in enumerate(entries):
            if x.is_number:
                try:
                    out[:, k] = complex(x).real
                except (TypeError, ValueError):
                    pass
            else:
                symbolic.append(k)
        if not symbolic:
            return out
        free = sorted(set().union(*(entries[k].free_symbols for k in symbolic)), key=lambda v: v.name)
        try:
            fn = numeric_function(free, [entries[k] for k in symbolic])
        except Exception:          # noqa: BLE001 -- a function numpy does not know: sympy below
            fn = None
        for row, pt in zip(out, pts):
            try:
                if fn is None:
                    raise TypeError
                with np.errstate(all="ignore"):
                    vals = np.array([complex(v).real for v in fn(*[pt[v] for v in free])], dtype=float)
                if not np.all(np.isfinite(vals)):
                    raise ValueError
                row[symbolic] = vals
            except (TypeError, ValueError, ArithmeticError, KeyError, NameError):
                exact = {s: sp.Float(v) for s, v in pt.items()}
                for k in symbolic:
                    try:
                        row[k] = complex(entries[k].xreplace(exact).evalf()).real
                    except (TypeError, ValueError):
                        pass
        return out

    @staticmethod
    def left_null(J, tol=1e-9):
        """Orthonormal basis of ``{y: yᵀ·J = 0}``.  Columns are scaled to unit norm first (the left
        null space does not change), so unknowns of different units (a charge and a force) do not
        hide each other below the rank tolerance."""
        m, n = J.shape
        if n == 0:
            return np.eye(m)
        norms = np.linalg.norm(J, axis=0)
        J = J / np.where(norms > 0, norms, 1.0)
        U, s, _ = np.linalg.svd(J)
        r = int(np.sum(s > tol * max(s.max(initial=0.0), 1e-300)))
        return U[:, r:]

    # -- main ------------------------------------------------------------------------------------
    def run(self):
        self.build()
        for _round in range(4):
            self.match()
            groups = self.over_groups()
            if not groups:
                break
            self.rates = _Rates(self)
            progressed = False
            for eq_ids, alg in groups:
                if self.resolve_group(eq_ids, alg):
                    progressed = True
            if not progressed:
                break
        else:
            self.match()
        leftover = self.over_groups()
        if leftover and not self.errors():
            self.findings.append(Finding("overdetermined", sorted({i for eqs, _ in leftover for i in eqs})))
        if not self.errors():
            missing, reach = self.under_vars()
            if missing:
                missing = self.find_placeholders(missing, reach)
            if missing:
                self.findings.append(Finding("undetermined", variables=sorted(missing, key=lambda v: v.name),
                                             related=sorted(reach, key=lambda v: v.name)))
        integrated = [s for s in self.states if s not in self.demoted]
        return Analysis(self.flat, self.equations, dict(self.m_eq), self.unknowns, integrated,
                        self.demoted, self.aliases, findings=self.findings)

    def errors(self):
        return [f for f in self.findings if f.kind in ERROR_FINDINGS]

    def resolve_group(self, eq_ids, alg) -> bool:
        """Resolve one over-determined group; True if the system changed (states demoted)."""
        state_syms = [s.symbol for s in self.states if s not in self.demoted]
        present = set().union(*(self.equations[i].expr.free_symbols for i in eq_ids))
        stvars = [s for s in state_syms if s in present]
        samples = self.jacobians(eq_ids, alg, stvars)
        Ja, Js = samples[0]
        N = self.left_null(Ja)
        if N.shape[1] == 0:
            return False
        C = N.T @ Js
        redundant = self.left_null(C)
        W = N @ redundant                    # combinations free of unknowns and states
        rank_c = N.shape[1] - W.shape[1]
        for col in W.T:
            support = [eq_ids[k] for k in np.nonzero(np.abs(col) > 1e-8 * np.abs(col).max())[0]]
            self.findings.append(Finding("redundant", support))
        if rank_c == 0:
            return False
        if W.shape[1] == 0 and self.locked(eq_ids, alg):
            return False
        ext_ids, ext_alg = self.with_earlier_groups(eq_ids, alg)
        if len(ext_ids) > len(eq_ids):
            present = set().union(*(self.equations[i].expr.free_symbols for i in ext_ids))
            stvars = [s for s in state_syms if s in present]
            samples = self.jacobians(ext_ids, ext_alg, stvars)
        chosen = self.choose_demotions(ext_ids, ext_alg, stvars, samples, rank_c, self.rates)
        if self.errors():
            return False
        self.demote(eq_ids, chosen)
        self.resolved.append((list(eq_ids), list(alg), list(chosen)))
        return True

    def with_earlier_groups(self, eq_ids, alg):
        """The group's equations and algebraic unknowns together with those of the groups resolved
        before that share unknowns with it (transitively), whose demoted states are unknowns now.

        A state demoted earlier is computed from that group's constraint, so the constraint this
        group imposes on the remaining states is the one left after eliminating it: without this,
        demoting the charges of an open piezo stack one group at a time leaves their sum (which
        only the open terminal's zero current fixes) to no equation, a singular loop.
        """
        ids, unknowns = list(eq_ids), list(alg)
        symbols = set().union(*(self.equations[i].expr.free_symbols for i in ids))
        pending = list(self.resolved)
        grown = True
        while grown:
            grown = False
            for group in list(pending):
                g_ids, g_alg, g_chosen = group
                if symbols & (set(g_alg) | set(g_chosen)):
                    pending.remove(group)
                    ids += [i for i in g_ids if i not in ids]
                    unknowns += [v for v in list(g_alg) + list(g_chosen) if v not in unknowns]
                    symbols |= set().union(*(self.equations[i].expr.free_symbols for i in g_ids))
                    grown = True
        return ids, unknowns

    def locked(self, eq_ids, alg) -> bool:
        kin = [i for i in eq_ids if self.equations[i].role in ("constraint", "node")
               and not self.equations[i].expr.has(T)]
        if len(kin) < 2:
            return False
        vs = sorted(set().union(*(self.equations[i].expr.free_symbols for i in kin)) & set(alg),
                    key=lambda s: s.name)
        Jk = self.jacobians(kin, vs, [])[0][0]
        if np.linalg.matrix_rank(Jk, tol=1e-9 * max(np.abs(Jk).max(), 1e-300)) < len(vs):
            return False
        self.findings.append(Finding("locked", kin))
        return True

    def choose_demotions(self, eq_ids, alg, stvars, samples, count, rates=None):
        """Pick ``count`` states to demote, best conditioned along the expected motion first.

        At each sample point the constraint gradients ``C = Nᵀ·∂F/∂x`` are scaled consistently
        (the left null basis ``N`` is normalised on fixed reference equations), so a state whose
        coefficient vanishes somewhere along the motion (a crank at its dead centre) scores low;
        a state with no coefficient at all (the constraint does not determine it) is never chosen.
        States whose rate is fixed by the rest of the network (see :class:`_Rates`) rank after all
        others, then the ``prefer_state`` hint, then the score.
        """
        prefer = set(self.flat.prefer_state)
        nulls = [self.left_null(Ja) for Ja, _ in samples]
        d = min(N.shape[1] for N in nulls)
        ref = self.reference_rows(nulls, d)
        mats, floors = [], []
        for N, (_Ja, Js) in zip(nulls, samples):
            N = N[:, :d]
            try:
                N = N @ np.linalg.inv(N[ref, :])
            except np.linalg.LinAlgError:
                pass
            mats.append(N.T @ Js)
            # a coefficient below rounding of the terms it combines is zero
            floors.append(1e-9 * np.linalg.norm(N) * np.linalg.norm(Js, axis=0))
        chosen = []
        available = list(range(len(stvars)))
        for _ in range(count):
            best, best_score = None, -np.inf
            free = rates.free() if rates is not None else None
            # the norm of every state's column at every sample, at once (one norm call per column
            # and sample was most of this function's time: 10,000 calls for 100 dependent inertias)
            norms = np.array([np.linalg.norm(M, axis=0) if M.size else np.zeros(len(stvars)) for M in mats])
            for j in reversed(available):     # ties: keep the earlier state, demote the later one
                col = norms[:, j]
                if not any(c > floor[j] for c, floor in zip(col, floors)):
                    continue                  # the constraint does not determine this state
                score = col.min() / col.max()
                if stvars[j].name in prefer:
                    score -= 2.0
                if free is not None and der(stvars[j]) not in free:
                    score -= 4.0
                if score > best_score + 1e-9:
                    best, best_score = j, score
            if best is None:
                break
            chosen.append(stvars[best])
            available.remove(best)
            if rates is not None:
                rates.take(der(stvars[best]))
            new = []
            for M in mats:                  # eliminate the chosen state from the remaining constraints
                if M.shape[0] == 0:
                    new.append(M)
                    continue
                k = int(np.argmax(np.abs(M[:, best])))
                piv = M[k] / M[k, best] if M[k, best] != 0 else M[k]
                rest = np.delete(M - np.outer(M[:, best], piv), k, axis=0)
                new.append(rest)
            mats = new
        return chosen

    @staticmethod
    def reference_rows(nulls, d):
        """``d`` equations whose weights in the null combinations never vanish over the samples."""
        weight = np.min([np.abs(N[:, :d]).max(axis=1) / max(np.abs(N).max(), 1e-300) for N in nulls], axis=0)
        A = nulls[0][:, :d]
        rows: list = []
        basis = np.zeros((0, d))       # orthonormal basis of the rows taken so far
        largest = 0.0
        for i in np.argsort(-weight):  # one pass: a row dependent on the taken ones stays dependent
            if len(rows) == d:
                break
            r = A[i] - basis.T @ (basis @ A[i])
            size = np.linalg.norm(r)
            # independent beyond rounding: a residual at eps level (a row dependent on the taken ones up
            # to rounding) would make N[ref] singular (a locked inertia beside its held node did)
            if size > 1e-9 * max(largest, np.linalg.norm(A[i])):
                rows.append(int(i))
                basis = np.vstack([basis, r / size])
                largest = max(largest, np.linalg.norm(A[i]))
        return rows

    def demote(self, eq_ids, chosen):
        unknown_set = set(self.unknowns)
        states = {s.symbol: s for s in self.states}
        new_unknowns = []
        for sym in chosen:
            self.demoted.append(states[sym])
            new_unknowns.append(sym)
        all_states = {s.symbol for s in self.states}
        owners = []
        for i in eq_ids:
            eq = self.equations[i]
            e = eq.expr
            total = derivative(e, T)
            for v in e.free_symbols:
                if v in unknown_set:
                    dv = der(v)
                    if dv not in unknown_set:
                        unknown_set.add(dv)
                        new_unknowns.append(dv)
                    total += derivative(e, v) * dv
                elif v in all_states:
                    total += derivative(e, v) * der(v)
                elif v in self.flat.inputs:
                    total += derivative(e, v) * derivative(sp.sympify(self.flat.inputs[v]), T)
            if total.has(sp.DiracDelta):
                self.findings.append(Finding("impulse", [i]))
            self.equations.append(Equation(sp.expand(total), eq.owner, "differentiated", None, "d/dt " + eq.note))
            owners.append(eq.owner)
        self.unknowns += new_unknowns
        self.findings.append(Finding("demoted", list(eq_ids), states=list(chosen)))

    # -- findings for the checks ---------------------------------------------------------------------
    def nearest_sums(self, start, reach) -> list:
        """The junctions (and nodes) nearest to the variables ``start`` whose sums use them, found by
        walking through the equations of the under-determined part ``reach`` (transformers are
        passed through, a junction or node ends the walk)."""
        rev = self.equations_of()
        seen_v, seen_e, found = set(start), set(), []
        queue = deque(start)
        while queue:
            v = queue.popleft()
            for i in rev.get(v, []):
                if i in seen_e:
                    continue
                seen_e.add(i)
                owner = self.equations[i].owner
                prim = self.flat.primitives.get(owner)
                if (prim is None and owner.startswith("node(")) or \
                        (prim is not None and prim.kind.startswith("junction")):
                    if owner not in found:
                        found.append(owner)
                    continue
                for w in self.adj[i]:
                    if w in reach and w not in seen_v:
                        seen_v.add(w)
                        queue.append(w)
        return found

    def find_placeholders(self, missing, reach) -> list:
        """Record the placeholders the under-determined part reaches (see :func:`placeholder_needs`);
        return the under-determined variables none of them explains."""
        found = []
        for path, prim in self.flat.primitives.items():
            words = placeholder_needs(prim)
            if words is None:
                continue
            port_vars = {}
            for port in prim.ports:
                for kind in ("e", "f"):
                    sym = var(f"{path}.{port}.{kind}")
                    port_vars[self.aliases.get(sym, (sym, 1))[0]] = sym
            hit = [port_vars[v] for v in port_vars if v in reach]
            if hit:
                found.append((path, words, hit, set(port_vars)))
        if not found:
            return missing
        explained = set()
        for path, words, hit, reps in found:
            sums = self.nearest_sums([self.aliases.get(sym, (sym, 1))[0] for sym in hit], reach)
            self.findings.append(Finding("placeholder", variables=hit, path=path, words=words, sums=sums))
            for v in missing:
                if self.reach_of([v]) & reps:
                    explained.add(v)
        return [v for v in missing if v not in explained]


class _Rates:
    """Which storage rates can still follow a constraint (Pantelides' criterion), for one round.

    A demoted state's rate ``der(x)`` is computed from the differentiated constraint, so its state
    equation must compute the storage's flow instead; that takes an alternating path of the
    matching from an unknown no equation determines to ``der(x)``.  A rate that a source or an open
    port fixes (the charge behind open electrodes) has no such path: demoting that state would let
    it jump at t = 0 through a terminal that carries no current.  Demotions share the paths, so each
    one taken (:meth:`take`) is flipped into a private copy of the matching: the charges of an open
    stack can follow their voltage constraint only as long as some other charge absorbs the sum.
    """

    def __init__(self, analyser: "_Analyser"):
        self.an = analyser
        self.m_eq = dict(analyser.m_eq)
        self.m_var = dict(analyser.m_var)
        self.taken: set = set()
        self._free = None

    def _search(self):
        """Breadth-first alternating search from the unknowns no equation determines (those taken
        are spoken for); returns ``{unknown: (previous unknown, equation) or None}``."""
        rev = self.an.equations_of()
        start = [v for v in self.an.unknowns if v not in self.m_var and v not in self.taken]
        parent = {v: None for v in start}
        queue = deque(start)
        while queue:
            v = queue.popleft()
            for i in rev.get(v, []):
                w = self.m_eq.get(i)
                if w is not None and w not in parent and w not in self.taken:
                    parent[w] = (v, i)
                    queue.append(w)
        return parent

    def free(self) -> set:
        """Unknowns an alternating path can free, in the current private matching."""
        if self._free is None:
            self._free = self._search()
        return set(self._free)

    def take(self, rate) -> None:
        """Reserve ``rate`` for a differentiated constraint: flip the path that frees it."""
        parent = self._free if self._free is not None else self._search()
        self._free = None
        self.taken.add(rate)
        if rate not in parent:
            return
        w = rate
        del self.m_var[w]
        while parent[w] is not None:        # equation i takes v; v's old equation is passed on
            v, i = parent[w]
            self.m_eq[i] = v
            self.m_var[v] = i
            w = v


@bulk
def analyse(flat: FlatNetwork, diagnose: bool = True) -> Analysis:
    """Run the causality analysis on a flat network.

    With ``diagnose`` the structural checks of :mod:`multipole.checks` word the findings into
    ``analysis.diagnostics``; :func:`multipole.pipeline.check` passes False and runs every check
    itself (those that need the assembled equations too)."""
    from .checks import Context
    analysis = _Analyser(flat).run()
    if diagnose:
        analysis.diagnostics = run_checks(Context(analysis), stages=("structure",))
    return analysis
