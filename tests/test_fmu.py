"""FMU export (FMI 2.0 Model Exchange), checked by a real importer: FMPy validates the model
description and simulates the FMU; its trajectories must converge to those of ``multipole
simulate`` as both solvers' tolerances shrink, and a tuned parameter must change the result as
the closed form says.  Exports that the FMU cannot represent are refused with their code."""
from __future__ import annotations

import math
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from helpers import scene
from multipole import fmu, pipeline
from multipole.cli import main
from multipole.errors import MultipoleError
from multipole.netlist import load

ROOT = Path(__file__).resolve().parent.parent
DIAGRAMS = ROOT / "diagrams"

needs_cc = pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc")), reason="no C compiler on this machine")


def _fmpy():
    return pytest.importorskip("fmpy", reason="FMPy is not installed (pip install -e '.[fmu]')")


SPRING_MASS = """
name: spring_mass
parameters: {m: 2.0, c: 800.0, x0: 0.01}
elements:
  wall:   {type: ground, domain: translational}
  spring: {type: spring, c: c, x0: x0, domain: translational}
  mass:   {type: mass, m: m}
connections:
  - [wall.p, spring.a]
  - [spring.b, mass.a]
outputs: [spring.deflection, mass.v]
simulate: {t_end: 1.0, dt_out: 0.001}
"""


def _export(sc, tmp_path, name="model.fmu") -> Path:
    path = tmp_path / name
    fmu.export(sc, path)
    return path


@needs_cc
def test_cli_export_writes_an_fmu_that_fmpy_validates(tmp_path, capsys):
    fmpy = _fmpy()
    from fmpy.validation import validate_fmu
    path = tmp_path / "drive_train.fmu"
    assert main(["export", str(DIAGRAMS / "drive_train.yaml"), "--fmu", str(path)]) == 0
    assert f"wrote {path}" in capsys.readouterr().out
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as zf:
        assert "binaries/linux64/drive_train.so" in zf.namelist()
    md = fmpy.read_model_description(str(path), validate=True)
    assert md.fmiVersion == "2.0" and md.modelExchange.modelIdentifier == "drive_train"
    var = {v.name: v for v in md.modelVariables}
    # units and meanings from the element catalogue; parameters tunable, outputs computed
    assert (var["rotor.J"].unit, var["rotor.J"].causality, var["rotor.J"].variability) == \
        ("kg*m^2", "parameter", "tunable")
    assert "moment of inertia" in var["rotor.J"].description and float(var["rotor.J"].start) == 2.0e-3
    assert var["c_shaft"].causality == "parameter" and "shaft.c" in var["c_shaft"].description
    assert (var["rotor.omega"].unit, var["rotor.omega"].causality) == ("rad/s", "output")
    assert var["shaft.force"].unit == "N*m"
    # nominals atol/rtol of the scene (atol 1e-9 by default, rtol 1e-8): FMPy's absolute tolerance
    # rtol·nominal then equals the scene's
    assert float(var["rotor.p"].nominal) == pytest.approx(1e-9 / 1e-8, rel=1e-12)
    units = {u.name: u.baseUnit for u in md.unitDefinitions}
    assert (units["N*m"].kg, units["N*m"].m, units["N*m"].s) == (1, 2, -2)
    assert [d.variable.name for d in md.derivatives] == [f"der({s})" for s in ("rotor.p", "shaft.q", "load.p")]


def _worst(result_fmu, result, outputs) -> float:
    """The largest difference over the outputs, relative to each output's largest magnitude."""
    return max(float(np.max(np.abs(result_fmu[o] - result[o])) / np.max(np.abs(result[o]))) for o in outputs)


def _numeric_loops(monkeypatch):
    """Every linear loop left after elimination solved numerically in the generated code (not as a
    formula): the path of large loops, taken here by small ones.  The models built so are kept out
    of the process's memos and the disk cache (their keys do not know the limits): a later test of
    the same scene must not get them."""
    import multipole.equations
    monkeypatch.setattr(multipole.equations, "SYMBOLIC_LIMIT", 0)
    monkeypatch.setattr(multipole.equations, "CORE_SYMBOLIC_LIMIT", 0)     # and no core of a split loop either
    for memo in ("_MODELS", "_PRUNED", "_CHECKED", "_RESTORED"):
        monkeypatch.setattr(pipeline, memo, {})
    monkeypatch.setenv("MULTIPOLE_CACHE", "off")


def _has_numeric_loop(sc) -> bool:
    return any(b.kind == "linear" and b.solution is None for b in pipeline.equations(sc).blocks)


@needs_cc
@pytest.mark.parametrize("name, what, t_end", [
    ("drive_train.yaml", "the drive train", None),
    ("hard/slack_rope.yaml", "events: a rope going slack and taut 15 times", None),
    ("hard/slider_crank.yaml", "a numeric linear loop with the crank angle in its matrix", 2.0)])
def test_fmu_trajectories_converge_to_multipole_simulate(name, what, t_end, tmp_path, monkeypatch):
    """FMPy's CVode (BDF) and multipole's solver make different errors; as both tolerances shrink
    from 1e-8 to 1e-12 the difference must shrink with them (by at least 100 times: it does not
    if the FMU computes another model), down to 1e-6 of each output's range."""
    fmpy = _fmpy()
    sc = load(DIAGRAMS / name)
    if name == "hard/slider_crank.yaml":
        _numeric_loops(monkeypatch)
        assert _has_numeric_loop(sc)
    path = _export(sc, tmp_path)
    worst = {}
    for rtol in (1e-8, 1e-12):
        # the same error control on both sides: FMPy's absolute tolerance is rtol × the FMU's nominals
        ref = pipeline.run(sc, t_end=t_end, rtol=rtol, atol=rtol * fmu.nominal(sc), progress=False)
        outputs = list(ref.outputs)
        got = fmpy.simulate_fmu(str(path), stop_time=ref.t[-1], output_interval=ref.t[1] - ref.t[0],
                                relative_tolerance=rtol, output=outputs, record_events=False)
        assert len(got) == len(ref.t) and np.allclose(got["time"], ref.t, rtol=0, atol=1e-9 * ref.t[-1])
        worst[rtol] = _worst(got, ref, outputs)
    if name == "hard/slack_rope.yaml":
        assert len(ref.events) >= 10          # the scene does switch
    assert worst[1e-12] <= 1e-6, (what, worst)
    assert worst[1e-12] <= worst[1e-8] / 100 or worst[1e-8] <= 1e-7, (what, worst)


@needs_cc
def test_a_tuned_parameter_changes_the_frequency_as_theory_says(tmp_path):
    """Undamped spring-mass from rest at q(0) = x0: q(t) = x0·cos(ωt), ω = sqrt(c/m).  The FMU's
    stiffness is a tunable parameter: four times c doubles ω; the start value x0 is a parameter the
    state's start is computed from."""
    fmpy = _fmpy()
    path = _export(scene(SPRING_MASS), tmp_path)
    m, c, x0 = 2.0, 800.0, 0.01
    for start, stiffness, amplitude in (({}, c, x0), ({"c": 4 * c}, 4 * c, x0), ({"x0": 0.03}, c, 0.03)):
        r = fmpy.simulate_fmu(str(path), stop_time=1.0, output_interval=1e-3, relative_tolerance=1e-10,
                              start_values=start, output=["spring.deflection", "mass.v"], record_events=False)
        w = math.sqrt(stiffness / m)
        expected = amplitude * np.cos(w * r["time"])
        # CVode at rtol 1e-10 over 4.5 (or 9) periods: the phase error stays below 1e-6 of the amplitude
        assert np.max(np.abs(np.abs(r["spring.deflection"]) - np.abs(expected))) <= 1e-6 * amplitude, start
        assert np.max(np.abs(np.abs(r["mass.v"]) - np.abs(amplitude * w * np.sin(w * r["time"])))) <= \
            1e-6 * amplitude * w, start


def test_newton_loop_is_refused_naming_the_element(tmp_path):
    path = tmp_path / "loop.fmu"
    with pytest.raises(fmu.FmuError) as exc:
        fmu.export(load(DIAGRAMS / "hard" / "nonlinear_loop.yaml"), path)
    assert exc.value.code == "fmu_newton_loop"
    assert "d_2" in exc.value.message and "Newton" in exc.value.message
    assert not path.exists()


def test_position_closure_is_refused_naming_the_element(tmp_path):
    """A four-bar: its dyad's closure is evaluated at every call (by its formula), which the C code
    does not do: refused naming the dyad, no file written."""
    path = tmp_path / "fourbar.fmu"
    with pytest.raises(fmu.FmuError) as exc:
        fmu.export(load(DIAGRAMS / "linkages" / "fourbar_crank_rocker.yaml"), path)
    assert exc.value.code == "fmu_newton_loop"
    assert "position closure of rocker" in exc.value.message
    assert not path.exists()


def test_table_is_refused_naming_the_element(tmp_path):
    with pytest.raises(fmu.FmuError) as exc:
        fmu.export(load(DIAGRAMS / "weber" / "spur_elastic_table.yaml"), tmp_path / "table.fmu")
    assert exc.value.code == "fmu_table"
    assert "element mesh" in exc.value.message


def test_no_c_compiler_is_a_clear_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(fmu.shutil, "which", lambda name: None)
    monkeypatch.delenv("CC", raising=False)
    path = tmp_path / "model.fmu"
    with pytest.raises(fmu.FmuError) as exc:
        fmu.export(load(DIAGRAMS / "drive_train.yaml"), path)
    assert exc.value.code == "no_c_compiler"
    assert "apt-get install gcc" in exc.value.fix
    assert main(["export", str(DIAGRAMS / "drive_train.yaml"), "--fmu", str(path)]) == 2
    assert "error[no_c_compiler]" in capsys.readouterr().err
    assert not path.exists()


def test_export_of_an_ill_posed_scene_exits_1_with_the_diagnostics(tmp_path, capsys):
    path = tmp_path / "rigid.fmu"
    assert main(["export", str(DIAGRAMS / "power_split_rigid.yaml"), "--fmu", str(path)]) == 1
    err = capsys.readouterr().err
    assert "not well-posed, nothing exported" in err and "error[kinematic_overdetermination]" in err
    assert not path.exists()


def test_export_refuses_a_target_that_is_not_an_fmu(tmp_path, capsys):
    assert main(["export", str(DIAGRAMS / "drive_train.yaml"), "--fmu", str(tmp_path / "model.zip")]) == 2
    assert "error[bad_output]" in capsys.readouterr().err


def test_units_are_read_as_si_base_units():
    assert fmu.base_units("N*m*s/rad") == {"kg": 1, "m": 2, "s": -1, "rad": -1}
    assert fmu.base_units("m/s^2") == {"m": 1, "s": -2}
    assert fmu.base_units("Ohm") == {"kg": 1, "m": 2, "s": -3, "A": -2}
    assert fmu.base_units("N*m | N") is None and fmu.base_units("-") is None


@needs_cc
def test_set_gives_the_parameters_their_default_values(tmp_path, capsys):
    import xml.etree.ElementTree as ET
    path = tmp_path / "stiffer.fmu"
    assert main(["export", str(DIAGRAMS / "drive_train.yaml"), "--fmu", str(path), "--set", "c_shaft=4000",
                 "--set", "rotor.J=0.004"]) == 0
    with zipfile.ZipFile(path) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    start = {v.get("name"): v.find("Real").get("start") for v in root.iter("ScalarVariable")}
    assert float(start["c_shaft"]) == 4000.0 and float(start["rotor.J"]) == 0.004
    assert start["rotor.p"] is None          # computed from rotor.J and rotor.omega0 when initialisation ends


def test_a_value_the_parameters_make_infinite_is_refused_as_simulate_refuses_it(tmp_path):
    sc = scene("""
        name: zero_law
        parameters: {m: 2.0, k: 1.0}
        elements:
          wall:   {type: ground, domain: translational}
          damper: {type: damper, law: "f/(k - 1)", domain: translational}
          mass:   {type: mass, m: m, v0: 1.0}
        connections:
          - [wall.p, damper.a]
          - [damper.b, mass.a]
        outputs: [mass.v]
        simulate: {t_end: 1.0}
        """)
    with pytest.raises(MultipoleError) as simulated:
        pipeline.run(sc, progress=False)
    with pytest.raises(fmu.FmuError) as exported:
        fmu.export(sc, tmp_path / "zero.fmu")
    assert exported.value.code == simulated.value.code == "infinite_value"
    assert "element damper" in exported.value.message
    assert not (tmp_path / "zero.fmu").exists()


@needs_cc
@pytest.mark.parametrize("name", ["drive_train.yaml", "weber/spur_elastic_fourpole_varying.yaml"])
def test_directional_derivatives_match_central_differences(name, tmp_path, monkeypatch):
    """fmi2GetDirectionalDerivative (d derivatives/dx and d outputs/dx, one state at a time) against
    central differences of fmi2GetDerivatives and the outputs.  Both models are linear in the
    state (the mesh stiffness of the second varies with time only; its loop is solved numerically
    here), so the differences have no truncation error, only rounding: at most a few ε·|F|/h."""
    import ctypes
    _fmpy()
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Model
    sc = load(DIAGRAMS / name)
    if name != "drive_train.yaml":
        _numeric_loops(monkeypatch)
        assert _has_numeric_loop(sc)
    path = _export(sc, tmp_path)
    md = read_model_description(str(path))
    m = FMU2Model(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.modelExchange.modelIdentifier,
                  instanceName="jacobian")
    m.instantiate()
    m.setupExperiment(startTime=0.0, stopTime=1.0)
    m.enterInitializationMode()
    m.exitInitializationMode()
    m.newDiscreteStates()
    m.enterContinuousTimeMode()
    states = [d.variable.derivative.valueReference for d in md.derivatives]
    unknowns = [d.variable.valueReference for d in md.derivatives] + [o.variable.valueReference for o in md.outputs]
    n = len(states)
    x = np.random.default_rng(1).normal(size=n) * 0.1
    m.setTime(0.3)

    def values(xx):
        m.setContinuousStates((ctypes.c_double * n)(*xx), n)
        dx = (ctypes.c_double * n)()
        m.getDerivatives(dx, n)
        return np.array(list(dx) + m.getReal([o.variable.valueReference for o in md.outputs]))
    for j in range(n):
        m.setContinuousStates((ctypes.c_double * n)(*x), n)
        exact = np.array(m.getDirectionalDerivative(unknowns, [states[j]], [1.0]))
        h = 1e-6 * max(1.0, abs(x[j]))
        up, down = values(x + h * np.eye(n)[j]), values(x - h * np.eye(n)[j])
        rounding = 8 * np.finfo(float).eps * np.maximum(np.abs(up), np.abs(down)).max() / h
        assert np.max(np.abs(exact - (up - down) / (2 * h))) <= rounding, (name, j)
    m.terminate()
    m.freeInstance()
