"""Bad input: one clean line naming file, line and element; exit 2; nothing executed."""
import os
from pathlib import Path

import pytest

from multipole.cli import main

GOOD = """\
name: ok
elements:
  motor: {type: torque_source, value: 1}
  body:  {type: inertia, J: 0.1}
connections:
  - [motor.p, body.a]
"""

MARKER = "/tmp/multipole_pwned_marker"

CASES = {
    "malformed_yaml": ("elements:\n  motor: {type: torque_source, value: 1\n", ["invalid YAML"], ":3"),
    "duplicate_key": (GOOD.replace("  body:", "  motor: {type: ground}\n  body:"), ["'motor' appears twice"], ":4"),
    "zero_inertia": (GOOD.replace("J: 0.1", "J: 0"), ["'J'", "must be positive", "element 'body'"], ":4"),
    "negative_inertia": (GOOD.replace("J: 0.1", "J: -2*0.1"), ["must be positive", "element 'body'"], ":4"),
    "unknown_solver": (GOOD + "simulate: {t_end: 1, solver: foo}\n", ["unknown solver 'foo'"], ":7"),
    "unknown_type": (GOOD.replace("type: inertia", "type: inertai"), ["unknown element type", "inertia"], ":4"),
    "unknown_parameter": (GOOD.replace("J: 0.1", "J: 0.1, K: 3"), ["no parameter 'K'", "element 'body'"], ":4"),
    "missing_parameter": (GOOD.replace("J: 0.1", "omega0: 1"), ["needs parameter 'J'", "element 'body'"], ":4"),
    "unknown_port": (GOOD.replace("body.a]", "body.c]"), ["no port 'c'", "element 'body'"], ":6"),
    "port_used_twice": (GOOD + "  - [body.a, motor.p]\n", ["used twice"], ":7"),
    "non_numeric": (GOOD.replace("J: 0.1", "J: [1, 2]"), ["expected a number", "element 'body'"], ":4"),
    "unknown_name": (GOOD.replace("J: 0.1", "J: J_rotor"), ["J_rotor", "element 'body'"], ":4"),
    "code_import": (GOOD.replace("value: 1", f"value: \"__import__('os').system('touch {MARKER}')\""),
                    ["element 'motor'"], ":3"),
    "code_attribute": (GOOD.replace("value: 1", "value: \"t.__class__\""), ["element 'motor'"], ":3"),
    "code_lambda": (GOOD.replace("value: 1", "value: \"(lambda: 1)()\""), ["element 'motor'"], ":3"),
    "python_tag": ("elements: !!python/object/apply:os.system ['touch " + MARKER + "']\n", ["invalid YAML"], ":"),
    "unknown_output": (GOOD + "outputs: [body.speed]\n", ["unknown output 'body.speed'"], ":7"),
    "unknown_top_key": (GOOD + "simulation: {t_end: 1}\n", ["unknown top-level key"], ":7"),
}

#: the error code each case must carry (the contract scripts match on)
CODES = {
    "malformed_yaml": "yaml_syntax", "duplicate_key": "duplicate_key", "zero_inertia": "bad_value",
    "negative_inertia": "bad_value", "unknown_solver": "unknown_solver", "unknown_type": "unknown_type",
    "unknown_parameter": "unknown_parameter", "missing_parameter": "missing_parameter",
    "unknown_port": "unknown_port", "port_used_twice": "port_used_twice", "non_numeric": "not_numeric",
    "unknown_name": "unknown_name", "code_import": "unsafe_expression", "code_attribute": "unsafe_expression",
    "code_lambda": "unsafe_expression", "python_tag": "yaml_syntax", "unknown_output": "unknown_output",
    "unknown_top_key": "unknown_key",
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_gives_one_clean_line(case, tmp_path, capsys):
    text, words, line = CASES[case]
    if os.path.exists(MARKER):
        os.remove(MARKER)
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    verb = "simulate" if case == "unknown_output" else "check"
    code = main([verb, str(path), "--t-end", "0.1"] if verb == "simulate" else [verb, str(path)])
    out = capsys.readouterr()
    assert code == 2
    assert "Traceback" not in out.err + out.out
    lines = [ln for ln in out.err.splitlines() if ln.strip()]
    assert len(lines) == 1, out.err
    assert lines[0].startswith(f"error[{CODES[case]}] "), lines[0]
    assert str(path) + line in lines[0]
    for w in words:
        assert w in lines[0]
    assert not os.path.exists(MARKER)


def test_overrides_must_name_existing_parameters(tmp_path, capsys):
    path = tmp_path / "scene.yaml"
    path.write_text(GOOD)
    assert main(["check", str(path), "--set", "body.Q=3"]) == 2
    assert "no parameter 'Q'" in capsys.readouterr().err
    assert main(["check", str(path), "--set", "gain=3"]) == 2
    assert "no such scene or element parameter" in capsys.readouterr().err
    assert main(["check", str(path), "--set", "body.J=0.5"]) == 0
