"""`multipole diagram`: Weber block diagrams drawn from the causality the analyser found.

The figures are checked as files (valid PNG/SVG); the drawing itself is checked on the drawing
model (`multipole.diagram.layout`): blocks and arrows against the analysis and against Weber's
rules for junctions, transformers and storage (Mehrpoltheorie, sections 4.1-4.3):

* a Σ box computes exactly one of its variables from the others, a branching point (dot) receives
  exactly one and distributes it;
* a transformer passes the flow one way and the effort the other way;
* an inertia in integral causality receives the effort and returns the flow, in derivative
  causality the other way round.
"""
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

import pytest

from helpers import check, scene
from multipole import pipeline
from multipole.cli import main
from multipole.diagram import layout
from multipole.netlist import load

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted((ROOT / "diagrams").rglob("*.yaml"))

GEARED = """
name: geared
description: two inertias joined by an ideal gear
parameters: {J1: 0.01, J2: 0.3, i: 4.0}
elements:
  drive: {type: torque_source, value: 2.0}
  J_2:   {type: inertia, J: J2}
  gear:  {type: ideal_gear, i: i}
  J_1:   {type: inertia, J: J1}
connections:
  - [drive.p, J_2.a]
  - [J_2.b, gear.b]
  - [gear.a, J_1.a]
"""

# fifteen elements: electrical input, a gyrator, two gear stages, parallel spring/damper,
# two loads on one node, nonlinear friction, an unconnected port
LARGE = """
name: large
elements:
  supply: {type: voltage_source, value: "24*step(t)"}
  Ra:     {type: resistor, R: 0.5}
  La:     {type: inductor, L: 0.002}
  gnd:    {type: ground, domain: electrical}
  emf:    {type: GY, r: 0.05, domain_a: electrical, domain_b: rotational}
  rotor:  {type: inertia, J: 1.0e-4}
  g1:     {type: ideal_gear, i: 4}
  shaft1: {type: inertia, J: 1.0e-3}
  g2:     {type: ideal_gear, i: 3}
  spring: {type: spring, c: 500}
  damp:   {type: damper, d: 0.1}
  load1:  {type: inertia, J: 0.2}
  fric:   {type: damper, law: "2*tanh(f/0.01)"}
  housing: {type: ground}
  load2:  {type: inertia, J: 0.1}
connections:
  - [supply.p, Ra.a]
  - [Ra.b, La.a]
  - [La.b, emf.a]
  - [supply.n, gnd.p]
  - [emf.b, rotor.a]
  - [rotor.b, g1.a]
  - [g1.b, shaft1.a]
  - [shaft1.b, g2.a]
  - [g2.b, spring.a, damp.a]
  - [spring.b, damp.b, load1.a, load2.a]
  - [load1.b, fric.a]
  - [fric.b, housing.p]
"""


def _analysed():
    """(name, analysis, diagram) for every scene in diagrams/ and the inline ones."""
    out = []
    for path in SCENES:
        sc = load(path)
        an = pipeline.check(sc)
        out.append((path.stem, an, layout(an, sc.element_types)))
    for name, text in (("geared", GEARED), ("large", LARGE)):
        sc = scene(text)
        an = pipeline.check(sc)
        out.append((name, an, layout(an, sc.element_types)))
    return out


CASES = _analysed()
WELL_POSED = [c for c in CASES if c[1].ok]


def _ids(cases):
    return [c[0] for c in cases]


def _rigid_loops(an):
    """Elements of rigid couplings resolved by derivative causality: their equations are solved
    together, so the analyser may orient the arrows inside either way."""
    return {e for d in an.diagnostics if d.code == "derivative_causality" for e in d.elements}


def _trace(diagram, arrow):
    """Follow an arrow back through blocks that only pass a value on; the owner of the block
    where the value is computed."""
    block = arrow.source
    for _ in range(len(diagram.blocks) + 1):
        b = diagram.blocks[block]
        if not b.identity:
            return b.owner
        sources = {a.source for a in diagram.arrows if a.target == block and a.row == arrow.row}
        assert len(sources) == 1, f"{block} receives {arrow.row} from {sources}"
        block = sources.pop()
    raise AssertionError(f"{arrow.variable}: the arrows run in a circle")


# ---------------------------------------------------------------------------------------------
# the command

@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_command_writes_png_and_svg_for_every_scene(path, tmp_path, capsys):
    expected = load(path).expect_check or 0
    png, svg = tmp_path / "d.png", tmp_path / "d.svg"
    assert main(["diagram", str(path), "-o", str(png)]) == expected
    assert main(["diagram", str(path), "-o", str(svg)]) == expected
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    root = ET.parse(svg).getroot()
    assert root.tag.endswith("svg")
    assert "wrote" in capsys.readouterr().out


def test_exit_codes_well_posed_and_conflict(tmp_path, capsys):
    assert main(["diagram", str(ROOT / "diagrams" / "drive_train.yaml"), "-o", str(tmp_path / "a.png")]) == 0
    assert main(["diagram", str(ROOT / "diagrams" / "power_split_rigid.yaml"), "-o", str(tmp_path / "b.png")]) == 1
    assert (tmp_path / "b.png").stat().st_size > 20_000     # drawn anyway
    capsys.readouterr()


def test_set_override_reaches_the_figure(tmp_path, capsys):
    svg = tmp_path / "d.svg"
    assert main(["diagram", str(ROOT / "diagrams" / "drive_train.yaml"), "-o", str(svg),
                 "--set", "load.J=0.75"]) == 0
    assert "J = 0.75" in svg.read_text()
    capsys.readouterr()


@pytest.mark.parametrize("args", [["diagrams/drive_train.yaml", "-o", "{tmp}/d.pdf"],
                                  ["diagrams/no_such_scene.yaml", "-o", "{tmp}/d.png"],
                                  ["diagrams/drive_train.yaml", "-o", "{tmp}/missing_dir/d.png"],
                                  ["diagrams/drive_train.yaml", "-o", "{tmp}/d.png", "--set", "nope=1"]])
def test_bad_input_is_one_line_and_exit_2(args, tmp_path, capsys):
    argv = ["diagram"] + [str(ROOT / a) if a.startswith("diagrams/") else a.format(tmp=tmp_path) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error[") and "\n" not in err and "Traceback" not in err
    assert not list(tmp_path.glob("d.*"))


# ---------------------------------------------------------------------------------------------
# the drawing model against the analysis

@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_every_primitive_has_a_block_in_its_element(case):
    _name, an, d = case
    owners = {b.owner for b in d.blocks.values()}
    assert set(an.flat.primitives) <= owners
    groups = {g.element: g for g in d.groups}
    assert set(groups) == {an.flat.element_of(p) for p in an.flat.primitives}
    for b in d.blocks.values():
        if b.owner in an.flat.primitives:
            assert b.element == an.flat.element_of(b.owner)
            g = groups[b.element]
            assert g.x0 <= b.x - b.w / 2 and b.x + b.w / 2 <= g.x1 and g.y0 <= b.y <= g.y1, b.id


@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_one_arrow_per_port_variable(case):
    _name, an, d = case
    counts = Counter(a.variable for a in d.arrows)
    assert set(counts) == {v.name for v in an.flat.variables()}
    assert set(counts.values()) == {1}
    for a in d.arrows:
        assert a.source in d.blocks and a.target in d.blocks and a.source != a.target
        assert a.row == a.variable[-1]


@pytest.mark.parametrize("case", WELL_POSED, ids=_ids(WELL_POSED))
def test_arrows_lead_back_to_the_equation_that_computes_the_variable(case):
    _name, an, d = case
    for v in an.flat.variables():
        arrow = d.arrow_of(v.name)
        assert arrow.determined
        assert _trace(d, arrow) == an.computed_by(v), v.name


@pytest.mark.parametrize("case", WELL_POSED, ids=_ids(WELL_POSED))
def test_weber_counting_rule_sum_computes_one_dot_receives_one(case):
    """Each Σ box has exactly one output and each branching point exactly one input."""
    _name, an, d = case
    for b in d.blocks.values():
        if b.kind not in ("sum", "dot"):
            continue
        prim = an.flat.primitives.get(b.owner)
        if prim is not None:
            mine = [d.arrow_of(f"{b.owner}.{p}.{b.row}") for p in prim.ports]
        else:
            node = next(n for n in an.flat.nodes if n.name == b.owner)
            mine = [d.arrow_of(f"{p}.{b.row}") for p in node.ports]
        outs = sum(a.source == b.id for a in mine)
        ins = sum(a.target == b.id for a in mine)
        assert outs + ins == len(mine)
        if b.kind == "sum":
            assert outs == 1, b.id
        else:
            assert ins == 1, b.id


@pytest.mark.parametrize("case", WELL_POSED, ids=_ids(WELL_POSED))
def test_transformers_pass_flow_and_effort_in_opposite_directions(case):
    _name, an, d = case
    rigid = _rigid_loops(an)
    tfs = [p for p, prim in an.flat.primitives.items() if prim.kind in ("TF", "GY")
           and an.flat.element_of(p) not in rigid]
    for p in tfs:
        out = {v: d.arrow_of(f"{p}.{v}").source.startswith(p + ":") for v in ("a.f", "b.f", "a.e", "b.e")}
        if an.flat.primitives[p].kind == "TF":
            assert out["a.f"] != out["b.f"] and out["a.e"] != out["b.e"]
            assert out["b.f"] == out["a.e"], p       # flow a -> b goes with effort b -> a
        else:                                         # gyrator: each effort from the other port's flow
            assert out["a.e"] != out["b.f"] and out["b.e"] != out["a.f"]


@pytest.mark.parametrize("case", WELL_POSED, ids=_ids(WELL_POSED))
def test_storage_integral_or_derivative_causality(case):
    _name, an, d = case
    demoted = {s.owner for s in an.demoted}
    rigid = _rigid_loops(an)
    for p, prim in an.flat.primitives.items():
        if prim.kind not in ("I", "C") or (p not in demoted and an.flat.element_of(p) in rigid):
            continue
        b = d.blocks[f"{p}:x"]
        received = "e" if prim.kind == "I" else "f"    # integral causality: integrate the input
        given = "f" if received == "e" else "e"
        inp, outp = d.arrow_of(f"{p}.p.{received}"), d.arrow_of(f"{p}.p.{given}")
        if p in demoted:
            assert b.derivative and "d/dt" in b.label
        else:
            assert not b.derivative and "∫" in b.label
            assert inp.target == b.id and outp.source == b.id


def test_geared_inertias_mark_derivative_causality(tmp_path):
    an = check(GEARED)
    assert [s.owner for s in an.demoted] == ["J_1"]
    d = layout(an)
    marked = {b.owner for b in d.blocks.values() if b.derivative}
    assert marked == {"J_1"}
    # Weber's derivative causality: the gear imposes the speed on J_1, J_1 answers with J*dω/dt
    assert d.arrow_of("J_1.p.f").target == "J_1:x" and d.arrow_of("J_1.p.e").source == "J_1:x"
    assert d.has_derivative and any("derivative causality" in text for _c, text in d.messages)
    from multipole.diagram import render
    render(d, tmp_path / "g.svg")
    text = (tmp_path / "g.svg").read_text()
    assert "d/dt" in text and "derivative causality" in text     # block and legend


def test_drive_train_blocks_weber_notation():
    an = pipeline.check(load(ROOT / "diagrams" / "drive_train.yaml"))
    d = layout(an)
    kinds = {b.id: b.kind for b in d.blocks.values()}
    # inertia: common speed (type b) -> dot in the flow row, Σ in the effort row; spring the dual
    assert kinds["rotor.j:f"] == "dot" and kinds["rotor.j:e"] == "sum"
    assert kinds["shaft.j:f"] == "sum" and kinds["shaft.j:e"] == "dot"
    assert kinds["gear:f"] == "ratio" and kinds["gear:e"] == "ratio"
    assert {kinds[f"{p}:x"] for p in ("rotor", "shaft", "load")} == {"storage"}
    assert kinds["bearing:x"] == "resistance" and kinds["motor:x"] == "source"
    # the three-port node after the gear: a dot for the common speed, a Σ for the torques
    node = next(n.name for n in an.flat.nodes if len(n.ports) == 3 and "gear.b" in n.ports)
    assert kinds[f"{node}:f"] == "dot" and kinds[f"{node}:e"] == "sum"
    # the gear computes the output speed from the input speed: f_b = f_a / i
    assert d.blocks["gear:f"].label == "1/i" and d.blocks["gear:e"].label == "-1/i"
    rows = {b.row for b in d.blocks.values() if b.owner in ("rotor", "shaft", "bearing", "motor")}
    assert rows == {"x"}                          # cross-couplings and sources between the rows
    for el in {b.element for b in d.blocks.values() if b.element}:      # flows above, efforts below
        y = {row: {b.y for b in d.blocks.values() if b.element == el and b.row == row} for row in "fxe"}
        assert all(f > x > e for f in y["f"] for x in y["x"] for e in y["e"]), el


# ---------------------------------------------------------------------------------------------
# conflicts

def test_power_split_conflict_in_red_with_the_diagnostics_words(tmp_path, capsys):
    path = ROOT / "diagrams" / "power_split_rigid.yaml"
    an = pipeline.check(load(path))
    errors = an.errors
    assert errors
    involved = {e for d in errors for e in d.elements}
    d = layout(an)
    assert d.red_elements() == involved == {"path_A", "path_B"}
    assert {b.owner for b in d.blocks.values() if b.conflict} == {"path_A", "path_B"}
    assert {g.element for g in d.groups if g.conflict} == involved
    for err in errors:
        assert any(err.message in text for _c, text in d.messages)
    # kinematic over-determination: both transformers' flow blocks receive both flows
    for p in ("path_A", "path_B"):
        assert d.arrow_of(f"{p}.a.f").target == f"{p}:f" and d.arrow_of(f"{p}.b.f").target == f"{p}:f"
    # static under-determination: the arrows nobody computes are exactly the undetermined ones
    undetermined = {a.variable for a in d.arrows if not a.determined}
    assert undetermined and undetermined == {v.name for v in an.flat.variables() if not an.computed_by(v)}
    svg = tmp_path / "p.svg"
    assert main(["diagram", str(path), "-o", str(svg)]) == 1
    text = svg.read_text()
    assert "kinematic_overdetermination" in text and "#d62728" in text
    capsys.readouterr()


def test_well_posed_scenes_have_no_red():
    for _name, an, d in WELL_POSED:
        assert not d.red_elements() and not d.has_conflict
        assert all(a.determined for a in d.arrows)


# ---------------------------------------------------------------------------------------------
# readability

def _overlap(a, b, pad=0.02):
    return (abs(a[0] - b[0]) * 2 < a[2] + b[2] + pad) and (abs(a[1] - b[1]) * 2 < a[3] + b[3] + pad)


@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_blocks_and_frames_do_not_overlap(case):
    _name, _an, d = case
    boxes = [(b.id, (b.x, b.y, max(b.w, 0.12), max(b.h, 0.12))) for b in d.blocks.values()]
    for i, (ida, a) in enumerate(boxes):
        for idb, b in boxes[i + 1:]:
            assert not _overlap(a, b), f"{ida} overlaps {idb}"
    frames = [((g.x0 + g.x1) / 2, (g.y0 + g.y1) / 2, g.x1 - g.x0, g.y1 - g.y0) for g in d.groups]
    for i, a in enumerate(frames):
        for b in frames[i + 1:]:
            assert not _overlap(a, b, pad=-0.05)


def test_nested_networks_are_kept_together_in_sub_frames():
    framed = 0
    for _name, an, d in CASES:
        by_element = {}
        for g in d.subgroups:
            framed += 1
            inside = [b for b in d.blocks.values() if b.owner.startswith(g.element + ".") and b.row != "x"]
            assert inside, g.element
            assert all(g.x0 <= b.x <= g.x1 and g.y0 <= b.y <= g.y1 for b in inside), g.element
            by_element.setdefault(an.flat.element_of(g.element), []).append(g)
        for frames in by_element.values():           # one frame per nested network, side by side
            names = [g.element for g in frames]
            assert len(names) == len(set(names))
            frames.sort(key=lambda g: g.x0)
            assert all(a.x1 <= b.x0 for a, b in zip(frames, frames[1:]))
    assert framed       # the planetary and gear-train scenes nest spur stages


@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_wires_are_orthogonal_and_end_on_their_blocks(case):
    _name, _an, d = case
    for a in d.arrows:
        pts = a.points
        assert len(pts) >= 2, a.variable
        for (x0, y0), (x1, y1) in zip(pts[:-1], pts[1:]):
            assert abs(x0 - x1) < 1e-9 or abs(y0 - y1) < 1e-9, a.variable
        def touches(pt, bid):
            b = d.blocks[bid]
            return abs(pt[0] - b.x) <= b.w / 2 + 1e-6 and abs(pt[1] - b.y) <= b.h / 2 + 1e-6

        # a leg to a two-port connection between elements ends at the (invisible) node point
        assert touches(pts[0], a.source) or touches(pts[-1], a.target), a.variable
        if a.head:
            assert touches(pts[-1], a.target), a.variable
