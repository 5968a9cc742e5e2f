"""Test and benchmark fixtures: scalable scene builders and hand-written reference models, shared
by the tests, ``benchmarks/``, the docs and ``multipole bench`` (like PyDy's ``models.py``).

They are not machine elements, so they live outside the element library ``elements/``.

Each builder returns the YAML text of a netlist (load it with :func:`multipole.loads`); the scenes
in ``diagrams/hard/`` and the bench scenes ``diagrams/drive_train.yaml`` and ``diagrams/rlc_series.yaml``
(:data:`SCENE_FILES`) are written from these builders by ``python benchmarks/make_hard_scenes.py``
and a test keeps them in step.  :func:`bench_scenes` offers them to ``multipole bench`` through the
``multipole.bench_scenes`` entry point, so the bench finds them in an installed package.  Where a scene is linear, the builder also derives a closed-form
reference from a *hand-written* state matrix (written from the physics here, not taken from the
generated code) and stores it in the scene's ``reference`` mapping.

:data:`HAND_MODELS` maps a ``hand_model`` key to a factory of a :class:`HandModel`: a hand-written numpy
right-hand side of the same equations (with its Jacobian), used by the bench to measure the cost
of the generated code against hand-written code, and by the tests as an independent computation.

A scene is paired with its hand-written model explicitly, by ``reference: {hand_model: KEY}`` in
the netlist (the bench finds :func:`hand_model` through the ``multipole.hand_models`` entry point).

Conventions used below (those of ``elements/basic.py``): a spring's state ``q`` is its compression
``∫(f_a - f_b) dt`` [m] and its force ``c*q`` [N] pushes its a-side neighbour back; a body's state is
its momentum ``p`` [N·s]; a damper's relative flow is ``f = f_a - f_b`` [m/s].
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["HandModel", "HAND_MODELS", "hand_model", "mass_spring_chain", "two_mass_oscillator",
           "stiff_drive_train", "mathieu_oscillator", "stick_slip", "slack_rope", "slider_crank",
           "differentiated_step", "nonlinear_loop", "piezo_stack_step", "slider_crank_position", "HARD_SCENES", "mathieu_boundaries",
           "stick_slip_exact", "slack_rope_events", "linear_response", "drive_train", "rlc_series",
           "SCENE_FILES", "bench_scenes"]


# -------------------------------------------------------------------------------------------------
# hand-written models

@dataclass
class HandModel:
    """A hand-written right-hand side ``x' = rhs(t, x)`` with named states.

    ``state_names`` use the kernel's names (``m1.p``, ``k1.q``) so that a state vector can be
    permuted into the generated model's order; ``outputs`` maps an output name to a function
    ``g(t, X)`` of the time and a state array ``X`` of shape ``(n_states, n_times)``.
    """

    name: str
    state_names: list
    x0: np.ndarray
    rhs: Callable
    jac: Callable | None = None
    outputs: dict = field(default_factory=dict)
    A: np.ndarray | None = None          # state matrix of a linear model
    forcing: Callable | None = None      # B*u(t) of a linear model

    def permutation(self, names) -> np.ndarray:
        """Indices ``idx`` with ``x_hand = x_generated[idx]`` for a model whose states are ``names``."""
        names = list(names)
        return np.array([names.index(s) for s in self.state_names])


def _num(x) -> str:
    """A float written so that the YAML loader and the expression parser read it back exactly."""
    text = repr(float(x))
    return text if ("e" in text or "." in text or "inf" in text or "nan" in text) else text + ".0"


def _params(values: dict) -> str:
    return "{" + ", ".join(f"{k}: {_num(v)}" for k, v in values.items()) + "}"


def _values(params: dict, defaults: dict) -> dict:
    """The scene's parameter values (``params``, e.g. after ``--set``) over the builder's ``defaults``."""
    return {k: float(params.get(k, v)) for k, v in defaults.items()}


def linear_response(A, y0, c, forcing_step=None, tau=None, t=None):
    """Closed-form output ``c·y(t)`` of ``y' = A y + B·U·(1 - exp(-t/tau))``, ``y(0) = y0``.

    ``forcing_step`` is the vector ``B·U`` (``None``: free response).  Returns a text expression
    of ``t`` (real modal terms ``exp(a t)·(α cos b t + β sin b t)``) when ``t`` is None, else its
    values at the times ``t``.  ``A`` must be diagonalisable and, with forcing, invertible.
    """
    A = np.asarray(A, dtype=float)
    y0 = np.asarray(y0, dtype=float)
    c = np.asarray(c, dtype=float)
    const = 0.0
    terms = []                       # (rate, omega, alpha, beta)
    r0 = y0.copy()
    if forcing_step is not None:
        bu = np.asarray(forcing_step, dtype=float)
        y_s = -np.linalg.solve(A, bu)                                # steady state
        w = np.linalg.solve(A + np.eye(len(A)) / tau, bu)           # coefficient of exp(-t/tau)
        const = float(c @ y_s)
        terms.append((-1.0 / tau, 0.0, float(c @ w), 0.0))
        r0 = y0 - y_s - w
    lam, V = np.linalg.eig(A)
    g = (c @ V) * np.linalg.solve(V, r0)                             # output weight of each mode
    done = np.zeros(len(lam), dtype=bool)
    for j, lj in enumerate(lam):
        if done[j]:
            continue
        done[j] = True
        if abs(lj.imag) > 1e-12 * max(1.0, abs(lj)):
            k = next(i for i in range(len(lam)) if not done[i] and abs(lam[i] - np.conj(lj)) <= 1e-9 * abs(lj))
            done[k] = True
            b = abs(lj.imag)
            gj = g[j] if lj.imag > 0 else g[k]
            terms.append((lj.real, b, 2 * gj.real, -2 * gj.imag))
        else:
            terms.append((lj.real, 0.0, float(g[j].real), 0.0))
    if t is not None:
        t = np.asarray(t, dtype=float)
        out = np.full_like(t, const)
        for a, b, al, be in terms:
            out += np.exp(a * t) * (al * np.cos(b * t) + be * np.sin(b * t))
        return out
    parts = [_num(const)]
    for a, b, al, be in terms:
        env = f"exp({_num(a)}*t)*" if a != 0 else ""
        if b == 0:
            parts.append(f"{env}({_num(al)})")
        else:
            parts.append(f"{env}({_num(al)}*cos({_num(b)}*t) + {_num(be)}*sin({_num(b)}*t))")
    return " + ".join(parts)


def _linear_hand(name, names, A, x0, rhs, forcing=None, outputs=None) -> HandModel:
    """A linear model ``x' = A x + forcing(t)`` whose right-hand side ``rhs`` is written out in scalars
    as carefully as the generated code (a matrix product allocates arrays for a few numbers); ``A``
    is its constant Jacobian, ``A`` and ``forcing`` also serve the closed-form references."""
    A = np.asarray(A, dtype=float)

    def jac(t, x):
        return A
    return HandModel(name, list(names), np.asarray(x0, dtype=float), rhs, jac, outputs or {}, A, forcing)


# -------------------------------------------------------------------------------------------------
# mass-spring chain (scaling benchmark)

def mass_spring_chain(n: int, m: float = 1.0, c: float = 1.0e4, F0: float = 10.0, w: float = 20.0,
                      t_end: float = 1.0, c3: float = 0.0) -> str:
    """``n`` masses ``m`` [kg] joined by springs ``c`` [N/m]: wall–k1–m1–k2–m2–…–kn–mn ← F.

    The last mass is driven by ``F0*sin(w*t)`` [N].  ``2n`` states.  With ``c3`` [N/m³] not zero
    the springs are hardening, ``force = c*q + c3*q**3`` (a ``C`` element with that law behind a
    junction): the same states, a right-hand side that is not affine.
    """
    params = {'m': m, 'c': c, 'F0': F0, 'w': w} | ({'c3': c3} if c3 else {})
    name = f"mass_spring_chain_{n}" + ("_cubic" if c3 else "")
    lines = [f"name: {name}",
             f"description: {n} masses and {n} springs in a chain, fixed at one end, forced at the other",
             f"parameters: {_params(params)}",
             "elements:",
             "  wall: {type: ground, domain: translational}"]
    for i in range(1, n + 1):
        if c3:
            lines.append(f"  k{i}: {{type: junction_a, ports: [a, b, s], signs: [1, -1, -1], domain: translational}}")
            lines.append(f'  s{i}: {{type: C, law: "c*q + c3*q**3", domain: translational}}')
        else:
            lines.append(f"  k{i}: {{type: spring, c: c, domain: translational}}")
        lines.append(f"  m{i}: {{type: mass, m: m}}")
    lines += ['  force: {type: force_source, value: "F0*sin(w*t)"}', "connections:", "  - [wall.p, k1.a]"]
    for i in range(1, n + 1):
        lines.append(f"  - [k{i}.b, m{i}.a]")
        lines.append(f"  - [m{i}.b, {'k%d.a' % (i + 1) if i < n else 'force.p'}]")
        if c3:
            lines.append(f"  - [k{i}.s, s{i}.p]")
    lines += [f"outputs: [m{n}.v, {'s1.p.e' if c3 else 'k1.force'}]",
              f"simulate: {{t_end: {_num(t_end)}, dt_out: {_num(t_end / 200)}, rtol: 1.0e-6, atol: 1.0e-9}}",
              "reference: {kind: tight, hand_model: mass_spring_chain}"]
    return "\n".join(lines) + "\n"


def _chain_hand(params: dict, n: int) -> HandModel:
    """Hand-written chain: ``q_i' = v_{i-1} - v_i``, ``p_i' = F_i - F_{i+1}`` (+ F on the last) with the
    spring forces ``F_i = c q_i + c3 q_i³`` (``c3`` = 0 unless the scene has it: linear springs)."""
    m, c, F0, w = (float(params[k]) for k in ("m", "c", "F0", "w"))
    c3 = float(params.get("c3", 0.0))
    spring = "s" if c3 else "k"
    names = [f"{spring}{i}.q" for i in range(1, n + 1)] + [f"m{i}.p" for i in range(1, n + 1)]

    def rhs(t, x):
        q, p = x[:n], x[n:]
        v = p / m
        dq = np.empty(n)
        dq[0] = -v[0]
        dq[1:] = v[:-1] - v[1:]
        dp = c * q + c3 * q**3
        dp[:-1] -= dp[1:].copy()
        dp[-1] += F0 * np.sin(w * t)
        return np.concatenate((dq, dp))

    J = np.zeros((2 * n, 2 * n))
    idx = np.arange(n)
    J[idx, n + idx] = -1.0 / m
    J[idx[1:], n + idx[:-1]] = 1.0 / m
    J[n + idx, idx] = c
    J[n + idx[:-1], idx[1:]] = -c

    def jac(t, x):
        if not c3:
            return J
        out = J.copy()
        slope = c + 3.0 * c3 * x[:n]**2                 # dF_i/dq_i
        out[n + idx, idx] = slope
        out[n + idx[:-1], idx[1:]] = -slope[1:]
        return out
    force = f"{spring}1.p.e" if c3 else "k1.force"
    outs = {f"m{n}.v": lambda t, X: X[2 * n - 1] / m, force: lambda t, X: c * X[0] + c3 * X[0]**3}
    return HandModel(f"mass_spring_chain_{n}", names, np.zeros(2 * n), rhs, jac, outs, None if c3 else J)


# -------------------------------------------------------------------------------------------------
# two-mass oscillator (long horizon, energy)

_TWO_MASS = {"m1": 1.0, "m2": 0.5, "k1": 40.0, "k2": 20.0, "x1_0": 0.1, "v2_0": 0.2}


def _two_mass_matrix(p):
    """States (k1.q, m1.p, k2.q, m2.p): q1' = -v1, p1' = k1 q1 - k2 q2, q2' = v1 - v2, p2' = k2 q2."""
    m1, m2, k1, k2 = (float(p[k]) for k in ("m1", "m2", "k1", "k2"))
    return np.array([[0.0, -1 / m1, 0.0, 0.0],
                     [k1, 0.0, -k2, 0.0],
                     [0.0, 1 / m1, 0.0, -1 / m2],
                     [0.0, 0.0, k2, 0.0]])


def _two_mass_x0(p):
    # the first mass pushed 0.1 m towards the wall (k1 compressed, k2 stretched), the second moving
    return np.array([p["x1_0"], 0.0, -p["x1_0"], p["m2"] * p["v2_0"]], dtype=float)


def two_mass_oscillator(periods: float = 20.0, name: str = "two_mass_oscillator", bench: bool = True,
                        **params) -> str:
    """Conservative wall–k1–m1–k2–m2 oscillator (no damping), ``periods`` of its slower mode.

    Reference: the modal closed form of ``m1.v``; conserved energy
    ``E = m1 v1²/2 + m2 v2²/2 + k1 q1²/2 + k2 q2²/2`` [J].
    """
    p = {**_TWO_MASS, **params}
    A = _two_mass_matrix(p)
    slow = float(np.min(np.abs(np.linalg.eigvals(A).imag)))
    t_end = periods * 2 * np.pi / slow
    expr = linear_response(A, _two_mass_x0(p), [0.0, 1 / p["m1"], 0.0, 0.0])
    return f"""name: {name}
description: >
  Conservative two-mass oscillator over {periods:g} periods of its slow mode; closed-form
  reference from the modal solution, energy must be conserved.
parameters: {_params(p)}
elements:
  wall: {{type: ground, domain: translational}}
  k1:   {{type: spring, c: k1, x0: x1_0, domain: translational}}
  m1:   {{type: mass, m: m1}}
  k2:   {{type: spring, c: k2, x0: -x1_0, domain: translational}}
  m2:   {{type: mass, m: m2, v0: v2_0}}
connections:
  - [wall.p, k1.a]
  - [k1.b, m1.a]
  - [m1.b, k2.a]
  - [k2.b, m2.a]
outputs: [m1.v, m2.v, k1.deflection, k2.deflection]
simulate: {{t_end: {_num(t_end)}, dt_out: {_num(t_end / (40 * periods))}, solver: auto, rtol: 1.0e-8, atol: 1.0e-10}}
reference:
  kind: closed_form
  hand_model: two_mass_oscillator
  output: m1.v
  expression: "{expr}"
  energy: "0.5*m1*m1.v**2 + 0.5*m2*m2.v**2 + 0.5*k1*k1.deflection**2 + 0.5*k2*k2.deflection**2"
bench: {'true' if bench else 'false'}
"""


def _two_mass_hand(params: dict) -> HandModel:
    p = _values(params, _TWO_MASS)
    m1, m2, k1, k2 = (float(p[k]) for k in ("m1", "m2", "k1", "k2"))
    outs = {"m1.v": lambda t, X: X[1] / m1, "m2.v": lambda t, X: X[3] / m2}

    def rhs(t, x):
        v1, v2 = x[1] / m1, x[3] / m2
        return [-v1, k1 * x[0] - k2 * x[2], v1 - v2, k2 * x[2]]
    return _linear_hand("two_mass_oscillator", ["k1.q", "m1.p", "k2.q", "m2.p"], _two_mass_matrix(p),
                        _two_mass_x0(p), rhs, outputs=outs)


# -------------------------------------------------------------------------------------------------
# stiff drive train

_STIFF = {"T0": 10.0, "tau": 0.2, "J1": 1.0e-3, "J2": 1.0, "c": 1.0e9, "d_s": 1.0e3, "d_b": 1.0}


def _stiff_matrix(p):
    """States (rotor.p, shaft.q, load.p); ω1 = p1/J1, ω2 = p2/J2:
    p1' = T - c q - d_s (ω1 - ω2),  q' = ω1 - ω2,  p2' = c q + d_s (ω1 - ω2) - d_b ω2."""
    J1, J2, c, ds, db = (float(p[k]) for k in ("J1", "J2", "c", "d_s", "d_b"))
    return np.array([[-ds / J1, -c, ds / J2],
                     [1 / J1, 0.0, -1 / J2],
                     [ds / J1, c, -(ds + db) / J2]])


def stiff_drive_train(t_end: float = 3.0, name: str = "stiff_drive_train", **params) -> str:
    """Motor rotor J1 – very stiff damped shaft (c, d_s) – load J2 on a bearing damper d_b.

    The shaft mode has |λ| ≈ sqrt(c (1/J1 + 1/J2)) ≈ 1e6 1/s, the load mode λ ≈ -d_b/(J1 + J2) ≈ -1
    1/s: an eigenvalue ratio of about 1e6.  The motor torque rises as ``T0*(1 - exp(-t/tau))`` [N·m].
    Reference: the closed form of ``load.omega`` from the hand-written state matrix.
    """
    p = {**_STIFF, **params}
    A = _stiff_matrix(p)
    expr = linear_response(A, np.zeros(3), [0.0, 0.0, 1 / p["J2"]], [p["T0"], 0.0, 0.0], p["tau"])
    return f"""name: {name}
description: >
  Motor, very stiff damped shaft and a slow load on a bearing damper: eigenvalue ratio about 1e6.
  An explicit method is held to steps of about 3e-6 s by the shaft mode; an implicit one is not.
parameters: {_params(p)}
elements:
  motor:   {{type: torque_source, value: "T0*(1 - exp(-t/tau))"}}
  rotor:   {{type: inertia, J: J1}}
  shaft:   {{type: spring, c: c}}
  shaft_d: {{type: damper, d: d_s}}
  load:    {{type: inertia, J: J2}}
  bearing: {{type: damper, d: d_b}}
  housing: {{type: ground}}
connections:
  - [motor.p, rotor.a]
  - [rotor.b, shaft.a, shaft_d.a]
  - [shaft.b, shaft_d.b, load.a]
  - [load.b, bearing.a]
  - [bearing.b, housing.p]
outputs: [load.omega, rotor.omega, shaft.force]
simulate: {{t_end: {_num(t_end)}, dt_out: {_num(t_end / 300)}, solver: auto, rtol: 1.0e-6, atol: 1.0e-9}}
reference:
  kind: closed_form
  hand_model: stiff_drive_train
  output: load.omega
  expression: "{expr}"
bench: true
"""


def _stiff_hand(params: dict) -> HandModel:
    p = _values(params, _STIFF)
    T0, tau = p["T0"], p["tau"]

    J1, J2, c, ds, db = (float(p[k]) for k in ("J1", "J2", "c", "d_s", "d_b"))

    def forcing(t):
        return np.array([T0 * (1 - np.exp(-t / tau)), 0.0, 0.0])

    def rhs(t, x):
        w1, w2 = x[0] / J1, x[2] / J2
        shaft = c * x[1] + ds * (w1 - w2)
        return [T0 * (1.0 - math.exp(-t / tau)) - shaft, w1 - w2, shaft - db * w2]
    outs = {"load.omega": lambda t, X: X[2] / J2, "rotor.omega": lambda t, X: X[0] / J1}
    return _linear_hand("stiff_drive_train", ["rotor.p", "shaft.q", "load.p"], _stiff_matrix(p), np.zeros(3),
                        rhs, forcing, outs)


# -------------------------------------------------------------------------------------------------
# parametric excitation (Mathieu)

def mathieu_oscillator(delta: float = 0.2, eps: float = 0.2, periods: int = 20, q0: float = 1.0,
                       v0: float = 0.0, name: str = "mathieu") -> str:
    """Unit mass on a spring whose stiffness is ``delta + eps*cos(t)`` [N/m]: ``x'' + (δ + ε cos t) x = 0``.

    The spring is a kernel ``C`` primitive with the law ``(delta + eps*cos(t))*q``; the excitation
    period is 2π s.  See :func:`mathieu_boundaries` for the analytic first instability tongue.
    """
    t_end = 2 * np.pi * periods
    return f"""name: {name}
description: >
  Parametric excitation: x'' + (delta + eps*cos(t))*x = 0 (Mathieu). The first instability
  tongue lies around delta = 1/4 between 1/4 - eps/2 - eps^2/8 and 1/4 + eps/2 - eps^2/8.
parameters: {_params({'delta': delta, 'eps': eps, 'q0': q0, 'v0': v0})}
elements:
  body:   {{type: mass, m: 1.0, v0: v0}}
  spring: {{type: C, law: "(delta + eps*cos(t))*q", domain: translational, q0: q0}}
connections:
  - [body.a, spring.p]
outputs: [spring.q, body.v]
simulate: {{t_end: {_num(t_end)}, dt_out: {_num(np.pi / 20)}, solver: auto, rtol: 1.0e-9, atol: 1.0e-12}}
reference: {{kind: tight, hand_model: mathieu, output: spring.q}}
bench: true
"""


def mathieu_boundaries(eps: float) -> tuple[float, float]:
    """Analytic boundaries (δ_lower, δ_upper) of the first tongue of ``x'' + (δ + ε cos t) x = 0``.

    Harmonic balance with ``x = a cos(t/2) + b sin(t/2)`` (the 2:1 resonance) gives
    ``δ = 1/4 ± ε/2`` to first order; the next terms of the Lindstedt–Poincaré expansion are
    ``-ε²/8 ∓ ε³/32`` (Kovacic, Rand & Sah, Appl. Mech. Rev. 70 (2018), eq. for the n = 1 tongue).
    """
    return 0.25 - eps / 2 - eps**2 / 8 + eps**3 / 32, 0.25 + eps / 2 - eps**2 / 8 - eps**3 / 32


_MATHIEU = {"delta": 0.2, "eps": 0.2, "q0": 1.0, "v0": 0.0}


def _mathieu_hand(params: dict) -> HandModel:
    """States (body.p [N·s], spring.q [m]), unit mass: ``p' = -(δ + ε cos t) q``, ``q' = p``."""
    p = _values(params, _MATHIEU)
    delta, eps = p["delta"], p["eps"]

    def rhs(t, x):
        mom, q = x
        return np.array([-(delta + eps * math.cos(t)) * q, mom])

    def jac(t, x):
        return np.array([[0.0, -(delta + eps * math.cos(t))], [1.0, 0.0]])
    outs = {"spring.q": lambda t, X: X[1], "body.v": lambda t, X: X[0]}
    return HandModel("mathieu", ["body.p", "spring.q"], np.array([p["v0"], p["q0"]]), rhs, jac, outs)


# -------------------------------------------------------------------------------------------------
# stick-slip

_STICK = {"m": 1.0, "k": 100.0, "v_belt": 0.1, "F_s": 10.0, "F_k": 6.0, "v_reg": 1.0e-6, "v_s": 1.0e-4}


def stick_slip(t_end: float = 3.0, name: str = "stick_slip", **params) -> str:
    """A mass ``m`` held by a spring ``k`` to the wall, lying on a belt moving at ``v_belt`` [m/s].

    Friction (a ``damper`` with a law of the slip speed ``f = v_belt - v``): static level ``F_s``,
    kinetic level ``F_k`` [N], regularised as ``(F_k + (F_s - F_k)*exp(-(f/v_s)**2))*tanh(f/v_reg)``.
    The mass starts stuck (moving with the belt) at the spring's rest position.
    """
    p = {**_STICK, **params}
    return f"""name: {name}
description: >
  Stick-slip: a mass on a moving belt held by a spring, Coulomb friction with static level F_s and
  kinetic level F_k, regularised by tanh(f/v_reg) and a Stribeck drop over v_s.
parameters: {_params(p)}
elements:
  belt:     {{type: velocity_source, value: v_belt}}
  friction: {{type: damper, law: "(F_k + (F_s - F_k)*exp(-(f/v_s)**2))*tanh(f/v_reg)", domain: translational}}
  body:     {{type: mass, m: m, v0: v_belt}}
  spring:   {{type: spring, c: k, domain: translational}}
  wall:     {{type: ground, domain: translational}}
connections:
  - [belt.p, friction.a]
  - [friction.b, body.a]
  - [body.b, spring.a]
  - [spring.b, wall.p]
outputs: [body.v, spring.deflection, friction.force]
simulate: {{t_end: {_num(t_end)}, dt_out: 0.002, solver: auto, rtol: 1.0e-8, atol: 1.0e-10}}
reference: {{kind: tight, hand_model: stick_slip, output: spring.deflection}}
bench: true
"""


def _stick_slip_hand(params: dict) -> HandModel:
    """States (body.p [N·s], spring.q [m]); slip speed ``f = v_belt - v`` [m/s]:
    ``p' = F(f) - k q``, ``q' = v``, with the regularised Coulomb–Stribeck law ``F`` below."""
    p = _values(params, _STICK)
    m, k, v_belt, F_s, F_k, v_reg, v_s = (p[n] for n in ("m", "k", "v_belt", "F_s", "F_k", "v_reg", "v_s"))

    def friction(f):
        """Friction force [N] at the slip speed ``f`` [m/s]: static level F_s, kinetic F_k."""
        return (F_k + (F_s - F_k) * math.exp(-(f / v_s) ** 2)) * math.tanh(f / v_reg)

    def friction_slope(f):
        """dF/df [N·s/m]."""
        th = math.tanh(f / v_reg)
        bump = (F_s - F_k) * math.exp(-(f / v_s) ** 2)
        return -2 * f / v_s**2 * bump * th + (F_k + bump) * (1 - th * th) / v_reg

    def rhs(t, x):
        mom, q = x
        v = mom / m
        return np.array([friction(v_belt - v) - k * q, v])

    def jac(t, x):
        return np.array([[-friction_slope(v_belt - x[0] / m) / m, -k], [1 / m, 0.0]])
    outs = {"body.v": lambda t, X: X[0] / m, "spring.deflection": lambda t, X: X[1]}
    return HandModel("stick_slip", ["body.p", "spring.q"], np.array([m * v_belt, 0.0]), rhs, jac, outs)


def stick_slip_exact(t, m=1.0, k=100.0, v_belt=0.1, F_s=10.0, F_k=6.0, **_ignored):
    """Exact piecewise solution (position ``x``, velocity ``v``) of ideal Coulomb stick-slip.

    Start stuck at ``x = 0`` moving with the belt.  Stick: ``x' = v_belt`` until the spring force
    ``k x`` reaches the static level ``F_s``.  Slip (``v < v_belt``, kinetic friction ``F_k`` forward):
    ``m x'' = F_k - k x``, a harmonic motion of ``ω = sqrt(k/m)`` about ``F_k/k`` with
    ``x - F_k/k = A cos ωτ + B sin ωτ``, ``A = (F_s - F_k)/k``, ``B = v_belt/ω``.  The speed returns
    to ``v_belt`` after ``τ_slip = (π + 2φ)/ω``, ``φ = atan2(B, A)``, at ``x = (2F_k - F_s)/k`` where
    the spring force is within the static level: the mass sticks again for
    ``2(F_s - F_k)/(k v_belt)``.  From the first breakaway on the motion is periodic.
    """
    t = np.asarray(t, dtype=float)
    w = np.sqrt(k / m)
    A, B = (F_s - F_k) / k, v_belt / w
    phi = np.arctan2(B, A)
    t1 = F_s / (k * v_belt)
    t_slip = (np.pi + 2 * phi) / w
    t_stick = 2 * (F_s - F_k) / (k * v_belt)
    period = t_slip + t_stick
    x = v_belt * t
    v = np.full_like(t, v_belt)
    late = t > t1
    tau = np.mod(t[late] - t1, period)
    slip = tau < t_slip
    xs = F_k / k + A * np.cos(w * tau) + B * np.sin(w * tau)
    vs = -A * w * np.sin(w * tau) + B * w * np.cos(w * tau)
    xst = (2 * F_k - F_s) / k + v_belt * (tau - t_slip)
    x[late] = np.where(slip, xs, xst)
    v[late] = np.where(slip, vs, v_belt)
    return x, v, {"t_break": t1, "t_slip": t_slip, "t_stick": t_stick, "period": period}


# -------------------------------------------------------------------------------------------------
# slack rope

_ROPE = {"m": 10.0, "k": 1.0e4, "g": 9.81, "h0": 0.1}


def slack_rope(t_end: float = 3.0, name: str = "slack_rope", **params) -> str:
    """A load ``m`` [kg] on a tension-only rope of stiffness ``k`` [N/m], dropped from ``h0`` [m] of slack.

    The rope is a kernel ``C`` with the law ``k*min(q, 0)``: ``q`` [m] is the height of the load
    above the point where the rope becomes taut, so it pulls only while ``q < 0``.  No damping:
    ``E = m v²/2 + m g q + k min(q, 0)²/2`` [J] is conserved; taut/slack switches are events.
    """
    p = {**_ROPE, **params}
    return f"""name: {name}
description: >
  A load bouncing on a tension-only rope (C law k*min(q, 0)): the rope goes slack and taut again,
  each switch is an event; no damping, so the energy is conserved across the switches.
parameters: {_params(p)}
elements:
  rope:    {{type: C, law: "k*min(q, 0)", domain: translational, q0: h0}}
  load:    {{type: mass, m: m}}
  gravity: {{type: force_source, value: "-m*g"}}
connections:
  - [rope.p, load.a]
  - [load.b, gravity.p]
outputs: [rope.q, load.v, rope.p.e]
simulate: {{t_end: {_num(t_end)}, dt_out: 0.001, solver: auto, rtol: 1.0e-9, atol: 1.0e-12}}
reference:
  kind: tight
  hand_model: slack_rope
  output: rope.q
  energy: "0.5*m*load.v**2 + m*g*rope.q + 0.5*k*min(rope.q, 0)**2"
bench: true
"""


def _slack_rope_hand(params: dict) -> HandModel:
    """States (rope.q [m], load.p [N·s]): ``q' = p/m``, ``p' = -m g - T(q)`` with the tension-only
    rope ``T(q) = k min(q, 0)`` [N] written as a plain function (no events: the step-size control
    finds the kinks)."""
    p = _values(params, _ROPE)
    m, k, g = p["m"], p["k"], p["g"]

    def rope(q):
        """Rope force [N] at the height ``q`` [m] above the taut point: pulls only when ``q < 0``."""
        return k * min(q, 0.0)

    def rhs(t, x):
        q, mom = x
        return np.array([mom / m, -m * g - rope(q)])

    def jac(t, x):
        return np.array([[0.0, 1 / m], [-k if x[0] < 0 else 0.0, 0.0]])
    outs = {"rope.q": lambda t, X: X[0], "load.v": lambda t, X: X[1] / m}
    return HandModel("slack_rope", ["rope.q", "load.p"], np.array([p["h0"], 0.0]), rhs, jac, outs)


def slack_rope_events(n: int, m=10.0, k=1.0e4, g=9.81, h0=0.1, **_ignored) -> np.ndarray:
    """Exact times [s] of the first ``n`` taut/slack switches of :func:`slack_rope`.

    Free fall from rest over ``h0``: taut at ``t1 = sqrt(2 h0/g)`` with ``v1 = -sqrt(2 g h0)``.  Taut:
    ``q = δ(cos ωτ - 1) + (v1/ω) sin ωτ`` (``δ = m g/k``, ``ω = sqrt(k/m)``) returns to 0 after
    ``τ_c = (2π + 2ψ)/ω``, ``ψ = atan2(v1/ω, δ)``; then a flight of ``2|v1|/g`` back to the rope.
    """
    w = np.sqrt(k / m)
    v1 = -np.sqrt(2 * g * h0)
    psi = np.arctan2(v1 / w, m * g / k)
    t_c = (2 * np.pi + 2 * psi) / w
    t_f = 2 * abs(v1) / g
    out, t = [], np.sqrt(2 * h0 / g)
    for i in range(n):
        out.append(t)
        t += t_c if i % 2 == 0 else t_f
    return np.array(out)


# -------------------------------------------------------------------------------------------------
# slider-crank through its dead centres

_CRANK = {"r": 0.05, "l": 0.2, "J": 0.05, "m": 0.5, "F0": 200.0, "w0": 60.0}


def slider_crank_position(phi, r=0.05, l=0.2, **_ignored):
    """Piston position ``x = r cos φ + sqrt(l² - r² sin² φ)`` [m] of a centric slider-crank."""
    return r * np.cos(phi) + np.sqrt(l**2 - (r * np.sin(phi)) ** 2)


def slider_crank(t_end: float = 10.0, name: str = "slider_crank", prefer: str | None = None, **params) -> str:
    """Flywheel ``J`` [kg·m²] – slider-crank (crank ``r``, rod ``l`` [m]) – piston ``m`` [kg].

    Piston position ``x = r cos φ + sqrt(l² - r² sin² φ)``; the crank is a modulated TF with the
    ratio ``dx/dφ`` (zero at both dead centres φ = kπ), so the piston is in derivative causality and
    the flywheel carries the motion through the dead centres with the effective inertia
    ``J + m (dx/dφ)²``.  A constant piston force ``F0`` [N] pushes towards the crank: its work
    ``-F0 (x(t) - x(0))`` equals the change of kinetic energy.  ``prefer`` sets ``prefer_state``.
    """
    p = {**_CRANK, **params}
    ratio = "-r*sin(q) - r**2*sin(q)*cos(q)/sqrt(l**2 - r**2*sin(q)**2)"
    extra = f"prefer_state: [{prefer}]\n" if prefer else ""
    return f"""name: {name}
description: >
  Slider-crank with flywheel, started at a dead centre and carried through both dead centres for
  many revolutions while a constant piston force accelerates and brakes it.
parameters: {_params(p)}
elements:
  flywheel: {{type: inertia, J: J, omega0: w0}}
  crank:    {{type: TF, ratio: "{ratio}", domain_a: translational, domain_b: rotational}}
  piston:   {{type: mass, m: m}}
  gas:      {{type: force_source, value: "-F0"}}
connections:
  - [flywheel.b, crank.b]
  - [crank.a, piston.a]
  - [piston.b, gas.p]
{extra}outputs: [flywheel.omega, crank.q, piston.v]
simulate: {{t_end: {_num(t_end)}, dt_out: 0.001, solver: auto, rtol: 1.0e-9, atol: 1.0e-12}}
reference:
  kind: tight
  hand_model: slider_crank
  output: flywheel.omega
  energy: "0.5*J*flywheel.omega**2 + 0.5*m*piston.v**2 + F0*(r*cos(crank.q) + sqrt(l**2 - r**2*sin(crank.q)**2))"
bench: true
"""


def _crank_kinematics(phi, r, l):
    """Derivatives ``x'``, ``x''``, ``x‴`` [m/rad, m/rad², m/rad³] of the piston position of
    :func:`slider_crank_position` with respect to the crank angle ``φ`` [rad].

    With ``s = sqrt(l² - r² sin² φ)`` and ``a = sin φ cos φ`` (so ``s' = -r² a/s``, ``a' = cos 2φ``):
    ``x' = -r sin φ - r² a/s``, ``x'' = -r cos φ - r² cos 2φ/s - r⁴ a²/s³``,
    ``x‴ = r sin φ + 4 r² a/s - 3 r⁴ a cos 2φ/s³ - 3 r⁶ a³/s⁵``.
    """
    sn, cs = math.sin(phi), math.cos(phi)
    a, c2 = sn * cs, cs * cs - sn * sn
    s = math.sqrt(l * l - (r * sn) ** 2)
    d1 = -r * sn - r * r * a / s
    d2 = -r * cs - r * r * c2 / s - r**4 * a * a / s**3
    d3 = r * sn + 4 * r * r * a / s - 3 * r**4 * a * c2 / s**3 - 3 * r**6 * a**3 / s**5
    return d1, d2, d3


def _slider_crank_hand(params: dict) -> HandModel:
    """States (flywheel.p = J ω [N·m·s], crank.q = φ [rad]); the piston (mass m, speed ``x'(φ) ω``)
    is rigidly tied to the crank.  Lagrange with ``T = (J + m x'²) ω²/2`` and the potential ``F0 x``
    of the constant gas force: ``(J + m x'²) ω' = -x' (F0 + m x'' ω²)``, so
    ``p' = -J x' (F0 + m x'' ω²)/(J + m x'²)``, ``φ' = ω = p/J``."""
    p = _values(params, _CRANK)
    r, l, J, m, F0 = p["r"], p["l"], p["J"], p["m"], p["F0"]

    def rhs(t, x):
        mom, phi = x
        w = mom / J
        d1, d2, _ = _crank_kinematics(phi, r, l)
        return np.array([-J * d1 * (F0 + m * d2 * w * w) / (J + m * d1 * d1), w])

    def jac(t, x):
        mom, phi = x
        w = mom / J
        d1, d2, d3 = _crank_kinematics(phi, r, l)
        den = J + m * d1 * d1
        num = -J * d1 * (F0 + m * d2 * w * w)
        dnum_dphi = -J * (d2 * (F0 + m * d2 * w * w) + d1 * m * d3 * w * w)
        dnum_dp = -2 * m * d1 * d2 * w
        return np.array([[dnum_dp / den, (dnum_dphi * den - num * 2 * m * d1 * d2) / den**2], [1 / J, 0.0]])

    def piston_speed(t, X):
        d1 = np.array([_crank_kinematics(phi, r, l)[0] for phi in np.atleast_1d(X[1])])
        return d1 * X[0] / J
    outs = {"flywheel.omega": lambda t, X: X[0] / J, "crank.q": lambda t, X: X[1], "piston.v": piston_speed}
    return HandModel("slider_crank", ["flywheel.p", "crank.q"], np.array([J * p["w0"], 0.0]), rhs, jac, outs)


# -------------------------------------------------------------------------------------------------
# differentiated step, nonlinear algebraic loop

def differentiated_step(smooth: bool = False, name: str = "differentiated_step") -> str:
    """A speed source steps the rotor of a rigid gear pair: both inertias are rigidly tied to the
    source, so their momenta follow by differentiation of its speed; a step would need an impulse.
    ``smooth=True`` gives the speed a finite rise time ``w0*(1 - exp(-t/tau))`` instead.
    """
    value = "w0*(1 - exp(-t/tau))" if smooth else "w0*step(t - 0.1)"
    expect = "" if smooth else "expect_check: 1\n"
    return f"""name: {name}
description: >
  A speed source imposes {'a smooth rise' if smooth else 'a step'} on a rotor rigidly geared to a load: the
  inertias are in derivative causality, so the source torque needs d/dt of the imposed speed.
{expect}parameters: {{w0: 100.0, tau: 0.05, J1: 1.0e-3, J2: 0.02, i: 4.0}}
elements:
  drive: {{type: speed_source, value: "{value}"}}
  rotor: {{type: inertia, J: J1}}
  gear:  {{type: ideal_gear, i: i}}
  load:  {{type: inertia, J: J2}}
connections:
  - [drive.p, rotor.a]
  - [rotor.b, gear.a]
  - [gear.b, load.a]
outputs: [load.omega, drive.p.e]
simulate: {{t_end: 0.5, dt_out: 0.001}}
"""


_LOOP = {"m": 2.0, "V": 3.0, "w": 2.0, "d1": 1.5, "k1": 4.0, "a2": 1.0, "b2": 0.5}


def nonlinear_loop(t_end: float = 6.0, name: str = "nonlinear_loop", **params) -> str:
    """A belt ``V*sin(w*t)`` [m/s] drags a mass ``m`` through two nonlinear dampers in series.

    The node between the dampers has no mass: its speed ``u`` solves the zero-storage loop
    ``d1 (v_b - u) + k1 (v_b - u)³ = a2 sinh((u - v)/b2)`` [N] — Newton in the generated code.
    """
    p = {**_LOOP, **params}
    return f"""name: {name}
description: >
  Two nonlinear dampers in series without a mass between them: a nonlinear algebraic loop that
  Newton's method solves at every evaluation, over a wide range of slip speeds.
parameters: {_params(p)}
elements:
  belt: {{type: velocity_source, value: "V*sin(w*t)"}}
  d_1:  {{type: damper, law: "d1*f + k1*f**3", domain: translational}}
  d_2:  {{type: damper, law: "a2*sinh(f/b2)", domain: translational}}
  body: {{type: mass, m: m}}
connections:
  - [belt.p, d_1.a]
  - [d_1.b, d_2.a]
  - [d_2.b, body.a]
outputs: [body.v, d_1.force, d_2.force]
simulate: {{t_end: {_num(t_end)}, dt_out: 0.01, solver: auto, rtol: 1.0e-9, atol: 1.0e-12}}
reference: {{kind: tight, hand_model: nonlinear_loop, output: body.v}}
bench: true
"""


def _loop_hand(params: dict) -> HandModel:
    """State body.p [N·s].  With ``Δ = v_belt - v`` and the slip ``s = u - v`` of the second damper
    [m/s], the series force ``F`` [N] solves ``h(s) = d1 (Δ - s) + k1 (Δ - s)³ - a2 sinh(s/b2) = 0``;
    ``h`` falls strictly in ``s`` and changes sign between 0 and Δ, so Newton's method safeguarded
    by bisection on that bracket finds the one root.  ``p' = F = a2 sinh(s/b2)``; by the implicit
    function theorem ``dF/dΔ = G1 G2/(G1 + G2)`` (the series conductance) with
    ``G1 = d1 + 3 k1 (Δ - s)²``, ``G2 = a2 cosh(s/b2)/b2`` [N·s/m]."""
    p = _values(params, _LOOP)
    m, V, w, d1, k1, a2, b2 = (p[n] for n in ("m", "V", "w", "d1", "k1", "a2", "b2"))

    def slip(delta):
        """Root ``s`` [m/s] of ``h`` for the slip speed ``delta`` [m/s] across both dampers."""
        lo, hi = min(0.0, delta), max(0.0, delta)
        s = 0.5 * (lo + hi)
        for _ in range(200):
            f1 = delta - s
            h = d1 * f1 + k1 * f1**3 - a2 * math.sinh(s / b2)
            if h > 0:
                lo = s
            else:
                hi = s
            new = s + h / (d1 + 3 * k1 * f1 * f1 + a2 * math.cosh(s / b2) / b2)
            if not lo <= new <= hi:                     # Newton left the bracket: bisect
                new = 0.5 * (lo + hi)
            if abs(new - s) <= 1e-15 * max(abs(delta), 1e-300):
                return new
            s = new
        return s

    def rhs(t, x):
        s = slip(V * math.sin(w * t) - x[0] / m)
        return np.array([a2 * math.sinh(s / b2)])

    def jac(t, x):
        delta = V * math.sin(w * t) - x[0] / m
        s = slip(delta)
        G1, G2 = d1 + 3 * k1 * (delta - s) ** 2, a2 * math.cosh(s / b2) / b2
        return np.array([[-G1 * G2 / (G1 + G2) / m]])
    outs = {"body.v": lambda t, X: X[0] / m}
    return HandModel("nonlinear_loop", ["body.p"], np.zeros(1), rhs, jac, outs)


# -------------------------------------------------------------------------------------------------
# the two bench scenes of diagrams/ (not built here): drive train and series RLC circuit

#: diagrams/drive_train.yaml: gear ratio i, shaft stiffness c_shaft [N·m/rad] (scene parameters) and
#: the element values written in the file: inertias J1, J2 [kg·m²], shaft and bearing damping
#: d_s, d_b [N·m·s/rad], motor torque T0 (1 - exp(-t/tau)) [N·m], tau [s].
_DRIVE = {"i": 3.0, "c_shaft": 2000.0, "J1": 2.0e-3, "J2": 0.5, "d_s": 0.5, "d_b": 0.8, "T0": 10.0, "tau": 0.05}


def _drive_train_hand(params: dict) -> HandModel:
    """States (rotor.p, shaft.q, load.p); the gear gives the shaft the input speed ``ω1/i`` and the
    rotor the torque ``τ/i`` of the shaft ``τ = c q + d_s (ω1/i - ω2)`` [N·m]:
    ``p1' = T(t) - τ/i``, ``q' = ω1/i - ω2``, ``p2' = τ - d_b ω2``."""
    p = _values(params, _DRIVE)
    i, c, J1, J2, ds, db = (p[n] for n in ("i", "c_shaft", "J1", "J2", "d_s", "d_b"))
    A = np.array([[-ds / (i * i * J1), -c / i, ds / (i * J2)],
                  [1 / (i * J1), 0.0, -1 / J2],
                  [ds / (i * J1), c, -(ds + db) / J2]])
    T0, tau = p["T0"], p["tau"]

    def forcing(t):
        return np.array([T0 * (1 - math.exp(-t / tau)), 0.0, 0.0])

    def rhs(t, x):
        w1, w2 = x[0] / J1, x[2] / J2
        shaft = c * x[1] + ds * (w1 / i - w2)
        return [T0 * (1.0 - math.exp(-t / tau)) - shaft / i, w1 / i - w2, shaft - db * w2]
    outs = {"rotor.omega": lambda t, X: X[0] / J1, "load.omega": lambda t, X: X[2] / J2,
            "shaft.force": lambda t, X: c * X[1]}
    return _linear_hand("drive_train", ["rotor.p", "shaft.q", "load.p"], A, np.zeros(3), rhs, forcing, outs)


#: diagrams/rlc_series.yaml: supply V [V] (scene parameter), R [Ω], L [H], C [F] from the file.
_RLC = {"V": 12.0, "R": 10.0, "L": 0.1, "C": 1.0e-4}


def _rlc_hand(params: dict) -> HandModel:
    """States (L1.p = L i [V·s], C1.q [C]): ``p' = V step(t) - R p/L - q/C``, ``q' = p/L``."""
    p = _values(params, _RLC)
    V, R, L, C = p["V"], p["R"], p["L"], p["C"]
    A = np.array([[-R / L, -1 / C], [1 / L, 0.0]])

    def forcing(t):
        return np.array([V if t >= 0 else 0.0, 0.0])

    def rhs(t, x):
        current = x[0] / L
        return [(V if t >= 0 else 0.0) - R * current - x[1] / C, current]
    outs = {"C1.v": lambda t, X: X[1] / C, "L1.i": lambda t, X: X[0] / L}
    return _linear_hand("rlc_series", ["L1.p", "C1.q"], A, np.zeros(2), rhs, forcing, outs)


#: piezo_stack_step: one PZT disc [m/V, m/N, F, Ω], the load [kg], the supply [V] and the pull [N]
_STACK = {"k_P": 5.0e-10, "delta_P": 1.0e-10, "C_P": 5.0e-9, "R": 10.0, "M": 0.05, "U": 100.0, "F": 50.0}


def piezo_stack_step(n: int = 6, t_end: float = 4.0e-5, name: str = "piezo_stack_step", **params) -> str:
    """A stack of ``n`` massless piezo discs (each ``k_P, delta_P, C_P`` and its electrode resistance
    ``R``) switched onto a supply ``U`` at t = 0, driving a load mass ``M`` pulled by ``F``.

    Weber Bild 38 reduced by hand: the stack is one element with ``n·k_P, n·delta_P, n·C_P, R/n``.
    Its electrical modes decay with ``|λ| ≈ 1/(R·C_blocked) = 4e7 1/s`` within a microsecond, the
    load oscillates at ``1.8e5 rad/s``: DOP853 at rtol 1e-10 would be held to its stability limit
    (about 270 steps where the tolerance asks for about 70) and its dense output is then wrong by
    thousands of tolerances; ``auto`` must take an implicit method.
    """
    p = {**_STACK, **params}
    return f"""name: {name}
description: >
  Stack of {n} massless piezo discs switched onto a voltage supply, driving a load mass: electrical
  modes of 4e7 1/s that die out in a microsecond next to a mechanical mode of 1.8e5 rad/s.
parameters: {_params(p)}
elements:
  piezo:  {{type: piezo_stack, n: {n}, k_P: k_P, delta_P: delta_P, C_P: C_P, m: 0.0, R: R}}
  base:   {{type: ground, domain: translational}}
  supply: {{type: voltage_source, value: "U*step(t)"}}
  gnd:    {{type: ground, domain: electrical}}
  load:   {{type: mass, m: M}}
  pull:   {{type: force_source, value: F}}
connections:
  - [base.p, piezo.mech_a]
  - [supply.p, piezo.elec_a]
  - [supply.n, piezo.elec_b, gnd.p]
  - [piezo.mech_b, load.a]
  - [load.b, pull.p]
outputs: [piezo.stroke, piezo.force, piezo.charge, piezo.voltage, piezo.current]
simulate: {{t_end: {t_end:.6e}, dt_out: {t_end / 1000:.6e}, solver: auto, rtol: 1.0e-10, atol: 1.0e-20}}
bench: false
"""


# -------------------------------------------------------------------------------------------------

#: file name in diagrams/hard/ -> YAML text
def _hard() -> dict:
    return {
        "stiff_drive_train.yaml": stiff_drive_train(),
        "mathieu.yaml": mathieu_oscillator(),
        "stick_slip.yaml": stick_slip(),
        "slack_rope.yaml": slack_rope(),
        "slider_crank.yaml": slider_crank(),
        "two_mass_long.yaml": two_mass_oscillator(periods=1.0e4, name="two_mass_long", bench=False),
        "two_mass_oscillator.yaml": two_mass_oscillator(),
        "differentiated_step.yaml": differentiated_step(),
        "nonlinear_loop.yaml": nonlinear_loop(),
        "piezo_stack_step.yaml": piezo_stack_step(),
    }


HARD_SCENES = _hard()


def drive_train() -> str:
    """Bench scene ``diagrams/drive_train.yaml``: motor (torque ramp to 10 N·m), ideal gear ``i``,
    elastic shaft ``c_shaft`` [N·m/rad] with damping, load inertia on a damped bearing."""
    return """\
name: drive_train
description: Motor -> ideal gear -> elastic shaft -> load, with shaft and bearing damping
parameters: {i: 3.0, c_shaft: 2000.0}
elements:
  motor:   {type: torque_source, value: "10*(1 - exp(-t/0.05))"}
  rotor:   {type: inertia, J: 2.0e-3}
  gear:    {type: ideal_gear, i: i}
  shaft:   {type: spring, c: c_shaft}
  shaft_d: {type: damper, d: 0.5}
  load:    {type: inertia, J: 0.5}
  bearing: {type: damper, d: 0.8}
  housing: {type: ground}
connections:
  - [motor.p, rotor.a]
  - [rotor.b, gear.a]
  - [gear.b, shaft.a, shaft_d.a]
  - [shaft.b, shaft_d.b, load.a]
  - [load.b, bearing.a]
  - [bearing.b, housing.p]
outputs: [rotor.omega, load.omega, shaft.force]
simulate: {t_end: 2.0, dt_out: 0.002, solver: auto, rtol: 1.0e-8}
reference: {kind: tight, hand_model: drive_train}
bench: true
"""


def rlc_series() -> str:
    """Bench scene ``diagrams/rlc_series.yaml``: series RLC circuit (10 Ω, 0.1 H, 100 µF) driven by
    a ``V`` [V] step."""
    return """\
name: rlc_series
description: Series RLC circuit driven by a 12 V step; capacitor voltage and loop current
parameters: {V: 12.0}
elements:
  supply: {type: voltage_source, value: "V*step(t)"}
  R1:     {type: resistor, R: 10.0}
  L1:     {type: inductor, L: 0.1}
  C1:     {type: capacitor, C: 1.0e-4}
  gnd:    {type: ground, domain: electrical}
connections:
  - [supply.p, R1.a]
  - [R1.b, L1.a]
  - [L1.b, C1.a]
  - [C1.b, supply.n, gnd.p]
outputs: [C1.v, L1.i]
simulate: {t_end: 0.1, dt_out: 1.0e-4, rtol: 1.0e-9, atol: 1.0e-12}
reference: {kind: tight, hand_model: rlc_series}
bench: true
"""


#: path under diagrams/ -> YAML text of every scene written from this module
SCENE_FILES: dict = {"drive_train.yaml": drive_train(), "rlc_series.yaml": rlc_series(),
                     **{f"hard/{name}": text for name, text in HARD_SCENES.items()}}


def bench_scenes() -> list:
    """``(name, yaml_text)`` of the scenes this module offers ``multipole bench`` (registered in the
    entry point group ``multipole.bench_scenes``; the bench keeps those tagged ``bench: true``)."""
    return list(SCENE_FILES.items())

#: scene name (or its start) -> factory(parameters of the scene) of a hand-written model
HAND_MODELS: dict = {
    "two_mass_oscillator": _two_mass_hand,
    "stiff_drive_train": _stiff_hand,
    "drive_train": _drive_train_hand,
    "rlc_series": _rlc_hand,
    "mathieu": _mathieu_hand,
    "nonlinear_loop": _loop_hand,
    "slack_rope": _slack_rope_hand,
    "slider_crank": _slider_crank_hand,
    "stick_slip": _stick_slip_hand,
}


def hand_model(scene) -> HandModel | None:
    """The hand-written model a loaded scene names in ``reference: {hand_model: KEY}`` (a key of
    :data:`HAND_MODELS`, or ``mass_spring_chain``, whose length is the number of masses in the
    scene); ``None`` if the scene names none or a key this module does not know."""
    key = (scene.reference or {}).get("hand_model")
    if not isinstance(key, str) or (key != "mass_spring_chain" and key not in HAND_MODELS):
        return None                  # another entry's scene (its parameters may be formulas)
    params = {k: float(v) for k, v in scene.network.params.items()}
    if key == "mass_spring_chain":
        return _chain_hand(params, sum(t == "mass" for t in scene.element_types.values()))
    factory = HAND_MODELS.get(key) if isinstance(key, str) else None
    return factory(params) if factory else None
