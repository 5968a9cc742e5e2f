"""YAML netlists (DESIGN §5): untrusted text in, a :class:`Scene` out.

* YAML is read with a loader derived from ``yaml.SafeLoader`` that only adds line numbers (no
  Python object tags, duplicate keys refused).
* Every formula goes through :func:`multipole.expressions.parse_expression` (a whitelist).
* Every error is a :class:`~multipole.errors.NetlistError` naming the file, line and element.

``overrides`` (the CLI's ``--set NAME=VALUE``) replace a scene parameter (``r1=0.03``) or an element
parameter (``mesh.c=1e9``) before anything is built.
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path

import sympy as sp
import yaml

from .catalogue import ElementType, catalogue
from .errors import MultipoleError, NetlistError
from .expressions import parse_expression
from .network import Network
from .primitives import LAW_F, LAW_P, LAW_Q, T, Primitive

_LAW_VARS = {"f": LAW_F, "q": LAW_Q, "p": LAW_P}
_TOP_KEYS = {"name", "description", "parameters", "elements", "connections", "outputs", "simulate",
             "expect_check", "bench", "prefer_state", "reference"}
_SIM_KEYS = {"t_end": float, "dt_out": float, "solver": str, "rtol": float, "atol": float,
             "max_step": float, "backend": str}
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class _Map(dict):
    line = 0
    lines: dict = {}


class _List(list):
    line = 0
    lines: list = []


class _Loader(yaml.SafeLoader):
    """SafeLoader that records the line of every mapping key and sequence item."""


def _construct_map(loader, node):
    loader.flatten_mapping(node)
    out = _Map()
    out.line, out.lines = node.start_mark.line + 1, {}
    for k_node, v_node in node.value:
        key = loader.construct_object(k_node, deep=True)
        if not isinstance(key, (str, int, float)):
            raise NetlistError("yaml_key", "keys must be plain names", where=f":{k_node.start_mark.line + 1}")
        if key in out:
            raise NetlistError("duplicate_key", f"key {key!r} appears twice", "keep one of them",
                               where=f":{k_node.start_mark.line + 1}")
        out[key] = loader.construct_object(v_node, deep=True)
        out.lines[key] = k_node.start_mark.line + 1
    return out


def _construct_seq(loader, node):
    out = _List(loader.construct_object(c, deep=True) for c in node.value)
    out.line, out.lines = node.start_mark.line + 1, [c.start_mark.line + 1 for c in node.value]
    return out


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_map)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_seq)


@dataclass
class Scene:
    """A loaded netlist: the root network plus what to simulate and show."""

    name: str
    description: str
    path: str
    network: Network
    outputs: list
    simulate: dict
    expect_check: int | None
    bench: bool
    digest: str
    output_lines: dict = field(default_factory=dict)
    element_lines: dict = field(default_factory=dict)
    element_types: dict = field(default_factory=dict)
    reference: dict = field(default_factory=dict)
    element_values: dict = field(default_factory=dict)   # element -> {parameter: text as written}, for messages

    def where(self, element: str = "", key: str = "") -> str:
        line = self.element_lines.get(element) or self.output_lines.get(key)
        text = f"{self.path}:{line}" if line else self.path
        return f"{text} element '{element}'" if element else text


def load(path, overrides=None) -> Scene:
    """Read a netlist file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise NetlistError("no_file", f"cannot read {path}: {exc.strerror}", "check the path") from None
    return loads(text, str(path), overrides)


def loads(text: str, filename: str = "<netlist>", overrides=None) -> Scene:
    """Read a netlist from text; ``filename`` is used in error messages."""
    try:
        data = yaml.load(text, Loader=_Loader)  # noqa: S506 — a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = f":{mark.line + 1}" if mark else ""
        raise NetlistError("yaml_syntax", f"invalid YAML: {exc.problem or exc.context}", "fix the YAML syntax",
                           f"{filename}{line}") from None
    except yaml.YAMLError as exc:
        raise NetlistError("yaml_syntax", f"invalid YAML: {exc}", "fix the YAML syntax", filename) from None
    except NetlistError as exc:          # raised while reading: ``where`` holds ":line"
        exc.where = filename + exc.where
        raise
    return _Builder(data, filename, dict(overrides or {})).scene(text)


def _resolve(params: dict) -> dict:
    """{Symbol: number} of the scene parameters (they may refer to each other; no cycles)."""
    values = {sp.Symbol(k): sp.sympify(v) for k, v in params.items()}
    for _ in range(len(values) + 1):
        values = {k: v.xreplace(values) for k, v in values.items()}
    return {k: v for k, v in values.items() if v.is_number}


class _Builder:
    def __init__(self, data, filename, overrides):
        self.data, self.file, self.overrides = data, filename, overrides
        self.used_overrides: set = set()
        self.numbers: dict = {}

    def err(self, code, message, fix="", line=None, element=""):
        where = f"{self.file}:{line}" if line else self.file
        if element:
            where += f" element '{element}'"
        return NetlistError(code, message, fix, where)

    def scene(self, text) -> Scene:
        d = self.data
        if not isinstance(d, dict):
            raise self.err("not_a_netlist", "the file is not a YAML mapping with 'elements' and 'connections'",
                           "start from a scene in diagrams/")
        for key in d:
            if key not in _TOP_KEYS:
                raise self.err("unknown_key", f"unknown top-level key {key!r}",
                               f"allowed: {', '.join(sorted(_TOP_KEYS))}", d.lines.get(key))
        if "elements" not in d or not isinstance(d["elements"], dict) or not d["elements"]:
            raise self.err("no_elements", "the netlist needs a non-empty 'elements' mapping", line=d.lines.get("elements"))
        params = self.parameters(d.get("parameters") or _Map())
        symbols = {name: sp.Symbol(name) for name in params}
        children, types, lines, texts = {}, {}, {}, {}
        for name, spec in d["elements"].items():
            line = d["elements"].lines.get(name)
            children[name], types[name] = self.element(name, spec, symbols, line)
            lines[name] = line
            texts[name] = {k: str(v) for k, v in spec.items() if k != "type"}
        unused = set(self.overrides) - self.used_overrides
        if unused:
            raise self.err("unknown_override", f"--set {sorted(unused)[0]}: no such scene or element parameter",
                           "use NAME=VALUE for a scene parameter or ELEMENT.PARAM=VALUE")
        connections = self.connections(d.get("connections") or _List(), children)
        outputs, out_lines = self.outputs(d)
        prefer = d.get("prefer_state") or []
        if not isinstance(prefer, list) or not all(isinstance(s, str) for s in prefer):
            raise self.err("bad_value", "prefer_state must be a list of state names such as crank.p",
                           line=d.lines.get("prefer_state"))
        sim = self.simulate(d.get("simulate") or _Map())
        expect = d.get("expect_check")
        if expect not in (None, 0, 1, 2):
            raise self.err("bad_value", "expect_check must be 0, 1 or 2", line=d.lines.get("expect_check"))
        try:
            net = Network(str(d.get("name", Path(self.file).stem)), children, connections, params=params,
                          prefer_state=prefer)
        except MultipoleError as exc:
            raise self.err(exc.code, exc.message, exc.fix) from None
        digest = hashlib.sha256((text + repr(sorted(self.overrides.items()))).encode()).hexdigest()
        return Scene(str(d.get("name", Path(self.file).stem)), str(d.get("description", "")), self.file, net,
                     outputs, sim, expect, bool(d.get("bench", False)), digest, out_lines, lines, types,
                     dict(d.get("reference") or {}), texts)

    # -- sections --------------------------------------------------------------------------------
    def parameters(self, raw) -> dict:
        if not isinstance(raw, dict):
            raise self.err("bad_value", "'parameters' must be a mapping name: value", line=getattr(raw, "line", None))
        names = {n: sp.Symbol(n) for n in raw}
        out = {}
        for name, value in raw.items():
            line = raw.lines.get(name)
            if not isinstance(name, str) or not _NAME.match(name):
                raise self.err("bad_name", f"parameter name {name!r} is not a plain name", line=line)
            if name in self.overrides:
                value = self.overrides[name]
                self.used_overrides.add(name)
            others = {k: v for k, v in names.items() if k != name}
            out[name] = self.expr(value, others, f"parameter '{name}'", line)
        self.check_cycles(out)
        self.numbers = _resolve(out)
        return out

    def check_cycles(self, params):
        import networkx as nx
        g = nx.DiGraph()
        for k, v in params.items():
            g.add_node(k)
            for s in v.free_symbols:
                g.add_edge(k, s.name)
        try:
            cycle = nx.find_cycle(g)
        except nx.NetworkXNoCycle:
            return
        raise self.err("parameter_cycle", "parameters refer to each other in a cycle: "
                       + " -> ".join(a for a, _ in cycle), "give one of them a number")

    def expr(self, value, symbols, what, line, element=""):
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self.err("not_numeric", f"{what}: expected a number or a formula, got {value!r}",
                           "write a number such as 1.5e-3 or a formula in quotes", line, element)
        where = f"{self.file}:{line}" + (f" element '{element}'" if element else "") + f" {what}"
        return parse_expression(value, symbols, where)

    def element(self, name, spec, symbols, line):
        if not isinstance(name, str) or not _NAME.match(name):
            raise self.err("bad_name", f"element name {name!r} must be a plain name (letters, digits, _)",
                           line=line)
        if not isinstance(spec, dict) or "type" not in spec:
            raise self.err("no_type", "every element needs a 'type'", "e.g. {type: inertia, J: 1e-3}", line, name)
        types = catalogue()
        tname = spec["type"]
        etype = types.get(tname) if isinstance(tname, str) else None
        if etype is None:
            import difflib
            close = difflib.get_close_matches(str(tname), types, 3)
            raise self.err("unknown_type", f"unknown element type {tname!r}",
                           f"did you mean {', '.join(close)}?" if close else "run 'multipole elements' for the list",
                           spec.lines.get("type", line), name)
        values = {k: v for k, v in spec.items() if k != "type"}
        for key, value in self.overrides.items():
            if key.startswith(name + ".") and key.count(".") == 1:
                values[key.split(".", 1)[1]] = value
                self.used_overrides.add(key)
        kwargs = {}
        for key in values:
            if etype.param(key) is None:
                raise self.err("unknown_parameter", f"{tname} has no parameter {key!r}",
                               f"parameters of {tname}: {', '.join(p.name for p in etype.params)}",
                               spec.lines.get(key, line), name)
        for p in etype.params:
            pline = spec.lines.get(p.name, line)
            if p.name not in values:
                if p.required:
                    raise self.err("missing_parameter", f"{tname} needs parameter {p.name!r} [{p.unit}]: {p.doc}",
                                   f"add {p.name}: <value> to element '{name}'", line, name)
                kwargs[p.name] = p.default
                continue
            kwargs[p.name] = self.param_value(p, values[p.name], symbols, pline, name)
        for group in etype.one_of:
            given = [g for g in group if g in values]
            if len(given) != 1:
                raise self.err("missing_parameter" if not given else "conflicting_parameters",
                               f"{tname} needs exactly one of {', '.join(group)}"
                               + (f" (got {', '.join(given)})" if given else ""), "", line, name)
        try:
            built = etype.build(**kwargs)
        except MultipoleError as exc:
            raise self.err(exc.code, exc.message, exc.fix, line, name) from None
        except (ValueError, TypeError, ZeroDivisionError, ArithmeticError) as exc:
            raise self.err("cannot_build", f"cannot build {tname}: {exc}", "check the parameter values",
                           line, name) from None
        return built, tname

    def param_value(self, p, value, symbols, line, element):
        what = f"parameter '{p.name}'"
        if p.kind == "number":
            expr = self.expr(value, symbols, what, line, element)
            number = sp.sympify(expr).xreplace(self.numbers)
            if p.positive and number.is_number and not float(number) > 0:
                raise self.err("bad_value", f"{what} [{p.unit}] must be positive, got {float(number):g}",
                               "give a positive value; to leave the part out, join its neighbours directly",
                               line, element)
            return expr
        if p.kind == "time":
            return self.expr(value, {**symbols, "t": T}, what, line, element)
        if p.kind == "law":
            return self.expr(value, {**symbols, "t": T, p.law_var: _LAW_VARS[p.law_var]}, what, line, element)
        if p.kind == "choice":
            if value not in p.choices:
                raise self.err("bad_value", f"{what} must be one of {', '.join(p.choices)}, got {value!r}",
                               line=line, element=element)
            return value
        if p.kind == "bool":
            if not isinstance(value, bool):
                raise self.err("bad_value", f"{what} must be true or false", line=line, element=element)
            return value
        if p.kind == "names":
            if not isinstance(value, list) or not all(isinstance(v, str) and _NAME.match(v) for v in value):
                raise self.err("bad_value", f"{what} must be a list of port names", line=line, element=element)
            return list(value)
        if p.kind == "numbers":
            if not isinstance(value, list):
                raise self.err("bad_value", f"{what} must be a list of numbers", line=line, element=element)
            return [float(self.expr(v, symbols, what, line, element)) for v in value]
        if p.kind == "matrix":
            if not isinstance(value, list) or not value or not all(isinstance(r, list) for r in value):
                raise self.err("bad_value", f"{what} must be a list of rows", line=line, element=element)
            if len({len(r) for r in value}) != 1:
                raise self.err("bad_value", f"{what}: all rows must have the same length", line=line, element=element)
            local = dict(symbols)
            if p.law_var == "q":          # modulated matrices: q1, q2, ... are the b-port displacements
                local.update({f"q{k}": sp.Symbol(f"q{k}") for k in range(1, len(value[0]) + 1)})
            return [[self.expr(v, local, what, line, element) for v in row] for row in value]
        raise self.err("bad_value", f"{what}: unsupported parameter kind {p.kind}", line=line, element=element)

    def connections(self, raw, children) -> list:
        if not isinstance(raw, list):
            raise self.err("bad_connections", "'connections' must be a list of port lists such as [motor.p, pinion.a]",
                           line=getattr(raw, "line", None))
        seen: dict = {}
        out = []
        for k, conn in enumerate(raw):
            line = raw.lines[k] if k < len(raw.lines) else None
            if not isinstance(conn, list) or len(conn) < 2:
                raise self.err("bad_connection", f"connection {conn!r} must list two or more ports",
                               "write [element.port, element.port]", line)
            for ref in conn:
                if not isinstance(ref, str) or ref.count(".") != 1:
                    raise self.err("bad_port_reference", f"{ref!r} is not of the form element.port", "", line)
                el, port = ref.split(".")
                if el not in children:
                    raise self.err("unknown_element", f"connection names unknown element {el!r}",
                                   f"elements are {', '.join(children)}", line)
                ports = children[el].ports
                if port not in ports:
                    raise self.err("unknown_port", f"element '{el}' has no port {port!r}",
                                   f"its ports are {', '.join(ports)}", line, el)
                if ref in seen:
                    raise self.err("port_used_twice", f"port {ref} is used twice (also on line {seen[ref]})",
                                   "list all ports of one node in a single connection entry", line, el)
                seen[ref] = line
            out.append(list(conn))
        return out

    def outputs(self, d):
        raw = d.get("outputs") or []
        if not isinstance(raw, list) or not all(isinstance(o, str) for o in raw):
            raise self.err("bad_outputs", "'outputs' must be a list of names such as pinion.omega",
                           line=d.lines.get("outputs"))
        lines = {o: (raw.lines[k] if hasattr(raw, "lines") and k < len(raw.lines) else None)
                 for k, o in enumerate(raw)}
        return list(raw), lines

    def simulate(self, raw) -> dict:
        if not isinstance(raw, dict):
            raise self.err("bad_value", "'simulate' must be a mapping", line=getattr(raw, "line", None))
        out = {}
        for key, value in raw.items():
            if key not in _SIM_KEYS:
                raise self.err("unknown_key", f"unknown simulate option {key!r}",
                               f"allowed: {', '.join(_SIM_KEYS)}", raw.lines.get(key))
            typ = _SIM_KEYS[key]
            if typ is float:
                if isinstance(value, bool) or not isinstance(value, (int, float)) or value <= 0:
                    raise self.err("not_numeric", f"simulate.{key} must be a positive number, got {value!r}",
                                   line=raw.lines.get(key))
                out[key] = float(value)
            else:
                out[key] = str(value)
        if "solver" in out:
            from .simulate import SOLVERS
            if out["solver"] != "auto" and out["solver"] not in SOLVERS:
                raise self.err("unknown_solver", f"unknown solver {out['solver']!r}",
                               f"use auto or one of {', '.join(SOLVERS)}", raw.lines.get("solver"))
        return out
