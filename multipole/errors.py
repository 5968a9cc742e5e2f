"""Exceptions raised by the kernel.

Every error carries a short machine-readable ``code``, a one-line ``message`` that names the
file, line and element where known, and a suggested ``fix``.  The CLI prints ``str(error)``
as one line without a traceback and exits with the class's ``exit_code``:

* 1 -- structural problems found by the check (:class:`IllPosedError`),
* 2 -- invalid input or options (:class:`NetlistError`, :class:`ModelError`, the base class),
* 3 -- a well-posed model that failed while running (:class:`RunError`: Newton failure,
  non-finite state or output, failed step, arithmetic error in the model, not enough memory).
"""
from __future__ import annotations


class MultipoleError(Exception):
    """Base class: an invalid model or netlist (CLI exit code 2)."""

    #: the status the ``multipole`` command exits with when this error ends it
    exit_code = 2

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

    exit_code = 1


class RunError(MultipoleError):
    """A well-posed model that failed while running (CLI exit code 3): the message names the
    element and the time [s] where known."""

    exit_code = 3


class NewtonError(RunError, ArithmeticError):
    """An algebraic loop has no solution at one evaluation of the model: Newton's method did not
    converge (``newton_failed``), or a position closure's formula has no real value there
    (``closure_unreachable``).

    A run-time error (exit code 3); also an ``ArithmeticError``, so code that treats a failed
    evaluation of the model as arithmetic (the solver choice, the step loop) handles it alike."""

    def __init__(self, message: str, fix: str = "check the loop's laws and parameters for a state where "
                 "they have no solution", where: str = "", code: str = "newton_failed"):
        super().__init__(code, message, fix, where)


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a run; ``t`` is the simulated time reached [s] (None if not known)."""

    def __init__(self, t: float | None = None):
        self.t = t
        super().__init__(f"interrupted at t = {t:.6g} s" if t is not None else "interrupted")


class MultipoleWarning(UserWarning):
    """Something the user should know before (or after) a run that still goes ahead; the CLI
    prints it as one ``multipole: warning:`` line on stderr."""


class LongRunWarning(MultipoleWarning):
    """A run that will take very long: the CLI prints it at once, before the wait it announces
    (other project warnings are printed when the command ends, never before its error line)."""
