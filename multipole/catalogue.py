"""The element catalogue: element types by name, with ports, parameters (units) and quantities.

The kernel registers its primitives here (for teaching netlists); element libraries register
their machine elements through the ``multipole.elements`` entry-point group (the bundled
``elements`` package does so), so the kernel never imports a machine element by name.
"""
from __future__ import annotations

import functools
import inspect
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Callable

from .errors import ModelError
from .network import Network
from .primitives import C, GY, I, MTF, R, TF, CField, Se, Sf, Tap, junction_a, junction_b

REQUIRED = object()


@dataclass(frozen=True)
class Reduction:
    """A simplification an element type offers ``multipole reduce`` (:mod:`multipole.reduce`),
    declared by the element library; the kernel applies it to the netlist without knowing the type.

    * ``join``: the element is replaced by a rigid joint of these ports (their nodes merge): a
      spring made rigid, a body made massless;
    * ``level`` and ``levels``: the parameter naming a fidelity level and the levels from the most
      detailed to the simplest (the element may drop to any simpler level); ``drop`` pairs a level
      with the parameters to remove when dropping to it (they belong to the levels left behind),
      and ``adapt(entry, level)``, if given, returns the element's netlist entry (a dict) with the
      parameters the simpler level needs worked out from the detailed ones (None: not offered);
    * ``adapt`` alone: the element's entry becomes ``adapt(entry, None)`` (a chain of identical
      parts lumped into one; None: not offered);
    * none of these: the element is removed and its ports are left open (a negligible damper).

    ``action`` is the word the report uses (``rigid``, ``massless``, ``removed``, ``level``).
    """

    action: str
    join: tuple = ()
    level: str = ""
    levels: tuple = ()
    drop: tuple = ()                  # ((level, (parameter, ...)), ...)
    adapt: Callable | None = None


@dataclass
class Param:
    """A parameter of an element type.

    ``kind``: ``number`` (constant, may use scene parameters), ``time`` (expression of ``t``),
    ``law`` (expression of the law variable ``law_var`` and ``t``), ``choice`` (one of
    ``choices``), ``bool``, ``names`` (list of port names), ``numbers`` (list of numbers),
    ``file`` (a data file named relative to the netlist file; the builder gets the path).
    """

    name: str
    unit: str = ""
    doc: str = ""
    default: object = REQUIRED
    kind: str = "number"
    choices: tuple = ()
    law_var: str = ""
    positive: bool = False            # a number that must be > 0 (inertia, stiffness, ...)
    nonnegative: bool = False         # >= 0 (a literal 0 leaves the part out: massless rotor, ...)
    nonzero: bool = False             # != 0 (ratios of transformers and gears)
    maximum: float | None = None      # largest accepted value (counts of repeated elements)
    max_items: int | None = None      # longest accepted list (kind numbers: stages of repeated parts)

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    @property
    def bounds(self) -> str:
        """The declared rules as text, e.g. ``> 0, <= 50`` ('' when there are none)."""
        rules = ["> 0"] * self.positive + [">= 0"] * self.nonnegative + ["!= 0"] * self.nonzero
        if self.maximum is not None:
            rules.append(f"<= {self.maximum:g}")
        if self.max_items is not None:
            rules.append(f"at most {self.max_items} values")
        return ", ".join(rules)

    def problem(self, value: float) -> str:
        """Why the constant ``value`` is not acceptable for this parameter ('' when it is)."""
        if self.positive and not value > 0:
            return "must be positive"
        if self.nonnegative and not value >= 0:
            return "must not be negative"
        if self.nonzero and value == 0:
            return "must not be zero"
        if self.maximum is not None and not value <= self.maximum:
            return f"must be at most {self.maximum:g}"
        return ""


@dataclass
class ElementType:
    """A buildable element type: ``build(**params)`` returns a Network or a Primitive.

    Each fact is declared here once.  ``params`` are the builder's arguments, in its order and with
    their defaults: the builder itself declares no defaults, and ``build`` (the builder wrapped at
    registration) fills them in from the :class:`Param` list, so netlists and Python callers get
    the same defaults.  ``quantities`` maps a quantity's name to ``"unit: meaning"``; a Network the
    builder returns names its :class:`~multipole.network.Quantity` objects by their expression
    only, and ``build`` gives them the declared unit and meaning.  A unit that depends on the
    configuration is declared with alternatives (``"N*m | N"``); the builder then states the one
    it built (e.g. from the port's domain).  Dotted names document quantities of a child element
    (``mesh12.force``; ``s<k>.force`` for the numbered children s1, s2, ...).
    """

    name: str
    build: Callable
    doc: str
    ports: dict                       # port name -> description (domain, role)
    params: list
    quantities: dict = field(default_factory=dict)   # name -> "unit: meaning"
    one_of: tuple = ()                # groups of parameters of which exactly one must be given
    category: str = "element"
    reductions: tuple = ()            # Reduction objects: what ``multipole reduce`` may do with it

    def __post_init__(self):
        for red in self.reductions:
            if set(red.join) - set(self.ports) or (red.level and (self.param(red.level) is None or len(red.levels) < 2)):
                raise ModelError("bad_element_type", f"element type {self.name}: reduction {red.action!r} names ports "
                                 "or a level parameter the type does not declare",
                                 "join only declared ports; give a declared level parameter and at least two levels")
        self.builder = self.build
        taken = inspect.signature(self.builder).parameters
        declared = [p.name for p in self.params]
        if list(taken) != declared:
            raise ModelError("bad_element_type", f"element type {self.name}: the builder takes "
                             f"({', '.join(taken)}), the declared parameters are ({', '.join(declared)})",
                             "declare one Param per builder argument, in the builder's order")
        own = [n for n, a in taken.items() if a.default is not a.empty or a.kind is not a.POSITIONAL_OR_KEYWORD]
        if own:
            raise ModelError("bad_element_type", f"element type {self.name}: the builder declares defaults or "
                             f"special arguments ({', '.join(own)})", "give defaults in the Param only")
        try:
            signature = inspect.Signature([inspect.Parameter(p.name, inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                                             default=inspect.Parameter.empty if p.required else
                                                             p.default) for p in self.params])
        except ValueError:
            raise ModelError("bad_element_type", f"element type {self.name}: a required parameter follows one with "
                             "a default", "declare the required parameters first") from None

        @functools.wraps(self.builder)
        def build(*args, **kwargs):
            bound = signature.bind(*args, **kwargs)
            bound.apply_defaults()
            made = self.builder(*bound.args)
            if isinstance(made, Network):
                self._document(made)
            return made

        build.__signature__ = signature
        self.build = build

    def quantity(self, name: str) -> tuple[str, str]:
        """``(unit, meaning)`` of a declared quantity; the unit may list alternatives ``"N*m | N"``."""
        unit, _, meaning = self.quantities[name].partition(": ")
        return (unit, meaning) if meaning else ("", unit)

    def _document(self, net: Network) -> None:
        """Give the built network's quantities their declared unit and meaning (refuse undeclared ones)."""
        for name, q in net.quantities.items():
            if name not in self.quantities:
                raise ModelError("undeclared_quantity", f"element type {self.name} builds the quantity {name!r} "
                                 "it does not declare", f"add {name!r} to the quantities of {self.name}")
            unit, meaning = self.quantity(name)
            choices = unit.split(" | ")
            if (q.unit or len(choices) > 1) and q.unit not in choices:
                raise ModelError("quantity_unit", f"element type {self.name}: quantity {name!r} built in "
                                 f"{q.unit or 'no unit'}, declared in {unit}",
                                 "state one of the declared units when building it")
            q.unit, q.doc = q.unit or unit, meaning

    def param(self, name: str) -> Param | None:
        return next((p for p in self.params if p.name == name), None)

    def markdown(self) -> str:
        """A reference section for docs/elements.md."""
        lines = [f"### `{self.name}`", "", self.doc, "", "| port | meaning |", "| --- | --- |"]
        lines += [f"| `{p}` | {d} |" for p, d in self.ports.items()]
        lines += ["", "| parameter | unit | default | meaning |", "| --- | --- | --- | --- |"]
        for p in self.params:
            default = "required" if p.required else ("—" if p.default is None else f"`{p.default}`")
            extra = f" (one of {', '.join(p.choices)})" if p.choices else f" ({p.bounds})" if p.bounds else ""
            lines.append(f"| `{p.name}` | {p.unit or '–'} | {default} | {p.doc}{extra} |")
        for group in self.one_of:
            lines.append(f"\nGive exactly one of {', '.join(f'`{g}`' for g in group)}.")
        if self.quantities:
            lines += ["", "| quantity | meaning |", "| --- | --- |"]
            lines += [f"| `{q}` | {d} |" for q, d in self.quantities.items()]
        return "\n".join(lines) + "\n"

    def describe(self) -> str:
        lines = [f"{self.name} — {self.doc}", "  ports:"]
        lines += [f"    {p}: {d}" for p, d in self.ports.items()]
        lines.append("  parameters:")
        for p in self.params:
            default = "required" if p.required else f"default {p.default!r}"
            extra = f" one of {', '.join(p.choices)}" if p.choices else f", {p.bounds}" if p.bounds else ""
            lines.append(f"    {p.name} [{p.unit or '-'}] ({p.kind}, {default}{extra}): {p.doc}")
        for group in self.one_of:
            lines.append(f"    (give exactly one of: {', '.join(group)})")
        if self.quantities:
            lines.append("  quantities:")
            lines += [f"    {q}: {d}" for q, d in self.quantities.items()]
        return "\n".join(lines)


_REGISTRY: dict[str, ElementType] = {}
_LOADED = False


def register(etype: ElementType) -> ElementType:
    """Add an element type to the catalogue (later registrations of a name are refused)."""
    if etype.name in _REGISTRY and _REGISTRY[etype.name] is not etype:
        raise ModelError("duplicate_type", f"element type {etype.name!r} is registered twice")
    _REGISTRY[etype.name] = etype
    return etype


def element(name: str, doc: str, ports: dict, params: list, quantities: dict | None = None, **options):
    """Decorator: register the decorated builder as element type ``name`` and return its ``build``
    (the builder with the declared defaults and quantity units), e.g.::

        @element("spring", "linear spring", {"a": "port a", "b": "port b"}, [Param("c", "N/m", "stiffness")],
                 {"force": "N: effort in the spring"})
        def spring(c): ...
    """
    def declare(builder: Callable) -> Callable:
        return register(ElementType(name, builder, doc, ports, params, dict(quantities or {}), **options)).build
    return declare


def catalogue() -> dict[str, ElementType]:
    """All registered element types (loads the ``multipole.elements`` entry points once)."""
    global _LOADED
    if not _LOADED:
        _LOADED = True
        for ep in entry_points(group="multipole.elements"):
            ep.load()
    return dict(_REGISTRY)


# -- kernel primitives as netlist types ----------------------------------------------------------

_DOMAIN = Param("domain", "", "energy domain of the ports", "rotational", "choice",
                ("rotational", "translational", "electrical", "hydraulic"))


register(ElementType("Se", lambda value, domain: Se(value, domain), "effort source (primitive)",
                     {"p": "imposes the effort on its neighbour"},
                     [Param("value", "effort unit", "effort as a function of t", kind="time"), _DOMAIN],
                     category="primitive"))
register(ElementType("Sf", lambda value, domain: Sf(value, domain), "flow source (primitive)",
                     {"p": "imposes the flow on its neighbour"},
                     [Param("value", "flow unit", "flow as a function of t", kind="time"), _DOMAIN],
                     category="primitive"))
register(ElementType(
    "TF", lambda ratio, domain_a, domain_b, q0: TF(ratio, domain_a, domain_b, q0),
    "ideal transformer f_a = k*f_b, e_b = -k*e_a; k may depend on q, the displacement of port b",
    {"a": "port a (domain_a)", "b": "port b (domain_b); q = ∫ f_b dt"},
    [Param("ratio", "f_a/f_b", "ratio k, a number or an expression of q", kind="law", law_var="q", nonzero=True),
     Param("domain_a", "", "domain of port a", "rotational", "choice", _DOMAIN.choices),
     Param("domain_b", "", "domain of port b", "rotational", "choice", _DOMAIN.choices),
     Param("q0", "displacement unit of b", "initial displacement of port b", 0.0)],
    {"q": "displacement unit of b: displacement of port b (modulated ratio only)"}, category="primitive"))
register(ElementType(
    "GY", lambda r, domain_a, domain_b: GY(r, domain_a, domain_b), "ideal gyrator e_a = r*f_b, e_b = -r*f_a",
    {"a": "port a", "b": "port b"},
    [Param("r", "e_a/f_b", "gyrator modulus", nonzero=True),
     Param("domain_a", "", "domain of port a", "electrical", "choice", _DOMAIN.choices),
     Param("domain_b", "", "domain of port b", "rotational", "choice", _DOMAIN.choices)],
    category="primitive"))
register(ElementType(
    "I", lambda J, law, domain, p0: I(J=J, law=law, dom=domain, p0=p0), "inertia one-port: p' = e, f = p/J",
    {"p": "the port"},
    [Param("J", "kg*m^2 | kg | H", "inertia (or give law)", None, positive=True),
     Param("law", "flow unit", "flow as a function of the momentum p", None, "law", law_var="p"), _DOMAIN,
     Param("p0", "momentum unit", "initial momentum", 0.0)],
    {"p": "momentum"}, one_of=(("J", "law"),), category="primitive"))
register(ElementType(
    "C", lambda c, law, domain, q0: C(c=c, law=law, dom=domain, q0=q0), "compliance one-port: q' = f, e = c*q",
    {"p": "the port"},
    [Param("c", "effort/displacement", "stiffness (or give law)", None, positive=True),
     Param("law", "effort unit", "effort as a function of the displacement q", None, "law", law_var="q"),
     _DOMAIN, Param("q0", "displacement unit", "initial displacement", 0.0)],
    {"q": "displacement"}, one_of=(("c", "law"),), category="primitive"))
register(ElementType(
    "R", lambda r, law, domain: R(r=r, law=law, dom=domain), "resistance one-port: e = r*f or e = law(f)",
    {"p": "the port"},
    [Param("r", "effort/flow", "resistance (or give law)", None),
     Param("law", "effort unit", "effort as a function of the flow f", None, "law", law_var="f"), _DOMAIN],
    one_of=(("r", "law"),), category="primitive"))
for _kind, _fn in (("a", junction_a), ("b", junction_b)):
    register(ElementType(
        f"junction_{_kind}", (lambda fn: lambda ports, signs, domain: fn(ports, domain, signs))(_fn),
        "type-a junction: common effort, flows add (0-junction)" if _kind == "a" else
        "type-b junction: common flow, efforts add (1-junction)",
        {"<ports>": "the names listed in 'ports'"},
        [Param("ports", "", "port names", kind="names"),
         Param("signs", "", "orientation +1/-1 per port", None, "numbers"), _DOMAIN],
        category="primitive"))
register(ElementType(
    "MTF", lambda matrix, domains_a, domains_b, q0: MTF(matrix, domains_a, domains_b, q0),
    "multiport transformer f_a = K(q)·f_b, e_b = -Kᵀ·e_a; q1..qm = ∫ f_b (a Jacobian, e.g. of a linkage)",
    {"a1..an": "one port per matrix row", "b1..bm": "one port per matrix column; qj = ∫ f_bj dt"},
    [Param("matrix", "f_a/f_b", "n×m matrix K, entries numbers or expressions of q1..qm", kind="matrix", law_var="q"),
     Param("domains_a", "", "domain of each a port", kind="names"),
     Param("domains_b", "", "domain of each b port", kind="names"),
     Param("q0", "displacement units", "initial displacements of the b ports", None, "numbers")],
    {"q1..qm": "displacements of the b ports"}, category="primitive"))
register(ElementType(
    "CField", lambda compliance, domains, q0: CField(compliance, domains, q0),
    "multiport compliance field q' = f, q = S·e (S symmetric: reciprocal coupling, e.g. piezo)",
    {"p1..pn": "one port per matrix row"},
    [Param("compliance", "displacement/effort", "symmetric n×n compliance matrix S", kind="matrix"),
     Param("domains", "", "domain of each port", kind="names"),
     Param("q0", "displacement units", "initial displacements", None, "numbers")],
    {"q1..qn": "displacements"}, category="primitive"))
register(ElementType(
    "Tap", lambda domain, q0: Tap(domain, q0),
    "displacement tap: takes no effort, integrates its flow into q (an angle or travel sensor)",
    {"p": "the measured port"}, [_DOMAIN, Param("q0", "displacement unit", "initial displacement", 0.0)],
    {"q": "displacement"}, category="primitive"))
