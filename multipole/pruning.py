"""Exact pruning: keep only what the requested outputs need.

:func:`prune` takes the assembled :class:`~multipole.equations.Equations` and the names of the
requested outputs and returns the equations restricted to the backward closure of those outputs
over the dependency graph, with a :class:`Pruning` record of what was dropped and why.  Nothing is
approximated: every kept variable is computed by exactly the same expressions as before.

The closure starts from the symbols the outputs and the elements' run-time monitors read and from
the *protected set*: the switching functions that depend on time alone (steps and tables of the
sources), so that the run's restarts at known times are the same with and without pruning. It then
follows

* a variable computed by a block (explicit, linear loop, Newton loop) to everything the block
  reads: a loop is kept whole, with its start values;
* a state to the expression of its derivative (a state is needed as soon as a needed expression
  reads it, and then everything its derivative reads is needed);
* an input to its expression of time.

What is left out (an independent subsystem that no output observes: a second load nobody plots, a
sensor branch) is dropped before code generation, together with its state-dependent switching
functions.  When nothing can be dropped the equations are returned unchanged (the same object).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import sympy as sp

from .equations import Equations, switching_functions


@dataclass
class Pruning:
    """What :func:`prune` dropped for ``outputs``, and why.

    ``dropped_states``: ``[(state name, element, reason)]``; ``dropped_variables``: the number of
    algebraic variables (block unknowns) left out; ``dropped_switches``: the switching functions
    (as text) that only the dropped part had; ``ops_before``/``ops_after``: sympy's operation count
    of the right-hand side's evaluation order (blocks and derivatives) with and without pruning.
    """

    outputs: list
    states_before: int
    dropped_states: list = field(default_factory=list)
    dropped_variables: int = 0
    dropped_switches: list = field(default_factory=list)
    ops_before: int = 0
    ops_after: int = 0

    @property
    def states_pruned(self) -> int:
        return len(self.dropped_states)

    def lines(self) -> list:
        """The record as text lines (``multipole check --explain``)."""
        outs = ", ".join(self.outputs) if self.outputs else "(the states)"
        if not self.dropped_states and not self.dropped_variables:
            return [f"pruning for outputs {outs}: nothing dropped (every state and variable is needed)"]
        out = [f"pruning for outputs {outs}: {self.states_pruned} of {self.states_before} state(s) and "
               f"{self.dropped_variables} algebraic variable(s) dropped; right-hand side {self.ops_before} -> "
               f"{self.ops_after} operations"]
        for name, element, reason in self.dropped_states:
            out.append(f"  dropped state {name} (element {element}): {reason}")
        for text in self.dropped_switches:
            out.append(f"  dropped switching function {text}: it reads only dropped variables")
        return out

    def to_dict(self) -> dict:
        return {"outputs": list(self.outputs), "states_before": self.states_before,
                "states_pruned": self.states_pruned,
                "dropped_states": [{"state": n, "element": e, "reason": r} for n, e, r in self.dropped_states],
                "dropped_variables": self.dropped_variables, "dropped_switches": list(self.dropped_switches),
                "ops_before": self.ops_before, "ops_after": self.ops_after}


def _block_reads(b) -> set:
    """Every symbol block ``b`` reads (:meth:`multipole.equations.Block.reads`)."""
    exprs = b.reads()
    return set().union(*(sp.sympify(e).free_symbols for e in exprs)) if exprs else set()


class _Graph:
    """The dependency graph of ``eq``: who computes a symbol, and what that reads."""

    def __init__(self, eq: Equations):
        self.eq = eq
        self.block_of = {v: k for k, b in enumerate(eq.blocks) for v in b.variables}
        self.state_of = {s.symbol: i for i, s in enumerate(eq.states)}
        self.reads = [_block_reads(b) for b in eq.blocks]
        self.der_reads = [sp.sympify(d).free_symbols for d in eq.derivatives]
        self.input_reads = {u: sp.sympify(e).free_symbols for u, e in eq.inputs.items()}

    def state_dependent(self) -> set:
        """The states and every variable computed from a state (one pass in evaluation order)."""
        out = set(self.state_of)
        for k, b in enumerate(self.eq.blocks):
            if self.reads[k] & out:
                out |= set(b.variables)
        return out

    def closure(self, seeds):
        """``(symbols, blocks, states)`` reached backwards from ``seeds``."""
        seen, blocks, states = set(), set(), set()
        todo = list(seeds)
        while todo:
            s = todo.pop()
            if s in seen:
                continue
            seen.add(s)
            if s in self.block_of:
                k = self.block_of[s]
                if k not in blocks:
                    blocks.add(k)
                    todo += self.reads[k] | set(self.eq.blocks[k].variables)
            if s in self.state_of:
                i = self.state_of[s]
                if i not in states:
                    states.add(i)
                    todo += self.der_reads[i]
            if s in self.input_reads:
                todo += self.input_reads[s]
        return seen, blocks, states


def _switches(eq: Equations, blocks, inputs) -> list:
    """The switching functions of the blocks ``blocks`` and of the inputs ``inputs`` (see
    :func:`multipole.equations.switching_functions`), without repeats."""
    exprs = [e for k in sorted(blocks) for e in (eq.blocks[k].solution or eq.blocks[k].residuals)]
    exprs += [sp.sympify(eq.inputs[u]) for u in inputs]
    out: dict = {}
    for g in (g for e in exprs for g in switching_functions(sp.sympify(e)) if g.free_symbols):
        if g not in out and -g not in out:
            out[g] = None
    return list(out)


def _ops(eq: Equations, blocks, states, counts: dict) -> int:
    """sympy's operation count of the blocks ``blocks`` and the derivatives of ``states``; each
    block's count is kept in ``counts`` (the kept blocks are counted before and after pruning:
    ``count_ops`` of a mechanism's loop solutions was a sixth of its model build)."""
    total = 0
    for k in blocks:
        if k not in counts:
            b = eq.blocks[k]
            counts[k] = sum(sp.count_ops(e) for e in list(b.solution if b.solution is not None else b.residuals))
            if b.matrix is not None:
                counts[k] += sum(sp.count_ops(e) for e in list(b.matrix) + list(b.rhs))
        total += counts[k]
    return total + sum(sp.count_ops(eq.derivatives[i]) for i in states)


def prune(eq: Equations, outputs) -> tuple[Equations, Pruning]:
    """``(pruned equations, record)`` for the output names ``outputs`` (see the module's doc).

    The pruned equations keep the order of the states and blocks; when nothing is dropped they are
    ``eq`` itself.  Raises what :meth:`Equations.output` raises for an unknown output name.
    """
    outputs = list(outputs)
    graph = _Graph(eq)
    seeds = set().union(*(sp.sympify(eq.output(o)).free_symbols for o in outputs)) if outputs else set()
    # the run-time monitors watch the physics whether or not anyone plots it (a drum paying out, a
    # dead centre): what they read is kept like an output
    seeds |= set().union(*(sp.sympify(e).free_symbols for e, _m, _o in getattr(eq, "monitors", [])))
    _seen, blocks, states = graph.closure(seeds)
    record = Pruning(outputs, len(eq.states))
    if len(blocks) == len(eq.blocks) and len(states) == len(eq.states):
        return eq, record
    # protected: switching functions of time alone (a step in a source), so the run restarts at
    # the same instants: the input or block that holds one is kept
    moving = graph.state_dependent()
    carriers = [([u], [e]) for u, e in eq.inputs.items()] + \
        [(b.variables, b.solution or b.residuals) for b in eq.blocks]
    for variables, exprs in carriers:
        for g in (g for e in exprs for g in switching_functions(sp.sympify(e)) if g.free_symbols):
            if not g.free_symbols & moving:
                seeds |= set(variables)
                break
    all_switches = _switches(eq, range(len(eq.blocks)), eq.inputs)
    seen, blocks, states = graph.closure(seeds)
    if len(blocks) == len(eq.blocks) and len(states) == len(eq.states):
        return eq, record
    kept = _switches(eq, blocks, [u for u in eq.inputs if u in seen])
    record.dropped_switches = [str(g) for g in all_switches if g not in kept and -g not in kept]
    flat = eq.analysis.flat if eq.analysis is not None else None
    reason = ("no requested output reads it, directly or through the variables and states it feeds"
              if outputs else "nothing is requested")
    for i, s in enumerate(eq.states):
        if i not in states:
            element = flat.element_of(s.owner) if flat is not None else s.name.split(".")[0]
            record.dropped_states.append((s.name, element, reason))
    record.dropped_variables = sum(len(b.variables) for k, b in enumerate(eq.blocks) if k not in blocks)
    every_state = range(len(eq.states))
    counts: dict = {}
    record.ops_before = _ops(eq, range(len(eq.blocks)), every_state, counts)
    record.ops_after = _ops(eq, blocks, states, counts)
    order = sorted(states)
    pruned = dataclasses.replace(
        eq, states=[eq.states[i] for i in order], derivatives=[eq.derivatives[i] for i in order],
        blocks=[b for k, b in enumerate(eq.blocks) if k in blocks],
        inputs={u: e for u, e in eq.inputs.items() if u in seen})
    return pruned, record


__all__ = ["Pruning", "prune"]
