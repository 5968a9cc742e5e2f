"""Every diagnostic code, rendered from a netlist that triggers it, reads in the user's names.

The codes come from the registry (:data:`multipole.diagnostics.REGISTRY`), so a new check without a
triggering netlist here fails :func:`test_every_registered_code_has_a_triggering_netlist`.  Each
rendered text is searched for the analyser's internal names (nodes, inner primitives, port
variables, sympy forms) and for broken articles.
"""
import re
from pathlib import Path

import numpy as np
import pytest

from helpers import run, scene
from multipole import pipeline
from multipole.causality import Finding
from multipole.checks import Context, listing, user_expression
from multipole.cli import main
from multipole.diagnostics import REGISTRY, run_checks
from multipole.errors import MultipoleError, MultipoleWarning
from multipole.netlist import load

ROOT = Path(__file__).resolve().parents[1]
DIAGRAMS = ROOT / "diagrams"

#: the DC motor of diagrams/weber/dc_motor.yaml with the supply's ground forgotten (issue 8 §2)
OPEN_GROUND = (DIAGRAMS / "weber" / "dc_motor.yaml").read_text() \
    .replace("  gnd:     {type: ground, domain: electrical}\n", "") \
    .replace("  - [supply.n, gnd.p]\n", "")

ISOLATED = """
name: isolated
elements:
  drive:   {type: torque_source, value: 1}
  rotor:   {type: inertia, J: 0.1}
  spare:   {type: inertia, J: 0.2}
  spring:  {type: spring, c: 100}
  housing: {type: ground}
connections:
  - [drive.p, rotor.a]
  - [spare.b, spring.a]
  - [spring.b, housing.p]
"""

TWO_TORQUE_SOURCES = """
name: two_torque_sources
elements:
  t1: {type: torque_source, value: 1}
  t2: {type: torque_source, value: "2*step(t - 1)"}
connections:
  - [t1.p, t2.p]
"""

SPLIT = """
name: split
elements:
  motor:  {type: torque_source, value: 5}
  input:  {type: inertia, J: 1.0e-3}
  path_A: {type: ideal_gear, i: -3}
  path_B: {type: ideal_gear, i: IB}
  output: {type: inertia, J: 2.0e-2}
connections:
  - [motor.p, input.a]
  - [input.b, path_A.a, path_B.a]
  - [path_A.b, path_B.b, output.a]
"""

PARALLEL_TRANSFORMERS = """
name: parallel_transformers
elements:
  supply: {type: voltage_source, value: "10"}
  t1: {type: TF, ratio: 2, domain_a: electrical, domain_b: electrical}
  t2: {type: TF, ratio: 2, domain_a: electrical, domain_b: electrical}
  load: {type: resistor, R: 5}
  gnd: {type: ground, domain: electrical}
connections:
  - [supply.p, t1.a, t2.a]
  - [t1.b, t2.b, load.a]
  - [load.b, supply.n, gnd.p]
"""

NO_GROUND = """
name: no_ground
elements:
  v: {type: voltage_source, value: 1}
  r: {type: resistor, R: 5}
connections:
  - [v.p, r.a]
  - [r.b, v.n]
"""

CANCELLING_RESISTORS = """
name: cancelling_resistors
elements:
  supply: {type: voltage_source, value: 1}
  r1: {type: resistor, R: 2.0}
  r2: {type: R, r: -2.0, domain: electrical}
  gnd: {type: ground, domain: electrical}
connections:
  - [supply.p, r1.a]
  - [r1.b, r2.p]
  - [supply.n, gnd.p]
"""

INCONSISTENT_START = """
name: inconsistent_start
elements:
  drive: {type: torque_source, value: 2}
  J_1:   {type: inertia, J: 0.01}
  gear:  {type: ideal_gear, i: 4}
  J_2:   {type: inertia, J: 0.3, omega0: 1.5}
connections:
  - [drive.p, J_1.a]
  - [J_1.b, gear.a]
  - [gear.b, J_2.a]
"""


def _file(path):
    return lambda: load(path)


def _text(text):
    return lambda: scene(text)


def linkage_triggers() -> dict:
    """The position and closure checks, on the netlists of tests/test_linkage_checks.py."""
    import test_linkage_checks as lk
    return {"position_overdetermined": (_text(lk.TWO_OUTPUTS), ["rocker and extra", "join extra.b2"]),
            "position_loop": (_text(lk.NO_ORDER), ["d1 and d2"]),
            "position_undetermined": (_text(lk.ANCHOR_TO_ANCHOR), ["no element determines the position of"]),
            "cannot_assemble": (_text(lk.unreachable(0.6, 0.25)), ["rocker cannot be assembled", "by 0.05 m"]),
            "redundant_closure": (lk.redundant_closure_scene, ["rocker: only 0 of its 1"]),
            "mobility": (_text(lk.FOURBAR), ["crank (DAN", "rocker (DDD"]),
            "vdi_structure": (_text(lk.FOURBAR), ["crank (DAN: rotary drive, class 1)"])}


#: code -> (scene, words the message or fix must contain: the user's names for what went wrong)
TRIGGERS = {
    "powerless_source": (_text(OPEN_GROUND), ["supply", "supply.n", "connect supply.n to ground"]),
    "isolated_subnetwork": (_text(ISOLATED), ["housing, spare and spring"]),
    "source_conflict": (_text(TWO_TORQUE_SOURCES), ["t1 and t2", "an angular velocity source"]),
    "kinematic_overdetermination": (_text(SPLIT.replace("IB", "-3")), ["path_A", "path_B"]),
    "static_overdetermination": (_text(PARALLEL_TRANSFORMERS), ["t1", "t2", "voltage"]),
    "locked_loop": (_text(SPLIT.replace("IB", "-2.5")), ["path_A", "path_B"]),
    "input_differentiation": (_file(DIAGRAMS / "hard" / "differentiated_step.yaml"), ["drive", "w0*step(t - 0.1)"]),
    "missing_cross_coupling": (_file(DIAGRAMS / "weber" / "spur_normal_no_friction.yaml"), ["mesh", "mu"]),
    "underdetermined": (_text(NO_GROUND), ["nothing determines the", "add a ground"]),
    "singular_loop": (_text(CANCELLING_RESISTORS), ["r1", "r2"]),
    "initial_values": (_text(INCONSISTENT_START), ["J_2.p", "given 0.45"]),
    "derivative_causality": (_file(DIAGRAMS / "weber" / "dc_motor.yaml"), ["load", "motor"]),
    "algebraic_loop": (_file(DIAGRAMS / "hard" / "nonlinear_loop.yaml"), ["d_1", "d_2"]),
    "unconnected_port": (_text(OPEN_GROUND), ["supply.n"]),
    "degrees_of_freedom": (_file(DIAGRAMS / "weber" / "dc_motor.yaml"), ["motor.inertia.p"]),
    **linkage_triggers(),
    **__import__("test_belt_contour").contour_triggers(),     # the curve roll's side check
    **__import__("test_belt_planar").planar_triggers(),       # the planar span against its roll
    **__import__("test_belt_planar_curve").planar_curve_triggers(),   # the curve span against its roll
    **__import__("test_belt_monitors").belt_triggers(),     # the static belt checks (elements/belt_checks.py)
}

#: codes no netlist can reach today; each is rendered from a finding planted on a real scene instead
#: (a safety net of the analyser: structural over-determination left after its resolution rounds)
PLANTED = {"overdetermined": (_text(SPLIT.replace("IB", "-3")), ["path_A", "path_B"])}

#: the analyser's names that must never reach a message or fix
INTERNAL = [
    (re.compile(r"node\("), "a node name"),
    (re.compile(r"\.j\."), "an inner junction"),
    (re.compile(r"Heaviside|DiracDelta"), "a sympy form of step()"),
    (re.compile(r"\b\w+(\.\w+)+\.[ef]\b"), "a port variable name"),
    (re.compile(r"\b\w+\.(src|j|loop|res|gap|friction)\b"), "an inner primitive of an element"),
    (re.compile(r"(?<![\w.])a a\b"), "a doubled article"),
    (re.compile(r"(?<![\w.])a [aeiou]\w", re.IGNORECASE), "'a' before a vowel"),
]


def internal_names(text: str) -> list:
    return [f"{what}: {m.group(0)!r}" for rx, what in INTERNAL for m in [rx.search(text)] if m]


def rendered(diagnostics) -> str:
    return "\n".join(str(d) for d in diagnostics)


def test_every_registered_code_has_a_triggering_netlist():
    from multipole.catalogue import catalogue
    catalogue()                       # element libraries register their own checks when they load
    assert set(REGISTRY) == set(TRIGGERS) | set(PLANTED)


@pytest.mark.parametrize("code", sorted(TRIGGERS))
def test_each_code_renders_in_the_users_names(code):
    make, words = TRIGGERS[code]
    an = pipeline.check(make())
    found = [d for d in an.diagnostics if d.code == code]
    assert found, f"{code} not triggered; got {[d.code for d in an.diagnostics]}"
    for d in found:
        text = f"{d.message}\n{d.fix}\n{' '.join(d.path)}"
        assert internal_names(text) == [], text
        assert d.severity == REGISTRY[code].severity
    assert all(w in "\n".join(f"{d.message} {d.fix}" for d in found) for w in words), rendered(found)


@pytest.mark.parametrize("code", sorted(PLANTED))
def test_codes_without_a_netlist_render_from_a_planted_finding(code):
    make, words = PLANTED[code]
    an = pipeline.check(make())
    kinds = {"overdetermined": "overdetermined"}
    support = next(f.equations for f in an.findings if f.kind == "redundant")
    an.findings = [Finding(kinds[code], support)]
    found = [d for d in run_checks(Context(an), stages=("structure",)) if d.code == code]
    assert len(found) == 1
    text = f"{found[0].message}\n{found[0].fix}"
    assert internal_names(text) == [] and all(w in text for w in words), text


@pytest.mark.parametrize("path", sorted(DIAGRAMS.rglob("*.yaml")), ids=lambda p: p.stem)
def test_scenes_in_diagrams_show_no_internal_names_and_no_false_warning(path):
    """Every shipped scene is wired on purpose (the DC motor scenes of diagrams/weber among them):
    no open-terminal warning, and no internal name in any diagnostic."""
    diagnostics = pipeline.check(load(path)).diagnostics
    assert internal_names(rendered(diagnostics)) == [], rendered(diagnostics)
    assert [d.code for d in diagnostics if d.severity == "warning"] == []


def test_a_nonlinear_loop_without_solution_at_the_start_is_named_by_its_elements():
    """The second kind of singular loop: a massless pinion whose Coulomb tooth friction has no
    solution at t = 0 (see tests/test_derivative_causality.py)."""
    from test_derivative_causality import MASSLESS_PINION
    an = pipeline.check(scene(MASSLESS_PINION.replace("DAMPING", "0.0")))
    [d] = an.errors
    assert d.code == "singular_loop" and "through mesh" in d.message and d.elements == ["mesh"]
    assert internal_names(f"{d.message}\n{d.fix}") == []


def test_the_patterns_catch_what_the_issue_quoted():
    """The texts issue 8 quoted before the fix are all rejected (so the patterns can fail)."""
    for bad in ("the torque around node(d, node(k is imposed twice", "add a spring at shaft.j.b",
                "nothing determines load.j.x.e", "flow source imposes 10*Heaviside(t - 0.1, 1)",
                "drive one side with a angular velocity source instead"):
        assert internal_names(bad), bad


def test_open_ground_is_warned_first_and_named():
    """The forgotten ground of issue 8 §2: the supply's current is forced to zero through its open
    n pin.  The check still exits 0 (the open pin is a documented default) but the first line of
    its report warns, naming the pin and the fix; a run warns too, and indeed gives zero current."""
    an = pipeline.check(scene(OPEN_GROUND))
    assert an.ok and an.diagnostics[0].code == "powerless_source"
    d = an.diagnostics[0]
    assert d.severity == "warning" and d.ports == ["supply.n"] and d.fix.startswith("connect supply.n to ground")
    flywheel = OPEN_GROUND.replace("  - [load.b, bearing.a, brake.p]", "  - [load.b, bearing.a, brake.p, flywheel.a]") \
        .replace("  housing:", "  flywheel: {type: inertia, J: 1.0e-5}\n  housing:")
    [d] = [d for d in pipeline.check(scene(flywheel)).diagnostics if d.severity == "warning"]
    assert d.ports == ["supply.n"]          # the flywheel's free end b does not silence the supply
    with pytest.warns(MultipoleWarning, match=r"\[powerless_source\] supply can deliver no power.*supply\.n"):
        res = run(OPEN_GROUND.replace("t_end: 1.6", "t_end: 0.01"))      # simulate repeats the warning
    assert np.all(res["motor.current"] == 0.0)


def test_open_ground_warning_is_printed_first(tmp_path, capsys):
    path = tmp_path / "open.yaml"
    path.write_text(OPEN_GROUND)
    assert main(["check", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].startswith("  warning[powerless_source] supply can deliver no power")
    assert lines[-1] == "well-posed: 0 error(s), 1 warning(s), 1 state(s)"


def test_a_source_that_only_sets_a_potential_is_not_warned_about():
    """The offset source of a floating motor circuit carries no current by design (nothing closes a
    loop through it): its zero current comes from the circuit, not from an unconnected pin — not even
    from the free shaft end in the same scene."""
    from test_dc_motor import motor_scene
    an = pipeline.check(scene(motor_scene(shaft="free", motor_extra=", grounded: false", supply="floating")))
    assert an.ok and [d.code for d in an.diagnostics if d.severity == "warning"] == []


@pytest.mark.parametrize("kind,n", [("element", 1), ("stack", 3)])
def test_open_electrodes_of_a_force_sensor_are_not_a_forgotten_ground(kind, n):
    """A massless piezo sensor with open electrodes under a constant force: the force source does no
    work because the force is constant (the stroke takes its static value at t = 0), not because a
    pin is open; sensing the open-circuit voltage is the point of the scene."""
    from test_piezo import piezo_scene
    an = pipeline.check(scene(piezo_scene(kind, n, "open", "force", m=0, r=0, t_end=1e-6, dt=1e-7)))
    assert an.ok and [d.code for d in an.diagnostics if d.severity == "warning"] == []


def test_spare_part_that_moves_from_its_initial_value_is_not_isolated():
    """A separate free system with a nonzero initial value is a legitimate second system."""
    moving = ISOLATED.replace("spare:   {type: inertia, J: 0.2}", "spare:   {type: inertia, J: 0.2, omega0: 3}")
    assert "isolated_subnetwork" not in [d.code for d in pipeline.check(scene(moving)).diagnostics]
    single = "elements:\n  m: {type: mass, m: 1, v0: 1}\n  k: {type: spring, c: 4, domain: translational}\n" \
             "connections:\n  - [m.b, k.a]\n"
    assert [d.code for d in pipeline.check(scene(single)).diagnostics if d.severity == "warning"] == []


def test_user_expression_writes_steps_as_the_netlist_does():
    import sympy as sp
    t, w0 = sp.symbols("t w0")
    assert user_expression(w0 * sp.Heaviside(t - sp.Rational(1, 10), 1)) == "w0*step(t - 1/10)"
    assert user_expression(sp.Max(0, t) + sp.Abs(w0) * sp.Min(t, 1)) == "abs(w0)*min(1, t) + max(0, t)"
    assert listing(["a"]) == "a" and listing(["a", "b", "c"]) == "a, b and c"


def test_the_diagnostics_page_lists_every_code_with_its_severity():
    rows = dict(re.findall(r"^\| `(\w+)` \| (\w+) \|", (ROOT / "docs" / "diagnostics.md").read_text(), re.MULTILINE))
    assert rows == {code: check.severity for code, check in REGISTRY.items()}
    assert list(rows) == list(REGISTRY)          # in report order


def test_the_forgotten_ground_example_of_the_page_is_what_check_prints(tmp_path, capsys, monkeypatch):
    page = (ROOT / "docs" / "diagnostics.md").read_text()
    shown = re.search(r"\$ multipole check dc_motor_open.yaml\n(.*?)\n```", page, re.DOTALL).group(1)
    (tmp_path / "dc_motor_open.yaml").write_text(OPEN_GROUND)
    monkeypatch.chdir(tmp_path)
    assert main(["check", "dc_motor_open.yaml"]) == 0
    assert capsys.readouterr().out.rstrip("\n") == shown


#: a port variable in printed equations: ``element.port.e`` of the netlist, or ``element.innerN.e``
PORT_VARIABLE = re.compile(r"\b(\w+(?:\.\w+)+)\.[ef]\b")


def internal_names_in_equations(text: str, flat) -> list:
    """Internal names in the equation text or an output list, where port variables belong (so the
    port-variable pattern of :data:`INTERNAL` is replaced by: every ``x.y.e`` names a netlist port
    or a numbered inner variable of an element)."""
    bad = [f"{what}: {m.group(0)!r}" for rx, what in INTERNAL[:3] for m in [rx.search(text)] if m]
    rx, what = INTERNAL[4]            # an element's quantity may carry such a name (a roll's friction torque)
    bad += [f"{what}: {m.group(0)!r}" for m in rx.finditer(text) if m.group(0) not in flat.quantities][:1]
    return bad + [f"a port variable no netlist port shows: {m.group(0)!r}" for m in PORT_VARIABLE.finditer(text)
                  if m.group(1) not in flat.external_ports and not re.fullmatch(r"\w+\.inner\d+", m.group(1))]


@pytest.mark.parametrize("path", sorted(DIAGRAMS.rglob("*.yaml")), ids=lambda p: p.stem)
def test_equations_steps_and_unknown_output_fix_use_the_netlists_names(path):
    """``multipole equations --steps`` (state equations, evaluation order, Weber's chains) and the
    fix of an unknown output name the netlist's ports, elements and expressions: no node(...), no
    inner junction, no sympy Heaviside, no port variable of a primitive an element is built of."""
    sc = load(path)
    if not pipeline.check(sc).ok:
        pytest.skip("not well-posed (on purpose): no equations to print")
    eq = pipeline.equations(sc)
    flat = eq.analysis.flat
    text = eq.to_text(sc.outputs, steps=True)
    assert internal_names_in_equations(text, flat) == [], internal_names_in_equations(text, flat)
    element = next(iter(flat.elements)) if not sc.outputs else sc.outputs[0].split(".")[0]
    with pytest.raises(MultipoleError) as err:
        eq.output(f"{element}.no_such_output")
    assert err.value.code == "unknown_output"
    offered = [o for o in err.value.fix.split(": ", 1)[1].split(", ") if o != "…"]
    assert internal_names_in_equations(err.value.fix, flat) == [], err.value.fix
    assert all(o in flat.quantities or o[:-2] in flat.external_ports or o in eq.state_names for o in offered), offered
    assert [q for q in flat.quantities if q.startswith(element + ".")][:1] == \
        [o for o in offered if o in flat.quantities][:1]      # the element's quantities come first


def test_equation_patterns_catch_inner_names():
    """The scan above can fail: the names the equations printed before (node owners, inner junction
    ports, the mass's inner port) are all caught."""
    flat = pipeline.equations(load(DIAGRAMS / "drive_train.yaml")).analysis.flat
    for bad in ("load.j.a.e = shaft.p.e", "[node(gear.b, shaft.j.a)]", "rotor.p.e", "k*Heaviside(q)"):
        assert internal_names_in_equations(bad, flat), bad
    assert internal_names_in_equations("load.a.e = rotor.inner1.e + step(q)", flat) == []
