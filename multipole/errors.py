"""Exceptions raised by the kernel.

Every error carries a short machine-readable ``code``, a one-line ``message`` that names the
file, line and element where known, and a suggested ``fix``.  The CLI prints ``str(error)``
without a traceback and exits with status 2.
"""
from __future__ import annotations


class MultipoleError(Exception):
    """Base class: an invalid model or netlist (CLI exit code 2)."""

    def __init__(self, code: str, message: str, fix: str = "", where: str = ""):
        self.code = code
        self.message = message
        self.fix = fix
        self.where = where
        super().__init__(str(self))

    def __str__(self) -> str:
        text = f"{self.where}: {self.message}" if self.where else self.message
        if self.fix:
            text += f" (fix: {self.fix})"
        return f"error[{self.code}] {text}"


class NetlistError(MultipoleError):
    """A netlist that cannot be read: syntax, unknown names, bad values, unsafe expressions."""


class ModelError(MultipoleError):
    """A network that is built wrongly in code: bad port names, duplicate names, bad laws."""


class IllPosedError(MultipoleError):
    """A structurally ill-posed network asked to produce equations (see ``multipole check``)."""


class NewtonError(ArithmeticError):
    """Newton's method did not converge in an algebraic loop (at one evaluation of the model)."""
