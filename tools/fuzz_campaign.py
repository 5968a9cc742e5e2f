"""Fuzzing: generated and mutated netlists through the CLI; only the project's own errors, never a traceback.

    python tools/fuzz_campaign.py --check 10000 --simulate 1000 --equations 1000 -o fuzz_out

Every case is a netlist written to a file and run through ``multipole.cli.main([verb, path, ...])``
in-process, in a worker subprocess with a memory cap (``resource.setrlimit(RLIMIT_AS)``) and a time
cap per case (``signal.setitimer``; the parent restarts a worker that does not answer).  A case
passes when ``main`` returns 0, 1, 2 or 3, prints no traceback, and an exit 2 or 3 comes with
exactly one ``error[...]`` line on stderr and nothing before it there.  Failures are counted by
class (traceback, hang, wrong exit code, stray output, worker killed) and written to the output
folder (``<class>-<verb>-<case>.yaml`` plus ``.txt`` with what was printed), so each can be
re-run with ``multipole VERB FILE``.

Half of the cases are *generated* (random element types from the catalogue, random parameters of
every kind, random connections, outputs and simulate options; every other one a chain that is
well-posed by construction with random source and law expressions, so that runs happen), half
*mutated* (the scenes in
``diagrams/`` with random deletions, type swaps, values replaced by strings, lists, mappings,
huge/NaN/negative numbers and unicode, and text-level damage: YAML tags, duplicated keys, deep
nesting, alias bombs, bad bytes).  Case ``k`` of a seed is always the same netlist.

``tests/test_fuzz.py`` runs the same generator at a size for the test suite; docs/testing.md has
the counts of the last campaign.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import signal
import sys
import time
import traceback
from collections import Counter
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
VERBS = ("check", "simulate", "equations", "linearize", "diagram")
EXIT_CODES = (0, 1, 2, 3)
T_END = 0.002                     # simulate: the horizon, or the scene's own if that is shorter
EXTRA_ARGS = {"diagram": ["-o", "fuzz_diagram.svg"]}   # diagram writes in the working folder
NON_FINITE = re.compile(r"= -?(nan|inf)\b")       # a final value printed by simulate


class CaseTimeout(BaseException):
    """Raised by the alarm inside a case (a BaseException, so no ``except Exception`` swallows it)."""


# -- generated netlists ----------------------------------------------------------------------------

def pick(rng, items):
    """One of ``items`` as the Python object itself (numpy's choice would make arrays of mixed lists)."""
    items = list(items)
    return items[int(rng.integers(len(items)))]


FUNCS = ["sin", "cos", "exp", "sqrt", "tanh", "atan", "abs", "step", "ramp", "log", "sign"]
DOMAINS = ("rotational", "translational", "electrical")
AWKWARD = 0.04        # share of awkward values (NaN, inf, huge, tiny, strings) where a number is expected


def number(rng, positive=False):
    """A number as engineers write them; with probability AWKWARD an awkward one."""
    r = rng.random()
    if r < AWKWARD:
        return pick(rng, [0.0, -1.0, 1e308, 1e-308, float("nan"), float("inf"), 5e-324, "1e-3", "1.0e9", "-0.0",
                          ".5", "abc", 10 ** 40])
    if r < 0.15:
        return int(rng.integers(1, 100)) if positive else int(rng.integers(-3, 100))
    x = float(10 ** rng.uniform(-4, 4))
    x = x if positive or rng.random() < 0.8 else -x
    return round(x, int(rng.integers(1, 8))) if rng.random() < 0.5 else x


def magnitude(rng, lo=-4.0, hi=4.0) -> float:
    """A positive float, log-uniform between 10**lo and 10**hi."""
    return float(10 ** rng.uniform(lo, hi))


def expression(rng, var="t", depth=0):
    """A random expression of ``var`` from the documented grammar (sometimes of t or pi only)."""
    r = rng.random()
    if depth > 2 or r < 0.3:
        return str(pick(rng, [var, var, "t", "pi", f"{number(rng, True)}"]))
    if r < 0.6:
        fn = pick(rng, FUNCS)
        arg = expression(rng, var, depth + 1)
        return f"{fn}({arg})" if fn not in ("step", "ramp") else f"{fn}({arg} - {rng.uniform(0, 0.01):.4f})"
    op = pick(rng, ["+", "-", "*", "/", "**"])
    rhs = expression(rng, var, depth + 1) if op != "**" else str(rng.integers(0, 4))
    return f"({expression(rng, var, depth + 1)} {op} {rhs})"


#: element types whose ports all belong to one fixed domain
FIXED_DOMAIN = {"inertia": "rotational", "torque_source": "rotational", "speed_source": "rotational",
                "ideal_gear": "rotational", "spur_stage": "rotational", "gear_train": "rotational",
                "planetary": "rotational", "mass": "translational", "force_source": "translational",
                "velocity_source": "translational", "resistor": "electrical", "capacitor": "electrical",
                "inductor": "electrical", "voltage_source": "electrical", "current_source": "electrical"}


def ports_with_domains(et, params) -> list:
    """(port, domain) of an element type for the given parameters (templates expanded)."""
    def default(name):
        return params.get(name, et.param(name).default if et.param(name) else "rotational")
    out = []
    for key in et.ports:
        if key == "<ports>":
            out += [(name, default("domain")) for name in params.get("ports") or []]
        elif key in ("a1..an", "b1..bm"):
            doms = params.get("domains_a" if key[0] == "a" else "domains_b") or []
            out += [(f"{key[0]}{k + 1}", d) for k, d in enumerate(doms)]
        elif key == "p1..pn":
            out += [(f"p{k + 1}", d) for k, d in enumerate(params.get("domains") or [])]
        elif et.name in FIXED_DOMAIN:
            out.append((key, FIXED_DOMAIN[et.name]))
        elif et.name == "dc_motor":
            out.append((key, "rotational" if key == "shaft" else "electrical"))
        elif et.name.startswith("piezo"):
            out.append((key, "translational" if key.startswith("mech") else "electrical"))
        elif et.name in ("TF", "GY"):
            out.append((key, default(f"domain_{key}")))
        else:
            out.append((key, default("domain")))
    return out


def parameter(rng, p, given, scene_params):
    """A random value for parameter ``p``, mostly valid for its kind (``given``: the element's so far)."""
    if p.kind == "choice":
        return str(pick(rng, [c for c in p.choices if c != "hydraulic"])) if rng.random() > AWKWARD else "nonsense"
    if p.kind == "bool":
        return bool(rng.random() < 0.5)
    if p.kind == "time":
        return expression(rng, "t") if rng.random() < 0.8 else number(rng)
    if p.kind == "law":
        return expression(rng, p.law_var or "t") if rng.random() < 0.6 else number(rng, True)
    if p.name == "ports":
        return [f"x{k}" for k in range(int(rng.integers(2, 5)))]
    if p.name == "signs":
        return [int(pick(rng, [1, -1])) for _ in given.get("ports", [])]
    if p.name in ("domains_a", "domains_b", "domains"):
        matrix = given.get("matrix") or given.get("compliance") or [[1]]
        count = len(matrix[0]) if p.name == "domains_b" else len(matrix)
        return [str(pick(rng, DOMAINS)) for _ in range(count)]
    if p.name == "q0" and p.kind == "numbers":
        matrix = given.get("matrix") or given.get("compliance") or [[1]]
        return [number(rng) for _ in range(len(matrix[0]))]
    if p.kind == "numbers":
        return [number(rng, True) for _ in range(int(rng.integers(1, 4)))]
    if p.kind == "matrix":
        n = int(rng.integers(1, 3))
        if p.name == "compliance":                   # symmetric, diagonally dominant
            off = [[0.1 * magnitude(rng, -2, 0) for _ in range(n)] for _ in range(n)]
            return [[(off[i][j] + off[j][i]) / 2 if i != j else 1.0 + magnitude(rng, -2, 1) for j in range(n)]
                    for i in range(n)]
        m = int(rng.integers(1, 3))
        q = [f"q{k + 1}" for k in range(m)]
        return [[number(rng) if rng.random() < 0.7 else expression(rng, str(pick(rng, q))) for _ in range(m)]
                for _ in range(n)]
    if rng.random() < 0.1 and scene_params:
        return str(pick(rng, list(scene_params)))    # a scene parameter's name
    return number(rng, p.positive)


def element(rng, et, scene_params) -> dict:
    """Parameters of one element of type ``et``: the required ones, some optional ones, and the
    combinations the element documents (one of a group, a gear stage's level, a planetary's form)."""
    groups = {g for group in et.one_of for g in group}
    chosen = {str(pick(rng, group)) for group in et.one_of}
    given = {}
    for p in et.params:
        if p.name in groups and p.name not in chosen:
            continue
        if p.required or p.name in chosen or rng.random() < 0.3:
            given[p.name] = parameter(rng, p, given, scene_params)
    if et.name == "spur_stage" and rng.random() > AWKWARD:
        level = str(pick(rng, ["ideal", "elastic", "normal"]))
        given = {k: v for k, v in given.items() if k in ("r1", "r2", "internal", "z1", "phase0")}
        given["level"] = level
        if level == "elastic":
            given["c"] = magnitude(rng, 4, 9) if rng.random() < 0.7 else "1e5*(1 + 0.2*cos(q))"
            given.update({k: number(rng, True) for k in ("d", "x0") if rng.random() < 0.3})
        if level == "normal":
            given.update(c_n=magnitude(rng, 4, 9), z1=int(rng.integers(10, 40)), mu=0.05)
        if given.get("internal"):
            given["r2"] = 3 * given["r1"] if isinstance(given["r1"], (int, float)) else given["r2"]
    if et.name == "gear_train" and rng.random() > AWKWARD:
        n = int(rng.integers(1, 4))
        given = {"r1": [number(rng, True) for _ in range(n)], "r2": [number(rng, True) for _ in range(n)]}
        if rng.random() < 0.5:
            given.update(level="elastic", c=magnitude(rng, 4, 9))
            if rng.random() < 0.5:
                given["J"] = [number(rng, True) for _ in range(n - 1)]
    if et.name == "planetary" and rng.random() > AWKWARD:
        keep = {k: v for k, v in given.items() if k in ("c", "d", "J_p", "module")}
        if rng.random() < 0.5:
            z = int(rng.integers(10, 40))
            given = {"z_sun": z, "z_ring": z + 2 * int(rng.integers(2, 30)), **keep}
        else:
            given = {f"r{k}": number(rng, True) for k in range(1, 5)} | keep
    if et.name == "piezo_stack" and rng.random() > AWKWARD:
        given["n"] = int(rng.integers(1, 4))
    return given


def generated_netlist(rng) -> dict:
    """A random scene: 1-7 catalogue elements with random parameters, ports joined mostly within
    their domain, random outputs and (sometimes) simulate options."""
    from multipole import catalogue
    types = catalogue()
    names = sorted(types)
    scene_params = {f"p{k}": number(rng, True) for k in range(int(rng.integers(0, 3)))}
    elements, by_domain = {}, {}
    for k in range(int(rng.integers(1, 8))):
        et = types[str(pick(rng, names))]
        given = element(rng, et, scene_params)
        elements[f"e{k}"] = {"type": et.name, **given}
        for port, dom in ports_with_domains(et, given):
            by_domain.setdefault(dom if rng.random() > AWKWARD else "any", []).append(f"e{k}.{port}")
    connections = []
    for ports in by_domain.values():
        rng.shuffle(ports)
        while len(ports) >= 2 and rng.random() < 0.9:
            size = 2 if rng.random() < 0.8 else 3
            connections.append([ports.pop() for _ in range(min(size, len(ports)))])
    rng.shuffle(connections)
    if connections and rng.random() < AWKWARD:
        connections.append([connections[0][0], connections[-1][-1]])     # a port used twice
    outputs = []
    for name, params in elements.items():
        quantities = [q for q in types[params["type"]].quantities if "<" not in q and ".." not in q]
        if quantities and rng.random() < 0.7:
            outputs.append(f"{name}.{pick(rng, quantities)}")
    doc = {"name": f"fuzz_{int(rng.integers(1 << 30))}", "elements": elements, "connections": connections}
    if scene_params:
        doc["parameters"] = scene_params
    if outputs:
        doc["outputs"] = outputs
    if rng.random() < 0.5:
        doc["simulate"] = {"t_end": 0.002, "dt_out": 0.001}
    return doc


# -- mutated netlists ------------------------------------------------------------------------------

def scene_files() -> list:
    return sorted(p for p in (ROOT / "diagrams").rglob("*.yaml"))


def _nodes(tree, path=()):
    """Every (path, value) of a YAML tree."""
    yield path, tree
    if isinstance(tree, dict):
        for k, v in tree.items():
            yield from _nodes(v, path + (k,))
    elif isinstance(tree, list):
        for k, v in enumerate(tree):
            yield from _nodes(v, path + (k,))


def _set(tree, path, value):
    for key in path[:-1]:
        tree = tree[key]
    tree[path[-1]] = value


def _delete(tree, path):
    for key in path[:-1]:
        tree = tree[key]
    del tree[path[-1]]


def replacement(rng):
    """A value of the wrong kind, size or sign."""
    return pick(rng, [
        "abc", "", " ", "é€ü", "日本", "\u202e", "t", "q", "nan", "inf", "-inf", "1e999", "1/0", "0**-1",
        "sqrt(-1)", "log(-2)", "(-8)**(1/3)", "x" * 300, "9" * 400, "(" * 60 + "1" + ")" * 60,
        "__import__('os')", "t.__class__", "exp(1000)", "acos(2)", "gamma(t)", "sign(f)", "1/t", "step(t)*1e300",
        [], [1, 2], [[1]], {}, {"a": 1}, None, True, False,
        0, -1, -1e-9, 1e-320, 1e308, -1e308, float("nan"), float("inf"), -float("inf"), 10 ** 30, -(10 ** 20),
        "$name", "a.b.c", "e0.a",
    ])


def mutate_tree(rng, tree):
    """One random structural mutation of a parsed scene (in place)."""
    from multipole import catalogue
    nodes = [(p, v) for p, v in _nodes(tree) if p]
    path, value = nodes[int(rng.integers(len(nodes)))]
    r = rng.random()
    if r < 0.2:
        _delete(tree, path)
    elif r < 0.35 and isinstance(tree.get("elements"), dict) and tree["elements"]:
        name = str(pick(rng, list(tree["elements"])))
        if isinstance(tree["elements"][name], dict):
            tree["elements"][name]["type"] = str(pick(rng, sorted(catalogue())))
    elif r < 0.45 and isinstance(tree.get("simulate"), dict):
        key = str(pick(rng, ["t_end", "dt_out", "rtol", "atol", "max_step", "solver", "backend"]))
        tree["simulate"][key] = replacement(rng)
    elif r < 0.55 and isinstance(tree.get("connections"), list) and tree["connections"]:
        k = int(rng.integers(len(tree["connections"])))
        other = tree["connections"][int(rng.integers(len(tree["connections"])))]
        if isinstance(tree["connections"][k], list) and isinstance(other, list) and other:
            tree["connections"][k] = list(tree["connections"][k]) + [other[0]]
    elif r < 0.62 and isinstance(value, (int, float)) and not isinstance(value, bool):
        _set(tree, path, value * float(pick(rng, [-1, 0, 1e300, 1e-300, 10 ** float(rng.uniform(-20, 20))])))
    else:
        _set(tree, path, replacement(rng))


def mutate_text(rng, text: str) -> str | bytes:
    """Damage at the YAML level (what a parsed tree cannot express)."""
    lines = text.splitlines()
    r = rng.random()
    k = int(rng.integers(len(lines))) if lines else 0
    if r < 0.15:                                      # a duplicated line (duplicated key)
        return "\n".join(lines[:k + 1] + lines[k:]) + "\n"
    if r < 0.3:                                       # a YAML tag on a value
        tag = str(pick(rng, ["!!timestamp", "!!int", "!!float", "!!bool", "!!binary", "!!set", "!!omap",
                              "!!python/object:os.system", "!!python/name:os.system", "!custom"]))
        return "\n".join(line.replace(": ", f": {tag} ", 1) if i == k else line for i, line in enumerate(lines)) + "\n"
    if r < 0.4:                                       # deep nesting
        depth = int(rng.integers(50, 3000))
        return text + f"description: {'[' * depth}1{']' * depth}\n"
    if r < 0.5:                                       # an alias bomb used in a name
        levels = int(rng.integers(3, 10))
        bomb = ["bomb:", '  l0: &l0 "laugh"']
        for i in range(1, levels):
            bomb.append(f"  l{i}: &l{i} [{', '.join(['*l' + str(i - 1)] * 9)}]")
        return "\n".join(bomb) + f"\nname: *l{levels - 1}\n" + text
    if r < 0.6:                                       # bytes that are not UTF-8, control characters, tabs
        raw = text.encode()
        pos = int(rng.integers(len(raw) + 1))
        return raw[:pos] + bytes(pick(rng, [b"\xff\xfe", b"\x00", b"\t", b"\x1b[2J", b"\xc3("])) + raw[pos:]
    if r < 0.7:                                       # a truncated file
        return text[:int(rng.integers(len(text) + 1))]
    if r < 0.8:                                       # a huge integer
        return text.replace("1.0", "1" + "0" * int(rng.integers(20, 6000)), 1)
    if r < 0.9:                                       # a parameter cycle / self reference
        return text + "parameters: {a: b, b: a}\n" if "parameters:" not in text else \
            text.replace("parameters:", "parameters: {cyc1: cyc2, cyc2: cyc1*2}\nparameters_old:", 1)
    return "\n".join(lines[:k] + lines[k + 1:]) + "\n"   # a deleted line


def mutated_netlist(rng, files=None) -> str | bytes:
    """A scene from diagrams/ with 1-3 structural mutations and, sometimes, text-level damage."""
    files = files or scene_files()
    path = files[int(rng.integers(len(files)))]
    text = path.read_text()
    tree = yaml.safe_load(text)
    if isinstance(tree, dict) and rng.random() < 0.8:
        for _ in range(int(rng.integers(1, 4))):
            if not tree:
                break
            mutate_tree(rng, tree)
        text = yaml.safe_dump(tree, sort_keys=False, allow_unicode=bool(rng.random() < 0.5))
    if rng.random() < 0.4:
        return mutate_text(rng, text)
    return text


def chain_netlist(rng) -> dict:
    """A scene that is well-posed by construction, so that ``simulate`` runs it: a mechanical chain
    (a torque or force source, bodies joined by springs, dampers with a random law, gears) or a
    series circuit (a voltage source, R, L, C, a DC motor on an inertia), with random expressions in
    the sources and laws, so that the run-time failures (1/t, sqrt of a negative number, exp(1000),
    a law log(f)) are reached."""
    elements, connections = {}, []
    if rng.random() < 0.6:
        rot = rng.random() < 0.6
        dom = "rotational" if rot else "translational"
        body = ("inertia", "J") if rot else ("mass", "m")
        elements["src"] = {"type": "torque_source" if rot else "force_source", "value": expression(rng, "t")}
        prev = "src.p"
        for k in range(int(rng.integers(1, 4))):
            elements[f"b{k}"] = {"type": body[0], body[1]: magnitude(rng, -3, 1)}
            connections.append([prev, f"b{k}.a"])
            kind = pick(rng, ["spring", "damper", "law", "gear", "spur"] if rot else ["spring", "damper", "law"])
            name = f"c{k}"
            if kind == "spring":
                elements[name] = {"type": "spring", "c": magnitude(rng, 0, 6), "domain": dom}
            elif kind == "damper":
                elements[name] = {"type": "damper", "d": magnitude(rng, -2, 2), "domain": dom}
            elif kind == "law":
                elements[name] = {"type": "damper", "law": expression(rng, "f"), "domain": dom}
            elif kind == "gear":
                elements[name] = {"type": "ideal_gear", "i": number(rng)}
            else:
                elements[name] = {"type": "spur_stage", "r1": magnitude(rng, -2, -1), "r2": magnitude(rng, -2, -1),
                                  "level": "elastic", "c": magnitude(rng, 5, 8)}
            connections.append([f"b{k}.b", f"{name}.a"])
            prev = f"{name}.b"
        if rng.random() < 0.5:
            elements["end"] = {"type": body[0], body[1]: magnitude(rng, -3, 1)}
            connections.append([prev, "end.a"])
        outputs = [f"{n}.{'omega' if rot else 'v'}" for n, e in elements.items() if e["type"] == body[0]]
    else:
        elements["src"] = {"type": "voltage_source", "value": expression(rng, "t")}
        elements["gnd"] = {"type": "ground", "domain": "electrical"}
        prev = "src.p"
        parts = [str(pick(rng, ["R", "L", "C", "motor"])) for _ in range(int(rng.integers(1, 4)))]
        for k, part in enumerate(parts):
            name = f"{part}{k}"
            if part == "R":
                elements[name] = {"type": "resistor", "R": magnitude(rng, -2, 3)}
            elif part == "L":
                elements[name] = {"type": "inductor", "L": magnitude(rng, -5, 0)}
            elif part == "C":
                elements[name] = {"type": "capacitor", "C": magnitude(rng, -7, -2)}
            else:
                elements[name] = {"type": "dc_motor", "k": magnitude(rng, -3, 0), "R": magnitude(rng, -1, 1),
                                  "L": magnitude(rng, -4, -2), "J": magnitude(rng, -5, -3), "grounded": False}
                elements[f"load{k}"] = {"type": "damper", "law": expression(rng, "f")}
                connections.append([f"{name}.shaft", f"load{k}.a"])
                connections.append([prev, f"{name}.elec"])
                prev = f"{name}.elec_n"
                continue
            connections.append([prev, f"{name}.a"])
            prev = f"{name}.b"
        connections.append([prev, "src.n", "gnd.p"])
        outputs = ["src.i"]
    return {"name": f"chain_{int(rng.integers(1 << 30))}", "elements": elements, "connections": connections,
            "outputs": outputs}


def netlist(seed: int, index: int, files=None) -> str | bytes:
    """Case ``index`` of ``seed``: odd cases mutated, even cases generated (every other one a chain
    that is well-posed by construction)."""
    rng = np.random.default_rng([seed, index])
    if index % 2:
        return mutated_netlist(rng, files)
    doc = chain_netlist(rng) if index % 4 == 2 else generated_netlist(rng)
    return yaml.safe_dump(doc, sort_keys=False, allow_unicode=True)


# -- running one case ------------------------------------------------------------------------------

def simulate_args(path: str) -> list:
    """``--t-end`` T_END or the scene's own ``t_end`` if shorter (a fuzzed run must not be made longer
    than the scene asks), and ``--dt-out`` half of it."""
    t_end = T_END
    try:
        if os.path.getsize(path) < 1 << 16:
            with open(path, encoding="utf-8") as fh:
                own = yaml.safe_load(fh)["simulate"]["t_end"]
            if isinstance(own, (int, float)) and 0 < own < T_END:
                t_end = float(own)
    except Exception:                  # noqa: BLE001 - any damage: the default horizon
        pass
    return ["--t-end", repr(t_end), "--dt-out", repr(t_end / 2), "--quiet"]


def _alarm(signum, frame):
    raise CaseTimeout()


def run_case(verb: str, path: str, time_cap: float = 20.0) -> tuple[str, int | None, str]:
    """Run ``multipole VERB PATH`` in this process: (outcome, exit code, what was printed).

    Outcomes: ``ok``; ``traceback`` (an exception escaped ``main``), ``hang`` (over ``time_cap``
    seconds), ``exit_code`` (not 0-3), ``output`` (exit 2/3 without exactly one error line on stderr,
    or anything before it there, or a traceback printed), ``wrong_result`` (simulate exit 0 with a
    non-finite final value)."""
    from multipole.cli import main
    args = [verb, path] + (simulate_args(path) if verb == "simulate" else EXTRA_ARGS.get(verb, []))
    out, err = io.StringIO(), io.StringIO()
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, time_cap)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(args)
    except CaseTimeout:
        return "hang", None, out.getvalue() + err.getvalue()
    except BaseException:                              # noqa: BLE001 - what we are hunting
        return "traceback", None, out.getvalue() + err.getvalue() + traceback.format_exc()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    printed = out.getvalue() + err.getvalue()
    if code not in EXIT_CODES:
        return "exit_code", code, printed
    if "Traceback (most recent call last)" in printed:
        return "output", code, printed
    if code in (2, 3):
        lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
        errors = [ln for ln in lines if ln.startswith("error[")]
        if len(errors) != 1 or lines[0] != errors[0]:
            return "output", code, printed
    if verb == "simulate" and code == 0 and NON_FINITE.search(out.getvalue()):
        return "wrong_result", code, printed
    return "ok", code, printed


# -- the campaign: worker subprocesses with time and memory caps -----------------------------------

def _worker(conn, memory_mb: int, time_cap: float, folder: str):
    import resource
    signal.signal(signal.SIGINT, signal.SIG_IGN)          # Ctrl-C stops the parent, which stops us
    limit = memory_mb * 1024 * 1024
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    os.environ.setdefault("MULTIPOLE_CACHE", "off")
    os.chdir(folder)
    import multipole.cli  # noqa: F401  (import before the first case, outside its time cap)
    from multipole import catalogue
    catalogue()
    files = scene_files()
    while True:
        job = conn.recv()
        if job is None:
            return
        verb, seed, index = job
        data = netlist(seed, index, files)
        path = os.path.join(folder, f"case{index}.yaml")
        with open(path, "wb") as fh:
            fh.write(data if isinstance(data, bytes) else data.encode())
        outcome, code, printed = run_case(verb, path, time_cap)
        conn.send((outcome, code, printed[-4000:]))


class Worker:
    """A worker subprocess (spawned, so it starts clean) running one case at a time."""

    def __init__(self, memory_mb, time_cap, folder):
        import multiprocessing as mp
        ctx = mp.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child, memory_mb, time_cap, folder), daemon=True)
        self.proc.start()
        self.job, self.deadline = None, 0.0

    def stop(self):
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join(5)


OUTCOMES = ("ok", "traceback", "hang", "exit_code", "output", "wrong_result", "killed")


def campaign(counts: dict, seed: int, out: Path, memory_mb: int, time_cap: float, workers: int = 1) -> Counter:
    """Run ``counts[verb]`` cases per verb on ``workers`` subprocesses; print and return the tally."""
    out.mkdir(parents=True, exist_ok=True)
    # verbs interleaved in proportion, so a campaign stopped early (Ctrl-C) has covered each of them
    jobs = sorted(((verb, index) for verb, n in counts.items() for index in range(n)),
                  key=lambda job: ((job[1] + 0.5) / counts[job[0]], job[0]), reverse=True)
    tally, exits = Counter(), Counter()
    pool = []
    for k in range(workers):
        (out / f"work{k}").mkdir(exist_ok=True)
        pool.append(Worker(memory_mb, time_cap, str(out / f"work{k}")))
    start, done, files = time.time(), 0, scene_files()

    def record(verb, index, outcome, code, printed):
        nonlocal done
        done += 1
        tally[(verb, outcome)] += 1
        exits[(verb, code)] += 1
        if outcome != "ok":
            data = netlist(seed, index, files)
            stem = out / f"{outcome}-{verb}-{index}"
            stem.with_suffix(".yaml").write_bytes(data if isinstance(data, bytes) else data.encode())
            stem.with_suffix(".txt").write_text(printed)
        if done % 500 == 0:
            bad = sum(v for (vb, o), v in tally.items() if o != "ok")
            print(f"{done}/{sum(counts.values())} cases, {time.time() - start:.0f} s, {bad} failures", flush=True)

    try:
        _drive(pool, jobs, record, seed, memory_mb, time_cap, out)
    except KeyboardInterrupt:
        print("interrupted: the counts below are the cases run so far")
    for w in pool:
        if w.job is None and w.proc.is_alive():
            w.conn.send(None)
        w.stop()
    lines = [f"{'verb':<10} {'cases':>6} " + " ".join(f"{o:>12}" for o in OUTCOMES) + "   exit codes"]
    for verb in counts:
        codes = ", ".join(f"{c}: {k}" for (vb, c), k in sorted(exits.items(), key=lambda i: str(i[0][1]))
                          if vb == verb)
        ran = sum(k for (vb, o), k in tally.items() if vb == verb)
        lines.append(f"{verb:<10} {ran:>6} " + " ".join(f"{tally[(verb, o)]:>12}" for o in OUTCOMES) + f"   {codes}")
    lines.append(f"seed {seed}, wall time {time.time() - start:.0f} s with {workers} worker(s), memory cap "
                 f"{memory_mb} MB, time cap {time_cap:g} s per case; failing inputs in {out}")
    print("\n" + "\n".join(lines))
    (out / "summary.txt").write_text("\n".join(lines) + "\n")
    return tally


def _drive(pool, jobs, record, seed, memory_mb, time_cap, out):
    """Hand out jobs to idle workers, collect answers, replace workers that die or stop answering."""
    from multiprocessing.connection import wait
    while jobs or any(w.job for w in pool):
        for k, w in enumerate(pool):
            if w.job is None and jobs:
                w.job = jobs.pop()
                w.deadline = time.time() + time_cap + 60      # the worker's own alarm fires first
                w.conn.send((w.job[0], seed, w.job[1]))
        busy = [w for w in pool if w.job]
        ready = wait([w.conn for w in busy], timeout=5)
        for k, w in enumerate(pool):
            if not w.job:
                continue
            if w.conn in ready:
                try:
                    record(*w.job, *w.conn.recv())
                    w.job = None
                    continue
                except EOFError:
                    record(*w.job, "killed", None, f"worker died, exit code {w.proc.exitcode}")
            elif time.time() > w.deadline:
                record(*w.job, "hang", None, "no answer from the worker (its alarm did not fire)")
            else:
                continue
            w.stop()
            pool[k] = Worker(memory_mb, time_cap, str(out / f"work{k}"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", type=int, default=10_000, help="netlists through check")
    ap.add_argument("--simulate", type=int, default=1_000, help="netlists through simulate (short horizon)")
    ap.add_argument("--equations", type=int, default=1_000, help="netlists through equations")
    ap.add_argument("--linearize", type=int, default=0, help="netlists through linearize")
    ap.add_argument("--diagram", type=int, default=0, help="netlists through diagram (an SVG in the worker's folder)")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--memory-mb", type=int, default=3000, help="address-space cap of the worker")
    ap.add_argument("--time-cap", type=float, default=30.0, help="seconds per case")
    ap.add_argument("--workers", type=int, default=1, help="worker subprocesses")
    ap.add_argument("-o", "--output", default="fuzz_out", help="folder for failing inputs")
    args = ap.parse_args(argv)
    counts = {verb: getattr(args, verb) for verb in VERBS}
    tally = campaign({v: n for v, n in counts.items() if n}, args.seed, Path(args.output), args.memory_mb,
                     args.time_cap, args.workers)
    return 0 if all(o == "ok" for (v, o) in tally.elements()) else 1


if __name__ == "__main__":
    sys.exit(main())
