"""Hostile and malformed netlists: each is refused in one line naming file:line (and element).

One test class per kind of input (issues 8 §3 and 9 §2, §4): YAML numbers, the function
allow-list, parameter cycles and reserved names, degenerate values, size limits, loader values and
simulate options.  Expected values come from the netlist reference (docs/netlist.md) and from
independent float arithmetic, never from the loader itself.
"""
from __future__ import annotations

import math
import re
import textwrap
from pathlib import Path

import pytest
import yaml

from multipole import netlist
from multipole.cli import main
from multipole.errors import MultipoleError, NetlistError
from multipole.expressions import FUNCTIONS, parse_expression
from multipole.netlist import load, loads

ROOT = Path(__file__).resolve().parents[1]

BASE = """\
name: probe
parameters: PARAMS
elements:
  src: {type: torque_source, value: 1}
  body: {type: inertia, J: JVAL}
  EXTRA
connections:
  - [src.p, body.a]
simulate: SIM
"""
#: line numbers in BASE
PARAM_LINE, BODY_LINE, EXTRA_LINE, SIM_LINE = 2, 5, 6, 9


def netlist_text(params="{ja: 0.5}", j="ja", sim="{t_end: 1.0}", extra="") -> str:
    return BASE.replace("PARAMS", params).replace("JVAL", j).replace("SIM", sim).replace("EXTRA", extra)


def refused(text: str, code: str, line: int | None, element: str = "", overrides=None) -> NetlistError:
    """Load ``text`` and check the error: its code, one line, ``f.yaml:line`` and the element."""
    with pytest.raises(NetlistError) as exc:
        loads(text, "f.yaml", overrides)
    err = exc.value
    assert err.code == code, str(err)
    assert "\n" not in str(err)
    if line is not None:
        assert err.where.startswith(f"f.yaml:{line}"), str(err)
    if element:
        assert f"element '{element}'" in err.where, str(err)
    return err


# -- 1. YAML numbers as engineers write them ------------------------------------------------------

class TestYamlNumbers:
    @pytest.mark.parametrize("text, value", [("1e-3", 1e-3), ("1e3", 1e3), ("1.0e9", 1.0e9), ("-2E+5", -2e5),
                                             (".5e-2", 0.005), ("+3E2", 300.0)])
    def test_exponent_forms_are_numbers_everywhere(self, text, value):
        sim_value = abs(value)
        scene = loads(netlist_text(params=f"{{ja: 0.5, pa: {text}}}",
                                   sim=f"{{t_end: {sim_value if value < 0 else text}, rtol: 1e-6}}",
                                   extra=f"g: {{type: gear_train, r1: [{'1e-2' if value < 0 else text}], r2: [2e-2]}}"),
                      "f.yaml")
        assert scene.simulate["t_end"] == pytest.approx(sim_value, rel=1e-15)
        assert scene.simulate["rtol"] == pytest.approx(1e-6, rel=1e-15)
        assert float(scene.network.params["pa"]) == pytest.approx(value, rel=1e-15)

    def test_list_values_and_element_values(self):
        scene = loads(netlist_text(j="2.5e-3", extra="g: {type: gear_train, r1: [1e-2], r2: [3e-2]}"), "f.yaml")
        ratio = scene.network.children["g"].quantities["ratio"].build(None)
        assert float(ratio) == pytest.approx(-3.0, rel=1e-12)      # -r2/r1 of one external stage

    def test_plain_safe_load_is_unchanged(self):
        # the resolver is added to the project's loader only, never to yaml.SafeLoader
        assert yaml.safe_load("a: 1e-3") == {"a": "1e-3"}

    def test_words_stay_words(self):
        scene = loads(netlist_text().replace("name: probe", "name: e3"), "f.yaml")
        assert scene.name == "e3"


# -- 2. the expression allow-list ----------------------------------------------------------------

class TestFunctionAllowList:
    def documented(self) -> list[str]:
        text = (ROOT / "docs" / "netlist.md").read_text(encoding="utf-8")
        match = re.search(r"these functions: `([^`]*)`", text)
        assert match, "docs/netlist.md lists the functions after 'these functions:'"
        return match.group(1).split()

    def test_documented_functions_are_exactly_the_allowed_ones(self):
        assert sorted(self.documented()) == sorted(FUNCTIONS)

    @pytest.mark.parametrize("call", [
        "sin(t)", "cos(t)", "tan(t)", "asin(t/10)", "acos(t/10)", "atan(t)", "atan2(t, 1)", "sinh(t)", "cosh(t)",
        "tanh(t)", "exp(t)", "log(1 + t)", "sqrt(1 + t)", "abs(t)", "sign(t)", "min(t, 1)", "max(t, 1, 2)",
        "step(t)", "step(t, 0.1)", "ramp(t, 0.1)", "pulse(t, 0.1, 0.2)", "interp(t, [0, 1], [0, 2])"])
    def test_every_documented_function_is_accepted(self, call):
        assert call.split("(")[0] in self.documented()
        expr = parse_expression(call, {"t": netlist.T})
        assert expr.free_symbols == {netlist.T}

    @pytest.mark.parametrize("text, code", [
        ("gamma(t)", "unsafe_expression"), ("factorial(5)", "unsafe_expression"),
        ("Lambda(t, t)", "unsafe_expression"), ("Function(t)", "unsafe_expression"),
        ("Symbol(t)", "unsafe_expression"), ("__import__('os')", "unsafe_expression"),
        ("eval(1)", "unsafe_expression"), ("exec(1)", "unsafe_expression"), ("getattr(t, 1)", "unsafe_expression"),
        ("Integral(t, t)", "unsafe_expression"), ("S(1)", "unsafe_expression"), ("N(t)", "unsafe_expression"),
        ("(lambda: 1)()", "unsafe_expression"), ("lambda: 1", "unsafe_expression"),
        ("sin.__class__", "unsafe_expression"),
        # E is not a constant of the language (write exp(1)); nor are I, oo, zoo, nan, S, N
        ("E", "unknown_name"), ("I", "unknown_name"), ("oo", "unknown_name"), ("zoo", "unknown_name"),
        ("nan", "unknown_name"), ("S", "unknown_name"), ("N", "unknown_name"), ("gamma", "unknown_name"),
        ("eval", "unknown_name"), ("lambda", "bad_expression")])
    def test_other_names_are_refused(self, text, code):
        with pytest.raises(NetlistError) as exc:
            parse_expression(text, {"t": netlist.T}, "f.yaml:3")
        assert exc.value.code == code
        assert exc.value.where == "f.yaml:3"

    def test_refused_in_a_netlist_with_file_line_and_element(self):
        refused(netlist_text(extra="m: {type: torque_source, value: 'gamma(t)'}"), "unsafe_expression",
                EXTRA_LINE, "m")


# -- 3. parameter cycles and reserved names ------------------------------------------------------

class TestParameterNames:
    @pytest.mark.parametrize("params, first", [("{a: b, b: a}", "b"), ("\n  x: 1\n  a: c\n  b: a\n  c: b", "a")])
    def test_cycle_is_one_line(self, params, first):
        err = refused(netlist_text(params=params, j="x" if "x" in params else "a"), "parameter_cycle", None)
        assert f"parameter '{first}'" in err.message and "->" in err.message
        assert re.match(r"f\.yaml:\d+$", err.where)

    def test_cycle_through_set(self):
        text = netlist_text(params="{a: 1.0, b: 2.0}", j="a")
        refused(text, "parameter_cycle", PARAM_LINE, overrides={"a": "b", "b": "a"})

    @pytest.mark.parametrize("command", [["check"], ["simulate", "--quiet"], ["equations"]])
    def test_cycle_on_the_command_line(self, tmp_path, capsys, command):
        path = tmp_path / "cycle.yaml"
        path.write_text(netlist_text(params="{a: 1.0, b: 2.0}", j="a"), encoding="utf-8")
        assert main([command[0], str(path), "--set", "a=b", "--set", "b=a", *command[1:]]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and err.startswith("error[parameter_cycle]")
        assert f"{path}:{PARAM_LINE}" in err

    @pytest.mark.parametrize("name", ["t", "f", "q", "p", "pi", "sin", "step", "interp", "min", "q1", "q12",
                                      "lambda", "None"])
    def test_reserved_names_are_refused(self, name):
        err = refused(netlist_text(params=f"\n  ja: 0.5\n  {name}: 2.0", sim="{t_end: 1.0}"), "reserved_name",
                      PARAM_LINE + 2)
        assert repr(name) in err.message

    @pytest.mark.parametrize("name", ["t0", "q0", "f_c", "p_max", "E", "I", "gamma"])
    def test_ordinary_names_are_accepted(self, name):
        scene = loads(netlist_text(params=f"{{{name}: 0.25}}", j=name), "f.yaml")
        assert float(scene.network.params[name]) == 0.25


# -- 4. degenerate values from the catalogue's declarations --------------------------------------

class TestDegenerateValues:
    @pytest.mark.parametrize("extra, param", [
        ("g: {type: ideal_gear, i: 0}", "i"),
        ("g: {type: ideal_gear, i: 'ja - 0.5'}", "i"),
        ("g: {type: TF, ratio: 0}", "ratio"),
        ("g: {type: TF, ratio: '0*q'}", "ratio"),
        ("g: {type: GY, r: 0}", "r"),
        ("g: {type: dc_motor, k: 0.1, R: 1, L: 1e-3, J: -1e-4}", "J"),
        ("g: {type: dc_motor, k: 0.1, R: 1, L: -1e-3, J: 1e-4}", "L"),
        ("g: {type: dc_motor, k: 0, R: 1, L: 1e-3, J: 1e-4}", "k"),
        ("g: {type: mass, m: -1}", "m"),
        ("g: {type: spring, c: -1e3}", "c"),
        ("g: {type: spur_stage, r1: 0.01, r2: 0.02, level: elastic, c: -1e8}", "c"),
        ("g: {type: spur_stage, r1: '-0.0', r2: 0.02}", "r1"),
        ("g: {type: gear_train, r1: ['-0.0'], r2: [0.02]}", "r1"),
        ("g: {type: piezo_element, k_P: 1e-9, delta_P: -1e-8, C_P: 1e-6}", "delta_P"),
        ("g: {type: planetary, z_sun: -20, z_ring: 60}", "z_sun"),
    ])
    def test_refused(self, extra, param):
        err = refused(netlist_text(extra=extra), "bad_value", EXTRA_LINE, "g")
        assert f"parameter '{param}'" in err.message

    def test_literal_zero_still_leaves_a_part_out(self):
        loads(netlist_text(extra="g: {type: dc_motor, k: 0.1, R: 1, L: 0, J: 0}"), "f.yaml")


# -- 5. size limits ------------------------------------------------------------------------------

class TestLimits:
    def test_file_size(self, tmp_path):
        path = tmp_path / "big.yaml"
        path.write_bytes(b"#" * netlist.MAX_FILE_BYTES + b"\n")
        with pytest.raises(NetlistError) as exc:
            load(path)
        assert exc.value.code == "too_large" and exc.value.where == str(path)

    @pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
    def test_endless_file_is_not_read_whole(self):
        with pytest.raises(NetlistError) as exc:
            load("/dev/zero")
        assert exc.value.code == "too_large"

    def test_number_of_elements(self):
        n = netlist.MAX_ELEMENTS + 1
        text = "elements:\n" + "".join(f"  g{k}: {{type: ground}}\n" for k in range(n))
        err = refused(text, "too_large", 1)
        assert str(n) in err.message

    def test_stack_count(self):
        from elements.piezo import MAX_STACK
        err = refused(netlist_text(extra=f"s: {{type: piezo_stack, n: {MAX_STACK + 1}, k_P: 1e-9, delta_P: 1e-8, "
                                         "C_P: 1e-6}"), "bad_value", EXTRA_LINE, "s")
        assert "parameter 'n'" in err.message and f"at most {MAX_STACK}" in err.message

    @staticmethod
    def chain(p0: float, count: int = 38) -> str:
        lines = [f"  p0: {p0!r}"] + [f"  p{i}: p{i - 1}*p{i - 1} + p{i - 1}" for i in range(1, count + 1)]
        return "\n" + "\n".join(lines)

    def test_chained_parameters_are_numbers_not_expansions(self):
        value = 1e-3
        for _ in range(38):                    # independent float arithmetic
            value = value * value + value
        scene = loads(netlist_text(params=self.chain(1e-3), j="p38"), "f.yaml")
        flat_value = scene.network.params["p38"]
        assert flat_value.free_symbols == {netlist.sp.Symbol("p37")}   # kept as a formula, not expanded
        from multipole.network import flatten
        values = {s.name: v for s, v in flatten(scene.network).param_values().items()}
        assert values["p38"] == pytest.approx(value, rel=1e-12)

    def test_chained_parameters_that_overflow(self):
        value, first = 1.0001, None
        for i in range(1, 39):
            value = value * value + value
            if math.isinf(value):
                first = i
                break
        err = refused(netlist_text(params=self.chain(1.0001), j="p0"), "bad_value", PARAM_LINE + 1 + first)
        assert f"parameter 'p{first}'" in err.message

    def test_billion_laughs(self):
        text = "a: &a [x, x, x, x, x, x, x, x, x, x]\n"
        for k, name in enumerate("bcdefghi"):
            prev = "abcdefghi"[k]
            text += f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 10) + "]\n"
        err = refused(text, "too_large", None)
        assert re.match(r"f\.yaml:\d+$", err.where)

    def test_recursive_alias(self):
        refused("a: &a [1, *a]\n", "yaml_syntax", 1)

    def test_deep_nesting(self):
        refused("a: " + "[" * 5000, "too_large", None)


# -- 6. loader values ----------------------------------------------------------------------------

class TestLoaderValues:
    @pytest.mark.parametrize("tag", ["!!timestamp x", "!!int x", "!!float x", "!!bool x"])
    def test_tags_with_bad_values(self, tag):
        refused(netlist_text(params=f"{{ja: 0.5, a: {tag}}}"), "yaml_value", PARAM_LINE)

    def test_integer_with_thousands_of_digits(self):
        refused(netlist_text(params="{ja: " + "9" * 5000 + "}"), "too_large", PARAM_LINE)

    def test_integer_with_thousands_of_digits_in_a_formula(self):
        with pytest.raises(NetlistError) as exc:
            parse_expression("1" * 400, {}, "f.yaml:2")
        assert exc.value.code == "bad_expression"

    def test_not_utf8(self, tmp_path):
        path = tmp_path / "latin1.yaml"
        path.write_bytes(netlist_text().replace("name: probe", "name: probe\ndescription: caf\xe9").encode("latin-1"))
        with pytest.raises(NetlistError) as exc:
            load(path)
        assert exc.value.code == "not_utf8" and exc.value.where == f"{path}:2"

    @pytest.mark.parametrize("char", ["\x00", "\x07", "\x1b"])
    def test_control_characters(self, char):
        refused(netlist_text().replace("name: probe", f"name: probe\ndescription: 'a{char}b'"), "yaml_syntax", 2)

    @pytest.mark.parametrize("formula", ["sqrt(-1)", "log(-2)", "(-8)**(1/3)", "acos(2)", "2*sqrt(-1)*t"])
    def test_complex_constants(self, formula):
        refused(netlist_text(extra=f"m: {{type: torque_source, value: '{formula}'}}"), "complex_value", EXTRA_LINE, "m")

    @pytest.mark.parametrize("params", ["{b: -4.0, ja: 'sqrt(b)'}", "{b: -8.0, ja: 'b**(1/3)'}"])
    def test_complex_parameter_values(self, params):
        err = refused(netlist_text(params=params), "complex_value", PARAM_LINE)
        assert "parameter 'ja'" in err.message

    def test_parameter_that_divides_by_zero(self):
        refused(netlist_text(params="{b: 0, ja: '1/b'}"), "bad_value", PARAM_LINE)

    def test_list_parameters_use_scene_parameters(self):
        scene = loads(netlist_text(params="{ja: 0.5, ra: 0.01}", extra="g: {type: gear_train, r1: [ra], r2: [0.04]}"),
                      "f.yaml", {"ra": "0.02"})
        assert float(scene.network.children["g"].quantities["ratio"].build(None)) == pytest.approx(-2.0, rel=1e-12)

    def test_list_parameters_with_unknown_names(self):
        refused(netlist_text(extra="g: {type: gear_train, r1: [rb], r2: [0.04]}"), "unknown_name", EXTRA_LINE, "g")

    @pytest.mark.parametrize("name", ["a$b", "x`rm`", "$\\frac{1}{0}$", "a\nb", "[1]", "''"])
    def test_junk_in_the_scene_name(self, name):
        text = netlist_text().replace("name: probe", f"name: {name!r}" if "\n" not in name else 'name: "a\\nb"')
        refused(text, "bad_name", 1)


# -- 7. simulate options -------------------------------------------------------------------------

class TestSimulateOptions:
    @pytest.mark.parametrize("sim, code", [
        ("{t_end: .nan}", "not_numeric"), ("{t_end: .inf}", "not_numeric"), ("{t_end: 1, rtol: .nan}", "not_numeric"),
        ("{t_end: 1, atol: .inf}", "not_numeric"), ("{t_end: 1, dt_out: .inf}", "not_numeric"),
        ("{t_end: 1, atol: -1e-6}", "not_numeric"), ("{t_end: 1, dt_out: -1e-3}", "not_numeric"),
        ("{t_end: 0}", "not_numeric"), ("{t_end: '1'}", "not_numeric"), ("{t_end: true}", "not_numeric"),
        ("{t_end: 1, max_step: 1e-300}", "bad_option"),
        ("{t_end: 1, rtol: 1e-16}", "bad_option"), ("{t_end: 1, rtol: 1}", "bad_option"),
        ("{t_end: 1, dt_out: 2}", "bad_option"),
        ("{t_end: 1, solver: [RK45]}", "bad_option"), ("{t_end: 1, solver: Euler}", "unknown_solver"),
    ])
    def test_refused_at_load(self, sim, code):
        refused(netlist_text(sim=sim), code, SIM_LINE)

    def test_accepted(self):
        scene = loads(netlist_text(sim="{t_end: 2, dt_out: 1e-3, rtol: 1e-14, atol: 1e-12, max_step: 1e-2}"), "f.yaml")
        assert scene.simulate == {"t_end": 2.0, "dt_out": 1e-3, "rtol": 1e-14, "atol": 1e-12, "max_step": 1e-2}

    def test_the_same_validator_serves_command_line_values(self):
        check = netlist.validate_simulate_options
        assert check({"t_end": 0.5, "dt_out": None, "rtol": 1e-6}) == {"t_end": 0.5, "rtol": 1e-6}
        for options, code in [({"t_end": 1.0, "dt_out": -1.0}, "not_numeric"), ({"rtol": float("nan")}, "not_numeric"),
                              ({"t_end": 1.0, "dt_out": 5.0}, "bad_option"), ({"max_step": -1.0}, "not_numeric")]:
            with pytest.raises(NetlistError) as exc:
                check(options, "cli.yaml")
            assert exc.value.code == code and exc.value.where == "cli.yaml"

    def test_run_validates_overrides_of_every_caller(self):
        from multipole import pipeline
        scene = loads(netlist_text(sim="{t_end: 1.0, dt_out: 0.1}"), "f.yaml")
        for kwargs, code in [({"dt_out": -1.0}, "not_numeric"), ({"rtol": 1e-16}, "bad_option"),
                             ({"t_end": float("nan")}, "not_numeric"), ({"dt_out": 2.0}, "bad_option")]:
            with pytest.raises(NetlistError) as exc:
                pipeline.run(scene, progress=False, **kwargs)
            assert exc.value.code == code and exc.value.where == "f.yaml", str(exc.value)
        with pytest.raises(MultipoleError) as exc:           # the grid is sized by simulate.output_grid
            pipeline.run(scene, dt_out=1e-320, progress=False)
        assert exc.value.code == "grid_too_large"

    def test_shorter_run_than_the_scene_grid(self):
        from multipole import pipeline
        scene = loads(netlist_text(sim="{t_end: 1.0, dt_out: 0.1}"), "f.yaml")
        result = pipeline.run(scene, t_end=0.05, progress=False)    # the scene's dt_out is longer: default grid
        assert result.t[-1] == pytest.approx(0.05, rel=1e-12) and len(result.t) > 2
        # torque 1 N*m on J = 0.5 kg*m^2 from rest: p = t
        assert result.states[-1, 0] == pytest.approx(0.05, rel=1e-6)


def test_gear_train_stage_count():
    from elements.gears import MAX_STAGES
    radii = ", ".join(["0.01"] * (MAX_STAGES + 1))
    err = refused(netlist_text(extra=f"g: {{type: gear_train, r1: [{radii}], r2: [{radii}]}}"), "bad_value",
                  EXTRA_LINE, "g")
    assert f"at most {MAX_STAGES}" in err.message


# -- 7. classes the fuzz campaign found (docs/testing.md) -----------------------------------------

_TWO_BODIES = """\
elements:
  J1: {type: inertia, J: 1.0}
  d: {type: damper, law: "LAW"}
  J2: {type: inertia, J: 1.0, omega0: 1.0}
connections:
  - [J1.b, d.a]
  - [d.b, J2.a]
outputs: [J1.omega]
simulate: {t_end: 0.1}
"""


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("law", ["sign(1/f)", "abs(sqrt(log(f)))"])
def test_law_the_code_printer_cannot_write_is_one_line(tmp_path, capsys, law):
    path = tmp_path / "law.yaml"
    path.write_text(_TWO_BODIES.replace("LAW", law), encoding="utf-8")
    assert main(["simulate", str(path), "--quiet"]) == 2
    err = _one_line(capsys)
    assert err.startswith("error[unsupported_expression]") and "element d" in err and str(path) in err


def test_reference_that_is_not_a_mapping(tmp_path, capsys):
    path = tmp_path / "ref.yaml"
    path.write_text("elements: {J: {type: inertia, J: 1.0}}\nreference: \"x\"\n", encoding="utf-8")
    assert main(["check", str(path)]) == 2
    assert _one_line(capsys).startswith(f"error[bad_value] {path}:2")


@pytest.mark.parametrize("text", [
    "elements: {L1: {type: inductor, L: 5.0e-324}}\n",                   # 1/L overflows at every sample
    "elements:\n  tf: {type: TF, ratio: \"ramp(sqrt(t) - 0.0005)\"}\n  k: {type: spring, c: 10.0}\n"
    "  J: {type: inertia, J: 1.0}\nconnections:\n  - [tf.b, k.a]\n  - [J.b, tf.a]\n",   # NaN at t < 0
])
def test_structural_check_survives_entries_that_do_not_evaluate(tmp_path, capsys, text):
    """The analyser samples constraint Jacobians numerically; an entry that is not identically zero
    but overflows or is undefined at a sample is generically nonzero, as its finite twin would be."""
    path = tmp_path / "s.yaml"
    path.write_text(text, encoding="utf-8")
    twin = tmp_path / "twin.yaml"
    twin.write_text(text.replace("5.0e-324", "1.0e-3").replace("sqrt(t) - 0.0005", "t + 1"), encoding="utf-8")
    code = main(["check", str(path)])
    out = capsys.readouterr()
    assert "Traceback" not in out.err and code == main(["check", str(twin)])


@pytest.mark.parametrize("law", ["sin(exp(2988.190461**3))", "cos(1e308*10)", "exp(1000.0)", "exp(1000)*f"])
def test_constant_beyond_float_range_is_refused_at_once(law):
    """sympy's numbers have no range limit; sin of exp(2.7e10) took it practically forever (a hang in
    the fuzz campaign, seed 2027 case 5636)."""
    text = netlist_text(extra=f'g: {{type: damper, law: "{law}"}}')
    err = refused(text, "bad_expression", EXTRA_LINE, "g")
    assert "beyond the range" in err.message


def test_equation_text_does_not_simplify_functions_of_the_unknowns(tmp_path, capsys, monkeypatch):
    """sympy's simplify of tanh(73 + f) - pi/f ran for minutes (fuzz campaign, seed 2028, equations
    case 150); the printed equations only simplify rational expressions."""
    import multipole.equations as equations

    def refuse(expr, *args, **kwargs):
        if expr.atoms(equations.sp.Function):
            raise AssertionError(f"simplify called on {expr}")
        return expr
    monkeypatch.setattr(equations.sp, "simplify", refuse)
    path = tmp_path / "law.yaml"
    path.write_text(_TWO_BODIES.replace("LAW", "tanh(73.24 + f) - (pi + pi/f)"), encoding="utf-8")
    assert main(["equations", str(path)]) == 0
    assert "tanh" in capsys.readouterr().out


def test_nonlinear_loop_whose_coefficient_is_a_bare_parameter(tmp_path, capsys):
    """Tearing a loop substituted parameter values into a coefficient that was one parameter alone,
    which gave a Python float instead of a sympy number (AttributeError; fuzz seed 2030 case 284)."""
    path = tmp_path / "tear.yaml"
    path.write_text(textwrap.dedent("""\
        elements:
          e0: {type: MTF, matrix: [[3908.6448781946165, 5993.3308793]], domains_a: [electrical],
               domains_b: [translational, electrical]}
          e1: {type: piezo_element, k_P: 0.024357177009724257, delta_P: 177.27106, C_P: 57}
          e2: {type: GY, r: -31.1427, domain_a: translational, domain_b: translational}
          e3: {type: damper, law: "sin(sign(f))**2", domain: translational}
        connections:
          - [e0.b2, e1.elec_b]
          - [e2.a, e3.a]
          - [e1.mech_a, e0.b1]
          - [e3.b, e2.b]
        """), encoding="utf-8")
    assert main(["check", str(path)]) == 0
    assert "Traceback" not in capsys.readouterr().err


@pytest.mark.parametrize("name", ["/etc/passwd", "../outside.csv", "tables/../../outside.csv"])
def test_a_data_file_outside_the_netlists_folder_is_refused_unread(tmp_path, capsys, name):
    """A netlist may read only the files of its own folder (and below): an absolute path or one that
    climbs out is refused with the line and the element, before anything is opened."""
    (tmp_path / "outside.csv").write_text("theta [rad], r [m]\n")
    folder = tmp_path / "scene"
    (folder / "tables").mkdir(parents=True)
    path = folder / "wheel.yaml"
    path.write_text(f"name: wheel\nelements:\n  w: {{type: curve_roll, contour: {name}}}\nconnections: []\n")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error[file_outside_folder] ") and "wheel.yaml:3 element 'w'" in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
