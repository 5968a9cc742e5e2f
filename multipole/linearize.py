"""Linearisation (DESIGN §3: ``Equations ──linearize──▶ python-control StateSpace``).

The explicit ODE is linearised about the initial state and the inputs at ``t = 0`` by implicit
differentiation of the evaluation order at that point (:func:`numeric_jacobians`), so every
well-posed scene linearises, with or without closed-form loops (``method="symbolic"``
differentiates the substituted ODE instead where every loop has a closed form):
``A = ∂f/∂x``, ``B = ∂f/∂u``, ``C = ∂y/∂x``, ``D = ∂y/∂u`` with the scene's sources as inputs ``u``
and its outputs as ``y``.  The result is a :class:`control.StateSpace` with named signals, plus the
eigenvalues with their natural frequencies [Hz] and damping ratios.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from .equations import Equations, block_values
from .errors import IllPosedError, MultipoleError, RunError
from .primitives import T


@dataclass
class Linearization:
    """Matrices, names and modal data of a linearised scene."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: list
    inputs: list
    outputs: list
    units: dict = field(default_factory=dict)     # input, output or state name -> SI unit
    name: str = ""                                # the scene's
    point: str = "at t = 0 about the initial state"

    def statespace(self):
        """A :class:`control.StateSpace` named after the scene, with the scene's state names and
        its input and output names written by :func:`control_name` (python-control reserves the dot
        for ``system.signal`` in :func:`control.interconnect`)."""
        import control
        return control.ss(self.A, self.B, self.C, self.D, states=list(self.states),
                          inputs=[control_name(n) for n in self.inputs],
                          outputs=[control_name(n) for n in self.outputs],
                          name=control_name(self.name).replace(":", "_") or None)

    def modes(self) -> list[tuple[complex, float, float]]:
        """(eigenvalue [1/s], natural frequency [Hz], damping ratio) sorted by frequency.

        Parts below rounding of the largest eigenvalue (1e-12 of it) are set to zero, so a
        rigid-body mode reads 0 (not 1e-51 Hz) and an undamped one has zeta = 0."""
        out = []
        lams = np.linalg.eigvals(self.A) if self.A.size else np.zeros(0)
        tiny = 1e-12 * (np.abs(lams).max() if lams.size else 0.0)
        for lam in lams:
            lam = complex(lam.real if abs(lam.real) > tiny else 0.0, lam.imag if abs(lam.imag) > tiny else 0.0)
            wn = abs(lam)
            zeta = (-lam.real / wn if wn > 0 else 1.0) + 0.0     # + 0.0: no "-0"
            out.append((complex(lam), wn / (2 * np.pi), zeta))
        return sorted(out, key=lambda m: (m[1], m[0].imag))

    def to_text(self) -> str:
        def mat(name, M, rows, cols):
            lines = [f"{name} ({len(rows)}x{len(cols)}), rows {', '.join(rows) or '-'}; columns {', '.join(cols) or '-'}"]
            lines += ["  [" + ", ".join(f"{v: .6g}" for v in row) + "]" for row in M]
            return lines
        lines = mat("A", self.A, self.states, self.states) + mat("B", self.B, self.states, self.inputs)
        lines += mat("C", self.C, self.outputs, self.states) + mat("D", self.D, self.outputs, self.inputs)
        lines.append("Modes (eigenvalue, natural frequency, damping ratio):")
        for lam, f, z in self.modes():
            lines.append(f"  {lam.real: .6g}{lam.imag:+.6g}j 1/s   f_n = {f:.6g} Hz   zeta = {z:.4g}")
        return "\n".join(lines)


def linearize(eq: Equations, outputs, method: str = "numeric") -> Linearization:
    """Linearise ``eq`` about its initial state and the inputs at t = 0.

    ``method``: ``numeric`` (default) differentiates the evaluation order at the operating point
    (see :func:`numeric_jacobians`): exact up to rounding and valid for every well-posed scene,
    with or without closed-form loops; ``symbolic`` differentiates the ODE with every loop
    substituted, which needs every algebraic loop in closed form (slower; the two agree to
    rounding, which the tests check).
    """
    if method not in ("symbolic", "numeric"):
        raise ValueError(f"method must be numeric or symbolic, not {method!r}")
    if method == "symbolic" and any(b.solution is None for b in eq.blocks):
        raise IllPosedError("not_symbolic", "symbolic linearisation needs every algebraic loop solved symbolically",
                            "use method='numeric' (the default)")
    if method == "numeric":
        return Linearization(*numeric_jacobians(eq, outputs), [s.name for s in eq.states],
                             [u.name for u in eq.inputs], list(outputs))
    xs = [s.symbol for s in eq.states]
    us = list(eq.inputs)
    f = sp.Matrix([eq.substituted(d, max_ops=10**9) for d in eq.derivatives])
    y = sp.Matrix([eq.substituted(eq.output(o), max_ops=10**9) for o in outputs])
    point = {p: sp.Float(v) for p, v in eq.params.items()}
    point.update({x: sp.Float(v) for x, v in zip(xs, eq.initial_values())})
    point.update({u: sp.sympify(e).xreplace({T: sp.Integer(0)}).xreplace(point) for u, e in eq.inputs.items()})
    point[T] = sp.Float(0)

    def num(M, wrt, rows):
        if not wrt or not rows:
            return np.zeros((rows, len(wrt)))
        return np.array(M.jacobian(wrt).xreplace(point).evalf(), dtype=float).reshape(rows, len(wrt))

    return Linearization(num(f, xs, len(xs)), num(f, us, len(xs)), num(y, xs, len(outputs)), num(y, us, len(outputs)),
                         [s.name for s in eq.states], [u.name for u in us], list(outputs))


def numeric_jacobians(eq: Equations, outputs, t: float = 0.0, x=None):
    """``(A, B, C, D)`` at time ``t`` and state ``x`` (default: the initial state) by implicit
    differentiation of the evaluation order, exact up to rounding.

    Every block computes its variables ``z`` from earlier ones ``w`` through residuals ``r(z, w) = 0``
    (an explicit assignment, a linear loop or a nonlinear loop alike), so at the operating point
    ``dz = −(∂r/∂z)⁻¹·(∂r/∂w)·dw``.  Carried through the blocks in order, starting from the states
    and the inputs, this gives the derivatives of every ``d/dt x`` and every output with respect to
    them — the Jacobian of the compiled model, for loops with and without closed form.  Input
    derivatives that the resolution of derivative causality introduced are functions of time, not
    inputs, as in the symbolic path.
    """
    xs = [s.symbol for s in eq.states]
    us = list(eq.inputs)
    n, m = len(xs), len(us)
    x = eq.initial_values() if x is None else list(x)
    values = {k: sp.Float(v) for k, v in block_values(eq, t, x)[0].items()}
    grad = {sym: row for sym, row in zip(xs + us, np.eye(n + m))}

    def d(expr, sym):
        value = complex(sp.sympify(sp.diff(expr, sym).xreplace(values)).evalf())
        if value.imag != 0 or not np.isfinite(value.real):
            raise ArithmeticError(f"d({expr})/d({sym}) is not finite at the operating point")
        return value.real

    for b in eq.blocks:
        index = {z: k for k, z in enumerate(b.variables)}
        Jz = np.zeros((len(b.residuals), len(index)))
        Jw = np.zeros((len(b.residuals), n + m))
        for i, r in enumerate(b.residuals):
            r = sp.sympify(r)
            for sym in r.free_symbols:
                if sym in index:
                    Jz[i, index[sym]] = d(r, sym)
                elif sym in grad and grad[sym].any():
                    Jw[i] += d(r, sym) * grad[sym]
        G = -np.linalg.solve(Jz, Jw)
        grad.update(zip(b.variables, G))

    def rows(exprs):
        out = np.zeros((len(exprs), n + m))
        for k, e in enumerate(exprs):
            e = sp.sympify(e)
            for sym in e.free_symbols:
                if sym in grad:
                    out[k] += d(e, sym) * grad[sym]
        return out
    F = rows(eq.derivatives)
    Y = rows([eq.output(o) for o in outputs])
    return F[:, :n], F[:, n:], Y[:, :n], Y[:, n:]


def control_name(name: str) -> str:
    """A scene name as a python-control signal name: ``rotor.omega`` -> ``rotor:omega``.

    python-control refuses a dot in an input or output name (``control.interconnect`` reads
    ``sys.signal``), so the dot is written as a colon; nothing else changes, and element names (letters,
    digits, ``_``) never contain a colon, so the mapping is one to one."""
    return name.replace(".", ":")


def driven_inputs(scene, eq: Equations) -> list:
    """The inputs of ``eq`` that the netlist drives: the sources of an element whose type has a
    parameter of kind ``time`` (a torque, speed, voltage or current source).  A ground or a reference
    inside an element (a motor's internal 0 V) is a fixed value, not an input."""
    from .catalogue import catalogue
    from .simulate import element_of
    types = catalogue()
    out = []
    for u in eq.inputs:
        et = types.get(scene.element_types.get(element_of(u.name), ""))
        if et is None or any(p.kind == "time" for p in et.params):
            out.append(u)
    return out


def input_units(eq: Equations) -> dict:
    """{input name: SI unit}: the effort or flow unit of the port its source imposes."""
    flat = eq.analysis.flat
    units = {}
    for u in eq.inputs:
        path = u.name.rsplit(".", 1)[0]
        prim, dom = flat.primitives.get(path), flat.port_domains.get(f"{path}.p")
        if prim is not None and dom is not None and getattr(prim, "variable", None) in ("e", "f"):
            units[u.name] = dom.effort_unit if prim.variable == "e" else dom.flow_unit
    return units


def operating_point(scene, eq: Equations, at=None) -> tuple[float, list, str]:
    """``(t, x, text)``: the time [s] and state of the operating point ``at`` and its description.

    ``at`` is None (t = 0 and the initial state), a time [s] (the state the scene's simulation
    reaches at that time, with its ``simulate`` options) or a mapping ``{state name: value}`` (SI),
    optionally with ``"t"``; states it does not name keep their initial values."""
    x0 = eq.initial_values()
    if at is None:
        return 0.0, x0, "at t = 0 about the initial state"
    if isinstance(at, dict):
        unknown = sorted(set(at) - set(eq.state_names) - {"t"})
        if unknown:
            raise MultipoleError("unknown_state", f"operating point: {', '.join(unknown)} is not a state",
                                 f"states: {', '.join(eq.state_names)}", scene.path)
        t = float(at.get("t", 0.0))
        return t, [float(at.get(n, v)) for n, v in zip(eq.state_names, x0)], f"at t = {t:g} s about the given state"
    if isinstance(at, numbers.Real) and not isinstance(at, bool) and np.isfinite(at) and at >= 0:
        if at == 0:
            return 0.0, x0, "at t = 0 about the initial state"
        from . import pipeline
        result = pipeline.run(scene, t_end=float(at), progress=False, prune=False)     # every state
        return float(at), list(result.states[-1]), f"at t = {at:g} s about the simulated state"
    raise MultipoleError("bad_operating_point", f"operating point at={at!r} is not a time or a mapping of states",
                         "at=None (t = 0), at=0.5 (the state simulated at 0.5 s) or at={'rotor.p': 0.1}",
                         scene.path)


def scene_linearization(scene, at=None, outputs=None) -> Linearization:
    """The :class:`Linearization` of ``scene`` at the operating point ``at`` (see
    :func:`operating_point`): inputs are the sources the netlist drives (:func:`driven_inputs`),
    outputs the scene's (default, else its states).  A Jacobian that is infinite or undefined there is
    a :class:`~multipole.errors.RunError` ``not_linearizable`` naming the element."""
    from . import pipeline
    eq = pipeline.equations(scene)
    outputs = list(outputs) if outputs is not None else (scene.outputs or eq.state_names)
    for out in outputs:
        eq.output(out)                     # an unknown name: one error naming it
    t, x, text = operating_point(scene, eq, at)
    try:
        A, B, C, D = numeric_jacobians(eq, outputs, t, x)
        bad = [f"matrix {m} has infinite or NaN entries" for m, M in zip("ABCD", (A, B, C, D))
               if not np.all(np.isfinite(M))]
    except (TypeError, ValueError, ArithmeticError) as exc:    # sympy cannot evaluate a derivative there
        if isinstance(exc, MultipoleError):
            raise
        bad = [f"a derivative cannot be evaluated ({type(exc).__name__}: {str(exc).strip()[:100]})"]
    if bad:
        raise _not_linearizable(scene, outputs, bad[0], text, t, x)
    inputs = list(eq.inputs)
    keep = [inputs.index(u) for u in driven_inputs(scene, eq)]
    units = {**{o: eq.units.get(o, "") for o in outputs}, **input_units(eq),
             **{s.name: s.unit for s in eq.analysis.flat.states}}
    return Linearization(A, B[:, keep], C, D[:, keep], list(eq.state_names), [inputs[k].name for k in keep],
                         outputs, units, scene.name, text)


def linearize_scene(scene, at=None, outputs=None):
    """The scene linearised at ``at`` as a python-control ``StateSpace`` (``multipole.linearize``).

    ``at``: None (t = 0, the initial state), a time [s] (the state the scene's own simulation reaches
    then) or ``{state name: value}`` (SI, optionally ``"t"``).  Inputs are the sources the netlist
    drives (grounds are not inputs), outputs the scene's ``outputs`` (or ``outputs`` given here), in
    SI units; states are the scene's states (``rotor.p``).  Input and output names are the scene's
    with the dot written as a colon (``rotor:omega``, :func:`control_name`), because python-control
    reserves the dot for ``system.signal``; the system is named after the scene.  Raises
    :class:`~multipole.errors.IllPosedError` for a scene the check refuses and
    :class:`~multipole.errors.RunError` ``not_linearizable`` where the Jacobian is not finite."""
    return scene_linearization(scene, at, outputs).statespace()


def cmd_linearize(args) -> int:
    """CLI: print the state-space matrices and modes; optionally a Bode plot."""
    from .cli import FIGURE_FORMATS, _overrides, check_output_path
    from .netlist import load
    check_output_path(args.bode, FIGURE_FORMATS, "--bode")
    scene = load(args.file, _overrides(args.set))
    lin = scene_linearization(scene, getattr(args, "at", None))
    print(f"# {scene.name}: linearised {lin.point}")
    print(lin.to_text())
    if args.bode:
        from .plotting import bode
        bode(lin, args.bode, scene.name)            # written atomically
        print(f"wrote {args.bode}")
    return 0


def _not_linearizable(scene, outputs, what: str, point: str = "at t = 0 about the initial state", t: float = 0.0,
                      x=None) -> RunError:
    """The error for a Jacobian that is infinite or undefined at the operating point (``log(f)``,
    ``1/f``, ``sqrt(f)`` or an ideal ``sign(f)`` law at f = 0, ``1/t`` at t = 0), naming the element
    where the compiled Jacobian fails at time ``t`` [s] and state ``x`` (default: the initial one)."""
    from . import pipeline
    from .simulate import model_failure
    err = RunError("not_linearizable", f"the linear model is infinite or undefined {point}: {what}",
                   "linearise where the laws are smooth: give the states initial values away from a kink or "
                   "singularity (e.g. omega0), or regularise the law (tanh instead of sign)",
                   scene.path)
    try:
        model = pipeline.model(scene, outputs, prune=False)        # x is the full state
        with np.errstate(all="ignore"):
            model.jac(t, model.x0 if x is None else np.asarray(x, dtype=float))
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        failure = model_failure(model, exc) if not isinstance(exc, MultipoleError) else None
        if failure is not None and failure.element in scene.element_lines:
            err.message += f"; {failure.message}"
            err.where = scene.where(element=failure.element)
    except MultipoleError:
        pass
    return err
