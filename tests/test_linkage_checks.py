"""Linkage diagnostics of ``multipole check`` and of a run (issue 12, "check in Weber's and VDI's
words"): mobility with the structural order, two outputs joined, a position loop (no Assur order),
an anchor nothing positions, a redundant closure, anchors listed once per bundle, a dyad that cannot
be assembled at t = 0, and the dead centre during a run.  Each has a netlist that triggers it and
one that does not; expected numbers come from the geometry written out here."""
from __future__ import annotations

import dataclasses
import math
import re

import pytest
import sympy as sp

from helpers import scene
from multipole import Closure, Network, RunError, pipeline
from multipole.cli import main

FOURBAR = """
name: fourbar
parameters: {w: 2.0}
elements:
  motor: {type: speed_source, value: w}
  crank: {type: DAN, l: 0.2, phi0: 0.3, m: 1.0, J: 0.01, x1: 0, y1: 0}
  rocker: {type: DDD, l1: 0.6, l2: 0.5, K: 1, m1: 2.0, J1: 0.06, m2: 1.5, J2: 0.03, x2: 0.7, y2: 0}
connections:
  - [motor.p, crank.drive]
  - [crank.b, rocker.a1]
outputs: [crank.phi, rocker.transmission]
"""

#: a second dyad on the same crank and frame point whose output is joined to the first one's output
TWO_OUTPUTS = FOURBAR.replace("connections:", """  extra: {type: DDD, l1: 0.6, l2: 0.5, K: 1, x2: 0.7, y2: 0}
connections:""").replace("[crank.b, rocker.a1]", "[crank.b, rocker.a1, extra.a1]\n  - [rocker.b2, extra.b2]")

#: each dyad anchored on the other's output: no structural order
NO_ORDER = """
name: no_assur_order
elements:
  d1: {type: DDD, l1: 0.6, l2: 0.5, x2: 0.7, y2: 0}
  d2: {type: DDD, l1: 0.6, l2: 0.5, x2: 0.0, y2: 0.5}
connections:
  - [d1.b1, d2.a1]
  - [d2.b1, d1.a1]
"""

#: two anchors joined to each other and to nothing that moves
ANCHOR_TO_ANCHOR = """
name: anchors_only
elements:
  d1: {type: DDD, l1: 0.6, l2: 0.5, x2: 0.7, y2: 0}
  d2: {type: DDD, l1: 0.6, l2: 0.5, x2: 0.0, y2: 0.5}
connections:
  - [d1.a1, d2.a1]
"""

#: the four-bar with the crank at phi0 = pi: |P1P2| = 0.7 + 0.2 = 0.9 m, the links reach L1 + L2
def unreachable(l1: float, l2: float, phi0: float = math.pi) -> str:
    return FOURBAR.replace("phi0: 0.3", f"phi0: {phi0!r}").replace("l1: 0.6, l2: 0.5", f"l1: {l1}, l2: {l2}")


#: a four-bar driven at its rocker (a DAN at (0.7, 0), r = 0.5 m) with the crank (0.2 m, at the
#: origin) and the coupler (0.6 m) as the dyad: the rocker tip's distance d from the origin obeys
#: d^2 = 0.7^2 + 0.5^2 + 2*0.7*0.5*cos(theta); the dyad folds (dead centre) at d = 0.6 - 0.2
ROCKER_DRIVEN = """
name: rocker_driven_fourbar
parameters: {w: 1.0}
elements:
  motor: {type: speed_source, value: w}
  rocker: {type: DAN, l: 0.5, phi0: THETA0, m: 1.0, J: 0.01, x1: 0.7, y1: 0}
  dyad: {type: DDD, l1: 0.6, l2: 0.2, K: 1, m1: 2.0, J1: 0.06, m2: 1.0, J2: 0.01, x2: 0, y2: 0}
connections:
  - [motor.p, rocker.drive]
  - [rocker.b, dyad.a1]
outputs: [rocker.phi, dyad.transmission, rocker.torque]
"""
THETA0 = 2.0944
#: times are printed with 6 significant digits: half a unit of the last one, relative, for t >= 0.1 s
PRINTED = 5e-6
A, R, L1, L2 = 0.7, 0.5, 0.6, 0.2


def theta_at(sin_gamma: float) -> float:
    """Rocker angle [rad] at which the folded dyad's links make the angle gamma (sin gamma given),
    on the branch theta > THETA0: d^2 = L1^2 + L2^2 - 2 L1 L2 cos(gamma)."""
    d2 = L1 ** 2 + L2 ** 2 - 2 * L1 * L2 * math.sqrt(1 - sin_gamma ** 2)
    return math.acos((d2 - A ** 2 - R ** 2) / (2 * A * R))


def rocker_driven():
    return scene(ROCKER_DRIVEN.replace("THETA0", repr(THETA0)))


def found(text_or_scene, code):
    sc = scene(text_or_scene) if isinstance(text_or_scene, str) else text_or_scene
    return [d for d in pipeline.check(sc).diagnostics if d.code == code]


# -- 1. mobility and the structural order --------------------------------------------------------

def test_mobility_of_the_four_bar_is_grueblers_with_the_modules_in_structural_order():
    n_links, n_revolute = 4, 4              # frame, crank, coupler, rocker; four revolute joints
    [d] = found(FOURBAR, "mobility")
    assert d.severity == "info"
    assert f"F = {3 * (n_links - 1) - 2 * n_revolute} " in d.message
    assert "3 displacement state(s) - 2 closure relation(s)" in d.message
    order = d.message.split("structural order: ", 1)[1]
    assert order.index("crank (DAN") < order.index("rocker (DDD") and d.elements == ["crank", "rocker"]
    assert "rocker (DDD: 2 displacement(s) bound by 2 closure relation(s)) on crank and the frame " \
           "determines rocker.b1 and rocker.b2" in order


FIVE_BAR = """
name: five_bar
parameters: {w: 2.0}
elements:
  motor1: {type: speed_source, value: w}
  motor2: {type: speed_source, value: -w}
  crank1: {type: DAN, l: 0.2, phi0: 1.2}
  crank2: {type: DAN, l: 0.2, phi0: 1.9, x1: 0.7}
  dyad: {type: DDD, l1: 0.6, l2: 0.6, K: 1}
connections:
  - [motor1.p, crank1.drive]
  - [motor2.p, crank2.drive]
  - [crank1.b, dyad.a1]
  - [crank2.b, dyad.a2]
"""


@pytest.mark.parametrize("text, links, joints, drives", [(FOURBAR, 3, 4, 1), (FIVE_BAR, 4, 5, 2)],
                         ids=["four-bar", "five-bar"])
def test_the_vdi_reading_counts_links_joints_and_drives(text, links, joints, drives):
    """Counted by hand: the four-bar has crank, coupler and rocker on four revolute joints; the
    five-bar two cranks and a dyad of two links on five."""
    [d] = found(text, "vdi_structure")
    F = 3 * links - 2 * joints
    assert f"n = {links + 1} links with the frame, g = {joints} joints: F = 3(n - 1) - 2g = {F}, " \
           f"{drives} drive(s): forced motion" in d.message
    assert "(DDD: dyad, class 2)" in d.message and "(DAN: rotary drive, class 1)" in d.message
    [m] = found(text, "mobility")
    assert f"mobility F = {F} " in m.message          # the kernel's count from the position graph agrees


def test_no_vdi_reading_without_modules_or_with_a_position_error():
    assert found(TWO_OUTPUTS, "vdi_structure") == [] and found(NO_ORDER, "vdi_structure") == []


def test_no_mobility_line_for_a_scene_without_positions():
    assert found("""
        name: plain
        elements:
          drive: {type: torque_source, value: 1}
          J: {type: inertia, J: 0.1}
        connections:
          - [drive.p, J.a]
        """, "mobility") == []
    assert found("""
        name: plain
        elements:
          drive: {type: torque_source, value: 1}
          J: {type: inertia, J: 0.1}
        connections:
          - [drive.p, J.a]
        """, "vdi_structure") == []


# -- 2. over-constrained linkages ----------------------------------------------------------------

def test_two_outputs_joined_is_a_check_error_naming_the_loop_and_a_fix(tmp_path, capsys):
    [d] = found(TWO_OUTPUTS, "position_overdetermined")
    assert d.severity == "error" and d.elements == ["extra", "rocker"]
    assert "rocker.b2 and extra.b2" in d.message and "passive constraint" in d.message
    assert d.path == ["crank", "rocker", "extra", "crank"]
    assert "join extra.b2 to an anchor" in d.fix
    path = tmp_path / "two.yaml"
    path.write_text(TWO_OUTPUTS)
    assert main(["check", str(path)]) == 1
    assert "error[position_overdetermined]" in capsys.readouterr().out


def test_the_four_bar_has_no_position_error():
    an = pipeline.check(scene(FOURBAR))
    assert an.ok
    assert not {"position_overdetermined", "position_loop", "position_undetermined", "cannot_assemble",
                "redundant_closure"} & {d.code for d in an.diagnostics}


def redundant_closure_scene():
    """The four-bar with its dyad wrapped in a network that adds one more closure on the coupler
    angle, whose relation sin^2 + cos^2 - 1 = 0 holds for every angle: it constrains nothing."""
    sc = scene(FOURBAR)
    root = sc.network
    dyad = root.children["rocker"]
    ang = sp.Symbol("ang")
    brace = Network("brace", {"rocker": dyad}, ports={p: f"rocker.{p}" for p in dyad.ports},
                    bundles=dict(dyad.bundles), signals={"ang": "rocker.L1.K.q3"},
                    closures=[Closure(["rocker.L1.K.q3"], [sp.sin(ang) ** 2 + sp.cos(ang) ** 2 - 1])])
    net = Network(root.kind, {**root.children, "rocker": brace}, root.connections, root.ports, root.params)
    return dataclasses.replace(sc, network=net)


def test_a_closure_whose_relation_constrains_nothing_is_a_redundant_closure():
    constrains_nothing, bound_twice = found(redundant_closure_scene(), "redundant_closure")
    assert constrains_nothing.severity == "error" and constrains_nothing.elements == ["rocker"]
    assert constrains_nothing.message.startswith("rocker: only 0 of its 1 position relations are independent")
    assert "rocker.rocker.L1.K.q3 is already bound by the closure of rocker" in bound_twice.message
    assert found(FOURBAR, "redundant_closure") == []


# -- 3. unconnected anchors, once per bundle -----------------------------------------------------

def test_unconnected_anchors_are_listed_once_per_bundle_as_frame_fixed_at_their_pose():
    lines = {d.ports[0]: d.message for d in found(FOURBAR, "unconnected_port")}
    assert not [p for p in lines if re.search(r"\.(x|y|phi)$", p)], lines
    assert "fixed to the frame" in lines["crank.a"] and "fixed to the frame" in lines["rocker.a2"]
    pose = dict(re.findall(r"\b(x|y) = (\S+?)(?:,|$)", lines["rocker.a2"]))
    assert float(pose["x"]) == pytest.approx(0.7, abs=1e-12) and float(pose["y"]) == pytest.approx(0.0, abs=1e-12)
    assert "free end" in lines["rocker.b1"]
    assert "rocker.a1" not in lines and "crank.b" not in lines         # connected: not listed


# -- 4. cannot be assembled at t = 0 -------------------------------------------------------------

def test_a_dyad_whose_links_do_not_reach_is_named_with_the_shortfall(tmp_path, capsys):
    distance = 0.7 + 0.2                    # crank tip at (-0.2, 0), the rocker's frame point at (0.7, 0)
    [d] = found(unreachable(0.6, 0.25), "cannot_assemble")
    assert d.severity == "error" and d.elements == ["rocker"]
    assert "exceeds l1 + l2" in d.message
    amount = float(re.search(r"by (\S+) m$", d.message).group(1))
    assert amount == pytest.approx(distance - (0.6 + 0.25), rel=1e-3)        # printed to 3 digits
    [d] = found(unreachable(1.3, 0.3, 0.0), "cannot_assemble")              # |P1P2| = 0.5 < 1.3 - 0.3
    amount = float(re.search(r"by (\S+) m$", d.message).group(1))
    assert "shorter than |l1 - l2|" in d.message and amount == pytest.approx((1.3 - 0.3) - 0.5, rel=1e-3)
    path = tmp_path / "short.yaml"
    path.write_text(unreachable(0.6, 0.25))
    assert main(["simulate", str(path), "--t-end", "0.1"]) == 1
    assert "cannot_assemble" in capsys.readouterr().err


def test_a_dyad_that_just_reaches_can_be_assembled():
    assert found(unreachable(0.6, 0.35), "cannot_assemble") == []


# -- 5. no Assur order -----------------------------------------------------------------------------

def test_dyads_anchored_on_each_other_have_no_structural_order():
    [d] = found(NO_ORDER, "position_loop")
    assert d.severity == "error" and d.elements == ["d1", "d2"] and d.path in (["d1", "d2", "d1"], ["d2", "d1", "d2"])
    assert "class 3 or higher" in d.message


#: a dyad whose output is joined to both its anchors (found by the fuzz test: the start values read
#: each other around the circle, and substituting them again and again never ended)
SELF_ANCHORED = """
name: self_anchored
elements:
  d: {type: SSD, xs1: 0.043, m1: 0.0125, J2: 1.34, y1: 0.0003, y2: 1.22}
connections:
  - [d.a2, d.b1, d.a1]
outputs: [d.omega]
"""


def test_a_dyad_anchored_on_its_own_output_is_one_position_loop_and_its_start_values_stay_as_written():
    sc = scene(SELF_ANCHORED)
    analysis = pipeline.check(sc)
    [d] = [d for d in analysis.diagnostics if d.code == "position_loop"]
    assert d.elements == ["d"] and "d.a1" in d.message
    # the circle's start values are not substituted into each other (each round doubled them)
    assert max(sp.count_ops(s.initial) for s in analysis.flat.states) < 200


def test_an_anchor_joined_only_to_an_anchor_has_no_position():
    ds = found(ANCHOR_TO_ANCHOR, "position_undetermined")
    assert ds and all(d.severity == "error" for d in ds)
    assert {d.ports[0] for d in ds} <= {"d1.a1", "d2.a1"}
    assert found(FOURBAR, "position_undetermined") == [] and found(FOURBAR, "position_loop") == []


# -- 6. the dead centre during a run --------------------------------------------------------------

def test_a_rocker_driven_four_bar_pushed_through_its_dead_centre_stops_there():
    t_dead = (theta_at(0.0) - THETA0) / 1.0           # the dyad folds: no assembly beyond
    t_guard = (theta_at(0.1) - THETA0) / 1.0          # |sin(phi2 - phi1)| = 0.1, the DDD threshold
    with pytest.raises(RunError) as exc:
        pipeline.run(rocker_driven(), t_end=1.0, rtol=1e-8, progress=False)
    assert exc.value.code == "dead_centre" and exc.value.element == "dyad"
    t_stop = float(re.search(r"at t = (\S+) s", exc.value.message).group(1))     # printed to 6 digits
    assert t_guard * (1 - PRINTED) <= t_stop <= t_dead * (1 + PRINTED), (t_guard, t_stop, t_dead)


def test_the_same_four_bar_short_of_the_dead_centre_runs_without_a_report():
    t_guard = (theta_at(0.1) - THETA0) / 1.0
    res = pipeline.run(rocker_driven(), t_end=0.8 * t_guard, rtol=1e-8, progress=False)
    assert res.monitors == []
    assert abs(res["dyad.transmission"]).min() > 0.1


def test_a_run_that_comes_near_the_dead_centre_reports_time_and_module():
    t_guard, t_dead = ((theta_at(s) - THETA0) / 1.0 for s in (0.1, 0.0))
    t_end = t_guard + 0.2 * (t_dead - t_guard)
    res = pipeline.run(rocker_driven(), t_end=t_end, dt_out=t_end / 50, rtol=1e-8, progress=False)
    [(t_note, element, code, text)] = res.monitors
    assert (element, code) == ("dyad", "near_dead_centre") and text.startswith("comes near its dead centre")
    assert t_guard * (1 - PRINTED) <= t_note <= t_end * (1 + PRINTED)


def test_the_crank_driven_four_bar_never_reports_a_dead_centre():
    res = pipeline.run(scene(FOURBAR), t_end=math.pi, rtol=1e-8, progress=False)     # one revolution
    assert res.monitors == []


# -- 7. unconnected ports on a frame-fixed housing ------------------------------------------------

def test_a_support_on_a_frame_fixed_housing_is_listed_as_held_by_the_frame_not_as_a_free_end():
    """A bearing's ``support`` turns with its housing: held by the frame while the anchor is
    unconnected (frame-fixed), a free end once the anchor sits on a moving link (here crank2's
    output, driven at 0.5 rad/s); the dyad's ``drive`` is on a moving link either way."""
    def texts(text):
        return {d.ports[0]: d.message.split(": ", 1)[1] for d in found(text, "unconnected_port")}
    fixed = texts(FOURBAR)
    for el, anchor in (("crank", "crank.a.phi"), ("rocker", "rocker.a2.phi")):
        assert fixed[f"{el}.support"].startswith(f"held by the frame (its motion is that of {anchor}, fixed")
    assert fixed["rocker.drive"] == "free end (effort 0)"
    moving = texts(FOURBAR.replace("connections:", "  crank2: {type: DAN, l: 0.1, phi0: 0.0, x1: 0.7, y1: 0.0}\n"
                                   "  motor2: {type: speed_source, value: 0.5}\nconnections:")
                   .replace("  - [crank.b, rocker.a1]", "  - [crank.b, rocker.a1]\n  - [crank2.b, rocker.a2]\n"
                            "  - [motor2.p, crank2.drive]"))
    assert moving["rocker.support"] == "free end (effort 0)"
    assert moving["crank2.support"].startswith("held by the frame (its motion is that of crank2.a.phi")
