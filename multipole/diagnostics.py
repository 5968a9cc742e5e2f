"""Diagnostics: what the causality analyser found, in Weber's words, with a suggested fix.

A diagnostic has a ``code`` from :data:`CATALOGUE`, a ``severity`` (``error`` makes ``check``
exit 1; ``warning`` and ``info`` do not), the elements and ports involved (a loop is listed as a
path), a plain-language ``message`` and a ``fix``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

#: code -> (severity, what it means)
CATALOGUE: dict[str, tuple[str, str]] = {
    "kinematic_overdetermination": (
        "error", "a rigid loop imposes a flow twice (consistent ratios): the junction gets two flow "
                 "inputs and its effort sum is one input short — static under-determination"),
    "static_overdetermination": (
        "error", "the dual: an effort is imposed twice and the corresponding flow is undetermined"),
    "locked_loop": (
        "error", "a rigid loop with inconsistent ratios: the only motion it admits is standstill"),
    "source_conflict": (
        "error", "two sources impose the same variable (or the balance of a massless node)"),
    "overdetermined": (
        "error", "equations that impose more than they can, with no storage to resolve it"),
    "underdetermined": (
        "error", "variables no equation determines"),
    "missing_cross_coupling": (
        "error", "variables no equation determines because a branch ends where the element's "
                 "structure needs a cross-coupling the parameters leave out; the element names it "
                 "and says how to add it"),
    "derivative_causality": (
        "info", "storage elements coupled rigidly: one is put into derivative causality and "
                "resolved into an effective inertia or compliance"),
    "algebraic_loop": (
        "info", "a loop without storage: solved symbolically when linear, by Newton otherwise"),
    "input_differentiation": (
        "error", "resolving derivative causality needs the time derivative of an input that has "
                 "none (a step or a pulse): the response would be an impulse"),
    "singular_loop": (
        "error", "an algebraic loop whose equations are singular: it has no unique solution"),
    "unconnected_port": (
        "info", "a port nobody connected takes its default termination"),
    "degrees_of_freedom": (
        "info", "the states the simulation integrates"),
}


@dataclass
class Diagnostic:
    """One finding of the analyser."""

    code: str
    message: str
    fix: str = ""
    elements: list = field(default_factory=list)
    ports: list = field(default_factory=list)
    path: list = field(default_factory=list)
    severity: str = ""

    def __post_init__(self):
        if self.code not in CATALOGUE:
            raise ValueError(f"unknown diagnostic code {self.code!r}")
        self.severity = self.severity or CATALOGUE[self.code][0]

    def to_dict(self) -> dict:
        return asdict(self)

    def __str__(self) -> str:
        text = f"{self.severity}[{self.code}] {self.message}"
        if self.path:
            text += "\n    loop: " + " -> ".join(self.path)
        if self.fix:
            text += f"\n    fix: {self.fix}"
        return text
