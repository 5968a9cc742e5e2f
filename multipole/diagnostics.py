"""Diagnostics: what the check found, in the user's words, with a suggested fix.

A diagnostic has a ``code``, a ``severity`` (``error`` makes ``check`` exit 1; ``warning`` and
``info`` do not), the elements and ports involved (a loop is listed as a path), a plain-language
``message`` and a ``fix``.

Every code belongs to a registered check (:func:`register`): its severity, what it means and the
function that produces its findings.  :func:`run_checks` runs them in registration order, which
is also the order ``multipole check`` prints them in; the checks themselves are in
:mod:`multipole.checks`.  Adding a diagnostic is one decorated function there.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Callable

SEVERITIES = ("error", "warning", "info")


@dataclass(frozen=True)
class Check:
    """A registered check: the diagnostic ``code`` it reports, its ``severity``, what the code
    means, and ``run(context) -> iterable of Diagnostic``.  ``stage`` is ``"structure"`` (needs the
    causality analysis only) or ``"equations"`` (needs the assembled equations: runs only when the
    structural checks found no error and the caller can assemble them)."""

    code: str
    severity: str
    meaning: str
    run: Callable
    stage: str = "structure"


#: code -> Check, in registration (= report) order
REGISTRY: dict[str, Check] = {}

#: code -> (severity, what it means); kept in step with :data:`REGISTRY`
CATALOGUE: dict[str, tuple[str, str]] = {}


def register(code: str, severity: str, meaning: str, stage: str = "structure"):
    """Decorator registering ``run(context)`` as the check that reports ``code``."""
    if severity not in SEVERITIES:
        raise ValueError(f"severity of {code!r} must be one of {SEVERITIES}")
    if stage not in ("structure", "equations"):
        raise ValueError(f"stage of {code!r} must be 'structure' or 'equations'")

    def deco(run):
        if code in REGISTRY:
            raise ValueError(f"diagnostic code {code!r} is registered twice")
        REGISTRY[code] = Check(code, severity, meaning, run, stage)
        CATALOGUE[code] = (severity, meaning)
        return run
    return deco


def run_checks(context, stages=("structure", "equations")) -> list:
    """Run the registered checks of ``stages`` on ``context`` (see :class:`multipole.checks.Context`)
    and return their diagnostics in registration order.  Equation-stage checks run only when no
    structural error was found and ``context.can_assemble``."""
    from . import checks  # noqa: F401  (registers the kernel's checks)
    found: dict[str, list] = {}
    for check in REGISTRY.values():
        if check.stage == "structure" and "structure" in stages:
            found[check.code] = list(check.run(context))
    errors = any(d.severity == "error" for ds in found.values() for d in ds)
    if "equations" in stages and not errors and context.can_assemble:
        for check in REGISTRY.values():
            if check.stage == "equations":
                found[check.code] = list(check.run(context))
    return [d for code in REGISTRY for d in found.get(code, [])]


@dataclass
class Diagnostic:
    """One finding of a check."""

    code: str
    message: str
    fix: str = ""
    elements: list = field(default_factory=list)
    ports: list = field(default_factory=list)
    path: list = field(default_factory=list)
    severity: str = ""

    def __post_init__(self):
        if not CATALOGUE:
            from . import checks  # noqa: F401
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


def names_list(names, most: int = 8) -> str:
    """``a, b, c`` (for a short repr) — at most ``most`` names, then ``… (n more)``."""
    names = list(names)
    more = f", … ({len(names) - most} more)" if len(names) > most else ""
    return ", ".join(names[:most]) + more
