"""`multipole diagram`: Weber block diagrams drawn from the causality the analyser found.

The figures are checked as files (valid PNG/SVG); the drawing itself is checked on the drawing
model (`multipole.diagram.layout`): blocks and arrows against the analysis and against Weber's
rules for junctions, transformers and storage (Mehrpoltheorie, sections 4.1-4.3):

* a Σ box computes exactly one of its variables from the others, a branching point (dot) receives
  exactly one and distributes it;
* a transformer passes the flow one way and the effort the other way;
* an inertia in integral causality receives the effort and returns the flow, in derivative
  causality the other way round.

Readability is checked on the rendered figure with matplotlib's renderer: no two texts overlap,
none leaves the figure, no wire runs through a text, no label is cut off; nested sub-elements
follow the chain of connections, identical ones in the same inner order.
"""
import re
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

import pytest

from helpers import check, scene
from multipole import pipeline
from multipole.cli import main
from multipole.diagram import figure, layout
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
        if an.flat.closures or an.flat.position_providers:
            continue                 # planar and band scenes: tests/test_diagram_closures.py
        out.append((path.stem, an, layout(an, sc.element_types)))
    for name, text in (("geared", GEARED), ("large", LARGE)):
        sc = scene(text)
        an = pipeline.check(sc)
        out.append((name, an, layout(an, sc.element_types)))
    sc = load(ROOT / "diagrams" / "weber" / "piezo_stack.yaml", {"piezo.n": "3"})   # drawn in full
    an = pipeline.check(sc)
    out.append(("piezo_stack_3", an, layout(an, sc.element_types)))
    return out


CASES = _analysed()
WELL_POSED = [c for c in CASES if c[1].ok]


def _ids(cases):
    return [c[0] for c in cases]


def _hidden(diagram):
    """Primitives inside sub-elements drawn collapsed (a placeholder stands for them)."""
    gone = [g for subs in diagram.collapsed.values() for g in subs]
    return lambda path: any(path.startswith(g + ".") for g in gone)


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
        if b.kind == "repeat":       # a collapsed run may pass the value on: only its element is known
            return ("collapsed run of", b.element)
        if not b.identity:
            return b.owner
        sources = {a.source for a in diagram.arrows if a.target == block and a.row == arrow.row}
        assert len(sources) == 1, f"{block} receives {arrow.row} from {sources}"
        block = sources.pop()
    raise AssertionError(f"{arrow.variable}: the arrows run in a circle")


# ---------------------------------------------------------------------------------------------
# the command

#: the linkage and band scenes are drawn by the command in tests/test_diagram_closures.py
DRAWN = [p for p in SCENES if p.parent.name not in ("linkages", "belts")]


@pytest.mark.parametrize("path", DRAWN, ids=lambda p: p.stem)
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


@pytest.mark.parametrize("args", [["diagrams/drive_train.yaml", "-o", "{tmp}/d.txt"],
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
    hidden = _hidden(d)
    assert {p for p in an.flat.primitives if not hidden(p)} <= owners
    assert all(b.kind == "repeat" for b in d.blocks.values() if b.owner not in an.flat.primitives
               and "…" in b.owner)
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
    hidden = _hidden(d)
    for a in d.arrows:
        assert a.source in d.blocks and a.target in d.blocks
        assert a.row == a.variable[-1]
        assert a.hidden == hidden(a.variable.rsplit(".", 2)[0])
        if a.hidden:                 # inside a collapsed run: no wire, stands at the placeholder
            assert not a.drawn and d.blocks[a.source].kind == "repeat"
        else:
            assert a.source != a.target


@pytest.mark.parametrize("case", WELL_POSED, ids=_ids(WELL_POSED))
def test_arrows_lead_back_to_the_equation_that_computes_the_variable(case):
    _name, an, d = case
    hidden = _hidden(d)
    for v in an.flat.variables():
        arrow = d.arrow_of(v.name)
        assert arrow.determined
        if arrow.hidden or hidden(an.computed_by(v) or ""):
            continue                 # computed inside a collapsed run
        source = _trace(d, arrow)
        if isinstance(source, tuple):    # drawn as coming out of a collapsed run of its own element
            assert source[1] == an.flat.element_of(an.computed_by(v)), v.name
        else:
            assert source == an.computed_by(v), v.name


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
    hidden = _hidden(d)
    for p, prim in an.flat.primitives.items():
        if prim.kind not in ("I", "C") or (p not in demoted and an.flat.element_of(p) in rigid) or hidden(p):
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
        if a.hidden:
            continue
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


# ---------------------------------------------------------------------------------------------
# the rendered figure: texts measured with matplotlib's renderer (display pixels)

def _measure(diagram):
    """(figure, [(text, bbox)], [wire segments]) of the rendered diagram."""
    from matplotlib.text import Text
    fig = figure(diagram)
    fig.set_dpi(60)                      # extents scale with the dpi; a coarse raster is faster
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    texts = [(t.get_text(), t.get_window_extent(renderer)) for t in fig.findobj(Text)
             if t.get_visible() and t.get_text().strip()]
    ax = fig.axes[0]
    wires = []
    for line in ax.lines:
        if line.get_gid() == "wire":
            xy = ax.transData.transform(line.get_xydata())
            wires += list(zip(map(tuple, xy[:-1]), map(tuple, xy[1:])))
    return fig, texts, wires


def _boxes_overlap(a, b, tol=0.5):
    return a.x0 + tol < b.x1 - tol and b.x0 + tol < a.x1 - tol and a.y0 + tol < b.y1 - tol and b.y0 + tol < a.y1 - tol


def _crosses(bb, p, q, tol=1.0):
    """An axis-parallel segment p-q passes through the inside of box bb."""
    (x0, y0), (x1, y1) = p, q
    if abs(y0 - y1) < 1e-6:
        return bb.y0 + tol < y0 < bb.y1 - tol and min(x0, x1) < bb.x1 - tol and max(x0, x1) > bb.x0 + tol
    return bb.x0 + tol < x0 < bb.x1 - tol and min(y0, y1) < bb.y1 - tol and max(y0, y1) > bb.y0 + tol


@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_texts_apart_inside_the_figure_and_off_the_wires(case):
    _name, _an, d = case
    fig, texts, wires = _measure(d)
    width, height = fig.bbox.width, fig.bbox.height
    for text, bb in texts:
        assert bb.x0 >= -1 and bb.y0 >= -1 and bb.x1 <= width + 1 and bb.y1 <= height + 1, f"clipped: {text!r}"
    for i, (ta, a) in enumerate(texts):
        for tb, b in texts[i + 1:]:
            assert not _boxes_overlap(a, b), f"{ta!r} overlaps {tb!r}"
    assert wires
    for text, bb in texts:
        if text == "?" or text.startswith("×"):      # marks that sit on their wire on purpose
            continue
        for p, q in wires:
            assert not _crosses(bb, p, q), f"a wire runs through {text!r}"


@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_labels_are_never_cut(case):
    _name, _an, d = case
    for b in d.blocks.values():
        assert not b.label.endswith("…") and not b.note.endswith("…"), b.id
    refs = {int(m) for b in d.blocks.values() for m in re.findall(r"\[(\d+)\]", b.label + b.note)}
    notes = [line for line in d.footnotes if line.startswith("[")]
    assert refs == set(range(1, len(notes) + 1))        # every footnote mark has its footnote


def test_long_expressions_in_full():
    """Weber's ρ_X/r ratios of the normal level and a long source law are written out in full."""
    sc = load(ROOT / "diagrams" / "weber" / "spur_normal_teaching.yaml")
    d = layout(pipeline.check(sc), sc.element_types)
    labels = {b.label for b in d.blocks.values() if b.owner.startswith("mesh.tangent")}
    assert {"g/r1 + sin(α)", "-g/r2 + sin(α)"} <= labels | {line.split(": ", 1)[-1] for line in d.footnotes}
    assert any(line.startswith("symbols in the blocks:") and "α = 0.349" in line and "g = 0.002" in line
               for line in d.footnotes)
    sc = load(ROOT / "diagrams" / "weber" / "piezo_stack.yaml")
    d = layout(pipeline.check(sc), sc.element_types)
    assert d.blocks["amp:x"].note == "e = [1]"
    assert "[1] amp: e = U0*(1 - cos(pi*min(1, t/t_r)))/2" in d.footnotes


def test_planetary_ratios_symbolic_and_meshes_in_chain_order():
    sc = load(ROOT / "diagrams" / "weber" / "planetary_willis.yaml")
    an = pipeline.check(sc)
    d = layout(an, sc.element_types)
    ratios = [b.label for b in d.blocks.values() if b.kind == "ratio"]
    assert ratios and all(re.search(r"r[12]", r) for r in ratios), ratios      # no bare 125/9 or 0.024
    assert any("in pg.mesh34: r1 = 0.024, r2 = 0.072" in line for line in d.footnotes)
    frames = {g.element: g for g in d.subgroups}
    x = {b.owner: b.x for b in d.blocks.values()}
    # sun -> sun's relative-speed junction -> mesh12 -> planet -> mesh34 -> ring's junction
    assert x["pg.rel_sun"] < frames["pg.mesh12"].x0 < frames["pg.mesh12"].x1 < x["pg.planet"] \
        < frames["pg.mesh34"].x0 < frames["pg.mesh34"].x1 < x["pg.rel_ring"]
    assert d.lanes == 1                     # the three sources sit in the gear's lane
    assert {g.element for g in d.groups if g.x0 > frames["pg.mesh34"].x1} == {"carrier", "ring"}


def _frame_order(d, parent):
    frames = sorted((g for g in d.subgroups if g.element.startswith(parent + ".")), key=lambda g: g.x0)
    return [g.element.rsplit(".", 1)[1] for g in frames]


def test_identical_sub_elements_in_chain_order_and_alike():
    d = next(c[2] for c in CASES if c[0] == "piezo_stack_3")
    assert _frame_order(d, "piezo") == ["e1", "e2", "e3"]
    inner = []
    for disc in ("e1", "e2", "e3"):
        prims = sorted((b for b in d.blocks.values() if b.owner.startswith(f"piezo.{disc}.") and b.row != "x"),
                       key=lambda b: b.x)
        inner.append(list(dict.fromkeys(b.owner.split(".", 2)[2] for b in prims)))
    assert inner[0] == inner[1] == inner[2] and len(inner[0]) >= 3
    # mechanically in series: each disc's tip is its last item, next to the following disc's base
    assert inner[0][0] == "gap" and inner[0][-1] == "tip"


def test_large_repeat_drawn_collapsed_with_a_note():
    sc = load(ROOT / "diagrams" / "weber" / "piezo_stack.yaml")
    an = pipeline.check(sc)
    d = layout(an, sc.element_types)
    assert _frame_order(d, "piezo") == ["e1", "e2", "e10"]
    ph = next(b for b in d.blocks.values() if b.kind == "repeat")
    assert ph.label == "7 × piezo_element"
    e2 = next(g for g in d.subgroups if g.element == "piezo.e2")
    e10 = next(g for g in d.subgroups if g.element == "piezo.e10")
    assert e2.x1 < ph.x < e10.x0
    assert d.collapsed[ph.id] == [f"piezo.e{k}" for k in range(3, 10)]
    assert any(line.startswith("piezo: 10 × piezo_element, drawn: 3 (e1, e2, e10)") for line in d.footnotes)
    # the seven parallel electrical wires of the hidden discs are one wire marked ×7
    multi = [a for a in d.arrows if a.multiplicity > 1]
    assert multi and {a.multiplicity for a in multi} == {7} and all(a.drawn for a in multi)
    # the parallel electrodes are buses: one line each instead of a wire bundle
    assert {b.owner for b in d.blocks.values() if b.bus} == {"piezo.plus", "piezo.minus"}


def test_terminals_packed_next_to_what_they_act_on():
    for name in ("piezo_element", "planetary_willis", "dc_motor_gear_load", "drive_train"):
        _n, an, d = next(c for c in CASES if c[0] == name)
        frames = {g.element: g for g in d.groups}
        assert d.lanes <= 2, name
        for el, g in frames.items():
            partners = {an.flat.element_of(p) for n in an.flat.nodes if n.origin != "termination"
                        for p in n.ports if any(an.flat.element_of(q) == el for q in n.ports)} - {el}
            if len(partners) == 1:           # a source or ground: beside or right below its partner
                other = frames[partners.pop()]
                gap = max(other.x0 - g.x1, g.x0 - other.x1)
                same_lane = abs(g.y0 - other.y0) < d.lane_h / 2
                assert gap < 3.0 or (same_lane and gap < 8.0), (name, el)
    d = next(c[2] for c in CASES if c[0] == "piezo_element")
    assert d.lanes == 2                 # was three lanes, two of them nearly empty


def test_two_port_connections_have_no_dead_end():
    """Where the two legs of a connection between elements meet, the wire goes on (no stub that
    runs out to the node point and back)."""
    for _name, an, d in CASES:
        for n in an.flat.nodes:
            if len(n.ports) != 2 or len({an.flat.element_of(p) for p in n.ports}) != 2:
                continue
            for row in ("e", "f"):
                a, b = (d.arrow_of(f"{p}.{row}") for p in n.ports)
                pa, pb = a.points, b.points
                shared = [(i, j) for i in (0, -1) for j in (0, -1)
                          if abs(pa[i][0] - pb[j][0]) < 1e-9 and abs(pa[i][1] - pb[j][1]) < 1e-9]
                assert shared, (n.name, row)
                i, j = shared[0]
                near_a, near_b = pa[1 if i == 0 else -2], pb[1 if j == 0 else -2]
                meet = pa[i]
                da = (near_a[0] - meet[0], near_a[1] - meet[1])
                db = (near_b[0] - meet[0], near_b[1] - meet[1])
                same_way = (abs(da[0]) < 1e-9 and abs(db[0]) < 1e-9 and da[1] * db[1] > 0) or \
                           (abs(da[1]) < 1e-9 and abs(db[1]) < 1e-9 and da[0] * db[0] > 0)
                assert not same_way, (n.name, row)


def test_gyrator_ties_each_effort_to_the_other_sides_flow():
    _n, an, d = next(c for c in CASES if c[0] == "dc_motor_gear_load")
    gy = next(p for p, prim in an.flat.primitives.items() if prim.kind == "GY")
    bf, be = d.blocks[f"{gy}:f"], d.blocks[f"{gy}:e"]
    assert len(d.links) == 2
    side = {}
    for port in ("a", "b"):
        arrow = d.arrow_of(f"{gy}.{port}.f")
        end = arrow.points[0] if arrow.source == bf.id else arrow.points[-1]
        side[port] = end[0] < bf.x
    for pts, _colour, head in d.links:
        assert head
        (x0, y0), (x1, y1) = pts
        assert (y0 > y1) == (abs(y0 - (bf.y - bf.h / 2)) < 1e-9)     # from the flow block down, or up
        start_left, end_left = x0 < bf.x, x1 < bf.x
        assert start_left != end_left                                # across: one side to the other
    # the current (received on the electrical side) sets the torque on the shaft side, the speed
    # (received on the shaft side) the back-emf on the electrical side: both links point down
    assert not an.computed_by(f"{gy}.a.f") == gy and not an.computed_by(f"{gy}.b.f") == gy
    assert all(pts[0][1] > pts[1][1] for pts, _c, _h in d.links)

