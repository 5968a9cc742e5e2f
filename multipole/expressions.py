"""Safe parsing of formulas written in netlists.

Netlist values such as ``"5*step(t)"`` or ``"F_c*tanh(f/v_reg)"`` are untrusted text.  They
are parsed with :func:`ast.parse` and the syntax tree is walked node by node; only the
constructs below are accepted and translated into sympy.  Nothing is ever evaluated as
Python (no ``eval``, ``exec``, ``compile`` or ``sympify`` of a string).

Grammar
-------
::

    expr     := number | name | "(" expr ")" | ("+" | "-") expr
              | expr ("+" | "-" | "*" | "/" | "**") expr
              | function "(" expr ("," expr)* ")"
              | "interp" "(" expr "," "[" number ("," number)+ "]" "," "[" expr ("," expr)+ "]" ")"
    number   := integer or decimal literal, e.g. 3, 0.5, 1.0e-3   (no complex, no True/False)
    name     := a name the context allows (parameters, t, law variables such as f or q),
                possibly dotted like mesh.c when the context defines that dotted name,
                or the constant pi

Powers are written ``**`` (``^`` is rejected).  Integers stay exact (``1/2`` is the rational
one half); decimal literals become floating point numbers.

Functions
---------
``sin cos tan asin acos atan sinh cosh tanh exp log sqrt``
    one argument each; ``log`` is the natural logarithm.
``atan2(y, x)``
    angle of the point (x, y).
``abs(x)``, ``sign(x)``
    absolute value, sign (-1, 0 or 1).
``min(a, b, ...)``, ``max(a, b, ...)``
    two or more arguments.
``step(x)``, ``step(x, x0)``
    1 where ``x >= x0`` (default ``x0 = 0``), else 0 (``Heaviside(x - x0, 1)``).
``ramp(x)``, ``ramp(x, x0)``
    ``max(0, x - x0)`` (default ``x0 = 0``).
``pulse(x, x0, width)``
    1 for ``x0 <= x < x0 + width``, else 0.
``interp(x, [x0, x1, ...], [y0, y1, ...])``
    straight lines through the points (xi, yi); constant ``y0`` below ``x0`` and constant last
    y above the last x.  The x values must be numbers, strictly increasing, at least two, and
    as many as the y values; the y values may be expressions.  Lists are allowed only here.

Only the functions above may be called (an explicit allow-list, :data:`FUNCTIONS`); every other
call, such as ``gamma(t)``, ``factorial(5)``, ``Integral(t, t)`` or ``eval(1)``, is refused.
``pi`` is the only constant: ``E``, ``I``, ``oo``, ``nan`` and other sympy names are unknown names
(write ``exp(1)`` for e).  The names in :data:`RESERVED_NAMES` (``t``, the law variables ``f``,
``q``, ``p``, the matrix displacements ``q1``, ``q2``, ..., ``pi``, the function names and Python
keywords) cannot be parameter names: :func:`reserved` tells whether a name is one of them.

Limits: at most 2000 characters and at most 50 levels of nesting (long flat sums and
products do not count as nesting); integer literals of at most 300 digits; exact powers that
would be enormous, like ``9**9**9``, are refused.  A constant part that is not a real number
(``sqrt(-1)``, ``log(-2)``, ``acos(2)``, ``(-8)**(1/3)``, whose principal value is complex) is
refused.  Errors are raised as
:class:`multipole.errors.NetlistError` with code ``bad_expression`` (syntax or unsupported
construct), ``unknown_name`` (a name the context does not define), ``complex_value`` (a constant
that is not real) or ``unsafe_expression`` (attribute access, double-underscore names, lambda,
subscripts, calls of names that are not in the function list).
"""
from __future__ import annotations

import ast
import keyword
import math
import re
from typing import Mapping

import sympy

from multipole.errors import NetlistError

__all__ = ["FUNCTIONS", "RESERVED_NAMES", "parse_expression", "reserved"]

MAX_LENGTH = 2000
MAX_DEPTH = 50
MAX_DIGITS = 300           # longest integer literal (beyond it a float conversion overflows)
_MAX_POWER_BITS = 100_000  # refuse exact powers whose result would exceed about this many bits


def _step(x, x0=0):
    return sympy.Heaviside(x - x0, 1)


def _ramp(x, x0=0):
    return sympy.Max(0, x - x0)


def _pulse(x, x0, width):
    return sympy.Heaviside(x - x0, 1) - sympy.Heaviside(x - x0 - width, 1)


# name -> (sympy constructor, fewest arguments, most arguments or None for no limit)
_TABLE = {
    **{name: (getattr(sympy, name), 1, 1) for name in
       ("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log", "sqrt")},
    "atan2": (sympy.atan2, 2, 2),
    "abs": (sympy.Abs, 1, 1),
    "sign": (sympy.sign, 1, 1),
    "min": (sympy.Min, 2, None),
    "max": (sympy.Max, 2, None),
    "step": (_step, 1, 2),
    "ramp": (_ramp, 1, 2),
    "pulse": (_pulse, 3, 3),
    "interp": (None, 3, 3),
}

FUNCTIONS: tuple[str, ...] = tuple(_TABLE)
"""Names of the functions an expression may call (the allow-list; docs/netlist.md lists the same)."""

_ALLOWED_CALLS = frozenset(FUNCTIONS)

RESERVED_NAMES: frozenset = frozenset({"t", "f", "q", "p", "pi", *FUNCTIONS, *keyword.kwlist})
"""Names a scene parameter may not take: time, the law variables, ``pi``, functions, keywords."""

_RESERVED_PATTERN = re.compile(r"q[1-9][0-9]*")    # q1, q2, ...: displacements in modulated matrices


def reserved(name: str) -> bool:
    """True if ``name`` means something in the expression language (not usable as a parameter)."""
    return name in RESERVED_NAMES or bool(_RESERVED_PATTERN.fullmatch(name))


def _complex_part(expr: sympy.Expr):
    """The first constant part of ``expr`` that is not a real number, or None."""
    if expr.has(sympy.I):
        return expr
    for part in expr.atoms(sympy.Pow, sympy.Function):
        if part.is_number and part.is_extended_real is False:
            return part
    return None

_BINARY = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_DESCRIPTIONS = {
    ast.Compare: "comparisons", ast.BoolOp: "'and'/'or'", ast.IfExp: "if-expressions",
    ast.ListComp: "comprehensions", ast.SetComp: "comprehensions", ast.DictComp: "comprehensions",
    ast.GeneratorExp: "comprehensions", ast.JoinedStr: "f-strings", ast.NamedExpr: "':='",
    ast.Dict: "dictionaries", ast.Set: "sets", ast.Tuple: "tuples",
    ast.List: "lists outside interp(...)", ast.Starred: "'*' unpacking",
}
_SYNTAX_HINT = "write a formula such as '2*r1 + 0.5*sin(t)' with numbers, names, + - * / ** and ()"


def _quote(text: str) -> str:
    """Return ``text`` on one line, shortened, in single quotes."""
    text = " ".join(text.split())
    return f"'{text[:77]}...'" if len(text) > 80 else f"'{text}'"


def parse_expression(source, symbols: Mapping[str, sympy.Basic], where: str = "") -> sympy.Expr:
    """Turn a netlist value (str, int or float) into a sympy expression.

    ``symbols`` maps each name the formula may use (possibly dotted, e.g. ``"mesh.c"``) to its
    sympy object; ``pi`` is always available.  ``where`` is copied into any
    :class:`NetlistError` raised.  See the module docstring for the grammar.
    """
    if isinstance(source, bool) or not isinstance(source, (str, int, float)):
        raise NetlistError("bad_expression",
                           f"expected a number or a formula, got {type(source).__name__} {source!r}",
                           _SYNTAX_HINT, where)
    if isinstance(source, int):
        if abs(source) >= 10 ** MAX_DIGITS:
            raise NetlistError("bad_expression", f"the integer has more than {MAX_DIGITS} digits",
                               "write a decimal number such as 1.5e20", where)
        return sympy.Integer(source)
    if isinstance(source, float):
        if not math.isfinite(source):
            raise NetlistError("bad_expression", f"the number {source!r} is not finite",
                               "use a finite number", where)
        return sympy.Float(source)
    return _Parser(source, symbols, where).parse()


class _Parser:
    """Walks the syntax tree of one formula and builds the sympy expression."""

    def __init__(self, text: str, symbols: Mapping[str, sympy.Basic], where: str):
        self.text = text.strip()
        self.symbols = symbols
        self.where = where

    def error(self, code: str, message: str, fix: str = "") -> NetlistError:
        return NetlistError(code, message, fix, self.where)

    def segment(self, node: ast.AST) -> str:
        return _quote(ast.get_source_segment(self.text, node) or ast.unparse(node))

    def parse(self) -> sympy.Expr:
        if not self.text:
            raise self.error("bad_expression", "the expression is empty", _SYNTAX_HINT)
        if len(self.text) > MAX_LENGTH:
            raise self.error("bad_expression",
                             f"the expression is {len(self.text)} characters long (limit {MAX_LENGTH})",
                             "split the formula into parameters")
        try:
            tree = ast.parse(self.text, mode="eval")
        except (SyntaxError, ValueError, RecursionError, MemoryError) as exc:
            detail = getattr(exc, "msg", None) or "too complex"
            raise self.error("bad_expression",
                             f"cannot read the expression {_quote(self.text)}: {detail}",
                             _SYNTAX_HINT) from None
        try:
            result = self.walk(tree.body, 1)
        except (TypeError, ValueError, ArithmeticError) as exc:  # sympy refused an operation
            raise self.error("bad_expression", f"cannot evaluate {_quote(self.text)}: {' '.join(str(exc).split())}",
                             _SYNTAX_HINT) from None
        if result.has(sympy.zoo, sympy.nan, sympy.oo, -sympy.oo):
            raise self.error("bad_expression",
                             f"the expression {_quote(self.text)} is infinite or undefined ({result})",
                             "check for division by zero or log(0)")
        bad = _complex_part(result)
        if bad is not None:
            raise self.error("complex_value",
                             f"the expression {_quote(self.text)} has a part that is not a real number ({bad})",
                             "only real values are supported: check signs under sqrt, log, acos, asin and "
                             "fractional powers")
        return result

    def walk(self, node: ast.AST, depth: int) -> sympy.Expr:
        if depth > MAX_DEPTH:
            raise self.error("bad_expression",
                             f"the expression {_quote(self.text)} is nested more than {MAX_DEPTH} levels deep",
                             "simplify the formula or split it into parameters")
        if isinstance(node, ast.Constant):
            return self.constant(node)
        if isinstance(node, (ast.Name, ast.Attribute)):
            return self.name(node)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            value = self.walk(node.operand, depth + 1)
            return -value if isinstance(node.op, ast.USub) else value
        if isinstance(node, ast.BinOp):
            return self.binary(node, depth)
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        if isinstance(node, (ast.Lambda, ast.Subscript)):
            kind = "lambda" if isinstance(node, ast.Lambda) else "indexing"
            raise self.error("unsafe_expression", f"{kind} is not allowed in expressions: {self.segment(node)}",
                             _SYNTAX_HINT)
        what = _DESCRIPTIONS.get(type(node), "such constructs")
        if isinstance(node, ast.UnaryOp):
            what = "the operators 'not' and '~'"
        raise self.error("bad_expression", f"{what} are not allowed in expressions: {self.segment(node)}",
                         _SYNTAX_HINT)

    def constant(self, node: ast.Constant) -> sympy.Expr:
        value = node.value
        if isinstance(value, int) and not isinstance(value, bool):
            if abs(value) >= 10 ** MAX_DIGITS:
                raise self.error("bad_expression", f"an integer in {self.segment(node)} has more than "
                                 f"{MAX_DIGITS} digits", "write a decimal number such as 1.5e20")
            return sympy.Integer(value)
        if isinstance(value, float) and math.isfinite(value):
            return sympy.Float(value)
        if isinstance(value, complex):
            problem = "complex numbers are not supported"
        elif isinstance(value, (str, bytes)):
            problem = "text strings are not allowed"
        elif isinstance(value, float):
            problem = "the number is too large"
        else:
            problem = f"{value!r} is not a number"
        raise self.error("bad_expression", f"{problem} in expressions: {self.segment(node)}", _SYNTAX_HINT)

    def name(self, node: ast.AST) -> sympy.Expr:
        original, parts = node, []
        while isinstance(node, ast.Attribute):
            parts.append(node.attr)
            node = node.value
        if isinstance(node, ast.Name):
            parts.append(node.id)
        dotted = ".".join(reversed(parts))
        if dotted in self.symbols:
            return self.symbols[dotted]
        if dotted == "pi":
            return sympy.pi
        if not isinstance(node, ast.Name) or any(p.startswith("__") for p in parts) or (
                len(parts) > 1 and not any(key.startswith(parts[-1] + ".") for key in self.symbols)):
            raise self.error("unsafe_expression",
                             f"attribute access and double-underscore names are not allowed: {self.segment(original)}",
                             "refer to parameters by their plain names")
        allowed = sorted({*self.symbols, "pi"})
        listing = ", ".join(allowed[:20]) + (f", ... ({len(allowed) - 20} more)" if len(allowed) > 20 else "")
        raise self.error("unknown_name", f"unknown name {_quote(dotted)}; allowed names: {listing}",
                         "check the spelling or declare the parameter")

    def binary(self, node: ast.BinOp, depth: int) -> sympy.Expr:
        # Walk the left spine iteratively so that long sums like a+b+c+... do not count as nesting.
        chain = []
        while isinstance(node, ast.BinOp):
            chain.append(node)
            node = node.left
        value = self.walk(node, depth + 1)
        for op_node in reversed(chain):
            if isinstance(op_node.op, ast.BitXor):
                raise self.error("bad_expression", f"'^' is not a power operator: {self.segment(op_node)}",
                                 "write powers with '**', e.g. x**2")
            if type(op_node.op) not in _BINARY:
                raise self.error("bad_expression",
                                 f"only + - * / ** are allowed as operators: {self.segment(op_node)}",
                                 _SYNTAX_HINT)
            right = self.walk(op_node.right, depth + 1)
            if isinstance(op_node.op, ast.Add):
                value = value + right
            elif isinstance(op_node.op, ast.Sub):
                value = value - right
            elif isinstance(op_node.op, ast.Mult):
                value = value * right
            elif isinstance(op_node.op, ast.Div):
                value = value / right
            else:
                self.check_power(value, right, op_node)
                value = value ** right
            value = self.in_range(value, op_node)
        return value

    def check_power(self, base: sympy.Expr, exponent: sympy.Expr, node: ast.AST) -> None:
        """Refuse exact powers so large that sympy would compute for a very long time."""
        if not exponent.is_Rational:
            return
        bits = 1 + sum(max(r.p.bit_length(), r.q.bit_length()) for r in base.atoms(sympy.Rational))
        if bits * abs(exponent) > _MAX_POWER_BITS:
            raise self.error("bad_expression", f"the power {self.segment(node)} is too large",
                             "use smaller exponents or decimal numbers")

    def call(self, node: ast.Call, depth: int) -> sympy.Expr:
        func = node.func
        if not isinstance(func, ast.Name) or func.id not in _ALLOWED_CALLS:
            raise self.error("unsafe_expression",
                             f"only these functions may be called: {', '.join(FUNCTIONS)}; "
                             f"got {self.segment(func)}", "use one of the listed functions")
        name = func.id
        if node.keywords or any(isinstance(arg, ast.Starred) for arg in node.args):
            raise self.error("bad_expression",
                             f"function arguments must be plain and positional: {self.segment(node)}",
                             f"pass arguments by position, without '=' or '*'")
        constructor, low, high = _TABLE[name]
        count = len(node.args)
        if count < low or (high is not None and count > high):
            wanted = (f"{low}" if low == high else f"{low} or more" if high is None else f"{low} or {high}")
            raise self.error("bad_expression",
                             f"{name}() takes {wanted} argument{'s' * (wanted != '1')}, got {count}: "
                             f"{self.segment(node)}", "see the function list in the documentation")
        if name == "interp":
            return self.interp(node, depth)
        return self.in_range(constructor(*(self.walk(arg, depth + 1) for arg in node.args)), node)

    def in_range(self, value: sympy.Expr, node: ast.AST) -> sympy.Expr:
        """Refuse a constant beyond the floating-point range as soon as it appears: sympy's numbers
        have no such limit, and a function of one (sin(exp(1e10))) takes sympy practically forever."""
        if not value.is_number:
            return value
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        except (TypeError, ValueError):   # complex or undefined: refused in their own words later
            return value
        if math.isinf(number) and not value.has(sympy.oo, sympy.zoo):
            raise self.error("bad_expression", f"the constant {self.segment(node)} is beyond the range of "
                             "floating-point numbers (about 1.8e308)", "check the exponent and the units")
        return value

    def interp(self, node: ast.Call, depth: int) -> sympy.Expr:
        x_node, xs_node, ys_node = node.args
        fix = "write interp(x, [x0, x1, ...], [y0, y1, ...]) with increasing numbers x0 < x1 < ..."
        if not (isinstance(xs_node, ast.List) and isinstance(ys_node, ast.List)):
            raise self.error("bad_expression",
                             f"interp() needs two lists [...] as 2nd and 3rd argument: {self.segment(node)}", fix)
        x = self.walk(x_node, depth + 1)
        xs = [self.walk(item, depth + 2) for item in xs_node.elts]
        ys = [self.walk(item, depth + 2) for item in ys_node.elts]
        if len(xs) < 2 or len(xs) != len(ys):
            raise self.error("bad_expression",
                             f"interp() needs at least 2 points and as many x as y values "
                             f"(got {len(xs)} and {len(ys)}): {self.segment(node)}", fix)
        if not all(v.is_number and v.is_real for v in xs) or not all(
                bool(a < b) for a, b in zip(xs, xs[1:])):
            raise self.error("bad_expression",
                             f"interp() x values must be strictly increasing numbers: {self.segment(xs_node)}",
                             fix)
        pieces = [(ys[0], x < xs[0])]
        for x0, x1, y0, y1 in zip(xs, xs[1:], ys, ys[1:]):
            pieces.append((y0 + (y1 - y0) * (x - x0) / (x1 - x0), x < x1))
        pieces.append((ys[-1], True))
        return sympy.Piecewise(*pieces)
