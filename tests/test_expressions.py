"""Tests for the whitelist expression parser ``multipole.expressions``."""
import os

import pytest
import sympy
from hypothesis import given, settings
from hypothesis import strategies as st

from multipole.errors import NetlistError
from multipole.expressions import FUNCTIONS, parse_expression

t, x, f, r1, r2, F_c, v_reg, c = sympy.symbols("t x f r1 r2 F_c v_reg c")
SYMS = {"t": t, "x": x, "f": f, "r1": r1, "r2": r2, "F_c": F_c, "v_reg": v_reg, "mesh.c": c}
H = sympy.Heaviside


def parse(text, symbols=SYMS, where=""):
    return parse_expression(text, symbols, where)


def rejects(text, code, symbols=SYMS, where="net.yaml:3 element 'm' parameter 'k'"):
    with pytest.raises(NetlistError) as info:
        parse_expression(text, symbols, where)
    error = info.value
    assert error.code == code, str(error)
    assert error.where == where
    assert "\n" not in error.message
    return error


# ---------------------------------------------------------------- accepted input

@pytest.mark.parametrize("text, expected", [
    ("5*step(t)", 5 * H(t, 1)),
    ("r2/r1", r2 / r1),
    ("-2", sympy.Integer(-2)),
    ("+3", sympy.Integer(3)),
    ("1/2", sympy.Rational(1, 2)),
    ("2**10", sympy.Integer(1024)),
    ("F_c*tanh(f/v_reg)", F_c * sympy.tanh(f / v_reg)),
    ("(t + 1)*(t - 1)", (t + 1) * (t - 1)),
    ("-t**2", -(t ** 2)),
    ("2*pi*f", 2 * sympy.pi * f),
    ("mesh.c * 2", 2 * c),
    ("  t  ", t),
    ("atan2(r1, r2)", sympy.atan2(r1, r2)),
    ("abs(t) + sign(t)", sympy.Abs(t) + sympy.sign(t)),
    ("min(t, 1, r1)", sympy.Min(t, 1, r1)),
    ("max(t, 0)", sympy.Max(t, 0)),
    ("step(t, 2)", H(t - 2, 1)),
    ("ramp(t)", sympy.Max(0, t)),
    ("ramp(t, 1.5)", sympy.Max(0, t - sympy.Float(1.5))),
    ("pulse(t, 1, 2)", H(t - 1, 1) - H(t - 3, 1)),
    ("sqrt(exp(log(t)))", sympy.sqrt(t)),
    ("sin(t)+cos(t)+tan(t)+asin(t)+acos(t)+atan(t)+sinh(t)+cosh(t)",
     sympy.sin(t) + sympy.cos(t) + sympy.tan(t) + sympy.asin(t) + sympy.acos(t)
     + sympy.atan(t) + sympy.sinh(t) + sympy.cosh(t)),
])
def test_formulas_match_hand_written_sympy(text, expected):
    assert parse(text) == expected


def test_numbers_keep_their_kind():
    assert parse(7, {}) == 7 and isinstance(parse(7, {}), sympy.Integer)
    assert isinstance(parse("7", {}), sympy.Integer)
    assert parse(0.25, {}) == sympy.Float(0.25) and isinstance(parse(0.25, {}), sympy.Float)
    value = parse("1.0e-3", {})
    assert isinstance(value, sympy.Float) and value == sympy.Float(1.0e-3)


def test_symbols_mapping_is_used_verbatim():
    q = sympy.Symbol("q", positive=True)
    assert parse("q*2", {"q": q}) == 2 * q
    assert parse("pi", {}) is sympy.pi


def test_step_ramp_pulse_numeric_values():
    assert parse("step(t)").subs(t, 0) == 1
    assert parse("step(t)").subs(t, -1e-9) == 0
    assert parse("step(t, 2)").subs(t, 1.9) == 0
    assert parse("step(t, 2)").subs(t, 2) == 1
    assert parse("ramp(t, 1)").subs(t, 3) == 2
    assert parse("ramp(t, 1)").subs(t, 0) == 0
    pulse = parse("pulse(t, 1, 2)")
    assert [pulse.subs(t, v) for v in (0.5, 1, 2.9, 3, 4)] == [0, 1, 1, 0, 0]


def test_interp_values_by_hand():
    curve = parse("interp(t, [0, 1, 3], [0, 10, 0])")
    assert isinstance(curve, sympy.Piecewise)
    expected = {-5: 0, 0: 0, 0.5: 5, 1: 10, 2: 5, 2.5: 2.5, 3: 0, 100: 0}
    for at, value in expected.items():
        assert float(curve.subs(t, at)) == pytest.approx(value)


def test_interp_constant_extrapolation_and_expression_values():
    curve = parse("interp(x, [-1, 1], [r1, 2*r1])")
    assert sympy.simplify(curve.subs(x, -7) - r1) == 0
    assert sympy.simplify(curve.subs(x, 0) - sympy.Rational(3, 2) * r1) == 0
    assert sympy.simplify(curve.subs(x, 9) - 2 * r1) == 0
    assert float(parse("interp(2, [0, 4.0], [1, 3])")) == pytest.approx(2.0)


# ---------------------------------------------------------------- rejected input

MARKER = "/tmp/pwned_marker_multipole_test"


@pytest.mark.parametrize("text", [
    f"__import__('os').system('touch {MARKER}')",
    f"open('{MARKER}', 'w')",
    f"().__class__.__base__.__subclasses__()",
    f"[c for c in ().__class__.__base__.__subclasses__()]",
    f"(lambda: __import__('os').system('touch {MARKER}'))()",
    f"getattr(__import__('os'), 'system')('touch {MARKER}')",
    f"step.__globals__",
    f"sin(t)(1)",
])
def test_code_execution_attempts_are_rejected_and_nothing_runs(text):
    if os.path.exists(MARKER):
        os.remove(MARKER)
    with pytest.raises(NetlistError) as info:
        parse(text)
    assert info.value.code in ("unsafe_expression", "bad_expression")
    assert not os.path.exists(MARKER)


@pytest.mark.parametrize("text", [
    "__import__('os').system('echo pwned')",
    "().__class__",
    "x.__class__",
    "x.real",
    "lambda: 1",
    "[1, 2][0]",
    "open('f')",
    "eval('1')",
    "t(1)",
    "__builtins__",
    "sin(t)(1)",
    "mesh.c.__class__",
])
def test_unsafe_constructs(text):
    error = rejects(text, "unsafe_expression")
    assert error.message.count("'") >= 2  # quotes the offending text


@pytest.mark.parametrize("text", [
    '"a"', "'a' + 'b'", "t if t else 1", "t < 1", "t and 1", "not t", "~t", "t // 2", "t % 2",
    "[1, 2]", "(1, 2)", "{1: 2}", "{1}", "[i for i in [1]]", "(y := 2)", "f'{t}'",
    "sin(x=1)", "max(*[1, 2])", "True", "None", "1j", "2 + 3j", "...", "b'x'",
    "", "   ", "1 +", "sin(", "t t", "1e999", "1/0", "log(0)", "9**9**9", "(2*t)**(10**9)",
    "a\x00b",
])
def test_bad_expressions(text):
    rejects(text, "bad_expression")


def test_caret_hints_at_power():
    error = rejects("2^3", "bad_expression")
    assert "power" in error.message and "2^3" in error.message
    assert "x**2" in error.fix


def test_syntax_error_does_not_leak():
    error = rejects("1 +* (", "bad_expression")
    assert not isinstance(error, SyntaxError) and error.__cause__ is None
    assert "'1 +* ('" in error.message


@pytest.mark.parametrize("text", ["sin(t, t)", "sin()", "atan2(t)", "min(t)", "max()", "step(t, 1, 2)",
                                  "ramp()", "pulse(t, 1)", "interp(t, [0, 1])", "sqrt(1, 2)",
                                  "abs(t, 1)", "sign()", "atan2(t, t, t)"])
def test_wrong_arity(text):
    error = rejects(text, "bad_expression")
    assert "argument" in error.message and ", got " in error.message


@pytest.mark.parametrize("text", [
    "interp(t, [0], [1])", "interp(t, [0, 1], [1])", "interp(t, [1, 0], [1, 2])",
    "interp(t, [0, 0], [1, 2])", "interp(t, [0, t], [1, 2])", "interp(t, (0, 1), (1, 2))",
    "interp(t, 0, 1)", "interp(t, [0, 1j], [1, 2])",
])
def test_bad_interp(text):
    rejects(text, "bad_expression")


def test_unknown_name_lists_allowed_names_sorted():
    error = rejects("r3 * 2", "unknown_name")
    assert "'r3'" in error.message
    assert "F_c, f, mesh.c, pi, r1, r2, t, v_reg, x" in error.message


def test_unknown_name_list_is_truncated():
    many = {f"p{i:02d}": sympy.Symbol(f"p{i:02d}") for i in range(40)}
    error = rejects("zz", "unknown_name", symbols=many)
    assert "p19" in error.message and "p30" not in error.message and "more" in error.message


def test_unknown_dotted_name_and_function_used_as_value():
    rejects("mesh.k", "unknown_name")
    rejects("sin", "unknown_name")


@pytest.mark.parametrize("source", [True, False, None, [1], b"1", 1j])
def test_non_text_sources_rejected(source):
    rejects(source, "bad_expression")


def test_non_finite_float_source_rejected():
    rejects(float("inf"), "bad_expression")
    rejects(float("nan"), "bad_expression")


def test_length_and_depth_limits():
    rejects("1+" * 1000 + "1", "bad_expression")          # 2001 characters
    assert parse("+".join(["t"] * 500)) == 500 * t         # long but flat: allowed
    rejects("(" * 60 + "t" + ")" * 60 + "*" + "sin(" * 51 + "t" + ")" * 51, "bad_expression")
    rejects("-" * 1500 + "1", "bad_expression")
    assert parse("sin(" * 20 + "t" + ")" * 20) is not None


def test_error_text_format():
    error = rejects("nope", "unknown_name", where="a.yaml:12 element 'mesh' parameter 'c'")
    assert str(error).startswith("error[unknown_name] a.yaml:12 element 'mesh' parameter 'c': ")


def test_functions_tuple():
    assert set(FUNCTIONS) == {"sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh",
                              "exp", "log", "sqrt", "atan2", "abs", "sign", "min", "max", "step",
                              "ramp", "pulse", "interp"}


# ---------------------------------------------------------------- properties

_leaf = st.one_of(st.integers(-50, 50).map(lambda n: (str(n), sympy.Integer(n))),
                  st.sampled_from([("t", t), ("r1", r1), ("pi", sympy.pi)]))


def _combine(children):
    ops = st.sampled_from([("+", lambda a, b: a + b), ("-", lambda a, b: a - b),
                           ("*", lambda a, b: a * b)])
    return st.one_of(
        st.tuples(children, ops, children).map(
            lambda v: (f"({v[0][0]}) {v[1][0]} ({v[2][0]})", v[1][1](v[0][1], v[2][1]))),
        children.map(lambda v: (f"sin({v[0]})", sympy.sin(v[1]))),
        children.map(lambda v: (f"step({v[0]})", H(v[1], 1))),
    )


@settings(max_examples=150, deadline=None)
@given(st.recursive(_leaf, _combine, max_leaves=12))
def test_random_formulas_match_independent_construction(pair):
    text, expected = pair
    assert parse(text) == expected


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.text(max_size=60),
                 st.text(alphabet="0123456789tpi+-*/^().,[] sinepmaxrl_j'\"=<", max_size=60)))
def test_arbitrary_text_gives_expression_or_netlist_error(text):
    try:
        result = parse(text)
    except NetlistError as error:
        assert error.code in ("bad_expression", "unknown_name", "unsafe_expression")
    else:
        assert isinstance(result, sympy.Basic)
