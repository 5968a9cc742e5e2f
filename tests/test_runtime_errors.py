"""Run-time failures, exit codes and output files (docs/cli.md).

Every failure of a well-posed model while it runs is one line on stderr, names the file:line of
the element and the time, and exits 3; structural problems exit 1 in every verb; invalid options
exit 2 before any work; Ctrl-C exits 130 and leaves no file behind.
"""
import os
import select
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from multipole import pipeline
from multipole.cli import main
from multipole.errors import MultipoleError, NewtonError, RunError
from multipole.netlist import load
from multipole.simulate import MAX_OUTPUT_ROWS, expected_steps, simulate

ROOT = Path(__file__).resolve().parents[1]
DRIVE = ROOT / "diagrams" / "drive_train.yaml"
RIGID = ROOT / "diagrams" / "power_split_rigid.yaml"

#: a free inertia driven by a torque source and braked by a damper; {value} and {law} filled in
BRAKED = """\
name: braked
elements:
  src:     {{type: torque_source, value: "{value}"}}
  rotor:   {{type: inertia, J: 1.0}}
  brake:   {{type: damper, law: "{law}"}}
  housing: {{type: ground}}
connections:
  - [src.p, rotor.a]
  - [rotor.b, brake.a]
  - [brake.b, housing.p]
outputs: [rotor.omega, brake.force]
simulate: {{t_end: {t_end}, dt_out: 0.01}}
"""

#: two inertias on a stiff undamped shaft: omega_n = sqrt(c (1/J1 + 1/J2)) = sqrt(2e9) rad/s
STIFF = """\
name: stiff
elements:
  src:   {type: torque_source, value: "sin(10*t)"}
  rotor: {type: inertia, J: 1.0e-3}
  shaft: {type: spring, c: 1.0e6}
  load:  {type: inertia, J: 1.0e-3}
connections:
  - [src.p, rotor.a]
  - [rotor.b, shaft.a]
  - [shaft.b, load.a]
outputs: [load.omega]
simulate: {t_end: 1.0e+6, dt_out: 1.0}
"""


def write(tmp_path, text, name="scene.yaml") -> str:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return str(path)


def braked(tmp_path, value="1.0", law="1.0*f", t_end=0.1) -> str:
    return write(tmp_path, BRAKED.format(value=value, law=law, t_end=t_end))


def one_error_line(capsys) -> str:
    """The only line on stderr (no traceback, no warning before it)."""
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("error[")
    return err[0]


# ------------------------------------------------------------------------------------------------
# exit codes

@pytest.mark.parametrize("verb", ["check", "equations", "linearize", "simulate", "diagram"])
def test_structural_problems_exit_1_in_every_verb(verb, tmp_path, capsys):
    extra = ["-o", str(tmp_path / "d.png")] if verb == "diagram" else []
    assert main([verb, str(RIGID), *extra]) == 1
    capsys.readouterr()


def test_error_classes_carry_their_exit_code():
    assert MultipoleError("x", "y").exit_code == 2
    assert issubclass(NewtonError, RunError) and NewtonError("no solution").exit_code == 3
    assert NewtonError("no solution").code == "newton_failed"


def test_library_warnings_never_precede_the_error_line(capsys, monkeypatch):
    """A numpy warning during a command that then fails is dropped; after a success it is printed
    as one line after the output."""
    import warnings
    from multipole import cli

    def failing(args):
        warnings.warn("overflow encountered in exp", RuntimeWarning)
        raise RunError("arithmetic_error", "failed")
    monkeypatch.setattr(cli, "cmd_elements", failing)
    assert main(["elements"]) == 3
    assert capsys.readouterr().err.splitlines() == ["error[arithmetic_error] failed"]

    def succeeding(args):
        warnings.warn("overflow encountered in exp", RuntimeWarning)
        print("done")
        return 0
    monkeypatch.setattr(cli, "cmd_elements", succeeding)
    assert main(["elements"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "done\n"
    assert captured.err.splitlines() == ["multipole: warning: RuntimeWarning: overflow encountered in exp"]


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    out = capsys.readouterr().out.split()
    assert out[0] == "multipole" and out[1][0].isdigit()


# ------------------------------------------------------------------------------------------------
# arithmetic failures in the model: exit 3, one line naming file:line, element and time

@pytest.mark.parametrize("value, law, element, words", [
    ("1/t", "1.0*f", "src", "division by zero at t = 0 s in src.u = 1/t"),
    ("sqrt(t - 0.01)", "1.0*f", "src", "outside the domain of a function"),
    ("exp(1000 + t)", "1.0*f", "src", "overflow"),
    ("1.0", "log(f)", "brake", "at t = 0 s in brake.p.e = log(brake.p.f)"),
    ("1.0", "1/f", "brake", "division by zero at t = 0 s in brake"),
    ("1.0", "sqrt(f)", "brake", "division by zero at t = 0 s in the Jacobian near brake"),
])
def test_arithmetic_failures_are_one_line_naming_element_and_time(tmp_path, capsys, value, law, element, words):
    path = braked(tmp_path, value, law)
    assert main(["simulate", path, "--quiet"]) == 3
    line = one_error_line(capsys)
    line_no = 3 if element == "src" else 5            # the element's line in BRAKED
    assert line.startswith(f"error[arithmetic_error] {path}:{line_no} element '{element}': ")
    assert words in line


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_a_switching_function_outside_its_domain_is_one_line(tmp_path, capsys, backend):
    """abs(sqrt(t - 0.01)) is a switching function of time alone, undefined before t = 0.01 s."""
    if backend == "numba":
        pytest.importorskip("numba")
    path = braked(tmp_path, "abs(sqrt(t - 0.01))")
    assert main(["simulate", path, "--quiet", "--backend", backend]) == 3
    line = one_error_line(capsys)
    assert "at t = 0 s" in line and "sqrt(t - 0.01)" in line
    if backend == "numpy":           # Python raises in the line that computes the source's value
        assert line.startswith(f"error[arithmetic_error] {path}:3 element 'src': ")
    else:                            # compiled code gives NaN, found where the switches are scheduled
        assert line.startswith("error[not_finite] ")


def test_a_failure_during_the_run_names_the_time_it_happened(tmp_path, capsys):
    """omega' = -sqrt(omega) from omega(0) = 1: omega = (1 - t/2)^2 reaches 0 at t = 2 s, after which
    the root of a negative speed is undefined."""
    path = write(tmp_path, """\
        name: sqrt_brake
        elements:
          body:    {type: inertia, J: 1.0, omega0: 1.0}
          brake:   {type: damper, law: "sqrt(f)"}
          housing: {type: ground}
        connections:
          - [body.b, brake.a]
          - [brake.b, housing.p]
        outputs: [body.omega]
        simulate: {t_end: 3.0, dt_out: 0.1, solver: RK45}
        """)
    assert main(["simulate", path, "--quiet"]) == 3
    line = one_error_line(capsys)
    assert f"{path}:4 element 'brake'" in line
    t = float(line.split(" at t = ")[1].split(" s")[0])
    assert 1.99 < t < 2.01      # the step that crosses t = 2 s; its trial points are within one step


def test_newton_failure_is_a_run_time_error_naming_the_loop(tmp_path, capsys):
    """Dampers sinh(f) and cosh(f) in series carry one torque e: omega = asinh(e) + acosh(e) needs
    e >= 1, so the loop has no solution once omega < asinh(1) = 0.881 (from omega0 = 3, braking)."""
    path = write(tmp_path, """\
        name: no_loop_solution
        elements:
          rotor:   {type: inertia, J: 1.0, omega0: 3.0}
          d1:      {type: damper, law: "sinh(f)"}
          d2:      {type: damper, law: "cosh(f)"}
          housing: {type: ground}
        connections:
          - [rotor.b, d1.a]
          - [d1.b, d2.a]
          - [d2.b, housing.p]
        outputs: [rotor.omega]
        simulate: {t_end: 5.0}
        """)
    assert main(["simulate", path, "--quiet"]) == 3
    line = one_error_line(capsys)
    assert "no solution at t = " in line and "algebraic loop" in line
    assert f"{path}:4 element 'd1'" in line or f"{path}:5 element 'd2'" in line


def test_non_finite_outputs_are_refused(tmp_path, capsys):
    """A speed source 1e300 exp(1000 t) on a damper: no state, the output force d*omega exceeds the
    largest float (1.8e308) from t = ln(1.8e8)/1000 = 0.0190 s on: the first non-finite row is 0.02 s."""
    path = write(tmp_path, """\
        name: overflowing_output
        elements:
          drive:   {type: speed_source, value: "1e300*exp(1000*t)"}
          brake:   {type: damper, d: 1.0}
          housing: {type: ground}
        connections:
          - [drive.p, brake.a]
          - [brake.b, housing.p]
        outputs: [brake.force]
        simulate: {t_end: 0.1, dt_out: 0.01}
        """)
    out = tmp_path / "r.csv"
    assert main(["simulate", path, "--quiet", "--out", str(out)]) == 3
    line = one_error_line(capsys)
    assert line.startswith("error[not_finite]") and "output brake.force" in line and "t = 0.02 s" in line
    assert not out.exists()


def test_ideal_coulomb_friction_runs_against_the_closed_form(tmp_path):
    """sign(f) friction of 1 N m on J = 1 kg m^2 driven by 2 N m until t = 0.05 s: omega = t up to
    0.05 s, then the friction alone brakes it, omega = 0.1 - t (both exact: piecewise linear)."""
    result = pipeline.run(load(braked(tmp_path, "2*step(0.05 - t)", "sign(f)", t_end=0.09)), progress=False)
    t = result.t
    expected = np.where(t <= 0.05, t, 0.1 - t)
    assert np.allclose(result["rotor.omega"], expected, rtol=0, atol=1e-9)
    assert np.allclose(result["brake.force"][t > 0], 1.0, rtol=0, atol=1e-12)


def test_ideal_coulomb_friction_sticking_ends_as_chattering(tmp_path, capsys):
    """At rest after t = 0.1 s the ideal law switches at every step: a clean run-time error."""
    path = braked(tmp_path, "2*step(0.05 - t)", "sign(f)", t_end=0.15)
    assert main(["simulate", path, "--quiet"]) == 3
    assert one_error_line(capsys).startswith("error[chattering]")


# ------------------------------------------------------------------------------------------------
# linearize

def test_linearize_with_a_source_equal_to_t(tmp_path, capsys):
    """J = 1, d = 1: A = [-1] (p' = -p/J*d), B = [1] (the torque), whatever the torque's value."""
    assert main(["linearize", braked(tmp_path, "t")]) == 0
    out = capsys.readouterr().out
    assert "A (1x1)" in out
    rows = out.splitlines()
    a_row = rows[rows.index(next(r for r in rows if r.startswith("A (1x1)"))) + 1]
    b_row = rows[rows.index(next(r for r in rows if r.startswith("B (1x"))) + 1]
    assert float(a_row.strip(" []")) == pytest.approx(-1.0, abs=1e-12)
    assert float(b_row.strip(" []").split(",")[0]) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("law", ["1/f", "log(f)"])
def test_linearize_at_a_singular_law_is_one_line(tmp_path, capsys, law):
    path = braked(tmp_path, "1.0", law)
    assert main(["linearize", path]) == 3
    line = one_error_line(capsys)
    assert line.startswith(f"error[not_linearizable] {path}:5 element 'brake'")


# ------------------------------------------------------------------------------------------------
# options and output files

def test_an_output_grid_too_large_is_refused_up_front(capsys):
    assert main(["simulate", str(DRIVE), "--t-end", "1e9", "--dt-out", "1e-6", "--quiet"]) == 2
    line = one_error_line(capsys)
    assert line.startswith(f"error[grid_too_large] {DRIVE}:") or line.startswith(f"error[grid_too_large] {DRIVE}")
    assert "1e+15 rows" in line and "PB" in line
    model = pipeline.model(load(DRIVE))
    with pytest.raises(MultipoleError) as exc:
        simulate(model, 1e9, 1e-6)
    assert exc.value.code == "grid_too_large" and exc.value.exit_code == 2
    assert MAX_OUTPUT_ROWS == 10_000_000          # the documented cap (docs/cli.md)


@pytest.mark.parametrize("option, value", [("--dt-out", "-1"), ("--dt-out", "0"), ("--t-end", "inf"),
                                           ("--rtol", "nan"), ("--rtol", "1.5"), ("--atol", "-1e-9")])
def test_bad_numbers_on_the_command_line_are_refused(tmp_path, capsys, option, value):
    out = tmp_path / "r.csv"
    assert main(["simulate", str(DRIVE), f"{option}={value}", "--quiet", "--out", str(out)]) == 2
    line = one_error_line(capsys)
    code = "bad_option" if option == "--rtol" and value == "1.5" else "not_numeric"
    assert line.startswith(f"error[{code}] command line: simulate.{option[2:].replace('-', '_')} ")
    assert not out.exists()


@pytest.mark.parametrize("target, words", [("{tmp}", "is a folder"), ("{tmp}/r.json", "unsupported file type"),
                                           ("{tmp}/r.npz", "use one of .csv")])
def test_out_that_cannot_be_written_is_refused_before_the_run(tmp_path, capsys, target, words):
    assert main(["simulate", str(DRIVE), "--quiet", "--out", target.format(tmp=tmp_path)]) == 2
    assert words in one_error_line(capsys)
    assert not any(tmp_path.iterdir())


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes into read-only folders")
def test_out_in_a_read_only_folder_is_refused(tmp_path, capsys):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        assert main(["simulate", str(DRIVE), "--quiet", "--out", str(folder / "r.csv")]) == 2
        assert "not writable" in one_error_line(capsys)
    finally:
        folder.chmod(0o700)


def test_diagram_writes_pdf(tmp_path, capsys):
    pdf = tmp_path / "d.pdf"
    assert main(["diagram", str(DRIVE), "-o", str(pdf)]) == 0
    assert pdf.read_bytes()[:5] == b"%PDF-"
    assert [p.name for p in tmp_path.iterdir()] == ["d.pdf"]      # no temporary file left
    capsys.readouterr()


def test_csv_is_written_atomically(tmp_path, monkeypatch):
    """A write that fails half-way keeps the previous file whole and leaves no temporary file."""
    result = pipeline.run(load(DRIVE), t_end=0.01, progress=False)
    out = tmp_path / "r.csv"
    result.to_csv(out)
    before = out.read_text()

    def broken(path, data, **kw):
        with open(path, "w") as fh:
            fh.write("t,rotor.omega\n0,")
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(np, "savetxt", broken)
    with pytest.raises(OSError):
        result.to_csv(out)
    assert out.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["r.csv"]


# ------------------------------------------------------------------------------------------------
# long runs: warned about, Ctrl-C

def test_steps_estimate_is_the_fastest_oscillation(tmp_path):
    """Undamped two-inertia shaft: the eigenvalues are 0, 0 and +-j omega_n with
    omega_n = sqrt(c (1/J1 + 1/J2)); five steps per period give 0.8 omega_n t_end steps."""
    model = pipeline.model(load(write(tmp_path, STIFF)))
    omega_n = np.sqrt(1e6 * (1 / 1e-3 + 1 / 1e-3))
    steps, why = expected_steps(model, "auto", 1e6)
    assert steps == pytest.approx(0.8 * omega_n * 1e6, rel=1e-9)
    assert expected_steps(model, "RK45", 1e6)[0] == pytest.approx(omega_n / 4 * 1e6, rel=1e-9)


def test_a_run_of_very_many_steps_is_warned_about_first(tmp_path, capsys, monkeypatch):
    sim = sys.modules["multipole.simulate"]       # the package exports a function of the same name
    monkeypatch.setattr(sim, "MANY_STEPS", 1e3)      # 0.8 omega_n t_end = 3.6e3 steps over 0.1 s
    assert main(["simulate", write(tmp_path, STIFF), "--t-end", "0.1", "--quiet"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("multipole: warning: stiff: the stiffness estimate says")


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT and select on pipes are POSIX")
def test_ctrl_c_during_simulate_is_one_line_exit_130_and_no_file(tmp_path):
    path = write(tmp_path, STIFF)              # about 3.6e10 steps: interrupted long before the end
    out = tmp_path / "r.csv"
    env = dict(os.environ, MULTIPOLE_CACHE=str(tmp_path / "cache"))
    proc = subprocess.Popen([sys.executable, "-m", "multipole.cli", "simulate", path, "--quiet", "--out", str(out)],
                            stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    try:
        ready, _, _ = select.select([proc.stderr], [], [], 120)
        assert ready, "no warning line within 120 s"
        warning = proc.stderr.readline()       # printed before the integration starts
        assert warning.startswith("multipole: warning:")
        time.sleep(1.0)                        # let it integrate for a moment
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    lines = stderr.strip().splitlines()
    assert proc.returncode == 130
    assert len(lines) == 1 and "interrupted at t = " in lines[0] and "discarded" in lines[0], lines
    assert "Traceback" not in stderr
    assert not out.exists() and [p.name for p in tmp_path.iterdir() if p.suffix != ".yaml"] == ["cache"]


def test_an_infinite_initial_state_is_one_error_before_any_step():
    """The driver refuses a non-finite start (scipy's solvers raised a bare ValueError)."""
    import numpy as np
    from multipole import loads, pipeline
    from multipole.simulate import simulate
    scene = loads("elements:\n  J: {type: inertia, J: 1.0}\n  T: {type: torque_source, value: '1.0'}\n"
                  "connections:\n  - [T.p, J.a]\n", "inf.yaml")
    model = pipeline.model(scene)
    with pytest.raises(RunError) as exc:
        simulate(model, 1.0, x0=np.array([np.inf]), progress=False)
    assert exc.value.code == "not_finite" and "J.p" in exc.value.message


def test_a_check_warning_never_comes_before_the_error_line(tmp_path, capsys):
    """simulate repeats the check's warnings; when the run then fails, the error line is first and the
    warning follows as context (fuzz campaign, seed 2029, simulate case 496; its run failed on
    0*(1/sqrt(q*t)) in the Jacobian, which the generated code now prints as 0 (e1.a.e is held at
    zero), so the source's 1/t makes the run fail instead)."""
    path = tmp_path / "w.yaml"
    path.write_text(textwrap.dedent("""\
        elements:
          e0: {type: I, J: 102.8792918, domain: electrical}
          e1: {type: TF, ratio: "0.14762049014990505*sqrt(q*t)"}
          e2: {type: spur_stage, r1: 102.8792918, r2: 1345.131717, z1: 0.03174, level: elastic,
               c: "1e5*(1 + 0.2*cos(q))", d: 0.3030148}
          e3: {type: Sf, value: "1/t"}
        connections:
          - [e2.b, e3.p]
          - [e1.b, e2.a]
        outputs: [e0.p, e1.q]
        simulate: {t_end: 0.001}
        """), encoding="utf-8")
    code = main(["simulate", str(path), "--quiet"])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert code == 3 and err[0].startswith("error["), err
    assert any(ln.startswith("multipole: warning: [") for ln in err[1:]), err
