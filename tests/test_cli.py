"""The command-line contract (DESIGN §6) and every scene in diagrams/."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from multipole import pipeline
from multipole.cli import main
from multipole.netlist import load

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted((ROOT / "diagrams").rglob("*.yaml"))


@pytest.mark.parametrize("path", SCENES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_scene_checks_and_simulates(path, capsys):
    scene = load(path)
    expected = scene.expect_check or 0
    assert main(["check", str(path)]) == expected
    if expected == 0:
        t_end = min(scene.simulate.get("t_end", 1.0), 10 * scene.simulate.get("dt_out", 1.0))
        res = pipeline.run(scene, t_end=t_end, progress=False)
        assert all(np.all(np.isfinite(v)) for v in res.outputs.values())
    capsys.readouterr()


def test_check_json(capsys):
    code = main(["check", str(ROOT / "diagrams" / "power_split_rigid.yaml"), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 1 and data["exit_code"] == 1 and not data["well_posed"]
    err = [d for d in data["diagnostics"] if d["severity"] == "error"]
    assert err[0]["code"] == "kinematic_overdetermination" and err[0]["path"]


def test_simulate_writes_csv_on_the_output_grid(tmp_path, capsys):
    out = tmp_path / "r.csv"
    png = tmp_path / "r.png"
    code = main(["simulate", str(ROOT / "diagrams" / "drive_train.yaml"), "--t-end", "0.1", "--dt-out", "0.01",
                 "--out", str(out), "--plot", str(png), "--quiet", "--set", "c_shaft=1000"])
    assert code == 0
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["t [s]", "rotor.omega [rad/s]", "load.omega [rad/s]", "shaft.force [N*m]"]
    t = np.array([float(r[0]) for r in rows[1:]])
    assert np.allclose(t, np.linspace(0, 0.1, 11), atol=1e-12)
    assert png.stat().st_size > 10_000
    assert "solver" in capsys.readouterr().out


def test_set_overrides_change_the_result(tmp_path):
    path = ROOT / "diagrams" / "rlc_series.yaml"
    a = pipeline.run(load(path), t_end=0.02, progress=False)
    b = pipeline.run(load(path, {"V": "24"}), t_end=0.02, progress=False)
    assert np.allclose(b["C1.v"], 2 * a["C1.v"], rtol=1e-6, atol=1e-9)


def test_equations_formats(capsys):
    path = str(ROOT / "diagrams" / "drive_train.yaml")
    assert main(["equations", path]) == 0
    text = capsys.readouterr().out
    assert "d/dt rotor.p" in text and "c_shaft*shaft.q" in text
    assert main(["equations", path, "--format", "latex"]) == 0
    assert "\\frac{d}{dt}" in capsys.readouterr().out
    assert main(["equations", path, "--format", "python"]) == 0
    assert "def rhs(t, x):" in capsys.readouterr().out
    assert main(["equations", path, "--steps"]) == 0
    assert "Back-calculation" in capsys.readouterr().out


def test_elements_catalogue(capsys):
    assert main(["elements"]) == 0
    listing = capsys.readouterr().out
    for name in ("inertia", "mass", "spring", "damper", "torque_source", "speed_source", "ground", "ideal_gear",
                 "resistor", "capacitor", "inductor", "voltage_source", "current_source", "TF", "GY", "Se",
                 "Sf", "I", "C", "R", "junction_a", "junction_b"):
        assert f"  {name} " in listing
    assert main(["elements", "spring"]) == 0
    assert "c [N*m/rad | N/m]" in capsys.readouterr().out


def test_linearize_modes_match_the_closed_form(capsys):
    """Series RLC: eigenvalues -R/(2L) ± j*sqrt(1/(LC) - (R/2L)^2)."""
    from multipole.linearize import linearize
    R, L, C = 10.0, 0.1, 1.0e-4
    scene = load(ROOT / "diagrams" / "rlc_series.yaml")
    lin = linearize(pipeline.equations(scene), scene.outputs)
    lam = sorted(np.linalg.eigvals(lin.A), key=lambda z: z.imag)
    alpha, wd = R / (2 * L), np.sqrt(1 / (L * C) - (R / (2 * L)) ** 2)
    assert np.allclose(lam, [-alpha - 1j * wd, -alpha + 1j * wd], rtol=1e-12)
    # static gain from the supply voltage to the capacitor voltage is 1
    G0 = lin.D - lin.C @ np.linalg.solve(lin.A, lin.B)
    assert np.isclose(G0[scene.outputs.index("C1.v"), lin.inputs.index("supply.u")], 1.0, rtol=1e-12)
    assert main(["linearize", str(ROOT / "diagrams" / "rlc_series.yaml")]) == 0
    assert f"f_n = {1 / np.sqrt(L * C) / (2 * np.pi):.6g} Hz" in capsys.readouterr().out


def test_models_are_restored_from_the_disk_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("MULTIPOLE_CACHE", str(tmp_path / "cache"))   # empty: nothing cached by earlier tests
    pipeline._MODELS.clear()
    path = ROOT / "diagrams" / "rlc_series.yaml"
    first = pipeline.run(load(path), t_end=0.01, progress=False)
    pipeline._MODELS.clear()                       # as in a new process
    second = pipeline.run(load(path), t_end=0.01, progress=False)
    assert second.stats["model_cached"] and not first.stats["model_cached"]
    assert np.array_equal(first["C1.v"], second["C1.v"])
    pipeline._MODELS.clear()
    changed = pipeline.run(load(path, {"V": "6"}), t_end=0.01, progress=False)   # other digest
    assert not changed.stats["model_cached"]
    assert np.allclose(changed["C1.v"], first["C1.v"] / 2, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("option, value, words", [
    ("--out", "{tmp}/missing/r.csv", "does not exist"),
    ("--plot", "{tmp}/missing/r.png", "does not exist"),
    ("--plot", "{tmp}/r.txt", "unsupported file type"),
])
def test_unwritable_outputs_are_refused_before_simulating(tmp_path, capsys, option, value, words):
    code = main(["simulate", str(ROOT / "diagrams" / "rlc_series.yaml"), option, value.format(tmp=tmp_path),
                 "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and words in err[0] and option in err[0]
    assert not any(tmp_path.iterdir())


def test_check_json_reports_an_invalid_file_as_json(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nelements:\n  a: {type: no_such_type}\n", encoding="utf-8")
    code = main(["check", str(bad), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 2 and data["exit_code"] == 2 and data["error"]["code"] == "unknown_type"
    assert "bad.yaml:3" in data["error"]["where"] + data["error"]["message"]


@pytest.mark.parametrize("name", ["drive_train.yaml", "hard/nonlinear_loop.yaml"])
def test_latex_rows_are_well_formed_math(name, capsys):
    """Every row of the LaTeX output parses as math (matplotlib's mathtext, an independent parser)."""
    from matplotlib.mathtext import MathTextParser
    assert main(["equations", str(ROOT / "diagrams" / name), "--format", "latex"]) == 0
    text = capsys.readouterr().out
    body = text.split("\\begin{aligned}\n")[1].split("\n\\end{aligned}")[0]
    parser = MathTextParser("path")
    for row in body.split(" \\\\\n"):
        parser.parse("$" + row.replace("&=", "=") + "$")
    assert "shaft_{" not in text and "d_{" not in text    # dotted names stay whole, not subscripted


def test_python_output_runs_on_its_own_and_equals_the_model(capsys):
    """The printed Python (with a Newton loop) runs in a fresh namespace and gives the model's rhs."""
    path = ROOT / "diagrams" / "hard" / "nonlinear_loop.yaml"
    assert main(["equations", str(path), "--format", "python"]) == 0
    namespace: dict = {}
    exec(capsys.readouterr().out, namespace)       # our own generated code, from our own scene
    model = pipeline.model(load(path))
    for t, x in ((0.3, [0.5]), (1.2, [-2.0])):
        assert np.allclose(namespace["rhs"](t, np.array(x)), model.rhs(t, np.array(x)), rtol=1e-12, atol=0)


def test_text_equations_say_when_a_loop_has_no_closed_form(capsys):
    assert main(["equations", str(ROOT / "diagrams" / "hard" / "nonlinear_loop.yaml")]) == 0
    text = capsys.readouterr().out
    assert "where d_1.b.f solves the algebraic loop(s) below" in text and "no closed form" in text
    assert "newton loop for (d_1.b.f)" in text      # torn: Newton on one unknown, the rest explicit
