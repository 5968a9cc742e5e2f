"""``multipole reduce`` (issue 14, part 2): simplifications verified by re-simulation.

Expected values: the rigid stiff drive train is one inertia J1 + J2 on the bearing damper, whose
speed under the torque T0·(1 - exp(-t/tau)) has a closed form; the activity shares obey the power
balance (the motor delivers what the other elements store and dissipate, so it holds half of the
sum of ∫|P| dt when no element's power changes sign); the netlist edits follow their definition.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from multipole import Reduction, catalogue, pipeline
from multipole.cli import main
from multipole.errors import IllPosedError, MultipoleError, NetlistError
from multipole.netlist import loads
from multipole.reduce import apply, output_error, reduce

ROOT = Path(__file__).resolve().parents[1]
STIFF = ROOT / "diagrams" / "hard" / "stiff_drive_train.yaml"
SPEEDS = ["load.omega", "rotor.omega"]


@pytest.fixture(scope="module")
def stiff():
    return reduce(STIFF, tol=1e-3, outputs=SPEEDS, progress=False)


def test_stiff_shaft_becomes_rigid(stiff):
    reduced, report = stiff
    actions = {s.element: s.action for s in report.accepted}
    assert actions.get("shaft") == "rigid"
    assert "shaft" not in reduced.element_types and "shaft_d" not in reduced.element_types
    assert report.states_full == 3 and report.states_reduced == 1
    assert report.error <= 1e-3
    assert report.wall_full > 0 and report.wall_reduced > 0 and math.isfinite(report.speedup)
    assert "bearing" in reduced.element_types          # its loss is most of what the outputs show


def test_reduced_speed_is_the_rigid_closed_form(stiff):
    _reduced, report = stiff
    T0, tau, J, d = 10.0, 0.2, 0.001 + 1.0, 1.0           # diagrams/hard/stiff_drive_train.yaml
    a = d / J
    C = -T0 / (J * (a - 1 / tau))
    t = report.reduced.t
    omega = T0 / d * (1 - np.exp(-a * t)) + C * (np.exp(-t / tau) - np.exp(-a * t))
    for name in SPEEDS:                     # rtol 1e-6 of the scene: agreement to a few 1e-6 of the peak
        assert np.max(np.abs(report.reduced.outputs[name] - omega)) <= 1e-5 * np.max(omega)


def test_reduced_netlist_is_valid_and_reproduces_its_error(stiff, tmp_path):
    _reduced, report = stiff
    path = tmp_path / "reduced.yaml"
    path.write_text(report.text)
    assert main(["check", str(path)]) == 0
    again = pipeline.run(loads(report.text, str(path)), progress=False)
    assert np.array_equal(again.t, report.full.t)
    assert output_error(report.full, again, SPEEDS) == pytest.approx(report.error, rel=1e-6, abs=1e-12)


def test_activity_shares_follow_the_power_balance(stiff):
    _reduced, report = stiff
    assert sum(report.activity.values()) == pytest.approx(1.0, abs=1e-12)
    assert report.activity["motor"] == pytest.approx(0.5, abs=1e-6)
    assert report.activity["housing"] == 0.0
    assert report.activity["shaft_d"] < 1e-9 and report.activity["bearing"] > 0.1


def test_nothing_removable_says_so_and_keeps_the_model(tmp_path, capsys):
    src = ROOT / "diagrams" / "drive_train.yaml"
    out = tmp_path / "same.yaml"
    assert main(["reduce", str(src), "--tol", "1e-6", "-o", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "nothing can be simplified" in text and "(unchanged)" in text
    assert yaml.safe_load(out.read_text()) == yaml.safe_load(src.read_text())


def test_report_files(tmp_path, capsys):
    folder = tmp_path / "rep"
    assert main(["reduce", str(STIFF), "--outputs", *SPEEDS, "--report", str(folder), "--quiet"]) == 0
    capsys.readouterr()
    rows = list(csv.DictReader((folder / "report.csv").open()))
    assert [r["element"] for r in rows if r["accepted"] == "yes"][-1] == "shaft"
    assert "| shaft | spring |" in (folder / "report.md").read_text()
    assert (folder / "outputs.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("tol", ["0", "1", "-0.1", "nan", "2"])
def test_bad_tolerance_exits_2(tol, capsys):
    assert main(["reduce", str(STIFF), "--tol", tol]) == 2
    assert "error[bad_option]" in capsys.readouterr().err


def test_unknown_output_exits_2(capsys):
    assert main(["reduce", str(STIFF), "--outputs", "load.omegaa"]) == 2
    assert "error[unknown_output]" in capsys.readouterr().err
    with pytest.raises(NetlistError) as exc:
        reduce(STIFF, outputs=["nobody.f"])
    assert exc.value.code == "unknown_output"


def test_ill_posed_scene_is_refused():
    with pytest.raises(IllPosedError) as exc:
        reduce(ROOT / "diagrams" / "power_split_rigid.yaml")
    assert exc.value.code == "kinematic_overdetermination"


def test_join_merges_the_two_nodes_and_remove_opens_the_ports():
    data = {"elements": {"a": {}, "s": {}, "b": {}, "d": {}},
            "connections": [["a.p", "s.a", "d.a"], ["s.b", "d.b", "b.p"], ["b.q", "x.p"]]}
    rigid = apply(data, "s", Reduction("rigid", join=("a", "b")))
    assert rigid["connections"] == [["a.p", "d.a", "d.b", "b.p"], ["b.q", "x.p"]]
    assert "s" not in rigid["elements"] and "s" in data["elements"]       # a copy
    removed = apply(data, "d", Reduction("removed"))
    assert removed["connections"] == [["a.p", "s.a"], ["s.b", "b.p"], ["b.q", "x.p"]]
    gone = apply({"elements": {"x": {}, "b": {}}, "connections": [["b.q", "x.p"]]}, "x", Reduction("removed"))
    assert gone["connections"] == []                        # a node of one port is no connection


def test_element_library_declares_reductions_the_kernel_checks():
    types = catalogue()
    assert [r.action for r in types["spring"].reductions] == ["rigid"]
    assert [r.action for r in types["damper"].reductions] == ["removed"]
    from multipole.catalogue import ElementType, Param
    with pytest.raises(MultipoleError) as exc:
        ElementType("bad", lambda c: None, "bad", {"a": "port a"}, [Param("c")],
                    reductions=(Reduction("rigid", join=("a", "zz")),))
    assert exc.value.code == "bad_element_type"


SPUR = ROOT / "diagrams" / "weber" / "spur_normal.yaml"


def test_gear_with_negligible_friction_drops_a_level():
    reduced, report = reduce(SPUR, tol=1e-3, outputs=["pinion.omega", "wheel.omega"], progress=False,
                             overrides={"mesh.mu": "1e-5"})
    level = [s for s in report.accepted if s.element == "mesh"]
    assert level and level[0].action == "level normal -> elastic"      # the nearest simpler level first
    assert reduced.element_types["mesh"] == "spur_stage" and "load" in reduced.element_types
    entry = yaml.safe_load(report.text)["elements"]["mesh"]
    assert entry["level"] in ("elastic", "ideal") and "mu" not in entry and "c_n" not in entry
    assert report.error <= 1e-3


def test_gear_whose_losses_are_observed_keeps_normal(capsys):
    reduced, report = reduce(SPUR, tol=1e-3, outputs=["pinion.omega", "wheel.omega", "mesh.loss"], progress=True)
    bar = capsys.readouterr().err
    assert "reduce [" in bar and "mesh level" in bar                     # the progress bar names the candidate
    assert not report.accepted
    mesh = [s for s in report.steps if s.element == "mesh"]
    assert mesh and all(not s.accepted for s in mesh)
    assert report.text == SPUR.read_text()                  # unchanged: the user's file as it is


def test_spur_elastic_level_projects_the_normal_stiffness():
    red = catalogue()["spur_stage"].reductions[0]
    alpha = 0.3
    entry = {"type": "spur_stage", "level": "normal", "c_n": 2.0e8, "d": 100.0, "alpha": alpha, "mu": 0.05}
    moved = red.adapt(entry, "elastic")
    # normal deflection = circumferential deflection * cos(alpha), circumferential force = normal * cos(alpha)
    assert moved["c"] == pytest.approx(2.0e8 * math.cos(alpha) ** 2, rel=1e-15)
    assert moved["d"] == pytest.approx(100.0 * math.cos(alpha) ** 2, rel=1e-15)
    assert red.adapt({**entry, "alpha": "a"}, "elastic") is None


def test_piezo_stack_observed_at_its_tip_is_lumped():
    path = ROOT / "diagrams" / "weber" / "piezo_stack.yaml"
    reduced, report = reduce(path, tol=1e-2, outputs=["piezo.stroke", "load.v"], progress=False)
    lumped = [s for s in report.accepted if s.element == "piezo"]
    assert lumped and lumped[0].action == "lumped"
    assert yaml.safe_load(report.text)["elements"]["piezo"]["n"] == 1
    assert report.states_reduced < report.states_full
    assert report.error <= 1e-2
    assert "piezo lumped" in report.summary() and f"{report.error:.3g}" in report.summary()


def test_piezo_stack_lumping_keeps_the_static_stack_laws():
    red = catalogue()["piezo_stack"].reductions[0]
    n = 10
    entry = {"type": "piezo_stack", "n": n, "k_P": 5.0e-9, "delta_P": 1.0e-9, "C_P": 5.0e-8, "m": 5.0e-4, "R": 10.0}
    one = red.adapt(entry, None)
    # Weber Bild 38: stroke n*k_P*U, compliance n*delta_P, capacitance n*C_P, electrodes in parallel R/n
    assert one["n"] == 1
    assert one["k_P"] == pytest.approx(n * 5.0e-9) and one["delta_P"] == pytest.approx(n * 1.0e-9)
    assert one["C_P"] == pytest.approx(n * 5.0e-8) and one["R"] == pytest.approx(10.0 / n)
    # tip masses moving with k/n of the stroke: kinetic energy sum m*(k/n)^2 over k = 1..n
    assert one["m"] == pytest.approx(5.0e-4 * sum((k / n) ** 2 for k in range(1, n + 1)), rel=1e-12)
    assert red.adapt({**entry, "n": 1}, None) is None
    assert red.adapt({**entry, "k_P": "kp"}, None)["k_P"] == "(kp)*10"


def test_scene_without_a_file_is_refused():
    sc = loads(STIFF.read_text(), "inline.yaml")
    with pytest.raises(NetlistError) as exc:
        reduce(sc)
    assert exc.value.code == "no_file"
