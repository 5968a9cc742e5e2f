"""YAML netlists (DESIGN §5): untrusted text in, a :class:`Scene` out.

* YAML is read with a loader derived from ``yaml.SafeLoader`` that only adds line numbers (no
  Python object tags, duplicate keys refused), reads ``1e-3`` and ``-2E+5`` as numbers (YAML 1.2
  floats) and bounds the input (:data:`MAX_FILE_BYTES`, :data:`MAX_YAML_NODES` after alias
  expansion, :data:`MAX_ELEMENTS`).
* Every formula goes through :func:`multipole.expressions.parse_expression` (a whitelist).
* Every error is a :class:`~multipole.errors.NetlistError` naming the file, line and element.

``overrides`` (the CLI's ``--set NAME=VALUE``) replace a scene parameter (``r1=0.03``) or an element
parameter (``mesh.c=1e9``) before anything is built.
"""
from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import sympy as sp
import yaml

from .catalogue import ElementType, catalogue
from .errors import MultipoleError, NetlistError
from .expressions import MAX_DIGITS, parse_expression, reserved
from .network import Network, expand_connection
from .primitives import LAW_F, LAW_P, LAW_Q, T, Primitive
from .stages import bulk

_LAW_VARS = {"f": LAW_F, "q": LAW_Q, "p": LAW_P}
_TOP_KEYS = {"name", "description", "parameters", "elements", "connections", "outputs", "simulate",
             "expect_check", "bench", "prefer_state", "reference", "metrics"}
#: what a ``metrics:`` formula (and ``sweep --metrics``) may take of an output ``o``: ``o.final``,
#: ``o.max``, ``o.min``, ``o.rms``, ``o.mean`` and ``o.settling`` (docs/sweeps.md, "Metrics")
METRIC_KINDS = ("final", "max", "min", "rms", "mean", "settling")
_SIM_KEYS = {"t_end": float, "dt_out": float, "solver": str, "rtol": float, "atol": float,
             "max_step": float, "backend": str}
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_SCENE_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.+\- ]{0,79}$")

MAX_FILE_BYTES = 8 << 20          # 8 MiB: larger files are refused without reading them whole
MAX_YAML_NODES = 1_000_000        # YAML nodes after expanding aliases (refuses "billion laughs")
MAX_ELEMENTS = 50_000             # elements in one scene (a 10,000-pair chain has 20,002)
MAX_LIST = 1000                   # entries of a list parameter
MAX_STEPS = 100_000_000           # t_end/max_step
MIN_RTOL = 1e-14                  # below it the integrators cannot meet the tolerance in float64

# YAML 1.2 core-schema floats: PyYAML (YAML 1.1) reads 1e-3, 1e3, 1.0e9 and -2E+5 as strings
_FLOAT_12 = re.compile(r"^[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)[eE][-+]?[0-9]+$")


class _Map(dict):
    line = 0
    lines: dict = {}


class _List(list):
    line = 0
    lines: list = []


class _Loader(yaml.SafeLoader):
    """SafeLoader that records the line of every mapping key and sequence item and bounds the input."""

    def compose_document(self):
        node = super().compose_document()
        _check_size(node)
        return node

    def construct_object(self, node, deep=False):
        try:
            return super().construct_object(node, deep)
        except (NetlistError, yaml.YAMLError):
            raise
        except (ValueError, TypeError, KeyError, AttributeError, OverflowError, ArithmeticError) as exc:
            value = node.value if isinstance(node, yaml.ScalarNode) else ""
            raise NetlistError("yaml_value", f"cannot read {str(value)[:40]!r} as {node.tag.rsplit(':', 1)[-1]}",
                               "write a plain number or text without a '!!' tag",
                               where=f":{node.start_mark.line + 1}") from None


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))


def _children(node):
    if isinstance(node, yaml.SequenceNode):
        return node.value
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    return []


def _check_size(root) -> None:
    """Refuse a document of more than MAX_YAML_NODES nodes once aliases are expanded, or a cycle."""
    if root is None:
        return
    size: dict = {}
    open_: set = set()
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            open_.discard(key)
            size[key] = 1 + sum(size[id(c)] for c in _children(node))
            if size[key] > MAX_YAML_NODES:
                raise NetlistError("too_large", f"the YAML document expands to more than {MAX_YAML_NODES} "
                                   "values (aliases *name repeat what they refer to)",
                                   "write the netlist without nested aliases",
                                   where=f":{node.start_mark.line + 1}")
            continue
        if key in size:
            continue
        open_.add(key)
        stack.append((node, True))
        for child in _children(node):
            if id(child) in open_:
                raise NetlistError("yaml_syntax", "an alias refers to the mapping or list that contains it",
                                   "remove the recursive alias", where=f":{child.start_mark.line + 1}")
            if id(child) not in size:
                stack.append((child, False))


def _construct_int(loader, node):
    digits = str(node.value).lstrip("+-").replace("_", "")
    if len(digits) > MAX_DIGITS:
        raise NetlistError("too_large", f"an integer of {len(digits)} digits (limit {MAX_DIGITS})",
                           "write a decimal number such as 1.5e20", where=f":{node.start_mark.line + 1}")
    return loader.construct_yaml_int(node)


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
_Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)


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
    metrics: dict = field(default_factory=dict)   # metric name -> sympy formula of symbols ``output.kind``

    def where(self, element: str = "", key: str = "") -> str:
        line = self.element_lines.get(element) or self.output_lines.get(key)
        text = f"{self.path}:{line}" if line else self.path
        return f"{text} element '{element}'" if element else text


def load(path, overrides=None, parameters=None) -> Scene:
    """Read a netlist file (UTF-8, at most :data:`MAX_FILE_BYTES` bytes)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise NetlistError("no_file", f"cannot read {path}: {exc.strerror}", "check the path") from None
    if len(data) > MAX_FILE_BYTES:
        raise NetlistError("too_large", f"the file is larger than {MAX_FILE_BYTES // 1024} KiB",
                           "a netlist is a short text file: check the path", str(path))
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise NetlistError("not_utf8", f"the file is not UTF-8 text (byte {exc.start} is {data[exc.start]:#04x})",
                           "save the file as UTF-8", f"{path}:{line}") from None
    return loads(text, str(path), overrides, parameters)


@bulk
def loads(text: str, filename: str = "<netlist>", overrides=None, parameters=None) -> Scene:
    """Read a netlist from text; ``filename`` is used in error messages.

    ``parameters``: extra scene parameters ``{name: value}`` added to the ``parameters:`` section
    (a parameter study makes an element parameter a scene parameter this way, ``mesh.c`` set to
    the name of an added parameter, so that it stays a symbol of the equations)."""
    if len(text) > MAX_FILE_BYTES:
        raise NetlistError("too_large", f"the netlist is longer than {MAX_FILE_BYTES // 1024} KiB",
                           "a netlist is a short text", filename)
    try:
        data = yaml.load(text, Loader=_Loader)  # noqa: S506 — a SafeLoader subclass
    except RecursionError:
        raise NetlistError("too_large", "the YAML is nested too deeply", "flatten the netlist", filename) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = f":{mark.line + 1}" if mark else ""
        raise NetlistError("yaml_syntax", f"invalid YAML: {exc.problem or exc.context}", "fix the YAML syntax",
                           f"{filename}{line}") from None
    except yaml.reader.ReaderError as exc:      # a control character: name it and its line
        line = text[:exc.position].count("\n") + 1
        raise NetlistError("yaml_syntax", f"invalid YAML: character #x{exc.character:04x} is not allowed "
                           "in YAML text", "remove the control character", f"{filename}:{line}") from None
    except yaml.YAMLError as exc:
        raise NetlistError("yaml_syntax", f"invalid YAML: {' '.join(str(exc).split())}", "fix the YAML syntax",
                           filename) from None
    except NetlistError as exc:          # raised while reading: ``where`` holds ":line"
        exc.where = filename + exc.where
        raise
    builder = _Builder(data, filename, dict(overrides or {}))
    builder.extra = dict(parameters or {})
    return builder.scene(text + repr(sorted(builder.extra.items())) if builder.extra else text)


def validate_simulate_options(options: dict, where: str = "", lines: dict | None = None) -> dict:
    """Check the simulate options (``t_end``, ``dt_out``, ``rtol``, ``atol``, ``max_step``, ``solver``,
    ``backend``) and return them with numbers as floats; ``None`` values are left out.

    Used by the loader for the ``simulate:`` section and by the CLI for ``--t-end``, ``--dt-out``,
    ``--rtol`` and ``--atol`` (pass the scene's options merged with the overrides so that
    ``dt_out <= t_end`` is checked across both).  Raises :class:`NetlistError` (code ``not_numeric``
    for a value that is not a positive finite number, ``bad_option`` for one out of range,
    ``unknown_key``, ``unknown_solver``); ``where`` is the file name and ``lines`` maps an option
    to its line.  The size of the output grid is checked by :func:`multipole.simulate.output_grid`.
    """
    lines = lines or {}

    def err(code, key, message, fix=""):
        line = lines.get(key)
        return NetlistError(code, message, fix, f"{where}:{line}" if line and where else where)

    out = {}
    for key, value in options.items():
        if value is None:
            continue
        if key not in _SIM_KEYS:
            raise err("unknown_key", key, f"unknown simulate option {key!r}", f"allowed: {', '.join(_SIM_KEYS)}")
        if _SIM_KEYS[key] is str:
            if not isinstance(value, str):
                raise err("bad_option", key, f"simulate.{key} must be a name, got {value!r}")
            out[key] = value
            continue
        try:
            number = float(value) if not isinstance(value, (bool, str)) else math.nan
        except (TypeError, ValueError, OverflowError):
            number = math.nan
        if not math.isfinite(number) or not number > 0:
            raise err("not_numeric", key, f"simulate.{key} must be a positive finite number, got {value!r}",
                      "e.g. t_end: 0.5, dt_out: 1.0e-3, rtol: 1.0e-6")
        out[key] = number
    rtol = out.get("rtol")
    if rtol is not None and not MIN_RTOL <= rtol < 1:
        raise err("bad_option", "rtol", f"simulate.rtol = {rtol:g} is outside [{MIN_RTOL:g}, 1)",
                  "typical values are 1e-3 to 1e-10")
    t_end, dt_out, max_step = out.get("t_end"), out.get("dt_out"), out.get("max_step")
    if t_end is not None and dt_out is not None:
        if dt_out > t_end:
            raise err("bad_option", "dt_out", f"simulate.dt_out = {dt_out:g} s is longer than t_end = {t_end:g} s",
                      "choose dt_out <= t_end")
    if t_end is not None and max_step is not None and t_end / max_step > MAX_STEPS:
        raise err("bad_option", "max_step", f"t_end/max_step = {t_end / max_step:.3g} steps (limit {MAX_STEPS:.0e})",
                  "choose a larger max_step")
    if out.get("solver", "auto") != "auto":     # scipy's integrators only for a scene that names one
        from .solvers import SOLVERS
        if out["solver"] not in SOLVERS:
            raise err("unknown_solver", "solver", f"unknown solver {out['solver']!r}",
                      f"use auto or one of {', '.join(SOLVERS)}")
    return out


class _Builder:
    def __init__(self, data, filename, overrides):
        self.data, self.file, self.overrides = data, filename, overrides
        self.used_overrides: set = set()
        self.numbers: dict = {}
        self.extra: dict = {}
        self.file_hashes: list = []     # (path, sha256 of the contents) of every 'file' parameter

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
        if len(d["elements"]) > MAX_ELEMENTS:
            raise self.err("too_large", f"{len(d['elements'])} elements (limit {MAX_ELEMENTS})",
                           "split the scene or use elements that repeat a part (e.g. piezo_stack n)",
                           d.lines.get("elements"))
        if isinstance(d.get("name"), int) and not isinstance(d["name"], bool):
            d["name"] = str(d["name"])                      # name: 2024
        if "name" in d and not (isinstance(d["name"], str) and _SCENE_NAME.match(d["name"])):
            raise self.err("bad_name", f"scene name {str(d['name'])[:40]!r} may use letters, digits, spaces "
                           "and _ . + -", "e.g. name: gear_stage", d.lines.get("name"))
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
        reference = d.get("reference") or {}
        if not isinstance(reference, dict):
            raise self.err("bad_value", "reference must be a mapping such as {kind: tight, output: load.omega}",
                           "see 'reference' in docs/netlist.md", d.lines.get("reference"))
        sim = self.simulate(d.get("simulate") or _Map())
        metrics = self.metrics(d.get("metrics") or _Map(), outputs, d.lines.get("metrics"))
        expect = d.get("expect_check")
        if expect not in (None, 0, 1, 2):
            raise self.err("bad_value", "expect_check must be 0, 1 or 2", line=d.lines.get("expect_check"))
        try:
            net = Network(str(d.get("name", Path(self.file).stem)), children, connections, params=params,
                          prefer_state=prefer)
        except MultipoleError as exc:
            raise self.err(exc.code, exc.message, exc.fix) from None
        digest = hashlib.sha256((text + repr(sorted(self.overrides.items())) + repr(self.file_hashes)).encode()
                                ).hexdigest()
        return Scene(str(d.get("name", Path(self.file).stem)), str(d.get("description", "")), self.file, net,
                     outputs, sim, expect, bool(d.get("bench", False)), digest, out_lines, lines, types,
                     dict(reference), texts, metrics)

    # -- sections --------------------------------------------------------------------------------
    def parameters(self, raw) -> dict:
        if not isinstance(raw, dict):
            raise self.err("bad_value", "'parameters' must be a mapping name: value", line=getattr(raw, "line", None))
        if self.extra:
            merged = _Map(raw)
            merged.line, merged.lines = raw.line, dict(raw.lines)
            merged.update(self.extra)
            raw = merged
        names = {n: sp.Symbol(n) for n in raw if isinstance(n, str)}
        out = {}
        for name, value in raw.items():
            line = raw.lines.get(name)
            if not isinstance(name, str) or not _NAME.match(name):
                raise self.err("bad_name", f"parameter name {name!r} is not a plain name", line=line)
            if reserved(name):
                raise self.err("reserved_name", f"parameter name {name!r} is reserved in formulas "
                               "(time t, law variables f q p, pi, function names)",
                               f"rename the parameter, e.g. {name}_0", line)
            if name in self.overrides:
                value = self.overrides[name]
                self.used_overrides.add(name)
            others = {k: v for k, v in names.items() if k != name}
            out[name] = self.expr(value, others, f"parameter '{name}'", line)
        self.numbers = self.evaluate(out, raw.lines)
        return out

    def evaluate(self, params: dict, lines: dict) -> dict:
        """{Symbol: Float} of the scene parameters, evaluated numerically in dependency order.

        Numbers, never symbolic substitution: chains like ``p2: p1*p1 + p1`` stay linear in size.
        A cycle is a ``parameter_cycle``; a value that is not finite or not real is refused.
        """
        import networkx as nx
        g = nx.DiGraph()
        for k, v in params.items():
            g.add_node(k)
            for s in v.free_symbols:
                g.add_edge(s.name, k)
        try:
            cycle = nx.find_cycle(g)
        except nx.NetworkXNoCycle:
            cycle = None
        if cycle:
            names = [b for _, b in cycle]
            first = min(names, key=lambda n: lines.get(n, 0))
            k = names.index(first)
            path = names[k:] + names[:k + 1]
            raise self.err("parameter_cycle", f"parameter '{first}' depends on itself: " + " -> ".join(path),
                           "give one of them a number", lines.get(first))
        numbers: dict = {}
        for name in nx.topological_sort(g):
            value = sp.N(params[name].xreplace(numbers))
            if not value.is_number:
                continue
            number = complex(value) if not value.has(sp.zoo, sp.nan, sp.oo) else complex(math.nan)
            if not (math.isfinite(number.real) and math.isfinite(number.imag)):
                raise self.err("bad_value", f"parameter '{name}' is not a finite number (overflow, division by zero "
                               "or log(0))", "check the formula", lines.get(name))
            if number.imag != 0:
                raise self.err("complex_value", f"parameter '{name}' is not a real number ({value})",
                               "check signs under sqrt, log and fractional powers", lines.get(name))
            numbers[sp.Symbol(name)] = sp.Float(number.real)
        return numbers

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

    def check_value(self, p, expr, line, element):
        """Refuse a constant value the parameter's declaration rules out (positive, nonzero, ...)."""
        number = sp.sympify(expr).xreplace(self.numbers)
        if not number.is_number:
            return
        value = float(number)
        problem = p.problem(value)
        if problem:
            fix = ("the limit keeps checking and simulating quick (docs/netlist.md, Limits)" if "at most" in problem
                   else "give a physical value; to leave a part out, join its neighbours directly")
            raise self.err("bad_value", f"parameter '{p.name}' [{p.unit or '-'}] {problem}, got {value:g}", fix,
                           line, element)

    def param_value(self, p, value, symbols, line, element):
        what = f"parameter '{p.name}'"
        if p.kind in ("number", "time", "law"):
            local = dict(symbols)
            if p.kind != "number":
                local["t"] = T
            if p.kind == "law":
                local[p.law_var] = _LAW_VARS[p.law_var]
            expr = self.expr(value, local, what, line, element)
            self.check_value(p, expr, line, element)
            return expr
        if p.kind == "file":              # a data file (a table) named relative to the netlist file
            if not isinstance(value, str) or not value.strip() or "\0" in value:
                raise self.err("bad_value", f"{what} must be a file name, a path relative to the netlist file",
                               "e.g. contour: wheel1.csv", line, element)
            folder = Path(self.file).resolve().parent
            path = Path(self.file).parent / value
            if Path(value).is_absolute() or not path.resolve().is_relative_to(folder):
                raise self.err("file_outside_folder", f"{what}: {value!r} lies outside the netlist's folder",
                               "keep data files beside the netlist or in a folder below it and name them "
                               "relative to it (a netlist may only read what its own folder holds)",
                               line, element)
            try:                          # the scene's digest (cache key) covers the data file too
                if path.is_file():        # (a device or pipe is left to the element, which refuses it)
                    with open(path, "rb") as fh:
                        digest = hashlib.sha256(fh.read(MAX_FILE_BYTES + 1)).hexdigest()
                    self.file_hashes.append((str(path), digest))
            except OSError:
                pass                      # the element names the file it cannot read
            return str(path)
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
            if not isinstance(value, list) or len(value) > MAX_LIST or \
                    not all(isinstance(v, str) and _NAME.match(v) for v in value):
                raise self.err("bad_value", f"{what} must be a list of at most {MAX_LIST} port names",
                               line=line, element=element)
            return list(value)
        if p.kind == "numbers":
            longest = p.max_items or MAX_LIST
            if not isinstance(value, list) or len(value) > longest:
                raise self.err("bad_value", f"{what} must be a list of at most {longest} numbers",
                               "the limit keeps checking and simulating quick (docs/netlist.md, Limits)",
                               line, element)
            out = []
            for v in value:
                expr = self.expr(v, symbols, what, line, element)
                number = sp.sympify(expr).xreplace(self.numbers)
                if not number.is_number:
                    raise self.err("not_numeric", f"{what}: {v!r} is not a constant", line=line, element=element)
                self.check_value(p, number, line, element)
                out.append(float(number))
            return out
        if p.kind == "matrix":
            if not isinstance(value, list) or not value or not all(isinstance(r, list) for r in value) \
                    or len(value) * len(value[0]) > MAX_LIST:
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
                if port not in ports and port not in (getattr(children[el], "bundles", None) or {}):
                    raise self.err("unknown_port", f"element '{el}' has no port {port!r}",
                                   f"its ports are {', '.join(ports)}", line, el)
                if ref in seen:
                    raise self.err("port_used_twice", f"port {ref} is used twice (also on line {seen[ref]})",
                                   "list all ports of one node in a single connection entry", line, el)
                seen[ref] = line
            try:
                out += expand_connection(list(conn), children)
            except MultipoleError as exc:
                raise self.err(exc.code, exc.message, exc.fix, line) from None
        return out

    def outputs(self, d):
        raw = d.get("outputs") or []
        if not isinstance(raw, list) or not all(isinstance(o, str) for o in raw):
            raise self.err("bad_outputs", "'outputs' must be a list of names such as pinion.omega",
                           line=d.lines.get("outputs"))
        lines = {o: (raw.lines[k] if hasattr(raw, "lines") and k < len(raw.lines) else None)
                 for k, o in enumerate(raw)}
        return list(raw), lines

    def metrics(self, raw, outputs, line) -> dict:
        """``metrics:`` {name: formula of ``output.kind`` values} (:data:`METRIC_KINDS`), each
        parsed by the expression whitelist; the outputs are those the scene lists."""
        if not isinstance(raw, dict):
            raise self.err("bad_metric", "'metrics' must be a mapping name: formula",
                           "e.g. metrics: {overshoot: \"load.omega.max/load.omega.final - 1\"}", line)
        symbols = {f"{o}.{k}": sp.Symbol(f"{o}.{k}") for o in outputs for k in METRIC_KINDS}
        out = {}
        for name, value in raw.items():
            mline = raw.lines.get(name, line)
            if not isinstance(name, str) or not _NAME.match(name) or name in symbols:
                raise self.err("bad_metric", f"metric name {name!r} must be a plain name (letters, digits, _)",
                               "e.g. overshoot", mline)
            if not outputs:
                raise self.err("bad_metric", f"metric {name!r}: the scene lists no outputs to take metrics of",
                               "add outputs: [...]", mline)
            out[name] = self.expr(value, symbols, f"metric '{name}'", mline)
        return out

    def simulate(self, raw) -> dict:
        if not isinstance(raw, dict):
            raise self.err("bad_value", "'simulate' must be a mapping", line=getattr(raw, "line", None))
        return validate_simulate_options({k: (math.nan if v is None else v) for k, v in raw.items()},
                                         self.file, raw.lines)
